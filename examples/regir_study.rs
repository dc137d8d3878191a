//! Would a ReGIR-style world-space grid of presampled VPLs (RTXDI's ReGIR) give RIS candidates
//! worth more than uniform ones? A CPU study on a dumped frame, before any GPU pass is built.
//!
//! `restir-vpl --headless --mode ris --scene S --width W --height H --frames 1 --dump-passes 0
//!  --dump-vpls DIR/vpls.ply --out DIR`, then
//! `cargo run --release --example regir_study -- DIR [CELLS_PER_AXIS] [ENTRY_CANDIDATES] [PIXELS] [normals]`
//! (`normals`: each cell split into 6 bins by the receiver's normal, whose cosine then bounds the
//! cell's target too).
//!
//! For the unshadowed target p̂ (the renderer's, without visibility and with ρ = 1), RIS over M
//! candidates drawn from a source q estimates Σ_y p̂(y) with variance Var[p̂(X)/q(X)] / M (the
//! target is the integrand). A grid entry is itself a RIS sample (Y, W) over K uniform candidates
//! with the cell's target p̂_c (positive wherever a pixel's in the cell can be); a pixel using M
//! entries estimates the same sum with variance Var[p̂(Y) W] / M. So each source's *relative
//! variance per candidate* (Var / mean²) says how many candidates it needs for a given quality,
//! and the ratio of two is the ratio of candidate evaluations at equal quality. Printed per source,
//! as the median and the mean over the sampled pixels (the mean approximates, for the unshadowed
//! luminance target, the per-pixel relative error an image's relMSE averages): uniform (the default), power (∝ lum Φ, `--candidate-source power`), the grid with k
//! candidates per entry and in the limit k → ∞, and a defensive mixture in that limit (half the
//! candidates uniform, half from the grid, balance-heuristic weights: an upper bound, exact for a
//! source chosen at random per candidate). Sums over every VPL, no Monte Carlo. Unshadowed only:
//! visibility, spatiotemporal reuse, pixels sharing a cell's finite pool of entries (variance ×
//! 1 + (M − 1)/E for M of E entries) and the grid's build cost are not in it.
use std::io::Read;

use anyhow::{bail, Context as _, Result};
use glam::Vec3;

struct Vpl {
    p: Vec3,
    n: Vec3,
    lum: f32,
    point: bool,
}

fn read_ply(path: &std::path::Path) -> Result<Vec<Vpl>> {
    let mut bytes = Vec::new();
    std::fs::File::open(path).with_context(|| path.display().to_string())?.read_to_end(&mut bytes)?;
    let end = bytes.windows(11).position(|w| w == b"end_header\n").context("no PLY header end")? + 11;
    let header = String::from_utf8_lossy(&bytes[..end]);
    let count: usize = header.lines().find_map(|l| l.strip_prefix("element vertex ")).context("vertex count")?.trim().parse()?;
    const REC: usize = 9 * 4 + 4;
    if bytes.len() < end + count * REC {
        bail!("{}: short file", path.display());
    }
    Ok((0..count)
        .map(|i| {
            let r = &bytes[end + i * REC..end + (i + 1) * REC];
            let f = |k: usize| f32::from_le_bytes(r[4 * k..4 * k + 4].try_into().unwrap());
            let flux = Vec3::new(f(6), f(7), f(8));
            Vpl { p: Vec3::new(f(0), f(1), f(2)), n: Vec3::new(f(3), f(4), f(5)), lum: flux.dot(Vec3::new(0.2126, 0.7152, 0.0722)), point: r[36] == 1 }
        })
        .collect())
}

/// Yuksel's clamped attenuation 2 / (d² + r² + d √(d² + r²)).
fn yuksel(d2: f32, r2: f32) -> f32 {
    2.0 / (d2 + r2 + (d2 * (d2 + r2)).sqrt())
}

/// The renderer's target without visibility (shaders/restir/vpl.glsl, ρ = 1, ns = ng = n).
fn target(v: &Vpl, x: Vec3, n: Vec3, r2: f32) -> f32 {
    let to_x = x - v.p;
    let d2 = to_x.length_squared();
    if d2 <= 0.0 {
        return 0.0;
    }
    let w = to_x / d2.sqrt();
    let cos_x = -n.dot(w);
    let emit = if v.point { 0.25 } else { v.n.dot(w) };
    if cos_x <= 0.0 || emit <= 0.0 {
        return 0.0;
    }
    v.lum * std::f32::consts::FRAC_1_PI * std::f32::consts::FRAC_1_PI * emit * cos_x * yuksel(d2, r2)
}

/// The cell's target: an upper bound of every point of the cell's bounding sphere (centre c,
/// radius rc) on the emission cosine and the attenuation, the receiver's cosine bounded by 1. It is
/// positive wherever `target` can be for a point in the cell.
fn cell_target(v: &Vpl, c: Vec3, rc: f32, r2: f32, axis: Option<Vec3>) -> f32 {
    let to_c = c - v.p;
    let dc = to_c.length();
    let dmin = (dc - rc).max(0.0);
    // With a normal bin (receivers whose normal's largest component is along `axis`: within
    // acos(1/√3) of it), the receiver's cosine is bounded too: the direction to the VPL lies within
    // asin(rc/dc) of the direction from the centre, so the angle between a normal of the bin and
    // it is at least angle(axis, −to_c) − acos(1/√3) − asin(rc/dc).
    let receiver = match axis {
        Some(a) if dc > rc => {
            let spread = (1.0f32 / 3.0f32.sqrt()).acos() + (rc / dc).asin();
            let angle = a.dot(-to_c / dc).clamp(-1.0, 1.0).acos();
            (angle - spread).max(0.0).cos().max(0.0) * if angle - spread >= std::f32::consts::FRAC_PI_2 { 0.0 } else { 1.0 }
        }
        _ => 1.0,
    };
    let emit = if v.point {
        0.25
    } else if dc <= rc {
        1.0
    } else {
        ((v.n.dot(to_c) + rc) / dmin.max(1e-6)).clamp(0.0, 1.0)
    };
    v.lum * std::f32::consts::FRAC_1_PI * std::f32::consts::FRAC_1_PI * emit * receiver * yuksel(dmin * dmin, r2)
}

/// The normal bin of a receiver: its normal's largest component, signed (6 bins).
fn normal_axis(n: Vec3) -> Vec3 {
    let a = n.abs();
    if a.x >= a.y && a.x >= a.z {
        Vec3::new(n.x.signum(), 0.0, 0.0)
    } else if a.y >= a.z {
        Vec3::new(0.0, n.y.signum(), 0.0)
    } else {
        Vec3::new(0.0, 0.0, n.z.signum())
    }
}

/// A small xorshift generator, to pick the pixels (the study needs no more).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let dir = std::path::PathBuf::from(args.get(1).context("usage: regir_study DIR [CELLS] [K] [PIXELS] [normals]")?);
    let cells: usize = args.get(2).map_or(Ok(8), |s| s.parse())?;
    let k: usize = args.get(3).map_or(Ok(8), |s| s.parse())?;
    let pixels: usize = args.get(4).map_or(Ok(400), |s| s.parse())?;
    // "normals": cells split into 6 bins by the receiver's normal, with its cosine bounded.
    let binned = args.get(5).is_some_and(|s| s == "normals");
    if cells == 0 || k == 0 || pixels == 0 {
        bail!("CELLS, K and PIXELS must be at least 1");
    }
    let vpls = read_ply(&dir.join("vpls.ply"))?;
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json"))?)?;
    let r = summary["vpl"]["yuksel_radius"].as_f64().context("summary.json: vpl.yuksel_radius")? as f32;
    let r2 = r * r;
    let frame = dir.join("passes/frame_0000");
    let pos = restir_vpl::output::read_exr(&frame.join("00_gbuffer__position.exr"))?;
    let nor = restir_vpl::output::read_exr(&frame.join("00_gbuffer__normal.exr"))?;
    let surface: Vec<(Vec3, Vec3)> = pos
        .pixels
        .iter()
        .zip(&nor.pixels)
        .map(|(p, n)| (Vec3::from(*p), Vec3::from(*n)))
        .filter(|(_, n)| (n.length() - 1.0).abs() < 1e-2)
        .collect();
    // The grid over the bounds of the VPLs and the visible surfaces.
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for p in vpls.iter().map(|v| v.p).chain(surface.iter().map(|s| s.0)) {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let size = (hi - lo) / cells as f32;
    let rc = 0.5 * size.length();
    let cell_of = |x: Vec3| -> [usize; 3] {
        let c = ((x - lo) / size).floor();
        [0, 1, 2].map(|i| (c[i].max(0.0) as usize).min(cells - 1))
    };
    let centre = |c: [usize; 3]| lo + (Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) + 0.5) * size;
    let total_lum: f64 = vpls.iter().map(|v| v.lum as f64).sum();
    let n = vpls.len() as f64;
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut ru, mut rp, mut rg, mut ri, mut rm) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut eval_cells = std::collections::HashMap::new();
    for _ in 0..pixels {
        let (x, nx) = surface[rng.below(surface.len())];
        // Exact moments for uniform (q = 1/N) and power (q = lum/Σlum).
        let (mut s1, mut s2u, mut s2p) = (0.0f64, 0.0f64, 0.0f64);
        for v in &vpls {
            let t = target(v, x, nx, r2) as f64;
            s1 += t;
            s2u += t * t * n;
            if v.lum > 0.0 {
                s2p += t * t * total_lum / v.lum as f64;
            }
        }
        if s1 <= 0.0 {
            continue;
        }
        ru.push(s2u / (s1 * s1) - 1.0);
        rp.push(s2p / (s1 * s1) - 1.0);
        // The grid: entries of this pixel's cell, each RIS over k uniform candidates.
        let cell = cell_of(x);
        let c0 = centre(cell);
        let axis = binned.then(|| normal_axis(nx));
        // Its limit for k → ∞, exactly: entries drawn ∝ p̂_c with W = Σ p̂_c / p̂_c(y) (finite k
        // blends it with uniform's, below).
        let (mut sc, mut s2c) = (0.0f64, 0.0f64);
        for v in &vpls {
            let pc = cell_target(v, c0, rc, r2, axis) as f64;
            if pc > 0.0 {
                let t = target(v, x, nx, r2) as f64;
                sc += pc;
                s2c += t * t / pc;
            }
        }
        ri.push(sc * s2c / (s1 * s1) - 1.0);
        // A defensive mixture, also for k → ∞: half the candidates uniform, half from the grid, the
        // pair weighted by the balance heuristic of the two (known) densities.
        let mut s2m = 0.0f64;
        for v in &vpls {
            let t = target(v, x, nx, r2) as f64;
            if t > 0.0 {
                let q = 0.5 / n + 0.5 * cell_target(v, c0, rc, r2, axis) as f64 / sc;
                s2m += t * t / q;
            }
        }
        rm.push(s2m / (s1 * s1) - 1.0);
        *eval_cells.entry(cell).or_insert(0usize) += 1;
        // Finite k, exactly: with w = p̂_c / q over k uniform candidates and r = p̂ / p̂_c, the
        // entry's estimate p̂(Y) W has E[(p̂ W)²] = (1/k) E[w² r²] + ((k−1)/k) E[w] E[w r²], so its
        // relative variance is (1/k) × uniform's + ((k−1)/k) × the k → ∞ limit's.
        let (ru_here, ri_here) = (ru[ru.len() - 1], ri[ri.len() - 1]);
        rg.push(ru_here / k as f64 + (k as f64 - 1.0) / k as f64 * ri_here);
    }
    if ru.is_empty() {
        bail!("none of the {pixels} sampled pixels is lit");
    }
    let stats = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        (v[v.len() / 2], v.iter().sum::<f64>() / v.len() as f64)
    };
    let (mu, au) = stats(&mut ru);
    let (mp, ap) = stats(&mut rp);
    let (mg, ag) = stats(&mut rg);
    let (mi, ai) = stats(&mut ri);
    let (mm, am) = stats(&mut rm);
    println!("{} VPLs, {} pixels sampled ({} lit), {cells}³ cells{} ({} visited), {k} candidates per grid entry, Yuksel r = {r}", vpls.len(), pixels, ru.len(), if binned { " × 6 normal bins" } else { "" }, eval_cells.len());
    println!("relative variance per candidate (median / mean over pixels)");
    println!("  uniform: {mu:.3} / {au:.3}");
    println!("  power:   {mp:.3} / {ap:.3}");
    println!("  grid, {k} uniform candidates per entry: {mg:.3} / {ag:.3}   (pixel-side candidates for uniform's quality: {:.2}× / {:.2}×)", mg / mu, ag / au);
    println!("  grid, k → ∞: {mi:.3} / {ai:.3}   ({:.2}× / {:.2}×)", mi / mu, ai / au);
    println!("  half uniform, half grid, k → ∞ (upper bound; exact for a source chosen at random): {mm:.3} / {am:.3}   ({:.2}× / {:.2}×)", mm / mu, am / au);
    Ok(())
}
