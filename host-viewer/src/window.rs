//! The interactive viewer (winit 0.30 `ApplicationHandler`): the baked view (the headless
//! pipeline drawn into a window surface) and the progressive path-traced view, from one camera.
//!
//! Controls, both views: left-drag orbits around the look-at point, the wheel zooms; W/A/S/D
//! fly forward/left/back/right, Q/E down/up (Shift: 4× faster), right-drag looks around; R
//! resets to the scene camera, F toggles false colour (baked: log luminance; path-traced: the
//! relative standard error), Esc quits. `P` switches between the baked and the path-traced
//! view of a `gi` scene. Path-traced view only: `+`/`=`/`]` and `-`/`[` change the exposure by
//! half a stop (`0` resets it), `I` cycles the integrator (implicit → explicit → mis), `O`
//! writes the accumulation as EXR + PNG.
//!
//! The event loop never renders a pass: the [`TraceWorker`] thread (and its rayon pool) does,
//! and wakes the loop with a user event when a frame is ready; the loop copies it into a
//! texture and presents it. The window's inner size is the film's and it is not resizable, so
//! the path-traced view maps film pixels 1:1 onto window pixels (a screenshot of the window is
//! the image); if a window manager resizes it anyway, the film is scaled to fit.

use crate::camera::ViewCamera;
use crate::display::{DisplayParams, TraceDisplay};
use crate::gpu::{self, MeshRenderer};
use crate::trace::{
    integrator_name, next_integrator, TraceFrame, TraceSetup, TraceWorker, FIRST_GENERATION,
};
use crate::ViewerError;
use ember_cli::bake::BakedMesh;
use ember_cli::scene_file::CameraDesc;
use ember_kernel::integrator::Integrator;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// The path-traced view's settings.
#[derive(Clone, Debug)]
pub struct TraceOptions {
    pub setup: TraceSetup,
    pub integrator: Integrator,
    /// Where `O` writes the EXR (the PNG beside it); `None`: `<stem>_<N>spp.exr` beside the
    /// scene file.
    pub output: Option<PathBuf>,
    /// The scene file, for the default output name.
    pub scene_path: PathBuf,
    /// Initial exposure in stops.
    pub exposure_stops: f32,
}

/// What the window shows at the start.
#[derive(Clone, Debug)]
pub struct WindowOptions {
    /// Shown in the title, e.g. the scene's file name.
    pub name: String,
    /// Inner size in physical pixels (the film size).
    pub width: u32,
    pub height: u32,
    pub false_colour: bool,
    /// The path-traced view, if there is one.
    pub trace: Option<TraceOptions>,
    /// Fewer messages.
    pub quiet: bool,
}

/// Half a stop per key press.
const EXPOSURE_STEP: f32 = 0.5;

/// A frame presented this long after the last camera input still counts as "while moving".
const MOVING_TAIL: Duration = Duration::from_millis(100);

#[derive(Debug)]
enum UserEvent {
    /// The worker has a new frame.
    Frame,
}

/// Opens the window and runs until it is closed. With a mesh, the window starts in the baked
/// view (`P` switches to the path-traced one if `options.trace` is set); without, in the
/// path-traced view.
///
/// # Errors
/// No display ([`ViewerError::Display`]), no adapter, a GPU error; neither a mesh nor a
/// path-traced view ([`ViewerError::Input`]).
pub fn run(
    mesh: Option<BakedMesh>,
    camera: &CameraDesc,
    options: WindowOptions,
) -> Result<(), ViewerError> {
    if let Some(m) = &mesh {
        gpu::validate_mesh(m)?;
    }
    if mesh.is_none() && options.trace.is_none() {
        return Err(ViewerError::Input(ember_cli::Error::new(
            "nothing to show: neither a baked mesh nor a path-traced view",
        )));
    }
    let scene_camera = ViewCamera::from_desc(camera);
    if !scene_camera.is_valid() {
        return Err(ViewerError::Input(ember_cli::Error::new(
            "the scene camera does not define a view",
        )));
    }
    let event_loop = EventLoop::<UserEvent>::with_user_event()
        .build()
        .map_err(|e| {
            ViewerError::Display(format!(
                "cannot open a window ({e}); is there a display (DISPLAY or WAYLAND_DISPLAY)? \
             Use --headless, or run under xvfb-run"
            ))
        })?;
    let instance = gpu::instance(Some(Box::new(event_loop.owned_display_handle())));
    let scale = mesh.as_ref().map_or_else(
        || {
            options
                .trace
                .as_ref()
                .map_or(1.0, |t| scene_scale_of(&t.setup))
        },
        scene_scale,
    );
    let worker = options.trace.as_ref().map(|t| {
        let proxy = event_loop.create_proxy();
        TraceWorker::start(
            t.setup.clone(),
            scene_camera,
            t.integrator,
            Box::new(move || {
                // The loop is gone only while the program ends.
                let _ = proxy.send_event(UserEvent::Frame);
            }),
        )
    });
    let mode = if mesh.is_some() {
        Mode::Baked
    } else {
        Mode::Traced
    };
    let mut app = App {
        instance,
        mesh,
        options: options.clone(),
        scene_camera,
        camera: scene_camera,
        false_colour: options.false_colour,
        error_view: false,
        exposure_stops: options.trace.as_ref().map_or(0.0, |t| t.exposure_stops),
        integrator: options
            .trace
            .as_ref()
            .map_or(Integrator::PathMis, |t| t.integrator),
        mode,
        worker,
        shown: None,
        fresh: false,
        requested: FIRST_GENERATION,
        stats: Stats::default(),
        saves: Vec::new(),
        scale,
        state: None,
        error: None,
        keys: HashSet::new(),
        left_drag: false,
        right_drag: false,
        cursor: None,
        last_frame: None,
        frame_ms: None,
        exit_requested: None,
    };
    let result = event_loop
        .run_app(&mut app)
        .map_err(|e| ViewerError::Display(format!("window event loop failed: {e}")));
    let exit_requested = app.exit_requested.unwrap_or_else(Instant::now);
    let stopped = app.worker.take().map(|w| {
        w.stop();
        exit_requested.elapsed()
    });
    for s in app.saves.drain(..) {
        let _ = s.join();
    }
    if !options.quiet && app.error.is_none() {
        app.stats.finish();
        if let Some(line) = app.stats.summary(stopped) {
            eprintln!("ember-view: {line}");
        }
    }
    result?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// Diagonal of the mesh's bounding box: the fly speed is a fraction of it per second.
fn scene_scale(mesh: &BakedMesh) -> f32 {
    bounding_diagonal(mesh.positions.iter().copied())
}

fn scene_scale_of(setup: &TraceSetup) -> f32 {
    bounding_diagonal(setup.scene.data.positions.iter().map(|p| p.to_array()))
}

fn bounding_diagonal(points: impl Iterator<Item = [f32; 3]>) -> f32 {
    let mut lo = glam::Vec3::splat(f32::INFINITY);
    let mut hi = glam::Vec3::splat(f32::NEG_INFINITY);
    for p in points {
        let p = glam::Vec3::from(p);
        if p.is_finite() {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    let d = (hi - lo).length();
    if d.is_finite() && d > 0.0 {
        d
    } else {
        1.0
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Baked,
    Traced,
}

/// Responsiveness of the path-traced view, printed when the window closes.
#[derive(Debug, Default)]
struct Stats {
    /// Camera changes (generation, time) not yet on screen.
    pending: std::collections::VecDeque<(u64, Instant)>,
    /// Camera change → first new frame of that view or a later one, in seconds.
    latencies: Vec<f64>,
    /// Current run of camera inputs (first, last).
    moving: Option<(Instant, Instant)>,
    moving_seconds: f64,
    moving_frames: u64,
    /// Block sides of the previews shown.
    preview_blocks: Vec<u32>,
    /// Samples per second and spp of the newest completed pass.
    rate: Option<(f64, u32)>,
}

impl Stats {
    fn camera_moved(&mut self, generation: u64, now: Instant) {
        self.pending.push_back((generation, now));
        self.moving = match self.moving {
            Some((start, last)) if now.duration_since(last) < MOVING_TAIL => Some((start, now)),
            Some((start, last)) => {
                self.moving_seconds += (last - start + MOVING_TAIL).as_secs_f64();
                Some((now, now))
            }
            None => Some((now, now)),
        };
    }

    fn frame_presented(&mut self, now: Instant, frame: &TraceFrame) {
        while let Some(&(g, t)) = self.pending.front() {
            if g > frame.generation {
                break;
            }
            self.latencies.push(now.duration_since(t).as_secs_f64());
            self.pending.pop_front();
        }
        if let Some((_, last)) = self.moving {
            if now.duration_since(last) <= MOVING_TAIL {
                self.moving_frames += 1;
            }
        }
        if frame.is_preview() {
            self.preview_blocks.push(frame.block);
        } else {
            self.rate = Some((frame.samples_per_second, frame.spp));
        }
    }

    fn finish(&mut self) {
        if let Some((start, last)) = self.moving.take() {
            self.moving_seconds += (last - start + MOVING_TAIL).as_secs_f64();
        }
    }

    fn summary(&self, stopped: Option<Duration>) -> Option<String> {
        let stopped = stopped?;
        let mut parts = Vec::new();
        if !self.latencies.is_empty() {
            let mut l = self.latencies.clone();
            l.sort_by(f64::total_cmp);
            parts.push(format!(
                "{} camera changes, each on screen (first frame of that view or a later one) after {:.0} ms median ({:.0} ms max), {:.1} new frames/s while moving",
                l.len(),
                1e3 * l[l.len() / 2],
                1e3 * l[l.len() - 1],
                self.moving_frames as f64 / self.moving_seconds.max(1e-9)
            ));
        }
        if !self.preview_blocks.is_empty() {
            let mut b = self.preview_blocks.clone();
            b.sort_unstable();
            parts.push(format!(
                "{} previews of one sample per {}x{} to {}x{} pixels (median {}x{})",
                b.len(),
                b[0],
                b[0],
                b[b.len() - 1],
                b[b.len() - 1],
                b[b.len() / 2],
                b[b.len() / 2]
            ));
        }
        if let Some((rate, spp)) = self.rate {
            parts.push(format!(
                "path tracing {:.3} M samples/s (accumulation at {spp} spp)",
                rate / 1e6
            ));
        }
        parts.push(format!(
            "rendering threads stopped {:.1} ms after the window was closed",
            stopped.as_secs_f64() * 1e3
        ));
        Some(parts.join("; "))
    }
}

struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    config: wgpu::SurfaceConfiguration,
    /// The sRGB format the pipelines render with (the surface format or its sRGB view).
    view_format: wgpu::TextureFormat,
    renderer: Option<MeshRenderer>,
    depth: wgpu::TextureView,
    display: Option<TraceDisplay>,
    adapter: wgpu::AdapterInfo,
}

struct App {
    instance: wgpu::Instance,
    mesh: Option<BakedMesh>,
    options: WindowOptions,
    scene_camera: ViewCamera,
    camera: ViewCamera,
    false_colour: bool,
    error_view: bool,
    exposure_stops: f32,
    integrator: Integrator,
    mode: Mode,
    worker: Option<TraceWorker>,
    /// The frame in the film texture.
    shown: Option<TraceFrame>,
    /// Whether `shown` was uploaded since the last present.
    fresh: bool,
    /// Generation of the latest view request.
    requested: u64,
    stats: Stats,
    saves: Vec<JoinHandle<()>>,
    scale: f32,
    state: Option<Gfx>,
    error: Option<ViewerError>,
    keys: HashSet<KeyCode>,
    left_drag: bool,
    right_drag: bool,
    cursor: Option<PhysicalPosition<f64>>,
    last_frame: Option<Instant>,
    frame_ms: Option<f64>,
    exit_requested: Option<Instant>,
}

const MOVE_KEYS: [KeyCode; 6] = [
    KeyCode::KeyW,
    KeyCode::KeyA,
    KeyCode::KeyS,
    KeyCode::KeyD,
    KeyCode::KeyQ,
    KeyCode::KeyE,
];

impl App {
    fn init(&mut self, event_loop: &ActiveEventLoop) -> Result<Gfx, ViewerError> {
        let attributes = Window::default_attributes()
            .with_title(format!("ember-view — {}", self.options.name))
            .with_inner_size(PhysicalSize::new(self.options.width, self.options.height))
            .with_resizable(false);
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| ViewerError::Display(format!("cannot create a window: {e}")))?,
        );
        let surface = match self.instance.create_surface(window.clone()) {
            Ok(s) => s,
            Err(e) => {
                // Without any adapter there is no backend to make a surface with: say that,
                // and what to install, rather than the surface error.
                pollster::block_on(gpu::request_adapter(&self.instance, None))?;
                return Err(ViewerError::Gpu(format!(
                    "cannot create a window surface: {e}"
                )));
            }
        };
        let adapter = pollster::block_on(gpu::request_adapter(&self.instance, Some(&surface)))?;
        let info = adapter.get_info();
        if !self.options.quiet {
            eprintln!("ember-view: adapter {}", gpu::describe(&info));
        }
        let (device, queue) = pollster::block_on(gpu::request_device(&adapter))?;
        device.on_uncaptured_error(Arc::new(|e| eprintln!("ember-view: GPU error: {e}")));
        let caps = surface.get_capabilities(&adapter);
        let Some(&first) = caps.formats.first() else {
            return Err(ViewerError::Gpu(format!(
                "the window surface is not supported by {}",
                info.name
            )));
        };
        // Prefer a surface format that is sRGB itself; otherwise render through an sRGB view.
        let format = caps
            .formats
            .iter()
            .copied()
            .find(wgpu::TextureFormat::is_srgb)
            .unwrap_or(first);
        let view_format = format.add_srgb_suffix();
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: wgpu::PresentMode::AutoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: if view_format == format {
                vec![]
            } else {
                vec![view_format]
            },
        };
        surface.configure(&device, &config);
        let renderer = match &self.mesh {
            Some(m) => Some(MeshRenderer::new(&device, view_format, m)?),
            None => None,
        };
        let display = match &self.options.trace {
            Some(_) => Some(TraceDisplay::new(
                &device,
                view_format,
                self.options.width,
                self.options.height,
            )?),
            None => None,
        };
        let depth = gpu::depth_view(&device, config.width, config.height);
        Ok(Gfx {
            window,
            surface,
            device,
            queue,
            config,
            view_format,
            renderer,
            depth,
            display,
            adapter: info,
        })
    }

    fn update_title(&self) {
        let Some(g) = &self.state else { return };
        let view = match self.mode {
            Mode::Baked => {
                let time = self
                    .frame_ms
                    .map_or_else(String::new, |ms| format!(" — {ms:.2} ms/frame"));
                format!(
                    "baked GI{time}{}",
                    if self.false_colour {
                        " — false colour"
                    } else {
                        ""
                    }
                )
            }
            Mode::Traced => self.trace_status(),
        };
        g.window.set_title(&format!(
            "ember-view — {} — {view} — {} ({:?})",
            self.options.name, g.adapter.name, g.adapter.backend,
        ));
    }

    /// "path tracing (mis) — 12/64 spp — 1.52 M samples/s — 3.4 s", with the exposure and the
    /// error view when they are on.
    fn trace_status(&self) -> String {
        let target = self
            .options
            .trace
            .as_ref()
            .map_or(0, |t| t.setup.target_spp);
        let (spp, state, rate, elapsed) = match &self.shown {
            Some(f) if f.generation == self.requested || f.is_preview() => (
                f.spp,
                if f.is_preview() {
                    " (preview)"
                } else if f.spp >= f.target_spp {
                    " (done)"
                } else {
                    ""
                },
                f.samples_per_second,
                f.elapsed.as_secs_f64(),
            ),
            _ => (0, " (starting)", 0.0, 0.0),
        };
        let mut s = format!(
            "path tracing ({}) — {spp}/{target} spp{state} — {:.2} M samples/s — {elapsed:.1} s",
            integrator_name(self.integrator),
            rate / 1e6
        );
        if self.exposure_stops != 0.0 {
            s.push_str(&format!(" — exposure {:+.1}", self.exposure_stops));
        }
        if self.error_view {
            s.push_str(" — relative error");
        }
        s
    }

    fn resize(&mut self, size: PhysicalSize<u32>) {
        let Some(g) = &mut self.state else { return };
        if size.width == 0 || size.height == 0 {
            return;
        }
        g.config.width = size.width;
        g.config.height = size.height;
        g.surface.configure(&g.device, &g.config);
        g.depth = gpu::depth_view(&g.device, size.width, size.height);
        g.window.request_redraw();
    }

    /// Applies the held fly keys for the time since the last frame; true if any is held.
    fn fly(&mut self) -> bool {
        let now = Instant::now();
        let dt = self
            .last_frame
            .map_or(0.0, |t| now.duration_since(t).as_secs_f32().min(0.1));
        self.last_frame = Some(now);
        let held = |k| self.keys.contains(&k);
        let axis = |plus, minus| f32::from(u8::from(held(plus))) - f32::from(u8::from(held(minus)));
        let (f, r, u) = (
            axis(KeyCode::KeyW, KeyCode::KeyS),
            axis(KeyCode::KeyD, KeyCode::KeyA),
            axis(KeyCode::KeyE, KeyCode::KeyQ),
        );
        let fast = held(KeyCode::ShiftLeft) || held(KeyCode::ShiftRight);
        let speed = 0.25 * self.scale * if fast { 4.0 } else { 1.0 } * dt;
        let any_held = MOVE_KEYS.iter().any(|&k| held(k));
        if f != 0.0 || r != 0.0 || u != 0.0 {
            self.camera.fly(f * speed, r * speed, u * speed);
            self.view_changed();
        }
        any_held
    }

    /// Tells the worker the current camera and integrator (in the path-traced view); a
    /// change restarts the accumulation.
    fn view_changed(&mut self) {
        if self.mode != Mode::Traced {
            return;
        }
        let Some(w) = &self.worker else { return };
        let generation = w.request(self.camera, self.integrator);
        if generation != self.requested {
            self.requested = generation;
            self.stats.camera_moved(generation, Instant::now());
        }
    }

    fn set_mode(&mut self, mode: Mode) {
        self.mode = mode;
        if let Some(w) = &self.worker {
            w.set_active(mode == Mode::Traced);
        }
        if mode == Mode::Traced {
            self.view_changed();
        }
        self.last_frame = None;
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        let moving = self.fly();
        let (camera, false_colour, mode) = (self.camera, self.false_colour, self.mode);
        let params = DisplayParams {
            window: (0, 0),
            exposure_stops: self.exposure_stops,
            error_view: self.error_view,
        };
        let Some(g) = &mut self.state else { return };
        let frame = match g.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f)
            | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return;
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                g.surface.configure(&g.device, &g.config);
                g.window.request_redraw();
                return;
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                self.error = Some(ViewerError::Gpu(
                    "the window surface reported a validation error".into(),
                ));
                event_loop.exit();
                return;
            }
        };
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(g.view_format),
            ..Default::default()
        });
        let mut encoder = g
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        match (mode, &g.renderer, &g.display) {
            (Mode::Traced, _, Some(display)) => {
                display.set_params(
                    &g.queue,
                    DisplayParams {
                        window: (g.config.width, g.config.height),
                        ..params
                    },
                );
                display.draw(&mut encoder, &view);
            }
            (_, Some(renderer), _) => {
                let aspect = g.config.width as f32 / g.config.height as f32;
                renderer.set_view(&g.queue, camera.view_proj(aspect), false_colour);
                renderer.draw(&mut encoder, &view, &g.depth);
            }
            _ => {}
        }
        let start = Instant::now();
        g.queue.submit([encoder.finish()]);
        if let Err(e) = g.device.poll(wgpu::PollType::wait_indefinitely()) {
            eprintln!("ember-view: waiting for the frame: {e}");
        }
        let ms = start.elapsed().as_secs_f64() * 1e3;
        g.window.pre_present_notify();
        g.queue.present(frame);
        if mode == Mode::Baked {
            // A little smoothing keeps the title readable.
            self.frame_ms = Some(self.frame_ms.map_or(ms, |old| 0.8 * old + 0.2 * ms));
        } else if self.fresh {
            self.fresh = false;
            if let Some(f) = &self.shown {
                self.stats.frame_presented(Instant::now(), f);
            }
        }
        // The title is set after the frame it describes is presented.
        self.update_title();
        if moving {
            self.request_redraw();
        } else {
            self.last_frame = None;
        }
    }

    fn request_redraw(&self) {
        if let Some(g) = &self.state {
            g.window.request_redraw();
        }
    }

    /// Takes the worker's newest frame into the film texture.
    fn frame_ready(&mut self) {
        let Some(w) = &self.worker else { return };
        let Some(frame) = w.take_frame() else { return };
        // The current view's frames, and previews of a camera on the way to it (newer than
        // what is shown) while it moves.
        let newer = self
            .shown
            .as_ref()
            .is_none_or(|s| frame.generation > s.generation);
        if frame.generation != self.requested && !(frame.is_preview() && newer) {
            return;
        }
        if let Some(g) = &self.state {
            if let Some(d) = &g.display {
                d.upload(&g.queue, &frame);
            }
        }
        self.shown = Some(frame);
        self.fresh = true;
        self.request_redraw();
    }

    /// Writes the shown accumulation as EXR + PNG (atomically, on a thread of its own).
    fn save(&mut self) {
        let Some(trace) = &self.options.trace else {
            return;
        };
        let frame = match &self.shown {
            Some(f) if f.generation == self.requested && !f.is_preview() => f,
            _ => {
                eprintln!("ember-view: nothing to save yet: no pass of this view has finished");
                return;
            }
        };
        let exr = trace
            .output
            .clone()
            .unwrap_or_else(|| default_output(&trace.scene_path, frame.spp));
        let image = frame.image();
        let spp = frame.spp;
        self.saves.push(std::thread::spawn(
            move || match ember_cli::image::write_exr_and_png(&exr, &image) {
                Ok(png) => eprintln!(
                    "ember-view: wrote {} and {} ({spp} spp)",
                    exr.display(),
                    png.display()
                ),
                Err(e) => eprintln!("ember-view: cannot save the image: {e}"),
            },
        ));
    }

    fn exit(&mut self, event_loop: &ActiveEventLoop) {
        self.exit_requested.get_or_insert_with(Instant::now);
        if let Some(w) = &self.worker {
            // Stop rendering now; the thread is joined once the loop has returned.
            w.set_active(false);
        }
        event_loop.exit();
    }

    fn key(&mut self, event_loop: &ActiveEventLoop, event: &KeyEvent) {
        let PhysicalKey::Code(code) = event.physical_key else {
            return;
        };
        match event.state {
            ElementState::Pressed => {
                self.keys.insert(code);
                if event.repeat && !matches!(code, k if is_exposure_key(k)) {
                    return;
                }
                let traced = self.mode == Mode::Traced;
                match code {
                    KeyCode::Escape => self.exit(event_loop),
                    KeyCode::KeyR => {
                        self.camera = self.scene_camera;
                        self.view_changed();
                    }
                    KeyCode::KeyF if traced => self.error_view = !self.error_view,
                    KeyCode::KeyF => self.false_colour = !self.false_colour,
                    KeyCode::KeyP if self.mesh.is_some() && self.worker.is_some() => {
                        self.set_mode(if traced { Mode::Baked } else { Mode::Traced });
                    }
                    KeyCode::KeyI if traced => {
                        self.integrator = next_integrator(self.integrator);
                        self.view_changed();
                    }
                    KeyCode::KeyO if traced => self.save(),
                    KeyCode::Digit0 if traced => self.exposure_stops = 0.0,
                    k if traced && is_exposure_key(k) => {
                        let up = matches!(
                            k,
                            KeyCode::Equal | KeyCode::NumpadAdd | KeyCode::BracketRight
                        );
                        self.exposure_stops += if up { EXPOSURE_STEP } else { -EXPOSURE_STEP };
                    }
                    _ => {}
                }
            }
            ElementState::Released => {
                self.keys.remove(&code);
            }
        }
        self.request_redraw();
    }

    fn cursor_moved(&mut self, position: PhysicalPosition<f64>) {
        let previous = self.cursor.replace(position);
        let Some(previous) = previous else { return };
        if !(self.left_drag || self.right_drag) {
            return;
        }
        let height = self
            .state
            .as_ref()
            .map_or(self.options.height, |g| g.config.height)
            .max(1);
        // Dragging across the window height turns by 180°.
        let per_pixel = std::f32::consts::PI / height as f32;
        let dx = (position.x - previous.x) as f32 * per_pixel;
        let dy = (position.y - previous.y) as f32 * per_pixel;
        if dx == 0.0 && dy == 0.0 {
            return;
        }
        if self.left_drag {
            // Drag right: the scene turns right (the eye goes left); drag down: look from above.
            self.camera.orbit(-dx, dy);
        } else {
            // First-person: drag right looks right, drag up looks up.
            self.camera.look(-dx, -dy);
        }
        self.view_changed();
        self.request_redraw();
    }
}

fn is_exposure_key(k: KeyCode) -> bool {
    matches!(
        k,
        KeyCode::Equal
            | KeyCode::NumpadAdd
            | KeyCode::BracketRight
            | KeyCode::Minus
            | KeyCode::NumpadSubtract
            | KeyCode::BracketLeft
    )
}

/// `<stem>_<spp>spp.exr` beside the scene file.
#[must_use]
pub fn default_output(scene: &Path, spp: u32) -> PathBuf {
    let stem = scene.file_stem().unwrap_or_default().to_string_lossy();
    scene.with_file_name(format!("{stem}_{spp}spp.exr"))
}

impl ApplicationHandler<UserEvent> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        match self.init(event_loop) {
            Ok(g) => {
                self.state = Some(g);
                let mode = self.mode;
                self.set_mode(mode);
                self.update_title();
                self.request_redraw();
            }
            Err(e) => {
                self.error = Some(e);
                self.exit(event_loop);
            }
        }
    }

    fn user_event(&mut self, _event_loop: &ActiveEventLoop, event: UserEvent) {
        match event {
            UserEvent::Frame => self.frame_ready(),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => self.exit(event_loop),
            WindowEvent::Resized(size) => self.resize(size),
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            WindowEvent::KeyboardInput { event, .. } => self.key(event_loop, &event),
            WindowEvent::Focused(false) => {
                self.keys.clear();
                self.left_drag = false;
                self.right_drag = false;
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let pressed = state == ElementState::Pressed;
                match button {
                    MouseButton::Left => self.left_drag = pressed,
                    MouseButton::Right => self.right_drag = pressed,
                    _ => {}
                }
            }
            WindowEvent::CursorMoved { position, .. } => self.cursor_moved(position),
            WindowEvent::CursorLeft { .. } => self.cursor = None,
            WindowEvent::MouseWheel { delta, .. } => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => (p.y / 40.0) as f32,
                };
                self.camera.zoom(steps);
                self.view_changed();
                self.request_redraw();
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_output_is_beside_the_scene() {
        assert_eq!(
            default_output(Path::new("data/cornell-box/cornell_box.toml"), 64),
            Path::new("data/cornell-box/cornell_box_64spp.exr")
        );
    }

    #[test]
    fn moving_frames_per_second() {
        let t0 = Instant::now();
        let mut s = Stats::default();
        let ms = Duration::from_millis;
        for i in 0..10 {
            s.camera_moved(i + 2, t0 + ms(20 * i));
        }
        let frame = |generation, spp| TraceFrame {
            generation,
            block: 1,
            width: 1,
            height: 1,
            rgba: vec![[0.0; 4]],
            spp,
            target_spp: 4,
            integrator: Integrator::PathMis,
            camera: ViewCamera {
                eye: glam::Vec3::Z,
                target: glam::Vec3::ZERO,
                up: glam::Vec3::Y,
                fov_y_degrees: 30.0,
            },
            samples_per_second: 5.0,
            elapsed: ms(1),
            invalid_samples: 0,
        };
        // A preview of the first move (generation 2) at 30 ms, one of the sixth (7) at 150 ms,
        // the last view's first pass at 1 s.
        s.frame_presented(t0 + ms(30), &frame(2, 0));
        s.frame_presented(t0 + ms(150), &frame(7, 0));
        s.frame_presented(t0 + ms(1000), &frame(11, 2));
        s.finish();
        // Moves from 0 to 180 ms (+100 ms tail); two frames within it.
        assert!(
            (s.moving_seconds - 0.28).abs() < 1e-6,
            "{}",
            s.moving_seconds
        );
        assert_eq!(s.moving_frames, 2);
        let want = [30, 130, 110, 90, 70, 50, 880, 860, 840, 820];
        assert_eq!(s.latencies.len(), want.len());
        for (l, w) in s.latencies.iter().zip(want) {
            assert!((l - f64::from(w) / 1e3).abs() < 1e-6, "{:?}", s.latencies);
        }
        assert_eq!(s.rate, Some((5.0, 2)));
        assert!(s.summary(Some(ms(3))).unwrap().contains("stopped 3.0 ms"));
    }
}
