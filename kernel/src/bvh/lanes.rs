//! The lanes of the wide BVH's slab test: one SIMD register of child boxes per axis.
//!
//! Eight lanes on x86-64, in `wide`'s `f32x8`: one 256-bit register where the build targets
//! AVX (`-C target-cpu=x86-64-v3` or `native` on a machine with AVX2), a pair of 128-bit SSE
//! registers in the baseline build. Four lanes (glam's `Vec4`: NEON, wasm SIMD or scalar)
//! everywhere else, soft-float x86-64 (`x86_64-unknown-none`) included, where `wide` would
//! fall back to a scalar maximum that keeps a NaN. The node width follows ([`super::WIDTH`]). Eight lanes on SSE2 cost two
//! instructions per axis and bound where four cost one, but the tree has about half the depth
//! and half the nodes; in the baseline build they rendered the Cornell box 6% and
//! TinyRender's `cbox.obj` 5–9% faster than four lanes, and the cubebox-sized bake 4–6% (AMD
//! EPYC, one thread, medians of 5 alternating runs, two runs), with the same images.
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

#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
pub use eight::{Lanes, LANES};
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
pub use quad::{Lanes, LANES};

/// Eight lanes in one `__m256` (AVX builds) or two `__m128` (SSE2), through `wide`'s safe
/// wrappers (the kernel's `unsafe` is confined to its C API and `crate::prefetch`). Only its
/// raw `maxps`/`minps` (`fast_max`/`fast_min`), `cmpps` with ordered predicates, `subps`,
/// `mulps` and `movmskps` are used, in their VEX forms with AVX.
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
mod eight {
    use wide::f32x8;

    pub const LANES: usize = 8;

    #[derive(Clone, Copy)]
    pub struct Lanes(f32x8);

    impl Lanes {
        #[inline(always)]
        pub fn load(a: &[f32; LANES]) -> Self {
            Self(f32x8::new(*a))
        }

        #[inline(always)]
        pub fn splat(x: f32) -> Self {
            Self(f32x8::splat(x))
        }

        #[inline(always)]
        pub fn sub(self, b: Self) -> Self {
            Self(self.0 - b.0)
        }

        #[inline(always)]
        pub fn mul(self, b: Self) -> Self {
            Self(self.0 * b.0)
        }

        /// `max(self, b)` where `self` is a number, `b` where it is NaN (`b` is never NaN):
        /// `maxps` and `vmaxps` return their second operand when either is NaN.
        #[inline(always)]
        pub fn max_ignoring_nan(self, b: Self) -> Self {
            Self(self.0.fast_max(b.0))
        }

        /// `min(self, b)` where `self` is a number, `b` where it is NaN, as `max_ignoring_nan`.
        #[inline(always)]
        pub fn min_ignoring_nan(self, b: Self) -> Self {
            Self(self.0.fast_min(b.0))
        }

        /// Bit `l` set where `t0 <= t1 && t0 < t_max && t1 > 0` in lane `l`.
        #[inline(always)]
        pub fn entered(t0: Self, t1: Self, t_max: f32) -> u32 {
            let inside =
                t0.0.simd_le(t1.0) & t0.0.simd_lt(f32x8::splat(t_max)) & t1.0.simd_gt(f32x8::ZERO);
            inside.to_bitmask()
        }

        #[inline(always)]
        pub fn to_array(self) -> [f32; LANES] {
            self.0.to_array()
        }
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

    impl Lanes {
        #[inline(always)]
        pub fn load(a: &[f32; LANES]) -> Self {
            Self(Vec4::from_array(*a))
        }

        #[inline(always)]
        pub fn splat(x: f32) -> Self {
            Self(Vec4::splat(x))
        }

        #[inline(always)]
        pub fn sub(self, b: Self) -> Self {
            Self(self.0 - b.0)
        }

        #[inline(always)]
        pub fn mul(self, b: Self) -> Self {
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
        pub fn max_ignoring_nan(self, b: Self) -> Self {
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

        /// `min(self, b)` where `self` is a number, `b` where it is NaN, as `max_ignoring_nan`.
        #[inline(always)]
        pub fn min_ignoring_nan(self, b: Self) -> Self {
            #[cfg(target_arch = "x86_64")]
            {
                Self(self.0.min(b.0))
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                Self(b.0.min(Vec4::select(self.0.is_nan_mask(), Vec4::INFINITY, self.0)))
            }
        }

        /// Bit `l` set where `t0 <= t1 && t0 < t_max && t1 > 0` in lane `l`.
        #[inline(always)]
        pub fn entered(t0: Self, t1: Self, t_max: f32) -> u32 {
            let inside = t0.0.cmple(t1.0) & t0.0.cmplt(Vec4::splat(t_max)) & t1.0.cmpgt(Vec4::ZERO);
            inside.bitmask()
        }

        #[inline(always)]
        pub fn to_array(self) -> [f32; LANES] {
            self.0.to_array()
        }
    }
}

#[cfg(test)]
mod tests {
    /// The tests of one lane implementation (module `$lanes`), run for every implementation
    /// the target compiles.
    macro_rules! lane_tests {
        ($lanes:ident) => {
            mod $lanes {
                use super::super::$lanes::{Lanes, LANES};

                /// The NaN rule the slab test relies on, on the backend this test is built for.
                #[test]
                fn min_and_max_ignore_a_nan_first_operand() {
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
                            let (va, vb) = (Lanes::load(&xs), Lanes::load(&ys));
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
                                let bits =
                                    Lanes::entered(Lanes::load(&t0), Lanes::load(&t1), t_max);
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
                    let a: [f32; LANES] = core::array::from_fn(|l| l as f32 * 1.25 - 3.0);
                    let b: [f32; LANES] = core::array::from_fn(|l| 0.1 + l as f32);
                    let (va, vb) = (Lanes::load(&a), Lanes::load(&b));
                    let d = va.sub(vb).to_array();
                    let p = va.mul(vb).to_array();
                    let s = Lanes::splat(2.5).to_array();
                    for lane in 0..LANES {
                        assert_eq!(d[lane].to_bits(), (a[lane] - b[lane]).to_bits());
                        assert_eq!(p[lane].to_bits(), (a[lane] * b[lane]).to_bits());
                        assert_eq!(s[lane], 2.5);
                    }
                }
            }
        };
    }

    lane_tests!(quad);
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    lane_tests!(eight);
}
