//! The window's overlay (F1): an egui panel drawn over the presented image with egui-ash-renderer,
//! in a render pass that loads the blitted preview and ends in the present layout. It shows what
//! the renderer did last frame (mode, view, size, frames accumulated, per-pass GPU ms and rays per
//! pixel, VPLs), the key table, widgets for the settings headless takes as flags, and with
//! `--reference REF.exr` a split screen (the reference on the right) with live RMSE and FLIP.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result};
use ash::vk;
use egui_ash_renderer::allocator::GpuAllocator;
use winit::window::Window;

use crate::eval::compare::{compare, to_srgb8, CompareOptions};
use crate::output::RgbImage;
use crate::renderer::Renderer;
use crate::settings::{Attenuation, Mode, NamedEnum, RenderSettings, View};
use crate::vk::Context;

use super::actions;
use super::swapchain::Swapchain;

/// A reference image shown beside the render, and its live error.
pub struct Reference {
    pub image: RgbImage,
    /// Where the split sits, as a fraction of the width (the reference is on the right).
    pub split: f32,
    texture: Option<(egui::TextureHandle, f32)>,
    rmse: Option<f64>,
    flip: Option<f64>,
    /// Frames accumulated when the metrics were computed.
    measured_at: Option<u32>,
    last_rmse: Option<Instant>,
    last_flip: Option<Instant>,
}

impl Reference {
    /// Reads `path` for a window rendering `settings`. A reference written by `restir-vpl
    /// reference` names its scene (a hash of the file): one of another scene is refused, since its
    /// RMSE and FLIP would read as a comparison; one of another camera is shown with a warning
    /// (the fly camera may go there). A plain EXR carries neither and is taken as given.
    pub fn load(path: &std::path::Path, settings: &RenderSettings) -> Result<Self> {
        use crate::eval::reference::{file_hash, read_exr_and_reference_meta, META_ATTRIBUTE};
        let (image, meta) = read_exr_and_reference_meta(path).with_context(|| format!("--reference {}", path.display()))?;
        if let Some(meta) = meta {
            let config: serde_json::Value = serde_json::from_str(&meta.config)
                .with_context(|| format!("--reference {}: bad settings in its '{META_ATTRIBUTE}' header attribute", path.display()))?;
            let ours = file_hash(&settings.scene)?;
            let theirs = config.get("scene_hash").and_then(|h| h.as_str()).unwrap_or("none");
            anyhow::ensure!(
                theirs == ours,
                "--reference {}: rendered from another scene ({}, scene hash {theirs}) than --scene {} (hash {ours}); \
                 its RMSE and FLIP would compare two scenes",
                path.display(),
                meta.scene,
                settings.scene.display()
            );
            let camera = serde_json::to_value(settings.camera)?;
            if config.get("camera").unwrap_or(&serde_json::Value::Null) != &camera {
                log::warn!(
                    "--reference {}: rendered from another camera than this window's first view; its RMSE and FLIP \
                     compare two views until the fly camera stands where the reference's did",
                    path.display()
                );
            }
        }
        Ok(Self { image, split: 0.5, texture: None, rmse: None, flip: None, measured_at: None, last_rmse: None, last_flip: None })
    }

    /// Recomputes RMSE (twice a second) and FLIP (every 3 s: it costs ~0.7 s at 1280×720) of the
    /// current mean against the reference, when the sizes agree.
    fn measure(&mut self, renderer: &Renderer) -> Result<()> {
        let s = renderer.settings();
        if (s.width, s.height) != (self.image.width, self.image.height) {
            return Ok(());
        }
        let due = |last: Option<Instant>, every: Duration| last.is_none_or(|t| t.elapsed() >= every);
        let (rmse_due, flip_due) = (due(self.last_rmse, Duration::from_millis(500)), due(self.last_flip, Duration::from_secs(3)));
        if !rmse_due && !flip_due {
            return Ok(());
        }
        let mean = RgbImage { width: s.width, height: s.height, pixels: renderer.read_mean()? };
        let c = compare(&mean, &self.image, &CompareOptions { flip: flip_due, exposure: s.exposure, ..Default::default() })?;
        self.rmse = Some(c.rmse);
        self.last_rmse = Some(Instant::now());
        if let Some(f) = c.flip {
            self.flip = Some(f);
            self.last_flip = Some(Instant::now());
        }
        self.measured_at = Some(renderer.accumulated());
        Ok(())
    }

    /// The reference as an egui texture through the renderer's own tonemap (exposure, sRGB).
    fn texture(&mut self, egui: &egui::Context, exposure: f32) -> egui::TextureId {
        if let Some((t, e)) = &self.texture {
            if *e == exposure {
                return t.id();
            }
        }
        let rgb = to_srgb8(&self.image, exposure);
        let size = [self.image.width as usize, self.image.height as usize];
        let image = egui::ColorImage::from_rgb(size, &rgb);
        let t = egui.load_texture("reference", image, egui::TextureOptions::NEAREST);
        let id = t.id();
        self.texture = Some((t, exposure));
        id
    }
}

/// What the overlay shows about the window itself.
pub struct WindowInfo<'a> {
    pub ms_per_frame: f64,
    pub message: &'a str,
    pub frozen: bool,
    /// The fly camera sees none of the scene: the message line says so when it has nothing else.
    pub out_of_view: bool,
    /// The camera stands where the window's first view stood (a --reference's RMSE and FLIP
    /// compare two views once it has left).
    pub at_first_view: bool,
}

/// What the title and the overlay say while the fly camera sees none of the scene.
pub const OUT_OF_VIEW: &str = "the scene is out of view (Home: back to its camera)";

/// A settings edit made with the overlay's widgets: applied by the window like a key's.
pub struct Edit {
    pub what: String,
    pub settings: RenderSettings,
}

pub struct Overlay {
    egui: egui::Context,
    state: egui_winit::State,
    /// egui's clock (its input's `time`).
    start: Instant,
    renderer: egui_ash_renderer::Renderer<GpuAllocator>,
    render_pass: vk::RenderPass,
    format: vk::Format,
    framebuffers: Vec<vk::Framebuffer>,
    extent: vk::Extent2D,
    pub reference: Option<Reference>,
    /// This frame's texture updates, and the textures egui freed in earlier frames (painted
    /// since): applied by `apply_texture_deltas`.
    set_now: Vec<(egui::TextureId, egui::epaint::ImageDelta)>,
    free_now: Vec<egui::TextureId>,
    /// What egui freed in this frame's `prepare`: its shapes may still use them.
    free_after_this_frame: Vec<egui::TextureId>,
    /// The last frame's shapes, ready to draw.
    primitives: Vec<egui::ClippedPrimitive>,
    pixels_per_point: f32,
    repaint_soon: bool,
    /// Last: fields drop in order, and the egui renderer's allocations must go back to the
    /// allocator before the context (if this is its last holder) destroys the device.
    ctx: Arc<Context>,
}

impl Overlay {
    pub fn new(ctx: &Arc<Context>, window: &Window, swapchain: &Swapchain, slots: usize, reference: Option<Reference>) -> Result<Self> {
        let egui = egui::Context::default();
        let state = egui_winit::State::new(
            egui.clone(),
            egui::ViewportId::ROOT,
            window,
            Some(window.scale_factor() as f32),
            window.theme(),
            None,
        );
        let format = swapchain.format.format;
        let render_pass = Self::render_pass(ctx, format)?;
        let renderer = egui_ash_renderer::Renderer::with_gpu_allocator(
            Arc::clone(&ctx.allocator),
            ctx.device.clone(),
            egui_ash_renderer::RenderMode::RenderPass(render_pass),
            egui_ash_renderer::Options {
                in_flight_frames: slots,
                srgb_framebuffer: is_srgb(format),
                ..Default::default()
            },
        );
        let renderer = match renderer {
            Ok(r) => r,
            Err(e) => {
                // SAFETY: the render pass was just created and nothing uses it.
                unsafe { ctx.device.destroy_render_pass(render_pass, None) };
                return Err(anyhow::anyhow!("creating the overlay's renderer: {e}"));
            }
        };
        let mut overlay = Self {
            ctx: ctx.clone(),
            egui,
            state,
            renderer,
            render_pass,
            format,
            framebuffers: Vec::new(),
            extent: swapchain.extent,
            reference,
            set_now: Default::default(),
            free_now: Vec::new(),
            free_after_this_frame: Vec::new(),
            primitives: Vec::new(),
            pixels_per_point: 1.0,
            repaint_soon: false,
            start: Instant::now(),
        };
        overlay.set_swapchain(swapchain)?;
        Ok(overlay)
    }

    /// Loads what the blit left in the image and ends in the present layout.
    fn render_pass(ctx: &Context, format: vk::Format) -> Result<vk::RenderPass> {
        let attachment = [vk::AttachmentDescription::default()
            .format(format)
            .samples(vk::SampleCountFlags::TYPE_1)
            .load_op(vk::AttachmentLoadOp::LOAD)
            .store_op(vk::AttachmentStoreOp::STORE)
            .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
            .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
            .initial_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
            .final_layout(vk::ImageLayout::PRESENT_SRC_KHR)];
        let color = [vk::AttachmentReference::default().attachment(0).layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
        let subpass = [vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color)];
        // The blit's writes before the overlay's loads and writes.
        let dependency = [vk::SubpassDependency::default()
            .src_subpass(vk::SUBPASS_EXTERNAL)
            .dst_subpass(0)
            .src_stage_mask(vk::PipelineStageFlags::TRANSFER)
            .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT)
            .dst_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE)];
        let info = vk::RenderPassCreateInfo::default().attachments(&attachment).subpasses(&subpass).dependencies(&dependency);
        // SAFETY: valid device and create info.
        let rp = unsafe { ctx.device.create_render_pass(&info, None) }.context("creating the overlay's render pass")?;
        ctx.set_name(rp, "overlay");
        Ok(rp)
    }

    /// Framebuffers for a (new) swapchain; call with the device idle.
    pub fn set_swapchain(&mut self, swapchain: &Swapchain) -> Result<()> {
        self.destroy_framebuffers();
        if swapchain.format.format != self.format {
            let rp = Self::render_pass(&self.ctx, swapchain.format.format)?;
            self.renderer
                .set_render_mode(egui_ash_renderer::RenderMode::RenderPass(rp))
                .map_err(|e| anyhow::anyhow!("the overlay's pipeline for {:?}: {e}", swapchain.format.format))?;
            // SAFETY: the device is idle; the renderer now uses the new render pass.
            unsafe { self.ctx.device.destroy_render_pass(self.render_pass, None) };
            self.render_pass = rp;
            self.format = swapchain.format.format;
        }
        for (i, view) in swapchain.views.iter().enumerate() {
            let views = [*view];
            let info = vk::FramebufferCreateInfo::default()
                .render_pass(self.render_pass)
                .attachments(&views)
                .width(swapchain.extent.width)
                .height(swapchain.extent.height)
                .layers(1);
            // SAFETY: the view belongs to a live swapchain image of this size.
            let fb = unsafe { self.ctx.device.create_framebuffer(&info, None) }.context("creating an overlay framebuffer")?;
            self.ctx.set_name(fb, &format!("overlay.framebuffer{i}"));
            self.framebuffers.push(fb);
        }
        self.extent = swapchain.extent;
        Ok(())
    }

    fn destroy_framebuffers(&mut self) {
        for fb in self.framebuffers.drain(..) {
            // SAFETY: callers make sure no submitted work uses it (device idle).
            unsafe { self.ctx.device.destroy_framebuffer(fb, None) };
        }
    }

    /// Passes a window event to egui; true when egui used it (the camera should then ignore it).
    pub fn on_window_event(&mut self, window: &Window, event: &winit::event::WindowEvent) -> bool {
        self.state.on_window_event(window, event).consumed
    }

    /// Whether egui wants the keyboard (a widget has focus): keys then go to it, not to actions.
    pub fn wants_keyboard(&self) -> bool {
        self.egui.egui_wants_keyboard_input()
    }

    /// Whether egui asked, in the last `prepare`, to be run again at once (its answer to some
    /// inputs takes two passes).
    pub fn repaint_soon(&self) -> bool {
        self.repaint_soon
    }

    /// egui_winit's `take_egui_input` with the window's size given instead of asked: that function
    /// asks the X server every frame, and winit panics on the answer when another program has
    /// destroyed the window since the last event (the window then panicked mid-frame under load
    /// before its `Destroyed` event arrived). The scale factor winit answers from its cache.
    fn take_input(&mut self, window: &Window, size: winit::dpi::PhysicalSize<u32>) -> egui::RawInput {
        let pixels_per_point = egui_winit::pixels_per_point(&self.egui, window);
        let input = self.state.egui_input_mut();
        input.time = Some(self.start.elapsed().as_secs_f64());
        let points = egui::vec2(size.width as f32, size.height as f32) / pixels_per_point;
        input.screen_rect = (points.x > 0.0 && points.y > 0.0).then(|| egui::Rect::from_min_size(egui::Pos2::ZERO, points));
        input.viewport_id = egui::ViewportId::ROOT;
        input.viewports.entry(egui::ViewportId::ROOT).or_default().native_pixels_per_point = Some(window.scale_factor() as f32);
        input.take()
    }

    /// Whether anything is drawn when the panel is hidden (the reference's split screen stays).
    pub fn has_reference(&self) -> bool {
        self.reference.is_some()
    }

    /// Builds this frame's shapes (the panel when `panel`, the reference's split screen) and keeps
    /// the texture changes for [`Overlay::apply_texture_deltas`] (call before recording the
    /// frame). Returns a settings edit made with the widgets.
    /// `size`: the window's inner size as its last `Resized` event gave it.
    pub fn prepare(
        &mut self,
        window: &Window,
        size: winit::dpi::PhysicalSize<u32>,
        renderer: &Renderer,
        info: &WindowInfo,
        panel_shown: bool,
    ) -> Result<Option<Edit>> {
        if let Some(r) = &mut self.reference {
            r.measure(renderer)?;
        }
        let raw = self.take_input(window, size);
        let mut edit = None;
        let egui = self.egui.clone();
        let reference = &mut self.reference;
        let mut output = egui.run_ui(raw, |ui| {
            if let Some(r) = reference.as_mut() {
                draw_reference(ui, r, renderer);
            }
            if panel_shown {
                edit = panel(ui, renderer, info, reference.as_ref());
            }
        });
        self.state.handle_platform_output(window, output.platform_output);
        self.repaint_soon = output.viewport_output.get(&egui::ViewportId::ROOT).is_some_and(|v| v.repaint_delay.is_zero());
        self.pixels_per_point = output.pixels_per_point;
        self.primitives = self.egui.tessellate(output.shapes, output.pixels_per_point);
        // egui frees "after painting": this frame's shapes may still use what it frees now, so
        // those go with the next frame's changes, once this frame has been shown.
        let freed = std::mem::take(&mut output.textures_delta.free).into_iter().collect();
        self.free_now.extend(std::mem::replace(&mut self.free_after_this_frame, freed));
        let set = std::mem::take(&mut output.textures_delta.set);
        self.set_now = set.into_iter().flat_map(|(id, deltas)| deltas.into_iter().map(move |d| (id, d))).collect();
        Ok(edit)
    }

    /// Whether [`Overlay::prepare`] left texture updates or frees to apply before this frame is
    /// recorded (the font atlas when new glyphs appear, the reference's texture after an exposure
    /// change): rare, at start-up and while the exposure is dragged.
    pub fn has_texture_deltas(&self) -> bool {
        !self.set_now.is_empty() || !self.free_now.is_empty()
    }

    /// Applies the pending texture updates and frees. The caller first waits for every earlier
    /// frame that may sample them (the present slots' fences): an updated or freed texture may still
    /// be read by an earlier overlay, and a present slot whose frame got no swapchain image moves on
    /// without waiting. (egui-ash-renderer's upload also waits for the queue to go idle, without a
    /// time limit; after those waits the queue is idle already.)
    pub fn apply_texture_deltas(&mut self) -> Result<()> {
        for (id, delta) in std::mem::take(&mut self.set_now) {
            self.renderer
                .set_texture(self.ctx.queue, self.ctx.command_pool, id, &delta)
                .map_err(|e| anyhow::anyhow!("uploading an overlay texture: {e}"))?;
        }
        for id in std::mem::take(&mut self.free_now) {
            self.renderer.free_texture(id).map_err(|e| anyhow::anyhow!("freeing an overlay texture: {e}"))?;
        }
        Ok(())
    }

    /// Records the overlay over swapchain image `image_index` (in TRANSFER_DST layout after the
    /// blit), leaving it in PRESENT_SRC layout.
    pub fn record(&mut self, cmd: vk::CommandBuffer, image_index: usize) -> Result<()> {
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(self.render_pass)
            .framebuffer(self.framebuffers[image_index])
            .render_area(vk::Rect2D { offset: vk::Offset2D::default(), extent: self.extent });
        self.ctx.begin_label(cmd, "overlay");
        // SAFETY: cmd is recording outside a render pass; the framebuffer matches the image.
        unsafe { self.ctx.device.cmd_begin_render_pass(cmd, &begin, vk::SubpassContents::INLINE) };
        let drawn = self.renderer.cmd_draw(cmd, self.extent, self.pixels_per_point, &self.primitives);
        // SAFETY: paired with the begin above.
        unsafe { self.ctx.device.cmd_end_render_pass(cmd) };
        self.ctx.end_label(cmd);
        drawn.map_err(|e| anyhow::anyhow!("drawing the overlay: {e}"))
    }
}

impl Drop for Overlay {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a submission may still be executing: what it draws with stays
        }
        // SAFETY: wait for idle, then destroy what the overlay created (the egui renderer frees
        // its own objects when dropped, before the context's allocator goes).
        unsafe {
            let _ = self.ctx.device.device_wait_idle();
        }
        self.destroy_framebuffers();
        // SAFETY: the device is idle.
        unsafe { self.ctx.device.destroy_render_pass(self.render_pass, None) };
    }
}

fn is_srgb(format: vk::Format) -> bool {
    matches!(format, vk::Format::B8G8R8A8_SRGB | vk::Format::R8G8B8A8_SRGB)
}

/// The reference over the right part of the screen, behind the panel, with a line at the split.
fn draw_reference(ui: &mut egui::Ui, r: &mut Reference, renderer: &Renderer) {
    let s = renderer.settings();
    if (s.width, s.height) != (r.image.width, r.image.height) {
        return;
    }
    let id = r.texture(ui.ctx(), s.exposure);
    let screen = ui.ctx().content_rect();
    let x = screen.min.x + r.split * screen.width();
    let rect = egui::Rect::from_min_max(egui::pos2(x, screen.min.y), screen.max);
    let uv = egui::Rect::from_min_max(egui::pos2(r.split, 0.0), egui::pos2(1.0, 1.0));
    let painter = ui.ctx().layer_painter(egui::LayerId::background());
    painter.image(id, rect, uv, egui::Color32::WHITE);
    painter.line_segment([egui::pos2(x, screen.min.y), egui::pos2(x, screen.max.y)], egui::Stroke::new(1.0, egui::Color32::YELLOW));
    painter.text(egui::pos2(x + 6.0, screen.max.y - 6.0), egui::Align2::LEFT_BOTTOM, "reference", egui::FontId::monospace(12.0), egui::Color32::YELLOW);
}

/// The panel; returns an edit when a widget changed a setting.
fn panel(ui: &mut egui::Ui, renderer: &Renderer, info: &WindowInfo, reference: Option<&Reference>) -> Option<Edit> {
    let s = renderer.settings();
    let mut edited = s.clone();
    let mut what: Option<String> = None;
    let stats = renderer.last_stats();
    let pixels = renderer.pixels().max(1) as f64;
    // No frame completed since the settings changed: no numbers yet, rather than the old ones.
    let measured = !stats.dispatch_ms.is_empty();
    let per_pixel = |rays: u64| if measured { format!("{:.2}", rays as f64 / pixels) } else { "–".to_string() };
    // In a small window (at 320×240 the 300 px panel hid the image) it starts collapsed to its
    // title bar (a click opens it); it is resizable, and narrower where the window is.
    let screen = ui.ctx().content_rect();
    let width = 300f32.min(0.6 * screen.width()).max(120.0);
    let roomy = screen.width() >= 480.0 && screen.height() >= 360.0;
    // A resize across 480×360 shows a new panel with the defaults for the new size, folded or
    // open (egui applies the defaults only when a panel is first shown: shrunk to 200×150 the open
    // panel covered the whole image, and grown back it kept the small height).
    let key = egui::Id::new("restir-vpl overlay panel");
    let (was_roomy, generation) = ui.ctx().data_mut(|d| d.get_temp::<(bool, u32)>(key)).unwrap_or((roomy, 0));
    let generation = if was_roomy == roomy { generation } else { generation + 1 };
    ui.ctx().data_mut(|d| d.insert_temp(key, (roomy, generation)));
    // Folded, the panel is its title bar alone: the out-of-view hint shows there too, short enough
    // for the narrowest panel ("out of view: Home" was cut to "out of view: H…" at 320 px; the
    // window's title and the open panel say what Home does). The id keeps the panel's state
    // across the title's change.
    // A refused key or edit says "refused" there as well: folded, the panel showed nothing of it
    // (a window under 480×360 starts folded, and without a title bar, as under Xvfb with no window
    // manager, the key looked as if it did nothing); open, the message line has it whole.
    let title = if info.out_of_view {
        "out of view"
    } else if info.message.starts_with("refused") {
        "refused"
    } else {
        "restir-vpl"
    };
    egui::Window::new(title)
        .id(key.with(generation))
        .default_pos([8.0, 8.0])
        .default_open(roomy)
        .default_width(width)
        .default_height(0.8 * screen.height())
        .resizable(true)
        .vscroll(true)
        .show(ui.ctx(), |ui| {
        ui.label(format!(
            "{} · view {} · {}×{}\n{:.1} ms/frame ({:.0} fps) · GPU {} ms\n{} frame{} accumulated{}",
            s.mode.name(),
            s.view.name(),
            s.width,
            s.height,
            info.ms_per_frame,
            1e3 / info.ms_per_frame.max(1e-3),
            if measured { format!("{:.2}", stats.gpu_ms()) } else { "–".to_string() },
            renderer.accumulated(),
            if renderer.accumulated() == 1 { "" } else { "s" },
            if info.frozen { " · FROZEN (F2 resumes, F3 steps)" } else { "" }
        ));
        if let Some(v) = renderer.vpl_summary() {
            // While flying: the last frame drew the sampling of a frame displayed alone
            // (candidates × neighbours; short, so that the line never wraps and moves the rows below).
            let moving = match v.moving_sampling {
                Some([c, n]) if stats.moving => format!(" · moving {c}×{n}"),
                _ => String::new(),
            };
            ui.label(format!("{} VPLs · {} rays/px{moving}", v.vpl_count, per_pixel(stats.rays)));
        } else {
            ui.label(format!("{} rays/px", per_pixel(stats.rays)));
        }
        // Always one line, empty or not, and truncated (the title has it whole): a message that
        // came and went moved every row below it, so a click meant for one setting landed on
        // the one above (spatial passes → boiling filter).
        let message = if info.message.is_empty() && info.out_of_view { OUT_OF_VIEW } else { info.message };
        ui.add(egui::Label::new(egui::RichText::new(message).color(egui::Color32::LIGHT_YELLOW)).truncate());
        if let Some(r) = reference {
            ui.separator();
            if (s.width, s.height) != (r.image.width, r.image.height) {
                ui.label(format!("reference is {}×{}: resize the window to compare", r.image.width, r.image.height));
            } else {
                let fmt = |v: Option<f64>| v.map(|v| format!("{v:.5}")).unwrap_or_else(|| "…".into());
                ui.label(format!("vs reference: RMSE {} · FLIP {}", fmt(r.rmse), fmt(r.flip)));
                if !info.at_first_view {
                    // (RMSE 1.1 after flying away read as a broken estimator.)
                    ui.label(egui::RichText::new("the camera has left the first view: two views compared (Home: back)").color(egui::Color32::LIGHT_YELLOW));
                }
            }
        }
        egui::CollapsingHeader::new("passes (GPU ms, rays/px)").default_open(true).show(ui, |ui| {
            egui::Grid::new("passes").striped(true).show(ui, |ui| {
                for (name, ms) in &stats.pass_ms() {
                    ui.monospace(*name);
                    ui.monospace(format!("{ms:8.3}"));
                    let rays = stats.rays_by_pass.iter().find(|(n, _)| n == name).map(|(_, r)| *r).unwrap_or(0);
                    ui.monospace(if rays > 0 { format!("{:6.2}", rays as f64 / pixels) } else { String::new() });
                    ui.end_row();
                }
            });
        });
        egui::CollapsingHeader::new("settings").default_open(true).show(ui, |ui| {
            combo(ui, "mode", &mut edited.mode, &mut what);
            if edited.mode != s.mode {
                super::fit_view_to_mode(&mut edited);
            }
            // Only the views this mode can show (others were listed, then refused with a
            // message that named command-line flags).
            let views: Vec<View> = View::ALL.iter().copied().filter(|&v| v == edited.view || super::can_show(&edited, v)).collect();
            combo_of(ui, "view", &mut edited.view, &views, &mut what);
            if super::reads_gi(&edited) && ui.checkbox(&mut edited.gi, "indirect VPLs (G)").changed() {
                what = Some("indirect VPLs".into());
            }
            if ui.checkbox(&mut edited.progressive, "progressive (P)").changed() {
                what = Some("progressive".into());
            }
            if ui.add(egui::Slider::new(&mut edited.exposure, -24.0..=24.0).text("exposure (EV)")).changed() {
                what = Some("exposure".into());
            }
            // Not in the path tracer, which reads no VPLs (a change would only restart it).
            if s.mode.uses_vpls() {
                combo(ui, "attenuation", &mut edited.attenuation, &mut what);
            }
            if edited.attenuation == Attenuation::InverseSquare {
                edited.compensate = false; // nothing to compensate (and refused by validation)
            }
            if edited.attenuation == Attenuation::Yuksel
                && s.mode.uses_vpls()
                && ui.checkbox(&mut edited.compensate, "compensate the clamp (Kollig & Keller)").changed()
            {
                what = Some("compensation".into());
            }
            if matches!(s.mode, Mode::Ris | Mode::Restir)
                && ui.add(egui::Slider::new(&mut edited.candidates, 1..=1024).logarithmic(true).text("candidates")).changed()
            {
                what = Some("candidates".into());
            }
            if s.mode == Mode::Restir {
                let width = edited.width;
                let r = &mut edited.restir;
                combo(ui, "bias", &mut r.bias, &mut what);
                if ui.checkbox(&mut r.temporal, "temporal reuse").changed() {
                    what = Some("temporal reuse".into());
                }
                if ui.add(egui::Slider::new(&mut r.mcap, 1.0..=100.0).logarithmic(true).text("M-cap")).changed() {
                    what = Some("M-cap".into());
                }
                let max_n = crate::gpu_types::MAX_SPATIAL_NEIGHBOURS;
                if ui.add(egui::Slider::new(&mut r.spatial_neighbours, 0..=max_n).text("neighbours")).changed() {
                    what = Some("spatial neighbours".into());
                }
                // A frame displayed alone with temporal history (flying; 0: as above).
                if ui.add(egui::Slider::new(&mut r.moving_candidates, 0..=64).text("candidates while moving")).changed() {
                    what = Some("candidates while moving".into());
                }
                if ui.add(egui::Slider::new(&mut r.moving_neighbours, 0..=max_n).text("neighbours while moving")).changed() {
                    what = Some("neighbours while moving".into());
                }
                // Shows the automatic radius until moved; a moved slider fixes it.
                let mut radius = r.spatial_radius_px(width);
                if ui.add(egui::Slider::new(&mut radius, 1.0..=64.0).text("radius (px)")).changed() {
                    r.spatial_radius = Some(radius);
                    what = Some("spatial radius".into());
                }
                if ui.add(egui::Slider::new(&mut r.spatial_passes, 0..=4).text("spatial passes")).changed() {
                    what = Some("spatial passes".into());
                }
                if ui.add(egui::Slider::new(&mut r.boiling_filter, 0.0..=1.0).text("boiling filter")).changed() {
                    what = Some("boiling filter".into());
                }
            }
        });
        egui::CollapsingHeader::new("keys (F1 hides this)").default_open(false).show(ui, |ui| {
            // The key in bold, then its description, wrapping as the panel's width allows (padded
            // to ten columns, a long key name such as "right mouse button" ran into its text).
            for (key, what) in actions::help_rows() {
                ui.horizontal_wrapped(|ui| {
                    ui.label(egui::RichText::new(key).monospace().strong());
                    ui.label(what);
                });
            }
        });
    });
    what.map(|w| Edit { what: format!("overlay: {w}"), settings: edited })
}

/// A combo box over a named enum's values.
fn combo<T: NamedEnum + Copy + PartialEq + 'static>(ui: &mut egui::Ui, label: &str, value: &mut T, what: &mut Option<String>) {
    combo_of(ui, label, value, T::ALL, what)
}

/// A combo box over some of a named enum's values.
fn combo_of<T: NamedEnum + Copy + PartialEq + 'static>(ui: &mut egui::Ui, label: &str, value: &mut T, values: &[T], what: &mut Option<String>) {
    egui::ComboBox::from_label(label).selected_text(value.name()).show_ui(ui, |ui| {
        for v in values {
            if ui.selectable_value(value, *v, v.name()).changed() {
                *what = Some(format!("{label} {}", v.name()));
            }
        }
    });
}
