//! Dialogs: the typed-path prompt and the native file dialog (timed on its thread, so a missing
//! portal falls back to the prompt), the unsaved-changes question, the recovery offer, notices
//! and the F1 help, and what a chosen path leads to (open, import, save, export, worlds).

use super::*;

/// What a path is asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Prompt {
    Open,
    SaveAs,
    Export,
    Import,
    NewWorld,
    OpenWorld,
    LoadStamp,
    InsertMesh,
    LoadReference,
}

impl Prompt {
    fn title(self) -> &'static str {
        match self {
            Prompt::Open => "Open scene",
            Prompt::SaveAs => "Save scene as",
            Prompt::Export => "Export mesh",
            Prompt::Import => "Import mesh as a new layer",
            Prompt::NewWorld => "New world",
            Prompt::OpenWorld => "Open world",
            Prompt::LoadStamp => "Load a stamp picture (PNG)",
            Prompt::InsertMesh => "Insert a mesh (a closed one)",
            Prompt::LoadReference => "Load a reference image (PNG or JPEG)",
        }
    }

    fn suggestion(self) -> &'static str {
        match self {
            Prompt::Open | Prompt::SaveAs => "scene.strata",
            Prompt::Export => "sculpt.glb",
            Prompt::Import => "mesh.ply",
            Prompt::NewWorld | Prompt::OpenWorld => "terrain.world",
            Prompt::LoadStamp => "stamp.png",
            Prompt::InsertMesh => "mesh.ply",
            Prompt::LoadReference => "front.png",
        }
    }
}

/// What waits for the user's answer to "save the changes first?".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Then {
    New,
    Open,
    /// Open the file in `StudioApp::open_next` (dropped on the window, or a recent file).
    OpenFile,
    /// Join the room in `StudioApp::join_next`.
    Join,
    Quit,
}

/// The typed-path prompt: a modal text field.
#[derive(Debug)]
pub(super) struct PathPrompt {
    pub(super) kind: Prompt,
    pub(super) text: String,
    /// Whether the field has been given keyboard focus (done once, when it first shows).
    pub(super) focused: bool,
    /// What to do after a successful save (a save asked for by the unsaved-changes question).
    pub(super) then: Option<Then>,
}

/// One path asked of a dialog service: what for, and where to start.
#[derive(Clone, Debug)]
pub struct DialogRequest {
    /// The dialog's title.
    pub title: &'static str,
    /// Whether an existing file is picked (open, import) rather than a file to write named.
    pub pick_existing: bool,
    /// The filter's name and its extensions.
    pub filter: (&'static str, Vec<&'static str>),
    /// The folder to start in.
    pub directory: Option<PathBuf>,
    /// The file name suggested for a file to write.
    pub file_name: &'static str,
}

/// How paths are asked for.
#[derive(Clone)]
pub enum Dialogs {
    /// The system's file dialogs (through the desktop portal), falling back to the typed prompt
    /// where none answers.
    Native,
    /// A typed path in a modal prompt (tests, and systems without a dialog service).
    Typed,
    /// Dialogs from this service, with the native dialogs' fallback to the typed prompt (tests
    /// that play a missing or a slow portal).
    Service(DialogService),
}

impl std::fmt::Debug for Dialogs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Dialogs::Native => "Native",
            Dialogs::Typed => "Typed",
            Dialogs::Service(_) => "Service",
        })
    }
}

/// The system's file dialog (rfd over the XDG desktop portal).
pub(super) fn system_dialog(r: &DialogRequest) -> Option<PathBuf> {
    let mut d = rfd::FileDialog::new().set_title(r.title).add_filter(r.filter.0, &r.filter.1);
    if let Some(dir) = &r.directory {
        d = d.set_directory(dir);
    }
    if r.pick_existing { d.pick_file() } else { d.set_file_name(r.file_name).save_file() }
}

/// A dialog's answer, timed on the dialog's own thread (never by when a frame polls it).
pub(super) struct DialogAnswer {
    pub(super) path: Option<PathBuf>,
    pub(super) took: Duration,
}

/// A native dialog running on its own thread.
pub(super) struct NativeDialog {
    pub(super) kind: Prompt,
    pub(super) then: Option<Then>,
    pub(super) answer: mpsc::Receiver<DialogAnswer>,
}

/// A dialog that comes back empty sooner than this never showed (no portal answered: rfd
/// returns in about 10 ms then, measured on this project's machines): the typed prompt is used
/// instead from then on. A person needs longer to cancel. The time is measured around the
/// dialog call on its thread, so a slow frame cannot turn "no service" into "cancelled".
pub(super) const NO_DIALOG_SERVICE: Duration = Duration::from_millis(250);

impl StudioApp {
    /// Reads a mesh for import and opens the resolution dialog; says why in the status bar if
    /// it cannot be read.
    pub(super) fn import_path(&mut self, path: PathBuf) -> bool {
        match self.studio.choose_import(path) {
            Ok(()) => true,
            Err(e) => {
                self.studio.message = e;
                false
            }
        }
    }

    /// Opens a scene file (dropped or recent), asking first about unsaved changes.
    pub(super) fn open_file(&mut self, ctx: &egui::Context, path: PathBuf) {
        // (Refused before the unsaved-changes question, which would be asked for nothing.)
        if let Err(e) = self.studio.refuse_in_session("open a scene") {
            self.studio.fail(e);
            return;
        }
        self.open_next = Some(path);
        self.guard(ctx, Then::OpenFile);
    }

    /// Files dropped on the window: a scene opens, a mesh is imported as a new layer, a PNG
    /// becomes the stamp's picture, a JPEG a reference image.
    pub(super) fn dropped(&mut self, ctx: &egui::Context) {
        let files = ctx.input(|i| i.raw.dropped_files.clone());
        for f in files {
            let path = f.path().to_path_buf();
            if path.as_os_str().is_empty() {
                continue;
            }
            let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
            match ext.as_deref() {
                Some("strata") => self.open_file(ctx, path),
                Some(e) if strata_mesh::import::MESH_EXTENSIONS.contains(&e) => {
                    self.import_path(path);
                }
                Some("png") => {
                    let _ = self.studio.act(Action::LoadStamp(path));
                }
                Some("jpg" | "jpeg") => {
                    let _ = self.studio.act(Action::LoadReference(path));
                }
                _ => {
                    self.studio.message = format!(
                        "Cannot open {}: not a scene, a mesh, a PNG stamp or a JPEG reference image",
                        path.display()
                    )
                }
            }
        }
    }

    /// Asks for a path: a native dialog where one answers, else the typed prompt.
    pub(super) fn ask_path(&mut self, ctx: &egui::Context, kind: Prompt, then: Option<Then>) {
        let service: DialogService = match &self.dialogs {
            Dialogs::Typed => return self.open_prompt(ctx, kind, then),
            Dialogs::Native => std::sync::Arc::new(system_dialog),
            Dialogs::Service(s) => s.clone(),
        };
        let request = DialogRequest {
            title: kind.title(),
            pick_existing: matches!(
                kind,
                Prompt::Open
                    | Prompt::Import
                    | Prompt::OpenWorld
                    | Prompt::LoadStamp
                    | Prompt::InsertMesh
                    | Prompt::LoadReference
            ),
            filter: match kind {
                Prompt::Open | Prompt::SaveAs => ("Strata scene", vec!["strata"]),
                Prompt::Export => ("Mesh", vec!["glb", "obj", "stl", "ply"]),
                Prompt::Import | Prompt::InsertMesh => ("Mesh", strata_mesh::import::MESH_EXTENSIONS.to_vec()),
                Prompt::NewWorld | Prompt::OpenWorld => ("Strata world", vec!["world"]),
                Prompt::LoadStamp => ("PNG image", vec!["png"]),
                Prompt::LoadReference => ("Picture", vec!["png", "jpg", "jpeg"]),
            },
            directory: self.studio.path.as_ref().and_then(|p| p.parent()).map(|p| p.to_path_buf()),
            file_name: kind.suggestion(),
        };
        let (tx, rx) = mpsc::channel();
        let repaint = ctx.clone();
        std::thread::spawn(move || {
            let started = Instant::now();
            let path = service(&request);
            let _ = tx.send(DialogAnswer { path, took: started.elapsed() });
            repaint.request_repaint();
        });
        self.native = Some(NativeDialog { kind, then, answer: rx });
        ctx.request_repaint_after(Duration::from_millis(20));
    }

    pub(super) fn open_prompt(&mut self, ctx: &egui::Context, kind: Prompt, then: Option<Then>) {
        let text = match (kind, &self.studio.path) {
            (Prompt::SaveAs, Some(p)) => p.display().to_string(),
            _ => kind.suggestion().to_string(),
        };
        self.prompt = Some(PathPrompt { kind, text, focused: false, then });
        // The prompt must show at once, not on the next input event.
        ctx.request_repaint();
    }

    /// Carries out what a path was asked for.
    pub(super) fn path_chosen(&mut self, ctx: &egui::Context, kind: Prompt, path: PathBuf, then: Option<Then>) {
        let done = match kind {
            Prompt::Open => {
                let ok = self.studio.act(Action::Open(path.clone())).is_ok();
                if ok {
                    self.autosave.forget();
                    self.recent.add(&path);
                }
                ok
            }
            Prompt::SaveAs => {
                let ok = self.studio.act(Action::SaveAs(path.clone())).is_ok();
                if ok {
                    self.autosave.forget();
                    self.recent.add(&path);
                }
                ok
            }
            Prompt::Export => self.studio.act(Action::Export(path)).is_ok(),
            Prompt::Import => self.import_path(path),
            Prompt::NewWorld => self.studio.act(Action::NewWorld(path, self.world_seed)).is_ok(),
            Prompt::OpenWorld => self.studio.act(Action::OpenWorld(path)).is_ok(),
            Prompt::LoadStamp => self.studio.act(Action::LoadStamp(path)).is_ok(),
            Prompt::InsertMesh => self.studio.act(Action::InsertFile(path)).is_ok(),
            Prompt::LoadReference => self.studio.act(Action::LoadReference(path)).is_ok(),
        };
        if done && let Some(then) = then {
            self.proceed(ctx, then);
        }
    }

    /// Asks before `then` if it would discard unsaved work, else does it.
    pub(super) fn guard(&mut self, ctx: &egui::Context, then: Then) {
        if self.studio.is_modified() {
            self.confirm = Some(then);
            ctx.request_repaint();
        } else {
            self.proceed(ctx, then);
        }
    }

    /// Does `then`, the changes having been saved or given up.
    pub(super) fn proceed(&mut self, ctx: &egui::Context, then: Then) {
        match then {
            Then::New => {
                // (Only a new scene makes the recovery file moot; a refused New keeps it.)
                if self.studio.act(Action::New).is_ok() {
                    self.autosave.forget();
                }
            }
            Then::Open => self.ask_path(ctx, Prompt::Open, None),
            Then::OpenFile => {
                if let Some(path) = self.open_next.take() {
                    self.path_chosen(ctx, Prompt::Open, path, None);
                }
            }
            Then::Join => {
                if let Some(params) = self.join_next.take()
                    && self.studio.act(Action::JoinSession(params)).is_ok()
                {
                    self.autosave.forget();
                }
            }
            Then::Quit => {
                self.autosave.forget();
                self.allow_close = true;
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
    }

    /// Save: to the scene's file, or asking for one the first time.
    pub(super) fn save(&mut self, ctx: &egui::Context, then: Option<Then>) {
        if self.studio.path.is_some() {
            if self.studio.act(Action::Save).is_ok() {
                self.autosave.forget();
                if let Some(then) = then {
                    self.proceed(ctx, then);
                }
            }
        } else {
            self.ask_path(ctx, Prompt::SaveAs, then);
        }
    }

    /// The typed-path prompt: modal, focused when it opens, its text selected so typing
    /// replaces the suggestion; Enter or OK goes, Escape or Cancel closes it.
    pub(super) fn prompt(&mut self, ctx: &egui::Context) {
        let Some(mut p) = self.prompt.take() else { return };
        let (mut go, mut cancel) = (false, false);
        let modal = egui::Modal::new(egui::Id::unique("path prompt")).show(ctx, |ui| {
            ui.heading(p.kind.title());
            let label = ui.label("Path:");
            let id = egui::Id::unique("path prompt field");
            let r = ui
                .add(egui::TextEdit::singleline(&mut p.text).id(id).desired_width(420.0))
                .labelled_by(label.id)
                .on_hover_text("Type the file's path; Enter answers, Escape cancels");
            if !p.focused {
                r.request_focus();
                if let Some(mut state) = egui::text_edit::TextEditState::load(ui.ctx(), id) {
                    state.cursor.set_char_range(Some(egui::text::CCursorRange::two(
                        egui::text::CCursor::new(0),
                        egui::text::CCursor::new(p.text.chars().count()),
                    )));
                    state.store(ui.ctx(), id);
                }
                p.focused = true;
            }
            go = r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            ui.horizontal(|ui| {
                go |= ui.button("OK").on_hover_text("Use this path (Enter)").clicked();
                cancel |= ui.button("Cancel").on_hover_text("Do nothing (Escape)").clicked();
            });
        });
        cancel |= modal.should_close();
        if go && !p.text.trim().is_empty() {
            let path = PathBuf::from(p.text.trim());
            self.path_chosen(ctx, p.kind, path, p.then);
        } else if cancel {
            // Closing the prompt is an answer too: say what did not happen.
            self.studio.message = match (p.kind, p.then) {
                (Prompt::SaveAs, Some(Then::Quit)) => "Save cancelled: nothing saved, Strata stays open".into(),
                (Prompt::SaveAs, Some(_)) => "Save cancelled: nothing saved, nothing else done".into(),
                (kind, _) => format!("{} cancelled", kind.title()),
            };
        } else {
            self.prompt = Some(p);
        }
    }

    /// Polls a native dialog. Every answer ends in something the user sees: a chosen path is
    /// carried out; an empty answer that came at once (timed on the dialog's thread) means no
    /// dialog service, and the typed prompt takes over, now and from then on; a dialog that
    /// failed does the same; a cancelled one says so in the status bar.
    pub(super) fn native_dialog(&mut self, ctx: &egui::Context) {
        let Some(d) = self.native.take() else { return };
        match d.answer.try_recv() {
            Ok(DialogAnswer { path: Some(path), .. }) => self.path_chosen(ctx, d.kind, path, d.then),
            Ok(DialogAnswer { path: None, took }) if took < NO_DIALOG_SERVICE => {
                self.dialogs = Dialogs::Typed;
                self.studio.message = "No file dialog service answered: type the path".into();
                self.open_prompt(ctx, d.kind, d.then);
            }
            Ok(DialogAnswer { path: None, .. }) => {
                self.studio.message = match (d.kind, d.then) {
                    (Prompt::SaveAs, Some(Then::Quit)) => "Save cancelled: nothing saved, Strata stays open".into(),
                    (Prompt::SaveAs, Some(_)) => "Save cancelled: nothing saved, nothing else done".into(),
                    (kind, _) => format!("{} cancelled", kind.title()),
                };
            }
            Err(mpsc::TryRecvError::Disconnected) => {
                self.dialogs = Dialogs::Typed;
                self.studio.message = "The file dialog failed: type the path".into();
                self.open_prompt(ctx, d.kind, d.then);
            }
            Err(mpsc::TryRecvError::Empty) => {
                self.native = Some(d);
                ctx.request_repaint_after(Duration::from_millis(50));
            }
        }
    }

    /// The keyboard help overlay (F1).
    pub(super) fn help(&mut self, ctx: &egui::Context) {
        if !self.help_open {
            return;
        }
        let mut open = true;
        egui::Window::new("Keyboard and mouse").open(&mut open).collapsible(false).show(ctx, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                egui::Grid::new("shortcuts").striped(true).show(ui, |ui| {
                    for (keys, what) in crate::keymap::help_rows() {
                        ui.label(keys);
                        ui.label(what);
                        ui.end_row();
                    }
                });
            });
        });
        self.help_open = open;
    }

    /// The unsaved-changes question.
    pub(super) fn confirm(&mut self, ctx: &egui::Context) {
        let Some(then) = self.confirm else { return };
        let what = match then {
            Then::New => "starting a new scene",
            Then::Open | Then::OpenFile => "opening another scene",
            Then::Join => "joining a shared room (its scene replaces this one)",
            Then::Quit => "quitting",
        };
        let name = self.studio.path.as_ref().map_or("the new scene".to_string(), |p| p.display().to_string());
        let mut choice = None;
        let modal = egui::Modal::new(egui::Id::unique("unsaved changes")).show(ctx, |ui| {
            ui.heading("Unsaved changes");
            ui.label(format!("Save the changes to {name} before {what}?"));
            ui.horizontal(|ui| {
                if ui.button("Save").on_hover_text("Save first, then go on").clicked() {
                    choice = Some(0);
                }
                if ui.button("Don't save").on_hover_text("Go on and lose the unsaved changes").clicked() {
                    choice = Some(1);
                }
                if ui.button("Cancel").on_hover_text("Stay with the scene as it is (Escape)").clicked() {
                    choice = Some(2);
                }
            });
        });
        if modal.should_close() {
            choice = Some(2);
        }
        match choice {
            Some(0) => {
                self.confirm = None;
                self.save(ctx, Some(then));
            }
            Some(1) => {
                self.confirm = None;
                self.proceed(ctx, then);
            }
            Some(_) => self.confirm = None,
            None => {}
        }
    }

    /// The offer to recover work autosaved by a session that did not end cleanly.
    pub(super) fn recovery(&mut self, ctx: &egui::Context) {
        let Some(found) = self.recovery.as_ref() else { return };
        let mut choice = None;
        egui::Modal::new(egui::Id::unique("recover")).show(ctx, |ui| {
            ui.heading("Recover unsaved work?");
            ui.label(format!(
                "Strata did not close cleanly. Work autosaved {} is available{}.",
                found.age_text(),
                found.origin.as_ref().map_or(String::new(), |p| format!(" (from {})", p.display()))
            ));
            ui.horizontal(|ui| {
                if ui.button("Recover").on_hover_text("Open the autosaved work").clicked() {
                    choice = Some(true);
                }
                if ui.button("Discard").on_hover_text("Delete the autosaved work and start afresh").clicked() {
                    choice = Some(false);
                }
            });
        });
        let Some(recover) = choice else { return };
        let found = self.recovery.take().expect("checked above");
        if recover {
            match found.load() {
                Ok(scene) => {
                    let _ = self.studio.act(Action::New);
                    self.studio.editor.set_scene(scene);
                    self.studio.camera = strata_viewport::camera_of(&self.studio.editor.scene.view);
                    self.studio.path = found.origin.clone();
                    // Recovered work is not in any file yet.
                    self.studio.editor.touch();
                    self.studio.message = "Recovered the autosaved work: save it to keep it".into();
                }
                Err(e) => self.studio.message = format!("Could not recover the autosaved work: {e}"),
            }
        }
        found.discard();
    }

    /// The error notice: stays, over the viewport, until the user closes it.
    pub(super) fn notice(&mut self, ctx: &egui::Context) {
        let Some(text) = self.studio.notice.clone() else { return };
        let mut close = false;
        egui::Window::new("Something went wrong")
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_TOP, egui::vec2(0.0, 36.0))
            .default_width(460.0)
            .show(ctx, |ui| {
                ui.add(egui::Label::new(text.as_str()).wrap());
                close = ui.button("Dismiss").on_hover_text("Close this notice (Escape)").clicked();
            });
        if close {
            self.studio.notice = None;
        }
    }
}
