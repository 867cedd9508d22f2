//! Streaming around viewers, paging edits through eviction and reopening, and damaged files.

use std::collections::HashSet;
use std::path::PathBuf;
use std::time::Duration;

use glam::DVec3;
use strata_terrain::{Recipe, StoredChunk, World, WorldError, WorldSettings, WorldStore};
use strata_volume::brush::{Brush, Sphere};
use strata_volume::{ChunkKey, CsgOp, EditSettings};

/// A fresh directory for one test's files.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-terrain-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn settings(view: f64) -> WorldSettings {
    WorldSettings {
        view_distance: view,
        vertical_ratio: 0.5,
        threads: 2,
        frame_budget: Duration::from_millis(20),
        flush_interval: Duration::from_secs(3600),
        memory_budget: usize::MAX,
        ..WorldSettings::default()
    }
}

const SETTLE: Duration = Duration::from_secs(120);

/// Every loaded chunk's stored form, for comparing worlds bit for bit.
fn snapshot(world: &World, keys: &[ChunkKey]) -> Vec<(ChunkKey, StoredChunk)> {
    keys.iter()
        .map(|&k| {
            assert!(world.is_loaded(k), "{k:?} is loaded");
            let v = world.volume();
            (k, StoredChunk { chunk: v.chunk(k).cloned(), materials: v.chunk_materials(k).cloned() })
        })
        .collect()
}

#[test]
fn a_viewer_on_a_path_loads_exactly_the_chunks_in_view_and_evicts_the_others() {
    let mut world = World::in_memory(&Recipe::with_seed(2), settings(40.0)).unwrap();
    let path = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(30.0, 5.0, 0.0),
        DVec3::new(100.0, -10.0, 40.0),
        DVec3::new(-60.0, 20.0, -60.0),
    ];
    for p in path {
        assert!(world.settle(&[p], SETTLE), "streaming settles");
        let want = world.chunks_in_view(&[p]);
        let have: HashSet<ChunkKey> = world.loaded().collect();
        assert_eq!(have, want, "loaded chunks at {p}");
        assert!(!want.is_empty());
        // Only loaded chunks are in the volume.
        assert!(world.volume().chunks().all(|(k, _)| have.contains(&k)));
        world.volume().check_invariants_within(&|k| have.contains(&k)).unwrap();
    }
    // Two viewers: the union of their views.
    let two = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(200.0, 0.0, 0.0)];
    assert!(world.settle(&two, SETTLE));
    assert_eq!(world.loaded().collect::<HashSet<_>>(), world.chunks_in_view(&two));
}

#[test]
fn memory_stays_under_the_budget_on_a_long_path() {
    let budget = 40 << 10;
    let mut s = settings(64.0);
    s.memory_budget = budget;
    let mut world = World::in_memory(&Recipe::with_seed(4), s).unwrap();
    let mut over = false;
    let mut most = 0;
    for i in 0..400 {
        let p = DVec3::new(i as f64 * 4.0, 0.0, (i as f64 * 0.05).sin() * 200.0);
        let r = world.update(&[p]);
        over |= r.over_budget;
        most = most.max(world.loaded_bytes());
        assert!(world.loaded_bytes() <= budget, "{} bytes loaded at step {i}", world.loaded_bytes());
        std::thread::sleep(Duration::from_millis(2));
    }
    // (On a loaded machine the workers may lag the path: at its end, wait for them.)
    let end = DVec3::new(399.0 * 4.0, 0.0, (399.0f64 * 0.05).sin() * 200.0);
    let t0 = std::time::Instant::now();
    while !over && t0.elapsed() < Duration::from_secs(20) {
        over |= world.update(&[end]).over_budget;
        most = most.max(world.loaded_bytes());
        assert!(world.loaded_bytes() <= budget, "{} bytes loaded at the path's end", world.loaded_bytes());
        std::thread::sleep(Duration::from_millis(5));
    }
    // The view of 64 cells holds more than the budget: it was the budget that held chunks back.
    assert!(over, "the path reached the budget (at most {most} bytes were loaded)");
}

fn crater(
    at: DVec3,
    r: f64,
) -> impl Fn(&mut strata_volume::Volume) -> Result<strata_volume::EditReport, strata_volume::EditError> {
    move |v| v.apply(CsgOp::Subtract, &Sphere::new(at, r).unwrap(), &EditSettings::default())
}

fn bounds_of(at: DVec3, r: f64) -> strata_volume::brush::Aabb {
    Sphere::new(at, r).unwrap().bounds()
}

#[test]
fn edits_survive_eviction_reload_and_reopening_bit_for_bit() {
    let dir = scratch("paging");
    let file = dir.join("world.redb");
    let home = DVec3::new(8.0, 0.0, 8.0);
    let far = DVec3::new(2000.0, 0.0, 0.0);
    let spot = DVec3::new(8.0, 0.0, 8.0);
    let (before, keys) = {
        let mut world = World::create(&file, &Recipe::with_seed(9), settings(32.0)).unwrap();
        assert!(world.settle(&[home], SETTLE));
        let surface = world.volume().raycast(spot + DVec3::Y * 200.0, -DVec3::Y, 400.0).expect("the ray meets ground");
        world.edit(bounds_of(surface.point, 6.0), crater(surface.point, 6.0)).unwrap();
        // A second edit, painted: materials page too.
        let paint_at = surface.point + DVec3::new(3.0, -2.0, 0.0);
        world.edit(bounds_of(paint_at, 4.0), |v| v.paint(&Sphere::new(paint_at, 4.0).unwrap(), 5)).unwrap();
        // The edited chunks within the view (the edit also loaded a ring around itself, which
        // leaves memory with the next view change).
        let view = world.chunks_in_view(&[home]);
        let keys: Vec<ChunkKey> =
            world.take_changed().into_iter().collect::<HashSet<_>>().into_iter().filter(|k| view.contains(k)).collect();
        assert!(!keys.is_empty());
        let before = snapshot(&world, &keys);
        // Away (evicted before any flush: kept for the next one), and back.
        assert!(world.settle(&[far], SETTLE));
        assert!(keys.iter().all(|k| !world.is_loaded(*k)));
        assert!(world.unflushed() > 0);
        assert!(world.settle(&[home], SETTLE));
        assert_eq!(snapshot(&world, &keys), before, "after eviction before a flush");
        // Flushed, away, back: read from the database.
        world.flush().unwrap();
        assert!(world.settle(&[far], SETTLE));
        assert!(world.settle(&[home], SETTLE));
        assert_eq!(snapshot(&world, &keys), before, "after a flush and eviction");
        (before, keys)
    };
    // Reopened.
    let mut world = World::open(&file, settings(32.0)).unwrap();
    assert!(world.store().unwrap().verify().unwrap() > 0);
    assert!(world.settle(&[home], SETTLE));
    assert_eq!(snapshot(&world, &keys), before, "after reopening");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn undo_works_across_eviction_and_an_undone_chunk_loses_its_record() {
    let dir = scratch("undo");
    let file = dir.join("world.redb");
    let home = DVec3::new(-20.0, 0.0, 30.0);
    let mut world = World::create(&file, &Recipe::with_seed(12), settings(32.0)).unwrap();
    assert!(world.settle(&[home], SETTLE));
    let keys: Vec<ChunkKey> = world.loaded().collect();
    let generated = snapshot(&world, &keys);
    let hit = world.volume().raycast(home + DVec3::Y * 200.0, -DVec3::Y, 400.0).unwrap().point;
    let record = world.edit(bounds_of(hit, 5.0), crater(hit, 5.0)).unwrap().undo;
    assert_ne!(snapshot(&world, &keys), generated);
    world.flush().unwrap();
    assert!(!world.store().unwrap().edited_keys().unwrap().is_empty());
    assert!(world.settle(&[DVec3::new(5000.0, 0.0, 0.0)], SETTLE));
    // Undo with the edited chunks out of memory: they are loaded for it.
    let redo = world.restore(record).unwrap_or_else(|b| panic!("{}", b.0));
    assert!(world.settle(&[home], SETTLE));
    assert_eq!(snapshot(&world, &keys), generated);
    world.flush().unwrap();
    assert!(world.store().unwrap().edited_keys().unwrap().is_empty(), "chunks back to the recipe are not stored");
    world.restore(redo).unwrap_or_else(|b| panic!("{}", b.0));
    assert_ne!(snapshot(&world, &keys), generated);
    drop(world);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn damaged_world_files_give_clear_errors() {
    let dir = scratch("damaged");
    // Not a database at all.
    let junk = dir.join("junk.redb");
    std::fs::write(&junk, b"this is not a world").unwrap();
    let e = World::open(&junk, settings(16.0)).unwrap_err();
    assert!(matches!(e, WorldError::Store(_)), "{e}");
    assert!(!e.to_string().is_empty());
    // Missing.
    assert!(World::open(&dir.join("missing.redb"), settings(16.0)).is_err());
    // A world with an edit, then every byte of a stretch overwritten: opening, verifying or
    // reading fails with an error, never a panic.
    let file = dir.join("world.redb");
    {
        let mut world = World::create(&file, &Recipe::with_seed(1), settings(16.0)).unwrap();
        let at = DVec3::new(4.0, 0.0, 4.0);
        world.edit(bounds_of(at, 20.0), crater(at, 20.0)).unwrap();
        world.flush().unwrap();
    }
    let clean = std::fs::read(&file).unwrap();
    let mut failures = 0;
    for (i, start) in (0..clean.len()).step_by(clean.len() / 16 + 1).enumerate() {
        let mut bytes = clean.clone();
        for b in bytes.iter_mut().skip(start).take(512) {
            *b = (i as u8).wrapping_mul(37) ^ 0x5a;
        }
        let damaged = dir.join(format!("damaged-{i}.redb"));
        std::fs::write(&damaged, &bytes).unwrap();
        let outcome = std::panic::catch_unwind(|| match WorldStore::open(&damaged) {
            Err(e) => Err(e.to_string()),
            Ok(store) => store.verify().map(|_| ()).map_err(|e| e.to_string()),
        });
        match outcome {
            Ok(Err(msg)) => {
                assert!(!msg.is_empty());
                failures += 1;
            }
            Ok(Ok(())) => {}
            Err(_) => panic!("a damaged world at byte {start} made the program panic"),
        }
    }
    assert!(failures > 0, "some damage is detected");
    // A record that is not a chunk.
    let store = WorldStore::open(&file).unwrap();
    let k = store.edited_keys().unwrap()[0];
    assert!(strata_terrain::decode_record(&[1, 2, 3, 4, 5]).is_err());
    assert!(store.read(k).unwrap().is_some());
    drop(store);
    let _ = std::fs::remove_dir_all(dir);
}

/// Every kind of edit through `World::edit` on a streamed world: CSG with each brush shape, the
/// sculpting tools (clay, smooth, inflate, flatten, pinch, grab) and paint, each at the surface
/// and across chunk borders; invariants hold within what is loaded after every one, and undoing
/// them all gives back the generated world bit for bit.
#[test]
fn every_tool_and_brush_edits_a_streamed_world_and_undoes() {
    use strata_volume::brush::{Capsule, Cuboid, Cylinder, Torus};
    use strata_volume::tools::{self, Dab, Smoothing};
    let mut world = World::in_memory(&Recipe::with_seed(6), settings(40.0)).unwrap();
    let home = DVec3::new(15.5, 0.0, 16.0);
    assert!(world.settle(&[home], SETTLE));
    let loaded: Vec<ChunkKey> = world.loaded().collect();
    let generated = snapshot(&world, &loaded);
    let ground =
        |w: &World, x: f64, z: f64| w.volume().raycast(DVec3::new(x, 120.0, z), -DVec3::Y, 400.0).unwrap().point;
    // Points on chunk borders (x = 16, z = 16) and off them.
    let spots = [(16.0, 16.0), (9.0, 22.0), (23.5, 8.25), (16.0, 3.0)];
    let mut records = Vec::new();
    for (i, &(x, z)) in spots.iter().cycle().take(12).enumerate() {
        let at = ground(&world, x, z);
        let r = 3.0 + (i % 3) as f64;
        let dab = Dab { material: 3, ..Dab::new(at, r, 0.8).unwrap() };
        let bounds = Sphere::new(at, r * 2.5).unwrap().bounds();
        let report = match i {
            0 => world.edit(bounds, |v| v.add(&Cuboid::new(at, DVec3::splat(r)).unwrap())),
            1 => world
                .edit(bounds, |v| v.subtract(&Capsule::new(at - DVec3::X * r, at + DVec3::Z * r, r * 0.5).unwrap())),
            2 => world.edit(bounds, |v| v.add(&Cylinder::new(at, DVec3::Y, r, r * 0.6).unwrap())),
            3 => world.edit(bounds, |v| v.subtract(&Torus::new(at, DVec3::Y, r, r * 0.3).unwrap())),
            4 => world.edit(bounds, |v| tools::clay(v, &dab, 1.5, false)),
            5 => world.edit(bounds, |v| tools::smooth(v, &dab, Smoothing::Laplacian, 2)),
            6 => world.edit(bounds, |v| tools::inflate(v, &dab, 0.8)),
            7 => world.edit(bounds, |v| tools::flatten(v, &dab)),
            8 => world.edit(bounds, |v| tools::pinch(v, &dab, None, 0.5)),
            9 => world.edit(bounds, |v| tools::grab(v, &dab, DVec3::new(1.5, 1.0, 0.0))),
            10 => world.edit(bounds, |v| tools::paint(v, &dab)),
            // A ball centred on a node, its radius a whole number of cells: nodes on its surface.
            _ => world.edit(bounds, |v| v.subtract(&Sphere::new(at.round(), 2.0).unwrap())),
        };
        let report = report.unwrap_or_else(|e| panic!("edit {i}: {e}"));
        records.push(report.undo);
        let known: HashSet<ChunkKey> = world.loaded().collect();
        world.volume().check_invariants_within(&|k| known.contains(&k)).unwrap_or_else(|e| panic!("edit {i}: {e}"));
    }
    let edits = records.iter().filter(|r| !r.is_empty()).count();
    assert!(edits >= 10, "the edits changed the world ({edits})");
    for record in records.into_iter().rev() {
        world.restore(record).unwrap_or_else(|b| panic!("{}", b.0));
    }
    assert_eq!(snapshot(&world, &loaded), generated, "undoing everything gives the generated world back");
}

/// Detail near the viewer: chunks within the detail distance are generated at level 1, the
/// others at the base level; moving away brings them back to the base level; the loaded
/// volume keeps every invariant across the seams between levels, its welded marching-cubes mesh
/// is closed, and an edit in a fine chunk keeps its level when the viewer leaves.
#[test]
fn chunks_near_the_viewer_are_finer_and_follow_it() {
    let mut s = settings(48.0);
    s.detail_distance = 20.0;
    let mut world = World::in_memory(&Recipe::with_seed(8), s).unwrap();
    let fine = strata_volume::Level::new(1).unwrap();
    let home = DVec3::new(8.0, 0.0, 8.0);
    assert!(world.settle(&[home], SETTLE));
    let counts = levels_follow(&world, |_| ());
    let at = |l: strata_volume::Level| counts[l.index()];
    assert!(at(strata_volume::Level::BASE) > 0 && at(fine) > 0, "both levels in view: {counts:?}");
    // An edit near the viewer, in fine chunks.
    let hit = world.volume().raycast(home + DVec3::Y * 100.0, -DVec3::Y, 300.0).unwrap().point;
    let report = world.edit(bounds_of(hit, 3.0), crater(hit, 3.0)).unwrap();
    let edited: Vec<ChunkKey> =
        report.changed.iter().copied().filter(|k| world.volume().stored_level(*k) == Some(fine)).collect();
    assert!(!edited.is_empty());
    let away = home + DVec3::new(40.0, 0.0, 0.0);
    assert!(world.settle(&[away], SETTLE));
    for &k in &edited {
        if world.is_loaded(k) {
            assert_eq!(world.volume().stored_level(k), Some(fine), "the edited chunk {k:?} keeps its level");
        }
    }
    // Apart from the edited chunks, every level follows the viewer.
    let loaded: HashSet<ChunkKey> = world.loaded().collect();
    for &k in &loaded {
        if let Some(l) = world.volume().stored_level(k)
            && !edited.contains(&k)
        {
            assert_eq!(l, world.generated_level(k), "{k:?}");
        }
    }
    world.volume().check_invariants_within(&|k| loaded.contains(&k)).unwrap();
    closed_inside(&world, &loaded);
}

/// Far terrain coarse (a clipmap): with a coarse distance, chunks beyond it are generated at
/// level −1, those within it at the base level, those within the detail distance at level 1,
/// each equal bit for bit to the chunk generated alone at its level (a solid chunk's materials
/// per base node, as the volume reads a uniform chunk's); the levels follow the
/// viewer; the loaded volume keeps every invariant across the seams of all three levels and
/// its welded mesh is closed. An edit out in the coarse ring is made at the base level, with
/// the same chunks as the same edit of a world without a coarse ring.
#[test]
fn far_chunks_are_coarse_follow_the_viewer_and_are_edited_at_the_base_level() {
    use strata_volume::Level;
    let mut s = settings(72.0);
    s.detail_distance = 16.0;
    s.coarse_distance = 40.0;
    let recipe = Recipe::with_seed(8);
    let field = strata_terrain::TerrainField::new(&recipe).unwrap();
    let mut world = World::in_memory(&recipe, s.clone()).unwrap();
    let check = |world: &World| {
        levels_follow(world, |k| {
            let want = world.generated_level(k);
            let g = strata_volume::generate_chunk(k, want, &field);
            assert!(world.volume().chunk(k) == g.chunk.as_ref(), "{k:?} as generated alone at {want:?}");
            // A uniform chunk has no level: its materials are per node of the base level.
            let materials = match g.chunk {
                Some(strata_volume::Chunk::Solid) => strata_volume::solid_chunk_materials(k, Level::BASE, &field),
                _ => g.materials,
            };
            assert_eq!(world.volume().chunk_materials(k), materials.as_ref(), "{k:?}'s materials");
        })
    };
    let home = DVec3::new(8.0, 0.0, 8.0);
    assert!(world.settle(&[home], SETTLE));
    let counts = check(&world);
    let at = |l: Level| counts[l.index()];
    assert!(
        at(Level::COARSEST) > 0 && at(Level::BASE) > 0 && at(Level::new(1).unwrap()) > 0,
        "three levels in view: {counts:?}"
    );
    // Moving on: chunks that crossed either distance are generated again at their new level,
    // one chunk at a time and in one jump.
    for step in 1..=3 {
        assert!(world.settle(&[home + DVec3::new(16.0 * step as f64, 0.0, 0.0)], SETTLE));
    }
    check(&world);
    let away = home + DVec3::new(48.0, 0.0, 96.0);
    assert!(world.settle(&[away], SETTLE));
    check(&world);
    // An edit out in the coarse ring, against the same edit of a world whose ring is not coarse.
    let mut plain = World::in_memory(&recipe, WorldSettings { coarse_distance: 0.0, ..s }).unwrap();
    assert!(plain.settle(&[away], SETTLE));
    let far = away + DVec3::new(56.0, 0.0, 8.0);
    let key = ChunkKey::containing(far).unwrap();
    let hit = plain.volume().raycast(far + DVec3::Y * 100.0, -DVec3::Y, 300.0).unwrap().point;
    assert_eq!(world.generated_level(ChunkKey::containing(hit).unwrap()), Level::COARSEST, "{key:?} is far");
    let report = world.edit(bounds_of(hit, 3.0), crater(hit, 3.0)).unwrap();
    let expected = plain.edit(bounds_of(hit, 3.0), crater(hit, 3.0)).unwrap();
    assert!(!report.changed.is_empty());
    assert_eq!(report.changed, expected.changed);
    assert_eq!(snapshot(&world, &report.changed), snapshot(&plain, &expected.changed), "the same edit");
    for &k in &report.changed {
        assert!(world.volume().stored_level(k).is_none_or(|l| l >= Level::BASE), "{k:?} edited at the base level");
    }
    let loaded: HashSet<ChunkKey> = world.loaded().collect();
    world.volume().check_invariants_within(&|k| loaded.contains(&k)).unwrap();
    closed_inside(&world, &loaded);
    // The edited chunks keep their level when the viewer moves on; the others follow it.
    assert!(world.settle(&[away + DVec3::new(-32.0, 0.0, 0.0)], SETTLE));
    for &k in &report.changed {
        if let Some(l) = world.volume().stored_level(k) {
            assert!(l >= Level::BASE, "{k:?} keeps the level it was edited at");
        }
    }
}

/// An edit beside chunks still waiting to be generated again at their level (the viewer just
/// moved across the detail distance) does not leave them at the old one: once the world
/// settles, every chunk the edit did not change is at the level its distance asks for.
#[test]
fn an_edit_beside_chunks_changing_level_leaves_them_to_reach_it() {
    let mut s = settings(48.0);
    s.detail_distance = 20.0;
    s.threads = 1;
    let mut world = World::in_memory(&Recipe::with_seed(8), s).unwrap();
    let home = DVec3::new(8.0, 0.0, 8.0);
    assert!(world.settle(&[home], SETTLE));
    let hit = world.volume().raycast(home + DVec3::new(24.0, 100.0, 0.0), -DVec3::Y, 300.0).unwrap().point;
    // One update at the new place queues the level changes; the edit comes before they are done.
    let _ = world.update(&[home + DVec3::new(32.0, 0.0, 0.0)]);
    assert!(world.pending_count() > 0, "level changes queued");
    let report = world.edit(bounds_of(hit, 2.0), crater(hit, 2.0)).unwrap();
    assert!(world.settle(&[home + DVec3::new(32.0, 0.0, 0.0)], SETTLE));
    for k in world.loaded().collect::<Vec<_>>() {
        if let Some(l) = world.volume().stored_level(k)
            && !report.changed.contains(&k)
        {
            assert_eq!(l, world.generated_level(k), "{k:?}");
        }
    }
}

/// Every loaded list chunk is at the level its distance asks for (and passes `each`, as every
/// loaded chunk does), the loaded volume keeps every invariant, and its welded mesh is closed
/// inside what is loaded; returns how many list chunks each level holds.
fn levels_follow(world: &World, each: impl Fn(ChunkKey)) -> [usize; strata_volume::coords::LEVEL_COUNT] {
    let loaded: HashSet<ChunkKey> = world.loaded().collect();
    let mut counts = [0usize; strata_volume::coords::LEVEL_COUNT];
    for &k in &loaded {
        if let Some(l) = world.volume().stored_level(k) {
            assert_eq!(l, world.generated_level(k), "{k:?} at the level its distance asks for");
            counts[l.index()] += 1;
        }
        each(k);
    }
    world.volume().check_invariants_within(&|k| loaded.contains(&k)).unwrap();
    closed_inside(world, &loaded);
    counts
}

/// The welded marching-cubes mesh of the loaded chunks has no open or non-manifold edge except
/// at the border of what is loaded (where the lists continue in chunks not in memory), seams
/// between levels included.
fn closed_inside(world: &World, loaded: &HashSet<ChunkKey>) {
    let mesh = strata_mesh::mesh_volume_with(world.volume(), strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    let mut uses: std::collections::HashMap<(u32, u32), i32> = std::collections::HashMap::new();
    for t in mesh.indices.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &uses {
        if n == 2 {
            continue;
        }
        let (pa, pb) = (
            DVec3::from(mesh.positions[a as usize].map(f64::from)),
            DVec3::from(mesh.positions[b as usize].map(f64::from)),
        );
        let mid = (pa + pb) / 2.0;
        let k = ChunkKey((mid / 16.0).floor().as_ivec3());
        let at_border = k.around().chain([k]).any(|n| !loaded.contains(&n));
        assert!(at_border, "edge {pa} – {pb} is used {n} times inside the loaded chunks");
    }
    assert!(mesh.indices.len() > 3000, "a mesh was made");
}

#[test]
fn sky_is_loaded_without_workers_but_an_edit_in_the_sky_comes_back_from_the_database() {
    let dir = scratch("sky");
    let file = dir.join("world.redb");
    let home = DVec3::new(8.0, 0.0, 8.0);
    let far = DVec3::new(2000.0, 0.0, 0.0);
    let mut world = World::create(&file, &Recipe::with_seed(5), settings(48.0)).unwrap();
    // The lowest chunk above home that the recipe proves empty.
    let sky = (0..64)
        .map(|y| ChunkKey::new(0, y, 0))
        .find(|k| world.field().decided_by_recipe(k.origin_grid()) == Some(false))
        .expect("the recipe has a top");
    // What a worker would have made of it: nothing.
    let g = strata_volume::generate_chunk(sky, strata_volume::Level::BASE, world.field());
    assert!(g.chunk.is_none() && g.materials.is_none());
    let viewer = sky.origin_grid().as_dvec3() + DVec3::splat(8.0);
    let mut proven = 0;
    let t0 = std::time::Instant::now();
    while world.pending_count() > 0 || proven == 0 {
        proven += world.update(&[viewer]).proven_empty;
        assert!(t0.elapsed() < SETTLE, "streaming settles");
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(world.settle(&[viewer], SETTLE));
    assert!(proven > 0, "some of the view is provably sky");
    assert_eq!(world.loaded().collect::<HashSet<_>>(), world.chunks_in_view(&[viewer]));
    // A ball built in the sky, flushed, evicted and seen again: read from the database, not
    // taken for sky.
    let ball = sky.origin_grid().as_dvec3() + DVec3::new(8.3, 7.9, 8.1);
    let add = move |v: &mut strata_volume::Volume| {
        v.apply(CsgOp::Add, &Sphere::new(ball, 5.0).unwrap(), &EditSettings::default())
    };
    world.edit(bounds_of(ball, 5.0), add).unwrap();
    assert!(world.volume().chunk(sky).is_some());
    let before = snapshot(&world, &[sky]);
    world.flush().unwrap();
    assert!(world.settle(&[far], SETTLE));
    assert!(!world.is_loaded(sky));
    assert!(world.settle(&[viewer], SETTLE));
    assert_eq!(snapshot(&world, &[sky]), before, "after a flush and eviction");
    drop(world);
    let mut world = World::open(&file, settings(48.0)).unwrap();
    assert!(world.settle(&[viewer], SETTLE));
    assert_eq!(snapshot(&world, &[sky]), before, "after reopening");
    // Home, far below the sky, loads as before.
    assert!(world.settle(&[home], SETTLE));
    assert_eq!(world.loaded().collect::<HashSet<_>>(), world.chunks_in_view(&[home]));
    let _ = std::fs::remove_dir_all(dir);
}

#[cfg(target_os = "linux")]
#[test]
fn generating_threads_run_below_the_normal_priority() {
    let world = World::in_memory(&Recipe::with_seed(2), settings(40.0)).unwrap();
    // The threads lower themselves as they start.
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    loop {
        let nice = strata_tests::thread_nice("terrain-");
        // The least priority: nice 19 (below the meshers' 9).
        if nice.len() >= 2 && nice.iter().all(|&n| n == 19) {
            break;
        }
        assert!(std::time::Instant::now() < deadline, "terrain threads' nice values: {nice:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
    drop(world);
}
