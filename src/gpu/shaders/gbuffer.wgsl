// G-buffer written by the cast pass and read by the shade pass (Rgba32Uint):
// x = f32 bits of the ray distance in metres (+inf bits for sky), y = hit cell (x | y << 16),
// z = traversal steps, w = flags (bit 0 hit, bit 2 step limit reached, bit 3 pixel shows no
// screen) | patch tests << 8.

const INF_BITS: u32 = 0x7f800000u;

// w: flags (1 hit, 4 step limit), patch tests (bits 8..30), bit 31 NEAR's near miss.
fn encode_gbuffer(tr: Trace) -> vec4<u32> {
    let flags = select(0u, 4u, tr.exhausted) | (min(tr.patches, 0x7fffffu) << 8u) | select(0u, 0x80000000u, tr.near);
    if (!tr.hit) {
        return vec4<u32>(INF_BITS, 0u, tr.steps, flags);
    }
    return vec4<u32>(bitcast<u32>(tr.t), u32(tr.cell.x) | (u32(tr.cell.y) << 16u), tr.steps, flags | 1u);
}

// G-buffer of a pixel that shows no screen (distortion tables): black.
fn no_screen_gbuffer() -> vec4<u32> {
    return vec4<u32>(INF_BITS, 0u, 0u, 8u);
}
