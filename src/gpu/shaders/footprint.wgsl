// The footprint of a pixel as anti-aliasing's shadow searches see it: the beam its sun rays
// form (`footprint_beam`, `pixel_beam`). Needs the ray table (ray_table.wgsl), `frame` and BIG
// (frame.wgsl), and the pass's G-buffer as `gbuffer`.

// Anti-aliasing's shadow searches: the footprint of a pixel is at most this many pixel widths
// long (a surface seen within a few degrees of grazing); the free-form shadow lists are
// padded by it.
const FOOTPRINT_BEAM_CAP: f32 = 2.0;

// Half the difference from `p` (relative to the eye) to the hit point of neighbour `q` at
// distance `tq` (negative: it shows no surface; the vector is then BIG long), across the
// unit direction `s`.
fn footprint_side(p: vec3<f32>, q: vec2<u32>, tq: f32, s: vec3<f32>) -> vec3<f32> {
    if (tq < 0.0) {
        return vec3<f32>(BIG);
    }
    let v = ray_dir(q) * tq - p;
    return 0.5 * (v - s * dot(v, s));
}

// Radius of the beam that the rays along `s` (unit, world) from the points of pixel `px`'s
// footprint form, its surface at distance `t`: from the hit distances of its neighbours
// across (`tx`: left, right) and down (`ty`: up, down; negative where one shows no surface
// or lies off the screen). Per axis the half-difference to the nearer neighbour (a depth jump
// on one side leaves the other) spans the footprint, a parallelogram whose corners lie
// max(|a + b|, |a - b|) from its centre across the beam; where both neighbours on an axis
// are missing, the pixel's own width 2 t w stands in. At most FOOTPRINT_BEAM_CAP widths.
fn footprint_beam(px: vec2<u32>, t: f32, tx: vec2<f32>, ty: vec2<f32>, s: vec3<f32>) -> f32 {
    let e = ray_entry(px);
    let p = e.xyz * t;
    let width = 2.0 * t * max(e.w, 0.0);
    let l = footprint_side(p, px - vec2<u32>(1u, 0u), tx.x, s);
    let r = footprint_side(p, px + vec2<u32>(1u, 0u), tx.y, s);
    let u = footprint_side(p, px - vec2<u32>(0u, 1u), ty.x, s);
    let d = footprint_side(p, px + vec2<u32>(0u, 1u), ty.y, s);
    let a = select(r, l, dot(l, l) < dot(r, r));
    let b = select(d, u, dot(u, u) < dot(d, d));
    var radius: f32;
    if (a.x < BIG && b.x < BIG) {
        radius = sqrt(max(dot(a + b, a + b), dot(a - b, a - b)));
    } else {
        radius = select(0.5 * width, length(a), a.x < BIG) + select(0.5 * width, length(b), b.x < BIG);
    }
    return min(radius, FOOTPRINT_BEAM_CAP * width);
}

// Hit distance of the G-buffer at `px` + `o`: negative where it shows no surface or lies off
// the screen.
fn footprint_neighbour_t(px: vec2<u32>, o: vec2<i32>) -> f32 {
    let q = vec2<i32>(px) + o;
    if (any(q < vec2<i32>(0)) || any(q >= vec2<i32>(frame.size.xy))) {
        return -1.0;
    }
    let g = textureLoad(gbuffer, q, 0);
    return select(-1.0, bitcast<f32>(g.x), (g.w & 1u) != 0u);
}

// `footprint_beam` of pixel `px`, its surface at distance `t`, its neighbours' hit distances
// read from the G-buffer.
fn pixel_beam(px: vec2<u32>, t: f32, s: vec3<f32>) -> f32 {
    let tx = vec2<f32>(footprint_neighbour_t(px, vec2<i32>(-1, 0)), footprint_neighbour_t(px, vec2<i32>(1, 0)));
    let ty = vec2<f32>(footprint_neighbour_t(px, vec2<i32>(0, -1)), footprint_neighbour_t(px, vec2<i32>(0, 1)));
    return footprint_beam(px, t, tx, ty, s);
}

// The same beam from the pixel's cone alone (ray differentials, no neighbour loads): the
// cone's cross-section at the hit, a disc of radius `r` (the pixel's corners: √2 times its
// half-width) around the unit view direction `d`, laid along `d` onto the surface's tangent
// plane (unit normal `n`) and seen across the unit direction `s`: the largest singular value
// of that linear map, times `r`. Exact for a plane; at most FOOTPRINT_BEAM_CAP widths.
fn cone_beam(d: vec3<f32>, n: vec3<f32>, s: vec3<f32>, r: f32) -> f32 {
    let a = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), abs(d.x) > 0.7);
    let u1 = normalize(cross(d, a));
    let u2 = cross(d, u1);
    var dn = dot(d, n);
    dn = select(min(dn, -1.0e-4), max(dn, 1.0e-4), dn >= 0.0);
    let p1 = u1 - d * (dot(u1, n) / dn);
    let p2 = u2 - d * (dot(u2, n) / dn);
    let c1 = p1 - s * dot(p1, s);
    let c2 = p2 - s * dot(p2, s);
    let g11 = dot(c1, c1);
    let g22 = dot(c2, c2);
    let g12 = dot(c1, c2);
    let h = 0.5 * (g11 - g22);
    let largest = 0.5 * (g11 + g22) + sqrt(h * h + g12 * g12);
    return min(r * sqrt(largest), FOOTPRINT_BEAM_CAP * sqrt(2.0) * r);
}
