//! The persistent `VkPipelineCache`: loaded when the context is created, saved when it is dropped,
//! so a second run skips the driver's shader compilation where the driver caches through it.
//!
//! The file lives in `$RESTIR_VPL_CACHE_DIR`, else `$XDG_CACHE_HOME/restir-vpl`, else
//! `~/.cache/restir-vpl`, and is named by the device (vendor, device id, driver version, the
//! driver's pipeline-cache UUID) and by the hash of every embedded SPIR-V module: another driver,
//! device or build never reads it. Its header is checked against the device before the driver sees
//! it; a file that does not match is ignored (and replaced on save). `RESTIR_VPL_PIPELINE_CACHE=off`
//! turns it off.

use std::path::{Path, PathBuf};

use ash::vk;

/// Where the cache of this device and build is kept, or None when caching is off or there is no
/// cache directory.
pub fn cache_path(props: &vk::PhysicalDeviceProperties) -> Option<PathBuf> {
    if std::env::var("RESTIR_VPL_PIPELINE_CACHE").is_ok_and(|v| v == "off") {
        return None;
    }
    // An empty variable is unset; XDG_CACHE_HOME and HOME count only when absolute (the XDG base
    // directory spec says to ignore a relative one: it put the cache in the working directory).
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty()).map(PathBuf::from);
    let dir = var("RESTIR_VPL_CACHE_DIR")
        .or_else(|| var("XDG_CACHE_HOME").filter(|d| d.is_absolute()).map(|d| d.join("restir-vpl")))
        .or_else(|| var("HOME").filter(|h| h.is_absolute()).map(|h| h.join(".cache").join("restir-vpl")))?;
    let uuid: String = props.pipeline_cache_uuid.iter().map(|b| format!("{b:02x}")).collect();
    Some(dir.join(format!(
        "pipelines-{:04x}-{:04x}-{:x}-{uuid}-{:016x}.bin",
        props.vendor_id,
        props.device_id,
        props.driver_version,
        crate::shaders::SPIRV_HASH
    )))
}

/// The cache file's data if its header (VkPipelineCacheHeaderVersionOne) names this device;
/// Err(reason) when it exists but does not.
pub fn load(path: &Path, props: &vk::PhysicalDeviceProperties) -> Result<Option<Vec<u8>>, String> {
    let data = match std::fs::read(path) {
        Ok(d) => d,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e.to_string()),
    };
    header_matches(&data, props)?;
    Ok(Some(data))
}

/// Checks the 32-byte header: length, version one, vendor, device and cache UUID.
pub fn header_matches(data: &[u8], props: &vk::PhysicalDeviceProperties) -> Result<(), String> {
    if data.len() < 32 {
        return Err(format!("{} bytes: shorter than a pipeline-cache header", data.len()));
    }
    let word = |i: usize| u32::from_le_bytes(data[4 * i..4 * i + 4].try_into().expect("4 bytes"));
    let (len, version, vendor, device) = (word(0), word(1), word(2), word(3));
    if len < 32 || version != vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32 {
        return Err(format!("header length {len}, version {version}: not a version-one pipeline cache"));
    }
    if vendor != props.vendor_id || device != props.device_id || data[16..32] != props.pipeline_cache_uuid {
        return Err("written by another device or driver".into());
    }
    Ok(())
}

/// Writes the cache atomically (see [`crate::output::write_replacing`]).
pub fn save(path: &Path, data: &[u8]) -> anyhow::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    crate::output::write_replacing(path, |partial| Ok(std::fs::write(partial, data)?))
}
