//! What a frame is asked for and what it gives back: render settings, the stage it is rendered
//! to, per-pass times and the captured output.

use crate::scene::SceneDesc;

/// How primary rays find the terrain.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum TraceMode {
    /// Maximum-pyramid traversal with exact bilinear patches (the product).
    Pyramid,
    /// Fixed-step march with bisection (benchmark baseline).
    March { step_cells: f32, bisections: u32 },
}

/// Per-frame switches.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RenderSettings {
    pub mode: TraceMode,
    pub shadows: bool,
    pub tile_prepass: bool,
    pub max_steps: u32,
    /// Footprint level of detail of the primary rays: its scale, `None` off (`render.lod`).
    pub lod: Option<f64>,
    /// Edge anti-aliasing (`render.antialias`).
    pub antialias: super::Antialias,
}

impl RenderSettings {
    /// Settings from the scene's `[render]` table.
    pub fn from_scene(desc: &SceneDesc) -> RenderSettings {
        RenderSettings {
            mode: TraceMode::Pyramid,
            shadows: desc.render.shadows,
            tile_prepass: desc.render.tile_prepass,
            max_steps: desc.render.max_steps,
            lod: desc.render.lod.scale(),
            antialias: super::Antialias::from_option(desc.render.antialias),
        }
    }
}

/// Wall-clock milliseconds per pass (each pass submitted and waited for on its own).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PassTimes {
    pub raygen_ms: f64,
    pub tile_ms: f64,
    pub cast_ms: f64,
    /// Free-form binning and cast (0 without free forms).
    pub objects_ms: f64,
    /// Voxel-model cast (0 without voxel models).
    pub voxels_ms: f64,
    /// Voxel-model shadow rays (0 without voxel models or shadows).
    pub voxel_shadow_ms: f64,
    /// Free-form shadow binning and sun rays (0 without free forms or shadows).
    pub object_shadow_ms: f64,
    pub shade_ms: f64,
    /// The sun's transmittance through the volumes at the surfaces (0 without a volume that
    /// casts a shadow).
    pub volume_shadow_ms: f64,
    /// Volume integration and compositing (0 without a volume).
    pub volume_ms: f64,
    /// Edge blend (0 without one).
    pub blend_ms: f64,
    /// Anti-aliasing: edge mask, every sample's passes, resolve (0 when off).
    pub antialias_ms: f64,
    pub readback_ms: f64,
    /// Not a time: the pixels anti-aliasing gave 16, 8 and 4 sub-pixel rays in the frame,
    /// which ride with the frame's times to its output.
    pub antialias_counts: [u64; 3],
}

impl PassTimes {
    /// Time to find every primary ray's hit (ray generation, tile pre-pass, terrain and
    /// free-form cast).
    pub fn primary_ms(&self) -> f64 {
        self.raygen_ms + self.tile_ms + self.cast_ms + self.objects_ms + self.voxels_ms
    }
}

/// How far a frame is rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Ray table, tile pre-pass and cast: primary-ray hits only (the G-buffer).
    Cast,
    /// Everything: shading, shadow rays, fog, sky.
    Shade,
}

/// What a captured frame holds.
#[derive(Clone, Debug)]
pub struct FrameOutput {
    pub width: u32,
    pub height: u32,
    /// sRGB RGBA8, row 0 at the top.
    pub rgba: Vec<u8>,
    /// Ray distance in metres per pixel, `+inf` for sky.
    pub depth: Vec<f32>,
    /// Primary traversal steps per pixel.
    pub steps: Vec<u32>,
    /// Exact patch tests per pixel.
    pub patch_tests: Vec<u32>,
    /// Shadow-ray traversal steps per pixel.
    pub shadow_steps: Vec<u32>,
    /// Flags per pixel: 1 hit, 2 in shadow, 4 step limit reached, 16 free form, 32 voxel model,
    /// 128 anti-aliased (sub-pixel rays cast; the other outputs are the centre ray's), 64 (with
    /// anti-aliasing, on terrain, free forms and sky) the centre ray passed within its cone of a
    /// thin feature (terrain, a free form, a voxel model).
    pub flags: Vec<u32>,
    /// Free-form index + 1 per pixel (0 where no free form shows).
    pub objects: Vec<u32>,
    /// Volume texture samples taken per pixel (empty without a volume).
    pub volume_samples: Vec<u32>,
    /// Volume lattice segments passed per pixel, sampled or skipped (empty without a volume).
    pub volume_segments: Vec<u32>,
    /// The sun's transmittance through the density volumes per pixel, 0..=255, for the opaque
    /// surface there (255 for sky; empty when no volume casts a shadow or shadows are off).
    pub volume_sun: Vec<u8>,
    pub times: PassTimes,
}

/// Flag of the pixels that got anti-aliasing samples (`aa_resolve.wgsl`).
pub const FLAG_ANTIALIASED: u32 = 128;

/// Capture flag of an anti-aliased frame's pixel whose centre ray passed within its cone (or
/// its sun ray within its footprint's beam) of something it missed ([`FrameOutput::flags`]).
pub const FLAG_NEAR_MISS: u32 = 64;

impl FrameOutput {
    /// Pixels that got anti-aliasing samples (flag 128).
    pub fn antialiased_pixels(&self) -> u64 {
        self.flags
            .iter()
            .filter(|f| *f & FLAG_ANTIALIASED != 0)
            .count() as u64
    }

    /// Pixels whose centre ray found a near miss through its cone (flag 64; anti-aliased
    /// frames only, each such pixel gets 16 samples).
    pub fn near_misses(&self) -> u64 {
        self.flags
            .iter()
            .filter(|f| *f & FLAG_NEAR_MISS != 0)
            .count() as u64
    }

    /// Sub-pixel rays anti-aliasing cast for the frame (0 when off).
    pub fn antialias_rays(&self) -> u64 {
        super::antialias::sample_rays(self.times.antialias_counts)
    }
}
