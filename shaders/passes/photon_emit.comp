// photon_emit: virtual point lights from the area lights (docs/method.md). Lights are
// chosen by inverting their CDF (push constant `light_count` entries), never from the frame constants.
//   PHOTON_EMIT_DIRECT, direct VPLs: sample i of N_d picks light t by inverting the light CDF at
//     the stratified u = (i + xi) / N_d (in 32-bit fixed point, rotated by one random word per
//     seed, so each u is exactly uniform), a uniform point on it, and gets flux Phi_t / (N_d P(t)),
//     P(t) the width of t's interval in the table (the probability it is really chosen with).
//   PHOTON_EMIT_PATHS, photon paths: each path starts like a direct sample (u: 32 random bits) with
//     flux Phi_t / P(t) in a cosine direction; at each hit it stores a VPL with flux
//     Phi * albedo * (ns.wi / ng.wi) (the shading normal's adjoint factor, 1 on flat surfaces;
//     normal ng toward the incoming photon) and bounces (cosine about ng) with that flux; Russian roulette after min_bounces
//     on the throughput relative to the start, survival clamp(max channel, 0.05, 0.95). The 1/P of
//     the path count is applied afterwards by PHOTON_EMIT_SCALE, once the number of traced paths is
//     known.
//   PHOTON_EMIT_SCALE, normalise: multiplies the flux of VPLs base + first .. + count by `scale`.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/trace.glsl"
#include "../lib/random.glsl"
#include "../lib/brdf.glsl"
#include "../lib/packing.glsl"

#ifndef RT_PIPELINE
layout(local_size_x = 64) in;
#endif
// after the local size: dispatch_index() reads gl_WorkGroupSize
#include "../lib/dispatch.glsl"

layout(set = 1, binding = 0, std430) buffer VplBuffer { Vpl vpls[]; };
// indirect_count: VPL slots taken; next_path: paths of this dispatch handed out; rays: closest-hit
// rays traced by this dispatch (both zeroed per batch; bench --rays reads the rays).
layout(set = 1, binding = 1, std430) buffer VplCounter { uint indirect_count; uint next_path; uint rays; } counters;
// The end of each light's interval in units of 2^-32 (photon_emit.rs's light_cdf); the last entry
// stands for 2^32.
layout(set = 1, binding = 2, std430) readonly buffer LightCdf { uint light_cdf[]; };

layout(push_constant) uniform Push {
    uint mode;         // PHOTON_EMIT_*
    uint first;        // first sample / path index of this dispatch
    uint count;        // samples / paths / VPLs in this dispatch
    uint total;        // N_d (PHOTON_EMIT_DIRECT)
    uint base;         // first VPL slot of the region written
    uint capacity;     // indirect slots available (PHOTON_EMIT_PATHS)
    uint min_bounces;
    uint max_bounces;
    uint seed;
    float scale;       // PHOTON_EMIT_SCALE
    uint light_count;  // entries of light_cdf
};

const uint SALT_DIRECT = 0x64697265u;
const uint SALT_PATHS = 0x70617468u;

// Smallest t with u < cdf[t], the last entry counting as 2^32 (never read).
uint invert_light_cdf(uint u) {
    uint lo = 0u;
    uint hi = light_count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (u < light_cdf[mid]) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

// The probability that invert_light_cdf picks t for a uniform 32-bit u: its interval's width.
// Zero only for the whole range (one light takes it all): a light of width 0 is never picked.
float light_choice_pdf(uint t) {
    uint lo = t == 0u ? 0u : light_cdf[t - 1u];
    uint hi = t + 1u == light_count ? 0u : light_cdf[t];
    uint width = hi - lo;  // modulo 2^32, so the last light's width is 2^32 - lo
    return width == 0u ? 1.0 : float(width) * (1.0 / 4294967296.0);
}

struct LightSample {
    vec3 position;
    float offset_scale;  // offset_ray's scale of the light's triangle
    vec3 normal;  // the emitting side
    vec3 power_over_pdf;  // Phi_t / P(t)
};

LightSample sample_light_point(uint t, inout Rng rng) {
    Light l = light_texels(lights, t);
    float pdf = light_choice_pdf(t);
    if ((l.flags & LIGHT_POINT) != 0u) {
        // Isotropic: power 4 pi I; `normal` is a uniform direction, used only to start photons.
        LightSample s;
        s.position = l.p0;
        s.offset_scale = 0.0;  // a point: never offset
        s.normal = sample_uniform_sphere(rand2(rng));
        s.power_over_pdf = l.emission * (4.0 * PI / pdf);
        return s;
    }
    vec3 b = sample_triangle_barycentrics(rand2(rng));
    LightSample s;
    s.position = b.x * l.p0 + b.y * l.p1 + b.z * l.p2;
    s.offset_scale = triangle_offset_scale(l.p0, l.p1, l.p2);
    s.normal = triangle_normal(l.p0, l.p1, l.p2);
    float sides = 1.0;
    if ((l.flags & MATERIAL_DOUBLE_SIDED) != 0u) {
        // Each face emits pi Le A: pick one with probability 1/2, the flux covers both.
        sides = 2.0;
        if (rand(rng) < 0.5) {
            s.normal = -s.normal;
        }
    }
    s.power_over_pdf = l.emission * (sides * PI * l.area / pdf);
    return s;
}

void direct_vpl(uint i) {
    Rng rng = rng_init(i, 0u, seed, SALT_DIRECT);
    // Stratum i in fixed point (float rounding only moves the strata a little), plus a rotation
    // shared by all i: any point plus a uniform 32-bit rotation is uniform, so P(t) is exact.
    float stratified = (float(i) + rand(rng)) / float(total) * 4294967296.0;
    Rng rotation = rng_init(0u, 2u, seed, SALT_DIRECT);
    uint t = invert_light_cdf(uint(min(stratified, 4294967040.0)) + rng_next(rotation));
    LightSample s = sample_light_point(t, rng);
    bool point = (light_texels(lights, t).flags & LIGHT_POINT) != 0u;
    Vpl v;
    v.position = point ? s.position : offset_ray(s.position, s.normal, s.offset_scale);
    v.kind = point ? VPL_DIRECT_POINT : VPL_DIRECT_AREA;
    v.normal = oct_quantize(s.normal);  // as its VplCandidate code stores it
    v.path = i;
    v.flux = s.power_over_pdf / float(total);
    v.yuksel_r2 = 0.0;  // per-VPL radii are set on the host (vpl_radius.rs) when asked for
    vpls[base + i] = v;
}

// The state of one photon path between bounces.
struct PhotonPath {
    uint index;
    Rng rng;
    uint bounce;   // the bounce whose hit the next ray looks for (1 = first)
    vec3 phi0;
    vec3 phi;
    vec3 origin;
    vec3 dir;
    bool from_point;  // the first segment of a point light's photon (see trace_segment)
};

PhotonPath start_path(uint p) {
    PhotonPath path;
    path.index = p;
    path.rng = rng_init(p, 1u, seed, SALT_PATHS);
    uint t = invert_light_cdf(rng_next(path.rng));
    LightSample s = sample_light_point(t, path.rng);
    path.phi0 = s.power_over_pdf;
    path.phi = path.phi0;
    bool point = (light_texels(lights, t).flags & LIGHT_POINT) != 0u;
    path.origin = point ? s.position : offset_ray(s.position, s.normal, s.offset_scale);
    path.dir = point ? s.normal : sample_cosine_hemisphere(s.normal, rand2(path.rng));
    path.bounce = 1u;
    path.from_point = point;
    return path;
}

// Traces one segment of `path`: stores a VPL at its hit and prepares the next segment. Returns
// false when the path has ended.
bool trace_segment(inout PhotonPath path) {
    Hit hit;
    float dist;
    if (!trace_closest(path.origin, path.dir, 1e30, hit, dist)) {
        return false;  // left the scene
    }
    if (path.from_point) {
        path.from_point = false;
        // A point light that lies in a surface (lies_in_hit_plane: within 4 ulps of its plane):
        // half its photons met that surface from behind, left VPLs facing away from the light and
        // bounced out of the room (a bulb placed on the Cornell box's floor: the VPL modes read
        // 1.13x the path tracer). The path tracer sees such a light at cos 0 from the surface,
        // which it does not light, and its shadow rays pass it (segment_visible_to_point): the
        // photon goes on past the plane, on its own side (upward ones into the room, downward
        // ones out through the floor).
        if (lies_in_hit_plane(path.origin, hit)) {
            path.origin = offset_ray(hit.position, -hit.geometric_normal, hit.offset_scale);
            return true;  // the same segment again, from past the plane
        }
    }
    // Shading normals (Veach's adjoint correction, on the photon's side): the path tracer and the
    // VPL shading reflect rho/pi * max(0, ns.wi) of the incoming radiance, while a photon's flux
    // is per unit of geometric area, which counts ng.wi of it: each photon carries ns.wi / ng.wi.
    // The reflected radiance is the same in every direction of ng's hemisphere, so the VPL emits
    // about ng and the next photon leaves cosine-distributed about ng. Without it the VPL modes
    // were 2.6 % too bright on a ceiling lit from a smooth-shaded 24-triangle sphere (flat: no
    // difference; docs/method.md). 1 where ns = ng.
    vec3 wi = -path.dir;
    float cos_geometric = dot(hit.geometric_normal, wi);
    float cos_shading = dot(hit.shading_normal, wi);
    float adjoint = cos_geometric > 0.0 && cos_shading > 0.0 ? cos_shading / cos_geometric : 0.0;
    path.phi *= hit_albedo(hit) * adjoint;
    // At a grazing hit (ng.wi near the smallest floats) the factor can overflow, and 0 * inf in a
    // channel of albedo 0 is NaN: such a photon ends there, storing nothing, rather than leave a
    // VPL of non-finite flux (it carries a vanishing share of the light: hits are dense in ng.wi).
    if (!is_finite(path.phi) || max3(path.phi) <= 0.0) {
        return false;
    }
    uint slot = atomicAdd(counters.indirect_count, 1u);
    if (slot < capacity) {
        Vpl v;
        v.position = offset_ray(hit.position, hit.geometric_normal, hit.offset_scale);
        v.kind = VPL_INDIRECT;
        v.normal = oct_quantize(hit.geometric_normal);  // faces the incoming photon; quantized as VplCandidate stores it
        v.path = path.index;
        v.flux = path.phi;
        v.yuksel_r2 = 0.0;
        vpls[base + slot] = v;
    }
    if (path.bounce == max_bounces) {
        return false;
    }
    if (path.bounce >= min_bounces) {
        // Survival ∝ the throughput left, per channel against its start; a channel the light
        // does not emit (phi0 = 0, e.g. a pure red light) would be 0 / 0 and is left out.
        vec3 left = vec3(path.phi0.x > 0.0 ? path.phi.x / path.phi0.x : 0.0,
                         path.phi0.y > 0.0 ? path.phi.y / path.phi0.y : 0.0,
                         path.phi0.z > 0.0 ? path.phi.z / path.phi0.z : 0.0);
        float q = clamp(max3(left), 0.05, 0.95);
        if (rand(path.rng) >= q) {
            return false;
        }
        path.phi /= q;
    }
    path.dir = sample_cosine_hemisphere(hit.geometric_normal, rand2(path.rng));
    if (dot(path.dir, hit.geometric_normal) <= 0.0) {
        return false;
    }
    path.origin = offset_ray(hit.position, hit.geometric_normal, hit.offset_scale);
    path.bounce += 1u;
    return true;
}

// Paths first .. first + count - 1, handed out one at a time from counters.next_path: an
// invocation whose path ends takes the next one at once, so on SIMD hardware (GPU warps,
// lavapipe's 8-wide lanes) every lane traces a ray in every iteration until the batch runs out,
// instead of waiting for the longest path of its group. Which invocation traces a path changes
// nothing: a path's random numbers come from its index alone.
void photon_paths() {
    PhotonPath path;
    bool alive = false;
    uint rays = 0u;
    for (;;) {
        if (!alive) {
            uint p = atomicAdd(counters.next_path, 1u);
            if (p >= count) {
                break;
            }
            path = start_path(first + p);
            alive = true;
        }
        alive = trace_segment(path);
        rays += 1u;
    }
    if (rays > 0u) {
        atomicAdd(counters.rays, rays);  // once per invocation, not per ray
    }
}

void main() {
    uint k = dispatch_index();
    if (k >= count) {
        return;
    }
    if (mode == PHOTON_EMIT_DIRECT) {
        direct_vpl(first + k);
    } else if (mode == PHOTON_EMIT_PATHS) {
        photon_paths();
    } else {
        vpls[base + first + k].flux *= scale;
    }
}
