//! The reference images panel (under the layers): each picture's switch, lock and selection;
//! the selected one's plane, opacity, width, place and turn, a button that looks at it square
//! on, and delete. Every change is an undo step, a drag one step.

use glam::DQuat;
use strata_editor::{ReferenceImage, ReferencePlane};

use super::*;

/// The turn of `r` within its plane (degrees), when it lies square to one.
fn in_plane_turn(r: &ReferenceImage) -> Option<(ReferencePlane, f64)> {
    let plane = r.plane()?;
    let rel = plane.rotation().inverse() * r.rotation;
    Some((plane, (2.0 * rel.z.atan2(rel.w)).to_degrees()))
}

impl StudioApp {
    pub(super) fn references_panel(&mut self, ui: &mut egui::Ui) {
        if self.studio.terrain.is_some() {
            return;
        }
        let count = self.studio.editor.scene.references.len();
        // (A picture just loaded opens the panel, so its controls are in sight.)
        let opened = (count > self.references_seen).then_some(true);
        self.references_seen = count;
        egui::CollapsingHeader::new(format!("Reference images ({count})"))
            .id_salt("reference images")
            .open(opened)
            .show(ui, |ui| self.reference_rows(ui));
    }

    fn reference_rows(&mut self, ui: &mut egui::Ui) {
        let mut select = None;
        let mut changed: Option<(usize, ReferenceImage)> = None;
        let selected = self.studio.selected_reference;
        for (i, r) in self.studio.editor.scene.references.iter().enumerate() {
            ui.horizontal(|ui| {
                let name = if r.name.chars().count() > 18 {
                    format!("{}…", r.name.chars().take(17).collect::<String>())
                } else {
                    r.name.clone()
                };
                if ui
                    .selectable_label(selected == Some(i), name)
                    .on_hover_text(format!(
                        "{}: select it to change it (the gizmo moves it while it is unlocked)",
                        r.name
                    ))
                    .clicked()
                {
                    select = Some(if selected == Some(i) { None } else { Some(i) });
                }
                let mut shown = r.visible;
                if ui.checkbox(&mut shown, "shown").on_hover_text("Draw this reference image").changed() {
                    changed = Some((i, ReferenceImage { visible: shown, ..r.clone() }));
                }
                let mut locked = r.locked;
                if ui
                    .checkbox(&mut locked, "locked in place")
                    .on_hover_text("Keep it where it is: no moving, turning, scaling or deleting until unlocked")
                    .changed()
                {
                    changed = Some((i, ReferenceImage { locked, ..r.clone() }));
                }
            });
        }
        if let Some(s) = select {
            self.studio.selected_reference = s;
        }
        if let Some((i, r)) = changed {
            self.studio.set_reference(i, r, false);
        }
        if ui
            .button(labelled("Load…", Command::LoadReference))
            .on_hover_text("Load a PNG or JPEG as a reference image, square to the view the camera is in")
            .clicked()
        {
            let ctx = ui.ctx().clone();
            self.ask_path(&ctx, Prompt::LoadReference, None);
        }
        let Some((i, r)) = self.studio.reference().map(|(i, r)| (i, r.clone())) else { return };
        ui.separator();
        let free = !r.locked;
        let mut next = r.clone();
        let mut dragging = false;
        let mut lay = None;
        ui.horizontal(|ui| {
            ui.label("Plane").on_hover_text("The view the picture lies square to");
            for plane in ReferencePlane::ALL {
                if ui
                    .add_enabled(free, egui::Button::selectable(r.plane() == Some(plane), plane.name()))
                    .on_hover_text(format!(
                        "Lay it square to the {} view, keeping its middle and width",
                        plane.name().to_lowercase()
                    ))
                    .clicked()
                {
                    lay = Some(plane);
                }
            }
        });
        let r1 = ui
            .add(egui::Slider::new(&mut next.opacity, 0.0..=1.0).text("opacity"))
            .on_hover_text("How much of the picture shows: 0 transparent, 1 opaque");
        dragging |= r1.dragged() && !r1.drag_started();
        ui.add_enabled_ui(free, |ui| {
            ui.horizontal(|ui| {
                let w = ui
                    .add(
                        egui::DragValue::new(&mut next.width)
                            .range(strata_editor::reference::WIDTH_RANGE.0..=strata_editor::reference::WIDTH_RANGE.1)
                            .speed(r.width * 0.005)
                            .prefix("width "),
                    )
                    .on_hover_text("Its width in world units (its height follows the picture)");
                dragging |= w.dragged() && !w.drag_started();
                if let Some((plane, mut turn)) = in_plane_turn(&r) {
                    let t = ui
                        .add(egui::DragValue::new(&mut turn).speed(0.5).suffix("°").prefix("turn "))
                        .on_hover_text("Its turn within its plane");
                    if t.changed() {
                        next.rotation = plane.rotation() * DQuat::from_rotation_z(turn.to_radians());
                    }
                    dragging |= t.dragged() && !t.drag_started();
                }
            });
            ui.horizontal(|ui| {
                ui.label("Middle");
                let mut c = next.center;
                for (k, name) in ["x ", "y ", "z "].into_iter().enumerate() {
                    let d = ui
                        .add(egui::DragValue::new(&mut c[k]).speed(0.1).prefix(name))
                        .on_hover_text("Where the picture's middle is (world units)");
                    dragging |= d.dragged() && !d.drag_started();
                }
                next.center = c;
            });
        });
        ui.horizontal(|ui| {
            if r.plane().is_some()
                && ui
                    .button("Look at it")
                    .on_hover_text("The view the picture is square to, centred on it (the front, right or top view)")
                    .clicked()
            {
                self.look_at_reference(i);
            }
            if ui
                .add_enabled(free, egui::Button::new("Delete image"))
                .on_hover_text("Delete this reference image (Ctrl+Z brings it back)")
                .clicked()
            {
                self.studio.delete_reference(i);
            }
        });
        // (A drag is one undo step: its first change makes the step, the rest join it; the
        // first frame that changes nothing makes none, so nothing joins an older step.)
        let dragging = dragging || ui.ctx().dragged_id().is_some();
        if let Some(plane) = lay {
            self.studio.lay_reference(i, plane);
        } else if next != r {
            let join = dragging && self.reference_drag == Some(i);
            if self.studio.set_reference(i, next, join) {
                self.reference_drag = dragging.then_some(i);
            }
        } else if !dragging {
            self.reference_drag = None;
        }
    }
}
