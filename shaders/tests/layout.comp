// Not used by the renderer: declares one buffer per mirrored struct so that tests/layout.rs can
// read the std430/std140 member offsets glslang assigns and compare them with src/gpu_types.rs.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/types.glsl"

layout(local_size_x = 1) in;

layout(set = 0, binding = 0, std430) buffer B0 { Vertex layout_vertex[]; };
layout(set = 0, binding = 1, std430) buffer B1 { Material layout_material[]; };
layout(set = 0, binding = 2, std430) buffer B2 { Instance layout_instance[]; };
layout(set = 0, binding = 3, std430) buffer B3 { Light layout_light[]; };
layout(set = 0, binding = 4, std430) buffer B4 { AliasEntry layout_alias[]; };
layout(set = 0, binding = 5, std430) buffer B5 { Surface layout_surface[]; };
layout(set = 0, binding = 6, std430) buffer B6 { Frame layout_frame_std430[]; };
layout(set = 0, binding = 7, std140) uniform B7 { Frame layout_frame_std140; };
layout(set = 0, binding = 8, std430) buffer B8 { Vpl layout_vpl[]; };
layout(set = 0, binding = 9, std430) buffer B9 { Reservoir layout_reservoir[]; };
layout(set = 0, binding = 10, std430) buffer B10 { VplParams layout_vpl_params[]; };
layout(set = 0, binding = 11, std430) buffer B11 { TextureInfo layout_texture[]; };
layout(set = 0, binding = 12, std430) buffer B12 { VplCandidate layout_vpl_candidate[]; };
layout(set = 0, binding = 13, std430) buffer B13 { GridParams layout_grid_params[]; };
layout(set = 0, binding = 14, std430) buffer B14 { GridEntry layout_grid_entry[]; };

void main() {
    // Touch every buffer so glslang keeps their declarations.
    layout_vertex[0].u = layout_material[0].albedo.x + layout_instance[0].world_from_object[0][0]
        + layout_light[0].area + layout_alias[0].keep + layout_surface[0].offset_scale
        + layout_frame_std430[0].aspect + layout_frame_std140.aspect + layout_vpl[0].flux.x
        + layout_reservoir[0].ucw + layout_vpl_params[0].yuksel_r2 + float(layout_texture[0].width)
        + layout_vpl_candidate[0].flux.x + layout_grid_params[0].cell_size.x + layout_grid_entry[0].ucw;
}
