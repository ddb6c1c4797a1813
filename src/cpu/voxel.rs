//! Voxel models on the CPU (f64): the hierarchical DDA the GPU pass runs step for step — a
//! ray clipped to the model box walks the brick grid (8³ voxels per brick) by Amanatides–Woo,
//! and inside each occupied brick walks its voxels the same way, jumping over empty space by
//! the distances of `voxel::skip` (out of a box of empty cells ahead of the ray, towards its
//! octant: the current brick grown by its gap, or the empty cube at the current voxel) —
//! plus a brute-force oracle
//! (a slab test against every voxel) and scene helpers (nearest hit over instances, shadow
//! query). Ray distances are in metres throughout: the ray is moved into voxel units rigidly
//! scaled, so `t` is unchanged.
//!
//! Cells are stepped by integer index and exit axis: the cell beyond the exit face is exact
//! along the exit axis; along the others a jump takes the exit point's cell clamped into the
//! cube it leaves (a plain step's cube is the cell itself, so nothing is floored there), and a
//! ray entering a brick starts at the entry point's voxel clamped into the brick.

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
    let iv = DVec3::new(inv(d.x), inv(d.y), inv(d.z));
    let (t0, t1, mut axis) = clip_to_box(b, o, iv, t_min, t_max)?;
    let step = [d.x, d.y, d.z].map(|v| if v >= 0.0 { 1i64 } else { -1 });
    let oct = crate::voxel::skip::octant([d.x, d.y, d.z]);
    let bd = b.brick_dims.map(|v| v as i64);
    let s = BRICK as i64;
    let p = o + d * t0;
    // Brick level (`cell` in bricks) or voxel level inside `brick` (`cell` in voxels).
    let mut level = 1u32;
    let mut cell = [0, 1, 2].map(|a| ((p[a] / s as f64).floor() as i64).clamp(0, bd[a] - 1));
    let mut brick = cell;
    let mut block = 0u32;
    let mut t = t0;
    let mut steps = 0u32;
    loop {
        steps += 1;
        if steps > 1_000_000 {
            return None;
        }
        if level == 1 {
            let entry = b.brick(cell.map(|c| c as u32));
            if entry != EMPTY_BRICK {
                // Into the brick, as a step of its own that does not move: its voxel at the
                // current point.
                level = 0;
                brick = cell;
                block = entry;
                let q = o + d * t;
                cell = [0, 1, 2]
                    .map(|a| (q[a].floor() as i64).clamp(brick[a] * s, brick[a] * s + s - 1));
                continue;
            }
        }
        // A box of voxels `[lo, hi)` holding the current cell, known to be empty, grown from the
        // cell by `ext` voxels towards the ray's octant (`voxel::skip`): a voxel to the empty
        // cube at its corner, a brick by its gap.
        let (base, size, ext) = if level == 0 {
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
            (cell, 1, b.voxel_jump(block, cell, oct) as i64 - 1)
        } else {
            let gap = b.brick_gap(cell.map(|c| c as u32), oct) as i64;
            (cell.map(|c| c * s), s, gap - 1)
        };
        let lo = [0, 1, 2].map(|a| base[a] - if step[a] > 0 { 0 } else { ext });
        let hi = [0, 1, 2].map(|a| base[a] + size + if step[a] > 0 { ext } else { 0 });
        let (t_exit, exit_axis) = exit_face(o, iv, step, lo, hi);
        t = t_exit;
        axis = exit_axis;
        if t > t1 {
            return None;
        }
        let next = beyond_exit(o + d * t, exit_axis, step, lo, hi);
        let next_brick = next.map(|c| c.div_euclid(s));
        if level == 0 && next_brick == brick {
            cell = next;
        } else {
            level = 1;
            cell = next_brick;
            if (0..3).any(|a| cell[a] < 0 || cell[a] >= bd[a]) {
                return None;
            }
        }
    }
}

/// The ray `o + t d` (`iv` = 1/d per axis) clipped to the model box and to `[t_min, t_max]`:
/// entry and exit distances and the entry axis (3 = it starts at `t_min`, inside), or `None`
/// when it misses.
#[inline]
fn clip_to_box(
    b: &Bricks,
    o: DVec3,
    iv: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, f64, usize)> {
    let dims = DVec3::new(b.dims[0] as f64, b.dims[1] as f64, b.dims[2] as f64);
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
    Some((t0, t1, axis))
}

/// Where the ray leaves the cube `[lo, hi)` through its face of exit (x before y before z on
/// ties): the distance and the exit axis.
#[inline]
fn exit_face(o: DVec3, iv: DVec3, step: [i64; 3], lo: [i64; 3], hi: [i64; 3]) -> (f64, usize) {
    let mut t_exit = BIG;
    let mut exit_axis = 0;
    for a in 0..3 {
        let edge = if step[a] > 0 { hi[a] } else { lo[a] };
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
    (t_exit, exit_axis)
}

/// The voxel beyond the exit face of the cube `[lo, hi)` at the exit point `q`; along the
/// other axes, the one the exit point lies in (clamped into the cube).
#[inline]
fn beyond_exit(q: DVec3, exit_axis: usize, step: [i64; 3], lo: [i64; 3], hi: [i64; 3]) -> [i64; 3] {
    [0, 1, 2].map(|a| {
        if a == exit_axis {
            if step[a] > 0 {
                hi[a]
            } else {
                lo[a] - 1
            }
        } else {
            (q[a].floor() as i64).clamp(lo[a], hi[a] - 1)
        }
    })
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

/// A rectangle of pixels, `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl PixelRect {
    /// The whole `width` x `height` image.
    pub fn full(width: u32, height: u32) -> PixelRect {
        PixelRect {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
    }

    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    pub fn area(&self) -> u64 {
        self.width() as u64 * self.height() as u64
    }

    pub fn contains(&self, x: u32, y: u32) -> bool {
        (self.x0..self.x1).contains(&x) && (self.y0..self.y1).contains(&y)
    }

    fn overlaps(&self, o: &PixelRect) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }

    fn union(&self, o: &PixelRect) -> PixelRect {
        PixelRect {
            x0: self.x0.min(o.x0),
            y0: self.y0.min(o.y0),
            x1: self.x1.max(o.x1),
            y1: self.y1.max(o.y1),
        }
    }
}

/// Pixels of the pinhole camera `cam` whose centre rays can meet the convex hull of `points`
/// (world): the bounding rectangle of their projections, widened by one pixel each way for
/// the f32 ray directions of the GPU; the whole image when a point lies behind the eye or
/// within a millimetre of its plane (the projection of the hull is unbounded there). `None`
/// when the rectangle misses the image.
///
/// A convex body entirely in front of the eye projects to the convex hull of its vertices'
/// projections, so a ray through a pixel centre outside the rectangle misses it.
pub fn covering_rect(cam: &crate::scene::Camera, points: &[DVec3]) -> Option<PixelRect> {
    let full = PixelRect::full(cam.width, cam.height);
    let rot_t = cam.rotation().transpose();
    let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for &p in points {
        if !p.is_finite() || (rot_t * (p - cam.pose.position)).z <= 1e-3 {
            return Some(full);
        }
        let Some((u, v)) = cam.project(p) else {
            return Some(full);
        };
        (u0, v0, u1, v1) = (u0.min(u), v0.min(v), u1.max(u), v1.max(v));
    }
    if points.is_empty() {
        return None;
    }
    // Pixel px's centre is at px + 0.5: the centres within [u0, u1] are
    // ceil(u0 - 0.5) ..= floor(u1 - 0.5); one pixel more each way.
    let lo = |c: f64| (c - 0.5).ceil() - 1.0;
    let hi = |c: f64| (c - 0.5).floor() + 2.0;
    let clamp = |c: f64, max: u32| c.clamp(0.0, max as f64) as u32;
    let r = PixelRect {
        x0: clamp(lo(u0), cam.width),
        y0: clamp(lo(v0), cam.height),
        x1: clamp(hi(u1), cam.width),
        y1: clamp(hi(v1), cam.height),
    };
    (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
}

/// A rectangle of pixels and the voxel instances drawn over it (bit `k` = instance `k`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InstanceRect {
    pub rect: PixelRect,
    pub instances: u64,
}

impl InstanceRect {
    /// The whole `width` x `height` image for every one of `count` instances.
    pub fn full(width: u32, height: u32, count: usize) -> InstanceRect {
        InstanceRect {
            rect: PixelRect::full(width, height),
            instances: all_instances(count),
        }
    }
}

/// The mask of instances `0..count` (at most 64).
pub fn all_instances(count: usize) -> u64 {
    debug_assert!(count <= 64);
    if count >= 64 {
        u64::MAX
    } else {
        (1u64 << count) - 1
    }
}

/// Rectangles covering every pixel in a set of rectangles, none overlapping another (each
/// overlapping group replaced by its bounding rectangle, drawn for the union of their
/// instances), so no pixel is drawn twice and each pixel runs only the instances whose own
/// rectangle its group overlaps.
pub fn merge_rects(mut rects: Vec<InstanceRect>) -> Vec<InstanceRect> {
    'again: loop {
        for i in 0..rects.len() {
            for j in i + 1..rects.len() {
                if rects[i].rect.overlaps(&rects[j].rect) {
                    let u = InstanceRect {
                        rect: rects[i].rect.union(&rects[j].rect),
                        instances: rects[i].instances | rects[j].instances,
                    };
                    rects.swap_remove(j);
                    rects[i] = u;
                    continue 'again;
                }
            }
        }
        return rects;
    }
}

/// Most rectangles a pass draws for `count` instances ([`partition_rects`] beyond this falls
/// back to [`merge_rects`], which never gives more than `count`).
pub fn max_rects(count: usize) -> usize {
    16 * count.max(1) + 4
}

/// The union of `rects`, cut into rectangles that do not overlap, each drawn for exactly the
/// instances whose own rectangles hold it: cells of the grid of all rectangle edges, runs of
/// equal cells in a row joined, then equal runs in consecutive rows. Unlike [`merge_rects`]
/// no pixel outside every rectangle is drawn and no pixel runs an instance whose rectangle
/// does not hold it.
pub fn partition_rects(rects: &[InstanceRect]) -> Vec<InstanceRect> {
    let edges = |f: fn(&PixelRect) -> [u32; 2]| {
        let mut e: Vec<u32> = rects.iter().flat_map(|r| f(&r.rect)).collect();
        e.sort_unstable();
        e.dedup();
        e
    };
    let xs = edges(|r| [r.x0, r.x1]);
    let ys = edges(|r| [r.y0, r.y1]);
    let mut out: Vec<InstanceRect> = Vec::new();
    // Runs of the previous row band, open to extension downwards.
    let mut open: Vec<usize> = Vec::new();
    let mut masks = vec![0u64; xs.len()];
    for band in ys.windows(2) {
        let (y0, y1) = (band[0], band[1]);
        // Each column's mask: the rectangles across this band, OR-ed over their columns.
        masks.fill(0);
        for r in rects.iter().filter(|r| r.rect.y0 <= y0 && y0 < r.rect.y1) {
            let i0 = xs.partition_point(|&x| x < r.rect.x0);
            let i1 = xs.partition_point(|&x| x < r.rect.x1);
            masks[i0..i1].iter_mut().for_each(|m| *m |= r.instances);
        }
        let mut runs: Vec<InstanceRect> = Vec::new();
        for (col, &mask) in xs.windows(2).zip(&masks) {
            let (x0, x1) = (col[0], col[1]);
            match runs.last_mut() {
                Some(last) if last.instances == mask && last.rect.x1 == x0 => last.rect.x1 = x1,
                _ if mask != 0 => runs.push(InstanceRect {
                    rect: PixelRect { x0, y0, x1, y1 },
                    instances: mask,
                }),
                _ => {}
            }
        }
        let mut next_open = Vec::new();
        for run in runs {
            let above = open.iter().copied().find(|&i| {
                let a = &out[i];
                a.instances == run.instances
                    && a.rect.x0 == run.rect.x0
                    && a.rect.x1 == run.rect.x1
                    && a.rect.y1 == y0
            });
            match above {
                Some(i) => {
                    out[i].rect.y1 = y1;
                    next_open.push(i);
                }
                None => {
                    next_open.push(out.len());
                    out.push(run);
                }
            }
        }
        open = next_open;
    }
    out
}

/// Slabs of z per model whose occupied bounding boxes give its screen rectangles.
pub const COVER_SLABS: u32 = 4;

/// Per instance, the boxes (voxel units) its screen rectangles are taken from: the bounding
/// boxes of its occupied voxels in [`COVER_SLABS`] slabs (`VoxelInstance::occupied_slabs`).
/// The renderer computes them once per upload.
pub fn cover_boxes(instances: &[VoxelInstance]) -> Vec<Vec<[DVec3; 2]>> {
    instances
        .iter()
        .map(|i| i.occupied_slabs(COVER_SLABS))
        .collect()
}

/// Each instance's rectangles (from `cover` of each of its boxes' world corners),
/// partitioned ([`partition_rects`]), or merged where there are more than
/// [`PARTITION_LIMIT`] of them or the partition would need more than [`max_rects`] draws.
fn instance_rects(
    instances: &[VoxelInstance],
    boxes: &[Vec<[DVec3; 2]>],
    cover: impl Fn([DVec3; 8]) -> Option<PixelRect>,
) -> Vec<InstanceRect> {
    let own: Vec<InstanceRect> = instances
        .iter()
        .zip(boxes)
        .enumerate()
        .flat_map(|(k, (i, b))| {
            b.iter()
                .filter_map(|&b| cover(i.local_box_corners(b)))
                .map(move |rect| InstanceRect {
                    rect,
                    instances: 1 << k,
                })
                .collect::<Vec<_>>()
        })
        .collect();
    // The partition costs up to (2 n)² cells times n rectangles: bounded to stay well under a
    // millisecond per pass.
    if own.len() <= PARTITION_LIMIT {
        let parts = partition_rects(&own);
        if parts.len() <= max_rects(instances.len()) {
            return parts;
        }
    }
    merge_rects(own)
}

/// Most rectangles `instance_rects` partitions; more are merged.
pub const PARTITION_LIMIT: usize = 64;

/// Pixels the voxel models' primary rays can hit, for a pinhole camera: the covering
/// rectangles of the models' occupied boxes ([`cover_boxes`]), partitioned, each with the
/// instances it can show.
pub fn primary_rects(
    instances: &[VoxelInstance],
    boxes: &[Vec<[DVec3; 2]>],
    cam: &crate::scene::Camera,
) -> Vec<InstanceRect> {
    instance_rects(instances, boxes, |c| covering_rect(cam, &c))
}

/// Pixels whose visible surface can lie in a voxel model's shadow, for a pinhole camera: the
/// covering rectangles of each model's occupied boxes ([`cover_boxes`]) swept away from the
/// sun down to `z_floor` (no surface lies lower), partitioned. The whole image when the sun is
/// within 0.5° of the horizon (the sweep would be unbounded).
pub fn shadow_rects(
    instances: &[VoxelInstance],
    boxes: &[Vec<[DVec3; 2]>],
    cam: &crate::scene::Camera,
    to_sun: DVec3,
    z_floor: f64,
) -> Vec<InstanceRect> {
    if to_sun.z < 0.5f64.to_radians().sin() {
        return vec![InstanceRect::full(cam.width, cam.height, instances.len())];
    }
    instance_rects(instances, boxes, |c| {
        let mut pts = c.to_vec();
        pts.extend(
            c.iter()
                .map(|&p| p - to_sun * ((p.z - z_floor).max(0.0) / to_sun.z)),
        );
        covering_rect(cam, &pts)
    })
}

/// The voxel models as the eye at `eye` sees them on the curved earth: each lowered rigidly by
/// the drop below the eye's tangent plane at its bottom centre; copies on a flat terrain. The
/// GPU renderer does the same per frame.
pub fn lowered(
    terrain: &crate::terrain::Terrain,
    eye: DVec3,
    instances: &[VoxelInstance],
) -> Vec<VoxelInstance> {
    let curv = terrain.curvature(eye);
    instances
        .iter()
        .map(|m| m.translated(terrain.curved_offset(&curv, m.position)))
        .collect()
}
