// Shared by the binning pass (ff_bin.wgsl) and the passes that read its lists (ff_bins.wgsl).

// Bin side in pixels (`gpu::objects::BIN`, which a compile-time assertion ties to this line).
const FF_BIN: u32 = 16u;
// List header of a bin that overflowed: test every object.
const FF_OVERFLOW: u32 = 0xffffffffu;
