//! RTXDI's boiling filter (`--boiling-filter S`): measured on the Cornell box against brute force
//! over the same VPLs, 16 accumulated ReSTIR frames at 96², eight pixel seeds pooled. Off, the
//! worst 0.1 % of the pixels carry about 19 % of the squared error (fireflies that temporal reuse
//! keeps); at strength 0.8 the filter must cut that share (to about 9 %) and the RMSE, at the price
//! of a small, bounded darkening (the filter removes energy: it is biased). (Until 2026-11-25 the
//! truth was traced with other VPLs than the runs, whose differences counted as fireflies: 40–75 %.)

mod common;

use common::*;
use restir_vpl::eval::compare::{compare, CompareOptions};
use restir_vpl::output::RgbImage;
use restir_vpl::scene::Scene;
use restir_vpl::settings::{Mode, RestirSettings};
use restir_vpl::renderer::Renderer;
use restir_vpl::RenderSettings;

#[test]
fn boiling_filter_cuts_fireflies_at_a_bounded_bias() {
    let scene = Scene::load(&repo_path("scenes/cornell_box.gltf")).unwrap();
    // The filter is for fireflies: measured at Yuksel's r = 1× the mean VPL spacing (the default
    // before `bench --radius` chose 8×), where temporal reuse keeps them. At the 8× default the
    // worst 0.1 % hold about 14 % of the squared error and the filter cuts that to about 12 %.
    let spacing = (scene.surface_area() / (std::f64::consts::PI * 16_000.0)).sqrt() as f32;
    let base = RenderSettings {
        vpls_direct: 8_000,
        vpls_indirect: 8_000,
        yuksel_radius: Some(spacing),
        ..small(96, 96, 16)
    };
    // One VPL set for all: the photon pass traces with the renderers' construction seed, and each
    // run restarts a renderer with another pixel seed (Renderer::restart keeps the VPLs). (Runs made
    // with `seed` set in the settings would trace other VPLs than the truth's.)
    let ctx = context();
    let gpu = upload(&ctx, &scene, &base);
    let mut brute = Renderer::new(ctx.clone(), gpu.clone(), RenderSettings { mode: Mode::Bruteforce, frames: 1, ..base.clone() }).unwrap();
    let camera = brute.initial_camera();
    brute.render_frame(&camera, false).unwrap();
    let truth = RgbImage { width: 96, height: 96, pixels: brute.read_mean().unwrap() };
    drop(brute);
    // Fireflies are rare events: in one run the worst 0.1 % (9 pixels) may hold one or none, so
    // one run's share moves a lot with the random numbers. Eight pixel seeds, averaged.
    const SEEDS: [u32; 8] = [1, 2, 3, 4, 5, 6, 7, 8];
    let restir = |strength: f32| {
        let settings = RenderSettings { mode: Mode::Restir, restir: RestirSettings { boiling_filter: strength, ..Default::default() }, ..base.clone() };
        let mut r = Renderer::new(ctx.clone(), gpu.clone(), settings).unwrap();
        let (mut rmse2, mut share, mut ratio) = (0.0, 0.0, 0.0);
        for seed in SEEDS {
            r.restart(seed).unwrap();
            for _ in 0..base.frames {
                r.render_frame(&camera, false).unwrap();
            }
            let image = RgbImage { width: 96, height: 96, pixels: r.read_mean().unwrap() };
            assert_all_finite(&image.pixels, "ReSTIR image");
            let c = compare(&image, &truth, &CompareOptions { flip: false, ..Default::default() }).unwrap();
            rmse2 += c.rmse * c.rmse;
            share += c.worst_share;
            ratio += c.mean_ratio;
        }
        common::assert_no_nonfinite_samples(&r, "run");
        let n = SEEDS.len() as f64;
        ((rmse2 / n).sqrt(), share / n, ratio / n)
    };
    let (off, on) = (restir(0.0), restir(0.8));
    common::assert_no_validation_errors(&ctx);
    eprintln!(
        "over {} seeds: off: RMSE {:.4}, worst 0.1% share {:.3}, mean ratio {:.4}; strength 0.8: RMSE {:.4}, share {:.3}, ratio {:.4}",
        SEEDS.len(),
        off.0, off.1, off.2, on.0, on.1, on.2
    );
    assert!(on.1 < 0.6 * off.1, "the filter should cut the fireflies' share: {} vs {}", on.1, off.1);
    assert!(on.0 < off.0, "and the RMSE: {} vs {}", on.0, off.0);
    // Biased, but boundedly: it darkens, by less than 3 % here (measured: about 0.6 %).
    assert!(on.2 < off.2 && on.2 > 0.97, "mean ratio {} (off: {})", on.2, off.2);
}
