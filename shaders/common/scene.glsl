// Set 0: the scene, declared once for every pass (geometry, materials, lights, frame constants),
// plus the loads every pass shares. Binding numbers match `SCENE_BINDINGS` in src/scene_gpu.rs.
// The TLAS (binding 0) and the two kinds of ray are in trace.glsl, included by the passes that
// trace: a pass that does not declares no ray-tracing capability.
#ifndef SCENE_GLSL
#define SCENE_GLSL

#include "types.glsl"
#include "texel_records.glsl"
#include "../lib/sampling.glsl"
#include "../lib/camera.glsl"
#include "../lib/finite.glsl"
#ifdef SCENE_TEXTURES
#include "../lib/texture.glsl"
#endif

// Geometry, materials, instances and lights are read at per-lane addresses (the hit a lane's ray
// found, the light it drew), so through texel views (texel_records.glsl says why).
layout(set = 0, binding = 1) uniform utextureBuffer vertices;  // Vertex, 2 RGBA32UI texels each
layout(set = 0, binding = 2) uniform utextureBuffer indices;  // R32UI
layout(set = 0, binding = 3) uniform utextureBuffer triangle_materials;  // R32UI
layout(set = 0, binding = 4) uniform utextureBuffer materials;  // Material, 2 RGBA32UI texels each
layout(set = 0, binding = 5) uniform utextureBuffer instances;  // Instance, 9 RGBA32UI texels each
layout(set = 0, binding = 6) uniform utextureBuffer lights;  // Light, 4 RGBA32UI texels each
layout(set = 0, binding = 7) uniform utextureBuffer light_alias;  // AliasEntry, RG32UI
layout(set = 0, binding = 8, std140) uniform FrameBuffer { Frame frame; };
#ifdef SCENE_TEXTURES
// Only in the `textured` shader variants, used when the scene has base-colour textures. Storage
// buffers: the texels of all textures together may outgrow a device's maxTexelBufferElements.
layout(set = 0, binding = 9, std430) readonly buffer TextureBuffer { TextureInfo textures[]; };
layout(set = 0, binding = 10, std430) readonly buffer TexelBuffer { uint texels[]; };
#endif

// A surface point reached by a ray, with normals oriented toward the ray's origin side.
struct Hit {
    vec3 position;
    vec3 geometric_normal;  // faces the incoming ray
    vec3 shading_normal;    // same hemisphere as geometric_normal
    uint material;
    bool front_face;        // the ray hit the glTF front face (counter-clockwise side)
    float offset_scale;     // offset_ray's scale for this triangle (triangle_offset_scale)
    uint instance;
    uint triangle;
#ifdef SCENE_TEXTURES
    vec2 uv;                // TEXCOORD_0
#endif
};

// Primary camera ray through image position `pixel` (in pixels, row 0 at the top).
vec3 camera_ray_direction(vec2 pixel) {
    return pinhole_direction(frame.camera_right, frame.camera_up, frame.camera_forward, frame.tan_half_fov, frame.aspect,
                             pixel, vec2(frame.width, frame.height));
}

// Where world point x appeared in the previous frame: image point (xy, pixels) and view depth (z)
// of the previous camera.
vec3 project_to_previous_frame(vec3 x) {
    return pinhole_project(frame.prev_camera_position, frame.prev_camera_right, frame.prev_camera_up,
                           frame.prev_camera_forward, frame.prev_tan_half_fov, frame.aspect, x,
                           vec2(frame.width, frame.height));
}

// The previous frame's pixel of a point projected there (q from project_to_previous_frame): false
// when it lies behind the previous camera or off its image. The tests are made on the floats
// before any conversion: converting a float beyond int's range (a point barely in front of the
// camera) is undefined, and a NaN is refused on its bits (lib/finite.glsl: a compiler may
// assume no NaN and fold the comparisons).
bool previous_pixel(vec3 q, out ivec2 pq) {
    pq = ivec2(0);
    if (!is_finite(q) || !(q.z > 0.0 && q.x >= 0.0 && q.y >= 0.0 && q.x < float(frame.width) && q.y < float(frame.height))) {
        return false;
    }
    pq = min(ivec2(floor(q.xy)), ivec2(frame.width, frame.height) - 1);
    return true;
}

// The G-buffer's two halves: element of pixel `index` in this frame's and the previous frame's.
uint surface_slot(uint index) {
    return frame.surface_offset + index;
}
uint prev_surface_slot(uint index) {
    return frame.prev_surface_offset + index;
}

// Reconstructs the hit on triangle `prim` of instance `inst` at barycentrics `bary` (of v1, v2).
Hit fetch_hit(uint inst, uint prim, vec2 bary, vec3 ray_dir) {
    // The matrices only for a transformed instance: they are 8 of an instance's 9 texels, and with
    // the identity the results are the same bit for bit.
    uvec4 header = instance_header_texels(instances, inst);  // first index, vertex, triangle; flags
    uint flags = header.w;
    bool identity = (flags & INSTANCE_IDENTITY) != 0u;
    uint first = header.x + 3u * prim;
    uint i0 = word_texel(indices, first) + header.y;
    uint i1 = word_texel(indices, first + 1u) + header.y;
    uint i2 = word_texel(indices, first + 2u) + header.y;
    Vertex v0 = vertex_texels(vertices, i0);
    Vertex v1 = vertex_texels(vertices, i1);
    Vertex v2 = vertex_texels(vertices, i2);
    vec3 b = vec3(1.0 - bary.x - bary.y, bary.x, bary.y);
    vec3 p0 = v0.position;
    vec3 p1 = v1.position;
    vec3 p2 = v2.position;
    if (!identity) {
        mat4 m = instance_matrix_texels(instances, inst, 0u);
        p0 = (m * vec4(p0, 1.0)).xyz;
        p1 = (m * vec4(p1, 1.0)).xyz;
        p2 = (m * vec4(p2, 1.0)).xyz;
    }
    Hit h;
    uint material_word = word_texel(triangle_materials, header.z + prim);
    h.offset_scale = triangle_offset_scale(p0, p1, p2);
    h.position = triangle_point(b, p0, p1, p2, h.offset_scale, material_word >> TRIANGLE_FLAT_EDGES_SHIFT);
    vec3 ng = triangle_normal(p0, p1, p2);
    if ((flags & INSTANCE_MIRRORED) != 0u) {
        ng = -ng;
    }
    ng = dot(ng, ng) > 0.0 ? ng : -ray_dir;
    h.front_face = dot(ng, ray_dir) < 0.0;
    if (!h.front_face) {
        ng = -ng;
    }
    vec3 n_obj = b.x * v0.normal + b.y * v1.normal + b.z * v2.normal;
    vec3 ns = ng;
    // Relative to the vertex normals' own lengths: a merged mesh's normals are scaled by the
    // inverse of its nodes' scale (merge.rs keeps them so), and against an absolute 1e-12 a node
    // scale from 1e6 on made every smooth surface flat.
    float n_len = dot(v0.normal, v0.normal) + dot(v1.normal, v1.normal) + dot(v2.normal, v2.normal);
    if (dot(n_obj, n_obj) > 1e-12 * n_len) {
        ns = n_obj;
        if (!identity) {
            ns = mat3(instance_matrix_texels(instances, inst, 1u)) * n_obj;
        }
        ns = normalize(ns);
        if (dot(ns, ng) < 0.0) {
            ns = -ns;
        }
    }
    h.geometric_normal = ng;
    h.shading_normal = ns;
    h.material = material_word & ((1u << TRIANGLE_FLAT_EDGES_SHIFT) - 1u);
    h.instance = inst;
    h.triangle = prim;
#ifdef SCENE_TEXTURES
    h.uv = b.x * vec2(v0.u, v0.v) + b.y * vec2(v1.u, v1.v) + b.z * vec2(v2.u, v2.v);
#endif
    return h;
}

#ifdef SCENE_TEXTURES
// Bilinear, sRGB-decoded base colour of texture `t` at `uv` (repeat wrapping; decoded per texel
// before filtering, as an sRGB image format would), or its one texel under `uv` for a NEAREST
// sampler.
vec3 sample_base_color(uint t, vec2 uv) {
    TextureInfo info = textures[t];
    // A uv that overflowed (vertex uvs near the float maximum interpolate to inf) reads as 0:
    // under repeat wrapping every float from 2^23 on is a whole number, so that is where any
    // huge finite uv lands too. fract(inf) is NaN, which made the filter weights and the albedo NaN.
    uv = vec2(is_finite(uv.x) ? uv.x : 0.0, is_finite(uv.y) ? uv.y : 0.0);
    uvec2 size = uvec2(info.width, info.height);
    if ((info.flags & TEXTURE_NEAREST) != 0u) {
        uvec2 p = nearest_texel(uv, size);
        return srgb_to_linear(unpack_rgba8(texels[info.offset + p.y * info.width + p.x]).rgb);
    }
    uvec2 x, y;
    vec2 f;
    bilinear_footprint(uv, size, x, y, f);
    uint row0 = info.offset + y.x * info.width;
    uint row1 = info.offset + y.y * info.width;
    vec3 c00 = srgb_to_linear(unpack_rgba8(texels[row0 + x.x]).rgb);
    vec3 c10 = srgb_to_linear(unpack_rgba8(texels[row0 + x.y]).rgb);
    vec3 c01 = srgb_to_linear(unpack_rgba8(texels[row1 + x.x]).rgb);
    vec3 c11 = srgb_to_linear(unpack_rgba8(texels[row1 + x.y]).rgb);
    return mix(mix(c00, c10, f.x), mix(c01, c11, f.x), f.y);
}
#endif

// Diffuse albedo at a hit: baseColorFactor, times the base colour texture where there is one.
vec3 hit_albedo(Hit h) {
    Material m = material_texels(materials, h.material);
#ifdef SCENE_TEXTURES
    if (m.texture >= 0) {
        return m.albedo * sample_base_color(uint(m.texture), h.uv);
    }
#endif
    return m.albedo;
}

// Picks a light in proportion to lum(power) through the alias table, from two words of 32
// random bits (the slot's, the keep test's); its probability is the light's `pdf` exactly
// (src/lights.rs, alias_pdfs).
uint sample_light_index(uint slot_bits, uint keep_bits) {
    uint slot = alias_slot(slot_bits, frame.light_count);
    AliasEntry e = alias_texels(light_alias, slot);
    return alias_resolve(slot, e.keep, e.alias, keep_bits);
}

#endif
