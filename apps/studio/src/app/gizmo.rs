//! The transform gizmo: handles drawn over the viewport for the waiting mesh insert, the
//! active layer while the layer gizmo is on (`Ctrl+T`), or the selected reference image while
//! it is shown and unlocked. Drag an axis's arrow to move along it, its ring knob around the centre to
//! turn about it, the centre square to scale; hold Ctrl to snap (a cell of the active layer,
//! 15°, tenths of the size). A layer's or a reference's drag is one undo step.

use glam::{DQuat, DVec3};

use super::*;

/// The handle's length on screen (points).
const ARM: f32 = 80.0;
/// How near the pointer must press to a handle (points).
const GRAB: f32 = 10.0;
/// Snapped turns (degrees).
const TURN_SNAP: f64 = 15.0;

/// A gizmo handle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Handle {
    /// Move along a world axis.
    Move(usize),
    /// Turn about a world axis.
    Turn(usize),
    /// Scale about the centre.
    Scale,
}

/// What the gizmo moves.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Target {
    Insert,
    Reference(usize),
    Layer(usize),
}

/// A drag of a handle in progress.
#[derive(Clone, Copy, Debug)]
pub(super) struct GizmoDrag {
    handle: Handle,
    target: Target,
    /// Where the press was (screen).
    from: egui::Pos2,
    /// The pivot, turn and scale (or size) when it began.
    centre: DVec3,
    rotation: DQuat,
    scale: f64,
    /// The layer's translation when it began.
    translation: DVec3,
    /// Whether the drag has made its undo step yet.
    stepped: bool,
}

impl StudioApp {
    /// Shows or hides the gizmo for the active layer.
    pub fn toggle_layer_gizmo(&mut self) {
        self.layer_gizmo = !self.layer_gizmo;
        self.studio.message = if self.layer_gizmo {
            "Transform gizmo: drag an arrow to move the layer, a ring knob to turn it, the square to scale it (Ctrl snaps)"
                .into()
        } else {
            "Transform gizmo off".into()
        };
    }

    /// What the gizmo acts on, its pivot (world), turn and scale: the waiting insert, else the
    /// active layer while the layer gizmo is on (pivoting about the middle of its chunks), else
    /// the selected reference image while it is shown and unlocked.
    fn gizmo_target(&self) -> Option<(Target, DVec3, DQuat, f64)> {
        if let Some(i) = &self.studio.insert {
            return Some((Target::Insert, i.placement.position, i.placement.rotation, i.placement.size));
        }
        if self.studio.terrain.is_some() {
            return None;
        }
        if !self.layer_gizmo {
            let (i, r) =
                self.studio.reference().filter(|(_, r)| !r.locked && r.visible && self.studio.show_references)?;
            return Some((Target::Reference(i), r.center, r.rotation, r.width));
        }
        let k = self.studio.editor.active_layer;
        let layer = self.studio.editor.scene.layers.get(k)?;
        let t = layer.transform;
        let centre = match layer.volume.chunk_bounds_grid() {
            Some((lo, hi)) => t.to_world((lo + hi) * 0.5),
            None => t.translation,
        };
        Some((Target::Layer(k), centre, t.rotation, t.scale))
    }

    /// The gizmo's handles on screen: each handle, where its knob is, and (for the arrows and
    /// rings) the line from the centre it is drawn on; `None` without a target or with the
    /// centre behind the camera.
    pub fn gizmo_handles(&self, rect: egui::Rect) -> Option<(egui::Pos2, Vec<(Handle, egui::Pos2)>)> {
        let (_, centre, _, _) = self.gizmo_target()?;
        let aspect = rect.width() / rect.height().max(1.0);
        let project = |p: DVec3| -> Option<egui::Pos2> {
            let clip = self.studio.camera.view_proj(aspect) * p.as_vec3().extend(1.0);
            if clip.w <= 1e-6 {
                return None;
            }
            let (x, y) = (clip.x / clip.w, clip.y / clip.w);
            Some(egui::pos2(rect.left() + (x + 1.0) * 0.5 * rect.width(), rect.top() + (1.0 - y) * 0.5 * rect.height()))
        };
        let c = project(centre)?;
        // World units per point at the centre's depth, from the screen length of a unit step.
        let mut handles = Vec::new();
        for a in 0..3 {
            let axis = DVec3::AXES[a];
            let Some(tip) = project(centre + axis) else { continue };
            let per_unit = (tip - c).length();
            if per_unit < 1e-3 {
                // (An axis along the view has no length on screen: its arrow and ring are hidden.)
                continue;
            }
            let dir = (tip - c) / per_unit;
            handles.push((Handle::Move(a), c + dir * ARM));
            handles.push((Handle::Turn(a), c + dir * (ARM * 0.55)));
        }
        handles.push((Handle::Scale, c));
        Some((c, handles))
    }

    /// [`StudioApp::gizmo_handles`] in the viewport as last laid out.
    pub fn gizmo_on_screen(&self) -> Option<(egui::Pos2, Vec<(Handle, egui::Pos2)>)> {
        self.gizmo_handles(self.viewport_rect?)
    }

    /// The pointer on the gizmo: a press near a handle starts a drag, which moves, turns or
    /// scales its target until the release. Returns whether the gizmo took the pointer this
    /// frame (the tools then do not see it).
    pub(super) fn gizmo_input(&mut self, ui: &egui::Ui, rect: egui::Rect) -> bool {
        let (pressed, down, pos, snap) = ui.input(|i| {
            (i.pointer.primary_pressed(), i.pointer.primary_down(), i.pointer.interact_pos(), i.modifiers.command)
        });
        if let Some(drag) = self.gizmo_drag {
            match (down, pos) {
                (true, Some(p)) => self.gizmo_drag_to(drag, p, rect, snap),
                _ => self.gizmo_drag = None,
            }
            return true;
        }
        let (Some(p), true) = (pos, pressed) else { return false };
        if !rect.contains(p) || self.modal_open() {
            return false;
        }
        let Some((_, handles)) = self.gizmo_handles(rect) else { return false };
        let Some((target, centre, rotation, scale)) = self.gizmo_target() else { return false };
        let hit = handles
            .iter()
            .map(|&(h, at)| (h, at.distance(p)))
            .filter(|&(_, d)| d <= GRAB)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((handle, _)) = hit else { return false };
        if matches!(target, Target::Layer(_))
            && let Err(e) = self.studio.refuse_in_session("move, turn or scale a layer")
        {
            // (A layer's placement is not shared with a room: said, and the press is taken.)
            self.studio.fail(e);
            return true;
        }
        let translation = match target {
            Target::Layer(k) => self.studio.editor.scene.layers[k].transform.translation,
            Target::Insert | Target::Reference(_) => centre,
        };
        self.gizmo_drag =
            Some(GizmoDrag { handle, target, from: p, centre, rotation, scale, translation, stepped: false });
        true
    }

    /// One frame of a drag: the target as the drag from its start says.
    fn gizmo_drag_to(&mut self, mut drag: GizmoDrag, p: egui::Pos2, rect: egui::Rect, snap: bool) {
        let Some((c, handles)) = self.gizmo_handles(rect) else { return };
        let cell = self.studio.editor.surface(self.studio.editor.active_surface()).map_or(1.0, |s| s.transform().scale);
        let (mut centre, mut rotation, mut scale) = (drag.centre, drag.rotation, drag.scale);
        match drag.handle {
            Handle::Move(a) => {
                // The pointer's travel along the arrow's screen direction, in world units.
                let Some(&(_, tip)) = handles.iter().find(|(h, _)| *h == Handle::Move(a)) else { return };
                let dir = (tip - c) / ARM;
                let aspect = rect.width() / rect.height().max(1.0);
                let vp = self.studio.camera.view_proj(aspect);
                let screen = |w: DVec3| {
                    let clip = vp * w.as_vec3().extend(1.0);
                    egui::vec2(clip.x / clip.w * rect.width() * 0.5, -clip.y / clip.w * rect.height() * 0.5)
                };
                let per_unit = (screen(drag.centre + DVec3::AXES[a]) - screen(drag.centre)).length().max(1e-3);
                let mut along = ((p - drag.from).dot(dir) / per_unit) as f64;
                if snap {
                    along = (along / cell).round() * cell;
                }
                centre = drag.centre + DVec3::AXES[a] * along;
            }
            Handle::Turn(a) => {
                let angle_of = |q: egui::Pos2| (q.y - c.y).atan2(q.x - c.x) as f64;
                let mut turn = angle_of(p) - angle_of(drag.from);
                // Screen angles grow clockwise (y down); seen along an axis pointing at the
                // viewer, a counter-clockwise drag is a positive turn about it.
                let towards_viewer = (self.studio.camera.eye().as_dvec3() - drag.centre).dot(DVec3::AXES[a]) > 0.0;
                if towards_viewer {
                    turn = -turn;
                }
                if snap {
                    let step = TURN_SNAP.to_radians();
                    turn = (turn / step).round() * step;
                }
                rotation = DQuat::from_axis_angle(DVec3::AXES[a], turn) * drag.rotation;
            }
            Handle::Scale => {
                let d = p - drag.from;
                let mut factor = (((d.x - d.y) / 150.0) as f64).exp();
                if snap {
                    factor = ((factor * 10.0).round() / 10.0).max(0.1);
                }
                scale = drag.scale * factor;
            }
        }
        match drag.target {
            Target::Insert => {
                if let Some(i) = self.studio.insert.as_mut() {
                    i.placement.position = centre;
                    i.placement.rotation = rotation;
                    i.placement.size = scale;
                    // (The panel's turn numbers follow, so editing one keeps this turn.)
                    let (y, x, z) = rotation.to_euler(glam::EulerRot::YXZ);
                    i.turn = [y, x, z].map(f64::to_degrees);
                }
            }
            Target::Reference(k) => {
                let Some(r) = self.studio.editor.scene.references.get(k) else { return };
                let moved = strata_editor::ReferenceImage { center: centre, rotation, width: scale, ..r.clone() };
                // (As a layer's: the first change of a drag makes its undo step, the rest join it.)
                let before = r.clone();
                if self.studio.set_reference(k, moved.repaired(), drag.stepped) {
                    drag.stepped |= self.studio.editor.scene.references.get(k) != Some(&before);
                }
            }
            Target::Layer(k) => {
                // About the pivot: t' = c' + R' S' (R S)⁻¹ (t − c).
                let relative = drag.rotation.inverse() * (drag.translation - drag.centre) / drag.scale;
                let translation = centre + rotation * relative * scale;
                let transform = strata_editor::LayerTransform { translation, rotation, scale };
                // (A drag is one undo step: its first change makes the step, the rest join it; a
                // frame that changes nothing makes none, so it cannot join an older step.)
                let before = self.studio.editor.scene.layers.get(k).map(|l| l.transform);
                match self.studio.editor.set_layer_transform(k, transform, drag.stepped) {
                    Ok(()) => {
                        drag.stepped |= before != self.studio.editor.scene.layers.get(k).map(|l| l.transform);
                    }
                    Err(e) => self.studio.message = format!("Could not transform the layer: {e}"),
                }
            }
        }
        self.gizmo_drag = Some(drag);
    }

    /// Draws the gizmo over the viewport.
    pub(super) fn paint_gizmo(&self, ui: &egui::Ui, rect: egui::Rect) {
        let Some((c, handles)) = self.gizmo_handles(rect) else { return };
        let painter = ui.painter_at(rect);
        let colours = [
            egui::Color32::from_rgb(230, 80, 80),
            egui::Color32::from_rgb(90, 200, 90),
            egui::Color32::from_rgb(90, 140, 240),
        ];
        let active = self.gizmo_drag.map(|d| d.handle);
        for (h, at) in handles {
            let lit = active == Some(h);
            match h {
                Handle::Move(a) => {
                    painter.line_segment([c, at], egui::Stroke::new(if lit { 4.0 } else { 2.5 }, colours[a]));
                    painter.circle_filled(at, 6.0, colours[a]);
                }
                Handle::Turn(a) => {
                    painter.circle_stroke(at, 6.0, egui::Stroke::new(if lit { 3.5 } else { 2.0 }, colours[a]));
                }
                Handle::Scale => {
                    let r = egui::Rect::from_center_size(at, egui::vec2(10.0, 10.0));
                    painter.rect_filled(r, 1.0, if lit { egui::Color32::WHITE } else { egui::Color32::LIGHT_GRAY });
                }
            }
        }
    }
}
