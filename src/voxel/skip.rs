//! Empty-space distances for the voxel DDA.
//!
//! * Bricks: for every empty brick, a lower bound of its Chebyshev (L∞) distance to the
//!   nearest occupied brick ([`chebyshev`]), refined into a distance in voxels from the
//!   brick's box ([`brick_gaps`]), and further, towards each octant, by the octant cube at the
//!   brick's back corner (`Bricks::brick_gap`). A ray in an empty brick leaves the brick's box
//!   grown by that gap in one step, since every voxel in it is empty.
//! * Voxels: for every empty voxel and each of the 8 octants a ray can travel in, the side of
//!   the largest empty cube that has the voxel as its corner and extends in that octant's
//!   directions ([`octant_cubes`]). A ray travelling in that octant leaves the cube before it
//!   can meet anything, so it jumps to the cube's exit in one step. In a sparse cloud of
//!   voxels (a tree's crown) the octant ahead is empty much further than the cube all around
//!   the voxel (a ray never looks back). Side 1 is the plain Amanatides–Woo step.
//!
//! The L∞ distance transform is separable: along x, then y, then z, each cell takes
//! `min over k of max(|k|, f(cell + k))`. Distances are capped (a cap is a valid lower bound,
//! and the cap bounds the transform's cost per cell).

use super::{BRICK, BRICK_VOXELS, EMPTY_BRICK};
use rayon::prelude::*;

/// Cap of the voxel-level octant cube sides (4 bits, [`super::JUMP_BITS`]).
pub const VOXEL_SKIP_CAP: u8 = 15;
/// Cap of the octant cubes the bricks' one-sided gaps come from (one byte per voxel while
/// they are computed).
pub const GAP_CUBE_CAP: u8 = 255;
/// Cap of the brick-level distances.
pub const BRICK_SKIP_CAP: u8 = 16;
/// Largest model (in voxels) whose octant cubes are computed, on dense grids of one byte per
/// voxel; larger models step voxel by voxel inside occupied bricks (side 1) and keep the
/// bricks' symmetric gaps.
pub const DENSE_LIMIT: u64 = 1 << 27;
/// Largest model (in voxels) whose 8 octant passes run in parallel; beyond, one at a time, so
/// that a large model holds one pass's grids at once.
pub const PARALLEL_LIMIT: u64 = 1 << 24;

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

/// Octant `oct` of a ray direction: bit `a` set where its component along axis `a` is >= 0.
pub fn octant(d: [f64; 3]) -> usize {
    (0..3).filter(|&a| d[a] >= 0.0).map(|a| 1 << a).sum()
}

/// Largest empty cubes of a `dims` grid (index `x + dx (y + dy z)`) that have a cell as their
/// corner and extend along octant `oct` (bit `a` set: towards +axis `a`, else towards −):
/// 0 where `occupied`, else `min(cap, s)` with every cell `c + (±k0, ±k1, ±k2)`,
/// `0 <= k < s`, empty. Beyond the grid counts as empty (rays are clipped to it).
///
/// Dynamic programming (the 3-D largest-square recurrence): the cube of side `s` at `c` is `c`
/// and the cubes of side `s - 1` at its 7 neighbours towards the octant, so
/// `s(c) = 1 + min(s(neighbours))`, visiting cells from the octant's far corner.
pub fn octant_cubes(dims: [usize; 3], occupied: &[bool], oct: usize, cap: u8) -> Vec<u8> {
    assert_eq!(occupied.len(), dims[0] * dims[1] * dims[2]);
    // Padded by one cell of `cap` on every side, so neighbours need no bounds checks.
    let p = dims.map(|d| d + 2);
    let mut f = vec![cap; p[0] * p[1] * p[2]];
    let towards: [bool; 3] = std::array::from_fn(|a| oct >> a & 1 != 0);
    // Far side first along every axis; `step` leads from a cell to its neighbour towards
    // the octant.
    let order = |a: usize, k: usize| if towards[a] { dims[a] - 1 - k } else { k };
    let step = |a: usize, i: usize| if towards[a] { i + 1 } else { i - 1 };
    let row = |y: usize, z: usize| p[0] * (y + p[1] * z);
    // Per row, the least of the 3 neighbours in the rows already done (towards y, z and both),
    // then along the row: s = 1 + min(that at x, that at x's neighbour, s at x's neighbour).
    let mut m = vec![cap; p[0]];
    for kz in 0..dims[2] {
        let z = order(2, kz) + 1;
        for ky in 0..dims[1] {
            let y = order(1, ky) + 1;
            let (ny, nz, nyz) = (
                row(step(1, y), z),
                row(y, step(2, z)),
                row(step(1, y), step(2, z)),
            );
            for (x, m) in m.iter_mut().enumerate() {
                *m = f[ny + x].min(f[nz + x]).min(f[nyz + x]);
            }
            let cur = row(y, z);
            let occ = &occupied[dims[0] * (y - 1 + dims[1] * (z - 1))..][..dims[0]];
            for kx in 0..dims[0] {
                let x = order(0, kx) + 1;
                let n = step(0, x);
                f[cur + x] = if occ[x - 1] {
                    0
                } else {
                    m[x].min(m[n]).min(f[cur + n]).saturating_add(1).min(cap)
                };
            }
        }
    }
    let mut out = Vec::with_capacity(occupied.len());
    for z in 1..=dims[2] {
        for y in 1..=dims[1] {
            out.extend_from_slice(&f[row(y, z) + 1..][..dims[0]]);
        }
    }
    out
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
