//! Procedural fields: cumulus-like cloud banks (fBm value noise shaped by a vertical profile),
//! a smoke column, and seed 004's 4-D function `g(x, y, z, w)` as `slices` 1-bit grids (bit i
//! of a voxel set where the surface `g(·, w_i) = 0` passes: `0 < g < POLE` there and
//! `-POLE < g ≤ 0` at a face neighbour, which leaves out `tan`'s poles), each slice drawn in
//! its own colour. Deterministic: the same parameters
//! give the same bytes.

use super::DensityGrid;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// `procedural = { kind = "clouds", size = [128, 128, 32], seed = 7, coverage = 0.5, feature = 32 }`
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProceduralVolume {
    /// `"clouds"` (flat-bottomed puffs) or `"smoke"` (a soft column).
    pub kind: String,
    /// Grid size in voxels.
    pub size: [u32; 3],
    #[serde(default)]
    pub seed: u32,
    /// Fraction of the sky covered, 0..1 (clouds).
    #[serde(default = "half")]
    pub coverage: f64,
    /// Size of the largest features in voxels.
    #[serde(default = "feature")]
    pub feature: f64,
    /// function4d: number of w slices (1..=8).
    #[serde(default = "eight")]
    pub slices: u32,
    /// function4d: first and last w.
    #[serde(default = "w_range")]
    pub w_range: [f64; 2],
    /// function4d: the grid spans `[-half_extent, half_extent]³` of the function's domain.
    #[serde(default = "five")]
    pub half_extent: f64,
}

fn eight() -> u32 {
    8
}
fn w_range() -> [f64; 2] {
    [0.0, std::f64::consts::PI]
}
fn five() -> f64 {
    5.0
}

/// Zero crossings with |g| beyond this on either side are `tan`'s poles, not surfaces.
pub const POLE: f64 = 2.0;

/// Seed 004's example: `g = sin(x+w)·cos y + sin y·cos z·tan(z+w) + sin(z+w)·cos x`.
pub fn function4d(x: f64, y: f64, z: f64, w: f64) -> f64 {
    (x + w).sin() * y.cos() + y.sin() * z.cos() * (z + w).tan() + (z + w).sin() * x.cos()
}

fn half() -> f64 {
    0.5
}
fn feature() -> f64 {
    32.0
}

fn hash(x: i64, y: i64, z: i64, seed: u32) -> f64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (z as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
        ^ (seed as u64).wrapping_mul(0x27D4_EB2F_1656_67C5);
    h ^= h >> 31;
    h = h.wrapping_mul(0x7FB5_D329_728E_A185);
    h ^= h >> 27;
    h = h.wrapping_mul(0x81DA_DEF4_BC2D_D44D);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in 0..1.
fn value_noise(p: [f64; 3], seed: u32) -> f64 {
    let i = p.map(|v| v.floor() as i64);
    let f: [f64; 3] = std::array::from_fn(|k| {
        let t = p[k] - i[k] as f64;
        t * t * (3.0 - 2.0 * t)
    });
    let mut acc = 0.0;
    for c in 0..8 {
        let o = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
        let w: f64 = (0..3)
            .map(|k| if o[k] == 1 { f[k] } else { 1.0 - f[k] })
            .product();
        acc += w * hash(i[0] + o[0], i[1] + o[1], i[2] + o[2], seed);
    }
    acc
}

fn fbm(p: [f64; 3], seed: u32, octaves: u32) -> f64 {
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 0.5, 0.0, p);
    for o in 0..octaves {
        sum += amp * value_noise(q, seed.wrapping_add(o * 1013));
        norm += amp;
        amp *= 0.5;
        q = q.map(|v| v * 2.03);
    }
    sum / norm
}

impl ProceduralVolume {
    pub fn validate(&self, field: &str) -> Result<()> {
        super::check_dims(field, self.size.map(u64::from))?;
        if !(0.0..=1.0).contains(&self.coverage) {
            return Err(Error::invalid(
                format!("{field}.coverage"),
                format!("must be in 0..=1, got {}", self.coverage),
            ));
        }
        if !self.feature.is_finite() || self.feature < 1.0 {
            return Err(Error::invalid(
                format!("{field}.feature"),
                format!("must be ≥ 1 voxel, got {}", self.feature),
            ));
        }
        if !["clouds", "smoke", "function4d"].contains(&self.kind.as_str()) {
            return Err(Error::invalid(
                format!("{field}.kind"),
                format!(
                    "{:?}: use \"clouds\", \"smoke\" or \"function4d\"",
                    self.kind
                ),
            ));
        }
        if !(1..=8).contains(&self.slices) {
            return Err(Error::invalid(
                format!("{field}.slices"),
                format!("must be 1..=8, got {}", self.slices),
            ));
        }
        if !self.w_range.iter().all(|w| w.is_finite())
            || !self.half_extent.is_finite()
            || self.half_extent <= 0.0
        {
            return Err(Error::invalid(
                format!("{field}.w_range/half_extent"),
                "must be finite (half_extent > 0)",
            ));
        }
        Ok(())
    }

    /// Densities in 0..1 (quantised to 8 bits over that range) with spacing `spacing`.
    pub fn generate(&self, field: &str, spacing: [f64; 3]) -> Result<DensityGrid> {
        self.validate(field)?;
        if self.kind == "function4d" {
            return Ok(self.slices4d(field, spacing));
        }
        let [nx, ny, nz] = self.size;
        let n = nx as usize * ny as usize * nz as usize;
        let mut values = vec![0.0; n];
        let inv = 1.0 / self.feature;
        let seed = self.seed;
        let clouds = self.kind == "clouds";
        let cov = self.coverage;
        use rayon::prelude::*;
        values
            .par_chunks_mut(nx as usize * ny as usize)
            .enumerate()
            .for_each(|(z, slab)| {
                let h = (z as f64 + 0.5) / nz as f64;
                for y in 0..ny as usize {
                    for x in 0..nx as usize {
                        let p = [x as f64 * inv, y as f64 * inv, z as f64 * inv * 1.5];
                        let v = if clouds {
                            // Flat base, rounded tops: the profile narrows the puffs upwards.
                            let base = fbm([p[0], p[1], 0.0], seed, 4);
                            let profile = (h * 6.0).min(1.0) * (1.0 - h * h);
                            let puff = fbm(p, seed ^ 0x5bd1, 5);
                            // Fade out towards the sides so the box does not show.
                            let side = (x.min(nx as usize - 1 - x).min(y).min(ny as usize - 1 - y))
                                as f64
                                / (0.12 * nx.min(ny) as f64);
                            let fade = side.min(1.0);
                            (base - (1.0 - cov) + 0.6 * profile * puff - 0.25).max(0.0)
                                * 2.5
                                * fade
                                * fade
                        } else {
                            let cx = (x as f64 + 0.5) / nx as f64 - 0.5;
                            let cy = (y as f64 + 0.5) / ny as f64 - 0.5;
                            let r = (cx * cx + cy * cy).sqrt() / (0.15 + 0.3 * h);
                            let puff = fbm(p, seed, 5);
                            ((1.0 - r).max(0.0) * (0.4 + puff) * (1.0 - h)).max(0.0) * 1.6
                        };
                        slab[x + y * nx as usize] = v.min(1.0);
                    }
                }
            });
        DensityGrid::from_values(field, self.size, &values, spacing, Some([0.0, 1.0]))
    }
}

impl ProceduralVolume {
    /// Domain coordinate of voxel centre `i` of `n`.
    pub fn domain(&self, i: u32, n: u32) -> f64 {
        let e = self.half_extent;
        -e + (i as f64 + 0.5) / n as f64 * 2.0 * e
    }

    /// `w` of slice `i`.
    pub fn slice_w(&self, i: u32) -> f64 {
        let [w0, w1] = self.w_range;
        if self.slices > 1 {
            w0 + (w1 - w0) * i as f64 / (self.slices - 1) as f64
        } else {
            w0
        }
    }

    fn slices4d(&self, field: &str, spacing: [f64; 3]) -> DensityGrid {
        let [nx, ny, nz] = self.size;
        let (sx, sy) = (nx as usize, ny as usize);
        let n = sx * sy * nz as usize;
        use rayon::prelude::*;
        let mut bits = vec![0u8; n];
        for s in 0..self.slices {
            let w = self.slice_w(s);
            let value: Vec<f64> = (0..n)
                .into_par_iter()
                .map(|i| {
                    let (x, y, z) = (i % sx, (i / sx) % sy, i / (sx * sy));
                    function4d(
                        self.domain(x as u32, nx),
                        self.domain(y as u32, ny),
                        self.domain(z as u32, nz),
                        w,
                    )
                })
                .collect();
            bits.par_iter_mut().enumerate().for_each(|(i, b)| {
                if !(value[i] > 0.0 && value[i] < POLE) {
                    return;
                }
                let (x, y, z) = (i % sx, (i / sx) % sy, i / (sx * sy));
                let out = |dx: i64, dy: i64, dz: i64| {
                    let (a, b, c) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                    a >= 0
                        && b >= 0
                        && c >= 0
                        && a < sx as i64
                        && b < sy as i64
                        && c < nz as i64
                        && {
                            let v = value[a as usize + sx * (b as usize + sy * c as usize)];
                            v <= 0.0 && v > -POLE
                        }
                };
                if out(1, 0, 0)
                    || out(-1, 0, 0)
                    || out(0, 1, 0)
                    || out(0, -1, 0)
                    || out(0, 0, 1)
                    || out(0, 0, -1)
                {
                    *b |= 1 << s;
                }
            });
        }
        let _ = field;
        DensityGrid {
            dims: self.size,
            data: bits,
            spacing,
            value_range: [0.0, 255.0],
            slices: self.slices,
        }
    }
}
