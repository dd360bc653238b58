//! `ember bench` end to end on a tiny ladder: the project's Cornell box at 32x32, rungs of 1 to
//! 64 spp with all three integrators, against a 1024-spp MIS reference rendered here with
//! another seed. Checks the CSV's exact columns, at least two rows per integrator, finite
//! values, doubling sample counts, the plot, and that the error falls from the first rung to the
//! last. About 3 s in release on 2 cores.

mod cli_util;
mod common;

use cli_util::{run_ember, TempDir};
use ember_cli::bench::{read_series_csv, CSV_COLUMNS};
use ember_kernel::integrator::Integrator;
use std::ffi::{OsStr, OsString};

fn os(v: impl AsRef<OsStr>) -> OsString {
    v.as_ref().to_os_string()
}

const INTEGRATORS: [&str; 3] = ["explicit", "mis", "implicit"];
const SIDE: u32 = 32;
const MAX_SPP: u32 = 64;
const REFERENCE_SPP: u32 = 1024;

/// Required fall of the relative MSE from the 1-spp rung to the 64-spp rung.
///
/// Expected: the variance falls as 1/spp, so the relMSE ratio is about
/// 64 / (1 + 64/1024) ≈ 60 (the reference's own noise, at 1024 spp, adds 1/16 of the last
/// rung's). The relMSE of one 32x32 image is itself a noisy, heavy-tailed estimate at 1 spp:
/// over 30 different base seeds the measured ratio ranged from 16 to 290 for explicit and MIS
/// (median 40) and from 34 to 140 for implicit. Requiring a factor 4 leaves a margin of 4
/// below the worst of those 30 draws; the test is deterministic (fixed seeds), the margin
/// protects it against changes to the random numbers an integrator draws.
const MIN_ERROR_RATIO: f64 = 4.0;

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn bench_writes_the_expected_csv_and_plot() {
    let dir = TempDir::new("bench");
    let scene = common::project_data("cornell-box/cornell_box.toml");
    // The reference: MIS, 16 times the largest rung's samples, seed 1 (the ladder's seeds are
    // hashes of the base seed and the rung, never 1).
    let reference = common::render_scene_full(
        &scene,
        Some(Integrator::PathMis),
        SIDE,
        SIDE,
        REFERENCE_SPP,
        1,
        16,
        0,
    );
    let ref_path = dir.path().join("reference.exr");
    ember_cli::image::write_exr(&ref_path, &reference.image).unwrap();
    let out = dir.path().join("out");
    let result = run_ember([
        os("bench"),
        os(&scene),
        os("--reference"),
        os(&ref_path),
        os("--integrators"),
        os(INTEGRATORS.join(",")),
        os("--max-spp"),
        os(MAX_SPP.to_string()),
        // A generous per-rung budget: the ladder is bounded by --max-spp, so a loaded machine
        // cannot cut it short (each rung takes well under 1 s).
        os("--budget"),
        os("60"),
        os("--threads"),
        os("2"),
        os("-o"),
        os(&out),
    ]);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(result.status.success(), "ember bench failed:\n{stderr}");
    eprintln!("{stderr}");

    let csv = std::fs::read_to_string(out.join("bench.csv")).expect("bench.csv");
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(CSV_COLUMNS.join(",").as_str()));
    assert_eq!(
        CSV_COLUMNS.join(","),
        "scene,integrator,spp,seconds,samples_per_second,rays_per_second,rmse,rel_mse,bias"
    );
    // (integrator, spp, numeric fields seconds..bias)
    let rows: Vec<(String, u32, Vec<f64>)> = lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), CSV_COLUMNS.len(), "row {l:?}");
            assert_eq!(f[0], "cornell_box", "row {l:?}");
            let nums: Vec<f64> = f[3..]
                .iter()
                .map(|v| {
                    v.parse()
                        .unwrap_or_else(|_| panic!("not a number in {l:?}"))
                })
                .collect();
            assert!(nums.iter().all(|v| v.is_finite()), "non-finite in {l:?}");
            // seconds, samples/s, rays/s, rmse, rel_mse positive; bias signed.
            assert!(nums[..5].iter().all(|&v| v > 0.0), "non-positive in {l:?}");
            (f[1].to_string(), f[2].parse().unwrap(), nums)
        })
        .collect();
    for name in INTEGRATORS {
        let mine: Vec<&(String, u32, Vec<f64>)> = rows.iter().filter(|r| r.0 == name).collect();
        assert!(mine.len() >= 2, "{name}: {} rows", mine.len());
        let spps: Vec<u32> = mine.iter().map(|r| r.1).collect();
        let expected: Vec<u32> = (0..mine.len()).map(|k| 1 << k).collect();
        assert_eq!(spps, expected, "{name}: spp must double from 1");
        assert_eq!(*spps.last().unwrap(), MAX_SPP, "{name}: ladder cut short");
        for r in &mine {
            // rays/s >= samples/s: every sample traces at least its camera ray.
            assert!(
                r.2[2] >= r.2[1],
                "{name} at {} spp: rays/s < samples/s",
                r.1
            );
        }
        let (first, last) = (mine[0].2[4], mine.last().unwrap().2[4]);
        assert!(
            last * MIN_ERROR_RATIO < first,
            "{name}: relMSE {first:.4e} at 1 spp, {last:.4e} at {MAX_SPP} spp (need a fall by {MIN_ERROR_RATIO}x)"
        );
    }
    assert_eq!(rows.len(), 3 * 7, "7 rungs (1..64 spp) per integrator");

    // The plot: an SVG with axis titles and one legend entry per integrator.
    let svg = std::fs::read_to_string(out.join("bench.svg")).expect("bench.svg");
    assert!(svg.starts_with("<svg"), "not an SVG");
    for text in ["wall time (s)", "relative MSE"]
        .iter()
        .chain(INTEGRATORS.iter())
    {
        assert!(svg.contains(text), "{text:?} missing from bench.svg");
    }
    // The CSV reads back as the plot's series.
    let series = read_series_csv(&out.join("bench.csv")).unwrap();
    assert_eq!(
        series.iter().map(|s| s.label.as_str()).collect::<Vec<_>>(),
        INTEGRATORS
    );
}

/// A reference of another size is refused before anything is rendered.
#[test]
fn bench_refuses_a_reference_of_another_size() {
    let dir = TempDir::new("bench-size");
    let reference = ember_cli::image::Image::new(8, 8);
    let ref_path = dir.path().join("reference.exr");
    ember_cli::image::write_exr(&ref_path, &reference).unwrap();
    let scene = common::project_data("cornell-box/cornell_box.toml");
    let result = run_ember([
        os("bench"),
        os(&scene),
        os("--reference"),
        os(&ref_path),
        os("--width"),
        os("16"),
        os("--height"),
        os("16"),
        os("-o"),
        os(dir.path().join("out")),
    ]);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("reference.exr") && stderr.contains("8x8"),
        "{stderr}"
    );
    assert!(!dir.path().join("out").exists(), "output written anyway");
}

/// The ray counter behind rays/s: with maxDepth 0 every sample traces exactly its camera ray;
/// with maxDepth 1 the explicit and MIS integrators add at most one shadow ray (and MIS one
/// BSDF ray) per sample, the implicit one at most one continuation ray. Counts do not depend on
/// the thread count.
#[test]
fn ray_counts_follow_the_path_structure() {
    use ember_cli::render::{render, RenderSettings, Shard};
    use ember_kernel::integrator::PathSettings;
    let scene = ember_cli::LoadedScene::load(&common::project_data("cornell-box/cornell_box.toml"))
        .unwrap();
    let camera = scene.camera(16, 16);
    let samples = 16 * 16 * 4u64;
    let count = |integrator, max_depth, threads| {
        let r = render(
            &scene.data.view(),
            &camera,
            &RenderSettings {
                integrator,
                path: PathSettings {
                    max_depth,
                    ..PathSettings::default()
                },
                spp: 4,
                seed: 7,
                sampler: ember_kernel::sampler::SamplerKind::Independent,
                tile: 8,
                threads,
                progress: false,
                shard: Shard::WHOLE,
                strategies: None,
            },
        );
        r.rays
    };
    for integrator in [
        Integrator::PathImplicit,
        Integrator::PathExplicit,
        Integrator::PathMis,
    ] {
        assert_eq!(count(integrator, 0, 1), samples, "{integrator:?}");
        let one = count(integrator, 1, 1);
        let most = if integrator == Integrator::PathMis {
            3
        } else {
            2
        };
        assert!(
            one > samples && one <= most * samples,
            "{integrator:?}: {one} rays for {samples} samples at maxDepth 1"
        );
        let unbounded = count(integrator, -1, 2);
        assert!(unbounded > one, "{integrator:?}");
        assert_eq!(unbounded, count(integrator, -1, 1), "{integrator:?}");
    }
}
