// restir_boiling: RTXDI's boiling filter (--boiling-filter S > 0), after temporal reuse
// (restir_temporal or restir_initial_temporal) and before spatial reuse. A reservoir whose weight
// sum exceeds 10/S - 9 times the mean non-zero weight sum of its 8x8 block of pixels is a firefly
// about to spread through reuse: it is dropped (its confidence kept). Biased: it removes energy.
//
// A pass of its own, not part of the temporal pass, because it averages over a workgroup in shared
// memory: a compute pass has that on both ways of tracing rays, a ray-generation shader (the
// temporal passes' variant for ray-tracing pipelines) has no workgroup. It traces nothing.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require

#include "../common/scene.glsl"
#include "../restir/reservoir.glsl"

// Fixed 8x8: the filter's blocks are the workgroups.
layout(local_size_x = 8, local_size_y = 8) in;
#include "../lib/dispatch.glsl"

// The temporal pass's output, filtered in place.
layout(set = 1, binding = 0, std430) buffer ReservoirCurrent { Reservoir reservoirs[]; };

layout(push_constant) uniform Push {
    float strength;  // > 0 (the pass does not run at 0)
} pc;

// One partial sum per subgroup (at most 64: a subgroup has at least one invocation).
shared float group_w[64];
shared uint group_n[64];

void main() {
    uvec2 pixel = dispatch_pixel();
    bool inside = pixel.x < frame.width && pixel.y < frame.height;
    uint index = pixel.y * frame.width + pixel.x;
    // Outside the image: an empty reservoir, which adds nothing to the block's mean.
    Reservoir r = inside ? reservoirs[index] : reservoir_empty(0.0);
    float w = reservoir_valid(r) ? r.ucw * r.target : 0.0;

    // Every invocation of the workgroup takes part: each subgroup sums its own invocations'
    // values in registers, its first invocation stores the partial sums, and after the one
    // barrier each invocation adds the partials in subgroup order, so all get the same mean.
    float w_sub = subgroupAdd(w);
    uint n_sub = subgroupAdd(w > 0.0 ? 1u : 0u);
    if (subgroupElect()) {
        group_w[gl_SubgroupID] = w_sub;
        group_n[gl_SubgroupID] = n_sub;
    }
    barrier();
    float sum = 0.0;
    uint count = 0u;
    for (uint i = 0u; i < gl_NumSubgroups; i++) {
        sum += group_w[i];
        count += group_n[i];
    }
    float mean = count > 0u ? sum / float(count) : 0.0;
    if (inside && boiling_rejects(w, mean, pc.strength)) {
        reservoirs[index] = reservoir_empty(r.confidence);
    }
}
