//! Scene files: round trips, corrupted and truncated files, interrupted saves, and random
//! byte mutations (`PROPTEST_CASES=100000 cargo test --release -p strata-editor --test files`
//! for the long run; CI runs the default 512 cases).

use std::path::{Path, PathBuf};

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use strata_editor::file::{self, SceneFileError, decode, encode, load, save, write_atomically};
use strata_editor::{Layer, LayerTransform, Material, Scene};
use strata_tests::files::{kill_at_random_moments, race_writers_with_reader};
use strata_volume::brush::{Cuboid, Sphere, Torus};
use strata_volume::{Chunk, ChunkKey, ChunkMaterials, Level, Volume};

/// The temporary files of saves of `path` present in its folder.
fn temp_files(path: &Path) -> Vec<PathBuf> {
    let prefix = format!(".{}.", path.file_name().unwrap().to_str().unwrap());
    std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_str().is_some_and(|n| n.starts_with(&prefix) && n.ends_with(".strata-tmp")))
        .map(|e| e.path())
        .collect()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-files-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn scene() -> Scene {
    let mut s = Scene::default();
    s.layers[0].volume.add(&Sphere::new(DVec3::new(8.0, 9.0, 10.0), 7.5).unwrap()).unwrap();
    let mut b = Layer::new("rocks");
    b.transform =
        LayerTransform { translation: DVec3::new(40.0, 0.0, -3.0), rotation: DQuat::from_rotation_z(0.3), scale: 0.25 };
    b.volume.add(&Cuboid::new(DVec3::new(-20.0, 3.0, 5.0), DVec3::new(6.0, 2.0, 9.0)).unwrap()).unwrap();
    b.volume.subtract(&Torus::new(DVec3::new(-20.0, 3.0, 5.0), DVec3::Y, 5.0, 1.5).unwrap()).unwrap();
    b.volume.fill_materials(1);
    b.locked = true;
    let mut c = Layer::new("hidden, empty");
    c.visible = false;
    s.layers.push(b);
    s.layers.push(c);
    s.materials.push(Material::new("Moss", [0.2, 0.5, 0.1], strata_editor::Texture::Grass));
    // Node materials of several runs in one layer.
    s.layers[0].volume.paint(&Sphere::new(DVec3::new(12.0, 9.0, 10.0), 4.0).unwrap(), 8).unwrap();
    s.layers[0].volume.paint(&Cuboid::new(DVec3::new(4.0, 9.0, 10.0), DVec3::splat(2.5)).unwrap(), 3).unwrap();
    s.view.yaw = -1.2;
    s
}

#[test]
fn scenes_with_several_layers_round_trip() {
    let s = scene();
    let path = temp("round.strata");
    assert!(save(&s, &path).unwrap().is_clean(), "a valid scene needs no repair");
    let back = load(&path).unwrap();
    assert!(back.report.is_clean(), "{}", back.report);
    assert_eq!(back.scene, s);
    assert_eq!(decode(&encode(&s).unwrap()).unwrap().scene, s);
    assert_eq!(encode(&s).unwrap(), encode(&back.scene).unwrap(), "the same scene gives the same bytes");
    assert!(temp_files(&path).is_empty(), "no temporary file is left behind");
}

#[test]
fn corrupted_truncated_and_newer_files_fail_cleanly() {
    let bytes = encode(&scene()).unwrap();
    let mut flipped = bytes.clone();
    let mid = file::HEADER_LEN + (bytes.len() - file::HEADER_LEN) / 2;
    flipped[mid] ^= 0x10;
    // A damaged payload is either unreadable or read with the damage reported.
    match decode(&flipped) {
        Err(SceneFileError::Checksum) => {}
        Ok(l) => assert!(l.report.repairs.iter().any(|r| r.contains("checksum")), "{}", l.report),
        Err(e) => panic!("unexpected error {e}"),
    }
    assert!(matches!(decode(&bytes[..bytes.len() - 1]), Err(SceneFileError::Truncated { .. })));
    assert!(matches!(decode(&bytes[..10]), Err(SceneFileError::Truncated { .. })));
    assert!(matches!(decode(b"PK\x03\x04 a zip"), Err(SceneFileError::BadMagic)));
    assert!(matches!(decode(&[]), Err(SceneFileError::BadMagic)));
    let mut newer = bytes.clone();
    newer[8..12].copy_from_slice(&(file::VERSION + 1).to_le_bytes());
    let err = decode(&newer).unwrap_err();
    assert!(matches!(err, SceneFileError::NewerVersion { .. }));
    assert!(err.to_string().contains("newer"), "{err}");
    let mut older = bytes.clone();
    older[8..12].copy_from_slice(&1u32.to_le_bytes());
    let err = decode(&older).unwrap_err();
    assert!(matches!(err, SceneFileError::OldVersion { found: 1, .. }), "{err}");
    assert!(err.to_string().contains("older"), "{err}");
    // A payload that checks out but does not decode.
    let mut junk = bytes[..file::HEADER_LEN].to_vec();
    let payload = vec![0xff; 40];
    junk[12..20].copy_from_slice(&(payload.len() as u64).to_le_bytes());
    junk[20..24].copy_from_slice(&crc32fast_hash(&payload).to_le_bytes());
    junk.extend_from_slice(&payload);
    assert!(matches!(decode(&junk), Err(SceneFileError::Payload(_))));
    assert!(load(&temp("does-not-exist.strata")).is_err());
}

/// CRC-32 (IEEE), bit by bit: an independent check of the format's checksum.
fn crc32fast_hash(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

#[test]
fn the_header_checksum_is_standard_crc32() {
    let bytes = encode(&scene()).unwrap();
    let stored = u32::from_le_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!(stored, crc32fast_hash(&bytes[file::HEADER_LEN..]));
}

#[test]
fn an_interrupted_save_keeps_the_old_file() {
    let path = temp("keep.strata");
    let old = scene();
    save(&old, &path).unwrap();
    let before = std::fs::read(&path).unwrap();
    let mut new = scene();
    new.layers.pop();
    let bytes = encode(&new).unwrap();
    // The write fails halfway, as a full disk or a crash would leave it.
    let r = write_atomically(&path, |f| {
        use std::io::Write;
        f.write_all(&bytes[..bytes.len() / 2])?;
        Err(std::io::Error::other("disk full"))
    });
    assert!(r.is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(load(&path).unwrap().scene, old);
    assert!(temp_files(&path).is_empty());
    // Saving into a folder that does not exist is an error, not a panic.
    assert!(save(&new, &temp("no/such/folder/x.strata")).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: std::env::var("PROPTEST_CASES").ok().and_then(|c| c.parse().ok()).unwrap_or(512), ..ProptestConfig::default() })]
    #[test]
    fn mutated_files_never_panic(edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8), cut in any::<prop::sample::Index>(), fix_crc in any::<bool>()) {
        thread_local!(static BYTES: Vec<u8> = encode(&scene()).unwrap());
        let mut bytes = BYTES.with(|b| b.clone());
        for (i, v) in edits {
            let at = i.index(bytes.len());
            bytes[at] = v;
        }
        if cut.index(4) == 0 {
            bytes.truncate(cut.index(bytes.len()));
        }
        if fix_crc && bytes.len() >= file::HEADER_LEN && bytes[..8] == file::MAGIC {
            // Make the checksum and length agree so the payload decoder itself is exercised.
            let payload_len = (bytes.len() - file::HEADER_LEN) as u64;
            bytes[12..20].copy_from_slice(&payload_len.to_le_bytes());
            let crc = crc32fast_hash(&bytes[file::HEADER_LEN..]);
            bytes[20..24].copy_from_slice(&crc.to_le_bytes());
            // (The version written: 5 for a scene without reference images.)
            let version: [u8; 4] = BYTES.with(|b| b[8..12].try_into().unwrap());
            bytes[8..12].copy_from_slice(&version);
        }
        if let Ok(s) = decode(&bytes) {
            // Whatever decodes is a valid scene: its volumes pass the invariant checker.
            for l in &s.scene.layers {
                prop_assert!(l.volume.check_invariants().is_ok());
            }
        }
    }
}

/// A scene whose layer `i` of `n` holds a chunk of lists at `key` and a sphere elsewhere.
fn damaged_chunk_bytes() -> (Vec<u8>, Scene) {
    let s = scene();
    let mut bytes = encode(&s).unwrap();
    // Find the first chunk record's bytes by re-encoding one chunk and searching for them.
    let (key, chunk) = s.layers[0].volume.chunks().find(|(_, c)| matches!(c, strata_volume::Chunk::Lists(_))).unwrap();
    let strata_volume::Chunk::Lists(lists) = chunk else { unreachable!() };
    let blob = postcard::to_allocvec(lists).unwrap();
    let at = bytes.windows(blob.len()).position(|w| w == blob.as_slice()).expect("the chunk's bytes are in the file");
    // Flip a byte in the middle of the chunk's crossings, then fix the file's own checksum so
    // only the chunk's checksum can tell.
    bytes[at + blob.len() / 2] ^= 0x5a;
    let crc = crc32fast_hash(&bytes[file::HEADER_LEN..]);
    bytes[20..24].copy_from_slice(&crc.to_le_bytes());
    let _ = key;
    (bytes, s)
}

#[test]
fn a_damaged_chunk_is_dropped_and_reported_and_the_rest_recovered() {
    let (bytes, original) = damaged_chunk_bytes();
    let loaded = decode(&bytes).expect("the scene is recovered");
    assert!(loaded.report.repairs.iter().any(|r| r.contains("failed its checksum")), "{}", loaded.report);
    let s = &loaded.scene;
    assert_eq!(s.layers.len(), 3);
    assert_eq!(s.layers[1], original.layers[1], "untouched layers come back exactly");
    assert_eq!(s.materials, original.materials);
    for l in &s.layers {
        l.volume.check_invariants().expect("a recovered volume is consistent");
    }
    // The damaged layer lost about one chunk, not everything.
    let (before, after) = (original.layers[0].volume.chunk_count(), s.layers[0].volume.chunk_count());
    assert!(after + 8 >= before && after > 0, "{before} chunks before, {after} after");
}

#[test]
fn saving_repairs_what_loading_would_refuse_and_says_so() {
    let mut s = scene();
    // A zero rotation set through the API, nodes of a material the palette lacks, a NaN view.
    s.layers[1].transform.rotation = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    s.layers[1].volume.fill_materials(40);
    s.view.distance = f64::INFINITY;
    assert!(!file::is_valid(&s));
    let path = temp("repaired.strata");
    let report = save(&s, &path).unwrap();
    assert_eq!(report.repairs.len(), 3, "{report}");
    assert!(report.repairs[0].contains("rocks") && report.repairs[0].contains("rotation"), "{report}");
    let back = load(&path).unwrap();
    assert!(back.report.is_clean(), "what was saved needs no repair: {}", back.report);
    assert!(back.scene.layers[1].transform.is_valid());
    let chunks = |v: &strata_volume::Volume| v.chunks().map(|(k, c)| (k, c.clone())).collect::<Vec<_>>();
    assert_eq!(chunks(&back.scene.layers[1].volume), chunks(&s.layers[1].volume));
    assert_eq!(back.scene.layers[1].volume.max_material(), Some(0), "unknown materials became material 0");
    assert!(back.scene.view.distance.is_finite());
    // The validated copy is what was written; the scene passed in is untouched.
    assert_eq!(s.layers[1].volume.max_material(), Some(40));
    let mut fixed = s.clone();
    assert_eq!(file::validate_scene(&mut fixed), report);
    assert_eq!(fixed, back.scene);
}

#[test]
fn layer_transforms_are_checked_where_they_enter() {
    assert!(LayerTransform::new(DVec3::ZERO, DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), 1.0).is_err());
    assert!(LayerTransform::new(DVec3::NAN, DQuat::IDENTITY, 1.0).is_err());
    for scale in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-12, 1e12] {
        assert!(LayerTransform::new(DVec3::ZERO, DQuat::IDENTITY, scale).is_err(), "scale {scale}");
    }
    let t = LayerTransform::new(DVec3::ONE, DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0), 0.5).unwrap();
    assert!(t.is_valid() && (t.rotation.length() - 1.0).abs() < 1e-12);
}

#[test]
fn a_cell_size_that_is_not_finite_and_positive_is_refused_on_deserialisation() {
    let mut v = strata_volume::Volume::new();
    v.add(&Sphere::new(DVec3::splat(8.0), 5.0).unwrap()).unwrap();
    let bytes = postcard::to_allocvec(&v).unwrap();
    assert_eq!(postcard::from_bytes::<strata_volume::Volume>(&bytes).unwrap(), v);
    // The cell size is the last field: an f64 in eight little-endian bytes.
    for bad in [f64::NAN, 0.0, -1.0, f64::INFINITY] {
        let mut b = bytes.clone();
        let n = b.len();
        b[n - 8..].copy_from_slice(&bad.to_le_bytes());
        let err = postcard::from_bytes::<strata_volume::Volume>(&b).unwrap_err();
        assert!(!err.to_string().is_empty(), "cell size {bad} refused");
    }
}

#[test]
fn version_2_files_still_open() {
    let s = scene();
    let payload = file::encode_version_2_payload(&s).unwrap();
    let mut bytes = file::MAGIC.to_vec();
    bytes.extend_from_slice(&2u32.to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&crc32fast_hash(&payload).to_le_bytes());
    bytes.extend_from_slice(&payload);
    let back = decode(&bytes).unwrap();
    assert!(back.report.is_clean(), "{}", back.report);
    assert_eq!(back.version, 2);
    // The shape comes back exactly; each layer's one material becomes its every node's.
    for (a, b) in back.scene.layers.iter().zip(&s.layers) {
        assert_eq!(a.volume.chunks().collect::<Vec<_>>(), b.volume.chunks().collect::<Vec<_>>());
        assert_eq!(a.name, b.name);
    }
    assert_eq!(
        back.scene.layers[1].volume.chunk_materials(strata_volume::ChunkKey::new(-2, 0, 0)).cloned(),
        Some(strata_volume::ChunkMaterials::Uniform(1))
    );
    assert_eq!(back.scene.materials.len(), s.materials.len());
    assert!(back.scene.materials.iter().zip(&s.materials).all(|(a, b)| a.name == b.name && a.color == b.color));
}

#[test]
fn unknown_material_ids_in_a_file_are_refused_with_a_clear_error() {
    let mut s = scene();
    s.layers[1].volume.fill_materials(200);
    // `encode` writes what it is given (`save` would repair it first).
    let err = decode(&encode(&s).unwrap()).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("rocks") && text.contains("200") && text.contains("palette"), "{text}");
}

#[test]
fn materials_survive_save_and_load_bit_for_bit() {
    let s = scene();
    assert!(s.layers[0].volume.material_chunks().any(|(_, m)| matches!(m, strata_volume::ChunkMaterials::Runs(_))));
    let back = decode(&encode(&s).unwrap()).unwrap();
    assert!(back.report.is_clean(), "{}", back.report);
    for (a, b) in back.scene.layers.iter().zip(&s.layers) {
        let mut ma: Vec<_> = a.volume.material_chunks().map(|(k, m)| (k, m.clone())).collect();
        let mut mb: Vec<_> = b.volume.material_chunks().map(|(k, m)| (k, m.clone())).collect();
        ma.sort_by_key(|(k, _)| k.0.to_array());
        mb.sort_by_key(|(k, _)| k.0.to_array());
        assert_eq!(ma, mb);
    }
    assert_eq!(back.scene.materials[8].texture, strata_editor::Texture::Grass);
}

#[cfg(unix)]
#[test]
fn non_regular_and_oversized_files_are_refused_before_reading() {
    let dir = temp("bounded");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // A link to an endless device.
    let zero = dir.join("zero.strata");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let err = load(&zero).unwrap_err();
    assert!(err.to_string().contains("not a regular file"), "{err}");
    // A FIFO: opening it would block until a writer comes; it is refused first.
    let fifo = dir.join("fifo.strata");
    let status = std::process::Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(status.success());
    let err = load(&fifo).unwrap_err();
    assert!(err.to_string().contains("not a regular file"), "{err}");
    // A sparse file over the limit: refused from its size, nothing read.
    let big = dir.join("big.strata");
    let f = std::fs::File::create(&big).unwrap();
    f.set_len(file::MAX_SCENE_BYTES + 1).unwrap();
    let rss = resident_bytes();
    let err = load(&big).unwrap_err();
    assert!(err.to_string().contains("larger than the limit"), "{err}");
    assert!(resident_bytes() < rss + (64 << 20), "memory did not grow");
    // A folder.
    assert!(load(&dir).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// This process's resident memory (Linux), or 0 where it cannot be read.
fn resident_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1).and_then(|p| p.parse::<u64>().ok()))
        .map_or(0, |pages| pages * 4096)
}

/// Two scenes of a few hundred kilobytes, so a save takes long enough to be interrupted.
fn big_scenes() -> (Scene, Scene) {
    let mut a = Scene::default();
    for i in 0..6 {
        let c = DVec3::new(20.0 * i as f64, 10.0, 5.0);
        a.layers[0].volume.add(&Sphere::new(c, 14.0).unwrap()).unwrap();
    }
    let mut b = a.clone();
    b.layers[0].volume.subtract(&Torus::new(DVec3::new(50.0, 10.0, 5.0), DVec3::Y, 20.0, 6.0).unwrap()).unwrap();
    b.layers.push(Layer::new("second"));
    (a, b)
}

/// Run by `saves_interrupted_by_a_kill_leave_the_old_or_the_new_file` in a child process: saves
/// the two scenes to the path in `STRATA_SAVE_CHILD` in turn until it is killed.
#[test]
#[ignore = "a helper: run as a child process by the kill test"]
fn save_child_process() {
    let Ok(path) = std::env::var("STRATA_SAVE_CHILD") else { return };
    let (a, b) = big_scenes();
    loop {
        save(&a, Path::new(&path)).unwrap();
        save(&b, Path::new(&path)).unwrap();
    }
}

#[test]
fn saves_interrupted_by_a_kill_leave_the_old_or_the_new_file() {
    let dir = temp("killed");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.strata");
    let (a, b) = big_scenes();
    save(&a, &path).unwrap();
    let mut killed_mid_save = 0;
    // Give the child time to start (tens of milliseconds), then kill it at a random moment.
    kill_at_random_moments("save_child_process", "STRATA_SAVE_CHILD", &path, 60, 20_000..80_000, |round| {
        let loaded = load(&path).unwrap_or_else(|e| panic!("round {round}: the file is corrupt: {e}"));
        assert!(loaded.report.is_clean());
        assert!(loaded.scene == a || loaded.scene == b, "round {round}: the file is neither scene");
        let temps = temp_files(&path);
        killed_mid_save += temps.len();
        assert!(temps.len() <= 1, "round {round}: temporary files accumulate: {temps:?}");
    });
    // The next save cleans up what the last killed save left.
    save(&a, &path).unwrap();
    assert!(temp_files(&path).is_empty());
    eprintln!("{killed_mid_save} of 60 kills left a temporary file behind (cleaned by the next save)");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn two_threads_saving_one_path_with_a_reader_never_show_a_corrupt_file() {
    let dir = temp("concurrent");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.strata");
    let (a, b) = big_scenes();
    save(&a, &path).unwrap();
    let saver = |scene| -> Box<dyn FnOnce() + Send + '_> {
        let path = &path;
        Box::new(move || {
            for _ in 0..200 {
                save(scene, path).unwrap();
            }
        })
    };
    let (reads, corrupt) = race_writers_with_reader(
        vec![saver(&a), saver(&b)],
        || matches!(load(&path), Ok(l) if l.report.is_clean() && (l.scene == a || l.scene == b)),
    );
    assert_eq!(corrupt, 0, "{corrupt} corrupt reads of {}", reads + corrupt);
    assert!(reads > 0);
    let last = load(&path).unwrap().scene;
    assert!(last == a || last == b);
    assert!(temp_files(&path).is_empty(), "no temporary files remain");
    std::fs::remove_dir_all(&dir).unwrap();
}

// Crafted files: fields that contradict each other, written through the format's own records.

/// A ball of radius 19 around (24, 20, 22) at `level`: 27 chunks, the middle one (1, 1, 1) solid,
/// painted so that the solid chunk and chunks of lists hold runs of materials.
fn ball(level: Level) -> Volume {
    let mut v = Volume::with_level(level);
    v.add(&Sphere::new(DVec3::new(24.0, 20.0, 22.0), 19.0).unwrap()).unwrap();
    v.paint(&Sphere::new(DVec3::new(30.0, 24.0, 26.0), 7.0).unwrap(), 2).unwrap();
    v.paint(&Cuboid::new(DVec3::new(8.0, 20.0, 22.0), DVec3::splat(4.0)).unwrap(), 1).unwrap();
    assert_eq!(v.chunk(SOLID_KEY), Some(&Chunk::Solid), "the ball's middle chunk is solid");
    assert!(
        matches!(v.chunk_materials(SOLID_KEY), Some(strata_volume::ChunkMaterials::Runs(_))),
        "the solid chunk holds runs of materials"
    );
    v
}

const SOLID_KEY: ChunkKey = ChunkKey::new(1, 1, 1);

fn scene_of(volume: Volume) -> Scene {
    let mut s = Scene::default();
    s.layers[0].volume = volume;
    s
}

fn key_text(k: ChunkKey) -> String {
    format!("({}, {}, {})", k.0.x, k.0.y, k.0.z)
}

/// Every stored chunk, sorted by key.
fn sorted_chunks(v: &Volume) -> Vec<(ChunkKey, Chunk)> {
    let mut c: Vec<(ChunkKey, Chunk)> = v.chunks().map(|(k, c)| (k, c.clone())).collect();
    c.sort_by_key(|(k, _)| k.0.to_array());
    c
}

/// Runs every query over the volume's stored box (none may panic), checks the invariants and
/// that a save and a reload give the scene back with nothing to repair.
fn check_loaded(scene: &Scene, what: &str) {
    for l in &scene.layers {
        let v = &l.volume;
        v.check_invariants().unwrap_or_else(|e| panic!("{what}: a loaded volume is consistent: {e}"));
        let Some((lo, hi)) = v.chunk_bounds_grid() else { continue };
        let per_unit = v.level().nodes_per_unit() as i64;
        let (lo_n, hi_n) = (lo.as_i64vec3() * per_unit, hi.as_i64vec3() * per_unit);
        let mut inside = 0u64;
        for z in (lo_n.z - 1..=hi_n.z).step_by(3) {
            for y in (lo_n.y - 1..=hi_n.y).step_by(5) {
                for x in lo_n.x - 1..=hi_n.x {
                    let node = glam::I64Vec3::new(x, y, z);
                    if v.node_inside(node) {
                        inside += 1;
                        assert!(v.node_material_at(node).is_some(), "{what}: an inside node {node} has a material");
                    }
                }
            }
        }
        assert!(inside > 0, "{what}: the solid is still there");
        for i in 0..2000 {
            let f = |k: u32| ((i * k) % 997) as f64 / 997.0;
            let _ = v.is_inside(lo - 1.0 + (hi - lo + 2.0) * DVec3::new(f(7), f(13), f(31)));
            let _ = v.material_near(lo + (hi - lo) * DVec3::new(f(11), f(17), f(5)));
        }
        let centre = (lo + hi) / 2.0;
        for dir in [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y, DVec3::Z, DVec3::NEG_Z] {
            let _ = v.raycast(centre - dir * 100.0 + DVec3::new(0.3, 0.2, 0.1), dir, 200.0);
        }
        let _ = v.crossing_stats();
        for axis in strata_volume::Axis::ALL {
            assert!(v.measured_volume(axis) > 0.0, "{what}: a volume is measured");
        }
    }
    // Tests run in parallel: one file per check.
    static SAVES: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let path = temp(&format!("crafted-{}.strata", SAVES.fetch_add(1, std::sync::atomic::Ordering::Relaxed)));
    assert!(save(scene, &path).unwrap().is_clean(), "{what}: a repaired scene saves as it is");
    let back = load(&path).unwrap();
    assert!(back.report.is_clean(), "{what}: what was saved needs no repair: {}", back.report);
    assert!(back.scene == *scene, "{what}: the repaired scene round-trips");
    std::fs::remove_file(&path).unwrap();
}

/// One volume at `level` holding exactly `chunks`, each with its materials.
fn assemble(level: Level, chunks: impl IntoIterator<Item = (ChunkKey, Chunk, Option<ChunkMaterials>)>) -> Volume {
    let mut materials = Vec::new();
    let chunks: Vec<(ChunkKey, Chunk)> = chunks
        .into_iter()
        .map(|(k, c, m)| {
            materials.push((k, m));
            (k, c)
        })
        .collect();
    let mut v = Volume::from_chunks(level, 1.0, chunks).unwrap();
    for (k, m) in materials {
        v.set_chunk_materials(k, m);
    }
    v
}

#[test]
fn every_layer_level_against_every_chunk_level_loads_without_a_panicking_query() {
    let sources: Vec<Volume> = (0..=strata_volume::coords::MAX_LEVEL).map(|k| ball(Level::new(k).unwrap())).collect();
    let mut keys: Vec<ChunkKey> = sources.iter().flat_map(|v| v.chunks().map(|(k, _)| k)).collect();
    keys.sort_by_key(|k| k.0.to_array());
    keys.dedup();
    // Which source each chunk comes from: all from one level, or (`None`) a mix of all three.
    let configs = (0..sources.len()).map(Some).chain([None]);
    for one_level in configs {
        let config = match one_level {
            Some(c) => format!("every chunk at level {c}"),
            None => "chunks at levels 0, 1 and 2".into(),
        };
        let source_of = |k: ChunkKey| one_level.unwrap_or((k.0.x + k.0.y + k.0.z).rem_euclid(3) as usize);
        let crafted: Vec<(ChunkKey, Chunk, Option<ChunkMaterials>)> = keys
            .iter()
            .filter_map(|&k| {
                let s = &sources[source_of(k)];
                s.chunk(k).map(|c| (k, c.clone(), s.chunk_materials(k).cloned()))
            })
            .collect();
        let solid_source = source_of(SOLID_KEY) as u8;
        for stored in [0u8, 1, 2, 3, 200] {
            let what = format!("{config}, layer level {stored}");
            let level = i8::try_from(stored).ok().and_then(Level::new).unwrap_or(Level::BASE);
            let crafted_volume = assemble(level, crafted.iter().cloned());
            let mut record = file::scene_record(&scene_of(crafted_volume.clone()), true).unwrap();
            record.layers[0].level = stored;
            let loaded = decode(&file::encode_record(&record).unwrap()).unwrap_or_else(|e| panic!("{what}: {e}"));
            // What must be repaired: a level that does not exist, and the solid chunk's runs of
            // materials, which are per node of the layer's level, where they were written for a
            // finer one and reach past the chunk's nodes. (Runs written for a coarser level fit
            // a finer one's node count: nothing in the file tells them apart, and they are kept.)
            let mut expected = 0;
            if stored > strata_volume::coords::MAX_LEVEL as u8 {
                expected += 1;
                assert!(
                    loaded
                        .report
                        .repairs
                        .iter()
                        .any(|r| r.contains(&format!("resolution level {stored} does not exist"))),
                    "{what}: {}",
                    loaded.report
                );
            }
            if solid_source as i8 > level.get() {
                expected += 1;
                assert!(
                    loaded
                        .report
                        .repairs
                        .iter()
                        .any(|r| r.contains(&format!("the materials of chunk {} do not fit it", key_text(SOLID_KEY)))
                            && r.contains("material 0")),
                    "{what}: {}",
                    loaded.report
                );
            }
            assert_eq!(loaded.report.repairs.len(), expected, "{what}: nothing else is repaired: {}", loaded.report);
            let v = &loaded.scene.layers[0].volume;
            assert_eq!(v.level(), level, "{what}");
            assert!(sorted_chunks(v) == sorted_chunks(&crafted_volume), "{what}: every chunk is kept as it was");
            // Every node of a chunk's own level reads as the ball of that level says.
            let n = level.cells() as i64;
            for z in (-1..3 * n + 1).step_by(2) {
                for y in (-1..3 * n + 1).step_by(3) {
                    for x in -1..3 * n + 1 {
                        let node = glam::I64Vec3::new(x, y, z);
                        let key = ChunkKey(node.div_euclid(glam::I64Vec3::splat(n)).as_ivec3());
                        let got = v.node_inside(node);
                        let want = match v.stored_level(key) {
                            None => v.chunk(key).is_some(),
                            Some(c) if c >= level => {
                                sources[c.get() as usize].node_inside(node * (1 << (c.get() - level.get())))
                            }
                            Some(c) => {
                                let f = 1 << (level.get() - c.get());
                                if node % f != glam::I64Vec3::ZERO {
                                    continue;
                                }
                                sources[c.get() as usize].node_inside(node / f)
                            }
                        };
                        assert_eq!(got, want, "{what}: node {node}");
                    }
                }
            }
            check_loaded(&loaded.scene, &what);
        }
    }
}

#[test]
fn a_chunk_whose_own_level_is_wrong_or_out_of_range_is_dropped_and_named() {
    for true_level in [0u8, 2] {
        let s = scene_of(ball(Level::new(true_level as i8).unwrap()));
        let record = file::scene_record(&s, true).unwrap();
        let at = record.layers[0].lists.iter().position(|c| c.key == ChunkKey::new(0, 1, 1)).expect("a chunk of lists");
        for wrong in [0u8, 1, 2, 3, 255].into_iter().filter(|&w| w != true_level) {
            let what = format!("a level-{true_level} chunk labelled level {wrong}");
            let mut record = file::scene_record(&s, true).unwrap();
            let c = &mut record.layers[0].lists[at];
            let mut bytes = std::mem::take(&mut c.bytes);
            assert_eq!(bytes[0], true_level, "a chunk's bytes begin with its level");
            bytes[0] = wrong;
            *c = file::ChunkRecord::new(c.key, bytes);
            let loaded = decode(&file::encode_record(&record).unwrap()).unwrap_or_else(|e| panic!("{what}: {e}"));
            let r = &loaded.report;
            assert!(
                r.repairs.iter().any(|r| r.contains("chunk (0, 1, 1) does not decode") && r.contains("dropped")),
                "{what}: {r}"
            );
            assert!(r.repairs.iter().any(|r| r.contains("rebuilt")), "{what}: the hole it leaves is closed: {r}");
            assert!(loaded.scene.layers[0].volume.chunk_count() >= 26, "{what}: the other chunks are kept");
            check_loaded(&loaded.scene, &what);
        }
    }
}

/// The postcard form of `strata_volume::ChunkLists`, for a chunk its own type cannot hold.
#[derive(serde::Serialize)]
struct RawChunkLists {
    level: u8,
    corner: bool,
    family_start: [u32; 2],
    nonempty: Vec<u64>,
    positions: Vec<u16>,
    normals: Vec<u16>,
}

/// The kinds of entry a file can give one chunk key.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    /// Lists without a crossing: an empty chunk written as lists (refused by the chunk's decoder).
    Empty,
    Solid,
    /// The chunk's own lists.
    Lists,
    /// Another chunk's lists.
    Other,
}

#[test]
fn every_pair_of_chunk_kinds_for_one_key_is_resolved_and_what_was_dropped_is_named() {
    use Kind::*;
    let s = scene_of(ball(Level::BASE));
    let key = ChunkKey::new(0, 1, 1);
    let lists_of = |k: ChunkKey| match s.layers[0].volume.chunk(k) {
        Some(Chunk::Lists(l)) => l.clone(),
        other => panic!("chunk {k:?} holds lists, not {other:?}"),
    };
    let (own, other) = (lists_of(key), lists_of(ChunkKey::new(2, 1, 1)));
    let empty = postcard::to_allocvec(&RawChunkLists {
        level: 0,
        corner: false,
        family_start: [0, 0],
        nonempty: vec![0; 12],
        positions: Vec::new(),
        normals: Vec::new(),
    })
    .unwrap();
    let kinds = [Empty, Solid, Lists, Other];
    for first in kinds {
        for second in kinds {
            let what = format!("chunk {} stored as {first:?} and as {second:?}", key_text(key));
            let mut record = file::scene_record(&s, true).unwrap();
            let layer = &mut record.layers[0];
            layer.lists.retain(|c| c.key != key);
            layer.materials.retain(|c| c.key != key);
            for kind in [first, second] {
                match kind {
                    Empty => layer.lists.push(file::ChunkRecord::new(key, empty.clone())),
                    Solid => layer.solid.push(key),
                    Lists => layer.lists.push(file::ChunkRecord::new(key, postcard::to_allocvec(&own).unwrap())),
                    Other => layer.lists.push(file::ChunkRecord::new(key, postcard::to_allocvec(&other).unwrap())),
                }
            }
            let loaded = decode(&file::encode_record(&record).unwrap()).unwrap_or_else(|e| panic!("{what}: {e}"));
            let r = &loaded.report;
            let named = |part: &str| r.repairs.iter().any(|s| s.contains(&key_text(key)) && s.contains(part));
            let empties = [first, second].iter().filter(|&&k| k == Empty).count();
            assert_eq!(
                r.repairs.iter().filter(|s| s.contains(&format!("chunk {} does not decode", key_text(key)))).count(),
                empties,
                "{what}: each empty entry is dropped and named: {r}"
            );
            // The entries the chunk decoder accepts, solid entries first (as the file lists them).
            let mut decoded: Vec<Kind> = [first, second].into_iter().filter(|&k| k == Solid).collect();
            decoded.extend([first, second].into_iter().filter(|&k| k == Lists || k == Other));
            let kept = decoded.iter().copied().find(|&k| k != Solid).or(decoded.first().copied());
            if decoded.len() == 2 {
                assert!(named("is stored 2 times"), "{what}: the duplicate is reported: {r}");
                let solid_dropped = decoded.contains(&Solid) && kept != Some(Solid) || decoded == [Solid, Solid];
                assert_eq!(named("1 solid entry"), solid_dropped, "{what}: a dropped solid entry is named: {r}");
                assert_eq!(
                    named("identical copy"),
                    decoded == [Lists, Lists] || decoded == [Other, Other],
                    "{what}: {r}"
                );
                assert_eq!(
                    named("different chunk of lists"),
                    matches!(decoded[..], [Lists, Other] | [Other, Lists]),
                    "{what}: {r}"
                );
            } else {
                assert!(!named("is stored"), "{what}: one entry is no duplicate: {r}");
            }
            let v = &loaded.scene.layers[0].volume;
            if kept == Some(Lists) {
                assert_eq!(v.chunk(key), Some(&Chunk::Lists(own.clone())), "{what}: the chunk's own lists are kept");
                assert_eq!(r.repairs.len(), empties + (decoded.len() == 2) as usize, "{what}: nothing else: {r}");
            } else {
                assert!(r.repairs.iter().any(|s| s.contains("rebuilt")), "{what}: the misfit is repaired: {r}");
            }
            check_loaded(&loaded.scene, &what);
        }
    }
}

#[test]
fn materials_stored_twice_or_for_an_empty_chunk_are_dropped_and_named() {
    let s = scene_of(ball(Level::BASE));
    let mut record = file::scene_record(&s, true).unwrap();
    let layer = &mut record.layers[0];
    let painted = layer.materials.iter().position(|c| c.key == SOLID_KEY).unwrap();
    // A second, different copy of the solid chunk's materials, and materials of a chunk that is empty.
    let mut twice = postcard::from_bytes::<ChunkMaterials>(&layer.materials[painted].bytes).unwrap();
    assert_ne!(twice, ChunkMaterials::Uniform(3));
    twice = ChunkMaterials::Uniform(3);
    layer.materials.push(file::ChunkRecord::new(SOLID_KEY, postcard::to_allocvec(&twice).unwrap()));
    let far = ChunkKey::new(9, 9, 9);
    layer.materials.push(file::ChunkRecord::new(far, postcard::to_allocvec(&ChunkMaterials::Uniform(2)).unwrap()));
    let loaded = decode(&file::encode_record(&record).unwrap()).unwrap();
    let r = &loaded.report;
    assert_eq!(r.repairs.len(), 2, "{r}");
    assert!(r.repairs[0].contains("chunk (1, 1, 1) are stored more than once"), "{r}");
    assert!(r.repairs[1].contains("chunk (9, 9, 9), which is empty"), "{r}");
    let v = &loaded.scene.layers[0].volume;
    assert_eq!(v.chunk_materials(SOLID_KEY), s.layers[0].volume.chunk_materials(SOLID_KEY), "the first copy is kept");
    assert_eq!(v.chunk_materials(far), None);
    assert!(loaded.scene == s, "nothing else changed");
    check_loaded(&loaded.scene, "materials twice");
}

#[test]
fn a_version_2_file_with_a_key_both_solid_and_lists_opens_and_says_what_was_dropped() {
    let s = scene_of(ball(Level::BASE));
    let payload = file::encode_version_2_payload(&s).unwrap();
    let mut v2: file::SceneV2 = postcard::from_bytes(&payload).unwrap();
    let key = ChunkKey::new(0, 1, 1);
    let chunks = &mut v2.layers[0].volume.chunks;
    assert!(chunks.lists.iter().any(|(k, _)| *k == key));
    // The key in the set of solid chunks, and a solid chunk among the chunks of lists.
    chunks.solid.push(key);
    chunks.lists.push((SOLID_KEY, Chunk::Solid));
    let payload = postcard::to_allocvec(&v2).unwrap();
    let mut bytes = file::MAGIC.to_vec();
    bytes.extend_from_slice(&2u32.to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&crc32fast_hash(&payload).to_le_bytes());
    bytes.extend_from_slice(&payload);
    let loaded = decode(&bytes).expect("a duplicate no longer fails the whole file");
    let r = &loaded.report;
    assert_eq!(r.repairs.len(), 2, "{r}");
    assert!(
        r.repairs.iter().any(|s| s.contains("chunk (0, 1, 1) is stored 2 times") && s.contains("1 solid entry")),
        "{r}"
    );
    assert!(
        r.repairs
            .iter()
            .any(|s| s.contains("chunk (1, 1, 1) is stored 2 times") && s.contains("one solid entry was kept")),
        "{r}"
    );
    assert!(
        sorted_chunks(&loaded.scene.layers[0].volume) == sorted_chunks(&s.layers[0].volume),
        "every chunk as it was"
    );
    check_loaded(&loaded.scene, "version 2 duplicates");
}

#[test]
fn a_repair_keeps_the_chunks_stored_at_other_levels_than_the_layers() {
    let sources: Vec<Volume> = (0..=strata_volume::coords::MAX_LEVEL).map(|k| ball(Level::new(k).unwrap())).collect();
    let damaged = ChunkKey::new(0, 1, 0);
    let near = |k: ChunkKey| (k.0 - damaged.0).abs().max_element() <= 1;
    for (stored, source) in [(0i8, 2usize), (2, 0), (1, 0), (1, 2)] {
        let what = format!("chunks at level {source} in a layer of level {stored}");
        let level = Level::new(stored).unwrap();
        let original = &sources[source];
        let crafted = assemble(level, original.chunks().map(|(k, c)| (k, c.clone(), None)));
        let mut record = file::scene_record(&scene_of(crafted), true).unwrap();
        let at = record.layers[0].lists.iter().position(|c| c.key == damaged).unwrap();
        record.layers[0].lists[at].crc ^= 1;
        let loaded = decode(&file::encode_record(&record).unwrap()).unwrap_or_else(|e| panic!("{what}: {e}"));
        let r = &loaded.report;
        assert!(r.repairs[0].contains("chunk (0, 1, 0) failed its checksum"), "{what}: {r}");
        assert!(
            r.repairs
                .iter()
                .any(|s| s.contains("rebuilt") && s.contains(&format!("brought to the layer's level {stored}"))),
            "{what}: {r}"
        );
        assert!(!r.to_string().contains("dropped,"), "{what}: no chunk is dropped for its level: {r}");
        let v = &loaded.scene.layers[0].volume;
        assert!(v.chunk_count() >= original.chunk_count() - 1, "{what}: the chunks are kept: {r}");
        for (k, c) in original.chunks() {
            if near(k) {
                continue;
            }
            match c {
                Chunk::Solid => assert_eq!(v.chunk(k), Some(&Chunk::Solid), "{what}: chunk {k:?}"),
                Chunk::Lists(l) => {
                    assert_eq!(v.stored_level(k), Some(l.level()), "{what}: chunk {k:?} keeps its level");
                    if l.level() < level {
                        assert_eq!(v.chunk(k), Some(c), "{what}: a coarser chunk comes back bit for bit");
                    }
                }
            }
        }
        // Away from the damage, every node of the layer's level reads as before.
        let n = level.cells() as i64;
        let coarse = Level::new(stored.min(source as i8)).unwrap();
        let f = 1i64 << (stored - coarse.get());
        for z in (0..3 * n).step_by(f as usize) {
            for y in (0..3 * n).step_by(f as usize) {
                for x in (0..3 * n).step_by(f as usize) {
                    let node = glam::I64Vec3::new(x, y, z);
                    if near(ChunkKey(node.div_euclid(glam::I64Vec3::splat(n)).as_ivec3())) {
                        continue;
                    }
                    let at_source = node * (1 << source) / (1 << stored);
                    assert_eq!(v.node_inside(node), original.node_inside(at_source), "{what}: node {node}");
                }
            }
        }
        check_loaded(&loaded.scene, &what);
    }
}
