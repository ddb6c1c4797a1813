// The footprint of a pixel as anti-aliasing's shadow searches see it: the beam its sun rays
// form (`footprint_beam`). Needs the ray table (ray_table.wgsl) and BIG (frame.wgsl).

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
