//! Paged rendering, CPU twin (issue 20's acceptance, the part that runs without a GPU): the
//! 16x16 × 257² synthetic mosaic, an 8 MiB pool (13 slots), flown by a scripted path, each
//! frame cast twice at 96x72 — through the pager's resident tiles (`cpu::paged`, the twin of
//! `terrain_paged.wgsl` with the paged stop rule) and through the in-memory window of the
//! finest level (full residency, `intersect_lod` exact). Per frame:
//!
//! * the pool never holds more than its budget; no update takes longer than `UPDATE_MAX`
//!   (the pager never reads on the frame's thread: `tests/pager.rs` checks that structurally);
//! * **no hole**: where the full-residency frame has terrain and the paged one sky, the ray
//!   must be above the paged (finest resident) surface at the full-residency hit point — it
//!   passed over a coarser surface, it did not fall through a crack. Required: 0 pixels
//!   otherwise; on the hover frames looking down, 0 paged sky pixels over terrain at all;
//! * **convergence**: after the camera stops the frame equals the full-residency one
//!   (identical hit masks, depth within 1e-9 relative) within `CONVERGE_FRAMES` frames and
//!   stays equal;
//! * host memory: VmHWM printed.
//!
//! On the GPU (`paged_gpu_flight_matches_twin_and_converges`, lavapipe and GL): the same
//! script rendered through the pool (`TerrainRenderer::new_paged`, shadows on, with and without
//! the paged tile pre-pass), every frame against the CPU twin over the same page table and pool
//! contents (hit masks and depth within
//! the oracle tolerance of `tests/lod.rs`), with no hole against the GPU's full-residency
//! render (same definition, GPU depth), and after the stop equal to it (identical hit masks,
//! depth within 1e-5 relative, colour mean ≤ 1/255) within `CONVERGE_FRAMES` frames.
//! `paged_gpu_curved_flight_matches_twin_and_converges`: the same on the curved earth (the twin
//! with the eye's curvature and metric in its rays). Display channels, free forms and split
//! pools against full residency follow. The CPU flight also holds the residency map equal to
//! the page-table search it replaces. `render_terrain_memory_cli`: `relief render --terrain-memory` (and `serve`)
//! and its errors.

mod common;

use common::{hwm_kib, pager_mosaic as mosaic};

use glam::DVec3;
use relief::cpu::paged::{intersect_paged, PagedTerrain};
use relief::cpu::traverse::{intersect_lod, GridRay, TraversalStats};
use relief::db::pager::{Pager, PagerOptions, TileStore, View};
use relief::db::{self, Database, Tile};
use relief::terrain::curved::GridCurvature;
use relief::terrain::{Terrain, TerrainFrame};
use std::sync::Arc;

const POOL: u64 = 8 << 20;
const W: usize = 96;
const H: usize = 72;
const FOV: f64 = 60.0;
const MAX_STEPS: u32 = 4096;
/// Frames after the camera stops within which the picture must equal full residency.
const CONVERGE_FRAMES: usize = 32;
const UPDATE_MAX: f64 = 0.010;

struct Store(Database);

impl TileStore for Store {
    fn database(&self) -> &Database {
        &self.0
    }
    fn read(&self, id: db::TileId) -> relief::Result<Option<Arc<Tile>>> {
        self.0.tile(id)
    }
}

/// Eye in the window's grid frame (samples, metres), heading and pitch in degrees.
#[derive(Clone, Copy, Debug)]
struct Cam {
    x: f64,
    y: f64,
    z: f64,
    heading: f64,
    pitch: f64,
}

fn rays(cam: Cam, spacing: [f64; 2]) -> Vec<GridRay> {
    let (h, p) = (cam.heading.to_radians(), cam.pitch.to_radians());
    let f = DVec3::new(h.sin() * p.cos(), h.cos() * p.cos(), p.sin());
    let right = DVec3::new(h.cos(), -h.sin(), 0.0);
    let up = right.cross(f);
    let tx = (FOV.to_radians() * 0.5).tan();
    let ty = tx * H as f64 / W as f64;
    let mut out = Vec::with_capacity(W * H);
    for py in 0..H {
        for px in 0..W {
            let u = (2.0 * (px as f64 + 0.5) / W as f64 - 1.0) * tx;
            let v = (1.0 - 2.0 * (py as f64 + 0.5) / H as f64) * ty;
            let m = (f + right * u + up * v).normalize();
            out.push(GridRay {
                o: DVec3::new(cam.x, cam.y, cam.z),
                d: DVec3::new(m.x / spacing[0], m.y / spacing[1], m.z),
                curv: GridCurvature::FLAT,
            });
        }
    }
    out
}

/// Height of the finest resident surface under grid point `p`.
fn resident_height(paged: &PagedTerrain, t: &Terrain, p: DVec3) -> f64 {
    let [cw, ch] = t.cells();
    let i = (p.x.floor().max(0.0) as usize).min(cw - 1);
    let j = (p.y.floor().max(0.0) as usize).min(ch - 1);
    let [h00, h10, h01, h11] = paged.patch_corners(0, i, j);
    let (u, v) = (
        (p.x - i as f64).clamp(0.0, 1.0),
        (p.y - j as f64).clamp(0.0, 1.0),
    );
    let s = h00 + (h10 - h00) * u;
    let n = h01 + (h11 - h01) * u;
    s + (n - s) * v
}

#[derive(Default, Debug)]
struct Compare {
    terrain: usize,
    holes: usize,
    coarse_sky: usize,
    mask_diff: usize,
    depth_diff: usize,
    coarse_hits: usize,
}

fn compare(t: &Terrain, paged: &PagedTerrain, cam: Cam) -> Compare {
    use rayon::prelude::*;
    let rs = rays(cam, t.frame.spacing);
    let per: Vec<_> = rs
        .par_iter()
        .map(|r| {
            let mut a = TraversalStats::default();
            let full = intersect_lod(t, r, [0.0, f64::INFINITY], MAX_STEPS, &mut a, true, 0.0);
            let mut b = TraversalStats::default();
            let pg = intersect_paged(t, paged, r, [0.0, f64::INFINITY], MAX_STEPS, &mut b);
            assert!(!a.exhausted && !b.exhausted, "step limit");
            let above = full.map(|(tf, _)| {
                let p = r.at(tf);
                p.z >= resident_height(paged, t, p) - 1e-6 * (1.0 + p.z.abs())
            });
            (full, pg, b.hit_level, above)
        })
        .collect();
    let mut c = Compare::default();
    for (full, pg, level, above) in per {
        c.terrain += full.is_some() as usize;
        match (full, pg) {
            (Some(_), None) => {
                c.mask_diff += 1;
                if above == Some(true) {
                    c.coarse_sky += 1;
                } else {
                    c.holes += 1;
                }
            }
            (None, Some(_)) => c.mask_diff += 1,
            (Some((a, _)), Some((b, _))) => {
                c.depth_diff += ((a - b).abs() > 1e-9 * a.abs().max(1.0)) as usize;
                c.coarse_hits += (level > 0) as usize;
            }
            (None, None) => {}
        }
    }
    c
}

/// The test's window: 8° x 8° of the finest level (2049² samples), its south-west sample on a
/// multiple of 2048 (its pyramid's top cell: the paged traversal starts from that one cell);
/// its origin sample and georeference.
fn window(path: &std::path::Path) -> (Terrain, [i64; 2], relief::terrain::GeoRef) {
    window_at(path, [46.0, 12.0, 54.0, 20.0])
}

/// The 8° x 8° window (2049² samples) of the finest level over `[lat, lon, lat, lon]`.
fn window_at(
    path: &std::path::Path,
    bounds: [f64; 4],
) -> (Terrain, [i64; 2], relief::terrain::GeoRef) {
    let database = Database::open(path).unwrap();
    let fine = database.header().levels.len() as u32 - 1;
    let spec = db::window::resolve(&database, Some(bounds), Some(fine)).unwrap();
    assert_eq!((spec.width, spec.height), (2049, 2049));
    let field = db::window::read(&database, &spec).unwrap();
    let frame = TerrainFrame {
        origin: DVec3::ZERO,
        axis_x: DVec3::X,
        axis_y: DVec3::Y,
        normal: DVec3::Z,
        spacing: field.spacing,
    };
    let geo = field.geo.expect("a database window is georeferenced");
    let terrain = Terrain::new(field, frame, 1.0).unwrap();
    eprintln!(
        "window {}x{} at sample ({}, {}), spacing {:.1} x {:.1} m, heights {}..{} m, top level {}",
        spec.width,
        spec.height,
        spec.i0,
        spec.j0,
        terrain.frame.spacing[0],
        terrain.frame.spacing[1],
        terrain.min_height,
        terrain.max_height,
        terrain.pyramid.top()
    );
    (terrain, [spec.i0, spec.j0], geo)
}

/// Flight frames, then hover frames.
const FLIGHT: usize = 40;
const HOVER: usize = 40;

/// The scripted camera: a low-level flight east over the middle row of tiles, 4 km a frame
/// (two finest tiles crossed), then a stop over the middle of a finest tile, looking down.
fn script(terrain: &Terrain) -> Vec<Cam> {
    let hi = terrain.max_height as f64;
    let dx = 4000.0 / terrain.frame.spacing[0];
    let mut out: Vec<Cam> = (1..=FLIGHT)
        .map(|k| Cam {
            x: 300.0 + dx * k as f64,
            y: 1000.0,
            z: hi + 800.0,
            heading: 90.0,
            pitch: -12.0,
        })
        .collect();
    let hover = Cam {
        x: 1152.0 + 40.0,
        y: 1152.0 - 90.0,
        z: hi + 1500.0,
        heading: 20.0,
        pitch: -60.0,
    };
    out.extend(std::iter::repeat_n(hover, HOVER));
    out
}

/// The flight's start: the mosaic's window, a pager over it with the test's pool, and a host
/// copy of the pool holding the pager's first uploads (`first`).
struct Flight {
    terrain: Terrain,
    origin: [i64; 2],
    geo: relief::terrain::GeoRef,
    top: usize,
    pager: Pager,
    pool: Vec<Option<Arc<Tile>>>,
    first: Vec<db::pager::Upload>,
}

impl Flight {
    fn start() -> Flight {
        Self::start_at([46.0, 12.0, 54.0, 20.0])
    }

    /// The flight over the 8° x 8° window at `bounds`.
    fn start_at(bounds: [f64; 4]) -> Flight {
        let path = mosaic();
        let (terrain, origin, geo) = window_at(&path, bounds);
        let top = terrain.pyramid.top();
        let store: Arc<dyn TileStore> = Arc::new(Store(Database::open(&path).unwrap()));
        let opts = PagerOptions {
            pool_bytes: POOL,
            ..PagerOptions::default()
        };
        let (pager, first) = Pager::new(store, opts).unwrap();
        let mut pool = vec![None; pager.slots().0];
        apply(&mut pool, &first);
        Flight {
            terrain,
            origin,
            geo,
            top,
            pager,
            pool,
            first,
        }
    }
}

/// The uploads `up` into the host copy of the pool.
fn apply(pool: &mut [Option<Arc<Tile>>], up: &[db::pager::Upload]) {
    for u in up {
        pool[u.slot as usize] = Some(u.tile.clone());
    }
}

/// The pager's view of camera `c` over the window of `geo`, `width` x `height` pixels.
fn view(geo: &relief::terrain::GeoRef, c: Cam, width: u32, height: u32) -> View {
    View {
        lon: geo.lon0 + c.x * geo.dlon,
        lat: geo.lat0 + c.y * geo.dlat,
        height: c.z,
        heading: c.heading,
        pitch: c.pitch,
        fov: FOV,
        width,
        height_px: height,
        cone: None,
    }
}

#[test]
fn paged_flight_no_holes_and_converges() {
    // Its updates are timed (`UPDATE_MAX`): not beside this binary's GPU tests, whose
    // software rasterisers take both cores.
    let _lock = common::gpu_lock();
    let Flight {
        terrain,
        origin,
        geo,
        top,
        mut pager,
        mut pool,
        ..
    } = Flight::start();
    let flight = FLIGHT;
    let (mut worst_update, mut converged, mut worst_holes) = (0f64, None, 0usize);
    let mut map_checks = 0usize;
    for (frame, &cam) in script(&terrain).iter().enumerate() {
        let (up, st) = pager.update(&view(&geo, cam, W as u32, H as u32)).unwrap();
        worst_update = worst_update.max(st.seconds);
        apply(&mut pool, &up);
        assert!(
            st.resident_bytes <= POOL,
            "frame {frame}: {} bytes",
            st.resident_bytes
        );
        let paged = PagedTerrain::new(pager.page_table(), &pool, 256, origin, top).unwrap();
        map_checks += map_matches_search(&terrain, &paged, frame);
        let c = compare(&terrain, &paged, cam);
        eprintln!(
            "frame {frame:2}: resident {} ({:.1} MiB) missing {:2} | terrain {:4} coarse hits {:4} coarse sky {:3} holes {} mask diff {:3} depth diff {:4}",
            st.resident, st.resident_bytes as f64 / 1048576.0, st.missing, c.terrain,
            c.coarse_hits, c.coarse_sky, c.holes, c.mask_diff, c.depth_diff
        );
        worst_holes = worst_holes.max(c.holes);
        assert!(c.terrain > 0, "frame {frame}: the view must see terrain");
        if frame >= flight {
            assert_eq!(
                c.coarse_sky, 0,
                "frame {frame}: sky over terrain while hovering"
            );
            let equal = c.mask_diff == 0 && c.depth_diff == 0;
            match (converged, equal) {
                (None, true) => converged = Some(frame - flight),
                (Some(at), false) => panic!("frame {frame}: diverged after converging at {at}"),
                _ => {}
            }
        }
    }
    let hwm = hwm_kib().unwrap_or(0);
    eprintln!("residency map: {map_checks} cells equal to the page table's search");
    eprintln!(
        "worst update {:.2} ms; converged {converged:?} frames after the stop; holes {worst_holes}; VmHWM {} MiB",
        worst_update * 1e3,
        hwm / 1024
    );
    assert_eq!(worst_holes, 0, "a ray fell through the paged surface");
    let at = converged.expect("the hover never matched full residency");
    assert!(at <= CONVERGE_FRAMES, "converged after {at} frames");
    assert!(map_checks > 0);
    assert!(
        worst_update < UPDATE_MAX,
        "an update took {:.1} ms",
        worst_update * 1e3
    );
}

/// The residency map (one read a step) answers as the page-table search it replaces (a tile
/// lookup per level tried): the finest resident level and its tile, at every level, on the
/// first and last cell of every tile-sized block (the map has one entry per block) and on
/// every cell of the coarser levels; returns the cells checked.
fn map_matches_search(terrain: &Terrain, paged: &PagedTerrain, frame: usize) -> usize {
    let pyr = &terrain.pyramid;
    let mut checked = 0;
    for (level, l) in pyr.levels.iter().enumerate() {
        let block = (256usize >> level.min(8)).max(1);
        let cells = |n: usize| {
            (0..n)
                .filter(move |&i| i % block == 0 || i % block == block - 1 || i + 1 == n)
                .collect::<Vec<_>>()
        };
        for &j in &cells(l.cells[1] as usize) {
            for &i in &cells(l.cells[0] as usize) {
                let a = paged.finest_resident(level as u32, i, j);
                let b = paged.finest_resident_searched(level as u32, i, j);
                let same = match (a, b) {
                    (Some((ja, ta)), Some((jb, tb))) => ja == jb && std::ptr::eq(ta, tb),
                    (None, None) => true,
                    _ => false,
                };
                assert!(
                    same,
                    "frame {frame}: level {level} cell ({i}, {j}): map {:?} search {:?}",
                    a.map(|x| x.0),
                    b.map(|x| x.0)
                );
                checked += 1;
            }
        }
    }
    checked
}

// ---------------------------------------------------------------------------------------------
// The GPU through the pool (`TerrainRenderer::new_paged`): the same mosaic, budget and script.

/// GPU frame size (≤ 128x96: lavapipe and GL in CI).
const GW: u32 = 96;
const GH: u32 = 72;
/// GPU (f32) against the CPU twin (f64) over the same page table: hit masks may differ on at
/// most this fraction of the pixels (grazing rays), depth within `GPU_CPU_DEPTH` relative on
/// the rest (the oracle tolerance of `tests/lod.rs`).
const GPU_CPU_MASK: f64 = 0.005;
const GPU_CPU_DEPTH: f64 = 1e-3;

fn gpu_camera(terrain: &Terrain, c: Cam) -> relief::scene::Camera {
    let pose = relief::scene::Pose {
        position: terrain.frame.grid_to_world(DVec3::new(c.x, c.y, c.z)),
        heading: c.heading,
        pitch: c.pitch,
        roll: 0.0,
        fov: FOV,
    };
    relief::scene::Camera::new(pose, GW, GH)
}

/// Per frame: GPU paged against the CPU twin over the same resident tiles, and against the
/// GPU's full-residency render of the in-memory window.
#[derive(Default, Debug)]
struct GpuCompare {
    terrain: usize,
    /// GPU paged vs CPU `intersect_paged`: hit masks differing; depth beyond tolerance.
    twin_mask: usize,
    twin_depth: usize,
    /// GPU paged vs GPU full residency.
    holes: usize,
    coarse_sky: usize,
    mask_diff: usize,
    depth_diff: usize,
    colour_mean: f64,
}

fn gpu_compare(
    terrain: &Terrain,
    paged: &PagedTerrain,
    cam: &relief::scene::Camera,
    gp: &relief::gpu::FrameOutput,
    full: &relief::gpu::FrameOutput,
) -> GpuCompare {
    use rayon::prelude::*;
    let n = (GW * GH) as usize;
    let twin: Vec<Option<f64>> = (0..n)
        .into_par_iter()
        .map(|k| {
            let (x, y) = (k as u32 % GW, k as u32 / GW);
            let r = GridRay::from_world(terrain, cam.pose.position, cam.pixel_ray(x, y));
            let mut st = TraversalStats::default();
            let hit = intersect_paged(terrain, paged, &r, [0.0, f64::INFINITY], MAX_STEPS, &mut st);
            hit.map(|(t, _)| t)
        })
        .collect();
    let mut c = GpuCompare::default();
    let mut colour = 0u64;
    for (k, &tw) in twin.iter().enumerate() {
        let (g, f) = (gp.depth[k] as f64, full.depth[k] as f64);
        let (gh, fh) = (g.is_finite(), f.is_finite());
        c.terrain += fh as usize;
        match (tw, gh) {
            (Some(t), true) => c.twin_depth += ((t - g).abs() > GPU_CPU_DEPTH * t) as usize,
            (None, false) => {}
            _ => c.twin_mask += 1,
        }
        match (fh, gh) {
            (true, false) => {
                c.mask_diff += 1;
                let (x, y) = (k as u32 % GW, k as u32 / GW);
                let r = GridRay::from_world(terrain, cam.pose.position, cam.pixel_ray(x, y));
                // The ray's height above the datum there (on the curved earth its z plus the
                // drop, as the traversal sees it).
                let (p, z) = (r.at(f), r.lifted(f));
                if z >= resident_height(paged, terrain, p) - 1e-3 * (1.0 + z.abs()) {
                    c.coarse_sky += 1;
                } else {
                    c.holes += 1;
                }
            }
            (false, true) => c.mask_diff += 1,
            (true, true) => c.depth_diff += ((f - g).abs() > 1e-5 * f) as usize,
            (false, false) => {}
        }
        for ch in 0..3 {
            colour +=
                (gp.rgba[4 * k + ch] as i32 - full.rgba[4 * k + ch] as i32).unsigned_abs() as u64;
        }
    }
    c.colour_mean = colour as f64 / (3 * n) as f64 / 255.0;
    c
}

#[test]
fn paged_gpu_flight_matches_twin_and_converges() {
    let Some(gpu) = common::gpu() else { return };
    let _lock = common::gpu_lock();
    flight_against_twin(gpu, false, [46.0, 12.0, 54.0, 20.0]);
}

/// `render --terrain-memory` of a scene whose window lies on no tile corner (`[46.3, 12.2, 50.1,
/// 16.4]`): the hollow window and the pool's move out to the tile corner south-west of it
/// (`db::window::on_tile_corners`), and with the camera placed geodetically on the curved
/// earth (everything eye-relative in the eye's metric) the paged frame, once its view is
/// resident, is the in-memory render of the scene's own window: depth within 1e-5 relative on
/// the same terrain pixels, colour mean ≤ 1/255. Looking down from 3 km above the highest
/// point, so the view wants the finest tiles everywhere.
#[test]
fn a_window_on_no_tile_corner_renders_paged_as_in_memory() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let db_path = mosaic();
    let dir = common::temp_dir("paged-unaligned");
    let scene = dir.join("unaligned.toml");
    std::fs::write(
        &scene,
        format!(
            "[terrain]\ndatabase = {:?}\nwindow = [46.3, 12.2, 50.1, 16.4]\ncurved = true\n[camera]\ngeodetic = [48.2, 14.3, 6000.0]\nheading = 20.0\npitch = -60.0\nfov = 60.0\n[output]\nwidth = 96\nheight = 72\n",
            db_path.display().to_string()
        ),
    )
    .unwrap();
    let sc = scene.to_str().unwrap();
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let o = out.to_str().unwrap();
        let mut args = vec!["render", sc, "--out", o];
        args.extend_from_slice(extra);
        let r = common::relief_cli(&args, &[]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let png = image::open(out.join("frame_0000.png")).unwrap().to_rgb8();
        let (_, _, depth) =
            relief::app::output::read_depth_tiff(&out.join("depth_0000.tiff")).unwrap();
        (png, depth, out)
    };
    // Plain and anti-aliased (the samples' rays walk the pool as the centre rays do).
    for aa in ["off", "edges"] {
        let paged_args = ["--terrain-memory", "8", "--antialias", aa];
        let (paged_png, paged_depth, paged_out) = render(&format!("paged-{aa}"), &paged_args);
        let meta = common::read_json(&paged_out.join("frame_0000.json"));
        assert_eq!(meta["paging"]["missing"], 0, "{}", meta["paging"]);
        if aa != "off" {
            let pixels = meta["antialias"]["pixels"].as_u64().unwrap_or(0);
            assert!(pixels > 100, "anti-aliased pixels: {}", meta["antialias"]);
        }
        let (mem_png, mem_depth, _) = render(&format!("memory-{aa}"), &["--antialias", aa]);
        compare_unaligned(aa, (&paged_png, &paged_depth), (&mem_png, &mem_depth));
    }
}

/// Paged against in-memory frames of `a_window_on_no_tile_corner_renders_paged_as_in_memory`:
/// the same terrain pixels, depth within 1e-5 relative, colour mean ≤ 1/255.
fn compare_unaligned(
    what: &str,
    (paged_png, paged_depth): (&image::RgbImage, &[f32]),
    (mem_png, mem_depth): (&image::RgbImage, &[f32]),
) {
    let (mut terrain, mut mask, mut depth) = (0, 0, 0);
    for (a, b) in paged_depth.iter().zip(mem_depth) {
        let (a, b) = (*a as f64, *b as f64);
        terrain += b.is_finite() as usize;
        match (a.is_finite(), b.is_finite()) {
            (true, true) => depth += ((a - b).abs() > 1e-5 * b) as usize,
            (false, false) => {}
            _ => mask += 1,
        }
    }
    let colour: u64 = paged_png
        .as_raw()
        .iter()
        .zip(mem_png.as_raw())
        .map(|(a, b)| (*a as i64 - *b as i64).unsigned_abs())
        .sum();
    let mean = colour as f64 / paged_png.as_raw().len() as f64 / 255.0;
    eprintln!(
        "unaligned window, antialias {what}: terrain {terrain} mask {mask} depth {depth} colour mean {mean:.5}"
    );
    assert!(terrain > 5000, "the view shows terrain: {terrain} pixels");
    assert_eq!((mask, depth), (0, 0), "paged differs from in memory");
    assert!(mean <= 1.0 / 255.0, "colour mean {mean}");
}

/// A window aligned to tiles only (1° = one 256-cell tile east and north of the aligned one:
/// its origin a multiple of 256 finest samples, not of its 2048-cell top cell): the paged
/// traversal starts from the tile level's grid of cells (`cpu::paged::traversal_top` 8, not
/// 11), and the flight matches the twin and converges to full residency as before.
#[test]
fn paged_gpu_flight_over_a_window_aligned_to_tiles_only() {
    let Some(gpu) = common::gpu() else { return };
    let _lock = common::gpu_lock();
    flight_against_twin(gpu, false, [47.0, 13.0, 55.0, 21.0]);
}

/// The same flight on the curved earth (`CURVED` in the paged cast, shade and tile pre-pass;
/// the CPU twin with the eye's curvature and metric in its rays): GPU against the twin on
/// every frame, no hole against the GPU's full residency, equal to it after the stop.
#[test]
fn paged_gpu_curved_flight_matches_twin_and_converges() {
    let Some(gpu) = common::gpu() else { return };
    let _lock = common::gpu_lock();
    flight_against_twin(gpu, true, [46.0, 12.0, 54.0, 20.0]);
}

fn flight_against_twin(gpu: &relief::gpu::Gpu, curved: bool, bounds: [f64; 4]) {
    let Flight {
        mut terrain,
        origin,
        geo,
        top,
        mut pager,
        mut pool,
        first,
    } = Flight::start_at(bounds);
    terrain.curved = curved;
    let slots = pool.len();
    let gpu_pool =
        relief::gpu::terrain_pool::TerrainPool::new(gpu, pager.page_table(), 256, slots).unwrap();
    assert!(gpu_pool.size().1 <= POOL, "GPU pool over the budget");
    let mut paged_r =
        relief::gpu::TerrainRenderer::new_paged(gpu, &terrain, gpu_pool, origin).unwrap();
    let start = relief::cpu::paged::traversal_top(origin, top);
    assert_eq!(paged_r.pool().unwrap().traversal_top() as usize, start);
    eprintln!("window at {origin:?}: pyramid top {top}, paged traversal from level {start}");
    let mut full_r = relief::gpu::TerrainRenderer::new(gpu, &terrain).unwrap();
    paged_r.apply_pages(gpu, &first, pager.page_table());
    let scene = common::synthetic_scene(GW, GH, "position = [0.0, 0.0, 5000.0]");
    let settings = common::settings(true, false);
    // The paged tile pre-pass (cone through the pool's maxima) starts the rays; the twin and
    // the full-residency render start at the top.
    let with_tiles = common::settings(true, true);
    let mut converged = [None; 2];
    let (mut worst_holes, mut worst_twin) = (0usize, 0f64);
    for (frame, &c) in script(&terrain).iter().enumerate() {
        let (up, st) = pager.update(&view(&geo, c, GW, GH)).unwrap();
        assert!(
            st.resident_bytes <= POOL,
            "frame {frame}: {} bytes",
            st.resident_bytes
        );
        apply(&mut pool, &up);
        paged_r.apply_pages(gpu, &up, pager.page_table());
        let cam = gpu_camera(&terrain, c);
        let full = full_r
            .capture(gpu, &terrain, &scene, &cam, &settings)
            .unwrap();
        let paged = PagedTerrain::new(pager.page_table(), &pool, 256, origin, top).unwrap();
        for (v, s) in [&settings, &with_tiles].into_iter().enumerate() {
            let gp = paged_r.capture(gpu, &terrain, &scene, &cam, s).unwrap();
            let g = gpu_compare(&terrain, &paged, &cam, &gp, &full);
            let pre = ["off", "on "][v];
            eprintln!(
                "GPU (curved {curved}) frame {frame:2} tile pre-pass {pre}: resident {:2} missing {:2} | terrain {:4} | vs CPU twin: mask {:3} depth {:3} | vs full: holes {} coarse sky {:3} mask {:3} depth {:4} colour mean {:.5}",
                st.resident, st.missing, g.terrain, g.twin_mask, g.twin_depth, g.holes, g.coarse_sky,
                g.mask_diff, g.depth_diff, g.colour_mean
            );
            let n = (GW * GH) as f64;
            let twin_bad = (g.twin_mask + g.twin_depth) as f64 / n;
            worst_twin = worst_twin.max(twin_bad);
            worst_holes = worst_holes.max(g.holes);
            assert!(g.terrain > 0, "frame {frame}: the view must see terrain");
            assert!(
                twin_bad <= GPU_CPU_MASK,
                "frame {frame}, tile pre-pass {pre}: GPU paged disagrees with the CPU twin on {} pixels",
                g.twin_mask + g.twin_depth
            );
            if frame >= FLIGHT {
                let equal = g.mask_diff == 0 && g.depth_diff == 0 && g.colour_mean <= 1.0 / 255.0;
                match (converged[v], equal) {
                    (None, true) => converged[v] = Some(frame - FLIGHT),
                    (Some(at), false) => {
                        panic!(
                            "frame {frame}, tile pre-pass {pre}: diverged after converging at {at}"
                        )
                    }
                    _ => {}
                }
            }
        }
    }
    eprintln!(
        "GPU (curved {curved}): converged {converged:?} frames after the stop (tile pre-pass off, on); holes {worst_holes}; worst twin disagreement {:.3}%; VmHWM {} MiB",
        worst_twin * 100.0,
        hwm_kib().unwrap_or(0) / 1024
    );
    assert_eq!(worst_holes, 0, "a GPU ray fell through the paged surface");
    for at in converged {
        let at = at.expect("the GPU hover never matched full residency");
        assert!(at <= CONVERGE_FRAMES, "converged after {at} frames");
    }
}

/// `relief render --terrain-memory`: a database scene renders one frame through an 8 MB pool
/// after its view's tiles are resident (the frame JSON's `paging`); a scene without a
/// database, a zero budget and a window not at the finest level are one-line errors.
#[test]
fn render_terrain_memory_cli() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let db_path = mosaic();
    let dir = common::temp_dir("paged-cli");
    let scene = |window: &str, extra: &str| {
        format!(
            "[terrain]\ndatabase = {:?}\nwindow = {window}\ncurved = false\n{extra}\n[camera]\nposition = [120000.0, 434000.0, 3700.0]\nheading = 90.0\npitch = -12.0\nfov = 60.0\n[output]\nwidth = 96\nheight = 72\n",
            db_path.display().to_string()
        )
    };
    let good = dir.join("mosaic.toml");
    std::fs::write(&good, scene("[46.0, 12.0, 54.0, 20.0]", "")).unwrap();
    let out = dir.join("out");
    let (g, o) = (good.to_str().unwrap(), out.to_str().unwrap());
    let r = common::relief_cli(&["render", g, "--terrain-memory", "8", "--out", o], &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let meta = common::read_json(&out.join("frame_0000.json"));
    let paging = &meta["paging"];
    eprintln!("paging: {paging}");
    assert_eq!(
        paging["missing"], 0,
        "rendered before the view was resident"
    );
    assert!(paging["resident_bytes"].as_u64().unwrap() <= 8 << 20);
    // `serve` pages each frame without waiting (no CIGI host: the scene's camera).
    let served = dir.join("served");
    let sv = served.to_str().unwrap();
    let r = common::relief_cli(
        &[
            "serve",
            g,
            "--cigi",
            "0",
            "--frames",
            "20",
            "--terrain-memory",
            "8",
            "--capture-frames",
            sv,
        ],
        &[],
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let last = common::read_json(&served.join("frame_0019.json"));
    assert!(
        last["paging"]["resident"].as_u64().unwrap() > 0,
        "{}",
        last["paging"]
    );
    let fail = |args: &[&str], want: &str| {
        let r = common::relief_cli(args, &[]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    };
    let hgt = common::terrains().join("alps-far.toml");
    let h = hgt.to_str().unwrap();
    fail(
        &["render", h, "--terrain-memory", "8", "--out", o],
        "has no `[terrain] database`",
    );
    fail(
        &["render", g, "--terrain-memory", "0", "--out", o],
        "--terrain-memory",
    );
    // `[terrain] memory` in the scene does what --terrain-memory does.
    let keyed = dir.join("keyed.toml");
    std::fs::write(&keyed, scene("[46.0, 12.0, 54.0, 20.0]", "memory = 8")).unwrap();
    let out2 = dir.join("out2");
    let (k, o2) = (keyed.to_str().unwrap(), out2.to_str().unwrap());
    let r = common::relief_cli(&["render", k, "--out", o2], &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let meta = common::read_json(&out2.join("frame_0000.json"));
    assert_eq!(meta["paging"]["missing"], 0, "{}", meta["paging"]);
    fail(
        &["render", h, "--wait-resident", "--out", o],
        "--wait-resident",
    );
    let coarse = dir.join("coarse.toml");
    std::fs::write(&coarse, scene("[46.0, 12.0, 54.0, 20.0]", "level = 5")).unwrap();
    let c = coarse.to_str().unwrap();
    fail(
        &["render", c, "--terrain-memory", "8", "--out", o],
        "finest level",
    );
}

/// Free forms over a paged terrain: a sphere, a box and a perturbed cylinder standing on the
/// hover's ground (shadows on, so the shade pass walks the pool from the objects too), GPU paged
/// against GPU full residency: converged frames equal (masks, depth within 1e-5, colour).
#[test]
fn paged_gpu_free_forms_match_full_residency() {
    let Some(gpu) = common::gpu() else { return };
    let _lock = common::gpu_lock();
    let objects = r#"
[[objects]]
shape = "sphere"
radius = 150.0
position = [X0, Y0, 0.0]
above_terrain = 100.0
material = { colour = [0.8, 0.2, 0.1] }

[[objects]]
shape = "box"
size = [250, 120, 200]
position = [X1, Y1, 0.0]
above_terrain = 0.0
heading = 30.0
material = { colour = [0.2, 0.3, 0.8] }

[[objects]]
shape = "cylinder"
radius = 90
height = 400
position = [X2, Y2, 0.0]
above_terrain = -5.0
pitch = 90.0
bounds = [[-120, -120, 0], [120, 120, 400]]
material = { colour = [0.6, 0.6, 0.6] }
[[objects.perturb]]
shape = "ellipsoid"
radii = [60, 60, 80]
centre = [0, 0, 0]
weight = 4
"#;
    let (at, object_px) = hover_against_full(gpu, objects);
    eprintln!("free forms: converged after {at} frames; {object_px} free-form pixels");
    assert!(
        object_px > 100,
        "the free forms must be in view: {object_px} pixels"
    );
    assert!(at <= CONVERGE_FRAMES, "converged after {at} frames");
}

/// The hover of the script through the pool, frame by frame against the full-residency render
/// of the in-memory window (`objects`: `[[objects]]` TOML placed around
/// the view's centre, `X0`..`Y2` replaced by world positions), until they match: the frame at
/// which they first matched (they must stay matched) and the free-form pixels of the
/// full-residency frame.
fn hover_against_full(gpu: &relief::gpu::Gpu, objects: &str) -> (usize, usize) {
    let path = mosaic();
    let (terrain, origin, geo) = window(&path);
    let store: Arc<dyn TileStore> = Arc::new(Store(Database::open(&path).unwrap()));
    let opts = PagerOptions {
        pool_bytes: POOL,
        ..PagerOptions::default()
    };
    let (mut pager, first) = Pager::new(store, opts).unwrap();
    let (slots, _) = pager.slots();
    let gpu_pool =
        relief::gpu::terrain_pool::TerrainPool::new(gpu, pager.page_table(), 256, slots).unwrap();
    let mut paged_r =
        relief::gpu::TerrainRenderer::new_paged(gpu, &terrain, gpu_pool, origin).unwrap();
    let mut full_r = relief::gpu::TerrainRenderer::new(gpu, &terrain).unwrap();
    paged_r.apply_pages(gpu, &first, pager.page_table());
    let c = *script(&terrain).last().unwrap();
    let cam = gpu_camera(&terrain, c);
    if !objects.is_empty() {
        // Around the point the view looks at, ~1 km ahead of the hover on its heading.
        let ahead = |d: f64, side: f64| {
            let h = c.heading.to_radians();
            let (e, n) = (d * h.sin() + side * h.cos(), d * h.cos() - side * h.sin());
            let p = terrain.frame.grid_to_world(DVec3::new(c.x, c.y, 0.0));
            (p.x + e, p.y + n)
        };
        let mut text = objects.to_string();
        for (k, (d, side)) in [(900.0, 0.0), (1100.0, 450.0), (800.0, -450.0)]
            .into_iter()
            .enumerate()
        {
            let (x, y) = ahead(d, side);
            text = text
                .replace(&format!("X{k}"), &format!("{x:.1}"))
                .replace(&format!("Y{k}"), &format!("{y:.1}"));
        }
        let scene = relief::scene::Scene::parse(
            &format!(
                "[terrain.procedural]\nsize = 2\n[camera]\nposition = [0.0, 0.0, 5000.0]\n{text}"
            ),
            std::path::Path::new("objects.toml"),
        )
        .unwrap();
        let objects = scene.free_forms(&terrain).unwrap();
        paged_r.set_objects(gpu, &objects).unwrap();
        full_r.set_objects(gpu, &objects).unwrap();
    }
    let scene = common::synthetic_scene(GW, GH, "position = [0.0, 0.0, 5000.0]");
    let settings = common::settings(true, false);
    let view = View {
        lon: geo.lon0 + c.x * geo.dlon,
        lat: geo.lat0 + c.y * geo.dlat,
        height: c.z,
        heading: c.heading,
        pitch: c.pitch,
        fov: FOV,
        width: GW,
        height_px: GH,
        cone: None,
    };
    let full = full_r
        .capture(gpu, &terrain, &scene, &cam, &settings)
        .unwrap();
    let object_px = full.objects.iter().filter(|&&o| o != 0).count();
    let converged = Hover {
        gpu,
        terrain: &terrain,
        scene: &scene,
        cam: &cam,
        view: &view,
        pool: POOL,
        label: "hover",
        min_terrain: 1,
    }
    .until_equal(&mut pager, &mut paged_r, &full);
    (
        converged.expect("the hover never matched full residency"),
        object_px,
    )
}

/// A hover through the pool against a full-residency frame.
struct Hover<'a> {
    gpu: &'a relief::gpu::Gpu,
    terrain: &'a Terrain,
    scene: &'a relief::scene::SceneDesc,
    cam: &'a relief::scene::Camera,
    view: &'a View,
    /// The pool's budget (bytes).
    pool: u64,
    label: &'a str,
    /// Terrain pixels the full-residency frame must have.
    min_terrain: usize,
}

impl Hover<'_> {
    /// `HOVER` frames, each: the pager updated for the view, its uploads applied, the paged
    /// frame rendered as a scene renders it (tile pre-pass on; the curved surface is nowhere
    /// above the flat maxima the cone tests) and compared with `full` (rendered from the top).
    /// The frame at which they first matched (they must stay matched), if they did.
    fn until_equal(
        &self,
        pager: &mut Pager,
        paged_r: &mut relief::gpu::TerrainRenderer,
        full: &relief::gpu::FrameOutput,
    ) -> Option<usize> {
        let mut converged = None;
        for frame in 0..HOVER {
            let (up, st) = pager.update(self.view).unwrap();
            assert!(st.resident_bytes <= self.pool);
            paged_r.apply_pages(self.gpu, &up, pager.page_table());
            let settings = common::settings(true, true);
            let gp = paged_r
                .capture(self.gpu, self.terrain, self.scene, self.cam, &settings)
                .unwrap();
            let (mask, depth, mean, terrain_px) = against_full(&gp, full);
            eprintln!(
                "{} frame {frame:2}: resident {:2} missing {:2} | terrain {terrain_px} mask {mask} depth {depth} colour mean {mean:.5}",
                self.label, st.resident, st.missing
            );
            assert!(
                terrain_px >= self.min_terrain,
                "{}: the view shows terrain",
                self.label
            );
            let equal = mask == 0 && depth == 0 && mean <= 1.0 / 255.0;
            match (converged, equal) {
                (None, true) => converged = Some(frame),
                (Some(at), false) => panic!("frame {frame}: diverged after converging at {at}"),
                _ => {}
            }
            // Give the workers the time a real frame would (the GPU frames here are short).
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        converged
    }
}

/// A paged frame against the full-residency one: hit masks differing (the free form shown
/// counts as the mask), depths beyond 1e-5 relative, mean colour difference (0..1), and the
/// full-residency frame's terrain pixels.
fn against_full(
    gp: &relief::gpu::FrameOutput,
    full: &relief::gpu::FrameOutput,
) -> (usize, usize, f64, usize) {
    let (mut mask, mut depth, mut colour, mut terrain_px) = (0, 0, 0u64, 0);
    let n = full.depth.len();
    for k in 0..n {
        let (g, f) = (gp.depth[k] as f64, full.depth[k] as f64);
        terrain_px += f.is_finite() as usize;
        match (g.is_finite(), f.is_finite()) {
            (true, true) => depth += ((f - g).abs() > 1e-5 * f) as usize,
            (false, false) => {}
            _ => mask += 1,
        }
        mask += (gp.objects[k] != full.objects[k]) as usize;
        for ch in 0..3 {
            let d = gp.rgba[4 * k + ch] as i32 - full.rgba[4 * k + ch] as i32;
            colour += d.unsigned_abs() as u64;
        }
    }
    (
        mask,
        depth,
        colour as f64 / (3 * n) as f64 / 255.0,
        terrain_px,
    )
}

/// A pool split over several storage bindings (as a pool over the adapter's binding size is:
/// 256 MB on lavapipe takes four) renders what one buffer renders: the flight and the hover
/// with the 13-slot pool in buffers of 4 slots (4 bindings), every frame bit for bit.
#[test]
fn paged_pool_split_over_bindings_renders_the_same() {
    let Some(gpu) = common::gpu() else { return };
    let _lock = common::gpu_lock();
    let Flight {
        terrain,
        origin,
        geo,
        mut pager,
        first,
        ..
    } = Flight::start();
    let slots = pager.slots().0;
    let table = pager.page_table();
    use relief::gpu::terrain_pool::TerrainPool;
    let one = TerrainPool::new(gpu, table, 256, slots).unwrap();
    // Room for 5 slots a buffer: split at a power of two, 4.
    let limit = 5 * db::pager::slot_bytes(256);
    let split = TerrainPool::with_binding_limit(gpu, table, 256, slots, limit).unwrap();
    assert_eq!((one.bindings(), split.bindings()), (1, 4));
    // Room for one slot a buffer: 13 bindings, over the four a pool may span.
    let one_slot = db::pager::slot_bytes(256);
    match TerrainPool::with_binding_limit(gpu, table, 256, slots, one_slot) {
        Err(e) => assert!(
            e.to_string().contains("--terrain-memory"),
            "the error names the option: {e}"
        ),
        Ok(p) => panic!("a pool of {} bindings was accepted", p.bindings()),
    }
    let mut r1 = relief::gpu::TerrainRenderer::new_paged(gpu, &terrain, one, origin).unwrap();
    let mut r3 = relief::gpu::TerrainRenderer::new_paged(gpu, &terrain, split, origin).unwrap();
    r1.apply_pages(gpu, &first, pager.page_table());
    r3.apply_pages(gpu, &first, pager.page_table());
    let scene = common::synthetic_scene(GW, GH, "position = [0.0, 0.0, 5000.0]");
    let settings = common::settings(true, true);
    let script = script(&terrain);
    let mut slots_used = std::collections::BTreeSet::new();
    for (frame, &c) in script.iter().enumerate().step_by(4) {
        let (up, _) = pager.update(&view(&geo, c, GW, GH)).unwrap();
        slots_used.extend(up.iter().map(|u| u.slot));
        r1.apply_pages(gpu, &up, pager.page_table());
        r3.apply_pages(gpu, &up, pager.page_table());
        let cam = gpu_camera(&terrain, c);
        let a = r1.capture(gpu, &terrain, &scene, &cam, &settings).unwrap();
        let b = r3.capture(gpu, &terrain, &scene, &cam, &settings).unwrap();
        assert!(a.depth.iter().any(|d| d.is_finite()));
        let depth_same = a
            .depth
            .iter()
            .zip(&b.depth)
            .all(|(x, y)| x.to_bits() == y.to_bits());
        assert!(
            depth_same && a.rgba == b.rgba,
            "frame {frame}: split pool differs"
        );
    }
    // The uploads reached every buffer of the split pool.
    assert!(
        slots_used.iter().any(|&s| s >= 12),
        "slots used: {slots_used:?}"
    );
}

/// A display channel looking elsewhere than the scene camera (a cylinder's left projector, 62°
/// to the left of the camera's forward, 96x72): the pager's view of it
/// (`app::paged::view_of` with its `ChannelRays`, what `render --display` and `view --display`
/// page for) holds every ray of the channel's table in its cone, the rays computed by the CPU
/// distortion oracle with the display-to-world rotation built here from heading and pitch; its
/// pixel angle is no larger than any neighbouring rays' angle. The camera's frustum, what the
/// pager was given before, leaves most of the channel's rays outside.
#[test]
fn paged_display_channel_pages_for_its_own_rays() {
    let (cfg, dir) = left_channel("own-rays");
    let points = cfg.channel_points(0).unwrap();
    let eye = DVec3::from(cfg.eye.position);
    let rays = relief::app::paged::ChannelRays {
        bundle: points.ray_bundle(eye).unwrap(),
        offset: glam::DMat3::IDENTITY,
    };
    let path = mosaic();
    let (terrain, _, geo) = window(&path);
    let c = *script(&terrain).last().unwrap();
    let cam = gpu_camera(&terrain, c);
    // Display x, y, z are the camera's right, forward and up (roll 0).
    let (h, p) = (c.heading.to_radians(), c.pitch.to_radians());
    let forward = DVec3::new(h.sin() * p.cos(), h.cos() * p.cos(), p.sin());
    let right = DVec3::new(h.cos(), -h.sin(), 0.0);
    let up = right.cross(forward);
    let table = relief::cpu::distortion::ray_table(
        &points,
        eye,
        glam::DMat3::from_cols(right, forward, up),
    );
    let direction = |v: &View| {
        let (h, p) = (v.heading.to_radians(), v.pitch.to_radians());
        DVec3::new(h.sin() * p.cos(), h.cos() * p.cos(), p.sin())
    };
    let channel = relief::app::paged::view_of(&geo, &terrain, &cam, Some(&rays));
    let camera = relief::app::paged::view_of(&geo, &terrain, &cam, None);
    let [half, pixel] = channel.cone.expect("a channel's view is a cone");
    let camera_half = (30f64.to_radians().tan())
        .hypot(30f64.to_radians().tan() * 0.75)
        .atan();
    let (mut lit, mut outside_camera, mut widest, mut finest) = (0, 0, 0f64, f64::INFINITY);
    for (d, cone) in table.rays.iter().flatten() {
        lit += 1;
        widest = widest.max(d.angle_between(direction(&channel)));
        outside_camera += (d.angle_between(direction(&camera)) > camera_half) as usize;
        if *cone > 0.0 {
            finest = finest.min(2.0 * cone);
        }
    }
    eprintln!(
        "channel: {lit} rays; view heading {:.2}° pitch {:.2}°, cone {:.2}° (widest ray {:.2}°), pixel {:.5} (finest neighbours {:.5}); {outside_camera} rays outside the camera's frustum cone",
        channel.heading, channel.pitch, half.to_degrees(), widest.to_degrees(), pixel, finest
    );
    assert!(lit > 4000, "the channel lights the screen");
    assert!(widest <= half + 1e-9, "every ray in the channel's cone");
    assert!(
        pixel <= finest * (1.0 + 1e-9),
        "the pixel angle is the finest"
    );
    assert!(
        half.to_degrees() < 45.0,
        "a cone around the channel, not the sky"
    );
    assert!(
        outside_camera * 2 > lit,
        "the camera's frustum misses most of them"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The cylinder's left projector, 62° to the left of the camera's forward and 6° down,
/// 96x72, written to a temporary directory (returned for removal).
fn left_channel(name: &str) -> (relief::display::DisplayConfig, std::path::PathBuf) {
    channel_config(name, [0.0, -0.4, 0.9], -62.0, -6.0, 64.0)
}

/// A cylinder (radius 3 m around the eye) with one 96x72 projector at `position` (metres from
/// the eye), `heading` and `pitch` from the camera's forward (degrees), with a `fov`-degree
/// lens, written to a temporary directory (returned for removal).
fn channel_config(
    name: &str,
    position: [f64; 3],
    heading: f64,
    pitch: f64,
    fov: f64,
) -> (relief::display::DisplayConfig, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!(
        "relief-paged-channel-{name}-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("channel.toml");
    let text = format!(
        "[screen]\nkind = \"cylinder\"\ncentre = [0.0, 0.0, 0.0]\nradius = 3.0\nbottom = -1.2\n\
         top = 1.4\n[eye]\nposition = [0.0, 0.0, 0.0]\n[[channel]]\nname = \"left\"\n\
         [channel.projector]\nposition = {position:?}\nheading = {heading:?}\npitch = {pitch:?}\n\
         width = 96\nheight = 72\nlens = {{ kind = \"perspective\", fov = {fov:?}, shift = [0.0, 0.0] }}\n",
    );
    std::fs::write(&config, text).unwrap();
    (relief::display::DisplayConfig::load(&config).unwrap(), dir)
}

/// A display channel through the pool: a narrow projector at the eye (16°, so its pixels want
/// the finest tiles out to ~150 km) looking 130° left of the camera and 9° down, at terrain
/// ~10–60 km away, partly in another finest tile than the eye's (77 km wide), rendered from its distortion table over the hover;
/// the pager given the channel's own view (`app::paged::view_of` with its `ChannelRays`, as
/// `render --display` does). Against the same channel rendered from the in-memory window: equal
/// (hit masks, depth within 1e-5 relative, colour mean ≤ 1/255) within `CONVERGE_FRAMES`
/// frames, and staying equal. Paged for the camera's view instead (what the pager was given
/// before channels paged for their rays), the channel is still not equal at the end of the
/// hover: the comparison sees it.
#[test]
fn paged_gpu_display_channel_matches_full_residency() {
    let Some(gpu) = common::gpu() else { return };
    let _lock = common::gpu_lock();
    let own = channel_hover(gpu, true);
    eprintln!("channel paged for its rays: converged after {own:?} frames");
    let camera_only = channel_hover(gpu, false);
    eprintln!("channel paged for the camera: converged after {camera_only:?} frames");
    let at = own.expect("the channel never matched full residency");
    assert!(at <= CONVERGE_FRAMES, "converged after {at} frames");
    assert!(
        camera_only.is_none(),
        "paged for the camera's view alone, the channel matched too: the test cannot tell"
    );
}

/// The channel test's pool: 32 MB, 52 slots. (The 13 of the 8 MB pool go to the coarse
/// levels and the chain of tiles down to the eye's finest one, whatever the view.)
const CHANNEL_POOL: u64 = 32 << 20;

/// The hover rendered through the channel, paged for the channel's rays (`own`) or for
/// the camera's view: the frame at which it first equalled the full-residency channel (it
/// must stay equal), if it did.
fn channel_hover(gpu: &relief::gpu::Gpu, own: bool) -> Option<usize> {
    let path = mosaic();
    let (terrain, origin, geo) = window(&path);
    let store: Arc<dyn TileStore> = Arc::new(Store(Database::open(&path).unwrap()));
    let opts = PagerOptions {
        pool_bytes: CHANNEL_POOL,
        ..PagerOptions::default()
    };
    let (mut pager, first) = Pager::new(store, opts).unwrap();
    let (slots, _) = pager.slots();
    let pool =
        relief::gpu::terrain_pool::TerrainPool::new(gpu, pager.page_table(), 256, slots).unwrap();
    let mut paged_r = relief::gpu::TerrainRenderer::new_paged(gpu, &terrain, pool, origin).unwrap();
    let mut full_r = relief::gpu::TerrainRenderer::new(gpu, &terrain).unwrap();
    paged_r.apply_pages(gpu, &first, pager.page_table());
    let (cfg, dir) = channel_config(
        if own { "own" } else { "camera" },
        [0.0; 3],
        -130.0,
        -9.0,
        16.0,
    );
    let points = cfg.channel_points(0).unwrap();
    let eye = DVec3::from(cfg.eye.position);
    paged_r.set_display(gpu, &points, eye).unwrap();
    full_r.set_display(gpu, &points, eye).unwrap();
    let rays = relief::app::paged::ChannelRays {
        bundle: points.ray_bundle(eye).unwrap(),
        offset: glam::DMat3::IDENTITY,
    };
    // The hover's position, looking out (heading 20°, level).
    let c = Cam {
        pitch: 0.0,
        ..*script(&terrain).last().unwrap()
    };
    let cam = gpu_camera(&terrain, c);
    let view = relief::app::paged::view_of(&geo, &terrain, &cam, own.then_some(&rays));
    let scene =
        common::synthetic_scene(points.width, points.height, "position = [0.0, 0.0, 5000.0]");
    let full = full_r
        .capture(gpu, &terrain, &scene, &cam, &common::settings(true, false))
        .unwrap();
    let converged = Hover {
        gpu,
        terrain: &terrain,
        scene: &scene,
        cam: &cam,
        view: &view,
        pool: CHANNEL_POOL,
        label: if own {
            "channel (own rays)"
        } else {
            "channel (camera's view)"
        },
        min_terrain: 1000,
    }
    .until_equal(&mut pager, &mut paged_r, &full);
    let _ = std::fs::remove_dir_all(&dir);
    converged
}
