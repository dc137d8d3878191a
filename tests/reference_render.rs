//! References rendered on the GPU: split runs merge into exactly one long run, `--resume` extends a
//! file, and the CLI refuses what would silently mix different settings.

mod common;

use std::process::Command;

use common::*;
use restir_vpl::eval::reference::{merge, read_reference, render_reference};
use restir_vpl::settings::Mode;
use restir_vpl::RenderSettings;

fn settings(mode: Mode) -> RenderSettings {
    RenderSettings {
        scene: repo_path("scenes/cornell_box.gltf"),
        mode,
        vpls_direct: 1000,
        vpls_indirect: 1000,
        ..small(24, 24, 5)
    }
}

/// Largest relative difference between two images (relative to max(|b|, 1e-3)); both must be
/// finite (a NaN would vanish in the max).
fn max_rel_diff(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    assert_all_finite(a, "image a");
    assert_all_finite(b, "image b");
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |c| ((p[c] - q[c]).abs() / q[c].abs().max(1e-3)) as f64))
        .fold(0.0, f64::max)
}

#[test]
fn merged_partial_references_equal_one_long_run() {
    let ctx = context();
    for mode in [Mode::Pt, Mode::Ris] {
        let s = settings(mode);
        let scene = upload(&ctx, &restir_vpl::scene::Scene::load(&s.scene).unwrap(), &s);
        let whole = render_reference(ctx.clone(), scene.clone(), &s, 0, 5, |_| {}).unwrap();
        let a = render_reference(ctx.clone(), scene.clone(), &s, 0, 2, |_| {}).unwrap();
        let b = render_reference(ctx.clone(), scene.clone(), &s, 2, 3, |_| {}).unwrap();
        // The parts are different samples: a part alone is not the whole.
        assert!(max_rel_diff(&a.image.pixels, &whole.image.pixels) > 1e-2, "{mode:?}: parts are not independent");
        let (merged, meta) = merge(&[(b.image, b.meta), (a.image, a.meta)]).unwrap();
        assert_eq!(meta.frames, 5);
        assert_eq!(meta.ranges, vec![(0, 5)]);
        // Frame k draws the same random numbers in every run, so the merge is the long run's mean
        // up to float rounding of the running means (f32, compensated) and of the weighted mean.
        let d = max_rel_diff(&merged.pixels, &whole.image.pixels);
        assert!(d < 1e-4, "{mode:?}: merged 2 + 3 frames differ from 5 frames by {d}");
        // Two estimates of the same noise from the same 5 frames: the parts' sample variances
        // (1 and 2 degrees of freedom per pixel) combined with weights (f_i / f)², and the whole
        // run's (4). They differ by sampling alone: for Gaussian pixels their ratio spreads by
        // about 3 % (one standard deviation) over these 24×24×3 values, far more with the path
        // tracer's heavy tails, where a few bright pixels carry most of the variance. A wrong
        // combination is off by a factor (linear weights f_i / f would give 2×), so 50 % separates
        // the two without flaking.
        let (nm, nw) = (meta.noise_mse.unwrap(), whole.noise_mse.unwrap());
        assert!(nm > 0.0 && (nm / nw - 1.0).abs() < 0.5, "noise estimates {nm} vs {nw}");
    }
    common::assert_no_validation_errors(&ctx);
}

/// Runs the binary, under the validation layer where it is installed (validation errors and
/// non-finite samples then fail the command).
fn cli(args: &[&str]) -> std::process::Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_restir-vpl"));
    c.current_dir(env!("CARGO_MANIFEST_DIR")).args(args);
    if common::validate() {
        c.env("RESTIR_VPL_VALIDATE", "1");
    }
    c.output().expect("run restir-vpl")
}

#[test]
fn cli_reference_resumes_and_refuses_mismatches() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.exr");
    let whole = dir.path().join("whole.exr");
    let p = part.to_str().unwrap();
    let common = ["--mode", "pt", "--width", "16", "--height", "16"];
    let run = |extra: &[&str]| {
        let mut args = vec!["reference"];
        args.extend_from_slice(&common);
        args.extend_from_slice(extra);
        cli(&args)
    };
    let o = run(&["--frames", "2", "--out", p]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("2 frames"));
    // An existing file is never overwritten without --resume.
    let o = run(&["--frames", "2", "--out", p]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--resume"), "{}", String::from_utf8_lossy(&o.stderr));
    // Resuming with other settings is refused, naming the file and what differs.
    let o = run(&["--frames", "1", "--max-bounces", "2", "--resume", "--out", p]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("part.exr") && e.contains("max_bounces") && !e.contains("seed"), "{e}");
    let o = run(&["--frames", "1", "--seed", "7", "--resume", "--out", p]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("seed") && e.contains("vs 7") && !e.contains("max_bounces"), "{e}");
    // Resume: 2 + 3 frames equal one 5-frame reference.
    let o = run(&["--frames", "3", "--resume", "--out", p]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&["--frames", "5", "--out", whole.to_str().unwrap()]);
    assert!(o.status.success());
    let (a, ma) = read_reference(&part).unwrap();
    let (b, mb) = read_reference(&whole).unwrap();
    assert_eq!((ma.frames, ma.ranges.clone()), (5, vec![(0, 5)]));
    assert_eq!(ma.config, mb.config);
    let d = max_rel_diff(&a.pixels, &b.pixels);
    assert!(d < 1e-4, "resumed reference differs from one run by {d}");
    // A resume past 2^32 frames is refused in --resume's terms (it named --first-frame, which
    // goes with it only to be refused).
    let near = dir.path().join("near.exr");
    let end = u64::from(u32::MAX) - 1;
    let meta = restir_vpl::eval::reference::ReferenceMeta { first_frame: end - 5, ranges: vec![(end - 5, end)], ..ma.clone() };
    restir_vpl::eval::reference::write_reference(&near, &a, &meta).unwrap();
    let o = run(&["--frames", "2", "--resume", "--out", near.to_str().unwrap()]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("--resume") && e.contains(&format!("end at {end}")) && !e.contains("--first-frame"), "{e}");
    // Temporal ReSTIR frames depend on each other: not a reference mode.
    let o = cli(&["reference", "--mode", "restir", "--frames", "1", "--out", dir.path().join("x.exr").to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--mode restir"));
    // The ReGIR grid carries state from frame to frame: a part from --first-frame k started with
    // an empty grid, and merged parts differed from one long run.
    let o = cli(&["reference", "--mode", "ris", "--grid-candidates", "8", "--frames", "1", "--out", dir.path().join("x.exr").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--grid-candidates 8") && err.contains("independent"), "{err}");
    // Settings that show each frame alone would write one frame labelled as all of them.
    let y = dir.path().join("y.exr");
    for (flags, named) in [(["--mode", "pt", "--progressive", "off"], "--progressive off"), (["--mode", "ris", "--view", "reservoir-w"], "--view reservoir-w")] {
        let o = cli(&[&["reference", "--width", "16", "--height", "16", "--frames", "2"][..], &flags[..], &["--out", y.to_str().unwrap()]].concat());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(named) && err.contains("mean of its frames"), "{err}");
        assert!(!y.exists());
    }
    // The VPL picture estimates nothing (it was taken, a "reference" with a noise of 0).
    let o = cli(&["reference", "--mode", "ris", "--view", "vpls", "--width", "16", "--height", "16", "--frames", "2", "--out", y.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--view vpls") && !y.exists(), "{err}");
    // A headless run's extra outputs are not a reference's: refused, not ignored.
    let ply = dir.path().join("v.ply");
    let o = run(&["--frames", "1", "--dump-vpls", ply.to_str().unwrap(), "--save-every", "1", "--out", y.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--dump-vpls, --save-every") && err.contains("--headless"), "{err}");
    assert!(!y.exists() && !ply.exists());
    // A camera path: a reference converges one camera, so it is refused (it was ignored: the
    // file was a still camera's image labelled with the path's frames).
    let o = run(&["--frames", "1", "--camera-path", "scenes/cornell_box.path.json", "--out", y.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--camera-path") && err.contains("--eye"), "{err}");
    assert!(!y.exists());
    // The exposure sets only a preview, which a reference does not write: said, not silently taken.
    let o = run(&["--frames", "1", "--exposure", "3", "--out", y.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("--exposure") && err.contains("changes nothing"), "{err}");
}
