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

// Does the ray miss object `id`'s bounding sphere within t_max? (overflow path only)
fn ff_sphere_miss(id: u32, ro: vec3<f32>, rd: vec3<f32>, t_max: f32) -> bool {
    let sp = ff_objects[id].sphere;
    let v = sp.xyz - ro;
    let tc = dot(v, rd);
    let d2 = dot(v, v) - tc * tc;
    return d2 > sp.w * sp.w || tc + sp.w < 0.0 || tc - sp.w > t_max;
}

struct FfNearest {
    hit: FfHit,
    id: u32,
    // Enclosure evaluations over all objects tested.
    iterations: u32,
}

// Nearest free-form hit in (t_min, t_max) among the objects of the pixel's bin `list`.
fn ff_nearest(px: vec2<u32>, list: u32, ro: vec3<f32>, rd: vec3<f32>, t_min: f32, t_max: f32) -> FfNearest {
    var best: FfNearest;
    best.hit.hit = false;
    best.id = 0u;
    best.iterations = 0u;
    var far = t_max;
    let base = ff_bin_base(px, list);
    let count = ff_bins[base];
    let all = count > frame.objects.w;
    let n = select(count, frame.objects.x, all);
    for (var j = 0u; j < n; j++) {
        var id = j;
        if (!all) {
            id = ff_bins[base + 1u + j];
        } else if (ff_sphere_miss(id, ro, rd, far)) {
            continue;
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
    let base = ff_bin_base(px, 1u);
    let count = ff_bins[base];
    let all = count > frame.objects.w;
    let n = select(count, frame.objects.x, all);
    for (var j = 0u; j < n; j++) {
        var id = j;
        if (!all) {
            id = ff_bins[base + 1u + j];
        } else if (ff_sphere_miss(id, ro, rd, BIG)) {
            continue;
        }
        if (ff_intersect(id, ro, rd, 0.0, BIG).hit) {
            return true;
        }
    }
    return false;
}
