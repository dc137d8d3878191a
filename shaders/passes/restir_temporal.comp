// restir_temporal: merges this frame's initial reservoir with the previous frame's final one at
// the reprojected pixel (restir_temporal.glsl says how), then applies the boiling filter when
// --boiling-filter is on. restir_initial_temporal runs the same functions fused with the initial
// RIS.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "restir_temporal.glsl"

// Fixed 8x8: the boiling filter reduces over 64 invocations.
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

layout(push_constant) uniform Push {
    VplParams params;
    float mcap;
    float normal_threshold;
    float depth_threshold;
    float boiling_strength;  // 0: off
} pc;

void main() {
    uvec2 pixel = dispatch_pixel();
    bool inside = pixel.x < frame.width && pixel.y < frame.height;
    uint index = inside ? pixel.y * frame.width + pixel.x : 0u;
    uint rays = 0u;
    bool changed = false;
    Reservoir r = reservoir_empty(0.0);
    if (inside) {
        Surface s = surface_texels(surfaces, surface_slot(index));
        if (s.offset_scale >= 0.0) {
            TemporalReuse t = TemporalReuse(pc.mcap, pc.normal_threshold, pc.depth_threshold);
            changed = temporal_merge(pixel, index, s, reservoirs[index], pc.params, t, surfaces, vpls, history, r, rays);
        }
    }
    // Uniform control flow: every invocation of the workgroup takes part in the reduction.
    if (pc.boiling_strength > 0.0 && boiling_filter_rejects(r, pc.boiling_strength) && inside) {
        r = reservoir_empty(r.confidence);
        changed = true;
    }
    if (inside && changed) {
        reservoirs[index] = r;
    }
    if (rays > 0u) {
        atomicAdd(ray_count[RAYS_TEMPORAL], rays);
    }
}
