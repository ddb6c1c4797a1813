//! The database file: header, tile index and tile blobs, with their checksums.
//!
//! All numbers little-endian. Layout:
//!
//! ```text
//! header   magic "RELIEFDB", format version u32, header length u32, tile cells N u32,
//!          level count u32, source count u32, flags u32 (0), tile count u64,
//!          index offset u64, data offset u64, extent (lon_min, lat_min, lon_max, lat_max) f64,
//!          height min, max f32;
//!          per level (coarsest first): samples per degree f64, tile range x0, y0, x1, y1 u32
//!          (x1, y1 exclusive), tile count u64;
//!          per source: name length u16, name (UTF-8), lon0, lat0, dlon, dlat f64,
//!          width, height u32, finest level u32;
//!          CRC-32 of the header's bytes before it
//! index    per tile (sorted by level, y, x): level, x, y, void samples u32, offset u64,
//!          length u32, CRC-32 of the blob u32, min, max height f32 (40 bytes);
//!          CRC-32 of the index's bytes before it
//! blobs    one zlib stream per tile: its (N+1)² heights (row 0 south, NaN = no data), each
//!          one's f32 bits XOR those of its prediction from the samples before it; then its
//!          N² cell maxima, each one's bits XOR those of the cell's corner maximum; each array
//!          split into its four byte planes (all first bytes, then all second bytes, …),
//!          which deflate packs far better than interleaved floats. The in-tile pyramid of
//!          the cell maxima (each level the max of 2x2, down to 1) is made on reading.
//! ```
//!
//! Sample `(i, j)` of a level with `d` samples per degree is at longitude `i / d − 180`,
//! latitude `j / d − 90`; tile `(x, y)` holds samples `x·N ..= x·N + N`, `y·N ..= y·N + N`.

use crate::{fileio, Error, Result};
use std::path::Path;

/// The first bytes of every database file.
pub const MAGIC: [u8; 8] = *b"RELIEFDB";
/// The format version this code writes and reads.
pub const VERSION: u32 = 1;
/// Smallest and largest tile size (cells per side), both powers of two.
pub const MIN_TILE: u32 = 16;
pub const MAX_TILE: u32 = 4096;
/// The default tile size.
pub const DEFAULT_TILE: u32 = 256;
/// Most levels a database may have (2⁴⁰ between the finest and the coarsest spacing).
pub const MAX_LEVELS: u32 = 40;
/// Largest header read (sources' names included).
pub const MAX_HEADER: u64 = 1 << 20;
/// Bytes of the fixed part of the header, of one level record and of one index entry.
pub const FIXED_HEADER: usize = 96;
pub const LEVEL_RECORD: usize = 32;
pub const INDEX_ENTRY: usize = 40;

/// A tile's address: level (0 = coarsest) and position in that level's tile grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileId {
    pub level: u32,
    pub x: u32,
    pub y: u32,
}

impl std::fmt::Display for TileId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "tile (level {}, x {}, y {})", self.level, self.x, self.y)
    }
}

/// The region the sources cover, degrees: from the south-west to the north-east sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extent {
    pub lon_min: f64,
    pub lat_min: f64,
    pub lon_max: f64,
    pub lat_max: f64,
}

/// One level of the database.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelInfo {
    /// Samples per degree (the spacing is its inverse; each level has half the next finer's).
    pub per_degree: f64,
    /// Tile range `x0..x1`, `y0..y1` that holds every tile of the level.
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
    /// Tiles stored at this level.
    pub tiles: u64,
}

impl LevelInfo {
    /// Degrees between samples.
    pub fn spacing(&self) -> f64 {
        1.0 / self.per_degree
    }
    /// Longitude of sample column `i`.
    pub fn lon(&self, i: i64) -> f64 {
        i as f64 / self.per_degree - 180.0
    }
    /// Latitude of sample row `j`.
    pub fn lat(&self, j: i64) -> f64 {
        j as f64 / self.per_degree - 90.0
    }
}

/// A source DEM the database was compiled from.
#[derive(Clone, Debug, PartialEq)]
pub struct SourceInfo {
    /// File name (without its directory).
    pub name: String,
    /// South-west sample and steps, degrees.
    pub lon0: f64,
    pub lat0: f64,
    pub dlon: f64,
    pub dlat: f64,
    pub width: u32,
    pub height: u32,
    /// The finest level its tiles start at (it gives samples at every level it covers).
    pub finest_level: u32,
}

/// Everything the header says.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    pub version: u32,
    /// Cells per tile side (N); a tile has (N+1)² samples.
    pub tile: u32,
    pub tile_count: u64,
    pub index_offset: u64,
    pub data_offset: u64,
    pub extent: Extent,
    /// Lowest and highest sample of the whole database.
    pub heights: [f32; 2],
    /// Coarsest first.
    pub levels: Vec<LevelInfo>,
    pub sources: Vec<SourceInfo>,
}

/// One tile's entry in the index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexEntry {
    pub id: TileId,
    /// Samples with no data (outside every source, or void in all of them).
    pub voids: u32,
    pub offset: u64,
    pub length: u32,
    pub crc: u32,
    /// Lowest sample of the tile and of every finer tile below it.
    pub min: f32,
    /// Highest: the top of its cell-maximum pyramid (bounds every finer sample below it).
    pub max: f32,
}

// ---------------------------------------------------------------------------------------------
// Header and index

/// A little-endian byte writer.
#[derive(Default)]
pub struct Writer(pub Vec<u8>);

impl Writer {
    pub fn u16(&mut self, v: u16) {
        self.0.extend(v.to_le_bytes());
    }
    pub fn u32(&mut self, v: u32) {
        self.0.extend(v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.0.extend(v.to_le_bytes());
    }
    pub fn f32(&mut self, v: f32) {
        self.0.extend(v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.0.extend(v.to_le_bytes());
    }
    /// Appends the CRC-32 of everything written so far.
    pub fn crc(&mut self) {
        let c = crc32fast::hash(&self.0);
        self.u32(c);
    }
}

/// A little-endian reader over a byte slice whose errors name the file and the field.
pub struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a Path,
}

impl<'a> Reader<'a> {
    pub fn new(bytes: &'a [u8], path: &'a Path) -> Self {
        Reader { bytes, at: 0, path }
    }
    fn take(&mut self, n: usize, field: &str) -> Result<&'a [u8]> {
        match self.bytes.get(self.at..self.at.saturating_add(n)) {
            Some(b) => {
                self.at += n;
                Ok(b)
            }
            None => Err(Error::format(
                self.path,
                format!(
                    "the database header ends before its field `{field}` (byte {}): the file is truncated or corrupt; rebuild it with `relief db build`",
                    self.at
                ),
            )),
        }
    }
    pub fn u16(&mut self, field: &str) -> Result<u16> {
        Ok(u16::from_le_bytes(self.take(2, field)?.try_into().unwrap()))
    }
    pub fn u32(&mut self, field: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, field)?.try_into().unwrap()))
    }
    pub fn u64(&mut self, field: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8, field)?.try_into().unwrap()))
    }
    pub fn f32(&mut self, field: &str) -> Result<f32> {
        Ok(f32::from_le_bytes(self.take(4, field)?.try_into().unwrap()))
    }
    pub fn f64(&mut self, field: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8, field)?.try_into().unwrap()))
    }
    pub fn bytes(&mut self, n: usize, field: &str) -> Result<&'a [u8]> {
        self.take(n, field)
    }
    pub fn position(&self) -> usize {
        self.at
    }
}

/// The header's bytes (CRC included).
pub fn write_header(h: &Header) -> Vec<u8> {
    let mut w = Writer::default();
    w.0.extend(MAGIC);
    w.u32(h.version);
    w.u32(header_len(h) as u32);
    w.u32(h.tile);
    w.u32(h.levels.len() as u32);
    w.u32(h.sources.len() as u32);
    w.u32(0);
    w.u64(h.tile_count);
    w.u64(h.index_offset);
    w.u64(h.data_offset);
    let e = &h.extent;
    for v in [e.lon_min, e.lat_min, e.lon_max, e.lat_max] {
        w.f64(v);
    }
    w.f32(h.heights[0]);
    w.f32(h.heights[1]);
    for l in &h.levels {
        w.f64(l.per_degree);
        for v in [l.x0, l.y0, l.x1, l.y1] {
            w.u32(v);
        }
        w.u64(l.tiles);
    }
    for s in &h.sources {
        w.u16(s.name.len() as u16);
        w.0.extend(s.name.as_bytes());
        for v in [s.lon0, s.lat0, s.dlon, s.dlat] {
            w.f64(v);
        }
        w.u32(s.width);
        w.u32(s.height);
        w.u32(s.finest_level);
    }
    w.crc();
    debug_assert_eq!(w.0.len(), header_len(h));
    w.0
}

/// Bytes of the header of `h` (CRC included).
pub fn header_len(h: &Header) -> usize {
    FIXED_HEADER
        + h.levels.len() * LEVEL_RECORD
        + h.sources
            .iter()
            .map(|s| 2 + s.name.len() + 44)
            .sum::<usize>()
        + 4
}

/// The index's bytes (CRC included).
pub fn write_index(entries: &[IndexEntry]) -> Vec<u8> {
    let mut w = Writer(Vec::with_capacity(entries.len() * INDEX_ENTRY + 4));
    for e in entries {
        for v in [e.id.level, e.id.x, e.id.y, e.voids] {
            w.u32(v);
        }
        w.u64(e.offset);
        w.u32(e.length);
        w.u32(e.crc);
        w.f32(e.min);
        w.f32(e.max);
    }
    w.crc();
    w.0
}

/// The first 16 bytes: magic, version and header length, checked in that order (so that a
/// file of another version says so whatever follows). Returns the header length.
pub fn check_preamble(head: &[u8], path: &Path, file_len: u64) -> Result<u64> {
    if head.len() < 16 || head[..8] != MAGIC {
        return Err(Error::format(
            path,
            "not a relief database (it does not start with `RELIEFDB`): give a file written by `relief db build`",
        ));
    }
    let version = u32::from_le_bytes(head[8..12].try_into().unwrap());
    if version != VERSION {
        return Err(Error::format(
            path,
            format!(
                "database format version {version}; this relief reads version {VERSION}: rebuild the database from its sources with this relief's `relief db build`"
            ),
        ));
    }
    let len = u32::from_le_bytes(head[12..16].try_into().unwrap()) as u64;
    if len < (FIXED_HEADER + 4) as u64 || len > MAX_HEADER {
        return Err(Error::format(
            path,
            format!("the header length field says {len} bytes, not within {}..={MAX_HEADER}: the file is corrupt", FIXED_HEADER + 4),
        ));
    }
    fileio::check_declared(path, "a database header", len, file_len)?;
    Ok(len)
}

/// Checks a CRC-32 stored in the last four bytes of `bytes`; `what` names the part.
pub fn check_crc(bytes: &[u8], path: &Path, what: &str) -> Result<()> {
    let (body, tail) = bytes.split_at(bytes.len().saturating_sub(4));
    let stored = u32::from_le_bytes(tail.try_into().unwrap_or([0; 4]));
    let computed = crc32fast::hash(body);
    if stored != computed {
        return Err(Error::format(
            path,
            format!(
                "the {what} checksum does not match (stored {stored:08x}, computed {computed:08x}): the file is corrupt; rebuild it with `relief db build`"
            ),
        ));
    }
    Ok(())
}
