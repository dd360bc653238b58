use crate::math::{next_float_down, next_float_up};
use glam::Vec3;

/// A ray `o + t·d` for `t` in `(0, t_max)`. `d` need not be normalised.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
    pub t_max: f32,
}

impl Ray {
    #[inline]
    #[must_use]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        Self {
            o,
            d,
            t_max: f32::INFINITY,
        }
    }

    #[inline]
    #[must_use]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// Shadow rays stop this fraction short of their target (pbrt-v4's `ShadowEpsilon`): the target
/// itself has already been offset off its surface, this only absorbs the rounding of `t`.
pub const SHADOW_EPSILON: f32 = 1e-4;

/// Moves `p` (with absolute error bound `p_err` per axis) off the surface with geometric normal
/// `n` to the side that `w` points to, far enough that a ray leaving it cannot re-hit the same
/// surface (pbrt-v4 `OffsetRayOrigin`). No fixed epsilon: the offset scales with the error bound.
// Always inlined: the path loops grew past the inliner's budget, and the call cost 1.4% of a
// Cornell box render (callgrind).
#[inline(always)]
#[must_use]
pub fn offset_ray_origin(p: Vec3, p_err: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_err);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    // Round away from p so the offset is not lost to rounding.
    let round = |v: f32, o: f32| {
        if o > 0.0 {
            next_float_up(v)
        } else if o < 0.0 {
            next_float_down(v)
        } else {
            v
        }
    };
    Vec3::new(
        round(po.x, offset.x),
        round(po.y, offset.y),
        round(po.z, offset.z),
    )
}

/// A ray leaving a surface point in direction `d`.
#[inline]
#[must_use]
pub fn spawn_ray(p: Vec3, p_err: Vec3, n: Vec3, d: Vec3) -> Ray {
    Ray::new(offset_ray_origin(p, p_err, n, d), d)
}

/// A shadow ray between two surface points, both ends offset off their surfaces
/// (pbrt-v4 `SpawnRayTo` with two interactions). Occluded iff anything is hit for `t < t_max`.
#[inline]
#[must_use]
pub fn spawn_ray_to(
    p_from: Vec3,
    err_from: Vec3,
    n_from: Vec3,
    p_to: Vec3,
    err_to: Vec3,
    n_to: Vec3,
) -> Ray {
    let o = offset_ray_origin(p_from, err_from, n_from, p_to - p_from);
    let target = offset_ray_origin(p_to, err_to, n_to, o - p_to);
    Ray {
        o,
        d: target - o,
        t_max: 1.0 - SHADOW_EPSILON,
    }
}
