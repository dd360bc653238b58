//! Bidirectional path tracing (Veach 1997, ch. 10; the structure of pbrt-v4's
//! `BDPTIntegrator`): a camera subpath and a light subpath in fixed-size vertex arrays the
//! caller provides ([`BdptScratch`]), every connection strategy `(s, t)` between them —
//! `s = 0` (the camera path hits an emitter), `s = 1` (next-event estimation), `t = 1` (light
//! tracing, splatted) and the general connections — each weighted by multiple importance
//! sampling over all the strategies that could have made the same path.
//!
//! - **Densities are area densities.** Every vertex stores `pdf_fwd` (of being sampled from
//!   its predecessor on its own subpath) and `pdf_rev` (from its successor, i.e. by the other
//!   subpath's walk), both per unit area at the vertex ([`convert_density`]).
//! - **MIS** uses pbrt-v4's recursive ratios (`MISWeight`): for the strategy `(s, t)`,
//!   `w = 1 / (1 + Σ r_i^β)` where `r_i` are products of `pdf_rev / pdf_fwd` along each
//!   subpath, with the connection's four reverse densities and the sampled endpoint replaced
//!   for the strategy; zero densities (delta lobes) count as 1 and strategies that would
//!   connect at a delta vertex are skipped. Balance (β = 1) or power (β = 2) heuristic.
//! - **Delta lobes** (mirrors, smooth glass) are never connected; their vertices carry
//!   `delta` and zero densities.
//! - **Shading normals**: light-subpath BSDFs are evaluated in importance transport through
//!   [`crate::bsdf::SurfaceBsdf`], which applies Veach's adjoint correction (pbrt-v4 omits it:
//!   its issues #385, #526). Connection cosines use shading normals, densities geometric ones.
//! - **Depth**: `max_depth` counts scattering vertices between camera and emitter, as
//!   TinyRender's: strategy `(s, t)` makes a path with `s + t − 2` of them. At most
//!   [`BDPT_MAX_DEPTH`]; `−1` is unbounded, truncated at that cap. Russian roulette is
//!   played on both subpaths at any depth limit ([`PathSettings::roulette_applies`]),
//!   throughput-adaptive as the MIS path tracer's, on each subpath's throughput relative to
//!   its start (a light subpath starts at `Le/p`): from `rr_depth` vertices on, survival
//!   `min(max(β/β₀)·η_scale, rr_prob)`.
//! - **Roulette and MIS.** The survival probabilities are not part of the densities the MIS
//!   weights use (the other subpath's walk would have its own); weights that sum to one over
//!   the strategies of a path keep the estimate unbiased whatever densities they come from.

use super::light_tracer::ray_to_camera;
use super::{dims, PathSettings};
use crate::bsdf::{Bsdf, Diffuse, SurfaceBsdf, TransportMode};
use crate::camera::Camera;
use crate::emitter::{emitter_pdf, pdf_le_direction, sample_emitter, sample_le};
use crate::geometry::{spawn_connection, spawn_ray, spawn_ray_to, Ray};
use crate::math::Frame;
use crate::sampler::Sampler;
use crate::scene::SceneView;
use crate::splat::SplatSink;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// The deepest paths BDPT renders: scattering vertices between camera and emitter. Larger
/// `max_depth` values are refused by hosts ([`check_depth`]).
pub const BDPT_MAX_DEPTH: u32 = 64;
/// Vertices of a camera subpath: the camera, then up to `BDPT_MAX_DEPTH + 1` surface points
/// (the last one may be an emitter, strategy `s = 0`).
pub const CAMERA_PATH_VERTICES: usize = BDPT_MAX_DEPTH as usize + 2;
/// Vertices of a light subpath: the point on the emitter and up to `BDPT_MAX_DEPTH` more.
pub const LIGHT_PATH_VERTICES: usize = BDPT_MAX_DEPTH as usize + 1;

/// Why a BDPT depth is not rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DepthTooLarge {
    pub max_depth: i32,
}

impl core::fmt::Display for DepthTooLarge {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "maxDepth = {} is deeper than bidirectional path tracing supports ({}; its subpaths \
             live in fixed-size arrays); use -1 (unbounded with Russian roulette, truncated \
             there) or at most {}",
            self.max_depth, BDPT_MAX_DEPTH, BDPT_MAX_DEPTH
        )
    }
}

/// Whether BDPT renders `max_depth` (−1 or at most [`BDPT_MAX_DEPTH`]).
///
/// # Errors
/// For deeper bounded depths.
pub fn check_depth(max_depth: i32) -> Result<(), DepthTooLarge> {
    if max_depth <= BDPT_MAX_DEPTH as i32 {
        Ok(())
    } else {
        Err(DepthTooLarge { max_depth })
    }
}

/// The MIS heuristic combining the strategies.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MisHeuristic {
    /// Weights proportional to the densities (pbrt-v4's BDPT).
    Balance,
    /// Weights proportional to the squared densities (Veach's recommendation; the default).
    #[default]
    Power,
}

impl MisHeuristic {
    #[inline]
    fn apply(self, r: f32) -> f32 {
        match self {
            Self::Balance => r,
            Self::Power => r * r,
        }
    }
}

/// What a vertex is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VertexKind {
    /// The pinhole.
    Camera,
    /// The point a light subpath starts from, on an emitter.
    Light,
    /// A scattering point (possibly on an emitter, for `s = 0`).
    #[default]
    Surface,
}

/// One vertex of a subpath.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    pub kind: VertexKind,
    /// The point, and where rays leave it (see `SurfaceInteraction::p_spawn`).
    pub p: Vec3,
    pub p_spawn: Vec3,
    pub p_err: Vec3,
    /// The BSDF at a surface vertex with its shading frame and geometric normal; for the
    /// camera and light vertices only the frame (the camera's forward axis, the emitter's
    /// shading normal) and the geometric normal are used.
    pub bsdf: SurfaceBsdf,
    /// Unit direction toward the previous vertex of its subpath (surface vertices).
    pub wo: Vec3,
    /// Throughput of the subpath up to and including this vertex's sampling density.
    pub beta: Rgb,
    /// Area density of this vertex, sampled from its predecessor on its subpath.
    pub pdf_fwd: f32,
    /// Area density of this vertex as the other subpath's walk would sample it.
    pub pdf_rev: f32,
    /// Scattered by a delta lobe (never connected).
    pub delta: bool,
    /// The emitter triangle (light vertices, and surface vertices on emitters).
    pub triangle: u32,
    /// Radiance emitted toward `wo` (surface vertices), or the emitter's `Ke` (light).
    pub le: Rgb,
    /// Camera subpath: the numbers of this vertex's `s = 1` connection.
    pub u_select: f32,
    pub u_light: Vec2,
}

impl Default for Vertex {
    fn default() -> Self {
        Self {
            kind: VertexKind::Surface,
            p: Vec3::ZERO,
            p_spawn: Vec3::ZERO,
            p_err: Vec3::ZERO,
            bsdf: SurfaceBsdf::new(
                Bsdf::Diffuse(Diffuse::new(Rgb::ZERO)),
                Frame::from_normal(Vec3::Z),
                Vec3::Z,
            ),
            wo: Vec3::Z,
            beta: Rgb::ZERO,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            delta: false,
            triangle: u32::MAX,
            le: Rgb::ZERO,
            u_select: 0.0,
            u_light: Vec2::ZERO,
        }
    }
}

impl Vertex {
    /// The geometric normal.
    #[inline]
    #[must_use]
    pub fn ng(&self) -> Vec3 {
        self.bsdf.ng
    }

    /// The shading normal.
    #[inline]
    #[must_use]
    pub fn ns(&self) -> Vec3 {
        self.bsdf.frame.n
    }

    /// On a surface (with a normal for cosines): every vertex but the pinhole.
    #[inline]
    #[must_use]
    pub fn is_on_surface(&self) -> bool {
        self.kind != VertexKind::Camera
    }

    /// Whether a connection may end here: the camera and emitter points always, a surface
    /// point when its BSDF has a non-delta lobe.
    #[inline]
    #[must_use]
    pub fn is_connectible(&self) -> bool {
        match self.kind {
            VertexKind::Camera | VertexKind::Light => true,
            VertexKind::Surface => self.bsdf.flags().is_non_specular(),
        }
    }

    /// The BSDF value for scattering from `wo` toward `next` (surface vertices).
    #[inline]
    fn f(&self, next: &Vertex, mode: TransportMode) -> Rgb {
        let w = next.p - self.p;
        let d2 = w.length_squared();
        if d2 == 0.0 || d2.is_nan() {
            return Rgb::ZERO;
        }
        self.bsdf.eval(self.wo, w / crate::math::sqrt(d2), mode)
    }
}

/// Converts the solid-angle density `pdf` of a direction leaving `from` toward `to` into a
/// density per unit area at `to`: `pdf · |cos θ_to| / d²` (no cosine at the pinhole).
#[inline]
#[must_use]
pub fn convert_density(pdf: f32, from: &Vertex, to: &Vertex) -> f32 {
    let w = to.p - from.p;
    let d2 = w.length_squared();
    if d2 == 0.0 || d2.is_nan() {
        return 0.0;
    }
    let inv_d2 = 1.0 / d2;
    let mut pdf = pdf;
    if to.is_on_surface() {
        pdf *= to.ng().dot(w * crate::math::sqrt(inv_d2)).abs();
    }
    pdf * inv_d2
}

/// Area density at `next` of the direction `v` would sample toward it, having been reached
/// from `prev` (pbrt's `Vertex::PDF`): the camera's direction density, the emitter's
/// emission density, or the BSDF's.
#[must_use]
pub fn vertex_pdf(camera: &Camera, v: &Vertex, prev: Option<&Vertex>, next: &Vertex) -> f32 {
    if v.kind == VertexKind::Light {
        return pdf_light(v, next);
    }
    let wn = next.p - v.p;
    if wn.length_squared() == 0.0 {
        return 0.0;
    }
    let wn = wn.normalize();
    let pdf = match v.kind {
        VertexKind::Camera => camera.pdf_we(wn).1 .0,
        _ => {
            let Some(prev) = prev else {
                return 0.0;
            };
            let wp = prev.p - v.p;
            if wp.length_squared() == 0.0 {
                return 0.0;
            }
            v.bsdf.pdf(wp.normalize(), wn, TransportMode::Radiance).0
        }
    };
    convert_density(pdf, v, next)
}

/// Area density at `next` of the emission from the emitter point `v` toward it
/// (cosine-weighted about `v`'s shading normal; pbrt's `PDFLight`).
#[must_use]
pub fn pdf_light(v: &Vertex, next: &Vertex) -> f32 {
    let w = next.p - v.p;
    if w.length_squared() == 0.0 {
        return 0.0;
    }
    let pdf = pdf_le_direction(v.ns(), w.normalize()).0;
    convert_density(pdf, v, next)
}

/// Area density of choosing `v` as the start of a light subpath (pbrt's `PDFLightOrigin`):
/// the emitter table's density for its triangle.
#[must_use]
pub fn pdf_light_origin(scene: &SceneView<'_>, v: &Vertex) -> f32 {
    emitter_pdf(scene, v.triangle).0
}

/// The fixed-size subpaths of one BDPT sample, provided by the caller and reused from sample
/// to sample (131 vertices of 188 bytes, about 24 KiB: hosts keep one per worker thread).
#[derive(Clone, Debug)]
pub struct BdptScratch {
    pub camera: [Vertex; CAMERA_PATH_VERTICES],
    pub light: [Vertex; LIGHT_PATH_VERTICES],
}

impl Default for BdptScratch {
    fn default() -> Self {
        Self {
            camera: [Vertex::default(); CAMERA_PATH_VERTICES],
            light: [Vertex::default(); LIGHT_PATH_VERTICES],
        }
    }
}

/// Receives what a BDPT sample produces besides the radiance of its own pixel: the `t = 1`
/// splats, and for debugging each strategy's unweighted contribution and weight.
pub trait BdptSink: SplatSink {
    /// Strategy `(s, t)` contributed `unweighted` (before its MIS `weight`) at `raster`.
    #[inline]
    fn strategy(&mut self, _s: u32, _t: u32, _raster: Vec2, _unweighted: Rgb, _weight: f32) {}
}

impl BdptSink for crate::splat::NoSplats {}
impl BdptSink for crate::splat::SplatBuffer<'_> {}

/// Walks a subpath from `ray`, filling `path[start..]` (`path[start - 1]` is its origin,
/// already set), `beta` the throughput carried along `ray`. Returns the number of vertices in
/// `path` afterwards.
///
/// The densities stored with the vertices are computed from the **vertex positions**
/// ([`vertex_pdf`]), exactly as [`mis_weight`] recomputes the connection's: `pdf_fwd` of a new
/// vertex from its two predecessors, and `pdf_rev` of the vertex two back once the new one
/// exists (only then is the direction it was reached from known by position; `mis_weight` reads
/// a stored `pdf_rev` only for vertices with two successors). Not from the sampled directions:
/// a ray leaves its vertex from an offset spawn point, so the direction between two vertices
/// is not quite the sampled one, and far from the origin (offsets grow with the coordinates)
/// densities of sampled directions and of positions no longer agree: the weights of a path's
/// strategies then stopped summing to one (the white furnace translated by 1e5 rendered 8.8%
/// too dark, 1.1% at 1e4).
#[allow(clippy::too_many_arguments)]
fn random_walk<S: Sampler>(
    scene: &SceneView<'_>,
    camera: &Camera,
    mut ray: Ray,
    mut beta: Rgb,
    mode: TransportMode,
    settings: &PathSettings,
    sampler: &mut S,
    path: &mut [Vertex],
    start: usize,
    rays: &mut u32,
) -> usize {
    let mut n = start;
    // Roulette sees the throughput relative to the subpath's start and, in radiance transport,
    // without the 1/η′² of the dielectric crossings (pbrt's `etaScale`).
    let beta0 = beta.max_element();
    let mut eta_scale = 1.0f32;
    // Whether the last scattering was by a delta lobe (its densities are 0).
    let mut delta_step = false;
    while n < path.len() {
        *rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            break;
        };
        let si = scene.interaction(&ray, &hit);
        let bsdf = scene.bsdf_at(&si);
        let mut v = Vertex {
            kind: VertexKind::Surface,
            p: si.p,
            p_spawn: si.p_spawn,
            p_err: si.p_err,
            bsdf,
            wo: si.wo,
            beta,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            delta: false,
            triangle: si.triangle,
            le: scene.emitted(&si),
            u_select: 0.0,
            u_light: Vec2::ZERO,
        };
        if !delta_step {
            let (cur, prev) = (&path[n - 1], n.checked_sub(2).map(|i| &path[i]));
            v.pdf_fwd = vertex_pdf(camera, cur, prev, &v);
            if let Some(prev) = prev {
                path[n - 2].pdf_rev = vertex_pdf(camera, cur, Some(&v), prev);
            }
        }
        // The numbers of this vertex, in the subpath's layout.
        let (lobe, direction, roulette) = match mode {
            TransportMode::Radiance => {
                let u = dims::Bounce::draw(sampler);
                (v.u_select, v.u_light) = (u.light_select, u.light);
                (u.lobe, u.direction, u.roulette)
            }
            TransportMode::Importance => {
                let u = dims::LightBounce::draw(sampler);
                (u.lobe, u.direction, u.roulette)
            }
        };
        path[n] = v;
        n += 1;
        if n == path.len() {
            break;
        }
        let view = bsdf.seen_from(si.wo);
        let Some(s) = view.sample(lobe, direction, mode) else {
            break;
        };
        // A delta scattering has zero densities both ways (the next vertex's `pdf_fwd` and
        // this one's predecessor's `pdf_rev`).
        delta_step = s.flags.is_specular();
        if delta_step {
            path[n - 1].delta = true;
            path[n - 2].pdf_rev = 0.0;
        }
        beta *= s.weight;
        if mode == TransportMode::Radiance && s.flags.is_transmission() {
            eta_scale *= s.eta * s.eta;
        }
        // Vertex n − 1 is scattering vertex number n − 1 of this subpath.
        let scale = eta_scale / beta0;
        if !settings.survives_adaptive_roulette((n - 1) as u32, roulette, scale, &mut beta) {
            break;
        }
        ray = si.spawn_ray(s.wi);
    }
    n
}

/// Vertex capacity of a subpath for `max_depth` (`extra` more than the depth: 2 camera, 1
/// light).
fn capacity(settings: &PathSettings, extra: usize, array: usize) -> usize {
    if settings.max_depth < 0 {
        array
    } else {
        (settings.max_depth as usize + extra).min(array)
    }
}

/// Generates the camera subpath for `ray` into `path`; returns its vertex count.
fn camera_subpath<S: Sampler>(
    scene: &SceneView<'_>,
    camera: &Camera,
    ray: &Ray,
    settings: &PathSettings,
    sampler: &mut S,
    path: &mut [Vertex; CAMERA_PATH_VERTICES],
    rays: &mut u32,
) -> usize {
    let n = capacity(settings, 2, CAMERA_PATH_VERTICES);
    path[0] = Vertex {
        kind: VertexKind::Camera,
        p: camera.eye,
        p_spawn: camera.eye,
        p_err: Vec3::ZERO,
        bsdf: SurfaceBsdf::new(
            Bsdf::Diffuse(Diffuse::new(Rgb::ZERO)),
            Frame::from_normal(camera.forward),
            camera.forward,
        ),
        // The pinhole's We cosθ / (p_pos p_dir) is 1.
        beta: Rgb::ONE,
        ..Vertex::default()
    };
    random_walk(
        scene,
        camera,
        *ray,
        Rgb::ONE,
        TransportMode::Radiance,
        settings,
        sampler,
        &mut path[..n],
        1,
        rays,
    )
}

/// Generates a light subpath into `path`; returns its vertex count (0 without emitters). Its
/// numbers start at dimension [`dims::BDPT_LIGHT_SUBPATH`], whatever the camera subpath drew.
fn light_subpath<S: Sampler>(
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    sampler: &mut S,
    path: &mut [Vertex; LIGHT_PATH_VERTICES],
    rays: &mut u32,
) -> usize {
    let n = capacity(settings, 1, LIGHT_PATH_VERTICES);
    sampler.set_dimension(dims::BDPT_LIGHT_SUBPATH);
    let u = dims::LightStart::draw(sampler);
    let Some(e) = sample_le(scene, u.select, u.position, u.direction) else {
        return 0;
    };
    let pt = &e.point;
    path[0] = Vertex {
        kind: VertexKind::Light,
        p: pt.p,
        p_spawn: pt.p,
        p_err: pt.p_err,
        bsdf: SurfaceBsdf::new(
            Bsdf::Diffuse(Diffuse::new(Rgb::ZERO)),
            Frame::from_normal(pt.n),
            pt.ng,
        ),
        beta: pt.radiance,
        pdf_fwd: pt.pdf.0,
        triangle: pt.triangle,
        le: pt.radiance,
        ..Vertex::default()
    };
    if n <= 1 {
        return 1;
    }
    let beta = pt.radiance * (pt.n.dot(e.w).abs() / (pt.pdf.0 * e.pdf_dir.0));
    let ray = spawn_ray(pt.p, pt.p_err, pt.ng, e.w);
    random_walk(
        scene,
        camera,
        ray,
        beta,
        TransportMode::Importance,
        settings,
        sampler,
        &mut path[..n],
        1,
        rays,
    )
}

/// The geometry term `|cos θ₀||cos θ₁| / d²` between two surface vertices (shading normals)
/// times their mutual visibility.
fn geometry(scene: &SceneView<'_>, a: &Vertex, b: &Vertex, rays: &mut u32) -> f32 {
    let d = a.p - b.p;
    let d2 = d.length_squared();
    if d2 == 0.0 || d2.is_nan() {
        return 0.0;
    }
    let w = d / crate::math::sqrt(d2);
    let g = a.ns().dot(w).abs() * b.ns().dot(w).abs() / d2;
    if g == 0.0 {
        return 0.0;
    }
    *rays += 1;
    // `a.f(b)` and `b.f(a)` saw the connection as `b.p - a.p` and its negation.
    let shadow = spawn_connection(
        a.p_spawn,
        a.p_err,
        a.ng(),
        b.p_spawn,
        b.p_err,
        b.ng(),
        b.p - a.p,
    );
    if scene.occluded(&shadow) {
        0.0
    } else {
        g
    }
}

/// One strategy's result: the contribution before its weight, the weight, and where it lands
/// when it is a splat (`t = 1`).
struct Connection {
    l: Rgb,
    weight: f32,
    raster: Option<Vec2>,
}

/// Connects the first `s` light vertices and the first `t` camera vertices (pbrt's
/// `ConnectBDPT`).
fn connect(
    scene: &SceneView<'_>,
    camera: &Camera,
    light: &[Vertex],
    cam: &[Vertex],
    s: usize,
    t: usize,
    heuristic: MisHeuristic,
    rays: &mut u32,
) -> Option<Connection> {
    let mut sampled: Option<Vertex> = None;
    let mut raster = None;
    let l = if s == 0 {
        // The camera subpath ends on an emitter, seen from its front.
        let pt = &cam[t - 1];
        pt.beta * pt.le
    } else if t == 1 {
        let qs = &light[s - 1];
        if !qs.is_connectible() {
            return None;
        }
        let cs = camera.sample_wi(qs.p)?;
        let cam_vertex = Vertex {
            kind: VertexKind::Camera,
            p: camera.eye,
            p_spawn: camera.eye,
            bsdf: cam[0].bsdf,
            beta: Rgb::splat(cs.we / cs.pdf.0),
            ..Vertex::default()
        };
        let mut l = qs.beta * cam_vertex.beta;
        if qs.kind == VertexKind::Surface {
            l *= qs.f(&cam_vertex, TransportMode::Importance);
        } else if qs.ns().dot(cs.wi) <= 0.0 || qs.ng().dot(cs.wi) <= 0.0 {
            // An emitter point seen from behind emits nothing toward the camera.
            return None;
        }
        if qs.is_on_surface() {
            l *= qs.ns().dot(cs.wi).abs();
        }
        if l == Rgb::ZERO {
            return None;
        }
        *rays += 1;
        if scene.occluded(&ray_to_camera(qs.p_spawn, qs.p_err, qs.ng(), &cs)) {
            return None;
        }
        raster = Some(cs.raster);
        sampled = Some(cam_vertex);
        l
    } else if s == 1 {
        let pt = &cam[t - 1];
        if !pt.is_connectible() {
            return None;
        }
        let es = sample_emitter(scene, pt.u_select, pt.u_light)?;
        let mut light_vertex = Vertex {
            kind: VertexKind::Light,
            p: es.p,
            p_spawn: es.p,
            p_err: es.p_err,
            bsdf: SurfaceBsdf::new(
                Bsdf::Diffuse(Diffuse::new(Rgb::ZERO)),
                Frame::from_normal(es.n),
                es.ng,
            ),
            triangle: es.triangle,
            le: es.radiance,
            ..Vertex::default()
        };
        let to_pt = pt.p - es.p;
        let d2 = to_pt.length_squared();
        if d2 == 0.0 || d2.is_nan() {
            return None;
        }
        let w = to_pt / crate::math::sqrt(d2);
        let cos_light = es.n.dot(w);
        if cos_light <= 0.0 || es.ng.dot(w) <= 0.0 {
            return None;
        }
        // Le / p_ω at pt, with p_ω = p_A d² / cos θ_light.
        let pdf_w = es.pdf.to_solid_angle(d2, cos_light).0;
        light_vertex.beta = es.radiance / pdf_w;
        light_vertex.pdf_fwd = pdf_light_origin(scene, &light_vertex);
        let l = pt.beta
            * pt.f(&light_vertex, TransportMode::Radiance)
            * light_vertex.beta
            * pt.ns().dot(-w).abs();
        if l == Rgb::ZERO {
            return None;
        }
        *rays += 1;
        let shadow = spawn_ray_to(pt.p_spawn, pt.p_err, pt.ng(), es.p, es.p_err, es.ng);
        if scene.occluded(&shadow) {
            return None;
        }
        sampled = Some(light_vertex);
        l
    } else {
        let (qs, pt) = (&light[s - 1], &cam[t - 1]);
        if !qs.is_connectible() || !pt.is_connectible() {
            return None;
        }
        let l = qs.beta
            * qs.f(pt, TransportMode::Importance)
            * pt.f(qs, TransportMode::Radiance)
            * pt.beta;
        if l == Rgb::ZERO {
            return None;
        }
        let g = geometry(scene, qs, pt, rays);
        l * g
    };
    if l == Rgb::ZERO || !crate::math::is_finite(l) {
        return None;
    }
    let weight = mis_weight(scene, camera, light, cam, sampled.as_ref(), s, t, heuristic);
    Some(Connection { l, weight, raster })
}

/// The MIS weight of strategy `(s, t)` for the path it made (pbrt-v4's `MISWeight`, with
/// the heuristic's exponent): `sampled` is the endpoint a `t = 1` or `s = 1` strategy sampled
/// in place of `cam[0]` or `light[0]`.
#[must_use]
pub fn mis_weight(
    scene: &SceneView<'_>,
    camera: &Camera,
    light: &[Vertex],
    cam: &[Vertex],
    sampled: Option<&Vertex>,
    s: usize,
    t: usize,
    heuristic: MisHeuristic,
) -> f32 {
    if s + t == 2 {
        return 1.0;
    }
    // The strategy's vertices: the sampled endpoint replaces the subpath's first vertex.
    let light_at = |i: usize| -> &Vertex {
        match sampled {
            Some(v) if s == 1 && i == 0 => v,
            _ => &light[i],
        }
    };
    let cam_at = |i: usize| -> &Vertex {
        match sampled {
            Some(v) if t == 1 && i == 0 => v,
            _ => &cam[i],
        }
    };
    let qs = (s > 0).then(|| light_at(s - 1));
    let pt = (t > 0).then(|| cam_at(t - 1));
    let qs_minus = (s > 1).then(|| light_at(s - 2));
    let pt_minus = (t > 1).then(|| cam_at(t - 2));
    // The four reverse densities the connection changes.
    let pt_rev = pt.map(|pt| match qs {
        Some(qs) => vertex_pdf(camera, qs, qs_minus, pt),
        None => pdf_light_origin(scene, pt),
    });
    let pt_minus_rev = pt_minus.map(|ptm| match qs {
        Some(qs) => vertex_pdf(camera, pt.unwrap_or(ptm), Some(qs), ptm),
        None => pdf_light(pt.unwrap_or(ptm), ptm),
    });
    let qs_rev = qs.map(|qs| vertex_pdf(camera, pt.unwrap_or(qs), pt_minus, qs));
    let qs_minus_rev = qs_minus.map(|qsm| vertex_pdf(camera, qs.unwrap_or(qsm), pt, qsm));
    let remap0 = |f: f32| if f != 0.0 { f } else { 1.0 };
    // Camera side: vertices t − 1 down to 1 (the pinhole cannot be hit).
    let cam_rev = |i: usize| -> f32 {
        if i + 1 == t {
            pt_rev.unwrap_or(0.0)
        } else if i + 2 == t {
            pt_minus_rev.unwrap_or(0.0)
        } else {
            cam_at(i).pdf_rev
        }
    };
    // The connection's endpoints are connectible, so not delta for this strategy.
    let cam_delta = |i: usize| i + 1 != t && cam_at(i).delta;
    let mut sum = 0.0f32;
    let mut ri = 1.0f32;
    for i in (1..t).rev() {
        ri *= remap0(cam_rev(i)) / remap0(cam_at(i).pdf_fwd);
        if !cam_delta(i) && !cam_delta(i - 1) {
            sum += heuristic.apply(ri);
        }
    }
    let light_rev = |i: usize| -> f32 {
        if i + 1 == s {
            qs_rev.unwrap_or(0.0)
        } else if i + 2 == s {
            qs_minus_rev.unwrap_or(0.0)
        } else {
            light_at(i).pdf_rev
        }
    };
    let light_delta = |i: usize| i + 1 != s && light_at(i).delta;
    ri = 1.0;
    for i in (0..s).rev() {
        ri *= remap0(light_rev(i)) / remap0(light_at(i).pdf_fwd);
        // Area emitters are never delta lights.
        let delta_before = i > 0 && light_delta(i - 1);
        if !light_delta(i) && !delta_before {
            sum += heuristic.apply(ri);
        }
    }
    let w = 1.0 / (1.0 + sum);
    if w.is_finite() {
        w
    } else {
        0.0
    }
}

/// One BDPT sample for the camera ray `ray`: returns the MIS-weighted radiance of the
/// strategies with `t ≥ 2` (the sample's own pixel) and splats those with `t = 1` into
/// `sink`, which also sees every strategy's contribution and weight ([`BdptSink`]).
/// `raster` is the camera sample's film position (for the strategy images). Dimensions: the
/// camera sample, [`dims::Bounce`] per camera vertex (its emitter numbers serve the `s = 1`
/// connection there), then, from [`dims::BDPT_LIGHT_SUBPATH`] on, [`dims::LightStart`] and
/// [`dims::LightBounce`] per light vertex. Every ray traced adds 1 to `rays`.
#[allow(clippy::too_many_arguments)]
pub fn li_bdpt<S: Sampler, K: BdptSink>(
    scene: &SceneView<'_>,
    camera: &Camera,
    ray: &Ray,
    raster: Vec2,
    settings: &PathSettings,
    heuristic: MisHeuristic,
    scratch: &mut BdptScratch,
    sampler: &mut S,
    sink: &mut K,
    rays: &mut u32,
) -> Rgb {
    let n_cam = camera_subpath(
        scene,
        camera,
        ray,
        settings,
        sampler,
        &mut scratch.camera,
        rays,
    );
    let n_light = light_subpath(scene, camera, settings, sampler, &mut scratch.light, rays);
    let (cam, light) = (&scratch.camera[..n_cam], &scratch.light[..n_light]);
    let mut l = Rgb::ZERO;
    for t in 1..=n_cam {
        for s in 0..=n_light {
            let depth = s as i64 + t as i64 - 2;
            if (s == 1 && t == 1) || depth < 0 || !settings.allows(depth as u32) {
                continue;
            }
            let Some(c) = connect(scene, camera, light, cam, s, t, heuristic, rays) else {
                continue;
            };
            let at = c.raster.unwrap_or(raster);
            sink.strategy(s as u32, t as u32, at, c.l, c.weight);
            let weighted = c.l * c.weight;
            if t == 1 {
                sink.splat(at, weighted);
            } else {
                l += weighted;
            }
        }
    }
    l
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{self, Bvh, BvhNode};
    use crate::emitter::{build_emitter_table, EmitterPolicy};
    use crate::material::Material;
    use crate::sampler::IndependentSampler;
    use crate::texture::Textures;
    use std::vec;
    use std::vec::Vec;

    /// A closed box seen from inside with every kind of BSDF: diffuse, Phong and mixture walls,
    /// a mirror and a rough metal panel, a smooth and a rough glass slab, and a ceiling light.
    struct TestScene {
        positions: Vec<Vec3>,
        normals: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        materials_of: Vec<u32>,
        materials: Vec<Material>,
        nodes: Vec<BvhNode>,
        order: Vec<u32>,
        emitters: Vec<u32>,
        cdf: Vec<f32>,
    }

    impl TestScene {
        fn new() -> Self {
            let materials = vec![
                Material::diffuse(Rgb::splat(0.7)),
                Material::phong(Rgb::splat(0.2), Rgb::splat(0.6), 20.0),
                Material::mixture(Rgb::new(0.5, 0.3, 0.2), Rgb::splat(0.4), 50.0),
                Material::conductor(Rgb::splat(0.9), 0.0),
                Material::conductor(Rgb::splat(0.8), 0.2),
                Material::dielectric(1.5, Rgb::ONE, 0.0),
                Material::dielectric(1.5, Rgb::ONE, 0.3),
                Material::diffuse(Rgb::ZERO).with_emission(Rgb::splat(4.0)),
            ];
            let mut s = Self {
                positions: Vec::new(),
                normals: Vec::new(),
                triangles: Vec::new(),
                materials_of: Vec::new(),
                materials,
                nodes: Vec::new(),
                order: Vec::new(),
                emitters: Vec::new(),
                cdf: Vec::new(),
            };
            // Quads as (corner, edge u, edge v, material); the normal is u × v.
            let quads: [(Vec3, Vec3, Vec3, u32); 16] = [
                (Vec3::new(-1.0, -1.0, -1.0), Vec3::Z * 2.0, Vec3::X * 2.0, 1), // floor
                (Vec3::new(-1.0, 1.0, -1.0), Vec3::X * 2.0, Vec3::Z * 2.0, 0),  // ceiling
                (Vec3::new(-1.0, -1.0, -1.0), Vec3::X * 2.0, Vec3::Y * 2.0, 2), // back
                (Vec3::new(-1.0, -1.0, -1.0), Vec3::Y * 2.0, Vec3::Z * 2.0, 0), // left
                (Vec3::new(1.0, -1.0, -1.0), Vec3::Z * 2.0, Vec3::Y * 2.0, 0),  // right
                (Vec3::new(-1.0, -1.0, 1.0), Vec3::Y * 2.0, Vec3::X * 2.0, 0),  // front
                (Vec3::new(-0.3, 0.99, -0.3), Vec3::X * 0.6, Vec3::Z * 0.6, 7), // light
                (
                    Vec3::new(-0.98, -0.6, -0.6),
                    Vec3::Y * 1.0,
                    Vec3::Z * 1.0,
                    3,
                ), // mirror
                (Vec3::new(0.98, -0.6, -0.6), Vec3::Z * 1.0, Vec3::Y * 1.0, 4), // rough metal
                // A smooth glass slab (front and back faces, outward normals).
                (Vec3::new(-0.6, -0.8, 0.0), Vec3::X * 0.5, Vec3::Y * 0.8, 5),
                (Vec3::new(-0.6, -0.8, -0.2), Vec3::Y * 0.8, Vec3::X * 0.5, 5),
                // A rough glass slab.
                (Vec3::new(0.1, -0.8, -0.3), Vec3::X * 0.5, Vec3::Y * 0.8, 6),
                (Vec3::new(0.1, -0.8, -0.5), Vec3::Y * 0.8, Vec3::X * 0.5, 6),
                // Two more diffuse and glossy panels facing the camera.
                (Vec3::new(-0.9, 0.2, -0.9), Vec3::X * 0.4, Vec3::Y * 0.4, 1),
                (Vec3::new(0.5, 0.2, -0.9), Vec3::X * 0.4, Vec3::Y * 0.4, 2),
                (Vec3::new(-0.2, -0.9, -0.9), Vec3::X * 0.4, Vec3::Y * 0.3, 4),
            ];
            for (c, u, v, m) in quads {
                let n = u.cross(v).normalize();
                let base = s.positions.len() as u32;
                s.positions.extend([c, c + u, c + u + v, c + v]);
                s.normals.extend([n; 4]);
                s.triangles
                    .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
                s.materials_of.extend([m, m]);
            }
            s.nodes = vec![BvhNode::default(); bvh::max_nodes(s.triangles.len())];
            s.order = vec![0; s.triangles.len()];
            let used = bvh::build_triangles(&s.positions, &s.triangles, &mut s.nodes, &mut s.order)
                .unwrap();
            s.nodes.truncate(used);
            s.emitters = vec![0; 2];
            s.cdf = vec![0.0; 2];
            let emission = |m: u32| s.materials[m as usize].emission;
            let n = build_emitter_table(
                &s.positions,
                &s.triangles,
                &s.materials_of,
                emission,
                EmitterPolicy::Area,
                &mut s.emitters,
                &mut s.cdf,
            )
            .unwrap();
            assert_eq!(n, 2);
            s
        }

        fn view(&self) -> SceneView<'_> {
            SceneView {
                positions: &self.positions,
                normals: &self.normals,
                triangles: &self.triangles,
                triangle_materials: &self.materials_of,
                materials: &self.materials,
                emitter_triangles: &self.emitters,
                emitter_cdf: &self.cdf,
                bvh: Bvh {
                    nodes: &self.nodes,
                    prim_order: &self.order,
                }
                .into(),
                textures: Textures::NONE,
            }
        }
    }

    /// Solid-angle density of `v` (a surface) scattering from `from` toward `to`, with a delta
    /// lobe counted as the discrete probability 1 (the same for every strategy that samples
    /// through it, so it cancels in the weights).
    fn scatter_pdf(v: &Vertex, from: &Vertex, to: &Vertex) -> f32 {
        if v.delta {
            return 1.0;
        }
        let (wp, wn) = ((from.p - v.p).normalize(), (to.p - v.p).normalize());
        v.bsdf.pdf(wp, wn, TransportMode::Radiance).0
    }

    /// Area density at `to` of `pdf` (solid angle at `from`), or the discrete 1 of a delta.
    fn to_area(pdf: f32, from: &Vertex, to: &Vertex, delta: bool) -> f32 {
        if delta {
            1.0
        } else {
            convert_density(pdf, from, to)
        }
    }

    /// Brute force: for the full path `x[0]` (camera) … `x[k]` (on the light), the density of
    /// each strategy `s` (light vertices) computed from scratch as a product along both
    /// subpaths, the set of strategies that can make the path, and their MIS weights.
    fn brute_force_weights(
        scene: &SceneView<'_>,
        camera: &Camera,
        x: &[Vertex],
        heuristic: MisHeuristic,
    ) -> Vec<Option<f32>> {
        let k = x.len() - 1;
        // The light-side vertex at x[k] (the emitter point).
        let light_end = light_vertex_of(&x[k]);
        let cam_pdf = |i: usize| -> f32 {
            if i == 1 {
                let d = (x[1].p - x[0].p).normalize();
                convert_density(camera.pdf_we(d).1 .0, &x[0], &x[1])
            } else {
                let delta = x[i - 1].delta;
                to_area(
                    scatter_pdf(&x[i - 1], &x[i - 2], &x[i]),
                    &x[i - 1],
                    &x[i],
                    delta,
                )
            }
        };
        let light_pdf = |j: usize| -> f32 {
            if j == k {
                pdf_light_origin(scene, &light_end)
            } else if j + 1 == k {
                pdf_light(&light_end, &x[j])
            } else {
                let delta = x[j + 1].delta;
                to_area(
                    scatter_pdf(&x[j + 1], &x[j + 2], &x[j]),
                    &x[j + 1],
                    &x[j],
                    delta,
                )
            }
        };
        let p: Vec<Option<f64>> = (0..=k + 1)
            .map(|s| {
                let t = k + 1 - s;
                // A connection joins x[t − 1] (the camera, or a surface) and x[t] (a surface,
                // or the light point itself when t = k): neither may scatter by a delta lobe.
                let connectible =
                    || s == 0 || ((t == 1 || !x[t - 1].delta) && (t == k || !x[t].delta));
                let valid = t >= 1 && !(s == 1 && t == 1) && connectible();
                if !valid {
                    return None;
                }
                let mut p = 1.0f64;
                for i in 1..t {
                    p *= f64::from(cam_pdf(i));
                }
                for j in (k + 1 - s)..=k {
                    p *= f64::from(light_pdf(j));
                }
                Some(p)
            })
            .collect();
        let beta = |v: f64| match heuristic {
            MisHeuristic::Balance => v,
            MisHeuristic::Power => v * v,
        };
        let total: f64 = p.iter().flatten().map(|&v| beta(v)).sum();
        p.iter()
            .map(|v| v.map(|v| (beta(v) / total) as f32))
            .collect()
    }

    /// `v` (a surface point on an emitter) as the first vertex of a light subpath.
    fn light_vertex_of(v: &Vertex) -> Vertex {
        Vertex {
            kind: VertexKind::Light,
            delta: false,
            ..*v
        }
    }

    /// The subpaths strategy `s` splits the full path `x` into, with the densities and delta
    /// flags the random walks would have stored (delta scatters store 0).
    fn split(
        scene: &SceneView<'_>,
        camera: &Camera,
        x: &[Vertex],
        s: usize,
    ) -> (Vec<Vertex>, Vec<Vertex>) {
        let k = x.len() - 1;
        let t = k + 1 - s;
        let fwd_cam = |i: usize| -> f32 {
            if i == 0 {
                return 0.0;
            }
            if i == 1 {
                let d = (x[1].p - x[0].p).normalize();
                return convert_density(camera.pdf_we(d).1 .0, &x[0], &x[1]);
            }
            if x[i - 1].delta {
                0.0
            } else {
                convert_density(scatter_pdf(&x[i - 1], &x[i - 2], &x[i]), &x[i - 1], &x[i])
            }
        };
        let light_end = light_vertex_of(&x[k]);
        let fwd_light = |j: usize| -> f32 {
            if j == k {
                pdf_light_origin(scene, &light_end)
            } else if j + 1 == k {
                pdf_light(&light_end, &x[j])
            } else if x[j + 1].delta {
                0.0
            } else {
                convert_density(scatter_pdf(&x[j + 1], &x[j + 2], &x[j]), &x[j + 1], &x[j])
            }
        };
        let cam: Vec<Vertex> = (0..t)
            .map(|i| Vertex {
                pdf_fwd: fwd_cam(i),
                pdf_rev: if i < k { fwd_light(i) } else { 0.0 },
                ..x[i]
            })
            .collect();
        let light: Vec<Vertex> = (0..s)
            .map(|j| {
                let i = k - j;
                let v = if j == 0 { light_end } else { x[i] };
                Vertex {
                    pdf_fwd: fwd_light(i),
                    pdf_rev: fwd_cam(i),
                    ..v
                }
            })
            .collect();
        (light, cam)
    }

    /// For random full paths through every kind of BSDF (delta ones included), the kernel's
    /// MIS weights (pbrt's recursive ratios with the connection's reverse densities replaced)
    /// equal the weights computed from the strategies' path densities by brute force, and sum
    /// to 1 over the strategies that can make the path; for both heuristics.
    #[test]
    fn mis_weights_sum_to_one_and_match_brute_force() {
        let data = TestScene::new();
        let scene = data.view();
        scene.validate().unwrap();
        let camera = Camera::look_at(
            Vec3::new(0.0, 0.0, 0.9),
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::Y,
            70.0,
            64,
            64,
        );
        let settings = PathSettings {
            max_depth: 12,
            ..PathSettings::default()
        };
        let mut path = [Vertex::default(); CAMERA_PATH_VERTICES];
        let (mut tested, mut with_delta, mut longest) = (0, 0, 0);
        for i in 0..20_000u32 {
            let mut sampler = IndependentSampler::new(5, u64::from(i), 0);
            let u = Vec2::new(sampler.next_1d(), sampler.next_1d());
            let ray = camera.generate_ray(i % 64, (i / 64) % 64, u);
            let n = camera_subpath(
                &scene,
                &camera,
                &ray,
                &settings,
                &mut sampler,
                &mut path,
                &mut 0,
            );
            if n < 3 || path[n - 1].le == Rgb::ZERO {
                continue;
            }
            let x = &path[..n];
            tested += 1;
            longest = longest.max(n);
            if x.iter().any(|v| v.delta) {
                with_delta += 1;
            }
            for heuristic in [MisHeuristic::Balance, MisHeuristic::Power] {
                let expected = brute_force_weights(&scene, &camera, x, heuristic);
                let mut sum = 0.0f64;
                for (s, e) in expected.iter().enumerate() {
                    let Some(e) = *e else { continue };
                    let t = n - s;
                    let (light, cam) = split(&scene, &camera, x, s);
                    let sampled = match (s, t) {
                        (1, _) => Some(&light[0]),
                        (_, 1) => Some(&cam[0]),
                        _ => None,
                    };
                    let w = mis_weight(&scene, &camera, &light, &cam, sampled, s, t, heuristic);
                    assert!(
                        (w - e).abs() <= 2e-4 * e.max(1e-3),
                        "path {i} ({n} vertices), (s, t) = ({s}, {t}), {heuristic:?}: kernel {w}, brute force {e}"
                    );
                    sum += f64::from(w);
                }
                assert!((sum - 1.0).abs() < 1e-4, "path {i}: weights sum to {sum}");
            }
        }
        std::println!("{tested} paths up to {longest} vertices, {with_delta} through delta lobes");
        assert!(
            tested > 300 && with_delta > 30,
            "{tested} paths, {with_delta} with delta"
        );
    }
}
