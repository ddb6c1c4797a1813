//! A paged window follows the camera in `relief render` and `relief view` (without a CIGI
//! host, whose ownship `tests/cigi_serve.rs` follows). A scene's `[path]`, in the scene
//! window's metres as every path is, flies in one second from the middle of its window to a
//! point beyond the window's north-east corner, 6 km up and looking down:
//!
//! * the 16x16 × 257² mosaic (`--terrain-memory 8`): a 2° x 2° window (513² samples) around
//!   49N 15E, the path to 51N 17.3E (`render` and `view`);
//! * real data: a database compiled from `terrains/N47E009.hgt` (SRTM, the Alpstein), a
//!   0.3° x 0.4° window around 47.25N 9.3E, the path to 47.6N 9.65E (`render`).
//!
//! Checked:
//!
//! * the window moves (`paging.window` in the frame JSON) and the view's tiles are resident;
//! * the camera is where the path puts it: its position in the frame JSON, taken through that
//!   frame's own `world_from_grid` and georeference, and its `camera.geodetic`, are the
//!   keyframes' latitude and longitude (the path computed from the scene window's frame)
//!   within 1e-9°, at the path's middle and at its end;
//! * the last frame is `relief render` (in memory) of a scene with that geodetic camera and a
//!   window around it: mean difference ≤ 1/255. Without the move the eye would be off the
//!   window, over no terrain.

mod common;

use common::{
    mean_diff, pager_mosaic, project_dir, read_json, relief_cli, relief_command, temp_dir, Xvfb,
};
use std::path::{Path, PathBuf};

const HEIGHT: f64 = 6000.0;

/// A flight over a database past its scene window's edge.
struct Flight {
    database: PathBuf,
    /// The scene's window and the in-memory reference's (around `end`): [lat, lon, lat, lon].
    window: [f64; 4],
    reference_window: [f64; 4],
    /// The path's first and last point: [lat, lon].
    start: [f64; 2],
    end: [f64; 2],
    /// The tile pool (MB).
    memory: u32,
}

/// The mosaic's flight.
fn mosaic_flight() -> Flight {
    Flight {
        database: pager_mosaic(),
        window: [48.0, 14.0, 50.0, 16.0],
        reference_window: [50.0, 16.0, 52.0, 18.0],
        start: [49.0, 15.0],
        end: [51.0, 17.3],
        memory: 8,
    }
}

/// The mosaic scene window's south-west corner on its finest level (14E, 48N at 256 samples a
/// degree): where the paged window starts.
const MOSAIC_WINDOW: [i64; 2] = [49664, 35328];

fn camera_lines(at: &str) -> String {
    format!("[camera]\n{at}\nheading = 20.0\npitch = -60.0\nfov = 60.0\n[output]\nwidth = 160\nheight = 120\n")
}

fn terrain_lines(db: &Path, window: [f64; 4], memory: &str) -> String {
    format!("[terrain]\ndatabase = {db:?}\nwindow = {window:?}\ncurved = true\n{memory}\n")
}

fn render(scene: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let r = relief_cli(&args, &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

/// A frame JSON's `world_from_grid` and `geo`: world position → [lat, lon].
fn geodetic_of(meta: &serde_json::Value, p: [f64; 3]) -> [f64; 2] {
    let m = &meta["terrain"]["world_from_grid"];
    let g = &meta["terrain"]["geo"];
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    // A database window's frame: x east, y north, axis-aligned (checked).
    assert_eq!(f(&m[0][1]), 0.0, "{m}");
    assert_eq!(f(&m[1][0]), 0.0, "{m}");
    let gx = (p[0] - f(&m[0][3])) / f(&m[0][0]);
    let gy = (p[1] - f(&m[1][3])) / f(&m[1][1]);
    [
        f(&g["lat0"]) + gy * f(&g["dlat"]),
        f(&g["lon0"]) + gx * f(&g["dlon"]),
    ]
}

/// The inverse of [`geodetic_of`]: [lat, lon] → world position at `HEIGHT`.
fn world_of(meta: &serde_json::Value, [lat, lon]: [f64; 2]) -> [f64; 3] {
    let m = &meta["terrain"]["world_from_grid"];
    let g = &meta["terrain"]["geo"];
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    let gx = (lon - f(&g["lon0"])) / f(&g["dlon"]);
    let gy = (lat - f(&g["lat0"])) / f(&g["dlat"]);
    [
        f(&m[0][3]) + gx * f(&m[0][0]),
        f(&m[1][3]) + gy * f(&m[1][1]),
        HEIGHT,
    ]
}

fn position(meta: &serde_json::Value) -> [f64; 3] {
    let p = &meta["camera"]["position"];
    [0, 1, 2].map(|k| p[k].as_f64().unwrap())
}

/// The flight's scene (its path in the scene window's metres, from a first frame's JSON) and
/// the in-memory reference at the path's end, rendered to `dir/reference`.
fn scenes(dir: &Path, f: &Flight) -> PathBuf {
    let memory = format!("memory = {}", f.memory);
    let start = dir.join("start.toml");
    let at = format!("geodetic = [{}, {}, {HEIGHT}]", f.start[0], f.start[1]);
    let text = terrain_lines(&f.database, f.window, &memory) + &camera_lines(&at);
    std::fs::write(&start, text).unwrap();
    render(&start, &dir.join("start"), &[]);
    let meta = read_json(&dir.join("start").join("frame_0000.json"));
    let (a, b) = (world_of(&meta, f.start), world_of(&meta, f.end));
    let key = |t: f64, p: [f64; 3]| {
        format!("  {{ time = {t}, position = {p:?}, heading = 20.0, pitch = -60.0, roll = 0.0, fov = 60.0 }},\n")
    };
    let flight = dir.join("flight.toml");
    let path = format!(
        "[path]\nfps = 4.0\nkeyframes = [\n{}{}]\n",
        key(0.0, a),
        key(1.0, b)
    );
    let text = terrain_lines(&f.database, f.window, &memory)
        + &camera_lines(&format!("position = {a:?}"))
        + &path;
    std::fs::write(&flight, text).unwrap();
    let reference = dir.join("reference.toml");
    let at = format!("geodetic = [{}, {}, {HEIGHT}]", f.end[0], f.end[1]);
    let text = terrain_lines(&f.database, f.reference_window, "") + &camera_lines(&at);
    std::fs::write(&reference, text).unwrap();
    render(&reference, &dir.join("reference"), &[]);
    flight
}

/// `what`'s frame `png` against the in-memory reference render in `dir`: mean ≤ 1/255.
fn assert_shows_the_reference(what: &str, png: &Path, dir: &Path) {
    let img = |p: &Path| image::open(p).unwrap().to_rgba8();
    let reference = dir.join("reference").join("frame_0000.png");
    let d = mean_diff(&img(png), &img(&reference));
    eprintln!("{what}: the path's end vs the in-memory render there: mean difference {d:.4}/255");
    assert!(d <= 1.0, "{what}: mean difference {d}/255");
}

fn assert_at(meta: &serde_json::Value, want: [f64; 2], what: &str) {
    let got = geodetic_of(meta, position(meta));
    let err = (got[0] - want[0]).abs().max((got[1] - want[1]).abs());
    assert!(
        err < 1e-9,
        "{what}: camera at {got:?}, the path puts it at {want:?}"
    );
    // The frame JSON's own `camera.geodetic` says the same.
    let g = &meta["camera"]["geodetic"];
    let said = [g[0].as_f64().unwrap(), g[1].as_f64().unwrap()];
    let err = (said[0] - want[0]).abs().max((said[1] - want[1]).abs());
    assert!(
        err < 1e-9,
        "{what}: camera.geodetic {g}, the path puts it at {want:?}"
    );
}

/// `relief render --frames 5 --wait-resident` of `f` in `dir`: the windows of frames 0, 2 and
/// 4 (t = 0, 0.5, 1 s), after checking the camera there, the view's tiles resident at the end
/// and the last frame against the reference.
fn render_flight(name: &str, dir: &Path, f: &Flight) -> [[i64; 2]; 3] {
    let flight = scenes(dir, f);
    let out = dir.join("flight");
    render(&flight, &out, &["--frames", "5", "--wait-resident"]);
    let meta = |k: u32| read_json(&out.join(format!("frame_{k:04}.json")));
    let (first, mid, last) = (meta(0), meta(2), meta(4));
    assert_eq!(last["paging"]["missing"], 0, "{name}: {}", last["paging"]);
    assert_at(&first, f.start, &format!("{name}: frame 0"));
    let middle = [0.5 * (f.start[0] + f.end[0]), 0.5 * (f.start[1] + f.end[1])];
    assert_at(
        &mid,
        middle,
        &format!("{name}: frame 2 (the path's middle)"),
    );
    assert_at(&last, f.end, &format!("{name}: frame 4 (the path's end)"));
    assert_shows_the_reference(name, &out.join("frame_0004.png"), dir);
    [first, mid, last].map(|m| {
        let w = &m["paging"]["window"];
        [w[0].as_i64().unwrap(), w[1].as_i64().unwrap()]
    })
}

/// The mosaic's flight: the window moves at frame 2 and again at frame 4.
#[test]
fn render_moves_a_paged_window_along_the_path() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let dir = temp_dir("paged-follow-render");
    let [first, mid, last] = render_flight("render", &dir, &mosaic_flight());
    assert_eq!(first, MOSAIC_WINDOW);
    assert_ne!(mid, first, "the window did not move");
    assert_ne!(last, mid, "the window did not move again");
}

/// Real data: the SRTM tile compiled by `relief db build`, flown past its window's corner.
#[test]
fn render_moves_a_paged_window_over_the_alps_database() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let dir = temp_dir("paged-follow-alps");
    let hgt = project_dir().join("terrains").join("N47E009.hgt");
    let database = common::db_build(dir.join("alps.reliefdb"), &hgt);
    let f = Flight {
        database,
        window: [47.1, 9.1, 47.4, 9.5],
        reference_window: [47.45, 9.45, 47.75, 9.85],
        start: [47.25, 9.3],
        end: [47.6, 9.65],
        memory: 64,
    };
    let [first, _, last] = render_flight("alps", &dir, &f);
    assert_ne!(last, first, "the window did not move");
}

/// `relief view` (Xvfb) plays the mosaic's path at 60 Hz and holds its end; the frames render
/// what is resident, so the last of 240 is checked (the pager reads in the background).
#[test]
fn view_moves_a_paged_window_along_the_path() {
    let lock = common::gpu_lock();
    if common::gpu().is_none() {
        return;
    }
    let Some(x) = Xvfb::start() else { return };
    let dir = temp_dir("paged-follow-view");
    let f = mosaic_flight();
    let flight = scenes(&dir, &f);
    let out = dir.join("flight");
    let args = [
        "view",
        flight.to_str().unwrap(),
        "--frames",
        "240",
        "--capture-frames",
        out.to_str().unwrap(),
    ];
    let o = relief_command(
        &args,
        &[("DISPLAY", x.display.as_str()), ("RUST_LOG", "warn")],
    )
    .output()
    .expect("the relief binary runs");
    drop(lock);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let last = read_json(&out.join("frame_0239.json"));
    assert_at(&last, f.end, "view: frame 239 (the path's end)");
    assert_shows_the_reference("view", &out.join("frame_0239.png"), &dir);
}
