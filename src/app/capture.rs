//! Headless frame capture: `frame_NNNN.png`, `depth_NNNN.tiff` (f32 ray distance, +inf sky)
//! and `frame_NNNN.json` (camera model, terrain mapping, timings, adapter).
//! Files are written atomically ([`crate::fileio::write_atomic`]: a temporary file renamed when
//! complete, removed on any error), so nothing is left half-written.

use crate::gpu::{FrameOutput, Gpu, RenderSettings, TerrainRenderer};
use crate::scene::{Camera, Scene};
use crate::terrain::Terrain;
use crate::{fileio, Error, Result};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Writes an sRGB RGBA8 image as PNG (atomically).
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    fileio::write_atomic(path, |f| encode_png(f, width, height, rgba))
}

/// Encodes an sRGB RGBA8 image as PNG into `f`.
fn encode_png(f: &mut fileio::AtomicFile, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    if rgba.len() as u64 != width as u64 * height as u64 * 4 {
        return Err(Error::invalid(
            "image",
            format!(
                "{} bytes do not make a {width}x{height} RGBA image",
                rgba.len()
            ),
        ));
    }
    let path = f.target().to_path_buf();
    image::write_buffer_with_format(
        f,
        rgba,
        width,
        height,
        image::ExtendedColorType::Rgba8,
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::format(path, format!("writing PNG: {e}")))
}

/// Writes a single-channel f32 TIFF (the depth image), atomically.
pub fn write_depth_tiff(path: &Path, width: u32, height: u32, depth: &[f32]) -> Result<()> {
    fileio::write_atomic(path, |f| encode_depth_tiff(f, width, height, depth))
}

fn encode_depth_tiff(
    f: &mut fileio::AtomicFile,
    width: u32,
    height: u32,
    depth: &[f32],
) -> Result<()> {
    let path = f.target().to_path_buf();
    let mut enc = tiff::encoder::TiffEncoder::new(f)
        .map_err(|e| Error::format(&path, format!("writing TIFF: {e}")))?;
    enc.write_image::<tiff::encoder::colortype::Gray32Float>(width, height, depth)
        .map_err(|e| Error::format(&path, format!("writing TIFF: {e}")))
}

/// Writes a JSON value (pretty-printed), atomically.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    fileio::write_atomic(path, |f| encode_json(f, value))
}

fn encode_json(f: &mut fileio::AtomicFile, value: &impl serde::Serialize) -> Result<()> {
    let path = f.target().to_path_buf();
    serde_json::to_writer_pretty(&mut *f, value)
        .map_err(|e| Error::format(path, format!("writing JSON: {e}")))
}

/// Writes a frame's PNG, depth TIFF and JSON all or nothing: all three are written and flushed
/// to temporary files before any is renamed into place ([`fileio::commit_all`]).
pub fn write_frame_files(
    png: &Path,
    tif: &Path,
    json: &Path,
    out: &FrameOutput,
    meta: &serde_json::Value,
) -> Result<()> {
    let mut a = fileio::AtomicFile::create(png)?;
    encode_png(&mut a, out.width, out.height, &out.rgba)?;
    let mut b = fileio::AtomicFile::create(tif)?;
    encode_depth_tiff(&mut b, out.width, out.height, &out.depth)?;
    let mut c = fileio::AtomicFile::create(json)?;
    encode_json(&mut c, meta)?;
    fileio::commit_all(vec![a, b, c])
}

/// Reads a depth TIFF written by [`write_depth_tiff`].
pub fn read_depth_tiff(path: &Path) -> Result<(u32, u32, Vec<f32>)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(file))
        .map_err(|e| Error::format(path, format!("{e}")))?;
    let (w, h) = dec
        .dimensions()
        .map_err(|e| Error::format(path, format!("{e}")))?;
    match dec
        .read_image()
        .map_err(|e| Error::format(path, format!("{e}")))?
    {
        tiff::decoder::DecodingResult::F32(v) => Ok((w, h, v)),
        _ => Err(Error::format(path, "not an f32 depth image")),
    }
}

fn mat_rows(m: glam::DMat4) -> Vec<[f64; 4]> {
    let t = m.transpose();
    vec![
        t.x_axis.to_array(),
        t.y_axis.to_array(),
        t.z_axis.to_array(),
        t.w_axis.to_array(),
    ]
}

/// The affine map from (i, j, h_file, 1) to world points, h_file being a sample's height as
/// the height file gives it (metres, before `terrain.vertical_scale`): the terrain's
/// `world_from_grid` with the vertical scale folded into its height column.
pub fn world_from_file_grid(scene: &Scene, terrain: &Terrain) -> glam::DMat4 {
    let mut m = terrain.frame.world_from_grid();
    m.z_axis *= scene.desc.terrain.vertical_scale;
    m
}

/// Metadata describing exactly how a frame's pixels were made.
pub fn frame_metadata(
    gpu: &Gpu,
    scene: &Scene,
    terrain: &Terrain,
    cam: &Camera,
    settings: &RenderSettings,
    frame: u32,
    out: &FrameOutput,
) -> serde_json::Value {
    let (fx, fy, cx, cy) = cam.intrinsics();
    let t = &out.times;
    let cast_ms = t.primary_ms();
    let pixels = (out.width * out.height) as f64;
    let hits = out.flags.iter().filter(|f| *f & 1 != 0).count();
    json!({
        "frame": frame,
        "time_s": scene.desc.path.as_ref().map(|p| frame as f64 / p.fps),
        "width": out.width,
        "height": out.height,
        "camera": {
            "model": "pinhole",
            "camera_axes": "x right, y down, z forward",
            "world_axes": "metres; x east, y north, z up unless the terrain's base plane says otherwise",
            "world_from_camera": mat_rows(cam.world_from_camera()),
            "intrinsics": { "fx": fx, "fy": fy, "cx": cx, "cy": cy },
            "pixel_centre": "pixel (i, j), counted from the top-left, has its centre at image point (i + 0.5, j + 0.5); \
                             its ray is normalize(R * ((u - cx) / fx, (v - cy) / fy, 1)) with R the rotation of world_from_camera",
            "position": cam.pose.position.to_array(),
            "heading_deg": cam.pose.heading,
            "pitch_deg": cam.pose.pitch,
            "roll_deg": cam.pose.roll,
            "hfov_deg": cam.pose.fov,
        },
        "depth": {
            "file": format!("depth_{frame:04}.tiff"),
            "quantity": "distance in metres from the camera centre along the pixel's unit ray to the nearest surface (terrain or free form); +inf where the ray meets none",
        },
        "terrain": {
            "samples": [terrain.field.width, terrain.field.height],
            "spacing_m": terrain.field.spacing,
            "world_from_grid": mat_rows(world_from_file_grid(scene, terrain)),
            "grid": "sample (i, j) with height h in metres as the height file gives it (before vertical_scale) is at world point world_from_grid * (i, j, h, 1): the vertical scale is folded into the height column; j runs north (row 0 is the southern edge); the surface is bilinear in each cell",
            "height_range_m": [terrain.min_height, terrain.max_height],
            "vertical_scale": scene.desc.terrain.vertical_scale,
            "voids_filled": terrain.field.voids_filled,
            "geo": terrain.field.geo,
        },
        "timing_ms": t,
        "primary_rays_per_second": pixels / (cast_ms * 1e-3),
        "mean_steps_per_ray": out.steps.iter().map(|&s| s as f64).sum::<f64>() / pixels,
        "surface_pixels": hits,
        "free_form_pixels": out.objects.iter().filter(|o| **o != 0).count(),
        "free_forms": scene.desc.objects.len(),
        "volumes": scene.desc.volumes.len(),
        // Per pixel with a volume: texture samples taken (empty-space skipping and early
        // termination leave the rest of the lattice unsampled).
        "volume_pixels": out.volume_samples.iter().filter(|s| **s != 0).count(),
        "volume_samples": out.volume_samples.iter().map(|&s| s as u64).sum::<u64>(),
        "voxel_models": scene.desc.voxels.len(),
        "settings": settings,
        "adapter": {
            "name": gpu.info.name,
            "backend": format!("{:?}", gpu.info.backend),
            "device_type": format!("{:?}", gpu.info.device_type),
            "driver": gpu.info.driver,
            "driver_info": gpu.info.driver_info,
        },
        "relief_version": env!("CARGO_PKG_VERSION"),
    })
}

/// Options of a headless render run.
#[derive(Clone, Debug)]
pub struct RenderJob {
    pub scene: PathBuf,
    pub size: Option<(u32, u32)>,
    pub frames: u32,
    pub first_frame: u32,
    pub out_dir: PathBuf,
    pub shadows: Option<bool>,
    pub tile_prepass: Option<bool>,
    /// Render through a distortion table: display config, channel index, eye override.
    pub display: Option<DisplayJob>,
    /// Render the warp test pattern ([`crate::display::pattern`], circles around the camera's
    /// forward direction) instead of the scene.
    pub pattern: bool,
    /// Render a dome master of this field of view (degrees) instead of a pinhole image:
    /// an angular fisheye around the vehicle's up axis ([`crate::display::dome_master`]).
    pub dome_master: Option<f64>,
}

/// The display part of a render job.
#[derive(Clone, Debug)]
pub struct DisplayJob {
    pub config: PathBuf,
    pub channel: usize,
    /// Eye point in the display frame; the config's eye when `None`.
    pub eye: Option<[f64; 3]>,
    /// Two-pass mode: render planar (or cube) images from the eye and warp them through the
    /// table (bilinear), as conventional warping software does; for comparison with direct.
    pub two_pass: bool,
}

/// Renders `job.frames` frames and writes them to `job.out_dir`; returns the file paths.
pub fn run(job: &RenderJob) -> Result<Vec<PathBuf>> {
    let mut scene = Scene::load(&job.scene)?;
    if let Some((w, h)) = job.size {
        scene.desc.output.width = w;
        scene.desc.output.height = h;
        scene.desc.validate()?;
    }
    if job.frames == 0 || job.frames > 100_000 {
        return Err(Error::invalid(
            "--frames",
            format!("must be 1..=100000, got {}", job.frames),
        ));
    }
    // The last frame number must exist: `--first` + `--frames` − 1 within u32.
    let last_frame = job.first_frame.checked_add(job.frames - 1).ok_or_else(|| {
        Error::invalid(
            "--first",
            format!(
                "{} with --frames {} runs past the largest frame number {}: lower --first or --frames",
                job.first_frame,
                job.frames,
                u32::MAX
            ),
        )
    })?;
    let terrain = scene.load_terrain()?;
    let objects = scene.free_forms(&terrain)?;
    let volumes = scene.volumes(&terrain)?;
    let voxels = scene.voxel_models(&terrain)?;
    let gpu = Gpu::new()?;
    log::info!("adapter: {}", gpu.describe());
    let mut renderer = TerrainRenderer::new(&gpu, &terrain)?;
    renderer.set_objects(&gpu, &objects)?;
    renderer.set_volumes(&gpu, &volumes)?;
    renderer.set_voxels(&gpu, &voxels)?;
    let fps = scene.desc.path.as_ref().map_or(30.0, |p| p.fps);
    let mut blend_after_warp = None;
    let mut display_meta = serde_json::Value::Null;
    // Two-pass mode: intermediate faces and the projector pixels' display-frame directions.
    let mut two_pass: Option<(Vec<super::verify::Face>, Vec<Option<glam::DVec3>>)> = None;
    if let Some(d) = &job.display {
        if job.size.is_some() {
            return Err(Error::invalid(
                "--size",
                "a distortion table renders at the projector's resolution; drop --size",
            ));
        }
        let cfg = crate::display::DisplayConfig::load(&d.config)?;
        let channel = cfg.channels.get(d.channel).ok_or_else(|| {
            Error::invalid(
                "--channel",
                format!(
                    "{} has {} channel(s), asked for index {}",
                    d.config.display(),
                    cfg.channels.len(),
                    d.channel
                ),
            )
        })?;
        let p = channel.projector;
        let points = cfg.channel_points(d.channel)?;
        let lit = points.points.iter().filter(|p| p.is_some()).count();
        if lit == 0 {
            return Err(Error::invalid(
                format!("{} channel {}", d.config.display(), d.channel),
                "no projector pixel reaches the screen",
            ));
        }
        let eye = glam::DVec3::from(d.eye.unwrap_or(cfg.eye.position));
        renderer.set_display(&gpu, &points, eye)?;
        if let Some(v) = channel.view {
            renderer.set_view_offset(v.matrix());
        }
        // Direct mode blends on the GPU; two-pass mode after its CPU warp (below).
        let blend = crate::display::blend::ChannelBlend::new(&cfg, d.channel);
        if d.two_pass {
            blend_after_warp = blend;
        } else {
            renderer.set_blend(&gpu, blend.as_ref())?;
        }
        let mut mode = json!("direct: one ray per projector pixel");
        if d.two_pass {
            let dirs: Vec<_> = points
                .points
                .iter()
                .map(|s| s.and_then(|s| (s - eye).try_normalize()))
                .map(|d| d.map(|d| channel.view.map_or(d, |v| v.matrix() * d)))
                .collect();
            let faces = super::verify::two_pass_faces(p.width, &dirs)?;
            mode = json!(format!(
                "two-pass: {} pinhole image(s) of {}x{} from the eye, warped bilinearly through the table",
                faces.len(),
                faces[0].width,
                faces[0].height
            ));
            two_pass = Some((faces, dirs));
        }
        scene.desc.output.width = p.width;
        scene.desc.output.height = p.height;
        display_meta = json!({
            "config": d.config.display().to_string(),
            "channel": d.channel,
            "channel_name": channel.name,
            "eye_display_frame": eye.to_array(),
            "pixels_on_screen": lit,
            "mode": mode,
            "model": "per-pixel ray = world_from_display * normalize(screen_point(pixel) - eye); world_from_display maps display x, y, z to the camera's right, forward, up",
        });
    }
    if let Some(fov) = job.dome_master {
        crate::display::dome_master::check_fov("--dome-master", fov)?;
        if job.display.is_some() {
            return Err(Error::invalid(
                "--dome-master",
                "renders the fulldome master itself; drop --display (use `relief warp apply` to \
                 warp a dome master into a projector channel)",
            ));
        }
        let o = &mut scene.desc.output;
        let size = o.width.min(o.height);
        (o.width, o.height) = (size, size);
        let points = super::verify::view_points(size, size, |x, y| {
            crate::display::dome_master::direction(x, y, size, fov)
        });
        renderer.set_display(&gpu, &points, glam::DVec3::ZERO)?;
        display_meta = json!({
            "mode": format!("dome master: {fov}° angular fisheye, {size}x{size}"),
            "model": "zenith (vehicle up) at the centre, vehicle forward at the bottom, right to the right; radius proportional to the angle from the zenith",
        });
    }
    let mut settings = RenderSettings::from_scene(&scene.desc);
    if let Some(s) = job.shadows {
        settings.shadows = s;
    }
    if let Some(t) = job.tile_prepass {
        settings.tile_prepass = t;
    }
    std::fs::create_dir_all(&job.out_dir).map_err(|e| Error::io(&job.out_dir, e))?;
    let mut written = Vec::new();
    for frame in job.first_frame..=last_frame {
        // An error names the frame and what is kept: every earlier frame is complete.
        let at = |e: Error| {
            let done = frame - job.first_frame;
            Error::invalid(
                format!("frame {frame}"),
                if done == 0 {
                    format!("{e}; no frame was written")
                } else {
                    format!(
                        "{e}; the {done} frame(s) before it are complete in {}",
                        job.out_dir.display()
                    )
                },
            )
        };
        let cam = scene.camera(frame, &terrain);
        renderer.set_time(frame as f64 / fps);
        if job.pattern {
            let params = crate::display::pattern::PatternParams::grid(cam.basis().2);
            renderer.set_pattern(&gpu, Some(params));
        }
        let mut out = match &two_pass {
            Some((faces, dirs)) => super::verify::render_two_pass(
                &gpu,
                &mut renderer,
                &terrain,
                &scene.desc,
                cam.pose,
                &settings,
                faces,
                dirs,
                cam.width,
                cam.height,
            )
            .map_err(at)?,
            None => renderer
                .capture(&gpu, &terrain, &scene.desc, &cam, &settings)
                .map_err(at)?,
        };
        if let Some(b) = &blend_after_warp {
            b.apply_rgba8(&mut out.rgba);
        }
        let png = job.out_dir.join(format!("frame_{frame:04}.png"));
        let tif = job.out_dir.join(format!("depth_{frame:04}.tiff"));
        let meta = job.out_dir.join(format!("frame_{frame:04}.json"));
        // None of the frame's files is written when one of them cannot be.
        for p in [&png, &tif, &meta] {
            fileio::check_writable_target(p).map_err(at)?;
        }
        let mut m = frame_metadata(&gpu, &scene, &terrain, &cam, &settings, frame, &out);
        if !display_meta.is_null() {
            m["display"] = display_meta.clone();
            m["camera"]["model"] =
                json!("distortion-table (see display); the pinhole intrinsics do not apply");
        }
        write_frame_files(&png, &tif, &meta, &out, &m).map_err(at)?;
        log::info!(
            "frame {frame}: raygen {:.1} ms, tile {:.1} ms, cast {:.1} ms, free forms {:.1} ms, voxels {:.1} ms, voxel shadows {:.1} ms, shade {:.1} ms, volume shadows {:.1} ms, volume {:.1} ms -> {}",
            out.times.raygen_ms,
            out.times.tile_ms,
            out.times.cast_ms,
            out.times.objects_ms,
            out.times.voxels_ms,
            out.times.voxel_shadow_ms,
            out.times.shade_ms,
            out.times.volume_shadow_ms,
            out.times.volume_ms,
            png.display()
        );
        written.extend([png, tif, meta]);
    }
    Ok(written)
}
