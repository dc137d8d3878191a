//! Pass-level debugging. `--dump-passes FRAMES` writes what every pass of the listed frames wrote,
//! as it stood right after the pass ran, to `OUT/passes/frame_NNNN/NN_<pass>__<what>.exr` (NN: the
//! dispatch's position in the frame), with `manifest.json` (pass order, skipped passes and why,
//! dispatch sizes, bindings, GPU ms, rays, and per output min / max / mean / non-finite count) and
//! `OUT/passes/index.html`, an inspector page. `--check-finite` captures the same outputs every
//! frame without writing them and stops at the first non-finite value, naming the frame, the
//! pass, the buffer and the pixels.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use serde::Serialize;

use crate::gpu_types::{oct_decode, GpuGridEntry, GpuReservoir, GpuSurface, GpuSurfaceTexels, GpuVplCandidate, CANDIDATE_INDEX_BITS, RESERVOIR_EMPTY};
use crate::output::{write_exr, write_png, RgbImage};
use crate::passes::{all_pass_descs, FramePlan, Step};
use crate::renderer::{CaptureKind, Captured, FrameStats};

/// Which frames `--dump-passes` writes: a list (`0,19`, which may name `last` too: `0,last`),
/// `last` or `all`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameSelection {
    All,
    Last,
    /// The frames listed, and the last one where `last` is listed too.
    List(Vec<u32>, bool),
}

impl FrameSelection {
    pub fn parse(s: &str) -> Result<Self, String> {
        match s.trim() {
            "all" => Ok(Self::All),
            "last" => Ok(Self::Last),
            list => {
                let mut frames = Vec::new();
                let mut last = false;
                for item in list.split(',').map(str::trim) {
                    match item {
                        "last" => last = true,
                        "all" => return Err(format!("'{s}': 'all' stands alone (every frame)")),
                        n => match n.parse::<u32>() {
                            Ok(n) => frames.push(n),
                            Err(_) => {
                                return Err(format!("'{s}': '{n}' is no frame number; expected frame numbers and 'last' separated by commas (0,19 or 0,last), or 'all'"))
                            }
                        },
                    }
                }
                Ok(Self::List(frames, last))
            }
        }
    }

    /// Whether frame `f` of a run of `frames` frames is dumped.
    pub fn contains(&self, f: u32, frames: u32) -> bool {
        match self {
            Self::All => true,
            Self::Last => f + 1 == frames,
            Self::List(l, last) => l.contains(&f) || (*last && f + 1 == frames),
        }
    }
}

/// One image decoded from a captured output: what it shows and its pixels.
pub struct Decoded {
    /// e.g. `position`, `w`, `rgb`.
    pub what: &'static str,
    /// How the page should show it: `hdr` (exposure + sRGB), `signed` (×0.5 + 0.5, normalised by
    /// the largest magnitude), `grey` (white at [`grey_white`]: the 99th percentile, so that a few
    /// huge values, which reservoir weights have, do not leave the rest black), `ids` (false colour,
    /// not to be read as numbers).
    pub look: &'static str,
    pub image: RgbImage,
    /// For an `ids` output of a per-pixel capture, the ids behind its false colour, for the page's
    /// readout: (ids per pixel, the ids; `u32::MAX` where there is none).
    pub raw_ids: Option<(usize, Vec<u32>)>,
}

impl Decoded {
    /// An output without ids behind it.
    pub fn new(what: &'static str, look: &'static str, image: RgbImage) -> Self {
        Self { what, look, image, raw_ids: None }
    }
}

/// The false colour of id `v` in an `ids` output (the G-buffer's: `instance × 65599 ^ triangle`).
pub fn hash_colour(v: u32) -> [f32; 3] {
    let mut h = v.wrapping_mul(0x9e37_79b9) ^ 0x5bd1_e995;
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    [(h & 255) as f32 / 255.0, ((h >> 8) & 255) as f32 / 255.0, ((h >> 16) & 255) as f32 / 255.0]
}

/// The G-buffer's packed records (a `CaptureKind::Surfaces` capture's bytes), decoded as the
/// passes decode them.
pub fn decode_surfaces(bytes: &[u8]) -> Vec<GpuSurface> {
    // Copied out as records: a byte vector has no alignment to cast in place.
    let packed: Vec<GpuSurfaceTexels> = bytemuck::pod_collect_to_vec(bytes);
    packed.iter().map(GpuSurfaceTexels::decode).collect()
}

/// The images a captured output decodes into: the frame's size, or for the tiles and the grid
/// one square of entries per tile or cell ([`GroupLayout`]).
pub fn decode(c: &Captured) -> Vec<Decoded> {
    let [width, height] = c.shape;
    let n = c.records();
    let img = |pixels: Vec<[f32; 3]>| RgbImage { width, height, pixels };
    // Positions in the file's coordinates (the scene may have been recentred), in f64.
    let file_position = |p: [f32; 3]| (glam::Vec3::from(p).as_dvec3() + c.origin.as_dvec3()).as_vec3().to_array();
    match c.kind {
        CaptureKind::Surfaces => {
            let s: Vec<GpuSurface> = decode_surfaces(&c.bytes[..n * std::mem::size_of::<GpuSurfaceTexels>()]);
            let ids = |s: &GpuSurface| match surface_ids(s) {
                [RESERVOIR_EMPTY, _] => [0.0; 3],
                [instance, triangle] => hash_colour(instance.wrapping_mul(65_599) ^ triangle),
            };
            vec![
                // (A miss's position is no point: left as stored.)
                Decoded::new("position", "signed", img(s.iter().map(|s| if s.offset_scale < 0.0 { s.position } else { file_position(s.position) }).collect())),
                Decoded::new("normal", "signed", img(s.iter().map(|s| s.shading_normal).collect())),
                // Beside the shading normal: where the two part, interpolated vertex normals are
                // at work (or went wrong: a smooth surface shaded flat has them equal).
                Decoded::new("geometric_normal", "signed", img(s.iter().map(|s| s.geometric_normal).collect())),
                Decoded::new("albedo", "hdr", img(s.iter().map(|s| s.albedo).collect())),
                Decoded::new("emission", "hdr", img(s.iter().map(|s| s.emission).collect())),
                Decoded::new("depth", "grey", img(s.iter().map(|s| [s.view_depth; 3]).collect())),
                Decoded { what: "ids", look: "ids", image: img(s.iter().map(ids).collect()), raw_ids: Some((2, s.iter().flat_map(surface_ids).collect())) },
                // The glTF material's index (the default material, for primitives without one,
                // follows the file's materials).
                Decoded { what: "material", look: "ids", image: img(s.iter().map(|s| surface_material(s).map_or([0.0; 3], hash_colour)).collect()), raw_ids: Some((1, s.iter().map(|s| surface_material(s).unwrap_or(RESERVOIR_EMPTY)).collect())) },
            ]
        }
        CaptureKind::Rgba => {
            let v: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&c.bytes[..n * 16]);
            vec![Decoded::new(c.buffer, "hdr", img(v.iter().map(|p| [p[0], p[1], p[2]]).collect()))]
        }
        CaptureKind::Reservoirs => {
            let r: Vec<GpuReservoir> = bytemuck::pod_collect_to_vec(&c.bytes[..n * std::mem::size_of::<GpuReservoir>()]);
            let vpl = |r: &GpuReservoir| if r.vpl == RESERVOIR_EMPTY { [0.0; 3] } else { hash_colour(r.vpl) };
            vec![
                Decoded { what: "vpl", look: "ids", image: img(r.iter().map(vpl).collect()), raw_ids: Some((1, r.iter().map(|r| r.vpl).collect())) },
                Decoded::new("w", "grey", img(r.iter().map(|r| [r.ucw; 3]).collect())),
                Decoded::new("m", "grey", img(r.iter().map(|r| [r.confidence; 3]).collect())),
                Decoded::new("target", "grey", img(r.iter().map(|r| [r.target; 3]).collect())),
            ]
        }
        CaptureKind::Candidates => {
            let t: Vec<GpuVplCandidate> = bytemuck::pod_collect_to_vec(&c.bytes[..n * std::mem::size_of::<GpuVplCandidate>()]);
            let layout = GroupLayout::of(c);
            let tiles = |f: &dyn Fn(&GpuVplCandidate) -> [f32; 3]| layout.image(&t.iter().map(f).collect::<Vec<_>>());
            vec![
                Decoded::new("vpl", "ids", tiles(&|t| hash_colour(candidate_index(t.vpl_kind)))),
                Decoded::new("position", "signed", tiles(&|t| file_position(t.position))),
                Decoded::new("normal", "signed", tiles(&|t| oct_decode(t.normal_oct))),
                // Grey (per channel, white at the 99th percentile): a VPL's flux is a small share
                // of the light's power, black in an image shown at exposure 0.
                Decoded::new("flux", "grey", tiles(&|t| t.flux)),
            ]
        }
        CaptureKind::GridEntries => {
            let g: Vec<GpuGridEntry> = bytemuck::pod_collect_to_vec(&c.bytes[..n * std::mem::size_of::<GpuGridEntry>()]);
            let layout = GroupLayout::of(c);
            let cells = |f: &dyn Fn(&GpuGridEntry) -> [f32; 3]| layout.image(&g.iter().map(f).collect::<Vec<_>>());
            // An empty entry (W = 0: not built, or no candidate) is black in the ids.
            let id = |e: &GpuGridEntry| if e.ucw > 0.0 { hash_colour(candidate_index(e.vpl_kind)) } else { [0.0; 3] };
            vec![
                Decoded::new("vpl", "ids", cells(&id)),
                Decoded::new("position", "signed", cells(&|e| if e.ucw > 0.0 { file_position(e.position) } else { e.position })),
                Decoded::new("normal", "signed", cells(&|e| if e.ucw > 0.0 { oct_decode(e.normal_oct) } else { [0.0; 3] })),
                Decoded::new("flux", "grey", cells(&|e| e.flux)),
                Decoded::new("w", "grey", cells(&|e| [e.ucw; 3])),
            ]
        }
        CaptureKind::Rgba8 => {
            let decode = |b: u8| {
                let c = b as f32 / 255.0;
                if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
            };
            vec![Decoded::new(c.buffer, "hdr", img(c.bytes[..n * 4].chunks_exact(4).map(|p| [decode(p[0]), decode(p[1]), decode(p[2])]).collect()))]
        }
    }
}

/// How a capture that is not per pixel is shown: each group of entries (a presampled tile, a
/// grid cell) as a square of `side`² pixels (entry `e` at column `e % side`, row `e / side`; a
/// last row cut short), the groups in rows of `columns` squares (group `g` in square row
/// `g / columns`); squares past the last group are black. The page's readout inverts it from
/// `side` (the manifest's `groups`).
#[derive(Clone, Debug, Serialize)]
pub struct GroupLayout {
    /// `tile` or `cell`.
    pub unit: &'static str,
    /// Groups (tiles, cells).
    pub count: u32,
    /// Entries per group.
    pub entries: u32,
    pub side: u32,
    pub columns: u32,
    pub rows: u32,
}

impl GroupLayout {
    pub fn of(c: &Captured) -> Self {
        let [entries, groups] = c.shape;
        let side = (entries as f64).sqrt().ceil().max(1.0) as u32;
        let columns = (groups as f64).sqrt().ceil().max(1.0) as u32;
        Self { unit: c.kind.group().unwrap_or("group"), count: groups, entries, side, columns, rows: groups.div_ceil(columns).max(1) }
    }

    /// The image of per-entry values `v` (group-major, as captured).
    fn image(&self, v: &[[f32; 3]]) -> RgbImage {
        let (width, height) = (self.columns * self.side, self.rows * self.side);
        let mut pixels = vec![[0.0; 3]; (width * height) as usize];
        for (i, value) in v.iter().enumerate() {
            let (g, e) = (i as u32 / self.entries, i as u32 % self.entries);
            let x = (g % self.columns) * self.side + e % self.side;
            let y = (g / self.columns) * self.side + e / self.side;
            pixels[(y * width + x) as usize] = *value;
        }
        RgbImage { width, height, pixels }
    }
}

/// A candidate's or grid entry's VPL index (the kind sits above it).
fn candidate_index(vpl_kind: u32) -> u32 {
    vpl_kind & ((1 << CANDIDATE_INDEX_BITS) - 1)
}

/// Records (row-major indices: pixels, or a tile capture's entries) where a captured output holds
/// a non-finite float in any field.
pub fn nonfinite_records(c: &Captured) -> Vec<usize> {
    let bpp = c.kind.bytes_per_record() as usize;
    // Which 4-byte words of a pixel's record are floats (the rest are ids).
    let float_word = |w: usize| match c.kind {
        CaptureKind::Surfaces => GpuSurfaceTexels::is_float_word(w),
        CaptureKind::Reservoirs => w != 0,                  // vpl index
        CaptureKind::Rgba => true,
        CaptureKind::Rgba8 => false,
        CaptureKind::Candidates => !matches!(w, 3 | 7), // vpl_kind, normal_oct
        CaptureKind::GridEntries => matches!(w, 0..=2 | 4..=6 | 8), // position, flux, W
    };
    (0..c.records())
        .filter(|&p| {
            let rec = &c.bytes[p * bpp..(p + 1) * bpp];
            rec.chunks_exact(4).enumerate().any(|(w, b)| float_word(w) && !f32::from_le_bytes(b.try_into().expect("4 bytes")).is_finite())
        })
        .collect()
}

/// Stops at the first non-finite value of a frame's captured outputs: names the frame, the pass,
/// the buffer and the first pixels.
pub fn check_finite(frame: u32, captured: &[Captured]) -> Result<()> {
    for c in captured {
        let bad = nonfinite_records(c);
        if !bad.is_empty() {
            let width = c.shape[0] as usize;
            let (unit, first): (&str, Vec<String>) = if c.kind.per_pixel() {
                ("pixel(s)", bad.iter().take(5).map(|&p| format!("({}, {})", p % width, p / width)).collect())
            } else {
                let group = c.kind.group().unwrap_or("group");
                (if bad.len() == 1 { "entry" } else { "entries" }, bad.iter().take(5).map(|&p| format!("{group} {} entry {}", p / width, p % width)).collect())
            };
            bail!(
                "--check-finite: frame {frame}: pass '{}'{} wrote non-finite values to '{}' at {} {unit}, first at {}",
                c.pass,
                if c.repeat > 0 { format!(" (dispatch {})", c.repeat + 1) } else { String::new() },
                c.buffer,
                bad.len(),
                first.join(", ")
            );
        }
    }
    Ok(())
}

/// Statistics of one output image over its finite values.
#[derive(Clone, Debug, Serialize)]
pub struct OutputStats {
    pub file: String,
    pub buffer: &'static str,
    pub what: &'static str,
    pub look: &'static str,
    pub min: f64,
    pub max: f64,
    pub mean: f64,
    /// The image's [width, height]: the frame's, or for `vpl_presample`'s tiles and
    /// `regir_build`'s grid a grid of squares, one per tile or cell ([`GroupLayout`]).
    pub size: [u32; 2],
    /// The tiles' or the grid's layout (absent for a per-pixel output).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub groups: Option<GroupLayout>,
    /// Pixels with a non-finite value in any channel.
    pub nonfinite: u64,
    /// The value the thumbnail shows white (`grey` images; their brighter pixels clip), else 0.
    pub white: f64,
}

/// `white`: the value `d`'s thumbnail shows white, as [`thumbnail`] returned it.
fn stats(file: String, buffer: &'static str, d: &Decoded, white: Option<f32>) -> OutputStats {
    let (mut min, mut max, mut sum, mut n, mut bad) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0u64, 0u64);
    for p in &d.image.pixels {
        // Counted in pixels, as --check-finite counts them.
        bad += u64::from(p.iter().any(|c| !c.is_finite()));
        for &c in p.iter().filter(|c| c.is_finite()) {
            min = min.min(c as f64);
            max = max.max(c as f64);
            sum += c as f64;
            n += 1;
        }
    }
    let finite_or_zero = |v: f64| if v.is_finite() { v } else { 0.0 };
    let white = white.map_or(0.0, f64::from);
    OutputStats { file, buffer, what: d.what, look: d.look, size: [d.image.width, d.image.height], groups: None, min: finite_or_zero(min), max: finite_or_zero(max), mean: if n > 0 { sum / n as f64 } else { 0.0 }, nonfinite: bad, white }
}

/// A dumped frame: its manifest and the values its page embeds for the per-pixel readout.
pub struct DumpedFrame {
    pub manifest: FrameManifest,
    /// Every output's values (the ids behind a false-colour output), when the frame has a readout.
    pub values: Vec<PixelValues>,
    /// Why the frame has no readout (its size, or the page's budget spent by earlier frames).
    pub readout_off: Option<String>,
}

/// One output's values as the page embeds them, as 32-bit words: one float per pixel for a grey
/// output whose three channels are equal, three otherwise (the variance, grey-scaled per channel); for a false-colour ids output the ids
/// themselves (the G-buffer's instance and triangle, a reservoir's VPL index; `u32::MAX`: none).
/// Row-major, row 0 at the top.
pub struct PixelValues {
    pub file: String,
    pub channels: usize,
    /// The words are ids (u32), not float bits.
    pub ids: bool,
    pub words: Vec<u32>,
}

/// A G-buffer record's (instance, triangle), both u32::MAX (RESERVOIR_EMPTY, a reservoir's "none"
/// too) for a miss.
fn surface_ids(s: &GpuSurface) -> [u32; 2] {
    if s.offset_scale < 0.0 { [RESERVOIR_EMPTY; 2] } else { [s.instance, s.triangle] }
}

/// A G-buffer record's material, None for a miss.
fn surface_material(s: &GpuSurface) -> Option<u32> {
    (s.offset_scale >= 0.0).then_some(s.material)
}

/// Most pixels whose values the page embeds for its per-pixel readout.
pub const READOUT_MAX_PIXELS: u32 = 256 * 256;

/// Most values one page embeds over all its frames (4 bytes each, ~5.3 characters in the page as
/// base64): `--dump-passes all` at 256×256 embedded every frame's (~2.6M values a ReSTIR frame, as
/// decimal text then), and 20 frames made a 688 MB page that Chromium showed blank. Frames past
/// the budget have no readout (the page says so) and their values are not kept in memory.
pub const READOUT_BUDGET_VALUES: usize = 8 << 20;

/// What is left of a page's [`READOUT_BUDGET_VALUES`] as its frames are dumped.
pub struct ReadoutBudget {
    left: usize,
}

impl Default for ReadoutBudget {
    fn default() -> Self {
        Self { left: READOUT_BUDGET_VALUES }
    }
}

impl ReadoutBudget {
    /// Keeps `values` (one frame's) if the budget holds them all; else gives why not.
    fn take(&mut self, values: &mut Vec<PixelValues>) -> Option<String> {
        let n: usize = values.iter().map(|v| v.words.len()).sum();
        if n <= self.left {
            self.left -= n;
            return None;
        }
        values.clear();
        Some(format!(
            "per-pixel readout off for this frame: the page embeds at most {}M values and earlier frames took {:.1}M of them (read the EXR files)",
            READOUT_BUDGET_VALUES >> 20,
            (READOUT_BUDGET_VALUES - self.left) as f64 / (1 << 20) as f64
        ))
    }
}

/// One pass of the frame, in order: run (with its outputs) or skipped (with why).
#[derive(Clone, Debug, Serialize)]
pub struct PassEntry {
    pub position: Option<usize>,
    pub pass: &'static str,
    pub repeat: u32,
    pub status: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why: Option<&'static str>,
    /// Workgroups dispatched (x, y, z) and the local size.
    pub workgroups: Option<[u32; 3]>,
    pub local_size: Option<[u32; 3]>,
    /// The pass's set-1 bindings (its own buffers), by the names the code and shader use.
    pub bindings: Vec<&'static str>,
    /// GPU ms of the pass (all its dispatches this frame) and the rays it traced per pixel.
    pub gpu_ms: Option<f64>,
    pub rays_per_pixel: Option<f64>,
    /// This frame ran the pass for the first time in the run (since the settings last changed):
    /// with a cold shader cache, lavapipe compiles the shader in its first dispatch, so its GPU ms
    /// holds the compilation (a dumped frame runs the passes apart, which other frames run fused:
    /// restir_spatial read 284 ms for ~1).
    pub first_dispatch: bool,
    pub outputs: Vec<OutputStats>,
}

#[derive(Clone, Debug, Serialize)]
pub struct FrameManifest {
    pub frame: u32,
    pub width: u32,
    pub height: u32,
    pub mode: String,
    pub view: String,
    pub passes: Vec<PassEntry>,
}

fn workgroups(local: [u32; 3], width: u32, height: u32) -> [u32; 3] {
    if local[1] > 1 {
        [width.div_ceil(local[0]), height.div_ceil(local[1]), 1]
    } else {
        [(width * height).div_ceil(local[0]), 1, 1]
    }
}

/// Removes `fdir` if it is a frame dump of an earlier run (it holds our manifest.json), so that a
/// new dump never mixes its files with another configuration's.
fn remove_dumped_frame(fdir: &Path) -> Result<()> {
    if fdir.join("manifest.json").is_file() {
        std::fs::remove_dir_all(fdir).with_context(|| format!("--dump-passes: removing the earlier dump {}", fdir.display()))?;
    }
    Ok(())
}

/// Checks, before any frame, that `dir` (`--out/passes`) can take a dump: absent or a directory,
/// with no file where a frame's folder goes and no folder where the page or the VPL file goes (each
/// was found only when its frame came up, after the frames before it had rendered).
pub fn check_dump_dir(dir: &Path) -> Result<()> {
    if !dir.exists() {
        return Ok(());
    }
    anyhow::ensure!(dir.is_dir(), "--dump-passes: {} exists and is not a directory", dir.display());
    for entry in std::fs::read_dir(dir).with_context(|| format!("--dump-passes: reading {}", dir.display()))? {
        let entry = entry.with_context(|| format!("--dump-passes: reading {}", dir.display()))?;
        let (name, path) = (entry.file_name().to_string_lossy().into_owned(), entry.path());
        if name.starts_with("frame_") && !path.is_dir() {
            anyhow::bail!("--dump-passes: {} is not a directory, and a frame's dump goes there; move it away", path.display());
        }
        if (name == "index.html" || name == "vpls.ply") && path.is_dir() {
            anyhow::bail!("--dump-passes: {} is a directory, and the dump writes that file; move it away", path.display());
        }
    }
    Ok(())
}

/// Removes an earlier run's frame dumps (`frame_NNNN/` with a manifest), inspector page and VPL
/// file from `dir` (`--out/passes`), before a run that dumps: its page then shows this run alone.
pub fn remove_earlier_dumps(dir: &Path) -> Result<()> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(()); // no earlier dump
    };
    for entry in entries {
        let entry = entry.with_context(|| format!("--dump-passes: reading {}", dir.display()))?;
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.starts_with("frame_") {
            remove_dumped_frame(&entry.path())?;
        } else if name == "index.html" || name == "vpls.ply" {
            std::fs::remove_file(entry.path()).with_context(|| format!("--dump-passes: removing the earlier {}", entry.path().display()))?;
        }
    }
    Ok(())
}

/// Writes one frame's dump under `dir/frame_NNNN/` and returns its manifest (also written there as
/// manifest.json). `variance`: the accumulation's per-pixel variance after the frame.
#[allow(clippy::too_many_arguments)]
pub fn write_frame(
    dir: &Path,
    frame: u32,
    width: u32,
    height: u32,
    settings: &crate::RenderSettings,
    plan: &FramePlan,
    stats_of_frame: &FrameStats,
    captured: &[Captured],
    variance: Option<Vec<[f32; 3]>>,
    log: &crate::renderer::FrameLog,
    budget: &mut ReadoutBudget,
) -> Result<DumpedFrame> {
    let fdir = dir.join(format!("frame_{frame:04}"));
    remove_dumped_frame(&fdir)?;
    std::fs::create_dir_all(&fdir).with_context(|| format!("--dump-passes: creating {}", fdir.display()))?;
    let descs = all_pass_descs();
    let pixels = (width * height).max(1) as f64;
    let mut passes = Vec::new();
    let mut values = Vec::new();
    let readout = width * height <= READOUT_MAX_PIXELS;
    // The dispatch's position in the frame: the plan is the frame's order, and a pass that ran
    // was dispatched once per capture of it (restir_spatial ×P), or once if nothing of it was
    // captured.
    let mut next_dispatch = 0usize;
    for (name, step) in plan.steps() {
        let desc = descs.iter().find(|d| d.name == name);
        let common = |position, repeat, status, why| PassEntry {
            position,
            pass: name,
            repeat,
            status,
            why,
            workgroups: None,
            local_size: desc.map(|d| d.local_size_with(settings.workgroup)),
            bindings: desc.map(|d| d.bindings.iter().map(|b| b.name).collect()).unwrap_or_default(),
            gpu_ms: None,
            rays_per_pixel: None,
            // (Only a pass's first dispatch in a frame compiles: restir_spatial's later ones do not.)
            first_dispatch: status == "run" && repeat == 0 && log.pass_ms.get(name).is_none_or(|v| v.len() <= 1),
            outputs: Vec::new(),
        };
        // The time of dispatch `repeat` of this pass.
        let dispatch_ms = |repeat: u32| stats_of_frame.dispatch_ms.iter().filter(|(n, _)| *n == name).nth(repeat as usize).map(|p| p.1);
        let captures = captured.iter().filter(|c| c.pass == name).count();
        match step {
            Step::Skip(why) => passes.push(common(None, 0, "skipped", Some(*why))),
            // A pass that ran without a captured output (none today: every pass's output is
            // copied): listed as run, with its time.
            Step::Run if captures == 0 => {
                let mut e = common(Some(next_dispatch), 0, "run", Some("no captured output"));
                next_dispatch += 1;
                e.gpu_ms = dispatch_ms(0);
                passes.push(e);
            }
            Step::Run => {
                for c in captured.iter().filter(|c| c.pass == name) {
                    let position = next_dispatch;
                    next_dispatch += 1;
                    let mut e = common(Some(position), c.repeat, "run", None);
                    e.workgroups = desc.map(|d| {
                        let local = d.local_size_with(settings.workgroup);
                        // regir_build: one workgroup per cell; vpl_presample: one invocation
                        // per tile entry.
                        if c.kind == CaptureKind::GridEntries {
                            let n = settings.grid.cells;
                            [n, n, n]
                        } else if c.kind.per_pixel() { workgroups(local, width, height) } else { [(c.records() as u32).div_ceil(local[0]), 1, 1] }
                    });
                    // This dispatch's own time; rays are counted per pass, so a pass dispatched
                    // several times (restir_spatial ×P) has its rays only in the frame's total.
                    e.gpu_ms = dispatch_ms(c.repeat);
                    if captures == 1 {
                        e.rays_per_pixel = stats_of_frame.rays_by_pass.iter().find(|(n, _)| *n == name).map(|p| p.1 as f64 / pixels);
                    }
                    let mut decoded = decode(c);
                    let groups = (!c.kind.per_pixel()).then(|| GroupLayout::of(c));
                    if c.buffer == "mean" {
                        if let Some(v) = &variance {
                            decoded.push(Decoded::new("variance", "grey", RgbImage { width, height, pixels: v.clone() }));
                        }
                    }
                    for d in &decoded {
                        let file = format!("{position:02}_{}__{}.exr", dump_name(c), d.what);
                        let (w, h) = (d.image.width, d.image.height);
                        write_exr(&fdir.join(&file), w, h, &d.image.pixels)?;
                        let (png, white) = thumbnail(d);
                        write_png(&fdir.join(file.replace(".exr", ".png")), w, h, &png)?;
                        e.outputs.push(OutputStats { groups: groups.clone(), ..stats(file.clone(), c.buffer, d, white) });
                        // (Kept only for a page that shows them: at 1280×720 every frame's were
                        // held to the end of the run, 167 MB a ReSTIR frame. The tiles are not
                        // pixels: the page reads their entries out of the EXR files.)
                        if readout && c.kind.per_pixel() {
                            let (channels, ids, words) = if d.look == "ids" {
                                match &d.raw_ids {
                                    Some((channels, words)) => (*channels, true, words.clone()),
                                    None => continue,
                                }
                            } else {
                                // One channel for a grey output whose three are equal (W, M, the
                                // target); the variance is grey-scaled but per channel.
                                let equal = d.image.pixels.iter().all(|p| p[0].to_bits() == p[1].to_bits() && p[1].to_bits() == p[2].to_bits());
                                let channels = if d.look == "grey" && equal { 1 } else { 3 };
                                (channels, false, d.image.pixels.iter().flat_map(|p| p[..channels].iter().map(|v| v.to_bits())).collect())
                            };
                            values.push(PixelValues { file, channels, ids, words });
                        }
                    }
                    passes.push(e);
                }
            }
        }
    }
    let manifest = FrameManifest {
        frame,
        width,
        height,
        mode: settings.mode.name().into(),
        view: settings.view.name().into(),
        passes,
    };
    let path = fdir.join("manifest.json");
    crate::output::write_text(&path, &serde_json::to_string_pretty(&manifest)?)?;
    let readout_off = if readout { budget.take(&mut values) } else { Some("per-pixel readout off above 256×256 pixels (read the EXR files)".to_string()) };
    Ok(DumpedFrame { manifest, values, readout_off })
}

/// A dispatch's name in file names: the pass, and for a repeated pass which dispatch.
fn dump_name(c: &Captured) -> String {
    if c.pass == crate::passes::RestirSpatialPass::NAME {
        format!("{}{}", c.pass, c.repeat + 1)
    } else {
        c.pass.to_string()
    }
}

/// The magnitude a `grey` image's thumbnail shows white: the 99th percentile of its finite
/// magnitudes, or the largest where that is 0 (a mostly empty image), at least 1e-30.
pub fn grey_white(d: &Decoded) -> f32 {
    let mut v: Vec<f32> = d.image.pixels.iter().flatten().filter(|c| c.is_finite()).map(|c| c.abs()).collect();
    if v.is_empty() {
        return 1e-30;
    }
    let k = ((v.len() - 1) as f64 * 0.99).round() as usize;
    let p99 = *v.select_nth_unstable_by(k, f32::total_cmp).1;
    let max = v.iter().fold(0f32, |m, &c| m.max(c));
    (if p99 > 0.0 { p99 } else { max }).max(1e-30)
}

/// The RGBA8 preview of a decoded image as the inspector shows it, and for a `grey` image the
/// value it shows white ([`grey_white`]).
pub fn thumbnail(d: &Decoded) -> (Vec<u8>, Option<f32>) {
    let grey = (d.look == "grey").then(|| grey_white(d));
    // Other looks scale by the largest finite magnitude (grey_white already read every value).
    let white = grey.unwrap_or_else(|| d.image.pixels.iter().flatten().filter(|c| c.is_finite()).fold(0f32, |m, &c| m.max(c.abs())).max(1e-30));
    let map = |c: f32| -> f32 {
        if !c.is_finite() {
            return 0.0;
        }
        match d.look {
            "signed" => 0.5 + 0.5 * (c / white),
            "grey" => c / white,
            "ids" => c,
            _ => {
                let c = c.clamp(0.0, 1.0);
                if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
            }
        }
    };
    let mut out = Vec::with_capacity(d.image.pixels.len() * 4);
    for p in &d.image.pixels {
        let bad = p.iter().any(|c| !c.is_finite());
        // Non-finite pixels in magenta.
        let rgb = if bad { [1.0, 0.0, 1.0] } else { [map(p[0]), map(p[1]), map(p[2])] };
        out.extend(rgb.iter().map(|&c| (c.clamp(0.0, 1.0) * 255.0).round() as u8));
        out.push(255);
    }
    (out, grey)
}

/// Writes `dir/index.html`: one self-contained page (PNG thumbnails beside it, no network) with
/// each dumped frame's passes in order as an event list, every output's thumbnail and statistics,
/// click to enlarge, and a per-pixel readout of every buffer on hover (values embedded in the
/// page, as base64 float32, for images up to 256×256 and within [`READOUT_BUDGET_VALUES`]).
/// `index.html#frame=F&x=X&y=Y` opens frame F's first output enlarged with pixel (X, Y)'s readout.
pub fn write_inspector(dir: &Path, frames: &[DumpedFrame]) -> Result<PathBuf> {
    use base64::Engine as _;
    let mut html = String::from(INSPECTOR_HEAD);
    let mut data = String::from("const FRAMES = [");
    for DumpedFrame { manifest: m, values, readout_off } in frames {
        let _ = write!(data, "{{frame:{},w:{},h:{},values:{{", m.frame, m.width, m.height);
        for v in values {
            let bytes: &[u8] = bytemuck::cast_slice(&v.words);
            let _ = write!(data, "{:?}:{{c:{},i:{},b:\"{}\"}},", v.file, v.channels, v.ids, base64::engine::general_purpose::STANDARD.encode(bytes));
        }
        data.push_str("}},");
        let _ = write!(html, "<section><h2>frame {} · {} · view {} · {}×{}</h2>", m.frame, m.mode, m.view, m.width, m.height);
        if let Some(why) = readout_off {
            let _ = write!(html, "<p class=note>{}</p>", esc(why));
        }
        html.push_str("<table><tr><th>#</th><th>pass</th><th>GPU ms</th><th>rays/px</th><th>groups</th><th>outputs</th></tr>");
        for p in &m.passes {
            if p.status == "skipped" {
                let _ = write!(html, "<tr class=skip><td></td><td>{}</td><td colspan=4>skipped: {}</td></tr>", p.pass, esc(p.why.unwrap_or("")));
                continue;
            }
            let _ = write!(
                html,
                "<tr><td>{}</td><td title=\"bindings: {}\">{}{}</td><td>{}</td><td>{}</td><td>{}</td><td class=outs>",
                p.position.map(|x| x.to_string()).unwrap_or_default(),
                esc(&p.bindings.join(", ")),
                p.pass,
                if p.pass == crate::passes::RestirSpatialPass::NAME { format!(" {}", p.repeat + 1) } else { String::new() },
                p.gpu_ms
                    .map(|v| if p.first_dispatch { format!("<span title=\"the pass's first dispatch in the run: with a cold shader cache, lavapipe compiles the shader in it\">{v:.3}*</span>") } else { format!("{v:.3}") })
                    .unwrap_or_default(),
                p.rays_per_pixel.map(|v| format!("{v:.2}")).unwrap_or_default(),
                p.workgroups.map(|g| format!("{}×{}×{}", g[0], g[1], g[2])).unwrap_or_default(),
            );
            if p.outputs.is_empty() {
                html.push_str(&esc(p.why.unwrap_or("")));
            }
            for o in &p.outputs {
                let png = format!("frame_{:04}/{}", m.frame, o.file.replace(".exr", ".png"));
                let _ = write!(
                    html,
                    "<figure><img src=\"{png}\" data-frame=\"{}\" data-file=\"{}\" data-w=\"{}\" data-h=\"{}\"{} onclick=\"big(this)\"><figcaption>{} <b>{}</b>{}<br>min {:.3e} max {:.3e}<br>mean {:.3e}{}{}</figcaption></figure>",
                    m.frame,
                    o.file,
                    o.size[0],
                    o.size[1],
                    o.groups.as_ref().map(|g| format!(" data-unit=\"{}\" data-side=\"{}\" data-entries=\"{}\"", g.unit, g.side, g.entries)).unwrap_or_default(),
                    o.buffer,
                    o.what,
                    o.groups.as_ref().map(|g| format!("<br>{} {}s × {} entries", g.count, g.unit, g.entries)).unwrap_or_default(),
                    o.min,
                    o.max,
                    o.mean,
                    if o.look != "grey" {
                        String::new()
                    } else if o.min == 0.0 && o.max == 0.0 && o.nonfinite == 0 {
                        "<br>all zero".to_string()
                    } else {
                        format!("<br>white at {:.3e} (99th pct.)", o.white)
                    },
                    if o.nonfinite > 0 { format!("<br><span class=bad>{} non-finite pixel(s)</span>", o.nonfinite) } else { String::new() }
                );
            }
            html.push_str("</td></tr>");
        }
        html.push_str("</table></section>");
    }
    data.push_str("];");
    html.push_str("<div id=zoom onclick=\"this.style.display='none'\"><img id=zimg><pre id=readout></pre></div>\n<script>\n");
    html.push_str(&data);
    html.push_str(INSPECTOR_SCRIPT);
    html.push_str("</script></body></html>\n");
    let path = dir.join("index.html");
    crate::output::write_text(&path, &html)?;
    Ok(path)
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

const INSPECTOR_HEAD: &str = r#"<!doctype html><html><head><meta charset="utf-8"><title>restir-vpl passes</title>
<style>
body{font:13px system-ui,sans-serif;background:#1e1e1e;color:#ddd;margin:16px}
h1{font-size:18px}h2{font-size:15px;margin-top:24px}
table{border-collapse:collapse}td,th{border-bottom:1px solid #333;padding:4px 8px;vertical-align:top;text-align:left}
tr.skip td{color:#777}.outs figure{display:inline-block;vertical-align:top;margin:0 8px 8px 0}
figure img{display:block;width:128px;height:128px;object-fit:contain;background:#111;image-rendering:pixelated;border:1px solid #444;cursor:zoom-in}figcaption{font-size:11px;color:#aaa}
.bad{color:#f5a}.note{color:#aa8}
#zoom{display:none;position:fixed;inset:0;background:rgba(0,0,0,.85);padding:24px}
#zimg{image-rendering:pixelated;max-width:70vw;max-height:85vh;cursor:crosshair}
#readout{position:fixed;right:16px;top:16px;width:26vw;white-space:pre-wrap;font:12px monospace;color:#eee}
</style></head><body><h1>restir-vpl · pass outputs</h1>
<p>Passes in the order the frame ran them; skipped passes say why. Click an output to enlarge it; hover a pixel for the values of every buffer of that frame there. Magenta: non-finite. GPU ms with *: the pass's first dispatch in the run, which on lavapipe with a cold shader cache holds the shader's compilation.</p>
"#;

const INSPECTOR_SCRIPT: &str = r#"
function big(img){
  const z=document.getElementById('zoom'), zi=document.getElementById('zimg');
  zi.src=img.src; zi.dataset.frame=img.dataset.frame; zi.dataset.file=img.dataset.file; z.style.display='block';
  // Enlarged to fill the view (a 64-px image too), in whole pixels' proportions; an image of
  // another size than the frame (the tiles, the grid) by its own.
  const w=Number(img.dataset.w), h=Number(img.dataset.h);
  zi.dataset.w=w; zi.dataset.h=h; zi.dataset.unit=img.dataset.unit||''; zi.dataset.side=img.dataset.side||''; zi.dataset.entries=img.dataset.entries||'';
  const s=Math.min(innerWidth*0.7/w, innerHeight*0.85/h); zi.style.width=(w*s)+'px'; zi.style.height=(h*s)+'px';
  document.getElementById('readout').textContent=img.dataset.file;
}
document.getElementById('zimg').addEventListener('mousemove',e=>{
  const zi=e.target, f=FRAMES.find(f=>String(f.frame)===zi.dataset.frame); if(!f)return;
  const r=zi.getBoundingClientRect(), w=Number(zi.dataset.w), h=Number(zi.dataset.h);
  const x=Math.floor((e.clientX-r.left)/r.width*w), y=Math.floor((e.clientY-r.top)/r.height*h);
  if(x<0||y<0||x>=w||y>=h)return;
  if(!zi.dataset.unit){document.getElementById('readout').textContent=readout(f,x,y);return;}
  // The tiles and the grid: a square of side × side entries per tile or cell (dump.rs's
  // GroupLayout), w / side squares a row.
  const side=Number(zi.dataset.side), group=Math.floor(y/side)*(w/side)+Math.floor(x/side), entry=(y%side)*side+x%side;
  document.getElementById('readout').textContent=`${zi.dataset.file}\n`+(entry<Number(zi.dataset.entries)?`${zi.dataset.unit} ${group}, entry ${entry}`:'(no entry here)')+' (no readout: read the EXR file)';
});
// Each output's values (float32, or u32 ids), decoded from base64 on first use.
function words(v){
  if(!v.f){const s=atob(v.b), u=new Uint8Array(s.length); for(let i=0;i<s.length;i++)u[i]=s.charCodeAt(i); v.f=v.i?new Uint32Array(u.buffer):new Float32Array(u.buffer);}
  return v.f;
}
function show(v,c){
  if(v.i)return c===4294967295?'none':String(c);
  return Number.isFinite(c)?c.toPrecision(5):'NaN/Inf';
}
function readout(f,x,y){
  let t=`pixel (${x}, ${y})\n`;
  const files=Object.keys(f.values);
  if(!files.length){t+='(no readout for this frame: see the note under its title)';}
  for(const k of files){
    const v=f.values[k], a=words(v), i=(y*f.w+x)*v.c;
    const s=Array.from(a.subarray(i,i+v.c),c=>show(v,c));
    t+=`${k}: ${s.join(', ')}\n`;
  }
  return t;
}
// index.html#frame=F&x=X&y=Y: that frame's first output enlarged, with that pixel's readout (all
// three given as whole numbers, or nothing happens).
{
  const q=new URLSearchParams(location.hash.slice(1)), whole=k=>/^\d+$/.test(q.get(k)||'');
  const f=whole('frame')&&whole('x')&&whole('y')?FRAMES.find(f=>String(f.frame)===q.get('frame')):null;
  const x=Number(q.get('x')), y=Number(q.get('y'));
  // The frame's first per-pixel output (not vpl_presample's tiles or regir_build's grid).
  const img=f&&[...document.querySelectorAll(`img[data-frame="${f.frame}"]`)].find(i=>!i.dataset.unit);
  if(img&&x<f.w&&y<f.h){big(img); document.getElementById('readout').textContent=readout(f,x,y);}
}
"#;

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(values: Vec<f32>) -> Decoded {
        let n = values.len() as u32;
        Decoded::new("w", "grey", RgbImage { width: n, height: 1, pixels: values.into_iter().map(|v| [v; 3]).collect() })
    }

    /// A few huge values (a reservoir weight's tail) no longer leave the rest black: the 99th
    /// percentile is white, brighter pixels clip, and a mostly empty image falls back to its max.
    #[test]
    fn grey_thumbnails_are_white_at_the_99th_percentile() {
        let mut v: Vec<f32> = (1..=1000).map(|i| i as f32).collect();
        v.extend([1e7; 5]);
        let d = grey(v);
        // 1005 values (each in three channels): the 99th percentile is the 995th smallest.
        assert_eq!(grey_white(&d), 995.0);
        let (t, white) = thumbnail(&d);
        assert_eq!(white, Some(995.0));
        assert_eq!(t[4 * 499], (500.0f32 / 995.0 * 255.0).round() as u8, "a middle value is grey, not black");
        assert_eq!(t[4 * 1002], 255, "a tail value clips to white");
        let sparse = grey([vec![0.0; 999], vec![5.0]].concat());
        assert_eq!(grey_white(&sparse), 5.0);
        assert_eq!(grey_white(&grey(vec![0.0, f32::NAN])), 1e-30);
    }

    /// The page's readout budget: frames are kept whole while it lasts; a frame past it keeps no
    /// values (so none are held in memory to the end of the run) and says why.
    #[test]
    fn the_readout_budget_keeps_whole_frames_until_it_is_spent() {
        let frame = |n: usize| vec![PixelValues { file: "a.exr".into(), channels: 1, ids: false, words: vec![0; n] }];
        let mut budget = ReadoutBudget::default();
        let third = READOUT_BUDGET_VALUES / 3;
        for _ in 0..3 {
            let mut f = frame(third);
            assert_eq!(budget.take(&mut f), None);
            assert_eq!(f[0].words.len(), third);
        }
        let mut over = frame(READOUT_BUDGET_VALUES - 3 * third + 1);
        let why = budget.take(&mut over).expect("past the budget");
        assert!(over.is_empty() && why.contains("readout off for this frame"), "{why}");
        let mut fits = frame(READOUT_BUDGET_VALUES - 3 * third);
        assert_eq!(budget.take(&mut fits), None, "a frame that fits what is left is kept");
    }
}
