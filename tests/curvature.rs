//! The curved WGS84 earth (issue 20): horizon dip and the elevation of a distant summit as the
//! CPU oracle and the GPU render them, against truth computed here from scratch (ECEF from
//! geodetic with the WGS84 constants, straight rays in ECEF, the exact ray–ellipsoid
//! quadratic), not through `relief::geodesy`.
//!
//! * sea-horizon dip from 1, 5 and 10 km over the Pacific (ETOPO20, `sea_level = 0`), four
//!   azimuths each: within 0.5 arc-minute of the ellipsoid's tangent elevation;
//! * Elbrus (N43E042 over ETOPO20) from 150 km north: the silhouette's elevation within 0.5
//!   arc-minute of the DEM's summit sample seen from the eye; the flat earth misses by > 5′;
//! * the GPU's hit/miss elevation through one-pixel renders within 0.5′ of the CPU's, and a
//!   hit's depth within 1e-4 relative;
//! * a 160x120 curved view on the GPU against the CPU oracle: depth and shadows.

mod common;

use common::{project_dir, terrains};
use glam::DVec3;
use rayon::prelude::*;
use relief::cpu;
use relief::db;
use relief::scene::{Camera, Pose, Scene};
use relief::terrain::Terrain;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const ARCMIN: f64 = 1.0 / 60.0;

// ---------------------------------------------------------------------------------------------
// Truth: WGS84 written out here.

const A: f64 = 6_378_137.0;
const F: f64 = 1.0 / 298.257_223_563;

fn e2() -> f64 {
    F * (2.0 - F)
}

/// ECEF of geodetic latitude, longitude (degrees) and height above the ellipsoid (m).
fn ecef(lat: f64, lon: f64, h: f64) -> DVec3 {
    let (sl, cl) = lat.to_radians().sin_cos();
    let (so, co) = lon.to_radians().sin_cos();
    let n = A / (1.0 - e2() * sl * sl).sqrt();
    DVec3::new(
        (n + h) * cl * co,
        (n + h) * cl * so,
        (n * (1.0 - e2()) + h) * sl,
    )
}

/// East, north, up unit vectors at a geodetic latitude, longitude.
fn enu(lat: f64, lon: f64) -> [DVec3; 3] {
    let (sl, cl) = lat.to_radians().sin_cos();
    let (so, co) = lon.to_radians().sin_cos();
    [
        DVec3::new(-so, co, 0.0),
        DVec3::new(-sl * co, -sl * so, cl),
        DVec3::new(cl * co, cl * so, sl),
    ]
}

/// Does the ray `o + t d` (t > 0) meet the ellipsoid? Exact quadratic in t on the scaled
/// sphere (x² + y²)/a² + z²/b² = 1.
fn hits_ellipsoid(o: DVec3, d: DVec3) -> bool {
    let b = A * (1.0 - F);
    let s = DVec3::new(1.0 / A, 1.0 / A, 1.0 / b);
    let (os, ds) = (o * s, d * s);
    let (qa, qb, qc) = (ds.dot(ds), 2.0 * os.dot(ds), os.dot(os) - 1.0);
    let disc = qb * qb - 4.0 * qa * qc;
    disc >= 0.0 && (-qb + disc.sqrt()) > 0.0
}

/// Unit direction at azimuth `az` (from north, clockwise) and elevation `el` (degrees) in a
/// frame with x east, y north, z up.
fn local_dir(az: f64, el: f64) -> DVec3 {
    let (sa, ca) = az.to_radians().sin_cos();
    let (se, ce) = el.to_radians().sin_cos();
    DVec3::new(sa * ce, ca * ce, se)
}

/// Largest elevation (degrees) in `[lo, hi]` at which `hits` holds, by bisection (`hits(lo)`
/// true, `hits(hi)` false), to 1e-7°.
fn bisect(mut lo: f64, mut hi: f64, mut hits: impl FnMut(f64) -> bool) -> f64 {
    assert!(
        hits(lo) && !hits(hi),
        "the bracket [{lo}, {hi}] does not bracket the edge"
    );
    while hi - lo > 1e-7 {
        let mid = 0.5 * (lo + hi);
        if hits(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The ellipsoid's tangent elevation (degrees) seen from (lat, lon, h) at azimuth `az`.
fn true_dip(lat: f64, lon: f64, h: f64, az: f64) -> f64 {
    let o = ecef(lat, lon, h);
    let [e, n, u] = enu(lat, lon);
    bisect(-10.0, 1.0, |el| {
        let d = local_dir(az, el);
        hits_ellipsoid(o, e * d.x + n * d.y + u * d.z)
    })
}

// ---------------------------------------------------------------------------------------------
// Scenes

fn build_once(name: &str, sources: &[PathBuf]) -> PathBuf {
    let dir = project_dir().join("target").join("test-output").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("{name}.reliefdb"));
    db::build(&p, sources, &db::BuildOptions::default(), &|_, _| {})
        .unwrap_or_else(|e| panic!("building {}: {e}", p.display()));
    p
}

fn etopo() -> PathBuf {
    project_dir().join("tests").join("data").join("etopo20.tif")
}

/// ETOPO20 alone (the Pacific) and ETOPO20 under N43E042 (Elbrus), built once per process.
fn pacific_db() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| build_once("curvature-pacific", &[etopo()]))
}

fn elbrus_db() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| {
        build_once(
            "curvature-elbrus",
            &[etopo(), terrains().join("N43E042.hgt")],
        )
    })
}

/// A scene over `db` with `[terrain]` lines `terrain` and the camera at `geodetic`.
fn scene(db: &Path, terrain: &str, geodetic: [f64; 3], heading: f64) -> (Scene, Terrain) {
    let text = format!(
        "[terrain]\ndatabase = \"{}\"\n{terrain}\n[sun]\nazimuth = 110.0\nelevation = 6.0\n[fog]\nvisibility = 0.0\n[camera]\ngeodetic = [{}, {}, {}]\nheading = {heading}\n",
        db.file_name().unwrap().to_string_lossy(),
        geodetic[0],
        geodetic[1],
        geodetic[2]
    );
    let scene = Scene::parse(&text, &db.with_file_name("scene.toml")).unwrap();
    let terrain = scene.load_terrain().unwrap();
    (scene, terrain)
}

/// The pacific window: 25..35 N, 157..143 W, deep ocean (ETOPO20 there is at least 3 km
/// deep); the eye at its centre.
const PACIFIC: [f64; 2] = [30.0, -150.0];
const PACIFIC_WINDOW: &str = "window = [25.0, -157.0, 35.0, -143.0]\nsea_level = 0.0";

/// A one-pixel camera looking at azimuth `az`, elevation `el`: its pixel's ray is the
/// camera's forward axis.
fn one_pixel(eye: DVec3, az: f64, el: f64) -> Camera {
    Camera::new(
        Pose {
            position: eye,
            heading: az,
            pitch: el,
            roll: 0.0,
            fov: 1.0,
        },
        1,
        1,
    )
}

fn cpu_hits(terrain: &Terrain, eye: DVec3, az: f64, el: f64) -> Option<f64> {
    let d = one_pixel(eye, az, el).pixel_ray(0, 0);
    cpu::cast_ray(terrain, eye, d, 0.0, f64::INFINITY).map(|h| h.t)
}

// ---------------------------------------------------------------------------------------------
// CPU oracle

#[test]
fn sea_horizon_dip_matches_the_ellipsoid_from_1_5_and_10_km() {
    let db = pacific_db();
    let mut worst = 0.0f64;
    for alt in [1000.0, 5000.0, 10000.0] {
        let (scene, terrain) = scene(db, PACIFIC_WINDOW, [PACIFIC[0], PACIFIC[1], alt], 0.0);
        assert!(terrain.curved, "databases are curved by default");
        assert_eq!(
            (terrain.min_height, terrain.max_height),
            (0.0, 0.0),
            "sea_level = 0 over open sea: a flat sea"
        );
        let eye = scene.camera_position(&terrain).unwrap();
        // The one-pixel camera's ray is local_dir (checked once: the test's own direction
        // convention is the camera's).
        let d = one_pixel(eye, 33.0, -2.0).pixel_ray(0, 0);
        assert!((d - local_dir(33.0, -2.0)).length() < 1e-12, "{d}");
        for az in [0.0, 90.0, 200.0, 300.0] {
            let got = bisect(-10.0, 1.0, |el| cpu_hits(&terrain, eye, az, el).is_some());
            let truth = true_dip(PACIFIC[0], PACIFIC[1], alt, az);
            let err = (got - truth).abs() / ARCMIN;
            eprintln!(
                "dip from {alt} m at azimuth {az}: rendered {got:.6}°, ellipsoid {truth:.6}°, error {err:.4}′"
            );
            assert!(
                err <= 0.5,
                "{alt} m, azimuth {az}: rendered dip {got}° against {truth}° ({err:.3}′)"
            );
            worst = worst.max(err);
        }
    }
    eprintln!("worst dip error {worst:.4} arc-minutes");
}

/// Nearest `t > 0` at which the ray `o + t d` meets the ellipsoid (same quadratic as
/// [`hits_ellipsoid`]).
fn ellipsoid_t(o: DVec3, d: DVec3) -> Option<f64> {
    let b = A * (1.0 - F);
    let s = DVec3::new(1.0 / A, 1.0 / A, 1.0 / b);
    let (os, ds) = (o * s, d * s);
    let (qa, qb, qc) = (ds.dot(ds), 2.0 * os.dot(ds), os.dot(os) - 1.0);
    let disc = qb * qb - 4.0 * qa * qc;
    (disc >= 0.0).then(|| (-qb - disc.sqrt()) / (2.0 * qa))
}

/// Where rays meet the sea, horizontally: from 5 km up at 34.5N, 4.5° north of the window's
/// centre latitude (where the grid's spacing is taken), rays 60–80 km long at four azimuths
/// meet the sea where the ellipsoid puts them (exact ray–ellipsoid intersection in ECEF)
/// within the second-order terms the grid does not model — a parallel `n` north of the eye
/// is shorter by `n tan φ / N` and bends `e² tan φ / 2N` away from the eye's east axis — plus
/// 20 m. The grid's spacing at the window's centre put them up to 4.8% of their east-west
/// reach off (2.9 km): the picture's metric is the eye's.
#[test]
fn rays_meet_the_sea_where_the_ellipsoid_puts_them_far_from_the_window_centre() {
    let db = pacific_db();
    let eye_geo = [34.5, -150.0, 5000.0];
    let (scene, terrain) = scene(db, PACIFIC_WINDOW, eye_geo, 0.0);
    let eye = scene.camera_position(&terrain).unwrap();
    let o = ecef(eye_geo[0], eye_geo[1], eye_geo[2]);
    let [ue, un, uu] = enu(eye_geo[0], eye_geo[1]);
    let tan_over_n = eye_geo[0].to_radians().tan()
        / (A / (1.0 - e2() * eye_geo[0].to_radians().sin().powi(2)).sqrt());
    let mut worst = 0.0f64;
    for (az, el) in [(60.0, -4.0), (90.0, -4.5), (200.0, -4.0), (250.0, -3.8)] {
        let d = local_dir(az, el);
        let hit =
            cpu::cast_ray(&terrain, eye, d, 0.0, f64::INFINITY).expect("the ray meets the sea");
        // The hit's z is in the eye's tangent frame: the sea less the drop there.
        let [lat, lon, z] = terrain.world_to_geodetic(hit.point).unwrap();
        let g = terrain.frame.world_to_grid(hit.point);
        let msl = z + terrain.curvature(eye).drop(g.x, g.y);
        assert!(msl.abs() < 1e-3, "on the sea: {msl} m");
        let rendered = ecef(lat, lon, 0.0);
        let dw = ue * d.x + un * d.y + uu * d.z;
        let t = ellipsoid_t(o, dw).expect("the true ray meets the ellipsoid");
        let truth = o + dw * t;
        let off = truth - o;
        let (e, n) = (off.dot(ue), off.dot(un));
        let bound = 1.1 * (e.abs() * n.abs() + 0.5 * e * e) * tan_over_n + 20.0;
        let err = (rendered - truth).length();
        eprintln!(
            "azimuth {az}, elevation {el}: {:.1} km (east {:.1}, north {:.1}); rendered {err:.1} m from the ellipsoid's point (bound {bound:.1} m); t {:.1} against {:.1} m",
            t / 1e3, e / 1e3, n / 1e3, hit.t, t
        );
        assert!(err <= bound, "azimuth {az}: {err} m off (bound {bound} m)");
        worst = worst.max(err / t);
    }
    eprintln!(
        "worst horizontal error {:.3}% of the distance",
        worst * 100.0
    );
}

/// Elbrus from 150 km north, 3000 m up: the eye, the summit sample (lat, lon, height) and
/// the curved and flat terrains.
struct Elbrus {
    scene: Scene,
    curved: Terrain,
    flat: Terrain,
    eye: DVec3,
    eye_geo: [f64; 3],
    summit: [f64; 3],
}

const ELBRUS_WINDOW: &str = "window = [43.0, 42.0, 44.9, 43.0]";

fn elbrus() -> &'static Elbrus {
    static E: OnceLock<Elbrus> = OnceLock::new();
    E.get_or_init(|| {
        let db = elbrus_db();
        let eye_geo = [44.70, 42.44, 3000.0];
        let (scene, curved) = scene(db, ELBRUS_WINDOW, eye_geo, 180.0);
        let (_, flat) = scene_flat(db, eye_geo);
        let eye = scene.camera_position(&curved).unwrap();
        // The highest sample within 0.05° of 43.35 N, 42.44 E.
        let geo = curved.field.geo.expect("georeferenced");
        let mut summit = [0.0, 0.0, f64::MIN];
        for j in 0..curved.field.height {
            for i in 0..curved.field.width {
                let (lat, lon) = (
                    geo.lat0 + j as f64 * geo.dlat,
                    geo.lon0 + i as f64 * geo.dlon,
                );
                let h = curved.field.at(i, j) as f64;
                if (lat - 43.35).abs() < 0.05 && (lon - 42.44).abs() < 0.05 && h > summit[2] {
                    summit = [lat, lon, h];
                }
            }
        }
        assert!(summit[2] > 5500.0, "Elbrus's summit sample is {summit:?}");
        Elbrus {
            scene,
            curved,
            flat,
            eye,
            eye_geo,
            summit,
        }
    })
}

fn scene_flat(db: &Path, eye_geo: [f64; 3]) -> (Scene, Terrain) {
    scene(
        db,
        &format!("{ELBRUS_WINDOW}\ncurved = false"),
        eye_geo,
        180.0,
    )
}

/// Azimuth and elevation (degrees) of the summit seen from the eye, from ECEF (the geoid
/// undulation taken as constant: heights above MSL are heights above the ellipsoid).
fn summit_truth(e: &Elbrus) -> (f64, f64) {
    let [lat, lon, h] = e.eye_geo;
    let (o, s) = (
        ecef(lat, lon, h),
        ecef(e.summit[0], e.summit[1], e.summit[2]),
    );
    let v = (s - o).normalize();
    let [east, north, up] = enu(lat, lon);
    (
        v.dot(east).atan2(v.dot(north)).to_degrees(),
        v.dot(up).asin().to_degrees(),
    )
}

/// The silhouette's elevation at azimuth `az` by bisection of hit/miss.
fn silhouette(terrain: &Terrain, eye: DVec3, az: f64) -> f64 {
    bisect(-3.0, 3.0, |el| cpu_hits(terrain, eye, az, el).is_some())
}

#[test]
fn a_summit_150_km_away_stands_at_its_ellipsoidal_elevation() {
    let e = elbrus();
    let (az, truth) = summit_truth(e);
    let got = silhouette(&e.curved, e.eye, az);
    let flat = silhouette(&e.flat, e.eye, az);
    let (err, flat_err) = ((got - truth).abs() / ARCMIN, (flat - truth).abs() / ARCMIN);
    eprintln!(
        "Elbrus sample {:?} at azimuth {az:.5}°: truth {truth:.5}°, curved {got:.5}° (error {err:.4}′), flat {flat:.5}° (error {flat_err:.2}′)",
        e.summit
    );
    assert!(
        err <= 0.5,
        "curved silhouette {got}° against {truth}° ({err:.3}′)"
    );
    assert!(
        flat_err > 5.0,
        "the flat earth is only {flat_err:.2}′ off: the view does not test the curve"
    );
}

// ---------------------------------------------------------------------------------------------
// GPU

fn gpu_hits(
    r: &mut relief::gpu::TerrainRenderer,
    g: &relief::gpu::Gpu,
    scene: &Scene,
    terrain: &Terrain,
    eye: DVec3,
    az: f64,
    el: f64,
) -> Option<f64> {
    let cam = one_pixel(eye, az, el);
    let out = r
        .capture(
            g,
            terrain,
            &scene.desc,
            &cam,
            &common::settings(false, true),
        )
        .expect("capture");
    out.depth[0].is_finite().then_some(out.depth[0] as f64)
}

#[test]
fn gpu_rays_find_the_same_horizon_and_silhouette_as_the_cpu() {
    use relief::gpu::TerrainRenderer;
    let _l = common::gpu_lock();
    let Some(g) = common::gpu() else {
        return;
    };
    let (scene, terrain) = scene(
        pacific_db(),
        PACIFIC_WINDOW,
        [PACIFIC[0], PACIFIC[1], 10000.0],
        0.0,
    );
    let eye = scene.camera_position(&terrain).unwrap();
    let mut r = TerrainRenderer::new(g, &terrain).expect("renderer");
    let az = 90.0;
    let cpu_dip = bisect(-10.0, 1.0, |el| cpu_hits(&terrain, eye, az, el).is_some());
    let gpu_dip = bisect(-10.0, 1.0, |el| {
        gpu_hits(&mut r, g, &scene, &terrain, eye, az, el).is_some()
    });
    let err = (gpu_dip - cpu_dip).abs() / ARCMIN;
    eprintln!("dip from 10 km: GPU {gpu_dip:.6}°, CPU {cpu_dip:.6}° ({err:.4}′)");
    assert!(err <= 0.5, "GPU dip {gpu_dip}° against CPU {cpu_dip}°");
    // A hit ray a degree below the horizon: depth within 1e-4 relative.
    let el = cpu_dip - 1.0;
    let c = cpu_hits(&terrain, eye, az, el).expect("CPU hit");
    let gd = gpu_hits(&mut r, g, &scene, &terrain, eye, az, el).expect("GPU hit");
    let rel = ((gd - c) / c).abs();
    eprintln!("depth at {el:.4}°: GPU {gd:.2} m, CPU {c:.2} m, relative {rel:e}");
    assert!(rel <= 1e-4, "GPU depth {gd} against CPU {c}");

    let e = elbrus();
    let (az, _) = summit_truth(e);
    let mut r = TerrainRenderer::new(g, &e.curved).expect("renderer");
    let cpu_el = silhouette(&e.curved, e.eye, az);
    let gpu_el = bisect(-3.0, 3.0, |el| {
        gpu_hits(&mut r, g, &e.scene, &e.curved, e.eye, az, el).is_some()
    });
    let err = (gpu_el - cpu_el).abs() / ARCMIN;
    eprintln!("Elbrus silhouette: GPU {gpu_el:.6}°, CPU {cpu_el:.6}° ({err:.4}′)");
    assert!(err <= 0.5, "GPU silhouette {gpu_el}° against CPU {cpu_el}°");
}

/// A 160x120 view of the Caucasus from the north on the curved earth, shadows on: GPU depth
/// against the CPU oracle (99.5% of pixels agree on hit/miss and within 1e-3 relative; the
/// rest are silhouettes) and GPU shadow flags against the CPU's shadow rays in the same
/// (eye's) frame (97% of the CPU's cast-shadow and sunlit pixels).
#[test]
fn a_curved_view_on_the_gpu_matches_the_cpu_oracle() {
    use relief::gpu::TerrainRenderer;
    let _l = common::gpu_lock();
    let Some(g) = common::gpu() else {
        return;
    };
    let e = elbrus();
    let (w, h) = (160u32, 120u32);
    let cam = Camera::new(
        Pose {
            position: e.eye,
            heading: 175.0,
            pitch: -1.5,
            roll: 0.0,
            fov: 30.0,
        },
        w,
        h,
    );
    let mut r = TerrainRenderer::new(g, &e.curved).expect("renderer");
    let out = r
        .capture(
            g,
            &e.curved,
            &e.scene.desc,
            &cam,
            &common::settings(true, true),
        )
        .expect("capture");
    let curv = e.curved.curvature(e.eye);
    let sun = e.scene.desc.sun.direction();
    let cpu: Vec<Option<(f64, Option<bool>)>> = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let hit = cpu::cast_ray(
                &e.curved,
                e.eye,
                cam.pixel_ray(k % w, k / w),
                0.0,
                f64::INFINITY,
            )?;
            let shadow = (hit.normal.dot(sun) > 0.05)
                .then(|| cpu::sun_visible_seen_from(&e.curved, curv, hit.point, hit.normal, sun));
            Some((hit.t, shadow))
        })
        .collect();
    let (mut bad, mut worst, mut hits) = (0usize, 0.0f64, 0usize);
    let (mut shadowed, mut dark, mut sunny, mut bright) = (0, 0, 0, 0);
    for (k, c) in cpu.iter().enumerate() {
        let gd = out.depth[k];
        match (c, gd.is_finite()) {
            (Some((t, shadow)), true) => {
                hits += 1;
                let rel = ((gd as f64 - t) / t).abs();
                if rel > 1e-3 {
                    bad += 1;
                } else {
                    worst = worst.max(rel);
                }
                match shadow {
                    Some(false) => {
                        shadowed += 1;
                        dark += (out.flags[k] & 2 != 0) as usize;
                    }
                    Some(true) => {
                        sunny += 1;
                        bright += (out.flags[k] & 2 == 0) as usize;
                    }
                    None => {}
                }
            }
            (None, false) => {}
            _ => bad += 1,
        }
    }
    let n = (w * h) as f64;
    eprintln!(
        "{hits} terrain pixels, {bad} disagree, worst depth {worst:e} relative among the rest; shadowed {shadowed} (GPU dark {dark}), sunny {sunny} (GPU lit {bright})"
    );
    assert!(hits as f64 > 0.3 * n, "only {hits} terrain pixels");
    if bad as f64 > 0.005 * n {
        let p = common::save_failure_image("curved-gpu-vs-cpu", w, h, &out.rgba);
        panic!("{bad} pixels disagree with the CPU ({})", p.display());
    }
    assert!(
        shadowed > 50 && sunny > 50,
        "shadowed {shadowed}, sunny {sunny}: the view does not test shadows"
    );
    assert!(
        dark as f64 >= 0.97 * shadowed as f64 && bright as f64 >= 0.97 * sunny as f64,
        "{dark}/{shadowed} CPU-shadowed pixels dark on the GPU, {bright}/{sunny} CPU-lit ones lit"
    );
}

/// `camera.geodetic`: exactly one of it and `position`; refused, naming the key, for a
/// terrain without a georeference and a point off the terrain.
#[test]
fn geodetic_camera_errors_name_the_key() {
    let db = pacific_db();
    let dir = db.parent().unwrap();
    let load = |terrain: &str, camera: &str| -> Result<(), String> {
        let text = format!("[terrain]\n{terrain}\n[camera]\n{camera}\n");
        let scene = Scene::parse(&text, &dir.join("errors.toml")).map_err(|e| e.to_string())?;
        scene.load_terrain().map(|_| ()).map_err(|e| e.to_string())
    };
    let pacific = format!(
        "database = \"{}\"\n{PACIFIC_WINDOW}",
        db.file_name().unwrap().to_string_lossy()
    );
    assert!(load(&pacific, "geodetic = [30.0, -150.0, 1000.0]").is_ok());
    for (terrain, camera, needle) in [
        (
            pacific.as_str(),
            "geodetic = [30.0, -150.0, 1000.0]\nposition = [0.0, 0.0, 1.0]",
            "camera.position",
        ),
        (pacific.as_str(), "heading = 3.0", "camera.position"),
        (
            pacific.as_str(),
            "geodetic = [40.0, -150.0, 1000.0]",
            "camera.geodetic",
        ),
        (
            pacific.as_str(),
            "geodetic = [30.0, nan, 1000.0]",
            "camera.geodetic",
        ),
        (
            "[terrain.procedural]\nsize = 2",
            "geodetic = [30.0, -150.0, 1000.0]",
            "camera.geodetic",
        ),
    ] {
        let terrain = terrain.strip_prefix("[terrain]\n").unwrap_or(terrain);
        let text = if terrain.starts_with("[terrain.procedural]") {
            let scene = format!("{terrain}\n[camera]\n{camera}\n");
            Scene::parse(&scene, &dir.join("errors.toml"))
                .and_then(|s| s.load_terrain().map(|_| ()))
                .map_err(|e| e.to_string())
        } else {
            load(terrain, camera)
        };
        let err = text.expect_err(camera);
        assert!(err.contains(needle), "{camera}: {err}");
    }
}
