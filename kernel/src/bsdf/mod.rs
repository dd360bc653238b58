//! The closed set of BSDFs, dispatched by `match` (no vtables, storable in slices).
//!
//! Contract (pbrt-v4 conventions; FORMAT.md §4 for the TinyRender materials):
//! - Directions are in the local shading frame (z = shading normal) and both point away from
//!   the surface: `wo` toward the viewer / previous vertex, `wi` toward the light / next vertex.
//!   Mitsuba's `si.wi` is our `wo`.
//! - [`Bsdf::eval`] returns the BSDF value **f without the cosine** (TinyRender's `eval` folds
//!   cosθᵢ in; ember keeps it out so BDPT and light tracing can apply their own geometry terms).
//! - [`Bsdf::sample`] returns `f`, `wi` and the pdf of `wi` **per unit solid angle** for the
//!   whole BSDF (for a mixture: the mixture pdf, whatever lobe was picked), or `None` when the
//!   sample is degenerate (zero or non-finite pdf, zero f, `wi` below the surface).
//! - [`Bsdf::pdf`] agrees with `sample` for every direction `sample` can return.
//! - [`TransportMode`] is passed everywhere for adjoint transport; the reflection-only BSDFs
//!   here are symmetric and ignore it.
//! - [`BsdfFlags`] classify lobes; integrators skip next-event estimation on purely specular
//!   ones (none yet: mirror and dielectric will be the first).

mod diffuse;
mod phong;

pub use diffuse::Diffuse;
pub use phong::Phong;

use crate::math::SolidAnglePdf;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// Whether radiance (from the camera) or importance (from the lights) is being transported.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    Radiance,
    Importance,
}

/// Lobe classification bits (pbrt's `BxDFFlags`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct BsdfFlags(pub u8);

impl BsdfFlags {
    pub const REFLECTION: Self = Self(1);
    pub const TRANSMISSION: Self = Self(2);
    pub const DIFFUSE: Self = Self(4);
    pub const GLOSSY: Self = Self(8);
    pub const SPECULAR: Self = Self(16);

    #[inline]
    #[must_use]
    pub const fn union(self, o: Self) -> Self {
        Self(self.0 | o.0)
    }

    #[inline]
    #[must_use]
    pub const fn contains(self, o: Self) -> bool {
        self.0 & o.0 == o.0
    }

    /// True when some lobe can be evaluated for an arbitrary direction (next-event estimation
    /// and MIS apply).
    #[inline]
    #[must_use]
    pub const fn is_non_specular(self) -> bool {
        self.0 & (Self::DIFFUSE.0 | Self::GLOSSY.0) != 0
    }
}

/// A sampled direction with the BSDF value and its solid-angle pdf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// BSDF value for (wo, wi), without the cosine.
    pub f: Rgb,
    pub pdf: SolidAnglePdf,
    /// The lobe that produced the sample.
    pub flags: BsdfFlags,
}

impl BsdfSample {
    /// The Monte Carlo throughput weight f·|cosθᵢ|/pdf.
    #[inline]
    #[must_use]
    pub fn weight(&self) -> Rgb {
        self.f * (self.wi.z.abs() / self.pdf.0)
    }
}

/// Every BSDF ember knows. `illum 7` → `Diffuse`, `illum 8` → `Mixture`, any other `illum` →
/// `Phong` (FORMAT.md §4).
///
/// `Phong` and `Mixture` have the same parameters and the same `eval` (FORMAT.md §4.3–4.4) and
/// the same sampling: the Phong lobe with probability `w_s`, the cosine lobe otherwise. The
/// TinyRender A4 Phong sampled the glossy lobe only, which is biased wherever `Kd > 0` and the
/// lobe pdf is 0; for `Kd = 0` (the A4 Phong scenes) `w_s = 1` and the two coincide. They stay
/// two variants because their lobe flags differ for a pure glossy Phong and scenes name them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    Diffuse(Diffuse),
    Phong(Phong),
    Mixture(Phong),
}

impl Bsdf {
    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        match self {
            Self::Diffuse(b) => b.eval(wo, wi, mode),
            Self::Phong(b) | Self::Mixture(b) => b.eval(wo, wi, mode),
        }
    }

    /// Samples `wi` for `wo` from two uniform numbers in `[0, 1)`.
    #[inline]
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let s = match self {
            Self::Diffuse(b) => b.sample(wo, u, mode),
            Self::Phong(b) | Self::Mixture(b) => b.sample(wo, u, mode),
        }?;
        // One place rejects degenerate samples for every variant (pbrt's BSDF wrapper).
        let valid = s.pdf.0 > 0.0
            && s.pdf.0.is_finite()
            && s.wi.z != 0.0
            && crate::math::is_finite(s.f)
            && s.f != Vec3::ZERO;
        valid.then_some(s)
    }

    #[inline]
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> SolidAnglePdf {
        match self {
            Self::Diffuse(b) => b.pdf(wo, wi, mode),
            Self::Phong(b) | Self::Mixture(b) => b.pdf(wo, wi, mode),
        }
    }

    #[inline]
    #[must_use]
    pub fn flags(&self) -> BsdfFlags {
        match self {
            Self::Diffuse(b) => b.flags(),
            Self::Phong(b) | Self::Mixture(b) => b.flags(),
        }
    }

    /// Hemispherical reflectance bound for diffuse-only estimates (the GI bake): `Kd` for
    /// diffuse, `scale·Kd` for the Phong family.
    #[inline]
    #[must_use]
    pub fn diffuse_reflectance(&self) -> Rgb {
        match self {
            Self::Diffuse(b) => b.kd,
            Self::Phong(b) | Self::Mixture(b) => b.kd * b.scale,
        }
    }
}
