// bench --rays: this device's raw ray rate, with nothing else in the shader. One ray per thread
// per dispatch: RAY_RATE_PRIMARY traces the camera ray through a jittered point of the pixel
// (coherent, closest hit); RAY_RATE_SHADOW traces a shadow ray (terminate on first hit) from a
// uniform point of the scene's bounds in a uniform direction, of uniform random length up to the
// bounds' diagonal (incoherent); RAY_RATE_BOUNCE traces a closest-hit ray of unbounded length from
// such a point in such a direction (incoherent: the rays of photon paths and path-tracer bounces).
// The only other work is one store per thread, so the compiler keeps the query.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/trace.glsl"
#include "../lib/random.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 1, binding = 0, std430) writeonly buffer Sink { uint sink[]; };

layout(push_constant) uniform Push {
    vec3 bounds_lo;
    uint mode;
    vec3 bounds_hi;
    uint dispatch_index;
} pc;

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    Rng rng = rng_init(pixel.x, pixel.y, pc.dispatch_index, 0x7261u);
    rayQueryEXT rq;
    if (pc.mode == RAY_RATE_PRIMARY) {
        vec3 dir = camera_ray_direction(vec2(pixel) + rand2(rng));
        rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFFu, frame.camera_position, 0.0, dir, 1e30);
    } else {
        vec3 extent = pc.bounds_hi - pc.bounds_lo;
        vec3 origin = pc.bounds_lo + extent * vec3(rand(rng), rand(rng), rand(rng));
        vec3 dir = sample_uniform_sphere(rand2(rng));
        if (pc.mode == RAY_RATE_BOUNCE) {
            rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFFu, origin, 0.0, dir, 1e30);
        } else {
            float len = max(rand(rng) * length(extent), 1e-6);
            rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT, 0xFFu, origin, 0.0, dir, len);
        }
    }
    while (rayQueryProceedEXT(rq)) {
    }
    sink[index] = rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionNoneEXT ? 0u : 1u;
}
