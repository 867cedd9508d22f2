//! The menu bar: File, Edit, View, Terrain and Help, with the keys of the binding table in
//! their labels.

use super::*;

/// A mesher picker (one radio button a mesher: menus stay open while one is picked) with a
/// simplification toggle and error, under `label`; false while the error
/// slider is being dragged. Dual contouring is simplified on export only, so the viewport's
/// picker offers it without.
pub(super) fn mesher_choice(
    ui: &mut egui::Ui,
    viewport: bool,
    label: &str,
    options: &mut strata_mesh::MeshOptions,
) -> bool {
    ui.label(label);
    for m in strata_mesh::Mesher::ALL {
        ui.radio_value(&mut options.mesher, m, m.name()).on_hover_text(m.summary());
    }
    let can_simplify = !viewport || options.mesher.block().is_some();
    if !can_simplify {
        options.simplify = None;
    }
    let mut on = options.simplify.is_some();
    let text = if viewport { "Simplify chunks (borders kept)" } else { "Simplify (meshoptimizer)" };
    if ui
        .add_enabled(can_simplify, egui::Checkbox::new(&mut on, text))
        .on_hover_text("Fewer triangles, within the error below")
        .changed()
    {
        options.simplify = on.then_some(0.1);
    }
    let mut settled = true;
    if let Some(e) = options.simplify.as_mut() {
        let r = ui
            .add(egui::Slider::new(e, 0.01..=1.0).logarithmic(true).text("error (cells)"))
            .on_hover_text("How far the simplified surface may stray, in cells");
        // While the slider is dragged nothing is remeshed; its last value counts.
        settled = !r.dragged() || r.drag_stopped();
    }
    settled
}

impl StudioApp {
    pub(super) fn menu(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button(labelled("New", Command::New)).on_hover_text("Start a new scene (asks first if there is unsaved work)").clicked() {
                    self.guard(&ctx, Then::New);
                }
                if ui.button(labelled("Open…", Command::Open)).on_hover_text("Open a scene file (.strata)").clicked() {
                    self.guard(&ctx, Then::Open);
                }
                ui.menu_button("Open recent", |ui| {
                    ui.label("Scenes opened or saved lately").on_hover_text("Kept in the recovery folder's recent.txt");
                    let recent: Vec<PathBuf> = self.recent.paths().to_vec();
                    if recent.is_empty() {
                        ui.label("No recent scenes");
                    }
                    for path in recent {
                        if ui.button(path.display().to_string()).on_hover_text("Open this scene").clicked() {
                            self.open_file(&ctx, path);
                        }
                    }
                });
                if ui
                    .button("Import mesh… (PLY, OBJ, STL, glTF)")
                    .on_hover_text("Convert a mesh into a new layer (or drop the file on the window)")
                    .clicked()
                {
                    self.ask_path(&ctx, Prompt::Import, None);
                }
                if ui
                    .button(labelled("Load stamp picture…", Command::LoadStamp))
                    .on_hover_text("Use a grey-scale PNG as the stamp tool's picture (or drop it on the window)")
                    .clicked()
                {
                    self.ask_path(&ctx, Prompt::LoadStamp, None);
                }
                if ui
                    .button(labelled("Load reference image…", Command::LoadReference))
                    .on_hover_text(
                        "A PNG or JPEG placed as a plane square to the view the camera is in, behind the model, to sculpt against",
                    )
                    .clicked()
                {
                    self.ask_path(&ctx, Prompt::LoadReference, None);
                }
                if ui.button(labelled("Save", Command::Save)).on_hover_text("Save the scene (asks for a path the first time)").clicked() {
                    self.save(&ctx, None);
                }
                if ui.button(labelled("Save as…", Command::SaveAs)).on_hover_text("Save the scene to a new file").clicked() {
                    self.ask_path(&ctx, Prompt::SaveAs, None);
                }
                ui.separator();
                if ui
                    .button("Export mesh… (glb, obj, stl, ply)")
                    .on_hover_text("Write the visible layers as one mesh, with the mesher chosen below")
                    .clicked()
                {
                    self.ask_path(&ctx, Prompt::Export, None);
                }
                mesher_choice(ui, false, "Export with", &mut self.studio.export);
                ui.label("Remove islands");
                for (choice, name) in [
                    (crate::studio::Islands::ForStl, "for STL"),
                    (crate::studio::Islands::Remove, "always"),
                    (crate::studio::Islands::Keep, "never"),
                ] {
                    ui.radio_value(&mut self.studio.islands, choice, name)
                        .on_hover_text("Drop stray pieces of the surface (isolated solid nodes) from exports");
                }
                ui.add(
                    egui::DragValue::new(&mut self.studio.island_cells)
                        .range(0.0..=1.0e6)
                        .speed(0.5)
                        .prefix("smaller than ")
                        .suffix(" cells³"),
                )
                .on_hover_text("The smallest piece an export keeps, in cells³ of its layer's grid");
                ui.separator();
                let in_room = self.studio.in_session();
                if ui
                    .add_enabled(!in_room, egui::Button::new("Host session…"))
                    .on_hover_text("Share this scene: others on the network sculpt it with you")
                    .clicked()
                {
                    self.open_session_dialog(&ctx, true);
                    ui.close();
                }
                if ui
                    .add_enabled(!in_room, egui::Button::new("Join session…"))
                    .on_hover_text("Sculpt a scene someone hosts (its address, room and token)")
                    .clicked()
                {
                    self.open_session_dialog(&ctx, false);
                    ui.close();
                }
                if ui
                    .add_enabled(in_room, egui::Button::new("Leave session"))
                    .on_hover_text("Leave the room (closing it if you host it); the scene stays here")
                    .clicked()
                {
                    let _ = self.studio.act(Action::LeaveSession);
                    ui.close();
                }
                ui.separator();
                if ui.button("Quit").on_hover_text("Close the studio (asks first if there is unsaved work)").clicked() {
                    self.guard(&ctx, Then::Quit);
                }
            });
            ui.menu_button("Edit", |ui| {
                if ui.button(labelled("Undo", Command::Undo)).on_hover_text("Take back the last step (a whole stroke)").clicked() {
                    let _ = self.studio.act(Action::Undo);
                }
                if ui.button(labelled("Redo", Command::Redo)).on_hover_text("Do again the last step taken back").clicked() {
                    let _ = self.studio.act(Action::Redo);
                }
                ui.separator();
                for a in strata_editor::MaskAction::ALL {
                    if ui.button(labelled(a.name(), Command::Mask(a))).on_hover_text(mask_tip(a)).clicked() {
                        let _ = self.studio.act(Action::Mask(a));
                        ui.close();
                    }
                }
                ui.separator();
                let mut gizmo = self.layer_gizmo;
                if ui
                    .checkbox(&mut gizmo, labelled("Transform gizmo", Command::LayerGizmo))
                    .on_hover_text("Handles on the active layer: drag to move, turn or scale it (one undo step a drag)")
                    .changed()
                {
                    self.toggle_layer_gizmo();
                }
                ui.menu_button("Insert mesh", |ui| {
                    ui.label("Placed with a press on the model, then added, subtracted or intersected")
                        .on_hover_text("Exactly: the core's CSG with the mesh as a brush");
                    let mut chosen = None;
                    for p in strata_editor::Primitive::ALL {
                        if ui
                            .button(p.name())
                            .on_hover_text("A closed primitive, placed with a press on the model")
                            .clicked()
                        {
                            chosen = Some(strata_editor::InsertMesh::primitive(p));
                        }
                    }
                    if ui.button("Bunny").on_hover_text("The Stanford bunny (built in)").clicked() {
                        chosen = Some(strata_editor::InsertMesh::bunny());
                    }
                    if let Some(m) = chosen {
                        self.studio.begin_insert(m);
                        ui.close();
                    }
                    if ui.button("From file…").on_hover_text("A closed mesh: PLY, OBJ, STL, glTF or GLB").clicked() {
                        self.ask_path(&ctx, Prompt::InsertMesh, None);
                        ui.close();
                    }
                    if self.studio.insert.is_some() {
                        ui.separator();
                        self.insert_buttons(ui);
                    }
                });
                ui.menu_button("Brush presets", |ui| {
                    ui.label("Pick a named brush").on_hover_text("Also the Presets shelf in the tool panel");
                    for (preset, _) in self.shelf() {
                        if ui.button(&preset.name).on_hover_text(preset.summary()).clicked() {
                            self.pick_preset(&preset);
                            ui.close();
                        }
                    }
                    ui.separator();
                    if ui
                        .button("Save brush as preset…")
                        .on_hover_text("Name it in the tool panel's presets shelf")
                        .clicked()
                    {
                        self.name_new_preset();
                        ui.close();
                    }
                });
            });
            ui.menu_button("Brush", |ui| self.brush_menu(ui));
            ui.menu_button("Layer", |ui| self.layer_menu(ui));
            ui.menu_button("View", |ui| {
                if ui
                    .checkbox(&mut self.studio.wireframe, labelled("Wireframe", Command::Wireframe))
                    .on_hover_text("Draw the triangles' edges over the surfaces")
                    .changed()
                {
                    ui.close();
                }
                use strata_render::AxisView::{Front, Right, Top};
                let views: [(&str, Action, Command); 7] = [
                    ("Frame the model", Action::FrameAll, Command::Frame),
                    ("Front", Action::AxisView(Front, false), Command::View(Front, false)),
                    ("Back", Action::AxisView(Front, true), Command::View(Front, true)),
                    ("Right", Action::AxisView(Right, false), Command::View(Right, false)),
                    ("Left", Action::AxisView(Right, true), Command::View(Right, true)),
                    ("Top", Action::AxisView(Top, false), Command::View(Top, false)),
                    ("Bottom", Action::AxisView(Top, true), Command::View(Top, true)),
                ];
                for (label, action, command) in views {
                    if ui.button(labelled(label, command)).on_hover_text("Look along a world axis at the model").clicked() {
                        let _ = self.studio.act(action);
                        ui.close();
                    }
                }
                let mut shown = self.studio.show_references;
                if ui
                    .checkbox(&mut shown, labelled("Reference images", Command::ShowReferences))
                    .on_hover_text("Draw the scene's reference images (each has its own switch in its panel)")
                    .changed()
                {
                    self.studio.toggle_references();
                    ui.close();
                }
                let mut ortho = self.studio.camera.orthographic;
                if ui
                    .checkbox(&mut ortho, labelled("Orthographic", Command::Orthographic))
                    .on_hover_text("Parallel projection (no perspective), as for axis views")
                    .changed()
                {
                    let _ = self.studio.act(Action::ToggleOrthographic);
                    ui.close();
                }
                let settled = mesher_choice(ui, true, "Viewport mesher", &mut self.studio.view_draft);
                // (A world is meshed as it streams: the choice waits for the scene.)
                if settled
                    && self.studio.terrain.is_none()
                    && self.studio.view_draft != self.studio.editor.view_mesher()
                {
                    let _ = self.studio.act(Action::ViewMesher(self.studio.view_draft));
                }
                let mut gpu = self.studio.gpu_meshing;
                if ui
                    .checkbox(&mut gpu, "GPU meshing")
                    .on_hover_text(
                        "Make the viewport's marching cubes on the GPU and draw them from there (exports mesh on the CPU)",
                    )
                    .changed()
                {
                    self.set_gpu_meshing(gpu);
                    ui.close();
                }
                ui.checkbox(&mut self.studio.lod, "Level of detail")
                    .on_hover_text("Mesh far chunks that were given more detail at a coarser level (marching cubes)");
                ui.add(egui::Slider::new(&mut self.studio.lod_pixels, 0.5..=8.0).text("largest cell (px)"))
                    .on_hover_text("How large a cell level of detail may show on screen");
            });
            ui.menu_button("Terrain", |ui| {
                ui.horizontal(|ui| {
                    let label = ui.label("Seed");
                    ui.add(egui::DragValue::new(&mut self.world_seed))
                        .labelled_by(label.id)
                        .on_hover_text("The seed new worlds are generated from");
                });
                if ui.button("New world…").on_hover_text("Create a world file from the seed and fly in it").clicked()
                {
                    self.ask_path(&ctx, Prompt::NewWorld, None);
                    ui.close();
                }
                if ui.button("Open world…").on_hover_text("Open a world file (.world) and fly in it").clicked() {
                    self.ask_path(&ctx, Prompt::OpenWorld, None);
                    ui.close();
                }
                let open = self.studio.terrain.is_some();
                if ui
                    .add_enabled(open, egui::Button::new(labelled("Bomb", Command::NextShape)))
                    .on_hover_text("Launch a bomb along the view: it blasts a crater")
                    .clicked()
                {
                    let _ = self.studio.act(Action::Bomb);
                    ui.close();
                }
                if ui
                    .add_enabled(open, egui::Button::new(labelled("Write world", Command::Save)))
                    .on_hover_text("Write the world's edits now (they are also written every 2 s and on Close world)")
                    .clicked()
                {
                    let _ = self.studio.act(Action::SaveWorld);
                    ui.close();
                }
                if ui
                    .add_enabled(open, egui::Button::new("Close world"))
                    .on_hover_text("Write the world and go back to the scene")
                    .clicked()
                {
                    let _ = self.studio.act(Action::CloseWorld);
                    ui.close();
                }
            });
            ui.menu_button("Help", |ui| {
                if ui
                    .button(labelled("Keyboard shortcuts", Command::Help))
                    .on_hover_text("Every key, and what the pointer does")
                    .clicked()
                {
                    self.help_open = true;
                    ui.close();
                }
            });
        });
    }
}

/// What a whole-mask action does, for its tooltip.
pub(super) fn mask_tip(a: strata_editor::MaskAction) -> &'static str {
    use strata_editor::MaskAction as M;
    match a {
        M::Invert => "Protect what is free and free what is protected, on the whole layer",
        M::Clear => "Free the whole layer: every tool acts everywhere again",
        M::Grow => "Grow the masked part of the layer by one cell in every direction",
        M::Shrink => "Shrink the masked part of the layer by one cell",
    }
}
