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
