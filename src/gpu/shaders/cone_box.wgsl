// A pixel's cone against a box, for anti-aliasing's near-miss searches of free forms and
// voxel models (included after FRAME).

// The span [x, y] (empty when x > y) of t in [t_min, t_max] over which the ray o + t d
// passes through the box [lo, hi] widened by w(t) = a + b t on every side: the box the cone
// of radius w(t) around the ray meets, in the L-infinity sense (a point up to √3 w(t) from
// the box can count). Per axis, lo - w(t) <= o + d t <= hi + w(t) is a pair of linear bounds
// on t: (d + b) t >= lo - a - o and (d - b) t <= hi + a - o, a bound from below where the
// factor is positive, from above where it is negative, none (or no t at all) where it is 0.
// A box widened by one w for the whole span (its far end's) would be wider than the cone
// where the ray passes near: along a runway 900 m long seen from before its threshold, grass
// pixels up to eight pixels beside it were flagged (`tests/antialias.rs`).
fn cone_box_span(o: vec3<f32>, d: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>, a: f32, b: f32, t_min: f32, t_max: f32) -> vec2<f32> {
    let lo_k = d + b;
    let lo_v = lo - a - o;
    let hi_k = d - b;
    let hi_v = hi + a - o;
    let zero = vec3<f32>(0.0);
    let lo_t = lo_v / select(lo_k, vec3<f32>(1.0), lo_k == zero);
    let hi_t = hi_v / select(hi_k, vec3<f32>(1.0), hi_k == zero);
    let enter = max(select(zero, lo_t, lo_k > zero), select(zero, hi_t, hi_k < zero));
    let leave = min(select(vec3<f32>(BIG), lo_t, lo_k < zero), select(vec3<f32>(BIG), hi_t, hi_k > zero));
    let never = any((lo_k == zero) & (lo_v > zero)) || any((hi_k == zero) & (hi_v < zero));
    let t0 = max(max(max(enter.x, enter.y), enter.z), t_min);
    let t1 = min(min(min(leave.x, leave.y), leave.z), t_max);
    return select(vec2<f32>(t0, t1), vec2<f32>(1.0, 0.0), never);
}
