//! The layers panel: select, show, lock, rename, move, turn and scale layers; add, duplicate,
//! delete, reorder and merge them; the resolution of new layers.

use super::*;

impl StudioApp {
    pub(super) fn layers(&mut self, ui: &mut egui::Ui) {
        ui.heading("Layers");
        if self.studio.terrain.is_some() {
            ui.label("Terrain mode: the tools edit the world. Terrain > Close world goes back to the scene's layers.");
            return;
        }
        let mut changed = false;
        let mut edited = false;
        let active = self.studio.editor.active_layer;
        let mut select = None;
        for (i, layer) in self.studio.editor.scene.layers.iter_mut().enumerate() {
            ui.horizontal(|ui| {
                if ui
                    .selectable_label(i == active, &layer.name)
                    .on_hover_text("Select: the tools edit this layer")
                    .clicked()
                {
                    select = Some(i);
                }
                changed |=
                    ui.checkbox(&mut layer.visible, "visible").on_hover_text("Show and export this layer").changed();
                edited |=
                    ui.checkbox(&mut layer.locked, "locked").on_hover_text("Keep the tools off this layer").changed();
            });
        }
        if let Some(i) = select {
            self.studio.editor.active_layer = i;
        }
        let active = self.studio.editor.active_layer;
        if let Some(layer) = self.studio.editor.scene.layers.get_mut(active) {
            ui.horizontal(|ui| {
                let label = ui.label("Name");
                // (In a shared room names are the room's: a local rename would not be seen.)
                let shared = self.studio.collab.is_some();
                edited |= ui
                    .add_enabled(!shared, egui::TextEdit::singleline(&mut layer.name))
                    .labelled_by(label.id)
                    .on_hover_text("The active layer's name")
                    .changed();
            });
        }
        // Move, turn (about the vertical) and scale the layer; a drag is one undo step.
        if let Some(mut t) = self.studio.editor.scene.layers.get(active).map(|l| l.transform) {
            let (mut yaw, _, _) = t.rotation.to_euler(glam::EulerRot::YXZ);
            yaw = yaw.to_degrees();
            let mut changed_t = false;
            let mut dragging = false;
            ui.horizontal(|ui| {
                ui.label("Move");
                for (k, name) in ["x ", "y ", "z "].into_iter().enumerate() {
                    let r = ui
                        .add(egui::DragValue::new(&mut t.translation[k]).speed(0.1).prefix(name))
                        .on_hover_text("Where the layer's grid point 0 is (world units); a drag is one undo step");
                    changed_t |= r.changed();
                    dragging |= r.dragged() && !r.drag_started();
                }
            });
            ui.horizontal(|ui| {
                let r = ui
                    .add(egui::DragValue::new(&mut yaw).speed(0.5).suffix("°").prefix("turn "))
                    .on_hover_text("The layer's turn about the vertical");
                changed_t |= r.changed();
                dragging |= r.dragged() && !r.drag_started();
                let r = ui
                    .add(egui::DragValue::new(&mut t.scale).speed(0.01).range(1e-3..=1e3).prefix("scale "))
                    .on_hover_text("World units per cell of the layer");
                changed_t |= r.changed();
                dragging |= r.dragged() && !r.drag_started();
            });
            if changed_t && let Err(e) = self.studio.refuse_in_session("move, turn or scale a layer") {
                self.studio.message = e;
            } else if changed_t {
                let (_, pitch, roll) = t.rotation.to_euler(glam::EulerRot::YXZ);
                t.rotation = glam::DQuat::from_euler(glam::EulerRot::YXZ, yaw.to_radians(), pitch, roll);
                match self.studio.editor.set_layer_transform(active, t, dragging) {
                    Ok(()) => {}
                    Err(e) => self.studio.message = e.to_string(),
                }
            }
        }
        if let Some(l) = self.studio.editor.scene.layers.get(self.studio.editor.active_layer) {
            let base = l.volume.level().cells();
            ui.label(format!("Base resolution {base}³ cells per chunk")).on_hover_text(
                "New chunks of this layer get this resolution; the detail tool (D) raises chunks above it",
            );
        }
        ui.horizontal(|ui| {
            ui.label("new layers");
            for k in 0..=strata_volume::coords::MAX_LEVEL {
                let level = strata_volume::Level::new(k).expect("a level");
                ui.selectable_value(&mut self.studio.new_layer_level, level, format!("{}³", 16 << k))
                    .on_hover_text("The base resolution (cells per chunk side) of layers added with Add");
            }
        });
        ui.horizontal(|ui| {
            if ui.button("Add").on_hover_text("Add an empty layer").clicked() {
                let _ = self.studio.act(Action::AddLayer);
            }
            if ui.button("Duplicate").on_hover_text("Copy the selected layer").clicked() {
                let _ = self.studio.act(Action::DuplicateLayer);
            }
            if ui.button("Delete").on_hover_text("Delete the selected layer (clears undo)").clicked() {
                let _ = self.studio.act(Action::DeleteLayer);
            }
        });
        ui.horizontal(|ui| {
            if ui.button("Up").on_hover_text("Move the selected layer up the list").clicked() {
                let _ = self.studio.act(Action::MoveLayer(-1));
            }
            if ui.button("Down").on_hover_text("Move the selected layer down the list").clicked() {
                let _ = self.studio.act(Action::MoveLayer(1));
            }
            if ui
                .button("Merge down")
                .on_hover_text("Merge the selected layer into the one below it (same rotation and cell size)")
                .clicked()
            {
                let _ = self.studio.act(Action::MergeDown);
            }
        });
        if changed || edited {
            self.studio.editor.touch();
        }
    }
}
