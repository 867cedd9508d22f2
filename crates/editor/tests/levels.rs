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
    e.frame(
        &ToolPose { position: p, orientation: DQuat::IDENTITY, pressure: 1.0, buttons: down, ..ToolPose::default() },
        BUDGET,
    )
    .unwrap();
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
    e.frame(
        &ToolPose { position: p, orientation: DQuat::IDENTITY, pressure: 1.0, buttons: ctrl, ..ToolPose::default() },
        BUDGET,
    )
    .unwrap();
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

/// One step of a random level map: an edit or a chunk's level change.
#[derive(Clone, Debug)]
enum Step {
    /// Add (or subtract) a ball.
    Ball { centre: DVec3, radius: f64, add: bool },
    /// Add (or subtract) a box.
    Box { centre: DVec3, half: DVec3, add: bool },
    /// Set chunk `key`'s level.
    Level { key: (i32, i32, i32), level: i8 },
}

fn step() -> impl proptest::strategy::Strategy<Value = Step> {
    use proptest::prelude::*;
    // Centres on nodes, half-cells, chunk planes (multiples of 16) or anywhere.
    let coord = (0.0f64..32.0, 0u8..4).prop_map(|(c, snap)| match snap {
        0 => c.round(),
        1 => c.floor() + 0.5,
        2 => (c / 16.0).round() * 16.0,
        _ => c,
    });
    let point = (coord.clone(), coord.clone(), coord).prop_map(|(x, y, z)| DVec3::new(x, y, z));
    // A grain on a chunk plane at a half-cell: a node only the finer of the two chunks has.
    let grain =
        ((0usize..3), 0i32..3, (0i32..64, 0i32..64), proptest::bool::ANY).prop_map(|(axis, plane, (a, b), add)| {
            let mut c = [0.0; 3];
            c[axis] = 16.0 * plane as f64;
            c[(axis + 1) % 3] = a as f64 * 0.5;
            c[(axis + 2) % 3] = b as f64 * 0.5;
            Step::Ball { centre: DVec3::from(c), radius: 0.3, add }
        });
    // Grains (a node or two: what a coarser level cannot hold) and larger balls; boxes that fill
    // whole chunks, so that a lowered chunk can become uniform.
    let radius = prop_oneof![0.3f64..1.2, 1.2f64..9.0];
    prop_oneof![
        2 => grain,
        1 => (point.clone(), radius, proptest::bool::weighted(0.6)).prop_map(
            |(centre, radius, add)| Step::Ball { centre, radius, add }
        ),
        2 => (point, (4.0f64..20.0, 4.0f64..20.0, 4.0f64..20.0), proptest::bool::weighted(0.8)).prop_map(
            |(centre, (x, y, z), add)| Step::Box { centre, half: DVec3::new(x, y, z), add }
        ),
        3 => ((0i32..2, 0i32..2, 0i32..2), -1i8..=2).prop_map(|(key, level)| Step::Level { key, level }),
    ]
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 32, ..Default::default() })]

    /// Random level maps in random orders (neighbours two levels apart, chunks lowered until
    /// uniform, uniform chunks raised), edits before and after: after every step the scene's
    /// file loads back equal with a clean report (the editor never builds what its own load
    /// would cut away), and marching cubes' chunk meshes welded by position are closed.
    #[test]
    fn random_level_maps_save_and_load_clean_and_mesh_closed(base in 0i8..=1, steps in proptest::collection::vec(step(), 1..12)) {
        let mut scene = strata_editor::Scene::default();
        scene.layers[0].volume = strata_volume::Volume::with_level(Level::new(base).unwrap());
        for s in &steps {
            let v = &mut scene.layers[0].volume;
            match *s {
                Step::Ball { centre, radius, add } => {
                    let ball = Sphere::new(centre, radius).unwrap();
                    if add { v.add(&ball).unwrap() } else { v.subtract(&ball).unwrap() };
                }
                Step::Box { centre, half, add } => {
                    let b = strata_volume::brush::Cuboid::new(centre, half).unwrap();
                    if add { v.add(&b).unwrap() } else { v.subtract(&b).unwrap() };
                }
                Step::Level { key: (x, y, z), level } => {
                    let _ = v.set_chunk_level(ChunkKey::new(x, y, z), Level::new(level).unwrap());
                }
            }
            let v = &scene.layers[0].volume;
            proptest::prop_assert!(v.check_invariants().is_ok(), "after {s:?}: {:?}", v.check_invariants());
            let loaded = strata_editor::file::decode(&strata_editor::file::encode(&scene).unwrap()).unwrap();
            proptest::prop_assert!(loaded.report.is_clean(), "after {s:?} the load repaired: {}", loaded.report);
            proptest::prop_assert!(loaded.scene.layers[0].volume == *v, "after {s:?} the load changed the volume");
            let cache = strata_mesh::MeshCache::build(v);
            let mesh = checks::weld_by_position(cache.iter());
            proptest::prop_assert!(checks::check_closed_manifold(&mesh).is_ok(), "after {s:?}: {:?}", checks::check_closed_manifold(&mesh));
        }
    }
}

/// Found by `random_level_maps_save_and_load_clean_and_mesh_closed`: a box face 0.018 past the
/// plane z = 16 leaves a crossing in the first cell of a level-2 chunk after a level-0 one; a
/// box added across the chunks' edge, then the level-0 chunk raised to 1.
#[test]
fn raising_a_chunk_before_a_finer_one_whose_first_cell_holds_a_crossing_keeps_the_invariants() {
    use strata_volume::brush::Cuboid;
    let mut v = strata_volume::Volume::new();
    v.add(
        &Cuboid::new(DVec3::new(4.728154128209596, 0.0, 0.0), DVec3::new(9.470084518883041, 4.0, 16.017701430200393))
            .unwrap(),
    )
    .unwrap();
    let _ = v.set_chunk_level(ChunkKey::new(0, 0, 1), Level::new(2).unwrap());
    v.add(&Cuboid::new(DVec3::new(24.5, 0.0, 17.0), DVec3::new(9.815766544524637, 4.0, 4.0)).unwrap()).unwrap();
    v.check_invariants().unwrap();
    let _ = v.set_chunk_level(ChunkKey::new(0, 0, 0), Level::new(1).unwrap());
    v.check_invariants().unwrap();
}

/// Fine chunks remeshed in parts (issue 29): strokes of every field tool over a ball stored in
/// 64³ chunks, with level of detail on and a frame budget so small that meshes wait for their
/// neighbours, leave the same meshes as an editor that meshed the result from scratch, and the
/// surface closed.
#[test]
fn strokes_on_fine_chunks_remesh_in_parts_to_what_a_fresh_editor_meshes() {
    let mut e = Editor::default();
    // A volume of 64³ chunks: the ball, and a second one far away, which level of detail
    // meshes coarser.
    let mut v = strata_volume::Volume::with_level(Level::FINEST);
    v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 12.0).unwrap()).unwrap();
    v.add(&Sphere::new(DVec3::new(200.0, 16.0, 16.0), 6.0).unwrap()).unwrap();
    v.set_cell_size(1.0).unwrap();
    e.scene.layers[0].volume = v;
    e.reset_caches();
    e.clear_history();
    // Near enough that the first ball stays at 64³ (its chunks then read plainly, in parts).
    let view = LodView { eye: DVec3::new(16.0, 16.0, 40.0), pixels_per_radian: 100.0, pixel_error: 2.0 };
    e.set_view(Some(view));
    e.finish_meshing();
    let before = e.scene.layers[0].volume.clone();
    let down = Buttons { primary: true, secondary: false };
    let tools =
        [ToolKind::Paint, ToolKind::Clay, ToolKind::Smooth, ToolKind::Inflate, ToolKind::Flatten, ToolKind::Pinch];
    for (i, kind) in tools.into_iter().enumerate() {
        e.tool.kind = kind;
        e.tool.radius = 1.0 + 0.5 * i as f64;
        e.tool.material = 1 + (i % 3) as u8;
        for k in 0..4 {
            // Across the top of the ball, over the borders of chunks (0, 0, 1) and (1, 1, 1).
            let x = 13.0 + 1.5 * k as f64 + 0.25 * i as f64;
            let from = DVec3::new(x, 16.0 - 0.5 * i as f64, 40.0);
            let p = e.pick(from, -DVec3::Z, 100.0).map(|h| h.point).expect("the ball is under the stroke");
            e.frame(
                &ToolPose {
                    position: p,
                    orientation: DQuat::IDENTITY,
                    pressure: 1.0,
                    buttons: down,
                    ..ToolPose::default()
                },
                Duration::ZERO,
            )
            .unwrap();
        }
        e.frame(&ToolPose::at(DVec3::ZERO, false), Duration::ZERO).unwrap();
    }
    e.finish_meshing();
    let v = &e.scene.layers[0].volume;
    assert!(*v != before, "the strokes sculpted");
    assert!(v.chunks().all(|(k, _)| k.0.x > 5 || e.lod_level(0, k).is_none()), "the first ball is meshed at 64³");
    assert_eq!(e.lod_level(0, ChunkKey::new(12, 0, 0)), Some(Level::BASE), "the far ball at 16³");
    let mut fresh = Editor::new(e.scene.clone());
    fresh.set_view(Some(view));
    fresh.finish_meshing();
    let (a, b) = (e.mesh_cache(0).unwrap(), fresh.mesh_cache(0).unwrap());
    assert_eq!(a.len(), b.len());
    let materials = |m: &Mesh| (0..m.positions.len()).map(|i| m.material(i)).collect::<Vec<_>>();
    for (k, m) in b.iter() {
        let c = a.mesh(k).unwrap_or_else(|| panic!("chunk {k:?} has no mesh"));
        assert!(
            c.positions == m.positions
                && c.indices == m.indices
                && c.normals == m.normals
                && materials(c) == materials(m),
            "chunk {k:?}: the stroked editor's mesh differs from a fresh one"
        );
    }
    // Each chunk's triangles are those of its whole block meshed at once.
    let cap = |k: ChunkKey| e.lod_level(0, k).unwrap_or(Level::FINEST);
    let mut block = strata_volume::VoxelBlock::default();
    let mut whole = Mesh::default();
    let triangles = |m: &Mesh| {
        let mut t: Vec<[[u32; 3]; 3]> =
            m.triangles().map(|t| t.map(|i| m.positions[i as usize].map(|c| (c + 0.0).to_bits()))).collect();
        for t in t.iter_mut() {
            let first = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
            t.rotate_left(first);
        }
        t.sort();
        t
    };
    for (k, m) in a.iter() {
        v.extract_block_capped(k, &cap, &mut block);
        strata_mesh::mesh_block(&block, &mut whole);
        assert!(triangles(m) == triangles(&whole), "chunk {k:?}: not the whole block's triangles");
    }
    checks::check_closed_manifold(&welded(&e)).unwrap();
}
