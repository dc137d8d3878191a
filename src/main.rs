//! The `restir-vpl` command line.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::Parser;
use glam::Vec3;

use restir_vpl::settings::{
    Attenuation, Bias, CameraOverride, CandidateSource, Mode, RenderSettings, RestirSettings, View,
};
use restir_vpl::vk::NoRayQueryDevice;

/// GPU global illumination: photon-traced VPLs + ReSTIR DI on Vulkan ray queries, with a path-traced
/// ground truth.
#[derive(Debug, Parser)]
#[command(name = "restir-vpl", version, about, args_conflicts_with_subcommands = true, args_override_self = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Render without a window and write images to --out.
    #[arg(long)]
    headless: bool,
    /// glTF 2.0 scene (.gltf or .glb).
    #[arg(long, default_value = "scenes/cornell_box.gltf")]
    scene: PathBuf,
    /// Estimator.
    #[arg(long, value_enum, default_value = "pt")]
    mode: Mode,
    /// Frames to render and average.
    #[arg(long, default_value_t = 20)]
    frames: u32,
    #[arg(long, default_value_t = 512)]
    width: u32,
    #[arg(long, default_value_t = 512)]
    height: u32,
    /// Output directory (final.exr, final.png, accum_NNNN.exr, summary.json).
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Also write accum_NNNN.exr every K frames.
    #[arg(long, default_value_t = 0, value_name = "K")]
    save_every: u32,
    /// Random seed; the same seed gives the same image.
    #[arg(long, default_value_t = 0)]
    seed: u32,
    /// Jitter primary rays inside the pixel (box filter) instead of tracing pixel centres.
    #[arg(long)]
    aa: bool,
    /// Path-tracer bounces (-1: unbounded, Russian roulette only).
    #[arg(long, default_value_t = 8, allow_negative_numbers = true)]
    max_bounces: i32,
    /// Exposure of the PNG preview in EV.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Camera position "x,y,z" (overrides the scene camera; needs --target).
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true)]
    eye: Option<Vec3>,
    /// Camera target "x,y,z".
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true)]
    target: Option<Vec3>,
    /// Camera up "x,y,z".
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true, default_value = "0,1,0")]
    up: Vec3,
    /// Vertical field of view in degrees (with --eye/--target; default 45, or the scene camera's).
    #[arg(long)]
    fov: Option<f32>,
    /// Direct VPLs (they replace the area lights).
    #[arg(long, default_value_t = 100_000)]
    vpls_direct: u32,
    /// Target number of indirect VPLs from photon paths (the paths traced are counted exactly).
    #[arg(long, default_value_t = 100_000)]
    vpls_indirect: u32,
    /// No global illumination: no indirect VPLs.
    #[arg(long)]
    no_gi: bool,
    /// Photon bounces before Russian roulette starts.
    #[arg(long, default_value_t = 0)]
    photon_min_bounces: u32,
    /// Maximum photon bounces (indirect VPLs per path).
    #[arg(long, default_value_t = 8)]
    photon_max_bounces: u32,
    /// Write the VPLs as a PLY point cloud (opens in MeshLab/Blender).
    #[arg(long, value_name = "FILE.ply")]
    dump_vpls: Option<PathBuf>,
    /// What the image shows: the estimate; the VPLs as spheres (blue direct, red indirect); the
    /// final reservoir's W or M or the kind of VPL it holds; or only direct / only indirect light.
    #[arg(long, value_enum, default_value = "final")]
    view: View,
    /// Sphere radius of `--view vpls` in scene units (default: 0.25% of the scene's diagonal).
    #[arg(long)]
    vpl_radius: Option<f32>,
    /// RIS candidates per pixel (ris and restir).
    #[arg(long, default_value_t = 32)]
    candidates: u32,
    /// Where RIS candidates come from: uniformly over the VPLs, or in proportion to their power.
    #[arg(long, value_enum, default_value = "uniform")]
    candidate_source: CandidateSource,
    /// ReSTIR temporal reuse of the previous frame's reservoirs.
    #[arg(long, value_enum, default_value = "on")]
    temporal: Toggle,
    /// Temporal history confidence cap, in multiples of the current frame's.
    #[arg(long, default_value_t = 20.0)]
    mcap: f32,
    /// ReSTIR spatial neighbours per pass (at most 32).
    #[arg(long, default_value_t = 8)]
    spatial_neighbours: u32,
    /// Radius of the disc spatial neighbours are drawn from (pixels).
    #[arg(long, default_value_t = 20.0)]
    spatial_radius: f32,
    /// Spatial reuse passes per frame.
    #[arg(long, default_value_t = 1)]
    spatial_passes: u32,
    /// Reject spatial neighbours whose shading normals' dot product is below this.
    #[arg(long, default_value_t = 0.9, allow_negative_numbers = true)]
    normal_threshold: f32,
    /// Reject spatial neighbours whose view depth differs by more than this fraction.
    #[arg(long, default_value_t = 0.1)]
    depth_threshold: f32,
    /// ReSTIR reuse: biased (confidence weights, no visibility in the targets) or unbiased
    /// (visibility-aware pairwise MIS; converges to the brute-force sum, more shadow rays).
    #[arg(long, value_enum, default_value = "biased")]
    bias: Bias,
    /// Shadow-test the initial ReSTIR sample (default: on for unbiased, where it is required; off
    /// for biased).
    #[arg(long, value_enum)]
    initial_visibility: Option<Toggle>,
    /// VPL distance attenuation.
    #[arg(long, value_enum, default_value = "yuksel")]
    attenuation: Attenuation,
    /// Yuksel's r in scene units (default: the mean VPL spacing, sqrt(scene area / (pi * VPLs))).
    #[arg(long)]
    yuksel_radius: Option<f32>,
    /// Vulkan device index (see --list-devices).
    #[arg(long)]
    device: Option<usize>,
    /// List Vulkan devices and what each lacks, then exit.
    #[arg(long)]
    list_devices: bool,
    /// Enable the Khronos validation layer (also RESTIR_VPL_VALIDATE=1).
    #[arg(long)]
    validate: bool,
    /// Print the pass list (what runs, what is skipped and why), device and scene details.
    #[arg(long, short)]
    verbose: bool,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// Throughput benchmark: primary rays and path tracing (Mrays/s, GPU ms per pass).
    Bench {
        #[arg(long, default_value = "scenes/cornell_box.gltf")]
        scene: PathBuf,
        /// Image width (default 512; with --modes, both sizes of the issue unless a size is given).
        #[arg(long)]
        width: Option<u32>,
        /// Image height (default 512).
        #[arg(long)]
        height: Option<u32>,
        /// Timed frames (after one warm-up frame).
        #[arg(long, default_value_t = 10)]
        frames: u32,
        #[arg(long)]
        device: Option<usize>,
        /// Also write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Instead: time the photon pass (100k + 100k VPLs) on this scene and on a generated
        /// scene of over 100k triangles.
        #[arg(long)]
        photons: bool,
        /// Instead: frame cost of uniform, RIS and ReSTIR (per pass, rays per pixel, ratio to
        /// uniform) at 1280×720 and 1280×1280 (or --width × --height if given) with 100k + 100k VPLs.
        #[arg(long)]
        modes: bool,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Toggle {
    On,
    Off,
}

impl Toggle {
    fn on(self) -> bool {
        self == Toggle::On
    }
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("'{s}': expected three comma-separated numbers, like 0,1,0"));
    }
    let mut v = [0f32; 3];
    for (i, p) in parts.iter().enumerate() {
        v[i] = p.parse::<f32>().map_err(|e| format!("'{s}': '{p}' is not a number ({e})"))?;
        if !v[i].is_finite() {
            return Err(format!("'{s}': '{p}' is not finite"));
        }
    }
    Ok(Vec3::from_array(v))
}

fn settings_from(cli: &Cli) -> Result<RenderSettings> {
    let camera = match (cli.eye, cli.target) {
        (Some(eye), Some(target)) => Some(CameraOverride {
            eye,
            target,
            up: cli.up,
            yfov_degrees: cli.fov.unwrap_or(45.0),
        }),
        (None, None) => {
            if cli.fov.is_some() {
                bail!("--fov needs --eye and --target (the scene camera keeps its own field of view)");
            }
            None
        }
        _ => bail!("--eye and --target go together"),
    };
    let validate = cli.validate || std::env::var("RESTIR_VPL_VALIDATE").is_ok_and(|v| v == "1");
    Ok(RenderSettings {
        scene: cli.scene.clone(),
        mode: cli.mode,
        width: cli.width,
        height: cli.height,
        frames: cli.frames,
        seed: cli.seed,
        aa: cli.aa,
        max_bounces: cli.max_bounces,
        exposure: cli.exposure,
        camera,
        save_every: cli.save_every,
        out_dir: Some(cli.out.clone()),
        validate,
        device_index: cli.device,
        verbose: cli.verbose,
        progress: true,
        vpls_direct: cli.vpls_direct,
        vpls_indirect: cli.vpls_indirect,
        gi: !cli.no_gi,
        photon_min_bounces: cli.photon_min_bounces,
        photon_max_bounces: cli.photon_max_bounces,
        dump_vpls: cli.dump_vpls.clone(),
        view: cli.view,
        vpl_radius: cli.vpl_radius,
        candidates: cli.candidates,
        candidate_source: cli.candidate_source,
        restir: RestirSettings {
            temporal: cli.temporal.on(),
            mcap: cli.mcap,
            spatial_neighbours: cli.spatial_neighbours,
            spatial_radius: cli.spatial_radius,
            spatial_passes: cli.spatial_passes,
            normal_threshold: cli.normal_threshold,
            depth_threshold: cli.depth_threshold,
            bias: cli.bias,
            initial_visibility: cli.initial_visibility.map(Toggle::on),
        },
        attenuation: cli.attenuation,
        yuksel_radius: cli.yuksel_radius,
    })
}

fn real_main(cli: Cli) -> Result<()> {
    if let Some(Command::Bench { scene, width, height, frames, device, json, photons, modes }) = &cli.command {
        if *frames == 0 {
            bail!("--frames 0: at least one timed frame is needed");
        }
        if *modes {
            let sizes = if width.is_some() || height.is_some() {
                vec![(width.unwrap_or(512), height.unwrap_or(512))]
            } else {
                vec![(1280, 720), (1280, 1280)]
            };
            let rows = restir_vpl::bench::modes(scene, &sizes, 100_000, 100_000, *frames, *device)?;
            print!("{}", restir_vpl::bench::modes_markdown(&rows));
            if let Some(path) = json {
                std::fs::write(path, serde_json::to_string_pretty(&rows)?)
                    .map_err(|e| anyhow::anyhow!("--json {}: {e}", path.display()))?;
            }
            return Ok(());
        }
        if *photons {
            let runs = (*frames).min(5);
            let loaded = restir_vpl::scene::Scene::load(scene)?;
            let dense = restir_vpl::bench::dense_scene(160, 320)?;
            println!("| scene | triangles | VPLs (direct + indirect) | photon paths | GPU ms (median of {runs}) | M paths/s |");
            println!("|---|---:|---:|---:|---:|---:|");
            for (s, label) in [(&loaded, scene.display().to_string()), (&dense, "generated bumpy sphere in a room".to_string())] {
                let b = restir_vpl::bench::photons(s, &label, 100_000, 100_000, runs, *device)?;
                println!(
                    "| {} | {} | {} + {} | {} | {:.1} | {:.2} |",
                    b.scene, b.triangles, b.direct, b.indirect_vpls, b.paths, b.gpu_ms, b.paths_per_second * 1e-6
                );
            }
            return Ok(());
        }
        let report = restir_vpl::bench::core(scene, width.unwrap_or(512), height.unwrap_or(512), *frames, *device)?;
        print!("{}", report.markdown());
        if let Some(path) = json {
            std::fs::write(path, serde_json::to_string_pretty(&report)?)
                .map_err(|e| anyhow::anyhow!("--json {}: {e}", path.display()))?;
        }
        return Ok(());
    }
    if cli.list_devices {
        let devices = restir_vpl::vk::context::list_devices()?;
        if devices.is_empty() {
            println!("no Vulkan devices found (is a Vulkan driver installed? run scripts/setup.sh)");
        }
        for d in devices {
            println!("{d}");
        }
        return Ok(());
    }
    let settings = settings_from(&cli)?;
    settings.validate()?;
    if !cli.headless {
        bail!("windowed mode is not available yet: pass --headless to render to files");
    }
    let out = restir_vpl::run(&settings)?;
    let s = &out.summary;
    println!("device: {}", s.device);
    println!(
        "scene: {} ({} triangles, {} area lights)",
        s.scene.path, s.scene.triangles, s.scene.area_lights
    );
    println!(
        "{} frames of {}x{} ({}), {:.2} rays/pixel/frame",
        s.frames, settings.width, settings.height, settings.mode.name(), s.rays_per_pixel.mean
    );
    if let Some(p) = &s.photons {
        println!(
            "photon_emit (once, static scene): {:.2} GPU ms, {} paths ({:.2} M paths/s), {} direct + {} indirect VPLs",
            p.gpu_ms,
            p.paths,
            p.paths_per_second * 1e-6,
            p.direct_vpls,
            p.indirect_vpls
        );
    }
    if let Some(v) = &s.vpl {
        println!(
            "vpl: {} VPLs, {} candidate(s) ({} source), Yuksel r = {}, targets with visibility: {}, unbiased reuse: {}",
            v.vpl_count,
            v.candidates,
            v.candidate_source,
            v.yuksel_radius.map(|r| format!("{r:.4}")).unwrap_or_else(|| "- (inverse square)".into()),
            v.initial_visibility,
            v.unbiased_reuse
        );
    }
    println!("GPU ms per pass (median / min / max), rays per pixel per frame (mean):");
    for (name, t) in &s.pass_ms {
        let rays = s.rays_per_pixel_by_pass.get(name).map(|r| format!("{:>8.2} rays/px", r.mean)).unwrap_or_default();
        println!("  {name:<16} {:>9.2} {:>9.2} {:>9.2} {rays}", t.median, t.min, t.max);
    }
    println!(
        "ms per frame: {:.2} GPU, {:.2} wall (median); total {:.2} s",
        s.gpu_ms_per_frame.median, s.wall_ms_per_frame.median, s.total_seconds
    );
    if s.nonfinite_samples > 0 {
        println!("non-finite samples replaced by 0: {}", s.nonfinite_samples);
    }
    for w in &s.warnings {
        println!("warning: {w}");
    }
    println!("images:");
    for o in &s.outputs {
        println!("  {o}");
    }
    if let Some(dir) = &settings.out_dir {
        println!("  {}", dir.join("summary.json").display());
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    restir_vpl::logger::init(cli.verbose);
    match real_main(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if e.downcast_ref::<NoRayQueryDevice>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
