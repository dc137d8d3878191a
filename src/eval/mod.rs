//! The evaluation harness, apart from the renderer: long references and their merging
//! ([`reference`]), image metrics ([`compare`]), benchmarks ([`bench`]), the error-versus-time study
//! ([`results`]) and the Markdown/CSV/plot report it writes ([`report`]). Everything here drives the
//! renderer through [`crate::renderer::Renderer`] like any other caller.

pub mod bench;
pub mod compare;
pub mod motion;
pub mod radius;
pub mod rays;
pub mod reference;
pub mod report;
pub mod results;
pub mod scaling;

/// Run `run`'s seed in the evaluations' repeated runs: a fixed stride from the base seed, never the
/// base seed itself (which renders the references). A renderer built with it traces its own VPL
/// set; one restarted with it keeps its VPL set and draws new pixel noise.
pub fn run_seed(base: u32, run: u32) -> u32 {
    base.wrapping_add(0x9e37_79b9u32.wrapping_mul(run + 1))
}

#[cfg(test)]
mod tests {
    use super::run_seed;

    /// Runs have seeds of their own (so VPL sets of their own), none of them the reference's.
    #[test]
    fn run_seeds_are_distinct_and_not_the_base() {
        for base in [0u32, 7, u32::MAX] {
            let seeds: Vec<u32> = (0..64).map(|k| run_seed(base, k)).collect();
            assert!(!seeds.contains(&base), "{base}: {seeds:?}");
            let mut sorted = seeds.clone();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), seeds.len(), "{base}: {seeds:?}");
        }
    }
}
