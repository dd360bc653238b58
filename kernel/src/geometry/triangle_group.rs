//! Several triangles tested against one ray at once: the watertight test of
//! [`WatertightRay::intersect`] computed in SIMD lanes, bit for bit.
//!
//! Why: a leaf holds up to [`GROUP_WIDTH`] triangles ([`crate::bvh::MAX_LEAF_PRIMS`]), and the
//! scalar test runs once per triangle with a branch on each of its rejections. In lanes, a
//! leaf costs about one test, and its rejections are masks (Embree's Triangle4 layout, with the
//! watertight test of Woop, Benthin and Wald instead of Möller–Trumbore).
//!
//! Width: eight triangles per group on x86-64 (every build with SSE2), four elsewhere. With
//! eight, the build makes leaves of up to eight (its cost model counts group tests), the tree
//! has half the nodes, and a leaf of five to eight costs one test instead of two. Where the CPU
//! has AVX2 the queries test a group in one 256-bit register ([`crate::simd::Avx8`], chosen at
//! run time, or `wide::f32x8` in builds for `x86-64-v3` or `native`): `bench/embree`'s rays ran
//! 2–26% faster than with groups of four (Intel Xeon, AVX-512, one thread, medians of 6
//! alternating runs), on both the Cornell box and the 1M-triangle sphere. On an x86-64 without
//! AVX2 the eight lanes are two SSE registers, and a leaf of up to four pays for eight; the
//! one tree for both instruction sets is worth that (see [`crate::simd`] for the measurement).
//! The hits do not depend on the width: the closest-hit order (`crate::bvh::closest`) does not
//! depend on how triangles are grouped.
//!
//! Exactness: every lane performs the scalar test's operations in the scalar test's order —
//! subtraction, multiplication, addition, division, comparisons, `abs` and `max` — which are
//! correctly rounded IEEE operations on SSE2, AVX, NEON, wasm SIMD and `wide`'s scalar fallback
//! alike; no fused multiply-add, no approximate reciprocal. The two places where lanes could
//! differ are handled: `max` (SSE's `maxps` and `f32::max` disagree only on NaN, and a lane
//! reaches the maxima only with a finite determinant, which needs every coordinate finite), and
//! the f64 recomputation of edge functions that are exactly zero, which is done for that lane
//! by the scalar test itself. The tests below compare lane and scalar results bit for bit, for
//! both widths on every target.

use super::triangle::{TriangleHit, WatertightRay};
use crate::math::gamma;
use glam::Vec3;

#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
pub use eight::{GroupHits, PairHits, TriangleGroup, GROUP_WIDTH};
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
pub use four::{GroupHits, PairHits, TriangleGroup, GROUP_WIDTH};

/// What a test of `W` triangles in lanes found: lane `i` hit at `t[i]` with barycentrics
/// `b1[i]`, `b2[i]` if bit `i` of `mask` is set.
#[derive(Clone, Copy, Debug)]
pub struct TriangleHits<const W: usize> {
    pub mask: u32,
    pub t: [f32; W],
    pub b1: [f32; W],
    pub b2: [f32; W],
}

impl<const W: usize> TriangleHits<W> {
    /// No hits.
    pub const NONE: Self = Self {
        mask: 0,
        t: [0.0; W],
        b1: [0.0; W],
        b2: [0.0; W],
    };

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

    /// Lane `lane` set to the hit `h`.
    #[inline(always)]
    fn set(&mut self, lane: usize, h: TriangleHit) {
        self.mask |= 1 << lane;
        self.t[lane] = h.t;
        self.b1[lane] = h.b1;
        self.b2[lane] = h.b2;
    }
}

/// The watertight test of `ray` against `W` triangles at once, `v[vertex][axis]` holding one
/// triangle per lane, for the lanes of `lanes`, each against `t_max`: the hits of the lanes
/// decided in f32, written to `out` (only its mask when there are none), and the lanes whose
/// edge function is exactly zero (bits, returned), which the caller decides with the scalar
/// test's f64 recomputation. The same operations in the same order as
/// [`WatertightRay::intersect`], lane by lane, whatever `W` and `L`.
///
/// The hits go to the caller's storage rather than out by value: returned, they were stored in
/// 32-byte halves and copied on in 64-byte loads that straddled those stores, a failed
/// store-to-load forward on every group test (3% of a render of `cbox.obj`, AMD Zen 5).
#[inline(always)]
fn watertight_lanes<const W: usize, L: crate::simd::Lanes<W>>(
    isa: L::Isa,
    ray: &WatertightRay,
    t_max: f32,
    lanes: u32,
    v: [[L; 3]; 3],
    out: &mut TriangleHits<W>,
) -> u32 {
    let splat = |x: f32| L::splat(isa, x);
    let kz = ray.k[2];
    let o = ray.o.to_array();
    let (sx, sy, sz) = (splat(ray.sx), splat(ray.sy), splat(ray.sz));
    // The permutation is the rotation that makes kz the last axis (`WatertightRay::new`:
    // kx = kz + 1, ky = kx + 1, mod 3). Spelt out per case; the branch goes the same way for
    // every group a ray tests. (Tried, 2026-12-06: loads at the axes `ray.k` names instead of
    // the branch. 6% fewer mispredictions in cachegrind's model on the 1k-triangle sphere, as
    // many instructions, and not faster in nine alternating runs; the loads then wait on `k`.)
    let rotate = |v: [L; 3]| match kz {
        0 => [v[1], v[2], v[0]],
        1 => [v[2], v[0], v[1]],
        _ => v,
    };
    let [ox, oy, oz] = rotate([splat(o[0]), splat(o[1]), splat(o[2])]);
    // Translated and permuted vertices.
    let vertex = |k: usize| {
        let [x, y, z] = rotate(v[k]);
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
    let zero = splat(0.0);
    let lanes = lanes & (u32::MAX >> (32 - W));
    // Lanes with an edge function exactly zero are decided in f64 by the scalar test.
    let on_edge = (e0.simd_eq(zero) | e1.simd_eq(zero) | e2.simd_eq(zero)).to_bitmask() & lanes;
    let negative = e0.simd_lt(zero) | e1.simd_lt(zero) | e2.simd_lt(zero);
    let positive = e0.simd_gt(zero) | e1.simd_gt(zero) | e2.simd_gt(zero);
    let det = e0 + e1 + e2;
    let mut ok = !(negative & positive) & det.simd_ne(zero) & det.is_finite();
    // Most groups a ray reaches it misses: stop before the distance and its error bound.
    if ok.to_bitmask() & lanes & !on_edge == 0 {
        out.mask = 0;
        return on_edge;
    }
    let max = |a: L, b: L| a.fast_max(b);
    let max_z_world = max(max(az.abs(), bz.abs()), cz.abs());
    az *= sz;
    bz *= sz;
    cz *= sz;
    let t_scaled = e0 * az + e1 * bz + e2 * cz;
    let t_max_det = splat(t_max) * det;
    let det_neg = det.simd_lt(zero);
    let det_pos = det.simd_gt(zero);
    ok &= !(det_neg & (t_scaled.simd_ge(zero) | t_scaled.simd_lt(t_max_det)));
    ok &= !(det_pos & (t_scaled.simd_le(zero) | t_scaled.simd_gt(t_max_det)));
    if ok.to_bitmask() & lanes & !on_edge == 0 {
        out.mask = 0;
        return on_edge;
    }
    let inv_det = splat(1.0) / det;
    let b1 = e1 * inv_det;
    let b2 = e2 * inv_det;
    let t = t_scaled * inv_det;
    let max_zt = max(max(az.abs(), bz.abs()), cz.abs());
    let delta_z = splat(gamma(3)) * max_zt;
    let max_xt = max(max(ax.abs(), bx.abs()), cx.abs());
    let max_yt = max(max(ay.abs(), by.abs()), cy.abs());
    let delta_x = splat(gamma(5)) * (max_xt + max_z_world);
    let delta_y = splat(gamma(5)) * (max_yt + max_z_world);
    let delta_e =
        splat(2.0) * (splat(gamma(2)) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = max(max(e0.abs(), e1.abs()), e2.abs());
    let delta_t = splat(3.0)
        * (splat(gamma(3)) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
        * inv_det.abs();
    ok &= t.simd_gt(delta_t);
    out.mask = ok.to_bitmask() & lanes & !on_edge;
    out.t = t.to_array();
    out.b1 = b1.to_array();
    out.b2 = b2.to_array();
    on_edge
}

/// The two-group test of AVX-512 ([`crate::simd::Isa::intersect_pair`]).
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
impl TriangleGroup {
    /// [`Self::intersect`] of two groups at once, in sixteen AVX-512 lanes: lane `i` of
    /// `pair[1]` is lane `8 + i` of `lanes` and of the hits, written to `hits`. The same hits,
    /// bit for bit.
    #[inline(always)]
    pub fn intersect_pair(
        isa: crate::simd::Avx512,
        pair: [&Self; 2],
        ray: &WatertightRay,
        t_max: f32,
        lanes: u32,
        hits: &mut PairHits,
    ) {
        use crate::simd::{Avx16, Avx512};
        // (A function, not a closure, so that it can be always inlined: out of line, the
        // intrinsics it calls would be calls too.)
        #[inline(always)]
        fn load(isa: Avx512, a: &[[f32; 8]; 3], b: &[[f32; 8]; 3]) -> [Avx16; 3] {
            [
                Avx16::from_halves(isa, &a[0], &b[0]),
                Avx16::from_halves(isa, &a[1], &b[1]),
                Avx16::from_halves(isa, &a[2], &b[2]),
            ]
        }
        let [a, b] = pair;
        let v = [
            load(isa, &a.v[0], &b.v[0]),
            load(isa, &a.v[1], &b.v[1]),
            load(isa, &a.v[2], &b.v[2]),
        ];
        let mut rest = watertight_lanes(isa, ray, t_max, lanes, v, hits);
        while rest != 0 {
            let lane = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            let [p0, p1, p2] = pair[lane / GROUP_WIDTH].triangle(lane % GROUP_WIDTH);
            if let Some(h) = ray.intersect(t_max, p0, p1, p2) {
                hits.set(lane, h);
            }
        }
    }
}

impl WatertightRay {
    /// [`Self::intersect`] of the lanes of `group` selected by `lanes` (bit `i`: lane `i`),
    /// each against `t_max`: the same hits, bit for bit.
    #[inline(always)]
    #[must_use]
    pub fn intersect_group(&self, t_max: f32, group: &TriangleGroup, lanes: u32) -> GroupHits {
        group.intersect(self, t_max, lanes)
    }
}

/// A group type of `$width` lanes in `wide`'s `$lanes`, aligned to `$align` bytes, which the
/// scene traces with where `$traced` holds (the other width is compiled for its tests).
macro_rules! triangle_group {
    ($module:ident, $lanes:ident, $width:literal, $align:literal, $traced:meta) => {
        #[cfg_attr(not($traced), allow(dead_code))]
        pub mod $module {
            use super::*;
            use crate::simd::{Baseline, Lanes};

            /// Triangles per group (SIMD lanes).
            pub const GROUP_WIDTH: usize = $width;

            /// The vertices of up to [`GROUP_WIDTH`] triangles, structure of arrays:
            /// `v[vertex][axis][lane]` (36 bytes per lane). Unused lanes repeat a used one
            /// (see [`TriangleGroup::from_triangles`]); a lane mask says which lanes a test
            /// reports.
            #[repr(C, align($align))]
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

            /// What [`TriangleGroup::intersect`] found.
            pub type GroupHits = TriangleHits<GROUP_WIDTH>;

            /// What [`crate::simd::Isa::intersect_pair`] found: two groups' lanes, the second
            /// group's from lane [`GROUP_WIDTH`] on.
            pub type PairHits = TriangleHits<{ 2 * GROUP_WIDTH }>;

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

                /// A group of the first [`GROUP_WIDTH`] (or fewer) of `tris`; lanes past them
                /// repeat the last triangle, so that a lane left out of a mask still holds
                /// ordinary numbers.
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

                /// [`WatertightRay::intersect`] of `ray` with the lanes selected by `lanes`
                /// (bit `i`: lane `i`), each against `t_max`: the same hits, bit for bit.
                #[inline(always)]
                #[must_use]
                pub fn intersect(&self, ray: &WatertightRay, t_max: f32, lanes: u32) -> GroupHits {
                    let mut hits = GroupHits::NONE;
                    self.intersect_into::<wide::$lanes>(Baseline, ray, t_max, lanes, &mut hits);
                    hits
                }

                /// [`Self::intersect`] in the lanes `L` of the instruction set `isa`
                /// ([`crate::simd`]), written to `hits` (not returned: `watertight_lanes` says
                /// why): the same hits, bit for bit.
                #[inline(always)]
                pub fn intersect_into<L: Lanes<GROUP_WIDTH>>(
                    &self,
                    isa: L::Isa,
                    ray: &WatertightRay,
                    t_max: f32,
                    lanes: u32,
                    hits: &mut GroupHits,
                ) {
                    // (No `array::map`, which need not be inlined, and must be with AVX.)
                    let load = |k: usize| {
                        let v = &self.v[k];
                        [L::new(isa, v[0]), L::new(isa, v[1]), L::new(isa, v[2])]
                    };
                    let v = [load(0), load(1), load(2)];
                    let on_edge = watertight_lanes(isa, ray, t_max, lanes, v, hits);
                    self.intersect_on_edge(ray, t_max, on_edge, hits);
                }

                /// The lanes `on_edge` of `hits` (an edge function exactly zero in f32)
                /// decided by the scalar test, which recomputes their edge functions in f64.
                #[inline(always)]
                fn intersect_on_edge(
                    &self,
                    ray: &WatertightRay,
                    t_max: f32,
                    on_edge: u32,
                    hits: &mut GroupHits,
                ) {
                    let mut rest = on_edge;
                    while rest != 0 {
                        let lane = rest.trailing_zeros() as usize;
                        rest &= rest - 1;
                        let [p0, p1, p2] = self.triangle(lane);
                        if let Some(h) = ray.intersect(t_max, p0, p1, p2) {
                            hits.set(lane, h);
                        }
                    }
                }
            }
        }
    };
}

triangle_group!(
    four,
    f32x4,
    4,
    16,
    not(all(target_arch = "x86_64", target_feature = "sse2"))
);
triangle_group!(
    eight,
    f32x8,
    8,
    32,
    all(target_arch = "x86_64", target_feature = "sse2")
);

#[cfg(test)]
mod tests {
    /// The tests of one group width (module `$group`), run for both widths on every target,
    /// with each lane type `$lanes` made by the token `$isa` (an `Option`: `None` where this
    /// CPU lacks its instructions) that the target compiles.
    macro_rules! group_tests {
        ($module:ident, $group:ident, $lanes:ty, $isa:expr) => {
            mod $module {
                use super::super::$group::{GroupHits, TriangleGroup, GROUP_WIDTH};
                use crate::geometry::triangle::{TriangleHit, WatertightRay};
                use crate::sampler::{IndependentSampler, Sampler};
                use glam::Vec3;

                type Lanes = $lanes;
                const ALL: u32 = (1 << GROUP_WIDTH) - 1;

                fn isa() -> Option<<Lanes as crate::simd::Lanes<GROUP_WIDTH>>::Isa> {
                    let isa = $isa;
                    if isa.is_none() {
                        std::eprintln!("skipped: this CPU lacks the instructions");
                    }
                    isa
                }

                /// The lane test's answer for every lane equals the scalar test's, bit for
                /// bit; lane `i` holds `tris[i % tris.len()]`.
                fn assert_same(ray: &WatertightRay, t_max: f32, tris: &[[Vec3; 3]]) -> u32 {
                    let Some(isa) = isa() else { return 0 };
                    let tris: [[Vec3; 3]; GROUP_WIDTH] =
                        core::array::from_fn(|lane| tris[lane % tris.len()]);
                    let mut group = TriangleGroup::default();
                    for (lane, &t) in tris.iter().enumerate() {
                        group.set(lane, t);
                    }
                    let bits =
                        |h: Option<TriangleHit>| h.map(|h| [h.t, h.b1, h.b2].map(f32::to_bits));
                    let mut hit_lanes = 0;
                    let top = 1 << (GROUP_WIDTH - 1);
                    for lanes in [ALL, 0x5555 & ALL, 0xAAAA & ALL, 0x1, top, 0x0] {
                        // Storage holding another test's leftovers: every answer must be
                        // written.
                        let mut hits = GroupHits {
                            mask: u32::MAX,
                            t: [f32::NAN; GROUP_WIDTH],
                            b1: [-1.0; GROUP_WIDTH],
                            b2: [-1.0; GROUP_WIDTH],
                        };
                        group.intersect_into::<Lanes>(isa, ray, t_max, lanes, &mut hits);
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
                            if lanes == ALL && scalar.is_some() {
                                hit_lanes += 1;
                            }
                        }
                        assert_eq!(hits.mask & !lanes, 0, "a lane outside the mask");
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
                        let tris = [0; GROUP_WIDTH].map(|_| {
                            [rng.vec(scale), rng.vec(scale), rng.vec(scale)].map(|v| c + v)
                        });
                        let t_max = [f32::INFINITY, 0.5, 2.0][i % 3];
                        hits += assert_same(&ray, t_max, &tris);
                    }
                    assert!(
                        isa().is_none() || hits > 1_250 * GROUP_WIDTH as u32,
                        "only {hits} hits: the comparison says little"
                    );
                }

                #[test]
                fn lanes_match_the_scalar_test_on_edges_vertices_and_odd_numbers() {
                    // A square split in two along its diagonal, rays through the shared edge,
                    // through a vertex and along the plane; degenerate, NaN and infinite
                    // triangles beside them.
                    let (a, b, c, d) = (Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
                    let nan = Vec3::splat(f32::NAN);
                    let inf = Vec3::new(f32::INFINITY, 0.0, 0.0);
                    let tris: [&[[Vec3; 3]]; 3] = [
                        &[[a, b, c], [a, c, d], [a, a, b], [nan, b, c]],
                        &[[a, c, d], [a, b, c], [inf, b, c], [a, b, b]],
                        &[[a, b, c], [a, c, d], [nan, b, c], [a, b, b], [inf, b, c]],
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
                                for group in tris {
                                    hits += assert_same(&ray, t_max, group);
                                }
                            }
                        }
                    }
                    assert!(isa().is_none() || hits > 10, "only {hits} hits");
                    // NaN and infinite rays.
                    for (o, dir) in [
                        (Vec3::splat(f32::NAN), -Vec3::Z),
                        (Vec3::new(0.5, 0.5, 1.0), Vec3::splat(f32::NAN)),
                        (Vec3::new(0.5, 0.5, f32::INFINITY), -Vec3::Z),
                        (Vec3::new(0.5, 0.5, 1.0), Vec3::ZERO),
                    ] {
                        let ray = WatertightRay::new(o, dir);
                        for group in tris {
                            assert_same(&ray, f32::INFINITY, group);
                        }
                    }
                }

                #[test]
                fn groups_hold_their_triangles_and_pad_with_the_last() {
                    let t = |k: f32| [Vec3::splat(k), Vec3::splat(k + 1.0), Vec3::splat(k + 2.0)];
                    let g = TriangleGroup::from_triangles(&[t(0.0), t(10.0)]);
                    assert_eq!(g.triangle(0), t(0.0));
                    for lane in 1..GROUP_WIDTH {
                        assert_eq!(g.triangle(lane), t(10.0));
                    }
                    assert_eq!(TriangleGroup::from_triangles(&[]), TriangleGroup::default());
                }
            }
        };
    }

    group_tests!(four, four, wide::f32x4, Some(crate::simd::Baseline));
    group_tests!(eight, eight, wide::f32x8, Some(crate::simd::Baseline));
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    group_tests!(
        eight_avx,
        eight,
        crate::simd::Avx8,
        crate::simd::Avx::detect()
    );

    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    group_tests!(
        eight_avx512,
        eight,
        crate::simd::Avx8<crate::simd::Avx512>,
        crate::simd::Avx512::detect()
    );

    /// AVX-512's test of two groups at once ([`super::TriangleGroup::intersect_pair`]).
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    mod pair {
        use super::super::{PairHits, TriangleGroup, GROUP_WIDTH};
        use crate::geometry::triangle::{TriangleHit, WatertightRay};
        use crate::sampler::{IndependentSampler, Sampler};
        use crate::simd::Avx512;
        use glam::Vec3;

        const ALL: u32 = (1 << (2 * GROUP_WIDTH)) - 1;

        fn isa() -> Option<Avx512> {
            let isa = Avx512::detect();
            if isa.is_none() {
                std::eprintln!("skipped: this CPU lacks AVX-512");
            }
            isa
        }

        /// Every lane of the pair test equals the scalar test of its triangle, bit for bit,
        /// for lane masks within either group and across both; lane `i` holds
        /// `tris[i % tris.len()]`. Returns the lanes hit with all lanes tested.
        fn assert_same(isa: Avx512, ray: &WatertightRay, t_max: f32, tris: &[[Vec3; 3]]) -> u32 {
            let tris: [[Vec3; 3]; 2 * GROUP_WIDTH] =
                core::array::from_fn(|lane| tris[lane % tris.len()]);
            let mut groups = [TriangleGroup::default(); 2];
            for (lane, &t) in tris.iter().enumerate() {
                groups[lane / GROUP_WIDTH].set(lane % GROUP_WIDTH, t);
            }
            let bits = |h: Option<TriangleHit>| h.map(|h| [h.t, h.b1, h.b2].map(f32::to_bits));
            let mut hit_lanes = 0;
            for lanes in [ALL, 0x5555, 0xAAAA, 0x00FF, 0xFF00, 0x0180, 0x8001, 0x0] {
                // Storage holding another test's leftovers: every answer must be written.
                let mut hits = PairHits {
                    mask: u32::MAX,
                    t: [f32::NAN; 2 * GROUP_WIDTH],
                    b1: [-1.0; 2 * GROUP_WIDTH],
                    b2: [-1.0; 2 * GROUP_WIDTH],
                };
                let pair = [&groups[0], &groups[1]];
                TriangleGroup::intersect_pair(isa, pair, ray, t_max, lanes, &mut hits);
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
                    if lanes == ALL && scalar.is_some() {
                        hit_lanes += 1;
                    }
                }
                assert_eq!(hits.mask & !lanes, 0, "a lane outside the mask");
            }
            hit_lanes
        }

        #[test]
        fn pairs_match_the_scalar_test_on_random_triangles() {
            let Some(isa) = isa() else { return };
            let mut rng = IndependentSampler::new(11, 0, 0);
            let mut f = move || rng.next_1d();
            let mut hits = 0;
            for i in 0..10_000 {
                let scale = [1e-4, 1.0, 1e4][i % 3];
                let mut vec = |s: f32| Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * s;
                let (o, d) = (vec(2.0 * scale), vec(1.0));
                let ray = WatertightRay::new(o, d);
                // Triangles around a point on the ray, so that about half are hit.
                let c = o + d * (f() * 4.0 - 1.0);
                let mut vec = |s: f32| Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * s;
                let tris: [[Vec3; 3]; 2 * GROUP_WIDTH] =
                    core::array::from_fn(|_| [vec(scale), vec(scale), vec(scale)].map(|v| c + v));
                let t_max = [f32::INFINITY, 0.5, 2.0][i % 3];
                hits += assert_same(isa, &ray, t_max, &tris);
            }
            assert!(hits > 1_250 * GROUP_WIDTH as u32, "only {hits} hits");
        }

        #[test]
        fn pairs_match_the_scalar_test_on_edges_vertices_and_odd_numbers() {
            let Some(isa) = isa() else { return };
            // As the groups' test of the same name: a split square, rays through its shared
            // edge, a vertex and along its plane, beside degenerate, NaN and infinite
            // triangles; here spread over both groups of the pair.
            let (a, b, c, d) = (Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
            let nan = Vec3::splat(f32::NAN);
            let inf = Vec3::new(f32::INFINITY, 0.0, 0.0);
            let sets: [&[[Vec3; 3]]; 3] = [
                &[[a, b, c], [a, c, d], [a, a, b], [nan, b, c], [a, b, b]],
                &[[a, c, d], [a, b, c], [inf, b, c]],
                &[
                    [a, b, c],
                    [a, c, d],
                    [nan, b, c],
                    [a, b, b],
                    [inf, b, c],
                    [a, a, b],
                    [b, c, d],
                ],
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
                        for tris in sets {
                            hits += assert_same(isa, &ray, t_max, tris);
                        }
                    }
                }
            }
            assert!(hits > 20, "only {hits} hits");
            for (o, dir) in [
                (Vec3::splat(f32::NAN), -Vec3::Z),
                (Vec3::new(0.5, 0.5, 1.0), Vec3::splat(f32::NAN)),
                (Vec3::new(0.5, 0.5, f32::INFINITY), -Vec3::Z),
                (Vec3::new(0.5, 0.5, 1.0), Vec3::ZERO),
            ] {
                let ray = WatertightRay::new(o, dir);
                for tris in sets {
                    assert_same(isa, &ray, f32::INFINITY, tris);
                }
            }
        }
    }

    /// The group the scene uses is the one its width names: eight wide on x86-64 (SSE2 or
    /// AVX, chosen at run time), four elsewhere.
    #[test]
    fn the_scene_uses_the_width_of_its_build() {
        let x86 = cfg!(all(target_arch = "x86_64", target_feature = "sse2"));
        assert_eq!(super::GROUP_WIDTH, if x86 { 8 } else { 4 });
        assert_eq!(
            core::mem::size_of::<super::TriangleGroup>(),
            36 * super::GROUP_WIDTH
        );
        assert_eq!(crate::bvh::MAX_LEAF_PRIMS, super::GROUP_WIDTH);
    }
}
