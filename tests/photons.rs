//! The photon pass: VPL flux normalisation (docs/method.md), geometry, determinism, PLY.

mod common;

use std::collections::BTreeMap;
use std::sync::Arc;

use common::*;
use glam::Vec3;
use restir_vpl::gpu_types::{GpuVpl, VPL_DIRECT_AREA, VPL_INDIRECT};
use restir_vpl::passes::PhotonStats;
use restir_vpl::renderer::Renderer;
use restir_vpl::scene::generate::{closed_box, GltfBuilder};
use restir_vpl::scene::Scene;
use restir_vpl::RenderSettings;

/// Runs only the photon pass (through the renderer) and returns the VPLs and its statistics.
fn vpls(scene: &Scene, settings: RenderSettings) -> (Vec<GpuVpl>, PhotonStats) {
    let ctx = context();
    let settings = RenderSettings { dump_vpls: Some("unused.ply".into()), ..settings };
    let gpu = upload(&ctx, scene, &settings);
    let r = Renderer::new(Arc::clone(&ctx), gpu, settings).expect("renderer");
    let v = r.read_vpls().expect("read").expect("VPLs present");
    let stats = r.photon_stats().expect("photon stats").clone();
    common::assert_no_validation_errors(&ctx);
    for x in &v {
        assert!(x.flux.iter().all(|c| c.is_finite() && *c >= 0.0), "bad flux {x:?}");
        assert!(x.position.iter().chain(&x.normal).all(|c| c.is_finite()), "bad VPL {x:?}");
        assert!((Vec3::from(x.normal).length() - 1.0).abs() < 1e-4, "normal not unit: {x:?}");
    }
    (v, stats)
}

fn light_power(scene: &Scene) -> [f64; 3] {
    restir_vpl::lights::LightSet::from_scene(scene).total_power
}

fn flux_sum(v: &[GpuVpl], kind: impl Fn(u32) -> bool) -> [f64; 3] {
    let mut s = [0.0; 3];
    for x in v.iter().filter(|x| kind(x.kind)) {
        for c in 0..3 {
            s[c] += x.flux[c] as f64;
        }
    }
    s
}

fn cornell() -> Scene {
    Scene::load(&repo_path("scenes/cornell_box.gltf")).unwrap()
}

/// Two area lights of different colours and areas (one double-sided) and a point light: the direct
/// VPLs' flux still sums to the total power Σ π·Le·A·sides + 4π·I.
fn two_lights() -> Scene {
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    let warm = b.material("warm", [0.5; 3], [9.0, 3.0, 1.0], false);
    let cool = b.material("cool", [0.5; 3], [0.5, 1.0, 4.0], true);
    let floor = b.quad("floor", [[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]], grey);
    b.node("floor", floor, [0.0; 3]);
    let l1 = b.quad("warm", [[-1.0, 2.0, -1.0], [1.0, 2.0, -1.0], [1.0, 2.0, -0.5], [-1.0, 2.0, -0.5]], warm);
    b.node("warm", l1, [0.0; 3]);
    let l2 = b.quad("cool", [[0.0, 1.0, 0.0], [0.3, 1.0, 0.0], [0.3, 1.5, 0.0], [0.0, 1.5, 0.0]], cool);
    b.node("cool", l2, [0.0; 3]);
    b.point_light("bulb", [0.5, 1.2, 0.5], [1.0, 0.8, 0.6], 0.7);
    b.camera("cam", [0.0, 1.0, 4.0], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0], 1.0);
    load_json(&b.to_json_string(), "two_lights")
}

fn assert_rel(a: [f64; 3], b: [f64; 3], tol: f64, what: &str) {
    for c in 0..3 {
        assert!((a[c] - b[c]).abs() <= tol * b[c].abs().max(1e-12), "{what}: channel {c}: {} vs {}", a[c], b[c]);
    }
}

/// The expected power above is the light list's own sum (`LightSet::total_power`, the code that
/// also builds the GPU lights): checked here against the scene's numbers by hand, so that a wrong
/// area, side count or point-light factor cannot hide in both.
#[test]
fn two_lights_power_by_hand() {
    let pi = std::f64::consts::PI;
    let warm = [9.0, 3.0, 1.0].map(|le: f64| pi * le * (2.0 * 0.5)); // one-sided, 2 m × 0.5 m
    let cool = [0.5, 1.0, 4.0].map(|le: f64| 2.0 * pi * le * (0.3 * 0.5)); // double-sided, 0.3 m × 0.5 m
    let bulb = [1.0, 0.8, 0.6].map(|c: f64| 4.0 * pi * 0.7 * c); // 0.7 cd
    let by_hand = [0, 1, 2].map(|c| warm[c] + cool[c] + bulb[c]);
    assert_rel(light_power(&two_lights()), by_hand, 1e-6, "total light power");
}

#[test]
fn direct_vpl_flux_equals_light_power() {
    for (scene, n) in [(cornell(), 20_000), (two_lights(), 30_000)] {
        let settings = RenderSettings { vpls_direct: n, gi: false, ..small(8, 8, 1) };
        let (v, _) = vpls(&scene, settings);
        assert_eq!(v.len(), n as usize);
        assert!(v.iter().all(|x| x.kind == VPL_DIRECT_AREA || x.kind == restir_vpl::gpu_types::VPL_DIRECT_POINT));
        assert_rel(flux_sum(&v, |_| true), light_power(&scene), 1e-3, "direct flux");
    }
}

/// Each light's own VPLs carry its power: the point light (last in the light table, whose width
/// wraps past 2^32) and the area lights apart. The strata make each light's VPL count its share
/// of N_d to within about one VPL, so a flux divided by anything but the probability the light is
/// chosen with shows, as would a light reading another's interval (tolerance 4e-3: the point
/// light takes ~34 % of the luminance, ~10,000 VPLs of 30,000, each 1e-4 of its power). It does
/// not reach the shares below 1e-6 where the float table was wrong: those need more VPLs than a
/// run holds (light_cdf's unit test covers them).
#[test]
fn each_lights_direct_vpls_carry_its_power() {
    let scene = two_lights();
    let set = restir_vpl::lights::LightSet::from_scene(&scene);
    let point = set.lights.iter().filter(|l| l.flags & restir_vpl::gpu_types::LIGHT_POINT != 0).map(|l| l.emission.map(|c| 4.0 * std::f64::consts::PI * c as f64)).next().expect("the scene's bulb");
    let (v, _) = vpls(&scene, RenderSettings { vpls_direct: 30_000, gi: false, ..small(8, 8, 1) });
    let points = v.iter().filter(|x| x.kind == restir_vpl::gpu_types::VPL_DIRECT_POINT).count();
    assert!(points > 1000, "{points} point-light VPLs");
    assert_rel(flux_sum(&v, |k| k == restir_vpl::gpu_types::VPL_DIRECT_POINT), point, 4e-3, "point light's VPLs");
    let total = light_power(&scene);
    assert_rel(flux_sum(&v, |k| k == VPL_DIRECT_AREA), [0, 1, 2].map(|c| total[c] - point[c]), 4e-3, "area lights' VPLs");
}

/// A 2 × 2 floor of albedo 0.5 under a point light 1 above its centre; with `tilt`, every
/// vertex's shading normal leans toward +x (normalize(tilt, 1, 0)) while the geometry stays flat.
fn floor_under_a_bulb(tilt: Option<f32>) -> Scene {
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    let positions = [[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]];
    let normals = tilt.map(|t| [Vec3::new(t, 1.0, 0.0).normalize().to_array(); 4]);
    let floor = b.mesh("floor", &positions, normals.as_ref().map(|n| &n[..]), &[0, 1, 2, 0, 2, 3], grey);
    b.node("floor", floor, [0.0; 3]);
    b.point_light("bulb", [0.0, 1.0, 0.0], [1.0; 3], 1.0);
    b.camera("cam", [0.0, 1.5, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.8);
    load_json(&b.to_json_string(), "floor_under_a_bulb")
}

/// Shading normals in the photon pass (Veach's adjoint correction): the path tracer and the VPL
/// shading reflect ρ/π · max(0, n_s·ω) of the incoming radiance, so one bounce off the floor must
/// leave the indirect VPLs a flux of ρ ∫ I max(0, n_s·ω) / d² dA (integrated here on a grid), not
/// the geometric ρ ∫ I (n_g·ω) / d² dA a photon's hit density gives without the factor. With the
/// shading normals tilted by 27° the two differ by 10 %; the tolerance is 4 standard errors of the
/// sum over paths (√Σ flux², ~0.3 % here). The flat floor checks the integral itself.
#[test]
fn photons_reflect_what_the_shading_normal_receives() {
    let expected = |tilt: Option<f32>| {
        let ns = Vec3::new(tilt.unwrap_or(0.0), 1.0, 0.0).normalize();
        let n = 1000;
        let cell = 2.0 / n as f64;
        let mut sum = 0.0f64;
        for i in 0..n {
            for k in 0..n {
                let p = Vec3::new((-1.0 + (i as f64 + 0.5) * cell) as f32, 0.0, (-1.0 + (k as f64 + 0.5) * cell) as f32);
                let to_light = Vec3::new(0.0, 1.0, 0.0) - p;
                let d2 = to_light.length_squared() as f64;
                sum += (ns.dot(to_light.normalize()).max(0.0) as f64) / d2 * cell * cell;
            }
        }
        0.5 * sum // ρ I ∫ cos / d², I = 1
    };
    for tilt in [None, Some(0.5)] {
        let settings = RenderSettings { vpls_direct: 1000, vpls_indirect: 100_000, photon_max_bounces: 1, ..small(8, 8, 1) };
        let (v, _) = vpls(&floor_under_a_bulb(tilt), settings);
        let indirect: Vec<f64> = v.iter().filter(|x| x.kind == VPL_INDIRECT).map(|x| x.flux[0] as f64).collect();
        let sum: f64 = indirect.iter().sum();
        let se = indirect.iter().map(|f| f * f).sum::<f64>().sqrt();
        let want = expected(tilt);
        assert!(indirect.len() > 50_000, "{} indirect VPLs", indirect.len());
        assert!((sum - want).abs() < 4.0 * se, "tilt {tilt:?}: indirect flux {sum} against {want} (± {se}); the geometric answer is {}", expected(None));
    }
}

/// A point light lying in a surface (a bulb placed on a floor, exactly at its height): the path
/// tracer sees it at cos 0 from that surface, so the photons must leave from the light's own
/// point past the floor's plane, not meet the floor at distance ~0. They met it: the upward half
/// hit it from behind, left VPLs facing below the floor and bounced out of the room (the VPL
/// modes read 1.13× the path tracer on the Cornell box). Here a floor at y = 0 and a ceiling at
/// y = 1 facing it, the bulb in the floor: every VPL below mid-height must face up (the floor's
/// lit side) and the upward photons must reach the ceiling (about half the paths' first hits).
#[test]
fn a_point_light_in_a_floor_sends_its_photons_past_it() {
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    let floor = b.mesh("floor", &[[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]], None, &[0, 1, 2, 0, 2, 3], grey);
    b.node("floor", floor, [0.0; 3]);
    let ceiling = b.mesh("ceiling", &[[-1.0, 1.0, -1.0], [1.0, 1.0, -1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]], None, &[0, 1, 2, 0, 2, 3], grey);
    b.node("ceiling", ceiling, [0.0; 3]);
    b.point_light("bulb", [0.3, 0.0, -0.2], [1.0; 3], 1.0);
    b.camera("cam", [0.0, 0.5, 3.0], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0], 0.8);
    let scene = load_json(&b.to_json_string(), "bulb_in_the_floor");
    let settings = RenderSettings { vpls_direct: 1000, vpls_indirect: 20_000, photon_max_bounces: 1, ..small(8, 8, 1) };
    let (v, stats) = vpls(&scene, settings);
    let indirect: Vec<&GpuVpl> = v.iter().filter(|x| x.kind == VPL_INDIRECT).collect();
    let facing_down_low = indirect.iter().filter(|x| x.position[1] < 0.5 && x.normal[1] < 0.0).count();
    assert_eq!(facing_down_low, 0, "{facing_down_low} of {} indirect VPLs at the floor face below it", indirect.len());
    // One bounce: a path's first hit is its only VPL, on the ceiling with probability Ω / 4π, Ω
    // the ceiling's solid angle from the bulb (∫ cos / d² dA = ∫ 1 / d³ dA at height 1, on a grid).
    let n = 1000;
    let cell = 2.0 / n as f64;
    let mut omega = 0.0;
    for i in 0..n {
        for k in 0..n {
            let (x, z) = (-1.0 + (i as f64 + 0.5) * cell - 0.3, -1.0 + (k as f64 + 0.5) * cell + 0.2);
            omega += (x * x + 1.0 + z * z).powf(-1.5) * cell * cell;
        }
    }
    let p = omega / (4.0 * std::f64::consts::PI);
    let paths = stats.paths as f64;
    let on_ceiling = indirect.iter().filter(|x| x.position[1] > 0.5).count() as f64;
    // 4 standard errors of the binomial count.
    let se = (paths * p * (1.0 - p)).sqrt();
    assert!((on_ceiling - p * paths).abs() < 4.0 * se, "{on_ceiling} ceiling VPLs of {paths} paths, expected {:.0} ± {se:.0}", p * paths);
}

/// A closed box of albedo ρ (the emitter quad inside it too), lit by one emitter of power Φ.
fn closed_box_scene(rho: f32) -> Scene {
    let mut b = GltfBuilder::new();
    let wall = b.material("wall", [rho; 3], [0.0; 3], false);
    let lamp = b.material("lamp", [rho; 3], [2.0, 2.0, 2.0], false);
    let m = closed_box(&mut b, "room", [-1.0; 3], [1.0; 3], wall, true);
    b.node("room", m, [0.0; 3]);
    // Facing down (-y): counter-clockwise seen from below.
    let l = b.quad("lamp", [[-0.2, 0.9, -0.2], [0.2, 0.9, -0.2], [0.2, 0.9, 0.2], [-0.2, 0.9, 0.2]], lamp);
    b.node("lamp", l, [0.0; 3]);
    b.camera("cam", [0.0, 0.0, 0.9], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 1.2);
    load_json(&b.to_json_string(), "closed_box")
}

/// Without Russian roulette every photon path in a closed box makes exactly B VPLs whose flux sums
/// to Φ·(ρ + … + ρ^B): the normalisation must be exact up to float rounding. Every ray hits, so
/// the pass counts exactly one ray per VPL (no batch overflows: each path makes exactly B).
#[test]
fn indirect_flux_closed_box_without_roulette_is_exact() {
    let rho = 0.6f64;
    let scene = closed_box_scene(rho as f32);
    let phi = light_power(&scene);
    assert!(phi[0] > 0.0);
    let b = 5u32;
    let settings = RenderSettings {
        vpls_direct: 1000,
        vpls_indirect: 20_000,
        photon_min_bounces: b,
        photon_max_bounces: b,
        ..small(8, 8, 1)
    };
    let (v, stats) = vpls(&scene, settings);
    let paths = stats.paths;
    let indirect: Vec<&GpuVpl> = v.iter().filter(|x| x.kind == VPL_INDIRECT).collect();
    assert_eq!(indirect.len() as u64, paths * b as u64, "every path bounces B times in a closed box");
    assert_eq!(stats.rays, indirect.len() as u64, "one closest-hit ray per VPL in a closed box");
    let series: f64 = (1..=b).map(|k| rho.powi(k as i32)).sum();
    let expected = phi.map(|p| p * series);
    assert_rel(flux_sum(&v, |k| k == VPL_INDIRECT), expected, 1e-4, "indirect flux");
}

/// With Russian roulette from the first bounce the total is right in expectation: within 4
/// standard errors of Φ·(ρ + … + ρ^B), the standard error taken from the per-path totals.
#[test]
fn indirect_flux_closed_box_with_roulette_is_unbiased() {
    let rho = 0.7f64;
    let scene = closed_box_scene(rho as f32);
    let phi = light_power(&scene);
    let settings = RenderSettings { vpls_direct: 1000, vpls_indirect: 40_000, seed: 5, ..small(8, 8, 1) };
    let b = settings.photon_max_bounces;
    let (v, stats) = vpls(&scene, settings);
    let paths = stats.paths;
    let mut per_path: BTreeMap<u32, f64> = BTreeMap::new();
    for x in v.iter().filter(|x| x.kind == VPL_INDIRECT) {
        *per_path.entry(x.path).or_default() += x.flux[0] as f64 * paths as f64;
    }
    let p = paths as f64;
    let mean = per_path.values().sum::<f64>() / p;
    let sq = per_path.values().map(|x| x * x).sum::<f64>() / p;
    let se = ((sq - mean * mean).max(0.0) / (p - 1.0)).sqrt();
    let series: f64 = (1..=b).map(|k| rho.powi(k as i32)).sum();
    let expected = phi[0] * series;
    eprintln!("indirect flux {mean} expected {expected} se {se} ({paths} paths)");
    assert!((mean - expected).abs() <= 4.0 * se, "{mean} vs {expected}: {:.1} SE", (mean - expected).abs() / se);
}


/// Every VPL lies on a surface (a short ray along −normal meets geometry within 1e-4 m) with its
/// normal along that surface's (within the octahedral quantisation), on the side the photons come
/// from: a point 1e-4 m along the normal is inside the room (within 1e-6: a VPL on a wall with a
/// flipped normal puts it 1e-4 outside) and outside both blocks (the segment from it to the camera,
/// which leaves through the open front, crosses the blocks' faces an even number of times; a VPL
/// on a block with a flipped normal puts it inside, an odd count). The surface-behind check alone
/// sees a flipped normal only through the ray offset (~1e-5 here) that puts the VPL off its
/// surface; these two do not depend on it.
#[test]
fn vpls_lie_on_surfaces_facing_the_photons() {
    let scene = cornell();
    let tris = world_triangles(&scene);
    let (v, _) = vpls(&scene, RenderSettings { vpls_direct: 500, vpls_indirect: 3000, ..small(8, 8, 1) });
    // The room is the bounds of every triangle; the camera, the scene's own (in front of the open
    // side).
    let corners = tris.iter().flatten();
    let (lo, hi) = (corners.clone().fold(Vec3::splat(f32::MAX), |a, &p| a.min(p)), corners.fold(Vec3::splat(f32::MIN), |a, &p| a.max(p)));
    let camera = scene.camera.as_ref().expect("the Cornell box has a camera").transform.w_axis.truncate();
    assert!(camera.z < lo.z, "the camera looks in through the open side");
    // The blocks' faces: inside the room, below its top, on none of its walls or its floor.
    let on = |a: f32, b: f32| (a - b).abs() < 1e-4;
    let blocks: Vec<[Vec3; 3]> = tris
        .iter()
        .copied()
        .filter(|t| {
            let all = |f: &dyn Fn(Vec3) -> bool| t.iter().all(|&p| f(p));
            all(&|p| p.y < 0.5) && !all(&|p| on(p.y, 0.0)) && !all(&|p| on(p.x, lo.x)) && !all(&|p| on(p.x, hi.x)) && !all(&|p| on(p.z, hi.z))
        })
        .collect();
    assert_eq!(blocks.len(), 2 * 2 * 5, "two blocks of five quads (their floor faces are left out)");
    for x in &v {
        let p = Vec3::from(x.position);
        let n = Vec3::from(x.normal);
        let behind = tris.iter().filter_map(|t| ray_triangle(p, -n, *t).map(|d| (d, *t))).min_by(|a, b| a.0.total_cmp(&b.0));
        let (nearest, tri) = behind.unwrap_or_else(|| panic!("VPL {x:?} has no surface behind it"));
        assert!(nearest < 1e-4, "VPL {x:?} is {nearest} m from the surface behind it");
        let plane = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
        assert!(n.dot(plane).abs() > 0.9999, "VPL {x:?}: normal {n} is not its surface's {plane}");
        let probe = p + n * 1e-4;
        assert!(probe.cmpge(lo - 1e-6).all() && probe.cmple(hi + 1e-6).all(), "VPL normal points out of the room: {x:?}");
        let to_camera = camera - probe;
        let crossings = blocks.iter().filter_map(|t| ray_triangle(probe, to_camera.normalize(), *t)).filter(|&d| d < to_camera.length()).count();
        assert!(crossings % 2 == 0, "VPL normal points into a block ({crossings} block faces toward the camera): {x:?}");
    }
}

#[test]
fn same_seed_same_vpl_set() {
    let scene = cornell();
    let s = || RenderSettings { vpls_direct: 2000, vpls_indirect: 4000, seed: 9, ..small(8, 8, 1) };
    let key = |v: &GpuVpl| (v.kind, v.path, v.position.map(f32::to_bits), v.flux.map(f32::to_bits));
    let sorted = |mut v: Vec<GpuVpl>| {
        v.sort_by_key(key);
        v.iter().map(key).collect::<Vec<_>>()
    };
    let (a, pa) = vpls(&scene, s());
    let (b, pb) = vpls(&scene, s());
    assert_eq!((pa.paths, pa.rays), (pb.paths, pb.rays));
    // The Cornell box is open at the front: some photons leave it, so there are more rays than
    // indirect VPLs, and every path traces at least one.
    assert!(pa.rays > pa.indirect_vpls as u64 && pa.rays >= pa.paths, "{pa:?}");
    assert!(pa.paths_gpu_ms > 0.0 && pa.paths_gpu_ms <= pa.gpu_ms, "the path batches are part of the pass: {pa:?}");
    let exact = |v: &[GpuVpl]| v.iter().map(key).collect::<Vec<_>>();
    assert_eq!(exact(&a), exact(&b), "same seed, same VPLs in the same order");
    for w in a.iter().filter(|v| v.kind == VPL_INDIRECT).collect::<Vec<_>>().windows(2) {
        assert!(w[0].path <= w[1].path, "indirect VPLs in path order");
    }
    let (c, _) = vpls(&scene, RenderSettings { seed: 10, ..s() });
    assert_ne!(sorted(a), sorted(c));
}

#[test]
fn ply_dump_parses_back() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("vpls.ply");
    let settings = RenderSettings {
        vpls_direct: 3000,
        vpls_indirect: 5000,
        dump_vpls: Some(ply.clone()),
        out_dir: Some(dir.path().to_path_buf()),
        ..small(16, 16, 1)
    };
    let out = render(&cornell(), &settings);
    let stats = out.summary.photons.clone().expect("photon stats in the summary");
    let back = restir_vpl::ply::read_vpls(&ply).expect("PLY parses");
    assert_eq!(back.len() as u32, stats.direct_vpls + stats.indirect_vpls);
    assert_eq!(back.iter().filter(|v| v.kind == VPL_INDIRECT).count() as u32, stats.indirect_vpls);
    assert_rel(flux_sum(&back, |k| k != VPL_INDIRECT), stats.direct_flux, 1e-6, "PLY direct flux");
    assert_rel(flux_sum(&back, |k| k == VPL_INDIRECT), stats.indirect_flux, 1e-6, "PLY indirect flux");
    let header = std::fs::read(&ply).unwrap();
    let text = String::from_utf8_lossy(&header[..200]);
    assert!(text.starts_with("ply\nformat binary_little_endian 1.0\n"), "{text}");
    // Record by record, the VPLs the GPU holds for the same settings (the photon pass is
    // deterministic): a writer and reader that agreed on a wrong field order (normals for
    // positions) passed the counts and sums above.
    let (gpu, _) = vpls(&cornell(), RenderSettings { dump_vpls: None, out_dir: None, ..settings });
    assert_eq!(back.len(), gpu.len());
    for (i, (p, g)) in back.iter().zip(&gpu).enumerate() {
        assert_eq!((p.position, p.normal, p.flux, p.kind), (g.position, g.normal, g.flux, g.kind), "VPL {i}");
    }
}

/// `--view vpls`: blue spheres only at the light (direct VPLs), red spheres on the white back wall
/// only when global illumination is on.
#[test]
fn vpl_debug_view() {
    use restir_vpl::settings::View;
    let scene = cornell();
    let s = |gi: bool| RenderSettings {
        view: View::Vpls,
        gi,
        vpls_direct: 20_000,
        vpls_indirect: 40_000,
        vpl_radius: Some(0.006),
        ..small(96, 96, 1)
    };
    let is_blue = |p: &[f32; 3]| p[2] > 0.3 && p[2] > 3.0 * p[0] && p[2] > 2.0 * p[1];
    let is_red = |p: &[f32; 3]| p[0] > 0.25 && p[0] > 5.0 * p[1] && p[0] > 5.0 * p[2];
    // Back wall, between the blocks and below the light: rows 30..45, columns 40..56.
    let back_wall = |o: &restir_vpl::RunOutput| {
        (30..45).flat_map(|y| (40..56).map(move |x| y * 96 + x)).filter(|&i| is_red(&o.mean[i])).count()
    };
    let gi = render(&scene, &s(true));
    assert!(gi.summary.pass_ms.contains_key("vpl_view") && !gi.summary.pass_ms.contains_key("pathtrace"));
    let blue: Vec<usize> = (0..96 * 96).filter(|&i| is_blue(&gi.mean[i])).collect();
    assert!(!blue.is_empty(), "direct VPLs drawn");
    assert!(blue.iter().all(|i| i / 96 < 16), "blue spheres only near the ceiling light");
    assert!(back_wall(&gi) > 5, "indirect VPLs drawn on the back wall");
    let direct_only = render(&scene, &s(false));
    assert_eq!(back_wall(&direct_only), 0, "no indirect VPLs with --no-gi");
}
