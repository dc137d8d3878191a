//! Per-VPL Yuksel radius from each VPL's nearest VPLs (`--yuksel-knn K`).
//!
//! The global rule takes r = M × the mean VPL spacing √(A / (π N)): the radius of the disc that
//! holds one VPL on average, if N VPLs covered the scene's area A evenly. The local rule asks the
//! same question around each VPL: if its K nearest VPLs (itself excluded) lie within d_K, the
//! local density on the surface is K / (π d_K²) and the local spacing is d_K / √K; r_i = M × that.
//! Where photons crowd (near a light, in a bright corner) VPLs get small radii and keep their
//! light; where they are sparse the clamp widens to hide their singularity. Virtual Blue Noise
//! Lighting (Li et al., HPG 2022) sets each VPL's radius the same way, from a k-nearest-neighbour
//! search (twice its Poisson-disk radius).
//!
//! Distances are Euclidean in 3D, so a VPL's neighbours may sit on another surface (across a
//! corner or a thin wall): there the density reads higher and the radius smaller than on one flat
//! surface — the safe side, since it darkens less.
//!
//! The search runs on the host through an R*-tree (`rstar`), once per VPL set (a static scene
//! traces photons once); `bench --radius` reports what it costs.

use rstar::primitives::GeomWithData;
use rstar::RTree;

/// Each point's local spacing d_K / √K from its `k` nearest other points (Euclidean). A point whose
/// K-th neighbour coincides with it (d_K = 0: VPLs of a point light share one position), or a set
/// of at most one point, gets `None`: it has no local spacing; the caller falls back to the global
/// rule for it. With fewer than K other points, all of them are used.
pub fn local_spacings(positions: &[[f32; 3]], k: usize) -> Vec<Option<f32>> {
    let n = positions.len();
    let k = k.min(n.saturating_sub(1));
    if k == 0 {
        return vec![None; n];
    }
    let tree = RTree::bulk_load(positions.iter().enumerate().map(|(i, p)| GeomWithData::new(*p, i as u32)).collect());
    let query = |p: &[f32; 3]| -> Option<f32> {
        // The nearest K + 1 include the point itself (or a twin at distance 0, which is the same).
        let d2 = tree.nearest_neighbor_iter_with_distance_2(*p).take(k + 1).last().map(|(_, d2)| d2)?;
        let s = (d2.sqrt() / (k as f32).sqrt()).max(0.0);
        (s > 0.0 && s.is_finite()).then_some(s)
    };
    // Two halves on two threads (this machine class has 2 cores; the tree is shared read-only).
    let threads = std::thread::available_parallelism().map(|t| t.get()).unwrap_or(1).clamp(1, 8);
    let chunk = n.div_ceil(threads).max(1);
    let mut out = vec![None; n];
    std::thread::scope(|scope| {
        for (ps, os) in positions.chunks(chunk).zip(out.chunks_mut(chunk)) {
            let query = &query;
            scope.spawn(move || {
                for (p, o) in ps.iter().zip(os.iter_mut()) {
                    *o = query(p);
                }
            });
        }
    });
    out
}

/// Yuksel's r² per VPL: (`multiple` × local spacing)², or `fallback_r`² where a VPL has no local
/// spacing (see [`local_spacings`]). Returns the r² values and the median radius (for the log).
pub fn knn_r2(positions: &[[f32; 3]], k: usize, multiple: f32, fallback_r: f32) -> (Vec<f32>, f32) {
    let spacings = local_spacings(positions, k);
    // At most MAX_YUKSEL_RADIUS, as the global radius is checked to be: a sparse VPL's local
    // spacing runs above the mean one, and with a large --yuksel-spacings its r² overflowed to inf
    // (the shader's G then 0, or NaN at d = 0). A radius that large clamps everywhere anyway.
    let max = crate::settings::MAX_YUKSEL_RADIUS;
    let mut radii: Vec<f32> = spacings.iter().map(|s| s.map_or(fallback_r, |s| (multiple * s).min(max))).collect();
    let r2 = radii.iter().map(|r| r * r).collect();
    let median = if radii.is_empty() {
        fallback_r
    } else {
        let mid = radii.len() / 2;
        *radii.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    (r2, median)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a square grid of pitch h the density is 1/h², so the spacing √(1/(π density)) is
    /// h/√π ≈ 0.564 h. With K = 12 the 12th neighbour of an interior point is at 2h (4 at h, 4 at
    /// √2 h, 4 at 2h): d_K/√K = 2h/√12 ≈ 0.577 h, 2.3 % off — the estimate's own discreteness.
    #[test]
    fn grid_spacing_matches_the_density() {
        let h = 0.01f32;
        let side = 60;
        let pts: Vec<[f32; 3]> = (0..side * side).map(|i| [(i % side) as f32 * h, 0.5, (i / side) as f32 * h]).collect();
        let s = local_spacings(&pts, 12);
        let centre = (side / 2) * side + side / 2;
        let got = s[centre].expect("interior point has neighbours");
        assert!((got - 2.0 * h / 12f32.sqrt()).abs() < 1e-6, "{got}");
        let expected = h / std::f32::consts::PI.sqrt();
        assert!((got / expected - 1.0).abs() < 0.05, "{got} vs {expected}");
    }

    /// Uniform random points on a unit square: the median local spacing is near the global
    /// √(A/(πN)) (within 15 %: the K-th neighbour distance of a Poisson process is a Gamma
    /// variable, median slightly below its mean, and points near the edge see fewer neighbours).
    #[test]
    fn random_points_agree_with_the_global_rule() {
        let n = 20_000;
        let mut state = 12345u64;
        let mut rnd = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let pts: Vec<[f32; 3]> = (0..n).map(|_| [rnd(), rnd(), 0.0]).collect();
        let global = (1.0 / (std::f32::consts::PI * n as f32)).sqrt();
        let (r2, median) = knn_r2(&pts, 16, 1.0, 123.0);
        assert_eq!(r2.len(), n);
        assert!(r2.iter().all(|r| r.is_finite() && *r > 0.0));
        assert!((median / global - 1.0).abs() < 0.15, "median {median} vs global {global}");
    }

    /// Coincident points (a point light's VPLs) and tiny sets fall back; nothing is NaN.
    #[test]
    fn degenerate_sets_fall_back() {
        let same = vec![[1.0f32, 2.0, 3.0]; 50];
        let (r2, median) = knn_r2(&same, 8, 8.0, 0.5);
        assert!(r2.iter().all(|&r| r == 0.25));
        assert_eq!(median, 0.5);
        assert_eq!(knn_r2(&[[0.0; 3]], 8, 8.0, 0.5).0, vec![0.25]);
        assert!(knn_r2(&[], 8, 8.0, 0.5).0.is_empty());
        // Two points: the one neighbour is used (K clamps to n − 1).
        let two = local_spacings(&[[0.0; 3], [3.0, 4.0, 0.0]], 8);
        assert_eq!(two, vec![Some(5.0), Some(5.0)]);
    }

    /// A large multiple of a sparse set's spacing stays a finite r² (its square overflowed f32).
    #[test]
    fn radii_stop_at_the_largest_radius_allowed() {
        let pts = [[0.0f32; 3], [1e3, 0.0, 0.0], [0.0, 1e3, 0.0]];
        let (r2, median) = knn_r2(&pts, 2, 1e17, 0.5);
        let max = crate::settings::MAX_YUKSEL_RADIUS;
        assert!(r2.iter().all(|r| r.is_finite() && *r == max * max), "{r2:?}");
        assert_eq!(median, max);
    }
}
