// Volume pass: per pixel, front-to-back emission-absorption through one density volume,
// P = sum I_n Omega_n prod_{m<n} (1 - Omega_m), cut at the opaque depth of terrain and free
// forms. Writes P, the transmittance T left and the contribution-weighted depth of the medium;
// the composite pass (volume_composite.wgsl) sorts the volumes by that depth per pixel and
// composites them over the shaded image. Step for step the same as `cpu::volume::integrate`
// (see there for the segment lattice, skipping and lighting).

// `struct Volume` (the uniforms) is in volume_types.wgsl, shared with the volume-sun pass.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(11) var data_in: texture_2d<u32>;
@group(0) @binding(12) var vol_tex: texture_3d<f32>;
@group(0) @binding(14) var<uniform> vol_table: array<vec4<f32>, VOL_TABLE>;
@group(0) @binding(15) var<storage, read> vol_bricks: array<u32>;
@group(0) @binding(16) var<uniform> vol: Volume;
// The sun's transmittance through the volume per voxel (`volume::shadow`; SHADOW), sampled
// with a linear filter: the field is smooth, so the sampler's 8-bit weights stay within a
// fraction of a level of the CPU reference's trilinear weights.
@group(0) @binding(17) var vol_shadow: texture_3d<f32>;
@group(0) @binding(18) var vol_linear: sampler;
// Nearest texel of the nearest level: `vol_texel` reads single texels through it.
@group(0) @binding(20) var vol_nearest: sampler;

// Voxels per brick side (`volume::BRICK`), table entries (`volume::transfer::TABLE_SIZE`),
// samples after which a ray gives up (`cpu::volume::MAX_SAMPLES`).
const VOL_BRICK: u32 = 8u;
const VOL_TABLE: u32 = 256u;
// Voxels towards the sun at which a sample reads its transmittance (`volume::shadow::OFFSET_VOXELS`).
const VOL_SHADOW_OFFSET: f32 = 1.0;
const VOL_MAX_SAMPLES: u32 = 65536u;
// Bits of a slice mask (`volume::procedural` function4d).
const VOL_SLICES: u32 = 8u;

struct VolOut {
    // f32 bits of P (linear, premultiplied) and T.
    @location(0) result: vec4<u32>,
    // x: texture samples taken, y: lattice segments passed, z: f32 bits of the medium's depth
    // (metres along the ray, weighted by each sample's contribution; +inf without one).
    @location(1) stats: vec4<u32>,
}

fn vol_jitter(px: vec2<u32>) -> f32 {
    var h = (px.x * 73856093u) ^ (px.y * 19349663u);
    h = (h ^ (h >> 16u)) * 0x7feb352du;
    h = (h ^ (h >> 15u)) * 0x846ca68bu;
    h = h ^ (h >> 16u);
    return f32(h >> 8u) / 16777216.0;
}

// Colour and extinction at filtered density d (0..1), interpolating the table.
fn vol_lookup(d: f32) -> vec4<f32> {
    let x = clamp(d * 255.0, 0.0, 255.0);
    let i0 = min(u32(floor(x)), VOL_TABLE - 1u);
    let i1 = min(i0 + 1u, VOL_TABLE - 1u);
    return mix(vol_table[i0], vol_table[i1], x - f32(i0));
}

// (box entry, start, end) of the ray o + t d inside the box (and shell) for 0 <= t < t_max;
// start >= end when it misses.
fn vol_interval(o: vec3<f32>, d: vec3<f32>, t_max: f32) -> vec3<f32> {
    let inv = select(vec3<f32>(BIG), 1.0 / d, abs(d) > vec3<f32>(1.0e-30));
    let ta = -o * inv;
    let tb = (vol.extent.xyz - o) * inv;
    let lo = min(ta, tb);
    let hi = max(ta, tb);
    let t0 = max(max(lo.x, lo.y), max(lo.z, 0.0));
    var te = min(min(hi.x, hi.y), min(hi.z, t_max));
    var ts = t0;
    if (SHELL) {
        let oc = (o - vol.shell_centre.xyz) / vol.shell_radii.xyz;
        let dd = d / vol.shell_radii.xyz;
        let a = dot(dd, dd);
        let b = dot(oc, dd);
        let disc = b * b - a * (dot(oc, oc) - 1.0);
        if (disc <= 0.0) {
            return vec3<f32>(t0, 1.0, 0.0);
        }
        let sq = sqrt(disc);
        ts = max(ts, (-b - sq) / a);
        te = min(te, (-b + sq) / a);
    }
    return vec3<f32>(t0, ts, te);
}

// Texel `c` of mip level `l` (n texels per axis). With SAMPLED_FETCH (on GL), read through the
// nearest sampler at its centre with an explicit level, exactly the texel `textureLoad`
// returns: llvmpipe's GL path fetches texels with one mip level for all lanes of a SIMD block,
// so a lane whose level differs from its neighbours' would read the wrong level
// (docs/robustness.md). Sampling costs ~1.5x the volume pass, so other adapters load.
fn vol_texel(c: vec3<i32>, n: vec3<i32>, l: f32) -> vec4<f32> {
    if (SAMPLED_FETCH) {
        return textureSampleLevel(vol_tex, vol_nearest, (vec3<f32>(c) + 0.5) / vec3<f32>(n), l);
    }
    // i32 level: naga's GLSL output bounds-checks with textureSize(sampler, int).
    return textureLoad(vol_tex, c, i32(l));
}

// Trilinear sample of mip level `level` at texture coordinates u (texel centres at
// (i + 0.5) / n, clamp to edge), with f32 weights: texture units filter with 8-bit weights,
// which the CPU reference cannot follow through steep transfer functions.
fn vol_trilinear(u: vec3<f32>, level: u32) -> vec4<f32> {
    let n = vec3<i32>(max(vol.dims.xyz >> vec3<u32>(level), vec3<u32>(1u)));
    let lf = f32(level);
    let q = u * vec3<f32>(n) - 0.5;
    let i0 = floor(q);
    let f = q - i0;
    let a = clamp(vec3<i32>(i0), vec3<i32>(0), n - 1);
    let b = clamp(vec3<i32>(i0) + 1, vec3<i32>(0), n - 1);
    let c000 = vol_texel(a, n, lf);
    let c100 = vol_texel(vec3<i32>(b.x, a.y, a.z), n, lf);
    let c010 = vol_texel(vec3<i32>(a.x, b.y, a.z), n, lf);
    let c110 = vol_texel(vec3<i32>(b.x, b.y, a.z), n, lf);
    let c001 = vol_texel(vec3<i32>(a.x, a.y, b.z), n, lf);
    let c101 = vol_texel(vec3<i32>(b.x, a.y, b.z), n, lf);
    let c011 = vol_texel(vec3<i32>(a.x, b.y, b.z), n, lf);
    let c111 = vol_texel(b, n, lf);
    let x0 = mix(mix(c000, c100, f.x), mix(c010, c110, f.x), f.y);
    let x1 = mix(mix(c001, c101, f.x), mix(c011, c111, f.x), f.y);
    return mix(x0, x1, f.z);
}

// Quadrilinear sample: trilinear in the two levels around `level`, blended. The second level
// is fetched only when some pixel of the SIMD block needs it: the loop decides at the end of
// its body, where Mesa's rasterisers leave a loop once no lane goes on (a test at the top
// still runs the whole body once more for the block).
fn vol_sample(u: vec3<f32>, level: f32) -> vec4<f32> {
    if (!MIPMAPS) {
        return vol_trilinear(u, 0u);
    }
    let l0 = floor(level);
    let f = level - l0;
    let lv = u32(l0);
    var acc = vec4<f32>(0.0);
    var i = 0u;
    // One call site for the trilinear fetch (Mesa inlines every call).
    loop {
        let wi = select(1.0 - f, f, i == 1u);
        acc += vol_trilinear(u, min(lv + i, vol.dims.w - 1u)) * wi;
        i += 1u;
        if (i == 2u || f <= 0.0) {
            break;
        }
    }
    return acc;
}

fn vol_ambient(n: vec3<f32>) -> vec3<f32> {
    let up = n.z;
    return mix(frame.sky_horizon.xyz, frame.sky_zenith.xyz, 0.5 + 0.5 * up) * (frame.sky_zenith.w * (0.6 + 0.4 * up));
}

@fragment
fn fs_volume(@builtin(position) pos: vec4<f32>) -> VolOut {
    let px = vec2<u32>(pos.xy);
    var out: VolOut;
    out.result = bitcast<vec4<u32>>(vec4<f32>(0.0, 0.0, 0.0, 1.0));
    out.stats = vec4<u32>(0u, 0u, 0x7f800000u, 0u);
    let e = ray_entry(px);
    if (e.w < 0.0) {
        return out;
    }
    let bits = textureLoad(data_in, vec2<i32>(px), 0).x;
    let t_max = select(bitcast<f32>(bits), BIG, (bits & 0x7f800000u) == 0x7f800000u);
    let dir = e.xyz;
    let o = vol.eye_local.xyz;
    let d = vec3<f32>(dot(vol.local_from_world_0.xyz, dir), dot(vol.local_from_world_1.xyz, dir), dot(vol.local_from_world_2.xyz, dir));
    let iv = vol_interval(o, d, t_max);
    let t0 = iv.x;
    let ts = iv.y;
    let te = iv.z;
    if (ts >= te) {
        return out;
    }
    let step = vol.eye_local.w;
    var j = 0.0;
    if (JITTER) {
        j = vol_jitter(px);
    }
    let ext = vol.extent.xyz;
    let voxel = vol.extent.w;
    let dims = vec3<f32>(vol.dims.xyz);
    let top = f32(vol.dims.w - 1u);
    let m = vol.material;
    let qsum = m.x + m.y + m.z;
    let sun = frame.sun_world.xyz;
    // The sun in the volume frame (self-shadowing reads).
    let sun_l = vec3<f32>(dot(vol.local_from_world_0.xyz, sun), dot(vol.local_from_world_1.xyz, sun), dot(vol.local_from_world_2.xyz, sun));
    let clight = frame.sun_colour.xyz * frame.sun_local.w;
    let dl = to_local(dir);
    let up_rate = dot(frame.local_from_world_2.xyz, dir);
    var acc = vec3<f32>(0.0);
    var tr = 1.0;
    // Sums of contribution (Omega T) and contribution times depth.
    var weight = 0.0;
    var weighted_t = 0.0;
    var samples = 0u;
    var segments = 0u;
    var k = floor((ts - t0) / step - j);
    // Two nested loops for SIMD rasterisers (as in the terrain traversal): the inner one only
    // walks the segment lattice past empty bricks and empty segments to the next segment to
    // sample; the sampling and lighting run after it, once for all lanes, instead of in every
    // walking iteration one lane needs. The same segments, samples and counts as one loop.
    loop {
        var found = false;
        var a = 0.0;
        var b = 0.0;
        var level = 0.0;
        loop {
            let bk = t0 + (k + j) * step;
            if (bk >= te || segments >= VOL_MAX_SAMPLES) {
                break;
            }
            segments += 1u;
            a = max(bk, ts);
            b = min(t0 + (k + 1.0 + j) * step, te);
            if (b <= a) {
                k += 1.0;
                continue;
            }
            let tm = 0.5 * (a + b);
            if (MIPMAPS) {
                level = clamp(log2(max(2.0 * e.w * tm / voxel, 1.0e-30)), 0.0, top);
            }
            if (SKIP) {
                let u = (o + d * tm) / ext;
                let bi = min(vec3<u32>(max(floor(u * dims / f32(VOL_BRICK)), vec3<f32>(0.0))), vol.bricks.xyz - 1u);
                // Level-0 samples need the exact bit, coarser ones the dilated one.
                let need = select(1u, 2u, level > 0.0);
                if ((vol_bricks[bi.x + vol.bricks.x * (bi.y + vol.bricks.y * bi.z)] & need) == 0u) {
                    let lo = vec3<f32>(bi * VOL_BRICK) * vol.spacing.xyz;
                    let hi = vec3<f32>(min((bi + 1u) * VOL_BRICK, vol.dims.xyz)) * vol.spacing.xyz;
                    let face = select(lo, hi, d > vec3<f32>(0.0));
                    let te3 = select(vec3<f32>(BIG), (face - o) / d, d != vec3<f32>(0.0));
                    let exit = min(te3.x, min(te3.y, te3.z));
                    k = max(k + 1.0, floor((exit - t0) / step - j));
                    continue;
                }
            }
            found = true;
            break;
        }
        if (!found) {
            break;
        }
        let tm = 0.5 * (a + b);
        let p = o + d * tm;
        let u = p / ext;
        if (SLICES) {
            // Slice masks: nearest voxel, each set bit absorbs and emits its slice's colour.
            let vi = clamp(vec3<i32>(floor(p / vol.spacing.xyz)), vec3<i32>(0), vec3<i32>(vol.dims.xyz) - 1);
            let bits = u32(textureLoad(vol_tex, vi, 0).x * 255.0 + 0.5);
            samples += 1u;
            for (var i = 0u; i < VOL_SLICES; i += 1u) {
                if (((bits >> i) & 1u) != 0u) {
                    let e = vol_table[i];
                    let omega = 1.0 - exp(-e.w * (b - a));
                    acc += aerial_perspective(e.xyz, tm, frame.eye.z + tm * up_rate, dl) * (omega * tr);
                    weight += omega * tr;
                    weighted_t += tm * (omega * tr);
                    tr *= 1.0 - omega;
                }
            }
            if (TERMINATION && tr < vol.spacing.w) {
                break;
            }
            k += 1.0;
            continue;
        }
        let s = vol_sample(u, level);
        samples += 1u;
        let c4 = vol_lookup(s.x);
        if (c4.w > 0.0) {
            let omega = 1.0 - exp(-c4.w * (b - a));
            let gl = (s.yzw * 255.0 - 128.0) / 127.0;
            let g = vol.world_from_local_0.xyz * gl.x + vol.world_from_local_1.xyz * gl.y + vol.world_from_local_2.xyz * gl.z;
            let len = length(g);
            let n = -g / max(len, 1.0e-6);
            let w = clamp(len * 4.0, 0.0, 1.0);
            let c = c4.xyz;
            let ndl = 0.5 + (max(dot(n, sun), 0.0) - 0.5) * w;
            let ca = c * vol_ambient(n * w);
            // The sun's light left after the volume's own extinction (self-shadowing).
            var sun_left = 1.0;
            if (SHADOW) {
                // Read VOL_SHADOW_OFFSET voxels towards the sun (`Volume::sun_transmittance`).
                let q = (p + sun_l * (VOL_SHADOW_OFFSET * voxel)) / ext;
                sun_left = textureSampleLevel(vol_shadow, vol_linear, q, 0.0).x;
            }
            let cd = clight * c * (ndl * sun_left);
            let r = 2.0 * dot(n, sun) * n - sun;
            let cs = clight * (pow(max(dot(r, -dir), 0.0), m.w) * w * sun_left);
            let i = (m.x * ca + m.y * cd + m.z * cs) / qsum;
            let lit = aerial_perspective(i, tm, frame.eye.z + tm * up_rate, dl);
            acc += lit * (omega * tr);
            weight += omega * tr;
            weighted_t += tm * (omega * tr);
            tr *= 1.0 - omega;
            if (TERMINATION && tr < vol.spacing.w) {
                break;
            }
        }
        k += 1.0;
    }
    let depth_bits = select(0x7f800000u, bitcast<u32>(weighted_t / weight), weight > 0.0);
    out.stats = vec4<u32>(samples, segments, depth_bits, 0u);
    out.result = bitcast<vec4<u32>>(vec4<f32>(acc, tr));
    return out;
}
