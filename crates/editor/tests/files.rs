//! Scene files: round trips, corrupted and truncated files, interrupted saves, and random
//! byte mutations (`PROPTEST_CASES=100000 cargo test --release -p strata-editor --test files`
//! for the long run; CI runs the default 512 cases).

use std::path::PathBuf;

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use strata_editor::file::{self, SceneFileError, decode, encode, load, save, write_atomically};
use strata_editor::{Layer, LayerTransform, Material, Scene};
use strata_volume::brush::{Cuboid, Sphere, Torus};

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
    b.material = 1;
    b.locked = true;
    let mut c = Layer::new("hidden, empty");
    c.visible = false;
    s.layers.push(b);
    s.layers.push(c);
    s.materials.push(Material { name: "Moss".into(), color: [0.2, 0.5, 0.1] });
    s.view.yaw = -1.2;
    s
}

#[test]
fn scenes_with_several_layers_round_trip() {
    let s = scene();
    let path = temp("round.strata");
    save(&s, &path).unwrap();
    assert_eq!(load(&path).unwrap(), s);
    assert_eq!(decode(&encode(&s).unwrap()).unwrap(), s);
    assert!(!file::temp_path(&path).exists(), "no temporary file is left behind");
}

#[test]
fn corrupted_truncated_and_newer_files_fail_cleanly() {
    let bytes = encode(&scene()).unwrap();
    let mut flipped = bytes.clone();
    let mid = file::HEADER_LEN + (bytes.len() - file::HEADER_LEN) / 2;
    flipped[mid] ^= 0x10;
    assert!(matches!(decode(&flipped), Err(SceneFileError::Checksum)));
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
    assert_eq!(load(&path).unwrap(), old);
    assert!(!file::temp_path(&path).exists());
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
            bytes[8..12].copy_from_slice(&file::VERSION.to_le_bytes());
        }
        if let Ok(s) = decode(&bytes) {
            // Whatever decodes is a valid scene: its volumes pass the invariant checker.
            for l in &s.layers {
                prop_assert!(l.volume.check_invariants().is_ok());
            }
        }
    }
}
