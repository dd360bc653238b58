use super::{BsdfFlags, BsdfSample, TransportMode};
use crate::math::{luminance, reflect_local, warp, Frame, SolidAnglePdf, INV_2PI, INV_PI};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// TinyRender's modified Phong (FORMAT.md §4.3–4.4):
/// `f = scale·(Kd/π + Ks·(n+2)/(2π)·max(0, cos α)ⁿ)` with `cos α = reflect(wo)·wi`.
/// Sampled as a mixture: the cosine-power lobe about `reflect(wo)` with probability `w_s`, the
/// cosine hemisphere otherwise; the pdf is always the whole mixture pdf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phong {
    pub kd: Rgb,
    pub ks: Rgb,
    /// Phong exponent `Ns`.
    pub exponent: f32,
    /// Energy clamp: `0.99 / M` when the largest component `M` of `Kd + Ks` exceeds 1.
    pub scale: f32,
    /// Probability of sampling the glossy lobe, `Ls / (Ld + Ls)` on luminances of the scaled
    /// reflectances.
    pub specular_weight: f32,
}

impl Phong {
    /// `kd`, `ks` and `exponent` as read from the MTL. Negative exponents are treated as 0.
    #[must_use]
    pub fn new(kd: Rgb, ks: Rgb, exponent: f32) -> Self {
        let (scale, specular_weight) = Self::weights(kd, ks, kd, ks);
        Self::with_weights(kd, ks, exponent, scale, specular_weight)
    }

    /// The energy clamp `scale` and the glossy sampling weight `w_s` of a Phong material whose
    /// reflectances are textures, from their per-channel maxima and averages (TinyRender's
    /// `getMax`/`getAverage`; for constants, maximum and average are the colour itself):
    /// `scale = 0.99 / M` when `M = max component of (max Kd + max Ks)` exceeds 1, and
    /// `w_s = Ls / (Ld + Ls)` with `L = luminance(average · scale)`.
    #[must_use]
    pub fn weights(kd_max: Rgb, ks_max: Rgb, kd_avg: Rgb, ks_avg: Rgb) -> (f32, f32) {
        let m = (kd_max + ks_max).max_element();
        let scale = if m > 1.0 { 0.99 / m } else { 1.0 };
        let ld = luminance(kd_avg * scale);
        let ls = luminance(ks_avg * scale);
        // Kd = Ks = 0 gives 0/0 in TinyRender; such a BSDF reflects nothing, any weight works.
        let specular_weight = if ld + ls > 0.0 { ls / (ld + ls) } else { 0.0 };
        (scale, specular_weight)
    }

    /// A Phong BSDF with precomputed [`Self::weights`] (the reflectances at one surface point
    /// of a textured material).
    #[must_use]
    pub fn with_weights(kd: Rgb, ks: Rgb, exponent: f32, scale: f32, specular_weight: f32) -> Self {
        Self {
            kd,
            ks,
            exponent: exponent.max(0.0),
            scale,
            specular_weight,
        }
    }

    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let cos_alpha = reflect_local(wo).dot(wi);
        let power = if self.has_lobe() {
            self.lobe_power(cos_alpha)
        } else {
            0.0
        };
        self.eval_with(cos_alpha, power)
    }

    /// [`Self::eval`] and [`Self::pdf`] with one `powf` for both (the value each would
    /// compute: the same function of the same `cos α`, so the results are theirs bit for bit).
    #[inline]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> (Rgb, SolidAnglePdf) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, SolidAnglePdf(0.0));
        }
        let cos_alpha = reflect_local(wo).dot(wi);
        // The power is needed for f where there is a lobe, for the pdf where it is sampled
        // (a texel of Ks may be black where the lobe's average weight is not).
        let power = if self.has_lobe() || self.specular_weight > 0.0 {
            self.lobe_power(cos_alpha)
        } else {
            0.0
        };
        (
            self.eval_with(cos_alpha, power),
            self.pdf_with(wi, cos_alpha, power),
        )
    }

    /// Whether the glossy lobe adds to f. A zero `Ks` (TinyRender's `cbox.mtl` gives its right
    /// wall a mixture with `Ks 0`) adds exactly zero (`f + 0·lobe = f`: the lobe is finite for
    /// `cos α ≤ 1` and a finite exponent), so its `powf` is skipped: 3% of a `cbox.obj` render.
    #[inline]
    fn has_lobe(&self) -> bool {
        self.ks != Rgb::ZERO
    }

    /// Whether this is Lambertian reflection with reflectance `kd`: no lobe (`Ks = 0`), never
    /// sampled (`w_s = 0`) and no energy clamp (`scale = 1`), as TinyRender's `cbox.mtl` gives
    /// its right wall. Its `eval`, `pdf` and `sample` are then [`super::Diffuse`]'s bit for bit
    /// (`x·1 = x`, `(1 − 0)·cosθ = cosθ`), except that its pdf is NaN, not 0, for a NaN
    /// direction: what lets the batched path tracer run it in the diffuse lanes.
    #[inline]
    #[must_use]
    pub fn is_lambertian(&self) -> bool {
        !self.has_lobe() && self.specular_weight == 0.0 && self.scale == 1.0
    }

    /// `max(0, cos α)ⁿ`, 0 where `cos α ≤ 0`.
    #[inline]
    fn lobe_power(&self, cos_alpha: f32) -> f32 {
        if cos_alpha > 0.0 {
            libm::powf(cos_alpha, self.exponent)
        } else {
            0.0
        }
    }

    /// The BSDF value for `wo`, `wi` above the surface, given `cos α` and its power.
    #[inline]
    fn eval_with(&self, cos_alpha: f32, power: f32) -> Rgb {
        let mut f = self.kd * INV_PI;
        if cos_alpha > 0.0 && self.has_lobe() {
            let lobe = (self.exponent + 2.0) * INV_2PI * power;
            f += self.ks * lobe;
        }
        f * self.scale
    }

    /// The mixture pdf for `wi` above the surface, given `cos α` and its power.
    #[inline]
    fn pdf_with(&self, wi: Vec3, cos_alpha: f32, power: f32) -> SolidAnglePdf {
        let ws = self.specular_weight;
        let mut pdf = (1.0 - ws) * wi.z * INV_PI;
        if ws > 0.0 {
            pdf += ws * warp::phong_lobe_pdf_of_power(cos_alpha, power, self.exponent);
        }
        SolidAnglePdf(pdf)
    }

    /// Whether [`Self::sample`]'s lobe depends on `uc`: not where the choice `uc < w_s` is
    /// fixed, with `w_s = 0` (`Ks = 0`, the cbox right wall: never the lobe) or `w_s = 1`
    /// (`Kd = 0`, the veach plates: always, for every `uc` in [0, 1), 0 included).
    #[inline]
    #[must_use]
    pub fn uses_lobe_choice(&self) -> bool {
        self.specular_weight > 0.0 && self.specular_weight < 1.0
    }

    #[inline]
    #[must_use]
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        // `uc` picks the lobe, `u` the direction within it.
        let (wi, flags) = if uc < self.specular_weight {
            let local = warp::sample_phong_lobe(u, self.exponent);
            let frame = Frame::from_normal(reflect_local(wo));
            (frame.to_world(local), BsdfFlags::GLOSSY_REFLECTION)
        } else {
            (
                warp::sample_cosine_hemisphere(u),
                BsdfFlags::DIFFUSE_REFLECTION,
            )
        };
        if wi.z <= 0.0 {
            return None;
        }
        let (f, pdf) = self.eval_pdf(wo, wi, mode);
        Some(BsdfSample {
            wi,
            f,
            pdf,
            flags,
            eta: 1.0,
        })
    }

    #[inline]
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> SolidAnglePdf {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return SolidAnglePdf(0.0);
        }
        if self.specular_weight <= 0.0 {
            // The cosine lobe alone: no power needed.
            return self.pdf_with(wi, 0.0, 0.0);
        }
        let cos_alpha = reflect_local(wo).dot(wi);
        self.pdf_with(wi, cos_alpha, self.lobe_power(cos_alpha))
    }

    #[inline]
    #[must_use]
    pub fn flags(&self) -> BsdfFlags {
        let mut f = BsdfFlags::NONE;
        if self.specular_weight > 0.0 {
            f = f.union(BsdfFlags::GLOSSY_REFLECTION);
        }
        if self.specular_weight < 1.0 {
            f = f.union(BsdfFlags::DIFFUSE_REFLECTION);
        }
        f
    }
}
