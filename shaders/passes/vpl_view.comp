// vpl_view: the VPL debug image (the thesis's Figure 5). The scene gets simple headlight diffuse
// shading; every VPL is drawn as a small sphere, blue for direct and red for indirect. VPLs are
// projected to the screen; each tests the exact ray-sphere intersection over its projected footprint
// against the G-buffer depth (no loop over all VPLs per pixel).
//   VPL_VIEW_CLEAR, per pixel: clear the sphere depth.
//   VPL_VIEW_DEPTH, per VPL: atomicMin of the sphere's hit distance (float bits order like uints for t > 0).
//   VPL_VIEW_ID, per VPL: the VPL whose distance won records its index.
//   VPL_VIEW_DRAW, per pixel: shade.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/scene.glsl"
#include "../common/texel_records.glsl"

layout(local_size_x = 64) in;
// after the local size: dispatch_index() reads gl_WorkGroupSize
#include "../lib/dispatch.glsl"

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2, std430) buffer SphereDepthBuffer { uint sphere_t[]; };
layout(set = 1, binding = 3, std430) buffer SphereIdBuffer { uint sphere_id[]; };
layout(set = 1, binding = 4, std430) writeonly buffer SampleBuffer { vec4 samples[]; };

layout(push_constant) uniform Push {
    uint mode;  // VPL_VIEW_*
    uint vpl_count;
    float radius;
    uint max_footprint;  // pixels, half-width
};

const uint NO_HIT = 0x7F800000u;  // +inf

// Distance along the unit ray to the sphere, or -1.
float ray_sphere(vec3 o, vec3 d, vec3 c, float r) {
    vec3 oc = o - c;
    float b = dot(oc, d);
    float q = dot(oc, oc) - r * r;
    float disc = b * b - q;
    if (disc < 0.0) {
        return -1.0;
    }
    float s = sqrt(disc);
    float t = -b - s;
    return t > 0.0 ? t : (-b + s > 0.0 ? -b + s : -1.0);
}

void splat(uint v, bool record) {
    vec3 c = vpl_texels(vpls, v).position;
    vec3 rel = c - frame.camera_position;
    float z = dot(rel, frame.camera_forward);
    if (z <= radius) {
        return;
    }
    float sx = dot(rel, frame.camera_right) / (z * frame.tan_half_fov * frame.aspect);
    float sy = dot(rel, frame.camera_up) / (z * frame.tan_half_fov);
    vec2 centre = vec2((sx + 1.0) * 0.5 * float(frame.width), (1.0 - sy) * 0.5 * float(frame.height));
    float pr = radius / (z * frame.tan_half_fov) * 0.5 * float(frame.height) * 1.5 + 1.0;
    int half_w = int(min(ceil(pr), float(max_footprint)));
    // Off the image by more than the footprint (or not finite): nothing to draw, and converting a
    // float beyond int's range is undefined.
    vec2 reach = vec2(float(half_w) + 1.0);
    if (!(all(greaterThan(centre, -reach)) && all(lessThan(centre, vec2(frame.width, frame.height) + reach)))) {
        return;
    }
    ivec2 ci = ivec2(floor(centre));
    for (int dy = -half_w; dy <= half_w; ++dy) {
        for (int dx = -half_w; dx <= half_w; ++dx) {
            ivec2 p = ci + ivec2(dx, dy);
            if (p.x < 0 || p.y < 0 || p.x >= int(frame.width) || p.y >= int(frame.height)) {
                continue;
            }
            uint i = uint(p.y) * frame.width + uint(p.x);
            vec3 dir = camera_ray_direction(vec2(p) + 0.5);
            float t = ray_sphere(frame.camera_position, dir, c, radius);
            Surface s = surface_texels(surfaces, surface_slot(i));
            // The surface's distance along this (unjittered) ray.
            float surface_t = s.offset_scale >= 0.0 ? dot(s.position - frame.camera_position, dir) : -1.0;
            if (t <= 0.0 || (surface_t >= 0.0 && t >= surface_t)) {
                continue;
            }
            if (!record) {
                atomicMin(sphere_t[i], floatBitsToUint(t));
            } else if (sphere_t[i] == floatBitsToUint(t)) {
                sphere_id[i] = v;
            }
        }
    }
}

void main() {
    uint k = dispatch_index();
    uint pixels = frame.width * frame.height;
    if (mode == VPL_VIEW_CLEAR) {
        if (k < pixels) {
            sphere_t[k] = NO_HIT;
            sphere_id[k] = 0xFFFFFFFFu;
        }
    } else if (mode == VPL_VIEW_DEPTH || mode == VPL_VIEW_ID) {
        if (k < vpl_count) {
            splat(k, mode == VPL_VIEW_ID);
        }
    } else if (k < pixels) {
        uvec2 p = uvec2(k % frame.width, k / frame.width);
        vec3 dir = camera_ray_direction(vec2(p) + 0.5);
        Surface s = surface_texels(surfaces, surface_slot(k));
        vec3 colour = vec3(0.0);
        if (s.offset_scale >= 0.0) {
            colour = s.albedo * (0.15 + 0.85 * abs(dot(s.shading_normal, dir))) + min(s.emission, vec3(1.0));
        }
        uint id = sphere_id[k];
        if (sphere_t[k] != NO_HIT && id != 0xFFFFFFFFu) {
            Vpl v = vpl_texels(vpls, id);
            float t = uintBitsToFloat(sphere_t[k]);
            vec3 n = normalize(frame.camera_position + t * dir - v.position);
            vec3 base = v.kind == VPL_INDIRECT ? vec3(0.9, 0.12, 0.08) : vec3(0.12, 0.3, 0.95);
            colour = base * (0.3 + 0.7 * max(0.0, -dot(n, dir)));
        }
        samples[k] = vec4(colour, 1.0);
    }
}
