//! ember's path tracers: one path loop whose state (throughput, η scale, the last scattering
//! event) is the same for every estimator, and whose differences are the named fields of a
//! [`PathStrategy`] (Mitsuba 3's `path.cpp` keeps one loop state the same way).

use super::direct::{sample_direct_unoccluded, DirectSample};
use super::{dims, PathSettings};
use crate::bsdf::{BsdfFlags, SurfaceBsdf, TransportMode};
use crate::emitter::emitter_pdf;
use crate::geometry::Ray;
use crate::math::SolidAnglePdf;
use crate::sampler::Sampler;
use crate::scene::{Hit, SceneView, SurfaceInteraction};
use crate::Rgb;
use glam::Vec3;

/// How light arriving directly from emitters is found at each scattering vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DirectLighting {
    /// BSDF sampling only: emission is counted wherever a path lands on an emitter
    /// (TinyRender's implicit path tracer).
    BsdfSampling,
    /// Next-event estimation (an emitter point and a shadow ray) at every vertex with a
    /// non-delta lobe; emission found by BSDF-sampled rays is counted only after a delta
    /// bounce, where no next-event estimate was made (TinyRender's explicit path tracer, with
    /// pbrt's `specularBounce` so that lights seen in mirrors and through glass appear).
    NextEvent,
    /// Both, combined by multiple importance sampling with the power heuristic (ember's).
    Mis,
}

/// How a path is ended at random once `rr_depth` bounces are done (where:
/// [`PathSettings::roulette_applies`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Roulette {
    /// Survival with the fixed probability `rr_prob`, at unbounded depth only (TinyRender).
    Fixed,
    /// Survival with probability `min(max component of β·η_scale, rr_prob)` (pbrt-v4, Mitsuba 3),
    /// where `η_scale` undoes the radiance scaling of dielectric crossings so that paths inside
    /// glass are not killed for being "dim" (pbrt's `etaScale`); at any depth limit, before a
    /// bounded path's last bounce.
    Adaptive,
}

/// What distinguishes the path tracers; everything else is the shared loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathStrategy {
    pub direct: DirectLighting,
    pub roulette: Roulette,
}

impl PathStrategy {
    pub const IMPLICIT: Self = Self {
        direct: DirectLighting::BsdfSampling,
        roulette: Roulette::Fixed,
    };
    pub const EXPLICIT: Self = Self {
        direct: DirectLighting::NextEvent,
        roulette: Roulette::Fixed,
    };
    pub const MIS: Self = Self {
        direct: DirectLighting::Mis,
        roulette: Roulette::Adaptive,
    };
}

/// Power heuristic (β = 2) weight of a strategy with density `a` against one with density `b`,
/// 0 when it is not finite (Mitsuba's guarded `mis_weight`).
#[inline]
#[must_use]
pub fn power_heuristic(a: SolidAnglePdf, b: SolidAnglePdf) -> f32 {
    let (a2, b2) = (a.0 * a.0, b.0 * b.0);
    let w = a2 / (a2 + b2);
    if w.is_finite() {
        w
    } else {
        0.0
    }
}

/// Radiance arriving along `ray` (emission seen directly plus scattered light).
#[inline(always)]
pub fn li_path<S: Sampler>(
    scene: &SceneView<'_>,
    ray: &Ray,
    settings: &PathSettings,
    strategy: &PathStrategy,
    sampler: &mut S,
    rays: &mut u32,
) -> Rgb {
    *rays += 1;
    let Some(hit) = scene.intersect(ray) else {
        return Rgb::ZERO;
    };
    let si = scene.interaction(ray, &hit);
    let bsdf = scene.bsdf_at(&si);
    scene.emitted(&si) + li_path_from_surface(scene, si, bsdf, settings, strategy, sampler, rays)
}

/// Radiance scattered at `si` toward `si.wo` (its own emission excluded), with `bsdf` at `si`
/// as the first scattering vertex and the scene's materials further on. Per bounce the
/// sampler's dimensions are laid out as [`dims`] says. Always inlined, so that a caller that
/// passes a constant strategy gets a loop specialised for it. Every ray it traces adds 1 to
/// `rays`.
#[inline(always)]
pub fn li_path_from_surface<S: Sampler>(
    scene: &SceneView<'_>,
    si: SurfaceInteraction,
    bsdf: SurfaceBsdf,
    settings: &PathSettings,
    strategy: &PathStrategy,
    sampler: &mut S,
    rays: &mut u32,
) -> Rgb {
    let mut path = PathState::new(si, bsdf);
    while path.bounce(scene, settings, strategy, sampler, rays) {}
    path.l
}

/// One path between bounces: everything the path loop carries from one scattering vertex to
/// the next (Mitsuba 3's loop state). [`li_path_from_surface`] runs [`Self::bounce`] until it
/// says the path has ended; a driver that advances many paths a bounce at a time runs the same
/// bounces, so its paths compute exactly what the one-path loop computes.
#[derive(Clone, Copy, Debug)]
pub struct PathState {
    /// Radiance gathered so far.
    pub l: Rgb,
    /// Throughput of the path up to `si`.
    pub beta: Rgb,
    /// Product of η′² over the dielectric crossings so far ([`Roulette::Adaptive`]).
    pub eta_scale: f32,
    /// Scattering vertices before `si`.
    pub bounces: u32,
    /// The scattering vertex the next bounce starts from, and its BSDF.
    pub si: SurfaceInteraction,
    pub bsdf: SurfaceBsdf,
}

impl PathState {
    /// A path whose first scattering vertex is `si` with `bsdf`, nothing gathered yet.
    #[inline(always)]
    #[must_use]
    pub fn new(si: SurfaceInteraction, bsdf: SurfaceBsdf) -> Self {
        Self {
            l: Rgb::ZERO,
            beta: Rgb::ONE,
            eta_scale: 1.0,
            bounces: 0,
            si,
            bsdf,
        }
    }

    /// Scatters at the current vertex: gathers its direct light, samples the next direction,
    /// plays roulette, traces the ray and counts the emission it finds. Returns whether the
    /// path goes on from a new vertex; the sampler must be at the vertex's first dimension
    /// ([`dims::BounceDims`]), and is left at the next vertex's.
    ///
    /// The bounce is its three steps with the rays traced between them, which is how a driver
    /// that traces the rays of many paths together runs it: [`Self::light`], the shadow ray,
    /// [`Self::scatter`], the scattered ray, [`Self::arrive`].
    #[inline(always)]
    pub fn bounce<S: Sampler>(
        &mut self,
        scene: &SceneView<'_>,
        settings: &PathSettings,
        strategy: &PathStrategy,
        sampler: &mut S,
        rays: &mut u32,
    ) -> bool {
        let Some((u, shadow)) = self.light(scene, settings, strategy, sampler) else {
            return false;
        };
        if let Some(shadow) = shadow {
            *rays += 1;
            self.add_light(&shadow, !scene.occluded(&shadow.ray));
        }
        let Some(next) = self.scatter(settings, strategy, sampler, u) else {
            return false;
        };
        *rays += 1;
        let hit = next.trace(scene, settings);
        self.arrive(scene, strategy, &next, hit)
    }

    /// Starts a bounce: counts the vertex and samples its next-event estimate. `None` if the
    /// path may not scatter here; otherwise the vertex's numbers and the shadow ray to trace
    /// with the light it brings (which [`Self::add_light`] adds if the ray is unoccluded).
    #[inline(always)]
    pub fn light<S: Sampler>(
        &mut self,
        scene: &SceneView<'_>,
        settings: &PathSettings,
        strategy: &PathStrategy,
        sampler: &mut S,
    ) -> Option<(dims::BounceDims, Option<ShadowQuery>)> {
        // `si` is scattering vertex number `bounces`; light reaching it directly completes a
        // path with `bounces` scattering vertices.
        self.bounces += 1;
        if !settings.allows(self.bounces) {
            return None;
        }
        let si = &self.si;
        let bsdf = &self.bsdf;
        let next_event =
            strategy.direct != DirectLighting::BsdfSampling && bsdf.flags().is_non_specular();
        // This vertex's numbers, each drawn only if it is used (the same numbers as drawing
        // them all: `dims::BounceDims`).
        let u = dims::BounceDims::start(sampler);
        if !next_event {
            return Some((u, None));
        }
        let mis = strategy.direct == DirectLighting::Mis;
        let (u_select, u_light) = u.light(sampler);
        let view = bsdf.seen_from(si.wo);
        let shadow = sample_direct_unoccluded(scene, si, &view, u_select, u_light, mis)
            .map(|(sample, ray)| ShadowQuery { ray, sample, mis });
        Some((u, shadow))
    }

    /// Adds the light of `shadow` if its ray is `unoccluded` (weighted only then: many of a
    /// closed scene's shadow rays are blocked).
    #[inline(always)]
    pub fn add_light(&mut self, shadow: &ShadowQuery, unoccluded: bool) {
        if unoccluded {
            let d = &shadow.sample;
            let w = if shadow.mis {
                power_heuristic(d.pdf, d.pdf_bsdf)
            } else {
                1.0
            };
            self.l += self.beta * d.contribution * w;
        }
    }

    /// Samples the direction the path leaves the vertex in and plays roulette: the ray to
    /// trace next, or `None` if the path ends here.
    #[inline(always)]
    pub fn scatter<S: Sampler>(
        &mut self,
        settings: &PathSettings,
        strategy: &PathStrategy,
        sampler: &mut S,
        u: dims::BounceDims,
    ) -> Option<NextRay> {
        let bounces = self.bounces;
        let si = &self.si;
        let bsdf = &self.bsdf;
        let flags = bsdf.flags();
        // The ray leaving the last vertex of a bounded path matters only for the emission it
        // may find, which next-event estimation has counted unless the bounce is a delta one.
        let terminal = settings.is_terminal(bounces);
        if terminal
            && strategy.direct == DirectLighting::NextEvent
            && !flags.contains(BsdfFlags::SPECULAR)
        {
            return None;
        }
        let lobe = if bsdf.uses_lobe_choice() {
            u.lobe(sampler)
        } else {
            0.0
        };
        let view = bsdf.seen_from(si.wo);
        let s = view.sample(lobe, u.direction(sampler), TransportMode::Radiance)?;
        // Emission found by the sampled ray counts unless next-event estimation has it.
        let counts_emission = strategy.direct != DirectLighting::NextEvent || s.flags.is_specular();
        if terminal && !counts_emission {
            return None;
        }
        self.beta *= s.weight;
        if s.flags.is_transmission() {
            self.eta_scale *= s.eta * s.eta;
        }
        let u_roulette = if settings.roulette_applies(strategy.roulette, bounces) {
            u.roulette(sampler)
        } else {
            0.0
        };
        let survives = match strategy.roulette {
            Roulette::Fixed => settings.survives_roulette(bounces, u_roulette, &mut self.beta),
            Roulette::Adaptive => settings.survives_adaptive_roulette(
                bounces,
                u_roulette,
                self.eta_scale,
                &mut self.beta,
            ),
        };
        if !survives {
            return None;
        }
        u.finish(sampler);
        Some(NextRay {
            ray: si.spawn_ray(s.wi),
            terminal,
            counts_emission,
            specular: s.flags.is_specular(),
            pdf: s.pdf,
        })
    }

    /// Ends the bounce where the ray `next` landed (`hit`, from [`NextRay::trace`]): counts the
    /// emission found there and moves the path to the new vertex. Returns whether the path
    /// goes on.
    #[inline(always)]
    pub fn arrive(
        &mut self,
        scene: &SceneView<'_>,
        strategy: &PathStrategy,
        next: &NextRay,
        hit: Option<Hit>,
    ) -> bool {
        let Some(hit) = hit else {
            return false;
        };
        self.arrive_at(scene, strategy, next, scene.interaction(&next.ray, &hit))
    }

    /// [`Self::arrive`] given the interaction `si` where `next` landed (for a driver that
    /// computes the interactions of many paths together).
    #[inline(always)]
    pub fn arrive_at(
        &mut self,
        scene: &SceneView<'_>,
        strategy: &PathStrategy,
        next: &NextRay,
        si: SurfaceInteraction,
    ) -> bool {
        let prev_p = self.si.p;
        self.si = si;
        let si = &self.si;
        if let Some((le, w)) = next.emission_found(scene, strategy, prev_p, si) {
            self.l += self.beta * le * w;
        }
        if next.terminal {
            return false;
        }
        self.bsdf = scene.bsdf_at(si);
        true
    }
}

/// A vertex's next-event shadow ray and the emitter sample it tests, which adds to the path's
/// radiance if the ray is unoccluded ([`PathState::add_light`]).
#[derive(Clone, Copy, Debug)]
pub struct ShadowQuery {
    pub ray: Ray,
    pub sample: DirectSample,
    /// Weighted against BSDF sampling (MIS).
    pub mis: bool,
}

/// The ray a path leaves a vertex along, with what [`PathState::arrive`] needs of its sample.
#[derive(Clone, Copy, Debug)]
pub struct NextRay {
    pub ray: Ray,
    /// The last ray of a bounded path (only emission it finds matters).
    pub terminal: bool,
    /// Whether emission it finds counts (next-event estimation has not counted it).
    pub counts_emission: bool,
    /// Sampled from a delta lobe.
    pub specular: bool,
    /// Solid-angle density of its direction.
    pub pdf: SolidAnglePdf,
}

impl NextRay {
    /// The emission this ray, leaving `prev_p`, finds where it lands at `si`, and its weight:
    /// `(Le, w)`, which adds `β·Le·w` to the path's radiance; `None` where it finds none or
    /// where next-event estimation counts it.
    #[inline(always)]
    #[must_use]
    pub fn emission_found(
        &self,
        scene: &SceneView<'_>,
        strategy: &PathStrategy,
        prev_p: Vec3,
        si: &SurfaceInteraction,
    ) -> Option<(Rgb, f32)> {
        if !self.counts_emission {
            return None;
        }
        let le = scene.emitted(si);
        if le == Rgb::ZERO {
            return None;
        }
        // A delta bounce has no next-event estimate to share the light with.
        let w = if strategy.direct == DirectLighting::Mis && !self.specular {
            let dist2 = (si.p - prev_p).length_squared();
            let cos_light = si.frame.n.dot(-self.ray.d);
            let pdf_light = emitter_pdf(scene, si.triangle).to_solid_angle(dist2, cos_light);
            power_heuristic(self.pdf, pdf_light)
        } else {
            1.0
        };
        Some((le, w))
    }

    /// Traces the ray: its closest hit, or for a terminal ray only a hit on an emitter.
    #[inline(always)]
    #[must_use]
    pub fn trace(&self, scene: &SceneView<'_>, settings: &PathSettings) -> Option<Hit> {
        let mut hit = None;
        self.trace_by(
            scene,
            settings,
            |ray, hit| *hit = scene.intersect(ray),
            &mut hit,
        );
        hit
    }

    /// [`Self::trace`] with the closest-hit query `intersect`, which writes its answer to the
    /// place it is given (the batched path tracer's, [`SceneView::intersect_with`]), into
    /// `hit`.
    #[inline(always)]
    pub fn trace_by(
        &self,
        scene: &SceneView<'_>,
        settings: &PathSettings,
        intersect: impl FnOnce(&Ray, &mut Option<Hit>),
        hit: &mut Option<Hit>,
    ) {
        if self.terminal {
            settings.terminal_hit_by(scene, &self.ray, intersect, hit);
        } else {
            intersect(&self.ray, hit);
        }
    }
}
