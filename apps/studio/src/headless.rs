//! The `--screenshot` mode: load or build a scene, render one frame offscreen, write a PNG. No
//! window is opened, so it works without a display.

use std::path::Path;

use glam::Mat4;
use strata_editor::{Scene, file};
use strata_render::{FrameSettings, Gpu, Renderer, render_offscreen};

use crate::studio::{Studio, default_scene};

/// Renders `scene` (or the default scene) at `size` into the PNG at `out`. Returns the adapter's
/// name.
pub fn screenshot(scene: Option<&Path>, out: &Path, size: (u32, u32), wireframe: bool) -> anyhow::Result<String> {
    let scene: Scene = match scene {
        Some(p) => {
            let loaded = file::load(p).map_err(|e| anyhow::anyhow!("could not open {}: {e}", p.display()))?;
            if !loaded.report.is_clean() {
                eprintln!("{}: repaired while loading: {}", p.display(), loaded.report);
            }
            loaded.scene
        }
        None => default_scene(),
    };
    let mut studio = Studio::new(scene);
    studio.editor.finish_meshing();
    let gpu = Gpu::headless()?;
    let mut renderer = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    upload_all(&studio, &gpu.device, &gpu.queue, &mut renderer);
    let settings = FrameSettings { camera: studio.camera, wireframe, ..Default::default() };
    let image = render_offscreen(&gpu, &mut renderer, size.0, size.1, &settings)?;
    image.save_png(out)?;
    Ok(gpu.info.name.clone())
}

/// Renders terrain of the default recipe with `seed`, seen from where terrain mode starts, at
/// `size` into the PNG at `out`, after streaming and meshing everything in view. Returns the
/// adapter's name.
pub fn terrain_screenshot(seed: u32, out: &Path, size: (u32, u32)) -> anyhow::Result<String> {
    let settings = strata_terrain::WorldSettings { view_distance: 128.0, detail_distance: 40.0, ..Default::default() };
    let mut mode = crate::terrain::TerrainMode::in_memory(&strata_terrain::Recipe::with_seed(seed), settings)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    if !mode.settle(std::time::Duration::from_secs(600)) {
        anyhow::bail!("the terrain did not finish streaming in ten minutes");
    }
    let gpu = Gpu::headless()?;
    let mut renderer = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    renderer.set_palette(&gpu.queue, &palette(&strata_editor::Scene::default()));
    for (key, mesh) in mode.meshes() {
        renderer.upload_chunk(&gpu.device, &gpu.queue, 0, key, mesh, Mat4::IDENTITY, [1.0; 3]);
    }
    let settings = FrameSettings { camera: mode.camera(), ..Default::default() };
    let image = render_offscreen(&gpu, &mut renderer, size.0, size.1, &settings)?;
    image.save_png(out)?;
    Ok(gpu.info.name.clone())
}

/// Uploads every chunk mesh of every visible layer.
pub(crate) fn upload_all(studio: &Studio, device: &wgpu::Device, queue: &wgpu::Queue, renderer: &mut Renderer) {
    renderer.clear();
    let scene = &studio.editor.scene;
    renderer.set_palette(queue, &palette(scene));
    for (i, layer) in scene.layers.iter().enumerate() {
        if !layer.visible {
            continue;
        }
        let model = layer_model(layer);
        for (key, mesh) in studio.editor.chunk_meshes(i) {
            renderer.upload_chunk(device, queue, i as u32, key, mesh, model, [1.0; 3]);
        }
    }
}

/// The scene's palette as the renderer draws it.
pub(crate) fn palette(scene: &strata_editor::Scene) -> Vec<strata_render::PaletteEntry> {
    scene
        .materials
        .iter()
        .map(|m| strata_render::PaletteEntry {
            color: m.color,
            texture: m.texture.layer(),
            scale: m.scale,
            roughness: m.roughness,
        })
        .collect()
}

/// A layer's grid-to-world matrix.
pub(crate) fn layer_model(layer: &strata_editor::Layer) -> Mat4 {
    let t = &layer.transform;
    Mat4::from_scale_rotation_translation(
        glam::Vec3::splat(t.scale as f32),
        t.rotation.as_quat(),
        t.translation.as_vec3(),
    )
}
