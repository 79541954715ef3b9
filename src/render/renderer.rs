//! The offscreen 3-D renderer: one colour and one depth texture, a lit
//! triangle pipeline and a line pipeline, built once; each frame takes
//! plain vertex data. The colour texture is shown by egui as an image, and
//! read back for headless screenshots.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec2, Vec3};

use crate::render::camera::OrbitCamera;

/// Colour format of the target: gamma-encoded values in a linear format,
/// which egui displays as they are.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A lit triangle corner.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct MeshVertex {
    /// World position, m.
    pub position: [f32; 3],
    /// Unit normal (either side is lit).
    pub normal: [f32; 3],
    /// Gamma-encoded RGBA.
    pub color: [f32; 4],
}

/// A line end.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct LineVertex {
    /// World position, m.
    pub position: [f32; 3],
    /// Gamma-encoded RGBA.
    pub color: [f32; 4],
}

/// What to draw this frame: triangle and line lists in the world frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Frame {
    /// Three vertices per triangle.
    pub triangles: Vec<MeshVertex>,
    /// Two vertices per line segment.
    pub lines: Vec<LineVertex>,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Uniforms {
    clip_from_world: [[f32; 4]; 4],
    light_dir: [f32; 4],
}

/// GPU state of the 3-D view.
pub struct Renderer {
    mesh_pipeline: wgpu::RenderPipeline,
    line_pipeline: wgpu::RenderPipeline,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    size: [u32; 2],
    triangles: GrowingBuffer,
    lines: GrowingBuffer,
    /// Background colour (gamma-encoded RGBA).
    pub background: [f64; 4],
}

/// A vertex buffer that grows to fit.
struct GrowingBuffer {
    buffer: wgpu::Buffer,
    capacity: u64,
    label: &'static str,
}

impl GrowingBuffer {
    fn new(device: &wgpu::Device, label: &'static str) -> Self {
        let capacity = 1 << 16;
        Self {
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: capacity,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            capacity,
            label,
        }
    }

    fn write(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, bytes: &[u8]) {
        let needed = bytes.len() as u64;
        if needed > self.capacity {
            self.capacity = needed.next_power_of_two();
            self.buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size: self.capacity,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
        }
        if !bytes.is_empty() {
            queue.write_buffer(&self.buffer, 0, bytes);
        }
    }
}

impl Renderer {
    /// Builds the pipelines and a target of `size` pixels.
    #[must_use]
    pub fn new(device: &wgpu::Device, size: [u32; 2]) -> Self {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("proprioscope shader"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
        });
        let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
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
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("proprioscope layout"),
            bind_group_layouts: &[Some(&bind_group_layout)],
            immediate_size: 0,
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("uniforms"),
            layout: &bind_group_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            }],
        });
        let mesh_attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x4];
        let line_attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4];
        let pipeline = |entry_vs, entry_fs, stride, attributes: &[wgpu::VertexAttribute], topology| {
            make_pipeline(
                device,
                &layout,
                &shader,
                (entry_vs, entry_fs),
                stride,
                attributes,
                topology,
            )
        };
        let mesh_pipeline = pipeline(
            "vs_mesh",
            "fs_mesh",
            std::mem::size_of::<MeshVertex>(),
            &mesh_attributes,
            wgpu::PrimitiveTopology::TriangleList,
        );
        let line_pipeline = pipeline(
            "vs_line",
            "fs_line",
            std::mem::size_of::<LineVertex>(),
            &line_attributes,
            wgpu::PrimitiveTopology::LineList,
        );
        let (color, color_view, depth_view) = targets(device, size);
        Self {
            mesh_pipeline,
            line_pipeline,
            uniforms,
            bind_group,
            color,
            color_view,
            depth_view,
            size,
            triangles: GrowingBuffer::new(device, "triangles"),
            lines: GrowingBuffer::new(device, "lines"),
            background: [0.16, 0.17, 0.19, 1.0],
        }
    }

    /// The current target size, pixels.
    #[must_use]
    pub fn size(&self) -> [u32; 2] {
        self.size
    }

    /// The colour target (to show it, or to copy it out).
    #[must_use]
    pub fn color_view(&self) -> &wgpu::TextureView {
        &self.color_view
    }

    /// Recreates the targets when the size changed; true if it did.
    pub fn resize(&mut self, device: &wgpu::Device, size: [u32; 2]) -> bool {
        let size = [size[0].max(1), size[1].max(1)];
        if size == self.size {
            return false;
        }
        let (color, color_view, depth_view) = targets(device, size);
        self.color = color;
        self.color_view = color_view;
        self.depth_view = depth_view;
        self.size = size;
        true
    }

    /// Draws `frame` as seen by `camera`.
    pub fn render(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, camera: &OrbitCamera, frame: &Frame) {
        let size = Vec2::new(self.size[0] as f32, self.size[1] as f32);
        let clip_from_world: Mat4 = camera.clip_from_world(size);
        // A head light, a little above and to the left of the eye.
        let light = (camera.eye() - camera.target).normalize_or(Vec3::Z) + Vec3::new(0.0, 0.0, 0.5);
        let uniforms = Uniforms {
            clip_from_world: clip_from_world.to_cols_array_2d(),
            light_dir: light.normalize_or(Vec3::Z).extend(0.0).to_array(),
        };
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&uniforms));
        self.triangles
            .write(device, queue, bytemuck::cast_slice(&frame.triangles));
        self.lines.write(device, queue, bytemuck::cast_slice(&frame.lines));
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("3-D view"),
        });
        {
            let [r, g, b, a] = self.background;
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("3-D view"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &self.color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            if !frame.triangles.is_empty() {
                pass.set_pipeline(&self.mesh_pipeline);
                pass.set_vertex_buffer(0, self.triangles.buffer.slice(..));
                pass.draw(0..frame.triangles.len() as u32, 0..1);
            }
            if !frame.lines.is_empty() {
                pass.set_pipeline(&self.line_pipeline);
                pass.set_vertex_buffer(0, self.lines.buffer.slice(..));
                pass.draw(0..frame.lines.len() as u32, 0..1);
            }
        }
        queue.submit([encoder.finish()]);
    }
}

/// One pipeline of the view: lit meshes or lines, depth-tested, blended.
fn make_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    shader: &wgpu::ShaderModule,
    (entry_vs, entry_fs): (&str, &str),
    stride: usize,
    attributes: &[wgpu::VertexAttribute],
    topology: wgpu::PrimitiveTopology,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(entry_vs),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some(entry_vs),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: stride as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes,
            })],
        },
        primitive: wgpu::PrimitiveState {
            topology,
            ..wgpu::PrimitiveState::default()
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
            module: shader,
            entry_point: Some(entry_fs),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: COLOR_FORMAT,
                blend: Some(wgpu::BlendState::ALPHA_BLENDING),
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

fn targets(device: &wgpu::Device, size: [u32; 2]) -> (wgpu::Texture, wgpu::TextureView, wgpu::TextureView) {
    let extent = wgpu::Extent3d {
        width: size[0].max(1),
        height: size[1].max(1),
        depth_or_array_layers: 1,
    };
    let color = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("3-D view colour"),
        size: extent,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: COLOR_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let depth = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("3-D view depth"),
        size: extent,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: DEPTH_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let color_view = color.create_view(&wgpu::TextureViewDescriptor::default());
    let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
    (color, color_view, depth_view)
}
