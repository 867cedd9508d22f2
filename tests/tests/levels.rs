//! Resolution levels end to end: raising and lowering chunks, level-of-detail blocks, and the
//! crack patching that makes chunks of different levels mesh into one closed surface.

use glam::{DVec3, IVec3};
use strata_mesh::{checks, mesh_volume};
use strata_volume::brush::Sphere;
use strata_volume::{ChunkKey, Level, Volume};

fn level(k: u8) -> Level {
    Level::new(k).unwrap()
}

fn list_keys(v: &Volume) -> Vec<ChunkKey> {
    let mut keys: Vec<ChunkKey> = v.chunks().filter(|(k, _)| v.stored_level(*k).is_some()).map(|(k, _)| k).collect();
    keys.sort();
    keys
}

fn closed(v: &Volume) -> strata_mesh::Mesh {
    let mesh = mesh_volume(v);
    if let Err(e) = checks::check_closed_manifold(&mesh) {
        panic!("mesh of {} triangles not closed: {e}", mesh.indices.len() / 3);
    }
    mesh
}

#[test]
fn one_raised_chunk_in_a_sphere_meshes_closed() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
    let before = v.clone();
    let key = ChunkKey::new(0, 0, 0);
    let r = v.set_chunk_level(key, level(1));
    assert_eq!(v.stored_level(key), Some(level(1)));
    v.check_invariants().unwrap();
    closed(&v);
    let _ = v.set_chunk_level(key, level(0));
    assert_eq!(v, before, "raise then lower gives back the lists");
    v.restore(r.undo);
}

#[test]
fn raise_then_lower_is_the_identity() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
    let before = v.clone();
    for k in list_keys(&v) {
        let _ = v.set_chunk_level(k, level(2));
        v.check_invariants().unwrap();
    }
    for k in list_keys(&v) {
        let _ = v.set_chunk_level(k, level(0));
    }
    assert_eq!(v, before);
}

#[test]
fn every_pair_of_levels_meshes_closed() {
    let _ = IVec3::ZERO;
    for (a, b) in [(0, 1), (1, 0), (0, 2), (2, 0), (1, 2), (2, 1)] {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
        for k in list_keys(&v) {
            let l = if k.0.x == 0 { a } else { b };
            let _ = v.set_chunk_level(k, level(l));
        }
        v.check_invariants().unwrap();
        closed(&v);
    }
}

#[test]
fn seams_are_patched_and_split() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
    let _ = v.set_chunk_level(ChunkKey::new(0, 0, 0), level(2));
    let (mut seams, mut patched) = (0, 0);
    for k in list_keys(&v) {
        let b = v.extract_block(k);
        seams += b.seams().len();
        patched += b.patched();
        assert_eq!(b.repaired(), 0);
    }
    eprintln!("seams {seams}, patched {patched}");
    assert!(seams > 0);
    let mesh = closed(&v);
    eprintln!("triangles {}", mesh.indices.len() / 3);
}
