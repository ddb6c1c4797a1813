//! `relief bench freeforms`: the cost of free forms on the frame, same run, same adapter: the
//! scene's objects against terrain only, then 10, 100 and 1000 generated objects in the view
//! and spread over the whole terrain.

use super::table::{Figures, Row, RunInfo, Table};
use super::timing::{interleaved_ms, scene_at_size, FrameSetup};
use crate::app::figures::median;
use crate::freeform::FreeForm;
use crate::gpu::{RenderSettings, Stage, TerrainRenderer};
use crate::scene::{Camera, SceneDesc};
use crate::terrain::Terrain;
use crate::world::World;
use crate::{Error, Result};
use serde::Serialize;
use std::path::Path;

/// What `relief bench freeforms` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct FreeFormBench {
    /// Quadrics (base + perturbations) in the scene's free forms.
    pub quadrics: usize,
    pub objects: usize,
    /// Median full-frame milliseconds (shadows on) without and with the scene's free forms,
    /// `frames` frames of each, timed one by one and interleaved.
    pub terrain_only_ms: f64,
    pub with_free_forms_ms: f64,
    /// `with_free_forms_ms / terrain_only_ms` (target ≤ 1.5).
    pub ratio: f64,
    /// Generated free forms all in the view, 150 m to 4 km away: (count, median frame ms).
    pub scaling: Vec<(usize, f64)>,
    /// Frame ms with the most generated objects over the fewest, all in view.
    pub scaling_ratio: f64,
    /// Generated free forms spread uniformly over the whole terrain, as a database of objects
    /// is, most of them out of the view: (count, median frame ms).
    pub spread: Vec<(usize, f64)>,
    /// Frame ms with the most spread objects over the fewest (the target: ≤ 3).
    pub spread_ratio: f64,
}

/// Where [`scattered_free_forms`] puts its objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scatter {
    /// In front of the camera, within the horizontal field of view, 150 m to 4 km away.
    InView,
    /// Uniformly over the whole terrain.
    OverTerrain,
}

/// `n` perturbed free forms (domed tanks, dented balls, bumpy ellipsoids) on the terrain,
/// placed as `scatter` says, deterministic.
pub fn scattered_free_forms(
    terrain: &Terrain,
    cam: &Camera,
    n: usize,
    scatter: Scatter,
) -> Result<Vec<FreeForm>> {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut rnd = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut text = String::new();
    let half = 0.5 * cam.pose.fov.to_radians();
    let (gw, gh) = (
        terrain.field.width as f64 - 1.0,
        terrain.field.height as f64 - 1.0,
    );
    for i in 0..n {
        let (x, y) = match scatter {
            Scatter::InView => {
                let dist = 150.0 + 3850.0 * rnd().powi(2);
                let ang = cam.pose.heading.to_radians() + half * (2.0 * rnd() - 1.0);
                (
                    cam.pose.position.x + dist * ang.sin(),
                    cam.pose.position.y + dist * ang.cos(),
                )
            }
            Scatter::OverTerrain => {
                let p = terrain
                    .frame
                    .grid_to_world(glam::DVec3::new(gw * rnd(), gh * rnd(), 0.0));
                (p.x, p.y)
            }
        };
        let s = 5.0 + 15.0 * rnd();
        let shape = match i % 3 {
            0 => format!(
                "shape = \"cylinder\"\nradius = {s}\nheight = {h}\nbounds = [[-{s}, -{s}, 0.0], [{s}, {s}, {h}]]\n[[objects.perturb]]\ncoefficients = [0, 0, 0, 0, 0, 0, 0, 0, {a}, {b}]\n",
                h = 2.0 * s,
                a = 1.0 / (0.4 * s),
                b = -(1.6 * s) / (0.4 * s)
            ),
            1 => format!(
                "shape = \"sphere\"\nradius = {s}\n[[objects.perturb]]\nshape = \"sphere\"\nradius = {r}\ncentre = [{s}, 0.0, {s2}]\nweight = 3.0\n",
                r = 0.6 * s,
                s2 = 0.3 * s
            ),
            _ => format!(
                "shape = \"ellipsoid\"\nradii = [{s}, {s2}, {s3}]\nheading = {h}\n[[objects.perturb]]\nshape = \"sphere\"\nradius = {r}\ncentre = [{c}, 0.0, {s3}]\nweight = -1.0\n",
                s2 = 0.6 * s,
                s3 = 0.5 * s,
                h = 360.0 * rnd(),
                r = 0.4 * s,
                c = 0.5 * s
            ),
        };
        text.push_str(&format!(
            "[[objects]]\nname = \"generated {i}\"\nposition = [{x}, {y}, 0.0]\nabove_terrain = 0.0\n{shape}\n"
        ));
    }
    let desc: SceneDesc = toml::from_str(&format!(
        "[terrain.procedural]\nsize = 2\n[camera]\nposition = [0.0, 0.0, 0.0]\n{text}"
    ))
    .map_err(|e| Error::invalid("generated objects", e.to_string()))?;
    desc.objects
        .iter()
        .enumerate()
        .filter_map(|(i, o)| {
            // Objects that would stand outside the terrain are skipped.
            match o.build(i, terrain) {
                Err(Error::Invalid { msg, .. }) if msg.contains("outside the terrain") => None,
                r => Some(r),
            }
        })
        .collect()
}

impl FrameSetup<'_> {
    /// The headline ratio: terrain only and with `objects`, one frame of each in turn (each
    /// timed alone, submit to idle), the median of each. Interleaving keeps slow spells of a
    /// shared machine from landing on one configuration only.
    fn interleaved(&self, plain: &mut TerrainRenderer, objects: &[FreeForm]) -> Result<(f64, f64)> {
        let (gpu, terrain, desc, cam, s) =
            (self.gpu, self.terrain, self.desc, self.cam, self.settings);
        let mut with = TerrainRenderer::new(gpu, terrain)?;
        with.set_objects(gpu, objects)?;
        for r in [&mut *plain, &mut with] {
            // Warm-up: shader compilation on first use, target allocation.
            r.capture(gpu, terrain, desc, cam, s)?;
        }
        let times = interleaved_ms(self.frames, |k| {
            let r = if k == 0 { &mut *plain } else { &mut with };
            r.render(gpu, terrain, desc, cam, s, Stage::Shade)?;
            gpu.wait()
        })?;
        let [a, b] = times.map(median);
        Ok((a, b))
    }

    /// Median frame ms with 10, 100 and 1000 generated objects placed as `scatter` says:
    /// (count, ms) each.
    fn scaling(&self, r: &mut TerrainRenderer, scatter: Scatter) -> Result<Vec<(usize, f64)>> {
        let (gpu, terrain, desc, cam, s) =
            (self.gpu, self.terrain, self.desc, self.cam, self.settings);
        let mut out = Vec::new();
        for n in [10, 100, 1000] {
            let generated = scattered_free_forms(terrain, cam, n, scatter)?;
            r.set_objects(gpu, &generated)?;
            // Warm-up: shader compilation on first use, target allocation.
            r.capture(gpu, terrain, desc, cam, s)?;
            let ms = self.median_ms(r, Stage::Shade)?;
            log::info!(
                "{} generated free forms ({scatter:?}): {ms:.1} ms",
                generated.len()
            );
            out.push((generated.len(), ms));
        }
        Ok(out)
    }
}

/// Runs the free-form benchmark on `scene_path` (its `[[objects]]`), then with 10, 100 and
/// 1000 generated objects.
pub fn run(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<(RunInfo, FreeFormBench)> {
    let scene = scene_at_size(scene_path, size)?;
    let world = World::load(&scene)?;
    let (terrain, objects) = (&world.terrain, &world.objects);
    let gpu = crate::app::gpu_options::open()?;
    let mut renderer = TerrainRenderer::new(&gpu, terrain)?;
    let cam = scene.camera(0, terrain);
    let settings = RenderSettings::from_scene(&scene.desc);
    let bench = FrameSetup {
        gpu: &gpu,
        terrain,
        desc: &scene.desc,
        cam: &cam,
        settings: &settings,
        frames,
    };
    let (terrain_only_ms, with_free_forms_ms) = bench.interleaved(&mut renderer, objects)?;
    let scaling = bench.scaling(&mut renderer, Scatter::InView)?;
    let spread = bench.scaling(&mut renderer, Scatter::OverTerrain)?;
    let details = FreeFormBench {
        quadrics: objects.iter().map(|o| o.nodes.len()).sum(),
        objects: objects.len(),
        terrain_only_ms,
        with_free_forms_ms,
        ratio: with_free_forms_ms / terrain_only_ms,
        scaling_ratio: scaling.last().map_or(0.0, |l| l.1) / scaling[0].1,
        scaling,
        spread_ratio: spread.last().map_or(0.0, |l| l.1) / spread[0].1,
        spread,
    };
    Ok((RunInfo::new(&gpu, scene_path, size, frames), details))
}

impl FreeFormBench {
    /// One row per frame time measured, the ratios as the summary.
    pub fn table(&self) -> Table {
        let row = |name: String, objects: usize, ms: f64| {
            Row::new(
                name,
                Figures::default()
                    .with("objects", objects as f64)
                    .with("frame_ms", ms),
            )
        };
        let mut rows = vec![
            row("terrain only".into(), 0, self.terrain_only_ms),
            row(
                "scene's free forms".into(),
                self.objects,
                self.with_free_forms_ms,
            ),
        ];
        for (label, series) in [("in view", &self.scaling), ("spread", &self.spread)] {
            for &(n, ms) in series {
                rows.push(row(format!("{n} generated, {label}"), n, ms));
            }
        }
        let summary = Figures::default()
            .with("quadrics", self.quadrics as f64)
            .with("ratio", self.ratio)
            .with("scaling_ratio", self.scaling_ratio)
            .with("spread_ratio", self.spread_ratio);
        let notes = vec![
            "terrain only and with the scene's free forms: medians of single frames, interleaved"
                .into(),
            "in view: 150 m - 4 km ahead; spread: uniformly over the terrain".into(),
        ];
        Table {
            rows,
            summary,
            notes,
        }
    }
}
