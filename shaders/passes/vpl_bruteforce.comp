// vpl_bruteforce: Le + sum over every VPL of c_i(x) with a shadow ray each: the VPL model's exact
// answer (small images). Dispatched in chunks of VPLs [first, first + count); the first chunk
// writes Le, later chunks add to the sample.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/vpl_target.glsl"
#include "../common/texel_records.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;
#endif
#include "../lib/dispatch.glsl"

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
// Every invocation reads VPL i in step (one address for all lanes): a storage buffer reads that once.
layout(set = 1, binding = 1, std430) readonly buffer VplBuffer { Vpl vpls[]; };
layout(set = 1, binding = 2, std430) buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 3, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"

layout(push_constant) uniform Push {
    VplParams params;
    uint first;
    uint count;
} pc;

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    if (frame.debug_poison == POISON_RAY_CARRY && index == 0u && pc.first == 0u) {
        count_rays(RAYS_BRUTEFORCE, 0xFFFFFF00u);  // tests of the carry only (before any early return)
    }
    Surface s = surface_texels(surfaces, surface_slot(index));
    VplParams p = pc.params;
    if (s.offset_scale < 0.0) {
        samples[index] = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 radiance = pc.first == 0u ? ((p.kind_mask & KIND_MASK_DIRECT) != 0u ? s.emission : vec3(0.0))
                                   : samples[index].rgb;
    uint rays = 0u;
    uint end = min(pc.first + pc.count, p.vpl_count);
    for (uint i = pc.first; i < end; ++i) {
        Vpl v = vpls[i];
        vec3 c = surface_vpl_contribution(s, v, p);
        if (max3(c) > 0.0) {
            rays += 1u;
            if (vpl_visible(s, v)) {
                radiance += c;
            }
        }
    }
    samples[index] = vec4(radiance, 1.0);
    count_rays(RAYS_BRUTEFORCE, rays);
}
