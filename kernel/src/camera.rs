//! The TinyRender pinhole camera (FORMAT.md §2.2 and §7).

use crate::geometry::Ray;
use crate::math::{AreaPdf, SolidAnglePdf};
use glam::{Vec2, Vec3};

/// The camera seen from a surface point ([`Camera::sample_wi`]): where on the film the point
/// projects, the importance arriving along the connection, and its density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSample {
    /// Continuous raster position (row 0 at the top).
    pub raster: Vec2,
    /// Unit world direction from the point to the camera.
    pub wi: Vec3,
    /// Distance from the point to the camera.
    pub dist: f32,
    /// Importance `We` of the camera ray through `raster` (pbrt's normalisation).
    pub we: f32,
    /// Density of choosing the camera point, converted to solid angle at the surface point
    /// (`d² / |cos θ_camera|` for the pinhole, whose lens "area" is 1).
    pub pdf: SolidAnglePdf,
}

/// Right-handed look-at pinhole camera with a full vertical field of view. Row 0 of the image
/// is the top row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    /// Camera-space +x, +y and −z in world space (`glm::lookAt` conventions).
    pub right: Vec3,
    pub up: Vec3,
    pub forward: Vec3,
    pub tan_half_fov: f32,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// `fov_deg` is the full vertical field of view in degrees.
    #[must_use]
    pub fn look_at(eye: Vec3, at: Vec3, up: Vec3, fov_deg: f32, width: u32, height: u32) -> Self {
        let forward = (at - eye).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        Self {
            eye,
            right,
            up,
            forward,
            tan_half_fov: libm::tanf(fov_deg.to_radians() * 0.5),
            width,
            height,
        }
    }

    /// The primary ray through pixel `(x, y)` at offset `u` in `[0, 1)²` within the pixel:
    /// camera-space direction `((2(x+uₓ)/W − 1)·tan(fov/2)·W/H, (1 − 2(y+u_y)/H)·tan(fov/2), −1)`.
    #[inline]
    #[must_use]
    pub fn generate_ray(&self, x: u32, y: u32, u: Vec2) -> Ray {
        let (w, h) = (self.width as f32, self.height as f32);
        let aspect = w / h;
        let cx = (2.0 * (x as f32 + u.x) / w - 1.0) * self.tan_half_fov * aspect;
        let cy = (1.0 - 2.0 * (y as f32 + u.y) / h) * self.tan_half_fov;
        let d = (self.right * cx + self.up * cy + self.forward).normalize();
        Ray::new(self.eye, d)
    }

    /// Pixel coordinates (continuous, row 0 at the top) where the world point `p` projects,
    /// or `None` behind the camera or outside the film; the inverse of [`Self::generate_ray`]
    /// used by light tracing to splat.
    #[must_use]
    pub fn raster_position(&self, p: Vec3) -> Option<Vec2> {
        self.raster_of_direction(p - self.eye)
    }

    /// Raster position of the camera ray with direction `d` (any length), or `None` behind
    /// the camera or outside the film.
    #[inline]
    #[must_use]
    pub fn raster_of_direction(&self, d: Vec3) -> Option<Vec2> {
        let z = d.dot(self.forward);
        if z.is_nan() || z <= 0.0 {
            return None;
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let cx = d.dot(self.right) / z / (self.tan_half_fov * w / h);
        let cy = d.dot(self.up) / z / self.tan_half_fov;
        let px = Vec2::new((cx + 1.0) * 0.5 * w, (1.0 - cy) * 0.5 * h);
        (px.x >= 0.0 && px.x < w && px.y >= 0.0 && px.y < h).then_some(px)
    }

    /// Area `A` of the film on the image plane at distance 1 (camera space):
    /// `(2 tan(fov/2) · W/H) · (2 tan(fov/2))`.
    #[inline]
    #[must_use]
    pub fn image_plane_area(&self) -> f32 {
        let t = self.tan_half_fov;
        4.0 * t * t * (self.width as f32 / self.height as f32)
    }

    /// Importance `We` of a camera ray with unit direction `d` (pbrt-v4's pinhole
    /// `PerspectiveCamera::We`): `1 / (A cos⁴θ)` inside the film, 0 outside, normalised so
    /// that `∫ We cosθ dω` over the film is 1. Pixel `j` measures `W·H ∫_j We cosθ L dω`, the
    /// mean radiance over its area, which is why light-tracing splats are divided only by
    /// the samples per pixel.
    #[inline]
    #[must_use]
    pub fn we(&self, d: Vec3) -> f32 {
        let cos = d.dot(self.forward);
        if self.raster_of_direction(d).is_none() {
            return 0.0;
        }
        let cos2 = cos * cos;
        1.0 / (self.image_plane_area() * cos2 * cos2)
    }

    /// Densities with which [`Self::generate_ray`] produces a ray of unit direction `d`: the
    /// position (a delta at the pinhole: pbrt reports 1, the lens "area") and the direction,
    /// `1 / (A cos³θ)` per unit solid angle (uniform on the film's area at distance 1).
    #[inline]
    #[must_use]
    pub fn pdf_we(&self, d: Vec3) -> (AreaPdf, SolidAnglePdf) {
        if self.raster_of_direction(d).is_none() {
            return (AreaPdf(0.0), SolidAnglePdf(0.0));
        }
        let cos = d.dot(self.forward);
        (
            AreaPdf(1.0),
            SolidAnglePdf(1.0 / (self.image_plane_area() * cos * cos * cos)),
        )
    }

    /// Connects the point `p` to the pinhole (pbrt-v4 `SampleWi`): `None` when `p` is behind
    /// the camera, outside the film's view, or at the pinhole itself.
    #[inline]
    #[must_use]
    pub fn sample_wi(&self, p: Vec3) -> Option<CameraSample> {
        let to_camera = self.eye - p;
        let dist2 = to_camera.length_squared();
        if dist2.is_nan() || dist2 <= 0.0 {
            return None;
        }
        let dist = crate::math::sqrt(dist2);
        let wi = to_camera / dist;
        let raster = self.raster_of_direction(-wi)?;
        let cos = (-wi).dot(self.forward);
        Some(CameraSample {
            raster,
            wi,
            dist,
            we: self.we(-wi),
            pdf: SolidAnglePdf(dist2 / cos.abs()),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_row_zero_is_top() {
        let c = Camera::look_at(
            Vec3::new(0.0, 0.8, 3.8),
            Vec3::new(0.0, 0.8, 0.0),
            Vec3::Y,
            30.0,
            800,
            600,
        );
        let r = c.generate_ray(400, 300, Vec2::ZERO);
        assert!((r.d - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        assert!(c.generate_ray(400, 0, Vec2::ZERO).d.y > 0.0);
        assert!(c.generate_ray(0, 300, Vec2::ZERO).d.x < 0.0);
        // Top edge of the film is at half the vertical fov.
        let top = c.generate_ray(400, 0, Vec2::new(0.0, 0.0)).d;
        assert!((libm::atan2f(top.y, -top.z).to_degrees() - 15.0).abs() < 1e-3);
        let p = c.eye + c.generate_ray(123, 456, Vec2::new(0.25, 0.75)).d * 2.0;
        let px = c.raster_position(p).unwrap();
        assert!((px - Vec2::new(123.25, 456.75)).length() < 1e-2, "{px}");
    }

    fn cbox() -> Camera {
        Camera::look_at(
            Vec3::new(0.0, 0.8, 3.8),
            Vec3::new(0.0, 0.8, 0.0),
            Vec3::Y,
            30.0,
            800,
            600,
        )
    }

    /// pbrt's normalisation: ∫ We cosθ dω over the directions of the film is 1. Integrated
    /// over the image plane at distance 1 (dω = cos³θ dA), midpoint rule on a fine grid in
    /// f64, with We itself from the kernel.
    #[test]
    fn importance_integrates_to_one_over_the_film() {
        let c = cbox();
        // BONUS-NOTES §6: A = 0.38292 for this camera.
        assert!(
            (c.image_plane_area() - 0.38292).abs() < 1e-4,
            "{}",
            c.image_plane_area()
        );
        let (n, m) = (800, 600);
        let mut sum = 0.0f64;
        for j in 0..m {
            for i in 0..n {
                let ray = c.generate_ray(i, j, Vec2::splat(0.5));
                let d = ray.d;
                let cos = f64::from(d.dot(c.forward));
                // Solid angle of the pixel: its area on the plane (A / (W·H)) times cos³θ.
                let domega = f64::from(c.image_plane_area()) / f64::from(n * m) * cos.powi(3);
                sum += f64::from(c.we(d)) * cos * domega;
            }
        }
        assert!((sum - 1.0).abs() < 1e-4, "∫ We cos dω = {sum}");
        // Outside the film (and behind the camera) there is no importance.
        assert_eq!(c.we(-c.forward), 0.0);
        assert_eq!(c.we((c.forward + c.right).normalize()), 0.0);
        // The direction pdf integrates to 1 likewise, and is We·cosθ (pinhole: pdf_pos = 1).
        let d = c.generate_ray(10, 20, Vec2::splat(0.3)).d;
        let (pos, dir) = c.pdf_we(d);
        assert_eq!(pos.0, 1.0);
        assert!((dir.0 - c.we(d) * d.dot(c.forward)).abs() <= 1e-6 * dir.0);
    }

    /// `sample_wi` inverts `generate_ray`: a point on a camera ray connects back to the same
    /// raster position, along the reversed direction, with We and the pdf of that direction.
    #[test]
    fn sample_wi_round_trips_with_generate_ray() {
        let c = cbox();
        for (x, y, u) in [
            (0u32, 0u32, 0.1f32),
            (400, 300, 0.5),
            (799, 599, 0.9),
            (17, 480, 0.3),
        ] {
            let ray = c.generate_ray(x, y, Vec2::new(u, 1.0 - u));
            let p = ray.o + ray.d * 2.5;
            let s = c.sample_wi(p).unwrap();
            let expected = Vec2::new(x as f32 + u, y as f32 + 1.0 - u);
            assert!(
                (s.raster - expected).length() < 2e-3,
                "{} vs {expected}",
                s.raster
            );
            assert!((s.wi + ray.d).length() < 1e-5);
            assert!((s.dist - 2.5).abs() < 1e-5);
            assert!((s.we - c.we(ray.d)).abs() <= 1e-5 * s.we);
            let cos = ray.d.dot(c.forward);
            assert!((s.pdf.0 - 2.5 * 2.5 / cos).abs() < 1e-4);
        }
        assert!(
            c.sample_wi(c.eye - c.forward).is_none(),
            "behind the camera"
        );
        assert!(c.sample_wi(c.eye).is_none(), "at the pinhole");
    }
}
