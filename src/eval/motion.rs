//! The real-time measurement (`bench --motion`): a camera moving along a path through each scene,
//! and the error of every displayed frame against a path-traced reference of that frame's camera.
//! This is the comparison a user of a real-time renderer decides on: each frame is shown once, so
//! its own error is what counts, at its own cost.
//!
//! Protocol (per scene, per run):
//! - All modes share the device and scene; their frames interleave (one frame of each mode per
//!   round) so drift on a shared machine hits every mode alike.
//! - Each mode first renders [`WARMUP_FRAMES`] frames at the path's first camera (a user who was
//!   looking before moving: ReSTIR's history is full), then measured frame f at the path's frame
//!   f + 1 after its first keyframe, so that every measured frame moved (frame 0 stood at the
//!   warm-up camera until stop 48: no G-buffer, no reprojection, 8–14 ms cheaper), with
//!   progressive accumulation off: the displayed image is that frame alone.
//! - Frame f is compared with the reference of the same camera: the path tracer, rendered once per
//!   camera and cached like the other references.
//! - With `runs > 1` the measurement repeats with independent VPL sets and pixel seeds (each run
//!   builds its renderers with its own seed; the modes of one run share it, so they stay paired)
//!   and the errors are averaged.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Context as _, Result};

use crate::camera::CameraPath;
use crate::eval::compare::{compare, CompareOptions};
use crate::eval::reference::{make_reference, ReferenceTarget};
use crate::eval::report::OverRuns;
use crate::eval::results::SceneSpec;
use crate::output::RgbImage;
use crate::renderer::Renderer;
use crate::eval::bench::GRID_CASE_CANDIDATES;
use crate::settings::{Bias, GridSettings, Mode, RenderSettings, RestirSettings};
use crate::vk::Context;

/// Frames every mode renders at the path's first camera before the path starts.
pub const WARMUP_FRAMES: u32 = 4;

/// One sampling configuration measured in motion.
#[derive(Clone, Debug)]
pub struct MotionMode {
    pub label: &'static str,
    pub mode: Mode,
    pub restir: RestirSettings,
    /// RIS candidates per pixel; None: the default.
    pub candidates: Option<u32>,
    /// Of them, from the ReGIR grid (0: none, all from the source pdf).
    pub grid_candidates: u32,
}

impl MotionMode {
    /// `base` with this mode's sampling.
    pub fn settings(&self, base: &RenderSettings) -> RenderSettings {
        let mut s = RenderSettings { mode: self.mode, restir: self.restir, ..base.clone() };
        if let Some(candidates) = self.candidates {
            s.candidates = candidates;
        }
        if self.grid_candidates > 0 {
            s.grid = GridSettings { candidates: self.grid_candidates, ..Default::default() };
        }
        s
    }
}

/// Uniform, RIS, ReSTIR biased and unbiased with temporal reuse following the reprojected pixel,
/// ReSTIR without temporal reuse (what the thesis's viewer did whenever the camera moved: it
/// reset every reservoir), and RIS and unbiased ReSTIR with the ReGIR grid
/// ([`GRID_CASE_CANDIDATES`], as `bench --modes --grid` times them): the grid's cells follow the
/// visible surfaces, so a cell the camera has just come to has no entries of its own yet.
pub fn motion_modes() -> Vec<MotionMode> {
    let restir = |bias, temporal| RestirSettings { bias, initial_visibility: Some(false), temporal, ..Default::default() };
    let mode = |label, mode, restir| MotionMode { label, mode, restir, candidates: None, grid_candidates: 0 };
    let (candidates, grid_candidates) = GRID_CASE_CANDIDATES;
    let grid = |m: MotionMode| MotionMode { candidates: Some(candidates), grid_candidates, ..m };
    vec![
        mode("uniform", Mode::Uniform, RestirSettings::default()),
        mode("ris", Mode::Ris, RestirSettings::default()),
        mode("restir", Mode::Restir, restir(Bias::Biased, true)),
        mode("restir-unbiased", Mode::Restir, restir(Bias::Unbiased, true)),
        mode("restir-no-temporal", Mode::Restir, restir(Bias::Unbiased, false)),
        grid(mode("ris-grid", Mode::Ris, RestirSettings::default())),
        grid(mode("restir-unbiased-grid", Mode::Restir, restir(Bias::Unbiased, true))),
    ]
}

/// One displayed frame of one mode (averaged over runs).
#[derive(Clone, Debug, serde::Serialize)]
pub struct MotionPoint {
    pub scene: String,
    pub mode: String,
    /// The measured frame's index, from 0: it stands at the camera path's frame `first + frame +
    /// 1` (`first`: where the measured span starts; 0 for the committed paths), since each
    /// measured frame has moved since the one before.
    pub frame: u32,
    /// GPU ms of that frame.
    pub gpu_ms: f64,
    pub rmse: f64,
    pub relmse: f64,
    pub flip: Option<f64>,
    /// This frame's RMSE in each run, in run order (for the spread over runs).
    #[serde(skip)]
    pub rmse_runs: Vec<f64>,
    /// The reference's own noise as a mean squared error (its per-pixel sample variance over its
    /// frames / frames, [`crate::eval::reference::ReferenceMeta::noise_mse`]; 0 when unknown).
    /// The images are independent of the reference, so it adds to every mode's expected squared
    /// error alike; [`MotionPoint::rmse_less_noise`] takes it out.
    pub ref_noise_mse: f64,
}

impl MotionPoint {
    /// The frame's RMSE (root mean over the runs) less the reference's noise.
    pub fn rmse_less_noise(&self) -> f64 {
        less_noise(self.rmse, self.ref_noise_mse)
    }
}

/// An RMSE against a noisy reference less that reference's own noise (an MSE): the estimate of the
/// RMSE against the reference's expectation, √max(rmse² − noise, 0).
pub fn less_noise(rmse: f64, noise_mse: f64) -> f64 {
    (rmse * rmse - noise_mse).max(0.0).sqrt()
}

/// What `bench --motion` measures.
#[derive(Clone, Debug)]
pub struct MotionOptions {
    /// Scenes, each with its camera path (`scenes/<name>.path.json` beside `scenes/<name>.gltf`).
    pub scenes: Vec<SceneSpec>,
    pub vpls_direct: u32,
    pub vpls_indirect: u32,
    /// Frames measured: the path's frames 1..=frames after its first keyframe (at most its span).
    pub frames: u32,
    /// Path-traced frames per reference.
    pub reference_frames: u32,
    pub runs: u32,
    pub flip: bool,
    pub out_dir: PathBuf,
    pub validate: bool,
}

impl MotionOptions {
    /// The three scenes at `scale` × the thesis's sizes.
    pub fn full(root: &Path, scale: f64) -> Self {
        Self {
            scenes: crate::eval::results::thesis_scenes(root, scale),
            vpls_direct: 100_000,
            vpls_indirect: 100_000,
            // The committed paths span 31 frames after their first keyframe: all of them.
            frames: 31,
            // Reference noise adds the same variance to every mode's squared error (the modes'
            // images are independent of the reference), so it shifts, never reorders, the modes.
            reference_frames: 128,
            runs: 2,
            flip: true,
            out_dir: root.join("docs"),
            validate: false,
        }
    }

    /// A smoke test: tiny images, a few frames, few VPLs, one run.
    pub fn quick(root: &Path) -> Self {
        let scenes = crate::eval::results::thesis_scenes(root, 0.05);
        Self {
            scenes,
            vpls_direct: 2_000,
            vpls_indirect: 2_000,
            frames: 4,
            reference_frames: 8,
            runs: 1,
            flip: false,
            out_dir: root.join("bench-out"),
            validate: false,
        }
    }
}

/// The camera path committed beside a scene: `scenes/x.gltf` → `scenes/x.path.json`.
pub fn path_file(scene: &Path) -> PathBuf {
    scene.with_extension("path.json")
}

/// The first keyframe's frame of `path` (read from `file`), if `frames` moving frames fit after
/// it; else an error naming the file: past its last keyframe the camera stands still.
fn check_span(path: &CameraPath, frames: u32, file: &Path) -> Result<u32> {
    let (first, last) = path.frame_range();
    let span = last - first;
    if frames > span {
        bail!(
            "{}: {frames} moving frames need a path spanning at least as many frames after its first keyframe; it spans \
             {span} (past its last keyframe the camera stands still)",
            file.display()
        );
    }
    Ok(first)
}

/// Measures every mode of [`motion_modes`] along each scene's path; returns the points (one per
/// scene × mode × frame).
pub fn run(ctx: &Arc<Context>, opts: &MotionOptions, log: &mut dyn FnMut(String)) -> Result<Vec<MotionPoint>> {
    run_modes(ctx, opts, &motion_modes(), log)
}

/// [`run`] with other modes (labels must differ): the same protocol for a study of settings.
pub fn run_modes(ctx: &Arc<Context>, opts: &MotionOptions, modes: &[MotionMode], log: &mut dyn FnMut(String)) -> Result<Vec<MotionPoint>> {
    if opts.frames == 0 || opts.runs == 0 || opts.reference_frames == 0 {
        bail!("bench --motion needs at least one frame, one run and one reference frame");
    }
    let refs_dir = opts.out_dir.join("references");
    let mut points = Vec::new();
    for spec in &opts.scenes {
        let label = spec.label();
        let path_json = path_file(&spec.path);
        let scene = spec.upload(ctx)?;
        // In the renderer's coordinates (the scene may have been recentred); the references take
        // their cameras back in the file's (as_override).
        let path = CameraPath::load(&path_json).with_context(|| format!("the camera path of {label}"))?.moved(-scene.info.origin);
        let first = check_span(&path, opts.frames, &path_json)?;
        // Measured frame f stands at the path's frame first + f + 1: each moved since the one before.
        let path_camera = |f: u32| path.at((first + f + 1) as f32);
        let base = RenderSettings {
            progressive: false,
            ..spec.base_settings((opts.vpls_direct, opts.vpls_indirect), opts.validate, None)
        };
        // One path-traced reference per camera of the path.
        let mut references: Vec<RgbImage> = Vec::new();
        let mut noise: Vec<f64> = Vec::new();
        for f in 0..opts.frames {
            let camera = path_camera(f);
            // Accumulated: `base` shows each frame alone, which made every "128-frame" reference
            // one frame (until 2026-11-25: the references' noise then hid the modes' differences).
            let settings = RenderSettings { mode: Mode::Pt, camera: Some(camera.as_override(scene.info.origin)), progressive: true, ..base.clone() };
            // Named by the path's frame (`_f…` files of the protocol before hold other cameras).
            let file = refs_dir.join(format!("{label}_{}x{}_motion_p{:03}_pt.exr", spec.width, spec.height, first + f + 1));
            let made = make_reference(ctx, &scene, &settings, &file, ReferenceTarget::AtLeast { frames: opts.reference_frames }, &mut |_, _| {})?;
            if let Some((n, _, wall)) = made.rendered {
                log(format!("{}: {n} pt frames in {:.1} s", file.display(), wall * 1e-3));
            }
            noise.push(made.meta.noise_mse.unwrap_or(0.0));
            references.push(made.image);
        }
        log(format!("{label}: measuring {} modes over {} moving frames at {}x{}", modes.len(), opts.frames, spec.width, spec.height));
        // Per (mode, frame) over the runs: gpu, rmse, relmse, flip; and each run's RMSE.
        let mut sums = vec![vec![[OverRuns::default(); 4]; opts.frames as usize]; modes.len()];
        let mut rmse_runs = vec![vec![Vec::with_capacity(opts.runs as usize); opts.frames as usize]; modes.len()];
        let compare_opts = CompareOptions { flip: opts.flip, ..Default::default() };
        for run in 0..opts.runs {
            // Each run its own VPL set and pixel noise, shared by its modes (paired run by run):
            // the ± over runs then covers the VPL set's own error too (one set for all runs until
            // stop 48). Seeds other than the base seed, the first run's too: the references are
            // rendered with it (as in `results`, where a run with it repeated the reference's own
            // random numbers and came out with too low an error).
            let seed = crate::eval::run_seed(base.seed, run);
            let mut renderers = Vec::new();
            for m in modes {
                let settings = RenderSettings { seed, ..m.settings(&base) };
                let mut r = Renderer::new(ctx.clone(), scene.clone(), settings).with_context(|| format!("mode {}", m.label))?;
                let start = path.at(first as f32);
                for _ in 0..WARMUP_FRAMES {
                    r.render_frame(&start, false)?;
                }
                renderers.push(r);
            }
            for f in 0..opts.frames {
                let camera = path_camera(f);
                for (i, r) in renderers.iter_mut().enumerate() {
                    let stats = r.render_frame(&camera, false)?;
                    let img = RgbImage { width: spec.width, height: spec.height, pixels: r.read_mean()? };
                    let c = compare(&img, &references[f as usize], &compare_opts)?;
                    let e = &mut sums[i][f as usize];
                    e[0].add(stats.gpu_ms());
                    e[1].add(c.rmse);
                    rmse_runs[i][f as usize].push(c.rmse);
                    e[2].add(c.relmse);
                    e[3].add(c.flip.unwrap_or(0.0));
                }
            }
            log(format!("  {label}: run {}/{} done", run + 1, opts.runs));
        }
        for (i, m) in modes.iter().enumerate() {
            for f in 0..opts.frames {
                let e = sums[i][f as usize];
                points.push(MotionPoint {
                    scene: label.clone(),
                    mode: m.label.to_string(),
                    frame: f,
                    gpu_ms: e[0].mean(),
                    rmse: e[1].rms(),
                    relmse: e[2].mean(),
                    flip: opts.flip.then(|| e[3].mean()),
                    rmse_runs: std::mem::take(&mut rmse_runs[i][f as usize]),
                    ref_noise_mse: noise[f as usize],
                });
            }
        }
    }
    Ok(points)
}

/// motion.csv: one row per scene × mode × frame.
pub fn write_csv(path: &Path, points: &[MotionPoint]) -> Result<()> {
    let mut s = String::from("scene,mode,frame,gpu_ms,rmse,relmse,flip\n");
    for p in points {
        s.push_str(&format!(
            "{},{},{},{:.4},{:.6e},{:.6e},{}\n",
            p.scene,
            p.mode,
            p.frame,
            p.gpu_ms,
            p.rmse,
            p.relmse,
            p.flip.map(|f| format!("{f:.6}")).unwrap_or_default()
        ));
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// The per-scene table: mean over the moving frames of each error and of the GPU time, and the
/// inverse efficiency relMSE × ms (lower is better: the error a mode buys with its time). RMSE
/// less the references' noise first (± its standard error over the runs), then against the
/// references as they are.
pub fn table_markdown(points: &[MotionPoint]) -> String {
    let scenes = crate::eval::report::ordered(points.iter().map(|p| p.scene.as_str()));
    let mut s = String::new();
    for scene in scenes {
        let noise = reference_noise_rmse(points, scene).unwrap_or(0.0);
        s += &format!(
            "\n**{scene}** (mean over the moving frames; the references' own noise: RMSE {noise:.4})\n\n| mode | GPU ms / frame | RMSE less the references' noise | RMSE | relMSE | FLIP | relMSE × ms |\n|---|---:|---:|---:|---:|---:|---:|\n"
        );
        let modes = crate::eval::report::ordered(points.iter().filter(|p| p.scene == scene).map(|p| p.mode.as_str()));
        for m in modes {
            let sel: Vec<&MotionPoint> = points.iter().filter(|p| p.scene == scene && p.mode == m).collect();
            let n = sel.len() as f64;
            let mean = |f: &dyn Fn(&MotionPoint) -> f64| sel.iter().map(|p| f(p)).sum::<f64>() / n;
            let (ms, relmse) = (mean(&|p| p.gpu_ms), mean(&|p| p.relmse));
            let raw = mean_rmse(points, scene, m).expect("the mode has points on the scene");
            let rmse = mean_rmse_less_noise(points, scene, m).expect("the mode has points on the scene");
            let flip = if sel.iter().all(|p| p.flip.is_some()) {
                format!("{:.4}", mean(&|p| p.flip.unwrap_or(0.0)))
            } else {
                "—".into()
            };
            let rmse = match mean_rmse_standard_error(points, scene, m) {
                Some(se) => format!("{rmse:.4} ± {se:.4}"),
                None => format!("{rmse:.4}"),
            };
            // Three significant digits: on a GPU a frame takes 0.4 ms, and {:.1} showed every mode
            // alike while the ratios came from the unrounded values.
            let fmt = crate::eval::report::fmt_sig3;
            s += &format!("| {m} | {} | {rmse} | {raw:.4} | {relmse:.4} | {flip} | {} |\n", fmt(ms), fmt(relmse * ms));
        }
    }
    s
}

/// One SVG per scene: RMSE of each displayed frame against its own reference.
pub fn plots(dir: &Path, points: &[MotionPoint]) -> Result<Vec<PathBuf>> {
    let curve: Vec<crate::eval::report::CurvePoint> = points
        .iter()
        .map(|p| crate::eval::report::CurvePoint {
            scene: p.scene.clone(),
            mode: p.mode.clone(),
            reference: "pt".into(),
            frames: p.frame + 1,
            gpu_ms: p.gpu_ms,
            wall_ms: p.gpu_ms,
            rmse: p.rmse,
            relmse: p.relmse,
            mean_ratio: 1.0,
            mean_ratio_se: None,
            worst_share: 0.0,
            flip: p.flip,
        })
        .collect();
    let scenes = crate::eval::report::ordered(points.iter().map(|p| p.scene.as_str()));
    let mut out = Vec::new();
    for scene in scenes {
        let f = dir.join(format!("{scene}_motion_rmse.svg"));
        crate::eval::report::plot_error_vs_displayed_frame(&f, &curve, scene, "pt", crate::eval::report::Metric::Rmse)?;
        out.push(f);
    }
    Ok(out)
}

/// What [`write_outputs`] wrote.
pub struct MotionFiles {
    pub csv: PathBuf,
    pub plots: Vec<PathBuf>,
}

/// motion.csv in `dir` and the plots in `dir/plots`.
pub fn write_outputs(dir: &Path, points: &[MotionPoint]) -> Result<MotionFiles> {
    let plots_dir = dir.join("plots");
    std::fs::create_dir_all(&plots_dir).with_context(|| format!("creating {}", plots_dir.display()))?;
    let csv = dir.join("motion.csv");
    write_csv(&csv, points)?;
    Ok(MotionFiles { csv, plots: plots(&plots_dir, points)? })
}

/// Mean of `of` over the moving frames of one scene and mode.
fn mean_over_frames(points: &[MotionPoint], scene: &str, mode: &str, of: fn(&MotionPoint) -> f64) -> Option<f64> {
    let sel: Vec<f64> = points.iter().filter(|p| p.scene == scene && p.mode == mode).map(of).collect();
    (!sel.is_empty()).then(|| sel.iter().sum::<f64>() / sel.len() as f64)
}

/// Mean RMSE over the moving frames of one scene and mode, against the references as they are.
fn mean_rmse(points: &[MotionPoint], scene: &str, mode: &str) -> Option<f64> {
    mean_over_frames(points, scene, mode, |p| p.rmse)
}

/// Mean RMSE over the moving frames of one scene and mode, less the references' noise
/// ([`MotionPoint::rmse_less_noise`]).
pub fn mean_rmse_less_noise(points: &[MotionPoint], scene: &str, mode: &str) -> Option<f64> {
    mean_over_frames(points, scene, mode, MotionPoint::rmse_less_noise)
}

/// The references' noise on one scene as an RMSE: the root of their mean noise MSE over the
/// frames (what [`MotionPoint::rmse_less_noise`] takes out, squared).
pub fn reference_noise_rmse(points: &[MotionPoint], scene: &str) -> Option<f64> {
    let mode = points.iter().find(|p| p.scene == scene)?.mode.clone();
    mean_over_frames(points, scene, &mode, |p| p.ref_noise_mse).map(f64::sqrt)
}

/// Mean GPU ms per displayed frame of one scene and mode.
pub fn mean_ms(points: &[MotionPoint], scene: &str, mode: &str) -> Option<f64> {
    mean_over_frames(points, scene, mode, |p| p.gpu_ms)
}

/// Each run's mean over the moving frames of `mode`'s RMSE on `scene` less the references' noise,
/// in run order (empty when the points carry no runs).
pub fn run_means(points: &[MotionPoint], scene: &str, mode: &str) -> Vec<f64> {
    let sel: Vec<&MotionPoint> = points.iter().filter(|p| p.scene == scene && p.mode == mode).collect();
    let runs = sel.iter().map(|p| p.rmse_runs.len()).min().unwrap_or(0);
    (0..runs).map(|r| sel.iter().map(|p| less_noise(p.rmse_runs[r], p.ref_noise_mse)).sum::<f64>() / sel.len() as f64).collect()
}

/// The standard error over runs of `mode`'s mean RMSE over the moving frames (None with one run).
pub fn mean_rmse_standard_error(points: &[MotionPoint], scene: &str, mode: &str) -> Option<f64> {
    let mut o = OverRuns::default();
    run_means(points, scene, mode).into_iter().for_each(|m| o.add(m));
    o.standard_error()
}

/// `a`'s mean RMSE over the moving frames as a share of `b`'s, run by run (the runs share their
/// seeds, so the pair moves together): the mean of the runs' ratios and its standard error.
pub fn paired_ratio(points: &[MotionPoint], scene: &str, a: &str, b: &str) -> Option<(f64, Option<f64>)> {
    let (ra, rb) = (run_means(points, scene, a), run_means(points, scene, b));
    let mut o = OverRuns::default();
    ra.iter().zip(&rb).filter(|(_, d)| **d > 0.0).for_each(|(n, d)| o.add(n / d));
    (o.count() > 0).then(|| (o.mean(), o.standard_error()))
}

/// The Markdown section: protocol, headline (temporal reuse following the reprojected pixels
/// against none, per scene), the table and the plots (paths relative to the Markdown's folder).
pub fn section_markdown(opts: &MotionOptions, points: &[MotionPoint], plots: &[PathBuf]) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let sizes: Vec<String> = opts.scenes.iter().map(|s| format!("{} {}×{}", s.label(), s.width, s.height)).collect();
    let defaults = RenderSettings { mode: Mode::Restir, ..Default::default() };
    let (moving_candidates, moving_neighbours) = defaults.moving_sampling();
    let _ = writeln!(
        s,
        "A camera moves along the path committed beside each scene (`scenes/<name>.path.json`); every displayed frame \
         (progressive accumulation off: the image is that frame alone) is compared with a path-traced reference of {} frames \
         at that frame's camera. Scenes: {}. VPLs: {} direct + {} indirect. {} moving frames (the path's frames after its first \
         keyframe, each moved since the one before) after {WARMUP_FRAMES} still warm-up frames at its first keyframe, {} run(s) \
         averaged, each with its own VPL set and pixel noise, shared by its modes (RMSE: the root of their mean squared error; ± the standard error over the runs of \
         each run's mean over the frames, and of the run-by-run share below{}); modes interleave frame by frame. ReSTIR variants use unshadowed targets; \
         with temporal reuse every displayed frame after the first has history and draws the sampling of a frame displayed alone \
         (`--moving-candidates`, `--moving-neighbours`: {} candidates and {} neighbours by default, its pixels without history {} and {}, against {} and {} without temporal reuse). \
         The references' own noise adds the same amount to every mode's expected squared error (the images are independent of \
         the reference), so it is taken out: each frame's RMSE is √max(RMSE² − n, 0), n the reference's mean per-pixel sample \
         variance over its frames divided by their number (recorded with the reference). The shares below and the first RMSE \
         column are so corrected; the second RMSE column, relMSE, FLIP and the plots are against the references as they are.\n",
        opts.reference_frames,
        sizes.join(", "),
        opts.vpls_direct,
        opts.vpls_indirect,
        opts.frames,
        opts.runs,
        // (With two runs a standard error rests on one degree of freedom: a rough guide only.)
        if opts.runs == 2 { "; with 2 runs each ± rests on one degree of freedom, a rough guide only" } else { "" },
        moving_candidates,
        moving_neighbours,
        defaults.candidates,
        defaults.restir.spatial_neighbours,
        defaults.candidates,
        defaults.restir.spatial_neighbours,
    );
    let scenes = crate::eval::report::ordered(points.iter().map(|p| p.scene.as_str()));
    for scene in &scenes {
        let on = mean_rmse_less_noise(points, scene, "restir-unbiased");
        let off = mean_rmse_less_noise(points, scene, "restir-no-temporal");
        let uniform = mean_rmse_less_noise(points, scene, "uniform");
        let ms = (mean_ms(points, scene, "restir-unbiased"), mean_ms(points, scene, "restir-no-temporal"));
        if let (Some(on), Some(off), Some(u), (Some(ms_on), Some(ms_off))) = (on, off, uniform, ms) {
            // The share run by run (± its standard error over the runs, which share their seeds).
            let share = match paired_ratio(points, scene, "restir-unbiased", "restir-no-temporal") {
                Some((r, Some(se))) => format!("{:.0} ± {:.0}%", 100.0 * r, 100.0 * se),
                _ => format!("{:.0}%", 100.0 * on / off),
            };
            let _ = writeln!(
                s,
                "- **{scene}**: unbiased ReSTIR with temporal reuse following the reprojected pixels has {share} of the \
                 per-frame RMSE of ReSTIR that drops its history on motion ({on:.4} vs {off:.4}) at {:.2}× its GPU time; uniform \
                 sampling: {u:.4}.",
                ms_on / ms_off
            );
        }
        // The ReGIR grid against the same mode without it, run by run.
        let (m, g) = GRID_CASE_CANDIDATES;
        let mut grid = Vec::new();
        for (name, with, without) in [("RIS", "ris-grid", "ris"), ("unbiased ReSTIR", "restir-unbiased-grid", "restir-unbiased")] {
            let (Some((r, se)), Some(ms_with), Some(ms_without)) =
                (paired_ratio(points, scene, with, without), mean_ms(points, scene, with), mean_ms(points, scene, without))
            else {
                continue;
            };
            let share = match se {
                Some(se) => format!("{:.0} ± {:.0}%", 100.0 * r, 100.0 * se),
                None => format!("{:.0}%", 100.0 * r),
            };
            grid.push(format!("{name} {share} at {:.2}× its GPU time", ms_with / ms_without));
        }
        if !grid.is_empty() {
            // ReSTIR's frames displayed alone with history draw fewer, never fewer than the grid's.
            let grid_mode = motion_modes().into_iter().find(|m| m.label == "restir-unbiased-grid").expect("the grid case");
            let moving = grid_mode.settings(&defaults).moving_sampling().0;
            let _ = writeln!(
                s,
                "- **{scene}**, the ReGIR grid ({m} candidates, {g} of them from the grid, against the default candidates from \
                 the source pdf alone; ReSTIR's frames displayed alone with history draw {moving}, {} from the grid): per-frame RMSE {}.",
                g.min(moving),
                grid.join("; ")
            );
        }
    }
    s.push_str(&table_markdown(points));
    s.push('\n');
    for p in plots {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let _ = writeln!(s, "![{name}](plots/{name})");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every measured frame must move: more frames than the path spans after its first keyframe
    /// are refused, naming the file.
    #[test]
    fn moving_frames_must_fit_in_the_path() {
        let path = CameraPath::from_json(
            r#"{"keyframes": [{"frame": 3, "eye": [0, 0, 0], "target": [0, 0, 1], "fov": 40},
                             {"frame": 34, "eye": [1, 0, 0], "target": [1, 0, 1], "fov": 40}]}"#,
        )
        .expect("a valid path");
        let file = Path::new("x.path.json");
        assert_eq!(check_span(&path, 31, file).unwrap(), 3);
        let e = check_span(&path, 32, file).unwrap_err().to_string();
        assert!(e.contains("x.path.json") && e.contains("spans 31"), "{e}");
    }
}
