// restir_initial's per-pixel work, shared by restir_initial.comp and restir_initial_temporal.comp
// (which fuses it with the temporal merge). Binding-free: the .comp files declare the bindings and
// pass their resources in.
//
// Per pixel, resampled importance sampling over the VPL set (Talbot 2005).
// M candidates from the source pdf (uniform, or proportional to lum(flux) through the VPL alias
// table), target p^ = lum of the unshadowed contribution, one chosen with probability
// w_j / sum w, w_j = p^(i_j) / (M p(i_j)); W = sum w / p^(y). With one uniform candidate this is
// uniform sampling exactly (W = N). Optionally the chosen sample is shadow-tested and the
// reservoir zeroed when occluded (then the target includes visibility).
// Shared by the uniform, ris and restir modes.
// Presampled (tile_count > 0): the candidates are consecutive entries, from a random start, of one
// random vpl_presample tile per pixel. Every tile entry is an independent draw from the source pdf,
// so each candidate is distributed as p and the M of a pixel are independent: the same estimator,
// reading 128 x 32 KB of tiles instead of the whole VPL buffer. (One tile per workgroup reads less
// memory still, but neighbours then share candidates and spatial reuse loses: +47% accumulated
// ReSTIR error at 16 frames on the Cornell box, against +12% with a tile per pixel.)
#ifndef RESTIR_INITIAL_GLSL
#define RESTIR_INITIAL_GLSL

#include "../common/vpl_target.glsl"
#include "../lib/random.glsl"
#include "../restir/reservoir.glsl"
#include "../common/texel_records.glsl"

const uint SALT_INITIAL = 0x7269u;

// Streams candidate VPL `i` (target t, flux Phi) into the reservoir with the RIS weight
// t / (M p(i)), p the source pdf: 1/N, or lum(Phi) / sum lum for the power source.
void initial_offer(inout ReservoirStream st, uint i, float t, vec3 flux, VplParams p, float u) {
    float source_pdf = p.source == 1u ? luminance(flux) / p.total_vpl_lum : 1.0 / float(p.vpl_count);
    float w = source_pdf > 0.0 ? t * (1.0 / float(p.candidates)) / source_pdf : 0.0;
    stream_update(st, i, w, t, u);
}

// The initial reservoir of `pixel`, whose surface is `s` (a hit or not). `tile_count`: presampled
// tiles in `tiles` (0: draw from `vpls`, through `vpl_alias` for the power source). Adds the
// shadow rays it traced to `rays`.
Reservoir initial_reservoir(uvec2 pixel, Surface s, VplParams p, uint tile_count, utextureBuffer vpls, utextureBuffer vpl_alias,
                            utextureBuffer tiles, inout uint rays) {
    if (s.offset_scale < 0.0 || p.vpl_count == 0u || p.candidates == 0u) {
        return reservoir_empty(1.0);
    }
    Rng rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_INITIAL);
    ReservoirStream st = stream_begin();
    if (tile_count > 0u) {
        uint tile = rand_index(rng, tile_count);
        uint base = tile * PRESAMPLE_TILE_SIZE;
        uint start = rand_index(rng, PRESAMPLE_TILE_SIZE);
        for (uint j = 0u; j < p.candidates; ++j) {
            VplCandidate c = candidate_texels(tiles, base + ((start + j) & (PRESAMPLE_TILE_SIZE - 1u)));
            // A per-VPL radius costs one extra read of the full record (off by default).
            float r2 = (p.flags & VPL_FLAG_PER_VPL_RADIUS) != 0u ? vpl_texels(vpls, candidate_index(c)).yuksel_r2 : p.yuksel_r2;
            float t = candidate_target(c, r2, s.position, s.shading_normal, s.geometric_normal, s.albedo, p);
            initial_offer(st, candidate_index(c), t, c.flux, p, rand(rng));
        }
    } else {
        for (uint j = 0u; j < p.candidates; ++j) {
            uint i = rand_index(rng, p.vpl_count);
            if (p.source == 1u) {
                AliasEntry e = alias_texels(vpl_alias, i);
                i = alias_resolve(i, e.keep, e.alias, rand(rng));
            }
            Vpl v = vpl_texels(vpls, i);
            float t = vpl_target(v, s.position, s.shading_normal, s.geometric_normal, s.albedo, p);
            initial_offer(st, i, t, v.flux, p, rand(rng));
        }
    }
    st.confidence = 1.0;
    Reservoir r = stream_finish(st);
    if (reservoir_valid(r) && (p.flags & VPL_FLAG_INITIAL_VISIBILITY) != 0u) {
        rays += 1u;
        if (!vpl_visible(s, vpl_texels(vpls, r.vpl))) {
            r = reservoir_empty(1.0);
        }
    }
    return r;
}

#endif
