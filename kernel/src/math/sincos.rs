//! [`super::sin_cos`] of several numbers at once, for the batched path tracer's lanes: libm's
//! `sincosf` spelt out branch-free, so that the compiler vectorises it in the instructions of
//! the code it is inlined into (the f64 polynomials in 512- or 256-bit registers), and bit for
//! bit the same.
//!
//! Exactness: for `|x| ≤ 9π/4` (every argument the warps make) `sincosf` evaluates one of its
//! two polynomials `k_sinf`, `k_cosf` at `x` shifted by a multiple of π/2 in f64, and returns
//! them swapped and negated by the octant. Each lane here makes the same shift (the same f64
//! operation, operands in the same order), evaluates both polynomials with libm's operations in
//! libm's order (no fused multiply-add: Rust never contracts), and selects what `sincosf`'s
//! branch for its octant returns: selections and sign flips, which do not round. Lanes past
//! 9π/4, infinite or NaN take `sincosf` itself. The tests compare with it bit for bit.

// The constants digit for digit as libm writes them (more digits than an f64 holds).
#![allow(clippy::excessive_precision)]

/// `k_sinf`'s coefficients (libm 0.2, FreeBSD's `k_sinf.c`).
const S1: f64 = -0.166_666_666_416_265_235_595;
const S2: f64 = 0.008_333_329_385_889_463_175_6;
const S3: f64 = -0.000_198_393_348_360_966_317_347;
const S4: f64 = 0.000_002_718_311_493_989_821_906_4;

/// `k_cosf`'s coefficients (FreeBSD's `k_cosf.c`).
const C0: f64 = -0.499_999_997_251_031_003_120;
const C1: f64 = 0.041_666_623_323_739_063_189_4;
const C2: f64 = -0.001_388_676_377_460_992_946_92;
const C3: f64 = 0.000_024_390_448_796_277_409_065_4;

/// `sincosf`'s multiples of π/2, rounded to f64 (its `0.5 · 3.1415926535897931160` is π/2 in
/// f64).
const PI_2: f64 = core::f64::consts::FRAC_PI_2;
const S1PIO2: f64 = PI_2;
const S2PIO2: f64 = 2.0 * PI_2;
const S3PIO2: f64 = 3.0 * PI_2;
const S4PIO2: f64 = 4.0 * PI_2;

/// Largest `|x|` bits of `sincosf`'s octant branches: π/4, 3π/4, 5π/4, 7π/4, 9π/4 (each
/// "about", as libm rounds them), and of its tiny arguments (2^-12).
const PIO4_BITS: u32 = 0x3f49_0fda;
const PIO4_3_BITS: u32 = 0x4016_cbe3;
const PIO4_5_BITS: u32 = 0x407b_53d1;
const PIO4_7_BITS: u32 = 0x40af_eddf;
const PIO4_9_BITS: u32 = 0x40e2_31d5;
const TINY_BITS: u32 = 0x3980_0000;

#[inline(always)]
fn k_sinf(x: f64) -> f32 {
    let z = x * x;
    let w = z * z;
    let r = S3 + z * S4;
    let s = z * x;
    ((x + s * (S1 + z * S2)) + s * w * r) as f32
}

#[inline(always)]
fn k_cosf(x: f64) -> f32 {
    let z = x * x;
    let w = z * z;
    let r = C2 + z * C3;
    (((1.0 + z * C0) + w * C1) + (w * z) * r) as f32
}

/// `sincosf(x)` for `|x| ≤ 9π/4` without a branch (anything for other `x`).
#[inline(always)]
fn sin_cos_near(x: f32) -> (f32, f32) {
    let bits = x.to_bits();
    let ix = bits & 0x7fff_ffff;
    let sign = bits >> 31 != 0;
    let xd = f64::from(x);
    // The octant: `a` up to π/4, then `b`, `c`, `d`, `e` up to 3π/4, 5π/4, 7π/4, 9π/4.
    let a = ix <= PIO4_BITS;
    let b = !a & (ix <= PIO4_3_BITS);
    let c = !a & !b & (ix <= PIO4_5_BITS);
    let d = !a & !b & !c & (ix <= PIO4_7_BITS);
    let k = if b {
        S1PIO2
    } else if c {
        S2PIO2
    } else if d {
        S3PIO2
    } else {
        S4PIO2
    };
    // The shifted argument, each as `sincosf` computes it (`π/2 − x` for positive x in the
    // second octant, `x + kπ/2` for negative x, `x − kπ/2` otherwise).
    let shifted_up = xd + k;
    let shifted_down = if b { k - xd } else { xd - k };
    let shifted = if sign { shifted_up } else { shifted_down };
    let y = if a { xd } else { shifted };
    let (ks, kc) = (k_sinf(y), k_cosf(y));
    // Octants b and d swap sine and cosine; the signs as `sincosf` gives them.
    let swap = b | d;
    let s_neg = (b & sign) | c | (d & !sign);
    let c_neg = c | (d & sign);
    let s = if swap { kc } else { ks };
    let co = if swap { ks } else { kc };
    let s = if s_neg { -s } else { s };
    let co = if c_neg { -co } else { co };
    // |x| < 2^-12: `(x, 1)`.
    let tiny = ix < TINY_BITS;
    (if tiny { x } else { s }, if tiny { 1.0 } else { co })
}

/// `(sin x[l], cos x[l])` for each lane `l` whose bit is set in `lanes`, bit for bit
/// [`super::sin_cos`] (other lanes hold values of no meaning). Always inlined, so that it is
/// vectorised with the instructions of its caller.
#[inline(always)]
#[must_use]
pub fn sin_cos_lanes<const N: usize>(x: &[f32; N], lanes: u32) -> ([f32; N], [f32; N]) {
    let mut sin = [0.0; N];
    let mut cos = [0.0; N];
    let mut far = 0u32;
    for l in 0..N {
        (sin[l], cos[l]) = sin_cos_near(x[l]);
        far |= u32::from(x[l].to_bits() & 0x7fff_ffff > PIO4_9_BITS) << l;
    }
    far &= lanes;
    while far != 0 {
        let l = far.trailing_zeros() as usize;
        far &= far - 1;
        (sin[l], cos[l]) = super::sin_cos(x[l]);
    }
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    fn bits(v: (f32, f32)) -> (u32, u32) {
        (v.0.to_bits(), v.1.to_bits())
    }

    /// Eight arguments at a time through the lanes, each against `libm::sincosf`.
    struct Check {
        x: [f32; 8],
        n: usize,
    }

    impl Check {
        fn new() -> Self {
            Self { x: [0.0; 8], n: 0 }
        }

        fn push(&mut self, x: f32) {
            self.x[self.n] = x;
            self.n += 1;
            if self.n == 8 {
                self.flush();
            }
        }

        /// The lanes compiled for the build's baseline and, where this CPU has them, for AVX2
        /// and AVX-512 (as the batched path tracer runs them), each against `sincosf`.
        fn flush(&mut self) {
            let lanes = (1u32 << self.n) - 1;
            let baseline = Some(sin_cos_lanes(&self.x, lanes));
            #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
            let (avx2, avx512) = {
                use crate::simd::{Avx, Avx512};
                let avx2 = Avx::detect().map(|avx| {
                    avx.run(
                        #[inline(always)]
                        |_| sin_cos_lanes(&self.x, lanes),
                    )
                });
                let avx512 = Avx512::detect().map(|avx512| {
                    avx512.run(
                        #[inline(always)]
                        |_| sin_cos_lanes(&self.x, lanes),
                    )
                });
                (avx2, avx512)
            };
            #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
            let (avx2, avx512) = (None, None);
            let answers = [("baseline", baseline), ("avx2", avx2), ("avx512", avx512)];
            for (isa, (s, c)) in answers.into_iter().filter_map(|(i, a)| Some((i, a?))) {
                for l in 0..self.n {
                    let x = self.x[l];
                    assert_eq!(
                        bits((s[l], c[l])),
                        bits(libm::sincosf(x)),
                        "{isa}: sin_cos_lanes({x:e}) (bits {:#x}) = ({:e}, {:e}), sincosf {:?}",
                        x.to_bits(),
                        s[l],
                        c[l],
                        libm::sincosf(x)
                    );
                }
            }
            self.n = 0;
        }
    }

    /// The angles the warps make (`2π·u` on the samplers' 24-bit grid; the concentric disk's,
    /// in [−π/4, 3π/4]), every octant's edges, a stride through all bit patterns (NaN,
    /// infinities, subnormals, arguments past 9π/4) and one through [−9π/4, 9π/4].
    #[test]
    fn lanes_are_sincosf_bit_for_bit() {
        let mut check = Check::new();
        for i in 0..1u32 << 24 {
            check.push(2.0 * PI * (i as f32 * (1.0 / (1u32 << 24) as f32)));
        }
        for i in 0..=1u32 << 20 {
            let r = -1.0 + 2.0 * (i as f32 / (1u32 << 20) as f32);
            check.push(FRAC_PI_4 * r);
            check.push(FRAC_PI_2 - FRAC_PI_4 * r);
        }
        for edge in [
            TINY_BITS,
            PIO4_BITS,
            PIO4_3_BITS,
            PIO4_5_BITS,
            PIO4_7_BITS,
            PIO4_9_BITS,
        ] {
            for bits in edge - 64..=edge + 64 {
                check.push(f32::from_bits(bits));
                check.push(-f32::from_bits(bits));
            }
        }
        for bits in (0..=u32::MAX).step_by(4099) {
            check.push(f32::from_bits(bits));
        }
        for bits in (0..=PIO4_9_BITS).step_by(97) {
            check.push(f32::from_bits(bits));
            check.push(-f32::from_bits(bits));
        }
        for x in [
            0.0,
            f32::MIN_POSITIVE,
            1e-30,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
        ] {
            check.push(x);
            check.push(-x);
        }
        check.flush();
    }

    /// Every argument of [−9π/4, 9π/4], where the lanes compute `sincosf` themselves:
    /// 2.2 billion of them, so run by hand (`cargo test --release -p ember-kernel --lib
    /// sincos -- --ignored`).
    #[test]
    #[ignore]
    fn lanes_are_sincosf_on_every_argument_they_compute() {
        let mut check = Check::new();
        for bits in 0..=PIO4_9_BITS {
            check.push(f32::from_bits(bits));
            check.push(-f32::from_bits(bits));
        }
        check.flush();
    }

    /// Lanes outside the mask are not computed by the scalar fallback, and lanes in it are,
    /// whatever their neighbours hold.
    #[test]
    fn far_lanes_take_the_scalar_code_only_in_the_mask() {
        let x = [1e10, f32::NAN, 0.5, -7.5, f32::INFINITY, 3.0, -1e-5, 100.0];
        let (s, c) = sin_cos_lanes(&x, 0b1010_1011);
        for l in [0, 1, 3, 5, 7] {
            assert_eq!(bits((s[l], c[l])), bits(libm::sincosf(x[l])), "lane {l}");
        }
    }
}
