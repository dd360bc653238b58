//! Per-vertex precomputed global illumination (TinyRender's `gi` pass, FORMAT.md §6).

use super::batch::{IndependentPixels, Job, Origin, Pixel, PixelSamples, BATCH};
use super::path_lanes::PathLanes;
use super::{dims, li_path_from_surface, PathSettings, PathStrategy, SampleResult};
use crate::bsdf::{Bsdf, SurfaceBsdf};
use crate::math::{gamma, warp, Frame};
use crate::sampler::{
    lanes_of, mix64, IndependentSampler, Sampler, SamplerKind, ZSobolLayout, ZSobolPixelSampler,
};
use crate::scene::{SceneView, SurfaceInteraction};
use crate::simd::Isa;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// The path tracer a bake runs from each vertex.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BakeEstimator {
    /// Multiple importance sampling of direct light (the default): low variance everywhere.
    #[default]
    Mis,
    /// TinyRender's explicit path tracing (next-event estimation only): the estimator of its
    /// reference images, with unbounded variance at vertices on room edges.
    Explicit,
}

impl BakeEstimator {
    #[must_use]
    pub const fn strategy(self) -> PathStrategy {
        match self {
            Self::Mis => PathStrategy::MIS,
            Self::Explicit => PathStrategy::EXPLICIT,
        }
    }
}

/// The samples of a bake: how many per vertex, from which sampler, with which seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BakeSamples {
    /// Owen-scrambled Sobol' points per vertex ([`SamplerKind::ZSobol`], the default of the
    /// hosts: about a third of independent sampling's error at 300 samples per vertex) or
    /// independent numbers.
    pub sampler: SamplerKind,
    pub seed: u64,
    pub per_vertex: u32,
}

/// A surface point to bake: position, unit normal, material and texture coordinates (read
/// only when the material is textured).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakePoint {
    pub p: Vec3,
    pub n: Vec3,
    pub material: u32,
    pub uv: Vec2,
}

/// Estimates the view-independent radiance of `point` from `samples` path-tracing samples:
/// its emission plus the **cosine-weighted average over view directions** of the light it
/// scatters,
///
/// `B = Le + (1/π) ∫_{H+} L_s(ωo) cosθo dωo`,
///
/// i.e. its radiosity divided by π. A Gouraud-shaded mesh can show one colour per vertex
/// whatever the view, and this is the constant closest to the true outgoing radiance in the
/// cosine-weighted least-squares sense; it also conserves the energy the surface sends out.
/// For a Lambertian surface it is exactly its outgoing radiance. For a glossy one it keeps
/// the lobe's energy, spread over the hemisphere; a mirror of reflectance `Ks` shows `Ks` times
/// the average incident radiance (as a white diffuse surface of albedo `Ks` would), a glass
/// surface the average of what it reflects and transmits toward its front side. Each sample
/// draws its view direction from the cosine-weighted hemisphere about the normal
/// ([`dims::BAKE_VIEW`]) and traces the full BSDF from there.
///
/// The default estimator is path tracing with multiple importance sampling of direct light
/// ([`BakeEstimator::Mis`]). Mesh vertices sit on the edges where walls meet, and there pure
/// next-event estimation has unbounded variance (the 1/d² of the neighbouring wall): its
/// estimates at room edges came out 20–30% low at 1024 samples in the furnace test. The BSDF
/// samples that MIS adds cover the near field; the expected value is the same.
///
/// Sample `i` is keyed by `(seed, key, i)`; `key` identifies the vertex. With
/// [`SamplerKind::ZSobol`] each vertex draws its own Owen-scrambled Sobol' points (a
/// one-pixel [`ZSobolLayout`] seeded by `(seed, key)`, room for `per_vertex` samples rounded
/// up to a power of two), so its samples are stratified in every dimension pair while the
/// vertices' estimates stay independent of one another.
///
/// The point is treated as exact input (a mesh vertex): its error bound is that of a value
/// rounded once, and rays leave it offset along the normal by that bound.
///
/// The MIS bake runs [`BATCH`] samples at a time ([`bake_vertex_batched`], its diffuse
/// vertices in SIMD lanes), which gives this value bit for bit (tests/tests/batched.rs);
/// the explicit one runs one sample at a time ([`bake_vertex_by_sample`]).
#[must_use]
pub fn bake_vertex(
    scene: &SceneView<'_>,
    point: &BakePoint,
    settings: &PathSettings,
    estimator: BakeEstimator,
    samples: &BakeSamples,
    key: u64,
) -> Rgb {
    match estimator {
        BakeEstimator::Mis => bake_vertex_batched(scene, point, settings, estimator, samples, key),
        BakeEstimator::Explicit => {
            bake_vertex_by_sample(scene, point, settings, estimator, samples, key)
        }
    }
}

/// [`bake_vertex`] one sample after another: the reference the batched bake is tested
/// against.
#[must_use]
pub fn bake_vertex_by_sample(
    scene: &SceneView<'_>,
    point: &BakePoint,
    settings: &PathSettings,
    estimator: BakeEstimator,
    samples: &BakeSamples,
    key: u64,
) -> Rgb {
    let Some(vertex) = Vertex::new(scene, point, settings, estimator, samples) else {
        return Rgb::ZERO;
    };
    let count = samples.per_vertex;
    let mut sum = Rgb::ZERO;
    match samples.sampler {
        SamplerKind::Independent => {
            for i in 0..count {
                sum += vertex.sample(&mut IndependentSampler::new(samples.seed, key, i));
            }
        }
        SamplerKind::ZSobol => {
            let mut sampler = vertex_sobol(samples, key);
            for i in 0..count {
                sampler.start_sample(i, 0);
                sum += vertex.sample(&mut sampler);
            }
        }
    }
    vertex.material_emission + sum / count as f32
}

/// [`bake_vertex`] with [`BATCH`] samples at a time through the batched path tracer
/// (`super::batch`), for any estimator: the same value bit for bit.
#[must_use]
pub fn bake_vertex_batched(
    scene: &SceneView<'_>,
    point: &BakePoint,
    settings: &PathSettings,
    estimator: BakeEstimator,
    samples: &BakeSamples,
    key: u64,
) -> Rgb {
    let Some(vertex) = Vertex::new(scene, point, settings, estimator, samples) else {
        return Rgb::ZERO;
    };
    let count = samples.per_vertex;
    let (mut independent, mut zsobol);
    let pixel = match samples.sampler {
        SamplerKind::Independent => {
            independent = IndependentPixels::new(samples.seed, key);
            Pixel::Independent(&mut independent)
        }
        SamplerKind::ZSobol => {
            zsobol = vertex_sobol(samples, key);
            Pixel::ZSobol(&mut zsobol)
        }
    };
    let job = Job {
        strategy: &vertex.strategy,
        scene,
        settings,
        origin: &vertex,
        packet_segments: 0,
    };
    let mut sum = Rgb::ZERO;
    job.dispatch(pixel, 0, count, |r: &SampleResult| {
        sum += finite_or_zero(r.l)
    });
    vertex.material_emission + sum / count as f32
}

/// Each vertex its own Sobol' points, scrambled by a seed of its own: the vertices' estimates
/// stay independent of one another, each stratified over its samples.
fn vertex_sobol(samples: &BakeSamples, key: u64) -> ZSobolPixelSampler {
    let vertex_seed = mix64(samples.seed ^ key.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    ZSobolLayout::new(vertex_seed, samples.per_vertex, 1, 1).pixel_sampler(0, 0)
}

/// A sample's estimate, or zero if it is not finite.
#[inline(always)]
fn finite_or_zero(l: Rgb) -> Rgb {
    if crate::math::is_finite(l) {
        l
    } else {
        Rgb::ZERO
    }
}

/// What every sample of a vertex shares.
struct Vertex<'s, 'a> {
    scene: &'s SceneView<'a>,
    point: &'s BakePoint,
    n: Vec3,
    frame: Frame,
    bsdf: Bsdf,
    material_emission: Rgb,
    settings: &'s PathSettings,
    strategy: PathStrategy,
}

impl<'s, 'a> Vertex<'s, 'a> {
    /// The vertex of `point`, or `None` if it has nothing to bake (no normal, no samples).
    fn new(
        scene: &'s SceneView<'a>,
        point: &'s BakePoint,
        settings: &'s PathSettings,
        estimator: BakeEstimator,
        samples: &BakeSamples,
    ) -> Option<Self> {
        let n = point.n.normalize_or_zero();
        if n == Vec3::ZERO || samples.per_vertex == 0 {
            return None;
        }
        let material = scene.material(point.material);
        Some(Self {
            scene,
            point,
            n,
            frame: Frame::from_normal(n),
            bsdf: material.bsdf(&scene.textures, || point.uv),
            material_emission: material.emission,
            settings,
            strategy: estimator.strategy(),
        })
    }

    /// The vertex seen along the view direction drawn from `u` (cosine-weighted about the
    /// normal).
    #[inline(always)]
    fn interaction(&self, u: Vec2) -> SurfaceInteraction {
        let (frame, p) = (self.frame, self.point.p);
        let view = warp::sample_cosine_hemisphere(u);
        SurfaceInteraction {
            p,
            p_spawn: p,
            p_err: p.abs() * gamma(1),
            ng: self.n,
            frame,
            wo: frame.to_world(view),
            material: self.point.material,
            triangle: u32::MAX,
            b1: 0.0,
            b2: 0.0,
        }
    }

    /// One path's estimate of the scattered light (zero if it is not finite).
    #[inline]
    fn sample<S: Sampler>(&self, sampler: &mut S) -> Rgb {
        let si = self.interaction(dims::bake_view(sampler));
        let l = li_path_from_surface(
            self.scene,
            si,
            SurfaceBsdf::new(self.bsdf, self.frame, self.n),
            self.settings,
            &self.strategy,
            sampler,
            &mut 0,
        );
        finite_or_zero(l)
    }
}

/// A bake's paths start at the vertex, seen along their view directions.
impl Origin for &Vertex<'_, '_> {
    const DIMENSIONS: u32 = dims::BAKE_VIEW;

    #[inline(always)]
    fn start<I: Isa, P: PixelSamples>(
        &self,
        _isa: I,
        _scene: &SceneView<'_>,
        pixel: &mut P,
        indices: &[u32; BATCH],
        used: u32,
        state: &mut PathLanes,
        _seen: &mut [Rgb; BATCH],
        _results: &mut [SampleResult; BATCH],
    ) -> u32 {
        for lane in lanes_of(used) {
            pixel.start_sample(indices[lane], 0);
            state
                .si
                .set(lane, &self.interaction(dims::bake_view(pixel)));
            state.start(lane, self.bsdf);
        }
        used
    }

    #[inline(always)]
    fn one<P: PixelSamples>(
        &self,
        _index: u32,
        _strategy: &PathStrategy,
        _scene: &SceneView<'_>,
        _settings: &PathSettings,
        pixel: &mut P,
    ) -> SampleResult {
        SampleResult {
            l: self.sample(pixel),
            rays: 0,
        }
    }
}
