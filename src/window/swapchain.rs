//! The window's swapchain: created for the surface's current size, recreated as a unit on resize,
//! and the blit that puts the renderer's preview on screen.

use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use ash::vk;

use crate::settings::PresentMode;
use crate::vk::Context;

/// The surface has no area (a window being minimised): the caller waits and tries again.
#[derive(Debug, thiserror::Error)]
#[error("the window has no area (minimised)")]
pub struct NoArea;

fn vk_present_mode(mode: PresentMode) -> vk::PresentModeKHR {
    match mode {
        PresentMode::Fifo => vk::PresentModeKHR::FIFO,
        PresentMode::Mailbox => vk::PresentModeKHR::MAILBOX,
        PresentMode::Immediate => vk::PresentModeKHR::IMMEDIATE,
    }
}

pub struct Swapchain {
    ctx: Arc<Context>,
    pub raw: vk::SwapchainKHR,
    pub format: vk::SurfaceFormatKHR,
    pub extent: vk::Extent2D,
    pub images: Vec<vk::Image>,
    pub views: Vec<vk::ImageView>,
    /// The present mode it uses: the one asked for, or fifo where the surface lacks it (the
    /// summary's `displayed.present_mode` says this one, not the request).
    pub mode: PresentMode,
    /// Signalled when presentation is done with image i (one per image, so a semaphore is never
    /// reused while a present still waits on it).
    pub render_finished: Vec<vk::Semaphore>,
}

impl Swapchain {
    /// A swapchain of `wanted` size (the surface's current extent wins where it is fixed),
    /// replacing `old` if given.
    pub fn new(ctx: &Arc<Context>, wanted: vk::Extent2D, mode: PresentMode, old: Option<&Swapchain>) -> Result<Self> {
        let p = ctx.presentation.as_ref().context("the context was made without a window")?;
        let pd = ctx.physical_device;
        // SAFETY: surface and physical device belong to this context's instance.
        let (caps, formats, modes) = unsafe {
            (
                p.surface_loader.get_physical_device_surface_capabilities(pd, p.surface)?,
                p.surface_loader.get_physical_device_surface_formats(pd, p.surface)?,
                p.surface_loader.get_physical_device_surface_present_modes(pd, p.surface)?,
            )
        };
        // The preview is already sRGB-encoded: a UNORM target shows it as is (the blit from an
        // sRGB-typed staging image into an sRGB target is the identity too).
        let preferred = [vk::Format::B8G8R8A8_UNORM, vk::Format::R8G8B8A8_UNORM, vk::Format::B8G8R8A8_SRGB, vk::Format::R8G8B8A8_SRGB];
        let format = preferred
            .iter()
            .find_map(|f| formats.iter().find(|s| s.format == *f).copied())
            .or_else(|| formats.first().copied())
            .context("the surface offers no formats")?;
        let mode = if modes.contains(&vk_present_mode(mode)) {
            mode
        } else {
            log::warn!("--present-mode {}: not offered by this surface; using fifo", mode.name());
            PresentMode::Fifo
        };
        let present_mode = vk_present_mode(mode);
        let extent = if caps.current_extent.width != u32::MAX {
            caps.current_extent
        } else {
            vk::Extent2D {
                width: wanted.width.clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                height: wanted.height.clamp(caps.min_image_extent.height, caps.max_image_extent.height),
            }
        };
        if extent.width == 0 || extent.height == 0 {
            return Err(NoArea.into());
        }
        let mut count = caps.min_image_count + 1;
        if caps.max_image_count > 0 {
            count = count.min(caps.max_image_count);
        }
        if !caps.supported_usage_flags.contains(vk::ImageUsageFlags::TRANSFER_DST) {
            bail!("the surface's images cannot be transfer destinations; cannot show the preview");
        }
        // The preview is blitted into the swapchain image: its format must take blits.
        // SAFETY: valid physical device.
        let format_props = unsafe { ctx.instance.get_physical_device_format_properties(pd, format.format) };
        if !format_props.optimal_tiling_features.contains(vk::FormatFeatureFlags::BLIT_DST) {
            bail!("the surface's format {:?} cannot be a blit destination; cannot show the preview", format.format);
        }
        // Opaque where offered (every desktop driver seen); otherwise the first mode the surface has.
        let composite_alpha = [
            vk::CompositeAlphaFlagsKHR::OPAQUE,
            vk::CompositeAlphaFlagsKHR::INHERIT,
            vk::CompositeAlphaFlagsKHR::PRE_MULTIPLIED,
            vk::CompositeAlphaFlagsKHR::POST_MULTIPLIED,
        ]
        .into_iter()
        .find(|m| caps.supported_composite_alpha.contains(*m))
        .context("the surface offers no composite alpha mode")?;
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(p.surface)
            .min_image_count(count)
            .image_format(format.format)
            .image_color_space(format.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::COLOR_ATTACHMENT)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(composite_alpha)
            .present_mode(present_mode)
            .clipped(true)
            .old_swapchain(old.map(|o| o.raw).unwrap_or_default());
        // SAFETY: valid device and surface; the old swapchain (if any) is retired by this call.
        let raw = unsafe { p.swapchain_loader.create_swapchain(&info, None) }.context("vkCreateSwapchainKHR")?;
        ctx.set_name(raw, "swapchain");
        // Owned from here, so that a failure below destroys what was made (Drop): a leaked
        // swapchain outlived its surface, which vkDestroySurfaceKHR forbids.
        let mut made = Self { ctx: ctx.clone(), raw, format, extent, images: Vec::new(), views: Vec::new(), mode, render_finished: Vec::new() };
        // SAFETY: the swapchain was just created.
        made.images = unsafe { p.swapchain_loader.get_swapchain_images(raw) }?;
        let images = made.images.clone();
        for (i, image) in images.iter().enumerate() {
            ctx.set_name(*image, &format!("swapchain.image{i}"));
            let view_info = vk::ImageViewCreateInfo::default()
                .image(*image)
                .view_type(vk::ImageViewType::TYPE_2D)
                .format(format.format)
                .subresource_range(color_range());
            // SAFETY: the image belongs to the swapchain.
            let view = unsafe { ctx.device.create_image_view(&view_info, None) }?;
            ctx.set_name(view, &format!("swapchain.view{i}"));
            made.views.push(view);
            // SAFETY: valid device.
            let sem = unsafe { ctx.device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None) }?;
            ctx.set_name(sem, &format!("swapchain.render_finished{i}"));
            made.render_finished.push(sem);
        }
        log::info!(
            "swapchain: {}x{} {:?} {:?}, {} images, {:?}",
            extent.width,
            extent.height,
            format.format,
            format.color_space,
            images.len(),
            present_mode
        );
        Ok(made)
    }
}

impl Drop for Swapchain {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a submission that did not finish may still use it (Context::wait_fence)
        }
        let p = self.ctx.presentation.as_ref().expect("a swapchain implies a presentation");
        // SAFETY: the window waits for the device to be idle before dropping a swapchain.
        unsafe {
            for v in &self.views {
                self.ctx.device.destroy_image_view(*v, None);
            }
            for s in &self.render_finished {
                self.ctx.device.destroy_semaphore(*s, None);
            }
            p.swapchain_loader.destroy_swapchain(self.raw, None);
        }
    }
}

pub fn color_range() -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange::default().aspect_mask(vk::ImageAspectFlags::COLOR).level_count(1).layer_count(1)
}
