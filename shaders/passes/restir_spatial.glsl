// restir_spatial's per-pixel work, shared by restir_spatial.comp and restir_spatial_shade.comp
// (which fuses the last spatial pass with vpl_shade). Binding-free: the .comp files declare the
// bindings and pass their resources in.
//
// Merges each pixel's reservoir (canonical) with those of up to K random
// neighbours within a disc of `radius` pixels; neighbours whose normal or depth differ too much
// are rejected. Targets are always evaluated at the receiving pixel.
//  - biased: confidence weights M_k / sum M, targets without visibility (no rays);
//  - unbiased: confidence-weighted pairwise MIS (Lin et al. 2022) with the same target everywhere.
//    With --initial-visibility on (off by default) the targets include visibility: two shadow
//    rays per neighbour (receiving pixel -> neighbour's sample, neighbour -> canonical sample).
//    Off: unshadowed targets, no rays here, visibility only in vpl_shade. Either way the converged
//    mean is the brute-force sum.
#ifndef RESTIR_SPATIAL_GLSL
#define RESTIR_SPATIAL_GLSL

#include "../common/vpl_target.glsl"
#include "../lib/random.glsl"
#include "../restir/reservoir.glsl"
#include "../common/texel_records.glsl"

const uint SALT_SPATIAL = 0x7370u;

// restir_spatial's settings (its push constants, less the VPL parameters).
struct SpatialReuse {
    uint neighbours;
    // Neighbours of a pixel whose reservoir has no temporal history (confidence 1: disoccluded,
    // off screen in the previous frame, or a whole frame after a camera jump). A frame displayed
    // alone draws fewer neighbours where history is, but such a pixel, like a first frame, has only
    // its own candidates and its neighbours: it keeps the still count. Depends on the confidence
    // alone, never on the samples. The first spatial pass only: in a later one (--spatial-passes 2
    // or more) a pixel's confidence already counts the neighbours it merged, so every pixel with a
    // neighbour found takes `neighbours`.
    uint neighbours_without_history;
    float radius;
    float normal_threshold;
    float depth_threshold;
    uint pass_index;
};

// A neighbour of `pixel` from the disc of radius sr.radius (u: two uniforms), accepted when it is
// inside the image, not the pixel itself, and a surface like `s` (normal and depth thresholds).
// The choice depends on geometry only, never on the reservoirs' samples.
bool pick_neighbour(uvec2 pixel, Surface s, vec2 u, SpatialReuse sr, utextureBuffer surfaces, out uint qi) {
    ivec2 q = ivec2(pixel) + ivec2(round(sample_concentric_disk(u) * sr.radius));
    qi = 0u;
    if (q.x < 0 || q.y < 0 || q.x >= int(frame.width) || q.y >= int(frame.height) || q == ivec2(pixel)) {
        return false;
    }
    qi = uint(q.y) * frame.width + uint(q.x);
    Surface sq = surface_texels(surfaces, surface_slot(qi));
    return sq.offset_scale >= 0.0
        && same_surface(s.shading_normal, s.view_depth, sq.shading_normal, sq.view_depth, sr.normal_threshold, sr.depth_threshold);
}

// The spatial merge of `pixel` (surface `s`, a hit; canonical reservoir `rc`) with the reservoirs
// in `src`. `unbiased`: pairwise MIS (p.flags' VPL_FLAG_UNBIASED); `visible_targets`: unbiased
// reuse evaluates every target the way the reservoirs were built, with visibility when the initial
// samples were shadow-tested (VPL_FLAG_INITIAL_VISIBILITY). The passes give both as
// specialisation constants, so a pipeline holds only the code its settings run. Adds the shadow
// rays it traced to `rays`.
Reservoir spatial_merge(uvec2 pixel, Surface s, Reservoir rc, VplParams p, SpatialReuse sr, utextureBuffer surfaces,
                        utextureBuffer vpls, utextureBuffer src, bool unbiased, bool visible_targets, inout uint rays) {
    Rng rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_SPATIAL ^ (sr.pass_index << 16));

    uint wanted = min(rc.confidence > 1.0 ? sr.neighbours : sr.neighbours_without_history, MAX_SPATIAL_NEIGHBOURS);
    bool canonical_valid = reservoir_valid(rc);
    float pc_yc = canonical_valid ? rc.target : 0.0;

    if (!unbiased) {
        // Biased: confidence weights M_k / sum M. The common factor 1 / sum M is applied at the
        // end, so one loop suffices: w'_k = M_k p^_x(y_k) W_k, W = sum w' / (sum M p^_x(y)).
        ReservoirStream st = stream_begin();
        float m_total = rc.confidence;
        for (uint j = 0u; j < wanted; ++j) {
            uint qi;
            bool found = pick_neighbour(pixel, s, rand2(rng), sr, surfaces, qi);
            float u = rand(rng);
            if (!found) {
                continue;
            }
            Reservoir rn = reservoir_texels(src, qi);
            m_total += rn.confidence;
            if (reservoir_valid(rn)) {
                float pc_yn = surface_vpl_target(s, vpl_texels(vpls, rn.vpl), p, false, rays);
                stream_update(st, rn.vpl, rn.confidence * pc_yn * rn.ucw, pc_yn, u);
            }
        }
        if (canonical_valid) {
            stream_update(st, rc.vpl, rc.confidence * pc_yc * rc.ucw, pc_yc, rand(rng));
        }
        st.w_sum /= m_total;
        st.confidence = m_total;
        return stream_finish(st);
    }

    // Unbiased: pick the neighbours first, since the pairwise weights need their count and total
    // confidence.
    uint nb[MAX_SPATIAL_NEIGHBOURS];
    uint k = 0u;
    for (uint j = 0u; j < wanted; ++j) {
        uint qi;
        if (!pick_neighbour(pixel, s, rand2(rng), sr, surfaces, qi)) {
            continue;
        }
        nb[k] = qi;
        k += 1u;
    }
    if (k == 0u) {
        return rc;
    }

    float mc = rc.confidence;
    float m_total = mc;
    for (uint j = 0u; j < k; ++j) {
        m_total += reservoir_texels(src, nb[j]).confidence;
    }
    Vpl vc;
    if (canonical_valid) {
        vc = vpl_texels(vpls, rc.vpl);
    }
    float m_c_share = mc / float(k);
    float canonical_mis = 0.0;

    ReservoirStream st = stream_begin();
    for (uint j = 0u; j < k; ++j) {
        uint qi = nb[j];
        Reservoir rn = reservoir_texels(src, qi);
        float mn = rn.confidence;
        Surface sq = surface_texels(surfaces, surface_slot(qi));
        // The canonical sample as the neighbour would have produced it.
        float pn_yc = canonical_valid ? surface_vpl_target(sq, vc, p, visible_targets, rays) : 0.0;
        canonical_mis += pairwise_canonical_weight(mn, pn_yc, m_c_share, pc_yc, m_total);
        if (reservoir_valid(rn)) {
            float pc_yn = surface_vpl_target(s, vpl_texels(vpls, rn.vpl), p, visible_targets, rays);
            float m = pairwise_neighbour_weight(mn, rn.target, m_c_share, pc_yn, m_total);
            stream_update(st, rn.vpl, m * pc_yn * rn.ucw, pc_yn, rand(rng));
        }
    }
    if (canonical_valid) {
        stream_update(st, rc.vpl, canonical_mis * pc_yc * rc.ucw, pc_yc, rand(rng));
    }
    st.confidence = m_total;
    return stream_finish(st);
}

#endif
