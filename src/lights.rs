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
        let alias = alias_table(&weights);
        // Each light's probability of being picked as the shaders pick it (`alias_pdfs`), which
        // the path tracer divides by: w / Σw differed from it by up to 2^-32 / keep relative.
        let picked = alias_pdfs(&alias);
        let pdfs: Vec<f64> = if total_power_lum > 0.0 { picked } else { vec![0.0; weights.len()] };
        let pdf = |i: usize| pdfs[i] as f32;
        let lights = tris
            .iter()
            .enumerate()
            .map(|(i, t)| GpuLight {
                p0: t.p[0].to_array(),
                area: t.area,
                p1: t.p[1].to_array(),
                pdf: pdf(i),
                p2: t.p[2].to_array(),
                flags: if t.double_sided { MATERIAL_DOUBLE_SIDED } else { 0 },
                emission: t.emission.to_array(),
                _pad0: 0,
            })
            .chain(points.iter().enumerate().map(|(k, (pos, i))| GpuLight {
                p0: pos.to_array(),
                pdf: pdf(tris.len() + k),
                flags: LIGHT_POINT,
                emission: i.to_array(),
                ..Default::default()
            }))
            .collect();
        Self { lights, alias, total_power_lum, total_power }
    }
}

/// The smallest `keep` of an entry with a positive weight: 2^-32, the shaders' resolution
/// (`alias_resolve` keeps when 32 random bits are below floor(keep · 2^32)), so that every light
/// and VPL with power can be picked.
const MIN_KEEP: f32 = 1.0 / 4_294_967_296.0;

/// Vose's alias method: slot i keeps i with probability `keep`, else yields `alias`. Sampling a
/// uniform slot then resolving gives P(i) = w_i / Σw up to the shaders' arithmetic, which
/// [`alias_pdfs`] gives exactly.
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
        let keep = if weights[s] > 0.0 { (scaled[s] as f32).max(MIN_KEEP) } else { scaled[s] as f32 };
        table[s] = GpuAliasEntry { keep, alias: l as u32 };
        scaled[l] = (scaled[l] + scaled[s]) - 1.0;
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    // Leftovers (rounding): keep themselves with probability 1.
    table
}

/// The probability that the shaders pick each index from `table` (shaders/lib/sampling.glsl):
/// the slot floor(b · n / 2^32) of 32 random bits b, which slot k gets for
/// ceil((k + 1) 2^32 / n) − ceil(k 2^32 / n) of the 2^32 values, then the slot kept when 32 more
/// bits are below floor(keep · 2^32) (keep ≥ 1: always), else its alias. Exact (integer counts)
/// up to the final f64 rounding.
pub fn alias_pdfs(table: &[GpuAliasEntry]) -> Vec<f64> {
    let n = table.len() as u128;
    let two32: u128 = 1 << 32;
    let mut p = vec![0.0f64; table.len()];
    for (k, e) in table.iter().enumerate() {
        let k = k as u128;
        let slot_values = ((k + 1) * two32).div_ceil(n) - (k * two32).div_ceil(n);
        let kept: u128 = if e.keep >= 1.0 { two32 } else { (f64::from(e.keep.max(0.0)) * two32 as f64).floor() as u128 };
        p[k as usize] += (slot_values * kept) as f64 / (two32 * two32) as f64;
        p[e.alias as usize] += (slot_values * (two32 - kept)) as f64 / (two32 * two32) as f64;
    }
    p
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

    /// `alias_pdfs` is what the shaders' 32-bit arithmetic samples: it sums to 1, agrees with
    /// w / Σw for ordinary weights, keeps every index with a weight pickable (a light with 1e-12
    /// of the power, which float keep tests never picked), and matches a draw of 4 million pairs
    /// of 32-bit words through the same integer steps (each index within 5 standard errors).
    #[test]
    fn alias_pdfs_are_the_shaders_sampling_probabilities() {
        let w = [1.0, 2.0, 0.0, 3.0, 1e-12, 0.5, 7.0];
        let total: f64 = w.iter().sum();
        let table = alias_table(&w);
        let p = alias_pdfs(&table);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{p:?}");
        for (i, wi) in w.iter().enumerate() {
            if *wi >= 1e-3 || *wi == 0.0 {
                assert!((p[i] - wi / total).abs() <= 1e-6 * (wi / total) + 1e-15, "index {i}: {} against {}", p[i], wi / total);
            }
        }
        assert!(p[4] > 0.0 && p[4] < 1e-9, "the faint index: {}", p[4]);
        assert_eq!(p[2], 0.0, "a zero weight is never picked");
        // The shaders' steps on the CPU (xorshift words; the counts are binomial).
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 32) as u32
        };
        let draws = 4_000_000u64;
        let mut counts = vec![0u64; w.len()];
        for _ in 0..draws {
            let slot = ((u64::from(next()) * w.len() as u64) >> 32) as usize;
            let e = &table[slot];
            let bits = next();
            let kept = e.keep >= 1.0 || bits < (f64::from(e.keep) * 4_294_967_296.0) as u32;
            counts[if kept { slot } else { e.alias as usize }] += 1;
        }
        for (i, (&c, &pi)) in counts.iter().zip(&p).enumerate() {
            let se = (draws as f64 * pi * (1.0 - pi)).sqrt().max(1.0);
            assert!((c as f64 - draws as f64 * pi).abs() <= 5.0 * se, "index {i}: {c} draws against {} expected", draws as f64 * pi);
        }
    }
}
