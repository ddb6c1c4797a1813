//! Empty-space distances for the voxel DDA: for every empty voxel (and every empty brick), a
//! lower bound of its Chebyshev (L∞) distance to the nearest occupied voxel (brick). A ray in
//! an empty cell at distance `s` may jump out of the cube of cells within `s - 1` of it in one
//! step, since every cell of that cube is empty; `s = 1` is the plain Amanatides–Woo step.
//!
//! The L∞ distance transform is separable: along x, then y, then z, each cell takes
//! `min over k of max(|k|, f(cell + k))`. Distances are capped (a cap is a valid lower bound,
//! and the cap bounds the transform's cost per cell).

use super::{BRICK, BRICK_VOXELS, EMPTY_BRICK};
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

/// Bricks around an empty one searched for the voxel-exact gap ([`brick_gaps`]).
pub const GAP_REACH: i64 = 2;

/// Per brick of a brick `table` (blocks in `pool`, brick-level distances `brick_skip`), 0
/// where occupied, else a lower bound `g >= 1` of the L∞ distance in voxels from the brick's
/// box to the nearest occupied voxel: every voxel within `g - 1` of the box is empty, so a
/// ray may leave the box grown by `g - 1` voxels in one step. A brick `s` bricks from the
/// nearest occupied one has `g >= 8 (s - 1) + 1`; within [`GAP_REACH`] bricks of occupied
/// ones, `g` is the distance to the nearest occupied brick's bounding box of occupied voxels
/// (a lower bound of the distance to its voxels), which near a sparse surface is often
/// several voxels more than the brick-level bound.
pub fn brick_gaps(bd: [u32; 3], table: &[u32], pool: &[u8], brick_skip: &[u8]) -> Vec<u16> {
    let b = BRICK as i64;
    let bd = bd.map(|d| d as i64);
    let index = |c: [i64; 3]| (c[0] + bd[0] * (c[1] + bd[1] * c[2])) as usize;
    // Bounding box of each occupied brick's voxels (model voxel coordinates, inclusive).
    let bbox = |c: [i64; 3], block: u32| {
        let mut lo = [i64::MAX; 3];
        let mut hi = [i64::MIN; 3];
        let voxels = &pool[block as usize * BRICK_VOXELS..][..BRICK_VOXELS];
        for (li, _) in voxels.iter().enumerate().filter(|(_, &v)| v != 0) {
            let l = [li as i64 % b, (li as i64 / b) % b, li as i64 / (b * b)];
            for a in 0..3 {
                lo[a] = lo[a].min(c[a] * b + l[a]);
                hi[a] = hi[a].max(c[a] * b + l[a]);
            }
        }
        (lo, hi)
    };
    let cells: Vec<[i64; 3]> = (0..bd[2])
        .flat_map(|z| (0..bd[1]).flat_map(move |y| (0..bd[0]).map(move |x| [x, y, z])))
        .collect();
    let boxes: Vec<Option<([i64; 3], [i64; 3])>> = cells
        .par_iter()
        .map(|&c| {
            let block = table[index(c)];
            (block != EMPTY_BRICK).then(|| bbox(c, block))
        })
        .collect();
    cells
        .par_iter()
        .map(|&c| {
            let s = brick_skip[index(c)] as i64;
            if s == 0 {
                return 0;
            }
            if s > GAP_REACH {
                return (b * (s - 1) + 1) as u16;
            }
            // Occupied bricks beyond the reach lie at least 8 * reach + 1 voxels away.
            let mut g = b * GAP_REACH + 1;
            for dz in -GAP_REACH..=GAP_REACH {
                for dy in -GAP_REACH..=GAP_REACH {
                    for dx in -GAP_REACH..=GAP_REACH {
                        let n = [c[0] + dx, c[1] + dy, c[2] + dz];
                        if (0..3).any(|a| n[a] < 0 || n[a] >= bd[a]) {
                            continue;
                        }
                        if let Some((lo, hi)) = boxes[index(n)] {
                            let gap = (0..3)
                                .map(|a| (lo[a] - (c[a] * b + b - 1)).max(c[a] * b - hi[a]).max(0))
                                .max()
                                .unwrap_or(0);
                            g = g.min(gap);
                        }
                    }
                }
            }
            g.max(1) as u16
        })
        .collect()
}
