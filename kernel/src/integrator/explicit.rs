use super::direct::sample_direct;
use super::PathSettings;
use crate::bsdf::{Bsdf, TransportMode};
use crate::geometry::Ray;
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
    sampler.count_ray();
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
            if let Some(d) = sample_direct(scene, &si, &bsdf, u_select, u_light, sampler) {
                l += beta * d.contribution;
            }
        }
        // The next vertex only matters if its direct lighting is within the depth limit.
        if settings.is_terminal(bounces) {
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
        sampler.count_ray();
        let Some(hit) = scene.intersect(&next) else {
            break;
        };
        si = scene.interaction(&next, &hit);
        bsdf = scene.material(si.material).bsdf;
    }
    l
}
