//! Cloud layers (`[[clouds]]`) on the GPU against the CPU reference (`cpu::clouds`): the
//! layers seen against the sky, and the sun through them on the ground.

mod common;

use common::{gpu, gpu_lock, save_failure_image, settings, synthetic_scene, terrain_from_fn};
use glam::DVec3;
use relief::colour::{linear_to_srgb8, srgb_to_linear};
use relief::cpu::clouds::{composite, sun_transmittance, CloudLight, CloudRay, Deck};
use relief::gpu::{FrameOutput, TerrainRenderer};
use relief::scene::clouds::CloudLayer;
use relief::scene::{Camera, Pose, SceneDesc};
use relief::terrain::Terrain;

const W: u32 = 160;
const H: u32 = 120;

fn render(terrain: &Terrain, desc: &SceneDesc, cam: &Camera) -> Option<FrameOutput> {
    let g = gpu()?;
    let mut r = TerrainRenderer::new(g, terrain).expect("renderer");
    Some(
        r.capture(g, terrain, desc, cam, &settings(true, true))
            .expect("capture"),
    )
}

fn ramp() -> Terrain {
    terrain_from_fn(129, 10.0, |x, y| 100.0 + 0.05 * x + 0.03 * y)
}

fn camera(pitch: f64) -> Camera {
    let pose = Pose {
        position: DVec3::new(640.0, 300.0, 400.0),
        heading: 20.0,
        pitch,
        roll: 0.0,
        fov: 80.0,
    };
    Camera::new(pose, W, H)
}

fn scene(layers: &[CloudLayer], sun_intensity: f32) -> SceneDesc {
    let mut desc = synthetic_scene(W, H, "position = [640.0, 300.0, 400.0]");
    desc.sun.azimuth = 30.0;
    desc.sun.elevation = 40.0;
    desc.sun.intensity = sun_intensity;
    desc.clouds = layers.to_vec();
    desc.validate().unwrap();
    desc
}

fn layer(base: f64, thickness: f64, coverage: f64, visibility: f64, feature: f64) -> CloudLayer {
    CloudLayer {
        base,
        thickness,
        coverage,
        visibility,
        feature,
        seed: base as u32,
        relief: 1.0,
    }
}

fn rgb(c: [f32; 3]) -> DVec3 {
    DVec3::new(c[0].into(), c[1].into(), c[2].into())
}

/// The clouds' light of a daylight, as `clouds.wgsl` takes it from the frame block.
fn cloud_light(day: &relief::scene::Daylight) -> CloudLight {
    CloudLight {
        sun: day.light,
        sun_colour: rgb(day.sun_colour) * f64::from(day.intensity),
        ambient: (rgb(day.zenith) + rgb(day.horizon)) * (0.5 * f64::from(day.ambient)),
    }
}

/// Fails, with the frame saved as `name`, where a pixel is more than `allowed` levels off.
fn fail_if_off(name: &str, worst: i32, allowed: i32, rgba: &[u8], what: &str) {
    if worst > allowed {
        let p = save_failure_image(name, W, H, rgba);
        panic!(
            "{what} up to {worst} levels off (at most {allowed}); {}",
            p.display()
        );
    }
}

fn lin(px: &[u8]) -> DVec3 {
    DVec3::new(
        srgb_to_linear(px[0]),
        srgb_to_linear(px[1]),
        srgb_to_linear(px[2]),
    )
}

fn off(px: &[u8], want: DVec3) -> i32 {
    let want = [want.x, want.y, want.z].map(linear_to_srgb8);
    (0..3)
        .map(|i| (i32::from(px[i]) - i32::from(want[i])).abs())
        .max()
        .unwrap()
}

/// Two layers over a camera looking up through haze: a broken deck of dense cloud 500 m above
/// it and a thin overcast higher up. Every sky pixel is the CPU's composite of the layers over
/// the daylight's sky, within a level (f32 against f64 along paths of up to 200 km).
#[test]
fn cloud_layers_against_the_sky_match_the_cpu_reference() {
    let _l = gpu_lock();
    let terrain = ramp();
    let cam = camera(25.0);
    let layers = [
        layer(900.0, 300.0, 0.5, 80.0, 600.0),
        layer(2000.0, 200.0, 1.0, 1500.0, 2500.0),
    ];
    // Uniform haze of 20 km visibility over the clouds (the sky behind them is not hazed).
    let hazy = |layers: &[CloudLayer]| {
        let mut d = scene(layers, 2.6);
        d.fog.visibility = 20_000.0;
        d.fog.scale_height = 0.0;
        d
    };
    let desc = hazy(&layers);
    let Some(out) = render(&terrain, &desc, &cam) else {
        return;
    };
    let Some(clear) = render(&terrain, &hazy(&[]), &cam) else {
        return;
    };
    let day = desc.daylight();
    let light = cloud_light(&day);
    let decks: Vec<Deck> = layers.iter().map(Deck::new).collect();
    let fr = &terrain.frame;
    let eye = fr.world_to_grid(cam.pose.position);
    let (mut sky, mut worst, mut beyond_one, mut changed) = (0, 0, 0, 0);
    for k in 0..(W * H) as usize {
        if out.depth[k].is_finite() {
            continue;
        }
        let d = cam.pixel_ray(k as u32 % W, k as u32 / W);
        let ray = CloudRay {
            eye,
            dir: fr.world_dir_to_grid(d),
            a: 0.0,
            spacing: fr.spacing,
        };
        let behind = common::daylight_sky(&day, d);
        // `aerial_perspective`: c τ + the haze's colour (1 − τ), here for light c of opacity w.
        let scatter = rgb(day.fog_colour)
            + light.sun_colour / f64::from(day.intensity)
                * (0.25 * d.dot(day.light).max(0.0).powi(8));
        let haze = |c: DVec3, w: f64, s: f64, _z: f64| {
            let tau = (-3.912 / 20_000.0 * s).exp();
            c * tau + scatter * ((1.0 - tau) * w)
        };
        let want = composite(&decks, &ray, f64::INFINITY, behind, &light, haze);
        let px = &out.rgba[4 * k..4 * k + 3];
        let o = off(px, want);
        worst = worst.max(o);
        beyond_one += usize::from(o > 1);
        changed += usize::from(off(&clear.rgba[4 * k..4 * k + 3], want) > 10);
        sky += 1;
    }
    eprintln!(
        "{sky} sky pixels: worst {worst} level(s) from the CPU's clouds, {beyond_one} beyond one; {changed} more than 10 levels from the cloudless sky"
    );
    let what = format!("sky pixels ({beyond_one} beyond one level) against the CPU reference");
    fail_if_off("clouds-sky", worst, 1, &out.rgba, &what);
    assert!(sky > 8000, "{sky} sky pixels");
    assert!(
        changed > sky / 3,
        "the clouds changed only {changed} sky pixels"
    );
}

/// The ground seen from under a broken deck: each pixel is lit by the sun times the CPU's
/// transmittance through the cloud above it (the frames without the clouds, with and without
/// the sun, give the pixel's sunlit and its ambient part), within 2 levels (8-bit rounding of
/// the two frames it is made from); pixels whose sunlit colour is clipped at white are left
/// out.
#[test]
fn the_ground_under_a_layer_takes_the_sun_through_it() {
    let _l = gpu_lock();
    let terrain = ramp();
    let cam = camera(-35.0);
    let layers = [layer(900.0, 300.0, 0.5, 300.0, 1200.0)];
    let desc = scene(&layers, 2.6);
    let (Some(cloudy), Some(sunny), Some(shade)) = (
        render(&terrain, &desc, &cam),
        render(&terrain, &scene(&[], 2.6), &cam),
        render(&terrain, &scene(&[], 0.0), &cam),
    ) else {
        return;
    };
    let day = desc.daylight();
    let decks: Vec<Deck> = layers.iter().map(Deck::new).collect();
    let fr = &terrain.frame;
    let sun_grid = fr.world_dir_to_grid(day.light);
    let (mut ground, mut saturated, mut worst, mut t_min, mut t_max) = (0, 0, 0, 1.0f64, 0.0f64);
    for k in 0..(W * H) as usize {
        let t = f64::from(cloudy.depth[k]);
        if !t.is_finite() {
            continue;
        }
        let d = cam.pixel_ray(k as u32 % W, k as u32 / W);
        let p = fr.world_to_grid(cam.pose.position + d * t);
        let tr = sun_transmittance(&decks, p, sun_grid, fr.spacing);
        if sunny.rgba[4 * k..4 * k + 3].contains(&255) {
            // Sunlit white (snow at the ramp's top): the sunlit part is clipped there.
            saturated += 1;
            continue;
        }
        let (lit, dark) = (lin(&sunny.rgba[4 * k..]), lin(&shade.rgba[4 * k..]));
        let want = dark + (lit - dark) * tr;
        let o = off(&cloudy.rgba[4 * k..4 * k + 3], want);
        if o > 10 && k % 7 == 0 {
            let got = lin(&cloudy.rgba[4 * k..]);
            eprintln!(
                "DBG k {k} p {p:?} cpu T {tr:.3} gpu T {:.3}",
                (got.y - dark.y) / (lit.y - dark.y)
            );
        }
        worst = worst.max(o);
        t_min = t_min.min(tr);
        t_max = t_max.max(tr);
        ground += 1;
    }
    eprintln!(
        "{ground} ground pixels within {worst} level(s) of the sun through the CPU's cloud ({saturated} sunlit white left out); transmittance {t_min:.3}..{t_max:.3}"
    );
    fail_if_off("clouds-ground", worst, 2, &cloudy.rgba, "ground pixels");
    assert!(ground > 8000, "{ground} ground pixels checked");
    assert!(
        t_min < 0.2 && t_max > 0.95,
        "the deck's shadow and its gaps: {t_min}..{t_max}"
    );
}

/// `relief bench clouds --json`: the frame with the scene's layers against the same frame
/// without them, both timed; a scene without layers is refused by name.
#[test]
fn the_bench_times_the_frame_with_and_without_the_layers() {
    if gpu().is_none() {
        return;
    }
    let _l = gpu_lock();
    let scene = common::terrains().join("overcast.toml");
    let scene = scene.to_str().unwrap();
    let args = [
        "bench", "clouds", scene, "--size", "160x90", "--frames", "2", "--json",
    ];
    let o = common::relief_cli(&args, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let d = &v["details"];
    assert_eq!(d["layers"], 2, "{d}");
    let (clear, clouds, ratio) = (
        d["clear_ms"].as_f64().unwrap(),
        d["clouds_ms"].as_f64().unwrap(),
        d["ratio"].as_f64().unwrap(),
    );
    assert!(clear > 0.0 && clouds > 0.0, "{d}");
    assert!((ratio - clouds / clear).abs() < 1e-9, "{d}");
    let alps = common::terrains().join("alps.toml");
    let o = common::relief_cli(&["bench", "clouds", alps.to_str().unwrap()], &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("[[clouds]]"), "{err}");
}

/// On the curved earth (SRTM N47E009 with `terrain.curved`) a layer is a shell: a view ray's
/// height above it grows by `a s²`. Looking just above the horizon from 3 km, under a broken
/// layer from 3.5 to 3.8 km, every sky pixel is the CPU's composite with the curvature of the
/// eye's grid, within a level; on the flat earth the same rays give other pictures.
#[test]
fn a_layer_follows_the_curved_earth() {
    let _l = gpu_lock();
    let Some(g) = gpu() else {
        return;
    };
    let hgt = common::terrains().join("N47E009.hgt");
    let text = |curved: bool| {
        format!(
            "[terrain]\nsource = {hgt:?}\ncurved = {curved}\n[sun]\nazimuth = 200.0\nelevation = 30.0\n\
             [fog]\nvisibility = 0.0\n[camera]\ngeodetic = [47.5, 9.5, 3000.0]\nheading = 90.0\npitch = 4.0\nfov = 60.0\n\
             [output]\nwidth = {W}\nheight = {H}\n\
             [[clouds]]\nbase = 3500.0\nthickness = 300.0\ncoverage = 0.5\nvisibility = 150.0\nfeature = 4000.0\nseed = 5\n"
        )
    };
    let mut frames = Vec::new();
    for curved in [true, false] {
        let path = common::temp_dir("clouds-curved").join(format!("curved-{curved}.toml"));
        std::fs::write(&path, text(curved)).unwrap();
        let scene = relief::scene::Scene::load(&path).unwrap();
        let terrain = scene.load_terrain().unwrap();
        assert_eq!(terrain.curved, curved);
        let cam = scene.camera(0, &terrain);
        let mut r = TerrainRenderer::new(g, &terrain).expect("renderer");
        let out = r
            .capture(g, &terrain, &scene.desc, &cam, &settings(true, true))
            .expect("capture");
        frames.push((scene, terrain, cam, out));
    }
    let (scene, terrain, cam, out) = &frames[0];
    let desc = &scene.desc;
    let day = desc.daylight();
    let light = cloud_light(&day);
    let decks: Vec<Deck> = desc.clouds.iter().map(Deck::new).collect();
    let fr = &terrain.frame;
    let curv = terrain.curvature(cam.pose.position);
    let eye = fr.world_to_grid(cam.pose.position);
    let (mut sky, mut worst, mut differs) = (0, 0, 0);
    for k in 0..(W * H) as usize {
        if out.depth[k].is_finite() {
            continue;
        }
        let d = cam.pixel_ray(k as u32 % W, k as u32 / W);
        let g = fr.world_dir_to_grid(d) / curv.metric.extend(1.0);
        let ray = CloudRay {
            eye,
            dir: g,
            a: curv.k.x * g.x * g.x + curv.k.y * g.y * g.y,
            spacing: fr.spacing,
        };
        let behind = common::daylight_sky(&day, d);
        let want = composite(&decks, &ray, f64::INFINITY, behind, &light, |c, _, _, _| c);
        let px = &out.rgba[4 * k..4 * k + 3];
        worst = worst.max(off(px, want));
        differs += usize::from(px != &frames[1].3.rgba[4 * k..4 * k + 3]);
        sky += 1;
    }
    eprintln!(
        "curved earth: {sky} sky pixels within {worst} level(s) of the CPU's layer (a = {:.3e} per m² ahead); {differs} differ from the flat earth's",
        curv.k.x / (fr.spacing[0] * curv.metric.x).powi(2)
    );
    fail_if_off(
        "clouds-curved",
        worst,
        1,
        &out.rgba,
        "sky pixels against the CPU's shell",
    );
    assert!(sky > 8000, "{sky} sky pixels");
    assert!(
        differs > sky / 10,
        "the curvature changed only {differs} pixels"
    );
}
