//! Partial references with frame counts (`restir_vpl::eval::reference`): metadata round trip, merging,
//! and the errors that keep non-mergeable parts apart. CPU only.

use std::process::Command;

use restir_vpl::output::{write_exr, RgbImage};
use restir_vpl::eval::reference::{merge, read_reference, write_reference, ReferenceMeta};

fn image(width: u32, height: u32, seed: u32) -> RgbImage {
    let pixels = (0..width * height)
        .map(|i| {
            let h = (i.wrapping_mul(2654435761).wrapping_add(seed.wrapping_mul(40503))) % 10007;
            let v = h as f32 / 1000.0;
            [v, 0.5 * v + seed as f32, (i % 7) as f32 * 0.1 + 1e-3 * seed as f32]
        })
        .collect();
    RgbImage { width, height, pixels }
}

fn meta(frames: u64, first_frame: u64) -> ReferenceMeta {
    ReferenceMeta::new(frames, first_frame, 7, "pt", "scenes/cornell_box.gltf", 12, 10, "bounces=8;aa=1")
}

#[test]
fn merge_two_parts_from_files() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (image(12, 10, 1), image(12, 10, 2));
    let (ma, mb) = (meta(3, 0), meta(5, 3));
    let (pa, pb) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
    write_reference(&pa, &a, &ma).unwrap();
    write_reference(&pb, &b, &mb).unwrap();

    // Round trip: pixels bit-exact, metadata equal.
    let (ra, rma) = read_reference(&pa).unwrap();
    assert_eq!(rma, ma);
    assert_eq!(rma.ranges, vec![(0, 3)]);
    assert_eq!((ra.width, ra.height), (12, 10));
    assert!(ra.pixels.iter().zip(&a.pixels).all(|(x, y)| x.map(f32::to_bits) == y.map(f32::to_bits)));
    let rb = read_reference(&pb).unwrap();

    let (m, mm) = merge(&[(ra.clone(), rma.clone()), rb.clone()]).unwrap();
    assert_eq!(mm.frames, 8);
    assert_eq!(mm.first_frame, 0);
    assert_eq!(mm.ranges, vec![(0, 8)]);
    assert!(mm.is_contiguous());
    assert_eq!((mm.seed, mm.mode.as_str(), mm.config.as_str()), (7, "pt", "bounces=8;aa=1"));
    for (i, p) in m.pixels.iter().enumerate() {
        for (c, &v) in p.iter().enumerate() {
            let want = (3.0 * a.pixels[i][c] as f64 + 5.0 * b.pixels[i][c] as f64) / 8.0;
            assert!((v as f64 - want).abs() <= 1e-6 * want.abs().max(1.0), "pixel {i} channel {c}: {v} vs {want}");
        }
    }

    // Order independent, bit for bit.
    let (m2, mm2) = merge(&[rb, (ra, rma)]).unwrap();
    assert_eq!(mm2, mm);
    assert!(m2.pixels.iter().zip(&m.pixels).all(|(x, y)| x.map(f32::to_bits) == y.map(f32::to_bits)));

    // The merged reference round-trips too, and merges with a later part.
    let pc = dir.path().join("c.exr");
    write_reference(&pc, &m, &mm).unwrap();
    let (rc, rmc) = read_reference(&pc).unwrap();
    assert_eq!(rmc, mm);
    let (_, m3) = merge(&[(rc, rmc), (image(12, 10, 3), meta(2, 10))]).unwrap();
    assert_eq!(m3.frames, 10);
    assert_eq!(m3.ranges, vec![(0, 8), (10, 12)]);
    assert!(!m3.is_contiguous());
    assert_eq!(m3.describe_frames(), "10 frames: [0, 8) [10, 12)");
}

#[test]
fn metadata_survives_non_ascii_scene_names() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("r.exr");
    let mut m = meta(4, 2);
    m.scene = "scènes/コーネル.gltf".into();
    write_reference(&p, &image(12, 10, 0), &m).unwrap();
    assert_eq!(read_reference(&p).unwrap().1, m);
}

#[test]
fn noise_estimate_round_trips_and_merges() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("r.exr");
    let mut ma = meta(3, 0);
    ma.noise_mse = Some(0.125);
    write_reference(&p, &image(12, 10, 0), &ma).unwrap();
    assert_eq!(read_reference(&p).unwrap().1, ma);
    let mut mb = meta(5, 3);
    mb.noise_mse = Some(0.0625);
    // Variance of the weighted mean: (3/8)^2 * 0.125 + (5/8)^2 * 0.0625.
    let (_, m) = merge(&[(image(12, 10, 0), ma.clone()), (image(12, 10, 1), mb)]).unwrap();
    let want = (3.0f64 / 8.0).powi(2) * 0.125 + (5.0f64 / 8.0).powi(2) * 0.0625;
    assert!((m.noise_mse.unwrap() - want).abs() < 1e-15);
    // Unknown in one part (one frame has no variance: a top-up by a single frame): that part takes
    // the others' per-frame variance, 3 × 0.125 here, so the merge keeps an estimate (it was None,
    // and the results page then said "unknown"). Unknown in every part: unknown.
    let (_, m) = merge(&[(image(12, 10, 0), ma.clone()), (image(12, 10, 1), meta(5, 3))]).unwrap();
    let want = (3.0f64 / 8.0).powi(2) * 0.125 + (5.0f64 / 8.0).powi(2) * (3.0 * 0.125 / 5.0);
    assert!((m.noise_mse.unwrap() - want).abs() < 1e-15, "{:?}", m.noise_mse);
    let (_, m) = merge(&[(image(12, 10, 0), meta(3, 0)), (image(12, 10, 1), meta(5, 3))]).unwrap();
    assert_eq!(m.noise_mse, None);
    // A negative or non-finite estimate (a hand-edited header) is refused, not merged.
    for bad in [-1.0, f64::INFINITY, f64::NAN] {
        let mut mc = ma.clone();
        mc.noise_mse = Some(bad);
        let e = format!("{:#}", merge(&[(image(12, 10, 0), mc)]).unwrap_err());
        assert!(e.contains("noise_mse"), "{bad}: {e}");
    }
}

#[test]
fn overlapping_ranges_are_refused() {
    let e = merge(&[(image(12, 10, 1), meta(3, 0)), (image(12, 10, 2), meta(5, 2))]).unwrap_err().to_string();
    assert!(e.contains("overlap") && e.contains("part #1") && e.contains("part #2"), "{e}");
    assert!(e.contains("[0, 3)") && e.contains("[2, 7)"), "{e}");
    // The same part twice.
    let e = merge(&[(image(12, 10, 1), meta(3, 0)), (image(12, 10, 1), meta(3, 0))]).unwrap_err().to_string();
    assert!(e.contains("overlap"), "{e}");
}

#[test]
fn different_settings_are_refused() {
    let a = (image(12, 10, 1), meta(3, 0));
    let mut mb = meta(5, 3);
    mb.config = "bounces=4;aa=1".into();
    let e = merge(&[a.clone(), (image(12, 10, 2), mb)]).unwrap_err().to_string();
    assert!(e.contains("settings") && e.contains("part #1") && e.contains("part #2"), "{e}");
    // Settings (as `reference` writes them: JSON) are compared key by key and the message names
    // only the keys that differ.
    let config = |bounces: i32| format!(r#"{{"mode":"pt","max_bounces":{bounces},"aa":false,"scene_hash":"1"}}"#);
    let (mut ma, mut mb) = (meta(3, 0), meta(5, 3));
    (ma.config, mb.config) = (config(8), config(2));
    let e = merge(&[(image(12, 10, 1), ma), (image(12, 10, 2), mb)]).unwrap_err().to_string();
    assert!(e.contains("settings: max_bounces 8 vs 2") && !e.contains("aa") && !e.contains("scene_hash"), "{e}");

    let mut mb = meta(5, 3);
    mb.seed = 8;
    mb.mode = "restir".into();
    let e = merge(&[a.clone(), (image(12, 10, 2), mb)]).unwrap_err().to_string();
    assert!(e.contains("seed") && e.contains("mode"), "{e}");

    let mut mb = ReferenceMeta::new(5, 3, 7, "pt", "scenes/cornell_box.gltf", 10, 12, "bounces=8;aa=1");
    mb.scene = "other.gltf".into();
    let e = merge(&[a, (image(10, 12, 2), mb)]).unwrap_err().to_string();
    assert!(e.contains("12x10") && e.contains("10x12") && e.contains("scene"), "{e}");

    assert!(merge(&[]).is_err());
}

#[test]
fn plain_exr_is_not_a_reference() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("final.exr");
    let img = image(12, 10, 0);
    write_exr(&p, 12, 10, &img.pixels).unwrap();
    let e = format!("{:#}", read_reference(&p).unwrap_err());
    assert!(e.contains("final.exr") && e.contains("not a restir-vpl reference") && e.contains("`restir-vpl reference`"), "{e}");
    let e = format!("{:#}", read_reference(&dir.path().join("missing.exr")).unwrap_err());
    assert!(e.contains("missing.exr"), "{e}");
}

#[test]
fn cli_merge_references() {
    let dir = tempfile::tempdir().unwrap();
    let (pa, pb, pc) = (dir.path().join("a.exr"), dir.path().join("b.exr"), dir.path().join("c.exr"));
    write_reference(&pa, &image(12, 10, 1), &meta(3, 0)).unwrap();
    write_reference(&pb, &image(12, 10, 2), &meta(5, 3)).unwrap();
    let bin = env!("CARGO_BIN_EXE_restir-vpl");
    let o = Command::new(bin)
        .args(["merge-references", &pb.display().to_string(), &pa.display().to_string(), "--out", &pc.display().to_string()])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "stderr: {}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("8 frames: [0, 8)") && out.contains("contiguous"), "{out}");
    assert_eq!(read_reference(&pc).unwrap().1.frames, 8);

    // Overlap through the CLI names the files.
    let o = Command::new(bin)
        .args(["merge-references", &pa.display().to_string(), &pa.display().to_string(), "--out", &pc.display().to_string()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("a.exr") && err.contains("overlap") && !err.contains("panicked"), "{err}");

    // An existing --out is replaced only with --overwrite.
    let merge_into_c = |extra: &[&str]| {
        let (a, b, c) = (pa.display().to_string(), pb.display().to_string(), pc.display().to_string());
        let mut args = vec!["merge-references", &a, &b, "--out", &c];
        args.extend_from_slice(extra);
        Command::new(bin).args(&args).output().unwrap()
    };
    let before = std::fs::read(&pc).unwrap();
    let o = merge_into_c(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("c.exr") && err.contains("--overwrite") && !err.contains("panicked"), "{err}");
    assert_eq!(std::fs::read(&pc).unwrap(), before, "the existing reference is untouched");
    let o = merge_into_c(&["--overwrite"]);
    assert!(o.status.success(), "stderr: {}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read_reference(&pc).unwrap().1.frames, 8);
    // A missing directory of --out is created, as `reference --out` does.
    let deep = dir.path().join("new/dir/m.exr");
    let o = Command::new(bin)
        .args(["merge-references", &pa.display().to_string(), &pb.display().to_string(), "--out", &deep.display().to_string()])
        .output()
        .unwrap();
    assert!(o.status.success(), "stderr: {}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read_reference(&deep).unwrap().1.frames, 8);
    // A directory as --out is named as one (the advice was "pass --overwrite", which then failed).
    let o = Command::new(bin)
        .args(["merge-references", &pa.display().to_string(), &pb.display().to_string(), "--out", &dir.path().display().to_string()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("is a directory") && !err.contains("--overwrite"), "{err}");
}

/// A part with a NaN or Inf pixel is refused (it would spread into the merge, which `compare`
/// then rejects), and so is an --out that is one of the parts.
#[test]
fn non_finite_parts_and_out_over_an_input_are_refused() {
    for bad in [f32::NAN, f32::INFINITY] {
        let mut img = image(12, 10, 2);
        img.pixels[12 * 3 + 5][1] = bad;
        let e = format!("{:#}", merge(&[(image(12, 10, 1), meta(3, 0)), (img, meta(5, 3))]).unwrap_err());
        assert!(e.contains("part #2") && e.contains("NaN or Inf") && e.contains("(5, 3)"), "{e}");
    }
    let dir = tempfile::tempdir().unwrap();
    let (pa, pb) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
    write_reference(&pa, &image(12, 10, 1), &meta(3, 0)).unwrap();
    write_reference(&pb, &image(12, 10, 2), &meta(5, 3)).unwrap();
    let before = std::fs::read(&pb).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_restir-vpl"))
        .args(["merge-references", &pa.display().to_string(), &pb.display().to_string(), "--out", &pb.display().to_string()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--out") && err.contains("b.exr") && !err.contains("panicked"), "{err}");
    assert_eq!(std::fs::read(&pb).unwrap(), before, "the input is untouched");
}

/// A reference's config keeps only what its mode's image depends on: a path-traced reference
/// survives a change of ReSTIR's or the VPLs' settings, a RIS reference one of ReSTIR's, and none
/// survives a change of what it does use. Configs written before a key was dropped still match.
#[test]
fn reference_configs_ignore_settings_the_mode_does_not_use() {
    use restir_vpl::eval::reference::{reference_config, same_config};
    use restir_vpl::settings::{Bias, Mode, RenderSettings};
    let config = |f: &dyn Fn(&mut RenderSettings)| {
        let mut s = RenderSettings::default();
        f(&mut s);
        reference_config(&s, "abc").unwrap()
    };
    let pt = config(&|s| s.mode = Mode::Pt);
    let pt_other_restir = config(&|s| {
        s.mode = Mode::Pt;
        s.restir.bias = Bias::Biased;
        s.vpls_direct = 7;
        s.candidates = 3;
    });
    assert!(same_config(&pt, &pt_other_restir));
    // A setting at its default None matches a file written before it existed (null = absent).
    let mut with_null: serde_json::Value = serde_json::from_str(&pt).unwrap();
    with_null["a_later_setting"] = serde_json::Value::Null;
    assert!(same_config(&pt, &with_null.to_string()));
    with_null["a_later_setting"] = serde_json::json!(3);
    assert!(!same_config(&pt, &with_null.to_string()));
    // Debugging, output and speed-only flags never change the image. (A workgroup in the config
    // made every reference written before --workgroup existed unusable by `results`; so did the
    // way of tracing, whose images are bit-identical both ways, for references before --trace.)
    assert_eq!(pt, config(&|s| {
        s.mode = Mode::Pt;
        s.check_finite = true;
        s.renderdoc_capture = Some(3);
        s.workgroup = [16, 4];
        s.fuse_passes = Some(true);
        s.tracing = Some(restir_vpl::vk::context::Tracing::Pipeline);
    }));
    assert!(!same_config(&pt, &config(&|s| {
        s.mode = Mode::Pt;
        s.max_bounces = 2;
    })));
    assert!(!same_config(&pt, &config(&|s| s.mode = Mode::Ris)));

    let ris = config(&|s| s.mode = Mode::Ris);
    assert!(same_config(&ris, &config(&|s| {
        s.mode = Mode::Ris;
        s.restir.mcap = 3.0;
    })));
    assert!(!same_config(&ris, &config(&|s| {
        s.mode = Mode::Ris;
        s.candidates = 3;
    })));
    // Every flag a reference run warns "has no effect here" about is left out, so a resume
    // without it matches (a RIS file made with --max-bounces 3 was refused: "max_bounces 3 vs 8").
    let unused = |mode: Mode, flags: &[&str], f: &dyn Fn(&mut RenderSettings)| {
        let mut s = RenderSettings { mode, ..Default::default() };
        f(&mut s);
        let warned = s.unused_flags(flags);
        assert_eq!(warned.len(), flags.len(), "{mode:?}: {flags:?} should all be unused: {warned:?}");
        assert!(same_config(&reference_config(&s, "abc").unwrap(), &config(&|d| d.mode = mode)), "{mode:?}: {flags:?}");
    };
    for mode in [Mode::Ris, Mode::Uniform, Mode::Bruteforce] {
        unused(mode, &["max_bounces", "vpl_radius"], &|s| {
            s.max_bounces = 3;
            s.vpl_radius = Some(0.5);
        });
    }
    unused(Mode::Uniform, &["presample"], &|s| s.presample = !s.presample);
    unused(Mode::Pt, &["yuksel_spacings", "yuksel_knn", "no_gi", "presample"], &|s| {
        s.yuksel_spacings = Some(4.0);
        s.yuksel_knn = Some(3);
        s.gi = false;
        s.presample = !s.presample;
    });
    // Without GI the indirect VPLs' settings shape nothing (GI itself does).
    let no_gi = |f: &dyn Fn(&mut RenderSettings)| {
        config(&|s| {
            s.mode = Mode::Ris;
            s.gi = false;
            f(s);
        })
    };
    assert!(same_config(&no_gi(&|_| ()), &no_gi(&|s| {
        s.vpls_indirect = 5;
        s.photon_max_bounces = 2;
    })));
    assert!(!same_config(&no_gi(&|_| ()), &ris));
    // ReSTIR with --temporal off (the one a reference takes): its temporal settings do nothing.
    let restir_still = |mcap: f32, boiling: f32| {
        config(&|s| {
            s.mode = Mode::Restir;
            s.restir.temporal = false;
            s.restir.mcap = mcap;
            s.restir.boiling_filter = boiling;
        })
    };
    assert!(same_config(&restir_still(20.0, 0.2), &restir_still(3.0, 0.0)));
    // Without spatial reuse either, the spatial settings and the thresholds do nothing (a file
    // made with --spatial-radius 5 was refused for a resume without it).
    let no_reuse = |radius: Option<f32>, threshold: f32, neighbours: u32| {
        config(&|s| {
            s.mode = Mode::Restir;
            s.restir.temporal = false;
            s.restir.spatial_passes = 0;
            s.restir.spatial_radius = radius;
            s.restir.normal_threshold = threshold;
            s.restir.spatial_neighbours = neighbours;
        })
    };
    let plain = no_reuse(None, 0.9, 4);
    assert!(same_config(&plain, &no_reuse(Some(5.0), 0.5, 8)));
    for (a, b) in [(&plain, &restir_still(20.0, 0.2)), (&no_reuse(None, 0.9, 4), &config(&|s| {
        s.mode = Mode::Restir;
        s.restir.temporal = false;
        s.restir.spatial_radius = Some(5.0);
    }))] {
        assert!(!same_config(a, b), "spatial reuse on or off differs");
    }

    // The ReGIR grid: no key unless RIS or ReSTIR take candidates from it, so references written
    // before it existed still match; with grid candidates the config differs.
    let with_grid = |mode: Mode, candidates: u32| {
        config(&|s| {
            s.mode = mode;
            s.grid.candidates = candidates;
            s.grid.cells = 7;
        })
    };
    assert!(!pt.contains("grid") && !ris.contains("grid"), "{ris}");
    assert_eq!(with_grid(Mode::Pt, 4), pt);
    assert_eq!(with_grid(Mode::Ris, 0), ris);
    assert!(!same_config(&with_grid(Mode::Ris, 4), &ris));
    assert!(with_grid(Mode::Ris, 4).contains("\"grid\""));

    // An older file's config still holds the keys now dropped, with other values.
    let mut old: serde_json::Value = serde_json::from_str(&pt).unwrap();
    old.as_object_mut().unwrap().insert("restir".into(), serde_json::json!({"bias": "biased"}));
    old.as_object_mut().unwrap().insert("candidates".into(), serde_json::json!(4));
    assert!(same_config(&old.to_string(), &pt));
    assert!(!same_config("not json", &pt));
}
