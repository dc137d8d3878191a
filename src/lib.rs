//! restir-vpl: GPU global illumination with photon-traced virtual point lights and ReSTIR DI on
//! Vulkan ray queries, with a path-traced ground truth.
//!
//! Layout: [`vk`] (thin Vulkan layer), [`scene`] (glTF loading), [`scene_gpu`] (set 0),
//! [`passes`] (one module per compute pass; the frame order is in [`passes::Passes::record_frame`]),
//! [`renderer`] (submission), [`headless`] (runs and outputs).

pub mod camera;
pub mod dump;
pub mod eval;
pub mod gpu_types;
pub mod headless;
pub mod lights;
pub mod logger;
pub mod output;
pub mod passes;
pub mod ply;
pub mod renderer;
pub mod scene;
pub mod scene_gpu;
pub mod settings;
pub mod vk;
pub mod vpl_radius;
pub mod window;

/// SPIR-V of every shader, compiled by build.rs.
pub mod shaders {
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
}

pub use headless::{run, RunOutput, Summary};
pub use settings::{Mode, RenderSettings};
pub use vk::NoTracingDevice;
