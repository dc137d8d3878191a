//! GPU timestamp scopes: each pass is wrapped in a debug label and a pair of timestamps of the same
//! name, so a capture and the timing table read alike.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;

use gpu_allocator::MemoryLocation;

use super::{Buffer, Context};

pub struct GpuTimer {
    ctx: Arc<Context>,
    pool: vk::QueryPool,
    capacity: u32,
    used: u32,
    scopes: Vec<(&'static str, u32)>,
    /// The scopes begun and not yet ended, innermost last: (breadcrumb index, which is also the
    /// index of the name in `begun`; first query, None for one begun when the pool was full or
    /// without timestamps).
    open: Vec<(usize, Option<u32>)>,
    /// The breadcrumb of the scope ended last, until [`GpuTimer::breadcrumb`] records it.
    ended: Option<usize>,
    /// Breadcrumbs: one word per scope begun this frame (up to `max_scopes`), 0 at the start,
    /// written 1 by the device when the scope's work has finished. The host reads them while a
    /// frame is late ([`GpuTimer::progress`]) straight from mapped memory: no Vulkan call, so no
    /// driver lock a hung queue holds (lavapipe's `vkGetQueryPoolResults` waits for the queue).
    breadcrumbs: Buffer,
    /// The scopes' names in the order they were begun (their breadcrumbs' order).
    begun: Vec<&'static str>,
    period_ns: f64,
    valid: bool,
    /// The bits of a timestamp that count (timestampValidBits: 36 on some Intel GPUs, 64 here):
    /// a difference across a wrap is taken modulo 2^bits.
    mask: u64,
}

impl GpuTimer {
    /// `max_scopes`: how many scopes one frame may record.
    pub fn new(ctx: &Arc<Context>, max_scopes: u32) -> Result<Self> {
        let capacity = max_scopes * 2;
        // Before the pool, which nothing would destroy if this failed after it.
        let breadcrumbs = Buffer::new(
            ctx,
            "gpu_timer.breadcrumbs",
            4 * u64::from(max_scopes),
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(capacity);
        // SAFETY: valid device.
        let pool = unsafe { ctx.device.create_query_pool(&info, None) }.context("timestamp query pool")?;
        ctx.set_name(pool, "gpu_timer");
        // SAFETY: families exist; index validated at context creation.
        let families = unsafe { ctx.instance.get_physical_device_queue_family_properties(ctx.physical_device) };
        let bits = families[ctx.queue_family as usize].timestamp_valid_bits;
        let valid = bits > 0 && ctx.properties.limits.timestamp_period > 0.0;
        let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
        Ok(Self {
            ctx: ctx.clone(),
            pool,
            capacity,
            used: 0,
            scopes: Vec::new(),
            open: Vec::new(),
            ended: None,
            breadcrumbs,
            begun: Vec::new(),
            period_ns: ctx.properties.limits.timestamp_period as f64,
            valid,
            mask,
        })
    }

    /// Resets the pool and the breadcrumbs at the start of a frame's command buffer (the slot's
    /// previous frame has completed).
    pub fn reset(&mut self, cmd: vk::CommandBuffer) {
        // SAFETY: cmd is recording; the pool is not in use by pending work (frames are fenced).
        unsafe { self.ctx.device.cmd_reset_query_pool(cmd, self.pool, 0, self.capacity) };
        self.used = 0;
        self.scopes.clear();
        self.open.clear();
        self.ended = None;
        self.begun.clear();
        self.breadcrumbs.zero().expect("the breadcrumbs are host-visible (GpuToCpu)");
    }

    /// Opens a debug label and a timestamp scope named `name`.
    pub fn begin(&mut self, cmd: vk::CommandBuffer, name: &'static str) {
        self.ctx.begin_label(cmd, name);
        let crumb = self.begun.len();
        self.begun.push(name);
        // No timestamps where the queue has none (VUID-vkCmdWriteTimestamp-timestampValidBits-00829).
        if self.valid && self.used + 2 <= self.capacity {
            // SAFETY: query index within the pool.
            // BOTTOM_OF_PIPE, not TOP_OF_PIPE: a timestamp's first scope is the stage it names, so
            // at the top of the pipe it waits for nothing and may be written while the pass before
            // is still running (the barrier between them does not cover it), counting that pass's
            // tail twice. At the bottom it is written once all earlier work has finished.
            unsafe { self.ctx.device.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.pool, self.used) };
            self.open.push((crumb, Some(self.used)));
            self.used += 2;
        } else {
            self.open.push((crumb, None));
        }
    }

    /// Closes the innermost open scope (its end timestamp). Its breadcrumb follows with
    /// [`GpuTimer::breadcrumb`].
    pub fn end(&mut self, cmd: vk::CommandBuffer) {
        if let Some((crumb, query)) = self.open.pop() {
            if let Some(q) = query {
                // SAFETY: query index within the pool.
                unsafe { self.ctx.device.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.pool, q + 1) };
                self.scopes.push((self.begun[crumb], q));
            }
            self.ended = Some(crumb);
        }
        self.ctx.end_label(cmd);
    }

    /// Records the breadcrumb of the scope ended last: a 4-byte fill the device performs once the
    /// work before it is done, made available to the host by a transfer→host barrier (which holds
    /// up no later device work). The caller records it after a barrier that orders that work
    /// before the TRANSFER stage (the frame's `compute_barrier` after each pass does); a scope
    /// without one keeps no breadcrumb.
    pub fn breadcrumb(&mut self, cmd: vk::CommandBuffer) {
        let Some(crumb) = self.ended.take() else { return };
        let offset = 4 * crumb as u64;
        if offset < self.breadcrumbs.size {
            // SAFETY: cmd is recording; the breadcrumb lies within the buffer.
            unsafe { self.ctx.device.cmd_fill_buffer(cmd, self.breadcrumbs.raw, offset, 4, 1) };
            // Made available to the host at once: a hung frame never reaches its final
            // host_read_barrier, and without one a device write need not become visible.
            crate::vk::pipeline::transfer_to_host_barrier(&self.ctx, cmd);
        }
    }

    /// While the frame may still be running (a wait for its fence is taking long): which of its
    /// scopes the device has finished and the first it has not, from the breadcrumbs (read from
    /// mapped memory, without a Vulkan call). None before any scope was recorded. A scope without
    /// a breadcrumb ([`GpuTimer::breadcrumb`] not called) counts as not finished.
    pub fn progress(&self) -> Option<String> {
        if self.begun.is_empty() {
            return None;
        }
        let done = self.breadcrumbs.read_words_volatile(self.begun.len().min(self.breadcrumbs.size as usize / 4)).ok()?;
        let finished = done.iter().take_while(|&&w| w != 0).count();
        let names = self.begun[..finished].join(", ");
        Some(match self.begun.get(finished) {
            Some(name) => format!(
                "the device finished {finished} of its {} passes ({}); the first not finished: {name}",
                self.begun.len(),
                if finished == 0 { "none" } else { &names },
            ),
            None => format!("the device finished all its {} passes (the copies after them remain)", self.begun.len()),
        })
    }

    /// After the frame's fence: (scope name, milliseconds) in recording order.
    pub fn collect(&self) -> Result<Vec<(&'static str, f64)>> {
        if !self.valid || self.used == 0 {
            return Ok(Vec::new());
        }
        let mut data = vec![0u64; self.used as usize];
        // SAFETY: the frame's fence has signalled, so all written queries are available.
        unsafe {
            self.ctx.device.get_query_pool_results(
                self.pool,
                0,
                &mut data,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .context("reading GPU timestamps")?;
        let mut out: Vec<(&'static str, u32, f64)> = self
            .scopes
            .iter()
            .map(|(name, q)| {
                let ticks = data[*q as usize + 1].wrapping_sub(data[*q as usize]) & self.mask;
                (*name, *q, ticks as f64 * self.period_ns * 1e-6)
            })
            .collect();
        out.sort_by_key(|x| x.1);
        Ok(out.into_iter().map(|(n, _, ms)| (n, ms)).collect())
    }
}

impl Drop for GpuTimer {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a frame may still be writing its timestamps
        }
        // SAFETY: no pending work uses the pool.
        unsafe { self.ctx.device.destroy_query_pool(self.pool, None) };
    }
}
