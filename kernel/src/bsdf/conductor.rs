use super::fresnel::reflect;
use super::microfacet::TrowbridgeReitz;
use super::{BsdfFlags, BsdfSample, TransportMode};
use crate::math::SolidAnglePdf;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// A metal (`illum 5`): reflectance `Ks` at every angle (no Fresnel falloff, Mitsuba's
/// `conductor` with `material = "none"`). Smooth when the distribution is effectively smooth
/// (a perfect mirror, `f = Ks δ(wi − reflect(wo)) / |cosθᵢ|`); otherwise the Trowbridge–Reitz
/// microfacet BRDF `f = D(m) G(wo, wi) Ks / (4 cosθₒ cosθᵢ)`, sampled by visible normals.
/// One-sided like every opaque BSDF of ember: nothing is reflected below the shading normal.
/// Reciprocal, so both transport modes are the same.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    pub ks: Rgb,
    pub distribution: TrowbridgeReitz,
}

impl Conductor {
    #[must_use]
    pub fn new(ks: Rgb, alpha: f32) -> Self {
        Self {
            ks,
            distribution: TrowbridgeReitz::new(alpha),
        }
    }

    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        let d = &self.distribution;
        if d.effectively_smooth() || wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let m = (wo + wi).normalize_or_zero();
        if m == Vec3::ZERO {
            return Rgb::ZERO;
        }
        let f = self.ks * (d.d(m) * d.g_over_cosines(wo, wi) * 0.25);
        // Finite for every pair whose cosines are representable; 0 rather than an overflow.
        if crate::math::is_finite(f) {
            f
        } else {
            Rgb::ZERO
        }
    }

    #[inline]
    #[must_use]
    pub fn sample(&self, wo: Vec3, _uc: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let d = &self.distribution;
        if d.effectively_smooth() {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample {
                wi,
                f: self.ks / wi.z,
                pdf: SolidAnglePdf(1.0),
                flags: BsdfFlags::SPECULAR_REFLECTION,
                eta: 1.0,
            });
        }
        let m = d.sample_visible_normal(wo, u);
        let wi = reflect(wo, m);
        if wi.z <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
            pdf: SolidAnglePdf(d.visible_normal_pdf(wo, m) / (4.0 * wo.dot(m))),
            flags: BsdfFlags::GLOSSY_REFLECTION,
            eta: 1.0,
        })
    }

    #[inline]
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> SolidAnglePdf {
        let d = &self.distribution;
        if d.effectively_smooth() || wo.z <= 0.0 || wi.z <= 0.0 {
            return SolidAnglePdf(0.0);
        }
        let m = (wo + wi).normalize_or_zero();
        if m == Vec3::ZERO {
            return SolidAnglePdf(0.0);
        }
        SolidAnglePdf(d.visible_normal_pdf(wo, m) / (4.0 * wo.dot(m)))
    }

    #[inline]
    #[must_use]
    pub fn flags(&self) -> BsdfFlags {
        if self.distribution.effectively_smooth() {
            BsdfFlags::SPECULAR_REFLECTION
        } else {
            BsdfFlags::GLOSSY_REFLECTION
        }
    }
}
