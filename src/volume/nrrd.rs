//! NRRD reader (`NRRD0001`..`NRRD0005`): 3-D scalar volumes, raw or gzip encoding, attached or
//! detached (`data file:`) data, any scalar type, either endianness. Spacing comes from
//! `spacings` or the lengths of `space directions` (millimetres when `space` is an anatomical
//! one or `space units` says mm, else metres); `space directions` must be axis-aligned.

use super::DensityGrid;
use crate::{Error, Result};
use std::io::Read;
use std::path::Path;

/// Sample types NRRD names, with their byte size.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Kind {
    fn parse(s: &str) -> Option<Kind> {
        Some(match s {
            "signed char" | "int8" | "int8_t" => Kind::I8,
            "uchar" | "unsigned char" | "uint8" | "uint8_t" => Kind::U8,
            "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
                Kind::I16
            }
            "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => Kind::U16,
            "int" | "signed int" | "int32" | "int32_t" => Kind::I32,
            "uint" | "unsigned int" | "uint32" | "uint32_t" => Kind::U32,
            "float" => Kind::F32,
            "double" => Kind::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Kind::I8 | Kind::U8 => 1,
            Kind::I16 | Kind::U16 => 2,
            Kind::I32 | Kind::U32 | Kind::F32 => 4,
            Kind::F64 => 8,
        }
    }

    /// Value of one sample's bytes.
    fn value(self, b: &[u8], big: bool) -> f64 {
        macro_rules! get {
            ($t:ty) => {{
                let a = b.try_into().expect("sample size");
                (if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            Kind::I8 => b[0] as i8 as f64,
            Kind::U8 => b[0] as f64,
            Kind::I16 => get!(i16),
            Kind::U16 => get!(u16),
            Kind::I32 => get!(i32),
            Kind::U32 => get!(u32),
            Kind::F32 => get!(f32),
            Kind::F64 => get!(f64),
        }
    }
}

/// Sample type names accepted by [`decode_samples`] (NRRD spellings).
pub fn parse_kind(s: &str) -> bool {
    Kind::parse(s).is_some()
}

/// Decodes `count` samples of NRRD type `kind` from `bytes`; `path` names the file.
pub(crate) fn decode_samples(
    path: &Path,
    kind: &str,
    big_endian: bool,
    bytes: &[u8],
    count: usize,
) -> Result<Vec<f64>> {
    let k = Kind::parse(kind)
        .ok_or_else(|| Error::format(path, format!("unsupported sample type {kind:?}")))?;
    decode(path, k, big_endian, bytes, count)
}

fn decode(path: &Path, k: Kind, big_endian: bool, bytes: &[u8], count: usize) -> Result<Vec<f64>> {
    let kind = format!("{k:?}");
    let need = count
        .checked_mul(k.size())
        .ok_or_else(|| Error::format(path, "sample count overflows"))?;
    if bytes.len() < need {
        return Err(Error::format(
            path,
            format!(
                "data is truncated: {} bytes for {count} {kind} samples ({need} bytes needed)",
                bytes.len()
            ),
        ));
    }
    if bytes.len() > need {
        log::warn!(
            "{}: {} bytes of data after the {count} samples ignored",
            path.display(),
            bytes.len() - need
        );
    }
    Ok(bytes[..need]
        .chunks_exact(k.size())
        .map(|b| k.value(b, big_endian))
        .collect())
}

/// Parses "(a,b,c)" into three numbers.
fn vector(s: &str) -> Option<[f64; 3]> {
    let s = s.trim().strip_prefix('(')?.strip_suffix(')')?;
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse().ok())
        .collect::<Option<_>>()?;
    v.try_into().ok()
}

/// Gunzips `bytes`, refusing more than `limit` bytes of output.
pub(crate) fn gunzip(path: &Path, bytes: &[u8], limit: usize) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(bytes)
        .take(limit as u64 + 1)
        .read_to_end(&mut out)
        .map_err(|e| Error::format(path, format!("corrupt or truncated gzip stream: {e}")))?;
    if out.len() > limit {
        return Err(Error::format(
            path,
            format!("gzip stream holds more than the {limit} bytes the header declares"),
        ));
    }
    Ok(out)
}

/// Reads a 3-D NRRD volume. Values are quantised to 8 bits over `range` (data units), or
/// over the type's range for 8-bit data and the data's min..max otherwise.
pub fn load(path: &Path, range: Option<[f64; 2]>) -> Result<DensityGrid> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let fmt = |m: String| Error::format(path, m);
    let magic = bytes.get(..8).unwrap_or(&[]);
    if !(magic.starts_with(b"NRRD000") && (b'1'..=b'5').contains(&magic[7])) {
        return Err(fmt(
            "not a NRRD file (expected the magic NRRD0001..NRRD0005)".into(),
        ));
    }
    // Header: lines up to the first empty line.
    let mut pos = 0;
    let mut lines = Vec::new();
    loop {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|e| pos + e)
            .ok_or_else(|| fmt("header does not end (no empty line before the data)".into()))?;
        let line = std::str::from_utf8(&bytes[pos..end])
            .map_err(|_| fmt("header is not text".into()))?
            .trim_end_matches('\r');
        pos = end + 1;
        if line.is_empty() {
            break;
        }
        lines.push(line.to_string());
        if lines.len() > 1000 {
            return Err(fmt("header has more than 1000 lines".into()));
        }
    }
    let mut kind = None;
    let mut dimension = None;
    let mut sizes: Option<Vec<u64>> = None;
    let mut encoding = "raw".to_string();
    let mut big_endian = false;
    let mut spacings: Option<Vec<f64>> = None;
    let mut directions: Option<Vec<[f64; 3]>> = None;
    let mut space = String::new();
    let mut units_mm = false;
    let mut data_file = None;
    let mut byte_skip = 0usize;
    for line in lines.iter().skip(1) {
        if line.starts_with('#') {
            continue;
        }
        let Some((key, val)) = line.split_once(':') else {
            return Err(fmt(format!("header line {line:?} is not `field: value`")));
        };
        // `key:=value` lines are key/value pairs, not fields.
        if val.starts_with('=') {
            continue;
        }
        let val = val.trim();
        match key.trim() {
            "type" => {
                kind =
                    Some(Kind::parse(val).ok_or_else(|| fmt(format!("unsupported type {val:?}")))?)
            }
            "dimension" => dimension = val.parse::<u32>().ok(),
            "sizes" => {
                sizes = Some(
                    val.split_whitespace()
                        .map(|s| s.parse().ok())
                        .collect::<Option<_>>()
                        .ok_or_else(|| fmt(format!("sizes {val:?} are not integers")))?,
                )
            }
            "encoding" => encoding = val.to_string(),
            "endian" => big_endian = val == "big",
            "spacings" => {
                spacings = Some(
                    val.split_whitespace()
                        .map(|s| s.parse().ok())
                        .collect::<Option<_>>()
                        .ok_or_else(|| fmt(format!("spacings {val:?} are not numbers")))?,
                )
            }
            "space directions" => {
                directions = Some(
                    val.split_whitespace()
                        .map(vector)
                        .collect::<Option<_>>()
                        .ok_or_else(|| fmt(format!("space directions {val:?} are not (x,y,z)")))?,
                )
            }
            "space" => space = val.to_string(),
            "space units" => units_mm = val.contains("mm"),
            "data file" | "datafile" => data_file = Some(val.to_string()),
            "byte skip" | "byteskip" => {
                byte_skip = val.parse().map_err(|_| {
                    fmt(format!("byte skip {val:?} is not a count (-1 unsupported)"))
                })?
            }
            _ => {}
        }
    }
    let kind = kind.ok_or_else(|| fmt("header has no `type`".into()))?;
    if dimension != Some(3) {
        return Err(fmt(format!(
            "only 3-D scalar volumes are supported (dimension: {dimension:?})"
        )));
    }
    let sizes = sizes.ok_or_else(|| fmt("header has no `sizes`".into()))?;
    let sizes: [u64; 3] = sizes
        .try_into()
        .map_err(|s: Vec<u64>| fmt(format!("`sizes` has {} entries, 3 expected", s.len())))?;
    let dims = super::check_dims(&path.display().to_string(), sizes)?;
    let anatomical = space.contains("anterior")
        || space.contains("posterior")
        || space.contains("scanner")
        || space.contains("3D-");
    let to_m = if units_mm || anatomical { 1e-3 } else { 1.0 };
    let spacing: [f64; 3] = if let Some(d) = directions {
        let d: [[f64; 3]; 3] = d
            .try_into()
            .map_err(|_| fmt("`space directions` needs three vectors".into()))?;
        for (i, v) in d.iter().enumerate() {
            let off: f64 = (0..3).filter(|&k| k != i).map(|k| v[k].abs()).sum();
            if off > 1e-6 * v[i].abs().max(1e-30) {
                return Err(fmt(format!(
                    "space direction {i} {v:?} is not axis-aligned (oblique volumes are not supported; resample first)"
                )));
            }
        }
        std::array::from_fn(|i| d[i][i].abs() * to_m)
    } else if let Some(s) = spacings {
        let s: [f64; 3] = s
            .try_into()
            .map_err(|_| fmt("`spacings` needs three numbers".into()))?;
        s.map(|v| if v.is_finite() { v * to_m } else { to_m })
    } else {
        [to_m; 3]
    };
    let count = dims.iter().map(|&d| d as usize).product::<usize>();
    let need = count * kind.size();
    let payload: Vec<u8> = match &data_file {
        Some(f) => {
            let p = path.parent().unwrap_or(Path::new("")).join(f);
            std::fs::read(&p).map_err(|e| Error::io(&p, e))?
        }
        None => bytes[pos..].to_vec(),
    };
    let payload = payload.get(byte_skip..).unwrap_or(&[]);
    let raw = match encoding.as_str() {
        "raw" => payload.to_vec(),
        "gzip" | "gz" => gunzip(path, payload, need)?,
        e => {
            return Err(fmt(format!(
                "encoding {e:?} is not supported (use raw or gzip)"
            )))
        }
    };
    let values = decode(path, kind, big_endian, &raw, count)?;
    let range = range.or(match kind {
        Kind::U8 => Some([0.0, 255.0]),
        Kind::I8 => Some([-128.0, 127.0]),
        _ => None,
    });
    DensityGrid::from_values(&path.display().to_string(), dims, &values, spacing, range)
}
