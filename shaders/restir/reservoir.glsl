// Reservoirs for resampled importance sampling over a fixed VPL set (Talbot 2005; Bitterli et al.
// 2020; Lin et al. 2022). A sample is a VPL index, so the shift between pixels is the identity with
// Jacobian 1. Streaming: each candidate j arrives with resampling weight w_j and its target at the
// receiving pixel; the chosen one is kept with probability w_j / sum w. Binding-free.
#ifndef RESERVOIR_GLSL
#define RESERVOIR_GLSL

#include "../common/types.glsl"
#include "../lib/finite.glsl"

// A reservoir while candidates stream in.
struct ReservoirStream {
    uint vpl;
    float target;   // p^ of `vpl` at the receiving pixel
    float w_sum;
    float confidence;
};

ReservoirStream stream_begin() {
    ReservoirStream s;
    s.vpl = RESERVOIR_EMPTY;
    s.target = 0.0;
    s.w_sum = 0.0;
    s.confidence = 0.0;
    return s;
}

// Offers candidate `vpl` with resampling weight `w` (>= 0) and target `target` at the receiving
// pixel; `u` uniform in [0, 1). Returns true when it became the chosen sample.
bool stream_update(inout ReservoirStream s, uint vpl, float w, float target, float u) {
    if (!(w > 0.0)) {
        return false;
    }
    s.w_sum += w;
    if (u * s.w_sum < w) {
        s.vpl = vpl;
        s.target = target;
        return true;
    }
    return false;
}

// W = (sum w) / p^(y); an empty or zero-target reservoir has W = 0 and keeps its confidence.
Reservoir stream_finish(ReservoirStream s) {
    Reservoir r;
    bool ok = s.vpl != RESERVOIR_EMPTY && s.target > 0.0 && s.w_sum > 0.0;
    r.vpl = ok ? s.vpl : RESERVOIR_EMPTY;
    r.ucw = ok ? s.w_sum / s.target : 0.0;
    r.confidence = s.confidence;
    r.target = ok ? s.target : 0.0;
    if (!is_finite(r.ucw)) {
        r.vpl = RESERVOIR_EMPTY;
        r.ucw = 0.0;
        r.target = 0.0;
    }
    return r;
}

// RTXDI's boiling filter: a reservoir whose weight sum exceeds its neighbourhood's mean non-zero
// weight sum by the factor 10/strength - 9 (strength 0.2: 41x) is a firefly about to spread
// through reuse; the filter drops it. Biased (it removes energy). strength <= 0: off.
bool boiling_rejects(float w_sum, float mean_nonzero_w_sum, float strength) {
    return strength > 0.0 && mean_nonzero_w_sum > 0.0 && w_sum > mean_nonzero_w_sum * (10.0 / strength - 9.0);
}

Reservoir reservoir_empty(float confidence) {
    Reservoir r;
    r.vpl = RESERVOIR_EMPTY;
    r.ucw = 0.0;
    r.confidence = confidence;
    r.target = 0.0;
    return r;
}

bool reservoir_valid(Reservoir r) {
    return r.vpl != RESERVOIR_EMPTY && r.ucw > 0.0;
}

// Confidence-weighted pairwise MIS (Lin et al. 2022, generalised balance heuristic paired with the
// canonical technique; the canonical confidence is split evenly over the k pairs). For a neighbour
// i with confidence m_i, canonical confidence m_c and total confidence m_total:
//   weight of neighbour i's sample y:    (m_i p_i(y)) / (m_i p_i(y) + (m_c/k) p_c(y)) * (m_i + m_c/k) / m_total
//   canonical weight gets from pair i:   ((m_c/k) p_c(y)) / (m_i p_i(y) + (m_c/k) p_c(y)) * (m_i + m_c/k) / m_total
// The weights of all techniques sum to 1 wherever p_c(y) > 0, and a technique that cannot produce
// y (p_i(y) = 0) gets none. With equal targets they reduce to the confidence weights m/m_total.
float pairwise_neighbour_weight(float m_i, float p_i, float m_c_share, float p_c, float m_total) {
    float denom = m_i * p_i + m_c_share * p_c;
    return denom > 0.0 ? (m_i * p_i / denom) * (m_i + m_c_share) / m_total : 0.0;
}

float pairwise_canonical_weight(float m_i, float p_i, float m_c_share, float p_c, float m_total) {
    float denom = m_i * p_i + m_c_share * p_c;
    // p_c = 0: the canonical pixel has nothing to integrate at y, any weight is fine; give the
    // pair's share so the weights still sum to 1.
    return denom > 0.0 ? (m_c_share * p_c / denom) * (m_i + m_c_share) / m_total : (m_i + m_c_share) / m_total;
}

#endif
