//! Every scene the editor can build saves and reloads: random editor sessions (layers,
//! transforms, strokes of every brush shape, mesh imports with vertices on the grid, undo and
//! redo, renames, hidden and locked layers, transforms set through the editor and wrongly
//! through the public fields, field-tool strokes, mirroring and line strokes) are saved, loaded
//! and compared.
//!
//! Cases default to 48; `PROPTEST_CASES=500 cargo test --release -p strata-editor --test
//! sessions` runs a longer search.

use std::time::Duration;

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use strata_editor::file::{self, load, save};
use strata_editor::{BrushShape, Buttons, Editor, Layer, LayerTransform, Modifiers, Scene, ToolKind, ToolPose};
use strata_volume::brush::{MeshBrush, MeshRule};

#[derive(Clone, Debug)]
enum Step {
    AddLayer,
    Select(usize),
    Transform {
        translation: [i8; 3],
        turn: u8,
        scale_log2: i8,
    },
    /// A transform written straight into the public fields (zero rotation, NaN scale, …).
    BadTransform(u8),
    /// A transform through the editor (an undo step; `merge` continues a drag).
    SetTransform {
        translation: [i8; 3],
        turn: u8,
        merge: bool,
    },
    /// A stroke of a field tool (0 smooth, 1 inflate, 2 flatten).
    FieldStroke {
        tool: u8,
        radius: u8,
        from: [i8; 3],
        to: [i8; 3],
        inverted: bool,
    },
    /// Mirroring across a layer-grid plane turned on or off.
    Mirror(u8),
    /// A line-tool stroke.
    Line {
        from: [i8; 3],
        to: [i8; 3],
    },
    Stroke {
        shape: u8,
        radius: u8,
        from: [i8; 3],
        to: [i8; 3],
        erase: bool,
    },
    Import {
        corner: [i8; 3],
        size: [u8; 3],
    },
    Undo,
    Redo,
    Rename(u8),
    ToggleVisible,
    ToggleLocked,
}

fn step() -> impl Strategy<Value = Step> {
    let v3 = || [any::<i8>(), any::<i8>(), any::<i8>()];
    prop_oneof![
        1 => Just(Step::AddLayer),
        1 => (0..4usize).prop_map(Step::Select),
        1 => (v3(), 0..8u8, -3..3i8).prop_map(|(translation, turn, scale_log2)| Step::Transform { translation, turn, scale_log2 }),
        1 => (0..5u8).prop_map(Step::BadTransform),
        1 => (v3(), 0..8u8, any::<bool>()).prop_map(|(translation, turn, merge)| Step::SetTransform { translation, turn, merge }),
        3 => (0..3u8, 2..10u8, v3(), v3(), any::<bool>()).prop_map(|(tool, radius, from, to, inverted)| Step::FieldStroke { tool, radius, from, to, inverted }),
        1 => (0..3u8).prop_map(Step::Mirror),
        1 => (v3(), v3()).prop_map(|(from, to)| Step::Line { from, to }),
        6 => (0..4u8, 1..12u8, v3(), v3(), any::<bool>()).prop_map(|(shape, radius, from, to, erase)| Step::Stroke { shape, radius, from, to, erase }),
        1 => (v3(), [1..12u8, 1..12u8, 1..12u8]).prop_map(|(corner, size)| Step::Import { corner, size }),
        2 => Just(Step::Undo),
        1 => Just(Step::Redo),
        1 => any::<u8>().prop_map(Step::Rename),
        1 => Just(Step::ToggleVisible),
        1 => Just(Step::ToggleLocked),
    ]
}

fn p(v: [i8; 3]) -> DVec3 {
    DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) / 4.0
}

/// A box mesh with corners on an eighth-cell grid: faces on grid planes, as an imported CAD
/// model has.
fn box_mesh(corner: [i8; 3], size: [u8; 3]) -> MeshBrush {
    let lo = DVec3::new(corner[0] as f64, corner[1] as f64, corner[2] as f64) / 8.0;
    let (v, t) = strata_tests::box_mesh(lo, DVec3::new(size[0] as f64, size[1] as f64, size[2] as f64));
    MeshBrush::new(&v, &t, MeshRule::EvenOdd).unwrap()
}

fn run(steps: &[Step]) -> Result<(), TestCaseError> {
    let mut e = Editor::default();
    for s in steps {
        let layers = e.scene.layers.len();
        match *s {
            Step::AddLayer => {
                e.scene.layers.push(Layer::new(format!("Layer {}", layers + 1)));
                e.reset_caches();
            }
            Step::Select(i) => e.active_layer = i % layers.max(1),
            Step::Transform { translation, turn, scale_log2 } => {
                let q = DQuat::from_rotation_y(turn as f64 * std::f64::consts::FRAC_PI_4);
                let t = LayerTransform::new(p(translation), q, (scale_log2 as f64).exp2()).unwrap();
                if let Some(l) = e.scene.layers.get_mut(e.active_layer) {
                    l.transform = t;
                }
            }
            Step::BadTransform(k) => {
                if let Some(l) = e.scene.layers.get_mut(e.active_layer) {
                    match k {
                        0 => l.transform.rotation = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0),
                        1 => l.transform.scale = f64::NAN,
                        2 => l.transform.scale = -2.0,
                        3 => l.transform.translation.x = f64::INFINITY,
                        _ => l.transform.rotation = DQuat::from_xyzw(0.0, 3.0, 0.0, 4.0),
                    }
                }
            }
            Step::SetTransform { translation, turn, merge } => {
                let q = DQuat::from_rotation_y(turn as f64 * std::f64::consts::FRAC_PI_4);
                let t = LayerTransform::new(p(translation), q, 1.0).unwrap();
                // Refused on a missing layer; otherwise an undo step.
                let _ = e.set_layer_transform(e.active_layer, t, merge);
            }
            Step::FieldStroke { tool, radius, from, to, inverted } => {
                let field: Vec<ToolKind> = ToolKind::ALL.into_iter().filter(|k| k.is_field_tool()).collect();
                e.tool.kind = field[tool as usize % field.len()];
                // At most 5 cells of the layer's grid, so a small-scale layer does not make each
                // dab read a huge region (time, not correctness).
                let scale = e.scene.layers.get(e.active_layer).map_or(1.0, |l| l.transform.scale);
                let scale = if scale.is_finite() && scale > 0.0 { scale } else { 1.0 };
                e.tool.radius = (radius as f64 / 2.0).min(5.0 * scale);
                let buttons = Buttons { primary: !inverted, secondary: inverted };
                for k in 0..=2 {
                    let at = p(from).lerp(p(to), k as f64 / 2.0);
                    let pose = ToolPose {
                        position: at,
                        orientation: DQuat::IDENTITY,
                        pressure: 1.0,
                        buttons,
                        ..ToolPose::default()
                    };
                    let _ = e.frame(&pose, Duration::ZERO);
                }
                let _ = e.frame(&ToolPose::at(p(to), false), Duration::ZERO);
            }
            Step::Mirror(axis) => {
                let a = axis as usize % 3;
                e.tool.symmetry[a] = !e.tool.symmetry[a];
                e.tool.symmetry_center = DVec3::new(4.0, 2.0, 8.0);
            }
            Step::Line { from, to } => {
                e.tool.kind = ToolKind::Add;
                e.tool.radius = 1.5;
                let _ = e.line_stroke(p(from), p(to), 1.0, Modifiers::default());
            }
            Step::Stroke { shape, radius, from, to, erase } => {
                e.tool.shape = [BrushShape::Sphere, BrushShape::Box, BrushShape::Capsule, BrushShape::Cylinder]
                    [shape as usize % 4];
                e.tool.radius = radius as f64 / 2.0;
                e.tool.kind = if erase { ToolKind::Erase } else { ToolKind::Add };
                let buttons = Buttons { primary: true, secondary: false };
                for k in 0..=3 {
                    let at = p(from).lerp(p(to), k as f64 / 3.0);
                    let pose = ToolPose {
                        position: at,
                        orientation: DQuat::IDENTITY,
                        pressure: 1.0,
                        buttons,
                        ..ToolPose::default()
                    };
                    // Refusals (a locked layer, a bad transform) leave the scene as it was.
                    let _ = e.frame(&pose, Duration::ZERO);
                }
                let _ = e.frame(&ToolPose::at(p(to), false), Duration::ZERO);
            }
            Step::Import { corner, size } => {
                // Refused on a locked layer; otherwise one undo step.
                let _ = e.apply(e.active_layer, strata_volume::CsgOp::Add, &box_mesh(corner, size));
            }
            Step::Undo => {
                e.undo();
            }
            Step::Redo => {
                e.redo();
            }
            Step::Rename(c) => {
                if let Some(l) = e.scene.layers.get_mut(e.active_layer) {
                    l.name.push(char::from_u32(0x20 + c as u32 * 37 % 0x2000).unwrap_or('?'));
                }
            }
            Step::ToggleVisible => {
                if let Some(l) = e.scene.layers.get_mut(e.active_layer) {
                    l.visible = !l.visible;
                }
            }
            Step::ToggleLocked => {
                if let Some(l) = e.scene.layers.get_mut(e.active_layer) {
                    l.locked = !l.locked;
                }
            }
        }
        for (i, l) in e.scene.layers.iter().enumerate() {
            if let Err(v) = l.volume.check_invariants() {
                return Err(TestCaseError::fail(format!("after {s:?}: layer {i}: {v}")));
            }
        }
    }
    let dir = std::env::temp_dir().join(format!("strata-sessions-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!(
        "{:x}.strata",
        steps.len() as u64 * 7919 + steps.iter().map(|s| format!("{s:?}").len() as u64).sum::<u64>()
    ));
    let report = save(&e.scene, &path).map_err(|err| TestCaseError::fail(err.to_string()))?;
    // Only transforms written wrongly through the fields need a repair.
    let mut expected: Scene = e.scene.clone();
    let repairs = file::validate_scene(&mut expected);
    prop_assert_eq!(&report, &repairs);
    prop_assert!(report.repairs.iter().all(|r| r.contains("transform")), "{}", report);
    let back = load(&path).map_err(|err| TestCaseError::fail(format!("the saved scene does not reopen: {err}")))?;
    prop_assert!(back.report.is_clean(), "{}", back.report);
    prop_assert_eq!(back.scene, expected);
    let _ = std::fs::remove_file(&path);
    Ok(())
}

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(48)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), max_shrink_iters: 100, ..ProptestConfig::default() })]

    #[test]
    fn every_scene_an_editor_session_builds_saves_and_reopens_equal(steps in proptest::collection::vec(step(), 1..40)) {
        run(&steps)?;
    }
}
