//! Named 2-D images (the window's staging image), allocated like [`super::Buffer`]: the same name in
//! gpu-allocator and in VK_EXT_debug_utils.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;
use gpu_allocator::vulkan::Allocation;
use gpu_allocator::MemoryLocation;

use super::Context;

pub struct Image {
    ctx: Arc<Context>,
    pub raw: vk::Image,
    allocation: Option<Allocation>,
    pub extent: vk::Extent2D,
    pub format: vk::Format,
    pub name: String,
}

impl Image {
    /// A device-local, optimally tiled 2-D image with one mip level.
    pub fn new(ctx: &Arc<Context>, name: &str, extent: vk::Extent2D, format: vk::Format, usage: vk::ImageUsageFlags) -> Result<Self> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D { width: extent.width.max(1), height: extent.height.max(1), depth: 1 })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let device = &ctx.device;
        // SAFETY: valid device and create info.
        let raw = unsafe { device.create_image(&info, None) }.with_context(|| format!("vkCreateImage '{name}'"))?;
        // SAFETY: raw was just created.
        let requirements = unsafe { device.get_image_memory_requirements(raw) };
        let allocation = ctx.allocate_bound(
            name,
            requirements,
            MemoryLocation::GpuOnly,
            false,
            // SAFETY: memory comes from the allocator for this image's requirements.
            |a| unsafe { device.bind_image_memory(raw, a.memory(), a.offset()) },
            // SAFETY: raw was just created and is used by nothing.
            || unsafe { device.destroy_image(raw, None) },
        )?;
        ctx.set_name(raw, name);
        Ok(Self { ctx: ctx.clone(), raw, allocation: Some(allocation), extent, format, name: name.to_string() })
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a submission that did not finish may still use it (Context::wait_fence)
        }
        // SAFETY: the owner guarantees no pending GPU work uses this image.
        unsafe { self.ctx.device.destroy_image(self.raw, None) };
        if let Some(a) = self.allocation.take() {
            self.ctx.free(a);
        }
    }
}

/// Records an image layout transition with a full-pipeline dependency (simple and correct; the
/// window records two per frame).
pub fn transition(ctx: &Context, cmd: vk::CommandBuffer, image: vk::Image, from: vk::ImageLayout, to: vk::ImageLayout) {
    let barrier = [vk::ImageMemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::MEMORY_WRITE)
        .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE)
        .old_layout(from)
        .new_layout(to)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(
            vk::ImageSubresourceRange::default().aspect_mask(vk::ImageAspectFlags::COLOR).level_count(1).layer_count(1),
        )];
    // SAFETY: cmd is recording; the image is alive for the command buffer's lifetime.
    unsafe {
        ctx.device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::ALL_COMMANDS,
            vk::PipelineStageFlags::ALL_COMMANDS,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &barrier,
        )
    };
}
