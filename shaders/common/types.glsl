// GPU structs, std430, and shared constants. Mirror of src/gpu_types.rs (the source of truth);
// tests/layout.rs checks that offsets and sizes agree, and every `const uint` here against its Rust
// twin (`gpu_types::GLSL_CONSTANTS`, the RAYS_* slots from `passes::RAY_SLOT_NAMES`).
// Binding-free: declarations only.
#ifndef TYPES_GLSL
#define TYPES_GLSL

const uint MATERIAL_DOUBLE_SIDED = 1u;
const uint LIGHT_POINT = 2u;
const uint TEXTURE_NEAREST = 1u;
const uint INSTANCE_MIRRORED = 1u;
const uint INSTANCE_IDENTITY = 2u;
// A triangle-material word: the material index below this bit, the triangle's flat edges from it
// (bit k: the edge opposite vertex k is shared with one coplanar triangle).
const uint TRIANGLE_FLAT_EDGES_SHIFT = 29u;
const uint FRAME_AA = 1u;

struct Vertex {
    vec3 position;
    float u;
    vec3 normal;
    float v;
};

struct Material {
    vec3 albedo;
    int texture;
    vec3 emission;
    uint flags;
};

struct TextureInfo {
    uint offset;
    uint width;
    uint height;
    uint flags;  // TEXTURE_NEAREST or 0
};

struct Instance {
    mat4 world_from_object;
    mat4 normal_to_world;
    uint first_index;
    uint first_vertex;
    uint first_triangle;
    uint flags;
};

struct Light {
    vec3 p0;
    float area;
    vec3 p1;
    float pdf;
    vec3 p2;
    uint flags;
    vec3 emission;
    uint _pad0;
};

struct AliasEntry {
    float keep;
    uint alias;
};

struct Surface {
    vec3 position;
    float offset_scale;
    vec3 shading_normal;
    uint instance;
    vec3 geometric_normal;
    uint triangle;
    vec3 albedo;
    uint material;
    vec3 emission;
    float view_depth;
};

struct Frame {
    vec3 camera_position;
    float tan_half_fov;
    vec3 camera_right;
    float aspect;
    vec3 camera_up;
    uint frame_index;
    vec3 camera_forward;
    uint seed;
    uint width;
    uint height;
    int max_bounces;
    uint flags;
    uint light_count;
    uint instance_count;
    float total_light_power;
    float exposure;
    uint accumulated_frames;
    uint surface_offset;
    uint prev_surface_offset;
    uint _pad1;
    vec3 prev_camera_position;
    float prev_tan_half_fov;
    vec3 prev_camera_right;
    uint debug_poison;
    vec3 prev_camera_up;
    uint _pad2;
    vec3 prev_camera_forward;
    uint _pad3;
};

const uint VPL_DIRECT_AREA = 0u;
const uint VPL_DIRECT_POINT = 1u;
const uint VPL_INDIRECT = 2u;

struct Vpl {
    vec3 position;
    uint kind;
    vec3 normal;
    uint path;
    vec3 flux;
    float yuksel_r2;
};

struct VplCandidate {
    vec3 position;
    uint vpl_kind;
    vec3 flux;
    uint normal_oct;
};


// Slots of the per-frame ray counter (one per pass that traces rays besides gbuffer).
const uint RAYS_PATHTRACE = 0u;
const uint RAYS_INITIAL = 1u;
const uint RAYS_TEMPORAL = 2u;
const uint RAYS_SPATIAL = 3u;
const uint RAYS_SHADE = 4u;
const uint RAYS_BRUTEFORCE = 5u;
const uint RAYS_COMPENSATE = 6u;
const uint RAYS_INITIAL_TEMPORAL = 7u;
const uint RAYS_SPATIAL_SHADE = 8u;
// Every count is 64-bit: slot i's high word is at RAYS_HIGH + i (common/ray_count.glsl carries
// into it; a pass may trace more than 2^32 rays in a frame: passes::RAY_SLOT_NAMES says which).
const uint RAYS_HIGH = 9u;

const uint RESERVOIR_EMPTY = 0xFFFFFFFFu;

struct Reservoir {
    uint vpl;
    float ucw;
    float confidence;
    float target;
};

const uint ATTENUATION_INVERSE_SQUARE = 0u;
const uint ATTENUATION_YUKSEL = 1u;
const uint KIND_MASK_DIRECT = 1u;
const uint KIND_MASK_INDIRECT = 2u;
const uint VPL_FLAG_INITIAL_VISIBILITY = 1u;
const uint VPL_FLAG_UNBIASED = 2u;
const uint VPL_FLAG_SAME_DOMAIN = 4u;
const uint VPL_FLAG_PER_VPL_RADIUS = 8u;

// Push-constant codes of single passes.
// vpl_shade `view`: what the pass writes.
const uint SHADE_VIEW_FINAL = 0u;
const uint SHADE_VIEW_RESERVOIR_W = 1u;
const uint SHADE_VIEW_RESERVOIR_M = 2u;
const uint SHADE_VIEW_VPL_KIND = 3u;
const uint SHADE_VIEW_MOTION = 4u;
// vpl_compensate `first_hop`: what the first compensation ray's hit carries.
const uint COMPENSATE_EMISSION = 1u;
const uint COMPENSATE_VPLS = 2u;
const uint POISON_VPL_SHADE = 1u;
const uint POISON_RAY_CARRY = 2u;
const uint POISON_VPL_PRESAMPLE = 3u;
const uint POISON_REGIR_BUILD = 4u;
// vpl_view `mode`: the step of the dispatch.
const uint VPL_VIEW_CLEAR = 0u;
const uint VPL_VIEW_DEPTH = 1u;
const uint VPL_VIEW_ID = 2u;
const uint VPL_VIEW_DRAW = 3u;
// photon_emit `mode`: what the dispatch does.
const uint PHOTON_EMIT_DIRECT = 0u;
const uint PHOTON_EMIT_PATHS = 1u;
const uint PHOTON_EMIT_SCALE = 2u;
// bench ray_rate `mode`: the kind of ray (shaders/bench/ray_rate.comp).
const uint RAY_RATE_PRIMARY = 0u;
const uint RAY_RATE_SHADOW = 1u;
const uint RAY_RATE_BOUNCE = 2u;
// restir_spatial: most neighbours per pass (the settings refuse more).
const uint MAX_SPATIAL_NEIGHBOURS = 32u;
// RGBA32UI texels per pixel in the G-buffer (texel_records.glsl packs a Surface into them).
const uint SURFACE_TEXELS = 4u;
// Storage-buffer bindings gbuffer writes the G-buffer through (each an equal run of records).
const uint GBUFFER_CHUNKS = 8u;
// VplCandidate: index bits of `vpl_kind` (the kind above); vpl_presample tiles.
const uint CANDIDATE_INDEX_BITS = 30u;
const uint PRESAMPLE_TILE_SIZE = 1024u;
const uint PRESAMPLE_MAX_TILES = 128u;

struct VplParams {
    uint vpl_count;
    uint attenuation;
    float yuksel_r2;
    uint kind_mask;
    uint candidates;
    uint source;
    float total_vpl_lum;
    uint flags;
};

// The world-space grid of presampled VPLs (ReGIR): GpuGridParams in src/gpu_types.rs.
const uint REGIR_WORKGROUP = 64u;
const uint GRID_FLAG_BALANCE = 1u;
struct GridParams {
    vec3 lo;
    uint cells;
    vec3 cell_size;
    uint entries;
    uint entry_candidates;
    uint grid_candidates;
    uint flags;  // GRID_FLAG_*
    uint _pad1;
};

// A VplCandidate (the first 32 bytes) and its contribution weight: GpuGridEntry.
struct GridEntry {
    vec3 position;
    uint vpl_kind;
    vec3 flux;
    uint normal_oct;
    float ucw;
    uint _pad0;
    uint _pad1;
    uint _pad2;
};

#endif
