// gbuffer: one primary ray per pixel (through the pixel centre, or jittered inside it with --aa)
// -> position, normals, albedo, emission toward the camera, depth and ids.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/scene.glsl"
#include "../lib/random.glsl"
#include "../lib/brdf.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;

// Written as SURFACE_TEXELS RGBA32UI texels per Surface (texel_records.glsl's packed layout, which
// every other pass reads through a texel view): a storage buffer of the G-buffer's two halves would
// pass lavapipe's 128 MiB maxStorageBufferRange from about 1M pixels on.
layout(set = 1, binding = 0, rgba32ui) uniform writeonly uimageBuffer surfaces;

const uint SALT_GBUFFER = 0x6762u;

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    vec2 jitter = vec2(0.5);
    if ((frame.flags & FRAME_AA) != 0u) {
        Rng rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_GBUFFER);
        jitter = rand2(rng);
    }
    vec3 dir = camera_ray_direction(vec2(pixel) + jitter);

    Surface s;
    s.position = vec3(0.0);
    s.hit_t = -1.0;
    s.shading_normal = vec3(0.0);
    s.instance = 0xFFFFFFFFu;
    s.geometric_normal = vec3(0.0);
    s.triangle = 0xFFFFFFFFu;
    s.albedo = vec3(0.0);
    s.material = 0xFFFFFFFFu;
    s.emission = vec3(0.0);
    s.view_depth = -1.0;

    Hit hit;
    float t;
    if (trace_closest(frame.camera_position, dir, 1e30, hit, t)) {
        Material m = material_texels(materials, hit.material);
        s.position = hit.position;
        s.hit_t = t;
        s.shading_normal = hit.shading_normal;
        s.instance = hit.instance;
        s.geometric_normal = hit.geometric_normal;
        s.triangle = hit.triangle;
        s.albedo = hit_albedo(hit);
        s.material = hit.material;
        bool emits = hit.front_face || (m.flags & MATERIAL_DOUBLE_SIDED) != 0u;
        s.emission = emits ? m.emission : vec3(0.0);
        s.view_depth = t * dot(dir, frame.camera_forward);
    }
    uvec4 texels[SURFACE_TEXELS];
    surface_to_texels(s, texels);
    int k = int(SURFACE_TEXELS * surface_slot(index));
    for (int j = 0; j < int(SURFACE_TEXELS); ++j) {
        imageStore(surfaces, k + j, texels[j]);
    }
}
