//! The interactive viewer (winit 0.30 `ApplicationHandler`): the same pipeline as the headless
//! mode, drawn into a window surface.
//!
//! Controls: left-drag orbits around the look-at point, the wheel zooms; W/A/S/D fly
//! forward/left/back/right, Q/E down/up (Shift: 4× faster), right-drag looks around; R resets
//! to the scene camera, F toggles false colour, Esc quits. The title shows the frame time
//! (command submission to GPU completion).

use crate::camera::ViewCamera;
use crate::gpu::{self, MeshRenderer};
use crate::ViewerError;
use ember_cli::bake::BakedMesh;
use ember_cli::scene_file::CameraDesc;
use std::collections::HashSet;
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// What the window shows at the start.
#[derive(Clone, Debug)]
pub struct WindowOptions {
    /// Shown in the title, e.g. the scene's file name.
    pub name: String,
    /// Initial inner size in physical pixels (the film size).
    pub width: u32,
    pub height: u32,
    pub false_colour: bool,
}

/// Opens the window and runs until it is closed.
///
/// # Errors
/// No display ([`ViewerError::Display`]), no adapter, a GPU error.
pub fn run(
    mesh: BakedMesh,
    camera: &CameraDesc,
    options: WindowOptions,
) -> Result<(), ViewerError> {
    gpu::validate_mesh(&mesh)?;
    let scene_camera = ViewCamera::from_desc(camera);
    if !scene_camera.is_valid() {
        return Err(ViewerError::Input(ember_cli::Error::new(
            "the scene camera does not define a view",
        )));
    }
    let event_loop = EventLoop::new().map_err(|e| {
        ViewerError::Display(format!(
            "cannot open a window ({e}); is there a display (DISPLAY or WAYLAND_DISPLAY)? \
             Use --headless, or run under xvfb-run"
        ))
    })?;
    let instance = gpu::instance(Some(Box::new(event_loop.owned_display_handle())));
    let scale = scene_scale(&mesh);
    let mut app = App {
        instance,
        mesh,
        options: options.clone(),
        scene_camera,
        camera: scene_camera,
        false_colour: options.false_colour,
        scale,
        state: None,
        error: None,
        keys: HashSet::new(),
        left_drag: false,
        right_drag: false,
        cursor: None,
        last_frame: None,
        frame_ms: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| ViewerError::Display(format!("window event loop failed: {e}")))?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// Diagonal of the mesh's bounding box: the fly speed is a fraction of it per second.
fn scene_scale(mesh: &BakedMesh) -> f32 {
    let mut lo = glam::Vec3::splat(f32::INFINITY);
    let mut hi = glam::Vec3::splat(f32::NEG_INFINITY);
    for p in &mesh.positions {
        let p = glam::Vec3::from(*p);
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

struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    config: wgpu::SurfaceConfiguration,
    /// The sRGB format the pipeline renders with (the surface format or its sRGB view).
    view_format: wgpu::TextureFormat,
    renderer: MeshRenderer,
    depth: wgpu::TextureView,
    adapter: wgpu::AdapterInfo,
}

struct App {
    instance: wgpu::Instance,
    mesh: BakedMesh,
    options: WindowOptions,
    scene_camera: ViewCamera,
    camera: ViewCamera,
    false_colour: bool,
    scale: f32,
    state: Option<Gfx>,
    error: Option<ViewerError>,
    keys: HashSet<KeyCode>,
    left_drag: bool,
    right_drag: bool,
    cursor: Option<PhysicalPosition<f64>>,
    last_frame: Option<Instant>,
    frame_ms: Option<f64>,
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
            .with_inner_size(PhysicalSize::new(self.options.width, self.options.height));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| ViewerError::Display(format!("cannot create a window: {e}")))?,
        );
        let surface = self
            .instance
            .create_surface(window.clone())
            .map_err(|e| ViewerError::Gpu(format!("cannot create a window surface: {e}")))?;
        let adapter = pollster::block_on(gpu::request_adapter(&self.instance, Some(&surface)))?;
        let info = adapter.get_info();
        eprintln!("ember-view: adapter {}", gpu::describe(&info));
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
        let renderer = MeshRenderer::new(&device, view_format, &self.mesh)?;
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
            adapter: info,
        })
    }

    fn update_title(&self) {
        let Some(g) = &self.state else { return };
        let time = self
            .frame_ms
            .map_or_else(String::new, |ms| format!(" — {ms:.2} ms/frame"));
        g.window.set_title(&format!(
            "ember-view — {}{time} — {} ({:?}){}",
            self.options.name,
            g.adapter.name,
            g.adapter.backend,
            if self.false_colour {
                " — false colour"
            } else {
                ""
            }
        ));
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
        if f != 0.0 || r != 0.0 || u != 0.0 {
            self.camera.fly(f * speed, r * speed, u * speed);
        }
        MOVE_KEYS.iter().any(|&k| held(k))
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        let moving = self.fly();
        let (camera, false_colour) = (self.camera, self.false_colour);
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
        let aspect = g.config.width as f32 / g.config.height as f32;
        g.renderer
            .set_view(&g.queue, camera.view_proj(aspect), false_colour);
        let mut encoder = g
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        g.renderer.draw(&mut encoder, &view, &g.depth);
        let start = Instant::now();
        g.queue.submit([encoder.finish()]);
        if let Err(e) = g.device.poll(wgpu::PollType::wait_indefinitely()) {
            eprintln!("ember-view: waiting for the frame: {e}");
        }
        let ms = start.elapsed().as_secs_f64() * 1e3;
        g.window.pre_present_notify();
        g.queue.present(frame);
        // A little smoothing keeps the title readable.
        self.frame_ms = Some(self.frame_ms.map_or(ms, |old| 0.8 * old + 0.2 * ms));
        self.update_title();
        if moving {
            if let Some(g) = &self.state {
                g.window.request_redraw();
            }
        } else {
            self.last_frame = None;
        }
    }

    fn request_redraw(&self) {
        if let Some(g) = &self.state {
            g.window.request_redraw();
        }
    }

    fn key(&mut self, event_loop: &ActiveEventLoop, event: &KeyEvent) {
        let PhysicalKey::Code(code) = event.physical_key else {
            return;
        };
        match event.state {
            ElementState::Pressed => {
                self.keys.insert(code);
                if event.repeat {
                    return;
                }
                match code {
                    KeyCode::Escape => event_loop.exit(),
                    KeyCode::KeyR => self.camera = self.scene_camera,
                    KeyCode::KeyF => self.false_colour = !self.false_colour,
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
        if self.left_drag {
            // Drag right: the scene turns right (the eye goes left); drag down: look from above.
            self.camera.orbit(-dx, dy);
        } else {
            // First-person: drag right looks right, drag up looks up.
            self.camera.look(-dx, -dy);
        }
        self.request_redraw();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        match self.init(event_loop) {
            Ok(g) => {
                self.state = Some(g);
                self.update_title();
                self.request_redraw();
            }
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
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
                self.request_redraw();
            }
            _ => {}
        }
    }
}
