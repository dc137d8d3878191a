//! RTXDI's boiling filter (`--boiling-filter S`): measured on the Cornell box against brute force
//! over the same VPLs, 16 accumulated ReSTIR frames at 96². Off, the worst 0.1 % of the pixels
//! carry 40–75 % of the squared error (fireflies that temporal reuse keeps); at strength 0.8 the
//! filter must cut that share and the RMSE, at the price of a small, bounded darkening (the filter
//! removes energy: it is biased).

mod common;

use common::*;
use restir_vpl::eval::compare::{compare, CompareOptions};
use restir_vpl::output::RgbImage;
use restir_vpl::scene::Scene;
use restir_vpl::settings::{Mode, RestirSettings};
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
    let image = |s: &RenderSettings| {
        let out = render(&scene, s);
        RgbImage { width: 96, height: 96, pixels: out.mean }
    };
    let truth = image(&RenderSettings { mode: Mode::Bruteforce, frames: 1, ..base.clone() });
    let restir = |strength: f32| {
        let s = RenderSettings { mode: Mode::Restir, restir: RestirSettings { boiling_filter: strength, ..Default::default() }, ..base.clone() };
        compare(&image(&s), &truth, &CompareOptions { flip: false, ..Default::default() }).unwrap()
    };
    let (off, on) = (restir(0.0), restir(0.8));
    eprintln!(
        "off: RMSE {:.4}, worst 0.1% share {:.3}, mean ratio {:.4}; strength 0.8: RMSE {:.4}, share {:.3}, ratio {:.4}",
        off.rmse, off.worst_share, off.mean_ratio, on.rmse, on.worst_share, on.mean_ratio
    );
    assert!(on.worst_share < 0.6 * off.worst_share, "the filter should cut the fireflies' share: {} vs {}", on.worst_share, off.worst_share);
    assert!(on.rmse < off.rmse, "and the RMSE: {} vs {}", on.rmse, off.rmse);
    // Biased, but boundedly: it darkens, by less than 3 % here (measured: about 1.2 %).
    assert!(on.mean_ratio < off.mean_ratio && on.mean_ratio > 0.97, "mean ratio {} (off: {})", on.mean_ratio, off.mean_ratio);
}
