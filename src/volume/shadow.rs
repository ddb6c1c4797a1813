//! Volume self-shadowing: the sun's transmittance through the volume's own extinction.
//!
//! Per cell centre `p` (a cell is a voxel, or a block of voxels in large volumes, see
//! [`MAX_CELLS`]), `T(p) = exp(−∫ σ(p + λ s) dλ)` from `p` to where the ray towards the sun `s`
//! leaves the box, `σ` the classified extinction per metre. Both renderers light a sample's
//! diffuse and specular terms with `T`, read trilinearly from the same bytes (one per cell,
//! `T · 255` rounded; the GPU through a linear sampler).
//!
//! Computed by slice propagation (one pass over the grid, not one march to the box per voxel):
//! layers of voxels are taken across the axis along which the sun ray crosses layers fastest,
//! starting at the sun-facing side. A voxel's ray is followed towards the sun through the next
//! `STRIDE` layer planes (one layer spacing `Δλ` apart), the extinction bilinear in each, the
//! optical depth summed by trapezoids; there it adds the depth already computed for that layer,
//! bilinear at the point reached (falling to zero at a face the ray leaves by). A ray that
//! leaves the box before then ends with its last extinction over the rest of the way.
//!
//! Two reads of the grid: the volume's own samples (self-shadowing, and the other volumes'
//! shadows baked in by [`shadow_each_other`](super::desc::shadow_each_other)) and opaque surfaces below it
//! (`Volume::transmittance_to_sun`: this volume alone, multiplied over the volumes).

/// How far towards the sun (in voxels of the smallest spacing) a sample reads its
/// transmittance (WGSL `VOL_SHADOW_OFFSET`): a sample inside a surface's dense layer would
/// otherwise count that layer's own extinction and darken a surface facing the sun.
pub const OFFSET_VOXELS: f64 = 1.0;

use super::DensityGrid;
use super::TransferTable;
use glam::DVec3;
use rayon::prelude::*;

/// Layers a voxel's ray is followed through, sampling the extinction in each layer's plane,
/// before it takes the optical depth interpolated in the layer it reached: each interpolation
/// smooths the depth a little (most across the kinks where the face the ray leaves by
/// changes), so doing it once per `STRIDE` layers instead of once per layer keeps that error
/// `STRIDE` times smaller, for `STRIDE` extinction reads per voxel.
const STRIDE: usize = 16;

/// Most cells of a transmittance grid: larger volumes get theirs at a coarser resolution (the
/// shadow is soft and sampled filtered), which keeps the computation within about half a second
/// on two cores.
pub const MAX_CELLS: usize = 1 << 21;

/// A volume's self-shadowing: the transmittance grid (`dims` cells covering the volume's box,
/// one byte each, x fastest) for the unit direction towards the sun `sun` (volume frame).
#[derive(Clone, Debug)]
pub struct SunShadow {
    pub sun: DVec3,
    pub dims: [u32; 3],
    /// Through this volume alone: what surfaces below it read (`Volume::transmittance_to_sun`).
    pub data: Vec<u8>,
    /// Through this volume and the scene's other volumes (see [`shadow_each_other`](super::desc::shadow_each_other)): what the
    /// volume's own samples read; `None` where no other volume shadows it (`data` serves).
    pub lit: Option<Vec<u8>>,
}

impl SunShadow {
    /// The grid the volume's samples are lit with.
    pub fn lit_data(&self) -> &[u8] {
        self.lit.as_deref().unwrap_or(&self.data)
    }
}

/// The sun's transmittance through `grid` classified by `table` (extinction per metre in each
/// entry's alpha), for the unit direction towards the sun `sun` in the volume frame: per voxel,
/// or per block of 2³, 4³… voxels where the grid has more than [`MAX_CELLS`] (extinction
/// averaged over the block; the cells divide the box evenly, so where a side is not a multiple
/// of the block the blocks and the cells differ by less than a voxel).
pub fn sun_transmittance(grid: &DensityGrid, table: &TransferTable, sun: DVec3) -> SunShadow {
    let n = grid.dims.map(|d| d as usize);
    let sigma_of: Vec<f64> = table.entries.iter().map(|e| e[3] as f64).collect();
    let mut f = 1;
    let cells = |f: usize| n.iter().map(|&d| d.div_ceil(f)).product::<usize>();
    while cells(f) > MAX_CELLS {
        f *= 2;
    }
    let m = n.map(|d| d.div_ceil(f));
    let mut sigma = vec![0.0; cells(f)];
    let mut count = vec![0u32; cells(f)];
    for z in 0..n[2] {
        for y in 0..n[1] {
            for x in 0..n[0] {
                let k = x / f + m[0] * (y / f + m[1] * (z / f));
                sigma[k] += sigma_of[grid.data[x + n[0] * (y + n[1] * z)] as usize];
                count[k] += 1;
            }
        }
    }
    for (s, c) in sigma.iter_mut().zip(&count) {
        *s /= (*c).max(1) as f64;
    }
    // Cells cover the box exactly (the last ones of an axis may hold fewer voxels).
    let extent = DVec3::from(grid.extent());
    let sp = extent / DVec3::new(m[0] as f64, m[1] as f64, m[2] as f64);
    SunShadow {
        sun,
        dims: m.map(|d| d as u32),
        data: propagate(&sigma, m, sp, sun),
        lit: None,
    }
}

/// Transmittance bytes of an extinction field `sigma_cells` (`n` cells of size `sp`, x fastest)
/// for the unit direction towards the sun `sun`.
fn propagate(sigma_cells: &[f64], n: [usize; 3], sp: DVec3, sun: DVec3) -> Vec<u8> {
    // Layers across the axis `a` along which the ray crosses voxel layers fastest.
    let per_metre = (sun / sp).abs();
    let a = if per_metre.x >= per_metre.y && per_metre.x >= per_metre.z {
        0
    } else if per_metre.y >= per_metre.z {
        1
    } else {
        2
    };
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    let (na, nb, nc) = (n[a], n[b], n[c]);
    // One layer spacing along the ray, and the layer step towards the sun.
    let dl = 1.0 / per_metre[a];
    let towards: isize = if sun[a] > 0.0 { 1 } else { -1 };
    // Grid coordinates of cell (ia, ib, ic) in layer order, and its index.
    let cell = |ia: usize, ib: usize, ic: usize| -> [usize; 3] {
        let mut v = [0; 3];
        v[a] = ia;
        v[b] = ib;
        v[c] = ic;
        v
    };
    let index = |ia: usize, ib: usize, ic: usize| -> usize {
        let v = cell(ia, ib, ic);
        v[0] + n[0] * (v[1] + n[1] * v[2])
    };
    let sigma_at = |ia: usize, ib: usize, ic: usize| sigma_cells[index(ia, ib, ic)];
    let extent = sp * DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
    // Distance from p to the box boundary along the sun.
    let exit = |p: DVec3| -> f64 {
        let mut l = f64::INFINITY;
        for k in 0..3 {
            if sun[k] > 0.0 {
                l = l.min((extent[k] - p[k]) / sun[k]);
            } else if sun[k] < 0.0 {
                l = l.min(-p[k] / sun[k]);
            }
        }
        l.max(0.0)
    };
    // Per layer axis (b, c): does the sun ray leave the box through its low / high face?
    // Between such a face and the outermost voxel centres the optical depth falls linearly to
    // zero at the face, instead of staying at the outermost centre's value.
    let exits = [b, c].map(|k| (sun[k] < 0.0, sun[k] > 0.0));
    // Layers from the sun-facing side, so that the layer a ray reaches is always done.
    let layers: Vec<usize> = if towards > 0 {
        (0..na).rev().collect()
    } else {
        (0..na).collect()
    };
    let mut tau = vec![0.0f32; sigma_cells.len()];
    for &ia in &layers {
        let rows: Vec<Vec<f32>> = (0..nc)
            .into_par_iter()
            .map(|ic| {
                (0..nb)
                    .map(|ib| {
                        let v = cell(ia, ib, ic);
                        let p = DVec3::new(v[0] as f64 + 0.5, v[1] as f64 + 0.5, v[2] as f64 + 0.5)
                            * sp;
                        let mut sigma_prev = sigma_at(ia, ib, ic);
                        let mut depth = 0.0;
                        for j in 1..=STRIDE {
                            let layer = ia as isize + towards * j as isize;
                            let q = p + sun * (dl * j as f64);
                            // Position of q in that layer, in voxel-centre index units.
                            let qb = q[b] / sp[b] - 0.5;
                            let qc = q[c] / sp[c] - 0.5;
                            let inside = layer >= 0
                                && layer < na as isize
                                && qb >= -0.5
                                && qb <= nb as f64 - 0.5
                                && qc >= -0.5
                                && qc <= nc as f64 - 0.5;
                            if !inside {
                                // The ray leaves the box before this layer.
                                let rest = exit(p) - dl * (j - 1) as f64;
                                return (depth + sigma_prev * rest.max(0.0)) as f32;
                            }
                            let (wb, sb) = axis_weights(qb, nb, exits[0]);
                            let (wc, sc) = axis_weights(qc, nc, exits[1]);
                            let layer = layer as usize;
                            let s = weighted(sb, sc, |ib, ic| sigma_at(layer, ib, ic));
                            depth += 0.5 * (sigma_prev + s) * dl;
                            sigma_prev = s;
                            if j == STRIDE {
                                depth +=
                                    weighted(wb, wc, |ib, ic| tau[index(layer, ib, ic)] as f64);
                            }
                        }
                        depth as f32
                    })
                    .collect()
            })
            .collect();
        for (ic, row) in rows.into_iter().enumerate() {
            for (ib, d) in row.into_iter().enumerate() {
                tau[index(ia, ib, ic)] = d;
            }
        }
    }
    tau.iter()
        .map(|&d| ((-(d as f64)).exp() * 255.0).round() as u8)
        .collect()
}

/// Interpolation weights along one layer axis at voxel-centre coordinate `x` (in
/// `-0.5..=n-0.5`): two (index, weight) pairs for the optical depth, whose weights fall short
/// of 1 towards a face the sun ray leaves through (`exit`: low, high), where the depth is zero;
/// and two clamped to the outermost centre for the extinction.
type Weights = [(usize, f64); 2];

fn axis_weights(x: f64, n: usize, exit: (bool, bool)) -> (Weights, Weights) {
    let last = (n - 1) as f64;
    if x < 0.0 {
        let edge = [(0, 1.0), (0, 0.0)];
        let w = if exit.0 {
            2.0 * (x + 0.5).max(0.0)
        } else {
            1.0
        };
        return ([(0, w), (0, 0.0)], edge);
    }
    if x > last {
        let edge = [(n - 1, 1.0), (n - 1, 0.0)];
        let w = if exit.1 {
            2.0 * (last + 0.5 - x).max(0.0)
        } else {
            1.0
        };
        return ([(n - 1, w), (n - 1, 0.0)], edge);
    }
    let i0 = (x.floor() as usize).min(n - 1);
    let i1 = (i0 + 1).min(n - 1);
    let f = x - i0 as f64;
    let w = [(i0, 1.0 - f), (i1, f)];
    (w, w)
}

/// A layer field interpolated with the weights of its two axes.
fn weighted(wx: Weights, wy: Weights, f: impl Fn(usize, usize) -> f64) -> f64 {
    let mut acc = 0.0;
    for (y, a) in wy {
        for (x, b) in wx {
            if a * b != 0.0 {
                acc += a * b * f(x, y);
            }
        }
    }
    acc
}

/// Trilinear sample of a per-voxel byte field (`dims`, x fastest) at texture coordinates `u`
/// (voxel centres at `(i + 0.5) / n`, clamp to edge), scaled to 0..1: how the GPU's linear
/// sampler reads the same bytes.
pub fn sample(data: &[u8], dims: [u32; 3], u: [f64; 3]) -> f64 {
    let n = dims.map(|d| d as i64);
    let mut i0 = [0i64; 3];
    let mut f = [0.0; 3];
    for k in 0..3 {
        let q = u[k] * n[k] as f64 - 0.5;
        let fl = q.floor();
        i0[k] = fl as i64;
        f[k] = q - fl;
    }
    let at = |x: i64, y: i64, z: i64| -> f64 {
        let x = x.clamp(0, n[0] - 1) as usize;
        let y = y.clamp(0, n[1] - 1) as usize;
        let z = z.clamp(0, n[2] - 1) as usize;
        data[x + n[0] as usize * (y + n[1] as usize * z)] as f64
    };
    let mut acc = 0.0;
    for dz in 0..2 {
        for dy in 0..2 {
            for dx in 0..2 {
                let w = (if dx == 1 { f[0] } else { 1.0 - f[0] })
                    * (if dy == 1 { f[1] } else { 1.0 - f[1] })
                    * (if dz == 1 { f[2] } else { 1.0 - f[2] });
                acc += w * at(i0[0] + dx, i0[1] + dy, i0[2] + dz);
            }
        }
    }
    acc / 255.0
}
