// Not used by the renderer: runs the binding-free VPL and reservoir headers on the GPU for
// tests/vpl_math.rs. `pc.test` picks the case:
//  0: attenuation G(d) for (d2, r2, mode) triples in `inputs` -> `outputs[i].x`
//  1: vpl_contribution for the VPL/point pairs in `vpls`/`points` -> `outputs[i].xyz`
//  2: stream `pc.n` candidates with weights `inputs[j].x` through a reservoir; index -> `chosen[i]`,
//     and W * target of the chosen one -> `outputs[i].x` (should be sum w)
//  3: pairwise MIS weights for random confidences/targets: sum over all techniques -> `outputs[i].x`
//  4: the first `pc.n` numbers of the stream a pass seeds for pixel (i % 128, (i / 128) % 128) in
//     frame i / 16384 -> `chosen[i * n + j]`
//  5: pairwise MIS weights of one pair: `inputs[i]` = (m_i, p_i, m_c / k, p_c), `points[i].x` =
//     total confidence -> (neighbour weight, canonical weight) in `outputs[i].xy`
//  6: the ReGIR cell target: VPL `vpls[i]`, a cell's bounding sphere `inputs[i]` = (centre, radius),
//     a receiver `points[2i]` (position) with normal `points[2i+1]`, albedo 1 -> (pixel target,
//     cell target) in `outputs[i].xy`
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../lib/random.glsl"
#include "../restir/vpl.glsl"
#include "../restir/reservoir.glsl"
#include "../restir/regir.glsl"

layout(local_size_x = 64) in;
// after the local size: dispatch_index() reads gl_WorkGroupSize
#include "../lib/dispatch.glsl"

layout(set = 1, binding = 0, std430) readonly buffer Inputs { vec4 inputs[]; };
layout(set = 1, binding = 1, std430) readonly buffer Vpls { Vpl vpls[]; };
layout(set = 1, binding = 2, std430) readonly buffer Points { vec4 points[]; };
layout(set = 1, binding = 3, std430) writeonly buffer Outputs { vec4 outputs[]; };
layout(set = 1, binding = 4, std430) writeonly buffer Chosen { uint chosen[]; };

layout(push_constant) uniform Push {
    uint test;
    uint count;
    uint n;
    uint seed;
    VplParams params;
} pc;

void main() {
    uint i = dispatch_index();
    if (i >= pc.count) {
        return;
    }
    if (pc.test == 0u) {
        vec4 c = inputs[i];
        outputs[i] = vec4(vpl_attenuation(c.x, floatBitsToUint(c.z), c.y), 0.0, 0.0, 0.0);
    } else if (pc.test == 1u) {
        // points[2i] = position, points[2i+1] = normal (shading = geometric); albedo 1.
        vec3 x = points[2u * i].xyz;
        vec3 n = points[2u * i + 1u].xyz;
        outputs[i] = vec4(vpl_contribution(vpls[i], x, n, n, vec3(1.0), pc.params), 0.0);
    } else if (pc.test == 2u) {
        Rng rng = rng_init(i, 17u, 0u, pc.seed);
        ReservoirStream s = stream_begin();
        for (uint j = 0u; j < pc.n; ++j) {
            float w = inputs[j].x;
            float target = inputs[j].y;
            stream_update(s, j, w, target, rand(rng));
        }
        s.confidence = 3.0;
        Reservoir r = stream_finish(s);
        chosen[i] = r.vpl;
        outputs[i] = vec4(r.target, r.ucw, r.confidence, 0.0);
    } else if (pc.test == 3u) {
        Rng rng = rng_init(i, 29u, 0u, pc.seed);
        uint k = 1u + rand_index(rng, 8u);
        float mc = 1.0 + 20.0 * rand(rng);
        float m[8];
        float p[8];
        float total = mc;
        for (uint j = 0u; j < k; ++j) {
            m[j] = 1.0 + 20.0 * rand(rng);
            // Some techniques cannot produce the sample (target 0).
            p[j] = rand(rng) < 0.3 ? 0.0 : rand(rng) * 5.0;
            total += m[j];
        }
        float p_c = 0.01 + rand(rng);
        float sum = 0.0;
        for (uint j = 0u; j < k; ++j) {
            sum += pairwise_neighbour_weight(m[j], p[j], mc / float(k), p_c, total);
            sum += pairwise_canonical_weight(m[j], p[j], mc / float(k), p_c, total);
        }
        outputs[i] = vec4(sum, float(k), 0.0, 0.0);
    } else if (pc.test == 5u) {
        vec4 a = inputs[i];
        float total = points[i].x;
        outputs[i] = vec4(pairwise_neighbour_weight(a.x, a.y, a.z, a.w, total), pairwise_canonical_weight(a.x, a.y, a.z, a.w, total), 0.0, 0.0);
    } else if (pc.test == 6u) {
        Vpl v = vpls[i];
        vec3 x = points[2u * i].xyz;
        vec3 n = points[2u * i + 1u].xyz;
        float t = vpl_target(v, x, n, n, vec3(1.0), pc.params);
        float c = regir_cell_target(v.position, v.kind, v.normal, v.flux, vpl_r2(v.yuksel_r2, pc.params), inputs[i].xyz, inputs[i].w, pc.params);
        outputs[i] = vec4(t, c, 0.0, 0.0);
    } else if (pc.test == 4u) {
        Rng rng = rng_init(i % 128u, (i / 128u) % 128u, i / 16384u, pc.seed);
        for (uint j = 0u; j < pc.n; ++j) {
            chosen[i * pc.n + j] = rng_next(rng);
        }
    }
}
