//! The studio driven as a user drives it (`egui_kittest`, no window, no GPU): keys, clicks and
//! typed text go through egui exactly as a window's events do.

use std::path::PathBuf;
use std::time::Duration;

use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT, Queryable};
use strata_editor::ToolKind;
use strata_studio::{Dialogs, Studio, StudioApp, default_scene};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-ui-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A left drag from the viewport's centre (which looks at the default ball) to the right, in
/// `steps` moves of 4 points, then the release.
fn drag_over_the_ball(h: &mut Harness<'static, StudioApp>, steps: usize) {
    let centre = egui::pos2(640.0, 400.0);
    h.hover_at(centre);
    h.step();
    h.drag_at(centre);
    h.step();
    for i in 1..=steps {
        h.hover_at(centre + egui::vec2(i as f32 * 4.0, 0.0));
        h.step();
    }
    h.drop_at(centre + egui::vec2(steps as f32 * 4.0, 0.0));
    h.step();
    h.step();
}

fn harness(dir: &std::path::Path) -> Harness<'static, StudioApp> {
    harness_with(dir, default_scene(), Dialogs::Typed)
}

/// Types `text` as a keyboard does: a key press (for keys egui knows) and the text it makes.
fn type_keys(h: &mut Harness<'_, StudioApp>, text: &str) {
    for ch in text.chars() {
        if let Some(key) = egui::Key::from_name(&ch.to_ascii_uppercase().to_string()) {
            h.key_press(key);
        }
        h.event(egui::Event::Text(ch.to_string()));
        h.run();
    }
}

#[test]
fn the_first_ctrl_s_on_a_new_scene_opens_the_prompt_focused_and_a_typed_path_saves() {
    let dir = temp("save");
    let mut h = harness(&dir);
    h.run();
    let (kind, wireframe) = (h.state().studio.editor.tool.kind, h.state().studio.wireframe);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.run();
    assert!(h.state().modal_open(), "the first Ctrl+S opens the prompt");
    let field = h.get_by_label("Path:");
    assert!(field.is_focused(), "the path field has the keyboard at once");
    // Letters that are tool shortcuts (a, e, w, 1–4, [ ]) must reach the field, not the tools.
    let path = dir.join("a_new_wide_scene[1].strata");
    type_keys(&mut h, &path.display().to_string());
    assert_eq!(h.get_by_label("Path:").value().as_deref(), Some(path.display().to_string().as_str()));
    h.key_press(egui::Key::Enter);
    h.run();
    assert!(!h.state().modal_open(), "Enter closes the prompt");
    assert!(path.exists(), "Enter saved {}", path.display());
    let s = &h.state().studio;
    assert_eq!(s.path.as_deref(), Some(path.as_path()));
    assert_eq!((s.editor.tool.kind, s.wireframe), (kind, wireframe), "no tool was toggled");
    assert!(!s.is_modified());
    let back = strata_editor::file::load(&path).unwrap();
    assert_eq!(back.scene.layers, s.editor.scene.layers);
}

#[test]
fn escape_closes_the_prompt_without_saving_and_keys_reach_the_tools_again() {
    let dir = temp("escape");
    let mut h = harness(&dir);
    h.run();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.run();
    assert!(h.state().modal_open());
    h.key_press(egui::Key::Escape);
    h.run();
    assert!(!h.state().modal_open());
    assert!(h.state().studio.path.is_none());
    h.key_press(egui::Key::E);
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Erase, "with no prompt, E picks the erase tool");
}

#[test]
fn new_with_unsaved_changes_asks_first() {
    let dir = temp("new");
    let mut h = harness(&dir);
    h.run();
    // A stroke on the clay.
    let before = h.state().studio.editor.scene.clone();
    {
        let s = &mut h.state_mut().studio;
        let down = strata_editor::Buttons { primary: true, secondary: false };
        for i in 0..5 {
            s.pointer(Some((i as f32 * 0.01, 0.0)), down, 1.0, 1.5, Duration::from_millis(20));
        }
        s.pointer(Some((0.05, 0.0)), strata_editor::Buttons::default(), 1.0, 1.5, Duration::from_millis(20));
        assert!(s.is_modified());
    }
    let sculpted = h.state().studio.editor.scene.clone();
    assert_ne!(sculpted, before);
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("New (Ctrl+N)").click();
    h.run();
    assert!(h.state().modal_open(), "the unsaved-changes question is up");
    assert_eq!(h.state().studio.editor.scene, sculpted, "nothing is discarded before the answer");
    h.get_by_label("Cancel").click();
    h.run();
    assert!(!h.state().modal_open());
    assert_eq!(h.state().studio.editor.scene, sculpted, "Cancel keeps the work");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::N);
    h.run();
    h.get_by_label("Don't save").click();
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers, before.layers, "Don't save starts anew");
    assert!(!h.state().studio.is_modified());
    // With nothing to lose, New asks nothing.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::N);
    h.run();
    assert!(!h.state().modal_open());
}

#[test]
fn saving_from_the_unsaved_changes_question_then_does_what_was_asked() {
    let dir = temp("save-then-new");
    let mut h = harness(&dir);
    h.run();
    h.state_mut().studio.editor.touch();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::N);
    h.run();
    h.get_by_label("Save").click();
    h.run();
    // The scene has no file: the path prompt asks for one, then the new scene follows.
    assert!(h.get_by_label("Path:").is_focused());
    let path = dir.join("kept.strata");
    h.get_by_label("Path:").type_text(""); // (focus stays; the suggestion is selected)
    type_keys(&mut h, &path.display().to_string());
    h.key_press(egui::Key::Enter);
    h.run();
    assert!(path.exists());
    assert!(h.state().studio.path.is_none(), "then the new scene");
    assert!(!h.state().modal_open());
}

#[test]
fn the_layer_name_field_takes_typed_text() {
    let dir = temp("name");
    let mut h = harness(&dir);
    h.run();
    h.get_by_label("Name").click();
    h.run();
    assert!(h.get_by_label("Name").is_focused());
    type_keys(&mut h, " awe gp");
    assert_eq!(h.state().studio.editor.scene.layers[0].name, "Clay awe gp");
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Clay, "typing a, w, e, g, p renamed, toggled nothing");
    assert!(!h.state().studio.wireframe);
    assert!(h.state().studio.is_modified(), "a rename is a change to save");
}

#[test]
fn unsaved_work_is_autosaved_and_offered_back_after_a_crash() {
    let dir = temp("recover");
    let mut h = harness(&dir);
    h.state_mut().set_autosave_interval(Duration::from_millis(0));
    h.step();
    h.state_mut().studio.editor.scene.layers[0].name = "precious".into();
    h.state_mut().studio.editor.touch();
    // (An autosave keeps the UI repainting while there is unsaved work: step, do not settle.)
    let recovery = dir.join("recovery");
    for _ in 0..500 {
        h.step();
        if std::fs::read_dir(&recovery).map(|d| d.count()).unwrap_or(0) >= 2 {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    h.state_mut().wait_for_autosave();
    let own = dir.join("recovery").join(format!("recovery-{}.strata", std::process::id()));
    assert!(own.exists(), "the recovery file was written");
    // A crash: the process is gone and its file stays. Pretend it was another process's.
    let orphan = dir.join("recovery").join("recovery-999999999.strata");
    std::fs::copy(&own, &orphan).unwrap();
    drop(h);
    let mut h = harness(&dir);
    h.run();
    assert!(h.state().modal_open(), "recovery is offered");
    h.get_by_label("Recover").click();
    h.run();
    let s = &h.state().studio;
    assert_eq!(s.editor.scene.layers[0].name, "precious");
    assert!(s.is_modified(), "recovered work still needs saving");
    assert!(!orphan.exists(), "the recovery file is consumed");
}

#[test]
fn quit_with_unsaved_changes_asks_first() {
    let dir = temp("quit");
    let mut h = harness(&dir);
    h.run();
    h.state_mut().studio.editor.touch();
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Quit").click();
    h.run();
    assert!(h.state().modal_open(), "the unsaved-changes question is up before quitting");
    // (Panics unless the question names what waits for it.)
    h.get_by_label_contains("before quitting");
    h.get_by_label("Cancel").click();
    h.run();
    assert!(!h.state().modal_open(), "Cancel keeps the studio open");
}

#[test]
fn every_tool_is_one_key_or_click_away_with_its_settings() {
    let dir = temp("tools");
    let mut h = harness(&dir);
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Clay, "clay is the default tool");
    // The clay tool shows its fillet; the smooth tool its choice of method.
    assert!(h.query_all_by_label("fillet (× radius)").count() > 0);
    for (key, kind) in [
        (egui::Key::D, ToolKind::Detail),
        (egui::Key::G, ToolKind::Grab),
        (egui::Key::P, ToolKind::Pinch),
        (egui::Key::T, ToolKind::Flatten),
        (egui::Key::I, ToolKind::Inflate),
        (egui::Key::S, ToolKind::Smooth),
        (egui::Key::A, ToolKind::Add),
        (egui::Key::C, ToolKind::Clay),
    ] {
        h.key_press(key);
        h.run();
        assert_eq!(h.state().studio.editor.tool.kind, kind, "{key:?}");
    }
    h.get_by_label("Smooth (S)").click();
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Smooth);
    h.get_by_label("Paper's smoothing (Eq. 1)").click();
    h.run();
    assert!(h.state().studio.editor.tool.paper_smoothing);
    h.get_by_label("Grab (G)").click();
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Grab);
    // The alignment tool: orient to the surface, lock strokes to an axis.
    h.get_by_label("Orient brush to surface").click();
    h.run();
    assert!(h.state().studio.editor.tool.orient_to_normal);
    h.get_by_label("along Y").click();
    h.run();
    assert_eq!(h.state().studio.editor.tool.axis_lock, Some(1));
    // X mirrors; the preview then shows the dab and its image.
    h.key_press(egui::Key::X);
    h.run();
    assert!(h.state().studio.editor.tool.symmetry[0]);
    let p = h.state().studio.surface_point(0.2, 0.0, 1.6).unwrap();
    h.state_mut().studio.hover = Some(p);
    assert_eq!(h.state().studio.preview_dabs().len(), 2, "the dab and its mirror image");
}

fn bunny_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply")
}

/// Steps the harness until the import in progress ends (or 60 s pass).
fn wait_for_import(h: &mut Harness<'_, StudioApp>) {
    let start = std::time::Instant::now();
    while h.state().studio.import_job.is_some() {
        assert!(start.elapsed() < Duration::from_secs(60), "the import ends");
        std::thread::sleep(Duration::from_millis(20));
        h.step();
    }
    h.run();
}

#[test]
fn a_mesh_is_imported_through_the_menu_with_its_resolution_and_can_be_cancelled() {
    let dir = temp("import");
    let mut h = harness(&dir);
    h.run();
    // Cancel at the resolution dialog: nothing changes.
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Import mesh… (PLY, OBJ, STL, glTF)").click();
    h.run();
    assert!(h.get_by_label("Path:").is_focused());
    type_keys(&mut h, &bunny_path().display().to_string());
    h.key_press(egui::Key::Enter);
    h.run();
    assert!(h.state().studio.pending_import.is_some(), "{}", h.state().studio.message);
    assert!(h.query_all_by_label("cells along the longest side").count() > 0);
    let estimate = h.query_all_by_label_contains("MiB").count();
    assert!(estimate > 0, "the dialog estimates the memory");
    h.get_by_label("Cancel").click();
    h.run();
    assert!(h.state().studio.pending_import.is_none());
    assert_eq!(h.state().studio.editor.scene.layers.len(), 1);
    // Import at a small resolution: a new active layer.
    h.state_mut().studio.choose_import(bunny_path()).unwrap();
    h.state_mut().studio.pending_import.as_mut().unwrap().cells = 48;
    h.run();
    h.get_by_label("Import").click();
    h.step();
    wait_for_import(&mut h);
    let s = &h.state().studio;
    assert_eq!(s.editor.scene.layers.len(), 2, "{}", s.message);
    assert_eq!(s.editor.active_layer, 1);
    assert_eq!(s.editor.scene.layers[1].name, "bunny");
    assert!(!s.editor.scene.layers[1].volume.is_empty());
    // A large import cancelled from its progress window leaves the scene as it was.
    h.state_mut().studio.choose_import(bunny_path()).unwrap();
    h.state_mut().studio.pending_import.as_mut().unwrap().cells = 2048;
    h.run();
    h.get_by_label("Import").click();
    h.step();
    assert!(h.state().studio.import_job.is_some());
    h.get_by_label("Cancel import").click();
    h.step();
    wait_for_import(&mut h);
    assert_eq!(h.state().studio.editor.scene.layers.len(), 2, "{}", h.state().studio.message);
    assert!(h.state().studio.message.contains("cancelled"), "{}", h.state().studio.message);
}

#[derive(Debug)]
struct Dropped(PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &std::path::Path {
        &self.0
    }
    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

#[test]
fn dropped_files_open_scenes_and_import_meshes_and_recent_files_are_remembered() {
    let dir = temp("drop");
    let mut h = harness(&dir);
    h.run();
    // A dropped mesh opens the import dialog.
    h.input_mut().dropped_files.push(std::sync::Arc::new(Dropped(bunny_path())));
    h.run();
    assert!(h.state().studio.pending_import.is_some());
    h.get_by_label("Cancel").click();
    h.run();
    // A saved scene, dropped back after a new scene, opens (no unsaved work to ask about).
    let path = dir.join("dropped.strata");
    h.state_mut().studio.act(strata_studio::Action::SaveAs(path.clone())).unwrap();
    h.state_mut().studio.act(strata_studio::Action::New).unwrap();
    h.state_mut().studio.editor.scene.layers[0].name = "changed".into();
    h.state_mut().studio.mark_saved();
    h.input_mut().dropped_files.push(std::sync::Arc::new(Dropped(path.clone())));
    h.run();
    assert_eq!(h.state().studio.path.as_deref(), Some(path.as_path()), "{}", h.state().studio.message);
    assert_eq!(h.state().studio.editor.scene.layers[0].name, "Clay");
    // Opened scenes are remembered, across restarts of the app.
    let canonical = std::fs::canonicalize(&path).unwrap();
    assert_eq!(h.state().recent.paths().first(), Some(&canonical));
    let again = harness(&dir);
    assert_eq!(again.state().recent.paths().first(), Some(&canonical));
    // Something else dropped is refused with a message.
    let txt = dir.join("notes.txt");
    std::fs::write(&txt, "hi").unwrap();
    h.input_mut().dropped_files.push(std::sync::Arc::new(Dropped(txt)));
    h.run();
    assert!(h.state().studio.message.contains("not a scene, a mesh, a PNG stamp or a JPEG reference image"));
    // A dropped PNG becomes the stamp's picture.
    let png_path = dir.join("drop.png");
    {
        let mut e = png::Encoder::new(std::io::BufWriter::new(std::fs::File::create(&png_path).unwrap()), 2, 2);
        e.set_color(png::ColorType::Grayscale);
        e.write_header().unwrap().write_image_data(&[0, 255, 255, 0]).unwrap();
    }
    h.input_mut().dropped_files.push(std::sync::Arc::new(Dropped(png_path)));
    h.run();
    assert_eq!(h.state().studio.stamp_name(), "drop.png", "{}", h.state().studio.message);
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Stamp);
}

#[test]
fn help_views_and_layer_operations_through_keys_and_buttons() {
    let dir = temp("help");
    let mut h = harness(&dir);
    h.run();
    h.key_press(egui::Key::F1);
    h.run();
    assert!(h.state().help_open);
    // The overlay lists every binding of the one table, with its keys, and the pointer controls.
    for (keys, does) in strata_studio::keymap::help_rows() {
        assert!(h.query_all_by_label(&keys).count() > 0, "the help lists the keys {keys:?}");
        assert!(h.query_all_by_label(&does).count() > 0, "the help says what {keys:?} does");
    }
    h.key_press(egui::Key::Escape);
    h.run();
    assert!(!h.state().help_open);
    // Views: 1 front, Ctrl+3 left, 5 orthographic, Home frames.
    h.key_press(egui::Key::Num1);
    h.run();
    assert_eq!((h.state().studio.camera.yaw, h.state().studio.camera.pitch), (0.0, 0.0));
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Num3);
    h.run();
    assert!((h.state().studio.camera.yaw - 1.5 * std::f32::consts::PI).abs() < 1e-5);
    h.key_press(egui::Key::Num5);
    h.run();
    assert!(h.state().studio.camera.orthographic);
    h.state_mut().studio.camera.distance = 5000.0;
    h.key_press(egui::Key::Home);
    h.run();
    assert!(h.state().studio.camera.distance < 500.0, "framed");
    // B cycles the brush shape.
    h.key_press(egui::Key::B);
    h.run();
    assert_eq!(h.state().studio.editor.tool.shape, strata_editor::BrushShape::Box);
    // Layers: duplicate, move, merge down, delete.
    h.get_by_label("Duplicate").click();
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers.len(), 2);
    assert_eq!(h.state().studio.editor.scene.layers[1].name, "Clay copy");
    h.get_by_label("Up").click();
    h.run();
    assert_eq!(h.state().studio.editor.active_layer, 0);
    assert_eq!(h.state().studio.editor.scene.layers[0].name, "Clay copy");
    h.get_by_label("Merge down").click();
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers.len(), 1, "{}", h.state().studio.message);
    // Layer operations are undo steps like strokes.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers.len(), 2, "Ctrl+Z took the merge back");
    h.key_press_modifiers(egui::Modifiers::COMMAND | egui::Modifiers::SHIFT, egui::Key::Z);
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers.len(), 1);
    h.get_by_label("Delete").click();
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers.len(), 1);
    assert!(h.state().studio.editor.scene.layers[0].volume.is_empty(), "the last layer is emptied");
}

#[test]
fn a_stroke_through_the_pointer_sculpts_and_ctrl_z_takes_it_back() {
    let dir = temp("stroke");
    let mut h = harness(&dir);
    h.run();
    let before = h.state().studio.editor.scene.layers[0].volume.clone();
    drag_over_the_ball(&mut h, 8);
    let after = h.state().studio.editor.scene.layers[0].volume.clone();
    assert!(after != before, "the drag sculpted: {}", h.state().studio.message);
    assert_eq!(h.state().studio.editor.history().undo_len(), 1, "one stroke, one step");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert!(h.state().studio.editor.scene.layers[0].volume == before, "Ctrl+Z undid the stroke");
}

/// Modifiers held over a drag, as a sculptor holds them: Ctrl turns clay into carving and Shift
/// smooths, while the tool stays clay (issue 30: the pose carries the modifiers; the tool and
/// the buttons are left alone). Each drag is one undo step.
#[test]
fn ctrl_and_shift_held_over_a_drag_carve_and_smooth_while_the_tool_stays() {
    let dir = temp("modifiers");
    let mut h = harness(&dir);
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Clay);
    let solid = |h: &Harness<'static, StudioApp>| {
        h.state().studio.editor.scene.layers[0].volume.measured_volume(strata_volume::Axis::X)
    };
    let held = |h: &mut Harness<'static, StudioApp>, m: egui::Modifiers| {
        h.event(egui::Event::ModifiersChanged(m));
        h.run();
    };
    let start = solid(&h);
    drag_over_the_ball(&mut h, 8);
    let clayed = solid(&h);
    assert!(clayed > start, "clay adds: {start} -> {clayed}");
    held(&mut h, egui::Modifiers::COMMAND);
    assert!(h.state().studio.inverse_held, "Ctrl is seen as held");
    drag_over_the_ball(&mut h, 8);
    held(&mut h, egui::Modifiers::NONE);
    let carved = solid(&h);
    assert!(carved < clayed, "Ctrl + drag carves with clay: {clayed} -> {carved}");
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Clay, "Ctrl leaves the tool");
    let before = h.state().studio.editor.scene.layers[0].volume.clone();
    held(&mut h, egui::Modifiers::SHIFT);
    assert!(h.state().studio.smooth_held, "Shift is seen as held");
    drag_over_the_ball(&mut h, 8);
    held(&mut h, egui::Modifiers::NONE);
    let smoothed = solid(&h);
    assert!(h.state().studio.editor.scene.layers[0].volume != before, "Shift + drag smoothed");
    // Volume-preserving smoothing keeps the volume far closer than a clay stroke changes it.
    assert!(
        (smoothed - carved).abs() < 0.25 * (clayed - start),
        "Shift smooths, it does not add clay: {carved} -> {smoothed} (clay added {})",
        clayed - start
    );
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Clay, "Shift leaves the tool");
    assert_eq!(h.state().studio.editor.history().undo_len(), 3, "three drags, three undo steps");
}

/// Every tool, picked by its key, strokes the ball at a radius of 20 cells (issue 29: the
/// radius the frame targets are set for), and each stroke is one undo step.
#[test]
fn a_stroke_of_every_tool_at_radius_20_sculpts() {
    let dir = temp("radius20");
    let mut h = harness(&dir);
    h.run();
    for (key, kind) in [
        (egui::Key::C, ToolKind::Clay),
        (egui::Key::S, ToolKind::Smooth),
        (egui::Key::I, ToolKind::Inflate),
        (egui::Key::T, ToolKind::Flatten),
        (egui::Key::P, ToolKind::Pinch),
        (egui::Key::G, ToolKind::Grab),
        (egui::Key::A, ToolKind::Add),
        (egui::Key::E, ToolKind::Erase),
    ] {
        h.key_press(key);
        h.run();
        assert_eq!(h.state().studio.editor.tool.kind, kind, "{key:?}");
        h.state_mut().studio.editor.tool.radius = 20.0 * strata_studio::DEFAULT_CELL;
        let steps = h.state().studio.editor.history().undo_len();
        let before = h.state().studio.editor.scene.layers[0].volume.clone();
        drag_over_the_ball(&mut h, 12);
        let after = &h.state().studio.editor.scene.layers[0].volume;
        assert!(*after != before, "{kind:?} at radius 20 sculpted nothing: {}", h.state().studio.message);
        assert_eq!(h.state().studio.editor.history().undo_len(), steps + 1, "{kind:?}: one stroke, one step");
    }
}

#[test]
fn the_detail_tool_raises_the_resolution_where_it_is_dragged() {
    let dir = temp("detail");
    let mut h = harness(&dir);
    h.run();
    h.key_press(egui::Key::D);
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Detail);
    h.get_by_label("32³ cells").click();
    h.run();
    assert_eq!(h.state().studio.editor.tool.detail_level, strata_volume::Level::new(1).unwrap());
    drag_over_the_ball(&mut h, 4);
    let v = &h.state().studio.editor.scene.layers[0].volume;
    let counts = v.level_counts();
    let (base, fine) = (strata_volume::Level::BASE.index(), strata_volume::Level::new(1).unwrap().index());
    assert!(counts[fine] > 0, "chunks under the drag were raised: {counts:?} ({})", h.state().studio.message);
    assert!(counts[base] > 0, "and the others kept the base level");
    v.check_invariants().unwrap();
    let status = h.state().studio.status();
    assert!(status.contains("×32³") && status.contains("×16³"), "the status bar counts the chunks by level: {status}");
    assert!(!status.contains("×8³") && !status.contains("×64³"), "by their own levels: {status}");
    assert_eq!(h.state().studio.editor.history().undo_len(), 1, "one stroke, one step");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers[0].volume.level_counts()[fine], 0, "Ctrl+Z undid it");
}

#[test]
fn a_layer_can_be_added_at_a_finer_base_resolution() {
    let dir = temp("base");
    let mut h = harness(&dir);
    h.run();
    assert!(h.query_all_by_label("Base resolution 16³ cells per chunk").count() > 0);
    h.get_by_label("64³").click();
    h.run();
    h.get_by_label("Add").click();
    h.run();
    let layers = &h.state().studio.editor.scene.layers;
    assert_eq!(layers.len(), 2);
    assert_eq!(layers[1].volume.level(), strata_volume::Level::FINEST, "the new layer's base is 64³");
    assert!(h.query_all_by_label("Base resolution 64³ cells per chunk").count() > 0);
}

#[test]
fn paint_an_eyedropper_and_a_new_material_from_the_palette() {
    let dir = temp("paint");
    let mut h = harness(&dir);
    h.run();
    h.key_press(egui::Key::V);
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Paint);
    h.get_by_label("Grass").click();
    h.run();
    assert_eq!(h.state().studio.editor.tool.material, 2, "the palette sets the current material");
    h.state_mut().studio.editor.tool.field_strength = 1.0;
    let shape: Vec<_> = h.state().studio.editor.scene.layers[0].volume.chunks().map(|(k, c)| (k, c.clone())).collect();
    drag_over_the_ball(&mut h, 4);
    let v = &h.state().studio.editor.scene.layers[0].volume;
    assert!(v.has_materials(), "the stroke painted ({})", h.state().studio.message);
    let now: Vec<_> = v.chunks().map(|(k, c)| (k, c.clone())).collect();
    assert!(now == shape, "painting never changes the shape");
    v.check_invariants().unwrap();
    assert_eq!(h.state().studio.editor.history().undo_len(), 1, "one stroke, one step");
    // Another material, then the eyedropper on the painted spot takes grass back.
    h.get_by_label("Red").click();
    h.run();
    assert_eq!(h.state().studio.editor.tool.material, 5);
    h.key_press(egui::Key::K);
    h.run();
    assert!(h.state().studio.eyedropper);
    let centre = egui::pos2(640.0, 400.0);
    h.hover_at(centre);
    h.step();
    h.drag_at(centre);
    h.step();
    h.drop_at(centre);
    h.step();
    assert!(!h.state().studio.eyedropper, "one click, then it disarms");
    assert_eq!(h.state().studio.editor.tool.material, 2, "{}", h.state().studio.message);
    // A new material joins the palette and becomes current; its colour is editable.
    let before = h.state().studio.editor.scene.materials.len();
    // (Below the tool panel's fold: scrolled to, as a user scrolls.)
    h.get_by_label("New material").scroll_to_me();
    h.run();
    h.get_by_label("New material").click();
    h.run();
    let s = &h.state().studio;
    assert_eq!(s.editor.scene.materials.len(), before + 1);
    assert_eq!(s.editor.tool.material as usize, before);
    // Undo takes the paint away exactly.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert!(!h.state().studio.editor.scene.layers[0].volume.has_materials(), "Ctrl+Z undid the paint");
}

/// Terrain mode as a user meets it: Terrain > New world with a typed path, WASD flies; a left
/// drag digs with the editor's tools (the world's own stroke, one step of the editor's history:
/// Ctrl+Z gives the generated ground back exactly, Ctrl+Y the dig); B launches a bomb that blasts
/// a crater with debris, another step of the same history; scene commands wait and say so; Close
/// world writes it and gives the scene back untouched, and Open world finds the crater and the
/// viewer where they were.
#[test]
fn a_new_world_is_flown_through_dug_bombed_undone_closed_and_reopened() {
    let dir = temp("terrain");
    let mut h = harness(&dir);
    h.state_mut().studio.world_settings.view_distance = 40.0;
    h.state_mut().studio.world_settings.threads = 2;
    h.state_mut().studio.world_settings.vertical_ratio = 1.5;
    h.state_mut().studio.world_settings.detail_distance = 16.0;
    h.run();
    let scene_before = h.state().studio.editor.scene.clone();
    h.get_by_label("Terrain").click();
    h.run();
    h.get_by_label("New world…").click();
    h.run();
    let path = dir.join("valley.world");
    type_keys(&mut h, &path.display().to_string());
    h.key_press(egui::Key::Enter);
    h.run_steps(3);
    assert!(h.state().studio.terrain.is_some(), "{}", h.state().studio.message);
    assert!(h.state().studio.editor.world().is_some(), "the tools edit the world");
    let start = h.state().studio.terrain.as_ref().unwrap().eye;
    // Fly forward for a moment, W held (W is the wireframe key in a scene: not here).
    h.key_down(egui::Key::W);
    for _ in 0..5 {
        std::thread::sleep(Duration::from_millis(10));
        h.step();
    }
    h.key_up(egui::Key::W);
    h.step();
    assert!(!h.state().studio.wireframe, "W flies in terrain mode");
    let eye = h.state().studio.terrain.as_ref().unwrap().eye;
    assert!(eye.distance(start) > 0.5, "W flew from {start} to {eye}");
    // Let the ground stream in, then look down at it.
    let world = |h: &Harness<'static, StudioApp>| h.state().studio.editor.world().unwrap().volume().clone();
    let settle = std::time::Instant::now();
    while h.state().studio.editor.world().unwrap().loaded_count() < 50 && settle.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(10));
        h.step();
    }
    h.state_mut().studio.terrain.as_mut().unwrap().pitch = 1.2;
    for _ in 0..400 {
        std::thread::sleep(Duration::from_millis(5));
        h.step();
        let s = &h.state().studio;
        if s.editor.world().unwrap().pending_count() == 0 && s.editor.pending() == 0 {
            break;
        }
    }
    assert!(h.state().studio.editor.triangle_count() > 0, "the world's meshes come through the editor");
    // Dig: a left drag with the tool terrain mode starts with (erase).
    let generated = world(&h);
    drag_over_the_ball(&mut h, 6);
    let dug = world(&h);
    assert_ne!(dug, generated, "the drag dug: {}", h.state().studio.message);
    assert_eq!(h.state().studio.editor.history().undo_len(), 1, "one stroke, one step");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.step();
    assert_eq!(world(&h), generated, "Ctrl+Z gave the generated ground back");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Y);
    h.step();
    assert_eq!(world(&h), dug, "Ctrl+Y dug again");
    // Bomb.
    h.key_press(egui::Key::B);
    h.step();
    assert_eq!(h.state().studio.terrain.as_ref().unwrap().projectiles.len(), 1, "B launched a bomb");
    let flight = std::time::Instant::now();
    while h.state().studio.terrain.as_ref().unwrap().craters == 0 && flight.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(10));
        h.step();
    }
    let t = h.state().studio.terrain.as_ref().unwrap();
    assert_eq!(t.craters, 1, "the bomb hit the ground");
    assert!(!t.particles.is_empty(), "debris flies");
    assert!(!t.particle_mesh().indices.is_empty(), "debris is drawn");
    assert_eq!(h.state().studio.editor.history().undo_len(), 2, "the crater is a step of the editor's history");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.step();
    assert_eq!(world(&h), dug, "Ctrl+Z undid the crater");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Y);
    h.step();
    assert_ne!(world(&h), dug, "Ctrl+Y blasted it again");
    // Ctrl+S writes the world (the scene is not touched).
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.step();
    assert!(h.state().studio.message.contains("World written"), "{}", h.state().studio.message);
    // A scene command waits for the world, and says so.
    h.key_press(egui::Key::Num1);
    h.step();
    assert!(h.state().studio.message.contains("Close world"), "{}", h.state().studio.message);
    let eye = h.state().studio.terrain.as_ref().unwrap().eye;
    h.get_by_label("Terrain").click();
    h.run_steps(3);
    h.get_by_label("Close world").click();
    h.run_steps(3);
    assert!(h.state().studio.terrain.is_none(), "{}", h.state().studio.message);
    assert!(h.state().studio.editor.world().is_none());
    assert!(h.state().studio.editor.scene == scene_before, "the scene came back untouched");
    // Reopened: the crater is in the file, the viewer where it was.
    h.get_by_label("Terrain").click();
    h.run_steps(3);
    h.get_by_label("Open world…").click();
    h.run_steps(3);
    let field = h.get_by_label("Path:");
    field.focus();
    h.run_steps(3);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    type_keys(&mut h, &path.display().to_string());
    h.key_press(egui::Key::Enter);
    h.run_steps(3);
    let t = h.state().studio.terrain.as_ref().expect("the world opened");
    assert!(t.eye.distance(eye) < 1e-9, "the viewer is back at {eye}, not {}", t.eye);
    let store = h.state().studio.editor.world().unwrap().store().unwrap();
    assert!(!store.edited_keys().unwrap().is_empty(), "the crater was written");
    h.get_by_label("Terrain").click();
    h.run_steps(3);
    h.get_by_label("Close world").click();
    h.run_steps(3);
    let _ = std::fs::remove_dir_all(dir);
}

/// Waits (stepping frames) until the world has nothing left to generate or mesh.
fn settle_world(h: &mut Harness<'static, StudioApp>) {
    let start = std::time::Instant::now();
    while start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(5));
        h.step();
        let s = &h.state().studio;
        if s.editor.world().unwrap().pending_count() == 0 && s.editor.pending() == 0 {
            return;
        }
    }
    panic!("the world did not settle: {}", h.state().studio.status());
}

/// The far ring as a user meets it (the studio generates chunks beyond a distance at 8³ cells,
/// nearer ones at 16³; here a small world, so the ring is near): the status bar counts the
/// surface chunks of each size, the streamed ground meshes closed across the sizes, flying
/// ahead sharpens the chunks it nears and coarsens those it leaves, and a dig lands at the base
/// level and meshes closed; Ctrl+Z gives the ground back (the coarse chunks it reached at the
/// base level, generated again for it), Ctrl+Y the dig.
#[test]
fn far_terrain_streams_coarse_and_sharpens_as_the_viewer_flies_and_digs() {
    use strata_volume::Level;
    let dir = temp("coarse");
    let mut h = harness(&dir);
    {
        let w = &mut h.state_mut().studio.world_settings;
        w.view_distance = 56.0;
        w.threads = 2;
        w.vertical_ratio = 1.0;
        w.detail_distance = 0.0;
        w.coarse_distance = 24.0;
    }
    h.run();
    h.get_by_label("Terrain").click();
    h.run();
    h.get_by_label("New world…").click();
    h.run();
    type_keys(&mut h, &dir.join("far.world").display().to_string());
    h.key_press(egui::Key::Enter);
    h.run_steps(3);
    assert!(h.state().studio.terrain.is_some(), "{}", h.state().studio.message);
    settle_world(&mut h);
    let world = |h: &Harness<'static, StudioApp>| h.state().studio.editor.world().unwrap().volume().clone();
    // Every edge of the welded mesh is used twice, but at the border of what is loaded (where
    // the ground goes on in chunks not in memory).
    let closed = |h: &Harness<'static, StudioApp>, when: &str| {
        let world = h.state().studio.editor.world().unwrap();
        let loaded: std::collections::HashSet<_> = world.loaded().collect();
        let mesh = strata_mesh::mesh_volume_with(world.volume(), strata_mesh::MeshOptions::default()).unwrap();
        assert!(!mesh.indices.is_empty(), "{when}: ground");
        let mut uses = std::collections::HashMap::<(u32, u32), u32>::new();
        for t in mesh.indices.chunks_exact(3) {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        for ((a, b), n) in uses.into_iter().filter(|&(_, n)| n != 2) {
            let mid =
                (glam::Vec3::from(mesh.positions[a as usize]) + glam::Vec3::from(mesh.positions[b as usize])) / 2.0;
            let k = strata_volume::ChunkKey((mid.as_dvec3() / 16.0).floor().as_ivec3());
            assert!(
                k.around().any(|n| !loaded.contains(&n)),
                "{when}: edge at {mid} used {n} times inside the loaded ground"
            );
        }
    };
    let levels = |h: &Harness<'static, StudioApp>| {
        let w = h.state().studio.editor.world().unwrap();
        w.loaded().map(|k| (k, w.generated_level(k))).collect::<std::collections::HashMap<_, _>>()
    };
    let counts = world(&h).level_counts();
    assert!(counts[Level::COARSEST.index()] > 0 && counts[Level::BASE.index()] > 0, "both sizes: {counts:?}");
    let status = h.state().studio.status();
    assert!(status.contains("×8³") && status.contains("×16³"), "the status bar counts both sizes: {status}");
    closed(&h, "streamed");
    // Fly ahead with W held (about 40 cells a second) past a chunk or two.
    let before = levels(&h);
    let start = h.state().studio.terrain.as_ref().unwrap().eye;
    h.key_down(egui::Key::W);
    let flight = std::time::Instant::now();
    while h.state().studio.terrain.as_ref().unwrap().eye.distance(start) < 40.0
        && flight.elapsed() < Duration::from_secs(30)
    {
        std::thread::sleep(Duration::from_millis(20));
        h.step();
    }
    h.key_up(egui::Key::W);
    h.step();
    let flown = h.state().studio.terrain.as_ref().unwrap().eye.distance(start);
    assert!(flown >= 40.0, "W flew {flown} cells in 30 s");
    settle_world(&mut h);
    let after = levels(&h);
    let sharpened = after.iter().filter(|(k, l)| **l == Level::BASE && before.get(k) == Some(&Level::COARSEST)).count();
    let coarsened = after.iter().filter(|(k, l)| **l == Level::COARSEST && before.get(k) == Some(&Level::BASE)).count();
    assert!(sharpened > 0 && coarsened > 0, "flying sharpened {sharpened} chunks and coarsened {coarsened}");
    closed(&h, "after the flight");
    // Look down and dig.
    h.state_mut().studio.terrain.as_mut().unwrap().pitch = 1.2;
    settle_world(&mut h);
    let generated = world(&h);
    drag_over_the_ball(&mut h, 6);
    settle_world(&mut h);
    let dug = world(&h);
    assert_ne!(dug, generated, "the drag dug: {}", h.state().studio.message);
    let edited: Vec<_> = dug.chunks().filter(|(k, c)| generated.chunk(*k) != Some(*c)).map(|(k, _)| k).collect();
    assert!(!edited.is_empty(), "the dig changed chunks");
    for k in &edited {
        let l = dug.stored_level(*k);
        assert!(l.is_none_or(|l| l >= Level::BASE), "{k:?} was edited at {l:?}");
    }
    closed(&h, "dug");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.step();
    // The ground as generated, but that the coarse chunks the dig reached were generated again
    // at the base level first (where they stay until the viewer moves on).
    let undone = world(&h);
    let field = h.state().studio.editor.world().unwrap().field();
    let mut raised = 0;
    let keys: std::collections::HashSet<_> = undone.chunks().chain(generated.chunks()).map(|(k, _)| k).collect();
    for k in keys {
        if undone.chunk(k) != generated.chunk(k) {
            assert_eq!(generated.stored_level(k), Some(Level::COARSEST), "Ctrl+Z left {k:?} changed");
            let g = strata_volume::generate_chunk(k, Level::BASE, field);
            assert!(undone.chunk(k) == g.chunk.as_ref(), "Ctrl+Z left {k:?} unlike its ground at the base level");
            raised += 1;
        }
    }
    assert!(raised < edited.len(), "Ctrl+Z gave the dug chunks back");
    assert!(raised > 0, "the dig reached the coarse ring (so an edit there was made at the base level)");
    closed(&h, "undone");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Y);
    h.step();
    assert!(world(&h) == dug, "Ctrl+Y dug again");
    h.get_by_label("Terrain").click();
    h.run_steps(3);
    h.get_by_label("Close world").click();
    h.run_steps(3);
    assert!(h.state().studio.terrain.is_none(), "{}", h.state().studio.message);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn the_viewport_and_exports_take_the_mesher_chosen_in_the_menus() {
    let dir = temp("meshers");
    let mut h = harness(&dir);
    h.run();
    // Frames remesh within a time budget: finish, so the count does not depend on the machine.
    h.state_mut().studio.editor.finish_meshing();
    let mc = h.state().studio.editor.triangle_count();
    assert!(mc > 0);
    // View > Viewport mesher: regularised tetrahedra.
    h.get_by_label("View").click();
    h.run();
    h.get_by_label("regularised tetrahedra").click();
    h.run();
    let s = &h.state().studio;
    assert_eq!(s.editor.view_mesher().mesher, strata_mesh::Mesher::ClusteredTetrahedra, "{}", s.message);
    let rmt = s.editor.triangle_count();
    assert!(rmt > 0 && rmt < mc, "the viewport shows the clustered mesh: {rmt} of {mc}");
    assert!(s.message.contains("regularised tetrahedra"), "{}", s.message);
    h.key_press(egui::Key::Escape);
    h.run();
    // A stroke remeshes with it.
    drag_over_the_ball(&mut h, 6);
    h.state_mut().studio.editor.finish_meshing();
    assert_eq!(h.state().studio.editor.history().undo_len(), 1);
    // File > Export with: dual contouring, simplified; then export through the prompt.
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("dual contouring").click();
    h.run();
    if h.query_by_label("Simplify (meshoptimizer)").is_none() {
        // A click in a menu may close it: open it again.
        h.get_by_label("File").click();
        h.run();
    }
    h.get_by_label("Simplify (meshoptimizer)").click();
    h.run();
    if h.query_by_label("Export mesh… (glb, obj, stl, ply)").is_none() {
        h.get_by_label("File").click();
        h.run();
    }
    let export = h.state().studio.export;
    assert_eq!(export.mesher, strata_mesh::Mesher::DualContouring);
    assert_eq!(export.simplify, Some(0.1));
    h.get_by_label("Export mesh… (glb, obj, stl, ply)").click();
    h.run();
    let path = dir.join("out.ply");
    type_keys(&mut h, &path.display().to_string());
    h.key_press(egui::Key::Enter);
    h.run();
    let s = &h.state().studio;
    assert!(path.exists(), "{}", s.message);
    let written = strata_mesh::import::load_mesh(&path).unwrap();
    let full = s.editor.export_mesh(strata_mesh::MeshOptions::new(strata_mesh::Mesher::DualContouring)).unwrap();
    assert!(
        written.triangles.len() < full.triangle_count(),
        "simplified: {} of {}",
        written.triangles.len(),
        full.triangle_count()
    );
}

// ---- What a newcomer hits in the first hour (issue 27) ----

/// The app on `scene` with paths asked of `dialogs`.
fn harness_with(dir: &std::path::Path, scene: strata_editor::Scene, dialogs: Dialogs) -> Harness<'static, StudioApp> {
    let app = StudioApp::headless(Studio::new(scene), dialogs, dir.join("recovery"));
    Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .build_ui_state(|ui, app: &mut StudioApp| app.show(ui, None), app)
}

/// A dialog service that answers `answer` after `after` (no portal: nothing, in a few ms).
fn service(after: Duration, answer: Option<PathBuf>) -> Dialogs {
    Dialogs::Service(std::sync::Arc::new(move |_: &strata_studio::DialogRequest| {
        std::thread::sleep(after);
        answer.clone()
    }))
}

/// Types `path` into the focused prompt and presses Enter.
fn enter_path(h: &mut Harness<'static, StudioApp>, path: &std::path::Path) {
    type_keys(h, &path.display().to_string());
    h.key_press(egui::Key::Enter);
    h.run();
}

/// File > Quit with unsaved changes, then Save in the question (one frame of it).
fn quit_and_save(h: &mut Harness<'static, StudioApp>) {
    h.state_mut().studio.editor.touch();
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Quit").click();
    h.run();
    h.get_by_label("Save").click();
    h.step();
}

/// One frame slower than the dialog fallback's window (software rendering, a heavy remesh).
fn slow_frame(h: &mut Harness<'static, StudioApp>) {
    std::thread::sleep(Duration::from_millis(600));
    h.step();
    h.run();
}

#[test]
fn with_no_dialog_service_and_slow_frames_every_save_and_open_ends_in_a_prompt_or_a_file() {
    let dir = temp("no-portal");
    let no_portal = || service(Duration::from_millis(30), None);
    // Ctrl+S on a new scene: the dialog answers nothing at once, the next frame is slow.
    let mut h = harness_with(&dir, default_scene(), no_portal());
    h.run();
    h.state_mut().studio.editor.touch();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.step();
    slow_frame(&mut h);
    assert!(h.get_by_label("Path:").is_focused(), "Ctrl+S ends in the typed prompt: {}", h.state().studio.message);
    let path = dir.join("saved.strata");
    enter_path(&mut h, &path);
    assert!(path.exists(), "the typed path saved");
    assert!(!h.state().studio.is_modified());

    // File > Save on a new scene.
    let mut h = harness_with(&dir, default_scene(), no_portal());
    h.run();
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Save (Ctrl+S)").click();
    h.step();
    slow_frame(&mut h);
    assert!(h.get_by_label("Path:").is_focused(), "File > Save ends in the typed prompt");

    // Save from the unsaved-changes question on Quit: the prompt, then the file, then the quit.
    let mut h = harness_with(&dir, default_scene(), no_portal());
    h.run();
    quit_and_save(&mut h);
    slow_frame(&mut h);
    assert!(h.get_by_label("Path:").is_focused(), "Save in the question ends in the typed prompt");
    let quit_path = dir.join("before-quit.strata");
    enter_path(&mut h, &quit_path);
    assert!(quit_path.exists(), "Save from the Quit question saved");
    assert!(!h.state().studio.is_modified());

    // Open.
    let mut h = harness_with(&dir, default_scene(), no_portal());
    h.run();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::O);
    h.step();
    slow_frame(&mut h);
    assert!(h.get_by_label("Path:").is_focused(), "Ctrl+O ends in the typed prompt");
    enter_path(&mut h, &path);
    assert_eq!(h.state().studio.path.as_deref(), Some(path.as_path()), "the typed path opened");

    // Import, Export and New world from their menus, each with a slow frame after the click.
    for (menu, item) in [
        ("File", "Import mesh… (PLY, OBJ, STL, glTF)"),
        ("File", "Export mesh… (glb, obj, stl, ply)"),
        ("Terrain", "New world…"),
        ("File", "Load reference image… (Ctrl+Shift+I)"),
    ] {
        let mut h = harness_with(&dir, default_scene(), no_portal());
        h.run();
        h.get_by_label(menu).click();
        h.run();
        h.get_by_label(item).click();
        h.step();
        slow_frame(&mut h);
        assert!(h.get_by_label("Path:").is_focused(), "{menu} > {item} ends in the typed prompt");
    }
}

/// File > Export mesh… with no dialog service and slow frames, marching cubes: the typed path
/// gets the mesh `strata export` writes (shading normals creased, chunk by chunk), byte for
/// byte, not the mesher's normals, and the status bar says what was written.
#[test]
fn an_export_typed_with_no_dialog_service_writes_the_command_line_s_shaded_mesh_and_says_so() {
    let dir = temp("export-typed");
    let mut h = harness_with(&dir, default_scene(), service(Duration::from_millis(30), None));
    h.run();
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Export mesh… (glb, obj, stl, ply)").click();
    h.step();
    slow_frame(&mut h);
    assert!(h.get_by_label("Path:").is_focused(), "the export ends in the typed prompt");
    let path = dir.join("ball.glb");
    enter_path(&mut h, &path);
    slow_frame(&mut h);
    let s = &h.state().studio;
    assert!(path.exists(), "{}", s.message);
    assert!(s.message.starts_with("Exported ") && s.message.contains("ball.glb"), "said: {}", s.message);
    let palette = s.editor.scene.export_palette();
    let written = std::fs::read(&path).unwrap();
    let shaded = dir.join("shaded.glb");
    let (mesh, _) = s.editor.export_mesh_shaded(s.export, strata_mesh::normals::DEFAULT_CREASE_DEGREES).unwrap();
    strata_mesh::export::save_mesh_with(&mesh, &shaded, &palette).unwrap();
    assert!(written == std::fs::read(&shaded).unwrap(), "the studio writes the command line's mesh");
    let plain = dir.join("plain.glb");
    strata_mesh::export::save_mesh_with(&s.editor.export_mesh(s.export).unwrap(), &plain, &palette).unwrap();
    assert!(written != std::fs::read(&plain).unwrap(), "not the mesher's normals");
    assert!(s.message.contains(&format!("{} triangles", mesh.triangle_count())), "said: {}", s.message);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_dialog_answer_counts_whatever_the_frames_and_a_cancel_is_said() {
    let dir = temp("slow-dialog");
    // A person picks a file after a while; the frames are slow too.
    let path = dir.join("picked.strata");
    let mut h = harness_with(&dir, default_scene(), service(Duration::from_millis(400), Some(path.clone())));
    h.run();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.step();
    slow_frame(&mut h);
    for _ in 0..50 {
        if path.exists() {
            break;
        }
        slow_frame(&mut h);
    }
    assert!(path.exists(), "the dialog's answer saved: {}", h.state().studio.message);
    // A person cancels (the dialog showed for a while): the status bar says so.
    let mut h = harness_with(&dir, default_scene(), service(Duration::from_millis(400), None));
    h.run();
    quit_and_save(&mut h);
    for _ in 0..50 {
        slow_frame(&mut h);
        if !h.state().modal_open() {
            break;
        }
    }
    let message = h.state().studio.message.clone();
    assert!(message.contains("cancelled") && message.contains("stays open"), "said: {message}");
    assert!(h.state().studio.is_modified(), "nothing was lost or pretended saved");
}

#[test]
fn a_focused_field_keeps_shortcut_letters_even_in_the_frame_it_was_clicked() {
    let dir = temp("field-letters");
    let mut h = harness(&dir);
    h.run();
    h.get_by_label("material name").click();
    h.run();
    type_keys(&mut h, "v");
    let s = &h.state().studio;
    assert_eq!(s.editor.scene.materials[0].name, "Clayv");
    assert_eq!(s.editor.tool.kind, ToolKind::Clay, "V went to the field, not to the paint tool");
    // A click on the field and a key in one slow frame.
    let mut h = harness(&dir);
    h.run();
    let field = h.get_by_label("Name").rect().center();
    h.event(egui::Event::PointerMoved(field));
    press_release(&mut h, field);
    h.key_press(egui::Key::E);
    h.event(egui::Event::Text("e".into()));
    h.step();
    h.run();
    let s = &h.state().studio;
    assert_eq!(s.editor.tool.kind, ToolKind::Clay, "E went to the field, not to the erase tool");
    assert_eq!(s.editor.scene.layers[0].name, "Claye");
}

#[test]
fn the_tool_panel_does_not_move_under_the_pointer_when_the_tool_changes() {
    let dir = temp("panel");
    let mut h = harness(&dir);
    h.run();
    let at = |h: &Harness<'static, StudioApp>| h.get_by_label("material name").rect().top();
    let clay = at(&h);
    for key in [egui::Key::A, egui::Key::D, egui::Key::S, egui::Key::G, egui::Key::V] {
        h.key_press(key);
        h.run();
        assert_eq!(at(&h), clay, "the material name field stays put for {:?}", h.state().studio.editor.tool.kind);
    }
}

#[test]
fn the_window_title_names_the_file_and_marks_unsaved_changes() {
    let dir = temp("title");
    let mut h = harness(&dir);
    h.run();
    assert_eq!(h.state().sent_title(), "Untitled — Strata Studio");
    h.state_mut().studio.editor.touch();
    h.run();
    assert_eq!(h.state().sent_title(), "Untitled* — Strata Studio");
    let path = dir.join("named.strata");
    h.state_mut().studio.act(strata_studio::Action::SaveAs(path)).unwrap();
    h.run();
    assert_eq!(h.state().sent_title(), "named.strata — Strata Studio");
}

#[test]
fn errors_stay_in_a_notice_until_dismissed_and_the_status_bar_stays_one_line() {
    let dir = temp("notice");
    let mut h = harness(&dir);
    h.run();
    let viewport = h.state().viewport_rect().unwrap();
    let missing = dir.join("no such folder").join("x".repeat(300) + ".strata");
    let _ = h.state_mut().studio.act(strata_studio::Action::Open(missing));
    for _ in 0..5 {
        h.step();
    }
    h.run();
    assert!(h.query_all_by_label_contains("Could not open").count() >= 1, "the error is shown");
    assert_eq!(h.state().viewport_rect().unwrap(), viewport, "a long error does not shrink the viewport");
    h.get_by_label("Dismiss").click();
    h.run();
    assert!(h.state().studio.notice.is_none());
    assert!(h.query_by_label("Dismiss").is_none(), "the notice is gone once read");
}

#[test]
fn a_view_message_goes_once_the_camera_moves_and_new_windows_get_their_second_frame() {
    let dir = temp("stale");
    let mut h = harness(&dir);
    h.run();
    h.key_press(egui::Key::Num1);
    h.run();
    assert!(h.state().studio.status().contains("Front view"));
    h.state_mut().studio.camera.orbit(0.5, 0.1);
    h.run();
    assert!(!h.state().studio.status().contains("Front view"), "{}", h.state().studio.status());
    // F1: the help window is laid out in a first pass; the app asks for the frame that shows it.
    h.key_press(egui::Key::F1);
    h.step();
    assert!(h.ctx.has_requested_repaint(), "the frame that opened the help asks for one more");
    h.key_press(egui::Key::F1);
    h.run();
    // A notice that comes from no input (a background job failing): its first frame asks for
    // the next, or the notice would show only once the pointer moves.
    h.state_mut().studio.notice = Some("The large dab failed".into());
    h.step();
    assert!(h.ctx.has_requested_repaint(), "the frame that opened the notice asks for one more");
}

/// Queues a press and a release of the primary button at `at` (for one frame).
fn press_release(h: &mut Harness<'static, StudioApp>, at: egui::Pos2) {
    for pressed in [true, false] {
        h.event(egui::Event::PointerButton {
            pos: at,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: egui::Modifiers::NONE,
        });
    }
}

/// Presses and releases the primary button at `at` within one frame.
fn quick_click(h: &mut Harness<'static, StudioApp>, at: egui::Pos2) {
    press_release(h, at);
    h.step();
}

#[test]
fn keys_and_clicks_of_one_slow_frame_all_count_in_order() {
    let dir = temp("one-frame");
    let mut h = harness(&dir);
    h.run();
    let r0 = h.state().studio.editor.tool.radius;
    // V then E within one frame ends on erase; three ] grow the brush three times.
    for key in [egui::Key::V, egui::Key::E, egui::Key::CloseBracket, egui::Key::CloseBracket, egui::Key::CloseBracket] {
        h.key_press(key);
    }
    h.step();
    let s = &h.state().studio;
    assert_eq!(s.editor.tool.kind, ToolKind::Erase);
    assert!((s.editor.tool.radius / r0 - 1.15f64.powi(3)).abs() < 1e-9, "radius {} from {r0}", s.editor.tool.radius);
    // A click on the ball pressed and released within one frame is a dab.
    let before = h.state().studio.editor.scene.layers[0].volume.clone();
    let centre = h.state().viewport_rect().unwrap().center();
    h.hover_at(centre);
    h.step();
    quick_click(&mut h, centre);
    h.run();
    assert!(h.state().studio.editor.scene.layers[0].volume != before, "the quick click erased a dab");
    assert_eq!(h.state().studio.editor.history().undo_len(), 1);
}

#[test]
fn f_sizes_the_brush_by_dragging_and_the_radius_can_live_on_screen() {
    let dir = temp("resize");
    let mut h = harness(&dir);
    h.run();
    let centre = h.state().viewport_rect().unwrap().center();
    h.hover_at(centre);
    h.run();
    let r0 = h.state().studio.editor.tool.radius;
    h.key_press(egui::Key::F);
    h.run();
    assert!(h.state().modal_open(), "sizing holds the keyboard and the pointer");
    h.hover_at(centre + egui::vec2(60.0, 0.0));
    h.run();
    let r1 = h.state().studio.editor.tool.radius;
    assert!(r1 > r0 * 1.5, "moving away grows the brush: {r0} → {r1}");
    quick_click(&mut h, centre + egui::vec2(60.0, 0.0));
    h.run();
    assert!(!h.state().modal_open());
    let kept = h.state().studio.editor.tool.radius;
    assert!((kept - r1).abs() < 1e-9 && h.state().studio.editor.history().undo_len() == 0, "the click kept it, no dab");
    // Escape puts the old size back.
    h.key_press(egui::Key::F);
    h.run();
    h.hover_at(centre + egui::vec2(200.0, 0.0));
    h.run();
    h.key_press(egui::Key::Escape);
    h.run();
    assert_eq!(h.state().studio.editor.tool.radius, kept);
    // On screen: the world radius follows the zoom, the screen size stays.
    h.state_mut().studio.screen_radius = true;
    h.hover_at(centre);
    h.run();
    let near = h.state().studio.editor.tool.radius;
    h.state_mut().studio.camera.distance *= 2.0;
    h.hover_at(centre + egui::vec2(1.0, 0.0));
    h.run();
    let far = h.state().studio.editor.tool.radius;
    assert!(far > near * 1.3, "zoomed out, the same screen size is more world: {near} → {far}");
}

#[test]
fn the_wheel_zooms_towards_the_pointer() {
    let dir = temp("zoom");
    let mut h = harness(&dir);
    h.run();
    let rect = h.state().viewport_rect().unwrap();
    let at = rect.center() + egui::vec2(rect.width() * 0.2, -rect.height() * 0.1);
    h.hover_at(at);
    h.run();
    let s = &h.state().studio;
    let (x, y) = ((at.x - rect.left()) / rect.width() * 2.0 - 1.0, 1.0 - (at.y - rect.top()) / rect.height() * 2.0);
    let world = s.surface_point(x, y, rect.width() / rect.height()).unwrap();
    let d0 = s.camera.distance;
    h.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Point,
        delta: egui::vec2(0.0, 200.0),
        phase: egui::TouchPhase::Move,
        source: egui::MouseWheelSource::Wheel,
        modifiers: egui::Modifiers::NONE,
    });
    for _ in 0..30 {
        h.step();
    }
    assert!(h.state().studio.camera.distance < d0 * 0.95, "zoomed in");
    let seen = h.state().screen_of(world.as_vec3()).unwrap();
    assert!((seen - at).length() < 3.0, "the point under the pointer stays under it: {seen:?} vs {at:?}");
}

/// Two boxes facing the camera, the left one 20 units nearer than the right one.
fn two_depths() -> strata_editor::Scene {
    use strata_volume::brush::Cuboid;
    let mut scene = default_scene();
    let cell = scene.layers[0].transform.scale;
    let v = &mut scene.layers[0].volume;
    *v = strata_volume::Volume::new();
    for (c, half) in [
        (glam::DVec3::new(20.0, 16.0, 40.0), glam::DVec3::new(8.0, 8.0, 4.0)),
        (glam::DVec3::new(42.0, 16.0, 20.0), glam::DVec3::new(14.0, 8.0, 4.0)),
    ] {
        v.add(&Cuboid::new(c / cell, half / cell).unwrap()).unwrap();
    }
    scene.view =
        strata_editor::View { target: glam::DVec3::new(32.0, 16.0, 30.0), distance: 70.0, yaw: 0.0, pitch: 0.0 };
    scene
}

/// A left drag from `a` to `b` (screen points) in `steps` moves.
fn drag(h: &mut Harness<'static, StudioApp>, a: egui::Pos2, b: egui::Pos2, steps: usize) {
    h.hover_at(a);
    h.step();
    h.drag_at(a);
    h.step();
    for i in 1..=steps {
        h.hover_at(a + (b - a) * (i as f32 / steps as f32));
        h.step();
    }
    h.drop_at(b);
    h.step();
    h.run();
}

#[test]
fn a_stroke_from_a_near_surface_onto_a_far_one_stays_on_the_surface() {
    let dir = temp("follow");
    for kind in [ToolKind::Add, ToolKind::Paint] {
        let mut h = harness_with(&dir, two_depths(), Dialogs::Typed);
        h.run();
        {
            let s = &mut h.state_mut().studio;
            s.editor.tool.kind = kind;
            s.editor.tool.radius = 1.5;
            s.editor.tool.material = 4;
            // (Paint at full strength paints every node; below, a dithered share.)
            s.editor.tool.field_strength = 1.0;
        }
        let (a, b) = {
            let app = h.state();
            (
                app.screen_of(glam::Vec3::new(22.0, 16.0, 44.0)).unwrap(),
                app.screen_of(glam::Vec3::new(46.0, 16.0, 24.0)).unwrap(),
            )
        };
        drag(&mut h, a, b, 24);
        // At the stroke's end, the far box's front (z = 24) is what the stroke worked on.
        let s = &h.state().studio;
        let eye = s.camera.eye().as_dvec3();
        // (A little short of the end: the last dab is up to a spacing before it.)
        let end = glam::DVec3::new(44.0, 16.0, 24.0);
        let pick = s.editor.pick(eye, (end - eye).normalize(), 1e4).expect("the far box is under the stroke's end");
        match kind {
            ToolKind::Paint => {
                assert_eq!(s.editor.material_at(&pick), Some(4), "the far face was painted where the stroke ended");
            }
            _ => {
                // Matter was added on the far face (it came out towards the eye), not left in the
                // air at the near box's depth.
                assert!(pick.point.z > 24.5 && pick.point.z < 28.0, "added on the far face: {:?}", pick.point);
            }
        }
    }
}

#[test]
fn grab_moves_the_surface_as_far_as_the_pointer() {
    let dir = temp("grab");
    let mut h = harness(&dir);
    h.run();
    h.key_press(egui::Key::G);
    h.run();
    h.state_mut().studio.editor.tool.radius = 5.0;
    // From a point on the ball's front, 60 points to the right.
    let rect = h.state().viewport_rect().unwrap();
    let a = rect.center();
    let b = a + egui::vec2(60.0, 0.0);
    let (start, moved_to) = {
        let s = &h.state().studio;
        let aspect = rect.width() / rect.height();
        let ndc = |p: egui::Pos2| {
            ((p.x - rect.left()) / rect.width() * 2.0 - 1.0, 1.0 - (p.y - rect.top()) / rect.height() * 2.0)
        };
        let (x, y) = ndc(a);
        let start = s.surface_point(x, y, aspect).unwrap();
        let eye = s.camera.eye().as_dvec3();
        let depth = (start - eye).length();
        let (x, y) = ndc(b);
        let (o, d) = s.camera.ray(x, y, aspect);
        (start, o.as_dvec3() + d.as_dvec3() * depth)
    };
    drag(&mut h, a, b, 12);
    // The material that was under the pointer is under it again, where the pointer went.
    let s = &h.state().studio;
    let eye = s.camera.eye().as_dvec3();
    let pick = s.editor.pick(eye, (moved_to - eye).normalize(), 1e4).expect("the grabbed surface is under the pointer");
    let travel = (moved_to - start).length();
    let err = (pick.point - moved_to).length();
    assert!(err < 0.25 * travel, "grabbed {travel:.2} units; the surface is {err:.2} from where the pointer went");
}

/// Issue 32: a region masked with the mask tool (M) keeps its shape, its crossings included,
/// when the smooth tool is dragged across it; the mask's actions run from their keys and the
/// Edit menu, each one undo step.
#[test]
fn a_masked_region_keeps_its_shape_when_smoothed_across() {
    let dir = temp("mask");
    let mut h = harness(&dir);
    h.run();
    let cell = strata_studio::DEFAULT_CELL;
    // A ridge of clay first, so that smoothing has something to take off.
    h.state_mut().studio.editor.tool.radius = 6.0 * cell;
    drag_over_the_ball(&mut h, 12);
    h.key_press(egui::Key::M);
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Mask);
    h.state_mut().studio.editor.tool.field_strength = 1.0;
    h.state_mut().studio.editor.tool.radius = 8.0 * cell;
    drag_over_the_ball(&mut h, 6);
    let volume = h.state().studio.editor.scene.layers[0].volume.clone();
    let (lo, hi) = volume.chunk_bounds_grid().unwrap();
    let nodes: Vec<glam::I64Vec3> = (lo.z as i64..=hi.z as i64)
        .flat_map(|z| {
            (lo.y as i64..=hi.y as i64)
                .flat_map(move |y| (lo.x as i64..=hi.x as i64).map(move |x| glam::I64Vec3::new(x, y, z)))
        })
        .filter(|n| volume.mask().weight(*n) == strata_volume::PROTECTED)
        .collect();
    assert!(nodes.len() > 100, "the stroke masked {} nodes", nodes.len());
    // The held nodes' states and the crossings along x between two of them.
    let shape = |v: &strata_volume::Volume| -> Vec<bool> {
        nodes
            .iter()
            .flat_map(|n| {
                let along = v.mask().weight(*n + glam::I64Vec3::X) == strata_volume::PROTECTED;
                let edge: Vec<bool> = if along {
                    (1..8).map(|k| v.is_inside(n.as_dvec3() + glam::DVec3::X * (k as f64 / 8.0))).collect()
                } else {
                    Vec::new()
                };
                std::iter::once(v.node_inside(*n)).chain(edge)
            })
            .collect()
    };
    let held = shape(&volume);
    h.key_press(egui::Key::S);
    h.run();
    h.state_mut().studio.editor.tool.radius = 14.0 * cell;
    h.state_mut().studio.editor.tool.field_strength = 1.0;
    drag_over_the_ball(&mut h, 12);
    let smoothed = h.state().studio.editor.scene.layers[0].volume.clone();
    assert!(smoothed != volume, "the smooth stroke changed nothing: {}", h.state().studio.message);
    assert!(shape(&smoothed) == held, "the masked region changed under smoothing");
    // Ctrl+I inverts the mask, the Edit menu clears it; Ctrl+Z takes each back.
    let steps = h.state().studio.editor.history().undo_len();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::I);
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers[0].volume.mask().weight(nodes[0]), 0, "inverted");
    h.get_by_label("Edit").click();
    h.run();
    h.get_by_label("Clear mask (Alt+M)").click();
    h.run();
    assert!(h.state().studio.editor.scene.layers[0].volume.mask().is_clear(), "{}", h.state().studio.message);
    assert_eq!(h.state().studio.editor.history().undo_len(), steps + 2);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert!(*h.state().studio.editor.scene.layers[0].volume.mask() == *smoothed.mask(), "undone back to the mask");
}

/// Issue 32: `R` cycles the stroke stabiliser; a shaky drag across the ball with it strong
/// lays its dabs along a far straighter line than the same drag without it.
#[test]
fn a_stabilised_stroke_draws_a_shaky_drag_as_a_clean_line() {
    let dir = temp("stabiliser");
    let mut h = harness(&dir);
    h.run();
    h.key_press(egui::Key::A);
    h.run();
    h.state_mut().studio.editor.tool.radius = 3.0 * strata_studio::DEFAULT_CELL;
    // The dabs of a drag that zigzags 6 points up and down as it goes right: how much they
    // wiggle.
    let shaky = |h: &mut Harness<'static, StudioApp>| -> f64 {
        h.state_mut().studio.editor.record_ops(true);
        let centre = egui::pos2(600.0, 400.0);
        h.hover_at(centre);
        h.step();
        h.drag_at(centre);
        h.step();
        for i in 1..=24 {
            let wobble = if i % 2 == 0 { 6.0 } else { -6.0 };
            h.hover_at(centre + egui::vec2(i as f32 * 4.0, wobble));
            h.step();
        }
        h.drop_at(centre + egui::vec2(100.0, 0.0));
        h.step();
        h.step();
        let dabs: Vec<glam::DVec3> = h
            .state_mut()
            .studio
            .editor
            .take_ops()
            .into_iter()
            .flat_map(|o| o.op.dabs)
            .filter_map(|d| match d {
                strata_editor::DabRecord::Dab { at, .. } => Some(at),
                _ => None,
            })
            .collect();
        h.state_mut().studio.editor.record_ops(false);
        assert!(dabs.len() > 4, "the drag made {} dabs", dabs.len());
        // How much longer the path through the dabs is than the way from the first to the
        // last: a zigzag's wiggle (a straight line: 0).
        let path: f64 = dabs.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        path / (dabs[dabs.len() - 1] - dabs[0]).length() - 1.0
    };
    let plain = shaky(&mut h);
    assert_eq!(h.state().studio.editor.stabiliser, strata_editor::Stabiliser::Off);
    h.key_press(egui::Key::R);
    h.run();
    h.key_press(egui::Key::R);
    h.run();
    assert_eq!(h.state().studio.editor.stabiliser, strata_editor::Stabiliser::Strong, "{}", h.state().studio.message);
    let steady = shaky(&mut h);
    assert!(plain > 0.3, "the drag did not zigzag: {plain}");
    assert!(steady < 0.3 * plain, "stabilised, the path wiggles {steady}; without, {plain}");
}

/// The solid nodes of the default scene's layer (what a stamp adds to or carves from).
fn solid_nodes(h: &Harness<'static, StudioApp>) -> usize {
    let v = &h.state().studio.editor.scene.layers[0].volume;
    let (lo, hi) = v.chunk_bounds_grid().unwrap();
    let mut n = 0;
    for z in lo.z as i64..=hi.z as i64 {
        for y in lo.y as i64..=hi.y as i64 {
            for x in lo.x as i64..=hi.x as i64 {
                n += usize::from(v.node_inside(glam::I64Vec3::new(x, y, z)));
            }
        }
    }
    n
}

/// Issue 32: `H` picks the stamp tool; a picture picked from its list is sprayed across the ball
/// (material rises, one undo step); `J` switches to dragging one stamp out (nothing changes
/// until the release, the preview grows with the drag); a PNG typed into the prompt that
/// Ctrl+Shift+O opens becomes the picture.
#[test]
fn a_stamp_is_picked_sprayed_dragged_out_and_loaded_from_a_png() {
    use strata_editor::{StampSource, StampStroke};
    use strata_volume::tools::BuiltinStamp;
    let dir = temp("stamp");
    let mut h = harness(&dir);
    h.run();
    h.key_press(egui::Key::H);
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Stamp);
    h.get_by_value("Dome").click();
    h.run();
    h.get_by_label("Ring").click();
    h.run();
    assert_eq!(h.state().studio.editor.tool.stamp.source, StampSource::Builtin(BuiltinStamp::Ring));
    let cell = strata_studio::DEFAULT_CELL;
    h.state_mut().studio.editor.tool.radius = 6.0 * cell;
    h.state_mut().studio.editor.tool.field_strength = 1.0;
    let before = solid_nodes(&h);
    let steps = h.state().studio.editor.history().undo_len();
    drag_over_the_ball(&mut h, 12);
    let sprayed = solid_nodes(&h);
    assert!(
        sprayed > before + 50,
        "the sprayed stamps raised {} nodes: {}",
        sprayed - before,
        h.state().studio.message
    );
    assert_eq!(h.state().studio.editor.history().undo_len(), steps + 1);
    // Dragging one out: J, then press at the ball's middle and drag 60 points right.
    h.key_press(egui::Key::J);
    h.run();
    assert_eq!(h.state().studio.editor.tool.stamp.stroke, StampStroke::Drag);
    let centre = egui::pos2(640.0, 400.0);
    h.hover_at(centre);
    h.step();
    h.drag_at(centre);
    h.step();
    for i in 1..=15 {
        h.hover_at(centre + egui::vec2(i as f32 * 4.0, 0.0));
        h.step();
    }
    assert_eq!(solid_nodes(&h), sprayed, "nothing is stamped while dragging");
    let (_, radius, _) = h.state().studio.editor.stamp_drag().expect("a stamp is being dragged out");
    assert!(radius > 6.0 * cell, "the drag sized it to {radius}");
    assert!(h.state().studio.preview_scale() > 1.0, "the preview shows the dragged size");
    h.drop_at(centre + egui::vec2(60.0, 0.0));
    h.step();
    h.step();
    assert!(h.state().studio.editor.stamp_drag().is_none());
    assert!(solid_nodes(&h) > sprayed, "the released stamp raised nothing: {}", h.state().studio.message);
    assert_eq!(h.state().studio.editor.history().undo_len(), steps + 2);
    // A PNG through the prompt: a white square on black.
    let path = dir.join("square.png");
    {
        let file = std::fs::File::create(&path).unwrap();
        let mut e = png::Encoder::new(std::io::BufWriter::new(file), 8, 8);
        e.set_color(png::ColorType::Grayscale);
        let pixels: Vec<u8> =
            (0..64).map(|i| if (2..6).contains(&(i % 8)) && (2..6).contains(&(i / 8)) { 255 } else { 0 }).collect();
        e.write_header().unwrap().write_image_data(&pixels).unwrap();
    }
    h.key_press_modifiers(egui::Modifiers { shift: true, ..egui::Modifiers::COMMAND }, egui::Key::O);
    h.run();
    enter_path(&mut h, &path);
    assert!(
        matches!(h.state().studio.editor.tool.stamp.source, StampSource::Loaded(_)),
        "{}",
        h.state().studio.message
    );
    assert!(h.state().studio.message.contains("square.png"), "{}", h.state().studio.message);
    assert_eq!(h.state().studio.stamp_name(), "square.png");
    // A file that is not a PNG is said, and the picture stays.
    let bad = dir.join("bad.png");
    std::fs::write(&bad, b"not a png").unwrap();
    h.key_press_modifiers(egui::Modifiers { shift: true, ..egui::Modifiers::COMMAND }, egui::Key::O);
    h.run();
    enter_path(&mut h, &bad);
    assert!(h.state().studio.notice.as_deref().is_some_and(|n| n.contains("bad.png")), "{:?}", h.state().studio.notice);
    assert_eq!(h.state().studio.stamp_name(), "square.png");
}

/// Issue 32: a preset picked from the shelf sets the brush; each tool keeps its own falloff; a
/// falloff point dragged makes a custom curve; the brush saved as a preset under a typed name is
/// on the shelf of the next studio started on the same folder, and the Edit menu picks presets.
#[test]
fn presets_are_picked_saved_and_kept_and_each_tool_keeps_its_falloff() {
    use strata_volume::tools::Falloff;
    let dir = temp("presets");
    let mut h = harness(&dir);
    h.run();
    h.get_by_label("Presets").click();
    h.run();
    h.get_by_label("Polish").click();
    h.run();
    let tool = h.state().studio.editor.tool;
    assert_eq!((tool.kind, tool.falloff, tool.field_strength), (ToolKind::Smooth, Falloff::Sphere, 0.8));
    // Inflate has its own falloff (smooth, never set); smoothing's comes back with it.
    h.key_press(egui::Key::I);
    h.run();
    assert_eq!(h.state().studio.editor.tool.falloff, Falloff::Smooth);
    h.key_press(egui::Key::S);
    h.run();
    assert_eq!(h.state().studio.editor.tool.falloff, Falloff::Sphere);
    // Dragging the curve's middle point down makes a custom falloff, lower in the middle.
    let plot = h.get_by_label("Drag a point to shape the falloff: centre on the left, rim on the right").rect();
    let middle =
        egui::pos2(plot.left() + plot.width() * 0.5, plot.bottom() - plot.height() * Falloff::Sphere.at(0.5) as f32);
    h.hover_at(middle);
    h.step();
    h.drag_at(middle);
    h.step();
    h.hover_at(middle + egui::vec2(0.0, 20.0));
    h.step();
    h.drop_at(middle + egui::vec2(0.0, 20.0));
    h.run();
    let custom = h.state().studio.editor.tool.falloff;
    assert!(matches!(custom, Falloff::Curve(_)), "{custom:?}");
    assert!(custom.at(0.5) < Falloff::Sphere.at(0.5) - 0.1, "{}", custom.at(0.5));
    // Save it as "Low middle".
    h.get_by_label("Save preset…").click();
    h.run();
    type_keys(&mut h, "Low middle");
    h.key_press(egui::Key::Enter);
    h.run();
    assert!(h.state().studio.message.contains("Saved preset"), "{}", h.state().studio.message);
    assert!(dir.join("recovery").join("presets.json").exists());
    // Another tool, then the Edit menu's presets.
    h.get_by_label("Edit").click();
    h.run();
    h.get_by_label("Brush presets").click();
    h.run();
    // (The shelf has a Rivets button too: the open menu's is found first.)
    h.query_all_by_label("Rivets").next().unwrap().click();
    h.run();
    assert_eq!(h.state().studio.editor.tool.kind, ToolKind::Stamp);
    // A studio started again on the folder has the preset; picking it brings the curve back.
    let mut again = harness(&dir);
    again.run();
    again.get_by_label("Presets").click();
    again.run();
    again.get_by_label("Low middle").click();
    again.run();
    let tool = again.state().studio.editor.tool;
    assert_eq!((tool.kind, tool.falloff), (ToolKind::Smooth, custom));
    // A damaged presets file is said at start and never overwritten.
    let damaged = temp("presets-damaged");
    std::fs::create_dir_all(damaged.join("recovery")).unwrap();
    let file = damaged.join("recovery").join("presets.json");
    std::fs::write(&file, b"{ half a preset").unwrap();
    let mut h = harness(&damaged);
    h.run();
    assert!(
        h.state().studio.notice.as_deref().is_some_and(|n| n.contains("presets.json")),
        "{:?}",
        h.state().studio.notice
    );
    h.get_by_label("Presets").click();
    h.run();
    h.get_by_label("Save preset…").click();
    h.run();
    type_keys(&mut h, "x");
    h.key_press(egui::Key::Enter);
    h.run();
    assert!(h.state().studio.message.contains("not overwritten"), "{}", h.state().studio.message);
    assert_eq!(std::fs::read(&file).unwrap(), b"{ half a preset");
}

/// A left drag over the ball whose every move also brings a touch of force `force` (how
/// eframe reports a pen's or a finger's pressure), then the release.
fn pen_drag(h: &mut Harness<'static, StudioApp>, force: f32) {
    let centre = egui::pos2(640.0, 400.0);
    let touch = |phase, pos| egui::Event::Touch {
        device_id: egui::TouchDeviceId(1),
        id: egui::TouchId(1),
        phase,
        pos,
        force: Some(force),
    };
    h.hover_at(centre);
    h.step();
    h.event(touch(egui::TouchPhase::Start, centre));
    h.drag_at(centre);
    h.step();
    for i in 1..=6 {
        let p = centre + egui::vec2(i as f32 * 4.0, 0.0);
        h.event(touch(egui::TouchPhase::Move, p));
        h.hover_at(p);
        h.step();
    }
    let end = centre + egui::vec2(24.0, 0.0);
    h.event(touch(egui::TouchPhase::End, end));
    h.drop_at(end);
    h.step();
    h.step();
}

/// Issue 32: a pen's pressure (synthetic touch force) reaches the dabs and scales the brush
/// through the curves; Alt+P turns it off (full pressure); a mouse dabs at full pressure.
#[test]
fn pen_pressure_scales_the_brush_through_its_curves_and_alt_p_turns_it_off() {
    let dir = temp("pressure");
    let mut h = harness(&dir);
    h.run();
    h.key_press(egui::Key::A);
    h.run();
    h.state_mut().studio.editor.tool.strength = 1.0;
    h.state_mut().studio.editor.record_ops(true);
    let pressures = |h: &mut Harness<'static, StudioApp>| -> Vec<f64> {
        h.state_mut()
            .studio
            .editor
            .take_ops()
            .into_iter()
            .flat_map(|o| o.op.dabs)
            .map(|d| match d {
                strata_editor::DabRecord::Dab { pressure, .. } | strata_editor::DabRecord::Grab { pressure, .. } => {
                    pressure
                }
            })
            .collect()
    };
    pen_drag(&mut h, 0.3);
    let pen = pressures(&mut h);
    assert!(!pen.is_empty() && pen.iter().all(|&p| (p - 0.3).abs() < 1e-6), "{pen:?}");
    let tool = h.state().studio.editor.tool;
    assert!((tool.radius_at(0.3) - 0.3 * tool.radius).abs() < 1e-6, "the linear size curve at 0.3");
    drag_over_the_ball(&mut h, 4);
    let mouse = pressures(&mut h);
    assert!(!mouse.is_empty() && mouse.iter().all(|&p| p == 1.0), "a mouse dabs at full pressure: {mouse:?}");
    h.key_press_modifiers(egui::Modifiers::ALT, egui::Key::P);
    h.run();
    assert!(!h.state().studio.editor.tool.pressure.enabled, "{}", h.state().studio.message);
    let tool = h.state().studio.editor.tool;
    assert_eq!(tool.radius_at(0.3), tool.radius, "off: as at full pressure");
    // The tool panel's Pressure section holds the switch, the amounts and the curves.
    h.get_by_label("Pressure (Alt+P)").click();
    h.run();
    h.get_by_label("Pressure on (Alt+P)").click();
    h.run();
    assert!(h.state().studio.editor.tool.pressure.enabled);
    assert!(h.query_all_by_label("pressure to size").count() > 0);
}

/// Issue 32: Edit → Insert mesh → Bunny waits as a preview; a press on the ball places it on
/// the surface; the panel sizes it; Add insert applies it as one undo step; Escape cancels a
/// waiting cube; an open mesh file is refused with its reason.
#[test]
fn the_bunny_is_inserted_placed_on_the_surface_added_and_undone() {
    let dir = temp("insert");
    let mut h = harness(&dir);
    h.run();
    let start = h.state().studio.editor.scene.layers[0].volume.clone();
    let insert_from_menu = |h: &mut Harness<'static, StudioApp>, item: &str| {
        h.get_by_label("Edit").click();
        h.run();
        h.get_by_label("Insert mesh").click();
        h.run();
        h.get_by_label(item).click();
        h.run();
    };
    insert_from_menu(&mut h, "Bunny");
    assert!(h.state().studio.insert.is_some(), "{}", h.state().studio.message);
    // A press and release on the ball's middle places it there, on the surface.
    let centre = egui::pos2(640.0, 400.0);
    h.hover_at(centre);
    h.step();
    h.drag_at(centre);
    h.step();
    h.drop_at(centre);
    h.step();
    let placed = h.state().studio.insert.as_ref().unwrap().placement.position;
    let layer = &h.state().studio.editor.scene.layers[0];
    let g = layer.transform.to_grid(placed);
    let sides: Vec<bool> = [glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z]
        .iter()
        .flat_map(|&d| [layer.volume.is_inside(g + d * 0.7), layer.volume.is_inside(g - d * 0.7)])
        .collect();
    assert!(sides.contains(&true) && sides.contains(&false), "placed {placed:?}: not on the surface");
    assert_eq!(h.state().studio.editor.scene.layers[0].volume, start, "placing changes nothing");
    h.state_mut().studio.insert.as_mut().unwrap().placement.size = 3.0;
    let steps = h.state().studio.editor.history().undo_len();
    h.get_by_label("Add insert").click();
    h.run();
    assert!(h.state().studio.insert.is_none(), "{}", h.state().studio.message);
    let added = h.state().studio.editor.scene.layers[0].volume.clone();
    assert!(added != start);
    added.check_invariants().unwrap();
    assert_eq!(h.state().studio.editor.history().undo_len(), steps + 1);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert_eq!(h.state().studio.editor.scene.layers[0].volume, start, "Ctrl+Z takes the insert back");
    // Escape drops a waiting cube.
    insert_from_menu(&mut h, "Cube");
    assert!(h.state().studio.insert.is_some());
    h.key_press(egui::Key::Escape);
    h.run();
    assert!(h.state().studio.insert.is_none());
    // An open mesh from a file is refused, saying why.
    let open = dir.join("open.obj");
    std::fs::write(&open, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n").unwrap();
    insert_from_menu(&mut h, "From file…");
    enter_path(&mut h, &open);
    assert!(h.state().studio.insert.is_none());
    assert!(
        h.state().studio.notice.as_deref().is_some_and(|n| n.contains("not closed")),
        "{:?}",
        h.state().studio.notice
    );
}

/// Drags gizmo handle `handle` by `by` (points) in a few frames, then releases it.
fn drag_handle(h: &mut Harness<'static, StudioApp>, handle: strata_studio::GizmoHandle, by: egui::Vec2) {
    let (_, handles) = h.state().gizmo_on_screen().expect("the gizmo shows");
    let at = handles.iter().find(|(k, _)| *k == handle).expect("the handle shows").1;
    h.hover_at(at);
    h.step();
    h.drag_at(at);
    h.step();
    for i in 1..=5 {
        h.hover_at(at + by * (i as f32 / 5.0));
        h.step();
    }
    h.drop_at(at + by);
    h.step();
    h.step();
}

/// Issue 32: the gizmo moves the waiting bunny insert along an axis (nothing sculpted);
/// Ctrl snaps the move to cells; `Ctrl+T` shows it on the active layer, whose move, turn and
/// scale are one undo step a drag.
#[test]
fn the_gizmo_moves_an_insert_and_moves_and_turns_a_layer_one_undo_step_a_drag() {
    use strata_studio::GizmoHandle;
    let dir = temp("gizmo");
    let mut h = harness(&dir);
    h.run();
    let start = h.state().studio.editor.scene.layers[0].volume.clone();
    h.get_by_label("Edit").click();
    h.run();
    h.get_by_label("Insert mesh").click();
    h.run();
    h.get_by_label("Bunny").click();
    h.run();
    h.run();
    let before = h.state().studio.insert.as_ref().unwrap().placement;
    let (c, handles) = h.state().gizmo_on_screen().unwrap();
    let tip = handles.iter().find(|(k, _)| *k == GizmoHandle::Move(0)).unwrap().1;
    drag_handle(&mut h, GizmoHandle::Move(0), (tip - c).normalized() * 40.0);
    let after = h.state().studio.insert.as_ref().unwrap().placement;
    let moved = after.position - before.position;
    assert!(moved.x > 0.1 && moved.y.abs() < 1e-9 && moved.z.abs() < 1e-9, "moved {moved:?}");
    assert_eq!(h.state().studio.editor.scene.layers[0].volume, start, "dragging the gizmo sculpts nothing");
    // With Ctrl held the move snaps to cells of the active layer (0.25 units).
    h.event(egui::Event::ModifiersChanged(egui::Modifiers::COMMAND));
    drag_handle(&mut h, GizmoHandle::Move(0), (tip - c).normalized() * 33.0);
    h.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    let snapped = h.state().studio.insert.as_ref().unwrap().placement.position.x - after.position.x;
    let cells = snapped / strata_studio::DEFAULT_CELL;
    assert!(snapped > 0.1 && (cells - cells.round()).abs() < 1e-9, "snapped by {snapped}");
    h.key_press(egui::Key::Escape);
    h.run();
    // The layer gizmo: a move along y, then a turn about y, each one undo step.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::T);
    h.run();
    let t0 = h.state().studio.editor.scene.layers[0].transform;
    let steps = h.state().studio.editor.history().undo_len();
    let (c, handles) = h.state().gizmo_on_screen().unwrap();
    let tip = handles.iter().find(|(k, _)| *k == GizmoHandle::Move(1)).unwrap().1;
    drag_handle(&mut h, GizmoHandle::Move(1), (tip - c).normalized() * 30.0);
    let t1 = h.state().studio.editor.scene.layers[0].transform;
    assert!(t1.translation.y > t0.translation.y + 0.1, "{t0:?} -> {t1:?}");
    assert_eq!(h.state().studio.editor.history().undo_len(), steps + 1, "a drag is one step");
    let (c, handles) = h.state().gizmo_on_screen().unwrap();
    let ring = handles.iter().find(|(k, _)| *k == GizmoHandle::Turn(1)).unwrap().1;
    let side = egui::vec2(-(ring - c).y, (ring - c).x);
    drag_handle(&mut h, GizmoHandle::Turn(1), side * 0.8);
    let t2 = h.state().studio.editor.scene.layers[0].transform;
    assert!(t2.rotation.angle_between(t1.rotation) > 0.2, "turned by {}", t2.rotation.angle_between(t1.rotation));
    assert_eq!(h.state().studio.editor.history().undo_len(), steps + 2);
    // The square scales about the layer's middle: up and right grows it.
    drag_handle(&mut h, GizmoHandle::Scale, egui::vec2(30.0, -30.0));
    let t3 = h.state().studio.editor.scene.layers[0].transform;
    assert!(t3.scale > t2.scale * 1.3, "{} -> {}", t2.scale, t3.scale);
    assert_eq!(h.state().studio.editor.history().undo_len(), steps + 3);
    assert_eq!(h.state().studio.editor.scene.layers[0].volume, start, "the lists stay; only the placement changes");
    for _ in 0..3 {
        h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
        h.run();
    }
    assert_eq!(h.state().studio.editor.scene.layers[0].transform, t0, "three undos give the layer back");
}

/// An 8 × 4 picture, red on the left half and blue on the right, as a PNG or a JPEG.
fn red_blue_picture(path: &std::path::Path) {
    let img =
        image::RgbImage::from_fn(8, 4, |x, _| if x < 4 { image::Rgb([255, 0, 0]) } else { image::Rgb([0, 0, 255]) });
    img.save(path).unwrap();
}

/// Issue 32: a PNG loaded with `Ctrl+Shift+I` in the right view lies square to it, selected;
/// its opacity follows the panel's slider; the gizmo moves it (one undo step); locked, it keeps
/// its place and cannot be deleted; it is saved with the scene and reopens equal; `Alt+R` hides
/// them all; a dropped JPEG becomes one too, and a file that is not a picture is said.
#[test]
fn a_reference_image_is_loaded_faded_moved_locked_and_saved_with_the_scene() {
    use strata_editor::ReferencePlane;
    use strata_studio::GizmoHandle;
    let dir = temp("reference");
    let mut h = harness(&dir);
    h.run();
    let png = dir.join("side.png");
    red_blue_picture(&png);
    h.key_press(egui::Key::Num3);
    h.run();
    h.key_press_modifiers(egui::Modifiers { shift: true, ..egui::Modifiers::COMMAND }, egui::Key::I);
    h.run();
    enter_path(&mut h, &png);
    h.run();
    let r = h.state().studio.editor.scene.references.first().cloned().expect("loaded");
    assert_eq!(r.plane(), Some(ReferencePlane::Side), "square to the right view");
    assert_eq!(r.name, "side.png");
    assert_eq!(h.state().studio.selected_reference, Some(0));
    assert!(h.state().studio.message.contains("side.png"), "{}", h.state().studio.message);
    assert!(h.state().studio.is_modified(), "a reference is unsaved work");
    // The panel opened on it: the opacity slider takes the arrow keys.
    h.get_by_role_and_label(egui::accesskit::Role::Slider, "opacity").focus();
    h.run();
    for _ in 0..3 {
        h.key_press(egui::Key::ArrowRight);
        h.run();
    }
    let faded = h.state().studio.editor.scene.references[0].opacity;
    assert!(faded > r.opacity, "opacity {} -> {faded}", r.opacity);
    // The gizmo sits on the selected, unlocked picture: an upward drag moves it up, one step.
    h.key_press(egui::Key::Escape);
    h.run();
    let steps = h.state().studio.editor.history().undo_len();
    let (c, handles) = h.state().gizmo_on_screen().expect("the gizmo is on the picture");
    let tip = handles.iter().find(|(k, _)| *k == GizmoHandle::Move(1)).unwrap().1;
    drag_handle(&mut h, GizmoHandle::Move(1), (tip - c).normalized() * 30.0);
    let moved = h.state().studio.editor.scene.references[0].clone();
    assert!(moved.center.y > r.center.y + 0.1, "{:?} -> {:?}", r.center, moved.center);
    assert_eq!(h.state().studio.editor.history().undo_len(), steps + 1, "a drag is one step");
    // Locked: no gizmo, and Delete does nothing.
    h.get_by_label("locked in place").click();
    h.run();
    assert!(h.state().studio.editor.scene.references[0].locked);
    assert!(h.state().gizmo_on_screen().is_none(), "a locked picture has no gizmo");
    h.get_by_label("Delete image").click();
    h.run();
    assert_eq!(h.state().studio.editor.scene.references.len(), 1, "a locked picture stays");
    // Saved with the scene and reopened equal.
    let scene_path = dir.join("with-reference.strata");
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.run();
    enter_path(&mut h, &scene_path);
    let saved = h.state().studio.editor.scene.references.clone();
    let loaded = strata_editor::file::load(&scene_path).unwrap();
    assert!(loaded.report.is_clean(), "{}", loaded.report);
    assert_eq!(loaded.scene.references, saved);
    h.state_mut().studio.act(strata_studio::Action::Open(scene_path.clone())).unwrap();
    assert_eq!(h.state().studio.editor.scene.references, saved);
    // Alt+R hides them all (a view setting: the scene is unchanged).
    h.key_press_modifiers(egui::Modifiers::ALT, egui::Key::R);
    h.run();
    assert!(!h.state().studio.show_references);
    assert!(!h.state().studio.is_modified());
    // A dropped JPEG becomes a reference; a file that is not a picture is said.
    let jpeg = dir.join("top.jpg");
    red_blue_picture(&jpeg);
    h.key_press(egui::Key::Num7);
    h.run();
    h.input_mut().dropped_files.push(std::sync::Arc::new(Dropped(jpeg)));
    h.run();
    let refs = &h.state().studio.editor.scene.references;
    assert_eq!(refs.len(), 2, "{}", h.state().studio.message);
    assert_eq!(refs[1].plane(), Some(ReferencePlane::Top));
    assert!(h.state().studio.show_references, "loading one shows them again");
    // In the back view (Ctrl+1) a picture faces the back, behind the model from there.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Num1);
    h.run();
    h.state_mut().studio.act(strata_studio::Action::LoadReference(png.clone())).unwrap();
    let back = h.state().studio.editor.scene.references[2].clone();
    assert_eq!(back.view(), Some((ReferencePlane::Front, true)));
    assert!(back.center.z > 20.0, "behind the ball (z about 18) seen from the back: {:?}", back.center);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert_eq!(h.state().studio.selected_reference, None, "an undone picture is not selected");
    let bad = dir.join("notes.png");
    std::fs::write(&bad, b"not a picture").unwrap();
    h.key_press_modifiers(egui::Modifiers { shift: true, ..egui::Modifiers::COMMAND }, egui::Key::I);
    h.run();
    enter_path(&mut h, &bad);
    assert!(
        h.state().studio.notice.as_deref().is_some_and(|n| n.contains("notes.png")),
        "{:?}",
        h.state().studio.notice
    );
    assert_eq!(h.state().studio.editor.scene.references.len(), 2);
    // Undo takes the dropped one back.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert_eq!(h.state().studio.editor.scene.references.len(), 1);
}

/// Every interactive control now on screen: (role, label, description).
fn controls_on_screen(h: &Harness<'static, StudioApp>) -> Vec<(egui::accesskit::Role, String, Option<String>)> {
    use egui::accesskit::Role;
    let interactive = [
        Role::Button,
        Role::CheckBox,
        Role::RadioButton,
        Role::Slider,
        Role::SpinButton,
        Role::ComboBox,
        Role::TextInput,
        Role::MultilineTextInput,
        Role::Switch,
        Role::Link,
    ];
    let mut out = Vec::new();
    for role in interactive {
        for n in h.query_all_by_role(role) {
            let a = n.accesskit_node();
            out.push((role, a.label().unwrap_or_default(), a.description()));
        }
    }
    out
}

/// The menu bar's menus.
const MENUS: [&str; 7] = ["File", "Edit", "Brush", "Layer", "View", "Terrain", "Help"];

/// The submenus (by the start of their titles).
const SUBMENUS: [&str; 11] = [
    "Open recent",
    "Insert mesh",
    "Brush presets",
    "Shape",
    "Stabiliser",
    "Mirror",
    "Lock stroke",
    "Falloff",
    "Detail raises to",
    "New layers' resolution",
    "Reference image ",
];

/// Opens the menu entry `path` (`Brush > Mirror > Y`; a segment ending in `*` by its start)
/// and says whether its last entry shows; the menus are closed again.
fn menu_entry_shows(h: &mut Harness<'static, StudioApp>, path: &str) -> bool {
    let segments: Vec<&str> = path.split(" > ").collect();
    let labels = |h: &Harness<'static, StudioApp>| -> Vec<String> {
        controls_on_screen(h).into_iter().map(|(_, label, _)| label).collect()
    };
    // (Only what the menus add counts: the panels show controls of the same names.)
    let before = labels(h);
    let find = |h: &Harness<'static, StudioApp>, segment: &str| {
        let now = labels(h);
        let count = |list: &[String], l: &str| list.iter().filter(|x| *x == l).count();
        now.iter()
            .find(|label| {
                (strata_studio::keymap::label_matches(segment, label) || label.starts_with(&format!("{segment} (")))
                    && count(&now, label) > count(&before, label)
            })
            .cloned()
    };
    h.get_by_role_and_label(egui::accesskit::Role::Button, segments[0]).click();
    h.run();
    let mut shown = true;
    for (k, segment) in segments.iter().enumerate().skip(1) {
        let Some(label) = find(h, segment) else {
            shown = false;
            break;
        };
        if k + 1 < segments.len() {
            h.get_by_role_and_label(egui::accesskit::Role::Button, &label).hover();
            h.run();
        }
    }
    h.key_press(egui::Key::Escape);
    h.run();
    h.key_press(egui::Key::Escape);
    h.run();
    shown
}

/// Issue 32: every control of the panels, menus and dialogs has a tooltip, and every panel
/// and dialog control is reached by a key or a menu entry recorded in the binding table
/// (`keymap::CONTROLS`; items of the scene's lists by Tab, values by Tab and the arrow keys),
/// whose keys are bound and whose menu entries exist. Walked with every tool, the collapsible
/// sections open, a reference image selected, an insert waiting, and each dialog up.
#[test]
fn every_control_has_a_tooltip_and_a_key_or_menu_entry_in_the_binding_table() {
    use egui::accesskit::Role;
    use strata_studio::keymap::{Reach, controls_for, keys_in_label};
    let dir = temp("audit");
    let mut h = harness(&dir);
    h.run();
    // (state, role, label, description), each control once per state.
    let mut seen: Vec<(String, Role, String, Option<String>)> = Vec::new();
    let look =
        |h: &Harness<'static, StudioApp>, state: &str, seen: &mut Vec<(String, Role, String, Option<String>)>| {
            for (role, label, d) in controls_on_screen(h) {
                if !seen.iter().any(|(s, r, l, _)| s == state && *r == role && *l == label) {
                    seen.push((state.to_string(), role, label, d));
                }
            }
        };
    let png = dir.join("r.png");
    red_blue_picture(&png);
    h.state_mut().studio.act(strata_studio::Action::LoadReference(png)).unwrap();
    h.run();
    h.run();
    look(&h, "panel", &mut seen);
    for key in [
        egui::Key::A,
        egui::Key::E,
        egui::Key::S,
        egui::Key::I,
        egui::Key::T,
        egui::Key::P,
        egui::Key::G,
        egui::Key::D,
        egui::Key::V,
        egui::Key::H,
        egui::Key::M,
        egui::Key::C,
    ] {
        h.key_press(key);
        h.run();
        look(&h, "panel", &mut seen);
    }
    for header in ["Presets", "Pressure (Alt+P)"] {
        h.get_by_label(header).click();
        h.run();
    }
    look(&h, "panel", &mut seen);
    h.state_mut().studio.begin_insert(strata_editor::InsertMesh::bunny());
    h.run();
    look(&h, "panel", &mut seen);
    for menu in MENUS {
        h.get_by_role_and_label(Role::Button, menu).click();
        h.run();
        look(&h, "menu", &mut seen);
        let submenus: Vec<String> = controls_on_screen(&h)
            .into_iter()
            .filter(|(_, l, _)| SUBMENUS.iter().any(|s| l.starts_with(s)))
            .map(|(_, l, _)| l)
            .collect();
        for sub in submenus {
            h.get_by_role_and_label(Role::Button, &sub).hover();
            h.run();
            look(&h, "menu", &mut seen);
        }
        h.key_press(egui::Key::Escape);
        h.run();
        h.key_press(egui::Key::Escape);
        h.run();
    }
    h.key_press(egui::Key::Escape);
    h.run();
    // Dialogs: the help, the path prompt, the unsaved-changes question, the session dialog and
    // the import dialog.
    h.key_press(egui::Key::F1);
    h.run();
    look(&h, "dialog", &mut seen);
    h.key_press(egui::Key::Escape);
    h.run();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.run();
    look(&h, "dialog", &mut seen);
    h.key_press(egui::Key::Escape);
    h.run();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::N);
    h.run();
    look(&h, "dialog", &mut seen);
    h.query_all_by_label("Cancel").last().unwrap().click();
    h.run();
    for entry in ["Host session…", "Join session…"] {
        h.get_by_label("File").click();
        h.run();
        h.get_by_label(entry).click();
        h.run();
        look(&h, "dialog", &mut seen);
        h.query_all_by_label("Cancel").last().unwrap().click();
        h.run();
    }
    h.input_mut().dropped_files.push(std::sync::Arc::new(Dropped(bunny_path())));
    h.run();
    look(&h, "dialog", &mut seen);
    h.get_by_label("Cancel").click();
    h.run();
    // The data the lists show: layers, materials, presets, stamp pictures, reference images.
    let studio = &h.state().studio;
    let mut items: Vec<String> = studio.editor.scene.layers.iter().map(|l| l.name.clone()).collect();
    items.extend(studio.editor.scene.materials.iter().map(|m| m.name.clone()));
    items.extend(studio.editor.scene.references.iter().map(|r| r.name.clone()));
    items.extend(strata_editor::Preset::builtin().into_iter().map(|p| p.name));
    items.extend(studio.stamp_choices().into_iter().map(|(_, n)| n));
    let mut failures = Vec::new();
    let sliders: Vec<String> =
        seen.iter().filter(|(_, r, _, d)| *r == Role::Slider && d.is_some()).map(|(_, _, l, _)| l.clone()).collect();
    for (state, role, label, description) in &seen {
        // (A menu's title opens it: it is not a control of its own.)
        let menu_title = *role == Role::Button
            && (MENUS.contains(&label.as_str()) || state == "menu" && SUBMENUS.iter().any(|s| label.starts_with(s)));
        // (A slider's number box is part of the slider, whose tooltip it shares.)
        let slider_box = *role == Role::SpinButton && sliders.contains(label);
        if description.is_none() && !menu_title && !slider_box && label != "Close window" {
            failures.push(format!("[{state}] {role:?} {label:?} has no tooltip"));
        }
        if state == "menu" || menu_title {
            continue; // (a menu entry is one)
        }
        let value_role = matches!(
            role,
            Role::Slider | Role::SpinButton | Role::TextInput | Role::MultilineTextInput | Role::ComboBox
        );
        let reached = keys_in_label(label).is_some()
            || items.contains(label)
            || controls_for(label).any(|c| match c.reach {
                Reach::Value => value_role,
                Reach::Answer => state == "dialog",
                Reach::Key(_) | Reach::Menu(_) => true,
            });
        if !reached {
            failures.push(format!("[{state}] {role:?} {label:?} has no key or menu entry in the binding table"));
        }
    }
    assert!(failures.is_empty(), "{} controls:\n{}", failures.len(), failures.join("\n"));
    // Each row's menu entry exists (with the insert waiting and the reference selected).
    h.state_mut().studio.begin_insert(strata_editor::InsertMesh::bunny());
    h.run();
    let mut missing = Vec::new();
    for c in strata_studio::keymap::CONTROLS {
        if h.state().studio.insert.is_none() {
            // (The Escape that closes a menu also drops the waiting insert.)
            h.state_mut().studio.begin_insert(strata_editor::InsertMesh::bunny());
            h.run();
        }
        if let Reach::Menu(path) = c.reach
            && !menu_entry_shows(&mut h, path)
        {
            missing.push(path);
        }
    }
    assert!(missing.is_empty(), "menu entries of the binding table that do not show: {missing:?}");
}

/// View > GPU meshing where the studio has no GPU viewport: refused in words, left off.
#[test]
fn gpu_meshing_without_a_gpu_viewport_says_it_cannot() {
    let dir = temp("gpu-meshing-headless");
    let mut h = harness(&dir);
    h.run();
    assert!(!h.state().studio.gpu_meshing, "off without a GPU viewport");
    h.get_by_label("View").click();
    h.run();
    h.get_by_label("GPU meshing").click();
    h.run();
    let s = &h.state().studio;
    assert!(!s.gpu_meshing && !s.editor.gpu_meshing(), "{}", s.message);
    assert!(s.message.contains("GPU meshing is not available (there is no GPU viewport)"), "{}", s.message);
    let _ = std::fs::remove_dir_all(dir);
}

/// View > GPU meshing on the GPU viewport (lavapipe in CI): off by default on a software
/// adapter, on when asked; the ball is then drawn from chunks meshed on the GPU, a stroke goes
/// through them, and turning it off gives the CPU's meshes back.
#[test]
fn gpu_meshing_from_the_view_menu_draws_the_gpus_chunks_and_gives_them_back() {
    let Some(gpu) = strata_render::Gpu::for_tests("the GPU meshing kittest") else { return };
    let software = gpu.info.device_type == wgpu::DeviceType::Cpu;
    drop(gpu);
    let dir = temp("gpu-meshing");
    let mut h = Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .wgpu()
        .build_eframe(|cc| StudioApp::with_gpu(cc, Studio::new(default_scene()), Dialogs::Typed, dir.join("recovery")));
    h.run_steps(2);
    if software {
        assert!(!h.state().studio.gpu_meshing, "off by default on a software adapter");
    }
    if !h.state().studio.gpu_meshing {
        h.get_by_label("View").click();
        h.run_steps(2);
        h.get_by_label("GPU meshing").click();
        h.run_steps(2);
    }
    let settle = |h: &mut Harness<'static, StudioApp>| {
        for _ in 0..200 {
            h.step();
            if h.state().studio.editor.pending() == 0 {
                break;
            }
        }
        h.run_steps(2);
    };
    settle(&mut h);
    let s = &h.state().studio;
    assert!(s.gpu_meshing && s.editor.gpu_meshing(), "{}", s.message);
    assert!(s.gpu_chunks > 0 && s.editor.triangle_count() == 0, "{} GPU chunks", s.gpu_chunks);
    assert!(s.status().contains("chunks meshed on the GPU"), "{}", s.status());
    let before = s.gpu_chunks;
    drag_over_the_ball(&mut h, 6);
    settle(&mut h);
    let s = &h.state().studio;
    assert_eq!(s.editor.history().undo_len(), 1, "the stroke went through: {}", s.message);
    assert!(s.gpu_chunks >= before, "{} GPU chunks after the stroke, {before} before", s.gpu_chunks);
    // Dual contouring in the viewport: the default ball has one level, so it is made and drawn
    // on the GPU, vertices and quads.
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("dual contouring").click();
    settle(&mut h);
    h.key_press(egui::Key::Escape);
    settle(&mut h);
    let s = &h.state().studio;
    assert_eq!(s.editor.view_mesher().mesher, strata_mesh::Mesher::DualContouring, "{}", s.message);
    assert!(s.editor.has_vertex_solver() && s.editor.caller_dual(0), "{}", s.message);
    assert!(s.gpu_chunks > 0 && s.editor.triangle_count() == 0, "{} chunks on the GPU", s.gpu_chunks);
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("GPU meshing").click();
    settle(&mut h);
    let s = &h.state().studio;
    assert!(!s.gpu_meshing && s.gpu_chunks == 0 && s.editor.triangle_count() > 0, "{}", s.message);
    assert!(s.message.contains("GPU meshing off"), "{}", s.message);
    let _ = std::fs::remove_dir_all(dir);
}
