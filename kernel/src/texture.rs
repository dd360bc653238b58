//! RGB image textures in caller slices, looked up as TinyRender does (FORMAT.md §4).

use crate::Rgb;
use glam::Vec2;

/// The texture id of a reflectance that is a constant ([`crate::material::Reflectance`]).
pub const NO_TEXTURE: u32 = u32::MAX;

/// An RGB image: `width × height` linear texels at `texels[first_texel..]`, stored **bottom row
/// first** (TinyRender flips rows at load so that `v = 0` is the bottom of the picture), each
/// row left to right. Texture coordinates are transformed by `uv·uv_scale + uv_offset` (the
/// MTL map options `-s` and `-o`) before the lookup.
///
/// `#[repr(C)]`: the C API reads its callers' `EmberTexture` arrays in place as this type.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub first_texel: u32,
    pub uv_scale: Vec2,
    pub uv_offset: Vec2,
}

impl Texture {
    /// A texture with the identity coordinate transform.
    #[must_use]
    pub fn new(width: u32, height: u32, first_texel: u32) -> Self {
        Self {
            width,
            height,
            first_texel,
            uv_scale: Vec2::ONE,
            uv_offset: Vec2::ZERO,
        }
    }

    /// Number of texels.
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index into the texel slice of the texel at `uv`: nearest lookup of `st = frac(uv)`,
    /// `x = clamp(⌊s·w⌋, 0, w−1)`, `y = clamp(⌊t·h⌋, 0, h−1)`, computed as TinyRender's
    /// `BitmapTexture3f::eval` does (`st = uv + 1; st − floor(st)`). Non-finite coordinates
    /// give texel 0.
    #[inline]
    #[must_use]
    pub fn texel_index(&self, uv: Vec2) -> usize {
        let st = uv * self.uv_scale + self.uv_offset + Vec2::ONE;
        let st = st - Vec2::new(libm::floorf(st.x), libm::floorf(st.y));
        // `as` saturates (and sends NaN to 0); the clamp keeps s = 1 − ε·w rounding inside.
        let x = ((st.x * self.width as f32) as i64).clamp(0, i64::from(self.width) - 1);
        let y = ((st.y * self.height as f32) as i64).clamp(0, i64::from(self.height) - 1);
        self.first_texel as usize + y as usize * self.width as usize + x as usize
    }
}

/// A scene's textures: per-vertex texture coordinates (indexed like the positions; empty when
/// no material is textured), the texture table and the texels.
#[derive(Clone, Copy, Debug, Default)]
pub struct Textures<'a> {
    pub uvs: &'a [Vec2],
    pub textures: &'a [Texture],
    pub texels: &'a [Rgb],
}

impl Textures<'_> {
    /// No textures.
    pub const NONE: Textures<'static> = Textures {
        uvs: &[],
        textures: &[],
        texels: &[],
    };

    /// The texel of texture `id` at `uv` ([`Texture::texel_index`]). `id` and the texture's
    /// texel range must be valid ([`crate::scene::SceneView::validate`]).
    #[inline]
    #[must_use]
    pub fn lookup(&self, id: u32, uv: Vec2) -> Rgb {
        self.texels[self.textures[id as usize].texel_index(uv)]
    }
}

impl<'a> Textures<'a> {
    /// The texels of texture `id`; `None` when there is no such texture or its texels are
    /// empty or lie outside `texels` (what [`crate::scene::SceneView::validate`] refuses).
    #[must_use]
    pub fn texels_of(&self, id: u32) -> Option<&'a [Rgb]> {
        let t = self.textures.get(id as usize)?;
        let start = t.first_texel as usize;
        let texels = self.texels.get(start..start.checked_add(t.len())?)?;
        (!texels.is_empty()).then_some(texels)
    }
}

/// Per-channel maximum and average of a texture's texels (TinyRender's `getMax` and
/// `getAverage`, which Phong's energy clamp and lobe weight are derived from). The sum is in
/// f64 so that it does not depend on the texture's size; `None` for an empty slice.
#[must_use]
pub fn texel_stats(texels: &[Rgb]) -> Option<(Rgb, Rgb)> {
    if texels.is_empty() {
        return None;
    }
    let mut max = Rgb::splat(f32::NEG_INFINITY);
    let mut sum = glam::DVec3::ZERO;
    for t in texels {
        max = max.max(*t);
        sum += t.as_dvec3();
    }
    Some((max, (sum / texels.len() as f64).as_vec3()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_follows_tinyrender() {
        let t = Texture::new(4, 2, 10);
        // Bottom row first: v in [0, 0.5) is row 0.
        assert_eq!(t.texel_index(Vec2::new(0.0, 0.0)), 10);
        assert_eq!(t.texel_index(Vec2::new(0.26, 0.1)), 11);
        assert_eq!(t.texel_index(Vec2::new(0.99, 0.51)), 10 + 4 + 3);
        // Wrapping: frac(uv), negative coordinates too.
        assert_eq!(t.texel_index(Vec2::new(1.26, 2.1)), 11);
        assert_eq!(t.texel_index(Vec2::new(-0.74, -0.9)), 11);
        // u = 1 wraps to 0.
        assert_eq!(t.texel_index(Vec2::new(1.0, 0.0)), 10);
        assert_eq!(t.texel_index(Vec2::new(f32::NAN, f32::INFINITY)), 10);
        let mut s = t;
        s.uv_scale = Vec2::splat(2.0);
        s.uv_offset = Vec2::new(0.25, 0.0);
        // 0.2·2 + 0.25 = 0.65 → x = 2.
        assert_eq!(s.texel_index(Vec2::new(0.2, 0.0)), 12);
    }

    #[test]
    fn stats_are_per_channel() {
        let (max, avg) = texel_stats(&[Rgb::new(1.0, 0.0, 0.5), Rgb::new(0.0, 0.5, 0.5)]).unwrap();
        assert_eq!(max, Rgb::new(1.0, 0.5, 0.5));
        assert_eq!(avg, Rgb::new(0.5, 0.25, 0.5));
        assert!(texel_stats(&[]).is_none());
    }

    #[test]
    fn texels_of_checks_ids_and_ranges() {
        let texels = [Rgb::ONE; 6];
        let textures = [
            Texture::new(2, 2, 2),
            Texture::new(2, 2, 3),
            Texture::new(0, 1, 0),
        ];
        let t = Textures {
            uvs: &[],
            textures: &textures,
            texels: &texels,
        };
        assert_eq!(t.texels_of(0).map(<[Rgb]>::len), Some(4));
        assert!(t.texels_of(1).is_none(), "one texel past the end");
        assert!(t.texels_of(2).is_none(), "empty");
        assert!(t.texels_of(3).is_none(), "no such texture");
        let far = [Texture::new(u32::MAX, u32::MAX, u32::MAX)];
        assert!(Textures {
            textures: &far,
            ..t
        }
        .texels_of(0)
        .is_none());
    }
}
