//! Headless runs of the bundled Cornell box through the library: outputs, finiteness, summary,
//! determinism, and agreement between seeds.

mod common;

use common::*;
use restir_vpl::output::read_exr;
use restir_vpl::scene::Scene;
use restir_vpl::headless::RunOutput;
use restir_vpl::RenderSettings;

fn cornell() -> Scene {
    Scene::load(&repo_path("scenes/cornell_box.gltf")).expect("bundled Cornell box loads")
}

#[test]
fn cornell_box_writes_outputs_and_summary() {
    let dir = tempfile::tempdir().expect("temp dir");
    let settings = RenderSettings { out_dir: Some(dir.path().to_path_buf()), save_every: 2, ..small(64, 64, 4) };
    let out = render(&cornell(), &settings);
    for f in ["final.exr", "final.png", "accum_0002.exr", "accum_0004.exr", "summary.json"] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    let exr = read_exr(&dir.path().join("final.exr")).expect("final.exr reads back");
    assert_eq!((exr.width, exr.height), (64, 64));
    assert_all_finite(&exr.pixels, "final.exr");
    assert_eq!(exr.pixels, out.mean, "final.exr holds the mean image, row 0 at the top");
    let png = image::open(dir.path().join("final.png")).expect("final.png decodes");
    assert_eq!((png.width(), png.height()), (64, 64));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).expect("summary parses");
    assert_eq!(summary["frames"], 4);
    assert_eq!(summary["nonfinite_samples"], 0);
    assert_eq!(summary["validation_errors"], 0);
    for pass in ["gbuffer", "pathtrace", "accumulate", "tonemap"] {
        assert!(summary["pass_ms"][pass]["median"].as_f64().is_some(), "pass {pass} timed");
    }
    assert!(summary["rays_per_pixel"]["mean"].as_f64().unwrap() > 1.0);
    // The image is lit: the light is visible and walls reflect.
    let lum: f64 = out.mean.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum::<f64>() / out.mean.len() as f64;
    assert!(lum > 0.05, "image mean {lum}");
}

/// Row 0 is the top: the ceiling light appears in the upper part, the red wall on the left and the
/// green wall on the right, as in the published photographs.
#[test]
fn cornell_box_orientation() {
    let out = render(&cornell(), &small(64, 64, 8));
    let px = |x: usize, y: usize| out.mean[y * 64 + x];
    let light_rows: Vec<usize> =
        (0..64).filter(|&y| (0..64).any(|x| px(x, y).iter().all(|&c| c > 3.0))).collect();
    assert!(!light_rows.is_empty() && light_rows.iter().all(|&y| y < 12), "light rows {light_rows:?}");
    // Average a patch of each side wall (x 1..5 and 59..63, rows 24..40) to tame the noise.
    let patch = |x0: usize| {
        let mut s = [0f32; 3];
        for y in 24..40 {
            for x in x0..x0 + 4 {
                for c in 0..3 {
                    s[c] += px(x, y)[c] / 64.0;
                }
            }
        }
        s
    };
    let (left, right) = (patch(1), patch(59));
    // Red albedo (0.63, 0.065, 0.05) and green (0.14, 0.45, 0.091) under a warm light (17, 12, 4).
    assert!(left[0] > 4.0 * left[1], "left wall is red: {left:?}");
    assert!(right[1] > 1.5 * right[0] && right[1] > 2.0 * left[1], "right wall is green: {right:?}");
}

#[test]
fn same_seed_same_image_different_seed_same_mean() {
    let scene = cornell();
    let frames = 16;
    let a = render(&scene, &RenderSettings { seed: 11, ..small(48, 48, frames) });
    let b = render(&scene, &RenderSettings { seed: 11, ..small(48, 48, frames) });
    assert!(a.mean == b.mean, "same seed must give a bit-identical image");
    let c = render(&scene, &RenderSettings { seed: 12, ..small(48, 48, frames) });
    assert!(a.mean != c.mean, "different seeds must give different noise");
    // Same expectation: the difference of the image means is within 4 standard errors.
    let all = 0..(48 * 48) as usize;
    let (ma, sa) = image_mean_and_se(&a, frames, all.clone());
    let (mc, sc) = image_mean_and_se(&c, frames, all);
    let se = (sa * sa + sc * sc).sqrt();
    assert!((ma - mc).abs() <= 4.0 * se, "means {ma} vs {mc}: {:.1} standard errors", (ma - mc).abs() / se);
}

/// The workgroup shape changes only how pixels are grouped, never which random numbers a pixel
/// uses: the image is bit-identical at 8×8, 16×4 (wider than 8: a shader that ignored its
/// specialisation would leave columns unwritten) and an odd 5×3 that does not divide the image.
/// pt covers gbuffer and pathtrace; ReSTIR with --compensate restir_initial, restir_spatial,
/// vpl_shade and vpl_compensate (uniform and RIS use the same passes); brute force its own pass.
#[test]
fn workgroup_shape_leaves_the_image_unchanged() {
    use restir_vpl::settings::Mode;
    let scene = cornell();
    for (mode, compensate) in [(Mode::Pt, false), (Mode::Restir, true), (Mode::Bruteforce, false)] {
        let base = RenderSettings { mode, compensate, vpls_direct: 600, vpls_indirect: 600, aa: true, ..small(36, 28, 3) };
        let image = |workgroup: [u32; 2]| render(&scene, &RenderSettings { workgroup, ..base.clone() }).mean;
        let reference = image([8, 8]);
        assert_all_finite(&reference, "8x8");
        assert!(reference.iter().any(|p| p[0] > 0.0), "{mode:?}: the image is lit");
        for workgroup in [[16, 4], [5, 3]] {
            assert!(image(workgroup) == reference, "{mode:?}: {workgroup:?} changes the image");
        }
    }
}

/// With --aa the G-buffer is retraced every frame (jittered); without it, once.
#[test]
fn gbuffer_traced_once_unless_aa() {
    let scene = cornell();
    let still = render(&scene, &small(32, 32, 5));
    assert_eq!(still.summary.pass_ms["gbuffer"].count, 1);
    let aa = render(&scene, &RenderSettings { aa: true, ..small(32, 32, 5) });
    assert_eq!(aa.summary.pass_ms["gbuffer"].count, 5);
    // Anti-aliasing changes edge pixels but not the image's overall brightness much: jittered
    // primary rays average each pixel's footprint where the still G-buffer samples its centre, so
    // the two means differ by what the edges' coverage moves, not by noise. 10 % is a sanity
    // bound (a jitter that lost or doubled the light would be off by far more), not a statistical
    // test.
    let m = |o: &restir_vpl::RunOutput| o.mean.iter().map(|p| p[1] as f64).sum::<f64>() / o.mean.len() as f64;
    assert!((m(&still) - m(&aa)).abs() < 0.1 * m(&still), "means {} (still) vs {} (--aa)", m(&still), m(&aa));
}

/// `--progressive off` (what `bench --motion` renders its displayed frames with): every image is
/// its frame alone, on a still camera too. The mean equals the last frame's samples, the count
/// stays 1, and consecutive images differ (fresh random numbers), where progressive accumulation
/// counts every frame.
#[test]
fn progressive_off_shows_each_frame_alone() {
    let ctx = context();
    let scene = cornell();
    let settings = RenderSettings { mode: restir_vpl::settings::Mode::Restir, progressive: false, ..small(32, 32, 1) };
    let gpu = upload(&ctx, &scene, &settings);
    let mut r = restir_vpl::renderer::Renderer::new(ctx.clone(), gpu.clone(), settings.clone()).unwrap();
    let camera = r.initial_camera();
    let mut last: Option<Vec<[f32; 3]>> = None;
    for _ in 0..4 {
        r.render_frame(&camera, false).unwrap();
        assert_eq!(r.accumulated(), 1);
        let (mean, samples) = (r.read_mean().unwrap(), r.read_frame_samples().unwrap());
        assert_eq!(mean, samples, "the image is the frame's samples");
        if let Some(prev) = &last {
            assert_ne!(prev, &mean, "a new frame draws new random numbers");
        }
        last = Some(mean);
    }
    let mut p = restir_vpl::renderer::Renderer::new(ctx.clone(), gpu, RenderSettings { progressive: true, ..settings }).unwrap();
    for _ in 0..4 {
        p.render_frame(&camera, false).unwrap();
    }
    assert_eq!(p.accumulated(), 4);
    assert_no_validation_errors(&ctx);
}

/// `--merge-blas`: the living room (47 instances, transformed) traced as one merged world-space
/// mesh renders the instanced image. Both runs use the same random numbers, so a pixel differs only
/// where float rounding of the baked vertices (or a ray through a shared edge) sends a path
/// elsewhere: 2 of 2,304 pixels measured. A wrong winding, normal or material would change every
/// pixel that sees the surface; a different seed changes nearly all. The bound is 1 % of pixels.
#[test]
fn merged_scene_renders_the_instanced_image() {
    let scene = Scene::load(&repo_path("scenes/living_room.gltf")).expect("bundled living room loads");
    let base = small(48, 48, 2);
    let instanced = render(&scene, &RenderSettings { merge_blas: 0, ..base.clone() });
    let merged = render(&scene, &RenderSettings { merge_blas: u32::MAX, ..base.clone() });
    assert_eq!(instanced.summary.scene.merged_instances, 0);
    assert_eq!((merged.summary.scene.merged_instances, merged.summary.scene.blases), (scene.instances.len(), 1));
    let differing = |a: &RunOutput, b: &RunOutput| {
        a.mean
            .iter()
            .zip(&b.mean)
            .filter(|(p, q)| (0..3).any(|c| (p[c] - q[c]).abs() > 1e-3 * (q[c].abs() + 1e-3)))
            .count()
    };
    let n = differing(&merged, &instanced);
    assert!(n * 100 <= merged.mean.len(), "{n} of {} pixels differ between merged and instanced", merged.mean.len());
    // The check can tell: another seed changed 930 pixels (40 %; the rest see no light in 2
    // frames or only the emitters), and untransformed shading normals in the merged mesh 121 (5 %).
    let other_seed = render(&scene, &RenderSettings { merge_blas: 0, seed: base.seed + 1, ..base });
    let m = differing(&other_seed, &instanced);
    assert!(m * 10 > merged.mean.len(), "another seed changes only {m} pixels");
}

/// A settings change that changes nothing, or only the exposure (tonemap applies it to the
/// accumulated mean), keeps the accumulation; any other change starts it again. Dragging the
/// window's exposure slider used to restart it at every step.
#[test]
fn exposure_changes_keep_the_accumulation_and_other_changes_restart_it() {
    use restir_vpl::camera::Camera;
    use restir_vpl::renderer::Renderer;
    let ctx = context();
    let scene = cornell();
    let settings = RenderSettings { vpls_direct: 500, vpls_indirect: 500, ..small(32, 32, 1) };
    let gpu = upload(&ctx, &scene, &settings);
    let camera = Camera::initial(&gpu.info, None);
    let mut r = Renderer::new(ctx.clone(), gpu, settings.clone()).unwrap();
    for _ in 0..3 {
        r.render_frame(&camera, false).unwrap();
    }
    assert_eq!(r.accumulated(), 3);
    let mean_before = r.read_mean().unwrap();
    r.apply_settings(RenderSettings { exposure: 2.0, ..settings.clone() }).unwrap();
    r.apply_settings(RenderSettings { exposure: 2.0, ..settings.clone() }).unwrap();
    assert_eq!((r.accumulated(), r.settings().exposure), (3, 2.0), "exposure alone keeps the accumulation");
    assert_eq!(r.read_mean().unwrap(), mean_before, "and the accumulated mean (exposure is tonemap's)");
    r.render_frame(&camera, false).unwrap();
    assert_eq!(r.accumulated(), 4);
    r.apply_settings(RenderSettings { exposure: 2.0, candidates: 8, ..settings }).unwrap();
    r.render_frame(&camera, false).unwrap();
    assert_eq!(r.accumulated(), 1, "another change starts again");
    common::assert_no_nonfinite_samples(&r, "run");
    common::assert_no_validation_errors(&ctx);
}

/// The Cornell box's light mirrored in x about its own centre line is the same light, so the
/// path-traced image must not change: a mirroring transform reverses a triangle's winding, and the
/// GPU's light sampling took the emitting face from the vertex order (it used the back face, and
/// the image came out at 0.51–0.58 of the brightness). The means of two independent
/// 16-frame runs must agree within 4 standard errors of their difference (the per-pixel
/// variances bound it; 4 SE: a false failure about once in 16,000 runs).
#[test]
fn a_mirrored_emitter_lights_from_its_front_face() {
    let path = repo_path("scenes/cornell_box.gltf");
    let mut doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let light = doc["nodes"].as_array().unwrap().iter().position(|n| n["name"] == "light").expect("the box has a light node");
    let positions = doc["meshes"][doc["nodes"][light]["mesh"].as_u64().unwrap() as usize]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap();
    let accessor = &doc["accessors"][positions as usize];
    let centre2 = accessor["min"][0].as_f64().unwrap() + accessor["max"][0].as_f64().unwrap();
    doc["nodes"][light]["matrix"] = serde_json::json!([-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, centre2, 0, 0, 1]);
    let mirrored = Scene::from_gltf_slice(doc.to_string().as_bytes(), path.parent(), "mirrored_light.gltf").unwrap();
    assert!(mirrored.instances.iter().any(|i| i.is_mirrored()), "the light's instance mirrors");

    const FRAMES: u32 = 16;
    let settings = RenderSettings { mode: restir_vpl::settings::Mode::Pt, ..small(48, 48, FRAMES) };
    let pixels = 0..48 * 48;
    let (m0, se0) = image_mean_and_se(&render(&cornell(), &settings), FRAMES, pixels.clone());
    let (m1, se1) = image_mean_and_se(&render(&mirrored, &RenderSettings { seed: settings.seed + 1, ..settings.clone() }), FRAMES, pixels);
    let tol = 4.0 * (se0 * se0 + se1 * se1).sqrt();
    assert!((m1 - m0).abs() < tol, "mirrored light: mean {m1:.5} against {m0:.5} (tolerance {tol:.5}, ratio {:.3})", m1 / m0);
}

/// `compare`'s 8-bit mapping (`to_srgb8`, what FLIP sees) is the PNG preview's: the GPU tonemap of
/// final.exr at the run's exposure, byte for byte up to rounding at a half (GPU `pow` against the
/// host's `powf`: at most one step, in a few pixels).
#[test]
fn compare_maps_to_8_bits_as_the_png_preview_does() {
    let dir = tempfile::tempdir().expect("temp dir");
    let settings = RenderSettings { out_dir: Some(dir.path().to_path_buf()), exposure: 1.5, mode: restir_vpl::settings::Mode::Pt, ..small(40, 30, 2) };
    render(&cornell(), &settings);
    let exr = read_exr(&dir.path().join("final.exr")).unwrap();
    let png = image::open(dir.path().join("final.png")).unwrap().to_rgb8().into_raw();
    let ours = restir_vpl::eval::compare::to_srgb8(&exr, settings.exposure);
    assert_eq!(ours.len(), png.len());
    let off: Vec<(usize, u8, u8)> = ours.iter().zip(&png).enumerate().filter(|(_, (a, b))| a != b).map(|(i, (a, b))| (i, *a, *b)).collect();
    assert!(off.iter().all(|&(_, a, b)| a.abs_diff(b) <= 1), "channels differ by more than one step: {:?}", &off[..off.len().min(8)]);
    assert!(off.len() * 100 <= ours.len(), "{} of {} channels differ by a step", off.len(), ours.len());
    assert!(png.iter().any(|&v| v > 0 && v < 255), "a lit, unsaturated image");
}

/// An image of more than 65,535 × 64 pixels: the per-pixel 1-D passes (accumulate, tonemap) need
/// more workgroups along x than Vulkan guarantees (maxComputeWorkGroupCount[0] = 65,535 on
/// lavapipe and Intel), so `dispatch_1d` folds them into rows. Before, this was a validation error
/// (VUID-vkCmdDispatch-groupCountX-00386) and undefined on such devices. The items past the first
/// 65,535 groups (the last 5,760 pixels here, the bottom 2.7 rows) must be rendered like the
/// others. So the camera sits inside a closed emitting box and the path tracer stops at the first
/// hit: every pixel is exactly Le, in the accumulated mean (accumulate) and in the PNG (tonemap).
/// (The Cornell box would not do: its bottom rows are black in a correct image.)
#[test]
fn images_over_4_megapixels_dispatch_within_the_workgroup_count_limit() {
    let (w, h) = (2100u32, 2000u32);
    let first_folded = 65_535 * 64;
    assert!(u64::from(w) * u64::from(h) > first_folded);
    let le = 1.5f32;
    let scene = load_json(&restir_vpl::scene::generate::furnace_box_gltf(0.5, le, 2.0), "furnace box");
    let dir = tempfile::tempdir().expect("temp dir");
    let settings = RenderSettings {
        mode: restir_vpl::settings::Mode::Pt,
        max_bounces: 0,
        out_dir: Some(dir.path().to_path_buf()),
        ..small(w, h, 1)
    };
    let out = render(&scene, &settings);
    let wrong: Vec<(usize, [f32; 3])> = out.mean.iter().copied().enumerate().filter(|(_, p)| p.iter().any(|&c| (c - le).abs() > 1e-6)).collect();
    assert!(wrong.is_empty(), "{} pixels are not Le = {le}, e.g. {:?} (the first {first_folded} are in the first 65,535 groups)", wrong.len(), &wrong[..wrong.len().min(4)]);
    let png = image::open(dir.path().join("final.png")).expect("final.png").to_rgb8();
    let first = *png.get_pixel(0, 0);
    assert!(first.0.iter().all(|&c| c > 0), "Le maps to a lit preview pixel: {first:?}");
    let off = png.enumerate_pixels().filter(|(_, _, p)| **p != first).count();
    assert_eq!(off, 0, "preview pixels unlike the first (tonemap past the first 65,535 groups?)");
}

/// The accumulation's per-pixel variance (the GPU's Welford update, which every "k standard
/// errors" tolerance of the suite divides by) equals the unbiased sample variance of the frames'
/// own samples read back one by one, and its mean their mean. The GPU keeps both in f32 with
/// compensation, the host sums in f64: the tolerance is 1e-4 relative (a wrong (n − 1)/n factor
/// or count is off by 1/n ≥ 3 %, and 32 frames of f32 rounding stay near 1e-6).
#[test]
fn the_accumulated_variance_is_the_sample_variance_of_the_frames() {
    let ctx = context();
    let scene = cornell();
    // Uniform sampling of few VPLs and the path tracer: both noisy from frame to frame.
    for mode in [restir_vpl::settings::Mode::Uniform, restir_vpl::settings::Mode::Pt] {
        let settings = RenderSettings { mode, vpls_direct: 200, vpls_indirect: 200, ..small(16, 16, 32) };
        let gpu = upload(&ctx, &scene, &settings);
        let mut r = restir_vpl::renderer::Renderer::new(ctx.clone(), gpu, settings).unwrap();
        let camera = r.initial_camera();
        let frames = 32;
        let mut samples: Vec<Vec<[f32; 3]>> = Vec::new();
        for _ in 0..frames {
            r.render_frame(&camera, false).unwrap();
            samples.push(r.read_frame_samples().unwrap());
        }
        assert_eq!(r.accumulated(), frames);
        let (variance, mean) = (r.read_variance().unwrap(), r.read_mean().unwrap());
        let n = f64::from(frames);
        let mut noisy = 0;
        for p in 0..variance.len() {
            for c in 0..3 {
                let m = samples.iter().map(|s| f64::from(s[p][c])).sum::<f64>() / n;
                let v = samples.iter().map(|s| (f64::from(s[p][c]) - m).powi(2)).sum::<f64>() / (n - 1.0);
                let (gv, gm) = (f64::from(variance[p][c]), f64::from(mean[p][c]));
                assert!((gm - m).abs() <= 1e-4 * m.abs() + 1e-9, "{mode:?} pixel {p} channel {c}: mean {gm} against {m}");
                assert!((gv - v).abs() <= 1e-4 * v + 1e-6 * m * m + 1e-12, "{mode:?} pixel {p} channel {c}: variance {gv} against {v} (mean {m})");
                noisy += usize::from(v > 1e-3 * m * m && v > 0.0);
            }
        }
        // The check means something only where the frames differ.
        assert!(noisy > variance.len(), "{mode:?}: only {noisy} noisy channel-pixels");
        assert_no_nonfinite_samples(&r, "variance run");
    }
    assert_no_validation_errors(&ctx);
}
