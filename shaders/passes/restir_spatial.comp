// restir_spatial: merges each pixel's reservoir with random neighbours' reservoirs
// (restir_spatial.glsl says how); one dispatch per spatial pass. restir_spatial_shade runs the
// same function for the last pass, fused with vpl_shade.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "restir_spatial.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;
#endif
#include "../lib/dispatch.glsl"

// The reuse's kind, fixed per pipeline (specialisation constants 2 and 3, the pass desc's
// `constants`; the renderer sets them from the VPL flags it pushes): unbiased pairwise MIS, and
// visibility in its targets. The driver then compiles only the branch the settings run (on
// lavapipe the other branches, inlined ray query included, cost 15-21 % of this pass).
layout(constant_id = 2) const bool UNBIASED = true;
layout(constant_id = 3) const bool VISIBLE_TARGETS = false;

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2) uniform utextureBuffer src;  // Reservoir, 1 texel each
layout(set = 1, binding = 3, std430) writeonly buffer ReservoirOut { Reservoir dst[]; };
layout(set = 1, binding = 4, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"

layout(push_constant) uniform Push {
    VplParams params;
    uint neighbours;
    uint neighbours_without_history;
    float radius;
    float normal_threshold;
    float depth_threshold;
    uint pass_index;
} pc;

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    Surface s = surface_texels(surfaces, surface_slot(index));
    Reservoir rc = reservoir_texels(src, index);
    if (s.offset_scale < 0.0) {
        dst[index] = rc;
        return;
    }
    uint rays = 0u;
    SpatialReuse sr = SpatialReuse(pc.neighbours, pc.neighbours_without_history, pc.radius, pc.normal_threshold, pc.depth_threshold, pc.pass_index);
    dst[index] = spatial_merge(pixel, s, rc, pc.params, sr, surfaces, vpls, src, UNBIASED, VISIBLE_TARGETS, rays);
    count_rays(RAYS_SPATIAL, rays);
}
