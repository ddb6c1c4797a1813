//! Greyscale PNG height maps (8 or 16 bit): height = offset + value * scale.

use super::heightfield::Heightfield;
use crate::{Error, Result};
use std::path::Path;

/// Loads a greyscale PNG; `spacing` is required (PNG has no georeference).
pub fn load(
    path: &Path,
    spacing: Option<[f64; 2]>,
    scale: f64,
    offset: f64,
) -> Result<Heightfield> {
    let spacing = spacing.ok_or_else(|| {
        Error::format(
            path,
            "a PNG height map has no georeference: set terrain.cell_size = [dx, dy] (metres)",
        )
    })?;
    let img =
        image::open(path).map_err(|e| Error::format(path, format!("cannot read PNG: {e}")))?;
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
