//! Materials: what a surface is made of, turned into a [`Bsdf`] at each surface point.
//!
//! A [`Material`] holds parameters, some of which may be textures; [`Material::bsdf`] reads
//! the texels at the point's texture coordinates and builds the BSDF there. Materials without
//! textures never compute texture coordinates.

use crate::bsdf::{Bsdf, Conductor, Dielectric, Diffuse, Phong};
use crate::texture::{texel_stats, Textures, NO_TEXTURE};
use crate::Rgb;
use glam::Vec2;

/// An RGB reflectance: a constant, or a texture when `texture` is not [`NO_TEXTURE`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reflectance {
    pub value: Rgb,
    pub texture: u32,
}

impl Reflectance {
    #[inline]
    #[must_use]
    pub const fn constant(value: Rgb) -> Self {
        Self {
            value,
            texture: NO_TEXTURE,
        }
    }

    #[inline]
    #[must_use]
    pub const fn texture(id: u32) -> Self {
        Self {
            value: Rgb::ZERO,
            texture: id,
        }
    }

    #[inline]
    #[must_use]
    pub const fn is_textured(&self) -> bool {
        self.texture != NO_TEXTURE
    }

    /// The reflectance at texture coordinates `uv` (computed only if textured).
    #[inline(always)]
    fn at<F: FnOnce() -> Vec2>(&self, textures: &Textures<'_>, uv: &mut Lazy<F>) -> Rgb {
        if self.is_textured() {
            textures.lookup(self.texture, uv.get())
        } else {
            self.value
        }
    }

    /// Per-channel maximum and average over the surface: the constant itself, or
    /// [`texel_stats`] of the texture's texels; `None` for a texture that `textures` does not
    /// hold ([`Textures::texels_of`]).
    #[must_use]
    pub fn stats(&self, textures: &Textures<'_>) -> Option<(Rgb, Rgb)> {
        if self.is_textured() {
            texel_stats(textures.texels_of(self.texture)?)
        } else {
            Some((self.value, self.value))
        }
    }
}

/// Texture coordinates computed on first use (only textured parameters need them).
struct Lazy<F> {
    f: Option<F>,
    v: Vec2,
}

impl<F: FnOnce() -> Vec2> Lazy<F> {
    #[inline]
    fn new(f: F) -> Self {
        Self {
            f: Some(f),
            v: Vec2::ZERO,
        }
    }

    #[inline]
    fn get(&mut self) -> Vec2 {
        if let Some(f) = self.f.take() {
            self.v = f();
        }
        self.v
    }
}

/// Parameters of the Phong family: reflectances, exponent, and the energy clamp and lobe
/// weight derived once from the reflectances' maxima and averages ([`Phong::weights`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhongParams {
    pub kd: Reflectance,
    pub ks: Reflectance,
    pub exponent: f32,
    pub scale: f32,
    pub specular_weight: f32,
}

/// The scattering model of a material and its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// Lambertian (`illum 7`).
    Diffuse { kd: Reflectance },
    /// TinyRender's modified Phong (`illum` other than 5–8).
    Phong(PhongParams),
    /// Diffuse + Phong mixture (`illum 8`).
    Mixture(PhongParams),
    /// Metal (`illum 5`): reflectance `Ks`, roughness `alpha` (0: a mirror).
    Conductor { ks: Reflectance, alpha: f32 },
    /// Glass (`illum 6`): relative IOR `eta`, transmission tint `tf`, roughness `alpha`.
    Dielectric { eta: f32, tf: Rgb, alpha: f32 },
}

/// A material: how it scatters and what it emits (`Ke`, one-sided, toward the side the shading
/// normal points to; FORMAT.md §5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub surface: Surface,
    pub emission: Rgb,
}

impl Material {
    /// A black, non-emissive diffuse material.
    pub const BLACK: Self = Self {
        surface: Surface::Diffuse {
            kd: Reflectance::constant(Rgb::ZERO),
        },
        emission: Rgb::ZERO,
    };

    #[must_use]
    pub fn diffuse(kd: Rgb) -> Self {
        Self::new(Surface::Diffuse {
            kd: Reflectance::constant(kd),
        })
    }

    #[must_use]
    pub fn phong(kd: Rgb, ks: Rgb, exponent: f32) -> Self {
        Self::new(Surface::Phong(PhongParams::constant(kd, ks, exponent)))
    }

    #[must_use]
    pub fn mixture(kd: Rgb, ks: Rgb, exponent: f32) -> Self {
        Self::new(Surface::Mixture(PhongParams::constant(kd, ks, exponent)))
    }

    #[must_use]
    pub fn conductor(ks: Rgb, alpha: f32) -> Self {
        Self::new(Surface::Conductor {
            ks: Reflectance::constant(ks),
            alpha,
        })
    }

    #[must_use]
    pub fn dielectric(eta: f32, tf: Rgb, alpha: f32) -> Self {
        Self::new(Surface::Dielectric { eta, tf, alpha })
    }

    /// A non-emissive material with this surface.
    #[must_use]
    pub const fn new(surface: Surface) -> Self {
        Self {
            surface,
            emission: Rgb::ZERO,
        }
    }

    #[must_use]
    pub fn with_emission(self, emission: Rgb) -> Self {
        Self { emission, ..self }
    }

    #[inline]
    #[must_use]
    pub fn is_emissive(&self) -> bool {
        self.emission != Rgb::ZERO
    }

    /// The texture ids the material reads ([`NO_TEXTURE`] where a parameter is constant).
    #[inline]
    #[must_use]
    pub fn texture_ids(&self) -> [u32; 2] {
        match self.surface {
            Surface::Diffuse { kd } => [kd.texture, NO_TEXTURE],
            Surface::Phong(p) | Surface::Mixture(p) => [p.kd.texture, p.ks.texture],
            Surface::Conductor { ks, .. } => [ks.texture, NO_TEXTURE],
            Surface::Dielectric { .. } => [NO_TEXTURE; 2],
        }
    }

    #[inline]
    #[must_use]
    pub fn is_textured(&self) -> bool {
        self.texture_ids() != [NO_TEXTURE; 2]
    }

    /// The BSDF at a surface point; `uv` (the point's texture coordinates) is called only for
    /// a textured material, once. Always inlined: a call per path vertex was 1% of a Cornell
    /// box render (callgrind), and the path loop is too large for the inliner to take it.
    #[inline(always)]
    #[must_use]
    pub fn bsdf(&self, textures: &Textures<'_>, uv: impl FnOnce() -> Vec2) -> Bsdf {
        let mut uv = Lazy::new(uv);
        match self.surface {
            Surface::Diffuse { kd } => Bsdf::Diffuse(Diffuse::new(kd.at(textures, &mut uv))),
            Surface::Phong(p) => Bsdf::Phong(p.at(textures, &mut uv)),
            Surface::Mixture(p) => Bsdf::Mixture(p.at(textures, &mut uv)),
            Surface::Conductor { ks, alpha } => {
                Bsdf::Conductor(Conductor::new(ks.at(textures, &mut uv), alpha))
            }
            Surface::Dielectric { eta, tf, alpha } => {
                Bsdf::Dielectric(Dielectric::new(eta, tf, alpha))
            }
        }
    }

    /// The BSDF of a material without textures (tests, tools).
    #[must_use]
    pub fn constant_bsdf(&self) -> Bsdf {
        self.bsdf(&Textures::NONE, || Vec2::ZERO)
    }
}

impl PhongParams {
    /// Constant reflectances: the clamp and weight as [`Phong::new`] computes them.
    #[must_use]
    pub fn constant(kd: Rgb, ks: Rgb, exponent: f32) -> Self {
        let p = Phong::new(kd, ks, exponent);
        Self {
            kd: Reflectance::constant(kd),
            ks: Reflectance::constant(ks),
            exponent: p.exponent,
            scale: p.scale,
            specular_weight: p.specular_weight,
        }
    }

    /// Reflectances that may be textures: the clamp and weight from their maxima and averages
    /// over `textures` ([`Reflectance::stats`], [`Phong::weights`]); `None` when a texture is
    /// missing from `textures`. Equals [`Self::constant`] for constant reflectances.
    #[must_use]
    pub fn new(
        kd: Reflectance,
        ks: Reflectance,
        exponent: f32,
        textures: &Textures<'_>,
    ) -> Option<Self> {
        Some(Self::from_stats(
            kd,
            ks,
            exponent,
            kd.stats(textures)?,
            ks.stats(textures)?,
        ))
    }

    /// As [`Self::new`] with the `(maximum, average)` of each reflectance already computed
    /// (hosts that share one texture among many materials compute its statistics once).
    #[must_use]
    pub fn from_stats(
        kd: Reflectance,
        ks: Reflectance,
        exponent: f32,
        (kd_max, kd_avg): (Rgb, Rgb),
        (ks_max, ks_avg): (Rgb, Rgb),
    ) -> Self {
        let (scale, specular_weight) = Phong::weights(kd_max, ks_max, kd_avg, ks_avg);
        Self {
            kd,
            ks,
            exponent: exponent.max(0.0),
            scale,
            specular_weight,
        }
    }

    #[inline(always)]
    fn at<F: FnOnce() -> Vec2>(&self, textures: &Textures<'_>, uv: &mut Lazy<F>) -> Phong {
        Phong::with_weights(
            self.kd.at(textures, uv),
            self.ks.at(textures, uv),
            self.exponent,
            self.scale,
            self.specular_weight,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::Texture;

    #[test]
    fn phong_weights_come_from_the_texels() {
        let (kd, ks) = (Rgb::new(0.2, 0.5, 0.1), Rgb::splat(0.3));
        let constant = PhongParams::constant(kd, ks, 20.0);
        let none = Textures::NONE;
        let same = PhongParams::new(
            Reflectance::constant(kd),
            Reflectance::constant(ks),
            20.0,
            &none,
        );
        assert_eq!(same, Some(constant));
        // Texels whose maximum (0.9 + 0.3 > 1) clamps while their average would not.
        let texels = [Rgb::splat(0.9), Rgb::splat(0.1), Rgb::ZERO, Rgb::splat(0.2)];
        let textures = [Texture::new(2, 2, 0)];
        let t = Textures {
            uvs: &[],
            textures: &textures,
            texels: &texels,
        };
        let p =
            PhongParams::new(Reflectance::texture(0), Reflectance::constant(ks), -1.0, &t).unwrap();
        let (scale, weight) = Phong::weights(Rgb::splat(0.9), ks, Rgb::splat(0.3), ks);
        assert_eq!(
            (p.scale, p.specular_weight, p.exponent),
            (scale, weight, 0.0)
        );
        assert!((scale - 0.99 / 1.2).abs() < 1e-6);
        assert!(
            PhongParams::new(Reflectance::texture(1), Reflectance::constant(ks), 1.0, &t).is_none()
        );
    }
}
