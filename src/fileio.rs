//! Bounded reading and atomic writing: the one place where loaders check a file's declared
//! sizes before allocating and where outputs are written so that nothing half-written is left.
//!
//! * **Memory budget** ([`check_alloc`]): every loader estimates the memory a file's declared
//!   sizes will take (samples, nodes, voxels, decoded pixels) and asks before allocating. The
//!   budget is process-wide ([`set_memory_budget`], `relief --memory-budget MB`), default
//!   [`DEFAULT_MEMORY_BUDGET`].
//! * **Declared vs actual length** ([`check_declared`], [`check_inflated`]): a size field may
//!   not claim more data than the file holds (or, for compressed data, than the file's bytes can
//!   inflate to at the codec's best ratio).
//! * **Bounded reads** ([`read_file`], [`read_to_string`], [`open_regular`]): only regular
//!   files are read (not `/dev/zero`, pipes or directories), their length is checked against a
//!   limit from their metadata before reading, and the read itself stops at the limit, so a
//!   growing file cannot exhaust memory either.
//! * **Atomic writes** ([`write_atomic`], [`AtomicFile`]): output goes to a temporary file in
//!   the target's directory (`.NAME.relief-tmp-PID-N`), renamed over the target when complete
//!   and removed on every error path and, once [`install_signal_cleanup`] ran, on SIGINT and
//!   SIGTERM.

use crate::{Error, Result};
use std::fs::File;
use std::io::{BufWriter, Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// Default memory budget for what one file's loader may allocate: 8 GiB.
///
/// Large enough for every genuine input relief accepts (a 3601² SRTM tile needs about
/// 0.2 GiB while loading, the largest accepted volume (2^29 voxels) about 1 GiB, a
/// 16384² GeoTIFF or drape a few GiB), and small enough that on the 16 GiB machines relief
/// targets a file whose header lies fails with a clean error instead of having the process
/// killed by the out-of-memory killer or aborted by the allocator.
pub const DEFAULT_MEMORY_BUDGET: u64 = 8 << 30;

/// Largest text configuration file read (scene, display configuration, raw-volume header):
/// 16 MiB, far beyond any hand- or tool-written TOML.
pub const MAX_CONFIG_BYTES: u64 = 16 << 20;

/// Best compression ratio of deflate (zlib, gzip, PNG, TIFF Deflate): 258-byte matches coded
/// in as little as 2 bits give at most about 1032 output bytes per input byte.
pub const DEFLATE_MAX_RATIO: u64 = 1032;

/// A bound on the compression ratio of any codec relief reads through `tiff` or `image`
/// (TIFF LZW's 12-bit codes expand to at most a few thousand bytes each; PackBits 64:1).
pub const ANY_CODEC_MAX_RATIO: u64 = 4096;

static BUDGET: AtomicU64 = AtomicU64::new(DEFAULT_MEMORY_BUDGET);

/// Sets the process-wide memory budget in bytes (at least 1 MiB).
pub fn set_memory_budget(bytes: u64) {
    BUDGET.store(bytes.max(1 << 20), Ordering::Relaxed);
}

/// The process-wide memory budget in bytes.
pub fn memory_budget() -> u64 {
    BUDGET.load(Ordering::Relaxed)
}

/// `bytes` as a short human-readable size.
pub fn human_bytes(bytes: u64) -> String {
    const K: f64 = 1024.0;
    let b = bytes as f64;
    if b < K {
        format!("{bytes} bytes")
    } else if b < K * K {
        format!("{:.1} KiB", b / K)
    } else if b < K * K * K {
        format!("{:.1} MiB", b / (K * K))
    } else {
        format!("{:.1} GiB", b / (K * K * K))
    }
}

/// Checks that an allocation of `bytes` (an estimate of what loading `what` will take, at its
/// peak) fits the memory budget; `what` names the file or field.
pub fn check_alloc(what: impl std::fmt::Display, bytes: u64) -> Result<()> {
    let budget = memory_budget();
    if bytes <= budget {
        return Ok(());
    }
    Err(Error::Limit {
        what: what.to_string(),
        msg: format!(
            "loading it needs {} of memory, more than the memory budget of {}; \
             raise --memory-budget (MiB) if the file is genuine",
            human_bytes(bytes),
            human_bytes(budget)
        ),
    })
}

/// Checks that `what` (a size the file declares, e.g. "a 8000x8000 u16 raster"), which
/// needs `declared` bytes of data, fits in the `available` bytes the file holds.
pub fn check_declared(path: &Path, what: &str, declared: u64, available: u64) -> Result<()> {
    if declared <= available {
        return Ok(());
    }
    Err(Error::format(
        path,
        format!(
            "the file claims {what} ({declared} bytes); it holds only {available} bytes \
             (truncated, or a size field is wrong)"
        ),
    ))
}

/// Like [`check_declared`] for compressed data: `available` compressed bytes inflate to at most
/// `max_ratio` times as many.
pub fn check_inflated(
    path: &Path,
    what: &str,
    declared: u64,
    available: u64,
    max_ratio: u64,
) -> Result<()> {
    if max_ratio <= 1 {
        return check_declared(path, what, declared, available);
    }
    if declared <= available.saturating_mul(max_ratio) {
        return Ok(());
    }
    Err(Error::format(
        path,
        format!(
            "the file claims {what} ({declared} bytes); its {available} bytes of compressed data \
             cannot hold that much (at most {max_ratio}:1), so it is truncated or a size field \
             is wrong"
        ),
    ))
}

fn check_regular(path: &Path, meta: &std::fs::Metadata) -> Result<()> {
    if meta.is_dir() {
        return Err(Error::format(path, "is a directory, not a file"));
    }
    if !meta.is_file() {
        return Err(Error::format(
            path,
            "is not a regular file (a device, pipe or socket); give a file",
        ));
    }
    Ok(())
}

/// Opens a regular file for reading and returns it with its length; directories, devices
/// (`/dev/zero`), pipes and sockets are refused.
pub fn open_regular(path: &Path) -> Result<(File, u64)> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    check_regular(path, &meta)?;
    Ok((file, meta.len()))
}

/// The length of a regular file (see [`open_regular`]).
pub fn file_len(path: &Path) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    check_regular(path, &meta)?;
    Ok(meta.len())
}

fn too_long(path: &Path, len: u64, max_bytes: u64) -> Error {
    let hint = if max_bytes >= memory_budget() {
        "; raise --memory-budget (MiB) if the file is genuine"
    } else {
        ""
    };
    Error::Limit {
        what: path.display().to_string(),
        msg: format!(
            "the file is {} bytes, more than the {} read at most for this kind of file{hint}",
            len,
            human_bytes(max_bytes)
        ),
    }
}

/// Reads at most `max_bytes` bytes from `reader` into a vector, failing (naming `path`) when
/// there are more.
pub fn read_bounded(path: &Path, reader: impl Read, max_bytes: u64) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    reader
        .take(max_bytes.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| Error::io(path, e))?;
    if out.len() as u64 > max_bytes {
        return Err(too_long(path, out.len() as u64, max_bytes));
    }
    Ok(out)
}

/// Reads a whole regular file of at most `max_bytes` bytes. The length is checked from the
/// metadata before anything is read, and the read stops after `max_bytes + 1` bytes.
pub fn read_file(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    let (file, len) = open_regular(path)?;
    if len > max_bytes {
        return Err(too_long(path, len, max_bytes));
    }
    let mut out = Vec::with_capacity(len as usize);
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| Error::io(path, e))?;
    if out.len() as u64 > max_bytes {
        return Err(too_long(path, out.len() as u64, max_bytes));
    }
    Ok(out)
}

/// Text from bytes; `path` names the file when they are not UTF-8.
pub fn text_from_bytes(path: &Path, bytes: Vec<u8>) -> Result<String> {
    String::from_utf8(bytes).map_err(|e| {
        Error::format(
            path,
            format!(
                "not a text file (invalid UTF-8 at byte {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// Reads a UTF-8 text file of at most `max_bytes` bytes (see [`read_file`]).
pub fn read_to_string(path: &Path, max_bytes: u64) -> Result<String> {
    text_from_bytes(path, read_file(path, max_bytes)?)
}

/// A TOML error on one line: `line L, column C (`the line`): message` (`toml`'s own display
/// spans several lines with a source snippet).
pub fn toml_error(text: &str, e: &toml::de::Error) -> String {
    let msg = e.message().trim().replace('\n', " ");
    let Some(span) = e.span() else {
        return msg;
    };
    let at = span.start.min(text.len());
    let before = text.get(..at).unwrap_or("");
    let line = before.matches('\n').count() + 1;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[start..].chars().count() + 1;
    let src = text[start..].lines().next().unwrap_or("").trim();
    let src: String = src.chars().take(80).collect();
    if src.is_empty() {
        format!("line {line}, column {column}: {msg}")
    } else {
        format!("line {line}, column {column} (`{src}`): {msg}")
    }
}

/// Decodes an image (PNG, or TIFF through `image`) held in `bytes`; see [`read_image`].
pub fn decode_image(
    bytes: &[u8],
    path: &Path,
    extra_bytes_per_pixel: u64,
) -> Result<image::DynamicImage> {
    decode_image_from(
        std::io::Cursor::new(bytes),
        bytes,
        path,
        bytes.len() as u64,
        extra_bytes_per_pixel,
    )
}

/// Reads an image file (PNG, or TIFF through `image`) after checking its declared size: the
/// pixels must fit what the file's compressed bytes can hold and, with
/// `extra_bytes_per_pixel` for what the caller will make of each pixel, the memory budget.
pub fn read_image(path: &Path, extra_bytes_per_pixel: u64) -> Result<image::DynamicImage> {
    let (mut file, len) = open_regular(path)?;
    let mut head = Vec::with_capacity(32);
    (&mut file)
        .take(32)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(path, e))?;
    file.seek(std::io::SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
    decode_image_from(
        std::io::BufReader::new(file),
        &head,
        path,
        len,
        extra_bytes_per_pixel,
    )
}

/// The bytes of filtered scanlines a PNG's header declares (before deflate), from its first
/// 32 bytes: signature, then the IHDR chunk (width, height, bit depth, colour type, ...,
/// interlace). Decoders expand palettes and low bit depths, so this, not the decoded size, is
/// what the compressed data must hold.
fn png_raw_bytes(head: &[u8]) -> Option<u64> {
    if head.len() < 29 || &head[..8] != b"\x89PNG\r\n\x1a\n" || &head[12..16] != b"IHDR" {
        return None;
    }
    let w = u32::from_be_bytes(head[16..20].try_into().ok()?) as u64;
    let h = u32::from_be_bytes(head[20..24].try_into().ok()?) as u64;
    let depth = head[24] as u64;
    let channels = match head[25] {
        0 | 3 => 1,
        2 => 3,
        4 => 2,
        6 => 4,
        _ => return None,
    };
    // Interlaced images have a few more (shorter) rows; one filter byte per row either way.
    let row = (w * channels * depth).div_ceil(8);
    Some(h * (1 + row))
}

fn decode_image_from<R: std::io::BufRead + Seek>(
    reader: R,
    head: &[u8],
    path: &Path,
    len: u64,
    extra_bytes_per_pixel: u64,
) -> Result<image::DynamicImage> {
    use image::ImageDecoder;
    let mut reader = image::ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let Some(format) = reader.format() else {
        return Err(Error::format(
            path,
            "not an image file (neither PNG nor TIFF)",
        ));
    };
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(memory_budget());
    reader.limits(limits);
    let bad = |e: image::ImageError| Error::format(path, format!("cannot read the image: {e}"));
    let decoder = reader.into_decoder().map_err(bad)?;
    let (w, h) = decoder.dimensions();
    let total = decoder.total_bytes();
    let what = format!("a {w}x{h} {:?} image", decoder.color_type());
    match (format, png_raw_bytes(head)) {
        (image::ImageFormat::Png, Some(raw)) => {
            check_inflated(path, &what, raw, len, DEFLATE_MAX_RATIO)?
        }
        // Other codecs (and palettes, low bit depths) expand by at most 32 x another factor.
        _ => check_inflated(path, &what, total, len, ANY_CODEC_MAX_RATIO * 32)?,
    }
    check_alloc(
        path.display(),
        total.saturating_add((w as u64 * h as u64).saturating_mul(extra_bytes_per_pixel)),
    )?;
    image::DynamicImage::from_decoder(decoder).map_err(bad)
}

// ---------------------------------------------------------------------------------------------
// Atomic writes

/// Temporary files being written, removed by the signal handler.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static COUNTER: AtomicU64 = AtomicU64::new(0);

fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// An output file being written: a temporary file next to the target, renamed over the target
/// by [`AtomicFile::commit`] and removed when dropped uncommitted (every error path).
/// Writes go through a buffer; the flush at commit reports a full disk.
pub struct AtomicFile {
    target: PathBuf,
    tmp: PathBuf,
    file: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Creates the temporary file for `path`. Fails, naming `path`, when it is a directory or
    /// its directory cannot be written.
    pub fn create(path: &Path) -> Result<AtomicFile> {
        check_writable_target(path)?;
        let name = path
            .file_name()
            .ok_or_else(|| Error::format(path, "is not a file name"))?
            .to_string_lossy();
        // Keep the temporary name within NAME_MAX.
        let short: String = name.chars().take(120).collect();
        let tmp_name = format!(
            ".{short}.relief-tmp-{}-{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        );
        let tmp = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.join(tmp_name),
            _ => PathBuf::from(tmp_name),
        };
        // Registered and created under the lock, so the signal handler (which holds it until
        // the process exits) sees every temporary file that exists.
        let mut live = live();
        let file = File::create_new(&tmp).map_err(|e| Error::io(path, e))?;
        live.push(tmp.clone());
        drop(live);
        Ok(AtomicFile {
            target: path.to_path_buf(),
            tmp,
            file: Some(BufWriter::new(file)),
        })
    }

    /// The file being replaced.
    pub fn target(&self) -> &Path {
        &self.target
    }

    fn writer(&mut self) -> &mut BufWriter<File> {
        self.file.as_mut().expect("open until commit")
    }

    /// Flushes the data and renames the temporary file over the target.
    pub fn commit(mut self) -> Result<()> {
        let mut w = self.file.take().expect("open until commit");
        w.flush().map_err(|e| Error::io(&self.target, e))?;
        let file = w
            .into_inner()
            .map_err(|e| Error::io(&self.target, e.into_error()))?;
        drop(file);
        let mut live = live();
        std::fs::rename(&self.tmp, &self.target).map_err(|e| Error::io(&self.target, e))?;
        live.retain(|p| p != &self.tmp);
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        let mut live = live();
        if let Some(pos) = live.iter().position(|p| p == &self.tmp) {
            // Not committed: close and remove.
            self.file = None;
            let _ = std::fs::remove_file(&self.tmp);
            live.remove(pos);
        }
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.writer().write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.writer().flush()
    }
}

impl Seek for AtomicFile {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.writer().seek(pos)
    }
}

/// Commits several files together: all are flushed first (a full disk fails them all), then
/// renamed while the signal handler is held off, so a signal never leaves only some of them.
pub fn commit_all(mut files: Vec<AtomicFile>) -> Result<()> {
    for f in &mut files {
        f.flush().map_err(|e| Error::io(&f.target, e))?;
    }
    let mut live = live();
    for f in &mut files {
        std::fs::rename(&f.tmp, &f.target).map_err(|e| Error::io(&f.target, e))?;
        live.retain(|p| p != &f.tmp);
    }
    Ok(())
}

/// Fails, naming `path`, when it is an existing directory (or not a file name).
pub fn check_writable_target(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::format(
            path,
            "is a directory; cannot write the output file there",
        ));
    }
    if path.file_name().is_none() {
        return Err(Error::format(path, "is not a file name"));
    }
    Ok(())
}

/// Writes `path` atomically: `write` fills an [`AtomicFile`] (Write + Seek), which is renamed
/// over `path` when `write` succeeds and removed when anything fails.
pub fn write_atomic<T>(path: &Path, write: impl FnOnce(&mut AtomicFile) -> Result<T>) -> Result<T> {
    let mut f = AtomicFile::create(path)?;
    let out = write(&mut f)?;
    f.commit()?;
    Ok(out)
}

/// Writes `bytes` to `path` atomically (see [`write_atomic`]).
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |f| f.write_all(bytes).map_err(|e| Error::io(path, e)))
}

/// Installs SIGINT and SIGTERM handlers (once; Unix only) that remove the temporary files of
/// writes in progress and exit with status 130 (SIGINT) or 143 (SIGTERM). A signal that was
/// ignored when the process started stays ignored.
pub fn install_signal_cleanup() {
    #[cfg(unix)]
    signals::install();
}

#[cfg(unix)]
mod signals {
    use std::sync::atomic::{AtomicI32, Ordering};

    static WRITE_FD: AtomicI32 = AtomicI32::new(-1);

    extern "C" fn on_signal(sig: libc::c_int) {
        // Async-signal-safe: one write(2) to the pipe the cleanup thread waits on.
        let fd = WRITE_FD.load(Ordering::Relaxed);
        if fd >= 0 {
            let b = sig as u8;
            unsafe {
                libc::write(fd, &b as *const u8 as *const libc::c_void, 1);
            }
        }
    }

    fn cleanup_and_exit(sig: i32) -> ! {
        // Held until the process ends: no temporary file is created or renamed after this.
        let live = super::live();
        let mut removed = 0;
        for p in live.iter() {
            if std::fs::remove_file(p).is_ok() {
                removed += 1;
            }
        }
        let name = if sig == libc::SIGINT {
            "SIGINT"
        } else {
            "SIGTERM"
        };
        let msg = if removed > 0 {
            format!("relief: {name}: removed {removed} unfinished output file(s)\n")
        } else {
            format!("relief: {name}\n")
        };
        unsafe {
            libc::write(2, msg.as_ptr() as *const libc::c_void, msg.len());
            // _exit: no atexit handlers or destructors while other threads (GPU drivers) run.
            libc::_exit(128 + sig)
        }
    }

    pub(super) fn install() {
        static ONCE: std::sync::Once = std::sync::Once::new();
        ONCE.call_once(|| unsafe {
            let mut fds = [0 as libc::c_int; 2];
            if libc::pipe(fds.as_mut_ptr()) != 0 {
                log::warn!("cannot install the signal handlers: pipe failed");
                return;
            }
            for fd in fds {
                libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC);
            }
            WRITE_FD.store(fds[1], Ordering::Relaxed);
            let read_fd = fds[0];
            let spawned = std::thread::Builder::new()
                .name("relief-signals".into())
                .spawn(move || loop {
                    let mut b = 0u8;
                    let n = libc::read(read_fd, &mut b as *mut u8 as *mut libc::c_void, 1);
                    if n == 1 {
                        cleanup_and_exit(b as i32);
                    }
                    if n == 0 {
                        return;
                    }
                });
            if spawned.is_err() {
                log::warn!("cannot install the signal handlers: no thread");
                return;
            }
            for sig in [libc::SIGINT, libc::SIGTERM] {
                let mut old: libc::sigaction = std::mem::zeroed();
                if libc::sigaction(sig, std::ptr::null(), &mut old) == 0
                    && old.sa_sigaction == libc::SIG_IGN
                {
                    continue;
                }
                let mut sa: libc::sigaction = std::mem::zeroed();
                sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
                sa.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut sa.sa_mask);
                libc::sigaction(sig, &sa, std::ptr::null_mut());
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("relief-fileio-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn entries(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn write_atomic_renames_on_success_and_removes_on_error() {
        let d = dir("atomic");
        let p = d.join("out.bin");
        write_file_atomic(&p, b"hello").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"hello");
        let e = write_atomic(&p, |f| {
            f.write_all(b"partial").unwrap();
            Err::<(), _>(Error::invalid("test", "fails half-way"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("fails half-way"));
        assert_eq!(std::fs::read(&p).unwrap(), b"hello", "target untouched");
        assert_eq!(entries(&d), vec!["out.bin"], "no temporary file left");
        // Panics unwind through the drop guard too.
        let r = std::panic::catch_unwind(|| {
            write_atomic::<()>(&p, |f| {
                f.write_all(b"x").unwrap();
                panic!("writer panics")
            })
        });
        assert!(r.is_err());
        assert_eq!(entries(&d), vec!["out.bin"]);
        assert!(live().is_empty() || !live().iter().any(|t| t.starts_with(&d)));
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn write_atomic_refuses_a_directory_target_before_writing() {
        let d = dir("atomic-dir");
        let target = d.join("frame_0000.png");
        std::fs::create_dir(&target).unwrap();
        let e = write_file_atomic(&target, b"x").unwrap_err().to_string();
        assert!(
            e.contains("frame_0000.png") && e.contains("directory"),
            "{e}"
        );
        assert_eq!(entries(&d), vec!["frame_0000.png"]);
        let e = write_file_atomic(&d.join("missing/x.bin"), b"x")
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing/x.bin"), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn read_file_checks_kind_and_length_first() {
        let d = dir("read");
        let p = d.join("a.txt");
        std::fs::write(&p, b"0123456789").unwrap();
        assert_eq!(read_file(&p, 10).unwrap().len(), 10);
        let e = read_file(&p, 9).unwrap_err().to_string();
        assert!(e.contains("a.txt") && e.contains("10 bytes"), "{e}");
        let e = read_file(&d, 100).unwrap_err().to_string();
        assert!(e.contains("directory"), "{e}");
        #[cfg(unix)]
        {
            let e = read_file(Path::new("/dev/zero"), 100)
                .unwrap_err()
                .to_string();
            assert!(e.contains("/dev/zero") && e.contains("regular"), "{e}");
        }
        std::fs::write(&p, b"ok\xff\xfe").unwrap();
        let e = read_to_string(&p, 100).unwrap_err().to_string();
        assert!(
            e.contains("not a text file (invalid UTF-8 at byte 2)"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&d);
    }

    /// A 1-bit PNG compresses beyond deflate's ratio relative to its decoded (8-bit) size; the
    /// check uses the scanline bytes its header declares, so it loads.
    #[test]
    fn low_bit_depth_png_is_not_refused_by_the_ratio_check() {
        fn chunk(out: &mut Vec<u8>, ty: &[u8; 4], data: &[u8]) {
            out.extend((data.len() as u32).to_be_bytes());
            out.extend(ty);
            out.extend(data);
            let mut crc = flate2::Crc::new();
            crc.update(ty);
            crc.update(data);
            out.extend(crc.sum().to_be_bytes());
        }
        let (w, h) = (2048u32, 2048u32);
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut ihdr = w.to_be_bytes().to_vec();
        ihdr.extend(h.to_be_bytes());
        ihdr.extend([1, 0, 0, 0, 0]);
        chunk(&mut png, b"IHDR", &ihdr);
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
        for _ in 0..h {
            z.write_all(&[0u8; 1 + 2048 / 8]).unwrap();
        }
        chunk(&mut png, b"IDAT", &z.finish().unwrap());
        chunk(&mut png, b"IEND", &[]);
        assert!((w * h) as usize / png.len() > DEFLATE_MAX_RATIO as usize);
        let img = decode_image(&png, Path::new("bits.png"), 0).unwrap();
        assert_eq!((img.width(), img.height()), (w, h));
    }

    #[test]
    fn size_checks_name_the_file_and_the_fix() {
        let e = check_declared(
            Path::new("x.tif"),
            "a 8000x8000 u16 raster",
            128_000_000,
            100,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("x.tif") && e.contains("holds only 100 bytes"),
            "{e}"
        );
        let e = check_inflated(Path::new("x.png"), "pixels", 1 << 30, 1000, 1032)
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.png") && e.contains("1032:1"), "{e}");
        let e = check_alloc("x.vox", u64::MAX).unwrap_err().to_string();
        assert!(e.contains("x.vox") && e.contains("--memory-budget"), "{e}");
        assert!(check_alloc("x", 1 << 20).is_ok());
    }
}
