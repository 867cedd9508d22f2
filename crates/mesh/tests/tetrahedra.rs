//! Marching tetrahedra with and without the integrated clustering: every corner case of one
//! cell, analytic shapes, the bunny, a noise asteroid, random edits, chunk borders.

use std::f64::consts::PI;

use glam::{DQuat, DVec3, Vec3};
use proptest::prelude::*;
use strata_mesh::checks::{aspect_stats, check_closed_manifold, signed_volume};
use strata_mesh::{BlockMesher, Mesh, MeshCache, TetraScratch, mesh_block_tetra, tetra_volume};
use strata_volume::brush::{Brush, Cuboid, Sphere, Torus};
use strata_volume::{Axis, ChunkKey, CsgOp, EditSettings, Level, Volume, VoxelBlock};

fn mesh_one(block: &VoxelBlock, cluster: bool) -> Mesh {
    let mut mesh = Mesh::default();
    mesh_block_tetra(block, cluster, &mut TetraScratch::default(), &mut mesh);
    mesh
}

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
            let t = 0.1 + 0.2 * ((lower[0] + 2 * lower[1] + 3 * lower[2] + axis.index()) % 5) as f32;
            (t, Vec3::X)
        });
        for cluster in [false, true] {
            let mesh = mesh_one(&block, cluster);
            if case == 0 {
                assert_eq!(mesh.triangle_count(), 0);
                continue;
            }
            check_closed_manifold(&mesh).unwrap_or_else(|e| panic!("case {case} cluster {cluster}: {e}"));
            let v = signed_volume(&mesh);
            assert!(v > 0.0, "case {case} cluster {cluster}: volume {v} (inverted)");
        }
    }
}

#[test]
fn sphere_reduction() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(15.7, -0.4, 16.3), 20.0).unwrap()).unwrap();
    let plain = tetra_volume(&v, false).unwrap();
    let clustered = tetra_volume(&v, true).unwrap();
    check_closed_manifold(&plain).unwrap();
    check_closed_manifold(&clustered).unwrap();
    let exact = 4.0 / 3.0 * PI * 8000.0;
    eprintln!(
        "plain {} tris vol {:.4}  clustered {} tris vol {:.4} aspect {:?} / {:?}",
        plain.triangle_count(),
        signed_volume(&plain) / exact,
        clustered.triangle_count(),
        signed_volume(&clustered) / exact,
        aspect_stats(&plain),
        aspect_stats(&clustered)
    );
}

#[test]
fn small_sphere_reduction() {
    for (c, r) in [(8.3, 6.1), (24.0, 20.0), (0.0, 20.0)] {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::splat(c), r).unwrap()).unwrap();
        let plain = tetra_volume(&v, false).unwrap();
        let clustered = tetra_volume(&v, true).unwrap();
        let mc = strata_mesh::mesh_volume(&v);
        eprintln!(
            "r {r}: mc {} plain {} clustered {} ({:.1} %) aspect {:.2} mc aspect {:.2}",
            mc.triangle_count(),
            plain.triangle_count(),
            clustered.triangle_count(),
            100.0 * (1.0 - clustered.triangle_count() as f64 / plain.triangle_count() as f64),
            aspect_stats(&clustered).mean,
            aspect_stats(&mc).mean
        );
    }
}
