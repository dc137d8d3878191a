// vpl_shade: the pixel's estimate from its final reservoir: Le + c_y(x) W, with a shadow ray for
// y (none in unbiased ReSTIR with visibility in the targets, where a sample with positive target
// at x is visible from x). Also
// writes the reservoir debug views. Shared by the uniform, ris and restir modes.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/vpl_target.glsl"
#include "../restir/reservoir.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 1, binding = 0, std430) readonly buffer SurfaceBuffer { Surface surfaces[]; };
layout(set = 1, binding = 1, std430) readonly buffer VplBuffer { Vpl vpls[]; };
layout(set = 1, binding = 2, std430) readonly buffer ReservoirIn { Reservoir reservoirs[]; };
layout(set = 1, binding = 3, std430) writeonly buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 4, std430) buffer RayCounter { uint ray_count[]; };

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
    Surface sp = surfaces[prev_surface_slot(uint(pq.y) * frame.width + uint(pq.x))];
    if (sp.hit_t < 0.0
        || !same_surface(s.shading_normal, q.z, sp.shading_normal, sp.view_depth, pc.normal_threshold, pc.depth_threshold)) {
        return vec3(motion, -1.0);
    }
    return vec3(motion, length(sp.position - s.position) / max(s.view_depth, 1e-30));
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    if (frame.debug_poison == POISON_VPL_SHADE && pixel == uvec2(1u, 1u)) {
        samples[index] = vec4(vec3(uintBitsToFloat(0x7fc00000u)), 1.0);  // tests of --check-finite only
        return;
    }
    Surface s = surfaces[surface_slot(index)];
    VplParams p = pc.params;
    if (s.hit_t < 0.0) {
        samples[index] = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    Reservoir r = reservoirs[index];
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
            uint kind = vpls[r.vpl].kind;
            colour = kind == VPL_INDIRECT ? vec3(1.0, 0.1, 0.05) : kind == VPL_DIRECT_POINT ? vec3(0.1, 0.9, 1.0) : vec3(0.1, 0.25, 1.0);
        }
        samples[index] = vec4(colour, 1.0);
        return;
    }
    vec3 radiance = (p.kind_mask & KIND_MASK_DIRECT) != 0u ? s.emission : vec3(0.0);
    uint rays = 0u;
    if (valid) {
        Vpl v = vpls[r.vpl];
        vec3 c = surface_vpl_contribution(s, v, p);
        if (max3(c) > 0.0) {
            bool visible = true;
            bool visible_targets = (p.flags & VPL_FLAG_UNBIASED) != 0u && (p.flags & VPL_FLAG_INITIAL_VISIBILITY) != 0u;
            if (!visible_targets) {
                rays = 1u;
                visible = vpl_visible(s, v);
            }
            if (visible) {
                radiance += c * r.ucw;
            }
        }
    }
    samples[index] = vec4(radiance, 1.0);
    if (rays > 0u) {
        atomicAdd(ray_count[RAYS_SHADE], rays);
    }
}
