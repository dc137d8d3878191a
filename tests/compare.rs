//! Image metrics (`restir_vpl::eval::compare`) and the `restir-vpl compare` command. CPU only.

use std::path::Path;
use std::process::{Command, Output};

use restir_vpl::eval::compare::{compare, error_image, to_srgb8, CompareOptions};
use restir_vpl::output::{write_exr, RgbImage};

fn image(width: u32, height: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> RgbImage {
    let pixels = (0..height).flat_map(|y| (0..width).map(move |x| (x, y))).map(|(x, y)| f(x, y)).collect();
    RgbImage { width, height, pixels }
}

/// A smooth gradient with some structure, values in [0, 1].
fn scene(width: u32, height: u32) -> RgbImage {
    image(width, height, |x, y| {
        let u = x as f32 / width as f32;
        let v = y as f32 / height as f32;
        [u, v, 0.5 + 0.4 * ((x / 4 + y / 4) % 2) as f32 * (1.0 - u)]
    })
}

fn no_flip() -> CompareOptions {
    CompareOptions { flip: false, ..CompareOptions::default() }
}

#[test]
fn identical_images() {
    let a = scene(32, 24);
    let c = compare(&a, &a.clone(), &CompareOptions::default()).unwrap();
    assert_eq!((c.width, c.height, c.pixels, c.pixels_compared), (32, 24, 768, 768));
    assert_eq!(c.rmse, 0.0);
    assert_eq!(c.relmse, 0.0);
    assert_eq!(c.mean_ratio, 1.0);
    assert_eq!(c.flip, Some(0.0));
    assert!(!c.has_non_finite());
}

#[test]
fn black_images_ratio_is_one_and_zero_mean_reference_is_not_nan() {
    let black = image(4, 4, |_, _| [0.0; 3]);
    let c = compare(&black, &black, &CompareOptions::default()).unwrap();
    assert_eq!(c.mean_ratio, 1.0);
    let grey = image(4, 4, |_, _| [0.5; 3]);
    let c = compare(&grey, &black, &no_flip()).unwrap();
    assert_eq!(c.mean_ratio, f64::INFINITY);
    // The printed table says so in words ("inf" read as a number; the JSON writes null).
    let t = restir_vpl::eval::compare::table(&c);
    assert!(t.contains("mean ratio       none: the reference's mean is 0") && !t.contains("inf"), "{t}");
}

#[test]
fn constant_offset_rmse() {
    // Values on a 1/256 grid and offsets that keep every sum exact in f32: RMSE is exactly c.
    let b = image(16, 16, |x, y| [x as f32 / 256.0, y as f32 / 16.0, 2.0 + (x + y) as f32 / 64.0]);
    for offset in [0.25f32, 1.0 / 1024.0, 3.0, -0.5] {
        let a = RgbImage { pixels: b.pixels.iter().map(|p| p.map(|v| v + offset)).collect(), ..b.clone() };
        let c = compare(&a, &b, &no_flip()).unwrap();
        let want = offset.abs() as f64;
        assert!((c.rmse - want).abs() <= 1e-6 * want, "offset {offset}: rmse {}", c.rmse);
        assert_eq!(c.mean_ratio > 1.0, offset > 0.0);
        assert_eq!(c.flip, None);
    }
}

#[test]
fn relmse_hand_computed() {
    // 2x1: pixel 0 a = (1, 2, 0), b = (0, 1, 0.1); pixel 1 a = (0.5, 0.5, 0.5), b = (0.5, 0, 1).
    let a = RgbImage { width: 2, height: 1, pixels: vec![[1.0, 2.0, 0.0], [0.5, 0.5, 0.5]] };
    let b = RgbImage { width: 2, height: 1, pixels: vec![[0.0, 1.0, 0.1], [0.5, 0.0, 1.0]] };
    let terms = [
        1.0 / (0.0 + 0.01),  // (1-0)^2 / (0 + 0.01) = 100
        1.0 / (1.0 + 0.01),  // (2-1)^2 / 1.01
        0.01 / (0.01 + 0.01), // (0-0.1)^2 / 0.02 = 0.5
        0.0,                 // equal
        0.25 / (0.0 + 0.01), // (0.5-0)^2 / 0.01 = 25
        0.25 / (1.0 + 0.01), // (0.5-1)^2 / 1.01
    ];
    let expect = terms.iter().sum::<f64>() / 6.0;
    let c = compare(&a, &b, &no_flip()).unwrap();
    assert!((c.relmse - expect).abs() < 1e-6 * expect, "relmse {} expected {expect}", c.relmse);
    let se: f64 = [1.0, 1.0, 0.01, 0.0, 0.25, 0.25].iter().sum();
    assert!((c.rmse - (se / 6.0f64).sqrt()).abs() < 1e-7);
    let ratio = (1.0 + 2.0 + 0.0 + 0.5 + 0.5 + 0.5) / (0.0 + 1.0 + 0.1 + 0.5 + 0.0 + 1.0);
    assert!((c.mean_ratio - ratio).abs() < 1e-6, "{} vs {ratio}", c.mean_ratio);
}

#[test]
fn nan_pixel_reported_and_excluded() {
    let b = scene(8, 6);
    let mut a = b.clone();
    a.pixels[2 * 8 + 5] = [f32::NAN, 0.0, 0.0]; // (5, 2)
    a.pixels[4 * 8 + 1] = [0.0, f32::INFINITY, 0.0]; // (1, 4)
    let c = compare(&a, &b, &CompareOptions::default()).unwrap();
    assert_eq!(c.non_finite_a.nan, 1);
    assert_eq!(c.non_finite_a.inf, 1);
    assert_eq!(c.non_finite_a.first, vec![(5, 2), (1, 4)]);
    assert_eq!(c.non_finite_b.count(), 0);
    assert!(c.has_non_finite());
    assert_eq!(c.pixels_compared, 48 - 2);
    // Excluded: the remaining pixels are identical.
    assert_eq!(c.rmse, 0.0);
    assert_eq!(c.relmse, 0.0);
    assert_eq!(c.mean_ratio, 1.0);
    let f = c.flip.unwrap();
    assert!(f.is_finite() && f > 0.0, "FLIP sees the bad pixels as black: {f}");
    let d = c.non_finite_a.describe();
    assert!(d.contains("(5, 2)") && d.contains("1 NaN"), "{d}");
}

#[test]
fn worst_share_tells_fireflies_from_spread_noise() {
    // 100×100 = 10,000 pixels: the worst 0.1% are 10 pixels.
    let b = image(100, 100, |_, _| [0.5, 0.5, 0.5]);
    let spread = image(100, 100, |_, _| [0.6, 0.6, 0.6]);
    let c = compare(&spread, &b, &no_flip()).unwrap();
    assert!((c.worst_share - 0.001).abs() < 1e-9, "{}", c.worst_share);
    // One firefly of +100 among pixels off by 0.01: it carries 1e4 / (1e4 + 9999·1e-4) of the error.
    let firefly = image(100, 100, |x, y| if (x, y) == (3, 7) { [100.5; 3] } else { [0.51; 3] });
    let c = compare(&firefly, &b, &no_flip()).unwrap();
    assert!(c.worst_share > 0.9999, "{}", c.worst_share);
    assert_eq!(compare(&b, &b, &no_flip()).unwrap().worst_share, 0.0);
}

#[test]
fn size_mismatch_names_both_sizes() {
    let e = compare(&scene(8, 6), &scene(6, 8), &CompareOptions::default()).unwrap_err().to_string();
    assert!(e.contains("8x6") && e.contains("6x8"), "{e}");
}

#[test]
fn flip_sees_a_visible_difference() {
    let b = scene(64, 48);
    let a = image(64, 48, |x, y| if (x / 8 + y / 8) % 2 == 0 { [1.0, 0.2, 0.2] } else { b.pixels[(y * 64 + x) as usize] });
    let c = compare(&a, &b, &CompareOptions::default()).unwrap();
    let f = c.flip.unwrap();
    assert!(f > 0.05 && f <= 1.0, "FLIP {f}");
    // A brighter exposure of the same pair changes FLIP (exposure is applied).
    let c2 = compare(&a, &b, &CompareOptions { exposure: -3.0, ..CompareOptions::default() }).unwrap();
    assert_ne!(c2.flip.unwrap(), f);
}

#[test]
fn srgb_mapping_matches_the_png_tonemap() {
    let img = RgbImage { width: 4, height: 1, pixels: vec![[0.0, 1.0, 2.0], [f32::NAN, 0.5, 0.0], [-1.0, 0.002, 0.2140], [0.25, 0.0, 0.0]] };
    let q = to_srgb8(&img, 0.0);
    assert_eq!(&q[0..3], &[0, 255, 255]);
    assert_eq!(&q[3..6], &[0, 0, 0], "a non-finite pixel is black");
    assert_eq!(q[6], 0);
    assert_eq!(q[7], (12.92f32 * 0.002 * 255.0).round() as u8);
    // The expected bytes from the sRGB curve in f64, written out independently of the code under
    // test (0.214 lands near 0.5, a rounding boundary: 127.49).
    let srgb8 = |x: f64| ((1.055 * x.powf(1.0 / 2.4) - 0.055) * 255.0).round() as u8;
    assert_eq!(q[8], srgb8(0.214));
    // +1 EV doubles the input: 0.25 -> 0.5.
    assert_eq!(to_srgb8(&img, 1.0)[9], srgb8(0.5));
}

#[test]
fn error_image_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("err.png");
    let b = scene(16, 8);
    let a = image(16, 8, |_, _| [1.0, 1.0, 1.0]);
    error_image(&a, &b, &CompareOptions::default(), &p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    // A 16×8 image that shows where the two differ: not one colour.
    let png = image::load_from_memory(&bytes).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (16, 8));
    let first = *png.get_pixel(0, 0);
    assert!(png.pixels().any(|p| *p != first), "the error image is one colour");
}

// ---- the command line ----

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_restir-vpl"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .output()
        .expect("binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn save(dir: &Path, name: &str, img: &RgbImage) -> String {
    let p = dir.join(name);
    write_exr(&p, img.width, img.height, &img.pixels).unwrap();
    p.display().to_string()
}

#[test]
fn cli_clean_input() {
    let dir = tempfile::tempdir().unwrap();
    let b = scene(24, 16);
    let a = RgbImage { pixels: b.pixels.iter().map(|p| p.map(|v| v + 0.25)).collect(), ..b.clone() };
    let (pa, pb) = (save(dir.path(), "a.exr", &a), save(dir.path(), "b.exr", &b));
    let json = dir.path().join("m.json");
    let png = dir.path().join("err.png");
    let o = run(&["compare", &pa, &pb, "--json", &json.display().to_string(), "--error-image", &png.display().to_string()]);
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    let out = stdout(&o);
    for k in ["RMSE", "relMSE", "mean ratio", "FLIP", "2.500000e-1", "384"] {
        assert!(out.contains(k), "stdout should contain '{k}':\n{out}");
    }
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!((v["comparison"]["rmse"].as_f64().unwrap() - 0.25).abs() < 1e-6, "{v}");
    assert!(v["comparison"]["flip"].as_f64().unwrap() > 0.0);
    assert!(png.is_file());

    let o = run(&["compare", &pb, &pb, "--no-flip"]);
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    assert!(stdout(&o).contains("not computed"), "{}", stdout(&o));
}

#[test]
fn cli_nan_pixel_fails_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let b = scene(8, 8);
    let mut a = b.clone();
    a.pixels[3 * 8 + 2] = [f32::NAN; 3];
    let (pa, pb) = (save(dir.path(), "with_nan.exr", &a), save(dir.path(), "ref.exr", &b));
    let o = run(&["compare", &pa, &pb]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("with_nan.exr") && err.contains("(2, 3)") && err.contains("1 non-finite pixel"), "{err}");
    assert!(!err.contains("ref.exr:"), "the clean reference is not reported: {err}");
    // The metrics over the finite pixels are still printed.
    assert!(stdout(&o).contains("RMSE") && stdout(&o).contains("63 compared"), "{}", stdout(&o));
}

/// With no pixel finite in both images there are no metrics: printing and writing RMSE 0 and mean
/// ratio 1 (a perfect match's values) is what the command did.
#[test]
fn cli_no_pixel_compared_gives_no_metrics() {
    let dir = tempfile::tempdir().unwrap();
    let b = scene(4, 4);
    let a = RgbImage { pixels: vec![[f32::NAN; 3]; 16], ..b.clone() };
    let (pa, pb) = (save(dir.path(), "all_nan.exr", &a), save(dir.path(), "ref.exr", &b));
    let json = dir.path().join("m.json");
    let o = run(&["compare", &pa, &pb, "--no-flip", "--json", &json.display().to_string()]);
    assert_eq!(o.status.code(), Some(3), "stderr: {}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("0 compared") && out.contains("no pixel is finite in both images") && !out.contains("RMSE             0"), "{out}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // (FLIP's settings too: with --no-flip it was not computed, and its exposure and pixels per
    // degree were written as if it had been.)
    for k in ["rmse", "relmse", "mean_ratio", "worst_share", "flip", "flip_exposure", "flip_ppd"] {
        assert!(v["comparison"][k].is_null(), "{k}: {v}");
    }
}

#[test]
fn cli_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let pb = save(dir.path(), "b.exr", &scene(4, 4));
    let o = run(&["compare", "/nonexistent/a.exr", &pb]);
    let err = stderr(&o);
    assert!(!o.status.success() && o.status.code() != Some(3), "{err}");
    assert!(err.contains("/nonexistent/a.exr") && !err.contains("panicked"), "{err}");
}

/// An output named like an input (also through another spelling of its path) is refused before
/// anything is written: it replaced the image with a PNG or with JSON, exit 0.
#[test]
fn cli_outputs_never_replace_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let (pa, pb) = (save(dir.path(), "a.exr", &scene(4, 4)), save(dir.path(), "b.exr", &scene(4, 4)));
    let before = std::fs::read(&pa).unwrap();
    let other_spelling = dir.path().join(".").join("a.exr").display().to_string();
    let sibling = dir.path().join("out.json").display().to_string();
    for (args, want) in [
        (vec!["--error-image", pa.as_str()], "--error-image"),
        (vec!["--json", other_spelling.as_str()], "--json"),
        (vec!["--json", pb.as_str()], "--json"),
        (vec!["--json", sibling.as_str(), "--error-image", sibling.as_str()], "both name"),
    ] {
        let mut all = vec!["compare", pa.as_str(), pb.as_str()];
        all.extend(args);
        let o = run(&all);
        let err = stderr(&o);
        assert!(!o.status.success() && err.contains(want) && !err.contains("panicked"), "{all:?}: {err}");
    }
    assert_eq!(std::fs::read(&pa).unwrap(), before, "the input is untouched");
    assert!(!dir.path().join("out.json").exists());
}

#[test]
fn cli_size_mismatch() {
    let dir = tempfile::tempdir().unwrap();
    let (pa, pb) = (save(dir.path(), "a.exr", &scene(4, 4)), save(dir.path(), "b.exr", &scene(5, 4)));
    let o = run(&["compare", &pa, &pb]);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("4x4") && err.contains("5x4") && !err.contains("panicked"), "{err}");
}

#[test]
fn flip_pixels_per_degree_outside_its_range_are_refused_and_its_ends_give_finite_flip() {
    let b = scene(32, 24);
    let a = image(32, 24, |x, y| if (x / 8 + y / 8) % 2 == 0 { [1.0, 0.2, 0.2] } else { b.pixels[(y * 32 + x) as usize] });
    let (lo, hi) = (*restir_vpl::eval::compare::PPD_RANGE.start(), *restir_vpl::eval::compare::PPD_RANGE.end());
    for ppd in [lo, hi] {
        let f = compare(&a, &b, &CompareOptions { ppd, ..CompareOptions::default() }).unwrap().flip.unwrap();
        assert!(f.is_finite() && (0.0..=1.0).contains(&f), "ppd {ppd}: FLIP {f}");
    }
    // 1e-20 gave FLIP NaN with exit 0 before the range check.
    for bad in ["1e-20", "0.5", "20000", "inf"] {
        let dir = tempfile::tempdir().unwrap();
        let (pa, pb) = (save(dir.path(), "a.exr", &a), save(dir.path(), "b.exr", &b));
        let o = run(&["compare", &pa, &pb, "--ppd", bad]);
        let err = stderr(&o);
        assert!(o.status.code() == Some(2) && err.contains("--ppd") && !err.contains("panicked"), "--ppd {bad}: exit status 2 (bad arguments, `compare --help`): {:?} {err}", o.status.code());
    }
    // An output named like an input is a bad argument too (2), a missing input another error (1).
    let dir = tempfile::tempdir().unwrap();
    let (pa, pb) = (save(dir.path(), "a.exr", &a), save(dir.path(), "b.exr", &b));
    let o = run(&["compare", &pa, &pb, "--json", &pa]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("is also the input"), "{}", stderr(&o));
    let missing = dir.path().join("missing.exr").display().to_string();
    let o = run(&["compare", &missing, &pb]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

/// `cargo test --release --test compare -- --ignored --nocapture flip_timing`: FLIP's cost at 1280×720.
#[test]
#[ignore]
fn flip_timing_1280x720() {
    let b = scene(1280, 720);
    let a = image(1280, 720, |x, y| {
        let p = b.pixels[(y * 1280 + x) as usize];
        let n = ((x.wrapping_mul(7919) ^ y.wrapping_mul(104729)) % 1000) as f32 / 5000.0;
        p.map(|v| v + n)
    });
    let time = |opts: CompareOptions| {
        let runs = 5;
        let t = std::time::Instant::now();
        let mut c = None;
        for _ in 0..runs {
            c = Some(compare(&a, &b, &opts).unwrap());
        }
        (t.elapsed().as_secs_f64() * 1e3 / runs as f64, c.unwrap())
    };
    let (ms_flip, c) = time(CompareOptions::default());
    let (ms_plain, _) = time(no_flip());
    println!("1280x720: compare with FLIP {ms_flip:.1} ms (FLIP {:.4}), without {ms_plain:.1} ms", c.flip.unwrap());
}
