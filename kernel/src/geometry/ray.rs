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

/// A shadow ray from `o` to `target` (both already offset off their surfaces, with error
/// bounds `err_from` and `err_to`), occluded iff anything is hit for `t < t_max`.
///
/// It stops short of `target` by a **distance** on the scale of the rounding of the two
/// points and of `t` (a few ulps of the larger coordinates plus the error bounds), not by a
/// fixed fraction of its length as pbrt-v4's `ShadowEpsilon` (1e-4) does: a fraction of the
/// length skips every occluder within that distance of the target, 0.35 mm at 3.5 m, and light
/// leaked through a wall meeting the target's surface (BDPT's connections of a vertex beside a
/// corner to a light path on the wall's other side; `tests/tests/bdpt.rs`, the camera inside a
/// closed box). The offsets already keep both ends' own surfaces out of `(0, 1)`; the slack
/// only absorbs the rounding of the hit's `t`, which the intersection test computes to a few
/// ulps of the coordinates involved.
#[inline]
#[must_use]
pub fn shadow_ray(o: Vec3, err_from: Vec3, target: Vec3, err_to: Vec3) -> Ray {
    let d = target - o;
    let len = crate::math::sqrt(d.length_squared());
    let scale = o.abs().max(target.abs()).max_element();
    let slack = SHADOW_ULPS * f32::EPSILON * scale + 2.0 * err_from.max(err_to).max_element();
    // At least one ulp below 1, and never below 0 (a segment shorter than its slack is
    // unoccluded, as the two points are indistinguishable at that precision).
    let t_max = if len > 0.0 {
        (1.0 - slack / len).clamp(0.0, 1.0 - f32::EPSILON)
    } else {
        0.0
    };
    Ray { o, d, t_max }
}

/// Ulps of the larger coordinate of a shadow ray's ends that it stops short of its target.
const SHADOW_ULPS: f32 = 16.0;

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

/// A shadow ray for a connection between two scattering vertices whose BSDFs were evaluated
/// with the direction `w` from `from` to `to` (and `-w` back): each end is offset to the side
/// of its surface that its BSDF saw the connection leave on, not the target toward the
/// origin's side as in [`spawn_ray_to`]. The two differ only when `w` lies (to rounding) in a
/// surface's plane: for two points of one face seen from its two sides (a camera path inside a
/// closed box, a light path outside it), rounding can make each BSDF accept the grazing
/// connection on its own side; offset toward the origin, the ray could then run beside the
/// face, while offset to the BSDFs' sides it crosses it. (A guard for that grazing case: the
/// leak `tests/tests/bdpt.rs` found through a closed box was [`shadow_ray`]'s.)
#[inline]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub fn spawn_connection(
    p_from: Vec3,
    err_from: Vec3,
    n_from: Vec3,
    p_to: Vec3,
    err_to: Vec3,
    n_to: Vec3,
    w: Vec3,
) -> Ray {
    let o = offset_ray_origin(p_from, err_from, n_from, w);
    let target = offset_ray_origin(p_to, err_to, n_to, -w);
    shadow_ray(o, err_from, target, err_to)
}

/// A ray leaving a surface point in direction `d`.
#[inline]
#[must_use]
pub fn spawn_ray(p: Vec3, p_err: Vec3, n: Vec3, d: Vec3) -> Ray {
    Ray::new(offset_ray_origin(p, p_err, n, d), d)
}

/// A shadow ray between two surface points, both ends offset off their surfaces
/// (pbrt-v4 `SpawnRayTo` with two interactions), stopping short as [`shadow_ray`] says.
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
    shadow_ray(o, err_from, target, err_to)
}
