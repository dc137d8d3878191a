//! Benchmark reports without a GPU: CSV in and out, Markdown tables and SVG plots of the
//! error-vs-frames / error-vs-time curves that the benchmark records.
//!
//! - [`CurvePoint`]s (one checkpoint of one accumulation run) go to and from CSV with
//!   [`write_curves_csv`] / [`read_curves_csv`], so plots and tables can be redone without
//!   rendering again.
//! - [`error_table_markdown`] gives the thesis' Table 2 shape (error at t frames, % change against
//!   uniform sampling at the same t); [`equal_time_table_markdown`] gives the error reached within
//!   wall-time budgets, the view a user decides on.
//! - [`frame_time_table_markdown`] gives the Table 1 shape (per-frame cost per scene and mode) and a
//!   per-pass breakdown per scene.
//! - [`plot_error_vs_frames`] / [`plot_error_vs_time`] write log-log SVG plots, which GitHub
//!   Markdown shows with `![](plots/x.svg)`. Text goes out as SVG `<text>` (no fonts needed here).
//!
//! Modes keep the same colour in every plot: uniform blue, RIS green, ReSTIR red (as in the
//! thesis), other modes other colours (see [`mode_color`]).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{anyhow, bail, Context as _, Result};
use serde::{Deserialize, Serialize};

/// One checkpoint of one accumulation run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurvePoint {
    /// Short scene label, e.g. "cornell_box".
    pub scene: String,
    /// Sampling mode label, e.g. "uniform", "ris", "restir", "restir-unbiased".
    pub mode: String,
    /// "pt" (path-traced ground truth: total error including the VPL bias) or "vpl" (converged VPL
    /// answer: sampling error only).
    pub reference: String,
    /// Accumulated frames t.
    pub frames: u32,
    /// Cumulative GPU time of those frames (sum of pass timestamps).
    pub gpu_ms: f64,
    /// Cumulative wall time of those frames (excludes checkpoint readback).
    pub wall_ms: f64,
    pub rmse: f64,
    pub relmse: f64,
    /// mean(image) / mean(reference): the estimator's bias shows here once the noise averages out.
    pub mean_ratio: f64,
    /// Standard error of `mean_ratio` over independent runs (None from a single run).
    pub mean_ratio_se: Option<f64>,
    /// Share of the squared error in the worst 0.1% of pixels (fireflies when near 1).
    pub worst_share: f64,
    pub flip: Option<f64>,
}

/// Per-frame cost of one mode on one scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameTimeRow {
    pub scene: String,
    pub mode: String,
    pub width: u32,
    pub height: u32,
    /// Median GPU ms per frame.
    pub gpu_ms: f64,
    /// Median wall ms per frame.
    pub wall_ms: f64,
    /// Mean rays per pixel per frame, all passes.
    pub rays_per_pixel: f64,
    /// Median GPU ms per pass.
    pub pass_ms: BTreeMap<String, f64>,
}

/// Which error a table or plot shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Metric {
    Rmse,
    RelMse,
    Flip,
}

impl Metric {
    pub const ALL: [Metric; 3] = [Metric::Rmse, Metric::RelMse, Metric::Flip];

    /// Display name: "RMSE", "relMSE", "FLIP".
    pub fn label(self) -> &'static str {
        match self {
            Metric::Rmse => "RMSE",
            Metric::RelMse => "relMSE",
            Metric::Flip => "FLIP",
        }
    }

    /// File-name friendly name: "rmse", "relmse", "flip" (also what [`str::parse`] accepts).
    pub fn key(self) -> &'static str {
        match self {
            Metric::Rmse => "rmse",
            Metric::RelMse => "relmse",
            Metric::Flip => "flip",
        }
    }

    /// This metric's value in `p` (`None` for FLIP when it was not computed).
    pub fn of(self, p: &CurvePoint) -> Option<f64> {
        match self {
            Metric::Rmse => Some(p.rmse),
            Metric::RelMse => Some(p.relmse),
            Metric::Flip => p.flip,
        }
    }
}

impl std::fmt::Display for Metric {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.label())
    }
}

impl std::str::FromStr for Metric {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "rmse" => Ok(Metric::Rmse),
            "relmse" | "rel-mse" | "rel_mse" => Ok(Metric::RelMse),
            "flip" => Ok(Metric::Flip),
            _ => bail!("unknown metric {s:?} (expected rmse, relmse or flip)"),
        }
    }
}

/// "pt" → "path-traced reference", "vpl" → "converged VPL reference", anything else → itself.
pub fn reference_label(reference: &str) -> String {
    match reference {
        "pt" => "path-traced reference".into(),
        "vpl" => "converged VPL reference".into(),
        other => format!("reference \"{other}\""),
    }
}

/// Display name of a mode label: the tokens "uniform", "ris", "restir" become "Uniform", "RIS",
/// "ReSTIR", so "restir-unbiased" → "ReSTIR-unbiased"; other tokens stay as they are.
pub fn mode_display_name(mode: &str) -> String {
    mode.split('-')
        .map(|t| match t {
            "uniform" => "Uniform",
            "ris" => "RIS",
            "restir" => "ReSTIR",
            other => other,
        })
        .collect::<Vec<_>>()
        .join("-")
}

/// Formats `v` with 3 significant digits, keeping trailing zeros ("0.410", "12.3", "1234");
/// scientific below 1e-3 and from 1e5 on ("1.00e-4").
pub fn fmt_sig3(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let e = v.abs().log10().floor() as i32;
    if !(-3..5).contains(&e) {
        return format!("{v:.2e}");
    }
    let mut decimals = (2 - e).max(0) as usize;
    let mut s = format!("{v:.decimals$}");
    // Rounding up to the next power of ten (0.9996 → "1.000") would give a 4th digit; at the top
    // of the range (99999.6 → "100000") a sixth, where the exponent form takes over.
    if s.trim_start_matches('-').parse::<f64>().unwrap_or(0.0) >= 10f64.powi(e + 1) {
        if decimals == 0 {
            return if e + 1 >= 5 { format!("{v:.2e}") } else { s };
        }
        decimals -= 1;
        s = format!("{v:.decimals$}");
    }
    s
}

/// [`fmt_sig3`] without trailing zeros ("0.4", "20", "1e-4"); for axis ticks and budgets.
fn fmt_short(v: f64) -> String {
    let s = fmt_sig3(v);
    let trim = |m: &str| -> String {
        if m.contains('.') {
            m.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            m.to_string()
        }
    };
    match s.split_once('e') {
        Some((m, e)) => format!("{}e{}", trim(m), e),
        None => trim(&s),
    }
}

/// " (-39.0%)": the change of `v` against `base`, or "" where `base` is unusable.
fn pct_suffix(v: f64, base: Option<f64>) -> String {
    match base {
        Some(b) if b != 0.0 && b.is_finite() && v.is_finite() => format!(" ({:+.1}%)", (v / b - 1.0) * 100.0),
        _ => String::new(),
    }
}

const UNIFORM: &str = "uniform";
const DASH: &str = "—";

/// One quantity over independent runs (or any sample): how `results`, `bench --motion` and
/// `bench --radius` combine the runs' errors and biases.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OverRuns {
    n: usize,
    sum: f64,
    sum_sq: f64,
}

impl OverRuns {
    pub fn add(&mut self, x: f64) {
        self.n += 1;
        self.sum += x;
        self.sum_sq += x * x;
    }

    /// How many values were added.
    pub fn count(&self) -> usize {
        self.n
    }

    /// The mean of the values (0 for none).
    pub fn mean(&self) -> f64 {
        if self.n == 0 { 0.0 } else { self.sum / self.n as f64 }
    }

    /// The root of the mean square: for per-run RMSEs, the RMSE over all runs (their mean MSE's
    /// root; the mean of the RMSEs would be biased low). 0 for none.
    pub fn rms(&self) -> f64 {
        if self.n == 0 { 0.0 } else { (self.sum_sq / self.n as f64).sqrt() }
    }

    /// The standard error of [`OverRuns::mean`]: the sample variance (over n − 1) divided by n,
    /// rooted; None for fewer than two values.
    pub fn standard_error(&self) -> Option<f64> {
        (self.n > 1).then(|| {
            let n = self.n as f64;
            // NaN stays NaN (an infinite value among them): f64::max(NaN, 0) is 0, which printed
            // "inf ± 0.0000".
            let spread = self.sum_sq - self.sum * self.sum / n;
            if spread.is_nan() { f64::NAN } else { (spread.max(0.0) / (n - 1.0) / n).sqrt() }
        })
    }
}

// ---------------------------------------------------------------------------------------------
// CSV

const CSV_HEADER: [&str; 12] = [
    "scene", "mode", "reference", "frames", "gpu_ms", "wall_ms", "rmse", "relmse", "mean_ratio", "worst_share", "flip",
    "mean_ratio_se",
];
/// The header before `mean_ratio_se` (stop 38); such files still read, without standard errors.
const CSV_HEADER_V1: usize = 11;

fn csv_field<'a>(path: &Path, what: &str, s: &'a str) -> Result<&'a str> {
    if s.contains([',', '"', '\n', '\r']) {
        bail!("{}: cannot write {what} {s:?} to CSV: it contains a comma, quote or line break", path.display());
    }
    Ok(s)
}

/// Writes `points` as CSV: a header row (`scene,mode,reference,frames,gpu_ms,wall_ms,rmse,relmse,mean_ratio,worst_share,flip,mean_ratio_se`)
/// and one row per point; FLIP and the standard error are empty when `None`. Numbers are written so that they read back
/// exactly. Text fields must not contain commas, quotes or line breaks (an error otherwise).
/// Creates the parent directory.
pub fn write_curves_csv(path: impl AsRef<Path>, points: &[CurvePoint]) -> Result<()> {
    let path = path.as_ref();
    let mut s = CSV_HEADER.join(",");
    s.push('\n');
    for p in points {
        let flip = p.flip.map(|f| f.to_string()).unwrap_or_default();
        let se = p.mean_ratio_se.map(|f| f.to_string()).unwrap_or_default();
        writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{}",
            csv_field(path, "scene", &p.scene)?,
            csv_field(path, "mode", &p.mode)?,
            csv_field(path, "reference", &p.reference)?,
            p.frames,
            p.gpu_ms,
            p.wall_ms,
            p.rmse,
            p.relmse,
            p.mean_ratio,
            p.worst_share,
            flip,
            se
        )
        .unwrap();
    }
    create_parent(path)?;
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// Reads a file written by [`write_curves_csv`] (or before `mean_ratio_se` was added). Blank lines
/// are skipped; the header must match.
pub fn read_curves_csv(path: impl AsRef<Path>) -> Result<Vec<CurvePoint>> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim_end_matches('\r'))).filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        bail!("{}: empty CSV file (expected the header {})", path.display(), CSV_HEADER.join(","));
    };
    let got: Vec<&str> = header.split(',').map(str::trim).collect();
    if got != CSV_HEADER && got != CSV_HEADER[..CSV_HEADER_V1] {
        bail!("{}: unexpected CSV header {header:?} (expected {})", path.display(), CSV_HEADER.join(","));
    }
    let fields = got.len();
    let mut out = Vec::new();
    for (n, line) in lines {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != fields {
            bail!("{}:{n}: expected {fields} fields, found {}", path.display(), f.len());
        }
        let num = |i: usize| -> Result<f64> {
            f[i].parse::<f64>()
                .map_err(|e| anyhow!("{}:{n}: field {} = {:?}: {e}", path.display(), CSV_HEADER[i], f[i]))
        };
        out.push(CurvePoint {
            scene: f[0].to_string(),
            mode: f[1].to_string(),
            reference: f[2].to_string(),
            frames: f[3]
                .parse()
                .map_err(|e| anyhow!("{}:{n}: field frames = {:?}: {e}", path.display(), f[3]))?,
            gpu_ms: num(4)?,
            wall_ms: num(5)?,
            rmse: num(6)?,
            relmse: num(7)?,
            mean_ratio: num(8)?,
            worst_share: num(9)?,
            flip: if f[10].is_empty() { None } else { Some(num(10)?) },
            mean_ratio_se: if fields <= CSV_HEADER_V1 || f[CSV_HEADER_V1].is_empty() { None } else { Some(num(CSV_HEADER_V1)?) },
        });
    }
    Ok(out)
}

fn create_parent(path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Selection helpers

fn select<'a>(points: &'a [CurvePoint], scene: &str, reference: &str) -> Vec<&'a CurvePoint> {
    points.iter().filter(|p| p.scene == scene && p.reference == reference).collect()
}

/// Distinct values in first-appearance order (scenes, modes, passes as the tables list them).
pub fn ordered<T: PartialEq>(items: impl IntoIterator<Item = T>) -> Vec<T> {
    let mut out: Vec<T> = Vec::new();
    for s in items {
        if !out.contains(&s) {
            out.push(s);
        }
    }
    out
}

fn no_data(scene: &str, reference: &str) -> String {
    format!("_No data for scene `{scene}` against the {}._\n", reference_label(reference))
}

fn table_header(out: &mut String, first: &str, cols: &[String]) {
    writeln!(out, "| {first} | {} |", cols.join(" | ")).unwrap();
    writeln!(out, "|---|{}", "---:|".repeat(cols.len())).unwrap();
}

// ---------------------------------------------------------------------------------------------
// Table 2: error at t frames

/// Table 2 of the thesis for one scene and one reference: a caption line, then rows = modes (in
/// first-appearance order), columns = the checkpoints present (`t=1`, `t=2`, ...), cells = the
/// metric with 3 significant digits and, except in the uniform row, the change relative to the
/// "uniform" row at the same t, e.g. `0.250 (-39.0%)` (no % at all when there is no uniform row or
/// it lacks that t). Missing values are "—". If several points share mode and t, the first counts.
/// With no matching points the result is a one-line "no data" note.
pub fn error_table_markdown(points: &[CurvePoint], scene: &str, reference: &str, metric: Metric) -> String {
    let sel = select(points, scene, reference);
    if sel.is_empty() {
        return no_data(scene, reference);
    }
    let modes = ordered(sel.iter().map(|p| p.mode.clone()));
    let mut ts: Vec<u32> = sel.iter().map(|p| p.frames).collect();
    ts.sort_unstable();
    ts.dedup();
    let value = |mode: &str, t: u32| sel.iter().find(|p| p.mode == mode && p.frames == t).and_then(|p| metric.of(p));

    let mut out = String::new();
    writeln!(
        out,
        "**{scene}**: {} against the {} after t accumulated frames (% change relative to Uniform at the same t)\n",
        metric.label(),
        reference_label(reference)
    )
    .unwrap();
    let cols: Vec<String> = ts.iter().map(|t| format!("t={t}")).collect();
    table_header(&mut out, "Sampling technique", &cols);
    for mode in &modes {
        let cells: Vec<String> = ts
            .iter()
            .map(|&t| match value(mode, t) {
                None => DASH.to_string(),
                Some(v) => {
                    let base = if mode == UNIFORM { None } else { value(UNIFORM, t) };
                    format!("{}{}", fmt_sig3(v), pct_suffix(v, base))
                }
            })
            .collect();
        writeln!(out, "| {} | {} |", mode_display_name(mode), cells.join(" | ")).unwrap();
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Equal time

/// The error one mode reaches within a wall-time budget; see [`error_within_budget`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BudgetValue {
    pub value: f64,
    /// The run's last checkpoint came before the budget ran out: `value` is the error at the end
    /// of the run (not extrapolated), so the budget would reach at least this.
    pub run_ended: bool,
}

/// The `metric` that `mode` reaches on `scene` against `reference` within `budget_ms` of wall time.
///
/// Between two checkpoints the error is interpolated log-log in (wall_ms, error), i.e. along a
/// power law such as error ∝ t^-½, which is what progressive accumulation follows (linear
/// interpolation where a value or time is not positive). Past the last checkpoint the last value is
/// taken as is and flagged [`BudgetValue::run_ended`]. `None` when the mode's first checkpoint
/// took longer than the budget, or the mode has no value of this metric.
pub fn error_within_budget(
    points: &[CurvePoint],
    scene: &str,
    reference: &str,
    mode: &str,
    metric: Metric,
    budget_ms: f64,
) -> Option<BudgetValue> {
    let mut c: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.scene == scene && p.reference == reference && p.mode == mode)
        .filter_map(|p| metric.of(p).map(|v| (p.wall_ms, v)))
        .filter(|(w, v)| w.is_finite() && !v.is_nan())
        .collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    let i = c.iter().rposition(|&(w, _)| w <= budget_ms)?;
    if i + 1 == c.len() {
        return Some(BudgetValue { value: c[i].1, run_ended: budget_ms > c[i].0 });
    }
    let ((w0, e0), (w1, e1)) = (c[i], c[i + 1]);
    let value = if w1 <= w0 {
        e1
    } else if w0 > 0.0 && e0 > 0.0 && e1 > 0.0 {
        let f = (budget_ms.ln() - w0.ln()) / (w1.ln() - w0.ln());
        (e0.ln() + (e1.ln() - e0.ln()) * f).exp()
    } else {
        e0 + (e1 - e0) * (budget_ms - w0) / (w1 - w0)
    };
    Some(BudgetValue { value, run_ended: false })
}

/// Equal-time table for one scene and one reference: rows = modes (first-appearance order),
/// columns = the wall-time budgets, cells = the error reached within each budget as computed by
/// [`error_within_budget`] (log-log interpolation between checkpoints of wall_ms; "—" where the
/// mode's first checkpoint did not fit in the budget; a trailing "*" where the run ended before the
/// budget and the value is that of the last checkpoint, with a footnote), with the % change
/// relative to Uniform within the same budget.
pub fn equal_time_table_markdown(
    points: &[CurvePoint],
    scene: &str,
    reference: &str,
    metric: Metric,
    budgets_ms: &[f64],
) -> String {
    let sel = select(points, scene, reference);
    if sel.is_empty() {
        return no_data(scene, reference);
    }
    if budgets_ms.is_empty() {
        return format!("_No time budgets given for scene `{scene}`._\n");
    }
    let modes = ordered(sel.iter().map(|p| p.mode.clone()));
    let mut out = String::new();
    writeln!(
        out,
        "**{scene}**: {} against the {} reached within a wall-time budget (equal time; log-log \
         interpolation between checkpoints; % change relative to Uniform within the same budget)\n",
        metric.label(),
        reference_label(reference)
    )
    .unwrap();
    let cols: Vec<String> = budgets_ms.iter().map(|&b| format!("{} ms", fmt_short(b))).collect();
    table_header(&mut out, "Sampling technique", &cols);
    let mut any_ended = false;
    for mode in &modes {
        let cells: Vec<String> = budgets_ms
            .iter()
            .map(|&b| match error_within_budget(points, scene, reference, mode, metric, b) {
                None => DASH.to_string(),
                Some(bv) => {
                    any_ended |= bv.run_ended;
                    // No % against a run that ended before the budget, or for one: that would
                    // compare errors at different times.
                    let base = if mode == UNIFORM || bv.run_ended {
                        None
                    } else {
                        error_within_budget(points, scene, reference, UNIFORM, metric, b).filter(|u| !u.run_ended).map(|u| u.value)
                    };
                    let star = if bv.run_ended { "*" } else { "" };
                    format!("{}{star}{}", fmt_sig3(bv.value), pct_suffix(bv.value, base))
                }
            })
            .collect();
        writeln!(out, "| {} | {} |", mode_display_name(mode), cells.join(" | ")).unwrap();
    }
    if any_ended {
        out.push_str("\n\\* the run ended before this budget: error at its last checkpoint.\n");
    }
    out
}

/// Wall-time budgets for [`equal_time_table_markdown`]: the 1-2-5 values from the fastest mode's
/// first checkpoint to the time every mode reached (the earliest last checkpoint) on `scene`
/// against `reference`, thinned to at most 6: past it some mode's run has ended and the table
/// would compare errors at different times. Empty without data.
pub fn suggest_budgets_ms(points: &[CurvePoint], scene: &str, reference: &str) -> Vec<f64> {
    let sel = select(points, scene, reference);
    let modes = ordered(sel.iter().map(|p| p.mode.clone()));
    let mut lo = f64::INFINITY;
    let mut hi = f64::INFINITY;
    for m in &modes {
        let ws = sel.iter().filter(|p| &p.mode == m).map(|p| p.wall_ms).filter(|w| w.is_finite() && *w > 0.0);
        let (mn, mx) = ws.fold((f64::INFINITY, 0.0f64), |(a, b), w| (a.min(w), b.max(w)));
        lo = lo.min(mn);
        hi = hi.min(mx);
    }
    if !(lo.is_finite() && hi >= lo) {
        return Vec::new();
    }
    let mut v: Vec<f64> = nice_values(lo, hi, &[1.0, 2.0, 5.0]);
    if v.is_empty() {
        v.push(hi);
    }
    while v.len() > 6 {
        v = v.iter().copied().enumerate().filter(|(i, _)| i % 2 == (v.len() - 1) % 2).map(|(_, x)| x).collect();
    }
    v
}

/// Values m·10^k (m in `mults`) within [lo, hi], ascending.
fn nice_values(lo: f64, hi: f64, mults: &[f64]) -> Vec<f64> {
    if !(lo > 0.0 && hi >= lo && hi.is_finite()) {
        return Vec::new();
    }
    let mut out = Vec::new();
    for k in (lo.log10().floor() as i32 - 1)..=(hi.log10().ceil() as i32) {
        for m in mults {
            // Parsed from text so that e.g. 0.3 is exactly the literal, not 3 * 0.1.
            let v: f64 = format!("{m}e{k}").parse().unwrap();
            if v >= lo * (1.0 - 1e-12) && v <= hi * (1.0 + 1e-12) {
                out.push(v);
            }
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Table 1: frame times

/// Table 1 of the thesis plus rays: rows = scenes (with resolution; first-appearance order),
/// for each mode (first-appearance order) a column "GPU ms" (median per frame, with "×1.23"
/// relative to uniform on the same scene) and a column "rays/px" (per frame). Then, per scene, a
/// compact table of the median GPU ms per pass (rows = passes, columns = modes) with the median
/// GPU and wall ms per frame at the bottom. Empty input gives a "no data" note.
pub fn frame_time_table_markdown(rows: &[FrameTimeRow]) -> String {
    if rows.is_empty() {
        return "_No frame-time data._\n".into();
    }
    let modes = ordered(rows.iter().map(|r| r.mode.clone()));
    let scenes = ordered(rows.iter().map(|r| (r.scene.clone(), r.width, r.height)));
    let find = |s: &(String, u32, u32), mode: &str| {
        rows.iter().find(|r| r.scene == s.0 && r.width == s.1 && r.height == s.2 && r.mode == mode)
    };

    let mut out = String::new();
    out.push_str("Median GPU time per frame (ms; × relative to Uniform) and rays per pixel per frame (all passes)\n\n");
    let mut cols = vec!["Resolution".to_string()];
    for m in &modes {
        let name = mode_display_name(m);
        cols.push(format!("{name} GPU ms"));
        cols.push(format!("{name} rays/px"));
    }
    writeln!(out, "| Scene | {} |", cols.join(" | ")).unwrap();
    writeln!(out, "|---|---|{}", "---:|".repeat(cols.len() - 1)).unwrap();
    for s in &scenes {
        let base = find(s, UNIFORM).map(|r| r.gpu_ms).filter(|b| *b > 0.0 && b.is_finite());
        let mut cells = vec![format!("{}×{}", s.1, s.2)];
        for m in &modes {
            match find(s, m) {
                None => cells.extend([DASH.to_string(), DASH.to_string()]),
                Some(r) => {
                    let ratio = match base {
                        Some(b) if m != UNIFORM && r.gpu_ms.is_finite() => format!(" (×{:.2})", r.gpu_ms / b),
                        _ => String::new(),
                    };
                    cells.push(format!("{}{ratio}", fmt_sig3(r.gpu_ms)));
                    cells.push(fmt_sig3(r.rays_per_pixel));
                }
            }
        }
        writeln!(out, "| {} | {} |", s.0, cells.join(" | ")).unwrap();
    }

    for s in &scenes {
        let present: Vec<&FrameTimeRow> = modes.iter().filter_map(|m| find(s, m)).collect();
        writeln!(out, "\n**{}** ({}×{}): median GPU ms per pass\n", s.0, s.1, s.2).unwrap();
        let cols: Vec<String> = present.iter().map(|r| mode_display_name(&r.mode)).collect();
        table_header(&mut out, "Pass", &cols);
        let mut passes = ordered(present.iter().flat_map(|r| r.pass_ms.keys().cloned()));
        passes.sort();
        for pass in &passes {
            let cells: Vec<String> =
                present.iter().map(|r| r.pass_ms.get(pass).map(|&v| fmt_sig3(v)).unwrap_or_else(|| DASH.into())).collect();
            writeln!(out, "| {pass} | {} |", cells.join(" | ")).unwrap();
        }
        let gpu: Vec<String> = present.iter().map(|r| format!("**{}**", fmt_sig3(r.gpu_ms))).collect();
        writeln!(out, "| **frame, GPU** | {} |", gpu.join(" | ")).unwrap();
        let wall: Vec<String> = present.iter().map(|r| fmt_sig3(r.wall_ms)).collect();
        writeln!(out, "| frame, wall | {} |", wall.join(" | ")).unwrap();
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Plots

/// Colour of a mode in every plot, as RGB: uniform blue, ris green, restir red (thesis colours),
/// restir-unbiased purple; any other label gets a colour from a fixed palette chosen by a hash of
/// the label (so it is the same in every plot; two such labels may share one).
pub fn mode_color(mode: &str) -> (u8, u8, u8) {
    match mode {
        "uniform" => PALETTE[0],
        "ris" => PALETTE[1],
        "restir" => PALETTE[2],
        "restir-unbiased" => PALETTE[3],
        other => {
            // FNV-1a: stable across runs and platforms.
            let h = other.bytes().fold(0xcbf29ce484222325u64, |h, b| (h ^ b as u64).wrapping_mul(0x100000001b3));
            PALETTE[4 + (h % (PALETTE.len() as u64 - 4)) as usize]
        }
    }
}

/// The colours of one plot's series: a mode's own colour ([`mode_color`]) where no earlier series
/// of the plot has it, else the first palette colour not yet used in the plot (hashed colours of
/// other keys can collide; within one plot they must not).
fn series_colors(series: &[(String, Vec<(f64, f64)>)]) -> Vec<(u8, u8, u8)> {
    let mut used: Vec<(u8, u8, u8)> = Vec::new();
    for (key, _) in series {
        let own = mode_color(key);
        let c = if used.contains(&own) { PALETTE.iter().copied().find(|c| !used.contains(c)).unwrap_or(own) } else { own };
        used.push(c);
    }
    used
}

const PALETTE: [(u8, u8, u8); 10] = [
    (31, 119, 180),  // blue
    (44, 160, 44),   // green
    (214, 39, 40),   // red
    (148, 103, 189), // purple
    (255, 127, 14),  // orange
    (140, 86, 75),   // brown
    (227, 119, 194), // pink
    (127, 127, 127), // grey
    (188, 189, 34),  // olive
    (23, 190, 207),  // cyan
];

/// Marker shape per mode (helps in grey scale): 0 circle, 1 triangle, 2 square, 3 cross.
fn mode_marker(mode: &str) -> u8 {
    match mode {
        "uniform" => 0,
        "ris" => 1,
        "restir" => 2,
        "restir-unbiased" => 3,
        other => (other.len() % 4) as u8,
    }
}

#[derive(Clone, Copy)]
enum XAxis {
    Frames,
    WallMs,
    /// Displayed frames of a moving camera (path frame + 1), not accumulated.
    Displayed,
}

/// Log-log SVG plot of `metric` against accumulated frames for one scene and one reference: one
/// line with markers per mode (first-appearance order), a legend beside the plot, axis labels and a
/// title naming scene and reference. Points whose value is not positive and finite (and, for FLIP,
/// points without a value) cannot sit on a log axis and are skipped. An error (naming `path`) when
/// nothing is left to plot. Creates the parent directory.
pub fn plot_error_vs_frames(
    path: impl AsRef<Path>,
    points: &[CurvePoint],
    scene: &str,
    reference: &str,
    metric: Metric,
) -> Result<()> {
    plot(path.as_ref(), points, scene, reference, metric, XAxis::Frames)
}

/// As [`plot_error_vs_frames`], against cumulative wall time (ms) instead of frames; points with a
/// non-positive wall time are skipped too.
pub fn plot_error_vs_time(
    path: impl AsRef<Path>,
    points: &[CurvePoint],
    scene: &str,
    reference: &str,
    metric: Metric,
) -> Result<()> {
    plot(path.as_ref(), points, scene, reference, metric, XAxis::WallMs)
}

/// As [`plot_error_vs_frames`] for a moving camera: each point's `frames` is the displayed frame
/// (path frame + 1) and its error is that frame's alone.
pub fn plot_error_vs_displayed_frame(path: impl AsRef<Path>, points: &[CurvePoint], scene: &str, reference: &str, metric: Metric) -> Result<()> {
    plot(path.as_ref(), points, scene, reference, metric, XAxis::Displayed)
}

/// Bold (labelled) and light tick values for a log axis over [lo, hi]: 1-2-5 steps when that gives
/// 3..=10 labels, decades when it gives more, 1..9 steps when it gives fewer.
fn log_ticks(lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>) {
    let all = nice_values(lo, hi, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    let b125 = nice_values(lo, hi, &[1.0, 2.0, 5.0]);
    let bold = if (3..=10).contains(&b125.len()) {
        b125
    } else if b125.len() > 10 {
        let mut d = nice_values(lo, hi, &[1.0]);
        let step = d.len().div_ceil(10);
        if step > 1 {
            d = d.into_iter().step_by(step).collect();
        }
        d
    } else {
        all.clone()
    };
    let light = if all.len() <= 200 { all.into_iter().filter(|v| !bold.contains(v)).collect() } else { Vec::new() };
    (bold, light)
}

/// A log range around [lo, hi] with some margin, at least a factor `min_ratio` wide.
fn padded(lo: f64, hi: f64, pad: f64, min_ratio: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (lo / pad, hi * pad);
    if hi / lo < min_ratio {
        let mid = (lo * hi).sqrt();
        let half = min_ratio.sqrt();
        lo = mid / half;
        hi = mid * half;
    }
    (lo, hi)
}

fn plot(path: &Path, points: &[CurvePoint], scene: &str, reference: &str, metric: Metric, x: XAxis) -> Result<()> {
    let sel = select(points, scene, reference);
    let modes = ordered(sel.iter().map(|p| p.mode.clone()));
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for m in &modes {
        let mut pts: Vec<(f64, f64)> = sel
            .iter()
            .filter(|p| &p.mode == m)
            .filter_map(|p| {
                let xv = match x {
                    XAxis::Frames | XAxis::Displayed => p.frames as f64,
                    XAxis::WallMs => p.wall_ms,
                };
                metric.of(p).map(|y| (xv, y))
            })
            .filter(|&(a, b)| a > 0.0 && a.is_finite() && b > 0.0 && b.is_finite())
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        if !pts.is_empty() {
            series.push((m.clone(), pts));
        }
    }
    if series.is_empty() {
        bail!(
            "{}: nothing to plot: no point of scene {scene:?} against reference {reference:?} has a positive {}{}",
            path.display(),
            metric.label(),
            if matches!(x, XAxis::WallMs) { " and a positive wall time" } else { "" }
        );
    }
    let (x_desc, x_name) = match x {
        XAxis::Frames => ("accumulated frames", "accumulated frames"),
        XAxis::WallMs => ("cumulative wall time (ms)", "wall time"),
        XAxis::Displayed => ("displayed frame of the moving camera (each frame alone)", "displayed frame"),
    };
    let axes = LogLogAxes {
        title: format!("{scene}: {} vs {x_name} ({})", metric.label(), reference_label(reference)),
        x_desc: x_desc.into(),
        y_desc: format!("{} vs {}", metric.label(), reference_label(reference)),
        legend: "Sampling".into(),
    };
    write_loglog_svg(path, &series, &axes)
}

/// Titles of a log-log plot.
pub struct LogLogAxes {
    pub title: String,
    pub x_desc: String,
    pub y_desc: String,
    /// Heading of the legend beside the plot.
    pub legend: String,
}

/// Writes a log-log line plot of `series` (key, points with positive coordinates) as SVG. A key
/// that names a mode ("ris", "restir-unbiased") gets that mode's colour, marker and display name
/// in every plot of the project; other keys are shown as given.
pub fn write_loglog_svg(path: &Path, series: &[(String, Vec<(f64, f64)>)], axes: &LogLogAxes) -> Result<()> {
    let svg = render_svg(series, axes).map_err(|e| anyhow!("{}: drawing the plot: {e}", path.display()))?;
    create_parent(path)?;
    std::fs::write(path, svg).with_context(|| format!("writing {}", path.display()))
}

fn render_svg(series: &[(String, Vec<(f64, f64)>)], axes: &LogLogAxes) -> std::result::Result<String, Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    use plotters::style::text_anchor::{HPos, Pos, VPos};

    let all = || series.iter().flat_map(|(_, p)| p.iter());
    let (x_lo, x_hi) = all().fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (y_lo, y_hi) = all().fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let (x_lo, x_hi) = padded(x_lo, x_hi, 1.25, 3.0);
    let (y_lo, y_hi) = padded(y_lo, y_hi, 1.15, 3.0);
    let (xb, xl) = log_ticks(x_lo, x_hi);
    let (yb, yl) = log_ticks(y_lo, y_hi);
    let (title, x_desc, y_desc) = (axes.title.as_str(), axes.x_desc.as_str(), axes.y_desc.as_str());
    let labels: Vec<String> = series.iter().map(|(m, _)| mode_display_name(m)).collect();
    let colors = series_colors(series);
    let legend_w = (labels.iter().map(|l| l.chars().count()).max().unwrap_or(0) as u32 * 9 + 70).clamp(130, 280);

    let (w, h) = (760 + legend_w, 520u32);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let body = root.titled(title, ("sans-serif", 24))?;
        let (plot_area, legend_area) = body.split_horizontally(w - legend_w);

        let mut chart = ChartBuilder::on(&plot_area)
            .margin(12)
            .x_label_area_size(52)
            .y_label_area_size(80)
            .build_cartesian_2d(
                (x_lo..x_hi).log_scale().with_key_points(xb).with_light_points(xl),
                (y_lo..y_hi).log_scale().with_key_points(yb).with_light_points(yl),
            )?;
        let fmt = |v: &f64| fmt_short(*v);
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&fmt)
            .y_label_formatter(&fmt)
            .label_style(("sans-serif", 17))
            .axis_desc_style(("sans-serif", 18))
            .bold_line_style(RGBColor(200, 200, 200))
            .light_line_style(RGBColor(238, 238, 238))
            .draw()?;

        for ((mode, pts), &(r, g, b)) in series.iter().zip(&colors) {
            let c = RGBColor(r, g, b);
            chart.draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))?;
            let filled = c.filled();
            match mode_marker(mode) {
                0 => {
                    chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, filled)))?;
                }
                1 => {
                    chart.draw_series(pts.iter().map(|&p| TriangleMarker::new(p, 5, filled)))?;
                }
                2 => {
                    chart.draw_series(pts.iter().map(|&p| EmptyElement::at(p) + Rectangle::new([(-4, -4), (4, 4)], filled)))?;
                }
                _ => {
                    chart.draw_series(pts.iter().map(|&p| Cross::new(p, 4, c.stroke_width(2))))?;
                }
            }
        }

        // Legend beside the plot, so that it never covers data.
        legend_area.draw(&Text::new(
            axes.legend.as_str(),
            (12, 24),
            TextStyle::from(("sans-serif", 18).into_font()).pos(Pos::new(HPos::Left, VPos::Center)),
        ))?;
        for (i, (((mode, _), label), &(r, g, b))) in series.iter().zip(&labels).zip(&colors).enumerate() {
            let y = 52 + 26 * i as i32;
            let c = RGBColor(r, g, b);
            legend_area.draw(&PathElement::new(vec![(12, y), (44, y)], c.stroke_width(2)))?;
            let filled = c.filled();
            match mode_marker(mode) {
                0 => legend_area.draw(&Circle::new((28, y), 4, filled))?,
                1 => legend_area.draw(&TriangleMarker::new((28, y), 5, filled))?,
                2 => legend_area.draw(&Rectangle::new([(24, y - 4), (32, y + 4)], filled))?,
                _ => legend_area.draw(&Cross::new((28, y), 4, c.stroke_width(2)))?,
            }
            legend_area.draw(&Text::new(
                label.clone(),
                (52, y),
                TextStyle::from(("sans-serif", 18).into_font()).pos(Pos::new(HPos::Left, VPos::Center)),
            ))?;
        }
        root.present()?;
    }
    Ok(svg)
}

/// The machine the measurements ran on, in words (CPU model, threads, memory, OS).
pub fn host_description() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| t.lines().find(|l| l.starts_with("model name")).and_then(|l| l.split(':').nth(1)).map(|m| m.trim().to_string()))
        .unwrap_or_else(|| "unknown CPU".into());
    let threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(0);
    let mem = std::fs::read_to_string("/proc/meminfo").ok().and_then(|t| {
        t.lines()
            .find(|l| l.starts_with("MemTotal:"))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|kb| kb.parse::<f64>().ok())
            .map(|kb| format!(", {:.0} GiB memory", kb / (1024.0 * 1024.0)))
    });
    format!("{cpu}, {threads} hardware threads{}, {}", mem.unwrap_or_default(), std::env::consts::OS)
}

/// Today's date in UTC as YYYY-MM-DD, from the system clock (for a generated report's header).
pub fn utc_date() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (y, m, d) = civil_from_days((secs / 86_400) as i64);
    format!("{y:04}-{m:02}-{d:02}")
}

/// The proleptic Gregorian (year, month, day) of `days` since 1970-01-01 (H. Hinnant's
/// `civil_from_days`).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// mean ratio per scene × mode at each scene's last checkpoint, against both references.
pub fn bias_table_markdown(points: &[CurvePoint], scene_labels: &[String]) -> String {
    let modes = ordered(points.iter().map(|p| p.mode.as_str()));
    let mut s = String::from("| scene | reference |");
    for m in &modes {
        let _ = write!(s, " {} |", mode_display_name(m));
    }
    s.push_str("\n|---|---|");
    s.push_str(&"---:|".repeat(modes.len()));
    s.push('\n');
    for label in scene_labels {
        let label = label.as_str();
        for reference in ["vpl", "pt"] {
            let here: Vec<&CurvePoint> = points.iter().filter(|p| p.scene == label && p.reference == reference).collect();
            let Some(last_t) = here.iter().map(|p| p.frames).max() else { continue };
            let _ = write!(s, "| {label} (t = {last_t}) | {reference} |");
            for m in &modes {
                match here.iter().find(|p| p.mode == *m && p.frames == last_t) {
                    Some(p) => match p.mean_ratio_se {
                        Some(se) => {
                            let _ = write!(s, " {:.4} ± {:.4} |", p.mean_ratio, se);
                        }
                        None => {
                            let _ = write!(s, " {:.4} |", p.mean_ratio);
                        }
                    },
                    None => s.push_str(" — |"),
                }
            }
            s.push('\n');
        }
    }
    s
}

/// The accuracy goals of the default mode (issue 12), checked per scene against the path-traced
/// reference: at frame count `t_bias` the share of squared error in the worst 0.1 % of pixels is at
/// most `max_firefly_share` and |mean ratio − 1| below `max_bias`; and at each t in `equal_time_at`
/// `mode`'s RMSE after t frames is below `rival`'s RMSE within the same wall time (log-log
/// interpolation along the rival's curve; a rival whose run ended before that time is not
/// compared, since its last value overstates its error). Returns the table and one verdict line.
///
/// The runs share one VPL set, whose own error offsets the ratio against the path tracer.
/// `model_ratio` gives, per scene, mean(VPL answer) / mean(pt) over many VPL sets with its
/// standard error; where a scene has one, the bias over VPL sets is estimated as the mode's ratio
/// against its own set's converged answer (the "vpl" reference) times that mean, its standard
/// error from both, and the mark compares that estimate. Otherwise it compares the ratio against
/// the path tracer.
#[allow(clippy::too_many_arguments)]
pub fn goals_markdown(
    points: &[CurvePoint],
    scene_labels: &[String],
    model_ratio: &[(String, f64, f64)],
    mode: &str,
    rival: &str,
    t_bias: u32,
    equal_time_at: &[u32],
    max_firefly_share: f64,
    max_bias: f64,
) -> String {
    let at_ref = |scene: &str, reference: &str, m: &str, t: u32| {
        points.iter().find(|p| p.scene == scene && p.reference == reference && p.mode == m && p.frames == t)
    };
    let at = |scene: &str, m: &str, t: u32| at_ref(scene, "pt", m, t);
    let mark = |ok: bool| if ok { "✓" } else { "✗" };
    let pct = |ratio: f64, se: Option<f64>| {
        format!("{:+.2}{} %", 100.0 * (ratio - 1.0), se.map(|se| format!(" ± {:.2}", 100.0 * se)).unwrap_or_default())
    };
    let mut s = format!(
        "| scene | worst 0.1 % share, t = {t_bias} (≤ {:.0} %) | bias against pt, t = {t_bias} (within ±{:.0} %) |",
        100.0 * max_firefly_share,
        100.0 * max_bias
    );
    for t in equal_time_at {
        let _ = write!(s, " RMSE t = {t}: {} vs {} at equal time |", mode_display_name(mode), mode_display_name(rival));
    }
    s.push_str("\n|---|---:|---:|");
    s.push_str(&"---:|".repeat(equal_time_at.len()));
    s.push('\n');
    let (mut fireflies_ok, mut bias_ok, mut faster_scenes) = (0, 0, 0);
    for label in scene_labels {
        let label = label.as_str();
        let _ = write!(s, "| {label} |");
        match at(label, mode, t_bias) {
            Some(p) => {
                let f = p.worst_share <= max_firefly_share;
                let this_set = pct(p.mean_ratio, p.mean_ratio_se);
                let over_sets = model_ratio.iter().find(|m| m.0 == label).zip(at_ref(label, "vpl", mode, t_bias)).map(|((_, m, sm), v)| {
                    let sv = v.mean_ratio_se.unwrap_or(0.0);
                    (v.mean_ratio * m, (sv * m).hypot(v.mean_ratio * sm))
                });
                let b = ((over_sets.map_or(p.mean_ratio, |o| o.0)) - 1.0).abs() < max_bias;
                fireflies_ok += f as usize;
                bias_ok += b as usize;
                let bias = match over_sets {
                    Some((r, se)) => format!("{} over VPL sets ({this_set} on the runs' set)", pct(r, Some(se))),
                    None => this_set,
                };
                let _ = write!(s, " {:.0} % {} | {bias} {} |", 100.0 * p.worst_share, mark(f), mark(b));
            }
            None => s.push_str(" — | — |"),
        }
        let mut all_below = !equal_time_at.is_empty();
        for &t in equal_time_at {
            let ours = at(label, mode, t);
            let theirs = ours.and_then(|p| error_within_budget(points, label, "pt", rival, Metric::Rmse, p.wall_ms));
            match (ours, theirs) {
                (Some(p), Some(r)) if !r.run_ended => {
                    let below = p.rmse < r.value;
                    all_below &= below;
                    let _ = write!(s, " {} vs {} {} |", fmt_sig3(p.rmse), fmt_sig3(r.value), mark(below));
                }
                (Some(p), Some(_)) => {
                    all_below = false;
                    let _ = write!(s, " {} vs — ({} run ended first) |", fmt_sig3(p.rmse), mode_display_name(rival));
                }
                _ => {
                    all_below = false;
                    s.push_str(" — |");
                }
            }
        }
        faster_scenes += all_below as usize;
        s.push('\n');
    }
    let n = scene_labels.len();
    let _ = write!(
        s,
        "\nFireflies within the goal on {fireflies_ok} of {n} scenes, bias within it on {bias_ok} of {n}; {} below {} at \
         equal time at every t on {faster_scenes} of {n} scenes.\n",
        mode_display_name(mode),
        mode_display_name(rival)
    );
    s
}

/// Final RMSE of each mode at the last checkpoint and the best mode at the common equal-time budget.
pub fn observations(points: &[CurvePoint], scene: &str, reference: &str) -> Vec<String> {
    let mut out = Vec::new();
    let last_t = points.iter().filter(|p| p.scene == scene && p.reference == reference).map(|p| p.frames).max();
    let Some(last_t) = last_t else { return out };
    let at_last: Vec<&CurvePoint> =
        points.iter().filter(|p| p.scene == scene && p.reference == reference && p.frames == last_t).collect();
    if let Some(best) = at_last.iter().min_by(|a, b| a.rmse.total_cmp(&b.rmse)) {
        out.push(format!(
            "At equal frame count (t = {last_t}) the lowest RMSE is {} ({}).",
            mode_display_name(&best.mode),
            fmt_sig3(best.rmse)
        ));
    }
    // Equal time: the budget every mode reached (the smallest final wall time).
    let budget = at_last.iter().map(|p| p.wall_ms).fold(f64::INFINITY, f64::min);
    if budget.is_finite() {
        let mut best: Option<(String, f64)> = None;
        let mut modes: Vec<&str> = at_last.iter().map(|p| p.mode.as_str()).collect();
        modes.dedup();
        for m in modes {
            if let Some(e) = error_within_budget(points, scene, reference, m, Metric::Rmse, budget) {
                let e = e.value;
                if best.as_ref().is_none_or(|b| e < b.1) {
                    best = Some((m.to_string(), e));
                }
            }
        }
        if let Some((m, e)) = best {
            out.push(format!(
                // (The budget to three figures: rounded to whole ms it read as the table's column of
                // that name, whose values are at another budget.)
                "At equal wall time ({} ms, the time the fastest-finishing mode needed for t = {last_t}) the lowest RMSE is {} ({}).",
                fmt_sig3(budget),
                mode_display_name(&m),
                fmt_sig3(e)
            ));
        }
    }
    // Accumulating more frames of an unbiased estimator lowers the expected error; a rise says a few
    // rare, very bright samples (fireflies) dominate the RMSE at these run counts.
    let modes = ordered(points.iter().filter(|p| p.scene == scene && p.reference == reference).map(|p| p.mode.as_str()));
    for m in modes {
        let mut curve: Vec<&CurvePoint> =
            points.iter().filter(|p| p.scene == scene && p.reference == reference && p.mode == m).collect();
        curve.sort_by_key(|p| p.frames);
        let rises: Vec<String> = curve
            .windows(2)
            .filter(|w| w[1].rmse > w[0].rmse * 1.05)
            .map(|w| {
                format!(
                    "t = {} → {}: {} → {}, the worst 0.1% of pixels carrying {:.0}% → {:.0}% of the squared error",
                    w[0].frames,
                    w[1].frames,
                    fmt_sig3(w[0].rmse),
                    fmt_sig3(w[1].rmse),
                    100.0 * w[0].worst_share,
                    100.0 * w[1].worst_share
                )
            })
            .collect();
        if !rises.is_empty() {
            out.push(format!(
                "{}'s RMSE rises with more frames ({}): a few very bright pixels (fireflies) make its RMSE at this \
                 number of runs; FLIP (`curves.csv`) is less sensitive to them (relMSE is more: it divides by the \
                 reference's brightness).",
                mode_display_name(m),
                rises.join("; ")
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::civil_from_days;

    /// Three significant digits: decimals as needed below 1000, whole numbers up to 99999, the
    /// exponent form outside; a value that rounds up to the next power of ten keeps three digits
    /// (99999.6 printed "100000").
    #[test]
    fn three_significant_digits() {
        let cases = [
            (0.00123456, "0.00123"),
            (0.99996, "1.00"),
            (1.2345, "1.23"),
            (999.6, "1000"),
            (12345.0, "12345"),
            (99999.6, "1.00e5"),
            (123456.0, "1.23e5"),
            (0.0001234, "1.23e-4"),
            (-0.99996, "-1.00"),
            (0.0, "0"),
        ];
        for (v, want) in cases {
            assert_eq!(super::fmt_sig3(v), want, "{v}");
        }
    }

    /// Against dates computed elsewhere (Python's datetime): the epoch, the day before it, a leap
    /// day, the day after it, a century that is not a leap year, and a day of this project.
    #[test]
    fn days_since_the_epoch_become_dates() {
        let cases = [(0, (1970, 1, 1)), (-1, (1969, 12, 31)), (11_016, (2000, 2, 29)), (11_017, (2000, 3, 1)), (47_541, (2100, 3, 1)), (20_783, (2026, 11, 26))];
        for (days, date) in cases {
            assert_eq!(civil_from_days(days), date, "day {days}");
        }
    }

    /// The standard error over runs: √(s² / n) with the n − 1 variance; an infinite value makes
    /// it NaN, not 0 (it printed "inf ± 0.0000").
    #[test]
    fn the_standard_error_over_runs() {
        let mut r = super::OverRuns::default();
        for x in [1.0, 2.0, 4.0] {
            r.add(x);
        }
        // Mean 7/3, s² = ((4/3)² + (1/3)² + (5/3)²) / 2 = 7/3.
        assert!((r.standard_error().unwrap() - (7.0f64 / 3.0 / 3.0).sqrt()).abs() < 1e-12);
        let mut inf = super::OverRuns::default();
        inf.add(1.0);
        inf.add(f64::INFINITY);
        assert!(inf.standard_error().unwrap().is_nan());
        let mut one = super::OverRuns::default();
        one.add(1.0);
        assert_eq!(one.standard_error(), None);
    }
}
