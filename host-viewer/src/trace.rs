//! The path-traced view's CPU side: a worker thread that drives host-cli's
//! [`Progressive`] renderer (rayon tiles, passes of samples) for the camera and integrator the
//! window asks for, and hands each finished pass to the window as a [`TraceFrame`].
//!
//! The worker never touches wgpu or the window: the event loop only copies the latest frame
//! into a texture. A camera or integrator change bumps a generation counter that the renderer
//! checks before every tile, so a pass for an old view is dropped within one tile; the
//! accumulation then restarts with a one-sample preview at a quarter of the pixels
//! ([`Progressive::preview`], every 2×2 block; coarser blocks when that is too slow for
//! [`PREVIEW_SECONDS`]) before the full-resolution passes. A preview in flight is finished
//! (it is what a moving view shows) and the next one starts from the newest camera.
//!
//! Because the passes are [`Progressive::render_pass`] calls, the mean of a frame at N spp is
//! bit for bit the image `ember render` writes at N spp with the same camera, seed and
//! integrator (`tests/progressive.rs` checks it).

use crate::camera::ViewCamera;
use ember_cli::image::Image;
use ember_cli::render::{Progressive, RenderSettings, Shard};
use ember_cli::LoadedScene;
use ember_kernel::integrator::{Integrator, MisHeuristic, PathSettings};
use ember_kernel::Rgb;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Side of the blocks of the moving-camera preview: one sample per 2×2 block, more when a
/// preview takes longer than [`PREVIEW_SECONDS`] (up to [`MAX_PREVIEW_BLOCK`]).
pub const PREVIEW_BLOCK: u32 = 2;
pub const MAX_PREVIEW_BLOCK: u32 = 16;

/// A preview should take at most this long, so that a moving view shows ~15 frames a second:
/// slower ones double the block side of the next, faster than a quarter of it halve it.
pub const PREVIEW_SECONDS: f64 = 1.0 / 15.0;

/// A pass aims at this wall time, so the view updates a few times a second once the camera is
/// still (the first pass is always one sample).
pub const TARGET_PASS_SECONDS: f64 = 0.25;

/// At most this many samples per pixel in one pass.
pub const MAX_PASS_SPP: u32 = 1024;

/// The generation of the view a worker starts with (the camera and integrator given to
/// [`TraceWorker::start`]).
pub const FIRST_GENERATION: u64 = 1;

/// Short name of an integrator, as `--integrator` spells it.
#[must_use]
pub fn integrator_name(i: Integrator) -> &'static str {
    ember_cli::bench::integrator_name(i)
}

/// The next integrator of the cycle implicit → explicit → mis → lighttracer → bdpt →
/// implicit (BDPT with the balance heuristic goes to implicit too).
#[must_use]
pub fn next_integrator(i: Integrator) -> Integrator {
    match i {
        Integrator::PathImplicit => Integrator::PathExplicit,
        Integrator::PathExplicit => Integrator::PathMis,
        Integrator::PathMis => Integrator::LightTracing,
        Integrator::LightTracing => Integrator::Bdpt(MisHeuristic::Power),
        Integrator::Bdpt(_) => Integrator::PathImplicit,
    }
}

/// Relative standard error of a pixel's mean: the square root of the variance of the mean over
/// the mean, both averaged over the three channels. −1 where it is undefined (fewer than two
/// samples, or a black pixel).
#[must_use]
pub fn relative_error(mean: Rgb, variance_of_mean: Rgb, spp: u32) -> f32 {
    let m = (mean.x + mean.y + mean.z) / 3.0;
    let v = (variance_of_mean.x + variance_of_mean.y + variance_of_mean.z) / 3.0;
    if spp < 2 || m.is_nan() || m <= 0.0 || !v.is_finite() {
        return -1.0;
    }
    v.max(0.0).sqrt() / m
}

/// What the worker renders, besides the camera and integrator the window chooses.
#[derive(Clone, Debug)]
pub struct TraceSetup {
    pub scene: Arc<LoadedScene>,
    pub width: u32,
    pub height: u32,
    pub path: PathSettings,
    pub seed: u64,
    /// The sample sequence (ZSobol's is laid out for `target_spp`).
    pub sampler: ember_kernel::sampler::SamplerKind,
    /// Rendering threads (rayon); 0 is one per core.
    pub threads: usize,
    pub tile: u32,
    /// Rendering stops at this many samples per pixel.
    pub target_spp: u32,
}

/// One image for the window: a preview or the accumulation after a pass.
#[derive(Clone, Debug)]
pub struct TraceFrame {
    /// The view request it belongs to (see [`TraceWorker::request`]).
    pub generation: u64,
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at the top: linear mean RGB (exactly `ember render`'s pixel at `spp`
    /// samples) and the [`relative_error`] in the fourth channel.
    pub rgba: Vec<[f32; 4]>,
    /// Samples per pixel in the image; 0 for a preview.
    pub spp: u32,
    /// Side of the blocks of a preview (one sample each); 1 for an accumulation.
    pub block: u32,
    pub target_spp: u32,
    pub integrator: Integrator,
    pub camera: ViewCamera,
    /// Samples per second of the passes so far (0 for a preview).
    pub samples_per_second: f64,
    /// Wall time since the accumulation (re)started.
    pub elapsed: Duration,
    /// Samples that came out NaN or infinite (counted as 0, as `ember render` does).
    pub invalid_samples: u64,
}

impl TraceFrame {
    #[must_use]
    pub fn is_preview(&self) -> bool {
        self.spp == 0
    }

    /// The mean radiance as an image (what `ember render` writes at `spp` samples).
    #[must_use]
    pub fn image(&self) -> Image {
        Image {
            width: self.width,
            height: self.height,
            pixels: self
                .rgba
                .iter()
                .map(|p| Rgb::new(p[0], p[1], p[2]))
                .collect(),
        }
    }
}

/// The view the window wants rendered.
#[derive(Clone, Copy, Debug)]
struct Control {
    camera: ViewCamera,
    integrator: Integrator,
    generation: u64,
    active: bool,
    quit: bool,
}

#[derive(Debug)]
struct Shared {
    control: Mutex<Control>,
    wake: Condvar,
    /// Copies of the control's generation, activity and quit flag, read between tiles.
    generation: AtomicU64,
    active: AtomicBool,
    quit: AtomicBool,
    frame: Mutex<Option<TraceFrame>>,
}

impl Shared {
    fn control(&self) -> MutexGuard<'_, Control> {
        self.control
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// The rendering thread of the path-traced view. Dropping it stops the thread (as
/// [`TraceWorker::stop`] does).
pub struct TraceWorker {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for TraceWorker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TraceWorker").finish_non_exhaustive()
    }
}

impl TraceWorker {
    /// Starts the thread, idle until [`Self::set_active`]. `notify` is called (on the worker
    /// thread) after each new frame, e.g. to wake the event loop.
    ///
    /// # Panics
    /// If the thread cannot be spawned.
    pub fn start(
        setup: TraceSetup,
        camera: ViewCamera,
        integrator: Integrator,
        notify: Box<dyn Fn() + Send>,
    ) -> Self {
        let shared = Arc::new(Shared {
            control: Mutex::new(Control {
                camera,
                integrator,
                generation: FIRST_GENERATION,
                active: false,
                quit: false,
            }),
            wake: Condvar::new(),
            generation: AtomicU64::new(FIRST_GENERATION),
            active: AtomicBool::new(false),
            quit: AtomicBool::new(false),
            frame: Mutex::new(None),
        });
        let worker_shared = shared.clone();
        let thread = std::thread::Builder::new()
            .name("ember-trace".into())
            .spawn(move || run(&setup, &worker_shared, &*notify))
            .expect("cannot spawn the rendering thread");
        Self {
            shared,
            thread: Some(thread),
        }
    }

    /// Asks for this camera and integrator. If either differs from the current request, the
    /// generation goes up, work in flight is abandoned at the next tile and the accumulation
    /// restarts. Returns the generation of the request.
    pub fn request(&self, camera: ViewCamera, integrator: Integrator) -> u64 {
        let mut c = self.shared.control();
        if c.camera != camera || c.integrator != integrator {
            c.camera = camera;
            c.integrator = integrator;
            c.generation += 1;
            self.shared
                .generation
                .store(c.generation, Ordering::Relaxed);
            self.shared.wake.notify_all();
        }
        c.generation
    }

    /// Renders (true) or pauses (false; the pass in flight is abandoned, the accumulation
    /// kept).
    pub fn set_active(&self, active: bool) {
        let mut c = self.shared.control();
        c.active = active;
        self.shared.active.store(active, Ordering::Relaxed);
        self.shared.wake.notify_all();
    }

    /// The newest frame not taken yet.
    pub fn take_frame(&self) -> Option<TraceFrame> {
        self.shared
            .frame
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .take()
    }

    /// Stops the thread (abandoning the tile loop at the next tile) and waits for it; returns
    /// how long that took.
    pub fn stop(mut self) -> Duration {
        self.shutdown()
    }

    fn shutdown(&mut self) -> Duration {
        let start = Instant::now();
        {
            let mut c = self.shared.control();
            c.quit = true;
            self.shared.quit.store(true, Ordering::Relaxed);
            self.shared.wake.notify_all();
        }
        if let Some(t) = self.thread.take() {
            // A panic on the worker has already been printed; there is nothing more to do.
            let _ = t.join();
        }
        start.elapsed()
    }
}

impl Drop for TraceWorker {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.shutdown();
        }
    }
}

/// Samples of the next pass: one at first, then as many as fit in [`TARGET_PASS_SECONDS`] at
/// the rate of the passes so far, never past the target.
fn pass_count(p: &Progressive, target: u32) -> u32 {
    let remaining = target.saturating_sub(p.spp());
    if p.spp() == 0 {
        return remaining.min(1);
    }
    let per_spp = p.seconds() / f64::from(p.spp());
    let fit = if per_spp > 0.0 {
        (TARGET_PASS_SECONDS / per_spp)
            .floor()
            .min(f64::from(MAX_PASS_SPP)) as u32
    } else {
        MAX_PASS_SPP
    };
    fit.clamp(1, MAX_PASS_SPP).min(remaining)
}

fn run(setup: &TraceSetup, shared: &Shared, notify: &dyn Fn()) {
    let view = setup.scene.data.view();
    let (w, h) = (setup.width, setup.height);
    let settings = |integrator| RenderSettings {
        integrator,
        path: setup.path,
        spp: setup.target_spp,
        seed: setup.seed,
        sampler: setup.sampler,
        tile: setup.tile.max(1),
        threads: setup.threads,
        progress: false,
        shard: Shard::WHOLE,
        strategies: None,
    };
    let mut progressive: Option<Progressive> = None;
    let mut current = 0u64;
    let mut started = Instant::now();
    let mut block = PREVIEW_BLOCK;
    loop {
        let request = {
            let mut c = shared.control();
            loop {
                if c.quit {
                    return;
                }
                let fresh = c.generation != current;
                let unfinished = progressive
                    .as_ref()
                    .is_some_and(|p| p.spp() < setup.target_spp);
                if c.active && (fresh || unfinished) {
                    break;
                }
                c = shared
                    .wake
                    .wait(c)
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
            }
            *c
        };
        let generation = request.generation;
        let stop = || {
            shared.generation.load(Ordering::Relaxed) != generation
                || !shared.active.load(Ordering::Relaxed)
                || shared.quit.load(Ordering::Relaxed)
        };
        let s = settings(request.integrator);
        if generation != current {
            let camera = request.camera.kernel_camera(w, h);
            match &mut progressive {
                Some(p) => p.restart(camera, &s),
                None => progressive = Some(Progressive::new(camera, &s)),
            }
            current = generation;
            started = Instant::now();
            let p = progressive.as_ref().expect("created above");
            // A preview is finished even when the camera moves on meanwhile: it is the frame
            // that lets the view follow the mouse (abandoning it for every mouse event would
            // show nothing until the mouse stops).
            let paused =
                || !shared.active.load(Ordering::Relaxed) || shared.quit.load(Ordering::Relaxed);
            let t0 = Instant::now();
            if let Some(image) = p.preview(&view, block, &paused) {
                let seconds = t0.elapsed().as_secs_f64();
                let rgba = image.pixels.iter().map(|c| [c.x, c.y, c.z, -1.0]).collect();
                let mut f = frame(&request, setup, rgba, 0, 0.0, started, 0);
                f.block = block;
                publish(shared, notify, f);
                if seconds > PREVIEW_SECONDS && block < MAX_PREVIEW_BLOCK {
                    block *= 2;
                } else if seconds < PREVIEW_SECONDS / 4.0 && block > PREVIEW_BLOCK {
                    block /= 2;
                }
            }
            continue;
        }
        let p = progressive.as_mut().expect("a generation was started");
        let count = pass_count(p, setup.target_spp);
        if count == 0 || !p.render_pass(&view, count, &stop, &|_| {}) {
            continue;
        }
        let r = p.snapshot();
        let rgba = r
            .image
            .pixels
            .iter()
            .zip(&r.variance.pixels)
            .map(|(m, v)| [m.x, m.y, m.z, relative_error(*m, *v, r.spp)])
            .collect();
        let rate = p.pixels() as f64 * f64::from(r.spp) / r.seconds.max(1e-9);
        publish(
            shared,
            notify,
            frame(
                &request,
                setup,
                rgba,
                r.spp,
                rate,
                started,
                r.invalid_samples,
            ),
        );
    }
}

fn frame(
    request: &Control,
    setup: &TraceSetup,
    rgba: Vec<[f32; 4]>,
    spp: u32,
    samples_per_second: f64,
    started: Instant,
    invalid_samples: u64,
) -> TraceFrame {
    TraceFrame {
        generation: request.generation,
        width: setup.width,
        height: setup.height,
        rgba,
        spp,
        block: 1,
        target_spp: setup.target_spp,
        integrator: request.integrator,
        camera: request.camera,
        samples_per_second,
        elapsed: started.elapsed(),
        invalid_samples,
    }
}

fn publish(shared: &Shared, notify: &dyn Fn(), frame: TraceFrame) {
    // An accumulation of a view that is no longer wanted is not shown; a preview is (it is
    // the newest look at a moving camera).
    if !frame.is_preview() && shared.generation.load(Ordering::Relaxed) != frame.generation {
        return;
    }
    *shared
        .frame
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(frame);
    notify();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrators_cycle_through_every_integrator() {
        let mut i = Integrator::PathImplicit;
        let mut seen = Vec::new();
        for _ in 0..5 {
            seen.push(integrator_name(i));
            i = next_integrator(i);
        }
        assert_eq!(i, Integrator::PathImplicit);
        assert_eq!(seen, ["implicit", "explicit", "mis", "lighttracer", "bdpt"]);
        let balance = Integrator::Bdpt(MisHeuristic::Balance);
        assert_eq!(next_integrator(balance), Integrator::PathImplicit);
    }

    #[test]
    fn relative_error_is_the_standard_error_over_the_mean() {
        let e = relative_error(Rgb::splat(0.5), Rgb::splat(0.0025), 16);
        assert!((e - 0.1).abs() < 1e-6, "{e}");
        assert_eq!(relative_error(Rgb::splat(0.5), Rgb::splat(0.01), 1), -1.0);
        assert_eq!(relative_error(Rgb::ZERO, Rgb::ZERO, 16), -1.0);
        assert_eq!(relative_error(Rgb::splat(1.0), Rgb::ZERO, 4), 0.0);
    }
}
