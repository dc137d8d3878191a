//! The two ways of tracing rays (shaders/common/trace.glsl) give the same images: ray queries, and
//! ray-tracing pipelines (the passes that trace compiled as ray-generation shaders, with the hit
//! and miss shaders of shaders/rt/), the only way on GPUs without ray queries such as NVIDIA's
//! H100. lavapipe has both, so every mode is rendered twice here, under the validation layer.
//!
//! Tolerance: on one device both ways traverse the same acceleration structure with the same
//! code, so a ray returns the same hit; the images came out bit-identical in every case tried
//! (Mesa 25.0). We allow a relative RMSE of 1e-5 for a compiler that contracts a multiply-add
//! differently in the two builds. Anything wrong in what a ray returns (barycentrics in the other
//! order, another instance or triangle, a miss for a hit, a blocked shadow ray for a clear one)
//! moves whole surfaces by far more: each of those, planted in the shaders, failed this test by
//! at least 1e-2.

mod common;

use std::sync::Arc;
use std::time::Instant;

use restir_vpl::headless::run_with;
use restir_vpl::scene::Scene;
use restir_vpl::settings::{Bias, Mode, RenderSettings};
use restir_vpl::vk::context::Tracing;
use restir_vpl::vk::Context;

fn context(tracing: Tracing) -> Arc<Context> {
    let ctx = common::context_tracing(Some(tracing));
    assert_eq!(ctx.tracing, tracing);
    ctx
}

/// The mean image of `settings` on `scene`, traced the `tracing` way (no validation error, no
/// non-finite sample: `common::render_on`).
fn render(tracing: Tracing, scene: &Scene, settings: &RenderSettings) -> Vec<[f32; 3]> {
    let out = common::render_on(&context(tracing), scene, settings);
    assert_eq!(out.summary.device.tracing, Some(tracing), "the summary names the way rays were traced");
    out.mean
}

/// sqrt(mean squared difference) / mean of `b`, over all channels.
fn relative_rmse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let n = (a.len() * 3) as f64;
    let se: f64 = a.iter().zip(b).flat_map(|(x, y)| (0..3).map(move |c| (x[c] as f64 - y[c] as f64).powi(2))).sum();
    let mean: f64 = b.iter().flat_map(|y| y.iter().map(|&v| v as f64)).sum::<f64>() / n;
    assert!(mean > 0.0, "the reference image is black");
    (se / n).sqrt() / mean
}

fn base(mode: Mode, size: u32, frames: u32) -> RenderSettings {
    RenderSettings {
        mode,
        width: size,
        height: size,
        frames,
        vpls_direct: 4000,
        vpls_indirect: 4000,
        validate: common::validate(),
        ..Default::default()
    }
}

#[test]
fn ray_tracing_pipelines_render_what_ray_queries_render() {
    let cornell = Scene::load(&common::repo_path("scenes/cornell_box.gltf")).expect("Cornell box loads");
    let living = Scene::load(&common::repo_path("scenes/living_room.gltf")).expect("living room loads");
    let mut unbiased_visible = base(Mode::Restir, 48, 3);
    unbiased_visible.restir.initial_visibility = Some(true);
    let mut fused = unbiased_visible.clone();
    fused.fuse_passes = Some(true);
    let mut biased = base(Mode::Restir, 48, 3);
    biased.restir.bias = Bias::Biased;
    let mut compensate = base(Mode::Restir, 48, 2);
    compensate.compensate = true;
    let mut moving = base(Mode::Restir, 48, 3);
    moving.camera_path = Some(common::repo_path("scenes/cornell_box.path.json"));
    moving.progressive = false;
    let cases: Vec<(&str, &Scene, RenderSettings)> = vec![
        ("pt", &cornell, base(Mode::Pt, 48, 2)),
        ("pt, textured living room", &living, base(Mode::Pt, 48, 1)),
        ("uniform", &cornell, base(Mode::Uniform, 48, 3)),
        ("ris", &cornell, base(Mode::Ris, 48, 3)),
        ("restir", &cornell, base(Mode::Restir, 48, 3)),
        ("restir biased", &cornell, biased),
        ("restir, visibility in targets", &cornell, unbiased_visible),
        ("restir, visibility in targets, fused passes", &cornell, fused),
        ("restir --compensate", &cornell, compensate),
        ("restir, moving camera", &cornell, moving),
        ("restir, textured living room", &living, base(Mode::Restir, 48, 2)),
        ("bruteforce", &cornell, RenderSettings { vpls_direct: 500, vpls_indirect: 500, ..base(Mode::Bruteforce, 24, 1) }),
    ];
    let mut failures = Vec::new();
    for (name, scene, settings) in &cases {
        let query = render(Tracing::Query, scene, settings);
        let pipeline = render(Tracing::Pipeline, scene, settings);
        let e = relative_rmse(&pipeline, &query);
        eprintln!("{name}: relative RMSE {e:.3e}");
        if e > 1e-5 {
            failures.push(format!("{name}: relative RMSE {e:.3e} between ray-tracing pipelines and ray queries"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The boiling filter (`restir_boiling`, a compute pass of its own because it averages over a
/// workgroup in shared memory, which a ray-generation shader lacks) runs with either way of
/// tracing and gives the same image; and it drops reservoirs here (the image differs from one
/// without it), so the comparison is not of two unfiltered images.
#[test]
fn the_boiling_filter_runs_with_ray_tracing_pipelines() {
    let cornell = Scene::load(&common::repo_path("scenes/cornell_box.gltf")).expect("Cornell box loads");
    let mut settings = base(Mode::Restir, 48, 4);
    // The strongest filter (drops every reservoir above its block's mean): 0.6 dropped none in
    // 4 frames of 48² here.
    settings.restir.boiling_filter = 1.0;
    let query = render(Tracing::Query, &cornell, &settings);
    let pipeline = render(Tracing::Pipeline, &cornell, &settings);
    let e = relative_rmse(&pipeline, &query);
    eprintln!("boiling filter 1.0: relative RMSE {e:.3e} between the two ways");
    assert!(e <= 1e-5, "boiling filter: relative RMSE {e:.3e} between ray-tracing pipelines and ray queries");
    let mut off = settings.clone();
    off.restir.boiling_filter = 0.0;
    let unfiltered = render(Tracing::Pipeline, &cornell, &off);
    let change = relative_rmse(&pipeline, &unfiltered);
    eprintln!("boiling filter 1.0 against none: relative RMSE {change:.3e}");
    // A filter that dropped nothing would leave the image bit-identical; 1e-3 is 100 times the
    // tolerance above.
    assert!(change > 1e-3, "the boiling filter changed nothing (relative RMSE {change:.3e}): the comparison tests nothing");
}

/// Settings that ask for one way of tracing on a context made for the other are refused by name,
/// not traced the context's way without a word.
#[test]
fn settings_asking_for_the_other_way_are_refused() {
    let cornell = Scene::load(&common::repo_path("scenes/cornell_box.gltf")).expect("Cornell box loads");
    let settings = RenderSettings { tracing: Some(Tracing::Pipeline), ..base(Mode::Pt, 8, 1) };
    let ctx = context(Tracing::Query);
    let gpu = common::upload(&ctx, &cornell, &settings);
    let err = run_with(ctx.clone(), gpu.clone(), &settings, Instant::now()).err().expect("refused");
    let msg = format!("{err:#}");
    assert!(msg.contains("--trace pipeline") && msg.contains("ray queries"), "{msg}");
    let same = RenderSettings { tracing: Some(Tracing::Query), ..settings };
    run_with(ctx.clone(), gpu, &same, Instant::now()).expect("the context's own way runs");
    common::assert_no_validation_errors(&ctx);
}
