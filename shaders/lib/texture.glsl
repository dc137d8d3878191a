// Texture math without bindings: sRGB decoding and the footprint of a bilinear lookup with
// repeat wrapping. The texel loads themselves live in shaders/common/scene.glsl.
#ifndef LIB_TEXTURE_GLSL
#define LIB_TEXTURE_GLSL

// The sRGB transfer function (IEC 61966-2-1), per channel, for values in [0, 1].
vec3 srgb_to_linear(vec3 c) {
    vec3 lo = c / 12.92;
    vec3 hi = pow((c + 0.055) / 1.055, vec3(2.4));
    return mix(hi, lo, lessThanEqual(c, vec3(0.04045)));
}

// Unpacks an RGBA8 texel stored little-endian (r in the low byte) to [0, 1].
vec4 unpack_rgba8(uint t) {
    return vec4(t & 0xFFu, (t >> 8) & 0xFFu, (t >> 16) & 0xFFu, t >> 24) / 255.0;
}

// Bilinear footprint of `uv` (glTF convention: (0, 0) is the first texel of row 0) on a
// `size` texture with repeat wrapping: texel columns x.xy, rows y.xy and the weights of the
// second column / row in f.
void bilinear_footprint(vec2 uv, uvec2 size, out uvec2 x, out uvec2 y, out vec2 f) {
    vec2 p = fract(uv) * vec2(size) - 0.5;
    vec2 base = floor(p);
    f = p - base;
    // base is in [-1, size - 1] (fract < 1), so base + size is not negative, and the wrap is an
    // unsigned remainder: GLSL's % of a negative int is undefined in Vulkan (OpSMod with a
    // negative operand), where lavapipe happened to give the mathematical answer. Unsigned, any
    // value (even from a NaN uv) lands in [0, size).
    uvec2 w0 = uvec2(ivec2(base) + ivec2(size)) % size;
    uvec2 w1 = (w0 + 1u) % size;
    x = uvec2(w0.x, w1.x);
    y = uvec2(w0.y, w1.y);
}

// The texel under `uv` (NEAREST filtering, repeat wrapping): column floor(fract(u) * width), row
// likewise, kept below the size where fract rounds up to 1.0 (and for any NaN).
uvec2 nearest_texel(vec2 uv, uvec2 size) {
    return min(uvec2(fract(uv) * vec2(size)), size - 1u);
}

#endif
