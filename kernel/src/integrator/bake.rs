//! Per-vertex precomputed global illumination (TinyRender's `gi` pass, FORMAT.md §6).

use super::{dims, li_path_from_surface, PathSettings, PathStrategy};
use crate::bsdf::SurfaceBsdf;
use crate::math::{gamma, warp, Frame};
use crate::sampler::{mix64, IndependentSampler, Sampler, SamplerKind, ZSobolLayout};
use crate::scene::{SceneView, SurfaceInteraction};
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
#[must_use]
pub fn bake_vertex(
    scene: &SceneView<'_>,
    point: &BakePoint,
    settings: &PathSettings,
    estimator: BakeEstimator,
    samples: &BakeSamples,
    key: u64,
) -> Rgb {
    let n = point.n.normalize_or_zero();
    let count = samples.per_vertex;
    if n == Vec3::ZERO || count == 0 {
        return Rgb::ZERO;
    }
    let frame = Frame::from_normal(n);
    let material = scene.material(point.material);
    let vertex = Vertex {
        scene,
        point,
        n,
        frame,
        bsdf: SurfaceBsdf::new(material.bsdf(&scene.textures, || point.uv), frame, n),
        settings,
        strategy: estimator.strategy(),
    };
    let mut sum = Rgb::ZERO;
    match samples.sampler {
        SamplerKind::Independent => {
            for i in 0..count {
                sum += vertex.sample(&mut IndependentSampler::new(samples.seed, key, i));
            }
        }
        // Each vertex its own Sobol' points, scrambled by a seed of its own: the vertices'
        // estimates stay independent of one another, each stratified over its samples.
        SamplerKind::ZSobol => {
            let vertex_seed = mix64(samples.seed ^ key.wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let mut sampler = ZSobolLayout::new(vertex_seed, count, 1, 1).pixel_sampler(0, 0);
            for i in 0..count {
                sampler.start_sample(i, 0);
                sum += vertex.sample(&mut sampler);
            }
        }
    }
    material.emission + sum / count as f32
}

/// What every sample of a vertex shares.
struct Vertex<'s, 'a> {
    scene: &'s SceneView<'a>,
    point: &'s BakePoint,
    n: Vec3,
    frame: Frame,
    bsdf: SurfaceBsdf,
    settings: &'s PathSettings,
    strategy: PathStrategy,
}

impl Vertex<'_, '_> {
    /// One path's estimate of the scattered light (zero if it is not finite).
    #[inline]
    fn sample<S: Sampler>(&self, sampler: &mut S) -> Rgb {
        let (frame, p) = (self.frame, self.point.p);
        let view = warp::sample_cosine_hemisphere(dims::bake_view(sampler));
        let si = SurfaceInteraction {
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
        };
        let l = li_path_from_surface(
            self.scene,
            si,
            self.bsdf,
            self.settings,
            &self.strategy,
            sampler,
            &mut 0,
        );
        if crate::math::is_finite(l) {
            l
        } else {
            Rgb::ZERO
        }
    }
}
