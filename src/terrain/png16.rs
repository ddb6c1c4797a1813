//! Greyscale PNG height maps (8 or 16 bit): height = offset + value * scale.

use super::heightfield::Heightfield;
use crate::{fileio, Error, Result};
use std::path::Path;

/// Per pixel, beyond the decoded image: raw values, samples and the height field.
const BYTES_PER_PIXEL: u64 = 24;

/// Loads a greyscale PNG; `spacing` is required (PNG has no georeference). The declared size
/// is checked against the file's length and the memory budget before decoding.
pub fn load(
    path: &Path,
    spacing: Option<[f64; 2]>,
    scale: f64,
    offset: f64,
) -> Result<Heightfield> {
    let spacing = need_spacing(path, spacing)?;
    let img = fileio::read_image(path, BYTES_PER_PIXEL)?;
    from_image(path, img, spacing, scale, offset)
}

/// [`load`] from the file's bytes; `path` names it in errors.
pub fn decode(
    bytes: &[u8],
    path: &Path,
    spacing: Option<[f64; 2]>,
    scale: f64,
    offset: f64,
) -> Result<Heightfield> {
    let spacing = need_spacing(path, spacing)?;
    let img = fileio::decode_image(bytes, path, BYTES_PER_PIXEL)?;
    from_image(path, img, spacing, scale, offset)
}

fn need_spacing(path: &Path, spacing: Option<[f64; 2]>) -> Result<[f64; 2]> {
    spacing.ok_or_else(|| {
        Error::format(
            path,
            "a PNG height map has no georeference: set terrain.cell_size = [dx, dy] (metres)",
        )
    })
}

fn from_image(
    path: &Path,
    img: image::DynamicImage,
    spacing: [f64; 2],
    scale: f64,
    offset: f64,
) -> Result<Heightfield> {
    let color = img.color();
    if color.has_color() {
        return Err(Error::format(
            path,
            format!("a height map PNG must be greyscale, this one is {color:?}"),
        ));
    }
    let (w, h) = (img.width() as usize, img.height() as usize);
    // Raw sample values: 8-bit maps are not stretched to 16 bits.
    let raw: Vec<u16> = match img {
        image::DynamicImage::ImageLuma8(g) => g.into_raw().into_iter().map(u16::from).collect(),
        image::DynamicImage::ImageLuma16(g) => g.into_raw(),
        other => {
            return Err(Error::format(
                path,
                format!(
                    "a height map PNG must be 8- or 16-bit grey without alpha, this one is {:?}",
                    other.color()
                ),
            ))
        }
    };
    let mut samples = vec![None; w * h];
    for row in 0..h {
        let j = h - 1 - row;
        for i in 0..w {
            samples[j * w + i] = Some((offset + raw[row * w + i] as f64 * scale) as f32);
        }
    }
    Heightfield::from_samples_with_voids(&path.display().to_string(), w, h, samples, spacing, None)
}
