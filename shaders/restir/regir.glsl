// The world-space grid of presampled VPLs (ReGIR, Boksansky et al. 2021; RTXDI's ReGIR), as
// regir_build fills it and restir_initial reads it. Binding-free: the passes do the loads and stores.
//
// The grid covers the scene's bounds with GridParams.cells^3 cells. Each cell holds `entries`
// entries; an entry is one RIS sample (y, W) over `entry_candidates` candidates from the source pdf
// q (uniform or power) with the *cell target* p^_c below. A pixel takes some of its RIS candidates
// from its cell's entries (generalised RIS, Lin et al. 2022: a candidate's weight is
// m(y) p^(y) W_y, W_y an unbiased contribution weight) and the rest from q, with balance-heuristic
// weights between the two sources in which the grid's density is replaced by the pseudo-density
// p^_c(x) / S, S the cell's normalisation estimated by its previous build (independent of this
// frame's entries, so any value keeps the weights summing to one and the estimator unbiased).
//
// The cell target bounds, over the cell's bounding sphere (centre c, radius rc), the renderer's
// unshadowed target (vpl.glsl) except for the receiver's cosine and albedo (both at most 1): the
// emission cosine at the sphere's nearest possible direction and the attenuation at its nearest
// distance. So p^_c(y) > 0 wherever p^(y) > 0 at any receiver in the cell, which the pure-grid case
// (no candidate from q) needs to be unbiased; with candidates from q the MIS weights need only the
// weights' sum. The bound is examples/regir_study.rs's cell_target (with the normal bins off).
#ifndef REGIR_GLSL
#define REGIR_GLSL

#include "../common/types.glsl"
#include "vpl.glsl"
#include "../lib/finite.glsl"

// The flat index of the cell holding x, or -1 outside the grid (or no grid).
int regir_cell(GridParams g, vec3 x) {
    if (g.cells == 0u) {
        return -1;
    }
    vec3 c = floor((x - g.lo) / g.cell_size);
    if (any(lessThan(c, vec3(0.0))) || any(greaterThanEqual(c, vec3(float(g.cells)))) || !is_finite(c)) {
        return -1;
    }
    uvec3 u = uvec3(c);
    return int((u.z * g.cells + u.y) * g.cells + u.x);
}

// The cell's integer coordinates from its flat index.
uvec3 regir_cell_coords(GridParams g, uint cell) {
    return uvec3(cell % g.cells, (cell / g.cells) % g.cells, cell / (g.cells * g.cells));
}

vec3 regir_cell_centre(GridParams g, uint cell) {
    return g.lo + (vec3(regir_cell_coords(g, cell)) + 0.5) * g.cell_size;
}

float regir_cell_radius(GridParams g) {
    return 0.5 * length(g.cell_size);
}

// p^_c: the cell target of a VPL (position y, kind, unit normal ny, flux, Yuksel r2 as the pixel's
// target uses it: vpl_r2) for the cell of centre c and bounding radius rc. Zero only where no point
// of the sphere can receive the VPL's light (behind its surface, or its kind masked out).
float regir_cell_target(vec3 y, uint kind, vec3 ny, vec3 flux, float r2, vec3 c, float rc, VplParams p) {
    if (!vpl_kind_enabled(kind, p.kind_mask)) {
        return 0.0;
    }
    vec3 to_c = c - y;
    float dc = length(to_c);
    float dmin = max(dc - rc, 0.0);
    float emit;
    if (kind == VPL_DIRECT_POINT) {
        emit = 0.25;
    } else if (dc <= rc) {
        emit = 1.0;
    } else {
        // For x in the sphere, ny.(x - y) <= ny.to_c + rc and |x - y| >= dmin.
        emit = clamp((dot(ny, to_c) + rc) / max(dmin, 1e-30), 0.0, 1.0);
    }
    if (!(emit > 0.0)) {
        return 0.0;
    }
    // Inverse square would be unbounded at dmin = 0: there the attenuation is capped at the one of
    // a tenth of the cell radius (any positive value keeps the support).
    float d2 = p.attenuation == ATTENUATION_YUKSEL ? dmin * dmin : max(dmin * dmin, 0.01 * rc * rc);
    float t = luminance(flux) * INV_PI * INV_PI * emit * vpl_attenuation(d2, p.attenuation, r2);
    // Overflow clamps (the support must stay); a NaN (0 * inf at degenerate scales) counts as 0.
    // Tested on the bits (lib/finite.glsl: isnan may fold to false).
    if (!is_finite(t)) {
        return floatBitsToUint(t) == 0x7F800000u ? 3.0e38 : 0.0;
    }
    return min(t, 3.0e38);
}

// The grid source's pseudo-density at a candidate: p^_c / S (S <= 0: no estimate yet, 0).
float regir_pseudo_pdf(float cell_target, float inv_norm) {
    return cell_target * inv_norm;
}

#endif
