use super::{BsdfFlags, BsdfSample, TransportMode};
use crate::math::{warp, SolidAnglePdf, INV_PI};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// Lambertian reflection, `f = Kd/π` (`illum 7`), sampled with the cosine hemisphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diffuse {
    pub kd: Rgb,
}

impl Diffuse {
    #[must_use]
    pub fn new(kd: Rgb) -> Self {
        Self { kd }
    }

    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        self.kd * INV_PI
    }

    #[inline]
    #[must_use]
    pub fn sample(&self, wo: Vec3, _uc: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = warp::sample_cosine_hemisphere(u);
        Some(BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
            pdf: SolidAnglePdf(warp::cosine_hemisphere_pdf(wi.z)),
            flags: self.flags(),
            eta: 1.0,
        })
    }

    #[inline]
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> SolidAnglePdf {
        if wo.z <= 0.0 {
            return SolidAnglePdf(0.0);
        }
        SolidAnglePdf(warp::cosine_hemisphere_pdf(wi.z))
    }

    #[inline]
    #[must_use]
    pub fn flags(&self) -> BsdfFlags {
        BsdfFlags::DIFFUSE_REFLECTION
    }
}
