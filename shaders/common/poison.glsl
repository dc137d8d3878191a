// The test NaN of RESTIR_VPL_DEBUG_POISON=vpl_shade (tests of --check-finite only): one pixel's
// shaded sample is a NaN, planted where the shading runs, in vpl_shade or fused in
// restir_spatial_shade. Pure functions; the pass passes its frame's debug_poison.
#ifndef POISON_GLSL
#define POISON_GLSL

bool shade_poisoned(uint debug_poison, uvec2 pixel) {
    return debug_poison == POISON_VPL_SHADE && pixel == uvec2(1u, 1u);
}

// The NaN every planted fault writes (vpl_presample's and regir_build's too).
float poison_nan() {
    return uintBitsToFloat(0x7fc00000u);
}

vec4 poison_sample() {
    return vec4(vec3(poison_nan()), 1.0);
}

#endif
