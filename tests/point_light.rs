//! Point lights (KHR_lights_punctual) in the path tracer, against the closed form.
//!
//! A point light of intensity I at height h above an infinite-enough plane of albedo ρ, nothing
//! else: the radiance leaving the plane at x is L = (ρ/π)·I·cos θ / d² (d the distance to the light,
//! cos θ = h/d); no other light path exists (a plane cannot see itself). With a single light the
//! next-event estimate is deterministic, so every pixel must match to float precision.

mod common;

use common::*;
use glam::Vec3;
use restir_vpl::camera::Camera;
use restir_vpl::scene::generate::GltfBuilder;
use restir_vpl::settings::CameraOverride;
use restir_vpl::RenderSettings;

#[test]
fn point_light_over_a_plane_matches_the_closed_form() {
    let (rho, intensity, h) = (0.5f32, 2.0f32, 1.0f32);
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [rho; 3], [0.0; 3], false);
    let m = b.quad("plane", [[-5.0, 0.0, -5.0], [-5.0, 0.0, 5.0], [5.0, 0.0, 5.0], [5.0, 0.0, -5.0]], grey);
    b.node("plane", m, [0.0; 3]);
    b.point_light("bulb", [0.0, h, 0.0], [1.0, 1.0, 1.0], intensity);
    let scene = load_json(&b.to_json_string(), "point_light");
    let (w, hgt) = (48u32, 48u32);
    let cam = CameraOverride {
        eye: Vec3::new(0.3, 3.0, 0.2),
        target: Vec3::new(0.0, 0.0, 0.0),
        up: Vec3::new(0.0, 0.0, -1.0),
        yfov_degrees: 60.0,
    };
    let settings = RenderSettings { camera: Some(cam), max_bounces: 3, ..small(w, hgt, 2) };
    let out = render(&scene, &settings);
    let c = Camera::look_at(cam.eye, cam.target, cam.up, cam.yfov_degrees.to_radians(), "test");
    let tan = (c.yfov * 0.5).tan();
    let light = Vec3::new(0.0, h, 0.0);
    let mut checked = 0;
    for py in 0..hgt {
        for px in 0..w {
            let ndc_x = 2.0 * (px as f32 + 0.5) / w as f32 - 1.0;
            let ndc_y = 1.0 - 2.0 * (py as f32 + 0.5) / hgt as f32;
            let dir = (c.forward + ndc_x * tan * c.right + ndc_y * tan * c.up).normalize();
            let t = -c.position.y / dir.y;
            let x = c.position + t * dir;
            if x.x.abs() > 4.9 || x.z.abs() > 4.9 {
                continue;
            }
            let d2 = (light - x).length_squared();
            let cos = h / d2.sqrt();
            let expected = rho / std::f32::consts::PI * intensity * cos / d2;
            let got = out.mean[(py * w + px) as usize];
            for ch in got {
                assert!((ch - expected).abs() <= 1e-3 * expected, "pixel ({px},{py}): {ch} vs {expected}");
            }
            checked += 1;
        }
    }
    assert!(checked > 1000);
}

/// Point lights spawned in the window (L) are held to the loader's limit on the lights' power:
/// each press added a quarter of the scene's, and past 1e30 W the 32-bit fluxes overflow. A light
/// that keeps the total under it is taken, one that passes it is refused and the lights stay.
/// A point light lying in a surface (a bulb placed on a floor, exactly at its height) lights a
/// wall behind it as the closed form says, every pixel: the shadow rays toward it met the floor
/// at the light's own point (t ~ their length, rounded either way), and speckles of the wall went
/// black (the Cornell box's direct light read 16 % dark). One bounce: the wall's direct light
/// alone, L = (ρ/π)·I·cos θ / d² with cos θ = (z_light − z_wall) / d. And one just under the
/// floor lights nothing above it.
#[test]
fn a_point_light_lying_in_a_floor_lights_the_wall_behind_it() {
    let (rho, intensity) = (0.5f32, 2.0f32);
    let light = Vec3::new(0.1, 0.0, 0.2);
    let scene = floor_and_wall(rho, light, intensity, "bulb_in_the_floor");
    let (w, hgt) = (48u32, 48u32);
    let cam = CameraOverride { eye: Vec3::new(0.0, 1.0, 3.0), target: Vec3::new(0.0, 1.0, -1.0), up: Vec3::Y, yfov_degrees: 60.0 };
    // The path tracer's light sampling, and the VPL shading's shadow rays to the light's direct
    // VPLs (all at the light: brute force over them is the same sum, with 1/d²).
    let pt = RenderSettings { camera: Some(cam), max_bounces: 1, ..small(w, hgt, 2) };
    let vpls = RenderSettings {
        mode: restir_vpl::settings::Mode::Bruteforce,
        view: restir_vpl::settings::View::Direct,
        attenuation: restir_vpl::settings::Attenuation::InverseSquare,
        vpls_direct: 64,
        vpls_indirect: 64,
        ..pt.clone()
    };
    for settings in [pt.clone(), vpls.clone()] {
        wall_matches_the_closed_form(&scene, &settings, light, rho, intensity);
    }
    // A bulb just under the floor (1e-5: ~20 ulps of the scene's largest coordinate, so not in
    // it) is behind it: the wall stays black in both. (Shadow rays that stopped a margin short of
    // the light, 2^-16 of their length, let it through for wall points above ~0.3.)
    let under = floor_and_wall(rho, Vec3::new(light.x, -1e-5, light.z), intensity, "bulb_under_the_floor");
    for settings in [pt, vpls] {
        let out = render(&under, &settings);
        let lit = out.mean.iter().filter(|p| p.iter().any(|&c| c != 0.0)).count();
        assert_eq!(lit, 0, "{:?}: {lit} pixels lit by a light under the floor", settings.mode);
    }
}

/// A 10 × 6 floor (y = 0, facing up) meeting a 10 × 5 wall at z = -1 (facing +z), albedo ρ, and a
/// white point light of `intensity` at `light`.
fn floor_and_wall(rho: f32, light: Vec3, intensity: f32, name: &str) -> restir_vpl::scene::Scene {
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [rho; 3], [0.0; 3], false);
    let floor = b.quad("floor", [[-5.0, 0.0, -1.0], [-5.0, 0.0, 5.0], [5.0, 0.0, 5.0], [5.0, 0.0, -1.0]], grey);
    b.node("floor", floor, [0.0; 3]);
    let wall = b.quad("wall", [[-5.0, 0.0, -1.0], [5.0, 0.0, -1.0], [5.0, 5.0, -1.0], [-5.0, 5.0, -1.0]], grey);
    b.node("wall", wall, [0.0; 3]);
    b.point_light("bulb", light.to_array(), [1.0, 1.0, 1.0], intensity);
    load_json(&b.to_json_string(), name)
}

fn wall_matches_the_closed_form(scene: &restir_vpl::scene::Scene, settings: &RenderSettings, light: Vec3, rho: f32, intensity: f32) {
    let (w, hgt) = (settings.width, settings.height);
    let cam = settings.camera.expect("the test's camera");
    let out = render(scene, settings);
    let c = Camera::look_at(cam.eye, cam.target, cam.up, cam.yfov_degrees.to_radians(), "test");
    let tan = (c.yfov * 0.5).tan();
    let (mut checked, mut black) = (0, 0);
    for py in 0..hgt {
        for px in 0..w {
            let ndc_x = 2.0 * (px as f32 + 0.5) / w as f32 - 1.0;
            let ndc_y = 1.0 - 2.0 * (py as f32 + 0.5) / hgt as f32;
            let dir = (c.forward + ndc_x * tan * c.right + ndc_y * tan * c.up).normalize();
            let x = c.position + (-1.0 - c.position.z) / dir.z * dir;
            if x.y < 0.05 || x.y > 4.9 || x.x.abs() > 4.9 {
                continue;
            }
            let d = (light - x).length();
            let expected = rho / std::f32::consts::PI * intensity * ((light.z - x.z) / d) / (d * d);
            let got = out.mean[(py * w + px) as usize];
            black += usize::from(got[0] == 0.0);
            for ch in got {
                assert!((ch - expected).abs() <= 1e-3 * expected, "{:?}: pixel ({px},{py}) of the wall: {ch} vs {expected} ({black} black so far)", settings.mode);
            }
            checked += 1;
        }
    }
    assert!(checked > 1000, "{checked} wall pixels");
}

#[test]
fn spawned_lights_are_held_to_the_power_limit() {
    use restir_vpl::lights::PointEmitter;
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    let m = b.quad("plane", [[-5.0, 0.0, -5.0], [-5.0, 0.0, 5.0], [5.0, 0.0, 5.0], [5.0, 0.0, -5.0]], grey);
    b.node("plane", m, [0.0; 3]);
    b.point_light("bulb", [0.0, 1.0, 0.0], [1.0, 1.0, 1.0], 1.0);
    let scene = load_json(&b.to_json_string(), "spawned_light_limit");
    let ctx = context();
    let settings = RenderSettings { mode: restir_vpl::settings::Mode::Uniform, vpls_direct: 100, vpls_indirect: 100, ..small(8, 8, 1) };
    let gpu = upload(&ctx, &scene, &settings);
    let mut r = restir_vpl::renderer::Renderer::new(ctx.clone(), gpu, settings).unwrap();
    // 4π I W each: 0.6e30 W is taken, a second one (1.2e30 W in all) is refused.
    let light = PointEmitter { position: Vec3::new(1.0, 1.0, 0.0), intensity: Vec3::splat(0.6e30 / (4.0 * std::f32::consts::PI)) };
    r.set_extra_lights(vec![light]).expect("under the limit");
    let err = format!("{:#}", r.set_extra_lights(vec![light, light]).unwrap_err());
    assert!(err.contains("1e30 W"), "{err}");
    assert_eq!(r.extra_lights().len(), 1, "the lights stay as they were");
    r.render_frame(&r.initial_camera(), false).unwrap();
    assert_all_finite(&r.read_mean().unwrap(), "after a refused light");
    assert_no_validation_errors(&ctx);
}
