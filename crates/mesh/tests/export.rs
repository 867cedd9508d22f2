//! Exports re-read with independent reader crates give back the same counts and bounds.

use std::path::PathBuf;

use glam::DVec3;
use strata_mesh::Mesh;
use strata_mesh::export::{MeshFormat, save_mesh};
use strata_tests::files::race_writers_with_reader;
use strata_volume::Volume;
use strata_volume::brush::{Sphere, Torus};

fn scene() -> Mesh {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(5.0, 6.0, 7.0), 9.0).unwrap()).unwrap();
    v.add(&Torus::new(DVec3::new(5.0, 6.0, 7.0), DVec3::Y, 12.0, 3.0).unwrap()).unwrap();
    strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default()).expect("marching cubes meshes every volume")
}

fn bounds(points: impl Iterator<Item = [f32; 3]>) -> ([f32; 3], [f32; 3]) {
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-export-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn glb_reads_back_with_the_gltf_crate() {
    let mesh = scene();
    let path = temp("scene.glb");
    save_mesh(&mesh, &path).unwrap();
    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    assert_eq!(positions, mesh.positions);
    assert_eq!(indices, mesh.indices);
    assert_eq!(reader.read_normals().unwrap().count(), mesh.vertex_count());
    // Accessor min/max are required for POSITION and must match the data.
    let acc = prim.get(&gltf::Semantic::Positions).unwrap();
    let (lo, hi) = bounds(mesh.positions.iter().copied());
    assert_eq!(acc.min().unwrap(), serde_json::json!(lo));
    assert_eq!(acc.max().unwrap(), serde_json::json!(hi));
    assert_eq!(std::fs::metadata(&path).unwrap().len() % 4, 0, "GLB length is 4-byte aligned");
}

#[test]
fn obj_reads_back_with_tobj() {
    let mesh = scene();
    let path = temp("scene.obj");
    save_mesh(&mesh, &path).unwrap();
    let (models, _) = tobj::load_obj(&path, &tobj::LoadOptions { single_index: true, ..Default::default() }).unwrap();
    let m = &models[0].mesh;
    assert_eq!(m.indices.len(), mesh.indices.len());
    assert_eq!(m.positions.len(), mesh.positions.len() * 3);
    let read = bounds(m.positions.chunks(3).map(|p| [p[0], p[1], p[2]]));
    assert_eq!(read, bounds(mesh.positions.iter().copied()));
}

#[test]
fn stl_reads_back_with_stl_io() {
    let mesh = scene();
    let path = temp("scene.stl");
    save_mesh(&mesh, &path).unwrap();
    let stl = stl_io::read_stl(&mut std::fs::File::open(&path).unwrap()).unwrap();
    assert_eq!(stl.faces.len(), mesh.triangle_count());
    let read = bounds(stl.vertices.iter().map(|v| [v[0], v[1], v[2]]));
    assert_eq!(read, bounds(mesh.positions.iter().copied()));
}

#[test]
fn ply_reads_back_with_ply_rs() {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let mesh = scene();
    let path = temp("scene.ply");
    save_mesh(&mesh, &path).unwrap();
    let mut f = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
    let ply = Parser::<DefaultElement>::new().read_ply(&mut f).unwrap();
    let verts = &ply.payload["vertex"];
    let faces = &ply.payload["face"];
    assert_eq!(verts.len(), mesh.vertex_count());
    assert_eq!(faces.len(), mesh.triangle_count());
    let get = |e: &DefaultElement, k: &str| match e[k] {
        Property::Float(v) => v,
        _ => panic!("float property"),
    };
    let read = bounds(verts.iter().map(|e| [get(e, "x"), get(e, "y"), get(e, "z")]));
    assert_eq!(read, bounds(mesh.positions.iter().copied()));
}

#[test]
fn bad_paths_and_meshes_are_errors_and_keep_the_old_file() {
    let mesh = scene();
    assert!(save_mesh(&mesh, &temp("scene.xyz")).is_err());
    let path = temp("keep.obj");
    save_mesh(&mesh, &path).unwrap();
    let before = std::fs::read(&path).unwrap();
    let mut broken = mesh.clone();
    broken.indices.push(u32::MAX);
    broken.indices.extend([0, 1]);
    assert!(save_mesh(&broken, &path).is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before, "a failed save leaves the old file");
    assert_eq!(MeshFormat::from_path(std::path::Path::new("a.GLB")), Some(MeshFormat::Glb));
    assert!(save_mesh(&Mesh::default(), &temp("empty.glb")).is_err(), "an empty mesh is refused");
    assert!(!temp("empty.glb").exists());
}

/// Two threads export different meshes to one path 100 times each while a third reads it: every
/// read is one whole mesh, never a mix or a partial file, and no temporary file is left.
#[test]
fn two_threads_exporting_to_one_path_never_leave_a_corrupt_or_partial_file() {
    let path = temp("race.stl");
    let dir = path.parent().unwrap().to_path_buf();
    let a = scene();
    let b = {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(1.0, 2.0, 3.0), 5.0).unwrap()).unwrap();
        strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default())
            .expect("marching cubes meshes every volume")
    };
    assert_ne!(a.triangle_count(), b.triangle_count());
    save_mesh(&a, &path).unwrap();
    let counts = [a.triangle_count(), b.triangle_count()];
    let read = |p: &std::path::Path| -> Option<usize> {
        let bytes = std::fs::read(p).ok()?;
        let stl = stl_io::read_stl(&mut std::io::Cursor::new(bytes)).ok()?;
        Some(stl.faces.len())
    };
    let writer = |mesh| -> Box<dyn FnOnce() + Send + '_> {
        let path = &path;
        Box::new(move || {
            for _ in 0..100 {
                save_mesh(mesh, path).unwrap();
            }
        })
    };
    let (reads, bad) =
        race_writers_with_reader(vec![writer(&a), writer(&b)], || read(&path).is_some_and(|n| counts.contains(&n)));
    assert_eq!(bad, 0, "{bad} corrupt or partial reads of {}", reads + bad);
    assert!(counts.contains(&read(&path).expect("the last export reads")));
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("race.stl."))
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
}
