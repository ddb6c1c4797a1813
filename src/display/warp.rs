//! Warp file formats: MPCDI-style PFM geometry warps (2-D u,v or 3-D screen X,Y,Z per pixel,
//! NaN = no data) and Paul Bourke warp meshes (`x y u v i` nodes, types 1 and 2).

use crate::{fileio, Error, Result};
use std::path::Path;

/// Row order of a PFM file's data. Netpbm stores the bottom row first; some tools store the
/// top row first, so readers must be told.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowOrder {
    BottomToTop,
    TopToBottom,
}

/// A PFM image: `channels` (1 or 3) f32 per pixel, rows top to bottom in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Pfm {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    pub data: Vec<f32>,
}

impl Pfm {
    /// Pixel `(x, y)` (y from the top).
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        let c = self.channels as usize;
        &self.data[(y as usize * self.width as usize + x as usize) * c..][..c]
    }
}

fn header_token<'a>(bytes: &'a [u8], pos: &mut usize) -> Option<&'a str> {
    while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
        *pos += 1;
    }
    let start = *pos;
    while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() {
        *pos += 1;
    }
    std::str::from_utf8(&bytes[start..*pos])
        .ok()
        .filter(|s| !s.is_empty())
}

/// Reads a PFM file.
pub fn read_pfm(path: &Path, order: RowOrder) -> Result<Pfm> {
    let bytes = fileio::read_file(path, fileio::memory_budget())?;
    parse_pfm(&bytes, path, order)
}

/// Parses PFM bytes; `path` names the file in errors.
pub fn parse_pfm(bytes: &[u8], path: &Path, order: RowOrder) -> Result<Pfm> {
    let mut pos = 0;
    let bad = |msg: &str| Error::format(path, format!("not a PFM file: {msg}"));
    let channels = match header_token(bytes, &mut pos) {
        Some("PF") => 3,
        Some("Pf") => 1,
        _ => return Err(bad("the header must start with PF (colour) or Pf (grey)")),
    };
    let mut num = |what: &str| -> Result<f64> {
        header_token(bytes, &mut pos)
            .and_then(|t| t.parse::<f64>().ok())
            .ok_or_else(|| bad(&format!("bad or missing {what} in the header")))
    };
    let (w, h, scale) = (num("width")?, num("height")?, num("scale")?);
    if !(w >= 1.0
        && h >= 1.0
        && w <= 65536.0
        && h <= 65536.0
        && w.fract() == 0.0
        && h.fract() == 0.0)
    {
        return Err(bad(&format!("size {w}x{h} is not 1..=65536 per side")));
    }
    if scale == 0.0 || !scale.is_finite() {
        return Err(bad("the scale must be non-zero (negative = little-endian)"));
    }
    pos += 1; // the single whitespace byte after the scale
    let (w, h) = (w as u32, h as u32);
    let n = (w as usize) * (h as usize) * channels;
    let body = &bytes[pos.min(bytes.len())..];
    if body.len() < n * 4 {
        return Err(Error::format(
            path,
            format!(
                "short data: {w}x{h}x{channels} floats need {} bytes, the file has {}",
                n * 4,
                body.len()
            ),
        ));
    }
    // The floats and their reordered copy.
    fileio::check_alloc(path.display(), (n as u64).saturating_mul(8))?;
    let little = scale < 0.0;
    let vals: Vec<f32> = body[..n * 4]
        .chunks_exact(4)
        .map(|b| {
            let b = [b[0], b[1], b[2], b[3]];
            if little {
                f32::from_le_bytes(b)
            } else {
                f32::from_be_bytes(b)
            }
        })
        .collect();
    let row = w as usize * channels;
    let data = match order {
        RowOrder::TopToBottom => vals,
        RowOrder::BottomToTop => vals.chunks_exact(row).rev().flatten().copied().collect(),
    };
    Ok(Pfm {
        width: w,
        height: h,
        channels: channels as u32,
        data,
    })
}

/// Writes a little-endian PFM file in the given row order (atomically: nothing half-written is
/// left).
pub fn write_pfm(path: &Path, pfm: &Pfm, order: RowOrder) -> Result<()> {
    let mut out = format!(
        "{}\n{} {}\n-1.0\n",
        if pfm.channels == 3 { "PF" } else { "Pf" },
        pfm.width,
        pfm.height
    )
    .into_bytes();
    let row = (pfm.width * pfm.channels) as usize;
    let rows: Vec<&[f32]> = match order {
        RowOrder::TopToBottom => pfm.data.chunks_exact(row).collect(),
        RowOrder::BottomToTop => pfm.data.chunks_exact(row).rev().collect(),
    };
    for r in rows {
        for v in r {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    fileio::write_file_atomic(path, &out)
}

/// One node of a Bourke warp mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshNode {
    /// Position in the projector image: x in ±aspect, y in ±1 (up).
    pub x: f64,
    pub y: f64,
    /// Source-image coordinates 0..1, v = 0 at the bottom.
    pub u: f64,
    pub v: f64,
    /// Brightness; negative = node unused.
    pub i: f64,
}

/// A Paul Bourke warp mesh: type 2 rectangular (nx x ny nodes, rows bottom to top), type 1 polar.
#[derive(Clone, Debug, PartialEq)]
pub struct BourkeMesh {
    pub mesh_type: u32,
    pub nx: usize,
    pub ny: usize,
    pub nodes: Vec<MeshNode>,
}

/// Most nodes a Bourke mesh may declare.
pub const MAX_MESH_NODES: usize = 16_000_000;

/// Reads a Bourke mesh.
pub fn read_bourke(path: &Path) -> Result<BourkeMesh> {
    let text = fileio::read_to_string(path, fileio::memory_budget())?;
    parse_bourke(&text, path)
}

/// Parses a Bourke mesh's text; `path` names the file in errors. The declared node count is
/// checked against the lines the file has and the memory budget before nodes are stored.
pub fn parse_bourke(text: &str, path: &Path) -> Result<BourkeMesh> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let bad = |line: usize, msg: String| Error::format(path, format!("line {}: {msg}", line + 1));
    let (l0, t) = lines
        .next()
        .ok_or_else(|| Error::format(path, "empty file: expected a mesh type (1 or 2)"))?;
    let mesh_type: u32 = t
        .trim()
        .parse()
        .map_err(|_| bad(l0, format!("mesh type must be 1 or 2, got `{}`", t.trim())))?;
    if mesh_type != 1 && mesh_type != 2 {
        return Err(bad(
            l0,
            format!("mesh type must be 1 (polar) or 2 (rectangular), got {mesh_type}"),
        ));
    }
    let (l1, dims) = lines
        .next()
        .ok_or_else(|| Error::format(path, "missing the `nx ny` line"))?;
    let d: Vec<usize> = dims
        .split_whitespace()
        .filter_map(|s| s.parse().ok())
        .collect();
    let total = match d[..] {
        [nx, ny] if nx > 0 && ny > 0 => nx.checked_mul(ny).filter(|&t| t <= MAX_MESH_NODES),
        _ => None,
    };
    let Some(total) = total else {
        return Err(bad(
            l1,
            format!(
                "expected `nx ny` (positive, at most {MAX_MESH_NODES} nodes), got `{}`",
                dims.trim()
            ),
        ));
    };
    let (nx, ny) = (d[0], d[1]);
    // One line per node: a file with fewer lines cannot hold them.
    let remaining = lines.clone().count();
    if remaining < total {
        return Err(Error::format(
            path,
            format!("the header says {nx}x{ny} = {total} nodes, the file has {remaining}"),
        ));
    }
    fileio::check_alloc(
        path.display(),
        (total as u64).saturating_mul(std::mem::size_of::<MeshNode>() as u64),
    )?;
    let mut nodes = Vec::with_capacity(total);
    for (ln, l) in lines {
        let v: Vec<f64> = l
            .split_whitespace()
            .map(str::parse)
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| {
                bad(
                    ln,
                    format!("expected 5 numbers `x y u v i`, got `{}`", l.trim()),
                )
            })?;
        if v.len() != 5 || v.iter().any(|x| !x.is_finite()) {
            return Err(bad(
                ln,
                format!("expected 5 finite numbers `x y u v i`, got `{}`", l.trim()),
            ));
        }
        nodes.push(MeshNode {
            x: v[0],
            y: v[1],
            u: v[2],
            v: v[3],
            i: v[4],
        });
    }
    if nodes.len() != nx * ny {
        return Err(Error::format(
            path,
            format!(
                "the header says {nx}x{ny} = {} nodes, the file has {}",
                nx * ny,
                nodes.len()
            ),
        ));
    }
    Ok(BourkeMesh {
        mesh_type,
        nx,
        ny,
        nodes,
    })
}

/// Writes a Bourke mesh (shortest round-trip number formatting, so reading it back is exact),
/// atomically: nothing half-written is left.
pub fn write_bourke(path: &Path, mesh: &BourkeMesh) -> Result<()> {
    use std::fmt::Write;
    let mut s = format!("{}\n{} {}\n", mesh.mesh_type, mesh.nx, mesh.ny);
    for n in &mesh.nodes {
        let _ = writeln!(s, "{} {} {} {} {}", n.x, n.y, n.u, n.v, n.i);
    }
    fileio::write_file_atomic(path, s.as_bytes())
}
