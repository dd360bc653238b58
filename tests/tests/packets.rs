//! Packets of eight rays ([`SceneView::intersect_packet`], [`SceneView::occluded_packet`])
//! against the one-ray queries: bit for bit the same hits (distance, triangle, barycentrics)
//! and the same occlusion answers, for the rays a path tracer makes (a pixel's camera rays,
//! bounce rays, shadow rays to emitter samples), packets that mix rays from all over the film,
//! partial packets, and odd rays (axis-parallel, zero direction components, origins outside
//! the scene, tiny and infinite bounds), on scenes from 32 to 32k triangles.

mod common;

use common::*;
use ember_cli::LoadedScene;
use ember_kernel::emitter::sample_emitter;
use ember_kernel::geometry::{spawn_ray_to, Ray, PACKET};
use ember_kernel::sampler::{IndependentSampler, Sampler};
use ember_kernel::scene::{Hit, SceneView};
use glam::{Vec2, Vec3};
use std::path::PathBuf;

fn hit_bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.triangle, h.b1.to_bits(), h.b2.to_bits()))
}

/// Counts of what the comparisons saw, so that a test that compares nothing fails.
#[derive(Default, Debug)]
struct Seen {
    rays: usize,
    hits: usize,
    occluded: usize,
    unoccluded: usize,
}

fn check(view: &SceneView<'_>, rays: &[Ray; PACKET], what: &str, seen: &mut Seen) {
    for live in [0xFF, 0x5A, 0x81, 0x01, 0x00] {
        let packet = view.intersect_packet(rays, live);
        let occluded = view.occluded_packet(rays, live);
        assert_eq!(
            occluded & !live,
            0,
            "{what}: occlusion outside live {live:#x}"
        );
        for lane in 0..PACKET {
            if live >> lane & 1 == 0 {
                assert!(
                    packet[lane].is_none(),
                    "{what}: lane {lane} not live but hit"
                );
                continue;
            }
            let one = view.intersect(&rays[lane]);
            assert_eq!(
                hit_bits(packet[lane]),
                hit_bits(one),
                "{what}: lane {lane} of {live:#x}: ray {:?}",
                rays[lane]
            );
            // A hit carries its triangle's vertices as the index buffer gives them (from the
            // leaf groups, which `interaction` then reads instead of the index buffer).
            for h in [one, packet[lane]].into_iter().flatten() {
                assert_eq!(
                    h.vertices.map(|v| v.to_array().map(f32::to_bits)),
                    view.triangle_vertices(h.triangle)
                        .map(|v| v.to_array().map(f32::to_bits)),
                    "{what}: vertices of the hit of lane {lane}"
                );
            }
            let occ = view.occluded(&rays[lane]);
            assert_eq!(
                occluded >> lane & 1 == 1,
                occ,
                "{what}: occlusion of lane {lane} of {live:#x}: ray {:?}",
                rays[lane]
            );
            if live == 0xFF {
                seen.rays += 1;
                seen.hits += usize::from(one.is_some());
                seen.occluded += usize::from(occ);
                seen.unoccluded += usize::from(!occ);
            }
        }
    }
}

struct Rng(IndependentSampler);

impl Rng {
    fn f(&mut self) -> f32 {
        self.0.next_1d()
    }
    fn dir(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.f(), self.f(), self.f()) * 2.0 - 1.0;
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v;
            }
        }
    }
}

fn check_scene(toml: PathBuf) -> Seen {
    let scene = LoadedScene::load(&toml).unwrap();
    let view = scene.data.view();
    let what = toml.display().to_string();
    let (w, h) = (24, 18);
    let camera = scene.camera(w, h);
    let mut rng = Rng(IndependentSampler::new(0x9AC4E7, 1, 0));
    let mut seen = Seen::default();
    // Surface points from camera rays: (point, error, normal facing the camera ray).
    let mut points = Vec::new();
    for y in 0..h {
        for x in 0..w {
            // A pixel's eight camera rays: the coherent packet.
            let rays: [Ray; PACKET] =
                std::array::from_fn(|_| camera.generate_ray(x, y, Vec2::new(rng.f(), rng.f())));
            check(
                &view,
                &rays,
                &format!("{what} camera ({x}, {y})"),
                &mut seen,
            );
            for ray in &rays {
                if let Some(hit) = view.intersect(ray) {
                    let si = view.interaction(ray, &hit);
                    let n = if si.ng.dot(ray.d) < 0.0 {
                        si.ng
                    } else {
                        -si.ng
                    };
                    points.push((si, n));
                }
            }
        }
    }
    assert!(points.len() > 1000, "{what}: {} camera hits", points.len());
    // Bounce rays from one pixel's hits (chunks in film order) and from all over the film
    // (a stride), and shadow rays to emitter samples.
    let stride = points.len() / PACKET;
    let starts = (0..points.len() - PACKET)
        .step_by(2)
        .map(|s| (s, 1))
        .chain((0..points.len() - (PACKET - 1) * stride).map(|s| (s, stride)));
    for (start, spread) in starts {
        {
            let pick = |lane: usize| &points[start + lane * spread];
            let bounce: [Ray; PACKET] = std::array::from_fn(|lane| {
                let (si, n) = pick(lane);
                let mut d = rng.dir();
                if d.dot(*n) < 0.0 {
                    d = -d;
                }
                si.spawn_ray(d)
            });
            check(
                &view,
                &bounce,
                &format!("{what} bounce {start}/{spread}"),
                &mut seen,
            );
            let shadow: [Ray; PACKET] = std::array::from_fn(|lane| {
                let (si, _) = pick(lane);
                let (u, v) = (rng.f(), Vec2::new(rng.f(), rng.f()));
                match sample_emitter(&view, u, v) {
                    Some(es) => spawn_ray_to(si.p_spawn, si.p_err, si.ng, es.p, es.p_err, es.ng),
                    None => si.spawn_ray(rng.dir()),
                }
            });
            check(
                &view,
                &shadow,
                &format!("{what} shadow {start}/{spread}"),
                &mut seen,
            );
        }
    }
    // Odd rays: axis-parallel and zero direction components, origins outside the scene and on
    // its bounds, tiny, zero and infinite bounds.
    let (lo, hi) = view.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(a, b), p| (a.min(*p), b.max(*p)),
    );
    let size = (hi - lo).max_element();
    for i in 0..400 {
        let rays: [Ray; PACKET] = std::array::from_fn(|lane| {
            let u = Vec3::new(rng.f(), rng.f(), rng.f());
            let o = match (i + lane) % 4 {
                0 => lo + (hi - lo) * u,
                1 => lo - Vec3::splat(size) + (hi - lo + Vec3::splat(2.0 * size)) * u,
                2 => Vec3::new(lo.x, lo.y + (hi.y - lo.y) * u.y, lo.z + (hi.z - lo.z) * u.z),
                _ => (lo + hi) * 0.5,
            };
            let mut d = rng.dir();
            match (i * 7 + lane) % 5 {
                0 => d.x = 0.0,
                1 => d = Vec3::new(0.0, d.y, 0.0),
                2 => d = Vec3::new(0.0, 0.0, -1.0),
                3 => d *= 1e-3,
                _ => {}
            }
            let t_max = [f32::INFINITY, size * 0.1, 1e-6, 0.0, size][(i + 3 * lane) % 5];
            Ray { o, d, t_max }
        });
        check(&view, &rays, &format!("{what} odd {i}"), &mut seen);
    }
    seen
}

#[test]
fn packets_are_the_one_ray_queries_bit_for_bit() {
    for toml in [
        project_data("cornell-box/cornell_box.toml"),
        project_data("mirror-glass/mirror_glass.toml"),
        project_data("rough-spheres/rough_spheres.toml"),
        project_data("textured/textured.toml"),
        cbox_scene("cbox_path_explicit_rr.toml"),
    ] {
        let name = toml.display().to_string();
        let seen = check_scene(toml);
        assert!(seen.rays > 20_000, "{name}: {seen:?}");
        assert!(seen.hits > seen.rays / 4, "{name}: {seen:?}");
        assert!(
            seen.occluded > 1000 && seen.unoccluded > 1000,
            "{name}: {seen:?}"
        );
    }
}
