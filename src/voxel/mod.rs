//! Coloured voxel models (opaque): the model, MagicaVoxel `.vox` import ([`vox`]), the
//! compact segment format ([`segment`]), the brick occupancy grid the renderers traverse and
//! the `[[voxels]]` scene tables ([`desc`]). No GPU types live here.
//!
//! A model is a box of `dims` voxels (x east, y north, z up in its own frame, one unit per
//! voxel) holding palette indices 1..=255 (0 = empty) and, optionally, extra per-voxel
//! attribute bytes that the segment format carries (declared by their byte sizes).

pub mod desc;
pub mod segment;
pub mod skip;
pub mod vox;

pub use desc::{VoxelDesc, VoxelInstance};

use crate::{Error, Result};
use rayon::prelude::*;

/// Voxels per brick side: the coarse level of the hierarchical DDA (WGSL `VOX_BRICK`).
pub const BRICK: u32 = 8;
/// Voxels per brick.
pub const BRICK_VOXELS: usize = (BRICK * BRICK * BRICK) as usize;
/// Largest model side in voxels (a format limit: positions fit 16 bits on the GPU side).
pub const MAX_SIDE: u32 = 4096;
/// Marks an empty brick in [`Bricks::table`].
pub const EMPTY_BRICK: u32 = u32::MAX;
/// Bits of one octant's cube side in a word of [`Bricks::pool_jump`].
pub const JUMP_BITS: u32 = 4;
const JUMP_MASK: u32 = (1 << JUMP_BITS) - 1;

/// Octant `oct`'s cube side in a [`Bricks::pool_jump`] word (0 where occupied).
pub fn jump_side(word: u32, oct: usize) -> u8 {
    (word >> (JUMP_BITS * oct as u32) & JUMP_MASK) as u8
}
/// A `pool_jump` word of side 1 in every octant: plain Amanatides–Woo steps.
const PLAIN_STEPS: u32 = 0x1111_1111;
const _: () = assert!(skip::VOXEL_SKIP_CAP as u32 <= JUMP_MASK);

/// One occupied voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Voxel {
    pub pos: [u32; 3],
    /// Palette index, 1..=255.
    pub index: u8,
}

/// A voxel model. `voxels` are in canonical order (column `x + dims.x * y`, then z), with no
/// duplicates; `extra` holds `extra_stride()` bytes per voxel in the same order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VoxelModel {
    pub dims: [u32; 3],
    /// sRGB RGBA per palette index (entry 0 is unused: index 0 means empty).
    pub palette: Vec<[u8; 4]>,
    pub voxels: Vec<Voxel>,
    /// Byte size of each extra attribute (the segment header declares them).
    pub extra_sizes: Vec<u8>,
    pub extra: Vec<u8>,
}

impl VoxelModel {
    /// A model from voxels in any order; later duplicates of a position replace earlier ones.
    /// `what` names the source in errors.
    pub fn new(
        what: &str,
        dims: [u32; 3],
        palette: Vec<[u8; 4]>,
        mut voxels: Vec<Voxel>,
    ) -> Result<VoxelModel> {
        check_dims(what, dims)?;
        if palette.len() != 256 {
            return Err(Error::invalid(
                what,
                format!("palette has {} entries, need 256", palette.len()),
            ));
        }
        for v in &voxels {
            if v.index == 0 || (0..3).any(|a| v.pos[a] >= dims[a]) {
                return Err(Error::invalid(
                    what,
                    format!(
                        "voxel {:?} (palette index {}) is empty or outside the {}x{}x{} box",
                        v.pos, v.index, dims[0], dims[1], dims[2]
                    ),
                ));
            }
        }
        let key = |v: &Voxel| (v.pos[0] as u64 + dims[0] as u64 * v.pos[1] as u64, v.pos[2]);
        // Stable sort keeps the input order among duplicates; keep the last one.
        voxels.sort_by_key(key);
        let mut out: Vec<Voxel> = Vec::with_capacity(voxels.len());
        for v in voxels {
            match out.last_mut() {
                Some(last) if last.pos == v.pos => *last = v,
                _ => out.push(v),
            }
        }
        Ok(VoxelModel {
            dims,
            palette,
            voxels: out,
            extra_sizes: Vec::new(),
            extra: Vec::new(),
        })
    }

    /// Bytes of extra attributes per voxel.
    pub fn extra_stride(&self) -> usize {
        self.extra_sizes.iter().map(|&s| s as usize).sum()
    }

    /// Bytes of a dense grid of this model with one byte per voxel plus its extra attributes
    /// (the comparison the segment format's ratio is quoted against).
    pub fn dense_bytes(&self) -> u64 {
        let n = self.dims.iter().map(|&d| d as u64).product::<u64>();
        n * (1 + self.extra_stride() as u64)
    }

    /// The model with every voxel replaced by a `k`³ block of its colour (`k` >= 1), for
    /// benchmarks at a given voxel count. Extra attributes are dropped.
    pub fn upsampled(&self, k: u32) -> Result<VoxelModel> {
        let k = k.max(1);
        let dims = self.dims.map(|d| d.saturating_mul(k));
        check_dims("upsampled model", dims)?;
        let mut voxels = Vec::with_capacity(self.voxels.len() * (k * k * k) as usize);
        for v in &self.voxels {
            for z in 0..k {
                for y in 0..k {
                    for x in 0..k {
                        voxels.push(Voxel {
                            pos: [v.pos[0] * k + x, v.pos[1] * k + y, v.pos[2] * k + z],
                            index: v.index,
                        });
                    }
                }
            }
        }
        VoxelModel::new("upsampled model", dims, self.palette.clone(), voxels)
    }

    /// Dense palette-index grid, index `x + dx (y + dy z)`.
    pub fn dense(&self) -> Vec<u8> {
        let [dx, dy, dz] = self.dims.map(|d| d as usize);
        let mut g = vec![0u8; dx * dy * dz];
        for v in &self.voxels {
            let [x, y, z] = v.pos.map(|c| c as usize);
            g[x + dx * (y + dy * z)] = v.index;
        }
        g
    }

    /// The brick occupancy grid and brick pool the DDA traverses, with the empty-space
    /// distances of its jumps (`skip`).
    pub fn bricks(&self) -> Bricks {
        let bd = self.dims.map(|d| d.div_ceil(BRICK));
        let (table, pool) = self.brick_pool(bd);
        let occupied: Vec<bool> = table.iter().map(|&b| b != EMPTY_BRICK).collect();
        let brick_skip = skip::chebyshev(bd.map(|d| d as usize), &occupied, skip::BRICK_SKIP_CAP);
        let symmetric_gap = skip::brick_gaps(bd, &table, &pool, &brick_skip);
        let mut brick_gap: Vec<[u16; 8]> = symmetric_gap.iter().map(|&g| [g; 8]).collect();
        // Octant cubes on a dense grid where it is small enough: voxel-level jumps (else 1,
        // plain steps) and the bricks' one-sided gaps (else the symmetric ones).
        let mut pool_jump: Vec<u32> = pool
            .iter()
            .map(|&i| if i == 0 { PLAIN_STEPS } else { 0 })
            .collect();
        let cells: u64 = self.dims.iter().map(|&d| d as u64).product();
        if cells <= skip::DENSE_LIMIT {
            let octants = self.octant_skips(bd, &table, pool.len(), &symmetric_gap, cells);
            for (i, w) in pool_jump.iter_mut().enumerate() {
                *w = (0..8).fold(0, |w, oct| {
                    w | (octants[oct].0[i] as u32) << (JUMP_BITS * oct as u32)
                });
            }
            for (bi, g) in brick_gap.iter_mut().enumerate() {
                *g = std::array::from_fn(|oct| octants[oct].1[bi]);
            }
        }
        Bricks {
            dims: self.dims,
            brick_dims: bd,
            table,
            pool,
            pool_jump,
            brick_skip,
            brick_gap,
        }
    }

    /// The brick table (`bd` bricks) and the pool of occupied bricks' blocks, in the order
    /// the voxels first reach them.
    fn brick_pool(&self, bd: [u32; 3]) -> (Vec<u32>, Vec<u8>) {
        let mut table = vec![EMPTY_BRICK; bd.iter().map(|&d| d as usize).product()];
        let mut pool: Vec<u8> = Vec::new();
        for v in &self.voxels {
            let b = v.pos.map(|c| c / BRICK);
            let bi = (b[0] + bd[0] * (b[1] + bd[1] * b[2])) as usize;
            if table[bi] == EMPTY_BRICK {
                table[bi] = (pool.len() / BRICK_VOXELS) as u32;
                pool.resize(pool.len() + BRICK_VOXELS, 0);
            }
            let l = v.pos.map(|c| c % BRICK);
            pool[table[bi] as usize * BRICK_VOXELS
                + (l[0] + BRICK * (l[1] + BRICK * l[2])) as usize] = v.index;
        }
        (table, pool)
    }

    /// Per octant of ray directions, from the octant cubes on the dense grid: the jump code
    /// of each pool voxel and the one-sided gap of each brick (in parallel over the octants
    /// up to [`skip::PARALLEL_LIMIT`] cells).
    fn octant_skips(
        &self,
        bd: [u32; 3],
        table: &[u32],
        pool_len: usize,
        symmetric_gap: &[u16],
        cells: u64,
    ) -> Vec<(Vec<u8>, Vec<u16>)> {
        let occupied: Vec<bool> = self.dense().iter().map(|&i| i != 0).collect();
        let dense_index = self.dense_index(bd, table, pool_len);
        let octant =
            |oct: usize| self.octant_skip(oct, bd, table, &occupied, &dense_index, symmetric_gap);
        if cells <= skip::PARALLEL_LIMIT {
            (0..8).into_par_iter().map(octant).collect()
        } else {
            (0..8).map(octant).collect()
        }
    }

    /// Per pool voxel inside the model, its index in the dense grid (`u32::MAX` outside).
    fn dense_index(&self, bd: [u32; 3], table: &[u32], pool_len: usize) -> Vec<u32> {
        let [dx, dy, _] = self.dims.map(|d| d as usize);
        let mut dense_index = vec![u32::MAX; pool_len];
        for (bi, &block) in table.iter().enumerate() {
            if block == EMPTY_BRICK {
                continue;
            }
            let b = brick_coords(bd, bi);
            for li in 0..BRICK_VOXELS {
                let l = [li % 8, (li / 8) % 8, li / 64];
                let p: [usize; 3] = std::array::from_fn(|a| b[a] * BRICK as usize + l[a]);
                if (0..3).all(|a| p[a] < self.dims[a] as usize) {
                    dense_index[block as usize * BRICK_VOXELS + li] =
                        (p[0] + dx * (p[1] + dy * p[2])) as u32;
                }
            }
        }
        dense_index
    }

    /// Octant `oct`'s jump codes per pool voxel and gaps per brick (at least the symmetric
    /// ones).
    fn octant_skip(
        &self,
        oct: usize,
        bd: [u32; 3],
        table: &[u32],
        occupied: &[bool],
        dense_index: &[u32],
        symmetric_gap: &[u16],
    ) -> (Vec<u8>, Vec<u16>) {
        let f = skip::octant_cubes(
            self.dims.map(|d| d as usize),
            occupied,
            oct,
            skip::GAP_CUBE_CAP,
        );
        let codes = dense_index
            .iter()
            .map(|&k| {
                if k == u32::MAX {
                    1
                } else {
                    f[k as usize].min(skip::VOXEL_SKIP_CAP)
                }
            })
            .collect();
        // The brick's box grown by g - 1 voxels towards the octant is the cube of
        // side 8 + g - 1 at that corner.
        let gaps = (0..table.len())
            .map(|bi| {
                if table[bi] != EMPTY_BRICK {
                    return 0;
                }
                let side = f[self.brick_corner(bd, bi, oct)] as u16;
                (side + 1)
                    .saturating_sub(BRICK as u16)
                    .max(symmetric_gap[bi])
            })
            .collect();
        (codes, gaps)
    }

    /// Dense-grid index of brick `bi`'s corner voxel facing away from octant `oct` (the last
    /// one inside the model).
    fn brick_corner(&self, bd: [u32; 3], bi: usize, oct: usize) -> usize {
        let [dx, dy, _] = self.dims.map(|d| d as usize);
        let b = brick_coords(bd, bi);
        let p: [usize; 3] = std::array::from_fn(|a| {
            let lo = b[a] * BRICK as usize;
            if oct >> a & 1 != 0 {
                lo
            } else {
                (lo + BRICK as usize - 1).min(self.dims[a] as usize - 1)
            }
        });
        p[0] + dx * (p[1] + dy * p[2])
    }
}

/// Brick coordinates of brick index `bi` in a grid of `bd` bricks.
fn brick_coords(bd: [u32; 3], bi: usize) -> [usize; 3] {
    [
        bi % bd[0] as usize,
        (bi / bd[0] as usize) % bd[1] as usize,
        bi / (bd[0] * bd[1]) as usize,
    ]
}

/// Two-level occupancy: per brick of [`BRICK`]³ voxels, the index of its block in `pool`
/// ([`EMPTY_BRICK`] if it holds no voxel); each block holds the palette indices of its voxels,
/// local index `x + 8 (y + 8 z)`. With each, the empty space the DDA jumps over ([`skip`]):
/// per pool voxel the empty cubes ahead of it towards each octant (`pool_jump`), per brick
/// its distance in bricks to the nearest occupied one (`brick_skip`) and, towards each
/// octant, how far in voxels its box can grow and stay empty (`brick_gap`).
#[derive(Clone, Debug)]
pub struct Bricks {
    pub dims: [u32; 3],
    pub brick_dims: [u32; 3],
    pub table: Vec<u32>,
    pub pool: Vec<u8>,
    /// Per pool voxel, 0 where occupied, else for each octant `o` of ray directions
    /// ([`skip::octant`]) the side (1..=[`skip::VOXEL_SKIP_CAP`]) of the largest empty cube
    /// with the voxel as its corner towards that octant, in bits `4 o .. 4 o + 4`
    /// ([`skip::octant_cubes`]).
    pub pool_jump: Vec<u32>,
    /// Per brick, 0 where occupied, else its L∞ distance in bricks to the nearest occupied
    /// one ([`skip::chebyshev`]).
    pub brick_skip: Vec<u8>,
    /// Per brick and octant `o` of ray directions ([`skip::octant`]), 0 where occupied, else
    /// `g >= 1` such that the brick's box grown by `g - 1` voxels towards the octant (along
    /// axis `a` towards + where bit `a` of `o` is set, else towards −) holds no voxel: at least
    /// the symmetric gap of [`skip::brick_gaps`], more where the octant cube at the brick's
    /// back corner ([`skip::octant_cubes`]) reaches further.
    pub brick_gap: Vec<[u16; 8]>,
}

impl Bricks {
    /// Palette index of voxel `p` (0 = empty or outside).
    pub fn get(&self, p: [i64; 3]) -> u8 {
        if (0..3).any(|a| p[a] < 0 || p[a] >= self.dims[a] as i64) {
            return 0;
        }
        let p = p.map(|c| c as u32);
        let b = self.brick(p.map(|c| c / BRICK));
        if b == EMPTY_BRICK {
            return 0;
        }
        let l = p.map(|c| c % BRICK);
        self.pool[b as usize * BRICK_VOXELS + (l[0] + BRICK * (l[1] + BRICK * l[2])) as usize]
    }

    /// Side of the empty cube towards octant `oct` at voxel `p` inside an occupied brick
    /// (`block`, in range; 0 where occupied).
    pub fn voxel_jump(&self, block: u32, p: [i64; 3], oct: usize) -> u8 {
        let l = p.map(|c| c.rem_euclid(BRICK as i64) as u32);
        jump_side(
            self.pool_jump
                [block as usize * BRICK_VOXELS + (l[0] + BRICK * (l[1] + BRICK * l[2])) as usize],
            oct,
        )
    }

    /// Empty-space distance of brick `b` (in range; 0 where occupied).
    pub fn brick_skip(&self, b: [u32; 3]) -> u8 {
        let bd = self.brick_dims;
        self.brick_skip[(b[0] + bd[0] * (b[1] + bd[1] * b[2])) as usize]
    }

    /// Gap in voxels of brick `b` towards octant `oct` (in range; 0 where occupied).
    pub fn brick_gap(&self, b: [u32; 3], oct: usize) -> u16 {
        let bd = self.brick_dims;
        self.brick_gap[(b[0] + bd[0] * (b[1] + bd[1] * b[2])) as usize][oct]
    }

    /// Pool block of brick `b` (in range).
    pub fn brick(&self, b: [u32; 3]) -> u32 {
        let bd = self.brick_dims;
        self.table[(b[0] + bd[0] * (b[1] + bd[1] * b[2])) as usize]
    }

    /// Occupied bricks.
    pub fn occupied(&self) -> usize {
        self.pool.len() / BRICK_VOXELS
    }
}

/// Estimated peak memory of a model of `dims` with `voxels` voxels once loaded and turned
/// into its brick grid ([`VoxelModel::bricks`]): the voxel list, the dense grids of the
/// octant jumps (up to [`skip::DENSE_LIMIT`] cells), about 32 bytes of tables per brick and,
/// per occupied brick, its pool and jump codes. Loaders check it against the memory budget.
pub(crate) fn model_memory(dims: [u32; 3], voxels: u64) -> u64 {
    let cells: u64 = dims.iter().map(|&d| d as u64).product();
    let bricks: u64 = dims.iter().map(|&d| d.div_ceil(BRICK) as u64).product();
    let occupied = voxels.min(bricks);
    cells
        .min(skip::DENSE_LIMIT)
        .saturating_mul(4)
        .saturating_add(bricks.saturating_mul(32))
        .saturating_add(occupied.saturating_mul(BRICK_VOXELS as u64 * 5))
        .saturating_add(voxels.saturating_mul(48))
}

pub(crate) fn check_dims(what: &str, dims: [u32; 3]) -> Result<()> {
    if dims.iter().any(|&d| d == 0 || d > MAX_SIDE) {
        return Err(Error::invalid(
            what,
            format!(
                "model size {}x{}x{} voxels: every side must be 1..={MAX_SIDE}",
                dims[0], dims[1], dims[2]
            ),
        ));
    }
    Ok(())
}
