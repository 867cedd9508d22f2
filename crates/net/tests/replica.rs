//! The replica takes back at once what a room would refuse as out of bounds, instead of
//! sending it, and keeps the good operations around it.

use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::file::chunk_digests;
use strata_editor::{Buttons, Editor, LayerTransform, ToolKind, ToolPose};
use strata_net::protocol::ClientMsg;
use strata_net::{Event, Replica};

fn dab(e: &mut Editor, at: DVec3) {
    let pose = ToolPose { position: at, buttons: Buttons { primary: true, secondary: false }, ..ToolPose::default() };
    e.frame(&pose, Duration::ZERO).unwrap();
    e.frame(&ToolPose::at(at, false), Duration::ZERO).unwrap();
}

#[test]
fn an_operation_out_of_bounds_is_taken_back_and_not_sent() {
    let mut e = Editor::default();
    // A layer of tiny cells: a brush of radius 3 is 300 cells across its grid, over the bound.
    e.scene.layers[0].transform = LayerTransform::new(DVec3::ZERO, DQuat::IDENTITY, 0.01).unwrap();
    e.record_ops(true);
    e.tool.kind = ToolKind::Add;
    let mut replica = Replica::new();
    let start = chunk_digests(&e.scene).unwrap();
    // A good dab, a dab too large, a good dab: all applied locally in that order.
    e.tool.radius = 0.05;
    dab(&mut e, DVec3::new(0.1, 0.0, 0.0));
    e.tool.radius = 3.0;
    dab(&mut e, DVec3::ZERO);
    e.tool.radius = 0.05;
    dab(&mut e, DVec3::new(-0.1, 0.0, 0.0));
    let step = replica.step(&mut e, Vec::new());
    assert!(step.events.iter().any(|ev| matches!(ev, Event::Refused(r) if r.contains("radius"))), "{:?}", step.events);
    assert_eq!(replica.pending(), 2, "the two good dabs stay pending");
    assert!(step.send.iter().all(|m| !matches!(m, ClientMsg::Submit { .. })), "nothing is sent before a welcome");
    // What is left equals the two good dabs alone.
    let mut reference = Editor::default();
    reference.scene.layers[0].transform = e.scene.layers[0].transform;
    reference.tool.kind = ToolKind::Add;
    reference.tool.radius = 0.05;
    dab(&mut reference, DVec3::new(0.1, 0.0, 0.0));
    dab(&mut reference, DVec3::new(-0.1, 0.0, 0.0));
    assert_ne!(chunk_digests(&e.scene).unwrap(), start);
    assert_eq!(chunk_digests(&e.scene).unwrap(), chunk_digests(&reference.scene).unwrap());
}
