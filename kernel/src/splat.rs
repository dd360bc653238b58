//! Splats: contributions that land on arbitrary pixels (light tracing, BDPT's `t = 1`
//! strategies), accumulated so that an image does not depend on the order they arrive in.
//!
//! Floating-point sums depend on the order of their terms, and light paths from any tile
//! land on any pixel, so threads, tile orders and shards would each give other last bits.
//! Splats are therefore added as **fixed-point integers** (`i64`, [`SPLAT_FRACTION_BITS`]
//! fraction bits): integer addition is associative and commutative, so per-thread buffers,
//! atomics and shard files can be summed in any order with the same result. A splat value is
//! rounded once, to 2⁻³² ≈ 2.3·10⁻¹⁰ (far below any image's noise), and values up to 2³¹
//! are representable; the sum saturates instead of wrapping.

use crate::Rgb;
use glam::Vec2;

/// Receives contributions at arbitrary pixels. Path tracers write only their own pixel and do
/// not splat.
pub trait SplatSink {
    /// Adds `value` to the pixel containing the continuous raster position `raster` (row 0
    /// at the top). Positions outside the film are ignored.
    fn splat(&mut self, raster: Vec2, value: Rgb);
}

/// A sink that drops everything (for estimators that never splat, and for tests).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoSplats;

impl SplatSink for NoSplats {
    #[inline]
    fn splat(&mut self, _raster: Vec2, _value: Rgb) {}
}

/// Fraction bits of the fixed-point splat sums.
pub const SPLAT_FRACTION_BITS: u32 = 32;
/// Largest magnitude of one splat value (larger ones, and non-finite ones, are refused).
pub const SPLAT_MAX: f32 = 2_147_483_648.0; // 2^31

/// `v` in fixed point (rounded to nearest), or `None` when it is not finite or exceeds
/// [`SPLAT_MAX`]. The product is exact in f64, so the rounding is the only one.
#[inline]
#[must_use]
pub fn to_fixed(v: f32) -> Option<i64> {
    if !v.is_finite() || v.abs() >= SPLAT_MAX {
        return None;
    }
    let scaled = f64::from(v) * (1u64 << SPLAT_FRACTION_BITS) as f64;
    Some(libm::round(scaled) as i64)
}

/// The value of a fixed-point sum.
#[inline]
#[must_use]
pub fn from_fixed(sum: i64) -> f64 {
    sum as f64 / (1u64 << SPLAT_FRACTION_BITS) as f64
}

/// The final value of a pixel rendered with `spp` samples: `(sum + Σ splats) / spp` per
/// channel, where `sum` is the sum of the pixel's own samples ([`crate::integrator::PixelStats`]
/// `::sum`, 0 for light tracing) and `splats` its fixed-point splat sums. Every host resolves
/// images with this function (the C API's `ember_splat_resolve` too), so they agree bit for bit.
///
/// The arithmetic, per channel: `(f64(sum) + from_fixed(splat)) / f64(spp)` in IEEE binary64
/// with round-to-nearest-even, rounded once to f32 at the end. In C, with `FLT_EVAL_METHOD ==
/// 0`: `(float)(((double)sum + (double)splat / 4294967296.0) / (double)spp)`. Every step is a
/// correctly rounded IEEE operation (the `i64 → f64` conversion, the exact division by 2³², the
/// addition, the division, the narrowing), so the bits are the same on every target, soft
/// float included. Without splats the result equals the f32 mean `sum / spp` exactly (binary64
/// has more than 2·24 + 2 bits, so dividing in f64 and rounding to f32 is the correctly
/// rounded f32 quotient): path-traced images resolve to what they were before splats existed.
/// `spp` must be at least 1.
#[inline]
#[must_use]
pub fn resolve(sum: Rgb, splats: [i64; 3], spp: u32) -> Rgb {
    let n = f64::from(spp);
    let c = |s: f32, f: i64| ((f64::from(s) + from_fixed(f)) / n) as f32;
    Rgb::new(
        c(sum.x, splats[0]),
        c(sum.y, splats[1]),
        c(sum.z, splats[2]),
    )
}

/// The pixel index of `raster` in a `width × height` film, or `None` outside it.
#[inline]
#[must_use]
pub fn pixel_of(raster: Vec2, width: u32, height: u32) -> Option<usize> {
    let (x, y) = (libm::floorf(raster.x), libm::floorf(raster.y));
    // Written so that NaN positions are outside.
    if x >= 0.0 && y >= 0.0 && x < width as f32 && y < height as f32 {
        Some(y as usize * width as usize + x as usize)
    } else {
        None
    }
}

/// Fixed-point splat sums of a `width × height` film in a caller slice (one `[i64; 3]` per
/// pixel, row-major), for one thread or one work item; buffers are merged by adding them
/// ([`SplatBuffer::add`]) in any order.
#[derive(Debug)]
pub struct SplatBuffer<'a> {
    pub width: u32,
    pub height: u32,
    pub sums: &'a mut [[i64; 3]],
    /// Splats refused for being non-finite or too large.
    pub invalid: u64,
}

impl<'a> SplatBuffer<'a> {
    /// A buffer over `sums`, which must hold `width · height` pixels (`None` otherwise).
    #[must_use]
    pub fn new(width: u32, height: u32, sums: &'a mut [[i64; 3]]) -> Option<Self> {
        (sums.len() == width as usize * height as usize).then_some(Self {
            width,
            height,
            sums,
            invalid: 0,
        })
    }

    /// Adds another buffer's sums (saturating).
    pub fn add(&mut self, other: &[[i64; 3]]) {
        for (a, b) in self.sums.iter_mut().zip(other) {
            for c in 0..3 {
                a[c] = a[c].saturating_add(b[c]);
            }
        }
    }
}

impl SplatSink for SplatBuffer<'_> {
    #[inline]
    fn splat(&mut self, raster: Vec2, value: Rgb) {
        let Some(i) = pixel_of(raster, self.width, self.height) else {
            return;
        };
        let fixed = [to_fixed(value.x), to_fixed(value.y), to_fixed(value.z)];
        let [Some(r), Some(g), Some(b)] = fixed else {
            self.invalid += 1;
            return;
        };
        let px = &mut self.sums[i];
        px[0] = px[0].saturating_add(r);
        px[1] = px[1].saturating_add(g);
        px[2] = px[2].saturating_add(b);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_point_round_trips_and_sums_in_any_order() {
        for v in [0.0f32, 1.0, -1.0, 0.1, 1e-9, 3.5e8, -2.25] {
            let f = to_fixed(v).unwrap();
            assert!(
                (from_fixed(f) - f64::from(v)).abs() <= 0.5 / 4294967296.0,
                "{v}"
            );
        }
        assert!(to_fixed(f32::NAN).is_none());
        assert!(to_fixed(f32::INFINITY).is_none());
        assert!(to_fixed(3e9).is_none());
        // Float sums depend on order; the fixed-point sum does not.
        let values = [1e8f32, 1.0, -1e8, 1e-3, 7.25, 0.1];
        let forward: i64 = values.iter().map(|&v| to_fixed(v).unwrap()).sum();
        let backward: i64 = values.iter().rev().map(|&v| to_fixed(v).unwrap()).sum();
        assert_eq!(forward, backward);
        assert!((from_fixed(forward) - 8.351).abs() < 1e-6);
    }

    /// The resolve arithmetic written out with f64 operations, as the C API documents it.
    fn resolve_channel(sum: f32, splat: i64, spp: u32) -> f32 {
        let splat = splat as f64 / 4294967296.0;
        ((sum as f64 + splat) / spp as f64) as f32
    }

    #[test]
    fn resolve_is_the_documented_f64_arithmetic_and_the_f32_mean_without_splats() {
        // A deterministic spread of sums (including subnormal, huge and exactly divisible ones)
        // and sample counts.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut differs_from_f32_sum = 0;
        for i in 0..200_000u32 {
            let bits = next();
            let sum = match i % 4 {
                0 => f32::from_bits((bits as u32) & 0x7f7f_ffff),
                1 => (bits % 1_000_000) as f32 * 1e-3,
                2 => f32::from_bits(bits as u32 & 0x007f_ffff),
                _ => (bits >> 40) as f32,
            };
            let spp = [1, 2, 3, 4, 7, 10, 64, 1000, 4097, u32::MAX][i as usize % 10];
            // Without splats: exactly the f32 mean the path tracers' hosts compute.
            let r = resolve(Rgb::splat(sum), [0; 3], spp);
            assert_eq!(
                r.x.to_bits(),
                (sum / spp as f32).to_bits(),
                "{sum:e} / {spp}"
            );
            let splat = (next() >> 20) as i64;
            let r = resolve(Rgb::new(sum, 0.0, sum), [splat, splat, 0], spp);
            assert_eq!(r.x.to_bits(), resolve_channel(sum, splat, spp).to_bits());
            assert_eq!(r.y.to_bits(), resolve_channel(0.0, splat, spp).to_bits());
            assert_eq!(r.z.to_bits(), (sum / spp as f32).to_bits());
            // Not the same as adding the splats in f32 first (so the f64 steps matter).
            let f32_sum = ((sum + from_fixed(splat) as f32) / spp as f32).to_bits();
            differs_from_f32_sum += usize::from(r.x.to_bits() != f32_sum);
        }
        assert!(differs_from_f32_sum > 1000, "{differs_from_f32_sum}");
        // Light tracing: no own samples, the splats over spp.
        let one = to_fixed(1.0).unwrap();
        assert_eq!(
            resolve(Rgb::ZERO, [3 * one, one, 0], 4),
            Rgb::new(0.75, 0.25, 0.0)
        );
        assert_eq!(resolve(Rgb::ONE, [one, 0, 0], 2), Rgb::new(1.0, 0.5, 0.5));
    }

    #[test]
    fn buffer_splats_into_the_pixel_under_the_raster_position() {
        let mut sums = [[0i64; 3]; 6];
        let mut b = SplatBuffer::new(3, 2, &mut sums).unwrap();
        b.splat(Vec2::new(2.5, 1.99), Rgb::new(1.0, 2.0, 3.0));
        b.splat(Vec2::new(2.0, 1.0), Rgb::splat(0.5));
        b.splat(Vec2::new(3.0, 0.0), Rgb::ONE); // outside
        b.splat(Vec2::new(f32::NAN, 0.0), Rgb::ONE); // outside
        b.splat(Vec2::new(0.0, 0.0), Rgb::new(f32::INFINITY, 0.0, 0.0));
        assert_eq!(b.invalid, 1);
        assert_eq!(from_fixed(b.sums[5][0]), 1.5);
        assert_eq!(from_fixed(b.sums[5][2]), 3.5);
        assert_eq!(b.sums[0], [0; 3]);
        assert!(SplatBuffer::new(3, 3, &mut [[0; 3]; 6]).is_none());
    }
}
