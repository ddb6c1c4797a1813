//! What the answers stand on: the terrain or the database at full resolution ([`Ground`]), an
//! entity's body frame for requests given in it ([`EntityFrame`]), and the conversions between
//! geodetic points, world points and directions the answers share.

use crate::cigi::Session;
use crate::cpu::bodies::Bodies;
use crate::cpu::database::FullResolution;
use crate::db::Tiles;
use crate::terrain::Terrain;
use glam::DVec3;

/// The four least significant bits of host frame `f`.
pub(super) fn lsn(f: u32) -> u8 {
    (f & 0xF) as u8
}

/// The world point of `[lat, lon, alt]`, `None` off the terrain or without a georeference.
pub(super) fn world(t: &Terrain, lla: [f64; 3]) -> Option<DVec3> {
    t.geodetic_to_world("cigi", lla).ok()
}

/// Terrain height above MSL at `lat`, `lon` (the bilinear surface).
pub fn height_of_terrain(t: &Terrain, lat: f64, lon: f64) -> Option<f64> {
    let p = world(t, [lat, lon, 0.0])?;
    let g = t.frame.world_to_grid(p);
    t.height_at_grid(g.x, g.y)
}

/// Azimuth from true north and elevation above the horizontal (degrees) of world vector `v`
/// (grid +y is north, +x east, the base normal up).
pub fn azimuth_elevation(t: &Terrain, v: DVec3) -> (f64, f64) {
    let v = v.normalize_or_zero();
    let (e, n, u) = (
        v.dot(t.frame.axis_x),
        v.dot(t.frame.axis_y),
        v.dot(t.frame.normal),
    );
    (
        e.atan2(n).to_degrees(),
        u.clamp(-1.0, 1.0).asin().to_degrees(),
    )
}

/// World unit vector of azimuth `az` (from true north, clockwise) and elevation `el` (degrees).
pub fn direction(t: &Terrain, az: f64, el: f64) -> DVec3 {
    let (a, e) = (az.to_radians(), el.to_radians());
    let f = &t.frame;
    f.axis_x * (a.sin() * e.cos()) + f.axis_y * (a.cos() * e.cos()) + f.normal * e.sin()
}

/// An entity's body frame at the frame's host time, for requests given in it.
pub(super) struct EntityFrame {
    /// Geodetic position of its origin.
    pub(super) origin: [f64; 3],
    /// Columns right, forward, up in east-north-up (`geom::attitude_matrix`).
    pub(super) attitude: glam::DMat3,
}

impl EntityFrame {
    pub(super) fn of(g: &Ground, s: &Session, id: u16, now_host: f64) -> Option<EntityFrame> {
        let p = crate::world::entity_placement(s, g.terrain, id, now_host)?;
        Some(EntityFrame {
            origin: p.geodetic,
            attitude: p.attitude,
        })
    }

    /// Geodetic position of the body offsets `[x forward, y right, z down]` (metres).
    pub(super) fn point(&self, xyz: [f64; 3]) -> [f64; 3] {
        crate::world::body_point(self.origin, &self.attitude, xyz)
    }

    /// Azimuth from true north and elevation (degrees) of the body direction at azimuth `az`
    /// from the x axis towards y and elevation `el` above the xy plane.
    pub(super) fn az_el(&self, g: &Ground, az: f64, el: f64) -> (f64, f64) {
        let (a, e) = (az.to_radians(), el.to_radians());
        let m = &self.attitude;
        let d =
            m.y_axis * (a.cos() * e.cos()) + m.x_axis * (a.sin() * e.cos()) + m.z_axis * e.sin();
        azimuth_elevation(g.terrain, d)
    }

    /// The body offsets `[x forward, y right, z down]` of geodetic `lla`.
    pub(super) fn offsets(&self, lla: [f64; 3]) -> [f64; 3] {
        crate::world::body_offsets(self.origin, &self.attitude, lla)
    }
}

/// A request's point: geodetic as given, or body offsets of `entity` (`in_entity`).
pub(super) fn request_point(
    entity: Option<&EntityFrame>,
    in_entity: bool,
    p: [f64; 3],
) -> Option<[f64; 3]> {
    if in_entity {
        Some(entity?.point(p))
    } else {
        Some(p)
    }
}

/// What the queries are answered on: the scene's terrain, or on a database scene the database
/// at full resolution (`full`) with the tiles it is read through (the database itself, or
/// resident only: `db::ResidentOnly`).
#[derive(Clone, Copy)]
pub struct Ground<'a> {
    pub terrain: &'a Terrain,
    pub full: Option<(&'a FullResolution, &'a dyn Tiles)>,
    /// The entities drawn this frame: lines of sight meet them too.
    pub bodies: &'a Bodies,
    /// How many intersections a line of sight is answered with.
    pub los: LosResponses,
}

/// How many intersections a line-of-sight request is answered with (`--cigi-los`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LosResponses {
    /// One response: the nearest intersection (`count` 1).
    #[default]
    First,
    /// One response for every surface the line meets, nearest first: each entity where it
    /// meets it first and the terrain where it meets it first (`count` says how many).
    Every,
}

impl Ground<'_> {
    /// Height above MSL at `lat`, `lon`: the scene terrain's bilinear surface, or the
    /// database's finest tile there.
    pub(super) fn hot(&self, lat: f64, lon: f64) -> Option<f64> {
        match self.full {
            None => height_of_terrain(self.terrain, lat, lon),
            Some((f, tiles)) => f
                .height_in(tiles, lat, lon)
                .map_err(|e| log::debug!("CIGI HOT at {lat}, {lon}: {e}"))
                .ok()
                .flatten()
                .map(|s| s.height),
        }
    }

    /// A height no [`Ground::hot`] answer exceeds: the scene terrain's highest sample, or the
    /// database's highest tile maximum.
    pub(super) fn highest(&self) -> f64 {
        match self.full {
            None => f64::from(self.terrain.max_height),
            Some((f, _)) => f.highest(),
        }
    }

    /// The database's finest-level window around geodetic `a` and `b` (`None` without a
    /// database: the scene's terrain is used; `Some(Err)`: off the database, or a tile not
    /// resident, which the resident-only tiles record).
    pub(super) fn window(&self, a: [f64; 3], b: [f64; 3]) -> Option<Result<Terrain, ()>> {
        let (f, tiles) = self.full?;
        Some(match f.window_in(tiles, a, b) {
            Ok(Some(t)) => Ok(t),
            Ok(None) => Err(()),
            Err(e) => {
                log::debug!("CIGI query window around {a:?}, {b:?}: {e}");
                Err(())
            }
        })
    }
}
