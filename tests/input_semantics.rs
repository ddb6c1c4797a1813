//! Inputs that were accepted although wrong, or refused with a message naming no field
//! (issue 18): each is now refused naming the field and the fix, or does the right thing.
//! CLI cases run the binary and expect exit status 1 and one stderr line naming the field;
//! library cases call the library. Truths are computed here, independently of the code.

mod common;

use common::{
    gpu, gpu_lock, read_json, relief_cli, settings, synthetic_scene, temp_dir, terrain_from_fn,
};
use glam::{DVec3, DVec4};
use rayon::prelude::*;
use relief::cpu;
use relief::display::DisplayConfig;
use relief::gpu::TerrainRenderer;
use relief::scene::{Camera, Pose, Scene};
use relief::terrain::{geotiff, hgt, Terrain};
use std::path::{Path, PathBuf};
use std::process::Output;
use tiff::encoder::{colortype, TiffEncoder};
use tiff::tags::Tag;

fn relief(args: &[&str]) -> Output {
    relief_cli(args, &[("RUST_LOG", "warn")])
}

/// Asserts exit status 1 and exactly one stderr line that mentions every needle.
fn assert_one_line_error(what: &str, o: &Output, needles: &[&str]) -> String {
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert_eq!(
        o.status.code(),
        Some(1),
        "{what}: expected exit status 1\nstdout: {out}\nstderr: {err}"
    );
    let lines: Vec<_> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(
        lines.len(),
        1,
        "{what}: expected one stderr line, got {err}"
    );
    for n in needles {
        assert!(
            lines[0].contains(n),
            "{what}: stderr should mention `{n}`: {err}"
        );
    }
    lines[0].to_string()
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// A small procedural scene (65² samples, 30 m) with extra `[camera]` / `[terrain]` lines.
fn procedural_scene(dir: &Path, terrain_extra: &str, camera: &str, rest: &str) -> PathBuf {
    let p = dir.join("scene.toml");
    std::fs::write(
        &p,
        format!(
            "[terrain]\n{terrain_extra}\n[terrain.procedural]\nsize = 65\nheight = 1000.0\n\
             [camera]\n{camera}\n[output]\nwidth = 32\nheight = 24\n{rest}"
        ),
    )
    .unwrap();
    p
}

// ---------------------------------------------------------------------------------------------
// 1. --first near u32::MAX

#[test]
fn render_first_frame_past_u32_is_refused_naming_first() {
    let dir = temp_dir("first");
    let scene = procedural_scene(&dir, "", "position = [900.0, 900.0, 3000.0]", "");
    let out = dir.join("out");
    // Frames 4294967295 and 4294967296: the second does not exist.
    let o = relief(&[
        "render",
        &s(&scene),
        "--first",
        "4294967295",
        "--frames",
        "2",
        "--out",
        &s(&out),
    ]);
    assert_one_line_error("--first overflow", &o, &["--first", "4294967295"]);
    assert!(!out.exists(), "nothing may be written");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_of_the_last_frame_number_writes_that_frame() {
    let _l = gpu_lock();
    if gpu().is_none() {
        return;
    }
    let dir = temp_dir("first-last");
    let scene = procedural_scene(
        &dir,
        "",
        "position = [900.0, 900.0, 3000.0]\npitch = -60.0",
        "",
    );
    let out = dir.join("out");
    let o = relief(&[
        "render",
        &s(&scene),
        "--first",
        &u32::MAX.to_string(),
        "--frames",
        "1",
        "--out",
        &s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "frame_4294967295.png",
        "depth_4294967295.tiff",
        "frame_4294967295.json",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 2. Lenses whose radial distortion folds over inside the image

fn fisheye_config(dir: &Path, k1: f64) -> PathBuf {
    let p = dir.join(format!("fisheye{k1}.toml"));
    std::fs::write(
        &p,
        format!(
            "[screen]\nkind = \"dome\"\ncentre = [0.0, 0.0, 0.0]\nradius = 3.0\nmin_elevation = -20.0\n\
             [eye]\nposition = [0.0, 0.0, 0.0]\n[[channel]]\nname = \"fisheye\"\n[channel.projector]\n\
             position = [0.0, 0.0, 0.0]\npitch = 20.0\nwidth = 256\nheight = 256\n\
             lens = {{ kind = \"ftheta\", fov = 180.0 }}\ndistortion = {{ k1 = {k1:?} }}\n"
        ),
    )
    .unwrap();
    p
}

#[test]
fn a_lens_that_folds_over_inside_the_image_is_refused() {
    let dir = temp_dir("lens");
    // g(r) = r (1 + k1 r²) has g'(r) = 1 + 3 k1 r², zero at r = 1/sqrt(-3 k1). The f-theta
    // lens's field is the unit circle (normalised by the fisheye radius): the model folds over
    // inside the field when that radius is below 1, i.e. for k1 < -1/3.
    let threshold: f64 = -1.0 / 3.0;
    for (k1, folds) in [
        (-5.0, true),
        (threshold * 1.1, true),
        (threshold * 0.9, false),
        (-0.04, false),
    ] {
        let fold_radius = 1.0 / (-3.0 * k1).sqrt();
        assert_eq!(fold_radius < 1.0, folds, "k1 = {k1}: the truth is wrong");
        let r = DisplayConfig::load(&fisheye_config(&dir, k1));
        if folds {
            let e = r
                .expect_err(&format!("k1 = {k1} folds at r = {fold_radius}"))
                .to_string();
            assert!(
                e.contains("channel[0].projector.distortion") && e.contains("folds"),
                "k1 = {k1}: {e}"
            );
        } else {
            r.unwrap_or_else(|e| panic!("k1 = {k1} does not fold inside the field: {e}"));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 3. Line of sight with end points underground

/// 65² samples, 10 m: a 100 m plateau with a 20 m bump in the middle.
fn plateau() -> Terrain {
    terrain_from_fn(65, 10.0, |x, y| {
        let d = ((x - 320.0).powi(2) + (y - 320.0).powi(2)).sqrt();
        100.0 + if d < 100.0 { 20.0 } else { 0.0 }
    })
}

#[test]
fn line_of_sight_between_underground_points_is_blocked() {
    let t = plateau();
    // Ground is at 100 m away from the bump, 120 m on it; the lowest sample is 100 m.
    let cases = [
        // Both end points below the lowest sample, over the grid.
        (
            DVec3::new(50.0, 50.0, 20.0),
            DVec3::new(550.0, 80.0, 30.0),
            false,
        ),
        // Below the surface but above the lowest sample (under the bump).
        (
            DVec3::new(300.0, 320.0, 110.0),
            DVec3::new(340.0, 320.0, 110.0),
            false,
        ),
        // One end underground, the other in the air.
        (
            DVec3::new(100.0, 100.0, 50.0),
            DVec3::new(100.0, 100.0, 500.0),
            false,
        ),
        // Passing under the grid from outside to outside, below the ground.
        (
            DVec3::new(-50.0, 200.0, 50.0),
            DVec3::new(700.0, 200.0, 50.0),
            false,
        ),
        // In the air over the grid, and in the air across the bump's top.
        (
            DVec3::new(50.0, 50.0, 150.0),
            DVec3::new(550.0, 80.0, 150.0),
            true,
        ),
        (
            DVec3::new(100.0, 320.0, 130.0),
            DVec3::new(540.0, 320.0, 130.0),
            true,
        ),
        // Across the bump below its top: blocked by crossing it.
        (
            DVec3::new(100.0, 320.0, 110.0),
            DVec3::new(540.0, 320.0, 110.0),
            false,
        ),
        // Outside the grid altogether, low down: nothing to block.
        (
            DVec3::new(-500.0, -500.0, 0.0),
            DVec3::new(-100.0, -500.0, 0.0),
            true,
        ),
        // From a ground point up into the air.
        (
            DVec3::new(150.0, 150.0, 100.0),
            DVec3::new(150.0, 150.0, 900.0),
            true,
        ),
    ];
    for walls in [true, false] {
        let mut t = t.clone();
        t.walls = walls;
        for (k, (a, b, clear)) in cases.iter().enumerate() {
            assert_eq!(
                cpu::line_of_sight(&t, *a, *b),
                *clear,
                "case {k} (walls {walls}): {a} -> {b}"
            );
            assert_eq!(
                cpu::line_of_sight(&t, *b, *a),
                *clear,
                "case {k} reversed (walls {walls})"
            );
        }
    }
}

#[test]
fn cli_query_los_says_blocked_and_why_for_underground_points() {
    let dir = temp_dir("los");
    let scene = procedural_scene(&dir, "", "position = [900.0, 900.0, 3000.0]", "");
    // Ridged fBm heights are sum · height / 2 with sum ≥ 0: nothing is below 0 m.
    let o = relief(&[
        "query",
        &s(&scene),
        "--los",
        "300,300,-500",
        "1500,1200,-400",
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        out.contains("blocked") && out.contains("below the terrain surface"),
        "{out}"
    );
    let o = relief(&[
        "query",
        &s(&scene),
        "--los",
        "300,300,5000",
        "1500,1200,5000",
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("clear") && !out.contains("below"), "{out}");
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 4. camera.above_terrain outside the grid

#[test]
fn above_terrain_outside_the_grid_is_refused_naming_it() {
    let dir = temp_dir("agl");
    // The grid spans 0..1920 m (64 cells of 30 m) in x and y.
    let scene = procedural_scene(
        &dir,
        "",
        "position = [5000.0, 900.0, 0.0]\nabove_terrain = 50.0",
        "",
    );
    let o = relief(&["query", &s(&scene), "--at", "100,100"]);
    assert_one_line_error(
        "above_terrain off the grid",
        &o,
        &["camera.above_terrain", "5000", "1920"],
    );
    // Over the grid it sets the height: camera z = ground + 50.
    let scene = procedural_scene(
        &dir,
        "",
        "position = [700.0, 900.0, 0.0]\nabove_terrain = 50.0",
        "",
    );
    let sc = Scene::load(&scene).unwrap();
    let terrain = sc.load_terrain().unwrap();
    let cam = sc.camera(0, &terrain);
    let g = terrain.frame.world_to_grid(DVec3::new(700.0, 900.0, 0.0));
    let (i, j) = (g.x.floor() as usize, g.y.floor() as usize);
    let (u, v) = (g.x - i as f64, g.y - j as f64);
    let h = |i, j| terrain.field.at(i, j) as f64;
    let ground = h(i, j) * (1.0 - u) * (1.0 - v)
        + h(i + 1, j) * u * (1.0 - v)
        + h(i, j + 1) * (1.0 - u) * v
        + h(i + 1, j + 1) * u * v;
    assert!((cam.pose.position.z - (ground + 50.0)).abs() < 1e-6);
    // With a camera path it would be ignored: refused instead.
    let text = std::fs::read_to_string(&scene).unwrap()
        + "[path]\nkeyframes = [ { time = 0.0, position = [700.0, 900.0, 3000.0] } ]\n";
    let e = Scene::parse(&text, Path::new("agl.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("camera.above_terrain") && e.contains("[path]"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 5. Non-finite heights name the field

#[test]
fn overflowing_png_scale_and_procedural_height_are_refused_naming_the_field() {
    let dir = temp_dir("finite");
    let png = dir.join("h.png");
    let px: Vec<u16> = (0..16 * 16).map(|k| (k * 200) as u16).collect();
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(16, 16, px)
        .unwrap()
        .save(&png)
        .unwrap();
    let scene = dir.join("png.toml");
    std::fs::write(
        &scene,
        "[terrain]\nsource = \"h.png\"\ncell_size = [10.0, 10.0]\npng_scale = 1e38\n\
         [camera]\nposition = [50.0, 50.0, 1000.0]\n",
    )
    .unwrap();
    let o = relief(&["query", &s(&scene), "--at", "20,20"]);
    assert_one_line_error("png_scale 1e38", &o, &["terrain.png_scale", "h.png"]);
    // The same file at a sane scale loads.
    std::fs::write(
        &scene,
        "[terrain]\nsource = \"h.png\"\ncell_size = [10.0, 10.0]\npng_scale = 0.1\n\
         [camera]\nposition = [50.0, 50.0, 1000.0]\n",
    )
    .unwrap();
    let o = relief(&["query", &s(&scene), "--at", "20,20"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let p = dir.join("proc.toml");
    std::fs::write(
        &p,
        "[terrain.procedural]\nsize = 17\nheight = 1e300\n[camera]\nposition = [50.0, 50.0, 1000.0]\n",
    )
    .unwrap();
    let o = relief(&["query", &s(&p), "--at", "20,20"]);
    assert_one_line_error(
        "procedural height 1e300",
        &o,
        &["terrain.procedural.height"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 6, 9. GeoTIFF pixel scale and raster type

/// A 4x3 f32 GeoTIFF with the given pixel scale, tiepoint and GeoKeys.
fn write_geotiff(path: &Path, scale: [f64; 3], tie: [f64; 6], geokeys: &[u16]) {
    let file = std::fs::File::create(path).unwrap();
    let mut enc = TiffEncoder::new(std::io::BufWriter::new(file)).unwrap();
    let mut img = enc.new_image::<colortype::Gray32Float>(4, 3).unwrap();
    let e = img.encoder();
    e.write_tag(Tag::ModelPixelScaleTag, &scale[..]).unwrap();
    e.write_tag(Tag::ModelTiepointTag, &tie[..]).unwrap();
    e.write_tag(Tag::GeoKeyDirectoryTag, geokeys).unwrap();
    let data: Vec<f32> = (0..12).map(|k| 1000.0 + k as f32).collect();
    img.write_data(&data).unwrap();
}

/// GeoKey directory: geographic model (1024 = 2) and the raster type (1025).
fn geokeys(raster_type: u16) -> Vec<u16> {
    vec![1, 1, 0, 2, 1024, 0, 1, 2, 1025, 0, 1, raster_type]
}

#[test]
fn zero_or_negative_geotiff_pixel_scale_is_named_as_such() {
    let dir = temp_dir("scale");
    for (name, scale) in [
        ("zero.tif", [0.0, 0.001, 0.0]),
        ("negative.tif", [0.001, -0.001, 0.0]),
    ] {
        let p = dir.join(name);
        write_geotiff(&p, scale, [0.0, 0.0, 0.0, 9.0, 47.0, 0.0], &geokeys(1));
        let e = geotiff::load_heights(&p, None, None)
            .expect_err(name)
            .to_string();
        assert!(
            e.contains(name) && e.contains("pixel scale") && e.contains("ModelPixelScale"),
            "{name}: {e}"
        );
        assert!(!e.contains("no GeoTIFF"), "{name}: {e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn geotiff_pixel_is_point_and_pixel_is_area_place_samples_half_a_cell_apart() {
    let dir = temp_dir("raster-type");
    let (sx, sy) = (0.002, 0.001);
    // Tiepoint: raster (1, 2) -> lon 9.1, lat 47.2.
    let tie = [1.0, 2.0, 0.0, 9.1, 47.2, 0.0];
    let (area, point) = (dir.join("area.tif"), dir.join("point.tif"));
    write_geotiff(&area, [sx, sy, 0.0], tie, &geokeys(1));
    write_geotiff(&point, [sx, sy, 0.0], tie, &geokeys(2));
    let ga = geotiff::load_heights(&area, None, None)
        .unwrap()
        .geo
        .unwrap();
    let gp = geotiff::load_heights(&point, None, None)
        .unwrap()
        .geo
        .unwrap();
    // GeoTIFF 1.1, 2.5.2.2: PixelIsArea, raster point (I, J) is the top-left corner of pixel
    // (I, J), so the sample (centre) of pixel (i, j) is at raster (i + 0.5, j + 0.5);
    // PixelIsPoint, the sample of pixel (i, j) is raster (i, j). The grid's sample (0, 0) is
    // the south-west one: pixel (0, 2) of the 4x3 raster (rows north to south).
    let model = |ri: f64, rj: f64| (9.1 + (ri - 1.0) * sx, 47.2 - (rj - 2.0) * sy);
    let (lon_a, lat_a) = model(0.5, 2.5);
    let (lon_p, lat_p) = model(0.0, 2.0);
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
    assert!(
        close(ga.lon0, lon_a) && close(ga.lat0, lat_a),
        "area {ga:?}"
    );
    assert!(
        close(gp.lon0, lon_p) && close(gp.lat0, lat_p),
        "point {gp:?}"
    );
    assert!(close(ga.lon0 - gp.lon0, 0.5 * sx) && close(ga.lat0 - gp.lat0, -0.5 * sy));
    // A drape image is placed by the same rule.
    for (rt, lon, lat) in [(1u16, lon_a, lat_a), (2, lon_p, lat_p)] {
        let p = dir.join(format!("drape{rt}.tif"));
        {
            let file = std::fs::File::create(&p).unwrap();
            let mut enc = TiffEncoder::new(std::io::BufWriter::new(file)).unwrap();
            let mut img = enc.new_image::<colortype::RGB8>(4, 3).unwrap();
            let e = img.encoder();
            e.write_tag(Tag::ModelPixelScaleTag, &[sx, sy, 0.0][..])
                .unwrap();
            e.write_tag(Tag::ModelTiepointTag, &tie[..]).unwrap();
            e.write_tag(Tag::GeoKeyDirectoryTag, &geokeys(rt)[..])
                .unwrap();
            img.write_data(&[128u8; 36]).unwrap();
        }
        let g = geotiff::load_drape(&p).unwrap().geo.unwrap();
        assert!(
            close(g.lon0, lon) && close(g.lat0, lat),
            "drape, raster type {rt}: {g:?}"
        );
    }
    // No raster type key means PixelIsArea.
    let none = dir.join("none.tif");
    write_geotiff(&none, [sx, sy, 0.0], tie, &[1, 1, 0, 1, 1024, 0, 1, 2]);
    let gn = geotiff::load_heights(&none, None, None)
        .unwrap()
        .geo
        .unwrap();
    assert!(
        close(gn.lon0, lon_a) && close(gn.lat0, lat_a),
        "default {gn:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 7. Impossible .hgt tile names

#[test]
fn hgt_names_beyond_the_poles_or_the_antimeridian_are_refused_naming_the_file() {
    let dir = temp_dir("hgt");
    let bytes = vec![0u8; 1201 * 1201 * 2];
    for (name, what) in [
        ("N99E009.hgt", "latitude"),
        ("S91E009.hgt", "latitude"),
        ("N90E009.hgt", "latitude"),
        ("N47E181.hgt", "longitude"),
        ("N47W181.hgt", "longitude"),
    ] {
        let p = dir.join(name);
        std::fs::write(&p, &bytes).unwrap();
        let e = hgt::load(&p).expect_err(name).to_string();
        let stem = name.trim_end_matches(".hgt");
        assert!(e.contains(stem) && e.contains(what), "{name}: {e}");
        assert!(!e.contains("spacing"), "{name}: {e}");
        std::fs::remove_file(&p).unwrap();
    }
    // The extreme possible tiles load, with their corner from the name.
    for (name, lat, lon) in [("S90W180.hgt", -90.0, -180.0), ("N89E179.hgt", 89.0, 179.0)] {
        let p = dir.join(name);
        std::fs::write(&p, &bytes).unwrap();
        let g = hgt::load(&p).unwrap().geo.unwrap();
        assert_eq!((g.lat0, g.lon0), (lat, lon), "{name}");
        std::fs::remove_file(&p).unwrap();
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 8. world_from_grid in the frame JSON includes the vertical scale

const W: usize = 9;
const H: usize = 7;

fn file_height(i: usize, j_north: usize) -> f32 {
    // Row 0 of the file is the northern one.
    300.0 + 17.0 * i as f32 - 11.0 * j_north as f32 + ((i * j_north) % 5) as f32 * 3.5
}

/// A scene over a 9x7 f32 TIFF (no georeference, 25 m cells) at vertical scale 3.
fn vertical_scale_scene(dir: &Path) -> PathBuf {
    let tif = dir.join("h.tif");
    let file = std::fs::File::create(&tif).unwrap();
    let mut enc = TiffEncoder::new(std::io::BufWriter::new(file)).unwrap();
    let data: Vec<f32> = (0..W * H).map(|k| file_height(k % W, k / W)).collect();
    enc.write_image::<colortype::Gray32Float>(W as u32, H as u32, &data)
        .unwrap();
    let p = dir.join("vs.toml");
    std::fs::write(
        &p,
        "[terrain]\nsource = \"h.tif\"\ncell_size = [25.0, 25.0]\nvertical_scale = 3.0\n\
         origin = [1000.0, 2000.0, -40.0]\n[camera]\nposition = [1100.0, 2075.0, 5000.0]\n\
         pitch = -89.0\nfov = 40.0\n[output]\nwidth = 32\nheight = 24\n",
    )
    .unwrap();
    p
}

/// Rebuilds every sample from the file's heights through `m` (rows) and checks it against
/// the CPU oracle's surface.
fn check_rebuild(terrain: &Terrain, m: &[[f64; 4]; 4]) {
    for j_north in 0..H {
        for i in 0..W {
            let g = DVec4::new(
                i as f64,
                (H - 1 - j_north) as f64,
                file_height(i, j_north) as f64,
                1.0,
            );
            let w: Vec<f64> = m.iter().map(|r| DVec4::from(*r).dot(g)).collect();
            let p = DVec3::new(w[0], w[1], w[2]);
            let ground = cpu::terrain_point_below(terrain, p)
                .unwrap_or_else(|| panic!("sample ({i}, {j_north}) rebuilt off the grid at {p}"));
            assert!(
                (ground - p).length() < 1e-3,
                "sample ({i}, {j_north}): rebuilt {p}, CPU surface {ground}"
            );
        }
    }
}

#[test]
fn world_from_grid_rebuilds_the_surface_from_the_files_heights_at_vertical_scale_3() {
    let dir = temp_dir("vscale");
    let scene = Scene::load(&vertical_scale_scene(&dir)).unwrap();
    let terrain = scene.load_terrain().unwrap();
    let m = relief::app::capture::world_from_file_grid(&scene, &terrain)
        .transpose()
        .to_cols_array_2d();
    check_rebuild(&terrain, &m);
    // The frame JSON carries that matrix.
    let _l = gpu_lock();
    if gpu().is_some() {
        let out = dir.join("out");
        let o = relief(&["render", &s(&dir.join("vs.toml")), "--out", &s(&out)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let meta = read_json(&out.join("frame_0000.json"));
        let rows = &meta["terrain"]["world_from_grid"];
        let mut mj = [[0.0; 4]; 4];
        for (r, row) in mj.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = rows[r][c].as_f64().unwrap();
            }
        }
        check_rebuild(&terrain, &mj);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 10. terrain.walls

/// 65² samples, 10 m: a 100 m plateau up to x = 300 m, down to 0 by x = 310 m, flat 0 m to
/// x = 500 m, a 200 m ridge from x = 510 m on.
fn step_terrain(walls: bool) -> Terrain {
    let mut t = terrain_from_fn(65, 10.0, |x, _| {
        if x <= 300.0 {
            100.0
        } else if x < 505.0 {
            0.0
        } else {
            200.0
        }
    });
    t.walls = walls;
    t
}

#[test]
fn without_walls_rays_pass_under_the_surface_on_the_cpu() {
    let hit =
        |t: &Terrain, o: DVec3, d: DVec3| cpu::cast_ray(t, o, d, 0.0, f64::INFINITY).map(|h| h.t);
    let (on, off) = (step_terrain(true), step_terrain(false));
    assert!(on.walls, "walls are on by default");
    let close = |a: Option<f64>, b: f64| a.is_some_and(|a| (a - b).abs() < 1e-6);
    // Level ray at 50 m from the west: the wall at x = 0 (t = 100); without walls it passes
    // under the plateau, comes out where the bilinear slope 300..310 m is at 50 m (x = 305)
    // and meets the ridge's face 500..510 m at 50 m (x = 502.5) from above: t = 602.5.
    let o = DVec3::new(-100.0, 320.0, 50.0);
    assert!(
        close(hit(&on, o, DVec3::X), 100.0),
        "{:?}",
        hit(&on, o, DVec3::X)
    );
    assert!(
        close(hit(&off, o, DVec3::X), 602.5),
        "{:?}",
        hit(&off, o, DVec3::X)
    );
    // Dipping ray: the wall at x = 0; without walls it leaves the box below 0 m (x = 150 m,
    // still under the plateau): sky.
    let d = DVec3::new(1.0, 0.0, -0.2).normalize();
    assert!(close(hit(&on, o, d), 100.0 / d.x), "{:?}", hit(&on, o, d));
    assert_eq!(hit(&off, o, d), None);
    // Up from below the low ground: the floor with walls, nothing without.
    let below = DVec3::new(400.0, 320.0, -100.0);
    assert!(hit(&on, below, DVec3::Z).is_some_and(|t| (t - 100.0).abs() < 1e-3));
    assert_eq!(hit(&off, below, DVec3::Z), None);
    // From a camera underground (z = 95 under the plateau at x = 100) looking east: with
    // walls the ground at once (t = 0); without, it comes out of the slope at x = 300.5 and
    // hits the ridge's face at x = 504.75.
    let o = DVec3::new(100.0, 320.0, 95.0);
    assert!(close(hit(&on, o, DVec3::X), 0.0));
    assert!(
        close(hit(&off, o, DVec3::X), 404.75),
        "{:?}",
        hit(&off, o, DVec3::X)
    );
    // Rays from above do not change.
    let top = DVec3::new(400.0, 320.0, 1000.0);
    for t in [&on, &off] {
        assert!(close(hit(t, top, -DVec3::Z), 1000.0));
    }
}

#[test]
fn without_walls_the_gpu_agrees_with_the_cpu() {
    let _l = gpu_lock();
    let Some(g) = gpu() else {
        return;
    };
    let desc = synthetic_scene(160, 120, "position = [0.0, 0.0, 0.0]");
    let cam = Camera::new(
        Pose {
            position: DVec3::new(-250.0, 330.0, 60.0),
            heading: 90.0,
            pitch: -4.0,
            roll: 0.0,
            fov: 70.0,
        },
        160,
        120,
    );
    let settings = settings(false, true);
    let cpu_depth = |t: &Terrain| -> Vec<Option<f64>> {
        (0..160 * 120)
            .into_par_iter()
            .map(|k| {
                cpu::cast_ray(
                    t,
                    cam.pose.position,
                    cam.pixel_ray(k % 160, k / 160),
                    0.0,
                    f64::INFINITY,
                )
                .map(|h| h.t)
            })
            .collect()
    };
    let mut cpu_of = Vec::new();
    for walls in [true, false] {
        let terrain = step_terrain(walls);
        let mut r = TerrainRenderer::new(g, &terrain).expect("renderer");
        let out = r
            .capture(g, &terrain, &desc, &cam, &settings)
            .expect("capture");
        let c = cpu_depth(&terrain);
        let bad = c
            .iter()
            .zip(&out.depth)
            .filter(|(c, g)| match (c, g.is_finite()) {
                (Some(c), true) => ((**g as f64 - c) / c).abs() > 1e-3,
                (None, false) => false,
                _ => true,
            })
            .count();
        eprintln!(
            "walls {walls}: {} terrain pixels on the CPU, {bad} disagree on the GPU",
            c.iter().flatten().count()
        );
        assert!(
            bad <= 160 * 120 / 200,
            "walls {walls}: {bad} of {} pixels disagree with the CPU",
            160 * 120
        );
        cpu_of.push(c);
    }
    // The switch matters in this view: many pixels see the wall with walls and not without.
    let changed = cpu_of[0]
        .iter()
        .zip(&cpu_of[1])
        .filter(|(a, b)| match (a, b) {
            (Some(a), Some(b)) => (a - b).abs() > 1.0,
            (None, None) => false,
            _ => true,
        })
        .count();
    assert!(
        changed > 160 * 120 / 10,
        "only {changed} pixels change without walls"
    );
}
