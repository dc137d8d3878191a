//! The persistent `VkPipelineCache`: loaded when the context is created, saved when it is dropped,
//! so a second run skips the driver's shader compilation where the driver caches through it.
//!
//! The file lives in `$RESTIR_VPL_CACHE_DIR`, else `$XDG_CACHE_HOME/restir-vpl`, else
//! `~/.cache/restir-vpl`, and is named by the device (vendor, device id, driver version, the
//! driver's pipeline-cache UUID) and by the hash of every embedded SPIR-V module: another driver,
//! device or build never reads it. The driver's data is framed by our own 16 bytes (a magic, its
//! length and its CRC-32), and its header is checked against the device, before the driver sees
//! it: the spec allows only data the driver itself returned, so a file cut short or damaged on disk
//! (the driver's own header intact) must not reach it. A file that does not match is ignored (and
//! replaced on save). Saving removes old builds' files beside it ([`stale`]).
//! `RESTIR_VPL_PIPELINE_CACHE=off` turns it off.

use std::path::{Path, PathBuf};

use ash::vk;

/// Whether the cache is on: `RESTIR_VPL_PIPELINE_CACHE` unset, or on/off as
/// [`crate::settings::env_switch`] reads it (`OFF`, `0` and `false` wrote the cache without a
/// word). Read before the context makes anything, as `RESTIR_VPL_GPU_TIMEOUT_S` is.
pub fn enabled_from_env() -> anyhow::Result<bool> {
    crate::settings::env_switch("RESTIR_VPL_PIPELINE_CACHE", true)
}

/// Where the cache of this device and build is kept, or None when there is no cache directory.
pub fn cache_path(props: &vk::PhysicalDeviceProperties) -> Option<PathBuf> {
    // An empty variable is unset; XDG_CACHE_HOME and HOME count only when absolute (the XDG base
    // directory spec says to ignore a relative one: it put the cache in the working directory).
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty()).map(PathBuf::from);
    let dir = var("RESTIR_VPL_CACHE_DIR")
        .or_else(|| var("XDG_CACHE_HOME").filter(|d| d.is_absolute()).map(|d| d.join("restir-vpl")))
        .or_else(|| var("HOME").filter(|h| h.is_absolute()).map(|h| h.join(".cache").join("restir-vpl")))?;
    Some(dir.join(file_name(props)))
}

/// The cache file's name for this device and build ([`is_cache_file_name`] takes it).
fn file_name(props: &vk::PhysicalDeviceProperties) -> String {
    let uuid: String = props.pipeline_cache_uuid.iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "pipelines-v2-{:04x}-{:04x}-{:x}-{uuid}-{:016x}.bin",
        props.vendor_id,
        props.device_id,
        props.driver_version,
        crate::shaders::SPIRV_HASH
    )
}

/// The first bytes of every cache file this program writes ("v2" in the file name).
const MAGIC: &[u8; 8] = b"RVPLPC02";

/// The cache file's data (without our frame) if its frame is whole and its header
/// (VkPipelineCacheHeaderVersionOne) names this device; Err(reason) when it exists but is not.
pub fn load(path: &Path, props: &vk::PhysicalDeviceProperties) -> Result<Option<Vec<u8>>, String> {
    let file = match std::fs::read(path) {
        Ok(d) => d,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e.to_string()),
    };
    let data = unframe(&file)?;
    header_matches(data, props)?;
    Ok(Some(data.to_vec()))
}

/// The driver's data framed for the file: [`MAGIC`], its length and its CRC-32 (u32 each, little
/// endian), then the data.
fn frame(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(16 + data.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(data).to_le_bytes());
    out.extend_from_slice(data);
    out
}

/// The data inside a file's frame, if the frame is whole: its magic, its length and its checksum.
fn unframe(file: &[u8]) -> Result<&[u8], String> {
    if file.len() < 16 || &file[..8] != MAGIC {
        return Err(format!("{} bytes, not starting as this program's cache files do", file.len()));
    }
    let word = |i: usize| u32::from_le_bytes(file[i..i + 4].try_into().expect("4 bytes"));
    let (len, crc) = (word(8) as usize, word(12));
    let data = &file[16..];
    if data.len() != len {
        return Err(format!("{} bytes of data where its frame says {len}: cut short or damaged", data.len()));
    }
    if crc32fast::hash(data) != crc {
        return Err("its checksum does not match its data: damaged".into());
    }
    Ok(data)
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

/// Writes the cache atomically (see [`crate::output::write_replacing`]), then removes other
/// builds' and drivers' files beside it that [`stale`] names.
pub fn save(path: &Path, data: &[u8]) -> anyhow::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    anyhow::ensure!(u32::try_from(data.len()).is_ok(), "{} bytes of pipeline cache: more than its frame records", data.len());
    let framed = frame(data);
    crate::output::write_replacing(path, |partial| Ok(std::fs::write(partial, framed)?))?;
    for old in stale(path) {
        match std::fs::remove_file(&old) {
            Ok(()) => log::info!("pipeline cache: removed another build's {}", old.display()),
            Err(e) => log::debug!("pipeline cache: cannot remove {}: {e}", old.display()),
        }
    }
    Ok(())
}

/// How many cache files of other builds or drivers are kept beside the current one (the most
/// recently written), so that switching between a few builds (branches, worktrees) still finds
/// each one's file.
pub const KEEP_OTHERS: usize = 8;
/// Files older than this are removed whatever their number.
pub const KEEP_DAYS: u64 = 30;

/// Whether `name` is shaped as this program names its cache files, now or before "v2":
/// `pipelines-[v2-]VENDOR-DEVICE-DRIVER-UUID-SPIRVHASH.bin`, in hex, the UUID of 32 digits and the
/// hash of 16 (so another program's `pipelines-*.bin` in a shared directory is never taken).
fn is_cache_file_name(name: &str) -> bool {
    let Some(rest) = name.strip_prefix("pipelines-").and_then(|r| r.strip_suffix(".bin")) else { return false };
    let rest = rest.strip_prefix("v2-").unwrap_or(rest);
    let parts: Vec<&str> = rest.split('-').collect();
    let hex = |p: &str| !p.is_empty() && p.bytes().all(|b| b.is_ascii_hexdigit());
    parts.len() == 5 && parts.iter().all(|p| hex(p)) && parts[3].len() == 32 && parts[4].len() == 16
}

/// The cache files beside `current` to remove: every build writes its own (the shader hash is in
/// the name), and on a GPU each holds megabytes of compiled pipelines that no later build reads.
/// Only this program's file names count ([`is_cache_file_name`], any version), never `current`
/// itself: those unmodified for [`KEEP_DAYS`], and all but the [`KEEP_OTHERS`] newest of the rest.
pub fn stale(current: &Path) -> Vec<PathBuf> {
    let Some(dir) = current.parent() else { return Vec::new() };
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let now = std::time::SystemTime::now();
    let max_age = std::time::Duration::from_secs(KEEP_DAYS * 24 * 3600);
    let mut others: Vec<(std::time::SystemTime, PathBuf)> = entries
        .flatten()
        .filter(|e| e.file_name().to_str().is_some_and(is_cache_file_name) && e.path() != current)
        // Plain files only (not a link, whose target could be anything).
        .filter_map(|e| {
            let meta = std::fs::symlink_metadata(e.path()).ok().filter(|m| m.is_file())?;
            Some((meta.modified().ok()?, e.path()))
        })
        .collect();
    // Newest first; a file "modified" in the future (a clock set back) counts as new.
    others.sort_by_key(|(modified, _)| std::cmp::Reverse(*modified));
    others
        .into_iter()
        .enumerate()
        .filter(|(i, (modified, _))| *i >= KEEP_OTHERS || now.duration_since(*modified).is_ok_and(|age| age > max_age))
        .map(|(_, (_, path))| path)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn props() -> vk::PhysicalDeviceProperties {
        vk::PhysicalDeviceProperties { vendor_id: 0x10de, device_id: 0x2330, pipeline_cache_uuid: [7; 16], ..Default::default() }
    }

    /// A driver's data with a valid header and a body of `n` bytes.
    fn driver_data(n: usize) -> Vec<u8> {
        let p = props();
        let mut d = Vec::new();
        for w in [32u32, vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32, p.vendor_id, p.device_id] {
            d.extend_from_slice(&w.to_le_bytes());
        }
        d.extend_from_slice(&p.pipeline_cache_uuid);
        d.extend((0..n).map(|i| (i * 31 % 251) as u8));
        d
    }

    /// What was saved loads back as it was; a file cut short, a flipped byte in the driver's body
    /// (its header intact, which is all the driver's header check sees) or a file of the earlier
    /// unframed format is refused before the driver could read it.
    #[test]
    fn only_whole_frames_reach_the_driver() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cache.bin");
        let data = driver_data(5000);
        save(&path, &data).unwrap();
        assert_eq!(load(&path, &props()).unwrap(), Some(data.clone()));
        let file = std::fs::read(&path).unwrap();
        std::fs::write(&path, &file[..file.len() - 100]).unwrap();
        assert!(load(&path, &props()).unwrap_err().contains("cut short"));
        let mut flipped = file.clone();
        flipped[16 + 32 + 1000] ^= 0x40;
        std::fs::write(&path, &flipped).unwrap();
        assert!(load(&path, &props()).unwrap_err().contains("checksum"));
        std::fs::write(&path, &data).unwrap();
        assert!(load(&path, &props()).unwrap_err().contains("not starting as"));
        let other = vk::PhysicalDeviceProperties { device_id: 1, ..props() };
        save(&path, &data).unwrap();
        assert!(load(&path, &other).unwrap_err().contains("another device"));
        assert_eq!(load(&dir.path().join("none.bin"), &props()).unwrap(), None);
    }

    /// Saving removes other builds' files beyond the newest [`KEEP_OTHERS`] and any older than
    /// [`KEEP_DAYS`]; it keeps its own file, other names and links.
    #[test]
    fn saving_removes_old_builds_files_only() {
        assert!(is_cache_file_name(&file_name(&props())), "{}", file_name(&props()));
        let dir = tempfile::tempdir().unwrap();
        let day = std::time::Duration::from_secs(24 * 3600);
        let now = std::time::SystemTime::now();
        let made = |name: &str, age_days: u32| {
            let path = dir.path().join(name);
            std::fs::write(&path, b"x").unwrap();
            let f = std::fs::File::options().write(true).open(&path).unwrap();
            f.set_modified(now - day * age_days).unwrap();
            path
        };
        // Ten recent files of other builds (1..10 days old), one of an earlier naming, one 40
        // days old, and files this program did not name.
        let uuid = "32352e302e372d327e62706f31322b31";
        let named = |version: &str, hash: u32| format!("pipelines-{version}10005-0000-1-{uuid}-{hash:016x}.bin");
        let recent: Vec<_> = (1..=10).map(|d| made(&named("v2-", d), d)).collect();
        let ancient = made(&named("v2-", 99), 40);
        let older_version = made(&named("", 7), 2);
        // Another program's names, however old: "pipelines-*.bin" that is not shaped as ours too.
        let foreign = [made("notes.txt", 400), made(&format!("{}.keep", named("v2-", 5)), 400), made("other.bin", 400), made("pipelines-foo.bin", 400)];
        let link = dir.path().join(named("v2-", 77));
        std::os::unix::fs::symlink(&foreign[0], &link).unwrap();
        let current = dir.path().join(named("v2-", 0xc0ffee));
        save(&current, &driver_data(10)).unwrap();
        assert!(current.exists());
        // Newest first: days 1 and 2 (two files) and 3..=7 make KEEP_OTHERS = 8; 8, 9, 10 and
        // 40 days go.
        let mut kept: Vec<_> = recent.iter().chain([&ancient, &older_version]).filter(|p| p.exists()).cloned().collect();
        kept.sort();
        let mut expect: Vec<_> = recent[..7].iter().chain([&older_version]).cloned().collect();
        expect.sort();
        assert_eq!(kept, expect);
        assert!(foreign.iter().all(|f| f.exists()) && link.exists(), "only this program's cache files are removed");
    }
}
