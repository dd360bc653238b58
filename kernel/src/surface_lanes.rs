//! Surface interactions of eight hits at once ([`SceneView::interactions_in`]): the first stage
//! of issue 14's lever 3 that a batched path tracer runs in SIMD lanes instead of one lane after
//! another ([`crate::integrator::render_pixel_batched`]).
//!
//! Exactness: every lane performs [`SceneView::interaction`]'s operations in its order, each the
//! correctly rounded IEEE operation (`+ − × ÷ √`, sign flips, comparisons and selections that
//! move bits without rounding them), glam's `Vec3` methods spelt out as glam writes them (`dot`
//! as `(x·x′ + y·y′) + z·z′`, `normalize` as multiplication by `1 / length`). A point whose
//! spawn point must be moved in from an edge ([`crate::geometry::inset_barycentrics`]'s slow
//! path, a few in a thousand) is handed to the scalar code whole, so the lanes only ever
//! compute the common path. tests/tests/batched.rs compares whole renders bit for bit; the
//! tests below compare single interactions, edges and degenerate triangles included.

use crate::geometry::Ray;
use crate::math::{gamma, Frame};
use crate::scene::{Hit, SceneView, SurfaceInteraction};
use crate::simd::{Isa, Lanes};
use crate::vec_lanes::{triangle_point, Soa3, N, V3};
use glam::Vec3;

/// [`Frame::from_normal`] lane by lane: the tangents `s` and `t`.
#[inline(always)]
fn frame_from_normal<L: Lanes<N>>(isa: L::Isa, n: V3<L>) -> (V3<L>, V3<L>) {
    let one = L::splat(isa, 1.0);
    let sign = L::select(n.z.simd_ge(L::splat(isa, 0.0)), one, one.neg());
    let a = one.neg() / (sign + n.z);
    let b = n.x * n.y * a;
    let s = V3 {
        x: one + sign * n.x * n.x * a,
        y: sign * b,
        z: sign.neg() * n.x,
    };
    let t = V3 {
        x: b,
        y: sign + n.y * n.y * a,
        z: n.y.neg(),
    };
    (s, t)
}

/// Eight surface interactions stored field by field, a lane each: where the batched path
/// tracer keeps the vertices its paths scatter from.
#[derive(Clone, Copy, Debug, Default)]
pub struct SurfaceLanes {
    pub p: Soa3,
    pub p_spawn: Soa3,
    pub p_err: Soa3,
    pub ng: Soa3,
    /// The shading frame's axes.
    pub s: Soa3,
    pub t: Soa3,
    pub n: Soa3,
    pub wo: Soa3,
    pub material: [u32; N],
    pub triangle: [u32; N],
    pub b1: [f32; N],
    pub b2: [f32; N],
}

impl SurfaceLanes {
    /// The interaction of lane `l`.
    #[inline(always)]
    #[must_use]
    pub fn get(&self, l: usize) -> SurfaceInteraction {
        SurfaceInteraction {
            p: self.p.get(l),
            p_spawn: self.p_spawn.get(l),
            p_err: self.p_err.get(l),
            ng: self.ng.get(l),
            frame: Frame {
                s: self.s.get(l),
                t: self.t.get(l),
                n: self.n.get(l),
            },
            wo: self.wo.get(l),
            material: self.material[l],
            triangle: self.triangle[l],
            b1: self.b1[l],
            b2: self.b2[l],
        }
    }

    /// Sets lane `l` to `si`.
    #[inline(always)]
    pub fn set(&mut self, l: usize, si: &SurfaceInteraction) {
        self.p.set(l, si.p);
        self.p_spawn.set(l, si.p_spawn);
        self.p_err.set(l, si.p_err);
        self.ng.set(l, si.ng);
        self.s.set(l, si.frame.s);
        self.t.set(l, si.frame.t);
        self.n.set(l, si.frame.n);
        self.wo.set(l, si.wo);
        self.material[l] = si.material;
        self.triangle[l] = si.triangle;
        self.b1[l] = si.b1;
        self.b2[l] = si.b2;
    }
}

impl SceneView<'_> {
    /// [`Self::interaction`] of `hits[l]` for `rays[l]` in each lane `l` whose bit is set in
    /// `lanes` and whose hit is `Some` (`None` in the others), computed eight at a time in SIMD
    /// lanes, with AVX-512 or AVX2 where the CPU has it: the same interactions, bit for bit.
    #[inline]
    #[must_use]
    pub fn interactions(
        &self,
        rays: &[Ray; N],
        hits: &[Option<Hit>; N],
        lanes: u32,
    ) -> [Option<SurfaceInteraction>; N] {
        let mut out = SurfaceLanes::default();
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        let found = match (crate::simd::Avx512::detect(), crate::simd::Avx::detect()) {
            (Some(avx512), _) => avx512.run(
                #[inline(always)]
                |avx512| self.interactions_in(avx512, rays, hits, lanes, &mut out),
            ),
            (None, Some(avx)) => avx.run(
                #[inline(always)]
                |avx| self.interactions_in(avx, rays, hits, lanes, &mut out),
            ),
            (None, None) => {
                self.interactions_in(crate::simd::Baseline, rays, hits, lanes, &mut out)
            }
        };
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        let found = self.interactions_in(crate::simd::Baseline, rays, hits, lanes, &mut out);
        core::array::from_fn(|l| (found >> l & 1 != 0).then(|| out.get(l)))
    }

    /// [`Self::interaction`] of `hits[l]` for `rays[l]`, for each lane `l` whose bit is set in
    /// `lanes` and whose hit is `Some`, written to lane `l` of `out` (the other lanes of `out`
    /// are overwritten too, with no meaning): the same interactions, bit for bit, computed in
    /// the lanes of `isa`. Returns the lanes written (bits).
    #[inline(always)]
    pub fn interactions_in<I: Isa>(
        &self,
        isa: I,
        rays: &[Ray; N],
        hits: &[Option<Hit>; N],
        lanes: u32,
        out: &mut SurfaceLanes,
    ) -> u32 {
        let mut live = 0u32;
        let mut fill = None;
        for (l, hit) in hits.iter().enumerate() {
            if lanes >> l & 1 != 0 && hit.is_some() {
                live |= 1 << l;
                fill = fill.or(*hit);
            }
        }
        let Some(fill) = fill else {
            return 0;
        };
        // Lanes without a hit compute the first live lane's, and are not given out.
        let hit = |l: usize| hits[l].filter(|_| live >> l & 1 != 0).unwrap_or(fill);
        let hit: [Hit; N] = core::array::from_fn(hit);
        let corners: [[u32; 3]; N] =
            core::array::from_fn(|l| self.triangles[hit[l].triangle as usize]);
        let lane = |x: f32| I::Eight::splat(isa, x);
        let (zero, one) = (lane(0.0), lane(1.0));
        let vertex = |k: usize| V3::<I::Eight>::new(isa, |l| hit[l].vertices[k]);
        let normal = |k: usize| V3::<I::Eight>::new(isa, |l| self.normals[corners[l][k] as usize]);
        let (p0, p1, p2) = (vertex(0), vertex(1), vertex(2));
        let b1 = I::Eight::new(isa, core::array::from_fn(|l| hit[l].b1));
        let b2 = I::Eight::new(isa, core::array::from_fn(|l| hit[l].b2));
        let d = V3::<I::Eight>::new(isa, |l| rays[l].d);

        // `-ray.d.normalize()`.
        let wo = d.scale(one / d.dot(d).sqrt()).neg();
        // `surface_at_vertices`: the point and its error (`triangle_point`).
        let b0 = one - b1 - b2;
        let (e1, e2) = (p1.sub(p0), p2.sub(p0));
        let (p, p_err) = triangle_point(isa, b1, b2, p0, e1, e2);
        let cross = e1.cross(e2);
        let (ng, area2) = cross.normalize_or_zero(one, zero);
        // `inset_barycentrics`: the point stays where it is if the triangle is degenerate or
        // the point lies inside the bound of its fast acceptance; every other lane goes to the
        // scalar code.
        let degenerate = !(area2.simd_gt(zero) & area2.is_finite()) | ng.is_zero(zero);
        let edge2 = |e: V3<I::Eight>| e.dot(e);
        let longest = edge2(p2.sub(p1))
            .fast_max(edge2(p0.sub(p2)))
            .fast_max(edge2(p1.sub(p0)))
            .sqrt();
        let bound = longest
            * (lane(2.0) * (p_err.x + p_err.y + p_err.z) + lane(gamma(256)) * longest)
            / area2;
        let inside = b0.fast_min(b1).fast_min(b2).simd_ge(lane(1.01) * bound);
        let lanes_done = (degenerate | inside).to_bitmask() & live;
        // The shading normal, the geometric one where the vertex normals cancel.
        let normals = [normal(0), normal(1), normal(2)];
        let ns = V3::interpolated_normal(normals, [b0, b1, b2], ng, one, zero);
        let up = V3::splat(isa, Vec3::Z);
        let n = V3::select(ns.is_zero(zero), up, ns);
        let (s, t) = frame_from_normal(isa, n);

        out.p.store(p);
        out.p_spawn.store(p);
        out.p_err.store(p_err);
        out.ng.store(ng);
        out.s.store(s);
        out.t.store(t);
        out.n.store(n);
        out.wo.store(wo);
        out.b1 = b1.to_array();
        out.b2 = b2.to_array();
        out.triangle = hit.map(|h| h.triangle);
        out.material = out.triangle.map(|t| self.triangle_materials[t as usize]);
        let mut slow = live & !lanes_done;
        while slow != 0 {
            let l = slow.trailing_zeros() as usize;
            slow &= slow - 1;
            out.set(l, &self.interaction(&rays[l], &hit[l]));
        }
        live
    }
}

#[cfg(test)]
mod tests {
    use crate::bvh::Bvh;
    use crate::geometry::Ray;
    use crate::math::Frame;
    use crate::sampler::mix64;
    use crate::scene::{Hit, Material, SceneView, SurfaceInteraction};
    use crate::texture::Textures;
    use crate::vec_lanes::N;
    use glam::Vec3;
    use std::format;
    use std::vec::Vec;

    fn bits3(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    fn frame_bits(f: &Frame) -> [[u32; 3]; 3] {
        [bits3(f.s), bits3(f.t), bits3(f.n)]
    }

    /// Every field, as bits (a float comparison would take −0 for 0 and miss NaNs).
    fn bits(si: &SurfaceInteraction) -> ([[u32; 3]; 5], [[u32; 3]; 3], [u32; 4]) {
        (
            [si.p, si.p_spawn, si.p_err, si.ng, si.wo].map(bits3),
            frame_bits(&si.frame),
            [si.material, si.triangle, si.b1.to_bits(), si.b2.to_bits()],
        )
    }

    /// Uniform in [0, 1) from a counter.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 += 1;
            (mix64(self.0) >> 40) as f32 / (1u64 << 24) as f32
        }
        fn vec(&mut self, scale: f32) -> Vec3 {
            Vec3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5) * scale
        }
    }

    /// Triangles of many kinds: ordinary, far from the origin, tiny, slivers, degenerate
    /// (repeated and collinear vertices), with vertex normals that agree, disagree, cancel
    /// or are zero.
    struct Soup {
        positions: Vec<Vec3>,
        normals: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        materials_of: Vec<u32>,
        materials: Vec<Material>,
    }

    impl Soup {
        fn new(rng: &mut Rng) -> Self {
            let mut s = Self {
                positions: Vec::new(),
                normals: Vec::new(),
                triangles: Vec::new(),
                materials_of: Vec::new(),
                materials: [0.2, 0.5, 0.8]
                    .map(|a| Material::diffuse(Vec3::splat(a)))
                    .to_vec(),
            };
            for t in 0..96u32 {
                let offset = match t % 4 {
                    0 => Vec3::ZERO,
                    1 => rng.vec(2.0e5),
                    2 => rng.vec(10.0),
                    _ => Vec3::splat(-3.0e3),
                };
                let scale = [1.0, 1.0e-4, 3.0, 0.02][(t / 4 % 4) as usize];
                let mut p = [rng.vec(scale), rng.vec(scale), rng.vec(scale)].map(|v| v + offset);
                match t / 16 % 6 {
                    // A repeated vertex, collinear vertices, a sliver.
                    1 => p[2] = p[0],
                    2 => p[2] = p[0] + (p[1] - p[0]) * 0.5,
                    3 => p[2] = p[0] + (p[1] - p[0]) * 0.5 + rng.vec(scale * 1.0e-6),
                    _ => {}
                }
                let geometric = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
                let n: [Vec3; 3] = match t % 5 {
                    0 => [geometric; 3],
                    1 => [rng.vec(1.0), rng.vec(1.0), rng.vec(1.0)].map(Vec3::normalize_or_zero),
                    2 => [Vec3::Z, -Vec3::Z, Vec3::Z],
                    3 => [Vec3::ZERO; 3],
                    _ => [-geometric, geometric, rng.vec(1.0e-3)],
                };
                let base = s.positions.len() as u32;
                s.positions.extend(p);
                s.normals.extend(n);
                s.triangles.push([base, base + 1, base + 2]);
                s.materials_of.push(t % 3);
            }
            s
        }

        fn view(&self) -> SceneView<'_> {
            SceneView {
                positions: &self.positions,
                normals: &self.normals,
                triangles: &self.triangles,
                triangle_materials: &self.materials_of,
                materials: &self.materials,
                emitter_triangles: &[],
                emitter_cdf: &[],
                bvh: Bvh {
                    nodes: &[],
                    prim_order: &[],
                }
                .into(),
                textures: Textures::NONE,
            }
        }
    }

    /// Barycentrics inside, on and next to the edges and corners (where the spawn point is
    /// moved in by the scalar code), and outside (as rounding can give).
    fn barycentrics(rng: &mut Rng, k: usize) -> (f32, f32) {
        let (u, v) = (rng.next(), rng.next());
        match k % 6 {
            0 | 1 => {
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                (u, v)
            }
            2 => (0.0, v),
            3 => (u * 1.0e-6, 1.0 - u * 1.0e-6 - 1.0e-7),
            4 => (1.0, 0.0),
            _ => (-1.0e-7 * u, 0.5 + v * 1.0e-3),
        }
    }

    /// [`SceneView::interactions_in`], with the baseline lanes and with AVX where the CPU has
    /// it, against [`SceneView::interaction`] lane by lane: the same bits, for every kind of
    /// triangle and point, for every mask of live lanes and missing hits.
    #[test]
    fn lanes_give_the_scalar_interactions_bit_for_bit() {
        let mut rng = Rng(0x5eed);
        let soup = Soup::new(&mut rng);
        let scene = soup.view();
        scene.validate().unwrap();
        let mut compared = 0usize;
        let mut moved = 0usize;
        for round in 0..2000usize {
            let hits: [Option<Hit>; N] = core::array::from_fn(|l| {
                if (round + l) % 11 == 0 {
                    return None;
                }
                let triangle = (mix64((round * N + l) as u64) % soup.triangles.len() as u64) as u32;
                let (b1, b2) = barycentrics(&mut rng, round + l);
                let vertices =
                    soup.triangles[triangle as usize].map(|i| soup.positions[i as usize]);
                Some(Hit {
                    t: 1.0,
                    triangle,
                    b1,
                    b2,
                    vertices,
                })
            });
            let rays: [Ray; N] = core::array::from_fn(|l| {
                // Unit, unnormalised and tiny directions.
                let d = rng.vec(1.0) * [1.0, 7.0, 1.0e-3][l % 3] + Vec3::new(0.0, 0.0, 1.0e-4);
                Ray::new(rng.vec(4.0), d)
            });
            let lanes = if round % 7 == 0 {
                mix64(round as u64) as u32 & 0xFF
            } else {
                0xFF
            };
            let expect: [Option<SurfaceInteraction>; N] = core::array::from_fn(|l| {
                let hit = hits[l].filter(|_| lanes >> l & 1 != 0)?;
                Some(scene.interaction(&rays[l], &hit))
            });
            let mut stored = super::SurfaceLanes::default();
            let found =
                scene.interactions_in(crate::simd::Baseline, &rays, &hits, lanes, &mut stored);
            let baseline: [Option<SurfaceInteraction>; N] =
                core::array::from_fn(|l| (found >> l & 1 != 0).then(|| stored.get(l)));
            let dispatched = scene.interactions(&rays, &hits, lanes);
            for l in 0..N {
                let what = |which: &str| format!("{which}: round {round} lane {l} {:?}", hits[l]);
                assert_eq!(
                    expect[l].as_ref().map(bits),
                    baseline[l].as_ref().map(bits),
                    "{}",
                    what("baseline lanes")
                );
                assert_eq!(
                    expect[l].as_ref().map(bits),
                    dispatched[l].as_ref().map(bits),
                    "{}",
                    what("dispatched lanes")
                );
                if let Some(si) = &expect[l] {
                    compared += 1;
                    moved += usize::from(si.p_spawn != si.p);
                }
            }
        }
        // The comparison saw both the lanes' own path and the moved spawn points.
        assert!(compared > 10_000, "{compared} interactions compared");
        assert!(
            moved > 500,
            "only {moved} spawn points moved in from an edge"
        );
    }
}
