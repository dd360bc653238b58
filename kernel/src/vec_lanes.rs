//! Eight 3-vectors at a time: [`V3`], a lane type per axis, with glam's `Vec3` operations
//! spelt out as glam computes them (so that a lane computes the scalar code's bits), and
//! [`Soa3`], eight 3-vectors stored by axis, which is how the batched path tracer keeps its
//! paths' state between stages (a stage loads an axis with one instruction and stores it with
//! one, where eight `Vec3`s would be gathered and scattered a float at a time).

use crate::math::gamma;
use crate::simd::Lanes;
use glam::Vec3;

/// Lanes of eight.
pub(crate) const N: usize = 8;

/// Eight 3-vectors, a lane type per axis.
#[derive(Clone, Copy)]
pub(crate) struct V3<L> {
    pub x: L,
    pub y: L,
    pub z: L,
}

impl<L: Lanes<N>> V3<L> {
    /// Lane `l` is `v(l)`.
    #[inline(always)]
    pub fn new(isa: L::Isa, v: impl Fn(usize) -> Vec3) -> Self {
        Self {
            x: L::new(isa, core::array::from_fn(|l| v(l).x)),
            y: L::new(isa, core::array::from_fn(|l| v(l).y)),
            z: L::new(isa, core::array::from_fn(|l| v(l).z)),
        }
    }

    #[inline(always)]
    pub fn splat(isa: L::Isa, v: Vec3) -> Self {
        Self {
            x: L::splat(isa, v.x),
            y: L::splat(isa, v.y),
            z: L::splat(isa, v.z),
        }
    }

    #[inline(always)]
    pub fn splat_lanes(v: L) -> Self {
        Self { x: v, y: v, z: v }
    }

    #[inline(always)]
    pub fn add(self, b: Self) -> Self {
        Self {
            x: self.x + b.x,
            y: self.y + b.y,
            z: self.z + b.z,
        }
    }

    #[inline(always)]
    pub fn sub(self, b: Self) -> Self {
        Self {
            x: self.x - b.x,
            y: self.y - b.y,
            z: self.z - b.z,
        }
    }

    /// Component by component (glam's `Vec3 * Vec3`).
    #[inline(always)]
    pub fn mul(self, b: Self) -> Self {
        Self {
            x: self.x * b.x,
            y: self.y * b.y,
            z: self.z * b.z,
        }
    }

    /// glam's `Vec3 * f32`.
    #[inline(always)]
    pub fn scale(self, s: L) -> Self {
        Self {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }

    /// glam's `Vec3 / f32`: each component divided (not multiplied by a reciprocal).
    #[inline(always)]
    pub fn div(self, s: L) -> Self {
        Self {
            x: self.x / s,
            y: self.y / s,
            z: self.z / s,
        }
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        Self {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    #[inline(always)]
    pub fn neg(self) -> Self {
        Self {
            x: self.x.neg(),
            y: self.y.neg(),
            z: self.z.neg(),
        }
    }

    /// glam's `dot`.
    #[inline(always)]
    pub fn dot(self, b: Self) -> L {
        self.x * b.x + self.y * b.y + self.z * b.z
    }

    /// glam's `cross`.
    #[inline(always)]
    pub fn cross(self, b: Self) -> Self {
        Self {
            x: self.y * b.z - b.y * self.z,
            y: self.z * b.x - b.z * self.x,
            z: self.x * b.y - b.x * self.y,
        }
    }

    /// glam's `max` (`a > b ? a : b` per component, which is `maxps`).
    #[inline(always)]
    pub fn max(self, b: Self) -> Self {
        Self {
            x: self.x.fast_max(b.x),
            y: self.y.fast_max(b.y),
            z: self.z.fast_max(b.z),
        }
    }

    /// glam's `max_element`: `max(x, max(y, z))` with `a > b ? a : b`.
    #[inline(always)]
    pub fn max_element(self) -> L {
        self.x.fast_max(self.y.fast_max(self.z))
    }

    /// True where every component is zero (glam's `== Vec3::ZERO`).
    #[inline(always)]
    pub fn is_zero(self, zero: L) -> L {
        self.x.simd_eq(zero) & self.y.simd_eq(zero) & self.z.simd_eq(zero)
    }

    /// True where every component is finite ([`crate::math::is_finite`]).
    #[inline(always)]
    pub fn is_finite(self) -> L {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }

    #[inline(always)]
    pub fn select(mask: L, a: Self, b: Self) -> Self {
        Self {
            x: L::select(mask, a.x, b.x),
            y: L::select(mask, a.y, b.y),
            z: L::select(mask, a.z, b.z),
        }
    }

    /// The vertex normals `n` interpolated at the barycentrics `b` and normalised, or `ng`
    /// where they cancel, as the scalar code interpolates them (`n0 * b0 + n1 * b1 + n2 * b2`).
    #[inline(always)]
    pub fn interpolated_normal(n: [Self; 3], b: [L; 3], ng: Self, one: L, zero: L) -> Self {
        let (ns, _) = n[0]
            .scale(b[0])
            .add(n[1].scale(b[1]))
            .add(n[2].scale(b[2]))
            .normalize_or_zero(one, zero);
        Self::select(ns.is_zero(zero), ng, ns)
    }

    /// glam's `normalize_or_zero` (`self · (1 / length)` where that reciprocal is finite and
    /// positive), and the length it divided by.
    #[inline(always)]
    pub fn normalize_or_zero(self, one: L, zero: L) -> (Self, L) {
        let length = self.dot(self).sqrt();
        let rcp = one / length;
        let ok = rcp.is_finite() & rcp.simd_gt(zero);
        (
            Self::select(ok, self.scale(rcp), Self::splat_lanes(zero)),
            length,
        )
    }
}

/// [`crate::geometry::triangle_point`] lane by lane, given the edges `e1 = p1 − p0` and
/// `e2 = p2 − p0`: the point with barycentrics `(b1, b2)` and its error bound.
#[inline(always)]
pub(crate) fn triangle_point<L: Lanes<N>>(
    isa: L::Isa,
    b1: L,
    b2: L,
    p0: V3<L>,
    e1: V3<L>,
    e2: V3<L>,
) -> (V3<L>, V3<L>) {
    let x = e1.scale(b1);
    let y = e2.scale(b2);
    let p = p0.add(x.add(y));
    let p_err = p0
        .abs()
        .scale(L::splat(isa, gamma(1)))
        .add(x.abs().add(y.abs()).scale(L::splat(isa, gamma(6))));
    (p, p_err)
}

/// `f32::max(x, 0.0)` lane by lane: `x` where it is above 0, else 0 (NaN gives 0, as
/// `maxnum` does; a zero of either sign gives +0, which only a sign test could tell apart
/// from the scalar's, and none follows).
#[inline(always)]
pub(crate) fn max_zero<L: Lanes<N>>(x: L, zero: L) -> L {
    L::select(x.simd_gt(zero), x, zero)
}

/// `f32::min(x, b)` for a `b` that is never NaN: `b` where `x` is NaN, as `minnum` gives.
#[inline(always)]
pub(crate) fn min_num<L: Lanes<N>>(x: L, b: L) -> L {
    L::select(x.simd_lt(b), x, b)
}

/// Eight 3-vectors stored by axis: the path state of a batch between its stages.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Soa3 {
    pub x: [f32; N],
    pub y: [f32; N],
    pub z: [f32; N],
}

impl Soa3 {
    /// Every lane `v`.
    #[inline(always)]
    #[must_use]
    pub fn splat(v: Vec3) -> Self {
        Self {
            x: [v.x; N],
            y: [v.y; N],
            z: [v.z; N],
        }
    }

    /// Lane `l`.
    #[inline(always)]
    #[must_use]
    pub fn get(&self, l: usize) -> Vec3 {
        Vec3::new(self.x[l], self.y[l], self.z[l])
    }

    /// Sets lane `l`.
    #[inline(always)]
    pub fn set(&mut self, l: usize, v: Vec3) {
        self.x[l] = v.x;
        self.y[l] = v.y;
        self.z[l] = v.z;
    }

    #[inline(always)]
    pub(crate) fn load<L: Lanes<N>>(&self, isa: L::Isa) -> V3<L> {
        V3 {
            x: L::new(isa, self.x),
            y: L::new(isa, self.y),
            z: L::new(isa, self.z),
        }
    }

    #[inline(always)]
    pub(crate) fn store<L: Lanes<N>>(&mut self, v: V3<L>) {
        self.x = v.x.to_array();
        self.y = v.y.to_array();
        self.z = v.z.to_array();
    }
}
