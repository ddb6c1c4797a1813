//! Host memory of a paged scene (`--terrain-memory`, `[terrain] memory`): `World::load_as(scene,
//! true)` loads the database window hollow — no height field, no maximum pyramid — so the
//! host's memory does not grow with the window. Alone in its test binary, so that the
//! process's VmHWM is this test's.
//!
//! The window is the whole 16x16 × 257² mosaic at its finest level: 4097² samples, whose height
//! field alone is 64 MiB (a whole load assembles it at 24 bytes a sample, 384 MiB, and adds
//! the pyramid). The hollow load must raise the peak resident set by less than
//! `HOLLOW_MAX_MIB`, and place exactly what the whole window places: the same frame,
//! georeference, spacing, pyramid levels and height range, and the same ground heights under
//! 300 random points (from the database at full resolution against the window's samples).

mod common;

use relief::scene::Scene;
use relief::world::World;

/// Most the hollow load may raise VmHWM (MiB): the window's heights alone are 64 MiB.
const HOLLOW_MAX_MIB: u64 = 24;

fn scene(dir: &std::path::Path, name: &str, extra: &str) -> Scene {
    let path = dir.join(name);
    let text = format!(
        "[terrain]\ndatabase = {:?}\nlevel = 7\ncurved = false\n{extra}\n[camera]\ngeodetic = [48.0, 14.0, 3000.0]\nheading = 90.0\npitch = -12.0\nfov = 60.0\n[output]\nwidth = 96\nheight = 72\n",
        common::pager_mosaic().display().to_string()
    );
    std::fs::write(&path, text).unwrap();
    Scene::load(&path).unwrap()
}

#[test]
fn paged_world_does_not_hold_the_window() {
    let dir = common::temp_dir("paged-host");
    let s = scene(&dir, "whole.toml", "");
    let before = common::hwm_kib();
    let t0 = std::time::Instant::now();
    let hollow = World::load_as(&s, true).unwrap().terrain;
    let load_ms = t0.elapsed().as_secs_f64() * 1e3;
    let after = common::hwm_kib();
    let t = &hollow;
    let grown_mib = match (before, after) {
        (Some(b), Some(a)) => Some((a - b) / 1024),
        _ => None,
    };
    eprintln!(
        "hollow load of the 4097² window: {load_ms:.1} ms, VmHWM {:?} -> {:?} KiB (+{grown_mib:?} MiB)",
        before, after
    );
    if let Some(g) = grown_mib {
        assert!(
            g < HOLLOW_MAX_MIB,
            "the hollow load raised the peak resident set by {g} MiB (window heights: 64 MiB)"
        );
    }
    assert_eq!((t.field.width, t.field.height), (4097, 4097));
    assert!(t.is_hollow());
    assert!(t.field.heights.is_empty(), "the height field was built");
    assert!(t.pyramid.data.is_empty(), "the maximum pyramid was built");

    // The whole window places the same terrain.
    let t0 = std::time::Instant::now();
    let whole = World::load_as(&s, false).unwrap().terrain;
    let whole_ms = t0.elapsed().as_secs_f64() * 1e3;
    eprintln!(
        "whole load: {whole_ms:.1} ms, VmHWM now {:?} KiB",
        common::hwm_kib()
    );
    assert!(!whole.is_hollow() && whole.field.heights.len() == 4097 * 4097);
    assert_eq!(t.frame, whole.frame);
    assert_eq!(t.field.geo, whole.field.geo);
    assert_eq!(t.field.spacing, whole.field.spacing);
    assert_eq!(t.pyramid.levels, whole.pyramid.levels);
    assert_eq!(
        (t.min_height, t.max_height),
        (whole.min_height, whole.max_height),
        "the window lies on tile edges: the index's range is exact"
    );
    assert_eq!((t.walls, t.curved), (whole.walls, whole.curved));
    let mut rng = common::Rng::new(20);
    let mut worst = 0.0f64;
    for _ in 0..300 {
        let (x, y) = (rng.range(0.0, 4096.0), rng.range(0.0, 4096.0));
        let a = t
            .height_at_grid(x, y)
            .expect("ground under a point of the window");
        let b = whole.height_at_grid(x, y).unwrap();
        worst = worst.max((a - b).abs());
    }
    eprintln!("ground heights: worst difference {worst:.2e} m");
    assert!(worst < 1e-3, "hollow ground {worst} m off the window's");
    assert_eq!(t.height_at_grid(-1.0, 10.0), None);
    drop(whole);

    // Sea level and vertical scale: on the range and at the samples (a hollow terrain clamps
    // the interpolated height, a loaded one the samples: they agree on the samples).
    let s = scene(
        &dir,
        "scaled.toml",
        "window = [46.0, 12.0, 50.0, 16.0]\nsea_level = 1200.0\nvertical_scale = 2.0",
    );
    let hollow = World::load_as(&s, true).unwrap().terrain;
    let whole = World::load_as(&s, false).unwrap().terrain;
    assert_eq!(
        (hollow.min_height, hollow.max_height),
        (whole.min_height, whole.max_height)
    );
    for k in 0..200 {
        let (x, y) = ((k * 37 % 1025) as f64, (k * 91 % 1025) as f64);
        let (a, b) = (
            hollow.height_at_grid(x, y).unwrap(),
            whole.height_at_grid(x, y).unwrap(),
        );
        assert!((a - b).abs() < 1e-3, "({x}, {y}): {a} against {b}");
    }
}
