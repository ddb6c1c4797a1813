//! Density volumes: loaders and their errors, transfer functions, the CPU volume integral
//! against analytic truth, and the GPU volume pass against the CPU reference.

mod common;

use common::{
    gpu, gpu_lock, read_json, rgba_of, save_failure_image, save_failure_images, settings,
    terrain_from_fn, terrains,
};
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use relief::cpu::volume::{composite_sorted, integrate, VolumeLight};
use relief::gpu::{FrameOutput, TerrainRenderer};
use relief::scene::{Camera, Scene, SceneDesc};
use relief::terrain::Terrain;
use relief::volume::desc::VolumeMaterial;
use relief::volume::transfer::TfPoint;
use relief::volume::{DensityGrid, TransferFunction, Volume, VolumeSettings};
use std::io::Write;
use std::path::{Path, PathBuf};

fn brain_path() -> PathBuf {
    terrains().join("volumes/mni152_t1.nrrd")
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = common::project_dir()
        .join("target")
        .join("test-tmp")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A demo scene of `terrains/` at `w x h`: the scene, its terrain and its volumes.
fn demo_scene(name: &str, w: u32, h: u32) -> (Scene, Terrain, Vec<Volume>) {
    let mut scene = Scene::load(&terrains().join(name)).unwrap();
    scene.desc.output.width = w;
    scene.desc.output.height = h;
    let terrain = scene.load_terrain().unwrap();
    let vols = scene.volumes(&terrain).unwrap();
    (scene, terrain, vols)
}

/// Whether `path` (metres through a box along the sun) is the same at `p` and at eight points
/// `radius` metres around it in the horizontal plane (not near a shadow edge, which a grid's
/// trilinear read smears over a cell).
fn steady_around(p: DVec3, radius: f64, path: impl Fn(DVec3) -> f64) -> bool {
    let at = path(p);
    (0..8).all(|k| {
        let a = k as f64 * std::f64::consts::FRAC_PI_4;
        (path(p + DVec3::new(a.cos(), a.sin(), 0.0) * radius) - at).abs() < 1e-6
    })
}

#[test]
fn nrrd_brain_loads_with_its_header_size_spacing_and_bytes() {
    let g = relief::volume::nrrd::load(&brain_path(), None).unwrap();
    assert_eq!(g.dims, [197, 233, 189]);
    for s in g.spacing {
        assert!((s - 0.001).abs() < 1e-12, "1 mm voxels, got {s} m");
    }
    assert_eq!(g.value_range, [0.0, 255.0]);
    // Independent decode: the gzip payload after the header's blank line.
    let bytes = std::fs::read(brain_path()).unwrap();
    let start = bytes.windows(2).position(|w| w == b"\n\n").unwrap() + 2;
    let mut raw = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&bytes[start..]), &mut raw)
        .unwrap();
    assert_eq!(raw.len(), g.data.len());
    assert!(raw == g.data, "decoded voxels differ from the gzip payload");
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::File::create(&p).unwrap().write_all(bytes).unwrap();
    p
}

#[test]
fn bad_nrrd_files_are_refused_with_the_file_named() {
    let dir = tmp_dir("bad-nrrd");
    let good = std::fs::read(brain_path()).unwrap();
    let start = good.windows(2).position(|w| w == b"\n\n").unwrap() + 2;
    let header = |enc: &str, sizes: &str, kind: &str| {
        format!("NRRD0004\ntype: {kind}\ndimension: 3\nsizes: {sizes}\nencoding: {enc}\n\n")
            .into_bytes()
    };
    let mut corrupt = good.clone();
    for b in &mut corrupt[start + 5000..start + 5200] {
        *b ^= 0x5a;
    }
    let nan: Vec<u8> = [1.0f32, f32::NAN, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let cases: Vec<(&str, Vec<u8>, &str)> =
        vec![
        ("truncated-gzip.nrrd", good[..good.len() / 2].to_vec(), "gzip"),
        ("corrupt-gzip.nrrd", corrupt, "gzip"),
        ("bad-magic.nrrd", b"NRRX0004\n\n".to_vec(), "magic"),
        ("no-blank-line.nrrd", b"NRRD0004\ntype: uint8\n".to_vec(), "header"),
        (
            "short-raw.nrrd",
            [header("raw", "4 4 4", "uint8"), vec![7u8; 60]].concat(),
            "truncated",
        ),
        (
            "sizes-vs-gzip.nrrd",
            [header("gzip", "300 300 300", "uint8"), good[start..].to_vec()].concat(),
            "truncated",
        ),
        (
            "two-d.nrrd",
            b"NRRD0004\ntype: uint8\ndimension: 2\nsizes: 4 4\nencoding: raw\n\n0123456789abcdef"
                .to_vec(),
            "3-D",
        ),
        (
            "bzip.nrrd",
            [header("bzip2", "2 2 2", "uint8"), vec![0; 8]].concat(),
            "encoding",
        ),
        (
            "nan.nrrd",
            [header("raw", "2 2 2", "float"), nan].concat(),
            "not finite",
        ),
        (
            "huge.nrrd",
            [header("raw", "100000 2 2", "uint8"), vec![0; 8]].concat(),
            "grid size",
        ),
        (
            "too-many.nrrd",
            [header("gzip", "5000 5000 5000", "uint8"), good[start..].to_vec()].concat(),
            "downsample",
        ),
    ];
    for (name, bytes, want) in cases {
        let p = write(&dir, name, &bytes);
        let e = relief::volume::nrrd::load(&p, None)
            .err()
            .unwrap_or_else(|| panic!("{name} was accepted"))
            .to_string();
        assert!(
            e.contains(name),
            "{name}: error does not name the file: {e}"
        );
        assert!(e.contains(want), "{name}: expected {want:?} in: {e}");
    }
    let missing = relief::volume::nrrd::load(&dir.join("missing.nrrd"), None).unwrap_err();
    assert!(missing.to_string().contains("missing.nrrd"));
}

#[test]
fn raw_volume_with_a_toml_header_loads_and_checks_its_size() {
    let dir = tmp_dir("raw-volume");
    let values: Vec<u16> = (0..4 * 3 * 2).map(|i| (i * 1000) as u16).collect();
    let be: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
    write(&dir, "v.raw", &be);
    let h = write(
        &dir,
        "v.toml",
        b"file = \"v.raw\"\ndims = [4, 3, 2]\ntype = \"uint16\"\nendian = \"big\"\nspacing = [2.0, 2.0, 4.0]\nunits = \"mm\"\n",
    );
    let g = relief::volume::raw::load(&h, None).unwrap();
    assert_eq!(g.dims, [4, 3, 2]);
    assert_eq!(g.spacing, [0.002, 0.002, 0.004]);
    assert_eq!(g.value_range, [0.0, 23000.0]);
    for (i, v) in values.iter().enumerate() {
        let want = (*v as f64 / 23000.0 * 255.0).round() as u8;
        assert_eq!(g.data[i], want, "voxel {i}");
    }
    let short = write(
        &dir,
        "short.toml",
        b"file = \"v.raw\"\ndims = [4, 3, 3]\ntype = \"uint16\"\n",
    );
    let e = relief::volume::raw::load(&short, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("v.raw") && e.contains("truncated"), "{e}");
    let unknown = write(
        &dir,
        "unknown.toml",
        b"file = \"v.raw\"\ndims = [4, 3, 2]\ntype = \"uint16\"\nscale = 2\n",
    );
    let e = relief::volume::raw::load(&unknown, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown.toml") && e.contains("scale"), "{e}");
}

#[test]
fn transfer_functions_interpolate_validate_and_hide_the_brain_background() {
    let tf = TransferFunction {
        points: vec![
            TfPoint {
                value: 10.0,
                colour: [1.0, 0.0, 0.0],
                opacity: 0.0,
            },
            TfPoint {
                value: 20.0,
                colour: [0.0, 1.0, 0.0],
                opacity: 0.5,
            },
        ],
        unit: Some(2.0),
    };
    tf.validate("t").unwrap();
    let (c, a) = tf.eval(15.0);
    assert!((c[0] - 0.5).abs() < 1e-12 && (c[1] - 0.5).abs() < 1e-12 && (a - 0.25).abs() < 1e-12);
    assert_eq!(tf.eval(-5.0).1, 0.0);
    assert_eq!(tf.eval(50.0).1, 0.5);
    // σ per metre from opacity per unit: a slab one unit thick absorbs the point's opacity.
    let table = tf.table(|d| d, 1.0);
    let s = table.lookup(200.0 / 255.0)[3];
    assert!(((1.0 - (-s * 2.0).exp()) - 0.5).abs() < 1e-6, "σ {s}");
    let unsorted = TransferFunction {
        points: vec![tf.points[1], tf.points[0]],
        unit: None,
    };
    assert!(unsorted
        .validate("t")
        .unwrap_err()
        .to_string()
        .contains("sorted"));
    assert!(TransferFunction::preset("nope")
        .unwrap_err()
        .to_string()
        .contains("brain"));
    let g = relief::volume::nrrd::load(&brain_path(), None).unwrap();
    for name in ["brain", "brain-white"] {
        let tf = TransferFunction::preset(name).unwrap();
        let hidden = tf.hidden_fraction(&g.data, |d| g.value_of(d));
        eprintln!("{name}: hides {:.1}% of the voxels", 100.0 * hidden);
        assert!(hidden >= 0.7, "{name} hides only {hidden}");
    }
}

/// A volume of constant density `d` (8-bit), `n³` voxels of `voxel` metres, corner at
/// `corner`, one grey transfer point, ambient-only material (so the integral is analytic).
fn uniform_volume(n: u32, voxel: f64, corner: DVec3, d: u8, opacity: f64, step: f64) -> Volume {
    let grid = DensityGrid {
        dims: [n; 3],
        data: vec![d; (n * n * n) as usize],
        spacing: [voxel; 3],
        value_range: [0.0, 255.0],
        slices: 0,
    };
    let tf = TransferFunction {
        points: vec![
            TfPoint {
                value: 0.0,
                colour: [0.0; 3],
                opacity: 0.0,
            },
            TfPoint {
                value: 255.0,
                colour: [0.8, 0.6, 0.4],
                opacity,
            },
        ],
        unit: None,
    };
    Volume::new(
        "slab".into(),
        grid,
        tf,
        corner,
        DMat3::IDENTITY,
        VolumeSettings {
            step,
            early_termination: false,
            ..Default::default()
        },
        VolumeMaterial {
            ambient: 1.0,
            diffuse: 0.0,
            specular: 0.0,
            shininess: 1.0,
        },
        None,
    )
}

fn no_fog_light(desc: &SceneDesc, terrain: &Terrain) -> VolumeLight {
    let mut l = VolumeLight::new(desc, terrain);
    l.sigma = 0.0;
    l
}

/// Analytic colour of a ray crossing `len` metres of a uniform volume over `bg` (linear).
fn analytic_slab(v: &Volume, light: &VolumeLight, len: f64, bg: DVec3) -> DVec3 {
    let e = v.table.lookup(v.grid.data[0] as f64 / 255.0);
    // Gradient is zero in a uniform field: ambient light on a zero normal.
    let c = DVec3::new(e[0], e[1], e[2]) * light.ambient_light(DVec3::ZERO);
    let a = 1.0 - (-e[3] * len).exp();
    c * a + bg * (1.0 - a)
}

#[test]
fn cpu_uniform_slab_matches_the_analytic_integral_at_any_step() {
    let terrain = terrain_from_fn(3, 1.0, |_, _| 0.0);
    let desc = common::synthetic_scene(8, 8, "position = [0.0, 0.0, 100.0]");
    let light = no_fog_light(&desc, &terrain);
    let bg = DVec3::new(0.2, 0.3, 0.9);
    let mut worst: f64 = 0.0;
    for step in [1.0, 0.5, 0.25, 0.13] {
        let v = uniform_volume(16, 1.0, DVec3::ZERO, 128, 0.05, step);
        for k in 0..200 {
            // Rays from outside through the cube at assorted angles.
            let a = k as f64 * 0.37;
            let eye = DVec3::new(
                8.0 + 30.0 * a.cos(),
                8.0 + 30.0 * a.sin(),
                8.0 + (k % 7) as f64,
            );
            let target = DVec3::new(
                4.0 + (k % 9) as f64,
                5.0 + (k % 5) as f64,
                3.0 + (k % 11) as f64,
            );
            let dir = (target - eye).normalize();
            let r = integrate(&v, &light, eye, dir, 1e-4, f64::INFINITY, [0, 0]);
            let (t0, t1, _) = relief::cpu::freeform::clip_box(
                eye,
                dir,
                DVec3::ZERO,
                DVec3::splat(16.0),
                0.0,
                f64::INFINITY,
            )
            .unwrap();
            let want = analytic_slab(&v, &light, t1 - t0, bg);
            let got = r.over(bg);
            worst = worst.max((got - want).abs().max_element());
        }
    }
    eprintln!("worst |CPU − analytic| over steps 1 … 0.13 voxel: {worst:.2e}");
    assert!(
        worst < 1e-9,
        "uniform slab off the analytic integral by {worst}"
    );
}

/// Renders `desc` over `terrain` with `volumes`: (the image under the volumes, with their
/// shadows on the surfaces; the frame with them; the ray table).
fn render_pair(
    terrain: &Terrain,
    desc: &SceneDesc,
    cam: &Camera,
    volumes: &[Volume],
    objects: &[relief::freeform::FreeForm],
) -> Option<(FrameOutput, FrameOutput, Vec<[f32; 4]>)> {
    let g = gpu()?;
    let mut r = TerrainRenderer::new(g, terrain).unwrap();
    r.set_objects(g, objects).unwrap();
    r.set_volumes(g, volumes).unwrap();
    r.set_volumes_hidden(true);
    let under = r
        .capture(g, terrain, desc, cam, &settings(true, true))
        .unwrap();
    r.set_volumes_hidden(false);
    let out = r
        .capture(g, terrain, desc, cam, &settings(true, true))
        .unwrap();
    let rays = r.read_ray_table(g).unwrap();
    Some((under, out, rays))
}

/// The CPU reference image: the volume integrals per pixel along the GPU's own rays, cut at
/// the GPU's opaque depth, composited over the GPU's image under the volumes by
/// `composite_sorted` (per pixel, farthest medium first); `volumes` in scene order.
fn cpu_image(
    volumes: &[&Volume],
    light: &VolumeLight,
    cam: &Camera,
    under: &FrameOutput,
    rays: &[[f32; 4]],
) -> Vec<[u8; 3]> {
    cpu_image_and_undecided(volumes, light, cam, under, rays).0
}

/// [`cpu_image`] and, per pixel, whether a slice-mask sample on its ray is undecided at f32
/// precision ([`relief::cpu::volume::VolumeResult::undecided`]).
fn cpu_image_and_undecided(
    volumes: &[&Volume],
    light: &VolumeLight,
    cam: &Camera,
    under: &FrameOutput,
    rays: &[[f32; 4]],
) -> (Vec<[u8; 3]>, Vec<bool>) {
    let w = cam.width;
    (0..rays.len())
        .into_par_iter()
        .map(|k| {
            let e = rays[k];
            let u = &under.rgba[4 * k..4 * k + 3];
            if e[3] < 0.0 {
                return ([u[0], u[1], u[2]], false);
            }
            let dir = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64);
            let depth = under.depth[k] as f64;
            let t_max = if depth.is_finite() {
                depth
            } else {
                f64::INFINITY
            };
            let px = [k as u32 % w, k as u32 / w];
            let results: Vec<_> = volumes
                .iter()
                .map(|v| integrate(v, light, cam.pose.position, dir, e[3] as f64, t_max, px))
                .collect();
            let undecided = results.iter().any(|r| r.undecided > 0);
            (composite_sorted(&results, [u[0], u[1], u[2]]), undecided)
        })
        .unzip()
}

/// Mean and max absolute difference per channel (in 1/255 units) and the pixels the volume
/// changed.
fn compare(gpu_rgba: &[u8], cpu: &[[u8; 3]], under: &[u8]) -> (f64, u8, usize) {
    let (mut sum, mut max, mut touched) = (0u64, 0u8, 0usize);
    for (k, c) in cpu.iter().enumerate() {
        for ch in 0..3 {
            let d = gpu_rgba[4 * k + ch].abs_diff(c[ch]);
            sum += d as u64;
            max = max.max(d);
        }
        touched += (0..3).any(|ch| c[ch] != under[4 * k + ch]) as usize;
    }
    (sum as f64 / (3 * cpu.len()) as f64, max, touched)
}

#[test]
fn gpu_volume_matches_the_cpu_reference_on_the_brain_with_two_transfer_functions() {
    let _l = gpu_lock();
    let (scene, terrain, mut vols) = demo_scene("brain.toml", 160, 120);
    let cam = scene.camera(0, &terrain);
    let light = VolumeLight::new(&scene.desc, &terrain);
    // The second run also jitters the sample lattice per pixel (the same hash on both sides).
    for (tf, jitter) in [("brain", false), ("brain-white", true)] {
        vols[0].set_transfer(TransferFunction::preset(tf).unwrap());
        vols[0].settings.jitter = jitter;
        let Some((under, out, rays)) = render_pair(&terrain, &scene.desc, &cam, &vols, &[]) else {
            return;
        };
        let cpu = cpu_image(&[&vols[0]], &light, &cam, &under, &rays);
        let (mean, max, touched) = compare(&out.rgba, &cpu, &under.rgba);
        let samples: u64 = out.volume_samples.iter().map(|&s| s as u64).sum();
        eprintln!(
            "{tf} (jitter {jitter}): mean |GPU − CPU| {:.3}/255, max {max}/255 over {touched} volume pixels, {samples} GPU samples",
            mean
        );
        assert!(
            touched > 2000,
            "{tf}: the volume covers only {touched} pixels"
        );
        if mean >= 1.0 || max >= 4 {
            let p =
                save_failure_images(&format!("brain-{tf}"), 160, 120, &out.rgba, &rgba_of(&cpu));
            panic!(
                "{tf}: mean {mean:.3}/255 (< 1 required), max {max}/255 (< 4 required); {}",
                p.display()
            );
        }
    }
}

/// Renders `desc` with `volumes` once per settings variant.
fn render_variants(
    terrain: &Terrain,
    desc: &SceneDesc,
    cam: &Camera,
    volume: &Volume,
    variants: &[VolumeSettings],
) -> Option<Vec<FrameOutput>> {
    let g = gpu()?;
    let mut r = TerrainRenderer::new(g, terrain).unwrap();
    r.set_volumes(g, std::slice::from_ref(volume)).unwrap();
    Some(
        variants
            .iter()
            .map(|s| {
                r.set_volume_settings(g, *s);
                r.capture(g, terrain, desc, cam, &settings(true, true))
                    .unwrap()
            })
            .collect(),
    )
}

fn max_diff(a: &[u8], b: &[u8]) -> u8 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

#[test]
fn skipping_and_early_termination_change_nothing_visible() {
    let _l = gpu_lock();
    let (scene, terrain, mut vols) = demo_scene("brain.toml", 160, 120);
    let cam = scene.camera(0, &terrain);
    for tf in ["brain", "brain-white"] {
        vols[0].set_transfer(TransferFunction::preset(tf).unwrap());
        let on = vols[0].settings;
        let plain = VolumeSettings {
            skip: false,
            early_termination: false,
            ..on
        };
        let skip_only = VolumeSettings {
            early_termination: false,
            ..on
        };
        let Some(out) = render_variants(
            &terrain,
            &scene.desc,
            &cam,
            &vols[0],
            &[on, plain, skip_only],
        ) else {
            return;
        };
        let samples = |o: &FrameOutput| o.volume_samples.iter().map(|&s| s as u64).sum::<u64>();
        let (d_all, d_skip) = (
            max_diff(&out[0].rgba, &out[1].rgba),
            max_diff(&out[2].rgba, &out[1].rgba),
        );
        eprintln!(
            "{tf}: samples plain {} / skip {} / skip + termination {}; max difference {d_skip}/255 (skip), {d_all}/255 (both)",
            samples(&out[1]),
            samples(&out[2]),
            samples(&out[0])
        );
        assert!(
            d_all <= 1 && d_skip <= 1,
            "{tf}: skipping/termination changed the image by {d_all}/255"
        );
        assert!(
            samples(&out[2]) * 2 < samples(&out[1]),
            "{tf}: skipping saved too little: {} of {} samples",
            samples(&out[2]),
            samples(&out[1])
        );
        assert!(
            samples(&out[0]) < samples(&out[2]),
            "{tf}: early termination saved nothing"
        );
    }
}

/// A synthetic scene over `terrain`, `w x h`, camera at `eye` looking along heading/pitch.
fn synthetic(w: u32, h: u32, eye: DVec3, heading: f64, pitch: f64) -> (SceneDesc, Camera) {
    let desc = common::synthetic_scene(
        w,
        h,
        &format!(
            "position = [{}, {}, {}]\nheading = {heading}\npitch = {pitch}\nfov = 50.0",
            eye.x, eye.y, eye.z
        ),
    );
    let cam = Camera::new(
        relief::scene::Pose {
            position: eye,
            heading,
            pitch,
            roll: 0.0,
            fov: 50.0,
        },
        w,
        h,
    );
    (desc, cam)
}

#[test]
fn sun_transmittance_of_a_uniform_slab_matches_the_analytic_attenuation() {
    // A uniform box of extinction sigma: the transmittance at every voxel centre is
    // exp(-sigma * L), L the distance to the box along the sun, for a sun along an axis and an
    // oblique one (slice propagation, bilinear in the previous layer).
    let n = [24u32, 16, 20];
    let sp = [2.0, 3.0, 2.5];
    let grid = DensityGrid {
        dims: n,
        data: vec![200; (n[0] * n[1] * n[2]) as usize],
        spacing: sp,
        value_range: [0.0, 255.0],
        slices: 0,
    };
    let sigma = 0.02;
    let mut table = relief::volume::TransferTable {
        entries: vec![[0.0; 4]; 256],
    };
    table.entries[200] = [1.0, 1.0, 1.0, sigma as f32];
    let extent = DVec3::new(
        n[0] as f64 * sp[0],
        n[1] as f64 * sp[1],
        n[2] as f64 * sp[2],
    );
    for sun in [
        DVec3::Z,
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(0.5, -0.3, 0.8).normalize(),
        DVec3::new(-0.9, 0.2, 0.35).normalize(),
    ] {
        let sh = relief::volume::shadow::sun_transmittance(&grid, &table, sun);
        assert_eq!(sh.dims, n, "a grid this small keeps one cell per voxel");
        let t = sh.data;
        let (mut worst, mut sum) = (0.0f64, 0.0);
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    let p = DVec3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5)
                        * DVec3::from(sp);
                    let mut l = f64::INFINITY;
                    for k in 0..3 {
                        if sun[k] > 0.0 {
                            l = l.min((extent[k] - p[k]) / sun[k]);
                        } else if sun[k] < 0.0 {
                            l = l.min(-p[k] / sun[k]);
                        }
                    }
                    let want = (-sigma * l).exp();
                    let got = t[(x + n[0] * (y + n[1] * z)) as usize] as f64 / 255.0;
                    worst = worst.max((got - want).abs());
                    sum += (got - want).abs();
                }
            }
        }
        let mean = sum / t.len() as f64;
        eprintln!(
            "sun {sun:?}: transmittance error mean {:.4}, max {worst:.4}",
            mean
        );
        // Byte rounding (0.5/255) plus the bilinear read across the box's edges, where the
        // distance to the box has a kink.
        assert!(
            mean < 1.0 / 255.0 && worst < 0.03,
            "sun {sun:?}: mean {mean}, max {worst}"
        );
    }
}

#[test]
fn self_shadowing_only_darkens_and_visibly_darkens_the_brain() {
    // The brain lit with and without the sun's transmittance through itself: no pixel gets
    // brighter (transmittance <= 1 scales only the sun's terms), and the sulci and the side
    // away from the sun get visibly darker.
    let _l = gpu_lock();
    let (scene, terrain, vols) = demo_scene("brain.toml", 160, 120);
    assert!(
        vols[0].sun_shadow.is_some(),
        "the brain is self-shadowed by default"
    );
    let mut unlit = vols.clone();
    unlit[0].sun_shadow = None;
    let cam = scene.camera(0, &terrain);
    let Some((_, with, _)) = render_pair(&terrain, &scene.desc, &cam, &vols, &[]) else {
        return;
    };
    let (_, without, _) = render_pair(&terrain, &scene.desc, &cam, &unlit, &[]).unwrap();
    let (mut brighter, mut darker) = (0, 0);
    for (a, b) in with.rgba.chunks_exact(4).zip(without.rgba.chunks_exact(4)) {
        let v = |p: &[u8], c: usize| i32::from(p[c]);
        let (a, b) = ([v(a, 0), v(a, 1), v(a, 2)], [v(b, 0), v(b, 1), v(b, 2)]);
        brighter += (0..3).filter(|&c| a[c] > b[c] + 1).count();
        if (0..3).any(|c| a[c] + 10 < b[c]) {
            darker += 1;
        }
    }
    eprintln!(
        "self-shadowing: {darker} pixels darker by > 10 levels, {brighter} channels brighter"
    );
    assert_eq!(brighter, 0);
    assert!(darker > 500, "only {darker} pixels darkened");
}

#[test]
fn terrain_cuts_a_uniform_slab_at_the_analytic_depth_whatever_the_step() {
    let _l = gpu_lock();
    // A hill whose top pokes through a 60 m slab of haze lying on the ground.
    let terrain = terrain_from_fn(65, 10.0, |x, y| {
        let r2 = (x - 320.0).powi(2) + (y - 400.0).powi(2);
        90.0 * (-r2 / 15000.0).exp()
    });
    let (desc, cam) = synthetic(120, 90, DVec3::new(320.0, 40.0, 45.0), 0.0, -4.0);
    let slab = uniform_volume(32, 20.0, DVec3::new(0.0, 100.0, -20.0), 200, 0.05, 0.5);
    let slab = Volume {
        settings: VolumeSettings {
            early_termination: false,
            ..slab.settings
        },
        ..slab
    };
    let fine = VolumeSettings {
        step: 0.25,
        ..slab.settings
    };
    let Some(out) = render_variants(&terrain, &desc, &cam, &slab, &[slab.settings, fine]) else {
        return;
    };
    let Some((under, _, rays)) = render_pair(&terrain, &desc, &cam, &[], &[]) else {
        return;
    };
    let light = no_fog_light(&desc, &terrain);
    let (mut worst, mut cut, mut inside) = (0u8, 0, 0);
    for (k, e) in rays.iter().enumerate() {
        let dir = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64).normalize();
        let Some((t0, t1, _)) = relief::cpu::freeform::clip_box(
            cam.pose.position,
            dir,
            slab.corner,
            slab.corner + slab.extent(),
            0.0,
            f64::INFINITY,
        ) else {
            continue;
        };
        // The terrain distance from the CPU reference, not the GPU's depth.
        let t_terrain = relief::cpu::cast_ray(&terrain, cam.pose.position, dir, 0.0, f64::INFINITY)
            .map_or(f64::INFINITY, |h| h.t);
        let len = (t1.min(t_terrain) - t0).max(0.0);
        if len <= 0.0 {
            continue;
        }
        inside += 1;
        cut += (t_terrain < t1) as usize;
        let u = &under.rgba[4 * k..4 * k + 3];
        let bg = DVec3::from(
            [u[0], u[1], u[2]].map(|c| relief::cpu::volume::srgb_decode(c as f64 / 255.0)),
        );
        let c = analytic_slab(&slab, &light, len, bg);
        let want =
            [c.x, c.y, c.z].map(|v| (relief::cpu::volume::srgb_encode(v) * 255.0).round() as u8);
        for o in &out {
            for (ch, &want_ch) in want.iter().enumerate() {
                worst = worst.max(o.rgba[4 * k + ch].abs_diff(want_ch));
            }
        }
    }
    eprintln!("{inside} pixels see the slab, {cut} of them cut by the terrain; worst |GPU − analytic| {worst}/255 at steps 0.5 and 0.25 voxel; steps differ by {}/255", max_diff(&out[0].rgba, &out[1].rgba));
    assert!(
        inside > 3000 && cut > 1000,
        "the view misses the slab ({inside}) or the cut ({cut})"
    );
    if worst > 1 {
        let p = save_failure_image("slab-cut", 120, 90, &out[0].rgba);
        panic!(
            "GPU slab differs from the analytic integral by {worst}/255; {}",
            p.display()
        );
    }
    assert!(
        max_diff(&out[0].rgba, &out[1].rgba) <= 1,
        "halving the step changed the slab"
    );
}

#[test]
fn several_volumes_composite_back_to_front_like_the_cpu_reference() {
    // Three disjoint boxes of haze in different colours over flat ground: a far one, a near
    // one that covers part of it on screen, and one off to the side, listed near first. The
    // GPU composites them per pixel farthest first; so does the CPU reference, along the GPU's
    // rays.
    let _l = gpu_lock();
    let terrain = terrain_from_fn(65, 10.0, |_, _| 0.0);
    let (desc, cam) = synthetic(160, 120, DVec3::new(320.0, 20.0, 60.0), 0.0, -8.0);
    let tinted = |corner: DVec3, colour: [f64; 3], opacity: f64| {
        let mut v = uniform_volume(16, 8.0, corner, 200, opacity, 0.5);
        let mut tf = v.transfer.clone();
        tf.points[1].colour = colour;
        v.set_transfer(tf);
        v
    };
    let near = tinted(DVec3::new(250.0, 200.0, 10.0), [0.9, 0.2, 0.1], 0.3);
    let far = tinted(DVec3::new(300.0, 420.0, 20.0), [0.1, 0.3, 0.9], 0.5);
    let side = tinted(DVec3::new(420.0, 300.0, 0.0), [0.2, 0.9, 0.2], 0.3);
    let vols = vec![near, side, far];
    let Some((under, out, rays)) = render_pair(&terrain, &desc, &cam, &vols, &[]) else {
        return;
    };
    let light = VolumeLight::new(&desc, &terrain);
    let cpu = cpu_image(
        &vols.iter().collect::<Vec<_>>(),
        &light,
        &cam,
        &under,
        &rays,
    );
    let (mean, max, touched) = compare(&out.rgba, &cpu, &under.rgba);
    // Pixels where two volumes overlap on screen: both changed the colour.
    let overlap = (0..rays.len())
        .filter(|&k| {
            let e = rays[k];
            let dir = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64);
            let depth = under.depth[k] as f64;
            let t_max = if depth.is_finite() {
                depth
            } else {
                f64::INFINITY
            };
            vols.iter()
                .filter(|v| {
                    let (o, d) = (v.to_local(cam.pose.position), v.rotation.transpose() * dir);
                    relief::cpu::volume::ray_interval(v, o, d, t_max).is_some()
                })
                .count()
                >= 2
        })
        .count();
    eprintln!("three volumes: mean |GPU − CPU| {mean:.3}/255, max {max}/255 over {touched} pixels, {overlap} with two volumes on the ray");
    assert!(
        touched > 3000 && overlap > 300,
        "the view misses the volumes ({touched}, {overlap})"
    );
    if mean >= 1.0 || max >= 4 {
        let p = save_failure_images("volumes-three", 160, 120, &out.rgba, &rgba_of(&cpu));
        panic!(
            "mean {mean:.3}/255 (< 1 required), max {max}/255 (< 4 required); {}",
            p.display()
        );
    }
}

#[test]
fn a_volume_behind_a_free_form_is_hidden_and_one_in_front_tints_it() {
    let _l = gpu_lock();
    let terrain = terrain_from_fn(65, 10.0, |_, _| 0.0);
    let objects_toml = "[[objects]]\nname = \"ball\"\nshape = \"sphere\"\nradius = 40.0\nposition = [320.0, 300.0, 60.0]\n";
    let text = format!("[terrain.procedural]\nsize = 2\n[camera]\nposition = [0.0, 0.0, 100.0]\n[fog]\nvisibility = 0.0\n{objects_toml}");
    let objects = Scene::parse(&text, Path::new("ball.toml"))
        .unwrap()
        .free_forms(&terrain)
        .unwrap();
    let (desc, cam) = synthetic(120, 90, DVec3::new(320.0, 100.0, 60.0), 0.0, 0.0);
    let behind = uniform_volume(16, 10.0, DVec3::new(240.0, 380.0, 0.0), 200, 0.3, 0.5);
    let front = uniform_volume(16, 5.0, DVec3::new(280.0, 200.0, 20.0), 200, 0.1, 0.5);
    for (name, vol, expect_tint) in [("behind", &behind, false), ("in front", &front, true)] {
        let Some((under, out, _)) =
            render_pair(&terrain, &desc, &cam, std::slice::from_ref(vol), &objects)
        else {
            return;
        };
        let (mut ball, mut ball_changed, mut other_changed) = (0, 0, 0);
        for k in 0..under.objects.len() {
            let changed = (0..3).any(|c| under.rgba[4 * k + c] != out.rgba[4 * k + c]);
            assert_eq!(
                under.depth[k].to_bits(),
                out.depth[k].to_bits(),
                "{name}: depth changed at {k}"
            );
            if under.objects[k] != 0 {
                ball += 1;
                ball_changed += changed as usize;
            } else {
                other_changed += changed as usize;
            }
        }
        eprintln!("{name}: {ball} ball pixels, {ball_changed} tinted; {other_changed} other pixels changed");
        assert!(ball > 500, "{name}: the ball covers only {ball} pixels");
        assert!(
            other_changed > 300,
            "{name}: the volume is not visible beside the ball"
        );
        if expect_tint {
            assert!(
                ball_changed * 10 > ball * 9,
                "{name}: only {ball_changed} of {ball} ball pixels tinted"
            );
        } else {
            assert_eq!(
                ball_changed, 0,
                "{name}: a volume behind the ball shows through it"
            );
        }
    }
}

#[test]
fn cli_renders_the_brain_and_refuses_a_bad_volume_before_writing() {
    let dir = tmp_dir("volume-cli");
    let run = |args: &[&str]| common::relief_cli(args, &[]);
    let base = std::fs::read_to_string(terrains().join("brain.toml"))
        .unwrap()
        .replace(
            "source = \"volumes/mni152_t1.nrrd\"",
            &format!("source = {:?}", brain_path()),
        );
    for (name, scene, needles) in [
        (
            "missing",
            base.replace("mni152_t1.nrrd", "nope.nrrd"),
            vec!["nope.nrrd"],
        ),
        (
            "step",
            base.replace(
                "transfer = \"brain\"",
                "transfer = \"brain\"\nrender = { step = 0.0 }",
            ),
            vec!["mni152", "render.step"],
        ),
        (
            "preset",
            base.replace("transfer = \"brain\"", "transfer = \"bran\""),
            vec!["mni152", "bran", "brain-white"],
        ),
        (
            "key",
            base.replace("transfer = \"brain\"", "transfer = \"brain\"\ndensity = 2"),
            vec!["density"],
        ),
    ] {
        let p = dir.join(format!("{name}.toml"));
        std::fs::write(&p, scene).unwrap();
        let out = dir.join(format!("{name}-out"));
        let o = run(&[
            "render",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{name}: accepted");
        for n in needles {
            assert!(err.contains(n), "{name}: {n:?} not in {err}");
        }
        assert!(
            !out.join("frame_0000.png").exists(),
            "{name}: wrote a frame"
        );
    }
    if gpu().is_none() {
        return;
    }
    let _l = gpu_lock();
    let out = dir.join("out");
    let o = run(&[
        "render",
        "terrains/brain.toml",
        "--size",
        "96x72",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let meta = read_json(&out.join("frame_0000.json"));
    assert_eq!(meta["volumes"], 1);
    assert!(
        meta["volume_pixels"].as_u64().unwrap() > 1000,
        "{}",
        meta["volume_pixels"]
    );
}

#[test]
fn a_tight_shell_changes_nothing_and_saves_segments() {
    let _l = gpu_lock();
    let (scene, terrain, vols) = demo_scene("brain.toml", 128, 96);
    let cam = scene.camera(0, &terrain);
    // The smallest axis-aligned ellipsoid around the box centre that holds every voxel the
    // transfer function makes visible (with a voxel of margin for the trilinear support).
    let v = &vols[0];
    let ext = v.extent();
    let c = ext / 2.0;
    let sp = DVec3::from(v.grid.spacing);
    let [nx, ny, nz] = v.grid.dims;
    let mut r = DVec3::ZERO;
    let visible: Vec<bool> = (0..256).map(|d| v.table.entries[d][3] > 0.0).collect();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                if visible[v.grid.voxel(x, y, z) as usize] {
                    let p = (DVec3::new(x as f64, y as f64, z as f64) + 0.5) * sp - c;
                    r = r.max(p.abs() + sp * 6.0);
                }
            }
        }
    }
    // Scale the ellipsoid with semi-axes r until it holds every visible voxel (with margin).
    let mut scale: f64 = 0.0;
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                if visible[v.grid.voxel(x, y, z) as usize] {
                    let p = (DVec3::new(x as f64, y as f64, z as f64) + 0.5) * sp - c;
                    scale = scale.max(((p.abs() + sp * 6.0) / r).length());
                }
            }
        }
    }
    let radii = r * scale;
    let shelled = Volume {
        shell: Some((c, radii)),
        ..v.clone()
    };
    let plain = VolumeSettings {
        skip: false,
        early_termination: false,
        ..v.settings
    };
    let light = VolumeLight::new(&scene.desc, &terrain);
    let Some(a) = render_variants(&terrain, &scene.desc, &cam, v, &[plain]) else {
        return;
    };
    let b = render_variants(&terrain, &scene.desc, &cam, &shelled, &[plain]).unwrap();
    let segs = |o: &FrameOutput| o.volume_segments.iter().map(|&s| s as u64).sum::<u64>();
    let d = max_diff(&a[0].rgba, &b[0].rgba);
    eprintln!(
        "shell radii {radii:.3} m in a {ext:.3} m box: segments {} -> {}, max difference {d}/255",
        segs(&a[0]),
        segs(&b[0])
    );
    assert!(
        d <= 1,
        "a shell around all visible voxels changed the image by {d}/255"
    );
    assert!(
        segs(&b[0]) * 10 < segs(&a[0]) * 9,
        "the shell saved under 10% of the segments"
    );
    // The CPU reference follows the shell too.
    let k = (48 * 128 + 64) as usize;
    let rays = {
        let g = gpu().unwrap();
        let mut rr = TerrainRenderer::new(g, &terrain).unwrap();
        rr.capture(g, &terrain, &scene.desc, &cam, &settings(true, true))
            .unwrap();
        rr.read_ray_table(g).unwrap()
    };
    let e = rays[k];
    let dir = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64);
    let with = integrate(
        &shelled,
        &light,
        cam.pose.position,
        dir,
        e[3] as f64,
        f64::INFINITY,
        [64, 48],
    );
    let without = integrate(
        v,
        &light,
        cam.pose.position,
        dir,
        e[3] as f64,
        f64::INFINITY,
        [64, 48],
    );
    assert!(
        with.segments < without.segments
            && (with.colour - without.colour).abs().max_element() < 1e-3
    );
}

#[test]
fn procedural_clouds_are_deterministic_and_validated() {
    let scene = Scene::load(&terrains().join("clouds.toml")).unwrap();
    let pv = scene.desc.volumes[0].procedural.clone().unwrap();
    let a = pv.generate("clouds", [60.0; 3]).unwrap();
    let b = pv.generate("clouds", [60.0; 3]).unwrap();
    assert!(
        a.data == b.data,
        "the same parameters gave different clouds"
    );
    let lit = a.data.iter().filter(|&&d| d > 64).count() as f64 / a.data.len() as f64;
    eprintln!("clouds: {:.1}% of voxels above density 0.25", 100.0 * lit);
    assert!(
        (0.01..0.6).contains(&lit),
        "cloud cover {lit} is degenerate"
    );
    let other = relief::volume::procedural::ProceduralVolume {
        seed: pv.seed + 1,
        ..pv.clone()
    };
    assert!(
        other.generate("clouds", [60.0; 3]).unwrap().data != a.data,
        "the seed is ignored"
    );
    for (bad, field) in [
        (
            relief::volume::procedural::ProceduralVolume {
                coverage: 1.5,
                ..pv.clone()
            },
            "coverage",
        ),
        (
            relief::volume::procedural::ProceduralVolume {
                feature: f64::NAN,
                ..pv.clone()
            },
            "feature",
        ),
        (
            relief::volume::procedural::ProceduralVolume {
                size: [1, 4, 4],
                ..pv.clone()
            },
            "grid size",
        ),
        (
            relief::volume::procedural::ProceduralVolume {
                kind: "fog".into(),
                ..pv.clone()
            },
            "kind",
        ),
    ] {
        let e = bad.generate("clouds", [60.0; 3]).unwrap_err().to_string();
        assert!(e.contains(field), "{field}: {e}");
    }
}

#[test]
fn function4d_slices_mark_the_zero_crossings_of_each_w() {
    use relief::volume::procedural::{function4d, ProceduralVolume, POLE};
    let pv = ProceduralVolume {
        kind: "function4d".into(),
        size: [40, 36, 32],
        seed: 0,
        coverage: 0.5,
        feature: 32.0,
        slices: 5,
        w_range: [0.0, 2.0],
        half_extent: 5.0,
    };
    let g = pv.generate("f4d", [1.0; 3]).unwrap();
    assert_eq!(g.slices, 5);
    let [nx, ny, nz] = g.dims;
    let mut set = [0usize; 5];
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let bits = g.voxel(x, y, z);
                assert_eq!(bits >> 5, 0, "bits beyond the slices at ({x},{y},{z})");
                for (s, count) in set.iter_mut().enumerate() {
                    let w = 2.0 * s as f64 / 4.0;
                    let at = |i: i64, j: i64, k: i64| {
                        let d = |v: i64, n: u32| -5.0 + (v as f64 + 0.5) / n as f64 * 10.0;
                        function4d(d(i, nx), d(j, ny), d(k, nz), w)
                    };
                    let (xi, yi, zi) = (x as i64, y as i64, z as i64);
                    let v = at(xi, yi, zi);
                    let crossing = [
                        (1, 0, 0),
                        (-1, 0, 0),
                        (0, 1, 0),
                        (0, -1, 0),
                        (0, 0, 1),
                        (0, 0, -1),
                    ]
                    .iter()
                    .any(|&(a, b, c)| {
                        let (i, j, k) = (xi + a, yi + b, zi + c);
                        i >= 0
                            && j >= 0
                            && k >= 0
                            && i < nx as i64
                            && j < ny as i64
                            && k < nz as i64
                            && {
                                let u = at(i, j, k);
                                u <= 0.0 && u > -POLE
                            }
                    });
                    let want = v > 0.0 && v < POLE && crossing;
                    assert_eq!(
                        bits >> s & 1 == 1,
                        want,
                        "slice {s} at ({x},{y},{z}), g = {v}"
                    );
                    *count += want as usize;
                }
            }
        }
    }
    eprintln!("surface voxels per slice: {set:?}");
    assert!(
        set.iter().all(|&n| n > 500),
        "a slice is nearly empty: {set:?}"
    );
}

#[test]
fn gpu_matches_the_cpu_reference_on_the_4d_function_slices() {
    let _l = gpu_lock();
    let (scene, terrain, vols) = demo_scene("function4d.toml", 128, 96);
    assert_eq!(vols[0].grid.slices, 8);
    let cam = scene.camera(0, &terrain);
    let light = VolumeLight::new(&scene.desc, &terrain);
    let Some((under, out, rays)) = render_pair(&terrain, &scene.desc, &cam, &vols, &[]) else {
        return;
    };
    let (cpu, undecided) = cpu_image_and_undecided(&[&vols[0]], &light, &cam, &under, &rays);
    // The mean is over every pixel; the maximum leaves out the pixels where a mask sample lies
    // within f32 precision of a face between voxels with other bits (the GPU may read either
    // voxel there: a binary mask looked up at the nearest voxel is discontinuous).
    let (mean, _, touched) = compare(&out.rgba, &cpu, &under.rgba);
    let max = (0..cpu.len())
        .filter(|&k| !undecided[k])
        .flat_map(|k| (0..3).map(move |ch| (k, ch)))
        .map(|(k, ch)| out.rgba[4 * k + ch].abs_diff(cpu[k][ch]))
        .max()
        .unwrap_or(0);
    let n_undecided = undecided.iter().filter(|&&u| u).count();
    eprintln!(
        "4-D slices: mean |GPU − CPU| {mean:.3}/255 over all pixels, max {max}/255 over {touched} volume pixels less {n_undecided} undecided at f32 precision"
    );
    // About one sample in 200 falls that close to a face between different masks here, and a
    // ray takes about 200: some 17% of the pixels. The maximum still covers over 2000 pixels.
    assert!(
        touched - n_undecided > 2000 && n_undecided * 4 <= touched,
        "{touched} volume pixels, {n_undecided} of them undecided: too few decided pixels to test"
    );
    if mean >= 1.0 || max >= 4 {
        let p = save_failure_images("function4d", 128, 96, &out.rgba, &rgba_of(&cpu));
        panic!("mean {mean:.3}/255, max {max}/255; {}", p.display());
    }
}

#[test]
fn volumes_over_the_device_limit_are_refused_with_the_limit() {
    let _l = gpu_lock();
    let Some(g) = gpu() else {
        return;
    };
    let terrain = terrain_from_fn(3, 1.0, |_, _| 0.0);
    // Where the adapter allows sides the loader already refuses (an NVIDIA H200 allows 16384,
    // over `MAX_SIDE`), the check is tested on the same device with its limit lowered to
    // 2048 (lavapipe's is 4096): the check reads the limit from `Gpu::limits`.
    let capped;
    let g = if g.limits.max_texture_dimension_3d < relief::volume::MAX_SIDE {
        g
    } else {
        let mut limits = g.limits.clone();
        limits.max_texture_dimension_3d = 2048;
        capped = relief::gpu::Gpu {
            instance: g.instance.clone(),
            device: g.device.clone(),
            queue: g.queue.clone(),
            info: g.info.clone(),
            limits,
            downlevel: g.downlevel,
            params: g.params,
            options: g.options,
            uncaught: g.uncaught.clone(),
        };
        &capped
    };
    let max = g.limits.max_texture_dimension_3d;
    assert!(max < relief::volume::MAX_SIDE);
    let n = max + 1;
    let grid = DensityGrid {
        dims: [n, 2, 2],
        data: vec![100; n as usize * 4],
        spacing: [1.0; 3],
        value_range: [0.0, 255.0],
        slices: 0,
    };
    let v = Volume::new(
        "long".into(),
        grid,
        TransferFunction::preset("grey").unwrap(),
        DVec3::ZERO,
        DMat3::IDENTITY,
        VolumeSettings::default(),
        VolumeMaterial::default(),
        None,
    );
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    let e = r
        .set_volumes(g, std::slice::from_ref(&v))
        .unwrap_err()
        .to_string();
    assert!(e.contains("long") && e.contains(&max.to_string()), "{e}");
    // Too many volumes: each is a full-screen pass per frame.
    let small = uniform_volume(4, 1.0, DVec3::ZERO, 100, 0.1, 0.5);
    let many = vec![small; relief::gpu::MAX_VOLUMES + 1];
    let e = r.set_volumes(g, &many).unwrap_err().to_string();
    assert!(
        e.contains(&format!("at most {}", relief::gpu::MAX_VOLUMES)),
        "{e}"
    );
    r.set_volumes(g, &many[..2]).expect("two volumes are fine");
}

/// Metres the ray `p + λ s` (λ ≥ 0) runs inside the box `[lo, hi]`.
fn path_in_box(p: DVec3, s: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    relief::cpu::freeform::clip_box(p, s, lo, hi, 0.0, f64::INFINITY)
        .map_or(0.0, |(a, b, _)| (b - a).max(0.0))
}

#[test]
fn volume_shadow_on_the_ground_matches_the_analytic_attenuation_of_a_dense_block() {
    // A volume turned 29° about the vertical holds a dense block (extinction sigma) inside an
    // empty border. For ground points under it and suns overhead and oblique, the sun's
    // transmittance to the ground is exp(-sigma * L), L the path through the block. Where the
    // path length is the same 1.5 voxels around (not across a shadow edge, which the grid's
    // trilinear read smears over a cell) the read must match within 0.03.
    let (n, vox) = ([32u32, 28, 12], 5.0);
    let (blo, bhi) = ([4u32, 4, 4], [28u32, 24, 8]);
    let mut data = vec![0u8; (n[0] * n[1] * n[2]) as usize];
    for z in blo[2]..bhi[2] {
        for y in blo[1]..bhi[1] {
            for x in blo[0]..bhi[0] {
                data[(x + n[0] * (y + n[1] * z)) as usize] = 200;
            }
        }
    }
    let grid = DensityGrid {
        dims: n,
        data,
        spacing: [vox; 3],
        value_range: [0.0, 255.0],
        slices: 0,
    };
    let tf = TransferFunction {
        points: vec![
            TfPoint {
                value: 0.0,
                colour: [0.0; 3],
                opacity: 0.0,
            },
            TfPoint {
                value: 255.0,
                colour: [1.0; 3],
                opacity: 0.3,
            },
        ],
        unit: None,
    };
    let rotation = DMat3::from_rotation_z(0.5);
    let corner = DVec3::new(100.0, 200.0, 60.0);
    let mut v = Volume::new(
        "block".into(),
        grid,
        tf,
        corner,
        rotation,
        VolumeSettings::default(),
        VolumeMaterial::default(),
        None,
    );
    let sigma = v.table.entries[200][3] as f64;
    assert!(
        sigma > 0.01,
        "the block is nearly transparent: sigma {sigma}"
    );
    assert!(
        v.transmittance_to_sun(corner) == 1.0,
        "no grid before set_sun"
    );
    let (lo, hi) = (
        DVec3::from(blo.map(|b| b as f64 * vox)),
        DVec3::from(bhi.map(|b| b as f64 * vox)),
    );
    for (az, el) in [
        (0.0f64, 90.0f64),
        (30.0, 60.0),
        (200.0, 40.0),
        (110.0, 25.0),
    ] {
        let (az, el) = (az.to_radians(), el.to_radians());
        let sun = DVec3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin());
        v.set_sun(sun);
        let s_local = rotation.transpose() * sun;
        let (mut strict, mut strict_shadowed, mut shadowed) = (0, 0, 0);
        let (mut worst, mut sum, mut count) = (0.0f64, 0.0, 0);
        for i in 0..200 {
            for j in 0..200 {
                let p = DVec3::new(-150.0 + 2.1 * i as f64, 50.0 + 2.1 * j as f64, 0.0);
                let q = v.to_local(p);
                let len = path_in_box(q, s_local, lo, hi);
                let want = (-sigma * len).exp();
                let got = v.transmittance_to_sun(p);
                let err = (got - want).abs();
                sum += err;
                count += 1;
                shadowed += (want < 0.9) as usize;
                let steady = steady_around(q, 1.5 * vox * std::f64::consts::SQRT_2, |x| {
                    path_in_box(x, s_local, lo, hi)
                });
                if steady {
                    strict += 1;
                    strict_shadowed += (want < 0.9) as usize;
                    worst = worst.max(err);
                }
            }
        }
        eprintln!(
            "sun az {:.0}° el {:.0}°: {shadowed} of {count} ground points shadowed; away from \
             shadow edges ({strict} points, {strict_shadowed} shadowed) worst |read − exp(−σL)| \
             {worst:.4}; mean over all {:.4}",
            az.to_degrees(),
            el.to_degrees(),
            sum / count as f64
        );
        assert!(
            strict_shadowed > 100 && strict > 5000,
            "the test misses the shadow"
        );
        assert!(worst < 0.03, "transmittance off by {worst} away from edges");
    }
}

#[test]
fn clouds_shadow_the_ground_like_the_cpu_reference_and_only_darken_it() {
    // The demo scene's cumulus layer and smoke column over the Alps: per pixel, the GPU's
    // transmittance to the sun (volume-sun pass, both volumes multiplied) against the CPU
    // reference at the GPU's own surface point; then the image under the volumes with and
    // without their shadows: identical where nothing shadows, never brighter, visibly darker
    // under the clouds.
    let _l = gpu_lock();
    let (w, h) = (200, 112);
    let (scene, terrain, vols) = demo_scene("clouds.toml", w, h);
    assert!(vols.iter().all(|v| v.sun_shadow.is_some()));
    let cam = scene.camera(0, &terrain);
    let Some(g) = gpu() else {
        return;
    };
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    r.set_volumes(g, &vols).unwrap();
    r.set_volumes_hidden(true);
    let with = r
        .capture(g, &terrain, &scene.desc, &cam, &settings(true, true))
        .unwrap();
    let rays = r.read_ray_table(g).unwrap();
    assert_eq!(with.volume_sun.len(), (w * h) as usize);
    let (mut sum, mut max, mut shadowed) = (0.0f64, 0.0f64, 0);
    for (k, e) in rays.iter().enumerate() {
        let got = with.volume_sun[k] as f64 / 255.0;
        let want = if with.depth[k].is_finite() && with.flags[k] & 1 != 0 {
            let dir = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64);
            let p = cam.pose.position + dir * with.depth[k] as f64;
            relief::cpu::volume::sun_through_volumes(&vols, p)
        } else {
            1.0
        };
        shadowed += (want < 0.8) as usize;
        sum += (got - want).abs();
        max = max.max((got - want).abs());
    }
    let mean = sum / rays.len() as f64;
    eprintln!(
        "cloud shadows: {shadowed} of {} pixels below 0.8; |GPU − CPU| mean {:.3}/255, max {:.2}/255",
        rays.len(),
        mean * 255.0,
        max * 255.0
    );
    assert!(
        shadowed > rays.len() / 50,
        "only {shadowed} pixels in cloud shadow"
    );
    // 8-bit sampler weights and the 8-bit target, rounded once per volume.
    assert!(
        mean * 255.0 < 0.5 && max * 255.0 <= 3.0,
        "GPU transmittance off the CPU reference: mean {}/255, max {}/255",
        mean * 255.0,
        max * 255.0
    );
    let mut unshadowed = vols.clone();
    for v in &mut unshadowed {
        v.sun_shadow = None;
    }
    r.set_volumes(g, &unshadowed).unwrap();
    r.set_volumes_hidden(true);
    let without = r
        .capture(g, &terrain, &scene.desc, &cam, &settings(true, true))
        .unwrap();
    assert!(without.volume_sun.is_empty());
    let (mut brighter, mut changed_unshadowed, mut darker) = (0, 0, 0);
    for k in 0..rays.len() {
        let (a, b) = (
            &with.rgba[4 * k..4 * k + 3],
            &without.rgba[4 * k..4 * k + 3],
        );
        brighter += (0..3).filter(|&c| a[c] > b[c]).count();
        if with.volume_sun[k] == 255 {
            changed_unshadowed += (a != b) as usize;
        }
        darker += (0..3).any(|c| a[c] + 10 < b[c]) as usize;
    }
    eprintln!("with vs without cloud shadows: {darker} pixels darker by > 10 levels");
    assert_eq!(brighter, 0, "cloud shadows brightened {brighter} channels");
    assert_eq!(
        changed_unshadowed, 0,
        "{changed_unshadowed} pixels outside every shadow changed"
    );
    assert!(darker > 100, "only {darker} pixels visibly shadowed");
}

/// A box of `dims` voxels of `voxel` metres, all of density 200, classified grey with
/// `opacity` per voxel, lit by default (ambient, diffuse and specular), turned `heading`
/// radians about the vertical, self-shadowed for `sun`.
fn lit_block(
    dims: [u32; 3],
    voxel: f64,
    corner: DVec3,
    heading: f64,
    opacity: f64,
    colour: [f64; 3],
    sun: DVec3,
) -> Volume {
    let grid = DensityGrid {
        dims,
        data: vec![200; (dims[0] * dims[1] * dims[2]) as usize],
        spacing: [voxel; 3],
        value_range: [0.0, 255.0],
        slices: 0,
    };
    let tf = TransferFunction {
        points: vec![
            TfPoint {
                value: 0.0,
                colour: [0.0; 3],
                opacity: 0.0,
            },
            TfPoint {
                value: 200.0,
                colour,
                opacity,
            },
        ],
        unit: None,
    };
    let mut v = Volume::new(
        "block".into(),
        grid,
        tf,
        corner,
        DMat3::from_rotation_z(heading),
        VolumeSettings {
            jitter: false,
            ..Default::default()
        },
        VolumeMaterial::default(),
        None,
    );
    v.set_sun(sun);
    v
}

/// A dense slab (turned 20°) in the sun above a box of haze, for the default sun of the
/// synthetic scenes (azimuth 135°, elevation 30°).
fn slab_over_haze(sun: DVec3) -> (Volume, Volume) {
    let slab = lit_block(
        [30, 30, 6],
        8.0,
        DVec3::new(420.0, 80.0, 200.0),
        20f64.to_radians(),
        0.3,
        [0.9, 0.9, 0.9],
        sun,
    );
    let haze = lit_block(
        [16, 16, 16],
        8.0,
        DVec3::new(300.0, 300.0, 20.0),
        0.0,
        0.04,
        [0.9, 0.5, 0.3],
        sun,
    );
    (slab, haze)
}

#[test]
fn a_volume_shadows_another_by_the_analytic_attenuation() {
    // The haze box's lit grid after `shadow_each_other`: per cell centre, the sun's
    // transmittance through the haze itself and through the slab above it, against
    // exp(-σ_h L_h - σ_s L_s) with both paths clipped analytically; within 0.03 away from the
    // slab's shadow edges (which the grids' trilinear reads smear over a cell). The slab is
    // not shadowed by the haze below it, and a ground point under both reads each volume once.
    let sun = common::synthetic_scene(8, 8, "position = [0.0, 0.0, 100.0]")
        .sun
        .direction();
    let (mut slab, mut haze) = slab_over_haze(sun);
    let shadowed = relief::volume::desc::shadow_each_other(&mut [&mut slab, &mut haze]);
    assert_eq!(
        shadowed,
        vec![false, true],
        "only the haze lies in a shadow"
    );
    let sigma = |v: &Volume| v.table.entries[200][3] as f64;
    let path = |v: &Volume, p: DVec3| {
        let s = v.rotation.transpose() * sun;
        path_in_box(v.to_local(p), s, DVec3::ZERO, v.extent())
    };
    let sh = haze.sun_shadow.as_ref().unwrap();
    let lit = sh.lit.as_ref().unwrap();
    let n = sh.dims;
    let (mut worst, mut strict, mut in_shadow, mut darkened) = (0.0f64, 0, 0, 0);
    for z in 0..n[2] {
        for y in 0..n[1] {
            for x in 0..n[0] {
                let k = (x + n[0] * (y + n[1] * z)) as usize;
                let p =
                    haze.corner + DVec3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) * 8.0;
                let ls = path(&slab, p);
                let want = (-sigma(&haze) * path(&haze, p) - sigma(&slab) * ls).exp();
                darkened += (lit[k] < sh.data[k]) as usize;
                let steady = steady_around(p, 12.0 * std::f64::consts::SQRT_2, |x| path(&slab, x));
                if steady {
                    strict += 1;
                    in_shadow += (ls > 0.0) as usize;
                    worst = worst.max((lit[k] as f64 / 255.0 - want).abs());
                }
            }
        }
    }
    eprintln!(
        "haze lit through the slab: {darkened} of {} cells darkened; away from the shadow's \
         edges ({strict} cells, {in_shadow} in the shadow) worst |grid − analytic| {worst:.4}",
        lit.len()
    );
    assert!(
        in_shadow > 200 && strict > 1000,
        "the slab's shadow misses the haze"
    );
    assert!(
        worst < 0.03,
        "lit grid off the analytic transmittance by {worst}"
    );
    // Surfaces read each volume's own grid: the product is not counted twice.
    let both = [slab.clone(), haze.clone()];
    let (mut under_both, mut worst_ground) = (0, 0.0f64);
    for i in 0..60 {
        for j in 0..60 {
            let g = DVec3::new(100.0 + 6.0 * i as f64, 250.0 + 6.0 * j as f64, 0.0);
            let (ls, lh) = (path(&slab, g), path(&haze, g));
            let steady = steady_around(g, 12.0 * std::f64::consts::SQRT_2, |x| path(&slab, x));
            if ls > 0.0 && lh > 0.0 && steady {
                under_both += 1;
                let t = relief::cpu::volume::sun_through_volumes(&both, g);
                let want = (-sigma(&haze) * lh - sigma(&slab) * ls).exp();
                worst_ground = worst_ground.max((t - want).abs());
            }
        }
    }
    eprintln!("{under_both} ground points under both: worst |read − analytic| {worst_ground:.4}");
    assert!(under_both > 50, "no ground point lies under both");
    assert!(
        worst_ground < 0.03,
        "ground under both off by {worst_ground}"
    );
}

#[test]
fn gpu_lights_a_volume_through_another_like_the_cpu_reference() {
    // The slab over the haze seen from the side: the GPU image against the CPU reference
    // (both light the haze through the slab's shadow), and the reference without that shadow
    // differs visibly, so the comparison can tell.
    let _l = gpu_lock();
    let terrain = terrain_from_fn(65, 10.0, |_, _| 0.0);
    let (desc, cam) = synthetic(160, 120, DVec3::new(100.0, 250.0, 90.0), 66.0, 4.0);
    let (mut slab, mut haze) = slab_over_haze(desc.sun.direction());
    relief::volume::desc::shadow_each_other(&mut [&mut slab, &mut haze]);
    let vols = vec![slab, haze];
    let Some((under, out, rays)) = render_pair(&terrain, &desc, &cam, &vols, &[]) else {
        return;
    };
    let light = VolumeLight::new(&desc, &terrain);
    let cpu = cpu_image(&[&vols[0], &vols[1]], &light, &cam, &under, &rays);
    let (mean, max, touched) = compare(&out.rgba, &cpu, &under.rgba);
    let mut unshadowed = vols[1].clone();
    unshadowed.sun_shadow.as_mut().unwrap().lit = None;
    let cpu_unshadowed = cpu_image(&[&vols[0], &unshadowed], &light, &cam, &under, &rays);
    let differs = cpu
        .iter()
        .zip(&cpu_unshadowed)
        .filter(|(a, b)| (0..3).any(|c| a[c].abs_diff(b[c]) > 6))
        .count();
    eprintln!(
        "slab over haze: mean |GPU − CPU| {mean:.3}/255, max {max}/255 over {touched} volume \
         pixels; {differs} pixels differ by > 6 levels without the slab's shadow on the haze"
    );
    assert!(touched > 3000, "the volumes cover only {touched} pixels");
    assert!(
        differs > 300,
        "the slab's shadow hardly shows ({differs} pixels)"
    );
    if mean >= 1.0 || max >= 4 {
        let p = save_failure_image("slab-over-haze", 160, 120, &out.rgba);
        let exp: Vec<u8> = cpu.iter().flat_map(|c| [c[0], c[1], c[2], 255]).collect();
        save_failure_image("slab-over-haze-expected", 160, 120, &exp);
        panic!("mean {mean:.3}/255, max {max}/255; {}", p.display());
    }
}

#[test]
fn volumes_are_ordered_per_pixel_by_where_their_media_lie() {
    // A long thin layer of blue haze starting close to the camera, and a red box below its
    // near end: the layer's box centre is farther than the box's, yet along every ray that
    // crosses both the layer comes first. The GPU must composite per pixel in the order the
    // media lie along the ray; the oracle orders by each box's entry along the ray (exact for
    // disjoint boxes, and independent of the weighted depth the renderer sorts by). Ordering
    // by box centre instead would be visibly wrong there, so the test can tell.
    let _l = gpu_lock();
    let terrain = terrain_from_fn(65, 10.0, |_, _| 0.0);
    let (desc, cam) = synthetic(160, 120, DVec3::new(320.0, 20.0, 60.0), 0.0, -8.0);
    let sun = desc.sun.direction();
    let layer = lit_block(
        [30, 64, 1],
        8.0,
        DVec3::new(200.0, 100.0, 34.0),
        0.0,
        0.3,
        [0.2, 0.4, 0.9],
        sun,
    );
    let small = lit_block(
        [8, 8, 4],
        8.0,
        DVec3::new(290.0, 150.0, 0.0),
        0.0,
        0.5,
        [0.9, 0.2, 0.1],
        sun,
    );
    let mut vols = vec![layer, small];
    // As the renderer does: the layer shadows the box below it.
    relief::volume::desc::shadow_each_other(&mut vols.iter_mut().collect::<Vec<_>>());
    let Some((under, out, rays)) = render_pair(&terrain, &desc, &cam, &vols, &[]) else {
        return;
    };
    let light = VolumeLight::new(&desc, &terrain);
    let eye = cam.pose.position;
    let w = cam.width;
    let (mut both, mut sum, mut max, mut wrong_by_centre) = (0, 0u64, 0u8, 0);
    for (k, e) in rays.iter().enumerate() {
        let dir = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64);
        let t_max = if under.depth[k].is_finite() {
            under.depth[k] as f64
        } else {
            f64::INFINITY
        };
        let px = [k as u32 % w, k as u32 / w];
        let mut parts: Vec<(f64, relief::cpu::volume::VolumeResult)> = vols
            .iter()
            .filter_map(|v| {
                let (o, d) = (v.to_local(eye), v.rotation.transpose() * dir);
                let (t0, _, _) = relief::cpu::volume::ray_interval(v, o, d, t_max)?;
                Some((t0, integrate(v, &light, eye, dir, e[3] as f64, t_max, px)))
            })
            .collect();
        let u = &under.rgba[4 * k..4 * k + 3];
        let bg = DVec3::from(
            [u[0], u[1], u[2]].map(|c| relief::cpu::volume::srgb_decode(c as f64 / 255.0)),
        );
        let encode = |c: DVec3| {
            [c.x, c.y, c.z].map(|v| (relief::cpu::volume::srgb_encode(v) * 255.0).round() as u8)
        };
        // Farthest box entry first.
        parts.sort_by(|a, b| b.0.total_cmp(&a.0));
        let want = encode(parts.iter().fold(bg, |c, (_, r)| r.over(c)));
        for (ch, &want_ch) in want.iter().enumerate() {
            let d = out.rgba[4 * k + ch].abs_diff(want_ch);
            sum += d as u64;
            max = max.max(d);
        }
        if parts.len() == 2 {
            both += 1;
            // Box centres: the layer (listed first) is farther, so it would go first.
            let by_centre = encode(vols.iter().fold(bg, |c, v| {
                integrate(v, &light, eye, dir, e[3] as f64, t_max, px).over(c)
            }));
            wrong_by_centre += (0..3).any(|ch| by_centre[ch].abs_diff(want[ch]) > 10) as usize;
        }
    }
    assert!(
        vols[0].world_centre().distance(eye) > vols[1].world_centre().distance(eye),
        "the layer's centre must be the farther one"
    );
    let mean = sum as f64 / (3 * rays.len()) as f64;
    eprintln!(
        "layer over a box: {both} pixels see both; |GPU − oracle| mean {mean:.3}/255, max \
         {max}/255; ordering by box centre would be off by > 10 levels in {wrong_by_centre}"
    );
    assert!(both > 500, "only {both} pixels see both volumes");
    assert!(
        wrong_by_centre > 200,
        "box-centre order would hardly differ ({wrong_by_centre}): the test cannot tell"
    );
    if mean >= 1.0 || max >= 4 {
        let p = save_failure_image("volumes-per-pixel-order", 160, 120, &out.rgba);
        panic!("mean {mean:.3}/255, max {max}/255; {}", p.display());
    }
}
