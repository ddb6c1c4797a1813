// Quadric free forms: ray–object intersection, the same algorithm as `cpu/freeform.rs`.
// Per object: rigid move of the ray into the object frame (t stays in metres), clip to the
// bounding box, re-centre on the entry point p0 so every node's Q(p0 + s d) = α s² + β s + γ
// is well conditioned. F'(p0) <= 0: the ray enters the solid through a box face. Otherwise a
// plain quadric takes the stable first root; a perturbed one runs the depth-first interval
// search: an interval whose enclosure of F' stays above zero is skipped, others are halved
// down to L / 2^FF_LEVELS; the first leaf reached brackets the first point with F' <= 0.

struct FfObject {
    // Rows of the object-from-world rotation; local_0.w = a bound on |∇F'| over the box
    // widened by local_1.w metres each way (`FreeForm::gradient_bound`, anti-aliasing's near
    // misses of perturbed objects).
    local_0: vec4<f32>,
    local_1: vec4<f32>,
    local_2: vec4<f32>,
    // World position of the object origin; w = shadow-ray offset (m).
    position: vec4<f32>,
    // Bounding box in the object frame; w = bits of the first node / the node count.
    box_min: vec4<f32>,
    box_max: vec4<f32>,
    // Linear RGB; w = specular exponent.
    colour: vec4<f32>,
    // Qa, Qd, Qs; w = 1 for a convex solid (`FreeForm::is_convex`), else 0.
    material: vec4<f32>,
    // World bounding sphere: centre, radius.
    sphere: vec4<f32>,
}

// One quadric Ax²+By²+Cz²+Dxy+Exz+Fyz+Gx+Hy+Iz+K of a flattened perturbation tree
// (pre-order: a node's subtree is the run after it).
struct FfNode {
    // A, B, C, D.
    q0: vec4<f32>,
    // E, F, G, H.
    q1: vec4<f32>,
    // I, K, weight, depth.
    q2: vec4<f32>,
}

// `ff_objects` (binding 6, FfObject per object) and `ff_nodes` (binding 7, FfNode per node)
// are declared ahead of this file by `gpu::shaders::freeform`: uniform buffers where the scene
// fits (see `gpu::objects::FfTables`), storage buffers otherwise.

const FF_MAX_NODES: u32 = 16u;
const FF_MAX_DEPTH: u32 = 3u;
const FF_LEVELS: u32 = 16u;
// Shadow rays only ask whether a root exists: leaves of L / 2^10 (4 cm on a 40 m box) whose
// enclosure still admits F' <= 0 count as blocked, without the endpoint refinement.
const FF_SHADOW_LEVELS: u32 = 10u;
// Leaves of the near-miss search (`ff_intersect`): L / 2^4. Deeper costs more than the
// samples of the extra pixels a coarser leaf flags (airfield 1280x720: 6 levels +12 ms in
// the centre rays' perturbed pass, 4 levels +6 ms and 300 more pixels flagged).
const FF_NEAR_LEVELS: u32 = 4u;
const FF_LEAF: f32 = 2.5e-4;
const FF_MAX_ITERATIONS: u32 = 1024u;

// No arrays here: llvmpipe zero-initialises every function-scope array of an inlined shader
// at entry, for every fragment, whether or not the code runs. Node coefficients are
// recomputed from the storage buffer instead, and tree sums live in three scalars
// (FF_MAX_DEPTH = 3).

struct FfHit {
    hit: bool,
    t: f32,
    // Unit world normal of a box-face entry; zero otherwise (see `ff_normal`).
    n: vec3<f32>,
    // Enclosure evaluations spent.
    iterations: u32,
}

fn ff_to_local(ob: FfObject, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(ob.local_0.xyz, v), dot(ob.local_1.xyz, v), dot(ob.local_2.xyz, v));
}

fn ff_to_world(ob: FfObject, v: vec3<f32>) -> vec3<f32> {
    return ob.local_0.xyz * v.x + ob.local_1.xyz * v.y + ob.local_2.xyz * v.z;
}

fn ff_eval(n: FfNode, p: vec3<f32>) -> f32 {
    return p.x * (n.q0.x * p.x + n.q0.w * p.y + n.q1.x * p.z + n.q1.z) + p.y * (n.q0.y * p.y + n.q1.y * p.z + n.q1.w) + p.z * (n.q0.z * p.z + n.q2.x) + n.q2.y;
}

fn ff_grad(n: FfNode, p: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        2.0 * n.q0.x * p.x + n.q0.w * p.y + n.q1.x * p.z + n.q1.z,
        2.0 * n.q0.y * p.y + n.q0.w * p.x + n.q1.y * p.z + n.q1.w,
        2.0 * n.q0.z * p.z + n.q1.x * p.x + n.q1.y * p.y + n.q2.x,
    );
}

// (α, β, γ) with Q(o + s d) = α s² + β s + γ.
fn ff_along(n: FfNode, o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let md = vec3<f32>(
        n.q0.x * d.x + 0.5 * (n.q0.w * d.y + n.q1.x * d.z),
        n.q0.y * d.y + 0.5 * (n.q0.w * d.x + n.q1.y * d.z),
        n.q0.z * d.z + 0.5 * (n.q1.x * d.x + n.q1.y * d.y),
    );
    let g = vec3<f32>(n.q1.z, n.q1.w, n.q2.x);
    return vec3<f32>(dot(d, md), 2.0 * dot(o, md) + dot(g, d), ff_eval(n, o));
}

fn ff_quad(c: vec3<f32>, s: f32) -> f32 {
    return (c.x * s + c.y) * s + c.z;
}

// Exact range of a quadratic over [a, b].
fn ff_range(c: vec3<f32>, a: f32, b: f32) -> vec2<f32> {
    let fa = ff_quad(c, a);
    let fb = ff_quad(c, b);
    var r = vec2<f32>(min(fa, fb), max(fa, fb));
    if (c.x != 0.0) {
        let sv = -c.y / (2.0 * c.x);
        if (sv > a && sv < b) {
            let fv = ff_quad(c, sv);
            r = vec2<f32>(min(r.x, fv), max(r.y, fv));
        }
    }
    return r;
}

// A perturbed object's nodes along one ray, for scenes whose perturbed objects all have at most
// FF_RAY_NODES nodes (FF_SMALL, a constant the passes are built with): each node's (α, β, γ)
// and weight, and the depths, computed once per ray instead of reloaded from the storage
// buffer (a per-lane gather on Mesa's CPU adapters) and recomputed at every enclosure. Fields,
// not an array: llvmpipe zero-initialises function-scope arrays for every fragment.
const FF_RAY_NODES: u32 = 4u;

struct FfRayNodes {
    c0: vec4<f32>,
    c1: vec4<f32>,
    c2: vec4<f32>,
    c3: vec4<f32>,
    depth: vec4<u32>,
    count: u32,
}

fn ff_ray_node(n: FfNode, p0: vec3<f32>, dir: vec3<f32>) -> vec4<f32> {
    return vec4<f32>(ff_along(n, p0, dir), n.q2.z);
}

fn ff_ray_nodes(first: u32, count: u32, p0: vec3<f32>, dir: vec3<f32>) -> FfRayNodes {
    let last = first + max(min(count, FF_RAY_NODES), 1u) - 1u;
    let n0 = ff_nodes[first];
    let n1 = ff_nodes[min(first + 1u, last)];
    let n2 = ff_nodes[min(first + 2u, last)];
    let n3 = ff_nodes[min(first + 3u, last)];
    var r: FfRayNodes;
    r.c0 = ff_ray_node(n0, p0, dir);
    r.c1 = ff_ray_node(n1, p0, dir);
    r.c2 = ff_ray_node(n2, p0, dir);
    r.c3 = ff_ray_node(n3, p0, dir);
    r.depth = vec4<u32>(u32(n0.q2.w), u32(n1.q2.w), u32(n2.q2.w), u32(n3.q2.w));
    r.count = count;
    return r;
}

// The running sums of `ff_enclose` (see there).
struct FfSums {
    acc1: vec2<f32>,
    acc2: vec2<f32>,
    acc3: vec2<f32>,
    result: vec2<f32>,
}

// One node of `ff_enclose`'s reverse pre-order walk: c = (α, β, γ, weight), depth d.
fn ff_sum_node(s: FfSums, c: vec4<f32>, d: u32, a: f32, b: f32) -> FfSums {
    var o = s;
    var v = ff_range(c.xyz, a, b);
    if (d == 0u) {
        o.result = v + s.acc1;
        return o;
    }
    if (d == 1u) {
        v += s.acc2;
        o.acc2 = vec2<f32>(0.0);
    } else if (d == 2u) {
        v += s.acc3;
        o.acc3 = vec2<f32>(0.0);
    }
    let w = c.w;
    let lo = max(v.x, 0.0);
    let hi = max(v.y, 0.0);
    var r = w * vec2<f32>(lo * lo, hi * hi);
    r = select(r, r.yx, w < 0.0);
    if (d == 1u) {
        o.acc1 += r;
    } else if (d == 2u) {
        o.acc2 += r;
    } else {
        o.acc3 += r;
    }
    return o;
}

// `ff_enclose` from the per-ray node data (FF_SMALL): the same sums in the same order,
// unrolled over the four slots (slots past the object's count change nothing).
fn ff_enclose_ray(rn: FfRayNodes, a: f32, b: f32) -> vec2<f32> {
    var s: FfSums;
    s.acc1 = vec2<f32>(0.0);
    s.acc2 = vec2<f32>(0.0);
    s.acc3 = vec2<f32>(0.0);
    s.result = vec2<f32>(0.0);
    var t = ff_sum_node(s, rn.c3, rn.depth.w, a, b);
    if (rn.count > 3u) {
        s = t;
    }
    t = ff_sum_node(s, rn.c2, rn.depth.z, a, b);
    if (rn.count > 2u) {
        s = t;
    }
    t = ff_sum_node(s, rn.c1, rn.depth.y, a, b);
    if (rn.count > 1u) {
        s = t;
    }
    s = ff_sum_node(s, rn.c0, rn.depth.x, a, b);
    return s.result;
}

// Enclosure of F'(p0 + s d) over s in [a, b] (object `first`..`first + count` nodes): the tree
// in reverse pre-order, each node's exact range plus its children's sum, pushed through the
// monotone w·max(·,0)² into its parent's sum.
fn ff_enclose(first: u32, count: u32, p0: vec3<f32>, dir: vec3<f32>, a: f32, b: f32) -> vec2<f32> {
    var s: FfSums;
    s.acc1 = vec2<f32>(0.0);
    s.acc2 = vec2<f32>(0.0);
    s.acc3 = vec2<f32>(0.0);
    s.result = vec2<f32>(0.0);
    for (var k = count; k > 0u; k--) {
        let n = ff_nodes[first + k - 1u];
        let d = u32(n.q2.w);
        s = ff_sum_node(s, ff_ray_node(n, p0, dir), d, a, b);
        if (d == 0u) {
            break;
        }
    }
    return s.result;
}

// F' and its gradient (continuous: each perturbation adds 2·w·max(Q',0)·∇Q') at an
// object-frame point.
fn ff_value_grad(first: u32, count: u32, p: vec3<f32>) -> vec4<f32> {
    var acc1 = vec4<f32>(0.0);
    var acc2 = vec4<f32>(0.0);
    var acc3 = vec4<f32>(0.0);
    var result = vec4<f32>(0.0);
    for (var k = count; k > 0u; k--) {
        let n = ff_nodes[first + k - 1u];
        let d = u32(n.q2.w);
        var v = vec4<f32>(ff_eval(n, p), ff_grad(n, p));
        if (d == 0u) {
            result = v + acc1;
            break;
        }
        if (d == 1u) {
            v += acc2;
            acc2 = vec4<f32>(0.0);
        } else if (d == 2u) {
            v += acc3;
            acc3 = vec4<f32>(0.0);
        }
        let pos = max(v.x, 0.0);
        let r = n.q2.z * vec4<f32>(pos * pos, 2.0 * pos * v.yzw);
        if (d == 1u) {
            acc1 += r;
        } else if (d == 2u) {
            acc2 += r;
        } else {
            acc3 += r;
        }
    }
    return result;
}

// First root in [0, len] of α s² + β s + γ with γ > 0 (stable formula); -1 when none.
fn ff_plain_root(c: vec3<f32>, len: f32) -> f32 {
    let disc = c.y * c.y - 4.0 * c.x * c.z;
    if (disc < 0.0) {
        return -1.0;
    }
    let q = -0.5 * (c.y + select(-1.0, 1.0, c.y >= 0.0) * sqrt(disc));
    var r1 = BIG;
    var r2 = BIG;
    if (c.x != 0.0) {
        r1 = q / c.x;
    }
    if (q != 0.0) {
        r2 = c.z / q;
    }
    let lo = min(r1, r2);
    let s = select(max(r1, r2), lo, lo >= 0.0);
    if (s >= 0.0 && s <= len) {
        return s;
    }
    return -1.0;
}

// The ray in an object's frame and its span [t0, t1] inside the box (empty when t0 > t1);
// tn holds each slab's entry distance, to tell which face t0 enters through.
struct FfSpan {
    o: vec3<f32>,
    d: vec3<f32>,
    tn: vec3<f32>,
    t0: f32,
    t1: f32,
}

fn ff_span(ob: FfObject, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> FfSpan {
    var sp: FfSpan;
    sp.o = ff_to_local(ob, ro - ob.position.xyz);
    sp.d = ff_to_local(ob, rd);
    // Zero direction components become tiny ones of either sign (same result).
    let ds = select(sp.d, vec3<f32>(1.0e-20), abs(sp.d) < vec3<f32>(1.0e-20));
    let inv = 1.0 / ds;
    let ta = (ob.box_min.xyz - sp.o) * inv;
    let tb = (ob.box_max.xyz - sp.o) * inv;
    sp.tn = min(ta, tb);
    let tf = max(ta, tb);
    sp.t0 = max(max(sp.tn.x, sp.tn.y), max(sp.tn.z, t_min));
    sp.t1 = min(min(tf.x, tf.y), min(tf.z, t_max));
    return sp;
}

// Unit world normal of the box face a ray enters the solid through (its own direction reversed
// when it starts inside the box, t0 = t_min).
fn ff_entry_face(ob: FfObject, span: FfSpan, t_min: f32) -> vec3<f32> {
    let d = span.d;
    var face = -d;
    if (span.t0 > t_min) {
        if (span.t0 == span.tn.x) {
            face = vec3<f32>(-sign(d.x), 0.0, 0.0);
        } else if (span.t0 == span.tn.y) {
            face = vec3<f32>(0.0, -sign(d.y), 0.0);
        } else {
            face = vec3<f32>(0.0, 0.0, -sign(d.z));
        }
    }
    return ff_to_world(ob, face);
}

// First hit of the world ray ro + t rd (rd unit) with object `id`, t in [t_min, t_max]; the
// normal is left to `ff_normal`. `any`: shadow rays, which only need to know whether there is
// a hit (FF_SHADOW_LEVELS, no refinement; the hit's t is then a leaf's start). One loop drives every enclosure evaluation through a single
// call site (Mesa inlines each call and its SIMD rasteriser runs every loop body at least
// once per fragment block): phase 0 evaluates F'(p0); phase 1 is the depth-first search, in
// which interval (k, i) is [i, i + 1] · L / 2^k; phases 2 and 3 evaluate F' at the ends of
// the leaf for the final linear interpolation.
//
// `cone` not 0 (with `any`): the near-miss search of anti-aliasing's centre rays instead, for
// a ray that hits nothing: does it pass within r(t) = cone.x + cone.y t of the solid (a
// pixel's cone from the eye: (0, its reach); the sun rays of a pixel's footprint: (the
// beam's radius, 0))? A point that close has F' <= G r(t) (G = local_0.w, the gradient
// bound), so the search runs over the ray's span through the box widened by r(t) where the
// ray is (`ff_cone_span`), with every enclosure lowered by G r at the interval's far end: the intervals it skips
// hold no such point. G bounds the whole box and can be many times the gradient where the
// ray passes (a hangar's roof against its thin perturbations), so a leaf (L / 2^FF_NEAR_LEVELS)
// still admitted is then tested by the first-order distance estimate F' / |∇F'| at its
// middle, as plain objects are (`ff_near_leaf`); F'(p0) <= 0 at the widened box's entry is
// the solid beside the box. Where r at the span's end passes the margin the bound holds for
// (an object a few pixels wide), every ray through the widened box is a near miss.
fn ff_intersect(id: u32, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32, any: bool, cone: vec2<f32>) -> FfHit {
    var h: FfHit;
    h.hit = false;
    h.t = t_max;
    h.n = vec3<f32>(0.0);
    h.iterations = 0u;
    let ob = ff_objects[id];
    // Every near-miss step hangs on `near`, a constant where the caller passes 0: the
    // shader compiler then drops them from the plain search.
    let near = cone.x != 0.0 || cone.y != 0.0;
    var span: FfSpan;
    var lower = vec2<f32>(0.0);
    if (near) {
        span = ff_cone_span(ob, ro, rd, cone, t_min, t_max);
        lower = ob.local_0.w * cone;
        if (cone.x + cone.y * span.t1 > ob.local_1.w) {
            h.hit = span.t0 <= span.t1;
            return h;
        }
    } else {
        span = ff_span(ob, ro, rd, t_min, t_max);
    }
    let o = span.o;
    let d = span.d;
    let t0 = span.t0;
    let t1 = span.t1;
    if (t0 > t1) {
        return h;
    }
    let first = bitcast<u32>(ob.box_min.w);
    let count = min(bitcast<u32>(ob.box_max.w), FF_MAX_NODES);
    let p0 = o + d * t0;
    let len = t1 - t0;
    var rn: FfRayNodes;
    if (FF_SMALL) {
        rn = ff_ray_nodes(first, count, p0, d);
    }
    // Leaves need be no finer than FF_LEAF of the object's size: the refined root lies in its
    // leaf, so its distance from the surface is below that (a quarter of what the tests allow).
    let fine = u32(clamp(ceil(log2(len / (FF_LEAF * ob.sphere.w))), 1.0, f32(FF_LEVELS)));
    let levels = min(fine, select(select(FF_LEVELS, FF_SHADOW_LEVELS, any), FF_NEAR_LEVELS, near));
    var phase = 0u;
    var k = 0u;
    var i = 0u;
    var fa = 0.0;
    var s = -1.0;
    loop {
        let w = len / f32(1u << k);
        var a = 0.0;
        var b = 0.0;
        if (phase == 1u) {
            a = f32(i) * w;
            b = a + w;
        } else if (phase == 2u) {
            a = f32(i) * w;
            b = a;
        } else if (phase == 3u) {
            a = f32(i) * w + w;
            b = a;
        }
        var raw: f32;
        if (FF_SMALL) {
            raw = ff_enclose_ray(rn, a, b).x;
        } else {
            raw = ff_enclose(first, count, p0, d, a, b).x;
        }
        // Lowered in the near-miss search.
        let e = select(raw, raw - lower.x - lower.y * (t0 + b), near);
        h.iterations += 1u;
        if (phase == 0u) {
            if (raw <= 0.0) {
                // Entering the solid through the box: the face's normal.
                h.n = ff_entry_face(ob, span, t_min);
                s = 0.0;
                break;
            }
            if (count == 1u && !near) {
                s = ff_plain_root(ff_along(ff_nodes[first], p0, d), len);
                break;
            }
            phase = 1u;
            continue;
        }
        if (phase == 2u) {
            fa = e;
            phase = 3u;
            continue;
        }
        if (phase == 3u) {
            s = a - w;
            if (fa > 0.0 && e < 0.0) {
                s += w * fa / (fa - e);
            } else if (fa > 0.0) {
                s = a;
            }
            break;
        }
        if (h.iterations >= FF_MAX_ITERATIONS) {
            break;
        }
        if (e <= 0.0) {
            if (k < levels) {
                k += 1u;
                i *= 2u;
                continue;
            }
            if (!any) {
                phase = 2u;
                continue;
            }
            if (!near || ff_near_leaf(first, count, p0 + d * (a + 0.5 * w), t0 + a + 0.5 * w, cone, 0.5 * w)) {
                s = a;
                break;
            }
        }
        i += 1u;
        loop {
            if ((i & 1u) != 0u || k == 0u) {
                break;
            }
            i >>= 1u;
            k -= 1u;
        }
        if (k == 0u) {
            break;
        }
    }
    if (s < 0.0) {
        return h;
    }
    h.hit = true;
    h.t = t0 + s;
    return h;
}

// A leaf of the near-miss search (`ff_intersect`) that its lowered enclosure admits is a
// near miss when the first-order distance estimate F' / |∇F'| at its middle `p` (ray
// distance `t`) is within the cone's radius there plus half the leaf (`half`), or F' <= 0
// there.
fn ff_near_leaf(first: u32, count: u32, p: vec3<f32>, t: f32, cone: vec2<f32>, half: f32) -> bool {
    let vg = ff_value_grad(first, count, p);
    return vg.x <= (cone.x + cone.y * t + half) * length(vg.yzw);
}

// A plain object (one quadric, no perturbations: `box_max.w` bits = 1) in closed form, with
// its unit world normal: the answer of `ff_intersect`'s phase 0 and stable root without its
// loop, so the passes over plain objects carry no enclosure search at all (on Mesa's SIMD
// rasteriser a fragment block pays for a loop body even when no lane needs it).
fn ff_plain_hit(id: u32, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> FfHit {
    var h: FfHit;
    h.hit = false;
    h.t = t_max;
    h.n = vec3<f32>(0.0);
    h.iterations = 0u;
    let ob = ff_objects[id];
    let span = ff_span(ob, ro, rd, t_min, t_max);
    if (span.t0 > span.t1) {
        return h;
    }
    h.iterations = 1u;
    let node = ff_nodes[bitcast<u32>(ob.box_min.w)];
    let d = span.d;
    let p0 = span.o + d * span.t0;
    let c = ff_along(node, p0, d);
    var s = 0.0;
    if (c.z <= 0.0) {
        // Entering the solid through the box: the face's normal.
        h.n = ff_entry_face(ob, span, t_min);
    } else {
        s = ff_plain_root(c, span.t1 - span.t0);
        if (s < 0.0) {
            return h;
        }
        let g = ff_grad(node, p0 + d * s);
        h.n = select(-rd, ff_to_world(ob, normalize(g)), dot(g, g) > 0.0);
    }
    h.hit = true;
    h.t = span.t0 + s;
    return h;
}

// The ray in an object's frame and its span through the object's box widened by the cone's
// radius where the ray is, r(t) = cone.x + cone.y t (`cone_box_span`; the local frame is a
// rotation, so t and r are metres in it too).
fn ff_cone_span(ob: FfObject, ro: vec3<f32>, rd: vec3<f32>, cone: vec2<f32>, t_min: f32, t_max: f32) -> FfSpan {
    var sp: FfSpan;
    sp.o = ff_to_local(ob, ro - ob.position.xyz);
    sp.d = ff_to_local(ob, rd);
    let t = cone_box_span(sp.o, sp.d, ob.box_min.xyz, ob.box_max.xyz, cone.x, cone.y, t_min, t_max);
    sp.tn = vec3<f32>(t.x);
    sp.t0 = t.x;
    sp.t1 = t.y;
    return sp;
}

// Near miss of a plain object (anti-aliasing): does the ray, which misses the object, pass
// within r(t) = cone.x + cone.y t of it before `t_max` (`cone`: see `ff_intersect`)? Over
// the ray's span through the box widened by r(t) where the ray is (`ff_cone_span`) the
// quadric's lowest value F (the vertex of F(s) = a s² + b s + c, or an end) and its gradient
// there give the distance estimate F / |∇F|, never more than the distance for spheres and
// cylinders ((ρ² - r²) / 2ρ <= ρ - r) and exact for planes; F <= 0 there is the solid beside
// the box itself (a cap's or a slab's edge within reach).
fn ff_plain_near_miss(id: u32, ro: vec3<f32>, rd: vec3<f32>, cone: vec2<f32>, t_max: f32) -> bool {
    let ob = ff_objects[id];
    let span = ff_cone_span(ob, ro, rd, cone, 0.0, t_max);
    if (span.t0 > span.t1) {
        return false;
    }
    let node = ff_nodes[bitcast<u32>(ob.box_min.w)];
    let p0 = span.o + span.d * span.t0;
    let c = ff_along(node, p0, span.d);
    let len = span.t1 - span.t0;
    var s = select(0.0, len, ff_quad(c, len) < c.z);
    if (c.x > 0.0) {
        s = clamp(-c.y / (2.0 * c.x), 0.0, len);
    }
    let f = ff_quad(c, s);
    let g = ff_grad(node, p0 + span.d * s);
    return f <= 0.0 || f < (cone.x + cone.y * (span.t0 + s)) * length(g);
}

// Unit world normal of a hit from `ff_intersect`: the box face it carries, else the
// normalised gradient of F' (continuous across the perturbations' breakpoints).

fn ff_normal(id: u32, h: FfHit, ro: vec3<f32>, rd: vec3<f32>) -> vec3<f32> {
    if (dot(h.n, h.n) > 0.0) {
        return h.n;
    }
    let ob = ff_objects[id];
    let p = ff_to_local(ob, ro + rd * h.t - ob.position.xyz);
    let g = ff_value_grad(bitcast<u32>(ob.box_min.w), min(bitcast<u32>(ob.box_max.w), FF_MAX_NODES), p).yzw;
    if (dot(g, g) > 0.0) {
        return ff_to_world(ob, normalize(g));
    }
    return -rd;
}

// Octahedral unit-vector packing (2 x 16 bits) for the G-buffer.
fn oct_encode(n: vec3<f32>) -> u32 {
    var p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    if (n.z < 0.0) {
        p = (1.0 - abs(p.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), p >= vec2<f32>(0.0));
    }
    return pack2x16unorm(p * 0.5 + 0.5);
}

fn oct_decode(u: u32) -> vec3<f32> {
    let f = unpack2x16unorm(u) * 2.0 - 1.0;
    var n = vec3<f32>(f.x, f.y, 1.0 - abs(f.x) - abs(f.y));
    let t = max(-n.z, 0.0);
    n.x += select(t, -t, n.x >= 0.0);
    n.y += select(t, -t, n.y >= 0.0);
    return normalize(n);
}
