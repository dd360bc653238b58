//! The path-traced view's worker without a window: the frames it hands to the window are
//! `ember render`'s image (`ember_cli::render::render`) bit for bit at their spp, after camera
//! and integrator changes too, and it stops promptly.

use ember_cli::render::{render, RenderSettings, Shard};
use ember_cli::LoadedScene;
use ember_kernel::integrator::Integrator;
use ember_viewer::trace::{TraceFrame, TraceSetup, TraceWorker, FIRST_GENERATION};
use ember_viewer::ViewCamera;
use std::path::Path;
use std::sync::mpsc;
use std::sync::Arc;
use std::time::{Duration, Instant};

const W: u32 = 48;
const H: u32 = 36;

fn cornell() -> Arc<LoadedScene> {
    let toml = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/cornell-box/cornell_box.toml");
    Arc::new(LoadedScene::load(&toml).expect("data/cornell-box/cornell_box.toml"))
}

fn setup(scene: &Arc<LoadedScene>, target_spp: u32) -> TraceSetup {
    let (_, path, _) = scene.path_settings().unwrap();
    TraceSetup {
        scene: scene.clone(),
        width: W,
        height: H,
        path,
        seed: 99,
        sampler: ember_kernel::sampler::SamplerKind::Independent,
        threads: 2,
        tile: 16,
        target_spp,
    }
}

fn reference(s: &TraceSetup, camera: &ViewCamera, integrator: Integrator, spp: u32) -> Vec<u32> {
    let settings = RenderSettings {
        integrator,
        path: s.path,
        spp,
        seed: s.seed,
        sampler: s.sampler,
        tile: 16,
        threads: 2,
        progress: false,
        shard: Shard::WHOLE,
        strategies: None,
    };
    let r = render(&s.scene.data.view(), &camera.kernel_camera(W, H), &settings);
    r.image
        .pixels
        .iter()
        .flat_map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

fn bits(f: &TraceFrame) -> Vec<u32> {
    f.image()
        .pixels
        .iter()
        .flat_map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

/// The first frame of `generation` with at least `spp` samples (0: the first frame at all).
fn frame_at(
    worker: &TraceWorker,
    rx: &mpsc::Receiver<()>,
    generation: u64,
    spp: u32,
) -> TraceFrame {
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut seen = Vec::new();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        assert!(
            !left.is_zero(),
            "no frame at {spp} spp within 60 s; saw {seen:?}"
        );
        if rx.recv_timeout(left).is_err() {
            continue;
        }
        let Some(f) = worker.take_frame() else {
            continue;
        };
        if f.generation != generation {
            continue;
        }
        seen.push(f.spp);
        if f.spp >= spp {
            return f;
        }
    }
}

#[test]
fn frames_are_ember_render_bit_for_bit_across_restarts() {
    let scene = cornell();
    // 21 spp: not a multiple of any pass size the worker picks after the first pass of 1.
    let s = setup(&scene, 21);
    let camera = ViewCamera::from_desc(&scene.file.camera);
    // The scene camera through the view is the scene camera of `ember render`.
    assert_eq!(camera.kernel_camera(W, H), scene.camera(W, H));
    let (tx, rx) = mpsc::channel();
    let worker = TraceWorker::start(
        s.clone(),
        camera,
        Integrator::PathExplicit,
        Box::new(move || {
            let _ = tx.send(());
        }),
    );
    // Idle until activated.
    assert!(
        rx.recv_timeout(Duration::from_millis(300)).is_err(),
        "an inactive worker renders nothing"
    );
    worker.set_active(true);
    let last = frame_at(&worker, &rx, FIRST_GENERATION, 21);
    assert_eq!((last.spp, last.target_spp), (21, 21));
    assert_eq!(
        bits(&last),
        reference(&s, &camera, Integrator::PathExplicit, 21),
        "scene camera, explicit, 21 spp"
    );
    assert!(last.samples_per_second > 0.0);
    // Done: nothing more comes.
    assert!(rx.recv_timeout(Duration::from_millis(300)).is_err());

    // A camera move restarts the accumulation: a preview first, then passes up to 21 again.
    let mut moved = camera;
    moved.orbit(0.3, 0.1);
    let g = worker.request(moved, Integrator::PathExplicit);
    assert_eq!(g, FIRST_GENERATION + 1);
    let first = frame_at(&worker, &rx, g, 0);
    // The preview (0 spp), unless the first pass overwrote it before it was taken.
    assert!(
        first.spp <= 1,
        "the accumulation restarts: {} spp",
        first.spp
    );
    let last = frame_at(&worker, &rx, g, 21);
    assert_eq!(
        bits(&last),
        reference(&s, &moved, Integrator::PathExplicit, 21),
        "moved camera"
    );
    // Another integrator, then the scene camera again.
    let g = worker.request(moved, Integrator::PathMis);
    let last = frame_at(&worker, &rx, g, 21);
    assert_eq!(last.integrator, Integrator::PathMis);
    assert_eq!(
        bits(&last),
        reference(&s, &moved, Integrator::PathMis, 21),
        "MIS"
    );
    let g = worker.request(camera, Integrator::PathExplicit);
    let last = frame_at(&worker, &rx, g, 21);
    assert_eq!(
        bits(&last),
        reference(&s, &camera, Integrator::PathExplicit, 21),
        "back to the scene camera"
    );
    // The same request again changes nothing.
    assert_eq!(worker.request(camera, Integrator::PathExplicit), g);
    worker.stop();
}

/// With the ZSobol sampler the view's accumulation, whatever its passes, is `ember render
/// --sampler zsobol --spp N` at the target N (the samples are laid out for N up front).
#[test]
fn zsobol_frames_are_ember_render_bit_for_bit() {
    let scene = cornell();
    let s = TraceSetup {
        sampler: ember_kernel::sampler::SamplerKind::ZSobol,
        ..setup(&scene, 21)
    };
    let camera = ViewCamera::from_desc(&scene.file.camera);
    let (tx, rx) = mpsc::channel();
    let worker = TraceWorker::start(
        s.clone(),
        camera,
        Integrator::PathMis,
        Box::new(move || {
            let _ = tx.send(());
        }),
    );
    worker.set_active(true);
    let last = frame_at(&worker, &rx, FIRST_GENERATION, 21);
    let zsobol = reference(&s, &camera, Integrator::PathMis, 21);
    assert_eq!(bits(&last), zsobol, "ZSobol, MIS, 21 spp");
    let independent = TraceSetup {
        sampler: ember_kernel::sampler::SamplerKind::Independent,
        ..s.clone()
    };
    assert_ne!(
        zsobol,
        reference(&independent, &camera, Integrator::PathMis, 21)
    );
    worker.stop();
}

#[test]
fn a_stop_in_the_middle_of_a_long_render_is_prompt() {
    let scene = cornell();
    let mut s = setup(&scene, 1_000_000);
    // Small tiles: a stop waits for the tiles in flight, a few ms each here.
    s.tile = 4;
    let camera = ViewCamera::from_desc(&scene.file.camera);
    let (tx, rx) = mpsc::channel();
    let worker = TraceWorker::start(
        s,
        camera,
        Integrator::PathMis,
        Box::new(move || {
            let _ = tx.send(());
        }),
    );
    worker.set_active(true);
    // Let it reach passes of many samples (a quarter of a second each).
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        assert!(Instant::now() < deadline, "no pass of 8+ spp within 60 s");
        let _ = rx.recv_timeout(Duration::from_secs(1));
        if worker.take_frame().is_some_and(|f| f.spp >= 8) {
            break;
        }
    }
    std::thread::sleep(Duration::from_millis(100));
    let took = worker.stop();
    eprintln!("worker stopped in {:.2} ms", took.as_secs_f64() * 1e3);
    // One 4x4 tile per thread at the pass size in flight (~0.25 s of work over all 108 tiles)
    // is far below this, even on a loaded machine.
    assert!(took < Duration::from_millis(200), "stopping took {took:?}");
}
