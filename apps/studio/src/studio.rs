//! The studio's state and actions, independent of egui and wgpu.

use std::path::{Path, PathBuf};
use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::file::{self, SceneFileError};
use strata_editor::{Buttons, Editor, Layer, Modifiers, Scene, ToolKind, ToolPose, View};
use strata_mesh::Mesh;
use strata_render::Camera;
use strata_volume::brush::Sphere;

/// What a menu item, a key or a button asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// A fresh default scene (history cleared).
    New,
    /// Load a scene file; on failure the open scene stays.
    Open(PathBuf),
    /// Save to the current path (or fail asking for one).
    Save,
    /// Save to a new path and make it current.
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
    /// Launch a bomb along the view (terrain mode).
    Bomb,
    /// Mesh the viewport with this mesher and per-chunk simplification.
    ViewMesher(strata_mesh::MeshOptions),
}

/// A mesh chosen for import, waiting for the user to pick its resolution.
#[derive(Debug)]
pub struct PendingImport {
    /// Where it was read from.
    pub path: PathBuf,
    /// The triangles.
    pub mesh: strata_mesh::import::TriangleMesh,
    /// Cells along the longest side (the dialog's slider).
    pub cells: u32,
    /// Whether every edge is shared by two triangles.
    pub closed: bool,
}

impl PendingImport {
    /// The conversion's plan at the chosen resolution (cell size, estimated crossings and
    /// memory).
    pub fn plan(&self) -> Result<strata_editor::import::ImportPlan, strata_editor::import::ConvertError> {
        strata_editor::import::plan(&self.mesh, strata_editor::import::Resolution::Cells(self.cells))
    }
}

/// A mesh conversion running on a worker thread.
#[derive(Debug)]
pub struct ImportJob {
    /// The new layer's name.
    pub name: String,
    /// Progress and cancel.
    pub control: std::sync::Arc<strata_volume::EditControl>,
    /// When it started.
    pub started: std::time::Instant,
    worker: std::thread::JoinHandle<Result<Layer, strata_editor::import::ConvertError>>,
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
    /// The editor core.
    pub editor: Editor,
    /// Terrain mode's world, when one is open (the scene waits meanwhile).
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
    /// The largest cell, in pixels, level of detail may show.
    pub lod_pixels: f64,
    /// The viewport's height in pixels (for level of detail).
    pub viewport_height: f32,
    /// The view level of detail was last set for.
    last_lod: Option<strata_editor::LodView>,
    /// The base resolution level of layers added from now on (the detail tool raises chunks
    /// above it; new chunks of a layer are made at its base).
    pub new_layer_level: strata_volume::Level,
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
            lod_pixels: 1.5,
            viewport_height: 720.0,
            last_lod: None,
            new_layer_level: strata_volume::Level::BASE,
        };
        s.saved_revision = s.editor.revision();
        s.editor.tool.radius = DEFAULT_RADIUS;
        s
    }

    /// Whether the scene has changes that are not in its file (or, for a new scene, changes at
    /// all).
    pub fn is_modified(&self) -> bool {
        self.editor.revision() != self.saved_revision
    }

    /// Records that the scene as it is now is safe (saved, or just opened).
    pub fn mark_saved(&mut self) {
        self.saved_revision = self.editor.revision();
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

    /// World units per screen point at distance `depth` from the eye (for a perspective view;
    /// an orthographic view has the same scale everywhere).
    pub fn world_per_point(&self, depth: f64) -> f64 {
        let c = &self.camera;
        let half = (c.fov_y as f64 * 0.5).tan();
        let span = if c.orthographic { 2.0 * c.distance as f64 * half } else { 2.0 * depth.max(1e-6) * half };
        span / self.viewport_points.max(1.0) as f64
    }

    /// With a screen-space radius, sets the tool's world radius from
    /// [`Studio::radius_points`] at the depth of `at` (or of the view's target).
    pub fn apply_screen_radius(&mut self, at: Option<DVec3>) {
        if !self.screen_radius {
            return;
        }
        let eye = self.camera.eye().as_dvec3();
        let depth = at.map_or(self.camera.distance as f64, |p| (p - eye).length());
        let r = self.radius_points.clamp(1.0, 2000.0) as f64 * self.world_per_point(depth);
        if r.is_finite() {
            self.editor.tool.radius = r.clamp(0.05, 256.0);
        }
    }

    fn try_act(&mut self, action: Action) -> Result<(), String> {
        if let Some(t) = self.terrain.as_mut() {
            // Terrain mode: undo and redo act on the world.
            match action {
                Action::Undo => {
                    t.world.undo().map_err(|e| e.to_string())?;
                    return Ok(());
                }
                Action::Redo => {
                    t.world.redo().map_err(|e| e.to_string())?;
                    return Ok(());
                }
                _ => {}
            }
        }
        match action {
            Action::NewWorld(path, seed) => {
                let recipe = strata_terrain::Recipe::with_seed(seed);
                let mode = crate::terrain::TerrainMode::create(&path, &recipe, self.world_settings.clone())
                    .map_err(|e| format!("Could not create the world {}: {e}", path.display()))?;
                self.terrain = Some(mode);
                self.message = format!("New world {} from seed {seed}", path.display());
                self.world_path = Some(path);
                return Ok(());
            }
            Action::OpenWorld(path) => {
                let mode = crate::terrain::TerrainMode::open(&path, self.world_settings.clone())
                    .map_err(|e| format!("Could not open the world {}: {e}", path.display()))?;
                self.terrain = Some(mode);
                self.message = format!("Opened the world {}", path.display());
                self.world_path = Some(path);
                return Ok(());
            }
            Action::CloseWorld => {
                self.world_path = None;
                if let Some(mut t) = self.terrain.take() {
                    let written = t.save().map_err(|e| format!("Could not write the world: {e}"))?;
                    self.message = format!("World written ({written} chunks); back to the scene");
                }
                return Ok(());
            }
            Action::Bomb => {
                let t = self.terrain.as_mut().ok_or("Bombs need a world: Terrain > New world")?;
                t.bomb();
                return Ok(());
            }
            Action::New => {
                self.replace_scene(default_scene());
                self.path = None;
                self.mark_saved();
                self.message = "New scene".into();
            }
            Action::Open(path) => {
                let loaded = file::load(&path).map_err(|e| format!("Could not open {}: {e}", path.display()))?;
                self.replace_scene(loaded.scene);
                self.mark_saved();
                if !loaded.report.is_clean() {
                    // What was repaired is not in the file yet.
                    self.editor.touch();
                }
                self.message = if loaded.report.is_clean() {
                    format!("Opened {}", path.display())
                } else {
                    format!("Opened {} with repairs: {}", path.display(), loaded.report)
                };
                self.path = Some(path);
            }
            Action::Save => {
                let path = self.path.clone().ok_or("Save as… first: the scene has no file yet")?;
                self.save_to(&path)?;
            }
            Action::SaveAs(path) => {
                self.save_to(&path)?;
                self.path = Some(path);
            }
            Action::Export(path) => {
                let stl = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("stl"));
                let remove = match self.islands {
                    Islands::Keep => None,
                    Islands::ForStl if !stl => None,
                    Islands::ForStl | Islands::Remove => Some(self.island_cells),
                };
                let options = strata_mesh::MeshOptions { remove_islands: remove, ..self.export };
                let (mesh, islands) =
                    self.editor.export_mesh_reported(options).map_err(|e| format!("Could not export: {e}"))?;
                strata_mesh::export::save_mesh_with(&mesh, &path, &self.editor.scene.export_palette())
                    .map_err(|e| format!("Could not export {}: {e}", path.display()))?;
                self.message = format!("Exported {} triangles to {}", mesh.triangle_count(), path.display());
                if let Some(min) = remove {
                    self.message += &format!(
                        " (removed {} islands below {min} cells³: {} triangles, {:.2} cells³)",
                        islands.removed, islands.removed_triangles, islands.removed_volume
                    );
                }
            }
            Action::Undo | Action::Redo => {
                let undo = action == Action::Undo;
                let done = if undo { self.editor.undo() } else { self.editor.redo() };
                self.message = match (undo, done) {
                    (true, true) => "Undone".into(),
                    (true, false) => "Nothing to undo".into(),
                    (false, true) => "Redone".into(),
                    (false, false) => "Nothing to redo".into(),
                };
            }
            Action::ScaleRadius(f) => {
                if self.screen_radius {
                    let r = (self.radius_points * f as f32).clamp(1.0, 2000.0);
                    self.radius_points = r;
                    self.message = format!("Brush radius {r:.0} points on screen");
                } else {
                    let r = (self.editor.tool.radius * f).clamp(0.25, 256.0);
                    self.editor.tool.radius = r;
                    self.message = format!("Brush radius {r:.2}");
                }
            }
            Action::ToggleWireframe => self.wireframe = !self.wireframe,
            Action::ViewMesher(options) => {
                self.view_draft = options;
                self.editor.set_view_mesher(options).map_err(|e| format!("Could not change the mesher: {e}"))?;
                self.editor.finish_meshing();
                self.message = match options.simplify {
                    Some(e) => format!("Viewport: {}, chunks simplified to {e} cells", options.mesher),
                    None => format!("Viewport: {}", options.mesher),
                };
                let mixed = (0..self.editor.scene.layers.len())
                    .any(|l| self.editor.view_mesher_used(l).is_some_and(|m| m != options.mesher));
                if mixed {
                    self.message += " (layers whose chunks mix resolution levels are shown with marching cubes)";
                }
            }
            Action::AddLayer => {
                let mut layers = self.editor.scene.layers.clone();
                let n = layers.len() + 1;
                let mut layer = Layer::new(format!("Layer {n}"));
                let cell = layer.volume.cell_size();
                layer.volume = strata_volume::Volume::with_level(self.new_layer_level);
                layer.volume.set_cell_size(cell).expect("the default cell size is valid");
                layers.push(layer);
                self.editor.replace_layers(layers, n - 1);
            }
            Action::DeleteLayer | Action::DuplicateLayer | Action::MoveLayer(_) | Action::MergeDown => {
                self.layer_op(action)?;
            }
            Action::FrameAll => {
                let layers = self.editor.scene.layers.iter().filter(|l| l.visible);
                let v = View::framing(layers);
                self.camera.target = v.target.as_vec3();
                self.camera.distance = v.distance as f32;
                self.view_said("Framed the visible layers".into());
            }
            Action::AxisView(view, opposite) => {
                self.camera.axis_view(view, opposite);
                self.view_said(format!("{}{view:?} view", if opposite { "Opposite of the " } else { "" }));
            }
            Action::ToggleOrthographic => {
                self.camera.orthographic = !self.camera.orthographic;
                self.view_said(if self.camera.orthographic { "Orthographic" } else { "Perspective" }.into());
            }
        }
        Ok(())
    }

    /// Deletes, duplicates, moves or merges down the active layer. Layer operations renumber
    /// layers, which the undo history refers to by number: they clear it (and say so).
    fn layer_op(&mut self, action: Action) -> Result<(), String> {
        if self.busy() {
            return Err("Wait for the large dab or the import to finish".into());
        }
        self.editor.end_stroke();
        let mut layers = self.editor.scene.layers.clone();
        let i = self.editor.active_layer.min(layers.len().saturating_sub(1));
        let (what, active) = match action {
            Action::DeleteLayer => {
                let name = layers[i].name.clone();
                if layers.len() == 1 {
                    layers[0] = Layer::new("Layer 1");
                } else {
                    layers.remove(i);
                }
                (format!("Deleted layer {name:?}"), i.min(layers.len() - 1))
            }
            Action::DuplicateLayer => {
                let mut copy = layers[i].clone();
                copy.name = format!("{} copy", copy.name);
                copy.locked = false;
                layers.insert(i + 1, copy);
                (format!("Duplicated layer {:?}", layers[i].name), i + 1)
            }
            Action::MoveLayer(d) => {
                let j = i as i64 + d as i64;
                if j < 0 || j >= layers.len() as i64 {
                    return Ok(());
                }
                layers.swap(i, j as usize);
                (format!("Moved layer {:?} {}", layers[j as usize].name, if d > 0 { "down" } else { "up" }), j as usize)
            }
            Action::MergeDown => {
                if i + 1 >= layers.len() {
                    return Err("There is no layer below to merge into".into());
                }
                let upper = layers.remove(i);
                let lower = &mut layers[i];
                if lower.locked {
                    return Err(format!("Layer {:?} is locked", lower.name));
                }
                merge_into(&upper, lower)?;
                (format!("Merged {:?} into {:?}", upper.name, lower.name), i)
            }
            _ => unreachable!("only layer operations"),
        };
        // One undo step that restores the whole list.
        self.editor.replace_layers(layers, active);
        self.message = what;
        Ok(())
    }

    /// Reads the mesh at `path` for import and offers the resolution dialog.
    pub fn choose_import(&mut self, path: PathBuf) -> Result<(), String> {
        let mesh =
            strata_mesh::import::load_mesh(&path).map_err(|e| format!("Could not import {}: {e}", path.display()))?;
        let closed = strata_editor::import::is_closed(&mesh);
        self.pending_import = Some(PendingImport { path, mesh, cells: 256, closed });
        Ok(())
    }

    /// Starts converting the pending mesh on a worker thread.
    pub fn start_import(&mut self) -> Result<(), String> {
        let pending = self.pending_import.take().ok_or("No mesh is waiting to be imported")?;
        let plan = pending.plan().map_err(|e| format!("Could not import {}: {e}", pending.path.display()))?;
        let name = pending.path.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh").to_string();
        let control = std::sync::Arc::new(strata_volume::EditControl::default());
        let settings = strata_volume::EditSettings { control: Some(control.clone()), ..Default::default() };
        let (mesh, layer_name) = (pending.mesh, name.clone());
        let worker = std::thread::spawn(move || {
            strata_editor::import::convert(
                &mesh,
                &plan,
                strata_volume::brush::MeshRule::EvenOdd,
                &layer_name,
                &settings,
            )
        });
        self.import_job = Some(ImportJob { name, control, started: std::time::Instant::now(), worker });
        self.message = "Importing…".into();
        Ok(())
    }

    /// Collects a finished import (call every frame): the mesh becomes a new active layer, the
    /// camera frames it and the brush is sized to ten of its cells. Returns whether one finished.
    pub fn poll_import(&mut self) -> bool {
        if !self.import_job.as_ref().is_some_and(|j| j.worker.is_finished()) {
            return false;
        }
        let job = self.import_job.take().expect("checked above");
        let secs = job.started.elapsed().as_secs_f64();
        match job.worker.join().expect("the conversion does not panic") {
            Ok(layer) => {
                let cell = layer.transform.scale;
                let v = View::framing(std::iter::once(&layer));
                let mut layers = self.editor.scene.layers.clone();
                layers.push(layer);
                let n = layers.len();
                // An undo step: undo takes the imported layer away again.
                self.editor.replace_layers(layers, n - 1);
                self.editor.tool.radius = 10.0 * cell;
                self.camera.target = v.target.as_vec3();
                self.camera.distance = v.distance as f32;
                self.message = format!("Imported {:?} as a new layer in {secs:.1} s", job.name);
            }
            Err(strata_editor::import::ConvertError::Edit(strata_volume::EditError::Cancelled)) => {
                self.message = "Import cancelled".into();
            }
            Err(e) => self.fail(format!("Could not import {:?}: {e}", job.name)),
        }
        true
    }

    fn save_to(&mut self, path: &Path) -> Result<(), String> {
        self.editor.scene.view = strata_viewport::view_of(&self.camera);
        let report = file::save(&self.editor.scene, path)
            .map_err(|e: SceneFileError| format!("Could not save {}: {e}", path.display()))?;
        if report.is_clean() {
            self.message = format!("Saved {}", path.display());
        } else {
            // The file holds the repaired scene: show the same (the history, which refers to
            // the unrepaired volumes, starts anew).
            let mut scene = self.editor.scene.clone();
            file::validate_scene(&mut scene);
            let camera = self.camera;
            self.replace_scene(scene);
            self.camera = camera;
            self.message = format!("Saved {} with repairs (history cleared): {report}", path.display());
        }
        self.mark_saved();
        Ok(())
    }

    fn replace_scene(&mut self, scene: Scene) {
        self.camera = strata_viewport::camera_of(&scene.view);
        self.editor.set_scene(scene);
    }

    /// One frame of pointer input over the viewport: `ndc` the pointer in normalised device
    /// coordinates (`None` when outside), the buttons held, and the viewport's aspect ratio.
    /// The tool acts at the surface under the pointer (or on the ground plane when nothing is
    /// hit) while a button is held; a stroke keeps its depth when it leaves the surface.
    pub fn pointer(&mut self, ndc: Option<(f32, f32)>, buttons: Buttons, pressure: f64, aspect: f32, budget: Duration) {
        self.update_lod();
        // Holding Shift smooths, whatever the tool; Ctrl or Alt inverts it (the sculptors'
        // conventions): the pose says so, the tool and the buttons stay as they are.
        let modifiers = Modifiers { inverted: self.inverse_held, smooth: self.smooth_held };
        if self.eyedropper && self.job.is_none() {
            self.eyedropper_click(ndc, buttons, aspect);
        } else if self.line_mode && self.job.is_none() {
            self.line_click(ndc, buttons, modifiers, pressure, aspect);
        } else {
            self.pointer_with_tool(ndc, buttons, modifiers, pressure, aspect, budget);
        }
        self.prev_held = buttons.primary || buttons.secondary;
    }

    /// Tells the editor where the camera is, for level of detail (when the view changed).
    pub fn update_lod(&mut self) {
        let view = self.lod.then(|| strata_editor::LodView {
            eye: self.camera.eye().as_dvec3(),
            pixels_per_radian: (self.viewport_height.max(1.0) / self.camera.fov_y.max(1e-3)) as f64,
            pixel_error: self.lod_pixels.max(0.1),
        });
        if view != self.last_lod {
            self.editor.set_view(view);
            self.last_lod = view;
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

    /// A frame of the armed eyedropper: a click on the model takes the material under it.
    fn eyedropper_click(&mut self, ndc: Option<(f32, f32)>, buttons: Buttons, aspect: f32) {
        let pick = ndc.and_then(|(x, y)| {
            let (o, d) = self.camera.ray(x, y, aspect);
            self.editor.pick(o.as_dvec3(), d.as_dvec3(), 1.0e4)
        });
        self.hover = pick.as_ref().map(|p| p.point);
        let held = buttons.primary || buttons.secondary;
        if !held || self.prev_held {
            return;
        }
        let Some(pick) = pick else { return };
        match self.editor.material_at(&pick) {
            Some(id) => {
                self.editor.tool.material = id;
                let name = self.editor.scene.materials.get(id as usize).map_or("?", |m| m.name.as_str());
                self.message = format!("Material: {name}");
            }
            None => self.message = "Eyedropper: no material there".into(),
        }
        self.eyedropper = false;
    }

    /// Adds a material to the palette (a copy of the current one) and makes it current.
    pub fn add_material(&mut self) -> Option<u8> {
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

    /// A frame of the armed line tool: the first click picks the line's start, the second its end
    /// and applies the stroke (one undo step).
    fn line_click(
        &mut self,
        ndc: Option<(f32, f32)>,
        buttons: Buttons,
        modifiers: Modifiers,
        pressure: f64,
        aspect: f32,
    ) {
        let target = ndc.and_then(|(x, y)| self.surface_point(x, y, aspect));
        self.hover = target;
        let held = buttons.primary || buttons.secondary;
        let (Some(p), true) = (target, held && !self.prev_held) else { return };
        match self.line_start.take() {
            None => {
                self.line_start = Some(p);
                self.message = "Line: click the other end".into();
            }
            Some(a) => {
                let modifiers = Modifiers { inverted: modifiers.inverted || !buttons.primary, ..modifiers };
                match self.editor.line_stroke(a, p, pressure, modifiers) {
                    Ok(report) => {
                        self.message = format!("Line: {} dabs", report.dabs);
                    }
                    Err(e) => self.fail(e.to_string()),
                }
                self.line_mode = false;
            }
        }
    }

    fn pointer_with_tool(
        &mut self,
        ndc: Option<(f32, f32)>,
        buttons: Buttons,
        modifiers: Modifiers,
        pressure: f64,
        aspect: f32,
        budget: Duration,
    ) {
        let held = buttons.primary || buttons.secondary;
        // A stroke follows the surface under the pointer, skipping what its own dabs built or
        // carved (`Editor::stroke_surface`); where that surface is hidden under the stroke's
        // own work, and always with "follow the surface" off or for grab, it keeps its depth.
        let ray = ndc.map(|(x, y)| {
            let (o, d) = self.camera.ray(x, y, aspect);
            (o.as_dvec3(), d.as_dvec3())
        });
        let follow = self.editor.tool.follow_surface && self.editor.tool.kind != ToolKind::Grab;
        let target = match (ray, self.stroke_depth.filter(|_| held)) {
            (Some((o, d)), Some(depth)) => {
                let depth = if follow && self.editor.stroking() {
                    self.editor.stroke_surface(o, d, 1.0e4).unwrap_or(depth)
                } else {
                    depth
                };
                self.stroke_depth = Some(depth);
                Some(o + d * depth)
            }
            (Some((o, d)), None) => {
                // One pick: the point under the pointer and its normal (for oriented brushes).
                let hit = self.editor.pick(o, d, 1.0e4);
                self.hover_normal = hit.map(|h| h.normal);
                let p = hit.map(|h| h.point).or_else(|| ground_point(o, d));
                if held {
                    self.stroke_depth = p.map(|p| (p - o).length());
                }
                p
            }
            (None, _) => None,
        };
        if !held {
            self.stroke_depth = None;
        }
        self.hover = target;
        self.apply_screen_radius(target);
        if self.job.is_some() {
            // A large dab is running: input waits for it (the app shows its progress).
            return;
        }
        if !held {
            self.last_background_dab = None;
        }
        if let Some(p) = target.filter(|_| held) {
            let pose = ToolPose { position: p, orientation: self.brush_orientation(), pressure, buttons, modifiers };
            if self.editor.dab_chunks(&pose).is_ok_and(|c| c > self.background_chunks) {
                // Like a stroke's dabs: the next large dab waits until the pointer has moved by
                // the dab spacing (holding still does not repeat it).
                let spacing = self.editor.tool.dab_spacing();
                if self.last_background_dab.is_some_and(|last| (p - last).length() < spacing) {
                    return;
                }
                self.last_background_dab = Some(p);
                match self.editor.start_dab_job(&pose) {
                    Ok(job) => {
                        self.job = Some(job);
                        self.message = "Sculpting a large dab…".into();
                    }
                    Err(e) => self.fail(e.to_string()),
                }
                return;
            }
        }
        let pose = match target {
            Some(p) if held => {
                ToolPose { position: p, orientation: self.brush_orientation(), pressure, buttons, modifiers }
            }
            _ => ToolPose {
                position: target.unwrap_or_default(),
                orientation: self.brush_orientation(),
                pressure,
                buttons: Buttons::default(),
                ..ToolPose::default()
            },
        };
        match self.editor.frame(&pose, budget) {
            Ok(report) => {
                if report.dabs > 0 {
                    self.last_edit_ms = report.edit_time.as_secs_f64() * 1e3;
                }
                if !report.remeshed.is_empty() {
                    self.last_remesh_ms = report.remesh_time.as_secs_f64() * 1e3;
                }
            }
            Err(e) => self.fail(e.to_string()),
        }
    }

    /// The brush's orientation for the next dab: onto the surface normal under the pointer
    /// when the alignment tool orients brushes, else the world's axes.
    pub fn brush_orientation(&self) -> DQuat {
        match self.hover_normal.filter(|_| self.editor.tool.orient_to_normal) {
            Some(n) => strata_editor::orientation_for_normal(n),
            None => DQuat::IDENTITY,
        }
    }

    /// Where the brush preview goes: the dab at the pointer and its mirror images, each as
    /// (world placement, erasing); the shape and radius are [`Studio::preview_mesh`]'s.
    pub fn preview_dabs(&self) -> Vec<(DVec3, DQuat)> {
        let Some(p) = self.hover else { return Vec::new() };
        let Some(layer) = self.editor.scene.layers.get(self.editor.active_layer) else { return Vec::new() };
        self.editor.tool.mirrored(&layer.transform, p, self.brush_orientation())
    }

    /// Collects a finished background dab (call every frame); returns whether one finished.
    pub fn poll_job(&mut self) -> bool {
        if !self.job.as_ref().is_some_and(|j| j.is_finished()) {
            return false;
        }
        let job = self.job.take().expect("checked above");
        let secs = job.elapsed().as_secs_f64();
        self.message = match self.editor.finish_dab_job(job) {
            Ok(changed) => format!("Large dab: {changed} chunks changed in {secs:.1} s"),
            Err(strata_editor::EditorError::Edit(strata_volume::EditError::Cancelled)) => {
                "Large dab cancelled: nothing changed".into()
            }
            Err(e) => {
                self.notice = Some(e.to_string());
                e.to_string()
            }
        };
        true
    }

    /// Whether a background dab or an import is running.
    pub fn busy(&self) -> bool {
        self.job.is_some() || self.import_job.is_some()
    }

    /// The world point the tool acts on under viewport point `(x, y)` (NDC): the first surface
    /// hit, or the ground plane y = 0 when nothing is hit.
    pub fn surface_point(&self, x: f32, y: f32, aspect: f32) -> Option<DVec3> {
        let (o, d) = self.camera.ray(x, y, aspect);
        self.ray_target(o.as_dvec3(), d.as_dvec3())
    }

    fn ray_target(&self, o: DVec3, d: DVec3) -> Option<DVec3> {
        self.editor.pick(o, d, 1.0e4).map(|hit| hit.point).or_else(|| ground_point(o, d))
    }

    /// The brush preview mesh for the current shape and radius (rebuilt when they change),
    /// centred on the origin, in world units.
    pub fn preview_mesh(&mut self) -> &Mesh {
        let mut tool = self.editor.tool;
        if tool.kind.is_field_tool() || self.smooth_held {
            // Field tools act in a ball of the radius, whatever the CSG shape.
            tool.shape = strata_editor::BrushShape::Sphere;
        }
        let key = (tool.shape, tool.radius.to_bits());
        if self.preview.as_ref().is_none_or(|(s, r, _)| (*s, *r) != key) {
            // Meshed 12 cells across its radius, whatever the radius, then scaled to world units.
            let scale = tool.radius / 12.0;
            let mut v = strata_volume::Volume::new();
            let mesh = match strata_editor::LayerTransform::new(DVec3::ZERO, DQuat::IDENTITY, scale) {
                Ok(t) => match tool.brush(&t, DVec3::ZERO, DQuat::IDENTITY, 1.0).map(|b| v.add(b.as_ref()).map(|_| ()))
                {
                    Ok(Ok(())) => {
                        let mut m = strata_mesh::mesh_volume(&v);
                        for p in &mut m.positions {
                            *p = p.map(|c| c * scale as f32);
                        }
                        m
                    }
                    _ => Mesh::default(),
                },
                Err(_) => Mesh::default(),
            };
            self.preview = Some((key.0, key.1, mesh));
        }
        &self.preview.as_ref().expect("set above").2
    }

    /// The status bar's live figures.
    pub fn status(&self) -> String {
        if let Some(t) = &self.terrain {
            return format!("{} · {}", self.message, t.status());
        }
        let scene = &self.editor.scene;
        let levels = scene
            .layers
            .get(self.editor.active_layer)
            .map(|l| {
                let counts = l.volume.level_counts();
                let parts: Vec<String> = counts
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| **c > 0)
                    .map(|(k, c)| format!("{c}×{}³", 16 << k))
                    .collect();
                if parts.is_empty() { String::new() } else { format!(" · chunks {}", parts.join(" ")) }
            })
            .unwrap_or_default();
        format!(
            "{}{levels} · memory {:.2} MiB · {} crossings · {} triangles · edit {:.2} ms · remesh {:.2} ms · {} chunks queued · history {} steps",
            self.message,
            scene.volume_bytes() as f64 / (1024.0 * 1024.0),
            scene.crossings(),
            self.editor.triangle_count(),
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
    }
}

/// Merges `upper` into `lower`: the union of `upper`'s solid, carried into `lower`'s grid, with
/// `lower`'s. The layers must share rotation and cell size; `upper`'s offset is rounded to whole
/// cells of `lower`'s grid (so the merge is exact on the grid).
/// Where the ray `o + t·d` meets the ground plane y = 0 in front of the eye, if it does.
fn ground_point(o: DVec3, d: DVec3) -> Option<DVec3> {
    (d.y < -1e-6).then(|| o + d * (-o.y / d.y))
}

fn merge_into(upper: &Layer, lower: &mut Layer) -> Result<(), String> {
    let (tu, tl) = (upper.transform, lower.transform);
    let same_turn = (tu.rotation.dot(tl.rotation).abs() - 1.0).abs() < 1e-9;
    if !same_turn || (tu.scale / tl.scale - 1.0).abs() > 1e-9 {
        return Err("Merge down needs two layers with the same rotation and cell size".into());
    }
    let offset = tl.to_grid(tu.translation).round().as_ivec3();
    lower.volume.merge_from(&upper.volume, offset, &Default::default()).map_err(|e| format!("Could not merge: {e}"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("strata-studio-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    const DOWN: Buttons = Buttons { primary: true, secondary: false };
    const BUDGET: Duration = Duration::from_millis(20);

    #[test]
    fn dragging_over_the_clay_sculpts_and_undo_takes_it_back() {
        let mut s = Studio::new(default_scene());
        let before = s.editor.scene.layers[0].volume.clone();
        // The centre of the view looks at the ball.
        let p = s.surface_point(0.0, 0.0, 1.5).expect("the ball is under the centre");
        assert!((p - DVec3::new(32.0, 18.0, 32.0)).length() < 16.5);
        for i in 0..10 {
            s.pointer(Some((i as f32 * 0.01, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        }
        s.pointer(Some((0.1, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        assert_eq!(s.editor.history().undo_len(), 1);
        let _ = s.editor.take_changes();
        s.pointer(Some((0.2, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        s.pointer(Some((0.3, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        let changes = s.editor.take_changes();
        assert!(!changes.full && !changes.meshes.is_empty(), "remeshed chunks are listed for upload");
        s.act(Action::Undo).unwrap();
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers[0].volume, before);
        s.act(Action::Redo).unwrap();
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        assert!(s.status().contains("crossings"));
    }

    #[test]
    fn a_stroke_does_not_climb_onto_its_own_material() {
        let mut s = Studio::new(default_scene());
        s.editor.tool.radius = 3.0;
        let start = s.surface_point(0.0, 0.0, 1.0).unwrap();
        // Holding still for many frames adds at the same place: nothing grows towards the eye.
        for _ in 0..30 {
            s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.0, BUDGET);
        }
        s.pointer(Some((0.0, 0.0)), Buttons::default(), 1.0, 1.0, BUDGET);
        let eye = s.camera.eye().as_dvec3();
        let front = s.surface_point(0.0, 0.0, 1.0).unwrap();
        let grown = (start - eye).length() - (front - eye).length();
        assert!(grown < 3.5, "the surface moved {grown} towards the eye (brush radius 3)");
        assert!(grown > 1.0, "the dab added material in front of the start ({grown})");
    }

    #[test]
    fn a_dab_too_large_for_a_frame_runs_in_the_background_and_can_be_cancelled() {
        let mut s = Studio::new(default_scene());
        s.background_chunks = 1;
        s.editor.tool.radius = 12.0;
        let before = s.editor.scene.layers[0].volume.clone();
        s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        assert!(s.busy(), "the dab runs on a worker");
        // Cancelled: nothing changes.
        s.job.as_ref().unwrap().cancel();
        while !s.poll_job() {
            std::thread::sleep(Duration::from_millis(2));
        }
        s.pointer(Some((0.0, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert!(!s.busy());
        assert_eq!(s.editor.scene.layers[0].volume, before, "a cancelled dab changes nothing: {}", s.message);
        assert_eq!(s.editor.history().undo_len(), 0);
        // Run to the end: one undo step.
        s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        while !s.poll_job() {
            std::thread::sleep(Duration::from_millis(2));
        }
        assert!(s.message.contains("chunks changed"), "{}", s.message);
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        // Holding still does not repeat the dab.
        s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        assert!(!s.busy());
        s.pointer(Some((0.0, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert_eq!(s.editor.history().undo_len(), 1);
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers[0].volume, before);
    }

    #[test]
    fn holding_shift_smooths_and_the_field_tools_sculpt_through_the_pointer() {
        let mut s = Studio::new(default_scene());
        s.editor.tool.radius = 5.0;
        // A bump to smooth away, under the centre of the view.
        let p = s.surface_point(0.0, 0.0, 1.5).unwrap();
        let g = s.editor.scene.layers[0].transform.to_grid(p);
        s.editor.scene.layers[0].volume.add(&Sphere::new(g, 2.5 / DEFAULT_CELL).unwrap()).unwrap();
        s.editor.reset_caches();
        let bumped = s.editor.scene.layers[0].volume.clone();
        s.smooth_held = true;
        for _ in 0..3 {
            s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        }
        s.pointer(Some((0.0, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert_eq!(s.editor.tool.kind, ToolKind::Clay, "Shift only lends the smooth tool");
        let smoothed = s.editor.scene.layers[0].volume.clone();
        assert_ne!(smoothed, bumped, "{}", s.message);
        smoothed.check_invariants().unwrap();
        s.smooth_held = false;
        for kind in [ToolKind::Inflate, ToolKind::Flatten, ToolKind::Pinch] {
            s.set_kind(kind);
            let before = s.editor.scene.layers[0].volume.clone();
            s.pointer(Some((0.05, 0.0)), DOWN, 1.0, 1.5, BUDGET);
            s.pointer(Some((0.05, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
            assert_ne!(s.editor.scene.layers[0].volume, before, "{kind:?}: {}", s.message);
        }
        for _ in 0..4 {
            s.act(Action::Undo).unwrap();
        }
        assert_eq!(s.editor.scene.layers[0].volume, bumped, "four strokes, four undo steps");
    }

    #[test]
    fn the_default_ball_is_smooth_and_grab_and_the_inverse_tool_work_through_the_pointer() {
        let mut s = Studio::new(default_scene());
        s.editor.finish_meshing();
        let triangles = s.editor.triangle_count();
        assert!(triangles >= 100_000, "the default ball has {triangles} triangles");
        let cells = s.editor.tool.radius / s.editor.scene.layers[0].transform.scale;
        assert!((cells - 10.0).abs() < 1e-9, "the default brush is 10 cells ({cells})");
        // Grab: press on the ball and drag sideways; the surface follows, as one step.
        let before = s.editor.scene.layers[0].volume.clone();
        s.set_kind(ToolKind::Grab);
        for i in 0..6 {
            s.pointer(Some((0.0, i as f32 * 0.01)), DOWN, 1.0, 1.5, BUDGET);
        }
        s.pointer(Some((0.0, 0.05)), Buttons::default(), 1.0, 1.5, BUDGET);
        let grabbed = s.editor.scene.layers[0].volume.clone();
        assert!(grabbed != before, "grab moved the surface: {}", s.message);
        grabbed.check_invariants().unwrap();
        assert_eq!(s.editor.history().undo_len(), 1);
        // Ctrl or Alt held: clay carves instead of adding.
        s.set_kind(ToolKind::Clay);
        s.inverse_held = true;
        let v0 = grabbed.measured_volume(strata_volume::Axis::X);
        s.pointer(Some((0.1, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        s.pointer(Some((0.1, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        let v1 = s.editor.scene.layers[0].volume.measured_volume(strata_volume::Axis::X);
        assert!(v1 < v0, "the inverse of clay carves: {v0} -> {v1}");
        // Oriented brushes follow the surface under the pointer.
        s.inverse_held = false;
        s.editor.tool.orient_to_normal = true;
        s.pointer(Some((0.2, 0.1)), Buttons::default(), 1.0, 1.5, BUDGET);
        let n = s.hover_normal.expect("the pointer is over the ball");
        assert!((s.brush_orientation() * DVec3::Y - n).length() < 1e-9);
    }

    #[test]
    fn merge_down_unites_moved_layers_and_refuses_turned_ones() {
        let mut s = Studio::new(default_scene());
        s.act(Action::DuplicateLayer).unwrap();
        assert_eq!(s.editor.active_layer, 1);
        // Move the copy 8 cells along x (and a little: the offset is rounded to whole cells).
        let cell = s.editor.scene.layers[1].transform.scale;
        s.editor.scene.layers[1].transform.translation.x += 8.2 * cell;
        s.act(Action::MoveLayer(-1)).unwrap();
        assert_eq!(s.editor.active_layer, 0);
        let (upper, lower) = (s.editor.scene.layers[0].clone(), s.editor.scene.layers[1].clone());
        s.act(Action::MergeDown).unwrap();
        assert_eq!(s.editor.scene.layers.len(), 1);
        assert_eq!(s.editor.history().undo_len(), 3, "duplicate, move and merge are undo steps");
        let merged = &s.editor.scene.layers[0].volume;
        merged.check_invariants().unwrap();
        let c = glam::I64Vec3::new(128, 72, 128);
        for x in -80..90 {
            let n = c + glam::I64Vec3::new(x, 0, 0);
            let want = lower.volume.node_inside(n) || upper.volume.node_inside(n - glam::I64Vec3::new(8, 0, 0));
            assert_eq!(merged.node_inside(n), want, "node {n}");
        }
        assert!(merged.node_inside(c + glam::I64Vec3::new(70, 0, 0)), "the moved copy reaches further");
        // Undo takes the merge back, then the move; redo merges again.
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers.len(), 2);
        assert!(s.editor.take_changes().full, "the layer list changed: everything is drawn anew");
        assert_eq!(s.editor.scene.layers[0].volume, upper.volume);
        s.act(Action::Redo).unwrap();
        assert_eq!(s.editor.scene.layers.len(), 1);
        let merged = s.editor.scene.layers[0].volume.clone();
        // A stroke after the merge, then undoing everything, restores the one ball.
        s.act(Action::Undo).unwrap();
        s.act(Action::Undo).unwrap();
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers.len(), 1);
        assert_eq!(s.editor.scene.layers[0].volume, lower.volume);
        for _ in 0..3 {
            s.act(Action::Redo).unwrap();
        }
        assert_eq!(s.editor.scene.layers[0].volume, merged);
        // Turned layers are not merged.
        s.act(Action::DuplicateLayer).unwrap();
        s.editor.scene.layers[1].transform.rotation = DQuat::from_rotation_y(0.3);
        s.act(Action::MoveLayer(-1)).unwrap();
        let err = s.act(Action::MergeDown).unwrap_err();
        assert!(err.contains("same rotation"), "{err}");
        assert_eq!(s.editor.scene.layers.len(), 2);
        // Nothing below the last layer.
        s.editor.active_layer = 1;
        assert!(s.act(Action::MergeDown).is_err());
    }

    #[test]
    fn mirroring_centres_on_the_model_and_mirrors_strokes() {
        let mut s = Studio::new(default_scene());
        s.editor.finish_meshing();
        s.toggle_symmetry(0);
        assert_eq!(s.editor.tool.symmetry, [true, false, false]);
        assert_eq!(s.editor.tool.symmetry_center.x, 32.0 / DEFAULT_CELL, "the ball's centre: {}", s.message);
        let before = s.editor.scene.layers[0].volume.clone();
        s.pointer(Some((0.3, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        s.pointer(Some((0.3, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        s.toggle_symmetry(0);
        assert_eq!(s.editor.tool.symmetry, [false; 3]);
    }

    #[test]
    fn the_line_tool_strokes_between_two_clicks() {
        let mut s = Studio::new(default_scene());
        s.editor.tool.radius = 2.0;
        let before = s.editor.scene.layers[0].volume.clone();
        s.toggle_line_tool();
        for x in [-0.2f32, 0.2] {
            s.pointer(Some((x, 0.1)), DOWN, 1.0, 1.5, BUDGET);
            s.pointer(Some((x, 0.1)), Buttons::default(), 1.0, 1.5, BUDGET);
        }
        assert!(!s.line_mode, "the second click ends the line tool");
        assert!(s.message.starts_with("Line:"), "{}", s.message);
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        assert_eq!(s.editor.history().undo_len(), 1, "one step");
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers[0].volume, before);
    }

    #[test]
    fn moving_a_layer_undoes_and_redraws() {
        let mut s = Studio::new(default_scene());
        let _ = s.editor.take_changes();
        let t0 = s.editor.scene.layers[0].transform;
        let moved = strata_editor::LayerTransform { translation: DVec3::new(3.0, 0.0, 0.0), ..t0 };
        s.editor.set_layer_transform(0, moved, false).unwrap();
        assert!(s.is_modified());
        assert_eq!(s.editor.take_changes().layers, vec![0], "the moved layer is drawn where it went");
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers[0].transform, t0);
        let changes = s.editor.take_changes();
        assert_eq!(changes.layers, vec![0], "the layer is drawn where it is now");
        assert!(!changes.full && changes.meshes.iter().all(|(l, _)| *l != 0));
        assert_eq!(s.editor.take_changes(), strata_editor::ChangeList::default(), "then nothing more");
    }

    #[test]
    fn radius_keys_wireframe_and_layers() {
        let mut s = Studio::new(default_scene());
        let r = s.editor.tool.radius;
        s.act(Action::ScaleRadius(1.25)).unwrap();
        assert!((s.editor.tool.radius - r * 1.25).abs() < 1e-12);
        s.act(Action::ScaleRadius(1e9)).unwrap();
        assert_eq!(s.editor.tool.radius, 256.0);
        s.act(Action::ToggleWireframe).unwrap();
        assert!(s.wireframe);
        s.act(Action::AddLayer).unwrap();
        assert_eq!((s.editor.scene.layers.len(), s.editor.active_layer), (2, 1));
        assert!(!s.preview_mesh().indices.is_empty());
    }

    #[test]
    fn files_save_open_and_fail_without_losing_the_scene() {
        let mut s = Studio::new(default_scene());
        assert!(s.act(Action::Save).is_err(), "no path yet");
        let path = temp("scene.strata");
        s.camera.yaw = 1.25;
        s.act(Action::SaveAs(path.clone())).unwrap();
        let saved = s.editor.scene.clone();
        s.act(Action::New).unwrap();
        s.act(Action::Open(path.clone())).unwrap();
        assert_eq!(s.editor.scene, saved);
        assert!((s.camera.yaw - 1.25).abs() < 1e-6, "the view comes back");
        // A truncated file fails and the open scene stays.
        let bad = temp("bad.strata");
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&bad, &bytes[..bytes.len() - 3]).unwrap();
        let err = s.act(Action::Open(bad.clone())).unwrap_err();
        assert!(err.contains("truncated"), "{err}");
        assert_eq!(s.editor.scene, saved);
        assert_eq!(s.path.as_deref(), Some(path.as_path()));
        // A damaged one opens with what could be recovered, saying so, and counts as unsaved.
        let mut damaged = bytes.clone();
        let n = damaged.len();
        damaged[n - 3] ^= 0xff;
        std::fs::write(&bad, damaged).unwrap();
        s.act(Action::Open(bad)).unwrap();
        assert!(s.message.contains("repairs") && s.message.contains("checksum"), "{}", s.message);
        assert!(s.is_modified());
        assert_eq!(s.editor.scene.layers, saved.layers);
        s.act(Action::Open(path.clone())).unwrap();
        // Export in every format.
        for ext in ["glb", "obj", "stl", "ply"] {
            s.act(Action::Export(temp(&format!("out.{ext}")))).unwrap();
        }
        assert!(s.act(Action::Export(temp("out.xyz"))).is_err());
    }
}

#[cfg(test)]
mod island_tests {
    use super::*;

    #[test]
    fn exports_drop_stray_islands_for_stl_by_default_and_say_so() {
        let dir = std::env::temp_dir().join(format!("strata-studio-specks-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut s = Studio::new(default_scene());
        // A speck: one solid node well away from the ball.
        let cell = s.editor.scene.layers[0].transform.scale;
        let speck = DVec3::new(90.0, 18.0, 32.0) / cell;
        s.editor.scene.layers[0].volume.add(&Sphere::new(speck.round(), 0.4).unwrap()).unwrap();
        let count = |path: &std::path::Path| strata_mesh::import::load_mesh(path).unwrap().triangles.len();
        let stl = dir.join("print.stl");
        s.act(Action::Export(stl.clone())).unwrap();
        assert!(s.message.contains("removed 1 islands"), "{}", s.message);
        let obj = dir.join("game.obj");
        s.act(Action::Export(obj.clone())).unwrap();
        assert!(!s.message.contains("islands"), "{}", s.message);
        assert!(count(&obj) > count(&stl), "the OBJ keeps the speck's triangles");
        s.islands = Islands::Keep;
        s.act(Action::Export(stl.clone())).unwrap();
        assert_eq!(count(&stl), count(&obj), "kept when asked");
        s.islands = Islands::Remove;
        s.act(Action::Export(obj.clone())).unwrap();
        assert!(s.message.contains("removed 1 islands"), "{}", s.message);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
