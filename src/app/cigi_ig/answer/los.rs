//! Line-of-sight answers (segment and vector): the terrain's first hit from the CPU reference
//! and the entities drawn this frame ([`crate::cpu::bodies`]), whichever comes first; see the
//! parent module for what each field says.

use super::ground::{
    azimuth_elevation, direction, lsn, request_point, world, EntityFrame, Ground, LosResponses,
};
use crate::cigi::{
    LosExtendedResponse, LosResponse, LosSegmentRequest, LosVectorRequest, MessageBuilder, Packet,
};
use crate::cpu::bodies::{Bodies, BodyHit};
use crate::cpu::query::{cast_ray, line_of_sight};
use crate::cpu::Hit;
use crate::geodesy::{ecef_of, enu_basis, lla_of};
use crate::terrain::Terrain;
use glam::DVec3;

/// A surface a line of sight met: the terrain or an entity.
#[derive(Clone, Copy)]
enum Met {
    Terrain(Hit),
    Body(BodyHit),
}

impl Met {
    /// Metres from the line's start.
    fn range(&self) -> f64 {
        match self {
            Met::Terrain(h) => h.t,
            Met::Body(b) => b.t,
        }
    }
}

/// What one line-of-sight test found: the surfaces met, nearest first (the nearest alone
/// unless every intersection is asked for).
struct Los {
    valid: bool,
    visible: bool,
    met: Vec<Met>,
}

impl Los {
    /// An answer to a request that cannot be answered (`valid = false`).
    const INVALID: Los = Los {
        valid: false,
        visible: false,
        met: Vec::new(),
    };

    /// The test on the terrain (its first hit `hit`) and the entities `bodies` (nearest
    /// first), as `policy` asks: the nearest surface, or all of them in order of range. A
    /// line that meets an entity is not visible.
    fn new(
        valid: bool,
        visible: bool,
        hit: Option<Hit>,
        bodies: Vec<BodyHit>,
        policy: LosResponses,
    ) -> Los {
        let mut met: Vec<Met> = bodies.into_iter().map(Met::Body).collect();
        let visible = visible && met.is_empty();
        if let Some(h) = hit {
            let at = met.partition_point(|m| m.range() < h.t);
            met.insert(at, Met::Terrain(h));
        }
        if policy == LosResponses::First {
            met.truncate(1);
        }
        Los {
            valid,
            visible,
            met,
        }
    }
}

/// The entity frames a LOS segment's points may be given in: the request's entity (the
/// source's, and the response's) and the destination's (another entity's where the request
/// says so).
pub(super) struct SegmentFrames<'a> {
    pub entity: Option<&'a EntityFrame>,
    pub destination: Option<&'a EntityFrame>,
}

/// Azimuth from true north and elevation (degrees) of ECEF unit vector `v` at geodetic `at`.
fn ecef_azimuth_elevation(at: [f64; 3], v: DVec3) -> (f64, f64) {
    let enu = enu_basis(at[0], at[1]).transpose() * v;
    (
        enu.x.atan2(enu.y).to_degrees(),
        enu.z.clamp(-1.0, 1.0).asin().to_degrees(),
    )
}

/// How a LOS response is given: the request's ID, extended or basic, and the entity frame
/// its intersection is given in (`response_entity_frame`).
struct LosAnswer<'a> {
    id: u16,
    extended: bool,
    in_entity: Option<&'a EntityFrame>,
}

/// The largest response one query gets (a LOS extended response), bytes.
pub(super) const LARGEST_ANSWER: usize = 56;

/// The size of the Start of Frame each IG datagram begins with, bytes.
pub(super) const START_OF_FRAME: usize = 24;

/// How far an IG datagram may fill with intersections beyond each LOS request's nearest
/// ([`LosResponses::Every`]): UDP's 65,507 bytes less Start of Frame, the largest answer for
/// each of the most queries a frame takes
/// ([`MAX_QUERIES`](crate::cigi::session::MAX_QUERIES)) and 1 KiB: 7,115 bytes, 127 extended
/// responses.
pub const EVERY_BUDGET: usize = crate::cigi::DATAGRAM_LIMIT
    - START_OF_FRAME
    - crate::cigi::session::MAX_QUERIES * LARGEST_ANSWER
    - 1024;

/// The LOS responses (basic or extended) to one request from what the test found on `t`:
/// one for each surface met, or one saying none was. Past [`EVERY_BUDGET`] bytes of the
/// datagram a request gets its nearest intersection only (`count` says what was sent).
fn push_los(t: &Terrain, a: &LosAnswer, frame: u32, los: &Los, msg: &mut MessageBuilder) {
    let size = if a.extended {
        LosExtendedResponse::KIND.size()
    } else {
        LosResponse::KIND.size()
    };
    let room = EVERY_BUDGET.saturating_sub(msg.len()) / size;
    let count = los.met.len().min(room).clamp(1, usize::from(u8::MAX)) as u8;
    if los.met.is_empty() {
        push_one(t, a, frame, los, None, count, msg);
    }
    for m in los.met.iter().take(usize::from(count)) {
        push_one(t, a, frame, los, Some(m), count, msg);
    }
}

/// One LOS response: surface `met` of `los` (`None`: nothing met), one of `count`.
fn push_one(
    t: &Terrain,
    a: &LosAnswer,
    frame: u32,
    los: &Los,
    met: Option<&Met>,
    count: u8,
    msg: &mut MessageBuilder,
) {
    let (id, extended) = (a.id, a.extended);
    let range = met.map_or(0.0, Met::range);
    let body = match met {
        Some(Met::Body(b)) => Some(b),
        _ => None,
    };
    let entity_id = body.map_or(0, |b| b.id);
    if extended {
        let (mut lla, mut az, mut el, mut rgba) = ([0.0; 3], 0.0, 90.0, [0u8; 4]);
        match met {
            Some(Met::Terrain(h)) => {
                lla = t.world_to_geodetic(h.point).unwrap_or([0.0; 3]);
                (az, el) = azimuth_elevation(t, h.normal);
                rgba[3] = 255;
            }
            Some(Met::Body(b)) => {
                lla = lla_of(b.point);
                (az, el) = ecef_azimuth_elevation(lla, b.normal);
                rgba = b.colour;
            }
            None => {}
        }
        if let (Some(e), true) = (a.in_entity, met.is_some()) {
            lla = e.offsets(lla);
        }
        msg.push(&LosExtendedResponse {
            request_id: id,
            valid: los.valid,
            entity_valid: body.is_some(),
            range_valid: los.valid && met.is_some(),
            visible: los.visible,
            host_frame_lsn: lsn(frame),
            count,
            entity_id,
            range,
            lat: lla[0],
            lon: lla[1],
            alt: lla[2],
            red: rgba[0],
            green: rgba[1],
            blue: rgba[2],
            alpha: rgba[3],
            material: 0,
            normal_azimuth: az as f32,
            normal_elevation: el as f32,
        });
    } else {
        msg.push(&LosResponse {
            request_id: id,
            valid: los.valid,
            entity_valid: body.is_some(),
            visible: los.visible,
            host_frame_lsn: lsn(frame),
            count,
            entity_id,
            range,
        });
    }
}

/// One LOS segment response; `entity`: the request's entity frame where it uses one.
pub(super) fn los_segment(
    g: &Ground,
    r: &LosSegmentRequest,
    frames: &SegmentFrames,
    frame: u32,
    msg: &mut MessageBuilder,
) -> bool {
    let entity = frames.entity;
    let ga = request_point(
        entity,
        r.source_entity_frame,
        [r.source_lat, r.source_lon, r.source_alt],
    );
    let gb = request_point(
        frames.destination,
        r.destination_entity_frame,
        [r.destination_lat, r.destination_lon, r.destination_alt],
    );
    let placed = ga
        .zip(gb)
        .filter(|_| entity.is_some() || !r.response_entity_frame);
    let window = placed.and_then(|(ga, gb)| g.window(ga, gb));
    let t = match &window {
        Some(Ok(w)) => w,
        _ => g.terrain,
    };
    let ends = placed
        .and_then(|(ga, gb)| Some((world(t, ga)?, world(t, gb)?)))
        .filter(|_| !matches!(window, Some(Err(()))));
    let los = match ends {
        Some((a, b)) => {
            let len = (b - a).length();
            let hit = (len > 0.0)
                .then(|| cast_ray(t, a, (b - a) / len, 0.0, len))
                .flatten();
            let bodies = (placed
                .map(|(ga, gb)| segment_bodies(g.bodies, [ga, gb], r.alpha_threshold, g.los)))
            .unwrap_or_default();
            Los::new(true, line_of_sight(t, a, b), hit, bodies, g.los)
        }
        None => Los::INVALID,
    };
    let answer = LosAnswer {
        id: r.request_id,
        extended: r.extended,
        in_entity: entity.filter(|_| r.response_entity_frame),
    };
    push_los(t, &answer, frame, &los, msg);
    los.valid
}

/// One LOS vector response; `entity`: the request's entity frame where it uses one.
pub(super) fn los_vector(
    g: &Ground,
    r: &LosVectorRequest,
    entity: Option<&EntityFrame>,
    frame: u32,
    msg: &mut MessageBuilder,
) -> bool {
    let ranges_ok = r.min_range.is_finite()
        && r.max_range.is_finite()
        && r.min_range >= 0.0
        && r.max_range >= r.min_range;
    let dir_ok = r.azimuth.is_finite() && r.elevation.is_finite();
    let source = request_point(
        entity,
        r.source_entity_frame,
        [r.source_lat, r.source_lon, r.source_alt],
    )
    .filter(|_| entity.is_some() || !r.response_entity_frame);
    // From true north and the horizontal, or from the entity's x axis and xy plane.
    let (az, el) = (f64::from(r.azimuth), f64::from(r.elevation));
    let (az, el) = match entity.filter(|_| r.source_entity_frame && dir_ok) {
        Some(e) => e.az_el(g, az, el),
        None => (az, el),
    };
    // On a database: the window around the source and the far end (placed on the scene's
    // terrain); the ray is cast in the window's frame.
    let window = source.filter(|_| ranges_ok && dir_ok).and_then(|gs| {
        let s = world(g.terrain, gs)?;
        let d = direction(g.terrain, az, el);
        let end = g
            .terrain
            .world_to_geodetic(s + d * f64::from(r.max_range))?;
        g.window(gs, end)
    });
    let t = match &window {
        Some(Ok(w)) => w,
        _ => g.terrain,
    };
    let src = source
        .and_then(|gs| world(t, gs))
        .filter(|_| !matches!(window, Some(Err(()))));
    let los = match src.filter(|_| ranges_ok && dir_ok) {
        Some(a) => {
            let d = direction(t, az, el);
            let (near, far) = (f64::from(r.min_range), f64::from(r.max_range));
            let hit = cast_ray(t, a, d, near, far);
            let bodies = (source.map(|gs| {
                let ray = VectorRay {
                    from: gs,
                    az,
                    el,
                    range: [near, far],
                };
                vector_bodies(g.bodies, &ray, r.alpha_threshold, g.los)
            }))
            .unwrap_or_default();
            let los = Los::new(true, hit.is_none(), hit, bodies, g.los);
            // A basic response has no range-valid flag: a vector that meets nothing is invalid.
            let met = !los.met.is_empty();
            Los {
                valid: r.extended || met,
                visible: !met,
                ..los
            }
        }
        None => Los::INVALID,
    };
    let answer = LosAnswer {
        id: r.request_id,
        extended: r.extended,
        in_entity: entity.filter(|_| r.response_entity_frame),
    };
    push_los(t, &answer, frame, &los, msg);
    src.is_some() && ranges_ok && dir_ok
}

/// The entities on the line from ECEF `from` along unit `dir` within `range` metres whose
/// alpha is at least `min_alpha`, nearest first: all of them, or the nearest alone.
fn bodies_on(
    bodies: &Bodies,
    (from, dir): (DVec3, DVec3),
    range: [f64; 2],
    min_alpha: u8,
    policy: LosResponses,
) -> Vec<BodyHit> {
    match policy {
        _ if bodies.is_empty() => Vec::new(),
        LosResponses::First => (bodies.first_hit(from, dir, range, None, min_alpha))
            .into_iter()
            .collect(),
        LosResponses::Every => bodies.hits(from, dir, range, min_alpha),
    }
}

/// [`bodies_on`] the straight segment between geodetic `a` and `b`.
fn segment_bodies(
    bodies: &Bodies,
    [a, b]: [[f64; 3]; 2],
    min_alpha: u8,
    policy: LosResponses,
) -> Vec<BodyHit> {
    let (a, b) = (ecef_of(a), ecef_of(b));
    let len = (b - a).length();
    if len > 0.0 {
        bodies_on(bodies, (a, (b - a) / len), [0.0, len], min_alpha, policy)
    } else {
        Vec::new()
    }
}

/// A LOS vector: from geodetic `from` at azimuth `az` from true north and elevation `el`
/// (degrees, at `from`), between `range[0]` and `range[1]` metres.
struct VectorRay {
    from: [f64; 3],
    az: f64,
    el: f64,
    range: [f64; 2],
}

/// [`bodies_on`] `ray`.
fn vector_bodies(
    bodies: &Bodies,
    ray: &VectorRay,
    min_alpha: u8,
    policy: LosResponses,
) -> Vec<BodyHit> {
    let (a, e) = (ray.az.to_radians(), ray.el.to_radians());
    let enu = DVec3::new(a.sin() * e.cos(), a.cos() * e.cos(), e.sin());
    let d = enu_basis(ray.from[0], ray.from[1]) * enu;
    bodies_on(bodies, (ecef_of(ray.from), d), ray.range, min_alpha, policy)
}
