// Not used by the renderer: decodes records through texel_records.glsl and stores them through
// storage buffers of the real structs, for tests/vpl_math.rs (the round trip must give the bytes
// back). `pc.kind` picks the record: 0 Surface, 1 Vpl, 2 Reservoir, 3 VplCandidate, 4 Vertex,
// 5 Material, 6 Instance, 7 Light (RGBA32UI views), 8 AliasEntry (RG32UI), 9 uint (R32UI);
// 10: a Surface decoded and encoded again by surface_to_texels, as words (kind 0 reads the
// G-buffer's packed record, SURFACE_TEXELS texels).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "../common/texel_records.glsl"

layout(local_size_x = 64) in;
// after the local size: dispatch_index() reads gl_WorkGroupSize
#include "../lib/dispatch.glsl"

layout(set = 1, binding = 0) uniform utextureBuffer records;
layout(set = 1, binding = 1, std430) writeonly buffer OutSurfaces { Surface out_surfaces[]; };
layout(set = 1, binding = 2, std430) writeonly buffer OutVpls { Vpl out_vpls[]; };
layout(set = 1, binding = 3, std430) writeonly buffer OutReservoirs { Reservoir out_reservoirs[]; };
layout(set = 1, binding = 4, std430) writeonly buffer OutCandidates { VplCandidate out_candidates[]; };
layout(set = 1, binding = 5, std430) writeonly buffer OutVertices { Vertex out_vertices[]; };
layout(set = 1, binding = 6, std430) writeonly buffer OutMaterials { Material out_materials[]; };
layout(set = 1, binding = 7, std430) writeonly buffer OutInstances { Instance out_instances[]; };
layout(set = 1, binding = 8, std430) writeonly buffer OutLights { Light out_lights[]; };
layout(set = 1, binding = 9, std430) writeonly buffer OutAlias { AliasEntry out_alias[]; };
layout(set = 1, binding = 10, std430) writeonly buffer OutWords { uint out_words[]; };

layout(push_constant) uniform Push {
    uint kind;
    uint count;
} pc;

void main() {
    uint i = dispatch_index();
    if (i >= pc.count) {
        return;
    }
    if (pc.kind == 0u) {
        out_surfaces[i] = surface_texels(records, i);
    } else if (pc.kind == 1u) {
        out_vpls[i] = vpl_texels(records, i);
    } else if (pc.kind == 2u) {
        out_reservoirs[i] = reservoir_texels(records, i);
    } else if (pc.kind == 3u) {
        out_candidates[i] = candidate_texels(records, i);
    } else if (pc.kind == 4u) {
        out_vertices[i] = vertex_texels(records, i);
    } else if (pc.kind == 5u) {
        out_materials[i] = material_texels(records, i);
    } else if (pc.kind == 6u) {
        uvec4 h = instance_header_texels(records, i);
        Instance inst;
        inst.world_from_object = instance_matrix_texels(records, i, 0u);
        inst.normal_to_world = instance_matrix_texels(records, i, 1u);
        inst.first_index = h.x;
        inst.first_vertex = h.y;
        inst.first_triangle = h.z;
        inst.flags = h.w;
        out_instances[i] = inst;
    } else if (pc.kind == 7u) {
        out_lights[i] = light_texels(records, i);
    } else if (pc.kind == 8u) {
        out_alias[i] = alias_texels(records, i);
    } else if (pc.kind == 9u) {
        out_words[i] = word_texel(records, i);
    } else {
        uvec4 t[SURFACE_TEXELS];
        surface_to_texels(surface_texels(records, i), t);
        for (uint j = 0u; j < SURFACE_TEXELS; ++j) {
            for (uint c = 0u; c < 4u; ++c) {
                out_words[4u * SURFACE_TEXELS * i + 4u * j + c] = t[j][c];
            }
        }
    }
}
