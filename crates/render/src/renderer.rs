//! Pipelines, per-mesh GPU buffers and drawing.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Mat3, Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::camera::Camera;

/// Up to four materials of one vertex and their weights in 255ths (summing to 255), heaviest
/// first: the layout of `strata_mesh::VertexMaterial`, so a mesh's materials are lent as they
/// are stored (`bytemuck::cast_slice`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct MaterialBlend {
    /// Palette entries.
    pub ids: [u8; 4],
    /// Their weights.
    pub weights: [u8; 4],
}

/// A triangle mesh as the renderer reads it: plain slices a caller lends (the renderer depends
/// on no mesh or volume crate).
#[derive(Clone, Copy, Debug, Default)]
pub struct MeshRef<'a> {
    /// Vertex positions.
    pub positions: &'a [[f32; 3]],
    /// Unit normals, one per position.
    pub normals: &'a [[f32; 3]],
    /// Materials, one per position, or empty for material 0 throughout.
    pub materials: &'a [MaterialBlend],
    /// Three indices per triangle, counter-clockwise seen from outside.
    pub indices: &'a [u32],
    /// Per vertex, how much a mask holds it (0 to 255: drawn up to [`MASK_DARKENING`] darker),
    /// or empty where nothing is masked.
    pub shade: &'a [u8],
}

/// How much darker a vertex the mask holds fully is drawn.
pub const MASK_DARKENING: f32 = 0.55;

impl MeshRef<'_> {
    /// The materials of vertex `i`.
    fn material(&self, i: usize) -> MaterialBlend {
        self.materials.get(i).copied().unwrap_or(MaterialBlend { ids: [0; 4], weights: [255, 0, 0, 0] })
    }
}

/// Names one mesh the renderer holds. The renderer reads nothing from it but equality: the
/// caller chooses what a group and a key mean (the studio: a scene layer and a chunk's
/// coordinates, the streamed terrain, the debris), and drops a whole group at once with
/// [`Renderer::clear_group`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MeshId {
    /// A set of meshes dropped together.
    pub group: u32,
    /// The mesh within its group.
    pub key: [i32; 3],
}

/// Where a mesh's vertices are drawn: `model · (origin + position)`, the sum taken in `f64` and
/// rounded to `f32` once, so two meshes whose positions are relative to different origins put
/// a shared point on one world position bit for bit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The mesh's frame to the world (a layer's grid placed in the world).
    pub model: Mat4,
    /// Added to every position before `model` (a chunk's origin on its layer's grid).
    pub origin: DVec3,
}

impl Default for Placement {
    fn default() -> Self {
        Placement { model: Mat4::IDENTITY, origin: DVec3::ZERO }
    }
}

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
    /// Linear RGBA (for meshes, a tint over the materials' colours).
    pub color: [f32; 4],
    /// Up to four palette indices.
    pub ids: [u8; 4],
    /// Their weights in 255ths (all zero: no material, the colour alone).
    pub weights: [u8; 4],
}

const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 5] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x4, 3 => Uint8x4, 4 => Unorm8x4];

/// One material of the palette the renderer textures meshes with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaletteEntry {
    /// Linear RGB.
    pub color: [f32; 3],
    /// Layer of the detail texture ([`crate::textures::LAYERS`]).
    pub texture: u32,
    /// World units per texture repeat.
    pub scale: f32,
    /// Perceptual roughness in `[0, 1]`.
    pub roughness: f32,
}

impl Default for PaletteEntry {
    fn default() -> Self {
        PaletteEntry { color: [0.72, 0.62, 0.52], texture: 0, scale: 16.0, roughness: 0.7 }
    }
}

/// Entries of the palette uniform.
pub const PALETTE_SIZE: usize = 256;

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
    /// Unit vector from the target towards the eye; w: 1 orthographic, 0 perspective (lines are
    /// moved towards the eye along it or along their ray to the eye).
    view_axis: [f32; 4],
}

/// A translucent brush preview: a mesh in its own coordinates, placed by `model`.
#[derive(Clone, Copy, Debug)]
pub struct Preview<'a> {
    /// The brush's surface.
    pub mesh: MeshRef<'a>,
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
    /// Reference pictures, drawn behind the previews and blended over what is behind them.
    pub references: &'a [crate::ReferenceQuad<'a>],
}

impl Default for FrameSettings<'_> {
    fn default() -> Self {
        FrameSettings {
            camera: Camera::default(),
            wireframe: false,
            grid: true,
            background: [0.055, 0.06, 0.075, 1.0],
            previews: &[],
            references: &[],
        }
    }
}

/// A mesh made on the GPU and drawn where it lies, without coming back to the CPU (the
/// viewport's GPU meshing: `strata_gpu_mesh`): buffers shared by a batch's meshes (clones of a
/// `wgpu::Buffer` share it), its draw counts written on the GPU as indirect arguments.
#[derive(Clone, Debug)]
pub struct IndirectMesh {
    /// [`Vertex`]es, already in the world.
    pub vertices: wgpu::Buffer,
    /// Triangle-list indices into `vertices`.
    pub triangles: wgpu::Buffer,
    /// Line-list indices into `vertices`: every triangle's three edges (the wireframe).
    pub edges: wgpu::Buffer,
    /// Indirect indexed-draw arguments (`wgpu::util::DrawIndexedIndirectArgs`).
    pub args: wgpu::Buffer,
    /// Byte offset in `args` of this mesh's triangle draw.
    pub triangle_args: u64,
    /// Byte offset in `args` of this mesh's edge draw.
    pub edge_args: u64,
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
    palette: wgpu::Buffer,
    /// The detail texture, filled on the first [`Renderer::prepare`] (which has a queue).
    detail: wgpu::Texture,
    detail_filled: bool,
    bind_group: wgpu::BindGroup,
    meshes: HashMap<MeshId, GpuChunk>,
    /// Meshes made on the GPU (a mesh id is in `meshes` or here, never both).
    indirect: HashMap<MeshId, IndirectMesh>,
    grid_vertices: wgpu::Buffer,
    grid_count: u32,
    preview_buffers: Option<(wgpu::Buffer, wgpu::Buffer, u32)>,
    references: crate::references::ReferencePass,
    uploads: u64,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer").field("meshes", &self.meshes.len()).field("uploads", &self.uploads).finish()
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
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
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
        let palette = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("strata palette"),
            contents: bytemuck::cast_slice(&palette_uniforms(&[PaletteEntry::default()])),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let detail = detail_texture(device);
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("strata frame"),
            layout: &bind_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniforms.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: palette.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&detail.0) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::Sampler(&detail.1) },
            ],
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
        let grid = pipeline("strata grid", "vs_grid", "fs_grid", wgpu::PrimitiveTopology::LineList, true);
        let preview = pipeline("strata preview", "vs_mesh", "fs_preview", wgpu::PrimitiveTopology::TriangleList, true);
        let references = crate::references::ReferencePass::new(device, &shader, &bind_layout, color_format);
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
            palette,
            detail: detail.2,
            detail_filled: false,
            bind_group,
            meshes: HashMap::new(),
            indirect: HashMap::new(),
            grid_vertices,
            grid_count: grid_lines.len() as u32,
            preview_buffers: None,
            references,
            uploads: 0,
        }
    }

    /// Replaces the GPU data of mesh `id` with `mesh`, placed by `placement` and tinted `color`
    /// (multiplying the colours of its vertices' materials, see [`Renderer::set_palette`];
    /// white shows them as they are). An empty mesh removes it. Its buffers are rewritten in
    /// place when the new mesh fits them (a remeshed chunk rarely grows much) and reallocated
    /// half as large again as needed otherwise, so a stroke mostly writes, not allocates.
    pub fn upload_mesh(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        id: MeshId,
        mesh: MeshRef<'_>,
        placement: Placement,
        color: [f32; 3],
    ) {
        self.indirect.remove(&id);
        if mesh.indices.is_empty() {
            self.meshes.remove(&id);
            return;
        }
        let vertices =
            world_vertices(&mesh, placement.model, placement.origin, [color[0], color[1], color[2], 1.0], true);
        let edges = edge_indices(mesh.indices);
        let data: [(&[u8], wgpu::BufferUsages); 3] = [
            (bytemuck::cast_slice(&vertices), wgpu::BufferUsages::VERTEX),
            (bytemuck::cast_slice(mesh.indices), wgpu::BufferUsages::INDEX),
            (bytemuck::cast_slice(&edges), wgpu::BufferUsages::INDEX),
        ];
        let create = |(bytes, usage): (&[u8], wgpu::BufferUsages)| {
            let size = ((bytes.len() * 3 / 2).div_ceil(4) * 4) as u64;
            let b = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("mesh buffer"),
                size,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            queue.write_buffer(&b, 0, bytes);
            b
        };
        match self.meshes.get_mut(&id) {
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
                self.meshes.insert(id, chunk);
            }
        }
        self.uploads += 1;
    }

    /// Shows mesh `id` from buffers the GPU made (replacing what `id` showed). Its buffers are
    /// kept as long as a mesh of theirs is shown.
    pub fn show_indirect(&mut self, id: MeshId, mesh: IndirectMesh) {
        self.meshes.remove(&id);
        self.indirect.insert(id, mesh);
        self.uploads += 1;
    }

    /// Drops the buffers of one mesh.
    pub fn remove_mesh(&mut self, id: MeshId) {
        self.meshes.remove(&id);
        self.indirect.remove(&id);
    }

    /// Drops every mesh of `group`.
    pub fn clear_group(&mut self, group: u32) {
        self.meshes.retain(|id, _| id.group != group);
        self.indirect.retain(|id, _| id.group != group);
    }

    /// Drops every mesh.
    pub fn clear(&mut self) {
        self.meshes.clear();
        self.indirect.clear();
    }

    /// Meshes shown (uploaded and made on the GPU).
    pub fn mesh_count(&self) -> usize {
        self.meshes.len() + self.indirect.len()
    }

    /// Meshes shown that the GPU made ([`Renderer::show_indirect`]).
    pub fn indirect_count(&self) -> usize {
        self.indirect.len()
    }

    /// Whether mesh `id` is shown from buffers the GPU made.
    pub fn is_indirect(&self, id: MeshId) -> bool {
        self.indirect.contains_key(&id)
    }

    /// What mesh `id` is shown from, where the GPU made it.
    pub fn indirect(&self, id: MeshId) -> Option<&IndirectMesh> {
        self.indirect.get(&id)
    }

    /// Triangles drawn per frame of the uploaded meshes (the GPU-made ones' counts stay on the
    /// GPU).
    pub fn triangle_count(&self) -> usize {
        self.meshes.values().map(|c| c.triangle_indices as usize / 3).sum()
    }

    /// Mesh uploads since creation.
    pub fn uploads(&self) -> u64 {
        self.uploads
    }

    /// Reference pictures uploaded since creation (each once while it is kept: see
    /// [`crate::ReferenceQuad`]).
    pub fn picture_uploads(&self) -> u64 {
        self.references.uploads()
    }

    /// Sets the materials meshes are drawn with: entry `i` for material id `i` (ids past the
    /// end are drawn with entry 0; at most [`PALETTE_SIZE`] entries are used).
    pub fn set_palette(&mut self, queue: &wgpu::Queue, entries: &[PaletteEntry]) {
        queue.write_buffer(&self.palette, 0, bytemuck::cast_slice(&palette_uniforms(entries)));
    }

    /// Writes the frame's uniforms and preview buffers; call before [`Renderer::draw`].
    pub fn prepare(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, settings: &FrameSettings<'_>, aspect: f32) {
        if !self.detail_filled {
            for (mip, texels) in crate::textures::detail_mips().iter().enumerate() {
                let side = (crate::textures::SIZE >> mip) as u32;
                queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.detail,
                        mip_level: mip as u32,
                        origin: wgpu::Origin3d::ZERO,
                        aspect: wgpu::TextureAspect::All,
                    },
                    texels,
                    wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(side), rows_per_image: Some(side) },
                    wgpu::Extent3d {
                        width: side,
                        height: side,
                        depth_or_array_layers: crate::textures::LAYERS.len() as u32,
                    },
                );
            }
            self.detail_filled = true;
        }
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
            view_axis: toward_eye.extend(if cam.orthographic { 1.0 } else { 0.0 }).to_array(),
        };
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&u));
        self.references.prepare(device, queue, settings.references, cam.eye());
        // All previews in one pair of buffers, each mesh's indices offset past the ones before.
        let (mut vertices, mut indices) = (Vec::new(), Vec::new());
        for p in settings.previews.iter().filter(|p| !p.mesh.indices.is_empty()) {
            let base = vertices.len() as u32;
            vertices.extend(world_vertices(&p.mesh, p.model, DVec3::ZERO, p.color, false));
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

    /// Records the draws into `pass` (surfaces, wireframe, grid, reference pictures, then the
    /// translucent preview).
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, settings: &FrameSettings<'_>) {
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&self.fill);
        for c in self.meshes.values() {
            pass.set_vertex_buffer(0, c.vertices.slice(..));
            pass.set_index_buffer(c.triangles.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..c.triangle_indices, 0, 0..1);
        }
        for m in self.indirect.values() {
            pass.set_vertex_buffer(0, m.vertices.slice(..));
            pass.set_index_buffer(m.triangles.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed_indirect(&m.args, m.triangle_args);
        }
        if settings.wireframe {
            pass.set_pipeline(&self.wire);
            for c in self.meshes.values() {
                pass.set_vertex_buffer(0, c.vertices.slice(..));
                pass.set_index_buffer(c.edges.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..c.edge_indices, 0, 0..1);
            }
            for m in self.indirect.values() {
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                pass.set_index_buffer(m.edges.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed_indirect(&m.args, m.edge_args);
            }
        }
        if settings.grid {
            pass.set_pipeline(&self.grid);
            pass.set_vertex_buffer(0, self.grid_vertices.slice(..));
            pass.draw(0..self.grid_count, 0..1);
        }
        // (After the grid: grid lines behind a picture are covered by it, not drawn over it.)
        self.references.draw(pass, &self.bind_group);
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

/// The palette as the shader's uniform block: per entry (colour, 0) then (layer, scale,
/// roughness, 0); unused entries repeat entry 0.
fn palette_uniforms(entries: &[PaletteEntry]) -> Vec<[f32; 4]> {
    let first = entries.first().copied().unwrap_or_default();
    (0..PALETTE_SIZE)
        .flat_map(|i| {
            let e = entries.get(i).copied().unwrap_or(first);
            let layer = e.texture.min(crate::textures::LAYERS.len() as u32 - 1) as f32;
            let scale = if e.scale.is_finite() && e.scale > 0.0 { e.scale } else { 16.0 };
            [[e.color[0], e.color[1], e.color[2], 0.0], [layer, scale, e.roughness.clamp(0.0, 1.0), 0.0]]
        })
        .collect()
}

/// The (empty) detail texture array with its full mip chain, its view and its repeating sampler.
fn detail_texture(device: &wgpu::Device) -> (wgpu::TextureView, wgpu::Sampler, wgpu::Texture) {
    let side = crate::textures::SIZE as u32;
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("strata detail textures"),
        size: wgpu::Extent3d { width: side, height: side, depth_or_array_layers: crate::textures::LAYERS.len() as u32 },
        mip_level_count: side.trailing_zeros() + 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let view = texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("strata detail sampler"),
        address_mode_u: wgpu::AddressMode::Repeat,
        address_mode_v: wgpu::AddressMode::Repeat,
        address_mode_w: wgpu::AddressMode::Repeat,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        ..Default::default()
    });
    (view, sampler, texture)
}

/// The vertices [`Renderer::upload_mesh`] draws for `mesh` placed by `placement` and tinted
/// `color` (for checking meshes the GPU places against the CPU's placing).
pub fn placed_vertices(mesh: &MeshRef<'_>, placement: Placement, color: [f32; 3]) -> Vec<Vertex> {
    world_vertices(mesh, placement.model, placement.origin, [color[0], color[1], color[2], 1.0], true)
}

/// Vertices of `mesh` (positions relative to `origin`, a chunk's origin in the layer's grid)
/// moved into the world by `model` (normals by its inverse transpose).
///
/// Positions are placed in f64 and rounded to f32 once: the vertices two neighbouring chunks
/// share on their common face have the same grid position (origin + local is exact), so they
/// land on the same f32 world position bit for bit and the chunk meshes meet without cracks.
/// Composing `model · translate(origin)` in f32 per chunk instead rounds each chunk's product
/// differently, and under a rotated or scaled layer the shared vertices of neighbours differed
/// by an ulp or so.
fn world_vertices(
    mesh: &MeshRef<'_>,
    model: Mat4,
    origin: DVec3,
    color: [f32; 4],
    with_materials: bool,
) -> Vec<Vertex> {
    let normal_matrix = Mat3::from_mat4(model).inverse().transpose();
    let world_from_grid = model.as_dmat4();
    mesh.positions
        .iter()
        .zip(mesh.normals)
        .enumerate()
        .map(|(i, (p, n))| {
            let m = mesh.material(i);
            let dark = 1.0 - MASK_DARKENING * mesh.shade.get(i).map_or(0.0, |&s| s as f32 / 255.0);
            let color = [color[0] * dark, color[1] * dark, color[2] * dark, color[3]];
            Vertex {
                position: world_from_grid.transform_point3(origin + Vec3::from(*p).as_dvec3()).as_vec3().to_array(),
                normal: (normal_matrix * Vec3::from(*n)).normalize_or(Vec3::Y).to_array(),
                color,
                ids: m.ids,
                weights: if with_materials { m.weights } else { [0; 4] },
            }
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
            v.push(Vertex { position: p.to_array(), normal: [0.0, 1.0, 0.0], color, ids: [0; 4], weights: [0; 4] });
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
        let mesh = MeshRef {
            positions: &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            normals: &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            indices: &[0, 1, 2],
            ..Default::default()
        };
        let model =
            Mat4::from_scale_rotation_translation(Vec3::splat(2.0), glam::Quat::from_rotation_y(1.0), Vec3::X * 5.0);
        let v = world_vertices(&mesh, model, DVec3::ZERO, [1.0; 4], true);
        assert!((Vec3::from(v[1].position) - Vec3::new(5.0, 2.0, 0.0)).length() < 1e-5);
        for x in &v {
            assert!((Vec3::from(x.normal).length() - 1.0).abs() < 1e-5);
        }
        assert_eq!(edge_indices(mesh.indices), vec![0, 1, 1, 2, 2, 0]);
        // A masked vertex is drawn darker, in proportion to its weight.
        let shaded = MeshRef { shade: &[0, 255, 51], ..mesh };
        let v = world_vertices(&shaded, model, DVec3::ZERO, [1.0; 4], true);
        assert_eq!(v[0].color, [1.0; 4]);
        assert!((v[1].color[0] - (1.0 - MASK_DARKENING)).abs() < 1e-6 && v[1].color[3] == 1.0);
        assert!((v[2].color[1] - (1.0 - 0.2 * MASK_DARKENING)).abs() < 1e-6);
        // The grid's axis lines are coloured, the others translucent grey.
        assert!(grid_vertices().iter().any(|g| g.color == [0.85, 0.25, 0.25, 0.9]));
    }

    #[test]
    fn neighbouring_chunks_put_their_shared_vertices_on_one_world_position() {
        // A layer turned, scaled and moved as the studio's layers are, far enough from the
        // origin that an f32 rounding is worth about 1e-5 units.
        let model = Mat4::from_scale_rotation_translation(
            Vec3::splat(0.3),
            glam::Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 0.2),
            Vec3::new(123.4, -56.7, 88.9),
        );
        let cells = 16.0f32;
        let mut differ = 0;
        for i in 0..400 {
            // A vertex on the face x = 16 of chunk (k, 2, -3), which is x = 0 of chunk (k + 1, 2, -3):
            // marching cubes places both copies from the same crossing.
            let k = i % 20 - 10;
            let (y, z) = ((i as f32 * 0.137).fract() * cells, (i as f32 * 0.291).fract() * cells);
            let (low, high) = ([[cells, y, z]], [[0.0, y, z]]);
            fn chunk(p: &[[f32; 3]]) -> MeshRef<'_> {
                MeshRef { positions: p, normals: &[[1.0, 0.0, 0.0]], ..Default::default() }
            }
            let origin = |kx: i32| DVec3::new(f64::from(kx), 2.0, -3.0) * f64::from(cells);
            let a = world_vertices(&chunk(&low), model, origin(k), [1.0; 4], false);
            let b = world_vertices(&chunk(&high), model, origin(k + 1), [1.0; 4], false);
            differ += usize::from(a[0].position.map(f32::to_bits) != b[0].position.map(f32::to_bits));
        }
        assert_eq!(differ, 0, "{differ} of 400 shared vertices land on different world positions (a crack)");
    }
}
