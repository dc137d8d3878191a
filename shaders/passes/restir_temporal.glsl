// restir_temporal's per-pixel work, shared by restir_temporal.comp and restir_initial_temporal.comp
// (which fuses it with the initial RIS). Binding-free: the .comp files declare the bindings and
// pass their resources in.
//
// Merges this frame's initial reservoir (canonical) with the previous frame's
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
// With --boiling-filter S > 0, restir_boiling then filters the merged reservoirs.
#ifndef RESTIR_TEMPORAL_GLSL
#define RESTIR_TEMPORAL_GLSL

#include "../common/vpl_target.glsl"
#include "../lib/random.glsl"
#include "../restir/reservoir.glsl"
#include "../common/texel_records.glsl"

const uint SALT_TEMPORAL = 0x746du;

// restir_temporal's settings (its push constants, less the VPL parameters).
struct TemporalReuse {
    float mcap;
    float normal_threshold;
    float depth_threshold;
};

// Whether pixel `index` (surface `s`, a hit) has history that the temporal merge takes: the
// reprojected pixel `prev_index` shows the same surface `sp` in the previous frame (`s` itself
// when the G-buffer was not traced again) and its reservoir `rh` has positive confidence. Depends
// on the surfaces and the history alone, never on this frame's samples, so restir_initial may
// choose its candidate count by it without bias.
bool temporal_history(uint index, Surface s, VplParams p, TemporalReuse t, utextureBuffer surfaces, utextureBuffer history,
                      out uint prev_index, out Reservoir rh, out Surface sp) {
    prev_index = index;
    rh = reservoir_empty(0.0);
    sp = s;
    if ((p.flags & VPL_FLAG_SAME_DOMAIN) == 0u) {
        vec3 q = project_to_previous_frame(s.position);
        ivec2 pq;
        if (!previous_pixel(q, pq)) {
            return false;  // off screen or behind the previous camera: no history
        }
        prev_index = uint(pq.y) * frame.width + uint(pq.x);
        sp = surface_texels(surfaces, prev_surface_slot(prev_index));
        if (sp.offset_scale < 0.0
            || !same_surface(s.shading_normal, q.z, sp.shading_normal, sp.view_depth, t.normal_threshold, t.depth_threshold)) {
            return false;  // disoccluded: another surface (or none) was there
        }
    }
    rh = reservoir_texels(history, prev_index);
    // The canonical (initial) reservoir's confidence is 1, so the history's capped one is
    // min(confidence, mcap).
    return min(rh.confidence, t.mcap) > 0.0;
}

// The temporal merge of pixel `pixel` (surface `s`, a hit) with the history temporal_history
// found (`rh`, on the previous frame's surface `sp`, which it read): the merged reservoir, from
// the canonical reservoir `rc`.
Reservoir temporal_merge_history(uvec2 pixel, Surface s, Reservoir rc, Reservoir rh, Surface sp, VplParams p, TemporalReuse t,
                                 utextureBuffer vpls, inout uint rays) {
    bool same_domain = (p.flags & VPL_FLAG_SAME_DOMAIN) != 0u;
    float mc = rc.confidence;
    float mh = min(rh.confidence, t.mcap * mc);
    if (!(mh > 0.0)) {
        return rc;
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
    return stream_finish(st);
}

// temporal_history, then temporal_merge_history: true (with `result`) when there was history to
// merge; false when there was none (result = rc). `history`: the previous frame's final reservoirs.
bool temporal_merge(uvec2 pixel, uint index, Surface s, Reservoir rc, VplParams p, TemporalReuse t, utextureBuffer surfaces,
                    utextureBuffer vpls, utextureBuffer history, out Reservoir result, inout uint rays) {
    uint prev_index;
    Reservoir rh;
    Surface sp;
    if (!temporal_history(index, s, p, t, surfaces, history, prev_index, rh, sp)) {
        result = rc;
        return false;
    }
    result = temporal_merge_history(pixel, s, rc, rh, sp, p, t, vpls, rays);
    return true;
}

#endif
