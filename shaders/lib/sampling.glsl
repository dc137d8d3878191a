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

// Vose alias table, step 1: the slot that 32 random bits land in (floor(bits n / 2^32): slot k
// takes ceil((k+1) 2^32 / n) - ceil(k 2^32 / n) of the 2^32 values, which src/lights.rs counts).
uint alias_slot(uint bits, uint n) {
    uint slot;
    uint fraction;
    umulExtended(bits, n, slot, fraction);
    return slot;
}

// Step 2: keep the slot's own index with probability `keep`, else take its alias, from 32 more
// random bits: kept when bits < floor(keep 2^32) (keep >= 1: always), a probability exact to
// 2^-32 for any keep (src/lights.rs computes the lights' pdf from the same integers). The 24
// bits of a float uniform picked a light with keep 2e-7 1.2x too often, and one with keep 1e-5
// among 10^6 lights never (its slot's share of a shared 32-bit word left it ~4000 values).
uint alias_resolve(uint slot, float keep, uint alias_index, uint bits) {
    return (keep >= 1.0 || bits < uint(keep * 4294967296.0)) ? slot : alias_index;
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

// Smallest distance (in units of triangle_offset_scale) that triangle_point keeps between a hit and
// its triangle's edges: 2^-17, 64 ulps of the scale. In a room turned 30° and 20°, 2^-19 left 32
// black pixels of 128² along its edges and 2^-18 none: twice that. (Moving every hit toward its
// triangle's centroid by such a distance moved a 2e4-unit ground plane's hits 0.15 units and
// brightened a contact shadow's image 4 %; only hits this close to an edge move here.)
const float EDGE_MARGIN = 1.0 / 131072.0;

// The point of triangle (p0, p1, p2) at barycentrics b, kept EDGE_MARGIN × `scale` inside each of
// its edges (`scale`: triangle_offset_scale). Interpolated as given, a hit near an edge lies up
// to many ulps off the triangle (its barycentrics carry the intersection's own error), and at an
// inside edge shared with another wall (a room's corner, walls sharing their vertices) behind
// that wall's plane, where every ray leaving it (offset along its own normal only) started behind
// the wall: black pixels along a room's edges, axis-aligned or turned. Each barycentric is raised
// to the one that puts the point that far from the opposite edge (then renormalised), so only
// points that close to an edge move, across it: a large triangle's interior stays where it was.
// (The G-buffer's position moves with them: a plane's reprojection is exact to the margin.)
// `flat_edges` bit i: the edge opposite vertex i goes on into a coplanar neighbour (the loader's
// Mesh::flat_edges), where a hit past it is a hit on that neighbour: no margin there (on a large
// quad the margin moved every hit along its diagonal, 0.76 units on a 2e5-unit plane).
vec3 triangle_point(vec3 b, vec3 p0, vec3 p1, vec3 p2, float scale, uint flat_edges) {
    // In units of `scale`, whose squares cannot overflow.
    vec3 q0 = p0 / scale, q1 = p1 / scale, q2 = p2 / scale;
    float twice_area = length(cross(q1 - q0, q2 - q0));
    // The barycentric of vertex i at distance d from the opposite edge is d × |edge| / (2 × area).
    vec3 edges = vec3(length(q2 - q1), length(q0 - q2), length(q1 - q0));
    vec3 least = twice_area > 0.0 ? EDGE_MARGIN * edges / twice_area : vec3(0.0);
    bvec3 flat_edge = bvec3((flat_edges & 1u) != 0u, (flat_edges & 2u) != 0u, (flat_edges & 4u) != 0u);
    least = mix(least, vec3(0.0), flat_edge);
    if (least.x + least.y + least.z >= 1.0) {
        // A triangle too small to keep that margin: its centroid.
        return (p0 + p1 + p2) * (1.0 / 3.0);
    }
    vec3 kept = max(b, least);
    kept /= kept.x + kept.y + kept.z;
    return kept.x * p0 + kept.y * p1 + kept.z * p2;
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
