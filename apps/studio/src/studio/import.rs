//! Importing a mesh as a new layer: the plan the import dialog shows, the conversion on a
//! worker thread, and the layer it adds (one undo step).

use super::*;

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

impl Studio {
    /// Reads the mesh at `path` for import and offers the resolution dialog (a mesh becomes a
    /// scene layer: refused while a world is open).
    pub fn choose_import(&mut self, path: PathBuf) -> Result<(), String> {
        self.refuse_in_world("import a mesh")?;
        self.refuse_in_session("import a mesh as a new layer")?;
        let mesh =
            strata_mesh::import::load_mesh(&path).map_err(|e| format!("Could not import {}: {e}", path.display()))?;
        let closed = strata_editor::import::is_closed(&mesh);
        self.pending_import = Some(PendingImport { path, mesh, cells: 256, closed });
        Ok(())
    }

    /// Starts converting the pending mesh on a worker thread.
    pub fn start_import(&mut self) -> Result<(), String> {
        self.refuse_in_world("import a mesh")?;
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
}
