//! Reference images that can be rendered in parts and merged.
//!
//! A reference is the mean of N frames, stored as a float32 RGB EXR whose header carries a
//! [`ReferenceMeta`]: the JSON text attribute `restir_vpl.reference` (what is read back) and, for
//! people (`exrheader`), `restir_vpl.frames` ("8 frames: [0, 8)"). Parts rendered with the same
//! settings over disjoint frame ranges merge into the frame-count-weighted mean ([`merge`]), which
//! equals one render over all their frames.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, ensure, Context as _, Result};
use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::output::RgbImage;
use crate::renderer::Renderer;
use crate::scene_gpu::SceneGpu;
use crate::settings::{Bias, Mode, RenderSettings};
use crate::vk::Context;

/// EXR header attribute holding the [`ReferenceMeta`] as JSON.
pub const META_ATTRIBUTE: &str = "restir_vpl.reference";
/// Human-readable frame count and ranges.
pub const FRAMES_ATTRIBUTE: &str = "restir_vpl.frames";

/// What a reference image is the mean of.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceMeta {
    /// Frames averaged.
    pub frames: u64,
    /// Index of the first frame; a single run covers [first_frame, first_frame + frames).
    pub first_frame: u64,
    /// The frame ranges [start, end) averaged, sorted and coalesced (one range when contiguous);
    /// their lengths sum to `frames`.
    #[serde(default)]
    pub ranges: Vec<(u64, u64)>,
    pub seed: u64,
    pub mode: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    /// Opaque key of every other render setting that must agree for images to be merged.
    pub config: String,
    /// Estimated mean squared error of the mean image against its expectation (mean per-pixel
    /// sample variance / frames), when known. Merging combines it as Σ (frames_i / frames)² ·
    /// noise_mse_i; a part without one (a single frame has no variance) takes the per-frame
    /// variance of the parts that have one (None if no part has).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_mse: Option<f64>,
}

impl ReferenceMeta {
    /// A single run's metadata: frames [first_frame, first_frame + frames).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        frames: u64,
        first_frame: u64,
        seed: u64,
        mode: impl Into<String>,
        scene: impl Into<String>,
        width: u32,
        height: u32,
        config: impl Into<String>,
    ) -> Self {
        Self {
            frames,
            first_frame,
            ranges: vec![(first_frame, first_frame + frames)],
            seed,
            mode: mode.into(),
            scene: scene.into(),
            width,
            height,
            config: config.into(),
            noise_mse: None,
        }
    }

    /// One range of frames, no gaps.
    pub fn is_contiguous(&self) -> bool {
        self.ranges.len() <= 1
    }

    /// "8 frames: [0, 8)" or "6 frames: [0, 3) [5, 8)".
    pub fn describe_frames(&self) -> String {
        let r: Vec<String> = self.ranges.iter().map(|(s, e)| format!("[{s}, {e})")).collect();
        format!("{} frame{}: {}", self.frames, if self.frames == 1 { "" } else { "s" }, r.join(" "))
    }

    /// Checks the frame bookkeeping (ranges sorted, disjoint, non-empty, summing to `frames`,
    /// starting at `first_frame`) and, given an image, its size.
    pub fn validate(&self, image: Option<&RgbImage>) -> Result<()> {
        ensure!(self.frames > 0, "no frames");
        ensure!(!self.ranges.is_empty(), "no frame ranges");
        let mut sum = 0u64;
        let mut prev_end = None;
        for &(s, e) in &self.ranges {
            ensure!(s < e, "empty or reversed frame range [{s}, {e})");
            if let Some(p) = prev_end {
                ensure!(s > p, "frame ranges not sorted and disjoint: {}", self.describe_frames());
            }
            prev_end = Some(e);
            sum += e - s;
        }
        ensure!(sum == self.frames, "frame ranges hold {sum} frames, but frames = {}", self.frames);
        if let Some(v) = self.noise_mse {
            // A mean squared error: a negative or non-finite one would pass into every merge.
            ensure!(v.is_finite() && v >= 0.0, "noise_mse {v} is not a mean squared error (finite, ≥ 0)");
        }
        ensure!(
            self.ranges[0].0 == self.first_frame,
            "first_frame {} is not the start of the first range {:?}",
            self.first_frame,
            self.ranges[0]
        );
        if let Some(img) = image {
            ensure!(
                (img.width, img.height) == (self.width, self.height),
                "image is {}x{} but its metadata says {}x{}",
                img.width,
                img.height,
                self.width,
                self.height
            );
            ensure!(img.pixels.len() == img.width as usize * img.height as usize, "pixel count does not match the size");
            // A reference is a mean of finite frames; a NaN or Inf would spread into every merge
            // and comparison made from it.
            let non_finite = |p: &[f32; 3]| p.iter().any(|c| !c.is_finite());
            if let Some(i) = img.pixels.iter().position(non_finite) {
                let bad = img.pixels[i..].iter().filter(|p| non_finite(p)).count();
                bail!(
                    "{bad} pixel(s) are NaN or Inf, the first at ({}, {}): {:?}",
                    i % img.width as usize,
                    i / img.width as usize,
                    img.pixels[i]
                );
            }
        }
        Ok(())
    }
}

/// JSON with every non-ASCII character escaped as \uXXXX: EXR text attributes are bytes (the exr
/// crate takes Latin-1), so this keeps any scene path intact.
fn ascii_json<T: Serialize>(v: &T) -> Result<String> {
    let s = serde_json::to_string(v)?;
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        if ch.is_ascii() {
            out.push(ch);
        } else {
            let mut buf = [0u16; 2];
            for u in ch.encode_utf16(&mut buf) {
                out.push_str(&format!("\\u{u:04x}"));
            }
        }
    }
    Ok(out)
}

/// Writes a reference: float32 RGB EXR (lossless ZIP) with the metadata in header attributes.
pub fn write_reference(path: &Path, image: &RgbImage, meta: &ReferenceMeta) -> Result<()> {
    use exr::meta::attribute::{AttributeValue, Text};
    use exr::prelude::*;
    meta.validate(Some(image)).with_context(|| format!("writing reference {}: bad metadata", path.display()))?;
    let json = ascii_json(meta)?;
    let mut attributes = LayerAttributes { software_name: Some(Text::from("restir-vpl")), ..Default::default() };
    attributes.other.insert(Text::from(META_ATTRIBUTE), AttributeValue::Text(Text::from(json.as_str())));
    attributes
        .other
        .insert(Text::from(FRAMES_ATTRIBUTE), AttributeValue::Text(Text::from(meta.describe_frames().as_str())));
    let w = image.width as usize;
    let layer = Layer::new(
        (w, image.height as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let p: [f32; 3] = image.pixels[y * w + x];
            (p[0], p[1], p[2])
        }),
    );
    // Through a sibling and a rename: `reference --resume` rewrites a file that may hold hours of
    // frames, and an interrupted write must leave the old one whole.
    crate::output::write_replacing(path, |partial| {
        Image::from_layer(layer).write().to_file(partial).map_err(crate::output::exr_error)
    })
}

/// Reads a reference written by [`write_reference`]. A plain EXR (no metadata) is an error.
pub fn read_reference(path: &Path) -> Result<(RgbImage, ReferenceMeta)> {
    let (img, meta) = read_exr_and_reference_meta(path)?;
    let Some(meta) = meta else {
        bail!(
            "{} is not a restir-vpl reference: its EXR header has no '{META_ATTRIBUTE}' attribute (frame count, \
             seed, settings). A plain render (final.exr) cannot be merged; render references with \
             `restir-vpl reference`, then merge them with `restir-vpl merge-references`",
            path.display()
        );
    };
    meta.validate(Some(&img)).with_context(|| format!("{}: inconsistent reference metadata", path.display()))?;
    Ok((img, meta))
}

/// An EXR and, when its header has one, the reference metadata [`write_reference`] put there
/// (parsed, not validated); None for a plain EXR.
pub fn read_exr_and_reference_meta(path: &Path) -> Result<(RgbImage, Option<ReferenceMeta>)> {
    use exr::meta::attribute::AttributeValue;
    let (img, value) = crate::output::read_exr_with_attribute(path, META_ATTRIBUTE)?;
    let json = match value {
        Some(AttributeValue::Text(t)) => t.to_string(),
        Some(other) => bail!(
            "{}: header attribute '{META_ATTRIBUTE}' is not text ({other:?}); the file is not a restir-vpl reference",
            path.display()
        ),
        None => return Ok((img, None)),
    };
    let mut meta: ReferenceMeta = serde_json::from_str(&json)
        .with_context(|| format!("{}: bad '{META_ATTRIBUTE}' header attribute", path.display()))?;
    if meta.ranges.is_empty() {
        meta.ranges = vec![(meta.first_frame, meta.first_frame + meta.frames)];
    }
    Ok((img, Some(meta)))
}

/// Merges partial references into their frame-count-weighted mean (accumulated in f64). See
/// [`merge_labelled`]; errors name the parts as "part #1", "part #2", ... in the given order.
pub fn merge(parts: &[(RgbImage, ReferenceMeta)]) -> Result<(RgbImage, ReferenceMeta)> {
    let labels: Vec<String> = (1..=parts.len()).map(|i| format!("part #{i}")).collect();
    merge_labelled(parts, &labels)
}

/// [`merge`] with a label per part (e.g. its file name) for the error messages.
///
/// Errors if there are no parts, if sizes, mode, scene, seed or config differ, or if frame ranges
/// overlap (frames rendered twice are not independent samples). The result has frames = the sum,
/// first_frame = the minimum and the coalesced union of the ranges. It does not depend on the order
/// of the parts (they are summed in order of their first frame).
pub fn merge_labelled(parts: &[(RgbImage, ReferenceMeta)], labels: &[String]) -> Result<(RgbImage, ReferenceMeta)> {
    ensure!(!parts.is_empty(), "nothing to merge: no references given");
    ensure!(labels.len() == parts.len(), "{} labels for {} parts", labels.len(), parts.len());
    for ((img, meta), label) in parts.iter().zip(labels) {
        meta.validate(Some(img)).with_context(|| format!("{label}: bad reference"))?;
    }
    let (_, m0) = &parts[0];
    for ((_, m), label) in parts.iter().zip(labels).skip(1) {
        let mut diffs = Vec::new();
        if (m.width, m.height) != (m0.width, m0.height) {
            diffs.push(format!("size {}x{} vs {}x{}", m0.width, m0.height, m.width, m.height));
        }
        if m.mode != m0.mode {
            diffs.push(format!("mode '{}' vs '{}'", m0.mode, m.mode));
        }
        if m.scene != m0.scene {
            diffs.push(format!("scene '{}' vs '{}'", m0.scene, m.scene));
        }
        if m.seed != m0.seed {
            diffs.push(format!("seed {} vs {}", m0.seed, m.seed));
        }
        if !same_config(&m.config, &m0.config) {
            diffs.push(config_differences(&m0.config, &m.config));
        }
        if !diffs.is_empty() {
            bail!("cannot merge {} and {label}: they differ in {}", labels[0], diffs.join("; "));
        }
    }
    // Every range with its part, sorted by start: an overlap shows up between neighbours.
    let mut ranges: Vec<(u64, u64, usize)> =
        parts.iter().enumerate().flat_map(|(i, (_, m))| m.ranges.iter().map(move |&(s, e)| (s, e, i))).collect();
    ranges.sort_unstable();
    for pair in ranges.windows(2) {
        let ((s0, e0, i0), (s1, e1, i1)) = (pair[0], pair[1]);
        if s1 < e0 {
            bail!(
                "cannot merge {} and {}: frames [{s0}, {e0}) and [{s1}, {e1}) overlap (frames rendered twice are not \
                 independent samples; render the parts with different first frames)",
                labels[i0],
                labels[i1]
            );
        }
    }
    let mut union: Vec<(u64, u64)> = Vec::new();
    for &(s, e, _) in &ranges {
        match union.last_mut() {
            Some(last) if last.1 == s => last.1 = e,
            _ => union.push((s, e)),
        }
    }
    // Sum in order of first frame so the result is bitwise independent of the parts' order.
    let mut order: Vec<usize> = (0..parts.len()).collect();
    order.sort_by_key(|&i| parts[i].1.first_frame);
    let n = parts[0].0.pixels.len();
    let mut acc = vec![[0f64; 3]; n];
    let mut frames = 0u64;
    for &i in &order {
        let (img, m) = &parts[i];
        let wgt = m.frames as f64;
        frames += m.frames;
        for (a, p) in acc.iter_mut().zip(&img.pixels) {
            for c in 0..3 {
                a[c] += wgt * p[c] as f64;
            }
        }
    }
    let inv = 1.0 / frames as f64;
    // A part without a noise estimate (one frame has no variance: a top-up by a single frame, or
    // `--resume --frames 1`) takes the per-frame variance of the parts that have one: the settings
    // agree (checked above), so one frame's noise is the same in every part. Its MSE is that
    // variance over its frames.
    // (A part's per-frame variance is its noise × its frames; their mean weighted by frames.)
    let known: Vec<(f64, f64)> = order.iter().map(|&i| &parts[i].1).filter_map(|m| m.noise_mse.map(|v| (v * m.frames as f64, m.frames as f64))).collect();
    let known_frames: f64 = known.iter().map(|(_, f)| f).sum();
    let per_frame_variance = (known_frames > 0.0).then(|| known.iter().map(|(var, f)| var * f).sum::<f64>() / known_frames);
    let noise_mse = order.iter().try_fold(0f64, |acc, &i| {
        let m = &parts[i].1;
        let part = m.noise_mse.or_else(|| per_frame_variance.map(|v| v / m.frames as f64));
        part.map(|v| acc + (m.frames as f64 * inv).powi(2) * v)
    });
    let pixels = acc.iter().map(|a| [(a[0] * inv) as f32, (a[1] * inv) as f32, (a[2] * inv) as f32]).collect();
    let meta = ReferenceMeta {
        frames,
        first_frame: union[0].0,
        ranges: union,
        seed: m0.seed,
        mode: m0.mode.clone(),
        scene: m0.scene.clone(),
        width: m0.width,
        height: m0.height,
        config: m0.config.clone(),
        noise_mse,
    };
    Ok((RgbImage { width: m0.width, height: m0.height, pixels }, meta))
}

/// The `restir-vpl merge-references` command: merges `inputs` into `out` and prints the result's
/// frame count and ranges.
pub fn run_merge_cli(inputs: &[std::path::PathBuf], out: &Path, overwrite: bool) -> Result<()> {
    crate::output::check_image_extension("--out", out, "exr")?;
    // Writing over one of the parts would lose its frames if anything went wrong after the write.
    if let Some(p) = inputs.iter().find(|p| crate::output::same_file(p, out)) {
        bail!("--out {}: is also the input {}; write the merge to a new file", out.display(), p.display());
    }
    let mut parts = Vec::with_capacity(inputs.len());
    for p in inputs {
        parts.push(read_reference(p)?);
    }
    let labels: Vec<String> = inputs.iter().map(|p| p.display().to_string()).collect();
    let (img, meta) = merge_labelled(&parts, &labels)?;
    // A reference holds hours of frames: as `reference` does without --resume, never replace one
    // unasked.
    // (A directory first: "pass --overwrite" was the advice, and with it the write failed.)
    if out.is_dir() {
        bail!("--out {}: is a directory; name the merged reference's file (e.g. merged.exr)", out.display());
    }
    if !overwrite && out.symlink_metadata().is_ok() {
        bail!("--out {}: exists; pass --overwrite to replace it, or write the merge to a new file", out.display());
    }
    // As `reference --out`: a missing directory is created, and a failure names the flag.
    crate::output::prepare_output_file(out).map_err(|e| anyhow::anyhow!("--out {}: {e:#}", out.display()))?;
    write_reference(out, &img, &meta).map_err(|e| anyhow::anyhow!("--out {}: {e:#}", out.display()))?;
    for (p, (_, m)) in inputs.iter().zip(&parts) {
        crate::outln!("  {}: {}", p.display(), m.describe_frames());
    }
    crate::outln!(
        "merged {} reference{} into {}: {}{}",
        inputs.len(),
        if inputs.len() == 1 { "" } else { "s" },
        out.display(),
        meta.describe_frames(),
        if meta.is_contiguous() { " (contiguous)" } else { " (not contiguous)" }
    );
    Ok(())
}

/// FNV-1a 64 of a file's bytes: identifies the scene in reference metadata independently of the
/// path it was loaded from.
pub fn file_hash(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    Ok(format!("{h:016x}"))
}

/// The settings that decide what a reference converges to, as a canonical JSON string: every
/// field of [`RenderSettings`] except the ones that only affect bookkeeping or output files
/// (frame count, seed — stored separately —, output paths, exposure, logging, device, validation).
pub fn reference_config(settings: &RenderSettings, scene_hash: &str) -> Result<String> {
    let mut v = serde_json::to_value(settings)?;
    let obj = v.as_object_mut().expect("RenderSettings serialises to an object");
    // Output, debugging and speed-only flags (the image is the same for every workgroup shape,
    // with the passes fused or apart, and traced with ray queries or ray-tracing pipelines:
    // tests/trace_pipeline.rs).
    for k in ["scene", "frames", "seed", "exposure", "save_every", "out_dir", "validate", "device_index", "progress", "dump_vpls", "dump_passes", "check_finite", "renderdoc_capture", "workgroup", "fuse_passes", "tracing"] {
        obj.remove(k);
    }
    // A reference accumulates on a still camera (`--progressive off` is refused), so the
    // settings of frames displayed alone never apply to it.
    if let Some(restir) = obj.get_mut("restir").and_then(|r| r.as_object_mut()) {
        restir.remove("moving_candidates");
        restir.remove("moving_neighbours");
    }
    obj.insert("scene_hash".into(), serde_json::Value::String(scene_hash.into()));
    strip_unused(obj, settings.mode);
    // serde_json's map is ordered (BTreeMap), so the string is canonical.
    Ok(serde_json::to_string(&v)?)
}

/// Settings a mode's image does not depend on: a path-traced reference stays valid when, say,
/// ReSTIR's defaults change. The same rule as the "has no effect here" warnings
/// (`RenderSettings::unused_flags`) for what a reference can be made with: a file made with a
/// flag the run said did nothing was refused for a resume without it ("max_bounces 3 vs 8").
/// (`vpl_radius` sets only `--view vpls`, which no reference takes.)
fn unused_keys(mode: Mode) -> &'static [&'static str] {
    match mode {
        Mode::Pt => &[
            "restir",
            "candidates",
            "candidate_source",
            "presample",
            "attenuation",
            "vpl_radius",
            "yuksel_radius",
            "yuksel_spacings",
            "yuksel_knn",
            "vpls_direct",
            "vpls_indirect",
            "gi",
            "photon_min_bounces",
            "photon_max_bounces",
            "compensate",
        ],
        Mode::Bruteforce | Mode::Uniform => &["restir", "candidates", "candidate_source", "presample", "max_bounces", "vpl_radius"],
        Mode::Ris => &["restir", "max_bounces", "vpl_radius"],
        Mode::Restir => &["max_bounces", "vpl_radius"],
    }
}

fn strip_unused(obj: &mut serde_json::Map<String, serde_json::Value>, mode: Mode) {
    for k in unused_keys(mode) {
        obj.remove(*k);
    }
    // Without GI no indirect VPL is traced (their count and bounces shape nothing).
    if obj.get("gi").and_then(|g| g.as_bool()) == Some(false) {
        for k in ["vpls_indirect", "photon_min_bounces", "photon_max_bounces"] {
            obj.remove(k);
        }
    }
    // ReSTIR's temporal settings, with --temporal off (the only ReSTIR a reference takes); the
    // spatial ones without spatial reuse; the thresholds with neither (as unused_flags says; the
    // motion view, which reads them, is no reference's).
    if let Some(restir) = obj.get_mut("restir").and_then(|r| r.as_object_mut()) {
        let temporal = restir.get("temporal").and_then(|t| t.as_bool()) != Some(false);
        let passes = restir.get("spatial_passes").and_then(|v| v.as_u64());
        let spatial = passes != Some(0) && restir.get("spatial_neighbours").and_then(|v| v.as_u64()) != Some(0);
        if !temporal {
            restir.remove("mcap");
            restir.remove("boiling_filter");
        }
        if !spatial {
            // Which of the two turned it off stays: the other and the radius go.
            if passes == Some(0) {
                restir.remove("spatial_neighbours");
            } else {
                restir.remove("spatial_passes");
            }
            restir.remove("spatial_radius");
        }
        if !temporal && !spatial {
            restir.remove("normal_threshold");
            restir.remove("depth_threshold");
        }
    }
    // The ReGIR grid shapes only RIS and ReSTIR images, and only with grid candidates: without
    // them the image is the one of a build before the grid existed, whose files have no such key.
    let grid_used = matches!(mode, Mode::Ris | Mode::Restir)
        && obj.get("grid").and_then(|g| g.get("candidates")).and_then(|c| c.as_u64()).is_some_and(|c| c > 0);
    if !grid_used {
        obj.remove("grid");
    }
}

/// Drops every null-valued key, at any depth: a setting left at its default (`None`) reads the
/// same whether a config writes it as null or, written before the setting existed, lacks it.
fn drop_nulls(v: &mut serde_json::Value) {
    if let Some(obj) = v.as_object_mut() {
        obj.retain(|_, x| !x.is_null());
        obj.values_mut().for_each(drop_nulls);
    }
}

/// A reference config ([`reference_config`]) as [`same_config`] and [`config_differences`] compare
/// it: its JSON object without the settings its mode does not use, nor null-valued keys; None when
/// it is not such an object.
fn comparable_config(s: &str) -> Option<serde_json::Map<String, serde_json::Value>> {
    let mut v: serde_json::Value = serde_json::from_str(s).ok()?;
    let obj = v.as_object_mut()?;
    let mode: Mode = serde_json::from_value(obj.get("mode")?.clone()).ok()?;
    strip_unused(obj, mode);
    drop_nulls(&mut v);
    match v {
        serde_json::Value::Object(obj) => Some(obj),
        _ => None,
    }
}

/// Whether two references' configs ([`reference_config`]) describe the same image: equal once the
/// settings their mode does not use are dropped (files written before a key was dropped still
/// match), and null-valued keys with them. A config that is not JSON matches only itself.
pub fn same_config(a: &str, b: &str) -> bool {
    if a == b {
        return true;
    }
    match (comparable_config(a), comparable_config(b)) {
        (Some(x), Some(y)) => x == y,
        _ => false,
    }
}

/// The settings two reference configs differ in, key by key ("max_bounces 8 vs 2"), or both
/// whole when either does not parse.
fn config_differences(a: &str, b: &str) -> String {
    let (Some(x), Some(y)) = (comparable_config(a), comparable_config(b)) else {
        return format!("settings '{a}' vs '{b}'");
    };
    let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
    let null = serde_json::Value::Null;
    let shown: Vec<String> = keys
        .into_iter()
        // (Null-valued keys are dropped: "yuksel_knn null vs null" was listed as a difference.)
        .filter(|k| x.get(*k) != y.get(*k))
        .map(|k| format!("{k} {} vs {}", x.get(k).unwrap_or(&null), y.get(k).unwrap_or(&null)))
        .collect();
    format!("settings: {}", shown.join(", "))
}

/// Modes whose partial references are independent samples of one answer (no state carried from
/// frame to frame), so that split runs merge into exactly the mean of one long run.
pub fn reference_mode_ok(settings: &RenderSettings) -> Result<()> {
    // A reference is the mean of its frames: a view or setting that shows each frame alone would
    // write one frame labelled as all of them (and merge with that weight).
    if settings.view.shows_reservoirs() {
        bail!(
            "--view {}: shows each frame alone, never accumulated; a reference is the mean of its frames (use --view final, direct or indirect)",
            settings.view.name()
        );
    }
    if settings.view == crate::settings::View::Vpls {
        // (It was accepted: a "reference" of the VPL picture, with a noise of 0.)
        bail!("--view vpls: draws the VPL set, which estimates no radiance; a reference is an image's converged mean (use --view final, direct or indirect)");
    }
    if !settings.progressive {
        bail!("--progressive off: shows each frame alone; a reference is the mean of its frames (leave it on)");
    }
    if settings.uses_grid() {
        // A cell is built from the previous frame's requests and weighed with its previous build's
        // normalisation: a part starting at --first-frame k began with an empty grid, and its
        // merge differed from one long run (RMSE 2e-2 at 32², 4 frames; 6e-8 without the grid).
        bail!(
            "--grid-candidates {}: the ReGIR grid carries state from frame to frame, and a reference needs independent frames; use --grid-candidates 0 (RIS estimates the same answer without the grid)",
            settings.grid.candidates
        );
    }
    match settings.mode {
        Mode::Pt | Mode::Bruteforce | Mode::Uniform | Mode::Ris => Ok(()),
        Mode::Restir if !settings.restir.temporal && settings.restir.bias == Bias::Unbiased => Ok(()),
        Mode::Restir => bail!(
            "--mode restir: a reference needs frames that are independent of each other; use --mode pt \
             (ground truth), bruteforce or ris (the VPL answer), or restir with --bias unbiased --temporal off"
        ),
    }
}

/// A rendered (part of a) reference and the estimated mean squared error of its mean image
/// against its own expectation (mean per-pixel sample variance / frames).
pub struct ReferencePart {
    pub image: RgbImage,
    pub meta: ReferenceMeta,
    pub noise_mse: Option<f64>,
    pub gpu_ms: f64,
    pub wall_ms: f64,
}

/// Renders frames `[first_frame, first_frame + frames)` of a reference with `settings`.
pub fn render_reference(
    ctx: Arc<Context>,
    scene: Arc<SceneGpu>,
    settings: &RenderSettings,
    first_frame: u64,
    frames: u32,
    mut progress: impl FnMut(u32),
) -> Result<ReferencePart> {
    reference_mode_ok(settings)?;
    if frames == 0 {
        bail!("--frames 0: a reference needs at least one frame");
    }
    let first = u32::try_from(first_frame)
        .ok()
        .filter(|f| f.checked_add(frames).is_some())
        .with_context(|| format!("--first-frame {first_frame} with --frames {frames}: the range's end (first frame + frames) must stay below 2^32"))?;
    let hash = file_hash(&settings.scene)?;
    let config = reference_config(settings, &hash)?;
    let camera = Camera::initial(&scene.info, settings.camera.as_ref());
    let mut r = Renderer::new(ctx, scene, settings.clone())?;
    r.set_frame_index(first)?;
    let start = Instant::now();
    for f in 0..frames {
        r.render_frame(&camera, false)?;
        progress(f + 1);
    }
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let gpu_ms = r.log().gpu_ms.iter().sum();
    let pixels = r.read_mean()?;
    let noise_mse = if frames > 1 {
        let var = r.read_variance()?;
        let sum: f64 = var.iter().flat_map(|p| p.iter()).map(|&v| v as f64).sum();
        Some(sum / (3.0 * var.len() as f64) / frames as f64)
    } else {
        None
    };
    let scene_name = settings.scene.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let mut meta = ReferenceMeta::new(
        frames as u64,
        first_frame,
        settings.seed as u64,
        settings.mode.name(),
        scene_name,
        settings.width,
        settings.height,
        config,
    );
    meta.noise_mse = noise_mse;
    let image = RgbImage { width: settings.width, height: settings.height, pixels };
    Ok(ReferencePart { image, meta, noise_mse, gpu_ms, wall_ms })
}

/// How [`make_reference`] treats the file it writes.
#[derive(Clone, Copy, Debug)]
pub enum ReferenceTarget {
    /// A new file of `frames` frames from frame `first_frame`; an existing file is an error (it
    /// is never overwritten).
    New { first_frame: u64, frames: u32 },
    /// `frames` more frames after the file's last one, merged in (`reference --resume`).
    Extend { frames: u32 },
    /// At least `frames` frames: the file as it is when it has them, topped up when it has fewer,
    /// rendered when absent (the results runner's cache).
    AtLeast { frames: u32 },
}

/// The reference [`make_reference`] left in the file, and what this call rendered of it.
pub struct MadeReference {
    pub image: RgbImage,
    pub meta: ReferenceMeta,
    /// (frames, GPU ms, wall ms) rendered by this call; `None` when the file was reused as is.
    pub rendered: Option<(u32, f64, f64)>,
}

/// Writes the reference `path` for `settings` as `target` says: renders only the frames that are
/// missing and merges them with what the file holds. A file made with other settings (scene,
/// mode, size, seed or sampling flags) is an error naming it. `progress(done, total)` follows the
/// frames rendered.
pub fn make_reference(
    ctx: &Arc<Context>,
    scene: &Arc<SceneGpu>,
    settings: &RenderSettings,
    path: &Path,
    target: ReferenceTarget,
    progress: &mut dyn FnMut(u32, u32),
) -> Result<MadeReference> {
    reference_mode_ok(settings)?;
    let config = reference_config(settings, &file_hash(&settings.scene)?)?;
    let read_matching = || -> Result<(RgbImage, ReferenceMeta)> {
        let (image, meta) = read_reference(path)?;
        let mut differ = Vec::new();
        if !same_config(&meta.config, &config) {
            differ.push(config_differences(&meta.config, &config));
        }
        if meta.seed != settings.seed as u64 {
            differ.push(format!("seed {} vs {}", meta.seed, settings.seed));
        }
        if !differ.is_empty() {
            bail!(
                "{} was rendered with other settings than this run's (the file's vs this run's {}); pass the flags it \
                 was made with, or choose another file",
                path.display(),
                differ.join("; ")
            );
        }
        Ok((image, meta))
    };
    let (existing, first, frames) = match target {
        ReferenceTarget::New { first_frame, frames } => {
            if path.exists() {
                bail!("--out {}: file exists; pass --resume to extend it, or choose another file", path.display());
            }
            (None, first_frame, frames)
        }
        ReferenceTarget::Extend { frames } => {
            let (image, meta) = read_matching()?;
            let end = meta.ranges.iter().map(|r| r.1).max().unwrap_or(0);
            // Said here in --resume's terms (render_reference would name --first-frame, which
            // the user did not give).
            if end.checked_add(u64::from(frames)).is_none_or(|e| e > u64::from(u32::MAX)) {
                bail!(
                    "--resume {}: its frames end at {end}; {end} + --frames {frames} must stay below 2^32",
                    path.display()
                );
            }
            (Some((image, meta)), end, frames)
        }
        ReferenceTarget::AtLeast { frames } if path.exists() => {
            let (image, meta) = read_matching()?;
            if meta.frames >= frames as u64 {
                return Ok(MadeReference { image, meta, rendered: None });
            }
            let end = meta.ranges.iter().map(|r| r.1).max().unwrap_or(0);
            let missing = frames - meta.frames as u32;
            (Some((image, meta)), end, missing)
        }
        ReferenceTarget::AtLeast { frames } => (None, 0, frames),
    };
    // Where the reference goes is checked before the frames, not after them: a mistyped path must
    // not cost a whole reference render.
    crate::output::prepare_output_file(path)?;
    let part = render_reference(ctx.clone(), scene.clone(), settings, first, frames, |done| progress(done, frames))?;
    let rendered = Some((frames, part.gpu_ms, part.wall_ms));
    let (image, meta) = match existing {
        Some(old) => merge(&[old, (part.image, part.meta)])?,
        None => (part.image, part.meta),
    };
    write_reference(path, &image, &meta)?;
    Ok(MadeReference { image, meta, rendered })
}
