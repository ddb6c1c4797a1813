//! Reading the header and the index back, every field checked against the others and
//! against the file's length before anything they declare is allocated.

use super::format::{
    Extent, Header, IndexEntry, LevelInfo, Reader, SourceInfo, TileId, FIXED_HEADER, INDEX_ENTRY,
    LEVEL_RECORD, MAX_LEVELS, MAX_TILE, MIN_TILE,
};
use super::tile::max_blob;
use crate::{fileio, Error, Result};
use std::path::Path;

/// The error for a corrupt header field.
fn corrupt(path: &Path, m: String) -> Error {
    Error::format(
        path,
        format!("{m}: the file is corrupt; rebuild it with `relief db build`"),
    )
}

/// Parses and checks the header (`bytes`: exactly the header, its CRC last, already checked
/// by [`super::format::check_preamble`] and [`super::format::check_crc`]) of a file of
/// `file_len` bytes.
pub fn parse_header(bytes: &[u8], path: &Path, file_len: u64) -> Result<Header> {
    let bad = |m: String| corrupt(path, m);
    let mut r = Reader::new(bytes, path);
    r.bytes(8, "magic")?;
    let version = r.u32("version")?;
    let len = r.u32("header length")? as usize;
    let tile = r.u32("tile cells")?;
    let level_count = r.u32("level count")?;
    let source_count = r.u32("source count")?;
    let flags = r.u32("flags")?;
    let tile_count = r.u64("tile count")?;
    let index_offset = r.u64("index offset")?;
    let data_offset = r.u64("data offset")?;
    if flags != 0 {
        return Err(bad(format!(
            "the header's flags are {flags:#x}, this version knows none"
        )));
    }
    if !tile.is_power_of_two() || !(MIN_TILE..=MAX_TILE).contains(&tile) {
        return Err(bad(format!(
            "the tile size is {tile} cells, not a power of two in {MIN_TILE}..={MAX_TILE}"
        )));
    }
    if !(1..=MAX_LEVELS).contains(&level_count) {
        return Err(bad(format!(
            "the header claims {level_count} levels, not 1..={MAX_LEVELS}"
        )));
    }
    let need = FIXED_HEADER as u64
        + level_count as u64 * LEVEL_RECORD as u64
        + source_count as u64 * 46
        + 4;
    if need > bytes.len() as u64 {
        return Err(bad(format!(
            "the header claims {level_count} levels and {source_count} sources ({need} bytes at least) in {} bytes",
            bytes.len()
        )));
    }
    let (extent, heights) = parse_extent(&mut r, path)?;
    let levels = parse_levels(&mut r, path, level_count, tile, tile_count)?;
    let sources = parse_sources(&mut r, path, source_count, level_count)?;
    if r.position() + 4 != len || len != bytes.len() {
        return Err(bad(format!(
            "the header's fields take {} bytes, its length field says {len}",
            r.position() + 4
        )));
    }
    let index_len = tile_count
        .saturating_mul(INDEX_ENTRY as u64)
        .saturating_add(4);
    if index_offset != len as u64 || data_offset != index_offset.saturating_add(index_len) {
        return Err(bad(format!(
            "the index at byte {index_offset} and the tile data at byte {data_offset} do not follow the header ({len} bytes) and an index of {tile_count} tiles"
        )));
    }
    fileio::check_declared(
        path,
        &format!("an index of {tile_count} tiles"),
        data_offset,
        file_len,
    )?;
    Ok(Header {
        version,
        tile,
        tile_count,
        index_offset,
        data_offset,
        extent,
        heights,
        levels,
        sources,
    })
}

/// The extent and the height range.
fn parse_extent(r: &mut Reader, path: &Path) -> Result<(Extent, [f32; 2])> {
    let mut ext = [0.0; 4];
    for (k, name) in ["lon_min", "lat_min", "lon_max", "lat_max"]
        .iter()
        .enumerate()
    {
        ext[k] = r.f64(name)?;
    }
    let heights = [r.f32("height min")?, r.f32("height max")?];
    let extent = Extent {
        lon_min: ext[0],
        lat_min: ext[1],
        lon_max: ext[2],
        lat_max: ext[3],
    };
    let geo_ok = ext.iter().all(|v| v.is_finite())
        && (-180.0..=180.0).contains(&extent.lon_min)
        && (-180.0..=180.0).contains(&extent.lon_max)
        && (-90.0..=90.0).contains(&extent.lat_min)
        && (-90.0..=90.0).contains(&extent.lat_max)
        && extent.lon_min < extent.lon_max
        && extent.lat_min < extent.lat_max;
    if !geo_ok {
        return Err(corrupt(
            path,
            format!("the extent {ext:?} is not a region of the earth (lon_min, lat_min, lon_max, lat_max)"),
        ));
    }
    if !(heights[0].is_finite() && heights[1].is_finite() && heights[0] <= heights[1]) {
        return Err(corrupt(
            path,
            format!("the height range {heights:?} is not finite and ordered"),
        ));
    }
    Ok((extent, heights))
}

/// The level records, coarsest first, each checked against the one before.
fn parse_levels(
    r: &mut Reader,
    path: &Path,
    count: u32,
    tile: u32,
    tile_count: u64,
) -> Result<Vec<LevelInfo>> {
    let bad = |m: String| corrupt(path, m);
    let mut levels = Vec::with_capacity(count as usize);
    for l in 0..count {
        let level = LevelInfo {
            per_degree: r.f64("level samples per degree")?,
            x0: r.u32("level x0")?,
            y0: r.u32("level y0")?,
            x1: r.u32("level x1")?,
            y1: r.u32("level y1")?,
            tiles: r.u64("level tiles")?,
        };
        check_level(&level, l, levels.last(), tile).map_err(|m| bad(format!("level {l}: {m}")))?;
        levels.push(level);
    }
    if levels[0].tiles != 1 {
        return Err(bad(format!(
            "level 0 holds {} tiles; the coarsest level is one tile",
            levels[0].tiles
        )));
    }
    let sum: u64 = levels.iter().map(|l| l.tiles).sum();
    if sum != tile_count {
        return Err(bad(format!(
            "the levels hold {sum} tiles, the header says {tile_count}"
        )));
    }
    Ok(levels)
}

/// The source records.
fn parse_sources(
    r: &mut Reader,
    path: &Path,
    count: u32,
    level_count: u32,
) -> Result<Vec<SourceInfo>> {
    let bad = |m: String| corrupt(path, m);
    let mut sources = Vec::with_capacity(count as usize);
    for k in 0..count {
        let n = r.u16("source name length")? as usize;
        let name = std::str::from_utf8(r.bytes(n, "source name")?)
            .map_err(|_| bad(format!("source {k}'s name is not UTF-8")))?
            .to_string();
        let s = SourceInfo {
            name,
            lon0: r.f64("source lon0")?,
            lat0: r.f64("source lat0")?,
            dlon: r.f64("source dlon")?,
            dlat: r.f64("source dlat")?,
            width: r.u32("source width")?,
            height: r.u32("source height")?,
            finest_level: r.u32("source finest level")?,
        };
        let ok = s.lon0.is_finite()
            && s.lat0.is_finite()
            && s.dlon.is_finite()
            && s.dlat.is_finite()
            && s.dlon > 0.0
            && s.dlat > 0.0
            && s.width >= 2
            && s.height >= 2
            && s.finest_level < level_count;
        if !ok {
            return Err(bad(format!(
                "source {k} ({}) has an impossible georeference or size",
                s.name
            )));
        }
        sources.push(s);
    }
    Ok(sources)
}

/// Checks one level record against the previous (coarser) one; `Err` says what is wrong.
fn check_level(
    l: &LevelInfo,
    index: u32,
    coarser: Option<&LevelInfo>,
    tile: u32,
) -> std::result::Result<(), String> {
    if !(l.per_degree.is_finite() && l.per_degree > 0.0 && l.per_degree < 1e9) {
        return Err(format!(
            "{} samples per degree is not a positive number below 1e9",
            l.per_degree
        ));
    }
    if let Some(c) = coarser {
        if l.per_degree != 2.0 * c.per_degree {
            return Err(format!(
                "{} samples per degree is not twice level {}'s {}",
                l.per_degree,
                index - 1,
                c.per_degree
            ));
        }
    }
    // Tiles along longitude and latitude that the level's grid can have.
    let span = |deg: f64| (deg * l.per_degree / tile as f64).ceil() + 1.0;
    let ok =
        l.x0 < l.x1 && l.y0 < l.y1 && (l.x1 as f64) <= span(360.0) && (l.y1 as f64) <= span(180.0);
    if !ok {
        return Err(format!(
            "the tile range x {}..{}, y {}..{} is not within the earth",
            l.x0, l.x1, l.y0, l.y1
        ));
    }
    if l.tiles == 0 || l.tiles > (l.x1 - l.x0) as u64 * (l.y1 - l.y0) as u64 {
        return Err(format!("{} tiles do not fit its tile range", l.tiles));
    }
    Ok(())
}

/// Parses and checks the index (`bytes`: the index, its CRC last, already checked).
pub fn parse_index(
    bytes: &[u8],
    h: &Header,
    path: &Path,
    file_len: u64,
) -> Result<Vec<IndexEntry>> {
    let mut r = Reader::new(bytes, path);
    let mut out = Vec::with_capacity(h.tile_count as usize);
    let mut per_level = vec![0u64; h.levels.len()];
    let cap = max_blob(h.tile as usize);
    for k in 0..h.tile_count {
        let e = IndexEntry {
            id: TileId {
                level: r.u32("index level")?,
                x: r.u32("index x")?,
                y: r.u32("index y")?,
            },
            voids: r.u32("index voids")?,
            offset: r.u64("index offset")?,
            length: r.u32("index length")?,
            crc: r.u32("index crc")?,
            min: r.f32("index min")?,
            max: r.f32("index max")?,
        };
        let bad = |m: String| {
            Error::format(path, format!("index entry {k} ({}): {m}: the file is corrupt; rebuild it with `relief db build`", e.id))
        };
        let Some(level) = h.levels.get(e.id.level as usize) else {
            return Err(bad(format!(
                "level {} is not one of the {} levels",
                e.id.level,
                h.levels.len()
            )));
        };
        if !(level.x0..level.x1).contains(&e.id.x) || !(level.y0..level.y1).contains(&e.id.y) {
            return Err(bad("the tile is outside its level's tile range".into()));
        }
        let end = e.offset.saturating_add(e.length as u64);
        if e.offset < h.data_offset || end > file_len || e.length == 0 || e.length as u64 > cap {
            return Err(bad(format!(
                "its {} bytes at byte {} are not within the tile data (bytes {}..{file_len})",
                e.length, e.offset, h.data_offset
            )));
        }
        let samples = (h.tile as u64 + 1).pow(2);
        if !(e.min.is_finite() && e.max.is_finite()) || e.voids as u64 > samples {
            return Err(bad(format!(
                "its height range {}..{} or void count {} is impossible",
                e.min, e.max, e.voids
            )));
        }
        if let Some(prev) = out.last().map(|p: &IndexEntry| p.id) {
            let key = |t: TileId| (t.level, t.y, t.x);
            if key(prev) >= key(e.id) {
                return Err(bad(
                    "the index is not sorted by level, y, x (or names a tile twice)".into(),
                ));
            }
        }
        per_level[e.id.level as usize] += 1;
        out.push(e);
    }
    for (l, (n, level)) in per_level.iter().zip(&h.levels).enumerate() {
        if *n != level.tiles {
            return Err(Error::format(
                path,
                format!("the index holds {n} tiles of level {l}, the header says {}: the file is corrupt; rebuild it with `relief db build`", level.tiles),
            ));
        }
    }
    Ok(out)
}
