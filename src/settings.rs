//! Render settings shared by the CLI, the library API and the summary.

use std::path::PathBuf;

use glam::Vec3;
use serde::Serialize;

/// What each pixel estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Path tracing with next-event estimation and MIS: the ground truth.
    Pt,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Pt => "pt",
        }
    }
}

/// What the output image shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum View {
    /// The mode's radiance estimate.
    #[default]
    Final,
    /// Debug: diffuse-shaded scene with every VPL as a sphere (blue direct, red indirect).
    Vpls,
}

/// A camera given on the command line; replaces the scene's camera.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CameraOverride {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub yfov_degrees: f32,
}

#[derive(Clone, Debug, Serialize)]
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
    /// Write `accum_NNNN.exr` every K frames (0: never).
    pub save_every: u32,
    pub out_dir: Option<PathBuf>,
    pub validate: bool,
    pub device_index: Option<usize>,
    pub verbose: bool,
    /// Show a progress bar (only on a terminal, and only for runs over a second).
    pub progress: bool,
    /// Direct VPLs (they replace the area lights).
    pub vpls_direct: u32,
    /// Target number of indirect VPLs from photon paths.
    pub vpls_indirect: u32,
    /// Global illumination: indirect VPLs on (off: `--no-gi`).
    pub gi: bool,
    /// Russian roulette starts after this many photon bounces.
    pub photon_min_bounces: u32,
    pub photon_max_bounces: u32,
    /// Write the VPLs as a PLY point cloud here.
    pub dump_vpls: Option<PathBuf>,
    pub view: View,
    /// VPL sphere radius for `--view vpls` (scene units); default 0.25% of the scene's diagonal.
    pub vpl_radius: Option<f32>,
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
            save_every: 0,
            out_dir: None,
            validate: false,
            device_index: None,
            verbose: false,
            progress: false,
            vpls_direct: 100_000,
            vpls_indirect: 100_000,
            gi: true,
            photon_min_bounces: 0,
            photon_max_bounces: 8,
            dump_vpls: None,
            view: View::Final,
            vpl_radius: None,
        }
    }
}

/// Largest image side accepted (keeps per-pixel buffers well inside 32-bit indexing).
pub const MAX_IMAGE_SIDE: u32 = 16384;

impl RenderSettings {
    /// Whether this run needs the VPL set (and so the photon pass).
    pub fn needs_vpls(&self) -> bool {
        self.dump_vpls.is_some() || self.view == View::Vpls
    }

    /// The photon pass's settings.
    pub fn photon_settings(&self) -> crate::passes::PhotonSettings {
        crate::passes::PhotonSettings {
            direct: self.vpls_direct,
            indirect: if self.gi { self.vpls_indirect } else { 0 },
            min_bounces: self.photon_min_bounces,
            max_bounces: self.photon_max_bounces,
            seed: self.seed,
        }
    }

    /// Checks values the CLI cannot express as types; names the flag at fault.
    pub fn validate(&self) -> anyhow::Result<()> {
        use anyhow::bail;
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
            bail!("--vpls-direct 0: direct VPLs replace the area lights, so the image would lack direct light; \
                   use at least 1 (or --no-gi for an empty VPL set)");
        }
        if self.gi && self.vpls_indirect == 0 {
            bail!("--vpls-indirect 0 with global illumination on: pass --no-gi to turn indirect VPLs off");
        }
        if self.photon_max_bounces == 0 {
            bail!("--photon-max-bounces 0: photons need at least one bounce (use --no-gi for no indirect light)");
        }
        if self.photon_min_bounces > self.photon_max_bounces {
            bail!(
                "--photon-min-bounces {} exceeds --photon-max-bounces {}",
                self.photon_min_bounces,
                self.photon_max_bounces
            );
        }
        if let Some(r) = self.vpl_radius {
            if !(r > 0.0 && r.is_finite()) {
                bail!("--vpl-radius {r}: must be a positive number (scene units)");
            }
        }
        if let Some(c) = &self.camera {
            if !(c.yfov_degrees > 0.0 && c.yfov_degrees < 180.0) {
                bail!("--fov {}: must be in (0, 180) degrees", c.yfov_degrees);
            }
            let f = c.target - c.eye;
            if !f.is_finite() || f.length_squared() == 0.0 {
                bail!("--eye and --target must differ");
            }
            if f.cross(c.up).length_squared() <= 1e-12 * f.length_squared() * c.up.length_squared().max(1e-30) {
                bail!("--up must not be parallel to the view direction (--target minus --eye)");
            }
        }
        Ok(())
    }
}
