//! Furnace tests of the path tracer: a closed box whose surfaces all have albedo ρ and emit Le.
//! Exact answer everywhere: L = Le / (1 − ρ) with unbounded depth, and the truncated sum
//! Le·(1 − ρ^(D+1)) / (1 − ρ) with `--max-bounces D`. The VPL image with `--photon-max-bounces B`
//! is the same sum with D = B + 1 (the last test).
//!
//! Tolerance: the image mean must be within 4 standard errors (false-failure rate ~6e-5 for a
//! normal statistic; 64·64·frames samples make the CLT apply), and every 8×8 block of pixels within
//! 5 standard errors of its own (64 blocks: Bonferroni false-failure rate ~4e-5). The block test
//! catches bias that is local (corners, edges, self-intersection), which an image mean would hide.

mod common;

use common::*;
use restir_vpl::scene::generate::furnace_box_gltf;

fn furnace(albedo: f32, emission: f32, max_bounces: i32, frames: u32) {
    let scene = load_json(&furnace_box_gltf(albedo, emission, 2.0), "furnace");
    let (w, h) = (64u32, 64u32);
    let settings = restir_vpl::RenderSettings { max_bounces, seed: 7, ..small(w, h, frames) };
    let out = render(&scene, &settings);
    let rho = albedo as f64;
    let le = emission as f64;
    let expected = if max_bounces < 0 {
        le / (1.0 - rho)
    } else {
        le * (1.0 - rho.powi(max_bounces + 1)) / (1.0 - rho)
    };
    let (mean, se) = image_mean_and_se(&out, frames, 0..(w * h) as usize);
    eprintln!("furnace rho={albedo} Le={emission} D={max_bounces}: mean {mean:.5} expected {expected:.5} se {se:.2e}");
    assert!(
        (mean - expected).abs() <= 4.0 * se + 1e-6 * expected,
        "image mean {mean} vs expected {expected}: {:.1} standard errors",
        (mean - expected).abs() / se
    );
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            let block = (0..64usize).map(move |k| ((by * 8 + k as u32 / 8) * w + bx * 8 + k as u32 % 8) as usize);
            let (m, s) = image_mean_and_se(&out, frames, block);
            assert!(
                (m - expected).abs() <= 5.0 * s + 1e-6 * expected,
                "block ({bx},{by}) mean {m} vs {expected}: {:.1} standard errors",
                (m - expected).abs() / s
            );
        }
    }
}

#[test]
fn furnace_unbounded_depth_half_albedo() {
    furnace(0.5, 1.0, -1, 48);
}

#[test]
fn furnace_unbounded_depth_high_albedo() {
    furnace(0.8, 0.5, -1, 48);
}

#[test]
fn furnace_truncated_depths() {
    for d in [0, 1, 2, 4] {
        furnace(0.6, 1.0, d, 24);
    }
}

/// D = 0: only emission seen directly, which has no noise at all.
#[test]
fn furnace_zero_bounces_is_exact() {
    let scene = load_json(&furnace_box_gltf(0.5, 1.5, 2.0), "furnace");
    let out = render(&scene, &restir_vpl::RenderSettings { max_bounces: 0, ..small(32, 32, 2) });
    for p in &out.mean {
        for c in p {
            assert!((c - 1.5).abs() < 1e-6, "{p:?}");
        }
    }
}

/// The VPL image holds light paths of up to B + 1 reflections with `--photon-max-bounces B` (a VPL
/// at a photon's k-th hit carries Φ·ρ^k and reflects once more toward the pixel), so it converges
/// to the path tracer with `--max-bounces B + 1`: in the furnace, Le·(1 − ρ^(B+2)) / (1 − ρ). The
/// defaults keep the two aligned (B = 7 against D = 8).
///
/// Brute force with the inverse-square kernel (unclamped, so unbiased for any VPL set) over
/// independent VPL sets: the image mean of each set is one sample, and the test asks for the mean
/// of K = 24 sets within 5 standard errors (from their spread: t with 23 degrees of freedom exceeds
/// 5 with probability 4.7e-5, so ~1e-4 for the two depths) of the closed form, and more than 8
/// from the next shallower depth's (D = B: 18 % lower for B = 1, 5 % for B = 3; the standard error
/// is ~0.4 %).
#[test]
fn vpl_image_converges_to_the_path_tracer_one_bounce_deeper() {
    use restir_vpl::settings::{Attenuation, Mode};
    let defaults = restir_vpl::RenderSettings::default();
    assert_eq!(defaults.photon_max_bounces as i32 + 1, defaults.max_bounces, "default depths describe the same light paths");
    let (albedo, le) = (0.6f64, 1.0f64);
    let scene = load_json(&furnace_box_gltf(albedo as f32, le as f32, 2.0), "furnace");
    let truncated = |d: i32| le * (1.0 - albedo.powi(d + 1)) / (1.0 - albedo);
    for b in [1u32, 3] {
        let means: Vec<f64> = (0..24u32)
            .map(|seed| {
                let settings = restir_vpl::RenderSettings {
                    mode: Mode::Bruteforce,
                    attenuation: Attenuation::InverseSquare,
                    vpls_direct: 800,
                    vpls_indirect: 3200,
                    photon_max_bounces: b,
                    seed,
                    ..small(16, 16, 1)
                };
                let out = render(&scene, &settings);
                image_mean_and_se(&out, 1, 0..16 * 16).0
            })
            .collect();
        let k = means.len() as f64;
        let mean = means.iter().sum::<f64>() / k;
        let se = (means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt();
        let expected = truncated(b as i32 + 1);
        eprintln!(
            "furnace VPLs B={b}: mean {mean:.5} ± {se:.5}; path tracer D={}: {expected:.5}, D={b}: {:.5}, D={}: {:.5}",
            b + 1,
            truncated(b as i32),
            b + 2,
            truncated(b as i32 + 2)
        );
        assert!((mean - expected).abs() <= 5.0 * se, "B={b}: {mean} vs {expected}: {:.1} standard errors", (mean - expected).abs() / se);
        assert!((mean - truncated(b as i32)).abs() > 8.0 * se, "B={b}: cannot tell D=B from D=B+1 at this noise");
    }
}
