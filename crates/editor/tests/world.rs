//! The editor on a streamed world (`Editor::on_world`): every tool's strokes across chunk
//! borders, mirrored, undo to the generated world, a long session's history within its budget,
//! and undo across eviction — the same editor, history and meshes as a scene's.

use std::collections::HashSet;
use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::{Buttons, Editor, Material, ToolKind, ToolPose};
use strata_terrain::{Recipe, World, WorldSettings};
use strata_volume::{Chunk, ChunkKey, ChunkMaterials};

const SETTLE: Duration = Duration::from_secs(120);
const BUDGET: Duration = Duration::from_millis(50);
const DOWN: Buttons = Buttons { primary: true, secondary: false };

fn settings() -> WorldSettings {
    WorldSettings { view_distance: 40.0, threads: 1, detail_distance: 0.0, ..WorldSettings::default() }
}

/// An editor on an in-memory world of `seed`, streamed and meshed around `home`.
fn world_editor(seed: u32, home: DVec3) -> Editor {
    let world = World::in_memory(&Recipe::with_seed(seed), settings()).unwrap();
    let mut e = Editor::on_world(world, Material::builtin());
    assert!(e.world_mut().unwrap().settle(&[home], SETTLE));
    e.stream(home);
    e
}

type Snapshot = Vec<(ChunkKey, Option<Chunk>, Option<ChunkMaterials>)>;

/// The contents of `keys` now.
fn snapshot(e: &Editor, keys: &[ChunkKey]) -> Snapshot {
    let v = e.world().unwrap().volume();
    keys.iter().map(|&k| (k, v.chunk(k).cloned(), v.chunk_materials(k).cloned())).collect()
}

/// The ground under `(x, z)`, picked through the editor as the pointer does.
fn ground(e: &Editor, x: f64, z: f64) -> DVec3 {
    e.pick(DVec3::new(x, 300.0, z), -DVec3::Y, 600.0).unwrap_or_else(|| panic!("no ground under ({x}, {z})")).point
}

/// A stroke of frames along the ground from `x0` to `x1` at `z`, then the release.
fn stroke(e: &mut Editor, x0: f64, x1: f64, z: f64) {
    let steps = 12;
    for i in 0..=steps {
        let x = x0 + (x1 - x0) * i as f64 / steps as f64;
        let p = ground(e, x, z);
        let pose =
            ToolPose { position: p, orientation: DQuat::IDENTITY, pressure: 1.0, buttons: DOWN, ..ToolPose::default() };
        e.frame(&pose, BUDGET).unwrap_or_else(|err| panic!("{:?} at {p}: {err}", e.tool.kind));
    }
    let end = ground(e, x1, z);
    e.frame(&ToolPose::at(end, false), BUDGET).unwrap();
}

fn check_invariants(e: &Editor, what: &str) {
    let w = e.world().unwrap();
    let known: HashSet<ChunkKey> = w.loaded().collect();
    w.volume().check_invariants_within(&|k| known.contains(&k)).unwrap_or_else(|err| panic!("{what}: {err}"));
}

/// Every sculpting tool, mirrored across x, strokes across a chunk border of a world: each
/// stroke changes the world, is one step of the editor's history and keeps every invariant;
/// the viewport meshes what changed; undoing every step gives the generated world back.
#[test]
fn every_tool_strokes_a_world_across_chunk_borders_and_undoes_to_the_generated_world() {
    let home = DVec3::new(8.0, 0.0, 8.0);
    let mut e = world_editor(21, home);
    while e.pending() > 0 {
        e.frame(&ToolPose::default(), BUDGET).unwrap();
        std::thread::sleep(Duration::from_millis(2));
    }
    let keys: Vec<ChunkKey> = e.world().unwrap().loaded().collect();
    let generated = snapshot(&e, &keys);
    assert!(e.triangle_count() > 0, "the world is meshed through the editor");
    e.tool.radius = 3.0;
    e.tool.symmetry = [true, false, false];
    e.tool.symmetry_center = DVec3::new(4.0, 0.0, 0.0);
    e.tool.material = 3;
    // Masks are for scenes: the mask tool and the mask actions are refused, and change nothing.
    e.tool.kind = ToolKind::Mask;
    let before = snapshot(&e, &keys);
    let pose = ToolPose { position: ground(&e, 12.0, 4.0), buttons: DOWN, ..ToolPose::default() };
    assert!(matches!(e.frame(&pose, BUDGET), Err(strata_editor::EditorError::MaskOnWorld)));
    e.frame(&ToolPose::at(pose.position, false), BUDGET).unwrap();
    let world = e.surface_count() - 1;
    assert!(matches!(
        e.mask_all(world, strata_editor::MaskAction::Invert),
        Err(strata_editor::EditorError::MaskOnWorld)
    ));
    assert!(snapshot(&e, &keys) == before);
    for (i, kind) in ToolKind::ALL.into_iter().filter(|k| !k.is_mask()).enumerate() {
        e.tool.kind = kind;
        let before = snapshot(&e, &keys);
        let steps = e.history().undo_len();
        // From x = 10 to 22: across the chunk border at x = 16 (and its image across x = −16).
        let z = 4.0 + 2.5 * i as f64;
        stroke(&mut e, 10.0, 22.0, z);
        assert_ne!(snapshot(&e, &keys), before, "{kind:?} changed the world");
        assert_eq!(e.history().undo_len(), steps + 1, "{kind:?}: one stroke, one step");
        check_invariants(&e, &format!("after {kind:?}"));
    }
    // The viewport catches up with every change.
    for _ in 0..2000 {
        if e.pending() == 0 {
            break;
        }
        e.frame(&ToolPose::default(), BUDGET).unwrap();
        std::thread::sleep(Duration::from_millis(2));
    }
    assert_eq!(e.pending(), 0, "the world's meshes caught up");
    while e.undo() {}
    assert_eq!(snapshot(&e, &keys), generated, "undoing every stroke gives the generated world back");
    check_invariants(&e, "after undoing everything");
    // And redo takes the last stroke again.
    assert!(e.redo());
    assert_ne!(snapshot(&e, &keys), generated);
}

/// A long dig session keeps the editor's history within its budget: the oldest steps are
/// forgotten (their edits stay), the newest kept, and undoing every kept step gives the world as
/// it was after the forgotten ones.
#[test]
fn a_long_dig_session_on_a_world_keeps_its_history_within_the_budget() {
    let home = DVec3::new(10.0, 0.0, -10.0);
    let budget = 96 << 10;
    let mut e = world_editor(5, home);
    let mut reference = world_editor(5, home);
    e.set_history_budget(budget);
    for ed in [&mut e, &mut reference] {
        ed.tool.kind = ToolKind::Erase;
        ed.tool.radius = 3.0;
    }
    let spot = |i: usize| (home.x + (i % 12) as f64 * 2.5 - 15.0, home.z + (i % 5) as f64 * 2.0);
    let digs = 120;
    for i in 0..digs {
        let (x, z) = spot(i);
        let p = ground(&e, x, z);
        e.line_stroke(p, p, 1.0, Default::default()).unwrap();
        assert!(
            e.history().bytes() <= budget || e.history().undo_len() == 1,
            "dig {i}: {} bytes of history over the {budget}-byte budget",
            e.history().bytes()
        );
    }
    let kept = e.history().undo_len();
    assert!(kept > 1 && kept < digs, "the budget forgot the oldest steps and kept the newest: {kept}");
    // The reference makes only the digs whose steps were forgotten, at the same points.
    // (Each dig picks the ground as the earlier digs left it: the reference, making the same
    // digs in the same order, picks the same points.)
    for i in 0..digs - kept {
        let (x, z) = spot(i);
        let p = ground(&reference, x, z);
        reference.line_stroke(p, p, 1.0, Default::default()).unwrap();
    }
    while e.undo() {}
    assert_eq!(e.history().undo_len(), 0);
    let keys: Vec<ChunkKey> = e.world().unwrap().loaded().collect();
    reference.world_mut().unwrap().load_now(&keys).unwrap();
    assert_eq!(snapshot(&e, &keys), snapshot(&reference, &keys), "undoing every kept step");
}

/// Undo and redo reach chunks that left memory: the viewer flies away (the dug chunks are
/// evicted), the dig is undone from afar, and back home the ground is as generated.
#[test]
fn a_world_dig_is_undone_after_its_chunks_left_memory() {
    let home = DVec3::new(-20.0, 0.0, 30.0);
    let mut e = world_editor(12, home);
    let keys: Vec<ChunkKey> = e.world().unwrap().loaded().collect();
    let generated = snapshot(&e, &keys);
    e.tool.kind = ToolKind::Erase;
    e.tool.radius = 5.0;
    let p = ground(&e, home.x, home.z);
    e.line_stroke(p, p + DVec3::X * 12.0, 1.0, Default::default()).unwrap();
    let dug = snapshot(&e, &keys);
    assert_ne!(dug, generated);
    let far = DVec3::new(5000.0, 0.0, 0.0);
    assert!(e.world_mut().unwrap().settle(&[far], SETTLE));
    e.stream(far);
    assert!(keys.iter().all(|&k| !e.world().unwrap().is_loaded(k)), "the dug chunks left memory");
    assert!(e.try_undo().unwrap(), "undone from afar");
    assert!(e.world_mut().unwrap().settle(&[home], SETTLE));
    assert_eq!(snapshot(&e, &keys), generated, "back home, the ground is as generated");
    assert!(e.try_redo().unwrap());
    assert_eq!(snapshot(&e, &keys), dug, "redo digs again");
}

/// A streamed world's chunks are handed to the mesher a few frames' worth at a time (the rest
/// waits on the main thread); every loaded chunk still gets its mesh, the one meshing it
/// directly gives, and a chunk without surface gets none.
#[test]
fn every_streamed_chunk_is_meshed_as_direct_meshing_makes_it_a_backlog_at_a_time() {
    let home = DVec3::new(8.0, 0.0, 8.0);
    let world = World::in_memory(
        &Recipe::with_seed(33),
        WorldSettings { view_distance: 72.0, threads: 1, detail_distance: 0.0, ..WorldSettings::default() },
    )
    .unwrap();
    let mut e = Editor::on_world(world, Material::builtin());
    assert!(e.world_mut().unwrap().settle(&[home], SETTLE));
    e.stream(home);
    let mut frames = 0;
    while e.pending() > 0 {
        e.frame(&ToolPose::at(home, false), Duration::from_millis(1)).unwrap();
        std::thread::sleep(Duration::from_millis(1));
        frames += 1;
        assert!(frames < 20_000, "meshing never ends: {} pending", e.pending());
    }
    let w = e.world().unwrap();
    let keys: Vec<ChunkKey> = w.loaded().collect();
    let (mut block, mut direct) = (strata_volume::VoxelBlock::default(), strata_mesh::Mesh::default());
    let mut meshed = 0;
    for &k in &keys {
        w.volume().extract_block_into(k, &mut block);
        strata_mesh::mesh_block(&block, &mut direct);
        match e.chunk_mesh(0, k) {
            Some(m) => {
                assert_eq!(m.positions, direct.positions, "chunk {k:?}");
                assert_eq!(m.indices, direct.indices, "chunk {k:?}");
                meshed += 1;
            }
            None => assert!(direct.indices.is_empty(), "chunk {k:?} has surface but no mesh"),
        }
    }
    assert!(meshed > 16, "{meshed} of {} chunks meshed: more than one backlog's worth", keys.len());
}
