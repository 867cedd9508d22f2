//! Vertex materials from the meshers, and coloured exports re-read by independent crates.

use std::path::PathBuf;

use glam::DVec3;
use strata_mesh::export::{ExportMaterial, save_mesh_with, vertex_color};
use strata_mesh::{DualCache, Mesh, checks};
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::{CsgOp, EditSettings, Volume};

fn with(material: u8) -> EditSettings {
    EditSettings { material, ..Default::default() }
}

/// A slab `z < 10.3` over two chunks along x: material 1 for `x < 16`, material 2 beyond.
fn two_material_slab() -> Volume {
    let mut v = Volume::new();
    v.apply(CsgOp::Add, &Cuboid::new(DVec3::new(16.0, 16.0, 5.15), DVec3::new(14.6, 14.6, 5.15)).unwrap(), &with(2))
        .unwrap();
    v.paint(&Cuboid::new(DVec3::new(8.0, 16.0, 6.0), DVec3::new(8.0, 20.0, 10.0)).unwrap(), 1).unwrap();
    v.check_invariants().unwrap();
    v
}

fn weights_sum_to_one(m: &Mesh) {
    assert_eq!(m.materials.len(), m.vertex_count());
    for vm in &m.materials {
        assert_eq!(vm.weights.iter().map(|&w| w as u32).sum::<u32>(), 255, "{vm:?}");
    }
}

#[test]
fn a_painted_half_space_gives_its_vertices_its_material_alone() {
    let v = two_material_slab();
    for (name, mesh) in [
        (
            "marching cubes",
            strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default())
                .expect("marching cubes meshes every volume"),
        ),
        (
            "dual contouring",
            strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::DualContouring))
                .expect("dual contouring meshes every volume"),
        ),
    ] {
        checks::check_closed_manifold(&mesh).unwrap();
        weights_sum_to_one(&mesh);
        let mut painted = 0;
        for (i, p) in mesh.positions.iter().enumerate() {
            let m = mesh.material(i);
            // On the painted side, a cell or more from the boundary between the materials.
            if p[0] < 14.5 {
                painted += 1;
                assert!(m.weight_of(1) >= 0.99, "{name}: vertex {p:?} has {m:?}");
            } else if p[0] > 17.5 {
                assert!(m.weight_of(2) >= 0.99, "{name}: vertex {p:?} has {m:?}");
            }
        }
        assert!(painted > 100, "{name}: {painted} vertices on the painted side");
    }
}

#[test]
fn dual_vertices_blend_only_the_materials_of_solid_corners() {
    let mut v = Volume::new();
    v.apply(CsgOp::Add, &Sphere::new(DVec3::splat(12.0), 8.0).unwrap(), &with(3)).unwrap();
    v.paint(&Cuboid::new(DVec3::new(6.0, 12.0, 12.0), DVec3::new(6.0, 12.0, 12.0)).unwrap(), 5).unwrap();
    let dc = DualCache::build(&v).welded();
    weights_sum_to_one(&dc);
    // Vertices near the boundary plane x = 12 blend the two; none carries any other material.
    let mut blended = 0;
    for vm in &dc.materials {
        let (a, b) = (vm.weight_of(3), vm.weight_of(5));
        assert!((a + b - 1.0).abs() < 1e-6, "{vm:?}");
        if a > 0.0 && b > 0.0 {
            blended += 1;
        }
    }
    assert!(blended > 0, "cells across the boundary blend both materials");
}

fn palette() -> Vec<ExportMaterial> {
    vec![
        ExportMaterial { name: "Clay".into(), color: [0.5, 0.36, 0.26], roughness: 0.8 },
        ExportMaterial { name: "Moss green".into(), color: [0.1, 0.6, 0.1], roughness: 0.9 },
        ExportMaterial { name: "Sand".into(), color: [0.8, 0.7, 0.4], roughness: 0.7 },
    ]
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-materials-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn a_coloured_glb_passes_the_gltf_crates_checks_and_keeps_its_colours() {
    let mesh = strata_mesh::mesh_volume_with(&two_material_slab(), strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    let path = temp("slab.glb");
    save_mesh_with(&mesh, &path, &palette()).unwrap();
    // `gltf::import` validates the document (accessor types, bounds, required attributes).
    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let names: Vec<String> = doc.materials().map(|m| m.name().unwrap_or_default().to_string()).collect();
    assert_eq!(names, vec!["Moss green".to_string(), "Sand".to_string()], "one glTF material per material used");
    let mut triangles = 0;
    for prim in doc.meshes().next().unwrap().primitives() {
        let acc = prim.get(&gltf::Semantic::Colors(0)).unwrap();
        assert!(acc.normalized(), "COLOR_0 as normalised bytes");
        assert_eq!(acc.data_type(), gltf::accessor::DataType::U8);
        let reader = prim.reader(|b| Some(&buffers[b.index()]));
        let colors: Vec<[u8; 4]> = reader.read_colors(0).unwrap().into_rgba_u8().collect();
        assert_eq!(colors.len(), mesh.vertex_count());
        for (i, c) in colors.iter().enumerate() {
            let want = vertex_color(&mesh, i, &palette()).map(|x| (x * 255.0 + 0.5) as u8);
            assert_eq!(&c[..3], &want[..], "vertex {i}");
        }
        let material = prim.material().index().unwrap();
        let id = if material == 0 { 1 } else { 2 };
        let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        for t in indices.chunks(3) {
            let dominant = t.iter().filter(|&&i| mesh.material(i as usize).dominant() == id).count();
            assert!(dominant >= 2 || mesh.material(t[0] as usize).dominant() == id);
        }
        triangles += indices.len() / 3;
        assert!(prim.material().pbr_metallic_roughness().roughness_factor() > 0.6);
    }
    assert_eq!(triangles, mesh.triangle_count(), "every triangle in one primitive");
}

#[test]
fn obj_with_mtl_and_ply_keep_the_colours() {
    let mesh = strata_mesh::mesh_volume_with(&two_material_slab(), strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    let pal = palette();
    let obj = temp("slab.obj");
    save_mesh_with(&mesh, &obj, &pal).unwrap();
    let (models, materials) =
        tobj::load_obj(&obj, &tobj::LoadOptions { single_index: true, ..Default::default() }).unwrap();
    let materials = materials.unwrap();
    let mut found: Vec<(String, [f32; 3])> =
        materials.iter().map(|m| (m.name.clone(), m.diffuse.unwrap_or_default())).collect();
    found.sort_by(|a, b| a.0.cmp(&b.0));
    assert_eq!(found, vec![("1_Moss_green".into(), pal[1].color), ("2_Sand".into(), pal[2].color)]);
    assert_eq!(models.len(), 2, "one group per material");
    let total: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    assert_eq!(total, mesh.triangle_count());
    for m in &models {
        assert_eq!(m.mesh.vertex_color.len(), m.mesh.positions.len());
        for (p, c) in m.mesh.positions.chunks(3).zip(m.mesh.vertex_color.chunks(3)) {
            let i = mesh.positions.iter().position(|q| q[..] == p[..]).unwrap();
            let want = vertex_color(&mesh, i, &pal);
            assert!((0..3).all(|k| (c[k] - want[k]).abs() < 1e-5), "{c:?} vs {want:?}");
        }
    }

    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let ply = temp("slab.ply");
    save_mesh_with(&mesh, &ply, &pal).unwrap();
    let mut f = std::io::BufReader::new(std::fs::File::open(&ply).unwrap());
    let read = Parser::<DefaultElement>::new().read_ply(&mut f).unwrap();
    let verts = &read.payload["vertex"];
    assert_eq!(verts.len(), mesh.vertex_count());
    let byte = |e: &DefaultElement, k: &str| match e[k] {
        Property::UChar(v) => v,
        _ => panic!("uchar colour"),
    };
    let srgb = |c: f32| -> u8 {
        let s = if c <= 0.003_130_8 { c * 12.92 } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
        (s * 255.0 + 0.5) as u8
    };
    for (i, e) in verts.iter().enumerate() {
        let want = vertex_color(&mesh, i, &pal).map(srgb);
        assert_eq!([byte(e, "red"), byte(e, "green"), byte(e, "blue")], want, "vertex {i}");
    }
}
