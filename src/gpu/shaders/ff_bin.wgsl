// Object binning (compute, one invocation per 16x16-pixel bin). From the bin's rays (the ray
// table, so it works through any distortion) and the G-buffer:
// * list 0 (primary rays): objects whose bounding sphere meets the bin's cone of rays before
//   the farthest terrain hit of the bin;
// * list 1 (shadow rays): objects whose box, seen along the sun, covers some surface point
//   the bin shows and reaches sun-ward of it (bounds of the points in a frame whose third
//   axis is the sun: a shadow ray projects to a single point of the other two).
// Each list keeps plain objects (one quadric) and perturbed ones apart (layout in
// ff_bins.wgsl). Pixels then test only their bin's objects: cost grows with objects per bin.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer: texture_2d<u32>;
@group(0) @binding(8) var<storage, read_write> ff_bins_out: array<u32>;

// FF_BIN, FF_OVERFLOW: ff_consts.wgsl (prepended).
const NOT_ONE: u32 = 0xffffffffu;

// Pixel k of a walk around the border of the bin [p0, last] (k < 2 * (width + height); the
// corners are visited twice).
fn bin_border(p0: vec2<u32>, last: vec2<u32>, k: u32) -> vec2<u32> {
    let w = last.x - p0.x + 1u;
    let h = last.y - p0.y + 1u;
    if (k < w) {
        return vec2<u32>(p0.x + k, p0.y);
    }
    if (k < 2u * w) {
        return vec2<u32>(p0.x + k - w, last.y);
    }
    if (k < 2u * w + h) {
        return vec2<u32>(p0.x, p0.y + k - 2u * w);
    }
    return vec2<u32>(last.x, p0.y + min(k - 2u * w - h, h - 1u));
}

// Does the segment o + u dir, u in [0, u_max] (dir unit, world), come within `r` of the
// object's bounding box? Slab test of the segment against the box grown by r on every side
// (in the object frame): a point within Euclidean distance r of the box lies in the grown box,
// so `false` is a proof that the r-neighbourhood of the segment misses the box.
fn segment_near_box(ob: FfObject, o_world: vec3<f32>, dir: vec3<f32>, r: f32, u_max: f32) -> bool {
    let o = ff_to_local(ob, o_world - ob.position.xyz);
    let d = ff_to_local(ob, dir);
    let ds = select(d, vec3<f32>(1.0e-20), abs(d) < vec3<f32>(1.0e-20));
    let inv = 1.0 / ds;
    let ta = (ob.box_min.xyz - vec3<f32>(r) - o) * inv;
    let tb = (ob.box_max.xyz + vec3<f32>(r) - o) * inv;
    let tn = min(ta, tb);
    let tf = max(ta, tb);
    let t0 = max(max(tn.x, tn.y), max(tn.z, 0.0));
    let t1 = min(min(tf.x, tf.y), min(tf.z, u_max));
    return t0 <= t1;
}

// Pixel k of the rays that bound a bin's cone: its border, or with `every` all its pixels.
fn cone_pixel(p0: vec2<u32>, last: vec2<u32>, k: u32, every: bool) -> vec2<u32> {
    if (every) {
        let w = last.x - p0.x + 1u;
        return p0 + vec2<u32>(k % w, k / w);
    }
    return bin_border(p0, last, k);
}

fn bin_objects(b: vec2<u32>, list: u32) {
    if (b.x >= frame.objects.y || b.y >= frame.objects.z) {
        return;
    }
    let bins = frame.objects.y * frame.objects.z;
    let base = (list * bins + b.y * frame.objects.y + b.x) * (frame.objects.w + 1u);
    let p0 = b * FF_BIN;
    let p1 = min(p0 + FF_BIN, frame.size.xy);
    // Farthest surface point of the bin (sky: unbounded for primary rays).
    var t_hi = 0.0;
    var hits = 0u;
    var sky = false;
    // The free form every surface pixel of the bin shows, if there is one (NOT_ONE otherwise).
    var only = NOT_ONE;
    // Nearest surface point of the bin (shadow list).
    var t_lo = BIG;
    // Largest shadow-ray offset off a free-form surface the bin shows.
    var max_off = 0.0;
    for (var y = p0.y; y < p1.y; y++) {
        for (var x = p0.x; x < p1.x; x++) {
            let g = textureLoad(gbuffer, vec2<i32>(i32(x), i32(y)), 0);
            if ((g.w & 1u) != 0u) {
                let t = bitcast<f32>(g.x);
                t_hi = max(t_hi, t);
                if (list == 1u) {
                    t_lo = min(t_lo, t);
                    if ((g.w & 16u) != 0u) {
                        max_off = max(max_off, ff_objects[g.y & 0xffffu].position.w);
                    }
                }
                let id = select(NOT_ONE, g.y & 0xffffu, (g.w & 16u) != 0u);
                only = select(select(only, NOT_ONE, id != only), id, hits == 0u);
                hits += 1u;
            } else if ((g.w & 8u) == 0u) {
                sky = true;
            }
        }
    }
    if (list == 0u && sky) {
        t_hi = BIG;
    }
    if ((hits == 0u && !sky) || (list == 1u && hits == 0u)) {
        ff_bins_out[base] = 0u;
        return;
    }
    // Cone of the bin's rays from its border pixels (the ray table is smooth over a bin, so
    // the extreme directions lie on the border), padded by the widest pixel cone and 10%. The
    // axis is the centre pixel's ray (the mean border ray where the centre shows no screen);
    // the half-angle comes from the largest chord |e - axis|, without trigonometry per pixel.
    // In the anti-aliasing sample atlas (`frame.stamp.y` = 1) neighbouring entries need not be
    // neighbouring rays: the cone is then taken over every ray of the bin, around their mean.
    let last = p1 - vec2<u32>(1u);
    let every = frame.stamp.y != 0u;
    let width = p1.x - p0.x;
    let count = select(2u * ((p1.x - p0.x) + (p1.y - p0.y)), width * (p1.y - p0.y), every);
    let centre = ray_entry((p0 + last) / 2u);
    var axis = centre.xyz;
    var cone = max(centre.w, 0.0);
    if (centre.w < 0.0 || every) {
        var sum = vec3<f32>(0.0);
        for (var k = 0u; k < count; k++) {
            let e = ray_entry(cone_pixel(p0, last, k, every));
            if (e.w >= 0.0) {
                sum += e.xyz;
            }
        }
        axis = normalize(sum + vec3<f32>(0.0, 0.0, 1.0e-30));
    }
    var chord2 = 0.0;
    for (var k = 0u; k < count; k++) {
        let e = ray_entry(cone_pixel(p0, last, k, every));
        if (e.w >= 0.0) {
            let c = e.xyz - axis;
            chord2 = max(chord2, dot(c, c));
            cone = max(cone, e.w);
        }
    }
    let half_chord = 0.5 * sqrt(min(chord2, 4.0));
    var theta = 2.0 * atan2(half_chord, sqrt(max(1.0 - half_chord * half_chord, 0.0)));
    theta = 1.1 * theta + cone + 1.0e-4;
    let tan_theta = tan(min(theta, 1.0));
    let sec_theta = 1.0 / cos(min(theta, 1.0));
    let eye = frame.eye_world.xyz;
    // Shadow list: the bin's surface points (relative to the eye) in a sun frame (su, sv,
    // sun): ranges along su and sv, lowest along the sun. Each point is t d with t in
    // [t_lo, t_hi] and d within θ of the axis, so d·X lies within θ of axis·X for a unit X
    // (|d − axis| ≤ θ): bounds from two depths and the cone, no per-pixel ray loads.
    let sun = frame.sun_world.xyz;
    let su = normalize(select(cross(sun, vec3<f32>(1.0, 0.0, 0.0)), cross(sun, vec3<f32>(0.0, 0.0, 1.0)), abs(sun.z) < 0.9));
    let sv = cross(sun, su);
    let spread = min(theta, 2.0);
    let ax = vec3<f32>(dot(axis, su), dot(axis, sv), dot(axis, sun));
    let lo3 = min(t_lo * (ax - spread), t_hi * (ax - spread));
    let hi3 = max(t_lo * (ax + spread), t_hi * (ax + spread));
    let uv_lo = lo3.xy;
    let uv_hi = hi3.xy;
    let w_lo = lo3.z;
    // Padding of the sun-frame bounds: the shadow rays' offset off a free-form surface, and
    // (by a wide margin) f32 rounding of points up to t_hi away. Anti-aliasing's centre rays
    // (`frame.stamp.z` = 1) search the beam of a pixel's footprint too (`footprint_beam`: at
    // most FOOTPRINT_BEAM_CAP pixel widths, 2 t w).
    let beam = select(0.0, FOOTPRINT_BEAM_CAP * 2.0 * t_hi * 1.1 * cone, frame.stamp.z != 0u && list == 1u);
    let pad = max_off + 0.1 + 1.0e-4 * t_hi + beam;
    let cap = frame.objects.w;
    var n_plain = 0u;
    var n_general = 0u;
    // A convex solid cannot shadow its own surface (the shadow pass starts its rays off the
    // surface, towards the sun): a bin showing only one convex free form leaves it out of its
    // shadow list (a runway: otherwise every runway pixel would test the runway).
    var self_only = NOT_ONE;
    if (list == 1u && only != NOT_ONE && ff_objects[only].material.w > 0.0) {
        self_only = only;
    }
    for (var i = 0u; i < frame.objects.x; i++) {
        if (i == self_only) {
            continue;
        }
        let sp = ff_objects[i].sphere;
        var keep = false;
        if (list == 0u) {
            let v = sp.xyz - eye;
            let dist = length(v);
            if (dist <= sp.w) {
                keep = true;
            } else if (dist - sp.w <= t_hi) {
                // Sphere against the cone without trigonometry per object: a centre at axial
                // distance u and radial distance perp lies (perp - u tan θ) cos θ from the
                // cone's side, so it meets the cone when perp <= u tan θ + R / cos θ (u < 0
                // taken as 0: more permissive; a centre near the apex is caught above).
                let u = dot(v, axis);
                let perp = length(v - axis * u);
                keep = theta >= 1.0 || perp <= max(u, 0.0) * tan_theta + sp.w * sec_theta + 1.0e-4 * dist;
            }
            // The sphere of a long, thin object (a runway) covers far more of the screen than
            // its box, above all when the eye is inside the sphere: a bin's rays lie within
            // t tan(theta) of the axis at axial distance t, so the axis segment up to the
            // nearer of the farthest surface point and the sphere's far side must come within
            // that of the box.
            if (keep && theta < 1.0) {
                let reach = min(t_hi, dist + sp.w);
                let r = reach * tan_theta + 1.0e-2 + 1.0e-5 * reach;
                keep = segment_near_box(ff_objects[i], eye, axis, r, reach);
            }
        } else {
            // The object's box projected on the sun frame: exact ranges of an oriented box
            // (centre ± half-extents against the axis in the object frame). A shadow ray
            // from point p meets the box only if the box's su and sv ranges hold p's and the
            // box reaches p's height along the sun.
            let ob = ff_objects[i];
            let c = ob.position.xyz - eye;
            let bc = 0.5 * (ob.box_min.xyz + ob.box_max.xyz);
            let bh = 0.5 * (ob.box_max.xyz - ob.box_min.xyz);
            let lu = ff_to_local(ob, su);
            let lv = ff_to_local(ob, sv);
            let lw = ff_to_local(ob, sun);
            let centre = vec3<f32>(dot(c, su) + dot(bc, lu), dot(c, sv) + dot(bc, lv), dot(c, sun) + dot(bc, lw));
            let half = vec3<f32>(dot(bh, abs(lu)), dot(bh, abs(lv)), dot(bh, abs(lw)));
            let lo = centre.xy - half.xy;
            let hi = centre.xy + half.xy;
            keep = all(lo <= uv_hi + pad) && all(hi >= uv_lo - pad) && centre.z + half.z >= w_lo - pad;
            // Separating axes between the box and the prism the bin's shadow rays sweep (the
            // su-sv rectangle of the points, extruded along the sun): besides su, sv and the
            // sun, the cross products of the sun with the box's edges. They matter for long
            // boxes lying oblique in the sun frame (a runway), whose su-sv rectangle is loose.
            let rc = 0.5 * (uv_lo + uv_hi);
            let rh = 0.5 * (uv_hi - uv_lo);
            for (var k = 0u; k < 3u; k++) {
                let edge = select(select(ob.local_2.xyz, ob.local_1.xyz, k == 1u), ob.local_0.xyz, k == 0u);
                let a3 = cross(sun, edge);
                let len = length(a3);
                if (len > 1.0e-3) {
                    let a = a3 / len;
                    let a2 = vec2<f32>(dot(a, su), dot(a, sv));
                    let la = ff_to_local(ob, a);
                    let gap = abs(dot(c, a) + dot(bc, la) - dot(rc, a2));
                    keep = keep && gap <= dot(bh, abs(la)) + dot(rh, abs(a2)) + pad;
                }
            }
        }
        if (keep) {
            // Plain objects (one quadric) from the front of the slots, perturbed ones from the
            // back (see ff_bins.wgsl).
            let plain = bitcast<u32>(ff_objects[i].box_max.w) == 1u;
            if (n_plain + n_general < cap) {
                ff_bins_out[select(base + cap - n_general, base + 1u + n_plain, plain)] = i;
            }
            n_plain += select(0u, 1u, plain);
            n_general += select(1u, 0u, plain);
        }
    }
    ff_bins_out[base] = select(n_plain | (n_general << 16u), FF_OVERFLOW, n_plain + n_general > cap);
}

// Bin of invocation `lid` of workgroup `wg` (of `groups`): strided, so that every workgroup
// samples the whole screen. Mesa's CPU adapters hand each thread a fixed block of workgroups;
// with row-major bins one thread would get the sky and the other the objects.
fn strided_bin(wg: u32, lid: u32, groups: u32) -> vec2<u32> {
    let i = wg + groups * lid;
    return vec2<u32>(i % frame.objects.y, i / frame.objects.y);
}

@compute @workgroup_size(64)
fn cs_bin_primary(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32, @builtin(num_workgroups) n: vec3<u32>) {
    bin_objects(strided_bin(wg.x, lid, n.x), 0u);
}

@compute @workgroup_size(64)
fn cs_bin_shadow(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32, @builtin(num_workgroups) n: vec3<u32>) {
    bin_objects(strided_bin(wg.x, lid, n.x), 1u);
}
