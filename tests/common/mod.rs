//! Shared helpers for the integration tests.
#![allow(dead_code)]

use relief::scene::{Scene, SceneDesc};
use relief::terrain::{Heightfield, Terrain, TerrainFrame};
use std::path::{Path, PathBuf};

pub fn project_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn terrains() -> PathBuf {
    project_dir().join("terrains")
}

/// The shared GPU, or `None` with a printed reason when `RELIEF_SKIP_GPU_TESTS=1` and no
/// adapter exists. Without that variable a missing adapter fails the test.
pub fn gpu() -> Option<&'static relief::gpu::Gpu> {
    static GPU: std::sync::OnceLock<Option<relief::gpu::Gpu>> = std::sync::OnceLock::new();
    GPU.get_or_init(|| match relief::gpu::Gpu::new() {
        Ok(g) => {
            eprintln!("GPU tests on {}", g.describe());
            Some(g)
        }
        Err(e) if std::env::var("RELIEF_SKIP_GPU_TESTS").as_deref() == Ok("1") => {
            eprintln!("Skipping GPU tests: {e}");
            None
        }
        Err(e) => panic!("no GPU adapter ({e}); install mesa-vulkan-drivers, or set RELIEF_SKIP_GPU_TESTS=1 to skip GPU tests"),
    })
    .as_ref()
}

/// Serialises GPU tests (the software adapter uses both cores per frame anyway).
pub fn gpu_lock() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

/// A flat-ish scene description for synthetic terrains (its own terrain is never loaded).
pub fn synthetic_scene(width: u32, height: u32, camera: &str) -> SceneDesc {
    let text = format!(
        "[terrain.procedural]\nsize = 2\n[camera]\n{camera}\n[output]\nwidth = {width}\nheight = {height}\n[fog]\nvisibility = 0.0\n"
    );
    Scene::parse(&text, Path::new("synthetic.toml"))
        .expect("synthetic scene parses")
        .desc
}

/// Terrain from a height function on an `n x n` grid with `spacing` metres.
pub fn terrain_from_fn(n: usize, spacing: f64, f: impl Fn(f64, f64) -> f64) -> Terrain {
    let mut samples = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            samples.push(Some(f(i as f64 * spacing, j as f64 * spacing) as f32));
        }
    }
    let field =
        Heightfield::from_samples_with_voids("test", n, n, samples, [spacing, spacing], None)
            .unwrap();
    let frame = TerrainFrame {
        origin: glam::DVec3::ZERO,
        axis_x: glam::DVec3::X,
        axis_y: glam::DVec3::Y,
        normal: glam::DVec3::Z,
        spacing: [spacing, spacing],
    };
    Terrain::new(field, frame, 1.0).unwrap()
}

/// Writes `{name}-actual.png` (RGBA) for a failed image test into `target/test-output/` and
/// returns its path; for tests whose reference is not an image (a depth oracle), pair it with
/// [`save_failure_mask`].
pub fn save_failure_image(name: &str, width: u32, height: u32, rgba: &[u8]) -> PathBuf {
    let dir = project_dir().join("target").join("test-output");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("{name}-actual.png"));
    relief::app::output::write_png(&p, width, height, rgba).unwrap();
    p
}

/// For a failed comparison of two RGBA images: writes `{name}-actual.png`,
/// `{name}-expected.png` and `{name}-diff.png` (per channel |actual − expected| × 8, opaque)
/// into `target/test-output/`; returns the path of the diff.
pub fn save_failure_images(
    name: &str,
    width: u32,
    height: u32,
    actual: &[u8],
    expected: &[u8],
) -> PathBuf {
    save_failure_image(name, width, height, actual);
    save_failure_image(&format!("{name}-expected"), width, height, expected);
    let diff: Vec<u8> = actual
        .chunks_exact(4)
        .zip(expected.chunks_exact(4))
        .flat_map(|(a, e)| {
            let d = |c: usize| a[c].abs_diff(e[c]).saturating_mul(8);
            [d(0), d(1), d(2), 255]
        })
        .collect();
    let p = project_dir()
        .join("target")
        .join("test-output")
        .join(format!("{name}-diff.png"));
    relief::app::output::write_png(&p, width, height, &diff).unwrap();
    p
}

/// Writes `{name}-diff.png`: the pixels that disagree with a non-image oracle (a CPU depth,
/// an analytic answer) in white on black, beside [`save_failure_image`]'s `-actual`.
pub fn save_failure_mask(name: &str, width: u32, height: u32, bad: &[(u32, u32)]) -> PathBuf {
    let mut m = vec![0u8; (width * height * 4) as usize];
    for px in m.chunks_exact_mut(4) {
        px[3] = 255;
    }
    for &(x, y) in bad.iter().filter(|&&(x, y)| x < width && y < height) {
        let k = 4 * (y * width + x) as usize;
        m[k..k + 3].fill(255);
    }
    let dir = project_dir().join("target").join("test-output");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("{name}-diff.png"));
    relief::app::output::write_png(&p, width, height, &m).unwrap();
    p
}

/// RGBA bytes of an RGB image list of `[r, g, b]` (alpha 255), for the savers above.
pub fn rgba_of(rgb: &[[u8; 3]]) -> Vec<u8> {
    rgb.iter().flat_map(|c| [c[0], c[1], c[2], 255]).collect()
}

/// The product's render settings for GPU tests: pyramid traversal, 4096 steps, with the
/// given shadow and tile pre-pass switches.
pub fn settings(shadows: bool, tile_prepass: bool) -> relief::gpu::RenderSettings {
    relief::gpu::RenderSettings {
        mode: relief::gpu::TraceMode::Pyramid,
        shadows,
        tile_prepass,
        max_steps: 4096,
        lod: None,
        antialias: relief::gpu::Antialias::OFF,
    }
}

/// The frame JSON (`frame_NNNN.json`, `verify.json`, …) at `path`, parsed.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Mean absolute difference of two RGBA8 images, in units of 1/255.
pub fn mean_diff(a: &image::RgbaImage, b: &image::RgbaImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions());
    let s: u64 = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| u64::from(x.abs_diff(*y)))
        .sum();
    s as f64 / a.as_raw().len() as f64
}

/// Small deterministic RNG (xorshift64*) so tests need no extra crate.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
    }
}

/// A fresh, empty directory under `target/test-output/` for test `name`.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = project_dir()
        .join("target")
        .join("test-output")
        .join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The `relief` binary as a command run from the project directory, with `envs` set, Mesa's
/// device-select chatter off and no display (set `DISPLAY` on it for window tests).
pub fn relief_command(args: &[&str], envs: &[(&str, &str)]) -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_relief"));
    c.args(args)
        .env("NODEVICE_SELECT", "1")
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .current_dir(project_dir());
    for (k, v) in envs {
        c.env(k, v);
    }
    c
}

/// Runs the `relief` binary (see [`relief_command`]) and returns its output.
pub fn relief_cli(args: &[&str], envs: &[(&str, &str)]) -> std::process::Output {
    relief_command(args, envs)
        .output()
        .expect("the relief binary runs")
}

/// Compiles `source` (a `.hgt` or GeoTIFF) into the database `db` with `relief db build`,
/// asserting it succeeds; returns `db`.
pub fn db_build(db: PathBuf, source: &Path) -> PathBuf {
    let args = [
        "db",
        "build",
        db.to_str().unwrap(),
        source.to_str().unwrap(),
    ];
    let r = relief_cli(&args, &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    db
}

/// A 3″ SRTM tile `N47E009.hgt` written into `dir`: a field at 500 m with a hill (800 m high,
/// a Gaussian of 60 samples, centred on 47.5N 9.5E) whose top is a void (SRTM's −32768) of
/// `VOID_SIDE`² samples, rows and columns from `VOID_FIRST` (file order: row 0 north).
pub fn void_hgt(dir: &Path) -> PathBuf {
    const N: usize = 1201;
    let mut bytes = Vec::with_capacity(N * N * 2);
    for row in 0..N {
        for col in 0..N {
            let void = (VOID_FIRST..VOID_FIRST + VOID_SIDE).contains(&row)
                && (VOID_FIRST..VOID_FIRST + VOID_SIDE).contains(&col);
            let r2 = ((row as f64 - 600.0).powi(2) + (col as f64 - 600.0).powi(2)) / (60.0 * 60.0);
            let h = if void {
                relief::terrain::hgt::VOID
            } else {
                (500.0 + 800.0 * (-0.5 * r2).exp()).round() as i16
            };
            bytes.extend_from_slice(&h.to_be_bytes());
        }
    }
    let hgt = dir.join("N47E009.hgt");
    std::fs::write(&hgt, bytes).unwrap();
    hgt
}

/// The first row and column of [`void_hgt`]'s void, and its side in samples.
pub const VOID_FIRST: usize = 570;
pub const VOID_SIDE: usize = 60;

/// The adapters of a software machine a test can ask for by `WGPU_BACKEND`: `vulkan`
/// (lavapipe) where an adapter answers, and `gl` (llvmpipe). A missing Vulkan adapter is
/// printed, not failed: the README's machines may have GL only.
pub fn backends() -> Vec<&'static str> {
    let mut v = Vec::new();
    for b in ["vulkan", "gl"] {
        let probe = relief_cli(&["adapter"], &[("WGPU_BACKEND", b)]);
        if probe.status.success() {
            v.push(b);
        } else {
            eprintln!(
                "no {b} adapter here ({}); its runs are skipped",
                String::from_utf8_lossy(&probe.stderr).trim()
            );
        }
    }
    v
}

/// The 16x16 x 257² synthetic mosaic of the pager and paged tests, built once and kept between
/// runs (its name holds its options: the synth is deterministic).
pub fn pager_mosaic() -> PathBuf {
    use relief::db::{self, Database};
    let dir = project_dir().join("target").join("test-output");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("pager-synth-16x16-257-seed1.reliefdb");
    if Database::open(&p).is_err() {
        db::synth(&p, &db::SynthOptions::default(), &|_, _| {}).unwrap();
    }
    p
}

/// This process's peak resident set (VmHWM), KiB; `None` off Linux.
pub fn hwm_kib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// A private X server (`Xvfb -displayfd`, which picks a free display number), killed on drop.
pub struct Xvfb {
    child: std::process::Child,
    pub display: String,
}

impl Xvfb {
    /// `None`, with the reason printed, when Xvfb is not installed.
    pub fn start() -> Option<Xvfb> {
        let child = std::process::Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "1024x768x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn();
        let mut child = match child {
            Ok(c) => c,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                eprintln!(
                    "Skipping window test: Xvfb is not installed (Debian: xvfb; .ci/run installs it)"
                );
                return None;
            }
            Err(e) => panic!("cannot start Xvfb: {e}"),
        };
        let mut line = String::new();
        std::io::BufRead::read_line(
            &mut std::io::BufReader::new(child.stdout.take().unwrap()),
            &mut line,
        )
        .expect("Xvfb reports its display number");
        let n: u32 = line
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("Xvfb printed `{line}` instead of a display number"));
        Some(Xvfb {
            child,
            display: format!(":{n}"),
        })
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The shade pass's sky (`sky` in `shade.wgsl`, from the scene's daylight), linear, seen along
/// world direction `d` on a terrain whose up is +z: written out here as the tests' truth.
pub fn daylight_sky(day: &relief::scene::Daylight, d: glam::DVec3) -> glam::DVec3 {
    let v = |c: [f32; 3]| glam::DVec3::new(c[0].into(), c[1].into(), c[2].into());
    let (zenith, horizon, sun_colour) = (v(day.zenith), v(day.horizon), v(day.sun_colour));
    let up = d.z;
    let mut c = if up >= 0.0 {
        horizon.lerp(zenith, up.sqrt())
    } else {
        horizon * (1.0 + (0.6 - 1.0) * (-up * 4.0).clamp(0.0, 1.0))
    };
    let cs = d.dot(day.light);
    c += sun_colour * (0.35 * cs.max(0.0).powi(64));
    if cs > 0.27f64.to_radians().cos() {
        c += sun_colour * 20.0;
    }
    c
}
