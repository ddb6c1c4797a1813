//! The terrain database: many DEMs compiled into one tiled, multi-resolution file.
//!
//! `relief db build OUT SOURCES…` compiles SRTM `.hgt` tiles and GeoTIFFs in degrees —
//! mixed resolutions, a coarse global DEM under fine insets — into one file of tiles
//! addressed by (level, x, y) on a geographic grid anchored at longitude −180, latitude −90
//! ([`build()`]). Level 0 is the coarsest, one tile over the whole extent; each finer level
//! halves the spacing, down to the finest source's. A tile of N×N cells holds (N+1)² samples
//! (neighbours share their edge samples, so they meet without cracks) and its cell maxima,
//! where a cell's maximum bounds its own bilinear patch and every finer sample in its closed
//! footprint (their in-tile pyramid is made again on reading). The header carries the format version, the index a CRC-32 per tile
//! ([`mod@format`]). [`Database`] opens and checks a file and reads tiles through a bounded
//! cache ([`reader`]); [`window`] turns a region of one level into a [`Heightfield`] with its
//! georeference, which a scene renders as it renders a `.hgt`.
//!
//! [`query`] answers heights at full resolution through the cache, or resident only
//! ([`tiles`]: tiles not in memory are reported, not read), and [`prefetch`] warms the cache
//! on a worker thread. [`pager`] keeps the tiles a view needs in a fixed pool of slots, read on
//! worker threads; [`synth`](mod@synth) writes procedural mosaics. Not here yet: paged rendering (docs/database.md).
//!
//! [`Heightfield`]: crate::terrain::Heightfield

pub mod build;
pub mod format;
pub mod pager;
pub mod parse;
pub mod prefetch;
pub mod query;
pub mod reader;
pub mod source;
pub mod synth;
pub mod tile;
pub mod tiles;
pub mod window;

pub use build::{build, BuildOptions, BuildReport};
pub use format::{Extent, Header, IndexEntry, LevelInfo, SourceInfo, TileId};
pub use prefetch::Prefetcher;
pub use query::{height_at, height_in, height_resident, SurfaceSample};
pub use reader::Database;
pub use synth::{synth, SynthOptions};
pub use tile::Tile;
pub use tiles::{Lookup, Resident, ResidentOnly, Tiles};
pub use window::WindowSpec;
