//! The VPL estimators against the brute-force sum over the same VPL set (the VPL model's exact
//! answer), on the Cornell box at small size with few VPLs.
//!
//! - uniform and RIS (both candidate sources, with and without presampling, with and without the
//!   ReGIR grid): frames are independent,
//!   so each block's standard error comes from the spread of its per-frame means; every 12×12
//!   block's mean must lie within 5 standard errors of the brute-force block mean (17 checks per
//!   mode; a false alarm under 1e-4 per mode).
//! - unbiased ReSTIR: frames and neighbouring pixels are correlated, so the standard error comes
//!   from independent runs (32 seeds, same VPL set): |t| < 6 per block with 31 degrees of freedom
//!   (two-sided p ≈ 1.2e-6 per block, 17 checks per case). The threshold was set for 12 seeds
//!   (p ≈ 1e-4 there) and kept when the runs grew for power: the test also asserts that a
//!   whole-image bias of 1 % would fail it (`detectable`), so the conservative threshold costs no
//!   sensitivity that matters.
//! - biased ReSTIR: its deviation is measured and printed, not asserted.
//! - at equal frame count, RMSE(uniform) > RMSE(RIS) > RMSE(ReSTIR).

mod common;

use std::sync::Arc;

use restir_vpl::renderer::Renderer;
use restir_vpl::scene::Scene;
use restir_vpl::scene_gpu::SceneGpu;
use restir_vpl::settings::{Attenuation, Bias, CandidateSource, GridSettings, Mode, RenderSettings};
use restir_vpl::vk::Context;

const W: u32 = 48;
const H: u32 = 48;
const BLOCK: u32 = 12;

/// The Cornell box, uploaded once per test and shared by its renderers.
fn cornell(ctx: &Arc<Context>) -> Arc<SceneGpu> {
    let scene = Scene::load(&common::repo_path("scenes/cornell_box.gltf")).expect("Cornell box loads");
    Arc::new(SceneGpu::new(ctx, &scene, true, restir_vpl::vk::accel::MERGE_MAX_TRIANGLES).expect("scene uploads"))
}

fn settings(mode: Mode, w: u32, h: u32, direct: u32, indirect: u32) -> RenderSettings {
    RenderSettings {
        mode,
        width: w,
        height: h,
        vpls_direct: direct,
        vpls_indirect: indirect,
        validate: common::validate(),
        ..Default::default()
    }
}

/// Renders `frames` frames; returns (mean, variance) images.
fn render(renderer: &mut Renderer, frames: u32) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let camera = renderer.initial_camera();
    for _ in 0..frames {
        renderer.render_frame(&camera, false).expect("frame renders");
    }
    let mean = renderer.read_mean().unwrap();
    common::assert_all_finite(&mean, "mean");
    common::assert_no_nonfinite_samples(renderer, "run");
    (mean, renderer.read_variance().unwrap())
}

fn lum(c: &[f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Block index of each pixel (BLOCK×BLOCK blocks).
fn blocks(w: u32, h: u32) -> Vec<Vec<usize>> {
    let (bx, by) = (w / BLOCK, h / BLOCK);
    let mut out = vec![Vec::new(); (bx * by) as usize];
    for y in 0..h {
        for x in 0..w {
            out[((y / BLOCK) * bx + x / BLOCK) as usize].push((y * w + x) as usize);
        }
    }
    out
}

fn block_means(img: &[[f32; 3]], blocks: &[Vec<usize>]) -> Vec<f64> {
    blocks.iter().map(|b| b.iter().map(|&i| lum(&img[i])).sum::<f64>() / b.len() as f64).collect()
}

fn rmse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let s: f64 = a.iter().zip(b).map(|(x, y)| (0..3).map(|c| (x[c] as f64 - y[c] as f64).powi(2)).sum::<f64>()).sum();
    (s / (3 * a.len()) as f64).sqrt()
}

fn brute_force(ctx: &Arc<Context>, scene: &Arc<SceneGpu>, s: &RenderSettings) -> Vec<[f32; 3]> {
    let mut bf = Renderer::new(ctx.clone(), scene.clone(), RenderSettings { mode: Mode::Bruteforce, frames: 1, ..s.clone() }).unwrap();
    render(&mut bf, 1).0
}

/// Uniform and RIS (with and without presampling): frames are independent, so each block's standard
/// error comes from the spread of its per-frame means (valid although presampled pixels of one
/// frame share candidates); 5-SE bound per block and for the whole image.
#[test]
fn uniform_and_ris_converge_to_brute_force() {
    let ctx = common::context();
    let scene = cornell(&ctx);
    let base = settings(Mode::Uniform, W, H, 200, 400);
    let reference = brute_force(&ctx, &scene, &base);
    let mut all = vec![(0usize..(W * H) as usize).collect::<Vec<_>>()];
    all.extend(blocks(W, H));
    let ref_all = block_means(&reference, &all);
    // The last field: candidates (of 8) from the ReGIR grid (regir_build), the rest from the
    // source pdf with balance-heuristic weights; 8 of 8: the grid alone, which is unbiased only
    // because the cell target is positive wherever a pixel's target can be.
    let cases = [
        ("uniform", Mode::Uniform, CandidateSource::Uniform, false, 256, 0),
        ("ris (uniform source)", Mode::Ris, CandidateSource::Uniform, false, 96, 0),
        ("ris (power source)", Mode::Ris, CandidateSource::Power, false, 96, 0),
        ("ris (uniform source, presampled)", Mode::Ris, CandidateSource::Uniform, true, 96, 0),
        ("ris (power source, presampled)", Mode::Ris, CandidateSource::Power, true, 96, 0),
        ("ris (uniform source, presampled, 4 from the grid)", Mode::Ris, CandidateSource::Uniform, true, 96, 4),
        ("ris (power source, 4 from the grid)", Mode::Ris, CandidateSource::Power, false, 96, 4),
        ("ris (8 from the grid: the grid alone)", Mode::Ris, CandidateSource::Uniform, true, 96, 8),
    ];
    for (label, mode, source, presample, frames, grid) in cases {
        let grid = small_grid(grid);
        let s = RenderSettings { mode, candidate_source: source, candidates: 8, presample, grid, ..base.clone() };
        let mut r = Renderer::new(ctx.clone(), scene.clone(), s).unwrap();
        assert_eq!(r.vpl_summary().unwrap().presample, presample && mode == Mode::Ris, "{label}: presample pass present");
        assert_eq!(r.vpl_summary().unwrap().grid.is_some(), grid.candidates > 0, "{label}: regir_build present");
        assert_frames_converge(label, &mut r, frames, &all, &ref_all);
        if grid.candidates > 0 {
            assert_grid_used(label, &mut r);
        }
    }
    // Constant 1/M weights (--grid-balance off), which the balance heuristic otherwise uses only in
    // a cell's first built frame: unbiased through the cell target's coverage alone.
    let label = "ris (4 of 8 from the grid, constant weights)";
    let grid = GridSettings { balance: false, ..small_grid(4) };
    let mut r = Renderer::new(ctx.clone(), scene.clone(), RenderSettings { mode: Mode::Ris, candidates: 8, grid, ..base.clone() }).unwrap();
    assert_frames_converge(label, &mut r, 96, &all, &ref_all);
    assert_grid_used(label, &mut r);
    common::assert_no_validation_errors(&ctx);
}

/// Renders `frames` independent frames and asserts every block's mean within 5 standard errors
/// (from the spread of its per-frame means) of `reference`.
fn assert_frames_converge(label: &str, r: &mut Renderer, frames: u32, all: &[Vec<usize>], reference: &[f64]) {
    let camera = r.initial_camera();
    let mut per_frame: Vec<Vec<f64>> = Vec::new();
    for _ in 0..frames {
        r.render_frame(&camera, false).expect("frame renders");
        let img = r.read_frame_samples().unwrap();
        common::assert_all_finite(&img, label);
        per_frame.push(block_means(&img, all));
    }
    let mut worst = 0f64;
    for bi in 0..all.len() {
        let (m, se) = mean_and_se(per_frame.iter().map(|m| m[bi]));
        // A black block on both sides would pass any bound: the blocks must be lit and noisy.
        assert!(reference[bi] > 0.0 && se > 0.0, "{label}: block {bi}: reference {} and spread {se}: nothing to test", reference[bi]);
        let z = (m - reference[bi]) / se;
        worst = worst.max(z.abs());
        assert!(z.abs() < 5.0, "{label}: block {bi} mean {m:.6} vs brute force {:.6}: {z:.2} standard errors ({frames} frames)", reference[bi]);
    }
    let image_mean = per_frame.iter().map(|m| m[0]).sum::<f64>() / frames as f64;
    // The test's power: the smallest whole-image bias (block 0 is the whole image) that the bound
    // of 5 standard errors would still let through must be under 1 %.
    let detectable = 5.0 * whole_image_se(&per_frame) / reference[0];
    println!("{label}: {frames} frames, worst block |z| = {worst:.2}, image mean {image_mean:.5} vs {:.5}; a whole-image bias above {:.3}% fails", reference[0], 100.0 * detectable);
    assert!(detectable < 0.01, "{label}: too few frames to see a 1 % bias: 5 SE = {:.3}% of the mean", 100.0 * detectable);
}

/// The ReGIR grid of these 48×48 tests with `candidates` of a pixel's candidates from it: 6³ cells
/// of 64 entries (16³ would build far more cells than so few pixels need).
fn small_grid(candidates: u32) -> GridSettings {
    GridSettings { candidates, cells: 6, entries: 64, ..Default::default() }
}

/// The grid was built in the last frame, so the frames tested drew from it (a stamp bug that never
/// built a cell would fall back to the source pdf alone, which converges too).
fn assert_grid_used(label: &str, r: &mut Renderer) {
    let built = r.grid_cells_built().unwrap().expect("a grid");
    assert!(built > 0, "{label}: no grid cell was built in the last frame");
}

/// The standard error of the whole image's mean (block 0) from independent samples of it (frames
/// or runs).
fn whole_image_se(samples: &[Vec<f64>]) -> f64 {
    mean_and_se(samples.iter().map(|s| s[0])).1
}

/// The mean of independent samples and its standard error (sample standard deviation, n − 1,
/// over √n).
fn mean_and_se(xs: impl Iterator<Item = f64>) -> (f64, f64) {
    let xs: Vec<f64> = xs.collect();
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    (m, (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt())
}

/// Runs `runs` independent seeds of `frames` frames each (ReSTIR: frames and pixels correlate, so
/// the standard error comes from the runs) and returns per-run block means, the per-block t
/// statistics against `reference` and their printable lines. The caller asserts what it needs.
fn run_means(r: &mut Renderer, runs: u32, frames: u32, all: &[Vec<usize>], reference: &[f64]) -> (Vec<Vec<f64>>, Vec<f64>, Vec<String>) {
    let mut per_run: Vec<Vec<f64>> = Vec::new();
    for run in 0..runs {
        r.restart(1000 + run).unwrap();
        let (mean, _) = render(r, frames);
        per_run.push(block_means(&mean, all));
    }
    let mut ts = Vec::new();
    let mut lines = Vec::new();
    for bi in 0..all.len() {
        let (m, se) = mean_and_se(per_run.iter().map(|m| m[bi]));
        assert!(reference[bi] > 0.0 && se > 0.0, "block {bi}: reference {} and spread {se}: nothing to test", reference[bi]);
        let t = (m - reference[bi]) / se;
        ts.push(t);
        lines.push(format!("block {bi}: {m:.6} vs {:.6} ({:+.2}%, t = {t:.2})", reference[bi], 100.0 * (m / reference[bi] - 1.0)));
    }
    (per_run, ts, lines)
}

/// `--yuksel-knn`: each VPL's own radius (from its nearest VPLs) reaches every pass, so RIS and
/// unbiased ReSTIR converge to the brute-force sum with the same per-VPL radii (same bounds as
/// above), and that sum differs from the one radius of the global rule (the flag is not ignored).
/// RIS stays unbiased even with a wrong target, so the presampled candidate loop (which reads the
/// radius from the full record) is checked directly: wherever it and the direct loop pick the
/// same VPL for the same pixel and frame, they stored the same target p̂.
#[test]
fn per_vpl_radius_modes_converge_to_their_brute_force() {
    let ctx = common::context();
    let scene = cornell(&ctx);
    let global = settings(Mode::Ris, W, H, 200, 400);
    let base = RenderSettings { yuksel_knn: Some(8), yuksel_spacings: Some(4.0), ..global.clone() };
    let reference = brute_force(&ctx, &scene, &base);
    let other = brute_force(&ctx, &scene, &RenderSettings { yuksel_spacings: Some(4.0), ..global });
    let mean = reference.iter().map(lum).sum::<f64>() / reference.len() as f64;
    assert!(rmse(&reference, &other) > 1e-3 * mean, "per-VPL radii change the brute-force image");
    let mut all = vec![(0usize..(W * H) as usize).collect::<Vec<_>>()];
    all.extend(blocks(W, H));
    let ref_all = block_means(&reference, &all);
    let mut ris = Renderer::new(ctx.clone(), scene.clone(), RenderSettings { candidates: 8, ..base.clone() }).unwrap();
    assert!(ris.vpl_summary().unwrap().presample, "the presampled candidate loop is the one under test");
    assert_frames_converge("ris, per-VPL radius", &mut ris, 96, &all, &ref_all);
    // The ReGIR grid reads each VPL's radius in its cell target and its pixels' targets, in the
    // presampled loop and the direct one (presample off).
    // (The grid alone is noisier here: 256 frames keep a 1 % bias visible.)
    for (label, grid, presample, frames) in
        [("ris, per-VPL radius, 4 of 8 from the grid", 4, false, 96), ("ris, per-VPL radius, the grid alone", 8, true, 256)]
    {
        let grid = small_grid(grid);
        let mut r = Renderer::new(ctx.clone(), scene.clone(), RenderSettings { candidates: 8, presample, grid, ..base.clone() }).unwrap();
        assert_frames_converge(label, &mut r, frames, &all, &ref_all);
        assert_grid_used(label, &mut r);
    }
    let ris = |presample| RenderSettings { candidates: 8, presample, ..base.clone() };
    let (mut tiles, mut direct) =
        (Renderer::new(ctx.clone(), scene.clone(), ris(true)).unwrap(), Renderer::new(ctx.clone(), scene.clone(), ris(false)).unwrap());
    let camera = tiles.initial_camera();
    let (mut same, mut worst) = (0, 0f32);
    for _ in 0..32 {
        tiles.render_frame(&camera, false).unwrap();
        direct.render_frame(&camera, false).unwrap();
        let (a, b) = (tiles.read_reservoirs().unwrap().unwrap(), direct.read_reservoirs().unwrap().unwrap());
        for (x, y) in a.iter().zip(&b).filter(|(x, y)| x.vpl == y.vpl && x.vpl != restir_vpl::gpu_types::RESERVOIR_EMPTY) {
            same += 1;
            worst = worst.max((x.target - y.target).abs() / y.target.abs().max(1e-30));
        }
    }
    assert!(same >= 100, "only {same} pixels chose the same VPL in both loops: nothing to compare");
    assert!(worst < 1e-4, "presampled and direct candidate loops disagree on p̂ by {worst} (relative) over {same} pixels");
    let restir = RenderSettings { mode: Mode::Restir, candidates: 8, ..base };
    let mut r = Renderer::new(ctx.clone(), scene.clone(), restir).unwrap();
    // 24 runs: with 12, the VPL set the photon pass makes since it stopped overshooting small
    // targets (400 asked: ~400 made, ~650 before) left 6 SE at 1.1–1.2 % of the mean, and twice
    // the frames per run barely moved it (the temporal reuse correlates a run's frames), so the
    // power check below failed; more runs is what narrows a mean over runs.
    let (runs, ts, lines) = run_means(&mut r, 24, 16, &all, &ref_all);
    for (t, line) in ts.iter().zip(&lines) {
        assert!(t.abs() < 6.0, "unbiased restir, per-VPL radius, {line}");
    }
    // |t| < 6 over 24 runs (23 degrees of freedom): an unbiased block fails with probability
    // ~4e-6, one of the 17 (16 blocks and the whole image) ~7e-5. The power: the smallest
    // whole-image bias that |t| < 6 lets through must be under 1 %.
    let detectable = 6.0 * whole_image_se(&runs) / ref_all[0];
    println!("unbiased restir, per-VPL radius: a whole-image bias above {:.3}% fails", 100.0 * detectable);
    assert!(detectable < 0.01, "too few runs to see a 1 % bias: 6 SE = {:.3}% of the mean", 100.0 * detectable);
    common::assert_no_validation_errors(&ctx);
}

/// Unbiased ReSTIR: 32 independent runs, t-test per block, and enough runs that a 1 % whole-image
/// bias fails it, with and without visibility in the targets, with the grid, without temporal
/// reuse and with two spatial passes; biased ReSTIR's bias printed and bounded (1 % + 4 SE).
#[test]
fn restir_unbiased_converges_to_brute_force_and_biased_reports_its_bias() {
    let ctx = common::context();
    let scene = cornell(&ctx);
    let base = settings(Mode::Restir, W, H, 200, 400);
    let reference = brute_force(&ctx, &scene, &base);
    let bl = blocks(W, H);
    let mut all = vec![(0usize..(W * H) as usize).collect::<Vec<_>>()];
    all.extend(bl.iter().cloned());
    let ref_means = block_means(&reference, &all);
    const RUNS: u32 = 32;
    const FRAMES: u32 = 16;
    // The third field: candidates (of 8) from the ReGIR grid; the fourth: temporal reuse on and
    // the spatial passes (the default's 1, then without temporal reuse and with two spatial
    // passes, whose second merges reservoirs that already hold neighbours).
    let cases = [
        (Bias::Unbiased, true, 0, (true, 1)),
        (Bias::Unbiased, false, 0, (true, 1)),
        (Bias::Unbiased, false, 4, (true, 1)),
        (Bias::Unbiased, false, 0, (false, 1)),
        (Bias::Unbiased, false, 0, (true, 2)),
        (Bias::Biased, false, 0, (true, 1)),
    ];
    for (bias, visibility, grid, (temporal, spatial_passes)) in cases {
        let restir = restir_vpl::settings::RestirSettings { bias, initial_visibility: Some(visibility), temporal, spatial_passes, ..Default::default() };
        let grid = small_grid(grid);
        // With the grid, the fused initial + temporal pass (its own binding of the grid), which a
        // CPU device does not run by default.
        let fuse_passes = (grid.candidates > 0).then_some(true);
        let s = RenderSettings { restir, candidates: 8, grid, fuse_passes, ..base.clone() };
        let mut r = Renderer::new(ctx.clone(), scene.clone(), s).unwrap();
        let (runs, ts, lines) = run_means(&mut r, RUNS, FRAMES, &all, &ref_means);
        if grid.candidates > 0 {
            assert_grid_used("unbiased restir with the grid", &mut r);
            assert!(r.log().pass_stats().contains_key("restir_initial_temporal"), "the fused pass is the one under test");
        }
        let worst = ts.iter().fold(0f64, |w, t| w.max(t.abs()));
        // The test's power: the smallest whole-image bias that |t| < 6 would still let through.
        let detectable = 6.0 * whole_image_se(&runs) / ref_means[0];
        println!(
            "restir {bias:?} (visibility {visibility}, {} grid candidates, temporal {temporal}, {spatial_passes} spatial passes): a whole-image bias above {:.3}% fails the t-test",
            grid.candidates,
            100.0 * detectable
        );
        if bias == Bias::Unbiased {
            for (t, line) in ts.iter().zip(&lines) {
                assert!(t.abs() < 6.0, "unbiased restir (temporal {temporal}, {spatial_passes} spatial passes), {line}");
            }
            assert!(detectable < 0.01, "too few runs to see a 1 % bias: 6 SE = {:.3}% of the mean", 100.0 * detectable);
        }
        println!(
            "restir {bias:?} (targets with visibility: {visibility}): image mean {:.6} vs brute force {:.6} ({:+.3}%), worst block |t| = {worst:.2} over {RUNS} runs × {FRAMES} frames",
            runs.iter().map(|m| m[0]).sum::<f64>() / RUNS as f64,
            ref_means[0],
            100.0 * (runs.iter().map(|m| m[0]).sum::<f64>() / RUNS as f64 / ref_means[0] - 1.0)
        );
        if bias == Bias::Biased {
            println!("biased restir per block (measured, not asserted):\n  {}", lines.join("\n  "));
            // Biased reuse has a bias by design, so it is bounded, not tested for zero: on this
            // box it measured −0.14 % here and +0.02 % in docs/results.md (−1.6 % on the open
            // box there). Within 1 % plus 4 standard errors of the mean over runs, a defect of the
            // merge (a dropped weight or normalisation: tens of %) fails, its designed bias does not.
            let mean = runs.iter().map(|m| m[0]).sum::<f64>() / RUNS as f64;
            let se = whole_image_se(&runs);
            assert!((mean / ref_means[0] - 1.0).abs() < 0.01 + 4.0 * se / ref_means[0], "biased restir: image mean {mean} against brute force {} (SE {se})", ref_means[0]);
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// relMSE of one image against the reference: mean of (a − b)² / (b² + 0.01).
fn rel_mse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let s: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (0..3).map(|c| (x[c] as f64 - y[c] as f64).powi(2) / ((y[c] as f64).powi(2) + 0.01)).sum::<f64>())
        .sum();
    s / (3 * a.len()) as f64
}

/// Equal frame count: the error of the frame a user sees (frames 5 to 12, after the temporal
/// history has filled) must drop from uniform to RIS to ReSTIR. The spatial radius is scaled to the
/// 64-pixel image (4 px; the default 20 px is meant for 720p). Accumulated errors are printed too:
/// temporal reuse correlates frames, so averaging many ReSTIR frames gains less than averaging
/// independent RIS frames.
///
/// Tolerance: each mode runs SEEDS independent sequences (`restart` with another pixel seed; the
/// same VPL set, so one brute-force reference). For each claim "A beats B" the per-seed paired
/// differences d = relMSE(A) − relMSE(B) (each the mean of frames 5–12 of one sequence; seeds are
/// independent, the frames within one are not, so only the per-seed means enter) must have a mean
/// more than 4 standard errors below zero: with SEEDS − 1 = 15 degrees of freedom a mode no better
/// than the other passes this with probability 6e-4 (Student's t, one-sided). Sixteen seeds, not
/// six: the smallest margin measured (unshadowed-target ReSTIR against RIS) is then about 7
/// standard errors, so a change of random streams would fail a correct build rarely (at 4.5, with
/// six seeds, about one time in three). Seeds are fixed, so a build passes or fails the same way
/// every time.
#[test]
fn ris_beats_uniform_and_restir_beats_ris_at_equal_frames() {
    const SEEDS: u32 = 16;
    let ctx = common::context();
    let scene = cornell(&ctx);
    let (w, h, frames, skip) = (64, 64, 12, 4);
    let base = settings(Mode::Uniform, w, h, 1000, 2000);
    let reference = brute_force(&ctx, &scene, &base);
    let modes = [
        ("uniform", Mode::Uniform, Bias::Biased, None),
        ("ris", Mode::Ris, Bias::Biased, None),
        ("restir (unbiased, visibility in targets)", Mode::Restir, Bias::Unbiased, Some(true)),
        ("restir (unbiased, unshadowed targets)", Mode::Restir, Bias::Unbiased, Some(false)),
        ("restir (biased)", Mode::Restir, Bias::Biased, None),
    ];
    // errors[mode][seed]: the mean per-frame relMSE of frames skip+1..frames.
    let mut errors: Vec<Vec<f64>> = Vec::new();
    for (label, mode, bias, visibility) in modes {
        let restir = restir_vpl::settings::RestirSettings { bias, initial_visibility: visibility, spatial_radius: Some(4.0), ..Default::default() };
        let s = RenderSettings { mode, restir, ..base.clone() };
        let mut r = Renderer::new(ctx.clone(), scene.clone(), s).unwrap();
        let camera = r.initial_camera();
        let mut per_seed = Vec::new();
        for seed in 0..SEEDS {
            r.restart(3000 + seed).unwrap();
            let mut per_frame = Vec::new();
            for f in 0..frames {
                r.render_frame(&camera, false).unwrap();
                if f >= skip {
                    per_frame.push(rel_mse(&r.read_frame_samples().unwrap(), &reference));
                }
            }
            let mean = r.read_mean().unwrap();
            common::assert_all_finite(&mean, label);
            common::assert_no_nonfinite_samples(&r, label);
            if seed == 0 {
                println!("{label}: accumulated over {frames} frames (seed 0): RMSE {:.5}, relMSE {:.5}", rmse(&mean, &reference), rel_mse(&mean, &reference));
            }
            per_seed.push(per_frame.iter().sum::<f64>() / per_frame.len() as f64);
        }
        println!("{label}: per-frame relMSE (frames {}..{frames}) per seed {per_seed:.4?}", skip + 1);
        errors.push(per_seed);
    }
    let beats = |a: usize, b: usize| {
        let (mean, se) = mean_and_se(errors[a].iter().zip(&errors[b]).map(|(x, y)| x - y));
        println!("{} against {}: mean difference {mean:.4} ± {se:.4} (standard error)", modes[a].0, modes[b].0);
        assert!(mean < -4.0 * se, "{}'s per-frame relMSE is not below {}'s by 4 standard errors: difference {mean:.4} ± {se:.4}", modes[a].0, modes[b].0);
    };
    beats(1, 0);
    beats(2, 1);
    beats(3, 1);
    // Biased reuse has heavy tails here (confidence weights ignore how sharply a VPL's target
    // changes between neighbours: fireflies), but on average it still beats RIS.
    beats(4, 1);
    common::assert_no_validation_errors(&ctx);
}

/// `--view vpl-kind` shows, per pixel, the kind of the VPL the final reservoir holds (blue direct,
/// cyan point light, red indirect; black without a sample), checked against the reservoirs and the
/// VPL set read back; the Cornell box's view has both direct and indirect picks.
#[test]
fn vpl_kind_view_shows_the_kind_of_each_pixels_sample() {
    use restir_vpl::gpu_types::{RESERVOIR_EMPTY, VPL_DIRECT_AREA, VPL_DIRECT_POINT, VPL_INDIRECT};
    use restir_vpl::settings::View;
    let ctx = common::context();
    let scene = cornell(&ctx);
    let mut r = Renderer::new(ctx.clone(), scene.clone(), RenderSettings { view: View::VplKind, ..settings(Mode::Restir, 32, 32, 300, 600) }).unwrap();
    render(&mut r, 3);
    let image = r.read_frame_samples().unwrap();
    let reservoirs = r.read_reservoirs().unwrap().expect("restir keeps reservoirs");
    let vpls = r.read_vpls().unwrap().expect("restir has a VPL set");
    let mut seen = [0usize; 3];
    for (i, (p, res)) in image.iter().zip(&reservoirs).enumerate() {
        let want = if res.vpl == RESERVOIR_EMPTY || !(res.ucw > 0.0) {
            [0.0, 0.0, 0.0]
        } else {
            match vpls[res.vpl as usize].kind {
                VPL_INDIRECT => {
                    seen[2] += 1;
                    [1.0, 0.1, 0.05]
                }
                VPL_DIRECT_POINT => {
                    seen[1] += 1;
                    [0.1, 0.9, 1.0]
                }
                k => {
                    assert_eq!(k, VPL_DIRECT_AREA);
                    seen[0] += 1;
                    [0.1, 0.25, 1.0]
                }
            }
        };
        assert_eq!(*p, want, "pixel {i}: reservoir {res:?}");
    }
    assert!(seen[0] > 10 && seen[2] > 10, "direct and indirect picks expected: {seen:?}");
    common::assert_no_validation_errors(&ctx);
}

/// Inverse-square attenuation puts huge values next to VPLs; no mode may write NaN/Inf, and every
/// debug view renders.
#[test]
fn no_mode_or_view_writes_nan_with_inverse_square() {
    use restir_vpl::settings::View;
    let ctx = common::context();
    let scene = cornell(&ctx);
    for mode in [Mode::Uniform, Mode::Ris, Mode::Restir, Mode::Bruteforce] {
        for view in [View::Final, View::Direct, View::Indirect, View::ReservoirW, View::ReservoirM, View::VplKind] {
            if mode == Mode::Bruteforce && view.shows_reservoirs() {
                continue;
            }
            for bias in [Bias::Biased, Bias::Unbiased] {
                if bias == Bias::Unbiased && mode != Mode::Restir {
                    continue;
                }
                let s = RenderSettings {
                    attenuation: Attenuation::InverseSquare,
                    view,
                    aa: true,
                    restir: restir_vpl::settings::RestirSettings { bias, ..Default::default() },
                    ..settings(mode, 32, 32, 300, 600)
                };
                let mut r = Renderer::new(ctx.clone(), scene.clone(), s).unwrap();
                render(&mut r, 3);
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// Direct-only plus indirect-only equals the full brute-force image (the split is exact).
#[test]
fn direct_and_indirect_views_add_up() {
    use restir_vpl::settings::View;
    let ctx = common::context();
    let scene = cornell(&ctx);
    let base = settings(Mode::Bruteforce, 32, 32, 300, 600);
    let full = brute_force(&ctx, &scene, &base);
    let part = |view| {
        let mut r = Renderer::new(ctx.clone(), scene.clone(), RenderSettings { view, frames: 1, ..base.clone() }).unwrap();
        render(&mut r, 1).0
    };
    let (d, i) = (part(View::Direct), part(View::Indirect));
    for p in 0..full.len() {
        for c in 0..3 {
            let sum = d[p][c] + i[p][c];
            assert!((sum - full[p][c]).abs() <= 1e-4 * full[p][c].abs().max(1e-3), "pixel {p}: {sum} vs {}", full[p][c]);
        }
    }
    assert!(i.iter().map(lum).sum::<f64>() > 0.0, "indirect light is missing");
    // The split itself, not only its sum: the direct view is the brute-force image of the same
    // direct VPLs without any indirect ones (--no-gi traces the same direct set from the same seed;
    // the radius is given, since the default one follows the VPL count).
    let r = RenderSettings { yuksel_radius: Some(0.02), ..base.clone() };
    let d = {
        let mut x = Renderer::new(ctx.clone(), scene.clone(), RenderSettings { view: View::Direct, frames: 1, ..r.clone() }).unwrap();
        render(&mut x, 1).0
    };
    let no_gi = brute_force(&ctx, &scene, &RenderSettings { gi: false, ..r });
    let (dl, nl) = (d.iter().map(lum).sum::<f64>(), no_gi.iter().map(lum).sum::<f64>());
    assert!(dl > 0.0 && nl > 0.0, "direct light is missing: {dl} {nl}");
    for p in 0..d.len() {
        for c in 0..3 {
            assert!((d[p][c] - no_gi[p][c]).abs() <= 1e-4 * no_gi[p][c].abs().max(1e-3), "pixel {p}: direct view {} vs --no-gi {}", d[p][c], no_gi[p][c]);
        }
    }
    common::assert_no_validation_errors(&ctx);
}
