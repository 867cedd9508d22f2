//! The `--screenshot` mode: load or build a scene, render one frame offscreen, write a PNG. No
//! window is opened, so it works without a display. Scenes render through
//! [`strata_viewport::render_scene`] (the same path as `strata render`); terrain through
//! [`strata_render::screenshot`] fed the streamed world's meshes.

use std::path::Path;

use strata_editor::{Scene, file};
use strata_render::FrameSettings;

use crate::studio::default_scene;

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
    Ok(strata_viewport::render_scene(scene, out, size, wireframe)?)
}

/// Renders terrain of the default recipe with `seed`, seen from where terrain mode starts, at
/// `size` into the PNG at `out`, after streaming and meshing everything in view. Returns the
/// adapter's name.
pub fn terrain_screenshot(seed: u32, out: &Path, size: (u32, u32)) -> anyhow::Result<String> {
    let settings = strata_terrain::WorldSettings { view_distance: 128.0, detail_distance: 40.0, ..Default::default() };
    let recipe = strata_terrain::Recipe::with_seed(seed);
    let (mut mode, mut editor) = crate::terrain::TerrainMode::in_memory(&recipe, settings, Scene::default().materials)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    if !mode.settle(&mut editor, std::time::Duration::from_secs(600)) {
        anyhow::bail!("the terrain did not finish streaming in ten minutes");
    }
    // The world's meshes as the studio's window draws them: the editor's, through the viewport.
    let meshes = strata_viewport::scene_meshes(&editor);
    let palette = strata_viewport::palette(&editor.scene);
    let settings = FrameSettings { camera: mode.camera(), ..Default::default() };
    Ok(strata_render::screenshot(meshes, &palette, &settings, size, out)?)
}
