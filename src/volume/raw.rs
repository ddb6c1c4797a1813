//! Raw volumes with a small TOML header:
//!
//! ```toml
//! file = "head.raw"        # relative to the header; `.gz` is gunzipped
//! dims = [256, 256, 128]   # voxels, x fastest
//! type = "uint16"          # int8 uint8 int16 uint16 int32 uint32 float double
//! endian = "little"        # or "big"
//! spacing = [1.0, 1.0, 2.0]
//! units = "mm"             # spacing units: "m" (default) or "mm"
//! ```

use super::nrrd::Kind;
use super::DensityGrid;
use crate::{fileio, Error, Result};
use serde::Deserialize;
use std::path::Path;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHeader {
    file: std::path::PathBuf,
    dims: [u64; 3],
    #[serde(rename = "type")]
    kind: String,
    #[serde(default = "little")]
    endian: String,
    #[serde(default = "unit_spacing")]
    spacing: [f64; 3],
    #[serde(default = "metres")]
    units: String,
}

fn little() -> String {
    "little".into()
}
fn unit_spacing() -> [f64; 3] {
    [1.0; 3]
}
fn metres() -> String {
    "m".into()
}

/// Reads the header at `path` and the raw file it names; values are quantised to 8 bits over
/// `range` (data units), the type's range for 8-bit data, else the data's min..max. The data
/// file must be a regular file; the declared size is checked against its length (at
/// deflate's best ratio for `.gz`) and the memory budget before it is read, and only the
/// declared samples are read.
pub fn load(path: &Path, range: Option<[f64; 2]>) -> Result<DensityGrid> {
    let text = fileio::read_to_string(path, fileio::MAX_CONFIG_BYTES)?;
    let h: RawHeader = toml::from_str(&text).map_err(|e| {
        Error::format(
            path,
            format!("raw volume header: {}", fileio::toml_error(&text, &e)),
        )
    })?;
    let what = path.display().to_string();
    let dims = super::check_dims(&what, h.dims)?;
    let Some(kind) = Kind::parse(&h.kind) else {
        return Err(Error::invalid(
            format!("{what}: type"),
            format!(
                "{:?} is not a sample type (int8 uint8 int16 uint16 int32 uint32 float double)",
                h.kind
            ),
        ));
    };
    let big = match h.endian.as_str() {
        "little" => false,
        "big" => true,
        e => {
            return Err(Error::invalid(
                format!("{what}: endian"),
                format!("{e:?}: use \"little\" or \"big\""),
            ))
        }
    };
    let scale = match h.units.as_str() {
        "m" => 1.0,
        "mm" => 1e-3,
        u => {
            return Err(Error::invalid(
                format!("{what}: units"),
                format!("{u:?}: use \"m\" or \"mm\""),
            ))
        }
    };
    let data_path = path.parent().unwrap_or(Path::new("")).join(&h.file);
    super::nrrd::check_grid_memory(&what, kind, dims)?;
    let (file, len) = fileio::open_regular(&data_path)?;
    let count = dims.iter().map(|&d| d as usize).product::<usize>();
    let gzip = data_path.extension().is_some_and(|e| e == "gz");
    let bytes = super::nrrd::read_samples(&data_path, file, len, 0, gzip, kind, count)?;
    let range = range.or(match kind {
        Kind::U8 => Some([0.0, 255.0]),
        Kind::I8 => Some([-128.0, 127.0]),
        _ => None,
    });
    super::nrrd::grid_from_samples(
        &what,
        &data_path,
        kind,
        big,
        &bytes,
        dims,
        h.spacing.map(|s| s * scale),
        range,
    )
}
