//! A paged database with a thin feature and an edge to its data: a 3″ tile (N47E009, 1201²
//! samples) of a flat field at 500 m with one spike (a single sample 3,140 m higher, at
//! 47.5N 9.5E) and a ridge along its west edge (its three westmost columns at 1,500 m),
//! compiled by `relief db build` and rendered through the GPU tile pool (`--terrain-memory`).
//! The window moves out to the tile corner south-west of the scene's, so the pool holds voids
//! (NaN: no source data) west and north of the data. Each frame, once resident, is checked
//! against the same scene rendered in memory (where the window ends at the data), or against
//! the paged reference of 16 rays a pixel. Real data too: ETOPO20 with its sea, and the Rocky
//! Mountain National Park DEM with its drape across tile edges.

mod common;

use std::path::{Path, PathBuf};

const SIDE: usize = 1201;

/// Writes the tile and compiles it: the database's path.
fn needle_database(dir: &Path) -> PathBuf {
    let mut bytes = Vec::with_capacity(SIDE * SIDE * 2);
    for row in 0..SIDE {
        for col in 0..SIDE {
            let h: i16 = match (row, col) {
                (600, 600) => 3640,
                (_, 0..=2) => 1500,
                _ => 500,
            };
            bytes.extend_from_slice(&h.to_be_bytes());
        }
    }
    let hgt = dir.join("N47E009.hgt");
    std::fs::write(&hgt, bytes).unwrap();
    common::db_build(dir.join("needle.reliefdb"), &hgt)
}

/// A frame as `render` wrote it: colour and frame JSON.
struct Frame {
    rgb: image::RgbImage,
    json: serde_json::Value,
}

/// The test's database and a scene over it with `camera` (TOML lines) at `size`.
struct Needle {
    dir: PathBuf,
    scene: PathBuf,
}

impl Needle {
    fn new(name: &str, camera: &str, size: [u32; 2]) -> Needle {
        let dir = common::temp_dir(name);
        let db = needle_database(&dir);
        let scene = format!(
            "[terrain]\ndatabase = {:?}\nwindow = [47.0, 9.0, 48.0, 10.0]\ncurved = true\n\
             [render]\nshadows = false\n[camera]\n{camera}fov = 40.0\n\
             [output]\nwidth = {}\nheight = {}\n",
            db.display().to_string(),
            size[0],
            size[1]
        );
        Needle::with_scene(dir, &scene)
    }

    /// A scene of TOML `scene` in `dir` (its database already there).
    fn with_scene(dir: PathBuf, scene: &str) -> Needle {
        let path = dir.join("scene.toml");
        std::fs::write(&path, scene).unwrap();
        Needle { dir, scene: path }
    }

    /// Renders the scene into `name` with `args`; `paged`: through an 16 MB pool, once the
    /// view is resident.
    fn render(&self, name: &str, paged: bool, args: &[&str]) -> Frame {
        let out = self.dir.join(name);
        let mut all = vec![
            "render",
            self.scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        if paged {
            all.extend(["--terrain-memory", "16", "--wait-resident"]);
        }
        all.extend_from_slice(args);
        let r = common::relief_cli(&all, &[]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let json = common::read_json(&out.join("frame_0000.json"));
        if paged {
            assert_eq!(json["paging"]["missing"], 0, "{}", json["paging"]);
        }
        let rgb = image::open(out.join("frame_0000.png")).unwrap().to_rgb8();
        Frame { rgb, json }
    }

    /// Renders the scene paged and in memory with `args` and asserts the two frames within a
    /// level (`assert_within` under `name`).
    fn assert_paged_as_in_memory(&self, name: &str, args: &[&str]) {
        let paged = self.render("paged", true, args);
        let memory = self.render("memory", false, args);
        assert_within(name, &paged.rgb, &memory.rgb, 1);
    }
}

/// The largest channel difference of pixel `k`.
fn difference(a: &image::RgbImage, b: &image::RgbImage, k: usize) -> u8 {
    let (a, b) = (&a.as_raw()[3 * k..3 * k + 3], &b.as_raw()[3 * k..3 * k + 3]);
    (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap()
}

/// Asserts no channel of two frames differs by more than `levels`, saving `-actual`,
/// `-expected` and `-diff` images under `name` if one does.
fn assert_within(name: &str, actual: &image::RgbImage, expected: &image::RgbImage, levels: u8) {
    let (w, h) = actual.dimensions();
    let differ: Vec<(u32, u32, u8)> = (0..(w * h) as usize)
        .filter_map(|k| {
            let d = difference(actual, expected, k);
            (d > levels).then_some((k as u32 % w, k as u32 / w, d))
        })
        .collect();
    if !differ.is_empty() {
        let rgba = |i: &image::RgbImage| image::DynamicImage::ImageRgb8(i.clone()).to_rgba8();
        let p = common::save_failure_images(name, w, h, &rgba(actual), &rgba(expected));
        panic!(
            "{name}: {} pixels differ by more than {levels} (first {:?}; {})",
            differ.len(),
            &differ[..differ.len().min(8)],
            p.display()
        );
    }
}

/// The tile pre-pass bounds every ray of a screen tile (or of an anti-aliasing atlas tile)
/// with the maxima around it. A paged traversal's top level has many cells, not one: the
/// bound there must be the window's highest sample, not the first top-level cell's maximum
/// (which once let tiles skip the spike's top-level cell, 12 pixels of the plain frame and
/// 30 of the reference). With and without the pre-pass the frames are the same bytes.
#[test]
fn the_paged_tile_prepass_skips_no_terrain() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let camera = "geodetic = [47.05, 9.3, 2500.0]\nheading = 0.0\npitch = 0.0\n";
    let t = Needle::new("paged-needle-tile", camera, [320, 180]);
    for aa in ["off", "reference"] {
        let with = t.render(&format!("{aa}-tile"), true, &["--antialias", aa]);
        let without = t.render(
            &format!("{aa}-no-tile"),
            true,
            &["--antialias", aa, "--no-tile-prepass"],
        );
        assert_within(
            &format!("paged-tile-prepass-{aa}"),
            &with.rgb,
            &without.rgb,
            0,
        );
    }
}

/// The paged frame equals the in-memory one where the data ends, the pool holding voids beyond
/// it (within a level: the two compute a one-sided difference in a different order, and
/// llvmpipe's GL rounds one pixel of the west view apart; on lavapipe they are the same bytes):
/// * seen towards the data's north edge on the curved earth (84 km away, at the horizon):
///   shading reads a sample of the level alone where it lies on one (a void beside it once
///   made the bilinear weight-0 term NaN: 10 black pixels at 640x360);
/// * seen from above the ridge along the data's west edge: a void beside the shaded cell
///   makes the difference across it one-sided, as the in-memory window's edge does (1,280
///   black pixels before);
/// * with the camera placed in metres instead of geodetically: the paged window, moved out to
///   the tile corner 15 km west and 4.4 km south of the scene's, keeps the scene window's
///   metres (it once put the camera 15 km west of where the in-memory frame has it).
#[test]
fn a_paged_frame_at_the_edge_of_the_data_equals_the_in_memory_one() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let views = [
        (
            "north",
            "geodetic = [47.2751, 9.5, 1756.0]\nheading = 0.0\npitch = 2.0\n",
            [640, 360],
        ),
        (
            "west",
            "geodetic = [47.5, 9.03, 2500.0]\nheading = 270.0\npitch = -20.0\n",
            [320, 180],
        ),
        (
            "metric",
            "position = [37600.0, 30600.0, 1756.0]\nheading = 0.0\npitch = 2.0\n",
            [320, 180],
        ),
    ];
    for (name, camera, size) in views {
        let t = Needle::new(&format!("paged-needle-{name}"), camera, size);
        t.assert_paged_as_in_memory(&format!("paged-edge-{name}"), &[]);
    }
}

/// The spike seen 25 km away, centred between two pixel columns: its upper part, thinner than
/// a pixel, is missed by every centre ray. Anti-aliasing's centre rays search their pixel
/// cones through the paged traversal as through the in-memory one: the paged frame flags as
/// many near misses as the in-memory frame, and with `"edges"` the spike's pixels come to the
/// paged reference (16 rays a pixel). Before the paged near-miss build, the paged frame
/// flagged none and left rows of the spike out.
#[test]
fn a_needle_no_centre_ray_hits_is_found_through_the_pixel_cone_on_a_paged_database() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let camera = "geodetic = [47.2751, 9.5, 1756.0]\nheading = 0.0\npitch = 2.0\n";
    let t = Needle::new("paged-needle-cone", camera, [160, 90]);
    let aa = |name: &str, paged: bool| t.render(name, paged, &["--antialias", name]);
    let (off, edges, reference) = (aa("off", true), aa("edges", true), aa("reference", true));
    let memory = t.render("memory-edges", false, &["--antialias", "edges"]);
    let near = |f: &Frame| f.json["antialias"]["near_misses"].as_u64().unwrap();
    let (mut pixels, mut off_err, mut edges_err) = (0, 0u64, 0u64);
    for k in 0..(160 * 90) {
        let column = k % 160;
        let e = difference(&off.rgb, &reference.rgb, k);
        if (76..84).contains(&column) && e >= 8 {
            pixels += 1;
            off_err += u64::from(e);
            edges_err += u64::from(difference(&edges.rgb, &reference.rgb, k));
        }
    }
    eprintln!(
        "paged needle: {pixels} pixels the centre rays miss, error sum {off_err} -> {edges_err}; near misses {} paged, {} in memory",
        near(&edges),
        near(&memory)
    );
    assert!(pixels >= 5, "the spike is there and missed by one ray");
    assert!(near(&edges) > 0, "near misses found");
    assert_eq!(near(&edges), near(&memory), "as many as in memory");
    assert!(edges_err * 4 <= off_err, "found through the pixel cone");
}

/// `[terrain]`'s sea level and vertical scale shape the paged terrain as they shape a loaded
/// window (the tiles go through them on their way to the pool; they once reached it raw):
/// * the needle database with `vertical_scale = 1.5` and `sea_level = 600` (the field at 500 m
///   raised to it), sun shadows on, a cylinder and a sphere placed in metres over the terrain,
///   `"edges"`: within a level of the in-memory frame (once the paged ground lay at 750 m
///   instead of 900 and the depth of every ground pixel differed by about a quarter);
/// * ETOPO20 over the Pacific with `sea_level = 0` (the curvature tests' sea): the paged sea
///   is the sea, not the sea floor 5 km below it (once 23.7 km away where it is 8.4 km).
#[test]
fn sea_level_and_vertical_scale_shape_the_paged_terrain() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let dir = common::temp_dir("paged-needle-mapping");
    let db = needle_database(&dir);
    let needle = Needle::with_scene(
        dir,
        &format!(
            "[terrain]\ndatabase = {:?}\nwindow = [47.0, 9.0, 48.0, 10.0]\ncurved = true\n\
             vertical_scale = 1.5\nsea_level = 600.0\n[sun]\nazimuth = 200.0\nelevation = 25.0\n\
             [camera]\nposition = [37600.0, 52000.0, 2600.0]\nheading = 0.0\npitch = -22.0\nfov = 50.0\n\
             [output]\nwidth = 320\nheight = 180\n\
             [[objects]]\nshape = \"cylinder\"\nradius = 40\nheight = 600\n\
             position = [37900.0, 54000.0, 0.0]\nabove_terrain = 0.0\n\
             [[objects]]\nshape = \"sphere\"\nradius = 120\nposition = [37000.0, 54500.0, 0.0]\n\
             above_terrain = 200.0\n",
            db.display().to_string()
        ),
    );
    needle.assert_paged_as_in_memory("paged-mapping-needle", &["--antialias", "edges"]);

    let dir = common::temp_dir("paged-mapping-pacific");
    let etopo = common::project_dir().join("tests/data/etopo20.tif");
    let db = common::db_build(dir.join("etopo.reliefdb"), &etopo);
    let pacific = Needle::with_scene(
        dir,
        &format!(
            "[terrain]\ndatabase = {:?}\nwindow = [20.0, -160.0, 40.0, -140.0]\ncurved = true\n\
             sea_level = 0.0\n[camera]\ngeodetic = [30.0, -150.0, 3000.0]\nheading = 45.0\n\
             pitch = -3.0\nfov = 60.0\n[output]\nwidth = 320\nheight = 180\n",
            db.display().to_string()
        ),
    );
    pacific.assert_paged_as_in_memory("paged-mapping-pacific", &[]);
}

/// A paged frame has no seams along tile edges: the normals' neighbourhood reads the tile beside
/// where it reaches across an edge, as the in-memory window reads its next samples. The Rocky
/// Mountain National Park DEM (`terrains/rmnp-dem.tif`, 1″) compiled and paged, with its drape
/// and `vertical_scale = 1.5` as `terrains/rmnp.toml`: within a level of the in-memory frame
/// (a one-sided difference at each tile edge once left a seam: 1,173 pixels more than a level
/// off, 133 of them by 8 to 15).
#[test]
fn a_paged_frame_has_no_seams_at_tile_edges() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let dir = common::temp_dir("paged-seams");
    let dem = common::terrains().join("rmnp-dem.tif");
    let db = common::db_build(dir.join("rmnp.reliefdb"), &dem);
    let drape = common::terrains().join("rmnp-rgb.tif");
    let rmnp = Needle::with_scene(
        dir,
        &format!(
            "[terrain]\ndatabase = {:?}\ndrape = {:?}\nvertical_scale = 1.5\ncurved = false\n\
             [sun]\nazimuth = 135.0\nelevation = 35.0\nintensity = 1.5\n\
             [camera]\nposition = [17000.0, -2000.0, 9000.0]\nheading = 5.0\npitch = -25.0\nfov = 60.0\n\
             [output]\nwidth = 320\nheight = 180\n",
            db.display().to_string(),
            drape.display().to_string()
        ),
    );
    rmnp.assert_paged_as_in_memory("paged-seams-rmnp", &[]);
}

/// A void inside the data (SRTM v2's holes: no source has data there) on a hill's top, seen
/// from 9 km: the paged frame equals the in-memory one, since the database holds the void
/// filled as the loaders fill the file. Before, the pool got the void (NaN) and a cell with a
/// void corner had no surface: the paged frame showed a pit where the hill's top is.
#[test]
fn a_void_inside_the_data_renders_paged_as_in_memory() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let dir = common::temp_dir("paged-void");
    let hgt = common::void_hgt(&dir);
    let db = common::db_build(dir.join("void.reliefdb"), &hgt);
    let scene = format!(
        "[terrain]\ndatabase = {:?}\nwindow = [47.0, 9.0, 48.0, 10.0]\ncurved = true\n\
         [camera]\ngeodetic = [47.42, 9.5, 2500.0]\nheading = 0.0\npitch = -10.0\nfov = 40.0\n\
         [output]\nwidth = 320\nheight = 180\n",
        db.display().to_string()
    );
    let t = Needle::with_scene(dir, &scene);
    t.assert_paged_as_in_memory("paged-void", &[]);
}
