//! Vulkan instance, device selection and the objects every pass shares (queue, allocator, debug
//! utils). Device selection requires a way to trace rays, ray queries or else ray-tracing pipelines
//! ([`Tracing`]); [`NoTracingDevice`] is the typed error a caller branches on (exit code 2).

use std::ffi::{c_void, CStr, CString};
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context as _, Result};
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme, Allocator, AllocatorCreateDesc};
use gpu_allocator::MemoryLocation;

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// What one physical device is and what it lacks for this renderer.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceReport {
    pub index: usize,
    pub name: String,
    pub kind: String,
    pub api_version: String,
    pub driver: String,
    /// Missing extensions / features; empty when the device qualifies.
    pub missing: Vec<String>,
    /// How it would trace rays (None: it cannot).
    pub tracing: Option<Tracing>,
}

/// How rays are traced: the two implementations of shaders/common/trace.glsl, with the same
/// results (tests/trace_pipeline.rs compares them).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Tracing {
    /// `VK_KHR_ray_query`: inline in the compute passes. Chosen wherever a device has it.
    Query,
    /// `VK_KHR_ray_tracing_pipeline`: the passes that trace run as ray-generation shaders (one hit
    /// group, two miss shaders), for devices without ray queries, as NVIDIA's datacenter GPUs.
    /// No boiling filter there (it needs a workgroup's shared memory).
    Pipeline,
}

impl Tracing {
    /// The value of `--trace` / `RESTIR_VPL_TRACE` ("auto": None, the device's best).
    pub fn parse(s: &str) -> Option<Option<Tracing>> {
        match s {
            "auto" | "" => Some(None),
            _ => [Tracing::Query, Tracing::Pipeline].into_iter().find(|t| t.name() == s).map(Some),
        }
    }

    /// Its value of `--trace` / `RESTIR_VPL_TRACE`.
    pub fn name(self) -> &'static str {
        match self {
            Tracing::Query => "query",
            Tracing::Pipeline => "pipeline",
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            Tracing::Query => "ray queries",
            Tracing::Pipeline => "ray-tracing pipelines",
        }
    }
}

/// `RESTIR_VPL_TRACE` (query, pipeline or auto/unset), the choice of [`Tracing`] for every command.
pub fn tracing_from_env() -> Result<Option<Tracing>> {
    match std::env::var("RESTIR_VPL_TRACE") {
        Err(std::env::VarError::NotPresent) => Ok(None),
        Err(std::env::VarError::NotUnicode(v)) => bail!("RESTIR_VPL_TRACE={v:?}: expected query, pipeline or auto"),
        Ok(v) => Tracing::parse(&v).with_context(|| format!("RESTIR_VPL_TRACE={v:?}: expected query, pipeline or auto")),
    }
}

/// How often [`Context::wait_fence`] says that it is still waiting, with what the device has
/// finished.
pub const GPU_WAIT_WARN_EVERY: Duration = Duration::from_secs(60);

/// Serialises device (and instance) creation and destruction against pipeline creation and
/// destruction across every [`Context`] of the process. NVIDIA's driver (580.159 on an H200)
/// deadlocked in test binaries, which hold several contexts at once: a thread in `vkDestroyDevice` or
/// `vkCreateDevice` held the driver's process-wide lock and waited on a mutex, while a thread
/// creating or destroying a pipeline on a device of its own waited on the process-wide lock, and
/// (by elimination: the driver's frames have no names) held that mutex (stacks taken with eu-stack;
/// docs/gpu.md, "The test binaries hung"). A process with one context (the CLI, the window) never
/// met it. Pipelines take it shared, so contexts still compile in parallel; the device's lifetime
/// calls take it exclusively.
static DEVICE_LIFETIME: std::sync::RwLock<()> = std::sync::RwLock::new(());

/// Held (exclusively) while a device or an instance is created or destroyed; see
/// [`DEVICE_LIFETIME`]. Never while the same thread holds [`pipeline_creation_guard`] (that would
/// wait on itself): a pipeline's drop, which holds it, cannot drop the last `Arc<Context>`, since
/// the pipeline's own `ctx` field outlives its `Drop::drop`.
fn lifetime_exclusive() -> std::sync::RwLockWriteGuard<'static, ()> {
    DEVICE_LIFETIME.write().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Held (shared) while a pipeline (with its set, modules, layout and binding table) or the pipeline
/// cache is created or destroyed; see [`DEVICE_LIFETIME`]. Not re-entrant: take it once per call.
pub(crate) fn pipeline_creation_guard() -> std::sync::RwLockReadGuard<'static, ()> {
    DEVICE_LIFETIME.read().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Set when any context of the process is marked hung ([`Context::is_hung`]); read by
/// [`a_device_hung`].
static A_DEVICE_HUNG: AtomicBool = AtomicBool::new(false);

/// Whether a submission of any context of this process ran past the time limit. Such a process
/// must end without the driver's exit handlers: on an NVIDIA H100 (driver 580.159, stop 51) the
/// CLI printed its error, dropped everything and then spun for ever inside `exit()`, in the
/// driver's handlers (eu-stack: the main thread in `exit` under the driver's frames, running), so
/// the timeout never ended the process. The CLI ends such a process with `_exit`.
pub fn a_device_hung() -> bool {
    A_DEVICE_HUNG.load(Ordering::SeqCst)
}

/// `RESTIR_VPL_GPU_TIMEOUT_S`: how long one submission may run before [`Context::wait_fence`]
/// gives up on it, in seconds (fractions allowed); unset or 0: no limit. No limit by default,
/// because one legitimate submission can be long: a brute-force frame is one dispatch, accepted up
/// to [`crate::renderer::MAX_BRUTEFORCE_PAIRS`] shadow rays (about 2 hours on lavapipe); the
/// warnings every [`GPU_WAIT_WARN_EVERY`] say what a long or hung frame is doing either way.
pub fn gpu_timeout_from_env() -> Result<Option<Duration>> {
    const WHAT: &str = "expected a number of seconds below 1e9 (0: wait without a limit)";
    match std::env::var("RESTIR_VPL_GPU_TIMEOUT_S") {
        Err(std::env::VarError::NotPresent) => Ok(None),
        Err(std::env::VarError::NotUnicode(v)) => bail!("RESTIR_VPL_GPU_TIMEOUT_S={v:?}: {WHAT}"),
        Ok(v) => match v.trim().parse::<f64>() {
            Ok(0.0) => Ok(None),
            Ok(s) if s.is_finite() && s > 0.0 && s < 1e9 => Ok(Some(Duration::from_secs_f64(s))),
            _ => bail!("RESTIR_VPL_GPU_TIMEOUT_S={v:?}: {WHAT}"),
        },
    }
}

impl DeviceReport {
    pub fn qualifies(&self) -> bool {
        self.missing.is_empty()
    }
}

/// The note printed under the device table when no device qualifies and an NVIDIA device lacks ray
/// queries. NVIDIA's drivers expose `VK_KHR_ray_query` only on GPUs with RT cores (an NVIDIA
/// engineer in KhronosGroup/Vulkan-Docs#1241); datacenter GPUs have ray-tracing pipelines instead:
/// seen here on an H100 (driver 580.159.04), reported for the A100 (DXC's PR #5307).
pub fn no_device_hint(reports: &[DeviceReport]) -> Option<String> {
    let nvidia_without = reports.iter().any(|r| {
        r.name.to_ascii_uppercase().contains("NVIDIA") && r.missing.iter().any(|m| m.contains("ray_query") || m.contains("rayQuery"))
    });
    nvidia_without.then(|| {
        "note: NVIDIA drivers expose VK_KHR_ray_query only on GPUs with RT cores (GeForce/Quadro RTX and later); \
         datacenter GPUs (A100, H100, H200) have ray-tracing pipelines instead (an H100 with driver 580.159.04 \
         does), which `--trace pipeline` uses and `--trace auto` (the default) falls back to"
            .to_string()
    })
}

impl std::fmt::Display for DeviceReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "[{}] {} ({}, Vulkan {}, {})", self.index, self.name, self.kind, self.api_version, self.driver)?;
        if self.missing.is_empty() {
            write!(f, ": ok")?;
            match self.tracing {
                Some(t) => write!(f, " ({})", t.describe()),
                None => Ok(()),
            }
        } else {
            write!(f, ": lacks {}", self.missing.join(", "))
        }
    }
}

/// No physical device supports what the renderer needs (a way to trace rays and friends).
#[derive(Debug, thiserror::Error)]
#[error("no Vulkan device can trace rays (VK_KHR_acceleration_structure + VK_KHR_deferred_host_operations + \
bufferDeviceAddress, with VK_KHR_ray_query or VK_KHR_ray_tracing_pipeline); devices found:\n{}{}",
    if devices.is_empty() && hint.is_some() { "  (none)".to_string() }
    else if devices.is_empty() { "  (none: is a Vulkan driver installed? run scripts/setup.sh)".to_string() }
    else { devices.iter().map(|d| format!("  {d}")).collect::<Vec<_>>().join("\n") },
    hint.as_deref().map(|h| format!("\n{h}")).unwrap_or_default())]
pub struct NoTracingDevice {
    pub devices: Vec<DeviceReport>,
    pub hint: Option<String>,
}

/// Options for creating the context.
#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    /// Enable the Khronos validation layer (warn when it is not installed).
    pub validate: bool,
    /// Pick this physical device (index as in `--list-devices`).
    pub device_index: Option<usize>,
    /// Present to this window: the instance gets the platform's surface extensions, the device
    /// `VK_KHR_swapchain` and a queue family that can present to it.
    pub window: Option<WindowHandles>,
    /// How to trace rays (`--trace`); None: `RESTIR_VPL_TRACE`, else the device's best.
    pub tracing: Option<Tracing>,
}

/// The raw handles of a window to present to (from `raw-window-handle`).
#[derive(Clone, Copy, Debug)]
pub struct WindowHandles {
    pub display: raw_window_handle::RawDisplayHandle,
    pub window: raw_window_handle::RawWindowHandle,
}

/// The window's Vulkan surface and the loaders a swapchain needs.
pub struct Presentation {
    pub surface_loader: ash::khr::surface::Instance,
    pub surface: vk::SurfaceKHR,
    pub swapchain_loader: ash::khr::swapchain::Device,
}

/// Shared Vulkan state.
pub struct Context {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    pub physical_device: vk::PhysicalDevice,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    /// Shared with the window's overlay renderer (egui-ash-renderer), which must be dropped first:
    /// the context frees the allocator before it destroys the device.
    pub allocator: ManuallyDrop<Arc<Mutex<Allocator>>>,
    pub accel: ash::khr::acceleration_structure::Device,
    pub debug_utils: Option<ash::ext::debug_utils::Device>,
    debug_instance: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    pub report: DeviceReport,
    pub properties: vk::PhysicalDeviceProperties,
    pub as_properties: AccelProperties,
    /// How this context traces rays.
    pub tracing: Tracing,
    /// The ray-tracing-pipeline loader and limits, when `tracing` is [`Tracing::Pipeline`].
    pub ray_tracing: Option<RayTracingPipelines>,
    /// Whether the validation layer is active.
    pub validation_enabled: bool,
    validation: Arc<ValidationCounter>,
    pub command_pool: vk::CommandPool,
    /// Every pipeline is created through it; loaded from and saved to `pipeline_cache_file`.
    pub pipeline_cache: vk::PipelineCache,
    pub pipeline_cache_file: Option<std::path::PathBuf>,
    /// Bytes loaded from the file at start (0: none or not usable).
    pub pipeline_cache_loaded: usize,
    /// The window's surface, when the context was made for one.
    pub presentation: Option<Presentation>,
    /// Non-finite samples the accumulation replaced by 0 in any renderer on this context (the
    /// renderers report them as their frames complete): a shader bug, checked beside the
    /// validation errors by runs under validation (`--validate`, `RESTIR_VPL_VALIDATE=1`).
    nonfinite_samples: AtomicU64,
    /// How long one submission may run (`RESTIR_VPL_GPU_TIMEOUT_S`; None: no limit).
    pub gpu_timeout: Option<Duration>,
    /// The largest single memory allocation the device takes (maxMemoryAllocationSize, Vulkan
    /// 1.1): every buffer is checked against it before it is made or filled (lavapipe crashed
    /// copying a 2.2 GB vertex buffer).
    pub max_allocation: u64,
    /// Whether compute shaders have subgroup arithmetic (Vulkan 1.1's `subgroupAdd`,
    /// `subgroupElect`), which `restir_boiling`'s reduction uses.
    pub subgroup_arithmetic: bool,
    /// A submission ran past `gpu_timeout`: the device may still be executing it, so nothing it
    /// uses may be waited on or destroyed (the drops leave them to the process's exit).
    hung: AtomicBool,
}

/// The acceleration-structure limits the renderer uses.
#[derive(Clone, Copy, Debug)]
pub struct AccelProperties {
    pub min_scratch_offset_alignment: u32,
    /// maxInstanceCount: the most instances a TLAS holds.
    pub max_instance_count: u64,
}

/// What the ray-tracing-pipeline implementation needs of `VK_KHR_ray_tracing_pipeline`.
pub struct RayTracingPipelines {
    pub loader: ash::khr::ray_tracing_pipeline::Device,
    pub handle_size: u32,
    pub handle_alignment: u32,
    pub base_alignment: u32,
    pub max_invocations: u32,
}

/// Counts validation-layer messages by severity (the debug messenger's user data).
#[derive(Default)]
pub struct ValidationCounter {
    pub errors: AtomicU64,
    pub warnings: AtomicU64,
    pub first_error: Mutex<Option<String>>,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the loader passes a valid callback-data pointer; `user` is the Arc'd counter that the
    // context keeps alive for as long as the messenger exists.
    let (msg, counter) = unsafe {
        let msg = if data.is_null() || (*data).p_message.is_null() {
            String::from("(no message)")
        } else {
            CStr::from_ptr((*data).p_message).to_string_lossy().into_owned()
        };
        (msg, &*(user as *const ValidationCounter))
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        counter.errors.fetch_add(1, Ordering::SeqCst);
        if let Ok(mut first) = counter.first_error.lock() {
            first.get_or_insert_with(|| msg.clone());
        }
        log::error!("[vulkan {kind:?}] {msg}");
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        counter.warnings.fetch_add(1, Ordering::SeqCst);
        log::warn!("[vulkan {kind:?}] {msg}");
    } else {
        log::debug!("[vulkan {kind:?}] {msg}");
    }
    vk::FALSE
}

fn version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

fn device_kind(t: vk::PhysicalDeviceType) -> (&'static str, u32) {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => ("discrete GPU", 0),
        vk::PhysicalDeviceType::INTEGRATED_GPU => ("integrated GPU", 1),
        vk::PhysicalDeviceType::VIRTUAL_GPU => ("virtual GPU", 2),
        vk::PhysicalDeviceType::CPU => ("CPU", 3),
        _ => ("other", 4),
    }
}

/// Required whichever way rays are traced; [`Tracing`] adds its own.
const REQUIRED_EXTENSIONS: [&CStr; 2] = [ash::khr::acceleration_structure::NAME, ash::khr::deferred_host_operations::NAME];

/// Storage buffers a shader stage must be able to see (`maxPerStageDescriptorStorageBuffers`;
/// Vulkan guarantees only 4): `passes::storage_buffers_per_stage()`, which a test keeps equal.
pub const REQUIRED_STORAGE_BUFFERS_PER_STAGE: u32 = 10;

/// Inspects one physical device: what it lacks, and how it would trace rays when asked for
/// `request` (None: ray queries, else ray-tracing pipelines).
fn inspect(instance: &ash::Instance, index: usize, pd: vk::PhysicalDevice, request: Option<Tracing>) -> (DeviceReport, u32) {
    // SAFETY: `pd` comes from `enumerate_physical_devices` of this instance.
    let props = unsafe { instance.get_physical_device_properties(pd) };
    let name = props.device_name_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
    let (kind, rank) = device_kind(props.device_type);
    let mut missing = Vec::new();
    if props.api_version < vk::API_VERSION_1_2 {
        missing.push(format!("Vulkan 1.2 (has {})", version_string(props.api_version)));
    }
    // SAFETY: as above.
    let exts = unsafe { instance.enumerate_device_extension_properties(pd) }.unwrap_or_default();
    let has_ext = |n: &CStr| exts.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|x| x == n));
    for n in REQUIRED_EXTENSIONS {
        if !has_ext(n) {
            missing.push(n.to_string_lossy().into_owned());
        }
    }
    let mut query_missing = Vec::new();
    let mut pipeline_missing = Vec::new();
    if !has_ext(ash::khr::ray_query::NAME) {
        query_missing.push(ash::khr::ray_query::NAME.to_string_lossy().into_owned());
    }
    if !has_ext(ash::khr::ray_tracing_pipeline::NAME) {
        pipeline_missing.push(ash::khr::ray_tracing_pipeline::NAME.to_string_lossy().into_owned());
    }
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    // Chained only where the device has it (core in 1.2, else VK_KHR_driver_properties): the
    // layer would count the chain on an older device, one the run never picks, as an error.
    if props.api_version >= vk::API_VERSION_1_2 || has_ext(ash::khr::driver_properties::NAME) {
        let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver);
        // SAFETY: as above; Vulkan 1.1+ core query, with a structure the device knows.
        unsafe { instance.get_physical_device_properties2(pd, &mut props2) };
    }
    let driver_name = driver.driver_info_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
    let driver_id = driver.driver_name_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
    if props.api_version >= vk::API_VERSION_1_2 {
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut fas = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
        let mut frq = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
        let mut frt = vk::PhysicalDeviceRayTracingPipelineFeaturesKHR::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f12);
        if has_ext(ash::khr::acceleration_structure::NAME) {
            f2 = f2.push_next(&mut fas);
        }
        if has_ext(ash::khr::ray_query::NAME) {
            f2 = f2.push_next(&mut frq);
        }
        if has_ext(ash::khr::ray_tracing_pipeline::NAME) {
            f2 = f2.push_next(&mut frt);
        }
        // SAFETY: the chain only holds structs of extensions the device exposes.
        unsafe { instance.get_physical_device_features2(pd, &mut f2) };
        if f12.buffer_device_address == 0 {
            missing.push("feature bufferDeviceAddress".into());
        }
        if has_ext(ash::khr::acceleration_structure::NAME) && fas.acceleration_structure == 0 {
            missing.push("feature accelerationStructure".into());
        }
        if has_ext(ash::khr::ray_query::NAME) && frq.ray_query == 0 {
            query_missing.push("feature rayQuery".into());
        }
        if has_ext(ash::khr::ray_tracing_pipeline::NAME) && frt.ray_tracing_pipeline == 0 {
            pipeline_missing.push("feature rayTracingPipeline".into());
        }
    }
    let tracing = match request {
        Some(Tracing::Query) => {
            missing.extend(query_missing);
            Tracing::Query
        }
        Some(Tracing::Pipeline) => {
            missing.extend(pipeline_missing);
            Tracing::Pipeline
        }
        None if query_missing.is_empty() => Tracing::Query,
        None if pipeline_missing.is_empty() => Tracing::Pipeline,
        None => {
            missing.push(format!("{} (or {})", query_missing.join(", "), pipeline_missing.join(", ")));
            Tracing::Query
        }
    };
    let per_stage = props.limits.max_per_stage_descriptor_storage_buffers;
    if per_stage < REQUIRED_STORAGE_BUFFERS_PER_STAGE {
        missing.push(format!("{REQUIRED_STORAGE_BUFFERS_PER_STAGE} storage buffers per shader stage (has {per_stage})"));
    }
    // SAFETY: as above.
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    if !families.iter().any(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE)) {
        missing.push("a compute queue".into());
    }
    let report = DeviceReport {
        index,
        name,
        kind: kind.into(),
        api_version: version_string(props.api_version),
        driver: if driver_info_empty(&driver_name) { driver_id } else { format!("{driver_id} {driver_name}") },
        tracing: missing.is_empty().then_some(tracing),
        missing,
    };
    (report, rank)
}

fn driver_info_empty(s: &str) -> bool {
    s.trim().is_empty()
}

fn load_entry() -> Result<ash::Entry> {
    // SAFETY: loading the system Vulkan loader; no other code is running Vulkan yet.
    unsafe { ash::Entry::load() }.map_err(|e| {
        anyhow::anyhow!("cannot load the Vulkan loader (libvulkan.so.1): {e}; run scripts/setup.sh to install it")
    })
}

/// The instance that keeps the Vulkan loader and the drivers it found loaded until the process
/// exits (never destroyed; its own entry holds the loader).
static DRIVERS_KEPT: std::sync::OnceLock<Option<(ash::Entry, ash::Instance)>> = std::sync::OnceLock::new();

/// Makes, once per process, a bare instance (no layer, no extension) that is never destroyed, so
/// that the drivers stay loaded between contexts. The loader loads every driver when an instance
/// is made and unloads it when the last one is destroyed; NVIDIA's driver (580.159, H100, stop 42)
/// could not be loaded again after about 29 such rounds in one process: from then on the loader
/// got no vkCreateInstance from it and found no driver. A test binary, whose tests each make and
/// drop contexts one after another, met it (tests/furnace.rs's 48 in a row, with or without the
/// validation layer; docs/gpu.md); a command's one context never does. Where no instance can be
/// made, nothing is kept and the caller's own vkCreateInstance reports why. Called under
/// [`lifetime_exclusive`].
fn keep_drivers_loaded(entry: &ash::Entry) {
    DRIVERS_KEPT.get_or_init(|| {
        let info = vk::InstanceCreateInfo::default();
        // SAFETY: an empty create info; the instance is never destroyed (see above).
        unsafe { entry.create_instance(&info, None) }.ok().map(|instance| (entry.clone(), instance))
    });
}

/// The debug messenger's settings, for the messenger and for vkCreateInstance's pNext (which
/// covers the messages of vkCreateInstance and vkDestroyInstance themselves, where no messenger
/// exists yet or any longer). `counter` must outlive every use of the returned info.
fn messenger_info(counter: &Arc<ValidationCounter>) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                | vk::DebugUtilsMessageSeverityFlagsEXT::INFO,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(debug_callback))
        .user_data(Arc::as_ptr(counter) as *mut c_void)
}

/// Makes the instance; under the validation layer, where the loader has VK_EXT_debug_utils and
/// `counter` is given, the layer's messages of vkCreateInstance and vkDestroyInstance go to it too.
fn create_instance(
    entry: &ash::Entry,
    validate: bool,
    window: Option<&WindowHandles>,
    counter: Option<&Arc<ValidationCounter>>,
) -> Result<(ash::Instance, bool, bool)> {
    // The whole of it under the device-lifetime lock, the enumerations too, since each one has the
    // loader load and query every driver as vkCreateInstance does. (The failure that led here, a
    // test context on an H100 and an H200 finding no driver, was not a race between threads but
    // the driver's reloads: see keep_drivers_loaded.)
    let _lifetime = lifetime_exclusive();
    keep_drivers_loaded(entry);
    let has_validation = has_validation_layer(entry);
    // SAFETY: plain enumeration call on a loaded entry.
    let exts = unsafe { entry.enumerate_instance_extension_properties(None) }.unwrap_or_default();
    let has_debug_utils =
        exts.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == ash::ext::debug_utils::NAME));
    let use_validation = validate && has_validation;
    if validate && !has_validation {
        log::warn!("--validate: the Khronos validation layer is not installed (apt-get install vulkan-validationlayers); running without it");
    }
    let app_name = CString::new("restir-vpl").expect("no NUL in a literal");
    let app = vk::ApplicationInfo::default()
        .application_name(&app_name)
        .application_version(vk::make_api_version(0, 0, 1, 0))
        .engine_name(&app_name)
        .api_version(vk::API_VERSION_1_2);
    let layer_ptrs: Vec<*const i8> = if use_validation { vec![VALIDATION_LAYER.as_ptr()] } else { vec![] };
    let mut ext_ptrs: Vec<*const i8> = if has_debug_utils { vec![ash::ext::debug_utils::NAME.as_ptr()] } else { vec![] };
    if let Some(w) = window {
        let surface_exts = ash_window::enumerate_required_extensions(w.display)
            .context("this window system has no Vulkan surface extension")?;
        ext_ptrs.extend_from_slice(surface_exts);
    }
    // Synchronization validation (missing or wrong barriers between passes: hazards lavapipe's
    // in-order queue forgives and a GPU does not) with the layer's default checks, when the layer
    // offers VK_EXT_validation_features.
    let sync_features = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&sync_features);
    let layer_has_features = use_validation && {
        // SAFETY: plain enumeration call on a loaded entry.
        let layer_exts = unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }.unwrap_or_default();
        layer_exts.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == ash::ext::validation_features::NAME))
    };
    if layer_has_features {
        ext_ptrs.push(ash::ext::validation_features::NAME.as_ptr());
    }
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layer_ptrs)
        .enabled_extension_names(&ext_ptrs);
    if layer_has_features {
        info = info.push_next(&mut features);
    }
    // Under the validation layer only, and its VALIDATION messages only: the loader reports
    // through a chained messenger too, while it scans for drivers and layers (a manifest whose
    // library is missing: GENERAL errors), which are no error of this program's and failed every
    // run on a machine with a stray manifest.
    let mut instance_messenger = counter
        .filter(|_| has_debug_utils && use_validation)
        .map(|c| messenger_info(c).message_type(vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION));
    if let Some(m) = instance_messenger.as_mut() {
        info = info.push_next(m);
    }
    // SAFETY: the create info points at locals that outlive the call; the messenger's user data
    // (the caller's counter) outlives the instance.
    let instance = match unsafe { entry.create_instance(&info, None) } {
        Ok(instance) => instance,
        // The loader found no driver at all: no device, said as such (exit code 2).
        Err(vk::Result::ERROR_INCOMPATIBLE_DRIVER) => {
            return Err(NoTracingDevice {
                devices: Vec::new(),
                hint: Some("the Vulkan loader found no driver (VK_ICD_FILENAMES / VK_DRIVER_FILES, or install one: scripts/setup.sh)".into()),
            }
            .into())
        }
        Err(e) => return Err(e).context("vkCreateInstance failed"),
    };
    Ok((instance, use_validation, has_debug_utils))
}

/// Lists every physical device with what it lacks and how it would trace rays when asked for
/// `request` (`--trace`; None: `RESTIR_VPL_TRACE`, else auto), for `--list-devices`.
/// Every physical device with what it lacks. No driver at all, or no device, is the
/// [`NoTracingDevice`] error a render gives (the first names the driver files to check).
pub fn list_devices(request: Option<Tracing>) -> Result<Vec<DeviceReport>> {
    let request = requested_tracing(request)?;
    let entry = load_entry()?;
    let (instance, _, _) = create_instance(&entry, false, None, None)?;
    // SAFETY: the instance is valid; destroyed below after use.
    let pds = unsafe { instance.enumerate_physical_devices() }.unwrap_or_default();
    let reports: Vec<DeviceReport> = pds.iter().enumerate().map(|(i, pd)| inspect(&instance, i, *pd, request).0).collect();
    // Nothing created from the instance outlives this point.
    destroy_instance(&instance, &None);
    if reports.is_empty() {
        return Err(NoTracingDevice { devices: Vec::new(), hint: None }.into());
    }
    Ok(reports)
}

/// The way of tracing asked for: `request` (`--trace`), else `RESTIR_VPL_TRACE`, else None (the
/// device's best).
fn requested_tracing(request: Option<Tracing>) -> Result<Option<Tracing>> {
    request.map_or_else(tracing_from_env, |t| Ok(Some(t)))
}

/// The device a context takes when none is named: of those that qualify, the best kind (`inspect`'s
/// rank), then the lowest index.
fn best_device<T>(inspected: &[(DeviceReport, u32, T)]) -> Option<&(DeviceReport, u32, T)> {
    inspected.iter().filter(|x| x.0.qualifies()).min_by_key(|x| (x.1, x.0.index))
}

/// maxStorageBufferRange of the device a context made with these options would pick (as
/// [`Context::new`] chooses: `device_index`, else the best device that qualifies), read without
/// creating a device; None where there is none or the driver cannot be asked (the context's own
/// creation then says why). The scene loader asks it before decoding textures too large for
/// some devices ([`crate::scene::Scene::load_for_device`]).
pub fn storage_buffer_range(device_index: Option<usize>, request: Option<Tracing>) -> Option<u64> {
    let request = requested_tracing(request).ok()?;
    let entry = load_entry().ok()?;
    let (instance, _, _) = create_instance(&entry, false, None, None).ok()?;
    // SAFETY: the instance is valid; destroyed below, after its devices' properties are read.
    let pds = unsafe { instance.enumerate_physical_devices() }.unwrap_or_default();
    let inspected: Vec<(DeviceReport, u32, vk::PhysicalDevice)> =
        pds.iter().enumerate().map(|(i, pd)| { let (r, rank) = inspect(&instance, i, *pd, request); (r, rank, *pd) }).collect();
    let chosen = match device_index {
        Some(i) => inspected.iter().find(|x| x.0.index == i && x.0.qualifies()),
        None => best_device(&inspected),
    };
    // SAFETY: `pd` comes from this instance.
    let range = chosen.map(|x| u64::from(unsafe { instance.get_physical_device_properties(x.2) }.limits.max_storage_buffer_range));
    destroy_instance(&instance, &None);
    range
}

impl Context {
    pub fn new(opts: &ContextOptions) -> Result<Self> {
        let request = requested_tracing(opts.tracing)?;
        let gpu_timeout = gpu_timeout_from_env()?;
        let cache_enabled = super::pipeline_cache::enabled_from_env()?;
        let entry = load_entry()?;
        // Made before the instance and dropped after it (declared before `unwind`, and a field
        // of the context): the messengers read it as their user data until the instance is gone.
        let validation = Arc::new(ValidationCounter::default());
        let (instance, validation_enabled, has_debug_utils) =
            create_instance(&entry, opts.validate, opts.window.as_ref(), Some(&validation))?;
        // Destroys what is made below if a step fails (every `?` from here leaked the instance,
        // and after vkCreateDevice the device too); disarmed once the context owns them.
        let mut unwind = Unwind::default();
        unwind.instance = Some(instance.clone());
        let debug_instance = if has_debug_utils {
            let loader = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = messenger_info(&validation);
            // SAFETY: the counter behind user_data lives in `validation`, which outlives the messenger.
            let messenger = unsafe { loader.create_debug_utils_messenger(&info, None) }
                .context("vkCreateDebugUtilsMessengerEXT failed")?;
            Some((loader, messenger))
        } else {
            None
        };
        unwind.debug = debug_instance.clone();

        let surface = match &opts.window {
            Some(w) => {
                // SAFETY: the handles come from a live window that outlives the context (the window
                // module drops the context before the window).
                let raw = unsafe { ash_window::create_surface(&entry, &instance, w.display, w.window, None) };
                match raw {
                    Ok(raw) => Some((ash::khr::surface::Instance::new(&entry, &instance), raw)),
                    Err(e) => bail!("cannot create a Vulkan surface for the window: {e}"),
                }
            }
            None => None,
        };
        unwind.surface = surface.clone();
        // SAFETY: valid instance.
        let pds = match unsafe { instance.enumerate_physical_devices() } {
            Ok(pds) => pds,
            // The loader answers "no driver found a device" with an initialisation failure: that
            // is no device, reported below as such (exit code 2), not a cryptic error.
            Err(vk::Result::ERROR_INITIALIZATION_FAILED) => Vec::new(),
            Err(e) => return Err(e).context("vkEnumeratePhysicalDevices failed"),
        };
        let inspected: Vec<(DeviceReport, u32, vk::PhysicalDevice)> = pds
            .iter()
            .enumerate()
            .map(|(i, pd)| {
                let (mut r, rank) = inspect(&instance, i, *pd, request);
                if let Some((loader, raw)) = &surface {
                    if present_family(&instance, loader, *raw, *pd).is_none() {
                        r.missing.push("a compute and graphics queue that presents to the window (VK_KHR_swapchain)".into());
                        r.tracing = None;
                    }
                }
                (r, rank, *pd)
            })
            .collect();
        let reports: Vec<DeviceReport> = inspected.iter().map(|x| x.0.clone()).collect();
        let chosen = match opts.device_index {
            Some(i) => {
                let Some((r, _, pd)) = inspected.iter().find(|x| x.0.index == i) else {
                    bail!(
                        "--device {i}: there is no device {i}; devices:\n{}",
                        reports.iter().map(|d| format!("  {d}")).collect::<Vec<_>>().join("\n")
                    );
                };
                if !r.qualifies() {
                    return Err(NoTracingDevice {
                        devices: reports,
                        hint: Some(format!("--device {i} picks a device that cannot run the renderer")),
                    }
                    .into());
                }
                (r.clone(), *pd)
            }
            None => {
                let best = best_device(&inspected);
                match best {
                    Some((r, _, pd)) => (r.clone(), *pd),
                    None => {
                        let hint = no_device_hint(&reports);
                        return Err(NoTracingDevice { devices: reports, hint }.into());
                    }
                }
            }
        };
        let (report, physical_device) = chosen;
        let tracing = report.tracing.expect("a device that qualifies has a way to trace rays");

        // SAFETY: valid physical device of this instance.
        let properties = unsafe { instance.get_physical_device_properties(physical_device) };
        let mut asp = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
        let mut rtp = vk::PhysicalDeviceRayTracingPipelinePropertiesKHR::default();
        let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
        let mut maintenance3 = vk::PhysicalDeviceMaintenance3Properties::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut asp).push_next(&mut subgroup).push_next(&mut maintenance3);
        if tracing == Tracing::Pipeline {
            p2 = p2.push_next(&mut rtp);
        }
        // SAFETY: the device exposes VK_KHR_acceleration_structure (it qualified).
        unsafe { instance.get_physical_device_properties2(physical_device, &mut p2) };
        let as_properties =
            AccelProperties {
                min_scratch_offset_alignment: asp.min_acceleration_structure_scratch_offset_alignment,
                max_instance_count: asp.max_instance_count,
            };
        let subgroup_arithmetic = subgroup.supported_stages.contains(vk::ShaderStageFlags::COMPUTE)
            && subgroup
                .supported_operations
                .contains(vk::SubgroupFeatureFlags::BASIC | vk::SubgroupFeatureFlags::ARITHMETIC);

        // SAFETY: as above.
        let families = unsafe { instance.get_physical_device_queue_family_properties(physical_device) };
        let queue_family = match &surface {
            Some((loader, raw)) => present_family(&instance, loader, *raw, physical_device)
                .context("the chosen device has no compute and graphics queue that presents to the window")?,
            None => families
                .iter()
                .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE) && f.timestamp_valid_bits > 0)
                .or_else(|| families.iter().position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE)))
                .context("the chosen device has no compute queue")? as u32,
        };

        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
        let mut ext_ptrs: Vec<*const i8> = REQUIRED_EXTENSIONS.iter().map(|n| n.as_ptr()).collect();
        ext_ptrs.push(match tracing {
            Tracing::Query => ash::khr::ray_query::NAME.as_ptr(),
            Tracing::Pipeline => ash::khr::ray_tracing_pipeline::NAME.as_ptr(),
        });
        if surface.is_some() {
            ext_ptrs.push(ash::khr::swapchain::NAME.as_ptr());
        }
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default()
            .buffer_device_address(true)
            .host_query_reset(true);
        let mut fas = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
        let mut frq = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
        let mut frt = vk::PhysicalDeviceRayTracingPipelineFeaturesKHR::default().ray_tracing_pipeline(true);
        let features = vk::PhysicalDeviceFeatures::default();
        let info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&ext_ptrs)
            .enabled_features(&features)
            .push_next(&mut f12)
            .push_next(&mut fas);
        let info = match tracing {
            Tracing::Query => info.push_next(&mut frq),
            Tracing::Pipeline => info.push_next(&mut frt),
        };
        let device = {
            let _lifetime = lifetime_exclusive();
            // SAFETY: the create info references locals alive for the call; features were checked.
            unsafe { instance.create_device(physical_device, &info, None) }
        }
        .with_context(|| format!("vkCreateDevice failed on {}", report.name))?;
        unwind.device = Some(device.clone());
        // SAFETY: queue family and index exist (created above).
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let accel = ash::khr::acceleration_structure::Device::new(&instance, &device);
        let ray_tracing = (tracing == Tracing::Pipeline).then(|| RayTracingPipelines {
            loader: ash::khr::ray_tracing_pipeline::Device::new(&instance, &device),
            handle_size: rtp.shader_group_handle_size,
            handle_alignment: rtp.shader_group_handle_alignment.max(1),
            base_alignment: rtp.shader_group_base_alignment.max(1),
            max_invocations: rtp.max_ray_dispatch_invocation_count,
        });
        let debug_utils = has_debug_utils.then(|| ash::ext::debug_utils::Device::new(&instance, &device));

        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device,
            debug_settings: Default::default(),
            buffer_device_address: true,
            allocation_sizes: Default::default(),
        })
        .context("creating the GPU memory allocator")?;

        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device.
        let command_pool = unsafe { device.create_command_pool(&pool_info, None) }.context("vkCreateCommandPool")?;
        unwind.command_pool = command_pool;

        let pipeline_cache_file = cache_enabled.then(|| super::pipeline_cache::cache_path(&properties)).flatten();
        let initial = match &pipeline_cache_file {
            Some(path) => match super::pipeline_cache::load(path, &properties) {
                Ok(data) => data.unwrap_or_default(),
                Err(why) => {
                    log::warn!("pipeline cache {}: {why}; starting an empty one", path.display());
                    Vec::new()
                }
            },
            None => Vec::new(),
        };
        let pipelines = pipeline_creation_guard();
        // SAFETY: valid device; the initial data's header was checked against this device.
        let pipeline_cache = unsafe { device.create_pipeline_cache(&vk::PipelineCacheCreateInfo::default().initial_data(&initial), None) }
            .or_else(|e| {
                log::warn!("pipeline cache: the driver refused the saved data ({e}); starting an empty one");
                // SAFETY: as above, without initial data.
                unsafe { device.create_pipeline_cache(&vk::PipelineCacheCreateInfo::default(), None) }
            })
            .context("vkCreatePipelineCache")?;
        drop(pipelines);
        if let Some(path) = &pipeline_cache_file {
            log::info!("pipeline cache: {} ({} bytes loaded)", path.display(), initial.len());
        }

        let presentation = surface.map(|(surface_loader, surface)| Presentation {
            surface_loader,
            surface,
            swapchain_loader: ash::khr::swapchain::Device::new(&instance, &device),
        });
        log::info!("device: {report}");
        unwind.disarm();
        Ok(Self {
            entry,
            instance,
            physical_device,
            device,
            queue,
            queue_family,
            allocator: ManuallyDrop::new(Arc::new(Mutex::new(allocator))),
            pipeline_cache,
            pipeline_cache_loaded: initial.len(),
            pipeline_cache_file,
            accel,
            debug_utils,
            debug_instance,
            report,
            properties,
            as_properties,
            tracing,
            ray_tracing,
            validation_enabled,
            validation,
            command_pool,
            presentation,
            nonfinite_samples: AtomicU64::new(0),
            gpu_timeout,
            hung: AtomicBool::new(false),
            subgroup_arithmetic,
            max_allocation: maintenance3.max_memory_allocation_size,
        })
    }

    /// Refuses a `width`×`height` launch over this device's maxRayDispatchInvocationCount when rays
    /// are traced with ray-tracing pipelines (a pass traces one launch per pixel: 2^26 on lavapipe,
    /// 2^30 on NVIDIA); any size with ray queries.
    pub fn check_launch_size(&self, width: u32, height: u32) -> Result<()> {
        if let Some(rt) = &self.ray_tracing {
            let pixels = u64::from(width) * u64::from(height);
            if pixels > u64::from(rt.max_invocations) {
                bail!(
                    "--width {width} --height {height}: {pixels} pixels, more than the {} rays one launch may start on this \
                     device (maxRayDispatchInvocationCount; rays are traced with ray-tracing pipelines here)",
                    rt.max_invocations
                );
            }
        }
        Ok(())
    }

    /// The shader stages of a pass's descriptor sets and push constants: compute, and ray
    /// generation where the passes that trace are ray-generation shaders.
    pub fn pass_stages(&self) -> vk::ShaderStageFlags {
        match self.tracing {
            Tracing::Query => vk::ShaderStageFlags::COMPUTE,
            Tracing::Pipeline => vk::ShaderStageFlags::COMPUTE | vk::ShaderStageFlags::RAYGEN_KHR,
        }
    }

    /// The pipeline stages the passes run in, for barriers between them.
    pub fn pass_pipeline_stages(&self) -> vk::PipelineStageFlags {
        match self.tracing {
            Tracing::Query => vk::PipelineStageFlags::COMPUTE_SHADER,
            Tracing::Pipeline => vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
        }
    }

    /// The stages that read acceleration structures: the builds, and the passes' shaders that
    /// trace (compute with ray queries, the ray-tracing stage with pipelines).
    pub fn acceleration_structure_read_stages(&self) -> vk::PipelineStageFlags {
        vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR
            | match self.tracing {
                Tracing::Query => vk::PipelineStageFlags::COMPUTE_SHADER,
                Tracing::Pipeline => vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
            }
    }

    /// Validation-layer errors reported so far (0 when the layer is off).
    pub fn validation_errors(&self) -> u64 {
        self.validation.errors.load(Ordering::SeqCst)
    }

    /// Non-finite samples replaced by 0 so far, over every renderer on this context.
    pub fn nonfinite_samples(&self) -> u64 {
        self.nonfinite_samples.load(Ordering::SeqCst)
    }

    /// Adds `n` to [`Self::nonfinite_samples`] (renderers, as their frames complete).
    pub fn add_nonfinite_samples(&self, n: u64) {
        self.nonfinite_samples.fetch_add(n, Ordering::SeqCst);
    }

    /// The counter itself, to read after the context is gone: the messages of its teardown
    /// (vkDestroyDevice and vkDestroyInstance report every object left alive) come after any
    /// check a run makes through the context.
    pub fn validation_counter(&self) -> Arc<ValidationCounter> {
        Arc::clone(&self.validation)
    }

    /// The first validation error message, if any.
    pub fn first_validation_error(&self) -> Option<String> {
        self.validation.first_error.lock().ok().and_then(|g| g.clone())
    }

    /// Fails a run whose context drew validation errors (their text went to the log) or, under
    /// validation (the strict runs), whose renderers replaced non-finite samples. What every
    /// command checks before it exits 0: a benchmark, `results`, a reference, a window closed by
    /// its user ([`Context::ensure_clean_for`]).
    pub fn ensure_clean(&self) -> Result<()> {
        self.ensure_clean_for(false)
    }

    /// [`Context::ensure_clean`] for a run that asked for validation (`validate_requested`): its
    /// non-finite samples fail it whether or not the layer could be loaded, as a headless run's do.
    pub fn ensure_clean_for(&self, validate_requested: bool) -> Result<()> {
        self.ensure_no_validation_errors()?;
        let nonfinite = if self.validation_enabled || validate_requested { self.nonfinite_samples() } else { 0 };
        anyhow::ensure!(nonfinite == 0, "{nonfinite} non-finite sample(s) (NaN or Inf, replaced by 0 in the images) under validation: a shader produced them");
        Ok(())
    }

    /// The validation errors counted so far, as an error naming the first (they come before any
    /// count of non-finite samples in both checks below and above).
    fn ensure_no_validation_errors(&self) -> Result<()> {
        match self.validation_errors() {
            0 => Ok(()),
            n => anyhow::bail!("{n} Vulkan validation error(s) under validation; the first: {}", self.first_validation_error().unwrap_or_default()),
        }
    }

    /// For a command whose report is computed from its images (`results`, `bench --curves`,
    /// `--motion`, `--radius`, `reference`): [`Context::ensure_clean`], and any non-finite sample
    /// fails it with or without validation, since the accumulation replaced it by 0 and the
    /// report's errors and biases would hide it.
    pub fn ensure_clean_report(&self) -> Result<()> {
        self.ensure_no_validation_errors()?;
        let n = self.nonfinite_samples();
        anyhow::ensure!(
            n == 0,
            "{n} non-finite sample(s) (NaN or Inf) were replaced by 0 in the images this report is computed from: its numbers would hide a shader's defect (--check-finite finds the pass)"
        );
        Ok(())
    }

    /// Allocates memory for a buffer or image under `name` (the name gpu-allocator reports; callers
    /// give the Vulkan object the same one with [`Self::set_name`]).
    pub fn allocate(
        &self,
        name: &str,
        requirements: vk::MemoryRequirements,
        location: MemoryLocation,
        linear: bool,
    ) -> Result<Allocation> {
        self.allocator
            .lock()
            .map_err(|_| anyhow::anyhow!("allocator mutex poisoned"))?
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .with_context(|| format!("allocating {} bytes for '{name}'", requirements.size))
    }

    /// Memory for an object just created (a buffer or image), bound to it by `bind`. On failure
    /// the object is released by `destroy` (and the memory freed): no owner holds it yet.
    pub fn allocate_bound(
        &self,
        name: &str,
        requirements: vk::MemoryRequirements,
        location: MemoryLocation,
        linear: bool,
        bind: impl FnOnce(&Allocation) -> ash::prelude::VkResult<()>,
        destroy: impl FnOnce(),
    ) -> Result<Allocation> {
        let allocation = match self.allocate(name, requirements, location, linear) {
            Ok(allocation) => allocation,
            Err(e) => {
                destroy();
                return Err(e);
            }
        };
        if let Err(e) = bind(&allocation) {
            self.free(allocation);
            destroy();
            return Err(e).with_context(|| format!("binding memory of '{name}'"));
        }
        Ok(allocation)
    }

    /// Returns an allocation made by [`Self::allocate`] (after its object is destroyed).
    pub fn free(&self, allocation: Allocation) {
        if let Ok(mut alloc) = self.allocator.lock() {
            let _ = alloc.free(allocation);
        }
    }

    /// Names a Vulkan object for debuggers (RenderDoc, Nsight) through VK_EXT_debug_utils.
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(du) = &self.debug_utils {
            let Ok(cname) = CString::new(name) else { return };
            let info = vk::DebugUtilsObjectNameInfoEXT::default().object_handle(handle).object_name(&cname);
            // SAFETY: the handle belongs to this device; naming failures are harmless.
            let _ = unsafe { du.set_debug_utils_object_name(&info) };
        }
    }

    /// Opens a debug label region in a command buffer.
    pub fn begin_label(&self, cmd: vk::CommandBuffer, name: &str) {
        if let Some(du) = &self.debug_utils {
            let Ok(cname) = CString::new(name) else { return };
            let label = vk::DebugUtilsLabelEXT::default().label_name(&cname).color([0.3, 0.6, 1.0, 1.0]);
            // SAFETY: cmd is in the recording state (caller's contract).
            unsafe { du.cmd_begin_debug_utils_label(cmd, &label) };
        }
    }

    pub fn end_label(&self, cmd: vk::CommandBuffer) {
        if let Some(du) = &self.debug_utils {
            // SAFETY: paired with begin_label on the same command buffer.
            unsafe { du.cmd_end_debug_utils_label(cmd) };
        }
    }

    /// A primary command buffer from the shared pool and a fence, both named `name` (a frame slot,
    /// a present slot). The caller frees and destroys them.
    pub fn command_buffer_and_fence(&self, name: &str, signaled: bool) -> Result<(vk::CommandBuffer, vk::Fence)> {
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        let flags = if signaled { vk::FenceCreateFlags::SIGNALED } else { vk::FenceCreateFlags::empty() };
        // SAFETY: valid device and pool.
        unsafe {
            let cmd = self.device.allocate_command_buffers(&alloc).with_context(|| format!("allocating command buffer '{name}'"))?[0];
            self.set_name(cmd, name);
            let fence = match self.device.create_fence(&vk::FenceCreateInfo::default().flags(flags), None) {
                Ok(f) => f,
                Err(e) => {
                    self.device.free_command_buffers(self.command_pool, &[cmd]);
                    return Err(e).with_context(|| format!("creating fence '{name}'"));
                }
            };
            self.set_name(fence, name);
            Ok((cmd, fence))
        }
    }

    /// Records commands into a one-time command buffer, submits it and waits.
    pub fn one_shot(&self, record: impl FnOnce(vk::CommandBuffer)) -> Result<()> {
        self.ensure_not_hung()?;
        let (cmd, fence) = self.command_buffer_and_fence("one_shot", false)?;
        // SAFETY: valid pool; the buffer and fence are freed before returning.
        unsafe {
            let r = self
                .device
                .begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT))
                .and_then(|_| {
                    crate::vk::pipeline::submission_start_barrier(self, cmd);
                    record(cmd);
                    crate::vk::pipeline::host_read_barrier(self, cmd);
                    self.device.end_command_buffer(cmd)
                })
                .and_then(|_| {
                    let cmds = [cmd];
                    let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
                    self.device.queue_submit(self.queue, &submit, fence)
                })
                .context("one-shot submission failed (device lost?)")
                .and_then(|_| self.wait_fence(fence, &|| "a one-time submission (an upload, a read-back, an acceleration-structure build or the photon pass)".into(), &|| None));
            if !self.is_hung() {
                self.device.destroy_fence(fence, None);
                self.device.free_command_buffers(self.command_pool, &[cmd]);
            }
            r?;
        }
        Ok(())
    }

    /// Waits for `fence`, signalled by the submission `what` describes, in steps, so that one that
    /// does not finish becomes a diagnosis instead of a silent hang: every
    /// [`GPU_WAIT_WARN_EVERY`] it warns, with `progress()` (what the device has finished of it, where
    /// known), and after [`Context::gpu_timeout`] it marks the context hung ([`Context::is_hung`])
    /// and fails, saying the same.
    pub fn wait_fence(&self, fence: vk::Fence, what: &dyn Fn() -> String, progress: &dyn Fn() -> Option<String>) -> Result<()> {
        self.ensure_not_hung()?;
        let start = Instant::now();
        let mut next_warning = GPU_WAIT_WARN_EVERY;
        let detail = || progress().map(|p| format!("; {p}")).unwrap_or_default();
        loop {
            let left = self.gpu_timeout.map_or(GPU_WAIT_WARN_EVERY, |limit| limit.saturating_sub(start.elapsed()));
            let step = left.min(next_warning.saturating_sub(start.elapsed())).max(Duration::from_millis(1));
            // SAFETY: the fence belongs to a submission of this device.
            match unsafe { self.device.wait_for_fences(&[fence], true, step.as_nanos() as u64) } {
                Ok(()) => return Ok(()),
                Err(vk::Result::TIMEOUT) => {}
                Err(e) => return Err(e).with_context(|| format!("waiting for {} (device lost?){}", what(), detail())),
            }
            let waited = start.elapsed();
            if let Some(limit) = self.gpu_timeout.filter(|&limit| waited >= limit) {
                self.hung.store(true, Ordering::SeqCst);
                A_DEVICE_HUNG.store(true, Ordering::SeqCst);
                bail!(
                    "{} did not finish in {:.0} s on {} (RESTIR_VPL_GPU_TIMEOUT_S sets the limit, 0 for none){}",
                    what(),
                    limit.as_secs_f64(),
                    self.report.name,
                    detail()
                );
            }
            if waited >= next_warning {
                log::warn!("still waiting for {} after {:.0} s{}", what(), waited.as_secs_f64(), detail());
                next_warning = waited + GPU_WAIT_WARN_EVERY;
            }
        }
    }

    /// Whether a submission ran past the time limit ([`Context::wait_fence`]).
    pub fn is_hung(&self) -> bool {
        self.hung.load(Ordering::SeqCst)
    }

    /// Fails when the context is hung: nothing more may be submitted to or waited on it (the late
    /// submission may still use what it would reuse).
    pub fn ensure_not_hung(&self) -> Result<()> {
        anyhow::ensure!(!self.is_hung(), "{}: an earlier submission did not finish; the device takes no more work", self.report.name);
        Ok(())
    }

    /// `vkDeviceWaitIdle` before resources in use are replaced: fails at once when the context is
    /// hung (it would never return).
    pub fn wait_idle(&self) -> Result<()> {
        self.ensure_not_hung()?;
        // SAFETY: valid device.
        unsafe { self.device.device_wait_idle() }.context("waiting for the device")?;
        Ok(())
    }

    /// `vkDeviceWaitIdle` for the drops: nothing when the context is hung (it would never return).
    pub fn wait_idle_for_drop(&self) {
        if !self.is_hung() {
            // SAFETY: valid device.
            let _ = unsafe { self.device.device_wait_idle() };
        }
    }
}

/// The queue family of `pd` that computes, draws (the preview's blit and the overlay's render pass
/// need a graphics queue) and presents to `surface` (with timestamps when one does), if any.
fn present_family(
    instance: &ash::Instance,
    loader: &ash::khr::surface::Instance,
    surface: vk::SurfaceKHR,
    pd: vk::PhysicalDevice,
) -> Option<u32> {
    // SAFETY: `pd` belongs to `instance`; the surface was created from it.
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    let presents = |i: usize| {
        // SAFETY: as above; i indexes an existing family.
        unsafe { loader.get_physical_device_surface_support(pd, i as u32, surface) }.unwrap_or(false)
    };
    let ok = |i: usize, f: &vk::QueueFamilyProperties| f.queue_flags.contains(vk::QueueFlags::COMPUTE | vk::QueueFlags::GRAPHICS) && presents(i);
    let with_timestamps = families.iter().enumerate().position(|(i, f)| ok(i, f) && f.timestamp_valid_bits > 0);
    with_timestamps.or_else(|| families.iter().enumerate().position(|(i, f)| ok(i, f))).map(|i| i as u32)
}

/// What `Context::new` has made so far, destroyed in reverse order if it fails part-way (its
/// locals made later, the allocator, drop before this, which is declared first).
#[derive(Default)]
struct Unwind {
    instance: Option<ash::Instance>,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    surface: Option<(ash::khr::surface::Instance, vk::SurfaceKHR)>,
    device: Option<ash::Device>,
    command_pool: vk::CommandPool,
}

impl Unwind {
    /// The context owns everything now: nothing is destroyed here.
    fn disarm(&mut self) {
        self.instance = None;
        self.debug = None;
        self.surface = None;
        self.device = None;
        self.command_pool = vk::CommandPool::null();
    }
}

impl Drop for Unwind {
    fn drop(&mut self) {
        // SAFETY: on a failed Context::new, nothing made from these objects is left (no swapchain,
        // no submission); the reverse order of creation.
        unsafe {
            if let Some(device) = self.device.take() {
                if self.command_pool != vk::CommandPool::null() {
                    device.destroy_command_pool(self.command_pool, None);
                }
                let _lifetime = lifetime_exclusive();
                device.destroy_device(None);
            }
            if let Some((loader, raw)) = self.surface.take() {
                loader.destroy_surface(raw, None);
            }
        }
        if let Some(instance) = self.instance.take() {
            destroy_instance(&instance, &self.debug.take());
        }
    }
}

/// Destroys the debug messenger, if any, then the instance, under [`DEVICE_LIFETIME`].
fn destroy_instance(
    instance: &ash::Instance,
    debug: &Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
) {
    // SAFETY: called once every object made from the instance is gone (on error paths before any
    // device object exists, from Context's Drop after the device and surface).
    unsafe {
        if let Some((loader, m)) = debug {
            loader.destroy_debug_utils_messenger(*m, None);
        }
        let _lifetime = lifetime_exclusive();
        instance.destroy_instance(None);
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        if self.is_hung() {
            // The device may still be executing the submission that ran past the limit:
            // destroying it could block too. The process's exit frees it.
            log::warn!("the device is left as it is: a submission did not finish");
            return;
        }
        // SAFETY: every resource created from this device has been dropped before the context (the
        // renderer owns the context last); we wait for idle first.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_command_pool(self.command_pool, None);
            ManuallyDrop::drop(&mut self.allocator);
            // The pipeline cache belongs with the pipelines under DEVICE_LIFETIME.
            let pipelines = pipeline_creation_guard();
            let cache = self.pipeline_cache_file.as_ref().and_then(|path| match self.device.get_pipeline_cache_data(self.pipeline_cache) {
                Ok(data) if !data.is_empty() => Some((path, data)),
                Ok(_) => None,
                Err(e) => {
                    log::warn!("pipeline cache: reading it back failed: {e}");
                    None
                }
            });
            self.device.destroy_pipeline_cache(self.pipeline_cache, None);
            drop(pipelines);
            // The file is written outside the lock: other contexts' pipelines need not wait for it.
            if let Some((path, data)) = cache {
                if let Err(e) = super::pipeline_cache::save(path, &data) {
                    log::warn!("pipeline cache: cannot write {}: {e}", path.display());
                }
            }
            {
                let _lifetime = lifetime_exclusive();
                self.device.destroy_device(None);
            }
            if let Some(p) = self.presentation.take() {
                p.surface_loader.destroy_surface(p.surface, None);
            }
            destroy_instance(&self.instance, &self.debug_instance.take());
        }
    }
}

/// Whether the Khronos validation layer is installed (tests turn it on when it is).
pub fn validation_layer_available() -> bool {
    let Ok(entry) = load_entry() else { return false };
    // Under the device-lifetime lock, as create_instance's enumerations.
    let _lifetime = lifetime_exclusive();
    has_validation_layer(&entry)
}

/// Whether the loader lists the Khronos validation layer. Called under [`lifetime_exclusive`].
fn has_validation_layer(entry: &ash::Entry) -> bool {
    // SAFETY: plain enumeration on a loaded entry.
    let layers = unsafe { entry.enumerate_instance_layer_properties() }.unwrap_or_default();
    layers.iter().any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(name: &str, missing: &[&str]) -> DeviceReport {
        DeviceReport {
            index: 0,
            name: name.into(),
            kind: "discrete GPU".into(),
            api_version: "1.3.0".into(),
            driver: "test".into(),
            missing: missing.iter().map(|m| m.to_string()).collect(),
            tracing: None,
        }
    }

    #[test]
    fn hint_names_rt_cores_for_an_nvidia_device_without_ray_queries() {
        let h100 = report("NVIDIA H100 80GB HBM3", &["VK_KHR_ray_query", "feature rayQuery"]);
        let hint = no_device_hint(&[h100]).expect("an NVIDIA device without ray queries gets the note");
        assert!(hint.contains("RT cores") && hint.contains("--trace pipeline"), "{hint}");
        // Not for other vendors, nor for an NVIDIA device that lacks something else.
        assert_eq!(no_device_hint(&[report("AMD Radeon", &["VK_KHR_ray_query"])]), None);
        assert_eq!(no_device_hint(&[report("NVIDIA GeForce RTX 4090", &["Vulkan 1.2 (has 1.1.0)"])]), None);
        assert_eq!(no_device_hint(&[]), None);
    }
}
