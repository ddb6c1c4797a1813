//! `--terrain-memory MB`: a database scene rendered through the paged tile pool
//! (`gpu::terrain_pool`, `TerrainRenderer::new_paged`) instead of its window uploaded whole.
//! [`Paging`] drives the host pager once a frame: `Pager::update` for the camera's view, then
//! the uploads copied into the GPU pool (queue writes; neither blocks on a read).

use crate::db::pager::{FrameStats, Pager, PagerOptions, TileStore, View};
use crate::db::{self, Database};
use crate::display::screen_points::RayBundle;
use crate::gpu::terrain_pool::TerrainPool;
use crate::gpu::{Gpu, TerrainRenderer};
use crate::scene::{Camera, Scene};
use crate::terrain::desc::HeightSource;
use crate::terrain::{GeoRef, HeightMapping, Terrain};
use crate::world::World;
use crate::{Error, Result};
use glam::DVec3;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The host pager of a paged renderer and what maps a camera to its view.
pub struct Paging {
    pager: Pager,
    geo: GeoRef,
    /// The pool's budget in bytes.
    pub pool_bytes: u64,
    /// The last frame's statistics.
    pub last: FrameStats,
    /// A display channel's rays, paged for instead of the camera's frustum.
    channel: Option<ChannelRays>,
    /// The window this renderer's pool is set to ([`Paging::sync_window`]).
    spec: db::WindowSpec,
}

/// Moves a paged scene's window with the eye ([`Follower::follow`]): the window now, and what
/// it is rebuilt from when it moves. One per world; each paged renderer of the world then
/// takes the new window ([`Paging::sync_window`]).
///
/// The scene's camera, `[path]` and a window's free flight stay in the scene's own frame (the
/// metres of the window it was loaded with, on it or beyond it); [`Follower::to_window`] puts
/// their positions into the frame of the window now.
pub struct Follower {
    spec: db::WindowSpec,
    /// The window the scene was loaded with, and its terrain (hollow: no samples held).
    scene_spec: db::WindowSpec,
    scene_terrain: Terrain,
    /// Cells a tile side.
    n: usize,
    /// Samples per degree of the window's level.
    per_degree: f64,
    /// First and last sample of the window's level (its tiles' range).
    lo: [i64; 2],
    hi: [i64; 2],
    desc: crate::terrain::TerrainDesc,
    base_dir: std::path::PathBuf,
    /// The last window that could not be made (not tried again).
    refused: Option<db::WindowSpec>,
    /// A draped terrain: its image covers the scene's window only, so the window stays
    /// (said once, when the eye first wants it moved).
    draped: bool,
    /// The warning about a draped terrain was given.
    draped_said: bool,
}

/// Refuses `--terrain-memory` of 0 or more than 1 TiB.
fn pool_bytes(mb: u64) -> Result<u64> {
    if mb == 0 || mb > 1 << 20 {
        return Err(Error::invalid(
            "--terrain-memory",
            format!("{mb} MB: give the tile pool's size in MB, 1..=1048576"),
        ));
    }
    Ok(mb << 20)
}

/// `scene`'s database, opened, and its window as a paged scene places it (as `World::load_as`
/// placed the hollow window: on a tile's corner); a scene without a database is an error
/// naming `--terrain-memory`.
fn paged_window(scene: &Scene) -> Result<(Database, db::WindowSpec)> {
    let HeightSource::Database {
        path,
        window,
        level,
    } = scene.desc.terrain.height_source()?
    else {
        return Err(Error::invalid(
            "--terrain-memory",
            format!(
                "pages a terrain database; {} has no `[terrain] database` (height files and procedural terrains are uploaded whole)",
                scene.path.display()
            ),
        ));
    };
    let database = Database::open(&scene.base_dir.join(path))?;
    let spec = db::window::on_tile_corners(
        db::window::resolve(&database, window, level)?,
        database.tile_cells(),
    );
    Ok((database, spec))
}

/// A paged renderer of `world` (the window of `scene`'s database, its finest level, loaded
/// hollow by `World::load_as(scene, true)` or whole) with a pool of `mb` MB, its free forms,
/// volumes and voxel models, and the pager feeding it (the floor already uploaded). A scene without a database is an error naming
/// `--terrain-memory`.
pub fn renderer(
    gpu: &Gpu,
    scene: &Scene,
    world: &World,
    mb: u64,
) -> Result<(TerrainRenderer, Paging)> {
    let pool_bytes = pool_bytes(mb)?;
    let (mut database, spec) = paged_window(scene)?;
    // Host memory within the budget: the reads' cache no larger than the pool.
    database.set_cache_bytes(pool_bytes);
    let fine = database.header().levels.len() as u32 - 1;
    if spec.level != fine {
        return Err(Error::invalid(
            "terrain.level",
            format!(
                "paged rendering (--terrain-memory) reads the database's finest level {fine}; the scene's window renders level {} (set `level = {fine}` with a window that fits 16384 samples a side)",
                spec.level
            ),
        ));
    }
    let terrain = &world.terrain;
    let geo = terrain.field.geo.ok_or_else(|| {
        Error::invalid(
            "terrain",
            "a database window has no georeference".to_string(),
        )
    })?;
    let n = database.tile_cells();
    let store: Arc<dyn TileStore> = Arc::new(database);
    let opts = PagerOptions {
        pool_bytes,
        ..PagerOptions::default()
    };
    let (pager, first) = Pager::new(store, opts)?;
    let (slots, _) = pager.slots();
    let mut pool = TerrainPool::new(gpu, pager.page_table(), n, slots)?;
    pool.set_height_mapping(HeightMapping::of(&scene.desc.terrain)?);
    let mut r = TerrainRenderer::new_paged(gpu, terrain, pool, [spec.i0, spec.j0])?;
    r.apply_pages(gpu, &first, pager.page_table());
    super::upload::objects(gpu, &mut r, world)?;
    let paging = Paging {
        pager,
        geo,
        pool_bytes,
        last: FrameStats::default(),
        channel: None,
        spec,
    };
    Ok((r, paging))
}

/// A display channel's rays for the pager: their cone in the display frame and the channel's
/// view offset (world direction = attitude · offset · display direction, as the GPU's table
/// ray generation).
#[derive(Clone, Copy, Debug)]
pub struct ChannelRays {
    pub bundle: RayBundle,
    pub offset: glam::DMat3,
}

impl Paging {
    /// The pager's view of `cam` over `terrain` (eye longitude, latitude and height through
    /// the window's georeference; heading and pitch as the camera's, or the channel's rays).
    pub fn view(&self, terrain: &Terrain, cam: &Camera) -> View {
        view_of(&self.geo, terrain, cam, self.channel.as_ref())
    }

    /// Pages for a display channel's rays instead of the camera's frustum (a dome or cylinder
    /// channel looks elsewhere and wider than the scene camera).
    pub fn set_channel(&mut self, channel: ChannelRays) {
        self.channel = Some(channel);
    }
}

/// The pager's view of `cam` over `terrain` whose window has the georeference `geo`: the eye's
/// longitude, latitude and height; the camera's heading, pitch, field of view and size, or
/// with `channel` the direction of its rays' mean (through the camera's attitude and the
/// channel's offset) and their cone.
pub fn view_of(
    geo: &GeoRef,
    terrain: &Terrain,
    cam: &Camera,
    channel: Option<&ChannelRays>,
) -> View {
    let g = terrain.frame.world_to_grid(cam.pose.position);
    let mut v = View {
        lon: geo.lon0 + g.x * geo.dlon,
        lat: geo.lat0 + g.y * geo.dlat,
        height: g.z,
        heading: cam.pose.heading,
        pitch: cam.pose.pitch,
        fov: cam.pose.fov,
        width: cam.width,
        height_px: cam.height,
        cone: None,
    };
    if let Some(c) = channel {
        let (r, d, f) = cam.basis();
        let m = glam::DMat3::from_cols(r, f, -d) * c.offset;
        // The world frame of a database window is x east, y north, z up.
        let a = (m * c.bundle.axis).normalize();
        v.heading = a.x.atan2(a.y).to_degrees();
        v.pitch = a.z.clamp(-1.0, 1.0).asin().to_degrees();
        v.cone = Some([c.bundle.half_angle, c.bundle.pixel]);
    }
    v
}

impl Paging {
    /// One frame's paging before its cast: the pager's update for `cam` and its uploads
    /// copied into the pool. Never waits for a read.
    pub fn step(
        &mut self,
        gpu: &Gpu,
        r: &mut TerrainRenderer,
        terrain: &Terrain,
        cam: &Camera,
    ) -> Result<FrameStats> {
        let (uploads, stats) = self.pager.update(&self.view(terrain, cam))?;
        r.apply_pages(gpu, &uploads, self.pager.page_table());
        self.last = stats.clone();
        Ok(stats)
    }

    /// Sets this renderer's pool to `world`'s window, sample `spec` of the database's finest
    /// level, where [`Follower::follow`] moved it: the pool keeps its tiles and makes its
    /// residency map for the new window; the world's objects, moved with it, are uploaded
    /// again. Nothing where the pool is already there.
    pub fn sync_window(
        &mut self,
        gpu: &Gpu,
        r: &mut TerrainRenderer,
        world: &World,
        spec: db::WindowSpec,
    ) -> Result<()> {
        if spec == self.spec {
            return Ok(());
        }
        r.set_paged_window(gpu, &world.terrain, [spec.i0, spec.j0])?;
        super::upload::objects(gpu, r, world)?;
        self.geo = world.terrain.field.geo.ok_or_else(|| {
            Error::invalid(
                "terrain",
                "a database window has no georeference".to_string(),
            )
        })?;
        self.spec = spec;
        Ok(())
    }

    /// The last frame's statistics as frame metadata (`paging` in the frame JSON).
    pub fn json(&self) -> serde_json::Value {
        let s = &self.last;
        serde_json::json!({
            "window": [self.spec.i0, self.spec.j0],
            "pool_bytes": self.pool_bytes,
            "resident": s.resident,
            "resident_bytes": s.resident_bytes,
            "wanted": s.wanted,
            "missing": s.missing,
            "reads_in_flight": s.pending,
            "staged": s.staged,
            "uploads": s.uploads,
            "frames_missing": s.frames_missing,
        })
    }

    /// Steps (2 ms apart) until `cam`'s wanted tiles are all resident and nothing is being
    /// read or waiting, or `timeout` passes; returns the last statistics and the steps taken.
    pub fn settle(
        &mut self,
        gpu: &Gpu,
        r: &mut TerrainRenderer,
        terrain: &Terrain,
        cam: &Camera,
        timeout: Duration,
    ) -> Result<(FrameStats, u32)> {
        let start = Instant::now();
        let mut steps = 0;
        loop {
            let st = self.step(gpu, r, terrain, cam)?;
            steps += 1;
            let settled = st.missing == 0 && st.pending == 0 && st.staged == 0;
            if settled || start.elapsed() > timeout {
                return Ok((st, steps));
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

impl Follower {
    /// The follower of `scene`'s paged window (as [`renderer`] places it: the finest level,
    /// on a tile corner), `terrain` the world's terrain as loaded. A draped terrain's window
    /// stays where it is (its image covers the scene's window only; a warning says so the
    /// first time the eye would move it).
    pub fn new(scene: &Scene, terrain: &Terrain) -> Result<Follower> {
        let (database, spec) = paged_window(scene)?;
        let n = database.tile_cells();
        let lv = &database.header().levels[spec.level as usize];
        Ok(Follower {
            spec,
            scene_spec: spec,
            scene_terrain: terrain.clone(),
            n,
            per_degree: lv.per_degree,
            lo: [lv.x0 as i64 * n as i64, lv.y0 as i64 * n as i64],
            hi: [lv.x1 as i64 * n as i64, lv.y1 as i64 * n as i64],
            desc: scene.desc.terrain.clone(),
            base_dir: scene.base_dir.clone(),
            refused: None,
            draped: scene.desc.terrain.drape.is_some(),
            draped_said: false,
        })
    }

    /// The window now.
    pub fn spec(&self) -> db::WindowSpec {
        self.spec
    }

    /// Position `p` of the scene's own frame in the frame of the window now (`terrain`, the
    /// world's): the same point of the level, at the same height. `p` itself while the window
    /// has not moved.
    pub fn to_window(&self, terrain: &Terrain, p: DVec3) -> DVec3 {
        if self.spec == self.scene_spec {
            return p;
        }
        let shift = DVec3::new(
            (self.scene_spec.i0 - self.spec.i0) as f64,
            (self.scene_spec.j0 - self.spec.j0) as f64,
            0.0,
        );
        let g = self.scene_terrain.frame.world_to_grid(p) + shift;
        terrain.frame.grid_to_world(g)
    }

    /// Frame `frame`'s camera of `scene` (its `[path]` or its camera) in the scene's own frame.
    pub fn scene_camera(&self, scene: &Scene, frame: u32) -> Camera {
        scene.camera(frame, &self.scene_terrain)
    }

    /// [`Follower::follow`] for an eye at `eye` in the scene's own frame (a `[path]`, the
    /// window's free flight). Returns whether the window moved.
    pub fn follow_scene_eye(&mut self, world: &mut World, eye: DVec3) -> Result<bool> {
        let at = self.to_window(&world.terrain, eye);
        match world.terrain.world_to_geodetic(at) {
            Some(lla) => self.follow(world, lla),
            None => Ok(false),
        }
    }

    /// Moves the window to follow the eye at geodetic `[lat, lon, alt]` (on the window or off
    /// it) where [`db::window::follow`] says so: `world.terrain` becomes the hollow terrain of
    /// the new window (same size, on a tile corner) and the scene's free forms, volumes and
    /// voxel models keep their places on the ground (moved from the old window's frame to
    /// the new one's). Cameras and entities placed geodetically after this land in the new
    /// frame; each paged renderer then takes the window with [`Paging::sync_window`].
    /// Returns whether it moved.
    pub fn follow(&mut self, world: &mut World, [lat, lon, _]: [f64; 3]) -> Result<bool> {
        let at = [
            (lon + 180.0) * self.per_degree,
            (lat + 90.0) * self.per_degree,
        ];
        let Some(spec) = db::window::follow(self.spec, self.n, self.lo, self.hi, at) else {
            return Ok(false);
        };
        if self.refused == Some(spec) {
            return Ok(false);
        }
        if self.draped {
            if !std::mem::replace(&mut self.draped_said, true) {
                log::warn!(
                    "the paged window does not follow the eye: the terrain has a drape, which covers the scene's window only"
                );
            }
            return Ok(false);
        }
        let start = Instant::now();
        // The world's hollow window's database (its index read once, its tile cache warm).
        let from = match &world.terrain.hollow {
            Some(h) => h,
            None => {
                return Err(Error::invalid(
                    "--terrain-memory",
                    "a window follows the eye on a paged (hollow) database window only",
                ))
            }
        };
        let built = crate::terrain::hollow::window_spec(&self.desc, &self.base_dir, from, &spec);
        // A window that cannot be made (no data under it, a read failing) leaves the window
        // where it is: the IG keeps running.
        let terrain = match built {
            Ok(t) => t,
            Err(e) => {
                log::warn!(
                    "the paged window stays at ({}, {}): moving it to ({}, {}) failed: {e}",
                    self.spec.i0,
                    self.spec.j0,
                    spec.i0,
                    spec.j0
                );
                self.refused = Some(spec);
                return Ok(false);
            }
        };
        let old = &world.terrain;
        let shift = DVec3::new(
            (self.spec.i0 - spec.i0) as f64,
            (self.spec.j0 - spec.j0) as f64,
            0.0,
        );
        // The same sample of the level, in the new window's world frame.
        let moved = |p: DVec3| {
            terrain
                .frame
                .grid_to_world(old.frame.world_to_grid(p) + shift)
                - p
        };
        for o in &mut world.objects {
            *o = o.translated(moved(o.position));
        }
        for v in &mut world.volumes {
            *v = v.translated(moved(v.anchor()));
        }
        for m in &mut world.voxels {
            *m = m.translated(moved(m.position));
        }
        log::info!(
            "paged window moved with the eye: {}x{} samples from ({}, {}), was from ({}, {}); terrain and objects in {:.1} ms",
            spec.width,
            spec.height,
            spec.i0,
            spec.j0,
            self.spec.i0,
            self.spec.j0,
            start.elapsed().as_secs_f64() * 1e3
        );
        world.terrain = terrain;
        self.spec = spec;
        Ok(true)
    }
}
