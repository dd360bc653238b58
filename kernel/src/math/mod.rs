//! Math that knows nothing about rendering: frames, warps, float error bounds, colour.
//! Every transcendental goes through `libm` (directly or through glam's `libm` feature) so
//! results do not depend on the platform's math library.

mod float;
mod frame;
mod pdf;
pub mod warp;

pub use float::{gamma, next_float_down, next_float_up};
pub use frame::Frame;
pub use pdf::{AreaPdf, SolidAnglePdf};

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
