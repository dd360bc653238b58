//! The isotropic Trowbridge–Reitz (GGX) microfacet distribution with the height-correlated
//! Smith masking–shadowing function, and sampling of its visible normals.
//!
//! - `D(m) = α² / (π (sin²θ_m + α² cos²θ_m)²)`, written without tangents so that it stays
//!   exact for the smallest roughness used (α = [`MIN_ALPHA`]).
//! - `Λ(w) = (√(cos²θ + α² sin²θ) / |cosθ| − 1) / 2`, `G1 = 1/(1 + Λ)`, and the
//!   height-correlated `G(wo, wi) = 1/(1 + Λ(wo) + Λ(wi))` (Heitz 2014; pbrt-v4). Mitsuba 3's
//!   `roughconductor` uses the separable `G1(wo)·G1(wi)` instead, which differs by under 1% at
//!   the roughnesses ember's scenes use.
//! - Visible normals `D_w(m) = G1(w) max(0, w·m) D(m) / |cosθ_w|` are sampled with the
//!   spherical-cap method of Dupuy and Benyoub (2023): in the stretched configuration the
//!   visible normals are the directions from `−w` to a uniform point of the cap of the unit
//!   sphere above the plane `z = −w_z`. One sin/cos pair, no polar-disk warp.

use crate::math::{safe_sqrt, INV_PI, PI};
use glam::{Vec2, Vec3};

/// Below this roughness a surface is treated as perfectly smooth (pbrt-v4's
/// `EffectivelySmooth`): the lobe is narrower than f32 sampling resolves.
pub const SMOOTH_ALPHA: f32 = 1e-3;
/// Rough surfaces are rendered with at least this roughness.
pub const MIN_ALPHA: f32 = 1e-4;

/// The isotropic Trowbridge–Reitz distribution of roughness `alpha`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrowbridgeReitz {
    pub alpha: f32,
}

impl TrowbridgeReitz {
    #[inline]
    #[must_use]
    pub fn new(alpha: f32) -> Self {
        Self {
            alpha: alpha.max(MIN_ALPHA),
        }
    }

    /// Whether the distribution is so narrow that the surface is rendered as a delta lobe.
    #[inline]
    #[must_use]
    pub fn effectively_smooth(&self) -> bool {
        self.alpha < SMOOTH_ALPHA
    }

    /// Microfacet normal density `D(m)` per unit solid angle of `m` projected on the
    /// macrosurface (∫ D(m) cosθ_m dm = 1); `m` must be a unit vector.
    #[inline]
    #[must_use]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let sin2 = m.x * m.x + m.y * m.y;
        let k = sin2 + a2 * m.z * m.z;
        a2 * INV_PI / (k * k)
    }

    /// Smith's auxiliary function Λ(w).
    #[inline]
    #[must_use]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let cos2 = w.z * w.z;
        if cos2 == 0.0 {
            return f32::INFINITY;
        }
        let a2 = self.alpha * self.alpha;
        let sin2 = w.x * w.x + w.y * w.y;
        0.5 * (crate::math::sqrt((cos2 + a2 * sin2) / cos2) - 1.0)
    }

    /// Masking of one direction, `G1(w) = 1 / (1 + Λ(w))`.
    #[inline]
    #[must_use]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking–shadowing `G(wo, wi) = 1 / (1 + Λ(wo) + Λ(wi))`.
    #[inline]
    #[must_use]
    pub fn g(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// `G(wo, wi) / (|cosθₒ| |cosθᵢ|)`, the masking–shadowing factor of every microfacet BSDF
    /// with its two cosines, computed without dividing by them: with q(w) = √(cos²θ + α² sin²θ)
    /// (so Λ(w) = (q(w)/|cosθ| − 1)/2), |cosθₒ cosθᵢ| (1 + Λ(wo) + Λ(wi)) =
    /// (|cosθᵢ| q(wo) + |cosθₒ| q(wi)) / 2. At grazing angles G → 0 with the
    /// cosines and the quotient tends to 2/(α(|cosθₒ| + |cosθᵢ|)); `G / (cosθₒ cosθᵢ)` gave
    /// 0/0 = NaN once a cos² underflowed (|cosθ| ≲ 4e-23). 0 when the quotient is not
    /// representable (both directions within ~1e-38 of the horizon).
    #[inline]
    #[must_use]
    pub fn g_over_cosines(&self, wo: Vec3, wi: Vec3) -> f32 {
        let a2 = self.alpha * self.alpha;
        let q = |w: Vec3| crate::math::sqrt(w.z * w.z + a2 * (w.x * w.x + w.y * w.y));
        let (co, ci) = (wo.z.abs(), wi.z.abs());
        let g = 2.0 / (ci * q(wo) + co * q(wi));
        if g.is_finite() {
            g
        } else {
            0.0
        }
    }

    /// Density of [`Self::sample_visible_normal`] for `w`: `G1(w) |w·m| D(m) / |cosθ_w|`
    /// (`w` on either side; `m` in the upper hemisphere).
    #[inline]
    #[must_use]
    pub fn visible_normal_pdf(&self, w: Vec3, m: Vec3) -> f32 {
        let cos = w.z.abs();
        if cos == 0.0 {
            return 0.0;
        }
        // Back-facing microfacets are invisible: w·m must have the sign of w_z.
        let wm = w.dot(m);
        if wm * w.z <= 0.0 {
            return 0.0;
        }
        self.g1(w) * wm.abs() * self.d(m) / cos
    }

    /// A microfacet normal visible from `w`, distributed with [`Self::visible_normal_pdf`].
    /// A `w` below the surface is treated as its mirror image above (the distribution is
    /// symmetric), so the normal is always in the upper hemisphere.
    #[inline]
    #[must_use]
    pub fn sample_visible_normal(&self, w: Vec3, u: Vec2) -> Vec3 {
        let a = self.alpha;
        let w = if w.z < 0.0 { -w } else { w };
        // Stretch to the configuration where the distribution is that of a unit hemisphere.
        let wh = Vec3::new(a * w.x, a * w.y, w.z).normalize();
        let (sin_phi, cos_phi) = crate::math::sin_cos(2.0 * PI * u.x);
        let z = (1.0 - u.y) * (1.0 + wh.z) - wh.z;
        let sin_theta = safe_sqrt(1.0 - z * z);
        let cap = Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, z);
        let h = cap + wh;
        // Unstretch; the floor keeps the normal strictly above the horizon after rounding.
        Vec3::new(a * h.x, a * h.y, h.z.max(1e-6)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ f over the sphere by the midpoint rule in (cosθ, φ), in f64.
    fn integrate(f: impl Fn(Vec3) -> f64, nt: usize, np: usize) -> f64 {
        let mut sum = 0.0;
        for i in 0..nt {
            // Denser near the pole, where narrow lobes live: z = 1 − s², s uniform.
            let s0 = i as f64 / nt as f64;
            let s1 = (i + 1) as f64 / nt as f64;
            let s = 0.5 * (s0 + s1);
            let z = 1.0 - 2.0 * s * s;
            let dz = 2.0 * (s1 * s1 - s0 * s0);
            let r = (1.0 - z * z).max(0.0).sqrt();
            for j in 0..np {
                let phi = 2.0 * core::f64::consts::PI * (j as f64 + 0.5) / np as f64;
                let w = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                sum += f(w) * dz * 2.0 * core::f64::consts::PI / np as f64;
            }
        }
        sum
    }

    #[test]
    fn projected_normal_density_and_visible_normals_integrate_to_one() {
        for alpha in [0.05, 0.2, 0.6, 1.0] {
            let d = TrowbridgeReitz::new(alpha);
            let proj = integrate(|m| f64::from(d.d(m) * m.z.max(0.0)), 4000, 64);
            assert!((proj - 1.0).abs() < 2e-3, "alpha {alpha}: {proj}");
            for cos in [1.0f32, 0.5, 0.1, -0.7] {
                let sin = (1.0 - cos * cos).sqrt();
                let w = Vec3::new(sin * 0.6, sin * 0.8, cos);
                let v = integrate(|m| f64::from(d.visible_normal_pdf(w, m)), 4000, 128);
                assert!((v - 1.0).abs() < 5e-3, "alpha {alpha} cos {cos}: {v}");
            }
        }
    }

    /// G/(cosθₒ cosθᵢ) agrees with G divided by the cosines where that is representable, and
    /// stays finite (the grazing limit 2/(α(|cosθₒ| + |cosθᵢ|))) where the quotient was 0/0.
    #[test]
    fn g_over_cosines_is_finite_at_grazing_angles() {
        for alpha in [1e-3f32, 0.05, 0.5, 1.0] {
            let d = TrowbridgeReitz::new(alpha);
            for (co, ci) in [(1.0f32, 1.0f32), (0.7, -0.3), (0.05, 0.9), (-1e-3, -0.5)] {
                let w = |c: f32, phi: f32| {
                    let s = safe_sqrt(1.0 - c * c);
                    Vec3::new(s * libm::cosf(phi), s * libm::sinf(phi), c)
                };
                let (wo, wi) = (w(co, 0.3), w(ci, 2.0));
                let direct = d.g(wo, wi) / (wo.z * wi.z).abs();
                let robust = d.g_over_cosines(wo, wi);
                assert!(
                    (robust - direct).abs() <= 1e-5 * direct,
                    "{alpha} {co} {ci}"
                );
            }
            for c in [1e-20f32, f32::MIN_POSITIVE, 1e-30] {
                let wo = Vec3::new(0.0, -1.0, c);
                let wi = Vec3::new(1.0, 0.0, 1e-20);
                let g = d.g_over_cosines(wo, wi);
                let limit = 2.0 / (alpha * (c + 1e-20));
                assert!(
                    g.is_finite() && (g - limit).abs() <= 1e-5 * limit,
                    "{alpha} {c}: {g}"
                );
            }
        }
    }

    #[test]
    fn sampled_normals_are_visible_and_in_the_upper_hemisphere() {
        let d = TrowbridgeReitz::new(0.3);
        for cos in [1.0f32, 0.3, 0.01, -0.5] {
            let sin = (1.0 - cos * cos).sqrt();
            let w = Vec3::new(sin, 0.0, cos);
            for i in 0..64 {
                for j in 0..64 {
                    let u = Vec2::new((i as f32 + 0.5) / 64.0, (j as f32 + 0.5) / 64.0);
                    let m = d.sample_visible_normal(w, u);
                    assert!((m.length() - 1.0).abs() < 1e-5);
                    assert!(m.z > 0.0);
                    assert!(w.dot(m) * w.z >= -1e-6, "{w} {m}");
                }
            }
        }
    }
}
