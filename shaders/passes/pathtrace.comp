// pathtrace: unidirectional path tracing from the G-buffer's primary hit. Next-event estimation
// to the area lights (light chosen in proportion to lum(power), uniform point on the triangle) and
// cosine BSDF sampling, combined by MIS with the power heuristic. Russian roulette from the 3rd
// bounce with survival clamp(max channel of the path throughput, 0.05, 0.95).
// Never uses VPLs: this is the ground truth.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/direct_light.glsl"
#include "../lib/random.glsl"
#include "../lib/brdf.glsl"
#include "../common/texel_records.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;
#endif
#include "../lib/dispatch.glsl"

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1, std430) writeonly buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 2, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"

const uint SALT_PATHTRACE = 0x7074u;
const int RR_START_BOUNCE = 3;

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    Surface s = surface_texels(surfaces, surface_slot(index));
    if (s.offset_scale < 0.0) {
        samples[index] = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    Rng rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_PATHTRACE);
    uint rays = 0u;

    vec3 radiance = s.emission;
    vec3 throughput = vec3(1.0);
    vec3 x = s.position;
    vec3 ng = s.geometric_normal;
    vec3 ns = s.shading_normal;
    vec3 albedo = s.albedo;
    float x_scale = s.offset_scale;

    for (int bounce = 1; frame.max_bounces < 0 || bounce <= frame.max_bounces; ++bounce) {
        if (bounce >= RR_START_BOUNCE) {
            float q = clamp(max3(throughput), 0.05, 0.95);
            if (rand(rng) >= q) {
                break;
            }
            throughput /= q;
        }

        // Next-event estimation.
        if (frame.light_count > 0u) {
            radiance += throughput * next_event(x, ng, ns, x_scale, albedo, NEE_UNCLAMPED, rng, rays);
        }

        // BSDF sampling: cosine-weighted, f * cos / pdf = albedo.
        vec3 wi = sample_cosine_hemisphere(ns, rand2(rng));
        float cos_x = dot(ns, wi);
        if (cos_x <= 0.0 || dot(ng, wi) <= 0.0) {
            break;
        }
        float pdf_bsdf = lambert_pdf(cos_x);
        throughput *= albedo;
        Hit hit;
        float t;
        rays += 1u;
        if (!trace_closest(offset_ray(x, ng, x_scale), wi, 1e30, hit, t)) {
            break;
        }
        Material m = material_texels(materials, hit.material);
        bool double_sided = (m.flags & MATERIAL_DOUBLE_SIDED) != 0u;
        if (max3(m.emission) > 0.0 && (hit.front_face || double_sided)) {
            float cos_l = abs(dot(hit.geometric_normal, wi));
            radiance += throughput * m.emission * emission_hit_mis(m.emission, double_sided, pdf_bsdf, t, cos_l);
        }
        x = hit.position;
        ng = hit.geometric_normal;
        ns = hit.shading_normal;
        x_scale = hit.offset_scale;
        albedo = hit_albedo(hit);
    }
    samples[index] = vec4(radiance, 1.0);
    count_rays(RAYS_PATHTRACE, rays);
}
