//! The scene on the GPU: geometry, materials, instances, lights and BLAS/TLAS, uploaded once and
//! shared (through an `Arc`) by every renderer that draws it. Each renderer binds it as descriptor
//! set 0 (`SCENE_BINDINGS`, mirrored in shaders/common/scene.glsl) together with its own frame
//! uniform buffer (binding 8), see [`SceneGpu::write_set`].

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;
use glam::{Mat3, Mat4};

use crate::gpu_types::*;
use crate::lights::LightSet;
use crate::scene::Scene;
use crate::vk::accel::{self, InstanceDesc, MeshRange, SceneAccel};
use crate::vk::leaf_order::{self, Aabb};
use crate::passes::{ALIAS_TEXELS, RECORD_TEXELS, WORD_TEXELS};
use crate::vk::pipeline::{accel as accel_binding, storage, texels, uniform};
use crate::vk::{Binding, Buffer, Context, DescriptorSet};

/// Set 0's rows, then `extra` rows.
macro_rules! scene_bindings {
    ($($extra:expr),* $(,)?) => {
        &[
            accel_binding(0, "tlas"),
            texels(1, "vertices"),
            texels(2, "indices"),
            texels(3, "triangle_materials"),
            texels(4, "materials"),
            texels(5, "instances"),
            texels(6, "lights"),
            texels(7, "light_alias"),
            uniform(8, "frame"),
            $($extra),*
        ]
    };
}

/// Set 0, declared once for every pass.
pub const SCENE_BINDINGS: &[Binding] = scene_bindings!();

/// Set 0 of scenes drawn with base-colour textures: [`SCENE_BINDINGS`] plus the texture table and
/// the texels (RGBA8, sRGB-encoded), read by the `textured` shader variants only.
pub const SCENE_BINDINGS_TEXTURED: &[Binding] = scene_bindings!(storage(9, "textures"), storage(10, "texels"));

/// What the renderer needs to know of the scene besides its GPU buffers (kept from the [`Scene`]
/// it was uploaded from, so that renderers need only the [`SceneGpu`]).
#[derive(Clone, Debug)]
pub struct SceneInfo {
    /// The file the scene was loaded from (or its label).
    pub path: std::path::PathBuf,
    pub meshes: usize,
    pub materials: usize,
    /// Materials with a base-colour texture (whether or not textures were uploaded).
    pub textured_materials: usize,
    /// World-space bounds (min, max).
    pub bounds: (glam::Vec3, glam::Vec3),
    /// Total surface area of all instanced triangles (scene units²).
    pub surface_area: f64,
    /// The glTF camera (world transform, vertical field of view in radians), when there is one.
    pub camera: Option<(Mat4, f32)>,
    /// Loader warnings.
    pub warnings: Vec<String>,
    /// [`crate::scene::Scene::origin`]: the file's coordinates of this scene's origin.
    pub origin: glam::Vec3,
    /// The files besides `path` the scene was read from ([`crate::scene::Scene::files`]).
    pub files: Vec<std::path::PathBuf>,
}

pub struct SceneGpu {
    pub info: SceneInfo,
    /// Set 0's binding table (with or without the texture bindings).
    pub bindings: &'static [Binding],
    /// The scene's own lights (what renderers start with).
    pub lights: LightSet,
    /// The emitters behind them, to rebuild light sets with added lights.
    pub emitters: crate::lights::Emitters,
    pub triangle_count: usize,
    pub instance_count: usize,
    /// Base-colour textures are bound (set 0 is [`SCENE_BINDINGS_TEXTURED`]); passes that read
    /// albedo then use their `textured` shader variant.
    pub textured: bool,
    /// Texture count and texel bytes uploaded (0 when untextured).
    pub texture_count: usize,
    pub texel_bytes: usize,
    pub build_ms: f64,
    /// Wall ms of the BLAS builds and of the TLAS build (each waits for its submission; part of
    /// `build_ms`).
    pub blas_ms: f64,
    pub tlas_ms: f64,
    /// Instances merged into one world-space mesh ([`Scene::merged`]; 0 when not merged) and
    /// BLASes built.
    pub merged_instances: usize,
    pub blas_count: usize,
    // Kept alive for the descriptors.
    accel: SceneAccel,
    /// (binding, buffer) of every set-0 buffer but the frame constants.
    buffers: Vec<(u32, Buffer)>,
}

/// `GpuInstance::flags` of an instance with world-from-object transform `t`.
fn instance_flags(t: Mat4) -> u32 {
    let mirrored = if Mat3::from_mat4(t).determinant() < 0.0 { INSTANCE_MIRRORED } else { 0 };
    // Exactly the identity (glTF nodes without a transform): hit reconstruction skips the matrices.
    let identity = if t == Mat4::IDENTITY { INSTANCE_IDENTITY } else { 0 };
    mirrored | identity
}

fn storage_usage() -> vk::BufferUsageFlags {
    vk::BufferUsageFlags::STORAGE_BUFFER
}

/// Vertices and indices also feed the BLAS builds.
fn geometry_usage() -> vk::BufferUsageFlags {
    vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS | vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
}

impl SceneGpu {
    /// Uploads `scene`; with `textures` false (or a scene without textures) nothing texture-related
    /// is created and materials keep their base colour factor only. A scene of at most `merge_blas`
    /// triangles has its instances merged into one world-space mesh with one BLAS (`--merge-blas`,
    /// [`Scene::merged`]); every mesh's triangles and the TLAS's instances are handed to the builds
    /// in [`leaf_order::midpoint_split_order`].
    pub fn new(ctx: &Arc<Context>, scene: &Scene, textures: bool, merge_blas: u32) -> Result<Self> {
        // Every error names the scene, once (some said it, a buffer's device limit did not).
        Self::upload(ctx, scene, textures, merge_blas).with_context(|| scene.path.display().to_string())
    }

    fn upload(ctx: &Arc<Context>, scene: &Scene, textures: bool, merge_blas: u32) -> Result<Self> {
        let textured = textures && scene.materials.iter().any(|m| m.base_color_texture.is_some());
        let start = std::time::Instant::now();
        // What the rays see: a small scene's instances merged into one world-space mesh.
        let merge = scene.instances.len() > 1 && scene.triangle_count() <= merge_blas as usize;
        // The vertex buffer's texels (its meshes', and the merged copy of every instance's beside
        // them), checked before either is built: a few triangles over 2^26 vertices (a file's
        // accessor without a buffer view) were copied twice, 11 GB, before the buffer refused them.
        let mesh_vertices = |m: &crate::scene::Mesh| m.positions.len() as u64;
        let own: u64 = scene.meshes.iter().map(mesh_vertices).sum();
        let copied: u64 = if merge { scene.instances.iter().filter_map(|i| scene.meshes.get(i.mesh)).map(mesh_vertices).sum() } else { 0 };
        let texels = (own + copied) * (std::mem::size_of::<GpuVertex>() as u64 / RECORD_TEXELS.bytes);
        let limit = u64::from(ctx.properties.limits.max_texel_buffer_elements);
        anyhow::ensure!(
            texels <= limit,
            "{} vertices{} take {texels} texels, more than this device's maxTexelBufferElements ({limit})",
            own + copied,
            if merge { format!(" (with the merged copy of its {} instances: --merge-blas 0 leaves it out)", scene.instances.len()) } else { String::new() }
        );
        let merged_scene = merge.then(|| scene.merged());
        let traced = merged_scene.as_ref().unwrap_or(scene);
        let merged_instances = if merge { scene.instances.len() } else { 0 };
        anyhow::ensure!(
            (scene.materials.len() as u64) < 1 << TRIANGLE_FLAT_EDGES_SHIFT,
            "{} materials, more than the renderer indexes ({})",
            scene.materials.len(),
            1u32 << TRIANGLE_FLAT_EDGES_SHIFT
        );
        let mut vertices: Vec<GpuVertex> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut triangle_materials: Vec<u32> = Vec::new();
        let mut ranges = Vec::new();
        let mut mesh_first_triangle = Vec::new();
        let mut mesh_bounds = Vec::new();
        for mesh in &traced.meshes {
            let range = MeshRange {
                first_vertex: vertices.len() as u32,
                vertex_count: mesh.positions.len() as u32,
                first_index: indices.len() as u32,
                index_count: mesh.indices.len() as u32,
            };
            mesh_first_triangle.push(triangle_materials.len() as u32);
            for i in 0..mesh.positions.len() {
                let uv = mesh.uvs.get(i).copied().unwrap_or_default();
                vertices.push(GpuVertex {
                    position: mesh.positions[i].to_array(),
                    u: uv.x,
                    normal: mesh.normals.get(i).copied().unwrap_or_default().to_array(),
                    v: uv.y,
                });
            }
            // Triangles in the order that makes a non-sorting BVH builder's splits spatial
            // (leaf_order.rs); materials follow their triangles.
            let bounds: Vec<Aabb> = (0..mesh.triangle_count())
                .map(|t| mesh.triangle(t).map_or(Aabb::EMPTY, |p| Aabb::of_points(&p)))
                .collect();
            // Each word: the material, and from TRIANGLE_FLAT_EDGES_SHIFT the flat edges.
            let flat = mesh.flat_edges();
            for t in leaf_order::midpoint_split_order(&bounds) {
                let t = t as usize;
                indices.extend_from_slice(&mesh.indices[3 * t..3 * t + 3]);
                triangle_materials.push(mesh.triangle_materials[t] | u32::from(flat[t]) << TRIANGLE_FLAT_EDGES_SHIFT);
            }
            mesh_bounds.push(bounds.into_iter().fold(Aabb::EMPTY, Aabb::grow));
            ranges.push((mesh.name.clone(), range));
        }
        let materials: Vec<GpuMaterial> = scene
            .materials
            .iter()
            .map(|m| GpuMaterial {
                albedo: m.base_color.truncate().to_array(),
                texture: match m.base_color_texture {
                    Some(t) if textured => t as i32,
                    _ => -1,
                },
                emission: m.emission.to_array(),
                flags: if m.double_sided { MATERIAL_DOUBLE_SIDED } else { 0 },
            })
            .collect();
        let descs: Vec<InstanceDesc> = traced
            .instances
            .iter()
            .map(|inst| {
                let r = inst.transform.transpose().to_cols_array(); // rows of the transform
                InstanceDesc { mesh: inst.mesh, transform: r[..12].try_into().expect("12 of 16") }
            })
            .collect();
        let instance_bounds: Vec<Aabb> = traced
            .instances
            .iter()
            .map(|inst| {
                let b = mesh_bounds[inst.mesh];
                let corners: Vec<glam::Vec3> = (0..8)
                    .map(|c| {
                        let pick = |bit: u32, lo: f32, hi: f32| if c & bit == 0 { lo } else { hi };
                        let p = glam::Vec3::new(pick(1, b.min.x, b.max.x), pick(2, b.min.y, b.max.y), pick(4, b.min.z, b.max.z));
                        inst.transform.transform_point3(p)
                    })
                    .collect();
                Aabb::of_points(&corners)
            })
            .collect();
        let emitters = crate::lights::Emitters::from_scene(scene);
        let lights = LightSet::new(&emitters, &[]);

        let none = vk::BufferUsageFlags::empty();
        let vb = Buffer::with_texel_data(ctx, "scene.vertices", bytemuck::cast_slice(&vertices), RECORD_TEXELS, geometry_usage())?;
        let ib = Buffer::with_texel_data(ctx, "scene.indices", bytemuck::cast_slice(&indices), WORD_TEXELS, geometry_usage())?;
        let tm = Buffer::with_texel_data(ctx, "scene.triangle_materials", bytemuck::cast_slice(&triangle_materials), WORD_TEXELS, none)?;
        let mb = Buffer::with_texel_data(ctx, "scene.materials", bytemuck::cast_slice(&materials), RECORD_TEXELS, none)?;
        let accel = accel::build_scene(
            ctx,
            &vb,
            std::mem::size_of::<GpuVertex>() as u64,
            &ib,
            &ranges,
            &descs,
            &instance_bounds,
        )
        .context("building the acceleration structures")?;
        let instances: Vec<GpuInstance> = traced
            .instances
            .iter()
            .map(|inst| {
                let m = &ranges[inst.mesh].1;
                let t: Mat4 = inst.transform;
                let normal = Mat4::from_mat3(Mat3::from_mat4(t).inverse().transpose());
                GpuInstance {
                    world_from_object: t.to_cols_array(),
                    normal_to_world: normal.to_cols_array(),
                    first_index: m.first_index,
                    first_vertex: m.first_vertex,
                    first_triangle: mesh_first_triangle[inst.mesh],
                    flags: instance_flags(t),
                }
            })
            .collect();
        let inb = Buffer::with_texel_data(ctx, "scene.instances", bytemuck::cast_slice(&instances), RECORD_TEXELS, none)?;

        let mut buffers = vec![(1, vb), (2, ib), (3, tm), (4, mb), (5, inb)];
        let (mut texture_count, mut texel_bytes) = (0, 0);
        if textured {
            // Checked from the sizes before the texels are gathered into one more copy.
            let total: u64 = scene.textures.iter().map(|t| t.rgba8.len() as u64).sum();
            check_texel_range(scene, total, u64::from(ctx.properties.limits.max_storage_buffer_range))?;
            let mut table = Vec::with_capacity(scene.textures.len());
            let mut texels: Vec<u8> = Vec::with_capacity(total as usize);
            for t in &scene.textures {
                let flags = if t.nearest { crate::gpu_types::TEXTURE_NEAREST } else { 0 };
                // An image sampled two ways: the second texture reads the first one's texels.
                let offset = match t.texels_of {
                    Some(held) => table.get(held).map(|g: &GpuTexture| g.offset).context("a texture shares the texels of a later one")?,
                    None => (texels.len() / 4) as u32,
                };
                table.push(GpuTexture { offset, width: t.width, height: t.height, flags });
                texels.extend_from_slice(&t.rgba8);
            }
            anyhow::ensure!(
                texels.len() / 4 <= u32::MAX as usize,
                "textures hold {} texels, more than a 32-bit index reaches",
                texels.len() / 4
            );
            let tb = Buffer::with_data(ctx, "scene.textures", bytemuck::cast_slice(&table), storage_usage())?;
            let xb = Buffer::with_data(ctx, "scene.texels", &texels, storage_usage())?;
            texture_count = table.len();
            texel_bytes = texels.len();
            buffers.extend([(9, tb), (10, xb)]);
        }
        let bounds = scene.world_bounds();
        let info = SceneInfo {
            path: scene.path.clone(),
            meshes: scene.meshes.len(),
            materials: scene.materials.len(),
            textured_materials: scene.materials.iter().filter(|m| m.base_color_texture.is_some()).count(),
            bounds,
            surface_area: scene.surface_area(),
            camera: scene.camera.as_ref().map(|c| (c.transform, c.yfov)),
            warnings: scene.warnings.clone(),
            files: scene.files.clone(),
            origin: scene.origin,
        };
        Ok(Self {
            info,
            bindings: if textured { SCENE_BINDINGS_TEXTURED } else { SCENE_BINDINGS },
            lights,
            emitters,
            triangle_count: scene.triangle_count(),
            instance_count: scene.instances.len(),
            textured,
            texture_count,
            texel_bytes,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
            blas_ms: accel.blas_ms,
            tlas_ms: accel.tlas_ms,
            merged_instances,
            blas_count: accel.blas_count,
            accel,
            buffers,
        })
    }

    /// Points every variant of `set` (made from [`SceneGpu::bindings`]) at the scene: TLAS,
    /// geometry, materials and textures. The lights (bindings 6 and 7, see [`LightBuffers`]) and
    /// the frame constants (binding 8) belong to the renderer, which may add lights.
    pub fn write_set(&self, set: &DescriptorSet) -> Result<()> {
        set.write_accel(0, self.accel.tlas.raw)?;
        for (binding, buffer) in &self.buffers {
            set.write_buffer(*binding, buffer)?;
        }
        Ok(())
    }

    /// Whether the scene has emitters (area or point lights).
    pub fn has_emitters(&self) -> bool {
        !self.lights.lights.is_empty()
    }
}

/// A light set on the GPU: set 0's `lights` (binding 6) and `light_alias` (binding 7).
pub struct LightBuffers {
    pub set: LightSet,
    lights: Buffer,
    alias: Buffer,
}

impl LightBuffers {
    pub fn new(ctx: &Arc<Context>, set: LightSet) -> Result<Self> {
        let none = vk::BufferUsageFlags::empty();
        let lights = Buffer::with_texel_data(ctx, "scene.lights", bytemuck::cast_slice(&set.lights), RECORD_TEXELS, none)?;
        let alias = Buffer::with_texel_data(ctx, "scene.light_alias", bytemuck::cast_slice(&set.alias), ALIAS_TEXELS, none)?;
        Ok(Self { set, lights, alias })
    }

    /// Points bindings 6 and 7 of every variant of `set` at these lights.
    pub fn write_set(&self, set: &DescriptorSet) -> Result<()> {
        set.write_buffer(6, &self.lights)?;
        set.write_buffer(7, &self.alias)
    }
}

/// Refuses textures whose texels (`texel_bytes` of RGBA8 in one buffer) exceed a device's
/// maxStorageBufferRange (`range`): all texels are one storage-buffer binding, which a shader can
/// only read as far as that range (128 MiB on lavapipe, ~4 GiB on desktop GPUs); past it, reads are
/// undefined (VUID-VkWriteDescriptorSet-descriptorType-00333). The error names the sizes, the
/// largest textures and the way out ([`SceneGpu::new`] names the scene before it).
pub fn check_texel_range(scene: &Scene, texel_bytes: u64, range: u64) -> Result<()> {
    if texel_bytes <= range {
        return Ok(());
    }
    let largest = largest_textures(scene.textures.iter().map(|t| (t.name.as_str(), t.width, t.height)));
    Err(texel_range_refusal(&format!("{} textures", scene.textures.len()), texel_bytes, range, &largest))
}

/// The refusal of textures (`what`: "3 textures", "base colour textures") whose `texel_bytes` of
/// RGBA8 pass a device's maxStorageBufferRange `range`, naming `largest` ([`largest_textures`]):
/// the upload's ([`check_texel_range`]) and the loader's, which refuses them before decoding.
pub fn texel_range_refusal(what: &str, texel_bytes: u64, range: u64, largest: &str) -> anyhow::Error {
    anyhow::anyhow!(
        "its {what} hold {:.1} MiB of RGBA8 texels, more than this device lets a shader read through \
         one buffer (maxStorageBufferRange: {:.1} MiB); render with --textures off, or scale down the largest \
         ({largest})",
        texel_bytes as f64 / 1048576.0,
        range as f64 / 1048576.0,
    )
}

/// The three largest of `textures` (name, width, height) as the refusals name them: `'name' WxH`.
pub fn largest_textures<'a>(textures: impl Iterator<Item = (&'a str, u32, u32)>) -> String {
    let mut all: Vec<(&str, u32, u32)> = textures.collect();
    all.sort_by_key(|&(_, w, h)| std::cmp::Reverse(u64::from(w) * u64::from(h)));
    all.iter().take(3).map(|(name, w, h)| format!("'{name}' {w}x{h}")).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn only_the_exact_identity_skips_the_matrices() {
        assert_eq!(instance_flags(Mat4::IDENTITY), INSTANCE_IDENTITY);
        assert_eq!(instance_flags(Mat4::from_scale(Vec3::ONE)), INSTANCE_IDENTITY);
        assert_eq!(instance_flags(Mat4::from_translation(Vec3::new(0.0, 1e-7, 0.0))), 0);
        assert_eq!(instance_flags(Mat4::from_scale(Vec3::new(1.0, 1.0, 1.0 + 1e-6))), 0);
        assert_eq!(instance_flags(Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0))), INSTANCE_MIRRORED);
    }
}
