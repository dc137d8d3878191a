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
    if !validate() {
        common::skip("no validation layer installed (CI requires one)");
        return None;
    }
    Some(context())
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
