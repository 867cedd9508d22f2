//! Resolution levels in the editor: the detail tool, level of detail by camera distance with
//! hysteresis, meshes swapped with their neighbours, and mixed-level scenes saved and loaded.

use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::{Buttons, Editor, LodView, ToolKind, ToolPose};
use strata_mesh::{Mesh, checks};
use strata_volume::brush::Sphere;
use strata_volume::{ChunkKey, Level};

const BUDGET: Duration = Duration::from_millis(200);

fn editor_with_ball() -> Editor {
    let mut e = Editor::default();
    e.scene.layers[0].volume = strata_volume::Volume::new();
    e.scene.layers[0].volume.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 12.0).unwrap()).unwrap();
    e.scene.layers[0].volume.set_cell_size(1.0).unwrap();
    e.reset_caches();
    e.clear_history();
    e.finish_meshing();
    e
}

/// The cache's chunk meshes of layer 0 in grid units, welded by position.
fn welded(e: &Editor) -> Mesh {
    let mut out = Mesh::default();
    let mut ids = std::collections::HashMap::new();
    for (key, m) in e.mesh_cache(0).unwrap().iter() {
        let o = key.origin_grid().as_vec3();
        let remap: Vec<u32> = m
            .positions
            .iter()
            .map(|p| {
                let q = [p[0] + o.x, p[1] + o.y, p[2] + o.z];
                *ids.entry(q.map(|c| (c * 8192.0).round() as i64)).or_insert_with(|| {
                    out.positions.push(q);
                    out.normals.push([0.0, 0.0, 1.0]);
                    out.positions.len() as u32 - 1
                })
            })
            .collect();
        out.indices.extend(m.indices.iter().map(|&i| remap[i as usize]));
    }
    out
}

#[test]
fn the_detail_tool_raises_chunks_under_the_brush_as_one_undo_step() {
    let mut e = editor_with_ball();
    let before = e.scene.layers[0].volume.clone();
    e.tool.kind = ToolKind::Detail;
    e.tool.radius = 3.0;
    e.tool.detail_level = Level::new(1).unwrap();
    let p = DVec3::new(16.3, 15.8, 28.1);
    let down = Buttons { primary: true, secondary: false };
    e.frame(&ToolPose { position: p, orientation: DQuat::IDENTITY, pressure: 1.0, buttons: down }, BUDGET).unwrap();
    e.frame(&ToolPose::at(p, false), BUDGET).unwrap();
    e.finish_meshing();
    let v = &e.scene.layers[0].volume;
    let raised: Vec<ChunkKey> =
        v.chunks().filter(|(k, _)| v.stored_level(*k) == Some(Level::new(1).unwrap())).map(|(k, _)| k).collect();
    assert!(!raised.is_empty(), "chunks under the brush were raised");
    assert!(raised.len() < v.chunk_count(), "and only those");
    v.check_invariants().unwrap();
    checks::check_closed_manifold(&welded(&e)).unwrap();
    assert!(e.undo());
    e.finish_meshing();
    assert_eq!(e.scene.layers[0].volume, before, "one undo step restores the levels exactly");
    // The inverse lowers them again.
    assert!(e.redo());
    let ctrl = Buttons { primary: false, secondary: true };
    e.frame(&ToolPose { position: p, orientation: DQuat::IDENTITY, pressure: 1.0, buttons: ctrl }, BUDGET).unwrap();
    e.frame(&ToolPose::at(p, false), BUDGET).unwrap();
    assert_eq!(e.scene.layers[0].volume, before, "raising then lowering gives back the lists");
}

#[test]
fn level_of_detail_follows_the_camera_with_hysteresis_and_stays_closed() {
    let mut e = editor_with_ball();
    // Store everything at level 2.
    let keys: Vec<ChunkKey> = e.scene.layers[0].volume.chunks().map(|(k, _)| k).collect();
    let _ = e.scene.layers[0].volume.set_chunk_levels(&keys, Level::FINEST);
    e.reset_caches();
    e.clear_history();
    e.finish_meshing();
    let full = e.triangle_count();
    let view = |d: f64| LodView { eye: DVec3::new(16.0, 16.0, 16.0 + d), pixels_per_radian: 800.0, pixel_error: 2.0 };
    e.set_view(Some(view(1000.0)));
    e.finish_meshing();
    let far = e.triangle_count();
    assert_eq!(e.lod_level(0, ChunkKey::new(0, 0, 0)), Some(Level::BASE));
    assert!(far * 5 < full, "far: {far} of {full} triangles");
    checks::check_closed_manifold(&welded(&e)).unwrap();
    // Chunk (0, 0, 1) seen from `near` units (its nearest point): level 0 shows 800 / near
    // pixels, level 1 half that. At 250 units level 0 shows 3.2 pixels: level 1 at once.
    let key = ChunkKey::new(0, 0, 1);
    let at = |near: f64| view(8.0 + ((near + 13.9f64).powi(2) - 128.0).sqrt());
    e.set_view(Some(at(250.0)));
    e.finish_meshing();
    assert_eq!(e.lod_level(0, key), Some(Level::new(1).unwrap()), "level 1 at 250 units");
    checks::check_closed_manifold(&welded(&e)).unwrap();
    // At 450 units level 0 would show 1.78 pixels: fine enough, not clearly (≤ 2 / 1.5), so
    // the chunk stays at level 1; at 700 units (1.14 pixels) it goes coarser.
    e.set_view(Some(at(450.0)));
    assert_eq!(e.lod_level(0, key), Some(Level::new(1).unwrap()), "no flicker near the threshold");
    e.set_view(Some(at(700.0)));
    assert_eq!(e.lod_level(0, key), Some(Level::BASE));
    e.finish_meshing();
    checks::check_closed_manifold(&welded(&e)).unwrap();
    e.set_view(None);
    e.finish_meshing();
    assert_eq!(e.triangle_count(), full);
}

#[test]
fn lod_view_levels() {
    let v = LodView { eye: DVec3::ZERO, pixels_per_radian: 1000.0, pixel_error: 2.0 };
    let two = Level::FINEST;
    // A cell of 1 unit at 1,000 units is 1 pixel: level 0 (cell 1) is fine enough.
    assert_eq!(v.level_for(two, two, 1.0, 1000.0), Level::BASE);
    // At 100 units level 0 shows 10 pixels, level 1 5, level 2 2.5: the finest is needed.
    assert_eq!(v.level_for(two, two, 1.0, 100.0), two);
    // At 400 units level 1 shows 1.25 pixels (≤ 2/1.5): coarser from level 2.
    assert_eq!(v.level_for(two, two, 1.0, 400.0), Level::new(1).unwrap());
    // At 280 units level 1 shows 1.79 pixels: fine enough, but not clearly: a chunk at level 2
    // stays, one at level 1 keeps it.
    assert_eq!(v.level_for(two, two, 1.0, 280.0), two);
    assert_eq!(v.level_for(two, Level::new(1).unwrap(), 1.0, 280.0), Level::new(1).unwrap());
}

#[test]
fn a_scene_of_mixed_levels_saves_and_loads_exactly() {
    let mut e = editor_with_ball();
    let _ = e.scene.layers[0].volume.set_chunk_level(ChunkKey::new(0, 0, 0), Level::FINEST);
    let _ = e.scene.layers[0].volume.set_chunk_level(ChunkKey::new(1, 0, 0), Level::new(1).unwrap());
    let dir = std::env::temp_dir().join(format!("strata-levels-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("mixed.strata");
    strata_editor::file::save(&e.scene, &path).unwrap();
    let loaded = strata_editor::file::load(&path).unwrap();
    assert_eq!(loaded.scene.layers[0].volume, e.scene.layers[0].volume);
    loaded.scene.layers[0].volume.check_invariants().unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}
