use crate::math::gamma;
use glam::Vec3;

/// Axis-aligned bounding box; the empty box has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    pub const EMPTY: Self = Self {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    #[inline]
    #[must_use]
    pub fn from_points(a: Vec3, b: Vec3, c: Vec3) -> Self {
        Self {
            min: a.min(b).min(c),
            max: a.max(b).max(c),
        }
    }

    #[inline]
    #[must_use]
    pub fn union(self, o: Self) -> Self {
        Self {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    #[inline]
    #[must_use]
    pub fn grow(self, p: Vec3) -> Self {
        Self {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    #[inline]
    #[must_use]
    pub fn centroid(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    #[inline]
    #[must_use]
    pub fn extent(&self) -> Vec3 {
        (self.max - self.min).max(Vec3::ZERO)
    }

    #[inline]
    #[must_use]
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Slab test against `[0, t_max]` with pbrt's conservative rounding of the far distance.
    /// `inv_d` is `1/d` per axis and `neg` tells which axes have a negative direction.
    ///
    /// Branch-free: the entry distance is the largest near-slab distance and the exit distance
    /// the smallest far one, so one comparison decides. That is the decision of pbrt's
    /// axis-by-axis early exits (max(lo) <= min(hi) iff every lo_i <= hi_j) without their
    /// data-dependent branches. `f32::max`/`min` ignore a NaN (0·∞ for an origin on a slab
    /// plane with d = 0), so such a slab does not constrain the ray, as in pbrt.
    #[inline]
    #[must_use]
    pub fn hit(&self, o: Vec3, inv_d: Vec3, neg: [bool; 3], t_max: f32) -> bool {
        let sel = |lo: f32, hi: f32, n: bool| if n { (hi, lo) } else { (lo, hi) };
        let scale = 1.0 + 2.0 * gamma(3);
        let (x0, x1) = sel(self.min.x, self.max.x, neg[0]);
        let (y0, y1) = sel(self.min.y, self.max.y, neg[1]);
        let (z0, z1) = sel(self.min.z, self.max.z, neg[2]);
        let tx0 = (x0 - o.x) * inv_d.x;
        let tx1 = (x1 - o.x) * inv_d.x;
        let ty0 = (y0 - o.y) * inv_d.y;
        let ty1 = (y1 - o.y) * inv_d.y;
        let tz0 = (z0 - o.z) * inv_d.z;
        let tz1 = (z1 - o.z) * inv_d.z;
        let t0 = tx0.max(ty0).max(tz0);
        // pbrt scales each far distance; rounding is monotonic, so scaling their minimum once
        // gives the same number (`min(a·s, b·s) = min(a, b)·s` for `s > 0`, NaN ignored alike).
        let t1 = tx1.min(ty1).min(tz1) * scale;
        // t0 and t1 are NaN only if every slab produced a NaN; then nothing constrains.
        let entered = t0.partial_cmp(&t1) != Some(core::cmp::Ordering::Greater);
        entered & (t0 < t_max || t0.is_nan()) & (t1 > 0.0 || t1.is_nan())
    }
}
