// Per-bin object lists written by the binning pass (`ff_bin.wgsl`): two lists (0: primary
// rays, 1: shadow rays) per 16x16-pixel bin, each a header word followed by `frame.objects.w`
// slots. The header holds the number of plain objects (a single quadric, solved in closed
// form; low 16 bits, their indices fill the slots from the front) and of perturbed objects
// (high 16 bits, indices from the back). FF_OVERFLOW: the bin overflowed, test every object.
// Each list is processed by two passes, one per kind, drawn as one quad per bin that has
// objects of the kind (`vs_bins_*`): pixels of other bins never run the pass at all.

@group(0) @binding(8) var<storage, read> ff_bins: array<u32>;

// FF_BIN, FF_OVERFLOW: ff_consts.wgsl (prepended).
const FF_NONE: u32 = 0xffffffffu;

fn ff_bin_base(px: vec2<u32>, list: u32) -> u32 {
    let b = px / FF_BIN;
    let bins = frame.objects.y * frame.objects.z;
    return (list * bins + b.y * frame.objects.y + b.x) * (frame.objects.w + 1u);
}

// Objects of one kind in a list's header (every object when the bin overflowed).
fn ff_kind_count(header: u32, general: bool) -> u32 {
    if (header == FF_OVERFLOW) {
        return frame.objects.x;
    }
    return select(header & 0xffffu, header >> 16u, general);
}

// The objects of one kind (plain or perturbed) that a pixel's list holds.
struct FfList {
    base: u32,
    all: bool,
    general: bool,
    n: u32,
}

fn ff_list(px: vec2<u32>, list: u32, general: bool) -> FfList {
    var l: FfList;
    l.base = ff_bin_base(px, list);
    let header = ff_bins[l.base];
    l.all = header == FF_OVERFLOW;
    l.general = general;
    l.n = ff_kind_count(header, general);
    return l;
}

// Object `j` of the list, or FF_NONE when the bin overflowed and object j is of the other kind.
fn ff_list_id(l: FfList, j: u32) -> u32 {
    if (l.all) {
        let plain = bitcast<u32>(ff_objects[j].box_max.w) == 1u;
        return select(FF_NONE, j, plain != l.general);
    }
    if (l.general) {
        return ff_bins[l.base + frame.objects.w - j];
    }
    return ff_bins[l.base + 1u + j];
}

// Does bin `b` list objects of the kind in `list`?
fn ff_bin_has(b: u32, list: u32, general: bool) -> bool {
    let bins = frame.objects.y * frame.objects.z;
    return ff_kind_count(ff_bins[(list * bins + b) * (frame.objects.w + 1u)], general) > 0u;
}

// Vertex `v` (0..6) of the quad that starts at bin `b` for the pass over `list`'s objects of
// one kind. Runs of such bins along a row are drawn as one quad from the run's first bin;
// every other bin collapses to a point outside the clip volume (the clipper drops it before
// setup). One draw of 6 vertices per bin, not instanced: Mesa's software vertex pipeline
// pays a fixed cost per instance and per triangle (a 16x16 quad each costs ~3x its area
// drawn full-screen), hence the runs.
fn ff_bin_quad(v: u32, b: u32, list: u32, general: bool) -> vec4<f32> {
    return ff_bin_quad_of(v, b, list, general, false);
}

// Does bin `b` get drawn: it lists objects of the kind (`only`: and none of the other kind)?
fn ff_bin_drawn(b: u32, list: u32, general: bool, only: bool) -> bool {
    return ff_bin_has(b, list, general) && !(only && ff_bin_has(b, list, !general));
}

// As `ff_bin_quad`, over the bins `ff_bin_drawn` selects.
fn ff_bin_quad_of(v: u32, b: u32, list: u32, general: bool, only: bool) -> vec4<f32> {
    let none = vec4<f32>(-2.0, -2.0, 0.0, 1.0);
    let per_row = frame.objects.y;
    let x = b % per_row;
    if (b >= per_row * frame.objects.z || !ff_bin_drawn(b, list, general, only)) {
        return none;
    }
    if (x > 0u && ff_bin_drawn(b - 1u, list, general, only)) {
        return none;
    }
    var end = x + 1u;
    while (end < per_row && ff_bin_drawn(b - x + end, list, general, only)) {
        end += 1u;
    }
    // Two triangles: (0,0) (1,0) (1,1) and (0,0) (1,1) (0,1).
    let right = v == 1u || v == 2u || v == 4u;
    let bottom = v == 2u || v == 4u || v == 5u;
    let corner = vec2<u32>(select(x, end, right), b / per_row + select(0u, 1u, bottom)) * FF_BIN;
    let p = vec2<f32>(min(corner, frame.size.xy)) / vec2<f32>(frame.size.xy);
    return vec4<f32>(2.0 * p.x - 1.0, 1.0 - 2.0 * p.y, 0.0, 1.0);
}

@vertex
fn vs_bins_primary_plain(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    return ff_bin_quad(v % 6u, v / 6u, 0u, false);
}

@vertex
fn vs_bins_primary_general(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    return ff_bin_quad(v % 6u, v / 6u, 0u, true);
}

// Bins whose primary list holds plain objects only (and general only): where the other
// kind's cast pass copies its input through (see `gpu::objects::encode_cast`).
@vertex
fn vs_bins_primary_plain_only(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    return ff_bin_quad_of(v % 6u, v / 6u, 0u, false, true);
}

@vertex
fn vs_bins_primary_general_only(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    return ff_bin_quad_of(v % 6u, v / 6u, 0u, true, true);
}

@vertex
fn vs_bins_shadow_plain(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    return ff_bin_quad(v % 6u, v / 6u, 1u, false);
}

@vertex
fn vs_bins_shadow_general(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    return ff_bin_quad(v % 6u, v / 6u, 1u, true);
}

// Distance at which the ray enters object `id`'s box within [t_min, t_max]; BIG if it does not.
fn ff_box_entry(id: u32, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> f32 {
    let sp = ff_span(ff_objects[id], ro, rd, t_min, t_max);
    return select(BIG, sp.t0, sp.t0 <= sp.t1);
}

struct FfNearest {
    hit: FfHit,
    id: u32,
    // Enclosure evaluations over all objects tested.
    iterations: u32,
}

// A walk over the boxes a ray enters, nearest entry first. Each round scans the pixel's list
// with the cheap box test for the next box after (last_t, last_id) in (entry, index) order,
// then runs the full intersection on that one object only: on SIMD software rasterisers,
// which run a loop body at least once per fragment block, the intersection code then costs
// once per box actually entered instead of once per listed object.
struct FfWalk {
    list: FfList,
    last_t: f32,
    last_id: u32,
}

fn ff_walk(px: vec2<u32>, list: u32) -> FfWalk {
    var w: FfWalk;
    w.list = ff_list(px, list, true);
    w.last_t = -1.0;
    w.last_id = 0u;
    return w;
}

// The next box entered within [t_min, t_max] (its index), or FF_NONE when none is left.
fn ff_next(w: ptr<function, FfWalk>, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> u32 {
    var next_t = BIG;
    var next_id = FF_NONE;
    let l = (*w).list;
    for (var j = 0u; j < l.n; j++) {
        let id = ff_list_id(l, j);
        if (id == FF_NONE) {
            continue;
        }
        let te = ff_box_entry(id, ro, rd, t_min, t_max);
        let after = te > (*w).last_t || (te == (*w).last_t && id > (*w).last_id);
        if (te < BIG && after && (te < next_t || (te == next_t && id < next_id))) {
            next_t = te;
            next_id = id;
        }
    }
    (*w).last_t = next_t;
    (*w).last_id = next_id;
    return next_id;
}

// Nearest hit in [t_min, t_max] among the perturbed objects of the pixel's bin `list`.
fn ff_nearest(px: vec2<u32>, list: u32, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> FfNearest {
    var best: FfNearest;
    best.hit.hit = false;
    best.id = 0u;
    best.iterations = 0u;
    var far = t_max;
    var w = ff_walk(px, list);
    var id = ff_next(&w, ro, rd, t_min, far);
    // Exit tests at the end of the body as well: Mesa's SIMD rasterisers leave a loop only at
    // the end of an iteration in which no lane goes on, so a test at the top alone runs one
    // more (masked) intersection per fragment block.
    loop {
        if (id == FF_NONE) {
            break;
        }
        let h = ff_intersect(id, ro, rd, t_min, far, false, vec2<f32>(0.0));
        best.iterations += h.iterations;
        if (h.hit && h.t < far) {
            far = h.t;
            best.hit = h;
            best.id = id;
        }
        id = ff_next(&w, ro, rd, t_min, far);
        if (id == FF_NONE) {
            break;
        }
    }
    return best;
}

// True when a perturbed object of the pixel's shadow list blocks the ray from `ro` along `rd`.
fn ff_blocked(px: vec2<u32>, ro: vec3<f32>, rd: vec3<f32>) -> bool {
    var w = ff_walk(px, 1u);
    var id = ff_next(&w, ro, rd, 0.0, BIG);
    // Exit tests at the top and at the end of the body (see `ff_nearest`).
    loop {
        if (id == FF_NONE) {
            return false;
        }
        if (ff_intersect(id, ro, rd, 0.0, BIG, true, vec2<f32>(0.0)).hit) {
            return true;
        }
        id = ff_next(&w, ro, rd, 0.0, BIG);
        if (id == FF_NONE) {
            return false;
        }
    }
    return false;
}

// Nearest hit in [t_min, t_max] among the plain objects of the pixel's bin `list` (closed
// form, each object once, no walk).
fn ff_plain_nearest(px: vec2<u32>, list: u32, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> FfNearest {
    var best: FfNearest;
    best.hit.hit = false;
    best.id = 0u;
    best.iterations = 0u;
    var far = t_max;
    let l = ff_list(px, list, false);
    // The exit test at the end of the body (see `ff_nearest`); the passes draw only bins
    // whose list holds objects of the kind, the guard covers the rest.
    var j = 0u;
    loop {
        if (l.n == 0u) {
            break;
        }
        let id = ff_list_id(l, j);
        if (id != FF_NONE) {
            let h = ff_plain_hit(id, ro, rd, t_min, far);
            best.iterations += h.iterations;
            if (h.hit && h.t < far) {
                far = h.t;
                best.hit = h;
                best.id = id;
            }
        }
        j += 1u;
        if (j >= l.n) {
            break;
        }
    }
    return best;
}

// Anti-aliasing's centre rays (`frame.stamp.z` = 1): whether the ray, which hit no plain object
// of the pixel's bin `list` (0 primary, 1 shadow), passes within r(t) = cone.x + cone.y t of
// one before `t_max` (`ff_plain_near_miss`), object `skip` left out: a mast or wire thinner
// than the pixel that no centre ray hits, or the thin shadow it casts. Without anti-aliasing
// the loop runs no iteration (a uniform count: the SIMD lanes skip it together).
fn ff_plain_near(px: vec2<u32>, list: u32, ro: vec3<f32>, rd: vec3<f32>, cone: vec2<f32>, t_max: f32, skip: u32) -> bool {
    let l = ff_list(px, list, false);
    let n = select(0u, l.n, frame.stamp.z != 0u);
    var near = false;
    for (var j = 0u; j < n; j += 1u) {
        let id = ff_list_id(l, j);
        if (id != FF_NONE && id != skip && ff_plain_near_miss(id, ro, rd, cone, t_max)) {
            near = true;
        }
    }
    return near;
}

// The same for the perturbed objects of the pixel's list (`ff_intersect`'s near-miss search;
// only the `_near` passes call it).
fn ff_general_near(px: vec2<u32>, list: u32, ro: vec3<f32>, rd: vec3<f32>, cone: vec2<f32>, t_max: f32, skip: u32) -> bool {
    let l = ff_list(px, list, true);
    let n = select(0u, l.n, any(cone != vec2<f32>(0.0)));
    var near = false;
    for (var j = 0u; j < n; j += 1u) {
        let id = ff_list_id(l, j);
        if (id != FF_NONE && id != skip && !near && ff_intersect(id, ro, rd, 0.0, t_max, true, cone).hit) {
            near = true;
        }
    }
    return near;
}

// True when a plain object of the pixel's shadow list blocks the ray from `ro` along `rd`.
fn ff_plain_blocked(px: vec2<u32>, ro: vec3<f32>, rd: vec3<f32>) -> bool {
    let l = ff_list(px, 1u, false);
    // Exit test at the end of the body (see `ff_plain_nearest`).
    var j = 0u;
    loop {
        if (l.n == 0u) {
            return false;
        }
        let id = ff_list_id(l, j);
        if (id != FF_NONE && ff_plain_hit(id, ro, rd, 0.0, BIG).hit) {
            return true;
        }
        j += 1u;
        if (j >= l.n) {
            return false;
        }
    }
    return false;
}
