//! A sculpting session across chunk borders and negative coordinates: strokes, erasures, undo
//! of everything, redo of everything.

use glam::DVec3;
use strata_volume::brush::{Capsule, Sphere};
use strata_volume::{Axis, Volume};

#[test]
fn a_session_of_strokes_undoes_to_empty_and_redoes_to_the_same_volume() {
    let mut v = Volume::new();
    let mut history = Vec::new();
    // A spiral stroke of overlapping capsules through eight chunks around the origin.
    let mut last = DVec3::new(-20.0, -3.0, -11.0);
    for i in 1..60 {
        let a = i as f64 * 0.35;
        let p = DVec3::new(18.0 * a.cos(), 0.9 * i as f64 - 25.0, 18.0 * a.sin());
        history.push(v.add(&Capsule::new(last, p, 3.5).unwrap()).unwrap().undo);
        last = p;
    }
    // Erase bites out of it.
    for i in 0..12 {
        let c = DVec3::new(-15.0 + 3.0 * i as f64, -10.0 + 2.0 * i as f64, 0.5 * i as f64);
        history.push(v.subtract(&Sphere::new(c, 4.0).unwrap()).unwrap().undo);
    }
    v.check_invariants().unwrap();
    let volumes = Axis::ALL.map(|a| v.measured_volume(a));
    for w in volumes {
        assert!((w - volumes[0]).abs() / volumes[0] < 0.01, "axes measure {volumes:?}");
    }
    let sculpted = v.clone();
    let mut redo = Vec::new();
    while let Some(r) = history.pop() {
        redo.push(v.restore(r));
    }
    assert!(v.is_empty(), "undoing every edit leaves nothing");
    while let Some(r) = redo.pop() {
        v.restore(r);
    }
    assert_eq!(v, sculpted);
}
