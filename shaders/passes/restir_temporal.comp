// restir_temporal: merges this frame's initial reservoir (canonical) with the previous frame's
// final reservoir at the reprojected pixel: where this pixel's surface point appeared in the
// previous camera (identity for a still camera). History is rejected when that point was off
// screen, behind the previous camera, or covered by another surface there (normal and depth tests,
// as in spatial reuse): a disocclusion. The history's confidence is capped at mcap times the
// canonical's. Targets are evaluated at this frame's pixel.
//  - biased: confidence weights M_k / sum M, targets without visibility;
//  - unbiased: the generalised balance heuristic over the two techniques (Lin et al. 2022): the
//    history's technique is evaluated on the previous frame's surface at the reprojected pixel,
//    with targets that include visibility when the initial samples were shadow-tested. When the
//    G-buffer was not traced again this frame (still camera, no jitter) both techniques have the
//    same target, so the heuristic reduces to confidence weights and the history's sample is known
//    visible (its target there was positive).
// With --boiling-filter S > 0, RTXDI's boiling filter then drops reservoirs whose weight sum is
// more than 10/S - 9 times the mean non-zero weight sum of their 8x8 workgroup (biased).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/vpl_target.glsl"
#include "../lib/random.glsl"
#include "../restir/reservoir.glsl"
#include "../common/texel_records.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Both halves of the G-buffer ping-pong: surface_slot() and prev_surface_slot() pick them.
// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, 5 texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2, std430) buffer ReservoirCurrent { Reservoir reservoirs[]; };
layout(set = 1, binding = 3) uniform utextureBuffer history;  // Reservoir, 1 texel each
layout(set = 1, binding = 4, std430) buffer RayCounter { uint ray_count[]; };

layout(push_constant) uniform Push {
    VplParams params;
    float mcap;
    float normal_threshold;
    float depth_threshold;
    float boiling_strength;  // 0: off
} pc;

const uint SALT_TEMPORAL = 0x746du;

// The temporal merge of pixel `index`: true (with `result`) when it changes the canonical
// reservoir `rc`; false when there is no history to merge (result = rc).
bool temporal_merge(uvec2 pixel, uint index, Surface s, Reservoir rc, out Reservoir result, inout uint rays) {
    result = rc;
    VplParams p = pc.params;
    bool same_domain = (p.flags & VPL_FLAG_SAME_DOMAIN) != 0u;

    // The reprojected pixel and its previous surface.
    uint prev_index = index;
    if (!same_domain) {
        vec3 q = project_to_previous_frame(s.position);
        ivec2 pq;
        if (!previous_pixel(q, pq)) {
            return false;  // off screen or behind the previous camera: no history
        }
        prev_index = uint(pq.y) * frame.width + uint(pq.x);
        Surface sp = surface_texels(surfaces, prev_surface_slot(prev_index));
        if (sp.hit_t < 0.0
            || !same_surface(s.shading_normal, q.z, sp.shading_normal, sp.view_depth, pc.normal_threshold, pc.depth_threshold)) {
            return false;  // disoccluded: another surface (or none) was there
        }
    }
    Reservoir rh = reservoir_texels(history, prev_index);
    float mc = rc.confidence;
    float mh = min(rh.confidence, pc.mcap * mc);
    if (!(mh > 0.0)) {
        return false;
    }
    bool unbiased = (p.flags & VPL_FLAG_UNBIASED) != 0u;
    bool visible_targets = unbiased && (p.flags & VPL_FLAG_INITIAL_VISIBILITY) != 0u;

    // Targets at this pixel: the canonical's was computed here; the history's sample is evaluated
    // here (visible for sure when unbiased and the surface point is the same).
    float pc_yc = reservoir_valid(rc) ? rc.target : 0.0;
    float pc_yh = 0.0;
    if (reservoir_valid(rh)) {
        pc_yh = surface_vpl_target(s, vpl_texels(vpls, rh.vpl), p, visible_targets && !same_domain, rays);
    }

    float m_c = mc / (mc + mh);
    float m_h = mh / (mc + mh);
    if (unbiased && !same_domain) {
        Surface sp = surface_texels(surfaces, prev_surface_slot(prev_index));
        float ph_yc = reservoir_valid(rc) ? surface_vpl_target(sp, vpl_texels(vpls, rc.vpl), p, visible_targets, rays) : 0.0;
        float ph_yh = reservoir_valid(rh) ? rh.target : 0.0;
        float dc = mc * pc_yc + mh * ph_yc;
        float dh = mh * ph_yh + mc * pc_yh;
        m_c = dc > 0.0 ? mc * pc_yc / dc : 0.0;
        m_h = dh > 0.0 ? mh * ph_yh / dh : 0.0;
    }

    Rng rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_TEMPORAL);
    ReservoirStream st = stream_begin();
    if (reservoir_valid(rc)) {
        stream_update(st, rc.vpl, m_c * pc_yc * rc.ucw, pc_yc, rand(rng));
    }
    if (reservoir_valid(rh)) {
        stream_update(st, rh.vpl, m_h * pc_yh * rh.ucw, pc_yh, rand(rng));
    }
    st.confidence = mc + mh;
    result = stream_finish(st);
    return true;
}

shared float group_w[64];
shared uint group_n[64];

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    bool inside = pixel.x < frame.width && pixel.y < frame.height;
    uint index = inside ? pixel.y * frame.width + pixel.x : 0u;
    uint rays = 0u;
    bool changed = false;
    Reservoir r = reservoir_empty(0.0);
    if (inside) {
        Surface s = surface_texels(surfaces, surface_slot(index));
        if (s.hit_t >= 0.0) {
            changed = temporal_merge(pixel, index, s, reservoirs[index], r, rays);
        }
    }
    // The boiling filter: every invocation of the workgroup takes part in the reduction.
    if (pc.boiling_strength > 0.0) {
        float w = reservoir_valid(r) ? r.ucw * r.target : 0.0;
        uint lid = gl_LocalInvocationIndex;
        group_w[lid] = w;
        group_n[lid] = w > 0.0 ? 1u : 0u;
        barrier();
        for (uint stride = 32u; stride > 0u; stride >>= 1u) {
            if (lid < stride) {
                group_w[lid] += group_w[lid + stride];
                group_n[lid] += group_n[lid + stride];
            }
            barrier();
        }
        float mean = group_n[0] > 0u ? group_w[0] / float(group_n[0]) : 0.0;
        if (inside && boiling_rejects(w, mean, pc.boiling_strength)) {
            r = reservoir_empty(r.confidence);
            changed = true;
        }
    }
    if (inside && changed) {
        reservoirs[index] = r;
    }
    if (rays > 0u) {
        atomicAdd(ray_count[RAYS_TEMPORAL], rays);
    }
}
