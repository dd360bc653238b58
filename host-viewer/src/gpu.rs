//! wgpu set-up shared by the headless and window modes: instance, adapter and device, and the
//! mesh pipeline (one vertex buffer of position + colour, one index buffer, one draw).

use crate::ViewerError;
use bytemuck::{Pod, Zeroable};
use ember_cli::bake::BakedMesh;
use glam::Mat4;
use wgpu::util::DeviceExt;

/// The offscreen colour target: the hardware encodes linear → sRGB on store (and clamps).
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// What to install when there is no adapter.
pub const INSTALL_HINT: &str = "install a Vulkan driver, e.g. the software one: \
    `apt-get install mesa-vulkan-drivers` (Debian/Ubuntu; lavapipe), \
    or for OpenGL `apt-get install libegl1 libgl1-mesa-dri` (llvmpipe)";

/// Vulkan and GL, unless `WGPU_BACKEND` (e.g. `vulkan`, `gl`) says otherwise.
#[must_use]
pub fn backends() -> wgpu::Backends {
    (wgpu::Backends::VULKAN | wgpu::Backends::GL).with_env()
}

/// An instance on [`backends`]; `display` is the window system connection in window mode
/// (needed by GL to present).
#[must_use]
pub fn instance(display: Option<Box<dyn wgpu::wgt::WgpuHasDisplayHandle>>) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = backends();
    desc.flags = wgpu::InstanceFlags::from_build_config().with_env();
    desc.display = display;
    wgpu::Instance::new(desc)
}

/// A hardware adapter if there is one, else a fallback (software) adapter.
///
/// # Errors
/// [`ViewerError::NoAdapter`], naming the backends tried and what to install.
pub async fn request_adapter(
    instance: &wgpu::Instance,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<wgpu::Adapter, ViewerError> {
    let mut errors = Vec::new();
    for force_fallback_adapter in [false, true] {
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter,
            compatible_surface: surface,
            ..Default::default()
        };
        match instance.request_adapter(&options).await {
            Ok(adapter) => return Ok(adapter),
            Err(e) => {
                let e = e.to_string();
                if !errors.contains(&e) {
                    errors.push(e);
                }
            }
        }
    }
    Err(ViewerError::NoAdapter(format!(
        "no GPU adapter found on backends {:?} ({}); {INSTALL_HINT}",
        backends(),
        errors.join("; ")
    )))
}

/// A device with the adapter's own limits (so that large films fit).
///
/// # Errors
/// [`ViewerError::Gpu`] when the driver refuses.
pub async fn request_device(
    adapter: &wgpu::Adapter,
) -> Result<(wgpu::Device, wgpu::Queue), ViewerError> {
    let desc = wgpu::DeviceDescriptor {
        label: Some("ember-view"),
        required_limits: adapter.limits(),
        ..Default::default()
    };
    adapter.request_device(&desc).await.map_err(|e| {
        let info = adapter.get_info();
        ViewerError::Gpu(format!(
            "cannot create a device on {} ({:?}): {e}",
            info.name, info.backend
        ))
    })
}

/// One line describing an adapter: name, backend, type, driver.
#[must_use]
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    let driver = [info.driver.as_str(), info.driver_info.as_str()]
        .iter()
        .filter(|s| !s.is_empty())
        .copied()
        .collect::<Vec<_>>()
        .join(" ");
    format!(
        "{} ({:?} backend, {:?} device{}{})",
        info.name,
        info.backend,
        info.device_type,
        if driver.is_empty() { "" } else { ", " },
        driver
    )
}

/// Runs `f` inside validation and out-of-memory error scopes and turns what they catch into
/// [`ViewerError::Gpu`], instead of wgpu's default of panicking.
///
/// # Errors
/// The first error the device reported, or `f`'s own.
pub fn checked<T>(
    device: &wgpu::Device,
    what: &str,
    f: impl FnOnce() -> Result<T, ViewerError>,
) -> Result<T, ViewerError> {
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let result = f();
    let v = pollster::block_on(validation.pop());
    let o = pollster::block_on(oom.pop());
    if let Some(e) = v.or(o) {
        return Err(ViewerError::Gpu(format!("GPU error while {what}: {e}")));
    }
    result
}

/// One vertex as uploaded: position and baked linear RGB radiance (6 floats, 24 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub color: [f32; 3],
}

/// Matches `Uniforms` in `shaders/mesh.wgsl` (80 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Uniforms {
    view_proj: [f32; 16],
    params: [f32; 4],
}

/// Checks that a mesh can be drawn: as many colours as positions, indices in range.
///
/// # Errors
/// [`ViewerError::Input`] saying what is wrong.
pub fn validate_mesh(mesh: &BakedMesh) -> Result<(), ViewerError> {
    let n = mesh.positions.len();
    if mesh.colors.len() != n {
        return Err(ViewerError::Input(ember_cli::Error::new(format!(
            "baked mesh has {n} positions but {} colours",
            mesh.colors.len()
        ))));
    }
    if u32::try_from(n).is_err() {
        return Err(ViewerError::Input(ember_cli::Error::new(
            "baked mesh has more than 2^32 vertices",
        )));
    }
    if let Some((t, i)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find_map(|(t, tri)| tri.iter().find(|&&i| i as usize >= n).map(|&i| (t, i)))
    {
        return Err(ViewerError::Input(ember_cli::Error::new(format!(
            "baked mesh triangle {t} uses vertex {i}, but there are only {n} vertices"
        ))));
    }
    Ok(())
}

/// The interleaved vertices of a mesh; non-finite colours become black (a NaN must not reach
/// the colour target, where it would be undefined).
#[must_use]
pub fn vertices(mesh: &BakedMesh) -> Vec<Vertex> {
    mesh.positions
        .iter()
        .zip(&mesh.colors)
        .map(|(&position, c)| Vertex {
            position,
            color: c.map(|v| if v.is_finite() { v } else { 0.0 }),
        })
        .collect()
}

/// Rec. 709 luminance.
fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The log10 luminance range of the false-colour ramp: the 0.5th to 99.5th percentile of the
/// positive vertex luminances (so that a few emitter vertices do not squeeze the rest), and at
/// least one decade wide.
#[must_use]
pub fn false_colour_range(mesh: &BakedMesh) -> [f32; 2] {
    let mut l: Vec<f32> = mesh
        .colors
        .iter()
        .map(|&c| luminance(c))
        .filter(|y| y.is_finite() && *y > 0.0)
        .map(f32::log10)
        .collect();
    if l.is_empty() {
        return [-3.0, 0.0];
    }
    l.sort_by(f32::total_cmp);
    let at = |q: f64| l[((l.len() - 1) as f64 * q).round() as usize];
    let (lo, hi) = (at(0.005), at(0.995));
    let mid = 0.5 * (lo + hi);
    if hi - lo < 1.0 {
        [mid - 0.5, mid + 0.5]
    } else {
        [lo, hi]
    }
}

/// The mesh on the GPU with its pipeline for one colour format.
#[derive(Debug)]
pub struct MeshRenderer {
    pipeline: wgpu::RenderPipeline,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    /// log10 luminance at the ends of the false-colour ramp.
    pub false_colour_range: [f32; 2],
}

impl MeshRenderer {
    /// Uploads the mesh and builds the pipeline for `color_format` (an sRGB format, so the
    /// output is encoded as TinyRender's sRGB framebuffer is).
    ///
    /// # Errors
    /// A bad mesh ([`ViewerError::Input`]) or a GPU error.
    pub fn new(
        device: &wgpu::Device,
        color_format: wgpu::TextureFormat,
        mesh: &BakedMesh,
    ) -> Result<Self, ViewerError> {
        validate_mesh(mesh)?;
        checked(device, "uploading the mesh", || {
            Ok(Self::create(device, color_format, mesh))
        })
    }

    fn create(device: &wgpu::Device, color_format: wgpu::TextureFormat, mesh: &BakedMesh) -> Self {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("mesh.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shaders/mesh.wgsl").into()),
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("uniforms"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("uniforms"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("mesh"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("mesh"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                // TinyRender does not cull, and the scenes are one-sided shells seen from inside.
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: color_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        // wgpu buffers may not be empty: an empty mesh gets one unused element of each.
        let mut verts = vertices(mesh);
        if verts.is_empty() {
            verts.push(Vertex::default());
        }
        let mut index_data: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let index_count = index_data.len() as u32;
        if index_data.is_empty() {
            index_data.push(0);
        }
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vertices"),
            contents: bytemuck::cast_slice(&verts),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("indices"),
            contents: bytemuck::cast_slice(&index_data),
            usage: wgpu::BufferUsages::INDEX,
        });
        Self {
            pipeline,
            uniforms,
            bind_group,
            vertices,
            indices,
            index_count,
            false_colour_range: false_colour_range(mesh),
        }
    }

    /// Sets the camera matrix and the false-colour flag for the next draw.
    pub fn set_view(&self, queue: &wgpu::Queue, view_proj: Mat4, false_colour: bool) {
        let [lo, hi] = self.false_colour_range;
        let u = Uniforms {
            view_proj: view_proj.to_cols_array(),
            params: [if false_colour { 1.0 } else { 0.0 }, lo, hi, 0.0],
        };
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&u));
    }

    /// Records one render pass: clear to black and depth 1, draw the mesh with depth test
    /// `less`.
    pub fn draw(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        color: &wgpu::TextureView,
        depth: &wgpu::TextureView,
    ) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("mesh"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: color,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if self.index_count > 0 {
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..self.index_count, 0, 0..1);
        }
    }
}

/// A depth buffer of the given size.
#[must_use]
pub fn depth_view(device: &wgpu::Device, width: u32, height: u32) -> wgpu::TextureView {
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("depth"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        })
        .create_view(&wgpu::TextureViewDescriptor::default())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_layout_is_six_floats() {
        assert_eq!(std::mem::size_of::<Vertex>(), 24);
        assert_eq!(std::mem::size_of::<Uniforms>(), 80);
    }

    #[test]
    fn mesh_checks() {
        let mut m = BakedMesh {
            positions: vec![[0.0; 3]; 3],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            colors: vec![[1.0, f32::NAN, f32::INFINITY]; 3],
            triangles: vec![[0, 1, 2]],
            provenance: vec![],
        };
        assert!(validate_mesh(&m).is_ok());
        assert_eq!(vertices(&m)[0].color, [1.0, 0.0, 0.0]);
        m.triangles.push([0, 1, 3]);
        let e = validate_mesh(&m).unwrap_err().to_string();
        assert!(e.contains("triangle 1 uses vertex 3"), "{e}");
        m.triangles.pop();
        m.colors.pop();
        assert!(validate_mesh(&m).is_err());
    }

    #[test]
    fn false_colour_range_is_robust() {
        let mut m = BakedMesh::default();
        assert_eq!(false_colour_range(&m), [-3.0, 0.0]);
        m.colors = vec![[0.5; 3]; 10];
        let [lo, hi] = false_colour_range(&m);
        assert!((hi - lo - 1.0).abs() < 1e-6 && (0.5 * (lo + hi) - 0.5f32.log10()).abs() < 1e-6);
        m.colors = (0..1000)
            .map(|i| [10f32.powf(i as f32 / 250.0 - 3.0); 3])
            .collect();
        let [lo, hi] = false_colour_range(&m);
        assert!(
            (lo + 2.98).abs() < 0.01 && (hi - 0.98).abs() < 0.01,
            "{lo} {hi}"
        );
    }
}
