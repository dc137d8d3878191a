// BRDFs and colour helpers. Binding-free.
#ifndef BRDF_GLSL
#define BRDF_GLSL

#include "sampling.glsl"

// Rec. 709 luminance, as in docs/method.md.
float luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

float max3(vec3 v) {
    return max(v.x, max(v.y, v.z));
}

// Lambertian BRDF value f = rho / pi (two-sided: the caller orients normals).
vec3 lambert_brdf(vec3 albedo) {
    return albedo * INV_PI;
}

// Solid-angle pdf of cosine-weighted hemisphere sampling.
float lambert_pdf(float cos_theta) {
    return max(cos_theta, 0.0) * INV_PI;
}

#endif
