//! The path state of a batch of eight paths stored lane by lane ([`PathLanes`]), and the
//! stages of a bounce that run in SIMD lanes on it: next-event estimation and BSDF sampling
//! at diffuse vertices under multiple importance sampling ([`next_event_diffuse`],
//! [`scatter_diffuse`]), the whole bounce of the benchmark scenes. A lane at any other vertex
//! runs the one-path loop's own stages on a [`PathState`] taken out of the lanes and put back
//! ([`PathLanes::path`], [`PathLanes::put`]).
//!
//! Exactness: each lane performs the scalar code's operations in its order
//! ([`PathState::light`] with [`super::direct::sample_direct_unoccluded`], and
//! [`PathState::scatter`] with `BsdfView::sample` and `Diffuse::sample`), each the correctly
//! rounded IEEE operation, comparisons written so that NaNs fall on the side the scalar code's
//! fall, glam's `Vec3` methods as glam writes them ([`V3`]). What has no lane instruction runs
//! lane by lane in the scalar code's own functions: the search of an emitter CDF of more than
//! 16 entries and the gather of the emitter's triangle where there are more than eight
//! (`crate::emitter::EmitterTable`), the sine and cosine of angles past 9π/4, and the one-ulp
//! steps of the ray origins. tests/tests/batched.rs compares whole renders with the one-path
//! loop's bit for bit.

use super::path::{PathState, Roulette};
use super::PathSettings;
use crate::bsdf::{Bsdf, SurfaceBsdf};
use crate::emitter::{sample_emitter_lanes, sample_emitter_table, EmitterTable};
use crate::math::{sin_cos_lanes, INV_PI};
use crate::scene::SceneView;
use crate::simd::{Isa, Lanes};
use crate::surface_lanes::SurfaceLanes;
use crate::vec_lanes::{max_zero, min_num, Soa3, N, V3};
use crate::Rgb;
use core::f32::consts::{FRAC_PI_2, FRAC_PI_4};

/// Eight paths between bounces, stored by field: what [`PathState`] holds, a lane each.
#[derive(Clone, Copy, Debug)]
pub(super) struct PathLanes {
    /// Radiance gathered so far.
    pub l: Soa3,
    /// Throughput up to the vertex in `si`.
    pub beta: Soa3,
    pub eta_scale: [f32; N],
    /// The vertex each path scatters from next, and its BSDF.
    pub si: SurfaceLanes,
    pub bsdf: [Bsdf; N],
    /// The lanes whose BSDF is [`Bsdf::Diffuse`] or a Phong BSDF that is Lambertian
    /// ([`crate::bsdf::Phong::is_lambertian`]), and its reflectance there.
    pub diffuse: u32,
    pub kd: Soa3,
}

impl PathLanes {
    pub fn new() -> Self {
        Self {
            l: Soa3::default(),
            beta: Soa3::default(),
            eta_scale: [1.0; N],
            si: SurfaceLanes::default(),
            bsdf: [Bsdf::Diffuse(crate::bsdf::Diffuse::new(Rgb::ZERO)); N],
            diffuse: 0,
            kd: Soa3::default(),
        }
    }

    /// Starts lane `l`'s path at its vertex in `si` ([`PathState::new`]).
    #[inline(always)]
    pub fn start(&mut self, l: usize, bsdf: Bsdf) {
        self.l.set(l, Rgb::ZERO);
        self.beta.set(l, Rgb::ONE);
        self.eta_scale[l] = 1.0;
        self.set_bsdf(l, bsdf);
    }

    /// The BSDF at lane `l`'s vertex.
    #[inline(always)]
    pub fn set_bsdf(&mut self, l: usize, bsdf: Bsdf) {
        self.bsdf[l] = bsdf;
        // A Lambertian Phong's pdf differs from `Diffuse`'s only for a NaN direction, which
        // the side test (`sides_agree`) refuses before any BSDF sees it.
        let kd = match bsdf {
            Bsdf::Diffuse(d) => Some(d.kd),
            Bsdf::Phong(p) | Bsdf::Mixture(p) if p.is_lambertian() => Some(p.kd),
            _ => None,
        };
        self.diffuse &= !(1 << l);
        if let Some(kd) = kd {
            self.diffuse |= 1 << l;
            self.kd.set(l, kd);
        }
    }

    /// Lane `l`'s path as the one-path loop holds it, after `bounces` scattering vertices.
    #[inline(always)]
    pub fn path(&self, l: usize, bounces: u32) -> PathState {
        let si = self.si.get(l);
        PathState {
            l: self.l.get(l),
            beta: self.beta.get(l),
            eta_scale: self.eta_scale[l],
            bounces,
            bsdf: SurfaceBsdf::new(self.bsdf[l], si.frame, si.ng),
            si,
        }
    }

    /// Puts back what a bounce's stages change of lane `l`'s path (its vertex changes only
    /// where the path arrives at the next one).
    #[inline(always)]
    pub fn put(&mut self, l: usize, path: &PathState) {
        self.l.set(l, path.l);
        self.beta.set(l, path.beta);
        self.eta_scale[l] = path.eta_scale;
    }
}

/// The shadow rays of eight next-event estimates and the light each brings, a lane each.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ShadowLanes {
    pub o: Soa3,
    pub d: Soa3,
    pub t_max: [f32; N],
    /// `f·|cosθᵢ|·Le / p_ω` ([`super::DirectSample::contribution`]).
    pub contribution: Soa3,
    /// The emitter sample's solid-angle density, and the BSDF's for its direction.
    pub pdf: [f32; N],
    pub pdf_bsdf: [f32; N],
}

/// The rays eight paths leave their vertices along, a lane each.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct RayLanes {
    pub o: Soa3,
    pub d: Soa3,
    /// The solid-angle density of the sampled direction.
    pub pdf: [f32; N],
}

/// What a stage at a diffuse vertex reads of it, loaded once for the stages of a bounce
/// ([`Self::load`]; the vertex does not change between them).
pub(super) struct Vertex<L> {
    p: V3<L>,
    p_spawn: V3<L>,
    p_err: V3<L>,
    ng: V3<L>,
    s: V3<L>,
    t: V3<L>,
    n: V3<L>,
    kd: V3<L>,
    /// `wo` in the shading frame and its cosine with `ng` ([`SurfaceBsdf::seen_from`]).
    wo_l: V3<L>,
    wo_ng: L,
    inv_pi: L,
}

impl<L: Lanes<N>> Vertex<L> {
    #[inline(always)]
    pub(super) fn load(isa: L::Isa, state: &PathLanes) -> Self {
        let si = &state.si;
        let (s, t, n) = (si.s.load(isa), si.t.load(isa), si.n.load(isa));
        let wo: V3<L> = si.wo.load(isa);
        let ng = si.ng.load(isa);
        Self {
            p: si.p.load(isa),
            p_spawn: si.p_spawn.load(isa),
            p_err: si.p_err.load(isa),
            ng,
            wo_l: to_local(wo, s, t, n),
            wo_ng: wo.dot(ng),
            s,
            t,
            n,
            kd: state.kd.load(isa),
            inv_pi: L::splat(isa, INV_PI),
        }
    }

    /// `BsdfView::sides_agree`: the shading frame and `ng` agree on the sides of `wo` and
    /// `wi` (false where a product is 0 or NaN).
    #[inline(always)]
    fn sides_agree(&self, wi_ng: L, wi_l_z: L, zero: L) -> L {
        ((self.wo_ng * wi_ng) * (self.wo_l.z * wi_l_z)).simd_gt(zero)
    }

    /// `Diffuse::eval`: `kd/π` unless `wo` or `wi` is below the surface (`<= 0`, so that a
    /// NaN cosine evaluates, as the scalar test lets it).
    #[inline(always)]
    fn diffuse_eval(&self, wi_l_z: L, zero: L) -> V3<L> {
        let below = self.wo_l.z.simd_le(zero) | wi_l_z.simd_le(zero);
        V3::select(below, V3::splat_lanes(zero), self.kd.scale(self.inv_pi))
    }
}

/// [`Frame::to_local`].
#[inline(always)]
fn to_local<L: Lanes<N>>(v: V3<L>, s: V3<L>, t: V3<L>, n: V3<L>) -> V3<L> {
    V3 {
        x: v.dot(s),
        y: v.dot(t),
        z: v.dot(n),
    }
}

/// `warp::cosine_hemisphere_pdf`: `cosθ/π` above the horizon, 0 elsewhere (and for NaN).
#[inline(always)]
fn cosine_pdf<L: Lanes<N>>(cos_theta: L, inv_pi: L, zero: L) -> L {
    L::select(cos_theta.simd_gt(zero), cos_theta * inv_pi, zero)
}

/// [`crate::geometry::offset_ray_origin`] lane by lane; the one-ulp steps away from `p` run in
/// the scalar functions.
#[inline(always)]
fn offset_ray_origin<L: Lanes<N>>(
    isa: L::Isa,
    p: V3<L>,
    p_err: V3<L>,
    n: V3<L>,
    w: V3<L>,
    zero: L,
) -> V3<L> {
    let d = n.abs().dot(p_err);
    let offset = n.scale(d);
    let offset = V3::select(w.dot(n).simd_lt(zero), offset.neg(), offset);
    let po = p.add(offset);
    V3 {
        x: po.x.round_away(isa, offset.x),
        y: po.y.round_away(isa, offset.y),
        z: po.z.round_away(isa, offset.z),
    }
}

/// Next-event estimation at the diffuse vertices of `lanes` under MIS, in lanes: what
/// [`PathState::light`] computes there, with the emitter numbers `u_select` and `u_light`,
/// the emitters from the scene's [`EmitterTable`] where it has one (`emitters`). Writes each
/// lane's shadow ray and the light it brings to `out`, and returns the lanes that have one
/// (bits).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn next_event_diffuse<I: Isa>(
    isa: I,
    scene: &SceneView<'_>,
    emitters: Option<&EmitterTable<I::Eight>>,
    v: &Vertex<I::Eight>,
    lanes: u32,
    u_select: &[f32; N],
    u_light: [&[f32; N]; 2],
    out: &mut ShadowLanes,
) -> u32 {
    type L<I> = <I as Isa>::Eight;
    let sample = match emitters {
        Some(table) => sample_emitter_table(isa, scene, table, lanes, u_select, u_light),
        None => sample_emitter_lanes(isa, scene, lanes, u_select, u_light),
    };
    let Some((es, sampled)) = sample else {
        return 0;
    };
    let zero = L::<I>::splat(isa, 0.0);
    let (e_p, e_err, e_ng) = (es.p, es.p_err, es.ng);
    // `sample_direct_unoccluded`.
    let to_light = e_p.sub(v.p);
    let dist2 = to_light.dot(to_light);
    let wi = to_light.div(dist2.sqrt());
    let cos_light = es.n.dot(wi.neg());
    let wi_l = to_local(wi, v.s, v.t, v.n);
    let wi_ng = wi.dot(v.ng);
    let agree = v.sides_agree(wi_ng, wi_l.z, zero);
    let f = V3::select(agree, v.diffuse_eval(wi_l.z, zero), V3::splat_lanes(zero));
    let pdf_bsdf = L::<I>::select(
        agree & !v.wo_l.z.simd_le(zero),
        cosine_pdf(wi_l.z, v.inv_pi, zero),
        zero,
    );
    // As the scalar tests reject: `dist2` NaN or not positive, `cos_light <= 0` (a NaN passes),
    // `f` zero.
    let ok = dist2.simd_gt(zero) & !cos_light.simd_le(zero) & !f.is_zero(zero);
    // `spawn_ray_to` and `shadow_ray`.
    let o = offset_ray_origin(isa, v.p_spawn, v.p_err, v.ng, e_p.sub(v.p_spawn), zero);
    let target = offset_ray_origin(isa, e_p, e_err, e_ng, o.sub(e_p), zero);
    let d = target.sub(o);
    let len = d.dot(d).sqrt();
    let scale = o.abs().max(target.abs()).max_element();
    let slack = L::<I>::splat(isa, SHADOW_ULPS * f32::EPSILON) * scale
        + L::<I>::splat(isa, 2.0) * v.p_err.max(e_err).max_element();
    let t = L::<I>::splat(isa, 1.0) - slack / len;
    let t = L::<I>::select(t.simd_lt(zero), zero, t);
    let top = L::<I>::splat(isa, 1.0 - f32::EPSILON);
    let t = L::<I>::select(t.simd_gt(top), top, t);
    let t_max = L::<I>::select(len.simd_gt(zero), t, zero);
    // `AreaPdf::to_solid_angle` and the contribution.
    let pdf = es.pdf * dist2 / cos_light.abs();
    let contribution = f.mul(es.radiance).scale(wi.dot(v.n).abs() / pdf);
    out.o.store(o);
    out.d.store(d);
    out.t_max = t_max.to_array();
    out.contribution.store(contribution);
    out.pdf = pdf.to_array();
    out.pdf_bsdf = pdf_bsdf.to_array();
    ok.to_bitmask() & sampled
}

/// [`crate::geometry::shadow_ray`]'s margin in ulps of the larger coordinate.
const SHADOW_ULPS: f32 = 16.0;

/// Adds the light of the shadow rays of `lanes` that are not `occluded` (bits) to the paths'
/// radiance, weighted by the power heuristic ([`PathState::add_light`] under MIS).
#[inline(always)]
pub(super) fn add_light_lanes<I: Isa>(
    isa: I,
    state: &mut PathLanes,
    shadows: &ShadowLanes,
    lanes: u32,
    occluded: u32,
) {
    let lit = lanes & !occluded;
    if lit == 0 {
        return;
    }
    type L<I> = <I as Isa>::Eight;
    let zero = L::<I>::splat(isa, 0.0);
    let (a, b) = (
        L::<I>::new(isa, shadows.pdf),
        L::<I>::new(isa, shadows.pdf_bsdf),
    );
    // `power_heuristic`.
    let (a2, b2) = (a * a, b * b);
    let w = a2 / (a2 + b2);
    let w = L::<I>::select(w.is_finite(), w, zero);
    let l: V3<L<I>> = state.l.load(isa);
    let added = l.add(
        state
            .beta
            .load::<L<I>>(isa)
            .mul(shadows.contribution.load(isa))
            .scale(w),
    );
    let lit_lanes = lane_mask::<L<I>>(isa, lit);
    state.l.store(V3::select(lit_lanes, added, l));
}

/// All-ones lanes where `bits` has a bit, zero lanes elsewhere.
#[inline(always)]
fn lane_mask<L: Lanes<N>>(isa: L::Isa, bits: u32) -> L {
    let all = f32::from_bits(u32::MAX);
    L::new(
        isa,
        core::array::from_fn(|l| if bits >> l & 1 != 0 { all } else { 0.0 }),
    )
}

/// BSDF sampling and roulette at the diffuse vertices of `lanes` under MIS with
/// [`Roulette::Adaptive`], in lanes: what [`PathState::scatter`] computes there after
/// `bounces` vertices, with the direction numbers `u_direction` and the roulette numbers
/// `u_roulette`. Updates the throughputs, writes the rays to `out` and returns the lanes whose
/// paths go on (bits).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn scatter_diffuse<I: Isa>(
    isa: I,
    settings: &PathSettings,
    bounces: u32,
    state: &mut PathLanes,
    v: &Vertex<I::Eight>,
    lanes: u32,
    u_direction: [&[f32; N]; 2],
    u_roulette: &[f32; N],
    out: &mut RayLanes,
) -> u32 {
    type L<I> = <I as Isa>::Eight;
    let lane = |x: f32| L::<I>::splat(isa, x);
    let (zero, one) = (lane(0.0), lane(1.0));
    // `Diffuse::sample`: `warp::sample_cosine_hemisphere` (the concentric disk).
    let (ux, uy) = (
        L::<I>::new(isa, *u_direction[0]),
        L::<I>::new(isa, *u_direction[1]),
    );
    let two = lane(2.0);
    let (ox, oy) = (two * ux - one, two * uy - one);
    let centre = ox.simd_eq(zero) & oy.simd_eq(zero);
    let wide = ox.abs().simd_gt(oy.abs());
    let r = L::<I>::select(wide, ox, oy);
    let theta = L::<I>::select(
        wide,
        lane(FRAC_PI_4) * (oy / ox),
        lane(FRAC_PI_2) - lane(FRAC_PI_4) * (ox / oy),
    );
    let (sin, cos) = sin_cos_lanes(&theta.to_array(), lanes);
    let dx = L::<I>::select(centre, zero, r * L::<I>::new(isa, cos));
    let dy = L::<I>::select(centre, zero, r * L::<I>::new(isa, sin));
    let z = max_zero(one - dx * dx - dy * dy, zero).sqrt();
    let f = v.diffuse_eval(z, zero);
    let pdf = cosine_pdf(z, v.inv_pi, zero);
    // `Bsdf::sample`'s test of the sample, then `BsdfView::sample`'s.
    let valid = !v.wo_l.z.simd_le(zero)
        & pdf.simd_gt(zero)
        & pdf.is_finite()
        & z.simd_ne(zero)
        & f.is_finite()
        & !f.is_zero(zero);
    let wi = v.s.scale(dx).add(v.t.scale(dy)).add(v.n.scale(z));
    let wi_ng = wi.dot(v.ng);
    let weight = f.scale(z.abs() / pdf);
    let valid = valid & v.sides_agree(wi_ng, z, zero) & weight.is_finite();
    // The throughput, and roulette.
    let beta = state.beta.load::<L<I>>(isa).mul(weight);
    let mut alive = valid;
    let mut beta_out = beta;
    if settings.roulette_applies(Roulette::Adaptive, bounces) {
        let eta: L<I> = L::<I>::new(isa, state.eta_scale);
        let q = min_num(beta.scale(eta).max_element(), lane(settings.rr_prob));
        alive &= L::<I>::new(isa, *u_roulette).simd_lt(q);
        beta_out = beta.div(q);
    }
    let alive_bits = alive.to_bitmask() & lanes;
    let keep = lane_mask::<L<I>>(isa, alive_bits);
    state
        .beta
        .store(V3::select(keep, beta_out, state.beta.load(isa)));
    out.o
        .store(offset_ray_origin(isa, v.p_spawn, v.p_err, v.ng, wi, zero));
    out.d.store(wi);
    out.pdf = pdf.to_array();
    alive_bits
}
