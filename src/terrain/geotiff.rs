//! TIFF / GeoTIFF rasters through the `tiff` crate (strips and tiles, LZW / Deflate /
//! PackBits / uncompressed; u8, u16, i16, u32, i32, f32, f64 samples).
//!
//! GeoTIFF tags read: ModelPixelScale (33550), ModelTiepoint (33922), GeoKeyDirectory (34735,
//! key 1024 GTModelType: 1 projected metres, 2 geographic degrees) and GDAL_NODATA (42113).
//! Geographic spacing is converted to metres at the raster's centre latitude.

use super::heightfield::{metres_per_degree, GeoRef, Heightfield};
use crate::{Error, Result};
use std::io::{BufReader, Read, Seek};
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;
use tiff::ColorType;

/// The georeferencing found in a TIFF's tags.
#[derive(Clone, Copy, Debug, Default)]
pub struct GeoTags {
    /// ModelPixelScale (x, y): model units per pixel.
    pub scale: Option<[f64; 2]>,
    /// Model coordinates of the raster's top-left corner (pixel-is-area convention).
    pub top_left: Option<[f64; 2]>,
    /// `Some(true)`: geographic (degrees); `Some(false)`: projected (metres); `None`: unknown.
    pub geographic: Option<bool>,
    /// GDAL_NODATA.
    pub nodata: Option<f64>,
}

fn decoder<R: Read + Seek>(path: &Path, r: R) -> Result<Decoder<R>> {
    Decoder::new(r).map_err(|e| Error::format(path, format!("not a readable TIFF: {e}")))
}

fn read_geo_tags<R: Read + Seek>(dec: &mut Decoder<R>) -> GeoTags {
    let scale = dec
        .get_tag_f64_vec(Tag::ModelPixelScaleTag)
        .ok()
        .filter(|v| {
            v.len() >= 2 && v[0] > 0.0 && v[1] > 0.0 && v[0].is_finite() && v[1].is_finite()
        })
        .map(|v| [v[0], v[1]]);
    let tie = dec
        .get_tag_f64_vec(Tag::ModelTiepointTag)
        .ok()
        .filter(|v| v.len() >= 6);
    let top_left = match (tie, scale) {
        (Some(t), Some(s)) => Some([t[3] - t[0] * s[0], t[4] + t[1] * s[1]]),
        _ => None,
    };
    let geographic = dec
        .get_tag_u16_vec(Tag::GeoKeyDirectoryTag)
        .ok()
        .and_then(|keys| {
            keys.chunks_exact(4)
                .skip(1)
                .find(|k| k[0] == 1024)
                .map(|k| k[3] == 2)
        });
    let nodata = dec
        .get_tag_ascii_string(Tag::GdalNodata)
        .ok()
        .and_then(|s| s.trim().trim_end_matches('\0').trim().parse::<f64>().ok());
    GeoTags {
        scale,
        top_left,
        geographic,
        nodata,
    }
}

/// Decoded raster: one channel as f64 or several as u8-scaled.
struct Raster {
    width: usize,
    height: usize,
    channels: usize,
    /// `width * height * channels` values, rows north to south as stored.
    values: Vec<f64>,
    bits: u8,
    /// Samples were f32: no-data values are compared at f32 precision.
    f32_samples: bool,
    geo: GeoTags,
}

fn read_raster(path: &Path) -> Result<Raster> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut dec = decoder(path, BufReader::new(file))?;
    let (w, h) = dec
        .dimensions()
        .map_err(|e| Error::format(path, format!("bad TIFF header: {e}")))?;
    let colour = dec
        .colortype()
        .map_err(|e| Error::format(path, format!("unsupported TIFF colour type: {e}")))?;
    let (channels, bits) = match colour {
        ColorType::Gray(b) => (1, b),
        ColorType::GrayA(b) => (2, b),
        ColorType::RGB(b) => (3, b),
        ColorType::RGBA(b) => (4, b),
        other => {
            return Err(Error::format(
                path,
                format!("unsupported TIFF colour type {other:?}: expected grey (heights) or RGB/RGBA (drape)"),
            ))
        }
    };
    let geo = read_geo_tags(&mut dec);
    let data = dec.read_image().map_err(|e| {
        Error::format(path, format!("cannot decode the TIFF image data (corrupt or unsupported compression/sample format): {e}"))
    })?;
    let f32_samples = matches!(data, DecodingResult::F32(_));
    let values: Vec<f64> =
        match data {
            DecodingResult::U8(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::U16(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::I16(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::U32(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::I32(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::F64(v) => v,
            DecodingResult::I8(v) => v.into_iter().map(f64::from).collect(),
            _ => return Err(Error::format(
                path,
                "unsupported TIFF sample format: use u8, u16, i16, u32, i32, f32 or f64 samples",
            )),
        };
    let (width, height) = (w as usize, h as usize);
    if values.len() != width * height * channels {
        return Err(Error::format(
            path,
            format!(
                "decoded {} values, expected {width}x{height}x{channels}",
                values.len()
            ),
        ));
    }
    Ok(Raster {
        width,
        height,
        channels,
        values,
        bits,
        f32_samples,
        geo,
    })
}

/// Georeference of a raster: GeoRef of the south-west pixel centre plus metric spacing.
fn georef(
    path: &Path,
    r: &Raster,
    spacing_override: Option<[f64; 2]>,
) -> Result<([f64; 2], Option<GeoRef>)> {
    let (Some(scale), Some(tl)) = (r.geo.scale, r.geo.top_left) else {
        return match spacing_override {
            Some(s) => Ok((s, None)),
            None => Err(Error::format(
                path,
                "no GeoTIFF ModelPixelScale/ModelTiepoint tags: set terrain.cell_size = [dx, dy] (metres) in the scene",
            )),
        };
    };
    // Geographic when the GeoKey says so, or (no keys) when the numbers only make sense as degrees.
    let geographic = r
        .geo
        .geographic
        .unwrap_or(scale[0] < 0.1 && tl[0].abs() <= 360.0 && tl[1].abs() <= 90.0);
    let geo = GeoRef {
        lon0: tl[0] + 0.5 * scale[0],
        lat0: tl[1] - (r.height as f64 - 0.5) * scale[1],
        dlon: scale[0],
        dlat: scale[1],
    };
    let spacing = if let Some(s) = spacing_override {
        s
    } else if geographic {
        let centre_lat = tl[1] - 0.5 * r.height as f64 * scale[1];
        let (mx, my) = metres_per_degree(centre_lat);
        [scale[0] * mx, scale[1] * my]
    } else {
        scale
    };
    Ok((spacing, geographic.then_some(geo)))
}

/// Loads a single-channel (GeoTIFF) height raster. `nodata` overrides GDAL_NODATA.
pub fn load_heights(
    path: &Path,
    spacing_override: Option<[f64; 2]>,
    nodata: Option<f64>,
) -> Result<Heightfield> {
    let r = read_raster(path)?;
    if r.channels != 1 {
        return Err(Error::format(
            path,
            format!(
                "a height raster needs one sample per pixel, this one has {}",
                r.channels
            ),
        ));
    }
    let (spacing, geo) = georef(path, &r, spacing_override)?;
    // An f32 raster stores its no-data value rounded to f32 (GDAL_NODATA "-9999.9" is -9999.900390625).
    let nodata = nodata
        .or(r.geo.nodata)
        .map(|nd| if r.f32_samples { nd as f32 as f64 } else { nd });
    let (w, h) = (r.width, r.height);
    let mut samples = vec![None; w * h];
    for row in 0..h {
        let j = h - 1 - row;
        for i in 0..w {
            let v = r.values[row * w + i];
            let void = !v.is_finite() || nodata.is_some_and(|nd| v == nd) || v.abs() > 1.0e6;
            samples[j * w + i] = (!void).then_some(v as f32);
        }
    }
    Heightfield::from_samples_with_voids(&path.display().to_string(), w, h, samples, spacing, geo)
}

/// An RGB image draped over the terrain.
#[derive(Clone, Debug)]
pub struct Drape {
    pub width: usize,
    pub height: usize,
    /// RGBA8 (sRGB) texels, row 0 = south, like the height grid.
    pub rgba: Vec<u8>,
    /// Georeference of texel centres, where the file has one.
    pub geo: Option<GeoRef>,
}

/// Loads an RGB(A) TIFF or PNG as a drape image.
pub fn load_drape(path: &Path) -> Result<Drape> {
    let is_tiff = matches!(
        path.extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref(),
        Some("tif" | "tiff")
    );
    let (w, h, rows_north_first, geo): (usize, usize, Vec<[u8; 4]>, Option<GeoRef>) = if is_tiff {
        let r = read_raster(path)?;
        if r.channels < 3 {
            return Err(Error::format(path, "a drape image must be RGB or RGBA"));
        }
        let (_, geo) = georef(path, &r, Some([1.0, 1.0]))?;
        let max = if r.bits > 8 {
            ((1u32 << r.bits.min(16)) - 1) as f64
        } else {
            255.0
        };
        let px = r
            .values
            .chunks_exact(r.channels)
            .map(|c| {
                let q = |v: f64| (v / max * 255.0).round().clamp(0.0, 255.0) as u8;
                [q(c[0]), q(c[1]), q(c[2]), 255]
            })
            .collect();
        (r.width, r.height, px, geo)
    } else {
        let img = image::open(path)
            .map_err(|e| Error::format(path, format!("cannot read drape image: {e}")))?;
        let img = img.to_rgba8();
        let (w, h) = (img.width() as usize, img.height() as usize);
        (w, h, img.pixels().map(|p| p.0).collect(), None)
    };
    let mut rgba = vec![0u8; w * h * 4];
    for row in 0..h {
        let j = h - 1 - row;
        for i in 0..w {
            rgba[(j * w + i) * 4..][..4].copy_from_slice(&rows_north_first[row * w + i]);
        }
    }
    Ok(Drape {
        width: w,
        height: h,
        rgba,
        geo,
    })
}
