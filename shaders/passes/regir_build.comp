// regir_build: fills the world-space grid of presampled VPLs (ReGIR; shaders/restir/regir.glsl says
// what an entry is and how restir_initial uses it). One workgroup per cell, dispatched as the
// grid's cells^3; a cell is built only when a pixel asked for it in the previous frame (sparse:
// restir_initial stamps the cells its pixels lie in), so the cost follows the visible cells, not
// the grid. Each entry: RIS over `entry_candidates` draws from the source pdf (uniform, or power
// through the alias table) with the cell target p^_c; the entry stores the chosen VPL's candidate
// record and W = sum w / p^_c(y). The cell's record then gets this frame's stamp and the mean of
// its entries' sum w (an unbiased estimate of sum_i p^_c(i), the normalisation S); the previous
// build's S moves to the slot restir_initial reads, so the MIS weights never depend on the entries
// they weigh.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/scene.glsl"
#include "../lib/random.glsl"
#include "../restir/regir.glsl"
#include "../restir/reservoir.glsl"
#include "../common/texel_records.glsl"
#include "../common/poison.glsl"

layout(local_size_x = 64) in;  // REGIR_WORKGROUP

layout(set = 1, binding = 0) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpl_alias;  // AliasEntry, RG32UI
layout(set = 1, binding = 2, std430) writeonly buffer Entries { GridEntry entries[]; };
// Per cell: (stamp of the last frame a pixel asked for it + 1, stamp of the frame it was built in
// + 1 or 0, S of this build, S of the build before), the S as float bits.
layout(set = 1, binding = 3, std430) buffer Cells { uvec4 cells[]; };

layout(push_constant) uniform Push {
    VplParams params;
    GridParams grid;
} pc;

const uint SALT_REGIR = 0x7267u;

shared bool s_build;
shared uvec4 s_record;
shared float s_sum[REGIR_WORKGROUP];

void main() {
    GridParams g = pc.grid;
    VplParams p = pc.params;
    uint cell = (gl_WorkGroupID.z * g.cells + gl_WorkGroupID.y) * g.cells + gl_WorkGroupID.x;
    uint lane = gl_LocalInvocationID.x;
    if (lane == 0u) {
        uvec4 rec = cells[cell];
        // Asked for by a pixel of the previous frame (which wrote frame_index - 1 + 1). Frame 0
        // builds nothing: a zero-filled record would otherwise match and build every cell.
        s_build = frame.frame_index > 0u && rec.x == frame.frame_index && p.vpl_count > 0u;
        s_record = rec;
    }
    barrier();
    if (!s_build) {
        if (lane == 0u && s_record.y != 0u) {
            cells[cell].y = 0u;  // not built this frame: its entries are stale
        }
        return;
    }
    vec3 centre = regir_cell_centre(g, cell);
    float rc = regir_cell_radius(g);
    float inv_k = 1.0 / float(g.entry_candidates);
    float sum = 0.0;
    for (uint e = lane; e < g.entries; e += REGIR_WORKGROUP) {
        uint slot = cell * g.entries + e;
        Rng rng = rng_init(slot, frame.frame_index, frame.seed, SALT_REGIR);
        ReservoirStream st = stream_begin();
        Vpl chosen_vpl;
        for (uint j = 0u; j < g.entry_candidates; ++j) {
            uint i = rand_index(rng, p.vpl_count);
            if (p.source == 1u) {
                AliasEntry a = alias_texels(vpl_alias, i);
                i = alias_resolve(i, a.keep, a.alias, rng_next(rng));
            }
            Vpl v = vpl_texels(vpls, i);
            float q = vpl_source_pdf(v.flux, p);
            // With the normal as the entry's candidate record carries it (octahedral), as the pixels
            // evaluate the cell target.
            float t = regir_cell_target(v.position, v.kind, oct_decode(oct_encode(v.normal)), v.flux, vpl_r2(v.yuksel_r2, p), centre, rc, p);
            float w = q > 0.0 ? t * inv_k / q : 0.0;
            if (stream_update(st, i, w, t, rand(rng))) {
                chosen_vpl = v;
            }
        }
        // W = sum w / p^_c(y); an empty or non-finite one is 0 (stream_finish).
        Reservoir r = stream_finish(st);
        float ucw = r.ucw;
        GridEntry entry;
        if (reservoir_valid(r)) {
            VplCandidate c = vpl_candidate(chosen_vpl, r.vpl);
            entry.position = c.position;
            entry.vpl_kind = c.vpl_kind;
            entry.flux = c.flux;
            entry.normal_oct = c.normal_oct;
            sum += st.w_sum;
        } else {
            ucw = 0.0;
            entry.position = vec3(0.0);
            entry.vpl_kind = 0u;
            entry.flux = vec3(0.0);
            entry.normal_oct = 0u;
        }
        if (frame.debug_poison == POISON_REGIR_BUILD && e == 1u) {
            entry.flux = vec3(poison_nan());  // tests of --check-finite only
        }
        entry.ucw = ucw;
        entry._pad0 = 0u;
        entry._pad1 = 0u;
        entry._pad2 = 0u;
        entries[slot] = entry;
    }
    s_sum[lane] = sum;
    barrier();
    if (lane == 0u) {
        float total = 0.0;
        for (uint l = 0u; l < REGIR_WORKGROUP; ++l) {
            total += s_sum[l];
        }
        float s_new = total / float(g.entries);
        if (!(s_new <= 3.0e38)) {
            s_new = 0.0;
        }
        // The previous build's S becomes the one pixels read this frame.
        cells[cell] = uvec4(s_record.x, frame.frame_index + 1u, floatBitsToUint(s_new), s_record.z);
    }
}
