//! Command-line values: the parsers of sizes, vectors and modes, and the option group several
//! commands share (`--no-shadows`, `--no-tile-prepass`). The commands' option structs derive
//! `clap::Args` next to the code that runs them.

use crate::gpu::RenderSettings;

/// `WIDTHxHEIGHT`, each side 1..=16384.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}` is not WIDTHxHEIGHT"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in `{s}`"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in `{s}`"))?;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(format!("size {w}x{h} must be within 1..=16384 per side"));
    }
    Ok((w, h))
}

/// `N` comma-separated finite numbers.
pub fn parse_vec<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("`{s}`: {e}"))?;
    let arr: [f64; N] = v
        .try_into()
        .map_err(|_| format!("`{s}` needs {N} comma-separated numbers"))?;
    if arr.iter().any(|x| !x.is_finite()) {
        return Err(format!("`{s}` has a non-finite number"));
    }
    Ok(arr)
}

/// A point `X,Y,Z`.
pub fn parse_dvec3(s: &str) -> Result<glam::DVec3, String> {
    parse_vec::<3>(s).map(glam::DVec3::from)
}

/// Sun shadows and the tile pre-pass, each on as the scene says unless turned off here, and
/// footprint level of detail as the scene says unless set here.
#[derive(Clone, Copy, Debug, Default, clap::Args)]
pub struct RenderToggles {
    /// Turn sun shadows on surfaces off (terrain, free forms, voxel models, volumes casting onto them).
    #[arg(long)]
    pub no_shadows: bool,
    /// Turn the screen-tile pre-pass off.
    #[arg(long)]
    pub no_tile_prepass: bool,
    /// Footprint level of detail: on, off or a scale factor (overrides `[render] lod`).
    #[arg(long, value_name = "on|off|SCALE", value_parser = crate::scene::Lod::parse)]
    pub lod: Option<crate::scene::Lod>,
    /// Edge anti-aliasing: off, edges (4 to 16 sub-pixel rays per edge pixel, by its
    /// contrast), 4, 8, 16 (that many per edge pixel) or reference (16 in every pixel)
    /// (overrides `[render] antialias`).
    #[arg(long, value_name = "off|edges|N|reference", value_parser = crate::scene::AntialiasOption::parse)]
    pub antialias: Option<crate::scene::AntialiasOption>,
}

impl RenderToggles {
    /// Turns off in `settings` what these flags turn off.
    pub fn apply(&self, settings: &mut RenderSettings) {
        if self.no_shadows {
            settings.shadows = false;
        }
        if self.no_tile_prepass {
            settings.tile_prepass = false;
        }
        if let Some(lod) = self.lod {
            settings.lod = lod.scale();
        }
        if let Some(a) = self.antialias {
            settings.antialias = crate::gpu::Antialias::from_option(a);
        }
    }
}
