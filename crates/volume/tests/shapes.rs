//! Analytic checks: enclosed volumes, translation invariance, undo, mesh brushes and bad input.

use std::f64::consts::PI;

use glam::{DQuat, DVec3, I64Vec3};
use strata_volume::brush::{
    Brush, Capsule, Cuboid, Cylinder, MeshBrush, MeshRule, SdfBrush, Sphere, Torus, Transformed,
};
use strata_volume::{Axis, ChunkKey, CsgOp, EditError, EditSettings, Volume, brush_contains_node};

fn relative_error(measured: f64, exact: f64) -> f64 {
    (measured - exact).abs() / exact
}

fn assert_volume_close(brush: &dyn Brush, exact: f64, tolerance: f64) {
    let mut v = Volume::new();
    v.add(brush).unwrap();
    v.check_invariants().unwrap();
    for axis in Axis::ALL {
        let m = v.measured_volume(axis);
        let e = relative_error(m, exact);
        assert!(e < tolerance, "{axis:?}: measured {m}, exact {exact}, error {:.4} %", e * 100.0);
    }
}

#[test]
fn sphere_box_and_torus_volumes_are_within_half_a_percent_at_radius_20() {
    let c = DVec3::new(3.3, -7.1, 12.6);
    assert_volume_close(&Sphere::new(c, 20.0).unwrap(), 4.0 / 3.0 * PI * 8000.0, 0.005);
    // Lines stand for the cell-sized square around them (the midpoint rule), so an axis-aligned
    // box is measured exactly when its faces lie half-way between nodes; a rotated box averages.
    let half = DVec3::new(20.0, 13.0, 18.0);
    let aligned = Cuboid::new(DVec3::new(3.5, -7.5, 12.5), half).unwrap();
    assert_volume_close(&aligned, 8.0 * half.x * half.y * half.z, 0.005);
    let rot = DQuat::from_euler(glam::EulerRot::XYZ, 0.5, -0.3, 0.9);
    let rotated = Cuboid::oriented(c, DVec3::splat(20.0), rot, 0.0).unwrap();
    assert_volume_close(&rotated, 64000.0, 0.005);
    let (major, minor) = (20.0, 7.0);
    let torus = Torus::new(c, DVec3::new(0.3, 1.0, 0.2), major, minor).unwrap();
    assert_volume_close(&torus, 2.0 * PI * PI * major * minor * minor, 0.005);
}

#[test]
fn other_shapes_have_their_analytic_volumes() {
    let c = DVec3::new(-4.2, 9.9, 0.7);
    let cap = Capsule::new(c, c + DVec3::new(20.0, 10.0, -5.0), 9.0).unwrap();
    let len = DVec3::new(20.0, 10.0, -5.0).length();
    assert_volume_close(&cap, PI * 81.0 * (len + 4.0 / 3.0 * 9.0), 0.01);
    let cyl = Cylinder::new(c, DVec3::new(1.0, 2.0, 0.5), 15.0, 10.0).unwrap();
    assert_volume_close(&cyl, PI * 100.0 * 30.0, 0.01);
    let rot = DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, -0.2);
    let obox = Cuboid::oriented(c, DVec3::new(12.0, 9.0, 15.0), rot, 2.0).unwrap();
    let r: f64 = 2.0;
    let (a, b, d) = (24.0 - 2.0 * r, 18.0 - 2.0 * r, 30.0 - 2.0 * r);
    let rounded = a * b * d + 2.0 * r * (a * b + b * d + a * d) + PI * r * r * (a + b + d) + 4.0 / 3.0 * PI * r.powi(3);
    assert_volume_close(&obox, rounded, 0.01);
    let scaled = Transformed::new(Sphere::new(DVec3::ZERO, 2.0).unwrap(), rot, c, 8.0).unwrap();
    assert_volume_close(&scaled, 4.0 / 3.0 * PI * 16f64.powi(3), 0.005);
    let field =
        SdfBrush::new(move |p| (p - c).length() - 14.0, strata_volume::brush::Aabb::new(c - 15.0, c + 15.0), 1.0)
            .unwrap();
    assert_volume_close(&field, 4.0 / 3.0 * PI * 14f64.powi(3), 0.01);
}

/// Every chunk's data, keyed by its position relative to `base`.
fn relative_chunks(v: &Volume, base: ChunkKey) -> Vec<(glam::IVec3, strata_volume::Chunk)> {
    let mut out: Vec<_> = v.chunks().map(|(k, c)| (k.0 - base.0, c.clone())).collect();
    out.sort_by_key(|(k, _)| (k.z, k.y, k.x));
    out
}

#[test]
fn the_same_edits_a_million_cells_away_store_identical_chunk_local_data() {
    let far = DVec3::splat(1_000_000.0);
    let build = |offset: DVec3| {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(3.25, 7.5, -2.125) + offset, 13.375).unwrap()).unwrap();
        v.subtract(&Cuboid::new(DVec3::new(10.5, 0.25, 4.0) + offset, DVec3::new(6.0, 5.5, 7.25)).unwrap()).unwrap();
        let t = Torus::new(DVec3::new(-5.0, 2.5, 1.0) + offset, DVec3::new(1.0, 1.0, 0.0), 8.0, 2.5).unwrap();
        v.add(&t).unwrap();
        let rot = DQuat::from_rotation_y(0.4);
        v.add(
            &Transformed::new(Cuboid::new(DVec3::ZERO, DVec3::new(3.0, 4.0, 5.0)).unwrap(), rot, offset + 9.0, 1.5)
                .unwrap(),
        )
        .unwrap();
        v.check_invariants().unwrap();
        v
    };
    let near = build(DVec3::ZERO);
    let away = build(far);
    let shift = ChunkKey::new(62_500, 62_500, 62_500);
    assert_eq!(relative_chunks(&near, ChunkKey::new(0, 0, 0)), relative_chunks(&away, shift));
    assert!(near.chunk_count() > 8);
}

#[test]
fn undo_restores_the_exact_previous_volume_and_redo_reapplies() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(1.0, 2.0, 3.0), 17.0).unwrap()).unwrap();
    let before = v.clone();
    let mut records = Vec::new();
    for (i, op) in [CsgOp::Subtract, CsgOp::Add, CsgOp::Intersect, CsgOp::Add].into_iter().enumerate() {
        let b = Sphere::new(DVec3::new(9.0 * i as f64, -4.0, 6.0), 11.0).unwrap();
        records.push(v.apply(op, &b, &EditSettings::default()).unwrap().undo);
    }
    let after = v.clone();
    let mut redo = Vec::new();
    while let Some(r) = records.pop() {
        redo.push(v.restore(r));
    }
    assert_eq!(v, before);
    while let Some(r) = redo.pop() {
        v.restore(r);
    }
    assert_eq!(v, after);
}

#[test]
fn an_edit_reports_exactly_the_chunks_it_changed() {
    let mut v = Volume::new();
    let first = v.add(&Sphere::new(DVec3::new(8.0, 8.0, 8.0), 3.0).unwrap()).unwrap();
    assert_eq!(first.changed, vec![ChunkKey::new(0, 0, 0)]);
    let again = v.add(&Sphere::new(DVec3::new(8.0, 8.0, 8.0), 3.0).unwrap()).unwrap();
    assert!(again.changed.is_empty(), "adding the same brush twice changes nothing");
    // Touching node 16 of chunk 0 along x changes chunk 0's last cells and chunk 1.
    let edge = v.add(&Sphere::new(DVec3::new(16.5, 8.0, 8.0), 1.0).unwrap()).unwrap();
    assert_eq!(edge.changed, vec![ChunkKey::new(0, 0, 0), ChunkKey::new(1, 0, 0)]);
}

fn uv_sphere(radius: f64, center: DVec3, rings: u32, segments: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let mut verts = vec![center + DVec3::Z * radius, center - DVec3::Z * radius];
    for r in 1..rings {
        let phi = PI * r as f64 / rings as f64;
        for s in 0..segments {
            let th = 2.0 * PI * s as f64 / segments as f64;
            verts.push(center + radius * DVec3::new(phi.sin() * th.cos(), phi.sin() * th.sin(), phi.cos()));
        }
    }
    let ring = |r: u32, s: u32| 2 + (r - 1) * segments + s % segments;
    let mut tris = Vec::new();
    for s in 0..segments {
        tris.push([0, ring(1, s), ring(1, s + 1)]);
        tris.push([1, ring(rings - 1, s + 1), ring(rings - 1, s)]);
        for r in 1..rings - 1 {
            tris.push([ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)]);
            tris.push([ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)]);
        }
    }
    (verts, tris)
}

#[test]
fn a_mesh_sphere_matches_the_analytic_sphere_except_on_a_thin_shell() {
    let c = DVec3::new(20.3, 18.7, 21.1);
    let r = 15.0;
    let (verts, tris) = uv_sphere(r, c, 96, 192);
    let mesh = MeshBrush::new(&verts, &tris, MeshRule::EvenOdd).unwrap();
    assert!(mesh.is_closed());
    let mut a = Volume::new();
    let mut b = Volume::new();
    a.add(&mesh).unwrap();
    b.add(&Sphere::new(c, r).unwrap()).unwrap();
    a.check_invariants().unwrap();
    let mut differ = 0;
    for z in 0..45 {
        for y in 0..45 {
            for x in 0..45 {
                let node = I64Vec3::new(x, y, z);
                if a.node_inside(node) != b.node_inside(node) {
                    differ += 1;
                    // The polygonal sphere lies inside the true one by at most the sagitta.
                    let d = (node.as_dvec3() - c).length() - r;
                    assert!(d.abs() < 0.05, "node {node} differs {d} cells from the surface");
                }
            }
        }
    }
    // Nodes within the sagitta (15 (1 - cos(pi / 96)) = 0.008 cells) of the surface can differ:
    // about area x sagitta = 2827 x 0.008 = 23 on each side.
    assert!(differ < 120, "{differ} nodes differ");
    let e = relative_error(a.measured_volume(Axis::Z), b.measured_volume(Axis::Z));
    assert!(e < 0.003, "mesh and analytic volumes differ by {e}");
}

#[test]
fn a_mesh_with_a_hole_gives_a_consistent_volume_without_panicking() {
    let c = DVec3::new(8.2, 7.9, 8.4);
    let (verts, mut tris) = uv_sphere(6.0, c, 24, 48);
    tris.truncate(tris.len() - 30); // remove part of the bottom cap
    let mesh = MeshBrush::new(&verts, &tris, MeshRule::EvenOdd).unwrap();
    assert!(!mesh.is_closed());
    let mut v = Volume::new();
    let report = v.add(&mesh).unwrap();
    v.check_invariants().unwrap();
    assert!(v.is_inside(c), "the centre is still enclosed along x");
    let m = v.measured_volume(Axis::X);
    let exact = 4.0 / 3.0 * PI * 216.0;
    assert!(m > 0.5 * exact && m < 1.05 * exact, "measured {m} of {exact}");
    // The report says how many brush nodes had to be repaired for the axes to agree.
    let _ = report.repaired_nodes;
    let empty = MeshBrush::new(&verts, &[], MeshRule::EvenOdd);
    assert!(empty.is_err());
}

#[test]
fn huge_and_degenerate_brushes_are_refused_and_leave_the_volume_unchanged() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::ZERO, 5.0).unwrap()).unwrap();
    let before = v.clone();
    let huge = Sphere::new(DVec3::ZERO, 1e5).unwrap();
    assert!(matches!(v.add(&huge), Err(EditError::TooLarge { .. })));
    let beyond = Sphere::new(DVec3::ZERO, 1e12).unwrap();
    assert_eq!(v.add(&beyond).unwrap_err(), EditError::OutOfRange);
    let edge_of_world = Sphere::new(DVec3::splat(16.0 * i32::MAX as f64), 3.0).unwrap();
    assert_eq!(v.add(&edge_of_world).unwrap_err(), EditError::OutOfRange);
    let bad = SdfBrush::new(|p| p.length() - 1.0, strata_volume::brush::Aabb::new(DVec3::ONE, DVec3::ZERO), 1.0);
    assert!(bad.is_err());
    assert!(Sphere::new(DVec3::ZERO, f64::NAN).is_err());
    assert!(Transformed::new(Sphere::new(DVec3::ZERO, 1.0).unwrap(), DQuat::IDENTITY, DVec3::ZERO, -2.0).is_err());
    assert_eq!(v, before);
    // A tiny brush that holds no node changes nothing; one that holds a node changes it.
    assert!(v.add(&Sphere::new(DVec3::new(30.5, 30.5, 30.5), 0.1).unwrap()).unwrap().changed.is_empty());
    v.add(&Sphere::new(DVec3::new(30.0, 30.0, 30.0), 0.1).unwrap()).unwrap();
    assert!(v.node_inside(I64Vec3::new(30, 30, 30)));
    assert!(brush_contains_node(
        &Sphere::new(DVec3::new(30.0, 30.0, 30.0), 0.1).unwrap(),
        I64Vec3::new(30, 30, 30),
        v.level()
    ));
    v.check_invariants().unwrap();
}

#[test]
fn a_ray_hits_the_first_surface_it_meets() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(40.0, 3.0, -2.0), 10.0).unwrap()).unwrap();
    let hit = v.raycast(DVec3::new(-100.0, 3.0, -2.0), DVec3::X, 1000.0).expect("hit");
    assert!((hit.point.x - 30.0).abs() < 0.05, "{hit:?}");
    assert!(hit.normal.x < -0.9);
    let diag = DVec3::new(1.0, 1.0, 0.5).normalize();
    let start = DVec3::new(40.0, 3.0, -2.0) - diag * 50.0;
    let hit = v.raycast(start, diag, 100.0).expect("diagonal hit");
    assert!((hit.t - 40.0).abs() < 0.1, "{hit:?}");
    assert!(v.raycast(DVec3::new(-100.0, 30.0, -2.0), DVec3::X, 1000.0).is_none());
    assert_eq!(v.raycast(DVec3::new(40.0, 3.0, -2.0), DVec3::Y, 10.0).map(|h| h.t), Some(0.0));
    assert!(v.raycast(DVec3::NAN, DVec3::X, 1.0).is_none());
}

#[test]
fn memory_and_statistics_count_what_is_stored() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(5.0, 5.0, 5.0), 30.0).unwrap()).unwrap();
    let stats = v.crossing_stats();
    let mem = v.memory();
    assert_eq!(stats.total as usize, mem.crossings);
    assert_eq!(mem.positions, 2 * mem.crossings);
    assert_eq!(mem.normals, 2 * mem.crossings);
    assert!(stats.solid_chunks > 0 && stats.list_chunks > 0);
    assert_eq!(stats.histogram.iter().sum::<u64>(), stats.list_chunks * 3 * 256);
    assert!(stats.max_line >= 1 && stats.max_line <= 16);
    assert!(mem.chunk_map > 0 && mem.headers > 0);
}

#[test]
fn finer_levels_store_finer_lines() {
    for k in 1..=2 {
        let level = strata_volume::Level::new(k).unwrap();
        let sphere = Sphere::new(DVec3::new(7.3, 9.1, 8.2), 6.0).unwrap();
        let cube = Cuboid::new(DVec3::new(7.0, 9.0, 12.0), DVec3::new(3.0, 3.0, 3.0)).unwrap();
        let mut v = Volume::with_level(level);
        v.add(&sphere).unwrap();
        let exact = 4.0 / 3.0 * PI * 216.0;
        let e = relative_error(v.measured_volume(Axis::Y), exact);
        assert!(e < 0.005, "level {k}: error {e}");
        v.subtract(&cube).unwrap();
        v.check_invariants().unwrap();
        let n = 16i64 << k;
        for z in -2..n + 2 {
            for y in -2..n + 2 {
                for x in -2..n + 2 {
                    let node = I64Vec3::new(x, y, z);
                    let expect = brush_contains_node(&sphere, node, level) && !brush_contains_node(&cube, node, level);
                    assert_eq!(v.node_inside(node), expect, "level {k} node {node}");
                }
            }
        }
        let block = v.extract_block(ChunkKey::new(0, 0, 0));
        assert_eq!(block.cells(), 16 << k);
        assert_eq!(block.repaired(), 0);
        let back: Volume = postcard::from_bytes(&postcard::to_allocvec(&v).unwrap()).unwrap();
        assert_eq!(back, v, "level {k}: serde round trip");
    }
}

#[test]
fn volumes_round_trip_through_serde_and_corrupted_bytes_never_panic() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(3.0, 5.0, 7.0), 12.0).unwrap()).unwrap();
    v.subtract(&Cuboid::new(DVec3::new(9.0, 5.0, 7.0), DVec3::splat(5.0)).unwrap()).unwrap();
    let bytes = postcard::to_allocvec(&v).unwrap();
    let back: Volume = postcard::from_bytes(&bytes).unwrap();
    assert_eq!(back, v);
    let mut seed = 99u64;
    let mut accepted = 0;
    for round in 0..3000 {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let mut b = bytes.clone();
        match round % 3 {
            0 => b.truncate((seed >> 33) as usize % b.len()),
            _ => {
                for k in 0..1 + round % 4 {
                    let i = ((seed >> (7 + k)) as usize) % b.len();
                    b[i] ^= 1 << ((seed >> 40) % 8);
                }
            }
        }
        if let Ok(c) = postcard::from_bytes::<Volume>(&b) {
            // Whatever decodes is structurally sound enough to query without panicking.
            accepted += 1;
            let _ = c.check_invariants();
            let _ = c.memory();
            let _ = c.crossing_stats();
            let _ = c.measured_volume(Axis::Y);
            let _ = c.raycast(DVec3::new(-40.0, 5.0, 7.0), DVec3::X, 100.0);
            let keys: Vec<ChunkKey> = c.chunks().map(|(k, _)| k).collect();
            for k in keys {
                let _ = c.extract_block(k);
            }
        }
    }
    assert!(accepted < 3000);
}

#[test]
fn box_faces_that_land_on_node_planes_after_rounding_keep_the_axes_consistent() {
    // 16.3 + 17.7 and -0.4 + 13.1 round to (or next to) node coordinates: the face test must
    // come out the same along every axis.
    let b = Cuboid::new(DVec3::new(15.7, -0.4, 16.3), DVec3::new(20.3, 13.1, 17.7)).unwrap();
    let mut v = Volume::new();
    v.add(&b).unwrap();
    v.check_invariants().unwrap();
    for (k, _) in v.chunks().collect::<Vec<_>>() {
        assert_eq!(v.extract_block(k).repaired(), 0, "chunk {k:?}");
    }
    for z in [33, 34, 35] {
        for y in [-14, -13, 12, 13] {
            for x in [-5, -4, 35, 36, 37] {
                let node = I64Vec3::new(x, y, z);
                assert_eq!(v.node_inside(node), brush_contains_node(&b, node, v.level()), "node {node}");
            }
        }
    }
}

#[test]
fn a_cell_size_that_is_not_finite_and_positive_is_refused() {
    let mut v = strata_volume::Volume::new();
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(v.set_cell_size(bad).is_err(), "{bad}");
        assert_eq!(v.cell_size(), 1.0);
    }
    v.set_cell_size(0.25).unwrap();
    assert_eq!(v.cell_size(), 0.25);
}
