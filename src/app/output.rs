//! The files relief writes: sRGB RGBA8 PNG, single-channel f32 depth TIFF, pretty-printed
//! JSON, and a frame's three of them all or nothing. Every file is written atomically
//! ([`crate::fileio::write_atomic`]: a temporary file renamed when complete, removed on any
//! error), so nothing is left half-written.

use crate::gpu::FrameOutput;
use crate::{fileio, Error, Result};
use std::path::Path;

/// Writes an sRGB RGBA8 image as PNG (atomically).
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    fileio::write_atomic(path, |f| encode_png(f, width, height, rgba))
}

/// Encodes an sRGB RGBA8 image as PNG into `f`.
fn encode_png(f: &mut fileio::AtomicFile, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    if rgba.len() as u64 != width as u64 * height as u64 * 4 {
        return Err(Error::invalid(
            "image",
            format!(
                "{} bytes do not make a {width}x{height} RGBA image",
                rgba.len()
            ),
        ));
    }
    let path = f.target().to_path_buf();
    image::write_buffer_with_format(
        f,
        rgba,
        width,
        height,
        image::ExtendedColorType::Rgba8,
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::format(path, format!("writing PNG: {e}")))
}

/// Writes a single-channel f32 TIFF (the depth image), atomically.
pub fn write_depth_tiff(path: &Path, width: u32, height: u32, depth: &[f32]) -> Result<()> {
    fileio::write_atomic(path, |f| encode_depth_tiff(f, width, height, depth))
}

fn encode_depth_tiff(
    f: &mut fileio::AtomicFile,
    width: u32,
    height: u32,
    depth: &[f32],
) -> Result<()> {
    let path = f.target().to_path_buf();
    let mut enc = tiff::encoder::TiffEncoder::new(f)
        .map_err(|e| Error::format(&path, format!("writing TIFF: {e}")))?;
    enc.write_image::<tiff::encoder::colortype::Gray32Float>(width, height, depth)
        .map_err(|e| Error::format(&path, format!("writing TIFF: {e}")))
}

/// Writes a JSON value (pretty-printed), atomically.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    fileio::write_atomic(path, |f| encode_json(f, value))
}

fn encode_json(f: &mut fileio::AtomicFile, value: &impl serde::Serialize) -> Result<()> {
    let path = f.target().to_path_buf();
    serde_json::to_writer_pretty(&mut *f, value)
        .map_err(|e| Error::format(path, format!("writing JSON: {e}")))
}

/// Writes a frame's PNG, depth TIFF and JSON all or nothing: all three are written and flushed
/// to temporary files before any is renamed into place ([`fileio::commit_all`]).
pub fn write_frame_files(
    png: &Path,
    tif: &Path,
    json: &Path,
    out: &FrameOutput,
    meta: &serde_json::Value,
) -> Result<()> {
    let mut a = fileio::AtomicFile::create(png)?;
    encode_png(&mut a, out.width, out.height, &out.rgba)?;
    let mut b = fileio::AtomicFile::create(tif)?;
    encode_depth_tiff(&mut b, out.width, out.height, &out.depth)?;
    let mut c = fileio::AtomicFile::create(json)?;
    encode_json(&mut c, meta)?;
    fileio::commit_all(vec![a, b, c])
}

/// Reads a depth TIFF written by [`write_depth_tiff`].
pub fn read_depth_tiff(path: &Path) -> Result<(u32, u32, Vec<f32>)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(file))
        .map_err(|e| Error::format(path, format!("{e}")))?;
    let (w, h) = dec
        .dimensions()
        .map_err(|e| Error::format(path, format!("{e}")))?;
    match dec
        .read_image()
        .map_err(|e| Error::format(path, format!("{e}")))?
    {
        tiff::decoder::DecodingResult::F32(v) => Ok((w, h, v)),
        _ => Err(Error::format(path, "not an f32 depth image")),
    }
}

/// The paths of frame `n`'s files in `dir`: `frame_NNNN.png`, `depth_NNNN.tiff`,
/// `frame_NNNN.json`.
pub fn frame_paths(dir: &Path, n: u64) -> [std::path::PathBuf; 3] {
    [
        dir.join(format!("frame_{n:04}.png")),
        dir.join(format!("depth_{n:04}.tiff")),
        dir.join(format!("frame_{n:04}.json")),
    ]
}
