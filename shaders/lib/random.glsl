// Random numbers: PCG (O'Neill 2014) for the stream, a PCG hash to seed it per pixel/frame/seed.
// Binding-free.
#ifndef RANDOM_GLSL
#define RANDOM_GLSL

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// Seeds one independent stream per (a, b, c, salt): pixel x/y (or item index), frame, run seed.
uint rng_init(uint a, uint b, uint c, uint salt) {
    return pcg_hash(a ^ pcg_hash(b ^ pcg_hash(c ^ pcg_hash(salt))));
}

uint rng_next(inout uint state) {
    uint s = state;
    state = s * 747796405u + 2891336453u;
    uint word = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (word >> 22u) ^ word;
}

// Uniform in [0, 1) with 24 bits.
float rand(inout uint state) {
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
uint rand_index(inout uint state, uint n) {
    return rand_index_of(rng_next(state), n);
}

vec2 rand2(inout uint state) {
    float a = rand(state);
    return vec2(a, rand(state));
}

#endif
