//! The editor core driven by synthetic pose streams, compared with brushes applied directly.

use std::time::Duration;

use glam::{DQuat, DVec3, I64Vec3};
use strata_editor::{BrushShape, Buttons, Editor, Layer, LayerTransform, Modifiers, Scene, ToolKind, ToolPose};
use strata_mesh::MeshCache;
use strata_volume::Volume;
use strata_volume::brush::Sphere;

const BUDGET: Duration = Duration::from_millis(50);

fn states(v: &Volume, lo: i64, hi: i64) -> Vec<bool> {
    let mut out = Vec::new();
    for z in lo..hi {
        for y in lo..hi {
            for x in lo..hi {
                out.push(v.node_inside(I64Vec3::new(x, y, z)));
            }
        }
    }
    out
}

/// Frames moving the tool from `a` to `b` in `steps` frames with `buttons` held, then a release.
fn drag(e: &mut Editor, a: DVec3, b: DVec3, steps: usize, buttons: Buttons) {
    for i in 0..=steps {
        let p = a.lerp(b, i as f64 / steps as f64);
        let pose =
            ToolPose { position: p, orientation: DQuat::IDENTITY, pressure: 1.0, buttons, ..ToolPose::default() };
        e.frame(&pose, BUDGET).unwrap();
    }
    e.frame(&ToolPose::at(b, false), BUDGET).unwrap();
}

const DOWN: Buttons = Buttons { primary: true, secondary: false };
const ERASE: Buttons = Buttons { primary: false, secondary: true };

#[test]
fn a_stroke_places_evenly_spaced_dabs_like_direct_edits() {
    let mut e = Editor::default();
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    e.tool.radius = 4.3;
    e.tool.spacing = 0.25; // a dab every 1.075 cells
    let (a, b) = (DVec3::new(10.2, 12.1, 11.7), DVec3::new(31.6, 12.1, 11.7));
    drag(&mut e, a, b, 31, DOWN);
    assert_eq!(e.history().undo_len(), 1, "one stroke is one undo step");
    let mut direct = Volume::new();
    let spacing = 4.3 * 0.25;
    let dabs = ((b - a).length() / spacing).floor() as usize;
    for k in 0..=dabs {
        direct.add(&Sphere::new(a + DVec3::X * (k as f64 * spacing), 4.3).unwrap()).unwrap();
    }
    let got = &e.scene.layers[0].volume;
    got.check_invariants().unwrap();
    assert_eq!(states(got, 0, 40), states(&direct, 0, 40));
    assert!(!got.node_inside(I64Vec3::new(37, 12, 12)), "no dab beyond the path's end");
}

#[test]
fn erase_undo_and_redo_restore_exact_volumes() {
    let mut e = Editor::default();
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    e.tool.radius = 5.0;
    drag(&mut e, DVec3::new(5.0, 8.0, 8.0), DVec3::new(40.0, 8.0, 8.0), 20, DOWN);
    let after_add = e.scene.layers[0].volume.clone();
    // The secondary button erases while the tool adds.
    e.tool.radius = 3.0;
    drag(&mut e, DVec3::new(20.0, 4.0, 8.0), DVec3::new(20.0, 14.0, 8.0), 10, ERASE);
    let after_erase = e.scene.layers[0].volume.clone();
    assert_ne!(after_add, after_erase);
    assert!(!after_erase.node_inside(I64Vec3::new(20, 8, 8)));
    // Erasing directly gives the same node states.
    let mut direct = after_add.clone();
    for k in 0..=13 {
        direct.subtract(&Sphere::new(DVec3::new(20.0, 4.0 + k as f64 * 0.75, 8.0), 3.0).unwrap()).unwrap();
    }
    assert_eq!(states(&direct, 0, 48), states(&after_erase, 0, 48));

    assert!(e.undo());
    assert_eq!(e.scene.layers[0].volume, after_add);
    // Undo queues exactly the chunks it restored (and those that read them): the cache catches
    // up to a fresh build of the restored volume.
    e.finish_meshing();
    let fresh = MeshCache::build(&e.scene.layers[0].volume);
    assert_eq!(e.triangle_count(), fresh.triangle_count());
    for (k, m) in fresh.iter() {
        assert_eq!(e.mesh_cache(0).unwrap().mesh(k), Some(m), "chunk {k:?} after undo");
    }
    assert!(e.undo());
    assert!(e.scene.layers[0].volume.is_empty());
    assert!(!e.undo(), "nothing left to undo");
    assert!(e.redo());
    assert_eq!(e.scene.layers[0].volume, after_add);
    assert!(e.redo());
    assert_eq!(e.scene.layers[0].volume, after_erase);
    assert!(!e.redo());
    // A new stroke after an undo drops the redo stack.
    e.undo();
    drag(&mut e, DVec3::splat(30.0), DVec3::splat(31.0), 2, DOWN);
    assert_eq!(e.history().redo_len(), 0);
    // The erase tool erases with the primary button.
    e.tool.kind = ToolKind::Erase;
    assert!(e.scene.layers[0].volume.node_inside(I64Vec3::new(10, 8, 8)));
    drag(&mut e, DVec3::new(10.0, 8.0, 8.0), DVec3::new(10.0, 8.0, 8.0), 1, DOWN);
    assert!(!e.scene.layers[0].volume.node_inside(I64Vec3::new(10, 8, 8)));
}

#[test]
fn the_history_budget_drops_the_oldest_steps() {
    let mut e = Editor::default();
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    e.set_history_budget(20_000);
    for i in 0..12 {
        let p = DVec3::new(8.0 + 9.0 * i as f64, 8.0, 8.0);
        drag(&mut e, p, p + DVec3::Y, 1, DOWN);
    }
    let h = e.history();
    assert!(h.undo_len() < 12 && h.undo_len() >= 1, "{} steps kept", h.undo_len());
    assert!(h.bytes() <= 20_000 || h.undo_len() == 1);
    let kept = h.undo_len();
    for _ in 0..kept {
        assert!(e.undo());
    }
    // The oldest strokes are still there: their steps were forgotten, not their edits.
    assert!(e.scene.layers[0].volume.node_inside(I64Vec3::new(8, 8, 8)));
    assert!(!e.undo());
}

#[test]
fn shapes_pressure_and_layer_transforms() {
    let mut scene = Scene::default();
    let mut moved = Layer::new("moved");
    moved.transform =
        LayerTransform { translation: DVec3::new(100.0, 0.0, 0.0), rotation: DQuat::from_rotation_y(0.5), scale: 0.5 };
    scene.layers.push(moved);
    let mut e = Editor::new(scene);
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    e.active_layer = 1;
    for shape in [BrushShape::Sphere, BrushShape::Box, BrushShape::Capsule, BrushShape::Cylinder] {
        e.tool.shape = shape;
        e.tool.radius = 2.0;
        let p = DVec3::new(110.0, 5.0, 3.0);
        e.frame(&ToolPose::at(p, true), BUDGET).unwrap();
        e.frame(&ToolPose::at(p, false), BUDGET).unwrap();
        let l = &e.scene.layers[1];
        // A world radius of 2 is 4 cells in a layer of half-unit cells.
        let g = l.transform.to_grid(p).round().as_i64vec3();
        assert!(l.volume.node_inside(g), "{shape:?}");
        assert!(l.volume.is_inside(l.transform.to_grid(p + DVec3::new(0.0, 1.5, 0.0))), "{shape:?}");
        assert!(!l.volume.is_inside(l.transform.to_grid(p + DVec3::new(0.0, 0.0, 3.0))), "{shape:?}");
        e.undo();
    }
    assert!(e.scene.layers[0].volume.is_empty(), "the inactive layer is untouched");
    // Pressure scales the radius by the strength.
    e.tool.shape = BrushShape::Sphere;
    e.tool.strength = 1.0;
    e.tool.radius = 4.0;
    let p = DVec3::new(120.0, 0.0, 0.0);
    let pose = ToolPose { pressure: 0.25, ..ToolPose::at(p, true) };
    e.frame(&pose, BUDGET).unwrap();
    e.end_stroke();
    let l = &e.scene.layers[1];
    assert!(l.volume.is_inside(l.transform.to_grid(p + DVec3::X * 0.8)));
    assert!(!l.volume.is_inside(l.transform.to_grid(p + DVec3::X * 1.5)));
}

#[test]
fn bad_input_is_refused_and_changes_nothing() {
    let mut scene = Scene::default();
    scene.layers[0].locked = true;
    let mut e = Editor::new(scene);
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    assert!(e.frame(&ToolPose::at(DVec3::splat(5.0), true), BUDGET).is_err());
    assert!(e.frame(&ToolPose::at(DVec3::new(f64::NAN, 0.0, 0.0), true), BUDGET).is_err());
    e.scene.layers[0].locked = false;
    e.tool.radius = f64::NAN;
    assert!(e.frame(&ToolPose::at(DVec3::splat(5.0), true), BUDGET).is_err());
    e.tool.radius = 0.0;
    assert!(e.frame(&ToolPose::at(DVec3::splat(5.0), true), BUDGET).is_err());
    e.tool.radius = 1e12;
    assert!(e.frame(&ToolPose::at(DVec3::splat(5.0), true), BUDGET).is_err());
    e.active_layer = 7;
    e.tool.radius = 3.0;
    assert!(e.frame(&ToolPose::at(DVec3::splat(5.0), true), BUDGET).is_err());
    assert!(e.scene.layers[0].volume.is_empty());
    assert_eq!(e.history().undo_len(), 0);
    assert!(!e.stroking());
}

#[test]
fn remeshing_respects_the_budget_and_catches_up() {
    let mut e = Editor::default();
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    e.tool.radius = 20.0;
    e.frame(&ToolPose::at(DVec3::splat(30.0), true), Duration::ZERO).unwrap();
    let first = e.frame(&ToolPose::at(DVec3::splat(30.0), false), Duration::ZERO).unwrap();
    assert!(first.pending > 0, "a zero budget remeshes one batch a frame");
    let mut frames = 0;
    let mut shown = 0;
    while e.pending() > 0 {
        let r = e.frame(&ToolPose::at(DVec3::splat(30.0), false), Duration::ZERO).unwrap();
        // A new mesh is shown only with all its neighbours': none of them still waits.
        for &(layer, key) in &r.remeshed {
            for n in key.around() {
                assert!(!e.is_pending(layer, n), "{key:?} shown while {n:?} waits");
            }
        }
        shown += r.remeshed.len();
        frames += 1;
        assert!(frames < 1000);
    }
    assert!(shown > 0);
    assert_eq!(e.triangle_count(), MeshCache::build(&e.scene.layers[0].volume).triangle_count());
}

#[test]
fn picking_hits_the_nearest_visible_surface() {
    let mut scene = Scene::default();
    scene.layers[0].volume.add(&Sphere::new(DVec3::new(20.0, 20.0, 20.0), 6.0).unwrap()).unwrap();
    let mut near = Layer::new("near");
    near.volume.add(&Sphere::new(DVec3::new(20.0, 20.0, 5.0), 3.0).unwrap()).unwrap();
    scene.layers.push(near);
    let mut e = Editor::new(scene);
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    let hit = e.pick(DVec3::new(20.0, 20.0, -10.0), DVec3::Z, 100.0).unwrap();
    assert_eq!(hit.layer, 1);
    assert!((hit.point.z - 2.0).abs() < 0.1, "{hit:?}");
    assert!(hit.normal.z < -0.9);
    e.scene.layers[1].visible = false;
    let hit = e.pick(DVec3::new(20.0, 20.0, -10.0), DVec3::Z, 100.0).unwrap();
    assert_eq!(hit.layer, 0);
    assert!((hit.point.z - 14.0).abs() < 0.1, "{hit:?}");
    assert!(e.pick(DVec3::new(20.0, 20.0, -10.0), DVec3::X, 100.0).is_none());
    assert!(e.pick(DVec3::splat(f64::NAN), DVec3::Z, 100.0).is_none());
    let mesh = e.dual_contour_layer(0).unwrap();
    assert!(mesh.triangle_count() > 100);
}

#[test]
fn picking_skips_layers_the_ray_misses_and_bounds_its_work() {
    // 100 empty layers at a tiny scale cost nothing.
    let mut scene = Scene::default();
    scene.layers.clear();
    for i in 0..100 {
        let mut l = Layer::new(format!("empty {i}"));
        l.transform = LayerTransform::new(DVec3::ZERO, DQuat::IDENTITY, 1e-5).unwrap();
        scene.layers.push(l);
    }
    let mut e = Editor::new(scene);
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    let (hit, walked) = e.pick_counted(DVec3::new(0.0, 0.0, -50.0), DVec3::Z, 1e4);
    assert!(hit.is_none());
    assert_eq!(walked, 0, "empty layers walk no chunk");
    // A tiny-scale layer with two specks far apart (a ray along it would cross 10⁹ chunks of
    // its grid): the walk stops at the per-pick budget.
    let mut l = Layer::new("specks");
    l.transform = LayerTransform::new(DVec3::ZERO, DQuat::IDENTITY, 1e-5).unwrap();
    l.volume.add(&Sphere::new(DVec3::ZERO, 1.5).unwrap()).unwrap();
    l.volume.add(&Sphere::new(DVec3::new(1.6e10, 0.0, 0.0), 1.5).unwrap()).unwrap();
    assert!(l.volume.chunk_count() >= 2);
    e.scene.layers.push(l);
    e.reset_caches();
    let (_, walked) = e.pick_counted(DVec3::new(3.0e-5, 2.5e-6, 2.5e-6), DVec3::X, 1e6);
    assert!(walked <= strata_editor::PICK_CHUNK_STEPS, "{walked} chunks walked");
    // A layer in front hides the ones behind without walking them.
    let mut front = Layer::new("front");
    front.volume.add(&Sphere::new(DVec3::new(10.0, 10.0, 10.0), 5.0).unwrap()).unwrap();
    let mut back = Layer::new("back");
    back.volume.add(&Sphere::new(DVec3::new(10.0, 10.0, 90.0), 5.0).unwrap()).unwrap();
    let e = Editor::new(Scene { layers: vec![back, front], ..Scene::default() });
    let (hit, walked) = e.pick_counted(DVec3::new(10.0, 10.0, -20.0), DVec3::Z, 1e4);
    let hit = hit.expect("the front sphere");
    assert_eq!(hit.layer, 1);
    assert!((hit.point.z - 5.0).abs() < 0.6, "{}", hit.point);
    assert!(walked <= 4, "only the front layer's chunks up to the hit: {walked}");
}

#[test]
fn field_tools_stroke_as_one_undo_step_and_keep_the_volume_consistent() {
    for kind in ToolKind::ALL.into_iter().filter(|k| k.is_field_tool()) {
        let mut scene = Scene::default();
        scene.layers[0].volume.add(&Sphere::new(DVec3::new(16.0, 16.0, 16.0), 10.0).unwrap()).unwrap();
        scene.layers[0].volume.add(&Sphere::new(DVec3::new(24.0, 18.0, 16.0), 3.0).unwrap()).unwrap();
        let mut e = Editor::new(scene);
        e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
        let before = e.scene.layers[0].volume.clone();
        e.tool.kind = kind;
        e.tool.radius = 5.0;
        e.tool.field_strength = 1.0;
        e.tool.material = 3; // (paint changes materials only)
        drag(&mut e, DVec3::new(25.0, 18.0, 14.0), DVec3::new(25.0, 18.0, 18.0), 6, DOWN);
        let after = e.scene.layers[0].volume.clone();
        after.check_invariants().unwrap();
        assert_ne!(after, before, "{kind:?} changed the surface");
        assert_eq!(e.history().undo_len(), 1, "{kind:?}: one stroke, one step");
        assert!(e.undo());
        assert_eq!(e.scene.layers[0].volume, before, "{kind:?}: undo restores the exact volume");
        assert!(e.redo());
        assert_eq!(e.scene.layers[0].volume, after);
    }
    // Inflate grows, its secondary button (deflate) shrinks.
    for (buttons, grows) in [(DOWN, true), (ERASE, false)] {
        let mut scene = Scene::default();
        scene.layers[0].volume.add(&Sphere::new(DVec3::new(16.0, 16.0, 16.0), 10.0).unwrap()).unwrap();
        let mut e = Editor::new(scene);
        e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
        let v0 = e.scene.layers[0].volume.measured_volume(strata_volume::Axis::X);
        e.tool.kind = ToolKind::Inflate;
        e.tool.radius = 6.0;
        e.tool.field_strength = 1.0;
        drag(&mut e, DVec3::new(26.0, 16.0, 14.0), DVec3::new(26.0, 16.0, 18.0), 4, buttons);
        let v1 = e.scene.layers[0].volume.measured_volume(strata_volume::Axis::X);
        assert_eq!(v1 > v0, grows, "{v0} -> {v1}");
    }
}

#[test]
fn a_mirrored_stroke_across_a_plane_through_nodes_gives_mirrored_node_states() {
    for shape in [BrushShape::Sphere, BrushShape::Box, BrushShape::Capsule, BrushShape::Cylinder] {
        let mut e = Editor::new(Scene { layers: vec![Layer::new("clay")], ..Scene::default() });
        e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
        e.tool.shape = shape;
        e.tool.radius = 3.5;
        e.tool.symmetry = [true, false, false];
        e.tool.symmetry_center = DVec3::new(32.0, 0.0, 0.0);
        drag(&mut e, DVec3::new(36.25, 20.5, 18.0), DVec3::new(41.5, 24.0, 21.75), 8, DOWN);
        let v = &e.scene.layers[0].volume;
        v.check_invariants().unwrap();
        let mut inside = 0;
        for z in 10..32 {
            for y in 10..32 {
                for k in 0..16 {
                    let (a, b) = (I64Vec3::new(32 + k, y, z), I64Vec3::new(32 - k, y, z));
                    assert_eq!(v.node_inside(a), v.node_inside(b), "{shape:?}: node {a} and its mirror {b}");
                    inside += v.node_inside(a) as u32;
                }
            }
        }
        assert!(inside > 100, "{shape:?}: the stroke added material ({inside} nodes)");
        assert_eq!(e.history().undo_len(), 1, "both halves are one stroke");
        assert!(e.undo());
        assert!(e.scene.layers[0].volume.is_empty());
    }
    // A field tool mirrors too: both sides change.
    let mut scene = Scene::default();
    scene.layers[0].volume.add(&Sphere::new(DVec3::new(32.0, 16.0, 16.0), 10.0).unwrap()).unwrap();
    let mut e = Editor::new(scene);
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    let before = e.scene.layers[0].volume.clone();
    e.tool.kind = ToolKind::Inflate;
    e.tool.field_strength = 1.0;
    e.tool.radius = 4.0;
    e.tool.symmetry = [true, false, false];
    e.tool.symmetry_center = DVec3::new(32.0, 16.0, 16.0);
    drag(&mut e, DVec3::new(42.0, 16.0, 15.0), DVec3::new(42.0, 16.0, 17.0), 2, DOWN);
    let v = &e.scene.layers[0].volume;
    v.check_invariants().unwrap();
    let probe = |v: &Volume, x: i64| (0..3).filter(|d| v.node_inside(I64Vec3::new(x, 16, 15 + d))).count();
    assert!(probe(v, 42) > probe(&before, 42) && probe(v, 22) > probe(&before, 22), "both sides grew");
}

#[test]
fn the_line_tool_places_evenly_spaced_dabs_between_two_points_as_one_step() {
    let mut e = Editor::new(Scene { layers: vec![Layer::new("clay")], ..Scene::default() });
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    e.tool.radius = 2.0;
    let (a, b) = (DVec3::new(4.0, 10.0, 10.0), DVec3::new(28.0, 10.0, 10.0));
    let report = e.line_stroke(a, b, 1.0, Modifiers::default()).unwrap();
    // Dabs every spacing × radius = 0.5 cells, the first at a.
    assert_eq!(report.dabs, 1 + (24.0 / e.tool.dab_spacing()).floor() as usize);
    assert_eq!(e.history().undo_len(), 1);
    let v = &e.scene.layers[0].volume;
    v.check_invariants().unwrap();
    for x in 4..=28 {
        assert!(v.node_inside(I64Vec3::new(x, 10, 10)), "node {x} on the line");
    }
    assert!(!v.node_inside(I64Vec3::new(31, 10, 10)));
    let before = e.scene.layers[0].volume.clone();
    assert!(
        e.line_stroke(DVec3::new(40.0, 10.0, 10.0), DVec3::NAN, 1.0, Modifiers::default()).is_err(),
        "a bad end point is an error"
    );
    assert!(e.line_stroke(a, b, f64::INFINITY, Modifiers::default()).is_err(), "a bad pressure too");
    assert_eq!(e.history().undo_len(), 1, "and changes nothing");
    assert_eq!(e.scene.layers[0].volume, before);
}

#[test]
fn layer_transforms_change_with_undo_and_a_drag_is_one_step() {
    let mut e = Editor::default();
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    let t0 = e.scene.layers[0].transform;
    let moved = LayerTransform::new(DVec3::new(5.0, 0.0, 0.0), DQuat::from_rotation_y(0.3), 2.0).unwrap();
    e.set_layer_transform(0, moved, false).unwrap();
    assert_eq!(e.scene.layers[0].transform, moved);
    // A drag: its first change starts a step, the rest join it.
    for k in 1..=10 {
        let t = LayerTransform { translation: DVec3::new(5.0 + k as f64, 0.0, 0.0), ..moved };
        e.set_layer_transform(0, t, k > 1).unwrap();
    }
    assert_eq!(e.history().undo_len(), 2);
    assert!(e.undo());
    assert_eq!(e.scene.layers[0].transform, moved, "the drag undoes as one step");
    assert!(e.undo());
    assert_eq!(e.scene.layers[0].transform, t0);
    assert!(e.redo());
    assert_eq!(e.scene.layers[0].transform, moved);
    // Refused: nothing changes.
    let bad = LayerTransform { scale: 0.0, ..moved };
    assert!(e.set_layer_transform(0, bad, false).is_err());
    assert!(e.set_layer_transform(7, moved, false).is_err());
    assert_eq!(e.scene.layers[0].transform, moved);
}

#[test]
fn a_layer_with_a_transform_set_wrongly_through_its_fields_refuses_edits() {
    let mut e = Editor::default();
    e.tool.kind = ToolKind::Add; // the exact CSG tool (the default is clay)
    e.scene.layers[0].transform.rotation = DQuat::from_xyzw(0.0, 3.0, 0.0, 4.0);
    let before = e.scene.layers[0].volume.clone();
    let pose = ToolPose {
        position: DVec3::splat(8.0),
        orientation: DQuat::IDENTITY,
        pressure: 1.0,
        buttons: DOWN,
        ..ToolPose::default()
    };
    assert!(matches!(e.frame(&pose, BUDGET), Err(strata_editor::EditorError::BadLayerTransform(0))));
    assert!(e.dab_chunks(&pose).is_err());
    assert!(e.start_dab_job(&pose).is_err());
    assert_eq!(e.scene.layers[0].volume, before);
    // Repaired through the checked setter, it edits again.
    let t = e.scene.layers[0].transform.repaired();
    e.set_layer_transform(0, t, false).unwrap();
    e.frame(&pose, BUDGET).unwrap();
    assert_ne!(e.scene.layers[0].volume, before);
}

/// A scene with one ball of radius 10 at (16, 16, 16).
fn ball_editor() -> Editor {
    let mut scene = Scene::default();
    scene.layers[0].volume.add(&Sphere::new(DVec3::new(16.0, 16.0, 16.0), 10.0).unwrap()).unwrap();
    Editor::new(scene)
}

/// The surface's distance from the ball's centre along `dir`.
fn radius_along(v: &Volume, dir: DVec3) -> f64 {
    let c = DVec3::new(16.0, 16.0, 16.0);
    40.0 - v.raycast(c + dir * 40.0, -dir, 80.0).unwrap().t
}

#[test]
fn clay_is_the_default_and_blends_into_the_surface() {
    let mut e = ball_editor();
    assert_eq!(e.tool.kind, ToolKind::Clay);
    let before = e.scene.layers[0].volume.clone();
    e.tool.radius = 3.0;
    e.tool.field_strength = 1.0;
    drag(&mut e, DVec3::new(26.0, 16.0, 15.0), DVec3::new(26.0, 16.0, 17.0), 3, DOWN);
    let v = e.scene.layers[0].volume.clone();
    v.check_invariants().unwrap();
    // The ball of clay sits on the surface; beside it the surface rises in a fillet.
    assert!(radius_along(&v, DVec3::X) > 12.5, "clay added: {}", radius_along(&v, DVec3::X));
    let beside = DVec3::new(0.94, 0.0, 0.34).normalize();
    assert!(radius_along(&v, beside) > radius_along(&before, beside) + 0.1, "a fillet beside the stroke");
    assert_eq!(e.history().undo_len(), 1);
    // The inverse (secondary button) carves.
    let mut e = ball_editor();
    e.tool.radius = 3.0;
    e.tool.field_strength = 1.0;
    drag(&mut e, DVec3::new(26.0, 16.0, 15.0), DVec3::new(26.0, 16.0, 17.0), 3, ERASE);
    assert!(radius_along(&e.scene.layers[0].volume, DVec3::X) < 9.0);
}

#[test]
fn grab_drags_the_surface_with_the_pointer_as_one_step() {
    // One to one, whatever the field tools' strength (grab once moved by the strength, 0.5).
    for (mirrored, strength) in [(false, 0.5), (true, 1.0), (false, 0.1)] {
        let mut e = ball_editor();
        let before = e.scene.layers[0].volume.clone();
        e.tool.kind = ToolKind::Grab;
        e.tool.radius = 5.0;
        e.tool.field_strength = strength;
        e.tool.symmetry = [mirrored, false, false];
        e.tool.symmetry_center = DVec3::new(16.0, 16.0, 16.0);
        // Press on the surface at +x and drag 4 cells outwards over four frames.
        drag(&mut e, DVec3::new(26.0, 16.0, 16.0), DVec3::new(30.0, 16.0, 16.0), 4, DOWN);
        let v = e.scene.layers[0].volume.clone();
        v.check_invariants().unwrap();
        let moved = radius_along(&v, DVec3::X) - radius_along(&before, DVec3::X);
        assert!((moved - 4.0).abs() < 0.25, "the surface under the brush moved {moved}");
        let other = radius_along(&v, -DVec3::X) - radius_along(&before, -DVec3::X);
        if mirrored {
            assert!((other - 4.0).abs() < 0.25, "the mirrored side moved {other}");
        } else {
            assert!(other.abs() < 1e-3, "the far side stayed ({other})");
        }
        assert_eq!(e.history().undo_len(), 1, "the drag is one step");
        assert!(e.undo());
        assert_eq!(e.scene.layers[0].volume, before);
    }
}

#[test]
fn the_alignment_tool_snaps_locks_and_orients() {
    // Grid snap: a dab lands on the nearest multiple of the snap step.
    let mut e = Editor::new(Scene::default());
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 2.0;
    e.tool.grid_snap = 4.0;
    drag(&mut e, DVec3::new(9.3, 10.6, 13.1), DVec3::new(9.3, 10.6, 13.1), 1, DOWN);
    let mut direct = Volume::new();
    direct.add(&Sphere::new(DVec3::new(8.0, 12.0, 12.0), 2.0).unwrap()).unwrap();
    assert_eq!(e.scene.layers[0].volume, direct, "the dab snapped to (8, 12, 12)");
    // Axis lock: a wobbly stroke along x stays on the x line through its start.
    let mut e = Editor::new(Scene::default());
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 1.5;
    e.tool.axis_lock = Some(0);
    let path = [DVec3::new(10.0, 10.0, 10.0), DVec3::new(13.0, 12.5, 9.0), DVec3::new(16.0, 7.0, 11.0)];
    for p in path {
        let pose =
            ToolPose { position: p, orientation: DQuat::IDENTITY, pressure: 1.0, buttons: DOWN, ..ToolPose::default() };
        e.frame(&pose, Duration::ZERO).unwrap();
    }
    e.frame(&ToolPose::at(path[2], false), Duration::ZERO).unwrap();
    let v = &e.scene.layers[0].volume;
    for x in 10..=16 {
        assert!(v.node_inside(I64Vec3::new(x, 10, 10)), "node ({x}, 10, 10) is on the locked line");
    }
    assert!(!v.node_inside(I64Vec3::new(13, 12, 9)) && !v.node_inside(I64Vec3::new(16, 7, 11)));
    // Orient to normal: a box brush turned onto the surface normal.
    let n = DVec3::new(1.0, 1.0, 0.0).normalize();
    let q = strata_editor::orientation_for_normal(n);
    assert!((q * DVec3::Y - n).length() < 1e-12);
    let mut e = Editor::new(Scene::default());
    e.tool.kind = ToolKind::Add;
    e.tool.shape = BrushShape::Box;
    e.tool.radius = 3.0;
    let pose =
        ToolPose { position: DVec3::splat(12.0), orientation: q, pressure: 1.0, buttons: DOWN, ..ToolPose::default() };
    e.frame(&pose, Duration::ZERO).unwrap();
    let mut direct = Volume::new();
    direct
        .add(&strata_volume::brush::Cuboid::oriented(DVec3::splat(12.0), DVec3::splat(3.0), q, 0.0).unwrap())
        .unwrap();
    assert_eq!(e.scene.layers[0].volume, direct);
    assert!(!direct.node_inside(I64Vec3::new(15, 15, 12)), "the box's corner turned away from (+x, +y)");
}

#[test]
fn mirrored_directions_pair_with_the_mirrored_images_even_on_a_mirror_plane() {
    let mut t = strata_editor::ToolSettings { symmetry: [true, false, true], ..Default::default() };
    t.symmetry_center = DVec3::new(10.0, 0.0, 5.0);
    let layer = LayerTransform::default();
    for at in [DVec3::new(10.0, 3.0, 9.0), DVec3::new(13.0, 3.0, 5.0), DVec3::new(10.0, 3.0, 5.0)] {
        let dir = DVec3::new(1.0, 0.5, -2.0);
        let images = t.mirrored(&layer, at, DQuat::IDENTITY);
        let dirs = t.mirrored_directions(&layer, at, dir);
        assert_eq!(images.len(), dirs.len(), "{at}");
        for ((p, _), (q, v)) in images.iter().zip(&dirs) {
            assert_eq!(p, q);
            assert!((v.length() - dir.length()).abs() < 1e-12);
        }
        // A grab on a mirror plane keeps both drags.
        let drags = t.mirrored_with_vector(&layer, at, dir);
        assert!(drags.len() >= images.len());
    }
    assert_eq!(t.mirrored(&layer, DVec3::new(10.0, 3.0, 5.0), DQuat::IDENTITY).len(), 1, "on both planes: one dab");
}

#[test]
fn add_clay_and_paint_use_the_current_material_and_refuse_one_outside_the_palette() {
    let mut e = Editor::default();
    let count = e.scene.materials.len();
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 4.0;
    e.tool.material = 3;
    drag(&mut e, DVec3::new(10.0, 10.0, 10.0), DVec3::new(20.0, 10.0, 10.0), 8, DOWN);
    let v = &e.scene.layers[0].volume;
    assert_eq!(v.node_material_at(glam::I64Vec3::new(15, 10, 10)), Some(3), "add with material");
    e.tool.kind = ToolKind::Clay;
    e.tool.material = 4;
    drag(&mut e, DVec3::new(15.0, 14.0, 10.0), DVec3::new(15.0, 14.5, 10.0), 2, DOWN);
    let v = &e.scene.layers[0].volume;
    assert!(
        v.material_chunks().any(|(_, m)| m.change_points().unwrap().iter().any(|p| p.1 == 4)),
        "clay adds its material"
    );
    v.check_invariants().unwrap();
    // A material the palette lacks: the stroke is refused, nothing changes.
    let before = e.scene.layers[0].volume.clone();
    e.tool.kind = ToolKind::Paint;
    e.tool.material = count as u8;
    let pose = ToolPose {
        position: DVec3::new(15.0, 10.0, 10.0),
        orientation: DQuat::IDENTITY,
        pressure: 1.0,
        buttons: DOWN,
        ..ToolPose::default()
    };
    let err = e.frame(&pose, BUDGET).unwrap_err();
    assert!(err.to_string().contains("not in the palette"), "{err}");
    assert_eq!(e.scene.layers[0].volume, before);
    // The eyedropper reads the material under a pick.
    let pick = e.pick(DVec3::new(15.0, 10.0, -20.0), DVec3::Z, 100.0).expect("the stroke is hit");
    assert_eq!(e.material_at(&pick), Some(3));
}

#[test]
fn a_stroke_finds_the_surface_under_the_pointer_but_never_its_own_dabs() {
    use strata_volume::brush::Cuboid;
    // A near slab (front face z = 20, x up to 14) and a far one (front face z = 8), seen along -z.
    let slabs = || {
        let mut e = Editor::default();
        let v = &mut e.scene.layers[0].volume;
        v.add(&Cuboid::new(DVec3::new(6.0, 16.0, 16.0), DVec3::new(8.0, 8.0, 4.0)).unwrap()).unwrap();
        v.add(&Cuboid::new(DVec3::new(26.0, 16.0, 4.0), DVec3::new(12.0, 8.0, 4.0)).unwrap()).unwrap();
        e
    };
    let eye_z = 60.0;
    let along = |e: &Editor, x: f64| e.stroke_surface(DVec3::new(x, 16.0, eye_z), -DVec3::Z, 1e4);
    // (The lists hold crossings in fixed point and snapped off nodes: within a hundredth of a cell.)
    let at = |t: Option<f64>, face_z: f64| t.is_some_and(|t| (t - (eye_z - face_z)).abs() < 0.01);
    for (kind, buttons) in
        [(ToolKind::Add, DOWN), (ToolKind::Erase, DOWN), (ToolKind::Clay, DOWN), (ToolKind::Add, ERASE)]
    {
        let mut e = slabs();
        e.tool.kind = kind;
        e.tool.radius = 2.0;
        // No stroke: the first surface.
        assert!(at(along(&e, 10.0), 20.0) && at(along(&e, 24.0), 8.0));
        // A dab on the near face at x = 10.
        let pose = ToolPose {
            position: DVec3::new(10.0, 16.0, 20.0),
            orientation: DQuat::IDENTITY,
            pressure: 1.0,
            buttons,
            ..ToolPose::default()
        };
        e.frame(&pose, BUDGET).unwrap();
        assert!(e.stroking());
        // Over the dab: what the ray meets there is the dab's own work, and the face it sits on
        // is under it: no surface (the caller keeps the stroke's depth) rather than a climb or a dig.
        for x in [10.0, 10.5, 11.0] {
            assert_eq!(along(&e, x), None, "{kind:?} {buttons:?}: over its own dab at x = {x}");
        }
        // Away from the dab, the near face; past the near slab, the far face behind it.
        assert!(at(along(&e, 4.0), 20.0), "{kind:?}: the near face beside the dab");
        assert!(at(along(&e, 20.0), 8.0), "{kind:?}: the far face");
        e.frame(&ToolPose::at(DVec3::ZERO, false), BUDGET).unwrap();
        // The stroke over, its dabs are surface like any other.
        assert!(!e.stroking());
        assert!(along(&e, 10.0).is_some());
    }
    // A dab at the near slab's edge: a ray just past the edge leaves the dab in the air and
    // finds the far face, so a stroke carries on from the near surface onto the far one.
    let mut e = slabs();
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 2.0;
    e.frame(
        &ToolPose {
            position: DVec3::new(14.0, 16.0, 20.0),
            orientation: DQuat::IDENTITY,
            pressure: 1.0,
            buttons: DOWN,
            ..ToolPose::default()
        },
        BUDGET,
    )
    .unwrap();
    assert!(at(along(&e, 15.0), 8.0), "past the edge: {:?}", along(&e, 15.0));
}

/// The pose says how its buttons act: `inverted` erases with the add tool exactly as the
/// secondary button does, `smooth` smooths with any tool while the current tool stays, and a
/// change of either mid-stroke starts a new stroke (its own undo step).
#[test]
fn modifiers_in_the_pose_invert_and_smooth_without_touching_the_tool() {
    let base = {
        let mut e = Editor::default();
        e.tool.kind = ToolKind::Add;
        e.tool.radius = 5.0;
        drag(&mut e, DVec3::new(5.0, 8.0, 8.0), DVec3::new(40.0, 8.0, 8.0), 20, DOWN);
        e
    };
    let pose_drag = |e: &mut Editor, a: DVec3, b: DVec3, modifiers: Modifiers| {
        for i in 0..=10 {
            let p = a.lerp(b, i as f64 / 10.0);
            e.frame(&ToolPose { position: p, buttons: DOWN, modifiers, ..ToolPose::default() }, BUDGET).unwrap();
        }
        e.frame(&ToolPose::at(b, false), BUDGET).unwrap();
    };
    let (a, b) = (DVec3::new(20.0, 4.0, 8.0), DVec3::new(20.0, 14.0, 8.0));
    // Inverted by the pose equals inverted by the secondary button.
    let mut by_button = Editor::new(base.scene.clone());
    by_button.tool = base.tool;
    by_button.tool.radius = 3.0;
    drag(&mut by_button, a, b, 10, ERASE);
    let mut by_pose = Editor::new(base.scene.clone());
    by_pose.tool = base.tool;
    by_pose.tool.radius = 3.0;
    pose_drag(&mut by_pose, a, b, Modifiers { inverted: true, smooth: false });
    assert_eq!(by_pose.scene.layers[0].volume, by_button.scene.layers[0].volume);
    assert_ne!(by_pose.scene.layers[0].volume, base.scene.layers[0].volume, "it erased");
    assert_eq!(by_pose.tool.kind, ToolKind::Add);
    // Smooth by the pose equals the smooth tool, and the tool stays add.
    let mut smooth_tool = Editor::new(base.scene.clone());
    smooth_tool.tool = base.tool;
    smooth_tool.tool.kind = ToolKind::Smooth;
    pose_drag(&mut smooth_tool, a, b, Modifiers::default());
    let mut smooth_pose = Editor::new(base.scene.clone());
    smooth_pose.tool = base.tool;
    pose_drag(&mut smooth_pose, a, b, Modifiers { inverted: false, smooth: true });
    assert_eq!(smooth_pose.scene.layers[0].volume, smooth_tool.scene.layers[0].volume);
    assert_ne!(smooth_pose.scene.layers[0].volume, base.scene.layers[0].volume, "it smoothed");
    assert_eq!(smooth_pose.tool.kind, ToolKind::Add);
    // Shift pressed mid-stroke: two strokes, two undo steps.
    let mut e = Editor::new(base.scene.clone());
    e.tool = base.tool;
    let modifiers = [Modifiers::default(), Modifiers { inverted: false, smooth: true }];
    for (i, m) in modifiers.into_iter().enumerate() {
        let p = DVec3::new(12.0 + 6.0 * i as f64, 12.0, 8.0);
        e.frame(&ToolPose { position: p, buttons: DOWN, modifiers: m, ..ToolPose::default() }, BUDGET).unwrap();
    }
    e.frame(&ToolPose::at(DVec3::new(18.0, 12.0, 8.0), false), BUDGET).unwrap();
    assert_eq!(e.history().undo_len(), 2, "a modifier change ends the stroke");
}

/// A dab spanning more chunks than the frame's limit is refused before anything changes (the
/// studio then runs it in the background); under the limit, and for the line tool, it applies.
#[test]
fn dabs_over_the_frame_limit_are_refused_untouched_and_lines_ignore_the_limit() {
    let mut e = Editor::default();
    e.scene.layers[0].volume.add(&Sphere::new(DVec3::splat(32.0), 12.0).unwrap()).unwrap();
    e.clear_history();
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 20.0;
    let before = e.scene.layers[0].volume.clone();
    let pose = ToolPose { position: DVec3::new(32.0, 44.0, 32.0), buttons: DOWN, ..ToolPose::default() };
    let chunks = e.dab_chunks(&pose).unwrap();
    e.frame_dab_limit = chunks - 1;
    match e.frame(&pose, BUDGET) {
        Err(strata_editor::EditorError::DabTooLargeForFrame(n)) => assert_eq!(n, chunks),
        other => panic!("expected a refusal, got {other:?}"),
    }
    assert_eq!(e.scene.layers[0].volume, before, "nothing changed");
    assert!(!e.stroking());
    assert_eq!(e.history().undo_len(), 0);
    // The line tool applies whole whatever the limit, and leaves it as it was.
    e.line_stroke(pose.position, pose.position + DVec3::X * 4.0, 1.0, Modifiers::default()).unwrap();
    assert_ne!(e.scene.layers[0].volume, before);
    assert_eq!(e.frame_dab_limit, chunks - 1);
    // At the limit, a dragged dab applies.
    e.frame_dab_limit = chunks;
    e.frame(&ToolPose::at(pose.position, false), BUDGET).unwrap();
    let after_line = e.scene.layers[0].volume.clone();
    e.frame(&ToolPose { position: pose.position + DVec3::Z * 6.0, ..pose }, BUDGET).unwrap();
    assert_ne!(e.scene.layers[0].volume, after_line);
}

/// The dabs a shaky horizontal stroke makes at `y = 20` (the pointer zigzags ±2 cells) with
/// `stabiliser`: their largest distance from the line, and how far along it they got.
fn shaky_line(stabiliser: strata_editor::Stabiliser) -> (f64, f64) {
    let mut e = Editor::default();
    e.stabiliser = stabiliser;
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 2.0;
    e.record_ops(true);
    for i in 0..=60 {
        // (The stroke starts on the line: its first dab is where the pointer is.)
        let wobble = if i == 0 {
            0.0
        } else if i % 2 == 0 {
            2.0
        } else {
            -2.0
        };
        let p = DVec3::new(10.0 + i as f64 * 0.5, 20.0 + wobble, 12.0);
        e.frame(&ToolPose { position: p, buttons: DOWN, ..ToolPose::default() }, BUDGET).unwrap();
    }
    e.frame(&ToolPose::at(DVec3::new(40.0, 20.0, 12.0), false), BUDGET).unwrap();
    let dabs: Vec<DVec3> = e
        .take_ops()
        .into_iter()
        .flat_map(|o| o.op.dabs)
        .map(|d| match d {
            strata_editor::DabRecord::Dab { at, .. } => at,
            strata_editor::DabRecord::Grab { anchor, .. } => anchor,
        })
        .collect();
    let off_line = dabs.iter().map(|p| (p.y - 20.0).abs()).fold(0.0, f64::max);
    let reach = dabs.iter().map(|p| p.x).fold(f64::MIN, f64::max);
    (off_line, reach)
}

#[test]
fn the_stabiliser_draws_a_shaky_stroke_as_a_clean_line() {
    use strata_editor::Stabiliser;
    let (shaky, _) = shaky_line(Stabiliser::Off);
    let (weak, _) = shaky_line(Stabiliser::Weak);
    let (strong, reach) = shaky_line(Stabiliser::Strong);
    assert!(shaky >= 1.9, "unstabilised, the dabs follow the hand: {shaky}");
    eprintln!("off the line: {shaky} unstabilised, {weak} weak, {strong} strong");
    assert!(weak < 0.75 * shaky, "a weak rope steadies it: {weak} against {shaky}");
    assert!(strong < 0.25, "a strong rope draws a straight line: {strong} off it");
    // The brush trails the pointer by the rope: the line ends short of where the pointer went.
    assert!(reach < 40.0 - 5.0 && reach > 20.0, "the strong brush reached x = {reach}");
}

/// An editor with a slab whose top face lies on the grid plane y = 0 (the layer placed at the
/// origin, one cell per unit), and the slab's top height at `(x, z)`.
fn slab_editor() -> Editor {
    let mut e = Editor::default();
    let slab = strata_volume::brush::Cuboid::new(DVec3::new(0.0, -8.0, 0.0), DVec3::new(30.0, 8.0, 30.0)).unwrap();
    e.apply(0, strata_volume::CsgOp::Add, &slab).unwrap();
    e.clear_history();
    e
}

fn top(e: &Editor, x: f64, z: f64) -> f64 {
    let v = &e.scene.layers[0].volume;
    20.0 - v.raycast(DVec3::new(x, 20.0, z), -DVec3::Y, 60.0).unwrap().t
}

#[test]
fn a_sprayed_stamp_raises_its_picture_along_the_stroke_as_one_undo_step() {
    use strata_editor::{StampSource, StampStroke};
    let mut e = slab_editor();
    let before = e.scene.layers[0].volume.clone();
    e.tool.kind = ToolKind::Stamp;
    e.tool.radius = 6.0;
    e.tool.field_strength = 1.0;
    e.tool.stamp.source = StampSource::Builtin(strata_volume::tools::BuiltinStamp::Dome);
    assert_eq!(e.tool.stamp.stroke, StampStroke::Spray);
    drag(&mut e, DVec3::new(-10.0, 0.0, 0.0), DVec3::new(10.0, 0.0, 0.0), 10, DOWN);
    e.scene.layers[0].volume.check_invariants().unwrap();
    // A ridge of domes along the stroke (height up to half the radius each, overlapping).
    let ridge = top(&e, 0.3, 0.2);
    assert!(ridge > 2.5, "the stroke's middle rose by {ridge}");
    assert!(top(&e, 0.3, 12.0).abs() < 0.01, "beside the stroke nothing moved");
    assert!(e.undo());
    assert_eq!(e.scene.layers[0].volume, before);
    // The inverse tool carves.
    drag(&mut e, DVec3::new(-10.0, 0.0, 0.0), DVec3::new(10.0, 0.0, 0.0), 10, ERASE);
    assert!(top(&e, 0.3, 0.2) < -2.5);
}

#[test]
fn a_dragged_stamp_is_sized_and_turned_by_the_drag_and_equals_the_cores_stamp() {
    use strata_editor::StampStroke;
    use strata_volume::tools::{BuiltinStamp, Dab, StampPlacement, stamp};
    let mut e = slab_editor();
    let before = e.scene.layers[0].volume.clone();
    e.tool.kind = ToolKind::Stamp;
    e.tool.stamp.stroke = StampStroke::Drag;
    e.tool.stamp.source = strata_editor::StampSource::Builtin(BuiltinStamp::Star);
    e.tool.stamp.angle = 30.0;
    e.tool.field_strength = 0.8;
    // Pressed at the middle, dragged out to 9 cells along x: nothing changes until release.
    let centre = DVec3::new(1.0, 0.0, 2.0);
    let end = centre + DVec3::new(9.0, 0.0, 0.0);
    for i in 0..=6 {
        let p = centre.lerp(end, i as f64 / 6.0);
        e.frame(&ToolPose { position: p, buttons: DOWN, ..ToolPose::default() }, BUDGET).unwrap();
        assert_eq!(e.scene.layers[0].volume, before, "nothing is applied while dragging");
    }
    let (c, r, up) = e.stamp_drag().expect("a stamp is being dragged");
    assert_eq!((c, r, up), (centre, 9.0, end - centre));
    e.frame(&ToolPose::at(end, false), BUDGET).unwrap();
    assert!(e.stamp_drag().is_none());
    // The core's stamp of the same image, radius, strength and turn.
    let mut direct = before.clone();
    let dab = Dab::new(centre, 9.0, 0.8).unwrap();
    let placement = StampPlacement { up: DVec3::X, angle: 30f64.to_radians(), mirrored: false };
    stamp(&mut direct, &dab, &BuiltinStamp::Star.image(), &placement, 0.2 * 9.0).unwrap();
    assert_eq!(e.scene.layers[0].volume, direct);
    assert!(e.undo());
    assert_eq!(e.scene.layers[0].volume, before, "a dragged stamp is one undo step");
}

#[test]
fn a_mirrored_stamp_is_the_mirror_image_and_loaded_stamps_are_checked() {
    use strata_editor::{EditorError, StampSource};
    let mut e = slab_editor();
    // A picture white only in its top-right quarter.
    let corner = strata_volume::tools::StampImage::from_fn(32, |u, v| if u > 0.15 && v > 0.15 { 1.0 } else { 0.0 });
    e.tool.stamp.source = e.stamps.add("corner.png", corner);
    e.tool.kind = ToolKind::Stamp;
    e.tool.radius = 8.0;
    e.tool.field_strength = 1.0;
    e.tool.symmetry = [true, false, false];
    // The pose's y axis is the stamp's top: seen from above (+y), turn it to −z.
    let orientation = DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2);
    let at = DVec3::new(10.0, 0.0, 0.0);
    let pose = ToolPose { position: at, orientation, pressure: 1.0, buttons: DOWN, ..ToolPose::default() };
    e.frame(&pose, BUDGET).unwrap();
    e.frame(&ToolPose::at(at, false), BUDGET).unwrap();
    e.scene.layers[0].volume.check_invariants().unwrap();
    // Every sample and its mirror image across x = 0 rose alike (within 0.3 cells: the
    // field's distances are not bitwise symmetric far from the surface), and only one quarter
    // rose: the picture is mirrored, not repeated.
    let mut risen = 0;
    for (dx, dz) in [(3.0, 3.0), (-3.0, 3.0), (3.0, -3.0), (-3.0, -3.0)] {
        let (a, b) = (top(&e, 10.0 + dx, dz), top(&e, -10.0 - dx, dz));
        // (Raised by a fifth of the radius: 1.6.)
        assert!((a - b).abs() < 0.3, "({dx}, {dz}): {a} against its mirror image's {b}");
        assert!(a > 1.2 || a.abs() < 0.3, "({dx}, {dz}): {a}");
        risen += usize::from(a > 1.2);
    }
    assert_eq!(risen, 1);
    // An image this editor does not hold, and a loaded image in a room, are refused.
    let mut other = slab_editor();
    other.tool = e.tool;
    let refused = other.frame(&pose, BUDGET);
    assert!(matches!(refused, Err(EditorError::UnknownStamp)), "{refused:?}");
    e.record_ops(true);
    assert!(matches!(e.frame(&pose, BUDGET), Err(EditorError::NotShared(_))));
    e.tool.stamp.source = StampSource::default();
    e.frame(&pose, BUDGET).unwrap();
}

#[test]
fn pressure_curves_scale_size_and_strength_and_a_switch_turns_pressure_off() {
    use strata_volume::tools::FalloffCurve;
    let mut e = Editor::default();
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 4.0;
    e.tool.strength = 1.0;
    e.tool.pressure_to_strength = 1.0;
    // Size: a fifth of the radius at no pressure, rising steeply to full by half pressure.
    e.tool.pressure.size = FalloffCurve::new(&[(0.0, 0.2), (0.5, 1.0), (1.0, 1.0)]).unwrap();
    assert!((e.tool.radius_at(0.0) - 0.8).abs() < 1e-6, "(points are kept as f32)");
    assert!((e.tool.radius_at(0.5) - 4.0).abs() < 1e-6);
    assert!(e.tool.radius_at(0.25) > 0.8 && e.tool.radius_at(0.25) < 4.0);
    assert_eq!(e.tool.radius_at(f64::NAN), e.tool.radius_at(0.0), "NaN pressure reads as none");
    assert!((e.tool.field_strength_at(0.5) - 0.25).abs() < 1e-12, "the linear strength curve halves it");
    // A dab at pressure 0.1 is the brush of the curve's radius there.
    let p = DVec3::new(0.5, 0.25, -0.5);
    let r = e.tool.radius_at(0.1);
    let pose = ToolPose { position: p, pressure: 0.1, buttons: DOWN, ..ToolPose::default() };
    e.frame(&pose, BUDGET).unwrap();
    e.frame(&ToolPose::at(p, false), BUDGET).unwrap();
    let mut direct = Volume::new();
    let t = e.scene.layers[0].transform;
    direct.add(&Sphere::new(t.to_grid(p), r / t.scale).unwrap()).unwrap();
    assert_eq!(e.scene.layers[0].volume, direct);
    // Off: every dab as at full pressure.
    e.tool.pressure.enabled = false;
    assert_eq!(e.tool.radius_at(0.1), 4.0);
    assert_eq!(e.tool.field_strength_at(0.1), e.tool.field_strength);
}
