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

shared float group_w[64];
shared uint group_n[64];

void main() {
    uvec2 pixel = dispatch_pixel();
    bool inside = pixel.x < frame.width && pixel.y < frame.height;
    uint index = pixel.y * frame.width + pixel.x;
    // Outside the image: an empty reservoir, which adds nothing to the block's mean.
    Reservoir r = inside ? reservoirs[index] : reservoir_empty(0.0);
    float w = reservoir_valid(r) ? r.ucw * r.target : 0.0;

    // Every invocation of the workgroup takes part in the reduction (barriers).
    uint lid = gl_LocalInvocationIndex;
    group_w[lid] = w;
    group_n[lid] = w > 0.0 ? 1u : 0u;
    barrier();
    for (uint stride = 32u; stride > 0u; stride >>= 1u) {
        if (lid < stride) {
            group_w[lid] += group_w[lid + stride];
            group_n[lid] += group_n[lid + stride];
        }
        barrier();
    }
    float mean = group_n[0] > 0u ? group_w[0] / float(group_n[0]) : 0.0;
    if (inside && boiling_rejects(w, mean, pc.strength)) {
        reservoirs[index] = reservoir_empty(r.confidence);
    }
}
