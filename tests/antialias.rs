//! Edge anti-aliasing (`[render] antialias`) against relief's own 16-rays-per-pixel reference
//! (`antialias = "reference"`: 4x4 rays inside every pixel, resolved in linear light): the
//! p99 error and the temporal excess (`relief::app::quality`) on the alps path, the airfield
//! and a dome channel; what must not change (interior pixels, the warp test pattern, depth and
//! ids); and what the frame JSON reports.

mod common;

use relief::app::capture;
use relief::app::quality::{self, render_all, render_job, Quality, QualityRow};
use relief::colour::{linear_to_srgb8, srgb_to_linear};
use relief::gpu::{Antialias, FrameOutput};
use std::ops::Range;

const EDGES: Antialias = Antialias::EDGES;

/// The figures of `words`' run, 10 frames in motion, off and with edges.
fn measure(words: &[&str]) -> Option<(QualityRow, QualityRow)> {
    common::gpu()?;
    let _lock = common::gpu_lock();
    let job = render_job(words).unwrap();
    let Quality {
        rows,
        reference_change,
    } = quality::measure(&job, 10, &[Antialias::OFF, EDGES]).unwrap();
    let (off, edges) = (rows[0].clone(), rows[1].clone());
    eprintln!(
        "{words:?}: the reference changes {reference_change:.3}/255 a frame\n  off:   p99 {:.1}, mean {:.3}, temporal excess {:.3}\n  edges: p99 {:.1}, mean {:.3}, temporal excess {:.3} ({:.3?}); {:.0} extra rays a frame ({:.3} a pixel)",
        off.p99_error,
        off.mean_error,
        off.temporal_excess,
        edges.p99_error,
        edges.mean_error,
        edges.temporal_excess,
        edges.temporal_excess_parts,
        edges.extra_rays,
        edges.extra_rays_per_pixel
    );
    Some((off, edges))
}

/// The acceptance: a third of the one-ray p99 error and of its temporal excess, at most.
fn assert_a_third(off: &QualityRow, edges: &QualityRow) {
    assert!(off.p99_error >= 3.0, "the one-ray frames show aliasing");
    assert!(
        edges.p99_error <= off.p99_error / 3.0,
        "p99 error {} against {} without anti-aliasing",
        edges.p99_error,
        off.p99_error
    );
    assert!(
        edges.temporal_excess <= off.temporal_excess / 3.0,
        "temporal excess {} against {} without anti-aliasing",
        edges.temporal_excess,
        off.temporal_excess
    );
    assert!(edges.extra_rays > 0.0 && edges.extra_rays_per_pixel < 16.0);
}

#[test]
fn the_alps_path_loses_two_thirds_of_its_edge_error_and_crawl() {
    let alps = common::terrains().join("alps.toml");
    if let Some((off, edges)) = measure(&[alps.to_str().unwrap(), "--size", "320x180"]) {
        assert_a_third(&off, &edges);
    }
}

#[test]
fn the_airfields_hangars_and_runway_edges_stop_stepping() {
    let airfield = common::terrains().join("airfield.toml");
    if let Some((off, edges)) = measure(&[airfield.to_str().unwrap(), "--size", "320x180"]) {
        assert_a_third(&off, &edges);
    }
}

/// `distortion/dome-5proj.toml` with its projectors at `w`x`h` (same dome, eye, poses,
/// lenses and blends), written to `dir`.
fn small_dome(dir: &std::path::Path, w: u32, h: u32) -> std::path::PathBuf {
    let text =
        std::fs::read_to_string(common::project_dir().join("distortion/dome-5proj.toml")).unwrap();
    assert!(text.matches("width = 400").count() >= 4);
    let text = text
        .replace("width = 400", &format!("width = {w}"))
        .replace("height = 300", &format!("height = {h}"));
    let p = dir.join("dome-5proj-small.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_dome_channel_through_its_distortion_table_too() {
    let dir = std::env::temp_dir().join(format!("relief-aa-dome-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let dome = small_dome(&dir, 240, 180);
    let alps = common::terrains().join("alps.toml");
    let words = [
        alps.to_str().unwrap(),
        "--display",
        dome.to_str().unwrap(),
        "--channel",
        "0",
    ];
    if let Some((off, edges)) = measure(&words) {
        assert_a_third(&off, &edges);
    }
}

/// One frame of a scene at 320x180: off, with edges, the reference, and the frame at 4x the
/// size with one ray a pixel (the same rays as the reference's 16: pinhole pixel (4i + a,
/// 4j + b) has its centre at i + (a + ½)/4).
struct Four {
    off: FrameOutput,
    edges: FrameOutput,
    reference: FrameOutput,
    big: FrameOutput,
}

const W: usize = 320;
const H: usize = 180;

fn four(scene: &str) -> Four {
    let mut small = frames(
        scene,
        "320x180",
        &[Antialias::OFF, EDGES, Antialias::REFERENCE],
    );
    let big = frames(scene, "1280x720", &[Antialias::OFF]).remove(0);
    let (reference, edges, off) = (small.remove(2), small.remove(1), small.remove(0));
    Four {
        off,
        edges,
        reference,
        big,
    }
}

impl Four {
    /// Index of sample (a, b) of pixel (i, j) in the 4x frame.
    fn at(i: usize, j: usize, a: usize, b: usize) -> usize {
        (4 * j + b) * 4 * W + 4 * i + a
    }

    /// The 4x frame box-filtered 4x4 in linear light: the issue's own reference.
    fn filtered(&self) -> Vec<u8> {
        let mut out = vec![255u8; W * H * 4];
        for j in 0..H {
            for i in 0..W {
                for c in 0..3 {
                    let mut sum = 0.0;
                    for b in 0..4 {
                        for a in 0..4 {
                            sum += srgb_to_linear(self.big.rgba[Self::at(i, j, a, b) * 4 + c]);
                        }
                    }
                    out[(j * W + i) * 4 + c] = linear_to_srgb8(sum / 16.0);
                }
            }
        }
        out
    }

    /// Whether pixel (i, j)'s block shows the surface its centre ray shows (flags and free
    /// form; the same shadow) with no depth jump, and its colours span at most `spread`
    /// levels a channel.
    fn interior(&self, i: usize, j: usize, spread: u8) -> bool {
        let k = j * W + i;
        let centre = (self.off.flags[k] & 0x33, self.off.objects[k]);
        let b = &self.big;
        let (mut lo, mut hi) = ([255u8; 3], [0u8; 3]);
        let (mut dlo, mut dhi) = (f32::INFINITY, 0.0f32);
        for bb in 0..4 {
            for a in 0..4 {
                let q = Self::at(i, j, a, bb);
                if (b.flags[q] & 0x33, b.objects[q]) != centre {
                    return false;
                }
                for c in 0..3 {
                    lo[c] = lo[c].min(b.rgba[4 * q + c]);
                    hi[c] = hi[c].max(b.rgba[4 * q + c]);
                }
                (dlo, dhi) = (dlo.min(b.depth[q]), dhi.max(b.depth[q]));
            }
        }
        let smooth_depth = !dhi.is_finite() || dhi <= dlo * 1.02;
        smooth_depth && (0..3).all(|c| hi[c] - lo[c] <= spread)
    }
}

/// The first motion frame of `scene` at `size`, once per choice.
fn frames(scene: &str, size: &str, choices: &[Antialias]) -> Vec<FrameOutput> {
    let path = common::terrains().join(scene);
    let job = render_job(&[path.to_str().unwrap(), "--size", size]).unwrap();
    let (mut p, mut r) = capture::prepare(&job).unwrap();
    let cams = quality::motion_cameras(&p.scene, &p.world.terrain, 1);
    choices
        .iter()
        .map(|&c| render_all(&mut p, &mut r, &job, &cams, c).unwrap().frames[0].clone())
        .collect()
}

/// `"edges"` gives each edge pixel 4, 8 or 16 samples by its contrast. Each pixel it
/// anti-aliases equals the same pixel of the frame whose edge pixels all get 4, 8 or 16 (the
/// same sub-pixel positions: the first 4 or 8 of the 4x4 grid), so the mixed atlas (a group
/// holds one pixel's 16 samples, two pixels' 8 or four pixels' 4; the tree's list fills
/// several batches) is laid out and resolved right. It marks the pixels the fixed counts mark,
/// all three counts occur, and the extra rays it reports are the sum of its pixels' counts:
/// fewer than 16 a pixel.
#[test]
fn edges_gives_each_edge_pixel_4_8_or_16_samples_by_its_contrast() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let fixed = [4u32, 8, 16];
    for scene in ["alps.toml", "tree.toml"] {
        let mut choices = vec![EDGES];
        choices.extend(fixed.map(Antialias::edges));
        let f = frames(scene, "320x180", &choices);
        let (edges, by_count) = (&f[0], &f[1..]);
        let flagged =
            |o: &FrameOutput| -> Vec<bool> { o.flags.iter().map(|v| v & 128 != 0).collect() };
        for o in by_count {
            assert_eq!(
                flagged(edges),
                flagged(o),
                "{scene}: the same pixels are marked"
            );
        }
        let (mut per_count, mut none) = ([0u64; 3], Vec::new());
        for k in (0..W * H).filter(|&k| edges.flags[k] & 128 != 0) {
            // The fewest samples whose frame shows the pixel as `"edges"` does.
            match (0..3)
                .find(|&i| largest_channel_difference(&edges.rgba, &by_count[i].rgba, k) == 0)
            {
                Some(i) => per_count[i] += 1,
                None => none.push(k),
            }
        }
        let pixels = edges.antialiased_pixels();
        let rays = edges.antialias_rays();
        eprintln!(
            "{scene}: {pixels} pixels anti-aliased, equal to the frame with 4 / 8 / 16 samples: {per_count:?}, to none: {}; {rays} extra rays ({:.2} a pixel anti-aliased)",
            none.len(),
            rays as f64 / pixels as f64
        );
        assert!(
            none.is_empty(),
            "{scene}: pixels {none:?} match no sample count"
        );
        assert!(
            per_count.iter().all(|&c| c > 0),
            "{scene}: every count occurs"
        );
        for (o, n) in by_count.iter().zip(fixed) {
            assert_eq!(o.antialias_rays(), u64::from(n) * pixels);
        }
        // Every anti-aliased pixel is counted once, under the count it got.
        let counts = edges.times.antialias_counts;
        assert_eq!(counts.iter().sum::<u64>(), pixels);
        assert!(
            counts.iter().all(|&c| c > 0),
            "{scene}: every count occurs: {counts:?}"
        );
        assert!(
            rays > 4 * pixels && rays < 16 * pixels,
            "{scene}: {rays} extra rays"
        );
    }
}

fn largest_channel_difference(a: &[u8], b: &[u8], k: usize) -> u8 {
    (0..3)
        .map(|c| a[4 * k + c].abs_diff(b[4 * k + c]))
        .max()
        .unwrap()
}

/// relief's reference (16 sub-pixel rays from the ray table and its derivatives) is the
/// issue's: the frame at 4x the size box-filtered. Interior pixels (the centre ray's surface
/// in all their 4x4 block, no depth jump, a spread of at most one level: low variance) stay
/// within 1/255 of `antialias = "off"`, where the two references agree; pixels the
/// anti-aliasing changes come closer to the reference on the whole and none moves away from
/// it by more than a level. Depth and ids stay the centre rays'.
fn check_sharpness(scene: &str) {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let f = four(scene);
    let filtered = f.filtered();
    let agree = quality::pixel_errors(&f.reference.rgba, &filtered);
    let (p99, p999) = (
        quality::quantile(&agree, 0.99),
        quality::quantile(&agree, 0.999),
    );
    let (o, e, rf) = (&f.off.rgba, &f.edges.rgba, &f.reference.rgba);
    let (mut interior, mut interior_moved) = (0, 0);
    let (mut changed, mut off_err, mut edges_err, mut worse) = (0, 0u64, 0u64, 0);
    for j in 0..H {
        for i in 0..W {
            let k = j * W + i;
            let moved = largest_channel_difference(e, o, k);
            if f.interior(i, j, 1) && agree[k] <= 1 {
                interior += 1;
                interior_moved += usize::from(moved > 1);
            }
            if moved > 0 {
                changed += 1;
                let (eo, ee) = (
                    largest_channel_difference(o, rf, k),
                    largest_channel_difference(e, rf, k),
                );
                off_err += u64::from(eo);
                edges_err += u64::from(ee);
                worse += usize::from(ee > eo + 1);
            }
        }
    }
    eprintln!(
        "{scene}: reference vs the 4x frame box-filtered: p99 {p99}, p99.9 {p999}, worst {}; {interior} interior pixels, {interior_moved} moved by more than 1/255; {changed} pixels changed: error sum {off_err} -> {edges_err}, {worse} further from the reference by more than a level",
        agree.iter().max().unwrap()
    );
    assert!(
        p99 == 0.0 && p999 <= 1.0,
        "relief's reference is the 4x frame box-filtered"
    );
    assert!(interior > 5000, "the frame has interior pixels");
    assert_eq!(interior_moved, 0, "interior pixels stay");
    assert!(
        changed > 0 && edges_err < off_err,
        "changed pixels come closer"
    );
    assert_eq!(worse, 0, "no changed pixel moves away from the reference");
    assert_eq!(f.edges.depth, f.off.depth, "depth is the centre rays'");
    assert_eq!(f.edges.objects, f.off.objects, "ids are the centre rays'");
    // The step counters count the centre rays' near-miss search too: not compared.
    // Flags 128 (anti-aliased) and 64 (a near miss the centre ray's cone found) come with
    // anti-aliasing; the others are the centre rays'.
    let unflagged: Vec<u32> = f.edges.flags.iter().map(|v| v & !(128 | 64)).collect();
    assert_eq!(
        unflagged, f.off.flags,
        "flags are the centre rays' but 128 and 64"
    );
    let marked = f.edges.antialiased_pixels() as usize;
    assert!(
        marked > 0 && marked < W * H / 2,
        "{marked} pixels anti-aliased"
    );
    let unmarked_same = (0..W * H)
        .filter(|&k| f.edges.flags[k] & 128 == 0)
        .all(|k| largest_channel_difference(e, o, k) == 0);
    assert!(
        unmarked_same,
        "pixels without samples keep the centre ray's colour"
    );
}

#[test]
fn sharpness_and_outputs_stay_on_the_alps() {
    check_sharpness("alps.toml");
}

#[test]
fn sharpness_and_outputs_stay_on_the_airfield() {
    check_sharpness("airfield.toml");
}

fn relief(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_relief"))
        .args(args)
        .env("NODEVICE_SELECT", "1")
        .output()
        .unwrap()
}

fn frame_json(dir: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("frame_0000.json")).unwrap()).unwrap()
}

/// `--antialias` from the command line: the frame JSON counts the anti-aliased pixels and the
/// extra rays; the warp test pattern is left as it is (it has no edges to find: it is drawn
/// from the ray table alone); a bad value is refused naming the option.
#[test]
fn the_command_line_reports_extra_rays_and_leaves_the_pattern() {
    if common::gpu().is_none() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("relief-aa-cli-{}", std::process::id()));
    let alps = common::terrains().join("alps.toml");
    let alps = alps.to_str().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec!["render", alps, "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = relief(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let edges = frame_json(&run("edges", &["--size", "160x90", "--antialias", "edges"]));
    let aa = &edges["antialias"];
    let (pixels, rays) = (
        aa["pixels"].as_u64().unwrap(),
        aa["extra_rays"].as_u64().unwrap(),
    );
    eprintln!("160x90 alps: {pixels} pixels anti-aliased, {rays} extra rays");
    assert_eq!(aa["samples"].as_u64(), Some(16));
    assert_eq!(aa["adaptive"].as_bool(), Some(true));
    assert!(pixels > 0 && pixels < 160 * 90 / 2);
    assert!(rays >= 4 * pixels && rays < 16 * pixels, "4 to 16 a pixel");
    let by = &aa["pixels_by_samples"];
    let n = |k: &str| by[k].as_u64().unwrap();
    assert_eq!(n("16") + n("8") + n("4"), pixels);
    assert_eq!(16 * n("16") + 8 * n("8") + 4 * n("4"), rays);
    // The airfield's masts, aircraft and hangars give near misses, each with 16 samples.
    let airfield = common::terrains().join("airfield.toml");
    let out = dir.join("airfield");
    let args = [
        "render",
        airfield.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let o = relief(&[&args[..], &["--size", "160x90", "--antialias", "edges"]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let af = &frame_json(&out)["antialias"];
    let near = af["near_misses"].as_u64().unwrap();
    eprintln!("160x90 airfield: {near} near misses");
    assert!(near > 0 && near <= af["pixels_by_samples"]["16"].as_u64().unwrap());
    let sixteen = frame_json(&run("sixteen", &["--size", "160x90", "--antialias", "16"]));
    let aa = &sixteen["antialias"];
    assert_eq!(aa["adaptive"].as_bool(), Some(false));
    assert_eq!(aa["pixels"].as_u64(), Some(pixels));
    assert_eq!(aa["extra_rays"].as_u64(), Some(16 * pixels));
    let off = frame_json(&run("off", &["--size", "160x90"]));
    assert_eq!(off["antialias"]["extra_rays"].as_u64(), Some(0));

    let dome = small_dome(&dir, 160, 120);
    let pattern = |name: &str, aa: &str| {
        let d = [
            "--display",
            dome.to_str().unwrap(),
            "--pattern",
            "--antialias",
            aa,
        ];
        let out = run(name, &d);
        (
            std::fs::read(out.join("frame_0000.png")).unwrap(),
            frame_json(&out),
        )
    };
    let (plain, _) = pattern("pattern-off", "off");
    let (with, json) = pattern("pattern-edges", "edges");
    assert_eq!(plain, with, "the pattern is not anti-aliased");
    assert_eq!(json["antialias"]["extra_rays"].as_u64(), Some(0));

    let bad = relief(&["render", alps, "--antialias", "5"]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("--antialias"),
        "{err}"
    );
}

/// `relief bench antialias --json`: every choice's frame time and ratio (against plain frames
/// alternated with its own, the `off` row 1), the extra rays each casts, and the quality rows
/// of the same choices; the figures are the bench's, not the frames' (160x90, 2 frames).
#[test]
fn the_bench_reports_each_choices_ratio_extra_rays_and_quality() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let alps = common::terrains().join("alps.toml");
    let args = [
        "bench",
        "antialias",
        alps.to_str().unwrap(),
        "--size",
        "160x90",
        "--frames",
        "2",
        "--json",
        // The list built on the GPU, whatever the adapter (the default on GPUs): the bench
        // says so, and its figures below hold for that path too.
        "--aa-list",
        "gpu",
    ];
    let out = relief(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let d = &v["details"];
    assert_eq!(d["list"], "gpu");
    let timings = d["timings"].as_array().unwrap();
    let rows = d["quality"]["rows"].as_array().unwrap();
    assert_eq!((timings.len(), rows.len()), (5, 5));
    assert_eq!(timings[0]["ratio"], 1.0);
    assert_eq!(timings[0]["extra_rays"], 0);
    for t in timings {
        let (ms, ratio) = (
            t["frame_ms"].as_f64().unwrap(),
            t["ratio"].as_f64().unwrap(),
        );
        assert!(ms > 0.0 && ratio.is_finite() && ratio > 0.0, "{t}");
    }
    let rays: Vec<u64> = timings
        .iter()
        .map(|t| t["extra_rays"].as_u64().unwrap())
        .collect();
    // 4, 8 and 16 samples in each edge pixel: the same pixels, so 1 : 2 : 4.
    assert!(
        rays[1] > 0 && rays[2] == 2 * rays[1] && rays[3] == 4 * rays[1],
        "{rays:?}"
    );
    assert!(rays[4] > rays[1] && rays[4] < rays[3], "{rays:?}");
    let p99 = |k: usize| rows[k]["p99_error"].as_f64().unwrap();
    assert!(p99(3) < p99(0), "16 samples an edge pixel against one ray");
    // The temporal excess by the pixels' kind adds up; without anti-aliasing none is marked.
    for r in rows {
        let parts = &r["temporal_excess_parts"];
        let part = |k: &str| parts[k].as_f64().unwrap();
        let sum = part("marked") + part("sky") + part("smooth") + part("detail");
        let total = r["temporal_excess"].as_f64().unwrap();
        assert!((sum - total).abs() < 1e-9, "{r}");
    }
    assert_eq!(rows[0]["temporal_excess_parts"]["marked"], 0.0);
    assert!(rows[3]["temporal_excess_parts"]["marked"].as_f64().unwrap() > 0.0);
}

/// A flat procedural terrain under a drape `drape.png` (stretched over the grid), seen from
/// 4 km up looking down: each pixel covers about 4x4 texels.
fn drape_scene(dir: &std::path::Path, drape: &image::RgbImage) -> std::path::PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    drape.save(dir.join("drape.png")).unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "[terrain]\ndrape = \"drape.png\"\n[terrain.procedural]\nsize = 257\ncell_size = 30.0\nheight = 0.5\n\
         [sun]\nazimuth = 200.0\nelevation = 60.0\n[render]\nshadows = false\n\
         [camera]\nposition = [3840.0, 3000.0, 4000.0]\nheading = 0.0\npitch = -70.0\nfov = 40.0\n\
         [output]\nwidth = 160\nheight = 90\n",
    )
    .unwrap();
    scene
}

/// Footprint-filtered drape (`"edges"`): a black and white checkerboard of single texels,
/// minified about 4 times, renders as its mean in linear light, the frame of a uniform drape
/// of that mean (sRGB 188), where one ray a pixel shows an aliased pattern.
#[test]
fn a_minified_drape_is_its_mean_in_linear_light() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let base = std::env::temp_dir().join(format!("relief-aa-drape-{}", std::process::id()));
    let checker = image::RgbImage::from_fn(1024, 1024, |x, y| {
        image::Rgb([if (x + y) % 2 == 0 { 0 } else { 255 }; 3])
    });
    let grey = image::RgbImage::from_pixel(1024, 1024, image::Rgb([188; 3]));
    let render = |name: &str, drape: &image::RgbImage, aa: Antialias| {
        let scene = drape_scene(&base.join(name), drape);
        let job = render_job(&[scene.to_str().unwrap()]).unwrap();
        let (mut p, mut r) = capture::prepare(&job).unwrap();
        let cams = quality::motion_cameras(&p.scene, &p.world.terrain, 1);
        render_all(&mut p, &mut r, &job, &cams, aa)
            .unwrap()
            .frames
            .remove(0)
    };
    let truth = render("grey", &grey, Antialias::OFF);
    let plain = render("checker-off", &checker, Antialias::OFF);
    let filtered = render("checker-edges", &checker, EDGES);
    let errors = |f: &FrameOutput| quality::pixel_errors(&f.rgba, &truth.rgba);
    let (e_plain, e_filtered) = (errors(&plain), errors(&filtered));
    let p99 = |e: &[u8]| quality::quantile(e, 0.99);
    eprintln!(
        "checkerboard against its mean: one ray p99 {}, footprint-filtered p99 {} ({} pixels anti-aliased)",
        p99(&e_plain),
        p99(&e_filtered),
        filtered.antialiased_pixels()
    );
    assert!(
        p99(&e_plain) > 20.0,
        "one ray a pixel aliases the checkerboard"
    );
    assert!(p99(&e_filtered) <= 2.0, "the filtered drape is its mean");
    let _ = std::fs::remove_dir_all(&base);
}

/// What a thin feature's test measures: the feature's pixels (where the 16-ray reference
/// differs from one ray a pixel by 8 levels or more, in the given columns of a 160x90 frame),
/// their error sums with one ray and with `"edges"`, how many `"edges"` flagged as near misses
/// (and how many away from the feature), and the object pixels (free forms, voxel models) of
/// the one-ray frame.
struct ThinFeature {
    pixels: usize,
    off_err: u64,
    edges_err: u64,
    near: usize,
    /// Pixels flagged as near misses more than two columns away from `columns`.
    near_elsewhere: usize,
    object_pixels: usize,
}

/// Renders `scene` (160x90, over the 65x65 PNG heightfield `field` and the `files` written
/// beside it) with one ray a pixel, `"edges"` and the reference, and measures the feature in
/// `columns` and `rows`.
fn thin_feature(
    name: &str,
    field: &image::ImageBuffer<image::Luma<u16>, Vec<u16>>,
    png: &str,
    files: &[(&str, Vec<u8>)],
    scene: &str,
    columns: std::ops::Range<usize>,
    rows: std::ops::Range<usize>,
) -> ThinFeature {
    let dir = std::env::temp_dir().join(format!("relief-aa-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    field.save(dir.join(png)).unwrap();
    for (file, bytes) in files {
        std::fs::write(dir.join(file), bytes).unwrap();
    }
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    let job = render_job(&[path.to_str().unwrap()]).unwrap();
    let (mut p, mut r) = capture::prepare(&job).unwrap();
    let cams = quality::motion_cameras(&p.scene, &p.world.terrain, 1);
    let mut frame = |aa| {
        render_all(&mut p, &mut r, &job, &cams, aa)
            .unwrap()
            .frames
            .remove(0)
    };
    let (reference, off, edges) = (
        frame(Antialias::REFERENCE),
        frame(Antialias::OFF),
        frame(EDGES),
    );
    let mut t = ThinFeature {
        pixels: 0,
        off_err: 0,
        edges_err: 0,
        near: 0,
        near_elsewhere: (0..edges.flags.len())
            .filter(|&k| edges.flags[k] & 64 != 0)
            .filter(|&k| k % 160 + 2 < columns.start || k % 160 >= columns.end + 2)
            .count(),
        // Free-form ids, or voxel-model hits (flag 32).
        object_pixels: (0..off.objects.len())
            .filter(|&k| off.objects[k] != 0 || off.flags[k] & 32 != 0)
            .count(),
    };
    for j in rows {
        for i in columns.clone() {
            let k = j * 160 + i;
            let eo = largest_channel_difference(&off.rgba, &reference.rgba, k);
            if eo >= 8 {
                t.pixels += 1;
                t.off_err += u64::from(eo);
                let ee = largest_channel_difference(&edges.rgba, &reference.rgba, k);
                t.edges_err += u64::from(ee);
                t.near += usize::from(edges.flags[k] & 64 != 0);
            }
        }
    }
    eprintln!(
        "{name}: {} centre-ray object pixels; {} pixels the centre rays miss; error sum {} -> {}; {} flagged as near misses, {} elsewhere",
        t.object_pixels, t.pixels, t.off_err, t.edges_err, t.near, t.near_elsewhere
    );
    let _ = std::fs::remove_dir_all(&dir);
    t
}

/// The thin-feature tests' checks: the feature is there in the reference and missed by one
/// ray a pixel, near misses are flagged beside it and nowhere else, and with `"edges"` its
/// error sum falls to a quarter or less.
fn assert_found_through_the_cone(t: &ThinFeature) {
    assert!(
        t.pixels >= 10,
        "the feature is there in the reference and missed by one ray"
    );
    assert!(t.near > 0, "near misses found");
    assert_eq!(
        t.near_elsewhere, 0,
        "near misses flagged away from the feature"
    );
    assert!(t.edges_err * 4 <= t.off_err, "found through the pixel cone");
}

/// A mast on a flat field (the 65x65 `flat.png`, 10 m cells) seen as `view` (the scene's
/// camera and light) with the mast `model` (its TOML, `files` written beside the scene): no
/// centre ray may see it, and the pixels of `rows` in columns 77-82 get its coverage through
/// the pixel cone.
fn thin_mast(name: &str, files: &[(&str, Vec<u8>)], view: &str, model: &str, rows: Range<usize>) {
    let field = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(65, 65);
    let scene = format!(
        "[terrain]\nsource = \"flat.png\"\ncell_size = [10.0, 10.0]\n{view}\
         [output]\nwidth = 160\nheight = 90\n{model}"
    );
    let t = thin_feature(name, &field, "flat.png", files, &scene, 77..83, rows);
    assert_eq!(
        t.object_pixels, 0,
        "the mast must lie between the centre rays"
    );
    assert_found_through_the_cone(&t);
}

/// The scene TOML of a red cylinder 1.2 m wide and 120 m tall standing at (x, y); `perturbed`:
/// with a slight bulge halfway up, which makes it a perturbed free form (the enclosure search,
/// not the closed form).
fn cylinder_mast(x: f64, y: f64, perturbed: bool) -> String {
    let bulge =
        "[[objects.perturb]]\nshape = \"sphere\"\nradius = 1.0\ncentre = [0.0, 0.0, 60.0]\n\
                 weight = -0.2\n";
    format!(
        "[[objects]]\nshape = \"cylinder\"\nradius = 0.6\nheight = 120.0\n\
         position = [{x:?}, {y:?}, 0.0]\nmaterial = {{ colour = [0.9, 0.1, 0.1] }}\n{}",
        if perturbed { bulge } else { "" }
    )
}

/// A mast 1.2 m wide and 120 m tall, 1 km away on a flat field, about a quarter of a pixel
/// wide and standing between two pixel columns, so that no centre ray hits it: `model` (the
/// scene's TOML for it, `files` written beside the scene) at x = 320 m.
fn mast(name: &str, files: &[(&str, Vec<u8>)], model: &str) {
    let view = "[render]\nshadows = false\n\
                [camera]\nposition = [320.0, -1000.0, 40.0]\nheading = 0.0\npitch = 0.0\nfov = 40.0\n";
    thin_mast(name, files, view, model, 0..90);
}

/// A spike 500 m tall on a flat field (one sample of a 10 m grid): a needle about half a pixel
/// wide, centred between two pixel columns, so that no centre ray hits its upper part. The
/// near misses of the pixel cones find it: with `"edges"` its pixels come within a few levels
/// of the reference, where one ray a pixel leaves it out.
#[test]
fn a_needle_no_centre_ray_hits_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let mut field = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(65, 65);
    field.put_pixel(32, 65 - 1 - 40, image::Luma([1000]));
    let t = thin_feature(
        "needle",
        &field,
        "spike.png",
        &[],
        "[terrain]\nsource = \"spike.png\"\ncell_size = [10.0, 10.0]\npng_scale = 0.5\n\
         [render]\nshadows = false\n\
         [camera]\nposition = [320.0, -4000.0, 200.0]\nheading = 0.0\npitch = 2.0\nfov = 40.0\n\
         [output]\nwidth = 160\nheight = 90\n",
        78..82,
        0..90,
    );
    assert_found_through_the_cone(&t);
}

/// A spike's shadow: a spike 500 m tall (one sample of a 5 m grid, 65x257 samples) at the
/// field's north end, the sun due north behind it and 30° up, lays its shadow on the field
/// towards the eye (1 km up, 1.2-1.5 km away, looking 40° down) as a stripe that narrows
/// from the spike's 10 m base to nothing over 866 m. Its far part, thinner than the pixels
/// (about 6 m there), lies between the two pixel columns whose sun rays pass either side of the
/// spike, so that no centre ray's sun ray is blocked. The sun rays of the pixels' footprints
/// pass within their beam of the spike (the shade pass's terrain sun ray with a reach), and
/// the stripe's pixels get their samples.
#[test]
fn a_spikes_shadow_no_centre_ray_sees_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let mut field = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(65, 257);
    field.put_pixel(32, 257 - 1 - 240, image::Luma([1000]));
    let t = thin_feature(
        "spike-shadow",
        &field,
        "spike.png",
        &[],
        "[terrain]\nsource = \"spike.png\"\ncell_size = [5.0, 5.0]\npng_scale = 0.5\n\
         [sun]\nazimuth = 0.0\nelevation = 30.0\n\
         [camera]\nposition = [160.0, -200.0, 1000.0]\nheading = 0.0\npitch = -40.0\nfov = 40.0\n\
         [output]\nwidth = 160\nheight = 90\n",
        77..83,
        50..90,
    );
    assert_found_through_the_cone(&t);
}

/// Near misses on the curved earth: the alps seen to 110 km (`alps-far.toml`, most pixels
/// wider than a sample) flat and on the curved earth, whose datum drops 785 m below the eye's
/// tangent plane at 100 km. The drop changes the far picture a little, not how many rays pass
/// near a rise they miss: the near-miss tests measure the ray's height above the curved datum
/// as the traversal does, and the flat frame has next to none. (They once took its height
/// above the tangent plane, so that the drop counted as a rise: 5,547 near misses, a tenth of
/// the pixels, each given 16 samples.)
#[test]
fn the_curved_earth_adds_no_near_misses() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let flat = common::terrains().join("alps-far.toml");
    let text = std::fs::read_to_string(&flat).unwrap();
    let hgt = common::terrains().join("N47E009.hgt");
    let source = format!("source = {:?}\ncurved = true", hgt.to_str().unwrap());
    let curved_text = text.replace("source = \"N47E009.hgt\"", &source);
    assert_ne!(curved_text, text);
    let dir = std::env::temp_dir().join(format!("relief-aa-curved-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let curved = dir.join("alps-far-curved.toml");
    std::fs::write(&curved, curved_text).unwrap();
    let near = |scene: &std::path::Path| {
        let f = frames(scene.to_str().unwrap(), "320x180", &[EDGES]).remove(0);
        f.flags.iter().filter(|&&g| g & 64 != 0).count()
    };
    let (n_flat, n_curved) = (near(&flat), near(&curved));
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!("alps-far near misses at 320x180: flat {n_flat}, curved {n_curved}");
    // At most a thousandth of the pixels more than the flat frame's.
    assert!(
        n_curved <= n_flat + 320 * 180 / 1000,
        "the curved earth's drop counted as a rise: {n_curved} near misses against {n_flat}"
    );
}

/// The near-miss search of a free form is as wide as the pixel's cone where the ray passes,
/// not where the object ends: a runway 900 m long (a box, 0.2 m above a flat field) seen from
/// 110 m before its threshold, 15 m up. Every pixel flagged as a near miss lies within two
/// pixels of one that shows the runway, as the cone through a pixel's corners reaches. (The
/// search once widened the object's box by the cone's radius at the far side of its bounding
/// sphere, 9 times the radius at the threshold: grass pixels up to eight pixels beside the
/// runway were flagged and given 16 samples, here 122 of 387 near misses more than two pixels
/// away; on the airfield at 1280x720, 5,312 pixels whose centre colour already was the
/// reference's. Now the farthest is one pixel away.)
#[test]
fn a_runways_near_misses_stay_within_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    let dir = std::env::temp_dir().join(format!("relief-aa-runway-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(65, 65)
        .save(dir.join("flat.png"))
        .unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "[terrain]\nsource = \"flat.png\"\ncell_size = [30.0, 30.0]\n\
         [render]\nshadows = false\n\
         [camera]\nposition = [975.0, 400.0, 15.0]\nheading = 0.0\npitch = -3.0\nfov = 40.0\n\
         [output]\nwidth = 160\nheight = 90\n\
         [[objects]]\nshape = \"box\"\nsize = [30, 900, 1]\nposition = [960.0, 960.0, 0.0]\n\
         above_terrain = -0.8\nmaterial = { colour = [0.16, 0.16, 0.17] }\n",
    )
    .unwrap();
    let f = frames(scene.to_str().unwrap(), "160x90", &[EDGES]).remove(0);
    let _ = std::fs::remove_dir_all(&dir);
    let (w, h) = (160usize, 90usize);
    let shows_runway = |i: usize, j: usize| f.objects[j * w + i] != 0;
    let beside_runway = |k: usize| {
        let (i, j) = (k % w, k / w);
        (j.saturating_sub(2)..(j + 3).min(h))
            .any(|jj| (i.saturating_sub(2)..(i + 3).min(w)).any(|ii| shows_runway(ii, jj)))
    };
    let runway = f.objects.iter().filter(|&&o| o != 0).count();
    let near: Vec<usize> = (0..w * h).filter(|&k| f.flags[k] & 64 != 0).collect();
    let far_off = near.iter().filter(|&&k| !beside_runway(k)).count();
    eprintln!(
        "runway: {runway} pixels, {} near misses, {far_off} more than two pixels away",
        near.len()
    );
    assert!(runway > 500, "the runway is in view");
    assert!(
        !near.is_empty(),
        "the search flags the pixels its cone reaches"
    );
    assert_eq!(far_off, 0, "near misses flagged beyond the pixel cone");
}

/// The mast as a plain cylinder: the centre rays' near misses of plain free forms
/// (`ff_plain_near`) find it, and with `"edges"` its pixels come close to the reference,
/// where one ray a pixel leaves it out.
#[test]
fn a_mast_no_centre_ray_hits_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    mast("mast", &[], &cylinder_mast(320.0, 0.0, false));
}

/// The mast as a perturbed free form (a slight bulge halfway up makes it one: the enclosure
/// search, not the closed form): the near-miss search of perturbed objects (`ff_intersect`
/// with a reach) finds it.
#[test]
fn a_perturbed_mast_no_centre_ray_hits_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    mast("perturbed-mast", &[], &cylinder_mast(320.0, 0.0, true));
}

/// The mast as a voxel model (one column of 100 voxels of 1.2 m): the centre rays' near
/// misses of voxel models (`vox_near_miss`: the pixel wider than a voxel, the ray within the
/// cone's reach of a slab's box beside the model) find it.
#[test]
fn a_voxel_mast_no_centre_ray_hits_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    mast(
        "voxel-mast",
        &[("mast.rvs", voxel_mast())],
        &voxel_mast_at(320.0, 0.0),
    );
}

/// The voxel mast in a model two bricks wide (16x1x100 voxels of 1.2 m, the mast the first
/// voxel column of the second brick), placed so that the mast lies inside pixel column 79
/// between its centre ray and the brick boundary: that ray crosses only the empty first
/// brick, moving away from the mast, and must still be flagged (the brick's symmetric gap
/// within the cone's reach, `VoxTrace::touched`). Column 80's ray crosses the mast's brick.
#[test]
fn a_voxel_mast_beside_the_empty_brick_a_ray_crosses_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    // Bottom centre at x = 318.4 m: the model spans 308.8-328.0 m, the mast 318.4-319.6 m;
    // column 79's centre ray passes at 317.7 m, 0.6 voxels left of the brick boundary, and
    // column 79 covers 315.4-320.0 m at the mast's distance.
    mast(
        "voxel-mast-brick-gap",
        &[("mast.rvs", voxel_mast_in_brick(8, 16))],
        &voxel_mast_at(318.4, 0.0),
    );
}

/// The scene TOML of the voxel mast (`voxel_mast`, written beside the scene as `mast.rvs`,
/// voxels of 1.2 m), its model's bottom centre at (x, y).
fn voxel_mast_at(x: f64, y: f64) -> String {
    format!(
        "[[voxels]]\nname = \"mast\"\nfile = \"mast.rvs\"\nposition = [{x:?}, {y:?}, 0.0]\n\
         voxel_size = 1.2\n"
    )
}

/// A segment file of one column of 100 voxels.
fn voxel_mast() -> Vec<u8> {
    voxel_mast_in_brick(0, 1)
}

/// A segment file of a model `width` x 1 x 100 voxels holding one column of 100 voxels at
/// x = `x`.
fn voxel_mast_in_brick(x: u32, width: u32) -> Vec<u8> {
    let voxels = (0..100)
        .map(|z| relief::voxel::Voxel {
            pos: [x, 0, z],
            index: 1,
        })
        .collect();
    let mut palette = vec![[0, 0, 0, 255]; 256];
    palette[1] = [230, 26, 26, 255];
    let model = relief::voxel::VoxelModel::new("mast", [width, 1, 100], palette, voxels).unwrap();
    relief::voxel::segment::encode(&model)
}

/// A mast's shadow: the mast (`model`, the scene's TOML for it at x = 320 m, y = 600 m, 1.2 m
/// wide; `files` written beside the scene) 1 km away at the far side of the field, the sun due
/// north behind it and 20° up, lays its shadow on the field towards the eye (200 m up, looking
/// 10° down) as a stripe 1.2 m wide, a quarter to a third of a pixel, between two pixel
/// columns, so that no centre ray's sun ray is blocked. The sun rays of the pixels' footprints
/// pass the mast, and the stripe's pixels (rows 50-71, below the mast's foot and the field's
/// far edge) get their samples.
fn masts_shadow(name: &str, files: &[(&str, Vec<u8>)], model: &str) {
    let view = "[sun]\nazimuth = 0.0\nelevation = 20.0\n\
                [camera]\nposition = [320.0, -400.0, 200.0]\nheading = 0.0\npitch = -10.0\nfov = 40.0\n";
    thin_mast(name, files, view, model, 50..72);
}

/// The voxel mast's shadow: the sun rays of the footprints pass through the mast's voxels
/// (`vox_shadow_near`).
#[test]
fn a_voxel_masts_shadow_no_centre_ray_sees_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    masts_shadow(
        "voxel-mast-shadow",
        &[("mast.rvs", voxel_mast())],
        &voxel_mast_at(320.0, 600.0),
    );
}

/// The voxel mast's shadow beside an empty brick: the mast the last voxel column of the first
/// brick of a model two bricks wide (16x1x100 voxels), its shadow inside pixel column 80 left of
/// that column's sun rays, which cross only the empty second brick, moving away from the mast
/// (a sun due north: towards +x in the DDA's octant), and must still be flagged (the brick's
/// gap in every direction within the footprint's beam, `VoxTrace::touched`).
#[test]
fn a_voxel_masts_shadow_beside_the_empty_brick_its_sun_rays_cross_is_found() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    // Bottom centre at x = 321.4 m: the mast spans 320.2-321.4 m, column 80's ground points
    // lie at 321.6 m and beyond in the stripe's rows.
    masts_shadow(
        "voxel-mast-shadow-brick-gap",
        &[("mast.rvs", voxel_mast_in_brick(7, 16))],
        &voxel_mast_at(321.4, 600.0),
    );
}

/// The plain cylinder's shadow: the beam of a footprint's sun rays passes within reach of it
/// (`ff_plain_near` over the shadow list, in the free-form shadow pass's `_near` twin).
#[test]
fn a_masts_shadow_no_centre_ray_sees_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    masts_shadow("mast-shadow", &[], &cylinder_mast(320.6, 600.0, false));
}

/// The perturbed mast's shadow (`ff_general_near` over the shadow list: the enclosure search
/// with the footprint's beam as its reach).
#[test]
fn a_perturbed_masts_shadow_no_centre_ray_sees_is_found_through_the_pixel_cone() {
    if common::gpu().is_none() {
        return;
    }
    let _lock = common::gpu_lock();
    masts_shadow(
        "perturbed-mast-shadow",
        &[],
        &cylinder_mast(320.6, 600.0, true),
    );
}
