//! Synthetic mosaics (`relief db synth`): a database compiled from a procedural source, with
//! no source files and no sample array held.
//!
//! * through the CLI: it builds, `db info` lists it, bad options are one-line errors;
//! * neighbouring tiles meet bit for bit along their shared edges, at every level;
//! * the finest level's samples are the procedural function's own values at their indices,
//!   coarse levels' samples are the finer level's (every other one);
//! * the same options give the same file byte for byte; another seed another file.

mod common;

use common::{relief_cli, temp_dir};
use relief::db::{self, Database, TileId};
use std::path::{Path, PathBuf};

struct Cleanup(PathBuf);

impl Drop for Cleanup {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// A 4x3 mosaic of 65² source tiles in 32-cell database tiles.
fn small() -> db::SynthOptions {
    db::SynthOptions {
        tiles: [4, 3],
        samples: 65,
        tile: 32,
        ..db::SynthOptions::default()
    }
}

#[test]
fn a_synth_mosaic_builds_and_db_info_lists_it() {
    let dir = temp_dir("db-synth-cli");
    let _clean = Cleanup(dir.clone());
    let out = dir.join("m.reliefdb");
    let o = relief_cli(
        &[
            "db",
            "synth",
            &s(&out),
            "--tiles",
            "4x3",
            "--samples",
            "65",
            "--tile",
            "32",
            "--seed",
            "7",
        ],
        &[],
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("257x193 samples"), "{stdout}");
    let o = relief_cli(&["db", "info", &s(&out), "--verify"], &[]);
    let info = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{info}");
    assert!(
        info.contains("synth seed 7: 4x3 tiles of 65² samples"),
        "{info}"
    );
    assert!(
        info.contains("longitude 7.000000..11.000000, latitude 46.000000..49.000000"),
        "{info}"
    );
    assert!(info.contains("verified"), "{info}");
    // Bad options: one error line, nothing written.
    for (args, needle) in [
        (vec!["--tiles", "4y3"], "--tiles"),
        (vec!["--tiles", "0x3"], "--tiles"),
        (vec!["--samples", "1"], "--samples"),
        (vec!["--tile", "48"], "--tile"),
        (vec!["--lat", "89"], "--lat/--lon"),
        (vec!["--arcsec", "0.001"], "--arcsec"),
    ] {
        let bad = dir.join("bad.reliefdb");
        let mut a = vec!["db", "synth"];
        let b = s(&bad);
        a.push(&b);
        a.extend(args.iter().copied());
        let o = relief_cli(&a, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} should fail");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!bad.exists(), "{args:?} wrote a file");
    }
}

#[test]
fn synth_tiles_meet_bit_for_bit_and_sample_the_function() {
    let dir = temp_dir("db-synth-seams");
    let _clean = Cleanup(dir.clone());
    let out = dir.join("m.reliefdb");
    let opts = small();
    db::synth(&out, &opts, &|_, _| {}).unwrap();
    let d = Database::open(&out).unwrap();
    let n = d.tile_cells();
    let levels = d.header().levels.len() as u32;
    let mut edges = 0u64;
    for e in d.entries() {
        let t = d.tile(e.id).unwrap().unwrap();
        let TileId { level, x, y } = e.id;
        if let Some(east) = d.tile(TileId { level, x: x + 1, y }).unwrap() {
            for j in 0..=n {
                assert_eq!(t.height(n, j).to_bits(), east.height(0, j).to_bits());
                edges += 1;
            }
        }
        if let Some(north) = d.tile(TileId { level, x, y: y + 1 }).unwrap() {
            for i in 0..=n {
                assert_eq!(t.height(i, n).to_bits(), north.height(i, 0).to_bits());
                edges += 1;
            }
        }
    }
    assert!(edges > 1000, "only {edges} edge samples compared");
    // The finest level holds the function's values at the source indices; the level above
    // every other one of them.
    let src = opts.source().unwrap();
    let db::source::SourceData::Synth(f) = src.data else {
        panic!("a synth source")
    };
    let fine = &d.header().levels[levels as usize - 1];
    let per = fine.per_degree;
    let (i_off, j_off) = (
        ((opts.lon + 180.0) * per).round() as i64,
        ((opts.lat + 90.0) * per).round() as i64,
    );
    let mut checked = 0u64;
    for e in d.entries().iter().filter(|e| e.id.level + 2 >= levels) {
        let t = d.tile(e.id).unwrap().unwrap();
        let k = 1i64 << (levels - 1 - e.id.level);
        for j in 0..=n {
            for i in 0..=n {
                let gi = (e.id.x as i64 * n as i64 + i as i64) * k - i_off;
                let gj = (e.id.y as i64 * n as i64 + j as i64) * k - j_off;
                let h = t.height(i, j);
                let inside = gi >= 0 && gj >= 0 && gi < src.width as i64 && gj < src.height as i64;
                if inside {
                    assert_eq!(
                        h.to_bits(),
                        f.at(gi as usize, gj as usize).to_bits(),
                        "{} ({i}, {j})",
                        e.id
                    );
                    checked += 1;
                } else {
                    assert!(
                        h.is_nan(),
                        "{} ({i}, {j}) outside the mosaic holds {h}",
                        e.id
                    );
                }
            }
        }
    }
    assert!(checked > 60_000, "only {checked} samples checked");
}

#[test]
fn the_same_seed_gives_the_same_bytes() {
    let dir = temp_dir("db-synth-determinism");
    let _clean = Cleanup(dir.clone());
    let (a, b, c) = (
        dir.join("a.reliefdb"),
        dir.join("b.reliefdb"),
        dir.join("c.reliefdb"),
    );
    db::synth(&a, &small(), &|_, _| {}).unwrap();
    db::synth(&b, &small(), &|_, _| {}).unwrap();
    db::synth(&c, &db::SynthOptions { seed: 2, ..small() }, &|_, _| {}).unwrap();
    let (a, b, c) = (
        std::fs::read(a).unwrap(),
        std::fs::read(b).unwrap(),
        std::fs::read(c).unwrap(),
    );
    assert!(a == b, "two runs with the same seed differ");
    assert!(a != c, "another seed gave the same file");
}
