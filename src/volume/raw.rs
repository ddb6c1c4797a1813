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

use super::DensityGrid;
use crate::{Error, Result};
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
/// `range` (data units), the type's range for 8-bit data, else the data's min..max.
pub fn load(path: &Path, range: Option<[f64; 2]>) -> Result<DensityGrid> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let h: RawHeader = toml::from_str(&text)
        .map_err(|e| Error::format(path, format!("raw volume header: {e}")))?;
    let what = path.display().to_string();
    let dims = super::check_dims(&what, h.dims)?;
    if !super::nrrd::parse_kind(&h.kind) {
        return Err(Error::invalid(
            format!("{what}: type"),
            format!(
                "{:?} is not a sample type (int8 uint8 int16 uint16 int32 uint32 float double)",
                h.kind
            ),
        ));
    }
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
    let bytes = std::fs::read(&data_path).map_err(|e| Error::io(&data_path, e))?;
    let count = dims.iter().map(|&d| d as usize).product::<usize>();
    let bytes = if data_path.extension().is_some_and(|e| e == "gz") {
        let size = match h.kind.as_str() {
            "int8" | "uint8" => 1,
            "int16" | "uint16" => 2,
            "double" => 8,
            _ => 4,
        };
        super::nrrd::gunzip(&data_path, &bytes, count * size)?
    } else {
        bytes
    };
    let values = super::nrrd::decode_samples(&data_path, &h.kind, big, &bytes, count)?;
    let range = range.or(match h.kind.as_str() {
        "uint8" => Some([0.0, 255.0]),
        "int8" => Some([-128.0, 127.0]),
        _ => None,
    });
    DensityGrid::from_values(&what, dims, &values, h.spacing.map(|s| s * scale), range)
}
