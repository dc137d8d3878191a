// tonemap: exposure (2^EV) and the sRGB transfer curve -> 8-bit RGBA preview.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/scene.glsl"
#include "../lib/finite.glsl"

layout(local_size_x = 64) in;
// after the local size: dispatch_index() reads gl_WorkGroupSize
#include "../lib/dispatch.glsl"

layout(set = 1, binding = 0, std430) readonly buffer MeanBuffer { vec4 means[]; };
layout(set = 1, binding = 1, std430) writeonly buffer PreviewBuffer { uint preview[]; };

float srgb_encode(float c) {
    c = clamp(c, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

void main() {
    uint i = dispatch_index();
    if (i >= frame.width * frame.height) {
        return;
    }
    // A pixel with a non-finite channel is black (tested on the bits, lib/finite.glsl), as in
    // compare's CPU mapping (eval::compare::to_srgb8); negative channels become 0, and one that
    // the exposure takes past f32's range is white after srgb_encode's clamp.
    vec3 m = means[i].rgb;
    vec3 c = is_finite(m) ? m * frame.exposure : vec3(0.0);
    c = vec3(c.x > 0.0 ? c.x : 0.0, c.y > 0.0 ? c.y : 0.0, c.z > 0.0 ? c.z : 0.0);
    // floor(x + 0.5), not round(): round()'s direction at .5 is the implementation's choice.
    uvec3 q = uvec3(floor(vec3(srgb_encode(c.x), srgb_encode(c.y), srgb_encode(c.z)) * 255.0 + 0.5));
    preview[i] = q.x | (q.y << 8) | (q.z << 16) | (255u << 24);
}
