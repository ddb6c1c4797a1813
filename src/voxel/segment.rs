//! The compact segment format (`.rvs`, after seed-digest §2): the model as **segments along
//! z**, one per (x, y) column, each a run list `(free count, occupied count, occupied voxels
//! with their attributes)` ending with an occupied count of 0; empty segments are not stored;
//! a separate array holds each segment's byte offset; the header declares each extra
//! attribute's byte size.
//!
//! Layout (all integers little-endian):
//!
//! | offset | bytes | field |
//! |---|---|---|
//! | 0 | 8 | magic `RLFVSEG\0` |
//! | 8 | 2 | version (1) |
//! | 10 | 2 | `A`: number of extra attributes |
//! | 12 | 12 | model size `dx, dy, dz` (u32 each) |
//! | 24 | `A` | byte size of each extra attribute (u8, 1..=255) |
//! | | 1024 | palette: sRGB RGBA of indices 0..=255 |
//! | | 4·dx·dy | segment offsets (u32), column `x + dx·y`, relative to the segment data; `0xFFFFFFFF` = empty column |
//! | | 4 | `L`: bytes of segment data |
//! | | `L` | segments |
//!
//! A segment is a sequence of runs, each `f` (free voxels, LEB128 varint), `n` (occupied
//! voxels, varint) and `n` records of `1 + Σ sizes` bytes: the palette index (1..=255) then the
//! extra attributes in header order; the run with `n = 0` (written `0, 0`) ends it. The writer
//! is canonical (maximal runs, columns in order), so write → read → write is bit-exact.
//! The reader requires the segments in column order without overlap (so no voxel record is
//! read twice: the voxel count is bounded by the file's length) and checks the model's grid
//! against the memory budget before decoding.

use super::{Voxel, VoxelModel};
use crate::{fileio, Error, Result};
use std::path::Path;

pub const MAGIC: &[u8; 8] = b"RLFVSEG\0";
pub const VERSION: u16 = 1;
const EMPTY: u32 = u32::MAX;

fn varint(out: &mut Vec<u8>, mut v: u32) {
    loop {
        let b = (v & 0x7f) as u8;
        v >>= 7;
        if v == 0 {
            out.push(b);
            return;
        }
        out.push(b | 0x80);
    }
}

/// Encodes a model.
pub fn encode(m: &VoxelModel) -> Vec<u8> {
    let [dx, dy, _] = m.dims;
    let stride = m.extra_stride();
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(m.extra_sizes.len() as u16).to_le_bytes());
    for d in m.dims {
        out.extend_from_slice(&d.to_le_bytes());
    }
    out.extend_from_slice(&m.extra_sizes);
    for c in &m.palette {
        out.extend_from_slice(c);
    }
    let columns = (dx as usize) * (dy as usize);
    let mut offsets = vec![EMPTY; columns];
    let mut data = Vec::new();
    let mut i = 0;
    while i < m.voxels.len() {
        let v = m.voxels[i];
        let col = (v.pos[0] + dx * v.pos[1]) as usize;
        offsets[col] = data.len() as u32;
        let mut z = 0;
        while i < m.voxels.len() && {
            let w = m.voxels[i];
            (w.pos[0] + dx * w.pos[1]) as usize == col
        } {
            let start = i;
            let z0 = m.voxels[i].pos[2];
            while i + 1 < m.voxels.len()
                && m.voxels[i + 1].pos[0] == v.pos[0]
                && m.voxels[i + 1].pos[1] == v.pos[1]
                && m.voxels[i + 1].pos[2] == m.voxels[i].pos[2] + 1
            {
                i += 1;
            }
            i += 1;
            varint(&mut data, z0 - z);
            varint(&mut data, (i - start) as u32);
            for k in start..i {
                data.push(m.voxels[k].index);
                data.extend_from_slice(&m.extra[k * stride..(k + 1) * stride]);
            }
            z = z0 + (i - start) as u32;
        }
        varint(&mut data, 0);
        varint(&mut data, 0);
    }
    for o in offsets {
        out.extend_from_slice(&o.to_le_bytes());
    }
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(&data);
    out
}

struct Cursor<'a> {
    d: &'a [u8],
    pos: usize,
    path: &'a Path,
}

impl<'a> Cursor<'a> {
    fn err(&self, msg: impl std::fmt::Display) -> Error {
        Error::format(
            self.path,
            format!("malformed segment file at byte {}: {msg}", self.pos),
        )
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if n > self.d.len() - self.pos {
            return Err(self.err(format!(
                "{what} needs {n} bytes, {} left (truncated file?)",
                self.d.len() - self.pos
            )));
        }
        let s = &self.d[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().expect("4 bytes"),
        ))
    }
    fn u16(&mut self, what: &str) -> Result<u16> {
        Ok(u16::from_le_bytes(
            self.take(2, what)?.try_into().expect("2 bytes"),
        ))
    }
    fn varint(&mut self, what: &str) -> Result<u32> {
        let mut v: u64 = 0;
        for shift in (0..35).step_by(7) {
            let b = self.take(1, what)?[0];
            v |= ((b & 0x7f) as u64) << shift;
            if b & 0x80 == 0 {
                return u32::try_from(v).map_err(|_| self.err(format!("{what} overflows")));
            }
        }
        Err(self.err(format!("{what}: varint longer than 5 bytes")))
    }
}

/// The header of a segment file, read up to the segment data.
struct Header {
    dims: [u32; 3],
    extra_sizes: Vec<u8>,
    /// Bytes of extra attributes per voxel.
    stride: usize,
    palette: Vec<[u8; 4]>,
    offsets: Vec<u32>,
    /// Bytes of segment data.
    len: usize,
    /// Where the segment data starts in the file.
    base: usize,
}

/// Decodes segment-format bytes; `path` names the file in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<VoxelModel> {
    let mut c = Cursor {
        d: bytes,
        pos: 0,
        path,
    };
    let h = read_header(&mut c)?;
    let dims = h.dims;
    // Each record takes at least one byte of segment data.
    fileio::check_alloc(
        format!(
            "{} ({}x{}x{} voxels)",
            path.display(),
            dims[0],
            dims[1],
            dims[2]
        ),
        super::model_memory(dims, (h.len / (1 + h.stride)) as u64),
    )?;
    let mut voxels = Vec::new();
    let mut extra = Vec::new();
    // End of the previous column's segment (relative): segments do not overlap.
    let mut next_free = 0usize;
    for (col, &off) in h.offsets.iter().enumerate() {
        if off == EMPTY {
            continue;
        }
        if off as usize >= h.len {
            return Err(c.err(format!(
                "column {col}: offset {off} is past the segment data ({} bytes)",
                h.len
            )));
        }
        if (off as usize) < next_free {
            return Err(c.err(format!(
                "column {col}: its segment at offset {off} overlaps the previous column's (ending at {next_free}); segments are stored in column order, each once"
            )));
        }
        c.pos = h.base + off as usize;
        let (x, y) = (
            (col % dims[0] as usize) as u32,
            (col / dims[0] as usize) as u32,
        );
        read_segment(&mut c, &h, [x, y], &mut voxels, &mut extra)?;
        next_free = c.pos - h.base;
    }
    Ok(VoxelModel {
        dims,
        palette: h.palette,
        voxels,
        extra_sizes: h.extra_sizes,
        extra,
    })
}

/// Magic, version, attribute count, model size, attribute sizes, palette, segment offsets
/// and the length of the segment data, which must be the rest of the file.
fn read_header(c: &mut Cursor) -> Result<Header> {
    if c.take(8, "magic")? != MAGIC {
        return Err(Error::format(
            c.path,
            "not a relief segment file: it does not start with RLFVSEG",
        ));
    }
    let version = c.u16("version")?;
    if version != VERSION {
        return Err(c.err(format!(
            "version {version}; this build reads version {VERSION}"
        )));
    }
    let attrs = c.u16("attribute count")? as usize;
    let dims = [c.u32("dx")?, c.u32("dy")?, c.u32("dz")?];
    super::check_dims(&c.path.display().to_string(), dims)?;
    let extra_sizes = c.take(attrs, "attribute sizes")?.to_vec();
    if extra_sizes.contains(&0) {
        return Err(c.err("an extra attribute declares 0 bytes"));
    }
    let stride: usize = extra_sizes.iter().map(|&s| s as usize).sum();
    let palette: Vec<[u8; 4]> = c
        .take(1024, "palette")?
        .chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect();
    let columns = dims[0] as usize * dims[1] as usize;
    let offsets: Vec<u32> = c
        .take(4 * columns, "segment offsets")?
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
        .collect();
    let len = c.u32("segment data length")? as usize;
    let base = c.pos;
    if len != c.d.len() - base {
        return Err(c.err(format!(
            "the header declares {len} bytes of segment data, the file has {}",
            c.d.len() - base
        )));
    }
    Ok(Header {
        dims,
        extra_sizes,
        stride,
        palette,
        offsets,
        len,
        base,
    })
}

/// The segment of column `(x, y)` at the cursor: its runs' voxels and their extra attributes
/// appended to `voxels` and `extra`; the cursor is left after the segment.
fn read_segment(
    c: &mut Cursor,
    h: &Header,
    [x, y]: [u32; 2],
    voxels: &mut Vec<Voxel>,
    extra: &mut Vec<u8>,
) -> Result<()> {
    let (dims, stride) = (h.dims, h.stride);
    let mut z: u64 = 0;
    let mut runs = 0;
    loop {
        let f = c.varint("free count")?;
        let n = c.varint("occupied count")?;
        if n == 0 {
            break;
        }
        runs += 1;
        z += f as u64;
        if z + n as u64 > dims[2] as u64 {
            return Err(c.err(format!(
                "column ({x}, {y}): runs reach z = {}, the model is {} high",
                z + n as u64,
                dims[2]
            )));
        }
        let recs = c.take(n as usize * (1 + stride), "voxel records")?;
        for (k, r) in recs.chunks_exact(1 + stride).enumerate() {
            if r[0] == 0 {
                return Err(c.err(format!(
                    "column ({x}, {y}): occupied voxel with palette index 0"
                )));
            }
            voxels.push(Voxel {
                pos: [x, y, (z + k as u64) as u32],
                index: r[0],
            });
            extra.extend_from_slice(&r[1..]);
        }
        z += n as u64;
    }
    if runs == 0 {
        return Err(c.err(format!(
            "column ({x}, {y}) is stored but empty (empty segments are not stored)"
        )));
    }
    Ok(())
}

/// Writes a model to `path` atomically ([`fileio::write_atomic`]: nothing half-written is
/// left, whatever fails).
pub fn write(m: &VoxelModel, path: &Path) -> Result<u64> {
    let bytes = encode(m);
    fileio::write_file_atomic(path, &bytes)?;
    Ok(bytes.len() as u64)
}

/// Reads a segment file.
pub fn read(path: &Path) -> Result<VoxelModel> {
    let bytes = fileio::read_file(path, fileio::memory_budget())?;
    decode(&bytes, path)
}
