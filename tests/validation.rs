//! The validation layer's positive control: every GPU test asserts "0 validation errors", which
//! proves nothing unless an error is actually counted. A deliberately invalid command must raise
//! the count (where the layer is installed; CI requires it, see `common::validate`).

mod common;

use ash::vk;
use common::*;
use gpu_allocator::MemoryLocation;
use restir_vpl::vk::Buffer;

/// A context under the validation layer, or None (said) where the layer is not installed (CI
/// requires it: `common::validate`).
fn validated_context() -> Option<std::sync::Arc<restir_vpl::vk::Context>> {
    validation_or_skip().then(context)
}

#[test]
fn an_invalid_command_is_counted_as_a_validation_error() {
    let Some(ctx) = validated_context() else { return };
    assert_eq!(ctx.validation_errors(), 0, "a fresh context has no errors: {:?}", ctx.first_validation_error());
    // vkCmdFillBuffer on a buffer created without TRANSFER_DST usage
    // (VUID-vkCmdFillBuffer-dstBuffer-00029); drivers ignore usage flags, so it is harmless.
    let buffer = Buffer::new(&ctx, "validation_control", 256, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuOnly).unwrap();
    // SAFETY: cmd is recording; the buffer outlives the one-shot submission.
    ctx.one_shot(|cmd| unsafe { ctx.device.cmd_fill_buffer(cmd, buffer.raw, 0, 256, 0) }).unwrap();
    assert!(ctx.validation_errors() >= 1, "the invalid fill was not reported: the validation messenger does not count errors");
    let first = ctx.first_validation_error().unwrap_or_default();
    assert!(first.contains("00029") || first.contains("TRANSFER_DST"), "an unexpected first error: {first}");
}

/// Synchronization validation is on: a missing barrier (a buffer filled, then copied from, with no
/// dependency between the two) is counted as an error, so the suite's "0 errors" also means no
/// hazard between passes (which lavapipe's in-order queue forgives and a GPU does not).
#[test]
fn a_missing_barrier_is_counted_as_a_hazard() {
    let Some(ctx) = validated_context() else { return };
    assert_eq!(ctx.validation_errors(), 0, "a fresh context has no errors: {:?}", ctx.first_validation_error());
    let usage = vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST;
    let a = Buffer::new(&ctx, "hazard_a", 256, usage, MemoryLocation::GpuOnly).unwrap();
    let b = Buffer::new(&ctx, "hazard_b", 256, usage, MemoryLocation::GpuOnly).unwrap();
    // SAFETY: cmd is recording; both buffers outlive the one-shot submission.
    ctx.one_shot(|cmd| unsafe {
        ctx.device.cmd_fill_buffer(cmd, a.raw, 0, 256, 7);
        ctx.device.cmd_copy_buffer(cmd, a.raw, b.raw, &[vk::BufferCopy::default().size(256)]);
    })
    .unwrap();
    assert!(ctx.validation_errors() >= 1, "the unsynchronised copy was not reported: synchronization validation is off");
    let first = ctx.first_validation_error().unwrap_or_default();
    assert!(first.contains("SYNC-HAZARD-READ-AFTER-WRITE"), "an unexpected first error: {first}");
}

/// A callback that counts nothing: the leaked messenger below must not be what reports its own
/// leak.
unsafe extern "system" fn ignore_messages(
    _: vk::DebugUtilsMessageSeverityFlagsEXT,
    _: vk::DebugUtilsMessageTypeFlagsEXT,
    _: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _: *mut std::ffi::c_void,
) -> vk::Bool32 {
    vk::FALSE
}

/// vkDestroyInstance's own messages are counted: the context's messenger is gone by then, so
/// they reach only the one chained into vkCreateInstance. A messenger left alive (reporting to a
/// callback that counts nothing) must be reported as a leak when the context is dropped.
#[test]
fn an_object_left_at_vk_destroy_instance_is_counted() {
    let Some(ctx) = validated_context() else { return };
    let counter = ctx.validation_counter();
    let loader = ash::ext::debug_utils::Instance::new(&ctx.entry, &ctx.instance);
    let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR)
        .message_type(vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION)
        .pfn_user_callback(Some(ignore_messages));
    // SAFETY: a valid instance; the messenger is left alive on purpose, until the instance goes.
    let _leaked = unsafe { loader.create_debug_utils_messenger(&info, None) }.expect("a messenger");
    assert_eq!(counter.errors.load(std::sync::atomic::Ordering::SeqCst), 0);
    assert_eq!(std::sync::Arc::strong_count(&ctx), 1, "the test holds the only reference");
    drop(ctx);
    assert!(
        counter.errors.load(std::sync::atomic::Ordering::SeqCst) >= 1,
        "the messenger left at vkDestroyInstance was not reported: the instance's own messages are not counted"
    );
}

/// A renderer's whole life, teardown included, leaves no object alive and draws no message (also
/// through settings changes, a spawned light and a photon retrace, which replace objects): the
/// checks every run makes come before its context is dropped, and vkDestroyDevice and
/// vkDestroyInstance report what was left (buffers, pipelines, descriptor pools, ...) only then.
#[test]
fn a_render_leaves_nothing_alive_at_teardown() {
    let Some(ctx) = validated_context() else { return };
    let counter = ctx.validation_counter();
    let scene = restir_vpl::scene::Scene::load(&repo_path("scenes/cornell_box.gltf")).expect("the bundled scene loads");
    use restir_vpl::settings::Mode;
    let settings = |mode, size| restir_vpl::RenderSettings { mode, vpls_direct: 2000, vpls_indirect: 2000, ..small(size, size, 2) };
    render_on(&ctx, &scene, &settings(Mode::Restir, 32));
    // One renderer through what replaces its objects: settings (mode and size) changed, a light
    // spawned (the VPL set traced again), the photons retraced.
    let gpu = upload(&ctx, &scene, &settings(Mode::Restir, 32));
    let mut r = restir_vpl::renderer::Renderer::new(ctx.clone(), gpu, settings(Mode::Restir, 32)).unwrap();
    let camera = r.initial_camera();
    for (mode, size) in [(Mode::Restir, 32), (Mode::Uniform, 40), (Mode::Pt, 24), (Mode::Ris, 32), (Mode::Restir, 32)] {
        r.apply_settings(settings(mode, size)).unwrap();
        r.render_frame(&camera, false).unwrap();
    }
    let light = restir_vpl::lights::PointEmitter { position: glam::Vec3::new(0.0, 1.0, 0.0), intensity: glam::Vec3::splat(1.0) };
    r.set_extra_lights(vec![light]).unwrap();
    r.render_frame(&camera, false).unwrap();
    r.retrace_photons().unwrap();
    r.render_frame(&camera, false).unwrap();
    r.complete_all().unwrap();
    assert_no_validation_errors(&ctx);
    drop(r);
    assert_eq!(std::sync::Arc::strong_count(&ctx), 1, "the test holds the only reference");
    drop(ctx);
    assert_eq!(
        counter.errors.load(std::sync::atomic::Ordering::SeqCst),
        0,
        "the teardown drew validation errors (objects left alive?); first: {:?}",
        counter.first_error.lock().unwrap()
    );
}

/// A buffer larger than the device allocates at once is refused, naming it and the limit, before
/// anything is made or copied (lavapipe crashed in its copy of a 2.2 GB vertex buffer, which a
/// 704-byte glTF with a sparse accessor of 68M vertices asked for).
#[test]
fn a_buffer_beyond_the_allocation_limit_is_refused_by_name() {
    let ctx = context();
    assert!(ctx.max_allocation >= 1 << 30, "maxMemoryAllocationSize read as {}", ctx.max_allocation);
    let e = Buffer::new(&ctx, "too_large", ctx.max_allocation + 1, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuOnly)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("'too_large'") && e.contains("maxMemoryAllocationSize"), "{e}");
    assert_no_validation_errors(&ctx);
}
