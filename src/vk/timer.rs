//! GPU timestamp scopes: each pass is wrapped in a debug label and a pair of timestamps of the same
//! name, so a capture and the timing table read alike.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;

use super::Context;

pub struct GpuTimer {
    ctx: Arc<Context>,
    pool: vk::QueryPool,
    capacity: u32,
    used: u32,
    scopes: Vec<(&'static str, u32)>,
    /// The scopes begun and not yet ended, innermost last; None for one begun when the pool was
    /// full (it has a label but no timestamps), so that its `end` closes it and not its parent.
    open: Vec<Option<(&'static str, u32)>>,
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
            period_ns: ctx.properties.limits.timestamp_period as f64,
            valid,
            mask,
        })
    }

    /// Resets the pool at the start of a frame's command buffer.
    pub fn reset(&mut self, cmd: vk::CommandBuffer) {
        // SAFETY: cmd is recording; the pool is not in use by pending work (frames are fenced).
        unsafe { self.ctx.device.cmd_reset_query_pool(cmd, self.pool, 0, self.capacity) };
        self.used = 0;
        self.scopes.clear();
        self.open.clear();
    }

    /// Opens a debug label and a timestamp scope named `name`.
    pub fn begin(&mut self, cmd: vk::CommandBuffer, name: &'static str) {
        self.ctx.begin_label(cmd, name);
        // No timestamps where the queue has none (VUID-vkCmdWriteTimestamp-timestampValidBits-00829).
        if self.valid && self.used + 2 <= self.capacity {
            // SAFETY: query index within the pool.
            unsafe { self.ctx.device.cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, self.pool, self.used) };
            self.open.push(Some((name, self.used)));
            self.used += 2;
        } else {
            self.open.push(None);
        }
    }

    /// Closes the innermost open scope.
    pub fn end(&mut self, cmd: vk::CommandBuffer) {
        if let Some(Some((name, q))) = self.open.pop() {
            // SAFETY: query index within the pool.
            unsafe { self.ctx.device.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.pool, q + 1) };
            self.scopes.push((name, q));
        }
        self.ctx.end_label(cmd);
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
        // SAFETY: no pending work uses the pool.
        unsafe { self.ctx.device.destroy_query_pool(self.pool, None) };
    }
}
