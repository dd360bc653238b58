//! The GI bake: closed-form furnace values at vertices, PLY round trip, determinism.

mod common;

use common::*;
use ember_cli::bake::{bake, read_ply, write_ply, BakeSettings, BakedMesh};
use ember_cli::LoadedScene;
use ember_kernel::integrator::PathSettings;
use ember_kernel::sampler::DEFAULT_SEED;

fn settings(spv: u32, threads: usize) -> BakeSettings {
    BakeSettings {
        path: PathSettings {
            max_depth: -1,
            rr_depth: 5,
            rr_prob: 0.95,
            ..PathSettings::default()
        },
        samples_per_vertex: spv,
        seed: DEFAULT_SEED,
        threads,
        progress: false,
        vertex_inset: ember_cli::bake::BAKE_INSET,
        estimator: ember_kernel::integrator::BakeEstimator::Mis,
        sampler: ember_kernel::sampler::SamplerKind::ZSobol,
    }
}

/// In a closed box with albedo a and emission 1, the outgoing radiance at every vertex —
/// corners and edges included — is 1/(1 − a). The mean over vertices must be within 1%, and
/// every vertex within 6 standard errors of the per-vertex estimate (measured from the spread
/// of the vertices themselves, which all share one expected value).
#[test]
fn furnace_bake_matches_closed_form_at_every_vertex() {
    for (name, a) in [("furnace_a050", 0.5f64), ("furnace_a080", 0.8)] {
        let scene =
            LoadedScene::load(&project_data(&format!("furnace/{name}_explicit.toml"))).unwrap();
        let (mesh, report) = bake(&scene, &settings(1024, 0)).unwrap();
        let expected = 1.0 / (1.0 - a);
        let values: Vec<f64> = mesh.colors.iter().map(|c| f64::from(c[0])).collect();
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let worst = values
            .iter()
            .map(|v| (v - expected).abs())
            .fold(0.0f64, f64::max);
        println!(
            "{name}: {} keys for {} corners, mean {mean:.4} (expected {expected}), sd {sd:.4}, worst |err| {worst:.4}",
            report.unique_keys, report.face_corners
        );
        if std::env::var_os("EMBER_DUMP").is_some() {
            for (i, v) in values.iter().enumerate() {
                println!("v {i} {:?} {v:.3}", mesh.positions[i]);
            }
        }
        assert!(mesh.colors.iter().all(|c| c[0] == c[1] && c[1] == c[2]));
        assert!(
            (mean - expected).abs() / expected < 0.01,
            "{name}: mean {mean}"
        );
        assert!(
            worst < 6.0 * sd.max(1e-3 * expected),
            "{name}: a vertex is off by {worst}"
        );
    }
}

#[test]
fn bake_round_trips_through_ply() {
    let scene = LoadedScene::load(&project_data("furnace/furnace_a050_explicit.toml")).unwrap();
    let (mesh, _) = bake(&scene, &settings(4, 0)).unwrap();
    let dir = std::env::temp_dir().join(format!("ember-bake-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("furnace.bake.ply");
    write_ply(&path, &mesh).unwrap();
    let back: BakedMesh = read_ply(&path).unwrap();
    assert_eq!(back, mesh, "PLY round trip changed the bake");
    // Bit-identical floats, not just equal.
    let bits =
        |m: &BakedMesh| -> Vec<u32> { m.colors.iter().flatten().map(|v| v.to_bits()).collect() };
    assert_eq!(bits(&back), bits(&mesh));
    // A truncated file is an error, not a short mesh.
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 5]).unwrap();
    assert!(read_ply(&path).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bake_does_not_depend_on_thread_count() {
    let scene = LoadedScene::load(&project_data("cornell-box/cornell_box_gi.toml")).unwrap();
    let (one, _) = bake(&scene, &settings(8, 1)).unwrap();
    let (two, _) = bake(&scene, &settings(8, 2)).unwrap();
    let bits =
        |m: &BakedMesh| -> Vec<u32> { m.colors.iter().flatten().map(|v| v.to_bits()).collect() };
    assert_eq!(bits(&one), bits(&two));
    assert!(one
        .colors
        .iter()
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0));
}

/// What a baked vertex on glass or metal stores: the cosine-weighted average over view
/// directions of the light it scatters (its radiosity over π; see `bake_vertex`), a
/// view-independent value. Inside the black furnace whose walls emit 1, a point facing the
/// walls has closed-form values: a mirror of reflectance `Ks` stores `Ks` exactly (every view
/// sees a wall), a point on the smooth glass sphere stores 1 (the sphere is invisible: what is
/// not reflected crosses it, 1/η² in and η² out), a white GGX conductor stores its single-scattering
/// albedo averaged over views (E_avg of BONUS-NOTES §5: 0.700 at α = 0.5, 0.971 at 0.1), a
/// diffuse surface its Kd. Every integrator-level rule is exercised: delta lobes (no
/// next-event estimation, emission counted after the bounce), MIS weights of the rough lobe.
#[test]
fn baked_glass_and_metal_store_the_view_average() {
    use ember_kernel::integrator::{bake_vertex, BakeEstimator, BakePoint, BakeSamples};
    use ember_kernel::material::Material;
    use ember_kernel::sampler::SamplerKind;
    use ember_kernel::{Rgb, Vec2, Vec3};
    let mut scene = LoadedScene::load(&project_data("furnace/furnace_glass.toml")).unwrap();
    let base = scene.data.materials.len() as u32;
    let cases = [
        (
            "mirror Ks 0.8",
            Material::conductor(Rgb::splat(0.8), 0.0),
            0.8,
            0.0,
        ),
        (
            "smooth glass",
            Material::dielectric(1.5, Rgb::ONE, 0.0),
            1.0,
            0.0,
        ),
        (
            "GGX conductor a=0.5",
            Material::conductor(Rgb::ONE, 0.5),
            0.700,
            0.002,
        ),
        (
            "GGX conductor a=0.1",
            Material::conductor(Rgb::ONE, 0.1),
            0.971,
            0.002,
        ),
        (
            "diffuse Kd 0.5",
            Material::diffuse(Rgb::splat(0.5)),
            0.5,
            0.0,
        ),
    ];
    scene.data.materials.extend(cases.iter().map(|c| c.1));
    let view = scene.data.view();
    view.validate().unwrap();
    // Outside the glass sphere (centre z = -0.35, radius 0.45), facing the +z wall; and the
    // centroid of the sphere's first facet, with its normal, for the glass.
    let free = (Vec3::new(0.1, -0.2, 0.6), Vec3::Z);
    let glass = scene
        .data
        .objects
        .iter()
        .find(|o| o.name == "glass")
        .unwrap();
    let [a, b, c] = view.triangle_vertices(glass.triangles.start);
    let facet = ((a + b + c) / 3.0, (b - a).cross(c - a).normalize());
    // No roulette: every path but the GGX ones has an exact value.
    let path = PathSettings {
        rr_depth: 2000,
        ..PathSettings::default()
    };
    let samples = 40_000;
    for (k, &(name, _, expected, reference_error)) in cases.iter().enumerate() {
        for estimator in [BakeEstimator::Mis, BakeEstimator::Explicit] {
            let (p, n) = if name == "smooth glass" { facet } else { free };
            let point = BakePoint {
                p,
                n,
                material: base + k as u32,
                uv: Vec2::ZERO,
            };
            // Independent keys give independent estimates: their spread is the noise.
            let values: Vec<f64> = (0..8u64)
                .map(|key| {
                    let samples = BakeSamples {
                        sampler: SamplerKind::ZSobol,
                        seed: 7,
                        per_vertex: samples / 8,
                    };
                    let b = bake_vertex(&view, &point, &path, estimator, &samples, key);
                    assert!(b.is_finite() && b.x == b.y && b.y == b.z, "{name}: {b}");
                    f64::from(b.x)
                })
                .collect();
            let mean = values.iter().sum::<f64>() / 8.0;
            let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 7.0;
            let se = (var / 8.0).sqrt();
            println!("{name} ({estimator:?}): {mean:.5} ± {se:.5}, expected {expected}");
            // 5 standard errors (Student t, 7 dof, two-sided 1%: 3.5) plus the reference's
            // own quadrature error; exact cases must be exact up to the rounding of the f32
            // sum of 5000 samples (observed 4e-5).
            let tol = 5.0 * se + reference_error + 1e-4;
            assert!(
                (mean - expected).abs() <= tol,
                "{name} ({estimator:?}): {mean} vs {expected} ± {tol}"
            );
        }
    }
}

/// The default bake sampler, Owen-scrambled Sobol' points per vertex, lowers the error per
/// path against independent numbers, with the same expected values. Each vertex's variance is
/// measured over bakes with different seeds (randomised replicates: valid for quasi-random
/// points, whose samples within one vertex are not independent), pooled over the vertices of
/// the Cornell box; 64 paths per vertex, 6 seeds per sampler.
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn zsobol_bake_lowers_the_variance_per_path() {
    use ember_kernel::sampler::SamplerKind;
    let scene = LoadedScene::load(&project_data("cornell-box/cornell_box_gi.toml")).unwrap();
    const SEEDS: u64 = 6;
    let replicates = |sampler: SamplerKind| -> Vec<Vec<f64>> {
        (0..SEEDS)
            .map(|seed| {
                let s = BakeSettings {
                    sampler,
                    seed: 1000 + seed,
                    ..settings(64, 0)
                };
                let (mesh, _) = bake(&scene, &s).unwrap();
                mesh.colors
                    .iter()
                    .map(|c| f64::from(c[0] + c[1] + c[2]))
                    .collect()
            })
            .collect()
    };
    // Per vertex: the replicates' mean and variance; pooled over vertices.
    let pooled = |r: &[Vec<f64>]| -> (f64, f64, usize) {
        let vertices = r[0].len();
        let (mut mean_sum, mut var_sum) = (0.0, 0.0);
        for v in 0..vertices {
            let xs: Vec<f64> = r.iter().map(|b| b[v]).collect();
            let m = xs.iter().sum::<f64>() / SEEDS as f64;
            mean_sum += m;
            var_sum += xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (SEEDS - 1) as f64;
        }
        (
            mean_sum / vertices as f64,
            var_sum / vertices as f64,
            vertices,
        )
    };
    let (m_ind, v_ind, vertices) = pooled(&replicates(SamplerKind::Independent));
    let (m_zs, v_zs, _) = pooled(&replicates(SamplerKind::ZSobol));
    let ratio = v_zs / v_ind;
    println!(
        "{vertices} vertices: mean {m_ind:.5} (independent) vs {m_zs:.5} (zsobol), variance per vertex {v_ind:.3e} vs {v_zs:.3e}: ratio {ratio:.3}"
    );
    // The scene-wide means agree: their difference against the standard error of the
    // difference (vertices' replicate means are independent, so the mean over vertices has
    // variance v / (SEEDS · vertices) at most; neighbours share no samples).
    let se = ((v_ind + v_zs) / (SEEDS as f64 * vertices as f64)).sqrt();
    assert!(
        (m_ind - m_zs).abs() < 5.0 * se,
        "means differ: {m_ind} vs {m_zs} (se {se})"
    );
    assert!(ratio < 0.7, "zsobol/independent variance ratio {ratio}");
}
