//! Collision detection for the host: each frame the segments and volumes of entities whose
//! collision detection is on (Entity Control's bit) are tested, segments against the terrain
//! and the entities drawn, volumes against the other entities' volumes and the terrain, and
//! each contact is notified (CIGI's Collision Detection Segment and Volume Notifications).

use super::ground::{world, EntityFrame, Ground};
use crate::cigi::{
    CollisionSegmentNotification, CollisionVolumeDefinition, CollisionVolumeNotification,
    MessageBuilder, Packet, Session,
};
use crate::cpu::contact::{lowest_point, overlap, underside, Solid};
use crate::cpu::query::cast_ray;
use crate::geodesy::{ecef_of, enu_basis, lla_of};
use crate::geom::attitude_matrix;
use glam::{DMat3, DVec3};

/// One Collision Detection Segment Notification for each of this frame's segments
/// (`Session::collision_segments`) that meets the terrain or another drawn entity, onto `msg`:
/// the segment's points placed through its entity's body frame at host time `now_host`, the
/// first surface from its first point (distance 0 where that point lies under the terrain).
/// Segments whose entity cannot be placed, or (database scenes) whose tiles are not in memory,
/// are skipped this frame; a notification the datagram has no room for is dropped (it comes
/// again next frame while the contact lasts).
pub fn segment_collisions(
    g: &Ground,
    session: &Session,
    now_host: f64,
    msg: &mut MessageBuilder,
) -> Notified {
    let mut sent = Notified::default();
    for s in session.collision_segments() {
        let Some(frame) = EntityFrame::of(g, session, s.entity_id, now_host) else {
            continue;
        };
        let f = |v: [f32; 3]| v.map(f64::from);
        let ga = frame.point(f([s.x1, s.y1, s.z1]));
        let gb = frame.point(f([s.x2, s.y2, s.z2]));
        let window = g.window(ga, gb);
        let t = match &window {
            Some(Ok(w)) => w,
            Some(Err(())) => continue,
            None => g.terrain,
        };
        let Some((a, b)) = world(t, ga).zip(world(t, gb)) else {
            continue;
        };
        let len = (b - a).length();
        if len <= 0.0 {
            continue;
        }
        let ground = if t.height_above(a).is_some_and(|h| h < 0.0) {
            Some(0.0)
        } else {
            cast_ray(t, a, (b - a) / len, 0.0, len).map(|h| h.t)
        };
        let (ea, eb) = (ecef_of(ga), ecef_of(gb));
        let elen = (eb - ea).length();
        let body = g
            .bodies
            .first_hit(ea, (eb - ea) / elen, [0.0, elen], Some(s.entity_id), 0)
            .filter(|b| ground.is_none_or(|t| b.t < t));
        let (distance, contact) = match (body, ground) {
            (Some(b), _) => (b.t, Some(b.id)),
            (None, Some(t)) => (t, None),
            (None, None) => continue,
        };
        sent.push(
            msg,
            &CollisionSegmentNotification {
                entity_id: s.entity_id,
                segment_id: s.segment_id,
                entity_contact: contact.is_some(),
                contacted_entity_id: contact.unwrap_or(0),
                material_code: 0,
                distance: distance as f32,
            },
        );
    }
    sent
}

/// Collision notifications of a frame: sent, and dropped for want of room in the datagram.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Notified {
    pub sent: u64,
    pub dropped: u64,
}

impl Notified {
    /// Pushes `n` onto `msg` where it fits in the datagram, else counts it dropped.
    fn push<P: Packet>(&mut self, msg: &mut MessageBuilder, n: &P) {
        if msg.fits(P::KIND.size()) {
            msg.push(n);
            self.sent += 1;
        } else {
            self.dropped += 1;
        }
    }

    /// The sum of `self` and `o`.
    pub fn and(self, o: Notified) -> Notified {
        Notified {
            sent: self.sent + o.sent,
            dropped: self.dropped + o.dropped,
        }
    }
}

/// A volume placed: its entity, its ID, whether its entity's detection is on, its solid and
/// the east, north and up of its entity's place (ECEF).
struct Placed {
    entity: u16,
    id: u8,
    source: bool,
    solid: Solid,
    enu: [DVec3; 3],
}

/// The most vertical lines across a volume's underside each way, and the spacing (m) they
/// are drawn at below that.
const UNDERSIDE_LINES: usize = 33;
const UNDERSIDE_SPACING: f64 = 2.0;

/// Whether any point of volume `v`'s underside ([`underside`]: the lowest point of vertical
/// lines at most [`UNDERSIDE_SPACING`] apart, [`UNDERSIDE_LINES`] each way at most) lies below
/// the terrain's surface (`Ground::hot`; a point where it has no height does not count). A
/// volume whose lowest point is above every height the ground has is not sampled at all.
fn under_terrain(g: &Ground, v: &Placed) -> bool {
    if lla_of(lowest_point(&v.solid, v.enu[2]))[2] >= g.highest() {
        return false;
    }
    let size = match v.solid {
        Solid::Sphere { radius, .. } => 2.0 * radius,
        Solid::Cuboid { half, .. } => 2.0 * half.length(),
    };
    let n = ((size / UNDERSIDE_SPACING).ceil() as usize + 1).clamp(2, UNDERSIDE_LINES);
    underside(&v.solid, v.enu, n).into_iter().any(|p| {
        let [lat, lon, alt] = lla_of(p);
        g.hot(lat, lon).is_some_and(|h| alt < h)
    })
}

/// The solid of volume `v` of the entity whose body frame is `f`, in ECEF: a cuboid turned by
/// its yaw, pitch and roll from the body as an attached entity turns from its parent
/// (`world::entity_placement`).
fn solid(f: &EntityFrame, v: &CollisionVolumeDefinition) -> Solid {
    let centre = ecef_of(f.point([v.x, v.y, v.z].map(f64::from)));
    if !v.cuboid {
        return Solid::Sphere {
            centre,
            radius: f64::from(v.radius_height),
        };
    }
    let [yaw, pitch, roll] = [v.yaw, v.pitch, v.roll].map(f64::from);
    // Columns right, forward, up in east-north-up; the box's x forward, y right, z down.
    let m = f.attitude * attitude_matrix(yaw, pitch, roll);
    let enu = enu_basis(f.origin[0], f.origin[1]);
    Solid::Cuboid {
        centre,
        axes: DMat3::from_cols(enu * m.y_axis, enu * m.x_axis, -(enu * m.z_axis)),
        half: DVec3::new(
            f64::from(v.depth),
            f64::from(v.width),
            f64::from(v.radius_height),
        ) * 0.5,
    }
}

/// One Collision Detection Volume Notification for each pair of overlapping volumes of two
/// entities, to the entity whose detection is on (both, each its own, where both are), and one
/// (`entity_contact` false) for each of those entities' volumes that reaches below the
/// terrain, onto `msg`: volumes placed through their entities' body frames at host time
/// `now_host`. On a database scene read resident only, a volume over tiles not in memory is
/// tested against what is (the tiles it missed go to the prefetcher). A notification the
/// datagram has no room for is dropped.
pub fn volume_collisions(
    g: &Ground,
    session: &Session,
    now_host: f64,
    msg: &mut MessageBuilder,
) -> Notified {
    let mut frames = std::collections::BTreeMap::new();
    let mut placed = Vec::new();
    for (v, source) in session.collision_volumes() {
        let frame = frames
            .entry(v.entity_id)
            .or_insert_with(|| EntityFrame::of(g, session, v.entity_id, now_host));
        if let Some(f) = frame {
            let b = enu_basis(f.origin[0], f.origin[1]);
            placed.push(Placed {
                entity: v.entity_id,
                id: v.volume_id,
                source,
                solid: solid(f, v),
                enu: [b.x_axis, b.y_axis, b.z_axis],
            });
        }
    }
    let mut sent = Notified::default();
    for a in placed.iter().filter(|a| a.source) {
        if under_terrain(g, a) {
            let n = CollisionVolumeNotification {
                entity_id: a.entity,
                volume_id: a.id,
                entity_contact: false,
                contacted_entity_id: 0,
                contacted_volume_id: 0,
            };
            sent.push(msg, &n);
        }
        for b in placed.iter().filter(|b| b.entity != a.entity) {
            if overlap(&a.solid, &b.solid) {
                let n = CollisionVolumeNotification {
                    entity_id: a.entity,
                    volume_id: a.id,
                    entity_contact: true,
                    contacted_entity_id: b.entity,
                    contacted_volume_id: b.id,
                };
                sent.push(msg, &n);
            }
        }
    }
    sent
}
