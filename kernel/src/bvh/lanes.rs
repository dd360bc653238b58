//! The lanes of the wide BVH's slab test: one SIMD register of child boxes per axis
//! ([`BoxLanes`]).
//!
//! Eight lanes on x86-64: `wide`'s `f32x8` in the baseline build (a pair of 128-bit SSE
//! registers, or one 256-bit register where the whole build targets AVX), and
//! [`crate::simd::Avx8`] (one 256-bit register) where the ray queries are dispatched to AVX2 at
//! run time ([`crate::simd`]). Four lanes (glam's `Vec4`: NEON, wasm SIMD or scalar)
//! everywhere else, soft-float x86-64 (`x86_64-unknown-none`) included, where `wide` would
//! fall back to a scalar maximum that keeps a NaN. The node width follows
//! ([`super::WIDTH`]). Eight lanes on SSE2 cost two instructions per axis and bound where four
//! cost one, but the tree has about half the depth and half the nodes; in the baseline build
//! they rendered the Cornell box 6% and TinyRender's `cbox.obj` 5–9% faster than four lanes,
//! and the cubebox-sized bake 4–6% (AMD EPYC, one thread, medians of 5 alternating runs, two
//! runs), with the same images.
//!
//! Determinism: only subtraction, multiplication, comparisons and the NaN-ignoring `min`/`max`
//! below, lane by lane; each lane computes what [`crate::geometry::Aabb::hit`] computes for one
//! box, so the width changes which boxes a ray visits together, never whether it enters one,
//! and the closest-hit order ([`super::closest`]) makes the hit independent of the visit order.

// The one use of glam's SIMD `Vec4` in the kernel (clippy.toml bans it for its dot products
// and fused multiply-adds): only lane-wise operations that are exact on every backend are used
// here, and scripts/determinism.sh checks SSE2, AVX2, NEON, wasm32 and scalar builds against
// one hash.
#![allow(clippy::disallowed_types)]

/// The slab test's lanes: one box bound per lane and axis, [`super::WIDTH`] of them.
pub trait BoxLanes<const W: usize>: Copy {
    /// The instruction set token these lanes are made with ([`crate::simd::Isa`]).
    type Isa: Copy;
    fn load(isa: Self::Isa, a: &[f32; W]) -> Self;
    fn splat(isa: Self::Isa, x: f32) -> Self;
    fn sub(self, b: Self) -> Self;
    fn mul(self, b: Self) -> Self;
    /// `max(self, b)` where `self` is a number, `b` where it is NaN (`b` is never NaN).
    fn max_ignoring_nan(self, b: Self) -> Self;
    /// `min(self, b)` where `self` is a number, `b` where it is NaN, as `max_ignoring_nan`.
    fn min_ignoring_nan(self, b: Self) -> Self;
    /// Bit `l` set where `t0 <= t1 && t0 < t_max && t1 > 0` in lane `l`.
    fn entered(isa: Self::Isa, t0: Self, t1: Self, t_max: f32) -> u32;
    fn to_array(self) -> [f32; W];
}

/// Eight lanes on x86-64: `wide`'s `f32x8` in the baseline build (one `__m256` where the build
/// targets AVX, a pair of `__m128` with SSE2), [`crate::simd::Avx8`] where the queries are
/// dispatched to AVX at run time. Only raw `maxps`/`minps` (`fast_max`/`fast_min`), `cmpps`
/// with ordered predicates, `subps`, `mulps` and `movmskps` are used.
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
pub const LANES: usize = 8;
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
pub use quad::LANES;

/// The slab lanes of [`crate::simd::Baseline`].
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
pub type BaselineBoxes = wide::f32x8;
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
pub type BaselineBoxes = quad::Lanes;

#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
impl<L: crate::simd::Lanes<8>> BoxLanes<8> for L {
    type Isa = L::Isa;

    #[inline(always)]
    fn load(isa: L::Isa, a: &[f32; LANES]) -> Self {
        L::new(isa, *a)
    }

    #[inline(always)]
    fn splat(isa: L::Isa, x: f32) -> Self {
        L::splat(isa, x)
    }

    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        self - b
    }

    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        self * b
    }

    /// `maxps` and `vmaxps` return their second operand when either is NaN.
    #[inline(always)]
    fn max_ignoring_nan(self, b: Self) -> Self {
        self.fast_max(b)
    }

    #[inline(always)]
    fn min_ignoring_nan(self, b: Self) -> Self {
        self.fast_min(b)
    }

    #[inline(always)]
    fn entered(isa: L::Isa, t0: Self, t1: Self, t_max: f32) -> u32 {
        let inside =
            t0.simd_le(t1) & t0.simd_lt(L::splat(isa, t_max)) & t1.simd_gt(L::splat(isa, 0.0));
        inside.to_bitmask()
    }

    #[inline(always)]
    fn to_array(self) -> [f32; LANES] {
        crate::simd::Lanes::to_array(self)
    }
}

/// Four lanes in glam's `Vec4`, whichever backend glam picks for the target: the lanes of
/// every target but x86-64, compiled there too so that its tests run on every CI machine.
#[cfg_attr(all(target_arch = "x86_64", target_feature = "sse2"), allow(dead_code))]
mod quad {
    use glam::Vec4;

    pub const LANES: usize = 4;

    #[derive(Clone, Copy)]
    pub struct Lanes(Vec4);

    impl super::BoxLanes<LANES> for Lanes {
        type Isa = crate::simd::Baseline;

        #[inline(always)]
        fn load(_: Self::Isa, a: &[f32; LANES]) -> Self {
            Self(Vec4::from_array(*a))
        }

        #[inline(always)]
        fn splat(_: Self::Isa, x: f32) -> Self {
            Self(Vec4::splat(x))
        }

        #[inline(always)]
        fn sub(self, b: Self) -> Self {
            Self(self.0 - b.0)
        }

        #[inline(always)]
        fn mul(self, b: Self) -> Self {
            Self(self.0 * b.0)
        }
        /// `max(self, b)` where `self` is a number, `b` where it is NaN (`b` is never NaN).
        ///
        /// On x86-64, `a.max(b)` is exactly that: SSE's `maxps` returns its second operand when
        /// either is NaN, and glam's other x86-64 backends (scalar, `core::simd`) take the
        /// number, as `f32::max` does. That saves the NaN test and blend per slab (half the slab
        /// test's instructions on SSE2, which has no blend). NEON's and wasm's maxima propagate
        /// NaN, so there the NaN lanes are replaced first. Both give the same number in every
        /// lane, up to the sign of a zero, which no comparison of the slab test tells apart.
        #[inline(always)]
        fn max_ignoring_nan(self, b: Self) -> Self {
            #[cfg(target_arch = "x86_64")]
            {
                Self(self.0.max(b.0))
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                Self(b.0.max(Vec4::select(
                    self.0.is_nan_mask(),
                    Vec4::NEG_INFINITY,
                    self.0,
                )))
            }
        }

        #[inline(always)]
        fn min_ignoring_nan(self, b: Self) -> Self {
            #[cfg(target_arch = "x86_64")]
            {
                Self(self.0.min(b.0))
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                Self(b.0.min(Vec4::select(self.0.is_nan_mask(), Vec4::INFINITY, self.0)))
            }
        }

        #[inline(always)]
        fn entered(_: Self::Isa, t0: Self, t1: Self, t_max: f32) -> u32 {
            let inside = t0.0.cmple(t1.0) & t0.0.cmplt(Vec4::splat(t_max)) & t1.0.cmpgt(Vec4::ZERO);
            inside.bitmask()
        }

        #[inline(always)]
        fn to_array(self) -> [f32; LANES] {
            self.0.to_array()
        }
    }
}

#[cfg(test)]
mod tests {
    /// The tests of one lane implementation (`$lanes`, `$width` wide, made with the token
    /// `$isa`, an `Option`: `None` where this CPU lacks its instructions), run for every
    /// implementation the target compiles.
    macro_rules! lane_tests {
        ($module:ident, $lanes:ty, $width:expr, $isa:expr) => {
            mod $module {
                use super::super::BoxLanes;

                type Lanes = $lanes;
                const LANES: usize = $width;

                fn isa() -> Option<<Lanes as BoxLanes<LANES>>::Isa> {
                    let isa = $isa;
                    if isa.is_none() {
                        std::eprintln!("skipped: this CPU lacks the instructions");
                    }
                    isa
                }

                /// The NaN rule the slab test relies on, on the backend this test is built for.
                #[test]
                fn min_and_max_ignore_a_nan_first_operand() {
                    let Some(isa) = isa() else { return };
                    let values = [
                        f32::NAN,
                        f32::NEG_INFINITY,
                        -1.5,
                        -0.0,
                        0.0,
                        2.0,
                        f32::INFINITY,
                    ];
                    for &a in &values {
                        for &b in &values[1..] {
                            let mut xs = [1.0; LANES];
                            let mut ys = [1.0; LANES];
                            for lane in 0..LANES {
                                // Both operand orders, in alternate lanes.
                                (xs[lane], ys[lane]) =
                                    if lane % 2 == 0 { (a, b) } else { (b, a.max(b)) };
                            }
                            let (va, vb) = (Lanes::load(isa, &xs), Lanes::load(isa, &ys));
                            let max = va.max_ignoring_nan(vb).to_array();
                            let min = va.min_ignoring_nan(vb).to_array();
                            for lane in 0..LANES {
                                let (x, y) = (xs[lane], ys[lane]);
                                let want_max = if x.is_nan() { y } else { x.max(y) };
                                let want_min = if x.is_nan() { y } else { x.min(y) };
                                // Equal as numbers (a zero may come back with either sign).
                                assert!(max[lane] == want_max, "max({x}, {y}) = {}", max[lane]);
                                assert!(min[lane] == want_min, "min({x}, {y}) = {}", min[lane]);
                            }
                        }
                    }
                }

                /// The entry mask against the scalar rule, lane by lane, NaN distances included.
                #[test]
                fn entered_is_the_scalar_rule_per_lane() {
                    let Some(isa) = isa() else { return };
                    let values = [f32::NAN, -1.0, -0.0, 0.0, 0.5, 1.0, 3.0, f32::INFINITY];
                    let mut n = 0usize;
                    for &t_max in &[0.5f32, 1.0, f32::INFINITY] {
                        for &a in &values {
                            for &b in &values {
                                let mut t0 = [0.0; LANES];
                                let mut t1 = [0.0; LANES];
                                for lane in 0..LANES {
                                    t0[lane] = values[(lane + n) % values.len()];
                                    t1[lane] = if lane % 2 == 0 { a } else { b };
                                }
                                n += 1;
                                let (t0v, t1v) = (Lanes::load(isa, &t0), Lanes::load(isa, &t1));
                                let bits = Lanes::entered(isa, t0v, t1v, t_max);
                                for lane in 0..LANES {
                                    let want =
                                        t0[lane] <= t1[lane] && t0[lane] < t_max && t1[lane] > 0.0;
                                    assert_eq!(
                                        bits >> lane & 1 == 1,
                                        want,
                                        "lane {lane}: {t0:?} {t1:?}"
                                    );
                                }
                                assert_eq!(bits >> LANES, 0);
                            }
                        }
                    }
                }

                #[test]
                fn arithmetic_is_lane_wise_ieee() {
                    let Some(isa) = isa() else { return };
                    let a: [f32; LANES] = core::array::from_fn(|l| l as f32 * 1.25 - 3.0);
                    let b: [f32; LANES] = core::array::from_fn(|l| 0.1 + l as f32);
                    let (va, vb) = (Lanes::load(isa, &a), Lanes::load(isa, &b));
                    let d = va.sub(vb).to_array();
                    let p = va.mul(vb).to_array();
                    let s = <Lanes as BoxLanes<LANES>>::splat(isa, 2.5).to_array();
                    for lane in 0..LANES {
                        assert_eq!(d[lane].to_bits(), (a[lane] - b[lane]).to_bits());
                        assert_eq!(p[lane].to_bits(), (a[lane] * b[lane]).to_bits());
                        assert_eq!(s[lane], 2.5);
                    }
                }
            }
        };
    }

    lane_tests!(
        quad,
        super::super::quad::Lanes,
        4,
        Some(crate::simd::Baseline)
    );
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    lane_tests!(eight, wide::f32x8, 8, Some(crate::simd::Baseline));
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    lane_tests!(avx, crate::simd::Avx8, 8, crate::simd::Avx::detect());
}
