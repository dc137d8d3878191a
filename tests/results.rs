//! The equal-time benchmark end to end: `bench --curves --quick` on one scene and
//! `results --quick` on the three scenes write the CSVs, tables and plots they promise.

mod common;

use std::path::Path;
use std::process::Command;

use restir_vpl::eval::report::read_curves_csv;

/// Runs the binary, under the validation layer where it is installed (a validation error fails
/// the command: `check_validation` in src/main.rs).
fn cli(args: &[&str]) -> std::process::Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_restir-vpl"));
    c.current_dir(env!("CARGO_MANIFEST_DIR")).args(args);
    if common::validate() {
        c.env("RESTIR_VPL_VALIDATE", "1");
    }
    c.output().expect("run restir-vpl")
}

/// Runs `args --quick --out DIR` in a fresh temporary DIR, asserts success and returns DIR.
fn quick_run(args: &[&str]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = cli(&[args, &["--quick", "--out", out]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir
}

fn non_empty(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(!text.trim().is_empty(), "{} is empty", path.display());
    text
}

#[test]
fn bench_curves_quick_writes_csv_tables_and_plots() {
    let dir = quick_run(&["bench", "--curves"]);
    let points = read_curves_csv(dir.path().join("curves.csv")).unwrap();
    // 3 modes × 2 references × 3 checkpoints.
    assert_eq!(points.len(), 18, "{points:?}");
    for p in &points {
        assert!(p.rmse.is_finite() && p.rmse > 0.0 && p.relmse.is_finite(), "{p:?}");
        assert!(p.flip.is_some_and(|f| (0.0..=1.0).contains(&f)), "{p:?}");
        assert!(p.gpu_ms > 0.0 && p.wall_ms > 0.0, "{p:?}");
    }
    // Accumulating 5 uniform frames cuts the sampling error well below one frame's (about 1/√5 ≈
    // 0.45 when the reference's own noise is small, as here: its estimate is in the Markdown). The
    // bound 0.8 is far outside chance: uniform frames are independent per pixel, so an image's RMSE
    // over its thousands of pixels varies by about 1/√(2 · pixels), a few per cent, between runs;
    // only an accumulation that stopped averaging (or averaged one frame) fails it.
    let uniform = |t: u32| points.iter().find(|p| p.mode == "uniform" && p.reference == "vpl" && p.frames == t).unwrap();
    assert!(uniform(5).rmse < 0.8 * uniform(1).rmse, "{:?} vs {:?}", uniform(5), uniform(1));
    // Cumulative times grow with the frames.
    assert!(uniform(5).wall_ms > uniform(1).wall_ms);
    let md = non_empty(&dir.path().join("curves.md"));
    for needle in ["| Sampling technique | t=1 | t=2 | t=5 |", "Uniform", "RIS", "ReSTIR", "Equal time", "rays/px", "est. noise RMSE"] {
        assert!(md.contains(needle), "curves.md lacks {needle:?}:\n{md}");
    }
    non_empty(&dir.path().join("frame_times.csv"));
    // One scene's curves, nothing else: the three-scene moving-camera study (`bench --motion`,
    // ~25 minutes at full size) ran here too.
    assert!(!md.contains("Moving camera") && !dir.path().join("motion.csv").exists(), "{md}");
    for reference in ["pt", "vpl"] {
        for kind in ["frames", "time"] {
            let svg = non_empty(&dir.path().join(format!("plots/cornell_box_{reference}_rmse_vs_{kind}.svg")));
            assert!(svg.contains("<svg") && svg.contains("Uniform") && svg.contains("ReSTIR"));
        }
    }
    // One run (--quick): no standard error of the bias.
    assert!(points.iter().all(|p| p.mean_ratio_se.is_none()), "{points:?}");
    assert!(md.contains("one run: no standard error"), "{md}");
    // Both references were written and are reused by a second run (nothing re-rendered); with two
    // runs every point's bias has a standard error, shown in the bias table.
    let o = cli(&["bench", "--curves", "--quick", "--runs", "2", "--out", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("reusing"), "{}", String::from_utf8_lossy(&o.stderr));
    let points = read_curves_csv(dir.path().join("curves.csv")).unwrap();
    assert!(points.iter().all(|p| p.mean_ratio_se.is_some_and(|se| se.is_finite() && se >= 0.0)), "{points:?}");
    assert!(points.iter().any(|p| p.mean_ratio_se.is_some_and(|se| se > 0.0)), "two runs with different seeds differ: {points:?}");
    let md = non_empty(&dir.path().join("curves.md"));
    assert!(md.contains(" ± ") && md.contains("from 2 runs, 1 degree of freedom"), "{md}");
}

#[test]
fn results_quick_covers_the_three_scenes() {
    let dir = quick_run(&["results"]);
    let md = non_empty(&dir.path().join("results.md"));
    // A quick report says so, and when it was made (it read like the measurement itself): a
    // YYYY-MM-DD date before "(UTC)".
    let date = md.split(" (UTC)").next().and_then(|head| head.get(head.len().saturating_sub(10)..)).unwrap_or("");
    let dated = date.len() == 10 && date.char_indices().all(|(i, c)| if i == 4 || i == 7 { c == '-' } else { c.is_ascii_digit() });
    assert!(md.contains("**Quick run**") && dated, "{date:?}: {md}");
    for scene in ["cornell_box", "living_room", "open_box_figure"] {
        assert!(md.contains(&format!("## {scene}")), "results.md lacks {scene}");
        // The VPL model's mean ratio over other VPL sets (2 in the quick run), finite.
        let row = md.lines().find(|l| l.starts_with(&format!("| {scene} |")) && l.ends_with(" 2 sets) |")).expect(&md);
        let over_sets: f64 = row.rsplit('|').nth(1).unwrap().split_whitespace().next().unwrap().parse().expect(row);
        assert!(over_sets.is_finite() && over_sets > 0.0, "{row}");
        for reference in ["pt", "vpl"] {
            non_empty(&dir.path().join(format!("plots/{scene}_{reference}_rmse_vs_time.svg")));
        }
    }
    let points = read_curves_csv(dir.path().join("curves.csv")).unwrap();
    assert_eq!(points.len(), 3 * 18);
    // The moving-camera section: a headline per scene, the table, a plot per scene, the CSV
    // (3 scenes × 7 modes × 4 quick frames, plus the header), with the ReGIR grid's line per scene.
    assert!(md.contains("## Moving camera"), "results.md lacks the motion section:\n{md}");
    assert!(md.contains("restir-no-temporal") && md.contains("of the per-frame RMSE"), "{md}");
    assert_eq!(md.matches("the ReGIR grid (16 candidates, 8 of them from the grid").count(), 3, "{md}");
    assert!(md.contains("| ris-grid |") && md.contains("| restir-unbiased-grid |"), "{md}");
    for scene in ["cornell_box", "living_room", "open_box_figure"] {
        non_empty(&dir.path().join(format!("plots/{scene}_motion_rmse.svg")));
    }
    let csv = non_empty(&dir.path().join("motion.csv"));
    assert_eq!(csv.lines().count(), 1 + 3 * 7 * 4, "{csv}");
}

/// `bench --rays` at a tiny size: a raw primary, shadow and bounce rate for each of the three
/// scenes, and a share for every tracing pass of every mode and for the photon pass (gbuffer
/// against primary rays, photon_emit against bounce rays, pathtrace against their mix with shadow
/// rays, the rest against shadow rays), all positive and finite.
#[test]
fn bench_rays_reports_raw_rates_and_every_tracing_pass() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("rays.json");
    let o = cli(&["bench", "--rays", "--width", "24", "--height", "16", "--frames", "1", "--json", json.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows: serde_json::Value = serde_json::from_str(&non_empty(&json)).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 3, "three scenes");
    for r in rows {
        for kind in ["primary", "shadow", "bounce"] {
            let m = r[kind]["median"].as_f64().unwrap();
            assert!(m.is_finite() && m > 0.0, "{kind} rate {m} in {r}");
        }
        let passes = r["passes"].as_array().unwrap();
        let cases = [
            ("uniform", "vpl_shade", "shadow"),
            ("restir", "gbuffer", "primary"),
            ("restir --initial-visibility on", "restir_initial", "shadow"),
            ("restir --initial-visibility on", "restir_spatial", "shadow"),
            ("restir --compensate", "vpl_compensate", "shadow"),
            ("pt", "pathtrace", "bounce+shadow"),
            ("photons", "photon_emit", "bounce"),
        ];
        for (mode, pass, against) in cases {
            let p = passes.iter().find(|p| p["mode"] == mode && p["pass"] == pass).unwrap_or_else(|| panic!("{mode} {pass} missing: {r}"));
            let share = p["share"].as_f64().unwrap();
            assert!(share.is_finite() && share > 0.0, "{p}");
            assert_eq!(p["against"], against, "{p}");
            assert!(p["rays"].as_f64().unwrap() > 0.0, "{p}");
            assert_eq!(p["rays_per_pixel"].is_null(), pass == "photon_emit", "{p}");
        }
        // Without visibility in the targets the ReSTIR passes trace nothing, so they have no row.
        assert!(!passes.iter().any(|p| p["mode"] == "restir" && p["pass"] == "restir_spatial"), "{r}");
    }
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(table.contains("share of raw rate") && table.contains("vpl_compensate") && table.contains("photon_emit"), "{table}");
}

/// `bench --radius --quick --runs 2`: the table and CSV for the three scenes, every rule once per
/// scene, the radii growing with the multiple of the VPL spacing (global and per-VPL rules), every
/// figure finite, the bias with a standard error over the two runs.
#[test]
fn bench_radius_quick_writes_the_table_and_csv() {
    let dir = quick_run(&["bench", "--radius", "--runs", "2"]);
    let md = non_empty(&dir.path().join("radius.md"));
    assert!(md.contains("**Quick run**") && md.contains("(FLIP not computed)") && md.contains("(UTC) on **"), "{md}");
    let csv = non_empty(&dir.path().join("radius.csv"));
    use restir_vpl::eval::radius::{COMPENSATED_MULTIPLES, KNN_MULTIPLES, SPACING_MULTIPLES};
    let rules = SPACING_MULTIPLES.len() + 1 + COMPENSATED_MULTIPLES.len() + KNN_MULTIPLES.len();
    for scene in ["cornell_box", "living_room", "open_box_figure"] {
        assert!(md.contains(&format!("**{scene}**")), "{md}");
        let rows: Vec<Vec<&str>> = csv.lines().skip(1).filter(|l| l.starts_with(&format!("{scene},"))).map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), rules, "{csv}");
        let plain: Vec<f64> = rows.iter().filter(|r| r[1].contains("× spacing\"")).map(|r| r[2].parse().unwrap()).collect();
        assert_eq!(plain.len(), SPACING_MULTIPLES.len());
        assert!(plain.windows(2).all(|w| w[1] > w[0]), "radii grow with k: {plain:?}");
        let local: Vec<f64> = rows.iter().filter(|r| r[1].contains("local spacing")).map(|r| r[2].parse().unwrap()).collect();
        assert_eq!(local.len(), KNN_MULTIPLES.len());
        assert!(local[0] > 0.0 && local.windows(2).all(|w| w[1] > w[0]), "median per-VPL radii grow with M: {local:?}");
        for r in &rows {
            // radius, setup_s, gpu_ms, bias, bias_se, frame_variance, rmse_1, rmse_n, worst_share_n
            for i in [2, 3, 5, 6, 7, 8, 9, 10, 13] {
                let v = r[i];
                let x: f64 = v.parse().unwrap_or_else(|_| panic!("{v} in {r:?}"));
                assert!(x.is_finite(), "{r:?}");
            }
            // Two runs differ (their own VPL sets and pixel noise), so the bias has a spread.
            assert!(r[7].parse::<f64>().unwrap() > 0.0, "{r:?}");
        }
        // Each row's bias against the default rule's, run by run: the mean of the differences is
        // the difference of the means; the default row has none.
        let default = rows.iter().find(|r| r[1] == "\"8× spacing\"").expect("the default rule's row");
        assert!(default[14].is_empty() && default[15].is_empty(), "{default:?}");
        let default_bias: f64 = default[6].parse().unwrap();
        for r in rows.iter().filter(|r| r[1] != "\"8× spacing\"") {
            let (bias, paired, se): (f64, f64, f64) = (r[6].parse().unwrap(), r[14].parse().unwrap(), r[15].parse().unwrap());
            assert!((paired - (bias - default_bias)).abs() < 1e-9 && se.is_finite() && se >= 0.0, "{r:?}");
        }
        assert!(md.contains(" ± "), "the bias carries its standard error: {md}");
    }
}

/// `bench --scaling --quick`: every sweep has every mode at every size, positive finite times (the
/// builds and the photon pass: finite, not negative), and
/// the table states a measured and an expected exponent per curve.
#[test]
fn bench_scaling_quick_writes_the_table_and_csv() {
    let dir = quick_run(&["bench", "--scaling"]);
    let md = non_empty(&dir.path().join("scaling.md"));
    let csv = non_empty(&dir.path().join("scaling.csv"));
    let opts = restir_vpl::eval::scaling::ScalingOptions::quick(std::path::Path::new("."));
    for (sweep, sizes, extra) in [
        ("vpls", opts.vpl_counts.len(), &["photon_emit"][..]),
        ("pixels", opts.sizes.len(), &[][..]),
        ("triangles", opts.spheres.len(), &["photon_emit", "blas build", "tlas build"][..]),
    ] {
        let rows: Vec<Vec<&str>> = csv.lines().skip(1).filter(|l| l.starts_with(&format!("{sweep},"))).map(|l| l.split(',').collect()).collect();
        for what in ["uniform", "ris", "restir"].iter().chain(extra) {
            let of: Vec<&Vec<&str>> = rows.iter().filter(|r| r[2] == *what).collect();
            assert_eq!(of.len(), sizes, "{sweep} {what}: {csv}");
            for r in of {
                let ms: f64 = r[3].parse().unwrap();
                // A mode's frame takes time; a build or the photon pass may read 0 at a tiny size
                // (timestamps of a few µs on a coarse clock).
                let positive = ["uniform", "ris", "restir"].contains(what);
                assert!(ms.is_finite() && if positive { ms > 0.0 } else { ms >= 0.0 }, "{r:?}");
            }
        }
    }
    for title in ["**VPL count (Cornell box)**", "**Image size (Cornell box)**", "**Triangle count**"] {
        assert!(md.contains(title), "{md}");
    }
    assert!(md.contains("| exponent | expected |") && md.contains("expected 1: fixed work per pixel"), "{md}");
    // One log-log plot per sweep, linked from the Markdown, with a line per timed thing.
    for sweep in ["vpls", "pixels", "triangles"] {
        let link = format!("plots/scaling_{sweep}.svg");
        assert!(md.contains(&format!("]({link})")), "{md}");
        let svg = non_empty(&dir.path().join(&link));
        assert!(svg.starts_with("<svg") && svg.contains("RIS") && svg.contains("ReSTIR") && svg.contains("<polyline"), "{sweep}: {svg}");
    }
}

#[test]
fn bench_scaling_refuses_runs() {
    let o = cli(&["bench", "--scaling", "--runs", "2"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--runs"), "{}", String::from_utf8_lossy(&o.stderr));
}
