// vpl_shade: the pixel's estimate from its final reservoir (vpl_shade.glsl says how). Also writes
// the reservoir debug views. Shared by the uniform, ris and restir modes; restir_spatial_shade
// runs the same estimate fused with the last spatial pass.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "vpl_shade.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;
#endif
#include "../lib/dispatch.glsl"

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2) uniform utextureBuffer reservoirs;  // Reservoir, 1 texel each
layout(set = 1, binding = 3, std430) writeonly buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 4, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"
#include "../common/poison.glsl"

layout(push_constant) uniform Push {
    VplParams params;
    uint view;  // SHADE_VIEW_*
    float normal_threshold;  // restir_temporal's history tests, for the motion view
    float depth_threshold;
} pc;

// The motion view: the reprojection restir_temporal makes (same projection, same tests).
vec3 motion_view(uvec2 pixel, Surface s) {
    vec3 q = project_to_previous_frame(s.position);
    vec2 motion = q.xy - (vec2(pixel) + 0.5);
    ivec2 pq;
    if (!previous_pixel(q, pq)) {
        return vec3(motion, -1.0);
    }
    Surface sp = surface_texels(surfaces, prev_surface_slot(uint(pq.y) * frame.width + uint(pq.x)));
    if (sp.offset_scale < 0.0
        || !same_surface(s.shading_normal, q.z, sp.shading_normal, sp.view_depth, pc.normal_threshold, pc.depth_threshold)) {
        return vec3(motion, -1.0);
    }
    return vec3(motion, length(sp.position - s.position) / max(s.view_depth, 1e-30));
}

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    if (shade_poisoned(frame.debug_poison, pixel)) {
        samples[index] = poison_sample();
        return;
    }
    Surface s = surface_texels(surfaces, surface_slot(index));
    VplParams p = pc.params;
    if (s.offset_scale < 0.0) {
        samples[index] = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    Reservoir r = reservoir_texels(reservoirs, index);
    bool valid = reservoir_valid(r);
    if (pc.view == SHADE_VIEW_RESERVOIR_W) {
        samples[index] = vec4(vec3(r.ucw), 1.0);
        return;
    }
    if (pc.view == SHADE_VIEW_RESERVOIR_M) {
        samples[index] = vec4(vec3(r.confidence), 1.0);
        return;
    }
    if (pc.view == SHADE_VIEW_MOTION) {
        samples[index] = vec4(motion_view(pixel, s), 1.0);
        return;
    }
    if (pc.view == SHADE_VIEW_VPL_KIND) {
        vec3 colour = vec3(0.0);
        if (valid) {
            uint kind = vpl_texels(vpls, r.vpl).kind;
            colour = kind == VPL_INDIRECT ? vec3(1.0, 0.1, 0.05) : kind == VPL_DIRECT_POINT ? vec3(0.1, 0.9, 1.0) : vec3(0.1, 0.25, 1.0);
        }
        samples[index] = vec4(colour, 1.0);
        return;
    }
    uint rays = 0u;
    vec3 radiance = shade_estimate(s, r, p, vpls, rays);
    samples[index] = vec4(radiance, 1.0);
    count_rays(RAYS_SHADE, rays);
}
