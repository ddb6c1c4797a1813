//! SRTM `.hgt` tiles: square grids of big-endian i16 metres, rows north to south,
//! south-west corner in the file name (`N47E009.hgt`), void = -32768.

use super::heightfield::{metres_per_degree, GeoRef, Heightfield};
use crate::{Error, Result};
use std::path::Path;

/// SRTM void marker.
pub const VOID: i16 = -32768;

/// Parses `N47E009` / `s12w077` from a file stem into (lat, lon) of the south-west corner.
pub fn parse_tile_name(stem: &str) -> Option<(f64, f64)> {
    let s = stem.to_ascii_uppercase();
    let b = s.as_bytes();
    if b.len() < 7 {
        return None;
    }
    let lat_sign = match b[0] {
        b'N' => 1.0,
        b'S' => -1.0,
        _ => return None,
    };
    let lat: f64 = s.get(1..3)?.parse().ok()?;
    let lon_sign = match b[3] {
        b'E' => 1.0,
        b'W' => -1.0,
        _ => return None,
    };
    let lon: f64 = s.get(4..7)?.parse().ok()?;
    Some((lat_sign * lat, lon_sign * lon))
}

/// Loads an SRTM tile. Sizes 1201² (3″) and 3601² (1″) are accepted; the latitude for the
/// metric spacing comes from the file name.
pub fn load(path: &Path) -> Result<Heightfield> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let n = match bytes.len() {
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
    };
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    let (lat_s, lon_w) = parse_tile_name(stem).ok_or_else(|| {
        Error::format(
            path,
            "cannot read the tile's south-west corner from the file name; name it like N47E009.hgt",
        )
    })?;
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
    Heightfield::from_samples_with_voids(
        &path.display().to_string(),
        n,
        n,
        samples,
        [step * mx, step * my],
        Some(GeoRef {
            lon0: lon_w,
            lat0: lat_s,
            dlon: step,
            dlat: step,
        }),
    )
}
