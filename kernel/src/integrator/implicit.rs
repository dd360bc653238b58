use super::PathSettings;
use crate::bsdf::TransportMode;
use crate::geometry::Ray;
use crate::sampler::Sampler;
use crate::scene::SceneView;
use crate::Rgb;

/// Implicit path tracing: a BSDF-sampled random walk that adds emission wherever it lands on
/// an emitter. Per bounce it draws 2 dimensions for the BSDF and 1 for roulette.
pub fn li_implicit<S: Sampler>(
    scene: &SceneView<'_>,
    ray: &Ray,
    settings: &PathSettings,
    sampler: &mut S,
) -> Rgb {
    sampler.count_ray();
    let Some(hit) = scene.intersect(ray) else {
        return Rgb::ZERO;
    };
    let mut si = scene.interaction(ray, &hit);
    let mut l = scene.emitted(&si);
    let mut beta = Rgb::ONE;
    let mut bounces = 0u32;
    loop {
        // `si` is scattering vertex number `bounces + 1`; its emission was already counted.
        bounces += 1;
        if !settings.allows(bounces) {
            break;
        }
        let u_bsdf = sampler.next_2d();
        let u_rr = sampler.next_1d();
        let bsdf = &scene.material(si.material).bsdf;
        let Some(bs) = bsdf.sample(si.wo, u_bsdf, TransportMode::Radiance) else {
            break;
        };
        beta *= bs.weight();
        if !settings.survives_roulette(bounces, u_rr, &mut beta) {
            break;
        }
        let next = si.spawn_ray(si.frame.to_world(bs.wi));
        sampler.count_ray();
        // The last ray of a bounded path only looks for emitters.
        let hit = if settings.is_terminal(bounces) {
            settings.terminal_hit(scene, &next)
        } else {
            scene.intersect(&next)
        };
        let Some(hit) = hit else {
            break;
        };
        si = scene.interaction(&next, &hit);
        l += beta * scene.emitted(&si);
    }
    l
}
