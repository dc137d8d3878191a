// Compact encodings. Binding-free: pure functions of their arguments.
#ifndef PACKING_GLSL
#define PACKING_GLSL

// Octahedral unit-vector encoding (Cigolle et al. 2014, "A Survey of Efficient Representations for
// Independent Unit Vectors") in two snorm16: about 3e-5 rad of error. A zero vector encodes as +z.
// A decoded normal lies on the code's direction, so re-encoding it lands on the same code (up to
// float rounding at a half-step boundary): a normal stored decoded and a code made from it later
// describe the same vector.
uint oct_encode(vec3 n) {
    float l1 = abs(n.x) + abs(n.y) + abs(n.z);
    if (!(l1 > 0.0)) {
        return packSnorm2x16(vec2(0.0));
    }
    vec2 e = n.xy / l1;
    if (n.z < 0.0) {
        e = (1.0 - abs(e.yx)) * vec2(e.x >= 0.0 ? 1.0 : -1.0, e.y >= 0.0 ? 1.0 : -1.0);
    }
    return packSnorm2x16(e);
}

vec3 oct_decode(uint code) {
    vec2 e = unpackSnorm2x16(code);
    vec3 n = vec3(e, 1.0 - abs(e.x) - abs(e.y));
    float t = max(-n.z, 0.0);
    n.x += n.x >= 0.0 ? -t : t;
    n.y += n.y >= 0.0 ? -t : t;
    return normalize(n);
}

// A unit normal as the octahedral code stores it.
vec3 oct_quantize(vec3 n) {
    return oct_decode(oct_encode(n));
}

#endif
