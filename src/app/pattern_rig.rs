//! The pattern rig of `relief warp verify`: renders the warp test pattern (grid and grating,
//! [`crate::display::pattern`]) through virtual or real ray tables, on a flat stub terrain
//! that no ray is cast against.

use crate::display::pattern::PatternParams;
use crate::display::screen_points::ScreenPoints;
use crate::gpu::{FrameOutput, Gpu, RenderSettings, TerrainRenderer};
use crate::scene::{Camera, Pose, Scene, SceneDesc};
use crate::terrain::{Heightfield, Terrain, TerrainFrame};
use crate::Result;
use glam::DVec3;
use std::path::Path;

/// Renders the test pattern through virtual or real ray tables (no terrain is cast).
pub struct PatternRig {
    terrain: Terrain,
    scene: SceneDesc,
    renderer: TerrainRenderer,
}

/// A view rendered by a [`PatternRig`]: the grid, the grating and the GPU ray table.
pub struct PatternView {
    pub width: u32,
    pub height: u32,
    pub grid: Vec<u8>,
    pub grating: Vec<u8>,
    pub table: Vec<[f32; 4]>,
}

impl PatternRig {
    pub fn new(gpu: &Gpu) -> Result<PatternRig> {
        let field = Heightfield::from_samples_with_voids(
            "pattern",
            2,
            2,
            vec![Some(0.0); 4],
            [1.0, 1.0],
            None,
        )?;
        let frame = TerrainFrame {
            origin: DVec3::ZERO,
            axis_x: DVec3::X,
            axis_y: DVec3::Y,
            normal: DVec3::Z,
            spacing: [1.0, 1.0],
        };
        let terrain = Terrain::new(field, frame, 1.0)?;
        let scene = Scene::parse(
            "[terrain.procedural]\nsize = 2\n[camera]\nposition = [0.5, 0.5, 100.0]\n",
            Path::new("pattern.toml"),
        )?
        .desc;
        let renderer = TerrainRenderer::new(gpu, &terrain)?;
        Ok(PatternRig {
            terrain,
            scene,
            renderer,
        })
    }

    /// Renders grid and grating through the table of `points` seen from `eye` (vehicle
    /// attitude zero: world = display frame).
    pub fn render(
        &mut self,
        gpu: &Gpu,
        points: &ScreenPoints,
        eye: DVec3,
        grid: &PatternParams,
        grating: &PatternParams,
    ) -> Result<PatternView> {
        self.renderer.set_display(gpu, points, eye)?;
        let pose = Pose {
            position: DVec3::new(0.5, 0.5, 100.0),
            heading: 0.0,
            pitch: 0.0,
            roll: 0.0,
            fov: 60.0,
        };
        let cam = Camera::new(pose, points.width, points.height);
        let settings = RenderSettings::from_scene(&self.scene);
        let mut shot = |p: &PatternParams| -> Result<FrameOutput> {
            self.renderer.set_pattern(gpu, Some(*p));
            self.renderer
                .capture(gpu, &self.terrain, &self.scene, &cam, &settings)
        };
        let g = shot(grid)?;
        let r = shot(grating)?;
        Ok(PatternView {
            width: points.width,
            height: points.height,
            grid: g.rgba,
            grating: r.rgba,
            table: self.renderer.read_ray_table(gpu)?,
        })
    }
}
