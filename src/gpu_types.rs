//! GPU-visible structs and constants: the single Rust source of truth, mirrored in
//! `shaders/common/types.glsl` (std430 / std140-compatible). `tests/layout.rs` compiles that header
//! into SPIR-V and checks that every member name, offset and the struct sizes agree with these
//! definitions (through [`GpuStruct::FIELDS`], generated from the Rust fields themselves), and that
//! every `const uint` of the header has its twin of the same name and value in [`GLSL_CONSTANTS`].
//!
//! Rules: only 4-byte scalars, `[f32; 3]` followed by a scalar that fills its 16-byte slot, and
//! `[f32; 16]` matrices; explicit scalar padding fields (`_pad*`) everywhere else.

use bytemuck::{Pod, Zeroable};
use std::mem::size_of;

/// Implemented by every struct mirrored in GLSL.
pub trait GpuStruct: Pod {
    /// The struct's name in `shaders/common/types.glsl`.
    const GLSL_NAME: &'static str;
    /// (field name, byte offset) for every field, in declaration order.
    const FIELDS: &'static [(&'static str, usize)];
}

macro_rules! gpu_struct {
    ($(#[$m:meta])* pub struct $name:ident as $glsl:literal ($size:literal) {
        $( $(#[$fm:meta])* pub $f:ident : $t:ty ),* $(,)?
    }) => {
        $(#[$m])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
        pub struct $name { $( $(#[$fm])* pub $f: $t ),* }
        const _: () = assert!(size_of::<$name>() == $size);
        impl GpuStruct for $name {
            const GLSL_NAME: &'static str = $glsl;
            const FIELDS: &'static [(&'static str, usize)] =
                &[ $( (stringify!($f), std::mem::offset_of!($name, $f)) ),* ];
        }
    };
}

gpu_struct! {
    /// One mesh vertex: object-space position and normal (zero: use the flat geometric normal), uv.
    pub struct GpuVertex as "Vertex" (32) {
    pub position: [f32; 3],
    pub u: f32,
    pub normal: [f32; 3],
    pub v: f32,
}
}

/// Material flags (also `GpuLight::flags`).
pub const MATERIAL_DOUBLE_SIDED: u32 = 1;
/// `GpuLight::flags`: a point light (KHR_lights_punctual) at `p0` with radiant intensity
/// `emission` (W/sr), power 4π·I.
pub const LIGHT_POINT: u32 = 2;

gpu_struct! {
    /// Lambertian material: albedo = baseColorFactor, emitted radiance `emission`.
    pub struct GpuMaterial as "Material" (32) {
    pub albedo: [f32; 3],
    /// Texture index into the scene's texture array, or -1.
    pub texture: i32,
    pub emission: [f32; 3],
    /// `MATERIAL_*` bits.
    pub flags: u32,
}
}

gpu_struct! {
    /// One base-colour texture in the scene's texel buffer: `width × height` RGBA8 texels (sRGB
    /// encoded, row 0 = v 0) starting at texel `offset`. Sampled bilinearly with repeat wrapping.
    pub struct GpuTexture as "TextureInfo" (16) {
    pub offset: u32,
    pub width: u32,
    pub height: u32,
    /// `TEXTURE_NEAREST` or 0.
    pub flags: u32,
}
}

/// `GpuTexture::flags`: the sampler's magFilter is NEAREST: one texel, no filtering.
pub const TEXTURE_NEAREST: u32 = 1;

/// Instance flags.
pub const INSTANCE_MIRRORED: u32 = 1;
/// `GpuInstance::flags`: the transform is exactly the identity, so hit reconstruction skips both
/// matrices (their loads are most of a hit's memory reads on lavapipe).
pub const INSTANCE_IDENTITY: u32 = 2;
/// The triangle-material words (set 0's `triangle_materials`) hold the material index below this
/// bit and, from it, the triangle's flat edges ([`crate::scene::Mesh::flat_edges`]): bit k for the
/// edge opposite vertex k, shared with one coplanar triangle. `triangle_point` keeps its edge
/// margin only off the others.
pub const TRIANGLE_FLAT_EDGES_SHIFT: u32 = 29;

gpu_struct! {
    /// One TLAS instance (its `instanceCustomIndex` is its index here).
    pub struct GpuInstance as "Instance" (144) {
    /// World from object, column-major.
    pub world_from_object: [f32; 16],
    /// Inverse transpose of the upper 3×3 of `world_from_object`, column-major in a 4×4.
    pub normal_to_world: [f32; 16],
    /// First index of the mesh in the global index buffer (indices are local to the mesh).
    pub first_index: u32,
    /// First vertex of the mesh in the global vertex buffer.
    pub first_vertex: u32,
    /// First triangle of the mesh in the global per-triangle material buffer.
    pub first_triangle: u32,
    /// `INSTANCE_*` bits.
    pub flags: u32,
}
}

gpu_struct! {
    /// One emissive triangle in world space (an area light).
    pub struct GpuLight as "Light" (64) {
    pub p0: [f32; 3],
    /// World-space area (m²).
    pub area: f32,
    pub p1: [f32; 3],
    /// Probability of choosing this light, ∝ lum(Φ).
    pub pdf: f32,
    pub p2: [f32; 3],
    /// `MATERIAL_DOUBLE_SIDED` when it emits from both faces.
    pub flags: u32,
    /// Emitted radiance Le.
    pub emission: [f32; 3],
    pub _pad0: u32,
}
}

gpu_struct! {
    /// One slot of Vose's alias table.
    pub struct GpuAliasEntry as "AliasEntry" (8) {
    /// Probability of keeping this slot's own index.
    pub keep: f32,
    pub alias: u32,
}
}

gpu_struct! {
    /// The primary-hit record of one pixel, as the passes decode it from the G-buffer (stored
    /// packed: [`GpuSurfaceTexels`]).
    pub struct GpuSurface as "Surface" (80) {
    /// World-space hit position.
    pub position: [f32; 3],
    /// The hit triangle's largest |world coordinate|, the scale of its ray-origin offsets
    /// (`offset_ray` in shaders/lib/sampling.glsl); negative when the ray missed.
    pub offset_scale: f32,
    /// Shading normal, flipped to the viewer's side.
    pub shading_normal: [f32; 3],
    pub instance: u32,
    /// Geometric normal, flipped to the viewer's side.
    pub geometric_normal: [f32; 3],
    /// Triangle index within the instance's mesh.
    pub triangle: u32,
    pub albedo: [f32; 3],
    pub material: u32,
    /// Radiance emitted toward the camera (zero for the back of a single-sided emitter).
    pub emission: [f32; 3],
    /// View-space depth (distance along the camera's forward axis).
    pub view_depth: f32,
}
}

gpu_struct! {
    /// Frame constants (uniform buffer, set 0).
    pub struct GpuFrame as "Frame" (176) {
    pub camera_position: [f32; 3],
    /// tan(yfov / 2).
    pub tan_half_fov: f32,
    /// Camera basis: right, up and forward, unit length.
    pub camera_right: [f32; 3],
    pub aspect: f32,
    pub camera_up: [f32; 3],
    pub frame_index: u32,
    pub camera_forward: [f32; 3],
    pub seed: u32,
    pub width: u32,
    pub height: u32,
    /// Max bounces for the path tracer; negative: unbounded (Russian roulette only).
    pub max_bounces: i32,
    /// `FRAME_*` bits.
    pub flags: u32,
    pub light_count: u32,
    pub instance_count: u32,
    /// Σ over lights of lum(Φ) (for MIS: the light-selection pdf of a hit emitter).
    pub total_light_power: f32,
    /// Exposure multiplier for the tonemap pass (2^EV).
    pub exposure: f32,
    /// Frames accumulated so far including this one.
    pub accumulated_frames: u32,
    /// The G-buffer is a ping-pong of two halves in one buffer: this frame's surfaces start at
    /// element `surface_offset`, the previous frame's at `prev_surface_offset` (the same half when
    /// the G-buffer was not traced again this frame).
    pub surface_offset: u32,
    pub prev_surface_offset: u32,
    pub _pad1: u32,
    /// The previous frame's camera (for reprojection); equal to this frame's when it did not move.
    pub prev_camera_position: [f32; 3],
    pub prev_tan_half_fov: f32,
    pub prev_camera_right: [f32; 3],
    /// Tests only: `POISON_*`, a pass that writes a NaN (0: none).
    pub debug_poison: u32,
    pub prev_camera_up: [f32; 3],
    pub _pad2: u32,
    pub prev_camera_forward: [f32; 3],
    pub _pad3: u32,
}
}

/// Jitter primary rays inside the pixel (box filter).
pub const FRAME_AA: u32 = 1;


/// VPL kinds (`GpuVpl::kind`).
pub const VPL_DIRECT_AREA: u32 = 0;
pub const VPL_DIRECT_POINT: u32 = 1;
pub const VPL_INDIRECT: u32 = 2;

gpu_struct! {
    /// A virtual point light: a cosine emitter (isotropic for `VPL_DIRECT_POINT`) of flux `flux`.
    pub struct GpuVpl as "Vpl" (48) {
        /// World-space position, offset a few ulps off the surface along `normal`.
        pub position: [f32; 3],
        /// `VPL_*`.
        pub kind: u32,
        /// Unit normal, facing the side the photon arrived from (the emitting hemisphere).
        pub normal: [f32; 3],
        /// Index of the light sample (direct) or photon path (indirect) that made it.
        pub path: u32,
        /// Flux per channel (W).
        pub flux: [f32; 3],
        /// Yuksel's r² of this VPL alone, read with `VPL_FLAG_PER_VPL_RADIUS` (`--yuksel-knn`: from
        /// its nearest VPLs, `vpl_radius.rs`); 0 from the photon pass.
        pub yuksel_r2: f32,
    }
}

gpu_struct! {
    /// A ReSTIR reservoir after finalisation: the chosen VPL, its unbiased contribution weight W,
    /// its confidence M and the target p̂ of the chosen VPL at the reservoir's own pixel.
    pub struct GpuReservoir as "Reservoir" (16) {
        /// Index into the VPL buffer, or `RESERVOIR_EMPTY`.
        pub vpl: u32,
        /// Unbiased contribution weight W (0 when empty).
        pub ucw: f32,
        /// Confidence M (initial reservoirs count 1).
        pub confidence: f32,
        /// p̂ of `vpl` at the pixel that owns this reservoir.
        pub target: f32,
    }
}

gpu_struct! {
    /// A VPL as the RIS candidate loop reads it: a presampled copy (`vpl_presample` fills tiles of
    /// `PRESAMPLE_TILE_SIZE` of them), 32 bytes instead of 48, with its index and kind in one word
    /// and its normal octahedral-encoded (the photon pass stores every VPL normal already decoded
    /// from such a code, so both forms give the same target).
    pub struct GpuVplCandidate as "VplCandidate" (32) {
        pub position: [f32; 3],
        /// Index into the VPL buffer (low `CANDIDATE_INDEX_BITS` bits) and `VPL_*` kind above it.
        pub vpl_kind: u32,
        pub flux: [f32; 3],
        /// Octahedral normal, two snorm16 (`oct_encode` in shaders/lib/packing.glsl).
        pub normal_oct: u32,
    }
}

/// Bits of `GpuVplCandidate::vpl_kind` that hold the VPL index (the kind sits above them).
pub const CANDIDATE_INDEX_BITS: u32 = 30;
/// VPLs per presampled tile (a power of two: the candidate loop wraps with a mask).
pub const PRESAMPLE_TILE_SIZE: u32 = 1024;
/// Most tiles `vpl_presample` fills per frame (fewer for small images: one per 8×8 block of pixels).
pub const PRESAMPLE_MAX_TILES: u32 = 128;

/// `GpuReservoir::vpl` of an empty reservoir.
pub const RESERVOIR_EMPTY: u32 = u32::MAX;

/// `GpuVplParams::attenuation`.
pub const ATTENUATION_INVERSE_SQUARE: u32 = 0;
pub const ATTENUATION_YUKSEL: u32 = 1;
/// `GpuVplParams::kind_mask` bits.
pub const KIND_MASK_DIRECT: u32 = 1;
pub const KIND_MASK_INDIRECT: u32 = 2;
/// `GpuVplParams::flags` bits.
/// Targets include visibility: the initial sample is shadow-tested (and zeroed when occluded).
pub const VPL_FLAG_INITIAL_VISIBILITY: u32 = 1;
/// Unbiased (visibility-aware generalised MIS) reuse.
pub const VPL_FLAG_UNBIASED: u32 = 2;
/// The previous frame's pixels are the same surface points (no jitter, static camera).
pub const VPL_FLAG_SAME_DOMAIN: u32 = 4;
/// `GpuVplParams::flags`: each VPL's own Yuksel r² (`GpuVpl::yuksel_r2`) instead of `yuksel_r2`.
pub const VPL_FLAG_PER_VPL_RADIUS: u32 = 8;

gpu_struct! {
    /// Parameters every VPL pass shares: the head of their push constants.
    pub struct GpuVplParams as "VplParams" (32) {
        pub vpl_count: u32,
        /// `ATTENUATION_*`.
        pub attenuation: u32,
        /// Yuksel's r² (scene units²).
        pub yuksel_r2: f32,
        /// `KIND_MASK_*`: which VPL kinds contribute (debug views direct/indirect).
        pub kind_mask: u32,
        /// RIS candidates per pixel (1: uniform sampling).
        pub candidates: u32,
        /// Candidate source: 0 uniform, 1 ∝ lum(Φ) through the VPL alias table.
        pub source: u32,
        /// Σ lum(Φ_i) over the VPLs (the power source's normalisation).
        pub total_vpl_lum: f32,
        /// `VPL_FLAG_*`.
        pub flags: u32,
    }
}

/// `GpuGridParams::flags`: balance-heuristic weights between the grid and the source pdf (off:
/// constant 1/M weights, which lean on the cell target's coverage).
pub const GRID_FLAG_BALANCE: u32 = 1;

/// Threads of a `regir_build` workgroup (one workgroup per grid cell; each thread builds
/// `entries / REGIR_WORKGROUP` of the cell's entries).
pub const REGIR_WORKGROUP: u32 = 64;

gpu_struct! {
    /// The world-space grid of presampled VPLs (ReGIR; `regir_build`, read by `restir_initial`).
    /// `cells == 0`: no grid (every candidate from the source pdf).
    pub struct GpuGridParams as "GridParams" (48) {
        /// The grid's lower corner (scene units).
        pub lo: [f32; 3],
        /// Cells per axis (0: no grid).
        pub cells: u32,
        /// One cell's extent along each axis.
        pub cell_size: [f32; 3],
        /// Entries per cell (a multiple of `REGIR_WORKGROUP`).
        pub entries: u32,
        /// Candidates from the source pdf behind each entry (RIS with the cell's target).
        pub entry_candidates: u32,
        /// Of a pixel's `GpuVplParams::candidates`, how many come from its cell's entries.
        pub grid_candidates: u32,
        /// `GRID_FLAG_*`.
        pub flags: u32,
        pub _pad1: u32,
    }
}

gpu_struct! {
    /// One entry of a ReGIR grid cell (`regir_build`): a VPL drawn by RIS with the cell's target,
    /// and its unbiased contribution weight W (0: the entry is empty).
    pub struct GpuGridEntry as "GridEntry" (48) {
        pub position: [f32; 3],
        /// As `GpuVplCandidate::vpl_kind`.
        pub vpl_kind: u32,
        pub flux: [f32; 3],
        pub normal_oct: u32,
        /// W = Σ w / p̂_c(y) of the entry's RIS.
        pub ucw: f32,
        pub _pad0: u32,
        pub _pad1: u32,
        pub _pad2: u32,
    }
}

/// `vpl_shade`'s `view` push constant: what the pass writes.
pub const SHADE_VIEW_FINAL: u32 = 0;
pub const SHADE_VIEW_RESERVOIR_W: u32 = 1;
pub const SHADE_VIEW_RESERVOIR_M: u32 = 2;
pub const SHADE_VIEW_VPL_KIND: u32 = 3;
pub const SHADE_VIEW_MOTION: u32 = 4;

/// `vpl_compensate`'s `first_hop` push constant: what the light found by its first ray carries
/// (the view's share of the image): the emission seen, and the VPL estimate + recursion there.
pub const COMPENSATE_EMISSION: u32 = 1;
pub const COMPENSATE_VPLS: u32 = 2;

/// `GpuFrame::debug_poison`: `vpl_shade` (or `restir_spatial_shade`, where it runs fused there)
/// writes a NaN at pixel (1, 1) (tests of `--check-finite`).
pub const POISON_VPL_SHADE: u32 = 1;
/// `GpuFrame::debug_poison`: `vpl_bruteforce` counts 2^32 − 256 rays more at pixel (0, 0), so that
/// a small frame carries into its counter's high word (tests of the 64-bit count).
pub const POISON_RAY_CARRY: u32 = 2;
/// `GpuFrame::debug_poison`: `vpl_presample` writes a NaN flux into entry 1 of tile 0 (tests of
/// `--check-finite` on the tiles).
pub const POISON_VPL_PRESAMPLE: u32 = 3;
/// `GpuFrame::debug_poison`: `regir_build` writes a NaN flux into entry 1 of every cell it builds
/// (tests of `--check-finite` on the grid).
pub const POISON_REGIR_BUILD: u32 = 4;

/// `vpl_view`'s `mode` push constant: clear the sphere buffers (per pixel), splat the nearest
/// sphere depth (per VPL), record the VPL at that depth (per VPL), draw (per pixel).
pub const VPL_VIEW_CLEAR: u32 = 0;
pub const VPL_VIEW_DEPTH: u32 = 1;
pub const VPL_VIEW_ID: u32 = 2;
pub const VPL_VIEW_DRAW: u32 = 3;

/// `photon_emit`'s `mode` push constant: direct VPLs, photon paths, flux normalisation.
pub const PHOTON_EMIT_DIRECT: u32 = 0;
pub const PHOTON_EMIT_PATHS: u32 = 1;
pub const PHOTON_EMIT_SCALE: u32 = 2;

/// The `mode` push constant of `bench --rays`' kernel (shaders/bench/ray_rate.comp): primary,
/// shadow or closest-hit ("bounce") rays.
pub const RAY_RATE_PRIMARY: u32 = 0;
pub const RAY_RATE_SHADOW: u32 = 1;
pub const RAY_RATE_BOUNCE: u32 = 2;

/// Most neighbours one `restir_spatial` pass merges (a fixed-size array in the shader).
pub const MAX_SPATIAL_NEIGHBOURS: u32 = 32;

/// RGBA32UI texels per pixel in the G-buffer: a [`GpuSurface`] packed by `surface_to_texels`
/// (shaders/common/texel_records.glsl) with its normals octahedral, 64 bytes instead of 80. On
/// lavapipe each 16-byte store costs several milliseconds of a 1280×720 frame
/// (docs/performance.md), so the G-buffer stores as few as hold the surface.
pub const SURFACE_TEXELS: u32 = 4;

/// Storage-buffer bindings the `gbuffer` pass writes the G-buffer through, each covering an equal
/// run of records (one binding may not span the whole buffer: lavapipe's maxStorageBufferRange is
/// 128 MiB, the two halves of a 1280×720 G-buffer 113 MiB, of 3840×2160 1 GiB). On lavapipe a
/// storage-buffer store costs a fraction of an `imageStore` to a texel buffer (docs/performance.md).
pub const GBUFFER_CHUNKS: u32 = 8;

/// One pixel's G-buffer record as stored: `position, offset_scale | albedo, oct(shading_normal) |
/// emission, oct(geometric_normal) | instance, triangle, material, view_depth`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuSurfaceTexels {
    pub words: [u32; 16],
}
const _: () = assert!(size_of::<GpuSurfaceTexels>() == SURFACE_TEXELS as usize * 16);

impl GpuSurfaceTexels {
    /// The surface as `surface_texels` decodes it on the GPU (normals up to float rounding).
    pub fn decode(&self) -> GpuSurface {
        let w = &self.words;
        let f = |i: usize| f32::from_bits(w[i]);
        GpuSurface {
            position: [f(0), f(1), f(2)],
            offset_scale: f(3),
            shading_normal: oct_decode(w[7]),
            instance: w[12],
            geometric_normal: oct_decode(w[11]),
            triangle: w[13],
            albedo: [f(4), f(5), f(6)],
            material: w[14],
            emission: [f(8), f(9), f(10)],
            view_depth: f(15),
        }
    }

    /// Whether word `w` of the record holds a float (the others hold ids and normal codes).
    pub fn is_float_word(w: usize) -> bool {
        !matches!(w, 7 | 11 | 12 | 13 | 14)
    }
}

/// `oct_decode` of shaders/lib/packing.glsl: the unit vector of an octahedral code (two snorm16,
/// x in the low half).
pub fn oct_decode(code: u32) -> [f32; 3] {
    let snorm = |h: u32| ((h as u16 as i16) as f32 / 32767.0).clamp(-1.0, 1.0);
    let (ex, ey) = (snorm(code & 0xffff), snorm(code >> 16));
    let mut n = [ex, ey, 1.0 - ex.abs() - ey.abs()];
    let t = (-n[2]).max(0.0);
    n[0] += if n[0] >= 0.0 { -t } else { t };
    n[1] += if n[1] >= 0.0 { -t } else { t };
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    [n[0] / len, n[1] / len, n[2] / len]
}

/// (name, value) of every constant above, listed by name once.
macro_rules! glsl_constants {
    ($($name:ident),* $(,)?) => { &[ $( (stringify!($name), $name) ),* ] };
}

/// Every `const uint` of `shaders/common/types.glsl` but the ray-counter slots (those are
/// `passes::RAY_SLOT_NAMES`): (GLSL name = Rust name, value).
pub const GLSL_CONSTANTS: &[(&str, u32)] = glsl_constants![
    MATERIAL_DOUBLE_SIDED,
    LIGHT_POINT,
    TEXTURE_NEAREST,
    INSTANCE_MIRRORED,
    INSTANCE_IDENTITY,
    TRIANGLE_FLAT_EDGES_SHIFT,
    FRAME_AA,
    VPL_DIRECT_AREA,
    VPL_DIRECT_POINT,
    VPL_INDIRECT,
    RESERVOIR_EMPTY,
    ATTENUATION_INVERSE_SQUARE,
    ATTENUATION_YUKSEL,
    KIND_MASK_DIRECT,
    KIND_MASK_INDIRECT,
    VPL_FLAG_INITIAL_VISIBILITY,
    VPL_FLAG_UNBIASED,
    VPL_FLAG_SAME_DOMAIN,
    VPL_FLAG_PER_VPL_RADIUS,
    SHADE_VIEW_FINAL,
    SHADE_VIEW_RESERVOIR_W,
    SHADE_VIEW_RESERVOIR_M,
    SHADE_VIEW_VPL_KIND,
    SHADE_VIEW_MOTION,
    COMPENSATE_EMISSION,
    COMPENSATE_VPLS,
    POISON_VPL_SHADE,
    POISON_RAY_CARRY,
    POISON_VPL_PRESAMPLE,
    POISON_REGIR_BUILD,
    VPL_VIEW_CLEAR,
    VPL_VIEW_DEPTH,
    VPL_VIEW_ID,
    VPL_VIEW_DRAW,
    PHOTON_EMIT_DIRECT,
    PHOTON_EMIT_PATHS,
    PHOTON_EMIT_SCALE,
    REGIR_WORKGROUP,
    GRID_FLAG_BALANCE,
    RAY_RATE_PRIMARY,
    RAY_RATE_SHADOW,
    RAY_RATE_BOUNCE,
    MAX_SPATIAL_NEIGHBOURS,
    SURFACE_TEXELS,
    GBUFFER_CHUNKS,
    CANDIDATE_INDEX_BITS,
    PRESAMPLE_TILE_SIZE,
    PRESAMPLE_MAX_TILES,
];
