// restir_spatial: merges each pixel's reservoir (canonical) with those of up to K random
// neighbours within a disc of `radius` pixels; neighbours whose normal or depth differ too much
// are rejected. Targets are always evaluated at the receiving pixel.
//  - biased: confidence weights M_k / sum M, targets without visibility (no rays);
//  - unbiased: confidence-weighted pairwise MIS (Lin et al. 2022) with the same target everywhere.
//    With --initial-visibility on (off by default) the targets include visibility: two shadow
//    rays per neighbour (receiving pixel -> neighbour's sample, neighbour -> canonical sample).
//    Off: unshadowed targets, no rays here, visibility only in vpl_shade. Either way the converged
//    mean is the brute-force sum.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/vpl_target.glsl"
#include "../lib/random.glsl"
#include "../restir/reservoir.glsl"
#include "../common/texel_records.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, 5 texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2) uniform utextureBuffer src;  // Reservoir, 1 texel each
layout(set = 1, binding = 3, std430) writeonly buffer ReservoirOut { Reservoir dst[]; };
layout(set = 1, binding = 4, std430) buffer RayCounter { uint ray_count[]; };

layout(push_constant) uniform Push {
    VplParams params;
    uint neighbours;
    float radius;
    float normal_threshold;
    float depth_threshold;
    uint pass_index;
} pc;

const uint SALT_SPATIAL = 0x7370u;

// A neighbour of `pixel` from the disc of radius pc.radius (u: two uniforms), accepted when it is
// inside the image, not the pixel itself, and a surface like `s` (normal and depth thresholds).
// The choice depends on geometry only, never on the reservoirs' samples.
bool pick_neighbour(uvec2 pixel, Surface s, vec2 u, out uint qi) {
    ivec2 q = ivec2(pixel) + ivec2(round(sample_concentric_disk(u) * pc.radius));
    qi = 0u;
    if (q.x < 0 || q.y < 0 || q.x >= int(frame.width) || q.y >= int(frame.height) || q == ivec2(pixel)) {
        return false;
    }
    qi = uint(q.y) * frame.width + uint(q.x);
    Surface sq = surface_texels(surfaces, surface_slot(qi));
    return sq.hit_t >= 0.0
        && same_surface(s.shading_normal, s.view_depth, sq.shading_normal, sq.view_depth, pc.normal_threshold, pc.depth_threshold);
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    Surface s = surface_texels(surfaces, surface_slot(index));
    Reservoir rc = reservoir_texels(src, index);
    if (s.hit_t < 0.0) {
        dst[index] = rc;
        return;
    }
    VplParams p = pc.params;
    bool unbiased = (p.flags & VPL_FLAG_UNBIASED) != 0u;
    // Unbiased reuse evaluates every target the way the reservoirs were built: with visibility
    // when the initial samples were shadow-tested, without otherwise.
    bool visible_targets = unbiased && (p.flags & VPL_FLAG_INITIAL_VISIBILITY) != 0u;
    Rng rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_SPATIAL ^ (pc.pass_index << 16));

    uint wanted = min(pc.neighbours, MAX_SPATIAL_NEIGHBOURS);
    bool canonical_valid = reservoir_valid(rc);
    float pc_yc = canonical_valid ? rc.target : 0.0;
    uint rays = 0u;

    if (!unbiased) {
        // Biased: confidence weights M_k / sum M. The common factor 1 / sum M is applied at the
        // end, so one loop suffices: w'_k = M_k p^_x(y_k) W_k, W = sum w' / (sum M p^_x(y)).
        ReservoirStream st = stream_begin();
        float m_total = rc.confidence;
        for (uint j = 0u; j < wanted; ++j) {
            uint qi;
            bool found = pick_neighbour(pixel, s, rand2(rng), qi);
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
        dst[index] = stream_finish(st);
        return;
    }

    // Unbiased: pick the neighbours first, since the pairwise weights need their count and total
    // confidence.
    uint nb[MAX_SPATIAL_NEIGHBOURS];
    uint k = 0u;
    for (uint j = 0u; j < wanted; ++j) {
        uint qi;
        if (!pick_neighbour(pixel, s, rand2(rng), qi)) {
            continue;
        }
        nb[k] = qi;
        k += 1u;
    }
    if (k == 0u) {
        dst[index] = rc;
        return;
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
    dst[index] = stream_finish(st);
    if (rays > 0u) {
        atomicAdd(ray_count[RAYS_SPATIAL], rays);
    }
}
