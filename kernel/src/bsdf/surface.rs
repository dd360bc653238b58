//! [`SurfaceBsdf`]: a [`Bsdf`] at a surface point, in world space (pbrt-v4's `BSDF` class).
//! Integrators use BSDFs only through it, so none of them converts frames, tests sides or
//! corrects for shading normals itself.

use super::{Bsdf, BsdfFlags, TransportMode};
use crate::math::{Frame, SolidAnglePdf};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// A BSDF with the shading frame and the geometric normal of the point it is at.
///
/// - **Frames.** Directions in and out are world-space unit vectors, converted to the local
///   shading frame for the [`Bsdf`] and back.
/// - **Sides.** A pair of directions scatters only when the shading frame and the geometric
///   normal agree on whether it is a reflection (both on one side) or a transmission: where
///   an interpolated normal tilts a direction across the true surface, `eval`, `pdf` and
///   `sample` give nothing instead of letting light leak through the surface (pbrt-v3's
///   `BSDF::f` rule and Mitsuba's light-leak guard, here in both transport modes so that
///   paths traced from either end see the same scattering). Which side is the front is the
///   BSDF's business: opaque BSDFs are one-sided (TinyRender's convention), glass two-sided.
/// - **Adjoint shading normals.** In [`TransportMode::Importance`] the BSDF is multiplied by
///   `|wo·n_s| |wi·n_g| / (|wo·n_g| |wi·n_s|)` (Veach 1997, §5.3, eq. 5.19), the correction
///   that makes light paths carry the same contribution as camera paths when shading normals
///   differ from geometric ones. pbrt-v4 omits it (its issues #385, #526). With it, for every
///   pair of directions `a`, `b` and every BSDF, glass included:
///   `f_imp(a, b)·|b·n_s|/|b·n_g| = f_rad(b, a)·|a·n_s|/|a·n_g|`. There is no η′² factor
///   across glass: importance mode is the adjoint of radiance mode in the local frame,
///   `f_imp(a, b) = f_rad(b, a)`; it is `f_rad(a, b)` and `f_rad(b, a)` that differ by η′²
///   (f(wo, wi)/η_o² = f(wi, wo)/η_i², η_o and η_i the indices of the media wo and wi are in).
///   Tested in `kernel/tests/bsdf.rs`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceBsdf {
    pub bsdf: Bsdf,
    /// Shading frame (z = interpolated normal).
    pub frame: Frame,
    /// Unit geometric normal.
    pub ng: Vec3,
}

/// A sampled scattering direction in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scatter {
    /// World-space direction of the next vertex.
    pub wi: Vec3,
    /// BSDF value in the sampled transport mode (delta lobes: weight / |cosθᵢ|).
    pub f: Rgb,
    /// Solid-angle density of `wi` (delta lobes: the probability of the lobe).
    pub pdf: SolidAnglePdf,
    pub flags: BsdfFlags,
    /// Relative index of refraction of a transmission, 1 for reflection.
    pub eta: f32,
    /// Throughput weight `f·|wi·n_s|/pdf`.
    pub weight: Rgb,
}

impl SurfaceBsdf {
    #[inline]
    #[must_use]
    pub fn new(bsdf: Bsdf, frame: Frame, ng: Vec3) -> Self {
        Self { bsdf, frame, ng }
    }

    #[inline]
    #[must_use]
    pub fn flags(&self) -> BsdfFlags {
        self.bsdf.flags()
    }

    /// Whether sampling reads the lobe-choice number ([`Bsdf::uses_lobe_choice`]).
    #[inline]
    #[must_use]
    pub fn uses_lobe_choice(&self) -> bool {
        self.bsdf.uses_lobe_choice()
    }

    /// `|w·n_s|`, the cosine of a world direction with the shading normal.
    #[inline]
    #[must_use]
    pub fn abs_cos(&self, w: Vec3) -> f32 {
        w.dot(self.frame.n).abs()
    }

    /// The BSDF seen from the world direction `wo`: `wo` converted once for several queries
    /// (a path vertex evaluates, weights and samples with the same `wo`).
    #[inline]
    #[must_use]
    pub fn seen_from(&self, wo: Vec3) -> BsdfView<'_> {
        BsdfView {
            surface: self,
            wo,
            wo_l: self.frame.to_local(wo),
            wo_ng: wo.dot(self.ng),
        }
    }

    /// The BSDF value for world directions `wo`, `wi` (0 for delta lobes).
    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        self.seen_from(wo).eval(wi, mode)
    }

    /// The solid-angle density with which [`Self::sample`] returns `wi` (0 for delta lobes).
    #[inline]
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> SolidAnglePdf {
        self.seen_from(wo).pdf(wi, mode)
    }

    /// Samples the direction of the next vertex for world direction `wo` ([`Bsdf::sample`]).
    #[inline]
    #[must_use]
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2, mode: TransportMode) -> Option<Scatter> {
        self.seen_from(wo).sample(uc, u, mode)
    }
}

/// A [`SurfaceBsdf`] with its outgoing direction fixed ([`SurfaceBsdf::seen_from`]).
#[derive(Clone, Copy, Debug)]
pub struct BsdfView<'a> {
    pub surface: &'a SurfaceBsdf,
    /// The world direction toward the viewer / previous vertex.
    pub wo: Vec3,
    wo_l: Vec3,
    wo_ng: f32,
}

impl BsdfView<'_> {
    /// Whether the geometric and the shading normal agree on the sides of `wo` and `wi`
    /// (false also where either is on the horizon or a product underflows).
    #[inline]
    fn sides_agree(&self, wi_ng: f32, wi_l: Vec3) -> bool {
        (self.wo_ng * wi_ng) * (self.wo_l.z * wi_l.z) > 0.0
    }

    /// The adjoint shading-normal factor (1 in radiance transport).
    #[inline]
    fn correction(&self, mode: TransportMode, wi_ng: f32, wi_l: Vec3) -> f32 {
        match mode {
            TransportMode::Radiance => 1.0,
            TransportMode::Importance => {
                let num = self.wo_l.z.abs() * wi_ng.abs();
                let den = self.wo_ng.abs() * wi_l.z.abs();
                if den > 0.0 {
                    num / den
                } else {
                    0.0
                }
            }
        }
    }

    /// `|w·n_s|`, the cosine of a world direction with the shading normal.
    #[inline]
    #[must_use]
    pub fn abs_cos(&self, w: Vec3) -> f32 {
        self.surface.abs_cos(w)
    }

    #[inline]
    #[must_use]
    pub fn flags(&self) -> BsdfFlags {
        self.surface.flags()
    }

    /// The BSDF value toward world direction `wi` (0 for delta lobes).
    #[inline]
    #[must_use]
    pub fn eval(&self, wi: Vec3, mode: TransportMode) -> Rgb {
        let (wi_l, wi_ng) = (self.surface.frame.to_local(wi), wi.dot(self.surface.ng));
        if !self.sides_agree(wi_ng, wi_l) {
            return Rgb::ZERO;
        }
        self.surface.bsdf.eval(self.wo_l, wi_l, mode) * self.correction(mode, wi_ng, wi_l)
    }

    /// [`Self::eval`] and [`Self::pdf`] together, sharing the frame conversion (Mitsuba's
    /// `eval_pdf`): what next-event estimation with MIS needs.
    #[inline]
    #[must_use]
    pub fn eval_pdf(&self, wi: Vec3, mode: TransportMode) -> (Rgb, SolidAnglePdf) {
        let (wi_l, wi_ng) = (self.surface.frame.to_local(wi), wi.dot(self.surface.ng));
        if !self.sides_agree(wi_ng, wi_l) {
            return (Rgb::ZERO, SolidAnglePdf(0.0));
        }
        let (f, pdf) = self.surface.bsdf.eval_pdf(self.wo_l, wi_l, mode);
        (f * self.correction(mode, wi_ng, wi_l), pdf)
    }

    /// The solid-angle density with which [`Self::sample`] returns `wi` (0 for delta lobes).
    #[inline]
    #[must_use]
    pub fn pdf(&self, wi: Vec3, mode: TransportMode) -> SolidAnglePdf {
        let (wi_l, wi_ng) = (self.surface.frame.to_local(wi), wi.dot(self.surface.ng));
        if !self.sides_agree(wi_ng, wi_l) {
            return SolidAnglePdf(0.0);
        }
        self.surface.bsdf.pdf(self.wo_l, wi_l, mode)
    }

    /// Samples the direction of the next vertex ([`Bsdf::sample`]). Always inlined, so that
    /// the transport mode, a constant at every call, folds away.
    #[inline(always)]
    #[must_use]
    pub fn sample(&self, uc: f32, u: Vec2, mode: TransportMode) -> Option<Scatter> {
        let s = self.surface.bsdf.sample(self.wo_l, uc, u, mode)?;
        let wi = self.surface.frame.to_world(s.wi);
        let wi_ng = wi.dot(self.surface.ng);
        if !self.sides_agree(wi_ng, s.wi) {
            return None;
        }
        let f = s.f * self.correction(mode, wi_ng, s.wi);
        let weight = f * (s.wi.z.abs() / s.pdf.0);
        // The cosine over the pdf can still overflow, and in importance transport the
        // correction vanish (`Bsdf::sample` has refused zero and non-finite f and pdf).
        let vanished = mode == TransportMode::Importance && weight == Rgb::ZERO;
        if !crate::math::is_finite(weight) || vanished {
            return None;
        }
        Some(Scatter {
            wi,
            f,
            pdf: s.pdf,
            flags: s.flags,
            eta: s.eta,
            weight,
        })
    }
}
