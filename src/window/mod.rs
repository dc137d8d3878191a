//! The interactive window: winit's event loop drives the same [`Renderer`] a headless run drives,
//! one frame per redraw, and shows its preview through a swapchain. Keys map to named actions
//! ([`actions::KEYS`]); the camera follows a [`FlyController`] (or `--camera-path`).

pub mod actions;
pub mod overlay;
pub mod swapchain;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use ash::vk;
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use crate::camera::{Camera, CameraPath, FlyController, MoveKey};
use crate::headless::{finish_run, Summary};
use crate::lights::PointEmitter;
use crate::renderer::Renderer;
use crate::scene::Scene;
use crate::scene_gpu::SceneGpu;
use crate::settings::{Mode, NamedEnum, PresentMode, RenderSettings, View};
use crate::vk::image::transition;
use crate::vk::{Context, ContextOptions, Image, WindowHandles};

use actions::Action;
use overlay::{Overlay, WindowInfo};
use swapchain::Swapchain;

/// What the window needs besides the render settings.
#[derive(Clone, Debug, Default)]
pub struct WindowOptions {
    pub present_mode: PresentMode,
    /// Close after this many frames and write the outputs as a headless run does.
    pub frames: Option<u32>,
    /// A reference EXR for the overlay's split screen and live error.
    pub reference: Option<PathBuf>,
}

/// No display to open a window on.
#[derive(Debug, thiserror::Error)]
#[error("cannot open a window: {0}. No X11 or Wayland display is reachable (is DISPLAY or WAYLAND_DISPLAY set?); pass --headless to render to files instead")]
pub struct NoDisplay(pub String);

/// winit's text for an event loop that could not start, without the source location it puts in
/// front of an OS error ("os error at /root/.cargo/registry/…/mod.rs:765: neither WAYLAND_DISPLAY
/// …"): a user needs the reason, not where in winit it was found.
fn display_error_text(text: &str) -> String {
    let text = text.trim_end_matches('.');
    match text.strip_prefix("os error at ").and_then(|rest| rest.split_once(".rs:")) {
        Some((_, after)) => after.split_once(": ").map_or(after, |(_, reason)| reason).to_string(),
        None => text.to_string(),
    }
}

/// Opens a window and renders until it is closed (or `--frames N` frames). Returns the summary
/// written when the run ended with outputs (`--frames`), if any.
pub fn run(settings: RenderSettings, opts: WindowOptions) -> Result<Option<Summary>> {
    settings.validate()?;
    let start = Instant::now();
    // (The device's buffer limit is read before the window exists: the window's device is the
    // one a headless run picks, less any that cannot present.)
    let range = || crate::vk::context::storage_buffer_range(settings.device_index, settings.tracing);
    let scene = Scene::load_for_device(&settings.scene, settings.textures, &range)?;
    crate::headless::check_outputs_spare_inputs(&settings, &scene.files, opts.reference.as_deref())?;
    let reference = opts.reference.as_deref().map(|p| overlay::Reference::load(p, &settings)).transpose()?;
    // In the renderer's coordinates (the scene may have been recentred: Scene::origin).
    let path = settings.camera_path.as_deref().map(|p| CameraPath::load(p).context("--camera-path")).transpose()?.map(|p| p.moved(-scene.origin));
    let event_loop = EventLoop::new().map_err(|e| NoDisplay(display_error_text(&e.to_string())))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App { settings, opts, scene: Some(scene), reference, path, running: None, error: None, summary: None, start };
    event_loop.run_app(&mut app).context("the window's event loop failed")?;
    if let Some(e) = app.error {
        return Err(e);
    }
    Ok(app.summary)
}

struct App {
    settings: RenderSettings,
    opts: WindowOptions,
    /// The scene until it is uploaded (on the first `resumed`).
    scene: Option<Scene>,
    /// The --reference image until the overlay takes it.
    reference: Option<overlay::Reference>,
    path: Option<CameraPath>,
    running: Option<Running>,
    error: Option<anyhow::Error>,
    summary: Option<Summary>,
    start: Instant,
}

/// Below this window size (width, height) the overlay starts hidden.
const TINY_WINDOW: [u32; 2] = [240, 120];

/// Whether two cameras show the same view, to within 1e-4 of the scene's size in position and
/// ~1.4e-3 radians in direction (cosine 1 - 1e-6): a camera flown back by hand, or rebuilt from a
/// saved file, is not bit-identical to the first one.
fn same_view(a: &Camera, b: &Camera, bounds: &(glam::Vec3, glam::Vec3)) -> bool {
    let size = (bounds.1 - bounds.0).length().max(f32::MIN_POSITIVE);
    let along = |u: glam::Vec3, v: glam::Vec3| u.normalize_or_zero().dot(v.normalize_or_zero()) >= 1.0 - 1e-6;
    a.position.distance(b.position) <= 1e-4 * size && along(a.forward, b.forward) && along(a.up, b.up) && (a.yfov - b.yfov).abs() <= 1e-4
}

/// An X connection of the window's Vulkan surface's own, or nothing where there is no X.
#[cfg(any(target_os = "linux", target_os = "freebsd", target_os = "dragonfly", target_os = "netbsd", target_os = "openbsd"))]
type XConnection = x11rb::xcb_ffi::XCBConnection;
#[cfg(not(any(target_os = "linux", target_os = "freebsd", target_os = "dragonfly", target_os = "netbsd", target_os = "openbsd")))]
type XConnection = ();

/// On X11 the Vulkan surface gets a connection to the X server of its own, not winit's: the
/// driver presents through the connection the surface names, and on winit's one the X error of a
/// present to a window another program had just destroyed (BadDrawable from lavapipe's PutImage)
/// went to winit's error handler and came back as the failure of winit's next request, which it
/// panics on ("Failed to set window title", "Failed to unfocus input context": 3 of 24 closes by
/// `xdotool windowclose`). On its own connection the driver sees its errors itself and reports a
/// lost surface, which ends the run as a closed window. Other window systems keep their handles.
#[cfg(any(target_os = "linux", target_os = "freebsd", target_os = "dragonfly", target_os = "netbsd", target_os = "openbsd"))]
fn own_x_connection(handles: WindowHandles) -> Result<(Option<XConnection>, WindowHandles)> {
    use raw_window_handle::{RawDisplayHandle, RawWindowHandle, XcbDisplayHandle, XcbWindowHandle};
    let window = match handles.window {
        RawWindowHandle::Xlib(w) => u32::try_from(w.window).ok(),
        RawWindowHandle::Xcb(w) => Some(w.window.get()),
        _ => None,
    };
    let (Some(window), RawDisplayHandle::Xlib(_) | RawDisplayHandle::Xcb(_)) = (window.and_then(std::num::NonZeroU32::new), handles.display) else {
        return Ok((None, handles));
    };
    // The display winit opened: $DISPLAY, as here. Without a second connection (a server at its
    // client limit) the surface shares winit's, as before.
    let (conn, screen) = match x11rb::xcb_ffi::XCBConnection::connect(None) {
        Ok(c) => c,
        Err(e) => {
            log::warn!("the window surface's own X connection could not be opened ({e}); it shares the window's, where closing the window from another program may end in a panic inside winit");
            return Ok((None, handles));
        }
    };
    let Some(raw) = std::ptr::NonNull::new(conn.get_raw_xcb_connection()) else {
        return Ok((None, handles));
    };
    let display = RawDisplayHandle::Xcb(XcbDisplayHandle::new(Some(raw), screen as i32));
    let window = RawWindowHandle::Xcb(XcbWindowHandle::new(window));
    Ok((Some(conn), WindowHandles { display, window }))
}

#[cfg(not(any(target_os = "linux", target_os = "freebsd", target_os = "dragonfly", target_os = "netbsd", target_os = "openbsd")))]
fn own_x_connection(handles: WindowHandles) -> Result<(Option<XConnection>, WindowHandles)> {
    Ok((None, handles))
}

/// Everything alive while the window is open. Field order is drop order: GPU objects first, the
/// context after them, the window last (the surface must go before it).
struct Running {
    ui: Overlay,
    presenter: Presenter,
    swapchain: Swapchain,
    renderer: Renderer,
    scene: Arc<SceneGpu>,
    ctx: Arc<Context>,
    controller: FlyController,
    /// Frames shown since the window opened.
    frames: u32,
    /// The window frame at which `--camera-path` (last) started: Home plays it again.
    path_from: u32,
    /// The frame label of the last F4 dump: a later one takes a higher label even when no frame
    /// was shown between them (F2, then F4 twice, wrote one frame_NNNN folder over the other).
    last_dump_label: Option<u32>,
    /// Time spent frozen since the timed frames began (left out of `displayed`'s frame time).
    frozen_total: std::time::Duration,
    /// F2: when the freeze going on began (None: not frozen).
    frozen_since: Option<Instant>,
    /// The window is fully covered or minimised (winit's `Occluded`; X11 reports a window covered
    /// by others, not one unmapped).
    hidden: bool,
    /// When the pause while hidden began: frames displayed alone are not rendered while nobody
    /// can see them (an accumulation goes on); its time is left out as a freeze's is.
    paused_since: Option<Instant>,
    /// When the third frame was shown (after warm-up), and the last one.
    timed_from: Option<Instant>,
    last_shown: Option<Instant>,
    step: bool,
    /// Frozen: show the last frame again with the overlay redrawn (an input changed what it shows).
    refresh: bool,
    overlay: bool,
    /// The window's inner size as its last `Resized` event gave it: asking the window instead is
    /// a round trip to the X server that winit unwraps, so it panicked once another program had
    /// destroyed the window.
    size: winit::dpi::PhysicalSize<u32>,
    /// Another program destroyed the window: no event is handled after that (a redraw already
    /// queued would ask the gone window its size through egui).
    destroyed: bool,
    /// Enter wrote the outputs at least once (what the warning of a run closed early says).
    saved: bool,
    resize_pending: bool,
    looking: bool,
    cursor: Option<(f64, f64)>,
    last_frame: Instant,
    /// The next frame's interval is not a frame time (after a freeze or a step).
    timing_restarts: bool,
    /// The clock of key events and camera updates.
    clock: Instant,
    last_title: Instant,
    /// Exponentially smoothed ms per frame (wall) for the title.
    smoothed_ms: f64,
    /// Latest status message (errors of refused actions, saved files).
    message: String,
    /// The message as last seen by the title and since when: a message is cleared after
    /// `MESSAGE_SECONDS` (a "camera loaded" or "wrote …" stayed for hundreds of frames).
    message_since: (String, Instant),
    /// The fly camera sees none of the scene's bounds (the title then says how to come back: a
    /// view that flew out of the scene is black and looked like a fault).
    out_of_view: bool,
    /// The surface's own X connection (X11; `own_x_connection`), closed after the context has
    /// destroyed the surface.
    x_connection: Option<XConnection>,
    window: Arc<Window>,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_some() {
            return;
        }
        match self.open(event_loop) {
            Ok(r) => self.running = Some(r),
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        if let Err(e) = self.handle(event_loop, event) {
            self.error = Some(e);
            event_loop.exit();
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let path = self.path.as_ref();
        let counting = self.opts.frames.is_some();
        if let Some(r) = self.running.as_mut().filter(|r| !r.destroyed) {
            // Hidden, a frame that would be displayed alone (camera path playing, progressive
            // off) is seen by nobody: none is rendered until the window shows again. A still
            // camera's accumulation goes on (F2 freezes it), and so does a --frames run.
            let paused = r.hidden && !r.frozen() && !counting && !r.next_frame_accumulates(path);
            match (paused, r.paused_since) {
                (true, None) => {
                    r.paused_since = Some(Instant::now());
                    log::info!("window hidden: paused, since its frames are displayed alone (none accumulates); it resumes when shown");
                }
                (false, Some(since)) => {
                    r.frozen_total += r.timed_span(since, Instant::now());
                    r.paused_since = None;
                    r.timing_restarts = true; // the paused time is no frame's
                    log::info!("window: the pause while hidden ends (shown again, frozen, or accumulating)");
                }
                _ => {}
            }
            let drawing = !paused && (!r.frozen() || r.step || r.refresh) && r.size.width > 0 && r.size.height > 0;
            if drawing {
                event_loop.set_control_flow(ControlFlow::Poll);
                r.window.request_redraw();
            } else {
                // Frozen, hidden or minimised: sleep until an event (a key, a resize, shown again)
                // instead of spinning.
                event_loop.set_control_flow(ControlFlow::Wait);
            }
        }
    }

    fn exiting(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(r) = &mut self.running {
            // Closed by its user, the run has no summary for main to check (with --frames main
            // checks it, after printing it): the frames in flight complete so that their
            // non-finite samples count, and it fails under validation as a headless run does.
            if self.error.is_none() && self.summary.is_none() {
                if let Some(n) = self.opts.frames {
                    // Closed before --frames ended the run: say what is on disk.
                    let what = match (r.saved, &self.settings.out_dir) {
                        (true, _) => "the outputs are those Enter wrote last".to_string(),
                        (false, Some(_)) => "no outputs were written (Enter writes them at any frame)".to_string(),
                        (false, None) => "no outputs were written (none without --out)".to_string(),
                    };
                    log::warn!("closed after {} of --frames {n} frames: {what}", r.frames);
                }
                if let Err(e) = r.renderer.complete_all().and_then(|_| r.ctx.ensure_clean_for(self.settings.validate)) {
                    self.error = Some(e.context("the window's run"));
                }
            }
            // Waiting for idle before everything is dropped.
            r.ctx.wait_idle_for_drop();
            if r.ctx.is_hung() {
                // A hung context destroys neither its swapchain nor its surface (its Drop), and
                // the driver may use their X connection until the process exits: left open.
                std::mem::forget(r.x_connection.take());
            }
        }
        self.running = None;
    }
}

impl App {
    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<Running> {
        let s = &self.settings;
        let attrs = Window::default_attributes()
            .with_title("restir-vpl")
            .with_inner_size(winit::dpi::PhysicalSize::new(s.width, s.height));
        let window = Arc::new(event_loop.create_window(attrs).context("creating the window")?);
        let handles = WindowHandles {
            display: window.display_handle().context("the window's display handle")?.as_raw(),
            window: window.window_handle().context("the window's handle")?.as_raw(),
        };
        let (x_connection, handles) = own_x_connection(handles)?;
        let ctx = Arc::new(Context::new(&ContextOptions {
            validate: s.validate,
            device_index: s.device_index,
            window: Some(handles),
            tracing: s.tracing,
        })?);
        let scene_cpu = self.scene.take().context("the scene was already uploaded")?;
        let scene = Arc::new(SceneGpu::new(&ctx, &scene_cpu, s.textures, s.merge_blas).context("uploading the scene")?);
        let size = window.inner_size();
        // The folded panel's title bar (~120×30 px) hid half of a 100×60 window and all of a
        // 40×30 one: a window that small starts without the overlay (F1 shows it; the title says
        // what it would).
        let overlay = size.width >= TINY_WINDOW[0] && size.height >= TINY_WINDOW[1];
        if !overlay {
            log::info!("window {}×{}: the overlay starts hidden below {}×{} (F1 shows it)", size.width, size.height, TINY_WINDOW[0], TINY_WINDOW[1]);
        }
        let swapchain = Swapchain::new(&ctx, vk::Extent2D { width: size.width, height: size.height }, self.opts.present_mode, None)?;
        // The render size follows the window.
        self.settings.width = swapchain.extent.width;
        self.settings.height = swapchain.extent.height;
        // --mode bruteforce at a size the window would refuse on a key press: start in ReSTIR.
        let mut message = String::new();
        if let Some(why) = interactive_bruteforce_refusal(&self.settings, None, &ctx.report.kind) {
            self.settings.mode = Mode::Restir;
            message = format!("refused: {why}; started in mode restir");
            log::warn!("{message}");
        }
        // A reference of another size is compared only once the window has its size: said here
        // and in the title (the overlay's line that said it is folded away in a small window).
        if let Some(r) = self.reference.as_ref().filter(|r| (r.image.width, r.image.height) != (self.settings.width, self.settings.height)) {
            let note = format!(
                "--reference is {}×{} and the window {}×{}: resize the window to compare",
                r.image.width, r.image.height, self.settings.width, self.settings.height
            );
            log::warn!("{note}");
            if message.is_empty() {
                message = note;
            }
        }
        // (Whatever the view: V reaches the VPL view later.)
        if let Some(w) = Renderer::vpl_radius_warning(&self.settings, &scene) {
            log::warn!("{w}");
        }
        let renderer = Renderer::new(ctx.clone(), scene.clone(), self.settings.clone())?;
        let presenter = Presenter::new(&ctx, &swapchain)?;
        let ui = Overlay::new(&ctx, &window, &swapchain, PRESENT_SLOTS, self.reference.take())?;
        let (lo, hi) = scene.info.bounds;
        // The scene's up: --up where given, else glTF's +Y.
        let world_up = self.settings.camera.as_ref().map_or(glam::Vec3::Y, |c| c.up);
        let controller = FlyController::new(&renderer.initial_camera(), (hi - lo).length(), world_up);
        log::info!("window: {}", ctx.report);
        Ok(Running {
            ui,
            presenter,
            swapchain,
            renderer,
            scene,
            ctx,
            controller,
            frames: 0,
            path_from: 0,
            last_dump_label: None,
            frozen_total: std::time::Duration::ZERO,
            frozen_since: None,
            hidden: false,
            paused_since: None,
            timed_from: None,
            last_shown: None,
            step: false,
            refresh: false,
            overlay,
            size,
            destroyed: false,
            saved: false,
            resize_pending: false,
            looking: false,
            cursor: None,
            last_frame: Instant::now(),
            timing_restarts: false,
            clock: Instant::now(),
            last_title: Instant::now(),
            smoothed_ms: 0.0,
            message,
            message_since: (String::new(), Instant::now()),
            out_of_view: false,
            x_connection,
            window,
        })
    }

    fn handle(&mut self, event_loop: &ActiveEventLoop, event: WindowEvent) -> Result<()> {
        let Some(r) = self.running.as_mut() else { return Ok(()) };
        if r.destroyed {
            return Ok(());
        }
        // Another program destroyed the window (xdotool windowclose, xkill -id): the run ends as
        // if it had been closed.
        if matches!(event, WindowEvent::Destroyed) {
            log::warn!("the window was destroyed by another program; closing");
            r.destroyed = true;
            event_loop.exit();
            return Ok(());
        }
        if r.frozen() && !matches!(event, WindowEvent::RedrawRequested) {
            // No frame redraws the overlay and the title while frozen: an input (a key, the
            // pointer over the panel, a resize) shows the last frame again with them redrawn.
            r.refresh = true;
        }
        // Tab is kept from the panel: egui moves keyboard focus to its next widget on Tab, and the
        // keys then went to that widget (a collapsed panel's title button, with no sign of it)
        // instead of the shortcuts until Esc or a click in the image.
        let tab = matches!(&event, WindowEvent::KeyboardInput { event, .. } if event.physical_key == PhysicalKey::Code(KeyCode::Tab));
        if r.overlay && !tab && !matches!(event, WindowEvent::RedrawRequested) {
            // The panel takes the pointer over it, and the keys while one of its widgets has focus.
            let consumed = r.ui.on_window_event(&r.window, &event);
            let keyboard = matches!(event, WindowEvent::KeyboardInput { .. });
            // Key releases always reach the controller: a movement key held when a widget took
            // focus would otherwise stay down and the camera fly on.
            let release = matches!(&event, WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Released);
            if consumed && !release && (!keyboard || r.ui.wants_keyboard()) && !matches!(event, WindowEvent::Resized(_) | WindowEvent::Occluded(_) | WindowEvent::CloseRequested) {
                return Ok(());
            }
        }
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            // Releases made while another window has focus never arrive here.
            WindowEvent::Focused(false) => {
                r.controller.release_all(r.clock.elapsed().as_secs_f64());
                r.looking = false;
            }
            WindowEvent::Resized(size) => {
                r.size = size;
                r.resize_pending = true;
            }
            WindowEvent::Occluded(hidden) => {
                if hidden && !r.hidden {
                    // Keys held now would fly the camera where nobody sees it.
                    r.controller.release_all(r.clock.elapsed().as_secs_f64());
                    r.looking = false;
                }
                r.hidden = hidden;
            }
            WindowEvent::KeyboardInput { event, is_synthetic, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else { return Ok(()) };
                let down = event.state == ElementState::Pressed;
                let t = r.clock.elapsed().as_secs_f64();
                let movement = match code {
                    KeyCode::KeyW => Some(MoveKey::Forward),
                    KeyCode::KeyS => Some(MoveKey::Back),
                    KeyCode::KeyA => Some(MoveKey::Left),
                    KeyCode::KeyD => Some(MoveKey::Right),
                    KeyCode::Space => Some(MoveKey::Up),
                    KeyCode::ControlLeft => Some(MoveKey::Down),
                    _ => None,
                };
                match (movement, code) {
                    (Some(key), _) => {
                        if down && self.path.is_some() {
                            r.message = FOLLOWS_PATH.to_string();
                        }
                        r.controller.key(key, down, t);
                    }
                    (None, KeyCode::ShiftLeft | KeyCode::ShiftRight) => r.controller.set_fast(down),
                    (None, _) => {
                        // Not the presses winit makes up, on X11, for keys already down when the
                        // window gains focus: Esc held to close a dialog over the window quit the
                        // renderer, a held Return wrote its outputs, a workspace switch's digit
                        // changed the mode. (Held movement keys above still count.)
                        if down && !event.repeat && !is_synthetic {
                            if let Some(action) = actions::action_for(code) {
                                self.act(event_loop, action)?;
                            }
                        }
                    }
                }
            }
            WindowEvent::MouseInput { button: MouseButton::Right, state, .. } => {
                r.looking = state == ElementState::Pressed;
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let (true, Some((x, y))) = (r.looking, r.cursor) {
                    r.controller.look((position.x - x) as f32, (position.y - y) as f32);
                }
                r.cursor = Some((position.x, position.y));
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let notches = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => (p.y / 40.0) as f32,
                };
                r.controller.scroll(notches);
                // Said, as nothing else shows it (after a few notches one tap of W went through a
                // wall without a word).
                let v = r.controller.speed;
                let shown = if (0.01..1e4).contains(&v) { format!("{v:.3}") } else { format!("{v:.2e}") };
                r.message = format!("fly speed {shown} scene units/s (scroll wheel: ×1.25 a notch; Shift: ×6)");
            }
            WindowEvent::RedrawRequested => self.frame(event_loop)?,
            _ => {}
        }
        Ok(())
    }

    /// Applies a settings change (one that changes nothing, or only the exposure, keeps the
    /// accumulation: `Renderer::apply_settings`); a refused one (e.g. brute force over the pair limit) leaves
    /// everything as it was and says why.
    fn change(&mut self, what: &str, edit: impl FnOnce(&mut RenderSettings)) -> Result<()> {
        let r = self.running.as_mut().expect("called while running");
        let mut s = r.renderer.settings().clone();
        edit(&mut s);
        if let Some(why) = interactive_bruteforce_refusal(&s, r.traced_vpls(), &r.ctx.report.kind) {
            r.message = format!("refused: {why}");
            log::warn!("{what}: refused: {why}");
            return Ok(());
        }
        match r.renderer.apply_settings(s.clone()) {
            Ok(()) => {
                r.message = match view_hint(&s) {
                    Some(hint) => format!("{what} ({hint})"),
                    None => what.to_string(),
                };
                self.settings = s;
                log::info!("{}", r.message);
            }
            Err(e) => {
                r.message = format!("refused: {e:#}");
                log::warn!("{what}: refused: {e:#}");
            }
        }
        Ok(())
    }

    fn act(&mut self, event_loop: &ActiveEventLoop, action: Action) -> Result<()> {
        let r = self.running.as_mut().expect("called while running");
        match action {
            Action::SetMode(mode) => self.change(&format!("mode {}", mode.name()), |s| {
                s.mode = mode;
                fit_view_to_mode(s);
            })?,
            Action::ToggleGi if !reads_gi(r.renderer.settings()) => {
                // A change would restart the accumulation for a setting the path tracer never reads.
                r.message = "global illumination: the path tracer reads no VPLs (only its view vpls shows them)".to_string();
            }
            Action::ToggleGi => {
                let gi = !r.renderer.settings().gi;
                self.change(&format!("global illumination {}", if gi { "on" } else { "off" }), |s| s.gi = gi)?
            }
            Action::NextView | Action::PreviousView | Action::FinalView => {
                let current = r.renderer.settings().clone();
                let view = match action {
                    Action::FinalView => View::Final,
                    _ => next_valid_view(&current, action == Action::NextView),
                };
                self.change(&format!("view {}", view.name()), |s| s.view = view)?
            }
            Action::MoreCandidates | Action::FewerCandidates
                if !matches!(r.renderer.settings().mode, Mode::Ris | Mode::Restir) =>
            {
                // A change would restart the accumulation for a setting the mode never reads.
                r.message = format!("RIS candidates: mode {} draws none (ris and restir do)", r.renderer.settings().mode.name());
            }
            Action::MoreCandidates | Action::FewerCandidates => {
                let c = r.renderer.settings().candidates;
                let next = if action == Action::MoreCandidates { (c * 2).min(1024) } else { (c / 2).max(1) };
                if next == c {
                    r.message = format!("{c} RIS candidate{}: the {} there is", if c == 1 { "" } else { "s" }, if c == 1 { "fewest" } else { "most" });
                } else {
                    self.change(&format!("{next} RIS candidate{}", if next == 1 { "" } else { "s" }), |s| s.candidates = next)?
                }
            }
            Action::ToggleProgressive => {
                let p = !r.renderer.settings().progressive;
                self.change(&format!("progressive accumulation {}", if p { "on" } else { "off" }), |s| s.progressive = p)?
            }
            Action::SpawnLight | Action::RemoveLight => {
                let mut extra = r.renderer.extra_lights().to_vec();
                if action == Action::SpawnLight {
                    let camera = r.camera_on_screen(self.path.as_ref());
                    extra.push(spawned_light(&camera, &r.scene));
                } else if extra.pop().is_none() {
                    r.message = "no spawned light to remove".into();
                    return Ok(());
                }
                let n = extra.len();
                match r.renderer.set_extra_lights(extra) {
                    Ok(()) => r.message = format!("{n} spawned light(s); VPLs traced again"),
                    Err(e) => r.message = format!("refused: {e:#}"),
                }
            }
            // Writing can fail (a full disk, a read-only --out): the message says so and the
            // window stays, as a refused setting does.
            Action::SaveImage => {
                let outputs = Vec::new();
                let displayed = r.displayed(r.swapchain.mode);
                r.message = match finish_run(&r.ctx, &r.scene, &mut r.renderer, r.frames, self.opts.frames, outputs, Vec::new(), self.start, displayed) {
                    Ok(summary) => {
                        r.saved |= self.settings.out_dir.is_some();
                        let json = self.settings.out_dir.as_ref().map(|d| format!(", {}", d.join("summary.json").display())).unwrap_or_default();
                        format!("wrote {}{json}", summary.outputs.join(", "))
                    }
                    Err(e) => format!("saving failed: {e:#}"),
                };
                log::info!("{}", r.message);
            }
            Action::SaveCamera if self.settings.camera_path.as_deref().is_some_and(|p| crate::output::same_file(p, &camera_file(&self.settings))) => {
                // The saved camera would replace the path the window follows.
                r.message = format!("not saved: {} is the --camera-path", camera_file(&self.settings).display());
            }
            Action::SaveCamera => {
                let file = camera_file(&self.settings);
                let camera = r.camera_on_screen(self.path.as_ref());
                let written = file
                    .parent()
                    .filter(|d| !d.as_os_str().is_empty())
                    .map_or(Ok(()), std::fs::create_dir_all)
                    // In the file's coordinates, as --eye and --camera-path take them.
                    .and_then(|()| std::fs::write(&file, CameraPath::still(&camera.moved(r.scene.info.origin)).to_json()));
                r.message = match written {
                    Ok(()) => format!("camera saved to {}", file.display()),
                    Err(e) => format!("saving the camera to {} failed: {e}", file.display()),
                };
            }
            Action::HomeCamera if self.path.is_some() => {
                r.path_from = r.frames;
                r.message = "camera path: playing again from its first keyframe".into();
            }
            Action::LoadCamera if self.path.is_some() => r.message = FOLLOWS_PATH.to_string(),
            Action::LoadCamera => {
                let file = camera_file(&self.settings);
                match CameraPath::load(&file) {
                    Ok(p) => {
                        r.controller.set_camera(&p.at(0.0).moved(-r.scene.info.origin));
                        r.message = format!("camera loaded from {}", file.display());
                    }
                    Err(e) => r.message = format!("{e:#}"),
                }
            }
            Action::HomeCamera => r.controller.go_home(),
            Action::ToggleOverlay => r.overlay = !r.overlay,
            Action::Freeze => {
                r.timing_restarts = true; // the frozen time is no frame's
                let now = Instant::now();
                if let Some(since) = r.frozen_since.take() {
                    r.frozen_total += r.timed_span(since, now);
                    r.message = "resumed".into();
                } else {
                    r.frozen_since = Some(now);
                    // The frames in flight end now, so the summary's frame times leave the frozen
                    // time out, and the title says so at once (no frame redraws the overlay).
                    r.renderer.complete_all()?;
                    r.message = "frozen: F2 resumes, F3 renders one frame".into();
                    r.update_title(now);
                }
            }
            Action::Step => {
                r.step = r.frozen();
                r.timing_restarts = true;
            }
            Action::RenderDocCapture => {
                let camera = r.next_camera(self.path.as_ref());
                let mut rd = crate::vk::renderdoc::Capturer::attach(&r.ctx);
                if rd.attached() {
                    r.renderer.complete_all()?;
                    rd.start();
                    r.renderer.render_frame(&camera, true)?;
                    rd.end();
                    r.message = "RenderDoc: one frame captured".into();
                } else {
                    r.message = crate::vk::renderdoc::WINDOW_HOW_TO_CAPTURE.into();
                }
                log::info!("{}", r.message);
            }
            Action::DumpPasses => {
                let camera = r.next_camera(self.path.as_ref());
                let (stats, captured) = r.renderer.render_frame_captured(&camera, true)?;
                let s = r.renderer.settings().clone();
                let dir = s.out_dir.clone().unwrap_or_else(|| PathBuf::from(".")).join("passes");
                let plan = r.renderer.last_plan().context("a frame was just recorded")?.clone();
                let variance = Some(r.renderer.read_variance()?);
                let vpls = r.renderer.read_vpls()?;
                let label = r.last_dump_label.map_or(r.frames, |l| r.frames.max(l + 1));
                r.last_dump_label = Some(label);
                let written = crate::dump::write_frame(&dir, label, s.width, s.height, &s, &plan, &stats, &captured, variance, r.renderer.log(), &mut Default::default())
                    .and_then(|frame| crate::dump::write_inspector(&dir, &[frame]))
                    .and_then(|page| {
                        // The VPLs beside the page, as a headless dump writes them; a mode
                        // without VPLs leaves none (an earlier F4's would read as this frame's).
                        let ply = dir.join("vpls.ply");
                        match &vpls {
                            Some(v) => crate::ply::write_vpls(&ply, v, r.scene.info.origin)?,
                            None if ply.is_file() => std::fs::remove_file(&ply).with_context(|| format!("removing {}", ply.display()))?,
                            None => {}
                        }
                        Ok(page)
                    });
                r.message = match written {
                    Ok(page) => format!("passes written: {}", page.display()),
                    Err(e) => format!("writing the passes failed: {e:#}"),
                };
                log::info!("{}", r.message);
            }
            Action::Quit => event_loop.exit(),
        }
        Ok(())
    }

    /// Renders and shows one frame.
    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let r = self.running.as_mut().expect("called while running");
        // Frozen without F3: no frame; the last one is shown again with the overlay and the title
        // redrawn when an input asked for it.
        let mut refresh_only = r.frozen() && !r.step;
        if refresh_only && !std::mem::take(&mut r.refresh) {
            return Ok(());
        }
        r.step = false;
        let now = Instant::now();
        let dt = (now - r.last_frame).as_secs_f32();
        r.last_frame = now;
        if r.resize_pending {
            let size = r.size;
            if size.width == 0 || size.height == 0 {
                return Ok(()); // minimised: nothing to show until restored
            }
            // Nothing may use the old swapchain or targets while they are replaced.
            r.ctx.wait_idle()?;
            let wanted = vk::Extent2D { width: size.width, height: size.height };
            r.swapchain = match Swapchain::new(&r.ctx, wanted, self.opts.present_mode, Some(&r.swapchain)) {
                Ok(sc) => sc,
                // The surface went to zero area while the window still reported a size (being
                // minimised): try again on a later frame.
                Err(e) if e.is::<swapchain::NoArea>() => return Ok(()),
                Err(e) => return Err(e),
            };
            r.resize_pending = false;
            r.presenter = Presenter::new(&r.ctx, &r.swapchain)?;
            r.ui.set_swapchain(&r.swapchain)?;
            let (w, h) = (r.swapchain.extent.width, r.swapchain.extent.height);
            // A swapchain recreated at the same size (out of date, suboptimal) keeps the renderer
            // and what it has accumulated.
            if (w, h) != (r.renderer.settings().width, r.renderer.settings().height) {
                let mut s = r.renderer.settings().clone();
                (s.width, s.height) = (w, h);
                // Brute force that a key press would refuse at this size is refused here too: a
                // window grown from 24×16 to 200×150 started a frame of ~30 minutes on lavapipe.
                if let Some(why) = interactive_bruteforce_refusal(&s, r.traced_vpls(), &r.ctx.report.kind) {
                    s.mode = Mode::Restir;
                    r.message = format!("refused at {w}×{h}: {why}; switched to mode restir");
                    log::warn!("{}", r.message);
                }
                match r.renderer.apply_settings(s.clone()) {
                    Ok(()) => {}
                    // Brute force refused by the renderer at the new size (its pair limit is above
                    // the window's, checked above; this is any other refusal): fall back to ReSTIR
                    // rather than close the window.
                    Err(e) if s.mode == Mode::Bruteforce => {
                        s.mode = Mode::Restir;
                        r.renderer.apply_settings(s).with_context(|| format!("resizing to {w}×{h}"))?;
                        r.message = format!("refused at {w}×{h}: {e:#}; switched to mode restir");
                        log::warn!("{}", r.message);
                    }
                    Err(e) => return Err(e.context(format!("resizing to {w}×{h}"))),
                }
                self.settings = r.renderer.settings().clone();
                // The frame targets are new: there is no last frame to show again.
                refresh_only = false;
            }
        }
        let camera = match &self.path {
            _ if refresh_only => None,
            Some(p) => Some(p.at(r.path_frame(r.frames))),
            None => {
                r.controller.update(r.clock.elapsed().as_secs_f64());
                let camera = r.controller.camera();
                let (lo, hi) = r.scene.info.bounds;
                let s = r.renderer.settings();
                r.out_of_view = !camera.sees_box(lo, hi, s.width as f32 / s.height.max(1) as f32);
                Some(camera)
            }
        };
        let draw_ui = r.overlay || r.ui.has_reference();
        let edit = if draw_ui {
            // Only a --reference reads it. (A frame shown again, frozen, has no new camera: the
            // one it shows.)
            let at_first_view = !r.ui.has_reference() || {
                let shown = camera.unwrap_or_else(|| match &self.path {
                    Some(p) => p.at(r.path_frame(r.frames)),
                    None => r.controller.camera(),
                });
                same_view(&shown, &r.renderer.initial_camera(), &r.scene.info.bounds)
            };
            let info = WindowInfo { ms_per_frame: r.smoothed_ms, message: &r.message, frozen: r.frozen(), out_of_view: r.out_of_view, at_first_view };
            let edit = r.ui.prepare(&r.window, r.size, &r.renderer, &info, r.overlay)?;
            if r.ui.has_texture_deltas() {
                // Every earlier overlay that may sample those textures has finished: waits with the
                // hang diagnosis and RESTIR_VPL_GPU_TIMEOUT_S (the renderer's frames too, since the
                // texture upload waits for the whole queue).
                r.renderer.complete_all()?;
                r.presenter.wait_all(&r.ctx)?;
                r.ui.apply_texture_deltas()?;
            }
            edit
        } else {
            None
        };
        let ui = if draw_ui { Some(&mut r.ui) } else { None };
        match r.presenter.show(&r.ctx, &r.swapchain, &mut r.renderer, camera.as_ref(), ui)? {
            Shown::Yes => {}
            Shown::YesRecreate => r.resize_pending = true,
            Shown::SurfaceLost => {
                // As a Destroyed event: the run ends as if the window had been closed.
                log::warn!("the window was destroyed by another program; closing");
                r.destroyed = true;
                event_loop.exit();
                return Ok(());
            }
            shown @ (Shown::OutOfDate | Shown::NotReady) => {
                if matches!(shown, Shown::OutOfDate) {
                    r.resize_pending = true;
                } else {
                    log::debug!("no swapchain image within {} ms: frame skipped", ACQUIRE_TIMEOUT_NS / 1_000_000);
                }
                // The overlay's input was taken by prepare(): apply its edit even so.
                if let Some(e) = edit {
                    self.change(&e.what, |s| *s = e.settings)?;
                }
                return Ok(());
            }
        }
        if refresh_only {
            // An edit's message, and egui's own second pass after some inputs (a combo box
            // opening), need one more refresh.
            let edited = edit.is_some();
            if let Some(e) = edit {
                self.change(&e.what, |s| *s = e.settings)?;
            }
            let r = self.running.as_mut().expect("called while running");
            r.update_title(now);
            r.refresh = edited || r.ui.repaint_soon();
            return Ok(());
        }
        r.frames += 1;
        if r.frozen() {
            // A frame stepped with F3 ends now, not when the next step or the resume reuses its slot.
            r.renderer.complete_all()?;
        }
        let shown = Instant::now();
        if r.frames == 3 {
            r.timed_from = Some(shown);
        }
        r.last_shown = Some(shown);
        // A frame after a freeze or a step took as long as the GPU took (the wait was the user's);
        // otherwise a time-weighted average over the last ~0.5 s, so that after a switch to a
        // slower mode the figure follows within a frame or two instead of lagging for ten frames.
        let ms = if std::mem::take(&mut r.timing_restarts) { r.renderer.last_stats().gpu_ms() } else { dt as f64 * 1e3 };
        let weight = 1.0 - (-ms / 500.0).exp();
        r.smoothed_ms = if r.frames <= 2 { ms } else { r.smoothed_ms + weight * (ms - r.smoothed_ms) };
        if now.duration_since(r.last_title).as_secs_f64() > 0.25 {
            r.update_title(now);
        }
        if let Some(e) = edit {
            self.change(&e.what, |s| *s = e.settings)?;
        }
        let r = self.running.as_mut().expect("called while running");
        if r.frozen() && (r.overlay || r.ui.has_reference()) && r.ui.repaint_soon() {
            // A frame rendered while frozen (F3, or a resize's new targets) whose overlay egui
            // wants drawn once more: a panel shown for the first time (a resize across 480×360
            // makes a new one) is invisible on its first pass, so the frozen window showed no
            // overlay at all until the pointer moved.
            r.refresh = true;
        }
        if self.opts.frames == Some(r.frames) {
            let displayed = r.displayed(r.swapchain.mode);
            let summary = finish_run(&r.ctx, &r.scene, &mut r.renderer, r.frames, self.opts.frames, Vec::new(), Vec::new(), self.start, displayed)?;
            self.summary = Some(summary);
            event_loop.exit();
        }
        Ok(())
    }
}

impl Running {
    /// F2: the frame loop is frozen.
    fn frozen(&self) -> bool {
        self.frozen_since.is_some()
    }

    /// Writes the window's title (mode, frame time, accumulation, view and status message) and
    /// lets a status message go after `MESSAGE_SECONDS`.
    fn update_title(&mut self, now: Instant) {
        if self.message != self.message_since.0 {
            self.message_since = (self.message.clone(), now);
        } else if !self.message.is_empty() && now.duration_since(self.message_since.1).as_secs_f64() > MESSAGE_SECONDS {
            self.message.clear();
        }
        self.last_title = now;
        let s = self.renderer.settings();
        let accumulated = self.renderer.accumulated();
        let timing = if self.frozen() {
            "frozen (F2 resumes, F3 renders one frame)".to_string()
        } else {
            // No timed frame since a settings change: "–", as the overlay shows (the empty sum
            // printed "GPU -0.0 ms").
            let stats = self.renderer.last_stats();
            let gpu = if stats.dispatch_ms.is_empty() { "–".to_string() } else { format!("{:.1}", stats.gpu_ms()) };
            format!("{:.1} ms/frame ({:.0} fps, GPU {gpu} ms)", self.smoothed_ms, 1e3 / self.smoothed_ms.max(1e-3))
        };
        let view = if s.view != View::Final && !self.message.contains(&format!("view {}", s.view.name())) {
            format!(" · view {}", s.view.name())
        } else {
            String::new()
        };
        let mut message = if self.message.is_empty() || self.message.starts_with("frozen") { String::new() } else { format!(" · {}", self.message) };
        if self.out_of_view {
            message += &format!(" · {}", overlay::OUT_OF_VIEW);
        }
        self.window.set_title(&format!(
            "restir-vpl — {} · {timing} · {accumulated} frame{} accumulated{view}{message}",
            s.mode.name(),
            if accumulated == 1 { "" } else { "s" },
        ));
    }

    /// The VPL set traced now and the settings it was traced with (brute force's refusal).
    fn traced_vpls(&self) -> Option<(&crate::passes::PhotonStats, crate::settings::PhotonSettings)> {
        self.renderer.photon_stats().map(|p| (p, self.renderer.settings().photon_settings()))
    }

    /// The path's frame for window frame `frame` (the path starts again at `path_from`: Home).
    fn path_frame(&self, frame: u32) -> f32 {
        frame.saturating_sub(self.path_from) as f32
    }

    /// The camera of the frame on screen: frame() shows frame k from the path's frame k, then
    /// counts it.
    fn camera_on_screen(&self, path: Option<&CameraPath>) -> Camera {
        path.map_or_else(|| self.controller.camera(), |p| p.at(self.path_frame(self.frames.saturating_sub(1))))
    }

    /// Whether the next frame adds to the accumulation: progressive on, its camera the one on
    /// screen (a camera path holds its last keyframe once played) and no movement key held (a
    /// covered window may keep the keyboard).
    fn next_frame_accumulates(&self, path: Option<&CameraPath>) -> bool {
        self.renderer.settings().progressive
            && self.next_camera(path).same_view(&self.camera_on_screen(path))
            && (path.is_some() || !self.controller.moving())
    }

    /// The camera of the next frame (what a key that renders one, F4 or F12, renders).
    fn next_camera(&self, path: Option<&CameraPath>) -> Camera {
        path.map_or_else(|| self.controller.camera(), |p| p.at(self.path_frame(self.frames)))
    }

    /// The part of `[a, b]` after the timed frames began.
    fn timed_span(&self, a: Instant, b: Instant) -> std::time::Duration {
        self.timed_from.map_or(std::time::Duration::ZERO, |from| b.saturating_duration_since(a.max(from)))
    }

    /// Frames per second as shown, from the third frame on (None before two are timed), the time
    /// spent frozen (F2) left out.
    fn displayed(&self, mode: PresentMode) -> Option<crate::headless::DisplayedFrames> {
        let (from, last) = (self.timed_from?, self.last_shown?);
        let frames = self.frames.checked_sub(3).filter(|&n| n > 0)?;
        let ongoing = |since: Option<Instant>| since.map_or(std::time::Duration::ZERO, |since| self.timed_span(since, last));
        let frozen = self.frozen_total + ongoing(self.frozen_since) + ongoing(self.paused_since);
        let ms = (last - from).saturating_sub(frozen).as_secs_f64() * 1e3 / frames as f64;
        // All of the span frozen (F2 before the third frame, then F3 steps): no rate to give
        // (1e3 / 0 went into summary.json as null).
        if !(ms > 0.0) {
            return None;
        }
        Some(crate::headless::DisplayedFrames { present_mode: mode.name().to_string(), frames, ms_per_frame: ms, fps: 1e3 / ms })
    }
}

/// The point light L spawns: just in front of the camera (2% of the scene's size along the view),
/// white, with a quarter of the scene's light power (1 W/sr when the scene has none).
fn spawned_light(camera: &crate::camera::Camera, scene: &SceneGpu) -> PointEmitter {
    let (lo, hi) = scene.info.bounds;
    let size = (hi - lo).length().max(1e-6);
    let power = scene.lights.total_power_lum as f32;
    let intensity = if power > 0.0 { 0.25 * power / (4.0 * std::f32::consts::PI) } else { 1.0 };
    PointEmitter { position: camera.position + camera.forward * 0.02 * size, intensity: glam::Vec3::splat(intensity) }
}

/// Whether `s` can show `view` (the settings' checks pass with it): what V and the overlay's view
/// box offer, so that neither asks for a view only to be refused in terms of command-line flags.
pub(crate) fn can_show(s: &RenderSettings, view: View) -> bool {
    RenderSettings { view, ..s.clone() }.validate().is_ok()
}

/// The next (or previous) `--view` the current mode can show.
fn next_valid_view(s: &RenderSettings, forward: bool) -> View {
    let mut v = s.view;
    for _ in 0..View::ALL.len() {
        v = if forward { v.next() } else { v.previous() };
        if can_show(s, v) {
            return v;
        }
    }
    s.view
}

/// Where O and I keep the camera: camera.json in the output directory (or the working directory).
fn camera_file(s: &RenderSettings) -> PathBuf {
    s.out_dir.as_deref().unwrap_or(std::path::Path::new(".")).join("camera.json")
}

/// Whether a frame reached the screen.
enum Shown {
    Yes,
    /// Shown, but the swapchain no longer matches the window well: recreate it.
    YesRecreate,
    /// Not shown: the swapchain no longer matches the window; recreate it.
    OutOfDate,
    /// Not shown: no swapchain image came within ACQUIRE_TIMEOUT (a hidden or minimised window
    /// on some presentation engines); the event loop goes on, so the window still answers input.
    NotReady,
    /// The surface is gone: another program destroyed the window while the frame was on its way
    /// (its `Destroyed` event not yet handled).
    SurfaceLost,
}

/// How long `show` waits for a swapchain image before skipping the frame (instead of blocking the
/// event loop, and with it Esc, for as long as the presentation engine holds every image).
const ACQUIRE_TIMEOUT_NS: u64 = 1_000_000_000;

/// Per frame in flight: the command buffer that copies the preview to the swapchain image, its
/// fence and the semaphore the image acquisition signals; plus the staging image the preview is
/// copied into before the blit (the blit converts to the swapchain's format and size).
struct Presenter {
    ctx: Arc<Context>,
    staging: Image,
    cmds: Vec<vk::CommandBuffer>,
    fences: Vec<vk::Fence>,
    acquired: Vec<vk::Semaphore>,
    next: usize,
}

const PRESENT_SLOTS: usize = crate::renderer::FRAME_SLOTS;

impl Presenter {
    fn new(ctx: &Arc<Context>, swapchain: &Swapchain) -> Result<Self> {
        // The preview bytes are sRGB-encoded: typed as UNORM they blit unchanged into a UNORM
        // swapchain; typed as sRGB they decode and re-encode into an sRGB one.
        let srgb = matches!(swapchain.format.format, vk::Format::B8G8R8A8_SRGB | vk::Format::R8G8B8A8_SRGB);
        let format = if srgb { vk::Format::R8G8B8A8_SRGB } else { vk::Format::R8G8B8A8_UNORM };
        // SAFETY: valid physical device.
        let features = unsafe { ctx.instance.get_physical_device_format_properties(ctx.physical_device, format) };
        if !features.optimal_tiling_features.contains(vk::FormatFeatureFlags::BLIT_SRC) {
            bail!("this device cannot blit from {format:?}; cannot show the preview");
        }
        let staging = Image::new(
            ctx,
            "window.preview",
            swapchain.extent,
            format,
            vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::TRANSFER_SRC,
        )?;
        // Owned before the slots are made, so that a failure part-way destroys the slots made so
        // far (Drop; they leaked).
        let mut made = Self { ctx: ctx.clone(), staging, cmds: Vec::new(), fences: Vec::new(), acquired: Vec::new(), next: 0 };
        for i in 0..PRESENT_SLOTS {
            // All destroyed in Drop after a wait for idle.
            let (cmd, fence) = ctx.command_buffer_and_fence(&format!("present{i}"), true)?;
            made.cmds.push(cmd);
            made.fences.push(fence);
            // SAFETY: valid device.
            let sem = unsafe { ctx.device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None)? };
            ctx.set_name(sem, &format!("present{i}.acquired"));
            made.acquired.push(sem);
        }
        Ok(made)
    }

    /// Waits until present slot `f`'s last submission (blit and overlay) has finished.
    fn wait_slot(&self, ctx: &Context, f: usize) -> Result<()> {
        ctx.wait_fence(self.fences[f], &|| "a present slot (the last blit and overlay drawn into it)".into(), &|| None)
    }

    /// Waits until every present slot's last submission has finished.
    fn wait_all(&self, ctx: &Context) -> Result<()> {
        (0..self.fences.len()).try_for_each(|f| self.wait_slot(ctx, f))
    }

    /// Acquires a swapchain image, submits the renderer's frame (`camera`; None: none, the last
    /// frame's preview again), copies its preview onto the image and presents it. The renderer's
    /// frame stays in flight.
    /// `overlay`: drawn over the image after the blit.
    fn show(
        &mut self,
        ctx: &Context,
        swapchain: &Swapchain,
        renderer: &mut Renderer,
        camera: Option<&crate::camera::Camera>,
        overlay: Option<&mut Overlay>,
    ) -> Result<Shown> {
        let p = ctx.presentation.as_ref().expect("a window context");
        let f = self.next;
        let d = &ctx.device;
        self.wait_slot(ctx, f)?;
        // SAFETY: valid swapchain; the semaphore is unsignalled (its last wait has completed).
        let acquired =
            unsafe { p.swapchain_loader.acquire_next_image(swapchain.raw, ACQUIRE_TIMEOUT_NS, self.acquired[f], vk::Fence::null()) };
        let image_index = match acquired {
            Ok((i, _suboptimal)) => i,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => return Ok(Shown::OutOfDate),
            Err(vk::Result::ERROR_SURFACE_LOST_KHR) => return Ok(Shown::SurfaceLost),
            // Nothing was acquired and the semaphore stays unsignalled: the slot is reusable.
            Err(vk::Result::TIMEOUT | vk::Result::NOT_READY) => return Ok(Shown::NotReady),
            Err(e) => return Err(e).context("vkAcquireNextImageKHR"),
        };
        // From the acquire to the submit, an error leaves the slot's semaphore signalled with no
        // wait submitted and, after the fence reset, its fence unsignalled: the next use of the
        // slot (or its destruction at the window's end) then broke Vulkan's rules. They are
        // released below before the error goes on.
        let mut fence_reset = false;
        let record_and_submit = || -> Result<()> {
            // No camera: the preview of the last frame (complete: frozen) is shown again.
            if let Some(camera) = camera {
                renderer.submit_frame(camera, true)?;
            }
            let cmd = self.cmds[f];
            let image = swapchain.images[image_index as usize];
            let (w, h) = (renderer.settings().width, renderer.settings().height);
            // SAFETY: the slot's previous submission completed (fence waited); every object used is
            // alive until this slot's fence is waited on again.
            unsafe {
                d.reset_fences(&[self.fences[f]])?;
                fence_reset = true;
                d.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())?;
                d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT))?;
                ctx.begin_label(cmd, "present");
                // The renderer's tonemap wrote the preview with compute shaders in an earlier submission.
                crate::vk::pipeline::submission_start_barrier(ctx, cmd);
                transition(ctx, cmd, self.staging.raw, vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL);
                let copy = [vk::BufferImageCopy::default()
                    .image_subresource(vk::ImageSubresourceLayers::default().aspect_mask(vk::ImageAspectFlags::COLOR).layer_count(1))
                    .image_extent(vk::Extent3D { width: w.min(self.staging.extent.width), height: h.min(self.staging.extent.height), depth: 1 })
                    .buffer_row_length(w)];
                d.cmd_copy_buffer_to_image(cmd, renderer.preview_buffer().raw, self.staging.raw, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &copy);
                transition(ctx, cmd, self.staging.raw, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::TRANSFER_SRC_OPTIMAL);
                transition(ctx, cmd, image, vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL);
                let sub = vk::ImageSubresourceLayers::default().aspect_mask(vk::ImageAspectFlags::COLOR).layer_count(1);
                let corner = |e: vk::Extent2D| vk::Offset3D { x: e.width as i32, y: e.height as i32, z: 1 };
                let blit = [vk::ImageBlit::default()
                    .src_subresource(sub)
                    .src_offsets([vk::Offset3D::default(), corner(self.staging.extent)])
                    .dst_subresource(sub)
                    .dst_offsets([vk::Offset3D::default(), corner(swapchain.extent)])];
                d.cmd_blit_image(
                    cmd,
                    self.staging.raw,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    image,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &blit,
                    vk::Filter::NEAREST,
                );
                match overlay {
                    // Its render pass ends in the present layout.
                    Some(o) => o.record(cmd, image_index as usize)?,
                    None => transition(ctx, cmd, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::PRESENT_SRC_KHR),
                }
                ctx.end_label(cmd);
                d.end_command_buffer(cmd)?;
                let waits = [self.acquired[f]];
                let stages = [vk::PipelineStageFlags::TRANSFER];
                let signals = [swapchain.render_finished[image_index as usize]];
                let cmds = [cmd];
                let submit = [vk::SubmitInfo::default()
                    .wait_semaphores(&waits)
                    .wait_dst_stage_mask(&stages)
                    .command_buffers(&cmds)
                    .signal_semaphores(&signals)];
                d.queue_submit(ctx.queue, &submit, self.fences[f]).context("vkQueueSubmit (present)")?;
                Ok(())
            }
        };
        let submitted = record_and_submit();
        if let Err(e) = submitted {
            self.release_acquired(ctx, f, fence_reset);
            return Err(e);
        }
        // SAFETY: the submission above signals render_finished[image_index].
        unsafe {
            let signals = [swapchain.render_finished[image_index as usize]];
            let swapchains = [swapchain.raw];
            let indices = [image_index];
            let present = vk::PresentInfoKHR::default().wait_semaphores(&signals).swapchains(&swapchains).image_indices(&indices);
            self.next = (f + 1) % PRESENT_SLOTS;
            match p.swapchain_loader.queue_present(ctx.queue, &present) {
                Ok(false) => Ok(Shown::Yes),
                Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(Shown::YesRecreate),
                Err(vk::Result::ERROR_SURFACE_LOST_KHR) => Ok(Shown::SurfaceLost),
                Err(e) => Err(e).context("vkQueuePresentKHR"),
            }
        }
    }

    /// After an error between the acquire and the submit in [`Self::show`]: an empty submission
    /// waits on slot `f`'s acquire semaphore (unsignalling it) and, when the fence was reset,
    /// signals the fence, so that the slot is as a frame leaves it. Best effort: where it fails
    /// too (a lost device), nothing more is done.
    fn release_acquired(&self, ctx: &Context, f: usize, fence_reset: bool) {
        if ctx.is_hung() {
            return;
        }
        let waits = [self.acquired[f]];
        let stages = [vk::PipelineStageFlags::ALL_COMMANDS];
        let submit = [vk::SubmitInfo::default().wait_semaphores(&waits).wait_dst_stage_mask(&stages)];
        let fence = if fence_reset { self.fences[f] } else { vk::Fence::null() };
        // SAFETY: the acquire signals the semaphore and no submitted batch waits on it; the fence,
        // when given, was reset and no submission signals it.
        let _ = unsafe { ctx.device.queue_submit(ctx.queue, &submit, fence) };
    }
}

impl Drop for Presenter {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a submission may still be executing: its objects stay
        }
        // SAFETY: wait for idle, then free every slot's objects.
        unsafe {
            let _ = self.ctx.device.device_wait_idle();
            // (Each list on its own: a slot made in part has a fence and no semaphore.)
            for &f in &self.fences {
                self.ctx.device.destroy_fence(f, None);
            }
            for &s in &self.acquired {
                self.ctx.device.destroy_semaphore(s, None);
            }
            if !self.cmds.is_empty() {
                self.ctx.device.free_command_buffers(self.ctx.command_pool, &self.cmds);
            }
        }
    }
}

/// Most pixel × VPL pairs (shadow rays) a brute-force frame may have in the window, by device
/// kind: a frame is one submission, and the window answers no key until it ends. lavapipe traces
/// ~18M such rays a second on the 2-core reference machine (1.7 s for 320×240 × 400 VPLs), so
/// 1e8 is ~5 s a frame there; a GPU with RT cores traces ~1e9 a second or more. Headless runs keep
/// the larger `MAX_BRUTEFORCE_PAIRS`.
pub const WINDOW_BRUTEFORCE_PAIRS_CPU: u64 = 100_000_000;
pub const WINDOW_BRUTEFORCE_PAIRS_GPU: u64 = 2_000_000_000;

/// After a change of mode, the view falls back to the final image where the mode has no such
/// view: the reservoir views outside RIS and ReSTIR, all but the VPLs' in the path tracer (key 1-5
/// and the overlay's mode box alike; the box refused what the key did).
pub(crate) fn fit_view_to_mode(s: &mut RenderSettings) {
    if !s.mode.uses_reservoirs() && s.view.shows_reservoirs() || s.mode == Mode::Pt && s.view != View::Vpls {
        s.view = View::Final;
    }
}

/// Why the view `s` shows may look empty, where it can: the indirect view without indirect VPLs
/// is black (it was, without a word), and W and M are grey levels that 0 EV shows white.
pub(crate) fn view_hint(s: &RenderSettings) -> Option<&'static str> {
    match s.view {
        View::Indirect if !s.gi => Some("black: the indirect VPLs are off, G turns them on"),
        View::ReservoirW | View::ReservoirM if s.exposure >= 0.0 => Some("raw values as grey, white from 1 up at 0 EV: lower the overlay's exposure"),
        _ => None,
    }
}

/// Whether the indirect VPLs (G) change the image: not in the path tracer, except its VPL view.
pub(crate) fn reads_gi(s: &RenderSettings) -> bool {
    s.mode != Mode::Pt || s.view == View::Vpls
}

/// Why the window refuses brute force for `s` (None: it does not). Pressing 5 at 320×240 with the
/// default 200k VPLs froze the window for ~14 minutes a frame on lavapipe.
/// `traced`: the VPL set traced now and the settings it was traced with.
pub fn interactive_bruteforce_refusal(
    s: &RenderSettings,
    traced: Option<(&crate::passes::PhotonStats, crate::settings::PhotonSettings)>,
    device_kind: &str,
) -> Option<String> {
    if s.mode != crate::settings::Mode::Bruteforce {
        return None;
    }
    // The traced set's count when `s` keeps it, else (none traced yet, or `s` traces another:
    // G turning the indirect VPLs on) the counts asked for.
    let asked = s.photon_settings();
    let vpls = match traced {
        Some((p, with)) if with == asked => u64::from(crate::passes::PhotonEmitPass::vpl_count(p)),
        _ => u64::from(asked.direct) + u64::from(asked.indirect),
    };
    let pairs = crate::renderer::bruteforce_pairs(s, vpls);
    let limit = if device_kind == "CPU" { WINDOW_BRUTEFORCE_PAIRS_CPU } else { WINDOW_BRUTEFORCE_PAIRS_GPU };
    (pairs > limit).then(|| {
        format!(
            "brute force: {}×{} pixels × {vpls} VPLs = {pairs:.2e} shadow rays a frame, over the window's {limit:.0e} on a {device_kind} \
             device (the window would not answer for the whole frame); start with fewer VPLs (--vpls-direct/--vpls-indirect), \
             use a smaller window, or run it --headless",
            s.width,
            s.height,
            pairs = pairs as f64,
            limit = limit as f64
        )
    })
}

/// How long a status message stays in the title and the overlay.
const MESSAGE_SECONDS: f64 = 10.0;

/// What the movement keys and I answer while `--camera-path` drives the camera.
const FOLLOWS_PATH: &str = "the camera follows --camera-path: movement keys and I are off (Home plays the path again)";

#[cfg(test)]
mod tests {
    use super::{can_show, display_error_text, next_valid_view};
    use crate::settings::{Mode, NamedEnum, RenderSettings, View};

    /// A view that may look empty says why: indirect without indirect VPLs, W and M at 0 EV.
    #[test]
    fn a_view_that_may_look_empty_says_why() {
        use super::view_hint;
        let s = |view, gi, exposure| RenderSettings { mode: Mode::Restir, view, gi, exposure, ..Default::default() };
        assert!(view_hint(&s(View::Indirect, false, 0.0)).unwrap().contains("G turns them on"));
        assert!(view_hint(&s(View::ReservoirW, true, 0.0)).unwrap().contains("exposure"));
        for quiet in [s(View::Indirect, true, 0.0), s(View::ReservoirM, true, -8.0), s(View::Final, false, 0.0)] {
            assert_eq!(view_hint(&quiet), None);
        }
    }

    /// The views V cycles through and the overlay's view box lists: the path tracer has its
    /// estimate and the VPL view, no reservoir view; ReSTIR has every view.
    #[test]
    fn only_the_views_a_mode_can_show_are_offered() {
        let pt = RenderSettings { mode: Mode::Pt, ..Default::default() };
        let offered: Vec<&str> = View::ALL.iter().filter(|&&v| can_show(&pt, v)).map(|v| v.name()).collect();
        assert!(offered.contains(&"final") && offered.contains(&"vpls"), "{offered:?}");
        assert!(!offered.contains(&"reservoir-w") && !offered.contains(&"motion"), "{offered:?}");
        let restir = RenderSettings { mode: Mode::Restir, ..Default::default() };
        assert!(View::ALL.iter().all(|&v| can_show(&restir, v)));
        // V from the last view the path tracer shows wraps to one it shows.
        let last = *View::ALL.iter().rev().find(|&&v| can_show(&pt, v)).unwrap();
        assert!(can_show(&pt, next_valid_view(&RenderSettings { view: last, ..pt.clone() }, true)));
    }

    /// winit's source location goes; its reason and any other text stay as they are.
    #[test]
    fn the_display_error_keeps_the_reason_only() {
        let winit = "os error at /root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/winit-0.30.13/src/platform_impl/linux/mod.rs:765: \
                     neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set.";
        assert_eq!(display_error_text(winit), "neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set");
        assert_eq!(display_error_text("the event loop can't be recreated."), "the event loop can't be recreated");
    }
}
