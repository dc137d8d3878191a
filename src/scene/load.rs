//! glTF 2.0 loader: parses with the `gltf` crate (without its importer), resolves buffers
//! itself and reads accessors with explicit bounds checks, so malformed input yields an
//! error instead of a panic.

use super::{base64, Camera, Instance, Material, Mesh, PointLight, Scene, Texture};
use anyhow::{anyhow, bail, Context, Result};
use glam::{DMat3, DMat4, DVec3, Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::khr_lights_punctual::Kind as LightKind;
use gltf::mesh::{Mode, Semantic};
use gltf::Document;
use std::collections::BTreeMap;
use std::path::Path;

/// Accessors without a buffer view (all zeros, only sparse) larger than this are rejected,
/// to avoid absurd allocations from a tiny malicious file.
const MAX_VIEWLESS_ACCESSOR_BYTES: usize = 1 << 30;

/// How a load treats the textures: whether it decodes them, and the byte limit of the device that
/// will read them, asked only when their texels pass what every Vulkan device allows
/// ([`MIN_STORAGE_BUFFER_RANGE`]), so that a device's refusal comes before the decoding.
#[derive(Clone, Copy)]
pub struct TextureLoad<'a> {
    pub decode: bool,
    /// maxStorageBufferRange of the device the run will use (None: not known).
    pub device_range: &'a dyn Fn() -> Option<u64>,
}

impl TextureLoad<'_> {
    pub fn plain(decode: bool) -> TextureLoad<'static> {
        TextureLoad { decode, device_range: &|| None }
    }
}

/// Vulkan's guaranteed minimum maxStorageBufferRange (2^27 bytes, lavapipe's value): textures
/// within it fit every device, so no device is asked.
pub const MIN_STORAGE_BUFFER_RANGE: u64 = 1 << 27;

/// Reads and loads a `.gltf`/`.glb` file; external URIs resolve relative to its directory.
pub(super) fn load_path(path: &Path, decode_textures: TextureLoad) -> Result<Scene> {
    let bytes = crate::output::read_input(path).map_err(|e| anyhow!("scene file: {e:#}"))?;
    let base = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    let mut scene = load_slice(&bytes, Some(base), &path.display().to_string(), decode_textures)?;
    scene.path = path.to_path_buf();
    Ok(scene)
}

/// Loads glTF JSON or GLB bytes; every error is prefixed with `label`.
pub(super) fn load_slice(bytes: &[u8], base_dir: Option<&Path>, label: &str, decode_textures: TextureLoad) -> Result<Scene> {
    // glTF 2.0 lets a loader ignore a UTF-8 byte-order mark before the JSON; serde_json does not.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    load_inner(bytes, base_dir, label, decode_textures).map_err(|e| anyhow!("{label}: {e:#}"))
}

/// The glTF extensions the renderer reads.
const SUPPORTED_EXTENSIONS: [&str; 2] = ["KHR_materials_emissive_strength", "KHR_lights_punctual"];

fn load_inner(bytes: &[u8], base_dir: Option<&Path>, label: &str, decode_textures: TextureLoad) -> Result<Scene> {
    let (doc, blob) = parse(bytes)?;
    let buffers = load_buffers(&doc, base_dir, blob)?;
    let mut warnings = Vec::new();
    // Optional extensions the renderer does not read change the picture without a word otherwise
    // (KHR_texture_transform moved no texture); required ones are refused by the parser.
    for ext in doc.extensions_used() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) {
            warnings.push(format!("extension {ext} (in extensionsUsed) is not supported: ignored, so the image may differ from other renderers'"));
        }
    }
    check_node_matrices(doc.as_json(), &mut warnings);
    check_node_cycles(&doc)?;

    let nodes = traverse(&doc, &mut warnings)?;
    check_morph_weights(&nodes, &mut warnings);

    // Meshes referenced by the chosen scene, in glTF index order.
    let referenced: BTreeMap<usize, gltf::Mesh> = nodes
        .iter()
        .filter_map(|(node, _)| node.mesh().map(|m| (m.index(), m)))
        .collect();
    if referenced.is_empty() && doc.default_scene().is_none() && doc.scenes().len() > 1 {
        let with_meshes: Vec<String> = doc
            .scenes()
            .filter(|sc| sc.index() > 0 && scene_has_meshes(sc))
            .map(|sc| sc.name().map_or_else(|| sc.index().to_string(), |n| format!("{} ('{}')", sc.index(), shown_name(n))))
            .collect();
        if !with_meshes.is_empty() {
            bail!(
                "no triangles in scene 0, which is rendered because the file sets no default scene (its \"scene\" field); \
                 scene {} holds meshes: set \"scene\" to its index",
                with_meshes.join(", ")
            );
        }
    }
    check_geometry_size(&referenced)?;
    // The materials the chosen scene's primitives use: only their textures are read (a texture of
    // a material nothing here uses failed the scene when it could not be read).
    let used: std::collections::BTreeSet<usize> =
        referenced.values().flat_map(|m| m.primitives()).filter(|p| triangle_mode(p.mode())).filter_map(|p| p.material().index()).collect();

    // Materials: all glTF materials, the default one appended below if needed.
    let mut materials: Vec<Material> = doc
        .materials()
        .map(|m| convert_material(&m, &mut warnings))
        .collect::<Result<_>>()?;
    // The renderer's one BRDF is Lambertian: a metal (metallicFactor 1 is glTF's default when
    // pbrMetallicRoughness leaves it out) renders as a diffuse surface of its base colour, far
    // from how it looks elsewhere. One warning names them, after the alpha modes'.
    let mut metals: Vec<String> = Vec::new();
    for m in doc.materials().filter(|m| m.index().is_some_and(|i| used.contains(&i))) {
        let name = &materials[m.index().expect("filtered on the index")].name;
        if m.alpha_mode() != gltf::material::AlphaMode::Opaque {
            warnings.push(format!(
                "material '{name}': alphaMode {:?} (cut-outs, transparency) is not supported; rendered opaque",
                m.alpha_mode()
            ));
        }
        let pbr = m.pbr_metallic_roughness();
        if pbr.metallic_factor() > 0.0 {
            let texture = if pbr.metallic_roughness_texture().is_some() { " × its metallicRoughnessTexture" } else { "" };
            metals.push(format!("'{name}' ({}{texture})", pbr.metallic_factor()));
        }
    }
    if !metals.is_empty() {
        let shown = metals.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
        let more = if metals.len() > 5 { format!(" and {} more", metals.len() - 5) } else { String::new() };
        warnings.push(format!(
            "{} material(s) with a metallicFactor above 0 (metalness; 1 is glTF's default when the file leaves it out): {shown}{more}; \
             rendered as Lambertian diffuse surfaces of their base colour (the renderer's only BRDF)",
            metals.len()
        ));
    }
    let textures = load_textures(&doc, &buffers, base_dir, decode_textures, &used, &mut materials, &mut warnings)?;
    let default_material = materials.len() as u32;
    let mut uses_default = false;
    let mut mesh_map = BTreeMap::new();
    let mut meshes = Vec::with_capacity(referenced.len());
    for (gltf_index, gltf_mesh) in &referenced {
        let mesh = load_mesh(
            gltf_mesh,
            &buffers,
            &materials,
            default_material,
            &mut uses_default,
            &mut warnings,
        )?;
        mesh_map.insert(*gltf_index, meshes.len());
        meshes.push(mesh);
    }
    if uses_default {
        materials.push(Material::default_material());
    }

    let mut instances = Vec::new();
    let mut mesh_boxes: Vec<Option<Option<(Vec3, Vec3)>>> = vec![None; meshes.len()];
    let mut camera = None;
    let mut point_lights = Vec::new();
    // Where the scene is rendered about (zero unless it lies far from the file's origin), and
    // each mesh's own shift; the transforms move below, the meshes after the checks.
    let (origin, mesh_shift) = choose_origin(&meshes, &nodes, &mesh_map);
    let origin_f64 = origin.as_dvec3();
    for (node, world_f64) in &nodes {
        // The file's world transform in f32, which the checks judge (as before the move).
        let world = &world_f64.as_mat4();
        let node_name = node
            .name()
            .map(shown_name)
            .unwrap_or_else(|| format!("node{}", node.index()));
        if let Some(m) = node.mesh() {
            if let Some(&mesh) = mesh_map.get(&m.index()) {
                if Mat3::from_mat4(*world) == Mat3::ZERO {
                    // A zero scale is how glTF exporters hide a node: it has no surface to render.
                    warnings.push(format!("node '{node_name}' (mesh '{}'): scaled to nothing (zero scale), skipped", meshes[mesh].name));
                    continue;
                }
                let boxed = *mesh_boxes[mesh].get_or_insert_with(|| meshes[mesh].finite_box());
                check_mesh_transform(world, &meshes[mesh], boxed, &node_name)?;
                instances.push(Instance {
                    name: node_name.clone(),
                    mesh,
                    transform: moved_affine(world_f64, mesh_shift[mesh], origin_f64),
                });
            }
        }
        if let Some(cam) = node.camera() {
            let name = cam
                .name()
                .map(shown_name)
                .unwrap_or_else(|| node_name.clone());
            match cam.projection() {
                gltf::camera::Projection::Perspective(p) if camera.is_none() => {
                    // Kept whatever its yfov: one outside --fov's range is refused when a run would
                    // look through it, not when --eye/--target or --camera-path replace it
                    // (camera::scene_camera_problem). Ignored with a warning, the automatic camera
                    // took its place: a black image where it looked at the back of a wall.
                    check_camera_transform(world, &node_name, &name)?;
                    // (Its aspectRatio is the image's --width/--height, as glTF viewers do with
                    // the viewport's; exporters write it always, so it is not warned about.)
                    camera = Some(Camera {
                        name,
                        transform: moved_affine(world_f64, DVec3::ZERO, origin_f64),
                        yfov: p.yfov(),
                    });
                }
                gltf::camera::Projection::Perspective(_) => warnings.push(format!(
                    "camera '{name}' ignored (only the first perspective camera is used)"
                )),
                gltf::camera::Projection::Orthographic(_) => warnings.push(format!(
                    "orthographic camera '{name}' not supported, ignored"
                )),
            }
        }
        if let Some(light) = node.light() {
            let name = light
                .name()
                .map(shown_name)
                .unwrap_or_else(|| node_name.clone());
            match light.kind() {
                LightKind::Point => {
                    let position = (world_f64.w_axis.truncate() - origin_f64).as_vec3();
                    if !position.is_finite() || !world.w_axis.truncate().is_finite() {
                        bail!(
                            "point light '{name}' (node '{node_name}'): degenerate transform (non-finite world position {position})"
                        );
                    }
                    let (color, intensity) = (light.color(), light.intensity());
                    if !(color.iter().all(|c| c.is_finite() && *c >= 0.0) && intensity.is_finite() && intensity >= 0.0) {
                        bail!(
                            "point light '{name}': color {} and intensity {intensity} must be finite and non-negative \
                             (a negative channel emits negative light)",
                            fmt_floats(&color)
                        );
                    }
                    if let Some(range) = light.range() {
                        warnings.push(format!(
                            "point light '{name}': range {range} ignored; the light falls off with 1/d² everywhere"
                        ));
                    }
                    point_lights.push(PointLight {
                        name,
                        position,
                        color: Vec3::from_array(light.color()),
                        intensity: light.intensity(),
                    })
                }
                LightKind::Directional => {
                    warnings.push(format!("directional light '{name}' not supported, ignored"))
                }
                LightKind::Spot { .. } => {
                    warnings.push(format!("spot light '{name}' not supported, ignored"))
                }
            }
        }
        if node.skin().is_some() {
            warnings.push(format!(
                "node '{node_name}': skinning not supported, ignored"
            ));
        }
    }

    // The meshes move once every transform was checked against the file's vertices.
    for (m, shift) in meshes.iter_mut().zip(&mesh_shift) {
        if *shift != DVec3::ZERO {
            for p in &mut m.positions {
                *p = (p.as_dvec3() - *shift).as_vec3();
            }
        }
    }

    // Warnings are printed away from the load (in the run's summary): name the file in each. A
    // check below that refuses the scene carries them in its error instead, since they are often
    // its cause (a node scaled to nothing, non-finite positions) and no summary follows.
    let unlabelled = warnings.clone();
    let warnings = warnings.into_iter().map(|w| format!("{label}: {w}")).collect();
    let scene = Scene {
        path: label.into(),
        meshes,
        instances,
        materials,
        camera,
        point_lights,
        textures,
        warnings,
        files: external_files(&doc, base_dir),
        origin,
    };
    check_scene(scene).map_err(|e| {
        if unlabelled.is_empty() {
            e
        } else {
            anyhow!("{e:#} (the loader also noted: {})", unlabelled.join("; "))
        }
    })
}

/// The most emissive triangles (over all instances) a scene may have: each is a light of the
/// light set (its record, alias entry and host copy, ~130 bytes).
const MAX_EMISSIVE_TRIANGLES: u64 = 1 << 24;

/// The checks of a whole loaded scene: triangles to draw, emitters whose area and power a 32-bit
/// float holds. Adds a warning for emitters too small to keep.
fn check_scene(mut scene: Scene) -> Result<Scene> {
    let label = scene.path.display().to_string();
    if scene.triangle_count() == 0 {
        bail!("no triangles in scene");
    }
    check_scene_reach(&scene)?;
    if scene.origin != Vec3::ZERO {
        let o = scene.origin;
        log::info!("{label}: rendered about its bounds' centre [{}, {}, {}], far from the file's origin for its size (32-bit rays); camera inputs and outputs stay in the file's coordinates", o.x, o.y, o.z);
    }
    // Counted per mesh before any is made: every instance of an emissive mesh is its own lights
    // (200 instances of a 1M-triangle emissive grid took all 24 GB of memory and were killed).
    let emissive_per_mesh: Vec<u64> = scene
        .meshes
        .iter()
        .map(|m| m.triangle_materials.iter().filter(|&&mat| scene.materials.get(mat as usize).is_some_and(|x| x.is_emissive())).count() as u64)
        .collect();
    let emissive: u64 = scene.instances.iter().map(|i| emissive_per_mesh.get(i.mesh).copied().unwrap_or(0)).sum();
    if emissive > MAX_EMISSIVE_TRIANGLES {
        bail!(
            "its instances hold {emissive} emissive triangles, more than the renderer's light set takes ({MAX_EMISSIVE_TRIANGLES}); \
             make fewer triangles (or instances) emissive"
        );
    }
    // (Every emitter's area fits f32: check_scene_reach.)
    let (emitters, tiny, degenerate) = scene.emissive_triangles_and_tiny();
    if tiny > 0 {
        // Dropped from the light set; said, since in a tiny scene they can be all its light.
        scene.warnings.push(format!(
            "{}: {tiny} emissive triangle{} an area under 32-bit floats' smallest (1.4e-45 in the scene's units squared): \
             left out of the lights (in a scene this small, scale it up)",
            label,
            if tiny == 1 { " has" } else { "s have" }
        ));
    }
    if emitters.is_empty() && scene.point_lights.is_empty() && degenerate > 0 {
        // Else the only message was "no emitters", beside an emissive material the file plainly has
        // (a node's scale of 0 along one axis, which would flatten them, is refused above).
        scene.warnings.push(format!(
            "{}: its {degenerate} emissive triangle{} zero area (degenerate: {} vertices in a line or at one point), so the scene has no light",
            label,
            if degenerate == 1 { " has" } else { "s have" },
            if degenerate == 1 { "its" } else { "their" }
        ));
    }
    check_light_power(&scene, &emitters)?;
    Ok(scene)
}

/// Formats float components as `[-1, -1, -1, 1]` (exponent notation for huge or tiny values).
fn fmt_floats(v: &[f32]) -> String {
    let parts: Vec<String> = v
        .iter()
        .map(|&x| {
            let a = x.abs();
            if a.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
                format!("{x:e}")
            } else {
                format!("{x}")
            }
        })
        .collect();
    format!("[{}]", parts.join(", "))
}

/// A matrix's four columns as `[..], [..], [..], [..]` (`fmt_floats` each).
fn fmt_columns(m: &Mat4) -> String {
    m.to_cols_array_2d().iter().map(|c| fmt_floats(c)).collect::<Vec<_>>().join(", ")
}

/// A node's local matrix. TRS rotations are normalised first: the gltf crate builds the matrix
/// from the quaternion as written, so a non-unit one scales and shears and a zero one silently
/// becomes the identity. glTF requires unit quaternions; a zero or non-finite one is an error,
/// one off unit length by more than f32 rounding is normalised (with a warning beyond 1e-3).
fn local_matrix(node: &gltf::Node, warnings: &mut Vec<String>) -> Result<Mat4> {
    use gltf::scene::Transform;
    // JSON numbers beyond f32 read as ±Inf: said of the property, not as a NaN world matrix later.
    let outside = |what: &str, values: &[f32]| -> Result<()> {
        if values.iter().all(|v| v.is_finite()) {
            return Ok(());
        }
        bail!("node '{}': its {what} has a value outside the 32-bit float range (beyond ±3.4e38)", node_label(node))
    };
    let transform = match node.transform() {
        Transform::Decomposed { translation, rotation, scale } => {
            outside("translation", &translation)?;
            outside("rotation", &rotation)?;
            outside("scale", &scale)?;
            let len = rotation.iter().map(|&c| f64::from(c).powi(2)).sum::<f64>().sqrt();
            if !(len > 0.0 && len.is_finite()) {
                bail!(
                    "node '{}': rotation quaternion {} has length {len}; glTF requires a unit quaternion \
                     (a zero or non-finite one is no rotation)",
                    node_label(node),
                    fmt_floats(&rotation)
                );
            }
            let rotation = if (len - 1.0).abs() > 1e-6 {
                if (len - 1.0).abs() > 1e-3 {
                    warnings.push(format!(
                        "node '{}': rotation quaternion {} has length {}, not 1; normalised",
                        node_label(node),
                        fmt_floats(&rotation),
                        len as f32
                    ));
                }
                rotation.map(|c| (f64::from(c) / len) as f32)
            } else {
                rotation
            };
            Transform::Decomposed { translation, rotation, scale }
        }
        Transform::Matrix { matrix } => {
            outside("matrix", matrix.as_flattened())?;
            Transform::Matrix { matrix }
        }
    };
    Ok(Mat4::from_cols_array_2d(&transform.matrix()))
}

/// Node matrices the loader reads other than as written: one beside translation, rotation or
/// scale (glTF forbids both; the matrix is used), and one whose last row is not (0, 0, 0, 1) (a
/// projective matrix; read as affine).
fn check_node_matrices(root: &gltf::json::Root, warnings: &mut Vec<String>) {
    for (i, node) in root.nodes.iter().enumerate() {
        let Some(m) = node.matrix else { continue };
        let name = node.name.as_deref().map(shown_name).unwrap_or_else(|| format!("node{i}"));
        if node.translation.is_some() || node.rotation.is_some() || node.scale.is_some() {
            warnings.push(format!(
                "node '{name}': has a matrix and translation/rotation/scale, which glTF forbids; the matrix is used and the rest ignored"
            ));
        }
        // Column-major: the last row is elements 3, 7, 11 and 15.
        let row = [m[3], m[7], m[11], m[15]];
        if row != [0.0, 0.0, 0.0, 1.0] {
            warnings.push(format!("node '{name}': its matrix's last row is {}, not (0, 0, 0, 1); read as an affine transform", fmt_floats(&row)));
        }
    }
}

/// glTF's nodes form disjoint trees. A node that is its own ancestor is refused, naming the
/// cycle: traversal would drop the repeated reference, and in a file without scenes (where the
/// roots are the nodes nobody lists as a child) the cycle's nodes would vanish without a word.
fn check_node_cycles(doc: &Document) -> Result<()> {
    let nodes: Vec<gltf::Node> = doc.nodes().collect();
    let children: Vec<Vec<usize>> = nodes.iter().map(|n| n.children().map(|c| c.index()).collect()).collect();
    // 0: not reached yet, 1: on the current path, 2: done.
    let mut state = vec![0u8; nodes.len()];
    for start in 0..nodes.len() {
        if state[start] != 0 {
            continue;
        }
        state[start] = 1;
        let mut path = vec![(start, 0usize)];
        while let Some((node, next)) = path.last_mut() {
            let Some(&child) = children[*node].get(*next) else {
                state[*node] = 2;
                path.pop();
                continue;
            };
            *next += 1;
            match state.get(child) {
                Some(0) => {
                    state[child] = 1;
                    path.push((child, 0));
                }
                Some(1) => {
                    let from = path.iter().position(|&(n, _)| n == child).expect("a node on the path");
                    let cycle: Vec<String> =
                        path[from..].iter().map(|&(n, _)| node_label(&nodes[n])).chain([node_label(&nodes[child])]).collect();
                    bail!("node {child} ('{}') is its own ancestor ({}): glTF nodes must form trees", node_label(&nodes[child]), cycle.join(" -> "));
                }
                _ => {}
            }
        }
    }
    Ok(())
}

/// Morph targets are not applied: the base shape is rendered. Said where a node's (or its mesh's
/// default) weights would move it.
fn check_morph_weights(nodes: &[(gltf::Node, DMat4)], warnings: &mut Vec<String>) {
    let mut warned = std::collections::BTreeSet::new();
    for (node, _) in nodes {
        let Some(mesh) = node.mesh() else { continue };
        let targets = mesh.primitives().map(|p| p.morph_targets().len()).max().unwrap_or(0);
        let weights = node.weights().or_else(|| mesh.weights()).unwrap_or_default();
        if targets > 0 && weights.iter().any(|&w| w != 0.0) && warned.insert(mesh.index()) {
            let name = mesh.name().map_or_else(|| format!("mesh{}", mesh.index()), shown_name);
            warnings.push(format!(
                "mesh '{name}' (node '{}'): morph targets are not supported; its weights {} are ignored and the base shape is rendered",
                node_label(node),
                fmt_floats(weights)
            ));
        }
    }
}

/// The node's name, or `node{index}`.
fn node_label(node: &gltf::Node) -> String {
    node.name()
        .map(shown_name)
        .unwrap_or_else(|| format!("node{}", node.index()))
}

/// A camera node must have a finite orthonormal basis by plain f32 arithmetic: a zero or non-finite
/// matrix, a scale so small that the axes' squared lengths underflow f32, or parallel -Z and +Y axes
/// are refused. ([`crate::camera::Camera::from_transform`] would make a finite basis of any of these
/// by rescaling or picking an up direction, but the file's camera is then not the one it means.)
fn check_camera_transform(world: &Mat4, node_name: &str, camera_name: &str) -> Result<()> {
    let forward = (-world.z_axis.truncate()).normalize();
    let right = forward.cross(world.y_axis.truncate()).normalize();
    let up = right.cross(forward);
    let unit = |v: Vec3| v.is_finite() && (v.length() - 1.0).abs() < 1e-3;
    if world.w_axis.truncate().is_finite() && unit(forward) && unit(right) && unit(up) {
        return Ok(());
    }
    let what = if camera_name == node_name {
        format!("camera node '{node_name}'")
    } else {
        format!("camera node '{node_name}' (camera '{camera_name}')")
    };
    bail!(
        "{what}: degenerate transform (non-finite or zero-length basis): its world matrix has columns {}; \
         a camera needs a finite transform whose local -Z and +Y axes are non-zero and not parallel",
        fmt_columns(world)
    )
}

/// A mesh node's world transform must be finite and invertible (the renderer transforms normals
/// with its inverse transpose, which is NaN for a zero scale or matrix) and must keep the mesh's
/// finite vertices finite.
/// `boxed`: the mesh's [`Mesh::finite_box`], computed once per mesh.
fn check_mesh_transform(world: &Mat4, mesh: &Mesh, boxed: Option<(Vec3, Vec3)>, node_name: &str) -> Result<()> {
    let what = format!("node '{node_name}' (mesh '{}')", mesh.name);
    if !world.is_finite() {
        bail!(
            "{what}: degenerate transform (non-finite world matrix, columns {})",
            fmt_columns(world)
        );
    }
    // As the renderer inverts it: in f32 (a determinant overflowing f32 gives a zero inverse,
    // which is finite; one underflowing to zero, an infinite one).
    let linear = Mat3::from_mat4(*world);
    if linear.determinant() == 0.0 || !linear.inverse().is_finite() {
        let det = linear.as_dmat3().determinant();
        let det = if det == 0.0 { "0".to_string() } else { format!("{det:.3e}") };
        bail!(
            "{what}: degenerate transform (its world matrix cannot be inverted in 32-bit floats, determinant {det}: \
             a zero, tiny or huge scale, or a zero matrix); the renderer cannot transform its normals"
        );
    }
    // Every finite vertex must map to a finite point. When the bound of any coordinate over the
    // mesh's box (each term at its largest, summed in f64) stays far inside f32, none can
    // overflow; only else is every vertex transformed (per instance: 10,000 instances of a mesh
    // of 1M vertices took half a minute).
    let safe = boxed.is_none_or(|(lo, hi)| {
        let reach = lo.abs().max(hi.abs()).as_dvec3();
        let m = world.as_dmat4();
        (0..3).all(|i| {
            let row = m.row(i);
            let bound = row.x.abs() * reach.x + row.y.abs() * reach.y + row.z.abs() * reach.z + row.w.abs();
            bound < f64::from(f32::MAX) / 4.0
        })
    });
    if let Some(p) = mesh
        .positions
        .iter()
        .filter(|_| !safe)
        .find(|p| p.is_finite() && !world.transform_point3(**p).is_finite())
    {
        bail!(
            "{what}: the world transform takes vertex {p} to a non-finite position (beyond 32-bit floats); scale the scene down"
        );
    }
    Ok(())
}

/// How many times its own largest extent a scene's (or a mesh's) bounds' centre may lie from the
/// origin along an axis before it is moved: 4 bits of precision. (The Cornell box 1e3 away, 1800
/// extents, rendered 0.6 % bright in the path tracer, 3e3 away 1.2 %; a scene a few extents off
/// the origin loses a bit or two, and is left where the file has it.)
const FAR_FROM_ORIGIN: f64 = 16.0;

/// Where a scene is rendered about, and how far each mesh's vertices move: a scene whose bounds'
/// centre lies farther from the file's origin along an axis than [`FAR_FROM_ORIGIN`] times the
/// bounds' largest extent is moved so that the centre (rounded to f32, so that the file's coordinates are the renderer's
/// plus it, once rounded) is the origin; a mesh whose vertices lie that far from its own origin
/// (by the same rule) moves by its box's centre, its instances' transforms compensating. Rays are traced in 32-bit
/// floats and leave surfaces a few hundred ulps of their coordinates off them (`offset_ray`): a
/// Cornell box at 1e4 had its shadow rays and VPLs a quarter of a unit off the walls and rendered
/// 3.6× too dark, one at 1e5 two units off, its floor black. The bounds come from each
/// instance's mesh box corners under its f64 world transform (a box of the box: enough to decide).
fn choose_origin(meshes: &[Mesh], nodes: &[(gltf::Node, DMat4)], mesh_map: &BTreeMap<usize, usize>) -> (Vec3, Vec<DVec3>) {
    let boxes: Vec<Option<(Vec3, Vec3)>> = meshes.iter().map(Mesh::finite_box).collect();
    let far = |(a, b): (DVec3, DVec3)| ((a + b) * 0.5).abs().max_element() > FAR_FROM_ORIGIN * (b - a).max_element();
    let mesh_shift: Vec<DVec3> = boxes
        .iter()
        .map(|b| match b {
            Some((a, b)) if far((a.as_dvec3(), b.as_dvec3())) => ((*a + *b) * 0.5).as_dvec3(),
            _ => DVec3::ZERO,
        })
        .collect();
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for (node, world) in nodes {
        let Some(Some((a, b))) = node.mesh().and_then(|m| mesh_map.get(&m.index())).map(|&i| boxes[i]) else { continue };
        for corner in box_corners(a, b) {
            let p = world.transform_point3(corner.as_dvec3());
            if p.is_finite() {
                (lo, hi) = (lo.min(p), hi.max(p));
            }
        }
    }
    let origin = if lo.x <= hi.x && far((lo, hi)) { ((lo + hi) * 0.5).as_vec3() } else { Vec3::ZERO };
    if !origin.is_finite() {
        return (Vec3::ZERO, vec![DVec3::ZERO; meshes.len()]);
    }
    (origin, mesh_shift)
}

/// The world transform `world` of a mesh moved by `shift` (its vertices less `shift`), in a scene
/// rendered about `origin`: as an affine map (the renderer reads rows 0–2; a last row other than
/// (0, 0, 0, 1) is kept as the file has it), its translation becomes t + L·shift − origin, in f64.
fn moved_affine(world: &DMat4, shift: DVec3, origin: DVec3) -> Mat4 {
    let t = world.w_axis.truncate() + DMat3::from_mat4(*world) * shift - origin;
    DMat4::from_cols(world.x_axis, world.y_axis, world.z_axis, t.extend(world.w_axis.w)).as_mat4()
}

/// The eight corners of the box `(a, b)`.
fn box_corners(a: Vec3, b: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|k| Vec3::new(if k & 1 == 0 { a.x } else { b.x }, if k & 2 == 0 { a.y } else { b.y }, if k & 4 == 0 { a.z } else { b.z }))
}

/// Geometry, point lights and the camera within [`MAX_CAMERA_COORDINATE`](crate::camera::MAX_CAMERA_COORDINATE)
/// (1e18) of the origin, as `--eye` and `--target` must be: rays are traced in 32-bit floats, and a
/// shadow ray between points ~1e19 apart has a length that overflows, so it reads as blocked
/// (trace.glsl's `segment_ray`). A Cornell box scaled to 5e19 rendered 3,600× too dark, without a
/// word.
///
/// Within that reach a triangle's area is at most ~6e36, inside f32, so an emitter's area always
/// fits the light set's 32-bit record (a check of it after this one could never fail).
fn check_scene_reach(scene: &Scene) -> Result<()> {
    let most = crate::camera::MAX_CAMERA_COORDINATE;
    let far = |p: Vec3| p.abs().max_element() > most;
    // Each instance's mesh box, its eight corners transformed: within reach, every vertex is (a
    // point of the box is a convex combination of its corners, and so is its image under an
    // affine map). Only else are the vertices themselves bounded (world_bounds transforms every
    // vertex of an instance that is not axis-aligned: half a minute for 10,000 instances of a
    // 1M-vertex mesh, which the upload pays once already).
    let mut boxes: Vec<Option<Option<(Vec3, Vec3)>>> = vec![None; scene.meshes.len()];
    // In the file's coordinates: the renderer's plus the scene's origin (choose_origin).
    let file = |p: Vec3| (p.as_dvec3() + scene.origin.as_dvec3()).as_vec3();
    let boxed_within = scene.instances.iter().all(|inst| {
        let Some(mesh) = scene.meshes.get(inst.mesh) else { return true };
        let Some((a, b)) = *boxes[inst.mesh].get_or_insert_with(|| mesh.finite_box()) else { return true };
        box_corners(a, b).into_iter().all(|corner| {
            let p = file(inst.transform.transform_point3(corner));
            p.is_finite() && !far(p)
        })
    });
    let (lo, hi) = if boxed_within { (Vec3::ZERO, Vec3::ZERO) } else { let (lo, hi) = scene.world_bounds(); (file(lo), file(hi)) };
    let beyond = |what: String, p: Vec3| {
        anyhow!(
            "{what} lies at [{:.3e}, {:.3e}, {:.3e}], more than {most:e} from the origin along an axis: rays are traced in \
             32-bit floats; scale the scene down",
            p.x,
            p.y,
            p.z
        )
    };
    if far(lo) || far(hi) {
        let p = if far(lo) { lo } else { hi };
        return Err(beyond("its geometry (bounding box corner)".into(), p));
    }
    if let Some(l) = scene.point_lights.iter().find(|l| far(file(l.position))) {
        return Err(beyond(format!("point light '{}'", l.name), file(l.position)));
    }
    if let Some(c) = scene.camera.as_ref().filter(|c| far(file(c.transform.w_axis.truncate()))) {
        return Err(beyond(format!("camera '{}'", c.name), file(c.transform.w_axis.truncate())));
    }
    Ok(())
}

/// The most power (W, per channel) the lights may emit together. Fluxes, photon weights and
/// resampling weights are 32-bit floats on the GPU: a total near f32::MAX (3.4e38) overflows to
/// Inf on the way and every VPL mode rendered black without a word. 1e30 W leaves 8 orders of
/// magnitude for those products and is 4 orders above the Sun (3.8e26 W).
pub const MAX_LIGHT_POWER: f64 = 1e30;

fn check_light_power(scene: &Scene, emitters: &[super::EmissiveTriangle]) -> Result<()> {
    use std::f64::consts::PI;
    let mut lights: Vec<(f64, String)> = scene
        .point_lights
        .iter()
        .map(|l| (4.0 * PI * (l.color * l.intensity).max_element() as f64, format!("point light '{}'", l.name)))
        .collect();
    lights.extend(emitters.iter().map(|t| {
        let sides = if t.double_sided { 2.0 } else { 1.0 };
        (sides * PI * t.emission.max_element() as f64 * t.area as f64, format!("an emissive triangle of instance {}", t.instance))
    }));
    let total: f64 = lights.iter().map(|l| l.0).sum();
    if total.is_finite() && total <= MAX_LIGHT_POWER {
        return Ok(());
    }
    let brightest = lights.iter().max_by(|a, b| a.0.total_cmp(&b.0)).expect("a total above zero has a light");
    bail!(
        "the lights emit {total:.3e} W together, more than the {MAX_LIGHT_POWER:.0e} W the renderer's 32-bit fluxes \
         hold (the brightest: {}, {:.3e} W); scale the emission or intensity down",
        brightest.1,
        brightest.0
    )
}

/// Parses and validates the document; returns it with the GLB binary chunk, if any.
fn parse(bytes: &[u8]) -> Result<(Document, Option<Vec<u8>>)> {
    if bytes.starts_with(b"glTF") {
        // The gltf crate trusts the header's length field; check it first.
        let declared = bytes
            .get(8..12)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
            .ok_or_else(|| anyhow!("truncated GLB header ({} bytes)", bytes.len()))?;
        if declared < 12 || declared > bytes.len() {
            bail!(
                "GLB header declares {declared} bytes but the file has {}",
                bytes.len()
            );
        }
        // (The gltf crate said only "malformed glTF: unsupported version".)
        let version = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]);
        if version != 2 {
            bail!("GLB container version {version} is not supported: only version 2 (binary glTF 2.x) is read (version 1 is glTF 1.0's KHR_binary_glTF, another format)");
        }
        check_glb_chunks(&bytes[..declared])?;
    }
    // A byte-order mark opening a GLB's JSON chunk, ignored as the .gltf one is (load_slice): three
    // spaces in its place, JSON white space, keep every length and offset.
    let unmarked;
    let bytes = match bytes.get(20..23) {
        Some(b"\xEF\xBB\xBF") if bytes.starts_with(b"glTF") => {
            let mut copy = bytes.to_vec();
            copy[20..23].copy_from_slice(b"   ");
            unmarked = copy;
            &unmarked[..]
        }
        _ => bytes,
    };
    let parsed = gltf::Gltf::from_slice_without_validation(bytes).or_else(|e| with_scene_nodes_defaulted(bytes).ok_or(e));
    let gltf = match parsed {
        Ok(gltf) => gltf,
        Err(e) => {
            // A glTF 1.0 file fails the 2.0 schema: say which version it is rather than why.
            if let Ok(json) = serde_json::from_slice::<serde_json::Value>(bytes) {
                match &json["asset"]["version"] {
                    serde_json::Value::String(v) => check_version(v, None)?,
                    serde_json::Value::Number(v) => check_version(&v.to_string(), None)?,
                    _ => {}
                }
            }
            // Another kind of file entirely (a PLY, an OBJ): say what is read rather than where
            // the JSON parser stopped.
            let first = bytes.iter().find(|b| !b.is_ascii_whitespace());
            if first.is_none() {
                bail!("the file is empty (or only white space): not a glTF scene");
            }
            if !bytes.starts_with(b"glTF") && first != Some(&b'{') {
                let kind = if bytes.starts_with(b"ply") { " (it looks like a PLY file)" } else { "" };
                bail!("not a glTF file{kind}: scenes are glTF 2.0, as .gltf (JSON) or .glb (binary)");
            }
            bail!("malformed glTF: {e}");
        }
    };
    let root = gltf.document.as_json();
    check_version(&root.asset.version, root.asset.min_version.as_deref())?;
    precheck(root)?;

    use gltf::json::validation::Validate;
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, err| {
        errors.push(format!("{}: {err}", path()))
    });
    if !errors.is_empty() {
        bail!("invalid glTF: {}", errors.join("; "));
    }
    check_sources(root)?;
    Ok((gltf.document, gltf.blob))
}

/// Walks a GLB's chunks (the header already checked) so that a chunk whose length field runs
/// past the file, or a file that ends inside a chunk header, is named with its byte offset: the
/// gltf crate says only "failed to fill whole buffer" for some of these.
fn check_glb_chunks(glb: &[u8]) -> Result<()> {
    let mut at = 12;
    let mut k = 0;
    while at < glb.len() {
        let header = glb
            .get(at..at + 8)
            .ok_or_else(|| anyhow!("GLB chunk {k} at byte {at}: the file ends inside its 8-byte header"))?;
        let length = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
        let kind = String::from_utf8_lossy(&header[4..8]).trim_end_matches('\0').to_string();
        let left = glb.len() - at - 8;
        if length > left {
            bail!("GLB chunk {k} ({kind:?}) at byte {at} declares {length} bytes but only {left} follow its header");
        }
        if k == 0 && &header[4..8] != b"JSON" {
            bail!("GLB chunk 0 is {kind:?}; the first chunk must be JSON");
        }
        at += 8 + length;
        k += 1;
    }
    if k == 0 {
        bail!("GLB file has no chunks (a JSON chunk must follow the 12-byte header)");
    }
    Ok(())
}

/// `scene.nodes` is optional in glTF 2.0, but the gltf crate (1.4) requires it: the document
/// parsed again with `"nodes": []` given to every scene that lacks it, or None when no scene
/// lacks it (the parse failed for another reason) or it still fails.
fn with_scene_nodes_defaulted(bytes: &[u8]) -> Option<gltf::Gltf> {
    let (json, blob) = if bytes.starts_with(b"glTF") {
        let glb = gltf::Glb::from_slice(bytes).ok()?;
        (glb.json.into_owned(), glb.bin.map(std::borrow::Cow::into_owned))
    } else {
        (bytes.to_vec(), None)
    };
    let mut value: serde_json::Value = serde_json::from_slice(&json).ok()?;
    let mut defaulted = false;
    for scene in value.get_mut("scenes")?.as_array_mut()? {
        if let Some(scene) = scene.as_object_mut() {
            if !scene.contains_key("nodes") {
                scene.insert("nodes".into(), serde_json::Value::Array(Vec::new()));
                defaulted = true;
            }
        }
    }
    if !defaulted {
        return None;
    }
    let root: gltf::json::Root = serde_json::from_value(value).ok()?;
    Some(gltf::Gltf { document: Document::from_json_without_validation(root), blob })
}

/// What the schema validation leaves out and the gltf crate's accessors unwrap (they would panic):
/// an image needs a `uri` or a `bufferView`, the latter with a `mimeType`; a camera needs the
/// object its `type` names.
fn check_sources(root: &gltf::json::Root) -> Result<()> {
    use gltf::json::camera::Type;
    use gltf::json::validation::Checked;
    for (i, image) in root.images.iter().enumerate() {
        let name = image.name.clone().unwrap_or_else(|| format!("image{i}"));
        match (&image.uri, &image.buffer_view, &image.mime_type) {
            (Some(_), None, _) | (None, Some(_), Some(_)) => {}
            (None, None, _) => bail!("image {i} ('{name}') has neither a \"uri\" nor a \"bufferView\""),
            (Some(_), Some(_), _) => bail!("image {i} ('{name}') has both a \"uri\" and a \"bufferView\"; give one"),
            (None, Some(_), None) => bail!("image {i} ('{name}') has a \"bufferView\" but no \"mimeType\" (required with a bufferView)"),
        }
    }
    for (i, camera) in root.cameras.iter().enumerate() {
        let name = camera.name.clone().unwrap_or_else(|| format!("camera{i}"));
        let (has, object) = match camera.type_ {
            Checked::Valid(Type::Perspective) => (camera.perspective.is_some(), "perspective"),
            Checked::Valid(Type::Orthographic) => (camera.orthographic.is_some(), "orthographic"),
            Checked::Invalid => bail!("camera {i} ('{name}') has an invalid \"type\""),
        };
        if !has {
            bail!("camera {i} ('{name}') has \"type\": \"{object}\" but no \"{object}\" object");
        }
    }
    Ok(())
}

/// Only glTF 2.x is read: glTF 1.0 (and any other major version) is a different format, and an
/// asset whose minVersion is above 2.0 needs features this loader lacks.
fn check_version(version: &str, min_version: Option<&str>) -> Result<()> {
    let major = version.split('.').next().and_then(|m| m.parse::<u32>().ok());
    if major != Some(2) {
        bail!("asset.version '{version}' is not supported: only glTF 2.x (major version 2) is read");
    }
    if let Some(min) = min_version {
        if min != "2.0" {
            bail!("asset.minVersion '{min}' is not supported: only glTF 2.0 features are read");
        }
    }
    Ok(())
}

/// Checks done before the gltf crate's validation, which indexes the POSITION accessor
/// unchecked, and to report a missing POSITION with the mesh name.
fn precheck(root: &gltf::json::Root) -> Result<()> {
    use gltf::json::validation::Checked;
    // A view must lie inside its buffer's declared byteLength (the data may hold more: a view
    // past the declared length was read from the extra bytes without a word).
    for (vi, view) in root.buffer_views.iter().enumerate() {
        let Some(buffer) = root.buffers.get(view.buffer.value()) else { continue };
        let start = view.byte_offset.map_or(0, |o| o.0);
        let end = start.saturating_add(view.byte_length.0);
        if end > buffer.byte_length.0 {
            bail!(
                "buffer view {vi} (offset {start}, length {}) exceeds buffer {}'s byteLength ({} bytes)",
                view.byte_length.0,
                view.buffer.value(),
                buffer.byte_length.0
            );
        }
    }
    for (mi, mesh) in root.meshes.iter().enumerate() {
        let name = mesh.name.clone().unwrap_or_else(|| format!("mesh{mi}"));
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let Some(pos) = prim.attributes.get(&Checked::Valid(Semantic::Positions)) else {
                bail!("mesh '{name}' primitive {pi} has no POSITION attribute");
            };
            if pos.value() >= root.accessors.len() {
                bail!(
                    "mesh '{name}' primitive {pi}: POSITION accessor {} does not exist ({} accessors)",
                    pos.value(),
                    root.accessors.len()
                );
            }
        }
    }
    Ok(())
}

/// Resolves every buffer: GLB binary chunk, base64 `data:` URI or file relative to `base_dir`.
fn load_buffers(
    doc: &Document,
    base_dir: Option<&Path>,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<Vec<u8>>> {
    doc.buffers()
        .map(|buffer| {
            let i = buffer.index();
            let data = match buffer.source() {
                // Only buffer 0 may be the binary chunk (glTF 2.0, GLB): a later buffer without a
                // URI took it when buffer 0 had one, and one after buffer 0 was told the file had
                // no binary chunk.
                gltf::buffer::Source::Bin if i > 0 => {
                    bail!("buffer {i} has no \"uri\": only a .glb file's first buffer may omit it (it is then the binary chunk)")
                }
                gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                    anyhow!("buffer {i} has no \"uri\": only a .glb file's first buffer may omit it (it is then the binary chunk), and this file has no binary chunk")
                })?,
                gltf::buffer::Source::Uri(uri) => {
                    read_uri(uri, base_dir, Some(buffer.length() as u64)).with_context(|| format!("buffer {i}"))?
                }
            };
            if data.len() < buffer.length() {
                bail!(
                    "buffer {i}: expected {} bytes but found {}",
                    buffer.length(),
                    data.len()
                );
            }
            Ok(data)
        })
        .collect()
}

/// The files the document's buffers and images name (neither GLB chunks nor data URIs), as
/// [`read_uri`] resolves them ([`uri_file`]; a URI it would refuse names none).
fn external_files(doc: &Document, base_dir: Option<&Path>) -> Vec<std::path::PathBuf> {
    let buffers = doc.buffers().filter_map(|b| match b.source() {
        gltf::buffer::Source::Uri(uri) => Some(uri),
        gltf::buffer::Source::Bin => None,
    });
    let images = doc.images().filter_map(|i| match i.source() {
        gltf::image::Source::Uri { uri, .. } => Some(uri),
        gltf::image::Source::View { .. } => None,
    });
    buffers.chain(images).filter_map(|uri| uri_file(uri, base_dir).ok().flatten()).collect()
}

/// The bytes a URI names (of an external file, at most `at_most` of them where given).
fn read_uri(uri: &str, base_dir: Option<&Path>, at_most: Option<u64>) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| anyhow!("only base64 data URIs are supported"))?;
        return base64::decode(payload).map_err(|e| anyhow!("bad data URI: {e}"));
    }
    let path = uri_file(uri, base_dir)?.expect("not a data: URI (returned above)");
    crate::output::read_referenced(&path, at_most)
}

/// The file a URI names: relative to `base_dir`, percent-decoded; None for a `data:` URI, an
/// error for any other scheme, a control character, an absolute path or no base directory.
fn uri_file(uri: &str, base_dir: Option<&Path>) -> Result<Option<std::path::PathBuf>> {
    if uri.starts_with("data:") {
        return Ok(None);
    }
    if has_scheme(uri) {
        bail!("unsupported URI '{uri}' (only data: URIs and relative paths are supported)");
    }
    let relative = percent_decode(uri)?;
    if relative.chars().any(char::is_control) {
        // A NUL or other control character names no file and would reach the message raw.
        bail!("URI '{uri}' decodes to a path with a control character");
    }
    let rooted = Path::new(&relative).components().any(|c| matches!(c, std::path::Component::Prefix(_) | std::path::Component::RootDir));
    if relative.starts_with(['/', '\\']) || rooted {
        // base.join would drop the base (or, for a drive prefix such as C:x on Windows, its drive)
        // and read whatever file the URI names.
        bail!("URI '{uri}' is an absolute path; glTF names external files relative to the .gltf file");
    }
    let base = base_dir.ok_or_else(|| {
        anyhow!("external file '{relative}' cannot be resolved without a base directory")
    })?;
    Ok(Some(base.join(&relative)))
}

/// True if `uri` starts with an RFC 3986 scheme (`scheme:`).
fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            scheme.len() > 1
                && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
        }
        None => false,
    }
}

fn percent_decode(uri: &str) -> Result<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (bytes[i], hex) {
            (b'%', Some(b)) => {
                out.push(b);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out).map_err(|_| anyhow!("URI '{uri}' is not valid UTF-8 after decoding"))
}

/// Depth-first traversal of the chosen scene (default scene, else scene 0, else all root
/// nodes), returning each reachable node once with its world transform, composed in f64 (a
/// child's translation under a parent far from the origin keeps its digits until the scene is
/// moved about its centre: `choose_origin`).
fn traverse<'a>(
    doc: &'a Document,
    warnings: &mut Vec<String>,
) -> Result<Vec<(gltf::Node<'a>, DMat4)>> {
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; doc.nodes().len()];
            for node in doc.nodes() {
                for child in node.children() {
                    if let Some(flag) = is_child.get_mut(child.index()) {
                        *flag = true;
                    }
                }
            }
            doc.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };

    let mut visited = vec![false; doc.nodes().len()];
    let mut out = Vec::new();
    let mut stack: Vec<(gltf::Node, DMat4)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, DMat4::IDENTITY))
        .collect();
    while let Some((node, parent)) = stack.pop() {
        let Some(seen) = visited.get_mut(node.index()) else {
            continue;
        };
        if *seen {
            warnings.push(format!(
                "node {} is reachable more than once (a child of two parents, or listed twice); extra references ignored",
                node.index()
            ));
            continue;
        }
        *seen = true;
        let world = parent * local_matrix(&node, warnings)?.as_dmat4();
        stack.extend(
            node.children()
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .map(|c| (c, world)),
        );
        out.push((node, world));
    }
    Ok(out)
}

/// The material's name (shown as [`shown_name`] shows it), or `material{index}`.
fn material_label(m: &gltf::Material) -> String {
    m.name().map(shown_name).unwrap_or_else(|| format!("material{}", m.index().unwrap_or(0)))
}

fn convert_material(m: &gltf::Material, warnings: &mut Vec<String>) -> Result<Material> {
    let name = material_label(m);
    let pbr = m.pbr_metallic_roughness();
    // glTF 2.0 restricts each component to [0, 1]; outside it the albedo gives negative or
    // amplified (up to non-finite) radiance.
    let base_color = pbr.base_color_factor();
    if !base_color.iter().all(|c| (0.0..=1.0).contains(c)) {
        bail!(
            "material '{name}': baseColorFactor {} must lie in [0, 1]",
            fmt_floats(&base_color)
        );
    }
    // Errors, as baseColorFactor's are (a negative or infinite emission was set to zero after a
    // warning, which in a one-light scene rendered black). glTF 2.0 also restricts emissiveFactor
    // to [0, 1]: brightness above 1 is KHR_materials_emissive_strength's, and a file that puts it
    // in the factor is refused with the two numbers it should hold instead.
    let factor = m.emissive_factor();
    if !factor.iter().all(|c| c.is_finite() && *c >= 0.0) {
        bail!("material '{name}': emissiveFactor {} must be finite and not negative", fmt_floats(&factor));
    }
    let strength = m.emissive_strength().unwrap_or(1.0);
    if !(strength.is_finite() && strength >= 0.0) {
        bail!("material '{name}': KHR_materials_emissive_strength {strength} must be finite and not negative");
    }
    let largest = factor.iter().copied().fold(0.0f32, f32::max);
    if largest > 1.0 {
        let same = largest * strength;
        if !same.is_finite() {
            bail!(
                "material '{name}': emissiveFactor {} must lie in [0, 1] (glTF 2.0), and with emissive strength {strength} it \
                 overflows 32-bit floats",
                fmt_floats(&factor)
            );
        }
        bail!(
            "material '{name}': emissiveFactor {} must lie in [0, 1] (glTF 2.0); the same light is emissiveFactor {} \
             with KHR_materials_emissive_strength {{ \"emissiveStrength\": {same} }}",
            fmt_floats(&factor),
            fmt_floats(&factor.map(|c| c / largest))
        );
    }
    // A factor in [0, 1] times a finite strength is finite.
    let emission = Vec3::from_array(factor) * strength;
    if m.emissive_texture().is_some() && emission.max_element() > 0.0 {
        warnings.push(format!(
            "material '{name}': emissiveTexture is not supported: the whole surface emits emissiveFactor {}",
            fmt_floats(&m.emissive_factor())
        ));
    }
    Ok(Material {
        base_color: Vec4::from_array(base_color),
        emission,
        double_sided: m.double_sided(),
        // Filled in by `load_textures`.
        base_color_texture: None,
        name,
    })
}

/// Largest texture accepted (texels), so a corrupt header cannot ask for gigabytes.
const MAX_TEXELS: u64 = 1 << 26;

/// Longest name shown whole (characters); a longer one is cut there and says how long it was.
const SHOWN_NAME_CHARS: usize = 200;

/// A name from the file as messages and the summary show it: control characters escaped (a
/// material named "x\nerror: ..." printed a forged error line), and cut after
/// [`SHOWN_NAME_CHARS`] characters (a node named with a million characters was echoed whole in
/// its error).
fn shown_name(name: &str) -> String {
    let escaped = |s: &mut dyn Iterator<Item = char>| -> String {
        s.map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() }).collect()
    };
    let count = name.chars().count();
    if count <= SHOWN_NAME_CHARS {
        return escaped(&mut name.chars());
    }
    format!("{}… ({count} characters)", escaped(&mut name.chars().take(SHOWN_NAME_CHARS)))
}

/// Whether any node of `scene` (or below one) holds a mesh.
fn scene_has_meshes(scene: &gltf::Scene) -> bool {
    let mut stack: Vec<gltf::Node> = scene.nodes().collect();
    let mut seen = std::collections::BTreeSet::new();
    while let Some(n) = stack.pop() {
        if !seen.insert(n.index()) {
            continue;
        }
        if n.mesh().is_some() {
            return true;
        }
        stack.extend(n.children());
    }
    false
}

/// Vertices and indices over all of a scene's triangle primitives are limited to what the scene's
/// texel buffers hold on most devices (maxTexelBufferElements 2^27 on lavapipe, NVIDIA and Intel:
/// 2^26 vertices of two texels, 2^27 u32 indices), checked from the accessors' counts before any
/// is read: a few kilobytes of glTF (one large accessor without a buffer view, read by many
/// primitives) otherwise made the loader allocate tens of gigabytes and abort, and 2^26 vertices
/// took 11 GB and 30 s before the upload refused them without naming the file.
fn check_geometry_size(meshes: &BTreeMap<usize, gltf::Mesh>) -> Result<()> {
    const MAX_VERTICES: u64 = 1 << 26;
    const MAX_INDICES: u64 = 1 << 27;
    let (mut vertices, mut triangles) = (0u64, 0u64);
    for prim in meshes.values().flat_map(|m| m.primitives()).filter(|p| triangle_mode(p.mode())) {
        let n = prim.get(&Semantic::Positions).map_or(0, |a| a.count() as u64);
        // Counts come from the file (up to 2^64): the sums saturate.
        vertices = vertices.saturating_add(n);
        let listed = prim.indices().map_or(n, |a| a.count() as u64);
        triangles = triangles.saturating_add(if prim.mode() == Mode::Triangles { listed / 3 } else { listed.saturating_sub(2) });
    }
    if vertices > MAX_VERTICES || triangles.saturating_mul(3) > MAX_INDICES {
        bail!(
            "the scene's triangle primitives list {vertices} vertices and {triangles} triangles, more than a GPU's texel buffer \
             holds on most devices (at most {MAX_VERTICES} vertices and {} triangles)",
            MAX_INDICES / 3
        );
    }
    Ok(())
}

fn triangle_mode(mode: Mode) -> bool {
    matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)
}

/// Decodes every glTF image used as a base colour texture by a material in `used` (once each) and points the materials
/// at them. An unreadable or undecodable image is an error naming the material and the image.
fn load_textures(
    doc: &Document,
    buffers: &[Vec<u8>],
    base_dir: Option<&Path>,
    load: TextureLoad,
    used: &std::collections::BTreeSet<usize>,
    materials: &mut [Material],
    warnings: &mut Vec<String>,
) -> Result<Vec<Texture>> {
    let decode = load.decode;
    // Each used image read once, its size from its header; the total checked before any decode.
    let mut encoded = if decode { read_texture_images(doc, buffers, base_dir, used, load.device_range)? } else { BTreeMap::new() };
    let mut textures = Vec::new();
    let mut by_image: BTreeMap<(usize, bool), usize> = BTreeMap::new();
    for (m, material) in doc.materials().zip(materials.iter_mut()) {
        if !m.index().is_some_and(|i| used.contains(&i)) {
            continue;
        }
        let Some(info) = m.pbr_metallic_roughness().base_color_texture() else {
            continue;
        };
        let name = material.name.clone();
        if info.tex_coord() != 0 {
            warnings.push(format!(
                "material '{name}': base colour texture uses TEXCOORD_{}, only TEXCOORD_0 is supported; texture ignored",
                info.tex_coord()
            ));
            continue;
        }
        let texture = info.texture();
        let sampler = texture.sampler();
        use gltf::texture::WrappingMode::Repeat;
        if sampler.wrap_s() != Repeat || sampler.wrap_t() != Repeat {
            warnings.push(format!(
                "material '{name}': texture {} asks for {:?}/{:?} wrapping; sampled with repeat wrapping",
                texture.index(),
                sampler.wrap_s(),
                sampler.wrap_t()
            ));
        }
        // glTF leaves an absent magFilter to the renderer: bilinear. Without mipmaps the
        // minFilter's choice between texels is the magFilter's, so that one decides.
        let nearest = sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest);
        let image = texture.source();
        let key = (image.index(), nearest);
        let index = match by_image.get(&key) {
            Some(&i) => i,
            // --textures off: the image is not read; one white texel stands in (never uploaded).
            None if !decode => {
                textures.push(Texture::new(format!("image{} (not decoded)", image.index()), 1, 1, vec![255; 4], nearest));
                by_image.insert(key, textures.len() - 1);
                textures.len() - 1
            }
            None => {
                // Decoded and held once per image: a second sampling of it names the texture
                // holding its texels (which the upload shares).
                let decoded = match by_image.iter().find(|((i, _), _)| *i == image.index()) {
                    Some((_, &t)) => {
                        let held = textures[t].texels_of.unwrap_or(t);
                        let h: &Texture = &textures[held];
                        Texture { name: h.name.clone(), width: h.width, height: h.height, rgba8: Vec::new(), nearest, texels_of: Some(held) }
                    }
                    None => Texture {
                        nearest,
                        ..decode_image(encoded.remove(&image.index()).expect("read_texture_images reads every image decoded here")).with_context(|| {
                            format!("material '{name}': base colour texture image {}", image.index())
                        })?
                    },
                };
                textures.push(decoded);
                by_image.insert(key, textures.len() - 1);
                textures.len() - 1
            }
        };
        material.base_color_texture = Some(index);
    }
    Ok(textures)
}

/// Most texels of all textures together: all of them are one storage buffer binding of 4 bytes a
/// texel, and no device's maxStorageBufferRange (a u32) reaches 2^32 bytes.
const MAX_TOTAL_TEXELS: u64 = (u32::MAX / 4) as u64;

/// An image read but not yet decoded: its name, its bytes and its size from its header.
struct EncodedImage {
    name: String,
    bytes: Vec<u8>,
    width: u32,
    height: u32,
}

/// Reads every image a used material samples (once each; [`load_textures`] decodes them) and
/// refuses, before any is decoded, textures that together hold more than [`MAX_TOTAL_TEXELS`]
/// (from their headers; an image sampled two ways counts once, as it is uploaded once): twelve
/// 8192² images (200 KB files) took 6.4 GB and 10 s to decode before the upload refused them.
fn read_texture_images(
    doc: &Document,
    buffers: &[Vec<u8>],
    base_dir: Option<&Path>,
    used: &std::collections::BTreeSet<usize>,
    device_range: &dyn Fn() -> Option<u64>,
) -> Result<BTreeMap<usize, EncodedImage>> {
    // Each image with the first material that samples it (named in its errors, as load_textures does).
    let mut images: BTreeMap<usize, (gltf::Image, String)> = BTreeMap::new();
    for m in doc.materials().filter(|m| m.index().is_some_and(|i| used.contains(&i))) {
        if let Some(info) = m.pbr_metallic_roughness().base_color_texture().filter(|i| i.tex_coord() == 0) {
            let image = info.texture().source();
            images.entry(image.index()).or_insert((image, material_label(&m)));
        }
    }
    let mut read = BTreeMap::new();
    for (index, (image, material)) in &images {
        let what = || format!("material '{material}': base colour texture image {index}");
        let (name, bytes) = image_bytes(image, buffers, base_dir).with_context(what)?;
        let (width, height) = image_dimensions(&name, &bytes).with_context(what)?;
        read.insert(*index, EncodedImage { name, bytes, width, height });
    }
    let texels = |e: &EncodedImage| u64::from(e.width) * u64::from(e.height);
    let total: u64 = read.values().map(texels).sum();
    let largest = || crate::scene_gpu::largest_textures(read.values().map(|e| (e.name.as_str(), e.width, e.height)));
    if total > MAX_TOTAL_TEXELS {
        bail!(
            "its base colour textures hold {total} texels ({:.1} GiB of RGBA8), more than any device reads through one \
             buffer ({MAX_TOTAL_TEXELS} texels); render with --textures off, or scale down the largest ({})",
            (total * 4) as f64 / (1u64 << 30) as f64,
            largest()
        );
    }
    // The device's own limit, which the upload would apply after decoding them all (on
    // lavapipe, 128 MiB: a scene of 4 GiB of texels took minutes and as many GiB to be refused).
    if total * 4 > MIN_STORAGE_BUFFER_RANGE {
        if let Some(range) = device_range().filter(|&r| total * 4 > r) {
            return Err(crate::scene_gpu::texel_range_refusal("base colour textures", total * 4, range, &largest()));
        }
    }
    Ok(read)
}

/// An image's name (or `image{index}`) and its encoded bytes.
fn image_bytes(image: &gltf::Image, buffers: &[Vec<u8>], base_dir: Option<&Path>) -> Result<(String, Vec<u8>)> {
    let name = image
        .name()
        .map(shown_name)
        .unwrap_or_else(|| format!("image{}", image.index()));
    let (name, bytes) = match image.source() {
        gltf::image::Source::View { view, .. } => (name, view_bytes(&view, buffers)?.to_vec()),
        // The file read is named too: the image's name alone did not say which it was.
        gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
            let shown: String = uri.chars().take(200).collect();
            (format!("{name}' from '{shown}"), read_uri(uri, base_dir, None)?)
        }
        gltf::image::Source::Uri { uri, .. } => (name, read_uri(uri, base_dir, None)?),
    };
    Ok((name, bytes))
}

/// An encoded image's size from its header, within 1..=[`MAX_TEXELS`] texels.
fn image_dimensions(name: &str, bytes: &[u8]) -> Result<(u32, u32)> {
    if bytes.is_empty() {
        bail!("'{name}': empty (0 bytes)");
    }
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| anyhow!("'{name}': {e}"))?;
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| anyhow!("'{name}': cannot decode (PNG and JPEG are supported): {e}"))?;
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_TEXELS {
        bail!("'{name}': {w}x{h} texels is outside 1..={MAX_TEXELS}");
    }
    Ok((w, h))
}

/// Decodes an image [`read_texture_images`] read.
fn decode_image(image: EncodedImage) -> Result<Texture> {
    let EncodedImage { name, bytes, width: w, height: h } = image;
    let decoded = image::load_from_memory(&bytes)
        .map_err(|e| anyhow!("'{name}': cannot decode (PNG and JPEG are supported): {e}"))?
        .to_rgba8();
    Ok(Texture::new(name, w, h, decoded.into_raw(), false))
}

/// The triangle list of a strip or fan over the vertices `v` (glTF 2.0, 3.7.2.1: strip triangle i
/// is v_i, v_{i+1+i%2}, v_{i+2-i%2}, so every triangle keeps the strip's winding; fan triangle i is
/// v_{i+1}, v_{i+2}, v_0).
fn strip_or_fan_to_list(mode: Mode, v: &[u32]) -> Vec<u32> {
    let triangles = v.len().saturating_sub(2);
    let mut out = Vec::with_capacity(3 * triangles);
    for i in 0..triangles {
        match mode {
            Mode::TriangleStrip => out.extend([v[i], v[i + 1 + i % 2], v[i + 2 - i % 2]]),
            _ => out.extend([v[i + 1], v[i + 2], v[0]]),
        }
    }
    out
}

/// Concatenates all primitives of `mesh` into one [`Mesh`].
fn load_mesh(
    mesh: &gltf::Mesh,
    buffers: &[Vec<u8>],
    materials: &[Material],
    default_material: u32,
    uses_default: &mut bool,
    warnings: &mut Vec<String>,
) -> Result<Mesh> {
    let name = mesh
        .name()
        .map(shown_name)
        .unwrap_or_else(|| format!("mesh{}", mesh.index()));
    let mut out = Mesh {
        name: name.clone(),
        ..Mesh::default()
    };

    for (pi, prim) in mesh.primitives().enumerate() {
        let what = format!("mesh '{name}' primitive {pi}");
        if !triangle_mode(prim.mode()) {
            // Lines and points (an exporter's loose edges, a CAD file's outlines) have no surface.
            warnings.push(format!("{what}: mode {:?} has no surface to render; skipped", prim.mode()));
            continue;
        }
        let pos_acc = prim
            .get(&Semantic::Positions)
            .ok_or_else(|| anyhow!("{what} has no POSITION attribute"))?;
        let positions =
            read_vec3(&pos_acc, buffers).with_context(|| format!("{what}: POSITION"))?;
        let n = positions.len();
        // Each attribute's count against POSITION's before it is read (check_geometry_size
        // budgets POSITION only; a mismatched one was read whole first).
        for (semantic, label) in [(Semantic::Normals, "NORMAL"), (Semantic::TexCoords(0), "TEXCOORD_0"), (Semantic::Colors(0), "COLOR_0")] {
            if let Some(acc) = prim.get(&semantic) {
                if acc.count() != n {
                    bail!("{what}: {label} has {} elements but POSITION has {n}", acc.count());
                }
            }
        }

        let normals = match prim.get(&Semantic::Normals) {
            Some(acc)
                if (acc.data_type(), acc.dimensions()) == (DataType::F32, Dimensions::Vec3) =>
            {
                read_vec3(&acc, buffers).with_context(|| format!("{what}: NORMAL"))?
            }
            Some(acc) => {
                warnings.push(format!(
                    "{what}: NORMAL of type {:?} {:?} not supported, ignored",
                    acc.data_type(),
                    acc.dimensions()
                ));
                vec![Vec3::ZERO; n]
            }
            None => vec![Vec3::ZERO; n],
        };
        // A non-finite normal would reach the shading normal as NaN (an infinite one survives the
        // shader's zero-length test): it becomes zero, which the shader treats as no normal.
        let normals = replace_non_finite(normals, Vec3::ZERO, |v| v.is_finite(), &what, "NORMAL", "zero (no shading normal)", warnings);
        // Vertex colours multiply the base colour in glTF; they are not read.
        if let Some(acc) = prim.get(&Semantic::Colors(0)) {
            if let Some(colors) = read_colors(&acc, buffers).with_context(|| format!("{what}: COLOR_0"))? {
                let tinted = colors.iter().filter(|c| (**c - Vec3::ONE).abs().max_element() > 0.5 / 255.0).count();
                if tinted > 0 {
                    warnings.push(format!(
                        "{what}: COLOR_0 (vertex colours, {tinted} of {} not white) is not supported; the base colour is used without it",
                        colors.len()
                    ));
                }
            }
        }

        let uvs = match prim.get(&Semantic::TexCoords(0)) {
            Some(acc) => {
                match read_vec2(&acc, buffers).with_context(|| format!("{what}: TEXCOORD_0"))? {
                    Some(uvs) => uvs,
                    None => {
                        warnings.push(format!(
                            "{what}: TEXCOORD_0 of type {:?} {:?}{} not supported, ignored",
                            acc.data_type(),
                            acc.dimensions(),
                            if acc.data_type() == DataType::F32 || acc.normalized() { "" } else { " (not normalized)" }
                        ));
                        vec![Vec2::ZERO; n]
                    }
                }
            }
            None => {
                // As for the other texture features the renderer lacks: a warning, not an error.
                if let Some(m) = prim.material().index().and_then(|i| materials.get(i)) {
                    if m.base_color_texture.is_some() {
                        warnings.push(format!(
                            "{what}: material '{}' has a base colour texture but the primitive has no TEXCOORD_0; \
                             the texture is sampled at uv (0, 0)",
                            m.name
                        ));
                    }
                }
                vec![Vec2::ZERO; n]
            }
        };
        let uvs = replace_non_finite(uvs, Vec2::ZERO, |v| v.is_finite(), &what, "TEXCOORD_0", "(0, 0)", warnings);

        let listed = match prim.indices() {
            Some(acc) => {
                let indices =
                    read_indices(&acc, buffers).with_context(|| format!("{what}: indices"))?;
                if let Some((k, &i)) = indices.iter().enumerate().find(|(_, &i)| i as usize >= n) {
                    bail!("{what}: index {i} at position {k} is out of range ({n} vertices)");
                }
                indices
            }
            None => (0..n as u32).collect(),
        };
        let indices = match prim.mode() {
            Mode::TriangleStrip | Mode::TriangleFan => strip_or_fan_to_list(prim.mode(), &listed),
            _ if listed.len() % 3 != 0 => match prim.indices() {
                Some(_) => bail!("{what}: index count {} is not a multiple of 3", listed.len()),
                None => bail!("{what} is not indexed and its vertex count {n} is not a multiple of 3"),
            },
            _ => listed,
        };

        // A triangle with a non-finite vertex is dropped: in an acceleration structure its NaN
        // bounds took the whole BLAS with them (one such triangle anywhere blacked out the scene
        // once merged into one BLAS). Its vertices move onto a finite one of the primitive so that
        // no bound or scale computed over the vertices sees them.
        let (indices, positions) = drop_non_finite_triangles(indices, positions, &what, warnings);

        let material = match prim.material().index() {
            Some(i) => i as u32,
            None => {
                *uses_default = true;
                default_material
            }
        };

        let base = out.positions.len();
        if base + n > u32::MAX as usize {
            bail!("{what}: mesh has more than 2^32 vertices");
        }
        let base = base as u32;
        out.indices.extend(indices.iter().map(|&i| i + base));
        out.triangle_materials
            .extend(std::iter::repeat_n(material, indices.len() / 3));
        out.positions.extend(positions);
        out.normals.extend(normals);
        out.uvs.extend(uvs);
    }
    Ok(out)
}

/// `indices` without the triangles that use a non-finite position, `positions` with every
/// non-finite one replaced by the primitive's first finite one (or zero), and a warning saying how
/// many triangles went.
fn drop_non_finite_triangles(indices: Vec<u32>, mut positions: Vec<Vec3>, what: &str, warnings: &mut Vec<String>) -> (Vec<u32>, Vec<Vec3>) {
    if positions.iter().all(|p| p.is_finite()) {
        return (indices, positions);
    }
    let triangles = indices.len() / 3;
    let kept: Vec<u32> = indices
        .chunks_exact(3)
        .filter(|t| t.iter().all(|&i| positions[i as usize].is_finite()))
        .flatten()
        .copied()
        .collect();
    let dropped = triangles - kept.len() / 3;
    let finite = positions.iter().copied().find(|p| p.is_finite()).unwrap_or(Vec3::ZERO);
    let bad = positions.iter().filter(|p| !p.is_finite()).count();
    for p in positions.iter_mut().filter(|p| !p.is_finite()) {
        *p = finite;
    }
    warnings.push(format!(
        "{what}: {bad} non-finite vertex position{} (NaN or infinite): {dropped} of its {triangles} triangle{} dropped",
        if bad == 1 { "" } else { "s" },
        if triangles == 1 { "" } else { "s" }
    ));
    (kept, positions)
}

/// `values` with every element that fails `finite` replaced by `with`, and a warning naming the
/// attribute and how many were replaced.
fn replace_non_finite<T: Copy>(
    mut values: Vec<T>,
    with: T,
    finite: impl Fn(&T) -> bool,
    what: &str,
    attribute: &str,
    shown: &str,
    warnings: &mut Vec<String>,
) -> Vec<T> {
    let bad = values.iter().filter(|v| !finite(v)).count();
    if bad > 0 {
        warnings.push(format!("{what}: {bad} of {} {attribute} values are not finite; replaced by {shown}", values.len()));
        for v in values.iter_mut().filter(|v| !finite(v)) {
            *v = with;
        }
    }
    values
}

fn read_vec3(acc: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Vec<Vec3>> {
    if (acc.data_type(), acc.dimensions()) != (DataType::F32, Dimensions::Vec3) {
        bail!(
            "accessor {} must be FLOAT VEC3, found {:?} {:?}",
            acc.index(),
            acc.data_type(),
            acc.dimensions()
        );
    }
    let bytes = accessor_bytes(acc, buffers)?;
    Ok(bytes
        .chunks_exact(12)
        .map(|c| Vec3::new(f32_at(c, 0), f32_at(c, 4), f32_at(c, 8)))
        .collect())
}

/// Texture coordinates (float, or normalised unsigned byte/short); `None` for other types.
/// Float, or unsigned integers read as normalised: glTF 2.0's texture coordinates and colours
/// (integers that are not `normalized` need KHR_mesh_quantization, which is not supported).
fn read_vec2(acc: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Option<Vec<Vec2>>> {
    if acc.dimensions() != Dimensions::Vec2 || (acc.data_type() != DataType::F32 && !acc.normalized()) {
        return Ok(None);
    }
    let decode: fn(&[u8]) -> Vec2 = match acc.data_type() {
        DataType::F32 => |c| Vec2::new(f32_at(c, 0), f32_at(c, 4)),
        DataType::U16 => |c| {
            Vec2::new(
                f32::from(u16::from_le_bytes([c[0], c[1]])),
                f32::from(u16::from_le_bytes([c[2], c[3]])),
            ) / 65535.0
        },
        DataType::U8 => |c| Vec2::new(f32::from(c[0]), f32::from(c[1])) / 255.0,
        _ => return Ok(None),
    };
    let size = acc.size();
    let bytes = accessor_bytes(acc, buffers)?;
    Ok(Some(bytes.chunks_exact(size).map(decode).collect()))
}

/// A COLOR_0 accessor's RGB (alpha dropped): VEC3 or VEC4 of float or normalised u8 / u16; None
/// for other types.
fn read_colors(acc: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Option<Vec<Vec3>>> {
    if !matches!(acc.dimensions(), Dimensions::Vec3 | Dimensions::Vec4) || (acc.data_type() != DataType::F32 && !acc.normalized()) {
        return Ok(None);
    }
    let decode: fn(&[u8]) -> Vec3 = match acc.data_type() {
        DataType::F32 => |c| Vec3::new(f32_at(c, 0), f32_at(c, 4), f32_at(c, 8)),
        DataType::U16 => |c| {
            let u = |i: usize| f32::from(u16::from_le_bytes([c[2 * i], c[2 * i + 1]])) / 65535.0;
            Vec3::new(u(0), u(1), u(2))
        },
        DataType::U8 => |c| Vec3::new(f32::from(c[0]), f32::from(c[1]), f32::from(c[2])) / 255.0,
        _ => return Ok(None),
    };
    let bytes = accessor_bytes(acc, buffers)?;
    Ok(Some(bytes.chunks_exact(acc.size()).map(decode).collect()))
}

fn read_indices(acc: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u32>> {
    let ok = acc.dimensions() == Dimensions::Scalar
        && matches!(
            acc.data_type(),
            DataType::U8 | DataType::U16 | DataType::U32
        );
    if !ok {
        bail!(
            "index accessor {} must be an unsigned integer SCALAR, found {:?} {:?}",
            acc.index(),
            acc.data_type(),
            acc.dimensions()
        );
    }
    let size = acc.size();
    let bytes = accessor_bytes(acc, buffers)?;
    Ok(bytes
        .chunks_exact(size)
        .map(|c| match c {
            [a] => u32::from(*a),
            [a, b] => u32::from(u16::from_le_bytes([*a, *b])),
            [a, b, c, d] => u32::from_le_bytes([*a, *b, *c, *d]),
            _ => 0, // unreachable: size is 1, 2 or 4
        })
        .collect())
}

fn f32_at(c: &[u8], offset: usize) -> f32 {
    f32::from_le_bytes([c[offset], c[offset + 1], c[offset + 2], c[offset + 3]])
}

/// Bytes of a buffer view, checked against its buffer.
fn view_bytes<'b>(view: &gltf::buffer::View, buffers: &'b [Vec<u8>]) -> Result<&'b [u8]> {
    let buffer = view.buffer().index();
    let data = buffers.get(buffer).ok_or_else(|| {
        anyhow!(
            "buffer view {} refers to missing buffer {buffer}",
            view.index()
        )
    })?;
    let start = view.offset();
    view.offset()
        .checked_add(view.length())
        .and_then(|end| data.get(start..end))
        .ok_or_else(|| {
            anyhow!(
                "buffer view {} (offset {start}, length {}) exceeds buffer {buffer} ({} bytes)",
                view.index(),
                view.length(),
                data.len()
            )
        })
}

/// The accessor's elements, tightly packed (`count * size` bytes), with sparse
/// substitution applied. All offsets are bounds-checked.
fn accessor_bytes(acc: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u8>> {
    let id = acc.index();
    let size = acc.size();
    let count = acc.count();
    if count == 0 {
        bail!("accessor {id} is empty");
    }
    let total = count
        .checked_mul(size)
        .ok_or_else(|| anyhow!("accessor {id} is too large"))?;

    let mut out = match acc.view() {
        Some(view) => {
            let src = view_bytes(&view, buffers)?;
            let stride = view.stride().unwrap_or(size);
            if stride < size {
                bail!(
                    "accessor {id}: byte stride {stride} is smaller than the element size {size}"
                );
            }
            let start = acc.offset();
            let end = stride
                .checked_mul(count - 1)
                .and_then(|x| x.checked_add(start))
                .and_then(|x| x.checked_add(size));
            match end {
                Some(end) if end <= src.len() => {}
                _ => bail!(
                    "accessor {id} ({count} elements of {size} bytes, offset {start}, stride {stride}) \
                     exceeds buffer view {} ({} bytes)",
                    view.index(),
                    src.len()
                ),
            }
            let mut out = Vec::with_capacity(total);
            for i in 0..count {
                let o = start + i * stride;
                out.extend_from_slice(&src[o..o + size]);
            }
            out
        }
        None => {
            if total > MAX_VIEWLESS_ACCESSOR_BYTES {
                bail!("accessor {id} without buffer view is too large ({total} bytes)");
            }
            vec![0; total]
        }
    };

    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        let indices = sparse.indices();
        let index_size = indices.index_type().size();
        let values = sparse.values();
        let range = |view: &gltf::buffer::View, offset: usize, len: Option<usize>| {
            let src = view_bytes(view, buffers)?;
            len.and_then(|len| offset.checked_add(len))
                .and_then(|end| src.get(offset..end))
                .ok_or_else(|| {
                    anyhow!(
                        "accessor {id}: sparse data exceeds buffer view {}",
                        view.index()
                    )
                })
        };
        let index_bytes = range(&indices.view(), indices.offset(), n.checked_mul(index_size))?;
        let value_bytes = range(&values.view(), values.offset(), n.checked_mul(size))?;
        for (k, raw) in index_bytes.chunks_exact(index_size).enumerate() {
            let i = match raw {
                [a] => usize::from(*a),
                [a, b] => usize::from(u16::from_le_bytes([*a, *b])),
                [a, b, c, d] => u32::from_le_bytes([*a, *b, *c, *d]) as usize,
                _ => bail!("accessor {id}: invalid sparse index size"),
            };
            if i >= count {
                bail!("accessor {id}: sparse index {i} out of range ({count} elements)");
            }
            out[i * size..(i + 1) * size].copy_from_slice(&value_bytes[k * size..(k + 1) * size]);
        }
    }
    Ok(out)
}
