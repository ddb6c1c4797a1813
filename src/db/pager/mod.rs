//! The host pager: which tiles of a database a view needs resident in a fixed pool of slots
//! (the GPU's terrain memory), read and decoded on worker threads, handed out within a
//! per-frame upload budget, so that no frame waits for the disk.
//!
//! [`Pager::update`] is called once a frame with the [`View`]; it never reads a tile itself
//! (the workers do) and returns at once:
//!
//! 1. the wanted set ([`want`]): every tile of the coarse **floor** levels (read once when the
//!    pager starts, never evicted, so every position always has a resident level), then finer
//!    tiles in view whose cells are at least a pixel's footprint at their distance, most
//!    needed first, up to the pool's slots;
//! 2. read requests for wanted tiles neither resident nor being read, most needed first, at
//!    most `max_reads` at a time;
//! 3. finished tiles become **uploads** (a slot and the tile) most needed first, within the
//!    frame's upload bytes, and only where the tile's parent is resident: a resident tile's
//!    ancestors are all resident, so a ray can always fall back to the finest resident level;
//! 4. a full pool evicts the least needed resident tile that is no longer wanted and has no
//!    resident child; floor tiles are never evicted.
//!
//! The page table ([`PageTable`]) says per level and tile which slot holds it.

pub mod residency;
pub mod table;
pub mod want;

use super::format::{IndexEntry, TileId};
use super::reader::Database;
use super::tile::Tile;
use crate::{Error, Result};
use std::collections::{HashMap, HashSet};
use std::sync::{mpsc, Arc, Mutex};
use std::thread::JoinHandle;

pub use residency::ResidencyMap;
pub use table::PageTable;
pub use want::{parent, View};

/// Where the pager's workers read tiles from: a [`Database`], or (tests) a wrapper around one.
pub trait TileStore: Send + Sync + 'static {
    /// The database: header and index.
    fn database(&self) -> &Database;
    /// Reads, checks and decodes a tile (may block on the disk: called on workers only).
    fn read(&self, id: TileId) -> Result<Option<Arc<Tile>>> {
        self.database().tile(id)
    }
}

impl TileStore for Database {
    fn database(&self) -> &Database {
        self
    }
}

/// Options of the pager.
#[derive(Clone, Copy, Debug)]
pub struct PagerOptions {
    /// The pool's size in bytes (`--terrain-memory MB`).
    pub pool_bytes: u64,
    /// Bytes of tiles handed out for upload per frame (at least one tile a frame).
    pub upload_bytes: u64,
    /// Worker threads.
    pub workers: usize,
    /// Most tiles being read at once.
    pub max_reads: usize,
}

/// Default pool: 256 MiB.
pub const DEFAULT_POOL_BYTES: u64 = 256 << 20;

impl Default for PagerOptions {
    fn default() -> Self {
        PagerOptions {
            pool_bytes: DEFAULT_POOL_BYTES,
            upload_bytes: 8 << 20,
            workers: 2,
            max_reads: 8,
        }
    }
}

/// Bytes of one pool slot for tiles of `n` cells: the (n+1)² heights and the in-tile max
/// pyramid, f32.
pub fn slot_bytes(n: usize) -> u64 {
    Tile::bytes(n)
}

/// A tile to copy into a pool slot.
#[derive(Clone, Debug)]
pub struct Upload {
    pub slot: u32,
    pub id: TileId,
    pub tile: Arc<Tile>,
}

/// What one update did and where the pager stands.
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    /// Tiles handed out for upload this frame, and their bytes.
    pub uploads: usize,
    pub upload_bytes: u64,
    /// Tiles evicted this frame.
    pub evictions: usize,
    /// Wanted tiles this frame, and how many of them are not resident.
    pub wanted: usize,
    pub missing: usize,
    /// Resident slots and their bytes.
    pub resident: usize,
    pub resident_bytes: u64,
    /// Reads in flight, and finished tiles waiting for upload (host memory).
    pub pending: usize,
    pub staged: usize,
    pub staged_bytes: u64,
    /// Frames so far in which a wanted tile was missing.
    pub frames_missing: u64,
    /// Seconds the update took.
    pub seconds: f64,
}

type Done = (TileId, Result<Option<Arc<Tile>>>);

/// The pager: the pool's slots, the page table, the workers.
pub struct Pager {
    store: Arc<dyn TileStore>,
    index: HashMap<TileId, IndexEntry>,
    slots: usize,
    slot_bytes: u64,
    opts: PagerOptions,
    floor: Vec<TileId>,
    floor_level: u32,
    table: PageTable,
    /// Per slot its tile.
    slot_tile: Vec<Option<TileId>>,
    free: Vec<u32>,
    pending: HashSet<TileId>,
    staged: HashMap<TileId, Arc<Tile>>,
    requests: Option<mpsc::Sender<TileId>>,
    done: mpsc::Receiver<Done>,
    workers: Vec<JoinHandle<()>>,
    wanted: Vec<TileId>,
    frames_missing: u64,
}

impl Pager {
    /// Starts the workers and reads the floor levels into the pool (blocking: before the
    /// first frame). The floor is the finest level whose tiles, with all coarser ones, fill
    /// at most half the slots; an error where level 0 alone does not fit.
    pub fn new(store: Arc<dyn TileStore>, opts: PagerOptions) -> Result<(Pager, Vec<Upload>)> {
        let db = store.database();
        let n = db.tile_cells();
        let slot_bytes = slot_bytes(n);
        let slots = (opts.pool_bytes / slot_bytes) as usize;
        let index: HashMap<TileId, IndexEntry> = db.entries().iter().map(|e| (e.id, *e)).collect();
        let levels = db.header().levels.clone();
        let mut floor_level = None;
        let mut count = 0u64;
        for (l, lv) in levels.iter().enumerate() {
            count += lv.tiles;
            if count as usize * 2 > slots && l > 0 || count as usize > slots {
                break;
            }
            floor_level = Some(l as u32);
        }
        let Some(floor_level) = floor_level else {
            return Err(Error::invalid(
                "--terrain-memory",
                format!(
                    "{} MB holds {slots} slot(s) of {} KB (tiles of {n} cells): the coarsest level alone needs {}; give more terrain memory",
                    opts.pool_bytes >> 20,
                    slot_bytes >> 10,
                    levels.first().map_or(0, |l| l.tiles)
                ),
            ));
        };
        let floor: Vec<TileId> = db
            .entries()
            .iter()
            .filter(|e| e.id.level <= floor_level)
            .map(|e| e.id)
            .collect();
        let (req_tx, req_rx) = mpsc::channel::<TileId>();
        let (done_tx, done_rx) = mpsc::channel::<Done>();
        let req_rx = Arc::new(Mutex::new(req_rx));
        let workers = (0..opts.workers.max(1))
            .map(|k| {
                let (rx, tx, store) = (req_rx.clone(), done_tx.clone(), store.clone());
                std::thread::Builder::new()
                    .name(format!("relief-pager-{k}"))
                    .spawn(move || worker(&*store, &rx, &tx))
                    .map_err(|e| {
                        Error::invalid("pager", format!("cannot start a worker thread: {e}"))
                    })
            })
            .collect::<Result<Vec<_>>>()?;
        let mut pager = Pager {
            table: PageTable::new(&levels),
            store,
            index,
            slots,
            slot_bytes,
            opts,
            floor,
            floor_level,
            slot_tile: vec![None; slots],
            free: (0..slots as u32).rev().collect(),
            pending: HashSet::new(),
            staged: HashMap::new(),
            requests: Some(req_tx),
            done: done_rx,
            workers,
            wanted: Vec::new(),
            frames_missing: 0,
        };
        let uploads = pager.load_floor()?;
        Ok((pager, uploads))
    }

    fn load_floor(&mut self) -> Result<Vec<Upload>> {
        for id in self.floor.clone() {
            self.request(id);
        }
        let mut uploads = Vec::with_capacity(self.floor.len());
        while !self.pending.is_empty() {
            let (id, r) = self.done.recv().map_err(|_| stopped())?;
            self.pending.remove(&id);
            if let Some(t) = r? {
                self.staged.insert(id, t);
            }
        }
        for id in self.floor.clone() {
            if let Some(tile) = self.staged.remove(&id) {
                let slot = self.free.pop().expect("the floor fits the pool");
                self.place(id, slot);
                uploads.push(Upload { slot, id, tile });
            }
        }
        Ok(uploads)
    }

    fn request(&mut self, id: TileId) {
        if let Some(tx) = &self.requests {
            if tx.send(id).is_ok() {
                self.pending.insert(id);
            }
        }
    }

    fn place(&mut self, id: TileId, slot: u32) {
        self.slot_tile[slot as usize] = Some(id);
        self.table.set(id, Some(slot));
    }

    /// One frame: the wanted set for `view`, new read requests, finished tiles handed out as
    /// uploads within the frame's budget (evicting where the pool is full). Never blocks on
    /// a read. A tile that failed to read (a corrupt file) is the error.
    pub fn update(&mut self, view: &View) -> Result<(Vec<Upload>, FrameStats)> {
        let t0 = std::time::Instant::now();
        let store = self.store.clone();
        let viewer = want::Viewer::new(store.database().header(), *view);
        let wanted = want::wanted(
            &viewer,
            &self.index,
            &self.floor,
            self.floor_level,
            self.slots,
        );
        // Finished reads.
        while let Ok((id, r)) = self.done.try_recv() {
            self.pending.remove(&id);
            if let Some(t) = r? {
                self.staged.insert(id, t);
            }
        }
        let want_set: HashSet<TileId> = wanted.iter().map(|w| w.0).collect();
        self.staged.retain(|id, _| want_set.contains(id));
        // Requests, most needed first.
        for (id, _) in &wanted {
            if self.pending.len() >= self.opts.max_reads {
                break;
            }
            let known = self.table.slot(*id).is_some()
                || self.pending.contains(id)
                || self.staged.contains_key(id);
            if !known {
                self.request(*id);
            }
        }
        let mut stats = FrameStats::default();
        let budget = self.opts.upload_bytes.max(self.slot_bytes);
        let mut uploads = Vec::new();
        for (id, _) in &wanted {
            if stats.upload_bytes + self.slot_bytes > budget {
                break;
            }
            let ready = self.table.slot(*id).is_none()
                && self.staged.contains_key(id)
                && parent(*id).is_none_or(|p| self.table.slot(p).is_some());
            if !ready {
                continue;
            }
            let Some(slot) = self.free_slot(&viewer, &want_set, &mut stats) else {
                break;
            };
            let tile = self.staged.remove(id).expect("staged");
            self.place(*id, slot);
            uploads.push(Upload {
                slot,
                id: *id,
                tile,
            });
            stats.uploads += 1;
            stats.upload_bytes += self.slot_bytes;
        }
        self.wanted = wanted.iter().map(|w| w.0).collect();
        stats.wanted = wanted.len();
        stats.missing = wanted
            .iter()
            .filter(|w| self.table.slot(w.0).is_none())
            .count();
        if stats.missing > 0 {
            self.frames_missing += 1;
        }
        stats.resident = self.slots - self.free.len();
        stats.resident_bytes = stats.resident as u64 * self.slot_bytes;
        stats.pending = self.pending.len();
        stats.staged = self.staged.len();
        stats.staged_bytes = self.staged.len() as u64 * self.slot_bytes;
        stats.frames_missing = self.frames_missing;
        stats.seconds = t0.elapsed().as_secs_f64();
        Ok((uploads, stats))
    }

    /// A free slot, or one freed by evicting the least needed resident tile that is not
    /// wanted, not on the floor and has no resident child.
    fn free_slot(
        &mut self,
        viewer: &want::Viewer,
        want_set: &HashSet<TileId>,
        stats: &mut FrameStats,
    ) -> Option<u32> {
        if let Some(s) = self.free.pop() {
            return Some(s);
        }
        let victim = self
            .slot_tile
            .iter()
            .flatten()
            .filter(|id| id.level > self.floor_level && !want_set.contains(id))
            .filter(|id| {
                want::children(**id)
                    .iter()
                    .all(|c| self.table.slot(*c).is_none())
            })
            .map(|id| (*id, viewer.ratio(&self.index[id])))
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))?;
        let slot = self.table.slot(victim.0).expect("resident");
        self.table.set(victim.0, None);
        self.slot_tile[slot as usize] = None;
        stats.evictions += 1;
        Some(slot)
    }

    /// The page table: per level and tile, its slot.
    pub fn page_table(&self) -> &PageTable {
        &self.table
    }
    /// Slots in the pool, and bytes of each.
    pub fn slots(&self) -> (usize, u64) {
        (self.slots, self.slot_bytes)
    }
    /// The floor: the coarse levels `0..=floor_level`, always resident.
    pub fn floor_level(&self) -> u32 {
        self.floor_level
    }
    /// Last update's wanted tiles, most needed first.
    pub fn wanted(&self) -> &[TileId] {
        &self.wanted
    }
    /// The tile in each slot.
    pub fn slot_tiles(&self) -> &[Option<TileId>] {
        &self.slot_tile
    }
    /// The store the workers read.
    pub fn store(&self) -> &Arc<dyn TileStore> {
        &self.store
    }
}

impl Drop for Pager {
    fn drop(&mut self) {
        self.requests = None;
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

fn stopped() -> Error {
    Error::invalid("pager", "the worker threads stopped")
}

/// A worker: reads the requested tiles until the pager drops its request channel.
fn worker(store: &dyn TileStore, rx: &Mutex<mpsc::Receiver<TileId>>, tx: &mpsc::Sender<Done>) {
    loop {
        let next = rx.lock().unwrap_or_else(|e| e.into_inner()).recv();
        let Ok(id) = next else { return };
        if tx.send((id, store.read(id))).is_err() {
            return;
        }
    }
}
