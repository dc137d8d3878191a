// Ray tracing against set 0's TLAS: closest hits and shadow rays, the two kinds of ray the
// renderer traces. One interface, two implementations:
//  - ray queries (VK_KHR_ray_query), inline in a compute shader: the default;
//  - with RT_PIPELINE defined, ray-tracing pipelines (VK_KHR_ray_tracing_pipeline): the pass is
//    compiled as a ray-generation shader (build.rs, `raygen` variants) whose rays run the hit and
//    miss shaders in shaders/rt/. For devices with ray-tracing pipelines and no ray queries, as
//    NVIDIA's H100 (driver 580).
// Both ask the same of the traversal (opaque triangles, the closest hit, or any hit for a shadow
// ray) and return the same values, so a pass's code above this file is the same for both.
#ifndef TRACE_GLSL
#define TRACE_GLSL

#ifdef RT_PIPELINE
#extension GL_EXT_ray_tracing : require
#else
#extension GL_EXT_ray_query : require
#endif

#include "scene.glsl"
#ifdef RT_PIPELINE
#include "../rt/payload.glsl"
#endif

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;

#ifdef RT_PIPELINE
layout(location = RT_CLOSEST_PAYLOAD) rayPayloadEXT ClosestPayload closest_payload;
layout(location = RT_SHADOW_PAYLOAD) rayPayloadEXT uint shadow_payload;
#endif

// Whether a ray hits anything within t_max: the closest hit, or with `any_hit` the first found
// (a shadow ray: segment_visible). Nothing is fetched (`bench --rays` times it alone).
bool trace_hits(vec3 origin, vec3 dir, float t_max, bool any_hit) {
#ifdef RT_PIPELINE
    if (any_hit) {
        shadow_payload = 0u;
        traceRayEXT(tlas, gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsSkipClosestHitShaderEXT, 0xFFu,
                    0u, 0u, RT_SHADOW_MISS, origin, 0.0, dir, t_max, RT_SHADOW_PAYLOAD);
        return shadow_payload == 0u;
    }
    closest_payload.t = -1.0;
    traceRayEXT(tlas, gl_RayFlagsOpaqueEXT, 0xFFu, 0u, 0u, RT_CLOSEST_MISS, origin, 0.0, dir, t_max, RT_CLOSEST_PAYLOAD);
    return closest_payload.t >= 0.0;
#else
    rayQueryEXT rq;
    uint flags = any_hit ? gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT : gl_RayFlagsOpaqueEXT;
    rayQueryInitializeEXT(rq, tlas, flags, 0xFFu, origin, 0.0, dir, t_max);
    while (rayQueryProceedEXT(rq)) {
    }
    return rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionNoneEXT;
#endif
}

// Closest hit along a ray; false when it leaves the scene.
bool trace_closest(vec3 origin, vec3 dir, float t_max, out Hit hit, out float t) {
#ifdef RT_PIPELINE
    // The closest-hit shader left the hit in closest_payload.
    if (!trace_hits(origin, dir, t_max, false)) {
        t = -1.0;
        return false;
    }
    t = closest_payload.t;
    uint inst = closest_payload.instance;
    uint prim = closest_payload.primitive;
    vec2 bary = closest_payload.barycentrics;
#else
    rayQueryEXT rq;
    rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFFu, origin, 0.0, dir, t_max);
    while (rayQueryProceedEXT(rq)) {
    }
    if (rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionTriangleEXT) {
        t = -1.0;
        return false;
    }
    t = rayQueryGetIntersectionTEXT(rq, true);
    uint inst = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(rq, true));
    uint prim = uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, true));
    vec2 bary = rayQueryGetIntersectionBarycentricsEXT(rq, true);
#endif
    hit = fetch_hit(inst, prim, bary, dir);
    return true;
}

// The segment from `from` to `to` as a ray: its length and, where that is positive, its
// direction. False where it cannot be traced: a ray's origin, direction and t range must be
// finite (undefined otherwise: lavapipe forgives it, hardware traversal need not), so endpoints
// ~1e19 apart (len overflows) or not finite are taken as blocked, and they add nothing.
bool segment_ray(vec3 from, vec3 to, out vec3 dir, out float len) {
    vec3 d = to - from;
    len = length(d);
    dir = len > 0.0 ? d / len : vec3(0.0);
    return is_finite(len) && is_finite(from);
}

// Shadow ray: true when nothing blocks the segment from `from` to `to` (both already offset).
bool segment_visible(vec3 from, vec3 to) {
    vec3 dir;
    float len;
    if (!segment_ray(from, to, dir, len)) {
        return false;
    }
    return len <= 0.0 || !trace_hits(from, dir, len, true);
}

// Whether `p` lies in the plane of `hit`'s triangle: within 4 ulps of the triangle's largest
// coordinate, the rounding of a hit at distance 0 (a point light placed on a floor). Such a
// surface neither blocks nor is lit by a light at p (the path tracer sees it at cos 0).
bool lies_in_hit_plane(vec3 p, Hit hit) {
    return abs(dot(p - hit.position, hit.geometric_normal)) <= hit.offset_scale * (1.0 / 2097152.0);
}

// Shadow ray to a point that is not offset (a point light, its direct VPLs), which may lie in a
// surface: toward a bulb placed on a floor the ray met the floor at the light's own point, rounded
// either way, and speckles went black (the Cornell box's direct light 16 % dark). The closest hit
// decides: none, or the plane the point lies in, is visible; anything else blocks. (A margin off
// the ray's end let light through a floor 1e-6 thick, where the photons stopped.)
bool segment_visible_to_point(vec3 from, vec3 point) {
    vec3 dir;
    float len;
    if (!segment_ray(from, point, dir, len)) {
        return false;
    }
    Hit hit;
    float t;
    return len <= 0.0 || !trace_closest(from, dir, len, hit, t) || lies_in_hit_plane(point, hit);
}

#endif
