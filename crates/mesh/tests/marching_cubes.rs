//! Marching cubes: every corner case, analytic shapes, random edit sequences.

use std::f64::consts::PI;

use glam::{DQuat, DVec3, Vec3};
use proptest::prelude::*;
use strata_mesh::checks::{aspect_stats, check_closed_manifold, signed_volume, surface_area};
use strata_mesh::{Mesh, mesh_block};
use strata_volume::brush::{Brush, Capsule, Cuboid, Sphere, Torus};
use strata_volume::{Axis, ChunkKey, CsgOp, EditSettings, Level, Volume, VoxelBlock};

#[test]
fn all_256_corner_cases_of_one_cell_give_closed_oriented_surfaces() {
    for case in 0..256usize {
        let inside = |x: usize, y: usize, z: usize| {
            (1..=2).contains(&x) && (1..=2).contains(&y) && (1..=2).contains(&z) && {
                let k = (x - 1) | ((y - 1) << 1) | ((z - 1) << 2);
                (case >> k) & 1 == 1
            }
        };
        let block = VoxelBlock::from_fn(ChunkKey::new(0, 0, 0), Level::BASE, inside, |axis, lower| {
            // Vary positions so that fans over non-planar loops are exercised.
            let t = 0.3 + 0.1 * ((lower[0] + 2 * lower[1] + 3 * lower[2] + axis.index()) % 5) as f32;
            (t, Vec3::X)
        });
        let mut mesh = Mesh::default();
        mesh_block(&block, &mut mesh);
        if case == 0 {
            assert_eq!(mesh.triangle_count(), 0);
            continue;
        }
        check_closed_manifold(&mesh).unwrap_or_else(|e| panic!("case {case}: {e}"));
        let v = signed_volume(&mesh);
        assert!(v > 0.0, "case {case}: volume {v} (inverted)");
        let crossings: usize = Axis::ALL.iter().map(|&a| block.crossings(a).len()).sum();
        assert_eq!(mesh.vertex_count(), crossings, "one vertex per crossing");
    }
}

fn volume_of(brushes: &[&dyn strata_volume::brush::Brush]) -> Volume {
    let mut v = Volume::new();
    for b in brushes {
        v.add(*b).unwrap();
    }
    v
}

fn assert_mesh_volume(v: &Volume, exact: f64, tolerance: f64) -> Mesh {
    let mesh = strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    check_closed_manifold(&mesh).unwrap();
    let m = signed_volume(&mesh);
    assert!((m - exact).abs() / exact < tolerance, "mesh volume {m}, exact {exact}");
    mesh
}

#[test]
fn analytic_shapes_mesh_closed_with_their_volume_across_chunk_borders() {
    let c = DVec3::new(15.7, -0.4, 16.3);
    let sphere = Sphere::new(c, 20.0).unwrap();
    let mesh = assert_mesh_volume(&volume_of(&[&sphere]), 4.0 / 3.0 * PI * 8000.0, 0.01);
    let area = surface_area(&mesh);
    assert!((area - 4.0 * PI * 400.0).abs() / (4.0 * PI * 400.0) < 0.05, "area {area}");
    let stats = aspect_stats(&mesh);
    assert_eq!(stats.degenerate, 0);
    let half = DVec3::new(20.0, 13.0, 18.0);
    let aligned = Cuboid::new(DVec3::new(3.5, -7.5, 12.5), half).unwrap();
    assert_mesh_volume(&volume_of(&[&aligned]), 8.0 * half.x * half.y * half.z, 0.01);
    let torus = Torus::new(c, DVec3::new(0.3, 1.0, 0.2), 20.0, 7.0).unwrap();
    assert_mesh_volume(&volume_of(&[&torus]), 2.0 * PI * PI * 20.0 * 49.0, 0.01);
    let cap = Capsule::new(c, c + DVec3::new(20.0, 10.0, -5.0), 9.0).unwrap();
    let len = DVec3::new(20.0, 10.0, -5.0).length();
    assert_mesh_volume(&volume_of(&[&cap]), PI * 81.0 * (len + 12.0), 0.01);
}

#[test]
fn vertices_lie_exactly_on_the_stored_crossings() {
    let v = volume_of(&[&Sphere::new(DVec3::new(7.3, 8.1, 9.9), 6.2).unwrap()]);
    let block = v.extract_block(ChunkKey::new(0, 0, 0));
    let mut mesh = Mesh::default();
    mesh_block(&block, &mut mesh);
    let mut i = 0;
    for axis in Axis::ALL {
        for c in block.crossings(axis) {
            let mut p = c.lower.map(|x| x as f32);
            p[axis.index()] += c.t;
            assert_eq!(mesh.positions[i], p);
            // The stored position is exact: a multiple of 1/4096 of a cell.
            assert_eq!((c.t * 4096.0).fract(), 0.0);
            i += 1;
        }
    }
}

/// 12 by default; `PROPTEST_CASES=500 cargo test --release -p strata-mesh` searches longer.
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(12)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), max_shrink_iters: 50, ..ProptestConfig::default() })]

    #[test]
    fn random_edit_sequences_mesh_closed_and_match_the_lists_volume(
        large in any::<bool>(),
        edits in proptest::collection::vec(
            (0..3u8, 0..3u8, -10.0..50.0f64, -10.0..50.0f64, -10.0..50.0f64, 0.3..16.0f64, 0.0..3.0f64),
            20..40,
        )
    ) {
        let mut v = Volume::new();
        // The volume bar: within 1 % of the lists for spheres of radius >= 10 cells. (Marching
        // cubes chamfers sharp box edges, about a quarter cell² per cell of edge, which is more
        // than 1 % for boxes of this size; closedness is checked for every shape.)
        for (op, shape, x, y, z, r, angle) in edits {
            let (r, shape) = if large { (10.0 + r % 6.0, 0) } else { (r, shape) };
            let c = DVec3::new(x, y, z);
            let brush: Box<dyn Brush> = match shape {
                0 => Box::new(Sphere::new(c, r).unwrap()),
                1 => Box::new(Cuboid::oriented(c, DVec3::new(r, 0.7 * r + 0.2, 0.4 * r + 0.2), DQuat::from_rotation_y(angle), 0.0).unwrap()),
                _ => Box::new(Torus::new(c, DVec3::new(angle, 1.0, 0.5), r, 0.3 * r + 0.3).unwrap()),
            };
            let op = [CsgOp::Add, CsgOp::Subtract, CsgOp::Add][op as usize];
            v.apply(op, brush.as_ref(), &EditSettings::default()).unwrap();
        }
        if v.is_empty() {
            return Ok(());
        }
        let mesh = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default()).expect("marching cubes meshes every volume");
        prop_assert!(check_closed_manifold(&mesh).is_ok(), "{:?}", check_closed_manifold(&mesh));
        let lists = v.measured_volume(Axis::X);
        let m = signed_volume(&mesh);
        if large && lists > 5000.0 {
            prop_assert!((m - lists).abs() / lists < 0.01, "mesh {} lists {}", m, lists);
        }
    }
}

/// A uniform chunk takes the finest level among the list chunks across its faces and edges, so
/// a chunk whose only list neighbour is across an edge follows it (it used to take the
/// volume's level, which made the blocks around it patch seams that were not there); and a
/// level-of-detail cap given only for list chunks (as the editor's is) meshes closed.
#[test]
fn uniform_chunks_follow_their_list_neighbours_across_edges_and_capped_meshes_stay_closed() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(8.2, 7.9, 8.1), 3.3).unwrap()).unwrap();
    v.set_chunk_level(ChunkKey::new(0, 0, 0), Level::new(1).unwrap());
    assert!(v.chunks().all(|(k, _)| k == ChunkKey::new(0, 0, 0)), "one list chunk");
    assert_eq!(v.mesh_level(ChunkKey::new(1, 0, 0)), Level::new(1).unwrap(), "across a face");
    assert_eq!(v.mesh_level(ChunkKey::new(1, 1, 0)), Level::new(1).unwrap(), "across an edge");
    assert_eq!(v.mesh_level(ChunkKey::new(3, 0, 0)), Level::BASE, "far away: the volume's level");
    // Large balls over many chunks stored at level 2, capped to 1 and 0 where they hold lists.
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(20.3, 17.7, 15.2), 19.0).unwrap()).unwrap();
    v.add(&Cuboid::new(DVec3::new(44.0, 16.0, 16.0), DVec3::new(8.0, 8.0, 12.5)).unwrap()).unwrap();
    let keys: Vec<ChunkKey> = v.chunks().map(|(k, _)| k).collect();
    let _ = v.set_chunk_levels(&keys, Level::new(2).unwrap());
    for cap_to in [-1i8, 0, 1] {
        let cap = |k: ChunkKey| {
            if v.stored_level(k).is_some() { Level::new(cap_to + (k.0.x & 1) as i8).unwrap() } else { Level::FINEST }
        };
        let (m, _) = strata_mesh::mesh_volume_reported(&v, strata_mesh::MeshOptions::default(), Some(&cap)).unwrap();
        check_closed_manifold(&m).unwrap_or_else(|e| panic!("capped to {cap_to}: {e}"));
    }
}
