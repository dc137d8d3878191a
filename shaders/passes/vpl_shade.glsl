// vpl_shade's estimate, shared by vpl_shade.comp and restir_spatial_shade.comp (which fuses it
// with the last spatial pass). Binding-free: the .comp files pass their resources in.
#ifndef VPL_SHADE_GLSL
#define VPL_SHADE_GLSL

#include "../common/vpl_target.glsl"
#include "../restir/reservoir.glsl"
#include "../common/texel_records.glsl"

// The pixel's estimate from its final reservoir `r` at surface `s` (a hit): Le + c_y(x) W, with a
// shadow ray for y (added to `rays`) unless the targets included visibility (unbiased ReSTIR with
// --initial-visibility), where a sample with positive target at x is visible from x.
vec3 shade_estimate(Surface s, Reservoir r, VplParams p, utextureBuffer vpls, inout uint rays) {
    vec3 radiance = (p.kind_mask & KIND_MASK_DIRECT) != 0u ? s.emission : vec3(0.0);
    if (reservoir_valid(r)) {
        Vpl v = vpl_texels(vpls, r.vpl);
        vec3 c = surface_vpl_contribution(s, v, p);
        if (max3(c) > 0.0) {
            bool visible = true;
            bool visible_targets = (p.flags & VPL_FLAG_UNBIASED) != 0u && (p.flags & VPL_FLAG_INITIAL_VISIBILITY) != 0u;
            if (!visible_targets) {
                rays += 1u;
                visible = vpl_visible(s, v);
            }
            if (visible) {
                radiance += c * r.ucw;
            }
        }
    }
    return radiance;
}

#endif
