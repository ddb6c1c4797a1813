//! The terrain database (issue 20, first part): the compiler, the format, the reader, windows
//! of it as terrains, `relief db build|info`, on real data (SRTM N47E009 and N43E042, ETOPO20).
//!
//! * seams: N47E009 cut into 2x2 and 3x3 GeoTIFFs compiles to the same tiles, bit for bit, as
//!   the whole tile, and renders the same pictures through a database window;
//! * a window over the whole tile is the `.hgt`'s own terrain;
//! * mixed resolution: ETOPO20 under both SRTM insets: no hole at an inset's border, the step
//!   there no larger than the sources' disagreement; coarse cell maxima bound finer samples;
//! * bad input: overlapping sources, missing tiles, a corrupt tile, another format version, a
//!   truncated file, hostile headers, a window off the database.

mod common;

use common::{project_dir, relief_cli, temp_dir, terrains};
use relief::db::{self, Database, TileId};
use relief::terrain::{hgt, Heightfield};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use tiff::encoder::{colortype, TiffEncoder};
use tiff::tags::Tag;

fn s(p: &Path) -> String {
    p.display().to_string()
}

fn alps_hgt() -> PathBuf {
    terrains().join("N47E009.hgt")
}

fn etopo() -> PathBuf {
    project_dir().join("tests").join("data").join("etopo20.tif")
}

/// Compiles `sources` into `out` with the default tile size.
fn build(out: &Path, sources: &[PathBuf]) -> db::BuildReport {
    db::build(out, sources, &db::BuildOptions::default(), &|_, _| {})
        .unwrap_or_else(|e| panic!("building {}: {e}", out.display()))
}

/// Writes samples `i0..i0+w`, `j0..j0+h` of `f` (an SRTM tile at 1/1200°, south-west corner
/// (lon0, lat0)) as a geographic f32 GeoTIFF: PixelIsArea (the tiepoint at the top-left
/// pixel's corner, half a step off its sample) or PixelIsPoint (the tiepoint at the sample).
#[allow(clippy::too_many_arguments)]
fn write_piece(
    path: &Path,
    f: &Heightfield,
    lon0: f64,
    lat0: f64,
    i0: usize,
    j0: usize,
    w: usize,
    h: usize,
    area: bool,
) {
    let step = 1.0 / 1200.0;
    let mut data = Vec::with_capacity(w * h);
    for r in 0..h {
        let j = j0 + h - 1 - r;
        for i in i0..i0 + w {
            data.push(f.at(i, j));
        }
    }
    let (lon, lat) = (
        lon0 + i0 as f64 / 1200.0,
        lat0 + (j0 + h - 1) as f64 / 1200.0,
    );
    let (tie, raster_type) = if area {
        (
            [0.0, 0.0, 0.0, lon - 0.5 * step, lat + 0.5 * step, 0.0],
            1u16,
        )
    } else {
        ([0.0, 0.0, 0.0, lon, lat, 0.0], 2u16)
    };
    let file = std::fs::File::create(path).unwrap();
    let mut enc = TiffEncoder::new(std::io::BufWriter::new(file)).unwrap();
    let mut img = enc
        .new_image::<colortype::Gray32Float>(w as u32, h as u32)
        .unwrap();
    let e = img.encoder();
    e.write_tag(Tag::ModelPixelScaleTag, &[step, step, 0.0][..])
        .unwrap();
    e.write_tag(Tag::ModelTiepointTag, &tie[..]).unwrap();
    e.write_tag(
        Tag::GeoKeyDirectoryTag,
        &[1u16, 1, 0, 2, 1024, 0, 1, 2, 1025, 0, 1, raster_type][..],
    )
    .unwrap();
    img.write_data(&data).unwrap();
}

/// N47E009 cut into `k`x`k` GeoTIFF pieces sharing their border samples.
fn cut(dir: &Path, k: usize, area: bool) -> Vec<PathBuf> {
    let f = hgt::load(&alps_hgt()).unwrap();
    let c = 1200 / k;
    let mut out = Vec::new();
    for py in 0..k {
        for px in 0..k {
            let p = dir.join(format!("piece{k}-{px}-{py}.tif"));
            write_piece(&p, &f, 9.0, 47.0, px * c, py * c, c + 1, c + 1, area);
            out.push(p);
        }
    }
    out
}

/// The whole tile, 2x2 (PixelIsPoint) and 3x3 (PixelIsArea) databases, built once.
struct Seams {
    dir: PathBuf,
    whole: PathBuf,
    two: PathBuf,
    three: PathBuf,
}

/// Removes a test's directory when the test passes (a failing one keeps it for a look).
struct Cleanup(PathBuf);

impl Drop for Cleanup {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A directory under `target/test-output/` for what several tests of this process share,
/// made afresh (one name, so that runs do not pile up copies).
fn shared_dir(name: &str) -> PathBuf {
    let d = project_dir().join("target").join("test-output").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn seams() -> &'static Seams {
    static S: OnceLock<Seams> = OnceLock::new();
    S.get_or_init(|| {
        let dir = shared_dir("db-seams");
        let (whole, two, three) = (
            dir.join("whole.reliefdb"),
            dir.join("two.reliefdb"),
            dir.join("three.reliefdb"),
        );
        build(&whole, &[alps_hgt()]);
        build(&two, &cut(&dir, 2, false));
        build(&three, &cut(&dir, 3, true));
        Seams {
            dir,
            whole,
            two,
            three,
        }
    })
}

/// ETOPO20 under both SRTM insets, built once.
fn mixed() -> &'static PathBuf {
    static M: OnceLock<PathBuf> = OnceLock::new();
    M.get_or_init(|| {
        let p = shared_dir("db-mixed").join("mixed.reliefdb");
        build(&p, &[etopo(), alps_hgt(), terrains().join("N43E042.hgt")]);
        p
    })
}

fn all_tiles(d: &Database) -> HashMap<TileId, Arc<db::Tile>> {
    d.entries()
        .iter()
        .map(|e| (e.id, d.tile(e.id).unwrap().unwrap()))
        .collect()
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

// ---------------------------------------------------------------------------------------------
// Seams, at the sample level

#[test]
fn cut_sources_compile_to_the_same_tiles_bit_for_bit() {
    let s = seams();
    let whole = Database::open(&s.whole).unwrap();
    let tiles = all_tiles(&whole);
    for (name, p) in [("2x2", &s.two), ("3x3", &s.three)] {
        let d = Database::open(p).unwrap();
        assert_eq!(d.header().levels, whole.header().levels, "{name}: levels");
        assert_eq!(d.header().extent, whole.header().extent, "{name}: extent");
        let ids: Vec<TileId> = d.entries().iter().map(|e| e.id).collect();
        let want: Vec<TileId> = whole.entries().iter().map(|e| e.id).collect();
        assert_eq!(ids, want, "{name}: the same tiles");
        for id in ids {
            let (a, b) = (d.tile(id).unwrap().unwrap(), &tiles[&id]);
            assert!(
                bits(&a.heights) == bits(&b.heights),
                "{name}: {id}: heights differ"
            );
            assert!(
                bits(&a.maxima) == bits(&b.maxima),
                "{name}: {id}: cell maxima differ"
            );
        }
    }
    // Neighbouring tiles share their edge samples.
    let n = whole.tile_cells();
    let mut shared = 0;
    for (id, t) in &tiles {
        let east = TileId { x: id.x + 1, ..*id };
        let north = TileId { y: id.y + 1, ..*id };
        if let Some(e) = tiles.get(&east) {
            for j in 0..=n {
                assert_eq!(
                    t.height(n, j).to_bits(),
                    e.height(0, j).to_bits(),
                    "{id} / {east} row {j}"
                );
            }
            shared += 1;
        }
        if let Some(u) = tiles.get(&north) {
            for i in 0..=n {
                assert_eq!(
                    t.height(i, n).to_bits(),
                    u.height(i, 0).to_bits(),
                    "{id} / {north} column {i}"
                );
            }
            shared += 1;
        }
    }
    assert!(shared > 40, "only {shared} shared edges checked");
}

/// The whole tile compiled and windowed over its own extent is the `.hgt` loaded directly:
/// same size, spacing, placement, heights and pyramid.
#[test]
fn a_window_over_the_whole_tile_is_the_hgt_terrain() {
    let dir = &seams().dir;
    let scene = |terrain: &str| {
        let text = format!("[terrain]\n{terrain}\n[camera]\nposition = [1000.0, 1000.0, 3000.0]\n");
        relief::scene::Scene::parse(&text, &dir.join("scene.toml"))
            .unwrap()
            .load_terrain()
            .unwrap()
    };
    let direct = scene(&format!("source = \"{}\"", s(&alps_hgt())));
    let from_db = scene("database = \"whole.reliefdb\"");
    let (a, b) = (&direct.field, &from_db.field);
    assert_eq!((a.width, a.height), (b.width, b.height));
    assert_eq!(a.spacing, b.spacing, "metric spacing");
    assert!(bits(&a.heights) == bits(&b.heights), "heights");
    let (ga, gb) = (a.geo.unwrap(), b.geo.unwrap());
    assert_eq!(ga, gb, "georeference");
    assert_eq!(direct.frame, from_db.frame);
    assert_eq!(
        (direct.min_height, direct.max_height),
        (from_db.min_height, from_db.max_height)
    );
    assert!(
        bits(&direct.pyramid.data) == bits(&from_db.pyramid.data),
        "pyramid"
    );
    // A window of it starts at the window's south-west sample, with the same spacing.
    let part = scene("database = \"whole.reliefdb\"\nwindow = [47.25, 9.5, 47.5, 9.75]");
    assert_eq!((part.field.width, part.field.height), (301, 301));
    let g = part.field.geo.unwrap();
    assert!(
        (g.lon0 - 9.5).abs() < 1e-12 && (g.lat0 - 47.25).abs() < 1e-12,
        "{g:?}"
    );
    assert_eq!(part.field.at(0, 0).to_bits(), a.at(600, 300).to_bits());
    assert_eq!(part.field.at(300, 300).to_bits(), a.at(900, 600).to_bits());
}

/// Every finer sample below a coarse cell (its closed footprint) is at most the cell's
/// maximum. Checks the coarse tiles `check` accepts; returns the comparisons made.
fn check_coarse_maxima(d: &Database, check: impl Fn(TileId) -> bool) -> u64 {
    let tiles = all_tiles(d);
    let n = d.tile_cells() as i64;
    let mut checked = 0u64;
    for (id, t) in &tiles {
        for coarse in 0..id.level {
            let k = id.level - coarse;
            let (x0, y0) = (id.x as i64 * n, id.y as i64 * n);
            for b in 0..=n {
                for a in 0..=n {
                    let h = t.height(a as usize, b as usize);
                    if h.is_nan() {
                        continue;
                    }
                    let (i, j) = (x0 + a, y0 + b);
                    // The coarse cells whose closed footprint holds the sample.
                    let cells = |g: i64| {
                        let c = g >> k;
                        if g & ((1 << k) - 1) == 0 {
                            vec![c - 1, c]
                        } else {
                            vec![c]
                        }
                    };
                    for ci in cells(i) {
                        for cj in cells(j) {
                            let cid = TileId {
                                level: coarse,
                                x: (ci / n) as u32,
                                y: (cj / n) as u32,
                            };
                            if ci < 0 || cj < 0 || !check(cid) {
                                continue;
                            }
                            if let Some(ct) = tiles.get(&cid) {
                                let m = ct.cell_max(0, (ci % n) as usize, (cj % n) as usize);
                                assert!(
                                    m >= h,
                                    "{cid} cell ({}, {}) max {m} < {h} m at {id} sample ({a}, {b})",
                                    ci % n,
                                    cj % n
                                );
                                checked += 1;
                            }
                        }
                    }
                }
            }
        }
    }
    checked
}

#[test]
fn coarse_cell_maxima_bound_every_finer_sample() {
    let d = Database::open(&seams().whole).unwrap();
    let checked = check_coarse_maxima(&d, |_| true);
    eprintln!("coarse maxima: {checked} finer samples checked");
    assert!(checked > 5_000_000, "{checked}");
    // The in-tile pyramid: each level the max of 2x2 below.
    let t = d.tile(d.entries()[0].id).unwrap().unwrap();
    let n = t.n;
    for l in 1..=n.trailing_zeros() {
        let side = n >> l;
        for j in 0..side {
            for i in 0..side {
                let below = (0..4)
                    .map(|q| t.cell_max(l - 1, 2 * i + q % 2, 2 * j + q / 2))
                    .fold(f32::MIN, f32::max);
                assert_eq!(t.cell_max(l, i, j), below);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The command line

fn text(o: &std::process::Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A failing run: exit 1, one `error:` line mentioning every needle, no panic.
fn assert_fails(what: &str, o: &std::process::Output, needles: &[&str]) -> String {
    let (out, err) = text(o);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{what}: exit status\nstdout: {out}\nstderr: {err}"
    );
    assert!(!err.contains("panicked"), "{what}: panicked: {err}");
    let line = err
        .lines()
        .find(|l| l.starts_with("error:"))
        .unwrap_or_else(|| panic!("{what}: no error line: {err}"));
    for n in needles {
        assert!(
            line.contains(n),
            "{what}: the error should mention `{n}`: {line}"
        );
    }
    line.to_string()
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn db_build_and_info_through_the_cli() {
    let dir = temp_dir("db-cli");
    let _clean = Cleanup(dir.clone());
    let out = dir.join("alps.reliefdb");
    let o = relief_cli(&["db", "build", &s(&out), &s(&alps_hgt())], &[]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("5 levels") && stdout.contains("49 tiles") && stdout.contains("samples/s"),
        "{stdout}"
    );
    assert_eq!(
        files_in(&dir),
        vec!["alps.reliefdb"],
        "no temporary file left"
    );
    let o = relief_cli(&["db", "info", &s(&out), "--verify"], &[]);
    let (info, stderr) = text(&o);
    assert!(o.status.success(), "{info}\n{stderr}");
    for needle in [
        "format version 1",
        "latitude 47.000000..48.000000, longitude 9.000000..10.000000",
        "heights 388..2937 m",
        "256x256 cells",
        "49 tiles",
        "5 levels",
        "0.0008333° (3.000″)",
        "N47E009.hgt: 1201x1201 samples",
        "verified",
    ] {
        assert!(
            info.contains(needle),
            "db info should say `{needle}`:\n{info}"
        );
    }
    // A smaller tile size makes more, smaller tiles.
    let small = dir.join("small.reliefdb");
    let o = relief_cli(
        &["db", "build", &s(&small), &s(&alps_hgt()), "--tile", "64"],
        &[],
    );
    assert!(o.status.success(), "{:?}", text(&o));
    let d = Database::open(&small).unwrap();
    assert_eq!(d.tile_cells(), 64);
    assert!(d.header().tile_count > 300, "{}", d.header().tile_count);

    // Bad input: one error line, exit 1, nothing written.
    let bad = dir.join("bad.reliefdb");
    assert_fails(
        "--tile 100",
        &relief_cli(
            &["db", "build", &s(&bad), &s(&alps_hgt()), "--tile", "100"],
            &[],
        ),
        &["--tile", "100", "power of two"],
    );
    assert_fails(
        "--tile 8192",
        &relief_cli(
            &["db", "build", &s(&bad), &s(&alps_hgt()), "--tile", "8192"],
            &[],
        ),
        &["--tile"],
    );
    let missing = dir.join("N00E000.hgt");
    assert_fails(
        "missing source",
        &relief_cli(&["db", "build", &s(&bad), &s(&missing)], &[]),
        &["N00E000.hgt"],
    );
    let png = dir.join("grey.png");
    image::GrayImage::from_pixel(4, 4, image::Luma([7u8]))
        .save(&png)
        .unwrap();
    assert_fails(
        "png source",
        &relief_cli(&["db", "build", &s(&bad), &s(&png)], &[]),
        &["grey.png", "not a database source"],
    );
    let rmnp = terrains().join("rmnp-dem.tif");
    let o = relief_cli(&["db", "build", &s(&dir), &s(&rmnp)], &[]);
    assert_fails("output is a directory", &o, &["directory"]);
    assert_fails(
        "db info of a scene",
        &relief_cli(&["db", "info", &s(&terrains().join("alps.toml"))], &[]),
        &["alps.toml", "not a relief database"],
    );
    assert_eq!(
        files_in(&dir),
        vec!["alps.reliefdb", "grey.png", "small.reliefdb"],
        "nothing else written"
    );
}

// ---------------------------------------------------------------------------------------------
// Bad input

/// A scene reading `database` (relative to `dir`) with extra `[terrain]` lines.
fn db_scene(dir: &Path, name: &str, database: &str, extra: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(
        &p,
        format!("[terrain]\ndatabase = \"{database}\"\n{extra}\n[camera]\nposition = [1000.0, 1000.0, 4000.0]\n[output]\nwidth = 32\nheight = 24\n"),
    )
    .unwrap();
    p
}

#[test]
fn a_corrupt_tile_is_an_error_naming_it() {
    let dir = temp_dir("db-corrupt");
    let _clean = Cleanup(dir.clone());
    let p = dir.join("corrupt.reliefdb");
    std::fs::copy(&seams().whole, &p).unwrap();
    let (victim, offset, length) = {
        let d = Database::open(&p).unwrap();
        let e = d
            .entries()
            .iter()
            .find(|e| e.id.level == 4)
            .copied()
            .unwrap();
        (e.id, e.offset, e.length)
    };
    let mut bytes = std::fs::read(&p).unwrap();
    bytes[(offset + length as u64 / 2) as usize] ^= 0x10;
    std::fs::write(&p, &bytes).unwrap();
    let d = Database::open(&p).expect("the header and the index are intact");
    let e = d.tile(victim).unwrap_err().to_string();
    let name = format!("tile (level 4, x {}, y {})", victim.x, victim.y);
    assert!(
        e.contains("corrupt.reliefdb") && e.contains(&name) && e.contains("checksum"),
        "{e}"
    );
    for other in d.entries().iter().filter(|e| e.id != victim) {
        d.tile(other.id).unwrap().unwrap();
    }
    assert_fails(
        "db info --verify",
        &relief_cli(&["db", "info", &s(&p), "--verify"], &[]),
        &["corrupt.reliefdb", &name, "checksum"],
    );
    let o = relief_cli(&["db", "info", &s(&p)], &[]);
    assert!(o.status.success(), "info reads no tile: {:?}", text(&o));
    let scene = db_scene(&dir, "corrupt.toml", "corrupt.reliefdb", "");
    assert_fails(
        "query",
        &relief_cli(&["query", &s(&scene), "--at", "100,100"], &[]),
        &[&name, "checksum"],
    );
}

/// `bytes` with its header CRC made right again (after an edit of the header).
fn fix_header_crc(bytes: &mut [u8]) {
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let c = crc32fast::hash(&bytes[..len - 4]);
    bytes[len - 4..len].copy_from_slice(&c.to_le_bytes());
}

#[test]
fn other_versions_truncated_files_and_hostile_headers_are_refused() {
    let dir = temp_dir("db-hostile");
    let _clean = Cleanup(dir.clone());
    let good = std::fs::read(&seams().whole).unwrap();
    let open = |name: &str, bytes: &[u8]| -> String {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        let r = Database::open(&p).and_then(|d| d.verify(&|_, _| {}));
        let e = r.expect_err(name).to_string();
        assert!(e.contains(name) && !e.contains('\n'), "{name}: {e}");
        e
    };
    // Another format version, even with a sound checksum.
    let mut v = good.clone();
    v[8..12].copy_from_slice(&7u32.to_le_bytes());
    let e = open("version.reliefdb", &v);
    assert!(
        e.contains("format version 7")
            && e.contains("reads version 1")
            && e.contains("relief db build"),
        "{e}"
    );
    fix_header_crc(&mut v);
    assert!(open("version2.reliefdb", &v).contains("format version 7"));
    // Not a database.
    assert!(open("magic.reliefdb", &good[8..]).contains("not a relief database"));
    // Truncated anywhere: in the header, in the index, in the tiles.
    let d = Database::open(&seams().whole).unwrap();
    let h = d.header().clone();
    for cut in [
        0usize,
        5,
        15,
        60,
        h.index_offset as usize - 1,
        h.data_offset as usize - 3,
        good.len() / 2,
        good.len() - 1,
    ] {
        let e = open(&format!("cut{cut}.reliefdb"), &good[..cut]);
        assert!(
            e.contains("truncated")
                || e.contains("not a relief database")
                || e.contains("holds only")
                || e.contains("not within"),
            "cut at {cut}: {e}"
        );
    }
    // Hostile sizes with sound checksums: refused before anything of that size is allocated.
    let mut v = good.clone();
    v[32..40].copy_from_slice(&(1u64 << 40).to_le_bytes());
    fix_header_crc(&mut v);
    let e = open("tiles.reliefdb", &v);
    assert!(e.contains("tiles"), "{e}");
    let mut v = good.clone();
    v[20..24].copy_from_slice(&1000u32.to_le_bytes());
    fix_header_crc(&mut v);
    assert!(open("levels.reliefdb", &v).contains("1000 levels"));
    let mut v = good.clone();
    v[16..20].copy_from_slice(&100u32.to_le_bytes());
    fix_header_crc(&mut v);
    assert!(open("tile.reliefdb", &v).contains("power of two"));
    // A genuine database of 4096-cell tiles needs more than a small memory budget per tile.
    let small = dir.join("small.tif");
    let f = hgt::load(&alps_hgt()).unwrap();
    write_piece(&small, &f, 9.0, 47.0, 0, 0, 33, 33, false);
    let big = dir.join("big.reliefdb");
    let o = relief_cli(
        &["db", "build", &s(&big), &s(&small), "--tile", "4096"],
        &[],
    );
    assert!(o.status.success(), "{:?}", text(&o));
    assert_fails(
        "tile over the budget",
        &relief_cli(
            &["--memory-budget", "16", "db", "info", &s(&big), "--verify"],
            &[],
        ),
        &["big.reliefdb", "memory budget"],
    );
    let o = relief_cli(&["db", "info", &s(&big), "--verify"], &[]);
    assert!(o.status.success(), "{:?}", text(&o));
}

#[test]
fn windows_off_the_database_and_misplaced_keys_are_named() {
    let dir = temp_dir("db-window");
    let _clean = Cleanup(dir.clone());
    std::fs::copy(&seams().whole, dir.join("alps.reliefdb")).unwrap();
    let q = |name: &str, db: &str, extra: &str| {
        relief_cli(
            &[
                "query",
                &s(&db_scene(&dir, name, db, extra)),
                "--at",
                "100,100",
            ],
            &[],
        )
    };
    assert_fails(
        "off",
        &q(
            "off.toml",
            "alps.reliefdb",
            "window = [47.5, 9.5, 47.7, 10.5]",
        ),
        &[
            "terrain.window",
            "latitude 47.000000..48.000000, longitude 9.000000..10.000000",
        ],
    );
    assert_fails(
        "far off",
        &q(
            "far.toml",
            "alps.reliefdb",
            "window = [-10.0, 9.5, -9.0, 9.7]",
        ),
        &["terrain.window", "not within"],
    );
    assert_fails(
        "reversed",
        &q(
            "rev.toml",
            "alps.reliefdb",
            "window = [47.7, 9.5, 47.5, 9.7]",
        ),
        &["terrain.window", "south < north"],
    );
    assert_fails(
        "level",
        &q("level.toml", "alps.reliefdb", "level = 9"),
        &["terrain.level", "levels 0..=4"],
    );
    assert_fails(
        "missing",
        &q("missing.toml", "none.reliefdb", ""),
        &["none.reliefdb"],
    );
    let both = dir.join("both.toml");
    std::fs::write(&both, "[terrain]\nsource = \"x.hgt\"\ndatabase = \"alps.reliefdb\"\n[camera]\nposition = [0.0, 0.0, 10.0]\n").unwrap();
    assert_fails(
        "both",
        &relief_cli(&["query", &s(&both), "--at", "1,1"], &[]),
        &["terrain", "only one of"],
    );
    let stray = dir.join("stray.toml");
    std::fs::write(&stray, "[terrain]\nsource = \"x.hgt\"\nwindow = [47.0, 9.0, 48.0, 10.0]\n[camera]\nposition = [0.0, 0.0, 10.0]\n").unwrap();
    assert_fails(
        "window without database",
        &relief_cli(&["query", &s(&stray), "--at", "1,1"], &[]),
        &["terrain.window", "database only"],
    );
    // A window inside works, at the finest level by default, and at a level given.
    let o = q(
        "ok.toml",
        "alps.reliefdb",
        "window = [47.2, 9.2, 47.6, 9.7]",
    );
    assert!(o.status.success(), "{:?}", text(&o));
    let o = q(
        "ok2.toml",
        "alps.reliefdb",
        "window = [47.2, 9.2, 47.6, 9.7]\nlevel = 2",
    );
    let (out, err) = text(&o);
    assert!(
        o.status.success() && err.contains("level 2") && err.contains("151x121 samples"),
        "{out}\n{err}"
    );
}

#[test]
fn overlapping_sources_of_equal_resolution_the_first_wins_with_a_warning() {
    let dir = temp_dir("db-overlap");
    let _clean = Cleanup(dir.clone());
    let mut f = hgt::load(&alps_hgt()).unwrap();
    let (a, b) = (dir.join("west.tif"), dir.join("east.tif"));
    write_piece(&a, &f, 9.0, 47.0, 0, 0, 701, 1201, false);
    for h in &mut f.heights {
        *h += 10.0;
    }
    write_piece(&b, &f, 9.0, 47.0, 500, 0, 701, 1201, false);
    // Column 600 (lon 9.5) lies in both.
    let at = |p: &Path, i: usize, j: usize| {
        let d = Database::open(p).unwrap();
        let n = d.tile_cells();
        let (gi, gj) = (189 * 1200 + i, 137 * 1200 + j);
        let t = d
            .tile(TileId {
                level: 4,
                x: (gi / n) as u32,
                y: (gj / n) as u32,
            })
            .unwrap()
            .unwrap();
        t.height(gi % n, gj % n)
    };
    let orig = hgt::load(&alps_hgt()).unwrap();
    for (first, second, name, bump) in [(&a, &b, "west.tif", 0.0), (&b, &a, "east.tif", 10.0)] {
        let out = dir.join(format!("{name}.reliefdb"));
        let o = relief_cli(&["db", "build", &s(&out), &s(first), &s(second)], &[]);
        let (stdout, err) = text(&o);
        assert!(o.status.success(), "{stdout}\n{err}");
        let warn = err
            .lines()
            .find(|l| l.contains("overlap"))
            .unwrap_or_else(|| panic!("no overlap warning: {err}"));
        for needle in [
            "west.tif",
            "east.tif",
            "same resolution",
            "differing by up to 10 m",
            &format!("{name} wins"),
        ] {
            assert!(warn.contains(needle), "`{needle}` in: {warn}");
        }
        assert_eq!(
            at(&out, 600, 400),
            orig.at(600, 400) + bump,
            "first given wins in the overlap"
        );
        assert_eq!(at(&out, 100, 400), orig.at(100, 400), "west only");
        assert_eq!(at(&out, 1100, 400), orig.at(1100, 400) + 10.0, "east only");
    }
    // Sources that only share an edge do not warn.
    let o = relief_cli(
        &[
            "db",
            "build",
            &s(&dir.join("cut.reliefdb")),
            &s(&seams().dir.join("piece2-0-0.tif")),
            &s(&seams().dir.join("piece2-1-0.tif")),
        ],
        &[],
    );
    let (_, err) = text(&o);
    assert!(o.status.success() && !err.contains("overlap"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Mixed resolution: ETOPO20 under both SRTM insets

/// Bilinear height of a height field with a georeference at (lon, lat).
fn bilinear(f: &Heightfield, lon: f64, lat: f64) -> f64 {
    let g = f.geo.unwrap();
    let (x, y) = ((lon - g.lon0) / g.dlon, (lat - g.lat0) / g.dlat);
    let (i, j) = (
        (x.floor() as usize).min(f.width - 2),
        (y.floor() as usize).min(f.height - 2),
    );
    let (u, v) = (x - i as f64, y - j as f64);
    let h = |a: usize, b: usize| f.at(i + a, j + b) as f64;
    h(0, 0) * (1.0 - u) * (1.0 - v)
        + h(1, 0) * u * (1.0 - v)
        + h(0, 1) * (1.0 - u) * v
        + h(1, 1) * u * v
}

/// At an inset's border a window across it has no hole, takes the inset's own samples on its
/// side and ETOPO20's on the other, so the step there is no larger than the two sources'
/// disagreement plus ETOPO's own slope over one sample.
#[test]
fn mixed_resolution_has_no_hole_at_an_inset_border() {
    let path = mixed();
    let d = Database::open(path).unwrap();
    assert_eq!(d.header().levels.len(), 12);
    let globe = relief::terrain::geotiff::load_heights(&etopo(), None, None).unwrap();
    let step = 1.0 / 1200.0;
    // (inset, window across its border, the border: west edge (lon) or north edge (lat)).
    let cases = [
        ("N47E009.hgt", [47.3, 8.9, 47.7, 9.1], Err(9.0)),
        ("N43E042.hgt", [43.9, 42.3, 44.1, 42.7], Ok(44.0)),
    ];
    for (name, window, border) in cases {
        let inset = hgt::load(&terrains().join(name)).unwrap();
        let f = db::window::load(path, Some(window), None).unwrap();
        let g = f.geo.unwrap();
        assert_eq!(g.dlat, step, "{name}: the finest level");
        assert_eq!(f.voids_filled, 0, "{name}: no hole");
        assert!(f.heights.iter().all(|h| h.is_finite()), "{name}");
        let (mut worst_step, mut worst_allowed, mut samples) = (0.0f64, 0.0f64, 0);
        let along = if border.is_err() { f.height } else { f.width };
        for k in 0..along {
            // Positions inside the inset on the border and one sample outside.
            let ((lon_in, lat_in), (lon_out, lat_out)) = match border {
                Err(lon) => (
                    (lon, g.lat0 + k as f64 * step),
                    (lon - step, g.lat0 + k as f64 * step),
                ),
                Ok(lat) => (
                    (g.lon0 + k as f64 * step, lat),
                    (g.lon0 + k as f64 * step, lat + step),
                ),
            };
            let at = |lon: f64, lat: f64| {
                let (i, j) = (
                    ((lon - g.lon0) / step).round() as usize,
                    ((lat - g.lat0) / step).round() as usize,
                );
                f.at(i, j) as f64
            };
            let (h_in, h_out) = (at(lon_in, lat_in), at(lon_out, lat_out));
            let srtm = bilinear(&inset, lon_in, lat_in);
            assert!((h_in - srtm).abs() < 1e-6, "{name}: the inset's own sample on its border at {lon_in}, {lat_in}: {h_in} vs {srtm}");
            let (e_in, e_out) = (
                bilinear(&globe, lon_in, lat_in),
                bilinear(&globe, lon_out, lat_out),
            );
            assert!(
                (h_out - e_out).abs() < 1e-2,
                "{name}: ETOPO20 outside the inset at {lon_out}, {lat_out}: {h_out} vs {e_out}"
            );
            let allowed = (srtm - e_in).abs() + (e_in - e_out).abs() + 1e-2;
            let step_here = (h_in - h_out).abs();
            assert!(
                step_here <= allowed,
                "{name}: step {step_here} m at {lon_in}, {lat_in} > disagreement {allowed} m"
            );
            worst_step = worst_step.max(step_here);
            worst_allowed = worst_allowed.max(allowed);
            samples += 1;
        }
        eprintln!("{name}: {samples} border samples, step up to {worst_step:.1} m where the sources disagree by up to {worst_allowed:.1} m");
    }
    let checked = check_coarse_maxima(&d, |_| true);
    eprintln!("coarse maxima: {checked} finer samples checked");
    assert!(checked > 10_000_000);
}

/// A window at the finest level past the insets' tiles: the missing tiles are filled from the
/// nearest coarser level that has them, bilinearly, and a warning names them.
#[test]
fn missing_tiles_are_filled_from_a_coarser_level_with_a_warning() {
    let path = mixed();
    let d = Database::open(path).unwrap();
    let missing = TileId {
        level: 11,
        x: 891,
        y: 644,
    };
    assert!(
        !d.has_tile(missing) && d.has_tile(TileId { x: 890, ..missing }),
        "the window straddles the inset's last tiles"
    );
    let window = [47.4, 9.9, 47.6, 10.2];
    let f = db::window::load(path, Some(window), None).unwrap();
    assert_eq!(f.geo.unwrap().dlat, 1.0 / 1200.0);
    assert_eq!(f.voids_filled, 0);
    assert!(f.heights.iter().all(|h| h.is_finite()));
    // In the filled part, even samples are level 10's own samples.
    let g = f.geo.unwrap();
    let (gi, gj) = (
        ((g.lon0 + 180.0) * 1200.0).round() as i64,
        ((g.lat0 + 90.0) * 1200.0).round() as i64,
    );
    let coarse = d
        .tile(TileId {
            level: 10,
            x: 445,
            y: 322,
        })
        .unwrap()
        .unwrap();
    let mut compared = 0;
    for j in 0..f.height as i64 {
        for i in 0..f.width as i64 {
            let (x, y) = (gi + i, gj + j);
            let in_missing = x / 256 == 891 && y / 256 == 644 && x % 2 == 0 && y % 2 == 0;
            let (cx, cy) = (x / 2 - 445 * 256, y / 2 - 322 * 256);
            if in_missing && (0..=256).contains(&cx) && (0..=256).contains(&cy) {
                assert_eq!(
                    f.at(i as usize, j as usize),
                    coarse.height(cx as usize, cy as usize)
                );
                compared += 1;
            }
        }
    }
    assert!(compared > 1000, "{compared}");
    // The command line says which tiles were filled.
    let dir = temp_dir("db-missing");
    let _clean = Cleanup(dir.clone());
    std::fs::copy(path, dir.join("mixed.reliefdb")).unwrap();
    let scene = db_scene(
        &dir,
        "missing.toml",
        "mixed.reliefdb",
        "window = [47.4, 9.9, 47.6, 10.2]",
    );
    let o = relief_cli(&["query", &s(&scene), "--at", "100,100"], &[]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}\n{err}");
    let warn = err
        .lines()
        .find(|l| l.contains("not in the database"))
        .unwrap_or_else(|| panic!("no warning: {err}"));
    assert!(
        warn.contains("level 11")
            && warn.contains("tile (level 11, x 891, y 64")
            && warn.contains("from level 10"),
        "{warn}"
    );
}

// ---------------------------------------------------------------------------------------------
// Seams, in pictures (GPU)

/// The same views rendered through the whole tile's database and through the 2x2 and 3x3
/// cut ones: mean colour difference ≤ 1/255, depth within 1e-5 relative, no sky or
/// see-through pixel where the whole tile has terrain. The views straddle the cuts (the 2x2
/// cut at sample 600 in x and y, the 3x3 cuts at 400 and 800). The `.hgt` rendered directly
/// gives the same pictures too. All flat (`curved = false`: databases default to the curved
/// earth, the `.hgt` not; this test is about tiling, `tests/curvature.rs` about the curve).
#[test]
fn cut_databases_render_the_same_pictures_as_the_whole_tile() {
    use relief::gpu::TerrainRenderer;
    use relief::scene::{Camera, Pose, Scene};
    let _l = common::gpu_lock();
    let Some(g) = common::gpu() else {
        return;
    };
    let s = seams();
    let load = |terrain: String| {
        let text = format!(
            "[terrain]\n{terrain}\ncurved = false\n[sun]\nazimuth = 245.0\nelevation = 24.0\n[fog]\nvisibility = 90000.0\nscale_height = 3000.0\n[camera]\nposition = [0.0, 0.0, 5000.0]\n"
        );
        let scene = Scene::parse(&text, &s.dir.join("seams.toml")).unwrap();
        let terrain = scene.load_terrain().unwrap();
        (scene, terrain)
    };
    let db = |p: &Path| {
        format!(
            "database = \"{}\"",
            p.file_name().unwrap().to_string_lossy()
        )
    };
    let whole = load(db(&s.whole));
    let [dx, dy] = whole.1.frame.spacing;
    let at = |i: f64, j: f64, z: f64| glam::DVec3::new(i * dx, j * dy, z);
    let pose = |position, heading, pitch, roll| Pose {
        position,
        heading,
        pitch,
        roll,
        fov: 60.0,
    };
    let views = [
        (
            "over the 2x2 crossing",
            pose(at(600.0, 480.0, 9000.0), 10.0, -55.0, 0.0),
        ),
        (
            "across the 3x3 cuts",
            pose(at(330.0, 250.0, 2600.0), 40.0, -9.0, 0.0),
        ),
        (
            "along the 2x2 cut",
            pose(at(600.0, 60.0, 1800.0), 0.0, -4.0, 3.0),
        ),
        (
            "down the 3x3 crossing",
            pose(at(800.0, 800.0, 7000.0), 200.0, -80.0, 0.0),
        ),
    ];
    let (w, h) = (160u32, 120u32);
    let settings = common::settings(true, true);
    let render = |(scene, terrain): &(Scene, relief::terrain::Terrain), cam: &Camera| {
        let mut r = TerrainRenderer::new(g, terrain).expect("renderer");
        r.capture(g, terrain, &scene.desc, cam, &settings)
            .expect("capture")
    };
    let cut = [
        ("2x2", load(db(&s.two))),
        ("3x3", load(db(&s.three))),
        (
            "the .hgt itself",
            load(format!("source = \"{}\"", alps_hgt().display())),
        ),
    ];
    for (view, p) in views {
        let cam = Camera::new(p, w, h);
        let reference = render(&whole, &cam);
        let hits = reference.depth.iter().filter(|d| d.is_finite()).count();
        assert!(
            hits > (w * h / 3) as usize,
            "{view}: only {hits} terrain pixels"
        );
        for (name, world) in &cut {
            let out = render(world, &cam);
            let mean = out
                .rgba
                .iter()
                .zip(&reference.rgba)
                .map(|(a, b)| a.abs_diff(*b) as f64)
                .sum::<f64>()
                / out.rgba.len() as f64;
            let mut holes = 0;
            let mut worst = 0.0f64;
            for (a, b) in out.depth.iter().zip(&reference.depth) {
                if b.is_finite() && !a.is_finite() {
                    holes += 1;
                } else if b.is_finite() {
                    worst = worst.max(((a - b) / b).abs() as f64);
                }
            }
            let ok = mean <= 1.0 && worst <= 1e-5 && holes == 0;
            if !ok {
                let tag = format!("db-seams-{name}-{}", view.replace(' ', "-"));
                let p = common::save_failure_images(&tag, w, h, &out.rgba, &reference.rgba);
                panic!("{name}, {view}: mean {mean:.3}/255, depth {worst:e} relative, {holes} sky/see-through pixels where the whole tile has terrain ({})", p.display());
            }
            eprintln!("{name}, {view}: {hits} terrain pixels, mean {mean:.3}/255, depth {worst:e}, no holes");
        }
    }
}

/// Voids inside the data (no source has data there: SRTM v2's holes) are compiled filled, as
/// the loaders fill the same file (pull-push over the source), so the database holds what
/// rendering the file itself shows: a window of part of the tile gets the whole file's fill
/// (its own pull-push would differ), a query at full resolution answers inside the void, and
/// no tile keeps a void (a paged frame once showed the void as a pit: `tests/paged_needle.rs`).
#[test]
fn voids_inside_the_data_are_compiled_filled_as_the_loaders_fill_them() {
    let dir = temp_dir("db-voids");
    let hgt = common::void_hgt(&dir);
    let out = dir.join("voids.reliefdb");
    build(&out, std::slice::from_ref(&hgt));
    let d = Database::open(&out).unwrap();
    // Its tiles hold as many voids as those of the same file without its void: only where
    // no source reaches (past the tile's edges).
    let whole_dir = dir.join("whole");
    std::fs::create_dir_all(&whole_dir).unwrap();
    let mut bytes = std::fs::read(&hgt).unwrap();
    for h in bytes.chunks_exact_mut(2) {
        if i16::from_be_bytes([h[0], h[1]]) == hgt::VOID {
            h.copy_from_slice(&1000i16.to_be_bytes());
        }
    }
    let whole_hgt = whole_dir.join("N47E009.hgt");
    std::fs::write(&whole_hgt, bytes).unwrap();
    let whole = whole_dir.join("whole.reliefdb");
    build(&whole, &[whole_hgt]);
    let w = Database::open(&whole).unwrap();
    assert_eq!(d.entries().len(), w.entries().len());
    let differ: Vec<_> = d
        .entries()
        .iter()
        .zip(w.entries())
        .filter(|(a, b)| (a.id, a.voids) != (b.id, b.voids))
        .map(|(a, b)| (a.id, a.voids, b.voids))
        .collect();
    assert!(
        differ.is_empty(),
        "tiles, voids, voids without the void: {differ:?}"
    );
    let direct = hgt::load(&hgt).unwrap();
    assert_eq!(direct.voids_filled, common::VOID_SIDE * common::VOID_SIDE);
    // The window [47.4, 9.4, 47.6, 9.6] holds the void: samples 480..=720 of the file's
    // columns and of its rows counted from the south.
    let text = "[terrain]\ndatabase = \"voids.reliefdb\"\nwindow = [47.4, 9.4, 47.6, 9.6]\n\
                [camera]\nposition = [1000.0, 1000.0, 3000.0]\n";
    let part = relief::scene::Scene::parse(text, &dir.join("scene.toml"))
        .unwrap()
        .load_terrain()
        .unwrap();
    let f = &part.field;
    assert_eq!((f.width, f.height), (241, 241));
    assert_eq!(f.voids_filled, 0, "the window had voids to fill");
    let mut differ = 0;
    for j in 0..241 {
        for i in 0..241 {
            differ += usize::from(f.at(i, j).to_bits() != direct.at(480 + i, 480 + j).to_bits());
        }
    }
    assert_eq!(differ, 0, "window samples differing from the loaded file");
    // The void's centre, 47.5N 9.5E: row 600 of the file, 600 from the south.
    let q = db::height_at(&d, 47.5, 9.5)
        .unwrap()
        .expect("the void answers");
    let want = f64::from(direct.at(600, 600));
    assert!(
        (q.height - want).abs() < 1e-3
            && q.level == d.entries().iter().map(|e| e.id.level).max().unwrap(),
        "{q:?} against {want}"
    );
    assert!(
        want > 1000.0,
        "the fill rises towards the hill's top: {want}"
    );
}
