//! Shared helpers for the GPU tests: render in-process under the validation layer (where installed)
//! and check the invariants every run must keep.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use restir_vpl::headless::{run_with, RunOutput};
use restir_vpl::scene::Scene;
use restir_vpl::scene_gpu::SceneGpu;
use restir_vpl::vk::context::validation_layer_available;
use restir_vpl::vk::{Context, ContextOptions};
use restir_vpl::RenderSettings;

pub fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// The validation layer is on in tests wherever it is installed; under CI (`CI=true`, what
/// `.ci/run` sets) a missing layer is an error, since every "0 validation errors" would then hold
/// whatever the code does (the set-up step installs it). Elsewhere its absence is said loudly,
/// once per test binary.
pub fn validate() -> bool {
    let available = validation_layer_available();
    assert!(
        available || std::env::var("CI").as_deref() != Ok("true"),
        "CI=true but the Khronos validation layer is not installed (scripts/setup.sh --test installs it)"
    );
    if !available {
        static SAID: std::sync::Once = std::sync::Once::new();
        SAID.call_once(|| {
            skip("the Khronos validation layer is not installed: this binary's tests check no validation errors (scripts/setup.sh --test installs it)");
        });
    }
    available
}

/// [`validate`] for a test that checks the validation layer itself: false, with the test's skip
/// said, where no layer is installed (the caller returns).
pub fn validation_or_skip() -> bool {
    validate() || {
        skip("no validation layer installed (CI requires one)");
        false
    }
}

/// Says that a test (or a part of it) was skipped, where it cannot be missed: straight to the
/// process's stderr (the test harness captures `eprintln!` and shows it only for failing tests,
/// so a skipped test looked like a pass) and into `test-skips.txt` under cargo's target tmp
/// directory, which `scripts/test.sh` empties before the run and prints after it. Under CI a
/// missing prerequisite is a failure instead (each caller asserts that first).
pub fn skip(msg: &str) {
    use std::io::Write;
    let test = std::thread::current().name().unwrap_or("?").to_string();
    let line = format!("SKIPPED {test}: {msg}");
    let _ = writeln!(std::io::stderr().lock(), "\n*** {line} ***\n");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let _ = std::fs::create_dir_all(dir);
    if let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(dir.join("test-skips.txt")) {
        // One write per line: tests skip from parallel threads, and O_APPEND keeps each write whole.
        let _ = f.write_all(format!("{line}\n").as_bytes());
    }
}

pub fn context() -> Arc<Context> {
    context_tracing(None)
}

/// A context that traces rays `tracing`'s way (None: as `RESTIR_VPL_TRACE` says, else the device's best).
pub fn context_tracing(tracing: Option<restir_vpl::vk::context::Tracing>) -> Arc<Context> {
    report_crashes();
    Arc::new(Context::new(&ContextOptions { validate: validate(), tracing, ..Default::default() }).expect("a device that traces rays"))
}

/// With `RESTIR_VPL_CRASH_STACKS=1` (what `scripts/gpu-tests.sh` sets), a test binary killed by
/// SIGSEGV, SIGBUS, SIGILL or SIGFPE first prints the faulting thread's name and stack to the
/// process's stderr (past the harness's capture, which a dying process never prints; with the
/// symbol tables `scripts/gpu-pack.sh` keeps): on an H100 a test binary once died of a
/// segmentation fault with nothing else printed. Off by default: the handler replaces the one
/// the Rust runtime uses to name a stack overflow (which this one, on the overflowed stack,
/// cannot report), and it allocates and takes locks, which a handler should not (an alarm kills
/// the process if that hangs). It runs once, then the default action kills as before.
fn report_crashes() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    fn write_stderr(text: &str) {
        // SAFETY: write(2) on fd 2 with a valid buffer is async-signal-safe.
        unsafe { libc::write(2, text.as_ptr().cast(), text.len()) };
    }
    extern "C" fn on_fault(sig: libc::c_int) {
        // SAFETY: alarm is async-signal-safe; SIGALRM's default action ends the process if the
        // stack below never comes (a fault inside malloc leaves its lock held).
        unsafe { libc::alarm(10) };
        let name = match sig {
            libc::SIGSEGV => "SIGSEGV",
            libc::SIGBUS => "SIGBUS",
            libc::SIGILL => "SIGILL",
            _ => "SIGFPE",
        };
        write_stderr(&format!("\n*** {name}"));
        let thread = std::thread::current().name().unwrap_or("(unnamed)").to_string();
        let trace = std::backtrace::Backtrace::force_capture();
        write_stderr(&format!(" in thread {thread}; its stack:\n{trace}\n"));
        // SA_RESETHAND restored the default action, which this kills with (as a fault repeated
        // on return would).
        // SAFETY: raising a signal is async-signal-safe.
        unsafe { libc::raise(sig) };
    }
    if std::env::var("RESTIR_VPL_CRASH_STACKS").as_deref() != Ok("1") {
        return;
    }
    ONCE.call_once(|| {
        for sig in [libc::SIGSEGV, libc::SIGBUS, libc::SIGILL, libc::SIGFPE] {
            // SAFETY: a zeroed sigaction with a handler, an empty mask and these flags is valid.
            // Not SA_ONSTACK: symbolising the stack overflows the small alternate stack the Rust
            // runtime gives each thread.
            unsafe {
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = on_fault as extern "C" fn(libc::c_int) as libc::sighandler_t;
                action.sa_flags = libc::SA_RESETHAND;
                libc::sigemptyset(&mut action.sa_mask);
                libc::sigaction(sig, &action, std::ptr::null_mut());
            }
        }
    });
}

/// Uploads `scene` to `ctx` (textures as `settings` says).
pub fn upload(ctx: &Arc<Context>, scene: &Scene, settings: &RenderSettings) -> Arc<SceneGpu> {
    Arc::new(SceneGpu::new(ctx, scene, settings.textures, settings.merge_blas).expect("scene uploads"))
}

/// Renders `scene` with `settings`; asserts no validation errors and finite output.
pub fn render(scene: &Scene, settings: &RenderSettings) -> RunOutput {
    render_on(&context(), scene, settings)
}

/// [`render`] on a given context.
pub fn render_on(ctx: &Arc<Context>, scene: &Scene, settings: &RenderSettings) -> RunOutput {
    let gpu = upload(ctx, scene, settings);
    let out = run_with(ctx.clone(), gpu, settings, Instant::now()).expect("render succeeds");
    assert_no_validation_errors(ctx);
    assert_all_finite(&out.mean, "mean image");
    assert_eq!(out.summary.nonfinite_samples, 0, "non-finite samples were produced");
    out
}

/// No validation-layer error on `ctx` so far (the first one is in the failure message), and no
/// non-finite sample in any frame a renderer on `ctx` has completed (the accumulation replaces
/// them by 0, so a finite image alone proves nothing).
pub fn assert_no_validation_errors(ctx: &Context) {
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors; first: {:?}", ctx.first_validation_error());
    assert_eq!(ctx.nonfinite_samples(), 0, "renderers on this context produced non-finite samples (replaced by 0)");
}

/// What a subprocess run's summary.json must say (`what` names the run): the validation layer was
/// loaded exactly where the tests expect it (so its "0 errors" means something), no validation
/// error, and no non-finite sample (the accumulation turns them into zeros, so a finite image
/// alone proves nothing).
pub fn assert_clean_summary(s: &serde_json::Value, what: &str) {
    assert_eq!(s["validation_layer"], validate(), "{what}: the validation layer was {} in the run: {s}", if validate() { "not loaded" } else { "loaded" });
    assert_eq!(s["validation_errors"], 0, "{what}: validation errors: {s}");
    assert_eq!(s["nonfinite_samples"], 0, "{what}: non-finite samples: {s}");
}

/// No non-finite sample in any frame `r` has completed (the accumulation turns them into zeros,
/// so a finite image does not show them; `what` names the case).
pub fn assert_no_nonfinite_samples(r: &restir_vpl::renderer::Renderer, what: &str) {
    assert_eq!(r.nonfinite_samples_total(), 0, "{what}: non-finite samples");
}

pub fn load_json(json: &str, label: &str) -> Scene {
    Scene::from_gltf_slice(json.as_bytes(), None, label).expect("test scene loads")
}

pub fn small(width: u32, height: u32, frames: u32) -> RenderSettings {
    RenderSettings { width, height, frames, validate: validate(), ..Default::default() }
}

pub fn assert_all_finite(pixels: &[[f32; 3]], what: &str) {
    for (i, p) in pixels.iter().enumerate() {
        assert!(p.iter().all(|c| c.is_finite()), "{what}: pixel {i} is not finite: {p:?}");
    }
}

/// Mean over pixels of channel-averaged values, and its standard error from the per-pixel sample
/// variances (pixels are independent; each pixel mean averages `frames` iid samples).
pub fn image_mean_and_se(out: &RunOutput, frames: u32, pixels: impl Iterator<Item = usize> + Clone) -> (f64, f64) {
    let n = pixels.clone().count() as f64;
    let mean: f64 = pixels.clone().map(|i| out.mean[i].iter().map(|&c| c as f64).sum::<f64>() / 3.0).sum::<f64>() / n;
    // Channel average of a pixel has variance <= mean of channel variances (Cauchy-Schwarz); we use
    // that bound, which makes the test conservative.
    let var_sum: f64 = pixels.map(|i| out.variance[i].iter().map(|&c| c as f64).sum::<f64>() / 3.0).sum();
    let se = (var_sum / frames as f64).sqrt() / n;
    (mean, se)
}

/// Möller–Trumbore distance along a ray from `o` in direction `d`, or None (edges count as hits
/// within 1e-6 in barycentrics).
pub fn ray_triangle(o: glam::Vec3, d: glam::Vec3, t: [glam::Vec3; 3]) -> Option<f32> {
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let s = o - t[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let dist = e2.dot(q) / det;
    (u >= -1e-6 && v >= -1e-6 && u + v <= 1.0 + 1e-6 && dist >= 0.0).then_some(dist)
}

/// Every instanced triangle of `scene` in world space.
pub fn world_triangles(scene: &Scene) -> Vec<[glam::Vec3; 3]> {
    let mut out = Vec::new();
    for inst in &scene.instances {
        let m = &scene.meshes[inst.mesh];
        for t in 0..m.triangle_count() {
            let tri = m.triangle(t).unwrap();
            out.push(tri.map(|p| inst.transform.transform_point3(p)));
        }
    }
    out
}

/// Keeps images a failing check compared, as EXR files in `RESTIR_VPL_TEST_ARTIFACTS/<what>/`
/// (default `target/test-artifacts/<what>/`), so that a failure on a machine one cannot look at
/// (a lent GPU, CI) can be looked at afterwards; the path goes to stderr. A file that cannot be
/// written is said and skipped: the check's own failure is what the test reports.
pub fn keep_images(what: &str, images: &[(&str, &restir_vpl::output::RgbImage)]) {
    let root = std::env::var_os("RESTIR_VPL_TEST_ARTIFACTS").map(PathBuf::from).unwrap_or_else(|| repo_path("target/test-artifacts"));
    let dir = root.join(what.replace(|c: char| !c.is_ascii_alphanumeric() && c != '-' && c != '.', "_"));
    if let Err(e) = std::fs::create_dir_all(&dir) {
        eprintln!("keep_images: cannot create {}: {e}", dir.display());
        return;
    }
    for (name, img) in images {
        let path = dir.join(format!("{name}.exr"));
        match restir_vpl::output::write_exr(&path, img.width, img.height, &img.pixels) {
            Ok(()) => eprintln!("kept {}", path.display()),
            Err(e) => eprintln!("keep_images: cannot write {}: {e:#}", path.display()),
        }
    }
}
