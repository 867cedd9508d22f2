//! # strata-gpu-mesh
//!
//! Surface extraction in wgpu compute. [`GpuMarcher`] meshes many voxel blocks in one batch of
//! dispatches into GPU buffers a renderer can draw from directly: the same mesh as the CPU's
//! [`strata_mesh::mesh_block`], bit for bit in its positions and triangles (normals are
//! unpacked in `f32` on the GPU and in `f64` on the CPU, so they agree to a few ulps). The WGSL
//! is `shaders/marching_cubes.wgsl` (its passes are described there); it binds at most four
//! storage buffers a stage, so it runs on downlevel adapters too, lavapipe included.
//!
//! What is uploaded per block: its node bits (a word a row of up to 32 nodes), per axis and
//! line along it the crossings on the lines before and the crossed edges' bits (a crossing's
//! index is its rank: those plus the crossed edges before it on its line, counted on the GPU; a
//! block whose crossings are not listed line by line uploads the whole lookup instead), its
//! node materials (four a word,
//! for a block that has any but material 0) and its crossings (lower node, `t`, packed normal).
//! Each vertex gets the material of its edge's solid end, as the CPU's vertices do. Blocks
//! with seams (a face shared with a finer neighbour) have their triangles split at the finer
//! mesh's vertices there, as the CPU patches cracks: the seam points are uploaded as vertices,
//! and a `split` pass rewrites the block's triangles after the others.
//!
//! For the viewport, [`GpuMarcher::mesh_for_drawing`] also places the renderer's vertices in
//! the world and writes each block's indirect draw arguments and wireframe lines, so
//! `strata_render::Renderer::show_indirect` draws the meshes where they were made (the
//! viewport's residency and CPU fallbacks are `strata_viewport::GpuMeshing`'s).
//!
//! Dual contouring: [`GpuMarcher::dual_vertices`] solves every mixed cell's component
//! vertices (`shaders/dual_contouring.wgsl`), [`GpuMarcher::dual_mesh`] joins them into the
//! CPU's quads too (at one level, and across levels as the CPU joins a volume whose chunks
//! differ in level: [`DualJoin`]), both read back, and [`GpuMarcher::mesh_dual_for_drawing`]
//! makes the same for drawing, nothing read back.
#![warn(missing_docs)]

use bytemuck::{Pod, Zeroable};
use strata_mesh::{DualVertex, Mesh};
use strata_render::{IndirectMesh, Placement};
use strata_volume::{Axis, VoxelBlock};
use thiserror::Error;

/// The WGSL source: marching cubes, then dual contouring's vertices (which use its bindings and
/// helpers), one module.
pub const SHADER: &str = concat!(
    include_str!("../../../shaders/marching_cubes.wgsl"),
    include_str!("../../../shaders/dual_contouring.wgsl")
);

/// Threads of a chunk's workgroup (the shader's `THREADS`).
const THREADS: u32 = 256;
/// Words of the case table at the start of the data buffer.
const TABLE_WORDS: usize = 256 * 16;
/// Words of dual contouring's component table after it (the shader's `DUAL_TABLE`).
const DUAL_TABLE_WORDS: usize = 256 * 5;
/// Words of a dual-contouring vertex read back: cell, edges, position, normal, ids, weights.
const DUAL_WORDS: u64 = 10;
/// A crossing's lookup entry where a node's edge has none.
const NONE: u32 = u32::MAX;
/// Words of a vertex in [`GpuBatch::vertices`]: position, normal, the material id's bits.
pub const VERTEX_WORDS: u64 = 7;
/// The largest block taken, in cells a side (its rows of nodes are `u128`s).
pub const MAX_CELLS: usize = 127;

/// Why the GPU did not mesh.
#[derive(Debug, Error, PartialEq)]
pub enum GpuMeshError {
    /// The device lacks a limit the shader needs.
    #[error("the GPU lacks what meshing needs: {0}")]
    Limits(String),
    /// A block is larger than the shader takes ([`MAX_CELLS`] a side) or the batch larger than
    /// the device's buffers or dispatches allow (mesh it in smaller batches).
    #[error("the batch is too large for one dispatch: {0}")]
    TooLarge(String),
    /// Reading the results back failed (the device was lost).
    #[error("reading the GPU's mesh back failed: {0}")]
    Readback(String),
    /// The device reported an error while meshing (lost, out of memory).
    #[error("the GPU failed while meshing: {0}")]
    Device(String),
}

/// How dual contouring's quads join the cells around each edge, as the CPU's
/// [`strata_mesh::DualCache`] joins them: the form it takes depends on the volume, not on the
/// batch (a batch of one level from a volume that mixes levels is joined across levels).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DualJoin {
    /// A volume of one level: quads of the edges a chunk owns (its lower node in the chunk on
    /// the axes across it), through face midpoints where a component runs through both of a
    /// face's segments, fanned from a centre then.
    OneLevel,
    /// A volume whose chunks differ in level (or have differed: the CPU's cache keeps this form
    /// once it has taken it): a polygon per sign-changing edge of the finest level around it,
    /// made by the finest chunk there, a triangle where a coarser cell holds two of its cells.
    AcrossLevels,
}

/// What the shader needs of a device, checked by [`GpuMarcher::new`].
pub fn check_limits(limits: &wgpu::Limits) -> Result<(), GpuMeshError> {
    let needs = [
        ("storage buffers a compute stage", limits.max_storage_buffers_per_shader_stage, 4),
        ("compute workgroup size x", limits.max_compute_workgroup_size_x, THREADS),
        ("compute invocations a workgroup", limits.max_compute_invocations_per_workgroup, THREADS),
        ("compute workgroups a dimension", limits.max_compute_workgroups_per_dimension, 1024),
    ];
    for (what, has, need) in needs {
        if has < need {
            return Err(GpuMeshError::Limits(format!("{what}: {has}, needs {need}")));
        }
    }
    Ok(())
}

/// Whether an adapter can draw what [`GpuMarcher::mesh_for_drawing`] makes: besides
/// [`check_limits`], indirect draws (WebGL and some downlevel adapters lack them).
pub fn check_drawing(adapter: &wgpu::Adapter) -> Result<(), GpuMeshError> {
    check_limits(&adapter.limits())?;
    if !adapter.get_downlevel_capabilities().flags.contains(wgpu::DownlevelFlags::INDIRECT_EXECUTION) {
        return Err(GpuMeshError::Limits("indirect draws".into()));
    }
    Ok(())
}

/// A block as the shader reads it (the WGSL `Chunk`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ChunkInfo {
    n: u32,
    m: u32,
    words: u32,
    node_base: u32,
    lookup_base: u32,
    vertex_base: u32,
    y_base: u32,
    z_base: u32,
    spacing: f32,
    offset: [u32; 3],
    material_base: u32,
    rows_base: u32,
    crossing_base: u32,
    seam_base: u32,
    seam_slot: u32,
    seam_out: u32,
    centroid_first: u32,
    pair_base: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Params {
    chunk_count: u32,
    crossing_count: u32,
    place_row: u32,
    edge_row: u32,
    vertex_total: u32,
    triangle_slots: u32,
    extra_base: u32,
    extra_count: u32,
    seam_list_base: u32,
    /// Dual contouring's quads joined across levels (1) or at one level (0).
    mixed: u32,
    unused: [u32; 2],
}

/// A block's placement as the shader reads it (the WGSL `Placement`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct PlacementInfo {
    model: [[f32; 4]; 4],
    normal: [[f32; 4]; 3],
    origin: [f32; 4],
    tint: [f32; 4],
}

impl PlacementInfo {
    fn of(placement: &Placement, tint: [f32; 3]) -> Result<Self, GpuMeshError> {
        let o = placement.origin;
        // The origin is added in f32: exact for whole grid units below 2²⁴ (chunk origins).
        if !(o.is_finite() && o.abs().max_element() < (1u32 << 24) as f64 && o == o.round()) {
            return Err(GpuMeshError::TooLarge(format!("an origin the GPU cannot add exactly: {o}")));
        }
        let n = glam::Mat3::from_mat4(placement.model).inverse().transpose();
        Ok(PlacementInfo {
            model: placement.model.to_cols_array_2d(),
            normal: [n.x_axis.extend(0.0).to_array(), n.y_axis.extend(0.0).to_array(), n.z_axis.extend(0.0).to_array()],
            origin: [o.x as f32, o.y as f32, o.z as f32, 0.0],
            tint: [tint[0], tint[1], tint[2], 1.0],
        })
    }
}

/// Where [`GpuMarcher::mesh_for_drawing`] draws a block: as the renderer places an uploaded
/// chunk mesh ([`Placement`]: `model · (origin + position)`, `origin` whole grid units), tinted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrawPlacement {
    /// The block's chunk placed in the world.
    pub placement: Placement,
    /// Multiplies the materials' colours (white: as they are).
    pub tint: [f32; 3],
}

/// A batch meshed on the GPU for drawing ([`GpuMarcher::mesh_for_drawing`]): per block, the
/// renderer's [`IndirectMesh`] (sharing the batch's buffers), and the batch itself (for reading
/// back in tests).
#[derive(Debug)]
pub struct DrawBatch {
    /// The batch.
    pub batch: GpuBatch,
    /// Per block, what the renderer draws.
    pub meshes: Vec<IndirectMesh>,
    /// The renderer's vertices of the whole batch (12 words a vertex, as [`strata_render::Vertex`]).
    pub drawn: wgpu::Buffer,
}

/// The case table as the shader reads it (see the WGSL).
fn case_table() -> Vec<u32> {
    let mut out = vec![0u32; TABLE_WORDS + DUAL_TABLE_WORDS];
    for case in 0..=255u8 {
        let tris = strata_mesh::case_triangles(case);
        let at = case as usize * 16;
        out[at] = tris.len() as u32;
        for (j, (axis, lower)) in tris.iter().flatten().enumerate() {
            out[at + 1 + j] = *axis as u32 | (lower[0] as u32) << 2 | (lower[1] as u32) << 3 | (lower[2] as u32) << 4;
        }
        let components = strata_mesh::case_components(case);
        let at = TABLE_WORDS + case as usize * 5;
        out[at] = components.len() as u32;
        for (j, mask) in components.iter().enumerate() {
            out[at + 1 + j] = *mask as u32;
        }
    }
    out
}

/// A batch meshed on the GPU: one vertex buffer ([`VERTEX_WORDS`] words a vertex: position,
/// normal, the bits of its material id) and one index buffer for all its blocks, and where each
/// block's part is.
#[derive(Debug)]
pub struct GpuBatch {
    /// [`VERTEX_WORDS`] words a vertex: position (grid units from the block's chunk origin),
    /// normal, then the material id's bits (the material of its edge's solid end).
    pub vertices: wgpu::Buffer,
    /// Three `u32` a triangle, indexing `vertices` (the whole batch's).
    pub indices: wgpu::Buffer,
    /// Per block: its first vertex and its vertex room (its crossings', its seam points' and
    /// room for the centroids of split triangles).
    pub vertex_ranges: Vec<(u32, u32)>,
    /// Per block: its crossings and seam points (the vertices before its centroids), and its
    /// ordinal among the blocks with seams.
    seams: Vec<(u32, Option<u32>)>,
    /// Per block, its first triangle slot where it has seams (its triangles are split there).
    seam_out: Vec<u32>,
    /// Per block: whether its nodes have materials (its vertices' material ids mean something).
    pub with_materials: Vec<bool>,
    /// Words of `indices` written at most (the batch's capacity).
    pub index_capacity: u64,
    scratch: wgpu::Buffer,
    chunk_count: u32,
}

/// The pipelines of the marching-cubes passes.
#[derive(Debug)]
pub struct GpuMarcher {
    count: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    emit: wgpu::ComputePipeline,
    place: wgpu::ComputePipeline,
    place_extra: wgpu::ComputePipeline,
    split: wgpu::ComputePipeline,
    world: wgpu::ComputePipeline,
    draw_args: wgpu::ComputePipeline,
    edge_lines: wgpu::ComputePipeline,
    dual_count: wgpu::ComputePipeline,
    dual_emit: wgpu::ComputePipeline,
    quad_count: wgpu::ComputePipeline,
    quad_scan: wgpu::ComputePipeline,
    quad_emit: wgpu::ComputePipeline,
    dual_world: wgpu::ComputePipeline,
    dual_args: wgpu::ComputePipeline,
    table: Vec<u32>,
    /// Times the compute pass of each batch on the GPU, where the device has timestamp queries
    /// ([`GpuMarcher::enable_timer`]).
    timer: Option<GpuTimer>,
    /// Upload every block's whole crossing lookup, as for blocks whose crossings are not listed
    /// in rank order (off: the smaller row counts where they serve; on: for tests of that path).
    pub whole_lookups: bool,
}

impl GpuMarcher {
    /// The pipelines on `device`, refused with [`GpuMeshError::Limits`] when it lacks what the
    /// shader needs.
    pub fn new(device: &wgpu::Device) -> Result<Self, GpuMeshError> {
        check_limits(&device.limits())?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("strata marching_cubes.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        Ok(GpuMarcher {
            count: pipeline("count"),
            scan: pipeline("scan_chunks"),
            emit: pipeline("emit"),
            place: pipeline("place"),
            place_extra: pipeline("place_extra"),
            split: pipeline("split"),
            world: pipeline("world"),
            draw_args: pipeline("draw_args"),
            edge_lines: pipeline("edge_lines"),
            dual_count: pipeline("dual_count"),
            dual_emit: pipeline("dual_emit"),
            quad_count: pipeline("quad_count"),
            quad_scan: pipeline("quad_scan"),
            quad_emit: pipeline("quad_emit"),
            dual_world: pipeline("dual_world"),
            dual_args: pipeline("dual_args"),
            table: case_table(),
            timer: None,
            whole_lookups: false,
        })
    }

    /// Times every batch's compute pass with timestamp queries from now on (read with
    /// [`GpuMarcher::last_gpu_time`]); `false` where the device was not created with
    /// `wgpu::Features::TIMESTAMP_QUERY`.
    pub fn enable_timer(&mut self, device: &wgpu::Device, queue: &wgpu::Queue) -> bool {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return false;
        }
        let set = device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("gpu mesh timer"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let buffer = |usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("gpu mesh timestamps"),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        let resolve = buffer(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC);
        let period = queue.get_timestamp_period() as f64;
        self.timer = Some(GpuTimer { set, resolve, period });
        true
    }

    /// The GPU's time for the last batch's compute pass (waits for it), where the timer is on.
    pub fn last_gpu_time(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Option<std::time::Duration> {
        let timer = self.timer.as_ref()?;
        let words = read_words(device, queue, &timer.resolve, 4).ok()?;
        let (start, end) = (words[0] as u64 | (words[1] as u64) << 32, words[2] as u64 | (words[3] as u64) << 32);
        let nanos = end.checked_sub(start)? as f64 * timer.period;
        Some(std::time::Duration::from_nanos(nanos as u64))
    }

    /// The compute pass's timestamp writes, where the timer is on.
    fn timestamps(&self) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        self.timer.as_ref().map(|t| wgpu::ComputePassTimestampWrites {
            query_set: &t.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        })
    }

    /// The wireframe's pass: every triangle slot's lines (none where there is no room).
    fn dispatch_lines(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        group: &wgpu::BindGroup,
        slots: u64,
        groups: (u32, u32),
    ) {
        if slots > 0 {
            pass.set_pipeline(&self.edge_lines);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        }
    }

    /// Resolves the timer's queries into its buffer, after the pass.
    fn resolve_timer(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(t) = &self.timer {
            encoder.resolve_query_set(&t.set, 0..2, &t.resolve, 0);
        }
    }

    /// Meshes `blocks` (their cells `0..n`, as [`strata_mesh::mesh_block`] does, seams split)
    /// into one batch, submitted to `queue`. A batch whose buffers or dispatches would pass the
    /// device's limits is refused
    /// ([`GpuMeshError::TooLarge`], checked before anything is built: mesh it in parts).
    pub fn mesh(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        blocks: &[&VoxelBlock],
    ) -> Result<GpuBatch, GpuMeshError> {
        Ok(self.build(device, queue, blocks, None)?.0)
    }

    /// [`GpuMarcher::mesh`], then the renderer's vertices placed by `placements` (one a block),
    /// each block's indirect draw arguments and the wireframe's edges, all on the GPU: the
    /// meshes are drawn from where they were made ([`strata_render::Renderer::show_indirect`]),
    /// nothing read back. The adapter must execute indirect draws ([`check_drawing`]).
    pub fn mesh_for_drawing(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        blocks: &[&VoxelBlock],
        placements: &[DrawPlacement],
    ) -> Result<DrawBatch, GpuMeshError> {
        if placements.len() != blocks.len() {
            return Err(GpuMeshError::TooLarge(format!("{} placements for {} blocks", placements.len(), blocks.len())));
        }
        let (batch, draw) = self.build(device, queue, blocks, Some(placements))?;
        let (drawn, args, edges) = draw.expect("asked for");
        let stride = 40u64;
        let meshes = (0..blocks.len() as u64)
            .map(|k| IndirectMesh {
                vertices: drawn.clone(),
                triangles: batch.indices.clone(),
                edges: edges.clone(),
                args: args.clone(),
                triangle_args: k * stride,
                edge_args: k * stride + 20,
            })
            .collect();
        Ok(DrawBatch { batch, meshes, drawn })
    }

    /// Manifold dual contouring's vertices of `blocks`, placed on the GPU and read back: per
    /// block, what [`strata_mesh::dual_vertices`] gives on the CPU (same cells, components,
    /// normals and materials; positions solved in `f32`, within 1e-4 cells of the CPU's `f64`).
    /// The quads that join them are the CPU's ([`strata_mesh::DualCache`]).
    pub fn dual_vertices(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        blocks: &[&VoxelBlock],
    ) -> Result<Vec<Vec<DualVertex>>, GpuMeshError> {
        let run = self.dual_run(device, queue, blocks, None)?;
        let mut out = Vec::with_capacity(blocks.len());
        for k in 0..blocks.len() {
            let (from, to) = (run.first(k), run.first(k + 1));
            let part = run.vertices.get(from * 10..to * 10).ok_or_else(|| {
                GpuMeshError::Readback(format!("block {k}'s vertices {from}..{to} pass what was read"))
            })?;
            out.push(part.chunks_exact(10).map(dual_vertex).collect());
        }
        Ok(out)
    }

    /// Manifold dual contouring on the GPU, vertices and quads, read back: per block of
    /// `blocks` marked in `meshed`, the mesh of the edges it owns, as the CPU's
    /// [`strata_mesh::DualCache`] makes it by `join` (positions in the block's chunk frame; a
    /// quad's diagonal may differ where both are equally flat, vertices are not shared between
    /// polygons). The blocks around a meshed one lend their cells' vertices where they are in
    /// the batch: for [`DualJoin::OneLevel`] those before it on the axes across its edges (−x,
    /// −y, −z and their pairs), all of one level; for [`DualJoin::AcrossLevels`] all 26 around
    /// it (`ChunkKey::around`), of any levels.
    pub fn dual_mesh(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        blocks: &[&VoxelBlock],
        meshed: &[bool],
        join: DualJoin,
    ) -> Result<Vec<Mesh>, GpuMeshError> {
        if meshed.len() != blocks.len() {
            return Err(GpuMeshError::TooLarge(format!("{} flags for {} blocks", meshed.len(), blocks.len())));
        }
        let run = self.dual_run(device, queue, blocks, Some((meshed, join)))?;
        let dual_total = run.first(blocks.len());
        // Every vertex's position, normal and material, and its block (extras: the block they
        // were made for).
        let vertex = |i: usize| -> Result<(DualVertex, usize), GpuMeshError> {
            let v = run
                .vertices
                .get(i * 10..i * 10 + 10)
                .ok_or_else(|| GpuMeshError::Readback(format!("vertex {i} past what was read")))?;
            let block = if i < dual_total {
                (0..blocks.len()).rfind(|&k| run.first(k) <= i).unwrap_or(0)
            } else {
                v[1] as usize
            };
            Ok((dual_vertex(v), block))
        };
        let mut out = Vec::with_capacity(blocks.len());
        for (k, block) in blocks.iter().enumerate() {
            let (from, to) = (run.quad_first(k), run.quad_first(k + 1));
            let indices = run.indices.get(from * 3..to * 3).ok_or_else(|| {
                GpuMeshError::Readback(format!("block {k}'s triangles {from}..{to} pass what was read"))
            })?;
            let key = block.key().unwrap_or(strata_volume::ChunkKey::new(0, 0, 0));
            let mut mesh = Mesh::default();
            let mut local: std::collections::HashMap<u32, u32> = Default::default();
            for &i in indices {
                let next = mesh.positions.len() as u32;
                let id = match local.get(&i) {
                    Some(&id) => id,
                    None => {
                        let (v, b) = vertex(i as usize)?;
                        let shift = if (i as usize) < dual_total {
                            let other = blocks[b].key().unwrap_or(key);
                            (other.0 - key.0).as_vec3() * 16.0
                        } else {
                            glam::Vec3::ZERO
                        };
                        mesh.push_vertex((v.position + shift).to_array(), v.normal.to_array(), v.material, false);
                        local.insert(i, next);
                        next
                    }
                };
                mesh.indices.push(id);
            }
            out.push(mesh);
        }
        Ok(out)
    }

    /// Runs dual contouring's passes on `blocks`: the vertices, and with `meshed` the quads too.
    fn dual_run(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        blocks: &[&VoxelBlock],
        meshed: Option<(&[bool], DualJoin)>,
    ) -> Result<DualRun, GpuMeshError> {
        let submitted = self.dual_submit(device, queue, blocks, meshed, None)?;
        submitted.read(device, queue, meshed.is_some())
    }

    /// Dual contouring made on the GPU and drawn from there: [`GpuMarcher::dual_mesh`]
    /// without the read-back, each vertex placed in the world by its chunk's placement (one a
    /// block), each meshed block's indirect arguments and its wireframe's lines written on the
    /// GPU. Per block a [`IndirectMesh`] for the renderer (empty for the blocks that only lend
    /// vertices). The adapter must execute indirect draws ([`check_drawing`]).
    pub fn mesh_dual_for_drawing(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        blocks: &[&VoxelBlock],
        meshed: &[bool],
        placements: &[DrawPlacement],
        join: DualJoin,
    ) -> Result<DualDrawBatch, GpuMeshError> {
        if meshed.len() != blocks.len() || placements.len() != blocks.len() {
            return Err(GpuMeshError::TooLarge(format!(
                "{} flags and {} placements for {} blocks",
                meshed.len(),
                placements.len(),
                blocks.len()
            )));
        }
        let submitted = self.dual_submit(device, queue, blocks, Some((meshed, join)), Some(placements))?;
        let (drawn, args, edges) = submitted.drawing.clone().expect("asked for");
        let meshes = (0..blocks.len() as u64)
            .map(|k| IndirectMesh {
                vertices: drawn.clone(),
                triangles: submitted.indices.clone(),
                edges: edges.clone(),
                args: args.clone(),
                triangle_args: k * 40,
                edge_args: k * 40 + 20,
            })
            .collect();
        Ok(DualDrawBatch { meshes, submitted })
    }

    /// Submits dual contouring's passes (see [`GpuMarcher::dual_mesh`]), and with `draw` the
    /// drawing passes too.
    fn dual_submit(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        blocks: &[&VoxelBlock],
        meshed: Option<(&[bool], DualJoin)>,
        draw: Option<&[DrawPlacement]>,
    ) -> Result<DualSubmitted, GpuMeshError> {
        let mixed = matches!(meshed, Some((_, DualJoin::AcrossLevels)));
        // The quad passes find a crossing by its rank on its line: blocks that crack patching
        // filled from a dense grid (y and z crossings in node order) are listed again (copies
        // holding the same crossings); one that still cannot be (two crossings on one edge: no
        // block this crate's extraction makes) is refused.
        let relisted: Vec<Option<VoxelBlock>> = match meshed {
            Some(_) => blocks
                .iter()
                .map(|b| {
                    if line_counts(b).is_some() {
                        return Ok(None);
                    }
                    let mut copy = (*b).clone();
                    copy.list_line_by_line();
                    match line_counts(&copy) {
                        Some(_) => Ok(Some(copy)),
                        None => Err(GpuMeshError::TooLarge("a block's crossings cannot be listed line by line".into())),
                    }
                })
                .collect::<Result<_, _>>()?,
            None => Vec::new(),
        };
        let listed: Vec<&VoxelBlock> =
            blocks.iter().enumerate().map(|(k, b)| relisted.get(k).and_then(Option::as_ref).unwrap_or(b)).collect();
        let blocks = &listed[..];
        let (max_groups, binding) = batch_limits(device, blocks)?;
        let chunk_count = blocks.len() as u32;
        let crossings: u64 = blocks.iter().map(|b| crossing_count(b)).sum();
        let words: u64 = blocks.iter().map(|b| block_words(b) + 2 * crossing_count(b) + 20 + 27).sum::<u64>()
            + self.table.len() as u64;
        let dual_room: u64 = blocks.iter().map(|b| 4 * mixed_cells(b)).sum();
        // Quads: at most five extra vertices and eight triangles an owned crossing.
        let (extra_room, index_room) = if meshed.is_some() { (5 * crossings, 24 * crossings) } else { (0, 0) };
        let n = blocks.len() as u64;
        // Per thread and chunk: the vertex counts and scans, the quad counts and scans; then each
        // chunk's cell table (its cells' first vertices, n³ words).
        let tables = n * (THREADS as u64 + 2) + 1 + n * THREADS as u64 * 2 + n * 2 + (n + 1) * 2;
        let scratch_words = tables + blocks.iter().map(|b| (b.cells() as u64).pow(3)).sum::<u64>();
        let drawing = draw.is_some() as u64;
        check_sizes(
            binding,
            &[
                ("block data", words),
                ("vertices", (dual_room + extra_room) * DUAL_WORDS),
                ("drawn vertices", drawing * (dual_room + extra_room) * 12),
                ("indices", index_room),
                ("edge indices", drawing * index_room * 2),
                ("scratch", scratch_words),
            ],
        )?;
        let key_of = |b: &VoxelBlock| b.key().unwrap_or(strata_volume::ChunkKey::new(0, 0, 0));
        let index_of: std::collections::HashMap<strata_volume::ChunkKey, u32> =
            blocks.iter().enumerate().map(|(k, b)| (key_of(b), k as u32)).collect();
        if meshed.is_some() {
            let level = blocks.first().map(|b| b.level());
            if !mixed && blocks.iter().any(|b| Some(b.level()) != level) {
                return Err(GpuMeshError::TooLarge(
                    "dual contouring's quads of one level take blocks of one level (join them across levels)".into(),
                ));
            }
        }
        // The neighbours that lend vertices: −x, −y, −z, −x−y, −y−z, −z−x at one level; across
        // levels all 27 offsets, (dx + 1) + 3 (dy + 1) + 9 (dz + 1).
        let offsets: Vec<glam::IVec3> = if mixed {
            (0..27).map(|i| glam::IVec3::new(i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1)).collect()
        } else {
            [[-1, 0, 0], [0, -1, 0], [0, 0, -1], [-1, -1, 0], [0, -1, -1], [-1, 0, -1]]
                .map(glam::IVec3::from_array)
                .to_vec()
        };
        let mut data = self.table.clone();
        let mut infos = Vec::with_capacity(blocks.len());
        let mut cell_table = tables;
        for (k, block) in blocks.iter().enumerate() {
            let n = block.cells();
            if n > MAX_CELLS {
                return Err(GpuMeshError::TooLarge(format!("a block of {n} cells a side (at most {MAX_CELLS})")));
            }
            let BlockWords { words, node_base, lookup_base, rows_base, material_base } =
                upload_block(&mut data, block, self.whole_lookups && meshed.is_none());
            // Each crossing's t and packed normal, in the block's order (x, then y, then z).
            let pair_base = data.len() as u32;
            let mut axis_base = [0u32; 3];
            let mut seen = 0u32;
            for axis in Axis::ALL {
                axis_base[axis.index()] = seen;
                for c in block.crossings(axis) {
                    data.extend([c.t.to_bits(), c.normal.0 as u32]);
                }
                seen += block.crossings(axis).len() as u32;
            }
            let neighbours = data.len() as u32;
            for &d in &offsets {
                data.push(index_of.get(&key_of(block).offset(d)).copied().unwrap_or(NONE));
            }
            infos.push(ChunkInfo {
                n: n as u32,
                m: n as u32 + 1,
                words,
                node_base,
                lookup_base,
                vertex_base: 0,
                y_base: axis_base[1],
                z_base: axis_base[2],
                spacing: block.level().spacing() as f32,
                offset: [0; 3],
                material_base,
                rows_base,
                // Where its cell table starts in the scratch (the quad passes find a cell's
                // first vertex there).
                crossing_base: cell_table as u32,
                // For the quad passes: the neighbours, whether it makes quads, its crossings.
                seam_base: neighbours,
                seam_slot: meshed.map_or(0, |(m, _)| m[k] as u32),
                seam_out: NONE,
                centroid_first: seen,
                pair_base,
            });
            cell_table += (n as u64).pow(3);
        }
        // The quad passes read the chunks from `data` (four storage buffers a stage).
        let chunk_table = data.len() as u32;
        data.extend(bytemuck::cast_slice::<ChunkInfo, u32>(&infos));
        // Drawing dispatches: a thread a vertex slot, a thread a triangle slot.
        let vertex_slots = dual_room + extra_room;
        let rows = |slots: u64| -> Result<(u32, u32), GpuMeshError> {
            let groups = slots.div_ceil(64).max(1);
            let x = groups.min(max_groups as u64) as u32;
            let y = groups.div_ceil(x as u64);
            if y > max_groups as u64 {
                return Err(GpuMeshError::TooLarge(format!("{slots} slots")));
            }
            Ok((x, y as u32))
        };
        let (place_x, place_y) = rows(vertex_slots)?;
        let (edge_x, edge_y) = rows(index_room / 3)?;
        let placement_infos = match draw {
            Some(p) => p.iter().map(|d| PlacementInfo::of(&d.placement, d.tint)).collect::<Result<Vec<_>, _>>()?,
            None => Vec::new(),
        };
        let params = Params {
            chunk_count,
            crossing_count: 0,
            place_row: place_x * 64,
            edge_row: edge_x * 64,
            vertex_total: 0,
            triangle_slots: (index_room / 3) as u32,
            extra_base: 0,
            extra_count: 0,
            seam_list_base: chunk_table,
            mixed: mixed as u32,
            unused: [0; 2],
        };
        let filled = |label: &str, bytes: &[u8], usage| filled_buffer(device, queue, label, bytes, usage);
        let empty_with =
            |label: &str, words: u64, extra| empty_buffer(device, label, words, wgpu::BufferUsages::COPY_SRC | extra);
        let empty = |label: &str, words: u64| empty_with(label, words, wgpu::BufferUsages::empty());
        let uniform = filled("dual params", bytemuck::bytes_of(&params), wgpu::BufferUsages::UNIFORM);
        let chunks = filled("dual chunks", bytemuck::cast_slice(&infos), wgpu::BufferUsages::STORAGE);
        let data = filled("dual data", bytemuck::cast_slice(&data), wgpu::BufferUsages::STORAGE);
        let scratch = empty("dual scratch", scratch_words);
        let vertices = empty("dual vertices", (dual_room + extra_room) * DUAL_WORDS);
        let indices = empty_with("dual indices", index_room, wgpu::BufferUsages::INDEX);
        let drawing = draw.map(|_| {
            (
                filled("dual placements", bytemuck::cast_slice(&placement_infos), wgpu::BufferUsages::STORAGE),
                empty_with("dual drawn vertices", vertex_slots * 12, wgpu::BufferUsages::VERTEX),
                empty_with("dual draw args", blocks.len() as u64 * 10, wgpu::BufferUsages::INDIRECT),
                empty_with("dual edges", index_room * 2, wgpu::BufferUsages::INDEX),
            )
        });
        let mut all = vec![(0, &uniform), (1, &chunks), (2, &data), (4, &scratch), (5, &indices), (6, &vertices)];
        if let Some((p, d, a, e)) = &drawing {
            all.extend([(7, p), (8, d), (9, a), (10, e)]);
        }
        let group = |pipeline: &wgpu::ComputePipeline, used: &[u32]| bind_group(device, pipeline, &all, used);
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("dual") });
        if chunk_count > 0 {
            let mut pass = encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: self.timestamps() });
            dispatch(&mut pass, &self.dual_count, &group(&self.dual_count, &[0, 1, 2, 4]), (chunk_count, 1, 1));
            dispatch(&mut pass, &self.scan, &group(&self.scan, &[0, 4]), (1, 1, 1));
            dispatch(&mut pass, &self.dual_emit, &group(&self.dual_emit, &[0, 1, 2, 4, 6]), (chunk_count, 1, 1));
            if meshed.is_some() {
                dispatch(&mut pass, &self.quad_count, &group(&self.quad_count, &[0, 2, 4]), (chunk_count, 1, 1));
                dispatch(&mut pass, &self.quad_scan, &group(&self.quad_scan, &[0, 4]), (1, 1, 1));
                dispatch(&mut pass, &self.quad_emit, &group(&self.quad_emit, &[0, 2, 4, 5, 6]), (chunk_count, 1, 1));
            }
            if drawing.is_some() {
                dispatch(
                    &mut pass,
                    &self.dual_world,
                    &group(&self.dual_world, &[0, 4, 6, 7, 8]),
                    (place_x, place_y, 1),
                );
                dispatch(
                    &mut pass,
                    &self.dual_args,
                    &group(&self.dual_args, &[0, 4, 9]),
                    (chunk_count.div_ceil(64), 1, 1),
                );
                self.dispatch_lines(&mut pass, &group(&self.edge_lines, &[0, 5, 10]), index_room, (edge_x, edge_y));
            }
        }
        self.resolve_timer(&mut encoder);
        queue.submit([encoder.finish()]);
        Ok(DualSubmitted {
            chunk_count: chunk_count as usize,
            scratch,
            scratch_words,
            vertices,
            indices,
            drawing: drawing.map(|(_, d, a, e)| (d, a, e)),
        })
    }

    #[allow(clippy::type_complexity)]
    fn build(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        blocks: &[&VoxelBlock],
        draw: Option<&[DrawPlacement]>,
    ) -> Result<(GpuBatch, Option<(wgpu::Buffer, wgpu::Buffer, wgpu::Buffer)>), GpuMeshError> {
        let (max_groups, binding) = batch_limits(device, blocks)?;
        let chunk_count = blocks.len() as u32;
        // Each buffer within the device's limits, checked before anything is built (from bounds;
        // the exact sizes are checked again once the blocks are laid out).
        let words: u64 = blocks.iter().map(|b| block_words(b)).sum::<u64>() + self.table.len() as u64;
        let crossing_words: u64 = blocks.iter().map(|b| 4 * crossing_count(b)).sum();
        let seam_blocks = blocks.iter().filter(|b| !b.seams().is_empty()).count() as u64;
        let scratch_words = blocks.len() as u64 * (THREADS as u64 + 2) + 1 + 2 * seam_blocks;
        let drawing = draw.is_some() as u64;
        check_sizes(
            binding,
            &[
                ("block data", words),
                ("crossings", crossing_words),
                ("vertices", crossing_words / 4 * VERTEX_WORDS),
                ("drawn vertices", drawing * crossing_words / 4 * 12),
                ("indices", blocks.iter().map(|b| 15 * mixed_cells(b) + seam_words(b)).sum()),
                (
                    "edge indices",
                    drawing * blocks.iter().map(|b| 2 * (15 * mixed_cells(b) + seam_words(b))).sum::<u64>(),
                ),
                ("scratch", scratch_words),
            ],
        )?;
        let mut infos = Vec::with_capacity(blocks.len());
        let mut data = self.table.clone();
        let mut crossings: Vec<[u32; 4]> = Vec::new();
        let mut ranges = Vec::with_capacity(blocks.len());
        let mut with_materials = Vec::with_capacity(blocks.len());
        let mut index_capacity = 0u64;
        // Seam points (8 words each) and seam headers, appended to `data` after the blocks.
        let mut extras: Vec<u32> = Vec::new();
        let mut headers: Vec<Vec<u32>> = Vec::new();
        let mut seam_info = Vec::with_capacity(blocks.len());
        let mut seam_room = 0u64;
        let mut vertex_total = 0u64;
        for (k, block) in blocks.iter().enumerate() {
            let n = block.cells();
            if n > MAX_CELLS {
                return Err(GpuMeshError::TooLarge(format!("a block of {n} cells a side (at most {MAX_CELLS})")));
            }
            let m = n + 1;
            let BlockWords { words, node_base, lookup_base, rows_base, material_base } =
                upload_block(&mut data, block, self.whole_lookups);
            let vertex_base = vertex_total as u32;
            let crossing_base = crossings.len() as u32;
            let mut axis_base = [0u32; 3];
            for axis in Axis::ALL {
                axis_base[axis.index()] = crossings.len() as u32 - crossing_base;
                for c in block.crossings(axis) {
                    let [x, y, z] = c.lower.map(u32::from);
                    let lower = x | y << 8 | z << 16 | (axis.index() as u32) << 24;
                    crossings.push([lower, c.t.to_bits(), c.normal.0 as u32, k as u32]);
                }
            }
            let own = crossings.len() as u32 - crossing_base;
            // Seams: the points of each whose ends are both crossings of this block become
            // vertices after the crossings (in seam order, as `mesh_block` adds them), and an
            // entry (a, b, first point, count) the split pass finds by (a, b); a later seam
            // with the same ends takes the place of an earlier one, as the CPU's map does.
            let id = |(axis, l): (Axis, [u16; 3])| {
                block
                    .crossing_index(axis, l[0] as usize, l[1] as usize, l[2] as usize)
                    .map(|i| vertex_base + axis_base[axis.index()] + i)
            };
            let mut entries: std::collections::BTreeMap<(u32, u32), (u32, u32)> = Default::default();
            let mut points = 0u32;
            for seam in block.seams() {
                let (Some(a), Some(b)) = (id(seam.a), id(seam.b)) else { continue };
                let first = vertex_base + own + points;
                for (j, p) in seam.points.iter().enumerate() {
                    let position = p.position();
                    let normal = strata_volume::normal::unpack_normal(p.normal).as_vec3().to_array();
                    extras.push(first + j as u32);
                    extras.extend(position.iter().chain(&normal).map(|f| f.to_bits()));
                    extras.push(a);
                }
                entries.insert((a, b), (first, seam.points.len() as u32));
                points += seam.points.len() as u32;
            }
            let (seam_slot, seam_out, centroid_first, centroid_room) = if block.seams().is_empty() {
                (NONE, NONE, NONE, 0)
            } else {
                // Each entry splits at most two triangles, and a triangle given a centroid
                // uses two splits at least: at most one centroid an entry.
                let room = entries.len() as u32 + 1;
                let slot = headers.len() as u32;
                let centroid_first = vertex_base + own + points;
                let mut header = vec![entries.len() as u32, k as u32, seam_room as u32, centroid_first, slot];
                for ((a, b), (first, count)) in &entries {
                    header.extend([*a, *b, *first, *count]);
                }
                headers.push(header);
                let out = seam_room as u32;
                let splits: u64 = entries.values().map(|(_, c)| *c as u64).sum();
                seam_room += mixed_cells(block) * 5 + 2 * splits + 3 * entries.len() as u64;
                (slot, out, centroid_first, room)
            };
            let vertices = own + points + centroid_room;
            vertex_total += vertices as u64;
            ranges.push((vertex_base, vertices));
            seam_info.push((own + points, (seam_slot != NONE).then_some(seam_slot)));
            with_materials.push(block.has_materials());
            // At most five triangles a mixed cell.
            index_capacity += mixed_cells(block) * 15;
            let offset = block.offset().map(|o| o as u32);
            infos.push(ChunkInfo {
                n: n as u32,
                m: m as u32,
                words,
                node_base,
                lookup_base,
                vertex_base,
                y_base: axis_base[1],
                z_base: axis_base[2],
                spacing: block.level().spacing() as f32,
                offset,
                material_base,
                rows_base,
                crossing_base,
                seam_base: if seam_slot == NONE { NONE } else { seam_out },
                seam_slot,
                seam_out,
                centroid_first,
                pair_base: NONE,
            });
        }
        // The split triangles go after the others: their slots are offset by the first part's.
        let normal_slots = (index_capacity / 3) as u32;
        let mut seam_out: Vec<u32> = Vec::with_capacity(blocks.len());
        for info in &mut infos {
            if info.seam_slot != NONE {
                info.seam_out += normal_slots;
                info.seam_base = NONE;
            }
            seam_out.push(info.seam_out);
        }
        for h in &mut headers {
            h[2] += normal_slots;
        }
        index_capacity += seam_room * 3;
        let extra_base = data.len() as u32;
        let extra_count = (extras.len() / 8) as u32;
        data.extend(extras);
        let seam_list_base = data.len() as u32;
        let header_start = seam_list_base as usize + headers.len();
        let mut at = header_start as u32;
        for h in &headers {
            data.push(at);
            at += h.len() as u32;
        }
        for h in &headers {
            data.extend(h);
        }
        // The exact sizes, seam points and centroid room included.
        check_sizes(
            binding,
            &[
                ("block data", data.len() as u64),
                ("vertices", vertex_total * VERTEX_WORDS),
                ("drawn vertices", drawing * vertex_total * 12),
                ("indices", index_capacity),
                ("edge indices", drawing * index_capacity * 2),
            ],
        )?;
        let filled = |label: &str, bytes: &[u8], usage| filled_buffer(device, queue, label, bytes, usage);
        let storage = |label: &str, bytes: &[u8], extra: wgpu::BufferUsages| {
            filled(label, bytes, wgpu::BufferUsages::STORAGE | extra)
        };
        let empty = |label: &str, words: u64, extra| empty_buffer(device, label, words, extra);
        let crossing_count = crossings.len() as u32;
        let vertex_total = vertex_total as u32;
        let place_groups = vertex_total.max(crossing_count).div_ceil(64);
        let place_x = place_groups.clamp(1, max_groups);
        let place_y = place_groups.div_ceil(place_x).max(1);
        if place_y > max_groups {
            return Err(GpuMeshError::TooLarge(format!("{crossing_count} crossings")));
        }
        let edge_groups = (index_capacity / 3).div_ceil(64).min(u32::MAX as u64) as u32;
        let edge_x = edge_groups.clamp(1, max_groups);
        let edge_y = edge_groups.div_ceil(edge_x).max(1);
        if draw.is_some() && edge_y > max_groups {
            return Err(GpuMeshError::TooLarge(format!("{} triangles at most", index_capacity / 3)));
        }
        let placement_infos = match draw {
            Some(p) => p.iter().map(|d| PlacementInfo::of(&d.placement, d.tint)).collect::<Result<Vec<_>, _>>()?,
            None => Vec::new(),
        };
        let params = Params {
            chunk_count,
            crossing_count,
            place_row: place_x * 64,
            edge_row: edge_x * 64,
            vertex_total,
            triangle_slots: (index_capacity / 3) as u32,
            extra_base,
            extra_count,
            seam_list_base,
            mixed: 0,
            unused: [0; 2],
        };
        let uniform = filled("gpu mesh params", bytemuck::bytes_of(&params), wgpu::BufferUsages::UNIFORM);
        let chunks = storage("gpu mesh chunks", bytemuck::cast_slice(&infos), wgpu::BufferUsages::empty());
        let data = storage("gpu mesh data", bytemuck::cast_slice(&data), wgpu::BufferUsages::empty());
        let crossing_buffer =
            storage("gpu mesh crossings", bytemuck::cast_slice(&crossings), wgpu::BufferUsages::empty());
        let scratch = empty("gpu mesh scratch", scratch_words, wgpu::BufferUsages::COPY_SRC);
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::INDEX;
        let indices = empty("gpu mesh indices", index_capacity, copy);
        let vertices = empty("gpu mesh vertices", vertex_total as u64 * VERTEX_WORDS, copy);
        // For drawing: placements, the renderer's vertices, indirect arguments, edges.
        let drawing = draw.map(|_| {
            (
                storage("gpu mesh placements", bytemuck::cast_slice(&placement_infos), wgpu::BufferUsages::empty()),
                empty("gpu mesh drawn vertices", vertex_total as u64 * 12, copy),
                empty("gpu mesh draw args", chunk_count as u64 * 10, wgpu::BufferUsages::INDIRECT | copy),
                empty("gpu mesh edges", index_capacity * 2, copy),
            )
        });
        let mut all = vec![
            (0, &uniform),
            (1, &chunks),
            (2, &data),
            (3, &crossing_buffer),
            (4, &scratch),
            (5, &indices),
            (6, &vertices),
        ];
        if let Some((p, d, a, e)) = &drawing {
            all.extend([(7, p), (8, d), (9, a), (10, e)]);
        }
        let group = |pipeline: &wgpu::ComputePipeline, used: &[u32]| bind_group(device, pipeline, &all, used);
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("gpu mesh") });
        {
            let mut pass = encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: self.timestamps() });
            if chunk_count > 0 {
                dispatch(&mut pass, &self.count, &group(&self.count, &[0, 1, 2, 4]), (chunk_count, 1, 1));
            }
            dispatch(&mut pass, &self.scan, &group(&self.scan, &[0, 4]), (1, 1, 1));
            if chunk_count > 0 {
                dispatch(&mut pass, &self.emit, &group(&self.emit, &[0, 1, 2, 4, 5]), (chunk_count, 1, 1));
            }
            if crossing_count > 0 {
                dispatch(&mut pass, &self.place, &group(&self.place, &[0, 1, 2, 3, 6]), (place_x, place_y, 1));
            }
            if extra_count > 0 {
                dispatch(
                    &mut pass,
                    &self.place_extra,
                    &group(&self.place_extra, &[0, 2, 6]),
                    (extra_count.div_ceil(64).min(max_groups), extra_count.div_ceil(64 * max_groups).max(1), 1),
                );
            }
            if !headers.is_empty() {
                dispatch(&mut pass, &self.split, &group(&self.split, &[0, 2, 4, 5, 6]), (headers.len() as u32, 1, 1));
            }
            if drawing.is_some() {
                if vertex_total > 0 {
                    dispatch(&mut pass, &self.world, &group(&self.world, &[0, 1, 6, 7, 8]), (place_x, place_y, 1));
                }
                if chunk_count > 0 {
                    dispatch(
                        &mut pass,
                        &self.draw_args,
                        &group(&self.draw_args, &[0, 1, 4, 9]),
                        (chunk_count.div_ceil(64), 1, 1),
                    );
                }
                self.dispatch_lines(&mut pass, &group(&self.edge_lines, &[0, 5, 10]), index_capacity, (edge_x, edge_y));
            }
        }
        self.resolve_timer(&mut encoder);
        queue.submit([encoder.finish()]);
        let batch = GpuBatch {
            vertices,
            indices,
            vertex_ranges: ranges,
            seams: seam_info,
            seam_out,
            with_materials,
            index_capacity,
            scratch,
            chunk_count,
        };
        Ok((batch, drawing.map(|(_, d, a, e)| (d, a, e))))
    }
}

/// Dual contouring's passes submitted: their buffers.
#[derive(Debug)]
struct DualSubmitted {
    chunk_count: usize,
    scratch: wgpu::Buffer,
    scratch_words: u64,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    /// The renderer's vertices, the indirect arguments and the lines, when drawn.
    drawing: Option<(wgpu::Buffer, wgpu::Buffer, wgpu::Buffer)>,
}

impl DualSubmitted {
    /// Reads back what the passes left (waits for the GPU): the scratch, the dual and extra
    /// vertices, and with `quads` the triangles.
    fn read(&self, device: &wgpu::Device, queue: &wgpu::Queue, quads: bool) -> Result<DualRun, GpuMeshError> {
        if self.chunk_count == 0 {
            return Ok(DualRun { chunk_count: 0, scratch: Vec::new(), vertices: Vec::new(), indices: Vec::new() });
        }
        let scratch = read_words(device, queue, &self.scratch, self.scratch_words)?;
        let run = DualRun { chunk_count: self.chunk_count, scratch, vertices: Vec::new(), indices: Vec::new() };
        let extras = if quads { run.quad_extra_total() } else { 0 };
        let triangles = if quads { run.quad_first(self.chunk_count) } else { 0 };
        let vertices =
            read_words(device, queue, &self.vertices, (run.first(self.chunk_count) + extras) as u64 * DUAL_WORDS)?;
        let indices = read_words(device, queue, &self.indices, triangles as u64 * 3)?;
        Ok(DualRun { vertices, indices, ..run })
    }
}

/// Dual contouring made on the GPU for drawing ([`GpuMarcher::mesh_dual_for_drawing`]).
#[derive(Debug)]
pub struct DualDrawBatch {
    /// Per block, what the renderer draws (nothing for the blocks that only lend vertices).
    pub meshes: Vec<IndirectMesh>,
    submitted: DualSubmitted,
}

impl DualDrawBatch {
    /// What the renderer draws of each block, read back through the indirect arguments (for
    /// tests: drawing reads nothing back). Indices are the batch's (all blocks' vertices).
    pub fn read_back(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Vec<DrawnBlock>, GpuMeshError> {
        let Some((drawn, args, edges)) = &self.submitted.drawing else { return Ok(Vec::new()) };
        if self.meshes.is_empty() {
            return Ok(Vec::new());
        }
        let run = self.submitted.read(device, queue, true)?;
        let blocks = self.meshes.len();
        let args = read_words(device, queue, args, blocks as u64 * 10)?;
        let total = (run.first(blocks) + run.quad_extra_total()) as u64;
        let drawn = read_words(device, queue, drawn, total * 12)?;
        let lines = read_words(device, queue, edges, run.quad_first(blocks) as u64 * 6)?;
        let vertices: Vec<strata_render::Vertex> = bytemuck::cast_slice(&drawn).to_vec();
        let mut out = Vec::with_capacity(blocks);
        for k in 0..blocks {
            let a = &args[k * 10..k * 10 + 10];
            let slice = |from: u32, n: u32, all: &[u32]| -> Result<Vec<u32>, GpuMeshError> {
                all.get(from as usize..(from + n) as usize)
                    .map(<[u32]>::to_vec)
                    .ok_or_else(|| GpuMeshError::Readback(format!("block {k}'s draw arguments pass the buffer")))
            };
            out.push(DrawnBlock {
                vertices: vertices.clone(),
                triangles: slice(a[2], a[0], &run.indices)?,
                edges: slice(a[7], a[5], &lines)?,
            });
        }
        Ok(out)
    }
}

/// What dual contouring's passes left, read back.
struct DualRun {
    chunk_count: usize,
    scratch: Vec<u32>,
    vertices: Vec<u32>,
    indices: Vec<u32>,
}

impl DualRun {
    /// Block `k`'s first dual vertex (`k` = the count: all of them).
    fn first(&self, k: usize) -> usize {
        if self.chunk_count == 0 {
            return 0;
        }
        self.scratch[self.chunk_count * (THREADS as usize + 1) + k] as usize
    }

    fn quad_base(&self) -> usize {
        self.chunk_count * (THREADS as usize + 2) + 1 + self.chunk_count * (THREADS as usize + 1) * 2
    }

    /// Block `k`'s first quad triangle (`k` = the count: all of them).
    fn quad_first(&self, k: usize) -> usize {
        if self.chunk_count == 0 {
            return 0;
        }
        self.scratch[self.quad_base() + k * 2] as usize
    }

    /// The extra vertices (midpoints, centres) of all blocks.
    fn quad_extra_total(&self) -> usize {
        self.scratch[self.quad_base() + self.chunk_count * 2 + 1] as usize
    }
}

/// A dual vertex as the passes write it (ten words).
fn dual_vertex(v: &[u32]) -> DualVertex {
    let f = |i: usize| f32::from_bits(v[i]);
    DualVertex {
        cell: v[0],
        edges: v[1] as u16,
        position: glam::Vec3::new(f(2), f(3), f(4)),
        normal: glam::Vec3::new(f(5), f(6), f(7)),
        material: strata_mesh::VertexMaterial { ids: v[8].to_le_bytes(), weights: v[9].to_le_bytes() },
    }
}

/// Timestamp queries around a batch's compute pass.
#[derive(Debug)]
struct GpuTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    /// Nanoseconds a tick.
    period: f64,
}

/// The most workgroups a dispatch dimension takes and the most bytes a storage binding takes on
/// `device`; a batch of more blocks than the first is refused.
fn batch_limits(device: &wgpu::Device, blocks: &[&VoxelBlock]) -> Result<(u32, u64), GpuMeshError> {
    let limits = device.limits();
    let max_groups = limits.max_compute_workgroups_per_dimension;
    if blocks.len() > max_groups as usize {
        return Err(GpuMeshError::TooLarge(format!("{} blocks (at most {max_groups} a batch)", blocks.len())));
    }
    Ok((max_groups, limits.max_storage_buffer_binding_size.min(limits.max_buffer_size)))
}

/// Refuses a batch one of whose buffers (`what`, in words) passes `binding` bytes or 2³² words.
fn check_sizes(binding: u64, sizes: &[(&str, u64)]) -> Result<(), GpuMeshError> {
    for &(what, words) in sizes {
        if words * 4 > binding || words > u32::MAX as u64 {
            return Err(GpuMeshError::TooLarge(format!(
                "its {what} take {} MiB, more than the device's {} MiB a buffer",
                (words * 4) >> 20,
                binding >> 20
            )));
        }
    }
    Ok(())
}

/// One dispatch of `pipeline` with `group` in `pass`.
fn dispatch(
    pass: &mut wgpu::ComputePass<'_>,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    size: (u32, u32, u32),
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    pass.dispatch_workgroups(size.0, size.1, size.2);
}

/// A buffer holding `bytes` (at least one word: an empty binding is not allowed), written
/// through the queue rather than mapped at creation: on a lost device that is an error the
/// device reports (an error scope catches it), where mapping panics.
fn filled_buffer(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    bytes: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let contents: &[u8] = if bytes.is_empty() { &[0; 4] } else { bytes };
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: contents.len() as u64,
        usage: usage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    queue.write_buffer(&buffer, 0, contents);
    buffer
}

/// A storage buffer of `words` words (at least one), with the usages `extra` besides.
fn empty_buffer(device: &wgpu::Device, label: &str, words: u64, extra: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: words.max(1) * 4,
        usage: wgpu::BufferUsages::STORAGE | extra,
        mapped_at_creation: false,
    })
}

/// The bind group of `pipeline` with the bindings of `all` its entry point uses (`used`: its
/// layout is derived from the entry point, so it must get exactly those).
fn bind_group(
    device: &wgpu::Device,
    pipeline: &wgpu::ComputePipeline,
    all: &[(u32, &wgpu::Buffer)],
    used: &[u32],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry<'_>> = all
        .iter()
        .filter(|(b, _)| used.contains(b))
        .map(|(b, buffer)| wgpu::BindGroupEntry { binding: *b, resource: buffer.as_entire_binding() })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    })
}

/// Where a block's words start in the data buffer.
struct BlockWords {
    words: u32,
    node_base: u32,
    lookup_base: u32,
    rows_base: u32,
    material_base: u32,
}

/// Appends what the shaders read of `block` to `data`: its node bits (a row of `words` words a
/// line of nodes along x), its crossings' ranks as line counts (or its whole lookup, where it is
/// not listed line by line or `whole_lookup` asks for it), and its node materials (four a word,
/// where it has any).
fn upload_block(data: &mut Vec<u32>, block: &VoxelBlock, whole_lookup: bool) -> BlockWords {
    let m = block.cells() + 1;
    let words = m.div_ceil(32);
    let node_base = data.len() as u32;
    for z in 0..m {
        for y in 0..m {
            let row = block.row(y, z);
            for w in 0..words {
                data.push((row >> (32 * w)) as u32);
            }
        }
    }
    // The crossings' indices: their rank (per axis, the crossings of the lines before and the
    // crossed edges before them on their line), when the block lists them so, which extraction
    // does; else the whole lookup.
    let rows = if whole_lookup { None } else { line_counts(block) };
    let (lookup_base, rows_base) = match rows {
        Some(rows) => {
            let base = data.len() as u32;
            data.extend(rows);
            (NONE, base)
        }
        None => {
            let base = data.len() as u32;
            for axis in Axis::ALL {
                for z in 0..m {
                    for y in 0..m {
                        for x in 0..m {
                            data.push(block.crossing_index(axis, x, y, z).unwrap_or(NONE));
                        }
                    }
                }
            }
            (base, NONE)
        }
    };
    let material_base = if block.has_materials() {
        let base = data.len() as u32;
        let mut word = 0u32;
        for node in 0..m * m * m {
            let (x, y, z) = (node % m, (node / m) % m, node / (m * m));
            word |= (block.material(x, y, z) as u32) << (8 * (node % 4));
            if node % 4 == 3 || node + 1 == m * m * m {
                data.push(word);
                word = 0;
            }
        }
        base
    } else {
        NONE
    };
    BlockWords { words: words as u32, node_base, lookup_base, rows_base, material_base }
}

/// Words of the data buffer a block takes at most: its node bits, its crossing lookup (or the
/// smaller row counts) and its materials.
fn block_words(block: &VoxelBlock) -> u64 {
    let m = block.cells() as u64 + 1;
    let materials = if block.has_materials() { (m * m * m).div_ceil(4) } else { 0 };
    m * m * m.div_ceil(32) + 3 * m * m * m + materials
}

/// Per axis and line along it (line `u + m v`, with `(u, v)` the block coordinates across the
/// axis as `strata_volume::Axis::across` orders them), the crossings of that axis on the lines
/// before it, then the bits of the crossed edges along it (`words` words, bit `e` for the edge
/// from node `e`): when the block lists each axis's crossings line by line in that order and
/// along each line in order, which extraction does, a crossing's index is those before its line
/// plus the crossed edges before it on the line, which the shader counts. `None` for a block
/// listed otherwise (a repaired one appends the crossings it fills in).
fn line_counts(block: &VoxelBlock) -> Option<Vec<u32>> {
    let m = block.cells() + 1;
    let words = m.div_ceil(32);
    let mut out = vec![0u32; 3 * m * m * (1 + words)];
    for axis in Axis::ALL {
        let a = axis.index();
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let axis_base = a * m * m * (1 + words);
        let mut last: Option<(usize, usize)> = None;
        let mut seen = vec![0u32; m * m];
        for c in block.crossings(axis) {
            let lower = c.lower.map(usize::from);
            let (e, line) = (lower[a], lower[ua] + m * lower[va]);
            if last.is_some_and(|prev| prev >= (line, e)) {
                return None;
            }
            last = Some((line, e));
            seen[line] += 1;
            out[axis_base + line * (1 + words) + 1 + e / 32] |= 1 << (e % 32);
        }
        let mut before = 0u32;
        for (line, count) in seen.iter().enumerate() {
            out[axis_base + line * (1 + words)] = before;
            before += count;
        }
    }
    Some(out)
}

/// Index words a block's seams may add at most (its triangles written again, split).
fn seam_words(block: &VoxelBlock) -> u64 {
    if block.seams().is_empty() {
        return 0;
    }
    let points: u64 = block.seams().iter().map(|s| s.points.len() as u64).sum();
    15 * mixed_cells(block) + 6 * points + 9 * block.seams().len() as u64
}

/// The block's crossings, all axes.
fn crossing_count(block: &VoxelBlock) -> u64 {
    Axis::ALL.iter().map(|&a| block.crossings(a).len() as u64).sum()
}

/// The block's cells whose corners differ.
fn mixed_cells(block: &VoxelBlock) -> u64 {
    let n = block.cells();
    (0..n).flat_map(|z| (0..n).map(move |y| (y, z))).map(|(y, z)| block.mixed_cells(y, z).count_ones() as u64).sum()
}

/// Copies `buffer`'s first `words` words back to the CPU (waiting for the GPU).
fn read_words(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    words: u64,
) -> Result<Vec<u32>, GpuMeshError> {
    if words == 0 {
        return Ok(Vec::new());
    }
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("gpu mesh readback"),
        size: words * 4,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder =
        device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("gpu mesh readback") });
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, words * 4);
    queue.submit([encoder.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| GpuMeshError::Readback(e.to_string()))?;
    rx.recv().map_err(|e| GpuMeshError::Readback(e.to_string()))?.map_err(|e| GpuMeshError::Readback(e.to_string()))?;
    let view = staging.slice(..).get_mapped_range().map_err(|e| GpuMeshError::Readback(e.to_string()))?;
    let words = bytemuck::cast_slice(&view).to_vec();
    drop(view);
    staging.unmap();
    Ok(words)
}

/// One block's part of a [`DrawBatch`] read back: what the renderer draws of it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DrawnBlock {
    /// The block's vertices as the renderer reads them (in the world).
    pub vertices: Vec<strata_render::Vertex>,
    /// Its triangles, by its indirect arguments, indexing `vertices`.
    pub triangles: Vec<u32>,
    /// Its wireframe's line indices, by its indirect arguments, indexing `vertices`.
    pub edges: Vec<u32>,
}

impl DrawBatch {
    /// What the renderer draws of each block, read back through the indirect arguments (for
    /// tests: drawing reads nothing back).
    pub fn read_back(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Vec<DrawnBlock>, GpuMeshError> {
        let Some(first) = self.meshes.first() else { return Ok(Vec::new()) };
        let blocks = self.meshes.len() as u64;
        let args = read_words(device, queue, &first.args, blocks * 10)?;
        let scratch = read_words(device, queue, &self.batch.scratch, self.batch.scratch_words())?;
        let vertex_words = self.batch.vertex_ranges.last().map_or(0, |(b, n)| (*b + *n) as u64 * 12);
        let drawn = read_words(device, queue, &self.drawn, vertex_words)?;
        let indices = read_words(device, queue, &first.triangles, self.batch.index_capacity)?;
        let edges = read_words(device, queue, &first.edges, self.batch.index_capacity * 2)?;
        let mut out = Vec::with_capacity(self.meshes.len());
        for (k, &(base, _)) in self.batch.vertex_ranges.iter().enumerate() {
            let count = self.batch.vertices_of(&scratch, k);
            let a = &args[k * 10..k * 10 + 10];
            let slice = |from: u32, n: u32, all: &[u32]| -> Result<Vec<u32>, GpuMeshError> {
                let (from, to) = (from as usize, from as usize + n as usize);
                let part = all.get(from..to).ok_or_else(|| {
                    GpuMeshError::Readback(format!("block {k}'s draw arguments {from}..{to} pass the buffer"))
                })?;
                Ok(part.iter().map(|i| i.wrapping_sub(base)).collect())
            };
            let vertices = bytemuck::cast_slice(&drawn[base as usize * 12..(base + count) as usize * 12]).to_vec();
            out.push(DrawnBlock {
                vertices,
                triangles: slice(a[2], a[0], &indices)?,
                edges: slice(a[7], a[5], &edges)?,
            });
        }
        Ok(out)
    }
}

impl GpuBatch {
    /// The triangles of the whole batch (read back: waits for the GPU).
    pub fn triangle_count(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<u32, GpuMeshError> {
        let scratch = read_words(device, queue, &self.scratch, self.scratch_words())?;
        Ok((0..self.chunk_count as usize).map(|k| self.triangles_of(&scratch, k).1).sum())
    }

    fn seam_blocks(&self) -> u64 {
        self.seams.iter().filter(|(_, s)| s.is_some()).count() as u64
    }

    fn scratch_words(&self) -> u64 {
        self.chunk_count as u64 * (THREADS as u64 + 2) + 1 + 2 * self.seam_blocks()
    }

    fn first_at(&self, k: u32) -> usize {
        (self.chunk_count * (THREADS + 1) + k) as usize
    }

    fn seam_counts_at(&self, slot: u32) -> usize {
        (self.chunk_count * (THREADS + 2) + 1 + 2 * slot) as usize
    }

    /// Block `k`'s first triangle slot and its triangles, from the scratch read back (a block
    /// with seams: its split triangles).
    fn triangles_of(&self, scratch: &[u32], k: usize) -> (u32, u32) {
        match self.seams[k].1 {
            Some(slot) => (self.seam_out[k], scratch[self.seam_counts_at(slot)]),
            None => {
                let first = scratch[self.first_at(k as u32)];
                (first, scratch[self.first_at(k as u32 + 1)] - first)
            }
        }
    }

    /// Block `k`'s vertices: its crossings', its seam points' and its centroids'.
    fn vertices_of(&self, scratch: &[u32], k: usize) -> u32 {
        let (before, slot) = self.seams[k];
        before + slot.map_or(0, |s| scratch[self.seam_counts_at(s) + 1])
    }

    /// Each block's mesh as the CPU keeps it (vertices and indices local to the block), read
    /// back: for tests and exports, not for drawing.
    pub fn read_back(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Vec<Mesh>, GpuMeshError> {
        let scratch = read_words(device, queue, &self.scratch, self.scratch_words())?;
        let indices = read_words(device, queue, &self.indices, self.index_capacity)?;
        let vertex_words = self.vertex_ranges.last().map_or(0, |(b, n)| (*b + *n) as u64 * VERTEX_WORDS);
        let vertices = read_words(device, queue, &self.vertices, vertex_words)?;
        let w = VERTEX_WORDS as usize;
        let mut out = Vec::with_capacity(self.vertex_ranges.len());
        for (k, &(base, room)) in self.vertex_ranges.iter().enumerate() {
            let count = self.vertices_of(&scratch, k);
            if count > room {
                return Err(GpuMeshError::Readback(format!("block {k}: {count} vertices past its room {room}")));
            }
            let mut mesh = Mesh::default();
            for v in vertices[base as usize * w..(base + count) as usize * w].chunks_exact(w) {
                let f = |i: usize| f32::from_bits(v[i]);
                mesh.positions.push([f(0), f(1), f(2)]);
                mesh.normals.push([f(3), f(4), f(5)]);
                if self.with_materials[k] {
                    mesh.materials.push(strata_mesh::VertexMaterial::single(v[6] as u8));
                }
            }
            let (first, n) = self.triangles_of(&scratch, k);
            let (from, to) = (first as usize * 3, (first + n) as usize * 3);
            let part = indices.get(from..to).ok_or_else(|| {
                GpuMeshError::Readback(format!("block {k}'s triangles {from}..{to} pass the capacity"))
            })?;
            mesh.indices.extend(part.iter().map(|i| i.wrapping_sub(base)));
            out.push(mesh);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shader_parses_and_validates() {
        let module = naga::front::wgsl::parse_str(SHADER).expect("WGSL parses");
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
            .validate(&module)
            .expect("WGSL validates");
        for entry in [
            "count",
            "scan_chunks",
            "emit",
            "place",
            "place_extra",
            "split",
            "world",
            "draw_args",
            "edge_lines",
            "dual_count",
            "dual_emit",
            "quad_count",
            "quad_scan",
            "quad_emit",
            "dual_world",
            "dual_args",
        ] {
            assert!(module.entry_points.iter().any(|e| e.name == entry), "{entry}");
        }
    }

    #[test]
    fn the_case_table_holds_every_case_in_its_sixteen_words() {
        let t = case_table();
        assert_eq!(t.len(), TABLE_WORDS + DUAL_TABLE_WORDS);
        assert_eq!((t[0], t[255 * 16]), (0, 0), "no triangles in an empty or a full cell");
        assert_eq!(t[16], 1, "one corner inside: one triangle");
        assert!((0..256).all(|c| t[c * 16] <= 5));
    }

    #[test]
    fn extracted_blocks_list_their_crossings_line_by_line_and_the_counts_give_their_indices() {
        use strata_volume::brush::Sphere;
        let mut v = strata_volume::Volume::new();
        v.add(&Sphere::new(glam::DVec3::new(16.0, 15.5, 17.25), 11.3).unwrap()).unwrap();
        let mut blocks = 0;
        for key in strata_mesh::surface_chunks(&v) {
            let b = v.extract_block(key);
            let counts = line_counts(&b).expect("line by line");
            let m = b.cells() + 1;
            let words = m.div_ceil(32);
            // What the shader computes equals the CPU's lookup for every node of every axis.
            for axis in Axis::ALL {
                let a = axis.index();
                for z in 0..m {
                    for y in 0..m {
                        for x in 0..m {
                            let node = [x, y, z];
                            let (e, line) = (node[a], node[(a + 1) % 3] + m * node[(a + 2) % 3]);
                            let at = a * m * m * (1 + words) + line * (1 + words);
                            let mask = counts[at + 1] as u64 | (counts.get(at + 2).copied().unwrap_or(0) as u64) << 32;
                            let crossed = (mask >> e) & 1 == 1;
                            let rank = counts[at] + (mask & ((1u64 << e) - 1)).count_ones();
                            match b.crossing_index(axis, x, y, z) {
                                Some(i) => assert!(crossed && rank == i, "{axis:?} {node:?}"),
                                None => assert!(!crossed, "{axis:?} {node:?}"),
                            }
                        }
                    }
                }
            }
            blocks += 1;
        }
        assert!(blocks > 8);
    }

    #[test]
    fn downlevel_limits_are_enough_and_fewer_are_refused() {
        assert!(check_limits(&wgpu::Limits::downlevel_defaults()).is_ok());
        let poor = wgpu::Limits { max_storage_buffers_per_shader_stage: 2, ..wgpu::Limits::downlevel_defaults() };
        let e = check_limits(&poor).unwrap_err();
        assert!(e.to_string().contains("storage buffers"), "{e}");
    }
}
