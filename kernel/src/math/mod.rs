//! Math that knows nothing about rendering: frames, warps, float error bounds, colour.
//! Every transcendental goes through `libm` (directly or through glam's `libm` feature) so
//! results do not depend on the platform's math library.

mod float;
mod frame;
mod pdf;
mod sincos;
pub mod warp;

pub use float::{gamma, next_float_down, next_float_up};
pub use frame::Frame;
pub use pdf::{AreaPdf, SolidAnglePdf};
pub use sincos::sin_cos_lanes;

use glam::Vec3;

pub const PI: f32 = core::f32::consts::PI;
pub const INV_PI: f32 = core::f32::consts::FRAC_1_PI;
pub const INV_2PI: f32 = 0.5 * core::f32::consts::FRAC_1_PI;

/// Rec. 709 luminance with the weights TinyRender uses (FORMAT.md §4.3).
#[inline]
#[must_use]
pub fn luminance(c: Vec3) -> f32 {
    0.212_671 * c.x + 0.715_160 * c.y + 0.072_169 * c.z
}

#[inline]
#[must_use]
pub fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// `sqrt(max(0, x))`: for quantities that are non-negative up to rounding.
#[inline]
#[must_use]
pub fn safe_sqrt(x: f32) -> f32 {
    libm::sqrtf(x.max(0.0))
}

/// `(sin x, cos x)`: libm's `sincosf`, which is bit for bit `(libm::sinf(x), libm::cosf(x))`
/// (checked over all 2^32 inputs; the tests below check the angles the warps make) with one
/// range reduction instead of two. The sampling code's one implementation of sine and cosine.
#[inline]
#[must_use]
pub fn sin_cos(x: f32) -> (f32, f32) {
    libm::sincosf(x)
}

#[inline]
#[must_use]
pub fn powf(x: f32, y: f32) -> f32 {
    libm::powf(x, y)
}

/// Mirror reflection of `d` about the local normal +z (FORMAT.md §4.1).
#[inline]
#[must_use]
pub fn reflect_local(d: Vec3) -> Vec3 {
    Vec3::new(-d.x, -d.y, d.z)
}

/// True when every component is finite.
#[inline]
#[must_use]
pub fn is_finite(v: Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit equality, any NaN equal to any NaN.
    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    fn check(x: f32) {
        let (s, c) = sin_cos(x);
        assert!(
            same(s, libm::sinf(x)) && same(c, libm::cosf(x)),
            "sin_cos({x:e}) = ({s:e}, {c:e}), sinf {:e}, cosf {:e}",
            libm::sinf(x),
            libm::cosf(x)
        );
    }

    /// Replacing `sinf` and `cosf` by `sin_cos` leaves images unchanged: every azimuth the
    /// warps compute (`2π·u` on the samplers' 24-bit grid, and the concentric disk's angles,
    /// which lie in [−π/4, 3π/4]), and a stride through all bit patterns (NaN, infinities,
    /// subnormals, huge arguments with the slow reduction).
    #[test]
    fn sin_cos_is_sinf_and_cosf_bit_for_bit() {
        for i in 0..1u32 << 24 {
            let u = i as f32 * (1.0 / (1u32 << 24) as f32);
            check(2.0 * PI * u);
        }
        let quarter = core::f32::consts::FRAC_PI_4;
        for i in 0..=1u32 << 20 {
            let r = -1.0 + 2.0 * (i as f32 / (1u32 << 20) as f32);
            check(quarter * r);
            check(core::f32::consts::FRAC_PI_2 - quarter * r);
        }
        for bits in (0..=u32::MAX).step_by(4099) {
            check(f32::from_bits(bits));
        }
        for x in [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            1e-30,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
        ] {
            check(x);
            check(-x);
        }
    }
}
