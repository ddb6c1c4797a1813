//! Tiles: what one holds, and its blob (compressed, checked on reading).

use super::format::TileId;
use crate::{Error, Result};
use std::io::Read;
use std::path::Path;

/// A decoded tile.
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    /// Cells per side.
    pub n: usize,
    /// (n+1)² heights, row 0 south; NaN where no source has data.
    pub heights: Vec<f32>,
    /// The cell-maximum pyramid: n² cell maxima (each bounds its bilinear patch and every
    /// finer sample in the cell's footprint), then each coarser in-tile level the max of 2x2,
    /// down to 1. A cell with no data holds [`crate::terrain::pyramid::PAD`].
    pub maxima: Vec<f32>,
}

impl Tile {
    /// Height of sample `(i, j)`, `0 ≤ i, j ≤ n`.
    pub fn height(&self, i: usize, j: usize) -> f32 {
        self.heights[j * (self.n + 1) + i]
    }
    /// Offset of in-tile pyramid level `l` (0: n² cells) in [`Tile::maxima`].
    pub fn max_level_offset(n: usize, l: u32) -> usize {
        let side = n >> l;
        (n * n - side * side) / 3 * 4
    }
    /// Maximum of cell `(i, j)` of in-tile pyramid level `l` (side `n >> l`).
    pub fn cell_max(&self, l: u32, i: usize, j: usize) -> f32 {
        self.maxima[Self::max_level_offset(self.n, l) + j * (self.n >> l) + i]
    }
    /// Floats of a tile of `n` cells: heights and maxima.
    pub fn floats(n: usize) -> usize {
        (n + 1) * (n + 1) + (4 * n * n - 1) / 3
    }
    /// Bytes a decoded tile of `n` cells takes in memory.
    pub fn bytes(n: usize) -> u64 {
        Self::floats(n) as u64 * 4
    }
}

/// Largest blob of a tile of `n` cells: deflate can grow incompressible data a little.
pub fn max_blob(n: usize) -> u64 {
    let raw = raw_bytes(n);
    raw + raw / 64 + 4096
}

/// The pyramid of `cell_maxima` (n² values): all in-tile levels, finest first.
pub fn max_pyramid(n: usize, cell_maxima: &[f32]) -> Vec<f32> {
    let mut out = Vec::with_capacity((4 * n * n - 1) / 3);
    out.extend_from_slice(cell_maxima);
    let (mut side, mut at) = (n, 0);
    while side > 1 {
        let half = side / 2;
        for j in 0..half {
            for i in 0..half {
                let c = |a: usize, b: usize| out[at + (2 * j + b) * side + 2 * i + a];
                let m = c(0, 0).max(c(1, 0)).max(c(0, 1)).max(c(1, 1));
                out.push(m);
            }
        }
        at += side * side;
        side = half;
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Tile blobs

/// Each value's bits XOR the previous value's (neighbours share sign, exponent and leading
/// mantissa bits, which become zeros), split into byte planes.
fn shuffle(values: &[f32], out: &mut Vec<u8>) {
    let mut prev = 0u32;
    let xored: Vec<u32> = values
        .iter()
        .map(|v| {
            let b = v.to_bits();
            let x = b ^ prev;
            prev = b;
            x
        })
        .collect();
    for plane in 0..4 {
        out.extend(xored.iter().map(|x| x.to_le_bytes()[plane]));
    }
}

fn unshuffle(bytes: &[u8]) -> Vec<f32> {
    let n = bytes.len() / 4;
    let mut prev = 0u32;
    (0..n)
        .map(|k| {
            let x =
                u32::from_le_bytes([bytes[k], bytes[n + k], bytes[2 * n + k], bytes[3 * n + k]]);
            prev ^= x;
            f32::from_bits(prev)
        })
        .collect()
}

/// The prediction of height `k = j·side + i` of a grid `side` samples wide from the heights
/// before it: left + below − below-left (exact on planes, so on bilinear-filled areas nearly
/// so); the left or the below neighbour on the first row and column, and where a term is NaN.
#[inline]
fn predict(h: &[f32], i: usize, j: usize, k: usize, side: usize) -> f32 {
    let p = match (i, j) {
        (0, 0) => 0.0,
        (_, 0) => h[k - 1],
        (0, _) => h[k - side],
        _ => h[k - 1] + h[k - side] - h[k - side - 1],
    };
    if !p.is_nan() {
        return p;
    }
    [(i > 0).then(|| k - 1), (j > 0).then(|| k - side)]
        .into_iter()
        .flatten()
        .map(|q| h[q])
        .find(|v| !v.is_nan())
        .unwrap_or(0.0)
}

/// The heights' bits XOR their predictions' bits ([`predict`]).
fn residuals(h: &[f32], side: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(h.len());
    for j in 0..h.len() / side {
        for i in 0..side {
            let k = j * side + i;
            out.push(f32::from_bits(
                h[k].to_bits() ^ predict(h, i, j, k, side).to_bits(),
            ));
        }
    }
    out
}

/// Inverse of [`residuals`].
fn unresiduals(r: &[f32], side: usize) -> Vec<f32> {
    let mut h = vec![0.0f32; r.len()];
    for j in 0..r.len() / side {
        for i in 0..side {
            let k = j * side + i;
            let p = predict(&h, i, j, k, side);
            h[k] = f32::from_bits(r[k].to_bits() ^ p.to_bits());
        }
    }
    h
}

/// The highest of the four corners of each cell (PAD where all are NaN): the bound the
/// cell's own bilinear patch needs, and the prediction its stored maximum is coded against.
fn corner_maxima(heights: &[f32], n: usize) -> Vec<f32> {
    let np = n + 1;
    let mut out = Vec::with_capacity(n * n);
    for b in 0..n {
        for a in 0..n {
            let k = b * np + a;
            let m = heights[k]
                .max(heights[k + 1])
                .max(heights[k + np])
                .max(heights[k + np + 1]);
            out.push(crate::terrain::pyramid::PAD.max(m));
        }
    }
    out
}

/// Bytes of a tile's blob before deflate: its heights and its cell maxima.
pub fn raw_bytes(n: usize) -> u64 {
    (((n + 1) * (n + 1) + n * n) * 4) as u64
}

/// The blob of a tile, deflated: its heights (bits XOR their prediction, `residuals`),
/// then its cell maxima (bits XOR the cell's corner maximum: zero wherever nothing finer
/// rises above the cell's own corners, as everywhere on the finest level), each array in byte
/// planes. The in-tile pyramid above the cell maxima is not stored: it is their 2x2 maxima,
/// made again on reading ([`decode_tile`]).
pub fn encode_tile(tile: &Tile) -> Vec<u8> {
    use std::io::Write;
    let n = tile.n;
    let mut raw = Vec::with_capacity(raw_bytes(n) as usize);
    shuffle(&residuals(&tile.heights, n + 1), &mut raw);
    let cells = &tile.maxima[..n * n];
    let coded: Vec<f32> = cells
        .iter()
        .zip(corner_maxima(&tile.heights, n))
        .map(|(m, c)| f32::from_bits(m.to_bits() ^ c.to_bits()))
        .collect();
    shuffle(&coded, &mut raw);
    let mut z = flate2::write::ZlibEncoder::new(
        Vec::with_capacity(raw.len() / 3),
        flate2::Compression::new(6),
    );
    z.write_all(&raw).expect("writing to memory");
    z.finish().expect("writing to memory")
}

/// Decodes and checks a blob read for `id` (its CRC already verified): it must inflate to
/// exactly one tile of `n` cells, heights finite or NaN within ±[`crate::terrain::MAX_ABS_HEIGHT`],
/// each cell maximum a number at least its corners' maximum. Makes the in-tile pyramid.
pub fn decode_tile(bytes: &[u8], n: usize, path: &Path, id: TileId) -> Result<Tile> {
    let want = raw_bytes(n);
    let bad = |m: String| {
        Error::format(
            path,
            format!("{id}: {m}; rebuild the database with `relief db build`"),
        )
    };
    let mut raw = Vec::with_capacity(want as usize);
    flate2::read::ZlibDecoder::new(bytes)
        .take(want + 1)
        .read_to_end(&mut raw)
        .map_err(|e| bad(format!("its data does not inflate ({e})")))?;
    if raw.len() as u64 != want {
        return Err(bad(format!(
            "its data inflates to {} bytes, a tile of {n}x{n} cells has {want}",
            raw.len()
        )));
    }
    let split = (n + 1) * (n + 1) * 4;
    let heights = unresiduals(&unshuffle(&raw[..split]), n + 1);
    let limit = crate::terrain::MAX_ABS_HEIGHT as f32;
    if let Some(h) = heights.iter().find(|h| h.abs() > limit) {
        return Err(bad(format!(
            "it holds a height of {h} m, beyond ±{limit:e} m"
        )));
    }
    let corners = corner_maxima(&heights, n);
    let cells: Vec<f32> = unshuffle(&raw[split..])
        .iter()
        .zip(&corners)
        .map(|(x, c)| f32::from_bits(x.to_bits() ^ c.to_bits()))
        .collect();
    if cells.iter().zip(&corners).any(|(m, c)| m.is_nan() || m < c) {
        return Err(bad(
            "a cell maximum is below its own corners or not a number".into(),
        ));
    }
    let maxima = max_pyramid(n, &cells);
    Ok(Tile { n, heights, maxima })
}
