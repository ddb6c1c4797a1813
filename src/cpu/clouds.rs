//! Cloud layers (`[[clouds]]`, CIGI Weather Control layers 1–3): the reference of
//! `gpu/shaders/clouds.wgsl`, step for step, in f64.
//!
//! A layer is a slab between two heights above mean sea level (a spherical shell on a curved
//! earth: the ray's height is `ze + dz s + a s²`) filled with cloud of extinction
//! σ = 3.912 / (visibility inside the cloud) times a density in 0..=1. Its pattern is fixed to
//! the ground: three octaves of value noise over cells of `feature` metres, cut at the
//! threshold that leaves `coverage` of the plane clouded ([`Deck::new`] measures it), with a
//! soft edge; each cell is a dome on the base, its top rising with the pattern from
//! [`EDGE_TOP`] of the thickness at its edge to the layer's top (an overcast deck is flat).
//!
//! A view ray's path through the layer is sampled at [`VIEW_SAMPLES`] points, closer together
//! near where it enters (a long grazing path needs them there). Each sample's cloud is lit by
//! the sun through the cloud above it and by the sky, at the height the light leaving its
//! interval comes from, and composited front to back over what lies behind; each span is hazed
//! once, at its opacity-weighted distance. Where a sample stands for more than a cloud cell
//! its density fades to the layer's mean (the pattern filtered at the sample's footprint). A
//! surface under a layer takes the sun through it ([`sun_transmittance`]: [`SUN_SAMPLES`]
//! along the sun's direction, the earth's curvature not counted there).

use crate::scene::clouds::CloudLayer;
use glam::DVec3;

/// Samples along a view ray's path through one span of a layer.
pub const VIEW_SAMPLES: usize = 8;
/// Samples along the sun's path through a layer above a surface.
pub const SUN_SAMPLES: usize = 4;
/// Farthest a view ray is followed through a layer (m).
pub const REACH: f64 = 200_000.0;
/// Width of the pattern's soft edge (noise units).
pub const SOFT: f64 = 0.06;
/// Pattern value above the cut at which a cell's top reaches the layer's top (noise units).
pub const RELIEF: f64 = 0.2;
/// A cell's top at its edge, as a fraction of the layer's thickness.
pub const EDGE_TOP: f64 = 0.35;
/// Depth of a cell top's soft edge, as a fraction of the layer's thickness.
pub const TOP_SOFT: f64 = 0.3;
/// Fraction of the extinction that darkens the sun's light inside a cloud (light scattered
/// forward travels much further than the direct beam).
pub const SUN_SCATTER: f64 = 0.1;
/// Lowest sun elevation sine the paths towards it use.
pub const SUN_Z_MIN: f64 = 0.05;
/// Albedo of cloud.
pub const ALBEDO: f64 = 0.9;
/// A sample standing for this many cloud cells or fewer reads the pattern; from there to
/// [`FADE_TO`] its density fades to the layer's mean.
pub const FADE_FROM: f64 = 0.125;
/// See [`FADE_FROM`].
pub const FADE_TO: f64 = 0.625;

/// The weight of the layer's mean in a sample standing for `cells` cloud cells.
fn fade(cells: f64) -> f64 {
    ((cells - FADE_FROM) / (FADE_TO - FADE_FROM)).clamp(0.0, 1.0)
}

/// A layer prepared for rendering (what `Frame.clouds` holds on the GPU).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deck {
    pub base: f64,
    pub top: f64,
    /// Extinction of full cloud (1/m).
    pub sigma: f64,
    /// Pattern value where cloud starts (below 0: everywhere, above 1: nowhere).
    pub threshold: f64,
    /// Mean density over the plane.
    pub mean: f64,
    pub inv_feature: f64,
    pub seed: u32,
    /// How domed the cells are (`[[clouds]] relief`).
    pub relief: f64,
}

impl Deck {
    /// The layer with its threshold and mean density measured on a 256 x 256 lattice over
    /// 16 x 16 cells of its pattern ([`cut`]).
    pub fn new(l: &CloudLayer) -> Deck {
        let (threshold, mean) = cut(l.seed, l.coverage, l.relief);
        Deck {
            base: l.base,
            top: l.top(),
            sigma: 3.912 / l.visibility,
            threshold,
            mean,
            inv_feature: 1.0 / l.feature,
            seed: l.seed,
            relief: l.relief,
        }
    }

    /// The cloud column of pattern value `n`: its cover (0..=1, the soft edge) and the height
    /// of its top (with `relief` 1 cells are domes: [`EDGE_TOP`] of the thickness at their
    /// edge, the whole thickness [`RELIEF`] above the cut; with 0 flat at the layer's top; an
    /// overcast deck is flat).
    fn cell(&self, n: f64) -> (f64, f64) {
        let e = n - self.threshold;
        let cover = (e / SOFT).clamp(0.0, 1.0);
        let rise = (e / RELIEF).clamp(0.0, 1.0).sqrt();
        let sink = self.relief * (1.0 - EDGE_TOP) * (1.0 - rise);
        let top = self.base + (self.top - self.base) * (1.0 - sink);
        (cover, top)
    }

    /// The cloud column above ground point (x, y), metres from the grid's origin: its cover
    /// and the height of its top.
    pub fn column(&self, x: f64, y: f64) -> (f64, f64) {
        self.cell(pattern(
            x * self.inv_feature,
            y * self.inv_feature,
            self.seed,
        ))
    }

    /// Density (0..=1) at height `z` in a column of `cover` and `top`.
    pub fn density_in(&self, (cover, top): (f64, f64), z: f64) -> f64 {
        cover * ((top - z) / (TOP_SOFT * (self.top - self.base))).clamp(0.0, 1.0)
    }

    /// Cloud density (0..=1) at (x, y) metres from the grid's origin and height `z`.
    pub fn density(&self, x: f64, y: f64, z: f64) -> f64 {
        self.density_in(self.column(x, y), z)
    }
}

/// The pattern value where the cloud of `coverage` starts and the slab's mean density with
/// `relief` (a column's cover times the part of the thickness below its top, the soft top
/// counted at half its depth), kept for the last few layers: a frame's layers cost a lookup,
/// a new coverage a pass over the sorted lattice.
fn cut(seed: u32, coverage: f64, relief: f64) -> (f64, f64) {
    use std::sync::Mutex;
    type Key = (u32, u64, u64);
    static KEPT: Mutex<Vec<(Key, (f64, f64))>> = Mutex::new(Vec::new());
    let key = (seed, coverage.to_bits(), relief.to_bits());
    if let Some((_, c)) = KEPT
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .iter()
        .find(|(k, _)| *k == key)
    {
        return *c;
    }
    let v = sorted_lattice(seed);
    let threshold = if coverage >= 1.0 {
        -1.0
    } else if coverage <= 0.0 {
        2.0
    } else {
        let k = ((1.0 - coverage) * v.len() as f64) as usize;
        v[k.min(v.len() - 1)]
    };
    // A layer of unit thickness: the tops as fractions of it.
    let unit = Deck {
        base: 0.0,
        top: 1.0,
        sigma: 0.0,
        threshold,
        mean: 0.0,
        inv_feature: 0.0,
        seed,
        relief,
    };
    let mean = v
        .iter()
        .map(|&n| {
            let (cover, top) = unit.cell(n);
            cover * (top - 0.5 * TOP_SOFT).max(0.0)
        })
        .sum::<f64>()
        / v.len() as f64;
    let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    if kept.len() >= 16 {
        kept.remove(0);
    }
    kept.push((key, (threshold, mean)));
    (threshold, mean)
}

/// The pattern on the lattice [`Deck::new`] measures, sorted; kept for the last few seeds.
fn sorted_lattice(seed: u32) -> std::sync::Arc<Vec<f64>> {
    use std::sync::{Arc, Mutex};
    type Kept = Vec<(u32, Arc<Vec<f64>>)>;
    static KEPT: Mutex<Kept> = Mutex::new(Vec::new());
    let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, v)) = kept.iter().find(|(s, _)| *s == seed) {
        return v.clone();
    }
    let n = 256;
    let step = 16.0 / n as f64;
    let mut v = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            // Off the lattice of the noise (whose corners repeat values).
            let (x, y) = ((i as f64 + 0.37) * step, (j as f64 + 0.61) * step);
            v.push(pattern(x, y, seed));
        }
    }
    v.sort_by(f64::total_cmp);
    let v = Arc::new(v);
    if kept.len() >= 8 {
        kept.remove(0);
    }
    kept.push((seed, v.clone()));
    v
}

/// Hash of a lattice point to 0..1 (24 bits), as `cloud_hash` in the shader.
pub fn hash(ix: i32, iy: i32, seed: u32) -> f64 {
    let mut h = (ix as u32).wrapping_mul(0x8da6_b343)
        ^ (iy as u32).wrapping_mul(0xd816_3841)
        ^ seed.wrapping_mul(0xcb1a_b31f);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    (h >> 8) as f64 / 16_777_216.0
}

/// Value noise at (x, y) in lattice units: the corners' hashes blended by smoothstep.
pub fn value_noise(x: f64, y: f64, seed: u32) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i32, fy as i32);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (u, v) = (s(x - fx), s(y - fy));
    let a = hash(ix, iy, seed);
    let b = hash(ix.wrapping_add(1), iy, seed);
    let c = hash(ix, iy.wrapping_add(1), seed);
    let d = hash(ix.wrapping_add(1), iy.wrapping_add(1), seed);
    let ab = a + (b - a) * u;
    let cd = c + (d - c) * u;
    ab + (cd - ab) * v
}

/// The cloud pattern at (x, y) in cells: three octaves of value noise, weights 1, ½, ¼, in 0..1.
pub fn pattern(x: f64, y: f64, seed: u32) -> f64 {
    (value_noise(x, y, seed)
        + 0.5 * value_noise(2.0 * x, 2.0 * y, seed.wrapping_add(1))
        + 0.25 * value_noise(4.0 * x, 4.0 * y, seed.wrapping_add(2)))
        / 1.75
}

/// Where `ze + dz s + a s² <= h` for s in ℝ (a ≥ 0): an interval, possibly empty or unbounded.
fn below(ze: f64, dz: f64, a: f64, h: f64) -> Option<(f64, f64)> {
    let c = ze - h;
    if a <= 1e-12 {
        return if dz > 0.0 {
            Some((f64::NEG_INFINITY, -c / dz))
        } else if dz < 0.0 {
            Some((-c / dz, f64::INFINITY))
        } else if c <= 0.0 {
            Some((f64::NEG_INFINITY, f64::INFINITY))
        } else {
            None
        };
    }
    let disc = dz * dz - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let q = -0.5 * (dz + dz.signum() * disc.sqrt());
    let (r0, r1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
    Some((r0.min(r1), r0.max(r1)))
}

/// The parts of [0, tmax] where the height `ze + dz s + a s²` lies between `base` and `top`:
/// at most two spans (a ray on a curved earth may sink through a layer and rise back).
pub fn spans(ze: f64, dz: f64, a: f64, base: f64, top: f64, tmax: f64) -> Vec<(f64, f64)> {
    let Some((u0, u1)) = below(ze, dz, a, top) else {
        return Vec::new();
    };
    let (u0, u1) = (u0.max(0.0), u1.min(tmax));
    let mut out = Vec::new();
    let mut push = |s0: f64, s1: f64| {
        if s1 > s0 {
            out.push((s0, s1));
        }
    };
    match below(ze, dz, a, base) {
        // Below the base within (l0, l1): the layer before and after.
        Some((l0, l1)) => {
            push(u0, u1.min(l0));
            push(u0.max(l1), u1);
        }
        None => push(u0, u1),
    }
    out
}

/// The exponent that places a span's samples (1: evenly; more: closer near its start).
pub fn spacing_exponent(len: f64, inv_feature: f64) -> f64 {
    let cells = len * inv_feature;
    if cells <= 2.0 {
        1.0
    } else {
        (1.0 + (cells / 2.0).log2() / 3.0).min(4.0)
    }
}

/// A view ray in the terrain's grid frame: x, y in samples, z in metres above mean sea level
/// (`eye`), its direction per metre of travel (`dir`), the curved earth's `a` (the height
/// along it is `eye.z + dir.z s + a s²`; 0 on a flat terrain) and the grid's spacing (m).
#[derive(Clone, Copy, Debug)]
pub struct CloudRay {
    pub eye: DVec3,
    pub dir: DVec3,
    pub a: f64,
    pub spacing: [f64; 2],
}

impl CloudRay {
    /// Ground position (m from the grid's origin) and height at distance `s`.
    fn at(&self, s: f64) -> (f64, f64, f64) {
        let p = self.eye + self.dir * s;
        (
            p.x * self.spacing[0],
            p.y * self.spacing[1],
            self.eye.z + self.dir.z * s + self.a * s * s,
        )
    }
}

/// How the clouds are lit: the sun's (or the moon's) unit direction in the local frame, its
/// colour times its intensity, and the sky's light on a cloud's top.
#[derive(Clone, Copy, Debug)]
pub struct CloudLight {
    pub sun: DVec3,
    pub sun_colour: DVec3,
    pub ambient: DVec3,
}

/// Linear colour of cloud at height z in `deck`, in a column whose top is at `top`.
pub fn cloud_colour(deck: &Deck, z: f64, top: f64, light: &CloudLight) -> DVec3 {
    let h = ((z - deck.base) / (top - deck.base)).clamp(0.0, 1.0);
    let sun_z = light.sun.z.max(SUN_Z_MIN);
    let depth = (top - z).max(0.0) / sun_z;
    let direct = light.sun_colour
        * (light.sun.z.max(0.0) * (-SUN_SCATTER * deck.sigma * deck.mean * depth).exp());
    (direct + light.ambient * (0.5 + 0.5 * h)) * ALBEDO
}

/// The colour seen along `ray` up to distance `tmax` through `decks`, over `behind` (the
/// surface or sky there, already hazed). Each span is hazed once, at its opacity-weighted
/// distance s and height z: `haze(c, w, s, z)` is the aerial perspective of light c of
/// opacity w there (c τ + the haze's colour (1 − τ) w).
pub fn composite(
    decks: &[Deck],
    ray: &CloudRay,
    tmax: f64,
    behind: DVec3,
    light: &CloudLight,
    haze: impl Fn(DVec3, f64, f64, f64) -> DVec3,
) -> DVec3 {
    let tmax = tmax.min(REACH);
    let mut all: Vec<(f64, f64, usize)> = Vec::new();
    for (k, d) in decks.iter().enumerate() {
        for (s0, s1) in spans(ray.eye.z, ray.dir.z, ray.a, d.base, d.top, tmax) {
            all.push((s0, s1, k));
        }
    }
    all.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut acc, mut tr) = (DVec3::ZERO, 1.0);
    for (s0, s1, k) in all {
        let d = &decks[k];
        let len = s1 - s0;
        let p = spacing_exponent(len, d.inv_feature);
        let n = VIEW_SAMPLES as f64;
        let (mut light_sum, mut weight, mut sw, mut zw) = (DVec3::ZERO, 0.0, 0.0, 0.0);
        for i in 0..VIEW_SAMPLES {
            let i = i as f64;
            let ds = len * (((i + 1.0) / n).powf(p) - (i / n).powf(p));
            let s = s0 + len * ((i + 0.5) / n).powf(p);
            let (x, y, z) = ray.at(s);
            let w = fade(ds * d.inv_feature);
            let column = d.column(x, y);
            let density = d.density_in(column, z) * (1.0 - w) + d.mean * w;
            let alpha = 1.0 - (-d.sigma * density * ds).exp();
            // Where the sample stands for a cell or more, the layer's top lights it. The light
            // leaving the interval comes from its first mean free path: lit at that height.
            let top = column.1 * (1.0 - w) + d.top * w;
            let back = (0.5 * ds).min(1.0 / (d.sigma * density.max(0.05)));
            let z_lit = z - (ray.dir.z + 2.0 * ray.a * s) * back;
            let f = tr * alpha;
            light_sum += cloud_colour(d, z_lit, top, light) * f;
            weight += f;
            sw += s * f;
            zw += z * f;
            tr *= 1.0 - alpha;
        }
        let at = weight.max(1e-30);
        acc += haze(light_sum, weight, sw / at, zw / at);
    }
    acc + behind * tr
}

/// The sun's transmittance through `decks` to a surface at grid position `p` (x, y in
/// samples, z in metres above mean sea level), the sun's direction per metre in the grid frame
/// `sun_grid` (its z the elevation's sine).
pub fn sun_transmittance(decks: &[Deck], p: DVec3, sun_grid: DVec3, spacing: [f64; 2]) -> f64 {
    let sun_z = sun_grid.z.max(SUN_Z_MIN);
    let mut tau = 0.0;
    for d in decks.iter().filter(|d| p.z < d.top) {
        let s0 = (d.base - p.z).max(0.0) / sun_z;
        let s1 = (d.top - p.z).max(0.0) / sun_z;
        let ds = (s1 - s0) / SUN_SAMPLES as f64;
        let w = fade(ds * d.inv_feature);
        for i in 0..SUN_SAMPLES {
            let s = s0 + (i as f64 + 0.5) * ds;
            let q = p + sun_grid * s;
            let z = p.z + sun_z * s;
            let density = d.density(q.x * spacing[0], q.y * spacing[1], z) * (1.0 - w) + d.mean * w;
            tau += d.sigma * density * ds;
        }
    }
    (-tau).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(coverage: f64) -> CloudLayer {
        CloudLayer {
            base: 1000.0,
            thickness: 400.0,
            coverage,
            visibility: 60.0,
            feature: 2000.0,
            seed: 7,
            relief: 1.0,
        }
    }

    #[test]
    fn the_clouded_fraction_of_the_ground_is_the_coverage() {
        for coverage in [0.0, 0.1, 0.3, 0.5, 0.8, 1.0] {
            let d = Deck::new(&layer(coverage));
            // A lattice other than the one the threshold came from, over 40 x 40 km.
            let (mut clouded, n) = (0usize, 400);
            for j in 0..n {
                for i in 0..n {
                    let (x, y) = (100.0 * i as f64 + 13.0, 100.0 * j as f64 + 71.0);
                    clouded += usize::from(d.density(x, y, 1000.0) > 0.0);
                }
            }
            let f = clouded as f64 / (n * n) as f64;
            assert!(
                (f - coverage).abs() <= 0.04,
                "coverage {coverage}: {f:.3} of the ground under cloud"
            );
            assert!(d.mean <= coverage + 1e-9, "{coverage}: mean {}", d.mean);
        }
    }

    #[test]
    fn relief_domes_the_cells_or_leaves_them_flat() {
        let lowest_top = |relief: f64| {
            let d = Deck::new(&CloudLayer {
                relief,
                ..layer(0.5)
            });
            (0..2000)
                .map(|i| d.column(37.0 * i as f64, 11.0 * i as f64))
                .filter(|(cover, _)| *cover > 0.0)
                .map(|(_, top)| top)
                .fold(f64::INFINITY, f64::min)
        };
        // Flat: every clouded column reaches the layer's top (1,400 m).
        assert_eq!(lowest_top(0.0), 1400.0);
        // Domed: at a cell's edge the top is EDGE_TOP of the 400 m up.
        let edge = lowest_top(1.0);
        assert!(edge < 1000.0 + 400.0 * (EDGE_TOP + 0.15), "{edge}");
        assert!(edge >= 1000.0 + 400.0 * EDGE_TOP, "{edge}");
    }

    #[test]
    fn spans_are_where_the_ray_is_between_base_and_top() {
        let (base, top) = (1000.0, 1400.0);
        // Flat and curved (a = 1 / 2R), up, down, level, from below, inside and above.
        for a in [0.0, 1.0 / (2.0 * 6_371_000.0)] {
            for ze in [200.0, 1200.0, 3000.0] {
                for dz in [-0.5, -0.02, -0.001, 0.0, 0.001, 0.02, 0.5] {
                    let tmax = 150_000.0;
                    let got = spans(ze, dz, a, base, top, tmax);
                    // Brute force: every metre.
                    let inside = |s: f64| {
                        let z = ze + dz * s + a * s * s;
                        (base..=top).contains(&z)
                    };
                    for (s0, s1) in &got {
                        for k in 1..100 {
                            let s = s0 + (s1 - s0) * k as f64 / 100.0;
                            assert!(inside(s), "a {a} ze {ze} dz {dz}: {s} in {got:?}");
                        }
                    }
                    let mut s = 0.5;
                    while s < tmax {
                        if inside(s) {
                            assert!(
                                got.iter()
                                    .any(|(s0, s1)| *s0 - 1e-6 <= s && s <= *s1 + 1e-6),
                                "a {a} ze {ze} dz {dz}: {s} missing from {got:?}"
                            );
                        }
                        s += 97.0;
                    }
                }
            }
        }
    }

    #[test]
    fn an_overcast_deck_attenuates_as_beer_says() {
        let d = Deck::new(&layer(1.0));
        assert!((d.mean - (1.0 - 0.5 * TOP_SOFT)).abs() < 1e-9, "{}", d.mean);
        let light = CloudLight {
            sun: DVec3::Z,
            sun_colour: DVec3::ZERO,
            ambient: DVec3::ZERO,
        };
        // Straight up through 400 m of cloud of extinction 3.912 / 60: black cloud over white.
        let ray = CloudRay {
            eye: DVec3::new(0.0, 0.0, 0.0),
            dir: DVec3::Z,
            a: 0.0,
            spacing: [30.0, 30.0],
        };
        let c = composite(
            &[d],
            &ray,
            f64::INFINITY,
            DVec3::ONE,
            &light,
            |c, _, _, _| c,
        );
        // Eight samples 50 m apart, at 25..375 m into the deck, those in the soft top (its
        // upper 0.3 of the 400 m) thinner.
        let sigma = 3.912 / 60.0;
        let soft = |h: f64| ((400.0 - h) / (TOP_SOFT * 400.0)).clamp(0.0, 1.0);
        let depth: f64 = (0..8).map(|k| 50.0 * soft(25.0 + 50.0 * k as f64)).sum();
        assert!(depth < 400.0 - 50.0);
        let want = (-sigma * depth).exp();
        assert!(
            (c.x - want).abs() < 1e-12 * want.max(1.0),
            "{} vs {want}",
            c.x
        );
        // The sun's four samples, 100 m apart.
        let t = sun_transmittance(&[d], DVec3::new(5.0, 5.0, 10.0), DVec3::Z, [30.0, 30.0]);
        let depth: f64 = (0..4).map(|k| 100.0 * soft(50.0 + 100.0 * k as f64)).sum();
        let want = (-sigma * depth).exp();
        assert!((t - want).abs() < 1e-12, "{t} vs {want}");
        // Above the deck the sun is not dimmed.
        let t = sun_transmittance(&[d], DVec3::new(5.0, 5.0, 1500.0), DVec3::Z, [30.0, 30.0]);
        assert_eq!(t, 1.0);
    }
}
