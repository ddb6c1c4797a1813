// Per-bin object lists written by the binning pass (`ff_bin.wgsl`): two lists (0: primary
// rays, 1: shadow rays), each a count followed by up to `frame.objects.w` object indices per
// 16x16-pixel bin. A count above the capacity means "overflowed": test every object.

@group(0) @binding(8) var<storage, read> ff_bins: array<u32>;

const FF_BIN: u32 = 16u;

fn ff_bin_base(px: vec2<u32>, list: u32) -> u32 {
    let b = px / FF_BIN;
    let bins = frame.objects.y * frame.objects.z;
    return (list * bins + b.y * frame.objects.y + b.x) * (frame.objects.w + 1u);
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
    base: u32,
    all: bool,
    n: u32,
    last_t: f32,
    last_id: u32,
}

fn ff_walk(px: vec2<u32>, list: u32) -> FfWalk {
    var w: FfWalk;
    w.base = ff_bin_base(px, list);
    let count = ff_bins[w.base];
    w.all = count > frame.objects.w;
    w.n = select(count, frame.objects.x, w.all);
    w.last_t = -1.0;
    w.last_id = 0u;
    return w;
}

// The next box entered within [t_min, t_max] (its index), or 0xffffffff when none is left.
fn ff_next(w: ptr<function, FfWalk>, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> u32 {
    var next_t = BIG;
    var next_id = 0xffffffffu;
    for (var j = 0u; j < (*w).n; j++) {
        var id = j;
        if (!(*w).all) {
            id = ff_bins[(*w).base + 1u + j];
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

// Nearest free-form hit in [t_min, t_max] among the objects of the pixel's bin `list`.
fn ff_nearest(px: vec2<u32>, list: u32, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> FfNearest {
    var best: FfNearest;
    best.hit.hit = false;
    best.id = 0u;
    best.iterations = 0u;
    var far = t_max;
    var w = ff_walk(px, list);
    loop {
        let id = ff_next(&w, ro, rd, t_min, far);
        if (id == 0xffffffffu) {
            break;
        }
        let h = ff_intersect(id, ro, rd, t_min, far);
        best.iterations += h.iterations;
        if (h.hit && h.t < far) {
            far = h.t;
            best.hit = h;
            best.id = id;
        }
    }
    return best;
}

// True when a free form of the pixel's shadow list blocks the ray from `ro` along `rd`.
fn ff_blocked(px: vec2<u32>, ro: vec3<f32>, rd: vec3<f32>) -> bool {
    var w = ff_walk(px, 1u);
    loop {
        let id = ff_next(&w, ro, rd, 0.0, BIG);
        if (id == 0xffffffffu) {
            return false;
        }
        if (ff_intersect(id, ro, rd, 0.0, BIG).hit) {
            return true;
        }
    }
    return false;
}

// Stencil mark passes (no colour output): keep only pixels whose bin has objects in the list,
// so the free-form passes behind a stencil test skip the rest of the screen before shading.
@fragment
fn fs_mark_primary(@builtin(position) pos: vec4<f32>) {
    if (ff_bins[ff_bin_base(vec2<u32>(pos.xy), 0u)] == 0u) {
        discard;
    }
}

@fragment
fn fs_mark_shadow(@builtin(position) pos: vec4<f32>) {
    if (ff_bins[ff_bin_base(vec2<u32>(pos.xy), 1u)] == 0u) {
        discard;
    }
}
