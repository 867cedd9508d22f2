//! Carrying out an [`Action`]: files (new, open, save, export), undo and redo, the brush's
//! radius, views, the viewport's mesher, layer operations and terrain worlds.

use super::*;

/// Merges `upper` into `lower`: the union of `upper`'s solid, carried into `lower`'s grid, with
/// `lower`'s. The layers must share rotation and cell size; `upper`'s offset is rounded to whole
/// cells of `lower`'s grid (so the merge is exact on the grid).
pub(super) fn merge_into(upper: &Layer, lower: &mut Layer) -> Result<(), String> {
    let (tu, tl) = (upper.transform, lower.transform);
    let same_turn = (tu.rotation.dot(tl.rotation).abs() - 1.0).abs() < 1e-9;
    if !same_turn || (tu.scale / tl.scale - 1.0).abs() > 1e-9 {
        return Err("Merge down needs two layers with the same rotation and cell size".into());
    }
    let offset = tl.to_grid(tu.translation).round().as_ivec3();
    lower.volume.merge_from(&upper.volume, offset, &Default::default()).map_err(|e| format!("Could not merge: {e}"))?;
    Ok(())
}

impl Studio {
    pub(super) fn try_act(&mut self, action: Action) -> Result<(), String> {
        if let Some(what) = action.scene_only() {
            self.refuse_in_world(what)?;
        }
        if let Some(what) = action.unshared() {
            self.refuse_in_session(what)?;
        }
        match action {
            Action::HostSession(params) => return self.host_session(params),
            Action::JoinSession(params) => return self.join_session(params),
            Action::LeaveSession => return self.leave_session(),
            Action::Undo if self.in_session() => return self.undo_in_session(),
            Action::Redo if self.in_session() => return self.redo_in_session(),
            Action::NewWorld(path, seed) => {
                let recipe = strata_terrain::Recipe::with_seed(seed);
                let materials = self.scene_editor().scene.materials.clone();
                let (mode, editor) =
                    crate::terrain::TerrainMode::create(&path, &recipe, self.world_settings.clone(), materials)
                        .map_err(|e| format!("Could not create the world {}: {e}", path.display()))?;
                self.enter_world(mode, editor)?;
                self.message = format!("New world {} from seed {seed}", path.display());
                self.world_path = Some(path);
                return Ok(());
            }
            Action::OpenWorld(path) => {
                let materials = self.scene_editor().scene.materials.clone();
                let (mode, editor) = crate::terrain::TerrainMode::open(&path, self.world_settings.clone(), materials)
                    .map_err(|e| format!("Could not open the world {}: {e}", path.display()))?;
                self.enter_world(mode, editor)?;
                self.message = format!("Opened the world {}", path.display());
                self.world_path = Some(path);
                return Ok(());
            }
            Action::CloseWorld => {
                let written = self.leave_world()?;
                self.message = format!("World written ({written} chunks); back to the scene");
                return Ok(());
            }
            Action::Bomb => {
                let t = self.terrain.as_mut().ok_or("Bombs need a world: Terrain > New world")?;
                t.bomb();
                return Ok(());
            }
            Action::SaveWorld => {
                let t = self.terrain.as_ref().ok_or("No world is open: Terrain > New world or Open world")?;
                if self.editor.world().is_some_and(|w| w.store().is_none()) {
                    return Err(
                        "This world is kept in memory here (a shared room's world): it has no file to write".into()
                    );
                }
                let written = t.save(&mut self.editor).map_err(|e| format!("Could not write the world: {e}"))?;
                self.message = format!("World written ({written} chunks)");
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
                // Shading normals as `strata export` writes them (creased for marching cubes).
                let (mesh, islands) = self
                    .editor
                    .export_mesh_shaded(options, strata_mesh::normals::DEFAULT_CREASE_DEGREES)
                    .map_err(|e| format!("Could not export: {e}"))?;
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
                // (The selection is by number: a picture added or deleted back renumbers them.)
                let pictures = self.editor.scene.references.len();
                let done = if undo { self.editor.try_undo() } else { self.editor.try_redo() }
                    .map_err(|e| format!("Could not {}: {e}", if undo { "undo" } else { "redo" }))?;
                if self.editor.scene.references.len() != pictures {
                    self.selected_reference = None;
                }
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
            Action::LoadStamp(path) => self.load_stamp(&path)?,
            Action::InsertFile(path) => self.insert_file(&path)?,
            Action::LoadReference(path) => self.load_reference(&path)?,
            Action::Mask(a) => {
                let layer = self.editor.active_layer;
                self.editor.mask_all(layer, a).map_err(|e| format!("Could not {}: {e}", a.name().to_lowercase()))?;
                self.message = format!("{} (layer {:?})", a.name(), self.editor.scene.layers[layer].name);
            }
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
    pub(super) fn layer_op(&mut self, action: Action) -> Result<(), String> {
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

    /// Saves the scene (while a world is open, the scene waiting for it) to `path`.
    pub(super) fn save_to(&mut self, path: &Path) -> Result<(), String> {
        let camera = self.scene_camera();
        let editor = self.scene_editor_mut();
        editor.scene.view = strata_viewport::view_of(&camera);
        let report = file::save(&editor.scene, path)
            .map_err(|e: SceneFileError| format!("Could not save {}: {e}", path.display()))?;
        if report.is_clean() {
            self.message = format!("Saved {}", path.display());
        } else {
            // The file holds the repaired scene: show the same (the history, which refers to
            // the unrepaired volumes, starts anew; the camera stays).
            let mut scene = editor.scene.clone();
            file::validate_scene(&mut scene);
            editor.set_scene(scene);
            self.message = format!("Saved {} with repairs (history cleared): {report}", path.display());
        }
        self.mark_saved();
        Ok(())
    }

    /// Refuses `what` (a scene command) while a world is open, saying how to get back.
    pub(super) fn refuse_in_world(&self, what: &str) -> Result<(), String> {
        match self.terrain {
            Some(_) => Err(format!("A world is open: Terrain > Close world first, then {what}")),
            None => Ok(()),
        }
    }

    /// Opens terrain mode on `editor`'s world: the scene's editor and camera wait in `mode`
    /// (a world already open is written and closed first).
    pub(super) fn enter_world(&mut self, mut mode: crate::terrain::TerrainMode, editor: Editor) -> Result<(), String> {
        if self.terrain.is_some() {
            self.leave_world()?;
        }
        if self.busy() {
            return Err("Wait for the large dab or the import to finish".into());
        }
        self.editor.end_stroke();
        let scene = std::mem::replace(&mut self.editor, editor);
        mode.scene = Some(Box::new((scene, self.camera)));
        self.camera = mode.camera();
        self.terrain = Some(mode);
        self.line_mode = false;
        self.line_start = None;
        self.editor.redraw_all();
        Ok(())
    }

    /// Writes the open world and goes back to the scene; returns the chunks written. (The
    /// world's history goes with it.)
    pub(super) fn leave_world(&mut self) -> Result<usize, String> {
        let Some(t) = self.terrain.as_mut() else { return Ok(0) };
        self.editor.end_stroke();
        let written = t.save(&mut self.editor).map_err(|e| format!("Could not write the world: {e}"))?;
        let mut t = self.terrain.take().expect("checked");
        // (A world that came from a shared room has no scene waiting: a new one then.)
        let (scene, camera) = match t.scene.take() {
            Some(waiting) => *waiting,
            None => {
                let scene = default_scene();
                let camera = strata_viewport::camera_of(&scene.view);
                (Editor::new(scene), camera)
            }
        };
        let world = std::mem::replace(&mut self.editor, scene);
        self.camera = camera;
        // Materials added or recoloured on the world are the scene's palette too.
        if world.scene.materials != self.editor.scene.materials {
            self.editor.scene.materials = world.scene.materials.clone();
            self.editor.touch();
        }
        self.world_path = None;
        self.line_mode = false;
        self.line_start = None;
        self.editor.redraw_all();
        Ok(written)
    }

    pub(super) fn replace_scene(&mut self, scene: Scene) {
        self.camera = strata_viewport::camera_of(&scene.view);
        self.selected_reference = None;
        self.editor.set_scene(scene);
    }
}
