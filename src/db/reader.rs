//! Opening a database: the header and the index checked, tiles read on demand, each checked
//! against its CRC, and kept in a host cache bounded in bytes (least recently used first out).

use super::format::{self, Header, IndexEntry, TileId};
use super::parse;
use super::tile::{self, Tile};
use crate::{fileio, Error, Result};
use std::collections::{BTreeMap, HashMap};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Default size of the tile cache: 256 MiB.
pub const DEFAULT_CACHE_BYTES: u64 = 256 << 20;

/// Memory one index entry takes once loaded (the entry and its hash-map slot).
const ENTRY_MEMORY: u64 = 96;

/// Where the bytes come from: the file, or (tests, mutation runs) bytes in memory.
enum Store {
    File(std::fs::File),
    Bytes(Vec<u8>),
}

impl Store {
    fn read_at(&mut self, path: &Path, offset: u64, len: u64) -> Result<Vec<u8>> {
        match self {
            Store::File(f) => {
                f.seek(SeekFrom::Start(offset))
                    .map_err(|e| Error::io(path, e))?;
                let mut out = Vec::with_capacity(len as usize);
                f.take(len)
                    .read_to_end(&mut out)
                    .map_err(|e| Error::io(path, e))?;
                if out.len() as u64 != len {
                    return Err(Error::format(
                        path,
                        format!("the file ends at byte {} inside data it declares up to byte {}: it is truncated (or was changed while open)", offset + out.len() as u64, offset + len),
                    ));
                }
                Ok(out)
            }
            Store::Bytes(b) => {
                let end = offset.saturating_add(len);
                b.get(offset as usize..end as usize)
                    .map(<[u8]>::to_vec)
                    .ok_or_else(|| {
                        Error::format(
                            path,
                            format!("bytes {offset}..{end} are past the end ({} bytes)", b.len()),
                        )
                    })
            }
        }
    }
}

/// The tile cache: tiles by id with their last use, and the ids by last use.
#[derive(Default)]
struct Cache {
    tiles: HashMap<TileId, (Arc<Tile>, u64)>,
    by_use: BTreeMap<u64, TileId>,
    clock: u64,
    bytes: u64,
}

/// An open database.
pub struct Database {
    path: PathBuf,
    header: Header,
    index: HashMap<TileId, IndexEntry>,
    entries: Vec<IndexEntry>,
    file_len: u64,
    store: Mutex<Store>,
    cache: Mutex<Cache>,
    cache_limit: u64,
}

impl std::fmt::Debug for Database {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Database")
            .field("path", &self.path)
            .field("tiles", &self.entries.len())
            .finish()
    }
}

impl Database {
    /// Opens `path`: checks the magic, the format version, the header and the index (their
    /// CRCs and every field) before anything the header declares is allocated.
    pub fn open(path: &Path) -> Result<Database> {
        let (file, len) = fileio::open_regular(path)?;
        Self::from_store(path, Store::File(file), len)
    }

    /// [`Database::open`] on the bytes of a file; `path` names it in errors.
    pub fn from_bytes(path: &Path, bytes: Vec<u8>) -> Result<Database> {
        let len = bytes.len() as u64;
        Self::from_store(path, Store::Bytes(bytes), len)
    }

    fn from_store(path: &Path, mut store: Store, file_len: u64) -> Result<Database> {
        let head = store.read_at(path, 0, 16.min(file_len)).unwrap_or_default();
        let header_len = format::check_preamble(&head, path, file_len)?;
        let bytes = store.read_at(path, 0, header_len)?;
        format::check_crc(&bytes, path, "header")?;
        let header = parse::parse_header(&bytes, path, file_len)?;
        let index_len = header.data_offset - header.index_offset;
        fileio::check_alloc(
            path.display(),
            index_len.saturating_add(header.tile_count.saturating_mul(ENTRY_MEMORY)),
        )?;
        let bytes = store.read_at(path, header.index_offset, index_len)?;
        format::check_crc(&bytes, path, "index")?;
        let entries = parse::parse_index(&bytes, &header, path, file_len)?;
        let index = entries.iter().map(|e| (e.id, *e)).collect();
        Ok(Database {
            path: path.to_path_buf(),
            header,
            index,
            entries,
            file_len,
            store: Mutex::new(store),
            cache: Mutex::new(Cache::default()),
            cache_limit: DEFAULT_CACHE_BYTES,
        })
    }

    /// Sets the tile cache's bound in bytes (at least one tile is always kept).
    pub fn set_cache_bytes(&mut self, bytes: u64) {
        self.cache_limit = bytes;
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }
    /// Every tile's index entry, sorted by level, y, x.
    pub fn entries(&self) -> &[IndexEntry] {
        &self.entries
    }
    /// The file's size in bytes.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }
    /// Cells per tile side.
    pub fn tile_cells(&self) -> usize {
        self.header.tile as usize
    }
    /// The tile's index entry, where it is stored.
    pub fn entry(&self, id: TileId) -> Option<&IndexEntry> {
        self.index.get(&id)
    }
    /// Whether the tile is stored.
    pub fn has_tile(&self, id: TileId) -> bool {
        self.index.contains_key(&id)
    }
    /// Bytes of tiles in the cache now.
    pub fn cached_bytes(&self) -> u64 {
        self.cache.lock().unwrap_or_else(|e| e.into_inner()).bytes
    }

    /// The tile `id`, or `None` where the database holds no such tile. Its blob is read,
    /// checked against the CRC in the index (a mismatch is an error naming the file and the
    /// tile) and decoded; the tile is then kept in the cache.
    pub fn tile(&self, id: TileId) -> Result<Option<Arc<Tile>>> {
        let Some(entry) = self.index.get(&id) else {
            return Ok(None);
        };
        if let Some(tile) = self.cached_tile(id) {
            return Ok(Some(tile));
        }
        let n = self.tile_cells();
        fileio::check_alloc(
            self.path.display(),
            Tile::bytes(n).saturating_add(entry.length as u64),
        )?;
        let blob = self
            .store
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .read_at(&self.path, entry.offset, entry.length as u64)?;
        let crc = crc32fast::hash(&blob);
        if crc != entry.crc {
            return Err(Error::format(
                &self.path,
                format!(
                    "{id}: its checksum does not match (stored {:08x}, computed {crc:08x}): the tile is corrupt; rebuild the database with `relief db build`",
                    entry.crc
                ),
            ));
        }
        let tile = Arc::new(tile::decode_tile(&blob, n, &self.path, id)?);
        self.remember(id, tile.clone());
        Ok(Some(tile))
    }

    /// The tile `id` when it is in the cache now (its last use updated), else `None`: never
    /// reads the file, so it does not wait for the disk.
    pub fn cached_tile(&self, id: TileId) -> Option<Arc<Tile>> {
        let mut c = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        c.clock += 1;
        let now = c.clock;
        let (tile, used) = c.tiles.get_mut(&id)?;
        let (tile, old) = (tile.clone(), *used);
        *used = now;
        c.by_use.remove(&old);
        c.by_use.insert(now, id);
        Some(tile)
    }

    fn remember(&self, id: TileId, tile: Arc<Tile>) {
        let size = Tile::bytes(tile.n);
        let mut c = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        if c.tiles.contains_key(&id) {
            return;
        }
        while c.bytes + size > self.cache_limit && !c.by_use.is_empty() {
            let (&used, &old) = c.by_use.iter().next().expect("not empty");
            c.by_use.remove(&used);
            c.tiles.remove(&old);
            c.bytes -= size;
        }
        c.clock += 1;
        let now = c.clock;
        c.tiles.insert(id, (tile, now));
        c.by_use.insert(now, id);
        c.bytes += size;
    }

    /// Reads and checks every tile (CRC and contents); the first bad one is the error.
    /// `progress(done, total)` after each.
    pub fn verify(&self, progress: &dyn Fn(u64, u64)) -> Result<()> {
        let total = self.entries.len() as u64;
        for (k, e) in self.entries.iter().enumerate() {
            self.tile(e.id)?;
            progress(k as u64 + 1, total);
        }
        Ok(())
    }
}
