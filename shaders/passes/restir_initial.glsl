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
// With the ReGIR grid (the passes' `grid` variant, REGIR_GRID; GridParams.grid_candidates > 0;
// regir.glsl): the first of the M candidates
// are consecutive entries of the pixel's grid cell, the rest come from the source pdf as above, and
// every candidate's weight is m(y) p^(y) W(y) with the balance heuristic between the two sources
// (the grid's density replaced by the cell target over the cell's previous normalisation S; 1/M
// weights before the cell has one). The default variant holds none of the grid's code; in a cell
// not built this frame the grid variant's code and random stream are those above.
#ifndef RESTIR_INITIAL_GLSL
#define RESTIR_INITIAL_GLSL

#include "../common/vpl_target.glsl"
#include "../lib/random.glsl"
#include "../restir/reservoir.glsl"
#include "../common/texel_records.glsl"
#include "../restir/regir.glsl"

const uint SALT_INITIAL = 0x7269u;

// The pixel's use of the ReGIR grid (regir.glsl): its cell (-1: none, every candidate from q),
// the cell's bounding sphere, and 1/S of the cell's previous build (0: no estimate, so constant
// MIS weights 1/M).
struct GridPick {
    int cell;
    uint n_grid;
    float inv_norm;
    vec3 centre;
    float radius;
};

GridPick grid_pick(GridParams g, int cell, float norm, VplParams p) {
    GridPick k;
    k.cell = cell;
    k.n_grid = cell >= 0 ? min(g.grid_candidates, p.candidates) : 0u;
    k.inv_norm = k.n_grid > 0u && norm > 0.0 && (g.flags & GRID_FLAG_BALANCE) != 0u ? 1.0 / norm : 0.0;
    k.centre = cell >= 0 ? regir_cell_centre(g, uint(cell)) : vec3(0.0);
    k.radius = regir_cell_radius(g);
    return k;
}

// The RIS weight of a candidate from q (target t, source pdf q, cell target pc): t / (M q) without
// a grid (or without the cell's S: constant weights 1/M); with one, the balance heuristic between
// n_u draws from q and n_g from the grid, whose density is replaced by the pseudo-density pc / S.
float mixed_weight_from_source(float t, float q, float pc, GridPick k, uint n_u, uint m) {
    if (k.inv_norm > 0.0) {
        float denom = float(n_u) * q + float(k.n_grid) * regir_pseudo_pdf(pc, k.inv_norm);
        return denom > 0.0 ? t / denom : 0.0;
    }
    return q > 0.0 ? t * (1.0 / float(m)) / q : 0.0;
}

// The same for a grid entry (contribution weight W): m_g(y) t W / n_g with the balance heuristic's
// m_g, written t W / (n_u q / pg + n_g) so that a huge pseudo-density cannot make inf / inf; or
// t W / M.
float mixed_weight_from_grid(float t, float ucw, float q, float pc, GridPick k, uint n_u, uint m) {
    if (n_u == 0u) {
        // The grid alone: m_g = 1 wherever it can sample, whatever the pseudo-density.
        return t * ucw / float(k.n_grid);
    }
    if (k.inv_norm > 0.0) {
        float pg = regir_pseudo_pdf(pc, k.inv_norm);
        return pg > 0.0 ? t * ucw / (float(n_u) * q / pg + float(k.n_grid)) : 0.0;
    }
    return t * ucw / float(m);
}

// The cell target of a candidate at y (its normal as the candidate records carry it, octahedral)
// for its balance-heuristic weight: 0 without the cell's normalisation, and always 0 in the
// default variant, which holds none of the grid's code (build.rs, REGIR_GRID).
float candidate_cell_target(GridPick k, vec3 y, uint kind, uint normal_oct, vec3 flux, float r2, VplParams p) {
#ifdef REGIR_GRID
    return k.inv_norm > 0.0 ? regir_cell_target(y, kind, oct_decode(normal_oct), flux, r2, k.centre, k.radius, p) : 0.0;
#else
    return 0.0;
#endif
}

// The initial reservoir of `pixel`, whose surface is `s` (a hit or not). `tile_count`: presampled
// tiles in `tiles` (0: draw from `vpls`, through `vpl_alias` for the power source). `k` (grid_pick):
// the first k.n_grid candidates come from the pixel's grid cell's entries in `grid_entries`.
// Adds the shadow rays it traced to `rays`.
Reservoir initial_reservoir(uvec2 pixel, Surface s, VplParams p, uint tile_count, utextureBuffer vpls, utextureBuffer vpl_alias,
                            utextureBuffer tiles, GridParams g, GridPick k, utextureBuffer grid_entries, inout uint rays) {
    if (s.offset_scale < 0.0 || p.vpl_count == 0u || p.candidates == 0u) {
        return reservoir_empty(1.0);
    }
    Rng rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_INITIAL);
    ReservoirStream st = stream_begin();
    uint m = p.candidates;
    uint n_u = m - k.n_grid;
    bool per_vpl_r2 = (p.flags & VPL_FLAG_PER_VPL_RADIUS) != 0u;
#ifdef REGIR_GRID
    // Grid candidates (none without a grid or outside it): consecutive entries of the pixel's cell
    // from a random start, as from a presampled tile (the cell's entries are independent draws, so
    // any distinct ones will do; beyond `entries` they wrap).
    uint grid_start = k.n_grid > 0u ? rand_index(rng, g.entries) : 0u;
    for (uint j = 0u; j < k.n_grid; ++j) {
        uint e = uint(k.cell) * g.entries + (grid_start + j) % g.entries;
        float ucw = grid_entry_ucw_texels(grid_entries, e);
        float u = rand(rng);
        if (ucw > 0.0) {
            VplCandidate c = grid_entry_candidate_texels(grid_entries, e);
            uint kind = c.vpl_kind >> CANDIDATE_INDEX_BITS;
            vec3 n = oct_decode(c.normal_oct);
            float r2 = per_vpl_r2 ? vpl_texels(vpls, candidate_index(c)).yuksel_r2 : p.yuksel_r2;
            float t = vpl_target_at(c.position, kind, n, c.flux, r2, s.position, s.shading_normal, s.geometric_normal, s.albedo, p);
            float pc = candidate_cell_target(k, c.position, kind, c.normal_oct, c.flux, r2, p);
            float w = mixed_weight_from_grid(t, ucw, vpl_source_pdf(c.flux, p), pc, k, n_u, m);
            stream_update(st, candidate_index(c), w, t, u);
        }
    }
#endif
    if (tile_count > 0u) {
        uint tile = rand_index(rng, tile_count);
        uint base = tile * PRESAMPLE_TILE_SIZE;
        uint start = rand_index(rng, PRESAMPLE_TILE_SIZE);
        for (uint j = 0u; j < n_u; ++j) {
            VplCandidate c = candidate_texels(tiles, base + ((start + j) & (PRESAMPLE_TILE_SIZE - 1u)));
            // A per-VPL radius costs one extra read of the full record (off by default).
            float r2 = per_vpl_r2 ? vpl_texels(vpls, candidate_index(c)).yuksel_r2 : p.yuksel_r2;
            float t = candidate_target(c, r2, s.position, s.shading_normal, s.geometric_normal, s.albedo, p);
            float pc = candidate_cell_target(k, c.position, c.vpl_kind >> CANDIDATE_INDEX_BITS, c.normal_oct, c.flux, r2, p);
            float w = mixed_weight_from_source(t, vpl_source_pdf(c.flux, p), pc, k, n_u, m);
            stream_update(st, candidate_index(c), w, t, rand(rng));
        }
    } else {
        for (uint j = 0u; j < n_u; ++j) {
            uint i = rand_index(rng, p.vpl_count);
            if (p.source == 1u) {
                AliasEntry e = alias_texels(vpl_alias, i);
                i = alias_resolve(i, e.keep, e.alias, rng_next(rng));
            }
            Vpl v = vpl_texels(vpls, i);
            float t = vpl_target(v, s.position, s.shading_normal, s.geometric_normal, s.albedo, p);
            // The cell target with the normal as the grid's and the tiles' candidate records carry it
            // (octahedral), so that both sources' weights use one function and sum to one exactly.
            float pc = candidate_cell_target(k, v.position, v.kind, oct_encode(v.normal), v.flux, vpl_r2(v.yuksel_r2, p), p);
            float w = mixed_weight_from_source(t, vpl_source_pdf(v.flux, p), pc, k, n_u, m);
            stream_update(st, i, w, t, rand(rng));
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
