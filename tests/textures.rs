//! Base-colour textures on the GPU: orientation, bilinear filtering with repeat wrapping, sRGB
//! decoding, `--textures off`, and the textured variants of every pass that reads albedo.

mod common;

use common::*;
use restir_vpl::renderer::Renderer;
use restir_vpl::scene::generate::GltfBuilder;
use restir_vpl::settings::Mode;
use restir_vpl::RenderSettings;

const TEX_W: u32 = 4;
const TEX_H: u32 = 2;
const FACTOR: [f32; 3] = [0.8, 0.7, 0.6];

/// Eight clearly different sRGB texels, row 0 first.
fn texels() -> Vec<u8> {
    let colours: [[u8; 3]; 8] = [
        [255, 0, 0],
        [0, 255, 0],
        [0, 0, 255],
        [255, 255, 255],
        [20, 40, 60],
        [200, 100, 50],
        [10, 250, 128],
        [128, 128, 128],
    ];
    colours.iter().flat_map(|c| [c[0], c[1], c[2], 255]).collect()
}

/// A textured wall that exactly fills a 90° (vertical) view of aspect `aspect`, lit by a point
/// light at the camera. Only one surface: no light bounces between surfaces.
fn wall_scene(aspect: f32) -> String {
    // Corners CCW seen from +z; uv (0, 0) at the top left, as glTF puts the image's first row.
    wall_scene_with(aspect, [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]], false)
}

/// [`wall_scene`] with the corners' `uvs` and, with `nearest`, a sampler whose magFilter and
/// minFilter are NEAREST.
fn wall_scene_with(aspect: f32, uvs: [[f32; 2]; 4], nearest: bool) -> String {
    let mut b = GltfBuilder::new();
    let tex = b.texture_png("checker", TEX_W, TEX_H, &texels());
    let mat = b.textured_material("wall", FACTOR, tex, false);
    let positions = [[-aspect, 1.0, -1.0], [-aspect, -1.0, -1.0], [aspect, -1.0, -1.0], [aspect, 1.0, -1.0]];
    let mesh = b.mesh_with_uvs("wall", &positions, None, &uvs, &[0, 1, 2, 0, 2, 3], mat);
    b.node("wall", mesh, [0.0; 3]);
    b.point_light("bulb", [0.0, 0.0, 0.0], [1.0; 3], 5.0);
    b.camera("camera", [0.0; 3], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 90f32.to_radians());
    let mut json: serde_json::Value = serde_json::from_str(&b.to_json_string()).expect("the builder writes JSON");
    if nearest {
        const NEAREST: u32 = 9728;
        json["samplers"][0]["magFilter"] = NEAREST.into();
        json["samplers"][0]["minFilter"] = NEAREST.into();
    }
    json.to_string()
}

/// The decoded texel (x, y) of [`texels`], repeat-wrapped.
fn texel_linear(x: i64, y: i64) -> [f64; 3] {
    let t = texels();
    let x = x.rem_euclid(TEX_W as i64) as usize;
    let y = y.rem_euclid(TEX_H as i64) as usize;
    let i = 4 * (y * TEX_W as usize + x);
    [0, 1, 2].map(|c| srgb_to_linear(t[i + c] as f64 / 255.0))
}

/// Renders `scene` with and without textures (path tracer, one bounce: a point light at the camera
/// and one surface, so no randomness) and returns the worst difference between their per-pixel
/// ratio and `expected` at the pixel's (u, v) on a wall that fills the view with uv 0..1.
fn worst_ratio_error(scene: &restir_vpl::scene::Scene, (w, h): (u32, u32), expected: impl Fn(f64, f64) -> [f64; 3]) -> f64 {
    let settings = RenderSettings { mode: Mode::Pt, max_bounces: 1, ..small(w, h, 1) };
    let on = render(scene, &settings);
    let off = render(scene, &RenderSettings { textures: false, ..settings.clone() });
    let mut worst = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let e = expected((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
            for c in 0..3 {
                let (a, b) = (on.mean[i][c] as f64, off.mean[i][c] as f64);
                assert!(b > 1e-4, "pixel ({x}, {y}) unlit without textures: {b}");
                worst = worst.max((a / b - e[c]).abs());
            }
        }
    }
    worst
}

/// A sampler with magFilter NEAREST reads the one texel under each uv (pixel art, labels, ID
/// maps): it was filtered bilinearly like every other, without a word.
#[test]
fn a_nearest_sampler_reads_one_texel() {
    let (w, h) = (32u32, 16u32);
    let scene = load_json(&wall_scene_with(w as f32 / h as f32, [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]], true), "nearest.gltf");
    assert!(scene.textures[0].nearest);
    // Pixel centres fall inside texels (32 / 4 = 8 pixels per texel), never on their edges.
    let worst = worst_ratio_error(&scene, (w, h), |u, v| texel_linear((u * TEX_W as f64).floor() as i64, (v * TEX_H as f64).floor() as i64));
    assert!(worst < 1e-5, "textured / untextured differs from the nearest texel by up to {worst:e}");
}

/// Vertex uvs near the float maximum: their interpolation overflows to inf, and fract(inf) is NaN,
/// which made the albedo NaN (131 of 4096 pixels black in a review's wall). Under repeat wrapping a
/// uv that large is a whole number, so the wall reads the filtered texture at uv (0, 0).
#[test]
fn uvs_near_the_float_maximum_read_the_texture_at_zero() {
    let (w, h) = (16u32, 8u32);
    let big = f32::MAX;
    let scene = load_json(&wall_scene_with(w as f32 / h as f32, [[big, big], [big, big], [big, -big], [-big, big]], false), "huge-uv.gltf");
    // `render` also fails on any non-finite sample.
    let worst = worst_ratio_error(&scene, (w, h), |_, _| expected(0.0, 0.0));
    assert!(worst < 1e-5, "textured / untextured differs from the texture at uv 0 by up to {worst:e}");
}

fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Reference lookup, written independently of the shader: bilinear between texel centres, repeat
/// wrapping, each texel decoded from sRGB before filtering.
fn expected(u: f64, v: f64) -> [f64; 3] {
    let (x, y) = (u * TEX_W as f64 - 0.5, v * TEX_H as f64 - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let mut out = [0.0; 3];
    for (dx, dy, w) in [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)] {
        let c = texel_linear(x0 + dx, y0 + dy);
        for k in 0..3 {
            out[k] += w * c[k];
        }
    }
    out
}

#[test]
fn textured_over_untextured_is_the_filtered_srgb_texture() {
    let (w, h) = (32u32, 16u32);
    let scene = load_json(&wall_scene(w as f32 / h as f32), "wall.gltf");
    assert_eq!(scene.textures.len(), 1);
    // Pixel centres map linearly onto the wall, which fills the view exactly.
    let worst = worst_ratio_error(&scene, (w, h), expected);
    // The two renders trace identical rays (same seed, no randomness left with one point light
    // and one surface), so the ratio is the texture value up to float rounding of the
    // interpolated uv (a uv error of 1e-6 moves a bilinear value by < 1e-5 here; measured on
    // lavapipe: 2.9e-7). The bound was 2e-3, which an approximate sRGB decode (a 2.2 gamma is up
    // to ~1e-2 off the exact curve at dark values, cheaper fits ~1e-3) could have passed.
    assert!(worst < 1e-5, "textured / untextured differs from the filtered texture by up to {worst:e}");
}

#[test]
fn texture_variants_are_used_only_when_needed() {
    let ctx = context();
    let textured = load_json(&wall_scene(1.0), "wall.gltf");
    let cornell = restir_vpl::scene::Scene::load(&repo_path("scenes/cornell_box.gltf")).unwrap();
    // (scene, textures uploaded, textures in the renderer's settings, textured variants expected):
    // a scene uploaded with textures and shared by renderers draws without them when asked to.
    for (scene, upload_textures, textures, want) in
        [(&textured, true, true, true), (&textured, false, false, false), (&textured, true, false, false), (&cornell, true, true, false)]
    {
        let gpu = std::sync::Arc::new(restir_vpl::scene_gpu::SceneGpu::new(&ctx, scene, upload_textures, restir_vpl::vk::accel::MERGE_MAX_TRIANGLES).unwrap());
        assert_eq!(gpu.texture_count, if upload_textures && scene.textures.len() == 1 { 1 } else { 0 });
        for mode in [Mode::Pt, Mode::Uniform] {
            let settings =
                RenderSettings { mode, textures, vpls_direct: 500, vpls_indirect: 500, ..small(16, 16, 2) };
            let mut r = Renderer::new(ctx.clone(), gpu.clone(), settings).unwrap();
            assert_eq!(r.textured(), want, "mode {mode:?}, upload {upload_textures}, textures {textures}");
            let camera = r.initial_camera();
            r.render_frame(&camera, false).unwrap();
            r.render_frame(&camera, false).unwrap();
            assert_all_finite(&r.read_mean().unwrap(), "textured-scene image");
            common::assert_no_nonfinite_samples(&r, &format!("mode {mode:?}"));
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// Textures beyond the device's maxStorageBufferRange (all texels are one storage buffer) are
/// refused at upload with the scene, the sizes and the largest texture named, and the way out
/// (`--textures off`, which then uploads fine). Before, they were bound anyway: a validation error
/// (VUID-VkWriteDescriptorSet-descriptorType-00333) and undefined reads past the range.
#[test]
fn textures_over_the_storage_buffer_range_are_refused_by_name() {
    let ctx = context();
    let range = u64::from(ctx.properties.limits.max_storage_buffer_range);
    // The loader's probe reads the range of the device a context picks, before any context (it
    // refuses textures over it before decoding them: src/scene/tests.rs), and none for a device
    // that does not exist.
    assert_eq!(restir_vpl::vk::context::storage_buffer_range(None, None), Some(range));
    assert_eq!(restir_vpl::vk::context::storage_buffer_range(Some(99), None), None);
    let mut scene = load_json(&wall_scene(1.0), "wall.gltf");
    // The check itself on every device, against a made-up 4 KiB range: the texture's 8 KiB are
    // over it, and a range that holds them passes.
    let small = restir_vpl::scene::Texture::new("huge".into(), 1024, 2, vec![128; 1024 * 2 * 4], false);
    let mut small_scene = load_json(&wall_scene(1.0), "wall.gltf");
    small_scene.textures[0] = small;
    let err = format!("{:#}", restir_vpl::scene_gpu::check_texel_range(&small_scene, 8192, 4096).unwrap_err());
    for part in ["maxStorageBufferRange", "--textures off", "'huge' 1024x2"] {
        assert!(err.contains(part), "{part:?} missing from: {err}");
    }
    assert!(restir_vpl::scene_gpu::check_texel_range(&small_scene, 8192, 8192).is_ok());
    // Then through a real upload: one texture of 4-byte texels just over the device's range (a
    // narrow strip, to keep it small where the range is 128 MiB; where the range is too large to
    // allocate a test texture over it, only the check above ran).
    if range > 1 << 30 {
        common::skip(&format!("maxStorageBufferRange is {range} bytes: the upload over it is not tried (the check itself was)"));
        return;
    }
    let texels = range / 4 + 1;
    let (w, h) = (1024u32, texels.div_ceil(1024) as u32);
    scene.textures[0] = restir_vpl::scene::Texture::new("huge".into(), w, h, vec![128; (w * h * 4) as usize], false);
    let err = match restir_vpl::scene_gpu::SceneGpu::new(&ctx, &scene, true, restir_vpl::vk::accel::MERGE_MAX_TRIANGLES) {
        Ok(_) => panic!("{w}x{h} texels (over {range} bytes) were uploaded"),
        Err(e) => format!("{e:#}"),
    };
    for part in ["wall.gltf", "maxStorageBufferRange", "--textures off", &format!("'huge' {w}x{h}")] {
        assert!(err.contains(part), "{part:?} missing from: {err}");
    }
    assert!(restir_vpl::scene_gpu::SceneGpu::new(&ctx, &scene, false, restir_vpl::vk::accel::MERGE_MAX_TRIANGLES).is_ok());
    common::assert_no_validation_errors(&ctx);
}

/// One image sampled two ways (bilinear on the left half of the wall, NEAREST on the right): its
/// texels are decoded, held and uploaded once, the second texture naming the first's (they were
/// copied and uploaded twice), and the frame is the one rendered from two copies of the image.
#[test]
fn an_image_sampled_two_ways_is_held_once() {
    let (w, h) = (32u32, 16u32);
    let aspect = w as f32 / h as f32;
    let scene = |copies: bool| -> String {
        let mut b = GltfBuilder::new();
        let tex = b.texture_png("checker", TEX_W, TEX_H, &texels());
        let left = b.textured_material("left", FACTOR, tex, false);
        let right = b.textured_material("right", FACTOR, tex, false);
        let quad = |x0: f32, x1: f32| [[x0, 1.0, -1.0], [x0, -1.0, -1.0], [x1, -1.0, -1.0], [x1, 1.0, -1.0]];
        let (u0, u1) = (|u: f32| [[u, 0.0], [u, 1.0]], |u: f32| [[u, 1.0], [u, 0.0]]);
        let uvs = |a: f32, c: f32| [u0(a)[0], u0(a)[1], u1(c)[0], u1(c)[1]];
        let lm = b.mesh_with_uvs("left", &quad(-aspect, 0.0), None, &uvs(0.0, 0.5), &[0, 1, 2, 0, 2, 3], left);
        let rm = b.mesh_with_uvs("right", &quad(0.0, aspect), None, &uvs(0.5, 1.0), &[0, 1, 2, 0, 2, 3], right);
        b.node("left", lm, [0.0; 3]);
        b.node("right", rm, [0.0; 3]);
        b.point_light("bulb", [0.0, 0.0, 0.0], [1.0; 3], 5.0);
        b.camera("camera", [0.0; 3], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 90f32.to_radians());
        let mut json: serde_json::Value = serde_json::from_str(&b.to_json_string()).expect("the builder writes JSON");
        // The right half's texture: the same image (or a copy of it) through a NEAREST sampler.
        const NEAREST: u32 = 9728;
        let samplers = json["samplers"].as_array_mut().expect("the builder writes a sampler");
        samplers.push(serde_json::json!({ "magFilter": NEAREST, "minFilter": NEAREST }));
        let sampler = samplers.len() - 1;
        let mut source = json["textures"][tex]["source"].as_u64().expect("a texture source") as usize;
        if copies {
            let image = json["images"][source].clone();
            let images = json["images"].as_array_mut().unwrap();
            images.push(image);
            source = images.len() - 1;
        }
        let textures = json["textures"].as_array_mut().unwrap();
        textures.push(serde_json::json!({ "source": source, "sampler": sampler }));
        json["materials"][right]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = (textures.len() - 1).into();
        json.to_string()
    };
    let shared = load_json(&scene(false), "shared.gltf");
    let copied = load_json(&scene(true), "copied.gltf");
    assert_eq!(shared.textures.len(), 2);
    assert!(shared.textures[1].nearest && !shared.textures[0].nearest);
    assert_eq!((shared.textures[1].texels_of, shared.textures[1].rgba8.len()), (Some(0), 0), "the second sampling holds no copy");
    assert_eq!(copied.textures[1].texels_of, None);
    let settings = RenderSettings { mode: Mode::Pt, max_bounces: 1, ..small(w, h, 1) };
    let (a, b) = (render(&shared, &settings), render(&copied, &settings));
    let differ = a.mean.iter().zip(&b.mean).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "pixels where the shared image renders otherwise than two copies of it");
    // The two halves sample differently: the albedo (textured over untextured) is flat within a
    // texel on the NEAREST half (pixels 25 and 26 lie in texel 3), and varies on the bilinear one
    // (pixels 9 and 10 in texel 1).
    let off = render(&shared, &RenderSettings { textures: false, ..settings.clone() });
    let albedo = |x: usize| {
        let i = (h as usize / 4) * w as usize + x;
        a.mean[i][0] / off.mean[i][0]
    };
    assert!((albedo(25) - albedo(26)).abs() < 1e-5, "the NEAREST half reads one texel: {} and {}", albedo(25), albedo(26));
    assert!((albedo(9) - albedo(10)).abs() > 1e-3, "the bilinear half filters: {} and {}", albedo(9), albedo(10));
}
