// Next-event estimation to the scene's lights, shared by the path tracer and the bias
// compensation: one light chosen in proportion to lum(power) (alias table), a uniform point on it,
// one shadow ray; combined with cosine BSDF sampling by MIS (power heuristic) for area lights.
// Uses set 0 (lights, TLAS) through scene.glsl.
#ifndef DIRECT_LIGHT_GLSL
#define DIRECT_LIGHT_GLSL

#include "trace.glsl"
#include "../lib/brdf.glsl"
#include "../lib/random.glsl"
#include "../lib/sampling.glsl"
#include "../restir/vpl.glsl"

// Every light sample counts whole (the path tracer).
const float NEE_UNCLAMPED = -1.0;

// Light-selection pdf per unit area of any point on an emitter with radiance `le`: P(t) / A_t with
// P(t) = lum(Phi_t) / sum lum(Phi), Phi_t = sides * pi * Le * A_t.
float light_pdf_area(vec3 le, bool double_sided) {
    float sides = double_sided ? 2.0 : 1.0;
    return frame.total_light_power > 0.0 ? sides * PI * luminance(le) / frame.total_light_power : 0.0;
}

// Reflected radiance at x (geometric normal ng, shading normal ns, offset_ray scale x_scale, albedo rho) from one light
// sample. `residual_r2` < 0: the light counts whole; otherwise each sample is weighted by Yuksel's
// residual w(d) = 1 - d^2 G_r(d) for r^2 = residual_r2 (the light the clamped VPLs leave out).
// Consumes four random numbers whatever the light.
vec3 next_event(vec3 x, vec3 ng, vec3 ns, float x_scale, vec3 rho, float residual_r2, inout Rng rng, inout uint rays) {
    uint slot_bits = rng_next(rng);
    uint keep_bits = rng_next(rng);
    uint li = sample_light_index(slot_bits, keep_bits);
    Light l = light_texels(lights, li);
    vec2 u = rand2(rng);
    if ((l.flags & LIGHT_POINT) != 0u) {
        // A point light (delta): radiant intensity I, no MIS.
        vec3 to_light = l.p0 - x;
        float d2 = dot(to_light, to_light);
        vec3 wi = to_light * inversesqrt(max(d2, 1e-30));
        float cos_x = dot(ns, wi);
        float weight = residual_r2 < 0.0 ? 1.0 : yuksel_residual(d2, residual_r2);
        // (d2 × pdf underflowing to 0 made the sample infinite.)
        if (cos_x > 0.0 && dot(ng, wi) > 0.0 && d2 * l.pdf > 0.0 && weight > 0.0) {
            rays += 1u;
            if (segment_visible_to_point(offset_ray(x, ng, x_scale), l.p0)) {
                return lambert_brdf(rho) * l.emission * (weight * cos_x / (d2 * l.pdf));
            }
        }
        return vec3(0.0);
    }
    vec3 bc = sample_triangle_barycentrics(u);
    vec3 y = bc.x * l.p0 + bc.y * l.p1 + bc.z * l.p2;
    vec3 nl = triangle_normal(l.p0, l.p1, l.p2);
    vec3 to_light = y - x;
    float d2 = dot(to_light, to_light);
    float d = sqrt(d2);
    vec3 wi = to_light / d;
    float cos_x = dot(ns, wi);
    float cos_l_signed = -dot(nl, wi);
    bool double_sided = (l.flags & MATERIAL_DOUBLE_SIDED) != 0u;
    bool emits = double_sided ? cos_l_signed != 0.0 : cos_l_signed > 0.0;
    float weight = residual_r2 < 0.0 ? 1.0 : yuksel_residual(d2, residual_r2);
    if (cos_x > 0.0 && dot(ng, wi) > 0.0 && emits && d2 > 0.0 && weight > 0.0) {
        float cos_l = abs(cos_l_signed);
        // Divided by the probability this sample was drawn with (l.pdf: the alias table's exact
        // pick probability, src/lights.rs alias_pdfs); weighted by MIS with the pdf
        // emission_hit_mis gives the same point (lum(Phi_t) / sum, which differs from l.pdf by
        // about light count / 2^32), so that the two strategies' weights sum to 1 exactly.
        float pdf_light = (l.pdf / l.area) * d2 / cos_l;
        float w = power_heuristic(light_pdf_area(l.emission, double_sided) * d2 / cos_l, lambert_pdf(cos_x));
        vec3 nl_toward_x = cos_l_signed > 0.0 ? nl : -nl;
        // (A selection pdf that underflowed to 0 made w / pdf_light 0 / 0.)
        if (pdf_light > 0.0) {
            rays += 1u;
            if (segment_visible(offset_ray(x, ng, x_scale), offset_ray(y, nl_toward_x, triangle_offset_scale(l.p0, l.p1, l.p2)))) {
                return lambert_brdf(rho) * l.emission * (weight * cos_x * w / pdf_light);
            }
        }
    }
    return vec3(0.0);
}

// The MIS weight of an emitter with radiance `le` hit by a cosine-sampled ray (pdf `pdf_bsdf`) at
// distance t, cosine cos_l at the emitter: the BSDF strategy's share against next_event's.
float emission_hit_mis(vec3 le, bool double_sided, float pdf_bsdf, float t, float cos_l) {
    float pdf_light = cos_l > 0.0 ? light_pdf_area(le, double_sided) * t * t / cos_l : 0.0;
    return power_heuristic(pdf_bsdf, pdf_light);
}

#endif
