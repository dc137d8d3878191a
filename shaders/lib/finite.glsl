// Finiteness read off the bits. Unless a module declares SignedZeroInfNanPreserve, Vulkan lets the
// compiler assume floats are neither NaN nor infinite ("Precision and Operation of SPIR-V
// Instructions"), so isnan()/isinf() may fold to false and !(x > 0.0) may become x <= 0.0. An
// integer test of the exponent bits keeps its meaning whatever the compiler assumes: the guards
// that keep a NaN out of the accumulation and out of reused reservoirs use it. Binding-free.
#ifndef FINITE_GLSL
#define FINITE_GLSL

bool is_finite(float x) {
    return (floatBitsToUint(x) & 0x7F800000u) != 0x7F800000u;
}

bool is_finite(vec3 v) {
    return is_finite(v.x) && is_finite(v.y) && is_finite(v.z);
}

#endif
