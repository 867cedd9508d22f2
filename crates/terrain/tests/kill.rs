//! A child process editing and flushing a world is killed with SIGKILL at random moments; every
//! reopen must give exactly the world after the edits its last committed flush recorded.

use std::path::Path;
use std::time::Duration;

use glam::DVec3;
use strata_terrain::{Recipe, StoredChunk, World, WorldSettings, WorldStore};
use strata_tests::files::kill_at_random_moments;
use strata_volume::brush::{Brush, Sphere};
use strata_volume::{ChunkKey, CsgOp, EditSettings};

fn settings() -> WorldSettings {
    WorldSettings {
        view_distance: 0.0,
        vertical_ratio: 0.5,
        threads: 1,
        frame_budget: Duration::from_millis(5),
        flush_interval: Duration::from_secs(3600),
        memory_budget: usize::MAX,
        ..WorldSettings::default()
    }
}

/// Edit number `k` (from 1): a ball added or carved near the origin's surface.
fn apply(world: &mut World, k: u64) {
    let mut h = k.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let mut next = || {
        h ^= h >> 29;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        (h >> 11) as f64 / (1u64 << 53) as f64
    };
    let c = DVec3::new(next() * 48.0 - 24.0, next() * 24.0 - 12.0, next() * 48.0 - 24.0);
    let r = 2.0 + next() * 5.0;
    let op = if k.is_multiple_of(3) { CsgOp::Add } else { CsgOp::Subtract };
    let ball = Sphere::new(c, r).unwrap();
    world
        .edit(ball.bounds(), |v| {
            v.apply(op, &ball, &EditSettings { material: (k % 5) as u8, ..EditSettings::default() })
        })
        .unwrap();
}

fn edits_done(store: &WorldStore) -> u64 {
    store.note("edits").unwrap().map_or(0, |b| u64::from_le_bytes(b.try_into().unwrap()))
}

/// Run by the kill test in a child process: edits and flushes the world at
/// `STRATA_WORLD_CHILD` until it is killed.
#[test]
#[ignore = "a helper: run as a child process by the kill test"]
fn world_child_process() {
    let Ok(path) = std::env::var("STRATA_WORLD_CHILD") else { return };
    let mut world = World::open(Path::new(&path), settings()).unwrap();
    let mut k = edits_done(world.store().unwrap());
    loop {
        k += 1;
        apply(&mut world, k);
        world.set_note("edits", k.to_le_bytes().to_vec());
        world.flush().unwrap();
    }
}

#[test]
fn worlds_killed_mid_flush_reopen_as_the_last_committed_state() {
    let dir = std::env::temp_dir().join(format!("strata-terrain-kill-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("world.redb");
    let recipe = Recipe::with_seed(21);
    drop(World::create(&path, &recipe, settings()).unwrap());
    // The reference: the same edits in memory, as far as the world on disk has got.
    let mut reference = World::in_memory(&recipe, settings()).unwrap();
    let mut replayed = 0u64;
    let mut touched = std::collections::BTreeSet::<ChunkKey>::new();
    let mut progress = Vec::new();
    kill_at_random_moments("world_child_process", "STRATA_WORLD_CHILD", &path, 50, 40_000..200_000, |round| {
        let store = WorldStore::open(&path).unwrap_or_else(|e| panic!("round {round}: the world does not open: {e}"));
        store.verify().unwrap_or_else(|e| panic!("round {round}: a damaged chunk: {e}"));
        let k = edits_done(&store);
        assert!(k >= replayed, "round {round}: committed edits went back from {replayed} to {k}");
        while replayed < k {
            replayed += 1;
            apply(&mut reference, replayed);
            touched.extend(reference.take_changed());
        }
        progress.push(k);
        // Every chunk on disk is the reference's; every chunk not on disk is as generated.
        let stored: std::collections::BTreeSet<ChunkKey> = store.edited_keys().unwrap().into_iter().collect();
        let keys: Vec<ChunkKey> = touched.iter().copied().chain(stored.iter().copied()).collect();
        reference.load_now(&keys).unwrap();
        for &key in &keys {
            let want = StoredChunk {
                chunk: reference.volume().chunk(key).cloned(),
                materials: reference.volume().chunk_materials(key).cloned(),
            };
            let got = match store.read(key).unwrap() {
                Some(s) => s,
                None => {
                    let g = strata_volume::generate_chunk(key, strata_volume::Level::BASE, reference.field());
                    StoredChunk { chunk: g.chunk, materials: g.materials }
                }
            };
            assert!(got == want, "round {round}: chunk {key:?} is not the state after {k} edits");
        }
    });
    assert!(replayed > 5, "the child made progress: {progress:?}");
    eprintln!("committed edits after each kill: {progress:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
