//! Next-event estimation: direct light from a point sampled on the emitters.

use crate::bsdf::{BsdfView, TransportMode};
use crate::emitter::sample_emitter;
use crate::geometry::{spawn_ray_to, Ray};
use crate::math::SolidAnglePdf;
use crate::scene::{SceneView, SurfaceInteraction};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// An unoccluded emitter sample seen from a surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectSample {
    /// `f · |cosθᵢ| · Le / p_ω`: the one-sample estimate of direct scattered radiance.
    pub contribution: Rgb,
    /// World-space unit direction to the light.
    pub wi: Vec3,
    /// Density of `wi` under emitter sampling, per unit solid angle.
    pub pdf: SolidAnglePdf,
    /// Density of `wi` under BSDF sampling (for MIS weights; 0 when not asked for).
    pub pdf_bsdf: SolidAnglePdf,
}

/// Samples a point on the emitters for the surface point `si` with its BSDF seen from `si.wo`
/// and returns its unweighted contribution, or `None` when the
/// point is occluded, faces away, or the BSDF is zero for it (delta lobes, the wrong side).
/// `pdf_bsdf` is computed only when `with_bsdf_pdf` (MIS needs it; next-event estimation
/// alone does not). The shadow ray, when one is traced, adds 1 to `rays`.
#[inline]
pub fn sample_direct(
    scene: &SceneView<'_>,
    si: &SurfaceInteraction,
    bsdf: &BsdfView<'_>,
    u_select: f32,
    u_light: Vec2,
    with_bsdf_pdf: bool,
    rays: &mut u32,
) -> Option<DirectSample> {
    let (d, shadow) = sample_direct_unoccluded(scene, si, bsdf, u_select, u_light, with_bsdf_pdf)?;
    *rays += 1;
    (!scene.occluded(&shadow)).then_some(d)
}

/// [`sample_direct`] but for its shadow ray, which is returned for the caller to trace (the
/// sample counts only if the ray is unoccluded): what a driver that traces the shadow rays of
/// many paths together ([`super::render_pixel_batched`]) needs.
#[inline]
pub fn sample_direct_unoccluded(
    scene: &SceneView<'_>,
    si: &SurfaceInteraction,
    bsdf: &BsdfView<'_>,
    u_select: f32,
    u_light: Vec2,
    with_bsdf_pdf: bool,
) -> Option<(DirectSample, Ray)> {
    let es = sample_emitter(scene, u_select, u_light)?;
    let to_light = es.p - si.p;
    let dist2 = to_light.length_squared();
    if dist2.is_nan() || dist2 <= 0.0 {
        return None;
    }
    let wi = to_light / crate::math::sqrt(dist2);
    let cos_light = es.n.dot(-wi);
    if cos_light <= 0.0 {
        return None;
    }
    let (f, pdf_bsdf) = if with_bsdf_pdf {
        bsdf.eval_pdf(wi, TransportMode::Radiance)
    } else {
        let f = bsdf.eval(wi, TransportMode::Radiance);
        (f, SolidAnglePdf(0.0))
    };
    if f == Rgb::ZERO {
        return None;
    }
    let shadow = spawn_ray_to(si.p_spawn, si.p_err, si.ng, es.p, es.p_err, es.ng);
    let pdf = es.pdf.to_solid_angle(dist2, cos_light);
    Some((
        DirectSample {
            contribution: f * es.radiance * (bsdf.abs_cos(wi) / pdf.0),
            wi,
            pdf,
            pdf_bsdf,
        },
        shadow,
    ))
}
