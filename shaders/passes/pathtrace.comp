// pathtrace: unidirectional path tracing from the G-buffer's primary hit. Next-event estimation
// to the area lights (light chosen in proportion to lum(power), uniform point on the triangle) and
// cosine BSDF sampling, combined by MIS with the power heuristic. Russian roulette from the 3rd
// bounce with survival clamp(max channel of the path throughput, 0.05, 0.95).
// Never uses VPLs: this is the ground truth.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/scene.glsl"
#include "../lib/random.glsl"
#include "../lib/brdf.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 1, binding = 0, std430) readonly buffer SurfaceBuffer { Surface surfaces[]; };
layout(set = 1, binding = 1, std430) writeonly buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 2, std430) buffer RayCounter { uint ray_count[]; };

const uint SALT_PATHTRACE = 0x7074u;
const int RR_START_BOUNCE = 3;

// Light-selection pdf per unit area of any point on an emitter with radiance `le`: P(t) / A_t with
// P(t) = lum(Phi_t) / sum lum(Phi), Phi_t = sides * pi * Le * A_t.
float light_pdf_area(vec3 le, bool double_sided) {
    float sides = double_sided ? 2.0 : 1.0;
    return frame.total_light_power > 0.0 ? sides * PI * luminance(le) / frame.total_light_power : 0.0;
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    Surface s = surfaces[surface_slot(index)];
    if (s.hit_t < 0.0) {
        samples[index] = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    uint rng = rng_init(pixel.x, pixel.y, frame.frame_index, frame.seed ^ SALT_PATHTRACE);
    uint rays = 0u;

    vec3 radiance = s.emission;
    vec3 throughput = vec3(1.0);
    vec3 x = s.position;
    vec3 ng = s.geometric_normal;
    vec3 ns = s.shading_normal;
    vec3 albedo = s.albedo;

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
            uint li = sample_light_index(rand(rng));
            Light l = lights[li];
            if ((l.flags & LIGHT_POINT) != 0u) {
                // A point light (delta): radiant intensity I, no MIS.
                vec3 to_light = l.p0 - x;
                float d2 = dot(to_light, to_light);
                vec3 wi = to_light * inversesqrt(max(d2, 1e-30));
                float cos_x = dot(ns, wi);
                if (cos_x > 0.0 && dot(ng, wi) > 0.0 && d2 > 0.0) {
                    rays += 1u;
                    if (segment_visible(offset_ray(x, ng, frame.scene_scale), l.p0)) {
                        radiance += throughput * lambert_brdf(albedo) * l.emission * (cos_x / (d2 * l.pdf));
                    }
                }
                // Consume the same random numbers as an area light would (keeps streams aligned).
                rand2(rng);
            } else {
            vec3 bc = sample_triangle_barycentrics(rand2(rng));
            vec3 y = bc.x * l.p0 + bc.y * l.p1 + bc.z * l.p2;
            vec3 nl = normalize(cross(l.p1 - l.p0, l.p2 - l.p0));
            vec3 to_light = y - x;
            float d2 = dot(to_light, to_light);
            float d = sqrt(d2);
            vec3 wi = to_light / d;
            float cos_x = dot(ns, wi);
            float cos_l_signed = -dot(nl, wi);
            bool double_sided = (l.flags & MATERIAL_DOUBLE_SIDED) != 0u;
            bool emits = double_sided ? cos_l_signed != 0.0 : cos_l_signed > 0.0;
            if (cos_x > 0.0 && dot(ng, wi) > 0.0 && emits && d2 > 0.0) {
                float cos_l = abs(cos_l_signed);
                float pdf_light = (l.pdf / l.area) * d2 / cos_l;
                float w = power_heuristic(pdf_light, lambert_pdf(cos_x));
                vec3 nl_toward_x = cos_l_signed > 0.0 ? nl : -nl;
                rays += 1u;
                if (segment_visible(offset_ray(x, ng, frame.scene_scale), offset_ray(y, nl_toward_x, frame.scene_scale))) {
                    radiance += throughput * lambert_brdf(albedo) * l.emission * (cos_x * w / pdf_light);
                }
            }
            }
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
        if (!trace_closest(offset_ray(x, ng, frame.scene_scale), wi, 1e30, hit, t)) {
            break;
        }
        Material m = materials[hit.material];
        bool double_sided = (m.flags & MATERIAL_DOUBLE_SIDED) != 0u;
        if (max3(m.emission) > 0.0 && (hit.front_face || double_sided)) {
            float cos_l = abs(dot(hit.geometric_normal, wi));
            float pdf_light = cos_l > 0.0 ? light_pdf_area(m.emission, double_sided) * t * t / cos_l : 0.0;
            radiance += throughput * m.emission * power_heuristic(pdf_bsdf, pdf_light);
        }
        x = hit.position;
        ng = hit.geometric_normal;
        ns = hit.shading_normal;
        albedo = hit_albedo(hit);
    }
    samples[index] = vec4(radiance, 1.0);
    atomicAdd(ray_count[RAYS_PATHTRACE], rays);
}
