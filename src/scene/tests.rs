//! CPU-only unit tests for the scene loader, builder and built-in scenes.

use super::generate::cornell::{cornell_camera_yfov, LIGHT_EMISSION};
use super::*;
use super::generate::*;
use glam::{Mat4, Vec2, Vec3};
use serde_json::{json, Value};
use std::path::Path;

const EPS: f32 = 1e-5;

fn load_str(text: &str) -> anyhow::Result<Scene> {
    Scene::from_gltf_slice(text.as_bytes(), None, "test.gltf")
}

fn load_value(v: &Value) -> anyhow::Result<Scene> {
    load_str(&v.to_string())
}

/// Error text of a failed load (must not panic).
fn load_err(v: &Value) -> String {
    match load_value(v) {
        Ok(_) => panic!("expected an error"),
        Err(e) => format!("{e:#}"),
    }
}

fn assert_contains(msg: &str, words: &[&str]) {
    for w in words {
        assert!(
            msg.contains(w),
            "error message {msg:?} does not contain {w:?}"
        );
    }
}

/// A one-triangle document (material 0, emissive), parsed to JSON for editing.
fn triangle_doc() -> Value {
    let mut b = GltfBuilder::new();
    let m = b.material("glow", [0.5; 3], [2.0, 1.0, 0.5], false);
    let mesh = b.mesh(
        "tri",
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        None,
        &[0, 1, 2],
        m,
    );
    b.node("tri", mesh, [0.0; 3]);
    serde_json::from_str(&b.to_json_string()).unwrap()
}

fn cornell() -> Scene {
    load_str(&cornell_box_gltf()).expect("cornell box loads")
}

fn instance_named<'a>(scene: &'a Scene, name: &str) -> &'a Instance {
    scene
        .instances
        .iter()
        .find(|i| i.name == name)
        .unwrap_or_else(|| panic!("no instance {name}"))
}

/// World-space centroid of an instance's vertices.
fn instance_centroid(scene: &Scene, inst: &Instance) -> Vec3 {
    let mesh = &scene.meshes[inst.mesh];
    let sum: Vec3 = mesh
        .positions
        .iter()
        .map(|&p| inst.transform.transform_point3(p))
        .sum();
    sum / mesh.positions.len() as f32
}

/// World-space (triangle centroid, unit CCW normal) of every triangle of an instance.
fn triangle_frames(scene: &Scene, inst: &Instance) -> Vec<(Vec3, Vec3)> {
    let mesh = &scene.meshes[inst.mesh];
    (0..mesh.triangle_count())
        .map(|t| {
            let p = mesh
                .triangle(t)
                .unwrap()
                .map(|v| inst.transform.transform_point3(v));
            (
                (p[0] + p[1] + p[2]) / 3.0,
                (p[1] - p[0]).cross(p[2] - p[0]).normalize(),
            )
        })
        .collect()
}

// ---------------------------------------------------------------- Cornell box

/// The committed file at `path` is `generated`. With `UPDATE_SCENES` set a stale file is rewritten
/// and the test fails all the same, so that a run that changed a scene is never reported as a pass:
/// review the diff, then run the tests again without it.
fn assert_committed(path: &Path, generated: &str) {
    let committed = std::fs::read_to_string(path);
    if std::env::var_os("UPDATE_SCENES").is_some() && committed.as_deref().ok() != Some(generated) {
        std::fs::write(path, generated).unwrap();
        panic!("{} rewritten from its generator (UPDATE_SCENES): review the diff, then run the tests without it", path.display());
    }
    let committed = committed.unwrap_or_else(|e| panic!("cannot read {}: {e} (run with UPDATE_SCENES=1)", path.display()));
    assert!(committed == generated, "{} is stale; regenerate with UPDATE_SCENES=1", path.display());
}

#[test]
fn cornell_file_matches_generator() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_box.gltf");
    let generated = cornell_box_gltf();
    assert_committed(&path, &generated);
    assert_eq!(
        generated,
        cornell_box_gltf(),
        "generator is not deterministic"
    );
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.path, path);
}

#[test]
fn cornell_structure() {
    let s = cornell();
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let names: Vec<&str> = s.instances.iter().map(|i| i.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "floor",
            "ceiling",
            "back_wall",
            "left_wall_red",
            "right_wall_green",
            "short_block",
            "tall_block",
            "light"
        ]
    );
    assert_eq!(s.meshes.len(), 8);
    assert_eq!(s.materials.len(), 4);
    assert_eq!(s.triangle_count(), 5 * 2 + 2 * 5 * 2 + 2);
    for m in &s.meshes {
        assert_eq!(m.normals.len(), m.positions.len());
        assert_eq!(m.uvs.len(), m.positions.len());
        assert_eq!(m.triangle_materials.len(), m.triangle_count());
    }
    let (lo, hi) = s.world_bounds();
    assert!(lo.abs_diff_eq(Vec3::ZERO, EPS), "{lo}");
    assert!(
        hi.abs_diff_eq(Vec3::new(0.556, 0.5488, 0.5592), EPS),
        "{hi}"
    );
}

#[test]
fn cornell_camera() {
    let s = cornell();
    let cam = s.camera.as_ref().expect("camera");
    let expected = 2.0 * (0.0125f32 / 0.035).atan();
    assert!((cam.yfov - expected).abs() < 1e-6);
    assert!((cam.yfov - cornell_camera_yfov()).abs() < 1e-6);
    let eye = cam.transform.transform_point3(Vec3::ZERO);
    assert!(eye.abs_diff_eq(Vec3::new(0.278, 0.273, -0.8), EPS), "{eye}");
    let forward = cam.transform.transform_vector3(Vec3::NEG_Z);
    let up = cam.transform.transform_vector3(Vec3::Y);
    assert!(forward.abs_diff_eq(Vec3::Z, EPS), "{forward}");
    assert!(up.abs_diff_eq(Vec3::Y, EPS), "{up}");
}

#[test]
fn cornell_red_left_green_right() {
    let s = cornell();
    let cam = s.camera.as_ref().unwrap();
    let eye = cam.transform.transform_point3(Vec3::ZERO);
    let right = cam.transform.transform_vector3(Vec3::X);
    assert!(
        right.abs_diff_eq(Vec3::NEG_X, EPS),
        "screen-right must be -x, got {right}"
    );
    let red = instance_centroid(&s, instance_named(&s, "left_wall_red"));
    let green = instance_centroid(&s, instance_named(&s, "right_wall_green"));
    assert!(red.x > green.x);
    assert!((red - eye).dot(right) < 0.0, "red wall must be on the left");
    assert!(
        (green - eye).dot(right) > 0.0,
        "green wall must be on the right"
    );
    let red_mat = &s.materials
        [s.meshes[instance_named(&s, "left_wall_red").mesh].triangle_materials[0] as usize];
    let green_mat = &s.materials
        [s.meshes[instance_named(&s, "right_wall_green").mesh].triangle_materials[0] as usize];
    assert_eq!(red_mat.name, "red");
    assert!(red_mat.base_color.x > red_mat.base_color.y);
    assert_eq!(green_mat.name, "green");
    assert!(green_mat.base_color.y > green_mat.base_color.x);
}

#[test]
fn cornell_light() {
    let s = cornell();
    let tris = s.emissive_triangles();
    assert_eq!(tris.len(), 2);
    let le = Vec3::from(LIGHT_EMISSION);
    let mut power = Vec3::ZERO;
    for t in &tris {
        assert!(t.emission.abs_diff_eq(le, 1e-4), "{}", t.emission);
        assert!(t.normal.abs_diff_eq(Vec3::NEG_Y, EPS), "{}", t.normal);
        assert!(!t.double_sided);
        assert_eq!(s.instances[t.instance as usize].name, "light");
        assert!(t.p.iter().all(|p| (p.y - 0.5487).abs() < EPS));
        power += std::f32::consts::PI * t.emission * t.area;
    }
    let expected = std::f32::consts::PI * le * (0.13 * 0.105);
    assert!(
        power.abs_diff_eq(expected, 1e-4 * expected.max_element()),
        "{power} vs {expected}"
    );
}

#[test]
fn cornell_faces_oriented() {
    let s = cornell();
    let interior = Vec3::new(0.278, 0.274, 0.28);
    for name in [
        "floor",
        "ceiling",
        "back_wall",
        "left_wall_red",
        "right_wall_green",
    ] {
        for (c, n) in triangle_frames(&s, instance_named(&s, name)) {
            assert!(
                n.dot(interior - c) > 0.0,
                "{name} faces away from the interior"
            );
        }
    }
    for name in ["short_block", "tall_block"] {
        let inst = instance_named(&s, name);
        let center = instance_centroid(&s, inst);
        for (c, n) in triangle_frames(&s, inst) {
            assert!(n.dot(c - center) > 0.0, "{name} face points inward");
        }
    }
}

#[test]
fn furnace_box() {
    let s = load_str(&furnace_box_gltf(0.5, 2.0, 1.0)).unwrap();
    assert_eq!(s.instances.len(), 1);
    assert_eq!(s.triangle_count(), 12);
    let cam = s.camera.as_ref().unwrap();
    assert!((cam.yfov - 60f32.to_radians()).abs() < 1e-6);
    assert!(cam
        .transform
        .transform_point3(Vec3::ZERO)
        .abs_diff_eq(Vec3::ZERO, EPS));
    assert!(cam
        .transform
        .transform_vector3(Vec3::NEG_Z)
        .abs_diff_eq(Vec3::NEG_Z, EPS));
    let tris = s.emissive_triangles();
    assert_eq!(tris.len(), 12);
    let area: f32 = tris.iter().map(|t| t.area).sum();
    assert!((area - 6.0).abs() < 1e-4);
    for t in &tris {
        assert!(t.double_sided);
        assert!(t.emission.abs_diff_eq(Vec3::splat(2.0), 1e-5));
        let c = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        assert!(t.normal.dot(-c) > 0.0, "furnace faces must face inward");
    }
    assert!(s.materials[0]
        .base_color
        .truncate()
        .abs_diff_eq(Vec3::splat(0.5), EPS));
    let (lo, hi) = s.world_bounds();
    assert!(lo.abs_diff_eq(Vec3::splat(-0.5), EPS) && hi.abs_diff_eq(Vec3::splat(0.5), EPS));
}

// ---------------------------------------------------------------- loader errors

#[test]
fn error_missing_file() {
    let err = format!(
        "{:#}",
        Scene::load(Path::new("/nonexistent/dir/missing.gltf")).unwrap_err()
    );
    assert_contains(&err, &["missing.gltf", "cannot read"]);
}

#[test]
fn error_malformed_json() {
    let err = format!("{:#}", load_str("{ \"asset\": ").unwrap_err());
    assert_contains(&err, &["test.gltf", "malformed glTF"]);
    let err = format!(
        "{:#}",
        Scene::from_gltf_slice(b"", None, "empty.gltf").unwrap_err()
    );
    assert_contains(&err, &["empty.gltf", "the file is empty"]);
    // A UTF-8 byte-order mark before the JSON is ignored, as glTF allows.
    let with_bom = [&b"\xEF\xBB\xBF"[..], serde_json::to_string(&triangle_doc()).unwrap().as_bytes()].concat();
    assert_eq!(Scene::from_gltf_slice(&with_bom, None, "bom.gltf").unwrap().triangle_count(), 1);
    // Another kind of file is named as such, not parsed as broken JSON.
    let err = format!("{:#}", Scene::from_gltf_slice(b"ply\nformat ascii 1.0\n", None, "bunny.ply").unwrap_err());
    assert_contains(&err, &["bunny.ply", "not a glTF file", "PLY", ".gltf", ".glb"]);
    let err = format!("{:#}", Scene::from_gltf_slice(b"v 0 0 0\nf 1 2 3\n", None, "tri.obj").unwrap_err());
    assert_contains(&err, &["tri.obj", "not a glTF file"]);
    // Valid JSON, invalid glTF (dangling mesh index).
    let mut doc = triangle_doc();
    doc["nodes"][0]["mesh"] = json!(7);
    assert_contains(
        &load_err(&doc),
        &["test.gltf", "invalid glTF", "nodes[0].mesh"],
    );
}

/// Lines and points have no surface: skipped with a warning, the file's triangles still load (a
/// loose-edge primitive refused the whole file). Strips and fans become lists with the winding of
/// the list they stand for (glTF 2.0, 3.7.2.1).
#[test]
fn lines_and_points_are_skipped_and_strips_and_fans_become_lists() {
    for (mode, name) in [(0, "Points"), (1, "Lines"), (2, "LineLoop"), (3, "LineStrip")] {
        let mut doc = triangle_doc();
        let tri = doc["meshes"][0]["primitives"][0].clone();
        let mut wire = tri.clone();
        wire["mode"] = json!(mode);
        doc["meshes"][0]["primitives"] = json!([wire, tri]);
        let s = load_value(&doc).unwrap();
        assert_eq!(s.triangle_count(), 1, "{name}");
        assert_contains(&s.warnings.join("\n"), &["mesh 'tri' primitive 0: mode", name, "skipped"]);
        // Alone, nothing is left, and the error says why.
        doc["meshes"][0]["primitives"] = json!([wire]);
        assert_contains(&load_err(&doc), &["no triangles in scene", "skipped"]);
    }
    // A unit quad as a strip (0 1 2 3: triangles 012 and 132) and as a fan (0 1 3 2: 013 and 132),
    // counter-clockwise seen from +z.
    let quad = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
    for (mode, order, expect) in [(5, [0u32, 1, 2, 3], [0u32, 1, 2, 1, 3, 2]), (6, [0, 1, 3, 2], [1, 3, 0, 3, 2, 0])] {
        let mut b = GltfBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3], false);
        let mesh = b.mesh("quad", &quad, None, &order, m);
        b.node("quad", mesh, [0.0; 3]);
        let mut doc: Value = serde_json::from_str(&b.to_json_string()).unwrap();
        doc["meshes"][0]["primitives"][0]["mode"] = json!(mode);
        let s = load_value(&doc).unwrap();
        let mesh = &s.meshes[0];
        assert_eq!(mesh.indices, expect, "mode {mode}");
        for t in mesh.indices.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            assert!((b - a).cross(c - a).z > 0.0, "mode {mode}: triangle {t:?} is wound the other way");
        }
        assert!((s.meshes[0].indices.len() / 3) == 2 && s.warnings.is_empty(), "{:?}", s.warnings);
    }
}

#[test]
fn error_missing_position() {
    let mut doc = triangle_doc();
    doc["meshes"][0]["primitives"][0]["attributes"] = json!({ "NORMAL": 0 });
    assert_contains(
        &load_err(&doc),
        &["test.gltf", "mesh 'tri' primitive 0", "POSITION"],
    );
    doc["meshes"][0]["primitives"][0]["attributes"] = json!({ "POSITION": 99 });
    assert_contains(&load_err(&doc), &["POSITION accessor 99 does not exist"]);
}

#[test]
fn error_index_out_of_range() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [0.0; 3], false);
    let mesh = b.mesh(
        "bad",
        &[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        None,
        &[0, 1, 5],
        m,
    );
    b.node("bad", mesh, [0.0; 3]);
    let err = format!("{:#}", load_str(&b.to_json_string()).unwrap_err());
    assert_contains(&err, &["mesh 'bad' primitive 0", "index 5", "out of range"]);
}

#[test]
fn error_non_indexed_not_multiple_of_three() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [0.0; 3], false);
    let mesh = b.mesh(
        "four",
        &[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0; 3]],
        None,
        &[0, 1, 2],
        m,
    );
    b.node("four", mesh, [0.0; 3]);
    let mut doc: Value = serde_json::from_str(&b.to_json_string()).unwrap();
    doc["meshes"][0]["primitives"][0]
        .as_object_mut()
        .unwrap()
        .remove("indices");
    assert_contains(
        &load_err(&doc),
        &["mesh 'four' primitive 0", "not indexed", "multiple of 3"],
    );
}

#[test]
fn error_no_triangles() {
    let doc = json!({
        "asset": { "version": "2.0" },
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "name": "empty" }],
    });
    assert_contains(&load_err(&doc), &["test.gltf", "no triangles in scene"]);
    // Meshes that exist but are not referenced by the scene do not count.
    let mut doc = triangle_doc();
    doc["scenes"][0]["nodes"] = json!([]);
    assert_contains(&load_err(&doc), &["no triangles in scene"]);
    // When the loader's own warnings are why nothing is left, the error says them (no summary
    // follows an error to print them in).
    let mut doc = triangle_doc();
    doc["nodes"][0]["scale"] = json!([0.0, 0.0, 0.0]);
    let e = load_err(&doc);
    assert_contains(&e, &["test.gltf: no triangles in scene", "the loader also noted", "scaled to nothing (zero scale), skipped"]);
    assert_eq!(e.matches("test.gltf").count(), 1, "the file is named once: {e}");
}

#[test]
fn error_bad_buffers_do_not_panic() {
    // Accessor reading past the end of its buffer view.
    let mut doc = triangle_doc();
    doc["accessors"][0]["count"] = json!(1000);
    assert_contains(
        &load_err(&doc),
        &["mesh 'tri' primitive 0: POSITION", "exceeds buffer view"],
    );
    // Zero-count accessor.
    let mut doc = triangle_doc();
    doc["accessors"][1]["count"] = json!(0);
    assert_contains(&load_err(&doc), &["indices", "empty"]);
    // Byte stride smaller than the element.
    let mut doc = triangle_doc();
    doc["bufferViews"][0]["byteStride"] = json!(4);
    assert_contains(&load_err(&doc), &["stride"]);
    // Buffer view outside the buffer.
    let mut doc = triangle_doc();
    doc["bufferViews"][0]["byteOffset"] = json!(1_000_000);
    assert_contains(&load_err(&doc), &["exceeds buffer 0"]);
    // Float indices.
    let mut doc = triangle_doc();
    doc["accessors"][1]["componentType"] = json!(5126);
    assert_contains(&load_err(&doc), &["index accessor"]);
    // Broken base64.
    let mut doc = triangle_doc();
    doc["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@@");
    assert_contains(&load_err(&doc), &["buffer 0", "base64"]);
    // External file without a base directory.
    let mut doc = triangle_doc();
    doc["buffers"][0]["uri"] = json!("data.bin");
    assert_contains(&load_err(&doc), &["data.bin", "base directory"]);
    // A bufferView past its buffer's declared byteLength (the data itself holds the bytes).
    let mut doc = triangle_doc();
    let declared = doc["buffers"][0]["byteLength"].as_u64().unwrap();
    doc["buffers"][0]["byteLength"] = json!(declared - 4);
    assert_contains(&load_err(&doc), &["buffer view", "exceeds buffer 0's byteLength"]);
    // Truncated / lying GLB headers.
    for bytes in [
        &b"glTF"[..],
        b"glTF\x02\0\0\0\x04\0\0\0",
        b"glTF\x02\0\0\0\xff\xff\0\0",
    ] {
        let err = format!(
            "{:#}",
            Scene::from_gltf_slice(bytes, None, "bad.glb").unwrap_err()
        );
        assert_contains(&err, &["bad.glb", "GLB"]);
    }
    // Node cycles are refused, naming the cycle: a node its own child, and a cycle of two in a
    // file without scenes (where its nodes, nobody's roots, used to vanish without a word).
    let mut doc = triangle_doc();
    doc["nodes"][0]["children"] = json!([0]);
    assert_contains(&load_err(&doc), &["node 0 ('tri') is its own ancestor (tri -> tri)", "trees"]);
    let mut doc = triangle_doc();
    doc["nodes"].as_array_mut().unwrap().push(json!({ "name": "other", "children": [0] }));
    doc["nodes"][0]["children"] = json!([1]);
    doc.as_object_mut().unwrap().remove("scenes");
    doc.as_object_mut().unwrap().remove("scene");
    assert_contains(&load_err(&doc), &["is its own ancestor", "tri -> other -> tri"]);
    // A shared child (two parents) is not a cycle: a warning, the first placement kept.
    let mut doc = triangle_doc();
    doc["nodes"].as_array_mut().unwrap().push(json!({ "name": "a", "children": [0] }));
    doc["nodes"].as_array_mut().unwrap().push(json!({ "name": "b", "children": [0] }));
    doc["scenes"][0]["nodes"] = json!([1, 2]);
    let s = load_value(&doc).unwrap();
    assert_eq!(s.instances.len(), 1);
    assert!(s.warnings.iter().any(|w| w.contains("more than once")), "{:?}", s.warnings);
}

#[test]
fn integer_texcoords_are_read_only_when_normalized() {
    // TEXCOORD_0 as UNSIGNED_BYTE VEC2 (stride 4, as vertex attributes must be aligned).
    let bytes: Vec<u8> = vec![255, 0, 0, 0, 0, 255, 0, 0, 51, 102, 0, 0];
    let mut doc = triangle_doc();
    doc["buffers"].as_array_mut().unwrap().push(json!({
        "byteLength": bytes.len(),
        "uri": format!("data:application/octet-stream;base64,{}", crate::scene::base64::encode(&bytes)),
    }));
    let buffer = doc["buffers"].as_array().unwrap().len() - 1;
    doc["bufferViews"].as_array_mut().unwrap().push(json!({ "buffer": buffer, "byteLength": bytes.len(), "byteStride": 4 }));
    let view = doc["bufferViews"].as_array().unwrap().len() - 1;
    doc["accessors"].as_array_mut().unwrap().push(json!({
        "bufferView": view, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC2",
    }));
    let accessor = doc["accessors"].as_array().unwrap().len() - 1;
    doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(accessor);
    let s = load_value(&doc).unwrap();
    assert_eq!(s.meshes[0].uvs, [Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0), Vec2::new(0.2, 0.4)]);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // Not normalized: integer UVs need KHR_mesh_quantization; ignored with a warning.
    doc["accessors"][accessor]["normalized"] = json!(false);
    let s = load_value(&doc).unwrap();
    assert!(s.meshes[0].uvs.iter().all(|&uv| uv == Vec2::ZERO));
    assert_contains(&s.warnings.join("\n"), &["TEXCOORD_0 of type U8 Vec2 (not normalized) not supported, ignored"]);
}

#[test]
fn a_scene_without_nodes_is_valid() {
    // `scene.nodes` is optional in glTF 2.0 (the gltf crate requires it).
    let mut doc = triangle_doc();
    doc["scenes"].as_array_mut().unwrap().push(json!({ "name": "empty" }));
    let s = load_value(&doc).expect("scene 0 loads beside a scene without nodes");
    assert_eq!(s.instances.len(), 1);
    // Chosen, it is an empty scene: the error says so, not that the file is malformed.
    doc["scene"] = json!(1);
    let err = load_err(&doc);
    assert!(!err.contains("malformed"), "{err}");
}

#[test]
fn morph_targets_and_vertex_colours_are_named_when_they_would_change_the_image() {
    let warned = |doc: &Value, what: &str| load_value(doc).unwrap().warnings.iter().any(|w| w.contains(what));
    // Morph targets (POSITION displacements, here the positions themselves) under a weight of 1;
    // a weight of 0 changes nothing and says nothing; a node's weights override the mesh's.
    let mut doc = triangle_doc();
    doc["meshes"][0]["primitives"][0]["targets"] = json!([{ "POSITION": 0 }]);
    assert!(!warned(&doc, "morph targets"));
    doc["meshes"][0]["weights"] = json!([0.0]);
    assert!(!warned(&doc, "morph targets"));
    doc["meshes"][0]["weights"] = json!([1.0]);
    assert!(warned(&doc, "mesh 'tri' (node 'tri'): morph targets are not supported; its weights [1] are ignored"));
    doc["nodes"][0]["weights"] = json!([0.0]);
    assert!(!warned(&doc, "morph targets"));
    // COLOR_0: the positions as colours are not white; an all-white one is the identity.
    let mut doc = triangle_doc();
    doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(0);
    assert!(warned(&doc, "COLOR_0 (vertex colours, 3 of 3 not white) is not supported"));
    let white: Vec<u8> = [1.0f32; 9].iter().flat_map(|x| x.to_le_bytes()).collect();
    doc["buffers"].as_array_mut().unwrap().push(json!({
        "byteLength": white.len(),
        "uri": format!("data:application/octet-stream;base64,{}", crate::scene::base64::encode(&white)),
    }));
    let buffer = doc["buffers"].as_array().unwrap().len() - 1;
    doc["bufferViews"].as_array_mut().unwrap().push(json!({ "buffer": buffer, "byteLength": white.len() }));
    let view = doc["bufferViews"].as_array().unwrap().len() - 1;
    doc["accessors"].as_array_mut().unwrap().push(json!({ "bufferView": view, "componentType": 5126, "count": 3, "type": "VEC3" }));
    doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(doc["accessors"].as_array().unwrap().len() - 1);
    assert!(!warned(&doc, "COLOR_0"));
}

// ---------------------------------------------------------------- loader features

#[test]
fn non_indexed_primitive() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [0.0; 3], false);
    let pos = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [0.0, 1.0, 1.0],
    ];
    let mesh = b.mesh("soup", &pos, None, &[0, 1, 2], m);
    b.node("soup", mesh, [0.0; 3]);
    let mut doc: Value = serde_json::from_str(&b.to_json_string()).unwrap();
    doc["meshes"][0]["primitives"][0]
        .as_object_mut()
        .unwrap()
        .remove("indices");
    let s = load_value(&doc).unwrap();
    assert_eq!(s.meshes[0].indices, [0, 1, 2, 3, 4, 5]);
    assert_eq!(s.meshes[0].triangle_materials, [0, 0]);
    assert_eq!(s.triangle_count(), 2);
}

#[test]
fn normals_and_default_material() {
    let mut b = GltfBuilder::new();
    let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let nrm = [[0.0, 0.0, 1.0]; 3];
    let with = b.mesh("with_normals", &pos, Some(&nrm), &[0, 1, 2], 0);
    let without = b.mesh("without_normals", &pos, None, &[0, 1, 2], 0);
    b.node("a", with, [0.0; 3]);
    b.node("b", without, [0.0; 3]);
    let mut doc: Value = serde_json::from_str(&b.to_json_string()).unwrap();
    for mesh in doc["meshes"].as_array_mut().unwrap() {
        mesh["primitives"][0]
            .as_object_mut()
            .unwrap()
            .remove("material");
    }
    let s = load_value(&doc).unwrap();
    assert_eq!(s.materials, [Material::default_material()]);
    assert_eq!(s.meshes[0].normals, vec![Vec3::Z; 3]);
    assert_eq!(s.meshes[1].normals, vec![Vec3::ZERO; 3]);
    assert!(s.emissive_triangles().is_empty());
}

#[test]
fn node_hierarchy_transform() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [1.0; 3], false);
    let mesh = b.quad(
        "q",
        [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        m,
    );
    let parent = b.group(
        "parent",
        Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)).to_cols_array(),
    );
    let child = b.node_matrix(
        "child",
        mesh,
        Mat4::from_scale(Vec3::splat(2.0)).to_cols_array(),
    );
    b.add_child(parent, child);
    let s = load_str(&b.to_json_string()).unwrap();
    assert_eq!(s.instances.len(), 1);
    let expected =
        Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)) * Mat4::from_scale(Vec3::splat(2.0));
    assert!(s.instances[0].transform.abs_diff_eq(expected, EPS));
    let (lo, hi) = s.world_bounds();
    assert!(lo.abs_diff_eq(Vec3::new(1.0, 2.0, 3.0), EPS), "{lo}");
    assert!(hi.abs_diff_eq(Vec3::new(3.0, 4.0, 3.0), EPS), "{hi}");
    let area: f32 = s.emissive_triangles().iter().map(|t| t.area).sum();
    assert!((area - 4.0).abs() < 1e-5);
}

#[test]
fn mirrored_transform_keeps_front_face() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [1.0; 3], false);
    // A quad in the y = 1 plane facing down (-y).
    let quad = generate::orient_quad(
        [
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ],
        [0.0, -1.0, 0.0],
    );
    let mesh = b.quad("down", quad, m);
    b.node("plain", mesh, [0.0; 3]);
    b.node_matrix(
        "mirror_x",
        mesh,
        Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)).to_cols_array(),
    );
    // Mirroring in y flips the surface upside down: its front face now points +y.
    b.node_matrix(
        "mirror_y",
        mesh,
        Mat4::from_scale(Vec3::new(1.0, -1.0, 1.0)).to_cols_array(),
    );
    let s = load_str(&b.to_json_string()).unwrap();
    assert!(!s.instances[0].is_mirrored());
    assert!(s.instances[1].is_mirrored() && s.instances[2].is_mirrored());
    let tris = s.emissive_triangles();
    assert_eq!(tris.len(), 6);
    for t in &tris {
        let expected = if t.instance == 2 {
            Vec3::Y
        } else {
            Vec3::NEG_Y
        };
        assert!(
            t.normal.abs_diff_eq(expected, EPS),
            "instance {}: {}",
            t.instance,
            t.normal
        );
        assert!((t.area - 0.5).abs() < EPS);
        // The GPU's light sampling takes the front face from the vertex order alone
        // (cross(p1 - p0, p2 - p0), photon_emit and direct_light.glsl): it must agree.
        let ccw = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).normalize();
        assert!(ccw.abs_diff_eq(t.normal, EPS), "instance {}: vertex order faces {ccw}, normal {}", t.instance, t.normal);
    }
}

#[test]
fn degenerate_triangles_not_emissive() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [1.0; 3], false);
    let pos = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mesh = b.mesh("m", &pos, None, &[0, 1, 2, 0, 1, 3], m);
    b.node("m", mesh, [0.0; 3]);
    let s = load_str(&b.to_json_string()).unwrap();
    assert_eq!(s.triangle_count(), 2);
    let tris = s.emissive_triangles();
    assert_eq!(tris.len(), 1);
    assert_eq!(tris[0].triangle, 1);
    // One of two left: no warning (meshes hold degenerate triangles).
    assert!(!s.warnings.join("\n").contains("zero area"), "{:?}", s.warnings);
}

/// Emissive triangles all of zero area (their vertices in a line) are named: the only message
/// was "no emitters", beside the file's emissive material.
#[test]
fn emitters_of_zero_area_are_named() {
    let mut b = GltfBuilder::new();
    let m = b.material("glow", [0.5; 3], [2.0; 3], false);
    let mesh = b.mesh("line", &[[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], None, &[0, 1, 2], m);
    b.node("line", mesh, [0.0; 3]);
    let s = load_str(&b.to_json_string()).unwrap();
    assert_eq!(s.emissive_triangles_and_tiny().2, 1);
    assert_contains(&s.warnings.join("\n"), &["its 1 emissive triangle has zero area (degenerate: its vertices in a line or at one point)"]);
    // With a point light the scene has light: no such warning.
    b.point_light("bulb", [0.0, 1.0, 0.0], [1.0; 3], 1.0);
    let s = load_str(&b.to_json_string()).unwrap();
    assert!(!s.warnings.join("\n").contains("zero area"), "{:?}", s.warnings);
}

#[test]
fn scene_selection() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [0.0; 3], false);
    let mesh_a = b.quad(
        "a",
        [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        m,
    );
    let mesh_b = b.quad(
        "b",
        [[0.0; 3], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]],
        m,
    );
    b.node("a", mesh_a, [0.0; 3]);
    b.node("b", mesh_b, [0.0; 3]);
    let mut doc: Value = serde_json::from_str(&b.to_json_string()).unwrap();
    doc["scenes"] = json!([{ "nodes": [0] }, { "nodes": [1] }]);

    doc["scene"] = json!(1);
    let s = load_value(&doc).unwrap();
    assert_eq!(s.instances.len(), 1);
    assert_eq!(s.instances[0].name, "b");
    assert_eq!(s.meshes.len(), 1, "only referenced meshes are loaded");
    assert_eq!(s.meshes[0].name, "b");

    doc.as_object_mut().unwrap().remove("scene");
    let s = load_value(&doc).unwrap();
    assert_eq!(s.instances[0].name, "a", "without 'scene', scene 0 is used");

    doc.as_object_mut().unwrap().remove("scenes");
    let s = load_value(&doc).unwrap();
    assert_eq!(
        s.instances.len(),
        2,
        "without scenes, all root nodes are used"
    );
}

/// Lights whose power overflows the GPU's 32-bit fluxes are an error naming the brightest (a
/// point light of 1e38 cd rendered every VPL mode black without a word); a bright but
/// representable one loads.
#[test]
fn light_power_beyond_32_bit_fluxes_is_an_error() {
    let scene_with = |intensity: f32, emission: f32| {
        let mut b = GltfBuilder::new();
        let m = b.material("m", [0.5; 3], [0.0; 3], false);
        let hot = b.material("hot", [0.5; 3], [emission; 3], false);
        let floor = b.quad("floor", [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]], m);
        let panel = b.quad("panel", [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]], hot);
        b.node("floor", floor, [0.0; 3]);
        b.node("panel", panel, [0.0; 3]);
        b.point_light("bulb", [0.5, 0.5, 0.5], [1.0; 3], intensity);
        serde_json::from_str::<Value>(&b.to_json_string()).unwrap()
    };
    assert!(load_value(&scene_with(1e20, 1e20)).is_ok());
    let err = load_err(&scene_with(1e38, 1.0));
    assert_contains(&err, &["point light 'bulb'", "32-bit"]);
    let err = load_err(&scene_with(1.0, 1e36));
    assert_contains(&err, &["emissive triangle", "32-bit"]);
    // A negative channel passed the power check (its brightest channel) and emitted negative light.
    let mut doc = scene_with(1.0, 1.0);
    doc["extensions"]["KHR_lights_punctual"]["lights"][0]["color"] = json!([1.0, -1.0, 1.0]);
    assert_contains(&load_err(&doc), &["point light 'bulb'", "color [1, -1, 1]", "non-negative"]);
    let mut doc = scene_with(1.0, 1.0);
    doc["extensions"]["KHR_lights_punctual"]["lights"][0]["intensity"] = json!(-2.0);
    assert_contains(&load_err(&doc), &["point light 'bulb'", "intensity -2"]);
}

/// Geometry, point lights and cameras farther than 1e18 from the origin are refused, each named
/// (a Cornell box scaled to 5e19 rendered 3,600× too dark: shadow rays between points ~1e19 apart
/// read as blocked); 1e17 loads.
#[test]
fn a_scene_beyond_the_reach_of_32_bit_rays_is_an_error() {
    let scene = |offset: f32, light: f32, camera: f32| {
        let mut b = GltfBuilder::new();
        let m = b.material("m", [0.5; 3], [0.0; 3], false);
        let floor = b.quad("floor", [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]], m);
        b.node("floor", floor, [offset, 0.0, 0.0]);
        b.point_light("bulb", [light, 0.5, 0.5], [1.0; 3], 1.0);
        b.camera("cam", [camera, 0.0, 5.0], [camera, 0.0, 0.0], [0.0, 1.0, 0.0], 0.8);
        serde_json::from_str::<Value>(&b.to_json_string()).unwrap()
    };
    assert!(load_value(&scene(1e17, 1e17, 1e17)).is_ok());
    assert_contains(&load_err(&scene(2e18, 0.0, 0.0)), &["its geometry", "more than 1e18 from the origin", "scale the scene down"]);
    assert_contains(&load_err(&scene(0.0, 2e18, 0.0)), &["point light 'bulb' lies at", "more than 1e18"]);
    assert_contains(&load_err(&scene(0.0, 0.0, -2e18)), &["camera 'cam' lies at", "more than 1e18"]);
}

/// An emission that is negative or not finite is an error, as baseColorFactor's is: it was set
/// aside with a warning, which rendered black (the one light zeroed). A camera's yfov outside
/// [0.01°, 180°) was too (the automatic camera behind a wall): it is now refused by the run that
/// would look through it (tests in camera.rs and tests/cli.rs).
#[test]
fn a_bad_yfov_or_emission_is_an_error() {
    // The camera is kept, yfov and all: a run that looks through it refuses it
    // (camera::scene_camera_problem), one that replaces it with --eye/--target renders.
    for yfov in [0.0, -0.5, 4.0] {
        let mut doc = cornell_doc();
        doc["cameras"][0]["perspective"]["yfov"] = json!(yfov);
        assert_eq!(load_value(&doc).unwrap().camera.map(|c| c.yfov), Some(yfov));
    }
    let mut doc = triangle_doc();
    doc["materials"][0]["emissiveFactor"] = json!([-1.0, 0.5, 0.5]);
    assert_contains(&load_err(&doc), &["material 'glow': emissiveFactor [-1, 0.5, 0.5]", "not negative"]);
    for strength in [json!(-5.0), json!(1e39)] {
        let mut doc = triangle_doc();
        doc["materials"][0]["extensions"] = json!({ "KHR_materials_emissive_strength": { "emissiveStrength": strength } });
        assert_contains(&load_err(&doc), &["material 'glow': KHR_materials_emissive_strength", "finite and not negative"]);
    }
    // Above glTF's [0, 1], with the factor and strength that say the same.
    let mut doc = triangle_doc();
    doc["materials"][0].as_object_mut().unwrap().remove("extensions");
    doc["materials"][0]["emissiveFactor"] = json!([10.0, 1.0, 2.5]);
    assert_contains(
        &load_err(&doc),
        &["material 'glow': emissiveFactor [10, 1, 2.5] must lie in [0, 1]", "emissiveFactor [1, 0.1, 0.25]", "\"emissiveStrength\": 10 }"],
    );
    // A factor above 1 whose brightness no strength could carry says so.
    let mut doc = triangle_doc();
    doc["materials"][0]["extensions"] = json!({ "KHR_materials_emissive_strength": { "emissiveStrength": 1e38 } });
    doc["materials"][0]["emissiveFactor"] = json!([10.0, 1.0, 1.0]);
    let err = load_err(&doc);
    assert_contains(&err, &["emissiveFactor [10, 1, 1] must lie in [0, 1]", "overflows 32-bit floats"]);
    assert!(!err.contains("inf"), "{err}");
    // A factor in [0, 1] times the largest strength f32 holds is finite; the lights' total power
    // is what refuses it.
    let mut doc = triangle_doc();
    doc["materials"][0]["extensions"] = json!({ "KHR_materials_emissive_strength": { "emissiveStrength": 3.4e38 } });
    doc["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    assert_contains(&load_err(&doc), &["the lights emit", "more than the 1e30 W"]);
}

#[test]
fn lights_cameras_and_warnings() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [0.0; 3], false);
    let mesh = b.quad(
        "q",
        [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        m,
    );
    b.node("q", mesh, [0.0; 3]);
    b.point_light("bulb", [1.0, 2.0, 3.0], [1.0, 0.5, 0.25], 40.0);
    b.camera("first", [0.0, 0.0, 5.0], [0.0; 3], [0.0, 1.0, 0.0], 0.8);
    b.camera("second", [0.0, 0.0, 9.0], [0.0; 3], [0.0, 1.0, 0.0], 0.5);
    let mut doc: Value = serde_json::from_str(&b.to_json_string()).unwrap();
    let lights = doc["extensions"]["KHR_lights_punctual"]["lights"]
        .as_array_mut()
        .unwrap();
    lights.push(json!({ "name": "sun", "type": "directional" }));
    lights.push(json!({ "name": "cone", "type": "spot", "spot": {} }));
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(json!({ "extensions": { "KHR_lights_punctual": { "light": 1 } } }));
    nodes.push(json!({ "extensions": { "KHR_lights_punctual": { "light": 2 } } }));
    nodes.push(json!({ "name": "ortho_node", "camera": 2 }));
    doc["cameras"].as_array_mut().unwrap().push(
        json!({ "name": "ortho", "type": "orthographic", "orthographic": { "xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10 } }),
    );
    doc["scenes"][0]["nodes"] = json!([5, 0, 1, 2, 3, 4, 6]);

    let s = load_value(&doc).unwrap();
    assert_eq!(s.point_lights.len(), 1);
    let l = &s.point_lights[0];
    assert_eq!(l.name, "bulb");
    assert!(l.position.abs_diff_eq(Vec3::new(1.0, 2.0, 3.0), EPS));
    assert!(l.color.abs_diff_eq(Vec3::new(1.0, 0.5, 0.25), EPS));
    assert_eq!(l.intensity, 40.0);
    let cam = s.camera.as_ref().unwrap();
    assert_eq!(cam.name, "first");
    assert!((cam.yfov - 0.8).abs() < EPS);
    assert!(cam
        .transform
        .transform_vector3(Vec3::NEG_Z)
        .abs_diff_eq(Vec3::NEG_Z, EPS));
    let w = s.warnings.join("\n");
    assert_contains(
        &w,
        &[
            "directional light 'sun' not supported",
            "spot light 'cone' not supported",
            "orthographic camera 'ortho' not supported",
            "camera 'second' ignored",
        ],
    );
    assert!(!w.contains("range"), "{w}");
    // A light's range, which a glTF viewer would apply and this renderer does not, is said.
    doc["cameras"][0]["perspective"]["aspectRatio"] = json!(2.0);
    doc["extensions"]["KHR_lights_punctual"]["lights"][0]["range"] = json!(3.0);
    let w = load_value(&doc).unwrap().warnings.join("\n");
    assert_contains(&w, &["point light 'bulb': range 3 ignored"]);
    assert!(!w.contains("aspectRatio"), "exporters always write it: {w}");
}

/// A PNG (RGBA8) as a base64 data URI.
fn png_data_uri(width: u32, height: u32, rgba: &[u8]) -> String {
    let bytes = crate::output::encode_png(width, height, rgba).unwrap();
    format!("data:image/png;base64,{}", base64::encode(&bytes))
}

#[test]
fn base_color_textures_are_decoded_once_and_shared() {
    let mut doc = triangle_doc();
    let rgba = [255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 10, 20, 30, 255];
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 1 });
    doc["materials"].as_array_mut().unwrap().push(json!({
        "name": "second",
        "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } },
    }));
    doc["textures"] = json!([{ "source": 0 }, { "source": 0, "sampler": 0 }]);
    doc["samplers"] = json!([{ "wrapS": 33071 }]);
    doc["images"] = json!([{ "name": "checker", "uri": png_data_uri(2, 2, &rgba) }]);
    // Both materials in use (only used materials' textures are read).
    let mut second = doc["meshes"][0]["primitives"][0].clone();
    second["material"] = json!(1);
    doc["meshes"][0]["primitives"].as_array_mut().unwrap().push(second);
    let s = load_value(&doc).unwrap();
    assert_eq!(s.textures.len(), 1, "one image, decoded once");
    let t = &s.textures[0];
    assert_eq!((t.name.as_str(), t.width, t.height), ("checker", 2, 2));
    assert_eq!(t.rgba8, rgba);
    assert_eq!(s.materials[0].base_color_texture, Some(0));
    assert_eq!(s.materials[1].base_color_texture, Some(0));
    assert_contains(&s.warnings.join("\n"), &["material 'glow'", "ClampToEdge", "repeat wrapping"]);
}

#[test]
fn texture_errors_name_the_material_and_image() {
    let mut doc = triangle_doc();
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    doc["textures"] = json!([{ "source": 0 }]);
    doc["images"] = json!([{ "uri": "missing_texture.png" }]);
    let e = match Scene::from_gltf_slice(doc.to_string().as_bytes(), Some(Path::new("/nonexistent-dir")), "t.gltf") {
        Ok(_) => panic!("expected an error"),
        Err(e) => format!("{e:#}"),
    };
    assert_contains(&e, &["t.gltf", "material 'glow'", "image 0", "missing_texture.png"]);

    doc["images"] = json!([{ "uri": "data:image/png;base64,AAAA" }]);
    assert_contains(&load_err(&doc), &["material 'glow'", "cannot decode"]);

    doc["images"] = json!([{ "uri": png_data_uri(1, 1, &[1, 2, 3, 4]) }]);
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0, "texCoord": 1 });
    let s = load_value(&doc).unwrap();
    assert!(s.textures.is_empty());
    assert_eq!(s.materials[0].base_color_texture, None);
    assert_contains(&s.warnings.join("\n"), &["TEXCOORD_1", "ignored"]);
}

/// A PNG of `w`×`h` RGBA8 texels whose image data is cut short after two bytes: its size reads,
/// its texels do not decode.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8; 4], data: &[u8]| {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let start = png.len();
        png.extend_from_slice(kind);
        png.extend_from_slice(data);
        let crc = crc32fast::hash(&png[start..]);
        png.extend_from_slice(&crc.to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    // The start of a zlib stream: the header reader wants an IDAT chunk; its data is cut short.
    chunk(b"IDAT", &[0x78, 0x9c]);
    chunk(b"IEND", &[]);
    png
}

/// Textures holding more texels together than any device binds (2^30) are refused from their
/// headers, before any is decoded (twelve 8192² images took 6.4 GB and 10 s to decode before the
/// upload refused them): header-only PNGs, which could not be decoded, get this error.
#[test]
fn textures_too_large_together_are_refused_before_decoding() {
    let mut doc = triangle_doc();
    let prim = doc["meshes"][0]["primitives"][0].clone();
    let uri = format!("data:image/png;base64,{}", base64::encode(&png_header_only(8192, 8192)));
    let n = 16; // 16 × 2^26 texels = 2^30: 2^32 bytes, past any u32 maxStorageBufferRange
    let (mut materials, mut textures, mut images, mut prims) = (vec![], vec![], vec![], vec![]);
    for k in 0..n {
        materials.push(json!({ "name": format!("m{k}"), "pbrMetallicRoughness": { "baseColorTexture": { "index": k } } }));
        textures.push(json!({ "source": k }));
        images.push(json!({ "name": format!("big{k}"), "uri": uri }));
        let mut p = prim.clone();
        p["material"] = json!(k);
        prims.push(p);
    }
    doc["materials"] = json!(materials);
    doc["textures"] = json!(textures);
    doc["images"] = json!(images);
    doc["meshes"][0]["primitives"] = json!(prims);
    assert_contains(&load_err(&doc), &["1073741824 texels", "--textures off", "'big0' 8192x8192"]);
    // One fewer fits the total; the first image then fails to decode (it has no data).
    for key in ["materials", "textures", "images"] {
        doc[key].as_array_mut().unwrap().pop();
    }
    doc["meshes"][0]["primitives"].as_array_mut().unwrap().pop();
    assert_contains(&load_err(&doc), &["material 'm0'", "image 0"]);
}

/// Textures past the device's maxStorageBufferRange are refused from their headers, before any is
/// decoded, with the upload's words (on lavapipe's 128 MiB a scene of GiBs of texels decoded them
/// all, taking minutes and as much memory, before the upload refused them). The device is asked
/// only when the texels pass what every device allows (2^27 bytes); with no device known the
/// load goes on to decode (this header-only PNG then fails to decode).
#[test]
fn textures_past_the_devices_buffer_range_are_refused_before_decoding() {
    let mut doc = triangle_doc();
    doc["materials"] = json!([{ "name": "m", "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }]);
    doc["meshes"][0]["primitives"][0]["material"] = json!(0);
    doc["textures"] = json!([{ "source": 0 }]);
    let load = |w: u32, h: u32, range: Option<u64>, asked: &std::cell::Cell<u32>| {
        let mut d = doc.clone();
        d["images"] = json!([{ "name": "big", "uri": format!("data:image/png;base64,{}", base64::encode(&png_header_only(w, h))) }]);
        let device_range = || {
            asked.set(asked.get() + 1);
            range
        };
        let text = d.to_string();
        match super::load::load_slice(text.as_bytes(), None, "big.gltf", super::load::TextureLoad { decode: true, device_range: &device_range }) {
            Ok(_) => panic!("a header-only PNG loaded"),
            Err(e) => format!("{e:#}"),
        }
    };
    let asked = std::cell::Cell::new(0);
    // 8192² texels: 256 MiB, over lavapipe's 128 MiB.
    let e = load(8192, 8192, Some(128 << 20), &asked);
    assert_contains(&e, &["big.gltf", "256.0 MiB", "maxStorageBufferRange: 128.0 MiB", "--textures off", "'big' 8192x8192"]);
    assert_eq!(asked.get(), 1);
    // Within a 4 GiB device's range, or no device known: decoded (and this one fails there).
    for range in [Some(4u64 << 30), None] {
        assert_contains(&load(8192, 8192, range, &asked), &["image 0"]);
    }
    // Within what every device allows: the device is not asked (a probe costs an instance).
    let before = asked.get();
    assert_contains(&load(4096, 4096, Some(1), &asked), &["image 0"]);
    assert_eq!(asked.get(), before, "asked for a texture every device takes");
}

/// Only the materials the rendered scene uses have their textures read: a texture that cannot be
/// read, on a material no primitive uses or used only in another glTF scene, failed the file.
/// Cut-outs and transparency are not rendered: a used material asking for them is warned about.
#[test]
fn unused_materials_textures_are_not_read_and_alpha_modes_are_warned_about() {
    let mut doc = triangle_doc();
    doc["materials"].as_array_mut().unwrap().push(json!({
        "name": "unused",
        "alphaMode": "BLEND",
        "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } },
    }));
    doc["textures"] = json!([{ "source": 0 }]);
    doc["images"] = json!([{ "uri": "data:image/png;base64,AAAA" }]);
    let s = load_value(&doc).unwrap();
    assert!(s.textures.is_empty() && s.warnings.is_empty(), "{:?}", s.warnings);
    // The same material in another glTF scene, not the one rendered: still not read.
    let mut other = doc.clone();
    other["meshes"].as_array_mut().unwrap().push(json!({ "name": "elsewhere", "primitives": [{ "attributes": { "POSITION": 0 }, "material": 1 }] }));
    other["nodes"].as_array_mut().unwrap().push(json!({ "mesh": 1 }));
    other["scenes"].as_array_mut().unwrap().push(json!({ "nodes": [1] }));
    assert!(load_value(&other).unwrap().textures.is_empty());
    // Used only by a lines primitive, which is skipped: not read, and no alpha warning.
    let mut wire = doc.clone();
    let mut lines = wire["meshes"][0]["primitives"][0].clone();
    lines["mode"] = json!(1);
    lines["material"] = json!(1);
    wire["meshes"][0]["primitives"].as_array_mut().unwrap().push(lines);
    let s = load_value(&wire).unwrap();
    assert!(s.textures.is_empty() && !s.warnings.join("\n").contains("alphaMode"), "{:?}", s.warnings);
    // Used, it is read (and fails to decode), and its alpha mode is warned about.
    doc["meshes"][0]["primitives"][0]["material"] = json!(1);
    assert_contains(&load_err(&doc), &["material 'unused'", "cannot decode"]);
    doc["images"] = json!([{ "uri": png_data_uri(1, 1, &[1, 2, 3, 4]) }]);
    let s = load_value(&doc).unwrap();
    assert_eq!(s.textures.len(), 1);
    assert_contains(&s.warnings.join("\n"), &["material 'unused'", "alphaMode Blend", "rendered opaque"]);
    // Its pbrMetallicRoughness leaves metallicFactor out: glTF's default 1, a metal, rendered as
    // Lambertian diffuse with one warning naming it; metallicFactor 0 draws none.
    assert_contains(&s.warnings.join("\n"), &["1 material(s) with a metallicFactor above 0", "'unused' (1)", "Lambertian"]);
    doc["materials"][1]["pbrMetallicRoughness"]["metallicFactor"] = json!(0.0);
    assert!(!load_value(&doc).unwrap().warnings.join("\n").contains("metallicFactor"));
    // A name's control characters are shown escaped: a newline in it printed a line of its own
    // (here a forged error).
    doc["materials"][1]["name"] = json!("unused\nerror: forged\u{1b}[2J");
    let w = load_value(&doc).unwrap().warnings;
    let alpha = w.iter().find(|w| w.contains("alphaMode")).expect("the alpha mode warning");
    assert!(alpha.contains(r"material 'unused\nerror: forged\u{1b}[2J'") && !alpha.contains('\n') && !alpha.contains('\u{1b}'), "{alpha:?}");
}

/// A file with several glTF scenes and no default renders scene 0; when that one is empty and
/// another holds meshes, the error says so (it said only "no triangles in scene").
#[test]
fn an_empty_first_scene_without_a_default_names_the_scene_with_meshes() {
    let mut doc = triangle_doc();
    doc.as_object_mut().unwrap().remove("scene");
    doc["scenes"] = json!([{ "nodes": [] }, { "name": "main", "nodes": [0] }]);
    assert_contains(&load_err(&doc), &["no triangles in scene 0", "no default scene", "scene 1 ('main') holds meshes"]);
    doc["scene"] = json!(1);
    assert_eq!(load_value(&doc).unwrap().triangle_count(), 1);
}

/// A few kilobytes of glTF (one accessor without a buffer view, 3 × 2^24 vertices, read by 16
/// primitives) asked the loader for tens of gigabytes and aborted; the accessors' counts are now
/// checked against what a GPU's texel buffer holds before any is read.
#[test]
fn geometry_beyond_a_storage_buffer_is_refused_before_it_is_read() {
    let mut doc = triangle_doc();
    let n = 3u64 << 24;
    doc["accessors"].as_array_mut().unwrap().push(json!({
        "componentType": 5126, "count": n, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0],
        "sparse": { "count": 1, "indices": { "bufferView": 0, "componentType": 5125 }, "values": { "bufferView": 0 } },
    }));
    let last = doc["accessors"].as_array().unwrap().len() - 1;
    let prim = json!({ "attributes": { "POSITION": last } });
    doc["meshes"][0]["primitives"] = json!(vec![prim; 16]);
    let e = load_err(&doc);
    assert_contains(&e, &["805306368 vertices", "more than a GPU's texel buffer holds"]);
    // Three vertices, and 2^26 triangles of indices: refused on the triangles.
    let mut doc = triangle_doc();
    doc["accessors"].as_array_mut().unwrap().push(json!({
        "componentType": 5125, "count": 3u64 << 26, "type": "SCALAR",
        "sparse": { "count": 1, "indices": { "bufferView": 0, "componentType": 5125 }, "values": { "bufferView": 0 } },
    }));
    let last = doc["accessors"].as_array().unwrap().len() - 1;
    doc["meshes"][0]["primitives"][0]["indices"] = json!(last);
    assert_contains(&load_err(&doc), &["3 vertices and 67108864 triangles", "44739242 triangles)"]);
    // Counts near 2^64 over several primitives saturate instead of wrapping past the check (or
    // overflowing, a panic where overflow is checked).
    let mut doc = triangle_doc();
    doc["accessors"].as_array_mut().unwrap().push(json!({
        "componentType": 5126, "count": 1u64 << 62, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0],
        "sparse": { "count": 1, "indices": { "bufferView": 0, "componentType": 5125 }, "values": { "bufferView": 0 } },
    }));
    let last = doc["accessors"].as_array().unwrap().len() - 1;
    let prim = json!({ "attributes": { "POSITION": last }, "indices": 1 });
    doc["meshes"][0]["primitives"] = json!(vec![prim; 4]);
    assert_contains(&load_err(&doc), &["18446744073709551615 vertices", "more than a GPU's texel buffer holds"]);
}

/// A NORMAL, TEXCOORD_0 or COLOR_0 whose count differs from POSITION's is refused before it is
/// read (COLOR_0 was not compared at all).
#[test]
fn attributes_of_another_count_than_position_are_refused() {
    for attribute in ["NORMAL", "TEXCOORD_0", "COLOR_0"] {
        let mut doc = triangle_doc();
        let kind = if attribute == "TEXCOORD_0" { "VEC2" } else { "VEC3" };
        doc["accessors"].as_array_mut().unwrap().push(json!({ "bufferView": 0, "componentType": 5126, "count": 2, "type": kind }));
        let last = doc["accessors"].as_array().unwrap().len() - 1;
        doc["meshes"][0]["primitives"][0]["attributes"][attribute] = json!(last);
        assert_contains(&load_err(&doc), &[attribute, "has 2 elements but POSITION has 3"]);
    }
}

/// Images and cameras that pass the schema but that the gltf crate's accessors would panic on.
#[test]
fn images_without_a_source_and_cameras_without_their_object_are_errors() {
    let mut doc = triangle_doc();
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    doc["textures"] = json!([{ "source": 0 }]);
    for (image, want) in [
        (json!({}), "neither a \"uri\" nor a \"bufferView\""),
        (json!({ "name": "pic", "bufferView": 0 }), "image 0 ('pic') has a \"bufferView\" but no \"mimeType\""),
        (json!({ "bufferView": 0, "uri": "x.png", "mimeType": "image/png" }), "both"),
    ] {
        doc["images"] = json!([image]);
        assert_contains(&load_err(&doc), &["image 0", want]);
    }
    let mut doc = cornell_doc();
    for (camera, want) in [
        (json!({ "name": "cam", "type": "orthographic", "perspective": { "yfov": 0.7, "znear": 0.1 } }), "\"type\": \"orthographic\" but no \"orthographic\" object"),
        (json!({ "type": "perspective", "orthographic": { "xmag": 1, "ymag": 1, "zfar": 10, "znear": 0.1 } }), "\"type\": \"perspective\" but no \"perspective\" object"),
    ] {
        doc["cameras"][0] = camera;
        assert_contains(&load_err(&doc), &["camera 0", want]);
    }
}

#[test]
fn emissive_strength_round_trip() {
    let mut b = GltfBuilder::new();
    let m = b.material("hot", [0.1; 3], [17.0, 12.0, 4.0], true);
    let mesh = b.quad(
        "q",
        [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        m,
    );
    b.node("q", mesh, [0.0; 3]);
    let text = b.to_json_string();
    assert!(text.contains("KHR_materials_emissive_strength"));
    let s = load_str(&text).unwrap();
    assert!(s.materials[0]
        .emission
        .abs_diff_eq(Vec3::new(17.0, 12.0, 4.0), 1e-4));
    assert!(s.materials[0].double_sided);
    let t = s.emissive_triangles();
    assert_eq!(t.len(), 2);
    assert!(t.iter().all(|t| t.normal.abs_diff_eq(Vec3::Z, EPS)));
}

/// Converts a builder document (one embedded buffer) to GLB; returns it and the JSON chunk length.
fn to_glb(mut doc: Value) -> (Vec<u8>, usize) {
    let uri = doc["buffers"][0]["uri"].as_str().unwrap().to_owned();
    let bin = base64::decode(uri.split_once(";base64,").unwrap().1).unwrap();
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    glb_of(&doc, &bin)
}

/// A GLB of `doc` (as written) with `bin` as its binary chunk; returns it and the JSON chunk length.
fn glb_of(doc: &Value, bin: &[u8]) -> (Vec<u8>, usize) {
    let mut json = doc.to_string().into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin_padded = bin.to_vec();
    while !bin_padded.len().is_multiple_of(4) {
        bin_padded.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin_padded.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json);
    glb.extend_from_slice(&(bin_padded.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin_padded);
    (glb, json.len())
}

#[test]
fn glb_round_trip() {
    let (glb, json_len) = to_glb(triangle_doc());
    // Another container version is named with what is read (the crate said "unsupported version").
    for v in [1u32, 3] {
        let mut other = glb.clone();
        other[4..8].copy_from_slice(&v.to_le_bytes());
        let e = format!("{:#}", Scene::from_gltf_slice(&other, None, "old.glb").unwrap_err());
        assert_contains(&e, &["old.glb", &format!("GLB container version {v} is not supported"), "only version 2"]);
    }
    let s = Scene::from_gltf_slice(&glb, None, "tiny.glb").unwrap();
    assert_eq!(s.triangle_count(), 1);
    assert_eq!(s.meshes[0].positions[1], Vec3::X);
    assert_eq!(s.emissive_triangles().len(), 1);

    // Without the BIN chunk the buffer cannot be resolved.
    let mut no_bin = glb[..12 + 8 + json_len].to_vec();
    let len = no_bin.len() as u32;
    no_bin[8..12].copy_from_slice(&len.to_le_bytes());
    let err = format!(
        "{:#}",
        Scene::from_gltf_slice(&no_bin, None, "tiny.glb").unwrap_err()
    );
    assert_contains(&err, &["tiny.glb", "buffer 0"]);

    // Chunk lengths that lie (the header's total length kept consistent with the file), each
    // named with its chunk and byte offset; before, some came out as "failed to fill whole buffer".
    let chunk_err = |bytes: &[u8]| format!("{:#}", Scene::from_gltf_slice(bytes, None, "tiny.glb").unwrap_err());
    let mut long_json = glb.clone();
    long_json[12..16].copy_from_slice(&((glb.len() - 20 + 1) as u32).to_le_bytes());
    assert_contains(&chunk_err(&long_json), &["tiny.glb", "GLB chunk 0 (\"JSON\") at byte 12 declares", "only"]);
    let mut short_json = glb.clone();
    short_json[12..16].copy_from_slice(&((json_len - 3) as u32).to_le_bytes());
    assert_contains(&chunk_err(&short_json), &["tiny.glb", "GLB chunk"]);
    let bin_at = 12 + 8 + json_len;
    let mut long_bin = glb.clone();
    long_bin[bin_at..bin_at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    assert_contains(&chunk_err(&long_bin), &["GLB chunk 1 (\"BIN\") at byte", "declares 4294967295 bytes"]);
    let mut bin_first = glb.clone();
    bin_first[16..20].copy_from_slice(b"BIN\0");
    assert_contains(&chunk_err(&bin_first), &["GLB chunk 0 is \"BIN\"", "must be JSON"]);
    // A byte-order mark opening the JSON chunk is ignored, as a .gltf's is ("expected value at
    // line 1 column 1" before): the JSON chunk again, with the mark and 4-byte padding.
    let json = std::str::from_utf8(&glb[20..20 + json_len]).unwrap().trim_end();
    let mut marked_json = [&b"\xEF\xBB\xBF"[..], json.as_bytes()].concat();
    while !marked_json.len().is_multiple_of(4) {
        marked_json.push(b' ');
    }
    let bin_chunk = &glb[bin_at..];
    let total = 12 + 8 + marked_json.len() + bin_chunk.len();
    let marked = [&b"glTF"[..], &2u32.to_le_bytes(), &(total as u32).to_le_bytes(), &(marked_json.len() as u32).to_le_bytes(), b"JSON", &marked_json, bin_chunk].concat();
    assert_eq!(Scene::from_gltf_slice(&marked, None, "bom.glb").unwrap().triangle_count(), 1);

    // Only buffer 0 may be the binary chunk: a later buffer without a URI took it (buffer 0 with
    // its own data URI), and after a buffer 0 that took it was told there was no binary chunk.
    let doc = triangle_doc();
    let uri = doc["buffers"][0]["uri"].as_str().unwrap().to_owned();
    let bin = base64::decode(uri.split_once(";base64,").unwrap().1).unwrap();
    let mut later = doc.clone();
    later["buffers"].as_array_mut().unwrap().push(json!({ "byteLength": bin.len() }));
    let (glb, _) = glb_of(&later, &bin);
    assert_contains(&chunk_err(&glb), &["buffer 1 has no \"uri\"", "only a .glb file's first buffer may omit it"]);
    let mut both = later.clone();
    both["buffers"][0].as_object_mut().unwrap().remove("uri");
    let (glb, _) = glb_of(&both, &bin);
    let e = chunk_err(&glb);
    assert!(e.contains("buffer 1 has no \"uri\"") && !e.contains("this file has no binary chunk"), "{e}");
}

#[test]
fn truncated_inputs_do_not_panic() {
    let (glb, _) = to_glb(triangle_doc());
    let text = triangle_doc().to_string();
    for len in 0..glb.len() {
        assert!(Scene::from_gltf_slice(&glb[..len], None, "cut.glb").is_err());
    }
    for len in (0..text.len()).step_by(7) {
        assert!(Scene::from_gltf_slice(&text.as_bytes()[..len], None, "cut.gltf").is_err());
    }
}

#[test]
fn external_buffer_file() {
    let mut doc = triangle_doc();
    let uri = doc["buffers"][0]["uri"].as_str().unwrap().to_owned();
    let bin = base64::decode(uri.split_once(";base64,").unwrap().1).unwrap();
    let dir = std::env::temp_dir().join(format!("restir-vpl-scene-test-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("sub dir")).unwrap();
    std::fs::write(dir.join("sub dir/data.bin"), &bin).unwrap();
    doc["buffers"][0]["uri"] = json!("sub%20dir/data.bin");
    let path = dir.join("ext.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    let s = Scene::load(&path);
    // A file longer than its buffer's byteLength is read up to it only (a 3 GB file behind a
    // 48-byte buffer was read whole).
    let mut long = bin.clone();
    long.extend(std::iter::repeat_n(0xabu8, 1 << 20));
    std::fs::write(dir.join("long.bin"), &long).unwrap();
    assert_eq!(crate::output::read_referenced(&dir.join("long.bin"), Some(bin.len() as u64)).unwrap(), bin);
    doc["buffers"][0]["uri"] = json!("long.bin");
    std::fs::write(&path, doc.to_string()).unwrap();
    let from_long = Scene::load(&path).map(|s| s.triangle_count());
    // A pipe is refused at once (it blocked the load for ever). If it were read, a writer opens it
    // after a while so that the test fails on the message instead of hanging.
    let fifo = dir.join("pipe.bin");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success());
    let from_pipe = made.then(|| {
        let unblock = fifo.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs(10));
            drop(std::fs::OpenOptions::new().write(true).open(unblock));
        });
        doc["buffers"][0]["uri"] = json!("pipe.bin");
        std::fs::write(&path, doc.to_string()).unwrap();
        Scene::load(&path).map(|_| ()).unwrap_err()
    });
    doc["buffers"][0]["uri"] = json!("sub%20dir/missing.bin");
    std::fs::write(&path, doc.to_string()).unwrap();
    let err = Scene::load(&path).map(|_| ()).unwrap_err();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(from_long.unwrap(), 1);
    let from_pipe = format!("{:#}", from_pipe.expect("mkfifo made a pipe"));
    assert_contains(&from_pipe, &["pipe.bin", "not a regular file"]);
    let s = s.unwrap();
    assert_eq!(s.triangle_count(), 1);
    assert_eq!(s.path, path);
    assert_contains(&format!("{err:#}"), &["ext.gltf", "missing.bin"]);
    // A NUL byte names no file; the message shows the URI as written, not the raw byte.
    doc["buffers"][0]["uri"] = json!("a%00b.bin");
    let err = format!("{:#}", Scene::from_gltf_slice(doc.to_string().as_bytes(), Some(Path::new("/tmp")), "nul.gltf").map(|_| ()).unwrap_err());
    assert_contains(&err, &["nul.gltf", "a%00b.bin", "control character"]);
    assert!(!err.contains('\0'), "{err:?}");
    // An absolute path, written plainly or percent-encoded, is refused before it is read (a
    // buffer naming /etc/passwd was read and failed later as an index out of range); a path up
    // and out of the file's directory stays a relative one.
    for uri in ["/etc/passwd", "%2Fetc%2Fpasswd", "\\\\server\\share\\x.bin"] {
        doc["buffers"][0]["uri"] = json!(uri);
        let err = format!("{:#}", Scene::from_gltf_slice(doc.to_string().as_bytes(), Some(Path::new("/tmp")), "abs.gltf").map(|_| ()).unwrap_err());
        assert_contains(&err, &["abs.gltf", "buffer 0", uri, "is an absolute path", "relative to the .gltf file"]);
    }
    doc["buffers"][0]["uri"] = json!("../no_such_dir_here/x.bin");
    let err = format!("{:#}", Scene::from_gltf_slice(doc.to_string().as_bytes(), Some(Path::new("/tmp/a")), "up.gltf").map(|_| ()).unwrap_err());
    assert_contains(&err, &["/tmp/a/../no_such_dir_here/x.bin"]);
    assert!(!err.contains("absolute"), "{err}");
}

// ---------------------------------------------------------------- builder

#[test]
fn builder_is_deterministic_and_valid() {
    let make = || {
        let mut b = GltfBuilder::new();
        let m = b.material("m", [0.1, 0.2, 0.3], [0.5, 0.0, 0.0], true);
        let mesh = closed_box(&mut b, "box", [-1.0; 3], [1.0; 3], m, false);
        b.node("box", mesh, [0.5, 0.0, 0.0]);
        b.camera("cam", [0.0, 0.0, 5.0], [0.0; 3], [0.0, 1.0, 0.0], 1.0);
        b.to_json_string()
    };
    let text = make();
    assert_eq!(text, make());
    assert!(text.ends_with('\n'));
    let doc: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(doc["accessors"][0]["min"], json!([-1.0, -1.0, -1.0]));
    assert_eq!(
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"],
        json!([0.1, 0.2, 0.3, 1.0])
    );
    let s = load_str(&text).unwrap();
    // Outward-facing box: all 12 triangle normals point away from the centre.
    let inst = &s.instances[0];
    for (c, n) in triangle_frames(&s, inst) {
        assert!(n.dot(c - Vec3::new(0.5, 0.0, 0.0)) > 0.0);
    }
}

#[test]
fn base64_round_trip() {
    for len in 0..20 {
        let data: Vec<u8> = (0..len as u8)
            .map(|i| i.wrapping_mul(37).wrapping_add(200))
            .collect();
        let text = base64::encode(&data);
        assert_eq!(text.len() % 4, 0);
        assert_eq!(base64::decode(&text).unwrap(), data);
    }
    assert_eq!(base64::encode(b"Man"), "TWFu");
    assert_eq!(base64::encode(b"Ma"), "TWE=");
    assert!(base64::decode("TW=u").is_err());
    assert!(base64::decode("T").is_err());
    // As lenient as data URIs in the wild need: no padding, whitespace, the URL-safe alphabet.
    assert_eq!(base64::decode("TWE").unwrap(), b"Ma");
    assert_eq!(base64::decode("TW\nFu").unwrap(), b"Man");
    assert_eq!(base64::decode("-_8=").unwrap(), base64::decode("+/8=").unwrap());
    assert_eq!(base64::decode("TWF=").unwrap(), b"Ma", "non-zero trailing bits");
}

#[test]
fn sparse_accessor() {
    let mut doc = triangle_doc();
    // Second buffer: sparse index 2 (u32) followed by the replacement value (0, 2, 0).
    let mut data = 2u32.to_le_bytes().to_vec();
    for f in [0.0f32, 2.0, 0.0] {
        data.extend_from_slice(&f.to_le_bytes());
    }
    doc["buffers"].as_array_mut().unwrap().push(json!({
        "byteLength": data.len(),
        "uri": format!("data:application/octet-stream;base64,{}", base64::encode(&data)),
    }));
    let views = doc["bufferViews"].as_array_mut().unwrap();
    views.push(json!({ "buffer": 1, "byteOffset": 0, "byteLength": 4 }));
    views.push(json!({ "buffer": 1, "byteOffset": 4, "byteLength": 12 }));
    doc["accessors"][0]["sparse"] = json!({
        "count": 1,
        "indices": { "bufferView": 2, "componentType": 5125 },
        "values": { "bufferView": 3 },
    });
    doc["accessors"][0]["max"] = json!([1.0, 2.0, 0.0]);
    let s = load_value(&doc).unwrap();
    assert_eq!(
        s.meshes[0].positions,
        [Vec3::ZERO, Vec3::X, Vec3::new(0.0, 2.0, 0.0)]
    );

    doc["accessors"][0]["sparse"]["count"] = json!(2);
    assert_contains(&load_err(&doc), &["sparse data exceeds buffer view"]);
}

#[test]
fn dangling_indices_are_errors_not_panics() {
    type Edit = fn(&mut Value);
    let edits: [(&str, Edit); 10] = [
        ("light", |d| {
            d["nodes"][0]["extensions"] = json!({ "KHR_lights_punctual": { "light": 9 } })
        }),
        ("camera", |d| d["nodes"][0]["camera"] = json!(9)),
        ("material", |d| {
            d["meshes"][0]["primitives"][0]["material"] = json!(9)
        }),
        ("scene", |d| d["scene"] = json!(9)),
        ("children", |d| d["nodes"][0]["children"] = json!([9])),
        ("accessor view", |d| {
            d["accessors"][0]["bufferView"] = json!(9)
        }),
        ("view buffer", |d| d["bufferViews"][0]["buffer"] = json!(9)),
        ("indices", |d| {
            d["meshes"][0]["primitives"][0]["indices"] = json!(9)
        }),
        ("normal", |d| {
            d["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(9)
        }),
        ("required extension", |d| {
            d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])
        }),
    ];
    for (what, edit) in edits {
        let mut doc = triangle_doc();
        edit(&mut doc);
        let err = load_err(&doc);
        assert!(err.contains("test.gltf: invalid glTF"), "{what}: {err}");
    }
}

// ---------------------------------------------------------------- thesis scenes
use super::generate::thesis::{
    FIGURE_MIN_TRIANGLES, FIGURE_NAME, FURNITURE_PREFIX, LIGHT_NAME, LIVING_ROOM_FURNITURE_PIECES,
    LIVING_ROOM_MAX, LIVING_ROOM_MIN, LIVING_ROOM_WINDOW_MAX, LIVING_ROOM_WINDOW_MIN, OPEN_BOX_MAX,
    OPEN_BOX_MIN, SCENE_ASPECT,
};

/// Checks that `scenes/<file>` is exactly `generate()` (rewriting it first with
/// `UPDATE_SCENES=1`) and that the generator is deterministic; returns the loaded scene.
fn committed_scene(file: &str, generate: fn() -> String) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(file);
    let generated = generate();
    assert_committed(&path, &generated);
    assert!(
        generated == generate(),
        "{file}: generator is not deterministic"
    );
    assert!(
        generated.len() < 4_500_000,
        "{file}: {} bytes",
        generated.len()
    );
    Scene::load(&path).unwrap()
}

fn open_box_scene() -> Scene {
    load_str(&open_box_figure_gltf()).expect("open box loads")
}

fn living_room_scene() -> Scene {
    load_str(&living_room_gltf()).expect("living room loads")
}

/// The scene's single area light: exactly two emissive triangles, both from the instance
/// named [`LIGHT_NAME`], coplanar with equal normals and sharing an edge (one quad).
/// Returns its four distinct corners and its front-face normal.
fn single_light_quad(s: &Scene) -> (Vec<Vec3>, Vec3) {
    let tris = s.emissive_triangles();
    assert_eq!(tris.len(), 2, "one quad light");
    for t in &tris {
        assert_eq!(s.instances[t.instance as usize].name, LIGHT_NAME);
        assert!(t.normal.abs_diff_eq(tris[0].normal, 1e-5));
        assert!(t.emission.min_element() > 0.0);
    }
    let mut corners: Vec<Vec3> = Vec::new();
    for p in tris.iter().flat_map(|t| t.p) {
        if !corners.iter().any(|c| c.abs_diff_eq(p, 1e-6)) {
            corners.push(p);
        }
    }
    assert_eq!(corners.len(), 4, "two triangles sharing an edge");
    (corners, tris[0].normal)
}

/// Whether any part of the convex planar polygon `poly` (world space) lies inside the view
/// frustum of `cam` for an image of aspect `aspect` (width / height; `yfov` is vertical).
/// The polygon is taken to camera space (camera looks down -Z) and clipped
/// (Sutherland-Hodgman) against the near plane `z <= -1e-3` and the four side planes
/// `|x| <= -z tan(yfov/2) aspect`, `|y| <= -z tan(yfov/2)`; it is outside the frustum
/// exactly when nothing is left. (Checking only the vertices would miss a large quad that
/// straddles the view with all corners outside it.)
fn polygon_in_frustum(cam: &Camera, aspect: f32, poly: &[Vec3]) -> bool {
    let view = cam.transform.inverse();
    let ty = (0.5 * cam.yfov).tan();
    let tx = ty * aspect;
    // Plane functions, >= 0 inside.
    let planes: [Box<dyn Fn(Vec3) -> f32>; 5] = [
        Box::new(|p: Vec3| -p.z - 1e-3),
        Box::new(move |p: Vec3| -p.z * tx - p.x),
        Box::new(move |p: Vec3| -p.z * tx + p.x),
        Box::new(move |p: Vec3| -p.z * ty - p.y),
        Box::new(move |p: Vec3| -p.z * ty + p.y),
    ];
    let mut pts: Vec<Vec3> = poly.iter().map(|&p| view.transform_point3(p)).collect();
    for plane in &planes {
        let mut out = Vec::new();
        for i in 0..pts.len() {
            let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
            let (da, db) = (plane(a), plane(b));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (b - a) * (da / (da - db)));
            }
        }
        pts = out;
        if pts.is_empty() {
            return false;
        }
    }
    true
}

/// Camera-space position of a world point, divided by its depth: (x / -z, y / -z, -z).
fn project(cam: &Camera, p: Vec3) -> Vec3 {
    let c = cam.transform.inverse().transform_point3(p);
    Vec3::new(c.x / -c.z, c.y / -c.z, -c.z)
}

/// World-space bounds of the instances whose names start with `prefix`.
fn bounds_of(s: &Scene, prefix: &str) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for inst in s.instances.iter().filter(|i| i.name.starts_with(prefix)) {
        for &p in &s.meshes[inst.mesh].positions {
            let w = inst.transform.transform_point3(p);
            lo = lo.min(w);
            hi = hi.max(w);
        }
    }
    assert!(lo.x <= hi.x, "no instance named {prefix}*");
    (lo, hi)
}

/// Parameter t in (0, 1) where the segment `a -> b` hits triangle `p`, if it does
/// (Möller-Trumbore, both faces).
fn segment_hits(a: Vec3, b: Vec3, p: [Vec3; 3]) -> Option<f32> {
    let d = b - a;
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let h = d.cross(e2);
    let det = e1.dot(h);
    if det.abs() < 1e-12 {
        return None;
    }
    let s = a - p[0];
    let u = s.dot(h) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let t = e2.dot(q) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 1e-4 && t < 1.0 - 1e-4).then_some(t)
}

/// Names of the instances that the segment `a -> b` passes through.
fn occluders(s: &Scene, a: Vec3, b: Vec3) -> Vec<String> {
    let mut hit = Vec::new();
    for inst in &s.instances {
        let mesh = &s.meshes[inst.mesh];
        for t in 0..mesh.triangle_count() {
            let p = mesh
                .triangle(t)
                .unwrap()
                .map(|v| inst.transform.transform_point3(v));
            if segment_hits(a, b, p).is_some() && !hit.contains(&inst.name) {
                hit.push(inst.name.clone());
            }
        }
    }
    hit
}

/// Every vertex normal present is unit length (no zero or NaN normals from the generators).
fn assert_unit_normals(s: &Scene) {
    for m in &s.meshes {
        assert_eq!(m.normals.len(), m.positions.len());
        for n in &m.normals {
            assert!(
                (n.length() - 1.0).abs() < 1e-3,
                "mesh {}: normal {n}",
                m.name
            );
        }
    }
}

#[test]
fn open_box_figure_file_matches_generator() {
    let s = committed_scene("open_box_figure.gltf", open_box_figure_gltf);
    assert_eq!(s.triangle_count(), open_box_scene().triangle_count());
}

#[test]
fn living_room_file_matches_generator() {
    let s = committed_scene("living_room.gltf", living_room_gltf);
    assert_eq!(s.triangle_count(), living_room_scene().triangle_count());
}

#[test]
fn open_box_figure_structure() {
    let s = open_box_scene();
    let figure = instance_named(&s, FIGURE_NAME);
    let n = s.meshes[figure.mesh].triangle_count();
    assert!(n >= FIGURE_MIN_TRIANGLES, "figure has {n} triangles");
    assert!(s.triangle_count() < 100_000);
    for name in [
        "floor",
        "back_wall",
        "left_wall",
        "right_wall_red",
        "sphere",
        "cube",
        "cylinder",
        "cone",
    ] {
        instance_named(&s, name);
    }
    assert_unit_normals(&s);

    // Walls face the box's interior; the red wall is at +x, on the right of the image.
    let (lo, hi) = (Vec3::from(OPEN_BOX_MIN), Vec3::from(OPEN_BOX_MAX));
    let centre = 0.5 * (lo + hi);
    for name in ["floor", "back_wall", "left_wall", "right_wall_red"] {
        for (c, n) in triangle_frames(&s, instance_named(&s, name)) {
            assert!(
                n.dot(centre - c) > 0.0,
                "{name} faces away from the interior"
            );
        }
    }
    let red = instance_named(&s, "right_wall_red");
    let material = &s.materials[s.meshes[red.mesh].triangle_materials[0] as usize];
    assert!(
        material.base_color.x > 0.5 && material.base_color.y < 0.15 && material.base_color.z < 0.15
    );
    let cam = s.camera.as_ref().expect("camera");
    assert!(
        project(cam, instance_centroid(&s, red)).x > 0.0,
        "red wall on screen right"
    );
    // Open at the top and the front: no geometry above the walls or in front of the box.
    for inst in s.instances.iter().filter(|i| i.name != LIGHT_NAME) {
        let (ilo, ihi) = bounds_of(&s, &inst.name);
        assert!(
            ihi.y <= hi.y + 1e-4 && ihi.z <= hi.z + 1e-4,
            "{} sticks out",
            inst.name
        );
        assert!(ilo.cmpge(lo - 1e-4).all(), "{} outside the box", inst.name);
    }

    // The figure, in the middle of the image.
    let (flo, fhi) = bounds_of(&s, FIGURE_NAME);
    let f = project(cam, 0.5 * (flo + fhi));
    assert!(f.x.abs() < 0.2 && f.y.abs() < 0.2, "figure at {f}");

    // One area light, entirely outside the view frustum at 16:9, shining into the box.
    let (corners, normal) = single_light_quad(&s);
    assert!(
        !polygon_in_frustum(cam, SCENE_ASPECT, &corners),
        "light visible"
    );
    let lc = corners.iter().sum::<Vec3>() / 4.0;
    assert!(
        normal.dot(centre - lc) > 0.5 * (centre - lc).length(),
        "light not aimed into the box"
    );
    assert!(
        occluders(&s, lc, centre).is_empty(),
        "{:?}",
        occluders(&s, lc, centre)
    );
    assert!(
        corners.iter().all(|c| c.y > hi.y || c.z > hi.z),
        "light inside the box"
    );
    let area = (corners[1] - corners[0])
        .cross(corners[3] - corners[0])
        .length();
    assert!(area > 1.0, "a large light: {area} m^2");
}

#[test]
fn living_room_structure() {
    let s = living_room_scene();
    assert_unit_normals(&s);
    // Furniture: every part instance is named `<piece>/<part>` with the prefix.
    let mut pieces: Vec<&str> = s
        .instances
        .iter()
        .filter(|i| i.name.starts_with(FURNITURE_PREFIX))
        .map(|i| i.name.split('/').next().unwrap())
        .collect();
    pieces.dedup();
    let mut sorted = pieces.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), pieces.len(), "parts of a piece are adjacent");
    assert_eq!(pieces.len(), LIVING_ROOM_FURNITURE_PIECES);
    assert!(pieces.len() >= 20);
    for piece in [
        "furniture_couch",
        "furniture_dining_table",
        "furniture_coffee_table",
        "furniture_tv",
        "furniture_rug",
    ] {
        assert!(pieces.contains(&piece), "{piece}");
    }

    // The room: everything but the light inside it.
    let (lo, hi) = (Vec3::from(LIVING_ROOM_MIN), Vec3::from(LIVING_ROOM_MAX));
    let (wlo, whi) = (
        Vec3::from(LIVING_ROOM_WINDOW_MIN),
        Vec3::from(LIVING_ROOM_WINDOW_MAX),
    );
    let window = 0.5 * (wlo + whi);
    for inst in s.instances.iter().filter(|i| i.name != LIGHT_NAME) {
        let (ilo, ihi) = bounds_of(&s, &inst.name);
        let slack = Vec3::new(0.25, 1e-3, 1e-3); // the window reveal sticks out in +x
        assert!(
            ilo.cmpge(lo - slack).all() && ihi.cmple(hi + slack).all(),
            "{} outside the room",
            inst.name
        );
    }
    let centre = 0.5 * (lo + hi);
    for (c, n) in triangle_frames(&s, instance_named(&s, "floor")) {
        assert!(n.dot(centre - c) > 0.0);
    }
    for (c, n) in triangle_frames(&s, instance_named(&s, "ceiling")) {
        assert!(n.dot(centre - c) > 0.0);
    }
    // Walls: the ones on the room's faces point inward.
    for (c, n) in triangle_frames(&s, instance_named(&s, "walls")) {
        let on_face = [c.x - lo.x, hi.x - c.x, c.z - lo.z, hi.z - c.z]
            .iter()
            .any(|d| d.abs() < 1e-4);
        if on_face {
            assert!(n.dot(centre - c) > 0.0, "wall triangle at {c} faces out");
        }
    }

    // One area light, outside the room, facing the window, not occluded from it,
    // and outside the view frustum at 16:9.
    let (corners, normal) = single_light_quad(&s);
    for c in &corners {
        assert!(
            c.x > hi.x + 0.2 || c.y > hi.y,
            "light corner {c} inside the room or its wall"
        );
    }
    let (llo, lhi) = bounds_of(&s, LIGHT_NAME);
    assert!(
        llo.x > hi.x || lhi.x < lo.x || llo.y > hi.y || llo.z > hi.z || lhi.z < lo.z,
        "light AABB overlaps the room"
    );
    let lc = corners.iter().sum::<Vec3>() / 4.0;
    assert!(
        normal.dot(window - lc) > 0.0,
        "light faces away from the window"
    );
    // A point in the middle of a pane (the window's centre is behind the frame's cross).
    let pane = wlo + 0.25 * (whi - wlo);
    let sunlit = Vec3::new(1.2, 0.0, 0.0);
    assert!(
        occluders(&s, lc, pane).is_empty(),
        "{:?}",
        occluders(&s, lc, pane)
    );
    assert_eq!(
        occluders(&s, lc, sunlit + Vec3::Y * 0.01),
        Vec::<String>::new(),
        "window light reaches the floor"
    );
    let cam = s.camera.as_ref().expect("camera");
    assert!(
        !polygon_in_frustum(cam, SCENE_ASPECT, &corners),
        "light visible"
    );
    // The camera is inside the room and sees the couch and the dining table.
    let eye = cam.transform.transform_point3(Vec3::ZERO);
    assert!(eye.cmpgt(lo).all() && eye.cmplt(hi).all());
    let ty = (0.5 * cam.yfov).tan();
    for piece in [
        "furniture_couch/",
        "furniture_dining_table/",
        "furniture_tv/",
    ] {
        let (plo, phi) = bounds_of(&s, piece);
        let p = project(cam, 0.5 * (plo + phi));
        assert!(
            p.x.abs() < ty * SCENE_ASPECT && p.y.abs() < ty && p.z > 0.0,
            "{piece} out of view: {p}"
        );
    }
    // The floor behind the couch (between its back and the left wall) sees no part of the
    // light: only bounced light reaches it.
    let (clo, chi) = bounds_of(&s, "furniture_couch/");
    let behind = Vec3::new(0.5 * (lo.x + clo.x), 0.01, 0.5 * (clo.z + chi.z));
    assert!(clo.x - lo.x > 0.1, "a gap behind the couch");
    for c in corners.iter().chain([&lc]) {
        assert!(
            !occluders(&s, *c, behind).is_empty(),
            "light reaches behind the couch"
        );
    }
}

/// The textured materials (floor, rug, painting) reference valid textures, images and a
/// sampler; their meshes carry TEXCOORD_0; images are embedded PNGs that decode; buffer
/// views are 4-byte aligned. Checked on the JSON since the loader may ignore textures.
#[test]
fn living_room_textures_are_valid() {
    let text = living_room_gltf();
    let doc: Value = serde_json::from_str(&text).unwrap();
    let uri = doc["buffers"][0]["uri"].as_str().unwrap();
    let buffer = base64::decode(uri.split_once("base64,").unwrap().1).unwrap();
    assert_eq!(
        buffer.len() as u64,
        doc["buffers"][0]["byteLength"].as_u64().unwrap()
    );
    let views = doc["bufferViews"].as_array().unwrap();
    for v in views {
        assert_eq!(v["byteOffset"].as_u64().unwrap() % 4, 0);
    }
    let textures = doc["textures"].as_array().unwrap();
    let images = doc["images"].as_array().unwrap();
    let samplers = doc["samplers"].as_array().unwrap();
    assert_eq!(samplers.len(), 1);
    assert_eq!(samplers[0]["wrapS"], json!(10497));
    let mut textured = Vec::new();
    for (mi, m) in doc["materials"].as_array().unwrap().iter().enumerate() {
        let Some(info) = m["pbrMetallicRoughness"].get("baseColorTexture") else {
            continue;
        };
        textured.push((mi, m["name"].as_str().unwrap().to_string()));
        assert_eq!(info["texCoord"], json!(0));
        let t = &textures[info["index"].as_u64().unwrap() as usize];
        assert!((t["sampler"].as_u64().unwrap() as usize) < samplers.len());
        let image = &images[t["source"].as_u64().unwrap() as usize];
        assert_eq!(image["mimeType"], json!("image/png"));
        let v = &views[image["bufferView"].as_u64().unwrap() as usize];
        let start = v["byteOffset"].as_u64().unwrap() as usize;
        let bytes = &buffer[start..start + v["byteLength"].as_u64().unwrap() as usize];
        let decoded = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).unwrap();
        assert!(decoded.width() >= 64 && decoded.width() <= 256 && decoded.height() >= 64);
    }
    let names: Vec<&str> = textured.iter().map(|(_, n)| n.as_str()).collect();
    assert_eq!(names, ["floor_wood", "rug", "painting"]);
    // Every primitive with a textured material has TEXCOORD_0, with one UV per position.
    let mut uses = 0;
    for mesh in doc["meshes"].as_array().unwrap() {
        for prim in mesh["primitives"].as_array().unwrap() {
            let m = prim["material"].as_u64().unwrap() as usize;
            if textured.iter().any(|(mi, _)| *mi == m) {
                uses += 1;
                let attrs = &prim["attributes"];
                let uv =
                    &doc["accessors"][attrs["TEXCOORD_0"].as_u64().expect("TEXCOORD_0") as usize];
                let pos = &doc["accessors"][attrs["POSITION"].as_u64().unwrap() as usize];
                assert_eq!(uv["type"], json!("VEC2"));
                assert_eq!(uv["count"], pos["count"]);
            }
        }
    }
    assert_eq!(uses, 3);
    // The loaded scene keeps the material's texture reference.
    let s = living_room_scene();
    let floor = instance_named(&s, "floor");
    let mat = &s.materials[s.meshes[floor.mesh].triangle_materials[0] as usize];
    assert!(mat.base_color_texture.is_some());
    assert!(s.meshes[floor.mesh].uvs.iter().any(|uv| uv.x.abs() > 1.0));
}

#[test]
fn builder_textures_and_uvs() {
    let make = || {
        let mut b = GltfBuilder::new();
        let rgba: Vec<u8> = (0..3 * 2 * 4).map(|i| (i * 10) as u8).collect();
        let t = b.texture_png("tiny", 3, 2, &rgba);
        let t2 = b.texture_png("tiny2", 1, 1, &[1, 2, 3, 255]);
        let m = b.textured_material("tex", [1.0, 0.5, 1.0], t2, true);
        let mesh = b.mesh_with_uvs(
            "tri",
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            None,
            &[[0.0, 0.0], [2.0, 0.0], [0.0, 0.5]],
            &[0, 1, 2],
            m,
        );
        b.node("tri", mesh, [0.0; 3]);
        (t, t2, b.to_json_string())
    };
    let (t, t2, text) = make();
    assert_eq!((t, t2), (0, 1));
    assert_eq!(text, make().2);
    let doc: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(doc["textures"].as_array().unwrap().len(), 2);
    assert_eq!(doc["images"].as_array().unwrap().len(), 2);
    assert_eq!(
        doc["samplers"].as_array().unwrap().len(),
        1,
        "one shared sampler"
    );
    assert_eq!(doc["textures"][1]["source"], json!(1));
    assert_eq!(
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"],
        json!({ "index": 1, "texCoord": 0 })
    );
    assert_eq!(doc["materials"][0]["doubleSided"], json!(true));
    assert!(doc["images"][0].get("uri").is_none());
    assert!(
        doc["bufferViews"][0].get("target").is_none(),
        "image views have no target"
    );
    for v in doc["bufferViews"].as_array().unwrap() {
        assert_eq!(v["byteOffset"].as_u64().unwrap() % 4, 0);
    }
    let s = load_str(&text).unwrap();
    assert_eq!(s.meshes[0].uvs[1], glam::Vec2::new(2.0, 0.0));
    assert!(s.materials[0].base_color_texture.is_some());
    // Without textures, none of the new arrays appear.
    let plain: Value = serde_json::from_str(&cornell_box_gltf()).unwrap();
    for key in ["textures", "images", "samplers"] {
        assert!(plain.get(key).is_none());
    }
}

// ---------------------------------------------------------------- input validation

/// The Cornell box as JSON, for editing.
fn cornell_doc() -> Value {
    serde_json::from_str(&cornell_box_gltf()).unwrap()
}

/// Index of the Cornell box's node called `name`.
fn cornell_node(doc: &Value, name: &str) -> usize {
    doc["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .position(|n| n["name"] == json!(name))
        .unwrap_or_else(|| panic!("no node {name}"))
}

/// A camera node whose transform leaves no finite basis (zero scale, a scale whose squares
/// underflow f32, a zero matrix) rendered a black image with exit 0: now an error naming the
/// file and the node. A zero rotation quaternion was taken as the identity: now an error too;
/// a non-unit one is normalised.
#[test]
fn degenerate_camera_transform_is_an_error() {
    let cam = cornell_node(&cornell_doc(), "camera");
    for (key, value) in [
        ("scale", json!([0.0, 0.0, 0.0])),
        ("scale", json!([1e-30, 1e-30, 1e-30])),
        ("scale", json!([1.0, 1.0, 0.0])),
        ("matrix", json!([0.0f32; 16].to_vec())),
    ] {
        let mut doc = cornell_doc();
        if key == "matrix" {
            let node = doc["nodes"][cam].as_object_mut().unwrap();
            node.remove("rotation");
            node.remove("translation");
        }
        doc["nodes"][cam][key] = value.clone();
        let err = load_err(&doc);
        assert_contains(
            &err,
            &["test.gltf: camera node 'camera'", "degenerate transform", "non-finite or zero-length basis"],
        );
        assert!(!err.contains("NaN"), "{key} {value}: {err}");
    }
    // A parent's degenerate transform counts too.
    let mut doc = cornell_doc();
    doc["nodes"].as_array_mut().unwrap().push(json!({ "name": "rig", "scale": [0.0, 0.0, 0.0], "children": [cam] }));
    let rig = doc["nodes"].as_array().unwrap().len() - 1;
    doc["scenes"][0]["nodes"].as_array_mut().unwrap().retain(|n| n != &json!(cam));
    doc["scenes"][0]["nodes"].as_array_mut().unwrap().push(json!(rig));
    assert_contains(&load_err(&doc), &["camera node 'camera'", "degenerate transform"]);

    let mut doc = cornell_doc();
    doc["nodes"][cam]["rotation"] = json!([0.0, 0.0, 0.0, 0.0]);
    assert_contains(
        &load_err(&doc),
        &["test.gltf: node 'camera': rotation quaternion [0, 0, 0, 0] has length 0", "unit quaternion"],
    );

    // A non-unit quaternion is normalised: the same camera as the unit one.
    let expected = cornell().camera.unwrap().transform;
    let mut doc = cornell_doc();
    doc["nodes"][cam]["rotation"] = json!([0.0, 3.0, 0.0, 0.0]);
    let s = load_value(&doc).unwrap();
    assert!(s.camera.unwrap().transform.abs_diff_eq(expected, EPS));
    assert_contains(&s.warnings.join("\n"), &["test.gltf: node 'camera': rotation quaternion [0, 3, 0, 0] has length 3", "normalised"]);
    doc["nodes"][cam]["rotation"] = json!([0.0, 1.0000001, 0.0, 0.0]);
    let s = load_value(&doc).unwrap();
    assert!(s.camera.unwrap().transform.abs_diff_eq(expected, EPS));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

/// The same degenerate transforms on a mesh node (NaN normals on the GPU) and one that takes
/// finite vertices to Inf are errors naming the node and the mesh; non-finite positions in the
/// file stay a warning, which now names the file.
#[test]
fn degenerate_mesh_transform_is_an_error() {
    let floor = cornell_node(&cornell_doc(), "floor");
    // A zero scale (or matrix) is how exporters hide a node: skipped with a warning.
    for (key, value) in [("scale", json!([0.0, 0.0, 0.0])), ("matrix", json!([0.0f32; 16].to_vec()))] {
        let mut doc = cornell_doc();
        doc["nodes"][floor][key] = value;
        let s = load_value(&doc).unwrap();
        assert_contains(&s.warnings.join("\n"), &["test.gltf: node 'floor' (mesh 'floor'): scaled to nothing (zero scale), skipped"]);
        assert!(s.instances.iter().all(|i| i.name != "floor"), "the hidden floor is not rendered");
    }
    // Anything else that cannot be inverted is an error.
    for (key, value) in [("scale", json!([1e-30, 1e-30, 1e-30])), ("scale", json!([1.0, 0.0, 1.0]))] {
        let mut doc = cornell_doc();
        doc["nodes"][floor][key] = value;
        assert_contains(
            &load_err(&doc),
            &["test.gltf: node 'floor' (mesh 'floor')", "degenerate transform", "cannot be inverted"],
        );
    }
    let mut doc = cornell_doc();
    doc["nodes"][floor]["scale"] = json!([1e38, 1.0, 1.0]);
    doc["nodes"][floor]["translation"] = json!([3e38, 0.0, 0.0]);
    assert_contains(&load_err(&doc), &["test.gltf: node 'floor' (mesh 'floor')", "non-finite position"]);
    // A number beyond f32 in the node's own properties is named (it was "non-finite world
    // matrix, columns [NaN, ...]").
    for (key, value) in [("translation", json!([1e39, 0.0, 0.0])), ("scale", json!([1.0, -1e39, 1.0])), ("matrix", json!([1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1e40, 0.0, 1.0]))] {
        let mut doc = cornell_doc();
        doc["nodes"][floor][key] = value;
        assert_contains(&load_err(&doc), &["node 'floor'", &format!("its {key} has a value outside the 32-bit float range")]);
    }
    // Past the mesh box's quick bound but finite at every vertex: beyond the 1e18 rays reach.
    let mut doc = cornell_doc();
    doc["nodes"][floor]["translation"] = json!([1e38, 0.0, 0.0]);
    assert_contains(&load_err(&doc), &["test.gltf: its geometry", "more than 1e18 from the origin"]);

    // A triangle with a NaN vertex goes (in one BLAS its NaN bounds blacked out the whole
    // scene), the primitive's other triangle stays, and no non-finite position is left behind
    // for the bounds.
    let mut b = GltfBuilder::new();
    let m = b.material("glow", [0.5; 3], [2.0, 1.0, 0.5], false);
    let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [f32::NAN, 1.0, 0.0]];
    let mesh = b.mesh("tri", &p, None, &[0, 1, 2, 1, 3, 2], m);
    b.node("tri", mesh, [0.0; 3]);
    let mut doc: Value = serde_json::from_str(&b.to_json_string()).unwrap();
    let pos = doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap() as usize;
    (doc["accessors"][pos]["min"], doc["accessors"][pos]["max"]) = (json!([0.0, 0.0, 0.0]), json!([1.0, 1.0, 0.0]));
    let s = load_value(&doc).unwrap();
    assert_contains(
        &s.warnings.join("\n"),
        &["test.gltf: mesh 'tri' primitive 0: 1 non-finite vertex position (NaN or infinite): 1 of its 2 triangles dropped"],
    );
    assert_eq!(s.meshes[0].indices, [0, 1, 2]);
    assert!(s.meshes[0].positions.iter().all(|p| p.is_finite()), "{:?}", s.meshes[0].positions);
    assert_eq!(s.emissive_triangles().len(), 1);
}

/// Non-finite NORMAL and TEXCOORD_0 values are replaced (zero normal: the shader's "no normal";
/// uv (0, 0)) with a warning naming the primitive and the count: an infinite normal used to reach
/// the shading normal as NaN.
#[test]
fn non_finite_normals_and_uvs_are_replaced_with_a_warning() {
    let mut b = GltfBuilder::new();
    let m = b.material("grey", [0.5; 3], [0.0; 3], false);
    let mesh = b.mesh_with_uvs(
        "tri",
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        Some(&[[0.0, 0.0, 1.0], [f32::INFINITY, 0.0, 1.0], [f32::NAN, 0.0, 0.0]]),
        &[[0.0, 0.0], [f32::NAN, 0.5], [1.0, f32::NEG_INFINITY]],
        &[0, 1, 2],
        m,
    );
    b.node("tri", mesh, [0.0; 3]);
    let s = load_value(&serde_json::from_str(&b.to_json_string()).unwrap()).unwrap();
    assert_contains(
        &s.warnings.join("\n"),
        &[
            "test.gltf: mesh 'tri' primitive 0: 2 of 3 NORMAL values are not finite; replaced by zero (no shading normal)",
            "test.gltf: mesh 'tri' primitive 0: 2 of 3 TEXCOORD_0 values are not finite; replaced by (0, 0)",
        ],
    );
    let mesh = &s.meshes[0];
    assert_eq!(mesh.normals, vec![Vec3::Z, Vec3::ZERO, Vec3::ZERO]);
    assert_eq!(mesh.uvs, vec![Vec2::ZERO, Vec2::ZERO, Vec2::ZERO]);
}

/// glTF 2.0 restricts baseColorFactor to [0, 1]: [-1, …] gave negative radiance, 1e30 non-finite
/// samples.
#[test]
fn base_color_factor_outside_unit_range_is_an_error() {
    for (factor, shown) in [
        (json!([-1.0, -1.0, -1.0, 1.0]), "[-1, -1, -1, 1]"),
        (json!([5.0, 5.0, 5.0, 1.0]), "[5, 5, 5, 1]"),
        (json!([1e30, 1e30, 1e30, 1.0]), "[1e30, 1e30, 1e30, 1]"),
        (json!([0.5, 0.5, 0.5, 1.5]), "[0.5, 0.5, 0.5, 1.5]"),
        (json!([1e39, 0.5, 0.5, 1.0]), "[inf, 0.5, 0.5, 1]"),
    ] {
        let mut doc = cornell_doc();
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = factor;
        let err = load_err(&doc);
        assert!(
            err == format!("test.gltf: material 'white': baseColorFactor {shown} must lie in [0, 1]"),
            "{err}"
        );
    }
    let mut doc = cornell_doc();
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = json!([0.0, 0.0, 0.0, 0.0]);
    doc["materials"][1]["pbrMetallicRoughness"]["baseColorFactor"] = json!([1.0, 1.0, 1.0, 1.0]);
    let s = load_value(&doc).unwrap();
    assert_eq!(s.materials[1].base_color, glam::Vec4::ONE);
}

/// A light scaled by 1e14 (or a whole scene by 1e11) overflowed the f32 cross product of its
/// edges: the area was Inf and the light silently left out. Areas and normals are now computed in
/// f64; an area beyond f32 is an error naming the mesh.
#[test]
fn large_scale_scenes_keep_their_lights() {
    let base = cornell();
    let base_light = base.emissive_triangles();
    assert_eq!(base_light.len(), 2);

    let light = cornell_node(&cornell_doc(), "light");
    let mut doc = cornell_doc();
    doc["nodes"][light]["scale"] = json!([1e14, 1e14, 1e14]);
    let s = load_value(&doc).unwrap();
    let tris = s.emissive_triangles();
    assert_eq!(tris.len(), 2);
    for (t, b) in tris.iter().zip(&base_light) {
        assert!((t.area / (b.area * 1e28) - 1.0).abs() < 1e-4, "{} vs {}", t.area, b.area);
        assert!(t.normal.abs_diff_eq(b.normal, EPS), "{}", t.normal);
    }

    let mut doc = cornell_doc();
    for node in doc["nodes"].as_array_mut().unwrap() {
        node["scale"] = json!([1e11, 1e11, 1e11]);
    }
    let s = load_value(&doc).unwrap();
    let tris = s.emissive_triangles();
    assert_eq!(tris.len(), 2);
    assert!((tris[0].area / (base_light[0].area * 1e22) - 1.0).abs() < 1e-4);
    let ratio = s.surface_area() / (base.surface_area() * 1e22);
    assert!((ratio - 1.0).abs() < 1e-4, "surface area ratio {ratio}");

    // Beyond 1.8e19 the transform's f32 inverse (the renderer's normal matrix) is NaN.
    let mut doc = cornell_doc();
    doc["nodes"][light]["scale"] = json!([1e21, 1e21, 1e21]);
    assert_contains(&load_err(&doc), &["test.gltf: node 'light' (mesh 'light')", "degenerate transform", "huge scale"]);

    // An emitter whose vertices are huge in the file (its area would not fit f32): beyond the
    // 1e18 that rays reach, which refuses it first.
    let mut b = GltfBuilder::new();
    let m = b.material("hot", [0.5; 3], [1e-30; 3], false);
    let mesh = b.mesh("huge", &[[0.0; 3], [1e20, 0.0, 0.0], [0.0, 1e20, 0.0]], None, &[0, 1, 2], m);
    b.node("huge_node", mesh, [0.0; 3]);
    assert_contains(
        &load_err(&serde_json::from_str(&b.to_json_string()).unwrap()),
        &["test.gltf: its geometry (bounding box corner) lies at", "more than 1e18"],
    );
}

/// Merging a scene whose instance transform's determinant overflows f32 keeps unit normals
/// (the f32 inverse was zero).
#[test]
fn large_scale_merge_keeps_normals() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [0.0; 3], false);
    let pos = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mesh = b.mesh("tri", &pos, Some(&[[0.0, 0.0, 1.0]; 3]), &[0, 1, 2], m);
    b.node_matrix("big", mesh, Mat4::from_scale(Vec3::new(1e14, 1e14, -1e14)).to_cols_array());
    b.node("plain", mesh, [0.0; 3]);
    let s = load_str(&b.to_json_string()).unwrap();
    let merged = s.merged();
    let normals = &merged.meshes.last().unwrap().normals;
    assert!(normals[..3].iter().all(|n| n.abs_diff_eq(Vec3::NEG_Z, EPS)), "{normals:?}");
    assert!(normals[3..].iter().all(|n| *n == Vec3::Z), "{normals:?}");
}

/// glTF 1.0 (and any other major version) is a different format.
#[test]
fn asset_version_other_than_2_is_an_error() {
    for version in ["1.0", "3.0", "two"] {
        let mut doc = cornell_doc();
        doc["asset"]["version"] = json!(version);
        assert_contains(
            &load_err(&doc),
            &[&format!("test.gltf: asset.version '{version}' is not supported"), "glTF 2.x"],
        );
    }
    // A real glTF 1.0 file fails the 2.0 schema first: the version is still what is reported.
    let v1 = json!({ "asset": { "version": "1.0" }, "meshes": { "m": { "primitives": [] } } });
    assert_contains(&load_err(&v1), &["asset.version '1.0' is not supported"]);
    let mut doc = cornell_doc();
    doc["asset"]["minVersion"] = json!("2.1");
    assert_contains(&load_err(&doc), &["asset.minVersion '2.1' is not supported"]);
    doc["asset"]["version"] = json!("2.1");
    doc["asset"]["minVersion"] = json!("2.0");
    assert!(load_value(&doc).is_ok());
}

/// A base colour texture on a primitive without TEXCOORD_0 is sampled at uv (0, 0): a warning,
/// like the other texture features the renderer lacks.
#[test]
fn texture_without_texcoords_warns() {
    let mut doc = triangle_doc();
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    doc["textures"] = json!([{ "source": 0 }]);
    doc["images"] = json!([{ "uri": png_data_uri(1, 1, &[1, 2, 3, 255]) }]);
    let s = load_value(&doc).unwrap();
    assert_eq!(s.materials[0].base_color_texture, Some(0));
    assert_contains(
        &s.warnings.join("\n"),
        &["test.gltf: mesh 'tri' primitive 0: material 'glow' has a base colour texture but the primitive has no \
           TEXCOORD_0; the texture is sampled at uv (0, 0)"],
    );
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
}

/// What the loader reads other than as written is said: an optional extension it does not
/// support (KHR_texture_transform moved no texture), a node with both a matrix and TRS (glTF
/// forbids it; the matrix wins), a projective node matrix (read as affine), and an emissive
/// texture (the whole surface emits the factor). Supported extensions stay silent.
#[test]
fn content_read_otherwise_than_written_is_warned_about() {
    let mut b = GltfBuilder::new();
    let texture = b.texture_png("t", 1, 1, &[255, 255, 255, 255]);
    let m = b.material("glow", [0.5; 3], [2.0, 1.0, 0.5], false);
    let mesh = b.mesh("tri", &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], None, &[0, 1, 2], m);
    let mut identity = [0.0f32; 16];
    for i in 0..4 {
        identity[5 * i] = 1.0;
    }
    b.node_matrix("both", mesh, identity);
    let mut projective = identity;
    projective[11] = 0.5;
    b.node_matrix("projective", mesh, projective);
    let mut doc: Value = serde_json::from_str(&b.to_json_string()).unwrap();
    doc["extensionsUsed"] = json!(["KHR_texture_transform", "KHR_materials_emissive_strength"]);
    let both = doc["nodes"].as_array().unwrap().iter().position(|n| n["name"] == "both").unwrap();
    doc["nodes"][both]["translation"] = json!([1.0, 0.0, 0.0]);
    doc["materials"][m]["emissiveTexture"] = json!({ "index": texture });
    let w = load_value(&doc).unwrap().warnings.join("\n");
    assert_contains(
        &w,
        &[
            "extension KHR_texture_transform (in extensionsUsed) is not supported",
            "node 'both': has a matrix and translation/rotation/scale",
            "node 'projective': its matrix's last row is [0, 0, 0.5, 1]",
            "material 'glow': emissiveTexture is not supported",
        ],
    );
    assert!(!w.contains("KHR_materials_emissive_strength"), "{w}");
    assert!(!w.contains("node 'projective': has a matrix"), "{w}");
}

/// An emissive triangle whose area is positive but under f32's smallest (a scene at 1e-30 scale)
/// cannot be a light; it is left out with a warning saying so (the only message was "no emitters").
#[test]
fn emitters_too_small_for_f32_are_named() {
    let mut b = GltfBuilder::new();
    let m = b.material("glow", [0.5; 3], [2.0, 1.0, 0.5], false);
    let mesh = b.mesh("tiny", &[[0.0, 0.0, 0.0], [1e-30, 0.0, 0.0], [0.0, 1e-30, 0.0]], None, &[0, 1, 2], m);
    b.node("tiny", mesh, [0.0; 3]);
    let s = load_str(&b.to_json_string()).unwrap();
    let (lights, tiny, degenerate) = s.emissive_triangles_and_tiny();
    assert!(lights.is_empty() && s.emissive_triangles().is_empty());
    assert_eq!((tiny, degenerate), (1, 0));
    assert_contains(&s.warnings.join("\n"), &["1 emissive triangle has an area under 32-bit floats' smallest"]);
    // A plain triangle says nothing.
    assert!(load_value(&triangle_doc()).unwrap().warnings.is_empty());
}

/// The world bounds of instances that only scale along the axes and move come from their mesh's
/// box: equal to transforming every vertex (up to the sign of a zero; negative and odd scales
/// too); other
/// instances (rotated, sheared) still transform every vertex.
#[test]
fn world_bounds_from_mesh_boxes_equal_every_vertex_transformed() {
    let mut s = cornell();
    let base = s.instances.clone();
    let transforms = [
        Mat4::from_scale_rotation_translation(Vec3::new(-3.7, 0.31, 1e-3), glam::Quat::IDENTITY, Vec3::new(1e4, -7.1, 0.3)),
        Mat4::from_translation(Vec3::new(-0.1, 1.0 / 3.0, 5e6)),
        Mat4::from_scale(Vec3::new(1e-7, -2.0, 7.0)),
        Mat4::from_rotation_y(0.3) * Mat4::from_scale(Vec3::splat(2.0)),
        Mat4::from_cols_array(&[1.0, 0.2, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 0.0, 1.0]),
    ];
    for (k, t) in transforms.iter().enumerate() {
        for inst in &base {
            s.instances.push(Instance { name: format!("{}-{k}", inst.name), mesh: inst.mesh, transform: *t * inst.transform });
        }
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for inst in &s.instances {
        for &p in &s.meshes[inst.mesh].positions {
            let w = inst.transform.transform_point3(p);
            lo = lo.min(w);
            hi = hi.max(w);
        }
    }
    assert_eq!(s.world_bounds(), (lo, hi));
}

/// A triangle's edge is flat where exactly one other triangle shares it in the same plane,
/// facing the same way, across it: a quad's diagonal is; a box's edges (90°), a fold back onto
/// itself, a shared edge of three triangles and a lone triangle's edges are not.
#[test]
fn flat_edges_are_the_coplanar_shared_ones() {
    let mesh = |positions: &[[f32; 3]], indices: &[u32]| Mesh {
        name: "m".into(),
        positions: positions.iter().map(|p| Vec3::from(*p)).collect(),
        normals: vec![Vec3::ZERO; positions.len()],
        uvs: vec![Vec2::ZERO; positions.len()],
        indices: indices.to_vec(),
        triangle_materials: vec![0; indices.len() / 3],
    };
    // A quad: triangles (0, 1, 2) and (0, 2, 3); their shared edge 0-2 lies opposite vertex 1 of
    // the first and vertex 2 (index 3) of the second. Positions repeated, not shared, also match.
    let quad = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(mesh(&quad, &[0, 1, 2, 0, 2, 3]).flat_edges(), [0b010, 0b100]);
    let apart = [quad[0], quad[1], quad[2], quad[0], quad[2], quad[3]];
    assert_eq!(mesh(&apart, &[0, 1, 2, 3, 4, 5]).flat_edges(), [0b010, 0b100]);
    // A large one (the plane of the GPU test) and a slightly bent one (1e-3 rad: not flat).
    let big = quad.map(|p| [p[0] * 2e5 - 1e5, p[1] * 2e5 - 1e5, 0.0]);
    assert_eq!(mesh(&big, &[0, 1, 2, 0, 2, 3]).flat_edges(), [0b010, 0b100]);
    let bent = [quad[0], quad[1], quad[2], [0.0, 1.0, 1e-3]];
    assert_eq!(mesh(&bent, &[0, 1, 2, 0, 2, 3]).flat_edges(), [0, 0]);
    // A corner of two walls at 90 degrees.
    let corner = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert_eq!(mesh(&corner, &[0, 1, 2, 0, 3, 1]).flat_edges(), [0, 0]);
    // Folded back onto itself (the second on the same side, facing the other way).
    let fold = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 0.0]];
    assert_eq!(mesh(&fold, &[0, 1, 2, 1, 0, 3]).flat_edges(), [0, 0]);
    // Three triangles on one edge (0-2): none of them flat there.
    let fan = [quad[0], quad[1], quad[2], quad[3], [0.0, 0.0, 1.0]];
    assert_eq!(mesh(&fan, &[0, 1, 2, 0, 2, 3, 0, 4, 2]).flat_edges(), [0, 0, 0]);
    assert_eq!(mesh(&quad[..3], &[0, 1, 2]).flat_edges(), [0]);
}

/// The surface area takes an instance that rotates, scales uniformly and moves as its mesh's own
/// area times s² (once per mesh), within 1e-6 of every triangle transformed exactly; other instances
/// (a non-uniform scale, a shear) still transform every triangle.
#[test]
fn surface_area_of_similar_instances_scales_the_meshs_own() {
    let mut s = cornell();
    let base = s.instances.clone();
    let transforms = [
        Mat4::from_scale_rotation_translation(Vec3::splat(3.7), glam::Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.4), Vec3::new(5.0, -2.0, 1e3)),
        Mat4::from_scale(Vec3::new(-2.0, 2.0, 2.0)),
        Mat4::from_scale(Vec3::new(1.0, 2.0, 3.0)),
        Mat4::from_cols_array(&[1.0, 0.2, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 0.0, 1.0]),
    ];
    for (k, t) in transforms.iter().enumerate() {
        for inst in &base {
            s.instances.push(Instance { name: format!("{}-{k}", inst.name), mesh: inst.mesh, transform: *t * inst.transform });
        }
    }
    let every_triangle: f64 = s
        .instances
        .iter()
        .flat_map(|inst| {
            let mesh = &s.meshes[inst.mesh];
            // In f64: the exact answer (f32 vertices moved 1e3 away round to ulps of 6e-5).
            let m = inst.transform.as_dmat4();
            (0..mesh.triangle_count()).filter_map(move |t| mesh.triangle(t)).map(move |p| {
                let [a, b, c] = p.map(|v| m.transform_point3(v.as_dvec3()));
                0.5 * (b - a).cross(c - a).length()
            })
        })
        .sum();
    let area = s.surface_area();
    assert!((area / every_triangle - 1.0).abs() < 1e-6, "{area} against {every_triangle}");
}

/// Emissive triangles over all instances beyond the light set's limit (2^24) are refused from
/// their per-mesh count, before any light is made: 200 instances of an emissive 1M-triangle grid
/// took all of the machine's memory. One more instance than fits here: 4097 × 4096.
#[test]
fn too_many_instanced_emitters_are_refused_before_they_are_made() {
    let build = |instances: usize| {
        let mut b = GltfBuilder::new();
        let glow = b.material("glow", [0.5; 3], [1.0; 3], false);
        let n = 4097;
        let positions: Vec<[f32; 3]> = (0..n).flat_map(|i| {
            let x = i as f32;
            [[x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x, 1.0, 0.0]]
        }).collect();
        let indices: Vec<u32> = (0..3 * n as u32).collect();
        let mesh = b.mesh("strip", &positions, None, &indices, glow);
        for i in 0..instances {
            b.node(&format!("n{i}"), mesh, [0.0, 0.0, i as f32]);
        }
        load_str(&b.to_json_string())
    };
    let e = format!("{:#}", build(4096).map(|_| ()).unwrap_err());
    assert_contains(&e, &["16781312 emissive triangles", "16777216"]);
    assert_eq!(build(2).unwrap().emissive_triangles().len(), 2 * 4097);
}

/// A scene far from the file's origin is moved about its centre with the node transforms
/// composed in f64: two children 0.3 apart under a parent at 5e6 (a georeferenced file's
/// metres) stay 0.3 apart (composed in f32, each child's world translation rounded to 0.5).
/// Only the translation moves: a matrix's last row other than (0, 0, 0, 1), read as affine,
/// keeps its linear part. A mesh whose vertices themselves lie far from its origin is moved to
/// its own centre, its instance compensating. A scene near the origin is left as it is.
#[test]
fn far_scenes_move_about_their_centre_in_f64() {
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [1.0; 3], false);
    let quad = b.quad("q", [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]], m);
    let parent = b.group("utm", Mat4::from_translation(Vec3::new(5e6, 0.0, 5e6)).to_cols_array());
    let a = b.node_matrix("a", quad, Mat4::from_translation(Vec3::new(0.3, 0.0, 0.3)).to_cols_array());
    let c = b.node_matrix("b", quad, Mat4::IDENTITY.to_cols_array());
    b.add_child(parent, a);
    b.add_child(parent, c);
    let s = load_str(&b.to_json_string()).unwrap();
    assert!((s.origin - Vec3::new(5e6, 0.0, 5e6)).abs().max_element() < 2.0, "origin {}", s.origin);
    let t = |i: usize| s.instances[i].transform.w_axis.truncate();
    let gap = t(0) - t(1);
    assert!((gap - Vec3::new(0.3, 0.0, 0.3)).abs().max_element() < 1e-6, "the children are {gap} apart");
    assert!(t(0).abs().max_element() < 2.0 && t(1).abs().max_element() < 2.0, "{} {}", t(0), t(1));

    // A last row other than (0, 0, 0, 1): the linear columns stay as the file has them.
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [1.0; 3], false);
    let quad = b.quad("q", [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]], m);
    let mut matrix = Mat4::from_translation(Vec3::splat(1e4));
    matrix.z_axis.w = 0.5;
    b.node_matrix("odd", quad, matrix.to_cols_array());
    let s = load_str(&b.to_json_string()).unwrap();
    let moved = s.instances[0].transform;
    assert!(s.origin != Vec3::ZERO);
    assert_eq!((moved.x_axis, moved.y_axis, moved.z_axis), (matrix.x_axis, matrix.y_axis, matrix.z_axis));

    // Vertices at 1e5 under an identity node: the mesh moves to its own centre.
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [1.0; 3], false);
    let (x, z) = (1e5f32, 1e5f32);
    let quad = b.quad("baked", [[x, 0.0, z], [x + 1.0, 0.0, z], [x + 1.0, 0.0, z + 1.0], [x, 0.0, z + 1.0]], m);
    b.node("baked", quad, [0.0; 3]);
    let s = load_str(&b.to_json_string()).unwrap();
    let (lo, hi) = s.world_bounds();
    assert!(lo.abs().max_element() <= 0.5 && hi.abs().max_element() <= 0.5, "moved bounds {lo} {hi}");
    assert!(s.meshes[0].positions.iter().all(|p| p.abs().max_element() <= 0.5), "{:?}", s.meshes[0].positions);
    assert!(((lo + s.origin) - Vec3::new(x, 0.0, z)).abs().max_element() < 0.01, "{lo} + {}", s.origin);

    // Near the origin (centre 1.5 extents away, as in node_hierarchy_transform): not moved.
    let near = load_str(&{
        let mut b = GltfBuilder::new();
        let m = b.material("m", [0.5; 3], [1.0; 3], false);
        let quad = b.quad("q", [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]], m);
        b.node("q", quad, [1.0, 2.0, 3.0]);
        b.to_json_string()
    })
    .unwrap();
    assert_eq!(near.origin, Vec3::ZERO);
}

/// A name from the file is shown cut after 200 characters, saying how long it was: a node named
/// with a million characters was echoed whole in its error.
#[test]
fn long_names_are_cut_in_messages() {
    let mut doc = triangle_doc();
    let long = "n".repeat(1_000_000);
    doc["nodes"][0]["name"] = json!(long);
    doc["nodes"][0]["rotation"] = json!([0.0, 0.0, 0.0, 0.0]);
    let e = load_err(&doc);
    assert!(e.len() < 1000 && e.contains(&format!("{}… (1000000 characters)", "n".repeat(200))), "{} characters: {}", e.len(), &e[..e.len().min(400)]);
    // A name at the limit is shown whole.
    doc["nodes"][0]["name"] = json!("m".repeat(200));
    let e = load_err(&doc);
    assert!(e.contains(&format!("'{}'", "m".repeat(200))) && !e.contains("characters)"), "{e}");
}
