//! The command line: a full headless run, and bad input that must give a clear message, a non-zero
//! exit and no panic.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::*;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_restir-vpl"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    if validate() {
        c.env("RESTIR_VPL_VALIDATE", "1");
    }
    c
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("binary runs")
}

/// Whether /dev/full exists (the full-disk and full-stdout cases write to it): a part skipped
/// without it says so, and fails under CI, whose machine has it.
fn dev_full() -> bool {
    Path::new("/dev/full").exists() || {
        assert!(std::env::var("CI").map_or(true, |v| v != "true"), "no /dev/full: the full-disk cases cannot run");
        common::skip("no /dev/full: the full-disk and full-stdout cases did not run");
        false
    }
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Fails with a message containing every word of `expect`, without panicking.
fn assert_fails(args: &[&str], expect: &[&str]) {
    let o = run(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} should fail; stderr: {err}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    // Refused cleanly: under the validation layer (where installed) nothing is left undestroyed
    // (a refusal after the frame fences were made left two: VUID-vkDestroyDevice-device-00378).
    assert!(!err.contains("VALIDATION"), "{args:?}: validation errors on the way out: {err}");
    for e in expect {
        assert!(err.contains(e), "{args:?}: stderr should mention '{e}': {err}");
    }
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// An empty path names no file: refused for every path flag, naming it (`--out ''` wrote the
/// outputs into the working directory without a word).
#[test]
fn an_empty_path_is_refused_naming_the_flag() {
    for args in [&["--headless", "--out", ""][..], &["--headless", "--scene", ""], &["--headless", "--camera-path", ""], &["reference", "--out", ""], &["compare", "", "b.exr"]] {
        let o = run(args);
        let err = stderr(&o);
        assert!(o.status.code() == Some(2) && err.contains("an empty path") && !err.contains("panicked"), "{args:?}: {:?} {err}", o.status.code());
    }
}

#[test]
fn headless_cornell_box_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().display().to_string();
    let o = run(&[
        "--headless", "--scene", "scenes/cornell_box.gltf", "--mode", "pt", "--frames", "3", "--width", "64",
        "--height", "48", "--out", &out, "--save-every", "1",
    ]);
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("final.exr") && stdout.contains("pathtrace"), "{stdout}");
    // The Cornell box's one light is a quad: two emissive triangles, named as such.
    assert!(stdout.contains("(32 triangles; lights: 2 emissive triangles)"), "{stdout}");
    for f in ["final.exr", "final.png", "accum_0001.exr", "accum_0003.exr", "summary.json"] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    let img = restir_vpl::output::read_exr(&dir.path().join("final.exr")).unwrap();
    assert_eq!((img.width, img.height), (64, 48));
    assert_all_finite(&img.pixels, "final.exr");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    common::assert_clean_summary(&s, "headless run");
    assert_eq!(s["settings"]["width"], 64);
}

#[test]
fn missing_scene_file() {
    assert_fails(&["--headless", "--scene", "/nonexistent/scene.gltf", "--frames", "1"], &["/nonexistent/scene.gltf"]);
}

/// A device or a directory as the scene is refused at once: /dev/zero was read until the
/// out-of-memory killer ended the process, with no message.
/// An output that cannot be written fails before the frames are rendered, naming --out.
#[test]
fn unwritable_outputs_fail_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("final.exr")).unwrap();
    let out = dir.path().display().to_string();
    let args = ["--headless", "--width", "8", "--height", "8", "--frames", "2", "--out", &out];
    assert_fails(&args, &["--out", "final.exr", "is a directory"]);
    assert!(!dir.path().join("final.png").exists(), "nothing was written");
    let file = dir.path().join("plain_file");
    std::fs::write(&file, b"x").unwrap();
    let file = file.display().to_string();
    assert_fails(&["--headless", "--width", "8", "--height", "8", "--frames", "1", "--out", &file], &["--out", "is a file"]);
    assert_fails(&["--headless", "--width", "8", "--height", "8", "--frames", "1", "--out", "/dev/null"], &["--out /dev/null", "exists and is not a directory"]);
}

/// An output name that is a link to an input is refused: out/final.png → the scene had the scene
/// overwritten with a PNG (the check looked only at names the input itself had).
#[cfg(unix)]
#[test]
fn an_output_linked_to_the_scene_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("box.gltf");
    std::fs::copy(repo_path("scenes/cornell_box.gltf"), &scene).unwrap();
    let before = std::fs::read(&scene).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::os::unix::fs::symlink("../box.gltf", out.join("final.png")).unwrap();
    let args = ["--headless", "--scene", scene.to_str().unwrap(), "--width", "8", "--height", "8", "--frames", "1", "--out", out.to_str().unwrap()];
    assert_fails(&args, &["--out", "writes final.png there, which is the scene"]);
    assert_eq!(std::fs::read(&scene).unwrap(), before, "the scene is untouched");
}

/// A run with --save-every replaces an earlier run's snapshots (a longer run's accum_0003 stayed
/// beside a shorter one's), and a directory where a snapshot goes is refused before the frames.
#[test]
fn save_every_replaces_an_earlier_runs_snapshots() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().display().to_string();
    let args = |frames: &'static str| {
        ["--headless", "--mode", "pt", "--width", "8", "--height", "8", "--save-every", "1", "--frames", frames, "--out", &out].map(String::from)
    };
    let o = run(&args("3").iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("accum_0003.exr").is_file());
    // Only files named as the program names them and holding an EXR go: a user's text file under
    // a snapshot's name stays, as do names the program never writes.
    std::fs::write(dir.path().join("accum_0007.exr"), b"not ours").unwrap();
    std::fs::copy(dir.path().join("accum_0003.exr"), dir.path().join("accum_00001.exr")).unwrap();
    std::fs::write(dir.path().join("accum_.exr"), b"not a snapshot name").unwrap();
    let o = run(&args("2").iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("removed 3 --save-every snapshot(s)"), "{}", stderr(&o));
    assert!(std::fs::read_to_string(dir.path().join("summary.json")).unwrap().contains("removed 3 --save-every snapshot(s)"));
    // A run without --save-every (or --dump-passes) leaves an earlier run's snapshots (and pass
    // dumps) there, and says so, also in its summary.
    std::fs::create_dir(dir.path().join("passes")).unwrap();
    std::fs::write(dir.path().join("passes/index.html"), b"<html>").unwrap();
    let plain = ["--headless", "--mode", "pt", "--width", "8", "--height", "8", "--frames", "1", "--out", &out];
    let o = run(&plain);
    assert!(o.status.success(), "{}", stderr(&o));
    for said in ["2 snapshot(s) accum_NNNN.exr of an earlier run are left there", "passes/ holds an earlier run's pass dumps"] {
        assert!(stderr(&o).contains(said), "{said}: {}", stderr(&o));
        assert!(std::fs::read_to_string(dir.path().join("summary.json")).unwrap().contains(said), "{said}");
    }
    std::fs::remove_dir_all(dir.path().join("passes")).unwrap();
    let mut names: Vec<String> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names, ["accum_.exr", "accum_00001.exr", "accum_0001.exr", "accum_0002.exr", "accum_0007.exr", "final.exr", "final.png", "summary.json"]);
    // A run that fails in its set-up (a bad camera path) removes nothing.
    let bad_path = dir.path().join("bad.path.json");
    std::fs::write(&bad_path, b"{ not json").unwrap();
    let o = run(&[args("2").iter().map(String::as_str).collect::<Vec<_>>(), vec!["--camera-path", bad_path.to_str().unwrap()]].concat());
    assert!(!o.status.success() && dir.path().join("accum_0002.exr").is_file(), "{}", stderr(&o));
    std::fs::remove_file(&bad_path).unwrap();
    std::fs::remove_file(dir.path().join("accum_0002.exr")).unwrap();
    std::fs::create_dir(dir.path().join("accum_0002.exr")).unwrap();
    let o = run(&args("2").iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!o.status.success() && stderr(&o).contains("accum_0002.exr is a directory"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("frames"), "refused before the frames: {}", stderr(&o));
}

#[test]
fn scene_that_is_not_a_file() {
    assert_fails(&["--headless", "--scene", "/dev/zero", "--frames", "1"], &["/dev/zero", "not a regular file"]);
    assert_fails(&["--headless", "--scene", "/tmp", "--frames", "1"], &["/tmp", "directory"]);
    assert_fails(&["--headless", "--camera-path", "/dev/zero", "--frames", "1"], &["--camera-path", "/dev/zero", "not a regular file"]);
    assert_fails(&["--headless", "--camera-path", "/nonexistent/path.json", "--frames", "1"], &["--camera-path", "/nonexistent/path.json"]);
}

#[test]
fn malformed_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "bad.gltf", "{ this is not json");
    assert_fails(&["--headless", "--scene", &p, "--frames", "1"], &["bad.gltf"]);
}

const LINES_GLTF: &str = r#"{"asset":{"version":"2.0"},
 "buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
 "bufferViews":[{"buffer":0,"byteLength":36}],
 "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],
 "meshes":[{"name":"wire","primitives":[{"attributes":{"POSITION":0},"mode":1}]}],
 "nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0}"#;

#[test]
fn non_triangle_primitive() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "lines.gltf", LINES_GLTF);
    // Lines are skipped with a warning; with nothing else in the file, no triangles are left.
    assert_fails(&["--headless", "--scene", &p, "--frames", "1"], &["lines.gltf", "no triangles in scene", "mesh 'wire' primitive 0: mode Lines", "skipped"]);
}

#[test]
fn scene_without_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "empty.gltf", r#"{"asset":{"version":"2.0"},"nodes":[{}],"scenes":[{"nodes":[0]}]}"#);
    assert_fails(&["--headless", "--scene", &p, "--frames", "1"], &["empty.gltf", "no triangles"]);
}

#[test]
fn bad_flags() {
    assert_fails(&["--headless", "--frames", "0"], &["--frames"]);
    assert_fails(&["--headless", "--width", "0"], &["--width"]);
    assert_fails(&["--headless", "--height", "0"], &["--height"]);
    assert_fails(&["--headless", "--mode", "nonsense"], &["--mode", "nonsense"]);
    assert_fails(&["--headless", "--eye", "1,2"], &["--eye"]);
    assert_fails(&["--headless", "--eye", "0,0,1"], &["--target"]);
    assert_fails(&["--headless", "--max-bounces", "-5"], &["--max-bounces"]);
    // Flags that would be silently ignored are errors, as --fov without --eye is.
    assert_fails(&["--headless", "--up", "0,0,1"], &["--up", "--eye"]);
    // A view vector whose square overflows is named as such, not as "--up parallel".
    assert_fails(&["--headless", "--eye", "1e30,0,0", "--target", "0,0,0"], &["--eye", "distance"]);
    // As a camera path's keyframes: within 1e18 of the origin (3e38 rendered black), and a field
    // of view whose tangent the motion vectors can divide by (1e-45 made NaN samples).
    assert_fails(&["--headless", "--eye", "2e18,0,0", "--target", "1.9e18,0,0"], &["--eye", "1e18 of the origin"]);
    assert_fails(&["--headless", "--eye", "0,0,1", "--target", "0,0,0", "--fov", "1e-45"], &["--fov 1e-45", "[0.01, 180)"]);
    assert_fails(&["--headless", "--mode", "restir", "--photon-max-bounces", "4294967295"], &["--photon-max-bounces 4294967295"]);
    assert_fails(&["--headless", "--frames", "1", "--out", "/tmp", "--dump-passes", "5"], &["--dump-passes 5", "--frames 1"]);
    // A selection partly in range names the frame that is not (it said "nothing would be dumped").
    assert_fails(&["--headless", "--frames", "3", "--out", "/tmp", "--dump-passes", "0,5"], &["--dump-passes 0,5: frame 5 is beyond", "--frames 3"]);
    assert_fails(&["--headless", "--frames", "0", "--out", "/tmp", "--dump-passes", "0"], &["--frames 0"]);
    // A negative value for an unsigned flag names the flag and the value (clap took "-5" for an
    // unknown flag before allow_negative_numbers), in subcommands too.
    assert_fails(&["--headless", "--width", "-5"], &["--width", "'-5'"]);
    // Values starting with a minus sign that are not plain numbers reach their flag's own parser
    // (they were "unexpected argument '-1' found", naming no flag).
    assert_fails(&["--headless", "--eye", "-1,0", "--target", "0,0,0"], &["--eye", "-1,0"]);
    assert_fails(&["--headless", "--exposure", "-inf"], &["--exposure", "finite"]);
    // A finite value beyond f32 is refused as typed (it became inf, and the message quoted "inf").
    assert_fails(&["--headless", "--mcap", "1e39"], &["--mcap", "1e39 is beyond 32-bit floats"]);
    assert_fails(&["compare", "a.exr", "b.exr", "--ppd", "-1e40"], &["--ppd", "-1e40 is beyond 32-bit floats"]);
    assert_fails(&["--headless", "--workgroup", "-8x8"], &["--workgroup", "-8"]);
    assert_fails(&["--headless", "--eye", "--target", "0,0,0"], &["--eye"]);
    // --dump-vpls over the scene or over a file the run writes to --out.
    let dump_out = std::env::temp_dir().join("restir-vpl-cli-dump-vpls");
    let final_exr = dump_out.join("final.exr").display().to_string();
    let dump_dir = dump_out.display().to_string();
    assert_fails(&["--headless", "--dump-vpls", "scenes/cornell_box.gltf"], &["--dump-vpls", "is also the scene"]);
    // A directory is refused before the photon pass (it was "Is a directory (os error 21)" after it).
    assert_fails(&["--headless", "--dump-vpls", "scenes"], &["--dump-vpls scenes: is a directory"]);
    // A window-only flag in a headless run is refused (it was ignored).
    assert_fails(&["--headless", "--present-mode", "mailbox"], &["--present-mode", "no window"]);
    // ... and a headless-only flag in the window (a --check-finite window checked nothing), before
    // any window opens (so with no display too).
    assert_fails(&["--frames", "1", "--check-finite", "--save-every", "1"], &["--save-every, --check-finite: done by --headless runs only", "Enter (write final.exr", "F4"]);
    assert_fails(&["--headless", "--out", &dump_dir, "--dump-vpls", &final_exr], &["--dump-vpls", "is also an output of --out"]);
    // ... and over a --save-every snapshot or --dump-passes' copy of the VPLs (the PLY was written,
    // then replaced by the snapshot, and the run said nothing).
    let snapshot = dump_out.join("accum_0002.exr").display().to_string();
    assert_fails(&["--headless", "--out", &dump_dir, "--frames", "4", "--save-every", "2", "--dump-vpls", &snapshot], &["--dump-vpls", "a --save-every output"]);
    let passes_ply = dump_out.join("passes").join("vpls.ply").display().to_string();
    assert_fails(&["--headless", "--out", &dump_dir, "--dump-passes", "last", "--dump-vpls", &passes_ply], &["--dump-vpls", "inside --dump-passes' folder"]);
    // A failed write names the flag and the file (a full disk said only "No space left on device").
    if dev_full() {
        let small = ["--headless", "--mode", "ris", "--width", "8", "--height", "8", "--frames", "1", "--vpls-direct", "500", "--vpls-indirect", "500"];
        assert_fails(&[&small[..], &["--out", &dump_dir, "--dump-vpls", "/dev/full"]].concat(), &["--dump-vpls: writing /dev/full"]);
    }
    assert_fails(&["bench", "--frames", "-1"], &["--frames", "'-1'"]);
    // Sizes and counts are refused before anything is measured (--rays ran its raw dispatches at a
    // width of 0; u32::MAX frames plus the warm-up wrapped to "--frames 0").
    assert_fails(&["bench", "--rays", "--width", "0"], &["--width 0"]);
    assert_fails(&["bench", "--rays", "--width", "4096", "--height", "8193", "--frames", "1"], &["--width 4096 --height 8193", "buffer limits"]);
    assert_fails(&["bench", "--frames", "4294967295", "--width", "8", "--height", "8"], &["--frames 4294967295", "at most"]);
    // Counts of `results` and `bench --curves` are checked before any reference renders, under
    // their own names; the "Instead" benches exclude each other.
    let out = std::env::temp_dir().join("restir-vpl-cli-bad-flags").display().to_string();
    assert_fails(&["results", "--quick", "--out", &out, "--pt-frames", "0"], &["--pt-frames 0"]);
    assert_fails(&["results", "--quick", "--out", &out, "--vpl-frames", "0"], &["--vpl-frames 0"]);
    assert_fails(&["results", "--quick", "--out", &out, "--checkpoints", "0"], &["--checkpoints"]);
    // Flags that would do nothing are refused: --quick sets its own sizes; --no-flip skips the
    // metric --ppd and --exposure set.
    assert_fails(&["results", "--quick", "--out", &out, "--scale", "4"], &["--quick", "--scale"]);
    assert_fails(&["compare", "a.exr", "b.exr", "--no-flip", "--ppd", "5"], &["--no-flip", "--ppd"]);
    assert_fails(&["compare", "a.exr", "b.exr", "--no-flip", "--exposure", "3"], &["--no-flip", "--exposure"]);
    assert_fails(&["bench", "--curves", "--quick", "--out", &out, "--checkpoints", "5,0"], &["--checkpoints"]);
    assert_fails(&["bench", "--photons", "--modes"], &["--photons", "--modes"]);
    // An unwritable reference path fails before the frames (it failed after rendering them all).
    // (No frame progress is printed: none was rendered.)
    let args = ["reference", "--width", "8", "--height", "8", "--frames", "3", "--out", "/proc/restir-vpl-test.exr"];
    assert_fails(&args, &["/proc/restir-vpl-test.exr"]);
    let err = stderr(&run(&args));
    assert!(!err.contains("/3 frames"), "the path was checked only after rendering: {err}");
    // An output named for another image format than the one written (an EXR named a.png).
    assert_fails(&["reference", "--width", "8", "--height", "8", "--frames", "3", "--out", "/tmp/restir-vpl-ref.png"], &["--out /tmp/restir-vpl-ref.png: writes an OpenEXR image", "*.exr"]);
    assert_fails(&["compare", "a.exr", "b.exr", "--error-image", "/tmp/restir-vpl-err.EXR"], &["--error-image /tmp/restir-vpl-err.EXR: writes a PNG image", "*.png"]);
    assert_fails(&["merge-references", "a.exr", "b.exr", "--out", "/tmp/restir-vpl-merged.png"], &["--out /tmp/restir-vpl-merged.png: writes an OpenEXR image"]);
    // A path ending in a separator names a directory: refused before the frames (the probe beside
    // "d" passed and the rename failed after them).
    let slash = std::env::temp_dir().join("restir-vpl-cli-slash").display().to_string() + "/";
    let args = ["reference", "--width", "8", "--height", "8", "--frames", "3", "--out", &slash];
    assert_fails(&args, &["--out", "names a directory"]);
    assert!(!stderr(&run(&args)).contains("/3 frames"), "the path was checked only after rendering");
    assert_fails(&["bench", "--curves", "--photons"], &["--curves", "--photons"]);
    // A flag the chosen benchmark does not read is refused, naming it (it was ignored).
    assert_fails(&["bench", "--rays", "--scene", "/nonexistent.gltf"], &["bench --rays does not use --scene"]);
    assert_fails(&["bench", "--curves", "--quick", "--frames", "0", "--json", "x.json"], &["bench --curves does not use --frames, --json"]);
    assert_fails(&["bench", "--photons", "--width", "64"], &["bench --photons does not use --width"]);
    assert_fails(&["bench", "--motion", "--scene", "scenes/cornell_box.gltf"], &["bench --motion does not use --scene"]);
    assert_fails(&["--headless", "--device", "99", "--frames", "1", "--width", "8", "--height", "8"], &["--device 99"]);
}

/// A flag the mode never reads is named in a warning (the table in `RenderSettings::unused_flags`
/// uses clap's ids: a renamed flag would drop out of it silently, which this catches).
#[test]
fn flags_the_mode_never_reads_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = run(&[
        "--headless", "--mode", "pt", "--frames", "1", "--width", "16", "--height", "16", "--candidates", "8",
        "--spatial-neighbours", "4", "--photon-max-bounces", "3", "--attenuation", "yuksel", "--max-bounces", "2",
        "--out", &out.display().to_string(),
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    for f in ["--candidates", "--spatial-neighbours", "--photon-max-bounces", "--attenuation"] {
        assert!(err.contains(&format!("{f} has no effect here")), "{f}: {err}");
    }
    assert!(!err.contains("--max-bounces has no effect"), "pt reads --max-bounces: {err}");
    // Kept in summary.json's warnings too (they reached stderr only).
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let kept: Vec<&str> = summary["warnings"].as_array().unwrap().iter().filter_map(|w| w.as_str()).collect();
    assert!(kept.iter().any(|w| w.starts_with("--candidates has no effect here")), "{kept:?}");
    let o = run(&[
        "--headless", "--mode", "restir", "--frames", "1", "--width", "16", "--height", "16", "--vpls-direct", "500",
        "--vpls-indirect", "500", "--spatial-neighbours", "4", "--max-bounces", "2", "--out", &out.display().to_string(),
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("--max-bounces has no effect here") && !err.contains("--spatial-neighbours has no effect"), "{err}");
}

/// A stderr that cannot be written (full: /dev/full) loses the messages, not the run: a warning
/// panicked there (exit 101) and an error's message turned its status 1 into 101.
#[cfg(unix)]
#[test]
fn a_full_stderr_changes_no_exit_status() {
    let dir = tempfile::tempdir().unwrap();
    let full = || std::fs::OpenOptions::new().write(true).open("/dev/full").expect("/dev/full");
    let out = dir.path().join("out");
    // --candidates in --mode pt: a warning.
    let o = bin()
        .args(["--headless", "--mode", "pt", "--candidates", "4", "--frames", "1", "--width", "8", "--height", "8", "--out"])
        .arg(&out)
        .stderr(full())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "a warning into a full stderr");
    assert!(out.join("final.exr").exists());
    let o = bin().args(["--headless", "--scene", "no/such/scene.gltf"]).stderr(full()).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "an error into a full stderr");
}

/// A `--vpl-radius` that is large against the scene warns that some spheres are not drawn (or are
/// cut to a square); the default radius (0.25 % of the diagonal) does not.
#[test]
fn a_vpl_radius_beyond_the_scene_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let view = |extra: &[&str]| {
        let mut args = vec![
            "--headless", "--view", "vpls", "--frames", "1", "--width", "16", "--height", "16", "--vpls-direct", "200",
            "--vpls-indirect", "200",
        ];
        args.extend_from_slice(extra);
        let o = run(&[&args[..], &["--out", &out.display().to_string()]].concat());
        let err = stderr(&o);
        assert!(o.status.success(), "{extra:?}: {err}");
        err
    };
    let err = view(&["--vpl-radius", "100"]);
    assert!(err.contains("--vpl-radius 100 is") && err.contains("spheres that hold the camera are not drawn"), "{err}");
    assert_eq!(err.matches("--vpl-radius 100 is").count(), 1, "said once: {err}");
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("--vpl-radius 100 is"), "kept in the summary: {summary}");
    let err = view(&[]);
    assert!(!err.contains("--vpl-radius"), "default radius: {err}");
}

/// A 2 × 2 grey floor facing up at y = 0 and a 0.4 × 0.4 lamp at y = 1 facing down on it, or up
/// into empty space (faces counter-clockwise seen from the side they face).
fn floor_and_lamp(lamp_faces_up: bool) -> restir_vpl::scene::generate::GltfBuilder {
    let mut b = restir_vpl::scene::generate::GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    let lamp = b.material("lamp", [0.5; 3], [5.0; 3], false);
    let floor = b.quad("floor", [[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]], grey);
    let mut corners = [[-0.2, 1.0, -0.2], [0.2, 1.0, -0.2], [0.2, 1.0, 0.2], [-0.2, 1.0, 0.2]];
    if lamp_faces_up {
        corners.reverse();
    }
    let panel = b.quad("panel", corners, lamp);
    b.node("floor", floor, [0.0; 3]);
    b.node("panel", panel, [0.0; 3]);
    b
}

/// A scene camera whose yfov is no field of view is refused by a run that would look through it,
/// naming the file; --eye/--target replace it and the run renders (an error at load stopped that
/// run too; before that, the camera was dropped with a warning and the automatic one saw black).
#[test]
fn a_scene_camera_with_a_bad_yfov_stops_only_the_runs_that_use_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = floor_and_lamp(false);
    b.camera("cam", [0.0, 0.5, 2.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.0);
    let p = write(dir.path(), "narrow.gltf", &b.to_json_string());
    let out = dir.path().join("out").display().to_string();
    let small = ["--headless", "--mode", "pt", "--frames", "1", "--width", "8", "--height", "8", "--scene", &p, "--out", &out];
    assert_fails(&small, &["narrow.gltf: its camera's yfov 0 rad", "--eye/--target"]);
    let o = run(&[&small[..], &["--eye", "0,0.5,2", "--target", "0,0,0"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn scene_without_emitters_renders_black_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = restir_vpl::scene::generate::GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    let m = b.quad("floor", [[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]], grey);
    b.node("floor", m, [0.0; 3]);
    b.camera("cam", [0.0, 1.0, 2.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 1.0);
    let p = write(dir.path(), "dark.gltf", &b.to_json_string());
    let out = dir.path().join("out");
    let o = run(&[
        "--headless", "--scene", &p, "--frames", "2", "--width", "16", "--height", "16", "--out",
        &out.display().to_string(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let all = format!("{}{}", stderr(&o), String::from_utf8_lossy(&o.stdout));
    assert!(all.contains("no emitters"), "warning expected: {all}");
    let img = restir_vpl::output::read_exr(&out.join("final.exr")).unwrap();
    assert!(img.pixels.iter().all(|p| *p == [0.0; 3]), "black image expected");
}

#[test]
fn list_devices_reports_each_device() {
    let o = run(&["--list-devices"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("[0]"), "{s}");
    assert!(run(&["--list-devices", "--verbose", "--trace", "auto"]).status.success());
    // It lists and exits: other flags and commands are refused, not silently ignored.
    assert_fails(&["--list-devices", "--width", "0", "--scene", "/nope.gltf"], &["--list-devices", "--width", "--scene"]);
    assert_fails(&["--list-devices", "--headless"], &["--list-devices", "--headless"]);
    assert_fails(&["--list-devices", "bench", "--rays"], &["--list-devices", "bench"]);
}

/// How rays are traced: `--trace` and `RESTIR_VPL_TRACE` pick it, `--list-devices` says it, a bad
/// value is refused by name.
#[test]
fn trace_choice_is_listed_and_checked() {
    // Lavapipe has both ways and auto takes ray queries; NVIDIA's datacenter GPUs (H100, H200)
    // have ray-tracing pipelines only, so there auto takes those and `--trace query` lists the
    // device as lacking VK_KHR_ray_query (this test failed there at stop 51, expecting lavapipe).
    let o = bin().args(["--list-devices", "--trace", "query"]).output().expect("binary runs");
    let listed = String::from_utf8_lossy(&o.stdout).to_string();
    let queries = listed.contains("ok (ray queries)");
    assert!(queries || (listed.contains("lacks VK_KHR_ray_query") && !listed.contains("llvmpipe")), "lavapipe must offer ray queries: {listed} {}", stderr(&o));
    let (auto, query) = if queries { ("(ray queries)", "(ray queries)") } else { ("(ray-tracing pipelines)", "lacks VK_KHR_ray_query") };
    for (args, env, expect) in [
        (&["--list-devices"][..], None, auto),
        (&["--list-devices", "--trace", "pipeline"][..], None, "(ray-tracing pipelines)"),
        (&["--list-devices"][..], Some("pipeline"), "(ray-tracing pipelines)"),
        (&["--list-devices", "--trace", "query"][..], Some("pipeline"), query),
        // auto given overrides the variable too
        (&["--list-devices", "--trace", "auto"][..], Some("pipeline"), auto),
    ] {
        let mut c = bin();
        c.args(args);
        if let Some(v) = env {
            c.env("RESTIR_VPL_TRACE", v);
        }
        let o = c.output().expect("binary runs");
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success() && out.contains(expect), "{args:?} RESTIR_VPL_TRACE={env:?}: {out} {}", stderr(&o));
    }
    assert_fails(&["--headless", "--trace", "rays", "--frames", "1"], &["--trace", "rays"]);
    let o = bin().args(["--list-devices"]).env("RESTIR_VPL_TRACE", "fast").output().expect("binary runs");
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("RESTIR_VPL_TRACE=\"fast\"") && !err.contains("panicked"), "{err}");
    // bench --workgroups compares the workgroup shapes of passes that, with pipelines, are
    // ray-generation shaders without workgroups: refused before any timing.
    let o = bin().args(["bench", "--workgroups", "--width", "16", "--height", "16", "--frames", "1"]).env("RESTIR_VPL_TRACE", "pipeline").output().expect("binary runs");
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("bench --workgroups") && err.contains("ray-tracing pipelines") && !err.contains("panicked"), "{err}");
}

/// `bench --modes --grid`: RIS and unbiased ReSTIR at 32, 16 and 16 with 8 from the ReGIR grid,
/// each row timed, the grid rows with their `regir_build` pass; and it does not combine with
/// `--fusion`.
#[test]
fn bench_modes_grid_times_the_grid_rows() {
    let o = run(&["bench", "--modes", "--grid", "--width", "24", "--height", "16", "--frames", "1"]);
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(o.status.success(), "{}", stderr(&o));
    let rows: Vec<&str> = out.lines().filter(|l| l.starts_with("| 24×16")).collect();
    assert_eq!(rows.len(), 7, "{out}");
    let grid_rows: Vec<&&str> = rows.iter().filter(|l| l.contains("(8 from the grid)")).collect();
    assert_eq!(grid_rows.len(), 2, "{out}");
    assert!(grid_rows.iter().all(|l| l.contains("regir_build")), "{out}");
    assert!(rows.iter().filter(|l| !l.contains("from the grid")).all(|l| !l.contains("regir_build")), "{out}");
    assert_fails(&["bench", "--modes", "--grid", "--fusion"], &["--grid", "--fusion"]);
}

/// `bench --modes --out DIR`: DIR/modes.md, both cameras of the usual cases in one run, with how
/// it was made and the ratios to uniform up front; it writes one report, so the single-table
/// variants are refused with it.
#[test]
fn bench_modes_out_writes_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let json = dir.path().join("modes.json");
    let o = run(&["bench", "--modes", "--out", out, "--json", json.to_str().unwrap(), "--scene", "scenes/cornell_box.gltf", "--width", "24", "--height", "16", "--frames", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let md = std::fs::read_to_string(dir.path().join("modes.md")).unwrap();
    for needle in ["Generated by `restir-vpl bench --modes --out", "Device: ", "Host: ", "| cornell_box | 24×16 | still |", "| cornell_box | 24×16 | moving |", "## scenes/cornell_box.gltf (32 triangles)"] {
        assert!(md.contains(needle), "modes.md lacks {needle:?}:\n{md}");
    }
    // Five modes on each camera, each row timed (from the JSON: the table's milliseconds are
    // rounded, and a fast GPU's frame at this size can round to 0).
    let rows: Vec<&str> = md.lines().filter(|l| l.starts_with("| 24×16 |")).collect();
    assert_eq!(rows.len(), 10, "{md}");
    let timed: Vec<serde_json::Value> = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(timed.len(), 10);
    assert!(timed.iter().all(|r| r["gpu_ms_per_frame"].as_f64().is_some_and(|ms| ms > 0.0)), "{timed:?}");
    assert_fails(&["bench", "--modes", "--moving", "--out", out], &["--out", "--moving"]);
}

#[test]
fn vpl_count_errors() {
    assert_fails(&["--headless", "--vpls-direct", "0", "--frames", "1"], &["--vpls-direct 0"]);
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("v.ply").display().to_string();
    // 4e9 VPLs of 48 bytes: rejected before any allocation.
    assert_fails(
        &["--headless", "--vpls-direct", "4000000000", "--frames", "1", "--width", "8", "--height", "8", "--dump-vpls", &ply],
        &["--vpls-direct 4000000000", "GiB"],
    );
}

/// `--no-gi --vpls-direct 0` is an empty VPL set, which the error for `--vpls-direct 0` offers: every
/// VPL mode renders it (the visible emitters only) instead of panicking when the VPLs are read back.
#[test]
fn empty_vpl_set_renders_in_every_vpl_mode() {
    let dir = tempfile::tempdir().unwrap();
    let mut means = Vec::new();
    for mode in ["uniform", "ris", "restir", "bruteforce"] {
        let out = dir.path().join(mode);
        let o = run(&[
            "--headless", "--mode", mode, "--vpls-direct", "0", "--no-gi", "--frames", "2", "--width", "16", "--height", "16",
            "--out", &out.display().to_string(),
        ]);
        assert!(o.status.success() && !stderr(&o).contains("panicked"), "{mode}: {}", stderr(&o));
        let img = restir_vpl::output::read_exr(&out.join("final.exr")).unwrap();
        assert_all_finite(&img.pixels, mode);
        means.push(img.pixels.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum::<f64>());
    }
    // No VPL lights anything, so every mode shows the same thing: the emitters seen directly.
    assert!(means.iter().all(|m| *m == means[0]) && means[0] > 0.0, "{means:?}");
}

/// A repeated flag overrides the earlier one (the render script appends the user's arguments).
/// A camera given with negative coordinates as separate arguments (`--eye -1,0.5,2`) is taken.
#[test]
fn negative_vectors_are_accepted_as_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().display().to_string();
    let args = ["--headless", "--width", "8", "--height", "8", "--frames", "1", "--mode", "pt", "--out", &out];
    let o = run(&[&args[..], &["--eye", "-0.2,0.27,-0.8", "--target", "-0.1,0.27,0", "--exposure", "-.5"]].concat());
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    let summary = std::fs::read_to_string(dir.path().join("summary.json")).unwrap();
    assert!(summary.contains("-0.2") && summary.contains("command line"), "{summary}");
    // Every flag that takes a value, in every subcommand: "-.5" is a value (in --normal-threshold's
    // range; clap read it as an unknown flag '-.'), "-inf" one its own check refuses by name.
    let restir = ["--mode", "restir", "--vpls-direct", "300", "--vpls-indirect", "300"];
    let o = run(&[&args[..], &restir[..], &["--normal-threshold", "-.5"]].concat());
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    assert_fails(&[&args[..], &restir[..], &["--mcap", "-.5"]].concat(), &["--mcap -0.5"]);
    assert_fails(&["compare", "a.exr", "b.exr", "--ppd", "-inf"], &["--ppd", "not -inf"]);
}

#[test]
fn later_flag_overrides_earlier() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().display().to_string();
    let o = run(&["--headless", "--frames", "0", "--frames", "1", "--width", "8", "--height", "8", "--out", &out]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A list flag too (its values were appended: "--checkpoints 0 --checkpoints 1" was [0, 1],
    // refused for the 0). The run stops at the --out after the checkpoints are checked: a file.
    let file = dir.path().join("a_file");
    std::fs::write(&file, b"x").unwrap();
    let file = file.display().to_string();
    for cmd in [&["results", "--quick"][..], &["bench", "--curves", "--quick"][..]] {
        let args = [cmd, &["--checkpoints", "0", "--checkpoints", "1,2", "--out", &file]].concat();
        let o = run(&args);
        assert!(!o.status.success() && stderr(&o).contains("not a directory") && !stderr(&o).contains("--checkpoints"), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn vpl_mode_flag_errors() {
    let h = ["--headless", "--width", "8", "--height", "8", "--frames", "1"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> { h.iter().copied().chain(extra.iter().copied()).collect() };
    assert_fails(&with(&["--mode", "ris", "--candidates", "0"]), &["--candidates 0"]);
    assert_fails(&with(&["--mode", "ris", "--candidates", "8", "--grid-candidates", "9"]), &["--grid-candidates 9", "--candidates (8)"]);
    assert_fails(&with(&["--mode", "ris", "--grid-candidates", "4", "--grid-cells", "0"]), &["--grid-cells 0"]);
    assert_fails(&with(&["--mode", "ris", "--grid-candidates", "4", "--grid-cells", "65"]), &["--grid-cells 65"]);
    assert_fails(&with(&["--mode", "ris", "--grid-candidates", "4", "--grid-entries", "100"]), &["--grid-entries 100", "multiple of 64"]);
    assert_fails(&with(&["--mode", "ris", "--grid-candidates", "4", "--grid-entry-candidates", "0"]), &["--grid-entry-candidates 0"]);
    assert_fails(&with(&["--mode", "restir", "--spatial-neighbours", "33"]), &["--spatial-neighbours 33"]);
    assert_fails(&with(&["--mode", "restir", "--spatial-radius", "0"]), &["--spatial-radius 0"]);
    assert_fails(&with(&["--mode", "restir", "--spatial-radius", "1e30"]), &["--spatial-radius 1e30", "from 1 to 32768"]);
    assert_fails(&with(&["--mode", "restir", "--normal-threshold", "2"]), &["--normal-threshold 2"]);
    assert_fails(&with(&["--mode", "restir", "--mcap=-1"]), &["--mcap"]);
    assert_fails(&with(&["--mode", "restir", "--yuksel-radius=-3"]), &["--yuksel-radius -3"]);
    assert_fails(&with(&["--mode", "restir", "--attenuation", "inverse-square", "--yuksel-radius", "1"]), &["--yuksel-radius", "yuksel"]);
    assert_fails(&with(&["--mode", "ris", "--attenuation", "inverse-square", "--compensate"]), &["--compensate", "yuksel"]);
    assert_fails(&with(&["--mode", "ris", "--yuksel-knn", "0"]), &["--yuksel-knn 0", "between 1 and"]);
    assert_fails(&with(&["--mode", "ris", "--yuksel-knn", "8", "--compensate"]), &["--yuksel-knn", "--compensate"]);
    assert_fails(&with(&["--mode", "ris", "--yuksel-knn", "8", "--yuksel-radius", "0.1"]), &["--yuksel-knn", "--yuksel-radius"]);
    assert_fails(&with(&["--mode", "ris", "--yuksel-spacings=-2"]), &["--yuksel-spacings -2"]);
    // Radii whose square leaves 32-bit floats in the shaders: given, or from the spacing rule.
    assert_fails(&with(&["--mode", "restir", "--yuksel-radius", "1e19"]), &["--yuksel-radius", "1e18"]);
    assert_fails(&with(&["--mode", "ris", "--yuksel-spacings", "1e30"]), &["--yuksel-spacings", "radius", "1e18"]);
    assert_fails(&with(&["--mode", "ris", "--attenuation", "inverse-square", "--yuksel-spacings", "4"]), &["--yuksel-spacings", "yuksel"]);
    assert_fails(&with(&["--mode", "pt", "--view", "reservoir-w"]), &["--view reservoir-w", "no reservoirs"]);
    assert_fails(&with(&["--mode", "bruteforce", "--view", "vpl-kind"]), &["--view vpl-kind"]);
    assert_fails(&with(&["--mode", "pt", "--view", "indirect"]), &["--view indirect"]);
    assert_fails(&with(&["--mode", "restir", "--temporal", "maybe"]), &["--temporal"]);
    assert_fails(&with(&["--mode", "restir", "--bias", "slightly"]), &["--bias"]);
    assert_fails(&with(&["--mode", "restir", "--workgroup", "64x64"]), &["--workgroup", "4096 invocations"]);
    assert_fails(&with(&["--mode", "restir", "--workgroup", "0x8"]), &["--workgroup", "1 to 1024"]);
    assert_fails(&with(&["--mode", "restir", "--workgroup", "8"]), &["--workgroup", "WIDTHxHEIGHT"]);
    // Brute force refuses a frame that would take hours, naming the flags to change.
    assert_fails(
        &["--headless", "--mode", "bruteforce", "--width", "4096", "--height", "4096", "--frames", "1"],
        &["--mode bruteforce", "--width"],
    );
}

#[test]
fn restir_summary_reports_rays_per_pass() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let args = [
        "--headless", "--mode", "restir", "--bias", "unbiased", "--initial-visibility", "on", "--width", "24", "--height", "24",
        "--frames", "3", "--vpls-direct", "100", "--vpls-indirect", "200", "--out", out, "--verbose",
    ];
    // Not given, --fuse-passes is on, and the summary records what it resolved to.
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["settings"]["fuse_passes"], true, "fused unless told off: {}", summary["device"]);
    // Passes apart: the four ReSTIR passes.
    let o = run(&[&args[..], &["--fuse-passes", "off"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    for pass in ["restir_initial", "restir_temporal", "restir_spatial", "vpl_shade"] {
        assert!(err.contains(&format!("  {pass}")), "pass list lacks {pass}: {err}");
    }
    assert!(err.contains("pathtrace                skip (mode is not pt)"), "{err}");
    assert!(err.contains("vpl_presample            run"), "presampling is on by default: {err}");
    assert!(err.contains("restir_spatial_shade     skip (--fuse-passes off)"), "{err}");
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    let by_pass = &summary["rays_per_pixel_by_pass"];
    // Unbiased reuse with visibility in the targets: rays in the initial and spatial passes,
    // none in the shade pass (the chosen sample is known visible).
    assert!(by_pass["restir_initial"]["mean"].as_f64().unwrap() > 0.0, "{by_pass}");
    assert!(by_pass["restir_spatial"]["mean"].as_f64().unwrap() > 0.0, "{by_pass}");
    assert!(by_pass.get("vpl_shade").is_none(), "{by_pass}");
    assert_eq!(summary["vpl"]["unbiased_reuse"], true);
    // The default radius: 8 × the mean VPL spacing √(A / (π N)) of the VPLs traced.
    let area = restir_vpl::scene::Scene::load(&repo_path("scenes/cornell_box.gltf")).unwrap().surface_area();
    let n = summary["vpl"]["vpl_count"].as_f64().unwrap();
    let want = restir_vpl::settings::DEFAULT_RADIUS_SPACINGS as f64 * (area / (std::f64::consts::PI * n)).sqrt();
    let r = summary["vpl"]["yuksel_radius"].as_f64().unwrap();
    assert!((r / want - 1.0).abs() < 1e-5, "Yuksel radius {r} vs 8 × the mean spacing {want} ({n} VPLs)");
    assert_eq!(restir_vpl::settings::DEFAULT_RADIUS_SPACINGS, 8.0, "the README's default");

    // Fused: frame 0 has no history, so restir_initial runs alone and the last
    // spatial pass is fused with the shading; from frame 1 restir_initial_temporal runs (its rays:
    // the initial visibility test, and the temporal merge's).
    let o = run(&[&args[..], &["--fuse-passes", "on"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    for line in [
        "restir_initial           run",
        "restir_initial_temporal  skip (restir_temporal does not run this frame)",
        "restir_spatial           skip (fused into restir_spatial_shade)",
        "restir_spatial_shade     run",
        "vpl_shade                skip (fused into restir_spatial_shade)",
    ] {
        assert!(err.contains(line), "frame 0's pass list lacks '{line}': {err}");
    }
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["settings"]["fuse_passes"], true);
    let by_pass = &summary["rays_per_pixel_by_pass"];
    assert!(by_pass["restir_initial_temporal"]["mean"].as_f64().unwrap() > 0.0, "{by_pass}");
    assert!(by_pass["restir_spatial_shade"]["mean"].as_f64().unwrap() > 0.0, "{by_pass}");
    assert_eq!(summary["pass_ms"]["restir_initial_temporal"]["count"], 2, "frames 1 and 2: {summary}");
    // Per frame over all frames, 0 where a pass traced nothing, so the passes add up to the whole
    // (restir_initial traced in frame 0 alone; its mean was over that one frame).
    let sum: f64 = by_pass.as_object().unwrap().values().map(|t| t["mean"].as_f64().unwrap()).sum();
    let whole = summary["rays_per_pixel"]["mean"].as_f64().unwrap();
    assert!((sum - whole).abs() <= 1e-9 * whole, "by pass {sum} against {whole}: {by_pass}");
    assert_eq!(by_pass["restir_initial"]["count"], 3, "{by_pass}");
    assert!(by_pass.get("vpl_shade").is_none() && by_pass.get("restir_spatial").is_none(), "{by_pass}");
}

#[test]
fn presample_off_skips_the_pass_and_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let common = ["--headless", "--width", "16", "--height", "16", "--frames", "1", "--vpls-direct", "50", "--vpls-indirect", "50", "--verbose", "--out", out];
    let o = run(&[&common[..], &["--mode", "ris", "--presample", "off"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("vpl_presample            skip (--presample off)"), "{}", stderr(&o));
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["vpl"]["presample"], false);
    assert!(summary["vpl"]["spatial_radius_px"].is_null(), "RIS has no spatial reuse: {summary}");
    let o = run(&[&common[..], &["--mode", "uniform"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("vpl_presample            skip (uniform sampling reads one VPL per pixel)"), "{}", stderr(&o));
    // Uniform draws its one VPL a pixel in restir_initial: the list says so, not only the name.
    assert!(stderr(&o).contains("restir_initial           run (1 candidate per pixel into its reservoir)"), "{}", stderr(&o));
    let o = run(&[&common[..], &["--mode", "ris", "--presample", "maybe"]].concat());
    assert!(!o.status.success() && stderr(&o).contains("--presample"), "{}", stderr(&o));
}

#[test]
fn restir_defaults_to_unbiased_reuse_with_unshadowed_targets() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = run(&[
        "--headless", "--mode", "restir", "--width", "24", "--height", "24", "--frames", "2", "--vpls-direct", "100",
        "--vpls-indirect", "200", "--out", out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["vpl"]["unbiased_reuse"], true, "{summary}");
    assert_eq!(summary["vpl"]["initial_visibility"], false, "{summary}");
    // The spatial radius scales with the width (20 px per 1280), at least 4 px: 4 at 24 px.
    assert_eq!(summary["vpl"]["spatial_radius_px"], 4.0, "{summary}");
    // No visibility in the targets: the one shadow ray per pixel at most is the shading's, which
    // runs fused with the last spatial pass by default; the reuse traces none.
    assert_eq!(summary["settings"]["fuse_passes"], true, "{summary}");
    let by_pass = &summary["rays_per_pixel_by_pass"];
    let shade = by_pass["restir_spatial_shade"]["mean"].as_f64().unwrap();
    assert!(shade > 0.0 && shade <= 1.0, "{by_pass}");
    for pass in ["restir_initial", "restir_initial_temporal", "restir_spatial", "vpl_shade"] {
        assert!(by_pass.get(pass).is_none(), "{pass} traced: {by_pass}");
    }
}

#[test]
fn pipeline_cache_is_saved_checked_and_a_foreign_file_ignored() {
    let cache = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let args = [
        "--headless", "--mode", "uniform", "--width", "16", "--height", "16", "--frames", "1", "--vpls-direct", "100",
        "--vpls-indirect", "100", "--verbose", "--out", out.path().to_str().unwrap(),
    ];
    let go = || bin().args(args).env("RESTIR_VPL_CACHE_DIR", cache.path()).output().expect("binary runs");
    let o = go();
    assert!(o.status.success(), "{}", stderr(&o));
    let files: Vec<_> = std::fs::read_dir(cache.path()).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(files.len(), 1, "one cache file per device and build: {files:?}");
    let file = &files[0];
    let data = std::fs::read(file).unwrap();
    // Our frame (magic, length, CRC-32), then VkPipelineCacheHeaderVersionOne: length 32 and
    // version 1 first.
    let driver = &data[16..];
    assert!(&data[..8] == b"RVPLPC02" && data[8..12] == (driver.len() as u32).to_le_bytes(), "{:?}", &data[..16]);
    assert!(driver.len() >= 32 && driver[0..4] == 32u32.to_le_bytes() && driver[4..8] == 1u32.to_le_bytes(), "{:?}", &driver[..driver.len().min(32)]);
    let o = go();
    assert!(stderr(&o).contains(&format!("({} bytes loaded)", driver.len())), "{}", stderr(&o));
    // A file from another device (wrong vendor in the header, its frame whole) is ignored with a
    // warning and replaced; so is a damaged one (its checksum fails).
    let mut foreign = data.clone();
    foreign[16 + 8..16 + 12].copy_from_slice(&0xdeadu32.to_le_bytes());
    let crc = crc32fast::hash(&foreign[16..]);
    foreign[12..16].copy_from_slice(&crc.to_le_bytes());
    let mut damaged = data.clone();
    *damaged.last_mut().unwrap() ^= 1;
    for (bad, says) in [(foreign, "written by another device or driver"), (damaged, "damaged")] {
        std::fs::write(file, &bad).unwrap();
        let o = go();
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
        assert_eq!(std::fs::read(file).unwrap(), data, "the file was not replaced");
    }
    // RESTIR_VPL_PIPELINE_CACHE=off: nothing read or written.
    let off = tempfile::tempdir().unwrap();
    for value in ["off", "OFF", "0", "false"] {
        let o = bin().args(args).env("RESTIR_VPL_CACHE_DIR", off.path()).env("RESTIR_VPL_PIPELINE_CACHE", value).output().unwrap();
        assert!(o.status.success(), "{value}: {}", stderr(&o));
        assert_eq!(std::fs::read_dir(off.path()).unwrap().count(), 0, "{value}");
    }
    // A value that is neither is refused, naming the variable (it wrote the cache).
    let o = bin().args(args).env("RESTIR_VPL_CACHE_DIR", off.path()).env("RESTIR_VPL_PIPELINE_CACHE", "maybe").output().unwrap();
    assert!(!o.status.success() && stderr(&o).contains("RESTIR_VPL_PIPELINE_CACHE=\"maybe\""), "{}", stderr(&o));
    assert_eq!(std::fs::read_dir(off.path()).unwrap().count(), 0);
}

#[test]
fn renderdoc_capture_without_renderdoc_says_how_and_goes_on() {
    let out = tempfile::tempdir().unwrap();
    let o = run(&[
        "--headless", "--mode", "uniform", "--width", "16", "--height", "16", "--frames", "3", "--vpls-direct", "100",
        "--vpls-indirect", "100", "--renderdoc-capture", "1", "--out", out.path().to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("renderdoccmd capture"), "{}", stderr(&o));
    assert!(out.path().join("final.exr").exists());
    assert_fails(
        &["--headless", "--frames", "3", "--renderdoc-capture", "3", "--width", "8", "--height", "8"],
        &["--renderdoc-capture", "frames 0..2"],
    );
}

#[test]
fn image_beyond_the_texel_buffer_limit_is_refused_or_rendered_never_a_crash() {
    // 4096² needs 134,217,728 G-buffer texels (2 halves × 4 texels a pixel), exactly lavapipe's
    // maxTexelBufferElements (2^27), and 256 MiB per 16-byte-a-pixel buffer, over its
    // maxStorageBufferRange (128 MiB), where the
    // build before the texel views crashed (segfault) instead of saying so. A device with larger
    // limits renders it (1 frame, path tracer).
    let out = tempfile::tempdir().unwrap();
    let o = run(&["--headless", "--mode", "pt", "--width", "4096", "--height", "4096", "--frames", "1", "--out", out.path().to_str().unwrap()]);
    let err = stderr(&o);
    assert!(o.status.code().is_some(), "killed by a signal: {err}");
    assert!(!err.contains("panicked"), "panicked: {err}");
    if !o.status.success() {
        for e in ["--width 4096 --height 4096", "buffer limits", "at most"] {
            assert!(err.contains(e), "the refusal should mention '{e}': {err}");
        }
        return;
    }
    // Rendered (a device with larger limits): a whole, finite, lit image and a clean run.
    let img = restir_vpl::output::read_exr(&out.path().join("final.exr")).unwrap();
    assert_eq!((img.width, img.height), (4096, 4096));
    assert_all_finite(&img.pixels, "final.exr");
    // Lit in every eighth of its rows but the last (the Cornell box's bottom rows are black in a
    // correct image): a render that stopped part-way would leave a band dark.
    let rows = 4096 / 8;
    for band in 0..7 {
        let px = &img.pixels[band * rows * 4096..(band + 1) * rows * 4096];
        assert!(px.iter().any(|p| p.iter().any(|&c| c > 0.0)), "rows {}..{} are dark", band * rows, (band + 1) * rows);
    }
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.path().join("summary.json")).unwrap()).unwrap();
    common::assert_clean_summary(&s, "4096² run");
}

#[test]
fn a_1280x720_frame_of_every_mode_stays_within_the_device_limits() {
    // The tests render 64–256 px, but buffer ranges grow with the image: at 1280×720 the G-buffer
    // (147 MB) bound as a storage buffer broke lavapipe's 128 MiB maxStorageBufferRange, a
    // validation error in every run at that size (the issue's benchmark size) that small images
    // never showed. Two frames per mode (few VPLs, so it stays quick) under the validation layer.
    if !validate() {
        common::skip("no validation layer: only checking that the runs succeed, not that they stay within the device limits");
    }
    let out = tempfile::tempdir().unwrap();
    let o = out.path().to_str().unwrap();
    let runs: [&[&str]; 5] = [
        &["--mode", "pt"],
        &["--mode", "uniform"],
        &["--mode", "ris"],
        &["--mode", "restir", "--compensate"],
        &["--mode", "restir", "--initial-visibility", "on"],
    ];
    for mode in runs {
        let mut args = vec!["--headless", "--width", "1280", "--height", "720", "--frames", "2", "--vpls-direct", "1000"];
        args.extend_from_slice(&["--vpls-indirect", "1000", "--out", o]);
        args.extend_from_slice(mode);
        let r = run(&args);
        let err = stderr(&r);
        assert!(r.status.success(), "{mode:?} failed: {err}");
        assert!(!err.contains("VALIDATION") && !err.contains("validation error"), "{mode:?}: {err}");
    }
}

/// The loader's own complaints are no validation error: a driver manifest whose library is
/// missing (a container with an NVIDIA manifest and no driver) made the loader report two errors
/// during vkCreateInstance, which the messenger chained there counted, and every run under
/// validation failed.
#[test]
fn a_stray_driver_manifest_is_no_validation_error() {
    if !common::validation_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("stray_icd.json");
    std::fs::write(&manifest, r#"{"file_format_version": "1.0.0", "ICD": {"library_path": "/nonexistent/libstray_vulkan.so", "api_version": "1.3.0"}}"#).unwrap();
    let o = bin()
        .args(["--headless", "--mode", "pt", "--width", "8", "--height", "8", "--frames", "1", "--out", dir.path().to_str().unwrap()])
        .env("VK_ADD_DRIVER_FILES", &manifest)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A command's exit status is what the tests' "0 validation errors" rests on for everything run as
/// a subprocess: with one invalid command recorded (a test-only switch), a headless run and
/// `reference` under validation exit non-zero naming the error, and without validation the same
/// runs succeed (the switch does nothing else).
#[test]
fn a_validation_error_fails_headless_and_reference_runs() {
    if !common::validation_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let small = ["--width", "8", "--height", "8", "--frames", "1", "--mode", "pt"];
    let headless = |strict: bool| {
        let mut c = bin();
        c.args(["--headless", "--out", dir.path().to_str().unwrap()]).args(small).env("RESTIR_VPL_DEBUG_POISON", "validation");
        if !strict {
            c.env_remove("RESTIR_VPL_VALIDATE");
        }
        c.output().unwrap()
    };
    let reference = |strict: bool| {
        // A new file each time: the failed run still writes its frames, as a headless run does.
        let exr = dir.path().join(format!("ref_{strict}.exr"));
        let mut c = bin();
        c.args(["reference", "--out", exr.to_str().unwrap()]).args(small).env("RESTIR_VPL_DEBUG_POISON", "validation");
        if !strict {
            c.env_remove("RESTIR_VPL_VALIDATE");
        }
        c.output().unwrap()
    };
    for (what, run) in [("headless", &headless as &dyn Fn(bool) -> Output), ("reference", &reference)] {
        let o = run(true);
        let err = stderr(&o);
        assert!(!o.status.success(), "{what}: exit 0 with a validation error: {err}");
        assert!(err.contains("validation error"), "{what}: {err}");
        let o = run(false);
        assert!(o.status.success(), "{what} without validation: {}", stderr(&o));
    }
}

/// No Vulkan driver at all (the loader pointed at a driver file that does not exist): every
/// command that needs a device says that no device qualifies, and why, with exit code 2 (as for
/// devices without ray queries); `--list-devices` lists none and succeeds, with the same words
/// (it said "no Vulkan devices found" without naming the driver files to check). Before, the loader's
/// answers came out as "vkCreateInstance failed" or "vkEnumeratePhysicalDevices failed", exit 1.
#[test]
fn no_vulkan_driver_is_reported_as_no_device_with_exit_code_2() {
    let without_driver = |args: &[&str]| {
        bin()
            .args(args)
            .env("VK_ICD_FILENAMES", "/nonexistent/restir-vpl-test-icd.json")
            .env("VK_DRIVER_FILES", "/nonexistent/restir-vpl-test-icd.json")
            .env_remove("RESTIR_VPL_VALIDATE")
            .output()
            .unwrap()
    };
    let o = without_driver(&["--headless", "--width", "8", "--height", "8", "--frames", "1"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("no Vulkan device can trace rays") && err.contains("found no driver"), "{err}");
    assert_eq!(err.matches("scripts/setup.sh").count(), 1, "the install hint is said once: {err}");
    assert!(!err.contains("panicked"), "{err}");
    let o = without_driver(&["--list-devices"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let listed = String::from_utf8_lossy(&o.stdout);
    assert!(listed.contains("(none)") && listed.contains("found no driver") && listed.contains("VK_ICD_FILENAMES"), "{o:?}");
    // RESTIR_VPL_VALIDATE is checked by every command, those without a device too (a typo
    // passed silently there).
    for args in [&["--list-devices"][..], &["compare", "a.exr", "b.exr"], &["merge-references", "a.exr", "b.exr", "--out", "c.exr"]] {
        let o = bin().args(args).env("RESTIR_VPL_VALIDATE", "maybe").output().unwrap();
        assert!(!o.status.success() && stderr(&o).contains("RESTIR_VPL_VALIDATE"), "{args:?}: {}", stderr(&o));
    }
}

/// A path that is not UTF-8 is refused before any work, naming its flag or argument (the summary
/// and reference files record paths as text: before, a headless run rendered, wrote its images and
/// then failed on summary.json, naming nothing).
#[cfg(unix)]
#[test]
fn non_utf8_paths_are_refused_naming_the_flag() {
    use std::os::unix::ffi::OsStrExt;
    let bad = std::ffi::OsStr::from_bytes(b"/tmp/restir-vpl-test-\xff");
    for (args, name) in [
        (vec!["--headless", "--frames", "1", "--out"], "--out"),
        (vec!["--headless", "--frames", "1", "--scene"], "--scene"),
        (vec!["compare", "/tmp/a.exr"], "<B.exr>"),
    ] {
        let o = bin().args(&args).arg(bad).output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(name) && err.contains("not valid UTF-8"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// The pipeline cache goes to an absolute directory only: an empty RESTIR_VPL_CACHE_DIR is unset,
/// and a relative XDG_CACHE_HOME is ignored (the XDG base directory spec), so HOME's .cache is
/// used. Before, both put the cache file in the working directory.
#[test]
fn an_empty_or_relative_cache_variable_is_not_the_working_directory() {
    let (cwd, home) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let out = cwd.path().join("out");
    let scene = repo_path("scenes/cornell_box.gltf");
    let o = bin()
        .current_dir(cwd.path())
        .env_remove("RESTIR_VPL_PIPELINE_CACHE")
        .env("RESTIR_VPL_CACHE_DIR", "")
        .env("XDG_CACHE_HOME", "relative-cache")
        .env("HOME", home.path())
        .args(["--headless", "--frames", "1", "--width", "8", "--height", "8", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    // (Mesa's own shader cache does follow a relative XDG_CACHE_HOME: only ours is checked.)
    fn ours(dir: &Path) -> Vec<std::path::PathBuf> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .flat_map(|p| if p.is_dir() { ours(&p) } else { vec![p] })
            .filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("pipelines-")))
            .collect()
    }
    assert_eq!(ours(cwd.path()), Vec::<std::path::PathBuf>::new(), "pipeline cache under the working directory");
    let cache = home.path().join(".cache/restir-vpl");
    assert!(std::fs::read_dir(&cache).is_ok_and(|mut d| d.next().is_some()), "no cache file in {}", cache.display());
}

/// Outputs that cannot be written are refused before the work, naming the flag: a bench's --json
/// naming a directory, an --out that is a file, compare's --error-image naming a directory (each
/// failed only after the benchmark, the references or FLIP had run).
#[test]
fn unwritable_outputs_are_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let (d, f) = (dir.path().to_str().unwrap(), file.to_str().unwrap());
    assert_fails(&["bench", "--json", d, "--frames", "1", "--width", "8", "--height", "8"], &["--json", "is a directory"]);
    assert_fails(&["bench", "--curves", "--quick", "--out", f], &["--out", "exists and is not a directory"]);
    assert_fails(&["results", "--quick", "--out", f], &["--out", "exists and is not a directory"]);
    assert_fails(&["compare", "a.exr", "b.exr", "--error-image", d], &["--error-image", "is a directory"]);
    // A device is written in place, and checking it makes no file beside it (in /dev): the first
    // version of the check refused /dev/null as --json for any user but root ("cannot create a
    // file beside /dev/null"; as root, which this suite may run as, it made and removed one).
    let exr = dir.path().join("img.exr");
    restir_vpl::output::write_exr(&exr, 2, 2, &[[0.5; 3]; 4]).unwrap();
    let o = run(&["compare", exr.to_str().unwrap(), exr.to_str().unwrap(), "--json", "/dev/null"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A submission that never finishes ends in an error after `RESTIR_VPL_GPU_TIMEOUT_S`, naming the
/// frame, the device, the passes the device finished and the first it did not (read from the
/// frame's breadcrumbs while it hangs), with a non-zero exit and no hang on the way out (the drops
/// leave the hung device alone). The hang is planted: `RESTIR_VPL_DEBUG_POISON=hang_after:<pass>`
/// makes every frame wait, after that pass, for an event the host never sets (on lavapipe the
/// queue waits forever; a GPU may reset instead, which ends the wait in a device-lost error). A
/// limit that is not a number of seconds is refused by name.
#[test]
fn a_frame_that_never_finishes_ends_in_an_error_naming_the_passes() {
    let args = ["--headless", "--mode", "restir", "--width", "32", "--height", "32", "--frames", "3", "--vpls-direct", "500", "--vpls-indirect", "500"];
    let start = std::time::Instant::now();
    let o = bin()
        .args(args)
        .env("RESTIR_VPL_DEBUG_POISON", "hang_after:restir_initial")
        .env("RESTIR_VPL_GPU_TIMEOUT_S", "2")
        .output()
        .expect("binary runs");
    let took = start.elapsed().as_secs_f64();
    let err = stderr(&o);
    assert!(!o.status.success() && !err.contains("panicked"), "{err}");
    // Frame 0: gbuffer, vpl_presample, restir_initial, (the planted wait), restir_spatial, ...
    for words in [
        "frame 0 did not finish in 2 s on",
        "RESTIR_VPL_GPU_TIMEOUT_S",
        "the device finished 3 of its",
        "(gbuffer, vpl_presample, restir_initial)",
        "the first not finished: restir_spatial",
        // and ends without the driver's exit handlers, in which NVIDIA's driver spun for ever
        // after the planted hang (docs/gpu.md, stop 51)
        "the process ends without the Vulkan driver's exit handlers",
    ] {
        assert!(err.contains(words), "lacks '{words}': {err}");
    }
    // The limit plus start-up (a few seconds here, more under the validation layer); a wait
    // without a limit would never return.
    assert!(took < 120.0, "took {took:.0} s");

    let o = bin().args(args).env("RESTIR_VPL_GPU_TIMEOUT_S", "soon").output().expect("binary runs");
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("RESTIR_VPL_GPU_TIMEOUT_S=\"soon\"") && !err.contains("panicked"), "{err}");
    // Refused in Renderer::new after its frame slots were made: they are freed (the layer, where
    // installed, reported both slots' fences alive at vkDestroyDevice before).
    let o = bin().args(args).env("RESTIR_VPL_DEBUG_POISON", "hang_after:no_such_pass").output().expect("binary runs");
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("hang_after:no_such_pass") && !err.contains("panicked"), "{err}");
    assert!(!err.contains("VUID"), "objects left alive: {err}");
}

/// The window's `--reference` must be of the window's scene: a reference written by `reference`
/// names its scene, and one of another scene is refused before any window opens, naming the flag
/// and both scenes (it was shown beside the render with RMSE and FLIP as if comparable). A
/// reference of the same scene is accepted as far as that check goes (no display here: the run then
/// fails on the window, not on the reference).
#[test]
fn the_window_refuses_a_reference_of_another_scene() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("cornell.exr");
    let o = run(&["reference", "--mode", "pt", "--width", "16", "--height", "12", "--frames", "2", "--out", exr.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = bin().args(["--scene", "scenes/living_room.gltf", "--reference", exr.to_str().unwrap()]).env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY").output().unwrap();
    let err = stderr(&o);
    assert!(!o.status.success() && !err.contains("panicked"), "{err}");
    assert!(err.contains("--reference") && err.contains("another scene") && err.contains("cornell_box.gltf") && err.contains("living_room.gltf"), "{err}");
    let o = bin().args(["--reference", exr.to_str().unwrap()]).env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY").output().unwrap();
    let err = stderr(&o);
    assert!(!o.status.success() && !err.contains("another scene") && !err.contains("panicked"), "{err}");
    // Nor may the run's outputs overwrite it: a reference at OUT/final.exr was replaced by Enter
    // (or --frames), without its scene's name, and then accepted for any scene.
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::copy(&exr, out.join("final.exr")).unwrap();
    let o = bin()
        .args(["--reference", out.join("final.exr").to_str().unwrap(), "--out", out.to_str().unwrap()])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("the run writes final.exr there, which is the --reference") && !err.contains("panicked"), "{err}");
}

/// One textured, emitting triangle in `dir/scene.gltf`: positions, UVs and indices in the external
/// buffer `dir/tri.bin` (returned with the scene's path), its texture the image file `image`.
fn textured_triangle(dir: &Path, image: &str) -> (String, Vec<u8>) {
    let mut bin = Vec::new();
    for v in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        bin.extend(v.iter().flat_map(|c| c.to_le_bytes()));
    }
    for uv in [[0f32, 0.0], [1.0, 0.0], [0.0, 1.0]] {
        bin.extend(uv.iter().flat_map(|c| c.to_le_bytes()));
    }
    bin.extend([0u16, 1, 2, 0].iter().flat_map(|i| i.to_le_bytes()));
    std::fs::write(dir.join("tri.bin"), &bin).unwrap();
    let json = r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"tri.bin","byteLength":68}],
        "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":24},{"buffer":0,"byteOffset":60,"byteLength":6}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},
                     {"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"},
                     {"bufferView":2,"componentType":5123,"count":3,"type":"SCALAR"}],
        "images":[{"uri":"IMAGE"}],"textures":[{"source":0}],
        "materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}},"emissiveFactor":[1,1,1]}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":1},"indices":2,"material":0}]}],
        "nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0}"#;
    (write(dir, "scene.gltf", &json.replace("IMAGE", image)), bin)
}

/// A run whose outputs would overwrite one of its own inputs is refused before any frame, naming
/// the flag and the input (found by a review helper; each of these wrote over its input with exit
/// 0): `--out` over the camera path (a path file named summary.json) and over a texture the scene
/// reads (named final.png), `--dump-vpls` over the scene's external buffer, and `bench --json`
/// over `--scene`. The input is left as it was.
#[test]
fn outputs_that_would_overwrite_an_input_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let png = restir_vpl::output::encode_png(1, 1, &[200, 200, 200, 255]).unwrap();
    std::fs::write(d.join("final.png"), &png).unwrap();
    let (scene, bin) = textured_triangle(d, "final.png");
    let path_json = d.join("paths").join("summary.json");
    std::fs::create_dir_all(path_json.parent().unwrap()).unwrap();
    std::fs::write(&path_json, r#"{"keyframes":[{"frame":0,"eye":[0.3,0.3,1],"target":[0.3,0.3,0],"up":[0,1,0],"fov":50}]}"#).unwrap();
    let path = path_json.to_str().unwrap();
    let small = ["--headless", "--mode", "ris", "--width", "8", "--height", "8", "--frames", "1", "--vpls-direct", "20", "--vpls-indirect", "20"];
    let cam = ["--eye", "0.3,0.3,1", "--target", "0.3,0.3,0"];
    let (paths_dir, buffer) = (d.join("paths").display().to_string(), d.join("tri.bin").display().to_string());
    let out_over_path = [&small[..], &["--scene", &scene, "--camera-path", path, "--out", &paths_dir]].concat();
    assert_fails(&out_over_path, &["--out", "summary.json", "the --camera-path"]);
    let out_over_texture = [&small[..], &cam[..], &["--scene", &scene, "--out", d.to_str().unwrap()]].concat();
    assert_fails(&out_over_texture, &["--out", "final.png", "a file the scene reads"]);
    let ply_over_buffer = [&small[..], &cam[..], &["--scene", &scene, "--dump-vpls", &buffer]].concat();
    assert_fails(&ply_over_buffer, &["--dump-vpls", "tri.bin", "a file the scene reads"]);
    assert_fails(&["bench", "--scene", &scene, "--json", &scene, "--width", "8", "--height", "8", "--frames", "1"], &["--json", "--scene"]);
    // The inputs are untouched, and the scene renders with another --out.
    assert_eq!(std::fs::read(d.join("tri.bin")).unwrap(), bin);
    assert_eq!(std::fs::read(d.join("final.png")).unwrap(), png);
    assert!(std::fs::read_to_string(&path_json).unwrap().contains("keyframes"));
    let ok = run(&[&small[..], &cam[..], &["--scene", &scene, "--out", d.join("out").to_str().unwrap()]].concat());
    assert!(ok.status.success(), "{}", stderr(&ok));
}

/// `RESTIR_VPL_VALIDATE` takes 1/0, true/false, yes/no, on/off, and refuses anything else by name
/// (`true` was silently off, and for `bench` and `results` the variable is the only switch).
#[test]
fn restir_vpl_validate_takes_the_usual_spellings_and_refuses_others() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let args = ["--headless", "--mode", "uniform", "--width", "8", "--height", "8", "--frames", "1", "--vpls-direct", "20", "--vpls-indirect", "20", "--out", out.to_str().unwrap()];
    let o = bin().args(args).env("RESTIR_VPL_VALIDATE", "maybe").output().unwrap();
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("RESTIR_VPL_VALIDATE=\"maybe\"") && !err.contains("panicked"), "{err}");
    // The timing benchmarks, which run without the layer, refuse it too (they took it silently).
    let o = bin().args(["bench", "--frames", "1", "--width", "8", "--height", "8"]).env("RESTIR_VPL_VALIDATE", "maybe").output().unwrap();
    assert!(!o.status.success() && stderr(&o).contains("RESTIR_VPL_VALIDATE=\"maybe\""), "{}", stderr(&o));
    let spellings: &[(&str, bool)] = if validate() { &[("true", true), ("ON", true), ("off", false), ("", false)] } else { &[("off", false), ("", false)] };
    for (value, on) in spellings {
        let o = bin().args(args).env("RESTIR_VPL_VALIDATE", value).output().unwrap();
        assert!(o.status.success(), "RESTIR_VPL_VALIDATE={value:?}: {}", stderr(&o));
        let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        assert_eq!(s["validation_layer"], *on, "RESTIR_VPL_VALIDATE={value:?}");
    }
    if !validate() {
        skip("no validation layer installed: RESTIR_VPL_VALIDATE=true not run (CI requires one)");
    }
}

/// `--textures off` neither reads nor decodes the scene's images: a scene whose texture is not an
/// image fails with textures on, naming the image, and renders with them off (the loader decoded
/// it either way, so the way out its other texture errors point to did not work for this one).
#[test]
fn textures_off_does_not_decode_the_images() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("albedo.png"), "not an image").unwrap();
    let (scene, _) = textured_triangle(d, "albedo.png");
    let out = d.join("out");
    let args = ["--headless", "--mode", "pt", "--width", "8", "--height", "8", "--frames", "1", "--eye", "0.3,0.3,1", "--target", "0.3,0.3,0", "--scene", &scene, "--out", out.to_str().unwrap()];
    // The file read is named beside the image (the message said only 'image0').
    assert_fails(&args, &["scene.gltf", "image 0", "from 'albedo.png'", "cannot decode"]);
    std::fs::write(d.join("albedo.png"), "").unwrap();
    assert_fails(&args, &["scene.gltf", "from 'albedo.png'", "empty (0 bytes)"]);
    let o = run(&[&args[..], &["--textures", "off"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join("final.exr").exists());
}

/// `reference --resume` continues after the last frame in --out: `--first-frame` is refused with
/// it, 0 included (0 was taken silently, as if not given).
#[test]
fn reference_resume_refuses_any_first_frame() {
    for first in ["0", "5"] {
        assert_fails(&["reference", "--resume", "--first-frame", first, "--out", "/tmp/restir-vpl-never-written.exr"], &["--resume", "--first-frame"]);
    }
}

/// Brute force counts its rays in 64 bits (up to 2e10 pixel × VPL pairs per frame are allowed; a
/// 32-bit count wrapped past 4.3e9 rays): with a test-only switch pixel (0, 0) counts 2^32 − 256
/// rays more, and the summary reports exactly that many more than the same run without it, where
/// a 32-bit count would report 256 fewer.
#[test]
fn brute_force_counts_its_rays_past_two_to_the_32() {
    let dir = tempfile::tempdir().unwrap();
    let rays = |poison: Option<&str>| {
        let out = dir.path().join(poison.unwrap_or("plain"));
        let mut c = bin();
        c.args(["--headless", "--mode", "bruteforce", "--width", "8", "--height", "8", "--vpls-direct", "300", "--vpls-indirect", "300", "--frames", "1", "--out", out.to_str().unwrap()]);
        if let Some(p) = poison {
            c.env("RESTIR_VPL_DEBUG_POISON", p);
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        s["rays_per_pixel_by_pass"]["vpl_bruteforce"]["mean"].as_f64().expect("brute force traced rays") * 64.0
    };
    let (plain, carried) = (rays(None), rays(Some("ray_carry")));
    assert!(plain > 0.0 && plain < 64.0 * 600.0, "{plain}");
    assert_eq!(carried - plain, (u32::MAX - 255) as f64, "{carried} vs {plain}");
}

/// README's "Command line" block names only flags its command has (`--help` of that command), and
/// README mentions every flag the program has: the usage text is prose, so nothing else keeps the
/// two in step. (Which flags go together is the parser's business and tested with it; this checks
/// names only.)
#[test]
fn readme_command_lines_name_only_flags_the_program_has() {
    fn flags(text: &str) -> std::collections::BTreeSet<String> {
        let mut out = std::collections::BTreeSet::new();
        let b = text.as_bytes();
        let mut i = 0;
        while let Some(at) = text[i..].find("--") {
            let start = i + at;
            let mut end = start + 2;
            while end < b.len() && (b[end].is_ascii_lowercase() || b[end].is_ascii_digit() || b[end] == b'-') {
                end += 1;
            }
            let before_ok = start == 0 || !(b[start - 1].is_ascii_alphanumeric() || b[start - 1] == b'-');
            if before_ok && end > start + 2 && b[start + 2].is_ascii_lowercase() {
                out.insert(text[start..end].trim_end_matches('-').to_string());
            }
            i = end;
        }
        out
    }
    let help = |cmd: Option<&str>| {
        let o = run(&cmd.into_iter().chain(["--help"]).collect::<Vec<_>>());
        assert!(o.status.success(), "{cmd:?} --help: {}", stderr(&o));
        let mut f = flags(&String::from_utf8_lossy(&o.stdout));
        f.insert("--help".into());
        f
    };
    let readme = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let block = readme.split("## Command line").nth(1).and_then(|s| s.split("```sh").nth(1)).and_then(|s| s.split("```").next()).expect("README has a Command line section with a sh block");
    let commands = ["bench", "reference", "merge-references", "compare", "results"];
    let mut known: std::collections::BTreeMap<Option<&str>, std::collections::BTreeSet<String>> = Default::default();
    let mut command: Option<&str> = None;
    let mut checked = 0;
    for line in block.lines() {
        if let Some(rest) = line.trim_start().strip_prefix("restir-vpl ") {
            command = commands.iter().copied().find(|c| rest.split_whitespace().next() == Some(*c));
        }
        // "(render flags: not --save-every, ...)": flags the command refuses, which its help hides
        // (the main command's help lists them).
        let (taken, refused) = line.split_once(": not ").unwrap_or((line, ""));
        let main_help = known.entry(None).or_insert_with(|| help(None)).clone();
        let have = known.entry(command).or_insert_with(|| help(command));
        for f in flags(taken) {
            assert!(have.contains(&f), "README's command line `{}` names {f}, which `restir-vpl {} --help` does not list", line.trim(), command.unwrap_or(""));
            checked += 1;
        }
        for f in flags(refused) {
            assert!(main_help.contains(&f) && !have.contains(&f), "README says `restir-vpl {}` refuses {f}: its help should not list it, the main help should", command.unwrap_or(""));
            checked += 1;
        }
    }
    assert!(checked > 100, "only {checked} flags found in README's command block");
    for command in [None].into_iter().chain(commands.iter().map(|c| Some(*c))) {
        for f in known.entry(command).or_insert_with(|| help(command)).iter().filter(|f| *f != "--help" && *f != "--version") {
            // As a whole flag: `--grid` inside `--grid-cells` does not count.
            let whole = readme.match_indices(f.as_str()).any(|(at, _)| {
                readme[at + f.len()..].chars().next().is_none_or(|c| !(c.is_ascii_alphanumeric() || c == '-'))
            });
            assert!(whole, "`restir-vpl {} --help` lists {f}, which README never mentions", command.unwrap_or(""));
        }
    }
}

/// A closed stdout (`restir-vpl … | head -1`) ends the run quietly with SIGPIPE's status, 141,
/// after its outputs are written: println! panicked there (exit 101, "failed printing to
/// stdout"), and a full stdout (/dev/full) is an error naming it.
#[test]
fn a_closed_stdout_ends_the_run_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["--headless", "--mode", "uniform", "--width", "8", "--height", "8", "--frames", "1", "--vpls-direct", "50", "--vpls-indirect", "50", "--out", dir.path().to_str().unwrap()];
    let mut child = bin().args(args).stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap();
    drop(child.stdout.take()); // the reader goes away before anything is printed
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(141), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(dir.path().join("summary.json").is_file(), "the outputs come first");
    if dev_full() {
        let o = bin().args(args).stdout(std::fs::File::create("/dev/full").unwrap()).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.code() == Some(1) && err.contains("writing to stdout"), "{err}");
    }
}

/// The printout's "final image" line gives this run's reason for averaging fewer frames than it
/// rendered: a reservoir view was said to be "--progressive off". `reference --help` hides the
/// render flags `reference` refuses (still refused by name when given).
#[test]
fn the_final_image_line_names_the_runs_reason_and_reference_help_lists_what_it_takes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let small = ["--headless", "--width", "8", "--height", "8", "--frames", "2", "--vpls-direct", "50", "--vpls-indirect", "50", "--out", out];
    for (extra, reason) in [
        (&["--mode", "restir", "--view", "reservoir-m"][..], "(--view reservoir-m shows one frame's reservoirs, not a mean)"),
        (&["--progressive", "off"][..], "(--progressive off: every image is its frame alone)"),
    ] {
        let o = run(&[&small[..], extra].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains(&format!("final image: the last frame alone {reason}")), "{extra:?}: {text}");
    }
    let o = run(&["reference", "--help"]);
    let help = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && help.contains("--frames") && help.contains("--resume"), "{help}");
    for refused in ["--save-every", "--dump-vpls", "--dump-passes", "--check-finite", "--renderdoc-capture", "--camera-path", "In a window"] {
        assert!(!help.contains(refused), "reference --help lists {refused}: {help}");
    }
    let o = run(&["reference", "--check-finite", "--out", &format!("{out}/r.exr")]);
    assert!(!o.status.success() && stderr(&o).contains("--check-finite"), "{}", stderr(&o));
}

/// Flags that only library tests set reach the settings from the command line too (the mapping
/// in main.rs was never run): `--depth-threshold` (and its refusals), `--candidate-source`,
/// `--photon-min-bounces`, and `--device 0`, which picks the first device and names it.
#[test]
fn command_line_flags_reach_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let args = ["--headless", "--width", "8", "--height", "8", "--frames", "1", "--vpls-direct", "50", "--vpls-indirect", "50", "--mode", "restir"];
    let flags = ["--depth-threshold", "0.2", "--candidate-source", "power", "--photon-min-bounces", "1", "--device", "0", "--out", out];
    let o = run(&[&args[..], &flags].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    let st = &s["settings"];
    assert_eq!((st["restir"]["depth_threshold"].as_f64(), &st["candidate_source"], &st["photon_min_bounces"]), (Some(0.2), &serde_json::json!("power"), &serde_json::json!(1)), "{st}");
    assert_eq!((&st["device_index"], &s["device"]["index"]), (&serde_json::json!(0), &serde_json::json!(0)), "{s}");
    assert!(s["device"]["name"].as_str().is_some_and(|n| !n.is_empty()), "{s}");
    for bad in ["-1", "nan", "inf"] {
        assert_fails(&[&args[..], &["--depth-threshold", bad]].concat(), &["--depth-threshold"]);
    }
}

/// The bundled Cornell box under a parent node moved by 1e4 along every axis, written to `dir`.
fn far_cornell(dir: &Path) -> std::path::PathBuf {
    let mut doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(repo_path("scenes/cornell_box.gltf")).unwrap()).unwrap();
    let roots = doc["scenes"][0]["nodes"].clone();
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(serde_json::json!({ "name": "far", "translation": [1e4, 1e4, 1e4], "children": roots }));
    doc["scenes"][0]["nodes"] = serde_json::json!([nodes.len() - 1]);
    let scene = dir.join("far.gltf");
    std::fs::write(&scene, doc.to_string()).unwrap();
    scene
}

/// A scene far from the file's origin is rendered about its centre (tests/scale.rs), and what a
/// run writes stays in the file's coordinates: the summary's camera, and the VPL dump's
/// positions, which lie in the moved Cornell box.
#[test]
fn a_far_scene_reports_in_the_files_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    let scene = far_cornell(dir.path());
    let ply = dir.path().join("vpls.ply");
    let out = dir.path().join("out");
    let o = run(&[
        "--headless", "--scene", scene.to_str().unwrap(), "--mode", "uniform", "--width", "16", "--height", "16", "--frames", "1",
        "--vpls-direct", "500", "--vpls-indirect", "500", "--dump-vpls", ply.to_str().unwrap(), "--out", out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let p: Vec<f64> = (0..3).map(|i| s["camera"]["position"][i].as_f64().unwrap()).collect();
    let want = [1e4 + 0.278, 1e4 + 0.273, 1e4 - 0.8];
    assert!(p.iter().zip(want).all(|(a, b)| (a - b).abs() < 0.01), "camera at {p:?}, the scene camera at {want:?}");
    let vpls = restir_vpl::ply::read_vpls(&ply).unwrap();
    assert!(!vpls.is_empty());
    for v in &vpls {
        assert!(v.position.iter().all(|&c| (1e4 - 0.01..=1e4 + 0.57).contains(&f64::from(c))), "a VPL at {:?}, outside the moved box", v.position);
    }
}

/// A lamp facing empty space: every photon leaves the scene, so no indirect VPL is made. The run
/// says so on stderr and keeps it in summary.json's warnings (which a closed box far from the
/// origin, all of whose photons left, had empty).
#[test]
fn no_indirect_vpls_is_a_summary_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = floor_and_lamp(true);
    b.camera("cam", [0.0, 3.0, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.7);
    let scene = dir.path().join("away.gltf");
    std::fs::write(&scene, b.to_json_string()).unwrap();
    let out = dir.path().join("out");
    let o = run(&["--headless", "--scene", scene.to_str().unwrap(), "--mode", "ris", "--width", "8", "--height", "8", "--frames", "1", "--vpls-direct", "100", "--vpls-indirect", "100", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["photons"]["indirect_vpls"], 0, "{s}");
    let warnings = s["warnings"].as_array().unwrap();
    assert!(warnings.iter().any(|w| w.as_str().unwrap().contains("--vpls-indirect 100: only 0 indirect VPLs")), "{warnings:?}");
}

/// A camera path given in the file's coordinates of a far scene is followed as the same path at
/// the origin is: the bundled box's committed path moved by 1e4 renders the moved box as the
/// path renders the box (mean within 0.5 %: the box's vertices move by up to an ulp at 1e4), and
/// the G-buffer's dumped positions lie in the moved box, in the file's coordinates.
#[test]
fn a_far_scene_follows_its_camera_path_and_dumps_file_positions() {
    let dir = tempfile::tempdir().unwrap();
    let scene = far_cornell(dir.path());
    let mut path: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(repo_path("scenes/cornell_box.path.json")).unwrap()).unwrap();
    for k in path["keyframes"].as_array_mut().unwrap() {
        for key in ["eye", "target"] {
            for c in k[key].as_array_mut().unwrap() {
                *c = serde_json::json!(c.as_f64().unwrap() + 1e4);
            }
        }
    }
    let far_path = dir.path().join("far.path.json");
    std::fs::write(&far_path, path.to_string()).unwrap();
    let common = ["--headless", "--mode", "pt", "--max-bounces", "2", "--width", "32", "--height", "32", "--frames", "6", "--progressive", "off"];
    let (near_out, far_out) = (dir.path().join("near"), dir.path().join("far"));
    let o = run(&[&common[..], &["--camera-path", "scenes/cornell_box.path.json", "--out", near_out.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&[&common[..], &["--scene", scene.to_str().unwrap(), "--camera-path", far_path.to_str().unwrap(), "--dump-passes", "5", "--out", far_out.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let read_exr = restir_vpl::output::read_exr;
    let (near, far) = (read_exr(&near_out.join("final.exr")).unwrap(), read_exr(&far_out.join("final.exr")).unwrap());
    let c = restir_vpl::eval::compare::compare(&far, &near, &restir_vpl::eval::compare::CompareOptions { flip: false, ..Default::default() }).unwrap();
    assert!((c.mean_ratio - 1.0).abs() < 5e-3, "the far box along the moved path: mean ratio {} against the box along the path", c.mean_ratio);
    let positions = read_exr(&far_out.join("passes/frame_0005/00_gbuffer__position.exr")).unwrap();
    let hits: Vec<&[f32; 3]> = positions.pixels.iter().filter(|p| p.iter().all(|&v| v > 1e3)).collect();
    assert!(hits.len() > 500, "{} of 1024 pixels hold a position in the moved box", hits.len());
    for p in hits {
        assert!(p.iter().all(|&v| (1e4 - 0.01..=1e4 + 0.57).contains(&f64::from(v))), "a dumped position {p:?} outside the moved box");
    }
}

/// Settings that the device or the VPL set made moot are said on stderr and kept in the summary's
/// `warnings` (they reached stderr only), and a run whose VPLs carry no power with
/// `--candidate-source power` renders its black image (it stopped with an error while every other
/// source and mode rendered one).
#[test]
fn settings_made_moot_at_set_up_are_kept_in_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let small = ["--headless", "--width", "16", "--height", "16", "--frames", "2"];
    let summary_warnings = |out: &Path| -> Vec<String> {
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        v["warnings"].as_array().unwrap().iter().map(|w| w.as_str().unwrap().to_string()).collect()
    };
    let cases: [(&[&str], &str); 3] = [
        (&["--mode", "ris", "--vpls-direct", "0", "--no-gi", "--candidate-source", "power"], "--candidate-source power: the VPLs carry no power"),
        (&["--mode", "ris", "--vpls-direct", "1", "--no-gi", "--yuksel-knn", "4"], "--yuksel-knn 4: the VPL set has 1 VPL"),
        (&["--mode", "ris", "--trace", "pipeline", "--workgroup", "16x4"], "--workgroup 16x4 has no effect here"),
    ];
    for (i, (flags, said)) in cases.iter().enumerate() {
        let out = dir.path().join(format!("run{i}"));
        let o = run(&[&small[..], flags, &["--out", out.to_str().unwrap()]].concat());
        assert!(o.status.success(), "{flags:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(said), "{flags:?}: {}", stderr(&o));
        assert!(summary_warnings(&out).iter().any(|w| w.contains(said)), "{flags:?}: {:?}", summary_warnings(&out));
        let image = restir_vpl::output::read_exr(&out.join("final.exr")).unwrap();
        assert!(image.pixels.iter().flatten().all(|v| v.is_finite()), "{flags:?}: a non-finite pixel");
    }
    // A scene without emitters: black, with the power source too, and no word of a photon
    // shortfall (the photon pass traced no path; the scene's own warning says why).
    let mut doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell_box.gltf")).unwrap()).unwrap();
    for m in doc["materials"].as_array_mut().unwrap() {
        m.as_object_mut().unwrap().remove("emissiveFactor");
    }
    let dark = write(dir.path(), "dark.gltf", &doc.to_string());
    let out = dir.path().join("dark");
    let o = run(&[&small[..], &["--mode", "restir", "--candidate-source", "power", "--scene", &dark, "--out", out.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let w = summary_warnings(&out);
    assert!(w.iter().any(|w| w.contains("the scene has no emitters")) && w.iter().any(|w| w.contains("carry no power")), "{w:?}");
    assert!(!stderr(&o).contains("--vpls-indirect"), "{}", stderr(&o));
    let image = restir_vpl::output::read_exr(&out.join("final.exr")).unwrap();
    assert!(image.pixels.iter().flatten().all(|&v| v == 0.0), "a scene without emitters renders black");
    // --check-finite keeps fusable pairs apart, and says so only where a pair would have fused.
    for (flags, apart) in [(&["--mode", "restir"][..], true), (&["--mode", "restir", "--temporal", "off", "--spatial-passes", "0"][..], false), (&["--mode", "restir", "--view", "vpls"][..], false), (&["--mode", "ris"][..], false)] {
        let out = dir.path().join("apart");
        let o = run(&[&small[..], flags, &["--check-finite", "--out", out.to_str().unwrap()]].concat());
        assert!(o.status.success(), "{flags:?}: {}", stderr(&o));
        assert_eq!(stderr(&o).contains("ran their passes apart"), apart, "{flags:?}: {}", stderr(&o));
    }
}
