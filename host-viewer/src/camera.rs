//! The TinyRender real-time camera (FORMAT.md §2.2): `lookAt(eye, at, up)` with a perspective of
//! the full vertical `fov`, aspect `width/height`, near 0.01 and far 1000, plus the orbit and fly
//! moves of the window mode.

use ember_cli::scene_file::CameraDesc;
use glam::{Mat4, Quat, Vec3};

/// Near and far planes of TinyRender's `glm::perspective`.
pub const Z_NEAR: f32 = 0.01;
pub const Z_FAR: f32 = 1000.0;

/// A look-at camera that can be moved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewCamera {
    pub eye: Vec3,
    /// The look-at point, which orbiting turns around.
    pub target: Vec3,
    pub up: Vec3,
    /// Full vertical field of view in degrees.
    pub fov_y_degrees: f32,
}

impl ViewCamera {
    #[must_use]
    pub fn from_desc(c: &CameraDesc) -> Self {
        Self {
            eye: c.eye.into(),
            target: c.at.into(),
            up: c.up.into(),
            fov_y_degrees: c.fov,
        }
    }

    /// The path tracer's camera for this view at a film size: the same `look_at` as
    /// `LoadedScene::camera`, so the scene camera gives `ember render`'s rays bit for bit.
    #[must_use]
    pub fn kernel_camera(&self, width: u32, height: u32) -> ember_kernel::camera::Camera {
        ember_kernel::camera::Camera::look_at(
            self.eye,
            self.target,
            self.up,
            self.fov_y_degrees,
            width,
            height,
        )
    }

    /// World → clip matrix for wgpu (clip z in [0, 1], right-handed, looking down −z).
    #[must_use]
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let proj = Mat4::perspective_rh(self.fov_y_degrees.to_radians(), aspect, Z_NEAR, Z_FAR);
        proj * Mat4::look_at_rh(self.eye, self.target, self.up)
    }

    /// Whether the camera defines a view: distinct eye and target, an up vector not parallel
    /// to the view direction, a field of view in (0°, 180°), all finite.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        let f = self.target - self.eye;
        self.eye.is_finite()
            && self.target.is_finite()
            && self.up.is_finite()
            && f.length_squared() > 0.0
            && f.normalize().cross(self.up).length_squared() > 1e-12
            && self.fov_y_degrees > 0.0
            && self.fov_y_degrees < 180.0
    }

    fn world_up(&self) -> Vec3 {
        self.up.try_normalize().unwrap_or(Vec3::Y)
    }

    fn forward(&self) -> Vec3 {
        (self.target - self.eye)
            .try_normalize()
            .unwrap_or(Vec3::NEG_Z)
    }

    /// Rotation of `v` by `yaw` about the world up and by `pitch` about the camera's right
    /// axis, with the pitch limited so that `v` stays at least 1° away from ±up.
    fn turn(&self, v: Vec3, yaw: f32, pitch: f32) -> Vec3 {
        let up = self.world_up();
        let v = Quat::from_axis_angle(up, yaw) * v;
        let len = v.length();
        if len == 0.0 {
            return v;
        }
        // Angle of v from up, kept in [1°, 179°].
        let angle = (v.dot(up) / len).clamp(-1.0, 1.0).acos();
        let limit = 1f32.to_radians();
        let new_angle = (angle - pitch).clamp(limit, std::f32::consts::PI - limit);
        let axis = up.cross(v).try_normalize();
        match axis {
            Some(axis) => Quat::from_axis_angle(axis, new_angle - angle) * v,
            None => v,
        }
    }

    /// Orbits the eye around the target: `yaw` about the up axis, `pitch` up/down (radians).
    pub fn orbit(&mut self, yaw: f32, pitch: f32) {
        let offset = self.eye - self.target;
        // Pitching the offset towards up raises the eye: "drag up = look from above".
        self.eye = self.target + self.turn(offset, yaw, pitch);
    }

    /// Moves the eye towards the target (`steps > 0`) or away, by 10 % of the distance a step.
    pub fn zoom(&mut self, steps: f32) {
        let offset = self.eye - self.target;
        let d = offset.length();
        let new_d = (d * 0.9f32.powf(steps)).clamp(1e-3, Z_FAR * 0.5);
        if d > 0.0 {
            self.eye = self.target + offset * (new_d / d);
        }
    }

    /// Moves eye and target together: along the view direction, to the right, and along up.
    pub fn fly(&mut self, forward: f32, right: f32, upward: f32) {
        let f = self.forward();
        let up = self.world_up();
        let r = f.cross(up).try_normalize().unwrap_or(Vec3::X);
        let d = f * forward + r * right + up * upward;
        self.eye += d;
        self.target += d;
    }

    /// Turns the view direction around the eye (first-person look): `yaw` left, `pitch` up.
    pub fn look(&mut self, yaw: f32, pitch: f32) {
        let dir = self.target - self.eye;
        self.target = self.eye + self.turn(dir, yaw, pitch);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> ViewCamera {
        ViewCamera {
            eye: Vec3::new(0.0, 0.8, 3.8),
            target: Vec3::new(0.0, 0.8, 0.0),
            up: Vec3::Y,
            fov_y_degrees: 30.0,
        }
    }

    #[test]
    fn projects_target_to_centre_and_up_to_top() {
        let c = cam();
        let m = c.view_proj(4.0 / 3.0);
        let p = m.project_point3(c.target);
        assert!(p.x.abs() < 1e-6 && p.y.abs() < 1e-6 && p.z > 0.0 && p.z < 1.0);
        let above = m.project_point3(c.target + Vec3::Y * 0.1);
        assert!(above.y > 0.0);
        // Top edge of the view: half the vertical fov.
        let edge = c.target + Vec3::Y * 3.8 * 15f32.to_radians().tan();
        assert!((m.project_point3(edge).y - 1.0).abs() < 1e-5);
    }

    #[test]
    fn orbit_keeps_distance_and_target() {
        let mut c = cam();
        c.orbit(0.7, 0.3);
        assert!(((c.eye - c.target).length() - 3.8).abs() < 1e-4);
        assert_eq!(c.target, Vec3::new(0.0, 0.8, 0.0));
        assert!(c.eye.y > 0.8, "pitching up raises the eye");
        // Pitch is limited short of the pole.
        c.orbit(0.0, 10.0);
        assert!(c.is_valid());
    }

    #[test]
    fn zoom_fly_and_look() {
        let mut c = cam();
        c.zoom(1.0);
        assert!(((c.eye - c.target).length() - 3.42).abs() < 1e-4);
        let before = c;
        c.fly(1.0, 0.0, 0.0);
        assert!((c.eye - (before.eye + Vec3::NEG_Z)).length() < 1e-5);
        c.fly(0.0, 1.0, 1.0);
        assert!((c.target - (before.target + Vec3::new(1.0, 1.0, -1.0))).length() < 1e-5);
        let eye = c.eye;
        c.look(0.5, 0.2);
        assert_eq!(c.eye, eye);
        assert!(c.is_valid());
    }

    #[test]
    fn invalid_cameras() {
        let mut c = cam();
        c.target = c.eye;
        assert!(!c.is_valid());
        let mut c = cam();
        c.up = Vec3::Z;
        assert!(!c.is_valid());
        let mut c = cam();
        c.fov_y_degrees = 0.0;
        assert!(!c.is_valid());
    }
}
