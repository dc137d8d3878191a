#version 460
// Miss shader 0: a closest-hit ray that left the scene.
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require

#include "payload.glsl"

layout(location = RT_CLOSEST_PAYLOAD) rayPayloadInEXT ClosestPayload payload;

void main() {
    payload.t = -1.0;
}
