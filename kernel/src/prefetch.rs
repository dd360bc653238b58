//! Cache prefetch hints, in this one function (one of the kernel's three audited `unsafe`
//! modules, with the C API and `crate::simd`'s AVX lanes).
//!
//! Why: on scenes larger than the caches, a BVH walk waits on memory for every node and leaf it
//! takes from its stack. Asking for their cache lines when they are pushed lets those loads
//! overlap the work on the nearer children. Measured with `bench/embree` (AMD EPYC, one
//! thread, medians of three alternating runs, portable build): shadow rays 8–13% faster on the
//! 1M-triangle sphere and 4–11% on the 100k one, incoherent rays up to 18% there, the Cornell
//! box's rays 2–7%, camera rays on the spheres 0–2%. The walk is latency-bound on those rays,
//! and safe Rust has no prefetch (a plain load of the line stalls on it, which was tried and
//! dropped). On scenes that fit the caches they neither pay nor cost: without them, the 1k
//! sphere's and the Cornell box's rays measured 0.96–1.01 of the speed with them, every 95%
//! interval containing 1 (`bench/embree/lockstep.py`, 6 epochs of 4 rounds, Intel Xeon,
//! 2026-12-06).
//!
//! Safety: a prefetch is a hint. It reads nothing the program can observe, cannot fault (a
//! prefetch of an unmapped address is dropped), and its address comes from a reference here.
//! `_mm_prefetch` is `unsafe` to call only because it is a `#[target_feature(enable = "sse")]`
//! function, and the implementation below is compiled only where SSE is enabled for the whole
//! build (every x86-64 target but the soft-float `x86_64-unknown-none`).
#![deny(clippy::undocumented_unsafe_blocks)]

/// Asks for the cache lines of `*r` (`prefetcht0`: into every level); nothing where there is no
/// SSE. Changes no result.
#[inline(always)]
pub fn prefetch<T>(r: &T) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse"))]
    {
        use core::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = core::ptr::from_ref(r).cast::<i8>();
        let mut offset = 0;
        while offset < core::mem::size_of::<T>() {
            // SAFETY: `_mm_prefetch` needs SSE, which this build enables (the cfg above); it
            // is a hint that neither reads observable memory nor faults, and the address is
            // inside `*r`.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(offset)) };
            offset += 64;
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse")))]
    let _ = r;
}
