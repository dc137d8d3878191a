// accumulate: running mean of the per-frame samples, kept as a mean (never a sum: a sum of n
// frames overflows floats when the mean times n passes 3.4e38, where a mean is finite whenever its
// samples are), with Neumaier compensation so that it stays accurate to float precision over 100k+
// frames; and Welford's mean squared deviation for the per-pixel variance. Non-finite samples are
// counted and replaced by zero.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/scene.glsl"
#include "../lib/finite.glsl"

layout(local_size_x = 64) in;
// after the local size: dispatch_index() reads gl_WorkGroupSize
#include "../lib/dispatch.glsl"

layout(set = 1, binding = 0, std430) readonly buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 1, std430) buffer RunningMeanBuffer { vec4 running_means[]; };
layout(set = 1, binding = 2, std430) buffer CompensationBuffer { vec4 compensation[]; };
layout(set = 1, binding = 3, std430) buffer DeviationBuffer { vec4 deviations[]; };
layout(set = 1, binding = 4, std430) writeonly buffer MeanBuffer { vec4 means[]; };
layout(set = 1, binding = 5, std430) buffer StatsBuffer { uint nonfinite_samples; };

const float FLOAT_MAX = 3.4028235e38;

// `v` held within the float range: at the largest float rounding could carry a mean of finite
// samples past it (a tie rounds to Inf), and Inf would then meet -Inf in the compensation.
vec3 within_floats(vec3 v) {
    return clamp(v, vec3(-FLOAT_MAX), vec3(FLOAT_MAX));
}

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
    // The mean is m + c (running mean and its compensation); d2 is the mean squared deviation
    // M2 / n of the n samples so far.
    precise vec3 m;
    precise vec3 c;
    vec3 d2;
    vec3 mean;  // m + c within the float range
    if (reset != 0u) {
        m = x;
        c = vec3(0.0);
        d2 = vec3(0.0);
        mean = x;
    } else {
        float n = float(max(frame.accumulated_frames, 2u));
        m = running_means[i].rgb;
        c = compensation[i].rgb;
        vec3 old_mean = within_floats(m + c);
        // The step (x - mean) / n, as x/n - mean/n: each term is finite, so is their difference.
        precise vec3 step = x / n - old_mean / n;
        precise vec3 t = within_floats(m + step);
        precise vec3 big_m = (m - t) + step;
        precise vec3 big_step = (step - t) + m;
        c += mix(big_step, big_m, greaterThanEqual(abs(m), abs(step)));
        m = t;
        mean = within_floats(m + c);
        // Welford: M2 += (x - old mean)(x - new mean), kept divided by n. A product past 3.4e38
        // (deviations beyond ~1.8e19) is +Inf, which the host reports as the largest float; it is
        // never Inf - Inf here.
        vec3 p = (x - old_mean) * (x - mean);
        d2 = deviations[i].rgb * ((n - 1.0) / n) + p / n;
    }
    running_means[i] = vec4(m, 0.0);
    compensation[i] = vec4(c, 0.0);
    deviations[i] = vec4(d2, 0.0);
    means[i] = vec4(mean, 1.0);
}
