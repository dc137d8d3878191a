// Records (types.glsl) read through a buffer's texel view: RGBA32UI (one 16-byte texelFetch per
// texel, the struct's fields in order), RG32UI for the 8-byte alias entries, R32UI for index lists.
// tests/vpl_math.rs reads each record both ways and compares. Binding-free: the caller passes the
// texel buffer (set 0's scene buffers, a pass's own).
//
// Why not the storage buffers the passes write them through: lavapipe (llvmpipe) turns a
// storage-buffer read at a per-invocation address into a loop over the 8 SIMD lanes that tests the
// lane, bounds-checks the offset and loads 4 bytes, per lane and per 32-bit word; a texel fetch
// goes through its texture path, which handles all lanes' bounds at once and loads a texel's 16
// bytes together (Mesa's gallivm source). Measured: ~0.8× a ReSTIR frame (docs/performance.md).
// On GPUs typed and storage-buffer loads are both common and cost about the same (not measured).
#ifndef TEXEL_RECORDS_GLSL
#define TEXEL_RECORDS_GLSL

#extension GL_EXT_samplerless_texture_functions : require

#include "types.glsl"
#include "../lib/packing.glsl"

uvec4 texel_at(utextureBuffer b, uint texel) {
    return texelFetch(b, int(texel));
}

// A Surface is stored as SURFACE_TEXELS texels with its two normals octahedral (packing.glsl,
// ~3e-5 rad): position, offset_scale | albedo, oct(shading normal) | emission, oct(geometric normal) |
// instance, triangle, material, view_depth. Four 16-byte stores per pixel in gbuffer instead of
// five (on lavapipe each cost ~7 ms of a 1280×720 frame as an imageStore, less through the storage
// buffers gbuffer now writes with), and a target evaluation at a surface reads three texels
// (position, albedo and both normals).
Surface surface_texels(utextureBuffer b, uint i) {
    uint k = SURFACE_TEXELS * i;
    uvec4 t0 = texel_at(b, k);
    uvec4 t1 = texel_at(b, k + 1u);
    uvec4 t2 = texel_at(b, k + 2u);
    uvec4 t3 = texel_at(b, k + 3u);
    Surface s;
    s.position = uintBitsToFloat(t0.xyz);
    s.offset_scale = uintBitsToFloat(t0.w);
    s.albedo = uintBitsToFloat(t1.xyz);
    s.shading_normal = oct_decode(t1.w);
    s.emission = uintBitsToFloat(t2.xyz);
    s.geometric_normal = oct_decode(t2.w);
    s.instance = t3.x;
    s.triangle = t3.y;
    s.material = t3.z;
    s.view_depth = uintBitsToFloat(t3.w);
    return s;
}

// The texels of a Surface, as surface_texels reads them (gbuffer stores them through storage buffers).
void surface_to_texels(Surface s, out uvec4 t[SURFACE_TEXELS]) {
    t[0] = uvec4(floatBitsToUint(s.position), floatBitsToUint(s.offset_scale));
    t[1] = uvec4(floatBitsToUint(s.albedo), oct_encode(s.shading_normal));
    t[2] = uvec4(floatBitsToUint(s.emission), oct_encode(s.geometric_normal));
    t[3] = uvec4(s.instance, s.triangle, s.material, floatBitsToUint(s.view_depth));
}

Vpl vpl_texels(utextureBuffer b, uint i) {
    uint k = 3u * i;
    uvec4 t0 = texel_at(b, k);
    uvec4 t1 = texel_at(b, k + 1u);
    uvec4 t2 = texel_at(b, k + 2u);
    Vpl v;
    v.position = uintBitsToFloat(t0.xyz);
    v.kind = t0.w;
    v.normal = uintBitsToFloat(t1.xyz);
    v.path = t1.w;
    v.flux = uintBitsToFloat(t2.xyz);
    v.yuksel_r2 = uintBitsToFloat(t2.w);
    return v;
}

Reservoir reservoir_texels(utextureBuffer b, uint i) {
    uvec4 t = texel_at(b, i);
    Reservoir r;
    r.vpl = t.x;
    r.ucw = uintBitsToFloat(t.y);
    r.confidence = uintBitsToFloat(t.z);
    r.target = uintBitsToFloat(t.w);
    return r;
}

// The VplCandidate whose two texels start at texel k.
VplCandidate candidate_texels_at(utextureBuffer b, uint k) {
    uvec4 t0 = texel_at(b, k);
    uvec4 t1 = texel_at(b, k + 1u);
    VplCandidate c;
    c.position = uintBitsToFloat(t0.xyz);
    c.vpl_kind = t0.w;
    c.flux = uintBitsToFloat(t1.xyz);
    c.normal_oct = t1.w;
    return c;
}

VplCandidate candidate_texels(utextureBuffer b, uint i) {
    return candidate_texels_at(b, 2u * i);
}

// A GridEntry is 3 texels: its VplCandidate's two, then (ucw, padding).
VplCandidate grid_entry_candidate_texels(utextureBuffer b, uint i) {
    return candidate_texels_at(b, 3u * i);
}

float grid_entry_ucw_texels(utextureBuffer b, uint i) {
    return uintBitsToFloat(texel_at(b, 3u * i + 2u).x);
}

Vertex vertex_texels(utextureBuffer b, uint i) {
    uvec4 t0 = texel_at(b, 2u * i);
    uvec4 t1 = texel_at(b, 2u * i + 1u);
    Vertex v;
    v.position = uintBitsToFloat(t0.xyz);
    v.u = uintBitsToFloat(t0.w);
    v.normal = uintBitsToFloat(t1.xyz);
    v.v = uintBitsToFloat(t1.w);
    return v;
}

Material material_texels(utextureBuffer b, uint i) {
    uvec4 t0 = texel_at(b, 2u * i);
    uvec4 t1 = texel_at(b, 2u * i + 1u);
    Material m;
    m.albedo = uintBitsToFloat(t0.xyz);
    m.texture = int(t0.w);
    m.emission = uintBitsToFloat(t1.xyz);
    m.flags = t1.w;
    return m;
}

// An Instance's last texel: first_index, first_vertex, first_triangle, flags.
const uint INSTANCE_TEXELS = 9u;
uvec4 instance_header_texels(utextureBuffer b, uint i) {
    return texel_at(b, INSTANCE_TEXELS * i + 8u);
}

// An Instance's matrix: 0 world_from_object, 1 normal_to_world (columns, as std430 stores a mat4).
mat4 instance_matrix_texels(utextureBuffer b, uint i, uint which) {
    uint k = INSTANCE_TEXELS * i + 4u * which;
    return mat4(uintBitsToFloat(texel_at(b, k)), uintBitsToFloat(texel_at(b, k + 1u)), uintBitsToFloat(texel_at(b, k + 2u)),
                uintBitsToFloat(texel_at(b, k + 3u)));
}

Light light_texels(utextureBuffer b, uint i) {
    uint k = 4u * i;
    uvec4 t0 = texel_at(b, k);
    uvec4 t1 = texel_at(b, k + 1u);
    uvec4 t2 = texel_at(b, k + 2u);
    uvec4 t3 = texel_at(b, k + 3u);
    Light l;
    l.p0 = uintBitsToFloat(t0.xyz);
    l.area = uintBitsToFloat(t0.w);
    l.p1 = uintBitsToFloat(t1.xyz);
    l.pdf = uintBitsToFloat(t1.w);
    l.p2 = uintBitsToFloat(t2.xyz);
    l.flags = t2.w;
    l.emission = uintBitsToFloat(t3.xyz);
    l._pad0 = t3.w;
    return l;
}

// Through an RG32UI view: one texel per entry.
AliasEntry alias_texels(utextureBuffer b, uint i) {
    uvec2 t = texel_at(b, i).xy;
    AliasEntry e;
    e.keep = uintBitsToFloat(t.x);
    e.alias = t.y;
    return e;
}

// Through an R32UI view.
uint word_texel(utextureBuffer b, uint i) {
    return texel_at(b, i).x;
}

#endif
