//! `relief render`: headless frame capture, `frame_NNNN.png`, `depth_NNNN.tiff` (f32 ray
//! distance, +inf sky) and `frame_NNNN.json` (camera model, terrain mapping, timings,
//! adapter), through the scene's pinhole camera, a display channel's distortion table (direct
//! or two-pass) or as a dome master. The files are written by [`super::output`].

use super::args::{parse_size, parse_vec, RenderToggles};
use super::output::{frame_paths, write_frame_files};
use super::paged::{ChannelRays, Follower, Paging};
use super::two_pass::{render_two_pass, view_points, TwoPass};
use crate::display::blend::ChannelBlend;
use crate::gpu::{FrameOutput, Gpu, RenderSettings, TerrainRenderer};
use crate::scene::{Camera, Scene};
use crate::terrain::Terrain;
use crate::world::World;
use crate::{fileio, Error, Result};
use serde_json::json;
use std::cell::RefCell;
use std::path::{Path, PathBuf};

// The writers lived here before `output`; their paths stay.

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

/// The frame's light (`scene::daylight`): the sun's and the moon's directions, which of them
/// lights the frame, and the sun and sky colours used.
fn lighting(desc: &crate::scene::SceneDesc) -> serde_json::Value {
    let day = desc.daylight();
    json!({
        "sun_deg": [desc.sun.azimuth, desc.sun.elevation],
        "moon": desc.moon.map(|m| json!({
            "deg": [m.azimuth, m.elevation],
            "illuminated": m.illuminated,
        })),
        "light": if day.moonlit { "moon" } else { "sun" },
        "twilight": desc.sky.twilight,
        "light_colour": day.sun_colour,
        "sky_zenith": day.zenith,
        "sky_horizon": day.horizon,
    })
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
    let aa_pixels = out.antialiased_pixels();
    json!({
        "frame": frame,
        "antialias": {
            "samples": settings.antialias.rays_per_pixel(),
            "adaptive": settings.antialias.adaptive,
            "every_pixel": settings.antialias.every_pixel,
            "pixels": aa_pixels,
            "extra_rays": out.antialias_rays(),
            "near_misses": out.near_misses(),
            "pixels_by_samples": {
                "16": out.times.antialias_counts[0],
                "8": out.times.antialias_counts[1],
                "4": out.times.antialias_counts[2],
            },
        },
        "time_s": scene.desc.path.as_ref().map(|p| frame as f64 / p.fps),
        "lighting": lighting(&scene.desc),
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
            // [lat, lon, alt] through the terrain's georeference (none without one).
            "geodetic": terrain.world_to_geodetic(cam.pose.position),
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

/// Options of a headless render run (`relief render`).
#[derive(Clone, Debug, clap::Args)]
pub struct RenderJob {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output size WxH (overrides `[output]`).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Number of frames (along the scene's `[path]` if it has one).
    #[arg(long, default_value_t = 1)]
    pub frames: u32,
    /// First frame number.
    #[arg(long = "first", value_name = "FIRST", default_value_t = 0)]
    pub first_frame: u32,
    /// Output directory.
    #[arg(long = "out", value_name = "OUT", default_value = "out")]
    pub out_dir: PathBuf,
    #[command(flatten)]
    pub toggles: RenderToggles,
    #[command(flatten)]
    pub display: DisplayArgs,
    /// Render the warp test pattern (5° azimuth/elevation grid, horizon, 10° circles around
    /// the view direction) instead of the scene.
    #[arg(long)]
    pub pattern: bool,
    /// Render a square dome master (angular fisheye of this many degrees, 180 for a
    /// hemisphere; zenith at the centre, forward at the bottom) instead of a pinhole view.
    #[arg(long, conflicts_with = "display")]
    pub dome_master: Option<f64>,
    /// Render a database scene through a paged tile pool of this many MB on the GPU (the
    /// window is not uploaded whole). One frame waits until its view's tiles are resident;
    /// with --frames N each frame renders what is resident then (unless --wait-resident).
    #[arg(long, value_name = "MB")]
    pub terrain_memory: Option<u64>,
    /// With --terrain-memory (or `[terrain] memory`): every frame waits (up to 60 s) until
    /// its view's tiles are resident.
    #[arg(long)]
    pub wait_resident: bool,
}

/// The display part of a render job: render through a distortion table.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct DisplayArgs {
    /// Render through a curved-screen distortion table (display config TOML).
    #[arg(long)]
    pub display: Option<PathBuf>,
    /// Channel (projector) of the display config.
    #[arg(long, default_value_t = 0)]
    pub channel: usize,
    /// Eye point X,Y,Z in the display frame (overrides the config's eye).
    #[arg(long, value_parser = parse_vec::<3>, allow_hyphen_values = true)]
    pub eye: Option<[f64; 3]>,
    /// With --display: two-pass mode (planar/cube images warped bilinearly through the
    /// table) instead of direct ray casting, for comparison.
    #[arg(long, requires = "display")]
    pub two_pass: bool,
}

/// How frames are projected when not through the scene's pinhole camera.
#[derive(Default)]
struct Projection {
    /// The frame metadata's `display` (null for the pinhole camera).
    meta: serde_json::Value,
    /// Two-pass mode blends after its CPU warp (direct mode on the GPU).
    blend_after_warp: Option<ChannelBlend>,
    /// Two-pass mode: the intermediate faces and the projector pixels' directions.
    two_pass: Option<TwoPass>,
    /// A channel's or dome master's rays as a cone, for the pager (paged terrain only).
    rays: Option<ChannelRays>,
}

/// What a run renders with besides its renderer: the scene (output size set), its world, the
/// adapter, the job's projection and the render settings.
pub struct Prepared {
    pub scene: Scene,
    pub world: World,
    pub gpu: Gpu,
    projection: Projection,
    pub settings: RenderSettings,
    /// The pager of a paged renderer (`--terrain-memory`).
    pub paging: Option<RefCell<Paging>>,
}

impl Prepared {
    /// The frame renderer of this run (`job` names the output directory and the pattern).
    pub fn frames<'a>(&'a self, job: &'a RenderJob) -> Frames<'a> {
        Frames {
            job,
            gpu: &self.gpu,
            scene: &self.scene,
            terrain: &self.world.terrain,
            settings: &self.settings,
            projection: &self.projection,
            fps: self.scene.desc.path.as_ref().map_or(30.0, |p| p.fps),
            paging: self.paging.as_ref(),
        }
    }

    /// A paged window moved to follow frame `frame`'s camera (`f`'s [`Follower::follow`]),
    /// and the renderer's pool with it; returns the camera in the frame of the window now.
    fn follow(&mut self, f: &mut Follower, r: &mut TerrainRenderer, frame: u32) -> Result<Camera> {
        let mut cam = f.scene_camera(&self.scene, frame);
        if f.follow_scene_eye(&mut self.world, cam.pose.position)? {
            if let Some(p) = &self.paging {
                p.borrow_mut()
                    .sync_window(&self.gpu, r, &self.world, f.spec())?;
            }
        }
        cam.pose.position = f.to_window(&self.world.terrain, cam.pose.position);
        Ok(cam)
    }
}

/// Loads `job`'s scene and world, opens the adapter and sets the renderer up for the job's
/// projection (pinhole, display channel, dome master).
pub fn prepare(job: &RenderJob) -> Result<(Prepared, TerrainRenderer)> {
    let mut scene = Scene::load(&job.scene)?;
    if let Some((w, h)) = job.size {
        scene.desc.output.width = w;
        scene.desc.output.height = h;
        scene.desc.validate()?;
    }
    let memory = paged_memory(job, &scene);
    let world = World::load_as(&scene, memory.is_some())?;
    let gpu = crate::app::gpu_options::open()?;
    log::info!("adapter: {}", gpu.describe());
    let (mut renderer, paging) = match memory {
        Some(mb) => {
            let (r, p) = super::paged::renderer(&gpu, &scene, &world, mb)?;
            (r, Some(RefCell::new(p)))
        }
        None if job.wait_resident => {
            return Err(Error::invalid(
                "--wait-resident",
                "applies to a paged terrain: give --terrain-memory MB or `[terrain] memory`",
            ))
        }
        None => (super::upload::renderer(&gpu, &world)?, None),
    };
    let mut projection = Projection::default();
    if let Some(config) = &job.display.display {
        projection = through_channel(job, config, &gpu, &mut renderer, &mut scene)?;
    }
    if let Some(fov) = job.dome_master {
        projection = dome_master(job, fov, &gpu, &mut renderer, &mut scene)?;
    }
    // A paged terrain pages for the tiles the channel's rays see, not the scene camera's.
    if let (Some(p), Some(rays)) = (&paging, projection.rays) {
        p.borrow_mut().set_channel(rays);
    }
    let mut settings = RenderSettings::from_scene(&scene.desc);
    job.toggles.apply(&mut settings);
    let prepared = Prepared {
        scene,
        world,
        gpu,
        projection,
        settings,
        paging,
    };
    Ok((prepared, renderer))
}

/// Renders `job.frames` frames and writes them to `job.out_dir`; returns the file paths.
pub fn run(job: &RenderJob) -> Result<Vec<PathBuf>> {
    let last_frame = last_frame(job)?;
    let (mut p, mut renderer) = prepare(job)?;
    std::fs::create_dir_all(&job.out_dir).map_err(|e| Error::io(&job.out_dir, e))?;
    // A paged window follows the camera (its `[path]` beyond the scene's window).
    let mut follower = match &p.paging {
        Some(_) => Some(Follower::new(&p.scene, &p.world.terrain)?),
        None => None,
    };
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
        let cam = match &mut follower {
            Some(f) => p.follow(f, &mut renderer, frame).map_err(at)?,
            None => p.scene.camera(frame, &p.world.terrain),
        };
        let frames = p.frames(job);
        written.extend(frames.render(&mut renderer, frame, &cam).map_err(at)?);
    }
    Ok(written)
}

/// The last frame number, after checking `--frames` and that `--first` + `--frames` − 1 fits.
fn last_frame(job: &RenderJob) -> Result<u32> {
    if job.frames == 0 || job.frames > 100_000 {
        return Err(Error::invalid(
            "--frames",
            format!("must be 1..=100000, got {}", job.frames),
        ));
    }
    job.first_frame.checked_add(job.frames - 1).ok_or_else(|| {
        Error::invalid(
            "--first",
            format!(
                "{} with --frames {} runs past the largest frame number {}: lower --first or --frames",
                job.first_frame,
                job.frames,
                u32::MAX
            ),
        )
    })
}

/// The pool size of a paged terrain: `--terrain-memory` or the scene's `[terrain] memory`.
fn paged_memory(job: &RenderJob, scene: &Scene) -> Option<u64> {
    job.terrain_memory.or(scene.desc.terrain.memory)
}

/// A channel's rays as the pager's cone, where the terrain is paged (none otherwise: the bundle
/// walks every projector pixel).
fn channel_rays(
    job: &RenderJob,
    scene: &Scene,
    points: &crate::display::screen_points::ScreenPoints,
    eye: glam::DVec3,
    offset: glam::DMat3,
) -> Option<ChannelRays> {
    paged_memory(job, scene)?;
    let bundle = points.ray_bundle(eye)?;
    Some(ChannelRays { bundle, offset })
}

/// Sets `renderer` up to render through channel `job.display.channel` of the display config
/// `config` (at the projector's resolution), direct or two-pass.
fn through_channel(
    job: &RenderJob,
    config: &Path,
    gpu: &Gpu,
    renderer: &mut TerrainRenderer,
    scene: &mut Scene,
) -> Result<Projection> {
    let d = &job.display;
    if job.size.is_some() {
        return Err(Error::invalid(
            "--size",
            "a distortion table renders at the projector's resolution; drop --size",
        ));
    }
    let cfg = crate::display::DisplayConfig::load(config)?;
    let channel = super::channel::channel(&cfg, &config.display().to_string(), d.channel)?;
    let p = channel.projector;
    let points = cfg.channel_points(d.channel)?;
    let lit = points.points.iter().filter(|p| p.is_some()).count();
    if lit == 0 {
        return Err(Error::invalid(
            format!("{} channel {}", config.display(), d.channel),
            "no projector pixel reaches the screen",
        ));
    }
    let eye = glam::DVec3::from(d.eye.unwrap_or(cfg.eye.position));
    renderer.set_display(gpu, &points, eye)?;
    if let Some(v) = channel.view {
        renderer.set_view_offset(v.matrix());
    }
    // Direct mode blends on the GPU; two-pass mode after its CPU warp.
    let blend = ChannelBlend::new(&cfg, d.channel);
    let mut projection = Projection {
        rays: channel_rays(
            job,
            scene,
            &points,
            eye,
            channel.view.map_or(glam::DMat3::IDENTITY, |v| v.matrix()),
        ),
        ..Projection::default()
    };
    if d.two_pass {
        projection.blend_after_warp = blend;
    } else {
        renderer.set_blend(gpu, blend.as_ref())?;
    }
    let mut mode = json!("direct: one ray per projector pixel");
    if d.two_pass {
        let two_pass = TwoPass::new(&points, eye, channel.view.map(|v| v.matrix()))?;
        mode = json!(two_pass.describe());
        projection.two_pass = Some(two_pass);
    }
    scene.desc.output.width = p.width;
    scene.desc.output.height = p.height;
    projection.meta = json!({
        "config": config.display().to_string(),
        "channel": d.channel,
        "channel_name": channel.name,
        "eye_display_frame": eye.to_array(),
        "pixels_on_screen": lit,
        "mode": mode,
        "model": "per-pixel ray = world_from_display * normalize(screen_point(pixel) - eye); world_from_display maps display x, y, z to the camera's right, forward, up",
    });
    Ok(projection)
}

/// Sets `renderer` up to render a square dome master of `fov` degrees.
fn dome_master(
    job: &RenderJob,
    fov: f64,
    gpu: &Gpu,
    renderer: &mut TerrainRenderer,
    scene: &mut Scene,
) -> Result<Projection> {
    crate::display::dome_master::check_fov("--dome-master", fov)?;
    if job.display.display.is_some() {
        return Err(Error::invalid(
            "--dome-master",
            "renders the fulldome master itself; drop --display (use `relief warp apply` to \
             warp a dome master into a projector channel)",
        ));
    }
    let o = &mut scene.desc.output;
    let size = o.width.min(o.height);
    (o.width, o.height) = (size, size);
    let points = view_points(size, size, |x, y| {
        crate::display::dome_master::direction(x, y, size, fov)
    });
    renderer.set_display(gpu, &points, glam::DVec3::ZERO)?;
    Ok(Projection {
        rays: channel_rays(
            job,
            scene,
            &points,
            glam::DVec3::ZERO,
            glam::DMat3::IDENTITY,
        ),
        meta: json!({
            "mode": format!("dome master: {fov}° angular fisheye, {size}x{size}"),
            "model": "zenith (vehicle up) at the centre, vehicle forward at the bottom, right to the right; radius proportional to the angle from the zenith",
        }),
        ..Projection::default()
    })
}

/// What every frame of a run shares.
pub struct Frames<'a> {
    job: &'a RenderJob,
    gpu: &'a Gpu,
    scene: &'a Scene,
    terrain: &'a Terrain,
    settings: &'a RenderSettings,
    projection: &'a Projection,
    fps: f64,
    paging: Option<&'a RefCell<Paging>>,
}

impl<'a> Frames<'a> {
    /// The same frames with `scene` in place of the run's (the host's sun and fog).
    pub fn with_scene<'b>(&self, scene: &'b Scene) -> Frames<'b>
    where
        'a: 'b,
    {
        Frames {
            job: self.job,
            gpu: self.gpu,
            scene,
            terrain: self.terrain,
            settings: self.settings,
            projection: self.projection,
            fps: self.fps,
            paging: self.paging,
        }
    }

    /// Renders frame `frame` through `cam` and writes its three files (none of them when one
    /// cannot be).
    fn render(
        &self,
        renderer: &mut TerrainRenderer,
        frame: u32,
        cam: &Camera,
    ) -> Result<[PathBuf; 3]> {
        renderer.set_time(frame as f64 / self.fps);
        let wait = self.job.frames == 1 || self.job.wait_resident;
        let paging = self.page(renderer, cam, wait)?;
        let out = self.render_camera(renderer, cam)?;
        self.write(&out, cam, frame, |m| {
            if let Some(p) = paging {
                m["paging"] = p;
            }
        })
    }

    /// Paged mode: the pager's step for `cam` before the frame (with `wait`, until the view's
    /// tiles are resident); the statistics for the frame JSON. Nothing without paging.
    pub fn page(
        &self,
        renderer: &mut TerrainRenderer,
        cam: &Camera,
        wait: bool,
    ) -> Result<Option<serde_json::Value>> {
        let Some(p) = self.paging else {
            return Ok(None);
        };
        let mut p = p.borrow_mut();
        if wait {
            let limit = std::time::Duration::from_secs(60);
            let (st, steps) = p.settle(self.gpu, renderer, self.terrain, cam, limit)?;
            if st.missing > 0 {
                log::warn!(
                    "{} wanted tile(s) still not resident after 60 s: rendering with coarser levels there",
                    st.missing
                );
            }
            log::info!("paging: resident after {steps} pager step(s)");
        } else {
            p.step(self.gpu, renderer, self.terrain, cam)?;
        }
        Ok(Some(p.json()))
    }

    /// Renders through `cam` (the job's projection and pattern) and returns the pixels.
    pub fn render_camera(
        &self,
        renderer: &mut TerrainRenderer,
        cam: &Camera,
    ) -> Result<FrameOutput> {
        let (gpu, scene, terrain, settings) = (self.gpu, self.scene, self.terrain, self.settings);
        if self.job.pattern {
            let params = crate::display::pattern::PatternParams::grid(cam.basis().2);
            renderer.set_pattern(gpu, Some(params));
        }
        let mut out = match &self.projection.two_pass {
            Some(tp) => render_two_pass(
                gpu,
                renderer,
                terrain,
                &scene.desc,
                cam.pose,
                settings,
                &tp.faces,
                &tp.dirs,
                cam.width,
                cam.height,
            )?,
            None => renderer.capture(gpu, terrain, &scene.desc, cam, settings)?,
        };
        if let Some(b) = &self.projection.blend_after_warp {
            b.apply_rgba8(&mut out.rgba);
        }
        Ok(out)
    }

    /// Writes frame `frame`'s three files to the job's output directory (none of them when
    /// one cannot be); `edit` adds to the frame JSON.
    pub fn write(
        &self,
        out: &FrameOutput,
        cam: &Camera,
        frame: u32,
        edit: impl FnOnce(&mut serde_json::Value),
    ) -> Result<[PathBuf; 3]> {
        let (gpu, scene, terrain, settings) = (self.gpu, self.scene, self.terrain, self.settings);
        let [png, tif, meta] = frame_paths(&self.job.out_dir, frame as u64);
        // None of the frame's files is written when one of them cannot be.
        for p in [&png, &tif, &meta] {
            fileio::check_writable_target(p)?;
        }
        let mut m = frame_metadata(gpu, scene, terrain, cam, settings, frame, out);
        if !self.projection.meta.is_null() {
            m["display"] = self.projection.meta.clone();
            m["camera"]["model"] =
                json!("distortion-table (see display); the pinhole intrinsics do not apply");
        }
        edit(&mut m);
        write_frame_files(&png, &tif, &meta, out, &m)?;
        log::info!(
            "frame {frame}: raygen {:.1} ms, tile {:.1} ms, cast {:.1} ms, free forms {:.1} ms, voxels {:.1} ms, voxel shadows {:.1} ms, free-form shadows {:.1} ms, shade {:.1} ms, volume shadows {:.1} ms, volume {:.1} ms -> {}",
            out.times.raygen_ms,
            out.times.tile_ms,
            out.times.cast_ms,
            out.times.objects_ms,
            out.times.voxels_ms,
            out.times.voxel_shadow_ms,
            out.times.object_shadow_ms,
            out.times.shade_ms,
            out.times.volume_shadow_ms,
            out.times.volume_ms,
            png.display()
        );
        Ok([png, tif, meta])
    }
}
