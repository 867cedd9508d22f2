//! The eframe window, in rooms: the app itself and its frame (here: state, title, repaints,
//! [`StudioApp::show`]), the menus (`menus.rs`), the tool panel (`tool_panel.rs`), the layers
//! panel (`layers_panel.rs`), prompts, dialogs, questions and the help (`dialogs.rs`), the
//! keyboard (`input.rs`), long jobs (`jobs.rs`) and the 3D viewport: pointer input and drawing
//! (`viewport.rs`; the renderer draws into a texture that egui shows).

use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use eframe::egui;
use glam::Mat4;
use strata_editor::{BrushShape, Buttons, ToolKind};
use strata_render::{DEPTH_FORMAT, FrameSettings, Placement, Preview, Renderer};

/// Where the falloff `3t⁴ − 4t³ + 1` is one half, as a fraction of the radius: the preview's
/// core, inside which a field tool acts at half its strength or more.
pub const FALLOFF_HALF: f64 = 0.6135;

use crate::keymap::{Command, command_for, keys_of, labelled};
use crate::recovery::Autosave;
use crate::studio::{Action, Studio};

mod dialogs;
mod gizmo;
pub use gizmo::Handle as GizmoHandle;
mod brush_menus;
mod input;
mod jobs;
mod layers_panel;
mod menus;
mod presets_panel;
mod references_panel;
mod session;
mod tool_panel;
mod viewport;

use dialogs::*;
pub use dialogs::{DialogRequest, Dialogs};
use viewport::*;

/// A file-dialog service: shows a dialog for the request and returns the chosen path, or `None`
/// when the user cancelled or no dialog could be shown. It runs on a thread of its own.
pub type DialogService = std::sync::Arc<dyn Fn(&DialogRequest) -> Option<PathBuf> + Send + Sync>;

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
    /// The Host or Join dialog, when open.
    session_dialog: Option<session::SessionDialog>,
    /// What the last Host or Join dialog was given (the next one starts from it).
    session_params: Option<crate::studio::SessionParams>,
    /// The room to join once the unsaved-changes question is answered.
    join_next: Option<crate::studio::SessionParams>,
    /// The brush presets shelf.
    presets: presets_panel::Shelf,
    /// The transform gizmo shows for the active layer (`Ctrl+T`; it always shows for a waiting
    /// insert).
    pub layer_gizmo: bool,
    /// Reference images the panel has seen (one more opens it).
    references_seen: usize,
    /// The reference image whose value a drag in the panel is changing, once it made its undo
    /// step (the rest of the drag joins that step).
    reference_drag: Option<usize>,
    /// A drag of a gizmo handle in progress.
    gizmo_drag: Option<gizmo::GizmoDrag>,
    /// The pressure of the touch (a pen's, where the platform reads it) in progress, from
    /// egui's touch events' force; `None` without one (a mouse: full pressure).
    pub pen_pressure: Option<f64>,
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
            gpu: strata_viewport::GpuMeshing::new(&rs.adapter, &rs.device).map_err(|e| e.to_string()),
            solver_failed: Default::default(),
        });
        // GPU meshing is on by default where the adapter is a GPU that can (a software adapter
        // such as lavapipe meshes faster on the CPU itself).
        let hardware =
            cc.wgpu_render_state.as_ref().is_some_and(|rs| rs.adapter.get_info().device_type != wgpu::DeviceType::Cpu);
        let mut app = StudioApp::headless(studio, dialogs, recovery_dir);
        app.studio.gpu_meshing = hardware && viewport.as_ref().is_some_and(|v| v.gpu.is_ok());
        app.viewport = viewport;
        app
    }

    /// Turns GPU meshing on or off (View → GPU meshing), saying what the viewport does now: it
    /// cannot where there is no GPU viewport or the adapter lacks what it needs; it meshes
    /// marching cubes of scene layers (not a world, not a masked layer) and solves dual
    /// contouring's vertices; the other meshers stay on the CPU.
    pub fn set_gpu_meshing(&mut self, on: bool) {
        if !on {
            self.studio.gpu_meshing = false;
            self.studio.message = "GPU meshing off: the CPU meshes the viewport".into();
            return;
        }
        let why_not = match &self.viewport {
            None => Some("there is no GPU viewport".to_string()),
            Some(v) => v.gpu.as_ref().err().cloned(),
        };
        if let Some(why) = why_not {
            self.studio.gpu_meshing = false;
            self.studio.fail(format!("GPU meshing is not available ({why}): the CPU meshes the viewport"));
            return;
        }
        self.studio.gpu_meshing = true;
        let mesher = self.studio.editor.view_mesher();
        self.studio.message = if mesher.mesher == strata_mesh::Mesher::DualContouring {
            "GPU meshing on: dual contouring made and drawn on the GPU (where a layer mixes levels, its vertices solved there and its quads joined on the CPU)".into()
        } else if mesher.mesher != strata_mesh::Mesher::MarchingCubes || mesher.simplify.is_some() {
            format!(
                "GPU meshing on: it meshes plain marching cubes, so the viewport's {} stays on the CPU",
                mesher.mesher
            )
        } else if self.studio.terrain.is_some() {
            "GPU meshing on for scenes: a world streams its meshes from the CPU".into()
        } else {
            "GPU meshing on: marching cubes made and drawn on the GPU (masked layers stay on the CPU)".into()
        };
    }

    /// The app without a GPU viewport (for UI tests): paths asked for as `dialogs` says,
    /// recovery files kept in `recovery_dir` (and one found there offered).
    pub fn headless(studio: Studio, dialogs: Dialogs, recovery_dir: PathBuf) -> Self {
        let recovery = crate::recovery::find(&recovery_dir);
        let recent = crate::recent::Recent::load(recovery_dir.join(crate::recent::FILE_NAME));
        let presets = presets_panel::Shelf::load(&recovery_dir);
        let mut studio = studio;
        if let Some(e) = &presets.load_error {
            studio.fail(e.clone());
        }
        StudioApp {
            layer_gizmo: false,
            references_seen: 0,
            reference_drag: None,
            gizmo_drag: None,
            pen_pressure: None,
            presets,
            world_seed: 1,
            last_frame: None,
            resize: None,
            title: String::new(),
            viewport_rect: None,
            shown: (0, String::new()),
            open_next: None,
            session_dialog: None,
            session_params: None,
            join_next: None,
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
            || self.session_dialog.is_some()
            || self.studio.busy()
            || self.studio.pending_import.is_some()
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
        let room = self.studio.collab.as_ref().map_or(String::new(), |c| format!(" (room {})", c.params.room));
        format!("{file}{mark}{room} — Strata Studio")
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
            self.session_dialog.is_some(),
            self.studio.collab.is_some(),
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

    /// The frame's UI without the GPU viewport's drawing (which needs `frame`): what UI tests
    /// drive.
    pub fn show(&mut self, ui: &mut egui::Ui, frame: Option<&mut eframe::Frame>) {
        let ctx = ui.ctx().clone();
        if ctx.input(|i| i.viewport().close_requested())
            && let Some(t) = self.studio.terrain.as_ref()
        {
            // The world is written as the window closes (its periodic flushes aside).
            if let Err(e) = t.save(&mut self.studio.editor) {
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
        self.studio.sync_falloff();
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
        egui::Panel::right("layers").show(ui, |ui| {
            self.people(ui);
            self.layers(ui);
            self.references_panel(ui);
        });
        egui::CentralPanel::default().show(ui, |ui| self.viewport(ui, frame));
        self.dropped(&ctx);
        self.job_progress(&ctx);
        self.import_dialog(&ctx);
        self.import_progress(&ctx);
        self.help(&ctx);
        self.native_dialog(&ctx);
        self.prompt(&ctx);
        self.session_dialog(&ctx);
        self.confirm(&ctx);
        self.recovery(&ctx);
        self.notice(&ctx);
        self.shortcuts(&ctx);
        // The room's strokes and the others' brushes arrive between input events: a live
        // session keeps frames coming.
        if self.studio.poll_session() {
            ctx.request_repaint_after(Duration::from_millis(33));
        }
        self.update_title(&ctx);
        self.repaint_on_change(&ctx);
        // (Not while a background dab holds a layer's volume: the copy would miss it.)
        if self.studio.is_modified() && !self.studio.busy() {
            self.autosave.tick(&self.studio, self.studio.scene_editor().revision());
            ctx.request_repaint_after(self.autosave.interval);
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
