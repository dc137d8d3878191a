//! `photon_emit`: direct VPLs from the area lights and indirect VPLs from photon paths, written to
//! one VPL buffer (shaders/passes/photon_emit.comp). For a static scene it runs once, before the
//! first frame, and its VPLs serve every frame.
//!
//! Layout of the VPL buffer: `[direct: N_d][indirect: up to capacity]`. Photon paths are launched
//! in batches until the indirect count reaches the target ([`BatchPlan`]); every launched path is
//! traced to its end and a batch that overflows the buffer is forgotten and traced again smaller,
//! so the paths kept are exactly 0 .. P and the final 1/P normalisation is right. Within a batch an
//! invocation whose path ends takes the next path at once (path regeneration), so SIMD lanes do
//! not idle behind the longest path of their group.

use std::sync::Arc;

use anyhow::{bail, ensure, Context as _, Result};
use ash::vk;
use gpu_allocator::MemoryLocation;
use serde::Serialize;

use crate::gpu_types::{GpuVpl, PHOTON_EMIT_DIRECT, PHOTON_EMIT_PATHS, PHOTON_EMIT_SCALE, VPL_INDIRECT};
use crate::lights::LightSet;
use crate::shaders;
use crate::settings::PhotonSettings;
use crate::vk::buffer::read_back_records;
use crate::vk::pipeline::{compute_barrier, storage};
use crate::vk::{Buffer, ComputePipeline, Context, GpuTimer};

use super::desc::{push_constants, PassDesc};

/// What the photon pass produced.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PhotonStats {
    pub direct_vpls: u32,
    pub indirect_vpls: u32,
    /// Photon paths traced (the normalisation count P).
    pub paths: u64,
    /// Closest-hit rays the photon paths traced, batches traced again after an overflow included
    /// (their time is in `paths_gpu_ms` too).
    pub rays: u64,
    pub batches: u32,
    /// GPU time of the whole pass: direct VPLs, photon paths and the flux normalisation (ms).
    pub gpu_ms: f64,
    /// GPU time of the photon path batches alone, the part that traces rays (ms).
    pub paths_gpu_ms: f64,
    pub wall_ms: f64,
    /// Σ flux of the direct / indirect VPLs per channel (W).
    pub direct_flux: [f64; 3],
    pub indirect_flux: [f64; 3],
    pub paths_per_second: f64,
}

push_constants! {
    struct Push {
        /// `PHOTON_EMIT_*`: what this dispatch does.
        mode: u32,
        /// First sample / path index of this dispatch.
        first: u32,
        /// Samples / paths / VPLs in this dispatch.
        count: u32,
        /// N_d (`PHOTON_EMIT_DIRECT`).
        total: u32,
        /// First VPL slot of the region written.
        base: u32,
        /// Indirect slots available (`PHOTON_EMIT_PATHS`).
        capacity: u32,
        min_bounces: u32,
        max_bounces: u32,
        seed: u32,
        /// Flux scale (`PHOTON_EMIT_SCALE`).
        scale: f32,
        /// Entries of `light_cdf`.
        light_count: u32,
    }
}

/// Largest single dispatch in items (keeps one submission short on slow devices).
const MAX_DISPATCH: u32 = 1 << 18;

/// Invocations that trace a batch of photon paths, each taking a new path when its last one ends
/// (enough to fill a large GPU; on lavapipe the first few workgroups take nearly all paths).
const PATH_LANES: u32 = 1 << 16;

/// How photon paths are launched: in batches until `target` indirect VPLs are stored in a buffer
/// of `capacity` slots. Every launched path is traced to its end and every batch's VPLs are kept,
/// so the paths traced are exactly 0 .. P and the 1/P normalisation is exact.
#[derive(Clone, Copy, Debug)]
pub struct BatchPlan {
    pub target: u32,
    pub capacity: u32,
    pub max_bounces: u32,
}

impl BatchPlan {
    /// Stops launching after this many paths (photons that keep leaving the scene).
    pub fn max_paths(&self) -> u64 {
        64 * self.target as u64 + 1_000_000
    }

    /// Paths in the next batch, `count` VPLs having come from `paths` paths so far. The first
    /// batch assumes every path makes `max_bounces` VPLs, so it fits the buffer whatever happens;
    /// later ones aim at the remaining VPLs from the mean per path so far, with 1 % + min(256,
    /// 4 √remaining) to spare (about 3–4 standard deviations of the VPLs that many paths make, so
    /// one more batch is rarely needed and a small target is not overshot ten times over), and
    /// no more than a quarter past the target were the mean two standard errors higher, and keep
    /// that expectation within 1/1.2 of the room left. A batch that overflows anyway (a mean from few paths can be far off) is traced again
    /// at half its size by [`Self::run`].
    pub fn batch_size(&self, count: u32, paths: u64) -> u32 {
        let room = self.capacity.saturating_sub(count) as f64;
        let (wanted, fits) = if paths == 0 {
            let worst = self.max_bounces as f64;
            (self.target as f64 / worst, room / worst)
        } else {
            let per_path = (count as f64 / paths as f64).max(1e-3);
            let remaining = self.target.saturating_sub(count) as f64;
            let spare = (4.0 * remaining.sqrt()).min(256.0);
            // A mean from few paths can be far too low: at two standard errors above it (a
            // path's VPLs lie in 0..=max_bounces, so their variance is at most max_bounces × the
            // mean), the batch should not pass the target by more than a quarter of it.
            let high = per_path + 2.0 * (self.max_bounces as f64 * per_path / paths as f64).sqrt();
            let bounded = (remaining + self.target as f64 / 4.0) / high;
            (((remaining * 1.01 + spare) / per_path).min(bounded), room / (1.2 * per_path))
        };
        let left = self.max_paths().saturating_sub(paths).min(u32::MAX as u64 / 2) as f64;
        wanted.ceil().min(fits.floor()).min(left).max(0.0) as u32
    }

    /// Launches batches until the target is reached: `trace(first, n)` traces paths first ..
    /// first + n and returns the VPL counter after it (which may exceed the capacity: VPLs past it
    /// were dropped); `reset(count)` sets the counter back so an overflowed batch is forgotten and
    /// its first half traced again. Returns (VPLs, paths, batches submitted).
    pub fn run(
        &self,
        trace: &mut dyn FnMut(u64, u32) -> Result<u32>,
        reset: &mut dyn FnMut(u32) -> Result<()>,
    ) -> Result<(u32, u64, u32)> {
        let (mut count, mut paths, mut batches) = (0u32, 0u64, 0u32);
        while count < self.target && paths < self.max_paths() {
            let mut batch = self.batch_size(count, paths);
            if batch == 0 {
                break;
            }
            loop {
                let after = trace(paths, batch)?;
                batches += 1;
                if after <= self.capacity {
                    count = after;
                    break;
                }
                ensure!(batch > 1, "photon_emit: one photon path overflowed the VPL buffer ({after} > {})", self.capacity);
                log::debug!("photon_emit: a batch of {batch} paths overflowed the VPL buffer; tracing {} of them again", batch / 2);
                reset(count)?;
                batch /= 2;
            }
            paths += batch as u64;
        }
        Ok((count, paths, batches))
    }
}

pub struct PhotonEmitPass {
    pipeline: ComputePipeline,
    pub vpls: Buffer,
    counter: Buffer,
    _cdf: Buffer,
    settings: PhotonSettings,
    capacity: u32,
    light_count: u32,
    /// The per-VPL radius rule the VPL records hold, (K, M bits, fallback r bits), and its median
    /// radius; None until [`Self::set_knn_radii`], and again after each [`Self::run`].
    knn_radii: std::cell::Cell<Option<((u32, u32, u32), f32)>>,
    ctx: Arc<Context>,
}

impl PhotonEmitPass {
    pub const NAME: &'static str = "photon_emit";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_PHOTON_EMIT, [64, 1, 1])
        .with_raygen(shaders::PASSES_PHOTON_EMIT_RAYGEN)
        .with_textured_raygen(shaders::PASSES_PHOTON_EMIT_TEXTURED_RAYGEN)
        .with_textured(shaders::PASSES_PHOTON_EMIT_TEXTURED)
        .with_push(Push::LAYOUT)
        .with_bindings(&[storage(0, "vpls"), storage(1, "indirect_count"), storage(2, "light_cdf")]);

    /// Room for indirect VPLs beyond the target: the last batch may overshoot by at most this.
    fn slack(s: &PhotonSettings) -> u32 {
        if s.indirect == 0 {
            0
        } else {
            (s.indirect / 4).max(1024u32.saturating_mul(s.max_bounces))
        }
    }

    /// Checks the counts against the device's memory before anything is allocated.
    pub fn check_memory(ctx: &Context, s: &PhotonSettings) -> Result<()> {
        let total = s.direct as u64 + s.indirect as u64 + Self::slack(s) as u64;
        let bytes = total * std::mem::size_of::<GpuVpl>() as u64;
        // SAFETY: valid physical device.
        let mem = unsafe { ctx.instance.get_physical_device_memory_properties(ctx.physical_device) };
        let heap = mem.memory_heaps[..mem.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(0);
        // Written as a storage buffer, read as texels (passes::RECORD_TEXELS): both limits hold.
        let limits = &ctx.properties.limits;
        let max_buffer = (limits.max_storage_buffer_range as u64).min(u64::from(limits.max_texel_buffer_elements) * super::RECORD_TEXELS.bytes);
        if bytes > heap / 2 || bytes > max_buffer || total > u32::MAX as u64 / 2 {
            bail!(
                "--vpls-direct {} / --vpls-indirect {}: {total} VPLs need {:.2} GiB, more than this device allows \
                 (half its {:.2} GiB device-local heap, or its {:.2} GiB limit on one buffer, storage or texel)",
                s.direct,
                s.indirect,
                bytes as f64 / (1u64 << 30) as f64,
                heap as f64 / (1u64 << 30) as f64,
                max_buffer as f64 / (1u64 << 30) as f64
            );
        }
        Ok(())
    }

    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        textured: bool,
        lights: &LightSet,
        settings: PhotonSettings,
    ) -> Result<Self> {
        Self::check_memory(ctx, &settings)?;
        ensure!(settings.max_bounces >= 1, "--photon-max-bounces must be at least 1");
        let capacity = settings.indirect + Self::slack(&settings);
        let total = settings.direct as u64 + capacity as u64;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST;
        let vpl_bytes = total * std::mem::size_of::<GpuVpl>() as u64;
        let vpls = Buffer::new(ctx, "photon_emit.vpls", vpl_bytes, usage | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER, MemoryLocation::GpuOnly)?
            .with_texel_view(super::RECORD_TEXELS)?;
        let counter = Buffer::new(ctx, "photon_emit.indirect_count", 16, usage, MemoryLocation::GpuOnly)?;
        let cdf = light_cdf(lights.lights.iter().map(|l| l.pdf as f64));
        // (One unread entry where no light can be chosen, since a buffer is not empty; the pass
        // then traces nothing.)
        let table: &[u32] = if cdf.is_empty() { &[0] } else { &cdf };
        let cdf_buf = Buffer::with_data(ctx, "photon_emit.light_cdf", bytemuck::cast_slice(table), vk::BufferUsageFlags::STORAGE_BUFFER)?;
        let pipeline = Self::DESC
            .pipeline(ctx, scene_layout)
            .textured(textured)
            .buffers(&[(0, &vpls), (1, &counter), (2, &cdf_buf)])
            .build()?;
        let light_count = cdf.len() as u32;
        Ok(Self {
            pipeline,
            vpls,
            counter,
            _cdf: cdf_buf,
            settings,
            capacity,
            light_count,
            knn_radii: Default::default(),
            ctx: ctx.clone(),
        })
    }

    fn push(&self, mode: u32) -> Push {
        Push {
            mode,
            first: 0,
            count: 0,
            total: self.settings.direct,
            base: 0,
            capacity: self.capacity,
            min_bounces: self.settings.min_bounces,
            max_bounces: self.settings.max_bounces,
            seed: self.settings.seed,
            scale: 1.0,
            light_count: self.light_count,
        }
    }

    /// Records dispatches of `count` items starting at `first`, split into bounded chunks.
    fn record_chunks(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, mut push: Push, first: u32, count: u32) {
        let mut done = 0;
        while done < count {
            let n = (count - done).min(MAX_DISPATCH);
            push.first = first + done;
            push.count = n;
            self.pipeline.dispatch_1d(cmd, scene_set, bytemuck::bytes_of(&push), n);
            done += n;
        }
    }

    /// Submits `record` inside the pass's label and timestamp scope, waits, and adds its GPU time.
    fn submit(&self, timer: &mut GpuTimer, gpu_ms: &mut f64, record: impl FnOnce(vk::CommandBuffer)) -> Result<()> {
        self.ctx.one_shot(|cmd| {
            timer.reset(cmd);
            timer.begin(cmd, Self::NAME);
            record(cmd);
            timer.end(cmd);
        })?;
        *gpu_ms += timer.collect()?.iter().map(|x| x.1).sum::<f64>();
        Ok(())
    }

    /// Records one batch of paths (`push.first`, `push.count`): next_path and rays are zeroed, then
    /// min(count, PATH_LANES) invocations take paths from it until the batch is done.
    fn record_paths(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, push: Push) {
        // SAFETY: cmd is recording; the counter is alive until the submission's wait returns.
        unsafe { self.ctx.device.cmd_fill_buffer(cmd, self.counter.raw, 4, 8, 0) };
        compute_barrier(&self.ctx, cmd);
        self.pipeline.dispatch_1d(cmd, scene_set, bytemuck::bytes_of(&push), push.count.min(PATH_LANES));
    }

    /// Sets the VPL counter: 0 before a run, back to the count before a batch that overflowed.
    fn set_counter(&self, value: u32) -> Result<()> {
        // SAFETY: the counter is alive until one_shot's wait returns.
        self.ctx.one_shot(|cmd| unsafe { self.ctx.device.cmd_fill_buffer(cmd, self.counter.raw, 0, 4, value) })
    }

    /// The VPL counter and the rays of the last batch.
    fn read_counter(&self) -> Result<(u32, u32)> {
        let words: Vec<u32> = read_back_records(&self.ctx, &self.counter, 3)?;
        Ok((words[0], words[2]))
    }

    /// Traces the photons and fills the VPL buffer (direct, then indirect in (path, bounce) order).
    /// Returns the statistics; the VPLs stay on the GPU.
    pub fn run(&self, scene_set: vk::DescriptorSet) -> Result<PhotonStats> {
        let start = std::time::Instant::now();
        self.knn_radii.set(None);
        let mut timer = GpuTimer::new(&self.ctx, 4)?;
        let mut stats = PhotonStats::default();
        let s = self.settings;
        self.set_counter(0)?;
        if self.light_count == 0 {
            return Ok(stats);
        }
        let mut gpu_ms = 0.0;
        // Direct VPLs.
        if s.direct > 0 {
            self.submit(&mut timer, &mut gpu_ms, |cmd| self.record_chunks(cmd, scene_set, self.push(PHOTON_EMIT_DIRECT), 0, s.direct))?;
            stats.direct_vpls = s.direct;
        }
        // Photon paths, in batches sized from the VPLs per path seen so far.
        if s.indirect > 0 {
            let plan = BatchPlan { target: s.indirect, capacity: self.capacity, max_bounces: s.max_bounces };
            let (mut rays, mut paths_ms) = (0u64, 0.0);
            let mut trace = |first: u64, batch: u32| -> Result<u32> {
                let push = Push { base: s.direct, first: first as u32, count: batch, ..self.push(PHOTON_EMIT_PATHS) };
                self.submit(&mut timer, &mut paths_ms, |cmd| self.record_paths(cmd, scene_set, push))?;
                let (count, batch_rays) = self.read_counter()?;
                rays += batch_rays as u64;
                Ok(count)
            };
            let (count, paths, batches) = plan.run(&mut trace, &mut |count| self.set_counter(count))?;
            gpu_ms += paths_ms;
            stats.paths_gpu_ms = paths_ms;
            stats.batches = batches;
            stats.rays = rays;
            if let Some(w) = indirect_shortfall(s.indirect, count, paths) {
                log::warn!("{w}");
            }
            if count > 0 {
                let push = Push { base: s.direct, scale: (1.0 / paths as f64) as f32, ..self.push(PHOTON_EMIT_SCALE) };
                self.submit(&mut timer, &mut gpu_ms, |cmd| self.record_chunks(cmd, scene_set, push, 0, count))?;
            }
            stats.indirect_vpls = count;
            stats.paths = paths;
        }
        stats.gpu_ms = gpu_ms;
        stats.wall_ms = start.elapsed().as_secs_f64() * 1e3;
        stats.paths_per_second = if gpu_ms > 0.0 { stats.paths as f64 / (gpu_ms * 1e-3) } else { 0.0 };
        let mut vpls = self.read_vpls(&stats)?;
        self.sort_indirect(&mut vpls[stats.direct_vpls as usize..])?;
        for v in &vpls {
            let target = if v.kind == VPL_INDIRECT { &mut stats.indirect_flux } else { &mut stats.direct_flux };
            for (sum, flux) in target.iter_mut().zip(v.flux) {
                *sum += flux as f64;
            }
        }
        Ok(stats)
    }

    /// Puts the indirect VPLs in (path, bounce) order: the atomic append order varies from run to
    /// run, and sampling indexes VPLs, so a fixed order keeps same-seed images bit-identical. Done
    /// once per static scene on the host (a few ms for 100k VPLs). A stable sort by path alone
    /// gives bounce order within a path: one invocation appends its path's VPLs bounce by bounce,
    /// so their slots increase.
    fn sort_indirect(&self, indirect: &mut [GpuVpl]) -> Result<()> {
        if indirect.is_empty() {
            return Ok(());
        }
        indirect.sort_by_key(|v| v.path);
        let offset = self.settings.direct as u64 * std::mem::size_of::<GpuVpl>() as u64;
        self.vpls.upload(offset, bytemuck::cast_slice(indirect))
    }

    /// The VPLs on the host: direct first, then indirect.
    pub fn read_vpls(&self, stats: &PhotonStats) -> Result<Vec<GpuVpl>> {
        // Direct VPLs from slot 0, indirect from slot `direct`. The buffer has a minimum size even
        // for an empty VPL set (`--no-gi --vpls-direct 0`), so only the slots in use are read as
        // records.
        let base = self.settings.direct as usize;
        let (direct, indirect) = (stats.direct_vpls as usize, stats.indirect_vpls as usize);
        let used = if indirect > 0 { base + indirect } else { direct };
        let all: Vec<GpuVpl> = read_back_records(&self.ctx, &self.vpls, used).context("reading VPLs back")?;
        let mut out = all[..direct].to_vec();
        out.extend_from_slice(&all[base.min(used)..used]);
        Ok(out)
    }

    /// Gives every VPL its own Yuksel r² (`GpuVpl::yuksel_r2`): `multiple` × its local spacing from
    /// its `k` nearest VPLs, `fallback` where it has none ([`crate::vpl_radius::knn_r2`]). Returns
    /// the median radius. The host search (~1 s for 200k VPLs) runs once per VPL set and rule: a
    /// settings change that keeps the VPL set reuses the records as they are.
    pub fn set_knn_radii(&self, stats: &PhotonStats, k: u32, multiple: f32, fallback: f32) -> Result<f32> {
        let key = (k, multiple.to_bits(), fallback.to_bits());
        if let Some((held, median)) = self.knn_radii.get() {
            if held == key {
                return Ok(median);
            }
        }
        let start = std::time::Instant::now();
        let mut vpls = self.read_vpls(stats)?;
        let positions: Vec<[f32; 3]> = vpls.iter().map(|v| v.position).collect();
        if let Some(w) = knn_set_warning(k, positions.len()) {
            log::warn!("{w}");
        }
        let (r2, median) = crate::vpl_radius::knn_r2(&positions, k as usize, multiple, fallback);
        for (v, r2) in vpls.iter_mut().zip(r2) {
            v.yuksel_r2 = r2;
        }
        // Back where read_vpls found them: direct from slot 0, indirect from slot `direct`.
        let direct = stats.direct_vpls as usize;
        self.vpls.upload(0, bytemuck::cast_slice(&vpls[..direct]))?;
        let offset = self.settings.direct as u64 * std::mem::size_of::<GpuVpl>() as u64;
        self.vpls.upload(offset, bytemuck::cast_slice(&vpls[direct..])).context("uploading per-VPL radii")?;
        self.knn_radii.set(Some((key, median)));
        log::info!(
            "vpl: per-VPL Yuksel radius from the {k} nearest VPLs in {:.0} ms (host): median {median:.4}, global rule {fallback:.4}",
            start.elapsed().as_secs_f64() * 1e3
        );
        Ok(median)
    }

    /// Number of VPL slots in use (direct + indirect, contiguous).
    pub fn vpl_count(stats: &PhotonStats) -> u32 {
        stats.direct_vpls + stats.indirect_vpls
    }
}

/// What `--yuksel-knn k` says of a set of `n` VPLs too small for it (None: large enough): on
/// stderr when the radii are set, and in the run's summary. local_spacings uses all the others
/// then, and none for a set of one.
pub fn knn_set_warning(k: u32, n: usize) -> Option<String> {
    (k as usize >= n).then(|| match n {
        0 | 1 => format!(
            "--yuksel-knn {k}: the VPL set has {n} VPL{}, so no VPL has a neighbour; every VPL takes the global rule's radius",
            if n == 1 { "" } else { "s" }
        ),
        n => format!("--yuksel-knn {k}: the VPL set has only {n} VPLs, so each VPL's radius comes from its {} others", n - 1),
    })
}

/// What a photon pass that made `made` indirect VPLs of the `asked` ones in `paths` paths says
/// (None: it made them all, or it traced no path: a scene without emitters, which the run says
/// in its own words): on stderr as it happens, and in the run's summary.
pub fn indirect_shortfall(asked: u32, made: u32, paths: u64) -> Option<String> {
    (made < asked && paths > 0).then(|| format!("--vpls-indirect {asked}: only {made} indirect VPLs after {paths} photon paths (photons leave the scene?)"))
}

/// The light-choice table of `photon_emit` from the lights' probabilities `pdfs` (any positive
/// scale): entry t is the end of light t's interval in 32-bit fixed point (units of 2^-32), so a
/// uniform 32-bit word u picks the first t with u < cdf[t]. The table ends at the last light of
/// positive probability (none after it can be chosen; empty if no light can), whose entry stands
/// for 2^32 and is 0 (the search never reads it). Every light of positive probability gets at least one unit, however
/// small its share, and the pass divides each VPL's flux by its light's width in this table, the
/// probability with which it is really chosen: a float table, searched with 24-bit uniforms, gave a
/// light of share 1e-7 about 1.2× its VPLs and one below ~3e-8 none (a dim point light beside area
/// lights, or ~10^6 emissive triangles), and divided by the exact share.
pub fn light_cdf(pdfs: impl Iterator<Item = f64> + Clone) -> Vec<u32> {
    const ONE: f64 = 4294967296.0;
    let total: f64 = pdfs.clone().filter(|p| *p > 0.0).sum();
    let mut positive_after = pdfs.clone().filter(|p| *p > 0.0).count() as u64;
    let n = pdfs.clone().enumerate().filter(|(_, p)| *p > 0.0).last().map_or(0, |(t, _)| t + 1);
    let (mut acc, mut end) = (0.0f64, 0u64);
    let mut cdf = Vec::with_capacity(n);
    for (t, p) in pdfs.take(n).enumerate() {
        if p > 0.0 {
            acc += p / total;
            positive_after -= 1;
            // At least one unit for this light, and room for one for each positive light after it.
            end = ((acc * ONE).round() as u64).max(end + 1).min((1u64 << 32) - positive_after);
        }
        cdf.push(if t + 1 == n { 0 } else { end as u32 });
    }
    cdf
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Widths as the shader reads them (`light_choice_pdf`), in units of 2^-32.
    fn widths(cdf: &[u32]) -> Vec<u64> {
        (0..cdf.len())
            .map(|t| {
                let lo = if t == 0 { 0 } else { cdf[t - 1] as u64 };
                let hi = if t + 1 == cdf.len() { 1u64 << 32 } else { cdf[t] as u64 };
                hi - lo
            })
            .collect()
    }

    #[test]
    fn light_cdf_gives_every_light_its_share_and_the_dimmest_at_least_one_unit() {
        // A bright area light, a dim point light last (share 1e-11, below 2^-32), a zero one.
        let pdfs = [0.6, 0.4 - 1e-11, 0.0, 1e-11];
        let w = widths(&light_cdf(pdfs.iter().copied()));
        assert_eq!(w.iter().sum::<u64>(), 1u64 << 32);
        assert_eq!(w[2], 0, "a light of probability 0 is never chosen");
        assert_eq!(w[3], 1, "the dimmest light is chosen with one unit, and its flux divided by it");
        for t in [0, 1] {
            assert!((w[t] as f64 / 4294967296.0 - pdfs[t]).abs() <= 2.0 / 4294967296.0, "light {t}: {w:?}");
        }
        // Shares of 1e-7 (where a float table with 24-bit uniforms was 19 % off) within one unit.
        let many: Vec<f64> = std::iter::once(1.0 - 1e-7 * 1000.0).chain(std::iter::repeat_n(1e-7, 1000)).collect();
        let w = widths(&light_cdf(many.iter().copied()));
        assert_eq!(w.iter().sum::<u64>(), 1u64 << 32);
        for (t, (w, p)) in w.iter().zip(&many).enumerate() {
            assert!((*w as f64 - p * 4294967296.0).abs() <= 1.0, "light {t}: width {w} for share {p}");
        }
        // One light takes everything; a list of zeros and one light too.
        assert_eq!(widths(&light_cdf([2.0].into_iter())), [1u64 << 32]);
        assert_eq!(widths(&light_cdf([0.0, 3.0, 0.0].into_iter())), [0, 1u64 << 32], "the table ends at the last light that can be chosen");
        assert!(light_cdf([0.0, 0.0].into_iter()).is_empty(), "no light can be chosen");
    }

    /// Runs `plan` against a simulated tracer where path p makes `vpls(p)` VPLs, checking what the
    /// GPU pass relies on: the paths kept are exactly 0 .. P, each traced once into the counter
    /// (an overflowed batch is forgotten whole), and the count is theirs. Returns (count, paths,
    /// batches, overflows).
    fn simulate(plan: BatchPlan, vpls: impl Fn(u64) -> u32) -> (u32, u64, u32, u32) {
        use std::cell::Cell;
        let counter = Cell::new(0u32);
        let next = Cell::new(0u64);
        let overflows = Cell::new(0u32);
        let mut trace = |first: u64, n: u32| -> Result<u32> {
            assert_eq!(first, next.get(), "batches continue where the kept ones ended");
            let made: u64 = (first..first + n as u64).map(&vpls).map(u64::from).sum();
            let after = (counter.get() as u64 + made).min(u32::MAX as u64) as u32;
            counter.set(after);
            if after <= plan.capacity {
                next.set(first + n as u64);
            } else {
                overflows.set(overflows.get() + 1);
            }
            Ok(after)
        };
        let mut reset = |c: u32| -> Result<()> {
            counter.set(c);
            Ok(())
        };
        let (count, paths, batches) = plan.run(&mut trace, &mut reset).unwrap();
        assert_eq!(paths, next.get());
        assert_eq!(count as u64, (0..paths).map(&vpls).map(u64::from).sum::<u64>(), "count is the kept paths' VPLs");
        assert!(count <= plan.capacity);
        (count, paths, batches, overflows.get())
    }

    fn hash(p: u64) -> u64 {
        let mut x = p.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        x ^= x >> 29;
        x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x ^ (x >> 32)
    }

    fn plan(target: u32, max_bounces: u32) -> BatchPlan {
        let slack = (target / 4).max(1024 * max_bounces);
        BatchPlan { target, capacity: target + slack, max_bounces }
    }

    /// Paths of 0..=3 VPLs (mean 1.5, the Cornell box makes ~1.8): the first batch gives the mean
    /// and the second all but at most a little of the rest; no overflow.
    #[test]
    fn typical_paths_take_two_or_three_batches() {
        let (count, paths, batches, overflows) = simulate(plan(100_000, 8), |p| (hash(p) % 4) as u32);
        assert!((100_000..102_000).contains(&count), "{count}");
        assert!(paths > 60_000, "{paths}");
        assert!(batches <= 3, "{batches} batches");
        assert_eq!(overflows, 0);
    }

    /// A small target (50, which overshot to 454 with a flat 256 to spare) ends near itself,
    /// in a few batches.
    #[test]
    fn a_small_target_is_not_overshot_many_times_over() {
        for seed in 0..64u64 {
            let (count, _, batches, overflows) = simulate(plan(50, 8), |p| (hash(p ^ (seed << 40)) % 4) as u32);
            assert!((50..=75).contains(&count), "seed {seed}: {count} VPLs for a target of 50");
            assert!(batches <= 6, "seed {seed}: {batches} batches");
            assert_eq!(overflows, 0);
        }
    }

    /// The first batch finds no VPL (every early path escapes) and later paths make many: the
    /// mean guess is far too low, the batch overflows and is traced again at half size until it
    /// fits; the target is still met with the paths contiguous.
    #[test]
    fn an_overflowing_batch_is_forgotten_and_halved() {
        let (count, _, _, overflows) = simulate(plan(200, 8), |p| if p < 100 { 0 } else { 3 });
        assert!(overflows >= 1, "the scenario overflows");
        assert!(count >= 200, "{count}");
    }

    /// Photons that never hit anything: stops after max_paths with no VPL.
    #[test]
    fn escaping_photons_stop_at_max_paths() {
        let p = plan(1000, 8);
        let (count, paths, _, _) = simulate(p, |_| 0);
        assert_eq!(count, 0);
        assert_eq!(paths, p.max_paths());
    }

    /// Every path bounces max_bounces times (closed box without roulette): the first batch's
    /// worst-case sizing is exact and nothing overflows.
    #[test]
    fn worst_case_paths_never_overflow() {
        let (count, _, _, overflows) = simulate(plan(20_000, 5), |_| 5);
        assert_eq!(overflows, 0);
        assert!(count >= 20_000);
    }
}
