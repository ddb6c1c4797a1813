//! `[terrain]` in a scene file: where the heights come from and how the grid is placed.

use super::procedural::RidgedFbm;
use crate::{Error, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `[terrain]`: height source and its placement.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TerrainDesc {
    /// Height file relative to the scene file: `.hgt`, `.tif`/`.tiff` or `.png`.
    pub source: Option<PathBuf>,
    /// Procedural terrain instead of a file.
    pub procedural: Option<RidgedFbm>,
    /// A terrain database (`relief db build`) relative to the scene file, instead of a file:
    /// a window of one of its levels is the height table.
    pub database: Option<PathBuf>,
    /// Database only: `[lat_south, lon_west, lat_north, lon_east]` in degrees (default: the
    /// database's whole extent).
    pub window: Option<[f64; 4]>,
    /// Database only: the level to read, 0 the coarsest (default: the finest level at which
    /// the window fits 16384 samples a side).
    pub level: Option<u32>,
    /// Database only: render through a paged GPU tile pool of this many MB instead of the
    /// window uploaded whole (`--terrain-memory` overrides it).
    pub memory: Option<u64>,
    /// Sample spacing in metres `[dx, dy]`; overrides the file's georeference (required for PNG).
    pub cell_size: Option<[f64; 2]>,
    /// No-data value; overrides GDAL_NODATA.
    pub nodata: Option<f64>,
    /// PNG only: metres per grey level.
    #[serde(default = "one")]
    pub png_scale: f64,
    /// PNG only: height of grey level 0.
    #[serde(default)]
    pub png_offset: f64,
    /// Vertical exaggeration.
    #[serde(default = "one")]
    pub vertical_scale: f64,
    /// World position of sample (0, 0) at height 0 (the base plane's origin).
    #[serde(default)]
    pub origin: [f64; 3],
    /// Base-plane normal (heights are measured along it).
    #[serde(default = "up")]
    pub normal: [f64; 3],
    /// Direction of grid +x in the world (made orthogonal to the normal).
    #[serde(default = "east")]
    pub axis_x: [f64; 3],
    /// RGB image draped over the terrain instead of the elevation/slope ramp.
    pub drape: Option<PathBuf>,
    /// Vertical side walls at the grid's edge down to the lowest sample (the terrain renders
    /// as a solid block); `false`: rays pass under the surface, seen from above only.
    #[serde(default = "yes")]
    pub walls: bool,
    /// The curved earth (WGS84, `geodesy::Curvature` at the eye): default on for a database,
    /// off for single height files and procedural terrain.
    pub curved: Option<bool>,
    /// Heights below this (metres, e.g. `0.0`) are raised to it at load: the sea floor of a
    /// global DEM becomes a flat sea surface.
    pub sea_level: Option<f64>,
}

fn yes() -> bool {
    true
}
fn one() -> f64 {
    1.0
}
fn up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}
fn east() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}

/// Where a terrain's heights come from.
#[derive(Clone, Copy, Debug)]
pub enum HeightSource<'a> {
    File(&'a Path),
    Procedural(&'a RidgedFbm),
    /// A window of a database level.
    Database {
        path: &'a Path,
        window: Option<[f64; 4]>,
        level: Option<u32>,
    },
}

impl TerrainDesc {
    /// The one height source the table names (exactly one of `source`, `procedural` and
    /// `database`; `window` and `level` only with `database`).
    pub fn height_source(&self) -> Result<HeightSource<'_>> {
        if self.database.is_none() {
            for (key, set) in [
                ("window", self.window.is_some()),
                ("level", self.level.is_some()),
                ("memory", self.memory.is_some()),
            ] {
                if set {
                    return Err(Error::invalid(
                        format!("terrain.{key}"),
                        "applies to a terrain database only: set `database = \"file.reliefdb\"` or remove it",
                    ));
                }
            }
        }
        match (&self.source, &self.procedural, &self.database) {
            (Some(src), None, None) => Ok(HeightSource::File(src)),
            (None, Some(p), None) => Ok(HeightSource::Procedural(p)),
            (None, None, Some(db)) => {
                if self.nodata.is_some() {
                    return Err(Error::invalid(
                        "terrain.nodata",
                        "applies to height files; a database marks no-data itself (give nodata to the sources' GeoTIFFs)",
                    ));
                }
                Ok(HeightSource::Database {
                    path: db,
                    window: self.window,
                    level: self.level,
                })
            }
            (None, None, None) => Err(Error::invalid(
                "terrain",
                "set `source = \"file.hgt|tif|png\"`, `database = \"file.reliefdb\"` or a `[terrain.procedural]` table",
            )),
            _ => Err(Error::invalid(
                "terrain",
                "set only one of `source`, `database` and `[terrain.procedural]`",
            )),
        }
    }

    /// Orthonormal (x, y, normal) axes of the base plane.
    pub fn axes(&self) -> Result<(DVec3, DVec3, DVec3)> {
        let n = DVec3::from(self.normal);
        let ax = DVec3::from(self.axis_x);
        if !n.is_finite() || n.length() < 1e-9 {
            return Err(Error::invalid(
                "terrain.normal",
                "must be a finite non-zero vector",
            ));
        }
        let n = n.normalize();
        let x = ax - n * ax.dot(n);
        if !x.is_finite() || x.length() < 1e-6 {
            return Err(Error::invalid(
                "terrain.axis_x",
                "must be finite and not parallel to terrain.normal",
            ));
        }
        let x = x.normalize();
        Ok((x, n.cross(x), n))
    }
}
