//! A small glTF 2.0 writer for tests and scene generators.
//!
//! Produces pretty-printed JSON with a single embedded base64 buffer, indexed `u32`
//! triangle meshes (POSITION with min/max, optional NORMAL and TEXCOORD_0),
//! diffuse/emissive materials (optionally with an embedded PNG base colour texture),
//! a perspective camera and `KHR_lights_punctual` point lights. Output is deterministic:
//! the same calls give byte-identical text.

use crate::scene::base64;
use glam::{Mat3, Quat, Vec3};
use serde_json::{json, Map, Value};

const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const LINEAR: u32 = 9729;
const REPEAT: u32 = 10497;
const EMISSIVE_STRENGTH: &str = "KHR_materials_emissive_strength";
const LIGHTS_PUNCTUAL: &str = "KHR_lights_punctual";

/// Incrementally builds a glTF document; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct GltfBuilder {
    buffer: Vec<u8>,
    buffer_views: Vec<Value>,
    accessors: Vec<Value>,
    materials: Vec<Value>,
    meshes: Vec<Value>,
    cameras: Vec<Value>,
    lights: Vec<Value>,
    images: Vec<Value>,
    samplers: Vec<Value>,
    textures: Vec<Value>,
    nodes: Vec<Node>,
    uses_emissive_strength: bool,
}

#[derive(Clone, Debug, Default)]
struct Node {
    name: String,
    mesh: Option<usize>,
    camera: Option<usize>,
    light: Option<usize>,
    translation: Option<[f32; 3]>,
    rotation: Option<[f32; 4]>,
    matrix: Option<[f32; 16]>,
    children: Vec<usize>,
}

impl GltfBuilder {
    /// An empty document.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a diffuse material and returns its index. Emission above 1 in any channel is
    /// written as `emissiveFactor` normalised to a maximum of 1 plus
    /// `KHR_materials_emissive_strength` = that maximum.
    pub fn material(
        &mut self,
        name: &str,
        base_color: [f32; 3],
        emission: [f32; 3],
        double_sided: bool,
    ) -> usize {
        let mut m = Map::new();
        m.insert("name".into(), json!(name));
        m.insert(
            "pbrMetallicRoughness".into(),
            json!({
                "baseColorFactor": floats(&[base_color[0], base_color[1], base_color[2], 1.0]),
                "metallicFactor": 0,
                "roughnessFactor": 1,
            }),
        );
        let max = emission.iter().copied().fold(0.0f32, f32::max);
        if max > 1.0 {
            m.insert("emissiveFactor".into(), floats(&emission.map(|e| e / max)));
            m.insert(
                "extensions".into(),
                json!({ EMISSIVE_STRENGTH: { "emissiveStrength": num(max) } }),
            );
            self.uses_emissive_strength = true;
        } else if max > 0.0 {
            m.insert("emissiveFactor".into(), floats(&emission));
        }
        if double_sided {
            m.insert("doubleSided".into(), json!(true));
        }
        self.materials.push(Value::Object(m));
        self.materials.len() - 1
    }

    /// Adds a material whose base colour is `base_color_factor` times the texture
    /// `texture` (an index returned by [`GltfBuilder::texture_png`], read with `TEXCOORD_0`);
    /// not emissive. Returns the material index.
    pub fn textured_material(
        &mut self,
        name: &str,
        base_color_factor: [f32; 3],
        texture: usize,
        double_sided: bool,
    ) -> usize {
        let index = self.material(name, base_color_factor, [0.0; 3], double_sided);
        if let Some(Value::Object(pbr)) = self.materials[index].get_mut("pbrMetallicRoughness") {
            pbr.insert(
                "baseColorTexture".into(),
                json!({ "index": texture, "texCoord": 0 }),
            );
        }
        index
    }

    /// Encodes `rgba8` (row-major, `width * height * 4` bytes, sRGB as glTF expects; row 0
    /// is the top of the image, v = 0) as a PNG embedded in the buffer and adds an image,
    /// the shared sampler (repeat wrapping, linear filtering; created on first use) and a
    /// texture. Returns the texture index.
    ///
    /// # Panics
    /// If `rgba8` does not hold exactly `width * height * 4` bytes.
    pub fn texture_png(&mut self, name: &str, width: u32, height: u32, rgba8: &[u8]) -> usize {
        assert_eq!(
            rgba8.len(),
            width as usize * height as usize * 4,
            "texture '{name}': RGBA8 data does not match {width}x{height}"
        );
        let png = crate::output::encode_png(width, height, rgba8)
            .unwrap_or_else(|e| panic!("texture '{name}': PNG encoding failed: {e}"));
        let view = self.push_view(&png, None);
        // Keep the buffer 4-byte aligned after the image for the accessors that follow.
        self.pad_buffer();
        self.images.push(json!({
            "name": name,
            "bufferView": view,
            "mimeType": "image/png",
        }));
        if self.samplers.is_empty() {
            self.samplers.push(json!({
                "magFilter": LINEAR,
                "minFilter": LINEAR,
                "wrapS": REPEAT,
                "wrapT": REPEAT,
            }));
        }
        self.textures.push(json!({
            "name": name,
            "sampler": 0,
            "source": self.images.len() - 1,
        }));
        self.textures.len() - 1
    }

    /// Adds a single-primitive indexed triangle mesh and returns its index.
    /// `normals`, when given, must have one entry per position.
    pub fn mesh(
        &mut self,
        name: &str,
        positions: &[[f32; 3]],
        normals: Option<&[[f32; 3]]>,
        indices: &[u32],
        material: usize,
    ) -> usize {
        self.mesh_impl(name, positions, normals, None, indices, material)
    }

    /// Like [`GltfBuilder::mesh`], with `TEXCOORD_0` texture coordinates (one per position).
    pub fn mesh_with_uvs(
        &mut self,
        name: &str,
        positions: &[[f32; 3]],
        normals: Option<&[[f32; 3]]>,
        uvs: &[[f32; 2]],
        indices: &[u32],
        material: usize,
    ) -> usize {
        self.mesh_impl(name, positions, normals, Some(uvs), indices, material)
    }

    fn mesh_impl(
        &mut self,
        name: &str,
        positions: &[[f32; 3]],
        normals: Option<&[[f32; 3]]>,
        uvs: Option<&[[f32; 2]]>,
        indices: &[u32],
        material: usize,
    ) -> usize {
        let (lo, hi) = positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(Vec3::from(p)), hi.max(Vec3::from(p))),
        );
        let position = self.vec3_accessor(positions, Some((lo.to_array(), hi.to_array())));
        let mut attributes = Map::new();
        attributes.insert("POSITION".into(), json!(position));
        if let Some(normals) = normals {
            attributes.insert("NORMAL".into(), json!(self.vec3_accessor(normals, None)));
        }
        if let Some(uvs) = uvs {
            let bytes: Vec<u8> = uvs.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
            let view = self.push_view(&bytes, Some(ARRAY_BUFFER));
            let accessor = self.push_accessor(json!({
                "bufferView": view,
                "componentType": FLOAT,
                "count": uvs.len(),
                "type": "VEC2",
            }));
            attributes.insert("TEXCOORD_0".into(), json!(accessor));
        }
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.push_view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        let index_accessor = self.push_accessor(json!({
            "bufferView": view,
            "componentType": UNSIGNED_INT,
            "count": indices.len(),
            "type": "SCALAR",
        }));
        self.meshes.push(json!({
            "name": name,
            "primitives": [{
                "attributes": attributes,
                "indices": index_accessor,
                "material": material,
            }],
        }));
        self.meshes.len() - 1
    }

    /// Adds a mesh made of quads, each split into triangles (0,1,2), (0,2,3); the front
    /// face is the counter-clockwise side as given.
    pub fn quads(&mut self, name: &str, quads: &[[[f32; 3]; 4]], material: usize) -> usize {
        let positions: Vec<[f32; 3]> = quads.iter().flatten().copied().collect();
        let indices: Vec<u32> = (0..quads.len() as u32)
            .flat_map(|q| [0, 1, 2, 0, 2, 3].map(|i| 4 * q + i))
            .collect();
        self.mesh(name, &positions, None, &indices, material)
    }

    /// Adds a one-quad mesh (two triangles (0,1,2), (0,2,3), CCW as given).
    pub fn quad(&mut self, name: &str, corners: [[f32; 3]; 4], material: usize) -> usize {
        self.quads(name, &[corners], material)
    }

    /// Adds a root node instancing `mesh` at `translation`; returns the node index.
    pub fn node(&mut self, name: &str, mesh: usize, translation: [f32; 3]) -> usize {
        self.push_node(Node {
            name: name.into(),
            mesh: Some(mesh),
            translation: (translation != [0.0; 3]).then_some(translation),
            ..Node::default()
        })
    }

    /// Adds a root node instancing `mesh` with a column-major 4x4 `matrix`.
    pub fn node_matrix(&mut self, name: &str, mesh: usize, matrix: [f32; 16]) -> usize {
        self.push_node(Node {
            name: name.into(),
            mesh: Some(mesh),
            matrix: Some(matrix),
            ..Node::default()
        })
    }

    /// Adds a node without a mesh (a transform group) with a column-major `matrix`.
    pub fn group(&mut self, name: &str, matrix: [f32; 16]) -> usize {
        self.push_node(Node {
            name: name.into(),
            matrix: Some(matrix),
            ..Node::default()
        })
    }

    /// Makes node `child` a child of node `parent` (it is then no longer a scene root).
    /// Out-of-range indices are ignored.
    pub fn add_child(&mut self, parent: usize, child: usize) {
        if child < self.nodes.len() {
            if let Some(p) = self.nodes.get_mut(parent) {
                p.children.push(child);
            }
        }
    }

    /// Adds a perspective camera node at `eye` whose local -Z points at `target`
    /// and whose local +Y is as close to `up` as possible.
    pub fn camera(
        &mut self,
        name: &str,
        eye: [f32; 3],
        target: [f32; 3],
        up: [f32; 3],
        yfov_radians: f32,
    ) {
        let forward = (Vec3::from(target) - Vec3::from(eye)).normalize();
        let right = forward.cross(Vec3::from(up)).normalize();
        let true_up = right.cross(forward);
        let mut q = Quat::from_mat3(&Mat3::from_cols(right, true_up, -forward)).normalize();
        if q.w < 0.0 {
            q = -q;
        }
        self.cameras.push(json!({
            "name": name,
            "type": "perspective",
            "perspective": { "yfov": num(yfov_radians), "znear": 0.01 },
        }));
        let camera = self.cameras.len() - 1;
        self.push_node(Node {
            name: name.into(),
            camera: Some(camera),
            translation: Some(eye),
            rotation: Some(q.to_array()),
            ..Node::default()
        });
    }

    /// Adds a `KHR_lights_punctual` point light (intensity in candela) and its node.
    pub fn point_light(&mut self, name: &str, position: [f32; 3], color: [f32; 3], intensity: f32) {
        self.lights.push(json!({
            "name": name,
            "type": "point",
            "color": floats(&color),
            "intensity": num(intensity),
        }));
        let light = self.lights.len() - 1;
        self.push_node(Node {
            name: name.into(),
            light: Some(light),
            translation: Some(position),
            ..Node::default()
        });
    }

    /// The document as pretty-printed JSON (keys sorted, trailing newline).
    pub fn to_json_string(&self) -> String {
        let mut is_child = vec![false; self.nodes.len()];
        for node in &self.nodes {
            for &c in &node.children {
                is_child[c] = true;
            }
        }
        let roots: Vec<usize> = (0..self.nodes.len()).filter(|&i| !is_child[i]).collect();

        let mut root = Map::new();
        root.insert(
            "asset".into(),
            json!({ "version": "2.0", "generator": "restir-vpl scene builder" }),
        );
        let mut used = Vec::new();
        if self.uses_emissive_strength {
            used.push(EMISSIVE_STRENGTH);
        }
        if !self.lights.is_empty() {
            used.push(LIGHTS_PUNCTUAL);
            root.insert(
                "extensions".into(),
                json!({ LIGHTS_PUNCTUAL: { "lights": self.lights } }),
            );
        }
        if !used.is_empty() {
            root.insert("extensionsUsed".into(), json!(used));
        }
        root.insert("scene".into(), json!(0));
        root.insert("scenes".into(), json!([{ "nodes": roots }]));
        let nodes: Vec<Value> = self.nodes.iter().map(Node::to_json).collect();
        let buffers = if self.buffer.is_empty() {
            Vec::new()
        } else {
            vec![json!({
                "byteLength": self.buffer.len(),
                "uri": format!("data:application/octet-stream;base64,{}", base64::encode(&self.buffer)),
            })]
        };
        for (key, list) in [
            ("nodes", &nodes),
            ("meshes", &self.meshes),
            ("materials", &self.materials),
            ("cameras", &self.cameras),
            ("textures", &self.textures),
            ("images", &self.images),
            ("samplers", &self.samplers),
            ("accessors", &self.accessors),
            ("bufferViews", &self.buffer_views),
            ("buffers", &buffers),
        ] {
            if !list.is_empty() {
                root.insert(key.into(), Value::Array(list.clone()));
            }
        }
        let text = serde_json::to_string_pretty(&sorted(Value::Object(root)))
            .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
        text + "\n"
    }

    fn push_node(&mut self, node: Node) -> usize {
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    /// Appends `bytes` (4-byte aligned) to the buffer as a new buffer view; `target` is
    /// omitted for non-vertex data (images).
    fn push_view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.pad_buffer();
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.buffer.len(),
            "byteLength": bytes.len(),
        });
        if let (Some(target), Value::Object(map)) = (target, &mut view) {
            map.insert("target".into(), json!(target));
        }
        self.buffer_views.push(view);
        self.buffer.extend_from_slice(bytes);
        self.buffer_views.len() - 1
    }

    /// Pads the buffer with zeros to a multiple of 4 bytes.
    fn pad_buffer(&mut self) {
        while !self.buffer.len().is_multiple_of(4) {
            self.buffer.push(0);
        }
    }

    fn push_accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn vec3_accessor(&mut self, data: &[[f32; 3]], bounds: Option<([f32; 3], [f32; 3])>) -> usize {
        let bytes: Vec<u8> = data
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        let view = self.push_view(&bytes, Some(ARRAY_BUFFER));
        let mut a = json!({
            "bufferView": view,
            "componentType": FLOAT,
            "count": data.len(),
            "type": "VEC3",
        });
        if let (Some((lo, hi)), Value::Object(map)) = (bounds, &mut a) {
            if !data.is_empty() {
                map.insert("min".into(), floats(&lo));
                map.insert("max".into(), floats(&hi));
            }
        }
        self.push_accessor(a)
    }
}

impl Node {
    fn to_json(&self) -> Value {
        let mut n = Map::new();
        n.insert("name".into(), json!(self.name));
        if let Some(mesh) = self.mesh {
            n.insert("mesh".into(), json!(mesh));
        }
        if let Some(camera) = self.camera {
            n.insert("camera".into(), json!(camera));
        }
        if let Some(light) = self.light {
            n.insert(
                "extensions".into(),
                json!({ LIGHTS_PUNCTUAL: { "light": light } }),
            );
        }
        if let Some(t) = self.translation {
            n.insert("translation".into(), floats(&t));
        }
        if let Some(r) = self.rotation {
            n.insert("rotation".into(), floats(&r));
        }
        if let Some(m) = self.matrix {
            n.insert("matrix".into(), floats(&m));
        }
        if !self.children.is_empty() {
            n.insert("children".into(), json!(self.children));
        }
        Value::Object(n)
    }
}

/// Adds an axis-aligned box of 6 quads (12 triangles) as one mesh and returns the mesh
/// index. With `facing_inward` the CCW front faces point into the box, else outward.
pub fn closed_box(
    builder: &mut GltfBuilder,
    name: &str,
    min: [f32; 3],
    max: [f32; 3],
    material: usize,
    facing_inward: bool,
) -> usize {
    let (lo, hi) = (Vec3::from(min), Vec3::from(max));
    let mut quads = Vec::with_capacity(6);
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for (side, outward) in [(lo, -1.0f32), (hi, 1.0)] {
            let corner = |a: f32, b: f32| {
                let mut p = [0.0; 3];
                p[axis] = side[axis];
                p[u] = if a > 0.0 { hi[u] } else { lo[u] };
                p[v] = if b > 0.0 { hi[v] } else { lo[v] };
                p
            };
            let face = [
                corner(0.0, 0.0),
                corner(1.0, 0.0),
                corner(1.0, 1.0),
                corner(0.0, 1.0),
            ];
            let mut dir = [0.0; 3];
            dir[axis] = if facing_inward { -outward } else { outward };
            quads.push(orient_quad(face, dir));
        }
    }
    builder.quads(name, &quads, material)
}

/// Returns the quad with its vertex order chosen so that its CCW front face points along
/// `direction` (reversed if the normal as given points away from it).
pub fn orient_quad(corners: [[f32; 3]; 4], direction: [f32; 3]) -> [[f32; 3]; 4] {
    let [p0, p1, p2, p3] = corners.map(Vec3::from);
    let normal = (p2 - p0).cross(p3 - p1);
    if normal.dot(Vec3::from(direction)) < 0.0 {
        [corners[0], corners[3], corners[2], corners[1]]
    } else {
        corners
    }
}

/// JSON number with the shortest decimal that round-trips the `f32` (`0.1`, not
/// `0.10000000149011612`); `-0` becomes `0`, non-finite values become `null`.
fn num(x: f32) -> Value {
    let x = if x == 0.0 { 0.0 } else { x };
    x.to_string()
        .parse::<f64>()
        .ok()
        .and_then(serde_json::Number::from_f64)
        .map_or(Value::Null, Value::Number)
}

fn floats(xs: &[f32]) -> Value {
    Value::Array(xs.iter().map(|&x| num(x)).collect())
}

/// Rebuilds objects with sorted keys, so output does not depend on serde_json's
/// `preserve_order` feature.
fn sorted(v: Value) -> Value {
    match v {
        Value::Object(map) => {
            let mut entries: Vec<(String, Value)> = map.into_iter().collect();
            entries.sort_by(|a, b| a.0.cmp(&b.0));
            Value::Object(entries.into_iter().map(|(k, v)| (k, sorted(v))).collect())
        }
        Value::Array(items) => Value::Array(items.into_iter().map(sorted).collect()),
        other => other,
    }
}
