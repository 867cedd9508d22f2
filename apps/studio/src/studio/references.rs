//! Reference images in the studio: loading a picture square to the view the camera is in,
//! selecting one (the gizmo then moves, turns and scales it while it is unlocked), laying it
//! square to another view, deleting it, and showing or hiding them all.

use super::*;
use strata_editor::{Picture, ReferenceImage, ReferencePlane};

impl Studio {
    /// The view a picture loaded now faces: the axis view the camera looks along (its plane,
    /// and whether it is the opposite view: back, left or bottom), else the front.
    pub fn reference_view(&self) -> (ReferencePlane, bool) {
        let c = &self.camera;
        let toward_eye = (c.eye() - c.target).normalize_or(glam::Vec3::Z);
        if toward_eye.y.abs() > 0.99 {
            (ReferencePlane::Top, toward_eye.y < 0.0)
        } else if toward_eye.x.abs() > 0.99 {
            (ReferencePlane::Side, toward_eye.x < 0.0)
        } else if toward_eye.z.abs() > 0.99 {
            (ReferencePlane::Front, toward_eye.z < 0.0)
        } else {
            (ReferencePlane::Front, false)
        }
    }

    /// Reads the picture at `path` (PNG or JPEG) as a reference image square to the view the
    /// camera is in, behind the visible layers, and selects it.
    pub(super) fn load_reference(&mut self, path: &Path) -> Result<(), String> {
        let picture = Picture::load(path).map_err(|e| format!("Could not load the reference image: {e}"))?;
        let (plane, opposite) = self.reference_view();
        let bounds = strata_editor::world_bounds(self.editor.scene.layers.iter().filter(|l| l.visible));
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        let (w, h, _) = picture.shown();
        let rotation = if opposite { plane.opposite_rotation() } else { plane.rotation() };
        let reference = ReferenceImage::facing(name.clone(), picture, rotation, bounds);
        let i = self.editor.add_reference(reference).map_err(|e| format!("Could not add the reference image: {e}"))?;
        self.selected_reference = Some(i);
        self.show_references = true;
        self.message = format!(
            "Reference image {name} ({w} × {h}) in the {} plane: the gizmo moves, turns and scales it; lock it, or click its name in the Reference images panel to put the gizmo away",
            plane.name().to_lowercase()
        );
        Ok(())
    }

    /// The selected reference image, if it still exists.
    pub fn reference(&self) -> Option<(usize, &ReferenceImage)> {
        let i = self.selected_reference?;
        self.editor.scene.references.get(i).map(|r| (i, r))
    }

    /// Replaces reference `i` (`merge`: a continuing drag joins its undo step); a refusal is
    /// said in the status bar.
    pub fn set_reference(&mut self, i: usize, reference: ReferenceImage, merge: bool) -> bool {
        match self.editor.set_reference(i, reference, merge) {
            Ok(()) => true,
            Err(e) => {
                self.message = format!("Could not change the reference image: {e}");
                false
            }
        }
    }

    /// Lays reference `i` square to `plane`, keeping its middle and width.
    pub fn lay_reference(&mut self, i: usize, plane: ReferencePlane) {
        let Some(r) = self.editor.scene.references.get(i) else { return };
        let laid = r.laid_to(plane);
        if self.set_reference(i, laid, false) {
            self.message = format!("Reference image square to the {} view", plane.name().to_lowercase());
        }
    }

    /// Deletes reference `i` (one undo step).
    pub fn delete_reference(&mut self, i: usize) {
        match self.editor.remove_reference(i) {
            Ok(r) => {
                self.selected_reference = None;
                self.message = if self.in_session() {
                    // (In a room, reference changes make no undo steps: Ctrl+Z is the room's.)
                    format!("Deleted the reference image {}", r.name)
                } else {
                    format!("Deleted the reference image {} (Ctrl+Z brings it back)", r.name)
                };
            }
            Err(e) => self.message = format!("Could not delete the reference image: {e}"),
        }
    }

    /// Shows or hides every reference image in the viewport (a view setting: the scene keeps
    /// each one's own shown flag).
    pub fn toggle_references(&mut self) {
        self.show_references = !self.show_references;
        let n = self.editor.scene.references.len();
        self.message = match (self.show_references, n) {
            (_, 0) => "No reference images: File > Load reference image… adds one".into(),
            (true, _) => format!("Reference images shown ({n})"),
            (false, _) => format!("Reference images hidden ({n})"),
        };
    }
}
