//! The process's C heap over long runs: large blocks are mapped on their own, so that freeing
//! one gives its memory back to the system.
//!
//! glibc serves a request from its heap unless it is at least the *mmap threshold*, and by
//! default that threshold rises to the size of every mapped block freed (up to 32 MiB): once
//! the loaders have freed a few large buffers, blocks of a megabyte come from the heap. Mesa's
//! GL driver (llvmpipe) streams uniforms through upload buffers of 1 MiB, a new one when the
//! last is full. On the heap, a freed one leaves a hole that small allocations split, and the
//! next comes from the top: `relief view --antialias edges` on llvmpipe GL grew by 1 MiB at
//! frames 1,737, 3,418 and 5,098 (160x90). With the threshold held at 1 MiB those buffers are
//! mapped and unmapped; the same run stays flat after its first 1 MiB step (a buffer the driver
//! keeps to the end).
//!
//! Only `relief view` holds it: loops that read whole frames back every frame (`render`,
//! `serve`, `bench soak`) would map and fault in their readbacks each time (`bench soak` at
//! 1280x720 on lavapipe: frame p50 162–165 ms → 179–199 ms), and the window reads none back.
//! Measurements: `docs/robustness.md`.

/// Requests of at least this many bytes are mapped on their own (Mesa's upload buffers are
/// 1 MiB and a few bytes).
pub const MAPPED_FROM: usize = 1 << 20;

/// Free memory at the top of the heap above this is given back (twice [`MAPPED_FROM`], what
/// glibc's own rule would set for it, kept from rising further).
pub const TRIM_ABOVE: usize = 2 << 20;

/// Holds glibc's mmap and trim thresholds at [`MAPPED_FROM`] and [`TRIM_ABOVE`] for the rest
/// of the process. Returns whether the C library took them (false off glibc, where there is
/// nothing to do).
pub fn map_large_blocks() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only sets two of the allocator's parameters; it is thread-safe.
        let (mmap, trim) = unsafe {
            (
                libc::mallopt(libc::M_MMAP_THRESHOLD, MAPPED_FROM as libc::c_int),
                libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_ABOVE as libc::c_int),
            )
        };
        let taken = mmap == 1 && trim == 1;
        if !taken {
            log::warn!("glibc refused its mmap/trim thresholds ({mmap}, {trim})");
        }
        taken
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

#[cfg(all(test, target_os = "linux", target_env = "gnu"))]
mod tests {
    use super::*;

    /// Whether glibc mapped the block at `p` on its own: bit 1 (`IS_MMAPPED`) of the size word
    /// just before the block.
    fn is_mapped(p: *mut libc::c_void) -> bool {
        // The pointer through `black_box` and a volatile read: the compiler knows malloc and
        // may otherwise drop or fold a block read outside its bounds.
        let p = std::hint::black_box(p) as *const usize;
        // SAFETY: `p` is a live block from glibc's malloc, preceded by its chunk header.
        unsafe { std::ptr::read_volatile(p.sub(1)) & 2 != 0 }
    }

    /// A driver's 1 MiB block after a larger one was freed: glibc's default would take it
    /// from the heap (the threshold risen to the freed block's size); held, it is mapped.
    #[test]
    fn a_megabyte_block_is_mapped_after_a_larger_one_was_freed() {
        assert!(map_large_blocks());
        // SAFETY: plain malloc/free pairs on blocks this test owns.
        unsafe {
            // Freed, a mapped 24 MiB block would raise glibc's default threshold past 1 MiB.
            let big = std::hint::black_box(libc::malloc(24 << 20));
            assert!(!big.is_null());
            libc::free(big);
            let mut aligned = std::ptr::null_mut();
            assert_eq!(
                libc::posix_memalign(&mut aligned, 4096, MAPPED_FROM + 48),
                0
            );
            assert!(is_mapped(aligned), "a 1 MiB block came from the heap");
            libc::free(aligned);
            let small = libc::malloc(MAPPED_FROM / 2);
            assert!(!is_mapped(small), "a half-megabyte block was mapped");
            libc::free(small);
        }
    }
}
