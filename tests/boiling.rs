//! RTXDI's boiling filter (`--boiling-filter S`): measured on the Cornell box against brute force
//! over the same VPLs, 16 accumulated ReSTIR frames at 96², four pixel seeds. Off, the worst 0.1 %
//! of the pixels carry 15–75 % of a run's squared error (fireflies that temporal reuse keeps; 47 %
//! averaged over the four seeds); at strength 0.8 the filter must cut that share and the RMSE, at
//! the price of a small, bounded darkening (the filter removes energy: it is biased).

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
    // Fireflies are rare events: in one run the worst 0.1 % (9 pixels) may hold one or none, so
    // one run's share went from 0.38 to 0.15 when only the random numbers changed. Four pixel
    // seeds (the same VPLs, so the same truth), their squared errors pooled.
    const SEEDS: [u32; 4] = [1, 2, 3, 4];
    let restir = |strength: f32| {
        let (mut rmse2, mut share, mut ratio) = (0.0, 0.0, 0.0);
        for seed in SEEDS {
            let s = RenderSettings { mode: Mode::Restir, seed, restir: RestirSettings { boiling_filter: strength, ..Default::default() }, ..base.clone() };
            let c = compare(&image(&s), &truth, &CompareOptions { flip: false, ..Default::default() }).unwrap();
            rmse2 += c.rmse * c.rmse;
            share += c.worst_share;
            ratio += c.mean_ratio;
        }
        let n = SEEDS.len() as f64;
        ((rmse2 / n).sqrt(), share / n, ratio / n)
    };
    let (off, on) = (restir(0.0), restir(0.8));
    eprintln!(
        "over {} seeds: off: RMSE {:.4}, worst 0.1% share {:.3}, mean ratio {:.4}; strength 0.8: RMSE {:.4}, share {:.3}, ratio {:.4}",
        SEEDS.len(),
        off.0, off.1, off.2, on.0, on.1, on.2
    );
    assert!(on.1 < 0.6 * off.1, "the filter should cut the fireflies' share: {} vs {}", on.1, off.1);
    assert!(on.0 < off.0, "and the RMSE: {} vs {}", on.0, off.0);
    // Biased, but boundedly: it darkens, by less than 3 % here (measured: about 1.2 %).
    assert!(on.2 < off.2 && on.2 > 0.97, "mean ratio {} (off: {})", on.2, off.2);
}
