// restir_initial_temporal: restir_initial and restir_temporal in one dispatch (as Bevy Solari's
// ReSTIR DI does): the pixel's initial reservoir is built in registers and merged with its history
// at once, so the surface is read once and the initial reservoirs never go through memory. The
// same functions and random streams as the two passes (restir_initial.glsl, restir_temporal.glsl),
// so the same estimator. Used when both would run and nothing needs the initial reservoirs on
// their own (--fuse-passes, on by default; not in a --dump-passes or --check-finite frame).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "restir_initial.glsl"
#include "restir_temporal.glsl"

// Fixed 8x8, as restir_temporal.
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8) in;
#endif
#include "../lib/dispatch.glsl"

// Both halves of the G-buffer ping-pong: surface_slot() and prev_surface_slot() pick them.
// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2) uniform utextureBuffer vpl_alias;  // AliasEntry, RG32UI
layout(set = 1, binding = 3) uniform utextureBuffer tiles;  // VplCandidate, 2 texels each
layout(set = 1, binding = 4) uniform utextureBuffer history;  // Reservoir, 1 texel each
layout(set = 1, binding = 5, std430) writeonly buffer ReservoirOut { Reservoir reservoirs_out[]; };
layout(set = 1, binding = 6, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"
layout(set = 1, binding = 7) uniform utextureBuffer grid_entries;  // GridEntry, 3 texels each
layout(set = 1, binding = 8, std430) buffer GridCells { uvec4 grid_cells[]; };  // regir_build.comp

layout(push_constant) uniform Push {
    VplParams params;
    GridParams grid;  // cells == 0: no grid
    uint tiles;  // presampled tiles to read (0: draw from the VPL buffer)
    // RIS candidates of a pixel without temporal history (params.candidates: those of a pixel
    // with it; more in a frame displayed alone: docs/performance.md, "Pixels without history").
    // The layout of restir_initial.comp's push constants (one Rust struct for both).
    uint candidates_without_history;
    float mcap;
    float normal_threshold;
    float depth_threshold;
} pc;

#include "regir_pixel.glsl"

void main() {
    uvec2 pixel = dispatch_pixel();
    if (pixel.x >= frame.width || pixel.y >= frame.height) {
        return;
    }
    uint index = pixel.y * frame.width + pixel.x;
    uint rays = 0u;
    Surface s = surface_texels(surfaces, surface_slot(index));
    // The history first: a pixel without it draws candidates_without_history (as restir_initial
    // does when the passes run apart).
    TemporalReuse t = TemporalReuse(pc.mcap, pc.normal_threshold, pc.depth_threshold);
    uint prev_index;
    Reservoir rh;
    Surface sp;
    bool has_history = s.offset_scale >= 0.0 && temporal_history(index, s, pc.params, t, surfaces, history, prev_index, rh, sp);
    VplParams params = pc.params;
    if (!has_history) {
        params.candidates = pc.candidates_without_history;
    }
    GridPick k = regir_pixel(s, pc.grid, params);
    Reservoir r = initial_reservoir(pixel, s, params, pc.tiles, vpls, vpl_alias, tiles, pc.grid, k, grid_entries, rays);
    if (has_history) {
        r = temporal_merge_history(pixel, s, r, rh, sp, pc.params, t, vpls, rays);
    }
    reservoirs_out[index] = r;
    count_rays(RAYS_INITIAL_TEMPORAL, rays);
}
