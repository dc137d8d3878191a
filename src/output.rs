//! Image and summary outputs: float32 RGB EXR (row 0 at the top), sRGB PNG, summary.json.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};

/// Writes `args` to stdout (what [`outln!`](crate::outln) and [`out!`](crate::out) print). A
/// closed stdout (`| head -1`) ends the process quietly with the status a death by SIGPIPE gives
/// (141): `println!` panicked there (Rust ignores SIGPIPE, so the write fails with EPIPE), and
/// restoring SIGPIPE's default would also kill the process on any other broken pipe, an output
/// FIFO's, with no message and its temporary files left behind.
pub fn stdout_write(args: std::fmt::Arguments) {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(141);
        }
        crate::errln!("error: writing to stdout: {e}");
        std::process::exit(1);
    }
}

/// Writes `args` to stderr (what [`errln!`](crate::errln) and [`err!`](crate::err) print), or
/// nothing when stderr is closed or full: `eprintln!` panicked there (`2>/dev/full`, a pipe whose
/// reader left), turning a warning or an error's message into a panic and exit status 101.
pub fn stderr_write(args: std::fmt::Arguments) {
    use std::io::Write as _;
    let mut err = std::io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|()| err.flush());
}

/// `eprintln!` through [`stderr_write`].
#[macro_export]
macro_rules! errln {
    () => {
        $crate::output::stderr_write(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::output::stderr_write(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `eprint!` through [`stderr_write`].
#[macro_export]
macro_rules! err {
    ($($arg:tt)*) => {
        $crate::output::stderr_write(format_args!($($arg)*))
    };
}

/// `println!` through [`stdout_write`].
#[macro_export]
macro_rules! outln {
    () => {
        $crate::output::stdout_write(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::output::stdout_write(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` through [`stdout_write`].
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::output::stdout_write(format_args!($($arg)*))
    };
}

/// Writes `path` through `write`, which is handed a hidden sibling (`.NAME.PID.N.partial`, N counting
/// the writes of this process, so that threads writing one file at once, as the contexts of a test
/// binary saving the pipeline cache, each have their own) to fill;
/// the sibling then replaces `path` by a rename. A reader polling the output (a script, the window
/// test pressing Enter again and again, another run sharing the pipeline cache) sees the old file or
/// the new one, never a half-written one.
///
/// A symbolic link is followed (the file it points to is replaced, the link stays), and a device
/// or a pipe (`/dev/null`) is written in place: the rename replaced the link or the device node
/// itself with a regular file.
pub fn write_replacing(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    stage(path, write)?.commit()
}

/// A file written as [`write_replacing`] writes it, up to the rename: [`Self::commit`] puts it in
/// place; dropped uncommitted, its partial file is removed. Files that belong together (a run's
/// images and summary) are all staged before any is committed, so that a write that fails (a full
/// disk) leaves the earlier set whole instead of a mix of two runs. A device or a pipe has no
/// partial file: it is written when staged.
#[must_use = "a staged file is removed unless committed"]
pub struct Staged {
    /// The partial file and its target; None once committed (or for a device, written in place).
    partial: Option<(PathBuf, PathBuf)>,
    /// The path as the caller named it, for messages.
    named: PathBuf,
}

impl Staged {
    /// Renames the partial file over its target.
    pub fn commit(mut self) -> Result<()> {
        if let Some((partial, target)) = self.partial.take() {
            let renamed = std::fs::rename(&partial, &target).with_context(|| format!("renaming {} to {}", partial.display(), target.display()));
            if renamed.is_err() {
                let _ = std::fs::remove_file(&partial);
            }
            renamed.with_context(|| format!("writing {}", self.named.display()))?;
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if let Some((partial, _)) = self.partial.take() {
            let _ = std::fs::remove_file(partial);
        }
    }
}

/// Writes `path`'s new content beside it, to be put in place by [`Staged::commit`].
pub fn stage(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<Staged> {
    let named = path.to_path_buf();
    let resolved = follow_links(path);
    match std::fs::metadata(&resolved) {
        Ok(m) if m.is_dir() => anyhow::bail!("writing {}: it is a directory", path.display()),
        Ok(m) if !m.is_file() => {
            write_in_place(&resolved, write).with_context(|| format!("writing {}", path.display()))?;
            return Ok(Staged { partial: None, named });
        }
        _ => {}
    }
    let path = resolved.as_path();
    let name = path.file_name().with_context(|| format!("{} names no file", path.display()))?;
    remove_stale_partials(path);
    let mut partial_name = std::ffi::OsString::from(".");
    partial_name.push(name);
    static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    partial_name.push(format!(".{}.{n}.partial", std::process::id()));
    let partial: PathBuf = path.with_file_name(partial_name);
    // Owned from here, so that a failed write's partial file is removed.
    let staged = Staged { partial: Some((partial.clone(), path.to_path_buf())), named };
    write(&partial).with_context(|| format!("writing {}", staged.named.display()))?;
    Ok(staged)
}

/// How old a partial file of a process that `/proc` does not show must be before it is taken as
/// left behind: a staged file lives from its write to its rename, seconds at most, so an hour
/// leaves room for a process `/proc` cannot see (another PID namespace sharing the directory, a
/// `hidepid` mount, another host on a network file system), whose file must not go.
const STALE_PARTIAL_AGE: std::time::Duration = std::time::Duration::from_secs(3600);

/// Removes, once per directory per process, the partial files (`.NAME.PID.N.partial`, as
/// [`stage`] names them) that a run killed while it wrote (SIGKILL, a power cut) left in the
/// directory of `path`: it could not remove its own, and they stayed beside the outputs for good.
/// One is removed when `/proc` (Linux; elsewhere none is) shows no process of its PID and it was
/// last written over [`STALE_PARTIAL_AGE`] ago. Best effort: a file that cannot be read or removed
/// is left.
fn remove_stale_partials(path: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    static CLEANED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    {
        let mut cleaned = CLEANED.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if cleaned.contains(&dir) {
            return;
        }
        cleaned.push(dir.clone());
    }
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return;
    };
    let decimal = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    for entry in entries.flatten() {
        let file = entry.file_name();
        // .NAME.PID.N.partial: PID and N decimal, NAME not empty.
        let Some(rest) = file.to_str().and_then(|f| f.strip_prefix('.')).and_then(|r| r.strip_suffix(".partial")) else {
            continue;
        };
        let mut parts = rest.rsplitn(3, '.');
        let (Some(n), Some(pid), Some(name)) = (parts.next(), parts.next(), parts.next()) else {
            continue;
        };
        if name.is_empty() || !decimal(pid) || !decimal(n) || Path::new("/proc").join(pid).exists() {
            continue;
        }
        let old = entry.metadata().and_then(|m| m.modified()).ok().and_then(|t| t.elapsed().ok()).is_some_and(|age| age >= STALE_PARTIAL_AGE);
        if old && entry.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// A device or a pipe written in place: the bytes are made in a temporary file first and then
/// copied in, because a writer that fails removes its output (the exr crate does), and a device
/// node removed that way (`/dev/full` when the write fails) is gone for every program.
fn write_in_place(target: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    use std::io::Write as _;
    static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    // A directory of our own (create_dir fails if the name exists, so nothing planted in a shared
    // /tmp is followed), private on Unix; the file inside it keeps the target's name.
    let dir = std::env::temp_dir().join(format!(".restir-vpl-{}-{n}", std::process::id()));
    let mut builder = std::fs::DirBuilder::new();
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder.create(&dir).with_context(|| format!("creating the temporary directory {}", dir.display()))?;
    let tmp = dir.join(target.file_name().unwrap_or(std::ffi::OsStr::new("output")));
    let copied = write(&tmp).and_then(|()| {
        let mut from = std::fs::File::open(&tmp).with_context(|| format!("reading back {}", tmp.display()))?;
        let mut out = std::fs::OpenOptions::new().write(true).open(target)?;
        std::io::copy(&mut from, &mut out)?;
        out.flush()?;
        Ok(())
    });
    let _ = std::fs::remove_dir_all(&dir);
    copied
}

/// `path` with symbolic links followed (also a link to a file not written yet); `path` itself when
/// it is no link.
fn follow_links(path: &Path) -> PathBuf {
    let mut p = path.to_path_buf();
    // A bounded walk: a loop of links ends here and fails when written.
    for _ in 0..40 {
        match std::fs::read_link(&p) {
            Ok(target) => p = p.parent().map_or(target.clone(), |d| d.join(&target)),
            Err(_) => return p,
        }
    }
    p
}

/// Reads an input file whole (a scene, one of its buffers or images, a camera path). Anything but a
/// regular file or a pipe is refused: `/dev/zero` as a scene would otherwise be read until the
/// out-of-memory killer ends the process, with no message.
pub fn read_input(path: &Path) -> Result<Vec<u8>> {
    read_file(path, true, None)
}

/// Reads a file a scene names (a buffer or an image): a regular file only (a pipe there, which
/// the scene file itself may be, blocked the load for ever), at most `at_most` bytes of it where
/// given (a buffer's byteLength: a 3 GB file behind a 48-byte buffer was read whole).
pub fn read_referenced(path: &Path, at_most: Option<u64>) -> Result<Vec<u8>> {
    read_file(path, false, at_most)
}

/// [`read_input`] and [`read_referenced`]: a directory or a device is refused (a pipe where
/// `pipe_ok`), then up to `at_most` bytes are read.
fn read_file(path: &Path, pipe_ok: bool, at_most: Option<u64>) -> Result<Vec<u8>> {
    let meta = std::fs::metadata(path).with_context(|| format!("cannot read '{}'", path.display()))?;
    #[cfg(unix)]
    let pipe = std::os::unix::fs::FileTypeExt::is_fifo(&meta.file_type());
    #[cfg(not(unix))]
    let pipe = false;
    anyhow::ensure!(!meta.is_dir(), "cannot read '{}': it is a directory", path.display());
    anyhow::ensure!(meta.is_file() || (pipe_ok && pipe), "cannot read '{}': not a regular file", path.display());
    let file = std::fs::File::open(path).with_context(|| format!("cannot read '{}'", path.display()))?;
    let limit = at_most.unwrap_or(u64::MAX);
    let mut data = Vec::with_capacity(meta.len().min(limit) as usize);
    std::io::Read::read_to_end(&mut std::io::Read::take(file, limit), &mut data)
        .with_context(|| format!("cannot read '{}'", path.display()))?;
    Ok(data)
}

/// Whether `path` is the directory `dir` or lies inside it (at any depth), both resolved as
/// [`same_file`] resolves them, so also when neither exists yet.
pub fn is_within(path: &Path, dir: &Path) -> bool {
    matches!((resolve_path(path), resolve_path(dir)), (Some(p), Some(d)) if p.starts_with(&d))
}

/// `p` with its deepest existing ancestor canonicalized and the rest applied as written, `..`
/// going up from what is resolved so far (the part that does not exist yet holds no symlinks, so
/// that is where `..` leads). None for an empty path.
fn resolve_path(p: &Path) -> Option<PathBuf> {
    if p.as_os_str().is_empty() {
        return None;
    }
    let components: Vec<std::path::Component> = p.components().collect();
    // The longest prefix that exists (a relative path's empty prefix is the working directory).
    for k in (0..=components.len()).rev() {
        let prefix: PathBuf = if k == 0 { PathBuf::from(".") } else { components[..k].iter().collect() };
        if let Ok(mut at) = prefix.canonicalize() {
            for c in &components[k..] {
                match c {
                    std::path::Component::CurDir => {}
                    std::path::Component::ParentDir => {
                        at.pop();
                    }
                    other => at.push(other),
                }
            }
            return Some(at);
        }
    }
    None
}

/// Whether `a` and `b` name the same file, also when either does not exist yet (its deepest
/// existing directory is then resolved, [`resolve_path`]): how an output is kept from overwriting
/// an input.
pub fn same_file(a: &Path, b: &Path) -> bool {
    // Two names of one file that resolve differently: hard links, bind mounts.
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            if x.dev() == y.dev() && x.ino() == y.ino() {
                return true;
            }
        }
    }
    matches!((resolve_path(a), resolve_path(b)), (Some(x), Some(y)) if x == y)
}

/// Creates the output directory `dir` of `flag` before a long run writes into it (a file there,
/// or a directory that cannot be made, was found only when the run ended).
pub fn prepare_output_dir(flag: &str, dir: &Path) -> Result<()> {
    // (A device such as /dev/null, or a file, said "cannot create the directory: File exists".)
    let what = if dir.is_file() { "is a file (it exists and is not a directory)" } else { "exists and is not a directory" };
    anyhow::ensure!(!dir.exists() || dir.is_dir(), "{flag} {}: {what}; name a directory (it is created if missing)", dir.display());
    std::fs::create_dir_all(dir).with_context(|| format!("{flag} {}: cannot create the directory", dir.display()))
}

/// Creates `path`'s directory and checks that it takes the file ([`check_writable`]): called
/// before a long render whose result goes to `path`.
pub fn prepare_output_file(path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    check_writable(path)
}

/// Checks that `path` can be written the way [`write_replacing`] will: its directory exists and
/// takes a new file (created and removed again here), and `path` is not a directory.
pub fn check_writable(path: &Path) -> Result<()> {
    // "d/" would pass the probe below (made beside "d", in the working directory) and fail at the
    // rename, after the render.
    let bytes = path.as_os_str().as_encoded_bytes();
    anyhow::ensure!(
        !bytes.ends_with(std::path::MAIN_SEPARATOR_STR.as_bytes()),
        "{} ends in a path separator, so it names a directory; name a file",
        path.display()
    );
    // ("d/." and "d/.." do not end in a separator and name no file either; components() drops
    // a trailing ".", so the bytes are looked at.)
    let dot = [std::path::MAIN_SEPARATOR as u8, b'.'];
    anyhow::ensure!(
        bytes != b"." && !bytes.ends_with(&dot) && matches!(path.components().next_back(), Some(std::path::Component::Normal(_))),
        "{} names no file (it ends in `.` or `..`); name a file",
        path.display()
    );
    // (Not "name a file": `--out DIR` names no file, and its final.exr can be a directory too.)
    anyhow::ensure!(!path.is_dir(), "{} is a directory where a file is to be written; move it away, or write elsewhere", path.display());
    // Checked where write_replacing writes: through a symbolic link (a dangling one included).
    let named = path;
    let linked = follow_links(path);
    let path = linked.as_path();
    let link_note = if path != named { format!(" (where the link {} leads)", named.display()) } else { String::new() };
    // A device or pipe (/dev/null, /dev/stdout) is written in place, with no file beside it: no
    // probe in /dev (not opened either: a pipe with no reader would block here).
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return Ok(());
    }
    let probe = {
        let name = path.file_name().with_context(|| format!("{} names no file", path.display()))?;
        let mut n = std::ffi::OsString::from(".");
        n.push(name);
        n.push(format!(".{}.probe", std::process::id()));
        path.with_file_name(n)
    };
    std::fs::File::create(&probe).with_context(|| format!("cannot create a file beside {}{link_note}", path.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Image file extensions a reader would take for a format (lowercase).
const IMAGE_EXTENSIONS: [&str; 9] = ["exr", "png", "jpg", "jpeg", "tif", "tiff", "hdr", "bmp", "webp"];

/// Refuses an output named for another image format than the one `flag` writes (`reference --out
/// a.png` wrote an OpenEXR file named a.png, `compare --error-image e.exr` a PNG): `format` is the
/// lowercase extension written. Any other name (none, `.tmp`, upper case) is left as given.
pub fn check_image_extension(flag: &str, path: &Path, format: &str) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    let what = if format == "exr" { "an OpenEXR image" } else { "a PNG image" };
    anyhow::ensure!(
        ext == format || !IMAGE_EXTENSIONS.contains(&ext.as_str()),
        "{flag} {}: writes {what}, which a .{ext} name would mislabel; name it *.{format}",
        path.display()
    );
    Ok(())
}

/// An RGBA8 image (row-major, row 0 at the top) encoded as PNG bytes.
pub fn encode_png(width: u32, height: u32, rgba: &[u8]) -> Result<Vec<u8>> {
    let mut png = Vec::new();
    image::ImageEncoder::write_image(image::codecs::png::PngEncoder::new(&mut png), rgba, width, height, image::ExtendedColorType::Rgba8)?;
    Ok(png)
}

/// Writes a float32 RGB OpenEXR file; `pixels` are row-major with row 0 at the top.
pub fn write_exr(path: &Path, width: u32, height: u32, pixels: &[[f32; 3]]) -> Result<()> {
    stage_exr(path, width, height, pixels)?.commit()
}

/// [`write_exr`] up to the rename ([`stage`]).
pub fn stage_exr(path: &Path, width: u32, height: u32, pixels: &[[f32; 3]]) -> Result<Staged> {
    anyhow::ensure!(pixels.len() == (width * height) as usize, "image size mismatch writing {}", path.display());
    stage(path, |partial| {
        exr::prelude::write_rgb_file(partial, width as usize, height as usize, |x, y| {
            let p = pixels[y * width as usize + x];
            (p[0], p[1], p[2])
        })
        .map_err(exr_error)
    })
}

/// An `exr` error as one message: its I/O variant prints the OS error and also hands it on as the
/// source, so a `{:#}` chain printed "No such file or directory (os error 2)" twice.
pub fn exr_error(e: exr::error::Error) -> anyhow::Error {
    match e {
        // What the crate makes of an unexpected end of file.
        exr::error::Error::Invalid(m) if m == "reference to missing bytes" => {
            anyhow::anyhow!("the file ends early (truncated? the EXR reader: {m})")
        }
        e => anyhow::anyhow!("{e}"),
    }
}

/// An RGB float image read from disk.
#[derive(Clone, Debug)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

/// The first four bytes of every OpenEXR file (20000630 as a little-endian u32).
const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Whether `path` is a regular file that starts with OpenEXR's magic number.
pub fn is_exr_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file()) && first_four_bytes(path).is_ok_and(|m| m == EXR_MAGIC)
}

/// The first four bytes of a file (where EXR_MAGIC is).
fn first_four_bytes(path: &Path) -> std::io::Result<[u8; 4]> {
    let mut magic = [0u8; 4];
    std::io::Read::read_exact(&mut std::fs::File::open(path)?, &mut magic)?;
    Ok(magic)
}

/// Reads the first RGB(A) layer of an EXR file as float32, row 0 at the top.
pub fn read_exr(path: &Path) -> Result<RgbImage> {
    Ok(read_exr_with_attribute(path, "")?.0)
}

/// [`read_exr`], plus the header attribute `attribute` (looked up in the layer's header, then the
/// image's) when the file has it. The one EXR reader of the crate.
pub fn read_exr_with_attribute(path: &Path, attribute: &str) -> Result<(RgbImage, Option<exr::meta::attribute::AttributeValue>)> {
    use exr::meta::attribute::Text;
    use exr::prelude::*;
    // The file is opened more than once (magic, header, pixels): a pipe (`<(cat a.exr)`) lost its
    // first bytes to the first read ("file identifier missing"), and a FIFO blocked.
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        anyhow::bail!("reading {}: not a regular file (a pipe or a device): EXR images are read from files", path.display());
    }
    // Another kind of file (a PNG, a scene) gets a plain answer, not the parser's "file identifier
    // missing".
    match first_four_bytes(path) {
        Ok(magic) if magic != EXR_MAGIC => {
            anyhow::bail!("reading {}: not an OpenEXR file (it does not start with EXR's magic number)", path.display())
        }
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            let len = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
            anyhow::bail!("reading {}: not an OpenEXR file ({len} bytes, shorter than EXR's magic number)", path.display())
        }
        // Unreadable: the parser below names the I/O error.
        _ => {}
    }
    // The header first: a file that claims a huge image (a corrupt or hostile header) must be an
    // error here, not an allocation of its claimed size before any pixel is read.
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(exr_error).with_context(|| format!("reading {}", path.display()))?;
    let side = crate::settings::MAX_IMAGE_SIDE as usize;
    if let Some(h) = meta.headers.iter().find(|h| h.layer_size.width() > side || h.layer_size.height() > side) {
        anyhow::bail!(
            "reading {}: its header claims a {}×{} image, larger than the {side}×{side} this program renders",
            path.display(),
            h.layer_size.width(),
            h.layer_size.height()
        );
    }
    // Exactly "R", "G", "B", as the reader below matches them (a file with r, g, b passed a
    // case-blind check here, then failed there with the crate's generic message).
    let has = |h: &exr::meta::header::Header, name: &str| h.channels.list.iter().any(|c| c.name.to_string() == name);
    if !meta.headers.iter().any(|h| ["R", "G", "B"].iter().all(|n| has(h, n))) {
        let found: Vec<String> = meta.headers.iter().flat_map(|h| h.channels.list.iter().map(|c| c.name.to_string())).collect();
        anyhow::bail!("reading {}: no layer has R, G and B channels, named so in capitals (found: {})", path.display(), found.join(", "));
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| RgbImage {
            width: resolution.width() as u32,
            height: resolution.height() as u32,
            pixels: vec![[0.0; 3]; resolution.width() * resolution.height()],
        },
        |img: &mut RgbImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.pixels[pos.y() * w + pos.x()] = [r, g, b];
        },
    )
    .map_err(exr_error)
    .with_context(|| format!("reading {}", path.display()))?;
    let value = if attribute.is_empty() {
        None
    } else {
        let key = Text::from(attribute);
        image.layer_data.attributes.other.get(&key).or_else(|| image.attributes.other.get(&key)).cloned()
    };
    Ok((image.layer_data.channel_data.pixels, value))
}

/// Writes `text` to `path` as [`write_replacing`] does (whole, or the earlier file left); errors
/// name the file.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    write_replacing(path, |partial| Ok(std::fs::write(partial, text)?))
}

/// Writes an RGBA8 buffer as PNG.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    stage_png(path, width, height, rgba)?.commit()
}

/// [`write_png`] up to the rename ([`stage`]).
pub fn stage_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<Staged> {
    stage(path, |partial| {
        // Encoded in memory and written with fs::write: image's save_buffer writes through a
        // BufWriter that it never flushes, so a full disk gave an empty file and no error.
        std::fs::write(partial, encode_png(width, height, rgba)?)?;
        Ok(())
    })
}

/// Median, min, max and mean of a list of timings.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TimingStats {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub mean: f64,
    pub count: usize,
}

impl TimingStats {
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
        Self { median, min: v[0], max: v[n - 1], mean: v.iter().sum::<f64>() / n as f64, count: n }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symbolic link named as an output keeps pointing where it did: the file it points to gets
    /// the image (a dangling link's target is created), and a device behind a link is written in
    /// place. The rename replaced the link (or, named directly, `/dev/null` itself) with a regular
    /// file.
    #[cfg(unix)]
    #[test]
    fn outputs_follow_links_and_write_devices_in_place() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target.png");
        let link = dir.path().join("link.png");
        std::os::unix::fs::symlink("target.png", &link).unwrap();
        write_replacing(&link, |p| Ok(std::fs::write(p, b"one")?)).unwrap();
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read(&target).unwrap(), b"one");
        write_replacing(&link, |p| Ok(std::fs::write(p, b"two")?)).unwrap();
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read(&target).unwrap(), b"two");
        let null = dir.path().join("null.png");
        std::os::unix::fs::symlink("/dev/null", &null).unwrap();
        write_replacing(&null, |p| Ok(std::fs::write(p, b"gone")?)).unwrap();
        assert!(std::fs::symlink_metadata(&null).unwrap().file_type().is_symlink());
        assert!(!std::fs::metadata("/dev/null").unwrap().is_file(), "/dev/null is still a device");
        let e = format!("{:#}", write_replacing(dir.path(), |p| Ok(std::fs::write(p, b"x")?)).unwrap_err());
        assert!(e.contains("directory"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3, "no partial file left behind");
    }

    /// A device is never handed to the writer itself: a writer that removes its output when it
    /// fails (the exr crate's) removed the device node, `/dev/full` included. And a failed write
    /// to a device is an error: a PNG written to `/dev/full` said nothing (image's unflushed
    /// BufWriter) and left an empty file on a full disk.
    #[cfg(unix)]
    #[test]
    fn devices_are_written_through_a_copy_and_their_errors_reported() {
        let dir = tempfile::tempdir().unwrap();
        let null = dir.path().join("out.exr");
        std::os::unix::fs::symlink("/dev/null", &null).unwrap();
        let mut given = PathBuf::new();
        let e = write_replacing(&null, |p| {
            // (A writer that removes its output on failure is what hurt; this one does not, so
            // that a regression cannot remove /dev/null: the path it was given is checked.)
            given = p.to_path_buf();
            std::fs::write(p, b"half")?;
            anyhow::bail!("the writer failed")
        })
        .unwrap_err();
        assert!(format!("{e:#}").contains("the writer failed"), "{e:#}");
        assert!(!given.starts_with("/dev") && given != null, "the writer was given {}", given.display());
        assert!(std::fs::metadata("/dev/null").is_ok_and(|m| !m.is_file()), "/dev/null is still a device");
        if Path::new("/dev/full").exists() {
            let e = write_png(Path::new("/dev/full"), 2, 2, &[7; 16]).unwrap_err();
            assert!(format!("{e:#}").contains("/dev/full"), "{e:#}");
        }
    }

    /// A hard link of an input is the input: an output written there would overwrite it (the
    /// canonical paths differ, so only the inode tells).
    #[cfg(unix)]
    #[test]
    fn a_hard_link_is_the_same_file() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, c) = (dir.path().join("scene.gltf"), dir.path().join("link.gltf"), dir.path().join("other.gltf"));
        std::fs::write(&a, b"{}").unwrap();
        std::fs::hard_link(&a, &b).unwrap();
        std::fs::write(&c, b"{}").unwrap();
        assert!(same_file(&a, &b) && same_file(&b, &a));
        assert!(!same_file(&a, &c));
    }

    /// Paths not there yet resolve from their deepest existing ancestor, `..` going up from what
    /// is resolved: through a symlink it leads where the link points, and a `..` in the missing part
    /// is taken as written.
    #[cfg(unix)]
    #[test]
    fn paths_not_there_yet_resolve_through_symlinks_and_dot_dot() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("out/passes/sub")).unwrap();
        std::fs::create_dir_all(d.join("x")).unwrap();
        std::os::unix::fs::symlink(d.join("out/passes/sub"), d.join("x/lnk")).unwrap();
        // x/lnk/.. is out/passes, not x.
        assert!(same_file(&d.join("x/lnk/../v.ply"), &d.join("out/passes/v.ply")));
        assert!(!same_file(&d.join("x/lnk/../v.ply"), &d.join("x/v.ply")));
        // `..` in a part that does not exist.
        assert!(same_file(&d.join("out/none/../passes/v.ply"), &d.join("out/passes/v.ply")));
        assert!(is_within(&d.join("out/none/../passes/v.ply"), &d.join("out/passes")));
        assert!(is_within(&d.join("out/passes"), &d.join("out/passes")), "the folder itself");
        assert!(!is_within(&d.join("out/passes/../v.ply"), &d.join("out/passes")), "out/v.ply is not inside");
        assert!(is_within(&d.join("x/lnk/new/v.ply"), &d.join("out/passes")), "inside through the link");
    }

    /// An EXR whose header claims a huge image is refused from its header, before an allocation of
    /// the claimed size (which aborted the process: "memory allocation of 120000000000 bytes").
    #[test]
    fn an_exr_header_claiming_a_huge_image_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("huge.exr");
        write_exr(&path, 4, 4, &[[0.5; 3]; 16]).unwrap();
        assert_eq!(read_exr(&path).unwrap().pixels.len(), 16);
        let mut bytes = std::fs::read(&path).unwrap();
        for name in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
            let at = bytes.windows(name.len()).position(|w| w == name).expect("the attribute is in the header") + name.len();
            // size (i32), then xmin, ymin, xmax, ymax
            for corner in [at + 12, at + 16] {
                bytes[corner..corner + 4].copy_from_slice(&99_999i32.to_le_bytes());
            }
        }
        std::fs::write(&path, bytes).unwrap();
        let err = format!("{:#}", read_exr(&path).unwrap_err());
        assert!(err.contains("100000×100000") && err.contains("huge.exr"), "{err}");
    }

    /// A file of another kind, or too short to hold EXR's magic number (empty included), is "not an
    /// OpenEXR file"; an EXR cut short after its magic number is the parser's error, naming the file.
    #[test]
    fn another_kind_of_file_is_not_an_exr() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("final.png");
        write_png(&png, 2, 2, &[7; 16]).unwrap();
        let err = format!("{:#}", read_exr(&png).unwrap_err());
        assert!(err.contains("final.png") && err.contains("not an OpenEXR file"), "{err}");
        for len in [0, 3] {
            let short = dir.path().join(format!("short{len}.exr"));
            std::fs::write(&short, &EXR_MAGIC[..len]).unwrap();
            let err = format!("{:#}", read_exr(&short).unwrap_err());
            assert!(err.contains(&format!("short{len}.exr")) && err.contains("not an OpenEXR file") && err.contains(&format!("{len} bytes")), "{err}");
        }
        let cut = dir.path().join("cut.exr");
        std::fs::write(&cut, EXR_MAGIC).unwrap();
        let err = format!("{:#}", read_exr(&cut).unwrap_err());
        assert!(err.contains("cut.exr") && !err.contains("not an OpenEXR"), "{err}");
        // A whole image cut short is said to end early (the crate says "reference to missing bytes").
        let whole = dir.path().join("whole.exr");
        write_exr(&whole, 4, 4, &[[0.5; 3]; 16]).unwrap();
        let bytes = std::fs::read(&whole).unwrap();
        let truncated = dir.path().join("truncated.exr");
        std::fs::write(&truncated, &bytes[..bytes.len() - 8]).unwrap();
        let err = format!("{:#}", read_exr(&truncated).unwrap_err());
        assert!(err.contains("truncated.exr") && err.contains("ends early"), "{err}");
    }

    /// An EXR without R, G and B channels is an error that says so and lists what it has (the exr
    /// crate's own message named no channel).
    #[test]
    fn an_exr_without_rgb_channels_names_its_channels() {
        use exr::prelude::*;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("depth.exr");
        let channels = SpecificChannels::build().with_channel("Z").with_pixel_fn(|_: Vec2<usize>| (1.0f32,));
        Image::from_channels((2, 2), channels).write().to_file(&path).unwrap();
        let err = format!("{:#}", read_exr(&path).unwrap_err());
        assert!(err.contains("depth.exr") && err.contains("R, G and B") && err.contains("found: Z"), "{err}");
        // Lower-case names are not the reader's: said here too, not by the crate's message.
        let lower = dir.path().join("lower.exr");
        let channels = SpecificChannels::build().with_channel("r").with_channel("g").with_channel("b").with_pixel_fn(|_: Vec2<usize>| (1.0f32, 1.0f32, 1.0f32));
        Image::from_channels((2, 2), channels).write().to_file(&lower).unwrap();
        let err = format!("{:#}", read_exr(&lower).unwrap_err());
        assert!(err.contains("lower.exr") && err.contains("in capitals") && err.contains("found: b, g, r"), "{err}");
    }

    /// A pipe or a device is refused by name: the reader opens the file three times, and a pipe
    /// lost its first bytes to the first ("file identifier missing" on a valid image).
    #[cfg(unix)]
    #[test]
    fn an_exr_that_is_not_a_regular_file_is_refused() {
        let err = format!("{:#}", read_exr(Path::new("/dev/null")).unwrap_err());
        assert!(err.contains("/dev/null") && err.contains("not a regular file"), "{err}");
    }

    /// A reader polling the file while it is rewritten sees only whole versions (the window test
    /// once read an empty summary.json that `std::fs::write` had just truncated).
    #[test]
    fn a_polling_reader_never_sees_a_partial_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("summary.json");
        let versions: Vec<String> = (0..2).map(|v| format!("{v}").repeat(1 << 20)).collect();
        write_replacing(&path, |p| Ok(std::fs::write(p, &versions[0])?)).unwrap();
        let stop = std::sync::atomic::AtomicBool::new(false);
        std::thread::scope(|s| {
            let reader = s.spawn(|| {
                let mut reads = 0;
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    let text = std::fs::read_to_string(&path).unwrap();
                    assert!(versions.contains(&text), "read {} bytes that are neither version", text.len());
                    reads += 1;
                }
                reads
            });
            for i in 0..200 {
                write_replacing(&path, |p| Ok(std::fs::write(p, &versions[i % 2])?)).unwrap();
            }
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
            assert!(reader.join().unwrap() > 0);
        });
        // A failed write keeps the old file and leaves no partial sibling behind.
        let before = std::fs::read_to_string(&path).unwrap();
        let err = write_replacing(&path, |p| {
            std::fs::write(p, "half")?;
            anyhow::bail!("encoder failed")
        })
        .unwrap_err();
        assert!(format!("{err:#}").contains("summary.json") && format!("{err:#}").contains("encoder failed"), "{err:#}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), before);
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("summary.json")]);
    }

    #[test]
    fn a_dead_process_partial_files_are_removed_at_the_next_write() {
        if !Path::new("/proc/self").exists() {
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("final.exr");
        let file = |name: &str, age_s: u64| {
            let p = dir.path().join(name);
            let f = std::fs::File::create(&p).unwrap();
            f.set_modified(std::time::SystemTime::now() - std::time::Duration::from_secs(age_s)).unwrap();
            p
        };
        // No process has PID 999999999 (Linux's pid_max is at most 2^22); this one runs.
        let hour = STALE_PARTIAL_AGE.as_secs();
        let dead = file(".final.exr.999999999.0.partial", hour + 60);
        let dead_other_output = file(".accum_0003.exr.999999999.12.partial", hour + 60);
        // Not shown by /proc but written a minute ago: perhaps a process /proc cannot see.
        let recent = file(".final.exr.999999998.0.partial", 60);
        let alive = file(&format!(".final.exr.{}.777.partial", std::process::id()), hour + 60);
        let not_ours = file(".final.exr.999999999.partial", hour + 60);
        let not_ours_either = file("final.exr.999999999.0.partial", hour + 60);
        write_replacing(&target, |p| Ok(std::fs::write(p, b"new")?)).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        for gone in [&dead, &dead_other_output] {
            assert!(!gone.exists(), "{} stays", gone.display());
        }
        for kept in [&recent, &alive, &not_ours, &not_ours_either] {
            assert!(kept.exists(), "{} was removed", kept.display());
        }
        // Once per directory: a second write there lists it no more.
        let later = file(".final.exr.999999999.1.partial", hour + 60);
        write_replacing(&target, |p| Ok(std::fs::write(p, b"newer")?)).unwrap();
        assert!(later.exists());
    }

    /// A path ending in a separator names a directory, refused before the render (it passed the
    /// probe, made beside "d" in the working directory, and failed at the rename after the frames);
    /// a link is checked where it leads, so a dangling one into a missing directory fails here.
    #[cfg(unix)]
    #[test]
    fn check_writable_refuses_directory_names_and_follows_links() {
        let dir = tempfile::tempdir().unwrap();
        let slash = PathBuf::from(format!("{}/d/", dir.path().display()));
        let e = format!("{:#}", check_writable(&slash).unwrap_err());
        assert!(e.contains("/d/") && e.contains("names a directory"), "{e}");
        for odd in ["d/.", "d/.."] {
            let e = format!("{:#}", check_writable(&dir.path().join(odd)).unwrap_err());
            assert!(e.contains("names no file"), "{odd}: {e}");
        }
        let link = dir.path().join("final.exr");
        std::os::unix::fs::symlink("/nonexistent-restir-vpl-dir/final.exr", &link).unwrap();
        let e = format!("{:#}", check_writable(&link).unwrap_err());
        assert!(e.contains("/nonexistent-restir-vpl-dir/final.exr") && e.contains("where the link"), "{e}");
        check_writable(&dir.path().join("new.exr")).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "the probe is removed; only the link is there");
    }

    /// Files staged together: until every one is committed the old ones stay whole, and a staged
    /// file dropped (a later one failed) leaves no partial file.
    #[test]
    fn staged_files_replace_nothing_until_committed() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("final.exr"), dir.path().join("summary.json"));
        std::fs::write(&a, "old a").unwrap();
        std::fs::write(&b, "old b").unwrap();
        let staged = stage(&a, |p| Ok(std::fs::write(p, "new a")?)).unwrap();
        let failed = stage(&b, |p| {
            std::fs::write(p, "half")?;
            anyhow::bail!("disk full")
        });
        assert!(failed.is_err());
        drop(staged);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "old b");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2, "no partial file left");
        let (x, y) = (stage(&a, |p| Ok(std::fs::write(p, "new a")?)).unwrap(), stage(&b, |p| Ok(std::fs::write(p, "new b")?)).unwrap());
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a", "staged, not yet in place");
        x.commit().unwrap();
        y.commit().unwrap();
        assert_eq!((std::fs::read_to_string(&a).unwrap(), std::fs::read_to_string(&b).unwrap()), ("new a".into(), "new b".into()));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    /// Threads replacing one file at once (the contexts of one test binary saving the pipeline
    /// cache as they are dropped): every write succeeds and the file is one of them whole. With one
    /// partial file per process they wrote into each other's and all but one rename failed.
    #[test]
    fn concurrent_replacements_of_one_file_do_not_mix() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shared.bin");
        let contents: Vec<Vec<u8>> = (0..8u8).map(|t| vec![t; 1 << 20]).collect();
        std::thread::scope(|s| {
            for c in &contents {
                let path = &path;
                s.spawn(move || {
                    for _ in 0..4 {
                        super::write_replacing(path, |p| Ok(std::fs::write(p, c)?)).expect("every write succeeds");
                    }
                });
            }
        });
        let written = std::fs::read(&path).unwrap();
        assert!(contents.contains(&written), "the file mixes writes ({} bytes)", written.len());
        let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().filter_map(Result::ok).map(|e| e.file_name()).collect();
        assert_eq!(leftovers.len(), 1, "partial files left: {leftovers:?}");
    }
}
