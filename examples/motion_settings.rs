//! ReSTIR's candidate × neighbour settings judged where ReSTIR is used: per displayed frame on a
//! moving camera (`bench --motion`'s protocol, its scenes, paths and cached references), at equal
//! time (relMSE × GPU ms per frame).
//!
//! `cargo run --release --example motion_settings -- [VARIANTS] [RUNS] [OUT]`
//! VARIANTS: comma-separated `candidates/neighbours` of unbiased ReSTIR on every frame, or
//! `candidates/neighbours>moving candidates/moving neighbours` for the frames displayed alone with
//! temporal history (`--moving-candidates`, `--moving-neighbours`; default
//! `32/8,32/8>16/4,32/8>32/4,32/8>8/4`); uniform and RIS (32 candidates) run beside them as
//! yardsticks. The first variant is the one the others are paired against.
//! RUNS: independent runs (default 4). OUT: where the references are cached (default bench-out,
//! `bench --motion`'s). Last, each run's mean RMSE per variant, to pair two builds run by run.

use std::sync::Arc;

use restir_vpl::eval::motion::{mean_ms, motion_modes, paired_ratio, run_means, run_modes, table_markdown, MotionMode, MotionOptions};
use restir_vpl::settings::{Bias, Mode, RestirSettings};
use restir_vpl::vk::Context;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
    let variants = arg(1, "32/8,32/8>16/4,32/8>32/4,32/8>8/4");
    let runs: u32 = arg(2, "4").parse()?;
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let opts = MotionOptions { runs, out_dir: root.join(arg(3, "bench-out")), flip: false, ..MotionOptions::full(&root, 0.2) };
    let yardsticks = ["uniform", "ris"];
    let mut modes: Vec<MotionMode> = motion_modes().into_iter().filter(|m| yardsticks.contains(&m.label)).collect();
    let pair = |t: &str| -> anyhow::Result<(u32, u32)> {
        let (c, n) = t.split_once('/').ok_or_else(|| anyhow::anyhow!("variant {t}: expected candidates/neighbours"))?;
        Ok((c.parse()?, n.parse()?))
    };
    for v in variants.split(',') {
        let (still, moving) = v.split_once('>').unwrap_or((v, "0/0"));
        let ((candidates, neighbours), (moving_candidates, moving_neighbours)) = (pair(still)?, pair(moving)?);
        let restir = RestirSettings {
            bias: Bias::Unbiased,
            initial_visibility: Some(false),
            spatial_neighbours: neighbours,
            moving_candidates,
            moving_neighbours,
            ..Default::default()
        };
        // Labels live as long as the process.
        let label: &'static str = Box::leak(format!("restir {v}").into_boxed_str());
        modes.push(MotionMode { label, mode: Mode::Restir, restir, candidates: Some(candidates), grid_candidates: 0 });
    }
    let ctx = Arc::new(Context::new(&Default::default())?);
    let points = run_modes(&ctx, &opts, &modes, &mut |line| eprintln!("{line}"))?;
    println!("{}", table_markdown(&points));
    // Each variant against the first, run by run (the runs share their seeds): RMSE and GPU time.
    let first = modes.iter().find(|m| m.mode == Mode::Restir).map(|m| m.label).expect("a ReSTIR variant");
    println!("| scene | variant | RMSE / {first}'s | GPU ms / {first}'s |\n|---|---|---:|---:|");
    for scene in restir_vpl::eval::report::ordered(points.iter().map(|p| p.scene.as_str())) {
        for m in modes.iter().filter(|m| m.mode == Mode::Restir && m.label != first) {
            if let (Some((r, se)), Some(ms), Some(ms_first)) =
                (paired_ratio(&points, scene, m.label, first), mean_ms(&points, scene, m.label), mean_ms(&points, scene, first))
            {
                println!("| {scene} | {} | {r:.3} ± {:.3} | {:.3} |", m.label, se.unwrap_or(f64::NAN), ms / ms_first);
            }
        }
    }
    // Each run's mean RMSE (less the references' noise) of every ReSTIR variant, so that another
    // build's output, whose runs share these seeds, can be paired with it run by run.
    println!("\n| scene | variant | RMSE of each run |\n|---|---|---|");
    for scene in restir_vpl::eval::report::ordered(points.iter().map(|p| p.scene.as_str())) {
        for m in modes.iter().filter(|m| m.mode == Mode::Restir) {
            let runs: Vec<String> = run_means(&points, scene, m.label).iter().map(|r| format!("{r:.5}")).collect();
            println!("| {scene} | {} | {} |", m.label, runs.join(" "));
        }
    }
    Ok(())
}
