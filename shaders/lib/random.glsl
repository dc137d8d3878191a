// Random numbers: PCG (O'Neill 2014) for the streams, a PCG hash to seed them per pixel/frame/seed.
// Binding-free.
#ifndef RANDOM_GLSL
#define RANDOM_GLSL

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// One PCG stream (O'Neill's pcg32 "setseq" with a 32-bit state): an LCG state and the stream's own
// odd increment. With one increment for all, every stream would be a window of the same 2^32
// cycle, and a 1280×720 frame drawing ~40 numbers per pixel would have ~7,000 pixel pairs whose
// windows overlap (the same numbers, shifted); with a per-stream increment two streams run the
// same cycle only if 31 hashed bits agree as well as overlapping (tests/vpl_math.rs, case 4).
struct Rng {
    uint state;
    uint inc;  // odd
};

// Seeds one independent stream per (a, b, c, salt): pixel x/y (or item index), frame, run seed.
// The state and the increment hash (a, b) in opposite orders, so a collision of one (a 2^-32
// chance per pair of streams: ~100 pairs in a 1280×720 frame) is not a collision of the other.
Rng rng_init(uint a, uint b, uint c, uint salt) {
    uint k = pcg_hash(c ^ pcg_hash(salt));
    Rng r;
    r.state = pcg_hash(a ^ pcg_hash(b ^ k));
    r.inc = (pcg_hash(b ^ pcg_hash(a ^ k ^ 0x68e31da4u)) << 1u) | 1u;
    // One step before the first number: rng_next outputs a hash of the state *before* it steps,
    // so two streams whose states collided would share their first number whatever their
    // increments; after the step that number depends on the increment too.
    r.state = r.state * 747796405u + r.inc;
    return r;
}

uint rng_next(inout Rng r) {
    uint s = r.state;
    r.state = s * 747796405u + r.inc;
    uint word = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (word >> 22u) ^ word;
}

// Uniform in [0, 1) with 24 bits.
float rand(inout Rng state) {
    return float(rng_next(state) >> 8) * (1.0 / 16777216.0);
}

// Uniform integer in [0, n) from the 32 random bits `bits` (as rand_index).
uint rand_index_of(uint bits, uint n) {
    uint hi;
    uint lo;
    umulExtended(bits, n, hi, lo);
    return hi;
}

// Uniform integer in [0, n) from 32 random bits: floor(r * n / 2^32), off from uniform by at most
// n / 2^32 relative (a float in [0, 1) has only 24 bits: 1% off for n = 200k).
uint rand_index(inout Rng state, uint n) {
    return rand_index_of(rng_next(state), n);
}

vec2 rand2(inout Rng state) {
    float a = rand(state);
    return vec2(a, rand(state));
}

#endif
