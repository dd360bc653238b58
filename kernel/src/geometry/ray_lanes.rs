//! Eight rays at once: the watertight triangle test of [`WatertightRay::intersect`] with one
//! ray per SIMD lane, against one triangle (the transpose of [`super::TriangleGroup`]'s four
//! triangles against one ray), for the packets of [`crate::bvh::WideBvh::traverse_packet`].
//!
//! Why: the samples of one pixel that a batched path tracer advances together
//! ([`crate::integrator::render_pixel_batched`]) start as nearly the same ray, so a packet walks
//! the tree once for all of them and tests each triangle it reaches once for all of them.
//!
//! Exactness: each lane performs the scalar test's operations in the scalar test's order on
//! its own ray (subtraction, multiplication, addition, division, comparisons, `abs`, and a
//! maximum that only ever sees numbers, as in [`super::TriangleGroup`]); the permutation that
//! makes a ray's dominant axis the last is a per-lane selection, which moves values without
//! rounding them. Lanes with an edge function exactly zero are decided by the scalar test
//! itself (its f64 recomputation). The lanes are plain arrays with element-wise loops of fixed
//! length, which LLVM turns into vector instructions on every target, so no target-specific
//! code is needed and every target computes the same bits.

use super::triangle::{TriangleHit, WatertightRay};
use crate::math::gamma;
use core::ops::{Add, Div, Mul, Sub};
use glam::Vec3;

/// Rays per packet.
pub const PACKET: usize = 8;

/// One `f32` per ray of a packet: an `f32x8` of `wide` on x86-64 (one AVX register, or two SSE
/// ones), an array elsewhere (element-wise loops); both compute each lane with the one IEEE
/// operation the scalar code uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct F8(pub [f32; PACKET]);

/// A per-lane condition: lane `i` of a packet is true where bit `i` is set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct M8(pub u32);

// (Not on soft-float x86-64, where `wide`'s fallback maximum would keep a NaN.)
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
mod simd {
    //! `F8` through `wide`'s safe wrappers: `vsubps`/`vmulps`/`vdivps`/`vaddps`, ordered
    //! compares, `vmaxps`/`vminps` (`fast_max`/`fast_min`: the second operand where either is
    //! NaN), `vblendvps`, `vandps`, `vmovmskps`, or their SSE pairs.
    use super::{F8, M8, PACKET};
    use wide::f32x8;

    #[inline(always)]
    fn v(a: F8) -> f32x8 {
        f32x8::new(a.0)
    }

    #[inline(always)]
    fn f(x: f32x8) -> F8 {
        F8(x.to_array())
    }

    #[inline(always)]
    fn mask(m: M8) -> f32x8 {
        let lanes: [f32; PACKET] =
            core::array::from_fn(|i| f32::from_bits(0u32.wrapping_sub(m.0 >> i & 1)));
        f32x8::new(lanes)
    }

    impl F8 {
        #[inline(always)]
        pub(super) fn add_(self, b: Self) -> Self {
            f(v(self) + v(b))
        }
        #[inline(always)]
        pub(super) fn sub_(self, b: Self) -> Self {
            f(v(self) - v(b))
        }
        #[inline(always)]
        pub(super) fn mul_(self, b: Self) -> Self {
            f(v(self) * v(b))
        }
        #[inline(always)]
        pub(super) fn div_(self, b: Self) -> Self {
            f(v(self) / v(b))
        }
        #[inline(always)]
        pub(super) fn lt_(self, b: Self) -> M8 {
            M8(v(self).simd_lt(v(b)).to_bitmask())
        }
        #[inline(always)]
        pub(super) fn le_(self, b: Self) -> M8 {
            M8(v(self).simd_le(v(b)).to_bitmask())
        }
        #[inline(always)]
        pub(super) fn gt_(self, b: Self) -> M8 {
            M8(v(self).simd_gt(v(b)).to_bitmask())
        }
        #[inline(always)]
        pub(super) fn ge_(self, b: Self) -> M8 {
            M8(v(self).simd_ge(v(b)).to_bitmask())
        }
        #[inline(always)]
        pub(super) fn eq_(self, b: Self) -> M8 {
            M8(v(self).simd_eq(v(b)).to_bitmask())
        }
        #[inline(always)]
        pub(super) fn ne_(self, b: Self) -> M8 {
            M8(v(self).simd_ne(v(b)).to_bitmask())
        }
        #[inline(always)]
        pub(super) fn abs_(self) -> Self {
            f(v(self).abs())
        }
        #[inline(always)]
        pub(super) fn max_or_(self, b: Self) -> Self {
            f(v(self).fast_max(v(b)))
        }
        #[inline(always)]
        pub(super) fn min_or_(self, b: Self) -> Self {
            f(v(self).fast_min(v(b)))
        }
        #[inline(always)]
        pub(super) fn select_(m: M8, a: Self, b: Self) -> Self {
            f(mask(m).select(v(a), v(b)))
        }
        #[inline(always)]
        pub(super) fn is_finite_(self) -> M8 {
            M8(v(self).is_finite().to_bitmask())
        }
    }
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
mod simd {
    //! `F8` as arrays, lane by lane.
    use super::{F8, M8, PACKET};

    macro_rules! lanewise {
        ($name:ident, $op:tt) => {
            #[inline(always)]
            pub(super) fn $name(self, b: Self) -> Self {
                Self(core::array::from_fn(|i| self.0[i] $op b.0[i]))
            }
        };
    }

    macro_rules! compare {
        ($name:ident, $op:tt) => {
            #[inline(always)]
            pub(super) fn $name(self, b: Self) -> M8 {
                let mut m = 0;
                for i in 0..PACKET {
                    m |= u32::from(self.0[i] $op b.0[i]) << i;
                }
                M8(m)
            }
        };
    }

    impl F8 {
        lanewise!(add_, +);
        lanewise!(sub_, -);
        lanewise!(mul_, *);
        lanewise!(div_, /);
        compare!(lt_, <);
        compare!(le_, <=);
        compare!(gt_, >);
        compare!(ge_, >=);
        compare!(eq_, ==);
        compare!(ne_, !=);
        #[inline(always)]
        pub(super) fn abs_(self) -> Self {
            Self(self.0.map(|x| f32::from_bits(x.to_bits() & 0x7FFF_FFFF)))
        }
        #[inline(always)]
        pub(super) fn max_or_(self, b: Self) -> Self {
            Self(core::array::from_fn(|i| {
                if self.0[i] > b.0[i] {
                    self.0[i]
                } else {
                    b.0[i]
                }
            }))
        }
        #[inline(always)]
        pub(super) fn min_or_(self, b: Self) -> Self {
            Self(core::array::from_fn(|i| {
                if self.0[i] < b.0[i] {
                    self.0[i]
                } else {
                    b.0[i]
                }
            }))
        }
        #[inline(always)]
        pub(super) fn select_(m: M8, a: Self, b: Self) -> Self {
            Self(core::array::from_fn(|i| {
                if m.0 >> i & 1 != 0 {
                    a.0[i]
                } else {
                    b.0[i]
                }
            }))
        }
        #[inline(always)]
        pub(super) fn is_finite_(self) -> M8 {
            let mut m = 0;
            for i in 0..PACKET {
                m |= u32::from(self.0[i].to_bits() & 0x7F80_0000 != 0x7F80_0000) << i;
            }
            M8(m)
        }
    }
}

impl F8 {
    #[inline(always)]
    #[must_use]
    pub const fn splat(x: f32) -> Self {
        Self([x; PACKET])
    }
    #[inline(always)]
    #[must_use]
    pub fn lt(self, b: Self) -> M8 {
        self.lt_(b)
    }
    #[inline(always)]
    #[must_use]
    pub fn le(self, b: Self) -> M8 {
        self.le_(b)
    }
    #[inline(always)]
    #[must_use]
    pub fn gt(self, b: Self) -> M8 {
        self.gt_(b)
    }
    #[inline(always)]
    #[must_use]
    pub fn ge(self, b: Self) -> M8 {
        self.ge_(b)
    }
    #[inline(always)]
    #[must_use]
    pub fn eq(self, b: Self) -> M8 {
        self.eq_(b)
    }
    #[inline(always)]
    #[must_use]
    pub fn ne(self, b: Self) -> M8 {
        self.ne_(b)
    }
    /// `|self|` (the sign bit cleared).
    #[inline(always)]
    #[must_use]
    pub fn abs(self) -> Self {
        self.abs_()
    }
    /// `self` where it is greater than `b`, else `b`: `max` for numbers, and `b` where either
    /// is NaN (SSE's `maxps`, the slab test's `max_ignoring_nan`).
    #[inline(always)]
    #[must_use]
    pub fn max_or(self, b: Self) -> Self {
        self.max_or_(b)
    }
    /// `self` where it is less than `b`, else `b` (`minps`).
    #[inline(always)]
    #[must_use]
    pub fn min_or(self, b: Self) -> Self {
        self.min_or_(b)
    }
    /// `a` where `m`, else `b`.
    #[inline(always)]
    #[must_use]
    pub fn select(m: M8, a: Self, b: Self) -> Self {
        Self::select_(m, a, b)
    }
    #[inline(always)]
    #[must_use]
    pub fn is_finite(self) -> M8 {
        self.is_finite_()
    }
}

impl core::ops::Add for F8 {
    type Output = Self;
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        self.add_(b)
    }
}

impl core::ops::Sub for F8 {
    type Output = Self;
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        self.sub_(b)
    }
}

impl core::ops::Mul for F8 {
    type Output = Self;
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        self.mul_(b)
    }
}

impl core::ops::Div for F8 {
    type Output = Self;
    #[inline(always)]
    fn div(self, b: Self) -> Self {
        self.div_(b)
    }
}

impl M8 {
    #[inline(always)]
    #[must_use]
    pub fn and(self, b: Self) -> Self {
        Self(self.0 & b.0)
    }
    #[inline(always)]
    #[must_use]
    pub fn or(self, b: Self) -> Self {
        Self(self.0 | b.0)
    }
    #[inline(always)]
    #[must_use]
    pub fn and_not(self, b: Self) -> Self {
        Self(self.0 & !b.0)
    }
    /// Bit `i` set where lane `i` is true.
    #[inline(always)]
    #[must_use]
    pub fn bits(self) -> u32 {
        self.0
    }
}

/// The rays of a packet, structure of arrays, with what the slab and triangle tests need per
/// ray precomputed as [`WatertightRay::new`] and the BVH's slab test compute it for one ray.
#[derive(Clone, Copy, Debug)]
pub struct RayLanes {
    /// `o[axis]`, `inv_d[axis]`: origins and reciprocal directions (the slab test).
    pub o: [F8; 3],
    pub inv_d: [F8; 3],
    /// Lanes whose reciprocal direction is negative on `axis` (the slab's near plane is the
    /// box's upper one).
    pub neg: [M8; 3],
    /// Each lane's scalar test (for exact-zero edge functions, and the permutation).
    pub scalar: [WatertightRay; PACKET],
    /// Lanes whose dominant axis `kz` is 0, and is 1 (else 2).
    kz0: M8,
    kz1: M8,
    sx: F8,
    sy: F8,
    sz: F8,
}

/// Lane `i` of `hits` is a hit at `t[i]`, barycentrics `b1[i]`, `b2[i]`, where bit `i` of `mask`.
#[derive(Clone, Copy, Debug)]
pub struct LaneHits {
    pub mask: u32,
    pub t: F8,
    pub b1: F8,
    pub b2: F8,
}

impl RayLanes {
    /// The packet of rays `o[i] + t·d[i]`; lanes beyond those a caller uses may hold any ray
    /// (their results are masked off).
    #[must_use]
    #[inline]
    pub fn new(o: &[Vec3; PACKET], d: &[Vec3; PACKET]) -> Self {
        let scalar: [WatertightRay; PACKET] =
            core::array::from_fn(|i| WatertightRay::new(o[i], d[i]));
        let axis = |v: &[Vec3; PACKET], a: usize| F8(core::array::from_fn(|i| v[i][a]));
        let inv: [Vec3; PACKET] = core::array::from_fn(|i| Vec3::ONE / d[i]);
        let inv_d = [axis(&inv, 0), axis(&inv, 1), axis(&inv, 2)];
        let zero = F8::splat(0.0);
        Self {
            o: [axis(o, 0), axis(o, 1), axis(o, 2)],
            inv_d,
            neg: inv_d.map(|v| v.lt(zero)),
            kz0: M8((0..PACKET).fold(0, |m, i| m | u32::from(scalar[i].k[2] == 0) << i)),
            kz1: M8((0..PACKET).fold(0, |m, i| m | u32::from(scalar[i].k[2] == 1) << i)),
            sx: F8(core::array::from_fn(|i| scalar[i].sx)),
            sy: F8(core::array::from_fn(|i| scalar[i].sy)),
            sz: F8(core::array::from_fn(|i| scalar[i].sz)),
            scalar,
        }
    }

    /// `(v[kx], v[ky], v[kz])` per lane (the rotation that makes `kz` the last axis,
    /// [`WatertightRay::new`]).
    #[inline(always)]
    fn permute(&self, v: [F8; 3]) -> [F8; 3] {
        let pick = |a: F8, b: F8, c: F8| F8::select(self.kz0, a, F8::select(self.kz1, b, c));
        [
            pick(v[1], v[2], v[0]),
            pick(v[2], v[0], v[1]),
            pick(v[0], v[1], v[2]),
        ]
    }

    /// [`WatertightRay::intersect`] of the triangle `(p0, p1, p2)` with the lanes of `lanes`,
    /// lane `i` against `t_max[i]`: the same hits, bit for bit.
    #[inline(always)]
    #[must_use]
    pub fn intersect(&self, t_max: &F8, p0: Vec3, p1: Vec3, p2: Vec3, lanes: u32) -> LaneHits {
        let vertex = |p: Vec3| {
            self.permute([
                F8::splat(p.x).sub(self.o[0]),
                F8::splat(p.y).sub(self.o[1]),
                F8::splat(p.z).sub(self.o[2]),
            ])
        };
        let [mut ax, mut ay, mut az] = vertex(p0);
        let [mut bx, mut by, mut bz] = vertex(p1);
        let [mut cx, mut cy, mut cz] = vertex(p2);
        let (sx, sy, sz) = (self.sx, self.sy, self.sz);
        ax = ax.add(sx.mul(az));
        ay = ay.add(sy.mul(az));
        bx = bx.add(sx.mul(bz));
        by = by.add(sy.mul(bz));
        cx = cx.add(sx.mul(cz));
        cy = cy.add(sy.mul(cz));
        let e0 = bx.mul(cy).sub(by.mul(cx));
        let e1 = cx.mul(ay).sub(cy.mul(ax));
        let e2 = ax.mul(by).sub(ay.mul(bx));
        let zero = F8::splat(0.0);
        let on_edge = e0.eq(zero).or(e1.eq(zero)).or(e2.eq(zero)).bits() & lanes;
        let negative = e0.lt(zero).or(e1.lt(zero)).or(e2.lt(zero));
        let positive = e0.gt(zero).or(e1.gt(zero)).or(e2.gt(zero));
        let det = e0.add(e1).add(e2);
        let mut ok = det
            .ne(zero)
            .and(det.is_finite())
            .and_not(negative.and(positive));
        let mut hits = LaneHits {
            mask: 0,
            t: zero,
            b1: zero,
            b2: zero,
        };
        if ok.bits() & lanes & !on_edge == 0 {
            return self.intersect_on_edge(t_max, p0, p1, p2, on_edge, hits);
        }
        let max_z_world = az.abs().max_or(bz.abs()).max_or(cz.abs());
        az = az.mul(sz);
        bz = bz.mul(sz);
        cz = cz.mul(sz);
        let t_scaled = e0.mul(az).add(e1.mul(bz)).add(e2.mul(cz));
        let t_max_det = t_max.mul(det);
        let det_neg = det.lt(zero);
        let det_pos = det.gt(zero);
        ok = ok.and_not(det_neg.and(t_scaled.ge(zero).or(t_scaled.lt(t_max_det))));
        ok = ok.and_not(det_pos.and(t_scaled.le(zero).or(t_scaled.gt(t_max_det))));
        if ok.bits() & lanes & !on_edge == 0 {
            return self.intersect_on_edge(t_max, p0, p1, p2, on_edge, hits);
        }
        let inv_det = F8::splat(1.0).div(det);
        let b1 = e1.mul(inv_det);
        let b2 = e2.mul(inv_det);
        let t = t_scaled.mul(inv_det);
        let max_zt = az.abs().max_or(bz.abs()).max_or(cz.abs());
        let delta_z = F8::splat(gamma(3)).mul(max_zt);
        let max_xt = ax.abs().max_or(bx.abs()).max_or(cx.abs());
        let max_yt = ay.abs().max_or(by.abs()).max_or(cy.abs());
        let g5 = F8::splat(gamma(5));
        let delta_x = g5.mul(max_xt.add(max_z_world));
        let delta_y = g5.mul(max_yt.add(max_z_world));
        let delta_e = F8::splat(2.0).mul(
            F8::splat(gamma(2))
                .mul(max_xt)
                .mul(max_yt)
                .add(delta_y.mul(max_xt))
                .add(delta_x.mul(max_yt)),
        );
        let max_e = e0.abs().max_or(e1.abs()).max_or(e2.abs());
        let delta_t = F8::splat(3.0)
            .mul(
                F8::splat(gamma(3))
                    .mul(max_e)
                    .mul(max_zt)
                    .add(delta_e.mul(max_zt))
                    .add(delta_z.mul(max_e)),
            )
            .mul(inv_det.abs());
        ok = ok.and(t.gt(delta_t));
        hits = LaneHits {
            mask: ok.bits() & lanes & !on_edge,
            t,
            b1,
            b2,
        };
        self.intersect_on_edge(t_max, p0, p1, p2, on_edge, hits)
    }

    /// `hits` with the lanes `on_edge` decided by each lane's scalar test.
    #[inline(always)]
    fn intersect_on_edge(
        &self,
        t_max: &F8,
        p0: Vec3,
        p1: Vec3,
        p2: Vec3,
        on_edge: u32,
        mut hits: LaneHits,
    ) -> LaneHits {
        let mut rest = on_edge;
        while rest != 0 {
            let lane = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if let Some(TriangleHit { t, b1, b2 }) =
                self.scalar[lane].intersect(t_max.0[lane], p0, p1, p2)
            {
                hits.mask |= 1 << lane;
                hits.t.0[lane] = t;
                hits.b1.0[lane] = b1;
                hits.b2.0[lane] = b2;
            }
        }
        hits
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{IndependentSampler, Sampler};

    struct Rng(IndependentSampler);

    impl Rng {
        fn f(&mut self) -> f32 {
            self.0.next_1d()
        }
        fn vec(&mut self, scale: f32) -> Vec3 {
            Vec3::new(self.f() - 0.5, self.f() - 0.5, self.f() - 0.5) * scale
        }
    }

    fn bits(h: Option<TriangleHit>) -> Option<[u32; 3]> {
        h.map(|h| [h.t, h.b1, h.b2].map(f32::to_bits))
    }

    /// Every lane's answer is its scalar test's, bit for bit, whatever the other lanes hold.
    fn assert_same(o: &[Vec3; PACKET], d: &[Vec3; PACKET], t_max: &F8, tri: [Vec3; 3]) -> u32 {
        let rays = RayLanes::new(o, d);
        let mut hit = 0;
        for lanes in [0xFF, 0x55, 0xAA, 0x01, 0x80, 0x00] {
            let h = rays.intersect(t_max, tri[0], tri[1], tri[2], lanes);
            for lane in 0..PACKET {
                let scalar = if lanes >> lane & 1 != 0 {
                    WatertightRay::new(o[lane], d[lane]).intersect(
                        t_max.0[lane],
                        tri[0],
                        tri[1],
                        tri[2],
                    )
                } else {
                    None
                };
                let lane_hit = (h.mask >> lane & 1 != 0).then(|| TriangleHit {
                    t: h.t.0[lane],
                    b1: h.b1.0[lane],
                    b2: h.b2.0[lane],
                });
                assert_eq!(
                    bits(lane_hit),
                    bits(scalar),
                    "lane {lane}: o {:?} d {:?} t_max {} tri {tri:?}",
                    o[lane],
                    d[lane],
                    t_max.0[lane]
                );
                hit += u32::from(lanes == 0xFF && scalar.is_some());
            }
            assert_eq!(h.mask & !lanes, 0);
        }
        hit
    }

    #[test]
    fn lanes_match_the_scalar_test_on_random_rays() {
        let mut rng = Rng(IndependentSampler::new(11, 0, 0));
        let mut hits = 0;
        for i in 0..6_000 {
            let scale = [1e-4, 1.0, 1e4][i % 3];
            let c = rng.vec(2.0 * scale);
            let tri = [rng.vec(scale), rng.vec(scale), rng.vec(scale)].map(|v| c + v);
            // Rays from anywhere through points near the triangle's centre: every dominant
            // axis and sign in the packet, about half the lanes hit.
            let mut o = [Vec3::ZERO; PACKET];
            let mut d = [Vec3::ZERO; PACKET];
            let mut t_max = F8::splat(0.0);
            for lane in 0..PACKET {
                o[lane] = c + rng.vec(4.0 * scale);
                let target = c + rng.vec(0.5 * scale);
                let k = [1.0, 1e-3, 7.0][(i + lane) % 3];
                d[lane] = (target - o[lane]) * k;
                // The target is at t = 1/k: bounds beyond it, and one short of it.
                t_max.0[lane] = [f32::INFINITY, 0.5 / k, 2.0 / k, 1e3 / k][(i / 3 + lane) % 4];
            }
            hits += assert_same(&o, &d, &t_max, tri);
        }
        assert!(hits > 4_000, "only {hits} hits: the comparison says little");
    }

    #[test]
    fn lanes_match_the_scalar_test_on_edges_vertices_and_odd_numbers() {
        let (a, b, c, d) = (Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
        let nan = Vec3::splat(f32::NAN);
        let inf = Vec3::new(f32::INFINITY, 0.0, 0.0);
        let tris = [
            [a, b, c],
            [a, c, d],
            [a, a, b],
            [nan, b, c],
            [inf, b, c],
            [a, b, b],
        ];
        // Through the shared diagonal, a vertex, an edge, along the plane, from behind, and
        // with zero, tiny and huge direction components.
        let origins = [
            Vec3::new(0.5, 0.5, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.5, -1.0),
            Vec3::new(-1.0, 0.5, 0.0),
            Vec3::new(0.25, 0.75, 2.0),
            Vec3::new(0.5, 0.0, 1e-30),
            Vec3::new(0.3, 0.3, -1e10),
            Vec3::new(0.5, 0.5, 0.0),
        ];
        let dirs = [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1e-30, -1e-30, -1.0),
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 0.0),
        ];
        for rot in 0..PACKET {
            let o: [Vec3; PACKET] = core::array::from_fn(|i| origins[(i + rot) % PACKET]);
            let dd: [Vec3; PACKET] = core::array::from_fn(|i| dirs[(i + rot) % PACKET]);
            for tri in tris {
                for t_max in [f32::INFINITY, 1.0, 0.5] {
                    assert_same(&o, &dd, &F8::splat(t_max), tri);
                }
            }
        }
    }
}
