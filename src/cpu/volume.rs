//! Volume integral (f64 reference of `gpu/shaders/volume.wgsl`, step for step).
//!
//! Front-to-back emission–absorption along the ray segment inside the volume box (and the
//! shell, if any), cut at the opaque depth of terrain and free forms:
//! `P = Σ I_n Ω_n Π_{m<n} (1 − Ω_m)`, then `P + T · background`.
//!
//! Segments: boundaries `b_k = t0 + (k + j)·Δ` (`t0` the box entry, `Δ` the step in metres, `j`
//! the pixel's jitter or 0), clipped to the ray's interval; each segment is sampled at its
//! middle and stands for its own length `ℓ`, so `Ω = 1 − exp(−σ·ℓ)` is exact for uniform
//! media whatever the step. Samples are quadrilinear in the [`VolumeTexture`](crate::volume::VolumeTexture) at the level
//! `log2(pixel footprint / voxel)` (0 without mip-maps). Empty-space skipping jumps from a
//! sample in an unoccupied brick to the segment holding the brick's exit; all skipped samples
//! have `σ = 0` exactly, so skipping changes nothing. Early termination stops when `T < ε`.
//! Lighting: the paper's colour formula with the classified colour as surface colour and the
//! outward density gradient as normal, blended towards isotropic (`n·l = ½`)
//! where the gradient is weak; haze in front of each sample as for surfaces.

use crate::scene::SceneDesc;
use crate::terrain::Terrain;
use crate::volume::{decode_gradient, Volume, BRICK};
use glam::DVec3;

/// Samples after which a ray gives up (WGSL `VOL_MAX_SAMPLES`).
pub const MAX_SAMPLES: u32 = 1 << 16;

/// Sun, sky and haze as the shade pass applies them, in world terms.
#[derive(Clone, Copy, Debug)]
pub struct VolumeLight {
    /// Unit vector towards the sun.
    pub sun: DVec3,
    /// Sun colour (linear) and intensity.
    pub sun_colour: DVec3,
    pub intensity: f64,
    pub zenith: DVec3,
    pub horizon: DVec3,
    pub ambient: f64,
    /// Haze colour and extinction per metre at the base plane (0 = no haze).
    pub fog_colour: DVec3,
    pub sigma: f64,
    pub scale_height: f64,
    /// Base plane (heights for the haze).
    pub origin: DVec3,
    pub normal: DVec3,
}

impl VolumeLight {
    pub fn new(scene: &SceneDesc, terrain: &Terrain) -> VolumeLight {
        let d = |c: [f32; 3]| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
        let day = scene.daylight();
        VolumeLight {
            sun: day.light,
            sun_colour: d(day.sun_colour),
            intensity: day.intensity as f64,
            zenith: d(day.zenith),
            horizon: d(day.horizon),
            ambient: day.ambient as f64,
            fog_colour: d(day.fog_colour),
            sigma: if scene.fog.visibility > 0.0 {
                3.912 / scene.fog.visibility
            } else {
                0.0
            },
            scale_height: scene.fog.scale_height,
            origin: terrain.frame.origin,
            normal: terrain.frame.normal,
        }
    }

    /// Sky light on a (possibly shortened) normal `n` (world).
    pub fn ambient_light(&self, n: DVec3) -> DVec3 {
        let up = n.z;
        self.horizon.lerp(self.zenith, 0.5 + 0.5 * up) * (self.ambient * (0.6 + 0.4 * up))
    }

    /// Haze between the eye and a point at distance `t`, as the shade pass applies it.
    pub fn haze(&self, c: DVec3, eye: DVec3, dir: DVec3, t: f64) -> DVec3 {
        if self.sigma <= 0.0 {
            return c;
        }
        let ze = (eye - self.origin).dot(self.normal);
        let zp = ze + t * dir.dot(self.normal);
        let hs = self.scale_height;
        let mut tau = self.sigma * t;
        if hs > 0.0 {
            let dz = zp - ze;
            tau = if dz.abs() > 1e-3 * hs {
                self.sigma * t * ((-ze / hs).exp() - (-zp / hs).exp()) / (dz / hs)
            } else {
                self.sigma * t * (-ze / hs).exp()
            };
        }
        let tr = (-tau).exp();
        let scatter =
            self.fog_colour + self.sun_colour * (0.25 * dir.dot(self.sun).max(0.0).powi(8));
        c * tr + scatter * (1.0 - tr)
    }
}

/// What one ray collected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeResult {
    /// Premultiplied colour `P` (linear).
    pub colour: DVec3,
    /// Transmittance left for what lies behind.
    pub transmittance: f64,
    /// Texture samples taken.
    pub samples: u32,
    /// Lattice segments passed (sampled or skipped).
    pub segments: u32,
    /// Where the medium lies along the ray: the samples' distances (metres) weighted by their
    /// contributions `Ω·T`; `+inf` where nothing contributed. [`composite_sorted`] orders
    /// volumes by it.
    pub depth: f64,
    /// Slice-mask samples whose nearest voxel the GPU's f32 arithmetic does not decide: the
    /// sample lies within the f32 error of its position ([`UNDECIDED_ULPS`]) of a face to a
    /// voxel with other bits, so the
    /// GPU may read either (a binary mask looked up at the nearest voxel is discontinuous
    /// there). Tests leave such pixels out of the maximum and bound how many there are.
    pub undecided: u32,
}

/// f32 roundings allowed in the GPU's sample position `o + d·t` (volume frame): the position
/// is within `UNDECIDED_ULPS · 2⁻²³ · (|o| + t)` metres of the exact one.
pub const UNDECIDED_ULPS: f64 = 8.0;

impl VolumeResult {
    /// `P + T · background` (linear).
    pub fn over(&self, background: DVec3) -> DVec3 {
        self.colour + background * self.transmittance
    }
}

/// The sun's light left at an opaque surface point `p` (world) after every volume between it
/// and the sun: the product of the volumes' [`Volume::transmittance_to_sun`], which is exact
/// where boxes overlap too (optical depths add). The shade pass scales the sun's terms of
/// terrain, free forms and voxel models by it (`gpu/shaders/volume_sun.wgsl`).
pub fn sun_through_volumes(volumes: &[Volume], p: DVec3) -> f64 {
    volumes.iter().map(|v| v.transmittance_to_sun(p)).product()
}

/// Per-pixel jitter in 0..1 (WGSL `vol_jitter`).
pub fn jitter(px: [u32; 2]) -> f64 {
    let mut h = px[0].wrapping_mul(73_856_093) ^ px[1].wrapping_mul(19_349_663);
    h = (h ^ (h >> 16)).wrapping_mul(0x7feb_352d);
    h = (h ^ (h >> 15)).wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    (h >> 8) as f64 / 16_777_216.0
}

/// The ray's interval inside the box `[0, ext]` (and the shell), from `t = 0` to `t_max`:
/// `(box entry, start, end)`.
pub fn ray_interval(v: &Volume, o: DVec3, d: DVec3, t_max: f64) -> Option<(f64, f64, f64)> {
    let (t0, t1, _) = super::freeform::clip_box(o, d, DVec3::ZERO, v.extent(), 0.0, t_max)?;
    let (mut ts, mut te) = (t0, t1);
    if let Some((c, r)) = v.shell {
        let oc = (o - c) / r;
        let dd = d / r;
        let a = dd.dot(dd);
        let b = oc.dot(dd);
        let cc = oc.dot(oc) - 1.0;
        let disc = b * b - a * cc;
        if disc <= 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        ts = ts.max((-b - sq) / a);
        te = te.min((-b + sq) / a);
    }
    (ts < te).then_some((t0, ts, te))
}

/// Integrates the volume along the unit world ray `eye + t·dir` for `t < t_max` (the opaque
/// depth, `f64::INFINITY` for sky). `cone` is the pixel's half-angle (radians), `px` its
/// position (jitter).
pub fn integrate(
    v: &Volume,
    light: &VolumeLight,
    eye: DVec3,
    dir: DVec3,
    cone: f64,
    t_max: f64,
    px: [u32; 2],
) -> VolumeResult {
    let mut res = VolumeResult {
        colour: DVec3::ZERO,
        transmittance: 1.0,
        samples: 0,
        segments: 0,
        depth: f64::INFINITY,
        undecided: 0,
    };
    // Sums of the contributions and of contribution times distance.
    let (mut weight, mut weighted_t) = (0.0, 0.0);
    let o = v.to_local(eye);
    let d = v.rotation.transpose() * dir;
    let Some((t0, ts, te)) = ray_interval(v, o, d, t_max) else {
        return res;
    };
    let s = &v.settings;
    let voxel = v.voxel();
    let step = s.step * voxel;
    let j = if s.jitter { jitter(px) } else { 0.0 };
    let ext = v.extent();
    let dims = DVec3::from(v.grid.dims.map(f64::from));
    let bdims = v.bricks.dims;
    let top = (v.texture.levels.len() - 1) as f64;
    let m = &v.material;
    let qsum = m.ambient + m.diffuse + m.specular;
    let clight = light.sun_colour * light.intensity;
    let mut k = ((ts - t0) / step - j).floor();
    while res.segments < MAX_SAMPLES {
        let bk = t0 + (k + j) * step;
        if bk >= te {
            break;
        }
        res.segments += 1;
        let a = bk.max(ts);
        let b = (t0 + (k + 1.0 + j) * step).min(te);
        if b <= a {
            k += 1.0;
            continue;
        }
        let tm = 0.5 * (a + b);
        let p = o + d * tm;
        let u = p / ext;
        let level = if s.mipmaps {
            (2.0 * cone * tm / voxel).max(1e-30).log2().clamp(0.0, top)
        } else {
            0.0
        };
        if s.skip {
            let vox = u * dims;
            let bi: [u32; 3] = std::array::from_fn(|i| {
                ((vox[i] / BRICK as f64).floor().max(0.0) as u32).min(bdims[i] - 1)
            });
            let idx = bi[0] + bdims[0] * (bi[1] + bdims[1] * bi[2]);
            // Level-0 samples need the exact bit, coarser ones the dilated one.
            let need = if level > 0.0 { 2 } else { 1 };
            if v.occupancy[idx as usize] & need == 0 {
                let sp = DVec3::from(v.grid.spacing);
                let mut exit = f64::INFINITY;
                for i in 0..3 {
                    if d[i] != 0.0 {
                        let lo = (bi[i] * BRICK) as f64 * sp[i];
                        let hi = (((bi[i] + 1) * BRICK).min(v.grid.dims[i])) as f64 * sp[i];
                        let face = if d[i] > 0.0 { hi } else { lo };
                        exit = exit.min((face - o[i]) / d[i]);
                    }
                }
                k = (k + 1.0).max(((exit - t0) / step - j).floor());
                continue;
            }
        }
        if v.grid.slices > 0 {
            // Slice masks: nearest voxel, each set bit absorbs and emits its slice's colour.
            let vi: [u32; 3] = std::array::from_fn(|i| {
                ((p[i] / v.grid.spacing[i]).floor().max(0.0) as u32).min(v.grid.dims[i] - 1)
            });
            let bits = v.grid.voxel(vi[0], vi[1], vi[2]);
            res.samples += 1;
            let err = UNDECIDED_ULPS * f64::from(f32::EPSILON) * (o.length() + tm);
            res.undecided += undecided_face(v, p, vi, bits, err) as u32;
            for i in 0..v.grid.slices as usize {
                if bits >> i & 1 != 0 {
                    let e = v.table.entries[i].map(f64::from);
                    let omega = 1.0 - (-e[3] * (b - a)).exp();
                    let c = light.haze(DVec3::new(e[0], e[1], e[2]), eye, dir, tm);
                    res.colour += c * (omega * res.transmittance);
                    weight += omega * res.transmittance;
                    weighted_t += tm * (omega * res.transmittance);
                    res.transmittance *= 1.0 - omega;
                }
            }
            if s.early_termination && res.transmittance < s.epsilon {
                break;
            }
            k += 1.0;
            continue;
        }
        let smp = v.texture.sample([u.x, u.y, u.z], level);
        res.samples += 1;
        let e = v.table.lookup(smp[0]);
        if e[3] > 0.0 {
            let omega = 1.0 - (-e[3] * (b - a)).exp();
            let g = v.rotation * DVec3::from(decode_gradient([smp[1], smp[2], smp[3]]));
            let len = g.length();
            // Outward normal (from dense to less dense): continuous along the ray, unlike a
            // normal flipped to face the eye.
            let n = -g / len.max(1e-6);
            let w = (len * 4.0).clamp(0.0, 1.0);
            let c = DVec3::new(e[0], e[1], e[2]);
            let ndl = 0.5 + (n.dot(light.sun).max(0.0) - 0.5) * w;
            let ca = c * light.ambient_light(n * w);
            // The sun's light left after the volume's own extinction (self-shadowing).
            let sun_left = v.sun_transmittance(p);
            let cd = clight * c * (ndl * sun_left);
            let r = 2.0 * n.dot(light.sun) * n - light.sun;
            let cs = clight * (r.dot(-dir).max(0.0).powf(m.shininess) * w * sun_left);
            let i = (m.ambient * ca + m.diffuse * cd + m.specular * cs) / qsum;
            let i = light.haze(i, eye, dir, tm);
            res.colour += i * (omega * res.transmittance);
            weight += omega * res.transmittance;
            weighted_t += tm * (omega * res.transmittance);
            res.transmittance *= 1.0 - omega;
            if s.early_termination && res.transmittance < s.epsilon {
                break;
            }
        }
        k += 1.0;
    }
    if weight > 0.0 {
        res.depth = weighted_t / weight;
    }
    res
}

/// sRGB encoding of a linear value (clamped to 0..1), as the shaders write it.
pub fn srgb_encode(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear value of an sRGB-encoded one.
pub fn srgb_decode(c: f64) -> f64 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The 8-bit sRGB pixel for one volume's `res` over the 8-bit sRGB pixel `under`.
pub fn composite(res: &VolumeResult, under: [u8; 3]) -> [u8; 3] {
    composite_sorted(std::slice::from_ref(res), under)
}

/// The 8-bit sRGB pixel the composite pass writes for the scene's volumes (`results` in scene
/// order) over the 8-bit sRGB pixel `under`: sorted by [`VolumeResult::depth`], farthest first
/// (ties in scene order), each `P + T·c` over the result so far, in linear light. Exact for
/// media that do not interleave along the ray, whether or not their boxes overlap.
pub fn composite_sorted(results: &[VolumeResult], under: [u8; 3]) -> [u8; 3] {
    let mut order: Vec<&VolumeResult> = results.iter().collect();
    // Stable: equal depths keep scene order, as the shader's insertion sort does.
    order.sort_by(|a, b| b.depth.total_cmp(&a.depth));
    let bg = DVec3::from(under.map(|c| srgb_decode(c as f64 / 255.0)));
    let c = order.iter().fold(bg, |c, r| r.over(c));
    [c.x, c.y, c.z].map(|v| (srgb_encode(v) * 255.0).round() as u8)
}

/// Whether the slice-mask sample at `p` (volume frame, metres), read at voxel `vi` with
/// `bits`, lies within `err` metres of a face to a neighbour with other bits.
fn undecided_face(v: &Volume, p: DVec3, vi: [u32; 3], bits: u8, err: f64) -> bool {
    (0..3).any(|i| {
        let sp = v.grid.spacing[i];
        let f = p[i] / sp - vi[i] as f64;
        let eps = err / sp;
        let mut n = vi;
        if f < eps && vi[i] > 0 {
            n[i] -= 1;
        } else if f > 1.0 - eps && vi[i] + 1 < v.grid.dims[i] {
            n[i] += 1;
        } else {
            return false;
        }
        v.grid.voxel(n[0], n[1], n[2]) != bits
    })
}

/// The volumes as the eye at `eye` sees them on the curved earth: each lowered rigidly by the
/// drop below the eye's tangent plane at its anchor (the bottom face's centre,
/// [`Volume::anchor`]); copies on a flat terrain. The GPU renderer does the same per frame.
pub fn lowered(terrain: &Terrain, eye: DVec3, volumes: &[Volume]) -> Vec<Volume> {
    let curv = terrain.curvature(eye);
    volumes
        .iter()
        .map(|v| v.translated(terrain.curved_offset(&curv, v.anchor())))
        .collect()
}
