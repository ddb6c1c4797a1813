//! NRRD reader (`NRRD0001`..`NRRD0005`): 3-D scalar volumes, raw or gzip encoding, attached or
//! detached (`data file:`) data, any scalar type, either endianness. Spacing comes from
//! `spacings` or the lengths of `space directions` (millimetres when `space` is an anatomical
//! one or `space units` says mm, else metres); `space directions` must be axis-aligned.
//!
//! Hostile files: the header is read first (at most [`MAX_HEADER_BYTES`]); the declared sizes
//! are checked against the memory budget and against the data the file holds (raw: its length;
//! gzip: its length at deflate's best ratio) before the samples are read, and gzip data is
//! inflated through a bound of the declared size. Only the declared samples are read from a
//! (detached) data file, which must be a regular file. Samples are quantised straight from the
//! bytes, without an f64 copy.

use super::DensityGrid;
use crate::{fileio, Error, Result};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Longest header read (the 1000 lines it may have, at generous line lengths).
pub const MAX_HEADER_BYTES: u64 = 1 << 20;

/// Sample types NRRD names, with their byte size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Kind {
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
    pub(crate) fn parse(s: &str) -> Option<Kind> {
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

/// Parses "(a,b,c)" into three numbers.
fn vector(s: &str) -> Option<[f64; 3]> {
    let s = s.trim().strip_prefix('(')?.strip_suffix(')')?;
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse().ok())
        .collect::<Option<_>>()?;
    v.try_into().ok()
}

/// Reads `count` samples of `k` (raw or gzip-encoded) from `r`, which holds `len` bytes of
/// which the first `skip` are skipped; `path` names the data in errors. The declared size is
/// checked against `len` before anything is read; gzip data is inflated through a bound.
pub(crate) fn read_samples(
    path: &Path,
    mut r: impl Read,
    len: u64,
    skip: u64,
    gzip: bool,
    k: Kind,
    count: usize,
) -> Result<Vec<u8>> {
    let need = (count as u64).saturating_mul(k.size() as u64);
    let truncated = |have: u64| {
        Error::format(
            path,
            format!(
                "data is truncated: {have} bytes for {count} {k:?} samples ({need} bytes needed)"
            ),
        )
    };
    if skip > len {
        return Err(Error::format(
            path,
            format!("data is truncated: byte skip {skip} is past its {len} bytes"),
        ));
    }
    std::io::copy(&mut r.by_ref().take(skip), &mut std::io::sink())
        .map_err(|e| Error::io(path, e))?;
    let avail = len - skip;
    if !gzip {
        if avail < need {
            return Err(truncated(avail));
        }
        if avail > need {
            log::warn!(
                "{}: {} bytes of data after the {count} samples ignored",
                path.display(),
                avail - need
            );
        }
        let mut out = vec![0u8; need as usize];
        r.read_exact(&mut out).map_err(|e| Error::io(path, e))?;
        return Ok(out);
    }
    fileio::check_inflated(
        path,
        &format!("{count} {k:?} samples"),
        need,
        avail,
        fileio::DEFLATE_MAX_RATIO,
    )?;
    let out = gunzip(path, r.take(avail), need)?;
    if (out.len() as u64) < need {
        return Err(truncated(out.len() as u64));
    }
    Ok(out)
}

/// Gunzips `r`, refusing more than `limit` bytes of output (inflated through a bound, so a
/// gzip bomb stops there).
pub(crate) fn gunzip(path: &Path, r: impl Read, limit: u64) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(std::io::BufReader::new(r))
        .take(limit.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| Error::format(path, format!("corrupt or truncated gzip stream: {e}")))?;
    if out.len() as u64 > limit {
        return Err(Error::format(
            path,
            format!("gzip stream holds more than the {limit} bytes the header declares"),
        ));
    }
    Ok(out)
}

/// Quantises the samples in `bytes` (x fastest) to 8 bits over `range`, or over the data's
/// own min..max when `range` is `None` ([`DensityGrid::from_samples`]), without an f64 copy.
/// Non-finite values are refused; `what` names the volume, `path` the data.
#[allow(clippy::too_many_arguments)]
pub(crate) fn grid_from_samples(
    what: &str,
    path: &Path,
    k: Kind,
    big_endian: bool,
    bytes: &[u8],
    dims: [u32; 3],
    spacing: [f64; 3],
    range: Option<[f64; 2]>,
) -> Result<DensityGrid> {
    let count = dims.iter().map(|&d| d as usize).product::<usize>();
    let need = count * k.size();
    if bytes.len() < need {
        return Err(Error::format(
            path,
            format!(
                "data is truncated: {} bytes for {count} {k:?} samples ({need} bytes needed)",
                bytes.len()
            ),
        ));
    }
    let samples = || {
        bytes[..need]
            .chunks_exact(k.size())
            .map(|b| k.value(b, big_endian))
    };
    DensityGrid::from_samples(what, dims, samples, spacing, range)
}

/// Checks the memory a `dims` grid of `k` samples takes while loading (the samples and the
/// quantised grid); `what` names the volume.
pub(crate) fn check_grid_memory(what: &str, k: Kind, dims: [u32; 3]) -> Result<()> {
    let count: u64 = dims.iter().map(|&d| d as u64).product();
    fileio::check_alloc(
        format!("{what} ({}x{}x{} {k:?} samples)", dims[0], dims[1], dims[2]),
        count.saturating_mul(k.size() as u64 + 1),
    )
}

/// Reads a 3-D NRRD volume. Values are quantised to 8 bits over `range` (data units), or
/// over the type's range for 8-bit data and the data's min..max otherwise.
pub fn load(path: &Path, range: Option<[f64; 2]>) -> Result<DensityGrid> {
    let (mut file, len) = fileio::open_regular(path)?;
    let mut head = Vec::new();
    (&mut file)
        .take(MAX_HEADER_BYTES)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(path, e))?;
    let h = header(path, &head)?;
    file.seek(SeekFrom::Start(h.len))
        .map_err(|e| Error::io(path, e))?;
    finish(path, h, file, len, range)
}

/// [`load`] from the file's bytes; `path` names the file and anchors a detached data file.
pub fn decode(bytes: &[u8], path: &Path, range: Option<[f64; 2]>) -> Result<DensityGrid> {
    let h = header(path, bytes)?;
    let rest = &bytes[h.len as usize..];
    finish(path, h, rest, bytes.len() as u64, range)
}

/// A parsed header.
struct Header {
    /// Its length in bytes, up to and including the empty line.
    len: u64,
    kind: Kind,
    dims: [u32; 3],
    spacing: [f64; 3],
    gzip: bool,
    big_endian: bool,
    data_file: Option<String>,
    byte_skip: u64,
}

/// Reads the samples (attached after the header in `attached`, or from the data file) and
/// quantises them.
fn finish(
    path: &Path,
    h: Header,
    attached: impl Read,
    file_len: u64,
    range: Option<[f64; 2]>,
) -> Result<DensityGrid> {
    let what = path.display().to_string();
    check_grid_memory(&what, h.kind, h.dims)?;
    let count = h.dims.iter().map(|&d| d as usize).product::<usize>();
    let (data_path, raw): (PathBuf, Vec<u8>) = match &h.data_file {
        Some(f) => {
            let p = path.parent().unwrap_or(Path::new("")).join(f);
            let (file, len) = fileio::open_regular(&p)?;
            let raw = read_samples(&p, file, len, h.byte_skip, h.gzip, h.kind, count)?;
            (p, raw)
        }
        None => {
            let raw = read_samples(
                path,
                attached,
                file_len.saturating_sub(h.len),
                h.byte_skip,
                h.gzip,
                h.kind,
                count,
            )?;
            (path.to_path_buf(), raw)
        }
    };
    let range = range.or(match h.kind {
        Kind::U8 => Some([0.0, 255.0]),
        Kind::I8 => Some([-128.0, 127.0]),
        _ => None,
    });
    grid_from_samples(
        &what,
        &data_path,
        h.kind,
        h.big_endian,
        &raw,
        h.dims,
        h.spacing,
        range,
    )
}

/// Parses the header at the start of `bytes`.
fn header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let fmt = |m: String| Error::format(path, m);
    let (lines, len) = header_lines(path, bytes)?;
    let f = Fields::read(path, &lines)?;
    let kind = f.kind.ok_or_else(|| fmt("header has no `type`".into()))?;
    if f.dimension != Some(3) {
        return Err(fmt(format!(
            "only 3-D scalar volumes are supported (dimension: {:?})",
            f.dimension
        )));
    }
    let sizes = f.sizes.ok_or_else(|| fmt("header has no `sizes`".into()))?;
    let sizes: [u64; 3] = sizes
        .try_into()
        .map_err(|s: Vec<u64>| fmt(format!("`sizes` has {} entries, 3 expected", s.len())))?;
    let dims = super::check_dims(&path.display().to_string(), sizes)?;
    let spacing = spacing(path, &f.space, f.units_mm, f.directions, f.spacings)?;
    let gzip = match f.encoding.as_str() {
        "raw" => false,
        "gzip" | "gz" => true,
        e => {
            return Err(fmt(format!(
                "encoding {e:?} is not supported (use raw or gzip)"
            )))
        }
    };
    Ok(Header {
        len,
        kind,
        dims,
        spacing,
        gzip,
        big_endian: f.big_endian,
        data_file: f.data_file,
        byte_skip: f.byte_skip,
    })
}

/// Checks the magic and splits the header into its lines (the magic line first), up to the
/// first empty line; also returns the header's length in bytes, the empty line included.
fn header_lines(path: &Path, bytes: &[u8]) -> Result<(Vec<String>, u64)> {
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
            .ok_or_else(|| {
                fmt(format!(
                    "header does not end (no empty line before the data{})",
                    if bytes.len() as u64 >= MAX_HEADER_BYTES {
                        format!(" within {MAX_HEADER_BYTES} bytes")
                    } else {
                        String::new()
                    }
                ))
            })?;
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
    Ok((lines, pos as u64))
}

/// The header's fields as written, before they are checked against each other.
#[derive(Default)]
struct Fields {
    kind: Option<Kind>,
    dimension: Option<u32>,
    sizes: Option<Vec<u64>>,
    encoding: String,
    big_endian: bool,
    spacings: Option<Vec<f64>>,
    directions: Option<Vec<[f64; 3]>>,
    space: String,
    units_mm: bool,
    data_file: Option<String>,
    byte_skip: u64,
}

impl Fields {
    /// The fields of the header `lines` after the magic line (comments and `key:=value`
    /// pairs skipped; unknown fields ignored).
    fn read(path: &Path, lines: &[String]) -> Result<Fields> {
        let mut f = Fields {
            encoding: "raw".to_string(),
            ..Fields::default()
        };
        for line in lines.iter().skip(1) {
            if line.starts_with('#') {
                continue;
            }
            let Some((key, val)) = line.split_once(':') else {
                return Err(Error::format(
                    path,
                    format!("header line {line:?} is not `field: value`"),
                ));
            };
            // `key:=value` lines are key/value pairs, not fields.
            if val.starts_with('=') {
                continue;
            }
            f.set(path, key.trim(), val.trim())?;
        }
        Ok(f)
    }

    /// One `key: value` field.
    fn set(&mut self, path: &Path, key: &str, val: &str) -> Result<()> {
        let fmt = |m: String| Error::format(path, m);
        match key {
            "type" => {
                self.kind =
                    Some(Kind::parse(val).ok_or_else(|| fmt(format!("unsupported type {val:?}")))?)
            }
            "dimension" => self.dimension = val.parse::<u32>().ok(),
            "sizes" => {
                self.sizes = Some(
                    val.split_whitespace()
                        .map(|s| s.parse().ok())
                        .collect::<Option<_>>()
                        .ok_or_else(|| fmt(format!("sizes {val:?} are not integers")))?,
                )
            }
            "encoding" => self.encoding = val.to_string(),
            "endian" => self.big_endian = val == "big",
            "spacings" => {
                self.spacings = Some(
                    val.split_whitespace()
                        .map(|s| s.parse().ok())
                        .collect::<Option<_>>()
                        .ok_or_else(|| fmt(format!("spacings {val:?} are not numbers")))?,
                )
            }
            "space directions" => {
                self.directions = Some(
                    val.split_whitespace()
                        .map(vector)
                        .collect::<Option<_>>()
                        .ok_or_else(|| fmt(format!("space directions {val:?} are not (x,y,z)")))?,
                )
            }
            "space" => self.space = val.to_string(),
            "space units" => self.units_mm = val.contains("mm"),
            "data file" | "datafile" => self.data_file = Some(val.to_string()),
            "byte skip" | "byteskip" => {
                self.byte_skip = val.parse().map_err(|_| {
                    fmt(format!("byte skip {val:?} is not a count (-1 unsupported)"))
                })?
            }
            _ => {}
        }
        Ok(())
    }
}

/// Sample spacing in metres: the lengths of the (axis-aligned) `space directions`, else the
/// `spacings`, else 1 unit; millimetres when `space` is an anatomical one or the units say mm.
fn spacing(
    path: &Path,
    space: &str,
    units_mm: bool,
    directions: Option<Vec<[f64; 3]>>,
    spacings: Option<Vec<f64>>,
) -> Result<[f64; 3]> {
    let fmt = |m: String| Error::format(path, m);
    let anatomical = space.contains("anterior")
        || space.contains("posterior")
        || space.contains("scanner")
        || space.contains("3D-");
    let to_m = if units_mm || anatomical { 1e-3 } else { 1.0 };
    Ok(if let Some(d) = directions {
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
    })
}
