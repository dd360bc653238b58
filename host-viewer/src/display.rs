//! The path-traced view on the GPU: the accumulation as an `Rgba32Float` texture (mean RGB and
//! relative error per film pixel), drawn by `shaders/display.wgsl` with an exposure and the
//! sRGB transfer, or as a false-colour map of the relative error.

use crate::gpu::checked;
use crate::trace::TraceFrame;
use crate::ViewerError;
use bytemuck::{Pod, Zeroable};

/// Texture format of the accumulation: the f32 means as the renderer computed them, so that the
/// shader sees `ember render`'s values bit for bit.
pub const FILM_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// Relative errors at the ends of the false-colour ramp: 0.1 % (dark blue) to 100 % (red).
pub const ERROR_RANGE_LOG10: [f32; 2] = [-3.0, 0.0];

/// Matches `Params` in `shaders/display.wgsl` (48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Params {
    size: [f32; 4],
    mode: [f32; 4],
    error_range: [f32; 4],
}

/// What the display shows besides the accumulation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayParams {
    /// Window (surface) size in pixels.
    pub window: (u32, u32),
    /// Exposure in stops: the radiance is multiplied by 2^stops before the sRGB transfer.
    pub exposure_stops: f32,
    /// Show the relative standard error in false colour instead of the radiance.
    pub error_view: bool,
}

/// The film texture and its pipeline for one target format.
#[derive(Debug)]
pub struct TraceDisplay {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
    texture: wgpu::Texture,
    params: wgpu::Buffer,
    width: u32,
    height: u32,
    srgb_target: bool,
}

impl TraceDisplay {
    /// A `width × height` film (black) drawn into targets of `target_format`.
    ///
    /// # Errors
    /// A film larger than the adapter allows ([`ViewerError::Input`]), or a GPU error.
    pub fn new(
        device: &wgpu::Device,
        target_format: wgpu::TextureFormat,
        width: u32,
        height: u32,
    ) -> Result<Self, ViewerError> {
        let max = device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(ViewerError::Input(ember_cli::Error::new(format!(
                "film size {width}x{height} is out of range: each side must be 1..={max} on this adapter"
            ))));
        }
        checked(device, "creating the path-traced view", || {
            Ok(Self::create(device, target_format, width, height))
        })
    }

    fn create(
        device: &wgpu::Device,
        target_format: wgpu::TextureFormat,
        width: u32,
        height: u32,
    ) -> Self {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("display.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shaders/display.wgsl").into()),
        });
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("film"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FILM_FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("display params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("display"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("display"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("display"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("display"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: target_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        Self {
            pipeline,
            bind_group,
            texture,
            params,
            width,
            height,
            srgb_target: target_format.is_srgb(),
        }
    }

    /// Copies a frame into the film texture (it must have the film's size).
    pub fn upload(&self, queue: &wgpu::Queue, frame: &TraceFrame) {
        debug_assert_eq!((frame.width, frame.height), (self.width, self.height));
        if (frame.width, frame.height) != (self.width, self.height)
            || frame.rgba.len() != self.width as usize * self.height as usize
        {
            return;
        }
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(&frame.rgba),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(16 * self.width),
                rows_per_image: Some(self.height),
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Sets the window size, exposure and view for the next draw.
    pub fn set_params(&self, queue: &wgpu::Queue, p: DisplayParams) {
        let params = Params {
            size: [
                self.width as f32,
                self.height as f32,
                p.window.0.max(1) as f32,
                p.window.1.max(1) as f32,
            ],
            mode: [
                exposure_multiplier(p.exposure_stops),
                if p.error_view { 1.0 } else { 0.0 },
                if self.srgb_target { 1.0 } else { 0.0 },
                0.0,
            ],
            error_range: [ERROR_RANGE_LOG10[0], ERROR_RANGE_LOG10[1], 0.0, 0.0],
        };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
    }

    /// Records the pass that draws the film over the whole target.
    pub fn draw(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::TextureView) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("display"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// 2^stops; exactly 1 at 0 stops, so the default view is the PNG's values.
#[must_use]
pub fn exposure_multiplier(stops: f32) -> f32 {
    if stops == 0.0 {
        1.0
    } else {
        stops.exp2()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_layout() {
        assert_eq!(std::mem::size_of::<Params>(), 48);
        assert_eq!(exposure_multiplier(0.0), 1.0);
        assert_eq!(exposure_multiplier(1.0), 2.0);
        assert_eq!(exposure_multiplier(-2.0), 0.25);
    }
}
