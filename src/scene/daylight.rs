//! Time of day: the sun and the sky a scene's sun elevation gives them. The scene's `[sun]` and
//! `[sky]` colours are those of full day; as the sun sinks below [`FULL_DAY`] degrees the direct
//! sun passes through more air and reddens (Rayleigh-like optical depths over the Kasten–Young
//! air mass, relative to the air mass at [`FULL_DAY`]) and is gone a degree below the horizon;
//! the sky and its light on the ground dim through civil, nautical and astronomical twilight to a
//! night floor, the horizon warms around sunset and the zenith deepens. At or above
//! [`FULL_DAY`] (every demo scene) nothing changes. `[sky] twilight = false` keeps the scene's
//! colours whatever the sun does.
//!
//! **The moon** (`[moon]`, or a CIGI host's Celestial Sphere Control): once the direct sun is
//! gone (a degree below the horizon) a moon above the horizon becomes the light — its
//! direction, a pale blue-white of [`MOONLIGHT`] times the sun's strength scaled by its lit
//! fraction and reddened low as the sun is, its disc and glow in the sky, its shadows — and
//! brightens the night sky by up to three times [`NIGHT`] (full, overhead).
//!
//! The sky's dimming is a display curve, not photometry: daylight to a moonless night spans
//! about 10⁸ in illuminance, which no projector shows; like an adapted eye, the curve falls to
//! 0.13 of day at the end of civil twilight (−6°) and to [`NIGHT`], 1/50, at the end of
//! astronomical twilight (−18°): a dark blue sky over a ground a few levels above black, the
//! terrain's silhouette against it still visible.

use super::SceneDesc;
use glam::DVec3;

/// Sun elevation (degrees) at and above which the scene's colours hold as given.
pub const FULL_DAY: f64 = 10.0;

/// Optical depths (red, green, blue) of the air towards the zenith that redden a low sun.
const TAU: [f64; 3] = [0.08, 0.14, 0.28];

/// Sky brightness relative to full day by sun elevation (degrees), interpolated in its
/// logarithm; constant below the last point.
const SKY: [(f64, f64); 10] = [
    (10.0, 1.0),
    (5.0, 0.85),
    (2.0, 0.65),
    (0.0, 0.5),
    (-2.0, 0.35),
    (-4.0, 0.22),
    (-6.0, 0.13),
    (-9.0, 0.07),
    (-12.0, 0.04),
    (-18.0, NIGHT),
];

/// The sky's brightness at night (the sun 18° or more below the horizon), relative to day.
pub const NIGHT: f64 = 1.0 / 50.0;

/// Moonlight at full moon against the sun's colour and strength: a display level (the full
/// moon's illuminance is about 1/400,000 of the sun's), as the night sky's [`NIGHT`] is.
pub const MOONLIGHT: f64 = 0.025;

/// Moonlight's colour (linear RGB): a pale blue-white, as night scenes are shown.
const MOON_COLOUR: [f64; 3] = [0.85, 0.9, 1.0];

/// A sunset horizon's colour at the luminance of 1 (Rec. 709 weights).
const SUNSET: [f64; 3] = [1.70, 0.85, 0.425];

/// How a twilight zenith's colour is scaled at its deepest.
const DEEP_ZENITH: [f64; 3] = [0.6, 0.75, 1.2];

/// The sun and sky that shading uses: the scene's, as its sun elevation makes them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Daylight {
    /// Unit vector (world) towards the light: the sun, or at night the moon.
    pub light: DVec3,
    /// Whether the light is the moon.
    pub moonlit: bool,
    /// Direct light (the sun's, or the moon's): linear RGB and irradiance scale.
    pub sun_colour: [f32; 3],
    pub intensity: f32,
    /// Sky at the zenith and the horizon (linear RGB) and the scale of its light on surfaces
    /// (which the colours carry: it dims with them).
    pub zenith: [f32; 3],
    pub horizon: [f32; 3],
    pub ambient: f32,
    /// The haze's colour: the scene's `[fog] colour` dimmed with the sky, else the horizon's.
    pub fog_colour: [f32; 3],
}

/// Kasten–Young (1989) relative air mass at elevation `e` degrees (valid above −6°).
fn air_mass(e: f64) -> f64 {
    1.0 / (e.to_radians().sin() + 0.50572 * (e + 6.07995).powf(-1.6364))
}

/// The sky's brightness relative to full day at sun elevation `e` (degrees).
pub fn sky_brightness(e: f64) -> f64 {
    if e >= SKY[0].0 {
        return 1.0;
    }
    for w in SKY.windows(2) {
        let ((e0, s0), (e1, s1)) = (w[0], w[1]);
        if e >= e1 {
            let f = (e0 - e) / (e0 - e1);
            return (s0.ln() + (s1.ln() - s0.ln()) * f).exp();
        }
    }
    SKY[SKY.len() - 1].1
}

/// The direct sun's transmittance (red, green, blue) at elevation `e` relative to
/// [`FULL_DAY`]'s: 1 at and above it, falling to 0 a degree below the horizon.
pub fn sun_transmittance(e: f64) -> [f64; 3] {
    if e >= FULL_DAY {
        return [1.0; 3];
    }
    let extra = air_mass(e.max(-0.5)) - air_mass(FULL_DAY);
    // Gone a degree below the horizon (refraction lifts the sun's disc about half a degree).
    let x = (e + 1.0).clamp(0.0, 1.0);
    let fade = x * x * (3.0 - 2.0 * x);
    TAU.map(|tau| (-tau * extra).exp() * fade)
}

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

fn mix(a: [f64; 3], b: [f64; 3], w: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * w)
}

impl SceneDesc {
    /// The sun and sky shading uses at the scene's sun elevation ([module docs](self)).
    pub fn daylight(&self) -> Daylight {
        let (sun, sky) = (&self.sun, &self.sky);
        let f = |c: [f32; 3]| c.map(f64::from);
        let g = |c: [f64; 3]| c.map(|v| v as f32);
        let e = sun.elevation;
        if !sky.twilight || e >= FULL_DAY {
            return Daylight {
                light: sun.direction(),
                moonlit: false,
                sun_colour: sun.colour,
                intensity: sun.intensity,
                zenith: sky.zenith,
                horizon: sky.horizon,
                ambient: sky.ambient,
                fog_colour: self.fog.colour.unwrap_or(sky.horizon),
            };
        }
        let mut t = sun_transmittance(e);
        let mut s = sky_brightness(e);
        let mut light = (sun.direction(), false);
        let moon = (self.moon).filter(|m| e <= -1.0 && m.elevation > 0.0 && m.illuminated > 0.0);
        if let Some(m) = moon {
            let k = m.illuminated;
            let tm = sun_transmittance(m.elevation);
            t = [0, 1, 2].map(|c| MOON_COLOUR[c] * MOONLIGHT * k * tm[c]);
            s = s.max(NIGHT * (1.0 + 2.0 * k * m.elevation.to_radians().sin()));
            light = (m.direction(), true);
        }
        // The horizon warms around sunset (most at 1° up), the zenith deepens from 6° down.
        let ramp = ((FULL_DAY - e) / 5.0).clamp(0.0, 1.0);
        let warm = 0.7 * ramp * (-((e - 1.0) / 3.5).powi(2)).exp();
        let h = f(sky.horizon);
        let horizon = mix(h, SUNSET.map(|c| c * luminance(h)), warm).map(|c| c * s);
        let deep = 0.5 * ((6.0 - e) / 18.0).clamp(0.0, 1.0);
        let zenith = mix([1.0; 3], DEEP_ZENITH, deep);
        let zenith = [0, 1, 2].map(|k| f64::from(sky.zenith[k]) * zenith[k] * s);
        let fog = match self.fog.colour {
            Some(c) => f(c).map(|v| v * s),
            None => horizon,
        };
        // The moon's light is its own colour, not the sun's.
        let colour = if light.1 { [1.0; 3] } else { f(sun.colour) };
        Daylight {
            light: light.0,
            moonlit: light.1,
            sun_colour: g([0, 1, 2].map(|k| colour[k] * t[k])),
            intensity: sun.intensity,
            zenith: g(zenith),
            horizon: g(horizon),
            // The sky's light on surfaces is its colours times this: it dims with them.
            ambient: sky.ambient,
            fog_colour: g(fog),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(elevation: f64) -> SceneDesc {
        let mut s: SceneDesc =
            toml::from_str("[terrain]\nsource = \"x.hgt\"\n[camera]\nposition = [0.0, 0.0, 0.0]\n")
                .unwrap();
        s.sun.elevation = elevation;
        s
    }

    /// At and above full day the scene's colours hold exactly; just below they differ by
    /// little (the curve is continuous there).
    #[test]
    fn full_day_keeps_the_scenes_colours_and_the_curve_is_continuous() {
        let day = scene(FULL_DAY).daylight();
        let s = scene(FULL_DAY);
        assert_eq!(day.sun_colour, s.sun.colour);
        assert_eq!(day.zenith, s.sky.zenith);
        assert_eq!(day.horizon, s.sky.horizon);
        assert_eq!(day.ambient, s.sky.ambient);
        let colours = |d: Daylight| Daylight {
            light: DVec3::ZERO,
            ..d
        };
        assert_eq!(colours(scene(45.0).daylight()), colours(day));
        let below = scene(FULL_DAY - 1e-6).daylight();
        let close = |a: [f32; 3], b: [f32; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-5);
        assert!(close(below.sun_colour, day.sun_colour), "{below:?}");
        assert!(close(below.zenith, day.zenith) && close(below.horizon, day.horizon));
        assert!((below.ambient - day.ambient).abs() < 1e-5);
        let mut off = scene(-10.0);
        off.sky.twilight = false;
        assert_eq!(colours(off.daylight()), colours(day));
    }

    /// At night a moon above the horizon is the light: its direction, a light scaled by its
    /// lit fraction, a brighter sky; below the horizon, new, or with the sun up it is not.
    #[test]
    fn the_moon_lights_the_night() {
        let mut night = scene(-20.0);
        let dark = night.daylight();
        night.moon = Some(crate::scene::Moon {
            azimuth: 120.0,
            elevation: 40.0,
            illuminated: 1.0,
        });
        let lit = night.daylight();
        assert!(lit.moonlit && !dark.moonlit);
        assert!((lit.light - night.moon.unwrap().direction()).length() < 1e-12);
        let want = (MOONLIGHT * MOON_COLOUR[2]) as f32;
        assert!((lit.sun_colour[2] - want).abs() < 1e-6, "{lit:?}");
        assert!(lit.zenith[2] > 1.5 * dark.zenith[2], "{lit:?} {dark:?}");
        let half = |k: f64| {
            let mut n = night.clone();
            n.moon.as_mut().unwrap().illuminated = k;
            n.daylight()
        };
        assert!((half(0.5).sun_colour[2] - want / 2.0).abs() < 1e-6);
        assert_eq!(half(0.0), dark);
        let mut set = night.clone();
        set.moon.as_mut().unwrap().elevation = -2.0;
        assert_eq!(set.daylight(), dark);
        let mut day = night.clone();
        day.sun.elevation = 30.0;
        assert!(!day.daylight().moonlit);
        assert_eq!(day.daylight().light, day.sun.direction());
    }

    /// As the sun sinks the sky and its light only dim (the horizon's luminance too, while it
    /// warms about sunset), the sun reddens and is gone a degree
    /// below the horizon; the night floor is [`NIGHT`].
    #[test]
    fn the_sky_dims_and_the_sun_reddens_as_it_sinks() {
        let mut last = scene(FULL_DAY).daylight();
        let mut e = FULL_DAY;
        while e > -30.0 {
            e -= 0.25;
            let d = scene(e).daylight();
            assert!((0..3).all(|k| d.zenith[k] <= last.zenith[k]), "{e}: {d:?}");
            // The horizon warms about sunset, at its luminance.
            let lum = |c: [f32; 3]| luminance(c.map(f64::from));
            assert!(
                lum(d.horizon) <= lum(last.horizon) * (1.0 + 1e-6),
                "{e}: {d:?}"
            );
            assert!(d
                .sun_colour
                .iter()
                .zip(last.sun_colour)
                .all(|(a, b)| *a <= b));
            if d.sun_colour[0] > 0.0 {
                let red = |c: [f32; 3]| c[0] / c[2].max(1e-30);
                assert!(red(d.sun_colour) >= red(last.sun_colour), "{e}: {d:?}");
            }
            last = d;
        }
        assert_eq!(scene(-1.0).daylight().sun_colour, [0.0; 3]);
        assert!(scene(0.0).daylight().sun_colour[0] > 0.0);
        let night = scene(-25.0).daylight();
        let day = scene(FULL_DAY).daylight();
        let deepest = 0.5 * DEEP_ZENITH[2] + 0.5;
        let ratio = night.zenith[2] / day.zenith[2];
        assert!((f64::from(ratio) - deepest * NIGHT).abs() < 1e-6, "{ratio}");
        assert!((sky_brightness(-6.0) - 0.13).abs() < 1e-12);
        // Sunset: the horizon is warmer than by day.
        let sunset = scene(1.0).daylight();
        let warmth = |c: [f32; 3]| c[0] / c[2];
        assert!(
            warmth(sunset.horizon) > 1.5 * warmth(day.horizon),
            "{sunset:?}"
        );
    }
}
