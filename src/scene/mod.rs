//! Scene description: glTF 2.0 loading into flat, renderer-friendly data. The scene generators
//! (the committed scenes, the furnace box and the glTF writer they use) are in [`generate`].
//!
//! All positions are in the glTF scene's units (metres for the built-in scenes).
//! Error messages name the file (or label) and the offending mesh/primitive;
//! they are single-level `anyhow` errors, so `{}` already shows everything.

mod base64;
pub mod generate;
mod load;
pub use load::MAX_LIGHT_POWER;
mod merge;

#[cfg(test)]
mod tests;

use glam::{Mat4, Vec2, Vec3, Vec4};
use std::path::PathBuf;

/// A loaded scene: meshes (one BLAS each), their instances, materials, camera and lights.
#[derive(Clone, Debug)]
pub struct Scene {
    /// File the scene was loaded from (or the label given to [`Scene::from_gltf_slice`]).
    pub path: PathBuf,
    /// One per glTF mesh referenced by at least one node of the chosen glTF scene.
    pub meshes: Vec<Mesh>,
    /// One per node with a mesh, in depth-first traversal order.
    pub instances: Vec<Instance>,
    /// The glTF materials, plus a default material appended if any primitive has none.
    pub materials: Vec<Material>,
    /// The first node (depth-first from the roots) carrying a perspective camera.
    pub camera: Option<Camera>,
    /// `KHR_lights_punctual` point lights.
    pub point_lights: Vec<PointLight>,
    /// Decoded base colour textures, indexed by [`Material::base_color_texture`].
    pub textures: Vec<Texture>,
    /// Non-fatal problems (unsupported features that were ignored).
    pub warnings: Vec<String>,
    /// The files besides `path` the scene names (external buffers and images, the images of
    /// materials it does not use included, though they are not read), so that a run can refuse
    /// outputs that would overwrite them: the file is the user's either way.
    pub files: Vec<PathBuf>,
    /// Where the file's coordinates put this scene's origin: a point's coordinates here are its
    /// coordinates in the file less `origin`. Zero unless the scene lies farther from the file's
    /// origin than its own size, when the loader renders it about its centre (rays are traced in
    /// 32-bit floats; load.rs `choose_origin` says why). Camera inputs and outputs stay in the
    /// file's coordinates.
    pub origin: Vec3,
}

/// Triangle mesh in object space; all glTF primitives of one mesh concatenated.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// glTF mesh name, or `mesh{index}`.
    pub name: String,
    /// Object-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Same length as `positions`; `Vec3::ZERO` where the primitive has no `NORMAL`
    /// (the renderer then uses the flat geometric normal).
    pub normals: Vec<Vec3>,
    /// Same length as `positions`; `Vec2::ZERO` where `TEXCOORD_0` is absent.
    pub uvs: Vec<Vec2>,
    /// Triangle list indexing `positions`.
    pub indices: Vec<u32>,
    /// One entry per triangle: index into [`Scene::materials`].
    pub triangle_materials: Vec<u32>,
}

/// A placement of a mesh in the world.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Node name, or `node{index}`.
    pub name: String,
    /// Index into [`Scene::meshes`].
    pub mesh: usize,
    /// World from object, with the full node hierarchy applied.
    pub transform: Mat4,
}

/// Diffuse material with optional emission.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// glTF material name, or `material{index}` (`default` for the appended default material).
    pub name: String,
    /// `baseColorFactor` (linear RGBA).
    pub base_color: Vec4,
    /// Emitted radiance Le: `emissiveFactor * KHR_materials_emissive_strength`.
    pub emission: Vec3,
    /// Whether back faces are shaded/emit like front faces.
    pub double_sided: bool,
    /// Index into [`Scene::textures`] of the base colour texture (`TEXCOORD_0`), if any; the
    /// albedo is `base_color` times the texture's linear (sRGB-decoded) colour.
    pub base_color_texture: Option<usize>,
}

/// A decoded glTF image used as a base colour texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// glTF image name, or `image{index}`.
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Row-major RGBA8, sRGB-encoded as stored in the file; row 0 is v = 0 (the image's top row).
    /// Empty where `texels_of` names the texture that holds them.
    pub rgba8: Vec<u8>,
    /// The sampler's magFilter is NEAREST: sampled as one texel (pixel art, labels, ID maps),
    /// else bilinear. (An image sampled both ways is two textures.)
    pub nearest: bool,
    /// The same image sampled the other way: its texels are those of this earlier texture (held
    /// and uploaded once).
    pub texels_of: Option<usize>,
}

impl Texture {
    /// A texture holding its own texels.
    pub fn new(name: String, width: u32, height: u32, rgba8: Vec<u8>, nearest: bool) -> Self {
        Self { name, width, height, rgba8, nearest, texels_of: None }
    }
}

/// Perspective camera.
#[derive(Clone, Debug)]
pub struct Camera {
    /// Camera (or node) name.
    pub name: String,
    /// World from camera; the camera looks down its local -Z with +Y up, as in glTF.
    pub transform: Mat4,
    /// Vertical field of view in radians.
    pub yfov: f32,
}

/// Isotropic point light (`KHR_lights_punctual` type `point`).
#[derive(Clone, Debug)]
pub struct PointLight {
    /// Light (or node) name.
    pub name: String,
    /// World-space position.
    pub position: Vec3,
    /// Linear RGB colour.
    pub color: Vec3,
    /// Luminous intensity in candela, as in glTF.
    pub intensity: f32,
}

/// A world-space emitting triangle, for light sampling / photon emission.
#[derive(Clone, Copy, Debug)]
pub struct EmissiveTriangle {
    /// World-space vertices, counter-clockwise about the front face: the mesh's order, the last
    /// two swapped for a mirroring instance.
    pub p: [Vec3; 3],
    /// Emitted radiance Le.
    pub emission: Vec3,
    /// World-space area.
    pub area: f32,
    /// Unit front-face normal in world space (glTF front face, mirroring accounted for).
    pub normal: Vec3,
    /// Whether the back face emits too.
    pub double_sided: bool,
    /// Index into [`Scene::instances`].
    pub instance: u32,
    /// Triangle index within the instance's mesh.
    pub triangle: u32,
}

impl Material {
    /// The material used for primitives without a material: 0.8 grey, not emissive, single-sided.
    pub fn default_material() -> Self {
        Material {
            name: "default".to_string(),
            base_color: Vec4::new(0.8, 0.8, 0.8, 1.0),
            emission: Vec3::ZERO,
            double_sided: false,
            base_color_texture: None,
        }
    }

    /// Whether any emission channel is positive.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

impl Mesh {
    /// The box `(min, max)` of the finite positions; None if there are none.
    pub fn finite_box(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.positions.iter().copied().filter(|p| p.is_finite());
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Per triangle, its flat edges: bit k is set when the edge opposite vertex k (matched by its
    /// end points' positions) is shared with exactly one other triangle, which lies in the same
    /// plane (within 1e-6 rad), faces the same way and lies across the edge: there the surface
    /// goes on flat, and a hit a few ulps past the edge is a hit on that neighbour. The GPU's
    /// `triangle_point` keeps hits a margin inside every other edge (an inside corner needs it: a
    /// hit past the edge is behind the other wall), not these: on a large plane split into two
    /// triangles the margin moved every hit near the diagonal (by 0.76 units on a 2e5-unit quad).
    pub fn flat_edges(&self) -> Vec<u8> {
        let n = self.triangle_count();
        let tri = |t: usize| self.triangle(t).filter(|p| p.iter().all(|v| v.is_finite())).map(|p| p.map(|v| v.as_dvec3()));
        // Vertices at one position (by bits) share an id: meshes repeat vertices per face.
        let mut first_at = std::collections::HashMap::with_capacity(self.positions.len());
        let id: Vec<u32> = (0..self.positions.len() as u32)
            .map(|v| *first_at.entry(self.positions[v as usize].to_array().map(f32::to_bits)).or_insert(v))
            .collect();
        // (the edge's two position ids, the triangle and the vertex opposite it), sorted by edge.
        let mut edges: Vec<(u64, u32)> = Vec::with_capacity(3 * n);
        for t in 0..n {
            let Some(i) = self.indices.get(3 * t..3 * t + 3).filter(|_| tri(t).is_some()) else { continue };
            for k in 0..3 {
                let (a, b) = (id[i[(k + 1) % 3] as usize], id[i[(k + 2) % 3] as usize]);
                edges.push(((u64::from(a.min(b)) << 32) | u64::from(a.max(b)), (3 * t + k) as u32));
            }
        }
        edges.sort_unstable_by_key(|e| e.0);
        let mut flat = vec![0u8; n];
        for sharing in edges.chunk_by(|x, y| x.0 == y.0).filter(|s| s.len() == 2) {
            let [(t, k), (u, l)] = [sharing[0].1, sharing[1].1].map(|tk| (tk as usize / 3, tk as usize % 3));
            if t == u {
                continue;
            }
            let (p, q) = (tri(t).expect("kept above"), tri(u).expect("kept above"));
            let (a, b) = (p[(k + 1) % 3], p[(k + 2) % 3]);
            let (nt, nu) = ((p[1] - p[0]).cross(p[2] - p[0]), (q[1] - q[0]).cross(q[2] - q[0]));
            let (Some(nt), Some(nu)) = (nt.try_normalize(), nu.try_normalize()) else { continue };
            // The other triangle's far vertex on this one's plane, on the other side of the edge.
            let (mine, theirs) = (p[k] - a, q[l] - a);
            let across = (b - a).cross(nt);
            let coplanar = nt.dot(theirs).abs() <= 1e-6 * theirs.length();
            if coplanar && nt.dot(nu) > 0.0 && across.dot(mine) * across.dot(theirs) < 0.0 {
                flat[t] |= 1 << k;
                flat[u] |= 1 << l;
            }
        }
        flat
    }

    /// Object-space vertices of triangle `t`, or `None` if `t` or its indices are out of range.
    pub fn triangle(&self, t: usize) -> Option<[Vec3; 3]> {
        let i = self.indices.get(3 * t..3 * t + 3)?;
        Some([
            *self.positions.get(i[0] as usize)?,
            *self.positions.get(i[1] as usize)?,
            *self.positions.get(i[2] as usize)?,
        ])
    }
}

impl Instance {
    /// True if the transform mirrors (negative determinant): the glTF front face is
    /// then clockwise in world space (e.g. needs a facing flip for ray-tracing instances).
    pub fn is_mirrored(&self) -> bool {
        self.transform.determinant() < 0.0
    }
}

impl Scene {
    /// Loads a `.gltf` (embedded `data:` URIs or external files relative to it) or `.glb` file.
    pub fn load(path: &std::path::Path) -> anyhow::Result<Scene> {
        load::load_path(path, load::TextureLoad::plain(true))
    }

    /// [`Scene::load`] for a run with `--textures` as given: with `textures` false the images are
    /// neither read nor decoded (a textured material keeps its base colour factor; its texture is a
    /// 1×1 white stand-in that nothing uploads), so a scene whose texture is missing or broken
    /// renders untextured, and a large one loads without the decoding's time.
    pub fn load_for(path: &std::path::Path, textures: bool) -> anyhow::Result<Scene> {
        load::load_path(path, load::TextureLoad::plain(textures))
    }

    /// [`Scene::load_for`] for a run on a device: textures that pass what every device reads
    /// through one buffer are checked against `device_range()` (the run's device's
    /// maxStorageBufferRange, None if unknown) before any is decoded, with the error the upload
    /// would give after decoding them all.
    pub fn load_for_device(path: &std::path::Path, textures: bool, device_range: &dyn Fn() -> Option<u64>) -> anyhow::Result<Scene> {
        load::load_path(path, load::TextureLoad { decode: textures, device_range })
    }

    /// Loads glTF JSON or GLB bytes. External buffer URIs are resolved against `base_dir`
    /// (and rejected when it is `None`); `label` names the source in error messages.
    pub fn from_gltf_slice(
        bytes: &[u8],
        base_dir: Option<&std::path::Path>,
        label: &str,
    ) -> anyhow::Result<Scene> {
        load::load_slice(bytes, base_dir, label, load::TextureLoad::plain(true))
    }

    /// Total number of instanced triangles.
    pub fn triangle_count(&self) -> usize {
        self.instances
            .iter()
            .filter_map(|inst| self.meshes.get(inst.mesh))
            .map(Mesh::triangle_count)
            .sum()
    }

    /// Total world-space area of all instanced triangles (one side each).
    pub fn surface_area(&self) -> f64 {
        let mut area = 0.0f64;
        // Each mesh's own area, once: an instance whose transform is a rotation and a uniform
        // scale s (and a move) has s² times it (10,000 instances of a large mesh transformed every
        // triangle of each); any other transforms its triangles.
        let mut own: Vec<Option<f64>> = vec![None; self.meshes.len()];
        for inst in &self.instances {
            let Some(mesh) = self.meshes.get(inst.mesh) else {
                continue;
            };
            if let Some(s2) = similarity_scale_squared(&inst.transform) {
                let a = *own[inst.mesh].get_or_insert_with(|| {
                    (0..mesh.triangle_count()).filter_map(|t| mesh.triangle(t)).map(|p| area_and_normal(p).0).filter(|x| x.is_finite()).sum()
                });
                area += s2 * a;
                continue;
            }
            for t in 0..mesh.triangle_count() {
                if let Some([a, b, c]) = mesh.triangle(t) {
                    let (a, b, c) = (
                        inst.transform.transform_point3(a),
                        inst.transform.transform_point3(b),
                        inst.transform.transform_point3(c),
                    );
                    let (x, _) = area_and_normal([a, b, c]);
                    if x.is_finite() {
                        area += x;
                    }
                }
            }
        }
        area
    }

    /// World-space AABB `(min, max)` of all instanced vertices with finite world positions;
    /// `(ZERO, ZERO)` if there are none. An instance whose transform only scales along the axes
    /// and moves takes its mesh's box, as exact as its vertices' up to the sign of a zero (each
    /// coordinate maps on its own, monotonically, rounding included); others transform every vertex (10,000 instances of a
    /// mesh of 1M vertices took half a minute that way).
    pub fn world_bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        let mut boxes: Vec<Option<Option<(Vec3, Vec3)>>> = vec![None; self.meshes.len()];
        for inst in &self.instances {
            let Some(mesh) = self.meshes.get(inst.mesh) else {
                continue;
            };
            let m = inst.transform;
            let diagonal = m.x_axis.y == 0.0
                && m.x_axis.z == 0.0
                && m.y_axis.x == 0.0
                && m.y_axis.z == 0.0
                && m.z_axis.x == 0.0
                && m.z_axis.y == 0.0
                && m.row(3) == glam::Vec4::W;
            if diagonal {
                let boxed = *boxes[inst.mesh].get_or_insert_with(|| mesh.finite_box());
                let Some((a, b)) = boxed else { continue };
                let (wa, wb) = (m.transform_point3(a), m.transform_point3(b));
                if wa.is_finite() && wb.is_finite() {
                    lo = lo.min(wa.min(wb));
                    hi = hi.max(wa.max(wb));
                    continue;
                }
            }
            for &p in &mesh.positions {
                let w = inst.transform.transform_point3(p);
                if !w.is_finite() {
                    continue; // the loader warns about these; they bound nothing
                }
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        if lo.x > hi.x {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (lo, hi)
        }
    }

    /// Every instanced triangle with an emissive material and positive world-space area (+Inf where
    /// the area does not fit f32: the loader refuses such a scene, `check_scene_reach`).
    pub fn emissive_triangles(&self) -> Vec<EmissiveTriangle> {
        self.emissive_triangles_and_tiny().0
    }

    /// [`Scene::emissive_triangles`], and how many emissive triangles it leaves out for an area
    /// that is positive but too small for f32 (under ~1.4e-45 in the scene's units squared: a
    /// scene at 1e-30 scale) and for an area of zero (degenerate, or flattened by a node's scale
    /// of 0), which the loader names in warnings.
    pub fn emissive_triangles_and_tiny(&self) -> (Vec<EmissiveTriangle>, usize, usize) {
        let mut out = Vec::new();
        let (mut tiny, mut degenerate) = (0, 0);
        for (ii, inst) in self.instances.iter().enumerate() {
            let Some(mesh) = self.meshes.get(inst.mesh) else {
                continue;
            };
            let flip = inst.is_mirrored();
            for (t, &mat) in mesh.triangle_materials.iter().enumerate() {
                let Some(material) = self.materials.get(mat as usize) else {
                    continue;
                };
                if !material.is_emissive() {
                    continue;
                }
                let Some(p) = mesh.triangle(t) else { continue };
                let p = p.map(|v| inst.transform.transform_point3(v));
                let (area64, normal) = area_and_normal(p);
                // Zero (or below f32's smallest) area: degenerate; NaN: non-finite vertices. Beyond
                // f32::MAX it is kept as +Inf for the loader to refuse, so nothing is dropped silently.
                let area = area64 as f32;
                if !(area > 0.0) {
                    tiny += usize::from(area64 > 0.0);
                    degenerate += usize::from(area64 == 0.0);
                    continue;
                }
                // A mirroring instance turns the mesh's counter-clockwise order clockwise: reversed,
                // the vertices' own winding gives the front face again, which is all the GPU's
                // light sampling has (it takes the normal from the vertex order).
                let (p, normal) = if flip { ([p[0], p[2], p[1]], -normal) } else { (p, normal) };
                out.push(EmissiveTriangle {
                    p,
                    emission: material.emission,
                    area,
                    normal,
                    double_sided: material.double_sided,
                    instance: ii as u32,
                    triangle: t as u32,
                });
            }
        }
        (out, tiny, degenerate)
    }
}

/// s² when the affine `m`'s linear part is a rotation (or reflection) times a uniform scale s,
/// within 1e-6 relative (its columns orthogonal and of one length: an f32 rotation is orthogonal
/// to ~1e-7, and areas then scale by s² to about that); None otherwise, or where it is
/// not finite. Areas scale by it.
fn similarity_scale_squared(m: &Mat4) -> Option<f64> {
    let m = m.as_dmat4();
    if m.row(3) != glam::DVec4::W {
        return None;
    }
    let c = [m.x_axis.truncate(), m.y_axis.truncate(), m.z_axis.truncate()];
    let s2 = (c[0].length_squared() + c[1].length_squared() + c[2].length_squared()) / 3.0;
    let tol = 1e-6 * s2;
    let uniform = c.iter().all(|v| (v.length_squared() - s2).abs() <= tol);
    let orthogonal = c[0].dot(c[1]).abs() <= tol && c[1].dot(c[2]).abs() <= tol && c[0].dot(c[2]).abs() <= tol;
    (s2 > 0.0 && s2.is_finite() && uniform && orthogonal).then_some(s2)
}

/// Area and unit normal (counter-clockwise winding) of the triangle `p`, computed in f64: in f32
/// the cross product of edges longer than ~1e19 (or its squared length, beyond ~1.8e19 m²)
/// overflows to Inf, and normalising it gives NaN. The area is 0 and the normal zero for a
/// degenerate triangle; the area is NaN or Inf only for non-finite vertices.
pub(crate) fn area_and_normal(p: [Vec3; 3]) -> (f64, Vec3) {
    let [a, b, c] = p.map(|v| v.as_dvec3());
    let cross = (b - a).cross(c - a);
    let len = cross.length();
    let normal = if len > 0.0 && len.is_finite() { (cross / len).as_vec3() } else { Vec3::ZERO };
    (0.5 * len, normal)
}
