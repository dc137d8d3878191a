//! Pass-level debugging: `--dump-passes` writes every pass's outputs in the plan's order with a
//! manifest and an inspector page; what the dump holds is what the passes computed (the final
//! reservoir's W recombined on the CPU reproduces the shaded sample); `--check-finite` names the
//! pass and pixel of a planted NaN and finds none in normal runs.

mod common;

use std::process::Command;

use common::*;
use glam::Vec3;
use restir_vpl::gpu_types::{GpuReservoir, GpuSurface, GpuVpl, RESERVOIR_EMPTY, VPL_DIRECT_POINT};
use restir_vpl::renderer::{CaptureKind, Renderer};
use restir_vpl::scene::Scene;
use restir_vpl::settings::{Attenuation, Mode};
use restir_vpl::RenderSettings;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_restir-vpl"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    if validate() {
        c.arg("--validate");
    }
    c
}

const SMALL: [&str; 10] = ["--headless", "--width", "64", "--height", "64", "--vpls-direct", "2000", "--vpls-indirect", "2000", "--seed"];

#[test]
fn dump_passes_writes_every_pass_in_plan_order_with_a_manifest_and_an_inspector() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    for (list, said) in [("0,all", "'all' stands alone"), ("0,x", "'x' is no frame number")] {
        let o = bin().args(SMALL).args(["3", "--mode", "restir", "--frames", "3", "--dump-passes", list, "--out", out]).output().unwrap();
        assert!(!o.status.success(), "'{list}' is not a valid list");
        assert!(String::from_utf8_lossy(&o.stderr).contains(&format!("--dump-passes '{list}': {said}")), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // Frame numbers and `last` together: frames 0 and 2 of 3.
    let o = bin().args(SMALL).args(["3", "--mode", "restir", "--frames", "3", "--dump-passes", "0,last", "--out", out]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (frame, expect) in [
        // Frame 0: no history yet; frame 2: the G-buffer is kept (still camera) and history reused.
        (0, vec!["gbuffer", "vpl_presample", "restir_initial", "restir_spatial", "vpl_shade", "accumulate"]),
        (2, vec!["vpl_presample", "restir_initial", "restir_temporal", "restir_spatial", "vpl_shade", "accumulate", "tonemap"]),
    ] {
        let fdir = dir.path().join(format!("passes/frame_{frame:04}"));
        let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(fdir.join("manifest.json")).unwrap()).unwrap();
        let passes = m["passes"].as_array().unwrap();
        let ran: Vec<&str> = passes.iter().filter(|p| p["status"] == "run").map(|p| p["pass"].as_str().unwrap()).collect();
        assert_eq!(ran, expect, "frame {frame}: the passes that ran, in order");
        // A skip names why the pass could not run before why it runs apart: in frame 0 there is
        // no temporal pass to fuse; in frame 2 fusion is on (the default) but a dumped frame runs
        // its passes apart.
        let why = |name: &str| passes.iter().find(|p| p["pass"] == name).unwrap()["why"].as_str().unwrap().to_string();
        let fused_why = if frame == 0 { "restir_temporal does not run this frame" } else { "pass outputs captured this frame" };
        assert_eq!(why("restir_initial_temporal"), fused_why, "frame {frame}");
        // Every pass of the plan is listed, the skipped ones with a reason: every pass but
        // photon_emit (run once before the first frame), one spatial pass.
        assert_eq!(passes.len(), restir_vpl::passes::ALL_PASSES.len() - 1, "{m}");
        for p in passes {
            if p["status"] == "skipped" {
                assert!(!p["why"].as_str().unwrap().is_empty(), "{p}");
                continue;
            }
            assert!(p["gpu_ms"].as_f64().unwrap() >= 0.0 && !p["bindings"].as_array().unwrap().is_empty(), "{p}");
            let outputs = p["outputs"].as_array().unwrap();
            // Every dispatch has its position in the frame, vpl_presample too (it had none).
            assert!(p["position"].as_u64().is_some(), "{p}");
            assert!(!outputs.is_empty(), "{p}");
            // vpl_presample's output is its tiles (one per 8×8 block: 64), not an image: each
            // shown as a square of its 1024 entries, eight squares a row.
            let size = if p["pass"] == "vpl_presample" { (256, 256) } else { (64, 64) };
            for o in outputs {
                let file = o["file"].as_str().unwrap();
                assert!(file.starts_with(&format!("{:02}_", p["position"].as_u64().unwrap())), "{file}");
                let img = restir_vpl::output::read_exr(&fdir.join(file)).unwrap();
                assert_eq!((img.width, img.height), size, "{file}");
                assert_eq!(o["groups"]["count"].as_u64(), (p["pass"] == "vpl_presample").then_some(64), "{o}");
                if p["pass"] == "vpl_presample" {
                    assert_eq!((&o["groups"]["unit"], &o["groups"]["side"], &o["groups"]["columns"]), (&serde_json::json!("tile"), &serde_json::json!(32), &serde_json::json!(8)), "{o}");
                }
                assert!(fdir.join(file.replace(".exr", ".png")).exists());
                assert_eq!(o["nonfinite"], 0, "{o}");
                assert!(o["min"].as_f64().unwrap() <= o["mean"].as_f64().unwrap() && o["mean"].as_f64().unwrap() <= o["max"].as_f64().unwrap(), "{o}");
            }
        }
        // Positions count up in the order the passes ran.
        let positions: Vec<u64> = passes.iter().filter_map(|p| p["position"].as_u64()).collect();
        assert_eq!(positions, (0..positions.len() as u64).collect::<Vec<_>>());
    }
    assert!(!dir.path().join("passes/frame_0001").exists(), "frame 1 was not asked for");
    let html = std::fs::read_to_string(dir.path().join("passes/index.html")).unwrap();
    for needle in ["frame 0", "frame 2", "restir_temporal", "skipped: no history before the first frame", "frame_0002/02_restir_temporal__w.png", "const FRAMES"] {
        assert!(html.contains(needle), "index.html lacks {needle:?}");
    }
    assert!(!html.contains("http://") && !html.contains("https://"), "the page must not reach the network");
    assert!(dir.path().join("passes/vpls.ply").exists());

    // A second dump into the same --out replaces the first: no frame of the restir run is left
    // to mix with it (frame 2 stayed, and frame 0 held both runs' files).
    let o = bin().args(SMALL).args(["3", "--mode", "uniform", "--frames", "1", "--dump-passes", "0", "--out", out]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!dir.path().join("passes/frame_0002").exists(), "the earlier run's frame 2 is removed");
    let left: Vec<String> = std::fs::read_dir(dir.path().join("passes/frame_0000")).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert!(left.iter().all(|f| !f.contains("restir_temporal") && !f.contains("restir_spatial")), "{left:?}");

    // A pass dispatched twice: each dispatch has its own position and time (they summed the
    // frame's before), and no per-dispatch ray count (rays are counted per pass).
    let sdir = tempfile::tempdir().unwrap();
    let o = bin().args(SMALL).args(["3", "--mode", "restir", "--frames", "1", "--spatial-passes", "2", "--dump-passes", "0", "--out", sdir.path().to_str().unwrap()]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(sdir.path().join("passes/frame_0000/manifest.json")).unwrap()).unwrap();
    let spatial: Vec<&serde_json::Value> = m["passes"].as_array().unwrap().iter().filter(|p| p["pass"] == "restir_spatial").collect();
    assert_eq!(spatial.len(), 2, "{m}");
    assert_eq!(spatial[1]["position"].as_u64().unwrap(), spatial[0]["position"].as_u64().unwrap() + 1);
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(sdir.path().join("summary.json")).unwrap()).unwrap();
    common::assert_clean_summary(&summary, "--dump-passes run");
    let total = summary["pass_ms"]["restir_spatial"]["mean"].as_f64().unwrap();
    let (a, b) = (spatial[0]["gpu_ms"].as_f64().unwrap(), spatial[1]["gpu_ms"].as_f64().unwrap());
    assert!(a > 0.0 && b > 0.0 && (a + b - total).abs() <= 1e-6 * total.max(1.0), "dispatches {a} + {b} against the frame's {total}");
    assert!(spatial.iter().all(|p| p["rays_per_pixel"].is_null()), "{m}");

    // With --compensate, vpl_compensate runs after vpl_shade and its dumped samples hold the
    // shaded estimate plus what it added (never less: compensation adds light).
    let cdir = tempfile::tempdir().unwrap();
    let cout = cdir.path().to_str().unwrap();
    let o = bin().args(SMALL).args(["3", "--mode", "ris", "--frames", "1", "--compensate", "--yuksel-radius", "0.1", "--dump-passes", "0", "--out", cout]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fdir = cdir.path().join("passes/frame_0000");
    let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(fdir.join("manifest.json")).unwrap()).unwrap();
    let ran: Vec<&str> = m["passes"].as_array().unwrap().iter().filter(|p| p["status"] == "run").map(|p| p["pass"].as_str().unwrap()).collect();
    assert_eq!(ran, ["gbuffer", "vpl_presample", "restir_initial", "vpl_shade", "vpl_compensate", "accumulate", "tonemap"]);
    let shaded = restir_vpl::output::read_exr(&fdir.join("03_vpl_shade__samples.exr")).unwrap();
    let compensated = restir_vpl::output::read_exr(&fdir.join("04_vpl_compensate__samples.exr")).unwrap();
    let (mut more, mut less) = (0, 0);
    for (a, b) in shaded.pixels.iter().zip(&compensated.pixels) {
        for c in 0..3 {
            if b[c] > a[c] {
                more += 1;
            } else if b[c] < a[c] {
                less += 1;
            }
        }
    }
    assert!(less == 0 && more > 0, "compensation only adds light: {more} values grew, {less} shrank");

    // The most outputs a captured frame writes: a moving camera (the G-buffer every frame), the
    // boiling filter (one more reservoir output) and --compensate (a second sample writer). The
    // capture buffer was once sized by a fixed count that this combination overran; it is now
    // sized from the frame's dispatches (an overrun fails the copy hook's assert, and the
    // validation layer where installed).
    let bdir = tempfile::tempdir().unwrap();
    let o = bin()
        .args(SMALL)
        .args(["3", "--mode", "restir", "--frames", "3", "--camera-path", "scenes/cornell_box.path.json", "--progressive", "off"])
        .args(["--boiling-filter", "0.5", "--compensate", "--dump-passes", "2", "--out", bdir.path().to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(bdir.path().join("passes/frame_0002/manifest.json")).unwrap()).unwrap();
    let ran: Vec<&str> = m["passes"].as_array().unwrap().iter().filter(|p| p["status"] == "run").map(|p| p["pass"].as_str().unwrap()).collect();
    assert_eq!(
        ran,
        ["gbuffer", "vpl_presample", "restir_initial", "restir_temporal", "restir_boiling", "restir_spatial", "vpl_shade", "vpl_compensate", "accumulate", "tonemap"]
    );
    assert!(bdir.path().join("passes/frame_0002/04_restir_boiling__w.exr").exists());
}

/// The CPU's c_y(x): (ρ/π)·I(ω)·cos_x·G(d) with Yuksel's G, as method.md and shaders/restir/vpl.glsl.
fn contribution(s: &GpuSurface, v: &GpuVpl, r2: f32) -> Vec3 {
    let to_x = Vec3::from(s.position) - Vec3::from(v.position);
    let d2 = to_x.length_squared();
    let w = to_x / d2.sqrt();
    let cos_x = -Vec3::from(s.shading_normal).dot(w);
    if cos_x <= 0.0 || Vec3::from(s.geometric_normal).dot(w) >= 0.0 {
        return Vec3::ZERO;
    }
    let emit = if v.kind == VPL_DIRECT_POINT { 0.25 } else { Vec3::from(v.normal).dot(w).max(0.0) };
    let g = 2.0 / (d2 + r2 + d2.sqrt() * (d2 + r2).sqrt());
    Vec3::from(s.albedo) / std::f32::consts::PI * Vec3::from(v.flux) * (emit * cos_x * g / std::f32::consts::PI)
}

/// A renderer of the bundled Cornell box with `settings`.
fn cornell_renderer(ctx: &std::sync::Arc<restir_vpl::vk::Context>, settings: RenderSettings) -> Renderer {
    let scene = Scene::load(&repo_path("scenes/cornell_box.gltf")).unwrap();
    let gpu = upload(ctx, &scene, &settings);
    Renderer::new(ctx.clone(), gpu, settings).unwrap()
}

/// vpl_presample's captured tiles hold copies of the VPLs they name (position and flux exact,
/// the normal through its octahedral code), and with the uniform source their indices are uniform
/// over the VPL set: the mean index lies within 4 standard errors of (N − 1)/2 (SE: N/√(12 n)
/// for n draws; 4 SE, a false alarm about once in 16,000 runs).
#[test]
fn presampled_tiles_copy_the_vpls_they_name_drawn_uniformly() {
    let ctx = context();
    let mut r = cornell_renderer(&ctx, RenderSettings { mode: Mode::Ris, vpls_direct: 2000, vpls_indirect: 2000, ..small(64, 64, 1) });
    let camera = r.initial_camera();
    let (_, captured) = r.render_frame_captured(&camera, false).unwrap();
    let vpls = r.read_vpls().unwrap().unwrap();
    let tiles = captured.iter().find(|c| c.pass == "vpl_presample").expect("the tiles are captured");
    assert_eq!((tiles.kind, tiles.buffer, tiles.shape), (CaptureKind::Candidates, "tiles", [1024, 64]));
    let candidates: Vec<restir_vpl::gpu_types::GpuVplCandidate> = bytemuck::pod_collect_to_vec(&tiles.bytes);
    assert_eq!(candidates.len(), tiles.records());
    let index_bits = restir_vpl::gpu_types::CANDIDATE_INDEX_BITS;
    let mut sum = 0f64;
    for c in &candidates {
        let i = (c.vpl_kind & ((1 << index_bits) - 1)) as usize;
        let v = &vpls[i];
        assert_eq!((c.position, c.flux, c.vpl_kind >> index_bits), (v.position, v.flux, v.kind), "entry naming VPL {i}");
        let n = restir_vpl::gpu_types::oct_decode(c.normal_oct);
        assert!((Vec3::from(n) - Vec3::from(v.normal)).length() < 1e-3, "VPL {i}: normal {n:?} against {:?}", v.normal);
        sum += i as f64;
    }
    let (n, count) = (candidates.len() as f64, vpls.len() as f64);
    let se = count / (12.0 * n).sqrt();
    let mean = sum / n;
    assert!((mean - (count - 1.0) / 2.0).abs() < 4.0 * se, "mean index {mean} of {count} VPLs (SE {se})");
    assert!(restir_vpl::dump::nonfinite_records(tiles).is_empty());
    common::assert_no_validation_errors(&ctx);
}

/// regir_build's captured grid: in the frames that build cells (from frame 1, for the cells
/// frame 0's pixels asked for), an entry with W > 0 copies the VPL it names, and every other entry
/// (not built, or no candidate) is zeros: the buffer starts zero-filled, so a cell never built
/// holds no stale memory for --check-finite to trip on. As many cells hold entries as the
/// renderer counts built.
#[test]
fn the_captured_grid_copies_the_vpls_its_entries_name() {
    let ctx = context();
    let grid = restir_vpl::settings::GridSettings { candidates: 4, cells: 6, entries: 64, ..Default::default() };
    let mut r = cornell_renderer(&ctx, RenderSettings { mode: Mode::Ris, candidates: 8, grid, fuse_passes: Some(false), vpls_direct: 2000, vpls_indirect: 2000, ..small(32, 32, 2) });
    let camera = r.initial_camera();
    let vpls = r.read_vpls().unwrap().unwrap();
    let index_bits = restir_vpl::gpu_types::CANDIDATE_INDEX_BITS;
    for frame in 0..2 {
        let (_, captured) = r.render_frame_captured(&camera, false).unwrap();
        let c = captured.iter().find(|c| c.pass == "regir_build").expect("the grid is captured");
        assert_eq!((c.kind, c.buffer, c.shape), (CaptureKind::GridEntries, "entries", [64, 216]));
        let entries: Vec<restir_vpl::gpu_types::GpuGridEntry> = bytemuck::pod_collect_to_vec(&c.bytes);
        let mut cells_with_entries = std::collections::BTreeSet::new();
        for (slot, e) in entries.iter().enumerate() {
            if e.ucw > 0.0 {
                let i = (e.vpl_kind & ((1 << index_bits) - 1)) as usize;
                let v = &vpls[i];
                assert_eq!((e.position, e.flux, e.vpl_kind >> index_bits), (v.position, v.flux, v.kind), "frame {frame}, entry {slot} naming VPL {i}");
                let n = restir_vpl::gpu_types::oct_decode(e.normal_oct);
                assert!((Vec3::from(n) - Vec3::from(v.normal)).length() < 1e-3, "entry {slot}: normal {n:?} against {:?}", v.normal);
                assert!(e.ucw.is_finite(), "entry {slot}: W {}", e.ucw);
                cells_with_entries.insert(slot / 64);
            } else {
                assert_eq!(bytemuck::bytes_of(e), &[0u8; 48][..], "frame {frame}, entry {slot}: an empty entry is zeros");
            }
        }
        let built = r.grid_cells_built().unwrap().expect("a grid");
        // Frame 0 builds nothing (no pixel asked yet); frame 1 builds what frame 0 asked for.
        assert_eq!(cells_with_entries.len() as u32, built, "frame {frame}");
        assert_eq!(built > 0, frame == 1, "frame {frame}: {built} cells built");
        assert!(restir_vpl::dump::nonfinite_records(c).is_empty());
    }
    assert_no_validation_errors(&ctx);
}

#[test]
fn the_dumped_final_reservoir_reproduces_the_shaded_sample() {
    let ctx = context();
    let mut r = cornell_renderer(&ctx, RenderSettings { mode: Mode::Restir, vpls_direct: 2000, vpls_indirect: 2000, ..small(64, 64, 1) });
    let camera = r.initial_camera();
    // Frame 0 traces the G-buffer; frame 1 keeps it (still camera) and reuses history.
    let (_, first) = r.render_frame_captured(&camera, false).unwrap();
    let (_, captured) = r.render_frame_captured(&camera, false).unwrap();
    let vpls = r.read_vpls().unwrap().unwrap();
    assert_eq!(r.settings().attenuation, Attenuation::Yuksel);
    let r2 = r.vpl_summary().unwrap().yuksel_radius.unwrap().powi(2);
    // Surfaces: frame 0's G-buffer; the final reservoirs: the last reservoir output before
    // vpl_shade; the samples: vpl_shade's.
    let surfaces_bytes = &first.iter().find(|c| c.kind == CaptureKind::Surfaces).unwrap().bytes;
    let surfaces: &[GpuSurface] = &restir_vpl::dump::decode_surfaces(surfaces_bytes);
    let shade = captured.iter().position(|c| c.pass == "vpl_shade").unwrap();
    let finals = captured[..shade].iter().rev().find(|c| c.kind == CaptureKind::Reservoirs).unwrap();
    assert_eq!(finals.pass, "restir_spatial");
    let reservoirs: &[GpuReservoir] = bytemuck::cast_slice(&finals.bytes);
    let samples: &[[f32; 4]] = bytemuck::cast_slice(&captured[shade].bytes);
    let (mut checked, mut shadowed) = (0, 0);
    let mut unblocked_shadows = Vec::new();
    let triangles = world_triangles(&Scene::load(&repo_path("scenes/cornell_box.gltf")).unwrap());
    for i in 0..64 * 64 {
        let (s, res, got) = (&surfaces[i], &reservoirs[i], samples[i]);
        if s.offset_scale < 0.0 || res.vpl == RESERVOIR_EMPTY {
            continue;
        }
        let le = Vec3::from(s.emission);
        let expected = le + contribution(s, &vpls[res.vpl as usize], r2) * res.ucw;
        let got = Vec3::new(got[0], got[1], got[2]);
        if (got - le).max_element() <= 0.0 && expected.max_element() > le.max_element() {
            // The shadow ray found the VPL occluded: the sample is Le alone. Checked on the CPU:
            // the segment from the surface to the VPL crosses a triangle (a pass that dropped
            // samples would otherwise pass as shadows).
            let from = Vec3::from(s.position) + 1e-4 * Vec3::from(s.geometric_normal);
            let to = Vec3::from(vpls[res.vpl as usize].position);
            let (dir, len) = ((to - from).normalize(), (to - from).length());
            let blocked = triangles.iter().filter_map(|t| ray_triangle(from, dir, *t)).any(|d| d > 1e-4 && d < len - 1e-4);
            if blocked {
                shadowed += 1;
            } else {
                unblocked_shadows.push(i);
            }
            continue;
        }
        for c in 0..3 {
            assert!(
                (got[c] - expected[c]).abs() <= 1e-4 * expected[c].abs() + 1e-6,
                "pixel {i}: dumped sample {got} vs CPU Le + c·W = {expected} (W {}, VPL {})",
                res.ucw,
                res.vpl
            );
        }
        checked += 1;
    }
    eprintln!("{checked} pixels recombined, {shadowed} shadowed, {} shadowed with nothing in the way on the CPU", unblocked_shadows.len());
    assert!(checked > 2000 && shadowed < checked, "{checked} checked, {shadowed} shadowed");
    // A segment grazing an edge or a corner may be judged apart by the GPU's and the CPU's
    // arithmetic: a handful at most (1 % of the shadowed).
    assert!(unblocked_shadows.len() * 100 <= shadowed.max(1), "pixels whose sample is Le alone with the VPL in sight: {unblocked_shadows:?}");
    common::assert_no_nonfinite_samples(&r, "run");
    common::assert_no_validation_errors(&ctx);
}

#[test]
fn check_finite_names_the_pass_and_pixel_of_a_planted_nan() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    // Normal runs: nothing non-finite in any pass.
    for mode in ["restir", "pt", "ris"] {
        let o = bin().args(SMALL).args(["5", "--mode", mode, "--frames", "2", "--check-finite", "--out", out]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{mode}: {err}");
        // ReSTIR's captured frames run apart what the summary's fuse_passes says runs fused.
        assert_eq!(err.contains("2 of 2 frame(s) ran their passes apart"), mode == "restir", "{mode}: {err}");
    }
    // A NaN planted (test-only switch) in `poison`'s output stops the run, naming what `needles` say.
    let planted = |poison: &str, args: &[&str], needles: &[&str]| {
        let o = bin().args(SMALL).args(["5"]).args(args).args(["--check-finite", "--out", out]).env("RESTIR_VPL_DEBUG_POISON", poison).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "--check-finite must stop: {err}");
        for needle in needles {
            assert!(err.contains(needle), "the error should name {needle}: {err}");
        }
    };
    // In vpl_presample's tiles, in the flux of tile 0's entry 1: the tiles are captured too.
    // Nothing else finds it: restir_initial's RIS drops a NaN candidate (its weight fails every
    // comparison), so no sample is NaN and the run without the check is clean.
    planted("vpl_presample", &["--mode", "ris", "--frames", "2"], &["frame 0", "'vpl_presample'", "'tiles'", "at 1 entry,", "tile 0 entry 1"]);
    // The same in regir_build's grid (entry 1 of every cell it builds, from frame 1).
    planted("regir_build", &["--mode", "ris", "--grid-candidates", "4", "--frames", "3"], &["frame 1", "'regir_build'", "'entries'", " entry 1"]);
    // In vpl_shade's output at pixel (1, 1).
    planted("vpl_shade", &["--mode", "uniform", "--frames", "2"], &["frame 0", "'vpl_shade'", "'samples'", "1 pixel(s)", "(1, 1)"]);
    // Without --check-finite and without validation the same run completes: accumulate counts
    // and replaces the NaN.
    let poisoned = |strict: bool, mode: &str| {
        // Not bin(): it adds --validate where the layer is installed.
        let mut c = Command::new(env!("CARGO_BIN_EXE_restir-vpl"));
        c.current_dir(env!("CARGO_MANIFEST_DIR"));
        c.args(SMALL).args(["5", "--mode", mode, "--frames", "2", "--out", out]).env("RESTIR_VPL_DEBUG_POISON", "vpl_shade");
        if strict {
            c.env("RESTIR_VPL_VALIDATE", "1");
        } else {
            c.env_remove("RESTIR_VPL_VALIDATE");
        }
        let o = c.output().unwrap();
        let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
        assert_eq!(s["nonfinite_samples"], 2, "{mode}: one NaN per frame, counted by accumulate: {s}");
        o
    };
    let o = poisoned(false, "uniform");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // ReSTIR shades in restir_spatial_shade by default (fused): the NaN is planted there too (it
    // was not, and a test of a fused run would have checked nothing).
    let o = poisoned(false, "restir");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Under validation (what the tests' command-line runs use) the count fails the run after
    // the outputs are written, as a validation error does.
    if validate() {
        let o = poisoned(true, "uniform");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains("2 non-finite sample(s)"), "{err}");
    }
    // A command whose numbers come from its images fails on them with or without validation: a
    // reference (the ground truth others are measured against) with samples replaced by 0.
    let reference = dir.path().join("ref.exr");
    let o = Command::new(env!("CARGO_BIN_EXE_restir-vpl"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["reference", "--mode", "ris", "--width", "8", "--height", "8", "--frames", "2", "--vpls-direct", "200", "--vpls-indirect", "200", "--out"])
        .arg(&reference)
        .env("RESTIR_VPL_DEBUG_POISON", "vpl_shade")
        .env_remove("RESTIR_VPL_VALIDATE")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("2 non-finite sample(s)") && err.contains("ref.exr"), "{err}");
}

/// The inspector page in a real browser: headless Chromium loads it (no network) and its
/// screenshot shows the thumbnails (many distinct colours, not a blank page). The test command's
/// set-up installs Chromium; without it this test fails under CI=true and says so loudly elsewhere.
#[test]
fn the_inspector_page_renders_in_headless_chromium() {
    let browser = ["chromium", "chromium-browser", "google-chrome"].into_iter().find(|b| {
        Command::new("sh").args(["-c", &format!("command -v {b}")]).output().is_ok_and(|o| o.status.success())
    });
    let Some(browser) = browser else {
        let msg = "the inspector test needs Chromium (bash scripts/test.sh installs it)";
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!("{msg}");
        }
        common::skip(msg);
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = bin().args(SMALL).args(["3", "--mode", "restir", "--frames", "1", "--dump-passes", "all", "--out", out]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = dir.path().join("passes/index.html");
    let shot = dir.path().join("shot.png");
    let o = Command::new(browser)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--window-size=1200,900"])
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("--user-data-dir={}", dir.path().join("profile").display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap();
    assert!(shot.exists(), "no screenshot: {}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&shot).unwrap().to_rgb8();
    let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() > 500, "the page looks blank: {} distinct colours", colours.len());

    // The per-pixel readout (base64 float32 in the page), opened by a link to one pixel: every
    // output it lists holds that pixel's value in the EXR beside the page, to its 5 digits.
    let (x, y) = (5u32, 3u32);
    let o = Command::new(browser)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=3000", "--dump-dom"])
        .arg(format!("--user-data-dir={}", dir.path().join("profile").display()))
        .arg(format!("file://{}#frame=0&x={x}&y={y}", page.display()))
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&o.stdout);
    let readout = dom.split("<pre id=\"readout\">").nth(1).and_then(|r| r.split("</pre>").next()).expect("the page has its readout");
    let mut checked = 0;
    let mut ids = 0;
    let (mut material, mut albedo) = (None, None);
    for line in readout.lines().skip(1) {
        let (file, values) = line.split_once(": ").unwrap_or_else(|| panic!("readout line {line:?}"));
        let exr = restir_vpl::output::read_exr(&dir.path().join("passes/frame_0000").join(file)).unwrap();
        let px = exr.pixels[(y * exr.width + x) as usize];
        if file.ends_with("gbuffer__albedo.exr") {
            albedo = Some(px);
        }
        // The ids themselves, whose false colour the EXR holds: (instance, triangle) of the
        // G-buffer, its material, a reservoir's VPL index.
        if file.ends_with("__ids.exr") || file.ends_with("__vpl.exr") || file.ends_with("__material.exr") {
            if values.contains("none") {
                assert_eq!(px, [0.0; 3], "{file} at ({x}, {y}): no id, black");
                ids += 1;
                continue;
            }
            let n: Vec<u32> = values.split(", ").map(|v| v.parse().unwrap_or_else(|_| panic!("{file}: id {v:?}"))).collect();
            let id = match n[..] {
                [instance, triangle] => instance.wrapping_mul(65_599) ^ triangle,
                [m] if file.ends_with("__material.exr") => {
                    material = Some(m);
                    m
                }
                [vpl] => vpl,
                _ => panic!("{file}: {values}"),
            };
            assert_eq!(restir_vpl::dump::hash_colour(id), px, "{file} at ({x}, {y}): ids {values} against the EXR's colour");
            ids += 1;
            continue;
        }
        for (c, v) in values.split(", ").enumerate() {
            let v: f32 = v.parse().unwrap_or_else(|_| panic!("{file}: {v:?}"));
            assert!((v - px[c]).abs() <= 1e-4 * px[c].abs() + 1e-30, "{file} at ({x}, {y}) channel {c}: the page reads {v}, the EXR holds {}", px[c]);
        }
        checked += 1;
    }
    assert!(checked >= 10 && ids >= 3, "the readout lists the frame's outputs, the G-buffer's and reservoirs' ids among them: {readout}");
    // The material read out is the one whose colour the G-buffer holds (the Cornell box has no
    // textures: albedo = baseColorFactor).
    let scene = Scene::load(std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell_box.gltf"))).unwrap();
    let m = material.unwrap_or_else(|| panic!("({x}, {y}) sees the box; no material read out: {readout}"));
    let base = scene.materials[m as usize].base_color;
    assert_eq!(albedo, Some([base.x, base.y, base.z]), "material {m} ('{}') at ({x}, {y})", scene.materials[m as usize].name);
}

/// `--aa` jitters each primary ray uniformly inside its own pixel: every captured hit, projected
/// back into the image, lies inside its pixel, and over 16 frames × the pixels that see the box
/// the sub-pixel offsets have mean 1/2 (within 4 standard errors, √(1/12 / n)) and variance 1/12
/// (within 10 %: a jitter of half the width has 1/48, a fixed offset 0) along each axis.
/// Without `--aa` every hit projects to its pixel's centre.
#[test]
fn aa_jitters_primary_rays_uniformly_inside_their_pixel() {
    let (w, h) = (24u32, 16u32);
    let ctx = context();
    for aa in [true, false] {
        let mut r = cornell_renderer(&ctx, RenderSettings { mode: Mode::Uniform, aa, vpls_direct: 200, vpls_indirect: 200, ..small(w, h, 16) });
        let camera = r.initial_camera();
        let (tan, aspect) = ((0.5 * camera.yfov).tan(), w as f32 / h as f32);
        let mut offsets: Vec<[f64; 2]> = Vec::new();
        for frame in 0..16 {
            let (_, captured) = r.render_frame_captured(&camera, false).unwrap();
            // Without --aa the G-buffer is traced once on a still camera.
            let Some(c) = captured.iter().find(|c| c.kind == CaptureKind::Surfaces) else {
                assert!(!aa && frame > 0, "frame {frame}: no G-buffer traced with --aa");
                continue;
            };
            for (i, s) in restir_vpl::dump::decode_surfaces(&c.bytes).iter().enumerate() {
                if s.offset_scale < 0.0 {
                    continue;
                }
                let d = Vec3::from(s.position) - camera.position;
                let z = d.dot(camera.forward);
                let ndc = (d.dot(camera.right) / (z * tan * aspect), d.dot(camera.up) / (z * tan));
                let (px, py) = (0.5 * (ndc.0 + 1.0) * w as f32, 0.5 * (1.0 - ndc.1) * h as f32);
                let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
                let (u, v) = (px - x, py - y);
                // (Hits are offset a few ulps off the surface: 1e-3 of a pixel.)
                assert!((-1e-3..=1.001).contains(&u) && (-1e-3..=1.001).contains(&v), "aa {aa}: pixel ({x}, {y})'s hit projects to offset ({u}, {v})");
                if !aa {
                    assert!((u - 0.5).abs() < 1e-3 && (v - 0.5).abs() < 1e-3, "pixel ({x}, {y}): offset ({u}, {v}) without --aa");
                }
                offsets.push([f64::from(u), f64::from(v)]);
            }
        }
        if aa {
            let n = offsets.len() as f64;
            assert!(n > 2000.0, "{n} hits");
            for axis in 0..2 {
                let mean = offsets.iter().map(|o| o[axis]).sum::<f64>() / n;
                let var = offsets.iter().map(|o| (o[axis] - mean).powi(2)).sum::<f64>() / (n - 1.0);
                let se = (1.0 / 12.0 / n).sqrt();
                assert!((mean - 0.5).abs() < 4.0 * se, "axis {axis}: mean offset {mean} (SE {se})");
                assert!((var * 12.0 - 1.0).abs() < 0.1, "axis {axis}: offset variance {var} against 1/12");
            }
        }
    }
    assert_no_validation_errors(&ctx);
}

/// The G-buffer's records land where the passes read them: at a pixel count that is not a multiple
/// of the 16-pixel granule the halves are rounded to, over both halves of the ping-pong (the camera
/// moves between the two frames, so frame 1 traces into the other half), every captured hit lies
/// on its own pixel's primary ray at the stored distance, with the stored view depth. A record
/// stored through the wrong chunk binding or half would hold another pixel's hit.
#[test]
fn the_captured_g_buffer_holds_each_pixels_own_primary_hit() {
    let (w, h) = (37u32, 23u32);
    let ctx = context();
    let mut r = cornell_renderer(&ctx, RenderSettings { mode: Mode::Uniform, vpls_direct: 500, vpls_indirect: 500, ..small(w, h, 2) });
    let first = r.initial_camera();
    let mut second = first;
    second.position += 0.05 * first.right - 0.03 * first.up;
    let mut checked = 0;
    for camera in [first, second] {
        let (_, captured) = r.render_frame_captured(&camera, false).unwrap();
        let bytes = &captured.iter().find(|c| c.kind == CaptureKind::Surfaces).expect("the G-buffer is captured").bytes;
        let surfaces = restir_vpl::dump::decode_surfaces(bytes);
        assert_eq!(surfaces.len(), (w * h) as usize, "one record per pixel");
        let tan = (0.5 * camera.yfov).tan();
        let aspect = w as f32 / h as f32;
        for (i, s) in surfaces.iter().enumerate() {
            if s.offset_scale < 0.0 {
                continue;
            }
            let (x, y) = ((i as u32 % w) as f32 + 0.5, (i as u32 / w) as f32 + 0.5);
            let ndc = (2.0 * x / w as f32 - 1.0, 1.0 - 2.0 * y / h as f32);
            let dir = (camera.forward + ndc.0 * tan * aspect * camera.right + ndc.1 * tan * camera.up).normalize();
            // The stored hit lies on the pixel's ray (t: its distance along it).
            let t = (Vec3::from(s.position) - camera.position).dot(dir);
            let expected = camera.position + t * dir;
            let err = (Vec3::from(s.position) - expected).length();
            assert!(t > 0.0 && err <= 1e-3 * (1.0 + t), "pixel ({x}, {y}): stored hit {:?} is {err} from its ray's point {expected:?} at t = {t}", s.position);
            // Its offset scale is its triangle's largest |coordinate|: the box spans 0..0.56.
            assert!(s.offset_scale > 0.0 && s.offset_scale <= 0.6, "pixel ({x}, {y}): offset scale {}", s.offset_scale);
            let depth = t * dir.dot(camera.forward);
            assert!((s.view_depth - depth).abs() <= 1e-3 * (1.0 + depth), "pixel ({x}, {y}): view depth {} against {depth}", s.view_depth);
            checked += 1;
        }
    }
    assert!(checked > w * h, "most pixels see the box: {checked} hits checked over two frames");
    common::assert_no_validation_errors(&ctx);
}

/// What the dump folder must take is checked before frame 0 (each case was found only when its
/// frame came up, after the frames before it had rendered and written their snapshots): OUT/passes
/// as a file, a file where a frame's folder goes. `--dump-vpls` inside OUT/passes is refused under
/// any spelling of the path (the dump's clean-up deleted it after it was reported written, or the
/// page overwrote it). With `--check-finite`, the frame it stops at is dumped with the page, though
/// the selection names another frame (the run stopped with the earlier dumps removed and nothing
/// in their place).
#[test]
fn the_dump_folder_is_checked_first_and_a_failing_frame_is_dumped() {
    let dir = tempfile::tempdir().unwrap();
    let run = |out: &std::path::Path, extra: &[&str]| bin().args(SMALL).args(["5", "--mode", "uniform", "--frames", "3", "--save-every", "1", "--out", out.to_str().unwrap()]).args(extra).output().unwrap();
    let refused = |o: &std::process::Output, needles: &[&str], out: &std::path::Path| {
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && !err.contains("panicked"), "{err}");
        for n in needles {
            assert!(err.contains(n), "should name {n}: {err}");
        }
        assert!(!out.join("accum_0001.exr").exists(), "refused before the first frame: {err}");
    };
    let a = dir.path().join("a");
    std::fs::create_dir_all(&a).unwrap();
    std::fs::write(a.join("passes"), "a file").unwrap();
    refused(&run(&a, &["--dump-passes", "last"]), &["--dump-passes", "not a directory"], &a);
    let b = dir.path().join("b");
    std::fs::create_dir_all(b.join("passes")).unwrap();
    std::fs::write(b.join("passes").join("frame_0002"), "a file").unwrap();
    refused(&run(&b, &["--dump-passes", "last"]), &["--dump-passes", "frame_0002"], &b);
    let c = dir.path().join("c");
    let spellings = [
        c.join("passes").join("v.ply"),
        c.join("passes").join("..").join("passes").join("index.html"),
        c.join("other").join("..").join("passes").join("v.ply"),
        c.join("passes"),
    ];
    for ply in spellings {
        refused(&run(&c, &["--dump-passes", "0", "--dump-vpls", ply.to_str().unwrap()]), &["--dump-vpls", "--dump-passes"], &c);
    }
    // --check-finite stopping at frame 0 of a run that dumps frame 2.
    let d = dir.path().join("d");
    let o = bin()
        .args(SMALL)
        .args(["5", "--mode", "uniform", "--frames", "3", "--check-finite", "--dump-passes", "2", "--out", d.to_str().unwrap()])
        .env("RESTIR_VPL_DEBUG_POISON", "vpl_shade")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("frame 0 is dumped in") && err.contains("'vpl_shade'"), "{err}");
    let manifest = d.join("passes").join("frame_0000").join("manifest.json");
    assert!(manifest.is_file() && d.join("passes").join("index.html").is_file(), "{err}");
    // The planted NaN is one pixel, counted as one (as --check-finite counts), not per channel.
    let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    let text = m.to_string();
    assert!(text.contains("\"nonfinite\":1") && !text.contains("\"nonfinite\":3"), "{text}");
}
