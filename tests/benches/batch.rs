//! The batched path tracer ([`render_pixel_batched`], issue 14's lever 3) against the one-path
//! loop ([`render_pixel_by_sample`]) it must equal bit for bit (tests/tests/batched.rs): wall time of a
//! whole film, one thread, on the project's Cornell box (32 triangles) and TinyRender's
//! `cbox.obj` (32k), MIS with Sobol' samples (the renderer's default); the batched film with
//! its rays traced one by one ([`PACKET_SEGMENTS`]) and as packets for the camera rays
//! (`batched-packets-1`) and the first bounce's too (`batched-packets-2`); and the same film
//! rendered in calls of 1, 2 and 4 samples per pixel (`calls/…`: a progressive view's passes),
//! pixel by pixel and a row at a time (`rows-…`, [`render_row`]: the lanes filled with
//! neighbouring pixels' samples).
//!
//!     cargo bench -p ember-tests --bench batch
//!     cargo bench -p ember-tests --bench batch -- --quick

use criterion::{Criterion, Throughput};
use ember_cli::LoadedScene;
use ember_kernel::integrator::{
    render_pixel_batched, render_pixel_by_sample, render_row, Integrator, PixelStats,
    PACKET_SEGMENTS,
};
use ember_kernel::sampler::{SamplerKind, Sampling};
use ember_kernel::splat::NoSplats;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

const WIDTH: u32 = 64;
const HEIGHT: u32 = 64;
const SPP: u32 = 16;

fn scenes() -> Vec<(&'static str, PathBuf)> {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    vec![
        (
            "cornell-box",
            here.join("../data/cornell-box/cornell_box.toml"),
        ),
        (
            "cbox",
            here.join("../../shared/tinyrender/data/a5/cbox/tinyrender/cbox_path_explicit_rr.toml"),
        ),
    ]
}

fn main() {
    // Every figure carries the CPU it was measured on.
    eprintln!("CPU: {}", ember_cli::simd::cpu_summary());
    let mut c = Criterion::default()
        .configure_from_args()
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    for (name, toml) in scenes() {
        let scene = LoadedScene::load(&toml).unwrap_or_else(|e| panic!("{}: {e}", toml.display()));
        let view = scene.data.view();
        let camera = scene.camera(WIDTH, HEIGHT);
        let (_, path, _) = scene.path_settings().unwrap();
        let integrator = Integrator::PathMis;
        let strategy = integrator.path_strategy().unwrap();
        let sampling = Sampling::new(SamplerKind::ZSobol, 7, SPP, WIDTH, HEIGHT);
        // `batched`: the segments traced as packets, or `None` for the one-path loop.
        // The film's SPP samples per pixel in calls of `per_call` (consecutive ranges, as the
        // passes of a progressive render call them).
        let film_in_calls = |batched: Option<u32>, per_call: u32| {
            let mut sum = 0.0f32;
            for y in 0..HEIGHT {
                for x in 0..WIDTH {
                    let mut stats = PixelStats::default();
                    for first in (0..SPP).step_by(per_call as usize) {
                        stats = if let Some(packet_segments) = batched {
                            render_pixel_batched(
                                &strategy,
                                &view,
                                &camera,
                                &path,
                                &sampling,
                                x,
                                y,
                                first,
                                per_call,
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
                                per_call,
                                stats,
                                None,
                                &mut NoSplats,
                            )
                        };
                    }
                    sum += stats.sum.x;
                }
            }
            sum
        };
        // The same calls row by row ([`render_row`]: a call of fewer samples than
        // `MIN_LANES` fills its lanes with neighbouring pixels' samples).
        let rows_in_calls = |per_call: u32| {
            let mut sum = 0.0f32;
            for y in 0..HEIGHT {
                let mut stats = vec![PixelStats::default(); WIDTH as usize];
                for first in (0..SPP).step_by(per_call as usize) {
                    render_row(
                        integrator,
                        &view,
                        &camera,
                        &path,
                        &sampling,
                        (0, y),
                        first,
                        per_call,
                        &mut stats,
                        None,
                        &mut NoSplats,
                    );
                }
                for s in &stats {
                    sum += s.sum.x;
                }
            }
            sum
        };
        let film = |batched: Option<u32>| film_in_calls(batched, SPP);
        let runs = [
            ("scalar", None),
            ("batched", Some(PACKET_SEGMENTS)),
            ("batched-packets-1", Some(1)),
            ("batched-packets-2", Some(2)),
        ];
        let expected = film(None).to_bits();
        for (what, batched) in runs {
            assert_eq!(film(batched).to_bits(), expected, "{name} {what}");
        }
        let mut group = c.benchmark_group(format!("film/{name}"));
        group.throughput(Throughput::Elements(u64::from(WIDTH * HEIGHT * SPP)));
        for (what, batched) in runs {
            group.bench_function(what, |b| b.iter(|| black_box(film(batched))));
        }
        group.finish();
        // Calls of fewer samples than a batch holds (a progressive view's passes, 1 spp
        // previews): the batched driver's lanes run part empty.
        let mut group = c.benchmark_group(format!("calls/{name}"));
        group.throughput(Throughput::Elements(u64::from(WIDTH * HEIGHT * SPP)));
        for per_call in [1, 2, 4] {
            for (what, batched) in [("scalar", None), ("batched", Some(PACKET_SEGMENTS))] {
                assert_eq!(
                    film_in_calls(batched, per_call).to_bits(),
                    expected,
                    "{name} {what} in calls of {per_call}"
                );
                group.bench_function(format!("{what}-{per_call}"), |b| {
                    b.iter(|| black_box(film_in_calls(batched, per_call)))
                });
            }
            assert_eq!(
                rows_in_calls(per_call).to_bits(),
                expected,
                "{name} rows in calls of {per_call}"
            );
            group.bench_function(format!("rows-{per_call}"), |b| {
                b.iter(|| black_box(rows_in_calls(per_call)))
            });
        }
        group.finish();
    }
    c.final_summary();
}
