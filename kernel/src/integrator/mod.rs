//! Light transport estimators. Each integrator is a function of the scene, a ray and a
//! [`Sampler`]; [`render_pixel`] averages them over a range of sample indices. The three path
//! tracers are one loop ([`li_path`]) with a [`PathStrategy`] each.
//!
//! Depth convention (TinyRender, FORMAT.md §6): `max_depth` counts scattering vertices between
//! the camera and the emitter. 0: emitters seen directly; 1: direct lighting; N: up to N
//! bounces; −1: unbounded, ended by Russian roulette.
//!
//! Russian roulette, two rules ([`Roulette`]):
//! - TinyRender's estimators (implicit, explicit path tracing) play it only when
//!   `max_depth == −1` (the rule of most TinyRender solutions, and the one the `_rr` reference
//!   uses): from `rr_depth` bounces on, a path continues with the fixed probability `rr_prob`
//!   and its throughput is divided by `rr_prob`. Bounded depths are rendered without roulette.
//! - ember's own estimators (MIS path tracing, the bake, light tracing, BDPT) use
//!   throughput-adaptive roulette capped by `rr_prob`
//!   ([`PathSettings::survives_adaptive_roulette`]) from `rr_depth` bounces on **at any depth
//!   limit**, as pbrt-v4 and Mitsuba 3 do: a bounded path that can no longer carry much light
//!   ends early instead of bouncing on to `max_depth`. The expected value is the bounded
//!   estimator's; only the variance and the work change (the cubebox bake, 12 bounces in a
//!   closed room: 0.56 of the time for 1.4 times the error, `bench/bake`). The last ray of a
//!   bounded path, which only looks for emission, is always traced, so `rr_depth ≥ max_depth`
//!   turns roulette off.

mod bake;
mod batch;
pub mod bdpt;
pub mod dims;
mod direct;
mod light_tracer;
mod path;
mod path_lanes;

pub use bake::{
    bake_vertex, bake_vertex_batched, bake_vertex_by_sample, BakeEstimator, BakePoint, BakeSamples,
};
pub use batch::{
    render_pixel_batched, render_run_batched, IndependentPixels, PixelSamples, Span, ZSobolPixels,
    BATCH, MIN_LANES, PACKET_SEGMENTS,
};
pub use bdpt::{li_bdpt, BdptScratch, BdptSink, MisHeuristic};
pub use direct::{sample_direct, DirectSample};
pub use light_tracer::{light_trace, ray_to_camera};
pub use path::{
    li_path, li_path_from_surface, power_heuristic, DirectLighting, PathState, PathStrategy,
    Roulette,
};

use crate::camera::Camera;
use crate::geometry::Ray;
use crate::sampler::{IndependentSampler, Sampler, SamplerKind, Sampling};
use crate::scene::SceneView;
use crate::Rgb;
use glam::Vec2;

/// Hard cap on the number of bounces even for `max_depth == −1`, so a scene with `rr_prob = 1`
/// and no absorption still terminates. At 1024 bounces the truncated energy is below 1e-22 of
/// the total in any scene whose albedo is at most 0.95.
pub const MAX_BOUNCES: u32 = 1024;

/// Which estimator to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// BSDF sampling only; emission counted at every vertex.
    PathImplicit,
    /// Next-event estimation at every vertex plus BSDF-sampled continuation; emission counted
    /// only at the camera vertex.
    PathExplicit,
    /// Emitter and BSDF sampling of direct light at every vertex, combined by multiple
    /// importance sampling (power heuristic). Not a TinyRender integrator.
    PathMis,
    /// Light tracing: paths from the emitters connected to the camera at every vertex and
    /// splatted (`type = "lighttracer"`).
    LightTracing,
    /// Bidirectional path tracing with every connection strategy, combined by MIS with the
    /// given heuristic (`type = "bdpt"`).
    Bdpt(MisHeuristic),
}

impl Integrator {
    /// The sampler the hosts use for this estimator unless told otherwise: the one with the
    /// lower error at equal time (`bench/sampler`, Cornell box 96², equal-time efficiency of
    /// Owen-scrambled Sobol' over independent samples, relMSE × seconds at equal spp):
    /// explicit 1.87–1.96, MIS 1.44–1.60, BDPT 1.58–2.00, but implicit 0.64–0.80 up to 256
    /// spp (1.02 at 512, 1.10 at 1024: its paths find the light by chance at any bounce, so
    /// stratifying the first dimensions buys less than the Sobol' indexing costs, 1.6 times
    /// the sampling time of a sample) and light tracing 0.92–1.03 (a light path's vertices land
    /// anywhere on the film, so stratifying a pixel's light paths stratifies no pixel's
    /// estimate). Those two keep independent samples.
    #[inline]
    #[must_use]
    pub const fn default_sampler(self) -> SamplerKind {
        match self {
            Self::PathImplicit | Self::LightTracing => SamplerKind::Independent,
            Self::PathExplicit | Self::PathMis | Self::Bdpt(_) => SamplerKind::ZSobol,
        }
    }

    /// The path loop settings of a path tracer (`None` for light tracing and BDPT).
    #[inline]
    #[must_use]
    pub const fn path_strategy(self) -> Option<PathStrategy> {
        match self {
            Self::PathImplicit => Some(PathStrategy::IMPLICIT),
            Self::PathExplicit => Some(PathStrategy::EXPLICIT),
            Self::PathMis => Some(PathStrategy::MIS),
            Self::LightTracing | Self::Bdpt(_) => None,
        }
    }

    /// Whether the estimator splats contributions onto other pixels than its sample's
    /// ([`crate::splat`]): tiles are then not independent.
    #[inline]
    #[must_use]
    pub const fn splats(self) -> bool {
        matches!(self, Self::LightTracing | Self::Bdpt(_))
    }
}

/// Path length and termination settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathSettings {
    pub max_depth: i32,
    pub rr_depth: i32,
    pub rr_prob: f32,
    /// Work the scene lets the integrators skip ([`Shortcuts::analyse`]); images are
    /// bit-identical with and without them.
    pub shortcuts: Shortcuts,
}

impl Default for PathSettings {
    /// TinyRender's `path` defaults: unbounded depth, roulette from depth 5 with survival 0.95;
    /// no shortcuts (they depend on the scene: see [`Shortcuts::analyse`]).
    fn default() -> Self {
        Self {
            max_depth: -1,
            rr_depth: 5,
            rr_prob: 0.95,
            shortcuts: Shortcuts::NONE,
        }
    }
}

/// Emitter triangles up to which [`Shortcuts::terminal_emitter_test`] pays: testing them one
/// by one must cost less than the closest-hit traversal it saves.
pub const TERMINAL_TEST_MAX_EMITTERS: usize = 16;

/// Work that a scene lets the integrators skip, found by [`Shortcuts::analyse`]. Each shortcut
/// gives bit-identical images to the general code where it applies (tested in CI); what it
/// skips is work whose result the scene makes known in advance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Shortcuts {
    /// The last ray of a bounded path (the one from the vertex at `max_depth`) only matters if
    /// it lands on an emitter. When the scene has few emissive triangles and all of them are in
    /// its emitter table, the ray is tested against those triangles alone first and the scene
    /// is traversed only if one is hit; a non-emissive closest hit then ends the path without
    /// computing its surface interaction. Exact: the watertight test's verdict for a triangle
    /// does not depend on the rest of the scene and only widens with the ray's extent, so a ray
    /// that misses every emissive triangle cannot have one as its closest hit.
    pub terminal_emitter_test: bool,
}

impl Shortcuts {
    /// The general code: nothing skipped.
    pub const NONE: Self = Self {
        terminal_emitter_test: false,
    };

    /// The shortcuts that apply to `scene` (one pass over its triangles). A scene that fails
    /// [`SceneView::validate`] gets none.
    #[must_use]
    pub fn analyse(scene: &SceneView<'_>) -> Self {
        if scene.validate().is_err() {
            return Self::NONE;
        }
        let emits = |t: u32| {
            let material = scene.triangle_materials[t as usize];
            scene.material(material).is_emissive()
        };
        // The table lists distinct triangles (validate checks they ascend), so when all of
        // them emit and there are as many as emissive triangles, it lists every one.
        let listed = scene.emitter_triangles;
        let emissive = (0..scene.triangles.len() as u32)
            .filter(|&t| emits(t))
            .count();
        let terminal_emitter_test = listed.len() <= TERMINAL_TEST_MAX_EMITTERS
            && listed.iter().all(|&t| emits(t))
            && emissive == listed.len();
        Self {
            terminal_emitter_test,
        }
    }
}

impl PathSettings {
    /// Whether a path may have `bounces` scattering vertices.
    #[inline]
    #[must_use]
    pub fn allows(&self, bounces: u32) -> bool {
        if self.max_depth < 0 {
            bounces <= MAX_BOUNCES
        } else {
            bounces <= self.max_depth as u32
        }
    }

    /// Whether the ray leaving scattering vertex `bounces` is the last of its path: the
    /// vertex it finds may only contribute its emission.
    #[inline]
    #[must_use]
    pub fn is_terminal(&self, bounces: u32) -> bool {
        !self.allows(bounces + 1)
    }

    /// Traces the last ray of a path ([`Self::is_terminal`]) and returns its closest hit only if
    /// that hit is on an emissive triangle: nothing else about it is needed. With
    /// [`Shortcuts::terminal_emitter_test`] the emitters are tested first (see there).
    #[inline]
    #[must_use]
    pub fn terminal_hit(&self, scene: &SceneView<'_>, ray: &Ray) -> Option<crate::scene::Hit> {
        let mut hit = None;
        self.terminal_hit_by(scene, ray, |ray, hit| *hit = scene.intersect(ray), &mut hit);
        hit
    }

    /// [`Self::terminal_hit`] with the closest-hit query `intersect`, which writes its answer
    /// to the place it is given (the batched path tracer's, [`SceneView::intersect_with`]),
    /// into `hit`.
    #[inline]
    pub fn terminal_hit_by(
        &self,
        scene: &SceneView<'_>,
        ray: &Ray,
        intersect: impl FnOnce(&Ray, &mut Option<crate::scene::Hit>),
        hit: &mut Option<crate::scene::Hit>,
    ) {
        if self.shortcuts.terminal_emitter_test && !scene.may_hit_emitter(ray) {
            *hit = None;
            return;
        }
        intersect(ray, hit);
        if let Some(h) = hit {
            let material = scene.triangle_materials[h.triangle as usize];
            if !scene.material(material).is_emissive() {
                *hit = None;
            }
        }
    }

    /// Whether Russian roulette of kind `roulette` is played after `bounces` scattering
    /// vertices (from `rr_depth` on; the fixed rule only at unbounded depth, the adaptive one
    /// before the last bounce of a bounded path too): otherwise the survival tests below
    /// ignore their number.
    #[inline]
    #[must_use]
    pub fn roulette_applies(&self, roulette: Roulette, bounces: u32) -> bool {
        let from = (bounces as i64) >= i64::from(self.rr_depth);
        match roulette {
            Roulette::Fixed => self.max_depth < 0 && from,
            Roulette::Adaptive => {
                from && (self.max_depth < 0 || (bounces as i64) < i64::from(self.max_depth))
            }
        }
    }

    /// Russian roulette after `bounces` scattering vertices, with the uniform number `u`.
    /// Returns false when the path is terminated; on survival divides `beta` by `rr_prob`.
    #[inline]
    pub fn survives_roulette(&self, bounces: u32, u: f32, beta: &mut Rgb) -> bool {
        if !self.roulette_applies(Roulette::Fixed, bounces) {
            return true;
        }
        if u >= self.rr_prob {
            return false;
        }
        *beta /= self.rr_prob;
        true
    }

    /// Throughput-adaptive Russian roulette (pbrt-v4, Mitsuba 3): from `rr_depth` bounces on,
    /// a path survives with probability equal to the largest component of its throughput
    /// times `eta_scale` (the product of η′² over the dielectric crossings so far, which
    /// undoes their radiance scaling; pbrt's `etaScale`), capped by `rr_prob`. Paths that can
    /// no longer carry much light end early, bright ones go on. Unbiased like the fixed rule,
    /// with far fewer rays per sample in absorbing scenes. Applies at bounded depths too,
    /// before the last bounce ([`Self::roulette_applies`]).
    #[inline]
    pub fn survives_adaptive_roulette(
        &self,
        bounces: u32,
        u: f32,
        eta_scale: f32,
        beta: &mut Rgb,
    ) -> bool {
        if !self.roulette_applies(Roulette::Adaptive, bounces) {
            return true;
        }
        let q = (*beta * eta_scale).max_element().min(self.rr_prob);
        // Written so that a NaN throughput ends the path.
        if u < q {
            *beta /= q;
            true
        } else {
            false
        }
    }
}

/// Radiance along `ray` with the chosen estimator; every ray traced adds 1 to `rays`.
#[inline]
pub fn li<S: Sampler>(
    integrator: Integrator,
    scene: &SceneView<'_>,
    ray: &Ray,
    settings: &PathSettings,
    sampler: &mut S,
    rays: &mut u32,
) -> Rgb {
    // One call per strategy, so that each path tracer is compiled with its strategy known
    // (the loop is inlined at each call and the branches on the strategy fold away).
    match integrator {
        Integrator::PathImplicit => {
            li_path(scene, ray, settings, &PathStrategy::IMPLICIT, sampler, rays)
        }
        Integrator::PathExplicit => {
            li_path(scene, ray, settings, &PathStrategy::EXPLICIT, sampler, rays)
        }
        Integrator::PathMis => li_path(scene, ray, settings, &PathStrategy::MIS, sampler, rays),
        // Not path tracers: they need the camera and a sink (see `render_sample`).
        Integrator::LightTracing | Integrator::Bdpt(_) => Rgb::ZERO,
    }
}

/// What one sample gives its own pixel: radiance (0 for light tracing, whose contributions
/// are all splats) and the rays it traced.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SampleResult {
    pub l: Rgb,
    pub rays: u32,
}

/// Renders sample `index` of pixel `(x, y)`: the kernel's rendering entry point. The sample
/// is keyed by `(sampling, (x, y), index)` and is a pure function of its key, the scene, the
/// camera and the settings. Path tracers return their radiance; light tracing traces one
/// light path (the `W·H·spp` light paths of an image are one per pixel sample) and BDPT one
/// pair of subpaths, and both put their contributions to other pixels into `sink` (see
/// [`crate::splat`] for accumulating them order-independently). `scratch` holds BDPT's
/// subpaths (other estimators take `None`); BDPT without it renders nothing.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn render_sample<K: BdptSink>(
    integrator: Integrator,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    sampling: &Sampling,
    x: u32,
    y: u32,
    index: u32,
    scratch: Option<&mut BdptScratch>,
    sink: &mut K,
) -> SampleResult {
    // One call, monomorphised for each sampler.
    macro_rules! sample {
        ($sampler:expr) => {
            sample_with(
                integrator,
                scene,
                camera,
                settings,
                x,
                y,
                scratch,
                sink,
                &mut $sampler,
            )
        };
    }
    match sampling.kind {
        SamplerKind::Independent => {
            let pixel = u64::from(y) * u64::from(camera.width) + u64::from(x);
            sample!(IndependentSampler::new(sampling.seed, pixel, index))
        }
        SamplerKind::ZSobol => sample!(sampling.zsobol().start_pixel_sample(x, y, index, 0)),
    }
}

/// [`render_sample`] with its sampler started.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn sample_with<S: Sampler, K: BdptSink>(
    integrator: Integrator,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    x: u32,
    y: u32,
    scratch: Option<&mut BdptScratch>,
    sink: &mut K,
    sampler: &mut S,
) -> SampleResult {
    let mut rays = 0u32;
    let l = match integrator {
        Integrator::LightTracing => {
            light_trace(scene, camera, settings, sampler, sink, &mut rays);
            Rgb::ZERO
        }
        Integrator::Bdpt(heuristic) => {
            let Some(scratch) = scratch else {
                return SampleResult::default();
            };
            let u = dims::camera(sampler);
            let ray = camera.generate_ray(x, y, u);
            let raster = Vec2::new(x as f32 + u.x, y as f32 + u.y);
            li_bdpt(
                scene, camera, &ray, raster, settings, heuristic, scratch, sampler, sink, &mut rays,
            )
        }
        _ => {
            let ray = camera.generate_ray(x, y, dims::camera(sampler));
            li(integrator, scene, &ray, settings, sampler, &mut rays)
        }
    };
    SampleResult { l, rays }
}

/// Sums of the samples of one pixel: enough for the mean and the sample variance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelStats {
    pub sum: Rgb,
    pub sum_sq: Rgb,
    /// Samples that came out NaN or infinite; they are counted as 0 (and reported by hosts).
    pub invalid: u32,
    /// Rays traced for these samples, closest-hit and shadow (for rays/s in benchmarks).
    pub rays: u64,
}

impl PixelStats {
    /// Adds one sample; a NaN or infinite one is counted in `invalid` instead (and in debug
    /// builds that is reported loudly, since it means a bug in an estimator).
    #[inline]
    pub fn add(&mut self, l: Rgb) {
        if crate::math::is_finite(l) {
            self.sum += l;
            self.sum_sq += l * l;
        } else {
            self.invalid += 1;
        }
        debug_assert!(
            crate::math::is_finite(self.sum),
            "non-finite value accumulated in a pixel"
        );
    }
}

/// Renders samples `first .. first + count` of pixel `(x, y)` with [`render_sample`] and
/// adds them, in sample order, to `stats`, with the number of rays they traced. Because each
/// sample is added to the running sums in index order, rendering `0..n` in one call or in any
/// sequence of consecutive ranges gives bit-identical sums: progressive and interrupted
/// renders agree with one-shot renders, whatever the threads or tiles.
///
/// MIS path tracing runs [`BATCH`] samples at a time ([`render_pixel_batched`], diffuse
/// vertices in SIMD lanes; a remainder of fewer than [`MIN_LANES`] samples one at a time),
/// which gives these sums bit for bit (tests/tests/batched.rs) in less time; the other
/// integrators run one sample at a time ([`render_pixel_by_sample`]).
#[allow(clippy::too_many_arguments)]
#[must_use]
pub fn render_pixel<K: BdptSink>(
    integrator: Integrator,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    sampling: &Sampling,
    x: u32,
    y: u32,
    first: u32,
    count: u32,
    stats: PixelStats,
    scratch: Option<&mut BdptScratch>,
    sink: &mut K,
) -> PixelStats {
    if integrator == Integrator::PathMis {
        return render_pixel_batched(
            &PathStrategy::MIS,
            scene,
            camera,
            settings,
            sampling,
            x,
            y,
            first,
            count,
            stats,
            PACKET_SEGMENTS,
        );
    }
    render_pixel_by_sample(
        integrator, scene, camera, settings, sampling, x, y, first, count, stats, scratch, sink,
    )
}

/// [`render_pixel`] for each pixel `(x + k, y)` of a run of a row, into `stats[k]`: the same
/// sums bit for bit. A call of fewer samples per pixel than a batch's lanes need
/// ([`MIN_LANES`]) under MIS path tracing fills its batches with the samples of neighbouring
/// pixels ([`render_run_batched`]); every other call runs pixel by pixel.
#[allow(clippy::too_many_arguments)]
pub fn render_row<K: BdptSink>(
    integrator: Integrator,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    sampling: &Sampling,
    (x, y): (u32, u32),
    first: u32,
    count: u32,
    stats: &mut [PixelStats],
    mut scratch: Option<&mut BdptScratch>,
    sink: &mut K,
) {
    if integrator == Integrator::PathMis && (count as usize) < MIN_LANES && stats.len() > 1 {
        render_run_batched(
            &PathStrategy::MIS,
            scene,
            camera,
            settings,
            sampling,
            (x, y),
            first,
            count,
            stats,
        );
        return;
    }
    for (k, s) in stats.iter_mut().enumerate() {
        *s = render_pixel(
            integrator,
            scene,
            camera,
            settings,
            sampling,
            x.wrapping_add(k as u32),
            y,
            first,
            count,
            *s,
            scratch.as_deref_mut(),
            sink,
        );
    }
}

/// [`render_pixel`] one sample after another through [`render_sample`]: the reference the
/// batched driver is tested against, and what every integrator but MIS path tracing runs.
#[must_use]
pub fn render_pixel_by_sample<K: BdptSink>(
    integrator: Integrator,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    sampling: &Sampling,
    x: u32,
    y: u32,
    first: u32,
    count: u32,
    mut stats: PixelStats,
    mut scratch: Option<&mut BdptScratch>,
    sink: &mut K,
) -> PixelStats {
    let mut add = |r: SampleResult| {
        stats.add(r.l);
        stats.rays += u64::from(r.rays);
    };
    match sampling.kind {
        SamplerKind::Independent => {
            for i in first..first + count {
                let r = render_sample(
                    integrator,
                    scene,
                    camera,
                    settings,
                    sampling,
                    x,
                    y,
                    i,
                    scratch.as_deref_mut(),
                    sink,
                );
                add(r);
            }
        }
        // One sampler for the pixel, restarted per sample: it keeps the per-pixel part of the
        // Sobol' indices ([`crate::sampler::ZSobolPixelSampler`]); the values are
        // `render_sample`'s.
        SamplerKind::ZSobol => {
            let mut sampler = sampling.zsobol().pixel_sampler(x, y);
            for i in first..first + count {
                sampler.start_sample(i, 0);
                let r = sample_with(
                    integrator,
                    scene,
                    camera,
                    settings,
                    x,
                    y,
                    scratch.as_deref_mut(),
                    sink,
                    &mut sampler,
                );
                add(r);
            }
        }
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::{PathSettings, Roulette};

    /// Where each roulette rule is played: the fixed one only at unbounded depth, the
    /// adaptive one from `rr_depth` on at any depth limit but never before a bounded path's
    /// last ray (so `rr_depth ≥ max_depth` turns it off).
    #[test]
    fn roulette_rules() {
        let settings = |max_depth, rr_depth| PathSettings {
            max_depth,
            rr_depth,
            ..PathSettings::default()
        };
        // Bit `b`: played after `b` bounces.
        let played = |s: PathSettings, r| {
            (0..16u32).fold(0u32, |m, b| m | u32::from(s.roulette_applies(r, b)) << b)
        };
        let range = |a: u32, b: u32| (a..b).fold(0u32, |m, i| m | 1 << i);
        assert_eq!(played(settings(-1, 5), Roulette::Fixed), range(5, 16));
        assert_eq!(played(settings(-1, 5), Roulette::Adaptive), range(5, 16));
        assert_eq!(played(settings(12, 5), Roulette::Fixed), 0);
        assert_eq!(played(settings(12, 5), Roulette::Adaptive), range(5, 12));
        assert_eq!(played(settings(5, 5), Roulette::Adaptive), 0);
        assert_eq!(played(settings(0, 0), Roulette::Adaptive), 0);
        assert_eq!(played(settings(3, 0), Roulette::Adaptive), range(0, 3));
    }

    /// A path the roulette is not played for survives untouched; where it is played, the
    /// survival probability is the throughput's largest component capped by `rr_prob`, and
    /// the survivor's throughput is divided by it.
    #[test]
    fn adaptive_roulette_at_a_bounded_depth() {
        let s = PathSettings {
            max_depth: 12,
            rr_depth: 5,
            ..PathSettings::default()
        };
        let beta0 = crate::Rgb::new(0.2, 0.1, 0.05);
        let mut beta = beta0;
        assert!(s.survives_adaptive_roulette(4, 0.99, 1.0, &mut beta));
        assert_eq!(beta, beta0);
        assert!(s.survives_adaptive_roulette(12, 0.99, 1.0, &mut beta));
        assert_eq!(beta, beta0);
        assert!(!s.survives_adaptive_roulette(5, 0.2, 1.0, &mut beta));
        assert!(s.survives_adaptive_roulette(5, 0.19, 1.0, &mut beta));
        assert_eq!(beta, beta0 / 0.2);
        let mut beta = beta0;
        assert!(s.survives_roulette(5, 0.99, &mut beta));
        assert_eq!(beta, beta0);
    }
}
