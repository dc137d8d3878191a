//! Thin Vulkan layer: context, named buffers, acceleration structures, compute pipelines with
//! binding tables, GPU timers.

pub mod accel;
pub mod leaf_order;
pub mod buffer;
pub mod context;
pub mod image;
pub mod pipeline;
pub mod pipeline_cache;
pub mod renderdoc;
pub mod timer;

pub use buffer::{Buffer, TexelFormat};
pub use image::Image;
pub use context::{WindowHandles, Presentation, Context, ContextOptions, DeviceReport, NoTracingDevice};
pub use pipeline::{Binding, BindingKind, ComputePipeline, DescriptorSet};
pub use timer::GpuTimer;
