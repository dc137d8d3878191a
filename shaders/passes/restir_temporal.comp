// restir_temporal: merges this frame's initial reservoir with the previous frame's final one at
// the reprojected pixel (restir_temporal.glsl says how). restir_initial_temporal runs the same
// functions fused with the initial RIS; restir_boiling filters the result when --boiling-filter is
// on.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "restir_temporal.glsl"

// Fixed 8x8 (restir_temporal does not take --workgroup; docs/workgroups.md measured it at 8x8).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8) in;
#endif
#include "../lib/dispatch.glsl"

// Both halves of the G-buffer ping-pong: surface_slot() and prev_surface_slot() pick them.
// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2, std430) buffer ReservoirCurrent { Reservoir reservoirs[]; };
layout(set = 1, binding = 3) uniform utextureBuffer history;  // Reservoir, 1 texel each
layout(set = 1, binding = 4, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"

layout(push_constant) uniform Push {
    VplParams params;
    float mcap;
    float normal_threshold;
    float depth_threshold;
} pc;

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    uint rays = 0u;
    Surface s = surface_texels(surfaces, surface_slot(index));
    if (s.offset_scale >= 0.0) {
        TemporalReuse t = TemporalReuse(pc.mcap, pc.normal_threshold, pc.depth_threshold);
        Reservoir r;
        if (temporal_merge(pixel, index, s, reservoirs[index], pc.params, t, surfaces, vpls, history, r, rays)) {
            reservoirs[index] = r;
        }
    }
    count_rays(RAYS_TEMPORAL, rays);
}
