//! Line-of-sight answers (segment and vector): the terrain's first hit from the CPU reference
//! and the entities drawn this frame ([`crate::cpu::bodies`]), whichever comes first; see the
//! parent module for what each field says.

use super::ground::{azimuth_elevation, direction, lsn, request_point, world, EntityFrame, Ground};
use crate::cigi::{
    LosExtendedResponse, LosResponse, LosSegmentRequest, LosVectorRequest, MessageBuilder,
};
use crate::cpu::bodies::{Bodies, BodyHit};
use crate::cpu::query::{cast_ray, line_of_sight};
use crate::cpu::Hit;
use crate::geodesy::{ecef_of, enu_basis, lla_of};
use crate::terrain::Terrain;
use glam::DVec3;

/// What one line-of-sight test found: the terrain's first hit, or an entity's where it comes
/// first (then `hit` is `None`).
struct Los {
    valid: bool,
    visible: bool,
    hit: Option<Hit>,
    body: Option<BodyHit>,
}

impl Los {
    /// An answer to a request that cannot be answered (`valid = false`).
    const INVALID: Los = Los {
        valid: false,
        visible: false,
        hit: None,
        body: None,
    };

    /// `self` with entity hit `body` where it comes before the terrain's hit (or the terrain
    /// has none): the line is then blocked by it.
    fn with_body(self, body: Option<BodyHit>) -> Los {
        match body.filter(|b| self.hit.as_ref().is_none_or(|h| b.t < h.t)) {
            Some(b) => Los {
                visible: false,
                hit: None,
                body: Some(b),
                ..self
            },
            None => self,
        }
    }

    /// Metres to the intersection (0 without one).
    fn range(&self) -> f64 {
        match (&self.hit, &self.body) {
            (Some(h), _) => h.t,
            (_, Some(b)) => b.t,
            _ => 0.0,
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

/// One LOS response (basic or extended) from what the test found on `t`.
fn push_los(t: &Terrain, a: &LosAnswer, frame: u32, los: &Los, msg: &mut MessageBuilder) {
    let (id, extended) = (a.id, a.extended);
    let range = los.range();
    let met = los.hit.is_some() || los.body.is_some();
    let entity_id = los.body.map_or(0, |b| b.id);
    if extended {
        let (mut lla, mut az, mut el, mut rgba) = ([0.0; 3], 0.0, 90.0, [0u8; 4]);
        if let Some(h) = &los.hit {
            lla = t.world_to_geodetic(h.point).unwrap_or([0.0; 3]);
            (az, el) = azimuth_elevation(t, h.normal);
            rgba[3] = 255;
        }
        if let Some(b) = &los.body {
            lla = lla_of(b.point);
            (az, el) = ecef_azimuth_elevation(lla, b.normal);
            rgba = b.colour;
        }
        if let (Some(e), true) = (a.in_entity, met) {
            lla = e.offsets(lla);
        }
        msg.push(&LosExtendedResponse {
            request_id: id,
            valid: los.valid,
            entity_valid: los.body.is_some(),
            range_valid: los.valid && met,
            visible: los.visible,
            host_frame_lsn: lsn(frame),
            count: 1,
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
            entity_valid: los.body.is_some(),
            visible: los.visible,
            host_frame_lsn: lsn(frame),
            count: 1,
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
            let los = Los {
                valid: true,
                visible: line_of_sight(t, a, b),
                hit,
                body: None,
            };
            los.with_body(placed.and_then(|(ga, gb)| segment_body(g.bodies, ga, gb)))
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
            let body = source.and_then(|gs| vector_body(g.bodies, gs, az, el, near, far));
            let los = Los {
                valid: true,
                visible: hit.is_none(),
                hit,
                body: None,
            }
            .with_body(body);
            // A basic response has no range-valid flag: a vector that meets nothing is invalid.
            let met = los.hit.is_some() || los.body.is_some();
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

/// The first entity on the straight segment between geodetic `a` and `b`.
fn segment_body(bodies: &Bodies, a: [f64; 3], b: [f64; 3]) -> Option<BodyHit> {
    if bodies.is_empty() {
        return None;
    }
    let (a, b) = (ecef_of(a), ecef_of(b));
    let len = (b - a).length();
    (len > 0.0)
        .then(|| bodies.first_hit(a, (b - a) / len, [0.0, len], None))
        .flatten()
}

/// The first entity on the ray from geodetic `from` at azimuth `az` from true north and
/// elevation `el` (degrees, at `from`) between `near` and `far` metres.
fn vector_body(
    bodies: &Bodies,
    from: [f64; 3],
    az: f64,
    el: f64,
    near: f64,
    far: f64,
) -> Option<BodyHit> {
    if bodies.is_empty() {
        return None;
    }
    let (a, e) = (az.to_radians(), el.to_radians());
    let enu = DVec3::new(a.sin() * e.cos(), a.cos() * e.cos(), e.sin());
    let d = enu_basis(from[0], from[1]) * enu;
    bodies.first_hit(ecef_of(from), d, [near, far], None)
}
