//! Mesh inserts in the studio: a primitive, the bunny or a mesh file waits as a preview; a
//! press (or drag) on the model places it on the surface; the panel sizes and turns it; Add,
//! Subtract or Intersect applies it to the active layer as one undo step.

use strata_editor::{InsertMesh, Placement};
use strata_volume::CsgOp;

use super::*;

/// An insert waiting to be applied.
#[derive(Clone, Debug)]
pub struct PendingInsert {
    /// The mesh.
    pub mesh: InsertMesh,
    /// Where it goes (its rotation is made from `turn`).
    pub placement: Placement,
    /// Its turn about y, then x, then z (degrees), as the panel edits it.
    pub turn: [f64; 3],
}

impl PendingInsert {
    /// The placement's rotation from the turn.
    pub fn sync_rotation(&mut self) {
        let [y, x, z] = self.turn.map(f64::to_radians);
        self.placement.rotation = DQuat::from_euler(glam::EulerRot::YXZ, y, x, z);
    }
}

impl Studio {
    /// Makes `mesh` the insert waiting to be applied: in the middle of the view (or at the
    /// pointer's surface point), as large as the brush's diameter.
    pub fn begin_insert(&mut self, mesh: InsertMesh) {
        let position = self.hover.unwrap_or(self.camera.target.as_dvec3());
        let size = (2.0 * self.editor.tool.radius).max(1e-3);
        self.message = format!(
            "Insert {}: press on the model to place it, size and turn it in the panel, then Add, Subtract or Intersect (Escape cancels)",
            mesh.name()
        );
        self.insert = Some(PendingInsert {
            mesh,
            placement: Placement { position, rotation: DQuat::IDENTITY, size },
            turn: [0.0; 3],
        });
    }

    /// Reads a mesh file as the insert waiting to be applied.
    pub(super) fn insert_file(&mut self, path: &Path) -> Result<(), String> {
        let mesh =
            strata_mesh::import::load_mesh(path).map_err(|e| format!("Could not read {}: {e}", path.display()))?;
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        let insert = InsertMesh::new(&name, &mesh).map_err(|e| format!("Could not insert it: {e}"))?;
        self.begin_insert(insert);
        Ok(())
    }

    /// Applies the waiting insert to the active layer by `op` (it stays waiting when refused).
    pub fn apply_insert(&mut self, op: CsgOp) -> Result<(), String> {
        let Some(pending) = self.insert.as_ref() else { return Err("No insert is waiting".into()) };
        let layer = self.editor.active_surface();
        let done = self.editor.insert_mesh(layer, &pending.mesh, &pending.placement, op);
        let name = pending.mesh.name().to_string();
        done.map_err(|e| format!("Could not insert {name}: {e}"))?;
        self.insert = None;
        let how = match op {
            CsgOp::Add => "added",
            CsgOp::Subtract => "subtracted",
            CsgOp::Intersect => "intersected",
        };
        self.message = format!("{name} {how} (Ctrl+Z takes it back)");
        Ok(())
    }

    /// Drops the waiting insert.
    pub fn cancel_insert(&mut self) {
        if let Some(p) = self.insert.take() {
            self.message = format!("Insert {} cancelled", p.mesh.name());
        }
    }

    /// A press or drag with an insert waiting places it on the surface under the pointer.
    pub(super) fn place_insert(&mut self, ndc: Option<(f32, f32)>, held: bool, aspect: f32) {
        let target = ndc.and_then(|(x, y)| self.surface_point(x, y, aspect));
        self.hover = target;
        if let (true, Some(p), Some(insert)) = (held, target, self.insert.as_mut()) {
            insert.placement.position = p;
        }
    }
}
