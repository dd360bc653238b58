//! Floating-point error analysis helpers (pbrt-v4 `util/float.h`, §6.8 of PBR 4th ed.).

/// Bound on the relative error of `n` chained float operations: n·ε / (1 − n·ε),
/// with ε = 2⁻²⁴ the unit roundoff of f32.
#[inline]
#[must_use]
pub const fn gamma(n: u32) -> f32 {
    let e = f32::EPSILON * 0.5;
    (n as f32 * e) / (1.0 - n as f32 * e)
}

/// The next representable float above `v` (identity for +inf and NaN).
#[inline]
#[must_use]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 || v.is_nan() {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next representable float below `v` (identity for -inf and NaN).
#[inline]
#[must_use]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 || v.is_nan() {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_float_steps_one_ulp() {
        assert!(next_float_up(1.0) > 1.0);
        assert_eq!(next_float_up(1.0).to_bits(), 1.0f32.to_bits() + 1);
        assert!(next_float_down(1.0) < 1.0);
        assert!(next_float_up(0.0) > 0.0);
        assert!(next_float_down(0.0) < 0.0);
        assert!(next_float_up(-1.0) > -1.0);
        assert!(next_float_down(-1.0) < -1.0);
        assert_eq!(next_float_up(f32::INFINITY), f32::INFINITY);
        assert!(gamma(3) > 3.0 * f32::EPSILON * 0.5);
    }
}
