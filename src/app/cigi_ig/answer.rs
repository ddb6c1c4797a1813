//! Answers to the host's queries from the CPU reference (`crate::cpu::query`): HAT/HOT, line of
//! sight (segment and vector) and position. Each query gets exactly one response packet, but
//! a line of sight with [`LosResponses::Every`] (`--cigi-los every`): one for each surface it
//! meets, nearest first, `count` saying how many.
//!
//! * **HOT** is the height above MSL of the terrain's bilinear surface at the query's latitude
//!   and longitude; **HAT** the query's altitude minus it. The extended response carries both
//!   and the surface normal as the ICD defines it: azimuth from true north (−180..180°),
//!   elevation above the local horizontal (−90..90°).
//! * **LOS segment**: `visible` from [`line_of_sight`](crate::cpu::query::line_of_sight) (an end point underground is blocked);
//!   the range, intersection point and normal from the first hit of [`cast_ray`] along the
//!   segment (on a curved terrain in the tangent frame of the source, as the CPU reference does).
//! * **LOS vector**: [`cast_ray`] from the source along azimuth/elevation between the minimum
//!   and maximum range; no hit is answered `valid = false` (basic) or `range_valid = false`
//!   (extended).
//! * Both meet the **entities drawn this frame** too ([`crate::cpu::bodies`]: each template's
//!   free form or voxel model in the entity's own east-north-up frame, the line taken there
//!   through ECEF): where one comes before the terrain the response names it (`entity_valid`,
//!   `entity_id`), with its range, intersection, normal and colour, and the segment is not
//!   visible. A line that starts inside an entity does not meet that entity, nor one whose
//!   alpha (the entity's times its surface's) is below the request's alpha threshold; the
//!   material mask is not applied (every surface is material 0).
//!   A segment's destination may be given in another entity's frame (`destination_entity_valid`).
//! * **Position**: the entity's pose at the frame's host time: geodetic where the IG put it
//!   (clamped to the ground, or carried by its parents when attached), or, for an attached
//!   entity asked for in its parent's frame, its offsets. Other object classes (parts, views,
//!   groups, trackers) and unknown entities get no response (counted).
//!
//! On a **database scene** (`[terrain] database`) every answer comes from the database at full
//! resolution (`cpu::database::FullResolution`), whatever level the scene renders: HOT from the
//! finest tile at the point, the normal, lines of sight and intersections over a window of the
//! finest level that fits around the query, made from the database's bounded host tile cache.
//! The frame a query arrives in never waits for the disk ([`Deferral`]): each HAT/HOT and LOS
//! query is answered there from tiles already in memory (resident only), or, where one it
//! needs is not, kept; its tiles go to a background [`Prefetcher`] and it is answered in the
//! **next** IG frame, before that frame's own queries, with that frame's host frame LSN (the
//! last IG Control received before the answer was calculated), reading synchronously only the
//! tiles the prefetcher has not read by then (counted: `blocking_reads`). So no answer is more
//! than one frame late, but where the frame's datagram has no room left for it (the last
//! frame's kept queries and a full frame of new ones; `no_room`): a query is then kept
//! another frame, whatever its kind. Position requests are otherwise never kept. Queries kept
//! when the run ends are answered in one more datagram (`CigiIg::finish`).
//!
//! **Requests in an entity's frame** (HAT/HOT `entity_frame`, LOS `source_entity_frame`,
//! `destination_entity_frame`, `response_entity_frame`) are taken through the entity's
//! placement at the frame's host time ([`crate::world::entity_placement`]: where the IG draws
//! it, clamped or carried by its parents): offsets x forward, y right, z down in its body
//! frame, a vector's azimuth from its x axis towards y and its elevation from its xy plane; an
//! extended response's intersection is given back as such offsets when asked. An entity the IG
//! cannot place (unknown, off the terrain) answers `valid = false`, as a point off the
//! terrain's georeferenced window does.

use crate::cigi::{
    HatHotExtendedResponse, HatHotRequest, HatHotResponse, MessageBuilder, Pose, PositionRequest,
    PositionResponse, Query, Session,
};
use crate::cpu::bodies::Bodies;
use crate::cpu::database::FullResolution;
use crate::cpu::query::cast_ray;
use crate::db::{Prefetcher, ResidentOnly, TileId};
use crate::terrain::Terrain;
pub use collide::{segment_collisions, volume_collisions, Notified};
use glam::DVec3;
pub use ground::{azimuth_elevation, direction, height_of_terrain, Ground, LosResponses};
use ground::{lsn, request_point, world, EntityFrame};
pub use los::EVERY_BUDGET;
use los::{los_segment, los_vector, SegmentFrames, LARGEST_ANSWER};

mod collide;
mod ground;
mod los;

/// What the answers of one frame did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AnswerCounts {
    pub hat_hot: u64,
    pub los: u64,
    pub position: u64,
    /// Answered `valid = false` (entity frames, points off the terrain).
    pub invalid: u64,
    /// Not answered (unknown entity, unsupported object class).
    pub unanswered: u64,
    /// Database scenes: kept for the next frame (a tile they need was not in memory, or the
    /// frame's datagram had no room left: `no_room`).
    pub deferred: u64,
    /// Database scenes: of those, kept because the datagram had no room for their answer (the
    /// last frame's kept queries and a full frame of new ones: [`Deferral::answer_frame`]).
    pub no_room: u64,
    /// Database scenes: kept queries whose tiles the prefetcher had not read by the frame that
    /// answers them (or the run's end), read there synchronously.
    pub blocking_reads: u64,
    /// Collision Detection Segment and Volume Notifications sent.
    pub collisions: u64,
    /// Collision notifications dropped: the frame's datagram had no room left for them.
    pub collisions_dropped: u64,
}

impl AnswerCounts {
    /// Adds `o`'s counts.
    pub fn add(&mut self, o: &AnswerCounts) {
        self.hat_hot += o.hat_hot;
        self.los += o.los;
        self.position += o.position;
        self.invalid += o.invalid;
        self.unanswered += o.unanswered;
        self.deferred += o.deferred;
        self.no_room += o.no_room;
        self.blocking_reads += o.blocking_reads;
        self.collisions += o.collisions;
        self.collisions_dropped += o.collisions_dropped;
    }
}

/// The surface normal below `lat`, `lon`: a vertical ray from above the highest sample.
fn normal_below(t: &Terrain, lat: f64, lon: f64) -> Option<DVec3> {
    let top = f64::from(t.max_height).max(0.0) + 100.0;
    let o = world(t, [lat, lon, top])?;
    let span = top - f64::from(t.min_height) + 100.0;
    cast_ray(t, o, -t.frame.normal, 0.0, span).map(|h| h.normal)
}

/// Answers every query of `queries` onto `msg`, each with the LSN of the host frame it came
/// in; `now_host` is the host time of the frame.
pub fn answer(
    t: &Ground,
    session: &Session,
    queries: &[Query],
    now_host: f64,
    msg: &mut MessageBuilder,
) -> AnswerCounts {
    let mut c = AnswerCounts::default();
    for q in queries {
        answer_one(t, session, q, frame_of(q), now_host, msg, &mut c);
    }
    c
}

/// The host frame query `q` came in.
fn frame_of(q: &Query) -> u32 {
    match q {
        Query::HatHot(_, f)
        | Query::LosSegment(_, f)
        | Query::LosVector(_, f)
        | Query::Position(_, f) => *f,
    }
}

/// Answers `q` onto `msg` with host frame `frame`'s LSN; `c` counts it.
fn answer_one(
    t: &Ground,
    session: &Session,
    q: &Query,
    frame: u32,
    now_host: f64,
    msg: &mut MessageBuilder,
    c: &mut AnswerCounts,
) {
    match q {
        Query::HatHot(r, _) => {
            c.hat_hot += 1;
            let entity = r
                .entity_frame
                .then(|| EntityFrame::of(t, session, r.entity_id, now_host))
                .flatten();
            let at = request_point(entity.as_ref(), r.entity_frame, [r.lat, r.lon, r.alt]);
            c.invalid += u64::from(!hat_hot(t, r, at, frame, msg));
        }
        Query::LosSegment(r, _) => {
            c.los += 1;
            let relative =
                r.source_entity_frame || r.destination_entity_frame || r.response_entity_frame;
            let entity = relative
                .then(|| EntityFrame::of(t, session, r.entity_id, now_host))
                .flatten();
            // The destination in another entity's frame where the request names one.
            let other = (r.destination_entity_frame && r.destination_entity_valid)
                .then(|| EntityFrame::of(t, session, r.destination_entity_id, now_host))
                .flatten();
            let frames = SegmentFrames {
                entity: entity.as_ref(),
                destination: if r.destination_entity_valid {
                    other.as_ref()
                } else {
                    entity.as_ref()
                },
            };
            c.invalid += u64::from(!los_segment(t, r, &frames, frame, msg));
        }
        Query::LosVector(r, _) => {
            c.los += 1;
            let relative = r.source_entity_frame || r.response_entity_frame;
            let entity = relative
                .then(|| EntityFrame::of(t, session, r.entity_id, now_host))
                .flatten();
            c.invalid += u64::from(!los_vector(t, r, entity.as_ref(), frame, msg));
        }
        Query::Position(r, _) => match position(t, session, r, now_host) {
            Some(p) => {
                c.position += 1;
                msg.push(&p);
            }
            None => c.unanswered += 1,
        },
    }
}

/// A database scene's queries answered without the frame they arrive in waiting for the disk:
/// each is first answered from resident tiles only; one that needs a tile not in memory is
/// kept, its tiles go to the [`Prefetcher`], and it is answered in the next frame, before that
/// frame's own queries (from the cache, or reading what the prefetcher has not read yet).
pub struct Deferral {
    prefetch: Prefetcher,
    kept: Vec<Query>,
}

impl Deferral {
    /// Starts the prefetcher on `full`'s database.
    pub fn new(full: &FullResolution) -> crate::Result<Deferral> {
        Ok(Deferral {
            prefetch: Prefetcher::new(full.shared().clone())?,
            kept: Vec::new(),
        })
    }

    /// Queries kept for the next frame.
    pub fn kept(&self) -> usize {
        self.kept.len()
    }

    /// The prefetcher.
    pub fn prefetcher(&self) -> &Prefetcher {
        &self.prefetch
    }

    /// One frame's answers onto `msg`: first every query kept from the last frame, with the
    /// LSN of `frame` (the host frame this frame answers for), read now where the prefetcher
    /// has not read its tiles yet (`blocking_reads`); then `queries`, each with the LSN of the
    /// frame it came in, answered from resident tiles or kept (`deferred`). Position requests
    /// are never kept.
    pub fn answer_frame(
        &mut self,
        on: &OnDatabase,
        queries: &[Query],
        frame: u32,
        msg: &mut MessageBuilder,
    ) -> AnswerCounts {
        let mut c = self.answer_kept(on, frame, msg);
        let mut missing = Vec::new();
        for q in queries {
            if !msg.fits(LARGEST_ANSWER) {
                c.deferred += 1;
                c.no_room += 1;
                self.kept.push(*q);
                continue;
            }
            if matches!(q, Query::Position(..)) {
                let g = Ground {
                    terrain: on.terrain,
                    full: None,
                    bodies: on.bodies,
                    los: on.los,
                };
                answer_one(&g, on.session, q, frame_of(q), on.now_host, msg, &mut c);
                continue;
            }
            if let Some(ids) = resident(on, q, frame_of(q), msg, &mut c) {
                c.deferred += 1;
                self.kept.push(*q);
                missing.extend(ids);
            }
        }
        self.prefetch.request(missing);
        c
    }

    /// Answers every kept query onto `msg` with `frame`'s LSN (resident, else read now:
    /// `blocking_reads`); none is kept after but those the datagram has no room for.
    pub fn answer_kept(
        &mut self,
        on: &OnDatabase,
        frame: u32,
        msg: &mut MessageBuilder,
    ) -> AnswerCounts {
        let mut c = AnswerCounts::default();
        for q in std::mem::take(&mut self.kept) {
            if !msg.fits(LARGEST_ANSWER) {
                c.no_room += 1;
                self.kept.push(q);
                continue;
            }
            if resident(on, &q, frame, msg, &mut c).is_some() {
                c.blocking_reads += 1;
                let g = Ground {
                    terrain: on.terrain,
                    full: Some((on.full, on.full.database())),
                    bodies: on.bodies,
                    los: on.los,
                };
                answer_one(&g, on.session, &q, frame, on.now_host, msg, &mut c);
            }
        }
        c
    }
}

/// What a database scene's frame answers on: the scene's terrain, the database at full
/// resolution, the session, the frame's host time.
pub struct OnDatabase<'a> {
    pub terrain: &'a Terrain,
    pub full: &'a FullResolution,
    pub session: &'a Session,
    pub now_host: f64,
    /// The entities drawn this frame (lines of sight meet them).
    pub bodies: &'a Bodies,
    /// How many intersections a line of sight is answered with.
    pub los: LosResponses,
}

/// Answers `q` from resident tiles only onto `msg` (counted in `c`): `None`, or the tiles it
/// needs that are not in memory (nothing pushed, nothing counted).
fn resident(
    on: &OnDatabase,
    q: &Query,
    frame: u32,
    msg: &mut MessageBuilder,
    c: &mut AnswerCounts,
) -> Option<Vec<TileId>> {
    let tiles = ResidentOnly::new(on.full.database());
    let g = Ground {
        terrain: on.terrain,
        full: Some((on.full, &tiles)),
        bodies: on.bodies,
        los: on.los,
    };
    let (mark, mut one) = (msg.len(), AnswerCounts::default());
    answer_one(&g, on.session, q, frame, on.now_host, msg, &mut one);
    let missing = tiles.missing();
    if missing.is_empty() {
        c.add(&one);
        None
    } else {
        msg.truncate(mark);
        Some(missing)
    }
}

/// One HAT/HOT response for the request's point `at` (geodetic; `None`: it cannot be
/// placed); `false` when it is answered invalid.
fn hat_hot(
    g: &Ground,
    r: &HatHotRequest,
    at: Option<[f64; 3]>,
    frame: u32,
    msg: &mut MessageBuilder,
) -> bool {
    let hot = at.and_then(|[lat, lon, _]| g.hot(lat, lon));
    let valid = hot.is_some();
    let hot = hot.unwrap_or(0.0);
    let [lat, lon, alt] = at.unwrap_or([0.0; 3]);
    let hat = if valid { alt - hot } else { 0.0 };
    if r.request_type & 3 == 2 {
        let at = [lat, lon, alt];
        let window = g.window(at, at);
        let t = match &window {
            Some(Ok(w)) => Some(w),
            Some(Err(())) => None,
            None => Some(g.terrain),
        };
        let (az, el) = t
            .filter(|_| valid)
            .and_then(|t| Some((t, normal_below(t, lat, lon)?)))
            .map_or((0.0, 90.0), |(t, n)| azimuth_elevation(t, n));
        msg.push(&HatHotExtendedResponse {
            request_id: r.request_id,
            valid,
            host_frame_lsn: lsn(frame),
            hat,
            hot,
            material: 0,
            normal_azimuth: az as f32,
            normal_elevation: el as f32,
        });
    } else {
        let is_hot = r.request_type & 3 == 1;
        msg.push(&HatHotResponse {
            request_id: r.request_id,
            valid,
            hot: is_hot,
            host_frame_lsn: lsn(frame),
            height: if is_hot { hot } else { hat },
        });
    }
    valid
}

/// The position of an entity (object class 0) at host time `now_host`: an attached entity
/// asked for in its parent's frame (or a submodel's), its offsets as sent; otherwise
/// geodetic, where the IG put it — clamped to the ground, or attached and carried by its
/// parents (`world::entity_placement`); an entity the IG cannot place, as the host sent it.
fn position(
    t: &Ground,
    s: &Session,
    r: &PositionRequest,
    now_host: f64,
) -> Option<PositionResponse> {
    if r.object_class != 0 {
        return None;
    }
    let e = s.entity(r.object_id)?;
    let mut p = s.pose_at(r.object_id, now_host)?;
    let relative = e.parent.is_some() && r.coordinate_system != 0;
    if !relative && (e.parent.is_some() || e.ground_clamp != 0) {
        let placed = crate::world::entity_placement(s, t.terrain, r.object_id, now_host)
            .map(|pl| (pl.geodetic, pl.attitude));
        match placed {
            Some(([lat, lon, alt], m)) => {
                let (yaw, pitch, roll) = crate::geom::attitude_angles(m);
                (p.lat, p.lon, p.alt) = (lat, lon, alt);
                (p.yaw, p.pitch, p.roll) = (yaw, pitch, roll);
            }
            // Attached below an entity off the terrain: the offsets, in the parent's frame.
            None if e.parent.is_some() => {
                return Some(position_response(r, 1, &p));
            }
            None => {}
        }
    }
    Some(position_response(r, u8::from(relative), &p))
}

fn position_response(r: &PositionRequest, coordinate_system: u8, p: &Pose) -> PositionResponse {
    PositionResponse {
        object_id: r.object_id,
        part_id: 0,
        object_class: 0,
        coordinate_system,
        lat: p.lat,
        lon: p.lon,
        alt: p.alt,
        roll: p.roll as f32,
        pitch: p.pitch as f32,
        yaw: p.yaw as f32,
    }
}

#[cfg(test)]
mod tests {
    use super::los::START_OF_FRAME;
    use super::LARGEST_ANSWER;
    use crate::cigi::{
        HatHotExtendedResponse, HatHotResponse, LosExtendedResponse, LosResponse, Packet,
        PositionResponse, StartOfFrame,
    };

    /// No response a query gets is larger than what the datagram check leaves room for.
    #[test]
    fn the_largest_answer_is_the_largest_response() {
        let sizes = [
            HatHotResponse::KIND.size(),
            HatHotExtendedResponse::KIND.size(),
            LosResponse::KIND.size(),
            LosExtendedResponse::KIND.size(),
            PositionResponse::KIND.size(),
        ];
        assert_eq!(sizes.into_iter().max(), Some(LARGEST_ANSWER));
        assert_eq!(StartOfFrame::KIND.size(), START_OF_FRAME);
    }
}
