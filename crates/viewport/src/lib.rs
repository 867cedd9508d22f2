//! # strata-viewport
//!
//! The road from the editor to the renderer, shared by the studio's window, its `--screenshot`
//! mode and `strata render` (which links no GUI): a scene layer's chunk meshes named and placed
//! for [`strata_render::Renderer`] ([`chunk_id`], [`chunk_placement`]), the scene's materials as
//! the renderer's palette ([`palette`]), a layer's grid placed in the world ([`layer_model`]),
//! the saved view as the renderer's camera and back ([`camera_of`], [`view_of`]), the scene's
//! reference images as the renderer's quads ([`reference_quads`]), and the headless screenshot
//! of a scene ([`render_scene`]).
//!
//! The renderer knows nothing of volumes: this crate is where chunk keys become its opaque
//! [`MeshId`]s, group `i` for scene layer `i`.
#![warn(missing_docs)]

use std::path::Path;

use glam::Mat4;
use strata_editor::{ChangeList, Editor, Layer, LayerTransform, Scene, View};
pub use strata_gpu_mesh::GpuMeshError;
use strata_gpu_mesh::{DrawPlacement, DualJoin, GpuMarcher};
use strata_mesh::Mesh;
use strata_render::{
    Camera, DrawMesh, FrameSettings, Gpu, MeshId, MeshRef, PaletteEntry, Placement, RenderError, Renderer,
    render_offscreen,
};
use strata_volume::{ChunkKey, VoxelBlock};

/// Lends `mesh` to the renderer as plain slices (its materials cast in place:
/// `VertexMaterial` and [`strata_render::MaterialBlend`] are both two `[u8; 4]`).
pub fn mesh_ref(mesh: &Mesh) -> MeshRef<'_> {
    MeshRef {
        positions: &mesh.positions,
        normals: &mesh.normals,
        materials: bytemuck::cast_slice(&mesh.materials),
        indices: &mesh.indices,
        shade: &[],
    }
}

/// How much the mask of `volume` holds each vertex of chunk `key`'s `mesh` (0 to 255, for
/// [`MeshRef::shade`]); empty where no mask reaches the chunk.
pub fn mask_shade(volume: &strata_volume::Volume, key: ChunkKey, mesh: &Mesh) -> Vec<u8> {
    let origin = key.origin_grid().as_dvec3();
    let side = glam::DVec3::splat(strata_volume::coords::CHUNK_CELLS as f64);
    let Some(mask) = volume.mask().sampler(origin, origin + side) else { return Vec::new() };
    mesh.positions
        .iter()
        .map(|p| (mask.at(origin + glam::Vec3::from(*p).as_dvec3()) * 255.0).round().clamp(0.0, 255.0) as u8)
        .collect()
}

/// The renderer's name for chunk `key` of mesh group `group` (a scene layer's index).
pub fn chunk_id(group: u32, key: ChunkKey) -> MeshId {
    MeshId { group, key: key.0.to_array() }
}

/// Where a chunk's mesh (relative to the chunk's origin, as the mesh caches keep it) is drawn
/// on a grid placed in the world by `model`.
pub fn chunk_placement(model: Mat4, key: ChunkKey) -> Placement {
    Placement { model, origin: key.origin_grid().as_dvec3() }
}

/// Uploads chunk `key`'s `mesh` of group `group` (an empty mesh drops it), untinted, darkened
/// where the mask of `volume` (the surface's) holds it.
#[allow(clippy::too_many_arguments)]
pub fn upload_chunk(
    renderer: &mut Renderer,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    group: u32,
    key: ChunkKey,
    mesh: &Mesh,
    model: Mat4,
    volume: &strata_volume::Volume,
) {
    let shade = mask_shade(volume, key, mesh);
    let mesh = MeshRef { shade: &shade, ..mesh_ref(mesh) };
    renderer.upload_mesh(device, queue, chunk_id(group, key), mesh, chunk_placement(model, key), [1.0; 3]);
}

/// The id of a mesh drawn over the surfaces that is not one of them (terrain mode's debris): a
/// group no surface uses (surfaces are groups from 0 up).
pub const OVERLAY_ID: MeshId = MeshId { group: u32::MAX, key: [0; 3] };

/// The shown reference images of `scene` as the renderer draws them.
pub fn reference_quads(scene: &Scene) -> Vec<strata_render::ReferenceQuad<'_>> {
    scene
        .references
        .iter()
        .filter(|r| r.visible && r.opacity > 0.0)
        .map(|r| {
            let (width, height, rgba) = r.picture.shown();
            strata_render::ReferenceQuad {
                key: r.picture.key(),
                pixels: strata_render::Pixels { width, height, rgba },
                corners: r.corners().map(|c| c.as_vec3()),
                opacity: r.opacity,
            }
        })
        .collect()
}

/// The scene's materials as the renderer's palette.
pub fn palette(scene: &Scene) -> Vec<PaletteEntry> {
    scene
        .materials
        .iter()
        .map(|m| PaletteEntry { color: m.color, texture: m.texture.layer(), scale: m.scale, roughness: m.roughness })
        .collect()
}

/// A layer's grid-to-world matrix.
pub fn layer_model(layer: &Layer) -> Mat4 {
    transform_model(&layer.transform)
}

/// The grid-to-world matrix of a surface's transform (a layer's, or a world's identity).
pub fn transform_model(t: &LayerTransform) -> Mat4 {
    Mat4::from_scale_rotation_translation(
        glam::Vec3::splat(t.scale as f32),
        t.rotation.as_quat(),
        t.translation.as_vec3(),
    )
}

/// The camera a saved view describes.
pub fn camera_of(v: &View) -> Camera {
    Camera {
        target: v.target.as_vec3(),
        distance: v.distance as f32,
        yaw: v.yaw as f32,
        pitch: v.pitch as f32,
        ..Camera::default()
    }
}

/// The view a scene saves for `c`.
pub fn view_of(c: &Camera) -> View {
    View { target: c.target.as_dvec3(), distance: c.distance as f64, yaw: c.yaw as f64, pitch: c.pitch as f64 }
}

/// The visible surface `i` of `editor` (a layer, or its world) and its grid-to-world matrix.
fn shown_surface(editor: &Editor, i: usize) -> Option<Mat4> {
    editor.surface(i).filter(|s| s.shown()).map(|s| transform_model(&s.transform()))
}

/// Every chunk mesh of every visible surface of `editor` (its scene's layers, or its world), as
/// the renderer draws it.
pub fn scene_meshes(editor: &Editor) -> Vec<DrawMesh<'_>> {
    let mut out = Vec::new();
    for i in 0..editor.surface_count() {
        let Some(model) = shown_surface(editor, i) else { continue };
        for (key, mesh) in editor.chunk_meshes(i) {
            out.push(DrawMesh {
                id: chunk_id(i as u32, key),
                mesh: mesh_ref(mesh),
                placement: chunk_placement(model, key),
                color: [1.0; 3],
            });
        }
    }
    out
}

/// Brings `renderer` up to date with `editor`'s viewport meshes by the change list `changes`
/// (from [`Editor::take_changes`]): the one road from the editor's meshes to the GPU, for the
/// studio's window and for headless renders alike, for scenes and worlds. Meshes are group `i`
/// for surface `i` (layer `i`, or the world after the layers).
pub fn apply_changes(
    editor: &Editor,
    changes: &ChangeList,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    renderer: &mut Renderer,
) {
    // Without GPU meshing nothing can fail.
    let _ = apply_changes_with(editor, changes, device, queue, renderer, None);
}

/// [`apply_changes`] with GPU meshing: the chunks of the surfaces the editor leaves to its
/// caller ([`Editor::set_gpu_meshing`]) are meshed by `gpu` and drawn from where they were made.
/// Blocks larger than the GPU meshes are meshed on the CPU here. An error means the GPU failed (its device lost, or out of memory): turn GPU
/// meshing off and the editor meshes everything again on the CPU.
pub fn apply_changes_with(
    editor: &Editor,
    changes: &ChangeList,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    renderer: &mut Renderer,
    gpu: Option<&mut GpuMeshing>,
) -> Result<(), GpuMeshError> {
    let mut by_caller: Vec<(usize, ChunkKey)> = Vec::new();
    let caller_surface = |i: usize| gpu.is_some() && editor.meshed_by_caller(i);
    if changes.full {
        upload_scene(editor, device, queue, renderer);
        for i in (0..editor.surface_count()).filter(|&i| caller_surface(i)) {
            by_caller.extend(editor.caller_chunks(i).into_iter().map(|k| (i, k)));
        }
        return mesh_on_gpu(editor, &by_caller, device, queue, renderer, gpu);
    }
    if changes.palette {
        renderer.set_palette(queue, &palette(&editor.scene));
    }
    for &i in &changes.layers {
        renderer.clear_group(i as u32);
        let Some(model) = shown_surface(editor, i) else { continue };
        let Some(volume) = editor.surface(i).map(|s| s.volume()) else { continue };
        if caller_surface(i) {
            by_caller.extend(editor.caller_chunks(i).into_iter().map(|k| (i, k)));
            continue;
        }
        for (key, mesh) in editor.chunk_meshes(i) {
            upload_chunk(renderer, device, queue, i as u32, key, mesh, model, volume);
        }
    }
    for &(i, key) in &changes.meshes {
        if caller_surface(i) {
            by_caller.push((i, key));
            continue;
        }
        let shown = shown_surface(editor, i).zip(editor.surface(i));
        match shown.and_then(|(model, s)| editor.chunk_mesh(i, key).map(|m| (model, m, s.volume()))) {
            Some((model, mesh, volume)) => upload_chunk(renderer, device, queue, i as u32, key, mesh, model, volume),
            None => renderer.remove_mesh(chunk_id(i as u32, key)),
        }
    }
    mesh_on_gpu(editor, &by_caller, device, queue, renderer, gpu)
}

/// The viewport's GPU meshing: marching cubes in wgpu compute ([`strata_gpu_mesh`]), on the
/// device the renderer draws with, its meshes drawn where they were made.
///
/// Chunks that did not change stay resident: a batch's buffers live while a chunk of it is
/// shown. So that a few chunks left of a large batch do not hold all of it, a batch whose
/// shown chunks fall below a quarter of its blocks has them meshed again into a new batch (the
/// old buffers are then dropped): the blocks held are at most four times the chunks shown.
#[derive(Debug)]
pub struct GpuMeshing {
    marcher: std::sync::Arc<GpuMarcher>,
    /// The batches meshes may still be shown from: their arguments buffer (which names the
    /// batch), the chunks last seen shown from it, and its blocks.
    batches: Vec<(wgpu::Buffer, Vec<MeshId>, usize)>,
    /// Chunks meshed again to let sparse batches go, since creation.
    repacked: usize,
    /// Set when the device is lost (its lost callback).
    lost: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

/// Blocks meshed a batch at most (each batch's buffers stay while a chunk of it is shown).
pub const GPU_BATCH: usize = 256;

impl GpuMeshing {
    /// GPU meshing on `device` (of `adapter`), or why the adapter cannot do it: the limits the
    /// shader needs, and indirect draws.
    pub fn new(adapter: &wgpu::Adapter, device: &wgpu::Device) -> Result<Self, GpuMeshError> {
        strata_gpu_mesh::check_drawing(adapter)?;
        // A lost device is told through this callback, not through error scopes.
        let lost = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let flag = lost.clone();
        device.set_device_lost_callback(move |_, _| flag.store(true, std::sync::atomic::Ordering::Relaxed));
        Ok(GpuMeshing {
            marcher: std::sync::Arc::new(GpuMarcher::new(device)?),
            batches: Vec::new(),
            repacked: 0,
            lost,
        })
    }

    /// A solver of dual contouring's cell vertices on this GPU, for
    /// [`Editor::set_vertex_solver`] (the viewport's dual contouring: vertices solved here and
    /// read back, quads joined by the editor). A device error leaves the frame's vertices to
    /// the CPU and sets `failed` (say so, and turn GPU meshing off).
    pub fn vertex_solver(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        failed: std::sync::Arc<std::sync::atomic::AtomicBool>,
    ) -> strata_editor::BoxedVertexSolver {
        let (marcher, device, queue, lost) = (self.marcher.clone(), device.clone(), queue.clone(), self.lost.clone());
        Box::new(move |blocks: &[&VoxelBlock]| {
            // In batches of GPU_BATCH; any batch the device's limits refuse leaves the whole
            // update to the CPU (too large is not a failure of the GPU).
            let mut out = Vec::with_capacity(blocks.len());
            for part in blocks.chunks(GPU_BATCH) {
                if lost.load(std::sync::atomic::Ordering::Relaxed) {
                    failed.store(true, std::sync::atomic::Ordering::Relaxed);
                    return None;
                }
                match with_error_scopes(&device, || marcher.dual_vertices(&device, &queue, part)) {
                    Ok(Ok(solved)) => out.extend(solved),
                    Ok(Err(GpuMeshError::TooLarge(_))) => return None,
                    Ok(Err(_)) | Err(_) => {
                        failed.store(true, std::sync::atomic::Ordering::Relaxed);
                        return None;
                    }
                }
            }
            Some(out)
        })
    }

    /// Blocks the batches still held hold (meshes shown or not).
    pub fn resident_blocks(&self) -> usize {
        self.batches.iter().map(|(_, _, size)| size).sum()
    }

    /// Chunks meshed again so that sparse batches could go, since creation.
    pub fn repacked(&self) -> usize {
        self.repacked
    }

    /// Forgets the batches no mesh of `renderer` is shown from any more, and returns the
    /// chunks shown from batches that fell below a quarter shown (to mesh again).
    fn sparse(&mut self, renderer: &Renderer) -> Vec<(usize, ChunkKey)> {
        let mut again = Vec::new();
        self.batches.retain_mut(|(args, ids, size)| {
            ids.retain(|id| renderer.indirect(*id).is_some_and(|m| &m.args == args));
            if ids.len() * 4 < *size {
                again.extend(ids.iter().map(|id| (id.group as usize, ChunkKey::new(id.key[0], id.key[1], id.key[2]))));
                return false;
            }
            true
        });
        again
    }
}

/// Runs `work` inside error scopes (validation, out of memory, internal): the first error the
/// device reports is returned as [`GpuMeshError::Device`], the work's own result otherwise. The
/// scopes are all popped, innermost first, whatever they hold.
fn with_error_scopes<T>(device: &wgpu::Device, work: impl FnOnce() -> T) -> Result<T, GpuMeshError> {
    let scopes = [wgpu::ErrorFilter::Validation, wgpu::ErrorFilter::OutOfMemory, wgpu::ErrorFilter::Internal]
        .map(|f| device.push_error_scope(f));
    let out = work();
    let mut first = None;
    for scope in scopes.into_iter().rev() {
        if let Some(e) = pollster::block_on(scope.pop()) {
            first.get_or_insert(e.to_string());
        }
    }
    match first {
        Some(e) => Err(GpuMeshError::Device(e)),
        None => Ok(out),
    }
}

/// Meshes chunks `keys` (surface, chunk) of caller-meshed surfaces on the GPU (hidden surfaces'
/// chunks are dropped, chunks without surface removed, blocks larger than it takes meshed here).
fn mesh_on_gpu(
    editor: &Editor,
    keys: &[(usize, ChunkKey)],
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    renderer: &mut Renderer,
    gpu: Option<&mut GpuMeshing>,
) -> Result<(), GpuMeshError> {
    let Some(gpu) = gpu else { return Ok(()) };
    mesh_either(editor, keys, device, queue, renderer, gpu)?;
    let again = gpu.sparse(renderer);
    gpu.repacked += again.len();
    mesh_either(editor, &again, device, queue, renderer, gpu)
}

/// Meshes `keys` by their surfaces' meshers: marching cubes, or dual contouring.
fn mesh_either(
    editor: &Editor,
    keys: &[(usize, ChunkKey)],
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    renderer: &mut Renderer,
    gpu: &mut GpuMeshing,
) -> Result<(), GpuMeshError> {
    type Keys = Vec<(usize, ChunkKey)>;
    let (dual, cubes): (Keys, Keys) = keys.iter().partition(|(i, _)| editor.caller_dual(*i));
    mesh_dual_keys(editor, &dual, device, queue, renderer, gpu)?;
    mesh_keys(editor, &cubes, device, queue, renderer, gpu)
}

/// Meshes the chunks `keys` (surface, chunk) of surfaces meshed by dual contouring on the GPU:
/// each batch holds chunks whose quads are made and the chunks that lend their cells' vertices
/// (at one level the chunks before them, across levels all 26 around them).
fn mesh_dual_keys(
    editor: &Editor,
    keys: &[(usize, ChunkKey)],
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    renderer: &mut Renderer,
    gpu: &mut GpuMeshing,
) -> Result<(), GpuMeshError> {
    use rayon::prelude::*;
    let mut by_surface: std::collections::BTreeMap<usize, Vec<ChunkKey>> = Default::default();
    for &(i, key) in keys {
        if shown_surface(editor, i).is_some() {
            by_surface.entry(i).or_default().push(key);
        } else {
            renderer.remove_mesh(chunk_id(i as u32, key));
        }
    }
    for (i, mut meshed) in by_surface {
        meshed.sort();
        meshed.dedup();
        let model = shown_surface(editor, i).unwrap_or_default();
        let join = if editor.caller_dual_across_levels(i) { DualJoin::AcrossLevels } else { DualJoin::OneLevel };
        let lenders = |k: ChunkKey| -> Vec<ChunkKey> {
            match join {
                DualJoin::AcrossLevels => k.around().collect(),
                DualJoin::OneLevel => strata_mesh::MeshCache::dependents(&[k]),
            }
        };
        let mut parts: Vec<Vec<ChunkKey>> = meshed.chunks(GPU_BATCH).rev().map(<[ChunkKey]>::to_vec).collect();
        while let Some(part) = parts.pop() {
            if gpu.lost.load(std::sync::atomic::Ordering::Relaxed) {
                return Err(GpuMeshError::Device("the device was lost".into()));
            }
            // The part's chunks and their lenders, blocks made in parallel.
            let mut all: Vec<ChunkKey> = part.iter().flat_map(|&k| lenders(k)).collect();
            all.sort();
            all.dedup();
            let blocks: Vec<(ChunkKey, Option<VoxelBlock>)> = all
                .par_iter()
                .map(|&key| {
                    let mut block = VoxelBlock::default();
                    let some = editor.view_block(i, key, &mut block)
                        && strata_volume::Axis::ALL.iter().any(|&a| !block.crossings(a).is_empty());
                    (key, some.then_some(block))
                })
                .collect();
            let present: Vec<(ChunkKey, VoxelBlock)> =
                blocks.into_iter().filter_map(|(k, b)| b.map(|b| (k, b))).collect();
            let wanted: std::collections::HashSet<ChunkKey> = part.iter().copied().collect();
            // Chunks without crossings make no quads.
            for key in &part {
                if !present.iter().any(|(k, _)| k == key) {
                    renderer.remove_mesh(chunk_id(i as u32, *key));
                }
            }
            let refs: Vec<&VoxelBlock> = present.iter().map(|(_, b)| b).collect();
            let flags: Vec<bool> = present.iter().map(|(k, _)| wanted.contains(k)).collect();
            let placements: Vec<DrawPlacement> = present
                .iter()
                .map(|(k, _)| DrawPlacement { placement: chunk_placement(model, *k), tint: [1.0; 3] })
                .collect();
            let made = with_error_scopes(device, || {
                gpu.marcher.mesh_dual_for_drawing(device, queue, &refs, &flags, &placements, join)
            })?;
            let made = match made {
                Ok(made) => made,
                Err(GpuMeshError::TooLarge(_)) if part.len() > 1 => {
                    let (a, b) = part.split_at(part.len() / 2);
                    parts.extend([b.to_vec(), a.to_vec()]);
                    continue;
                }
                Err(e) => return Err(e),
            };
            let mut ids: Vec<MeshId> = Vec::new();
            if let Some(first) = made.meshes.first() {
                let args = first.args.clone();
                for (((key, _), mesh), made_quads) in present.iter().zip(made.meshes).zip(&flags) {
                    if *made_quads {
                        let id = chunk_id(i as u32, *key);
                        renderer.show_indirect(id, mesh);
                        ids.push(id);
                    }
                }
                let count = ids.len();
                gpu.batches.push((args, ids, count));
            }
        }
    }
    Ok(())
}

/// Meshes `keys` (see [`mesh_on_gpu`]), recording the batches made.
fn mesh_keys(
    editor: &Editor,
    keys: &[(usize, ChunkKey)],
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    renderer: &mut Renderer,
    gpu: &mut GpuMeshing,
) -> Result<(), GpuMeshError> {
    if keys.is_empty() {
        return Ok(());
    }
    use rayon::prelude::*;
    // The blocks, made in parallel (the CPU's share of GPU meshing).
    let blocks: Vec<(usize, ChunkKey, Option<VoxelBlock>)> = keys
        .par_iter()
        .map(|&(i, key)| {
            let mut block = VoxelBlock::default();
            let shown = shown_surface(editor, i).is_some();
            let some = shown && editor.view_block(i, key, &mut block);
            (i, key, some.then_some(block))
        })
        .collect();
    let mut batch: Vec<(usize, ChunkKey, VoxelBlock)> = Vec::new();
    for (i, key, block) in blocks {
        // (A block without crossings has no mixed cell: no triangles.)
        let Some(block) = block.filter(|b| strata_volume::Axis::ALL.iter().any(|&a| !b.crossings(a).is_empty())) else {
            renderer.remove_mesh(chunk_id(i as u32, key));
            continue;
        };
        if block.cells() > strata_gpu_mesh::MAX_CELLS {
            // Larger than the shader takes: the CPU's marching cubes.
            let Some(model) = shown_surface(editor, i) else { continue };
            let Some(volume) = editor.surface(i).map(|s| s.volume()) else { continue };
            let mut mesh = Mesh::default();
            strata_mesh::mesh_block(&block, &mut mesh);
            upload_chunk(renderer, device, queue, i as u32, key, &mesh, model, volume);
            continue;
        }
        batch.push((i, key, block));
    }
    // Batches of at most GPU_BATCH blocks; one the device's limits refuse is halved, and a
    // single block they refuse is meshed on the CPU (too large is not a failure of the GPU).
    let mut parts: Vec<&[(usize, ChunkKey, VoxelBlock)]> = batch.chunks(GPU_BATCH).rev().collect();
    while let Some(part) = parts.pop() {
        if gpu.lost.load(std::sync::atomic::Ordering::Relaxed) {
            return Err(GpuMeshError::Device("the device was lost".into()));
        }
        let refs: Vec<&VoxelBlock> = part.iter().map(|(_, _, b)| b).collect();
        let placements: Vec<DrawPlacement> = part
            .iter()
            .map(|&(i, key, _)| DrawPlacement {
                placement: chunk_placement(shown_surface(editor, i).unwrap_or_default(), key),
                tint: [1.0; 3],
            })
            .collect();
        let made = with_error_scopes(device, || gpu.marcher.mesh_for_drawing(device, queue, &refs, &placements))?;
        let made = match made {
            Ok(made) => made,
            Err(GpuMeshError::TooLarge(_)) if part.len() > 1 => {
                let (a, b) = part.split_at(part.len() / 2);
                parts.extend([b, a]);
                continue;
            }
            Err(GpuMeshError::TooLarge(_)) => {
                let (i, key, block) = &part[0];
                let (Some(model), Some(volume)) = (shown_surface(editor, *i), editor.surface(*i).map(|s| s.volume()))
                else {
                    continue;
                };
                let mut mesh = Mesh::default();
                strata_mesh::mesh_block(block, &mut mesh);
                upload_chunk(renderer, device, queue, *i as u32, *key, &mesh, model, volume);
                continue;
            }
            Err(e) => return Err(e),
        };
        let ids: Vec<MeshId> = part.iter().map(|(i, key, _)| chunk_id(*i as u32, *key)).collect();
        if let Some(first) = made.meshes.first() {
            gpu.batches.push((first.args.clone(), ids.clone(), ids.len()));
        }
        for (id, mesh) in ids.into_iter().zip(made.meshes) {
            renderer.show_indirect(id, mesh);
        }
    }
    Ok(())
}

/// Replaces everything `renderer` holds with `editor`'s scene: its palette and every chunk
/// mesh of every visible surface.
pub fn upload_scene(editor: &Editor, device: &wgpu::Device, queue: &wgpu::Queue, renderer: &mut Renderer) {
    renderer.clear();
    renderer.set_palette(queue, &palette(&editor.scene));
    for i in 0..editor.surface_count() {
        let Some(model) = shown_surface(editor, i) else { continue };
        let Some(volume) = editor.surface(i).map(|s| s.volume()) else { continue };
        for (key, mesh) in editor.chunk_meshes(i) {
            upload_chunk(renderer, device, queue, i as u32, key, mesh, model, volume);
        }
    }
}

/// Meshes `scene` (every chunk, no time budget) and renders it from its saved view at `size`
/// into the PNG at `out`, headless, through the same change list and [`apply_changes`] as the
/// studio's window. Returns the adapter's name.
pub fn render_scene(scene: Scene, out: &Path, size: (u32, u32), wireframe: bool) -> Result<String, RenderError> {
    let camera = camera_of(&scene.view);
    let mut editor = Editor::new(scene);
    editor.finish_meshing();
    let gpu = Gpu::headless()?;
    let mut renderer = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let changes = editor.take_changes();
    apply_changes(&editor, &changes, &gpu.device, &gpu.queue, &mut renderer);
    let references = reference_quads(&editor.scene);
    let settings = FrameSettings { camera, wireframe, references: &references, ..Default::default() };
    let image = render_offscreen(&gpu, &mut renderer, size.0, size.1, &settings)?;
    image.save_png(out)?;
    Ok(gpu.info.name.clone())
}
