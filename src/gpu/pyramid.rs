//! The maximum pyramid as the GPU reads it: a square power-of-two mip chain, and its 3x3
//! dilation for the tile pre-pass.

use crate::terrain::Terrain;

/// Each cell of every level of a [`square_pyramid`] replaced by the maximum of its 3x3
/// neighbourhood (cells outside the square count as PAD): the tile pre-pass's cone test.
pub fn dilate_square_pyramid(data: &[f32], n: u32) -> Vec<f32> {
    use rayon::prelude::*;
    let pad = crate::terrain::pyramid::PAD;
    let mut out = vec![pad; data.len()];
    let mut side = n as usize;
    let mut offset = 0usize;
    loop {
        let src = &data[offset..offset + side * side];
        // Separable: 3-wide row maxima, then 3-tall column maxima of those.
        let mut rows = vec![pad; side * side];
        rows.par_chunks_mut(side).enumerate().for_each(|(j, row)| {
            let s = &src[j * side..][..side];
            for (i, out) in row.iter_mut().enumerate() {
                *out = s[i.saturating_sub(1)..=(i + 1).min(side - 1)]
                    .iter()
                    .copied()
                    .fold(pad, f32::max);
            }
        });
        out[offset..offset + side * side]
            .par_chunks_mut(side)
            .enumerate()
            .for_each(|(j, dst)| {
                let (lo, hi) = (j.saturating_sub(1), (j + 1).min(side - 1));
                for (i, out) in dst.iter_mut().enumerate() {
                    *out = (lo..=hi).map(|jj| rows[jj * side + i]).fold(pad, f32::max);
                }
            });
        offset += side * side;
        if side == 1 {
            break;
        }
        side /= 2;
    }
    out
}

/// The side of [`square_pyramid`]'s level 0, without building it.
pub fn square_side(terrain: &Terrain) -> u32 {
    let cells = terrain.pyramid.levels[0].cells;
    cells[0].max(cells[1]).next_power_of_two()
}

/// The maximum pyramid re-laid for the GPU as a square power-of-two mip chain: level L has side
/// `N >> L` (N = the next power of two of the larger cell count), starts at
/// `4 (N² − (N >> L)²) / 3` and is padded with [`crate::terrain::pyramid::PAD`]. Returns the data and N.
pub fn square_pyramid(terrain: &Terrain) -> (Vec<f32>, u32) {
    let pyr = &terrain.pyramid;
    let cells = pyr.levels[0].cells;
    let n = cells[0].max(cells[1]).next_power_of_two();
    debug_assert_eq!(pyr.levels.len() as u32, 32 - n.leading_zeros());
    let total = (4 * (n as u64 * n as u64) - 1) / 3 + 1;
    let mut data = vec![crate::terrain::pyramid::PAD; total as usize];
    for (l, level) in pyr.levels.iter().enumerate() {
        let side = (n >> l) as u64;
        let offset = (n as u64 * n as u64 - side * side) / 3 * 4;
        for j in 0..level.cells[1] as u64 {
            let src = &pyr.data[(level.offset as u64 + j * level.stored[0] as u64) as usize..]
                [..level.cells[0] as usize];
            data[(offset + j * side) as usize..][..src.len()].copy_from_slice(src);
        }
    }
    (data, n)
}
