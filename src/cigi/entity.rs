//! An entity as the host last described it: type, state, parent, the last two pose samples
//! with their host times, and Rate Control rates; its pose at any time.
//!
//! Pose at time `t` (seconds on the host's clock, [`super::Session::host_time_at`]):
//! * with non-zero rates (Rate Control of the entity itself): dead reckoning from the latest
//!   sample, `t` before it held at it;
//! * else, with extrapolation/interpolation enabled (the entity's bit and IG Control's) and
//!   two samples at different times: linear between them (angles and longitude the short way
//!   round), extrapolated at most two sample intervals (and at least 0.1 s) past the latest,
//!   held beyond (an IG reads datagrams at its frame starts, so at a 30 Hz host and a 60 Hz IG
//!   the latest sample it holds is up to an interval and a frame old; a host catching up after
//!   a stall sends two samples closer together than its rate);
//! * else the latest sample.

use crate::geodesy;

/// How far past the latest sample the two-sample extrapolation goes, in sample intervals.
pub const MAX_EXTRAPOLATION: f64 = 2.0;
/// ... and at least this far (seconds).
pub const MIN_EXTRAPOLATION_S: f64 = 0.1;

/// An entity's lifecycle state (destroyed entities are removed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EntityState {
    Inactive,
    Active,
}

/// Geodetic pose (degrees, metres above MSL) or, for an attached entity, offsets in metres
/// from the parent (`lat` = x forward, `lon` = y right, `alt` = z down); attitude in degrees.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose {
    pub lat: f64,
    pub lon: f64,
    pub alt: f64,
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
}

/// One host sample: the pose and the host time (s) it was sent for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub time: f64,
    pub pose: Pose,
}

/// Rate Control rates of an entity: m/s along x (north or forward), y (east or right),
/// z (down), and °/s of roll, pitch, yaw.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rates {
    pub linear: [f64; 3],
    pub angular: [f64; 3],
    /// Linear rates in the entity's body frame (else world or parent frame).
    pub body_frame: bool,
}

impl Rates {
    pub fn is_zero(&self) -> bool {
        self.linear.iter().chain(&self.angular).all(|&v| v == 0.0)
    }
}

/// An entity of the host's scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Entity {
    pub id: u16,
    pub entity_type: u16,
    pub state: EntityState,
    /// The parent when attached.
    pub parent: Option<u16>,
    pub alpha: u8,
    /// 0 none, 1 non-conformal, 2 conformal.
    pub ground_clamp: u8,
    /// Entity Control's collision detection bit: its segments are tested.
    pub collision_detection: bool,
    /// The entity's extrapolation/interpolation bit.
    pub extrapolation: bool,
    pub previous: Option<Sample>,
    pub latest: Sample,
    pub rates: Rates,
}

impl Entity {
    /// Records a new sample; a second sample for the same host time replaces the latest.
    pub fn push_sample(&mut self, s: Sample) {
        if s.time != self.latest.time {
            self.previous = Some(self.latest);
        }
        self.latest = s;
    }

    /// The pose at host time `t` (see the module's rules); `global_extrapolation` is IG
    /// Control's bit.
    pub fn pose_at(&self, t: f64, global_extrapolation: bool) -> Pose {
        if !self.rates.is_zero() {
            let attached = self.parent.is_some();
            return dead_reckon(&self.latest, &self.rates, t, attached);
        }
        match self.previous {
            Some(p) if self.extrapolation && global_extrapolation => {
                let span = self.latest.time - p.time;
                if span <= 0.0 || !t.is_finite() {
                    return self.latest.pose;
                }
                let reach = (MAX_EXTRAPOLATION * span).max(MIN_EXTRAPOLATION_S);
                let s = ((t - p.time) / span).clamp(0.0, 1.0 + reach / span);
                lerp_pose(&p.pose, &self.latest.pose, s, self.parent.is_none())
            }
            _ => self.latest.pose,
        }
    }
}

/// Wraps an angle difference into [−180, 180).
fn wrap180(d: f64) -> f64 {
    (d + 180.0).rem_euclid(360.0) - 180.0
}

/// Linear interpolation of two poses at fraction `s`; longitude (when geodetic) and the
/// angles go the short way round. Yaw ends in [0, 360), longitude in [−180, 180).
pub fn lerp_pose(a: &Pose, b: &Pose, s: f64, geodetic: bool) -> Pose {
    let lin = |x: f64, y: f64| x + (y - x) * s;
    let ang = |x: f64, y: f64| x + wrap180(y - x) * s;
    Pose {
        lat: lin(a.lat, b.lat),
        lon: if geodetic {
            wrap180(ang(a.lon, b.lon))
        } else {
            lin(a.lon, b.lon)
        },
        alt: lin(a.alt, b.alt),
        roll: wrap180(ang(a.roll, b.roll)),
        pitch: ang(a.pitch, b.pitch),
        yaw: ang(a.yaw, b.yaw).rem_euclid(360.0),
    }
}

/// The latest sample moved by the rates for `t − latest.time` seconds (none before it).
fn dead_reckon(latest: &Sample, r: &Rates, t: f64, attached: bool) -> Pose {
    let dt = if t.is_finite() {
        (t - latest.time).max(0.0)
    } else {
        0.0
    };
    let p = latest.pose;
    let mut v = r.linear;
    if r.body_frame {
        v = body_to_level(&p, v);
    }
    let (dx, dy, dz) = (v[0] * dt, v[1] * dt, v[2] * dt);
    let (lat, lon) = if attached {
        (p.lat + dx, p.lon + dy)
    } else {
        let m = geodesy::meridional_radius(p.lat) + p.alt;
        let n = geodesy::prime_vertical_radius(p.lat) + p.alt;
        let cos = p.lat.to_radians().cos().max(1e-9);
        let lat = (p.lat + (dx / m).to_degrees()).clamp(-90.0, 90.0);
        (lat, wrap180(p.lon + (dy / (n * cos)).to_degrees()))
    };
    Pose {
        lat,
        lon,
        alt: p.alt - dz,
        roll: wrap180(p.roll + r.angular[0] * dt),
        pitch: p.pitch + r.angular[1] * dt,
        yaw: (p.yaw + r.angular[2] * dt).rem_euclid(360.0),
    }
}

/// A body-frame vector (x forward, y right, z down) in the local level frame (x north,
/// y east, z down): yaw, then pitch, then roll.
fn body_to_level(p: &Pose, v: [f64; 3]) -> [f64; 3] {
    let (sr, cr) = p.roll.to_radians().sin_cos();
    let (sp, cp) = p.pitch.to_radians().sin_cos();
    let (sy, cy) = p.yaw.to_radians().sin_cos();
    let [x, y, z] = v;
    // Roll about x, pitch about y, yaw about z (z down).
    let (y1, z1) = (cr * y - sr * z, sr * y + cr * z);
    let (x2, z2) = (cp * x + sp * z1, -sp * x + cp * z1);
    [cy * x2 - sy * y1, sy * x2 + cy * y1, z2]
}
