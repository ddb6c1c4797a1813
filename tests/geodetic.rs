//! Geodetic placement (`geodetic = [lat, lon, alt]` for free forms, voxel models and volumes)
//! and objects on the curved earth: where a geodetic object lands against the terrain's
//! geographic reference, the same picture as the metric placement, bad input through the CLI,
//! and objects lowered with the curved surface under them.

mod common;

use common::{gpu, gpu_lock, terrains};
use glam::DVec3;
use relief::geodesy::{self, Geodetic};
use relief::scene::Scene;
use relief::terrain::Terrain;
use relief::world::World;
use std::path::{Path, PathBuf};

/// Eye of the test scenes (world metres over N47E009: ~47.45 N, 9.37 E).
const EYE: [f64; 3] = [28000.0, 50000.0, 2500.0];

/// A scene over N47E009 (`.hgt`, 3″) with `extra` appended (objects) and `terrain_extra`
/// added to `[terrain]`.
fn scene_text(terrain_extra: &str, extra: &str) -> String {
    let hgt = terrains().join("N47E009.hgt");
    format!(
        "[terrain]\nsource = {hgt:?}\n{terrain_extra}\n[camera]\nposition = {EYE:?}\nheading = 90.0\npitch = -20.0\n\
         [fog]\nvisibility = 0.0\n[output]\nwidth = 160\nheight = 120\n{extra}"
    )
}

fn load(text: &str) -> relief::Result<World> {
    let scene = Scene::parse(text, &terrains().join("geodetic.toml"))?;
    World::load(&scene)
}

/// World position of `[lat, lon, alt]` from the terrain's geographic reference alone: grid
/// x, y from the longitude and latitude steps, times the metric spacing, from the origin.
fn metric(t: &Terrain, [lat, lon, alt]: [f64; 3]) -> DVec3 {
    let geo = t.field.geo.expect("georeferenced");
    let gx = (lon - geo.lon0) / geo.dlon;
    let gy = (lat - geo.lat0) / geo.dlat;
    let [sx, sy] = t.frame.spacing;
    t.frame.origin + DVec3::new(gx * sx, gy * sy, alt)
}

const TANK: [f64; 3] = [47.4567, 9.6123, 812.5];
const TREE: [f64; 3] = [47.3011, 9.2077, 640.0];
const CLOUD: [f64; 3] = [47.61, 9.45, 2100.0];

fn three_kinds(tank: &str, tree: &str, cloud: &str) -> String {
    let vox = terrains().join("voxels/tree.vox");
    format!(
        "[[objects]]\nname = \"tank\"\nshape = \"cylinder\"\nradius = 12.0\nheight = 15.0\n{tank}\n\
         [[voxels]]\nname = \"tree\"\nfile = {vox:?}\nvoxel_size = 0.1\nheading = 30.0\n{tree}\n\
         [[volumes]]\nname = \"cloud\"\nprocedural = {{ kind = \"clouds\", size = [32, 32, 8], seed = 3 }}\n\
         voxel_size = [50.0, 50.0, 50.0]\ntransfer = \"cloud\"\nheading = 15.0\n{cloud}\n"
    )
}

fn key(k: &str, v: [f64; 3]) -> String {
    format!("{k} = [{:?}, {:?}, {:?}]", v[0], v[1], v[2])
}

#[test]
fn geodetic_objects_land_where_the_georeference_puts_them() {
    let text = scene_text(
        "",
        &three_kinds(
            &key("geodetic", TANK),
            &key("geodetic", TREE),
            &key("geodetic", CLOUD),
        ),
    );
    let w = load(&text).expect("geodetic scene loads");
    let t = &w.terrain;
    for (what, got, lla) in [
        ("free form", w.objects[0].position, TANK),
        ("voxel model", w.voxels[0].position, TREE),
        ("volume", w.volumes[0].anchor(), CLOUD),
    ] {
        let want = metric(t, lla);
        assert!(
            (got - want).abs().max_element() < 1e-9,
            "{what}: {got} against {want} from the GeoRef"
        );
        // And back.
        let back = t.world_to_geodetic(got).unwrap();
        for k in 0..3 {
            assert!(
                (back[k] - lla[k]).abs() < 1e-9,
                "{what}: {back:?} vs {lla:?}"
            );
        }
    }
    // The metric scene with those positions is the same world, bit for bit.
    let m = |lla| {
        let p = metric(t, lla);
        key("position", [p.x, p.y, p.z])
    };
    let wm = load(&scene_text("", &three_kinds(&m(TANK), &m(TREE), &m(CLOUD)))).unwrap();
    assert_eq!(wm.objects[0].position, w.objects[0].position);
    assert_eq!(wm.voxels[0].position, w.voxels[0].position);
    assert_eq!(wm.volumes[0].corner, w.volumes[0].corner);
    // above_terrain applies to a geodetic position as to a metric one.
    let agl = scene_text(
        "",
        &three_kinds(
            &format!("{}\nabove_terrain = 0.0", key("geodetic", TANK)),
            &key("geodetic", TREE),
            &key("geodetic", CLOUD),
        ),
    );
    let wa = load(&agl).unwrap();
    let ground = wa.terrain.point_below(wa.objects[0].position).unwrap();
    assert!((wa.objects[0].position - ground).length() < 1e-9);
}

/// Renders `text` through the CLI into `dir/name`; the PNG and depth TIFF bytes (and checks
/// that free forms show).
fn render_cli(dir: &Path, name: &str, text: &str) -> (Vec<u8>, Vec<u8>) {
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(&scene, text).unwrap();
    let out = dir.join(name);
    let o = common::relief_cli(
        &[
            "render",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[("RUST_LOG", "off")],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let meta = common::read_json(&out.join("frame_0000.json"));
    let shown = meta["free_form_pixels"].as_u64().unwrap();
    assert!(shown > 100, "{name}: the tower covers {shown} pixels");
    (
        std::fs::read(out.join("frame_0000.png")).unwrap(),
        std::fs::read(out.join("depth_0000.tiff")).unwrap(),
    )
}

#[test]
fn gpu_geodetic_free_form_renders_as_the_metric_one() {
    if gpu().is_none() {
        return;
    }
    let _l = gpu_lock();
    let dir = common::temp_dir("geodetic-gpu");
    // A tower 2.5 km east of the eye, in view; on the flat and on the curved earth.
    let lla = [47.45, 9.4, 1200.0];
    let tower = |placement: &str| {
        format!(
            "[[objects]]\nname = \"tower\"\nshape = \"cylinder\"\nradius = 60.0\nheight = 400.0\n{placement}\n\
             material = {{ colour = [0.8, 0.2, 0.1] }}\n"
        )
    };
    for curved in ["curved = false", "curved = true"] {
        let t = load(&scene_text(curved, &tower(&key("geodetic", lla)))).unwrap();
        let p = metric(&t.terrain, lla);
        let (png_g, depth_g) = render_cli(
            &dir,
            "geodetic",
            &scene_text(curved, &tower(&key("geodetic", lla))),
        );
        let (png_m, depth_m) = render_cli(
            &dir,
            "metric",
            &scene_text(curved, &tower(&key("position", [p.x, p.y, p.z]))),
        );
        assert!(png_g == png_m, "{curved}: the PNGs differ");
        assert!(depth_g == depth_m, "{curved}: the depth TIFFs differ");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs `render` on `text`; asserts a one-line error naming `field` and `what`, exit 1,
/// nothing written.
fn refused(dir: &Path, name: &str, text: &str, field: &str, what: &str) {
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(&scene, text).unwrap();
    let out: PathBuf = dir.join(name);
    let o = common::relief_cli(
        &[
            "render",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[("RUST_LOG", "off")],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{name}: {err}");
    assert!(!err.contains("panicked"), "{name}: {err}");
    assert_eq!(err.trim().lines().count(), 1, "{name}: not one line: {err}");
    assert!(
        err.contains(field) && err.contains(what),
        "{name}: the error does not name {field:?} / {what:?}: {err}"
    );
    assert!(
        !out.join("frame_0000.png").exists(),
        "{name}: wrote a frame"
    );
}

#[test]
fn bad_geodetic_positions_are_one_line_errors_naming_the_field() {
    let dir = common::temp_dir("geodetic-bad");
    let obj = |placement: &str| {
        format!("[[objects]]\nname = \"mast\"\nshape = \"sphere\"\nradius = 5.0\n{placement}\n")
    };
    let f = "objects[0] (\"mast\")";
    let cases = [
        (
            "both",
            scene_text(
                "",
                &obj("geodetic = [47.5, 9.5, 600.0]\nposition = [1.0, 2.0, 3.0]"),
            ),
            format!("{f}.position/geodetic"),
            "both are set",
        ),
        (
            "neither",
            scene_text("", &obj("")),
            format!("{f}.position/geodetic"),
            "neither is set",
        ),
        (
            "nan",
            scene_text("", &obj("geodetic = [nan, 9.5, 600.0]")),
            format!("{f}.geodetic"),
            "is not a position",
        ),
        (
            "latitude-95",
            scene_text("", &obj("geodetic = [95.0, 9.5, 600.0]")),
            format!("{f}.geodetic"),
            "latitude (-90..90)",
        ),
        (
            "off-terrain",
            scene_text("", &obj("geodetic = [47.5, 10.5, 600.0]")),
            format!("{f}.geodetic"),
            "off the terrain, which covers latitude 47.000000..48.000000, longitude 9.000000..10.000000",
        ),
        (
            "voxel-off-terrain",
            scene_text(
                "",
                &format!(
                    "[[voxels]]\nname = \"deer\"\nfile = {:?}\ngeodetic = [46.9, 9.5, 600.0]\n",
                    terrains().join("voxels/deer.vox")
                ),
            ),
            "voxels[0] (deer).geodetic".to_string(),
            "off the terrain",
        ),
        (
            "volume-off-terrain",
            scene_text(
                "",
                "[[volumes]]\nname = \"puff\"\nprocedural = { kind = \"clouds\", size = [16, 16, 8] }\ntransfer = \"cloud\"\ngeodetic = [47.5, 8.5, 600.0]\n",
            ),
            "volume \"puff\": geodetic".to_string(),
            "off the terrain",
        ),
        (
            "no-georef",
            "[terrain.procedural]\nsize = 65\n[camera]\nposition = [10.0, 10.0, 3000.0]\n"
                .to_string()
                + &obj("geodetic = [47.5, 9.5, 600.0]"),
            format!("{f}.geodetic"),
            "needs a georeferenced terrain",
        ),
    ];
    for (name, text, field, what) in &cases {
        refused(&dir, name, text, field, what);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Height (m) of the WGS84 point `(lat, lon, h)` above the tangent plane of the ellipsoid at
/// the eye's foot: the exact drop, for comparison with the paraboloid.
fn exact_height_above_eye_plane(eye: [f64; 3], lat: f64, lon: f64, h: f64) -> f64 {
    let foot = Geodetic {
        lat: eye[0],
        lon: eye[1],
        height: 0.0,
    };
    geodesy::height_above_tangent_plane(
        foot,
        geodesy::to_ecef(Geodetic {
            lat,
            lon,
            height: h,
        }),
    )
}

#[test]
fn objects_on_the_curved_earth_rest_on_the_ground_20_km_away() {
    // The eye over the tile's west, the objects 20 km east of it, resting on the ground.
    let eye = DVec3::new(5000.0, 50000.0, 1500.0);
    let text = |curved: &str| {
        scene_text(
            curved,
            &three_kinds(
                &format!(
                    "{}\nabove_terrain = 0.0",
                    key("position", [25000.0, 50000.0, 0.0])
                ),
                &format!(
                    "{}\nabove_terrain = 0.0",
                    key("position", [25000.0, 50100.0, 0.0])
                ),
                &format!(
                    "{}\nabove_terrain = 0.0",
                    key("position", [25000.0, 51000.0, 0.0])
                ),
            ),
        )
    };
    let w = load(&text("curved = true")).unwrap();
    let t = &w.terrain;
    assert!(t.curved);
    let curv = t.curvature(eye);
    let eye_lla = t.world_to_geodetic(eye).unwrap();
    let ff = relief::cpu::freeform::lowered(t, eye, &w.objects);
    let vox = relief::cpu::voxel::lowered(t, eye, &w.voxels);
    let vol = relief::cpu::volume::lowered(t, eye, &w.volumes);
    for (what, placed, seen) in [
        ("free form", w.objects[0].position, ff[0].position),
        ("voxel model", w.voxels[0].position, vox[0].position),
        ("volume", w.volumes[0].anchor(), vol[0].anchor()),
    ] {
        let g = t.frame.world_to_grid(placed);
        let ground = t.height_at_grid(g.x, g.y).unwrap();
        let drop = curv.drop(g.x, g.y);
        // 20 km: the drop is ~31 m.
        assert!((29.0..34.0).contains(&drop), "{what}: drop {drop} m");
        // The base above the curved surface under it (the surface the traversal renders,
        // the height sample lowered by the drop): 0, where unlowered it floats by the drop.
        let above = seen.z - (ground - drop);
        assert!(
            above.abs() < 1e-6,
            "{what}: base {above} m above the curved ground"
        );
        assert!((placed.z - (ground - drop) - drop).abs() < 1e-6);
        // Against the exact ellipsoid: the ground point's height above the eye's tangent
        // plane (m above the ellipsoid there; heights as given).
        let [lat, lon, _] = t.world_to_geodetic(placed).unwrap();
        let exact = exact_height_above_eye_plane(eye_lla, lat, lon, ground);
        // Within 0.25 m: the grid's metric spacing is that of the tile's centre latitude
        // (0.1% off here, 0.06 m of drop), and the paraboloid drops the quartic term.
        assert!(
            (seen.z - exact).abs() < 0.25,
            "{what}: lowered base at {} m, the ellipsoid's ground {exact} m above the eye's plane",
            seen.z
        );
        // Horizontally, the offset from the eye is measured in the eye's metric: its east
        // component is the exact ellipsoid's (ECEF, the eye's east-north-up frame) within
        // the second-order term the grid does not model — a parallel `n` metres north of the
        // eye is shorter by `n tan φ / N` (3.4 m over 20 km for the volume 1 km north) —
        // and 0.5 m, where the window's centre-latitude spacing put it 19 m off (0.1%).
        // North, the grid's parallel bends away from the eye's east axis by the other
        // second-order term, `e² tan φ / 2N` (34 m at 20 km).
        let foot = Geodetic {
            lat: eye_lla[0],
            lon: eye_lla[1],
            height: 0.0,
        };
        let enu = geodesy::enu_basis(foot.lat, foot.lon).transpose()
            * (geodesy::to_ecef(Geodetic {
                lat,
                lon,
                height: 0.0,
            }) - geodesy::to_ecef(foot));
        let (east, north) = (seen.x - eye.x, seen.y - eye.y);
        let tan_over_n = foot.lat.to_radians().tan() / geodesy::prime_vertical_radius(foot.lat);
        let shorter = (enu.x * enu.y).abs() * tan_over_n;
        assert!(
            (east - enu.x).abs() <= 1.05 * shorter + 0.5,
            "{what}: {east} m east of the eye, the ellipsoid's {} m (placed {} m)",
            enu.x,
            placed.x - eye.x
        );
        let bend = 0.5 * enu.x * enu.x * tan_over_n;
        assert!(
            (north - enu.y).abs() <= 1.05 * bend + 0.5,
            "{what}: {north} m north of the eye, the ellipsoid's {} m, bend {bend} m",
            enu.y
        );
    }
    // Flat terrain (the .hgt default): nothing moves.
    let flat = load(&text("")).unwrap();
    assert!(!flat.terrain.curved);
    let ff = relief::cpu::freeform::lowered(&flat.terrain, eye, &flat.objects);
    assert_eq!(ff[0].position, flat.objects[0].position);
}

/// Pixels where the GPU frame shows free form 0, and where the CPU oracle does for `objects`.
fn masks(
    out: &relief::gpu::FrameOutput,
    cam: &relief::scene::Camera,
    objects: &[relief::freeform::FreeForm],
) -> (Vec<bool>, Vec<bool>, f64) {
    let mut worst = 0.0f64;
    let (mut gpu_mask, mut cpu_mask) = (Vec::new(), Vec::new());
    for k in 0..cam.width * cam.height {
        let d = cam.pixel_ray(k % cam.width, k / cam.width);
        let hit = relief::cpu::freeform::intersect(
            &objects[0],
            cam.pose.position,
            d,
            0.0,
            f64::INFINITY,
            relief::cpu::freeform::CPU_LEVELS,
        );
        let g = out.objects[k as usize] == 1;
        if let (true, Some(h)) = (g, hit) {
            worst = worst.max(((out.depth[k as usize] as f64 - h.t) / h.t).abs());
        }
        gpu_mask.push(g);
        cpu_mask.push(hit.is_some());
    }
    (gpu_mask, cpu_mask, worst)
}

fn differing(a: &[bool], b: &[bool]) -> usize {
    a.iter().zip(b).filter(|(x, y)| x != y).count()
}

#[test]
fn gpu_lowers_free_forms_with_the_curved_earth_every_frame() {
    let Some(g) = gpu() else { return };
    let _l = gpu_lock();
    // A balloon 600 m above the ground at x = 25 km, seen against the sky through a 5° lens
    // from 20 km and then from 10 km west of it: the drop (31 m, then 8 m) moves it down by
    // 2.8 and 1.4 pixel rows.
    let text = scene_text(
        "curved = true",
        "[[objects]]\nname = \"balloon\"\nshape = \"sphere\"\nradius = 300.0\n\
         position = [25000.0, 50000.0, 0.0]\nabove_terrain = 600.0\n",
    );
    let scene = Scene::parse(&text, &terrains().join("geodetic.toml")).unwrap();
    let w = World::load(&scene).unwrap();
    let mut r = relief::gpu::TerrainRenderer::new(g, &w.terrain).unwrap();
    r.set_objects(g, &w.objects).unwrap();
    let z = w.objects[0].position.z;
    for x in [5000.0, 15000.0] {
        let cam = relief::scene::Camera::new(
            relief::scene::Pose {
                position: DVec3::new(x, 50000.0, z),
                heading: 90.0,
                pitch: 0.0,
                roll: 0.0,
                fov: 5.0,
            },
            160,
            120,
        );
        let out = r
            .capture(
                g,
                &w.terrain,
                &scene.desc,
                &cam,
                &common::settings(false, true),
            )
            .unwrap();
        let lowered = relief::cpu::freeform::lowered(&w.terrain, cam.pose.position, &w.objects);
        let (gm, cm, worst) = masks(&out, &cam, &lowered);
        let (_, placed, _) = masks(&out, &cam, &w.objects);
        let covered = gm.iter().filter(|b| **b).count();
        let (off_lowered, off_placed) = (differing(&gm, &cm), differing(&gm, &placed));
        eprintln!(
            "eye x {x}: {covered} balloon pixels; against the lowered CPU oracle {off_lowered} differ \
             (depth within {worst:.1e}), against the balloon as placed {off_placed}"
        );
        assert!(covered > 1000, "{covered}");
        assert!(off_lowered <= covered / 100, "{off_lowered} of {covered}");
        assert!(off_placed > 5 * off_lowered.max(10), "{off_placed}");
        assert!(worst < 1e-4, "{worst}");
    }
}

#[test]
fn gpu_lowers_voxel_models_and_volumes_as_the_oracle_places_them() {
    let Some(g) = gpu() else { return };
    let _l = gpu_lock();
    // A voxel tree and a cloud in the air 20 km east of the eye, on the curved earth; the
    // same frame on the flat terrain with the models moved where `cpu::*::lowered` puts them
    // must cover the same pixels, and the models as placed must not.
    let vox = terrains().join("voxels/tree.vox");
    let text = scene_text(
        "curved = true",
        &format!(
            "[[voxels]]\nname = \"tree\"\nfile = {vox:?}\nvoxel_size = 6.0\n\
             position = [25000.0, 49800.0, 0.0]\nabove_terrain = 500.0\n\
             [[volumes]]\nname = \"cloud\"\nprocedural = {{ kind = \"clouds\", size = [32, 32, 8], seed = 3, coverage = 0.9 }}\n\
             transfer = \"cloud\"\nvoxel_size = [10.0, 10.0, 30.0]\nposition = [25000.0, 50250.0, 0.0]\nabove_terrain = 700.0\n"
        ),
    );
    let scene = Scene::parse(&text, &terrains().join("geodetic.toml")).unwrap();
    let w = World::load(&scene).unwrap();
    let cam = relief::scene::Camera::new(
        relief::scene::Pose {
            position: DVec3::new(5000.0, 50000.0, w.voxels[0].position.z + 200.0),
            heading: 90.0,
            pitch: 0.0,
            roll: 0.0,
            fov: 5.0,
        },
        160,
        120,
    );
    let eye = cam.pose.position;
    let mut flat = w.terrain.clone();
    flat.curved = false;
    let render = |terrain: &Terrain,
                  voxels: &[relief::voxel::VoxelInstance],
                  volumes: &[relief::volume::Volume]| {
        let mut r = relief::gpu::TerrainRenderer::new(g, terrain).unwrap();
        r.set_voxels(g, voxels).unwrap();
        r.set_volumes(g, volumes).unwrap();
        let out = r
            .capture(
                g,
                terrain,
                &scene.desc,
                &cam,
                &common::settings(false, true),
            )
            .unwrap();
        let vox: Vec<bool> = out.flags.iter().map(|f| f & 32 != 0).collect();
        let vol: Vec<bool> = out.volume_samples.iter().map(|s| *s > 0).collect();
        (vox, vol)
    };
    let curved = render(&w.terrain, &w.voxels, &w.volumes);
    let moved = render(
        &flat,
        &relief::cpu::voxel::lowered(&w.terrain, eye, &w.voxels),
        &relief::cpu::volume::lowered(&w.terrain, eye, &w.volumes),
    );
    let placed = render(&flat, &w.voxels, &w.volumes);
    let n = |m: &[bool]| m.iter().filter(|b| **b).count();
    eprintln!(
        "voxel pixels {} (moved {}, placed {}; {} / {} differ), volume pixels {} ({} / {} differ)",
        n(&curved.0),
        n(&moved.0),
        n(&placed.0),
        differing(&curved.0, &moved.0),
        differing(&curved.0, &placed.0),
        n(&curved.1),
        differing(&curved.1, &moved.1),
        differing(&curved.1, &placed.1)
    );
    assert!(n(&curved.0) > 300 && n(&curved.1) > 300);
    assert_eq!(differing(&curved.0, &moved.0), 0);
    assert_eq!(differing(&curved.1, &moved.1), 0);
    assert!(differing(&curved.0, &placed.0) > 50);
    assert!(differing(&curved.1, &placed.1) > 50);
}
