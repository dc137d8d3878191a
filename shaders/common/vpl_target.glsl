// The target function of the VPL passes at a G-buffer surface, with or without visibility. Every
// pass evaluates p^ through this one function, so a sample whose target was positive at a pixel
// (visibility included) is visible from it when re-evaluated: same origin, same ray, same answer.
// Uses set 0 (the TLAS) through segment_visible (trace.glsl); the passes load surfaces and VPLs themselves.
#ifndef VPL_TARGET_GLSL
#define VPL_TARGET_GLSL

#include "trace.glsl"
#include "../restir/vpl.glsl"

// Shadow ray from the surface (offset along its geometric normal) to the VPL (already offset off
// its own surface by the photon pass; a point light's VPL sits at the light, which may lie in a
// surface: segment_visible_to_point).
bool vpl_visible(Surface s, Vpl v) {
    vec3 from = offset_ray(s.position, s.geometric_normal, s.offset_scale);
    return v.kind == VPL_DIRECT_POINT ? segment_visible_to_point(from, v.position) : segment_visible(from, v.position);
}

vec3 surface_vpl_contribution(Surface s, Vpl v, VplParams p) {
    return vpl_contribution(v, s.position, s.shading_normal, s.geometric_normal, s.albedo, p);
}

// p^(y) at surface s: lum of the unshadowed contribution, times V when `with_visibility` (one
// shadow ray, counted in `rays`, only when the unshadowed value is positive).
float surface_vpl_target(Surface s, Vpl v, VplParams p, bool with_visibility, inout uint rays) {
    if (s.offset_scale < 0.0) {
        return 0.0;
    }
    float t = vpl_target(v, s.position, s.shading_normal, s.geometric_normal, s.albedo, p);
    if (t > 0.0 && with_visibility) {
        rays += 1u;
        if (!vpl_visible(s, v)) {
            t = 0.0;
        }
    }
    return t;
}

#endif
