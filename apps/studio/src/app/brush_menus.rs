//! The Brush and Layer menus: every option of the tool panel, the layers panel and the selected
//! reference image as a menu entry too, so nothing is reachable by the pointer on a panel alone
//! (the binding table, `keymap::CONTROLS`, records how each panel control is reached; a UI test
//! checks it).

use strata_editor::ReferencePlane;
use strata_volume::tools::Falloff;

use super::*;

impl StudioApp {
    /// Brush: shape, stabiliser, mirror, radius on screen, surface following and orientation,
    /// stroke lock, pressure, falloff, the stamp's and smooth's and detail's options, the
    /// eyedropper and a new material.
    pub(super) fn brush_menu(&mut self, ui: &mut egui::Ui) {
        ui.menu_button("Shape", |ui| {
            for (shape, name) in [
                (BrushShape::Sphere, "Sphere"),
                (BrushShape::Box, "Box"),
                (BrushShape::Capsule, "Capsule"),
                (BrushShape::Cylinder, "Cylinder"),
            ] {
                ui.radio_value(&mut self.studio.editor.tool.shape, shape, name).on_hover_text(format!(
                    "The add and erase brushes' shape ({} cycles)",
                    keys_of(Command::NextShape)
                ));
            }
        });
        ui.menu_button(labelled("Stabiliser", Command::Stabiliser), |ui| {
            for s in strata_editor::Stabiliser::ALL {
                ui.radio_value(&mut self.studio.editor.stabiliser, s, s.name())
                    .on_hover_text("How far the brush trails the pointer on its rope");
            }
        });
        ui.menu_button("Mirror", |ui| {
            for (axis, name) in ["X", "Y", "Z"].into_iter().enumerate() {
                let mut on = self.studio.editor.tool.symmetry[axis];
                let label = if axis == 0 { labelled(name, Command::MirrorX) } else { name.to_string() };
                if ui
                    .checkbox(&mut on, label)
                    .on_hover_text("Mirror every dab across this plane of the layer")
                    .changed()
                {
                    self.studio.toggle_symmetry(axis);
                }
            }
        });
        ui.menu_button("Lock stroke", |ui| {
            let lock = &mut self.studio.editor.tool.axis_lock;
            ui.radio_value(lock, None, "Off").on_hover_text("Strokes go where the pointer goes");
            for (axis, name) in ["Along X", "Along Y", "Along Z"].into_iter().enumerate() {
                ui.radio_value(lock, Some(axis), name)
                    .on_hover_text("Keep a stroke on the line through its start along this axis of the layer");
            }
        });
        ui.menu_button("Falloff", |ui| {
            for f in Falloff::NAMED {
                ui.radio_value(&mut self.studio.editor.tool.falloff, f, f.name())
                    .on_hover_text("How the strength falls from the brush's centre to its rim");
            }
        });
        let tool = &mut self.studio.editor.tool;
        ui.checkbox(&mut self.studio.screen_radius, "Radius on screen")
            .on_hover_text("Keep the brush's size on screen as the view zooms");
        ui.checkbox(&mut tool.follow_surface, "Follow the surface")
            .on_hover_text("Strokes follow the surface under the pointer; off, a stroke keeps its starting depth");
        ui.checkbox(&mut tool.orient_to_normal, "Orient brush to surface")
            .on_hover_text("Turn box, capsule and cylinder brushes onto the surface normal");
        ui.checkbox(&mut tool.pressure.enabled, labelled("Pen pressure", Command::Pressure))
            .on_hover_text("A pen's or a touch's pressure scales the brush");
        ui.checkbox(&mut tool.paper_smoothing, "Paper's smoothing (Eq. 1)")
            .on_hover_text("The smooth tool moves crossings towards their neighbours' mean");
        ui.menu_button("Detail raises to", |ui| {
            for k in 1..=strata_volume::coords::MAX_LEVEL {
                let level = strata_volume::Level::new(k).expect("a level");
                ui.radio_value(&mut self.studio.editor.tool.detail_level, level, format!("{}³ cells", 16 << k))
                    .on_hover_text("Cells per chunk side the detail tool gives the chunks under the brush");
            }
        });
        ui.separator();
        let stamp = &mut self.studio.editor.tool.stamp;
        let spray = stamp.stroke == strata_editor::StampStroke::Spray;
        if ui
            .button(labelled(if spray { "Stamp: drag out one" } else { "Stamp: spray" }, Command::StampStroke))
            .on_hover_text("Spray stamps along the stroke, or drag out one")
            .clicked()
        {
            self.studio.toggle_stamp_stroke();
        }
        ui.checkbox(&mut self.studio.editor.tool.stamp.follow_stroke, "Stamp follows the stroke")
            .on_hover_text("A sprayed stamp's top points along the stroke (else up the screen)");
        if ui
            .button(labelled("Next stamp picture", Command::NextStamp))
            .on_hover_text("The stamp's next picture: built in, then loaded")
            .clicked()
        {
            self.studio.next_stamp();
        }
        ui.separator();
        if ui
            .button(labelled("Eyedropper", Command::Eyedropper))
            .on_hover_text("Click the model to take the material under the pointer")
            .clicked()
        {
            self.studio.toggle_eyedropper();
            ui.close();
        }
        if ui.button("New material").on_hover_text("Add a material to the palette and make it current").clicked() {
            self.studio.add_material();
            ui.close();
        }
    }

    /// Layer: add, duplicate, delete, reorder and merge; the active layer's switches; new layers'
    /// resolution; and the selected reference image's switches, plane, view and delete.
    pub(super) fn layer_menu(&mut self, ui: &mut egui::Ui) {
        for (name, action, tip) in [
            ("Add layer", Action::AddLayer, "Add an empty layer"),
            ("Duplicate layer", Action::DuplicateLayer, "Copy the active layer"),
            ("Delete layer", Action::DeleteLayer, "Delete the active layer"),
            ("Move layer up", Action::MoveLayer(-1), "Move the active layer up the list"),
            ("Move layer down", Action::MoveLayer(1), "Move the active layer down the list"),
            ("Merge down", Action::MergeDown, "Merge the active layer into the one below it"),
        ] {
            if ui.button(name).on_hover_text(tip).clicked() {
                let _ = self.studio.act(action);
                ui.close();
            }
        }
        let active = self.studio.editor.active_layer;
        if let Some(layer) = self.studio.editor.scene.layers.get_mut(active) {
            let mut changed =
                ui.checkbox(&mut layer.visible, "Layer visible").on_hover_text("Show and export it").changed();
            changed |= ui.checkbox(&mut layer.locked, "Layer locked").on_hover_text("Keep the tools off it").changed();
            if changed {
                self.studio.editor.touch();
            }
        }
        ui.menu_button("New layers' resolution", |ui| {
            for k in 0..=strata_volume::coords::MAX_LEVEL {
                let level = strata_volume::Level::new(k).expect("a level");
                ui.radio_value(&mut self.studio.new_layer_level, level, format!("{}³ cells", 16 << k))
                    .on_hover_text("The base resolution of layers added from now on");
            }
        });
        ui.separator();
        let Some((i, r)) = self.studio.reference().map(|(i, r)| (i, r.clone())) else {
            ui.label("Select a reference image in its panel for its entries here");
            return;
        };
        ui.menu_button(format!("Reference image {}", r.name), |ui| {
            let mut next = r.clone();
            ui.checkbox(&mut next.visible, "Shown").on_hover_text("Draw this reference image");
            ui.checkbox(&mut next.locked, "Locked in place").on_hover_text("Keep its place, turn and size");
            if next != r {
                self.studio.set_reference(i, next, false);
            }
            for plane in ReferencePlane::ALL {
                if ui
                    .add_enabled(!r.locked, egui::Button::new(format!("Lay square to the {} view", plane.name())))
                    .on_hover_text("Keep its middle and width")
                    .clicked()
                {
                    self.studio.lay_reference(i, plane);
                    ui.close();
                }
            }
            if ui
                .add_enabled(r.plane().is_some(), egui::Button::new("Look at it"))
                .on_hover_text("The view it is square to, centred on it")
                .clicked()
            {
                self.look_at_reference(i);
                ui.close();
            }
            if ui
                .add_enabled(!r.locked, egui::Button::new("Delete reference image"))
                .on_hover_text("Ctrl+Z brings it back")
                .clicked()
            {
                self.studio.delete_reference(i);
                ui.close();
            }
        });
    }

    /// The axis view reference `i` lies square to, centred on it.
    pub(super) fn look_at_reference(&mut self, i: usize) {
        let Some(r) = self.studio.editor.scene.references.get(i) else { return };
        let Some((plane, opposite)) = r.view() else { return };
        let view = match plane {
            ReferencePlane::Front => strata_render::AxisView::Front,
            ReferencePlane::Side => strata_render::AxisView::Right,
            ReferencePlane::Top => strata_render::AxisView::Top,
        };
        self.studio.camera.target = r.center.as_vec3();
        let _ = self.studio.act(Action::AxisView(view, opposite));
    }
}
