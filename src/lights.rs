//! Lights: every emissive triangle, with power Φ = sides·π·Le·A (sides = 2 for a double-sided
//! emitter), and every KHR_lights_punctual point light, with power Φ = 4π·I; chosen in proportion
//! to lum(Φ) through Vose's alias table.

use glam::Vec3;

use crate::gpu_types::{GpuAliasEntry, GpuLight, LIGHT_POINT, MATERIAL_DOUBLE_SIDED};
use crate::scene::Scene;

/// Rec. 709 luminance.
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The scene's area lights and their selection table.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub lights: Vec<GpuLight>,
    pub alias: Vec<GpuAliasEntry>,
    /// Σ lum(Φ_t) (W, luminance-weighted).
    pub total_power_lum: f64,
    /// Σ Φ_t per channel (W).
    pub total_power: [f64; 3],
}

/// A point light: position and radiant intensity I (W/sr per channel; power 4π·I).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointEmitter {
    pub position: Vec3,
    pub intensity: Vec3,
}

/// The emitters of a scene, kept on the host so that light sets can be rebuilt (with lights added
/// by the window) without the [`Scene`].
#[derive(Clone, Debug, Default)]
pub struct Emitters {
    pub triangles: Vec<crate::scene::EmissiveTriangle>,
    pub points: Vec<PointEmitter>,
}

impl Emitters {
    pub fn from_scene(scene: &Scene) -> Self {
        // glTF point-light intensity is in candela; radiometrically we read it as W/sr per channel.
        let points = scene
            .point_lights
            .iter()
            .map(|p| PointEmitter { position: p.position, intensity: p.color * p.intensity })
            .collect();
        Self { triangles: scene.emissive_triangles(), points }
    }
}

impl LightSet {
    pub fn from_scene(scene: &Scene) -> Self {
        Self::new(&Emitters::from_scene(scene), &[])
    }

    /// The lights of `emitters` plus `extra` point lights (points of zero or non-finite intensity
    /// are left out).
    pub fn new(emitters: &Emitters, extra: &[PointEmitter]) -> Self {
        let tris = &emitters.triangles;
        let points: Vec<(Vec3, Vec3)> = emitters
            .points
            .iter()
            .chain(extra)
            .map(|p| (p.position, p.intensity))
            .filter(|(_, i)| i.max_element() > 0.0 && i.is_finite())
            .collect();
        let powers: Vec<(Vec3, f64)> = tris
            .iter()
            .map(|t| {
                let sides = if t.double_sided { 2.0 } else { 1.0 };
                t.emission * (sides * std::f32::consts::PI * t.area)
            })
            .chain(points.iter().map(|(_, i)| *i * (4.0 * std::f32::consts::PI)))
            .map(|phi| (phi, luminance(phi) as f64))
            .collect();
        let total_power_lum: f64 = powers.iter().map(|p| p.1).sum();
        let mut total_power = [0.0f64; 3];
        for (phi, _) in &powers {
            total_power[0] += phi.x as f64;
            total_power[1] += phi.y as f64;
            total_power[2] += phi.z as f64;
        }
        let weights: Vec<f64> = powers.iter().map(|p| p.1).collect();
        let pdf = |w: f64| if total_power_lum > 0.0 { (w / total_power_lum) as f32 } else { 0.0 };
        let lights = tris
            .iter()
            .zip(&weights)
            .map(|(t, w)| GpuLight {
                p0: t.p[0].to_array(),
                area: t.area,
                p1: t.p[1].to_array(),
                pdf: pdf(*w),
                p2: t.p[2].to_array(),
                flags: if t.double_sided { MATERIAL_DOUBLE_SIDED } else { 0 },
                emission: t.emission.to_array(),
                _pad0: 0,
            })
            .chain(points.iter().zip(&weights[tris.len()..]).map(|((pos, i), w)| GpuLight {
                p0: pos.to_array(),
                pdf: pdf(*w),
                flags: LIGHT_POINT,
                emission: i.to_array(),
                ..Default::default()
            }))
            .collect();
        Self { lights, alias: alias_table(&weights), total_power_lum, total_power }
    }
}

/// Vose's alias method: slot i keeps i with probability `keep`, else yields `alias`. Sampling a
/// uniform slot then resolving gives P(i) = w_i / Σw exactly (up to float rounding of `keep`).
pub fn alias_table(weights: &[f64]) -> Vec<GpuAliasEntry> {
    let n = weights.len();
    let total: f64 = weights.iter().sum();
    if n == 0 || total <= 0.0 {
        return (0..n as u32).map(|i| GpuAliasEntry { keep: 1.0, alias: i }).collect();
    }
    let mut scaled: Vec<f64> = weights.iter().map(|w| w * n as f64 / total).collect();
    let mut table: Vec<GpuAliasEntry> = (0..n as u32).map(|i| GpuAliasEntry { keep: 1.0, alias: i }).collect();
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(s), Some(&l)) = (small.pop(), large.last()) {
        table[s] = GpuAliasEntry { keep: scaled[s] as f32, alias: l as u32 };
        scaled[l] = (scaled[l] + scaled[s]) - 1.0;
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    // Leftovers (rounding): keep themselves with probability 1.
    table
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The alias table reproduces the target distribution exactly (computed, not sampled).
    #[test]
    fn alias_table_is_exact() {
        let w = [1.0, 0.0, 5.0, 2.5, 0.25, 7.0, 1e-3];
        let t = alias_table(&w);
        let n = w.len() as f64;
        let total: f64 = w.iter().sum();
        let mut p = vec![0.0f64; w.len()];
        for (i, e) in t.iter().enumerate() {
            p[i] += e.keep as f64 / n;
            p[e.alias as usize] += (1.0 - e.keep as f64) / n;
        }
        for (i, wi) in w.iter().enumerate() {
            assert!((p[i] - wi / total).abs() < 1e-6, "slot {i}: {} vs {}", p[i], wi / total);
        }
    }
}
