//! Masks through the editor: the mask tool's strokes (add, take off, smooth with the smooth
//! modifier) protect what they cover from every other tool, the whole-mask actions undo as one
//! step each, they are refused in a room and on a world, and scenes keep their masks through a
//! save (an older file opens without one; a damaged chunk of a mask is dropped and named).

use std::time::Duration;

use glam::{DQuat, DVec3, I64Vec3};
use strata_editor::{Buttons, Editor, EditorError, Layer, MaskAction, Modifiers, Scene, ToolKind, ToolPose, file};
use strata_volume::brush::Cuboid;
use strata_volume::{PROTECTED, Volume};

const BUDGET: Duration = Duration::from_millis(50);
const DOWN: Buttons = Buttons { primary: true, secondary: false };
const OFF: Buttons = Buttons { primary: false, secondary: true };

/// Frames moving the tool from `a` to `b` with `buttons` and `modifiers`, then a release.
fn drag(e: &mut Editor, a: DVec3, b: DVec3, buttons: Buttons, modifiers: Modifiers) {
    let steps = 16;
    for i in 0..=steps {
        let p = a.lerp(b, i as f64 / steps as f64);
        let pose = ToolPose { position: p, orientation: DQuat::IDENTITY, pressure: 1.0, buttons, modifiers };
        e.frame(&pose, BUDGET).unwrap();
    }
    e.frame(&ToolPose::at(b, false), BUDGET).unwrap();
}

/// A box with sharp edges (smoothing rounds them), its top at y = 24.
fn boxed() -> Editor {
    let mut v = Volume::new();
    v.add(&Cuboid::new(DVec3::new(24.0, 16.0, 24.0), DVec3::new(14.0, 8.0, 6.0)).unwrap()).unwrap();
    Editor::new(Scene { layers: vec![Layer { volume: v, ..Layer::new("box") }], ..Scene::default() })
}

fn states(v: &Volume, nodes: &[I64Vec3]) -> Vec<bool> {
    nodes.iter().map(|n| v.node_inside(*n)).collect()
}

fn all_nodes() -> Vec<I64Vec3> {
    (0..48).flat_map(|z| (0..34).flat_map(move |y| (0..48).map(move |x| I64Vec3::new(x, y, z)))).collect()
}

#[test]
fn a_masked_region_keeps_its_shape_under_smoothing_across_it() {
    let mut e = boxed();
    e.tool.kind = ToolKind::Mask;
    e.tool.radius = 7.0;
    e.tool.field_strength = 1.0;
    // Mask the box's left end (x < 20) along its top edge and its sides.
    for z in [18.0, 24.0, 30.0] {
        drag(&mut e, DVec3::new(8.0, 24.0, z), DVec3::new(14.0, 24.0, z), DOWN, Modifiers::default());
        drag(&mut e, DVec3::new(8.0, 8.0, z), DVec3::new(14.0, 8.0, z), DOWN, Modifiers::default());
    }
    assert_eq!(e.history().undo_len(), 6, "each mask stroke is one undo step");
    let v = &e.scene.layers[0].volume;
    assert_eq!(v.mask().weight(I64Vec3::new(10, 24, 24)), PROTECTED);
    assert_eq!(v.mask().weight(I64Vec3::new(38, 24, 24)), 0);
    let held: Vec<I64Vec3> = all_nodes().into_iter().filter(|n| v.mask().weight(*n) == PROTECTED).collect();
    let free: Vec<I64Vec3> = all_nodes().into_iter().filter(|n| n.x > 30).collect();
    assert!(held.len() > 500, "{} nodes held", held.len());
    let (held_before, free_before) = (states(v, &held), states(v, &free));
    // Smooth along the whole top edge, the masked end included.
    e.tool.kind = ToolKind::Smooth;
    e.tool.radius = 5.0;
    for z in [18.0, 30.0] {
        drag(&mut e, DVec3::new(8.0, 24.0, z), DVec3::new(40.0, 24.0, z), DOWN, Modifiers::default());
    }
    let v = &e.scene.layers[0].volume;
    v.check_invariants().unwrap();
    assert!(states(v, &held) == held_before, "the masked end changed");
    assert!(states(v, &free) != free_before, "the free end was smoothed");
    // Taking the mask off (the inverse) then frees it; smoothing the mask softens its edge.
    let mask_before = v.mask().clone();
    e.tool.kind = ToolKind::Mask;
    drag(&mut e, DVec3::new(8.0, 24.0, 24.0), DVec3::new(9.0, 24.0, 24.0), OFF, Modifiers::default());
    assert!(e.scene.layers[0].volume.mask().weight(I64Vec3::new(8, 24, 24)) < PROTECTED / 4);
    let shift = Modifiers { smooth: true, ..Modifiers::default() };
    let edge = I64Vec3::new(19, 8, 24);
    let before = e.scene.layers[0].volume.mask().weight(edge);
    drag(&mut e, DVec3::new(17.0, 8.0, 24.0), DVec3::new(21.0, 8.0, 24.0), DOWN, shift);
    let after = e.scene.layers[0].volume.mask().weight(edge);
    assert_ne!(before, after, "the smooth modifier smooths the mask");
    // Undoing the two mask strokes gives the mask back exactly, and the shape is untouched.
    let shape = e.scene.layers[0].volume.chunks().map(|(k, c)| (k, c.clone())).collect::<Vec<_>>();
    assert!(e.undo());
    assert!(e.undo());
    assert!(*e.scene.layers[0].volume.mask() == mask_before);
    assert!(e.scene.layers[0].volume.chunks().map(|(k, c)| (k, c.clone())).collect::<Vec<_>>() == shape);
}

#[test]
fn whole_mask_actions_are_one_undo_step_each_and_refused_in_a_room() {
    let mut e = boxed();
    e.tool.kind = ToolKind::Mask;
    e.tool.radius = 4.0;
    e.tool.field_strength = 1.0;
    drag(&mut e, DVec3::new(20.0, 24.0, 24.0), DVec3::new(24.0, 24.0, 24.0), DOWN, Modifiers::default());
    let painted = e.scene.layers[0].volume.clone();
    let mut after = Vec::new();
    for a in [MaskAction::Invert, MaskAction::Grow, MaskAction::Shrink, MaskAction::Clear] {
        e.mask_all(0, a).unwrap();
        after.push(e.scene.layers[0].volume.clone());
    }
    assert!(e.scene.layers[0].volume.mask().is_clear(), "the last action clears it");
    assert_eq!(after[0].mask().weight(I64Vec3::new(0, 0, 0)), PROTECTED, "inverting holds what was free");
    assert_eq!(after[0].mask().weight(I64Vec3::new(22, 24, 24)), 0, "and frees what was held");
    for (i, v) in after.iter().enumerate().rev().skip(1) {
        assert!(e.undo());
        let now = &e.scene.layers[0].volume;
        assert!(
            now.mask() == v.mask(),
            "undo back to after action {i}: outside {} vs {}, {} vs {} chunks",
            now.mask().outside(),
            v.mask().outside(),
            now.mask().chunks().count(),
            v.mask().chunks().count()
        );
        assert!(*now == *v);
    }
    assert!(e.undo());
    assert!(e.scene.layers[0].volume == painted);
    assert!(e.redo());
    assert!(e.scene.layers[0].volume == after[0]);
    // Undoing an inversion redraws every chunk (its shading changes everywhere).
    e.finish_meshing();
    assert_eq!(e.pending(), 0);
    assert!(e.undo());
    assert!(e.pending() >= e.scene.layers[0].volume.chunk_count(), "{} chunks queued", e.pending());
    e.finish_meshing();
    e.record_ops(true);
    assert!(matches!(e.mask_all(0, MaskAction::Clear), Err(EditorError::NotShared(_))));
    e.record_ops(false);
    assert!(matches!(e.mask_all(7, MaskAction::Clear), Err(EditorError::NoLayer(7))));
}

#[test]
fn masks_survive_a_save_and_older_files_open_without_one() {
    let mut e = boxed();
    e.tool.kind = ToolKind::Mask;
    e.tool.radius = 5.0;
    e.tool.field_strength = 0.6;
    drag(&mut e, DVec3::new(10.0, 24.0, 24.0), DVec3::new(30.0, 24.0, 24.0), DOWN, Modifiers::default());
    e.mask_all(0, MaskAction::Grow).unwrap();
    let scene = e.scene.clone();
    assert!(!scene.layers[0].volume.mask().is_clear());
    let bytes = file::encode(&scene).unwrap();
    let back = file::decode(&bytes).unwrap();
    assert!(back.report.repairs.is_empty(), "{}", back.report);
    assert_eq!(back.version, 5, "a scene without reference images is written as version 5");
    assert!(back.scene == scene, "the mask came back bit for bit");
    // The same scene as version 4 wrote it: it opens, its mask clear, nothing else lost.
    let old = file::decode(&file::encode_version_4(&scene).unwrap()).unwrap();
    assert_eq!(old.version, 4);
    assert!(old.scene.layers[0].volume.mask().is_clear());
    let mut unmasked = scene.clone();
    unmasked.layers[0].volume.set_mask(Default::default());
    assert!(old.scene == unmasked);
    // A damaged chunk of a mask is dropped and named; the rest of the mask stays.
    let mut record = file::scene_record(&scene, true).unwrap();
    assert!(record.layers[0].masks.len() >= 2);
    record.layers[0].masks[0].bytes[0] ^= 0x55;
    let damaged = file::decode(&file::encode_record(&record).unwrap()).unwrap();
    assert!(damaged.report.repairs.iter().any(|r| r.contains("the mask of chunk")), "{}", damaged.report);
    assert_eq!(damaged.scene.layers[0].volume.mask().chunks().count(), record.layers[0].masks.len() - 1);
}
