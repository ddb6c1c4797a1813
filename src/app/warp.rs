//! `relief warp inspect|export`: read warp files and write a display configuration's warp.

use crate::display::screen_points::screen_points;
use crate::display::warp::{
    read_bourke, read_pfm, write_bourke, write_pfm, BourkeMesh, MeshNode, Pfm, RowOrder,
};
use crate::display::DisplayConfig;
use crate::{fileio, Error, Result};
use glam::DVec3;
use std::path::Path;

fn is_pfm(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("pfm"))
}

fn range(vals: impl Iterator<Item = f64>) -> (f64, f64, usize) {
    vals.filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY, 0), |(lo, hi, n), v| {
            (lo.min(v), hi.max(v), n + 1)
        })
}

/// A one-paragraph description of a warp file.
pub fn inspect(path: &Path, order: RowOrder) -> Result<String> {
    if is_pfm(path) {
        let p = read_pfm(path, order)?;
        let c = p.channels as usize;
        let valid = p
            .data
            .chunks_exact(c)
            .filter(|px| px[..c.min(2)].iter().all(|v| v.is_finite()))
            .count();
        let mut s = format!(
            "{}: PFM {}x{}, {} channel(s), rows read {:?}; {valid} of {} pixels have data (finite R{})",
            path.display(),
            p.width,
            p.height,
            p.channels,
            order,
            p.width * p.height,
            if c > 1 { ",G" } else { "" }
        );
        for ch in 0..c {
            let (lo, hi, n) = range(p.data.iter().skip(ch).step_by(c).map(|v| *v as f64));
            s += &format!("\n  channel {ch}: {n} finite values in {lo}..{hi}");
        }
        Ok(s)
    } else {
        let m = read_bourke(path)?;
        let used: Vec<&MeshNode> = m.nodes.iter().filter(|n| n.i >= 0.0).collect();
        let (ulo, uhi, _) = range(used.iter().map(|n| n.u));
        let (vlo, vhi, _) = range(used.iter().map(|n| n.v));
        let (ilo, ihi, _) = range(used.iter().map(|n| n.i));
        let (xlo, xhi, _) = range(m.nodes.iter().map(|n| n.x));
        Ok(format!(
            "{}: Bourke mesh type {} ({}), {}x{} nodes, {} used; x {xlo}..{xhi}; u {ulo}..{uhi}, v {vlo}..{vhi}, intensity {ilo}..{ihi}",
            path.display(),
            m.mesh_type,
            if m.mesh_type == 2 { "rectangular" } else { "polar" },
            m.nx,
            m.ny,
            used.len()
        ))
    }
}

/// Writes channel `channel` of a display configuration as a warp: `.pfm` = MPCDI-style 3-D
/// geometry (screen X, Y, Z in the display frame per projector pixel, NaN where no screen,
/// rows bottom to top); anything else = Bourke type-2 mesh (one node every `step` pixels)
/// mapping projector positions to a 180° angular-fisheye image around display +z as seen from
/// the eye (v = 0 at the bottom, intensity -1 for unused nodes).
pub fn export(
    config: &Path,
    channel: usize,
    eye: Option<[f64; 3]>,
    out: &Path,
    step: u32,
) -> Result<String> {
    fileio::check_writable_target(out)?;
    let cfg = DisplayConfig::load(config)?;
    let ch = super::channel::channel(&cfg, &config.display().to_string(), channel)?;
    let p = ch.projector;
    let pts = screen_points(&cfg.screen, &p);
    if is_pfm(out) {
        let data = pts
            .points
            .iter()
            .flat_map(|q| q.map_or([f32::NAN; 3], |q| [q.x as f32, q.y as f32, q.z as f32]))
            .collect();
        write_pfm(
            out,
            &Pfm {
                width: p.width,
                height: p.height,
                channels: 3,
                data,
            },
            RowOrder::BottomToTop,
        )?;
        return Ok(format!(
            "wrote {} (3-D PFM, {}x{}, rows bottom to top)",
            out.display(),
            p.width,
            p.height
        ));
    }
    if step == 0 {
        return Err(Error::invalid("--step", "must be at least 1 pixel"));
    }
    let eye = DVec3::from(eye.unwrap_or(cfg.eye.position));
    let (w, h) = (p.width, p.height);
    let aspect = w as f64 / h as f64;
    // Nodes every `step` pixels and one on the last pixel column and row, so the mesh covers
    // the whole image.
    let (nx, ny) = ((w - 1).div_ceil(step) + 1, (h - 1).div_ceil(step) + 1);
    let mut nodes = Vec::with_capacity((nx * ny) as usize);
    for j in 0..ny {
        // Rows bottom to top.
        let py = (h - 1 - (j * step).min(h - 1)) as usize;
        for i in 0..nx {
            let px = (i * step).min(w - 1) as usize;
            let x = ((px as f64 + 0.5) / w as f64 * 2.0 - 1.0) * aspect;
            let y = 1.0 - (py as f64 + 0.5) / h as f64 * 2.0;
            let node = match pts.points[py * w as usize + px] {
                Some(q) => {
                    // The 180° dome master's point (crate::display::dome_master: zenith at
                    // the centre, front at the bottom), v = 0 at the bottom.
                    let d = (q - eye).normalize();
                    match crate::display::dome_master::pixel(d, 1, 180.0) {
                        Some((u, v)) => MeshNode {
                            x,
                            y,
                            u,
                            v: 1.0 - v,
                            i: 1.0,
                        },
                        None => MeshNode {
                            x,
                            y,
                            u: 0.5,
                            v: 0.5,
                            i: -1.0,
                        },
                    }
                }
                None => MeshNode {
                    x,
                    y,
                    u: 0.0,
                    v: 0.0,
                    i: -1.0,
                },
            };
            nodes.push(node);
        }
    }
    let mesh = BourkeMesh {
        mesh_type: 2,
        nx: nx as usize,
        ny: ny as usize,
        nodes,
    };
    write_bourke(out, &mesh)?;
    Ok(format!(
        "wrote {} (Bourke type 2 mesh, {nx}x{ny} nodes)",
        out.display()
    ))
}

/// `relief warp apply`: warps a dome master (an existing fulldome frame, see
/// [`crate::display::dome_master`]) into one channel's projector image through the channel's
/// table, bilinearly, then applies the channel's edge blend, as a media server would. Writes a
/// PNG at the projector's resolution; black where the projector misses the screen or the
/// direction lies beyond the master's field. Returns a one-line summary.
pub fn apply_dome_master(
    config: &Path,
    channel: usize,
    eye: Option<[f64; 3]>,
    input: &Path,
    fov: f64,
    out: &Path,
) -> Result<String> {
    crate::display::dome_master::check_fov("--fov", fov)?;
    fileio::check_writable_target(out)?;
    let cfg = DisplayConfig::load(config)?;
    let ch = super::channel::channel(&cfg, &config.display().to_string(), channel)?;
    let img = read_dome_master(input)?;
    let (w, h) = img.dimensions();
    if w != h || w < 2 {
        return Err(Error::format(
            input,
            format!("a dome master is a square image, this one is {w}x{h}"),
        ));
    }
    let p = ch.projector;
    let pts = cfg.channel_points(channel)?;
    let eye = eye.map_or(DVec3::from(cfg.eye.position), DVec3::from);
    crate::error::check_finite("--eye", &eye.to_array())?;
    let offset = ch.view.map(|v| v.matrix());
    let src = img.as_raw();
    let mut rgba = vec![0u8; (p.width * p.height * 4) as usize];
    let (mut lit, mut covered) = (0usize, 0usize);
    for (k, s) in pts.points.iter().enumerate() {
        rgba[4 * k + 3] = 255;
        let Some(d) = s.and_then(|s| (s - eye).try_normalize()) else {
            continue;
        };
        lit += 1;
        let d = offset.map_or(d, |o| o * d);
        let Some((x, y)) = crate::display::dome_master::pixel(d, w, fov) else {
            continue;
        };
        covered += 1;
        let c = super::sampling::sample_rgba8(src, w, h, x, y);
        for i in 0..3 {
            rgba[4 * k + i] = (c[i] * 255.0).round() as u8;
        }
    }
    if let Some(b) = crate::display::blend::ChannelBlend::new(&cfg, channel) {
        b.apply_rgba8(&mut rgba);
    }
    super::output::write_png(out, p.width, p.height, &rgba)?;
    Ok(format!(
        "{}: channel {channel} ({}x{}), {lit} pixels on the screen, {covered} inside the {fov}° master{} -> {}",
        input.display(),
        p.width,
        p.height,
        if ch.blend.is_some() { ", edge blend applied" } else { "" },
        out.display()
    ))
}

/// Reads a dome master image as RGBA8, its declared size checked against the file's length and
/// the memory budget first.
fn read_dome_master(input: &Path) -> Result<image::RgbaImage> {
    // The RGBA copy.
    let img = fileio::read_image(input, 4).map_err(|e| match e {
        Error::Format { path, msg } => Error::Format {
            path,
            msg: format!("cannot read the dome master: {msg}"),
        },
        e => e,
    })?;
    Ok(img.to_rgba8())
}

/// `relief warp apply --mesh`: warps a dome master into a projector image of `size` through a
/// Paul Bourke type-2 mesh (nodes at projector positions x in ±aspect, y in ±1 up, holding the
/// master's u, v (v = 0 at the bottom) and a brightness), interpolating bilinearly between
/// nodes and multiplying by the interpolated brightness, as Bourke's own tools do. Cells with
/// an unused node (negative brightness) stay black.
pub fn apply_mesh(mesh: &Path, input: &Path, size: (u32, u32), out: &Path) -> Result<String> {
    fileio::check_writable_target(out)?;
    let m = read_bourke(mesh)?;
    if m.mesh_type != 2 {
        return Err(Error::format(
            mesh,
            format!(
                "type {} mesh: `warp apply` uses rectangular (type 2) meshes",
                m.mesh_type
            ),
        ));
    }
    let (w, h) = size;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(Error::invalid(
            "--size",
            format!("{w}x{h} is not 1..=16384 pixels"),
        ));
    }
    let (nx, ny) = (m.nx, m.ny);
    if nx < 2 || ny < 2 || m.nodes.len() != nx * ny {
        return Err(Error::format(
            mesh,
            format!("{nx}x{ny} nodes is not a grid to interpolate"),
        ));
    }
    let node = |i: usize, j: usize| &m.nodes[j * nx + i];
    // Node columns and rows must be ordered: x increasing along a row, y up the rows.
    let xs: Vec<f64> = (0..nx).map(|i| node(i, 0).x).collect();
    let ys: Vec<f64> = (0..ny).map(|j| node(0, j).y).collect();
    if xs.windows(2).any(|p| p[1] <= p[0]) || ys.windows(2).any(|p| p[1] <= p[0]) {
        return Err(Error::format(
            mesh,
            "node x must increase along each row and y up the rows (bottom row first)",
        ));
    }
    let img = read_dome_master(input)?;
    let (mw, mh) = img.dimensions();
    let aspect = w as f64 / h as f64;
    let mut rgba = vec![0u8; (w * h * 4) as usize];
    let mut lit = 0usize;
    for py in 0..h {
        let y = 1.0 - (py as f64 + 0.5) / h as f64 * 2.0;
        let Some(j) = ys.windows(2).position(|p| y >= p[0] && y <= p[1]) else {
            continue;
        };
        let fy = (y - ys[j]) / (ys[j + 1] - ys[j]);
        for px in 0..w {
            let k = ((py * w + px) * 4) as usize;
            rgba[k + 3] = 255;
            let x = ((px as f64 + 0.5) / w as f64 * 2.0 - 1.0) * aspect;
            let Some(i) = xs.windows(2).position(|p| x >= p[0] && x <= p[1]) else {
                continue;
            };
            let fx = (x - xs[i]) / (xs[i + 1] - xs[i]);
            let c = [
                node(i, j),
                node(i + 1, j),
                node(i, j + 1),
                node(i + 1, j + 1),
            ];
            if c.iter().any(|n| n.i < 0.0) {
                continue;
            }
            let lerp = |f: fn(&MeshNode) -> f64| {
                (f(c[0]) * (1.0 - fx) + f(c[1]) * fx) * (1.0 - fy)
                    + (f(c[2]) * (1.0 - fx) + f(c[3]) * fx) * fy
            };
            let (u, v, bright) = (lerp(|n| n.u), lerp(|n| n.v), lerp(|n| n.i));
            let s = super::sampling::sample_rgba8(
                img.as_raw(),
                mw,
                mh,
                u * mw as f64,
                (1.0 - v) * mh as f64,
            );
            for ch in 0..3 {
                rgba[k + ch] = (s[ch] * bright.clamp(0.0, 1.0) * 255.0).round() as u8;
            }
            lit += 1;
        }
    }
    super::output::write_png(out, w, h, &rgba)?;
    Ok(format!(
        "{}: {w}x{h} through the {nx}x{ny}-node mesh {}, {lit} pixels lit -> {}",
        input.display(),
        mesh.display(),
        out.display()
    ))
}
