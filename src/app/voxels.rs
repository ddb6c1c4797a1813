//! `relief voxels convert`: a voxel model to the segment format (.rvs), and the sizes
//! compared (`relief bench voxels` is in [`super::bench::voxels`]).

use crate::voxel::{desc::load_frames, segment};
use crate::{Error, Result};
use std::path::Path;

/// Sizes of a model in the formats compared.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SizeReport {
    pub voxels: usize,
    pub dims: [u32; 3],
    /// Dense grid, 1 byte (palette index) per voxel.
    pub dense_bytes: u64,
    /// Dense grid, 4 bytes (RGBA) per voxel.
    pub dense_rgba_bytes: u64,
    pub source_bytes: u64,
    pub segment_bytes: u64,
}

/// Converts `input` (.vox or .rvs; frame 0) to a segment file `output` and reports sizes.
pub fn convert(input: &Path, output: &Path) -> Result<SizeReport> {
    if output.extension().and_then(|e| e.to_str()) != Some("rvs") {
        return Err(Error::invalid(
            "output",
            format!(
                "{}: the segment format's extension is .rvs",
                output.display()
            ),
        ));
    }
    let m = load_frames(input)?.remove(0);
    let source_bytes = std::fs::metadata(input)
        .map_err(|e| Error::io(input, e))?
        .len();
    let segment_bytes = segment::write(&m, output)?;
    Ok(SizeReport {
        voxels: m.voxels.len(),
        dims: m.dims,
        dense_bytes: m.dense_bytes(),
        dense_rgba_bytes: m.dense_bytes() * 4,
        source_bytes,
        segment_bytes,
    })
}

/// Prints the sizes of `input`'s model.
pub fn print_sizes(input: &Path, r: &SizeReport) {
    let [x, y, z] = r.dims;
    println!("{}: {x}x{y}x{z}, {} voxels", input.display(), r.voxels);
    println!(
        "segment {} B; dense 1 B/voxel {} B ({:.1}x), dense RGBA {} B ({:.1}x); source file {} B ({:.2}x)",
        r.segment_bytes,
        r.dense_bytes,
        r.dense_bytes as f64 / r.segment_bytes as f64,
        r.dense_rgba_bytes,
        r.dense_rgba_bytes as f64 / r.segment_bytes as f64,
        r.source_bytes,
        r.source_bytes as f64 / r.segment_bytes as f64
    );
}
