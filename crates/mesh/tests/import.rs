//! Meshes read back: our own exports round-trip through every format, the shipped bunny loads,
//! and malformed files are errors.

use std::path::{Path, PathBuf};

use glam::DVec3;
use strata_mesh::export::save_mesh;
use strata_mesh::import::{ImportError, load_mesh};
use strata_mesh::mesh_volume;
use strata_volume::Volume;
use strata_volume::brush::{MeshBrush, MeshRule, Sphere};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-import-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn bunny_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply")
}

#[test]
fn exports_read_back_in_every_format() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(5.0, 6.0, 7.0), 9.0).unwrap()).unwrap();
    let mesh = mesh_volume(&v);
    for ext in ["obj", "stl", "ply"] {
        let path = temp(&format!("sphere.{ext}"));
        save_mesh(&mesh, &path).unwrap();
        let back = load_mesh(&path).unwrap();
        assert_eq!(back.triangles.len(), mesh.triangle_count(), "{ext}");
        // STL stores every triangle's corners; the others keep the shared vertices.
        if ext != "stl" {
            assert_eq!(back.vertices.len(), mesh.vertex_count(), "{ext}");
        }
        let (lo, hi) = back.bounds().unwrap();
        assert!((lo - DVec3::new(-4.0, -3.0, -2.0)).abs().max_element() < 1.0, "{ext}: {lo}");
        assert!((hi - DVec3::new(14.0, 15.0, 16.0)).abs().max_element() < 1.0, "{ext}: {hi}");
    }
}

#[test]
fn the_shipped_bunny_loads_and_is_a_closed_brush() {
    let bunny = load_mesh(&bunny_path()).unwrap();
    assert_eq!((bunny.vertices.len(), bunny.triangles.len()), (1839, 3674));
    let brush = MeshBrush::new(&bunny.vertices, &bunny.triangles, MeshRule::EvenOdd).unwrap();
    assert!(brush.is_closed());
}

#[test]
fn malformed_files_are_errors() {
    let garbage = temp("garbage.ply");
    std::fs::write(&garbage, b"ply\nformat nonsense\n\x00\x01").unwrap();
    assert!(matches!(load_mesh(&garbage), Err(ImportError::Parse { .. })));
    // A truncated binary PLY.
    let bytes = std::fs::read(bunny_path()).unwrap();
    let cut = temp("cut.ply");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    assert!(load_mesh(&cut).is_err());
    let bad_index = temp("bad.obj");
    std::fs::write(&bad_index, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    assert!(load_mesh(&bad_index).is_err());
    let nan = temp("nan.obj");
    std::fs::write(&nan, "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert!(load_mesh(&nan).is_err());
    let empty = temp("empty.obj");
    std::fs::write(&empty, "v 0 0 0\n").unwrap();
    assert!(matches!(load_mesh(&empty), Err(ImportError::Invalid { .. })));
    assert!(matches!(load_mesh(&temp("x.fbx")), Err(ImportError::UnknownFormat(_))));
    assert!(load_mesh(&temp("missing.stl")).is_err());
}
