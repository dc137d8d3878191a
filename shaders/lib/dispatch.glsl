// Which item or pixel an invocation works on, in a compute shader or (RT_PIPELINE) in a pass
// compiled as a ray-generation shader (trace.glsl), whose launch has no workgroups.
//
// dispatch_index(): the item index of a 1-D dispatch (ComputePipeline::dispatch_1d). Vulkan
// guarantees only 65,535 workgroups along x (maxComputeWorkGroupCount[0]; lavapipe's and Intel's
// value), so a larger count is folded into rows of gl_NumWorkGroups.x groups along y; the last row
// may run past the count, which the caller checks as for a partial workgroup. Needs
// local_size_y = 1, and the include after the local size is declared. A ray-generation launch is
// folded the same way (rows of gl_LaunchSizeEXT.x).
// dispatch_pixel(): the pixel of a 2-D dispatch (ComputePipeline::dispatch_2d).
// Binding-free.
#ifndef DISPATCH_GLSL
#define DISPATCH_GLSL

#ifdef RT_PIPELINE
uint dispatch_index() {
    return gl_LaunchIDEXT.y * gl_LaunchSizeEXT.x + gl_LaunchIDEXT.x;
}

uvec2 dispatch_pixel() {
    return gl_LaunchIDEXT.xy;
}
#else
uint dispatch_index() {
    return gl_GlobalInvocationID.y * (gl_NumWorkGroups.x * gl_WorkGroupSize.x) + gl_GlobalInvocationID.x;
}

uvec2 dispatch_pixel() {
    return gl_GlobalInvocationID.xy;
}
#endif

#endif
