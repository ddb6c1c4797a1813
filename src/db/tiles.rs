//! Where a query's tiles come from: read through the database's cache ([`Database`]: a tile
//! not cached is read from the file), or **resident only** ([`ResidentOnly`]: only tiles
//! already in the cache; one stored but not cached is recorded as missing and not read). The
//! resident-only lookups let a caller that must not wait for the disk (the CIGI IG's frame)
//! learn which tiles a query needs, hand them to a [`Prefetcher`], and answer later.
//!
//! [`Prefetcher`]: super::prefetch::Prefetcher

use super::format::TileId;
use super::reader::Database;
use super::tile::Tile;
use crate::{Error, Result};
use std::collections::BTreeSet;
use std::sync::{Arc, Mutex};

/// What a tile lookup found.
#[derive(Clone, Debug)]
pub enum Lookup {
    /// The tile.
    Tile(Arc<Tile>),
    /// The database holds no such tile.
    NotStored,
    /// Stored, but not in memory (resident-only lookups): recorded, not read.
    NotResident,
}

/// Tiles of one database for the queries (`db::height_in`, `db::window::read_from`).
pub trait Tiles: Sync {
    /// The database: header and index.
    fn database(&self) -> &Database;
    /// The tile `id`. Errors: a tile that fails its checks.
    fn lookup(&self, id: TileId) -> Result<Lookup>;
}

impl Tiles for Database {
    fn database(&self) -> &Database {
        self
    }

    /// Reads the tile when it is not cached.
    fn lookup(&self, id: TileId) -> Result<Lookup> {
        Ok(match self.tile(id)? {
            Some(t) => Lookup::Tile(t),
            None => Lookup::NotStored,
        })
    }
}

/// The error of a reading query that came back without its value (a reading [`Tiles`] never
/// misses a tile, so this does not happen).
pub(crate) fn not_read(db: &Database) -> Error {
    Error::invalid(
        "terrain.database",
        format!("{}: a tile was not read", db.path().display()),
    )
}

/// Resident-only lookups on a database: cached tiles, the others recorded as missing.
pub struct ResidentOnly<'a> {
    db: &'a Database,
    missing: Mutex<BTreeSet<TileId>>,
}

/// A resident-only query's outcome: its value, or the tiles it needs that are not in memory.
#[derive(Clone, Debug, PartialEq)]
pub enum Resident<T> {
    Ready(T),
    /// The stored tiles it looked up that were not cached (sorted, each once); some it would
    /// look up after them may be missing too.
    Missing(Vec<TileId>),
}

impl<'a> ResidentOnly<'a> {
    pub fn new(db: &'a Database) -> ResidentOnly<'a> {
        ResidentOnly {
            db,
            missing: Mutex::new(BTreeSet::new()),
        }
    }

    /// The tiles looked up so far that are stored but not cached, sorted.
    pub fn missing(&self) -> Vec<TileId> {
        let m = self.missing.lock().unwrap_or_else(|e| e.into_inner());
        m.iter().copied().collect()
    }

    /// Runs `f` on resident tiles only: `Ready` with its value when every tile it looked up
    /// was cached (or not stored), else `Missing` (its value, made without them, is dropped).
    pub fn run<T>(db: &Database, f: impl FnOnce(&dyn Tiles) -> Result<T>) -> Result<Resident<T>> {
        let r = ResidentOnly::new(db);
        let value = f(&r)?;
        let missing = r.missing();
        Ok(if missing.is_empty() {
            Resident::Ready(value)
        } else {
            Resident::Missing(missing)
        })
    }
}

impl Tiles for ResidentOnly<'_> {
    fn database(&self) -> &Database {
        self.db
    }

    fn lookup(&self, id: TileId) -> Result<Lookup> {
        if !self.db.has_tile(id) {
            return Ok(Lookup::NotStored);
        }
        Ok(match self.db.cached_tile(id) {
            Some(t) => Lookup::Tile(t),
            None => {
                self.missing
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .insert(id);
                Lookup::NotResident
            }
        })
    }
}
