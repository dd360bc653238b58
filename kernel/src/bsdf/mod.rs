//! The closed set of BSDFs, dispatched by `match` (no vtables, storable in slices), and
//! [`SurfaceBsdf`], the wrapper through which integrators use them.
//!
//! Contract of [`Bsdf`] (pbrt-v4's `BxDF`; FORMAT.md §4 for the TinyRender materials):
//! - Directions are in the local shading frame (z = shading normal) and both point away from
//!   the surface: `wo` toward the viewer / previous vertex, `wi` toward the light / next vertex.
//!   Mitsuba's `si.wi` is our `wo`. A direction below the surface (z < 0) is inside a
//!   transmissive material or behind an opaque one.
//! - [`Bsdf::eval`] returns the BSDF value **f without the cosine** (TinyRender's `eval` folds
//!   cosθᵢ in; ember keeps it out so BDPT and light tracing can apply their own geometry terms).
//!   Delta lobes contribute nothing to `eval` for any pair of directions.
//! - [`Bsdf::sample`]`(wo, uc, u, mode)` picks a lobe with the 1D number `uc` and a direction
//!   in it with the 2D number `u` (pbrt-v4's `Sample_f`). It returns `f`, `wi`, the pdf of `wi`
//!   **per unit solid angle** for the whole BSDF (for a mixture: the mixture pdf, whatever lobe
//!   was picked), the flags of the lobe sampled and `eta`, the relative index of refraction of
//!   a transmission (1 otherwise); or `None` when the sample is degenerate (zero or non-finite
//!   pdf, zero f, `wi` on the horizon). For a delta lobe `f` holds the lobe's weight divided by
//!   |cosθᵢ| and `pdf` the probability of choosing that lobe, so [`BsdfSample::weight`] is right
//!   for both kinds.
//! - [`Bsdf::pdf`] agrees with `sample` for every direction `sample` can return from a
//!   non-delta lobe, and is 0 for delta lobes.
//! - [`TransportMode`]: radiance is scaled by 1/η′² where it crosses a dielectric boundary;
//!   importance is not. The other BSDFs are reciprocal and ignore the mode. The shading-normal
//!   correction of importance transport is applied by [`SurfaceBsdf`], which knows both normals.
//! - [`BsdfFlags`] classify lobes; integrators skip next-event estimation where no lobe can be
//!   evaluated ([`BsdfFlags::is_non_specular`]).

mod conductor;
mod dielectric;
mod diffuse;
pub mod fresnel;
pub mod microfacet;
mod phong;
mod surface;

pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use phong::Phong;
pub use surface::{BsdfView, Scatter, SurfaceBsdf};

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
    pub const NONE: Self = Self(0);
    pub const REFLECTION: Self = Self(1);
    pub const TRANSMISSION: Self = Self(2);
    pub const DIFFUSE: Self = Self(4);
    pub const GLOSSY: Self = Self(8);
    pub const SPECULAR: Self = Self(16);
    pub const DIFFUSE_REFLECTION: Self = Self::DIFFUSE.union(Self::REFLECTION);
    pub const GLOSSY_REFLECTION: Self = Self::GLOSSY.union(Self::REFLECTION);
    pub const GLOSSY_TRANSMISSION: Self = Self::GLOSSY.union(Self::TRANSMISSION);
    pub const SPECULAR_REFLECTION: Self = Self::SPECULAR.union(Self::REFLECTION);
    pub const SPECULAR_TRANSMISSION: Self = Self::SPECULAR.union(Self::TRANSMISSION);

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

    /// True for a sample of a delta lobe.
    #[inline]
    #[must_use]
    pub const fn is_specular(self) -> bool {
        self.0 & Self::SPECULAR.0 != 0
    }

    #[inline]
    #[must_use]
    pub const fn is_transmission(self) -> bool {
        self.0 & Self::TRANSMISSION.0 != 0
    }
}

/// A sampled direction with the BSDF value and its pdf, in the local shading frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// BSDF value for (wo, wi), without the cosine (for a delta lobe: weight / |cosθᵢ|).
    pub f: Rgb,
    /// Solid-angle density (for a delta lobe: the probability of its lobe).
    pub pdf: SolidAnglePdf,
    /// The lobe that produced the sample.
    pub flags: BsdfFlags,
    /// Relative index of refraction η′ of a transmission (1 for reflection).
    pub eta: f32,
}

impl BsdfSample {
    /// The Monte Carlo throughput weight f·|cosθᵢ|/pdf.
    #[inline]
    #[must_use]
    pub fn weight(&self) -> Rgb {
        self.f * (self.wi.z.abs() / self.pdf.0)
    }
}

/// Every BSDF ember knows (the MTL mapping is in `crate::material` and the README):
/// `Diffuse` (`illum 7`), `Mixture` (`illum 8`), `Phong` (other `illum` values),
/// `Conductor` (`illum 5`), `Dielectric` (`illum 6`).
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
    Conductor(Conductor),
    Dielectric(Dielectric),
}

impl Bsdf {
    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        match self {
            Self::Diffuse(b) => b.eval(wo, wi, mode),
            Self::Phong(b) | Self::Mixture(b) => b.eval(wo, wi, mode),
            Self::Conductor(b) => b.eval(wo, wi, mode),
            Self::Dielectric(b) => b.eval(wo, wi, mode),
        }
    }

    /// Samples `wi` for `wo`: `uc` in `[0, 1)` chooses the lobe, `u` in `[0, 1)²` the direction.
    /// (Always inlined into the path loops, where the inliner left it out.)
    #[inline(always)]
    #[must_use]
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let s = match self {
            Self::Diffuse(b) => b.sample(wo, uc, u, mode),
            Self::Phong(b) | Self::Mixture(b) => b.sample(wo, uc, u, mode),
            Self::Conductor(b) => b.sample(wo, uc, u, mode),
            Self::Dielectric(b) => b.sample(wo, uc, u, mode),
        }?;
        // One place rejects degenerate samples for every variant (pbrt's BSDF wrapper).
        let valid = s.pdf.0 > 0.0
            && s.pdf.0.is_finite()
            && s.wi.z != 0.0
            && crate::math::is_finite(s.f)
            && s.f != Vec3::ZERO;
        valid.then_some(s)
    }

    /// [`Self::eval`] and [`Self::pdf`] together, bit for bit theirs; Phong computes its
    /// lobe's power once for both.
    #[inline]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> (Rgb, SolidAnglePdf) {
        match self {
            Self::Phong(b) | Self::Mixture(b) => b.eval_pdf(wo, wi, mode),
            _ => (self.eval(wo, wi, mode), self.pdf(wo, wi, mode)),
        }
    }

    #[inline]
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> SolidAnglePdf {
        match self {
            Self::Diffuse(b) => b.pdf(wo, wi, mode),
            Self::Phong(b) | Self::Mixture(b) => b.pdf(wo, wi, mode),
            Self::Conductor(b) => b.pdf(wo, wi, mode),
            Self::Dielectric(b) => b.pdf(wo, wi, mode),
        }
    }

    /// Whether [`Self::sample`] reads its lobe-choice number `uc`: Phong and mixture (glossy
    /// or diffuse lobe) and dielectrics (reflection or transmission) do; diffuse and conductor
    /// BSDFs have one lobe and ignore it, so the path loop does not draw it for them (and
    /// passes 0), nor for a Phong whose choice is fixed ([`Phong::uses_lobe_choice`]).
    #[inline]
    #[must_use]
    pub fn uses_lobe_choice(&self) -> bool {
        match self {
            Self::Phong(b) | Self::Mixture(b) => b.uses_lobe_choice(),
            Self::Dielectric(_) => true,
            Self::Diffuse(_) | Self::Conductor(_) => false,
        }
    }

    #[inline]
    #[must_use]
    pub fn flags(&self) -> BsdfFlags {
        match self {
            Self::Diffuse(b) => b.flags(),
            Self::Phong(b) | Self::Mixture(b) => b.flags(),
            Self::Conductor(b) => b.flags(),
            Self::Dielectric(b) => b.flags(),
        }
    }
}
