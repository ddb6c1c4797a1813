//! `relief bench clouds`: the frame with the scene's cloud layers against the same frame
//! without them (the scene's first camera at `--size`), frames alternated one by one.

use super::table::{Figures, Row, RunInfo, Table};
use super::timing::interleaved_ms;
use crate::app::figures::median;
use crate::app::quality;
use crate::gpu::Stage;
use crate::{Error, Result};
use serde::Serialize;
use std::path::Path;

/// What `relief bench clouds` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct CloudsBench {
    /// The scene's `[[clouds]]` layers.
    pub layers: usize,
    /// Median frame without the layers (ms).
    pub clear_ms: f64,
    /// Median frame with them (ms).
    pub clouds_ms: f64,
    /// `clouds_ms / clear_ms`.
    pub ratio: f64,
}

/// Times `scene_path` at `size`, `frames` frames with its cloud layers alternated with
/// `frames` without (each timed alone, submit to idle), after a warm-up of each.
pub fn run(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<(RunInfo, CloudsBench)> {
    let scene_arg = scene_path.to_string_lossy();
    let size_arg = format!("{}x{}", size.0, size.1);
    let job = quality::render_job(&[&scene_arg, "--size", &size_arg])?;
    let (p, mut renderer) = crate::app::capture::prepare(&job)?;
    let cloudy = p.scene.desc.clone();
    if cloudy.clouds.is_empty() {
        return Err(Error::invalid(
            "clouds",
            format!(
                "{} has no [[clouds]] layers to measure: give a scene with some (terrains/overcast.toml)",
                scene_path.display()
            ),
        ));
    }
    let mut clear = cloudy.clone();
    clear.clouds.clear();
    let cam = p.scene.camera(0, &p.world.terrain);
    let (gpu, terrain, s) = (&p.gpu, &p.world.terrain, &p.settings);
    // Warm-up: each variant's shade pipeline is built on first use.
    for d in [&clear, &cloudy] {
        renderer.capture(gpu, terrain, d, &cam, s)?;
    }
    let [off, with] = interleaved_ms(frames, |k| {
        let d = if k == 0 { &clear } else { &cloudy };
        renderer.render(gpu, terrain, d, &cam, s, Stage::Shade)?;
        gpu.wait()
    })?;
    let (clear_ms, clouds_ms) = (median(off), median(with));
    let run = RunInfo::new(gpu, scene_path, size, frames);
    Ok((
        run,
        CloudsBench {
            layers: cloudy.clouds.len(),
            clear_ms,
            clouds_ms,
            ratio: clouds_ms / clear_ms,
        },
    ))
}

impl CloudsBench {
    /// Two rows (without, with the layers) and the ratio.
    pub fn table(&self) -> Table {
        let rows = vec![
            Row::new("clear", Figures::default().with("frame_ms", self.clear_ms)),
            Row::new(
                format!("{} cloud layers", self.layers),
                Figures::default().with("frame_ms", self.clouds_ms),
            ),
        ];
        Table {
            rows,
            summary: Figures::default().with("ratio", self.ratio),
            notes: vec![
                "the scene's first camera; each frame with its layers alternated with one without them (medians)".into(),
            ],
        }
    }
}
