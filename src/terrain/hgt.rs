//! SRTM `.hgt` tiles: square grids of big-endian i16 metres, rows north to south,
//! south-west corner in the file name (`N47E009.hgt`), void = -32768.

use super::heightfield::{metres_per_degree, GeoRef, Heightfield, SampleGrid};
use crate::{fileio, Error, Result};
use std::path::Path;

/// SRTM void marker.
pub const VOID: i16 = -32768;

/// Parses `N47E009` / `s12w077` from a file stem into (lat, lon) of the south-west corner;
/// `None` where the name is not a tile name or names an impossible tile.
pub fn parse_tile_name(stem: &str) -> Option<(f64, f64)> {
    tile_corner(stem).ok()
}

/// As [`parse_tile_name`], with the reason when the stem is not a possible tile: a tile's
/// south-west corner lies within S90..N89 and W180..E179 (it spans one degree north and east).
pub fn tile_corner(stem: &str) -> std::result::Result<(f64, f64), String> {
    let like = "name it like N47E009.hgt (latitude N/S 2 digits, longitude E/W 3 digits)";
    let bad =
        || format!("cannot read the tile's south-west corner from the file name `{stem}`: {like}");
    let s = stem.to_ascii_uppercase();
    let b = s.as_bytes();
    if b.len() < 7 {
        return Err(bad());
    }
    let lat_sign = match b[0] {
        b'N' => 1.0,
        b'S' => -1.0,
        _ => return Err(bad()),
    };
    let digits = |r: std::ops::Range<usize>| {
        s.get(r)
            .filter(|d| d.bytes().all(|c| c.is_ascii_digit()))
            .and_then(|d| d.parse::<f64>().ok())
    };
    let lat = digits(1..3).ok_or_else(bad)?;
    let lon_sign = match b[3] {
        b'E' => 1.0,
        b'W' => -1.0,
        _ => return Err(bad()),
    };
    let lon = digits(4..7).ok_or_else(bad)?;
    let (lat, lon) = (lat_sign * lat, lon_sign * lon);
    if !(-90.0..=89.0).contains(&lat) {
        return Err(format!(
            "the file name `{stem}` puts the tile's south-west corner at latitude {lat}°, \
             but a tile's corner lies within S90..N89: rename the file to its real tile"
        ));
    }
    if !(-180.0..=179.0).contains(&lon) {
        return Err(format!(
            "the file name `{stem}` puts the tile's south-west corner at longitude {lon}°, \
             but a tile's corner lies within W180..E179: rename the file to its real tile"
        ));
    }
    Ok((lat, lon))
}

/// Loads an SRTM tile. Sizes 1201² (3″) and 3601² (1″) are accepted; the latitude for the
/// metric spacing comes from the file name. The length is checked (from the file's metadata)
/// before anything is read; devices and directories are refused.
pub fn load(path: &Path) -> Result<Heightfield> {
    load_samples(path)?.into_heightfield()
}

/// [`load`] without the void filling: the tile's samples, `None` where void.
pub fn load_samples(path: &Path) -> Result<SampleGrid> {
    let len = fileio::file_len(path)?;
    let n = tile_side(path, len)?;
    let bytes = fileio::read_file(path, len)?;
    tile_side(path, bytes.len() as u64)?;
    decode_square_samples(&bytes, n, path)
}

/// Decodes the bytes of an SRTM tile; `path` names the file in errors and gives the tile's
/// south-west corner (its name).
pub fn decode(bytes: &[u8], path: &Path) -> Result<Heightfield> {
    let n = tile_side(path, bytes.len() as u64)?;
    decode_square(bytes, n, path)
}

/// The side of an SRTM tile of `len` bytes.
fn tile_side(path: &Path, len: u64) -> Result<usize> {
    Ok(match len {
        l if l == 1201 * 1201 * 2 => 1201,
        l if l == 3601 * 3601 * 2 => 3601,
        l => {
            return Err(Error::format(
                path,
                format!(
                    "{l} bytes is not an SRTM tile: expected {} (1201x1201, 3\") or {} (3601x3601, 1\") bytes; \
                     the file is truncated or not a .hgt",
                    1201 * 1201 * 2,
                    3601 * 3601 * 2
                ),
            ))
        }
    })
}

/// Decodes a square `side x side` grid of big-endian i16 in SRTM layout (any side >= 2, e.g.
/// a small test sample; [`load`] accepts only SRTM's 1201 and 3601); `path` names the file and
/// gives the south-west corner.
pub fn decode_square(bytes: &[u8], side: usize, path: &Path) -> Result<Heightfield> {
    decode_square_samples(bytes, side, path)?.into_heightfield()
}

/// [`decode_square`] without the void filling.
pub fn decode_square_samples(bytes: &[u8], side: usize, path: &Path) -> Result<SampleGrid> {
    let n = side;
    let need = (n as u64).saturating_mul(n as u64).saturating_mul(2);
    if n < 2 || bytes.len() as u64 != need {
        return Err(Error::format(
            path,
            format!(
                "{} bytes is not a {n}x{n} tile of 2-byte samples ({need} bytes); the file is truncated or not a .hgt",
                bytes.len()
            ),
        ));
    }
    // Samples, the heightfield and its void filling: about 16 bytes per sample.
    fileio::check_alloc(path.display(), need.saturating_mul(8))?;
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    let (lat_s, lon_w) = tile_corner(stem).map_err(|m| Error::format(path, m))?;
    let step = 1.0 / (n - 1) as f64;
    let (mx, my) = metres_per_degree(lat_s + 0.5);
    let mut samples = vec![None; n * n];
    for row in 0..n {
        // File rows run north to south; grid row 0 is south.
        let j = n - 1 - row;
        for i in 0..n {
            let k = 2 * (row * n + i);
            let v = i16::from_be_bytes([bytes[k], bytes[k + 1]]);
            samples[j * n + i] = (v != VOID).then_some(v as f32);
        }
    }
    Ok(SampleGrid {
        what: path.display().to_string(),
        width: n,
        height: n,
        samples,
        spacing: [step * mx, step * my],
        geo: Some(GeoRef {
            lon0: lon_w,
            lat0: lat_s,
            dlon: step,
            dlat: step,
        }),
    })
}
