//! Empty-space distances for the voxel DDA: for every empty voxel (and every empty brick), a
//! lower bound of its Chebyshev (L∞) distance to the nearest occupied voxel (brick). A ray in
//! an empty cell at distance `s` may jump out of the cube of cells within `s - 1` of it in one
//! step, since every cell of that cube is empty; `s = 1` is the plain Amanatides–Woo step.
//!
//! The L∞ distance transform is separable: along x, then y, then z, each cell takes
//! `min over k of max(|k|, f(cell + k))`. Distances are capped (a cap is a valid lower bound,
//! and the cap bounds the transform's cost per cell).

use rayon::prelude::*;

/// Cap of the voxel-level distances (a jump crosses at most `2 * cap - 1` voxels).
pub const VOXEL_SKIP_CAP: u8 = 8;
/// Cap of the brick-level distances.
pub const BRICK_SKIP_CAP: u8 = 16;
/// Largest model (in voxels) whose voxel-level distances are computed, on a dense grid of one
/// byte per voxel; larger models step voxel by voxel inside occupied bricks (distance 1).
pub const DENSE_LIMIT: u64 = 1 << 27;

/// Capped L∞ distance transform of a `dims` grid (index `x + dx (y + dy z)`): 0 where
/// `occupied`, else `min(cap, distance to the nearest occupied cell)`.
pub fn chebyshev(dims: [usize; 3], occupied: &[bool], cap: u8) -> Vec<u8> {
    assert_eq!(occupied.len(), dims[0] * dims[1] * dims[2]);
    let mut f: Vec<u8> = occupied.iter().map(|&o| if o { 0 } else { cap }).collect();
    let strides = [1, dims[0], dims[0] * dims[1]];
    for (axis, stride) in strides.into_iter().enumerate() {
        f = pass(&f, dims, stride, axis);
    }
    f
}

/// One separable pass along `axis`: `g(i) = min over k of max(|k|, f(i + k))`, `|k| < f(i)`
/// (the values are capped already, so the search is too).
fn pass(f: &[u8], dims: [usize; 3], stride: usize, axis: usize) -> Vec<u8> {
    let slice = dims[0] * dims[1];
    let mut out = vec![0u8; f.len()];
    out.par_chunks_mut(slice.max(1))
        .enumerate()
        .for_each(|(z, o)| {
            for (j, g_out) in o.iter_mut().enumerate() {
                let i = z * slice + j;
                let c = [j % dims[0], j / dims[0], z][axis];
                let mut g = f[i];
                let mut k = 1usize;
                while (k as u8) < g {
                    if c >= k {
                        g = g.min(f[i - k * stride].max(k as u8));
                    }
                    if c + k < dims[axis] {
                        g = g.min(f[i + k * stride].max(k as u8));
                    }
                    k += 1;
                }
                *g_out = g;
            }
        });
    out
}
