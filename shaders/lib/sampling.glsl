// Sampling routines. Binding-free: pure functions of their arguments.
#ifndef SAMPLING_GLSL
#define SAMPLING_GLSL

const float PI = 3.14159265358979323846;
const float INV_PI = 0.31830988618379067154;

// Orthonormal basis around unit n (Duff et al. 2017, branchless).
void onb(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// Uniform point on the unit disk (Shirley & Chiu's concentric map).
vec2 sample_concentric_disk(vec2 u) {
    vec2 d = 2.0 * u - 1.0;
    if (d.x == 0.0 && d.y == 0.0) {
        return vec2(0.0);
    }
    if (abs(d.x) > abs(d.y)) {
        float phi = (PI / 4.0) * (d.y / d.x);
        return d.x * vec2(cos(phi), sin(phi));
    }
    float phi = (PI / 2.0) - (PI / 4.0) * (d.x / d.y);
    return d.y * vec2(cos(phi), sin(phi));
}

// Cosine-weighted direction around unit n; pdf = cos / pi (Malley's method on a concentric disk).
vec3 sample_cosine_hemisphere(vec3 n, vec2 u) {
    vec2 disk = sample_concentric_disk(u);
    float z = sqrt(max(0.0, 1.0 - dot(disk, disk)));
    vec3 t, b;
    onb(n, t, b);
    return normalize(disk.x * t + disk.y * b + z * n);
}

// Uniform direction on the unit sphere; pdf = 1 / (4 pi).
vec3 sample_uniform_sphere(vec2 u) {
    float z = 1.0 - 2.0 * u.x;
    float r = sqrt(max(0.0, 1.0 - z * z));
    float phi = 2.0 * PI * u.y;
    return vec3(r * cos(phi), r * sin(phi), z);
}

// Uniform point on a triangle (area-uniform), as barycentric weights (b0, b1, b2).
vec3 sample_triangle_barycentrics(vec2 u) {
    float su = sqrt(u.x);
    float b0 = 1.0 - su;
    float b1 = u.y * su;
    return vec3(b0, b1, 1.0 - b0 - b1);
}

// Power heuristic (beta = 2) weight of strategy a against b, a^2 / (a^2 + b^2), computed from the
// ratio of the smaller pdf to the larger so that it neither overflows (a pdf beyond ~1.8e19, from a
// tiny light or a grazing one: Inf / Inf) nor underflows: 1 for an infinite a against a finite b,
// 0 when a is 0.
float power_heuristic(float pdf_a, float pdf_b) {
    if (!(pdf_a > 0.0)) {
        return 0.0;
    }
    if (!(pdf_b > 0.0)) {
        return 1.0;
    }
    if (pdf_a >= pdf_b) {
        float r = pdf_b / pdf_a;
        return 1.0 / (1.0 + r * r);
    }
    float r = pdf_a / pdf_b;
    float r2 = r * r;
    return r2 / (1.0 + r2);
}

// Vose alias table, step 1: the slot that 32 random bits land in (floor(bits n / 2^32), exact for
// any n) and a fresh uniform with 24 bits from the low word of the product. (From a float u in
// [0, 1), u n keeps only 24 - log2(n) bits of fraction: for 10k lights the keep test was off by up
// to several times for small keep probabilities.)
uint alias_slot(uint bits, uint n, out float u_rest) {
    uint slot;
    uint fraction;
    umulExtended(bits, n, slot, fraction);
    u_rest = float(fraction >> 8) * (1.0 / 16777216.0);
    return slot;
}

// Step 2: keep the slot's own index with probability `keep`, else take its alias.
uint alias_resolve(uint slot, float keep, uint alias_index, float u_rest) {
    return u_rest < keep ? slot : alias_index;
}

// The scale of a triangle's rounding errors for offset_ray: its vertices' largest |coordinate|
// (a point interpolated from them is off its plane by a few ulps of that), never zero.
float triangle_offset_scale(vec3 p0, vec3 p1, vec3 p2) {
    vec3 m = max(max(abs(p0), abs(p1)), abs(p2));
    return max(max(m.x, max(m.y, m.z)), 1e-30);
}

// A triangle's unit normal (counter-clockwise p0, p1, p2) at any scale: the edges are divided by
// their largest |component| before the cross product, whose squared length would otherwise
// underflow f32 for triangles under ~1e-10 across (and overflow above ~1e19). Zero for a
// degenerate triangle.
//
// The cross product is written out and `precise` (SPIR-V NoContraction): a component whose two
// products are equal, as for a triangle with an edge along an axis (the Cornell box's red wall's
// second triangle has one along z: its normal's z), is then exactly 0 on every device. A compiler free to contract
// a*b - c*d into fma(a, b, -c*d) (NVIDIA's, by what it did; lavapipe's does not) leaves the product's rounding
// error instead, up to +-2e-10 there, whose sign follows the scene's scale; onb() turns its frame by 180
// degrees with the sign of n.z, so the same random numbers then sent a bounce elsewhere: on an
// H100 a tenth of the photon paths and some path-tracer paths differed between the Cornell box at
// scale 1 and at 1e-2 or 1e5 (tests/scale.rs; both images right, with other noise).
vec3 triangle_normal(vec3 p0, vec3 p1, vec3 p2) {
    vec3 e1 = p1 - p0;
    vec3 e2 = p2 - p0;
    vec3 m = max(abs(e1), abs(e2));
    float s = max(m.x, max(m.y, m.z));
    if (!(s > 0.0)) {
        return vec3(0.0);
    }
    vec3 a = e1 / s;
    vec3 b = e2 / s;
    precise vec3 n = vec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
    float len = length(n);
    return len > 0.0 ? n / len : vec3(0.0);
}

// `x` moved `n` ulps toward `to`, never past it: near the origin (|x| under `near`), where ulps
// vanish, by `tiny` instead, as offset_ray switches there.
float step_toward(float x, float to, int n, float near, float tiny) {
    if (to == x) {
        return x;
    }
    bool up = to > x;
    float moved;
    if (abs(x) < near) {
        moved = x + (up ? tiny : -tiny);
    } else {
        // Away from 0 the bits of a float grow with its magnitude.
        moved = intBitsToFloat(floatBitsToInt(x) + (((x > 0.0) == up) ? n : -n));
    }
    return up ? min(moved, to) : max(moved, to);
}

// The point of triangle (p0, p1, p2) at barycentrics b, on the triangle's side of each edge:
// interpolated, it rounds to a few ulps off the triangle, and at an inside edge shared with
// another wall (a room's corner, walls sharing their vertices) one ulp past that wall's plane,
// where every ray leaving it (offset along its own normal only) started behind the wall: black
// pixels along a room's edges. Clamped into the triangle's bounding box (exact for axis-aligned
// walls) and moved 4 ulps toward its centroid on each axis (`scale`: triangle_offset_scale; near
// the origin by scale / 2^26, 4 ulps at offset_ray's threshold of scale / 32).
vec3 triangle_point(vec3 b, vec3 p0, vec3 p1, vec3 p2, float scale) {
    vec3 p = clamp(b.x * p0 + b.y * p1 + b.z * p2, min(min(p0, p1), p2), max(max(p0, p1), p2));
    vec3 c = (p0 + p1 + p2) * (1.0 / 3.0);
    float near = scale * (1.0 / 32.0);
    float tiny = scale * (1.0 / 67108864.0);
    return vec3(step_toward(p.x, c.x, 4, near, tiny), step_toward(p.y, c.y, 4, near, tiny), step_toward(p.z, c.z, 4, near, tiny));
}

// Ray-origin offset against self-intersection (Waechter & Binder, Ray Tracing Gems, ch. 6):
// moves p along n by a few ulps (far from the origin) or, near the origin where ulps vanish, by a
// small amount. Their "near" and "small" (1/32 and 1/65536) are for triangles of unit size: here
// they are relative to `scale`, the largest |coordinate| of the triangle p lies on
// (triangle_offset_scale), so a scene scaled by any factor gets the same offsets relative to its
// size, and a triangle far away (a sky dome, a distant ground) no longer widens the offsets of the
// small ones near the origin (relative to the whole scene's extent they did: one triangle 1e5
// away lifted shadow rays 1.5 units off a 1-unit room and blacked it out).
//
// Near the origin the offset is scale / 2^20, the offset of 256 ulps just outside it (256 ulps of
// scale / 32), where W&B's scale / 65536 jumps 16-fold across the threshold: the hit position's
// error there, b0 p0 + b1 p1 + b2 p2 rounded, is bounded by a few ulps of `scale` on both sides,
// so the margin that holds just outside holds inside. A 2 x 2e4 ground plane lifted rays 0.15
// units near the origin (scale / 65536): a unit cube on it lost its contact shadow and the image
// was 2.9 % brighter than with the plane split into a small quad and a ring (path tracer,
// measured at stop 47); 0.0095 units now.
vec3 offset_ray(vec3 p, vec3 n, float scale) {
    float origin = scale * (1.0 / 32.0);
    float float_scale = scale * (1.0 / 1048576.0);
    const float int_scale = 256.0;
    ivec3 of_i = ivec3(int_scale * n);
    vec3 p_i = vec3(
        intBitsToFloat(floatBitsToInt(p.x) + ((p.x < 0.0) ? -of_i.x : of_i.x)),
        intBitsToFloat(floatBitsToInt(p.y) + ((p.y < 0.0) ? -of_i.y : of_i.y)),
        intBitsToFloat(floatBitsToInt(p.z) + ((p.z < 0.0) ? -of_i.z : of_i.z)));
    return vec3(
        abs(p.x) < origin ? p.x + float_scale * n.x : p_i.x,
        abs(p.y) < origin ? p.y + float_scale * n.y : p_i.y,
        abs(p.z) < origin ? p.z + float_scale * n.z : p_i.z);
}

#endif
