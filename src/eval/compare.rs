//! Image comparison: RMSE, relMSE, mean ratio (bias) and LDR-ꟻLIP between a test image and a
//! reference, with a report of non-finite pixels.
//!
//! Everything here is pure CPU code over [`RgbImage`]s, so a benchmark can call [`compare`] in
//! process on images read back from the GPU; the `restir-vpl compare` command is a thin wrapper.
//!
//! Conventions: `a` is the test image, `b` the reference. RMSE, relMSE and the mean ratio are taken
//! over the pixels where both images are finite in all three channels (others are counted and
//! reported in [`NonFinite`]); FLIP sees every pixel, with a non-finite pixel replaced by black.

use std::path::Path;

use anyhow::{bail, Result};
use serde::Serialize;

use crate::output::RgbImage;

/// FLIP's default pixels per degree of visual angle (0.7 m from a 0.7 m wide 4K monitor).
pub const DEFAULT_PPD: f32 = 67.0;

/// Positions of non-finite pixels listed in a [`NonFinite`] report.
pub const MAX_REPORTED_POSITIONS: usize = 10;

/// What to compute.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CompareOptions {
    /// Compute FLIP (the costly metric: about 0.7 s at 1280×720, single-threaded; the rest ~10 ms).
    pub flip: bool,
    /// Exposure in EV of the LDR mapping FLIP sees, as the renderer's PNG (`--exposure`): scale by
    /// 2^EV, clamp to [0, 1], sRGB encode, round to 8 bits.
    pub exposure: f32,
    /// FLIP's pixels per degree of visual angle.
    pub ppd: f32,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self { flip: true, exposure: 0.0, ppd: DEFAULT_PPD }
    }
}

/// Non-finite pixels of one image. A pixel with a NaN in any channel counts as NaN; one with an
/// infinity and no NaN counts as Inf.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct NonFinite {
    /// Pixels with a NaN channel.
    pub nan: u64,
    /// Pixels with an infinite channel and no NaN.
    pub inf: u64,
    /// The first (x, y) positions in row-major order (row 0 at the top), at most
    /// [`MAX_REPORTED_POSITIONS`].
    pub first: Vec<(u32, u32)>,
}

impl NonFinite {
    /// NaN + Inf pixels.
    pub fn count(&self) -> u64 {
        self.nan + self.inf
    }

    /// Scans an image.
    pub fn of(img: &RgbImage) -> Self {
        let mut r = Self::default();
        let w = img.width.max(1) as usize;
        for (i, p) in img.pixels.iter().enumerate() {
            if p.iter().any(|c| c.is_nan()) {
                r.nan += 1;
            } else if p.iter().any(|c| c.is_infinite()) {
                r.inf += 1;
            } else {
                continue;
            }
            if r.first.len() < MAX_REPORTED_POSITIONS {
                r.first.push(((i % w) as u32, (i / w) as u32));
            }
        }
        r
    }

    /// "3 non-finite pixels (2 NaN, 1 Inf), first at (x, y) (x, y) ...", or "no non-finite pixels".
    pub fn describe(&self) -> String {
        if self.count() == 0 {
            return "no non-finite pixels".into();
        }
        let pos: Vec<String> = self.first.iter().map(|(x, y)| format!("({x}, {y})")).collect();
        let more = if self.count() as usize > self.first.len() { " ..." } else { "" };
        format!(
            "{} non-finite pixel{} ({} NaN, {} Inf), at (x, y), row 0 at the top: {}{more}",
            self.count(),
            if self.count() == 1 { "" } else { "s" },
            self.nan,
            self.inf,
            pos.join(" ")
        )
    }
}

/// Result of [`compare`]. `a` is the test image, `b` the reference.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Comparison {
    pub width: u32,
    pub height: u32,
    /// width × height.
    pub pixels: u64,
    /// Pixels where both images are finite in all channels: those RMSE, relMSE and the means use.
    pub pixels_compared: u64,
    /// sqrt(mean over pixels and the 3 channels of (a − b)²).
    pub rmse: f64,
    /// Mean over pixels and channels of (a − b)² / (b² + 0.01).
    pub relmse: f64,
    /// Mean of a over the compared pixels and all channels.
    pub mean_a: f64,
    /// Mean of b over the compared pixels and all channels.
    pub mean_b: f64,
    /// Share of the summed squared error that the worst 0.1% of the compared pixels (at least one)
    /// carry: near 0.001 for evenly spread noise, near 1 when a few fireflies make the RMSE.
    pub worst_share: f64,
    /// mean_a / mean_b, the bias indicator (1 = unbiased on average). Never NaN: when mean_b is 0 it
    /// is 1 if mean_a is 0 too, else ±infinity with the sign of mean_a (written as `null` in JSON).
    /// With no pixel compared both means are 0 and the ratio is 1 (and RMSE, relMSE are 0).
    pub mean_ratio: f64,
    /// Mean LDR-ꟻLIP error in [0, 1] (NVIDIA's FLIP, `nv-flip` crate) of a against b, both mapped to
    /// 8-bit sRGB with [`CompareOptions::exposure`] as the renderer's PNG; non-finite pixels enter
    /// FLIP as black. `None` when not asked for.
    pub flip: Option<f64>,
    /// Exposure (EV) and pixels per degree FLIP used (`None` with `flip`: FLIP not computed).
    pub flip_exposure: Option<f32>,
    pub flip_ppd: Option<f32>,
    /// Non-finite pixels of a (test) and b (reference).
    pub non_finite_a: NonFinite,
    pub non_finite_b: NonFinite,
}

impl Comparison {
    /// True when either image has NaN or Inf pixels.
    pub fn has_non_finite(&self) -> bool {
        self.non_finite_a.count() + self.non_finite_b.count() > 0
    }
}

fn check_sizes(a: &RgbImage, b: &RgbImage) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        bail!(
            "image sizes differ: test image is {}x{}, reference is {}x{}",
            a.width,
            a.height,
            b.width,
            b.height
        );
    }
    for (img, which) in [(a, "test image"), (b, "reference")] {
        let n = img.width as usize * img.height as usize;
        if img.pixels.len() != n {
            bail!("{which}: {} pixels for a {}x{} image", img.pixels.len(), img.width, img.height);
        }
    }
    Ok(())
}

/// Compares test image `a` with reference `b`: RMSE, relMSE, mean ratio, optionally LDR-FLIP, and
/// the non-finite pixels of each. Errors if the sizes differ.
pub fn compare(a: &RgbImage, b: &RgbImage, opts: &CompareOptions) -> Result<Comparison> {
    Ok(compare_with_error_map(a, b, opts)?.0)
}

/// [`compare`], also returning FLIP's per-pixel error map (row-major, row 0 at the top; `None`
/// when `opts.flip` is off), e.g. for [`write_error_image`].
pub fn compare_with_error_map(
    a: &RgbImage,
    b: &RgbImage,
    opts: &CompareOptions,
) -> Result<(Comparison, Option<Vec<f32>>)> {
    check_sizes(a, b)?;
    let mut n = 0u64;
    let (mut se, mut rel, mut sum_a, mut sum_b) = (0f64, 0f64, 0f64, 0f64);
    let mut pixel_se = Vec::with_capacity(a.pixels.len());
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        if !(pa.iter().all(|c| c.is_finite()) && pb.iter().all(|c| c.is_finite())) {
            continue;
        }
        n += 1;
        let mut px = 0.0;
        for c in 0..3 {
            let (x, y) = (pa[c] as f64, pb[c] as f64);
            let d2 = (x - y) * (x - y);
            px += d2;
            se += d2;
            rel += d2 / (y * y + 0.01);
            sum_a += x;
            sum_b += y;
        }
        pixel_se.push(px);
    }
    let worst_share = if se > 0.0 {
        let k = pixel_se.len().div_ceil(1000);
        let split = pixel_se.len() - k;
        pixel_se.select_nth_unstable_by(split, f64::total_cmp);
        pixel_se[split..].iter().sum::<f64>() / se
    } else {
        0.0
    };
    let samples = (3 * n) as f64;
    let (rmse, relmse, mean_a, mean_b) = if n == 0 {
        (0.0, 0.0, 0.0, 0.0)
    } else {
        ((se / samples).sqrt(), rel / samples, sum_a / samples, sum_b / samples)
    };
    let mean_ratio = if mean_b != 0.0 {
        mean_a / mean_b
    } else if mean_a == 0.0 {
        1.0
    } else {
        f64::INFINITY.copysign(mean_a)
    };
    let map = if opts.flip { Some(flip_error_map(a, b, opts.exposure, opts.ppd)?) } else { None };
    let flip = map.as_ref().map(|m| {
        if m.is_empty() {
            0.0
        } else {
            m.iter().map(|&e| e as f64).sum::<f64>() / m.len() as f64
        }
    });
    let cmp = Comparison {
        width: a.width,
        height: a.height,
        pixels: a.pixels.len() as u64,
        pixels_compared: n,
        rmse,
        relmse,
        mean_a,
        mean_b,
        worst_share,
        mean_ratio,
        flip,
        flip_exposure: flip.map(|_| opts.exposure),
        flip_ppd: flip.map(|_| opts.ppd),
        non_finite_a: NonFinite::of(a),
        non_finite_b: NonFinite::of(b),
    };
    Ok((cmp, map))
}

/// The renderer's PNG mapping (shaders/passes/tonemap.comp) to tightly packed RGB8: scale by
/// 2^`exposure_ev`, clamp to [0, 1] (negative and NaN to 0), sRGB encode, round. A pixel with any
/// non-finite channel becomes black.
pub fn to_srgb8(img: &RgbImage, exposure_ev: f32) -> Vec<u8> {
    fn encode(c: f32) -> u8 {
        let c = if c > 0.0 { c.min(1.0) } else { 0.0 };
        let s = if c <= 0.0031308 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
        (s * 255.0).round().clamp(0.0, 255.0) as u8
    }
    let scale = 2f32.powf(exposure_ev);
    let mut out = Vec::with_capacity(img.pixels.len() * 3);
    for p in &img.pixels {
        if p.iter().all(|c| c.is_finite()) {
            out.extend(p.iter().map(|&c| encode(c * scale)));
        } else {
            out.extend([0, 0, 0]);
        }
    }
    out
}

/// FLIP's pixels per degree accepted: below one pixel per degree a pixel spans more than the
/// eye's acuity can be modelled with (FLIP's filters degenerate and give NaN from ~1e-19 on), and
/// above 10,000 its filters outgrow any image.
pub const PPD_RANGE: std::ops::RangeInclusive<f32> = 1.0..=10_000.0;

/// Per-pixel LDR-ꟻLIP error in [0, 1] of test `a` against reference `b`, both through
/// [`to_srgb8`] with `exposure_ev`; row-major, row 0 at the top.
pub fn flip_error_map(a: &RgbImage, b: &RgbImage, exposure_ev: f32, ppd: f32) -> Result<Vec<f32>> {
    check_sizes(a, b)?;
    if !PPD_RANGE.contains(&ppd) {
        bail!("FLIP pixels per degree must lie in [{}, {}], not {ppd}", PPD_RANGE.start(), PPD_RANGE.end());
    }
    if !exposure_ev.is_finite() {
        bail!("exposure must be a finite number, not {exposure_ev}");
    }
    if a.pixels.is_empty() {
        return Ok(Vec::new());
    }
    let (w, h) = (a.width, a.height);
    let test = nv_flip::FlipImageRgb8::with_data(w, h, &to_srgb8(a, exposure_ev));
    let reference = nv_flip::FlipImageRgb8::with_data(w, h, &to_srgb8(b, exposure_ev));
    Ok(nv_flip::flip(reference, test, ppd).to_vec())
}

/// Writes a FLIP error map (as from [`compare_with_error_map`]) as a PNG through FLIP's magma
/// colour map (black = no error, light yellow = 1).
pub fn write_error_image(path: &Path, width: u32, height: u32, map: &[f32]) -> Result<()> {
    if map.len() != width as usize * height as usize {
        bail!("error map has {} values for a {width}x{height} image ({})", map.len(), path.display());
    }
    let colours = nv_flip::FlipImageFloat::with_data(width, height, map).apply_color_lut(&nv_flip::magma_lut()).to_vec();
    let rgba: Vec<u8> = colours.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect();
    crate::output::write_png(path, width, height, &rgba)
}

/// Computes FLIP of `a` against reference `b` (with `opts.exposure`, `opts.ppd`, whatever
/// `opts.flip` says) and writes its magma error image to `path`.
pub fn error_image(a: &RgbImage, b: &RgbImage, opts: &CompareOptions, path: &Path) -> Result<()> {
    let map = flip_error_map(a, b, opts.exposure, opts.ppd)?;
    write_error_image(path, a.width, a.height, &map)
}

/// A short plain-text table of a comparison (what `restir-vpl compare` prints).
pub fn table(c: &Comparison) -> String {
    let mut s = String::new();
    let mut row = |k: &str, v: String| s.push_str(&format!("{k:<16} {v}\n"));
    row("size", format!("{}x{}", c.width, c.height));
    row(
        "pixels",
        format!(
            "{} ({} compared; non-finite: test {}, reference {})",
            c.pixels,
            c.pixels_compared,
            c.non_finite_a.count(),
            c.non_finite_b.count()
        ),
    );
    if c.pixels_compared == 0 {
        // The metrics' values (0, 0, ratio 1) would read as a perfect match.
        for k in ["RMSE", "relMSE", "worst 0.1% px", "mean ratio"] {
            row(k, "none: no pixel is finite in both images".into());
        }
    } else {
        row("RMSE", format!("{:.6e}", c.rmse));
        row("relMSE", format!("{:.6e}", c.relmse));
        row("worst 0.1% px", format!("{:.1}% of the squared error", 100.0 * c.worst_share));
        if c.mean_ratio.is_finite() {
            row("mean ratio", format!("{:.6} (test mean {:.6e} / reference mean {:.6e})", c.mean_ratio, c.mean_a, c.mean_b));
        } else {
            // (summary JSON writes it as null; "inf" read as a number.)
            row("mean ratio", format!("none: the reference's mean is 0 (test mean {:.6e})", c.mean_a));
        }
    }
    row(
        "FLIP (LDR)",
        match c.flip {
            Some(f) => format!("{f:.6} (mean; exposure {} EV, {} px/degree)", c.flip_exposure.unwrap_or(0.0), c.flip_ppd.unwrap_or(0.0)),
            None => "not computed (--no-flip)".into(),
        },
    );
    s
}

/// Returned by the `compare` command when an input had NaN/Inf pixels (after the metrics over the
/// finite pixels were printed); the binary exits with status 3 for it.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct NonFiniteInput(pub String);

/// An argument `compare` refuses before reading anything (a value out of range, an output named
/// like an input); the binary exits with status 2 for it, as for arguments that do not parse.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadArgument(pub String);

/// The `restir-vpl compare` command: reads test image `a` and reference `b` (EXR), prints
/// [`table`], optionally writes the FLIP error PNG and the JSON; returns [`NonFiniteInput`] (after
/// printing) when either image has non-finite pixels.
pub fn run_cli(
    a_path: &Path,
    b_path: &Path,
    opts: &CompareOptions,
    error_image: Option<&Path>,
    json: Option<&Path>,
) -> Result<()> {
    use anyhow::Context as _;
    if !opts.exposure.is_finite() {
        return Err(BadArgument("--exposure must be a finite number".into()).into());
    }
    if !PPD_RANGE.contains(&opts.ppd) {
        return Err(BadArgument(format!("--ppd must lie in [{}, {}] pixels per degree (67, the default, is FLIP's standard viewing set-up), not {}", PPD_RANGE.start(), PPD_RANGE.end(), opts.ppd)).into());
    }
    // An output named like an input would replace the image it was computed from.
    for (flag, out) in [("--error-image", error_image), ("--json", json)] {
        if let Some(out) = out {
            if let Some(input) = [a_path, b_path].into_iter().find(|i| crate::output::same_file(i, out)) {
                return Err(BadArgument(format!("{flag} {}: is also the input {}; write it to another file", out.display(), input.display())).into());
            }
        }
    }
    if let Some(e) = error_image {
        crate::output::check_image_extension("--error-image", e, "png").map_err(|e| BadArgument(format!("{e:#}")))?;
    }
    if let (Some(e), Some(j)) = (error_image, json) {
        if crate::output::same_file(e, j) {
            return Err(BadArgument(format!("--error-image and --json both name {}; give two files", e.display())).into());
        }
    }
    // Outputs checked before the comparison (FLIP takes a while on large images).
    for (flag, out) in [("--error-image", error_image), ("--json", json)] {
        if let Some(out) = out {
            crate::output::prepare_output_file(out).with_context(|| format!("{flag} {}", out.display()))?;
        }
    }
    let a = crate::output::read_exr(a_path).context("test image")?;
    let b = crate::output::read_exr(b_path).context("reference")?;
    let need_map = opts.flip || error_image.is_some();
    let (cmp, map) = compare_with_error_map(&a, &b, &CompareOptions { flip: need_map, ..*opts })
        .with_context(|| format!("comparing {} with {}", a_path.display(), b_path.display()))?;
    let cmp = if opts.flip { cmp } else { Comparison { flip: None, ..cmp } };
    crate::outln!("test       {}", a_path.display());
    crate::outln!("reference  {}", b_path.display());
    crate::out!("{}", table(&cmp));
    if let (Some(path), Some(map)) = (error_image, &map) {
        write_error_image(path, cmp.width, cmp.height, map).with_context(|| format!("--error-image {}", path.display()))?;
        crate::outln!("FLIP error image: {}", path.display());
    }
    if let Some(path) = json {
        let mut comparison = serde_json::to_value(&cmp)?;
        if cmp.pixels_compared == 0 {
            // As in the table: no value rather than a perfect match's.
            for k in ["rmse", "relmse", "mean_a", "mean_b", "worst_share", "mean_ratio"] {
                comparison[k] = serde_json::Value::Null;
            }
        }
        let text = serde_json::to_string_pretty(&serde_json::json!({
            "test": a_path.display().to_string(),
            "reference": b_path.display().to_string(),
            "comparison": comparison,
        }))?;
        std::fs::write(path, text).with_context(|| format!("--json {}", path.display()))?;
    }
    if cmp.has_non_finite() {
        let mut files = Vec::new();
        for (nf, path, which) in [(&cmp.non_finite_a, a_path, "test image"), (&cmp.non_finite_b, b_path, "reference")] {
            if nf.count() > 0 {
                crate::errln!("{which} {}: {}", path.display(), nf.describe());
                files.push(format!("{} ({})", path.display(), nf.count()));
            }
        }
        return Err(NonFiniteInput(format!(
            "non-finite pixels in {}; the metrics above are over the {} of {} pixels finite in both images",
            files.join(" and "),
            cmp.pixels_compared,
            cmp.pixels
        ))
        .into());
    }
    Ok(())
}
