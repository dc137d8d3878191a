// restir_spatial_shade: the last restir_spatial pass and vpl_shade in one dispatch (as Bevy
// Solari's ReSTIR DI does): the merged reservoir is written for the next frame's temporal reuse
// and shaded at once, so the surface is read once and the final reservoirs are not read back. The
// same functions and random streams as the two passes (restir_spatial.glsl, vpl_shade.glsl), so
// the same estimator. Used when both would run, the view is the shaded image and nothing needs
// the last spatial pass's reservoirs on their own (no --dump-passes or --check-finite frame;
// --fuse-passes, on by default).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "restir_spatial.glsl"
#include "vpl_shade.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;
#endif
#include "../lib/dispatch.glsl"

// The reuse's kind, fixed per pipeline (specialisation constants 2 and 3, the pass desc's
// `constants`; the renderer sets them from the VPL flags it pushes): unbiased pairwise MIS, and
// visibility in its targets. The driver then compiles only the branch the settings run (on
// lavapipe the other branches, inlined ray query included, cost 15-21 % of this pass).
layout(constant_id = 2) const bool UNBIASED = true;
layout(constant_id = 3) const bool VISIBLE_TARGETS = false;

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2) uniform utextureBuffer src;  // Reservoir, 1 texel each
layout(set = 1, binding = 3, std430) writeonly buffer ReservoirOut { Reservoir dst[]; };
layout(set = 1, binding = 4, std430) writeonly buffer SampleBuffer { vec4 samples[]; };
layout(set = 1, binding = 5, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"
#include "../common/poison.glsl"

layout(push_constant) uniform Push {
    VplParams params;
    uint neighbours;
    uint neighbours_without_history;
    float radius;
    float normal_threshold;
    float depth_threshold;
    uint pass_index;
} pc;

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    Surface s = surface_texels(surfaces, surface_slot(index));
    Reservoir rc = reservoir_texels(src, index);
    if (s.offset_scale < 0.0) {
        dst[index] = rc;
        samples[index] = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    uint rays = 0u;
    SpatialReuse sr = SpatialReuse(pc.neighbours, pc.neighbours_without_history, pc.radius, pc.normal_threshold, pc.depth_threshold, pc.pass_index);
    Reservoir r = spatial_merge(pixel, s, rc, pc.params, sr, surfaces, vpls, src, UNBIASED, VISIBLE_TARGETS, rays);
    dst[index] = r;
    samples[index] = vec4(shade_estimate(s, r, pc.params, vpls, rays), 1.0);
    if (shade_poisoned(frame.debug_poison, pixel)) {
        samples[index] = poison_sample();
    }
    count_rays(RAYS_SPATIAL_SHADE, rays);
}
