// gbuffer: one primary ray per pixel (through the pixel centre, or jittered inside it with --aa)
// -> position, normals, albedo, emission toward the camera, depth and ids.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/trace.glsl"
#include "../lib/random.glsl"
#include "../lib/brdf.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;
#endif
#include "../lib/dispatch.glsl"

// Written as SURFACE_TEXELS uvec4 per Surface (texel_records.glsl's packed layout, which every
// other pass reads through the buffer's texel view) through GBUFFER_CHUNKS storage buffers, each
// bound to pc.chunk_records consecutive records of the one G-buffer buffer: a single binding of
// both halves would pass lavapipe's 128 MiB maxStorageBufferRange from about 1M pixels on. Storage
// buffers, not imageStore to a storage texel buffer: on lavapipe the G-buffer pass took ~0.7x the
// time with them (docs/performance.md).
layout(set = 1, binding = 0, std430) writeonly buffer Chunk0 { uvec4 surfaces_chunk0[]; };
layout(set = 1, binding = 1, std430) writeonly buffer Chunk1 { uvec4 surfaces_chunk1[]; };
layout(set = 1, binding = 2, std430) writeonly buffer Chunk2 { uvec4 surfaces_chunk2[]; };
layout(set = 1, binding = 3, std430) writeonly buffer Chunk3 { uvec4 surfaces_chunk3[]; };
layout(set = 1, binding = 4, std430) writeonly buffer Chunk4 { uvec4 surfaces_chunk4[]; };
layout(set = 1, binding = 5, std430) writeonly buffer Chunk5 { uvec4 surfaces_chunk5[]; };
layout(set = 1, binding = 6, std430) writeonly buffer Chunk6 { uvec4 surfaces_chunk6[]; };
layout(set = 1, binding = 7, std430) writeonly buffer Chunk7 { uvec4 surfaces_chunk7[]; };

layout(push_constant) uniform Push {
    uint chunk_records;  // records per chunk binding (a multiple of 4: 256-byte aligned offsets)
} pc;

// Stores the record of G-buffer slot `slot` (surface_slot) through the binding that covers it.
void store_record(uint slot, uvec4 t[SURFACE_TEXELS]) {
    uint c = slot / pc.chunk_records;
    uint k = SURFACE_TEXELS * (slot - c * pc.chunk_records);
    for (uint j = 0u; j < SURFACE_TEXELS; ++j) {
        switch (c) {
        case 0u: surfaces_chunk0[k + j] = t[j]; break;
        case 1u: surfaces_chunk1[k + j] = t[j]; break;
        case 2u: surfaces_chunk2[k + j] = t[j]; break;
        case 3u: surfaces_chunk3[k + j] = t[j]; break;
        case 4u: surfaces_chunk4[k + j] = t[j]; break;
        case 5u: surfaces_chunk5[k + j] = t[j]; break;
        case 6u: surfaces_chunk6[k + j] = t[j]; break;
        default: surfaces_chunk7[k + j] = t[j]; break;
        }
    }
}

const uint SALT_GBUFFER = 0x6762u;

void main() {
    uvec2 pixel = dispatch_pixel();
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
    s.offset_scale = -1.0;
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
        s.offset_scale = hit.offset_scale;
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
    store_record(surface_slot(index), texels);
}
