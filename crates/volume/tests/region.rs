//! The region primitive: lists read into a signed distance field and written back.

use glam::{DVec3, I64Vec3};
use proptest::prelude::*;
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::tools::RegionError;
use strata_volume::{Axis, CsgOp, EditSettings, Volume};

fn sphere_volume(c: DVec3, r: f64) -> Volume {
    let mut v = Volume::new();
    v.add(&Sphere::new(c, r).unwrap()).unwrap();
    v
}

#[test]
fn the_field_read_from_a_sphere_is_its_signed_distance() {
    let c = DVec3::new(20.3, 19.7, 20.1);
    let v = sphere_volume(c, 10.0);
    let region = v.read_region(c - 14.0, c + 14.0, 0).unwrap();
    let (mut worst_near, mut worst_far) = (0.0f64, 0.0f64);
    let mut far_nodes = 0;
    for z in 0..region.dims[2] {
        for y in 0..region.dims[1] {
            for x in 0..region.dims[0] {
                let i = region.index(x, y, z);
                let exact = (region.grid_point(x, y, z) - c).length() - 10.0;
                let err = (region.phi[i] as f64 - exact).abs();
                assert_eq!(region.phi[i] < 0.0, v.node_inside(region.node(x, y, z)), "the sign is the node state");
                if exact.abs() <= 1.5 {
                    worst_near = worst_near.max(err);
                } else {
                    worst_far = worst_far.max(err / exact.abs());
                    far_nodes += 1;
                }
            }
        }
    }
    assert!(far_nodes > 1000);
    // Near the surface: the tangent planes of the stored crossings (positions to 1/2048 of a
    // cell, normals to about 0.7°).
    assert!(worst_near < 0.05, "near the surface the field is off by {worst_near} cells");
    // Beyond the band, the distance to the nearest crossing (crossings lie about a cell apart).
    assert!(worst_far < 0.05, "far from the surface the field is off by {:.1} % of the distance", worst_far * 100.0);
}

#[test]
fn a_region_written_back_untouched_leaves_the_volume_bit_for_bit() {
    let c = DVec3::new(15.5, 16.25, 17.0);
    let mut v = sphere_volume(c, 9.0);
    v.subtract(&Cuboid::new(c + DVec3::X * 6.0, DVec3::splat(3.0)).unwrap()).unwrap();
    let before = v.clone();
    // Weight 0 everywhere, with the field scrambled: nothing changes.
    let mut r = v.read_region(c - 12.0, c + 12.0, 1).unwrap();
    for p in &mut r.phi {
        *p = -*p + 0.3;
    }
    let report = v.write_region(&r).unwrap();
    assert!(report.changed.is_empty());
    assert_eq!(v, before);
    // Weight 1 everywhere with the field as read: nothing changes either (no re-quantisation).
    let mut r = v.read_region(c - 12.0, c + 12.0, 1).unwrap();
    r.weight.fill(1.0);
    let report = v.write_region(&r).unwrap();
    assert!(report.changed.is_empty(), "{:?}", report.changed);
    assert_eq!(v, before);
}

#[test]
fn an_offset_field_grows_a_sphere_by_the_offset_and_undo_restores_it() {
    let c = DVec3::new(24.0, 24.5, 23.75);
    let mut v = sphere_volume(c, 10.0);
    let before = v.clone();
    let mut r = v.read_region(c - 16.0, c + 16.0, 1).unwrap();
    for i in 0..r.phi.len() {
        r.phi[i] -= 2.5;
        r.weight[i] = 1.0;
    }
    let report = v.write_region(&r).unwrap();
    v.check_invariants().unwrap();
    assert!(!report.changed.is_empty());
    let grown = v.measured_volume(Axis::X);
    let expected = 4.0 / 3.0 * std::f64::consts::PI * 12.5f64.powi(3);
    assert!((grown / expected - 1.0).abs() < 0.03, "volume {grown}, a radius-12.5 ball has {expected}");
    for axis in [Axis::Y, Axis::Z] {
        assert!((v.measured_volume(axis) / grown - 1.0).abs() < 0.01);
    }
    v.restore(report.undo);
    assert_eq!(v, before, "undo restores the exact volume");
}

#[test]
fn only_owned_nodes_change_and_crossings_between_untouched_nodes_stay() {
    let c = DVec3::new(16.0, 16.0, 16.0);
    let mut v = sphere_volume(c, 12.0);
    let before = v.clone();
    // Own only the nodes with x < 16: erase them (a positive field).
    let mut r = v.read_region(c - 16.0, c + 16.0, 1).unwrap();
    for z in 0..r.dims[2] {
        for y in 0..r.dims[1] {
            for x in 0..r.dims[0] {
                let i = r.index(x, y, z);
                if r.node(x, y, z).x < 16 {
                    r.weight[i] = 1.0;
                    r.phi[i] = 1.0;
                }
            }
        }
    }
    v.write_region(&r).unwrap();
    v.check_invariants().unwrap();
    for z in -2..34 {
        for y in -2..34 {
            for x in 17..34 {
                let node = I64Vec3::new(x, y, z);
                assert_eq!(v.node_inside(node), before.node_inside(node), "node {node} was not owned");
            }
        }
    }
    assert!(!v.node_inside(I64Vec3::new(10, 16, 16)));
    // A y line at x = 20 holds only unowned nodes: its crossings are the old ones exactly.
    let key = strata_volume::ChunkKey::new(1, 0, 1);
    let (a, b) = (v.chunk(key), before.chunk(key));
    assert_eq!(a, b, "a chunk of only unowned nodes is bit for bit the same");
}

#[test]
fn bad_regions_are_errors() {
    let mut v = sphere_volume(DVec3::splat(8.0), 5.0);
    assert_eq!(v.read_region(DVec3::NAN, DVec3::ONE, 0).unwrap_err(), RegionError::BadBox);
    assert_eq!(v.read_region(DVec3::ONE, DVec3::ZERO, 0).unwrap_err(), RegionError::BadBox);
    assert!(matches!(v.read_region(DVec3::ZERO, DVec3::splat(1e4), 0), Err(RegionError::TooLarge { .. })));
    assert_eq!(v.read_region(DVec3::splat(-1e12), DVec3::ZERO, 0).unwrap_err(), RegionError::OutOfRange);
    let mut r = v.read_region(DVec3::ZERO, DVec3::splat(16.0), 1).unwrap();
    r.phi.pop();
    assert_eq!(v.write_region(&r).unwrap_err(), RegionError::Mismatch);
    // NaN and infinite fields from an operator make a consistent volume, not a panic.
    let mut r = v.read_region(DVec3::ZERO, DVec3::splat(16.0), 1).unwrap();
    for (k, p) in r.phi.iter_mut().enumerate() {
        *p = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.5][k % 4];
    }
    r.weight.fill(1.0);
    v.write_region(&r).unwrap();
    v.check_invariants().unwrap();
}

/// Random CSG scenes, then random region edits (offsets with a smooth falloff, noise), across
/// chunk borders and far from the origin: the invariants hold after every write, and undo
/// restores the exact volume.
fn random_region_edits(seed: u64, far: bool) -> Result<(), TestCaseError> {
    let mut rng = seed;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let shift = if far { DVec3::splat(1_000_000.0) } else { DVec3::ZERO };
    let mut v = Volume::new();
    let settings = EditSettings { parallel: false, ..Default::default() };
    for _ in 0..6 {
        let c = shift + DVec3::new(next(), next(), next()) * 40.0;
        let op = if next() < 0.7 { CsgOp::Add } else { CsgOp::Subtract };
        v.apply(op, &Sphere::new(c, 3.0 + next() * 10.0).unwrap(), &settings).unwrap();
    }
    for k in 0..6 {
        let c = shift + DVec3::new(next(), next(), next()) * 40.0;
        let radius = 1.0 + next() * 12.0;
        let amount = (next() - 0.5) * 4.0;
        let before = v.clone();
        let mut r = v.read_region(c - radius, c + radius, 2).unwrap();
        for z in 0..r.dims[2] {
            for y in 0..r.dims[1] {
                for x in 0..r.dims[0] {
                    let i = r.index(x, y, z);
                    let t = ((r.grid_point(x, y, z) - c).length() / radius).min(1.0);
                    let w = 3.0 * t.powi(4) - 4.0 * t.powi(3) + 1.0;
                    if w > 0.0 {
                        r.weight[i] = w as f32;
                        let noise = if k % 2 == 0 { (next() - 0.5) * 0.8 } else { 0.0 };
                        r.phi[i] -= (amount * w + noise) as f32;
                    }
                }
            }
        }
        let report = v.write_region(&r).map_err(|e| TestCaseError::fail(e.to_string()))?;
        if let Err(e) = v.check_invariants() {
            return Err(TestCaseError::fail(format!("region edit {k} at {c}, radius {radius}: {e}")));
        }
        let mut undone = v.clone();
        undone.restore(report.undo);
        prop_assert!(undone == before, "undo of region edit {} restores the volume", k);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    #[test]
    fn random_region_edits_keep_every_invariant(seed in 1u64.., far in any::<bool>()) {
        random_region_edits(seed, far)?;
    }
}

#[test]
fn a_field_that_is_zero_on_nodes_decides_them_inside_on_every_axis() {
    // An operator that writes the plane z = 16 through a row of nodes (and across a chunk
    // border): nodes on the plane have φ = 0 exactly.
    let c = DVec3::new(16.0, 16.0, 16.0);
    let mut v = sphere_volume(c, 11.0);
    let mut r = v.read_region(c - 8.0, c + 8.0, 1).unwrap();
    for z in 0..r.dims[2] {
        for y in 0..r.dims[1] {
            for x in 0..r.dims[0] {
                let i = r.index(x, y, z);
                r.weight[i] = 1.0;
                r.phi[i] = (r.grid_point(x, y, z).z - 16.0) as f32;
            }
        }
    }
    v.write_region(&r).unwrap();
    v.check_invariants().unwrap();
    for x in 10..23 {
        assert!(v.node_inside(I64Vec3::new(x, 16, 16)), "a node on the plane is inside");
        assert!(!v.node_inside(I64Vec3::new(x, 16, 17)));
    }
}

#[test]
fn a_region_read_within_a_reach_matches_the_full_read_there_and_keeps_every_sign() {
    use strata_volume::tools::{FAR, Reach};
    let v = sphere_volume(DVec3::new(20.3, 19.8, 20.1), 9.0);
    let (min, max) = (DVec3::splat(6.0), DVec3::splat(34.0));
    let full = v.read_region(min, max, 2).unwrap();
    for reach in [
        Reach::ball(DVec3::new(29.0, 20.0, 20.0), 5.0, 3.0),
        Reach::ball(DVec3::new(29.0, 20.0, 20.0), 5.0, 6.0),
        Reach::ball(DVec3::new(29.0, 20.0, 20.0), 5.0, 9.0),
        Reach::Capsule { a: DVec3::new(12.0, 20.0, 20.0), b: DVec3::new(28.0, 22.0, 19.0), radius: 3.0, depth: 4.5 },
    ] {
        let Reach::Capsule { depth, .. } = reach else { unreachable!() };
        let part = v.read_region_within(min, max, 2, reach).unwrap();
        assert_eq!(part.dims, full.dims);
        let (mut inside_reach, mut outside) = (0, 0);
        for z in 0..full.dims[2] {
            for y in 0..full.dims[1] {
                for x in 0..full.dims[0] {
                    let i = full.index(x, y, z);
                    assert_eq!(part.was_inside(i), full.was_inside(i), "every node keeps its state");
                    if part.phi[i].abs() == FAR {
                        outside += 1;
                    } else {
                        // Within the depth the field is the full read's (exactly in the band;
                        // beyond it the propagation's paths differ: a little slack); beyond the
                        // depth it is never below the depth.
                        let (a, b) = (part.phi[i].abs(), full.phi[i].abs());
                        if b <= 3.0 {
                            assert_eq!(a, b, "in the band");
                        } else if b <= depth as f32 {
                            assert!((a - b).abs() <= 0.15, "within the depth: {a} vs {b}");
                        } else {
                            assert!(a >= depth as f32 - 0.15, "beyond it never below the depth: {a} vs {b}");
                        }
                        inside_reach += 1;
                    }
                }
            }
        }
        assert!(inside_reach > 100 && outside > 1000, "{inside_reach} nodes read, {outside} skipped");
    }
    assert!(v.read_region_within(min, max, 2, Reach::ball(DVec3::NAN, 3.0, 3.0)).is_err());
}
