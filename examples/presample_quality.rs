//! Error of RIS and ReSTIR with and without light presampling (`--presample`), and of ReSTIR's
//! candidate × neighbour settings, against a long RIS accumulation of the same VPL set (the VPL
//! model's answer, so the VPL bias does not mask the variance).
//!
//! `cargo run --release --example presample_quality -- [SCENE] [W] [H] [REF_FRAMES] [VARIANTS] [SEEDS]`
//! VARIANTS: comma-separated `ris:on`, `restir:off/16/4`, `restir:on/32/8/10`
//! (mode:presample[/candidates[/neighbours[/spatial radius in pixels[/grid candidates[/grid cells[/grid entries[/constant]]]]]]];
//! defaults 32, 8, 20, 0 (no ReGIR grid), 16, 64, balance-heuristic weights).
//! Per variant: mean relMSE of single frames 5..16 (what a moving camera shows; ± the standard error
//! over the seeds of each seed's mean), of the accumulated
//! image after 1 and 16 frames, and the median GPU ms per frame, over SEEDS runs.

use std::sync::Arc;

use restir_vpl::eval::compare::{compare, CompareOptions};
use restir_vpl::output::RgbImage;
use restir_vpl::renderer::Renderer;
use restir_vpl::scene::Scene;
use restir_vpl::scene_gpu::SceneGpu;
use restir_vpl::settings::{Mode, RenderSettings, RestirSettings};
use restir_vpl::vk::Context;

/// relMSE (mean of (a − b)² / (b² + 0.01)) through the library's `compare`.
fn rel_mse(a: &[[f32; 3]], b: &[[f32; 3]], w: u32, h: u32) -> anyhow::Result<f64> {
    let img = |p: &[[f32; 3]]| RgbImage { width: w, height: h, pixels: p.to_vec() };
    Ok(compare(&img(a), &img(b), &CompareOptions { flip: false, ..Default::default() })?.relmse)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
    let scene_path = arg(1, "scenes/cornell_box.gltf");
    let (w, h): (u32, u32) = (arg(2, "640").parse()?, arg(3, "360").parse()?);
    let ref_frames: u32 = arg(4, "300").parse()?;
    let variants = arg(5, "ris:on,ris:off,restir:on,restir:off");
    let seeds: u32 = arg(6, "6").parse()?;
    let ctx = Arc::new(Context::new(&Default::default())?);
    let scene = Arc::new(SceneGpu::new(&ctx, &Scene::load(std::path::Path::new(&scene_path))?, true, restir_vpl::vk::accel::MERGE_MAX_TRIANGLES)?);
    let base = RenderSettings { scene: scene_path.clone().into(), width: w, height: h, ..Default::default() };
    let reference = {
        let s = RenderSettings { mode: Mode::Ris, presample: false, seed: 999, frames: ref_frames, ..base.clone() };
        let mut r = Renderer::new(ctx.clone(), scene.clone(), s)?;
        let camera = r.initial_camera();
        for _ in 0..ref_frames {
            r.render_frame(&camera, false)?;
        }
        r.read_mean()?
    };
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    for v in variants.split(',') {
        let (mode, rest) = v.split_once(':').ok_or_else(|| anyhow::anyhow!("variant {v}: expected mode:on|off[/c[/n[/r]]]"))?;
        let parts: Vec<&str> = rest.split('/').collect();
        let mode = if mode == "ris" { Mode::Ris } else { Mode::Restir };
        let candidates: u32 = parts.get(1).unwrap_or(&"32").parse()?;
        let neighbours: u32 = parts.get(2).unwrap_or(&"8").parse()?;
        let radius: f32 = parts.get(3).unwrap_or(&"20").parse()?;
        let grid = restir_vpl::settings::GridSettings {
            candidates: parts.get(4).unwrap_or(&"0").parse()?,
            cells: parts.get(5).unwrap_or(&"16").parse()?,
            entries: parts.get(6).unwrap_or(&"64").parse()?,
            balance: parts.get(7) != Some(&"constant"),
            ..Default::default()
        };
        let (mut frame_err, mut t1, mut t16, mut ms) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        // Each seed's mean per-frame relMSE: the seeds are independent, its frames are not.
        let mut per_seed = restir_vpl::eval::report::OverRuns::default();
        for seed in 0..seeds {
            let restir = RestirSettings { spatial_neighbours: neighbours, spatial_radius: Some(radius), ..Default::default() };
            let s = RenderSettings { mode, presample: parts[0] == "on", candidates, restir, grid, seed, frames: 16, ..base.clone() };
            let mut r = Renderer::new(ctx.clone(), scene.clone(), s)?;
            let camera = r.initial_camera();
            let first = frame_err.len();
            for f in 0..16 {
                r.render_frame(&camera, false)?;
                if f >= 4 {
                    frame_err.push(rel_mse(&r.read_frame_samples()?, &reference, w, h)?);
                }
                if f == 0 {
                    t1.push(rel_mse(&r.read_mean()?, &reference, w, h)?);
                }
            }
            per_seed.add(mean(&frame_err[first..]));
            t16.push(rel_mse(&r.read_mean()?, &reference, w, h)?);
            ms.push(r.log().gpu().median);
        }
        println!(
            "{scene_path} {w}x{h} {v}: per-frame relMSE {:.5} ± {:.5}, t=1 {:.5}, t=16 {:.5}, GPU ms {:.1}",
            mean(&frame_err),
            per_seed.standard_error().unwrap_or(f64::NAN),
            mean(&t1),
            mean(&t16),
            mean(&ms)
        );
    }
    Ok(())
}
