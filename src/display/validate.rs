//! Range checks of a display configuration ([`DisplayConfig::validate`]): the screen, the eye
//! and each channel's projector (pose, resolution, measured distortion, lens) and blend. Errors
//! name the field.

use super::{Channel, DisplayConfig, Lens, LensDistortion, Projector, Screen};
use crate::error::check_finite as finite;
use crate::{Error, Result};
use glam::DVec3;

impl DisplayConfig {
    /// Checks ranges; errors name the field.
    pub fn validate(&self) -> Result<()> {
        self.screen.validate()?;
        finite("eye.position", &self.eye.position)?;
        if self.channels.is_empty() {
            return Err(Error::invalid("channel", "needs at least one [[channel]]"));
        }
        for (i, c) in self.channels.iter().enumerate() {
            self.validate_channel(i, c)?;
        }
        Ok(())
    }

    /// Channel `i`: its view offset, blend, projector pose and resolution, distortion and lens.
    fn validate_channel(&self, i: usize, c: &Channel) -> Result<()> {
        let p = &c.projector;
        let f = |k: &str| projector_field(i, k);
        finite(&f("position"), &p.position)?;
        if let Some(v) = &c.view {
            finite(&format!("channel[{i}].view"), &[v.heading, v.pitch, v.roll])?;
        }
        if let Some(b) = &c.blend {
            if b.auto && self.channels.iter().any(|c| c.warp.is_some()) {
                return Err(Error::invalid(
                    format!("channel[{i}].blend.auto"),
                    "geometric blends invert the projector models; with measured warp files \
                     give fixed edge ramps instead",
                ));
            }
            b.validate(&format!("channel[{i}].blend"))?;
        }
        finite(&f("heading/pitch/roll"), &[p.heading, p.pitch, p.roll])?;
        if !(1..=16384).contains(&p.width) || !(1..=16384).contains(&p.height) {
            return Err(Error::invalid(
                f("width/height"),
                format!("must be 1..=16384, got {}x{}", p.width, p.height),
            ));
        }
        if let Some(d) = &p.distortion {
            validate_distortion(d, p, &f("distortion"))?;
        }
        validate_lens(p, i)
    }
}

/// `channel[i].projector.k`.
fn projector_field(i: usize, k: &str) -> String {
    format!("channel[{i}].projector.{k}")
}

impl Screen {
    /// The screen's geometry: finite points, positive radii, a non-empty cylinder band, a
    /// mirror inside its dome, a non-zero plane normal.
    fn validate(&self) -> Result<()> {
        match *self {
            Screen::Dome {
                centre,
                radius,
                min_elevation,
            } => {
                finite("screen.centre", &centre)?;
                finite("screen.min_elevation", &[min_elevation])?;
                positive_radius(radius)?;
            }
            Screen::Cylinder {
                centre,
                radius,
                bottom,
                top,
            } => {
                finite("screen.centre", &centre)?;
                positive_radius(radius)?;
                if !(bottom.is_finite() && top.is_finite() && top > bottom) {
                    return Err(Error::invalid(
                        "screen.bottom/top",
                        format!("need bottom < top, got {bottom}..{top}"),
                    ));
                }
            }
            Screen::MirrorDome {
                centre,
                radius,
                min_elevation,
                mirror_centre,
                mirror_radius,
            } => {
                finite("screen.centre", &centre)?;
                finite("screen.min_elevation", &[min_elevation])?;
                finite("screen.mirror_centre", &mirror_centre)?;
                positive_radius(radius)?;
                validate_mirror(centre, radius, mirror_centre, mirror_radius)?;
            }
            Screen::Flat { point, normal } => {
                finite("screen.point", &point)?;
                finite("screen.normal", &normal)?;
                if DVec3::from(normal).length() < 1e-9 {
                    return Err(Error::invalid("screen.normal", "must be non-zero"));
                }
            }
        }
        Ok(())
    }
}

fn positive_radius(radius: f64) -> Result<()> {
    if radius.is_finite() && radius > 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(
            "screen.radius",
            format!("must be > 0 metres, got {radius}"),
        ))
    }
}

/// A mirror dome's mirror: a positive radius, wholly inside the dome.
fn validate_mirror(
    centre: [f64; 3],
    radius: f64,
    mirror_centre: [f64; 3],
    mirror_radius: f64,
) -> Result<()> {
    if !(mirror_radius.is_finite() && mirror_radius > 0.0) {
        return Err(Error::invalid(
            "screen.mirror_radius",
            format!("must be > 0 metres, got {mirror_radius}"),
        ));
    }
    let gap = DVec3::from(mirror_centre).distance(DVec3::from(centre));
    if gap + mirror_radius >= radius {
        return Err(Error::invalid(
            "screen.mirror_centre/mirror_radius",
            "the mirror must lie inside the dome (|mirror_centre - centre| + mirror_radius < radius)",
        ));
    }
    Ok(())
}

/// A projector's measured distortion (named `field` in errors): bounded coefficients, a radial
/// part that does not fold over, and a model invertible over the whole image.
fn validate_distortion(d: &LensDistortion, p: &Projector, field: &str) -> Result<()> {
    let k = [d.k1, d.k2, d.k3, d.p1, d.p2];
    if k.iter().any(|v| !v.is_finite() || v.abs() > 10.0) {
        return Err(Error::invalid(
            field,
            format!("coefficients must be finite and within ±10, got {k:?}"),
        ));
    }
    // The radial part must not fold over inside the image.
    d.check_radial_monotonic(field, p)?;
    // The measured model must be invertible over the whole image.
    let corners = [(0.0, 0.0), (p.width as f64, 0.0), (0.0, p.height as f64)];
    let edge = corners
        .iter()
        .chain(&[
            (p.width as f64, p.height as f64),
            (0.5 * p.width as f64, 0.0),
        ])
        .all(|&(u, v)| p.ray(u, v).is_some() || matches!(p.lens, Lens::Ftheta { .. }));
    if !edge {
        return Err(Error::invalid(
            field,
            "does not invert over the image (the polynomial folds over before the \
             corners): check the coefficients' signs and units (normalised \
             coordinates, not pixels)",
        ));
    }
    Ok(())
}

/// Channel `i`'s projector lens: its field of view in range, a finite perspective shift.
fn validate_lens(p: &Projector, i: usize) -> Result<()> {
    let f = |k: &str| projector_field(i, k);
    match p.lens {
        Lens::Perspective { fov, shift } => {
            if !(fov.is_finite() && fov > 0.0 && fov < 179.0) {
                return Err(Error::invalid(
                    f("lens.fov"),
                    format!("perspective fov must be in (0, 179) degrees, got {fov}"),
                ));
            }
            finite(&f("lens.shift"), &shift)?;
        }
        Lens::Ftheta { fov } => {
            if !(fov.is_finite() && fov > 0.0 && fov <= 360.0) {
                return Err(Error::invalid(
                    f("lens.fov"),
                    format!("f-theta fov must be in (0, 360] degrees, got {fov}"),
                ));
            }
        }
    }
    Ok(())
}
