//! Warming a database's tile cache in the background: [`Prefetcher::request`] queues tile ids
//! (each once while it is queued or being read) and returns at once; one worker thread reads
//! them through [`Database::tile`], which keeps them in the shared cache, so a later
//! resident-only lookup (`db::tiles::ResidentOnly`) finds them. Dropping the prefetcher stops
//! the worker after the tile it is reading (the rest of the queue is dropped) and joins it.

use super::format::TileId;
use super::reader::Database;
use crate::{Error, Result};
use std::collections::{HashSet, VecDeque};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the prefetcher did so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PrefetchCounts {
    /// Ids queued (not counting those already queued, being read or cached).
    pub requested: u64,
    /// Requests done: the tile read into the cache (or found there meanwhile).
    pub read: u64,
    /// Reads that failed (a damaged tile; the query that needs it reads it again and reports).
    pub failed: u64,
}

#[derive(Default)]
struct State {
    queue: VecDeque<TileId>,
    /// Queued or being read.
    pending: HashSet<TileId>,
    stop: bool,
    counts: PrefetchCounts,
}

struct Shared {
    db: Arc<Database>,
    state: Mutex<State>,
    /// Signalled when a tile is queued, one is done, or the prefetcher stops.
    changed: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// One worker thread reading requested tiles into a database's cache.
pub struct Prefetcher {
    shared: Arc<Shared>,
    worker: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Prefetcher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Prefetcher")
            .field("counts", &self.counts())
            .finish()
    }
}

impl Prefetcher {
    /// Starts the worker on `db`.
    pub fn new(db: Arc<Database>) -> Result<Prefetcher> {
        let shared = Arc::new(Shared {
            db,
            state: Mutex::new(State::default()),
            changed: Condvar::new(),
        });
        let s = shared.clone();
        let worker = std::thread::Builder::new()
            .name("relief-prefetch".into())
            .spawn(move || work(&s))
            .map_err(|e| Error::invalid("prefetch", format!("cannot start a thread: {e}")))?;
        Ok(Prefetcher {
            shared,
            worker: Some(worker),
        })
    }

    /// The database.
    pub fn database(&self) -> &Arc<Database> {
        &self.shared.db
    }

    /// Queues `ids` for reading, in order, skipping those queued, being read or cached
    /// already; returns how many were queued. Never blocks on the disk.
    pub fn request(&self, ids: impl IntoIterator<Item = TileId>) -> usize {
        let mut s = self.shared.lock();
        let mut n = 0;
        for id in ids {
            if s.pending.contains(&id) || self.shared.db.cached_tile(id).is_some() {
                continue;
            }
            s.pending.insert(id);
            s.queue.push_back(id);
            n += 1;
        }
        s.counts.requested += n as u64;
        drop(s);
        if n > 0 {
            self.shared.changed.notify_all();
        }
        n
    }

    /// Tiles queued or being read.
    pub fn pending(&self) -> usize {
        self.shared.lock().pending.len()
    }

    /// What it did so far.
    pub fn counts(&self) -> PrefetchCounts {
        self.shared.lock().counts
    }

    /// Waits until nothing is queued or being read, at most `timeout`; whether it is idle.
    pub fn wait_idle(&self, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        let mut s = self.shared.lock();
        while !s.pending.is_empty() {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            s = self
                .shared
                .changed
                .wait_timeout(s, left)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        true
    }
}

impl Drop for Prefetcher {
    fn drop(&mut self) {
        self.shared.lock().stop = true;
        self.shared.changed.notify_all();
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

/// The worker: reads queued tiles until the prefetcher stops.
fn work(shared: &Shared) {
    loop {
        let id = {
            let mut s = shared.lock();
            loop {
                if s.stop {
                    return;
                }
                if let Some(id) = s.queue.pop_front() {
                    break id;
                }
                s = shared.changed.wait(s).unwrap_or_else(|e| e.into_inner());
            }
        };
        let r = shared.db.tile(id);
        if let Err(e) = &r {
            log::debug!("prefetch {id}: {e}");
        }
        let mut s = shared.lock();
        s.pending.remove(&id);
        match r {
            Ok(_) => s.counts.read += 1,
            Err(_) => s.counts.failed += 1,
        }
        drop(s);
        shared.changed.notify_all();
    }
}
