// accumulate: running mean of the per-frame samples. The sum is kept with Neumaier (compensated)
// summation, so the mean stays accurate to float precision over 100k+ frames; a sum of squares
// gives per-pixel variance. Non-finite samples are counted and replaced by zero.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/scene.glsl"
#include "../lib/finite.glsl"

layout(local_size_x = 64) in;
// after the local size: dispatch_index() reads gl_WorkGroupSize
#include "../lib/dispatch.glsl"

layout(set = 1, binding = 0, std430) readonly buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 1, std430) buffer SumBuffer { vec4 sums[]; };
layout(set = 1, binding = 2, std430) buffer CompensationBuffer { vec4 compensation[]; };
layout(set = 1, binding = 3, std430) buffer SquareBuffer { vec4 squares[]; };
layout(set = 1, binding = 4, std430) writeonly buffer MeanBuffer { vec4 means[]; };
layout(set = 1, binding = 5, std430) buffer StatsBuffer { uint nonfinite_samples; };

layout(push_constant) uniform Push {
    uint reset;
};

void main() {
    uint i = dispatch_index();
    if (i >= frame.width * frame.height) {
        return;
    }
    vec3 x = samples[i].rgb;
    if (!is_finite(x)) {
        atomicAdd(nonfinite_samples, 1u);
        x = vec3(0.0);
    }
    precise vec3 s;
    precise vec3 c;
    vec3 q;
    if (reset != 0u) {
        s = x;
        c = vec3(0.0);
        q = x * x;
    } else {
        s = sums[i].rgb;
        c = compensation[i].rgb;
        q = squares[i].rgb + x * x;
        precise vec3 t = s + x;
        precise vec3 big_s = (s - t) + x;
        precise vec3 big_x = (x - t) + s;
        c += mix(big_x, big_s, greaterThanEqual(abs(s), abs(x)));
        s = t;
    }
    sums[i] = vec4(s, 0.0);
    compensation[i] = vec4(c, 0.0);
    squares[i] = vec4(q, 0.0);
    precise vec3 total = s + c;
    means[i] = vec4(total / float(max(frame.accumulated_frames, 1u)), 1.0);
}
