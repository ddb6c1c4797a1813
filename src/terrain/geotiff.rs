//! TIFF / GeoTIFF rasters through the `tiff` crate (strips and tiles, LZW / Deflate /
//! PackBits / uncompressed; u8, u16, i16, u32, i32, f32, f64 samples).
//!
//! GeoTIFF tags read: ModelPixelScale (33550), ModelTiepoint (33922), GeoKeyDirectory (34735,
//! key 1024 GTModelType: 1 projected metres, 2 geographic degrees; key 1025 GTRasterType:
//! 1 PixelIsArea, the default, the tiepoint's raster point (0, 0) is the top-left pixel's
//! corner and its sample half a pixel in; 2 PixelIsPoint, raster point (0, 0) is that sample)
//! and GDAL_NODATA (42113).
//! Geographic spacing is converted to metres at the raster's centre latitude.

use super::heightfield::{metres_per_degree, GeoRef, Heightfield, SampleGrid};
use crate::{fileio, Error, Result};
use std::io::{BufReader, Read, Seek};
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;
use tiff::ColorType;

/// The georeferencing found in a TIFF's tags.
#[derive(Clone, Copy, Debug, Default)]
pub struct GeoTags {
    /// ModelPixelScale (x, y): model units per pixel (positive and finite).
    pub scale: Option<[f64; 2]>,
    /// The ModelPixelScale tag where it is not a usable scale (zero, negative, not finite or
    /// fewer than two values): refused by name rather than taken as missing.
    /// Its first two values (NaN where missing).
    pub bad_scale: Option<[f64; 2]>,
    /// Model coordinates of the sample position of pixel (0, 0) (the top-left pixel): its
    /// centre under PixelIsArea, the tiepoint's own convention under PixelIsPoint.
    pub first_sample: Option<[f64; 2]>,
    /// GTRasterTypeGeoKey (1025) is 2, RasterPixelIsPoint: raster coordinate (I, J) is the
    /// sample of pixel (I, J) itself. Otherwise (1, PixelIsArea, the default) (I, J) is the
    /// top-left corner of pixel (I, J), whose sample sits half a pixel in.
    pub pixel_is_point: bool,
    /// `Some(true)`: geographic (degrees); `Some(false)`: projected (metres); `None`: unknown.
    pub geographic: Option<bool>,
    /// GDAL_NODATA.
    pub nodata: Option<f64>,
}

/// Checks that the first image directory's entries fit in the file (`len` bytes): the `tiff`
/// crate allocates a tag's values from its declared count (up to 256 MiB) before reading
/// them. Leaves `r` at the start; anything else that is wrong is left to the decoder.
fn check_directory<R: Read + Seek>(path: &Path, r: &mut R, len: u64) -> Result<()> {
    use std::io::SeekFrom;
    let io = |e| Error::io(path, e);
    let mut head = Vec::with_capacity(16);
    r.seek(SeekFrom::Start(0)).map_err(io)?;
    r.by_ref().take(16).read_to_end(&mut head).map_err(io)?;
    let le = match head.get(..2) {
        Some(b"II") => true,
        Some(b"MM") => false,
        _ => return r.seek(SeekFrom::Start(0)).map(|_| ()).map_err(io),
    };
    let uint = |b: &[u8]| -> u64 {
        let mut a = [0u8; 8];
        if le {
            a[..b.len()].copy_from_slice(b);
            u64::from_le_bytes(a)
        } else {
            a[8 - b.len()..].copy_from_slice(b);
            u64::from_be_bytes(a)
        }
    };
    // Classic TIFF: 2-byte count, 12-byte entries, 4-byte values; BigTIFF: 8, 20, 8.
    let (ifd, count_len, value_len) = match (head.len(), head.get(2..4).map(uint)) {
        (n, Some(42)) if n >= 8 => (uint(&head[4..8]), 2usize, 4usize),
        (16, Some(43)) => (uint(&head[8..16]), 8, 8),
        _ => return r.seek(SeekFrom::Start(0)).map(|_| ()).map_err(io),
    };
    let entry_len = 4 + 2 * value_len as u64;
    let bad = |m: String| Error::format(path, format!("not a readable TIFF: {m}"));
    if ifd.saturating_add(count_len as u64) > len {
        return Err(bad(format!(
            "the image directory at byte {ifd} is past the end of the file ({len} bytes)"
        )));
    }
    r.seek(SeekFrom::Start(ifd)).map_err(io)?;
    let mut b = vec![0u8; count_len];
    r.read_exact(&mut b).map_err(io)?;
    let n = uint(&b);
    let room = (len - ifd - count_len as u64) / entry_len;
    if n > room {
        return Err(bad(format!(
            "the image directory claims {n} entries, the file has room for {room}"
        )));
    }
    let mut entry = vec![0u8; entry_len as usize];
    for _ in 0..n {
        r.read_exact(&mut entry).map_err(io)?;
        let tag = uint(&entry[..2]);
        let size: u64 = match uint(&entry[2..4]) {
            1 | 2 | 6 | 7 => 1,
            3 | 8 => 2,
            4 | 9 | 11 | 13 => 4,
            5 | 10 | 12 | 16 | 17 | 18 => 8,
            _ => continue,
        };
        let count = uint(&entry[4..4 + value_len]);
        let bytes = count.saturating_mul(size);
        if bytes > value_len as u64 {
            let offset = uint(&entry[4 + value_len..]);
            if offset.saturating_add(bytes) > len {
                return Err(bad(format!(
                    "tag {tag} claims {count} values ({bytes} bytes at byte {offset}); the file holds only {len} bytes"
                )));
            }
        }
    }
    r.seek(SeekFrom::Start(0)).map(|_| ()).map_err(io)
}

fn decoder<R: Read + Seek>(path: &Path, r: R) -> Result<Decoder<R>> {
    Decoder::new(r).map_err(|e| Error::format(path, format!("not a readable TIFF: {e}")))
}

fn read_geo_tags<R: Read + Seek>(dec: &mut Decoder<R>) -> GeoTags {
    let raw_scale = dec.get_tag_f64_vec(Tag::ModelPixelScaleTag).ok();
    let usable = |v: &Vec<f64>| v.len() >= 2 && v[..2].iter().all(|s| s.is_finite() && *s > 0.0);
    let scale = raw_scale
        .as_ref()
        .filter(|v| usable(v))
        .map(|v| [v[0], v[1]]);
    let bad_scale = raw_scale.filter(|v| !usable(v)).map(|v| {
        let at = |k: usize| v.get(k).copied().unwrap_or(f64::NAN);
        [at(0), at(1)]
    });
    let tie = dec
        .get_tag_f64_vec(Tag::ModelTiepointTag)
        .ok()
        .filter(|v| v.len() >= 6);
    let keys = dec.get_tag_u16_vec(Tag::GeoKeyDirectoryTag).ok();
    // GeoKey entries (after the 4-value header): key id, tag location (0 = value inline), count, value.
    let key = |id: u16| {
        keys.as_ref().and_then(|keys| {
            keys.chunks_exact(4)
                .skip(1)
                .find(|k| k[0] == id && k[1] == 0)
                .map(|k| k[3])
        })
    };
    let geographic = key(1024).map(|v| v == 2);
    let pixel_is_point = key(1025) == Some(2);
    // Raster coordinate of the sample of pixel (0, 0): (0.5, 0.5) under PixelIsArea, (0, 0)
    // under PixelIsPoint; the tiepoint maps raster (I, J) to model (X, Y); rows run south.
    let first_sample = match (tie, scale) {
        (Some(t), Some(s)) => {
            let c = if pixel_is_point { 0.0 } else { 0.5 };
            Some([t[3] + (c - t[0]) * s[0], t[4] - (c - t[1]) * s[1]])
        }
        _ => None,
    };
    let nodata = dec
        .get_tag_ascii_string(Tag::GdalNodata)
        .ok()
        .and_then(|s| s.trim().trim_end_matches('\0').trim().parse::<f64>().ok());
    GeoTags {
        scale,
        bad_scale,
        first_sample,
        pixel_is_point,
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

/// Bytes per pixel beyond the decoded samples: their f64 copies are counted per sample; this
/// is the caller's per-pixel output (height samples and field, or drape texels).
const BYTES_PER_PIXEL: u64 = 16;

fn read_raster(path: &Path) -> Result<Raster> {
    let (file, len) = fileio::open_regular(path)?;
    raster_from(path, BufReader::new(file), len)
}

/// Decodes a raster from `r` (`len` bytes, the whole file), checking the declared size against
/// the file's length (at the compression's best ratio) and the memory budget first.
fn raster_from<R: Read + Seek>(path: &Path, mut r: R, len: u64) -> Result<Raster> {
    check_directory(path, &mut r, len)?;
    let mut limits = tiff::decoder::Limits::default();
    let budget = usize::try_from(fileio::memory_budget()).unwrap_or(usize::MAX);
    limits.decoding_buffer_size = limits.decoding_buffer_size.min(budget);
    limits.intermediate_buffer_size = limits.intermediate_buffer_size.min(budget);
    let mut dec = decoder(path, r)?.with_limits(limits);
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
    // The declared size against the file and the budget, before the decoder allocates it.
    let samples = w as u64 * h as u64 * channels as u64;
    let declared = samples.saturating_mul(bits.max(1) as u64).div_ceil(8);
    let (ratio, codec) = match dec.find_tag_unsigned::<u16>(Tag::Compression) {
        Ok(None) | Ok(Some(1)) => (1, "uncompressed"),
        Ok(Some(32773)) => (64, "PackBits"),
        Ok(Some(8 | 32946)) => (fileio::DEFLATE_MAX_RATIO, "Deflate"),
        // Bilevel fax: a row takes at least one bit.
        Ok(Some(2..=4)) => ((w as u64).max(fileio::ANY_CODEC_MAX_RATIO), "CCITT fax"),
        _ => (fileio::ANY_CODEC_MAX_RATIO, "compressed"),
    };
    fileio::check_inflated(
        path,
        &format!("a {w}x{h} TIFF raster of {channels} {bits}-bit sample(s) per pixel, {codec}"),
        declared,
        len,
        ratio,
    )?;
    fileio::check_alloc(
        path.display(),
        declared
            .saturating_add(samples.saturating_mul(8))
            .saturating_add((w as u64 * h as u64).saturating_mul(BYTES_PER_PIXEL)),
    )?;
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
    if let Some(v) = &r.geo.bad_scale {
        return Err(Error::format(
            path,
            format!(
                "the GeoTIFF ModelPixelScale tag (33550) is {v:?}: the pixel scale must be two \
                 positive, finite model units per pixel (x, y); a zero or negative scale is not a \
                 georeference (fix the file, e.g. with gdal_edit.py -a_ullr, or strip the tag \
                 and set terrain.cell_size = [dx, dy])"
            ),
        ));
    }
    let (Some(scale), Some(first)) = (r.geo.scale, r.geo.first_sample) else {
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
        .unwrap_or(scale[0] < 0.1 && first[0].abs() <= 360.0 && first[1].abs() <= 90.0);
    // Grid sample (0, 0) is the south-west one: the last raster row's first sample.
    let geo = GeoRef {
        lon0: first[0],
        lat0: first[1] - (r.height as f64 - 1.0) * scale[1],
        dlon: scale[0],
        dlat: scale[1],
    };
    let spacing = if let Some(s) = spacing_override {
        s
    } else if geographic {
        let centre_lat = first[1] - 0.5 * (r.height as f64 - 1.0) * scale[1];
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
    heights(path, read_raster(path)?, spacing_override, nodata)?.into_heightfield()
}

/// [`load_heights`] without the void filling: the raster's samples, `None` where void or
/// no-data.
pub fn load_height_samples(path: &Path, nodata: Option<f64>) -> Result<SampleGrid> {
    heights(path, read_raster(path)?, None, nodata)
}

/// [`load_heights`] from the file's bytes; `path` names it in errors.
pub fn decode_heights(
    bytes: &[u8],
    path: &Path,
    spacing_override: Option<[f64; 2]>,
    nodata: Option<f64>,
) -> Result<Heightfield> {
    let r = raster_from(path, std::io::Cursor::new(bytes), bytes.len() as u64)?;
    heights(path, r, spacing_override, nodata)?.into_heightfield()
}

fn heights(
    path: &Path,
    r: Raster,
    spacing_override: Option<[f64; 2]>,
    nodata: Option<f64>,
) -> Result<SampleGrid> {
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
    Ok(SampleGrid {
        what: path.display().to_string(),
        width: w,
        height: h,
        samples,
        spacing,
        geo,
    })
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
        // RGBA copy, rows and the drape itself.
        let img = fileio::read_image(path, 12)?;
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
