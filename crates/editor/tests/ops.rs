//! Recorded edit operations replay bit for bit: random strokes of every tool (grab included),
//! mirrored, with dab positions on the grid and off it, on a turned and scaled layer, are
//! recorded by one editor and replayed by another starting from the same scene; both end with
//! the same chunk digests, equal to an editor that made the same strokes without recording,
//! and reverting the recorded operations in reverse gives the starting scene back exactly.
//!
//! Cases default to 24; `PROPTEST_CASES=200 cargo test --release -p strata-editor --test ops`
//! searches longer.

use std::time::Duration;

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use strata_editor::file::chunk_digests;
use strata_editor::{
    Buttons, Editor, LayerTransform, Modifiers, StampSettings, StampSource, StampStroke, ToolKind, ToolPose,
};
use strata_volume::CsgOp;
use strata_volume::brush::Sphere;
use strata_volume::tools::BuiltinStamp;

#[derive(Clone, Debug)]
struct StrokeCase {
    tool: u8,
    radius: u8,
    points: Vec<[i8; 3]>,
    /// Positions on the grid (whole cells) or at quarter cells.
    snapped: bool,
    inverted: bool,
    smooth: bool,
    mirror: u8,
    pressure: u8,
}

fn stroke_case() -> impl Strategy<Value = StrokeCase> {
    (
        0..ToolKind::ALL.len() as u8,
        2..12u8,
        prop::collection::vec([-40..40i8, -40..40i8, -40..40i8], 1..5),
        any::<bool>(),
        any::<bool>(),
        prop::bool::weighted(0.15),
        0..8u8,
        1..5u8,
    )
        .prop_map(|(tool, radius, points, snapped, inverted, smooth, mirror, pressure)| StrokeCase {
            tool,
            radius,
            points,
            snapped,
            inverted,
            smooth,
            mirror,
            pressure,
        })
}

/// A scene with a ball of clay on one layer, turned and scaled when `turned`.
fn start(turned: bool) -> Editor {
    let mut e = Editor::default();
    if turned {
        e.scene.layers[0].transform =
            LayerTransform::new(DVec3::new(0.5, -1.0, 2.0), DQuat::from_rotation_y(0.7), 1.25).unwrap();
    }
    e.apply(0, CsgOp::Add, &Sphere::new(DVec3::ZERO, 9.0).unwrap()).unwrap();
    e.clear_history();
    e
}

fn run_stroke(e: &mut Editor, s: &StrokeCase) {
    e.tool.kind = ToolKind::ALL[s.tool as usize % ToolKind::ALL.len()];
    e.tool.radius = s.radius as f64 / 2.0;
    e.tool.strength = 0.5;
    e.tool.symmetry = [s.mirror & 1 != 0, s.mirror & 2 != 0, s.mirror & 4 != 0];
    e.tool.symmetry_center = DVec3::new(1.0, 0.0, -2.0);
    // Stamps of every built-in image, sprayed (following the stroke or not) or dragged out,
    // turned.
    e.tool.stamp = StampSettings {
        source: StampSource::Builtin(BuiltinStamp::ALL[s.points.len() % BuiltinStamp::ALL.len()]),
        stroke: if s.radius.is_multiple_of(2) { StampStroke::Drag } else { StampStroke::Spray },
        follow_stroke: s.pressure.is_multiple_of(2),
        angle: s.radius as f64 * 17.0,
    };
    let scale = if s.snapped { 4.0 } else { 16.0 };
    let buttons = Buttons { primary: !s.inverted, secondary: s.inverted };
    let modifiers = Modifiers { inverted: false, smooth: s.smooth };
    let at = |p: &[i8; 3]| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) / scale * 4.0;
    for p in &s.points {
        let pose = ToolPose {
            position: at(p),
            orientation: DQuat::from_rotation_z(p[0] as f64 * 0.1),
            pressure: s.pressure as f64 / 4.0,
            buttons,
            modifiers,
        };
        // Refusals change nothing in either editor.
        let _ = e.frame(&pose, Duration::ZERO);
    }
    let _ = e.frame(&ToolPose::at(at(s.points.last().unwrap()), false), Duration::ZERO);
}

fn digests(e: &Editor) -> Vec<strata_editor::file::ChunkDigest> {
    chunk_digests(&e.scene).unwrap()
}

fn check(strokes: &[StrokeCase], turned: bool) -> Result<(), TestCaseError> {
    let mut recorder = start(turned);
    recorder.record_ops(true);
    let mut plain = start(turned);
    let mut replayer = start(turned);
    let before = digests(&recorder);
    let mut undos = Vec::new();
    for s in strokes {
        run_stroke(&mut recorder, s);
        run_stroke(&mut plain, s);
        for recorded in recorder.take_ops() {
            // Through the wire format, as the network sends them.
            let bytes = postcard::to_allocvec(&recorded.op).unwrap();
            let op: strata_editor::EditOp = postcard::from_bytes(&bytes).unwrap();
            prop_assert_eq!(&op, &recorded.op);
            replayer.replay(&op).unwrap();
            undos.push(recorded.undo);
        }
        prop_assert!(recorder.history().undo_len() == 0, "recording leaves the local history empty");
    }
    let after = digests(&recorder);
    prop_assert_eq!(&after, &digests(&plain), "recording changed what the strokes did");
    prop_assert_eq!(&after, &digests(&replayer), "a replay differs from the recorded strokes");
    recorder.scene.layers[0].volume.check_invariants().map_err(|e| TestCaseError::fail(e.to_string()))?;
    for undo in undos.into_iter().rev() {
        recorder.revert(undo).unwrap();
    }
    prop_assert_eq!(digests(&recorder), before, "reverting every operation did not restore the scene");
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(24)
    ))]

    #[test]
    fn recorded_operations_replay_bit_for_bit(strokes in prop::collection::vec(stroke_case(), 1..6), turned in any::<bool>()) {
        check(&strokes, turned)?;
    }
}

#[test]
fn a_replay_of_a_bad_operation_is_refused_and_changes_nothing() {
    let mut e = start(false);
    e.record_ops(true);
    run_stroke(
        &mut e,
        &StrokeCase {
            tool: 1,
            radius: 6,
            points: vec![[0, 0, 36], [8, 0, 36]],
            snapped: true,
            inverted: false,
            smooth: false,
            mirror: 0,
            pressure: 4,
        },
    );
    let ops = e.take_ops();
    assert!(!ops.is_empty());
    let mut other = start(false);
    let before = digests(&other);
    let mut op = ops[0].op.clone();
    op.surface = 3;
    assert!(other.replay(&op).is_err());
    let mut op = ops[0].op.clone();
    op.tool.material = 200;
    assert!(other.replay(&op).is_err());
    // A dab that cannot be made (a zero radius) after good ones: nothing stays applied.
    let mut op = ops[0].op.clone();
    op.dabs.push(op.dabs[0]);
    op.tool.radius = 0.0;
    assert!(other.replay(&op).is_err());
    assert_eq!(digests(&other), before);
}

#[test]
fn a_frame_of_more_dabs_than_an_operation_holds_is_recorded_as_several() {
    let mut e = start(false);
    e.record_ops(true);
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 0.5;
    // The smallest spacing (a hundredth of the radius): a drag of 25 units is 5,000 dabs.
    e.tool.spacing = 0.0;
    let down = Buttons { primary: true, secondary: false };
    let at = |x: f64| ToolPose { position: DVec3::new(x, 9.5, 0.0), buttons: down, ..ToolPose::default() };
    e.frame(&at(-12.5), Duration::ZERO).unwrap();
    let report = e.frame(&at(12.5), Duration::ZERO).unwrap();
    e.frame(&ToolPose::at(DVec3::new(12.5, 9.5, 0.0), false), Duration::ZERO).unwrap();
    assert!(report.dabs > strata_editor::op::MAX_OP_DABS, "{} dabs", report.dabs);
    let ops = e.take_ops();
    assert_eq!(ops.len(), 3, "one operation for the first frame, two for the second");
    assert!(ops.iter().all(|o| o.op.dabs.len() <= strata_editor::op::MAX_OP_DABS));
    assert!(ops.iter().all(|o| o.op.stroke == ops[0].op.stroke), "one stroke");
    let mut other = start(false);
    for o in &ops {
        other.replay(&o.op).unwrap();
    }
    assert_eq!(digests(&other), digests(&e));
    let before = digests(&start(false));
    for o in ops.into_iter().rev() {
        e.revert(o.undo).unwrap();
    }
    assert_eq!(digests(&e), before);
}
