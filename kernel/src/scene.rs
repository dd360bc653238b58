//! The scene as borrowed slices: what every integrator reads.

use crate::bsdf::SurfaceBsdf;
use crate::bvh::{closest, lower_bound, SceneBvh};
use crate::geometry::{
    inset_barycentrics, triangle_point, GroupHits, PairHits, Ray, RayLanes, TriangleHit,
    WatertightRay, F8, GROUP_WIDTH, PACKET,
};
use crate::math::Frame;
use crate::sampler::lanes_of;
use crate::simd::Isa;
use crate::texture::{Textures, NO_TEXTURE};
use crate::Rgb;
use glam::{Vec2, Vec3};

pub use crate::material::Material;

/// All scene data, borrowed from the host. Vertex attributes share one index per corner.
///
/// Emitter sampling reads `emitter_triangles` (indices of emissive triangles, sorted ascending
/// so that the pdf of a hit emitter is found by binary search) and
/// `emitter_cdf` (non-decreasing cumulative selection probabilities, one per entry, the last
/// one the total), filled by [`crate::emitter::build_emitter_table`] with the host's choice of
/// policy (TinyRender's rule is "an emitter uniformly, then a triangle of it in proportion to
/// area"). Textured materials read `textures`.
#[derive(Clone, Copy, Debug)]
pub struct SceneView<'a> {
    pub positions: &'a [Vec3],
    pub normals: &'a [Vec3],
    pub triangles: &'a [[u32; 3]],
    pub triangle_materials: &'a [u32],
    pub materials: &'a [Material],
    pub emitter_triangles: &'a [u32],
    pub emitter_cdf: &'a [f32],
    pub bvh: SceneBvh<'a>,
    pub textures: Textures<'a>,
}

/// Why a [`SceneView`] is not consistent; checked once by [`SceneView::validate`] so the hot
/// path can index without checks failing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneError {
    NormalCount { positions: usize, normals: usize },
    VertexIndex { triangle: usize, index: u32 },
    MaterialCount { triangles: usize, materials: usize },
    MaterialIndex { triangle: usize, index: u32 },
    EmitterCount { triangles: usize, cdf: usize },
    EmitterIndex { entry: usize, index: u32 },
    EmitterOrder { entry: usize },
    EmitterCdf { entry: usize },
    BvhPrimitive { entry: usize, index: u32 },
    BvhLeafTriangle { entry: usize },
    TextureIndex { material: usize, index: u32 },
    TextureTexels { texture: usize },
    UvCount { positions: usize, uvs: usize },
}

impl core::fmt::Display for SceneError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::NormalCount { positions, normals } => {
                write!(f, "{positions} positions but {normals} normals")
            }
            Self::VertexIndex { triangle, index } => {
                write!(f, "triangle {triangle} refers to missing vertex {index}")
            }
            Self::MaterialCount {
                triangles,
                materials,
            } => write!(f, "{triangles} triangles but {materials} material ids"),
            Self::MaterialIndex { triangle, index } => {
                write!(f, "triangle {triangle} refers to missing material {index}")
            }
            Self::EmitterCount { triangles, cdf } => {
                write!(f, "{triangles} emitter triangles but {cdf} cdf entries")
            }
            Self::EmitterIndex { entry, index } => {
                write!(
                    f,
                    "emitter entry {entry} refers to missing triangle {index}"
                )
            }
            Self::EmitterOrder { entry } => {
                write!(
                    f,
                    "emitter triangles are not sorted ascending at entry {entry}"
                )
            }
            Self::EmitterCdf { entry } => {
                write!(
                    f,
                    "emitter cdf is not finite and non-decreasing at entry {entry}"
                )
            }
            Self::BvhPrimitive { entry, index } => {
                write!(f, "BVH entry {entry} refers to missing triangle {index}")
            }
            Self::BvhLeafTriangle { entry } => write!(
                f,
                "the BVH's triangle group lane {entry} is missing or not the vertices of its entry's triangle"
            ),
            Self::TextureIndex { material, index } => {
                write!(f, "material {material} refers to missing texture {index}")
            }
            Self::TextureTexels { texture } => write!(
                f,
                "texture {texture} is empty or its texels lie outside the texel array"
            ),
            Self::UvCount { positions, uvs } => write!(
                f,
                "{positions} positions but {uvs} texture coordinates (a material is textured)"
            ),
        }
    }
}

/// A closest hit: triangle index, distance and barycentrics of vertices 1 and 2, and the
/// triangle's vertices ([`SceneView::triangle_vertices`]), which the leaf test had at hand, so
/// that [`SceneView::interaction`] need not fetch them through the index buffer again.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    pub b1: f32,
    pub b2: f32,
    pub vertices: [Vec3; 3],
}

/// A point on a surface with what shading and ray spawning need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceInteraction {
    /// The shading point.
    pub p: Vec3,
    /// Where rays leave from: `p`, or for a point within its error bound of an edge of its
    /// triangle, a point moved inside by that bound ([`inset_barycentrics`]), so that the
    /// rounding of `p` cannot put a ray origin behind a surface meeting the triangle there.
    pub p_spawn: Vec3,
    /// Absolute error bound per axis of both `p` and `p_spawn` (for robust ray origins).
    pub p_err: Vec3,
    /// Geometric normal, `normalize(cross(p1 − p0, p2 − p0))` (counter-clockwise is the front).
    pub ng: Vec3,
    /// Shading frame around the interpolated vertex normal.
    pub frame: Frame,
    /// Unit world-space direction toward the viewer (the previous path vertex).
    pub wo: Vec3,
    pub material: u32,
    /// The triangle and the barycentrics of vertices 1 and 2 of the point (for texture
    /// coordinates; `u32::MAX` for points that are not on a scene triangle).
    pub triangle: u32,
    pub b1: f32,
    pub b2: f32,
}

impl SurfaceInteraction {
    /// A ray leaving the surface toward world direction `d`.
    #[inline]
    #[must_use]
    pub fn spawn_ray(&self, d: Vec3) -> Ray {
        crate::geometry::spawn_ray(self.p_spawn, self.p_err, self.ng, d)
    }
}

impl<'a> SceneView<'a> {
    /// Checks every index once.
    ///
    /// # Errors
    /// The first inconsistency found.
    pub fn validate(&self) -> Result<(), SceneError> {
        let nv = self.positions.len();
        if self.normals.len() != nv {
            return Err(SceneError::NormalCount {
                positions: nv,
                normals: self.normals.len(),
            });
        }
        for (i, t) in self.triangles.iter().enumerate() {
            if let Some(&bad) = t.iter().find(|&&v| v as usize >= nv) {
                return Err(SceneError::VertexIndex {
                    triangle: i,
                    index: bad,
                });
            }
        }
        if self.triangle_materials.len() != self.triangles.len() {
            return Err(SceneError::MaterialCount {
                triangles: self.triangles.len(),
                materials: self.triangle_materials.len(),
            });
        }
        for (i, &m) in self.triangle_materials.iter().enumerate() {
            if m as usize >= self.materials.len() {
                return Err(SceneError::MaterialIndex {
                    triangle: i,
                    index: m,
                });
            }
        }
        if self.emitter_cdf.len() != self.emitter_triangles.len() {
            return Err(SceneError::EmitterCount {
                triangles: self.emitter_triangles.len(),
                cdf: self.emitter_cdf.len(),
            });
        }
        for (i, &t) in self.emitter_triangles.iter().enumerate() {
            if t as usize >= self.triangles.len() {
                return Err(SceneError::EmitterIndex { entry: i, index: t });
            }
            if i > 0 && self.emitter_triangles[i - 1] >= t {
                return Err(SceneError::EmitterOrder { entry: i });
            }
            let c = self.emitter_cdf[i];
            if !c.is_finite() || c < 0.0 || (i > 0 && self.emitter_cdf[i - 1] > c) {
                return Err(SceneError::EmitterCdf { entry: i });
            }
        }
        for (i, &t) in self.bvh.prim_order().iter().enumerate() {
            if t as usize >= self.triangles.len() {
                return Err(SceneError::BvhPrimitive { entry: i, index: t });
            }
        }
        let (order, groups) = (self.bvh.prim_order(), self.bvh.leaf_groups());
        if !groups.is_empty() {
            if groups.len() != order.len().div_ceil(GROUP_WIDTH) {
                return Err(SceneError::BvhLeafTriangle { entry: order.len() });
            }
            let bits = |v: [Vec3; 3]| v.map(|p| p.to_array().map(f32::to_bits));
            for (i, &t) in order.iter().enumerate() {
                let lane = groups[i / GROUP_WIDTH].triangle(i % GROUP_WIDTH);
                if bits(lane) != bits(self.triangle_vertices(t)) {
                    return Err(SceneError::BvhLeafTriangle { entry: i });
                }
            }
        }
        self.validate_textures()
    }

    /// Texture ids of materials, texel ranges of textures, and texture coordinates for every
    /// vertex when a material is textured.
    fn validate_textures(&self) -> Result<(), SceneError> {
        let t = &self.textures;
        for (i, tex) in t.textures.iter().enumerate() {
            let end = (tex.first_texel as usize).checked_add(tex.len());
            if tex.is_empty() || end.is_none_or(|e| e > t.texels.len()) {
                return Err(SceneError::TextureTexels { texture: i });
            }
        }
        let mut textured = false;
        for (i, m) in self.materials.iter().enumerate() {
            for id in m.texture_ids() {
                if id == NO_TEXTURE {
                    continue;
                }
                if id as usize >= t.textures.len() {
                    return Err(SceneError::TextureIndex {
                        material: i,
                        index: id,
                    });
                }
                textured = true;
            }
        }
        if textured && t.uvs.len() != self.positions.len() {
            return Err(SceneError::UvCount {
                positions: self.positions.len(),
                uvs: t.uvs.len(),
            });
        }
        Ok(())
    }

    #[inline]
    #[must_use]
    pub fn triangle_vertices(&self, tri: u32) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[tri as usize];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    #[inline]
    #[must_use]
    pub fn material(&self, id: u32) -> &'a Material {
        &self.materials[id as usize]
    }

    /// Closest hit along the ray.
    ///
    /// Runs in AVX-512 or AVX2 lanes where the CPU has them, in the build's baseline lanes
    /// otherwise ([`crate::simd`]); the hit is the same either way ([`Self::intersect_in`]).
    #[inline]
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        if let Some(avx512) = crate::simd::Avx512::detect() {
            return avx512.run(
                #[inline(always)]
                |avx512| self.intersect_in(avx512, ray),
            );
        }
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        if let Some(avx) = crate::simd::Avx::detect() {
            return avx.run(
                #[inline(always)]
                |avx| self.intersect_in(avx, ray),
            );
        }
        self.intersect_in(crate::simd::Baseline, ray)
    }

    /// [`Self::intersect`] with the lanes of the instruction set `isa`: the same hit whichever
    /// it is.
    #[inline(always)]
    #[must_use]
    pub fn intersect_in<I: Isa>(&self, isa: I, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let wray = WatertightRay::new(ray.o, ray.d);
        self.bvh.traverse_leaves_in::<false, I, _>(
            isa,
            ray.o,
            ray.d,
            ray.t_max,
            // Inlined, so that with AVX the lane code is compiled for AVX (`simd::Avx::run`).
            #[inline(always)]
            |first, count, t_max| {
                self.leaf_hits::<false, I>(isa, &wray, first, count, t_max, |prim, h, vertices| {
                    // The closest-hit order (`bvh::closest`): independent of the visit order.
                    if !closest::precedes(h.t, prim, best.map(|b| (b.t, b.triangle))) {
                        return None;
                    }
                    best = Some(Hit {
                        t: h.t,
                        triangle: prim,
                        b1: h.b1,
                        b2: h.b2,
                        vertices,
                    });
                    Some(closest::bound_after(h.t))
                })
            },
        );
        best
    }

    /// [`Self::intersect`] from code already running with the instructions `isa`: a direct call
    /// of the query compiled for them ([`Isa::call`]), without finding the CPU's level again.
    /// The hit is written to `hit`, not returned: returned, it was stored field by field and at
    /// once copied on by the caller in 32-byte loads, which cannot be forwarded from those
    /// stores and waited for them to reach the cache (0.8% of a batched render, AMD Zen 5).
    #[inline(always)]
    pub fn intersect_with<I: Isa>(&self, isa: I, ray: &Ray, hit: &mut Option<Hit>) {
        isa.call(
            #[inline(always)]
            |isa| *hit = self.intersect_in(isa, ray),
        );
    }

    /// [`Self::occluded`] from code already running with `isa`, as [`Self::intersect_with`].
    #[inline(always)]
    #[must_use]
    pub fn occluded_with<I: Isa>(&self, isa: I, ray: &Ray) -> bool {
        isa.call(
            #[inline(always)]
            |isa| self.occluded_in(isa, ray),
        )
    }

    /// Whether anything blocks the ray before `ray.t_max` (in AVX-512 or AVX2 lanes where the
    /// CPU has them, as [`Self::intersect`]).
    #[inline]
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        if let Some(avx512) = crate::simd::Avx512::detect() {
            return avx512.run(
                #[inline(always)]
                |avx512| self.occluded_in(avx512, ray),
            );
        }
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        if let Some(avx) = crate::simd::Avx::detect() {
            return avx.run(
                #[inline(always)]
                |avx| self.occluded_in(avx, ray),
            );
        }
        self.occluded_in(crate::simd::Baseline, ray)
    }

    /// [`Self::occluded`] with the lanes of the instruction set `isa`: the same answer
    /// whichever it is.
    #[inline(always)]
    #[must_use]
    pub fn occluded_in<I: Isa>(&self, isa: I, ray: &Ray) -> bool {
        let wray = WatertightRay::new(ray.o, ray.d);
        self.bvh.traverse_leaves_in::<true, I, _>(
            isa,
            ray.o,
            ray.d,
            ray.t_max,
            #[inline(always)]
            |first, count, t_max| {
                self.leaf_hits::<true, I>(isa, &wray, first, count, t_max, |_, h, _| Some(h.t))
            },
        )
    }

    /// [`Self::intersect`] of each ray `rays[i]` whose bit is set in `live`, walking the tree
    /// once for all of them ([`crate::bvh::WideBvh::traverse_packet`]): the same hits, bit for
    /// bit (tests/tests/packets.rs). Lanes outside `live` are `None`.
    #[must_use]
    pub fn intersect_packet(&self, rays: &[Ray; PACKET], live: u32) -> [Option<Hit>; PACKET] {
        let mut best: [Option<Hit>; PACKET] = [None; PACKET];
        let live = live & ((1 << PACKET) - 1);
        let SceneBvh::Wide(wide) = self.bvh else {
            for lane in lanes_of(live) {
                best[lane] = self.intersect(&rays[lane]);
            }
            return best;
        };
        let lanes = RayLanes::new(&rays.map(|r| r.o), &rays.map(|r| r.d));
        let mut t_max = F8(rays.map(|r| r.t_max));
        let walk = wide.traverse_packet::<false, _>(
            &lanes,
            &mut t_max,
            live,
            |first, count, mask, t_max| {
                for slot in first..first + count {
                    let (prim, vertices) = self.slot_triangle(slot);
                    let [p0, p1, p2] = vertices;
                    let hits = lanes.intersect(t_max, p0, p1, p2, mask);
                    for lane in lanes_of(hits.mask) {
                        let t = hits.t.0[lane];
                        if closest::precedes(t, prim, best[lane].map(|b| (b.t, b.triangle))) {
                            best[lane] = Some(Hit {
                                t,
                                triangle: prim,
                                b1: hits.b1.0[lane],
                                b2: hits.b2.0[lane],
                                vertices,
                            });
                            lower_bound(t_max, lane, t);
                        }
                    }
                }
                0
            },
        );
        if walk.is_err() {
            for lane in lanes_of(live) {
                best[lane] = self.intersect(&rays[lane]);
            }
        }
        best
    }

    /// [`Self::occluded`] of each ray `rays[i]` whose bit is set in `live`, as a bit mask,
    /// walking the tree once for all of them: the same answers (tests/tests/packets.rs).
    #[must_use]
    pub fn occluded_packet(&self, rays: &[Ray; PACKET], live: u32) -> u32 {
        let live = live & ((1 << PACKET) - 1);
        let one_by_one = || {
            lanes_of(live).fold(0u32, |m, lane| {
                m | u32::from(self.occluded(&rays[lane])) << lane
            })
        };
        let SceneBvh::Wide(wide) = self.bvh else {
            return one_by_one();
        };
        let lanes = RayLanes::new(&rays.map(|r| r.o), &rays.map(|r| r.d));
        let mut t_max = F8(rays.map(|r| r.t_max));
        let walk = wide.traverse_packet::<true, _>(
            &lanes,
            &mut t_max,
            live,
            |first, count, mask, t_max| {
                let mut hit = 0u32;
                for slot in first..first + count {
                    let (_, [p0, p1, p2]) = self.slot_triangle(slot);
                    hit |= lanes.intersect(t_max, p0, p1, p2, mask & !hit).mask;
                    if hit == mask {
                        break;
                    }
                }
                hit
            },
        );
        walk.unwrap_or_else(|_| one_by_one())
    }

    /// The primitive at `slot` of the tree's primitive order and its vertices (from the leaf
    /// groups where the tree has them).
    #[inline(always)]
    fn slot_triangle(&self, slot: u32) -> (u32, [Vec3; 3]) {
        let prim = self.bvh.prim_order()[slot as usize];
        let groups = self.bvh.leaf_groups();
        if groups.is_empty() {
            (prim, self.triangle_vertices(prim))
        } else {
            let s = slot as usize;
            (prim, groups[s / GROUP_WIDTH].triangle(s % GROUP_WIDTH))
        }
    }

    /// Tests the triangles of the leaf `prim_order[first .. first + count]` in slot order and
    /// offers each hit closer than the current bound to `accept(prim, hit, vertices)` (the
    /// triangle's vertices, from the leaf group where there is one), which returns
    /// the bound after it if it takes it; returns the last bound taken (with `ANY_HIT`, the
    /// first). With leaf groups, a group of triangles is tested at once against the bound at
    /// the start of their group (or of their pair of groups, [`Isa::intersect_pair`]): a hit is
    /// offered only if it precedes every hit taken, so the hits taken are those of the
    /// one-by-one test (`bvh::closest`), and the lane test computes each hit bit for bit as the
    /// scalar test does.
    #[inline(always)]
    fn leaf_hits<const ANY_HIT: bool, I: Isa>(
        &self,
        isa: I,
        wray: &WatertightRay,
        first: u32,
        count: u32,
        mut t_max: f32,
        mut accept: impl FnMut(u32, TriangleHit, [Vec3; 3]) -> Option<f32>,
    ) -> Option<f32> {
        let (order, groups) = (self.bvh.prim_order(), self.bvh.leaf_groups());
        let mut bound = None;
        let mut offer = |prim: u32, h: TriangleHit, vertices: [Vec3; 3], t_max: &mut f32| -> bool {
            if let Some(t) = accept(prim, h, vertices) {
                *t_max = t_max.min(t);
                bound = Some(*t_max);
                return ANY_HIT;
            }
            false
        };
        let (first, end) = (first as usize, (first + count) as usize);
        if groups.is_empty() {
            for &prim in &order[first..end] {
                let [p0, p1, p2] = self.triangle_vertices(prim);
                if let Some(h) = wray.intersect(t_max, p0, p1, p2) {
                    if offer(prim, h, [p0, p1, p2], &mut t_max) {
                        break;
                    }
                }
            }
            return bound;
        }
        // Where the lane tests write their hits (`watertight_lanes` says why not by value).
        let (mut pair_hits, mut group_hits) = (PairHits::NONE, GroupHits::NONE);
        let mut slot = first;
        while slot < end {
            let g = slot / GROUP_WIDTH;
            let base = g * GROUP_WIDTH;
            let lanes_end = end.min(base + GROUP_WIDTH);
            let lanes = ((1u32 << (lanes_end - base)) - 1) & !((1u32 << (slot - base)) - 1);
            // A leaf that goes on into the next group: both at once where the instruction set
            // has lanes for two (AVX-512), the second group's lanes above the first's, so that
            // the hits are offered in slot order all the same.
            if I::PAIRS && lanes_end < end {
                let pair_end = end.min(base + 2 * GROUP_WIDTH);
                let second = (1u32 << (pair_end - lanes_end)) - 1;
                let pair = [&groups[g], &groups[g + 1]];
                let lanes = lanes | second << GROUP_WIDTH;
                if isa.intersect_pair(pair, wray, t_max, lanes, &mut pair_hits) {
                    let hits = &pair_hits;
                    // (The same loop as the one group's below, spelt out: an iterator over
                    // the hits' lanes for both, `core::iter::from_fn`, rendered the Cornell
                    // box 3% slower, 2026-12-07.)
                    let mut mask = hits.mask;
                    while mask != 0 {
                        let lane = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let h = TriangleHit {
                            t: hits.t[lane],
                            b1: hits.b1[lane],
                            b2: hits.b2[lane],
                        };
                        let vertices = groups[g + lane / GROUP_WIDTH].triangle(lane % GROUP_WIDTH);
                        if offer(order[base + lane], h, vertices, &mut t_max) {
                            return bound;
                        }
                    }
                    slot = pair_end;
                    continue;
                }
            }
            groups[g].intersect_into::<I::Group>(isa, wray, t_max, lanes, &mut group_hits);
            let hits = &group_hits;
            let mut mask = hits.mask;
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let h = TriangleHit {
                    t: hits.t[lane],
                    b1: hits.b1[lane],
                    b2: hits.b2[lane],
                };
                if offer(order[base + lane], h, groups[g].triangle(lane), &mut t_max) {
                    return bound;
                }
            }
            slot = lanes_end;
        }
        bound
    }

    /// Whether the ray hits an emissive triangle of the emitter table before `ray.t_max`,
    /// ignoring everything else: each is tested with the closest-hit query's own watertight
    /// test, so when this is false no listed emitter can be the closest hit of `ray`.
    #[inline]
    #[must_use]
    pub fn may_hit_emitter(&self, ray: &Ray) -> bool {
        let wray = WatertightRay::new(ray.o, ray.d);
        self.emitter_triangles.iter().any(|&t| {
            let [p0, p1, p2] = self.triangle_vertices(t);
            wray.intersect(ray.t_max, p0, p1, p2).is_some()
        })
    }

    /// The surface point at barycentrics `(b1, b2)` of `triangle`, seen from world direction
    /// `wo_world` (pointing away from the surface).
    #[inline]
    #[must_use]
    pub fn surface_at(
        &self,
        triangle: u32,
        b1: f32,
        b2: f32,
        wo_world: Vec3,
    ) -> SurfaceInteraction {
        self.surface_at_vertices(triangle, self.triangle_vertices(triangle), b1, b2, wo_world)
    }

    /// [`Self::surface_at`] given the triangle's vertices (`triangle_vertices(triangle)`).
    #[inline]
    #[must_use]
    fn surface_at_vertices(
        &self,
        triangle: u32,
        [p0, p1, p2]: [Vec3; 3],
        b1: f32,
        b2: f32,
        wo_world: Vec3,
    ) -> SurfaceInteraction {
        let [i0, i1, i2] = self.triangles[triangle as usize];
        let b0 = 1.0 - b1 - b2;
        let (p, p_err) = triangle_point(b1, b2, p0, p1, p2);
        let ng = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        let b = [b0, b1, b2];
        let bs = inset_barycentrics(b, [p0, p1, p2], ng, p_err);
        let (p_spawn, p_err) = if bs == b {
            (p, p_err)
        } else {
            let (q, e) = triangle_point(bs[1], bs[2], p0, p1, p2);
            (q, p_err.max(e))
        };
        let n = |i: u32| self.normals[i as usize];
        let ns = (n(i0) * b0 + n(i1) * b1 + n(i2) * b2).normalize_or_zero();
        // Degenerate vertex normals fall back to the geometric normal.
        let ns = if ns == Vec3::ZERO { ng } else { ns };
        let frame = Frame::from_normal(if ns == Vec3::ZERO { Vec3::Z } else { ns });
        SurfaceInteraction {
            p,
            p_spawn,
            p_err,
            ng,
            frame,
            wo: wo_world,
            material: self.triangle_materials[triangle as usize],
            triangle,
            b1,
            b2,
        }
    }

    /// Interpolated texture coordinates at barycentrics `(b1, b2)` of `triangle`.
    #[inline]
    #[must_use]
    pub fn uv_at(&self, triangle: u32, b1: f32, b2: f32) -> Vec2 {
        let [i0, i1, i2] = self.triangles[triangle as usize];
        let uv = |i: u32| self.textures.uvs[i as usize];
        uv(i0) * (1.0 - b1 - b2) + uv(i1) * b1 + uv(i2) * b2
    }

    /// The BSDF at a surface point, with its material's textures read there.
    #[inline]
    #[must_use]
    pub fn bsdf_at(&self, si: &SurfaceInteraction) -> SurfaceBsdf {
        let bsdf = self
            .material(si.material)
            .bsdf(&self.textures, || self.uv_at(si.triangle, si.b1, si.b2));
        SurfaceBsdf::new(bsdf, si.frame, si.ng)
    }

    /// The interaction for a hit of `ray`.
    #[inline]
    #[must_use]
    pub fn interaction(&self, ray: &Ray, hit: &Hit) -> SurfaceInteraction {
        self.surface_at_vertices(
            hit.triangle,
            hit.vertices,
            hit.b1,
            hit.b2,
            -ray.d.normalize(),
        )
    }

    /// Radiance emitted from `si` toward its `wo` (one-sided, front = shading normal side).
    #[inline]
    #[must_use]
    pub fn emitted(&self, si: &SurfaceInteraction) -> Rgb {
        let m = self.material(si.material);
        if si.wo.dot(si.frame.n) > 0.0 {
            m.emission
        } else {
            Rgb::ZERO
        }
    }

    #[inline]
    #[must_use]
    pub fn has_emitters(&self) -> bool {
        !self.emitter_triangles.is_empty()
    }
}
