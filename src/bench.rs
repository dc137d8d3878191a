//! Benchmarks (not tests): throughput figures measured from GPU timestamps.

use std::sync::Arc;

use anyhow::Result;
use serde::Serialize;

use crate::output::TimingStats;
use crate::renderer::Renderer;
use crate::scene::Scene;
use crate::settings::RenderSettings;
use crate::vk::{Context, ContextOptions};

/// Primary-ray and path-tracing throughput of one scene.
#[derive(Clone, Debug, Serialize)]
pub struct CoreBench {
    pub device: String,
    pub scene: String,
    pub triangles: usize,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// GPU ms per pass (after one warm-up frame, which includes shader JIT on lavapipe).
    pub pass_ms: Vec<(String, TimingStats)>,
    pub gpu_ms_per_frame: TimingStats,
    pub primary_mrays_per_s: f64,
    pub pathtrace_mrays_per_s: f64,
    pub pathtrace_rays_per_pixel: f64,
}

/// Renders `frames` frames (plus one warm-up) with anti-aliasing on, so that the G-buffer's primary
/// rays are traced every frame, and reports throughput from the GPU timestamps.
pub fn core(scene_path: &std::path::Path, width: u32, height: u32, frames: u32, device: Option<usize>) -> Result<CoreBench> {
    let scene = Scene::load(scene_path)?;
    let ctx = Arc::new(Context::new(&ContextOptions { validate: false, device_index: device })?);
    let settings = RenderSettings {
        scene: scene_path.to_path_buf(),
        width,
        height,
        frames: frames + 1,
        aa: true,
        ..Default::default()
    };
    settings.validate()?;
    let mut r = Renderer::new(ctx.clone(), &scene, settings)?;
    r.render_frame(false)?; // warm-up: shader compilation, first-touch allocations
    r.pass_times.clear();
    let pixels = (width * height) as f64;
    let mut frame_ms = Vec::new();
    let mut pt_rays = 0.0;
    for _ in 0..frames {
        let s = r.render_frame(false)?;
        frame_ms.push(s.pass_ms.iter().map(|p| p.1).sum());
        pt_rays += s.rays as f64 - pixels;
    }
    let median = |name: &str| r.pass_times.get(name).map(|v| TimingStats::of(v)).unwrap_or_default();
    let gb = median("gbuffer");
    let pt_total_ms: f64 = r.pass_times.get("pathtrace").map(|v| v.iter().sum()).unwrap_or(0.0);
    Ok(CoreBench {
        device: ctx.report.name.clone(),
        scene: scene_path.display().to_string(),
        triangles: scene.triangle_count(),
        width,
        height,
        frames,
        pass_ms: r.pass_times.iter().map(|(k, v)| (k.to_string(), TimingStats::of(v))).collect(),
        gpu_ms_per_frame: TimingStats::of(&frame_ms),
        primary_mrays_per_s: if gb.median > 0.0 { pixels / (gb.median * 1e3) } else { 0.0 },
        pathtrace_mrays_per_s: if pt_total_ms > 0.0 { pt_rays / (pt_total_ms * 1e3) } else { 0.0 },
        pathtrace_rays_per_pixel: pt_rays / (pixels * frames as f64),
    })
}

impl CoreBench {
    /// A Markdown report.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "Core benchmark: {} ({} triangles), {}x{}, {} frames, device {}\n\n| pass | median ms | min ms | max ms |\n|---|---:|---:|---:|\n",
            self.scene, self.triangles, self.width, self.height, self.frames, self.device
        );
        for (name, t) in &self.pass_ms {
            s += &format!("| {name} | {:.2} | {:.2} | {:.2} |\n", t.median, t.min, t.max);
        }
        s += &format!(
            "\nGPU ms per frame (median): {:.2}\nprimary rays: {:.2} Mrays/s\npath tracing: {:.2} Mrays/s ({:.2} rays per pixel per frame)\n",
            self.gpu_ms_per_frame.median, self.primary_mrays_per_s, self.pathtrace_mrays_per_s, self.pathtrace_rays_per_pixel
        );
        s
    }
}
