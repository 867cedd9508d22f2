//! The studio's state and actions, independent of egui and wgpu, in rooms: the state, its
//! messages and small toggles (here), carrying out actions (`actions.rs`), importing meshes
//! (`import.rs`), the pointer over the viewport (`pointer.rs`) and the brush preview
//! (`preview.rs`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::file::{self, SceneFileError};
use strata_editor::{Buttons, Editor, Layer, Modifiers, Scene, ToolKind, ToolPose, View};
use strata_mesh::Mesh;
use strata_render::Camera;
use strata_volume::brush::Sphere;

mod actions;
mod collab;
mod import;
mod inserts;
mod pointer;
mod preview;
mod references;
mod stamps;
#[cfg(test)]
mod tests;

pub use collab::{Collab, SessionParams};
pub use import::{ImportJob, PendingImport};

/// What a menu item, a key or a button asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// A fresh default scene (history cleared).
    New,
    /// Load a scene file; on failure the open scene stays.
    Open(PathBuf),
    /// Save the scene to its current path (or fail asking for one); while a world is open, the
    /// scene waiting for it.
    Save,
    /// Save the scene to a new path and make it current (the waiting scene while a world is
    /// open).
    SaveAs(PathBuf),
    /// Export visible layers as a mesh (format from the extension: glb, obj, stl, ply).
    Export(PathBuf),
    /// Undo the last stroke.
    Undo,
    /// Redo.
    Redo,
    /// Multiply the brush radius.
    ScaleRadius(f64),
    /// Toggle the wireframe overlay.
    ToggleWireframe,
    /// Add an empty layer and make it active.
    AddLayer,
    /// Delete the active layer (the last one left is emptied instead).
    DeleteLayer,
    /// Copy the active layer into a new layer above it.
    DuplicateLayer,
    /// Move the active layer up (`+1`) or down (`−1`) the list.
    MoveLayer(i32),
    /// Merge the active layer into the one below it (a union through both transforms).
    MergeDown,
    /// Frame the visible layers (Home, numpad period).
    FrameAll,
    /// Look along an axis (numpad 1, 3, 7; with Ctrl the opposite view).
    AxisView(strata_render::AxisView, bool),
    /// Switch between perspective and orthographic projection (numpad 5).
    ToggleOrthographic,
    /// Create a world file from a seed and fly in it (terrain mode).
    NewWorld(PathBuf, u32),
    /// Open a world file in terrain mode.
    OpenWorld(PathBuf),
    /// Write the world and go back to the scene.
    CloseWorld,
    /// Write the open world's edits now (they are also written every few seconds).
    SaveWorld,
    /// Launch a bomb along the view (terrain mode).
    Bomb,
    /// Mesh the viewport with this mesher and per-chunk simplification.
    ViewMesher(strata_mesh::MeshOptions),
    /// Host a room on this machine with the scene as it is (File > Host session).
    HostSession(SessionParams),
    /// Join a room; the scene becomes the room's (File > Join session).
    JoinSession(SessionParams),
    /// Leave the room (closing it when this studio hosts it); the scene stays.
    LeaveSession,
    /// Invert, clear, grow or shrink the active layer's mask (one undo step).
    Mask(strata_editor::MaskAction),
    /// Load a PNG as the stamp tool's picture (File > Load stamp picture, or dropped).
    LoadStamp(PathBuf),
    /// Read a mesh file as an insert waiting to be placed (Edit > Insert mesh > From file).
    InsertFile(PathBuf),
    /// Read a PNG or JPEG as a reference image (File > Load reference image).
    LoadReference(PathBuf),
}

impl Action {
    /// For an action on the scene (its file, layers or orbit camera): what it does, for the
    /// message that refuses it while a world is open.
    pub fn scene_only(&self) -> Option<&'static str> {
        Some(match self {
            Action::New => "start a new scene",
            Action::Open(_) => "open a scene",
            Action::Export(_) => "export the scene",
            Action::AddLayer
            | Action::DeleteLayer
            | Action::DuplicateLayer
            | Action::MoveLayer(_)
            | Action::MergeDown => "change the layers",
            Action::FrameAll | Action::AxisView(..) | Action::ToggleOrthographic => "use the scene's views",
            Action::ViewMesher(_) => "change the viewport's mesher (a world is meshed by marching cubes as it streams)",
            Action::Mask(_) => "change a mask (masks are for scenes)",
            Action::LoadReference(_) => "load a reference image (they are kept with scenes)",
            _ => return None,
        })
    }

    /// For an action that changes what a shared room's operations refer to (the scene itself,
    /// its layers, or the editor's surface): what it does, for the message that refuses it while
    /// in a room.
    pub fn unshared(&self) -> Option<&'static str> {
        Some(match self {
            Action::New => "start a new scene",
            Action::Open(_) => "open a scene",
            Action::AddLayer
            | Action::DeleteLayer
            | Action::DuplicateLayer
            | Action::MoveLayer(_)
            | Action::MergeDown => "change the layers",
            Action::NewWorld(..) | Action::OpenWorld(_) => "open a world",
            Action::CloseWorld => "close the world",
            Action::Bomb => "launch bombs (a crater is not an operation the room can replay)",
            Action::Mask(_) => {
                "change the whole mask (mask strokes are shared; inverting, clearing, growing and shrinking are not)"
            }
            _ => return None,
        })
    }
}

/// World units per cell of the default scene's layer: its ball of radius 16 is 64 cells
/// across its radius, about 100,000 marching-cubes triangles, smooth to the eye.
pub const DEFAULT_CELL: f64 = 0.25;

/// The default brush radius in world units: 10 cells of the default layer, the radius at which
/// every tool's whole frame (dab and remesh) is measured against its 4 ms budget.
pub const DEFAULT_RADIUS: f64 = 2.5;

/// The default scene: a ball of clay of radius 16 (world units) resting on the grid, ready to
/// sculpt, in a layer of [`DEFAULT_CELL`] cells.
pub fn default_scene() -> Scene {
    let mut scene = Scene::default();
    scene.layers[0].name = "Clay".into();
    scene.layers[0].transform.scale = DEFAULT_CELL;
    let centre = DVec3::new(32.0, 18.0, 32.0) / DEFAULT_CELL;
    scene.layers[0]
        .volume
        .add(&Sphere::new(centre, 16.0 / DEFAULT_CELL).expect("valid default sphere"))
        .expect("the default sphere is a valid edit");
    scene.view = View { target: DVec3::new(32.0, 18.0, 32.0), distance: 90.0, yaw: 0.7, pitch: 0.45 };
    scene
}

/// Which exports remove stray islands: pieces of the surface enclosing fewer cells³ than
/// [`Studio::island_cells`] (isolated solid nodes that print as specks).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Islands {
    /// STL exports (for printing) only: the default.
    ForStl,
    /// Every export.
    Remove,
    /// None.
    Keep,
}

/// Everything the studio knows besides the GPU.
#[derive(Debug)]
pub struct Studio {
    /// The editor the tools, the pointer and undo drive: the scene's, or while a world is open
    /// the world's (the scene's then waits in [`crate::terrain::TerrainMode::scene`]).
    pub editor: Editor,
    /// Terrain mode's fly camera, bombs and debris, when a world is open.
    pub terrain: Option<crate::terrain::TerrainMode>,
    /// How worlds opened by the studio stream.
    pub world_settings: strata_terrain::WorldSettings,
    /// The viewport camera.
    pub camera: Camera,
    /// Where the scene was loaded from or last saved to.
    pub path: Option<PathBuf>,
    /// The file of the world open in terrain mode.
    pub world_path: Option<PathBuf>,
    /// Wireframe overlay on.
    pub wireframe: bool,
    /// The mesher and simplification of exports.
    pub export: strata_mesh::MeshOptions,
    /// Which exports drop stray islands (pieces enclosing less than [`Studio::island_cells`]).
    pub islands: Islands,
    /// The smallest piece an export keeps, in cells³ of its layer's grid.
    pub island_cells: f32,
    /// The viewport mesher as the View menu shows it (applied once its error slider settles).
    pub view_draft: strata_mesh::MeshOptions,
    /// The last message for the status bar (errors included).
    pub message: String,
    /// An error the user has not yet dismissed: shown in a notice that stays until read.
    pub notice: Option<String>,
    /// A message about the view (its text and the camera it describes): cleared once the camera
    /// moves, so the status bar never says "Front view" of an orbited camera.
    view_message: Option<(String, Camera)>,
    /// The brush radius is kept in screen points ([`Studio::radius_points`]) rather than world
    /// units: its size on screen stays as the view zooms.
    pub screen_radius: bool,
    /// The brush radius in screen points when [`Studio::screen_radius`] is on.
    pub radius_points: f32,
    /// The viewport's height in points (for the screen-space radius).
    pub viewport_points: f32,
    /// Last frame's edit time (ms).
    pub last_edit_ms: f64,
    /// Last frame's remesh time (ms).
    pub last_remesh_ms: f64,
    /// Where the tool would act (world), for the brush preview.
    pub hover: Option<DVec3>,
    /// The surface normal (world) under the pointer, when the pointer is over the model: what
    /// brushes are oriented to under [`strata_editor::ToolSettings::orient_to_normal`].
    pub hover_normal: Option<DVec3>,
    /// Ctrl or Alt is held: the primary button uses the inverse tool.
    pub inverse_held: bool,
    /// Distance along the pointer ray at which the stroke in progress acts.
    stroke_depth: Option<f64>,
    preview: Option<(strata_editor::BrushShape, u64, Mesh)>,
    /// The editor's revision when the scene was last saved, opened or created.
    saved_revision: u64,
    /// A dab too large for a frame, running on a worker thread.
    pub job: Option<strata_editor::DabJob>,
    /// Dabs whose brush box spans more chunks than this run on a worker thread with a progress
    /// bar and a cancel button instead of in the frame (32,768 chunks: a sphere of radius about
    /// 250 cells, which takes a few hundred milliseconds).
    pub background_chunks: u64,
    /// Where the last large dab of the stroke in progress went.
    last_background_dab: Option<DVec3>,
    /// Shift is held: the pointer smooths instead of using the tool.
    pub smooth_held: bool,
    /// The line tool is armed: the next two clicks on the model are a straight stroke's ends.
    pub line_mode: bool,
    /// The line's first end, once clicked.
    pub line_start: Option<DVec3>,
    /// The eyedropper is armed: the next click on the model makes the material under it the
    /// current material.
    pub eyedropper: bool,
    /// A button was held in the previous frame (to see presses).
    prev_held: bool,
    /// A mesh waiting for its import resolution.
    pub pending_import: Option<PendingImport>,
    /// A mesh conversion in progress.
    pub import_job: Option<ImportJob>,
    /// Level of detail by camera distance: far chunks stored above their layer's base level
    /// are meshed coarser.
    pub lod: bool,
    /// GPU meshing asked for (View → GPU meshing): the viewport's marching cubes of scene
    /// layers made on the GPU and drawn from there (on by default where the adapter is a GPU
    /// that can; the app keeps the editor's switch in step, for every scene opened).
    pub gpu_meshing: bool,
    /// Chunks the GPU meshed that the viewport shows (their triangles stay on the GPU).
    pub gpu_chunks: usize,
    /// The largest cell, in pixels, level of detail may show.
    pub lod_pixels: f64,
    /// The viewport's height in pixels (for level of detail).
    pub viewport_height: f32,
    /// The view level of detail was last set for.
    last_lod: Option<strata_editor::LodView>,
    /// The base resolution level of layers added from now on (the detail tool raises chunks
    /// above it; new chunks of a layer are made at its base).
    pub new_layer_level: strata_volume::Level,
    /// The shared room the studio is in, when it is in one.
    pub collab: Option<Collab>,
    /// Each tool's own falloff, while another tool is current (see [`Studio::sync_falloff`]).
    falloffs: Vec<(ToolKind, strata_volume::tools::Falloff)>,
    /// The tool whose falloff the brush holds.
    falloff_kind: ToolKind,
    /// A mesh insert waiting to be placed and applied.
    pub insert: Option<inserts::PendingInsert>,
    /// The reference image selected in its panel (the gizmo moves it while it is unlocked).
    pub selected_reference: Option<usize>,
    /// Reference images are drawn (View > Reference images).
    pub show_references: bool,
}

impl Studio {
    /// A studio on `scene`, with the camera the scene was saved with.
    pub fn new(scene: Scene) -> Self {
        let camera = strata_viewport::camera_of(&scene.view);
        let mut s = Studio {
            editor: Editor::new(scene),
            terrain: None,
            world_settings: strata_terrain::WorldSettings {
                view_distance: 192.0,
                detail_distance: 40.0,
                coarse_distance: 96.0,
                ..strata_terrain::WorldSettings::default()
            },
            camera,
            path: None,
            world_path: None,
            wireframe: false,
            export: strata_mesh::MeshOptions::default(),
            islands: Islands::ForStl,
            island_cells: strata_mesh::islands::DEFAULT_MIN_ISLAND_CELLS,
            view_draft: strata_mesh::MeshOptions::default(),
            message: "Ready. Left drag: sculpt · right drag: orbit · middle drag: pan · wheel: zoom".into(),
            notice: None,
            view_message: None,
            screen_radius: false,
            radius_points: 40.0,
            viewport_points: 720.0,
            last_edit_ms: 0.0,
            last_remesh_ms: 0.0,
            eyedropper: false,
            hover: None,
            hover_normal: None,
            inverse_held: false,
            stroke_depth: None,
            preview: None,
            saved_revision: 0,
            falloffs: Vec::new(),
            insert: None,
            selected_reference: None,
            show_references: true,
            falloff_kind: ToolKind::default(),
            job: None,
            background_chunks: 1 << 15,
            last_background_dab: None,
            smooth_held: false,
            line_mode: false,
            line_start: None,
            prev_held: false,
            pending_import: None,
            import_job: None,
            lod: true,
            gpu_meshing: false,
            gpu_chunks: 0,
            lod_pixels: 1.5,
            viewport_height: 720.0,
            last_lod: None,
            new_layer_level: strata_volume::Level::BASE,
            collab: None,
        };
        s.saved_revision = s.editor.revision();
        s.editor.tool.radius = DEFAULT_RADIUS;
        s
    }

    /// Whether the scene has changes that are not in its file (or, for a new scene, changes at
    /// all). (A world's edits are written as it goes.)
    pub fn is_modified(&self) -> bool {
        self.scene_editor().revision() != self.saved_revision
    }

    /// Records that the scene as it is now is safe (saved, or just opened).
    pub fn mark_saved(&mut self) {
        self.saved_revision = self.scene_editor().revision();
    }

    /// The scene's camera: [`Studio::camera`], or while a world is open the one waiting.
    pub fn scene_camera(&self) -> Camera {
        match self.terrain.as_ref().and_then(|t| t.scene.as_deref()) {
            Some((_, camera)) => *camera,
            None => self.camera,
        }
    }

    /// The scene's editor, to change (see [`Studio::scene_editor`]).
    pub fn scene_editor_mut(&mut self) -> &mut Editor {
        match self.terrain.as_mut().and_then(|t| t.scene.as_deref_mut()) {
            Some((editor, _)) => editor,
            None => &mut self.editor,
        }
    }

    /// The scene's editor: [`Studio::editor`], or while a world is open the one waiting.
    pub fn scene_editor(&self) -> &Editor {
        match self.terrain.as_ref().and_then(|t| t.scene.as_deref()) {
            Some((editor, _)) => editor,
            None => &self.editor,
        }
    }

    /// Carries out an action; errors go to the status message and leave the scene unchanged.
    pub fn act(&mut self, action: Action) -> Result<(), String> {
        let r = self.try_act(action);
        if let Err(e) = &r {
            self.fail(e.clone());
        }
        r
    }

    /// Reports an error: in the status bar and in a notice that stays until the user closes it.
    pub fn fail(&mut self, error: String) {
        self.message = error.clone();
        self.notice = Some(error);
    }

    /// Sets a message about the view the camera now shows.
    fn view_said(&mut self, text: String) {
        self.message = text.clone();
        self.view_message = Some((text, self.camera));
    }

    /// Drops a message about the view once the camera has moved on (call every frame).
    pub fn expire_messages(&mut self) {
        if let Some((text, camera)) = &self.view_message
            && (*camera != self.camera || *text != self.message)
        {
            if *text == self.message {
                self.message.clear();
            }
            self.view_message = None;
        }
    }

    /// Arms or disarms the eyedropper (`K`).
    pub fn toggle_eyedropper(&mut self) {
        self.eyedropper = !self.eyedropper;
        self.message = if self.eyedropper {
            "Eyedropper: click the model to take its material".into()
        } else {
            "Eyedropper off".into()
        };
    }

    /// Adds a material to the palette (a copy of the current one) and makes it current.
    pub fn add_material(&mut self) -> Option<u8> {
        if let Err(e) = self.refuse_in_session("add a material") {
            self.message = e;
            return None;
        }
        let palette = &mut self.editor.scene.materials;
        if palette.len() >= strata_volume::MATERIAL_IDS {
            self.message = format!("The palette is full ({} materials)", strata_volume::MATERIAL_IDS);
            return None;
        }
        let base = palette.get(self.editor.tool.material as usize).cloned().unwrap_or_else(|| palette[0].clone());
        palette.push(strata_editor::Material { name: format!("{} {}", base.name, palette.len()), ..base });
        let id = (palette.len() - 1) as u8;
        self.editor.tool.material = id;
        self.editor.touch();
        Some(id)
    }

    /// Arms or disarms the line tool (`L`).
    pub fn toggle_line_tool(&mut self) {
        self.line_mode = !self.line_mode;
        self.line_start = None;
        self.message =
            if self.line_mode { "Line: click the first end on the model".into() } else { "Line tool off".into() };
    }

    /// Whether a background dab or an import is running.
    pub fn busy(&self) -> bool {
        self.job.is_some() || self.import_job.is_some()
    }

    /// The status bar's live figures.
    pub fn status(&self) -> String {
        let room = self.collab.as_ref().map_or(String::new(), |c| {
            let people = c.session.peers().count() + 1;
            format!("Room {:?}: {} · {people} in the room · ", c.params.room, c.state_text())
        });
        format!("{room}{}", self.local_status())
    }

    fn local_status(&self) -> String {
        if let Some(t) = &self.terrain {
            return format!("{} · {}", self.message, t.status(&self.editor));
        }
        let scene = &self.editor.scene;
        let levels = scene
            .layers
            .get(self.editor.active_layer)
            .map(|l| {
                let parts = chunk_levels(&l.volume);
                if parts.is_empty() { String::new() } else { format!(" · chunks {parts}") }
            })
            .unwrap_or_default();
        format!(
            "{}{levels} · memory {:.2} MiB · {} crossings · {} triangles{} · edit {:.2} ms · remesh {:.2} ms · {} chunks queued · history {} steps",
            self.message,
            scene.volume_bytes() as f64 / (1024.0 * 1024.0),
            scene.crossings(),
            self.editor.triangle_count(),
            if self.gpu_chunks > 0 {
                format!(" + {} chunks meshed on the GPU", self.gpu_chunks)
            } else {
                String::new()
            },
            self.last_edit_ms,
            self.last_remesh_ms,
            self.editor.pending(),
            self.editor.history().undo_len(),
        )
    }

    /// Turns mirroring across the layer-grid plane of `axis` (0: x, 1: y, 2: z) on or off. The
    /// first mirror turned on centres the planes on the active layer's surface (its box's centre,
    /// rounded to nodes, so the planes pass through nodes and mirrored dabs mirror exactly).
    pub fn toggle_symmetry(&mut self, axis: usize) {
        let tool = &mut self.editor.tool;
        let on = !tool.symmetry[axis];
        if on
            && !tool.symmetry.iter().any(|&s| s)
            && let Some((lo, hi)) = self.editor.surface_bounds(self.editor.active_layer)
        {
            self.editor.tool.symmetry_center = ((lo + hi) * 0.5).round();
        }
        self.editor.tool.symmetry[axis] = on;
        let names = ["X", "Y", "Z"];
        let c = self.editor.tool.symmetry_center;
        self.message = format!(
            "Mirror {} {} (planes through {:.0}, {:.0}, {:.0})",
            names[axis],
            if on { "on" } else { "off" },
            c.x,
            c.y,
            c.z
        );
    }

    /// Switches add/erase.
    pub fn set_kind(&mut self, kind: ToolKind) {
        self.editor.tool.kind = kind;
        self.sync_falloff();
    }

    /// Gives each tool its own falloff: when the tool has changed since the last call, the
    /// brush's falloff is kept as the old tool's and the new tool's comes back (smooth for one
    /// not used yet). Call every frame.
    pub fn sync_falloff(&mut self) {
        let kind = self.editor.tool.kind;
        if kind == self.falloff_kind {
            return;
        }
        let old = (self.falloff_kind, self.editor.tool.falloff);
        match self.falloffs.iter_mut().find(|(k, _)| *k == old.0) {
            Some(slot) => *slot = old,
            None => self.falloffs.push(old),
        }
        self.editor.tool.falloff =
            self.falloffs.iter().find(|(k, _)| *k == kind).map_or_else(Default::default, |f| f.1);
        self.falloff_kind = kind;
    }

    /// Makes `preset` the brush (its falloff the tool's own from now on).
    pub fn apply_preset(&mut self, preset: &strata_editor::Preset) -> Result<(), strata_editor::PresetError> {
        self.sync_falloff();
        self.editor.apply_preset(preset)?;
        self.falloff_kind = self.editor.tool.kind;
        Ok(())
    }
}

/// The list chunks of `volume` counted by the cells a side they are stored at ("12×8³ 40×16³";
/// empty where it holds none).
pub(crate) fn chunk_levels(volume: &strata_volume::Volume) -> String {
    let parts: Vec<String> = volume
        .level_counts()
        .iter()
        .enumerate()
        .filter(|(_, c)| **c > 0)
        .map(|(k, c)| format!("{c}×{}³", strata_volume::Level::ALL[k].cells()))
        .collect();
    parts.join(" ")
}
