//! `bench --scaling`: how the cost grows as the work grows. Frame GPU ms of uniform, RIS and ReSTIR
//! (default settings) against the VPL count, the image size and the triangle count, and the photon
//! pass and the BLAS/TLAS builds against what they build. Each curve is summarised by its measured
//! exponent (the least-squares slope of log cost against log size) beside the exponent its
//! algorithm predicts, so a departure from the expected law is a number, not an impression.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context as _, Result};
use serde::Serialize;

use crate::eval::bench::{dense_scene, time_modes, time_photons};
use crate::scene::Scene;
use crate::scene_gpu::SceneGpu;
use crate::settings::{Mode, RenderSettings, RestirSettings};
use crate::vk::Context;

/// What `bench --scaling` measures.
#[derive(Clone, Debug)]
pub struct ScalingOptions {
    pub cornell: PathBuf,
    /// Total VPL counts (half direct, half indirect) of the VPL sweep.
    pub vpl_counts: Vec<u32>,
    /// Image sizes of the pixel sweep.
    pub sizes: Vec<(u32, u32)>,
    /// (rings, segments) of the generated sphere of the triangle sweep: 2·rings·segments triangles.
    pub spheres: Vec<(u32, u32)>,
    /// Image size of the VPL and triangle sweeps.
    pub size: (u32, u32),
    /// Total VPLs of the pixel and triangle sweeps.
    pub vpls: u32,
    /// Timed frames per mode and point (after two warm-up frames).
    pub frames: u32,
    /// Timed photon-pass runs per point (after the renderer's own first trace).
    pub photon_runs: u32,
}

impl ScalingOptions {
    /// The measurement for docs: 10k … 2M VPLs, 256×144 … 1920×1080, ~1k … ~1M triangles. The
    /// sizes share one aspect ratio: the camera keeps its vertical field of view, so at 16:9 the
    /// square Cornell box leaves dark bars at the sides that cost almost nothing, and a sweep from
    /// 256² and 512² to 1280×720 read that as a sublinear law (0.56–0.65 between 512² and
    /// 1280×720, about 1 on either side).
    pub fn full(root: &Path) -> Self {
        Self {
            cornell: root.join("scenes/cornell_box.gltf"),
            vpl_counts: vec![10_000, 50_000, 200_000, 1_000_000, 2_000_000],
            sizes: vec![(256, 144), (512, 288), (1280, 720), (1920, 1080)],
            spheres: vec![(16, 32), (50, 100), (160, 320), (500, 1000)],
            size: (640, 360),
            vpls: 200_000,
            frames: 3,
            photon_runs: 3,
        }
    }

    /// A smoke test: seconds.
    pub fn quick(root: &Path) -> Self {
        Self {
            cornell: root.join("scenes/cornell_box.gltf"),
            vpl_counts: vec![2_000, 8_000],
            sizes: vec![(32, 18), (64, 36)],
            spheres: vec![(8, 16), (16, 32)],
            size: (48, 32),
            vpls: 4_000,
            frames: 1,
            photon_runs: 1,
        }
    }
}

/// One measured cost at one size of one sweep.
#[derive(Clone, Debug, Serialize)]
pub struct ScalingPoint {
    /// "vpls", "pixels" or "triangles".
    pub sweep: &'static str,
    /// The swept quantity (VPLs, pixels or triangles).
    pub x: f64,
    /// What was timed: a mode's frame, "photon_emit", "blas build" or "tlas build".
    pub what: String,
    /// Milliseconds (GPU timestamps for frames and photons, wall for the builds).
    pub ms: f64,
}

/// The modes every sweep times.
fn cases() -> Vec<(&'static str, Mode, RestirSettings)> {
    vec![
        ("uniform", Mode::Uniform, RestirSettings::default()),
        ("ris", Mode::Ris, RestirSettings::default()),
        ("restir", Mode::Restir, RestirSettings::default()),
    ]
}

fn base(scene: &Path, (width, height): (u32, u32), vpls: u32) -> RenderSettings {
    RenderSettings {
        scene: scene.to_path_buf(),
        width,
        height,
        vpls_direct: vpls / 2,
        vpls_indirect: vpls - vpls / 2,
        ..Default::default()
    }
}

/// Runs the three sweeps; `log` receives a line per point.
pub fn run(ctx: &Arc<Context>, opts: &ScalingOptions, log: &mut dyn FnMut(String)) -> Result<Vec<ScalingPoint>> {
    let mut points = Vec::new();
    let push_modes = |points: &mut Vec<ScalingPoint>, sweep: &'static str, x: f64, rows: Vec<crate::eval::bench::ModeBench>| {
        for r in rows {
            points.push(ScalingPoint { sweep, x, what: r.label, ms: r.gpu_ms_per_frame });
        }
    };
    let cornell = Scene::load(&opts.cornell)?;
    let cornell_gpu = Arc::new(SceneGpu::new(ctx, &cornell, true, crate::vk::accel::MERGE_MAX_TRIANGLES).context("uploading the Cornell box")?);

    for &n in &opts.vpl_counts {
        let settings = base(&opts.cornell, opts.size, n);
        let rows = time_modes(ctx, &cornell_gpu, &settings, &cases(), opts.frames, None).with_context(|| format!("{n} VPLs"))?;
        log(format!("vpls {n}: {}", summary(&rows)));
        push_modes(&mut points, "vpls", n as f64, rows);
        let ms = time_photons(ctx, &cornell_gpu, &settings, opts.photon_runs)?.gpu_ms;
        points.push(ScalingPoint { sweep: "vpls", x: n as f64, what: "photon_emit".into(), ms });
    }

    for &(w, h) in &opts.sizes {
        let settings = base(&opts.cornell, (w, h), opts.vpls);
        let rows = time_modes(ctx, &cornell_gpu, &settings, &cases(), opts.frames, None).with_context(|| format!("{w}x{h}"))?;
        log(format!("{w}x{h}: {}", summary(&rows)));
        push_modes(&mut points, "pixels", (w * h) as f64, rows);
    }

    for &(rings, segments) in &opts.spheres {
        let scene = dense_scene(rings, segments)?;
        let t = scene.triangle_count() as f64;
        let gpu = Arc::new(SceneGpu::new(ctx, &scene, true, crate::vk::accel::MERGE_MAX_TRIANGLES).with_context(|| format!("uploading a sphere of {t} triangles"))?);
        points.push(ScalingPoint { sweep: "triangles", x: t, what: "blas build".into(), ms: gpu.blas_ms });
        points.push(ScalingPoint { sweep: "triangles", x: t, what: "tlas build".into(), ms: gpu.tlas_ms });
        let settings = base(&scene.path, opts.size, opts.vpls);
        let rows = time_modes(ctx, &gpu, &settings, &cases(), opts.frames, None).with_context(|| format!("{t} triangles"))?;
        log(format!("{t} triangles (BLAS {:.1} ms, TLAS {:.1} ms): {}", gpu.blas_ms, gpu.tlas_ms, summary(&rows)));
        push_modes(&mut points, "triangles", t, rows);
        let ms = time_photons(ctx, &gpu, &settings, opts.photon_runs)?.gpu_ms;
        points.push(ScalingPoint { sweep: "triangles", x: t, what: "photon_emit".into(), ms });
    }
    Ok(points)
}

fn summary(rows: &[crate::eval::bench::ModeBench]) -> String {
    rows.iter().map(|r| format!("{} {:.1} ms", r.label, r.gpu_ms_per_frame)).collect::<Vec<_>>().join(", ")
}

/// Least-squares slope of ln(ms) against ln(x): the measured exponent of cost ∝ x^k (None with
/// fewer than two usable points), and its standard error from the fit's residuals (None with
/// fewer than three points: two always fit exactly).
pub fn exponent(points: &[(f64, f64)]) -> Option<(f64, Option<f64>)> {
    let logs: Vec<(f64, f64)> =
        points.iter().filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite()).map(|(x, y)| (x.ln(), y.ln())).collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let (mx, my) = (logs.iter().map(|p| p.0).sum::<f64>() / n, logs.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let k = sxy / sxx;
    let residuals: f64 = logs.iter().map(|p| (p.1 - my - k * (p.0 - mx)).powi(2)).sum();
    let se = (logs.len() > 2).then(|| (residuals / (n - 2.0) / sxx).sqrt());
    Some((k, se))
}

/// A measured exponent departs from the expected range `lo..=hi`: by more than 0.1 and more than
/// two of its standard errors (with no standard error, two points, by more than 0.1).
pub fn departs(k: f64, se: Option<f64>, (lo, hi): (f64, f64)) -> bool {
    let d = if k < lo { lo - k } else if k > hi { k - hi } else { 0.0 };
    d > 0.1 && se.is_none_or(|se| d > 2.0 * se)
}

/// How a curve is expected to grow with its size x.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Law {
    /// ms ∝ x^k.
    Power(f64),
    /// ms ∝ log x (plus a constant): a power-law fit over x from `lo` up gives an exponent between
    /// 0 (the constant dominates) and 1 / ln lo (all of it logarithmic).
    Log,
    /// ms ∝ x log x: between 1 and 1 + 1 / ln lo likewise.
    NLogN,
}

impl Law {
    /// The exponents a power-law fit over sizes from `lo` may give under this law.
    fn range(self, lo: f64) -> (f64, f64) {
        let log = 1.0 / lo.max(std::f64::consts::E).ln();
        match self {
            Law::Power(k) => (k, k),
            Law::Log => (0.0, log),
            Law::NLogN => (1.0, 1.0 + log),
        }
    }
}

/// The law each curve is expected to follow, and why.
fn expected(sweep: &str, what: &str) -> (Law, &'static str) {
    match (sweep, what) {
        ("vpls", "photon_emit") => (Law::Power(1.0), "one photon path per VPL: linear"),
        ("vpls", _) => (Law::Power(0.0), "a fixed number of VPLs read per pixel: independent of the count (until the VPL buffer outgrows the caches)"),
        ("pixels", _) => (Law::Power(1.0), "fixed work per pixel: linear in pixels"),
        ("triangles", "blas build") => (Law::NLogN, "a BVH build: n log n, a power-law exponent from 1 to 1 + 1/ln n"),
        ("triangles", "tlas build") => (Law::Power(0.0), "one instance per mesh: independent of triangles"),
        ("triangles", _) => (Law::Log, "BVH traversal: logarithmic (plus the work that does not trace), a power-law exponent from 0 to 1/ln n"),
        _ => (Law::Power(f64::NAN), ""),
    }
}

/// The sweeps: (key, title, unit of x).
const SWEEPS: [(&str, &str, &str); 3] =
    [("vpls", "VPL count (Cornell box)", "VPLs"), ("pixels", "Image size (Cornell box)", "pixels"), ("triangles", "Triangle count", "triangles")];

/// The plot of one sweep, relative to the Markdown's directory.
fn plot_file(sweep: &str) -> String {
    format!("plots/scaling_{sweep}.svg")
}

/// One log-log plot per sweep under `dir` (`plots/scaling_<sweep>.svg`): every timed thing's ms
/// against the swept size, so a power law is a straight line and its exponent its slope.
pub fn write_plots(dir: &Path, points: &[ScalingPoint]) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for (sweep, title, unit) in SWEEPS {
        let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for p in points.iter().filter(|p| p.sweep == sweep && p.x > 0.0 && p.ms > 0.0 && p.ms.is_finite()) {
            match series.iter_mut().find(|(w, _)| *w == p.what) {
                Some((_, pts)) => pts.push((p.x, p.ms)),
                None => series.push((p.what.clone(), vec![(p.x, p.ms)])),
            }
        }
        if series.is_empty() {
            continue;
        }
        for (_, pts) in series.iter_mut() {
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        let axes = crate::eval::report::LogLogAxes {
            // "VPL count" stays, "Triangle count" → "triangle count".
            title: format!("Cost against the {}", if title.starts_with("VPL") { title.to_string() } else { title[..1].to_lowercase() + &title[1..] }),
            x_desc: unit.into(),
            y_desc: "ms (frames, photons: GPU; builds: wall)".into(),
            legend: "Timed".into(),
        };
        let path = dir.join(plot_file(sweep));
        crate::eval::report::write_loglog_svg(&path, &series, &axes)?;
        written.push(path);
    }
    Ok(written)
}

/// The Markdown section: one table per sweep (ms per size, measured and expected exponent) and its
/// plot ([`write_plots`]).
pub fn markdown(opts: &ScalingOptions, points: &[ScalingPoint], device: &str) -> String {
    let mut s = format!(
        "Device: {device}. GPU ms per frame (median of {} timed frame{} per mode after 2 warm-up frames, modes interleaved) of uniform, RIS (32 candidates) and ReSTIR (unbiased defaults); photon_emit: median GPU ms of {} re-trace{}; BLAS/TLAS: wall ms of the build submission. Exponent: least-squares slope of log ms against log size, ± its standard error from the fit's residuals (the sizes are timed one after another, so the machine's drift enters it); ✗ where it departs from the expected one by more than 0.1 and more than two standard errors; expected: what the algorithm predicts. The image sizes share one aspect ratio (16:9). VPL and triangle sweeps at {}×{}, pixel and triangle sweeps with {} VPLs. The triangle sweep is a room with a tessellated bumpy sphere (`bench::dense_scene`), seen from its camera.\n\n",
        opts.frames,
        if opts.frames == 1 { "" } else { "s" },
        opts.photon_runs,
        if opts.photon_runs == 1 { "" } else { "s" },
        opts.size.0,
        opts.size.1,
        opts.vpls
    );
    for (sweep, title, unit) in SWEEPS {
        let sel: Vec<&ScalingPoint> = points.iter().filter(|p| p.sweep == sweep).collect();
        if sel.is_empty() {
            continue;
        }
        let mut xs: Vec<f64> = sel.iter().map(|p| p.x).collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup();
        let whats = crate::eval::report::ordered(sel.iter().map(|p| p.what.as_str()));
        s += &format!("**{title}**\n\n| ms at {unit} |");
        for x in &xs {
            s += &format!(" {} |", fmt_count(*x));
        }
        s += " exponent | expected |\n|---|";
        s += &"---:|".repeat(xs.len() + 2);
        s += "\n";
        let mut laws: Vec<String> = Vec::new();
        for w in &whats {
            let pts: Vec<(f64, f64)> = sel.iter().filter(|p| p.what == *w).map(|p| (p.x, p.ms)).collect();
            s += &format!("| {w} |");
            for x in &xs {
                match pts.iter().find(|p| p.0 == *x) {
                    Some(p) => s += &format!(" {} |", crate::eval::report::fmt_sig3(p.1)),
                    None => s += " – |",
                }
            }
            let (law, why) = expected(sweep, w);
            let (lo, hi) = law.range(xs.first().copied().unwrap_or(1.0));
            let k = exponent(&pts).map_or("–".to_string(), |(k, se)| {
                let se_text = se.map_or(String::new(), |se| format!(" ± {se:.2}"));
                let mark = if departs(k, se, (lo, hi)) { " ✗" } else { "" };
                format!("{k:.2}{se_text}{mark}")
            });
            let e = if lo == hi { format!("{lo:.0}") } else { format!("{lo:.1}–{hi:.2}") };
            s += &format!(" {k} | {e} |\n");
            let law = format!("expected {e}: {why}");
            if !laws.contains(&law) {
                laws.push(law);
            }
        }
        s += "\n";
        for law in laws {
            s += &format!("- {law}\n");
        }
        s += &format!("\n![{title}: ms against {unit}, log-log]({})\n\n", plot_file(sweep));
    }
    s
}

fn fmt_count(x: f64) -> String {
    if x >= 1e6 {
        format!("{:.2}M", x / 1e6)
    } else if x >= 1e3 {
        format!("{:.0}k", x / 1e3)
    } else {
        format!("{x:.0}")
    }
}

/// sweep,x,what,ms
pub fn write_csv(path: &Path, points: &[ScalingPoint]) -> Result<()> {
    let mut s = String::from("sweep,x,what,ms\n");
    for p in points {
        s += &format!("{},{},{},{:.4}\n", p.sweep, p.x, p.what, p.ms);
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slope's standard error is 0 on an exact power law and grows with scatter; a departure
    /// needs both 0.1 and two standard errors.
    #[test]
    fn exponent_gives_a_standard_error_and_departures() {
        let exact: Vec<(f64, f64)> = [1e3, 1e4, 1e5].iter().map(|&x: &f64| (x, 2.0 * x)).collect();
        let (k, se) = exponent(&exact).unwrap();
        assert!((k - 1.0).abs() < 1e-9 && se.unwrap() < 1e-9);
        assert!(exponent(&exact[..2]).unwrap().1.is_none(), "two points fit exactly: no error");
        let scattered = [(1e3, 1.0), (1e4, 20.0), (1e5, 60.0), (1e6, 1500.0)];
        let (k, se) = exponent(&scattered).unwrap();
        assert!(se.unwrap() > 0.05, "{k} {se:?}");
        assert!(!departs(1.05, Some(0.01), (1.0, 1.0)), "within 0.1");
        assert!(departs(0.8, Some(0.05), (1.0, 1.0)) && !departs(0.8, Some(0.2), (1.0, 1.0)));
        assert!(departs(0.8, None, (1.0, 1.0)));
        // A logarithmic law over 1k… fits an exponent up to 1/ln 1000 = 0.145: 0.2 is within 0.1.
        let log = Law::Log.range(1000.0);
        assert!((log.1 - 1.0 / 1000f64.ln()).abs() < 1e-12 && log.0 == 0.0);
        assert!(!departs(0.2, Some(0.01), log) && departs(0.3, Some(0.01), log));
        // c ln x over 1k … 1M fits inside the range.
        let pts: Vec<(f64, f64)> = [1e3, 1e4, 1e5, 1e6].iter().map(|&x: &f64| (x, 5.0 * x.ln())).collect();
        let k = exponent(&pts).unwrap().0;
        assert!(k > log.0 && k < log.1, "{k} in {log:?}");
        assert!(exponent(&[(1.0, f64::INFINITY), (2.0, 1.0)]).is_none(), "a non-finite point is left out");
    }

    #[test]
    fn exponent_recovers_a_power_law() {
        let pts: Vec<(f64, f64)> = [1e3, 1e4, 1e5, 1e6].iter().map(|&x: &f64| (x, 3.0 * x.powf(0.75))).collect();
        assert!((exponent(&pts).unwrap().0 - 0.75).abs() < 1e-9);
        assert!(exponent(&pts[..1]).is_none());
        let flat = [(10.0, 5.0), (1000.0, 5.0)];
        assert!(exponent(&flat).unwrap().0.abs() < 1e-12);
    }
}
