//! Pipelines, per-chunk GPU buffers and drawing.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Mat4, Vec3};
use strata_mesh::Mesh;
use strata_volume::ChunkKey;
use wgpu::util::DeviceExt;

use crate::camera::Camera;

/// The depth buffer's format.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// One vertex as the shaders read it: world position, unit normal, linear RGBA.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Vertex {
    /// World position.
    pub position: [f32; 3],
    /// Unit normal.
    pub normal: [f32; 3],
    /// Linear RGBA.
    pub color: [f32; 4],
}

const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x4];

fn vertex_layout() -> wgpu::VertexBufferLayout<'static> {
    wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &VERTEX_ATTRIBUTES,
    }
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct FrameUniforms {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    light_dir: [f32; 4],
    line_color: [f32; 4],
}

/// A translucent brush preview: a mesh in its own coordinates, placed by `model`.
#[derive(Clone, Copy, Debug)]
pub struct Preview<'a> {
    /// The brush's surface.
    pub mesh: &'a Mesh,
    /// Its placement in the world.
    pub model: Mat4,
    /// Linear RGBA (alpha is the opacity).
    pub color: [f32; 4],
}

/// What one frame shows.
#[derive(Clone, Copy, Debug)]
pub struct FrameSettings<'a> {
    /// The camera.
    pub camera: Camera,
    /// Draw triangle edges over the surfaces.
    pub wireframe: bool,
    /// Draw the ground grid.
    pub grid: bool,
    /// Background colour (linear RGBA).
    pub background: [f64; 4],
    /// The brush previews (the dab and its mirror images, the falloff's core), drawn
    /// translucent over everything else.
    pub previews: &'a [Preview<'a>],
}

impl Default for FrameSettings<'_> {
    fn default() -> Self {
        FrameSettings {
            camera: Camera::default(),
            wireframe: false,
            grid: true,
            background: [0.055, 0.06, 0.075, 1.0],
            previews: &[],
        }
    }
}

struct GpuChunk {
    vertices: wgpu::Buffer,
    triangles: wgpu::Buffer,
    edges: wgpu::Buffer,
    triangle_indices: u32,
    edge_indices: u32,
}

/// Draws chunk meshes, the grid and the brush preview into any colour target with a depth
/// buffer of [`DEPTH_FORMAT`].
pub struct Renderer {
    fill: wgpu::RenderPipeline,
    wire: wgpu::RenderPipeline,
    grid: wgpu::RenderPipeline,
    preview: wgpu::RenderPipeline,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    chunks: HashMap<(u32, ChunkKey), GpuChunk>,
    grid_vertices: wgpu::Buffer,
    grid_count: u32,
    preview_buffers: Option<(wgpu::Buffer, wgpu::Buffer, u32)>,
    uploads: u64,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer").field("chunks", &self.chunks.len()).field("uploads", &self.uploads).finish()
    }
}

impl Renderer {
    /// Pipelines for a colour target of `color_format`.
    pub fn new(device: &wgpu::Device, color_format: wgpu::TextureFormat) -> Self {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("strata mesh.wgsl"),
            source: wgpu::ShaderSource::Wgsl(crate::SHADER.into()),
        });
        let bind_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("strata frame"),
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
            label: Some("strata"),
            bind_group_layouts: &[Some(&bind_layout)],
            immediate_size: 0,
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("strata frame uniforms"),
            size: std::mem::size_of::<FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("strata frame"),
            layout: &bind_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: uniforms.as_entire_binding() }],
        });
        let pipeline = |label: &str, vs: &str, fs: &str, topology: wgpu::PrimitiveTopology, blend: bool| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&layout),
                vertex: wgpu::VertexState {
                    module: &shader,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers: &[Some(vertex_layout())],
                },
                primitive: wgpu::PrimitiveState {
                    topology,
                    front_face: wgpu::FrontFace::Ccw,
                    cull_mode: (topology == wgpu::PrimitiveTopology::TriangleList && !blend)
                        .then_some(wgpu::Face::Back),
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(!blend),
                    depth_compare: Some(wgpu::CompareFunction::LessEqual),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &shader,
                    entry_point: Some(fs),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: color_format,
                        blend: Some(if blend { wgpu::BlendState::ALPHA_BLENDING } else { wgpu::BlendState::REPLACE }),
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let fill = pipeline("strata fill", "vs_mesh", "fs_mesh", wgpu::PrimitiveTopology::TriangleList, false);
        let wire = pipeline("strata wire", "vs_line", "fs_wire", wgpu::PrimitiveTopology::LineList, false);
        let grid = pipeline("strata grid", "vs_line", "fs_grid", wgpu::PrimitiveTopology::LineList, true);
        let preview = pipeline("strata preview", "vs_mesh", "fs_preview", wgpu::PrimitiveTopology::TriangleList, true);
        let grid_lines = grid_vertices();
        let grid_vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("strata grid"),
            contents: bytemuck::cast_slice(&grid_lines),
            usage: wgpu::BufferUsages::VERTEX,
        });
        Renderer {
            fill,
            wire,
            grid,
            preview,
            uniforms,
            bind_group,
            chunks: HashMap::new(),
            grid_vertices,
            grid_count: grid_lines.len() as u32,
            preview_buffers: None,
            uploads: 0,
        }
    }

    /// Replaces the GPU data of chunk `key` of `layer` with `mesh` (relative to the chunk's
    /// origin, as the mesh caches store it; the layer's grid is placed in the world by `model`),
    /// coloured `color`. An empty mesh removes the chunk. The chunk's buffers are rewritten in
    /// place when the new mesh fits them (a remeshed chunk rarely grows much) and reallocated
    /// half as large again as needed otherwise, so a stroke mostly writes, not allocates.
    #[allow(clippy::too_many_arguments)]
    pub fn upload_chunk(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        layer: u32,
        key: ChunkKey,
        mesh: &Mesh,
        model: Mat4,
        color: [f32; 3],
    ) {
        if mesh.indices.is_empty() {
            self.chunks.remove(&(layer, key));
            return;
        }
        let model = model * Mat4::from_translation(key.origin_grid().as_vec3());
        let vertices = world_vertices(mesh, model, [color[0], color[1], color[2], 1.0]);
        let edges = edge_indices(&mesh.indices);
        let data: [(&[u8], wgpu::BufferUsages); 3] = [
            (bytemuck::cast_slice(&vertices), wgpu::BufferUsages::VERTEX),
            (bytemuck::cast_slice(&mesh.indices), wgpu::BufferUsages::INDEX),
            (bytemuck::cast_slice(&edges), wgpu::BufferUsages::INDEX),
        ];
        let create = |(bytes, usage): (&[u8], wgpu::BufferUsages)| {
            let size = ((bytes.len() * 3 / 2).div_ceil(4) * 4) as u64;
            let b = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("chunk buffer"),
                size,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            queue.write_buffer(&b, 0, bytes);
            b
        };
        match self.chunks.get_mut(&(layer, key)) {
            Some(c) => {
                for (buffer, d) in [&mut c.vertices, &mut c.triangles, &mut c.edges].into_iter().zip(data) {
                    if buffer.size() >= d.0.len() as u64 {
                        queue.write_buffer(buffer, 0, d.0);
                    } else {
                        *buffer = create(d);
                    }
                }
                c.triangle_indices = mesh.indices.len() as u32;
                c.edge_indices = edges.len() as u32;
            }
            None => {
                let [v, t, e] = data.map(create);
                let chunk = GpuChunk {
                    vertices: v,
                    triangles: t,
                    edges: e,
                    triangle_indices: mesh.indices.len() as u32,
                    edge_indices: edges.len() as u32,
                };
                self.chunks.insert((layer, key), chunk);
            }
        }
        self.uploads += 1;
    }

    /// Drops the buffers of one chunk.
    pub fn remove_chunk(&mut self, layer: u32, key: ChunkKey) {
        self.chunks.remove(&(layer, key));
    }

    /// Drops every chunk of `layer`.
    pub fn clear_layer(&mut self, layer: u32) {
        self.chunks.retain(|(l, _), _| *l != layer);
    }

    /// Drops every chunk.
    pub fn clear(&mut self) {
        self.chunks.clear();
    }

    /// Chunks with buffers.
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Triangles drawn per frame.
    pub fn triangle_count(&self) -> usize {
        self.chunks.values().map(|c| c.triangle_indices as usize / 3).sum()
    }

    /// Chunk uploads since creation.
    pub fn uploads(&self) -> u64 {
        self.uploads
    }

    /// Writes the frame's uniforms and preview buffers; call before [`Renderer::draw`].
    pub fn prepare(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, settings: &FrameSettings<'_>, aspect: f32) {
        let cam = settings.camera;
        // The key light comes from above and to the upper left of the view, so the lit side,
        // the terminator and the shadowed side all show.
        let toward_eye = (cam.eye() - cam.target).normalize_or(Vec3::Z);
        let right = Vec3::Y.cross(toward_eye).normalize_or(Vec3::X);
        let light = (Vec3::Y * 0.8 - right * 0.55 + toward_eye * 0.45).normalize();
        let u = FrameUniforms {
            view_proj: cam.view_proj(aspect).to_cols_array_2d(),
            eye: cam.eye().extend(1.0).to_array(),
            light_dir: light.extend(0.0).to_array(),
            line_color: [0.05, 0.05, 0.06, 1.0],
        };
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&u));
        // All previews in one pair of buffers, each mesh's indices offset past the ones before.
        let (mut vertices, mut indices) = (Vec::new(), Vec::new());
        for p in settings.previews.iter().filter(|p| !p.mesh.indices.is_empty()) {
            let base = vertices.len() as u32;
            vertices.extend(world_vertices(p.mesh, p.model, p.color));
            indices.extend(p.mesh.indices.iter().map(|i| i + base));
        }
        self.preview_buffers = (!indices.is_empty()).then(|| {
            let vb = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("preview vertices"),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::VERTEX,
            });
            let ib = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("preview triangles"),
                contents: bytemuck::cast_slice(&indices),
                usage: wgpu::BufferUsages::INDEX,
            });
            (vb, ib, indices.len() as u32)
        });
    }

    /// Records the draws into `pass` (surfaces, wireframe, grid, then the translucent preview).
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, settings: &FrameSettings<'_>) {
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&self.fill);
        for c in self.chunks.values() {
            pass.set_vertex_buffer(0, c.vertices.slice(..));
            pass.set_index_buffer(c.triangles.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..c.triangle_indices, 0, 0..1);
        }
        if settings.wireframe {
            pass.set_pipeline(&self.wire);
            for c in self.chunks.values() {
                pass.set_vertex_buffer(0, c.vertices.slice(..));
                pass.set_index_buffer(c.edges.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..c.edge_indices, 0, 0..1);
            }
        }
        if settings.grid {
            pass.set_pipeline(&self.grid);
            pass.set_vertex_buffer(0, self.grid_vertices.slice(..));
            pass.draw(0..self.grid_count, 0..1);
        }
        if let Some((vb, ib, n)) = &self.preview_buffers {
            pass.set_pipeline(&self.preview);
            pass.set_vertex_buffer(0, vb.slice(..));
            pass.set_index_buffer(ib.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..*n, 0, 0..1);
        }
    }

    /// Prepares and draws one frame into `color` (cleared to the background) with `depth`.
    pub fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        color: &wgpu::TextureView,
        depth: &wgpu::TextureView,
        size: (u32, u32),
        settings: &FrameSettings<'_>,
    ) {
        self.prepare(device, queue, settings, size.0 as f32 / size.1.max(1) as f32);
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("strata frame") });
        {
            let [r, g, b, a] = settings.background;
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("strata frame"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: color,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            self.draw(&mut pass, settings);
        }
        queue.submit([encoder.finish()]);
    }
}

/// Vertices of `mesh` moved into the world by `model` (normals by its inverse transpose).
fn world_vertices(mesh: &Mesh, model: Mat4, color: [f32; 4]) -> Vec<Vertex> {
    let normal_matrix = Mat3::from_mat4(model).inverse().transpose();
    mesh.positions
        .iter()
        .zip(&mesh.normals)
        .map(|(p, n)| Vertex {
            position: model.transform_point3(Vec3::from(*p)).to_array(),
            normal: (normal_matrix * Vec3::from(*n)).normalize_or(Vec3::Y).to_array(),
            color,
        })
        .collect()
}

/// Line-list indices of every triangle's three edges.
fn edge_indices(triangles: &[u32]) -> Vec<u32> {
    triangles.chunks_exact(3).flat_map(|t| [t[0], t[1], t[1], t[2], t[2], t[0]]).collect()
}

/// The ground grid on y = 0: a line every 8 units over ±256, brighter every 64 and along the
/// x (red) and z (blue) axes.
fn grid_vertices() -> Vec<Vertex> {
    let mut v = Vec::new();
    let extent = 256.0f32;
    let mut line = |a: Vec3, b: Vec3, color: [f32; 4]| {
        for p in [a, b] {
            v.push(Vertex { position: p.to_array(), normal: [0.0, 1.0, 0.0], color });
        }
    };
    for i in -32..=32 {
        let c = i as f32 * 8.0;
        let color = if i == 0 {
            None
        } else if i % 8 == 0 {
            Some([0.5, 0.5, 0.55, 0.45])
        } else {
            Some([0.4, 0.4, 0.45, 0.14])
        };
        let x_axis = color.unwrap_or([0.85, 0.25, 0.25, 0.9]);
        let z_axis = color.unwrap_or([0.25, 0.4, 0.9, 0.9]);
        line(Vec3::new(-extent, 0.0, c), Vec3::new(extent, 0.0, c), x_axis);
        line(Vec3::new(c, 0.0, -extent), Vec3::new(c, 0.0, extent), z_axis);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertices_move_into_the_world_with_normals_kept_unit() {
        let mesh = Mesh {
            positions: vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            normals: vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            indices: vec![0, 1, 2],
            ..Default::default()
        };
        let model =
            Mat4::from_scale_rotation_translation(Vec3::splat(2.0), glam::Quat::from_rotation_y(1.0), Vec3::X * 5.0);
        let v = world_vertices(&mesh, model, [1.0; 4]);
        assert!((Vec3::from(v[1].position) - Vec3::new(5.0, 2.0, 0.0)).length() < 1e-5);
        for x in &v {
            assert!((Vec3::from(x.normal).length() - 1.0).abs() < 1e-5);
        }
        assert_eq!(edge_indices(&mesh.indices), vec![0, 1, 1, 2, 2, 0]);
        // The grid's axis lines are coloured, the others translucent grey.
        assert!(grid_vertices().iter().any(|g| g.color == [0.85, 0.25, 0.25, 0.9]));
    }
}
