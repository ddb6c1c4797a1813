//! Coloured voxel models: `.vox` import, the segment format, the CPU hierarchical DDA against a
//! brute-force oracle, the GPU pass against the CPU, the CLI.

mod common;

use common::{gpu, gpu_lock, save_failure_image, settings, terrain_from_fn, terrains, Rng};
use glam::{DMat3, DVec3};
use relief::cpu::voxel::{brute_force, dda, VoxelScene};
use relief::gpu::TerrainRenderer;
use relief::scene::{Camera, Pose};
use relief::voxel::vox::VoxFile;
use relief::voxel::{segment, Bricks, Voxel, VoxelInstance, VoxelModel};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn vox(name: &str) -> PathBuf {
    terrains().join("voxels").join(name)
}

#[test]
fn vox_files_load_with_the_provenance_voxel_counts() {
    let deer = VoxFile::load(&vox("deer.vox")).unwrap();
    assert_eq!(deer.version, 150);
    assert_eq!(deer.models.len(), 1);
    assert_eq!(deer.models[0].size, [26, 9, 27]);
    assert_eq!(deer.model_voxel_counts(), vec![355]);
    let frames = deer.frames().unwrap();
    assert_eq!(frames.len(), 1);
    assert_eq!(frames[0].voxels.len(), 355);
    assert_eq!(frames[0].dims, [26, 9, 27]);

    let tree = VoxFile::load(&vox("tree.vox")).unwrap();
    assert_eq!(tree.version, 200);
    assert_eq!(tree.model_voxel_counts(), vec![376_133, 52_606]);
    assert!(tree.models.iter().all(|m| m.size == [256, 256, 256]));
    let t = tree.frames().unwrap();
    assert_eq!(t.len(), 1);
    eprintln!(
        "tree composed: {:?}, {} voxels",
        t[0].dims,
        t[0].voxels.len()
    );
    // Model 0 is placed twice (rotated ±90° about z), model 1 once: the union holds at least
    // the larger model and at most all three placements.
    assert!(t[0].voxels.len() >= 376_133 && t[0].voxels.len() <= 2 * 376_133 + 52_606);

    let axes = VoxFile::load(&vox("axes.vox")).unwrap();
    assert_eq!(axes.version, 200);
    assert_eq!(axes.model_voxel_counts(), vec![920, 1640, 1480, 332]);
    assert!(
        axes.nodes.len() >= 20,
        "scene graph has {} nodes",
        axes.nodes.len()
    );
    let a = axes.frames().unwrap();
    assert_eq!(a.len(), 1);
    eprintln!(
        "axes composed: {:?}, {} voxels",
        a[0].dims,
        a[0].voxels.len()
    );
    // Three arrows each built from models 0..=2 plus the centre cube (model 3), all placed by
    // the scene graph: the composed box spans the arrows' translations (±47.. ±188 voxels).
    assert!(a[0].dims.iter().all(|&d| d > 100), "{:?}", a[0].dims);
    assert!(a[0].voxels.len() > 4000);
}

#[test]
fn vox_scene_graph_applies_rotation_and_translation() {
    // Hand-built v200 file: one 2x1x1 model (x = 0 colour 1, x = 1 colour 2), placed by a
    // transform with _r = 1 + 16·0 ... : rows (0,1,0)?  Use _r 17: row0 = -y, row1 = +x.
    let mut b = Vec::new();
    let chunk = |id: &[u8; 4], content: &[u8]| {
        let mut c = id.to_vec();
        c.extend((content.len() as i32).to_le_bytes());
        c.extend(0i32.to_le_bytes());
        c.extend(content);
        c
    };
    let i = |v: i32| v.to_le_bytes().to_vec();
    let s = |t: &str| [i(t.len() as i32), t.as_bytes().to_vec()].concat();
    let mut kids = Vec::new();
    kids.extend(chunk(b"SIZE", &[i(2), i(1), i(1)].concat()));
    kids.extend(chunk(
        b"XYZI",
        &[i(2), vec![0, 0, 0, 1, 1, 0, 0, 2]].concat(),
    ));
    // nTRN 0 -> nSHP 1, frame dict {_r: "17", _t: "10 20 30"}
    kids.extend(chunk(
        b"nTRN",
        &[
            i(0),
            i(0),
            i(1),
            i(-1),
            i(0),
            i(1),
            i(2),
            s("_r"),
            s("17"),
            s("_t"),
            s("10 20 30"),
        ]
        .concat(),
    ));
    kids.extend(chunk(b"nSHP", &[i(1), i(0), i(1), i(0), i(0)].concat()));
    b.extend(b"VOX ");
    b.extend(i(200));
    b.extend(b"MAIN");
    b.extend(i(0));
    b.extend(i(kids.len() as i32));
    b.extend(&kids);
    let f = VoxFile::parse(&b, Path::new("hand.vox")).unwrap();
    let m = &f.frames().unwrap()[0];
    // Centres: x = 0 -> (-0.5, 0.5, 0.5) -> R: (-0.5, -0.5, 0.5) (row0 = -y, row1 = +x);
    // x = 1 -> (0.5, 0.5, 0.5) -> (-0.5, 0.5, 0.5): the pair now runs along +y.
    assert_eq!(m.dims, [1, 2, 1]);
    let by_y: Vec<u8> = m.voxels.iter().map(|v| v.index).collect();
    assert_eq!(m.voxels[0].pos, [0, 0, 0]);
    assert_eq!(by_y, vec![1, 2]);
    // Truncating the same bytes anywhere gives an error naming the file, never a panic.
    for cut in 0..b.len() {
        let e =
            VoxFile::parse(&b[..cut], Path::new("hand.vox")).and_then(|f| f.frames().map(|_| ()));
        match e {
            Err(e) => assert!(e.to_string().contains("hand.vox"), "{e}"),
            Ok(()) => panic!("truncated at {cut} of {} parsed", b.len()),
        }
    }
}

#[test]
fn malformed_vox_files_are_refused_without_panics() {
    let good = std::fs::read(vox("axes.vox")).unwrap();
    let p = Path::new("bad.vox");
    assert!(VoxFile::parse(b"RIFF\0\0\0\0", p)
        .unwrap_err()
        .to_string()
        .contains("does not start with \"VOX \""));
    for cut in [0, 3, 8, 20, 100, 5000, good.len() / 2, good.len() - 1] {
        let e = VoxFile::parse(&good[..cut], p).and_then(|f| f.frames().map(|_| ()));
        let msg = e.expect_err("truncated file must fail").to_string();
        assert!(msg.starts_with("bad.vox"), "{msg}");
    }
    // Random corruption: errors or a valid model, never a panic.
    let mut rng = Rng::new(7);
    for _ in 0..300 {
        let mut b = good.clone();
        for _ in 0..4 {
            let k = (rng.range(0.0, 1.0) * b.len() as f64) as usize % b.len();
            b[k] = (rng.range(0.0, 1.0) * 256.0) as u8;
        }
        let _ = VoxFile::parse(&b, p).and_then(|f| f.frames().map(|_| ()));
    }
    // A voxel outside its model's size is named.
    let mut b = std::fs::read(vox("deer.vox")).unwrap();
    let xyzi = b.windows(4).position(|w| w == b"XYZI").unwrap();
    b[xyzi + 16] = 200; // first voxel's x
    let msg = VoxFile::parse(&b, p).unwrap_err().to_string();
    assert!(msg.contains("outside"), "{msg}");
}

fn random_model(rng: &mut Rng, dims: [u32; 3], fill: f64, extra_sizes: Vec<u8>) -> VoxelModel {
    let mut voxels = Vec::new();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                if rng.range(0.0, 1.0) < fill {
                    voxels.push(Voxel {
                        pos: [x, y, z],
                        index: 1 + (rng.range(0.0, 1.0) * 254.0) as u8,
                    });
                }
            }
        }
    }
    let palette = (0..256)
        .map(|i| [i as u8, (i * 7) as u8, (255 - i) as u8, 255])
        .collect();
    let mut m = VoxelModel::new("random", dims, palette, voxels).unwrap();
    let stride: usize = extra_sizes.iter().map(|&s| s as usize).sum();
    m.extra = (0..m.voxels.len() * stride)
        .map(|_| (rng.range(0.0, 1.0) * 256.0) as u8)
        .collect();
    m.extra_sizes = extra_sizes;
    m
}

#[test]
fn segment_format_round_trips_bit_exactly_with_extra_attributes() {
    let mut rng = Rng::new(11);
    for (dims, fill, extra) in [
        ([13, 7, 29], 0.3, vec![3, 1]),
        ([1, 1, 1], 1.0, vec![]),
        ([40, 3, 70], 0.02, vec![2, 4, 1]),
        ([9, 9, 9], 0.97, vec![1]),
    ] {
        let m = random_model(&mut rng, dims, fill, extra);
        let bytes = segment::encode(&m);
        let back = segment::decode(&bytes, Path::new("rt.rvs")).unwrap();
        assert_eq!(back, m, "model differs after a round trip ({dims:?})");
        assert_eq!(segment::encode(&back), bytes, "bytes differ ({dims:?})");
    }
    // The tree: real data through a file on disk.
    let tree = VoxFile::load(&vox("tree.vox"))
        .unwrap()
        .frames()
        .unwrap()
        .remove(0);
    let dir = common::project_dir().join("target/test-output");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("tree-roundtrip.rvs");
    let n = segment::write(&tree, &path).unwrap();
    let back = segment::read(&path).unwrap();
    assert_eq!(back, tree);
    assert_eq!(std::fs::read(&path).unwrap().len() as u64, n);
    eprintln!(
        "tree: {} voxels, dense {} B, segment {n} B ({:.1}x smaller)",
        tree.voxels.len(),
        tree.dense_bytes(),
        tree.dense_bytes() as f64 / n as f64
    );
}

#[test]
fn malformed_segment_files_are_refused_without_panics() {
    let mut rng = Rng::new(5);
    let m = random_model(&mut rng, [6, 5, 20], 0.4, vec![2]);
    let good = segment::encode(&m);
    let p = Path::new("bad.rvs");
    for cut in 0..good.len() {
        let msg = segment::decode(&good[..cut], p)
            .expect_err("truncated segment file must fail")
            .to_string();
        assert!(msg.starts_with("bad.rvs"), "{msg}");
    }
    for _ in 0..2000 {
        let mut b = good.clone();
        let k = (rng.range(0.0, 1.0) * b.len() as f64) as usize % b.len();
        b[k] ^= 1 << ((rng.range(0.0, 1.0) * 8.0) as u32 % 8);
        if let Ok(back) = segment::decode(&b, p) {
            // A flip that still decodes (a palette or attribute byte) stays inside the box.
            assert!(back
                .voxels
                .iter()
                .all(|v| (0..3).all(|a| v.pos[a] < back.dims[a])));
        }
    }
    let mut b = good.clone();
    b[8] = 9; // version
    assert!(segment::decode(&b, p)
        .unwrap_err()
        .to_string()
        .contains("version 9"));
}

/// Asserts that the DDA and the brute-force slab test agree on the ray (same hit distance to
/// 1e-9, on an occupied voxel, or both miss); true on a hit.
fn dda_agrees_with_brute_force(m: &VoxelModel, b: &Bricks, o: DVec3, d: DVec3, t_min: f64) -> bool {
    match (dda(b, o, d, t_min, 1e9), brute_force(m, o, d, t_min, 1e9)) {
        (None, None) => false,
        (Some(h), Some(w)) => {
            assert!(
                (h.t - w).abs() <= 1e-9 * (1.0 + w.abs()),
                "dda t {} vs brute force {w}: o {o} d {d} t_min {t_min}",
                h.t
            );
            assert_ne!(b.get(h.voxel), 0);
            true
        }
        (g, w) => panic!("dda {g:?} vs brute force {w:?}: o {o} d {d} t_min {t_min}"),
    }
}

#[test]
fn cpu_dda_matches_brute_force_on_random_rays() {
    let mut rng = Rng::new(3);
    let mut hits = 0;
    for (dims, fill) in [([21, 17, 13], 0.05), ([8, 8, 8], 0.3), ([35, 9, 40], 0.01)] {
        let m = random_model(&mut rng, dims, fill, vec![]);
        let b = m.bricks();
        let size = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
        for k in 0..4000 {
            // Origins around and inside the box, some rays axis-aligned.
            let o = DVec3::new(
                rng.range(0.0, 1.0),
                rng.range(0.0, 1.0),
                rng.range(0.0, 1.0),
            ) * size
                * 2.0
                - size * 0.5;
            let mut d = DVec3::new(
                rng.range(0.0, 1.0) - 0.5,
                rng.range(0.0, 1.0) - 0.5,
                rng.range(0.0, 1.0) - 0.5,
            );
            if k % 10 == 0 {
                d[k / 10 % 3] = 0.0;
            }
            if d.length() < 1e-3 {
                continue;
            }
            let d = d.normalize() * (0.5 + rng.range(0.0, 1.0) * 3.0);
            let t_min = if k % 7 == 0 {
                rng.range(0.0, 1.0) * 5.0
            } else {
                0.0
            };
            hits += dda_agrees_with_brute_force(&m, &b, o, d, t_min) as usize;
        }
    }
    assert!(hits > 1000, "only {hits} rays hit");
}

fn camera(position: DVec3, heading: f64, pitch: f64, w: u32, h: u32) -> Camera {
    Camera::new(
        Pose {
            position,
            heading,
            pitch,
            roll: 0.0,
            fov: 60.0,
        },
        w,
        h,
    )
}

fn instance(file: &str, pos: DVec3, heading: f64, voxel_size: f64) -> VoxelInstance {
    let frames = relief::voxel::desc::load_frames(&vox(file)).unwrap();
    let (r, d, f) = relief::geom::attitude_basis(heading, 0.0, 0.0);
    VoxelInstance::new(
        file,
        frames.into_iter().map(Arc::new).collect(),
        DMat3::from_cols(r, f, -d),
        pos,
        voxel_size,
    )
}

#[test]
fn gpu_voxel_depth_matches_the_cpu_dda() {
    let _l = gpu_lock();
    let terrain = terrain_from_fn(65, 10.0, |x, y| 0.02 * x + 0.01 * y);
    let ground = |x: f64, y: f64| 0.02 * x + 0.01 * y;
    let models = vec![
        instance(
            "deer.vox",
            DVec3::new(300.0, 330.0, ground(300.0, 330.0)),
            30.0,
            0.6,
        ),
        instance(
            "axes.vox",
            DVec3::new(345.0, 360.0, ground(345.0, 360.0)),
            -20.0,
            0.12,
        ),
        instance(
            "tree.vox",
            DVec3::new(270.0, 370.0, ground(270.0, 370.0)),
            0.0,
            0.1,
        ),
    ];
    let scene = VoxelScene::new(models.clone());
    let (w, h) = (240u32, 160u32);
    let cam = camera(DVec3::new(310.0, 290.0, 16.0), 0.0, -12.0, w, h);
    // Both kinds of draw run: a rectangle of one model (`fs_voxels_one`) and one of several.
    let rects =
        relief::cpu::voxel::primary_rects(&models, &relief::cpu::voxel::cover_boxes(&models), &cam);
    let ones = rects
        .iter()
        .filter(|r| r.instances.count_ones() == 1)
        .count();
    assert!(ones > 0 && ones < rects.len(), "{rects:?}");
    let Some(g) = gpu() else {
        return;
    };
    let mut desc = common::synthetic_scene(w, h, "position = [0.0, 0.0, 100.0]");
    desc.sun.azimuth = 120.0;
    desc.sun.elevation = 35.0;
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    r.set_voxels(g, &models).unwrap();
    let out = r
        .capture(g, &terrain, &desc, &cam, &settings(true, true))
        .unwrap();
    let mut agree = 0;
    let mut voxel_pixels = 0;
    let mut gpu_voxel = 0;
    for k in 0..(w * h) as usize {
        let d = cam.pixel_ray(k as u32 % w, k as u32 / w);
        let o = cam.pose.position;
        let ter = relief::cpu::query::cast_ray(&terrain, o, d, 0.0, f64::INFINITY).map(|h| h.t);
        let vx = scene.cast(o, d, 0.0, ter.unwrap_or(f64::INFINITY), 0.0);
        let is_vox = out.flags[k] & 32 != 0;
        gpu_voxel += is_vox as usize;
        let ok = match (vx, ter) {
            (Some(v), _) => {
                voxel_pixels += 1;
                is_vox && ((out.depth[k] as f64 - v.t) / v.t).abs() <= 1e-3
            }
            (None, Some(t)) => !is_vox && ((out.depth[k] as f64 - t) / t).abs() <= 1e-3,
            (None, None) => !out.depth[k].is_finite(),
        };
        agree += ok as usize;
    }
    let n = (w * h) as usize;
    let frac = agree as f64 / n as f64;
    eprintln!(
        "{agree}/{n} pixels agree ({:.3}%), {voxel_pixels} CPU voxel pixels, {gpu_voxel} GPU",
        100.0 * frac
    );
    assert!(
        voxel_pixels > 2000,
        "only {voxel_pixels} voxel pixels in view"
    );
    let shadowed = (0..n)
        .filter(|&k| out.flags[k] & 32 == 0 && out.flags[k] & 2 != 0)
        .count();
    assert!(
        shadowed > 100,
        "voxel models cast only {shadowed} shadow pixels"
    );
    if frac < 0.995 {
        let p = save_failure_image("voxels", w, h, &out.rgba);
        panic!(
            "only {:.3}% of pixels agree with the CPU DDA; image {}",
            100.0 * frac,
            p.display()
        );
    }
}

#[test]
fn gpu_voxel_shadows_fall_where_the_cpu_says() {
    let _l = gpu_lock();
    let terrain = terrain_from_fn(65, 10.0, |_, _| 0.0);
    let models = vec![instance(
        "deer.vox",
        DVec3::new(320.0, 330.0, 0.0),
        0.0,
        0.8,
    )];
    let scene = VoxelScene::new(models.clone());
    let (w, h) = (160u32, 120u32);
    let cam = camera(DVec3::new(320.0, 270.0, 40.0), 0.0, -35.0, w, h);
    let Some(g) = gpu() else {
        return;
    };
    let mut desc = common::synthetic_scene(w, h, "position = [0.0, 0.0, 100.0]");
    desc.sun.azimuth = 250.0;
    desc.sun.elevation = 30.0;
    let sun = desc.sun.direction();
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    r.set_voxels(g, &models).unwrap();
    let out = r
        .capture(g, &terrain, &desc, &cam, &settings(true, true))
        .unwrap();
    let (mut agree, mut cpu_shadow, mut n) = (0, 0, 0);
    for k in 0..(w * h) as usize {
        if out.flags[k] & 33 != 1 {
            continue; // terrain pixels only
        }
        let d = cam.pixel_ray(k as u32 % w, k as u32 / w);
        let p = cam.pose.position + d * out.depth[k] as f64;
        let blocked = !scene.clear(p, sun, 0.0);
        cpu_shadow += blocked as usize;
        n += 1;
        agree += (blocked == (out.flags[k] & 2 != 0)) as usize;
    }
    eprintln!("{agree}/{n} terrain pixels agree on voxel shadow ({cpu_shadow} shadowed)");
    assert!(
        cpu_shadow > 50,
        "the deer casts only {cpu_shadow} shadow pixels"
    );
    assert!(agree as f64 >= 0.995 * n as f64, "{agree}/{n}");
}

#[test]
fn oversize_voxel_models_are_refused_with_the_limit() {
    let _l = gpu_lock();
    let Some(g) = gpu() else {
        return;
    };
    let limit = g
        .limits
        .max_storage_buffer_binding_size
        .min(g.limits.max_buffer_size);
    // One voxel in a 4096³ box: its brick table alone is 512³ entries (512 MiB).
    let side = relief::voxel::MAX_SIDE;
    let table = (side as u64 / 8).pow(3) * 4;
    if table <= limit {
        eprintln!(
            "Skipping: the adapter allows {limit} bytes per storage buffer, more than {table}"
        );
        return;
    }
    let palette = vec![[200u8, 100, 50, 255]; 256];
    let one = vec![Voxel {
        pos: [5, 6, 7],
        index: 1,
    }];
    let m = VoxelModel::new("huge", [side; 3], palette, one).unwrap();
    let inst = VoxelInstance::new("big", vec![Arc::new(m)], DMat3::IDENTITY, DVec3::ZERO, 1.0);
    let terrain = terrain_from_fn(9, 10.0, |_, _| 0.0);
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    let msg = r.set_voxels(g, &[inst]).unwrap_err().to_string();
    assert!(
        msg.contains("voxel brick tables") && msg.contains(&limit.to_string()),
        "{msg}"
    );
}

#[test]
fn cli_converts_a_vox_file_and_renders_the_tree_demo() {
    let _l = gpu_lock();
    let bin = env!("CARGO_BIN_EXE_relief");
    let dir = common::project_dir().join("target/test-output/voxels-cli");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = std::process::Command::new(bin)
        .args(["voxels", "convert"])
        .arg(vox("deer.vox"))
        .arg(dir.join("deer.rvs"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("355 voxels") && text.contains("dense"),
        "{text}"
    );
    let back = segment::read(&dir.join("deer.rvs")).unwrap();
    assert_eq!(back.voxels.len(), 355);
    // A malformed input fails with the file named and leaves no output.
    std::fs::write(dir.join("bad.vox"), b"VOX \x96\0\0\0MAIN").unwrap();
    let out = std::process::Command::new(bin)
        .args(["voxels", "convert"])
        .arg(dir.join("bad.vox"))
        .arg(dir.join("bad.rvs"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.vox"));
    assert!(!dir.join("bad.rvs").exists());
    if gpu().is_none() {
        return;
    }
    let out = std::process::Command::new(bin)
        .arg("render")
        .arg(terrains().join("tree.toml"))
        .args(["--size", "160x90", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (w, h, depth) = relief::app::output::read_depth_tiff(&dir.join("depth_0000.tiff")).unwrap();
    assert_eq!((w, h), (160, 90));
    // The tree stands 30 m ahead of the camera in the middle of the image.
    let centre = depth[(45 * 160 + 80) as usize];
    assert!((25.0..40.0).contains(&centre), "centre depth {centre}");
}

#[test]
fn animated_models_show_the_frame_of_the_scene_time_on_gpu_and_cpu() {
    let _l = gpu_lock();
    // Two frames of a 12x12x16 model: a pillar that moves from one corner to the opposite.
    let mut palette = vec![[0u8, 0, 0, 255]; 256];
    palette[1] = [200, 60, 40, 255];
    let pillar = |x0: u32, y0: u32| {
        let mut v = Vec::new();
        for z in 0..16 {
            for y in y0..y0 + 4 {
                for x in x0..x0 + 4 {
                    v.push(Voxel {
                        pos: [x, y, z],
                        index: 1,
                    });
                }
            }
        }
        Arc::new(VoxelModel::new("pillar", [12, 12, 16], palette.clone(), v).unwrap())
    };
    let frames = vec![pillar(0, 0), pillar(8, 8)];
    let mut inst = VoxelInstance::new(
        "pillar",
        frames,
        DMat3::IDENTITY,
        DVec3::new(320.0, 330.0, 0.0),
        2.0,
    );
    inst.fps = 10.0;
    let terrain = terrain_from_fn(65, 10.0, |_, _| 0.0);
    let scene = VoxelScene::new(vec![inst.clone()]);
    let (w, h) = (120u32, 90u32);
    let cam = camera(DVec3::new(320.0, 270.0, 20.0), 0.0, -5.0, w, h);
    let Some(g) = gpu() else {
        return;
    };
    let desc = common::synthetic_scene(w, h, "position = [0.0, 0.0, 100.0]");
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    r.set_voxels(g, &[inst]).unwrap();
    let mut masks = Vec::new();
    for time in [0.0, 0.15, 0.25] {
        r.set_time(time);
        let out = r
            .capture(g, &terrain, &desc, &cam, &settings(false, true))
            .unwrap();
        let mut agree = 0;
        for k in 0..(w * h) as usize {
            let d = cam.pixel_ray(k as u32 % w, k as u32 / w);
            let vx = scene.cast(cam.pose.position, d, 0.0, f64::INFINITY, time);
            let is_vox = out.flags[k] & 32 != 0;
            agree += match vx {
                Some(v) => is_vox && ((out.depth[k] as f64 - v.t) / v.t).abs() <= 1e-3,
                None => !is_vox,
            } as usize;
        }
        let frac = agree as f64 / (w * h) as f64;
        eprintln!(
            "t = {time} s (frame {}): {:.2}% of pixels agree",
            (time * 10.0) as u32 % 2,
            100.0 * frac
        );
        assert!(
            frac >= 0.995,
            "t = {time}: only {:.2}% agree with the CPU",
            100.0 * frac
        );
        masks.push(out.flags.iter().map(|f| f & 32 != 0).collect::<Vec<bool>>());
    }
    assert!(masks[0] != masks[1], "frame 1 looks like frame 0");
    assert!(
        masks[0] == masks[2],
        "t = 0.25 s (frame 0 again at 10 fps) differs from t = 0"
    );
}

#[test]
fn chebyshev_distances_match_brute_force_and_bound_empty_cubes() {
    use relief::voxel::skip::chebyshev;
    let mut rng = Rng::new(11);
    for (dims, fill, cap) in [
        ([13, 7, 9], 0.02, 8u8),
        ([20, 3, 17], 0.005, 5),
        ([6, 6, 6], 0.0, 4),
    ] {
        let n = dims[0] * dims[1] * dims[2];
        let occ: Vec<bool> = (0..n).map(|_| rng.range(0.0, 1.0) < fill).collect();
        let got = chebyshev(dims, &occ, cap);
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let mut want = cap as usize;
                    for (i, _) in occ.iter().enumerate().filter(|(_, &o)| o) {
                        let q = [
                            i % dims[0],
                            (i / dims[0]) % dims[1],
                            i / (dims[0] * dims[1]),
                        ];
                        let d = q[0].abs_diff(x).max(q[1].abs_diff(y)).max(q[2].abs_diff(z));
                        want = want.min(d);
                    }
                    let k = x + dims[0] * (y + dims[1] * z);
                    assert_eq!(got[k] as usize, want, "cell {x},{y},{z} of {dims:?}");
                }
            }
        }
    }
}

#[test]
fn octant_cubes_are_the_largest_empty_cubes_ahead() {
    use relief::voxel::skip::octant_cubes;
    let mut rng = Rng::new(17);
    let mut wide = 0;
    for (dims, fill, cap) in [
        ([11, 7, 9], 0.03, 15u8),
        ([16, 3, 13], 0.01, 5),
        ([5, 6, 4], 0.0, 15),
        ([9, 9, 9], 0.3, 15),
        // The largest cap (one byte): cubes that run out of the grid reach it.
        ([7, 5, 6], 0.02, 255),
    ] {
        let n = dims[0] * dims[1] * dims[2];
        let occ: Vec<bool> = (0..n).map(|_| rng.range(0.0, 1.0) < fill).collect();
        let at = |p: [i64; 3]| -> bool {
            // Beyond the grid counts as empty.
            (0..3).all(|a| p[a] >= 0 && p[a] < dims[a] as i64)
                && occ[p[0] as usize + dims[0] * (p[1] as usize + dims[1] * p[2] as usize)]
        };
        for oct in 0..8 {
            let got = octant_cubes(dims, &occ, oct, cap);
            assert_eq!(got.len(), n, "one cube a cell");
            let sign: [i64; 3] = std::array::from_fn(|a| if oct >> a & 1 != 0 { 1 } else { -1 });
            for (k, &got) in got.iter().enumerate() {
                let c = [
                    (k % dims[0]) as i64,
                    ((k / dims[0]) % dims[1]) as i64,
                    (k / (dims[0] * dims[1])) as i64,
                ];
                // Brute force: the largest side s <= cap whose cube from c towards the octant
                // holds no occupied cell.
                let empty = |s: i64| {
                    (0..s).all(|i| {
                        (0..s).all(|j| {
                            (0..s).all(|l| {
                                !at([c[0] + sign[0] * i, c[1] + sign[1] * j, c[2] + sign[2] * l])
                            })
                        })
                    })
                };
                // Once a cube reaches past the grid along every axis, larger ones add only
                // cells beyond it (empty): the cap.
                let beyond = (0..3)
                    .map(|a| {
                        if sign[a] > 0 {
                            dims[a] as i64 - c[a]
                        } else {
                            c[a] + 1
                        }
                    })
                    .max()
                    .unwrap();
                let want = match (1..=beyond.min(cap as i64))
                    .take_while(|&s| empty(s))
                    .last()
                {
                    Some(s) if s == beyond => cap as i64,
                    Some(s) => s,
                    None => 0,
                };
                assert_eq!(got as i64, want, "cell {c:?}, octant {oct}, grid {dims:?}");
                wide += (want > 1) as usize;
            }
        }
    }
    eprintln!("{wide} cubes wider than one cell");
    assert!(wide > 1000, "only {wide} cubes wider than one cell");
}

/// A sparse model of a few solid blobs in a large box, so that the DDA jumps at both levels.
fn blob_model(rng: &mut Rng, dims: [u32; 3], blobs: usize) -> VoxelModel {
    let palette = vec![[90u8, 160, 60, 255]; 256];
    let mut voxels = Vec::new();
    for _ in 0..blobs {
        let c: [u32; 3] = std::array::from_fn(|a| rng.range(0.0, dims[a] as f64 - 1.0) as u32);
        let r = 1 + rng.range(0.0, 4.0) as u32;
        for z in c[2].saturating_sub(r)..(c[2] + r).min(dims[2]) {
            for y in c[1].saturating_sub(r)..(c[1] + r).min(dims[1]) {
                for x in c[0].saturating_sub(r)..(c[0] + r).min(dims[0]) {
                    if rng.range(0.0, 1.0) < 0.7 {
                        voxels.push(Voxel {
                            pos: [x, y, z],
                            index: 1 + (x % 200) as u8,
                        });
                    }
                }
            }
        }
    }
    VoxelModel::new("blobs", dims, palette, voxels).unwrap()
}

#[test]
fn brick_gaps_bound_the_distance_to_the_nearest_voxel() {
    let mut rng = Rng::new(23);
    let mut refined = 0;
    let mut one_sided = 0;
    let mut empty = 0;
    for dims in [[45u32, 37, 52], [70, 20, 24]] {
        let m = blob_model(&mut rng, dims, 6);
        let b = m.bricks();
        let bd = b.brick_dims;
        let symmetric = relief::voxel::skip::brick_gaps(bd, &b.table, &b.pool, &b.brick_skip);
        for bz in 0..bd[2] {
            for by in 0..bd[1] {
                for bx in 0..bd[0] {
                    let c = [bx, by, bz];
                    let gap = symmetric[(bx + bd[0] * (by + bd[1] * bz)) as usize] as i64;
                    let s = b.brick_skip(c) as i64;
                    if b.brick(c) != relief::voxel::EMPTY_BRICK {
                        assert_eq!(gap, 0, "occupied brick {c:?}");
                        assert!(
                            (0..8).all(|o| b.brick_gap(c, o) == 0),
                            "occupied brick {c:?}"
                        );
                        continue;
                    }
                    empty += 1;
                    // L∞ distance in voxels from the brick's box to the nearest voxel.
                    let nearest = m
                        .voxels
                        .iter()
                        .map(|v| {
                            (0..3)
                                .map(|a| {
                                    let (lo, p) = (c[a] as i64 * 8, v.pos[a] as i64);
                                    (lo - p).max(p - (lo + 7)).max(0)
                                })
                                .max()
                                .unwrap()
                        })
                        .min()
                        .unwrap_or(i64::MAX);
                    assert!(
                        gap >= 1 && gap <= nearest,
                        "brick {c:?}: gap {gap}, nearest voxel {nearest} voxels away"
                    );
                    assert!(
                        gap > 8 * (s - 1),
                        "brick {c:?}: gap {gap} below its brick distance {s}"
                    );
                    refined += (gap > 8 * (s - 1) + 1) as usize;
                    // Towards each octant: never below the symmetric gap, and the box grown
                    // that far towards the octant holds no voxel.
                    for o in 0..8 {
                        let g = b.brick_gap(c, o) as i64;
                        assert!(g >= gap, "brick {c:?}, octant {o}: {g} below {gap}");
                        let inside = |v: &Voxel| {
                            (0..3).all(|a| {
                                let lo = c[a] as i64 * 8;
                                let p = v.pos[a] as i64;
                                if o >> a & 1 != 0 {
                                    p >= lo && p < lo + 8 + g - 1
                                } else {
                                    p > lo - g && p < lo + 8
                                }
                            })
                        };
                        if let Some(v) = m.voxels.iter().find(|v| inside(v)) {
                            panic!("brick {c:?}, octant {o}: gap {g} reaches voxel {:?}", v.pos);
                        }
                        one_sided += (g > gap) as usize;
                    }
                }
            }
        }
    }
    eprintln!(
        "{refined} of {empty} empty bricks jump further than their brick distance allows; {one_sided} of {} brick octants further than the symmetric gap",
        8 * empty
    );
    assert!(refined > 20, "only {refined} bricks refined");
    assert!(
        one_sided > 100,
        "only {one_sided} brick octants reach further"
    );
}

#[test]
fn cpu_dda_with_empty_space_jumps_matches_brute_force() {
    let mut rng = Rng::new(5);
    let mut hits = 0;
    let (mut brick_jumps, mut voxel_jumps) = (0, 0);
    for dims in [[97u32, 64, 80], [40, 130, 33]] {
        let m = blob_model(&mut rng, dims, 12);
        let b = m.bricks();
        brick_jumps += b
            .brick_gap
            .iter()
            .filter(|g| g.iter().any(|&g| g > 1))
            .count();
        // Pool voxels whose cube ahead of them is wider than one voxel in some octant.
        voxel_jumps += b
            .pool_jump
            .iter()
            .filter(|&&w| (0..8).any(|o| relief::voxel::jump_side(w, o) > 1))
            .count();
        let size = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
        for k in 0..3000 {
            let o = DVec3::new(
                rng.range(-0.3, 1.3),
                rng.range(-0.3, 1.3),
                rng.range(-0.3, 1.3),
            ) * size;
            let mut d = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            if k % 2 == 0 {
                // Towards a voxel, so that many rays hit after jumps.
                let v = m.voxels
                    [(rng.range(0.0, 1.0) * m.voxels.len() as f64) as usize % m.voxels.len()];
                let c = DVec3::new(v.pos[0] as f64, v.pos[1] as f64, v.pos[2] as f64) + 0.5;
                d = c + DVec3::new(
                    rng.range(-2.0, 2.0),
                    rng.range(-2.0, 2.0),
                    rng.range(-2.0, 2.0),
                ) - o;
            }
            if k % 9 == 0 {
                d[k / 9 % 3] = 0.0;
            }
            if d.length() < 1e-3 {
                continue;
            }
            let d = d.normalize() * rng.range(0.3, 2.0);
            hits += dda_agrees_with_brute_force(&m, &b, o, d, 0.0) as usize;
        }
    }
    eprintln!(
        "{hits} hits; {brick_jumps} bricks and {voxel_jumps} pool voxels jump more than one cell"
    );
    assert!(hits > 1500, "only {hits} rays hit");
    assert!(
        brick_jumps > 100 && voxel_jumps > 1000,
        "too few jumps to test them"
    );
}

#[test]
fn screen_rectangles_hold_every_pixel_a_model_or_its_shadow_can_reach() {
    use relief::cpu::voxel::{cover_boxes, primary_rects, shadow_rects, InstanceRect};
    let terrain = terrain_from_fn(65, 10.0, |x, y| 0.02 * x + 0.01 * y);
    let models = vec![
        instance("deer.vox", DVec3::new(300.0, 330.0, 8.0), 30.0, 0.6),
        instance("axes.vox", DVec3::new(345.0, 360.0, 9.0), -20.0, 0.12),
    ];
    // Each model alone: a pixel it reaches must lie in a rectangle drawn for it.
    let alone: Vec<VoxelScene> = models
        .iter()
        .map(|m| VoxelScene::new(vec![m.clone()]))
        .collect();
    let sun = DVec3::new(0.4, -0.5, 0.6).normalize();
    let floor = terrain.lowest_z() - 1.0;
    let (w, h) = (200u32, 130u32);
    let mut tested = 0;
    let mut single = 0;
    let mut tighter = 0;
    for (pos, heading, pitch) in [
        (DVec3::new(310.0, 290.0, 16.0), 0.0, -12.0),
        (DVec3::new(250.0, 300.0, 30.0), 60.0, -25.0),
        // The eye inside the deer's box: the whole image.
        (DVec3::new(300.0, 330.0, 12.0), 10.0, 0.0),
    ] {
        let cam = camera(pos, heading, pitch, w, h);
        let boxes = cover_boxes(&models);
        let prim = primary_rects(&models, &boxes, &cam);
        let shad = shadow_rects(&models, &boxes, &cam, sun, floor);
        let drawn_for = |rs: &[InstanceRect], k: usize, x, y| {
            rs.iter()
                .any(|r| r.rect.contains(x, y) && r.instances & (1 << k) != 0)
        };
        for rs in [&prim, &shad] {
            for (i, a) in rs.iter().enumerate() {
                let a = a.rect;
                assert!(
                    rs[i + 1..]
                        .iter()
                        .map(|b| b.rect)
                        .all(|b| !(a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1)),
                    "{rs:?} overlap"
                );
            }
            single += rs.iter().filter(|r| r.instances.count_ones() == 1).count();
        }
        for y in 0..h {
            for x in 0..w {
                let d = cam.pixel_ray(x, y);
                let o = cam.pose.position;
                let t =
                    relief::cpu::query::cast_ray(&terrain, o, d, 0.0, f64::INFINITY).map(|h| h.t);
                for (k, scene) in alone.iter().enumerate() {
                    if scene.cast(o, d, 0.0, f64::INFINITY, 0.0).is_some() {
                        tested += 1;
                        assert!(
                            drawn_for(&prim, k, x, y),
                            "model {k}'s pixel {x},{y} outside {prim:?}"
                        );
                    }
                    if let Some(t) = t {
                        if !scene.clear(o + d * t, sun, 0.0) {
                            tested += 1;
                            assert!(
                                drawn_for(&shad, k, x, y),
                                "pixel {x},{y} shadowed by model {k} outside {shad:?}"
                            );
                        }
                    }
                }
            }
        }
        let area: u64 = prim.iter().map(|r| r.rect.area()).sum();
        // The same from the whole model boxes: the occupied slabs are never looser.
        let whole: Vec<Vec<[DVec3; 2]>> = models
            .iter()
            .map(|m| {
                let d = m.dims();
                vec![[
                    DVec3::ZERO,
                    DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64),
                ]]
            })
            .collect();
        let box_area: u64 = primary_rects(&models, &whole, &cam)
            .iter()
            .map(|r| r.rect.area())
            .sum();
        assert!(
            area <= box_area,
            "{area} px from slabs, {box_area} from boxes"
        );
        tighter += (area < box_area) as usize;
        eprintln!("camera at {pos}: primary rects {prim:?} ({area} px, {box_area} from the boxes), shadow rects {shad:?}");
    }
    assert!(tested > 2000, "only {tested} pixels reached");
    // The separate rectangles of one model each (not everything merged into one) occur.
    assert!(single > 0, "every rectangle was drawn for both models");
    assert!(
        tighter > 0,
        "the occupied slabs never gave smaller rectangles than the boxes"
    );
}

#[test]
fn a_herd_beyond_the_partition_limit_is_merged_and_still_covered() {
    use relief::cpu::voxel::{cover_boxes, primary_rects, COVER_SLABS, PARTITION_LIMIT};
    // 20 deer in a loose herd: more rectangles than the partition takes.
    let models: Vec<VoxelInstance> = (0..20)
        .map(|k| {
            let (x, y) = ((k % 5) as f64, (k / 5) as f64);
            instance(
                "deer.vox",
                DVec3::new(300.0 + 7.0 * x + 2.0 * y, 330.0 + 9.0 * y, 8.0),
                17.0 * k as f64,
                0.3,
            )
        })
        .collect();
    let boxes = cover_boxes(&models);
    let rects: usize = boxes.iter().map(|b| b.len()).sum();
    assert!(rects > PARTITION_LIMIT, "{rects} rectangles");
    assert!(boxes.iter().all(|b| b.len() <= COVER_SLABS as usize));
    let (w, h) = (96u32, 64u32);
    let cam = camera(DVec3::new(310.0, 290.0, 16.0), 0.0, -12.0, w, h);
    let drawn = primary_rects(&models, &boxes, &cam);
    assert!(
        drawn.len() <= models.len(),
        "{} merged rectangles",
        drawn.len()
    );
    let mut reached = 0;
    for (k, m) in models.iter().enumerate() {
        let scene = VoxelScene::new(vec![m.clone()]);
        for y in 0..h {
            for x in 0..w {
                let d = cam.pixel_ray(x, y);
                if scene
                    .cast(cam.pose.position, d, 0.0, f64::INFINITY, 0.0)
                    .is_some()
                {
                    reached += 1;
                    assert!(
                        drawn
                            .iter()
                            .any(|r| r.rect.contains(x, y) && r.instances & (1 << k) != 0),
                        "deer {k}'s pixel {x},{y} outside {drawn:?}"
                    );
                }
            }
        }
    }
    assert!(reached > 500, "only {reached} pixels reached");
}

#[test]
fn partitioned_rectangles_cover_the_union_once_with_the_exact_models() {
    use relief::cpu::voxel::{partition_rects, InstanceRect, PixelRect};
    let mut rng = Rng::new(31);
    let (w, h) = (64u32, 48u32);
    let mut pieces = 0;
    for round in 0..40 {
        let n = 1 + round % 6;
        let own: Vec<InstanceRect> = (0..n)
            .map(|k| {
                let x0 = rng.range(0.0, w as f64 - 1.0) as u32;
                let y0 = rng.range(0.0, h as f64 - 1.0) as u32;
                InstanceRect {
                    rect: PixelRect {
                        x0,
                        y0,
                        x1: (x0 + 1 + rng.range(0.0, 30.0) as u32).min(w),
                        y1: (y0 + 1 + rng.range(0.0, 30.0) as u32).min(h),
                    },
                    instances: 1 << k,
                }
            })
            .collect();
        let parts = partition_rects(&own);
        pieces += parts.len();
        for y in 0..h {
            for x in 0..w {
                let want = own
                    .iter()
                    .filter(|r| r.rect.contains(x, y))
                    .fold(0u64, |m, r| m | r.instances);
                let drawn: Vec<u64> = parts
                    .iter()
                    .filter(|r| r.rect.contains(x, y))
                    .map(|r| r.instances)
                    .collect();
                if want == 0 {
                    assert!(
                        drawn.is_empty(),
                        "pixel {x},{y} outside every rectangle drawn"
                    );
                } else {
                    assert_eq!(drawn, vec![want], "pixel {x},{y}: {own:?} -> {parts:?}");
                }
            }
        }
    }
    eprintln!("{pieces} pieces over 40 sets of 1-6 rectangles");
}

#[test]
fn gpu_voxel_depth_through_a_distortion_table_matches_the_cpu_dda() {
    use relief::display::screen_points::screen_points;
    use relief::display::DisplayConfig;
    let _l = gpu_lock();
    let cfg =
        DisplayConfig::load(&common::project_dir().join("distortion/dome-fisheye.toml")).unwrap();
    let mut p = cfg.channels[0].projector;
    p.width = 160;
    p.height = 160;
    let points = screen_points(&cfg.screen, &p);
    let terrain = terrain_from_fn(65, 10.0, |_, _| 0.0);
    let models = vec![
        instance("deer.vox", DVec3::new(318.0, 322.0, 0.0), 200.0, 0.15),
        instance("tree.vox", DVec3::new(326.0, 330.0, 0.0), 0.0, 0.05),
    ];
    let scene = VoxelScene::new(models.clone());
    let Some(g) = gpu() else {
        return;
    };
    let cam = camera(DVec3::new(320.0, 320.0, 1.5), 40.0, 0.0, p.width, p.height);
    let desc = common::synthetic_scene(p.width, p.height, "position = [0.0, 0.0, 100.0]");
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    r.set_display(g, &points, DVec3::from(cfg.eye.position))
        .unwrap();
    r.set_voxels(g, &models).unwrap();
    let out = r
        .capture(g, &terrain, &desc, &cam, &settings(false, true))
        .unwrap();
    let table = r.read_ray_table(g).unwrap();
    let (mut agree, mut n, mut voxel_pixels) = (0, 0, 0);
    for (k, e) in table.iter().enumerate() {
        if e[3] < 0.0 {
            continue; // no screen here
        }
        n += 1;
        let d = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64).normalize();
        let o = cam.pose.position;
        let ter = relief::cpu::query::cast_ray(&terrain, o, d, 0.0, f64::INFINITY).map(|h| h.t);
        let vx = scene.cast(o, d, 0.0, ter.unwrap_or(f64::INFINITY), 0.0);
        let is_vox = out.flags[k] & 32 != 0;
        agree += match vx {
            Some(v) => {
                voxel_pixels += 1;
                is_vox && ((out.depth[k] as f64 - v.t) / v.t).abs() <= 1e-3
            }
            None => !is_vox,
        } as usize;
    }
    eprintln!("{agree}/{n} dome pixels agree, {voxel_pixels} CPU voxel pixels");
    assert!(
        voxel_pixels > 1000,
        "only {voxel_pixels} voxel pixels on the dome"
    );
    if (agree as f64) < 0.995 * n as f64 {
        let p = save_failure_image("voxels-dome", p.width, p.height, &out.rgba);
        panic!(
            "only {agree}/{n} pixels agree with the CPU DDA; image {}",
            p.display()
        );
    }
}
