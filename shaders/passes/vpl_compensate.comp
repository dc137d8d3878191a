// vpl_compensate: bias compensation for Yuksel's clamped kernel (Kollig & Keller 2004), added to the
// frame's VPL estimate. The VPL sum with G_r keeps the share d^2 G_r(d) of the light that reaches x
// from a surface at distance d; the rest,
//   R(x) = integral over the hemisphere of (rho_x/pi) L(y(w) -> x) cos(theta_x) w_r(d) dw,
// w_r(d) = 1 - d^2 G_r(d), is estimated with one cosine-sampled ray: at its hit y,
//   R^(x) = rho_x w_r(d) / q * (Le(y -> x) + VPL estimate at y + R^(y)),
// the VPL estimate at y being RIS over the VPL set with one shadow ray (unbiased for the sum at y),
// and the recursion ended by Russian roulette on the weight: continue with
// q = min(0.95, w_r(d) max(rho)). No distance cut-off. In expectation over VPL sets, VPL sum + R
// equals the path tracer's answer whatever r (docs/method.md).
// `first_hop` says what the pixel's image holds (--view direct: emission only; indirect: no
// emission at the first hop; final: both); later hops always carry everything.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/vpl_target.glsl"
#include "../common/direct_light.glsl"
#include "../lib/random.glsl"
#include "../lib/sampling.glsl"
#include "../common/texel_records.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;
#endif
#include "../lib/dispatch.glsl"

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2, std430) buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 3, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"

layout(push_constant) uniform Push {
    VplParams params;
    uint first_hop;  // COMPENSATE_* bits
} pc;

const uint SALT_COMPENSATE = 0x636fu;
// A safety net only: every hop survives with q <= 0.95, so reaching it has probability < 2e-6.
const int MAX_HOPS = 256;

// RIS over the whole VPL set at surface s (uniform source, `candidates` draws, target = lum of the
// unshadowed contribution) with one shadow ray for the pick: an unbiased estimate of sum_i c_i(s).
vec3 vpl_estimate(Surface s, VplParams p, inout Rng rng, inout uint rays) {
    uint m = max(p.candidates, 1u);
    float w_sum = 0.0;
    uint pick = 0u;
    float pick_target = 0.0;
    for (uint j = 0u; j < m; ++j) {
        uint i = rand_index(rng, p.vpl_count);
        float t = vpl_target(vpl_texels(vpls, i), s.position, s.shading_normal, s.geometric_normal, s.albedo, p);
        w_sum += t;
        if (t > 0.0 && rand(rng) * w_sum < t) {
            pick = i;
            pick_target = t;
        }
    }
    if (!(pick_target > 0.0)) {
        return vec3(0.0);
    }
    Vpl v = vpl_texels(vpls, pick);
    rays += 1u;
    if (!vpl_visible(s, v)) {
        return vec3(0.0);
    }
    // W = (sum_j t_j / (m p)) / t(pick), p = 1/N, in an order that overflows last (w_sum * N
    // passed 3.4e38 first, with a tiny --yuksel-radius); a W past floats empties the estimate, as
    // stream_finish empties a reservoir, instead of an Inf whose product with a zero channel is NaN.
    float ucw = (w_sum / pick_target) * (float(p.vpl_count) / float(m));
    if (!is_finite(ucw)) {
        return vec3(0.0);
    }
    return surface_vpl_contribution(s, v, p) * ucw;
}

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    Surface s = surface_texels(surfaces, surface_slot(index));
    VplParams p = pc.params;
    if (s.offset_scale < 0.0 || p.vpl_count == 0u) {
        return;
    }
    // Later hops see every VPL, whatever the view.
    VplParams all = p;
    all.kind_mask = KIND_MASK_DIRECT | KIND_MASK_INDIRECT;
    Rng rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_COMPENSATE);
    uint rays = 0u;
    vec3 added = vec3(0.0);
    vec3 throughput = vec3(1.0);
    uint carry = pc.first_hop;
    for (int hop = 0; hop < MAX_HOPS && carry != 0u; ++hop) {
        // Emitters near s: next-event estimation weighted by the residual, MIS with the hit below.
        if ((carry & COMPENSATE_EMISSION) != 0u && frame.light_count > 0u) {
            added += throughput * next_event(s.position, s.geometric_normal, s.shading_normal, s.offset_scale, s.albedo, p.yuksel_r2, rng, rays);
        }
        vec3 wi = sample_cosine_hemisphere(s.shading_normal, rand2(rng));
        float cos_x = dot(s.shading_normal, wi);
        if (cos_x <= 0.0 || dot(s.geometric_normal, wi) <= 0.0) {
            break;
        }
        Hit hit;
        float t;
        rays += 1u;
        if (!trace_closest(offset_ray(s.position, s.geometric_normal, s.offset_scale), wi, 1e30, hit, t)) {
            break;
        }
        vec3 to_y = hit.position - s.position;
        float w = yuksel_residual(dot(to_y, to_y), p.yuksel_r2);
        float q = min(0.95, w * max3(s.albedo));
        if (!(q > 0.0) || rand(rng) >= q) {
            break;
        }
        // f cos / pdf = rho for cosine sampling.
        throughput *= s.albedo * (w / q);
        Material m = material_texels(materials, hit.material);
        bool double_sided = (m.flags & MATERIAL_DOUBLE_SIDED) != 0u;
        Surface y;
        y.position = hit.position;
        y.offset_scale = hit.offset_scale;
        y.shading_normal = hit.shading_normal;
        y.geometric_normal = hit.geometric_normal;
        y.albedo = hit_albedo(hit);
        y.emission = (hit.front_face || double_sided) ? m.emission : vec3(0.0);
        vec3 l = vec3(0.0);
        if ((carry & COMPENSATE_EMISSION) != 0u && max3(y.emission) > 0.0) {
            float cos_l = abs(dot(hit.geometric_normal, wi));
            l += y.emission * emission_hit_mis(m.emission, double_sided, lambert_pdf(cos_x), t, cos_l);
        }
        if ((carry & COMPENSATE_VPLS) != 0u) {
            l += vpl_estimate(y, all, rng, rays);
        }
        added += throughput * l;
        if ((carry & COMPENSATE_VPLS) == 0u) {
            break;  // direct light only: recursing would add indirect light
        }
        s = y;
        carry = COMPENSATE_EMISSION | COMPENSATE_VPLS;
    }
    samples[index].rgb += added;
    count_rays(RAYS_COMPENSATE, rays);
}
