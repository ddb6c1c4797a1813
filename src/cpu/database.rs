//! Queries on a database scene at the database's full resolution, whatever level the scene
//! renders: heights from the finest tile at the position (`db::query`), lines of sight over a
//! window of the finest level that fits around the segment. Tiles come through the
//! database's bounded cache, so repeated queries in one region read the file once; the
//! database is opened once and the windows are made from its cache. The `_in` forms take the
//! tiles from a [`Tiles`] (resident only: `db::ResidentOnly`, which never reads).

use super::query::line_of_sight;
use crate::db::{self, Database, SurfaceSample, Tiles};
use crate::terrain::{Terrain, TerrainDesc};
use crate::{Error, Result};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A database scene's terrain description and its database, open.
pub struct FullResolution {
    db: Arc<Database>,
    desc: TerrainDesc,
    base_dir: PathBuf,
    /// No surface height it answers is higher ([`Self::highest`]).
    highest: f64,
}

impl FullResolution {
    /// `None` when the terrain is not a database.
    pub fn open(desc: &TerrainDesc, base_dir: &Path) -> Result<Option<FullResolution>> {
        let Some(path) = &desc.database else {
            return Ok(None);
        };
        let db = Database::open(&base_dir.join(path))?;
        // Every tile's maximum bounds its finer samples; after sea level and the vertical
        // scale, as the heights answered.
        let top = (db.entries().iter()).fold(f64::NEG_INFINITY, |m, e| m.max(f64::from(e.max)));
        let top = desc.sea_level.map_or(top, |sea| top.max(sea));
        Ok(Some(FullResolution {
            db: Arc::new(db),
            desc: desc.clone(),
            base_dir: base_dir.to_path_buf(),
            highest: top * desc.vertical_scale,
        }))
    }

    /// A height no surface height this answers exceeds (metres above mean sea level): the
    /// database's highest tile maximum.
    pub fn highest(&self) -> f64 {
        self.highest
    }

    pub fn database(&self) -> &Database {
        &self.db
    }

    /// The database, shared (with a `db::Prefetcher` warming its cache).
    pub fn shared(&self) -> &Arc<Database> {
        &self.db
    }

    /// Geodetic `[lat, lon, alt]` of a world point of `terrain` (the scene's terrain).
    fn geodetic(terrain: &Terrain, p: DVec3) -> Result<[f64; 3]> {
        terrain.world_to_geodetic(p).ok_or_else(|| {
            Error::invalid(
                "terrain.database",
                "the scene's terrain has no geographic reference",
            )
        })
    }

    /// The surface below the world point `p` of the scene's `terrain`, at full resolution (the
    /// height above mean sea level, after `sea_level`); `None` off the database.
    pub fn height_at(&self, terrain: &Terrain, p: DVec3) -> Result<Option<SurfaceSample>> {
        let [lat, lon, _] = Self::geodetic(terrain, p)?;
        self.height_at_geodetic(lat, lon)
    }

    /// The surface at `lat`, `lon` (degrees) at full resolution, as [`Self::height_at`].
    pub fn height_at_geodetic(&self, lat: f64, lon: f64) -> Result<Option<SurfaceSample>> {
        self.height_in(&*self.db, lat, lon)
    }

    /// [`Self::height_at_geodetic`] through `tiles` (of this database): `Ok(None)` also where
    /// a resident-only `tiles` missed a tile (see its missing list).
    pub fn height_in(
        &self,
        tiles: &dyn Tiles,
        lat: f64,
        lon: f64,
    ) -> Result<Option<SurfaceSample>> {
        let s = db::height_in(tiles, lat, lon)?;
        Ok(s.map(|mut s| {
            if let Some(sea) = self.desc.sea_level {
                s.height = s.height.max(sea);
            }
            s.height *= self.desc.vertical_scale;
            s
        }))
    }

    /// Line of sight between world points `a` and `b` of the scene's `terrain` over the finest
    /// level of the database that fits a window around the segment (the scene's `curved`
    /// applies: the segment is seen from `a`). Returns the answer and the window terrain's
    /// level spacing (degrees).
    pub fn line_of_sight(&self, terrain: &Terrain, a: DVec3, b: DVec3) -> Result<(bool, f64)> {
        let (ga, gb) = (Self::geodetic(terrain, a)?, Self::geodetic(terrain, b)?);
        let local = self.window(ga, gb)?;
        let spacing = local.field.geo.map_or(f64::NAN, |g| g.dlat);
        let to_local = |g: [f64; 3]| local.geodetic_to_world("los", g);
        Ok((line_of_sight(&local, to_local(ga)?, to_local(gb)?), spacing))
    }

    /// A terrain of the finest level of the database that fits a window around geodetic
    /// points `ga` and `gb` (two samples of margin; the scene's terrain keys otherwise): the
    /// surface the full-resolution queries between them run on.
    pub fn window(&self, ga: [f64; 3], gb: [f64; 3]) -> Result<Terrain> {
        self.window_in(&*self.db, ga, gb)?
            .ok_or_else(|| db::tiles::not_read(&self.db))
    }

    /// [`Self::window`] through `tiles` (of this database); `None` where a resident-only
    /// `tiles` missed a tile (every missing tile of the window is recorded).
    pub fn window_in(
        &self,
        tiles: &dyn Tiles,
        ga: [f64; 3],
        gb: [f64; 3],
    ) -> Result<Option<Terrain>> {
        let e = self.db.header().extent;
        let finest = self.db.header().levels.last().map_or(1.0, |l| l.spacing());
        let m = 2.0 * finest;
        let w = [
            (ga[0].min(gb[0]) - m).max(e.lat_min),
            (ga[1].min(gb[1]) - m).max(e.lon_min),
            (ga[0].max(gb[0]) + m).min(e.lat_max),
            (ga[1].max(gb[1]) + m).min(e.lon_max),
        ];
        if !(w[0] < w[2] && w[1] < w[3]) {
            return Err(Error::invalid(
                "los",
                "the segment lies off the database: give points over the terrain",
            ));
        }
        let spec = db::window::resolve(&self.db, Some(w), None)?;
        let desc = TerrainDesc {
            window: Some(w),
            level: None,
            ..self.desc.clone()
        };
        Terrain::from_window(&desc, &self.base_dir, tiles, &spec)
    }
}
