//! Render settings shared by the CLI, the library API and the summary.

use std::path::PathBuf;

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// A settings enum with one name per variant: parsed from and written as that name (CLI, JSON,
/// the window's overlay), listed with its doc line as help.
pub trait NamedEnum: Copy + Sized + 'static {
    /// Every variant, in order.
    const ALL: &'static [Self];
    fn name(self) -> &'static str;
    /// One line for `--help` and the overlay.
    fn help(self) -> &'static str;
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|v| v.name() == name)
    }
    /// The variant after this one, wrapping around (the window cycles through them).
    fn next(self) -> Self {
        let i = Self::ALL.iter().position(|v| v.name() == self.name()).unwrap_or(0);
        Self::ALL[(i + 1) % Self::ALL.len()]
    }
    /// The variant before this one, wrapping around.
    fn previous(self) -> Self {
        let i = Self::ALL.iter().position(|v| v.name() == self.name()).unwrap_or(0);
        Self::ALL[(i + Self::ALL.len() - 1) % Self::ALL.len()]
    }
}

macro_rules! named_enum {
    ($(#[$m:meta])* pub enum $name:ident {
        $( #[doc = $doc:literal] $(#[$vm:meta])* $variant:ident = $text:literal, )*
    }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum $name { $( #[doc = $doc] $(#[$vm])* $variant, )* }

        impl NamedEnum for $name {
            const ALL: &'static [Self] = &[ $( Self::$variant ),* ];
            fn name(self) -> &'static str {
                match self { $( Self::$variant => $text ),* }
            }
            fn help(self) -> &'static str {
                match self { $( Self::$variant => $doc.trim() ),* }
            }
        }

        impl $name {
            pub fn name(self) -> &'static str {
                NamedEnum::name(self)
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(NamedEnum::name(*self))
            }
        }

        impl std::str::FromStr for $name {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                <Self as NamedEnum>::from_name(s).ok_or_else(|| {
                    let names: Vec<&str> = Self::ALL.iter().map(|v| NamedEnum::name(*v)).collect();
                    format!("'{s}' is not one of: {}", names.join(", "))
                })
            }
        }

        impl Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(NamedEnum::name(*self))
            }
        }

        impl<'de> Deserialize<'de> for $name {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let s = String::deserialize(d)?;
                s.parse().map_err(serde::de::Error::custom)
            }
        }
    };
}

named_enum! {
    /// What each pixel estimates.
    pub enum Mode {
        /// Path tracing with next-event estimation and MIS: the ground truth.
        Pt = "pt",
        /// One VPL per pixel, chosen uniformly; one shadow ray.
        Uniform = "uniform",
        /// Resampled importance sampling over --candidates VPLs; one shadow ray.
        Ris = "ris",
        /// ReSTIR DI over the VPLs: initial RIS, temporal and spatial reservoir reuse.
        Restir = "restir",
        /// Every VPL with a shadow ray: the VPL model's exact answer (small images only).
        Bruteforce = "bruteforce",
    }
}

impl Mode {
    /// Whether the mode shades with the VPL set.
    pub fn uses_vpls(self) -> bool {
        !matches!(self, Mode::Pt)
    }

    /// Whether the mode picks VPLs through reservoirs (restir_initial + vpl_shade).
    pub fn uses_reservoirs(self) -> bool {
        matches!(self, Mode::Uniform | Mode::Ris | Mode::Restir)
    }
}

named_enum! {
    /// Where RIS candidates come from.
    pub enum CandidateSource {
        /// Uniformly over the VPLs (as in the thesis).
        Uniform = "uniform",
        /// In proportion to lum(Φ) through an alias table.
        Power = "power",
    }
}

named_enum! {
    /// ReSTIR reuse flavour.
    pub enum Bias {
        /// Confidence-weighted reuse, targets without visibility: cheap, biased.
        Biased = "biased",
        /// Generalised (pairwise) MIS: converges to the brute-force sum.
        Unbiased = "unbiased",
    }
}

named_enum! {
    /// VPL distance attenuation.
    pub enum Attenuation {
        /// Yuksel's non-singular G(d) = 2 / (d² + r² + d·√(d² + r²)).
        Yuksel = "yuksel",
        /// G(d) = 1/d² (singular next to a VPL).
        InverseSquare = "inverse-square",
    }
}

named_enum! {
    /// How the window's frames wait for the display (`--present-mode`).
    #[derive(Default)]
    pub enum PresentMode {
        /// Wait for the vertical blank; never tears (every surface offers it).
        #[default]
        Fifo = "fifo",
        /// Replace the image waiting to be shown; no tearing, no waiting.
        Mailbox = "mailbox",
        /// Show at once; may tear.
        Immediate = "immediate",
    }
}

/// The ReSTIR settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RestirSettings {
    pub temporal: bool,
    /// Temporal history confidence cap, in multiples of the current frame's.
    pub mcap: f32,
    pub spatial_neighbours: u32,
    /// Disc radius for spatial neighbours (pixels); None: [`default_spatial_radius`] of the
    /// image width (resolved by [`RestirSettings::spatial_radius_px`]).
    pub spatial_radius: Option<f32>,
    pub spatial_passes: u32,
    /// Neighbours whose shading normals' dot product is below this are rejected.
    pub normal_threshold: f32,
    /// Neighbours whose view depth differs by more than this fraction are rejected.
    pub depth_threshold: f32,
    pub bias: Bias,
    /// RTXDI's boiling filter after temporal reuse: drop a reservoir whose weight sum exceeds its
    /// 8×8 workgroup's mean non-zero one by 10/strength − 9 (0: off; biased when on).
    pub boiling_filter: f32,
    /// Shadow-test the initial sample (targets include visibility). None: off (unbiased reuse
    /// stays unbiased without it; with it, two shadow rays per spatial neighbour).
    pub initial_visibility: Option<bool>,
    /// RIS candidates of a frame that is displayed alone (the camera moved this frame, or
    /// `--progressive off`) while temporal reuse has history: at most `--candidates`, at least the
    /// grid's; 0: `--candidates`. Such a frame's own error hardly depends on the candidates once
    /// reuse has history, where an accumulation's does (docs/performance.md, "Frames displayed
    /// alone").
    #[serde(default = "default_moving_candidates")]
    pub moving_candidates: u32,
    /// Spatial neighbours of such a frame: at most `--spatial-neighbours`; 0: `--spatial-neighbours`.
    #[serde(default = "default_moving_neighbours")]
    pub moving_neighbours: u32,
}

/// [`RestirSettings::moving_candidates`]' default: 8, since a pixel without history draws the
/// still count anyway (stop 43; 16 before: docs/performance.md, "Eight candidates").
pub fn default_moving_candidates() -> u32 {
    8
}

/// [`RestirSettings::moving_neighbours`]' default.
pub fn default_moving_neighbours() -> u32 {
    4
}

impl Default for RestirSettings {
    fn default() -> Self {
        Self {
            temporal: true,
            mcap: 20.0,
            spatial_neighbours: 8,
            spatial_radius: None,
            spatial_passes: 1,
            normal_threshold: 0.9,
            depth_threshold: 0.1,
            // Unbiased by default: biased reuse is measurably dark (docs/results.md), the unbiased
            // one with unshadowed targets costs a few percent more.
            bias: Bias::Unbiased,
            boiling_filter: 0.0,
            initial_visibility: None,
            moving_candidates: default_moving_candidates(),
            moving_neighbours: default_moving_neighbours(),
        }
    }
}

/// The spatial radius when none is given: the thesis's 20 px at its 1280 px width, scaled with the
/// image width, at least 4 px. Measured on the three scenes at 256–1280 px (docs/performance.md,
/// "The spatial radius"): a fixed 20 px is too wide for small images, where a pixel covers more of
/// the scene (1.8× the best relMSE at 16 frames at 256²); radii under 4 px reuse correlated
/// samples; between half and this radius relMSE is a little lower and FLIP higher (blotchier noise).
pub fn default_spatial_radius(width: u32) -> f32 {
    (SPATIAL_RADIUS_AT_1280 * width as f32 / 1280.0).max(MIN_SPATIAL_RADIUS)
}

/// [`default_spatial_radius`] at a 1280 px wide image (the thesis's radius), and its floor.
pub const SPATIAL_RADIUS_AT_1280: f32 = 20.0;
pub const MIN_SPATIAL_RADIUS: f32 = 4.0;

impl RestirSettings {
    /// The spatial disc radius in pixels at image width `width`: the one given, or
    /// [`default_spatial_radius`].
    pub fn spatial_radius_px(&self, width: u32) -> f32 {
        self.spatial_radius.unwrap_or_else(|| default_spatial_radius(width))
    }

    pub fn initial_visibility(&self) -> bool {
        self.initial_visibility.unwrap_or(false)
    }
}

named_enum! {
    /// What the output image shows.
    #[derive(Default)]
    pub enum View {
        /// The mode's radiance estimate.
        #[default]
        Final = "final",
        /// Debug: diffuse-shaded scene with every VPL as a sphere (blue direct, red indirect).
        Vpls = "vpls",
        /// Debug: the final reservoir's unbiased contribution weight W (grey).
        ReservoirW = "reservoir-w",
        /// Debug: the final reservoir's confidence M (grey).
        ReservoirM = "reservoir-m",
        /// Debug: the kind of VPL each pixel's reservoir holds (blue direct, cyan point light, red indirect, black none).
        VplKind = "vpl-kind",
        /// Debug (read the EXR): temporal reprojection. R, G: where the pixel's surface point was in the previous frame minus the pixel centre, in pixels; B: distance from that point to the previous surface found there, relative to depth (0 on a match), or -1 where history is rejected (off screen, disoccluded).
        Motion = "motion",
        /// Only the emitters seen directly and the direct VPLs (direct light).
        Direct = "direct",
        /// Only the indirect VPLs (global illumination).
        Indirect = "indirect",
    }
}

impl View {
    /// Whether the view reads the reservoirs (or, for motion, the temporal reprojection): such a
    /// view shows each frame alone, never accumulated.
    pub fn shows_reservoirs(self) -> bool {
        matches!(self, View::ReservoirW | View::ReservoirM | View::VplKind | View::Motion)
    }
}

/// What the photon pass traces: the VPL set's size and seed (plain data; the pass is
/// `crate::passes::PhotonEmitPass`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PhotonSettings {
    pub direct: u32,
    /// Target indirect VPL count (0: no global illumination).
    pub indirect: u32,
    pub min_bounces: u32,
    pub max_bounces: u32,
    pub seed: u32,
}

/// A camera given on the command line; replaces the scene's camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraOverride {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub yfov_degrees: f32,
}

/// The default Yuksel radius in mean VPL spacings √(A / (π N)). Chosen from `bench --radius`
/// (docs/radius.md): on the three scenes 8× keeps the clamp's darkening to 0.3–1.6 % while it cuts
/// the share of squared error in the worst 0.1 % of pixels from 27–44 % (1×) to 6–22 % and the
/// RMSE at t = 1 and t = 20 on every scene; larger multiples darken more (16×: 0.9–3.2 %).
/// `--compensate` removes the darkening for any radius.
pub const DEFAULT_RADIUS_SPACINGS: f32 = 8.0;
/// Most nearest VPLs `--yuksel-knn` may ask for.
pub const MAX_YUKSEL_KNN: u32 = 256;
/// The largest Yuksel radius: r² + d² stays far inside 32-bit floats (3.4e38) for any distance
/// within the camera's limits.
pub const MAX_YUKSEL_RADIUS: f32 = 1e18;

/// An automatic radius rule in words (summary.json's `yuksel_radius_source`): M × the mean VPL
/// spacing, or with `knn` M × each VPL's local spacing from its K nearest VPLs.
pub fn radius_rule_text(multiple: f32, knn: Option<u32>) -> String {
    match knn {
        None => format!("{multiple} x the mean VPL spacing sqrt(scene area / (pi * VPL count))"),
        Some(k) => format!(
            "per VPL: {multiple} x its local spacing d_{k} / sqrt({k}), d_{k} the distance to its {} nearest VPL \
             (yuksel_radius: the median)",
            ordinal(k)
        ),
    }
}

/// 1st, 2nd, 3rd, 4th, …, 11th, 12th, 13th, 21st.
fn ordinal(n: u32) -> String {
    let suffix = match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{n}{suffix}")
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderSettings {
    pub scene: PathBuf,
    pub mode: Mode,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub seed: u32,
    /// Jitter primary rays inside the pixel (box filter).
    pub aa: bool,
    /// Path-tracer bounces; negative: unbounded (Russian roulette only).
    pub max_bounces: i32,
    /// Exposure in EV for the PNG preview.
    pub exposure: f32,
    pub camera: Option<CameraOverride>,
    /// A camera path (`--camera-path`): frame f is seen from its camera at f.
    pub camera_path: Option<PathBuf>,
    /// Accumulate frames while nothing changes (off: every image is its own frame alone).
    pub progressive: bool,
    /// Write `accum_NNNN.exr` every K frames (0: never).
    pub save_every: u32,
    pub out_dir: Option<PathBuf>,
    pub validate: bool,
    pub device_index: Option<usize>,
    /// `--trace query|pipeline`; None: auto (RESTIR_VPL_TRACE if set, else the device's best).
    #[serde(default)]
    pub tracing: Option<crate::vk::context::Tracing>,
    /// Show a progress bar (only on a terminal, and only for runs over a second).
    pub progress: bool,
    /// Direct VPLs (they replace the area and point lights).
    pub vpls_direct: u32,
    /// Target number of indirect VPLs from photon paths.
    pub vpls_indirect: u32,
    /// Global illumination: indirect VPLs on (off: `--no-gi`).
    pub gi: bool,
    /// Russian roulette starts after this many photon bounces.
    pub photon_min_bounces: u32,
    /// At most this many indirect VPLs per photon path. A VPL at a path's k-th hit reflects once
    /// more toward the pixel, so the VPL image holds light paths of up to B + 1 reflections: the
    /// path tracer's `max_bounces` = B + 1 (default 7, against the path tracer's 8).
    pub photon_max_bounces: u32,
    /// Write the VPLs as a PLY point cloud here.
    pub dump_vpls: Option<PathBuf>,
    /// `--dump-passes`: frames whose pass outputs are written to `OUT/passes` (`0,19`, `last`, `0,last`,
    /// `all`; see `crate::dump::FrameSelection`).
    pub dump_passes: Option<String>,
    /// `--check-finite`: capture every pass's outputs each frame and stop at the first
    /// non-finite value.
    pub check_finite: bool,
    /// `--renderdoc-capture N`: wrap frame N in a RenderDoc capture (when run under RenderDoc).
    pub renderdoc_capture: Option<u32>,
    pub view: View,
    /// VPL sphere radius for `--view vpls` (scene units); default 0.25% of the scene's diagonal.
    pub vpl_radius: Option<f32>,
    /// RIS candidates per pixel (ris and restir).
    pub candidates: u32,
    pub candidate_source: CandidateSource,
    /// RTXDI-style light presampling for ris and restir: each frame `vpl_presample` draws tiles of
    /// candidates from the source pdf and `restir_initial` reads each pixel's candidates from one
    /// random tile (same estimator, cache-resident reads). Off: candidates straight from the VPL
    /// buffer.
    #[serde(default = "default_presample")]
    pub presample: bool,
    /// A world-space grid of presampled VPLs (ReGIR) that part of the RIS candidates come from
    /// (ris and restir; `grid.candidates == 0`: none).
    #[serde(default)]
    pub grid: GridSettings,
    /// ReSTIR's passes fused in pairs, as Bevy Solari runs them: `restir_initial_temporal`
    /// (initial RIS + temporal merge) and `restir_spatial_shade` (last spatial merge + shading),
    /// each one dispatch with the same functions and random streams as the two passes it replaces
    /// (the same image, bit for bit). A frame whose pass outputs are captured (`--dump-passes`,
    /// `--check-finite`) and the reservoir views run the passes apart. None (the default): fused,
    /// which saved 4–13 % of every ReSTIR frame measured on an NVIDIA H100 and, since the reuse's
    /// kind became specialisation constants, 0–10 % on lavapipe (AMD EPYC host; the Intel host
    /// gained 0–7 % already before) (docs/performance.md, "Pass fusion"). The renderer resolves it
    /// ([`RenderSettings::fuses_passes`]), so its settings and the run's summary say which ran.
    #[serde(default)]
    pub fuse_passes: Option<bool>,
    /// Workgroup (x, y) of the per-pixel passes whose shaders take it as specialisation constants
    /// (gbuffer, pathtrace, restir_initial, restir_spatial, restir_spatial_shade, vpl_shade,
    /// vpl_compensate, vpl_bruteforce); restir_temporal, restir_initial_temporal and restir_boiling
    /// stay 8×8 (the boiling filter's blocks are its workgroups). `--workgroup WxH`; `bench --workgroups` measures the choice.
    #[serde(default = "default_workgroup")]
    pub workgroup: [u32; 2],
    pub restir: RestirSettings,
    pub attenuation: Attenuation,
    /// Yuksel's r (scene units); None: [`DEFAULT_RADIUS_SPACINGS`] × the mean VPL spacing
    /// √(A / (π N)).
    pub yuksel_radius: Option<f32>,
    /// The multiple M of the automatic radius rules (`--yuksel-spacings`); None:
    /// [`DEFAULT_RADIUS_SPACINGS`].
    #[serde(default)]
    pub yuksel_spacings: Option<f32>,
    /// `--yuksel-knn K`: a radius per VPL, M × its local spacing d_K/√K from its K nearest VPLs
    /// (`vpl_radius.rs`), instead of M × the mean spacing of the whole set.
    #[serde(default)]
    pub yuksel_knn: Option<u32>,
    /// Sample base-colour textures (off: base colour factors only, untextured shader variants).
    pub textures: bool,
    /// `--merge-blas N`: a scene of at most N triangles has its instances merged into one
    /// world-space mesh with one BLAS (`Scene::merged`); 0: never, one BLAS per mesh. The same
    /// image up to float rounding of the transformed vertices.
    #[serde(default = "default_merge_blas")]
    pub merge_blas: u32,
    /// `--compensate`: add back the energy Yuksel's clamp removes (Kollig & Keller 2004), so a
    /// VPL mode converges to the path tracer for any radius (the `vpl_compensate` pass).
    #[serde(default)]
    pub compensate: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            scene: PathBuf::from("scenes/cornell_box.gltf"),
            mode: Mode::Pt,
            width: 512,
            height: 512,
            frames: 20,
            seed: 0,
            aa: false,
            max_bounces: 8,
            exposure: 0.0,
            camera: None,
            camera_path: None,
            progressive: true,
            save_every: 0,
            out_dir: None,
            validate: false,
            device_index: None,
            tracing: None,
            progress: false,
            vpls_direct: 100_000,
            vpls_indirect: 100_000,
            gi: true,
            photon_min_bounces: 0,
            photon_max_bounces: 7,
            dump_vpls: None,
            dump_passes: None,
            check_finite: false,
            renderdoc_capture: None,
            view: View::Final,
            vpl_radius: None,
            candidates: 32,
            candidate_source: CandidateSource::Uniform,
            presample: default_presample(),
            grid: GridSettings::default(),
            fuse_passes: None,
            workgroup: default_workgroup(),
            restir: RestirSettings::default(),
            attenuation: Attenuation::Yuksel,
            yuksel_radius: None,
            yuksel_spacings: None,
            yuksel_knn: None,
            textures: true,
            merge_blas: default_merge_blas(),
            compensate: false,
        }
    }
}

fn default_merge_blas() -> u32 {
    crate::vk::accel::MERGE_MAX_TRIANGLES
}

fn default_presample() -> bool {
    true
}

/// The ReGIR grid (`regir_build`; shaders/restir/regir.glsl): cells over the scene's bounds, each
/// holding entries drawn by RIS with a target bounding every receiver in the cell; a pixel takes
/// `candidates` of its `--candidates` from its cell, the rest from the source pdf, weighted by the
/// balance heuristic (unbiased either way).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GridSettings {
    /// Candidates per pixel from the grid (`--grid-candidates`; 0: no grid).
    pub candidates: u32,
    /// Cells per axis (`--grid-cells`).
    pub cells: u32,
    /// Entries per cell (`--grid-entries`, a multiple of 64).
    pub entries: u32,
    /// Source-pdf candidates behind each entry (`--grid-entry-candidates`).
    pub entry_candidates: u32,
    /// Balance-heuristic weights between the grid and the source pdf (`--grid-balance`); off:
    /// constant 1/M weights, unbiased through the cell target's coverage alone.
    pub balance: bool,
}

impl Default for GridSettings {
    fn default() -> Self {
        Self { candidates: 0, cells: 16, entries: 64, entry_candidates: 8, balance: true }
    }
}

/// Most cells per axis of the ReGIR grid (`--grid-cells`).
pub const MAX_GRID_CELLS: u32 = 64;

/// 8×8: a 64-invocation workgroup (a warp or wavefront pair on GPUs; eight 8-lane SIMD steps on
/// lavapipe), the size RTXDI and Bevy Solari use for their per-pixel passes.
pub const DEFAULT_WORKGROUP: [u32; 2] = [8, 8];

fn default_workgroup() -> [u32; 2] {
    DEFAULT_WORKGROUP
}

/// Parses `--workgroup WxH` (e.g. `8x8`, `16x4`): both sides 1..=1024 and at most 1024
/// invocations (Vulkan's guaranteed minimum of maxComputeWorkGroupInvocations is 128; the device's
/// own limit is checked when the passes are built).
pub fn parse_workgroup(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X', '×'])
        .ok_or_else(|| format!("'{s}': expected WIDTHxHEIGHT, like 8x8"))?;
    let side = |v: &str| -> Result<u32, String> {
        v.trim().parse::<u32>().map_err(|e| format!("'{s}': '{v}' is not a whole number ({e})"))
    };
    let size = [side(w)?, side(h)?];
    check_workgroup(size).map_err(|e| format!("'{s}': {e}"))?;
    Ok(size)
}

/// The bounds [`parse_workgroup`] documents, also checked by [`RenderSettings::validate`] for
/// settings built in code (a side of 0 would divide by zero when dispatching).
pub fn check_workgroup(size: [u32; 2]) -> Result<(), String> {
    if let Some(n) = size.iter().find(|&&n| n == 0 || n > 1024) {
        return Err(format!("each side must be 1 to 1024, not {n}"));
    }
    if size[0] * size[1] > 1024 {
        return Err(format!("{} invocations per workgroup, more than 1024", size[0] * size[1]));
    }
    Ok(())
}

/// Largest image side accepted (keeps per-pixel buffers well inside 32-bit indexing).
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// The most bounces a photon path may make (`--photon-max-bounces`).
pub const MAX_PHOTON_BOUNCES: u32 = 1024;

/// An on/off environment variable: 1, true, yes or on; 0, false, no or off (any case); unset or
/// empty, `default`. Any other value is an error naming the variable (`true` was once taken for
/// off, and `OFF` left the pipeline cache on, without a word). `RESTIR_VPL_VALIDATE` and
/// `RESTIR_VPL_PIPELINE_CACHE` are read through it.
pub fn env_switch(name: &str, default: bool) -> anyhow::Result<bool> {
    let refused = |v: &dyn std::fmt::Debug| anyhow::anyhow!("{name}={v:?}: expected 1 or 0 (true/false, yes/no, on/off)");
    match std::env::var(name) {
        Err(std::env::VarError::NotPresent) => Ok(default),
        Err(std::env::VarError::NotUnicode(v)) => Err(refused(&v)),
        Ok(v) => match v.to_ascii_lowercase().as_str() {
            "" => Ok(default),
            "1" | "true" | "yes" | "on" => Ok(true),
            "0" | "false" | "no" | "off" => Ok(false),
            _ => Err(refused(&v)),
        },
    }
}

impl RenderSettings {
    /// Whether ReSTIR's passes are fused: `--fuse-passes on|off`, fused when not given (None).
    pub fn fuses_passes(&self) -> bool {
        self.fuse_passes.unwrap_or(true)
    }

    /// Of the command-line flags `given` (clap ids: the field names of the CLI's render arguments,
    /// e.g. "spatial_neighbours"), those that this run never reads, each with why: e.g.
    /// `--candidates` in `--mode pt`. A headless run or a reference warns about them (a value that
    /// silently does nothing misleads a measurement); the window does not, since a key may switch
    /// it to a mode that reads them.
    pub fn unused_flags(&self, given: &[&str]) -> Vec<String> {
        let flag = |id: &str| format!("--{}", id.replace('_', "-"));
        let mode = self.mode.name();
        let mut out = Vec::new();
        for &id in given {
            let why = match id {
                "max_bounces" if self.mode != Mode::Pt => {
                    format!("it sets the path tracer's depth, and --mode {mode} shades with VPLs (their paths: --photon-max-bounces)")
                }
                "vpls_direct" | "vpls_indirect" | "no_gi" | "photon_min_bounces" | "photon_max_bounces" if !self.needs_vpls() => {
                    "it shapes the VPL set, and --mode pt traces no VPLs".to_string()
                }
                "attenuation" | "yuksel_radius" | "yuksel_spacings" | "yuksel_knn" | "compensate" if !self.mode.uses_vpls() => {
                    "it shapes how VPLs shade, and --mode pt does not shade with VPLs".to_string()
                }
                "candidates" | "candidate_source" | "presample" | "grid_candidates" | "grid_cells" | "grid_entries" | "grid_entry_candidates" | "grid_balance"
                    if !matches!(self.mode, Mode::Ris | Mode::Restir) =>
                {
                    format!("it sets the RIS candidates of --mode ris and restir, not of --mode {mode}")
                }
                "temporal" | "mcap" | "spatial_neighbours" | "spatial_radius" | "spatial_passes" | "normal_threshold"
                | "depth_threshold" | "bias" | "boiling_filter" | "initial_visibility" | "fuse_passes" | "moving_candidates"
                | "moving_neighbours"
                    if self.mode != Mode::Restir =>
                {
                    format!("it sets ReSTIR's reuse, and --mode {mode} reuses no reservoirs")
                }
                "mcap" | "boiling_filter" if self.mode == Mode::Restir && !self.restir.temporal => {
                    "it sets temporal reuse, which --temporal off turns off".to_string()
                }
                "moving_candidates" | "moving_neighbours" if self.mode == Mode::Restir && !self.restir.temporal => {
                    "it sets the frames whose temporal reuse has history, and --temporal off has none".to_string()
                }
                "moving_candidates" | "moving_neighbours" if self.mode == Mode::Restir && self.progressive && self.camera_path.is_none() => {
                    "it sets the frames displayed alone (--progressive off or --camera-path), and this run accumulates one still camera's".to_string()
                }
                "moving_neighbours" if self.mode == Mode::Restir && !self.reuses_spatially() => {
                    "it sets spatial reuse, which --spatial-passes 0 or --spatial-neighbours 0 turns off".to_string()
                }
                // (Both set to 0 is the user turning spatial reuse off twice: not worth a word.)
                "spatial_radius" | "spatial_neighbours"
                    if self.mode == Mode::Restir
                        && self.restir.spatial_passes == 0
                        && (id == "spatial_radius" || self.restir.spatial_neighbours > 0) =>
                {
                    "it sets spatial reuse, which --spatial-passes 0 turns off".to_string()
                }
                "spatial_radius" | "spatial_passes"
                    if self.mode == Mode::Restir
                        && self.restir.spatial_neighbours == 0
                        && (id == "spatial_radius" || self.restir.spatial_passes > 0) =>
                {
                    "it sets spatial reuse, which --spatial-neighbours 0 turns off".to_string()
                }
                // (--bias still decides whether the shade pass re-traces a shadow ray after
                // --initial-visibility, and --view motion reads the thresholds.)
                "normal_threshold" | "depth_threshold" | "fuse_passes"
                    if self.mode == Mode::Restir
                        && !self.restir.temporal
                        && !self.reuses_spatially()
                        && (id == "fuse_passes" || self.view != View::Motion) =>
                {
                    "it sets reservoir reuse, and with --temporal off and no spatial reuse there is none".to_string()
                }
                "grid_cells" | "grid_entries" | "grid_entry_candidates" | "grid_balance" if self.grid.candidates == 0 => {
                    "it shapes the ReGIR grid, and --grid-candidates 0 uses none".to_string()
                }
                // (What the pass's first ray carries for this view decides whether it runs.)
                "compensate" if self.view != View::Vpls && crate::renderer::compensate_first_hop(self.view, self.gi) == 0 => {
                    if self.view.shows_reservoirs() {
                        format!("--view {} shows reservoirs, which compensation does not change", self.view.name())
                    } else {
                        format!("--view {} with --no-gi shows no light that compensation could add to", self.view.name())
                    }
                }
                "vpl_radius" if self.view != View::Vpls => "it sets the spheres of --view vpls".to_string(),
                "progressive" if self.frames == 1 => {
                    "it sets whether frames accumulate, and --frames 1 renders one either way".to_string()
                }
                "vpls_indirect" | "photon_min_bounces" | "photon_max_bounces" if !self.gi => {
                    "it shapes the indirect VPLs, and --no-gi traces none".to_string()
                }
                "max_bounces" | "attenuation" | "yuksel_radius" | "yuksel_spacings" | "yuksel_knn" | "compensate" | "candidates" | "candidate_source"
                | "presample" | "grid_candidates" | "grid_cells" | "grid_entries" | "grid_entry_candidates" | "grid_balance" | "temporal" | "mcap" | "spatial_neighbours" | "spatial_radius" | "spatial_passes" | "normal_threshold"
                | "depth_threshold" | "bias" | "boiling_filter" | "initial_visibility" | "fuse_passes" | "moving_candidates"
                | "moving_neighbours"
                    if self.view == View::Vpls =>
                {
                    "--view vpls draws the VPLs instead of shading with them".to_string()
                }
                _ => continue,
            };
            out.push(format!("{} has no effect here: {why}", flag(id)));
        }
        out
    }

    /// (RIS candidates, spatial neighbours) of a ReSTIR frame displayed alone while temporal reuse
    /// has history ([`RestirSettings::moving_candidates`], [`RestirSettings::moving_neighbours`]):
    /// never more than the still camera's, never fewer candidates than the grid's. Without spatial
    /// reuse the neighbours are the still camera's (none are drawn either way: such a frame read
    /// as "moving" in the summary and the overlay when only --moving-neighbours differed).
    pub fn moving_sampling(&self) -> (u32, u32) {
        let r = &self.restir;
        let candidates = match r.moving_candidates {
            0 => self.candidates,
            m => m.min(self.candidates).max(self.grid.candidates).max(1),
        };
        let neighbours = match r.moving_neighbours {
            0 => r.spatial_neighbours,
            _ if !self.reuses_spatially() => r.spatial_neighbours,
            k => k.min(r.spatial_neighbours),
        };
        (candidates, neighbours)
    }

    /// Warnings for the flags in `given` (clap ids, as [`Self::unused_flags`] takes them) whose
    /// value is used only in part: `--moving-candidates` and `--moving-neighbours` above the still
    /// camera's counts (or candidates below the grid's), which [`Self::moving_sampling`] bounds;
    /// and values that leave a part of the reuse almost nothing to do: `--spatial-radius` past the
    /// image's diagonal, `--mcap 0`. The summary keeps the values given; the warning says what a
    /// frame does.
    pub fn bounded_flags(&self, given: &[&str]) -> Vec<String> {
        let mut out = Vec::new();
        if self.mode != Mode::Restir || self.view == View::Vpls {
            return out; // unused_flags names them
        }
        let r = &self.restir;
        let diagonal = f64::from(self.width).hypot(f64::from(self.height));
        if given.contains(&"spatial_radius") && self.reuses_spatially() && f64::from(r.spatial_radius_px(self.width)) > diagonal {
            // (Neighbours are drawn in the disc and those off the image dropped: at 32768 px on a
            // 32 px image the run rendered bit for bit what --spatial-passes 0 renders.)
            out.push(format!(
                "--spatial-radius {}: past the image's diagonal ({diagonal:.0} px), so nearly every neighbour drawn falls off the image and spatial reuse merges almost nothing",
                r.spatial_radius_px(self.width)
            ));
        }
        if !r.temporal {
            return out;
        }
        let (candidates, neighbours) = self.moving_sampling();
        if given.contains(&"moving_candidates") && r.moving_candidates > 0 && candidates != r.moving_candidates {
            out.push(format!(
                "--moving-candidates {}: a frame displayed alone draws {candidates} (at most --candidates {}, at least \
                 --grid-candidates {})",
                r.moving_candidates, self.candidates, self.grid.candidates
            ));
        }
        if given.contains(&"mcap") && r.mcap == 0.0 {
            // (A stress run found it rendering bit for bit what --temporal off renders.)
            out.push("--mcap 0 gives the history no confidence: temporal reuse merges nothing, as with --temporal off".to_string());
        }
        if given.contains(&"moving_neighbours") && self.reuses_spatially() && r.moving_neighbours > 0 && neighbours != r.moving_neighbours {
            out.push(format!(
                "--moving-neighbours {}: a frame displayed alone reuses {neighbours} (at most --spatial-neighbours {})",
                r.moving_neighbours, r.spatial_neighbours
            ));
        }
        out
    }

    /// Warnings for settings that make a run biased although its reuse is unbiased: the boiling
    /// filter drops reservoirs (their light goes), whatever `--bias` says.
    pub fn bias_warnings(&self) -> Vec<String> {
        let filters = self.mode == Mode::Restir && self.restir.temporal && self.view != View::Vpls && self.restir.boiling_filter > 0.0;
        if filters && self.restir.bias == Bias::Unbiased {
            vec![format!(
                "--boiling-filter {}: the filter drops reservoirs, so this run is biased (darker where it acts) \
                 although --bias unbiased keeps the reuse itself unbiased",
                self.restir.boiling_filter
            )]
        } else {
            Vec::new()
        }
    }

    /// Whether ReSTIR's settings ask for spatial reuse (passes and neighbours both above 0).
    pub fn reuses_spatially(&self) -> bool {
        self.restir.spatial_passes > 0 && self.restir.spatial_neighbours > 0
    }

    pub fn needs_vpls(&self) -> bool {
        self.dump_vpls.is_some() || self.view == View::Vpls || self.mode.uses_vpls()
    }

    /// Whether `vpl_presample` runs: ris and restir with `--presample on` (uniform sampling reads
    /// one VPL per pixel: a tile would cost more than it saves).
    pub fn presamples(&self) -> bool {
        self.presample && matches!(self.mode, Mode::Ris | Mode::Restir)
    }

    /// Whether `regir_build` runs: ris and restir with `--grid-candidates` above 0.
    pub fn uses_grid(&self) -> bool {
        self.grid.candidates > 0 && matches!(self.mode, Mode::Ris | Mode::Restir)
    }

    /// RIS candidates the restir_initial pass draws: one for uniform sampling.
    pub fn initial_candidates(&self) -> u32 {
        match self.mode {
            Mode::Uniform => 1,
            _ => self.candidates,
        }
    }

    /// The photon pass's settings.
    pub fn photon_settings(&self) -> PhotonSettings {
        PhotonSettings {
            direct: self.vpls_direct,
            indirect: if self.gi { self.vpls_indirect } else { 0 },
            min_bounces: self.photon_min_bounces,
            max_bounces: self.photon_max_bounces,
            seed: self.seed,
        }
    }

    /// The parsed `--dump-passes` selection.
    pub fn dump_passes_selection(&self) -> anyhow::Result<Option<crate::dump::FrameSelection>> {
        self.dump_passes
            .as_deref()
            .map(|s| crate::dump::FrameSelection::parse(s).map_err(|e| anyhow::anyhow!("--dump-passes {e}")))
            .transpose()
    }

    /// Checks values the CLI cannot express as types; names the flag at fault.
    pub fn validate(&self) -> anyhow::Result<()> {
        use anyhow::bail;
        if self.compensate && self.attenuation == Attenuation::InverseSquare {
            bail!(
                "--compensate: the inverse-square kernel removes no energy, there is nothing to compensate; \
                 use it with --attenuation yuksel"
            );
        }
        if let Err(e) = check_workgroup(self.workgroup) {
            bail!("--workgroup {}x{}: {e}", self.workgroup[0], self.workgroup[1]);
        }
        if !(0.0..=1.0).contains(&self.restir.boiling_filter) {
            bail!("--boiling-filter {}: expected a strength in [0, 1] (0: off)", self.restir.boiling_filter);
        }
        if let Some(n) = self.renderdoc_capture {
            if n >= self.frames {
                bail!("--renderdoc-capture {n}: the run renders frames 0..{} (--frames {})", self.frames.saturating_sub(1), self.frames);
            }
        }
        if let Some(ply) = &self.dump_vpls {
            // Refused before the photon pass runs, not after it.
            if ply.is_dir() {
                bail!("--dump-vpls {}: is a directory; name a file to write the VPLs to (e.g. vpls.ply)", ply.display());
            }
            // The run's inputs, and the files it writes to --out after the PLY.
            let mut taken = vec![("the scene", self.scene.clone())];
            taken.extend(self.camera_path.clone().map(|p| ("the --camera-path", p)));
            if let Some(dir) = &self.out_dir {
                taken.extend(crate::headless::RUN_OUTPUT_FILES.map(|f| ("an output of --out", dir.join(f))));
                // --save-every's snapshots (--dump-passes' folder is checked below).
                // (By name: one path per snapshot would be a million for --frames 1000000.)
                let snapshot = ply
                    .file_name()
                    .and_then(|n| n.to_str())
                    .and_then(|n| n.strip_prefix("accum_")?.strip_suffix(".exr")?.parse::<u32>().ok())
                    .filter(|&f| self.save_every > 0 && f > 0 && f <= self.frames && f % self.save_every == 0);
                if let Some(f) = snapshot {
                    taken.push(("a --save-every output", dir.join(crate::headless::snapshot_file(f))));
                }
                if self.dump_passes.is_some() && crate::output::is_within(ply, &dir.join("passes")) {
                    // The dump removes an earlier run's frames there and writes its own files.
                    bail!(
                        "--dump-vpls {}: is inside --dump-passes' folder {}, whose files the dump removes and writes; \
                         write the VPLs elsewhere (the dump keeps its own copy, passes/vpls.ply)",
                        ply.display(),
                        dir.join("passes").display()
                    );
                }
            }
            if let Some((what, p)) = taken.iter().find(|(_, p)| crate::output::same_file(ply, p)) {
                bail!("--dump-vpls {}: is also {what} ({}); write the VPLs to another file", ply.display(), p.display());
            }
        }
        let dump = self.dump_passes_selection()?;
        if dump.is_some() && self.out_dir.is_none() {
            bail!("--dump-passes writes to OUT/passes: give --out");
        }
        // (--frames 0 is reported below, under its own name.)
        if let (Some(crate::dump::FrameSelection::List(frames, _)), true) = (&dump, self.frames > 0) {
            if let Some(n) = frames.iter().find(|&&n| n >= self.frames) {
                bail!(
                    "--dump-passes {}: frame {n} is beyond the run's frames 0..{} (--frames {})",
                    self.dump_passes.as_deref().unwrap_or_default(),
                    self.frames.saturating_sub(1),
                    self.frames
                );
            }
        }
        if self.width == 0 || self.width > MAX_IMAGE_SIDE {
            bail!("--width {}: must be between 1 and {MAX_IMAGE_SIDE}", self.width);
        }
        if self.height == 0 || self.height > MAX_IMAGE_SIDE {
            bail!("--height {}: must be between 1 and {MAX_IMAGE_SIDE}", self.height);
        }
        if self.frames == 0 {
            bail!("--frames 0: at least one frame is needed");
        }
        if self.max_bounces < -1 {
            bail!("--max-bounces {}: use -1 for unbounded, or 0 and up", self.max_bounces);
        }
        if !self.exposure.is_finite() {
            bail!("--exposure must be a finite number");
        }
        if self.vpls_direct == 0 && self.gi {
            bail!("--vpls-direct 0: direct VPLs replace the area and point lights, so the image would lack direct light; \
                   use at least 1 (or --no-gi for an empty VPL set)");
        }
        if self.gi && self.vpls_indirect == 0 {
            bail!("--vpls-indirect 0 with global illumination on: pass --no-gi to turn indirect VPLs off");
        }
        if self.photon_max_bounces == 0 {
            bail!("--photon-max-bounces 0: photons need at least one bounce (use --no-gi for no indirect light)");
        }
        if self.photon_max_bounces > MAX_PHOTON_BOUNCES {
            // The VPL buffer keeps room for 1024 paths of this length; beyond a few dozen bounces
            // the roulette ends nearly every path anyway.
            bail!("--photon-max-bounces {}: at most {MAX_PHOTON_BOUNCES}", self.photon_max_bounces);
        }
        if self.photon_min_bounces > self.photon_max_bounces {
            bail!(
                "--photon-min-bounces {} exceeds --photon-max-bounces {}",
                self.photon_min_bounces,
                self.photon_max_bounces
            );
        }
        if self.candidates == 0 || self.candidates > 1024 {
            bail!("--candidates {}: must be between 1 and 1024", self.candidates);
        }
        let g = &self.grid;
        if g.candidates > self.candidates {
            bail!("--grid-candidates {}: at most --candidates ({}), of which they are a part", g.candidates, self.candidates);
        }
        if g.cells == 0 || g.cells > MAX_GRID_CELLS {
            bail!("--grid-cells {}: must be between 1 and {MAX_GRID_CELLS}", g.cells);
        }
        if g.entries == 0 || !g.entries.is_multiple_of(crate::gpu_types::REGIR_WORKGROUP) || g.entries > 4096 {
            bail!("--grid-entries {}: must be a multiple of {} between {} and 4096", g.entries, crate::gpu_types::REGIR_WORKGROUP, crate::gpu_types::REGIR_WORKGROUP);
        }
        if g.entry_candidates == 0 || g.entry_candidates > 1024 {
            bail!("--grid-entry-candidates {}: must be between 1 and 1024", g.entry_candidates);
        }
        let r = &self.restir;
        if !(r.mcap >= 0.0 && r.mcap.is_finite()) {
            bail!("--mcap {}: must be a finite number >= 0", r.mcap);
        }
        if r.spatial_neighbours > crate::gpu_types::MAX_SPATIAL_NEIGHBOURS {
            bail!(
                "--spatial-neighbours {}: at most {}",
                r.spatial_neighbours,
                crate::gpu_types::MAX_SPATIAL_NEIGHBOURS
            );
        }
        if r.moving_neighbours > crate::gpu_types::MAX_SPATIAL_NEIGHBOURS {
            bail!("--moving-neighbours {}: at most {}", r.moving_neighbours, crate::gpu_types::MAX_SPATIAL_NEIGHBOURS);
        }
        if r.moving_candidates > 1024 {
            bail!("--moving-candidates {}: at most 1024 (0: as --candidates)", r.moving_candidates);
        }
        if let Some(radius) = r.spatial_radius {
            // At most twice the largest image side: a disc that large already reaches every pixel,
            // and past 2^31 the shader's conversion of its offsets to integers is undefined.
            let most = 2.0 * MAX_IMAGE_SIDE as f32;
            if !(1.0..=most).contains(&radius) {
                bail!("--spatial-radius {radius:?}: must be a number of pixels from 1 to {most}");
            }
        }
        if r.spatial_passes > 8 {
            bail!("--spatial-passes {}: at most 8", r.spatial_passes);
        }
        if !(-1.0..=1.0).contains(&r.normal_threshold) {
            bail!("--normal-threshold {}: a cosine, must be in [-1, 1]", r.normal_threshold);
        }
        if !(r.depth_threshold >= 0.0 && r.depth_threshold.is_finite()) {
            bail!("--depth-threshold {}: a relative depth difference, must be >= 0", r.depth_threshold);
        }
        if let Some(y) = self.yuksel_radius {
            if !(y > 0.0 && y <= MAX_YUKSEL_RADIUS) {
                bail!("--yuksel-radius {y}: must be a positive number up to {MAX_YUKSEL_RADIUS:e} (scene units; the shaders square it in 32-bit floats)");
            }
            if self.attenuation != Attenuation::Yuksel {
                bail!("--yuksel-radius is only used with --attenuation yuksel");
            }
        }
        if let Some(m) = self.yuksel_spacings {
            if !(m > 0.0 && m.is_finite()) {
                bail!("--yuksel-spacings {m}: must be a positive finite number (a multiple of the VPL spacing)");
            }
        }
        if let Some(k) = self.yuksel_knn {
            if !(1..=MAX_YUKSEL_KNN).contains(&k) {
                bail!("--yuksel-knn {k}: must be between 1 and {MAX_YUKSEL_KNN} nearest VPLs");
            }
            if self.compensate {
                bail!("--yuksel-knn with --compensate: the compensation's residual weight needs one radius for every VPL; \
                       drop one of them");
            }
        }
        if self.yuksel_knn.is_some() || self.yuksel_spacings.is_some() {
            let flag = if self.yuksel_knn.is_some() { "--yuksel-knn" } else { "--yuksel-spacings" };
            if self.attenuation != Attenuation::Yuksel {
                bail!("{flag} is only used with --attenuation yuksel");
            }
            if self.yuksel_radius.is_some() {
                bail!("{flag} and --yuksel-radius both set Yuksel's radius: give one of them");
            }
        }
        if self.view.shows_reservoirs() && !self.mode.uses_reservoirs() {
            bail!("--view {}: mode {} has no reservoirs (use --mode uniform, ris or restir)", self.view.name(), self.mode.name());
        }
        if self.mode == Mode::Pt && matches!(self.view, View::Direct | View::Indirect) {
            bail!("--view {}: splits the VPL image; use a VPL mode (--mode uniform, ris, restir or bruteforce)", self.view.name());
        }
        if let Some(r) = self.vpl_radius {
            if !(r > 0.0 && r.is_finite()) {
                bail!("--vpl-radius {r}: must be a positive finite number (scene units)");
            }
        }
        if self.camera.is_some() && self.camera_path.is_some() {
            bail!("--camera-path and --eye/--target both set the camera: give one of them");
        }
        if let Some(c) = &self.camera {
            if !crate::camera::fov_ok(c.yfov_degrees) {
                bail!("--fov {:?}: must be in [{}, 180) degrees", c.yfov_degrees, crate::camera::MIN_FOV_DEGREES);
            }
            // As a camera path's keyframes are checked (camera::view_problem).
            use crate::camera::ViewProblem;
            match crate::camera::view_problem(c.eye, c.target, c.up) {
                Some(ViewProblem::SamePoint) => bail!("--eye and --target must differ"),
                Some(ViewProblem::Distance(_)) => {
                    bail!("--eye {} --target {}: their distance must be between 1e-18 and 1e18 (32-bit floats)", c.eye, c.target)
                }
                Some(ViewProblem::UpParallel) => {
                    bail!("--up {}: must be non-zero and not parallel to the view direction (--target minus --eye)", c.up)
                }
                // (--eye 3e38,0,0 rendered black.)
                Some(ViewProblem::FarFromOrigin { target }) => {
                    let (flag, p) = if target { ("--target", c.target) } else { ("--eye", c.eye) };
                    bail!(
                        "{flag} {:?},{:?},{:?}: must be within {:e} of the origin (32-bit floats)",
                        p.x,
                        p.y,
                        p.z,
                        crate::camera::MAX_CAMERA_COORDINATE
                    );
                }
                None => {}
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fuse_passes_fuses_unless_told_off() {
        let with = |fuse_passes| RenderSettings { fuse_passes, ..RenderSettings::default() };
        assert_eq!(RenderSettings::default().fuse_passes, None, "not given is the default");
        assert_eq!([with(None), with(Some(true)), with(Some(false))].map(|s| s.fuses_passes()), [true, true, false]);
    }

    /// The boiling filter with unbiased reuse is said to bias the run; with biased reuse, or off,
    /// or where it never runs (no temporal reuse), nothing is said.
    #[test]
    fn the_boiling_filter_is_said_to_bias_an_unbiased_run() {
        let with = |bias, boiling_filter, temporal| RenderSettings {
            mode: Mode::Restir,
            restir: RestirSettings { bias, boiling_filter, temporal, ..Default::default() },
            ..RenderSettings::default()
        };
        let w = with(Bias::Unbiased, 0.5, true).bias_warnings();
        assert!(w.len() == 1 && w[0].starts_with("--boiling-filter 0.5:") && w[0].contains("biased"), "{w:?}");
        for quiet in [with(Bias::Biased, 0.5, true), with(Bias::Unbiased, 0.0, true), with(Bias::Unbiased, 0.5, false)] {
            assert!(quiet.bias_warnings().is_empty());
        }
    }

    #[test]
    fn flags_a_mode_never_reads_are_named_with_why() {
        let with_mode = |mode| RenderSettings { mode, ..RenderSettings::default() };
        let named = |s: &RenderSettings, given: &[&str]| -> Vec<String> {
            s.unused_flags(given).iter().map(|w| w.split(' ').next().unwrap().to_string()).collect()
        };
        let pt = with_mode(Mode::Pt);
        assert_eq!(
            named(&pt, &["max_bounces", "candidates", "spatial_neighbours", "vpls_direct", "compensate", "width", "seed"]),
            ["--candidates", "--spatial-neighbours", "--vpls-direct", "--compensate"]
        );
        // --dump-vpls makes pt trace the VPLs: their flags are read then.
        let pt_dump = RenderSettings { dump_vpls: Some("v.ply".into()), ..pt.clone() };
        assert!(named(&pt_dump, &["vpls_direct", "photon_max_bounces"]).is_empty());
        let restir = with_mode(Mode::Restir);
        assert_eq!(named(&restir, &["max_bounces", "candidates", "spatial_neighbours", "mcap", "vpl_radius"]), ["--max-bounces", "--vpl-radius"]);
        assert_eq!(named(&with_mode(Mode::Uniform), &["candidates", "presample", "mcap"]), ["--candidates", "--presample", "--mcap"]);
        assert_eq!(named(&with_mode(Mode::Ris), &["candidates", "initial_visibility", "fuse_passes"]), ["--initial-visibility", "--fuse-passes"]);
        let w = pt.unused_flags(&["candidates"]);
        assert!(w[0].contains("no effect") && w[0].contains("--mode ris and restir"), "{w:?}");
        // Settings beside the mode: no GI traces no indirect VPLs; --view vpls shades with none.
        let no_gi = RenderSettings { gi: false, ..restir.clone() };
        assert_eq!(
            named(&no_gi, &["no_gi", "vpls_direct", "vpls_indirect", "photon_min_bounces", "photon_max_bounces"]),
            ["--vpls-indirect", "--photon-min-bounces", "--photon-max-bounces"]
        );
        // One frame is the same accumulated or not.
        assert_eq!(named(&RenderSettings { frames: 1, ..restir.clone() }, &["progressive"]), ["--progressive"]);
        assert!(named(&RenderSettings { frames: 2, ..restir.clone() }, &["progressive"]).is_empty());
        let view = RenderSettings { view: View::Vpls, ..restir.clone() };
        assert_eq!(named(&view, &["mcap", "candidates", "compensate", "vpl_radius", "vpls_direct"]), ["--mcap", "--candidates", "--compensate"]);
        assert!(view.unused_flags(&["mcap"])[0].contains("--view vpls draws the VPLs"));
        // The reservoir views show what compensation does not touch (a stress run found their
        // images bit for bit the same with and without it, and no word).
        for v in [View::ReservoirW, View::ReservoirM, View::VplKind, View::Motion] {
            assert_eq!(named(&RenderSettings { view: v, ..restir.clone() }, &["compensate", "mcap"]), ["--compensate"], "{v:?}");
        }
        assert!(named(&restir, &["compensate"]).is_empty());
        assert_eq!(named(&RenderSettings { view: View::Indirect, gi: false, ..restir.clone() }, &["compensate"]), ["--compensate"]);
        assert!(named(&RenderSettings { view: View::Indirect, ..restir.clone() }, &["compensate"]).is_empty());
        // --mcap 0 leaves temporal reuse nothing to merge.
        let mcap0 = RenderSettings { restir: RestirSettings { mcap: 0.0, ..Default::default() }, ..restir.clone() };
        assert!(mcap0.bounded_flags(&["mcap"]).iter().any(|w| w.contains("--mcap 0") && w.contains("--temporal off")), "{:?}", mcap0.bounded_flags(&["mcap"]));
        assert!(restir.bounded_flags(&["mcap"]).is_empty());
        // A spatial radius past the image's diagonal leaves no neighbour on the image.
        let far = RenderSettings { width: 32, height: 32, restir: RestirSettings { spatial_radius: Some(32768.0), ..Default::default() }, ..restir.clone() };
        assert!(far.bounded_flags(&["spatial_radius"]).iter().any(|w| w.contains("--spatial-radius 32768") && w.contains("diagonal (45 px)")), "{:?}", far.bounded_flags(&["spatial_radius"]));
        let near = RenderSettings { restir: RestirSettings { spatial_radius: Some(40.0), ..far.restir }, ..far.clone() };
        assert!(near.bounded_flags(&["spatial_radius"]).is_empty());
        // ReSTIR with parts of its reuse turned off: the flags of the parts that are off.
        let reuse = ["mcap", "boiling_filter", "spatial_radius", "spatial_neighbours", "spatial_passes", "normal_threshold", "bias", "candidates"];
        let no_temporal = RenderSettings { restir: RestirSettings { temporal: false, ..Default::default() }, ..restir.clone() };
        assert_eq!(named(&no_temporal, &reuse), ["--mcap", "--boiling-filter"]);
        let no_spatial = RenderSettings { restir: RestirSettings { spatial_passes: 0, ..Default::default() }, ..restir.clone() };
        assert_eq!(named(&no_spatial, &reuse), ["--spatial-radius", "--spatial-neighbours"]);
        let no_neighbours = RenderSettings { restir: RestirSettings { spatial_neighbours: 0, ..Default::default() }, ..restir.clone() };
        assert_eq!(named(&no_neighbours, &reuse), ["--spatial-radius", "--spatial-passes"]);
        let no_reuse = RenderSettings { restir: RestirSettings { temporal: false, spatial_passes: 0, ..Default::default() }, ..restir.clone() };
        assert_eq!(named(&no_reuse, &reuse), ["--mcap", "--boiling-filter", "--spatial-radius", "--spatial-neighbours", "--normal-threshold"]);
        // --view motion reads the thresholds; spatial reuse turned off by both of its flags is not
        // a contradiction.
        let motion = RenderSettings { view: View::Motion, ..no_reuse.clone() };
        assert_eq!(named(&motion, &["normal_threshold", "depth_threshold", "fuse_passes"]), ["--fuse-passes"]);
        let both_off = RenderSettings { restir: RestirSettings { spatial_passes: 0, spatial_neighbours: 0, ..Default::default() }, ..restir.clone() };
        assert_eq!(named(&both_off, &["spatial_passes", "spatial_neighbours", "spatial_radius"]), ["--spatial-radius"]);
        assert!(named(&restir, &reuse).is_empty());
    }

    #[test]
    fn default_radius_rule_names_its_multiple() {
        let text = radius_rule_text(DEFAULT_RADIUS_SPACINGS, None);
        assert!(text.starts_with(&format!("{DEFAULT_RADIUS_SPACINGS} x ")), "{text}");
        assert!(radius_rule_text(4.0, Some(16)).contains("4 x its local spacing d_16 / sqrt(16)"));
    }

    #[test]
    fn workgroup_bounds_hold_on_the_command_line_and_in_code() {
        assert_eq!(parse_workgroup("16x4"), Ok([16, 4]));
        assert_eq!(parse_workgroup("1×1024"), Ok([1, 1024]));
        for bad in ["0x8", "8x0", "2048x1", "64x32", "8", "8xa"] {
            assert!(parse_workgroup(bad).is_err(), "{bad}");
        }
        // Settings built in code skip the parser; validate() holds them to the same bounds.
        for (size, ok) in [([8, 8], true), ([0, 8], false), ([8, 0], false), ([64, 32], false)] {
            let s = RenderSettings { workgroup: size, ..RenderSettings::default() };
            let r = s.validate();
            assert_eq!(r.is_ok(), ok, "{size:?}");
            if let Err(e) = r {
                assert!(e.to_string().starts_with("--workgroup "), "{e}");
            }
        }
    }

    /// Without --spatial-radius the disc scales with the image width (20 px at 1280, never under
    /// 4 px); a given radius is kept at every width.
    #[test]
    fn spatial_radius_scales_with_width_unless_given() {
        let auto = RestirSettings::default();
        assert_eq!(auto.spatial_radius_px(1280), 20.0);
        assert_eq!(auto.spatial_radius_px(2560), 40.0);
        assert_eq!(auto.spatial_radius_px(512), 8.0);
        assert_eq!(auto.spatial_radius_px(64), 4.0);
        let given = RestirSettings { spatial_radius: Some(7.0), ..auto };
        assert_eq!(given.spatial_radius_px(64), 7.0);
        assert_eq!(given.spatial_radius_px(1920), 7.0);
    }

    #[test]
    fn ordinals_read_as_english() {
        let got: Vec<String> = [1, 2, 3, 4, 11, 12, 13, 21, 22, 101, 111, 256].into_iter().map(ordinal).collect();
        assert_eq!(got, ["1st", "2nd", "3rd", "4th", "11th", "12th", "13th", "21st", "22nd", "101st", "111th", "256th"]);
    }

    /// A frame displayed alone never samples more than the still camera's settings, never fewer
    /// candidates than the grid's, and 0 means the still settings; out-of-range values are refused
    /// naming the flag, and the flags are named where they cannot apply.
    #[test]
    fn moving_sampling_is_bounded_by_the_still_settings() {
        let with = |candidates, grid, spatial_neighbours, moving_candidates, moving_neighbours| RenderSettings {
            mode: Mode::Restir,
            candidates,
            grid: GridSettings { candidates: grid, ..Default::default() },
            restir: RestirSettings { spatial_neighbours, moving_candidates, moving_neighbours, ..Default::default() },
            // Frames displayed alone (a still camera accumulating has none).
            progressive: false,
            ..RenderSettings::default()
        };
        assert_eq!(RenderSettings { mode: Mode::Restir, ..Default::default() }.moving_sampling(), (8, 4));
        assert_eq!(with(32, 0, 8, 0, 0).moving_sampling(), (32, 8));
        assert_eq!(with(8, 0, 2, 16, 4).moving_sampling(), (8, 2));
        assert_eq!(with(32, 24, 8, 16, 4).moving_sampling(), (24, 4));
        // Without spatial reuse only the candidates can differ: --moving-candidates 0 then leaves
        // a frame sampled as a still one's (the renderer counted it as moving).
        let no_spatial = |moving_candidates| {
            let s = with(32, 0, 8, moving_candidates, 4);
            RenderSettings { restir: RestirSettings { spatial_passes: 0, ..s.restir }, ..s }
        };
        assert_eq!(no_spatial(0).moving_sampling(), (32, 8));
        assert_eq!(no_spatial(16).moving_sampling(), (16, 8));
        for (s, flag) in [(with(32, 0, 8, 1025, 4), "--moving-candidates 1025"), (with(32, 0, 8, 16, 33), "--moving-neighbours 33")] {
            let e = s.validate().unwrap_err().to_string();
            assert!(e.starts_with(flag), "{e}");
        }
        let named = |s: &RenderSettings| -> Vec<String> {
            s.unused_flags(&["moving_candidates", "moving_neighbours"]).iter().map(|w| w.split(' ').next().unwrap().to_string()).collect()
        };
        assert!(named(&with(32, 0, 8, 16, 4)).is_empty());
        // A still camera accumulating displays no frame alone (the flags changed nothing, unsaid).
        let still = RenderSettings { progressive: true, ..with(32, 0, 8, 16, 4) };
        assert_eq!(named(&still), ["--moving-candidates", "--moving-neighbours"]);
        assert!(named(&RenderSettings { camera_path: Some("p.json".into()), ..still }).is_empty());
        assert_eq!(named(&RenderSettings { mode: Mode::Ris, ..with(32, 0, 8, 16, 4) }), ["--moving-candidates", "--moving-neighbours"]);
        let no_temporal = with(32, 0, 8, 16, 4);
        let no_temporal = RenderSettings { restir: RestirSettings { temporal: false, ..no_temporal.restir }, ..no_temporal };
        assert_eq!(named(&no_temporal), ["--moving-candidates", "--moving-neighbours"]);
        assert_eq!(named(&with(32, 0, 0, 16, 4)), ["--moving-neighbours"]);
        // Values above the still counts are bounded, and a warning says to what, only for a flag
        // given (the default 8 under --candidates 4 is not the user's word).
        let both = ["moving_candidates", "moving_neighbours"];
        let w = with(32, 0, 8, 64, 20).bounded_flags(&both);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w[0].starts_with("--moving-candidates 64: a frame displayed alone draws 32"), "{w:?}");
        assert!(w[1].starts_with("--moving-neighbours 20: a frame displayed alone reuses 8"), "{w:?}");
        assert!(with(32, 24, 8, 16, 4).bounded_flags(&both)[0].contains("draws 24"));
        assert!(with(4, 0, 8, 8, 4).bounded_flags(&[]).is_empty());
        assert!(with(32, 0, 8, 16, 4).bounded_flags(&both).is_empty());
        assert!(with(32, 0, 8, 0, 0).bounded_flags(&both).is_empty());
    }

    /// `--view vpls` draws the VPL set whatever the mode: the path tracer's depth does nothing
    /// there either (it was not named).
    #[test]
    fn max_bounces_is_named_under_view_vpls() {
        let s = RenderSettings { mode: Mode::Pt, view: View::Vpls, ..Default::default() };
        let w = s.unused_flags(&["max_bounces"]);
        assert!(w.len() == 1 && w[0].starts_with("--max-bounces has no effect here: --view vpls"), "{w:?}");
        assert!(RenderSettings { mode: Mode::Pt, ..Default::default() }.unused_flags(&["max_bounces"]).is_empty());
    }
}
