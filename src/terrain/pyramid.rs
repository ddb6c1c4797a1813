//! The maximum-LOD pyramid.
//!
//! Level 0 holds one value per grid cell: the maximum of its four corner samples, which is
//! the maximum of the bilinear patch over the cell (a bilinear patch attains its extremes at
//! the corners), so the pyramid is conservative for the bilinear surface. Level `L+1` holds
//! the maximum of each 2x2 block of level `L`; the top level is a single value.
//!
//! Storage: all levels in one flat `f32` array. Every level below the top is stored with even
//! width and height, padded with [`PAD`], so both children of any real cell exist.

use super::heightfield::Heightfield;
use rayon::prelude::*;

/// Padding for cells outside the grid (no terrain). Finite: WGSL may assume no infinities.
pub const PAD: f32 = -1.0e30;

/// One pyramid level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Level {
    /// Real cells along x and y.
    pub cells: [u32; 2],
    /// Stored width (row stride) and height, ≥ `cells`.
    pub stored: [u32; 2],
    /// Offset of the level's first value in [`MaxPyramid::data`].
    pub offset: u32,
}

/// Maximum pyramid over a height field's cells.
#[derive(Clone, Debug)]
pub struct MaxPyramid {
    /// Level 0 (finest, one per cell) first, the single-value top last.
    pub levels: Vec<Level>,
    /// All levels' values.
    pub data: Vec<f32>,
}

impl MaxPyramid {
    /// The levels of the pyramid of a `width` x `height`-sample grid, holding no values
    /// (`data` empty): what a terrain whose samples are not held (a paged database window)
    /// keeps of its pyramid.
    pub fn shape(width: usize, height: usize) -> MaxPyramid {
        let mut cells = [(width - 1) as u32, (height - 1) as u32];
        let mut dims = vec![cells];
        while cells != [1, 1] {
            cells = [cells[0].div_ceil(2), cells[1].div_ceil(2)];
            dims.push(cells);
        }
        let mut levels = Vec::with_capacity(dims.len());
        let mut offset = 0u32;
        for (l, c) in dims.iter().enumerate() {
            let stored = if l + 1 == dims.len() {
                [1, 1]
            } else {
                [dims[l + 1][0] * 2, dims[l + 1][1] * 2]
            };
            levels.push(Level {
                cells: *c,
                stored,
                offset,
            });
            offset += stored[0] * stored[1];
        }
        MaxPyramid {
            levels,
            data: Vec::new(),
        }
    }

    /// Builds the pyramid of `field`.
    pub fn build(field: &Heightfield) -> MaxPyramid {
        let MaxPyramid { levels, .. } = Self::shape(field.width, field.height);
        let last = levels.last().expect("a pyramid has a top level");
        let mut data = vec![PAD; (last.offset + last.stored[0] * last.stored[1]) as usize];
        // Level 0 from the samples.
        {
            let l0 = levels[0];
            let (w, sw) = (field.width, l0.stored[0] as usize);
            let lvl = &mut data[..(l0.stored[0] * l0.stored[1]) as usize];
            lvl.par_chunks_mut(sw)
                .take(l0.cells[1] as usize)
                .enumerate()
                .for_each(|(j, row)| {
                    let (r0, r1) = (
                        &field.heights[j * w..][..w],
                        &field.heights[(j + 1) * w..][..w],
                    );
                    for i in 0..w - 1 {
                        row[i] = r0[i].max(r0[i + 1]).max(r1[i]).max(r1[i + 1]);
                    }
                });
        }
        for l in 1..levels.len() {
            let (src, dst) = (levels[l - 1], levels[l]);
            let (lo, hi) = data.split_at_mut(dst.offset as usize);
            let src_data = &lo[src.offset as usize..];
            let ssw = src.stored[0] as usize;
            let dsw = dst.stored[0] as usize;
            hi[..(dst.stored[0] * dst.stored[1]) as usize]
                .par_chunks_mut(dsw)
                .take(dst.cells[1] as usize)
                .enumerate()
                .for_each(|(j, row)| {
                    for (i, out) in row.iter_mut().enumerate().take(dst.cells[0] as usize) {
                        let a = &src_data[2 * j * ssw + 2 * i..];
                        let b = &src_data[(2 * j + 1) * ssw + 2 * i..];
                        *out = a[0].max(a[1]).max(b[0]).max(b[1]);
                    }
                });
        }
        MaxPyramid { levels, data }
    }

    /// Index of the top (single-value) level.
    pub fn top(&self) -> usize {
        self.levels.len() - 1
    }

    /// Maximum stored for cell `(i, j)` of `level`; [`PAD`] outside the real cells.
    #[inline]
    pub fn get(&self, level: usize, i: i64, j: i64) -> f32 {
        let l = &self.levels[level];
        if i < 0 || j < 0 || i >= l.cells[0] as i64 || j >= l.cells[1] as i64 {
            return PAD;
        }
        self.data[l.offset as usize + j as usize * l.stored[0] as usize + i as usize]
    }
}
