use super::fresnel::{fresnel_dielectric, reflect, refract};
use super::microfacet::TrowbridgeReitz;
use super::{BsdfFlags, BsdfSample, TransportMode};
use crate::math::SolidAnglePdf;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// Glass (`illum 6`): a boundary between the outside (the side the shading normal points to)
/// and a medium of relative index of refraction `eta` (MTL `Ni`), with the exact unpolarised
/// Fresnel equations and total internal reflection. Transmission is tinted by `tf` (MTL
/// `Tf`). Smooth when the distribution is effectively smooth (delta reflection and refraction,
/// chosen in proportion to their Fresnel weights, as pbrt-v4's `DielectricBxDF`); otherwise
/// the rough dielectric of Walter et al. (2007) with Trowbridge–Reitz microfacets, sampled by
/// visible normals.
///
/// Radiance crossing the boundary is scaled by `1/η′²` (η′ the relative IOR of the crossing)
/// in radiance transport only; importance is not scaled (Veach 1997, §5.2). The sample reports
/// η′ so that integrators can undo that scaling in their Russian roulette.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    pub eta: f32,
    pub tf: Rgb,
    pub distribution: TrowbridgeReitz,
}

/// `(pr, pt)`: the probabilities of choosing reflection and transmission, the Fresnel weights.
#[inline]
fn lobe_probabilities(r: f32) -> (f32, f32) {
    (r, 1.0 - r)
}

impl Dielectric {
    #[must_use]
    pub fn new(eta: f32, tf: Rgb, alpha: f32) -> Self {
        Self {
            eta,
            tf,
            distribution: TrowbridgeReitz::new(alpha),
        }
    }

    /// Whether the boundary scatters only into discrete directions. An index-matched boundary
    /// (`eta == 1`) does not bend light at any roughness: it is a delta transmission.
    #[inline]
    #[must_use]
    pub fn is_specular(&self) -> bool {
        self.eta == 1.0 || self.distribution.effectively_smooth()
    }

    /// The generalised half vector of a rough interaction, facing +z, with the relative IOR
    /// of the crossing (1 for reflection); `None` where the BSDF is zero by geometry
    /// (grazing directions, back-facing microfacets).
    #[inline]
    fn half_vector(&self, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
        let (co, ci) = (wo.z, wi.z);
        if co == 0.0 || ci == 0.0 {
            return None;
        }
        // Signs, not the product, which underflows to 0 for grazing pairs (and then made a
        // reflection pair take the transmission formula).
        let reflect = (co > 0.0) == (ci > 0.0);
        let etap = if reflect {
            1.0
        } else if co > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let m = (wi * etap + wo).normalize_or_zero();
        if m == Vec3::ZERO {
            return None;
        }
        let m = if m.z < 0.0 { -m } else { m };
        if m.dot(wi) * ci < 0.0 || m.dot(wo) * co < 0.0 {
            return None;
        }
        Some((m, etap, reflect))
    }

    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        if self.is_specular() {
            return Rgb::ZERO;
        }
        let Some((m, etap, reflect)) = self.half_vector(wo, wi) else {
            return Rgb::ZERO;
        };
        let r = fresnel_dielectric(wo.dot(m), self.eta);
        let f = if reflect {
            Rgb::splat(self.reflection(wo, wi, m, r))
        } else {
            self.tf * self.transmission(wo, wi, m, etap, r, mode)
        };
        // Finite for every pair whose cosines are representable; 0 rather than an overflow.
        if crate::math::is_finite(f) {
            f
        } else {
            Rgb::ZERO
        }
    }

    /// f of the reflection through the microfacet normal `m` with Fresnel reflectance `r`:
    /// D(m) G(wo, wi) r / (4 |cosθₒ cosθᵢ|).
    #[inline]
    fn reflection(&self, wo: Vec3, wi: Vec3, m: Vec3, r: f32) -> f32 {
        let d = &self.distribution;
        d.d(m) * d.g_over_cosines(wo, wi) * r * 0.25
    }

    /// f of the transmission through `m` (before the tint), Walter et al. (2007) eq. 21:
    /// D(m) G(wo, wi) (1 − r) |wi·m| |wo·m| / (|cosθₒ cosθᵢ| (wi·m + wo·m/η′)²), divided by
    /// η′² in radiance transport.
    #[inline]
    fn transmission(
        &self,
        wo: Vec3,
        wi: Vec3,
        m: Vec3,
        etap: f32,
        r: f32,
        mode: TransportMode,
    ) -> f32 {
        let d = &self.distribution;
        let denom = wi.dot(m) + wo.dot(m) / etap;
        let mut ft = d.d(m)
            * (1.0 - r)
            * d.g_over_cosines(wo, wi)
            * (wi.dot(m) * wo.dot(m) / (denom * denom)).abs();
        if mode == TransportMode::Radiance {
            ft /= etap * etap;
        }
        ft
    }

    #[inline]
    #[must_use]
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        if self.is_specular() {
            return self.sample_specular(wo, uc, mode);
        }
        let d = &self.distribution;
        let m = d.sample_visible_normal(wo, u);
        let r = fresnel_dielectric(wo.dot(m), self.eta);
        let (pr, pt) = lobe_probabilities(r);
        let pdf_m = d.visible_normal_pdf(wo, m);
        if uc < pr / (pr + pt) {
            let wi = reflect(wo, m);
            if wi.z == 0.0 || (wi.z > 0.0) != (wo.z > 0.0) {
                return None;
            }
            let pdf = pdf_m / (4.0 * wo.dot(m).abs()) * pr / (pr + pt);
            return Some(BsdfSample {
                wi,
                f: Rgb::splat(self.reflection(wo, wi, m, r)),
                pdf: SolidAnglePdf(pdf),
                flags: BsdfFlags::GLOSSY_REFLECTION,
                eta: 1.0,
            });
        }
        let (wi, etap) = refract(wo, m, self.eta)?;
        if wi.z == 0.0 || (wi.z > 0.0) == (wo.z > 0.0) {
            return None;
        }
        let denom = wi.dot(m) + wo.dot(m) / etap;
        let pdf = pdf_m * (wi.dot(m).abs() / (denom * denom)) * pt / (pr + pt);
        Some(BsdfSample {
            wi,
            f: self.tf * self.transmission(wo, wi, m, etap, r, mode),
            pdf: SolidAnglePdf(pdf),
            flags: BsdfFlags::GLOSSY_TRANSMISSION,
            eta: etap,
        })
    }

    /// Delta reflection with probability F, refraction otherwise (total internal reflection:
    /// F = 1). The "pdf" of a delta sample is the probability of its lobe.
    #[inline]
    fn sample_specular(&self, wo: Vec3, uc: f32, mode: TransportMode) -> Option<BsdfSample> {
        let r = fresnel_dielectric(wo.z, self.eta);
        let (pr, pt) = lobe_probabilities(r);
        if uc < pr / (pr + pt) {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample {
                wi,
                f: Rgb::splat(r / wi.z.abs()),
                pdf: SolidAnglePdf(pr / (pr + pt)),
                flags: BsdfFlags::SPECULAR_REFLECTION,
                eta: 1.0,
            });
        }
        let (wi, etap) = refract(wo, Vec3::Z, self.eta)?;
        let mut ft = (1.0 - r) / wi.z.abs();
        if mode == TransportMode::Radiance {
            ft /= etap * etap;
        }
        Some(BsdfSample {
            wi,
            f: self.tf * ft,
            pdf: SolidAnglePdf(pt / (pr + pt)),
            flags: BsdfFlags::SPECULAR_TRANSMISSION,
            eta: etap,
        })
    }

    #[inline]
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> SolidAnglePdf {
        if self.is_specular() {
            return SolidAnglePdf(0.0);
        }
        let Some((m, etap, reflect)) = self.half_vector(wo, wi) else {
            return SolidAnglePdf(0.0);
        };
        let d = &self.distribution;
        let r = fresnel_dielectric(wo.dot(m), self.eta);
        let (pr, pt) = lobe_probabilities(r);
        let pdf_m = d.visible_normal_pdf(wo, m);
        let pdf = if reflect {
            pdf_m / (4.0 * wo.dot(m).abs()) * pr / (pr + pt)
        } else {
            let denom = wi.dot(m) + wo.dot(m) / etap;
            pdf_m * (wi.dot(m).abs() / (denom * denom)) * pt / (pr + pt)
        };
        SolidAnglePdf(pdf)
    }

    #[inline]
    #[must_use]
    pub fn flags(&self) -> BsdfFlags {
        if self.is_specular() {
            BsdfFlags::SPECULAR_REFLECTION.union(BsdfFlags::SPECULAR_TRANSMISSION)
        } else {
            BsdfFlags::GLOSSY_REFLECTION.union(BsdfFlags::GLOSSY_TRANSMISSION)
        }
    }
}
