// Shade pass: per pixel, read the cast pass's G-buffer and shade: smooth normals, sun with a
// shadow ray through the same pyramid, sky ambient, elevation/slope ramp or drape, aerial
// perspective, sky. Writes sRGB colour and the capture data (distance bits, steps, patch tests
// and shadow steps, flags).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> heights: array<f32>;
@group(0) @binding(2) var<storage, read> pyramid: array<f32>;
@group(0) @binding(4) var gbuffer: texture_2d<u32>;
@group(0) @binding(5) var<storage, read> drape: array<u32>;
// The sun's transmittance through the density volumes per pixel (volume-sun pass; read with
// VOLUME_SHADOWS).
@group(0) @binding(19) var volume_sun: texture_2d<f32>;

// Feature constants SHADOWS, DRAPE and VOXELS (bool) are prepended per pipeline
// (`gpu::shade::ShadeFeatures`): Mesa's CPU rasterisers run both sides of every branch for the
// whole SIMD block, uniform or not, so a switched-off feature still costs its full price unless
// it is compiled out (a shadow ray never cast cost 18 ms of a 72 ms shade pass, an untaken drape
// lookup 12 ms; 1280x720, GL/llvmpipe).
// SHADOWS: sun shadow rays (terrain, and the free-form and voxel passes' answers).
// DRAPE: colour from the draped RGB image instead of the elevation/slope ramp.
// VOXELS: the scene has voxel models (G-buffer flag 32, voxel shadow flag 64).
// VOLUME_SHADOWS: density volumes shadow the surfaces (the volume-sun pass's target).
// NEAR: anti-aliasing's centre rays: the terrain sun ray searches its footprint's beam for
// rises it misses (flag 64).

struct Out {
    @location(0) colour: vec4<f32>,
    // x: f32 bits of the ray distance (+inf bits for sky), y: traversal steps,
    // z: patch tests (low 16 bits) and shadow-ray steps (high 16 bits), w: flags (1 hit, 2 in shadow, 4 step limit reached, 16 free form, 32 voxel model, 64 a near miss of the NEAR cast; the resolve adds 128).
    @location(1) data: vec4<u32>,
}

fn sky(dl: vec3<f32>) -> vec3<f32> {
    let up = dot(dl, frame.up_local.xyz);
    var c = mix(frame.sky_horizon.xyz, frame.sky_zenith.xyz, pow(clamp(up, 0.0, 1.0), 0.5));
    if (up < 0.0) {
        c = frame.sky_horizon.xyz * mix(1.0, 0.6, clamp(-up * 4.0, 0.0, 1.0));
    }
    let cs = dot(dl, frame.sun_local.xyz);
    c += frame.sun_colour.xyz * (0.35 * pow(max(cs, 0.0), 64.0));
    if (cs > frame.sun_colour.w) {
        c += frame.sun_colour.xyz * 20.0;
    }
    return c;
}

// Terrain at cell (i, j), (u, v) in the cell: the heights of its corners (h00, h10, h01, h11)
// and the smooth shading gradient (metres per grid unit), bilinear between the corners'
// central differences. Twelve loads: the 4x4 samples around the cell less its corners
// (clamped at the grid's edge), each loaded once.
struct CellShape {
    h: vec4<f32>,
    gradient: vec2<f32>,
}

fn cell_shape(i: i32, j: i32, u: f32, v: f32) -> CellShape {
    let wx = i32(frame.grid.x) - 1;
    let wy = i32(frame.grid.y) - 1;
    let xm = u32(max(i - 1, 0));
    let x0 = u32(i);
    let x1 = u32(min(i + 1, wx));
    let x2 = u32(min(i + 2, wx));
    let ym = u32(max(j - 1, 0));
    let y0 = u32(j);
    let y1 = u32(min(j + 1, wy));
    let y2 = u32(min(j + 2, wy));
    // Rows j and j + 1 across columns i - 1 ..= i + 2; columns i and i + 1 at rows j - 1, j + 2.
    var a = vec4<f32>(sample_height(xm, y0), sample_height(x0, y0), sample_height(x1, y0), sample_height(x2, y0));
    var b = vec4<f32>(sample_height(xm, y1), sample_height(x0, y1), sample_height(x1, y1), sample_height(x2, y1));
    var below = vec2<f32>(sample_height(x0, ym), sample_height(x1, ym));
    var above = vec2<f32>(sample_height(x0, y2), sample_height(x1, y2));
    if (PAGED) {
        // A paged tile keeps its voids (NaN: no source data, past the edge of the data): a
        // void beside the cell is extrapolated linearly from the cell's side, which makes the
        // difference across it one-sided.
        a = vec4<f32>(finite_or(a.x, 2.0 * a.y - a.z), a.y, a.z, finite_or(a.w, 2.0 * a.z - a.y));
        b = vec4<f32>(finite_or(b.x, 2.0 * b.y - b.z), b.y, b.z, finite_or(b.w, 2.0 * b.z - b.y));
        below = vec2<f32>(finite_or(below.x, 2.0 * a.y - b.y), finite_or(below.y, 2.0 * a.z - b.z));
        above = vec2<f32>(finite_or(above.x, 2.0 * b.y - a.y), finite_or(above.y, 2.0 * b.z - a.z));
    }
    let dx0 = f32(x1 - xm);
    let dx1 = f32(x2 - x0);
    let dy0 = f32(y1 - ym);
    let dy1 = f32(y2 - y0);
    let g00 = vec2<f32>((a.z - a.x) / dx0, (b.y - below.x) / dy0);
    let g10 = vec2<f32>((a.w - a.y) / dx1, (b.z - below.y) / dy0);
    let g01 = vec2<f32>((b.z - b.x) / dx0, (above.x - a.y) / dy1);
    let g11 = vec2<f32>((b.w - b.y) / dx1, (above.y - a.z) / dy1);
    var c: CellShape;
    c.h = vec4<f32>(a.y, a.z, b.y, b.z);
    c.gradient = mix(mix(g00, g10, u), mix(g01, g11, u), v);
    return c;
}

// `v`, or `f` where v is NaN or infinite (a test on its bits: WGSL may assume floats finite).
fn finite_or(v: f32, f: f32) -> f32 {
    return select(v, f, (bitcast<u32>(v) & 0x7f800000u) == 0x7f800000u);
}

fn local_normal(g: vec2<f32>) -> vec3<f32> {
    return normalize(vec3<f32>(-g.x * frame.spacing.z, -g.y * frame.spacing.w, 1.0));
}

// A drape level: where it starts in `drape`, its width and height.
struct DrapeLevel {
    offset: u32,
    w: i32,
    h: i32,
}

fn drape_level(level: u32) -> DrapeLevel {
    var d: DrapeLevel;
    var w = frame.drape_size.x;
    var h = frame.drape_size.y;
    var offset = 0u;
    for (var l = 0u; l < level; l += 1u) {
        offset += w * h;
        w = (w + 1u) / 2u;
        h = (h + 1u) / 2u;
    }
    d.offset = offset;
    d.w = i32(w);
    d.h = i32(h);
    return d;
}

fn drape_texel(d: DrapeLevel, x: i32, y: i32) -> vec3<f32> {
    let p = drape[d.offset + u32(clamp(y, 0, d.h - 1) * d.w + clamp(x, 0, d.w - 1))];
    return srgb_decode(unpack4x8unorm(p).xyz);
}

// Bilinear colour of drape level `d` at level-0 texel position `q` (texel centres at whole
// numbers): level l's texel j covers level-0 texels j 2^l .. (j + 1) 2^l - 1.
fn drape_bilinear(d: DrapeLevel, level: u32, q0: vec2<f32>) -> vec3<f32> {
    let q = (q0 + 0.5) / f32(1u << level) - 0.5;
    let f = floor(q);
    let a = q - f;
    let i = vec2<i32>(f);
    let c0 = mix(drape_texel(d, i.x, i.y), drape_texel(d, i.x + 1, i.y), a.x);
    let c1 = mix(drape_texel(d, i.x, i.y + 1), drape_texel(d, i.x + 1, i.y + 1), a.x);
    return mix(c0, c1, a.y);
}

// Surface colour at grid point `p` with normal `n`; `footprint`: the pixel's footprint radius
// there (metres), which picks the drape's mip levels (trilinear) with DRAPE_MIPS.
fn albedo(p: vec3<f32>, n: vec3<f32>, footprint: f32) -> vec3<f32> {
    if (DRAPE) {
        let q = frame.drape_map.xy + frame.drape_map.zw * p.xy;
        if (DRAPE_MIPS) {
            let per_metre = max(abs(frame.drape_map.z * frame.spacing.z), abs(frame.drape_map.w * frame.spacing.w));
            let top = f32(max(frame.drape_size.z, 1u) - 1u);
            let lod = clamp(log2(max(2.0 * footprint * per_metre, 1.0)), 0.0, top);
            let l0 = u32(floor(lod));
            let l1 = min(l0 + 1u, u32(top));
            let c0 = drape_bilinear(drape_level(l0), l0, q);
            let c1 = drape_bilinear(drape_level(l1), l1, q);
            return mix(c0, c1, lod - f32(l0));
        }
        return drape_bilinear(drape_level(0u), 0u, q);
    }
    let e = clamp((p.z - frame.heights_range.x) / max(frame.heights_range.y - frame.heights_range.x, 1.0), 0.0, 1.0);
    let slope = 1.0 - n.z;
    let low = vec3<f32>(0.10, 0.17, 0.05);
    let mid = vec3<f32>(0.20, 0.22, 0.10);
    let rock = vec3<f32>(0.28, 0.25, 0.22);
    let snow = vec3<f32>(0.85, 0.88, 0.92);
    var c = mix(low, mid, smoothstep(0.15, 0.55, e));
    c = mix(c, rock, smoothstep(0.12, 0.3, slope + 0.6 * smoothstep(0.55, 0.8, e)));
    c = mix(c, snow, smoothstep(0.78, 0.9, e) * (1.0 - smoothstep(0.25, 0.45, slope)));
    return c;
}

fn world_from_local(v: vec3<f32>) -> vec3<f32> {
    return frame.local_from_world_0.xyz * v.x + frame.local_from_world_1.xyz * v.y + frame.local_from_world_2.xyz * v.z;
}

// Sky light on a surface with local normal n.
fn ambient_light(n: vec3<f32>) -> vec3<f32> {
    let sky_up = dot(n, frame.up_local.xyz);
    return mix(frame.sky_horizon.xyz, frame.sky_zenith.xyz, 0.5 + 0.5 * sky_up) * (frame.sky_zenith.w * (0.6 + 0.4 * sky_up));
}

@fragment
fn fs_shade(@builtin(position) pos: vec4<f32>) -> Out {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer, vec2<i32>(px), 0);
    let dir_w = ray_dir(px);
    let dl = to_local(dir_w);
    var out: Out;
    var c: vec3<f32>;
    // One path per pixel kind, each leaving linear colour in c, and one sRGB encoding at the
    // end (the SIMD rasteriser runs every path, so nothing is repeated per path).
    if ((g.w & 1u) == 0u) {
        // Sky, or (flag 8) no screen under this pixel: black.
        let no_screen = (g.w & 8u) != 0u;
        c = select(sky(dl), vec3<f32>(0.0), no_screen);
        if (CLOUDS) {
            c = select(clouds_over(c, BIG, dir_w, dl), c, no_screen);
        }
        // Flag 64 of the data: the cast's near miss (G-buffer bit 31, anti-aliased frames).
        let near = select(0u, 64u, (g.w >> 31u) != 0u);
        out.data = select(vec4<u32>(INF_BITS, g.z, min((g.w >> 8u) & 0x7fffffu, 0xffffu), (g.w & 0xffu) | near), vec4<u32>(INF_BITS, 0u, 0u, g.w & 0xffu), no_screen);
    } else {
        let s = shade_surface(px, g, dir_w, dl);
        c = s.colour.xyz;
        out.data = s.data;
    }
    out.colour = vec4<f32>(srgb_encode8(c), 1.0);
    return out;
}

// Lit and fogged linear colour (not yet sRGB) and capture data of a surface pixel (terrain,
// free form or voxel model) with G-buffer g.
fn shade_surface(px: vec2<u32>, g: vec4<u32>, dir_w: vec3<f32>, dl: vec3<f32>) -> Out {
    var out: Out;
    var flags = g.w & 0xffu;
    let patches = (g.w >> 8u) & 0x7fffffu;
    let t = bitcast<f32>(g.x);
    let ro = frame.eye.xyz;
    let p = ro + to_grid_dir(dir_w) * t;
    // Curved earth: p is in the eye's tangent frame; its height above MSL (colour ramp,
    // haze altitude) is p.z + drop.
    var p_msl = p;
    if (CURVED) {
        p_msl.z = p.z + drop_at(p.xy);
    }
    let sun = frame.sun_local.xyz;
    let is_object = (flags & 16u) != 0u;
    // Voxel models (flag 32): palette RGBA in y, packed world face normal in z.
    let is_voxel = VOXELS && (flags & 32u) != 0u;
    // Geometric normal (local frame) for the shadow ray and offset of its origin (metres),
    // shading normal.
    var n_geom: vec3<f32>;
    var n: vec3<f32>;
    var off = frame.heights_range.z;
    if (is_object) {
        n_geom = to_local(oct_decode(g.z));
        n = n_geom;
        off = object_shadow_offset(g);
    } else if (is_voxel) {
        n_geom = to_local(normalize(unpack4x8snorm(g.z).xyz));
        n = n_geom;
    } else {
        let i = i32(g.y & 0xffffu);
        let j = i32(g.y >> 16u);
        let u = clamp(p.x - f32(i), 0.0, 1.0);
        let v = clamp(p.y - f32(j), 0.0, 1.0);
        shape_hint(g, i, j);
        let cell = cell_shape(i, j, u, v);
        let h = cell.h;
        let e = h.x - h.y - h.z + h.w;
        // Curved earth: the surface tilts with the drop's gradient.
        var dg = vec2<f32>(0.0);
        if (CURVED) {
            dg = drop_gradient(p.xy);
        }
        n_geom = local_normal(vec2<f32>(h.y - h.x + e * v, h.z - h.x + e * u) - dg);
        n = local_normal(cell.gradient - dg);
    }
    var lit = select(0.0, 1.0, dot(n_geom, sun) > 0.0);
    var shadow_steps = 0u;
    var sun_near = false;
    if (SHADOWS && lit > 0.0) {
        var sr: Ray;
        sr.o = p + vec3<f32>(n_geom.x * off * frame.spacing.z, n_geom.y * off * frame.spacing.w, n_geom.z * off);
        sr.d = frame.sun_grid.xyz;
        if (LOD && !is_object && !is_voxel) {
            // A hit on a coarse patch (footprint LOD) may lie below the finest surface: the
            // shadow ray starts above whichever is higher, or it would meet the ground at once.
            var ground = surface_height(p.x, p.y);
            if (CURVED) {
                ground -= drop_at(p.xy);
            }
            sr.o.z = max(sr.o.z, ground + off);
        }
        // NEAR (anti-aliasing's centre rays): the sun rays of the pixel's footprint form a
        // beam (`cone_beam`: the cone through the pixel's corners laid on the tangent plane;
        // from the neighbours' hit points, `pixel_beam`, it cost this pass 25 ms at 1280x720
        // on lavapipe). Where it is wider than half a cell, the terrain may hold a rise
        // thinner than it (a spike, a knife-edge ridge) whose shadow falls between two
        // pixels' sun rays: the ray then looks for rises it passes within the beam's radius
        // of, from where the beam has left the footprint's own ground (two radii across).
        var near = vec3<f32>(0.0);
        if (NEAR) {
            let beam = cone_beam(dl, n_geom, sun, sqrt(2.0) * t * max(ray_entry(px).w, 0.0));
            let across = max(length(frame.sun_world.xy), 1.0e-3);
            near = select(vec3<f32>(0.0), vec3<f32>(beam, 0.0, 2.0 * beam / across), max(frame.spacing.x, frame.spacing.y) <= 2.0 * beam);
        }
        // From level 0 in the origin's cell: the origin lies on (just above) a surface, so
        // the top-down descent would test cell after cell the ray is known to touch.
        let st = traverse_lod(sr, 0.0, BIG, frame.mode.y, 0u, 0.0, near);
        shadow_steps = st.steps;
        if (st.hit || objects_shadow(px) || (VOXELS && (flags & 64u) != 0u)) {
            lit = 0.0;
            flags |= 2u;
        } else {
            sun_near = NEAR && st.near;
        }
    }
    if (VOLUME_SHADOWS) {
        lit *= textureLoad(volume_sun, vec2<i32>(px), 0).x;
    }
    if (CLOUDS) {
        lit *= cloud_sun(vec3<f32>(p.xy, p_msl.z));
    }
    // Flag 64 (blocked by a voxel model, set by the voxel shadow pass) is folded into 2; it
    // then says a near miss of anti-aliased frames: on terrain and free forms the cast's or a
    // voxel model's sun rays' (G-buffer bit 31; a voxel hit keeps its steps there), on any
    // surface the free-form sun rays' (`objects_shadow_near`) and the terrain's (NEAR).
    flags &= 0xbfu;
    if ((!is_voxel && (g.w >> 31u) != 0u) || objects_shadow_near(px) || sun_near) {
        flags |= 64u;
    }
    var c: vec3<f32>;
    if (is_object) {
        c = object_colour(g, n, dl, lit);
        out.data = vec4<u32>(g.x, g.y >> 16u, min(shadow_steps, 0xffffu) << 16u, flags | (((g.y & 0xffffu) + 1u) << 8u));
    } else if (is_voxel) {
        let base = srgb_decode(unpack4x8unorm(g.y).xyz);
        let diffuse = frame.sun_colour.xyz * (frame.sun_local.w * max(dot(n, sun), 0.0) * lit);
        c = base * (diffuse + ambient_light(n));
        out.data = vec4<u32>(g.x, g.w >> 16u, min(shadow_steps, 0xffffu) << 16u, flags & 0x3fu);
    } else {
        var footprint = 0.0;
        if (DRAPE_MIPS) {
            footprint = t * max(ray_entry(px).w, 0.0);
        }
        let base = albedo(p_msl, n, footprint);
        let diffuse = frame.sun_colour.xyz * (frame.sun_local.w * max(dot(n, sun), 0.0) * lit);
        c = base * (diffuse + ambient_light(n));
        out.data = vec4<u32>(g.x, gbuffer_steps(g.z), min(patches, 0xffffu) | (min(shadow_steps, 0xffffu) << 16u), flags);
    }
    var hazed = aerial_perspective(c, t, p_msl.z, dl);
    if (CLOUDS) {
        hazed = clouds_over(hazed, t, dir_w, dl);
    }
    out.colour = vec4<f32>(hazed, 1.0);
    return out;
}
