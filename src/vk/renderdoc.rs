//! RenderDoc's in-application API (`--renderdoc-capture N`, F12 in the window): wraps one frame's
//! submission in a capture when the program runs under RenderDoc. It only attaches to a RenderDoc
//! that injected itself (the library is opened with RTLD_NOLOAD); otherwise one line says how to
//! start the run under it and everything goes on. Ray-query capture needs RenderDoc 1.36 or later
//! (its release notes: "Raytracing capture"); older ones hide the extensions, and the renderer then
//! finds no ray-query device.

use std::ffi::c_void;

use ash::vk::Handle;

use super::Context;

pub struct Capturer {
    api: Option<renderdoc::RenderDoc<renderdoc::V141>>,
    /// RENDERDOC_DEVICEPOINTER_FROM_VKINSTANCE: the dispatch-table pointer the instance handle points at.
    device: *const c_void,
}

/// What to do to capture when RenderDoc is not attached.
pub const HOW_TO_CAPTURE: &str = "RenderDoc is not attached, so no capture is taken: start the run under it, e.g. \
     `renderdoccmd capture -w ./target/release/restir-vpl --headless ... --renderdoc-capture N` \
     (ray queries need RenderDoc 1.36 or later); the run goes on";

/// The window's F12 without RenderDoc attached: the same, for a window (the headless command it
/// was told read as a way out of the window).
pub const WINDOW_HOW_TO_CAPTURE: &str = "RenderDoc is not attached, so F12 captures nothing: start the window under it, e.g. \
     `renderdoccmd capture -w restir-vpl --scene ...`, and press F12 there (ray queries need RenderDoc 1.36 or later)";

impl Capturer {
    pub fn attach(ctx: &Context) -> Self {
        let raw = ctx.instance.handle().as_raw() as *const *const c_void;
        // SAFETY: a VkInstance handle is a pointer to its loader dispatch table pointer, which is
        // what RenderDoc identifies a Vulkan instance by.
        let device = unsafe { *raw };
        Self { api: renderdoc::RenderDoc::<renderdoc::V141>::new().ok(), device }
    }

    pub fn attached(&self) -> bool {
        self.api.is_some()
    }

    pub fn start(&mut self) {
        if let Some(api) = &mut self.api {
            api.start_frame_capture(self.device, std::ptr::null());
        }
    }

    /// Ends the capture; true when one was taken.
    pub fn end(&mut self) -> bool {
        match &mut self.api {
            Some(api) => {
                api.end_frame_capture(self.device, std::ptr::null());
                true
            }
            None => false,
        }
    }
}
