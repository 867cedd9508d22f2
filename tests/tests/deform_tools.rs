//! Grab, pinch and clay, measured: the apex of a grabbed bump follows the drag, a drag of five
//! radii leaves a closed mesh, pinch narrows a ridge, clay meets the model in a fillet; every
//! edit keeps the invariants and undoes exactly.

use glam::DVec3;
use strata_mesh::checks;
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::tools::{Dab, ToolError, clay, grab, pinch};
use strata_volume::{EditReport, Volume};

/// A floor whose top is at z = 16.3, 60 cells square.
fn floor() -> Volume {
    let mut v = Volume::new();
    v.add(&Cuboid::new(DVec3::new(32.0, 32.0, 8.3), DVec3::new(30.0, 30.0, 8.0)).unwrap()).unwrap();
    v
}

/// The height of the topmost surface above `(x, y)`.
fn height(v: &Volume, x: f64, y: f64) -> f64 {
    let from = 120.0;
    from - v.raycast(DVec3::new(x, y, from), -DVec3::Z, 200.0).expect("the ray meets the solid").t
}

/// Checks the invariants, the closed marching-cubes mesh, and that undo restores `before`.
fn check(v: &Volume, before: &Volume, report: EditReport) {
    v.check_invariants().unwrap();
    checks::check_closed_manifold(
        &strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::default())
            .expect("marching cubes meshes every volume"),
    )
    .unwrap();
    let mut undone = v.clone();
    undone.restore(report.undo);
    assert!(undone == *before, "undo restores the volume exactly");
}

#[test]
fn a_grabbed_bump_moves_its_apex_by_the_drag() {
    let mut v = floor();
    let apex = DVec3::new(32.2, 31.9, 20.3);
    v.add(&Sphere::new(apex - DVec3::Z * 4.0, 4.0).unwrap()).unwrap();
    let h0 = height(&v, apex.x, apex.y);
    assert!((h0 - apex.z).abs() < 0.05, "the bump's apex is at {h0}");
    for (drag, dabs) in [(DVec3::new(0.0, 0.0, 3.0), 1), (DVec3::new(0.0, 0.0, 6.0), 4)] {
        let mut w = v.clone();
        // The stroke: `dabs` moves of the pointer, the brush following the apex.
        let mut centre = apex;
        let mut first: Option<EditReport> = None;
        for _ in 0..dabs {
            let step = drag / dabs as f64;
            let report = grab(&mut w, &Dab::new(centre, 8.0, 1.0).unwrap(), step).unwrap();
            w.check_invariants().unwrap();
            first = Some(match first {
                None => report,
                Some(f) => f.then(report),
            });
            centre += step;
        }
        let moved = height(&w, apex.x, apex.y) - h0;
        eprintln!("grab by {}: apex moved {moved:.3}", drag.z);
        assert!((moved - drag.z).abs() <= 0.25, "apex moved {moved}, dragged {}", drag.z);
        // The floor outside the brush did not move.
        assert_eq!(height(&w, 50.0, 50.0), height(&v, 50.0, 50.0));
        check(&w, &v, first.unwrap());
    }
}

#[test]
fn a_drag_of_five_radii_leaves_a_closed_surface() {
    for (drag, dabs) in [(DVec3::new(0.0, 0.0, 30.0), 1), (DVec3::new(21.0, 0.0, 21.0), 12)] {
        let mut v = floor();
        let before = v.clone();
        let mut centre = DVec3::new(32.0, 32.0, 16.3);
        let mut all: Option<EditReport> = None;
        for _ in 0..dabs {
            let step = drag / dabs as f64;
            let report = grab(&mut v, &Dab::new(centre, 6.0, 1.0).unwrap(), step).unwrap();
            all = Some(match all {
                None => report,
                Some(a) => a.then(report),
            });
            centre += step;
        }
        // The pulled spike reaches the end of the drag (within the blur of its tip) and stays
        // one closed piece of surface.
        let end = 32.0 + drag.x;
        let tip = (0..=16).map(|i| height(&v, end - 4.0 + i as f64 * 0.5, 32.0)).fold(f64::MIN, f64::max);
        eprintln!("drag {drag}: tip at {tip:.2}");
        assert!(tip > 16.3 + drag.z - 1.5, "the tip is at {tip}");
        check(&v, &before, all.unwrap());
    }
}

#[test]
fn pinch_narrows_a_ridge() {
    // A ridge along y, 6 cells wide and 4 high, on the floor.
    let mut v = floor();
    v.add(&Cuboid::new(DVec3::new(32.1, 32.0, 18.3), DVec3::new(3.0, 20.0, 2.0)).unwrap()).unwrap();
    let before = v.clone();
    // The ridge's width at height 18.3 across its middle.
    let width = |v: &Volume| {
        let left = v.raycast(DVec3::new(10.0, 32.3, 18.3), DVec3::X, 40.0).unwrap().t + 10.0;
        let right = 54.0 - v.raycast(DVec3::new(54.0, 32.3, 18.3), -DVec3::X, 40.0).unwrap().t;
        right - left
    };
    let w0 = width(&v);
    let mut all: Option<EditReport> = None;
    for _ in 0..3 {
        let report =
            pinch(&mut v, &Dab::new(DVec3::new(32.1, 32.0, 20.3), 7.0, 1.0).unwrap(), Some(DVec3::Y), 0.5).unwrap();
        all = Some(match all {
            None => report,
            Some(a) => a.then(report),
        });
    }
    let w1 = width(&v);
    eprintln!("pinch: ridge width {w0:.3} -> {w1:.3}");
    assert!(w1 < w0 - 0.5, "the ridge narrowed from {w0} to {w1}");
    // Far along the ridge, outside the brush, nothing moved.
    assert_eq!(height(&v, 32.1, 48.0), height(&before, 32.1, 48.0));
    check(&v, &before, all.unwrap());
}

#[test]
fn clay_meets_the_floor_in_a_fillet() {
    let centre = DVec3::new(32.2, 31.9, 16.3);
    for fillet in [0.0, 3.0] {
        let mut v = floor();
        let before = v.clone();
        let report = clay(&mut v, &Dab::new(centre, 4.0, 1.0).unwrap(), fillet, false).unwrap();
        // The ball's top.
        assert!((height(&v, centre.x, centre.y) - 20.3).abs() < 0.15, "top {}", height(&v, centre.x, centre.y));
        // Beside the ball's foot (5 cells out) the floor rises only with a fillet.
        let foot = height(&v, centre.x + 5.0, centre.y) - 16.3;
        eprintln!("clay fillet {fillet}: rise 5 cells out {foot:.3}");
        if fillet == 0.0 {
            assert!(foot.abs() < 0.05, "no fillet: the floor stays flat ({foot})");
        } else {
            assert!(foot > 0.2, "a fillet lifts the floor beside the ball ({foot})");
        }
        // Far away the floor is untouched.
        assert_eq!(height(&v, 50.0, 50.0), height(&before, 50.0, 50.0));
        check(&v, &before, report);
    }
    // Erasing carves a dimple with a rounded rim.
    let mut v = floor();
    let before = v.clone();
    let report = clay(&mut v, &Dab::new(centre, 4.0, 1.0).unwrap(), 3.0, true).unwrap();
    assert!((height(&v, centre.x, centre.y) - 12.3).abs() < 0.15);
    let rim = 16.3 - height(&v, centre.x + 4.5, centre.y);
    assert!(rim > 0.2, "the rim is rounded ({rim})");
    check(&v, &before, report);
}

#[test]
fn bad_deformations_are_errors_not_panics() {
    let mut v = floor();
    let before = v.clone();
    let dab = Dab::new(DVec3::new(32.0, 32.0, 16.3), 5.0, 1.0).unwrap();
    for drag in [DVec3::splat(f64::NAN), DVec3::new(f64::INFINITY, 0.0, 0.0)] {
        assert!(matches!(grab(&mut v, &dab, drag), Err(ToolError::BadParameter { .. })));
    }
    // A drag far beyond what a region may hold is refused before anything is read.
    assert!(grab(&mut v, &dab, DVec3::new(1e9, 0.0, 0.0)).is_err());
    assert!(pinch(&mut v, &dab, Some(DVec3::NAN), 0.5).is_err());
    assert!(pinch(&mut v, &dab, None, 1.5).is_err());
    assert!(pinch(&mut v, &dab, None, -1.5).is_err());
    assert!(pinch(&mut v, &dab, None, f64::NAN).is_err());
    assert!(clay(&mut v, &dab, f64::NAN, false).is_err());
    assert!(clay(&mut v, &dab, -1.0, false).is_err());
    assert_eq!(v, before, "refused edits change nothing");
    // A zero drag changes nothing.
    assert!(grab(&mut v, &dab, DVec3::ZERO).unwrap().changed.is_empty());
    assert_eq!(v, before);
}

#[test]
fn every_tool_deep_inside_the_solid_or_in_empty_space_keeps_it_so() {
    use strata_volume::tools::{Smoothing, flatten, inflate, smooth};
    // A region with no crossing at all reads one far distance everywhere; no operator may turn
    // it into a surface by overflowing (a Laplacian of the largest float is NaN).
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::splat(40.0), 30.0).unwrap()).unwrap();
    for at in [DVec3::splat(40.0), DVec3::splat(200.0)] {
        let before = v.clone();
        let dab = Dab::new(at, 5.0, 1.0).unwrap();
        for method in [Smoothing::VolumePreserving, Smoothing::Laplacian, Smoothing::Endpoints] {
            smooth(&mut v, &dab, method, 3).unwrap();
        }
        inflate(&mut v, &dab, 1.0).unwrap();
        flatten(&mut v, &dab).unwrap();
        grab(&mut v, &dab, DVec3::new(3.0, 0.0, 0.0)).unwrap();
        pinch(&mut v, &dab, None, 0.8).unwrap();
        clay(&mut v, &Dab::new(at, 5.0, 0.5).unwrap(), 2.0, at.x > 100.0).unwrap();
        v.check_invariants().unwrap();
        assert!(v == before, "dabs at {at} changed nothing");
    }
    // Clay in empty space adds its ball, of the strength times the radius.
    clay(&mut v, &Dab::new(DVec3::splat(200.0), 5.0, 0.5).unwrap(), 2.0, false).unwrap();
    assert!(v.node_inside(glam::I64Vec3::splat(200)) && v.node_inside(glam::I64Vec3::new(202, 200, 200)));
    assert!(!v.node_inside(glam::I64Vec3::new(203, 200, 200)));
}
