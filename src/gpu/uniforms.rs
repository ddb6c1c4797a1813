//! The CPU side of the terrain passes' parameter blocks: the `Frame` and `RayGen` blocks
//! ([`super::types`]) filled in from a terrain, a scene, a camera and the render settings.

use super::frame::{RenderSettings, TraceMode};
use super::types::{FrameUniforms, RayGenUniforms, MAX_LEVELS};
use crate::cpu::clouds::Deck;
use crate::scene::clouds::{CloudLayer, MAX_CLOUD_LAYERS};
use crate::scene::{Camera, SceneDesc};
use crate::terrain::Terrain;

fn v4(v: glam::DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
}

/// Pinhole ray-generation uniforms for a camera.
pub fn raygen_uniforms(cam: &Camera, display_eye: glam::DVec3) -> RayGenUniforms {
    let (r, d, f) = cam.basis();
    let (fx, fy, cx, cy) = cam.intrinsics();
    RayGenUniforms {
        right: v4(r, 0.0),
        down: v4(d, 0.0),
        forward: v4(f, 0.0),
        intrinsics: [fx as f32, fy as f32, cx as f32, cy as f32],
        size: [cam.width, cam.height, 0, 0],
        eye: v4(display_eye, 1.0),
    }
}

/// [`raygen_uniforms`] for table ray generation with a channel view offset: the basis
/// becomes the columns of `world_from_display · offset`.
pub fn table_raygen_uniforms(
    cam: &Camera,
    display_eye: glam::DVec3,
    offset: glam::DMat3,
) -> RayGenUniforms {
    let (r, d, f) = cam.basis();
    let m = glam::DMat3::from_cols(r, f, -d) * offset;
    RayGenUniforms {
        right: v4(m.col(0), 0.0),
        down: v4(-m.col(2), 0.0),
        forward: v4(m.col(1), 0.0),
        ..raygen_uniforms(cam, display_eye)
    }
}

/// The frame uniform block for a terrain, scene, camera and settings.
pub fn frame_uniforms(
    terrain: &Terrain,
    scene: &SceneDesc,
    cam: &Camera,
    s: &RenderSettings,
    tiles: [u32; 2],
) -> FrameUniforms {
    let fr = &terrain.frame;
    let curv = terrain.curvature(cam.pose.position);
    // A grid step in the eye's metric (the frame's spacing on a flat terrain).
    let [sx, sy] = [fr.spacing[0] * curv.metric.x, fr.spacing[1] * curv.metric.y];
    let eye = fr.world_to_grid(cam.pose.position);
    let local =
        |v: glam::DVec3| glam::DVec3::new(v.dot(fr.axis_x), v.dot(fr.axis_y), v.dot(fr.normal));
    let day = scene.daylight();
    let sun = day.light;
    let fog_colour = day.fog_colour;
    let sigma = if scene.fog.visibility > 0.0 {
        3.912 / scene.fog.visibility
    } else {
        0.0
    };
    let mut levels = [[0u32; 4]; MAX_LEVELS];
    for (dst, l) in levels.iter_mut().zip(&terrain.pyramid.levels) {
        *dst = [l.cells[0], l.cells[1], l.stored[0], l.offset];
    }
    let (drape_map, drape_size) = match &terrain.drape {
        Some((d, m)) => (
            [
                m.offset[0] as f32,
                m.offset[1] as f32,
                m.scale[0] as f32,
                m.scale[1] as f32,
            ],
            [
                d.width as u32,
                d.height as u32,
                crate::terrain::drape_mips::level_count(d, super::terrain_passes::DRAPE_LEVELS)
                    as u32,
                0,
            ],
        ),
        None => ([0.0; 4], [1, 1, 0, 0]),
    };
    let (mode, march) = match s.mode {
        TraceMode::Pyramid => (0, [0.0; 4]),
        TraceMode::March {
            step_cells,
            bisections,
        } => (1, [step_cells, bisections as f32, 0.0, 0.0]),
    };
    let c = |v: [f32; 3], w: f32| [v[0], v[1], v[2], w];
    let mut slack = (4.0 * crate::cpu::traverse::height_slack(terrain)).max(1e-3);
    if !curv.is_flat() {
        // f32 rounding of the drop (up to ~10 km at 350 km) in the cell bound test.
        slack = slack.max(1e-6 * curv.max_drop(terrain.cells()));
    }
    FrameUniforms {
        eye: v4(eye, 1.0),
        grid_from_world: [
            v4(fr.axis_x / sx, 0.0),
            v4(fr.axis_y / sy, 0.0),
            v4(fr.normal, 0.0),
        ],
        local_from_world: [v4(fr.axis_x, 0.0), v4(fr.axis_y, 0.0), v4(fr.normal, 0.0)],
        sun_local: v4(local(sun), day.intensity as f64),
        sun_grid: v4(fr.world_dir_to_grid(sun) / curv.metric.extend(1.0), 0.0),
        sun_colour: c(day.sun_colour, (0.27f64).to_radians().cos() as f32),
        up_local: v4(local(glam::DVec3::Z), 0.0),
        sky_zenith: c(day.zenith, day.ambient),
        sky_horizon: c(day.horizon, 0.0),
        fog_colour: c(fog_colour, sigma as f32),
        fog: [scene.fog.scale_height as f32, 0.0, 0.0, 0.0],
        spacing: [sx as f32, sy as f32, (1.0 / sx) as f32, (1.0 / sy) as f32],
        heights_range: [
            terrain.min_height,
            terrain.max_height,
            crate::cpu::query::shadow_offset(terrain) as f32,
            slack as f32,
        ],
        drape_map,
        size: [cam.width, cam.height, tiles[0], tiles[1]],
        grid: [
            terrain.field.width as u32,
            terrain.field.height as u32,
            terrain.pyramid.levels.len() as u32,
            0,
        ],
        mode: [
            mode,
            s.max_steps,
            (!terrain.walls) as u32,
            s.tile_prepass as u32,
        ],
        drape_size,
        march,
        pyramid_dims: [0; 4],
        eye_world: v4(cam.pose.position, 1.0),
        sun_world: v4(sun, 0.0),
        objects: [0; 4],
        stamp: [0; 4],
        curvature: [
            curv.eye.x as f32,
            curv.eye.y as f32,
            curv.k.x as f32,
            curv.k.y as f32,
        ],
        lod: [
            s.lod.map_or(0.0, |scale| (scale * 2.0 / sx.max(sy)) as f32),
            0.0,
            0.0,
            0.0,
        ],
        clouds: cloud_rows(&scene.clouds),
        cloud_info: [
            scene.clouds.len().min(MAX_CLOUD_LAYERS) as f32,
            fr.spacing[0] as f32,
            fr.spacing[1] as f32,
            0.0,
        ],
        levels,
    }
}

/// The frame block's rows of the cloud layers (`clouds.wgsl`).
fn cloud_rows(layers: &[CloudLayer]) -> [[f32; 4]; 2 * MAX_CLOUD_LAYERS] {
    let mut rows = [[0.0; 4]; 2 * MAX_CLOUD_LAYERS];
    for (k, l) in layers.iter().take(MAX_CLOUD_LAYERS).enumerate() {
        let d = Deck::new(l);
        rows[2 * k] = [d.base, d.top, d.sigma, d.threshold].map(|v| v as f32);
        rows[2 * k + 1] = [
            d.mean as f32,
            d.inv_feature as f32,
            d.seed as f32,
            d.relief as f32,
        ];
    }
    rows
}
