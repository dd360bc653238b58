//! The instruction sets the ray queries run with, chosen at run time: the kernel's lane code
//! (the wide BVH's slab test, the triangle groups' watertight test, and the surface
//! interactions of a batched path tracer's eight samples, `crate::surface_lanes`) written once
//! over [`Lanes`] and compiled three times on x86-64, for the build's baseline, for AVX2 (the
//! x86-64-v3 level) and for AVX-512 (x86-64-v4).
//!
//! Why: a build for the x86-64 baseline (the shipped binary, `cargo build --release`) knows
//! only SSE2, where eight lanes are two registers; a build for `x86-64-v3` or `native` runs
//! the same queries in one 256-bit register but does not start on a CPU without AVX. Embree
//! compiles its kernels per ISA and picks one at run time; so does this module, for the two
//! queries every integrator spends most of its time in ([`crate::scene::SceneView::intersect`]
//! and [`crate::scene::SceneView::occluded`]). The tree and its triangle groups are eight wide
//! on x86-64 whichever instructions walk them, so a scene built once is walked by either.
//!
//! Determinism: every lane operation here is the correctly rounded IEEE operation, or a
//! comparison, `maxps`/`minps` (which return their second operand when either is NaN, in SSE
//! and AVX alike), a bit mask or a bitwise operation: [`Avx8`] computes what `wide::f32x8`
//! computes, lane for lane, and the hits and images do not depend on which one ran (tests
//! below, `crate::geometry::triangle_group`'s and the determinism script's).
//!
//! Measured (`ember-bvh-embree` on `bench/embree`'s Cornell box and 1M-triangle sphere, Intel
//! Xeon with AVX-512, one thread pinned, medians of 3 alternating runs, 2026-12-06): the
//! dispatched queries ran 19–33% faster on the Cornell box and 15–36% on the sphere than the
//! shipped build before (SSE2 lanes, groups of four), about as fast as a `-C target-cpu=native`
//! build; the baseline lanes alone (`EMBER_SIMD=baseline`, groups of eight in SSE2 pairs) ran
//! between 10% slower and 26% faster than before, inside this instance's drift (an earlier
//! sitting had the sphere's camera rays 23% slower), so CPUs without AVX2 lose little to the one
//! tree. Renders: the Cornell box (MIS) 5% faster, TinyRender's `cbox.obj` unchanged within
//! noise, the `cbox_gi_high` bake 10% faster; the images and the bake are the same bits.
//!
//! AVX-512 ([`Avx512`], x86-64-v4, where the CPU has AVX-512 F, DQ, BW and VL): the same lane
//! code compiled a third time, for x86-64-v4, and a leaf that goes on into a second triangle
//! group tested in one 512-bit register ([`Avx16`], sixteen lanes: [`Isa::intersect_pair`]),
//! the way Mitsuba's LLVM variant runs sixteen lanes on such a CPU. The project's Cornell box
//! is one leaf of 32 triangles, so each ray takes two pair tests instead of four group tests.
//! Measured (AMD EPYC Zen 5, `ember render --integrator mis --threads 1`, 256², 64 spp, 3
//! alternating runs, 2026-12-07): 3.43–3.56 s against 3.58–3.72 s with eight lanes, and
//! 3.47–3.54 against 3.77–3.86 in a second sitting; TinyRender's `cbox.obj` (leaves of up to
//! eight triangles, few of them across two groups) level, 4.49–4.71 s either way; the same
//! EXRs. `EMBER_SIMD=avx2` ([`limit_to_avx2`]) keeps to eight lanes, for CPUs that lower their
//! clock for 512-bit instructions and for comparisons at an AVX2 machine's width.
//!
//! Why `core::arch` in this module rather than a crate: `wide` (the baseline lanes) picks its
//! instructions when it is compiled, so its `f32x8` inside an AVX function is still two SSE
//! registers (its `maxps`, `cmpps` and `movmskps` are SSE intrinsics that LLVM does not widen).
//! `pulp` and `multiversion` dispatch at run time only with their `std` feature, through
//! `std::is_x86_feature_detected!`, which a `no_std` kernel (and its C API) cannot use. What
//! is left is about twenty intrinsics and the CPUID test, here, behind a token.
//!
//! Safety: an [`Avx`] value exists only where the CPU and the operating system have AVX
//! ([`Avx::detect`]: CPUID and XCR0, as `std`'s `is_x86_feature_detected!` checks, which a
//! `no_std` kernel cannot call), an [`Avx512`] only where they have AVX-512 too
//! ([`Avx512::detect`]), an [`Avx8`] only where either was given, and an [`Avx16`] only where an
//! [`Avx512`] was. So the AVX
//! intrinsics behind `Avx8`'s operations, `unsafe` to call from code not compiled for AVX,
//! only ever run on a CPU that has them. [`Avx::run`] compiles its closure for AVX so that
//! those intrinsics inline into it; without that they would be calls.
#![deny(clippy::undocumented_unsafe_blocks)]

use crate::geometry::{PairHits, TriangleGroup, WatertightRay, GROUP_WIDTH};
use core::ops::{Add, AddAssign, BitAnd, BitAndAssign, BitOr, Div, Mul, MulAssign, Not, Sub};

/// SIMD lanes of `W` floats for the watertight test: IEEE arithmetic lane by lane, comparisons
/// giving all-ones or all-zero lanes, and their bit masks. A lane type is made only through
/// its instruction set's token ([`Lanes::Isa`]).
pub trait Lanes<const W: usize>:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + AddAssign
    + MulAssign
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + BitAndAssign
    + Not<Output = Self>
{
    /// The instruction set these lanes need, as a token that proves the CPU has it.
    type Isa: Copy;
    fn splat(isa: Self::Isa, x: f32) -> Self;
    fn new(isa: Self::Isa, a: [f32; W]) -> Self;
    fn to_array(self) -> [f32; W];
    /// Bit `l` set where lane `l`'s sign bit is (where a comparison held).
    fn to_bitmask(self) -> u32;
    fn simd_eq(self, b: Self) -> Self;
    /// True where either lane is NaN (unordered), as `cmpneqps`.
    fn simd_ne(self, b: Self) -> Self;
    fn simd_lt(self, b: Self) -> Self;
    fn simd_le(self, b: Self) -> Self;
    fn simd_gt(self, b: Self) -> Self;
    fn simd_ge(self, b: Self) -> Self;
    fn abs(self) -> Self;
    /// `maxps`: `self` where `self > b`, else `b` (so `b` where either is NaN).
    fn fast_max(self, b: Self) -> Self;
    /// `minps`: `self` where `self < b`, else `b`.
    fn fast_min(self, b: Self) -> Self;
    /// True where the lane is neither infinite nor NaN.
    fn is_finite(self) -> Self;
    /// The correctly rounded square root (as `libm::sqrtf`, `sqrtps`).
    fn sqrt(self) -> Self;
    /// The sign bit flipped (as the scalar `-x`, also for zeros and NaN).
    fn neg(self) -> Self;
    /// `a` in the lanes where `mask` (a comparison's result) holds, else `b`: bits moved, not
    /// rounded.
    #[inline(always)]
    fn select(mask: Self, a: Self, b: Self) -> Self {
        (mask & a) | (!mask & b)
    }
    /// Lane `l` is lane `index[l] % W` of `self`: a gather from a table of at most `W` entries
    /// held in lanes, bits moved, not rounded (one `vpermps` with AVX2).
    #[inline(always)]
    fn permute(self, isa: Self::Isa, index: &[u32; W]) -> Self {
        let a = self.to_array();
        Self::new(isa, core::array::from_fn(|l| a[index[l] as usize % W]))
    }
    /// `self` moved one ulp the way `o` points: [`crate::math::next_float_up`] where `o > 0`,
    /// [`crate::math::next_float_down`] where `o < 0`, `self` elsewhere (how a ray origin is
    /// rounded away from its surface); lane by lane in the scalar functions unless the lanes
    /// have integer steps.
    #[inline(always)]
    fn round_away(self, isa: Self::Isa, o: Self) -> Self {
        let (v, o) = (self.to_array(), o.to_array());
        let mut r = v;
        for l in 0..W {
            if o[l] > 0.0 {
                r[l] = crate::math::next_float_up(v[l]);
            } else if o[l] < 0.0 {
                r[l] = crate::math::next_float_down(v[l]);
            }
        }
        Self::new(isa, r)
    }
}

/// An instruction set the ray queries can run with, as a value: holding one is the proof that
/// the CPU has it. Names the lanes of the slab test and of the triangle groups.
pub trait Isa: Copy {
    type Boxes: crate::bvh::BoxLanes<{ crate::bvh::WIDTH }, Isa = Self>;
    type Group: Lanes<GROUP_WIDTH, Isa = Self>;
    /// Eight lanes on every target, for the samples a batched path tracer shades together
    /// ([`crate::integrator::BATCH`]).
    type Eight: Lanes<8, Isa = Self>;

    /// Whether these instructions multiply 64-bit integers in SIMD lanes (AVX-512DQ's
    /// `vpmullq`): the ZSobol sampler's digit permutations are then hashed for every lane at
    /// once, branch-free, rather than once per run of lanes with equal digits (which is faster
    /// where each 64-bit multiply in lanes takes three 32-bit ones). The numbers are the same.
    const LANE_HASHES: bool = false;

    /// `f(self)` in a function of its own, compiled for these instructions and called
    /// directly: how lane code already running at this level makes a per-ray query without
    /// finding the level again (`SceneView::intersect_with`). Out of line on purpose: the
    /// query inlined into the batched path tracer made its AVX-512 renders 2.5% slower
    /// (AMD EPYC Zen 5, 2026-12-07), and a dispatch at every call cost its AVX2 renders 3%.
    fn call<R>(self, f: impl FnOnce(Self) -> R) -> R;

    /// Whether [`Self::intersect_pair`] tests pairs of groups (AVX-512). Where it does not,
    /// a leaf's test does not ask whether it goes on into a second group: the bounds check of
    /// the second group's index kept the compiler from dropping that branch. Without it, 0.55%
    /// fewer instructions and 1.1% fewer mispredictions in cachegrind's model (AVX2, camera
    /// rays of `bench/embree`'s 1k-triangle sphere); time level in lockstep (0.99–1.07, every
    /// interval including 1; AMD EPYC Zen 3, 2026-12-08). Tried there and not kept: AVX2 pairs
    /// in two registers (a `Two<Avx8>` of sixteen lanes, the AVX-512 pair test's code), so
    /// that the project's Cornell box, one leaf of four groups, runs two tests of two with one
    /// early exit each: 18% fewer mispredictions but 4.7% more instructions in cachegrind's
    /// model (96², 16 spp), renders 0.99–1.09 of this code's time (medians of 16 pairs) and
    /// `bench/embree`'s Cornell box rays 0.92–1.02 in lockstep.
    const PAIRS: bool = false;

    /// The watertight test of two consecutive triangle groups at once, in lanes twice a
    /// group's width (AVX-512's sixteen), lane `GROUP_WIDTH + i` being lane `i` of the second
    /// group, written to `hits`; false (and `hits` untouched) where this instruction set has
    /// no such lanes ([`Self::PAIRS`]), and the groups are tested one after the other. The
    /// hits are the same bits either way, lane for lane.
    #[inline(always)]
    fn intersect_pair(
        self,
        _pair: [&TriangleGroup; 2],
        _ray: &WatertightRay,
        _t_max: f32,
        _lanes: u32,
        _hits: &mut PairHits,
    ) -> bool {
        false
    }
}

/// The instructions every build of this target has: SSE2 on x86-64, NEON on aarch64, and so
/// on (`wide`'s and glam's choice for the target).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Baseline;

impl Isa for Baseline {
    type Boxes = crate::bvh::BaselineBoxes;
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    type Group = wide::f32x8;
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    type Group = wide::f32x4;
    type Eight = wide::f32x8;

    #[inline(always)]
    fn call<R>(self, f: impl FnOnce(Self) -> R) -> R {
        #[inline(never)]
        fn out_of_line<R>(isa: Baseline, f: impl FnOnce(Baseline) -> R) -> R {
            f(isa)
        }
        out_of_line(self, f)
    }
}

/// `wide`'s lanes, as this target's build compiles them.
macro_rules! wide_lanes {
    ($lanes:ident, $width:literal) => {
        impl Lanes<$width> for wide::$lanes {
            type Isa = Baseline;
            #[inline(always)]
            fn splat(_: Baseline, x: f32) -> Self {
                Self::splat(x)
            }
            #[inline(always)]
            fn new(_: Baseline, a: [f32; $width]) -> Self {
                Self::new(a)
            }
            #[inline(always)]
            fn to_array(self) -> [f32; $width] {
                Self::to_array(self)
            }
            #[inline(always)]
            fn to_bitmask(self) -> u32 {
                Self::to_bitmask(self)
            }
            #[inline(always)]
            fn simd_eq(self, b: Self) -> Self {
                Self::simd_eq(self, b)
            }
            #[inline(always)]
            fn simd_ne(self, b: Self) -> Self {
                Self::simd_ne(self, b)
            }
            #[inline(always)]
            fn simd_lt(self, b: Self) -> Self {
                Self::simd_lt(self, b)
            }
            #[inline(always)]
            fn simd_le(self, b: Self) -> Self {
                Self::simd_le(self, b)
            }
            #[inline(always)]
            fn simd_gt(self, b: Self) -> Self {
                Self::simd_gt(self, b)
            }
            #[inline(always)]
            fn simd_ge(self, b: Self) -> Self {
                Self::simd_ge(self, b)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                Self::abs(self)
            }
            #[inline(always)]
            fn fast_max(self, b: Self) -> Self {
                Self::fast_max(self, b)
            }
            #[inline(always)]
            fn fast_min(self, b: Self) -> Self {
                Self::fast_min(self, b)
            }
            #[inline(always)]
            fn is_finite(self) -> Self {
                Self::is_finite(self)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                // `sqrtps` and NEON's `vsqrtq_f32` round correctly; elsewhere `wide` may fall
                // back to a software root, so each lane takes the scalar code's.
                if cfg!(any(
                    all(target_arch = "x86_64", target_feature = "sse2"),
                    target_arch = "aarch64"
                )) {
                    Self::sqrt(self)
                } else {
                    Self::new(Self::to_array(self).map(crate::math::sqrt))
                }
            }
            #[inline(always)]
            fn neg(self) -> Self {
                -self
            }
        }
    };
}

wide_lanes!(f32x4, 4);
wide_lanes!(f32x8, 8);

#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
pub use avx::{limit_to_avx2, limit_to_baseline, Avx, Avx16, Avx512, Avx8, AvxToken};

/// AVX: its token, its detection, and eight lanes in one `__m256`.
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[allow(unsafe_code)]
mod avx {
    use super::{Isa, Lanes, PairHits, TriangleGroup, WatertightRay};
    use core::arch::x86_64::{
        __m256, _mm256_add_epi32, _mm256_add_ps, _mm256_and_ps, _mm256_and_si256,
        _mm256_castps_si256, _mm256_castsi256_ps, _mm256_cmp_ps, _mm256_div_ps, _mm256_loadu_ps,
        _mm256_loadu_si256, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps,
        _mm256_or_ps, _mm256_permutevar8x32_ps, _mm256_set1_epi32, _mm256_set1_ps, _mm256_sqrt_ps,
        _mm256_storeu_ps, _mm256_sub_epi32, _mm256_sub_ps, _mm256_xor_ps, _CMP_EQ_OQ, _CMP_GE_OQ,
        _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_UQ,
    };
    use core::arch::x86_64::{
        __m512, _mm512_add_ps, _mm512_and_ps, _mm512_castps256_ps512, _mm512_castps_si512,
        _mm512_castsi512_ps, _mm512_cmp_ps_mask, _mm512_div_ps, _mm512_insertf32x8,
        _mm512_loadu_ps, _mm512_max_ps, _mm512_min_ps, _mm512_movepi32_mask, _mm512_movm_epi32,
        _mm512_mul_ps, _mm512_or_ps, _mm512_set1_epi32, _mm512_set1_ps, _mm512_sqrt_ps,
        _mm512_storeu_ps, _mm512_sub_ps, _mm512_xor_ps,
    };
    use core::marker::PhantomData;
    use core::ops::{Add, AddAssign, BitAnd, BitAndAssign, BitOr, Div, Mul, MulAssign, Not, Sub};
    use core::sync::atomic::{AtomicU8, Ordering};

    /// Proof that this CPU and its operating system support AVX2 and the rest of the x86-64-v3
    /// level (FMA, BMI1/2, LZCNT, POPCNT), which the AVX code is compiled for ([`Avx::detect`]).
    /// (The code never fuses a multiply and an add: Rust does not contract without being
    /// asked, and FMA only lets LLVM use VEX forms and `tzcnt` freely.)
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct Avx(());

    impl Isa for Avx {
        type Boxes = Avx8;
        type Group = Avx8;
        type Eight = Avx8;

        #[inline(always)]
        fn call<R>(self, f: impl FnOnce(Self) -> R) -> R {
            #[target_feature(enable = "avx,avx2,bmi1,bmi2,fma,lzcnt,popcnt")]
            #[inline(never)]
            fn out_of_line<R>(avx: Avx, f: impl FnOnce(Avx) -> R) -> R {
                f(avx)
            }
            // SAFETY: `self` exists only where `detect` found AVX on this CPU.
            unsafe { out_of_line(self, f) }
        }
    }

    const UNKNOWN: u8 = 0;
    const BASELINE: u8 = 1;
    const AVX: u8 = 2;
    const AVX512: u8 = 3;

    /// What this CPU has, found once for the process (`UNKNOWN` until then).
    static FOUND: AtomicU8 = AtomicU8::new(UNKNOWN);
    /// The most the queries may use ([`limit_to_baseline`], [`limit_to_avx2`]).
    static CAP: AtomicU8 = AtomicU8::new(AVX512);

    /// Makes the ray queries use the baseline instructions from now on, whatever the CPU has:
    /// for benchmarks of the dispatch and for tests of the baseline code on AVX machines.
    /// Results do not change.
    pub fn limit_to_baseline() {
        CAP.store(BASELINE, Ordering::Relaxed);
    }

    /// Makes the queries use at most AVX2 (eight lanes) from now on, on a CPU with AVX-512 too:
    /// for measuring what the sixteen lanes buy, for comparisons at an AVX2 machine's width,
    /// and for CPUs that lower their clock for 512-bit instructions. Results do not change.
    pub fn limit_to_avx2() {
        CAP.fetch_min(AVX, Ordering::Relaxed);
    }

    /// The level the queries run at: what the CPU has, capped. CPUID once, then two loads.
    #[inline]
    fn level() -> u8 {
        let mut found = FOUND.load(Ordering::Relaxed);
        if found == UNKNOWN {
            found = cpu_level();
            FOUND.store(found, Ordering::Relaxed);
        }
        found.min(CAP.load(Ordering::Relaxed))
    }

    impl Avx {
        /// The token, if this CPU has AVX2 (x86-64-v3) and the operating system saves its
        /// registers (and [`limit_to_baseline`] was not called).
        #[inline]
        #[must_use]
        pub fn detect() -> Option<Self> {
            (level() >= AVX).then_some(Self(()))
        }

        /// `f(self)` in a function compiled for x86-64-v3, so that the lane code `f` inlines
        /// runs in 256-bit registers. `f` should be an `#[inline(always)]` closure, and what it
        /// calls inlined too: a lane operation left out of line in baseline code is a call per
        /// instruction (twenty times slower, measured).
        #[inline(always)]
        pub fn run<R>(self, f: impl FnOnce(Self) -> R) -> R {
            #[target_feature(enable = "avx,avx2,bmi1,bmi2,fma,lzcnt,popcnt")]
            #[inline]
            fn with_avx<R>(avx: Avx, f: impl FnOnce(Avx) -> R) -> R {
                f(avx)
            }
            // SAFETY: `self` exists only where `detect` found AVX on this CPU.
            unsafe { with_avx(self, f) }
        }
    }

    /// Proof that this CPU and its operating system support x86-64-v4: AVX-512 F, DQ, BW and
    /// VL over x86-64-v3 ([`Avx512::detect`]). The AVX-512 functions run the same lane code
    /// as [`Avx`]'s in eight lanes ([`Avx8<Avx512>`]), and test two triangle groups at once
    /// in sixteen ([`Avx16`], [`Isa::intersect_pair`]).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct Avx512(());

    impl Isa for Avx512 {
        type Boxes = Avx8<Avx512>;
        type Group = Avx8<Avx512>;
        type Eight = Avx8<Avx512>;
        const LANE_HASHES: bool = true;
        const PAIRS: bool = true;

        #[inline(always)]
        fn call<R>(self, f: impl FnOnce(Self) -> R) -> R {
            #[target_feature(
                enable = "avx,avx2,bmi1,bmi2,fma,lzcnt,popcnt,avx512f,avx512dq,avx512bw,avx512vl"
            )]
            #[inline(never)]
            fn out_of_line<R>(avx: Avx512, f: impl FnOnce(Avx512) -> R) -> R {
                f(avx)
            }
            // SAFETY: `self` exists only where `detect` found x86-64-v4 on this CPU.
            unsafe { out_of_line(self, f) }
        }

        #[inline(always)]
        fn intersect_pair(
            self,
            pair: [&TriangleGroup; 2],
            ray: &WatertightRay,
            t_max: f32,
            lanes: u32,
            hits: &mut PairHits,
        ) -> bool {
            TriangleGroup::intersect_pair(self, pair, ray, t_max, lanes, hits);
            true
        }
    }

    impl Avx512 {
        /// The token, if this CPU has x86-64-v4 and the operating system saves its 512-bit
        /// and mask registers (and neither [`limit_to_baseline`] nor [`limit_to_avx2`] was
        /// called).
        #[inline]
        #[must_use]
        pub fn detect() -> Option<Self> {
            (level() >= AVX512).then_some(Self(()))
        }

        /// `f(self)` in a function compiled for x86-64-v4, as [`Avx::run`] for x86-64-v3.
        #[inline(always)]
        pub fn run<R>(self, f: impl FnOnce(Self) -> R) -> R {
            #[target_feature(
                enable = "avx,avx2,bmi1,bmi2,fma,lzcnt,popcnt,avx512f,avx512dq,avx512bw,avx512vl"
            )]
            #[inline]
            fn with_avx512<R>(avx: Avx512, f: impl FnOnce(Avx512) -> R) -> R {
                f(avx)
            }
            // SAFETY: `self` exists only where `detect` found x86-64-v4 on this CPU.
            unsafe { with_avx512(self, f) }
        }
    }

    /// The highest level this CPU and OS support. x86-64-v3: CPUID.1:ECX has FMA (bit 12),
    /// POPCNT (23), AVX (28) and OSXSAVE (27, the OS enabled XSAVE), CPUID.7:EBX has BMI1 (3),
    /// AVX2 (5) and BMI2 (8), CPUID.80000001h:ECX has LZCNT (5); and XCR0 bits 1 and 2 say the
    /// OS saves the SSE and AVX registers on a context switch (Intel SDM 14.3). x86-64-v4 adds
    /// CPUID.7:EBX AVX512F (16), AVX512DQ (17), AVX512BW (30) and AVX512VL (31), and XCR0 bits
    /// 5–7 (the mask registers and all 512 bits of the 32 vector registers; SDM 15.2).
    fn cpu_level() -> u8 {
        use core::arch::x86_64::{__cpuid, __cpuid_count, _xgetbv};
        #[target_feature(enable = "xsave")]
        fn xcr0() -> u64 {
            // SAFETY: reading XCR0 needs XSAVE enabled by the OS, which the caller checked.
            unsafe { _xgetbv(0) }
        }
        let bits = |word: u32, bits: &[u32]| bits.iter().all(|&b| word >> b & 1 == 1);
        // SAFETY: every x86-64 CPU has CPUID; leaves past the maxima it reports (leaf 0 and
        // 80000000h) are not read.
        #[allow(unused_unsafe)]
        let (max, max_ext) = unsafe { (__cpuid(0).eax, __cpuid(0x8000_0000).eax) };
        if max < 7 || max_ext < 0x8000_0001 {
            return BASELINE;
        }
        // SAFETY: as above, leaves 1 and 7 and 80000001h exist (checked).
        #[allow(unused_unsafe)]
        let (leaf1, leaf7, ext1) =
            unsafe { (__cpuid(1), __cpuid_count(7, 0), __cpuid(0x8000_0001)) };
        if !(bits(leaf1.ecx, &[12, 23, 27, 28])
            && bits(leaf7.ebx, &[3, 5, 8])
            && bits(ext1.ecx, &[5]))
        {
            return BASELINE;
        }
        // SAFETY: OSXSAVE (checked above) means XGETBV is available and XCR0 readable.
        let xcr0 = unsafe { xcr0() };
        if xcr0 & 0b110 != 0b110 {
            return BASELINE;
        }
        if bits(leaf7.ebx, &[16, 17, 30, 31]) && xcr0 & 0b1110_0000 == 0b1110_0000 {
            AVX512
        } else {
            AVX
        }
    }

    /// The six comparisons of [`Lanes`] through the type's `cmp::<PREDICATE>` (ordered
    /// predicates, and unordered not-equal as `cmpneqps`).
    macro_rules! comparisons {
        () => {
            #[inline(always)]
            fn simd_eq(self, b: Self) -> Self {
                self.cmp::<_CMP_EQ_OQ>(b)
            }

            #[inline(always)]
            fn simd_ne(self, b: Self) -> Self {
                self.cmp::<_CMP_NEQ_UQ>(b)
            }

            #[inline(always)]
            fn simd_lt(self, b: Self) -> Self {
                self.cmp::<_CMP_LT_OQ>(b)
            }

            #[inline(always)]
            fn simd_le(self, b: Self) -> Self {
                self.cmp::<_CMP_LE_OQ>(b)
            }

            #[inline(always)]
            fn simd_gt(self, b: Self) -> Self {
                self.cmp::<_CMP_GT_OQ>(b)
            }

            #[inline(always)]
            fn simd_ge(self, b: Self) -> Self {
                self.cmp::<_CMP_GE_OQ>(b)
            }
        };
    }

    /// `+=`, `*=` and `&=` through `+`, `*` and `&`.
    macro_rules! assignments {
        (impl<$($p:ident: $bound:ident)?> for $t:ty) => {
            impl<$($p: $bound)?> AddAssign for $t {
                #[inline(always)]
                fn add_assign(&mut self, b: Self) {
                    *self = *self + b;
                }
            }

            impl<$($p: $bound)?> MulAssign for $t {
                #[inline(always)]
                fn mul_assign(&mut self, b: Self) {
                    *self = *self * b;
                }
            }

            impl<$($p: $bound)?> BitAndAssign for $t {
                #[inline(always)]
                fn bitand_assign(&mut self, b: Self) {
                    *self = *self & b;
                }
            }
        };
    }

    /// Eight lanes in one AVX register; made only with a token `T` that proves AVX2: [`Avx`],
    /// or [`Avx512`] (the same instructions, compiled into the AVX-512 functions).
    #[derive(Clone, Copy, Debug)]
    pub struct Avx8<T = Avx>(__m256, PhantomData<T>);

    /// A token that proves AVX2 (and the rest of x86-64-v3): [`Avx`] or [`Avx512`].
    pub trait AvxToken: Isa {}
    impl AvxToken for Avx {}
    impl AvxToken for Avx512 {}

    impl<T> Avx8<T> {
        #[inline(always)]
        const fn wrap(v: __m256) -> Self {
            Self(v, PhantomData)
        }
    }

    /// `Avx8(op(a, b))` for an AVX intrinsic `op`.
    macro_rules! binary {
        ($trait:ident, $method:ident, $op:ident) => {
            impl<T: AvxToken> $trait for Avx8<T> {
                type Output = Self;
                #[inline(always)]
                fn $method(self, b: Self) -> Self {
                    // SAFETY: an `Avx8` exists only on a CPU with AVX (module docs).
                    Self::wrap(unsafe { $op(self.0, b.0) })
                }
            }
        };
    }

    binary!(Add, add, _mm256_add_ps);
    binary!(Sub, sub, _mm256_sub_ps);
    binary!(Mul, mul, _mm256_mul_ps);
    binary!(Div, div, _mm256_div_ps);
    binary!(BitAnd, bitand, _mm256_and_ps);
    binary!(BitOr, bitor, _mm256_or_ps);

    assignments!(impl<T: AvxToken> for Avx8<T>);

    impl<T: AvxToken> Not for Avx8<T> {
        type Output = Self;
        #[inline(always)]
        fn not(self) -> Self {
            // SAFETY: as for every `Avx8` operation.
            Self::wrap(unsafe { _mm256_xor_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(-1))) })
        }
    }

    impl<T: AvxToken> Avx8<T> {
        #[inline(always)]
        fn cmp<const PREDICATE: i32>(self, b: Self) -> Self {
            // SAFETY: as for every `Avx8` operation.
            Self::wrap(unsafe { _mm256_cmp_ps::<PREDICATE>(self.0, b.0) })
        }
    }

    impl<T: AvxToken> Lanes<8> for Avx8<T> {
        type Isa = T;

        #[inline(always)]
        fn splat(_: T, x: f32) -> Self {
            // SAFETY: the `Avx` token proves this CPU has AVX.
            Self::wrap(unsafe { _mm256_set1_ps(x) })
        }

        #[inline(always)]
        fn new(_: T, a: [f32; 8]) -> Self {
            // SAFETY: the `Avx` token proves AVX; the load reads the 32 bytes of `a`.
            Self::wrap(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }

        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut a = [0.0; 8];
            // SAFETY: as for every `Avx8` operation; the store writes the 32 bytes of `a`.
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }

        #[inline(always)]
        fn to_bitmask(self) -> u32 {
            // SAFETY: as for every `Avx8` operation.
            unsafe { _mm256_movemask_ps(self.0) as u32 }
        }

        #[inline(always)]
        fn permute(self, _: T, index: &[u32; 8]) -> Self {
            // SAFETY: an `Avx8` exists only where x86-64-v3 (AVX2) was found (module docs);
            // the load reads the 32 bytes of `index`. `vpermps` uses the low three bits of
            // each index: `index[l] % 8`.
            Self::wrap(unsafe {
                let index = _mm256_loadu_si256(index.as_ptr().cast());
                _mm256_permutevar8x32_ps(self.0, index)
            })
        }

        comparisons!();

        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: as for every `Avx8` operation.
            Self::wrap(unsafe {
                _mm256_and_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX)))
            })
        }

        #[inline(always)]
        fn fast_max(self, b: Self) -> Self {
            // SAFETY: as for every `Avx8` operation.
            Self::wrap(unsafe { _mm256_max_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn fast_min(self, b: Self) -> Self {
            // SAFETY: as for every `Avx8` operation.
            Self::wrap(unsafe { _mm256_min_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn is_finite(self) -> Self {
            // |x| < ∞ is false for both infinities and NaN (ordered comparison).
            // SAFETY: as for every `Avx8` operation.
            let inf = Self::wrap(unsafe { _mm256_set1_ps(f32::INFINITY) });
            self.abs().simd_lt(inf)
        }

        #[inline(always)]
        fn sqrt(self) -> Self {
            // SAFETY: as for every `Avx8` operation.
            Self::wrap(unsafe { _mm256_sqrt_ps(self.0) })
        }

        #[inline(always)]
        fn neg(self) -> Self {
            // SAFETY: as for every `Avx8` operation.
            Self::wrap(unsafe { _mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)) })
        }

        /// The scalar steps as integer steps of the bits: up, `-0` becomes `+0` (`v + 0`)
        /// and the bits go one up from a non-negative value, one down from a negative one;
        /// down, `+0` becomes `-0` (`-(-v + 0)`) and the bits go one down from a positive
        /// value, one up from a non-positive one; NaN and the infinity in the direction of the
        /// step stay.
        #[inline(always)]
        fn round_away(self, isa: T, o: Self) -> Self {
            let zero = Self::splat(isa, 0.0);
            let step = |v: Self, toward_one: Self| -> Self {
                // SAFETY: as for every `Avx8` operation (AVX2 integer adds: `Avx` is x86-64-v3).
                unsafe {
                    let one = _mm256_set1_epi32(1);
                    // +1 where `toward_one`, −1 elsewhere.
                    let delta = _mm256_sub_epi32(
                        _mm256_and_si256(_mm256_castps_si256(toward_one.0), _mm256_set1_epi32(2)),
                        one,
                    );
                    Self::wrap(_mm256_castsi256_ps(_mm256_add_epi32(
                        _mm256_castps_si256(v.0),
                        delta,
                    )))
                }
            };
            let stays = |v: Self, inf: f32| v.simd_ne(v) | v.simd_eq(Self::splat(isa, inf));
            let up_from = self + zero;
            let up = step(up_from, up_from.simd_ge(zero));
            let up = Self::select(stays(self, f32::INFINITY), self, up);
            let down_from = (self.neg() + zero).neg();
            let down = step(down_from, !down_from.simd_gt(zero));
            let down = Self::select(stays(self, f32::NEG_INFINITY), self, down);
            Self::select(
                o.simd_gt(zero),
                up,
                Self::select(o.simd_lt(zero), down, self),
            )
        }
    }

    /// Sixteen lanes in one AVX-512 register; made only with an [`Avx512`] token. Comparisons
    /// give all-ones lanes as [`Avx8`]'s do (from the mask register, `vpmovm2d`), so the lane
    /// code is the same; LLVM keeps the masks in mask registers where it can.
    #[derive(Clone, Copy, Debug)]
    pub struct Avx16(__m512);

    /// `Avx16(op(a, b))` for an AVX-512 intrinsic `op`.
    macro_rules! binary16 {
        ($trait:ident, $method:ident, $op:ident) => {
            impl $trait for Avx16 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, b: Self) -> Self {
                    // SAFETY: an `Avx16` exists only on a CPU with AVX-512 (module docs).
                    Self(unsafe { $op(self.0, b.0) })
                }
            }
        };
    }

    binary16!(Add, add, _mm512_add_ps);
    binary16!(Sub, sub, _mm512_sub_ps);
    binary16!(Mul, mul, _mm512_mul_ps);
    binary16!(Div, div, _mm512_div_ps);
    binary16!(BitAnd, bitand, _mm512_and_ps);
    binary16!(BitOr, bitor, _mm512_or_ps);

    assignments!(impl<> for Avx16);

    impl Not for Avx16 {
        type Output = Self;
        #[inline(always)]
        fn not(self) -> Self {
            // SAFETY: as for every `Avx16` operation.
            Self(unsafe { _mm512_xor_ps(self.0, _mm512_castsi512_ps(_mm512_set1_epi32(-1))) })
        }
    }

    impl Avx16 {
        #[inline(always)]
        fn cmp<const PREDICATE: i32>(self, b: Self) -> Self {
            // SAFETY: as for every `Avx16` operation.
            Self(unsafe {
                _mm512_castsi512_ps(_mm512_movm_epi32(_mm512_cmp_ps_mask::<PREDICATE>(
                    self.0, b.0,
                )))
            })
        }

        /// Lanes `0..8` from `low`, `8..16` from `high`.
        #[inline(always)]
        #[must_use]
        pub fn from_halves(_: Avx512, low: &[f32; 8], high: &[f32; 8]) -> Self {
            // SAFETY: the `Avx512` token proves AVX-512 F and DQ; each load reads the 32 bytes
            // of its array.
            Self(unsafe {
                _mm512_insertf32x8::<1>(
                    _mm512_castps256_ps512(_mm256_loadu_ps(low.as_ptr())),
                    _mm256_loadu_ps(high.as_ptr()),
                )
            })
        }
    }

    impl Lanes<16> for Avx16 {
        type Isa = Avx512;

        #[inline(always)]
        fn splat(_: Avx512, x: f32) -> Self {
            // SAFETY: the `Avx512` token proves this CPU has AVX-512.
            Self(unsafe { _mm512_set1_ps(x) })
        }

        #[inline(always)]
        fn new(_: Avx512, a: [f32; 16]) -> Self {
            // SAFETY: the token proves AVX-512; the load reads the 64 bytes of `a`.
            Self(unsafe { _mm512_loadu_ps(a.as_ptr()) })
        }

        #[inline(always)]
        fn to_array(self) -> [f32; 16] {
            let mut a = [0.0; 16];
            // SAFETY: as for every `Avx16` operation; the store writes the 64 bytes of `a`.
            unsafe { _mm512_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }

        #[inline(always)]
        fn to_bitmask(self) -> u32 {
            // SAFETY: as for every `Avx16` operation.
            u32::from(unsafe { _mm512_movepi32_mask(_mm512_castps_si512(self.0)) })
        }

        comparisons!();

        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: as for every `Avx16` operation.
            Self(unsafe { _mm512_and_ps(self.0, _mm512_castsi512_ps(_mm512_set1_epi32(i32::MAX))) })
        }

        /// `vmaxps` returns its second operand when either is NaN, as `maxps` does.
        #[inline(always)]
        fn fast_max(self, b: Self) -> Self {
            // SAFETY: as for every `Avx16` operation.
            Self(unsafe { _mm512_max_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn fast_min(self, b: Self) -> Self {
            // SAFETY: as for every `Avx16` operation.
            Self(unsafe { _mm512_min_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn is_finite(self) -> Self {
            // |x| < ∞ is false for both infinities and NaN (ordered comparison).
            // SAFETY: as for every `Avx16` operation.
            let inf = Self(unsafe { _mm512_set1_ps(f32::INFINITY) });
            self.abs().simd_lt(inf)
        }

        #[inline(always)]
        fn sqrt(self) -> Self {
            // SAFETY: as for every `Avx16` operation.
            Self(unsafe { _mm512_sqrt_ps(self.0) })
        }

        #[inline(always)]
        fn neg(self) -> Self {
            // SAFETY: as for every `Avx16` operation.
            Self(unsafe { _mm512_xor_ps(self.0, _mm512_set1_ps(-0.0)) })
        }
    }
}

#[cfg(all(test, target_arch = "x86_64", target_feature = "sse2"))]
mod tests {
    use super::{Avx, Avx8, Baseline, Lanes};
    use wide::f32x8;

    /// Numbers that tell rounding, signs and NaN handling apart.
    const VALUES: [f32; 16] = [
        f32::NAN,
        f32::NEG_INFINITY,
        -3.5,
        -1.0e-40,
        -0.0,
        0.0,
        1.0e-40,
        f32::MIN_POSITIVE,
        0.1,
        1.0 / 3.0,
        1.0,
        2.0,
        7.0e12,
        f32::MAX,
        f32::INFINITY,
        -f32::MAX,
    ];

    /// Every operation of [`Avx8`] gives the bits `wide::f32x8` (the baseline lanes) gives,
    /// on every pair of `VALUES` in every lane position.
    #[test]
    fn avx_lanes_compute_what_the_baseline_lanes_compute() {
        let Some(avx) = Avx::detect() else {
            std::eprintln!("skipped: this CPU lacks AVX2");
            return;
        };
        let n = VALUES.len();
        for shift in 0..n {
            for stride in [1, 3, 5, 7] {
                let a: [f32; 8] = core::array::from_fn(|l| VALUES[(l + shift) % n]);
                let b: [f32; 8] = core::array::from_fn(|l| VALUES[(l * stride + shift / 2) % n]);
                let (x, y) = (Avx8::new(avx, a), Avx8::new(avx, b));
                let (p, q) = (f32x8::new(a), f32x8::new(b));
                let bits = |v: [f32; 8]| v.map(f32::to_bits);
                let same = |what: &str, avx: Avx8, base: f32x8| {
                    assert_eq!(
                        bits(Lanes::to_array(avx)),
                        bits(Lanes::to_array(base)),
                        "{what} of {a:?} and {b:?}"
                    );
                    assert_eq!(
                        Lanes::to_bitmask(avx),
                        Lanes::to_bitmask(base),
                        "{what} mask"
                    );
                };
                same("+", x + y, p + q);
                same("-", x - y, p - q);
                same("*", x * y, p * q);
                same("/", x / y, p / q);
                same("&", x & y, p & q);
                same("|", x | y, p | q);
                same("!", !x, !p);
                same("==", x.simd_eq(y), Lanes::simd_eq(p, q));
                same("!=", x.simd_ne(y), Lanes::simd_ne(p, q));
                same("<", x.simd_lt(y), Lanes::simd_lt(p, q));
                same("<=", x.simd_le(y), Lanes::simd_le(p, q));
                same(">", x.simd_gt(y), Lanes::simd_gt(p, q));
                same(">=", x.simd_ge(y), Lanes::simd_ge(p, q));
                same("abs", x.abs(), Lanes::abs(p));
                same("max", x.fast_max(y), Lanes::fast_max(p, q));
                same("min", x.fast_min(y), Lanes::fast_min(p, q));
                same("is_finite", x.is_finite(), Lanes::is_finite(p));
                same("sqrt", x.sqrt(), Lanes::sqrt(p));
                same("neg", x.neg(), Lanes::neg(p));
                same(
                    "select",
                    Avx8::select(x.simd_lt(y), x, y),
                    Lanes::select(Lanes::simd_lt(p, q), p, q),
                );
                same(
                    "round_away",
                    x.round_away(avx, y),
                    p.round_away(Baseline, q),
                );
                // Indices past the lanes wrap (`vpermps` reads the low three bits).
                let index: [u32; 8] = core::array::from_fn(|l| (l * stride + shift) as u32 % 19);
                same(
                    "permute",
                    x.permute(avx, &index),
                    p.permute(Baseline, &index),
                );
                assert_eq!(
                    bits(x.permute(avx, &index).to_array()),
                    index.map(|i| a[i as usize % 8].to_bits()),
                    "permute {a:?} by {index:?}"
                );
                // The lanes give the scalar code's bits.
                let scalar = a.map(crate::math::sqrt).map(f32::to_bits);
                assert_eq!(bits(x.sqrt().to_array()), scalar, "sqrt of {a:?}");
                assert_eq!(
                    bits(x.neg().to_array()),
                    a.map(|v| (-v).to_bits()),
                    "-{a:?}"
                );
                same(
                    "splat",
                    Avx8::splat(avx, a[0]),
                    <f32x8 as Lanes<8>>::splat(Baseline, a[0]),
                );
            }
        }
    }

    /// Every operation of [`Avx16`] gives, in each half, the bits `wide::f32x8` gives.
    #[test]
    fn avx512_lanes_compute_what_the_baseline_lanes_compute() {
        use super::{Avx16, Avx512};
        let Some(avx) = Avx512::detect() else {
            std::eprintln!("skipped: this CPU lacks AVX-512");
            return;
        };
        let n = VALUES.len();
        let halves = |v: [f32; 16]| -> [[f32; 8]; 2] {
            [
                core::array::from_fn(|l| v[l]),
                core::array::from_fn(|l| v[8 + l]),
            ]
        };
        for shift in 0..n {
            for stride in [1, 3, 5, 7] {
                let a: [f32; 16] = core::array::from_fn(|l| VALUES[(l + shift) % n]);
                let b: [f32; 16] = core::array::from_fn(|l| VALUES[(l * stride + shift / 2) % n]);
                let (x, y) = (Avx16::new(avx, a), Avx16::new(avx, b));
                let [a0, a1] = halves(a);
                let [b0, b1] = halves(b);
                let (p, q) = (
                    [f32x8::new(a0), f32x8::new(a1)],
                    [f32x8::new(b0), f32x8::new(b1)],
                );
                let bits = |v: [f32; 8]| v.map(f32::to_bits);
                let same = |what: &str, wide: Avx16, base: [f32x8; 2]| {
                    let w = halves(Lanes::to_array(wide));
                    for h in 0..2 {
                        assert_eq!(
                            bits(w[h]),
                            bits(Lanes::to_array(base[h])),
                            "{what} of {a:?} and {b:?}, half {h}"
                        );
                    }
                    assert_eq!(
                        Lanes::to_bitmask(wide),
                        Lanes::to_bitmask(base[0]) | Lanes::to_bitmask(base[1]) << 8,
                        "{what} mask"
                    );
                };
                let both = |f: &dyn Fn(f32x8, f32x8) -> f32x8| [f(p[0], q[0]), f(p[1], q[1])];
                same("+", x + y, both(&|p, q| p + q));
                same("-", x - y, both(&|p, q| p - q));
                same("*", x * y, both(&|p, q| p * q));
                same("/", x / y, both(&|p, q| p / q));
                same("&", x & y, both(&|p, q| p & q));
                same("|", x | y, both(&|p, q| p | q));
                same("!", !x, both(&|p, _| !p));
                same("==", x.simd_eq(y), both(&|p, q| Lanes::simd_eq(p, q)));
                same("!=", x.simd_ne(y), both(&|p, q| Lanes::simd_ne(p, q)));
                same("<", x.simd_lt(y), both(&|p, q| Lanes::simd_lt(p, q)));
                same("<=", x.simd_le(y), both(&|p, q| Lanes::simd_le(p, q)));
                same(">", x.simd_gt(y), both(&|p, q| Lanes::simd_gt(p, q)));
                same(">=", x.simd_ge(y), both(&|p, q| Lanes::simd_ge(p, q)));
                same("abs", x.abs(), both(&|p, _| Lanes::abs(p)));
                same("max", x.fast_max(y), both(&|p, q| Lanes::fast_max(p, q)));
                same("min", x.fast_min(y), both(&|p, q| Lanes::fast_min(p, q)));
                same(
                    "is_finite",
                    x.is_finite(),
                    both(&|p, _| Lanes::is_finite(p)),
                );
                same("sqrt", x.sqrt(), both(&|p, _| Lanes::sqrt(p)));
                same("neg", x.neg(), both(&|p, _| Lanes::neg(p)));
                same(
                    "select",
                    Avx16::select(x.simd_lt(y), x, y),
                    both(&|p, q| Lanes::select(Lanes::simd_lt(p, q), p, q)),
                );
                same(
                    "splat",
                    Avx16::splat(avx, a[0]),
                    [<f32x8 as Lanes<8>>::splat(Baseline, a[0]); 2],
                );
                same(
                    "from_halves",
                    Avx16::from_halves(avx, &a0, &a1),
                    [f32x8::new(a0), f32x8::new(a1)],
                );
            }
        }
    }

    /// A build that assumes x86-64-v3 runs only where detection finds it.
    #[test]
    fn detection_agrees_with_the_build() {
        if cfg!(all(
            target_feature = "avx2",
            target_feature = "fma",
            target_feature = "bmi2"
        )) {
            assert!(Avx::detect().is_some());
        }
        if cfg!(all(
            target_feature = "avx512f",
            target_feature = "avx512dq",
            target_feature = "avx512bw",
            target_feature = "avx512vl"
        )) {
            assert!(super::Avx512::detect().is_some());
        }
        // AVX-512 comes with AVX2 (x86-64-v4 contains v3).
        if super::Avx512::detect().is_some() {
            assert!(Avx::detect().is_some());
        }
    }
}
