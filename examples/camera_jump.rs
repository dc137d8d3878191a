//! The frame right after a camera jump, where the moving sampling matters most: ReSTIR looks at
//! the Cornell box from its first camera for a while (frames displayed alone, history full), then
//! the camera jumps to a new view and that one frame is compared with a path-traced reference of
//! the new view. Two jumps: into the box's corner from inside (few surfaces keep history) and to
//! the camera path's last camera (most do). Unbiased ReSTIR with the default sampling of frames
//! displayed alone, against the still sampling on every frame (`--moving-candidates 0
//! --moving-neighbours 0`); the runs share their seeds, so the share is paired run by run.
//! docs/performance.md, "Pixels without history", has what it measured.
//!
//! `cargo run --release --example camera_jump -- [RUNS] [OUT]`
//! RUNS: seeds (default 8). OUT: where the references are cached (default bench-out).

use std::sync::Arc;

use anyhow::Context as _;
use glam::Vec3;
use restir_vpl::camera::{Camera, CameraPath};
use restir_vpl::eval::compare::{compare, CompareOptions};
use restir_vpl::eval::reference::{make_reference, ReferenceTarget};
use restir_vpl::eval::report::OverRuns;
use restir_vpl::output::RgbImage;
use restir_vpl::renderer::Renderer;
use restir_vpl::settings::{Bias, Mode, RenderSettings, RestirSettings};
use restir_vpl::vk::Context;

/// Frames at the first camera before the jump.
const BEFORE: u32 = 8;
/// Path-traced frames of each reference.
const REFERENCE_FRAMES: u32 = 256;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let runs: u32 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(8);
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out = root.join(args.get(2).map(String::as_str).unwrap_or("bench-out"));
    let spec = restir_vpl::eval::results::thesis_scenes(&root, 0.2)
        .into_iter()
        .find(|s| s.label() == "cornell_box")
        .context("the Cornell box among the thesis scenes")?;
    let ctx = Arc::new(Context::new(&Default::default())?);
    let scene = spec.upload(&ctx)?;
    let base = RenderSettings { progressive: false, ..spec.base_settings((100_000, 100_000), false, None) };
    let path = CameraPath::load(&root.join("scenes/cornell_box.path.json"))?.moved(-scene.info.origin);
    let start = path.at(0.0);
    let up = Vec3::Y;
    let corner = Camera::look_at(Vec3::new(0.45, 0.4, 0.1), Vec3::new(0.05, 0.1, 0.5), up, start.yfov, "corner");
    let jumps = [("into the corner", "corner", corner), ("to the path's last camera", "last", path.at(31.0))];
    let variants = [
        ("default", RestirSettings { bias: Bias::Unbiased, initial_visibility: Some(false), ..Default::default() }),
        (
            "still sampling",
            RestirSettings { bias: Bias::Unbiased, initial_visibility: Some(false), moving_candidates: 0, moving_neighbours: 0, ..Default::default() },
        ),
    ];
    println!("| jump | {} / {}'s RMSE (± s.e. over {runs} paired seeds) | RMSE | GPU ms of the jump frame |", variants[0].0, variants[1].0);
    println!("|---|---:|---:|---:|");
    for (name, tag, camera) in jumps {
        let settings = RenderSettings { mode: Mode::Pt, camera: Some(camera.as_override(scene.info.origin)), progressive: true, ..base.clone() };
        let file = out.join("references").join(format!("cornell_box_{}x{}_jump_{tag}_pt.exr", spec.width, spec.height));
        let reference = make_reference(&ctx, &scene, &settings, &file, ReferenceTarget::AtLeast { frames: REFERENCE_FRAMES }, &mut |_, _| {})?.image;
        let mut renderers = variants
            .iter()
            .map(|(_, restir)| Renderer::new(ctx.clone(), scene.clone(), RenderSettings { mode: Mode::Restir, restir: *restir, ..base.clone() }))
            .collect::<anyhow::Result<Vec<_>>>()?;
        let (mut ratio, mut rmse, mut ms) = (OverRuns::default(), OverRuns::default(), OverRuns::default());
        let mut per_seed = Vec::new();
        for run in 0..runs {
            let mut e = Vec::new();
            for (i, r) in renderers.iter_mut().enumerate() {
                r.restart(restir_vpl::eval::run_seed(base.seed, run))?;
                for _ in 0..BEFORE {
                    r.render_frame(&start, false)?;
                }
                let stats = r.render_frame(&camera, false)?;
                let img = RgbImage { width: spec.width, height: spec.height, pixels: r.read_mean()? };
                anyhow::ensure!(img.pixels.iter().flatten().all(|c| c.is_finite()), "a non-finite pixel in the jump frame");
                e.push(compare(&img, &reference, &CompareOptions::default())?.rmse);
                if i == 0 {
                    ms.add(stats.gpu_ms());
                }
            }
            ratio.add(e[0] / e[1]);
            per_seed.push(format!("{:.5}", e[0]));
            rmse.add(e[0]);
        }
        println!(
            "| {name} | {:.3} ± {:.3} | {:.4} | {:.1} |",
            ratio.mean(),
            ratio.standard_error().unwrap_or(f64::NAN),
            rmse.rms(),
            ms.mean()
        );
        // Each seed's RMSE of the default, to pair with another build's (the same seeds).
        eprintln!("{tag} default per seed: {}", per_seed.join(" "));
    }
    Ok(())
}
