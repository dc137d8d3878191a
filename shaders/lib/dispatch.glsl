// The item index of a 1-D dispatch (ComputePipeline::dispatch_1d). Vulkan guarantees only 65,535
// workgroups along x (maxComputeWorkGroupCount[0]; lavapipe's and Intel's value), so a larger
// count is folded into rows of gl_NumWorkGroups.x groups along y; the last row may run past the
// count, which the caller checks as for a partial workgroup. Needs local_size_y = 1, and the
// include after the local size is declared.
// Binding-free.
#ifndef DISPATCH_GLSL
#define DISPATCH_GLSL

uint dispatch_index() {
    return gl_GlobalInvocationID.y * (gl_NumWorkGroups.x * gl_WorkGroupSize.x) + gl_GlobalInvocationID.x;
}

#endif
