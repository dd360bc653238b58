//! One frame rendered offscreen and read back, as TinyRender saves its first real-time frame
//! (FORMAT.md §8): drawn into an 8-bit sRGB target, read back and decoded with the sRGB EOTF,
//! so the linear result is clamped to [0, 1] by construction.

use crate::camera::ViewCamera;
use crate::gpu::{self, MeshRenderer, COLOR_FORMAT};
use crate::{srgb8_to_linear_table, ViewerError};
use ember_cli::bake::BakedMesh;
use ember_cli::image::Image;
use ember_cli::scene_file::CameraDesc;
use std::sync::mpsc;
use std::time::Instant;

/// Where a frame came from and how long it took.
#[derive(Clone, Debug)]
pub struct FrameInfo {
    pub adapter: wgpu::AdapterInfo,
    /// Instance, adapter and device creation.
    pub setup_ms: f64,
    /// Mesh upload and pipeline creation (shader compilation).
    pub upload_ms: f64,
    /// From command submission to the read-back buffer being mapped.
    pub frame_ms: f64,
}

/// A rendered frame.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Linear RGB in [0, 1], row 0 at the top.
    pub image: Image,
    /// The 8-bit sRGB values as the GPU stored them, RGB interleaved, row 0 at the top.
    pub srgb8: Vec<u8>,
    pub info: FrameInfo,
}

/// An adapter and device for offscreen rendering.
#[derive(Debug)]
pub struct HeadlessGpu {
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub setup_ms: f64,
}

impl HeadlessGpu {
    /// Finds an adapter (hardware first, then fallback) on Vulkan or GL and opens a device.
    ///
    /// # Errors
    /// [`ViewerError::NoAdapter`] with what to install, or [`ViewerError::Gpu`].
    pub fn new() -> Result<Self, ViewerError> {
        let start = Instant::now();
        let instance = gpu::instance(None);
        let adapter = pollster::block_on(gpu::request_adapter(&instance, None))?;
        let (device, queue) = pollster::block_on(gpu::request_device(&adapter))?;
        Ok(Self {
            adapter,
            device,
            queue,
            setup_ms: start.elapsed().as_secs_f64() * 1e3,
        })
    }

    #[must_use]
    pub fn info(&self) -> wgpu::AdapterInfo {
        self.adapter.get_info()
    }

    /// Renders one `width`×`height` frame of `mesh` seen by `camera`.
    ///
    /// # Errors
    /// Bad size, camera or mesh ([`ViewerError::Input`]); a GPU error.
    pub fn render(
        &self,
        mesh: &BakedMesh,
        camera: &CameraDesc,
        width: u32,
        height: u32,
        false_colour: bool,
    ) -> Result<Frame, ViewerError> {
        let max = self.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(input(format!(
                "film size {width}x{height} is out of range: each side must be 1..={max} on this adapter"
            )));
        }
        let view_camera = ViewCamera::from_desc(camera);
        if !view_camera.is_valid() {
            return Err(input(format!(
                "the camera (eye {:?}, at {:?}, up {:?}, fov {}) does not define a view",
                camera.eye, camera.at, camera.up, camera.fov
            )));
        }
        let upload_start = Instant::now();
        let renderer = MeshRenderer::new(&self.device, COLOR_FORMAT, mesh)?;
        let upload_ms = upload_start.elapsed().as_secs_f64() * 1e3;
        let view_proj = view_camera.view_proj(width as f32 / height as f32);
        let (srgb8, frame_ms) = gpu::checked(&self.device, "rendering the frame", || {
            self.draw_and_read(&renderer, view_proj, width, height, false_colour)
        })?;
        let eotf = srgb8_to_linear_table();
        let pixels = srgb8
            .chunks_exact(3)
            .map(|p| {
                glam::Vec3::new(
                    eotf[p[0] as usize],
                    eotf[p[1] as usize],
                    eotf[p[2] as usize],
                )
            })
            .collect();
        Ok(Frame {
            image: Image {
                width,
                height,
                pixels,
            },
            srgb8,
            info: FrameInfo {
                adapter: self.info(),
                setup_ms: self.setup_ms,
                upload_ms,
                frame_ms,
            },
        })
    }

    /// Draws, copies the target into read-back buffers (in bands of rows, each buffer within
    /// the device's size limit, rows padded to `COPY_BYTES_PER_ROW_ALIGNMENT`), maps them and
    /// returns the RGB bytes without the padding, and the milliseconds from submission to the
    /// mapping.
    fn draw_and_read(
        &self,
        renderer: &MeshRenderer,
        view_proj: glam::Mat4,
        width: u32,
        height: u32,
        false_colour: bool,
    ) -> Result<(Vec<u8>, f64), ViewerError> {
        let device = &self.device;
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let target = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("frame"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COLOR_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let color = target.create_view(&wgpu::TextureViewDescriptor::default());
        let depth = gpu::depth_view(device, width, height);
        renderer.set_view(&self.queue, view_proj, false_colour);

        let unpadded = 4 * u64::from(width);
        let align = u64::from(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let padded = unpadded.div_ceil(align) * align;
        let max_buffer = device.limits().max_buffer_size.min(1 << 28);
        let rows_per_band = (max_buffer / padded).clamp(1, u64::from(height)) as u32;

        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("frame"),
        });
        renderer.draw(&mut encoder, &color, &depth);
        let mut bands = Vec::new();
        let mut y0 = 0;
        while y0 < height {
            let rows = rows_per_band.min(height - y0);
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("read-back"),
                size: padded * u64::from(rows),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: &target,
                    mip_level: 0,
                    origin: wgpu::Origin3d { x: 0, y: y0, z: 0 },
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(padded as u32),
                        rows_per_image: Some(rows),
                    },
                },
                wgpu::Extent3d {
                    width,
                    height: rows,
                    depth_or_array_layers: 1,
                },
            );
            bands.push((buffer, rows));
            y0 += rows;
        }

        let start = Instant::now();
        self.queue.submit([encoder.finish()]);
        let (tx, rx) = mpsc::channel();
        for (i, (buffer, _)) in bands.iter().enumerate() {
            let tx = tx.clone();
            buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send((i, r));
            });
        }
        drop(tx);
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| ViewerError::Gpu(format!("waiting for the frame: {e}")))?;
        for _ in 0..bands.len() {
            let (i, r) = rx
                .recv()
                .map_err(|_| ViewerError::Gpu("a read-back buffer was never mapped".into()))?;
            r.map_err(|e| ViewerError::Gpu(format!("cannot map read-back buffer {i}: {e}")))?;
        }
        let frame_ms = start.elapsed().as_secs_f64() * 1e3;

        let mut rgb = Vec::with_capacity(3 * width as usize * height as usize);
        for (buffer, rows) in &bands {
            {
                let data = buffer
                    .slice(..)
                    .get_mapped_range()
                    .map_err(|e| ViewerError::Gpu(format!("cannot read back the frame: {e}")))?;
                for row in data.chunks_exact(padded as usize).take(*rows as usize) {
                    for px in row[..unpadded as usize].chunks_exact(4) {
                        rgb.extend_from_slice(&px[..3]);
                    }
                }
            }
            buffer.unmap();
        }
        Ok((rgb, frame_ms))
    }
}

fn input(msg: String) -> ViewerError {
    ViewerError::Input(ember_cli::Error::new(msg))
}

/// Renders one frame of `mesh` offscreen on a new device: see [`HeadlessGpu::render`].
///
/// # Errors
/// No adapter ([`ViewerError::NoAdapter`], naming what to install), bad input, a GPU error.
pub fn render_headless(
    mesh: &BakedMesh,
    camera: &CameraDesc,
    width: u32,
    height: u32,
    false_colour: bool,
) -> Result<Frame, ViewerError> {
    HeadlessGpu::new()?.render(mesh, camera, width, height, false_colour)
}
