#version 460
// Miss shader 1: a shadow ray that nothing blocked (the payload starts at 0, blocked).
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require

#include "payload.glsl"

layout(location = RT_SHADOW_PAYLOAD) rayPayloadInEXT uint visible;

void main() {
    visible = 1u;
}
