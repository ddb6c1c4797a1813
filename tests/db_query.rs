//! Queries on a database scene read the database at full resolution through its tile cache,
//! whatever level the scene renders (issue 20: "the CPU oracle (`query --at`, `--los`) reads
//! the same database at full resolution"). Truth: the SRTM tile's own bilinear surface, read
//! here from the `.hgt` file.

mod common;

use common::{relief_cli, temp_dir, terrains};
use glam::DVec3;
use relief::cpu::database::FullResolution;
use relief::scene::Scene;
use std::path::Path;

/// N47E009's bilinear surface at (lat, lon), from the file's big-endian samples (row 0 north).
fn srtm_height(bytes: &[u8], lat: f64, lon: f64) -> f64 {
    let n = 1201usize;
    let at = |i: usize, j_south: usize| {
        let row = n - 1 - j_south;
        let k = 2 * (row * n + i);
        i16::from_be_bytes([bytes[k], bytes[k + 1]]) as f64
    };
    let (x, y) = ((lon - 9.0) * 1200.0, (lat - 47.0) * 1200.0);
    let (i, j) = (
        (x.floor() as usize).min(n - 2),
        (y.floor() as usize).min(n - 2),
    );
    let (u, v) = (x - i as f64, y - j as f64);
    at(i, j) * (1.0 - u) * (1.0 - v)
        + at(i + 1, j) * u * (1.0 - v)
        + at(i, j + 1) * (1.0 - u) * v
        + at(i + 1, j + 1) * u * v
}

fn scene(dir: &Path, extra: &str) -> Scene {
    let text = format!(
        "[terrain]\ndatabase = \"world.reliefdb\"\nwindow = [46.5, 8.5, 48.5, 10.5]\nlevel = 7\n{extra}\n[camera]\nposition = [1000.0, 1000.0, 9000.0]\n"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, &text).unwrap();
    Scene::parse(&text, &path).unwrap()
}

#[test]
fn database_queries_answer_at_full_resolution_through_the_tile_cache() {
    let dir = temp_dir("db-query");
    let hgt = terrains().join("N47E009.hgt");
    let etopo = common::project_dir().join("tests/data/etopo20.tif");
    let db = dir.join("world.reliefdb");
    relief::db::build(
        &db,
        &[etopo, hgt.clone()],
        &relief::db::BuildOptions::default(),
        &|_, _| {},
    )
    .unwrap();
    let srtm = std::fs::read(&hgt).unwrap();

    // The scene renders level 7 (48″ samples) over the inset; queries must see its 3″ samples.
    let s = scene(&dir, "curved = false");
    let terrain = s.load_terrain().unwrap();
    assert!(
        terrain.field.geo.unwrap().dlat > 0.01,
        "the scene renders a coarse level"
    );
    let full = FullResolution::open(&s.desc.terrain, &s.base_dir)
        .unwrap()
        .unwrap();
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut worst, mut coarse_off, mut top) = (0.0f64, 0.0f64, f64::NEG_INFINITY);
    for _ in 0..200 {
        let (lat, lon) = (47.02 + 0.96 * next(), 9.02 + 0.96 * next());
        let p = terrain.geodetic_to_world("test", [lat, lon, 0.0]).unwrap();
        let h = full
            .height_at(&terrain, p)
            .unwrap()
            .expect("over the database");
        assert_eq!(h.level, 11, "the finest level answers");
        let truth = srtm_height(&srtm, lat, lon);
        worst = worst.max((h.height - truth).abs());
        top = top.max(h.height);
        let rendered = terrain.point_below(p).unwrap().z;
        coarse_off = coarse_off.max((rendered - truth).abs());
    }
    // The samples are the file's (f32 of whole metres); the bilinear weights differ only by
    // the world round trip of the position (≈1e-12 of a sample).
    assert!(
        worst < 1e-3,
        "full-resolution height off the SRTM surface by {worst} m"
    );
    // The coarse level the scene renders is far off somewhere: the check above can fail.
    assert!(
        coarse_off > 50.0,
        "the coarse window is within {coarse_off} m"
    );
    println!("200 heights: worst {worst:.2e} m off SRTM (the rendered 48″ level: up to {coarse_off:.0} m)");
    // The bound collision volumes are skipped by (`FullResolution::highest`): above every
    // height answered (the Säntis, 2,502 m, is in the database) and no higher than the
    // world's highest summit (the database holds ETOPO20's whole world).
    let highest = full.highest();
    println!("highest {highest:.1} m, the highest of the 200: {top:.1} m");
    assert!(
        highest >= top && (2502.0..=8849.0).contains(&highest),
        "{highest}"
    );

    // Lines of sight at full resolution agree with the .hgt terrain's, on 100 segments.
    let flat = {
        let text = format!(
            "[terrain]\nsource = \"{}\"\n[camera]\nposition = [1000.0, 1000.0, 9000.0]\n",
            hgt.display()
        );
        Scene::parse(&text, &dir.join("hgt.toml"))
            .unwrap()
            .load_terrain()
            .unwrap()
    };
    let (mut blocked, mut differ_from_coarse) = (0, 0);
    for _ in 0..100 {
        let mut ends = [DVec3::ZERO; 2];
        let mut on_hgt = [DVec3::ZERO; 2];
        for k in 0..2 {
            let (lat, lon) = (47.05 + 0.9 * next(), 9.05 + 0.9 * next());
            let alt = 600.0 + 2000.0 * next();
            ends[k] = terrain.geodetic_to_world("test", [lat, lon, alt]).unwrap();
            on_hgt[k] = flat.geodetic_to_world("test", [lat, lon, alt]).unwrap();
        }
        let (clear, spacing) = full.line_of_sight(&terrain, ends[0], ends[1]).unwrap();
        assert!(
            (spacing - 1.0 / 1200.0).abs() < 1e-12,
            "finest level: {spacing}"
        );
        let truth = relief::cpu::line_of_sight(&flat, on_hgt[0], on_hgt[1]);
        assert_eq!(clear, truth, "segment {:?} -> {:?}", on_hgt[0], on_hgt[1]);
        blocked += usize::from(!truth);
        differ_from_coarse +=
            usize::from(relief::cpu::line_of_sight(&terrain, ends[0], ends[1]) != truth);
    }
    assert!(
        (10..=90).contains(&blocked),
        "{blocked} of 100 blocked: pick a fairer mix"
    );
    println!("100 lines of sight: {blocked} blocked, all as on the .hgt; the 48″ level differs on {differ_from_coarse}");

    // The data's edges and corners answer from the finest level too (the cell east or north
    // of an edge sample has no data: the cell before it has the same samples there).
    let alps = dir.join("alps.reliefdb");
    relief::db::build(
        &alps,
        std::slice::from_ref(&hgt),
        &relief::db::BuildOptions::default(),
        &|_, _| {},
    )
    .unwrap();
    let alps = relief::db::Database::open(&alps).unwrap();
    let finest = alps.header().levels.len() as u32 - 1;
    let mut edge = vec![(47.0, 9.0), (47.0, 10.0), (48.0, 9.0), (48.0, 10.0)];
    for k in 0..20 {
        let f = (k as f64 + next()) / 20.0;
        edge.extend([
            (47.0 + f, 10.0),
            (48.0, 9.0 + f),
            (47.0 + f, 9.0),
            (47.0, 9.0 + f),
        ]);
    }
    for (lat, lon) in edge {
        let h = relief::db::height_at(&alps, lat, lon)
            .unwrap()
            .expect("on the tile's edge");
        assert_eq!(h.level, finest, "({lat}, {lon})");
        let truth = srtm_height(&srtm, lat, lon);
        assert!(
            (h.height - truth).abs() < 1e-6,
            "({lat}, {lon}): {} vs {truth}",
            h.height
        );
    }
    assert!(relief::db::height_at(&alps, 48.001, 10.0)
        .unwrap()
        .is_none());

    // The CLI says which level answered.
    let out = relief_cli(
        &[
            "query",
            dir.join("scene.toml").to_str().unwrap(),
            "--at",
            "75000,111000",
        ],
        &[],
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("database level 11"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Resident-only lookups (what the CIGI IG tries first) read nothing: on a cold cache they
/// report the tiles a height or a window needs; once the prefetcher has read those, the same
/// queries answer bit for bit what the reading path does.
#[test]
fn resident_only_queries_report_missing_tiles_and_then_match_the_reading_path() {
    use relief::db::{height_at, height_in, window, Database, Prefetcher, Resident, ResidentOnly};
    use std::sync::Arc;
    use std::time::Duration;

    let dir = temp_dir("db-resident");
    let path = dir.join("alps.reliefdb");
    relief::db::build(
        &path,
        &[terrains().join("N47E009.hgt")],
        &relief::db::BuildOptions::default(),
        &|_, _| {},
    )
    .unwrap();
    let finest = Database::open(&path).unwrap().header().levels.len() as u32 - 1;
    let points = [(47.24937, 9.34331), (47.40123, 9.61877), (47.9, 9.05)];

    // Heights: cold, then warmed by the prefetcher.
    let db = Arc::new(Database::open(&path).unwrap());
    let mut wanted = Vec::new();
    for &(lat, lon) in &points {
        match ResidentOnly::run(&db, |t| height_in(t, lat, lon)).unwrap() {
            Resident::Missing(ids) => {
                assert_eq!(ids.len(), 1, "the finest tile at ({lat}, {lon}): {ids:?}");
                assert_eq!(ids[0].level, finest);
                wanted.extend(ids);
            }
            Resident::Ready(v) => panic!("a cold cache answered ({lat}, {lon}): {v:?}"),
        }
    }
    assert_eq!(db.cached_bytes(), 0, "resident-only lookups read nothing");
    let prefetch = Prefetcher::new(db.clone()).unwrap();
    assert!(prefetch.request(wanted.iter().copied()) >= 1);
    assert!(prefetch.wait_idle(Duration::from_secs(30)), "prefetched");
    assert_eq!(
        prefetch.request(wanted.iter().copied()),
        0,
        "cached tiles are not queued again"
    );
    assert!(db.cached_bytes() > 0);
    for &(lat, lon) in &points {
        let Resident::Ready(Some(r)) = ResidentOnly::run(&db, |t| height_in(t, lat, lon)).unwrap()
        else {
            panic!("({lat}, {lon}) is resident now");
        };
        let read = height_at(&db, lat, lon).unwrap().unwrap();
        assert_eq!(r.height.to_bits(), read.height.to_bits(), "({lat}, {lon})");
        assert_eq!((r.level, r.spacing), (read.level, read.spacing));
    }
    drop(prefetch);

    // Each id is queued once; dropping the prefetcher with a full queue stops its worker
    // after the tile it is reading.
    let db = Arc::new(Database::open(&path).unwrap());
    let prefetch = Prefetcher::new(db.clone()).unwrap();
    let ids: Vec<_> = db.entries().iter().map(|e| e.id).collect();
    assert_eq!(prefetch.request(ids.iter().copied()), ids.len());
    assert_eq!(prefetch.request(ids.iter().copied()), 0, "queued once");
    assert_eq!(prefetch.counts().requested, ids.len() as u64);
    let t = std::time::Instant::now();
    drop(prefetch);
    assert!(t.elapsed() < Duration::from_secs(5), "dropped at once");

    // A window of the finest level over several tiles: cold, one tile warm, all warm.
    let db = Database::open(&path).unwrap();
    let spec = window::resolve(&db, Some([47.2, 9.2, 47.45, 9.5]), Some(finest)).unwrap();
    let Resident::Missing(all) = ResidentOnly::run(&db, |t| window::read_from(t, &spec)).unwrap()
    else {
        panic!("a cold window answered");
    };
    assert!(all.len() >= 2, "the window spans tiles: {all:?}");
    assert!(all.iter().all(|id| id.level == finest && db.has_tile(*id)));
    assert_eq!(db.cached_bytes(), 0, "resident-only window reads nothing");
    db.tile(all[0]).unwrap();
    match ResidentOnly::run(&db, |t| window::read_from(t, &spec)).unwrap() {
        Resident::Missing(rest) => assert_eq!(rest, all[1..]),
        Resident::Ready(_) => panic!("a window with cold tiles answered"),
    }
    for id in &all {
        db.tile(*id).unwrap();
    }
    let Resident::Ready(Some(warm)) =
        ResidentOnly::run(&db, |t| window::read_from(t, &spec)).unwrap()
    else {
        panic!("the window is resident now");
    };
    let read = window::read(&db, &spec).unwrap();
    assert_eq!((warm.width, warm.height), (read.width, read.height));
    assert!(
        warm.heights
            .iter()
            .zip(&read.heights)
            .all(|(a, b)| a.to_bits() == b.to_bits()),
        "bit for bit"
    );
    println!(
        "window {}x{} at level {finest}: {} tiles reported missing, then equal to the reading path",
        spec.width,
        spec.height,
        all.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A frame's heights on a paged (hollow) window — the window's height above ground, CIGI's
/// ground clamping — never wait for the disk (`Terrain::height_now`): on a cold cache they
/// come at once from the coarsest level (held since the window opened), marked inexact, while
/// the finer tile is read in the background; then exactly what the reading path gives.
#[test]
fn a_frames_heights_on_a_paged_window_never_wait_for_the_disk() {
    use relief::db::Database;
    use relief::world::World;
    use std::time::{Duration, Instant};

    let dir = temp_dir("db-height-now");
    let path = common::db_build(dir.join("world.reliefdb"), &terrains().join("N47E009.hgt"));
    let finest = Database::open(&path).unwrap().header().levels.len() as u32 - 1;
    let text = format!(
        "[terrain]\ndatabase = \"world.reliefdb\"\nwindow = [47.1, 9.1, 47.9, 9.9]\nlevel = {finest}\ncurved = false\n[camera]\nposition = [1000.0, 1000.0, 9000.0]\n"
    );
    let s = Scene::parse(&text, &dir.join("scene.toml")).unwrap();
    let hollow = World::load_as(&s, true).unwrap().terrain;
    let h = hollow.hollow.as_ref().expect("a hollow window");
    assert!(h.pinned_tiles() >= 1, "the coarsest level is held");
    assert!(h.prefetcher().is_none(), "nothing missed yet");
    let bytes = std::fs::read(terrains().join("N47E009.hgt")).unwrap();

    let geo = hollow.field.geo.unwrap();
    let points = [(47.24937, 9.34331), (47.40123, 9.61877), (47.8, 9.15)];
    for (k, &(lat, lon)) in points.iter().enumerate() {
        let (x, y) = ((lon - geo.lon0) / geo.dlon, (lat - geo.lat0) / geo.dlat);
        let truth = srtm_height(&bytes, lat, lon);
        // Each point lies on a finest tile not read yet: the answer is at once, and coarse.
        let first = hollow.height_now(x, y).expect("the coarsest level answers");
        assert!(
            !first.exact,
            "point {k}: a tile not in memory was read on the caller's thread"
        );
        assert!(
            (first.height - truth).abs() > 0.01,
            "point {k}: the coarse answer {} is the exact one",
            first.height
        );
        assert!(
            (hollow.min_height as f64..=hollow.max_height as f64).contains(&first.height),
            "point {k}: {} outside the data's range",
            first.height
        );
        // The prefetcher reads the tile: exact within a few seconds, bit for bit the reading
        // path's, and the SRTM file's surface.
        let start = Instant::now();
        let exact = loop {
            let g = hollow.height_now(x, y).unwrap();
            if g.exact {
                break g.height;
            }
            assert!(
                start.elapsed() < Duration::from_secs(30),
                "point {k}: the tile never arrived"
            );
            std::thread::sleep(Duration::from_millis(2));
        };
        eprintln!(
            "point {k}: at once {:.1} m (coarse), {:.1} ms later {exact:.3} m (SRTM {truth:.3} m)",
            first.height,
            start.elapsed().as_secs_f64() * 1e3
        );
        assert_eq!(
            exact.to_bits(),
            hollow.height_at_grid(x, y).unwrap().to_bits()
        );
        assert!(
            (exact - truth).abs() < 1e-3,
            "point {k}: {exact} against {truth}"
        );
        assert_eq!(hollow.ground_msl(lat, lon), Some(exact));
    }
    // The height above ground waits for the exact height: none on a tile not read yet (a
    // fourth point, on a finest tile of its own), then the full-resolution one.
    let p = hollow
        .geodetic_to_world("test", [47.15, 9.85, 5000.0])
        .unwrap();
    assert_eq!(hollow.height_above_now(p), None, "none until exact");
    let start = Instant::now();
    let agl = loop {
        if let Some(a) = hollow.height_above_now(p) {
            break a;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "never exact");
        std::thread::sleep(Duration::from_millis(2));
    };
    let ground = hollow.height_above(p).map(|a| 5000.0 - a).unwrap();
    assert!(
        (agl - (5000.0 - ground)).abs() < 1e-9,
        "{agl} against {ground}"
    );
    let counts = h.prefetcher().expect("started on the first miss").counts();
    assert!(counts.read > points.len() as u64, "{counts:?}");

    // A window moved to follow the eye shares the held level and the prefetcher.
    let db = h.database();
    let spec = relief::db::window::resolve(db, Some([47.0, 9.0, 47.5, 9.5]), Some(finest)).unwrap();
    let moved =
        relief::terrain::hollow::window_spec(&s.desc.terrain, &s.base_dir, h, &spec).unwrap();
    let m = moved.hollow.as_ref().unwrap();
    assert_eq!(m.pinned_tiles(), h.pinned_tiles());
    assert!(std::ptr::eq(
        m.prefetcher().unwrap(),
        h.prefetcher().unwrap()
    ));

    // Off the grid: nothing.
    assert_eq!(hollow.height_now(-1.0, 0.0), None);
}
