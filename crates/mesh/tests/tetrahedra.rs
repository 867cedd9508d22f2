//! Marching tetrahedra with and without the integrated clustering: every corner case of one
//! cell (alone and at a chunk corner), analytic shapes on and off the grid, gaps and bubbles
//! thinner than two cells, random edit sequences, chunk borders, incremental meshing and mixed
//! levels.

use std::f64::consts::PI;

use glam::{DQuat, DVec3, IVec3, Vec3};
use proptest::prelude::*;
use strata_mesh::checks::{self, check_closed_manifold, hausdorff, signed_volume};
use strata_mesh::tetra::tetra_volume_per_chunk;
use strata_mesh::{BlockMesher, Mesh, MeshCache, TetraScratch, mesh_block_tetra};
use strata_volume::brush::{Brush, Capsule, Cuboid, Sphere, Torus};
use strata_volume::{Axis, ChunkKey, CsgOp, EditSettings, Level, Reach, Volume, VoxelBlock};

fn mesh_one(block: &VoxelBlock, cluster: bool) -> Mesh {
    let mut mesh = Mesh::default();
    mesh_block_tetra(block, cluster, &mut TetraScratch::default(), &mut mesh);
    mesh
}

/// Chunk meshes welded by exact position.
fn weld_by_position(parts: &[(ChunkKey, Mesh)]) -> Mesh {
    checks::weld_by_position(parts.iter().map(|(k, m)| (*k, m)))
}

/// The crossing of the single-cell tests: positions that vary by edge, away from the middle.
fn crossing(axis: Axis, g: [i64; 3]) -> f32 {
    0.1 + 0.2 * ((g[0] + 2 * g[1] + 3 * g[2] + axis.index() as i64).rem_euclid(5)) as f32
}

#[test]
fn all_256_corner_cases_of_one_cell_give_closed_oriented_surfaces() {
    // The 256 patterns of one cell's corners hold every pattern of each of its six
    // tetrahedra, so this covers the tetrahedra's own table too.
    for case in 0..256usize {
        let inside = |x: usize, y: usize, z: usize| {
            (1..=2).contains(&x) && (1..=2).contains(&y) && (1..=2).contains(&z) && {
                let k = (x - 1) | ((y - 1) << 1) | ((z - 1) << 2);
                (case >> k) & 1 == 1
            }
        };
        let block = VoxelBlock::from_fn(ChunkKey::new(0, 0, 0), Level::BASE, inside, |axis, l| {
            (crossing(axis, l.map(|c| c as i64)), Vec3::X)
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
fn every_corner_case_at_a_chunk_corner_meshes_closed_across_the_eight_chunks() {
    // The pattern's 2×2×2 nodes straddle the corner node (16, 16, 16) of eight chunks, plus a
    // random solid node nearby so clusters meet the chunk faces from both sides.
    for case in 0..256usize {
        let inside = |g: [i64; 3]| {
            let c = g.map(|v| v - 15);
            let in_cell = c.iter().all(|v| (0..=1).contains(v)) && {
                let k = (c[0] | (c[1] << 1) | (c[2] << 2)) as usize;
                (case >> k) & 1 == 1
            };
            let extra = g == [14 + (case % 3) as i64, 16, 15 + (case % 2) as i64];
            in_cell || extra
        };
        for cluster in [false, true] {
            let mut parts = Vec::new();
            for d in 0..8 {
                let key = ChunkKey(IVec3::new(d & 1, (d >> 1) & 1, (d >> 2) & 1));
                let o = key.origin_grid();
                let g = move |x: usize, y: usize, z: usize| [o.x + x as i64, o.y + y as i64, o.z + z as i64];
                let block = VoxelBlock::from_fn(
                    key,
                    Level::BASE,
                    |x, y, z| inside(g(x, y, z)),
                    |axis, l| (crossing(axis, g(l[0], l[1], l[2])), Vec3::X),
                );
                parts.push((key, mesh_one(&block, cluster)));
            }
            let mesh = weld_by_position(&parts);
            check_closed_manifold(&mesh).unwrap_or_else(|e| panic!("case {case} cluster {cluster}: {e}"));
            assert!(signed_volume(&mesh) > 0.0, "case {case}");
        }
    }
}

fn volume_of(brushes: &[&dyn Brush]) -> Volume {
    let mut v = Volume::new();
    for b in brushes {
        v.add(*b).unwrap();
    }
    v
}

/// The volume the lists' surface encloses: marching cubes' (its vertices are the stored
/// crossings). The lists' own measure counts lines lying in a face on the grid as full cells.
fn lists_volume(v: &Volume) -> f64 {
    signed_volume(
        &strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::default())
            .expect("marching cubes meshes every volume"),
    )
}

/// Every tetrahedra mesh of `v` (plain, clustered whole, clustered per chunk) is closed and
/// manifold, encloses the lists' volume within `tolerance`, and the clustered ones stay within
/// `max_distance` cells of the plain one.
fn assert_tetrahedra(v: &Volume, tolerance: f64, max_distance: f64) -> [Mesh; 3] {
    let plain =
        strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::Tetrahedra)).ok().unwrap();
    let whole =
        strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::ClusteredTetrahedra))
            .ok()
            .unwrap();
    let chunked = tetra_volume_per_chunk(v).unwrap();
    let lists = lists_volume(v);
    for (name, m) in [("plain", &plain), ("clustered", &whole), ("per chunk", &chunked)] {
        check_closed_manifold(m).unwrap_or_else(|e| panic!("{name}: {e}"));
        let vol = signed_volume(m);
        assert!((vol - lists).abs() / lists < tolerance, "{name}: volume {vol}, lists {lists}");
    }
    for (name, m) in [("clustered", &whole), ("per chunk", &chunked)] {
        let h = hausdorff(&plain, m, 2.0);
        assert!(h <= max_distance, "{name}: Hausdorff {h} cells from the plain mesh");
        assert!(
            m.triangle_count() < plain.triangle_count() / 2,
            "{name}: {} of {}",
            m.triangle_count(),
            plain.triangle_count()
        );
    }
    [plain, whole, chunked]
}

#[test]
fn analytic_shapes_mesh_closed_with_their_volume_on_and_off_the_grid() {
    let c = DVec3::new(15.7, -0.4, 16.3);
    assert_tetrahedra(&volume_of(&[&Sphere::new(c, 14.0).unwrap()]), 0.01, 0.5);
    // On the grid: centre on a node (and on chunk corners), integer radius.
    assert_tetrahedra(&volume_of(&[&Sphere::new(DVec3::new(16.0, 0.0, 32.0), 12.0).unwrap()]), 0.01, 0.5);
    // Box faces on grid planes and between them; a rotated box.
    let on = Cuboid::new(DVec3::new(16.0, 8.0, 0.0), DVec3::new(10.0, 6.0, 8.0)).unwrap();
    assert_tetrahedra(&volume_of(&[&on]), 0.01, 0.5);
    let off = Cuboid::new(DVec3::new(3.5, -7.5, 12.5), DVec3::new(13.0, 9.0, 11.0)).unwrap();
    assert_tetrahedra(&volume_of(&[&off]), 0.01, 0.5);
    // Off the grid the plain mesh chamfers a box's edges and corners by up to a third of a cell,
    // where the clustered vertex (placed by its candidates' tangent planes) comes back towards
    // the true corner: they differ by more than on smooth shapes, while the clustered vertices
    // are nearer the true box than the plain ones.
    let (q, h) = (DQuat::from_rotation_y(0.6), DVec3::new(9.0, 6.0, 5.0));
    let rot = Cuboid::oriented(c, h, q, 0.0).unwrap();
    let [plain, whole, chunked] = assert_tetrahedra(&volume_of(&[&rot]), 0.02, 0.75);
    let to_box = |p: &[f32; 3]| {
        let d = (q.inverse() * (DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) - c)).abs() - h;
        (d.max(DVec3::ZERO).length() + d.max_element().min(0.0)).abs()
    };
    let worst = |m: &Mesh| m.positions.iter().map(to_box).fold(0.0, f64::max);
    assert!(
        worst(&whole) <= worst(&plain) && worst(&chunked) <= worst(&plain),
        "{} {} {}",
        worst(&plain),
        worst(&whole),
        worst(&chunked)
    );
    let torus = Torus::new(c, DVec3::new(0.3, 1.0, 0.2), 14.0, 5.0).unwrap();
    assert_tetrahedra(&volume_of(&[&torus]), 0.01, 0.5);
    let cap = Capsule::new(c, c + DVec3::new(20.0, 10.0, -5.0), 6.0).unwrap();
    assert_tetrahedra(&volume_of(&[&cap]), 0.01, 0.5);
    // Thin features: a sheet one cell thick and a thin rod are kept, not flattened.
    let sheet = Cuboid::new(DVec3::new(8.0, 8.0, 8.25), DVec3::new(6.0, 6.0, 0.6)).unwrap();
    let rod = Capsule::new(DVec3::new(2.0, 20.3, 3.1), DVec3::new(28.0, 20.3, 3.1), 0.7).unwrap();
    for b in [&sheet as &dyn Brush, &rod] {
        let v = volume_of(&[b]);
        for m in [
            strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::ClusteredTetrahedra))
                .ok()
                .unwrap(),
            tetra_volume_per_chunk(&v).unwrap(),
        ] {
            check_closed_manifold(&m).unwrap();
            assert!(signed_volume(&m) > 0.3 * lists_volume(&v));
        }
    }
}

/// Where the outside is thinner than two cells (the places a table over corner states alone
/// closes over: a gap between two solids, a bubble under a surface, two spheres nearly
/// touching), the clustered meshes keep it open, within half a cell of the plain mesh.
#[test]
fn gaps_and_bubbles_thinner_than_two_cells_stay_within_half_a_cell() {
    // Two boxes 1.5 cells apart, their facing sides between grid planes.
    let left = Cuboid::new(DVec3::new(4.3, 8.2, 7.9), DVec3::new(6.0, 6.5, 6.2)).unwrap();
    let right = Cuboid::new(DVec3::new(17.8, 8.2, 7.9), DVec3::new(6.0, 6.5, 6.2)).unwrap();
    assert_tetrahedra(&volume_of(&[&left, &right]), 0.02, 0.5);
    // A bubble of radius 0.85 a cell under a sphere's surface.
    let mut v = volume_of(&[&Sphere::new(DVec3::new(0.0, 31.1, -2.04), 10.87).unwrap()]);
    let bubble = Sphere::new(DVec3::new(-3.13, 37.8, 4.66), 0.85).unwrap();
    v.apply(CsgOp::Subtract, &bubble, &EditSettings::default()).unwrap();
    assert_tetrahedra(&v, 0.02, 0.5);
    // Two spheres whose surfaces pass 0.6 cells apart, off the grid.
    let a = Sphere::new(DVec3::new(10.2, 10.3, 10.4), 7.0).unwrap();
    let b = Sphere::new(DVec3::new(24.8, 10.3, 10.4), 7.0).unwrap();
    assert_tetrahedra(&volume_of(&[&a, &b]), 0.02, 0.5);
}

#[test]
fn incremental_chunk_meshes_equal_a_full_rebuild_and_meet_across_borders() {
    for mesher in [BlockMesher::Tetrahedra, BlockMesher::ClusteredTetrahedra] {
        let mut volume = Volume::new();
        let mut cache = MeshCache::with_mesher(mesher);
        let mut seed = 7u64;
        for i in 0..40 {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let r = |s: u64| (s % 1000) as f64 / 1000.0;
            let c = DVec3::new(r(seed >> 10), r(seed >> 20), r(seed >> 30)) * 50.0 - 5.0;
            let s = Sphere::new(c, 3.0 + 9.0 * r(seed >> 40)).unwrap();
            let report = if i % 3 == 2 { volume.subtract(&s) } else { volume.add(&s) }.unwrap();
            cache.update(&volume, &report.changed);
        }
        let full = MeshCache::build_with(&volume, mesher);
        assert_eq!(cache.len(), full.len());
        for (k, m) in full.iter() {
            assert_eq!(cache.mesh(k), Some(m), "chunk {k:?}");
        }
        let parts: Vec<(ChunkKey, Mesh)> = cache.iter().map(|(k, m)| (k, m.clone())).collect();
        let welded = weld_by_position(&parts);
        check_closed_manifold(&welded).unwrap_or_else(|e| panic!("{mesher:?}: {e}"));
        assert_eq!(
            welded.triangle_count(),
            tetra_volume_per_chunk(&volume).map_or(0, |m| {
                if mesher == BlockMesher::ClusteredTetrahedra { m.triangle_count() } else { welded.triangle_count() }
            })
        );
    }
}

/// Clustered tetrahedra make each chunk face's clusters from both chunks' blocks: a change two
/// cells short of a face, inside one chunk, moves the mesh of the chunk across the face too; a
/// change farther from every face than the slabs reach moves no other chunk's mesh.
#[test]
fn a_change_beside_a_chunk_face_remeshes_the_chunk_across_it() {
    let ball = || volume_of(&[&Sphere::new(DVec3::new(16.3, 15.7, 16.2), 12.0).unwrap()]);
    let before = MeshCache::build_with(&ball(), BlockMesher::ClusteredTetrahedra);
    for (bump, across) in [
        (DVec3::new(14.8, 26.9, 20.2), Some(IVec3::X)),
        (DVec3::new(24.3, 14.9, 25.1), Some(IVec3::Y)),
        (DVec3::new(9.37, 8.77, 9.27), None),
    ] {
        for with_reach in [false, true] {
            let mut volume = ball();
            let mut cache = MeshCache::build_with(&volume, BlockMesher::ClusteredTetrahedra);
            let report = volume.add(&Sphere::new(bump, 1.0).unwrap()).unwrap();
            let own = ChunkKey(bump.as_ivec3().div_euclid(IVec3::splat(16)));
            assert_eq!(report.changed, vec![own], "the bump stays inside one chunk");
            // (CSG edits report no reach; every changed node and both ends of every changed
            // edge lie within two cells of the bump's centre.)
            let reach = with_reach.then(|| Reach { min: bump - 2.0, max: bump + 2.0 });
            let remeshed = cache.update_reached(&volume, &report.changed, reach);
            let full = MeshCache::build_with(&volume, BlockMesher::ClusteredTetrahedra);
            match across {
                Some(d) => {
                    let across = own.offset(d);
                    assert!(remeshed.contains(&across));
                    assert_ne!(
                        before.mesh(across),
                        full.mesh(across),
                        "the change moved a face cluster across the face"
                    );
                }
                None if with_reach => assert_eq!(remeshed, vec![own], "nothing else reads the change"),
                None => assert_eq!(remeshed.len(), 27),
            }
            assert_eq!(cache.len(), full.len());
            for (k, m) in full.iter() {
                assert_eq!(cache.mesh(k), Some(m), "chunk {k:?}");
            }
            let parts: Vec<(ChunkKey, Mesh)> = cache.iter().map(|(k, m)| (k, m.clone())).collect();
            check_closed_manifold(&weld_by_position(&parts)).unwrap();
        }
    }
}

#[test]
fn mixed_levels_fall_back_to_marching_cubes_for_the_whole_volume() {
    let mut v = volume_of(&[&Sphere::new(DVec3::new(15.7, 9.4, 16.3), 12.0).unwrap()]);
    assert!(
        strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::ClusteredTetrahedra))
            .ok()
            .is_some()
    );
    let mut cache = MeshCache::build_with(&v, BlockMesher::ClusteredTetrahedra);
    assert_eq!(cache.mesher_used(), BlockMesher::ClusteredTetrahedra);
    let key = ChunkKey::new(0, 0, 0);
    let changed = v.set_chunk_level(key, Level::new(1).unwrap()).changed;
    assert!(
        strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::ClusteredTetrahedra))
            .ok()
            .is_none(),
        "tetrahedra refuse mixed levels"
    );
    assert!(tetra_volume_per_chunk(&v).is_none());
    let remeshed = cache.update(&v, &changed);
    assert_eq!(cache.mesher_used(), BlockMesher::MarchingCubes);
    // Every chunk changed mesher together, so no border joins the two.
    for (k, _) in MeshCache::build(&v).iter() {
        assert!(remeshed.contains(&k), "{k:?} remeshed");
    }
    let parts: Vec<(ChunkKey, Mesh)> = cache.iter().map(|(k, m)| (k, m.clone())).collect();
    check_closed_manifold(&weld_by_position(&parts)).unwrap();
}

/// 12 by default; `PROPTEST_CASES=500 cargo test --release -p strata-mesh` searches longer.
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(12)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), max_shrink_iters: 50, ..ProptestConfig::default() })]

    /// Random edits, generic or snapped to the grid (centres on nodes or half-cells, integer or
    /// half radii, box faces on grid planes): every tetrahedra mesh is closed and manifold, and
    /// the clustered ones keep the volume.
    #[test]
    fn random_edit_sequences_mesh_closed_and_match_the_lists_volume(
        snap in 0..3u8,
        edits in proptest::collection::vec(
            (0..3u8, 0..3u8, -10.0..40.0f64, -10.0..40.0f64, -10.0..40.0f64, 0.3..12.0f64, 0.0..3.0f64),
            8..20,
        )
    ) {
        let mut v = Volume::new();
        for (op, shape, x, y, z, r, angle) in edits {
            let (c, r) = match snap {
                0 => (DVec3::new(x, y, z), r),
                1 => (DVec3::new(x.round(), y.round(), z.round()), r.round().max(1.0)),
                _ => (DVec3::new((x * 2.0).round() / 2.0, (y * 2.0).round() / 2.0, z.round()), (r * 2.0).round().max(1.0) / 2.0),
            };
            let brush: Box<dyn Brush> = match shape {
                0 => Box::new(Sphere::new(c, r).unwrap()),
                1 if snap > 0 => Box::new(Cuboid::new(c, DVec3::new(r, (0.7 * r).round().max(0.5), 2.0)).unwrap()),
                1 => Box::new(Cuboid::oriented(c, DVec3::new(r, 0.7 * r + 0.2, 0.4 * r + 0.2), DQuat::from_rotation_y(angle), 0.0).unwrap()),
                _ => Box::new(Torus::new(c, DVec3::new(angle, 1.0, 0.5), r, 0.3 * r + 0.3).unwrap()),
            };
            let op = [CsgOp::Add, CsgOp::Subtract, CsgOp::Add][op as usize];
            v.apply(op, brush.as_ref(), &EditSettings::default()).unwrap();
        }
        if v.is_empty() {
            return Ok(());
        }
        let plain = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::Tetrahedra)).ok().unwrap();
        prop_assert!(check_closed_manifold(&plain).is_ok(), "plain: {:?}", check_closed_manifold(&plain));
        let lists = lists_volume(&v);
        for m in [strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::ClusteredTetrahedra)).ok().unwrap(), tetra_volume_per_chunk(&v).unwrap()] {
            prop_assert!(check_closed_manifold(&m).is_ok(), "{:?}", check_closed_manifold(&m));
            // The bar: within half a cell of the plain mesh, creases, corners, fins and
            // grooves narrower than a cell included (proven for the node clusters, checked for
            // the short-edge rounds: `cluster.rs`).
            let h = hausdorff(&plain, &m, 2.0);
            prop_assert!(h <= f64::from(strata_mesh::tetra::MAX_REACH_CELLS) + 1e-4, "Hausdorff {} cells from the plain mesh", h);
            if lists > 2000.0 {
                let vol = signed_volume(&m);
                prop_assert!((vol - lists).abs() / lists < 0.03, "mesh {} lists {}", vol, lists);
            }
        }
    }
}

#[test]
fn a_big_sphere_loses_most_triangles_to_clustering() {
    let v = volume_of(&[&Sphere::new(DVec3::new(15.7, -0.4, 16.3), 20.0).unwrap()]);
    let [plain, whole, chunked] = assert_tetrahedra(&v, 0.01, 0.5);
    let exact = 4.0 / 3.0 * PI * 8000.0;
    assert!((signed_volume(&whole) - exact).abs() / exact < 0.01);
    let reduction = |m: &Mesh| 1.0 - m.triangle_count() as f64 / plain.triangle_count() as f64;
    // The bars are 80 % whole and 75 % per chunk; this sphere of radius 20 reaches
    // 82.9 % and 79.5 % (75.8 % while chunk faces were never clustered).
    assert!(reduction(&whole) >= 0.80, "whole: {:.3}", reduction(&whole));
    assert!(reduction(&chunked) >= 0.78, "per chunk: {:.3}", reduction(&chunked));
}
