#version 460
// The one hit group's closest-hit shader: records the hit as a ray query's committed triangle
// intersection would (trace.glsl's trace_closest reads it back). Shadow rays skip it.
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require

#include "payload.glsl"

layout(location = RT_CLOSEST_PAYLOAD) rayPayloadInEXT ClosestPayload payload;
hitAttributeEXT vec2 barycentrics;

void main() {
    payload.t = gl_HitTEXT;
    payload.instance = uint(gl_InstanceCustomIndexEXT);
    payload.primitive = uint(gl_PrimitiveID);
    payload.barycentrics = barycentrics;
}
