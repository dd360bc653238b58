//! The TinyRender pinhole camera (FORMAT.md §2.2 and §7).

use crate::geometry::Ray;
use glam::{Vec2, Vec3};

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
        let v = p - self.eye;
        let z = v.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let cx = v.dot(self.right) / z / (self.tan_half_fov * w / h);
        let cy = v.dot(self.up) / z / self.tan_half_fov;
        let px = Vec2::new((cx + 1.0) * 0.5 * w, (1.0 - cy) * 0.5 * h);
        (px.x >= 0.0 && px.x < w && px.y >= 0.0 && px.y < h).then_some(px)
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
}
