// restir_initial: per pixel, the initial RIS reservoir (restir_initial.glsl says how). Shared by
// the uniform, ris and restir modes; restir_initial_temporal runs the same function fused with the
// temporal merge.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "restir_initial.glsl"
#include "restir_temporal.glsl"

// 8×8 unless the renderer specialises it (--workgroup; constants 0 and 1).
#ifndef RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;
#endif
#include "../lib/dispatch.glsl"

// Records read at per-pixel addresses come through texel views (texel_records.glsl says why).
layout(set = 1, binding = 0) uniform utextureBuffer surfaces;  // Surface, SURFACE_TEXELS (4) texels each
layout(set = 1, binding = 1) uniform utextureBuffer vpls;  // Vpl, 3 texels each
layout(set = 1, binding = 2) uniform utextureBuffer vpl_alias;  // AliasEntry, RG32UI
layout(set = 1, binding = 3, std430) writeonly buffer ReservoirOut { Reservoir reservoirs_out[]; };
layout(set = 1, binding = 4, std430) buffer RayCounter { uint ray_count[]; };
#include "../common/ray_count.glsl"
layout(set = 1, binding = 5) uniform utextureBuffer tiles;  // VplCandidate, 2 texels each
layout(set = 1, binding = 6) uniform utextureBuffer grid_entries;  // GridEntry, 3 texels each
layout(set = 1, binding = 7, std430) buffer GridCells { uvec4 grid_cells[]; };  // regir_build.comp
layout(set = 1, binding = 8) uniform utextureBuffer history;  // Reservoir, 1 texel each: the other buffer

layout(push_constant) uniform Push {
    VplParams params;
    GridParams grid;  // cells == 0: no grid
    uint tiles;  // presampled tiles to read (0: draw from the VPL buffer)
    // RIS candidates of a pixel without temporal history: params.candidates except in a ReSTIR
    // frame displayed alone with temporal reuse (docs/performance.md, "Pixels without history"),
    // where restir_temporal follows with these thresholds. The same choice as the fused
    // restir_initial_temporal's, so the same frames.
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
    Surface s = surface_texels(surfaces, surface_slot(index));
    uint rays = 0u;
    VplParams params = pc.params;
    if (pc.candidates_without_history != params.candidates && s.offset_scale >= 0.0) {
        TemporalReuse t = TemporalReuse(pc.mcap, pc.normal_threshold, pc.depth_threshold);
        uint prev_index;
        Reservoir rh;
        Surface sp;
        if (!temporal_history(index, s, params, t, surfaces, history, prev_index, rh, sp)) {
            params.candidates = pc.candidates_without_history;
        }
    }
    GridPick k = regir_pixel(s, pc.grid, params);
    reservoirs_out[index] = initial_reservoir(pixel, s, params, pc.tiles, vpls, vpl_alias, tiles, pc.grid, k, grid_entries, rays);
    count_rays(RAYS_INITIAL, rays);
}
