//! Voxel models on the CPU (f64): the hierarchical DDA the GPU pass runs step for step — a
//! ray clipped to the model box walks the brick grid (8³ voxels per brick) by Amanatides–Woo,
//! and inside each occupied brick walks its voxels the same way — plus a brute-force oracle
//! (a slab test against every voxel) and scene helpers (nearest hit over instances, shadow
//! query). Ray distances are in metres throughout: the ray is moved into voxel units rigidly
//! scaled, so `t` is unchanged.
//!
//! Cells are stepped by integer index and exit axis, never by flooring positions, except where
//! a ray enters a brick (its first voxel is the entry point's, clamped into the brick).

use crate::voxel::{Bricks, VoxelInstance, VoxelModel, BRICK, EMPTY_BRICK};
use glam::DVec3;

/// A voxel hit in voxel units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxHit {
    /// Ray distance (metres when the ray direction is in voxel units per metre).
    pub t: f64,
    pub voxel: [i64; 3],
    /// Palette index.
    pub index: u8,
    /// Axis the ray entered the voxel through (0..3), 3 = the ray started inside it.
    pub axis: usize,
    /// DDA steps (bricks and voxels visited).
    pub steps: u32,
}

impl VoxHit {
    /// Outward face normal in voxel units (towards the ray's origin).
    pub fn normal(&self, d: DVec3) -> DVec3 {
        let mut n = DVec3::ZERO;
        let a = if self.axis < 3 {
            self.axis
        } else {
            // Started inside: the dominant axis.
            let ad = d.abs();
            if ad.x >= ad.y && ad.x >= ad.z {
                0
            } else if ad.y >= ad.z {
                1
            } else {
                2
            }
        };
        n[a] = if d[a] > 0.0 { -1.0 } else { 1.0 };
        n
    }
}

/// Finite stand-in for infinity (as in WGSL).
const BIG: f64 = 1.0e30;

fn inv(d: f64) -> f64 {
    if d.abs() < 1e-30 {
        BIG
    } else {
        1.0 / d
    }
}

/// Hierarchical DDA: first occupied voxel of `b` along `o + t d` with `t` in `[t_min, t_max]`
/// (`o`, `d` in voxel units).
pub fn dda(b: &Bricks, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<VoxHit> {
    let dims = DVec3::new(b.dims[0] as f64, b.dims[1] as f64, b.dims[2] as f64);
    let iv = DVec3::new(inv(d.x), inv(d.y), inv(d.z));
    let ta = (DVec3::ZERO - o) * iv;
    let tb = (dims - o) * iv;
    let lo = ta.min(tb);
    let hi = ta.max(tb);
    let mut axis = 0;
    let mut t0 = lo.x;
    if lo.y > t0 {
        t0 = lo.y;
        axis = 1;
    }
    if lo.z > t0 {
        t0 = lo.z;
        axis = 2;
    }
    let t1 = hi.x.min(hi.y).min(hi.z).min(t_max);
    if t0 < t_min {
        t0 = t_min;
        axis = 3;
    }
    if t0 > t1 {
        return None;
    }
    let step = [d.x, d.y, d.z].map(|v| if v >= 0.0 { 1i64 } else { -1 });
    let bd = b.brick_dims.map(|v| v as i64);
    let s = BRICK as i64;
    let p = o + d * t0;
    let mut level = 1u32;
    let mut cell = [0, 1, 2].map(|a| ((p[a] / s as f64).floor() as i64).clamp(0, bd[a] - 1));
    let mut brick = cell;
    let mut t = t0;
    let mut steps = 0u32;
    loop {
        steps += 1;
        if steps > 1_000_000 {
            return None;
        }
        let size = if level == 1 { s } else { 1 };
        // Exit distance of the current cell and its exit axis (x before y before z on ties).
        let mut t_exit = BIG;
        let mut exit_axis = 0;
        for a in 0..3 {
            let edge = (cell[a] + (step[a] > 0) as i64) * size;
            let te = if iv[a] == BIG {
                BIG
            } else {
                (edge as f64 - o[a]) * iv[a]
            };
            if te < t_exit {
                t_exit = te;
                exit_axis = a;
            }
        }
        if level == 1 {
            let bi = cell.map(|c| c as u32);
            if b.brick(bi) != EMPTY_BRICK {
                level = 0;
                brick = cell;
                let q = o + d * t;
                cell = [0, 1, 2]
                    .map(|a| (q[a].floor() as i64).clamp(brick[a] * s, brick[a] * s + s - 1));
                continue;
            }
        } else {
            let idx = b.get(cell);
            if idx != 0 {
                return Some(VoxHit {
                    t,
                    voxel: cell,
                    index: idx,
                    axis,
                    steps,
                });
            }
        }
        t = t_exit;
        axis = exit_axis;
        if t > t1 {
            return None;
        }
        cell[exit_axis] += step[exit_axis];
        if level == 0 && cell[exit_axis].div_euclid(s) != brick[exit_axis] {
            level = 1;
            cell = cell.map(|c| c.div_euclid(s));
        }
        if level == 1 && (cell[exit_axis] < 0 || cell[exit_axis] >= bd[exit_axis]) {
            return None;
        }
    }
}

/// The oracle: slab test of the ray against every occupied voxel of `m`, nearest entry.
pub fn brute_force(m: &VoxelModel, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<f64> {
    let iv = DVec3::new(inv(d.x), inv(d.y), inv(d.z));
    let mut best: Option<f64> = None;
    for v in &m.voxels {
        let lo_c = DVec3::new(v.pos[0] as f64, v.pos[1] as f64, v.pos[2] as f64);
        let ta = (lo_c - o) * iv;
        let tb = (lo_c + DVec3::ONE - o) * iv;
        let t0 = ta.min(tb).max_element().max(t_min);
        let t1 = ta.max(tb).min_element().min(t_max);
        if t0 <= t1 && best.is_none_or(|b| t0 < b) {
            best = Some(t0);
        }
    }
    best
}

/// Voxel models with their brick grids, ready for CPU queries.
pub struct VoxelScene {
    pub instances: Vec<VoxelInstance>,
    /// Per instance, per frame.
    pub bricks: Vec<Vec<Bricks>>,
}

/// A voxel hit in the world.
#[derive(Clone, Copy, Debug)]
pub struct SceneVoxelHit {
    pub t: f64,
    pub instance: usize,
    pub hit: VoxHit,
    /// World unit normal of the face hit.
    pub normal: DVec3,
    /// sRGB RGBA of the voxel.
    pub colour: [u8; 4],
}

impl VoxelScene {
    pub fn new(instances: Vec<VoxelInstance>) -> VoxelScene {
        let bricks = instances
            .iter()
            .map(|i| i.frames.iter().map(|f| f.bricks()).collect())
            .collect();
        VoxelScene { instances, bricks }
    }

    /// Nearest voxel hit of the world ray `o + t d` (unit `d`) in `[t_min, t_max]` at `time`.
    pub fn cast(
        &self,
        o: DVec3,
        d: DVec3,
        t_min: f64,
        t_max: f64,
        time: f64,
    ) -> Option<SceneVoxelHit> {
        let mut best: Option<SceneVoxelHit> = None;
        for (k, inst) in self.instances.iter().enumerate() {
            let frame = inst.frame_at(time);
            let far = best.map_or(t_max, |b| b.t);
            let (lo, ld) = (inst.to_local(o), inst.dir_to_local(d));
            if let Some(h) = dda(&self.bricks[k][frame], lo, ld, t_min, far) {
                if best.is_none_or(|b| h.t < b.t) {
                    best = Some(SceneVoxelHit {
                        t: h.t,
                        instance: k,
                        hit: h,
                        normal: inst.dir_to_world(h.normal(ld)),
                        colour: inst.frames[frame].palette[h.index as usize],
                    });
                }
            }
        }
        best
    }

    /// True when the ray from `p` towards the sun meets no voxel.
    pub fn clear(&self, p: DVec3, to_sun: DVec3, time: f64) -> bool {
        self.cast(p, to_sun, 0.0, f64::INFINITY, time).is_none()
    }
}

/// Offset (in voxels) a shadow ray leaves a voxel face by.
pub const SHADOW_OFFSET_VOXELS: f64 = 0.01;
