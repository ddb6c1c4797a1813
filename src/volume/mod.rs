//! Density volumes: a 3-D scalar grid placed in the world, its classification through a
//! transfer function, and the data both renderers sample.
//!
//! * [`DensityGrid`]: the scalar field, quantised to 8 bits (`0..=255` maps linearly onto
//!   `value_range` in the data's own units), with its voxel spacing in metres. Loaded from
//!   NRRD ([`nrrd`]), raw + TOML header ([`raw`]) or generated ([`procedural`]).
//! * [`VolumeTexture`]: what is sampled: per voxel the density and its gradient direction
//!   (RGBA8: `r` density, `gba` gradient), with box-filtered mip levels. The GPU uploads these
//!   bytes as they are and the CPU reference samples the same bytes, so both integrate the
//!   same field.
//! * [`BrickGrid`]: min/max density per brick of `BRICK³` voxels (with the one-voxel border
//!   trilinear filtering reads), classified through the transfer function into an occupancy
//!   bit per brick for empty-space skipping.
//! * [`transfer`]: piecewise-linear colour and opacity per density, presets, the 256-entry
//!   table both renderers interpolate.
//! * [`shadow`]: the sun's transmittance through the volume itself, per voxel (self-shadowing).
//! * [`desc`]: the `[[volumes]]` scene table and the placed [`Volume`].

pub mod desc;
pub mod nrrd;
pub mod procedural;
pub mod raw;
pub mod shadow;
pub mod transfer;

pub use desc::{Volume, VolumeDesc, VolumeSettings};
pub use transfer::{TransferFunction, TransferTable};

use crate::{Error, Result};

/// Voxels per brick side in the empty-space-skipping grid (WGSL `VOL_BRICK`).
pub const BRICK: u32 = 8;
/// Coarsest mip level sampled (WGSL `VOL_MAX_MIP`). A level-L trilinear sample reads voxels up
/// to 1.5·2^L away, so with one brick of dilation skipping stays exact up to level 2.
pub const MAX_MIP: u32 = 2;
/// Largest accepted grid side (voxels), before any device limit.
pub const MAX_SIDE: u32 = 8192;
/// Largest accepted voxel count (its RGBA texture, 2 GiB, is what the GPU side accepts).
pub const MAX_VOXELS: u64 = 1 << 29;

/// A scalar field on a regular grid, x fastest, quantised to 8 bits.
#[derive(Clone, Debug)]
pub struct DensityGrid {
    pub dims: [u32; 3],
    /// `dims[0] * dims[1] * dims[2]` densities, x fastest, then y, then z.
    pub data: Vec<u8>,
    /// Voxel spacing in metres (x, y, z).
    pub spacing: [f64; 3],
    /// Data value of density 0 and of density 255.
    pub value_range: [f64; 2],
    /// 0 for a density field; otherwise the voxels are bit masks of this many 1-bit slices
    /// (seed 004's 4-D function: bit i set where slice `w_i` has its surface), sampled
    /// nearest, each slice classified by transfer-table entry i.
    pub slices: u32,
}

/// Checks grid dimensions; `what` names the file or table in the error.
pub(crate) fn check_dims(what: &str, dims: [u64; 3]) -> Result<[u32; 3]> {
    if dims.iter().any(|&d| d < 2 || d > MAX_SIDE as u64) {
        return Err(Error::invalid(
            what,
            format!("grid size {dims:?}: every side must be 2..={MAX_SIDE} voxels"),
        ));
    }
    let total = dims.iter().product::<u64>();
    if total > MAX_VOXELS {
        return Err(Error::invalid(
            what,
            format!(
                "grid size {dims:?}: {total} voxels, at most {MAX_VOXELS}; downsample the volume"
            ),
        ));
    }
    Ok(dims.map(|d| d as u32))
}

impl DensityGrid {
    /// Quantises `values` (x fastest) to 8 bits over `range`, or over the data's own min..max
    /// when `range` is `None`. Non-finite values are refused.
    pub fn from_values(
        what: &str,
        dims: [u32; 3],
        values: &[f64],
        spacing: [f64; 3],
        range: Option<[f64; 2]>,
    ) -> Result<DensityGrid> {
        let n = dims.iter().map(|&d| d as usize).product::<usize>();
        if values.len() != n {
            return Err(Error::invalid(
                what,
                format!(
                    "{} values for a {}x{}x{} grid ({n} expected)",
                    values.len(),
                    dims[0],
                    dims[1],
                    dims[2]
                ),
            ));
        }
        Self::from_samples(what, dims, || values.iter().copied(), spacing, range)
    }

    /// As [`DensityGrid::from_values`], from `samples()`, an iterator over the grid's values
    /// (x fastest, as many as `dims` holds) that is walked twice (range, then quantisation)
    /// so that large inputs need no f64 copy.
    pub fn from_samples<I: Iterator<Item = f64>>(
        what: &str,
        dims: [u32; 3],
        samples: impl Fn() -> I,
        spacing: [f64; 3],
        range: Option<[f64; 2]>,
    ) -> Result<DensityGrid> {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (i, v) in samples().enumerate() {
            if !v.is_finite() {
                return Err(Error::invalid(
                    what,
                    format!("value {i} is not finite ({v})"),
                ));
            }
            lo = lo.min(v);
            hi = hi.max(v);
        }
        let [lo, hi] = range.unwrap_or([lo, hi]);
        let hi = if hi > lo { hi } else { lo + 1.0 };
        let scale = 255.0 / (hi - lo);
        let data = samples()
            .map(|v| ((v - lo) * scale).round().clamp(0.0, 255.0) as u8)
            .collect();
        let g = DensityGrid {
            dims,
            data,
            spacing,
            value_range: [lo, hi],
            slices: 0,
        };
        g.check(what)?;
        Ok(g)
    }

    /// Checks sizes and spacing; `what` names the source in the error.
    pub fn check(&self, what: &str) -> Result<()> {
        check_dims(what, self.dims.map(u64::from))?;
        let n = self.dims.iter().map(|&d| d as usize).product::<usize>();
        if self.data.len() != n {
            return Err(Error::invalid(
                what,
                format!("{} densities for {n} voxels", self.data.len()),
            ));
        }
        if self.spacing.iter().any(|s| !s.is_finite() || *s <= 0.0) {
            return Err(Error::invalid(
                what,
                format!(
                    "voxel spacing must be positive metres, got {:?}",
                    self.spacing
                ),
            ));
        }
        Ok(())
    }

    pub fn voxel(&self, x: u32, y: u32, z: u32) -> u8 {
        let [nx, ny, _] = self.dims;
        self.data[(x as usize) + nx as usize * (y as usize + ny as usize * z as usize)]
    }

    /// Data value of an 8-bit density.
    pub fn value_of(&self, d: f64) -> f64 {
        self.value_range[0] + d / 255.0 * (self.value_range[1] - self.value_range[0])
    }

    /// Size of the whole grid in metres.
    pub fn extent(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.dims[i] as f64 * self.spacing[i])
    }
}

/// The gradient vector of a sampled texel's `gba` channels (normalised 0..1 as samplers return
/// them): WGSL `(s.yzw * 255.0 - 128.0) / 127.0`.
pub fn decode_gradient(gba: [f64; 3]) -> [f64; 3] {
    gba.map(|c| (c * 255.0 - 128.0) / 127.0)
}

/// One mip level of a [`VolumeTexture`].
#[derive(Clone, Debug)]
pub struct MipLevel {
    pub dims: [u32; 3],
    /// RGBA8 texels, x fastest: density, gradient x, y, z (`128 + 127·g`, see
    /// [`VolumeTexture::from_grid`]).
    pub texels: Vec<[u8; 4]>,
}

impl MipLevel {
    fn at(&self, x: i64, y: i64, z: i64) -> [u8; 4] {
        let [nx, ny, nz] = self.dims.map(i64::from);
        let (x, y, z) = (x.clamp(0, nx - 1), y.clamp(0, ny - 1), z.clamp(0, nz - 1));
        self.texels[(x + nx * (y + ny * z)) as usize]
    }

    /// Trilinear sample (clamp to edge) at texture coordinates `u` in 0..1 per axis, texel
    /// centres at `(i + 0.5) / n`, channels normalised to 0..1 (as a GPU's linear sampler).
    pub fn sample(&self, u: [f64; 3]) -> [f64; 4] {
        let p: [f64; 3] = std::array::from_fn(|i| u[i] * self.dims[i] as f64 - 0.5);
        let i0: [i64; 3] = p.map(|v| v.floor() as i64);
        let f: [f64; 3] = std::array::from_fn(|i| p[i] - i0[i] as f64);
        let mut out = [0.0; 4];
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let w: f64 = (0..3)
                .map(|i| if o[i] == 1 { f[i] } else { 1.0 - f[i] })
                .product();
            if w == 0.0 {
                continue;
            }
            let t = self.at(i0[0] + o[0], i0[1] + o[1], i0[2] + o[2]);
            for c in 0..4 {
                out[c] += w * t[c] as f64 / 255.0;
            }
        }
        out
    }
}

/// The sampled form of a density grid: density and gradient per voxel, mip levels
/// `0..=MAX_MIP` (fewer when the grid gets small).
#[derive(Clone, Debug)]
pub struct VolumeTexture {
    pub levels: Vec<MipLevel>,
}

impl VolumeTexture {
    /// Density in `r`; in `gba` the central-difference gradient `g` (density levels per voxel)
    /// compressed to `c = g / max(|g|, 8)` and stored as `128 + 127·c` (so a flat field stores
    /// an exact zero; [`decode_gradient`] inverts it): the direction is exact
    /// where the field changes by at least 8 levels per voxel and fades to zero in flat
    /// regions, so shading can blend towards isotropic there. Mip level L+1 is the rounded
    /// mean of 2x2x2 texels of level L (sizes `max(1, n / 2)` as on the GPU; the last
    /// texel of an odd side is dropped, a side of 1 repeats).
    pub fn from_grid(g: &DensityGrid) -> VolumeTexture {
        let [nx, ny, nz] = g.dims;
        let at = |x: i64, y: i64, z: i64| {
            g.voxel(
                x.clamp(0, nx as i64 - 1) as u32,
                y.clamp(0, ny as i64 - 1) as u32,
                z.clamp(0, nz as i64 - 1) as u32,
            ) as f64
        };
        let mut texels = Vec::with_capacity(g.data.len());
        for z in 0..nz as i64 {
            for y in 0..ny as i64 {
                for x in 0..nx as i64 {
                    let gr = [
                        0.5 * (at(x + 1, y, z) - at(x - 1, y, z)),
                        0.5 * (at(x, y + 1, z) - at(x, y - 1, z)),
                        0.5 * (at(x, y, z + 1) - at(x, y, z - 1)),
                    ];
                    let len = (gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2]).sqrt();
                    let s = 1.0 / len.max(8.0);
                    let enc = |v: f64| (128.0 + 127.0 * (v * s)).round().clamp(1.0, 255.0) as u8;
                    if g.slices > 0 {
                        // Bit masks have no gradient.
                        texels.push([at(x, y, z) as u8, 128, 128, 128]);
                    } else {
                        texels.push([at(x, y, z) as u8, enc(gr[0]), enc(gr[1]), enc(gr[2])]);
                    }
                }
            }
        }
        let mut levels = vec![MipLevel {
            dims: g.dims,
            texels,
        }];
        while levels.len() <= MAX_MIP as usize {
            let prev = levels.last().expect("level 0 exists");
            // Level sizes as the GPU defines them: max(1, floor(n / 2)).
            if prev.dims.iter().all(|&d| d < 2) {
                break;
            }
            let dims = prev.dims.map(|d| (d / 2).max(1));
            let mut texels = Vec::with_capacity(dims.iter().map(|&d| d as usize).product());
            for z in 0..dims[2] as i64 {
                for y in 0..dims[1] as i64 {
                    for x in 0..dims[0] as i64 {
                        let mut sum = [0u32; 4];
                        for c in 0..8 {
                            let t =
                                prev.at(2 * x + (c & 1), 2 * y + ((c >> 1) & 1), 2 * z + (c >> 2));
                            for k in 0..4 {
                                sum[k] += t[k] as u32;
                            }
                        }
                        texels.push(sum.map(|s| ((s + 4) / 8) as u8));
                    }
                }
            }
            levels.push(MipLevel { dims, texels });
        }
        VolumeTexture { levels }
    }

    /// Quadrilinear sample: trilinear in the two levels around `level` (clamped to the
    /// levels present), blended linearly.
    pub fn sample(&self, u: [f64; 3], level: f64) -> [f64; 4] {
        let top = (self.levels.len() - 1) as f64;
        let l = level.clamp(0.0, top);
        let l0 = l.floor();
        let a = self.levels[l0 as usize].sample(u);
        let f = l - l0;
        if f <= 0.0 {
            return a;
        }
        let b = self.levels[(l0 as usize + 1).min(top as usize)].sample(u);
        std::array::from_fn(|i| a[i] + (b[i] - a[i]) * f)
    }
}

/// Min/max density per brick (over the brick's voxels and a one-voxel border) and the
/// occupancy derived from a transfer table.
#[derive(Clone, Debug)]
pub struct BrickGrid {
    /// Bricks per axis.
    pub dims: [u32; 3],
    /// Per brick `[min, max]` density.
    pub range: Vec<[u8; 2]>,
}

impl BrickGrid {
    pub fn new(g: &DensityGrid) -> BrickGrid {
        let dims = g.dims.map(|d| d.div_ceil(BRICK));
        let mut range = Vec::with_capacity(dims.iter().map(|&d| d as usize).product());
        for bz in 0..dims[2] {
            for by in 0..dims[1] {
                for bx in 0..dims[0] {
                    let lo = |b: u32| (b * BRICK).saturating_sub(1);
                    let hi = |b: u32, n: u32| ((b + 1) * BRICK + 1).min(n);
                    let (mut mn, mut mx) = (255u8, 0u8);
                    for z in lo(bz)..hi(bz, g.dims[2]) {
                        for y in lo(by)..hi(by, g.dims[1]) {
                            for x in lo(bx)..hi(bx, g.dims[0]) {
                                let v = g.voxel(x, y, z);
                                mn = mn.min(v);
                                mx = mx.max(v);
                            }
                        }
                    }
                    range.push([mn, mx]);
                }
            }
        }
        BrickGrid { dims, range }
    }

    /// One word per brick: bit 0 where the transfer table gives some opacity to a density in
    /// the brick's range (exact for level-0 samples, whose trilinear support stays within the
    /// one-voxel border), bit 1 the same dilated by one brick in every direction when `dilate`
    /// (coarser mip levels read further), else a copy of bit 0.
    pub fn occupancy(&self, table: &TransferTable, dilate: bool, slices: u32) -> Vec<u32> {
        let [bx, by, bz] = self.dims;
        let idx = |x: u32, y: u32, z: u32| (x + bx * (y + by * z)) as usize;
        let own: Vec<bool> = self
            .range
            .iter()
            .map(|&[mn, mx]| {
                if slices > 0 {
                    // Bit masks: any set bit whose slice has opacity.
                    mx > 0 && table.entries[..slices as usize].iter().any(|e| e[3] > 0.0)
                } else {
                    table.any_opaque(mn, mx)
                }
            })
            .collect();
        if !dilate {
            return own.iter().map(|&o| o as u32 * 3).collect();
        }
        let mut out = vec![0u32; own.len()];
        for z in 0..bz {
            for y in 0..by {
                for x in 0..bx {
                    if !own[idx(x, y, z)] {
                        continue;
                    }
                    out[idx(x, y, z)] |= 1;
                    for dz in z.saturating_sub(1)..(z + 2).min(bz) {
                        for dy in y.saturating_sub(1)..(y + 2).min(by) {
                            for dx in x.saturating_sub(1)..(x + 2).min(bx) {
                                out[idx(dx, dy, dz)] |= 2;
                            }
                        }
                    }
                }
            }
        }
        out
    }
}
