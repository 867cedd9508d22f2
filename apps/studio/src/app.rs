//! The eframe window: menus, tool palette, layers panel, status bar and the 3D viewport (the
//! renderer draws into a texture that egui shows).

use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use eframe::egui;
use glam::Mat4;
use strata_editor::{BrushShape, Buttons, ToolKind};
use strata_render::{DEPTH_FORMAT, FrameSettings, MeshId, Placement, Preview, Renderer};

/// Where the falloff `3t⁴ − 4t³ + 1` is one half, as a fraction of the radius: the preview's
/// core, inside which a field tool acts at half its strength or more.
pub const FALLOFF_HALF: f64 = 0.6135;

use crate::keymap::{Command, command_for, keys_of, labelled};
use crate::recovery::Autosave;
use crate::studio::{Action, Studio};

/// The GPU side of the viewport.
struct Viewport {
    renderer: Renderer,
    size: (u32, u32),
    color: Option<(wgpu::Texture, wgpu::TextureView, wgpu::TextureView)>,
    texture_id: Option<egui::TextureId>,
    /// The renderer holds terrain mode's meshes (not the scene's).
    terrain_shown: bool,
}

impl Viewport {
    /// Renders a frame into the viewport's texture and shows it in `rect`.
    fn present(
        &mut self,
        ui: &egui::Ui,
        rs: &egui_wgpu::RenderState,
        rect: egui::Rect,
        size: (u32, u32),
        settings: &FrameSettings<'_>,
    ) {
        let (_, cv, dv) = self.color.as_ref().expect("created before the first frame");
        self.renderer.render(&rs.device, &rs.queue, cv, dv, size, settings);
        if let Some(id) = self.texture_id {
            ui.painter().image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
        }
    }
}

/// Renderer layer ids of terrain mode's chunk meshes and its debris (scene layers count from 0).
const TERRAIN_LAYER: u32 = 1 << 20;
const DEBRIS_LAYER: u32 = (1 << 20) + 1;

/// What a path is asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Prompt {
    Open,
    SaveAs,
    Export,
    Import,
    NewWorld,
    OpenWorld,
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
        }
    }

    fn suggestion(self) -> &'static str {
        match self {
            Prompt::Open | Prompt::SaveAs => "scene.strata",
            Prompt::Export => "sculpt.glb",
            Prompt::Import => "mesh.ply",
            Prompt::NewWorld | Prompt::OpenWorld => "terrain.world",
        }
    }
}

/// What waits for the user's answer to "save the changes first?".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Then {
    New,
    Open,
    /// Open the file in `StudioApp::open_next` (dropped on the window, or a recent file).
    OpenFile,
    Quit,
}

/// The typed-path prompt: a modal text field.
#[derive(Debug)]
struct PathPrompt {
    kind: Prompt,
    text: String,
    /// Whether the field has been given keyboard focus (done once, when it first shows).
    focused: bool,
    /// What to do after a successful save (a save asked for by the unsaved-changes question).
    then: Option<Then>,
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

/// A file-dialog service: shows a dialog for the request and returns the chosen path, or `None`
/// when the user cancelled or no dialog could be shown. It runs on a thread of its own.
pub type DialogService = std::sync::Arc<dyn Fn(&DialogRequest) -> Option<PathBuf> + Send + Sync>;

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
fn system_dialog(r: &DialogRequest) -> Option<PathBuf> {
    let mut d = rfd::FileDialog::new().set_title(r.title).add_filter(r.filter.0, &r.filter.1);
    if let Some(dir) = &r.directory {
        d = d.set_directory(dir);
    }
    if r.pick_existing { d.pick_file() } else { d.set_file_name(r.file_name).save_file() }
}

/// A dialog's answer, timed on the dialog's own thread (never by when a frame polls it).
struct DialogAnswer {
    path: Option<PathBuf>,
    took: Duration,
}

/// A native dialog running on its own thread.
struct NativeDialog {
    kind: Prompt,
    then: Option<Then>,
    answer: mpsc::Receiver<DialogAnswer>,
}

/// A dialog that comes back empty sooner than this never showed (no portal answered: rfd
/// returns in about 10 ms then, measured on this project's machines): the typed prompt is used
/// instead from then on. A person needs longer to cancel. The time is measured around the
/// dialog call on its thread, so a slow frame cannot turn "no service" into "cancelled".
const NO_DIALOG_SERVICE: Duration = Duration::from_millis(250);

/// The desktop app.
pub struct StudioApp {
    /// State and actions.
    pub studio: Studio,
    viewport: Option<Viewport>,
    prompt: Option<PathPrompt>,
    /// The unsaved-changes question, with what waits for it.
    confirm: Option<Then>,
    dialogs: Dialogs,
    native: Option<NativeDialog>,
    /// The window may close (the user answered the unsaved-changes question).
    allow_close: bool,
    autosave: Autosave,
    /// A recovery file from a session that did not end cleanly, offered at start.
    recovery: Option<crate::recovery::Found>,
    /// The scene file to open once the unsaved-changes question is answered.
    open_next: Option<PathBuf>,
    /// Recently opened or saved scenes, newest first.
    pub recent: crate::recent::Recent,
    /// The keyboard help overlay (F1) is showing.
    pub help_open: bool,
    /// The seed of the next new world.
    pub world_seed: u32,
    /// When terrain mode last sculpted (dig and raise repeat at a fixed rate while held).
    last_dig: Option<Instant>,
    /// When the last terrain frame ran.
    last_frame: Option<Instant>,
    /// The brush being sized by dragging (F).
    resize: Option<Resize>,
    /// The window title last sent.
    title: String,
    /// Where the viewport was last laid out (screen points).
    viewport_rect: Option<egui::Rect>,
    /// What the windows, menus and modals showed last frame, and the status message (see
    /// [`StudioApp::repaint_on_change`]).
    shown: (u64, String),
}

/// Sizing the brush by dragging (Blender's F): the radius is the pointer's distance from
/// `centre` (screen points) until a click or Enter keeps it, or Escape or a right click puts the
/// old one back.
#[derive(Clone, Copy, Debug)]
struct Resize {
    centre: egui::Pos2,
    /// The radius before (world units, screen points).
    before: (f64, f32),
    /// World units per point where the brush is (for a world-space radius).
    world_per_point: f64,
}

impl std::fmt::Debug for StudioApp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StudioApp").field("studio", &self.studio).field("prompt", &self.prompt).finish()
    }
}

impl StudioApp {
    /// The app on `studio`, with GPU resources from eframe's wgpu state when there is one,
    /// native file dialogs and autosave to the user's recovery folder.
    pub fn new(cc: &eframe::CreationContext<'_>, studio: Studio) -> Self {
        let dialogs = if std::env::var_os("STRATA_TYPED_PATHS").is_some() { Dialogs::Typed } else { Dialogs::Native };
        StudioApp::with_gpu(cc, studio, dialogs, crate::recovery::default_dir())
    }

    /// [`StudioApp::new`] with the dialogs and the recovery folder chosen (for tests that drive
    /// the whole app, GPU viewport included, through `egui_kittest`'s eframe harness).
    pub fn with_gpu(cc: &eframe::CreationContext<'_>, studio: Studio, dialogs: Dialogs, recovery_dir: PathBuf) -> Self {
        let viewport = cc.wgpu_render_state.as_ref().map(|rs| Viewport {
            renderer: Renderer::new(&rs.device, wgpu::TextureFormat::Rgba8UnormSrgb),
            size: (0, 0),
            color: None,
            texture_id: None,
            terrain_shown: false,
        });
        let mut app = StudioApp::headless(studio, dialogs, recovery_dir);
        app.viewport = viewport;
        app
    }

    /// The app without a GPU viewport (for UI tests): paths asked for as `dialogs` says,
    /// recovery files kept in `recovery_dir` (and one found there offered).
    pub fn headless(studio: Studio, dialogs: Dialogs, recovery_dir: PathBuf) -> Self {
        let recovery = crate::recovery::find(&recovery_dir);
        let recent = crate::recent::Recent::load(recovery_dir.join(crate::recent::FILE_NAME));
        StudioApp {
            world_seed: 1,
            last_dig: None,
            last_frame: None,
            resize: None,
            title: String::new(),
            viewport_rect: None,
            shown: (0, String::new()),
            open_next: None,
            recent,
            help_open: false,
            studio,
            viewport: None,
            prompt: None,
            confirm: None,
            dialogs,
            native: None,
            allow_close: false,
            autosave: Autosave::new(recovery_dir),
            recovery,
        }
    }

    /// Sets how often unsaved work is written to the recovery file.
    pub fn set_autosave_interval(&mut self, every: Duration) {
        self.autosave.interval = every;
    }

    /// Waits for an autosave in progress to finish writing.
    pub fn wait_for_autosave(&mut self) {
        self.autosave.wait();
    }

    /// Whether a modal (a path prompt, a question, a dialog) has the keyboard.
    pub fn modal_open(&self) -> bool {
        self.prompt.is_some()
            || self.confirm.is_some()
            || self.native.is_some()
            || self.recovery.is_some()
            || self.resize.is_some()
            || self.studio.busy()
            || self.studio.pending_import.is_some()
    }

    /// Reads a mesh for import and opens the resolution dialog; says why in the status bar if
    /// it cannot be read.
    fn import_path(&mut self, path: PathBuf) -> bool {
        match self.studio.choose_import(path) {
            Ok(()) => true,
            Err(e) => {
                self.studio.message = e;
                false
            }
        }
    }

    /// Opens a scene file (dropped or recent), asking first about unsaved changes.
    fn open_file(&mut self, ctx: &egui::Context, path: PathBuf) {
        self.open_next = Some(path);
        self.guard(ctx, Then::OpenFile);
    }

    /// Files dropped on the window: a scene opens, a mesh is imported as a new layer.
    fn dropped(&mut self, ctx: &egui::Context) {
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
                _ => self.studio.message = format!("Cannot open {}: not a scene or a mesh", path.display()),
            }
        }
    }

    /// Asks for a path: a native dialog where one answers, else the typed prompt.
    fn ask_path(&mut self, ctx: &egui::Context, kind: Prompt, then: Option<Then>) {
        let service: DialogService = match &self.dialogs {
            Dialogs::Typed => return self.open_prompt(ctx, kind, then),
            Dialogs::Native => std::sync::Arc::new(system_dialog),
            Dialogs::Service(s) => s.clone(),
        };
        let request = DialogRequest {
            title: kind.title(),
            pick_existing: matches!(kind, Prompt::Open | Prompt::Import | Prompt::OpenWorld),
            filter: match kind {
                Prompt::Open | Prompt::SaveAs => ("Strata scene", vec!["strata"]),
                Prompt::Export => ("Mesh", vec!["glb", "obj", "stl", "ply"]),
                Prompt::Import => ("Mesh", strata_mesh::import::MESH_EXTENSIONS.to_vec()),
                Prompt::NewWorld | Prompt::OpenWorld => ("Strata world", vec!["world"]),
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

    fn open_prompt(&mut self, ctx: &egui::Context, kind: Prompt, then: Option<Then>) {
        let text = match (kind, &self.studio.path) {
            (Prompt::SaveAs, Some(p)) => p.display().to_string(),
            _ => kind.suggestion().to_string(),
        };
        self.prompt = Some(PathPrompt { kind, text, focused: false, then });
        // The prompt must show at once, not on the next input event.
        ctx.request_repaint();
    }

    /// Carries out what a path was asked for.
    fn path_chosen(&mut self, ctx: &egui::Context, kind: Prompt, path: PathBuf, then: Option<Then>) {
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
        };
        if done && let Some(then) = then {
            self.proceed(ctx, then);
        }
    }

    /// Asks before `then` if it would discard unsaved work, else does it.
    fn guard(&mut self, ctx: &egui::Context, then: Then) {
        if self.studio.is_modified() {
            self.confirm = Some(then);
            ctx.request_repaint();
        } else {
            self.proceed(ctx, then);
        }
    }

    /// Does `then`, the changes having been saved or given up.
    fn proceed(&mut self, ctx: &egui::Context, then: Then) {
        match then {
            Then::New => {
                let _ = self.studio.act(Action::New);
                self.autosave.forget();
            }
            Then::Open => self.ask_path(ctx, Prompt::Open, None),
            Then::OpenFile => {
                if let Some(path) = self.open_next.take() {
                    self.path_chosen(ctx, Prompt::Open, path, None);
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
    fn save(&mut self, ctx: &egui::Context, then: Option<Then>) {
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

    /// The keyboard shortcuts, run after the frame's widgets so that a text field focused in
    /// this very frame (a click and a key in one slow frame) keeps its letters. Key presses are
    /// taken one event at a time, in the order they came: three quick `]` grow the brush three
    /// times, `V` then `C` in one frame ends on clay.
    fn shortcuts(&mut self, ctx: &egui::Context) {
        if self.modal_open() {
            // A prompt or a question has the keyboard: no key reaches the tools.
            return;
        }
        let presses: Vec<(egui::Modifiers, egui::Key)> = ctx.input(|i| {
            i.events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::Key { key, pressed: true, modifiers, .. } => Some((*modifiers, *key)),
                    _ => None,
                })
                .collect()
        });
        for (mods, key) in presses {
            let Some(command) = command_for(mods, key) else { continue };
            // Letters typed into a field are the field's; commands with Ctrl still work there.
            if (ctx.egui_wants_keyboard_input() && !command.works_while_typing()) || self.modal_open() {
                continue;
            }
            ctx.input_mut(|i| i.consume_key(mods, key));
            self.run_command(ctx, command);
            ctx.request_repaint();
        }
    }

    /// Carries out a keyboard command.
    fn run_command(&mut self, ctx: &egui::Context, command: Command) {
        use Command as C;
        match command {
            C::Undo => {
                let _ = self.studio.act(Action::Undo);
            }
            C::Redo => {
                let _ = self.studio.act(Action::Redo);
            }
            C::SaveAs => self.ask_path(ctx, Prompt::SaveAs, None),
            C::Save => self.save(ctx, None),
            C::Open => self.guard(ctx, Then::Open),
            C::New => self.guard(ctx, Then::New),
            C::Help => self.help_open = !self.help_open,
            C::CloseHelp => self.help_open = false,
            _ if self.studio.terrain.is_some() => self.terrain_command(command),
            C::RadiusDown => {
                let _ = self.studio.act(Action::ScaleRadius(1.0 / 1.15));
            }
            C::RadiusUp => {
                let _ = self.studio.act(Action::ScaleRadius(1.15));
            }
            C::ResizeBrush => self.start_resize(ctx),
            C::Wireframe => {
                let _ = self.studio.act(Action::ToggleWireframe);
            }
            C::NextShape => {
                let tool = &mut self.studio.editor.tool;
                tool.shape = match tool.shape {
                    BrushShape::Sphere => BrushShape::Box,
                    BrushShape::Box => BrushShape::Capsule,
                    BrushShape::Capsule => BrushShape::Cylinder,
                    BrushShape::Cylinder => BrushShape::Sphere,
                };
                self.studio.message = format!("Brush shape: {:?}", tool.shape);
            }
            C::View(view, opposite) => {
                let _ = self.studio.act(Action::AxisView(view, opposite));
            }
            C::Orthographic => {
                let _ = self.studio.act(Action::ToggleOrthographic);
            }
            C::Frame => {
                let _ = self.studio.act(Action::FrameAll);
            }
            C::Tool(kind) => self.studio.set_kind(kind),
            C::Line => self.studio.toggle_line_tool(),
            C::MirrorX => self.studio.toggle_symmetry(0),
            C::Eyedropper => self.studio.toggle_eyedropper(),
        }
    }

    /// Terrain mode's keys (WASD, Q and E fly, read as held keys in the viewport): B (the
    /// scene's next-shape key) bombs,
    /// [ and ] size the dig.
    fn terrain_command(&mut self, command: Command) {
        use Command as C;
        match command {
            C::NextShape => {
                let _ = self.studio.act(Action::Bomb);
            }
            C::RadiusDown => {
                if let Some(t) = self.studio.terrain.as_mut() {
                    t.brush_radius = (t.brush_radius / 1.25).max(1.0);
                }
            }
            C::RadiusUp => {
                if let Some(t) = self.studio.terrain.as_mut() {
                    t.brush_radius = (t.brush_radius * 1.25).min(40.0);
                }
            }
            _ => {}
        }
    }

    fn menu(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button(labelled("New", Command::New)).clicked() {
                    self.guard(&ctx, Then::New);
                }
                if ui.button(labelled("Open…", Command::Open)).clicked() {
                    self.guard(&ctx, Then::Open);
                }
                ui.menu_button("Open recent", |ui| {
                    let recent: Vec<PathBuf> = self.recent.paths().to_vec();
                    if recent.is_empty() {
                        ui.label("No recent scenes");
                    }
                    for path in recent {
                        if ui.button(path.display().to_string()).clicked() {
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
                if ui.button(labelled("Save", Command::Save)).clicked() {
                    self.save(&ctx, None);
                }
                if ui.button(labelled("Save as…", Command::SaveAs)).clicked() {
                    self.ask_path(&ctx, Prompt::SaveAs, None);
                }
                ui.separator();
                if ui.button("Export mesh… (glb, obj, stl, ply)").clicked() {
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
                );
                ui.separator();
                if ui.button("Quit").clicked() {
                    self.guard(&ctx, Then::Quit);
                }
            });
            ui.menu_button("Edit", |ui| {
                if ui.button(labelled("Undo", Command::Undo)).clicked() {
                    let _ = self.studio.act(Action::Undo);
                }
                if ui.button(labelled("Redo", Command::Redo)).clicked() {
                    let _ = self.studio.act(Action::Redo);
                }
            });
            ui.menu_button("View", |ui| {
                if ui.checkbox(&mut self.studio.wireframe, labelled("Wireframe", Command::Wireframe)).changed() {
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
                    if ui.button(labelled(label, command)).clicked() {
                        let _ = self.studio.act(action);
                        ui.close();
                    }
                }
                let mut ortho = self.studio.camera.orthographic;
                if ui.checkbox(&mut ortho, labelled("Orthographic", Command::Orthographic)).changed() {
                    let _ = self.studio.act(Action::ToggleOrthographic);
                    ui.close();
                }
                let settled = mesher_choice(ui, true, "Viewport mesher", &mut self.studio.view_draft);
                if settled && self.studio.view_draft != self.studio.editor.view_mesher() {
                    let _ = self.studio.act(Action::ViewMesher(self.studio.view_draft));
                }
                ui.checkbox(&mut self.studio.lod, "Level of detail")
                    .on_hover_text("Mesh far chunks that were given more detail at a coarser level (marching cubes)");
                ui.add(egui::Slider::new(&mut self.studio.lod_pixels, 0.5..=8.0).text("largest cell (px)"))
                    .on_hover_text("How large a cell level of detail may show on screen");
            });
            ui.menu_button("Terrain", |ui| {
                ui.horizontal(|ui| {
                    let label = ui.label("Seed");
                    ui.add(egui::DragValue::new(&mut self.world_seed)).labelled_by(label.id);
                });
                if ui.button("New world…").on_hover_text("Create a world file from the seed and fly in it").clicked()
                {
                    self.ask_path(&ctx, Prompt::NewWorld, None);
                    ui.close();
                }
                if ui.button("Open world…").clicked() {
                    self.ask_path(&ctx, Prompt::OpenWorld, None);
                    ui.close();
                }
                let open = self.studio.terrain.is_some();
                if ui.add_enabled(open, egui::Button::new(labelled("Bomb", Command::NextShape))).clicked() {
                    let _ = self.studio.act(Action::Bomb);
                    ui.close();
                }
                if ui.add_enabled(open, egui::Button::new("Close world")).clicked() {
                    let _ = self.studio.act(Action::CloseWorld);
                    ui.close();
                }
            });
            ui.menu_button("Help", |ui| {
                if ui.button(labelled("Keyboard shortcuts", Command::Help)).clicked() {
                    self.help_open = true;
                    ui.close();
                }
            });
        });
    }

    fn palette(&mut self, ui: &mut egui::Ui) {
        let tool = &mut self.studio.editor.tool;
        ui.heading("Tool");
        let tips = [
            (ToolKind::Clay, "Add clay that blends into the surface in a soft fillet (Ctrl/Alt: carve)"),
            (ToolKind::Add, "Add the brush shape exactly (CSG union; Ctrl/Alt: erase)"),
            (ToolKind::Erase, "Cut the brush shape away exactly (CSG difference; Ctrl/Alt: add)"),
            (
                ToolKind::Smooth,
                "Smooth the surface, keeping its volume (hold Shift with any tool; Ctrl/Alt: Laplacian)",
            ),
            (ToolKind::Inflate, "Push the surface out along its normal (Ctrl/Alt: deflate)"),
            (ToolKind::Flatten, "Pull the surface towards the plane that fits it under the brush"),
            (ToolKind::Pinch, "Pull the surface towards the stroke into a crease (Ctrl/Alt: push apart)"),
            (ToolKind::Grab, "Drag the surface under the brush with the pointer"),
            (
                ToolKind::Detail,
                "Add resolution under the brush for fine detail (Ctrl/Alt: back to the layer's base level)",
            ),
            (ToolKind::Paint, "Paint the current material without changing the shape (Ctrl/Alt: the first material)"),
        ];
        for row in tips.chunks(3) {
            ui.horizontal(|ui| {
                for &(kind, tip) in row {
                    ui.selectable_value(&mut tool.kind, kind, labelled(kind.name(), Command::Tool(kind)))
                        .on_hover_text(tip);
                }
            });
        }
        // The tool's own options in a box of fixed height (the tallest tool's), so that nothing
        // below moves under the pointer when the tool changes (a mis-click once landed in the
        // material name field that way).
        let row = ui.spacing().interact_size.y + ui.spacing().item_spacing.y;
        ui.allocate_ui_with_layout(
            egui::vec2(ui.available_width(), 2.0 * row),
            egui::Layout::top_down(egui::Align::Min),
            |ui| {
                ui.set_min_height(2.0 * row);
                let tool = &mut self.studio.editor.tool;
                if tool.kind.is_field_tool() && tool.kind != ToolKind::Grab {
                    ui.add(egui::Slider::new(&mut tool.field_strength, 0.0..=1.0).text("tool strength"))
                        .on_hover_text("How strongly a dab acts at its centre; the falloff takes it to 0 at the rim");
                }
                if tool.kind == ToolKind::Grab {
                    ui.label("Grab moves the surface as far as the pointer");
                }
                if tool.kind == ToolKind::Clay {
                    ui.add(egui::Slider::new(&mut tool.fillet, 0.0..=2.0).text("fillet (× radius)"))
                        .on_hover_text("How softly clay blends into the surface: 0 is a plain union");
                }
                if tool.kind == ToolKind::Detail {
                    ui.horizontal(|ui| {
                        ui.label("raise to");
                        for k in 1..=strata_volume::coords::MAX_LEVEL {
                            let level = strata_volume::Level::new(k).expect("a level");
                            ui.selectable_value(&mut tool.detail_level, level, format!("{}³ cells", 16 << k))
                                .on_hover_text("Cells per chunk side the chunks under the brush get");
                        }
                    });
                }
                if tool.kind == ToolKind::Smooth {
                    ui.checkbox(&mut tool.paper_smoothing, "Paper's smoothing (Eq. 1)").on_hover_text(
                        "Move crossings towards their neighbours' mean instead of smoothing the field (shrinks a little)",
                    );
                }
            },
        );
        let mut toggle = None;
        ui.horizontal(|ui| {
            ui.label("Mirror");
            for (axis, name) in ["X (X)", "Y", "Z"].into_iter().enumerate() {
                let mut on = self.studio.editor.tool.symmetry[axis];
                if ui.checkbox(&mut on, name).on_hover_text("Mirror every dab across this plane of the layer").changed()
                {
                    toggle = Some(axis);
                }
            }
        });
        if let Some(axis) = toggle {
            self.studio.toggle_symmetry(axis);
        }
        let tool = &mut self.studio.editor.tool;
        ui.label("Shape (B cycles; add and erase)");
        ui.horizontal(|ui| {
            for (shape, name) in [
                (BrushShape::Sphere, "Sphere"),
                (BrushShape::Box, "Box"),
                (BrushShape::Capsule, "Capsule"),
                (BrushShape::Cylinder, "Cylinder"),
            ] {
                ui.selectable_value(&mut tool.shape, shape, name)
                    .on_hover_text("The shape of the add and erase brushes (field tools act in a ball)");
            }
        });
        let (down, up, drag) =
            (keys_of(Command::RadiusDown), keys_of(Command::RadiusUp), keys_of(Command::ResizeBrush));
        let keys = format!("({down} and {up} change it, {drag} drags it)");
        if self.studio.screen_radius {
            ui.add(
                egui::Slider::new(&mut self.studio.radius_points, 2.0..=400.0)
                    .logarithmic(true)
                    .text(format!("radius (points) {down} {up} {drag}")),
            )
            .on_hover_text(format!("Brush radius on screen: the same size whatever the zoom {keys}"));
        } else {
            ui.add(
                egui::Slider::new(&mut self.studio.editor.tool.radius, 0.25..=64.0)
                    .logarithmic(true)
                    .text(format!("radius {down} {up} {drag}")),
            )
            .on_hover_text(format!("Brush radius in world units {keys}"));
        }
        ui.checkbox(&mut self.studio.screen_radius, "Radius on screen")
            .on_hover_text("Keep the brush's size on screen as the view zooms, instead of its size in the world");
        let tool = &mut self.studio.editor.tool;
        ui.checkbox(&mut tool.follow_surface, "Follow the surface").on_hover_text(
            "Strokes follow the surface under the pointer; off, a stroke keeps the depth where it started",
        );
        ui.add(egui::Slider::new(&mut tool.strength, 0.0..=1.0).text("pressure to size"))
            .on_hover_text("How much a pen's pressure scales the radius (0: not at all)");
        ui.add(egui::Slider::new(&mut tool.spacing, 0.05..=1.0).text("dab spacing"))
            .on_hover_text("Distance between a stroke's dabs, as a fraction of the radius");
        ui.separator();
        ui.label("Alignment");
        ui.horizontal(|ui| {
            ui.label("snap to grid");
            ui.add(egui::DragValue::new(&mut tool.grid_snap).range(0.0..=64.0).speed(0.25).suffix(" cells"))
                .on_hover_text("Place dabs on multiples of this many cells of the layer's grid (0: off)");
        });
        ui.horizontal(|ui| {
            ui.label("lock stroke");
            ui.selectable_value(&mut tool.axis_lock, None, "off");
            for (axis, name) in ["along X", "along Y", "along Z"].into_iter().enumerate() {
                ui.selectable_value(&mut tool.axis_lock, Some(axis), name)
                    .on_hover_text("Keep a stroke on the line through its start along this axis of the layer");
            }
        });
        ui.checkbox(&mut tool.orient_to_normal, "Orient brush to surface")
            .on_hover_text("Turn box, capsule and cylinder brushes onto the surface normal under the pointer");
        ui.separator();
        ui.label(format!(
            "Ctrl or Alt + drag: the inverse tool. Shift: smooth. {}: line tool. {}: mirror X.",
            keys_of(Command::Line),
            keys_of(Command::MirrorX)
        ));
        ui.separator();
        self.materials(ui);
    }

    /// The material palette: the current material (what add and clay add and paint paints),
    /// each material's colour, texture, scale and roughness, the eyedropper and a new material.
    fn materials(&mut self, ui: &mut egui::Ui) {
        ui.heading("Materials");
        let mut changed = false;
        let current = &mut self.studio.editor.tool.material;
        let palette = &mut self.studio.editor.scene.materials;
        ui.horizontal_wrapped(|ui| {
            for (i, m) in palette.iter().enumerate() {
                let [r, g, b] = m.color.map(|c| (c.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0) as u8);
                let text = egui::RichText::new(&m.name).strong().color(egui::Color32::from_rgb(r, g, b));
                ui.selectable_value(current, i as u8, text).on_hover_text("Add, clay and paint use this material");
            }
        });
        if let Some(m) = palette.get_mut(*current as usize) {
            ui.horizontal(|ui| {
                let label = ui.label("material name");
                changed |= ui.text_edit_singleline(&mut m.name).labelled_by(label.id).changed();
            });
            ui.horizontal(|ui| {
                ui.label("colour");
                changed |= ui.color_edit_button_rgb(&mut m.color).changed();
                egui::ComboBox::from_label("texture").selected_text(m.texture.name()).show_ui(ui, |ui| {
                    for t in strata_editor::Texture::ALL {
                        changed |= ui.selectable_value(&mut m.texture, t, t.name()).changed();
                    }
                });
            });
            changed |= ui
                .add(egui::Slider::new(&mut m.scale, 1.0..=128.0).logarithmic(true).text("texture scale"))
                .on_hover_text("World units per repeat of the texture")
                .changed();
            changed |= ui.add(egui::Slider::new(&mut m.roughness, 0.0..=1.0).text("roughness")).changed();
        }
        ui.horizontal(|ui| {
            let dropper = if self.studio.eyedropper { "Eyedropper (armed)" } else { "Eyedropper (K)" };
            if ui.button(dropper).on_hover_text("Click the model to take the material under the pointer").clicked() {
                self.studio.toggle_eyedropper();
            }
            if ui.button("New material").clicked() {
                self.studio.add_material();
            }
        });
        if changed {
            self.studio.editor.touch();
        }
    }

    fn layers(&mut self, ui: &mut egui::Ui) {
        ui.heading("Layers");
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
                edited |= ui.text_edit_singleline(&mut layer.name).labelled_by(label.id).changed();
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
                    let r = ui.add(egui::DragValue::new(&mut t.translation[k]).speed(0.1).prefix(name));
                    changed_t |= r.changed();
                    dragging |= r.dragged() && !r.drag_started();
                }
            });
            ui.horizontal(|ui| {
                let r = ui.add(egui::DragValue::new(&mut yaw).speed(0.5).suffix("°").prefix("turn "));
                changed_t |= r.changed();
                dragging |= r.dragged() && !r.drag_started();
                let r = ui.add(egui::DragValue::new(&mut t.scale).speed(0.01).range(1e-3..=1e3).prefix("scale "));
                changed_t |= r.changed();
                dragging |= r.dragged() && !r.drag_started();
            });
            if changed_t {
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

    /// The typed-path prompt: modal, focused when it opens, its text selected so typing
    /// replaces the suggestion; Enter or OK goes, Escape or Cancel closes it.
    fn prompt(&mut self, ctx: &egui::Context) {
        let Some(mut p) = self.prompt.take() else { return };
        let (mut go, mut cancel) = (false, false);
        let modal = egui::Modal::new(egui::Id::unique("path prompt")).show(ctx, |ui| {
            ui.heading(p.kind.title());
            let label = ui.label("Path:");
            let id = egui::Id::unique("path prompt field");
            let r = ui.add(egui::TextEdit::singleline(&mut p.text).id(id).desired_width(420.0)).labelled_by(label.id);
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
                go |= ui.button("OK").clicked();
                cancel |= ui.button("Cancel").clicked();
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
    fn native_dialog(&mut self, ctx: &egui::Context) {
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

    /// A large dab on its worker: a progress bar and a cancel button, until it finishes.
    fn job_progress(&mut self, ctx: &egui::Context) {
        if self.studio.poll_job() {
            ctx.request_repaint();
            return;
        }
        let Some(job) = self.studio.job.as_ref() else { return };
        let (done, total) = job.progress();
        let fraction = if total > 0 { done as f32 / total as f32 } else { 0.0 };
        let mut cancel = false;
        egui::Modal::new(egui::Id::unique("large dab")).show(ctx, |ui| {
            ui.heading("Sculpting a large dab");
            ui.add(egui::ProgressBar::new(fraction).show_percentage().desired_width(320.0));
            ui.label(format!("{done} of {total} chunks · {:.1} s", job.elapsed().as_secs_f64()));
            cancel = ui.button("Cancel").on_hover_text("Stop; the layer stays as it was").clicked();
        });
        if cancel || ctx.input(|i| i.key_pressed(egui::Key::Escape)) {
            job.cancel();
        }
        ctx.request_repaint_after(Duration::from_millis(50));
    }

    /// The resolution dialog of a mesh about to be imported: cells along its longest side, with
    /// a live estimate of what the layer will hold.
    fn import_dialog(&mut self, ctx: &egui::Context) {
        let Some(p) = self.studio.pending_import.as_mut() else { return };
        let (mut go, mut cancel) = (false, false);
        let modal = egui::Modal::new(egui::Id::unique("import mesh")).show(ctx, |ui| {
            ui.heading("Import mesh as a new layer");
            ui.label(format!(
                "{}: {} triangles, {}",
                p.path.display(),
                p.mesh.triangles.len(),
                if p.closed { "closed" } else { "with holes (filled line by line)" }
            ));
            ui.add(egui::Slider::new(&mut p.cells, 16..=2048).logarithmic(true).text("cells along the longest side"))
                .on_hover_text("Finer keeps more detail and takes more memory and time");
            match p.plan() {
                Ok(plan) => ui.label(format!(
                    "cells of {:.4} units · about {:.0} thousand crossings · about {:.1} MiB",
                    plan.cell,
                    plan.estimated_crossings / 1e3,
                    plan.estimated_bytes() / (1024.0 * 1024.0)
                )),
                Err(e) => ui.label(e.to_string()),
            };
            ui.horizontal(|ui| {
                go = ui.button("Import").clicked();
                cancel = ui.button("Cancel").clicked();
            });
        });
        if cancel || modal.should_close() {
            self.studio.pending_import = None;
        } else if go && let Err(e) = self.studio.start_import() {
            self.studio.message = e;
        }
    }

    /// A mesh conversion on its worker: a progress bar and a cancel button.
    fn import_progress(&mut self, ctx: &egui::Context) {
        if self.studio.poll_import() {
            ctx.request_repaint();
            return;
        }
        let Some(job) = self.studio.import_job.as_ref() else { return };
        let (done, total) = job.control.progress();
        let fraction = if total > 0 { done as f32 / total as f32 } else { 0.0 };
        let mut cancel = false;
        egui::Modal::new(egui::Id::unique("importing")).show(ctx, |ui| {
            ui.heading(format!("Importing {}", job.name));
            ui.add(egui::ProgressBar::new(fraction).show_percentage().desired_width(320.0));
            ui.label(format!("{done} of {total} chunks · {:.1} s", job.started.elapsed().as_secs_f64()));
            cancel = ui.button("Cancel import").on_hover_text("Stop; the scene stays as it was").clicked();
        });
        if cancel || ctx.input(|i| i.key_pressed(egui::Key::Escape)) {
            job.control.cancel();
        }
        ctx.request_repaint_after(Duration::from_millis(50));
    }

    /// The keyboard help overlay (F1).
    fn help(&mut self, ctx: &egui::Context) {
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
    fn confirm(&mut self, ctx: &egui::Context) {
        let Some(then) = self.confirm else { return };
        let what = match then {
            Then::New => "starting a new scene",
            Then::Open | Then::OpenFile => "opening another scene",
            Then::Quit => "quitting",
        };
        let name = self.studio.path.as_ref().map_or("the new scene".to_string(), |p| p.display().to_string());
        let mut choice = None;
        let modal = egui::Modal::new(egui::Id::unique("unsaved changes")).show(ctx, |ui| {
            ui.heading("Unsaved changes");
            ui.label(format!("Save the changes to {name} before {what}?"));
            ui.horizontal(|ui| {
                if ui.button("Save").clicked() {
                    choice = Some(0);
                }
                if ui.button("Don't save").clicked() {
                    choice = Some(1);
                }
                if ui.button("Cancel").clicked() {
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
    fn recovery(&mut self, ctx: &egui::Context) {
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
                if ui.button("Recover").clicked() {
                    choice = Some(true);
                }
                if ui.button("Discard").clicked() {
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
    fn notice(&mut self, ctx: &egui::Context) {
        let Some(text) = self.studio.notice.clone() else { return };
        let mut close = false;
        egui::Window::new("Something went wrong")
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_TOP, egui::vec2(0.0, 36.0))
            .default_width(460.0)
            .show(ctx, |ui| {
                ui.add(egui::Label::new(text.as_str()).wrap());
                close = ui.button("Dismiss").clicked();
            });
        if close {
            self.studio.notice = None;
        }
    }

    /// The window's title: the scene's file name (or world's), `*` when it has unsaved changes.
    pub fn window_title(&self) -> String {
        let name =
            |p: &Option<PathBuf>| p.as_ref().and_then(|p| p.file_name()).map(|n| n.to_string_lossy().into_owned());
        if self.studio.terrain.is_some() {
            let world = name(&self.studio.world_path).unwrap_or_else(|| "world".into());
            return format!("{world} (terrain) — Strata Studio");
        }
        let file = name(&self.studio.path).unwrap_or_else(|| "Untitled".into());
        let mark = if self.studio.is_modified() { "*" } else { "" };
        format!("{file}{mark} — Strata Studio")
    }

    /// Where the viewport was last laid out (screen points), and the screen point of world
    /// point `p` there (for tests that aim at the model).
    pub fn viewport_rect(&self) -> Option<egui::Rect> {
        self.viewport_rect
    }

    /// The screen point (points) where the viewport shows world point `p`.
    pub fn screen_of(&self, p: glam::Vec3) -> Option<egui::Pos2> {
        let rect = self.viewport_rect?;
        let clip = self.studio.camera.view_proj(rect.width() / rect.height().max(1.0)) * p.extend(1.0);
        (clip.w > 0.0).then(|| {
            let (x, y) = (clip.x / clip.w, clip.y / clip.w);
            egui::pos2(rect.left() + (x + 1.0) * 0.5 * rect.width(), rect.top() + (1.0 - y) * 0.5 * rect.height())
        })
    }

    /// The title last sent to the window.
    pub fn sent_title(&self) -> &str {
        &self.title
    }

    fn update_title(&mut self, ctx: &egui::Context) {
        let title = self.window_title();
        if title != self.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.title = title;
        }
    }

    /// Asks for one more frame whenever a window, menu, notice or modal opened or closed in
    /// this one: egui lays out a new window in a first, invisible pass, and a reactive app does
    /// not draw again until the next input event (the F1 help showed clipped mid-word and menus
    /// showed only once the pointer moved).
    fn repaint_on_change(&mut self, ctx: &egui::Context) {
        let shown = [
            self.help_open,
            self.prompt.is_some(),
            self.confirm.is_some(),
            self.native.is_some(),
            self.recovery.is_some(),
            self.studio.notice.is_some(),
            self.resize.is_some(),
            self.studio.pending_import.is_some(),
            egui::Popup::is_any_open(ctx),
        ]
        .iter()
        .fold(0u64, |acc, &b| acc << 1 | b as u64);
        // (A new status message is a change too: it is drawn at once, not on the next event.)
        if shown != self.shown.0 || self.studio.message != self.shown.1 {
            self.shown = (shown, self.studio.message.clone());
            ctx.request_repaint();
        }
    }

    /// Starts sizing the brush by dragging (F): the pointer's distance from a centre placed so
    /// that the radius starts as it is.
    fn start_resize(&mut self, ctx: &egui::Context) {
        let Some(pointer) = ctx.pointer_latest_pos() else {
            self.studio.message = "Brush size: point at the viewport and press F".into();
            return;
        };
        let depth = self
            .studio
            .hover
            .map_or(self.studio.camera.distance as f64, |p| (p - self.studio.camera.eye().as_dvec3()).length());
        let world_per_point = self.studio.world_per_point(depth);
        let points = if self.studio.screen_radius {
            self.studio.radius_points
        } else {
            (self.studio.editor.tool.radius / world_per_point) as f32
        };
        let points = points.clamp(4.0, 2000.0);
        self.resize = Some(Resize {
            centre: pointer - egui::vec2(points, 0.0),
            before: (self.studio.editor.tool.radius, self.studio.radius_points),
            world_per_point,
        });
        self.studio.message = "Brush size: move the pointer; click or Enter keeps it, Escape cancels".into();
    }

    /// A frame of sizing the brush: the radius follows the pointer; a click or Enter (or F
    /// again) keeps it, Escape or a right click cancels. Returns whether sizing took this
    /// frame's input (the click that keeps the size is not also a dab).
    fn resize_input(&mut self, ui: &egui::Ui) -> bool {
        let Some(r) = self.resize else { return false };
        use egui::{Key, Modifiers};
        let keep = ui.input_mut(|i| {
            i.consume_key(Modifiers::NONE, Key::Enter)
                || i.consume_key(Modifiers::NONE, Key::F)
                || i.pointer.button_pressed(egui::PointerButton::Primary)
        });
        let cancel = ui.input_mut(|i| {
            i.consume_key(Modifiers::NONE, Key::Escape) || i.pointer.button_pressed(egui::PointerButton::Secondary)
        });
        let pointer = ui.input(|i| i.pointer.latest_pos()).unwrap_or(r.centre + egui::vec2(r.before.1, 0.0));
        let points = (pointer - r.centre).length().clamp(1.0, 2000.0);
        if cancel {
            (self.studio.editor.tool.radius, self.studio.radius_points) = r.before;
            self.studio.message = "Brush size unchanged".into();
            self.resize = None;
            return true;
        }
        if self.studio.screen_radius {
            self.studio.radius_points = points;
        } else {
            self.studio.editor.tool.radius = (points as f64 * r.world_per_point).clamp(0.05, 256.0);
        }
        let stroke = egui::Stroke::new(1.5, egui::Color32::from_rgb(120, 190, 255));
        ui.painter().circle_stroke(r.centre, points, stroke);
        ui.painter().circle_filled(r.centre, 2.0, stroke.color);
        if keep {
            self.studio.message = if self.studio.screen_radius {
                format!("Brush radius {points:.0} points on screen")
            } else {
                format!("Brush radius {:.2}", self.studio.editor.tool.radius)
            };
            self.resize = None;
        }
        true
    }

    /// The frame's UI without the GPU viewport's drawing (which needs `frame`): what UI tests
    /// drive.
    pub fn show(&mut self, ui: &mut egui::Ui, frame: Option<&mut eframe::Frame>) {
        let ctx = ui.ctx().clone();
        if ctx.input(|i| i.viewport().close_requested())
            && let Some(t) = self.studio.terrain.as_mut()
        {
            // The world is written as the window closes (its periodic flushes aside).
            if let Err(e) = t.save() {
                self.studio.message = format!("Could not write the world: {e}");
            }
        }
        if ctx.input(|i| i.viewport().close_requested()) && !self.allow_close {
            if self.studio.is_modified() {
                ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
                self.confirm = Some(Then::Quit);
            } else {
                self.autosave.forget();
            }
        }
        self.studio.expire_messages();
        egui::Panel::top("menu").show(ui, |ui| self.menu(ui));
        egui::Panel::bottom("status").show(ui, |ui| {
            // One line, whatever its length: a long error must not grow the bar and shrink the
            // viewport (the whole text is in the tooltip, and errors in their notice).
            let status = self.studio.status();
            ui.add(egui::Label::new(status.as_str()).truncate()).on_hover_text(status);
        });
        egui::Panel::left("tools").resizable(false).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| self.palette(ui));
        });
        egui::Panel::right("layers").show(ui, |ui| self.layers(ui));
        egui::CentralPanel::default().show(ui, |ui| self.viewport(ui, frame));
        self.dropped(&ctx);
        self.job_progress(&ctx);
        self.import_dialog(&ctx);
        self.import_progress(&ctx);
        self.help(&ctx);
        self.native_dialog(&ctx);
        self.prompt(&ctx);
        self.confirm(&ctx);
        self.recovery(&ctx);
        self.notice(&ctx);
        self.shortcuts(&ctx);
        self.update_title(&ctx);
        self.repaint_on_change(&ctx);
        // (Not while a background dab holds a layer's volume: the copy would miss it.)
        if self.studio.is_modified() && !self.studio.busy() {
            self.autosave.tick(&self.studio, self.studio.editor.revision());
            ctx.request_repaint_after(self.autosave.interval);
        }
    }

    fn viewport(&mut self, ui: &mut egui::Ui, frame: Option<&mut eframe::Frame>) {
        let (rect, response) = ui.allocate_exact_size(ui.available_size(), egui::Sense::click_and_drag());
        self.viewport_rect = Some(rect);
        let aspect = rect.width() / rect.height().max(1.0);
        if self.studio.terrain.is_some() {
            self.terrain_input(ui, &response, rect, aspect);
        } else {
            self.scene_input(ui, &response, rect, aspect);
        }
        self.draw(ui, frame, rect);
    }

    /// Terrain mode: WASD, Q and E fly (Shift faster), right drag looks, left click digs and
    /// Shift + left click raises (repeating while held), then one frame of streaming.
    fn terrain_input(&mut self, ui: &mut egui::Ui, response: &egui::Response, rect: egui::Rect, aspect: f32) {
        use egui::Key;
        let typing = ui.ctx().egui_wants_keyboard_input() || self.modal_open();
        let held = |k: Key| !typing && ui.input(|i| i.key_down(k));
        let axis = |plus: Key, minus: Key| held(plus) as i32 as f64 - held(minus) as i32 as f64;
        let delta = ui.input(|i| i.pointer.delta());
        let look = if response.dragged_by(egui::PointerButton::Secondary) {
            (-delta.x as f64 * 0.005, delta.y as f64 * 0.005)
        } else {
            (0.0, 0.0)
        };
        let input = crate::terrain::FlyInput {
            forward: axis(Key::W, Key::S),
            right: axis(Key::D, Key::A),
            up: axis(Key::E, Key::Q),
            look,
            fast: ui.input(|i| i.modifiers.shift),
        };
        let now = Instant::now();
        let dt = self.last_frame.map_or(1.0 / 60.0, |t| now.duration_since(t).as_secs_f64());
        self.last_frame = Some(now);
        let raise = ui.input(|i| i.modifiers.shift);
        let dig = response.is_pointer_button_down_on() && ui.input(|i| i.pointer.primary_down());
        let pointer = response.hover_pos();
        let Some(t) = self.studio.terrain.as_mut() else { return };
        t.fly(input, dt);
        if dig
            && let Some(p) = pointer
            && self.last_dig.is_none_or(|d| now.duration_since(d) > Duration::from_millis(90))
        {
            self.last_dig = Some(now);
            let x = (p.x - rect.left()) / rect.width() * 2.0 - 1.0;
            let y = 1.0 - (p.y - rect.top()) / rect.height() * 2.0;
            let (o, d) = t.camera().ray(x, y, aspect);
            if let Err(e) = t.sculpt(o.as_dvec3(), d.as_dvec3(), raise) {
                self.studio.message = e;
            }
        }
        t.tick(dt, Duration::from_millis(6));
        // The world streams, bombs fly and debris falls: draw every frame.
        ui.ctx().request_repaint();
    }

    fn scene_input(&mut self, ui: &mut egui::Ui, response: &egui::Response, rect: egui::Rect, aspect: f32) {
        self.studio.viewport_points = rect.height();
        let to_ndc = |p: egui::Pos2| {
            let x = (p.x - rect.left()) / rect.width() * 2.0 - 1.0;
            let y = 1.0 - (p.y - rect.top()) / rect.height() * 2.0;
            (x, y)
        };
        if self.resize_input(ui) {
            return;
        }
        // Camera: right drag orbits, middle drag pans, the wheel zooms towards the pointer.
        let typing = ui.ctx().egui_wants_keyboard_input();
        self.studio.smooth_held = ui.input(|i| i.modifiers.shift) && !typing;
        self.studio.inverse_held = ui.input(|i| i.modifiers.command || i.modifiers.alt) && !typing;
        let (delta, scroll, secondary_drag, middle, primary, secondary) = ui.input(|i| {
            (
                i.pointer.delta(),
                i.smooth_scroll_delta.y,
                i.pointer.button_down(egui::PointerButton::Secondary) && i.modifiers.alt,
                i.pointer.button_down(egui::PointerButton::Middle),
                i.pointer.primary_down(),
                i.pointer.secondary_down(),
            )
        });
        if response.hovered() {
            if scroll != 0.0 {
                let towards = response.hover_pos().map(to_ndc).map(|(x, y)| {
                    self.studio.surface_point(x, y, aspect).unwrap_or_else(|| {
                        // Nothing under the pointer: the point at the target's depth.
                        let cam = &self.studio.camera;
                        let (o, d) = cam.ray(x, y, aspect);
                        (o + d * cam.distance).as_dvec3()
                    })
                });
                zoom_towards(&mut self.studio.camera, towards.map(|p| p.as_vec3()), (-scroll * 0.001).exp());
            }
            if middle {
                self.studio.camera.pan(-delta.x / rect.height(), delta.y / rect.height());
            }
        }
        // Right drag orbits unless Alt is held (then it erases like the secondary tool button).
        let orbit = response.dragged_by(egui::PointerButton::Secondary) && !secondary_drag;
        if orbit {
            self.studio.camera.orbit(-delta.x * 0.008, delta.y * 0.008);
        }
        // Presses and releases of the primary button in this frame, in order, each where it
        // happened: a quick click within one slow frame is a dab (or a line end), not lost.
        let layer = ui.layer_id();
        let clicks: Vec<(egui::Pos2, bool)> = ui.input(|i| {
            i.events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::PointerButton { pos, button: egui::PointerButton::Primary, pressed, .. } => {
                        Some((*pos, *pressed))
                    }
                    _ => None,
                })
                .collect()
        });
        let budget = Duration::from_millis(6);
        let mut down = self.studio.editor.stroking();
        for (pos, pressed) in clicks {
            let on_viewport = rect.contains(pos) && ui.ctx().layer_id_at(pos) == Some(layer);
            if pressed && on_viewport && !self.modal_open() {
                let held = Buttons { primary: true, secondary: false };
                self.studio.pointer(Some(to_ndc(pos)), held, 1.0, aspect, budget);
                down = true;
            } else if !pressed && down {
                self.studio.pointer(Some(to_ndc(pos)), Buttons::default(), 1.0, aspect, budget);
                down = false;
            }
        }
        let ndc = response.hover_pos().filter(|_| response.hovered() || response.dragged()).map(to_ndc);
        let buttons = Buttons {
            primary: primary
                && (response.dragged_by(egui::PointerButton::Primary) || response.is_pointer_button_down_on()),
            secondary: secondary && secondary_drag,
        };
        self.studio.pointer(ndc, buttons, 1.0, aspect, budget);
    }

    fn draw(&mut self, ui: &mut egui::Ui, frame: Option<&mut eframe::Frame>, rect: egui::Rect) {
        let Some(rs) = frame.and_then(|f| f.wgpu_render_state()) else {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "No wgpu renderer",
                egui::FontId::default(),
                egui::Color32::RED,
            );
            return;
        };
        let Some(vp) = self.viewport.as_mut() else { return };
        let ppp = ui.ctx().pixels_per_point();
        let size = (((rect.width() * ppp) as u32).max(1), ((rect.height() * ppp) as u32).max(1));
        self.studio.viewport_height = size.1 as f32;
        if vp.size != size || vp.color.is_none() {
            let make = |format, usage, label, view_formats: &[wgpu::TextureFormat]| {
                rs.device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats,
                })
            };
            let color = make(
                wgpu::TextureFormat::Rgba8UnormSrgb,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
                "viewport colour",
                &[wgpu::TextureFormat::Rgba8Unorm],
            );
            let depth = make(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT, "viewport depth", &[]);
            let (cv, dv) = (color.create_view(&Default::default()), depth.create_view(&Default::default()));
            // The renderer writes sRGB-encoded bytes; egui composites in gamma space, so it reads
            // them through a plain (non-sRGB) view and shows exactly what the PNG path writes.
            let egui_view = color.create_view(&wgpu::TextureViewDescriptor {
                format: Some(wgpu::TextureFormat::Rgba8Unorm),
                ..Default::default()
            });
            let mut egui_renderer = rs.renderer.write();
            match vp.texture_id {
                Some(id) => egui_renderer.update_egui_texture_from_wgpu_texture(
                    &rs.device,
                    &egui_view,
                    wgpu::FilterMode::Linear,
                    id,
                ),
                None => {
                    vp.texture_id =
                        Some(egui_renderer.register_native_texture(&rs.device, &egui_view, wgpu::FilterMode::Linear))
                }
            }
            vp.color = Some((color, cv, dv));
            vp.size = size;
        }
        if let Some(t) = self.studio.terrain.as_mut() {
            // Terrain mode draws the world's chunk meshes and the debris instead of the scene.
            if !vp.terrain_shown {
                vp.renderer.clear();
                vp.renderer.set_palette(&rs.queue, &strata_viewport::palette(&self.studio.editor.scene));
                vp.terrain_shown = true;
                t.uploads.extend(t.meshes().map(|(k, _)| k).collect::<Vec<_>>());
            }
            for key in std::mem::take(&mut t.uploads) {
                match t.mesh(key) {
                    Some(mesh) => strata_viewport::upload_chunk(
                        &mut vp.renderer,
                        &rs.device,
                        &rs.queue,
                        TERRAIN_LAYER,
                        key,
                        mesh,
                        Mat4::IDENTITY,
                    ),
                    None => vp.renderer.remove_mesh(strata_viewport::chunk_id(TERRAIN_LAYER, key)),
                }
            }
            let debris = t.particle_mesh();
            // An empty mesh drops the debris.
            let id = MeshId { group: DEBRIS_LAYER, key: [0; 3] };
            vp.renderer.upload_mesh(
                &rs.device,
                &rs.queue,
                id,
                strata_viewport::mesh_ref(&debris),
                Placement::default(),
                [1.0; 3],
            );
            let settings = FrameSettings { camera: t.camera(), wireframe: self.studio.wireframe, ..Default::default() };
            vp.present(ui, rs, rect, size, &settings);
            return;
        }
        if vp.terrain_shown {
            vp.terrain_shown = false;
            self.studio.editor.redraw_all();
        }
        // What the editor's meshes changed since the last frame, applied by the one mirror.
        let changes = self.studio.editor.take_changes();
        strata_viewport::apply_changes(&self.studio.editor, &changes, &rs.device, &rs.queue, &mut vp.renderer);
        let inverse = self.studio.inverse_held;
        let kind = self.studio.editor.tool.kind;
        let erase = matches!((kind, inverse), (ToolKind::Erase, false) | (ToolKind::Add | ToolKind::Clay, true));
        let field = kind.is_field_tool() || self.studio.smooth_held;
        let wireframe = self.studio.wireframe;
        let camera = self.studio.camera;
        let dabs = self.studio.preview_dabs();
        let preview_mesh = strata_viewport::mesh_ref(self.studio.preview_mesh());
        let rgb = if erase { [1.0, 0.35, 0.3] } else { [0.35, 0.65, 1.0] };
        let mut previews = Vec::with_capacity(dabs.len() * 2);
        for (k, (p, q)) in dabs.into_iter().enumerate() {
            // The dab itself brighter than its mirror images.
            let alpha = if k == 0 { 0.22 } else { 0.12 };
            let model = Mat4::from_rotation_translation(q.as_quat(), p.as_vec3());
            previews.push(Preview { mesh: preview_mesh, model, color: [rgb[0], rgb[1], rgb[2], alpha] });
            if field {
                // The falloff: a core where the tool acts at half strength or more.
                let core = Mat4::from_scale(glam::Vec3::splat(FALLOFF_HALF as f32));
                previews.push(Preview {
                    mesh: preview_mesh,
                    model: model * core,
                    color: [rgb[0], rgb[1], rgb[2], alpha * 1.6],
                });
            }
        }
        let settings = FrameSettings { camera, wireframe, previews: &previews, ..Default::default() };
        vp.present(ui, rs, rect, size, &settings);
        // Repaint on our own only while meshing catches up or a stroke is in progress; pointer
        // and key events repaint anyway, so an idle editor uses no CPU.
        if self.studio.editor.pending() > 0 || self.studio.editor.stroking() {
            ui.ctx().request_repaint();
        }
    }
}

impl eframe::App for StudioApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.show(ui, Some(frame));
    }
}

/// Opens the window on `studio` and runs until it closes.
pub fn run_window(studio: Studio) -> anyhow::Result<()> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_title("Strata Studio"),
        ..Default::default()
    };
    eframe::run_native("Strata Studio", options, Box::new(|cc| Ok(Box::new(StudioApp::new(cc, studio)))))
        .map_err(|e| anyhow::anyhow!("the window could not start: {e}"))
}

/// Zooms `camera` by `factor` about `towards` (world), which stays where it is on screen: the
/// eye and the target both move along their lines through it. Without a point, about the target.
fn zoom_towards(camera: &mut strata_render::Camera, towards: Option<glam::Vec3>, factor: f32) {
    let before = camera.distance;
    camera.zoom(factor);
    let Some(p) = towards.filter(|p| p.is_finite()) else { return };
    // (The zoom clamps the distance: move the target by the factor actually taken.)
    let f = camera.distance / before;
    camera.target = p + (camera.target - p) * f;
}

/// A mesher picker (one radio button a mesher: menus stay open while one is picked) with a
/// simplification toggle and error, under `label`; false while the error
/// slider is being dragged. Dual contouring is simplified on export only, so the viewport's
/// picker offers it without.
fn mesher_choice(ui: &mut egui::Ui, viewport: bool, label: &str, options: &mut strata_mesh::MeshOptions) -> bool {
    ui.label(label);
    for m in strata_mesh::Mesher::ALL {
        ui.radio_value(&mut options.mesher, m, m.name());
    }
    let can_simplify = !viewport || options.mesher.block().is_some();
    if !can_simplify {
        options.simplify = None;
    }
    let mut on = options.simplify.is_some();
    let text = if viewport { "Simplify chunks (borders kept)" } else { "Simplify (meshoptimizer)" };
    if ui.add_enabled(can_simplify, egui::Checkbox::new(&mut on, text)).changed() {
        options.simplify = on.then_some(0.1);
    }
    let mut settled = true;
    if let Some(e) = options.simplify.as_mut() {
        let r = ui.add(egui::Slider::new(e, 0.01..=1.0).logarithmic(true).text("error (cells)"));
        // While the slider is dragged nothing is remeshed; its last value counts.
        settled = !r.dragged() || r.drag_stopped();
    }
    settled
}
