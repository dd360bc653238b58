//! The batched path tracers ([`render_pixel_batched`], issue 14's lever 3) against the one-path
//! loop ([`render_pixel_by_sample`]): bit for bit the same pixel sums and ray counts for implicit,
//! explicit and MIS path tracing, with both samplers, on scenes that hold every BSDF (diffuse,
//! Phong mixtures, smooth and rough conductors and dielectrics, textures), at bounded and
//! unbounded depths, for sample ranges that do not fill whole batches, with the rays traced
//! one by one and as packets.

mod common;

use common::*;
use ember_cli::LoadedScene;
use ember_kernel::integrator::{
    render_pixel_batched, render_pixel_by_sample, Integrator, PathSettings, PixelStats, BATCH,
    PACKET_SEGMENTS,
};
use ember_kernel::sampler::{SamplerKind, Sampling};
use ember_kernel::splat::NoSplats;
use std::path::{Path, PathBuf};

fn stats_bits(s: &PixelStats) -> [u32; 7] {
    let [a, b, c] = s.sum.to_array().map(f32::to_bits);
    let [d, e, f] = s.sum_sq.to_array().map(f32::to_bits);
    [a, b, c, d, e, f, s.rays as u32 ^ (s.invalid << 24)]
}

/// Every pixel of a `w × h` film: samples `first .. first + count` added to sums that already
/// hold samples `0 .. first` (as a progressive render does), with both drivers.
fn assert_same(toml: &Path, integrator: Integrator, path: PathSettings, kind: SamplerKind) {
    let scene = LoadedScene::load(toml).unwrap();
    let view = scene.data.view();
    let (w, h, spp) = (12, 9, 32);
    let camera = scene.camera(w, h);
    let strategy = integrator.path_strategy().unwrap();
    let sampling = Sampling::new(kind, 0xBA7C4, spp, w, h);
    let what = format!(
        "{} {integrator:?} {kind:?} maxDepth {}",
        toml.display(),
        path.max_depth
    );
    let mut rays = 0u64;
    let mut lit = 0usize;
    for y in 0..h {
        for x in 0..w {
            // `batched`: the segments traced as packets, or `None` for the one-path loop.
            let pixel = |first: u32, count: u32, stats: PixelStats, batched: Option<u32>| {
                if let Some(packet_segments) = batched {
                    render_pixel_batched(
                        &strategy,
                        &view,
                        &camera,
                        &path,
                        &sampling,
                        x,
                        y,
                        first,
                        count,
                        stats,
                        packet_segments,
                    )
                } else {
                    render_pixel_by_sample(
                        integrator,
                        &view,
                        &camera,
                        &path,
                        &sampling,
                        x,
                        y,
                        first,
                        count,
                        stats,
                        None,
                        &mut NoSplats,
                    )
                }
            };
            // 3 + 15 + 14: too few samples for the lanes (`MIN_LANES`: the one-path loop), a
            // whole batch and a partial one of 7, another whole one and one of 6;
            // rays traced one by one (the shipped choice) and as packets for the camera and
            // the first two bounces.
            let mut scalar = PixelStats::default();
            let mut batched = [PixelStats::default(); 2];
            for (first, count) in [(0, 3), (3, 15), (18, 14)] {
                scalar = pixel(first, count, scalar, None);
                for (b, packets) in batched.iter_mut().zip([PACKET_SEGMENTS, 3]) {
                    *b = pixel(first, count, *b, Some(packets));
                    assert_eq!(
                        stats_bits(&scalar),
                        stats_bits(b),
                        "{what}: pixel ({x}, {y}) after samples {first}..{}, {packets} packet \
                         segments",
                        first + count
                    );
                }
            }
            rays += scalar.rays;
            lit += usize::from(scalar.sum.max_element() > 0.0);
        }
    }
    // The comparison must have seen paths that bounce, and light.
    let pixels = (w * h) as u64;
    assert!(
        rays > pixels * u64::from(spp) * 2,
        "{what}: {rays} rays: paths end at once"
    );
    // Implicit paths find a small light by chance; with next-event estimation most pixels
    // see it.
    let needed = if integrator == Integrator::PathImplicit {
        1
    } else {
        (w * h) as usize / 2
    };
    assert!(lit >= needed, "{what}: only {lit} lit pixels");
}

fn scenes() -> Vec<PathBuf> {
    vec![
        project_data("cornell-box/cornell_box.toml"),
        project_data("mirror-glass/mirror_glass.toml"),
        project_data("mirror-glass/mirror_glass_rough.toml"),
        project_data("rough-spheres/rough_spheres.toml"),
        project_data("textured/textured.toml"),
        // TinyRender's box: its sphere is a Phong/diffuse mixture (illum 8).
        cbox_scene("cbox_path_explicit_rr.toml"),
    ]
}

#[test]
fn batched_path_tracers_are_the_scalar_ones_bit_for_bit() {
    assert_eq!(BATCH, 8);
    for toml in scenes() {
        let scene = LoadedScene::load(&toml).unwrap();
        let (_, scene_path, _) = scene.path_settings().unwrap();
        for integrator in [
            Integrator::PathImplicit,
            Integrator::PathExplicit,
            Integrator::PathMis,
        ] {
            for kind in [SamplerKind::ZSobol, SamplerKind::Independent] {
                // The scene's own depth (unbounded, with roulette, for most), and a bounded one
                // whose last ray takes the terminal shortcut.
                for max_depth in [scene_path.max_depth, 3] {
                    let path = PathSettings {
                        max_depth,
                        ..scene_path
                    };
                    assert_same(&toml, integrator, path, kind);
                }
            }
        }
    }
}

/// The batched bake ([`bake_vertex_batched`]) against the one-sample-at-a-time bake
/// ([`bake_vertex_by_sample`]): bit for bit the same vertex values for both estimators and both
/// samplers, on every BSDF scene, at the scene's depth and a bounded one, for sample counts
/// too few for the lanes (3: the one-path loop) and batches of 5, 6 and 8, at mesh vertices exactly (on the
/// edges where walls meet, as TinyRender bakes them) and stepped into a triangle.
#[test]
fn batched_bake_is_the_scalar_bake_bit_for_bit() {
    use ember_kernel::integrator::{
        bake_vertex_batched, bake_vertex_by_sample, BakeEstimator, BakePoint, BakeSamples,
    };
    use ember_kernel::{Vec2, Vec3};
    for toml in scenes() {
        let scene = LoadedScene::load(&toml).unwrap();
        let data = &scene.data;
        let view = data.view();
        let (_, scene_path, _) = scene.path_settings().unwrap();
        // A few vertices of every object, and one point with no normal (nothing to bake).
        let mut points = vec![BakePoint {
            p: Vec3::ZERO,
            n: Vec3::ZERO,
            material: 0,
            uv: Vec2::ZERO,
        }];
        for o in &data.objects {
            let step = (o.vertices.len() / 6).max(1);
            for v in o.vertices.clone().step_by(step) {
                let v = v as usize;
                let (p, n) = (data.positions[v], data.normals[v]);
                let uv = data.uvs.get(v).copied().unwrap_or(Vec2::ZERO);
                points.push(BakePoint {
                    p,
                    n,
                    material: o.material,
                    uv,
                });
                // Stepped toward the centroid of the object's first triangle.
                let c = view
                    .triangle_vertices(o.triangles.start)
                    .iter()
                    .sum::<Vec3>()
                    / 3.0;
                points.push(BakePoint {
                    p: p + (c - p) * 1e-3,
                    n,
                    material: o.material,
                    uv,
                });
            }
        }
        let mut lit = 0;
        for estimator in [BakeEstimator::Mis, BakeEstimator::Explicit] {
            for sampler in [SamplerKind::ZSobol, SamplerKind::Independent] {
                for max_depth in [scene_path.max_depth, 3] {
                    let path = PathSettings {
                        max_depth,
                        ..scene_path
                    };
                    for (k, point) in points.iter().enumerate() {
                        let per_vertex = [3, 13, 22][k % 3];
                        let samples = BakeSamples {
                            sampler,
                            seed: 0xBA4E,
                            per_vertex,
                        };
                        let key = k as u64;
                        let scalar =
                            bake_vertex_by_sample(&view, point, &path, estimator, &samples, key);
                        let batched =
                            bake_vertex_batched(&view, point, &path, estimator, &samples, key);
                        assert_eq!(
                            scalar.to_array().map(f32::to_bits),
                            batched.to_array().map(f32::to_bits),
                            "{}: {estimator:?} {sampler:?} maxDepth {max_depth}, point {k} \
                             ({point:?}), {per_vertex} samples: {scalar} against {batched}",
                            toml.display()
                        );
                        lit += usize::from(scalar.max_element() > 0.0);
                    }
                }
            }
        }
        // The comparison must have seen light at most of the points.
        assert!(
            lit > 2 * 2 * 2 * points.len() / 2,
            "{}: {lit} lit bakes of {}",
            toml.display(),
            8 * points.len()
        );
    }
}

/// Runs of a row ([`render_row`]: under MIS, a call of fewer samples per pixel than
/// [`MIN_LANES`] fills its batches with neighbouring pixels' samples) against the one-path
/// loop pixel by pixel: bit for bit the same sums and ray counts, for both samplers, films
/// laid out for 1 to 4 and 32 spp (odd and even powers of two, so both forms of the bottom
/// Sobol' digit), calls of 1 to 4 samples and of more, runs of one pixel, of a whole row and
/// of rows cut into runs that start anywhere, with sample indices past the layout (as an
/// embedder may ask).
#[test]
fn row_runs_are_the_scalar_pixels_bit_for_bit() {
    use ember_kernel::integrator::{render_row, MIN_LANES};
    assert_eq!(MIN_LANES, 5);
    let integrator = Integrator::PathMis;
    for toml in scenes() {
        let scene = LoadedScene::load(&toml).unwrap();
        let view = scene.data.view();
        let (_, path, _) = scene.path_settings().unwrap();
        let (w, h) = (13, 5);
        let camera = scene.camera(w, h);
        for kind in [SamplerKind::ZSobol, SamplerKind::Independent] {
            for layout_spp in [1, 2, 3, 4, 32] {
                let sampling = Sampling::new(kind, 0x5EED, layout_spp, w, h);
                // Consecutive calls (first, count): the last one runs past a small layout.
                let calls = [(0, 1), (1, 2), (3, 4), (7, 3), (10, 6)];
                // Runs of each row: (first x, pixels).
                for runs in [vec![(0, 13)], vec![(0, 1), (1, 5), (6, 7)], vec![(2, 3)]] {
                    let what = format!(
                        "{} {kind:?} layout {layout_spp} spp, runs {runs:?}",
                        toml.display()
                    );
                    for y in 0..h {
                        for &(x0, n) in &runs {
                            let mut row = vec![PixelStats::default(); n as usize];
                            let mut scalar = vec![PixelStats::default(); n as usize];
                            for (first, count) in calls {
                                render_row(
                                    integrator,
                                    &view,
                                    &camera,
                                    &path,
                                    &sampling,
                                    (x0, y),
                                    first,
                                    count,
                                    &mut row,
                                    None,
                                    &mut NoSplats,
                                );
                                for (k, s) in scalar.iter_mut().enumerate() {
                                    *s = render_pixel_by_sample(
                                        integrator,
                                        &view,
                                        &camera,
                                        &path,
                                        &sampling,
                                        x0 + k as u32,
                                        y,
                                        first,
                                        count,
                                        *s,
                                        None,
                                        &mut NoSplats,
                                    );
                                }
                                for (k, (a, b)) in row.iter().zip(&scalar).enumerate() {
                                    assert_eq!(
                                        stats_bits(b),
                                        stats_bits(a),
                                        "{what}: pixel ({}, {y}) after samples {first}..{}",
                                        x0 + k as u32,
                                        first + count
                                    );
                                }
                            }
                            assert!(
                                scalar.iter().all(|s| s.rays >= 16),
                                "{what}: no rays traced"
                            );
                        }
                    }
                }
            }
        }
    }
}
