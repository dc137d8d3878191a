//! Named GPU buffers. Every buffer carries the same name in gpu-allocator and in VK_EXT_debug_utils,
//! so captures read like the source.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;
use gpu_allocator::vulkan::Allocation;
use gpu_allocator::MemoryLocation;

use super::Context;

/// How a buffer's texel view reads it: the Vulkan format and one texel's size in bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TexelFormat {
    pub format: vk::Format,
    pub bytes: u64,
}

pub struct Buffer {
    ctx: Arc<Context>,
    pub raw: vk::Buffer,
    allocation: Option<Allocation>,
    pub size: u64,
    pub name: String,
    pub address: Option<vk::DeviceAddress>,
    /// A view of the whole buffer as texels (`with_texel_view`), for texel-buffer bindings.
    pub texel_view: Option<vk::BufferView>,
}

/// The texels of `format` in a buffer of `size` bytes named `name`, if the device's
/// maxTexelBufferElements allows a view of them all.
fn check_texels(ctx: &Context, name: &str, size: u64, format: TexelFormat) -> Result<u64> {
    let texels = size / format.bytes;
    let limit = u64::from(ctx.properties.limits.max_texel_buffer_elements);
    anyhow::ensure!(texels <= limit, "buffer '{name}' holds {texels} texels, more than this device's maxTexelBufferElements ({limit})");
    Ok(texels)
}

impl Buffer {
    /// Creates a buffer named `name`. Refused, before anything is made, when it is larger than
    /// the device allocates at once. `size` 0 is rounded up to 16 bytes (Vulkan forbids empty
    /// buffers; an empty scene array still needs a binding).
    pub fn new(
        ctx: &Arc<Context>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self> {
        let size = size.max(16);
        anyhow::ensure!(
            ctx.max_allocation == 0 || size <= ctx.max_allocation,
            "buffer '{name}' needs {:.2} GiB, more than this device allocates at once (maxMemoryAllocationSize {:.2} GiB)",
            size as f64 / (1u64 << 30) as f64,
            ctx.max_allocation as f64 / (1u64 << 30) as f64
        );
        let info = vk::BufferCreateInfo::default().size(size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        let device = &ctx.device;
        // SAFETY: valid device and create info.
        let raw = unsafe { device.create_buffer(&info, None) }.with_context(|| format!("vkCreateBuffer '{name}'"))?;
        // SAFETY: raw was just created.
        let requirements = unsafe { device.get_buffer_memory_requirements(raw) };
        let allocation = ctx.allocate_bound(
            name,
            requirements,
            location,
            true,
            // SAFETY: memory comes from the allocator for this buffer's requirements.
            |a| unsafe { device.bind_buffer_memory(raw, a.memory(), a.offset()) },
            // SAFETY: raw was just created and is used by nothing.
            || unsafe { device.destroy_buffer(raw, None) },
        )?;
        ctx.set_name(raw, name);
        let address = usage.contains(vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS).then(|| {
            // SAFETY: the buffer has SHADER_DEVICE_ADDRESS usage and bound memory.
            unsafe { device.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(raw)) }
        });
        Ok(Self { ctx: ctx.clone(), raw, allocation: Some(allocation), size, name: name.to_string(), address, texel_view: None })
    }

    /// A device-local buffer filled with `data` and read as texels of `texels` (`with_data` with
    /// UNIFORM_TEXEL_BUFFER added to `usage`, then `with_texel_view`).
    /// The texel count is checked before anything is made or copied.
    pub fn with_texel_data(ctx: &Arc<Context>, name: &str, data: &[u8], texels: TexelFormat, usage: vk::BufferUsageFlags) -> Result<Self> {
        check_texels(ctx, name, (data.len() as u64).max(16), texels)?;
        Self::with_data(ctx, name, data, usage | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER)?.with_texel_view(texels)
    }

    /// Adds a view of the whole buffer as texels of `texels` (the buffer needs UNIFORM_ or
    /// STORAGE_TEXEL_BUFFER usage), named as the buffer. Fails when the device's
    /// maxTexelBufferElements is below the buffer's texel count.
    pub fn with_texel_view(mut self, texels_format: TexelFormat) -> Result<Self> {
        let TexelFormat { format, bytes: texel_bytes } = texels_format;
        let texels = check_texels(&self.ctx, &self.name, self.size, texels_format)?;
        let info = vk::BufferViewCreateInfo::default().buffer(self.raw).format(format).offset(0).range(texels * texel_bytes);
        // SAFETY: the buffer is alive, was created with texel-buffer usage by the caller, and the
        // range lies inside it.
        let view = unsafe { self.ctx.device.create_buffer_view(&info, None) }
            .with_context(|| format!("vkCreateBufferView '{}'", self.name))?;
        self.ctx.set_name(view, &self.name);
        self.texel_view = Some(view);
        Ok(self)
    }

    /// A device-local buffer filled with `data` through a staging copy.
    pub fn with_data(ctx: &Arc<Context>, name: &str, data: &[u8], usage: vk::BufferUsageFlags) -> Result<Self> {
        let buffer = Self::new(ctx, name, data.len() as u64, usage | vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuOnly)?;
        buffer.upload(0, data)?;
        Ok(buffer)
    }

    /// Copies `data` to byte `offset` of a (device-local) buffer with TRANSFER_DST usage through a
    /// staging buffer, and waits.
    pub fn upload(&self, offset: u64, data: &[u8]) -> Result<()> {
        if data.is_empty() {
            return Ok(());
        }
        anyhow::ensure!(offset + data.len() as u64 <= self.size, "upload past the end of '{}'", self.name);
        let ctx = &self.ctx;
        let staging = Self::new(
            ctx,
            &format!("{}.staging", self.name),
            data.len() as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        staging.write(0, data)?;
        let region = [vk::BufferCopy::default().dst_offset(offset).size(data.len() as u64)];
        ctx.one_shot(|cmd| {
            // SAFETY: the region lies inside both buffers (checked above), which stay alive until
            // one_shot's wait completes.
            unsafe { ctx.device.cmd_copy_buffer(cmd, staging.raw, self.raw, &region) }
        })
    }

    /// The start of a host-visible buffer's mapping.
    fn mapped_ptr(&self) -> Result<std::ptr::NonNull<std::ffi::c_void>> {
        self.allocation.as_ref().and_then(|a| a.mapped_ptr()).with_context(|| format!("buffer '{}' is not host-visible", self.name))
    }

    /// Writes bytes into a host-visible buffer.
    pub fn write(&self, offset: usize, data: &[u8]) -> Result<()> {
        let slice = self.mapped_ptr()?;
        anyhow::ensure!(offset + data.len() <= self.size as usize, "write past the end of '{}'", self.name);
        // SAFETY: the mapping covers `size` bytes (checked above) and no GPU work uses the range now
        // (callers write between fenced submissions).
        unsafe {
            std::ptr::copy_nonoverlapping(data.as_ptr(), (slice.as_ptr() as *mut u8).add(offset), data.len());
        }
        Ok(())
    }

    /// Zeroes a host-visible buffer (no allocation, unlike `write` of a zeroed vector).
    pub fn zero(&self) -> Result<()> {
        let slice = self.mapped_ptr()?;
        // SAFETY: the mapping covers `size` bytes and no GPU work uses the buffer now (callers
        // write between fenced submissions).
        unsafe { std::ptr::write_bytes(slice.as_ptr() as *mut u8, 0, self.size as usize) };
        Ok(())
    }

    /// Reads bytes from a host-visible buffer.
    pub fn read(&self, offset: usize, len: usize) -> Result<Vec<u8>> {
        let alloc = self.allocation.as_ref().with_context(|| format!("buffer '{}' is freed", self.name))?;
        let slice = alloc.mapped_slice().with_context(|| format!("buffer '{}' is not host-visible", self.name))?;
        anyhow::ensure!(offset + len <= slice.len(), "read past the end of '{}'", self.name);
        Ok(slice[offset..offset + len].to_vec())
    }

    /// Reads `count` u32 words at the start of a host-visible buffer the device may be writing now
    /// (breadcrumbs of a frame that is late: `GpuTimer::progress`), one volatile read each: a
    /// word may be stale, never torn.
    pub fn read_words_volatile(&self, count: usize) -> Result<Vec<u32>> {
        let ptr = self.mapped_ptr()?;
        anyhow::ensure!(4 * count as u64 <= self.size, "read past the end of '{}'", self.name);
        let words = ptr.as_ptr() as *const u32;
        // SAFETY: the mapping covers `size` bytes (checked above) and is 4-byte aligned (mappings
        // are at least minMemoryMapAlignment = 64-byte aligned and buffers start aligned within them).
        Ok((0..count).map(|i| unsafe { words.add(i).read_volatile() }).collect())
    }

    pub fn address(&self) -> vk::DeviceAddress {
        self.address.expect("buffer created with SHADER_DEVICE_ADDRESS usage")
    }

    pub fn descriptor(&self) -> vk::DescriptorBufferInfo {
        vk::DescriptorBufferInfo::default().buffer(self.raw).offset(0).range(vk::WHOLE_SIZE)
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a submission that did not finish may still use it (Context::wait_fence)
        }
        // SAFETY: the owner guarantees no pending GPU work uses this buffer or its view (frames are
        // fenced); the view goes first.
        unsafe {
            if let Some(view) = self.texel_view.take() {
                self.ctx.device.destroy_buffer_view(view, None);
            }
            self.ctx.device.destroy_buffer(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            self.ctx.free(a);
        }
    }
}

/// Reads a device-local buffer back to the host through a staging copy.
pub fn read_back(ctx: &Arc<Context>, src: &Buffer) -> Result<Vec<u8>> {
    let staging = Buffer::new(
        ctx,
        &format!("{}.readback", src.name),
        src.size,
        vk::BufferUsageFlags::TRANSFER_DST,
        MemoryLocation::GpuToCpu,
    )?;
    let region = [vk::BufferCopy::default().size(src.size)];
    // one_shot's submission_start_barrier makes the source's writes (earlier submissions) visible
    // to the copy, and its host_read_barrier the copy to the read below.
    // SAFETY: both buffers are alive until one_shot's wait returns.
    ctx.one_shot(|cmd| unsafe { ctx.device.cmd_copy_buffer(cmd, src.raw, staging.raw, &region) })?;
    staging.read(0, src.size as usize)
}

/// The first `count` records of type `T` in `src`, copied out of the read-back bytes (which have
/// no alignment to cast in place). An error, not a panic, when the buffer is shorter.
pub fn read_back_records<T: bytemuck::Pod>(ctx: &Arc<Context>, src: &Buffer, count: usize) -> Result<Vec<T>> {
    let bytes = read_back(ctx, src)?;
    let need = count * std::mem::size_of::<T>();
    anyhow::ensure!(
        bytes.len() >= need,
        "buffer '{}' holds {} bytes, fewer than {count} records of {} bytes",
        src.name,
        bytes.len(),
        std::mem::size_of::<T>()
    );
    Ok(bytemuck::pod_collect_to_vec(&bytes[..need]))
}
