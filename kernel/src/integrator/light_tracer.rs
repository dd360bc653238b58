//! Light tracing (particle tracing): paths from the emitters, each vertex connected to the
//! camera and splatted where it lands on the film (BDPT's `t = 1` strategies alone, as
//! pbrt-v4's `LightPathIntegrator` and Mitsuba 3's `ptracer`).

use super::{dims, PathSettings};
use crate::bsdf::TransportMode;
use crate::camera::{Camera, CameraSample};
use crate::emitter::sample_le;
use crate::geometry::{offset_ray_origin, shadow_ray, spawn_ray, Ray};
use crate::sampler::Sampler;
use crate::scene::SceneView;
use crate::splat::SplatSink;
use crate::Rgb;
use glam::Vec3;

/// The shadow ray from a surface point (spawn point, error bound, geometric normal) to the
/// camera's pinhole; the pinhole is a point in free space, so only the surface end is offset.
#[inline]
#[must_use]
pub fn ray_to_camera(p: Vec3, p_err: Vec3, ng: Vec3, cs: &CameraSample) -> Ray {
    let o = offset_ray_origin(p, p_err, ng, cs.wi);
    let target = o + cs.wi * cs.dist;
    shadow_ray(o, p_err, target, Vec3::ZERO)
}

/// Traces one light path and splats every vertex's connection to the camera into `sink`.
///
/// The measurement: a splat `C` at the raster position of a connection estimates
/// `∫ We L cosθ dω` for the pixel it lands in, and pixel `j`'s value is `W·H` times that
/// integral (see [`Camera::we`]). Tracing one light path per pixel sample, `W·H·spp` in all,
/// the image is the sum of the splats divided by `spp` and **not** by any filter weight
/// (pbrt-v4's `LightPathIntegrator` scaling; the error of scaling them otherwise is a known
/// pitfall, BONUS-NOTES §4). Connections use the BSDF in importance transport, through
/// [`crate::bsdf::SurfaceBsdf`], with its adjoint shading-normal correction.
///
/// `max_depth` keeps TinyRender's meaning: a connection from the `k`-th scattering vertex of
/// the light path makes a path with `k` scattering vertices, so the emitter seen directly is
/// depth 0. Russian roulette is throughput-adaptive ([`PathSettings::survives_adaptive_roulette`])
/// /// on the throughput relative to the emitted `Le/p`, counted along the light path.
/// Dimensions: [`dims::LightStart`], then [`dims::LightBounce`] per vertex. Every ray traced
/// adds 1 to `rays`.
pub fn light_trace<S: Sampler, K: SplatSink>(
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    sampler: &mut S,
    sink: &mut K,
    rays: &mut u32,
) {
    let start = dims::LightStart::draw(sampler);
    let Some(e) = sample_le(scene, start.select, start.position, start.direction) else {
        return;
    };
    let pt = &e.point;
    // The emitter point seen by the camera (depth 0).
    if settings.allows(0) {
        if let Some(cs) = camera.sample_wi(pt.p) {
            let cos = pt.n.dot(cs.wi);
            if cos > 0.0 && cs.wi.dot(pt.ng) > 0.0 {
                *rays += 1;
                if !scene.occluded(&ray_to_camera(pt.p, pt.p_err, pt.ng, &cs)) {
                    sink.splat(
                        cs.raster,
                        pt.radiance * (cs.we * cos / (cs.pdf.0 * pt.pdf.0)),
                    );
                }
            }
        }
    }
    // Throughput of the emitted ray: Le |cosθ| / (p_A p_ω).
    let mut beta = pt.radiance * (pt.n.dot(e.w).abs() / (pt.pdf.0 * e.pdf_dir.0));
    let mut ray = spawn_ray(pt.p, pt.p_err, pt.ng, e.w);
    let relative = 1.0 / beta.max_element();
    let mut bounces = 0u32;
    loop {
        bounces += 1;
        if !settings.allows(bounces) {
            break;
        }
        *rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            break;
        };
        let si = scene.interaction(&ray, &hit);
        let bsdf = scene.bsdf_at(&si);
        let view = bsdf.seen_from(si.wo);
        let u = dims::LightBounce::draw(sampler);
        if bsdf.flags().is_non_specular() {
            if let Some(cs) = camera.sample_wi(si.p) {
                let f = view.eval(cs.wi, TransportMode::Importance);
                if f != Rgb::ZERO {
                    *rays += 1;
                    if !scene.occluded(&ray_to_camera(si.p_spawn, si.p_err, si.ng, &cs)) {
                        let c = beta * f * (view.abs_cos(cs.wi) * cs.we / cs.pdf.0);
                        sink.splat(cs.raster, c);
                    }
                }
            }
        }
        let Some(s) = view.sample(u.lobe, u.direction, TransportMode::Importance) else {
            break;
        };
        beta *= s.weight;
        if !settings.survives_adaptive_roulette(bounces, u.roulette, relative, &mut beta) {
            break;
        }
        ray = si.spawn_ray(s.wi);
    }
}
