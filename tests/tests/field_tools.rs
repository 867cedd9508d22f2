//! Random dabs of every field tool (inflate, smooth both ways, flatten) on random CSG scenes,
//! across chunk borders and a million cells from the origin: after every dab the invariants
//! hold, the marching-cubes mesh is closed and edge-manifold, and undo restores the exact
//! volume.

use glam::DVec3;
use proptest::prelude::*;
use strata_mesh::{checks, mesh_volume};
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::tools::{Dab, Smoothing, flatten, inflate, smooth};
use strata_volume::{CsgOp, EditSettings, Volume};

#[derive(Clone, Debug)]
enum Tool {
    Inflate(f64),
    Smooth(bool, u32),
    Flatten,
}

fn tool() -> impl Strategy<Value = Tool> {
    prop_oneof![
        (-3.0..3.0f64).prop_map(Tool::Inflate),
        (any::<bool>(), 1..8u32).prop_map(|(vp, passes)| Tool::Smooth(vp, passes)),
        Just(Tool::Flatten),
    ]
}

fn point() -> impl Strategy<Value = DVec3> {
    (0.0..40.0f64, 0.0..40.0f64, 0.0..40.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn run(scene: &[(bool, DVec3, f64)], dabs: &[(Tool, DVec3, f64, f64)], far: bool) -> Result<(), TestCaseError> {
    let shift = if far { DVec3::splat(1_000_000.0) } else { DVec3::ZERO };
    let mut v = Volume::new();
    let settings = EditSettings { parallel: false, ..Default::default() };
    for (i, &(boxy, c, r)) in scene.iter().enumerate() {
        let op = if i % 3 == 2 { CsgOp::Subtract } else { CsgOp::Add };
        if boxy {
            v.apply(op, &Cuboid::new(shift + c, DVec3::splat(r)).unwrap(), &settings).unwrap();
        } else {
            v.apply(op, &Sphere::new(shift + c, r).unwrap(), &settings).unwrap();
        }
    }
    for (k, (t, c, radius, strength)) in dabs.iter().enumerate() {
        let dab = Dab::new(shift + *c, *radius, *strength).unwrap();
        let before = v.clone();
        let report = match *t {
            Tool::Inflate(a) => inflate(&mut v, &dab, a),
            Tool::Smooth(vp, passes) => {
                smooth(&mut v, &dab, if vp { Smoothing::VolumePreserving } else { Smoothing::Laplacian }, passes)
            }
            Tool::Flatten => flatten(&mut v, &dab),
        }
        .map_err(|e| TestCaseError::fail(format!("dab {k}: {e}")))?;
        if let Err(e) = v.check_invariants() {
            return Err(TestCaseError::fail(format!("dab {k} ({t:?} at {c}, radius {radius}): {e}")));
        }
        let mut undone = v.clone();
        undone.restore(report.undo);
        prop_assert!(undone == before, "undo of dab {} restores the volume", k);
    }
    if !far {
        checks::check_closed_manifold(&mesh_volume(&v)).map_err(|e| TestCaseError::fail(format!("mesh: {e}")))?;
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: std::env::var("PROPTEST_CASES").ok().and_then(|c| c.parse().ok()).unwrap_or(16), max_shrink_iters: 50, ..ProptestConfig::default() })]

    #[test]
    fn random_dabs_of_every_field_tool_keep_every_invariant(
        scene in proptest::collection::vec((any::<bool>(), point(), 2.0..14.0f64), 1..6),
        dabs in proptest::collection::vec((tool(), point(), 1.0..12.0f64, 0.0..=1.0f64), 1..8),
        far in any::<bool>(),
    ) {
        run(&scene, &dabs, far)?;
    }
}
