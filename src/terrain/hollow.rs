//! A database window held without its samples: the terrain of a scene rendered through the
//! paged tile pool (`[terrain] memory`, `--terrain-memory`). The window keeps everything that
//! places it and shapes its traversal — size, georeference, metric spacing, frame, pyramid
//! levels, height range — so world coordinates and the paged renderer's uniforms are those of
//! the window loaded whole, but neither the height field nor the maximum pyramid is built: host
//! memory does not grow with the window. The height range comes from the database's index
//! (`db::window::height_bounds`, no tile read); heights asked of the terrain (camera and
//! object placement, height above ground) come from the database at full resolution
//! (`db::height_at`) through its tile cache, bounded by [`CACHE_BYTES`].
//!
//! A frame's thread asks through [`Hollow::height_now`] instead, which never waits for the
//! disk: it answers from the tiles in the cache (the finest level there), hands the tiles it
//! missed to a background [`Prefetcher`], and says whether its answer is the full-resolution
//! one; a frame or two later it is.

use super::{HeightMapping, Heightfield, MaxPyramid, Terrain, TerrainDesc};
use crate::db::{self, Database, Lookup, Prefetcher, ResidentOnly, Tile, TileId, Tiles};
use crate::{Error, Result};
use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// The tile cache of a hollow terrain's database (its height queries touch a few tiles).
pub const CACHE_BYTES: u64 = 16 << 20;

/// Where a hollow terrain's heights come from.
#[derive(Clone, Debug)]
pub struct Hollow {
    db: Arc<Database>,
    /// `terrain.sea_level` and `vertical_scale`.
    heights: HeightMapping,
    /// What [`Hollow::height_now`] answers from besides the cache; shared with the windows
    /// that follow the eye.
    now: Arc<Now>,
}

/// The tiles [`Hollow::height_now`] has without the disk, and the reader of those it misses.
#[derive(Debug, Default)]
struct Now {
    /// The database's coarsest level, read when the window is opened (where it has at most
    /// [`PINNED_TILES`] tiles): an answer everywhere over the data, however cold the cache.
    pinned: HashMap<TileId, Arc<Tile>>,
    /// Reads the tiles missed: started on the first miss (`None` when its thread could not
    /// start).
    prefetch: OnceLock<Option<Prefetcher>>,
}

/// Most tiles of the coarsest level a hollow window holds for [`Hollow::height_now`] (a
/// database's coarsest level has one to a few).
pub const PINNED_TILES: usize = 16;

/// The tiles a frame's height query reads: the pinned coarsest level, then the cache.
struct NowTiles<'a> {
    pinned: &'a HashMap<TileId, Arc<Tile>>,
    cached: ResidentOnly<'a>,
}

impl Tiles for NowTiles<'_> {
    fn database(&self) -> &Database {
        self.cached.database()
    }

    fn lookup(&self, id: TileId) -> Result<Lookup> {
        match self.pinned.get(&id) {
            Some(t) => Ok(Lookup::Tile(Arc::clone(t))),
            None => self.cached.lookup(id),
        }
    }
}

/// The surface height a frame's thread gets now ([`Hollow::height_now`],
/// `Terrain::height_now`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundNow {
    /// Metres (sea level and vertical scale applied).
    pub height: f64,
    /// Whether it is the full-resolution height (`Terrain::height_at_grid`'s); otherwise a
    /// coarser level's, while the finer tile is read in the background.
    pub exact: bool,
}

impl Hollow {
    /// The database the heights are read from.
    pub fn database(&self) -> &Database {
        &self.db
    }

    /// The same database, shared (a moved window reads through it).
    pub fn shared_database(&self) -> Arc<Database> {
        Arc::clone(&self.db)
    }

    /// The prefetcher of [`Hollow::height_now`]'s misses, once one has been missed (tests
    /// wait on it).
    pub fn prefetcher(&self) -> Option<&Prefetcher> {
        self.now.prefetch.get().and_then(Option::as_ref)
    }

    /// How many tiles of the coarsest level the window holds for [`Hollow::height_now`].
    pub fn pinned_tiles(&self) -> usize {
        self.now.pinned.len()
    }

    /// [`Hollow::height_at_grid`] for a caller that must not wait for the disk (a frame's
    /// thread: the window's height above ground, CIGI's ground clamping): the database's
    /// surface from the tiles in its cache and the coarsest level's (held since the window
    /// opened), on the finest level they have there (`db::height_resident`). Tiles of finer
    /// levels that are stored but not cached go to a background prefetcher, finest first, and
    /// the answer is marked inexact until they are in. `None` where no level held has data
    /// there.
    pub fn height_now(&self, geo: super::GeoRef, x: f64, y: f64) -> Option<GroundNow> {
        let (lat, lon) = (geo.lat0 + y * geo.dlat, geo.lon0 + x * geo.dlon);
        let tiles = NowTiles {
            pinned: &self.now.pinned,
            cached: ResidentOnly::new(&self.db),
        };
        let sample = match db::height_resident(&tiles, lat, lon) {
            Ok(s) => s,
            Err(e) => {
                log::warn!("terrain height at latitude {lat}, longitude {lon}: {e}");
                return None;
            }
        };
        let missing = tiles.cached.missing();
        let exact = missing.is_empty();
        if !exact {
            let prefetch = self.now.prefetch.get_or_init(|| {
                Prefetcher::new(Arc::clone(&self.db))
                    .map_err(|e| log::warn!("terrain heights: {e}; they are read when asked"))
                    .ok()
            });
            match prefetch {
                Some(p) => {
                    // The finest first: the tile of the exact answer.
                    p.request(missing.into_iter().rev());
                }
                // No thread to read them: read them here, as `height_at_grid` does.
                None => {
                    return self.height_at_grid(geo, x, y).map(|h| GroundNow {
                        height: h,
                        exact: true,
                    })
                }
            }
        }
        sample.map(|s| GroundNow {
            height: self.heights.height(s.height),
            exact,
        })
    }

    /// Height (metres, sea level and vertical scale applied) of the surface at grid position
    /// `(x, y)` of the window georeferenced by `geo`: the database's bilinear surface there on
    /// its finest level with data (`db::height_at`; for a window of the finest level the
    /// window's own surface, except in voids, which the database answers from a coarser level
    /// where a loaded window fills them). The sea level clamps the interpolated height (a
    /// loaded window clamps the samples: they differ only in cells crossing sea level).
    /// `None` where the database has no data or a tile fails its checks (logged).
    pub fn height_at_grid(&self, geo: super::GeoRef, x: f64, y: f64) -> Option<f64> {
        let (lat, lon) = (geo.lat0 + y * geo.dlat, geo.lon0 + x * geo.dlon);
        let h = match db::height_at(&self.db, lat, lon) {
            Ok(s) => s?.height,
            Err(e) => {
                log::warn!("terrain height at latitude {lat}, longitude {lon}: {e}");
                return None;
            }
        };
        Some(self.heights.height(h))
    }
}

/// The terrain of `desc`'s window of the database at `path` (`window`, `level` as a loaded
/// window resolves them), hollow: see the module.
pub(super) fn window(
    desc: &TerrainDesc,
    base_dir: &Path,
    path: &Path,
    window: Option<[f64; 4]>,
    level: Option<u32>,
) -> Result<Terrain> {
    let mut database = Database::open(path)?;
    database.set_cache_bytes(CACHE_BYTES);
    // A paged window starts on a tile's corner; the scene's metres stay those of its own
    // window (the in-memory one).
    let scene_window = db::window::resolve(&database, window, level)?;
    let spec = db::window::on_tile_corners(scene_window, database.tile_cells());
    let now = Arc::new(Now {
        pinned: pin_coarsest(&database)?,
        prefetch: OnceLock::new(),
    });
    anchored(
        desc,
        base_dir,
        Arc::new(database),
        now,
        &spec,
        &scene_window,
    )
}

/// The tiles of `database`'s coarsest level, read now, where there are at most
/// [`PINNED_TILES`] (none otherwise). Errors: a tile that fails its checks.
fn pin_coarsest(database: &Database) -> Result<HashMap<TileId, Arc<Tile>>> {
    let coarsest: Vec<TileId> = database
        .entries()
        .iter()
        .map(|e| e.id)
        .take_while(|id| id.level == 0)
        .collect();
    let mut pinned = HashMap::new();
    if coarsest.len() > PINNED_TILES {
        return Ok(pinned);
    }
    for id in coarsest {
        if let Some(t) = database.tile(id)? {
            pinned.insert(id, t);
        }
    }
    Ok(pinned)
}

/// The terrain of `desc` over window `spec` of `database` (opened from `desc`'s path, its
/// cache bounded: [`CACHE_BYTES`]), hollow: a paged window, also where it moves to follow the
/// eye (sharing the database, its index and cache, with the window it replaces).
pub fn window_spec(
    desc: &TerrainDesc,
    base_dir: &Path,
    from: &Hollow,
    spec: &db::WindowSpec,
) -> Result<Terrain> {
    let now = Arc::clone(&from.now);
    anchored(desc, base_dir, from.shared_database(), now, spec, spec)
}

/// [`window_spec`] placed in the metres of window `anchor` of the same level (the scene's own
/// window, which `spec` extends out to a tile corner): the metric spacing at `anchor`'s centre
/// latitude, and the world origin at `anchor`'s south-west sample, so that a position in metres
/// lands on the sample it lands on in the in-memory window of `anchor`.
fn anchored(
    desc: &TerrainDesc,
    base_dir: &Path,
    database: Arc<Database>,
    now: Arc<Now>,
    spec: &db::WindowSpec,
    anchor: &db::WindowSpec,
) -> Result<Terrain> {
    let spec = *spec;
    let path = database.path().to_path_buf();
    let path = path.as_path();
    let geo = db::window::georef(&database, &spec);
    let (lo, hi) = db::window::height_bounds(&database, &spec).ok_or_else(|| {
        Error::format(
            path,
            format!(
                "no tile under the window (level {}, {}x{} samples) has data",
                spec.level, spec.width, spec.height
            ),
        )
    })?;
    let heights = HeightMapping::of(desc)?;
    let (lo, hi) = match heights.sea_level {
        Some(s) => (lo.max(s), hi.max(s)),
        None => (lo, hi),
    };
    super::check_height_range(desc, base_dir, (lo, hi))?;
    let vs = heights.vertical_scale;
    let range = super::checked_range((super::scaled(lo, vs), super::scaled(hi, vs)), vs)?;
    let field = Heightfield {
        width: spec.width,
        height: spec.height,
        heights: Vec::new(),
        spacing: desc
            .cell_size
            .unwrap_or_else(|| db::window::georef(&database, anchor).metric_spacing(anchor.height)),
        geo: Some(geo),
        voids_filled: 0,
    };
    log::info!(
        "{}: level {} window of {}x{} samples held hollow (paged): heights {}..{} m from the index",
        path.display(),
        spec.level,
        spec.width,
        spec.height,
        range.0,
        range.1
    );
    let mut frame = super::desc_frame(desc, field.spacing)?;
    let (di, dj) = ((anchor.i0 - spec.i0) as f64, (anchor.j0 - spec.j0) as f64);
    frame.origin -= frame.axis_x * (di * field.spacing[0]) + frame.axis_y * (dj * field.spacing[1]);
    let pyramid = MaxPyramid::shape(field.width, field.height);
    let mut terrain = Terrain::assemble(field, frame, pyramid, range);
    terrain.hollow = Some(Hollow {
        db: database,
        heights,
        now,
    });
    Terrain::finish(desc, base_dir, terrain)
}

impl Terrain {
    /// Whether the samples are not held (a paged database window; see [`Hollow`]).
    pub fn is_hollow(&self) -> bool {
        self.hollow.is_some()
    }
}
