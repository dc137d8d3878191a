// vpl_presample: RTXDI-style light presampling. Each frame fills `tiles` tiles of
// PRESAMPLE_TILE_SIZE VplCandidates, every entry an independent draw from the RIS source pdf p
// (uniform: 1/N; power: lum(Phi_i) / sum lum(Phi) through the alias table). restir_initial then
// reads each pixel's candidates from one random tile (32 KB; all tiles 4 MB) instead of from the
// whole VPL buffer at random. Each entry is distributed exactly as p and independent of the pixel's
// choice of entries, so the per-pixel RIS estimator stays unbiased with the same source pdf (only
// neighbouring pixels' candidates become correlated within a frame).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/scene.glsl"
#include "../lib/random.glsl"
#include "../lib/sampling.glsl"
#include "../restir/vpl.glsl"
#include "../common/texel_records.glsl"
#include "../common/poison.glsl"

layout(local_size_x = 64) in;
// after the local size: dispatch_index() reads gl_WorkGroupSize
#include "../lib/dispatch.glsl"

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpl_alias;  // AliasEntry, RG32UI
layout(set = 1, binding = 2, std430) writeonly buffer Tiles { VplCandidate tiles[]; };

layout(push_constant) uniform Push {
    VplParams params;
    uint tiles;
} pc;

const uint SALT_PRESAMPLE = 0x7073u;

void main() {
    uint e = dispatch_index();
    if (e >= pc.tiles * PRESAMPLE_TILE_SIZE || pc.params.vpl_count == 0u) {
        return;
    }
    Rng rng = rng_init(e, frame.frame_index, frame.seed, SALT_PRESAMPLE);
    uint i = rand_index(rng, pc.params.vpl_count);
    if (pc.params.source == 1u) {
        AliasEntry a = alias_texels(vpl_alias, i);
        i = alias_resolve(i, a.keep, a.alias, rng_next(rng));
    }
    VplCandidate c = vpl_candidate(vpl_texels(vpls, i), i);
    if (frame.debug_poison == POISON_VPL_PRESAMPLE && e == 1u) {
        c.flux = vec3(poison_nan());  // tests of --check-finite only
    }
    tiles[e] = c;
}
