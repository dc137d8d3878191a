// count_rays: adds to a pass's 64-bit ray count in the frame's ray counter (common/types.glsl's
// RAYS_* slots, the high words at RAYS_HIGH + slot): the add that wraps the low word carries one
// into the high word. Included after the pass declares its `ray_count` buffer.
#ifndef RAY_COUNT_GLSL
#define RAY_COUNT_GLSL

void count_rays(uint slot, uint n) {
    if (n > 0u) {
        uint before = atomicAdd(ray_count[slot], n);
        if (before > 0xFFFFFFFFu - n) {
            atomicAdd(ray_count[RAYS_HIGH + slot], 1u);
        }
    }
}

#endif
