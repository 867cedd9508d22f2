//! # strata-viewport
//!
//! The road from the editor to the renderer, shared by the studio's window, its `--screenshot`
//! mode and `strata render` (which links no GUI): a scene layer's chunk meshes named and placed
//! for [`strata_render::Renderer`] ([`chunk_id`], [`chunk_placement`]), the scene's materials as
//! the renderer's palette ([`palette`]), a layer's grid placed in the world ([`layer_model`]),
//! the saved view as the renderer's camera and back ([`camera_of`], [`view_of`]), and the
//! headless screenshot of a scene ([`render_scene`]).
//!
//! The renderer knows nothing of volumes: this crate is where chunk keys become its opaque
//! [`MeshId`]s, group `i` for scene layer `i`.
#![warn(missing_docs)]

use std::path::Path;

use glam::Mat4;
use strata_editor::{Editor, Layer, Scene, View};
use strata_mesh::Mesh;
use strata_render::{Camera, DrawMesh, FrameSettings, MeshId, MeshRef, PaletteEntry, Placement, RenderError, Renderer};
use strata_volume::ChunkKey;

/// Lends `mesh` to the renderer as plain slices (its materials cast in place:
/// `VertexMaterial` and [`strata_render::MaterialBlend`] are both two `[u8; 4]`).
pub fn mesh_ref(mesh: &Mesh) -> MeshRef<'_> {
    MeshRef {
        positions: &mesh.positions,
        normals: &mesh.normals,
        materials: bytemuck::cast_slice(&mesh.materials),
        indices: &mesh.indices,
    }
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

/// Uploads chunk `key`'s `mesh` of group `group` (an empty mesh drops it), untinted.
pub fn upload_chunk(
    renderer: &mut Renderer,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    group: u32,
    key: ChunkKey,
    mesh: &Mesh,
    model: Mat4,
) {
    renderer.upload_mesh(device, queue, chunk_id(group, key), mesh_ref(mesh), chunk_placement(model, key), [1.0; 3]);
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
    let t = &layer.transform;
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

/// Every chunk mesh of every visible layer of `editor`'s scene, as the renderer draws it.
pub fn scene_meshes(editor: &Editor) -> Vec<DrawMesh<'_>> {
    let mut out = Vec::new();
    for (i, layer) in editor.scene.layers.iter().enumerate() {
        if !layer.visible {
            continue;
        }
        let model = layer_model(layer);
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

/// Replaces everything `renderer` holds with `editor`'s scene: its palette and every chunk
/// mesh of every visible layer.
pub fn upload_scene(editor: &Editor, device: &wgpu::Device, queue: &wgpu::Queue, renderer: &mut Renderer) {
    renderer.clear();
    renderer.set_palette(queue, &palette(&editor.scene));
    for m in scene_meshes(editor) {
        renderer.upload_mesh(device, queue, m.id, m.mesh, m.placement, m.color);
    }
}

/// Meshes `scene` (every chunk, no time budget) and renders it from its saved view at `size`
/// into the PNG at `out`, headless. Returns the adapter's name.
pub fn render_scene(scene: Scene, out: &Path, size: (u32, u32), wireframe: bool) -> Result<String, RenderError> {
    let camera = camera_of(&scene.view);
    let mut editor = Editor::new(scene);
    editor.finish_meshing();
    let settings = FrameSettings { camera, wireframe, ..Default::default() };
    strata_render::screenshot(scene_meshes(&editor), &palette(&editor.scene), &settings, size, out)
}
