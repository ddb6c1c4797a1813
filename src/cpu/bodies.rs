//! Lines of sight against bodies placed on the earth: the CIGI entities drawn from templates
//! (`world::Instances::bodies`). Each body's shape — its template's free form or voxel model
//! — is held at the origin of the body's own east-north-up frame (metres), and a line is taken
//! into that frame through ECEF: a straight line in space stays straight, and its distances
//! are metres whatever frame the terrain's world uses.

use super::freeform::{intersect, CPU_LEVELS};
use super::voxel::dda;
use crate::colour::linear_to_srgb8;
use crate::freeform::FreeForm;
use crate::geodesy::{ecef_of, enu_basis};
use crate::voxel::{Bricks, VoxelInstance, VoxelModel};
use crate::world::{BodyShape, Instances};
use glam::{DMat3, DVec3};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// Brick tables of voxel models for their lines of sight, made once per model (a model's
/// table costs 0.3–0.4 s for the 13–14 M-cell grids of `axes.vox` and `tree.vox`) and kept
/// for the run: the models of entity templates are the same from frame to frame.
#[derive(Default)]
pub struct BrickCache {
    /// By the model's address; the model is held so that the address stays its own.
    tables: Mutex<HashMap<usize, KeptTable>>,
}

/// A model and its brick table ([`BrickCache`]).
type KeptTable = (Arc<VoxelModel>, Arc<Bricks>);

impl BrickCache {
    /// `model`'s brick table, made now if it is not kept yet.
    pub fn get(&self, model: &Arc<VoxelModel>) -> Arc<Bricks> {
        let key = Arc::as_ptr(model) as usize;
        let mut t = self.tables.lock().unwrap_or_else(|e| e.into_inner());
        let (_, bricks) = t
            .entry(key)
            .or_insert_with(|| (Arc::clone(model), Arc::new(model.bricks())));
        Arc::clone(bricks)
    }

    /// How many tables are kept.
    pub fn len(&self) -> usize {
        self.tables.lock().unwrap_or_else(|e| e.into_inner()).len()
    }

    /// Whether none is kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A body's shape at the origin of its east-north-up frame.
enum Shape {
    Object(FreeForm),
    /// The model and the frame shown (its brick table from the cache).
    Voxels {
        model: VoxelInstance,
        frame: usize,
    },
}

struct Body {
    id: u16,
    /// The entity's alpha (its surfaces' alphas are scaled by it).
    alpha: u8,
    origin: DVec3,
    /// Columns east, north, up at the origin, in ECEF.
    enu: DMat3,
    shape: Shape,
    /// Radius about the origin that holds the shape (metres).
    reach: f64,
}

/// Where a line meets a body first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyHit {
    /// The body's entity ID.
    pub id: u16,
    /// Metres along the line from its start.
    pub t: f64,
    /// ECEF position of the intersection.
    pub point: DVec3,
    /// Unit surface normal, in ECEF.
    pub normal: DVec3,
    /// The surface's sRGB colour and alpha (the surface's alpha — 255 for a free form, the
    /// palette's for a voxel — scaled by the entity's).
    pub colour: [u8; 4],
}

/// The bodies of one frame, ready for lines of sight.
#[derive(Default)]
pub struct Bodies {
    bodies: Vec<Body>,
    bricks: Arc<BrickCache>,
}

impl Bodies {
    /// The bodies of `instances` (their placements and shapes), voxel models showing the
    /// animation frame of time `time` (seconds), their brick tables from `bricks`.
    pub fn of(instances: &Instances, time: f64, bricks: &Arc<BrickCache>) -> Bodies {
        let bodies = (instances.bodies.iter())
            .filter_map(|b| {
                let p = &b.placement;
                let origin = ecef_of(p.geodetic);
                let enu = enu_basis(p.geodetic[0], p.geodetic[1]);
                let (shape, reach) = match b.shape {
                    BodyShape::Object(k) => {
                        let (_, ff) = instances.drawn.get(k)?;
                        let ff = FreeForm {
                            position: DVec3::ZERO,
                            ..ff.clone()
                        };
                        let [lo, hi] = ff.bounds;
                        let reach = lo.abs().max(hi.abs()).length();
                        (Shape::Object(ff), reach)
                    }
                    BodyShape::Voxels(k) => {
                        let (_, v) = instances.voxels.get(k)?;
                        let model = VoxelInstance {
                            position: DVec3::ZERO,
                            ..v.clone()
                        };
                        let frame = model.frame_at(time);
                        let d = model.frames[frame].dims.map(f64::from);
                        let reach = DVec3::from(d).length() * model.voxel_size;
                        (Shape::Voxels { model, frame }, reach)
                    }
                };
                Some(Body {
                    id: b.id,
                    alpha: b.alpha,
                    origin,
                    enu,
                    shape,
                    reach,
                })
            })
            .collect();
        Bodies {
            bodies,
            bricks: Arc::clone(bricks),
        }
    }

    /// Whether there is no body.
    pub fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }

    /// The first body on the line from ECEF `from` along the ECEF unit direction `dir`, with
    /// `t` metres from `from` in `[t_min, t_max]`, body `except` left out and those whose alpha
    /// ([`BodyHit::colour`]'s) is below `min_alpha` passed; a body the line starts inside (at
    /// `t_min`) is not met.
    pub fn first_hit(
        &self,
        from: DVec3,
        dir: DVec3,
        [t_min, t_max]: [f64; 2],
        except: Option<u16>,
        min_alpha: u8,
    ) -> Option<BodyHit> {
        if t_min.is_nan() || t_max.is_nan() || t_min > t_max {
            return None;
        }
        let mut best: Option<BodyHit> = None;
        for b in self.bodies.iter().filter(|b| Some(b.id) != except) {
            let far = best.map_or(t_max, |h| h.t);
            let hit = self.hit(b, from, dir, [t_min, far]);
            if let Some(h) = hit.filter(|h| h.colour[3] >= min_alpha) {
                best = Some(h);
            }
        }
        best
    }

    /// Every body on the line from ECEF `from` along the ECEF unit direction `dir` within
    /// `[t_min, t_max]` metres whose alpha ([`BodyHit::colour`]'s) is at least `min_alpha`,
    /// each where the line meets it first, nearest first; a body the line starts inside is
    /// not met.
    pub fn hits(
        &self,
        from: DVec3,
        dir: DVec3,
        [t_min, t_max]: [f64; 2],
        min_alpha: u8,
    ) -> Vec<BodyHit> {
        if t_min.is_nan() || t_max.is_nan() || t_min > t_max {
            return Vec::new();
        }
        let mut hits: Vec<BodyHit> = (self.bodies.iter())
            .filter_map(|b| self.hit(b, from, dir, [t_min, t_max]))
            .filter(|h| h.colour[3] >= min_alpha)
            .collect();
        hits.sort_by(|a, b| a.t.total_cmp(&b.t));
        hits
    }

    /// Where the line from `from` along `dir` meets body `b` first within `[t_min, far]`.
    fn hit(&self, b: &Body, from: DVec3, dir: DVec3, [t_min, far]: [f64; 2]) -> Option<BodyHit> {
        // The line in the body's east-north-up metres.
        let to_enu = b.enu.transpose();
        let o = to_enu * (from - b.origin);
        let d = to_enu * dir;
        // Lines that pass farther than the body's reach miss it.
        let closest = (-o.dot(d)).clamp(t_min, far);
        if (o + d * closest).length() > b.reach {
            return None;
        }
        // A line that starts inside a body (a sensor in its own hull) does not meet it.
        let (t, normal, colour) = match &b.shape {
            Shape::Object(ff) => {
                let start = ff.to_local(o + d * t_min);
                let [lo, hi] = ff.bounds;
                let inside = start.cmpge(lo).all() && start.cmple(hi).all();
                if inside && ff.value(start) <= 0.0 {
                    return None;
                }
                let h = intersect(ff, o, d, t_min, far, CPU_LEVELS)?;
                let c = ff.material.colour.map(|c| linear_to_srgb8(f64::from(c)));
                (h.t, h.normal, [c[0], c[1], c[2], 255])
            }
            Shape::Voxels { model, frame } => {
                let m = &model.frames[*frame];
                let bricks = self.bricks.get(m);
                let ld = model.dir_to_local(d);
                let h = dda(&bricks, model.to_local(o), ld, t_min, far)?;
                // Axis 3: the line started in an occupied voxel.
                if h.axis >= 3 {
                    return None;
                }
                let n = model.dir_to_world(h.normal(ld));
                (h.t, n, m.palette[h.index as usize])
            }
        };
        // The surface's alpha scaled by the entity's.
        let alpha = (u32::from(colour[3]) * u32::from(b.alpha) + 127) / 255;
        (t <= far).then(|| BodyHit {
            id: b.id,
            t,
            point: from + dir * t,
            normal: (b.enu * normal).normalize_or_zero(),
            colour: [colour[0], colour[1], colour[2], alpha as u8],
        })
    }
}
