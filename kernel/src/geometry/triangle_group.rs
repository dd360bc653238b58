//! Four triangles tested against one ray at once: the watertight test of
//! [`WatertightRay::intersect`] computed in four SIMD lanes, bit for bit.
//!
//! Why: a leaf holds up to four triangles ([`crate::bvh::MAX_LEAF_PRIMS`]), and the scalar
//! test runs once per triangle with a branch on each of its rejections. In lanes, a leaf costs
//! about one test, and its rejections are masks (Embree's Triangle4 layout, with the
//! watertight test of Woop, Benthin and Wald instead of Möller–Trumbore).
//!
//! Exactness: every lane performs the scalar test's operations in the scalar test's order —
//! subtraction, multiplication, addition, division, comparisons, `abs` and `max` — which are
//! correctly rounded IEEE operations on SSE2, NEON, wasm SIMD and glam's scalar fallback alike;
//! no fused multiply-add, no approximate reciprocal. The two places where lanes could differ
//! are handled: `max` (SSE's `maxps` and `f32::max` disagree only on NaN, and a lane reaches the
//! maxima only with a finite determinant, which needs every coordinate finite), and the f64
//! recomputation of edge functions that are exactly zero, which is done for that lane by the
//! scalar test itself. The tests below compare lane and scalar results bit for bit.

// glam's Vec4 is banned in the kernel (kernel/clippy.toml) for its dot products and fused
// multiply-adds; here it is used for lane-wise operations only, as in the wide BVH's slab test.
#![allow(clippy::disallowed_types)]

use super::triangle::{TriangleHit, WatertightRay};
use crate::math::gamma;
use glam::{BVec4A, Vec3, Vec4};

/// Triangles per group (SIMD lanes).
pub const GROUP_WIDTH: usize = 4;

/// The vertices of up to four triangles, structure of arrays: `v[vertex][axis][lane]`
/// (144 bytes). Unused lanes repeat a used one (see [`TriangleGroup::from_triangles`]); a lane
/// mask says which lanes a test reports.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleGroup {
    pub v: [[[f32; GROUP_WIDTH]; 3]; 3],
}

impl Default for TriangleGroup {
    fn default() -> Self {
        Self {
            v: [[[0.0; GROUP_WIDTH]; 3]; 3],
        }
    }
}

impl TriangleGroup {
    /// Lane `lane`'s vertices.
    #[inline]
    #[must_use]
    pub fn triangle(&self, lane: usize) -> [Vec3; 3] {
        let v = &self.v;
        [0, 1, 2].map(|k| Vec3::new(v[k][0][lane], v[k][1][lane], v[k][2][lane]))
    }

    /// Sets lane `lane` to the triangle `tri`.
    #[inline]
    pub fn set(&mut self, lane: usize, tri: [Vec3; 3]) {
        for (vertex, p) in self.v.iter_mut().zip(tri) {
            for (axis, c) in vertex.iter_mut().zip(p.to_array()) {
                axis[lane] = c;
            }
        }
    }

    /// A group of the first four (or fewer) of `tris`; lanes past them repeat the last
    /// triangle, so that a lane left out of a mask still holds ordinary numbers.
    #[must_use]
    pub fn from_triangles(tris: &[[Vec3; 3]]) -> Self {
        let mut g = Self::default();
        if let Some(last) = tris.last() {
            for lane in 0..GROUP_WIDTH {
                g.set(lane, *tris.get(lane).unwrap_or(last));
            }
        }
        g
    }
}

/// What [`WatertightRay::intersect_group`] found: lane `i` hit at `t[i]` with barycentrics
/// `b1[i]`, `b2[i]` if bit `i` of `mask` is set.
#[derive(Clone, Copy, Debug)]
pub struct GroupHits {
    pub mask: u32,
    pub t: [f32; GROUP_WIDTH],
    pub b1: [f32; GROUP_WIDTH],
    pub b2: [f32; GROUP_WIDTH],
}

impl GroupHits {
    /// Lane `lane`'s hit, if it has one.
    #[inline]
    #[must_use]
    pub fn get(&self, lane: usize) -> Option<TriangleHit> {
        (self.mask >> lane & 1 != 0).then(|| TriangleHit {
            t: self.t[lane],
            b1: self.b1[lane],
            b2: self.b2[lane],
        })
    }
}

impl WatertightRay {
    /// [`Self::intersect`] of the lanes of `group` selected by `lanes` (bit `i`: lane `i`),
    /// each against `t_max`: the same hits, bit for bit.
    #[inline(always)]
    #[must_use]
    pub fn intersect_group(&self, t_max: f32, group: &TriangleGroup, lanes: u32) -> GroupHits {
        let kz = self.k[2];
        let o = self.o.to_array();
        let (sx, sy, sz) = (
            Vec4::splat(self.sx),
            Vec4::splat(self.sy),
            Vec4::splat(self.sz),
        );
        // The permutation is the rotation that makes kz the last axis (`WatertightRay::new`:
        // kx = kz + 1, ky = kx + 1, mod 3). Spelt out per case, so the loads need no bounds
        // checks; the branch goes the same way for every group a ray tests.
        let rotate = |v: [Vec4; 3]| match kz {
            0 => [v[1], v[2], v[0]],
            1 => [v[2], v[0], v[1]],
            _ => v,
        };
        let [ox, oy, oz] = rotate(o.map(Vec4::splat));
        // Translated and permuted vertices.
        let vertex = |k: usize| {
            let [x, y, z] = rotate(group.v[k].map(Vec4::from_array));
            [x - ox, y - oy, z - oz]
        };
        let [mut ax, mut ay, mut az] = vertex(0);
        let [mut bx, mut by, mut bz] = vertex(1);
        let [mut cx, mut cy, mut cz] = vertex(2);
        ax += sx * az;
        ay += sy * az;
        bx += sx * bz;
        by += sy * bz;
        cx += sx * cz;
        cy += sy * cz;
        let e0 = bx * cy - by * cx;
        let e1 = cx * ay - cy * ax;
        let e2 = ax * by - ay * bx;
        let zero = Vec4::ZERO;
        let lanes = lanes & 0xF;
        // Lanes with an edge function exactly zero are decided in f64 by the scalar test.
        let on_edge = (e0.cmpeq(zero) | e1.cmpeq(zero) | e2.cmpeq(zero)).bitmask() & lanes;
        let negative = e0.cmplt(zero) | e1.cmplt(zero) | e2.cmplt(zero);
        let positive = e0.cmpgt(zero) | e1.cmpgt(zero) | e2.cmpgt(zero);
        let det = e0 + e1 + e2;
        let mut ok: BVec4A = !(negative & positive) & det.cmpne(zero) & det.is_finite_mask();
        let mut hits = GroupHits {
            mask: 0,
            t: [0.0; GROUP_WIDTH],
            b1: [0.0; GROUP_WIDTH],
            b2: [0.0; GROUP_WIDTH],
        };
        // Most groups a ray reaches it misses: stop before the distance and its error bound.
        if ok.bitmask() & lanes & !on_edge == 0 {
            return self.intersect_on_edge(t_max, group, on_edge, hits);
        }
        let max_z_world = az.abs().max(bz.abs()).max(cz.abs());
        az *= sz;
        bz *= sz;
        cz *= sz;
        let t_scaled = e0 * az + e1 * bz + e2 * cz;
        let t_max_det = Vec4::splat(t_max) * det;
        let det_neg = det.cmplt(zero);
        let det_pos = det.cmpgt(zero);
        ok &= !(det_neg & (t_scaled.cmpge(zero) | t_scaled.cmplt(t_max_det)));
        ok &= !(det_pos & (t_scaled.cmple(zero) | t_scaled.cmpgt(t_max_det)));
        if ok.bitmask() & lanes & !on_edge == 0 {
            return self.intersect_on_edge(t_max, group, on_edge, hits);
        }
        let inv_det = Vec4::ONE / det;
        let b1 = e1 * inv_det;
        let b2 = e2 * inv_det;
        let t = t_scaled * inv_det;
        let max_zt = az.abs().max(bz.abs()).max(cz.abs());
        let delta_z = Vec4::splat(gamma(3)) * max_zt;
        let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
        let max_yt = ay.abs().max(by.abs()).max(cy.abs());
        let delta_x = Vec4::splat(gamma(5)) * (max_xt + max_z_world);
        let delta_y = Vec4::splat(gamma(5)) * (max_yt + max_z_world);
        let delta_e = Vec4::splat(2.0)
            * (Vec4::splat(gamma(2)) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = Vec4::splat(3.0)
            * (Vec4::splat(gamma(3)) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
            * inv_det.abs();
        ok &= t.cmpgt(delta_t);
        hits = GroupHits {
            mask: ok.bitmask() & lanes & !on_edge,
            t: t.to_array(),
            b1: b1.to_array(),
            b2: b2.to_array(),
        };
        self.intersect_on_edge(t_max, group, on_edge, hits)
    }

    /// `hits` with the lanes `on_edge` (an edge function exactly zero in f32) decided by the
    /// scalar test, which recomputes their edge functions in f64.
    #[inline(always)]
    fn intersect_on_edge(
        &self,
        t_max: f32,
        group: &TriangleGroup,
        on_edge: u32,
        mut hits: GroupHits,
    ) -> GroupHits {
        let mut rest = on_edge;
        while rest != 0 {
            let lane = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            let [p0, p1, p2] = group.triangle(lane);
            if let Some(h) = self.intersect(t_max, p0, p1, p2) {
                hits.mask |= 1 << lane;
                hits.t[lane] = h.t;
                hits.b1[lane] = h.b1;
                hits.b2[lane] = h.b2;
            }
        }
        hits
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{IndependentSampler, Sampler};

    /// The lane test's answer for every lane equals the scalar test's, bit for bit.
    fn assert_same(ray: &WatertightRay, t_max: f32, tris: &[[Vec3; 3]; GROUP_WIDTH]) -> u32 {
        let group = {
            let mut g = TriangleGroup::default();
            for (lane, &t) in tris.iter().enumerate() {
                g.set(lane, t);
            }
            g
        };
        let bits = |h: Option<TriangleHit>| h.map(|h| [h.t, h.b1, h.b2].map(f32::to_bits));
        let mut hit_lanes = 0;
        for lanes in [0xF, 0x5, 0xA, 0x1, 0x8, 0x0] {
            let hits = ray.intersect_group(t_max, &group, lanes);
            for (lane, &[p0, p1, p2]) in tris.iter().enumerate() {
                let scalar = if lanes >> lane & 1 != 0 {
                    ray.intersect(t_max, p0, p1, p2)
                } else {
                    None
                };
                assert_eq!(
                    bits(hits.get(lane)),
                    bits(scalar),
                    "lane {lane} of {tris:?}, mask {lanes:#x}, t_max {t_max}"
                );
                if lanes == 0xF && scalar.is_some() {
                    hit_lanes += 1;
                }
            }
        }
        hit_lanes
    }

    struct Rng(IndependentSampler);

    impl Rng {
        fn f(&mut self) -> f32 {
            self.0.next_1d()
        }
        fn vec(&mut self, scale: f32) -> Vec3 {
            Vec3::new(self.f() - 0.5, self.f() - 0.5, self.f() - 0.5) * scale
        }
    }

    #[test]
    fn lanes_match_the_scalar_test_on_random_triangles() {
        let mut rng = Rng(IndependentSampler::new(7, 0, 0));
        let mut hits = 0;
        for i in 0..20_000 {
            let scale = [1e-4, 1.0, 1e4][i % 3];
            let o = rng.vec(2.0 * scale);
            let d = rng.vec(1.0);
            let ray = WatertightRay::new(o, d);
            // Triangles around a point on the ray, so that about half are hit.
            let c = o + d * (rng.f() * 4.0 - 1.0);
            let tris = [0; GROUP_WIDTH]
                .map(|_| [rng.vec(scale), rng.vec(scale), rng.vec(scale)].map(|v| c + v));
            let t_max = [f32::INFINITY, 0.5, 2.0][i % 3];
            hits += assert_same(&ray, t_max, &tris);
        }
        assert!(hits > 5_000, "only {hits} hits: the comparison says little");
    }

    #[test]
    fn lanes_match_the_scalar_test_on_edges_vertices_and_odd_numbers() {
        // A square split in two along its diagonal, rays through the shared edge, through a
        // vertex and along the plane; degenerate, NaN and infinite triangles beside them.
        let (a, b, c, d) = (Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
        let nan = Vec3::splat(f32::NAN);
        let inf = Vec3::new(f32::INFINITY, 0.0, 0.0);
        let tris = [
            [[a, b, c], [a, c, d], [a, a, b], [nan, b, c]],
            [[a, c, d], [a, b, c], [inf, b, c], [a, b, b]],
        ];
        let mut hits = 0;
        for o in [
            Vec3::new(0.5, 0.5, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 3.0),
            Vec3::new(0.25, 0.75, 1.0),
            Vec3::new(-1.0, 0.5, 0.0),
        ] {
            for dir in [-Vec3::Z, Vec3::new(0.1, -0.2, -1.0), Vec3::X, Vec3::Z] {
                let ray = WatertightRay::new(o, dir);
                for t_max in [f32::INFINITY, 1.0, 0.999_999_9, 1.000_000_1] {
                    for group in &tris {
                        hits += assert_same(&ray, t_max, group);
                    }
                }
            }
        }
        assert!(hits > 10, "only {hits} hits");
        // NaN and infinite rays.
        for (o, dir) in [
            (Vec3::splat(f32::NAN), -Vec3::Z),
            (Vec3::new(0.5, 0.5, 1.0), Vec3::splat(f32::NAN)),
            (Vec3::new(0.5, 0.5, f32::INFINITY), -Vec3::Z),
            (Vec3::new(0.5, 0.5, 1.0), Vec3::ZERO),
        ] {
            let ray = WatertightRay::new(o, dir);
            for group in &tris {
                assert_same(&ray, f32::INFINITY, group);
            }
        }
    }

    #[test]
    fn groups_hold_their_triangles_and_pad_with_the_last() {
        let t = |k: f32| [Vec3::splat(k), Vec3::splat(k + 1.0), Vec3::splat(k + 2.0)];
        let g = TriangleGroup::from_triangles(&[t(0.0), t(10.0)]);
        assert_eq!(g.triangle(0), t(0.0));
        assert_eq!(g.triangle(1), t(10.0));
        assert_eq!(g.triangle(2), t(10.0));
        assert_eq!(g.triangle(3), t(10.0));
        assert_eq!(TriangleGroup::from_triangles(&[]), TriangleGroup::default());
    }
}
