//! `bench --radius`: the Yuksel radius as a measured trade-off. For each of the three scenes,
//! ReSTIR (default settings) with r = k × the mean VPL spacing (k = 1 … 64), the thesis's fixed
//! radius scaled to the scene, and large radii with `--compensate`, against a path-traced
//! reference: the converged bias, the per-frame variance, RMSE and FLIP after 1 and after
//! `frames` accumulated frames, the share of the squared error in the worst 0.1 % of pixels, and
//! GPU ms per frame (the median frame after the first; the rules run one after another, not
//! interleaved, so the machine's drift between them enters the comparison).
//!
//! Protocol (per scene): one renderer per rule and run, all sharing the device and scene; run k
//! has its own seed, so its own VPL set and pixel noise, and every rule's run k has the same one
//! (rows stay paired). The runs are averaged, and the bias carries its standard error over them:
//! one VPL set's own error moves the image's mean by tenths of a percent (0.4 % from set to set on
//! the living room), so a bias measured on one set says little below that. The reference is the path tracer with default
//! settings (8 bounces; the photons' default 7 gives the VPL images the same light paths), cached in `out/references`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use serde::Serialize;

use crate::eval::compare::{compare, CompareOptions};
use crate::eval::reference::{make_reference, ReferenceTarget};
use crate::eval::run_seed;
use crate::eval::results::SceneSpec;
use crate::output::RgbImage;
use crate::renderer::Renderer;
use crate::settings::{Mode, RenderSettings};
use crate::vk::Context;

/// The thesis's fixed radius, 3.0 units, read in the units of the classic Cornell box (555 units
/// wide): 3/555 of a scene's largest extent.
pub const THESIS_RADIUS_SHARE: f32 = 3.0 / 555.0;

/// Multiples of the mean VPL spacing measured without compensation.
pub const SPACING_MULTIPLES: [f32; 7] = [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0];
/// Multiples measured with `--compensate`.
pub const COMPENSATED_MULTIPLES: [f32; 2] = [16.0, 64.0];
/// Nearest VPLs of the per-VPL rule (`--yuksel-knn`).
pub const KNN_K: u32 = 16;
/// Multiples of each VPL's local spacing measured with the per-VPL rule. Photons crowd where light
/// is (the direct VPLs all lie on the lights), so local spacings run well below the mean one and
/// the useful multiples are larger.
pub const KNN_MULTIPLES: [f32; 4] = [8.0, 16.0, 32.0, 64.0];

/// What `bench --radius` measures.
#[derive(Clone, Debug)]
pub struct RadiusOptions {
    pub scenes: Vec<SceneSpec>,
    pub vpls_direct: u32,
    pub vpls_indirect: u32,
    /// Accumulated frames of the "t = frames" columns.
    pub frames: u32,
    pub reference_frames: u32,
    pub runs: u32,
    pub flip: bool,
    pub out_dir: PathBuf,
}

impl RadiusOptions {
    /// The three scenes at 0.2 × the thesis's sizes (256 px wide), 100k + 100k VPLs.
    pub fn full(root: &Path) -> Self {
        Self {
            scenes: crate::eval::results::thesis_scenes(root, 0.2),
            vpls_direct: 100_000,
            vpls_indirect: 100_000,
            frames: 20,
            reference_frames: 512,
            runs: 2,
            flip: true,
            out_dir: root.join("bench-out"),
        }
    }

    /// A smoke test: tiny images, few VPLs and frames.
    pub fn quick(root: &Path) -> Self {
        Self {
            scenes: crate::eval::results::thesis_scenes(root, 0.05),
            vpls_direct: 2_000,
            vpls_indirect: 2_000,
            frames: 3,
            reference_frames: 8,
            runs: 1,
            flip: false,
            out_dir: root.join("bench-out"),
        }
    }
}

/// One radius rule on one scene (averaged over runs).
#[derive(Clone, Debug, Serialize)]
pub struct RadiusRow {
    pub scene: String,
    pub rule: String,
    /// Yuksel's r (scene units); the median over VPLs for a per-VPL rule.
    pub radius: f32,
    /// Wall seconds to build the renderer (photons, the kNN search of a per-VPL rule, pipelines).
    pub setup_s: f64,
    pub compensate: bool,
    pub gpu_ms: f64,
    /// mean ratio − 1 of the image after `frames` frames against the path tracer, averaged over
    /// the runs (each with its own VPL set).
    pub bias: f64,
    /// The bias's standard error over the runs: VPL sets and pixel noise together (None for one run).
    pub bias_se: Option<f64>,
    /// The bias minus the default rule's (`DEFAULT_RADIUS_SPACINGS` × the mean spacing), run by run
    /// (run k has the same VPL set and seed under every rule), averaged: the rule's own effect.
    pub bias_vs_default: Option<f64>,
    /// Its standard error over the runs (None for one run).
    pub bias_vs_default_se: Option<f64>,
    /// Each run's bias, in run order.
    #[serde(skip)]
    pub bias_runs: Vec<f64>,
    /// Mean over pixels of the per-pixel variance across a run's frames (channel mean; the frames
    /// are correlated through temporal reuse, so this is below one frame's own variance).
    pub frame_variance: f64,
    pub rmse_1: f64,
    pub rmse_n: f64,
    pub flip_1: Option<f64>,
    pub flip_n: Option<f64>,
    /// Worst 0.1 % pixels' share of the squared error after `frames` frames.
    pub worst_share_n: f64,
}

/// Measures every rule on every scene.
pub fn run(ctx: &Arc<Context>, opts: &RadiusOptions, log: &mut dyn FnMut(String)) -> Result<Vec<RadiusRow>> {
    if opts.frames == 0 || opts.runs == 0 || opts.reference_frames == 0 {
        bail!("bench --radius needs at least one frame, one run and one reference frame");
    }
    let refs_dir = opts.out_dir.join("references");
    let compare_opts = CompareOptions { flip: opts.flip, ..Default::default() };
    let mut rows = Vec::new();
    for spec in &opts.scenes {
        let label = spec.label();
        let scene = spec.upload(ctx)?;
        let base = RenderSettings {
            mode: Mode::Restir,
            ..spec.base_settings((opts.vpls_direct, opts.vpls_indirect), false, None)
        };
        let file = refs_dir.join(format!("{label}_{}x{}_pt.exr", spec.width, spec.height));
        let made = make_reference(ctx, &scene, &RenderSettings { mode: Mode::Pt, ..base.clone() }, &file, ReferenceTarget::AtLeast { frames: opts.reference_frames }, &mut |_, _| {})?;
        if let Some((n, _, wall)) = made.rendered {
            log(format!("{}: {n} pt frames in {:.1} s", file.display(), wall * 1e-3));
        }
        let reference = made.image;
        // The mean VPL spacing, from the default rule's radius of a renderer with the default.
        let first = Renderer::new(ctx.clone(), scene.clone(), base.clone())
            .context("the default radius")?;
        let default_r = first
            .vpl_summary()
            .and_then(|v| v.yuksel_radius)
            .context("the VPL modes report their radius")?;
        let spacing = default_r / crate::settings::DEFAULT_RADIUS_SPACINGS;
        drop(first);
        let (lo, hi) = scene.info.bounds;
        let extent = (hi - lo).max_element();
        let fixed = |r: f32, compensate: bool| RenderSettings { yuksel_radius: Some(r), compensate, ..base.clone() };
        let mut rules: Vec<(String, RenderSettings)> =
            SPACING_MULTIPLES.iter().map(|&k| (format!("{k}× spacing"), fixed(k * spacing, false))).collect();
        rules.push(("thesis (3/555 of the extent)".into(), fixed(THESIS_RADIUS_SHARE * extent, false)));
        rules.extend(COMPENSATED_MULTIPLES.iter().map(|&k| (format!("{k}× spacing + --compensate"), fixed(k * spacing, true))));
        rules.extend(KNN_MULTIPLES.iter().map(|&m| {
            let s = RenderSettings { yuksel_knn: Some(KNN_K), yuksel_spacings: Some(m), ..base.clone() };
            (format!("per VPL: {m}× local spacing ({KNN_K}-NN)"), s)
        }));
        log(format!("{label}: {} rules at {}x{} (spacing {spacing:.5})", rules.len(), spec.width, spec.height));
        for (rule, settings) in rules {
            let compensate = settings.compensate;
            let mut sums = [crate::eval::report::OverRuns::default(); 7];
            let mut bias_runs = Vec::new();
            let (mut radius_sum, mut setup_sum) = (0.0f64, 0.0f64);
            for run in 0..opts.runs {
                // Run k traces its own VPL set (the seed seeds the photons and the pixels), the
                // same for every rule: the bias then averages over VPL sets, and rows stay paired.
                let seeded = RenderSettings { seed: run_seed(base.seed, run), ..settings.clone() };
                let start = std::time::Instant::now();
                let mut r = Renderer::new(ctx.clone(), scene.clone(), seeded).with_context(|| format!("{label}: {rule}, run {}", run + 1))?;
                setup_sum += start.elapsed().as_secs_f64();
                radius_sum += r.vpl_summary().and_then(|v| v.yuksel_radius).context("the VPL modes report their radius")? as f64;
                let camera = r.initial_camera();
                let mut ms: Vec<f64> = Vec::with_capacity(opts.frames as usize);
                let mut first = None;
                for f in 0..opts.frames {
                    ms.push(r.render_frame(&camera, false)?.gpu_ms());
                    if f == 0 {
                        let img = RgbImage { width: spec.width, height: spec.height, pixels: r.read_mean()? };
                        first = Some(compare(&img, &reference, &compare_opts)?);
                    }
                }
                let img = RgbImage { width: spec.width, height: spec.height, pixels: r.read_mean()? };
                let last = compare(&img, &reference, &compare_opts)?;
                let first = first.expect("frames > 0");
                bias_runs.push(last.mean_ratio - 1.0);
                let var = r.read_variance()?;
                let frame_variance = var.iter().map(|p| p.iter().map(|&c| c as f64).sum::<f64>() / 3.0).sum::<f64>() / var.len().max(1) as f64;
                // The median frame after the first: a new renderer's first frame holds the first
                // dispatch of every pass (lavapipe compiles a shader there) and has no history
                // (the first rules read 39 ms where the later ones read 34).
                let median_ms = crate::output::TimingStats::of(if ms.len() > 1 { &ms[1..] } else { &ms[..] }).median;
                for (s, v) in sums.iter_mut().zip([
                    median_ms,
                    frame_variance,
                    first.rmse,
                    last.rmse,
                    first.flip.unwrap_or(0.0),
                    last.flip.unwrap_or(0.0),
                    last.worst_share,
                ]) {
                    s.add(v);
                }
            }
            let radius = (radius_sum / opts.runs as f64) as f32;
            let setup_s = setup_sum / opts.runs as f64;
            let mut bias = crate::eval::report::OverRuns::default();
            bias_runs.iter().for_each(|&b| bias.add(b));
            rows.push(RadiusRow {
                scene: label.clone(),
                rule: rule.clone(),
                radius,
                setup_s,
                compensate,
                gpu_ms: sums[0].mean(),
                bias: bias.mean(),
                bias_se: bias.standard_error(),
                bias_vs_default: None,
                bias_vs_default_se: None,
                bias_runs,
                frame_variance: sums[1].mean(),
                // RMSEs over the runs: the root of their mean squared error.
                rmse_1: sums[2].rms(),
                rmse_n: sums[3].rms(),
                flip_1: opts.flip.then(|| sums[4].mean()),
                flip_n: opts.flip.then(|| sums[5].mean()),
                worst_share_n: sums[6].mean(),
            });
            log(format!("  {label}: {rule} done"));
        }
        pair_with_default(rows.iter_mut().filter(|r| r.scene == label));
    }
    Ok(rows)
}

/// The default rule's row label.
fn default_rule() -> String {
    format!("{}× spacing", crate::settings::DEFAULT_RADIUS_SPACINGS)
}

/// Fills each row's bias against the default rule's, run by run, in one scene's rows.
fn pair_with_default<'a>(rows: impl Iterator<Item = &'a mut RadiusRow>) {
    let mut rows: Vec<&mut RadiusRow> = rows.collect();
    let Some(default) = rows.iter().find(|r| r.rule == default_rule()).map(|r| r.bias_runs.clone()) else { return };
    for r in rows.iter_mut().filter(|r| r.rule != default_rule() && r.bias_runs.len() == default.len()) {
        let mut d = crate::eval::report::OverRuns::default();
        r.bias_runs.iter().zip(&default).for_each(|(a, b)| d.add(a - b));
        r.bias_vs_default = Some(d.mean());
        r.bias_vs_default_se = d.standard_error();
    }
}

/// The table, one block per scene.
pub fn markdown(opts: &RadiusOptions, rows: &[RadiusRow]) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let sizes: Vec<String> = opts.scenes.iter().map(|s| format!("{} {}×{}", s.label(), s.width, s.height)).collect();
    let _ = writeln!(
        s,
        "ReSTIR (unbiased, default settings) with each Yuksel radius rule against a path-traced reference of {} frames \
         (8 bounces; the photons' 7 give the VPL images the same light paths). Scenes: {}. VPLs: {} direct + {} indirect (the mean VPL \
         spacing is √(A/(πN))). {} run(s) averaged, each with its own seed, so its own VPL set and pixel noise; run k has the same VPL set \
         under every rule, so differences between rows are paired (RMSE: the root of the runs' mean squared error); t = 1 is the first frame, t = {} the \
         mean of {} accumulated frames. Bias: mean ratio − 1 after {} frames, ± its standard error over the runs (VPL sets and pixel noise together; \
         with few runs a rough one). Bias − default's: a row's bias minus the default rule's ({}), run by run, which share \
         their VPL set and seed, averaged ± its standard error: the rule's own effect, free of a set's offset and of most of the noise. Frame variance: mean per-pixel variance \
         across a run's frames (correlated through temporal reuse, so below one frame's own variance; comparable \
         between rows). Worst 0.1 %: share of the squared error in the worst 0.1 % of pixels after {} frames. Per-VPL \
         rules (`--yuksel-knn {KNN_K} --yuksel-spacings M`): each VPL's r is M × its local spacing d_K/√K from its K \
         nearest VPLs; their r column is the median over VPLs. Setup: wall seconds to build the renderer (photons, \
         pipelines, and the host's nearest-neighbour search of a per-VPL rule). GPU ms: the median frame after a run's \
         first (which compiles shaders and has no history), averaged over the runs; the rules run one after another, not \
         interleaved, so differences of a few percent are the machine's drift. The reference's own noise adds to \
         every row's error alike.\n",
        opts.reference_frames,
        sizes.join(", "),
        opts.vpls_direct,
        opts.vpls_indirect,
        opts.runs,
        opts.frames,
        opts.frames,
        opts.frames,
        default_rule(),
        opts.frames
    );
    let scenes = crate::eval::report::ordered(rows.iter().map(|r| r.scene.as_str()));
    for scene in scenes {
        let _ = writeln!(s, "**{scene}**\n");
        let _ = writeln!(
            s,
            "| rule | r | bias | bias − default's | frame variance | RMSE t=1 | RMSE t={n} | FLIP t=1 | FLIP t={n} | worst 0.1 % t={n} | GPU ms | setup s |",
            n = opts.frames
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
        for r in rows.iter().filter(|r| r.scene == scene) {
            let flip = |f: Option<f64>| f.map(|v| format!("{v:.4}")).unwrap_or_else(|| "–".into());
            let _ = writeln!(
                s,
                "| {} | {:.4} | {:+.2}{} % | {} | {:.4} | {:.4} | {:.4} | {} | {} | {:.0}% | {:.1} | {:.1} |",
                r.rule,
                r.radius,
                100.0 * r.bias,
                r.bias_se.map(|se| format!(" ± {:.2}", 100.0 * se)).unwrap_or_default(),
                match r.bias_vs_default {
                    Some(d) => format!("{:+.2}{} %", 100.0 * d, r.bias_vs_default_se.map(|se| format!(" ± {:.2}", 100.0 * se)).unwrap_or_default()),
                    None => "–".into(),
                },
                r.frame_variance,
                r.rmse_1,
                r.rmse_n,
                flip(r.flip_1),
                flip(r.flip_n),
                100.0 * r.worst_share_n,
                r.gpu_ms,
                r.setup_s
            );
        }
        s.push('\n');
    }
    s
}

/// radius.csv: one row per scene × rule.
pub fn write_csv(path: &Path, rows: &[RadiusRow]) -> Result<()> {
    let mut text =
        String::from("scene,rule,radius,setup_s,compensate,gpu_ms,bias,bias_se,frame_variance,rmse_1,rmse_n,flip_1,flip_n,worst_share_n,bias_vs_default,bias_vs_default_se\n");
    for r in rows {
        let opt = |v: Option<f64>| v.map(|x| x.to_string()).unwrap_or_default();
        text.push_str(&format!(
            "{},\"{}\",{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            r.scene,
            r.rule,
            r.radius,
            r.setup_s,
            r.compensate,
            r.gpu_ms,
            r.bias,
            opt(r.bias_se),
            r.frame_variance,
            r.rmse_1,
            r.rmse_n,
            opt(r.flip_1),
            opt(r.flip_n),
            r.worst_share_n,
            opt(r.bias_vs_default),
            opt(r.bias_vs_default_se)
        ));
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
