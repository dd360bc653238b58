use super::PathSettings;
use crate::bsdf::{Bsdf, TransportMode};
use crate::emitter::sample_emitter;
use crate::geometry::{spawn_ray_to, Ray};
use crate::sampler::Sampler;
use crate::scene::{SceneView, SurfaceInteraction};
use crate::Rgb;

/// Explicit path tracing: emission seen directly from the camera, next-event estimation (area
/// sampling of the emitters plus a shadow ray) at every scattering vertex, and BSDF sampling to
/// continue. Emitters hit by continuation rays are not counted, so nothing is counted twice.
pub fn li_explicit<S: Sampler>(
    scene: &SceneView<'_>,
    ray: &Ray,
    settings: &PathSettings,
    sampler: &mut S,
) -> Rgb {
    let Some(hit) = scene.intersect(ray) else {
        return Rgb::ZERO;
    };
    let si = scene.interaction(ray, &hit);
    let bsdf = scene.material(si.material).bsdf;
    scene.emitted(&si) + li_explicit_from_surface(scene, si, &bsdf, settings, sampler)
}

/// Reflected radiance leaving `si` toward `si.wo`, estimated by explicit path tracing from `si`
/// as the first scattering vertex (emission of `si` itself excluded), with `first_bsdf` at `si`
/// and the scene's materials further on. The GI bake starts here with a diffuse-only BSDF.
/// Per bounce it draws 1 + 2 dimensions for the emitter, 2 for the BSDF and 1 for roulette.
pub fn li_explicit_from_surface<S: Sampler>(
    scene: &SceneView<'_>,
    mut si: SurfaceInteraction,
    first_bsdf: &Bsdf,
    settings: &PathSettings,
    sampler: &mut S,
) -> Rgb {
    let mut l = Rgb::ZERO;
    let mut beta = Rgb::ONE;
    let mut bounces = 0u32;
    let mut bsdf = *first_bsdf;
    loop {
        bounces += 1;
        if !settings.allows(bounces) {
            break;
        }
        let u_select = sampler.next_1d();
        let u_light = sampler.next_2d();
        let u_bsdf = sampler.next_2d();
        let u_rr = sampler.next_1d();

        if bsdf.flags().is_non_specular() {
            l += beta * direct_light(scene, &si, &bsdf, u_select, u_light);
        }
        // The next vertex only matters if its direct lighting is within the depth limit.
        if !settings.allows(bounces + 1) {
            break;
        }
        let Some(bs) = bsdf.sample(si.wo, u_bsdf, TransportMode::Radiance) else {
            break;
        };
        beta *= bs.weight();
        if !settings.survives_roulette(bounces, u_rr, &mut beta) {
            break;
        }
        let next = si.spawn_ray(si.frame.to_world(bs.wi));
        let Some(hit) = scene.intersect(&next) else {
            break;
        };
        si = scene.interaction(&next, &hit);
        bsdf = scene.material(si.material).bsdf;
    }
    l
}

/// One-sample estimate of the radiance reflected at `si` from light arriving directly from
/// the emitters: `f · cosθᵢ · Le / p_ω`, zero when the emitter point is occluded, faces away, or
/// lies below the shading hemisphere.
#[inline]
fn direct_light(
    scene: &SceneView<'_>,
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    u_select: f32,
    u_light: glam::Vec2,
) -> Rgb {
    let Some(es) = sample_emitter(scene, u_select, u_light) else {
        return Rgb::ZERO;
    };
    let to_light = es.p - si.p;
    let dist2 = to_light.length_squared();
    if dist2.is_nan() || dist2 <= 0.0 {
        return Rgb::ZERO;
    }
    let wi_world = to_light / crate::math::sqrt(dist2);
    let cos_light = es.n.dot(-wi_world);
    if cos_light <= 0.0 {
        return Rgb::ZERO;
    }
    let wi = si.frame.to_local(wi_world);
    if wi.z <= 0.0 {
        return Rgb::ZERO;
    }
    let f = bsdf.eval(si.wo, wi, TransportMode::Radiance);
    if f == Rgb::ZERO {
        return Rgb::ZERO;
    }
    let shadow = spawn_ray_to(si.p, si.p_err, si.ng, es.p, es.p_err, es.ng);
    if scene.occluded(&shadow) {
        return Rgb::ZERO;
    }
    let pdf = es.pdf.to_solid_angle(dist2, cos_light);
    f * es.radiance * (wi.z / pdf.0)
}
