//! Meshes read back: our own exports round-trip through every format, the shipped bunny loads,
//! and malformed files are errors.

use std::path::{Path, PathBuf};

use glam::DVec3;
use strata_mesh::export::save_mesh;
use strata_mesh::import::{ImportError, load_mesh};
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
    let mesh = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    for ext in ["obj", "stl", "ply", "glb"] {
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

/// A binary STL of `tris` (each three corners), with `header` as its first bytes and `count`
/// declared.
fn binary_stl(header: &[u8], count: u32, tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut b = vec![b' '; 80];
    b[..header.len()].copy_from_slice(header);
    b.extend_from_slice(&count.to_le_bytes());
    for t in tris {
        b.extend_from_slice(&[0u8; 12]);
        for c in t {
            for v in c {
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 2]);
    }
    b
}

fn tetra() -> Vec<[[f32; 3]; 3]> {
    let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    vec![[p[0], p[2], p[1]], [p[0], p[1], p[3]], [p[0], p[3], p[2]], [p[1], p[2], p[3]]]
}

#[test]
fn binary_stl_files_whose_header_starts_with_solid_are_read_as_binary() {
    let path = temp("cad.stl");
    std::fs::write(&path, binary_stl(b"solid exported by a CAD tool", 4, &tetra())).unwrap();
    let m = load_mesh(&path).unwrap();
    assert_eq!((m.vertices.len(), m.triangles.len()), (4, 4), "shared corners are welded");
    let brush = MeshBrush::new(&m.vertices, &m.triangles, MeshRule::EvenOdd).unwrap();
    assert!(brush.is_closed());
}

#[test]
fn a_binary_stl_whose_count_disagrees_with_its_size_is_an_error() {
    for declared in [3, 5] {
        let path = temp(&format!("count{declared}.stl"));
        std::fs::write(&path, binary_stl(b"binary", declared, &tetra())).unwrap();
        let err = load_mesh(&path).unwrap_err().to_string();
        assert!(err.contains(&format!("declares {declared} triangles")) && err.contains("(4 triangles)"), "{err}");
    }
    let short = temp("short.stl");
    std::fs::write(&short, b"\x00\x01").unwrap();
    assert!(load_mesh(&short).is_err());
}

#[cfg(unix)]
#[test]
fn mesh_files_that_are_not_regular_files_are_refused_before_reading() {
    let link = temp("zero.stl");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    let err = load_mesh(&link).unwrap_err().to_string();
    assert!(err.contains("not a regular file"), "{err}");
}

#[test]
fn gltf_nodes_are_placed_by_their_transforms_and_bad_gltf_is_an_error() {
    // A glTF with one triangle in a buffer embedded as a data URI, used by two nodes: one
    // moved by +10 along x, one mirrored (scale −1 along x) under a parent moved by +5 along y.
    let floats: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    let b64 = {
        const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for c in bytes.chunks(3) {
            let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
            for k in 0..4 {
                if k <= c.len() {
                    out.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
                } else {
                    out.push('=');
                }
            }
        }
        out
    };
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
        "nodes":[{{"mesh":0,"translation":[10,0,0]}},{{"translation":[0,5,0],"children":[2]}},{{"mesh":0,"scale":[-1,1,1]}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}}],
        "buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,{b64}"}}]}}"#
    );
    let path = temp("two.gltf");
    std::fs::write(&path, json).unwrap();
    let m = load_mesh(&path).unwrap();
    assert_eq!(m.triangles.len(), 2);
    let (lo, hi) = m.bounds().unwrap();
    assert_eq!((lo, hi), (DVec3::new(-1.0, 0.0, 0.0), DVec3::new(11.0, 6.0, 0.0)));
    // The mirrored copy's faces are flipped back: both triangles face +z.
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.vertices[i as usize]);
        assert!((b - a).cross(c - a).z > 0.0, "{t:?}");
    }
    // A buffer file that is missing, and garbage, are errors.
    let missing = temp("missing-buffer.gltf");
    std::fs::write(&missing, r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":36,"uri":"nowhere.bin"}]}"#)
        .unwrap();
    assert!(load_mesh(&missing).is_err());
    let garbage = temp("garbage.glb");
    std::fs::write(&garbage, b"glTF\x02\x00\x00\x00nonsense").unwrap();
    assert!(load_mesh(&garbage).is_err());
}
