//! Reflection, refraction and the exact Fresnel equations of a dielectric boundary, in the
//! local shading frame (normal +z). pbrt-v4 `util/scattering.h` conventions.

use crate::math::safe_sqrt;
use glam::Vec3;

/// Mirror reflection of `wo` about the unit normal `n` (both pointing away from the surface).
#[inline]
#[must_use]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    -wo + n * (2.0 * wo.dot(n))
}

/// Refraction of `wi` (pointing away from the surface) through the boundary with unit normal
/// `n` and relative index of refraction `eta` = η_below / η_above of the side `n` points away
/// from. Returns the transmitted direction (unit length when `wi` is) and the relative IOR
/// `η′` of the crossing (`eta` when entering from the side `n` points to, `1/eta` when
/// leaving), or `None` under total internal reflection.
#[inline]
#[must_use]
pub fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(wi);
    let (mut eta, mut n) = (eta, n);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    if eta == 1.0 {
        // Index-matched: straight through, exactly.
        return Some((-wi, 1.0));
    }
    let cos2_t = cos2_transmitted(cos_i, eta);
    if cos2_t <= 0.0 {
        return None;
    }
    let cos_t = safe_sqrt(cos2_t);
    Some((-wi / eta + n * (cos_i / eta - cos_t), eta))
}

/// cos²θₜ = 1 − sin²θᵢ/η² of the transmitted direction, written as (cos²θᵢ + (η − 1)(η + 1))/η²
/// so that it does not cancel: `1 − (1 − cos²θᵢ)/η²` loses all precision when η is close to 1
/// (at η = 1 and cosθᵢ < 1.7e-4, `1 − cos²θᵢ` rounds to 1 and the boundary "reflected totally").
/// Written this way it is exactly cos²θᵢ at η = 1, so cosθₜ = cosθᵢ. ≤ 0 means total internal
/// reflection.
#[inline]
fn cos2_transmitted(cos_i: f32, eta: f32) -> f32 {
    (cos_i * cos_i + (eta - 1.0) * (eta + 1.0)) / (eta * eta)
}

/// Unpolarised Fresnel reflectance of a dielectric boundary for the cosine `cos_i` between the
/// incident direction and the normal, with `eta` = η_t/η_i for directions on the normal's side
/// (a negative `cos_i` means the direction is on the other side, where the ratio is `1/eta`).
/// Total internal reflection gives 1; an index-matched boundary (`eta == 1`) reflects exactly
/// nothing.
#[inline]
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    if eta == 1.0 {
        return 0.0;
    }
    let mut cos_i = cos_i.clamp(-1.0, 1.0);
    let mut eta = eta;
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let cos2_t = cos2_transmitted(cos_i, eta);
    if cos2_t <= 0.0 {
        return 1.0;
    }
    let cos_t = safe_sqrt(cos2_t);
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_reference_values() {
        // BONUS-NOTES §5: eta 1.5 gives 0.0400 at 0°, 0.0502 at 45°, 0.3877 at 80°.
        let f = |deg: f32| fresnel_dielectric(libm::cosf(deg.to_radians()), 1.5);
        assert!((f(0.0) - 0.04).abs() < 1e-6);
        assert!((f(45.0) - 0.0502).abs() < 1e-4);
        assert!((f(80.0) - 0.3877).abs() < 1e-4);
        assert!((fresnel_dielectric(1.0, 1.33) - 0.0201).abs() < 1e-4);
        // From inside, past the critical angle asin(1/1.5) = 41.81°: total reflection.
        let inside = |deg: f32| fresnel_dielectric(-libm::cosf(deg.to_radians()), 1.5);
        assert_eq!(inside(41.9), 1.0);
        assert!(inside(41.7) < 1.0);
        for cos in [1.0, 0.6021685, 0.3, 1e-4, 1e-30, -0.5] {
            assert_eq!(fresnel_dielectric(cos, 1.0), 0.0, "index-matched");
        }
    }

    #[test]
    fn refraction_obeys_snell() {
        let n = Vec3::Z;
        let wi = Vec3::new(0.6, 0.0, 0.8);
        let (wt, etap) = refract(wi, n, 1.5).unwrap();
        assert_eq!(etap, 1.5);
        assert!((wt.length() - 1.0).abs() < 1e-6);
        let sin_t = (wt.x * wt.x + wt.y * wt.y).sqrt();
        assert!((0.6 - 1.5 * sin_t).abs() < 1e-6, "sin_i = eta sin_t");
        assert!(wt.z < 0.0 && wt.x < 0.0);
        // Back through: the original direction, with the inverse ratio.
        let (back, etap) = refract(wt, n, 1.5).unwrap();
        assert!((back - wi).length() < 1e-6);
        assert!((etap - 1.0 / 1.5).abs() < 1e-7);
        assert!(refract(Vec3::new(0.8, 0.0, -0.6), n, 1.5).is_none(), "TIR");
    }

    /// Index-matched and nearly index-matched boundaries at grazing angles: straight through
    /// (exactly at η = 1), never a false total internal reflection, and Snell's law to f32
    /// precision where `1 − sin²θᵢ/η²` used to cancel.
    #[test]
    fn refraction_close_to_index_matched() {
        for cos in [1.0f32, 0.0683766, 1e-3, 1e-4, 1e-6] {
            let sin = safe_sqrt(1.0 - cos * cos);
            let wi = Vec3::new(sin * 0.6, sin * 0.8, cos);
            let (wt, etap) = refract(wi, Vec3::Z, 1.0).unwrap();
            assert_eq!((wt, etap), (-wi, 1.0), "cos {cos}");
            let (wt, _) = refract(-wi, Vec3::Z, 1.0).unwrap();
            assert_eq!(wt, wi);
            // Entering a slightly denser medium never reflects totally.
            let (wt, _) = refract(wi, Vec3::Z, 1.0001).unwrap();
            assert!(
                wt.z < 0.0 && (wt.length() - 1.0).abs() < 1e-6,
                "cos {cos}: {wt}"
            );
            // cosθₜ² = (cos²θᵢ + η² − 1)/η² in f64. The old `1 − sin²θᵢ/η²` was off by
            // ε/(2cosθₜ) (2e-6 at cosθᵢ = 1e-3); what is left is the rounding of the sum
            // −wᵢ/η + n(cosθᵢ/η − cosθₜ), a few ulps of 1.
            let eta = f64::from(1.0001f32);
            let c = f64::from(cos);
            let want = ((c * c + eta * eta - 1.0) / (eta * eta)).sqrt();
            assert!(
                (f64::from(-wt.z) - want).abs() < 2e-7,
                "cos {cos}: {wt} vs {want}"
            );
        }
    }
}
