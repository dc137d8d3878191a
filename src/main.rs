//! The `restir-vpl` command line.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args as _, CommandFactory as _, FromArgMatches as _, Parser};
use glam::Vec3;

use std::sync::LazyLock;

use restir_vpl::settings::{
    Attenuation, Bias, CameraOverride, CandidateSource, Mode, NamedEnum, PresentMode, RenderSettings, RestirSettings,
    View,
};
use restir_vpl::vk::context::Tracing;
use restir_vpl::vk::NoTracingDevice;

/// GPU global illumination: photon-traced VPLs + ReSTIR DI on Vulkan ray queries, with a path-traced
/// ground truth.
#[derive(Debug, Parser)]
#[command(name = "restir-vpl", version, about, args_conflicts_with_subcommands = true, args_override_self = true, allow_negative_numbers = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Render without a window and write images to --out.
    #[arg(long)]
    headless: bool,
    #[command(flatten)]
    render: RenderArgs,
    /// Output directory (final.exr, final.png, accum_NNNN.exr, summary.json).
    #[arg(value_parser = Utf8Path, long, default_value = "out")]
    out: PathBuf,
    /// List Vulkan devices and what each lacks, then exit.
    #[arg(long)]
    list_devices: bool,
    /// How the window's frames wait for the display [default: fifo].
    #[arg(long, value_parser = named::<PresentMode>())]
    present_mode: Option<PresentMode>,
    /// Window only: a reference EXR of the same camera and size (`reference` writes one); shown on
    /// the right of a split screen, with the live RMSE and FLIP of the image against it.
    #[arg(value_parser = Utf8Path, long, value_name = "REF.exr")]
    reference: Option<PathBuf>,
}

/// Everything that decides what is rendered (shared by the main command and `reference`).
#[derive(Debug, clap::Args)]
struct RenderArgs {
    /// glTF 2.0 scene (.gltf or .glb).
    #[arg(value_parser = Utf8Path, long, default_value_os_t = DEFAULTS.scene.clone())]
    scene: PathBuf,
    /// Estimator.
    #[arg(long, value_parser = named::<Mode>(), default_value_t = DEFAULTS.mode)]
    mode: Mode,
    /// Frames to render and average [default: 20]. In a window: close after this many frames and
    /// write the outputs as a headless run does (without it the window stays until closed).
    #[arg(long)]
    frames: Option<u32>,
    #[arg(long, default_value_t = DEFAULTS.width)]
    width: u32,
    #[arg(long, default_value_t = DEFAULTS.height)]
    height: u32,
    /// Also write accum_NNNN.exr every K frames.
    #[arg(long, default_value_t = DEFAULTS.save_every, value_name = "K")]
    save_every: u32,
    /// Random seed; the same seed gives the same image.
    #[arg(long, default_value_t = DEFAULTS.seed)]
    seed: u32,
    /// Jitter primary rays inside the pixel (box filter) instead of tracing pixel centres.
    #[arg(long)]
    aa: bool,
    /// Path-tracer bounces (-1: unbounded, Russian roulette only).
    #[arg(long, default_value_t = DEFAULTS.max_bounces, allow_negative_numbers = true)]
    max_bounces: i32,
    /// Exposure of the PNG preview in EV.
    #[arg(long, value_parser = parse_f32, default_value_t = DEFAULTS.exposure, allow_negative_numbers = true)]
    exposure: f32,
    /// Camera position "x,y,z" (overrides the scene camera; needs --target).
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true)]
    eye: Option<Vec3>,
    /// Camera target "x,y,z".
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true)]
    target: Option<Vec3>,
    /// Camera up "x,y,z" (with --eye/--target; default 0,1,0).
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true)]
    up: Option<Vec3>,
    /// Vertical field of view in degrees (with --eye/--target; default 45, or the scene camera's).
    #[arg(long, value_parser = parse_f32)]
    fov: Option<f32>,
    /// Camera path: {"keyframes": [{"frame": 0, "eye": [x,y,z], "target": [x,y,z], "up": [0,1,0],
    /// "fov": 40}, ...]} (fov vertical in degrees; linear interpolation; frames past the last
    /// keyframe hold it). Frame f of the run is seen from the path's camera at f.
    #[arg(value_parser = Utf8Path, long, value_name = "FILE.json")]
    camera_path: Option<PathBuf>,
    /// Accumulate frames while the camera and settings stay (off: each image is one frame).
    #[arg(long, value_enum, default_value_t = Toggle::from(DEFAULTS.progressive))]
    progressive: Toggle,
    /// Direct VPLs (they replace the area and point lights).
    #[arg(long, default_value_t = DEFAULTS.vpls_direct)]
    vpls_direct: u32,
    /// Target number of indirect VPLs from photon paths (the paths traced are counted exactly).
    #[arg(long, default_value_t = DEFAULTS.vpls_indirect)]
    vpls_indirect: u32,
    /// No global illumination: no indirect VPLs.
    #[arg(long)]
    no_gi: bool,
    /// Photon bounces before Russian roulette starts.
    #[arg(long, default_value_t = DEFAULTS.photon_min_bounces)]
    photon_min_bounces: u32,
    /// Maximum photon bounces (indirect VPLs per path); the VPL image then holds light paths of up to
    /// B + 1 reflections, the path tracer's --max-bounces B + 1.
    #[arg(long, default_value_t = DEFAULTS.photon_max_bounces)]
    photon_max_bounces: u32,
    /// Write the VPLs as a PLY point cloud (opens in MeshLab/Blender).
    #[arg(value_parser = Utf8Path, long, value_name = "FILE.ply")]
    dump_vpls: Option<PathBuf>,
    /// Write every pass's outputs of these frames (`0,19`, `last`, `0,last` or `all`) to OUT/passes: EXR
    /// and PNG per output, manifest.json per frame, index.html (the inspector page).
    #[arg(long, value_name = "FRAMES")]
    dump_passes: Option<String>,
    /// Check every pass's outputs for NaN/Inf every frame; stop at the first one, naming the frame,
    /// pass, buffer and pixels (costs a copy per pass; nothing when off).
    #[arg(long)]
    check_finite: bool,
    /// Wrap frame N's submission in a RenderDoc capture when running under RenderDoc (1.36 or later
    /// for ray queries); otherwise say how to start under it and go on.
    #[arg(long, value_name = "N")]
    renderdoc_capture: Option<u32>,
    /// What the image shows: the estimate; the VPLs as spheres (blue direct, red indirect); the
    /// final reservoir's W or M or the kind of VPL it holds; or only direct / only indirect light.
    #[arg(long, value_parser = named::<View>(), default_value_t = DEFAULTS.view)]
    view: View,
    /// Sphere radius of `--view vpls` in scene units (default: 0.25% of the scene's diagonal).
    #[arg(long, value_parser = parse_f32)]
    vpl_radius: Option<f32>,
    /// RIS candidates per pixel (ris and restir).
    #[arg(long, default_value_t = DEFAULTS.candidates)]
    candidates: u32,
    /// Where RIS candidates come from: uniformly over the VPLs, or in proportion to their power.
    #[arg(long, value_parser = named::<CandidateSource>(), default_value_t = DEFAULTS.candidate_source)]
    candidate_source: CandidateSource,
    /// Light presampling (ris, restir): each pixel's candidates come from one random tile of VPLs
    /// drawn from the source pdf this frame, instead of from the whole VPL buffer (same estimator,
    /// faster).
    #[arg(long, value_enum, default_value_t = Toggle::from(DEFAULTS.presample))]
    presample: Toggle,
    /// Of --candidates, how many come from a world-space grid of presampled VPLs (ReGIR: each cell
    /// holds VPLs drawn for the cell by RIS; ris and restir). 0: none. Unbiased for any value.
    #[arg(long, default_value_t = DEFAULTS.grid.candidates)]
    grid_candidates: u32,
    /// Cells per axis of the ReGIR grid over the scene's bounds (only the cells pixels see are built).
    #[arg(long, default_value_t = DEFAULTS.grid.cells)]
    grid_cells: u32,
    /// Entries per ReGIR grid cell (a multiple of 64).
    #[arg(long, default_value_t = DEFAULTS.grid.entries)]
    grid_entries: u32,
    /// Candidates from the source pdf behind each ReGIR grid entry.
    #[arg(long, default_value_t = DEFAULTS.grid.entry_candidates)]
    grid_entry_candidates: u32,
    /// Balance-heuristic weights between the ReGIR grid's candidates and the source pdf's (off:
    /// constant 1/M weights; both unbiased).
    #[arg(long, value_enum, default_value_t = Toggle::from(DEFAULTS.grid.balance))]
    grid_balance: Toggle,
    /// ReSTIR's passes fused in pairs (restir_initial_temporal, restir_spatial_shade), as Bevy
    /// Solari runs them: the same image, fewer dispatches. Frames whose pass outputs are dumped or
    /// checked run the passes apart; the reservoir views keep vpl_shade apart (it draws them).
    /// Default: on (it paid on every scene on an H100, and on lavapipe since the reuse's kind
    /// became specialisation constants; docs/performance.md, "Pass fusion").
    #[arg(long, value_enum)]
    fuse_passes: Option<Toggle>,
    /// Workgroup WxH of the per-pixel passes (gbuffer, pathtrace, restir_initial, restir_spatial,
    /// restir_spatial_shade, vpl_shade, vpl_compensate, vpl_bruteforce; restir_temporal,
    /// restir_initial_temporal and restir_boiling stay 8x8). Same image for any
    /// size; `bench --workgroups` measures them.
    #[arg(long, value_parser = Workgroup::parse, default_value_t = Workgroup(restir_vpl::settings::DEFAULT_WORKGROUP))]
    workgroup: Workgroup,
    /// ReSTIR temporal reuse of the previous frame's reservoirs.
    #[arg(long, value_enum, default_value_t = Toggle::from(DEFAULTS.restir.temporal))]
    temporal: Toggle,
    /// Temporal history confidence cap, in multiples of the current frame's.
    #[arg(long, value_parser = parse_f32, default_value_t = DEFAULTS.restir.mcap)]
    mcap: f32,
    /// ReSTIR spatial neighbours per pass (at most 32).
    #[arg(long, default_value_t = DEFAULTS.restir.spatial_neighbours)]
    spatial_neighbours: u32,
    /// Radius of the disc spatial neighbours are drawn from (pixels) [default: 20 per 1280 px of
    /// image width, at least 4].
    #[arg(long, value_parser = parse_f32)]
    spatial_radius: Option<f32>,
    /// Spatial reuse passes per frame.
    #[arg(long, default_value_t = DEFAULTS.restir.spatial_passes)]
    spatial_passes: u32,
    /// RIS candidates of a ReSTIR frame displayed alone (the camera moved, or --progressive off)
    /// while temporal reuse has history: its error hardly depends on them there, unlike an
    /// accumulation's (docs/performance.md, "Frames displayed alone"). At most --candidates; 0:
    /// --candidates.
    #[arg(long, default_value_t = DEFAULTS.restir.moving_candidates)]
    moving_candidates: u32,
    /// Spatial neighbours of such a frame (at most --spatial-neighbours; 0: --spatial-neighbours).
    #[arg(long, default_value_t = DEFAULTS.restir.moving_neighbours)]
    moving_neighbours: u32,
    /// Reject spatial neighbours whose shading normals' dot product is below this.
    #[arg(long, value_parser = parse_f32, default_value_t = DEFAULTS.restir.normal_threshold, allow_negative_numbers = true)]
    normal_threshold: f32,
    /// Reject spatial neighbours whose view depth differs by more than this fraction.
    #[arg(long, value_parser = parse_f32, default_value_t = DEFAULTS.restir.depth_threshold)]
    depth_threshold: f32,
    /// ReSTIR reuse: unbiased (pairwise MIS; converges to the brute-force sum) or biased
    /// (confidence weights as in the thesis: a few percent dark, fireflies).
    #[arg(long, value_parser = named::<Bias>(), default_value_t = DEFAULTS.restir.bias)]
    bias: Bias,
    /// RTXDI's boiling filter after temporal reuse (pass restir_boiling), strength in [0, 1] (0:
    /// off; 0.2 drops reservoirs 41× over their 8×8 neighbourhood's mean weight). Biased.
    #[arg(long, value_parser = parse_f32, default_value_t = DEFAULTS.restir.boiling_filter)]
    boiling_filter: f32,
    /// Shadow-test the initial ReSTIR sample, so that the targets include visibility (default off:
    /// unbiased either way; on costs two shadow rays per spatial neighbour).
    #[arg(long, value_enum)]
    initial_visibility: Option<Toggle>,
    /// VPL distance attenuation.
    #[arg(long, value_parser = named::<Attenuation>(), default_value_t = DEFAULTS.attenuation)]
    attenuation: Attenuation,
    /// Yuksel's r in scene units (default: 8 × the mean VPL spacing sqrt(scene area / (pi * VPLs)),
    /// chosen by `bench --radius`).
    #[arg(long, value_parser = parse_f32)]
    yuksel_radius: Option<f32>,
    /// The multiple M of the automatic Yuksel radius (default 8): M × the mean VPL spacing, or with
    /// --yuksel-knn M × each VPL's local spacing.
    #[arg(long, value_parser = parse_f32)]
    yuksel_spacings: Option<f32>,
    /// A Yuksel radius per VPL from its K nearest VPLs: M × d_K / sqrt(K), its local spacing
    /// (d_K: distance to the K-th nearest), instead of one radius from the mean spacing.
    #[arg(long)]
    yuksel_knn: Option<u32>,
    /// Add back the energy Yuksel's clamp removes near each VPL (Kollig & Keller 2004): one
    /// cosine-sampled ray per pixel, recursively, so VPL modes converge to the path tracer for any
    /// --yuksel-radius.
    #[arg(long)]
    compensate: bool,
    /// Sample glTF base colour textures (off: base colour factors only; a scene without textures
    /// never compiles the texture path).
    #[arg(long, value_enum, default_value_t = Toggle::from(DEFAULTS.textures))]
    textures: Toggle,
    /// A scene of at most N triangles has its instances merged into one world-space mesh: one BLAS,
    /// one TLAS instance, no instance transforms in traversal. 0: never (one BLAS per mesh, one
    /// TLAS instance per glTF node). The same image up to float rounding in pt; in the VPL modes
    /// the rounding sends some photons along other paths: another draw of the VPL set.
    #[arg(long, value_name = "N", default_value_t = DEFAULTS.merge_blas)]
    merge_blas: u32,
    /// Vulkan device index (see --list-devices).
    #[arg(long)]
    device: Option<usize>,
    /// How rays are traced: ray queries (inline in compute shaders), ray-tracing pipelines (for
    /// GPUs without ray queries, as NVIDIA's datacenter GPUs), or auto: ray queries where the
    /// device has them. Given, it overrides RESTIR_VPL_TRACE, which decides without it (and is
    /// what the benchmarks and `results` read).
    #[arg(long, value_enum)]
    trace: Option<TraceArg>,
    /// Enable the Khronos validation layer (also RESTIR_VPL_VALIDATE=1).
    #[arg(long)]
    validate: bool,
    /// Print the pass list (what runs, what is skipped and why), device and scene details.
    #[arg(long, short)]
    verbose: bool,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// Benchmarks: with no flag below, primary rays and path tracing (Mrays/s, GPU ms per pass);
    /// else the one chosen (--modes, --photons, --rays, --scaling, --workgroups, --curves,
    /// --motion, --radius).
    #[command(allow_negative_numbers = true)]
    Bench {
        #[arg(value_parser = Utf8Path, long, default_value_os_t = DEFAULTS.scene.clone())]
        scene: PathBuf,
        /// Image width (default 512; --modes: 1280×720 and 1280×1280 unless a size is given, and
        /// 1280×720 with --out; --rays and --workgroups: 1280×720; --curves: 320×320).
        #[arg(long)]
        width: Option<u32>,
        /// Image height (default 512).
        #[arg(long)]
        height: Option<u32>,
        /// Timed frames (after the warm-up frames), or runs of the photon pass with --photons.
        #[arg(long, default_value_t = 10)]
        frames: u32,
        /// Vulkan device index (see --list-devices).
        #[arg(long)]
        device: Option<usize>,
        /// Also write the figures as JSON to this file.
        #[arg(value_parser = Utf8Path, long)]
        json: Option<PathBuf>,
        /// Instead: time the photon pass (100k + 100k VPLs) on this scene and on a generated
        /// scene of over 100k triangles.
        #[arg(long)]
        photons: bool,
        /// Instead: frame cost of uniform, RIS and ReSTIR (per pass, rays per pixel, ratio to
        /// uniform) at 1280×720 and 1280×1280 (or --width × --height if given) with 100k + 100k VPLs;
        /// with --out, the report of both cameras on the three scenes (see --out).
        #[arg(long, conflicts_with = "photons")]
        modes: bool,
        /// With --modes: the camera follows the path committed beside the scene
        /// (scenes/<name>.path.json, back and forth) and every frame is displayed alone, as in the
        /// window while flying: the G-buffer and the temporal reprojection run every frame.
        #[arg(long, requires = "modes")]
        moving: bool,
        /// With --modes: instead of the usual cases, uniform and ReSTIR (biased, unbiased) with its
        /// passes apart and fused (--fuse-passes off / on), interleaved in one run.
        #[arg(long, requires = "modes")]
        fusion: bool,
        /// With --modes: instead of the usual cases, uniform, then RIS and unbiased ReSTIR with 32
        /// candidates, with 16, and with 16 of which 8 from the ReGIR grid (--grid-candidates),
        /// interleaved in one run.
        #[arg(long, requires = "modes", conflicts_with = "fusion")]
        grid: bool,
        /// Instead: GPU ms of every per-pixel pass of ReSTIR and the path tracer at seven workgroup
        /// shapes (--workgroup; 8x8 default, 4x4 … 64x1), interleaved frame by frame, with the
        /// ratio to 8x8. Default size 1280×720.
        #[arg(long, conflicts_with_all = ["modes", "photons", "curves", "motion", "rays", "radius", "scaling"])]
        workgroups: bool,
        /// Instead: error against frames and time on this scene (uniform, RIS, ReSTIR and the
        /// unbiased ReSTIR variants) against a path-traced and a converged VPL reference, both
        /// rendered first (cached in --out/references). Writes --out/curves.md, curves.csv,
        /// frame_times.csv and plots/*.svg. Default size 320×320, 64×64 with --quick (--width/--height to change).
        #[arg(long, conflicts_with_all = ["modes", "photons"])]
        curves: bool,
        /// Instead: the real-time measurement. A camera moves along the path committed beside each
        /// of the three scenes (scenes/<name>.path.json); every displayed frame of uniform, RIS,
        /// ReSTIR (biased and unbiased, temporal reuse following the reprojected pixels), ReSTIR
        /// without temporal reuse, and RIS and unbiased ReSTIR with the ReGIR grid is compared with
        /// a path-traced reference of that frame's camera (cached in --out/references). Writes --out/motion.md, motion.csv and plots/*_motion_rmse.svg.
        #[arg(long, conflicts_with_all = ["curves", "modes", "photons"])]
        motion: bool,
        /// Instead: this device's raw ray rate on the three scenes (coherent primary rays,
        /// incoherent shadow rays of random length and incoherent closest-hit rays, nothing else in
        /// the shader), and every tracing pass's rays per second in real frames (ReSTIR's passes apart; uniform, RIS,
        /// ReSTIR, ReSTIR --initial-visibility on, ReSTIR --compensate, pt) and in the photon pass
        /// as a share of the raw rate of its kind. Default size 1280×720.
        #[arg(long, conflicts_with_all = ["curves", "modes", "photons", "motion"])]
        rays: bool,
        /// Instead: the Yuksel radius as a trade-off on the three scenes. ReSTIR with r = 1…64 ×
        /// the mean VPL spacing, the thesis's radius scaled to the scene, and 16× / 64× with
        /// --compensate, against a path-traced reference (cached in --out/references): bias,
        /// per-frame variance, RMSE and FLIP at t = 1 and 20, worst-pixel share, GPU ms. Writes
        /// --out/radius.md and radius.csv.
        #[arg(long, conflicts_with_all = ["curves", "modes", "photons", "motion", "rays"])]
        radius: bool,
        /// Instead: how cost grows with the work. Frame GPU ms of uniform, RIS and ReSTIR against
        /// the VPL count (10k … 2M), the image size (256×144 … 1920×1080, 16:9) and the triangle count (~1k …
        /// ~1M, generated), with the photon pass and the BLAS/TLAS builds; each curve's measured
        /// exponent beside the expected one. Writes --out/scaling.md and scaling.csv.
        #[arg(long, conflicts_with_all = ["curves", "modes", "photons", "motion", "rays", "radius"])]
        scaling: bool,
        /// With --curves, --motion, --radius or --scaling: a smoke test (tiny images, few frames and VPLs).
        #[arg(long)]
        quick: bool,
        /// With --curves, --motion, --radius or --scaling: output directory. With --modes: write
        /// OUT/modes.md, the still and moving cameras of the three bundled scenes (or --scene) at
        /// 1280×720 (or the size given) in one run, with how it was made (docs/modes.md is one).
        #[arg(value_parser = Utf8Path, long, default_value = "bench-out")]
        out: PathBuf,
        /// With --curves: checkpoints (accumulated frames), comma separated [default: 1,2,5,10,20,40].
        #[arg(long, value_delimiter = ',', requires = "curves", action = clap::ArgAction::Set)]
        checkpoints: Option<Vec<u32>>,
        /// With --curves, --motion or --radius: independent runs averaged [default: 3 for --curves, 2 for
        /// --motion and --radius].
        #[arg(long)]
        runs: Option<u32>,
    },
    /// Compare a test image A with a reference B: RMSE, relMSE, mean ratio (bias) and LDR-FLIP.
    ///
    /// RMSE, relMSE and the mean ratio mean(A)/mean(B) are over the pixels finite in both images.
    /// FLIP is NVIDIA's LDR-FLIP (mean over the image) on both images mapped to 8-bit sRGB as the
    /// renderer's PNG (2^exposure, clamp, sRGB), with non-finite pixels as black.
    ///
    /// Exit status: 0 on success; 3 if either image has NaN or Inf pixels (reported on stderr with
    /// the file, count and first positions; the metrics over the finite pixels are still printed);
    /// 1 on other errors (missing or unreadable file, sizes differ); 2 on bad arguments.
    #[command(allow_negative_numbers = true)]
    Compare {
        /// Test image (EXR).
        #[arg(value_parser = Utf8Path, value_name = "A.exr")]
        test: PathBuf,
        /// Reference image (EXR).
        #[arg(value_parser = Utf8Path, value_name = "B.exr")]
        reference: PathBuf,
        /// Exposure in EV of FLIP's 8-bit mapping (as --exposure of the PNG preview).
        #[arg(long, value_parser = parse_f32, default_value_t = 0.0, allow_negative_numbers = true)]
        exposure: f32,
        /// Skip FLIP (the slow metric); its own flags (--exposure, --ppd, --error-image) are then
        /// refused, not ignored.
        #[arg(long, conflicts_with_all = ["error_image", "exposure", "ppd"])]
        no_flip: bool,
        /// FLIP's pixels per degree of visual angle.
        #[arg(long, value_parser = parse_f32, default_value_t = 67.0)]
        ppd: f32,
        /// Write FLIP's error map as a false-colour PNG (magma: black = no error).
        #[arg(value_parser = Utf8Path, long, value_name = "OUT.png")]
        error_image: Option<PathBuf>,
        /// Also write the metrics as JSON.
        #[arg(value_parser = Utf8Path, long, value_name = "OUT.json")]
        json: Option<PathBuf>,
    },
    /// Merge partial references (EXRs with restir-vpl reference metadata) rendered over disjoint
    /// frame ranges into their frame-count-weighted mean.
    ///
    /// The parts must agree in size, mode, scene, seed and settings; their frame ranges must not
    /// overlap. Prints the merged frame count and ranges.
    #[command(allow_negative_numbers = true)]
    MergeReferences {
        /// Partial references.
        #[arg(value_parser = Utf8Path, required = true, value_name = "REF.exr")]
        inputs: Vec<PathBuf>,
        /// Merged reference to write (a new file unless --overwrite).
        #[arg(value_parser = Utf8Path, long, value_name = "C.exr")]
        out: PathBuf,
        /// Replace --out when it exists (never one of the inputs).
        #[arg(long)]
        overwrite: bool,
    },
    /// Render a reference: a long accumulation (--mode pt for the ground truth; bruteforce or ris
    /// for the VPL answer) written as EXR with its frame range and settings in the header.
    ///
    /// Resumable (--resume renders --frames more frames after the file's last one and merges) and
    /// splittable (runs with disjoint --first-frame ranges combine with `merge-references`; frame k
    /// uses the same random numbers in every run, so the merge equals one long run).
    #[command(allow_negative_numbers = true)]
    Reference {
        #[command(flatten)]
        render: RenderArgs,
        /// The reference to write (with --resume: to extend). An existing file is never overwritten
        /// without --resume.
        #[arg(value_parser = Utf8Path, long, value_name = "REF.exr")]
        out: PathBuf,
        /// Index of the first frame: give each machine its own range. Not with --resume, which
        /// continues after the last frame in --out (refused even as 0).
        #[arg(long, default_value_t = 0, conflicts_with = "resume")]
        first_frame: u64,
        /// Extend --out: render --frames more frames after its last frame and merge them in.
        #[arg(long)]
        resume: bool,
    },
    /// Regenerate docs/results.md: references, error against frames and time, Table 1/2-shaped
    /// tables, CSVs and plots for the Cornell box, the living room and the open box with a figure.
    ///
    /// References are cached under OUT/references and resumed when more frames are asked for.
    #[command(allow_negative_numbers = true)]
    Results {
        /// Output directory (results.md, curves.csv, frame_times.csv, plots/, references/)
        /// [default: docs; with --quick: bench-out/results-quick, so that a smoke test does not
        /// overwrite the committed results].
        #[arg(value_parser = Utf8Path, long)]
        out: Option<PathBuf>,
        /// Image sizes as a fraction of the thesis's (Cornell box 1280×1280, others 1280×720).
        /// Not with --quick, which sets its own tiny sizes.
        #[arg(long, default_value_t = 0.25, conflicts_with = "quick")]
        scale: f64,
        /// Smoke test: tiny images, few frames and VPLs, three modes (seconds on lavapipe).
        #[arg(long)]
        quick: bool,
        /// Independent runs averaged per checkpoint.
        #[arg(long)]
        runs: Option<u32>,
        /// Frames of the path-traced references.
        #[arg(long)]
        pt_frames: Option<u32>,
        /// Frames of the converged VPL references (RIS).
        #[arg(long)]
        vpl_frames: Option<u32>,
        /// Checkpoints (accumulated frames), comma separated.
        #[arg(long, value_delimiter = ',', action = clap::ArgAction::Set)]
        checkpoints: Option<Vec<u32>>,
        /// Skip FLIP.
        #[arg(long)]
        no_flip: bool,
        /// Leave out the moving-camera section (its per-frame path-traced references are the
        /// slowest part; `bench --motion` measures it on its own).
        #[arg(long)]
        no_motion: bool,
        /// Vulkan device index (see --list-devices).
        #[arg(long)]
        device: Option<usize>,
    },
}

/// The library's defaults: the CLI's defaults are read from here, never written twice.
static DEFAULTS: LazyLock<RenderSettings> = LazyLock::new(RenderSettings::default);

/// Parses a settings enum by its names, listing them with their help in `--help`.
fn named<T: NamedEnum + Send + Sync>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::TypedValueParser as _;
    clap::builder::PossibleValuesParser::new(T::ALL.iter().map(|v| clap::builder::PossibleValue::new(v.name()).help(v.help())))
        .map(|s| T::from_name(&s).expect("clap accepts only the listed names"))
}

/// `--workgroup WxH`, printed the way it is parsed, so that the help's default is the renderer's.
#[derive(Clone, Copy, Debug)]
struct Workgroup([u32; 2]);

impl Workgroup {
    fn parse(s: &str) -> Result<Self, String> {
        restir_vpl::settings::parse_workgroup(s).map(Self)
    }
}

impl std::fmt::Display for Workgroup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.0[0], self.0[1])
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum TraceArg {
    Auto,
    Query,
    Pipeline,
}

impl TraceArg {
    /// None: auto (`RESTIR_VPL_TRACE` if set, else the device's best).
    fn tracing(self) -> Option<Tracing> {
        match self {
            TraceArg::Auto => None,
            TraceArg::Query => Some(Tracing::Query),
            TraceArg::Pipeline => Some(Tracing::Pipeline),
        }
    }
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

impl From<bool> for Toggle {
    fn from(on: bool) -> Self {
        if on {
            Toggle::On
        } else {
            Toggle::Off
        }
    }
}

impl std::fmt::Display for Toggle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.on() { "on" } else { "off" })
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

/// Every path flag and argument: refused up front when not UTF-8 (the outputs' summaries and
/// reference files record their paths as text; such a path failed after the render, naming no flag)
/// or empty (`--out ''` wrote the outputs into the working directory without a word).
#[derive(Clone)]
struct Utf8Path;

impl clap::builder::TypedValueParser for Utf8Path {
    type Value = PathBuf;

    fn parse_ref(&self, cmd: &clap::Command, arg: Option<&clap::Arg>, value: &std::ffi::OsStr) -> Result<PathBuf, clap::Error> {
        match value.to_str() {
            Some("") => {
                let name = arg.map_or_else(|| "a path".to_string(), ToString::to_string);
                // (No "'.' for the working directory": most path flags take a file, and
                // --dump-vpls '.' was then refused as a directory.)
                let message = format!("{name}: an empty path; name a file or directory\n");
                Err(clap::Error::raw(clap::error::ErrorKind::InvalidValue, message).with_cmd(cmd))
            }
            Some(s) => Ok(PathBuf::from(s)),
            None => {
                let name = arg.map_or_else(|| "a path".to_string(), ToString::to_string);
                let message = format!(
                    "{name}: '{}' is not valid UTF-8 (summaries and reference files record their paths as text): use a UTF-8 path\n",
                    value.to_string_lossy()
                );
                Err(clap::Error::raw(clap::error::ErrorKind::InvalidUtf8, message).with_cmd(cmd))
            }
        }
    }
}

fn settings_from(cli: &RenderArgs, out_dir: Option<PathBuf>) -> Result<RenderSettings> {
    let camera = match (cli.eye, cli.target) {
        (Some(eye), Some(target)) => Some(CameraOverride {
            eye,
            target,
            up: cli.up.unwrap_or(Vec3::Y),
            yfov_degrees: cli.fov.unwrap_or(45.0),
        }),
        (None, None) => {
            // Whose camera it would change: the path's keyframes, or the scene's camera.
            let keeps = if cli.camera_path.is_some() { "--camera-path's keyframes give" } else { "the scene camera keeps" };
            if cli.fov.is_some() {
                bail!("--fov needs --eye and --target ({keeps} the field of view)");
            }
            if cli.up.is_some() {
                bail!("--up needs --eye and --target ({keeps} the orientation)");
            }
            None
        }
        _ => bail!("--eye and --target go together"),
    };
    let validate = cli.validate || env_validate()?;
    Ok(RenderSettings {
        scene: cli.scene.clone(),
        mode: cli.mode,
        width: cli.width,
        height: cli.height,
        frames: cli.frames.unwrap_or(DEFAULTS.frames),
        seed: cli.seed,
        aa: cli.aa,
        max_bounces: cli.max_bounces,
        exposure: cli.exposure,
        camera,
        camera_path: cli.camera_path.clone(),
        progressive: cli.progressive.on(),
        save_every: cli.save_every,
        out_dir,
        validate,
        device_index: cli.device,
        tracing: cli.trace.and_then(TraceArg::tracing),
        progress: true,
        vpls_direct: cli.vpls_direct,
        vpls_indirect: cli.vpls_indirect,
        gi: !cli.no_gi,
        photon_min_bounces: cli.photon_min_bounces,
        photon_max_bounces: cli.photon_max_bounces,
        dump_vpls: cli.dump_vpls.clone(),
        dump_passes: cli.dump_passes.clone(),
        check_finite: cli.check_finite,
        renderdoc_capture: cli.renderdoc_capture,
        view: cli.view,
        vpl_radius: cli.vpl_radius,
        candidates: cli.candidates,
        candidate_source: cli.candidate_source,
        presample: cli.presample.on(),
        grid: restir_vpl::settings::GridSettings {
            candidates: cli.grid_candidates,
            cells: cli.grid_cells,
            entries: cli.grid_entries,
            entry_candidates: cli.grid_entry_candidates,
            balance: cli.grid_balance.on(),
        },
        fuse_passes: cli.fuse_passes.map(Toggle::on),
        workgroup: cli.workgroup.0,
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
            boiling_filter: cli.boiling_filter,
            moving_candidates: cli.moving_candidates,
            moving_neighbours: cli.moving_neighbours,
        },
        attenuation: cli.attenuation,
        yuksel_radius: cli.yuksel_radius,
        yuksel_spacings: cli.yuksel_spacings,
        yuksel_knn: cli.yuksel_knn,
        textures: cli.textures.on(),
        merge_blas: cli.merge_blas,
        compensate: cli.compensate,
    })
}

fn real_main(cli: Cli, given: &[String]) -> Result<()> {
    // Refused by every command, as README says, also those that open no device (compare,
    // merge-references), only list them, or run without the layer (the timing benchmarks: `=maybe`
    // was taken there without a word): a typo must not pass silently anywhere.
    env_validate()?;
    if let Some(Command::Compare { test, reference, exposure, no_flip, ppd, error_image, json }) = &cli.command {
        let opts = restir_vpl::eval::compare::CompareOptions { flip: !*no_flip, exposure: *exposure, ppd: *ppd };
        return restir_vpl::eval::compare::run_cli(test, reference, &opts, error_image.as_deref(), json.as_deref());
    }
    if let Some(Command::MergeReferences { inputs, out, overwrite }) = &cli.command {
        return restir_vpl::eval::reference::run_merge_cli(inputs, out, *overwrite);
    }
    if let Some(Command::Reference { render, out, first_frame, resume }) = &cli.command {
        let settings = settings_from(render, None)?;
        // A headless run's extra outputs and checks: a reference writes --out and nothing else
        // (they were accepted and did nothing).
        let headless_only = headless_only_flags(&settings);
        if !headless_only.is_empty() {
            bail!(
                "{}: not done by `reference`, which writes only --out; give {} to a --headless run with the same settings",
                headless_only.join(", "),
                if headless_only.len() == 1 { "it" } else { "them" }
            );
        }
        // A reference converges one camera's image over all its frames: a path would be ignored
        // (it was, without a word, and the file said nothing of it).
        if settings.camera_path.is_some() {
            bail!(
                "--camera-path: `reference` converges one camera's image over all its frames; give that camera with --eye/--target/--up/--fov (bench --motion renders a reference for each frame of a path)"
            );
        }
        settings.validate()?;
        // (A reference writes no summary: the warnings are printed only.)
        let _ = warn_unused_flags(&settings, given);
        // The EXR holds radiance; the exposure sets only the PNG preview, which a reference does not write.
        if given.iter().any(|g| g == "exposure") {
            log::warn!("--exposure: a reference writes radiance to an EXR and no preview, so the exposure changes nothing (give it to `compare`)");
        }
        return reference_main(&settings, out, *first_frame, *resume);
    }
    if let Some(Command::Results { out, scale, quick, runs, pt_frames, vpl_frames, checkpoints, no_flip, no_motion, device }) =
        &cli.command
    {
        if !(scale.is_finite() && *scale > 0.0 && *scale <= 4.0) {
            bail!("--scale {scale}: expected a number in (0, 4]");
        }
        let root = std::env::current_dir()?;
        let mut opts = if *quick {
            restir_vpl::eval::results::ResultsOptions::quick(&root)
        } else {
            restir_vpl::eval::results::ResultsOptions::full(&root, *scale)
        };
        // Checked before any reference renders, naming the flag (these were caught late, under
        // another flag's name).
        check_counts(&[("--runs", *runs), ("--pt-frames", *pt_frames), ("--vpl-frames", *vpl_frames)], checkpoints.as_deref())?;
        let out = out.clone().unwrap_or_else(|| PathBuf::from(if *quick { "bench-out/results-quick" } else { "docs" }));
        restir_vpl::output::prepare_output_dir("--out", &out)?;
        opts.out_dir = out;
        opts.runs = runs.unwrap_or(opts.runs);
        opts.pt_reference_frames = pt_frames.unwrap_or(opts.pt_reference_frames);
        opts.vpl_reference_frames = vpl_frames.unwrap_or(opts.vpl_reference_frames);
        if let Some(c) = checkpoints {
            opts.checkpoints = restir_vpl::eval::results::sorted_checkpoints(c);
        }
        opts.flip = !*no_flip;
        if *no_motion {
            opts.motion = None;
        }
        opts.device_index = *device;
        opts.command = command_line();
        return results_main(&opts);
    }
    if let Some(Command::Bench { scene, width, height, frames, device, json, photons, modes, moving, fusion, grid, workgroups, curves, motion, rays, radius, scaling, quick, out, checkpoints, runs }) =
        &cli.command
    {
        check_counts(&[("--runs", *runs)], checkpoints.as_deref())?;
        if *quick && !*curves && !*motion && !*radius && !*scaling {
            bail!("--quick goes with --curves, --motion, --radius or --scaling");
        }
        if runs.is_some() && !*curves && !*motion && !*radius {
            bail!("--runs goes with --curves, --motion or --radius");
        }
        // Each benchmark's own flags; another one given is refused, not ignored (`--rays --scene X`
        // measured the three scenes without a word).
        let (which, uses): (&str, &[&str]) = match () {
            _ if *scaling => ("--scaling", &["quick", "out", "device"]),
            _ if *radius => ("--radius", &["quick", "out", "runs", "device"]),
            _ if *motion => ("--motion", &["quick", "out", "runs", "device"]),
            _ if *curves => ("--curves", &["scene", "width", "height", "quick", "out", "checkpoints", "runs", "device"]),
            _ if *rays => ("--rays", &["width", "height", "frames", "json", "device"]),
            _ if *workgroups => ("--workgroups", &["scene", "width", "height", "frames", "json", "device"]),
            _ if *modes => ("--modes", &["scene", "width", "height", "frames", "json", "device", "moving", "fusion", "grid", "out"]),
            _ if *photons => ("--photons", &["scene", "frames", "device"]),
            _ => ("(the primary-ray and path-tracing benchmark)", &["scene", "width", "height", "frames", "json", "device"]),
        };
        let modes_flags = ["scaling", "radius", "motion", "curves", "rays", "workgroups", "modes", "photons"];
        let unused: Vec<String> =
            given.iter().filter(|id| !modes_flags.contains(&id.as_str()) && !uses.contains(&id.as_str())).map(|id| format!("--{id}")).collect();
        if !unused.is_empty() {
            bail!(
                "bench {which} does not use {}; it takes {}",
                unused.join(", "),
                uses.iter().map(|u| format!("--{u}")).collect::<Vec<_>>().join(", ")
            );
        }
        // Sizes and counts checked before anything runs, as a render's are (`--rays --width 0`
        // ran its raw dispatches before the first mode refused the size; a size past the frame
        // targets' limits bound a buffer beyond maxStorageBufferRange).
        if width.is_some() || height.is_some() {
            let d = RenderSettings::default();
            RenderSettings { width: width.unwrap_or(d.width), height: height.unwrap_or(d.height), ..d }.validate()?;
        }
        if *frames > MAX_BENCH_FRAMES {
            // (Warm-up frames are added to it: u32::MAX wrapped to "--frames 0".)
            bail!("--frames {frames}: a benchmark times at most {MAX_BENCH_FRAMES} frames");
        }
        // Outputs checked before the run, not when it ends.
        if let Some(path) = json {
            if restir_vpl::output::same_file(path, scene) {
                bail!("--json {}: is also the --scene; write the report to another file", path.display());
            }
            restir_vpl::output::prepare_output_file(path).map_err(|e| anyhow::anyhow!("--json {}: {e:#}", path.display()))?;
        }
        if *curves || *motion || *radius || *scaling {
            restir_vpl::output::prepare_output_dir("--out", out)?;
        }
        if *scaling {
            if runs.is_some() {
                bail!("--runs does not go with --scaling (it times every point in one run)");
            }
            let root = std::env::current_dir()?;
            let opts = if *quick {
                restir_vpl::eval::scaling::ScalingOptions::quick(&root)
            } else {
                restir_vpl::eval::scaling::ScalingOptions::full(&root)
            };
            let ctx = bench_context(*device)?;
            let points = restir_vpl::eval::scaling::run(&ctx, &opts, &mut |line| restir_vpl::errln!("{line}"))?;
            let md = write_report(
                out,
                "scaling.md",
                "How cost grows with the work (`bench --scaling`)",
                &restir_vpl::eval::scaling::markdown(&opts, &points, &ctx.report.name),
                &ctx.report.name,
                quick.then_some(" (two sizes a sweep: an exponent without its standard error)"),
            )?;
            let csv = out.join("scaling.csv");
            restir_vpl::eval::scaling::write_csv(&csv, &points)?;
            let plots = restir_vpl::eval::scaling::write_plots(out, &points)?;
            ctx.ensure_clean()?;
            restir_vpl::outln!("{}\n{}", md.display(), csv.display());
            for p in plots {
                restir_vpl::outln!("{}", p.display());
            }
            return Ok(());
        }
        if *radius {
            let root = std::env::current_dir()?;
            let mut opts = if *quick {
                restir_vpl::eval::radius::RadiusOptions::quick(&root)
            } else {
                restir_vpl::eval::radius::RadiusOptions::full(&root)
            };
            opts.out_dir = out.clone();
            opts.runs = runs.unwrap_or(opts.runs);
            let ctx = bench_context(*device)?;
            let rows = restir_vpl::eval::radius::run(&ctx, &opts, &mut |line| restir_vpl::errln!("{line}"))?;
            ctx.ensure_clean_report()?;
            let md = write_report(
                out,
                "radius.md",
                "The Yuksel radius as a trade-off (`bench --radius`)",
                &restir_vpl::eval::radius::markdown(&opts, &rows),
                &ctx.report.name,
                quick.then_some(" (FLIP not computed)"),
            )?;
            let csv = out.join("radius.csv");
            restir_vpl::eval::radius::write_csv(&csv, &rows)?;
            restir_vpl::outln!("{}\n{}", md.display(), csv.display());
            return Ok(());
        }
        if *motion {
            let root = std::env::current_dir()?;
            let mut opts = if *quick {
                restir_vpl::eval::motion::MotionOptions::quick(&root)
            } else {
                restir_vpl::eval::motion::MotionOptions::full(&root, 0.2)
            };
            opts.out_dir = out.clone();
            opts.runs = runs.unwrap_or(opts.runs);
            let ctx = bench_context(*device)?;
            let points = restir_vpl::eval::motion::run(&ctx, &opts, &mut |line| restir_vpl::errln!("{line}"))?;
            ctx.ensure_clean_report()?;
            let files = restir_vpl::eval::motion::write_outputs(out, &points)?;
            let md = write_report(
                out,
                "motion.md",
                "Moving camera: error of every displayed frame",
                &restir_vpl::eval::motion::section_markdown(&opts, &points, &files.plots),
                &ctx.report.name,
                quick.then_some(" (FLIP not computed)"),
            )?;
            restir_vpl::outln!("{}\n{}", md.display(), files.csv.display());
            for p in &files.plots {
                restir_vpl::outln!("{}", p.display());
            }
            return Ok(());
        }
        if *curves {
            let root = std::env::current_dir()?;
            let mut opts = if *quick {
                restir_vpl::eval::results::ResultsOptions::quick(&root)
            } else {
                restir_vpl::eval::results::ResultsOptions::full(&root, 0.25)
            };
            let default_side = if *quick { 64 } else { 320 };
            opts.scenes = vec![restir_vpl::eval::results::SceneSpec {
                path: scene.clone(),
                width: width.unwrap_or(default_side),
                height: height.unwrap_or(default_side),
            }];
            if *quick {
                opts.vpls_direct = 2_000;
                opts.vpls_indirect = 2_000;
            }
            opts.out_dir = out.clone();
            opts.markdown_name = "curves.md".into();
            // One scene's curves: the three-scene moving-camera study is `bench --motion`'s (it
            // ran here too, ~25 minutes on lavapipe, unasked).
            opts.motion = None;
            opts.device_index = *device;
            if let Some(c) = checkpoints {
                opts.checkpoints = restir_vpl::eval::results::sorted_checkpoints(c);
            }
            opts.runs = runs.unwrap_or(opts.runs);
            opts.command = command_line();
            return results_main(&opts);
        }
        if *frames == 0 {
            bail!("--frames 0: at least one timed frame is needed");
        }
        if *rays {
            let root = std::env::current_dir()?;
            let ctx = bench_context(*device)?;
            let (w, h) = (width.unwrap_or(1280), height.unwrap_or(720));
            if let Some(w) = restir_vpl::eval::rays::small_size_warning(w, h) {
                log::warn!("{w}");
            }
            let mut rows = Vec::new();
            for spec in restir_vpl::eval::results::thesis_scenes(&root, 1.0) {
                restir_vpl::errln!("bench --rays: {}", spec.path.display());
                rows.push(restir_vpl::eval::rays::measure(&ctx, &spec.path, w, h, *frames, *frames)?);
            }
            ctx.ensure_clean()?;
            restir_vpl::out!("{}", restir_vpl::eval::rays::markdown(&rows, &ctx.report.name));
            if let Some(path) = json {
                std::fs::write(path, serde_json::to_string_pretty(&rows)?)
                    .map_err(|e| anyhow::anyhow!("--json {}: {e}", path.display()))?;
            }
            return Ok(());
        }
        if *workgroups {
            let rows = restir_vpl::eval::bench::workgroups(scene, width.unwrap_or(1280), height.unwrap_or(720), *frames, *device)?;
            restir_vpl::out!("{}", restir_vpl::eval::bench::workgroups_markdown(&rows));
            if let Some(path) = json {
                std::fs::write(path, serde_json::to_string_pretty(&rows)?)
                    .map_err(|e| anyhow::anyhow!("--json {}: {e}", path.display()))?;
            }
            return Ok(());
        }
        if *modes && given.iter().any(|g| g == "out") {
            // The report docs/modes.md is: both cameras of the usual cases, on the three bundled
            // scenes (or --scene), at 1280×720 (or the size given), in one run.
            if *moving || *fusion || *grid {
                bail!("bench --modes --out writes the usual cases on both cameras; --moving, --fusion and --grid print one table (drop --out)");
            }
            restir_vpl::output::prepare_output_dir("--out", out)?;
            let scenes = if given.iter().any(|g| g == "scene") {
                vec![scene.clone()]
            } else {
                restir_vpl::eval::results::thesis_scenes(std::path::Path::new(""), 1.0).into_iter().map(|s| s.path).collect()
            };
            // Every scene's camera path before any timing (the moving half would fail after the still one).
            for path in &scenes {
                let file = restir_vpl::eval::motion::path_file(path);
                if !file.is_file() {
                    bail!("bench --modes --out: {} has no camera path beside it ({}), which the moving camera follows", path.display(), file.display());
                }
            }
            let size = (width.unwrap_or(1280), height.unwrap_or(720));
            let mut sections = Vec::new();
            let mut device_name = String::new();
            for path in &scenes {
                let (section, name) = restir_vpl::eval::bench::modes_section(path, size, *frames, *device)?;
                sections.push(section);
                device_name = name;
            }
            let body = restir_vpl::eval::bench::modes_report(&sections, *frames, &device_name, &command_line());
            // (The body says how it was made, date included.)
            let md = write_markdown(out, "modes.md", &format!("# VPL modes: frame cost (`restir-vpl bench --modes`)\n\n{body}"))?;
            if let Some(path) = json {
                let rows: Vec<_> = sections.iter().flat_map(|s| s.rows.iter()).collect();
                std::fs::write(path, serde_json::to_string_pretty(&rows)?).map_err(|e| anyhow::anyhow!("--json {}: {e}", path.display()))?;
            }
            restir_vpl::outln!("{}", md.display());
            return Ok(());
        }
        if *modes {
            let sizes = if width.is_some() || height.is_some() {
                vec![(width.unwrap_or(512), height.unwrap_or(512))]
            } else {
                vec![(1280, 720), (1280, 1280)]
            };
            let rows = restir_vpl::eval::bench::modes(scene, &sizes, 100_000, 100_000, *frames, *device, *moving, *fusion, *grid)?;
            restir_vpl::out!("{}", restir_vpl::eval::bench::modes_markdown(&rows));
            if let Some(path) = json {
                std::fs::write(path, serde_json::to_string_pretty(&rows)?)
                    .map_err(|e| anyhow::anyhow!("--json {}: {e}", path.display()))?;
            }
            return Ok(());
        }
        if *photons {
            // (It was capped at 5 without a word.)
            let runs = *frames;
            let loaded = restir_vpl::scene::Scene::load(scene)?;
            let dense = restir_vpl::eval::bench::dense_scene(160, 320)?;
            restir_vpl::outln!("| scene | triangles | VPLs (direct + indirect) | photon paths | closest-hit rays | GPU ms (median of {runs}) | M paths/s | M rays/s (path batches' time) |");
            restir_vpl::outln!("|---|---:|---:|---:|---:|---:|---:|---:|");
            for (s, label) in [(&loaded, scene.display().to_string()), (&dense, "generated bumpy sphere in a room".to_string())] {
                let b = restir_vpl::eval::bench::photons(s, &label, 100_000, 100_000, runs, *device)?;
                restir_vpl::outln!(
                    "| {} | {} | {} + {} | {} | {} | {:.1} | {:.2} | {:.2} |",
                    b.scene,
                    b.triangles,
                    b.direct,
                    b.indirect_vpls,
                    b.paths,
                    b.rays,
                    b.gpu_ms,
                    b.paths_per_second * 1e-6,
                    b.rays_per_second * 1e-6
                );
            }
            return Ok(());
        }
        let report = restir_vpl::eval::bench::core(scene, width.unwrap_or(512), height.unwrap_or(512), *frames, *device)?;
        restir_vpl::out!("{}", report.markdown());
        if let Some(path) = json {
            std::fs::write(path, serde_json::to_string_pretty(&report)?)
                .map_err(|e| anyhow::anyhow!("--json {}: {e}", path.display()))?;
        }
        return Ok(());
    }
    if cli.list_devices {
        // No driver, or no device: the listing is empty and succeeds, with the text a render's
        // error gives (which names the driver files where the loader found no driver).
        let devices = match restir_vpl::vk::context::list_devices(cli.render.trace.and_then(TraceArg::tracing)) {
            Err(e) if e.downcast_ref::<NoTracingDevice>().is_some() => {
                restir_vpl::outln!("{e}");
                Vec::new()
            }
            listed => listed?,
        };
        for d in devices {
            restir_vpl::outln!("{d}");
        }
        return Ok(());
    }
    let settings = settings_from(&cli.render, Some(cli.out.clone()))?;
    settings.validate()?;
    if cli.headless && cli.present_mode.is_some() {
        bail!("--present-mode sets how the window's frames wait for the display; a headless run has no window");
    }
    if cli.headless && cli.reference.is_some() {
        bail!("--reference shows a split screen in the window; headless runs compare with `restir-vpl compare`");
    }
    // The window does not do a headless run's extra outputs and checks (they were accepted and
    // did nothing there: a --check-finite window checked no frame).
    let headless_only = headless_only_flags(&settings);
    if !cli.headless && !headless_only.is_empty() {
        bail!(
            "{}: done by --headless runs only; the window has Enter (write final.exr, final.png and summary.json to --out at any frame), \
             F4 (dump the next frame's passes to --out/passes) and F12 (a RenderDoc capture)",
            headless_only.join(", ")
        );
    }
    let summary = if cli.headless {
        let noted = warn_unused_flags(&settings, given);
        restir_vpl::headless::run_noting(&settings, noted)?.summary
    } else {
        let opts = restir_vpl::window::WindowOptions {
            present_mode: cli.present_mode.unwrap_or_default(),
            frames: cli.render.frames,
            reference: cli.reference.clone(),
        };
        match restir_vpl::window::run(settings, opts)? {
            Some(summary) => summary,
            None => return Ok(()),
        }
    };
    let s = &summary;
    let settings = &s.settings;
    restir_vpl::outln!("device: {}", s.device);
    let plural = |n: usize, one: &str| if n == 1 { format!("1 {one}") } else { format!("{n} {one}s") };
    let triangles = s.scene.area_lights - s.scene.point_lights;
    let lights = match s.scene.point_lights {
        0 => plural(triangles, "emissive triangle"),
        points => format!("{} and {}", plural(triangles, "emissive triangle"), plural(points, "point light")),
    };
    restir_vpl::outln!("scene: {} ({} triangles; lights: {lights})", s.scene.path, s.scene.triangles);
    restir_vpl::outln!(
        "{} of {}x{} ({}), {:.2} rays/pixel/frame",
        plural(s.frames as usize, "frame"),
        settings.width,
        settings.height,
        settings.mode.name(),
        s.rays_per_pixel.mean
    );
    if s.accumulated_frames < s.frames {
        // (summary.json said so; the printout read as if final.exr averaged every frame.)
        // Why, in this run's terms (a reservoir view was told "--progressive off").
        let why = if settings.view.shows_reservoirs() {
            format!("--view {} shows one frame's reservoirs, not a mean", settings.view.name())
        } else if !settings.progressive {
            "--progressive off: every image is its frame alone".to_string()
        } else if settings.camera_path.is_some() {
            "the accumulation starts again each frame the --camera-path camera moves".to_string()
        } else {
            "the accumulation starts again when the camera or a setting changes".to_string()
        };
        restir_vpl::outln!(
            "final image: {} ({why})",
            match s.accumulated_frames {
                1 => "the last frame alone".to_string(),
                n => format!("the mean of the last {n} frames"),
            }
        );
    }
    if let Some(p) = &s.photons {
        restir_vpl::outln!(
            "photon_emit (once, static scene): {:.2} GPU ms, {} paths ({:.2} M paths/s), {} closest-hit rays, {} direct + {} indirect VPLs",
            p.gpu_ms,
            p.paths,
            p.paths_per_second * 1e-6,
            p.rays,
            p.direct_vpls,
            p.indirect_vpls
        );
    }
    if let Some(v) = &s.vpl {
        restir_vpl::outln!(
            "vpl: {} VPLs, {} candidate(s) ({} source{}{}), Yuksel r = {}{}{}",
            v.vpl_count,
            v.candidates,
            v.candidate_source,
            if v.presample { ", presampled tiles" } else { "" },
            v.grid
                .map(|g| format!(
                    ", {} from a ReGIR grid of {}³ cells × {} entries of {} candidates, {} cells built in the last frame",
                    g.candidates,
                    g.cells,
                    g.entries,
                    g.entry_candidates,
                    v.grid_cells_built.map_or("?".to_string(), |n| n.to_string())
                ))
                .unwrap_or_default(),
            v.yuksel_radius.map(|r| format!("{r:.4}")).unwrap_or_else(|| "- (inverse square)".into()),
            // Only ReSTIR has targets to reuse and reuse to bias (the line said "unbiased reuse:
            // false" for uniform sampling).
            if settings.mode == Mode::Restir {
                format!(", targets with visibility: {}, unbiased reuse: {}", v.initial_visibility, v.unbiased_reuse)
            } else {
                String::new()
            },
            v.spatial_radius_px.map(|r| format!(", spatial radius {r:.1} px")).unwrap_or_default()
        );
        if let (Some([c, n]), m @ 1..) = (v.moving_sampling, v.moving_frames) {
            restir_vpl::outln!(
                "  {m} frame(s) displayed alone with temporal history ran with {c} candidates and {n} neighbours, {} and {} for a pixel without history (--moving-candidates, --moving-neighbours)",
                settings.candidates, settings.restir.spatial_neighbours
            );
        }
    }
    // A pass's first dispatch apart: lavapipe compiles a shader when it is first dispatched (from
    // its disk cache after the first run), which once made a pass that ran once read 998 ms for 2.
    restir_vpl::outln!("GPU ms per pass: first dispatch (with a cold shader cache, lavapipe compiles the shader in it), then median / min / max of the later ones; rays per pixel per frame (mean):");
    for (name, t) in &s.pass_ms_after_first {
        let first = s.pass_first_ms.get(name).copied().unwrap_or(f64::NAN);
        let rays = s.rays_per_pixel_by_pass.get(name).map(|r| format!("{:>8.2} rays/px", r.mean)).unwrap_or_default();
        let later = if t.count > 0 { format!("{:>9.2} {:>9.2} {:>9.2}", t.median, t.min, t.max) } else { format!("{:>29}", "(ran once)") };
        restir_vpl::outln!("  {name:<24} {first:>9.2} {later} {rays}");
    }
    restir_vpl::outln!(
        "ms per frame: {:.2} GPU, {:.2} wall from recording to completion (median); the first frame {:.2} GPU; total {:.2} s",
        s.gpu_ms_per_frame.median, s.wall_ms_per_frame.median, s.gpu_ms_first_frame, s.total_seconds
    );
    if let Some(d) = &s.displayed {
        // The window records a frame while the one before still runs, so a frame's wall time
        // holds its wait behind that one (about twice the GPU time): how often frames were shown
        // is the window's frame time.
        restir_vpl::outln!(
            "window: a frame shown every {:.2} ms ({:.1} fps, {} timed frames, {} presents); with two frames in flight each frame's wall time above includes its wait behind the previous one",
            d.ms_per_frame, d.fps, d.frames, d.present_mode
        );
    }
    if s.nonfinite_samples > 0 {
        restir_vpl::outln!("non-finite samples replaced by 0: {}", s.nonfinite_samples);
    }
    for w in &s.warnings {
        restir_vpl::outln!("warning: {w}");
    }
    restir_vpl::outln!("outputs:");
    for o in &s.outputs {
        restir_vpl::outln!("  {o}");
    }
    if let Some(dir) = &settings.out_dir {
        restir_vpl::outln!("  {}", dir.join("summary.json").display());
    }
    // Asked for (--validate), the layer's errors fail the run, after the outputs are written, and
    // so do non-finite samples (a shader bug that the accumulation hides by writing 0).
    if s.validation_errors > 0 {
        bail!("{} Vulkan validation error(s) under --validate (the first is in the warnings above)", s.validation_errors);
    }
    if settings.validate && s.nonfinite_samples > 0 {
        bail!("{} non-finite sample(s) (NaN or Inf, replaced by 0 in the images) under --validate: a shader produced them", s.nonfinite_samples);
    }
    Ok(())
}

fn reference_main(settings: &RenderSettings, out: &std::path::Path, first_frame: u64, resume: bool) -> Result<()> {
    use restir_vpl::eval::reference::{make_reference, reference_mode_ok, ReferenceTarget};
    reference_mode_ok(settings)?;
    let target = if resume {
        // (--first-frame is refused with it by the parser, 0 included.)
        ReferenceTarget::Extend { frames: settings.frames }
    } else {
        ReferenceTarget::New { first_frame, frames: settings.frames }
    };
    // Before the device and the scene, as well as before the frames (make_reference checks again).
    restir_vpl::output::check_image_extension("--out", out, "exr")?;
    restir_vpl::output::prepare_output_file(out).map_err(|e| anyhow::anyhow!("--out {}: {e:#}", out.display()))?;
    let (ctx, scene) = upload(settings)?;
    let mut next_report = 0u32;
    let started = std::time::Instant::now();
    let made = make_reference(&ctx, &scene, settings, out, target, &mut |done, total| {
        if done >= next_report || done == total {
            restir_vpl::err!("\r{done}/{total} frames, {:.0} s", started.elapsed().as_secs_f64());
            next_report = done + (total / 20).max(1);
        }
    })?;
    restir_vpl::errln!();
    ctx.ensure_clean_report().map_err(|e| anyhow::anyhow!("{}: written, but {e:#}", out.display()))?;
    let meta = &made.meta;
    restir_vpl::outln!("{}: {} {}x{} of {}", out.display(), meta.mode, meta.width, meta.height, meta.scene);
    restir_vpl::outln!("frames: {}", meta.describe_frames());
    if let Some(mse) = meta.noise_mse {
        restir_vpl::outln!("estimated noise RMSE of the reference (sqrt(mean variance / frames)): {:.3e}", mse.sqrt());
    }
    if let Some((frames, gpu_ms, wall_ms)) = made.rendered {
        restir_vpl::outln!("this run: {frames} frames in {:.1} s wall, {:.1} s GPU", wall_ms * 1e-3, gpu_ms * 1e-3);
    }
    Ok(())
}

/// Counts given on the command line (`--runs`, frame counts) are at least 1, and so is every
/// `--checkpoints` entry (accumulated frame counts).
fn check_counts(counts: &[(&str, Option<u32>)], checkpoints: Option<&[u32]>) -> Result<()> {
    if let Some((flag, _)) = counts.iter().find(|(_, v)| *v == Some(0)) {
        bail!("{flag} 0: at least 1 is needed");
    }
    match checkpoints {
        Some(c) if c.is_empty() || c.contains(&0) => bail!("--checkpoints {c:?}: every checkpoint is a frame count of at least 1"),
        _ => Ok(()),
    }
}

/// `RESTIR_VPL_VALIDATE=1`: the Khronos validation layer, as `--validate` asks for it (the only
/// way for `bench` and `results`, which take no render flags).
/// Unset or empty, 0, false, no or off: off; 1, true, yes or on: on; anything else is refused by
/// name (`true` was taken for off without a word).
fn env_validate() -> Result<bool> {
    restir_vpl::settings::env_switch("RESTIR_VPL_VALIDATE", false)
}

/// The context of the benchmarks that take one (under the validation layer with
/// `RESTIR_VPL_VALIDATE=1`; the timing benchmarks `--modes`, `--photons`, `--workgroups` and the
/// primary-ray one make their own without it).
fn bench_context(device: Option<usize>) -> Result<std::sync::Arc<restir_vpl::vk::Context>> {
    Ok(std::sync::Arc::new(restir_vpl::vk::Context::new(&restir_vpl::vk::ContextOptions {
        validate: env_validate()?,
        device_index: device,
        ..Default::default()
    })?))
}

/// Writes a benchmark's report `OUT/name`: its title, then how it was made (the command, the date,
/// the device; a `--quick` run, `quick` given, says it is a smoke test and what it leaves out),
/// then `body`. (A quick report read like the measurement itself, and no report had a date.)
fn write_report(out: &std::path::Path, name: &str, title: &str, body: &str, device: &str, quick: Option<&str>) -> Result<PathBuf> {
    let mut made = format!("_Generated by `{}` on {} (UTC) on **{device}**._", command_line(), restir_vpl::eval::report::utc_date());
    if let Some(skips) = quick {
        made += &format!(" **Quick run** (`--quick`): a smoke test of the pipeline at tiny sizes and counts{skips}, not a measurement.");
    }
    write_markdown(out, name, &format!("# {title}\n\n{made}\n\n{body}"))
}

/// Writes `text` to `OUT/name` whole (or leaves the earlier file), creating OUT; its path.
fn write_markdown(out: &std::path::Path, name: &str, text: &str) -> Result<PathBuf> {
    std::fs::create_dir_all(out).map_err(|e| anyhow::anyhow!("--out {}: {e}", out.display()))?;
    let md = out.join(name);
    restir_vpl::output::write_text(&md, text)?;
    Ok(md)
}

/// This run's command line as a report quotes it: `restir-vpl` and the arguments given.
fn command_line() -> String {
    std::iter::once("restir-vpl".to_string()).chain(std::env::args().skip(1)).collect::<Vec<_>>().join(" ")
}

/// A context for `settings` (validation, device) with the scene loaded and uploaded to it.
fn upload(settings: &RenderSettings) -> Result<(std::sync::Arc<restir_vpl::vk::Context>, std::sync::Arc<restir_vpl::scene_gpu::SceneGpu>)> {
    let range = || restir_vpl::vk::context::storage_buffer_range(settings.device_index, settings.tracing);
    let scene = restir_vpl::scene::Scene::load_for_device(&settings.scene, settings.textures, &range)?;
    let ctx = std::sync::Arc::new(restir_vpl::vk::Context::new(&restir_vpl::vk::ContextOptions {
        validate: settings.validate,
        device_index: settings.device_index,
        tracing: settings.tracing,
        ..Default::default()
    })?);
    let gpu = restir_vpl::scene_gpu::SceneGpu::new(&ctx, &scene, settings.textures, settings.merge_blas)?;
    Ok((ctx, std::sync::Arc::new(gpu)))
}

fn results_main(opts: &restir_vpl::eval::results::ResultsOptions) -> Result<()> {
    let ctx = std::sync::Arc::new(restir_vpl::vk::Context::new(&restir_vpl::vk::ContextOptions {
        validate: opts.validate || env_validate()?,
        device_index: opts.device_index,
        ..Default::default()
    })?);
    let out = restir_vpl::eval::results::run(&ctx, opts, &mut |line| restir_vpl::errln!("{line}"))?;
    // (results::run has written its files by now.)
    ctx.ensure_clean_report().map_err(|e| anyhow::anyhow!("{}: written, but {e:#}", out.markdown.display()))?;
    restir_vpl::outln!("{}", out.markdown.display());
    restir_vpl::outln!("{}", out.csv.display());
    restir_vpl::outln!("{}", out.frame_times_csv.display());
    // (It was written and cited, and not listed.)
    if let Some(csv) = &out.motion_csv {
        restir_vpl::outln!("{}", csv.display());
    }
    for p in &out.plots {
        restir_vpl::outln!("{}", p.display());
    }
    Ok(())
}

/// The ids of the arguments given on the command line (not defaults, not the environment). The
/// derive's argument groups ("Cli", "RenderArgs", "Bench") are among a match's ids: their names
/// start with a capital, the arguments' never do.
fn flags_on_command_line(matches: &clap::ArgMatches) -> impl Iterator<Item = &str> {
    matches
        .ids()
        .map(|id| id.as_str())
        .filter(|id| id.starts_with(|c: char| c.is_ascii_lowercase()))
        .filter(|id| matches.value_source(id) == Some(clap::parser::ValueSource::CommandLine))
}

/// The render flags given on the command line (clap ids, as `RenderSettings::unused_flags` takes
/// them), of the main command or of `reference`; `bench`'s own flags for `bench`; none for the
/// other subcommands.
fn given_render_flags(matches: &clap::ArgMatches) -> Vec<String> {
    let m = match matches.subcommand() {
        Some(("reference", sub)) => sub,
        Some(("bench", sub)) => return flags_on_command_line(sub).map(str::to_string).collect(),
        Some(_) => return Vec::new(),
        None => matches,
    };
    RenderArgs::augment_args(clap::Command::new("render"))
        .get_arguments()
        .map(|a| a.get_id().as_str().to_string())
        .filter(|id| m.value_source(id) == Some(clap::parser::ValueSource::CommandLine))
        .collect()
}

/// The flags given among those that only a headless run acts on: its extra outputs and checks.
fn headless_only_flags(settings: &RenderSettings) -> Vec<&'static str> {
    [
        ("--dump-vpls", settings.dump_vpls.is_some()),
        ("--dump-passes", settings.dump_passes.is_some()),
        ("--save-every", settings.save_every > 0),
        ("--check-finite", settings.check_finite),
        ("--renderdoc-capture", settings.renderdoc_capture.is_some()),
    ]
    .into_iter()
    .filter_map(|(flag, given)| given.then_some(flag))
    .collect()
}

/// Prints the warnings about the command line (flags the run never reads or reads in part,
/// settings that bias it or leave it black) and returns them, for the summary's `warnings`.
fn warn_unused_flags(settings: &RenderSettings, given: &[String]) -> Vec<String> {
    let given: Vec<&str> = given.iter().map(String::as_str).collect();
    let mut out: Vec<String> = settings.unused_flags(&given).into_iter().chain(settings.bounded_flags(&given)).chain(settings.bias_warnings()).collect();
    if let Some(dir) = settings.out_dir.as_deref().filter(|d| d.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr") || e.eq_ignore_ascii_case("png"))) {
        out.push(format!("--out {}: names the directory the run writes final.exr, final.png and summary.json into, not an image file", dir.display()));
    }
    if settings.save_every > settings.frames {
        out.push(format!("--save-every {} is more than --frames {}: no snapshot is written", settings.save_every, settings.frames));
    }
    if settings.view == restir_vpl::settings::View::Indirect && !settings.gi {
        out.push("--view indirect with --no-gi: the image is black (--no-gi traces no indirect VPLs)".to_string());
    }
    if settings.mode.uses_vpls() && settings.view != restir_vpl::settings::View::Vpls && !settings.gi && settings.vpls_direct == 0 {
        out.push("--vpls-direct 0 with --no-gi: the VPL set is empty, so nothing is lit; only emitters seen directly show".to_string());
    }
    for w in &out {
        log::warn!("{w}");
    }
    out
}

/// A 32-bit float flag's value, read as f64 first: a finite value beyond f32 ("--mcap 1e39") is
/// refused as such (it became inf, and the flag's own check then quoted "inf", not what was
/// typed). NaN and the infinities pass, for each flag's own range check to name.
fn parse_f32(s: &str) -> Result<f32, String> {
    let v: f64 = s.trim().parse().map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() && v.abs() > f64::from(f32::MAX) {
        return Err(format!("{s} is beyond 32-bit floats (at most ±{:e})", f32::MAX));
    }
    Ok(v as f32)
}

/// The long flags (`--name`) of `cmd` and its subcommands that take a value. Their values may
/// start with a minus sign without being plain numbers ("-1,0,0", "-.5", "-inf", "-8x8"): clap's
/// `allow_negative_numbers` takes only plain numbers and reads the rest as unknown flags
/// ("unexpected argument '-.' found", not naming the flag: `--normal-threshold -.5`, a value in
/// its range, was refused so), and `allow_hyphen_values` would also take a following flag as the
/// value (`--eye --target …`).
fn value_flags(cmd: &clap::Command) -> std::collections::BTreeSet<String> {
    let mut out: std::collections::BTreeSet<String> = cmd
        .get_arguments()
        .filter(|a| a.get_action().takes_values())
        .filter_map(|a| a.get_long().map(|l| format!("--{l}")))
        .collect();
    for sub in cmd.get_subcommands() {
        out.extend(value_flags(sub));
    }
    out
}

/// `--eye -1,0,0` becomes `--eye=-1,0,0` for the flags in `flags` (those that take a value) when
/// the value looks like a signed value (a minus sign, then a digit, '.', or the start of inf/nan),
/// so the flag's own parser judges it; anything after `--` is left alone.
fn join_signed_values(args: Vec<std::ffi::OsString>, flags: &std::collections::BTreeSet<String>) -> Vec<std::ffi::OsString> {
    let mut out = Vec::with_capacity(args.len());
    let mut it = args.into_iter().peekable();
    while let Some(a) = it.next() {
        if a == "--" {
            out.push(a);
            out.extend(it);
            break;
        }
        let signed_next = it.peek().and_then(|n| n.to_str()).is_some_and(|n| {
            n.strip_prefix('-').and_then(|r| r.chars().next()).is_some_and(|c| c.is_ascii_digit() || ".iInN".contains(c))
        });
        match a.to_str() {
            Some(flag) if signed_next && flags.contains(flag) => {
                let value = it.next().expect("peeked");
                let mut joined = std::ffi::OsString::from(format!("{flag}="));
                joined.push(value);
                out.push(joined);
            }
            _ => out.push(a),
        }
    }
    out
}

/// The most frames a benchmark times (`bench --frames`).
const MAX_BENCH_FRAMES: u32 = 1_000_000;

/// `--list-devices` takes only `--trace` (the way of tracing it reports for) and `--verbose`.
fn list_devices_alone(matches: &clap::ArgMatches) -> Result<()> {
    let others: Vec<String> = flags_on_command_line(matches)
        .filter(|id| !["list_devices", "trace", "verbose"].contains(id))
        .map(|id| format!("--{}", id.replace('_', "-")))
        .collect();
    anyhow::ensure!(
        others.is_empty(),
        "--list-devices lists the devices and exits: it takes only --trace and --verbose, not {}",
        others.join(", ")
    );
    Ok(())
}

/// `reference`'s command as its help should read: the render flags it refuses (a headless run's
/// extra outputs and checks, `--camera-path`) are hidden, still parsed so that their refusal
/// names them; `--frames` loses the window's sentence.
fn reference_help(c: clap::Command) -> clap::Command {
    c.mut_subcommand("reference", |r| {
        ["save_every", "dump_vpls", "dump_passes", "check_finite", "renderdoc_capture", "camera_path"]
            .into_iter()
            .fold(r, |r, id| r.mut_arg(id, |a| a.hide(true)))
            .mut_arg("frames", |a| a.help("Frames this run renders and averages (with --resume: the frames added to the file's) [default: 20]"))
    })
}

fn main() -> ExitCode {
    let command = reference_help(Cli::command());
    let flags = value_flags(&command);
    let matches = command.get_matches_from(join_signed_values(std::env::args_os().collect(), &flags));
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let given = given_render_flags(&matches);
    restir_vpl::logger::init(cli.render.verbose);
    if cli.list_devices {
        // It lists and exits: any other flag was silently ignored (even a missing scene or a bad
        // size passed). Clap refuses it with a command.
        if let Err(e) = list_devices_alone(&matches) {
            restir_vpl::errln!("error: {e:#}");
            return ExitCode::from(2);
        }
    }
    // An explicit --trace, auto included, wins over RESTIR_VPL_TRACE, which a context reads when
    // its settings name no way of tracing (auto names none): removed before any context is made,
    // while the process has one thread.
    if cli.render.trace.is_some() {
        std::env::remove_var("RESTIR_VPL_TRACE");
    }
    let code = match real_main(cli, &given) {
        Ok(()) => 0,
        Err(e) => {
            restir_vpl::errln!("error: {e:#}");
            if e.downcast_ref::<NoTracingDevice>().is_some() || e.downcast_ref::<restir_vpl::eval::compare::BadArgument>().is_some() {
                2
            } else if e.downcast_ref::<restir_vpl::eval::compare::NonFiniteInput>().is_some() {
                3
            } else {
                1
            }
        }
    };
    if restir_vpl::vk::context::a_device_hung() {
        // The device may still run the submission that passed the limit, and NVIDIA's driver
        // waits for it in its exit handlers for ever (docs/gpu.md, stop 51): end without them.
        restir_vpl::errln!("warning: the process ends without the Vulkan driver's exit handlers, since a submission did not finish");
        use std::io::Write as _;
        let _ = std::io::stdout().flush();
        let _ = std::io::stderr().flush();
        // SAFETY: _exit ends the process at once; every file this run writes was written and
        // closed (flushed above for the standard streams) before real_main returned.
        #[cfg(unix)]
        unsafe {
            libc::_exit(code)
        }
        #[cfg(not(unix))]
        std::process::exit(code);
    }
    ExitCode::from(code as u8)
}
