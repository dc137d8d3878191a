// The ray payloads and miss indices of the ray-tracing-pipeline implementation of trace.glsl,
// shared by the ray-generation variants of the passes and by the hit and miss shaders beside this
// file. Binding-free.
#ifndef RT_PAYLOAD_GLSL
#define RT_PAYLOAD_GLSL

// A closest-hit ray's answer, as a ray query's committed intersection gives it. t < 0: a miss.
struct ClosestPayload {
    float t;
    uint instance;   // gl_InstanceCustomIndexEXT
    uint primitive;  // gl_PrimitiveID
    vec2 barycentrics;
};

// Payload locations (one per kind of ray) and the miss shader of each, by index in the shader
// binding table (src/vk/pipeline.rs builds it in this order: miss.rmiss, shadow_miss.rmiss).
#define RT_CLOSEST_PAYLOAD 0
#define RT_SHADOW_PAYLOAD 1
#define RT_CLOSEST_MISS 0u
#define RT_SHADOW_MISS 1u

#endif
