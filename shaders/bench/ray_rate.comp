// bench --rays: this device's raw ray rate, with nothing else in the shader. One ray per thread
// per dispatch: RAY_RATE_PRIMARY traces the camera ray through a jittered point of the pixel
// (coherent, closest hit); RAY_RATE_SHADOW traces a shadow ray (terminate on first hit) from a
// uniform point of the scene's bounds in a uniform direction, of uniform random length up to the
// bounds' diagonal (incoherent); RAY_RATE_BOUNCE traces a closest-hit ray of unbounded length from
// such a point in such a direction (incoherent: the rays of photon paths and path-tracer bounces).
// The only other work is one store per thread, so the compiler keeps the ray. Traced through
// trace.glsl's trace_hits: a ray query, or (the `raygen` variant) a ray-tracing pipeline.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/trace.glsl"
#include "../lib/random.glsl"

#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8) in;
#endif
#include "../lib/dispatch.glsl"

layout(set = 1, binding = 0, std430) writeonly buffer Sink { uint sink[]; };

layout(push_constant) uniform Push {
    vec3 bounds_lo;
    uint mode;
    vec3 bounds_hi;
    uint dispatch_index;
} pc;

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    Rng rng = rng_init(pixel.x, pixel.y, pc.dispatch_index, 0x7261u);
    bool hit;
    if (pc.mode == RAY_RATE_PRIMARY) {
        vec3 dir = camera_ray_direction(vec2(pixel) + rand2(rng));
        hit = trace_hits(frame.camera_position, dir, 1e30, false);
    } else {
        vec3 extent = pc.bounds_hi - pc.bounds_lo;
        vec3 origin = pc.bounds_lo + extent * vec3(rand(rng), rand(rng), rand(rng));
        vec3 dir = sample_uniform_sphere(rand2(rng));
        if (pc.mode == RAY_RATE_BOUNCE) {
            hit = trace_hits(origin, dir, 1e30, false);
        } else {
            float len = max(rand(rng) * length(extent), 1e-6);
            hit = trace_hits(origin, dir, len, true);
        }
    }
    sink[index] = hit ? 1u : 0u;
}
