// The contribution of one VPL to a surface point, as in docs/method.md:
//   c_i(x) = (rho_x/pi) * I_i(w) * max(0, -n_x.w) * G(d) * V(x, y_i),  w = (x - y_i)/d,
// with I_i(w) = Phi_i max(0, n_i.w)/pi for a cosine VPL and Phi_i/(4 pi) for a point-light VPL.
// G is 1/d^2 or Yuksel's non-singular 2/(d^2 + r^2 + d sqrt(d^2 + r^2)), with one r for every VPL
// (p.yuksel_r2) or, with VPL_FLAG_PER_VPL_RADIUS, each VPL's own (Vpl.yuksel_r2, from its nearest
// VPLs). Visibility is the caller's (shadow rays need the scene bindings). Binding-free.
#ifndef VPL_GLSL
#define VPL_GLSL

#include "../common/types.glsl"
#include "../lib/brdf.glsl"
#include "../lib/packing.glsl"

// Geometry term: inverse square, or Yuksel's form, which is finite at d = 0 (2/r^2) and tends to
// 1/d^2 when d >> r.
float vpl_attenuation(float d2, uint mode, float r2) {
    if (mode == ATTENUATION_YUKSEL) {
        return 2.0 / (d2 + r2 + sqrt(d2) * sqrt(d2 + r2));
    }
    return 1.0 / d2;
}

// The share of the true geometry term 1/d^2 that Yuksel's kernel leaves out, in solid angle:
// w(d) = 1 - d^2 G_r(d). With s = sqrt(d^2 + r^2) it is r^2 (s + 2d) / (s (s + d)^2), which has no
// cancellation: 1 at d = 0, 0.414 at d = r, ~3r^2/(4d^2) for d >> r. 0 for r = 0 (inverse square).
// Computed as (r^2/s^2) (1 + 2a) / (1 + a)^2 with a = d/s in [0, 1]: every factor is at most 1 (the
// cube s (s + d)^2 overflowed 32-bit floats for r above ~1e12, which made the residual 0).
float yuksel_residual(float d2, float r2) {
    if (!(r2 > 0.0)) {
        return 0.0;
    }
    float s2 = d2 + r2;
    float a = sqrt(d2 / s2);
    return clamp((r2 / s2) * (1.0 + 2.0 * a) / ((1.0 + a) * (1.0 + a)), 0.0, 1.0);
}

bool vpl_kind_enabled(uint kind, uint kind_mask) {
    uint bit = kind == VPL_INDIRECT ? KIND_MASK_INDIRECT : KIND_MASK_DIRECT;
    return (kind_mask & bit) != 0u;
}

// The scalar part of a VPL's unshadowed contribution to point x (shading normal ns, geometric normal
// ng, both facing the viewer's side): (1/pi) emit cos_x G(d), with emit = max(0, ny.w) for a cosine
// VPL (unit normal ny) and 1/4 for a point-light VPL, and r2 the VPL's Yuksel r^2 (vpl_r2). Zero
// when the VPL lies behind either surface, coincides with x, or its kind is masked out. Never
// NaN/Inf for finite inputs: no absolute distance is too small (a scene may be 1e-10 units across),
// only a contribution past f32's range (inverse square within ~1e-19 of the VPL) counts as zero.
float vpl_geometry(vec3 y, uint kind, vec3 ny, float r2, vec3 x, vec3 ns, vec3 ng, VplParams p) {
    if (!vpl_kind_enabled(kind, p.kind_mask)) {
        return 0.0;
    }
    vec3 to_x = x - y;
    float d2 = dot(to_x, to_x);
    if (!(d2 > 0.0)) {
        return 0.0;  // on the point itself: the cosines are undefined (and zero in the limit)
    }
    vec3 w = to_x * inversesqrt(d2);
    float cos_x = -dot(ns, w);
    float emit = kind == VPL_DIRECT_POINT ? 0.25 : dot(ny, w);
    if (cos_x <= 0.0 || dot(ng, w) >= 0.0 || emit <= 0.0) {
        return 0.0;
    }
    float g = INV_PI * emit * cos_x * vpl_attenuation(d2, p.attenuation, r2);
    return g <= 3.0e38 ? g : 0.0;
}

// Yuksel's r^2 of VPL v: its own with VPL_FLAG_PER_VPL_RADIUS, else the one of every VPL.
float vpl_r2(float own_r2, VplParams p) {
    return (p.flags & VPL_FLAG_PER_VPL_RADIUS) != 0u ? own_r2 : p.yuksel_r2;
}

// Unshadowed contribution of a VPL (position y, kind, unit normal ny, flux, Yuksel r2) to x
// (albedo rho).
vec3 vpl_contribution_at(vec3 y, uint kind, vec3 ny, vec3 flux, float r2, vec3 x, vec3 ns, vec3 ng, vec3 rho, VplParams p) {
    return lambert_brdf(rho) * flux * vpl_geometry(y, kind, ny, r2, x, ns, ng, p);
}

vec3 vpl_contribution(Vpl v, vec3 x, vec3 ns, vec3 ng, vec3 rho, VplParams p) {
    return vpl_contribution_at(v.position, v.kind, v.normal, v.flux, vpl_r2(v.yuksel_r2, p), x, ns, ng, rho, p);
}

// The compact copy of VPL `index` that the RIS candidate loop reads. Its normal decodes to v.normal
// (up to float rounding) because the photon pass stores normals already octahedral-quantized.
VplCandidate vpl_candidate(Vpl v, uint index) {
    VplCandidate c;
    c.position = v.position;
    c.vpl_kind = index | (v.kind << CANDIDATE_INDEX_BITS);
    c.flux = v.flux;
    c.normal_oct = oct_encode(v.normal);
    return c;
}

uint candidate_index(VplCandidate c) {
    return c.vpl_kind & ((1u << CANDIDATE_INDEX_BITS) - 1u);
}

// The RIS source pdf q(i) of a VPL of flux Phi: 1/N (uniform), or lum(Phi) / sum lum through the
// alias table (power source).
float vpl_source_pdf(vec3 flux, VplParams p) {
    return p.source == 1u ? luminance(flux) / p.total_vpl_lum : 1.0 / float(p.vpl_count);
}

// The resampling target p^ (without visibility) of a VPL at x: the luminance of its unshadowed
// contribution, lum(rho Phi) / pi times the geometry, as a scalar (the candidate loop's inner step;
// every pass evaluates targets through this one function).
float vpl_target_at(vec3 y, uint kind, vec3 ny, vec3 flux, float r2, vec3 x, vec3 ns, vec3 ng, vec3 rho, VplParams p) {
    return luminance(rho * flux) * (INV_PI * vpl_geometry(y, kind, ny, r2, x, ns, ng, p));
}

float vpl_target(Vpl v, vec3 x, vec3 ns, vec3 ng, vec3 rho, VplParams p) {
    return vpl_target_at(v.position, v.kind, v.normal, v.flux, vpl_r2(v.yuksel_r2, p), x, ns, ng, rho, p);
}

// The compact record has no room for a per-VPL radius: the caller passes vpl_r2 of the VPL's own
// (read from the full record only when VPL_FLAG_PER_VPL_RADIUS is set).
float candidate_target(VplCandidate c, float r2, vec3 x, vec3 ns, vec3 ng, vec3 rho, VplParams p) {
    return vpl_target_at(c.position, c.vpl_kind >> CANDIDATE_INDEX_BITS, oct_decode(c.normal_oct), c.flux, r2, x, ns, ng, rho, p);
}

#endif
