//! The editor: a scene, the tool, the stroke in progress, history and mesh caches.

use std::time::{Duration, Instant};

use glam::DVec3;
use std::sync::Arc;
use strata_mesh::islands::IslandReport;
use strata_mesh::{Mesh, MeshCache, MeshOptions, Mesher, MesherError, dual_contour_volume};
use strata_volume::brush::BrushError;

use strata_volume::{ChunkKey, EditControl, EditError, EditReport, EditSettings, Level, Volume};
use thiserror::Error;

use crate::history::{History, HistoryEntry};
use crate::lod::LodView;
use crate::pose::ToolPose;
use crate::scene::{Layer, Scene};
use crate::tool::{ToolKind, ToolSettings};
use crate::view_meshes::{ChangeList, ViewMeshes};

/// Why the editor refused something. The scene is unchanged.
#[derive(Debug, Error)]
pub enum EditorError {
    /// No layer with this index.
    #[error("there is no layer {0}")]
    NoLayer(usize),
    /// The layer is locked.
    #[error("layer {0} is locked")]
    Locked(usize),
    /// The layer's transform (set through its public fields) is not finite and invertible:
    /// nothing can be placed in its grid until it is repaired.
    #[error("layer {0} has a transform that is not finite and invertible")]
    BadLayerTransform(usize),
    /// A pose with NaN or infinite values.
    #[error("the tool pose is not finite")]
    BadPose,
    /// The tool's settings make no brush (zero or NaN radius, …).
    #[error(transparent)]
    Brush(#[from] BrushError),
    /// The edit was refused (too large, out of range).
    #[error(transparent)]
    Edit(#[from] EditError),
    /// A layer transform that is not finite and invertible.
    #[error(transparent)]
    Transform(#[from] crate::scene::TransformError),
    /// A field tool's dab was refused (a bad parameter, a region too large).
    #[error(transparent)]
    Tool(#[from] strata_volume::tools::ToolError),
    /// The mesher could not mesh a layer as asked (tetrahedra on mixed levels, a bad
    /// simplification bound).
    #[error(transparent)]
    Mesher(#[from] MesherError),
    /// The current material is not in the scene's palette.
    #[error("material {id} is not in the palette ({count} materials)")]
    UnknownMaterial {
        /// The tool's material.
        id: u8,
        /// Materials in the palette.
        count: usize,
    },
}

/// What one frame did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReport {
    /// Brush dabs applied this frame.
    pub dabs: usize,
    /// Time spent editing.
    pub edit_time: Duration,
    /// Time spent remeshing.
    pub remesh_time: Duration,
    /// Chunks remeshed this frame (their GPU buffers need uploading).
    pub remeshed: Vec<(usize, ChunkKey)>,
    /// Chunks still waiting for a remesh after this frame.
    pub pending: usize,
}

/// One dab applied on a worker thread ([`Editor::start_dab_job`]), for edits too large for a
/// frame: the layer's volume is with the worker until [`Editor::finish_dab_job`] takes it back.
#[derive(Debug)]
pub struct DabJob {
    layer: usize,
    control: Arc<EditControl>,
    started: Instant,
    worker: std::thread::JoinHandle<(Volume, Result<Vec<EditReport>, EditorError>)>,
}

impl DabJob {
    /// Chunks visited and to visit.
    pub fn progress(&self) -> (u64, u64) {
        self.control.progress()
    }

    /// Asks the worker to stop; [`Editor::finish_dab_job`] then restores the volume unchanged.
    pub fn cancel(&self) {
        self.control.cancel();
    }

    /// Whether the worker is done (finishing will not block).
    pub fn is_finished(&self) -> bool {
        self.worker.is_finished()
    }

    /// Time since the job started.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }
}

/// A surface point found by [`Editor::pick`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pick {
    /// The layer hit.
    pub layer: usize,
    /// Ray parameter of the hit (world units for a unit direction).
    pub t: f64,
    /// World point.
    pub point: DVec3,
    /// World outward normal.
    pub normal: DVec3,
}

struct Stroke {
    layer: usize,
    /// Where the last dab went (world, aligned).
    last: DVec3,
    /// The stroke's first position (world, before alignment): the axis lock's line.
    start: DVec3,
    /// A grab's centre (world): it follows the material it drags.
    anchor: DVec3,
    inverted: bool,
    /// The tool the stroke applies (the current tool, or smoothing while the pose says so).
    kind: ToolKind,
    records: Vec<strata_volume::UndoRecord>,
    /// Balls (world centre, radius) holding everything the stroke's dabs built or carved,
    /// mirror images included: the surface inside them is the stroke's own.
    own: Vec<(DVec3, f64)>,
}

impl Stroke {
    /// A stroke starting at `position` (aligned) for a pose at `start` (as given).
    fn new(layer: usize, position: DVec3, start: DVec3, inverted: bool, kind: ToolKind) -> Self {
        Stroke { layer, last: position, start, anchor: position, inverted, kind, records: Vec::new(), own: Vec::new() }
    }

    /// Whether world point `p` lies in one of the stroke's own balls.
    fn owns(&self, p: DVec3) -> bool {
        self.own.iter().any(|&(c, r)| (p - c).length_squared() <= r * r)
    }

    /// Where the ray `origin + t·dir` (unit `dir`), at `t` in the stroke's own balls, leaves
    /// their union.
    fn exit_own(&self, origin: DVec3, dir: DVec3, mut t: f64) -> f64 {
        // Each pass leaves every ball holding the point; a ball is left at most once, so the
        // loop ends within as many passes as there are balls.
        for _ in 0..=self.own.len() {
            let p = origin + dir * t;
            let mut next = t;
            for &(c, r) in &self.own {
                let off = p - c;
                if off.length_squared() <= r * r {
                    // The far root of |origin + s·dir − c| = r.
                    let b = (origin - c).dot(dir);
                    let disc = b * b - ((origin - c).length_squared() - r * r);
                    next = next.max(-b + disc.max(0.0).sqrt());
                }
            }
            if next <= t {
                return t;
            }
            // Just past the boundary, so the next pass does not find the same ball.
            t = next + 1e-9 * (1.0 + next.abs());
        }
        t
    }
}

/// The editor core: feed it one [`ToolPose`] per frame.
pub struct Editor {
    /// The scene being edited.
    pub scene: Scene,
    /// The current tool.
    pub tool: ToolSettings,
    /// The layer tools edit.
    pub active_layer: usize,
    history: History,
    stroke: Option<Stroke>,
    /// The viewport's meshes of every layer.
    meshes: ViewMeshes,
    settings: EditSettings,
    revision: u64,
    /// Counts changes of the layer list (see [`Editor::structure_revision`]).
    structure: u64,
}

impl std::fmt::Debug for Editor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Editor")
            .field("layers", &self.scene.layers.len())
            .field("tool", &self.tool)
            .field("active_layer", &self.active_layer)
            .field("history", &self.history)
            .finish()
    }
}

impl Default for Editor {
    fn default() -> Self {
        Editor::new(Scene::default())
    }
}

impl Editor {
    /// An editor on `scene`, every layer queued for meshing.
    pub fn new(scene: Scene) -> Self {
        let mut e = Editor {
            scene,
            tool: ToolSettings::default(),
            active_layer: 0,
            history: History::default(),
            stroke: None,
            meshes: ViewMeshes::new(MeshOptions::default(), &[]),
            settings: EditSettings::default(),
            revision: 0,
            structure: 0,
        };
        e.reset_caches();
        e
    }

    /// Replaces the scene (new or loaded): clears history and remeshes everything.
    pub fn set_scene(&mut self, scene: Scene) {
        self.scene = scene;
        self.revision += 1;
        self.history.clear();
        self.stroke = None;
        self.active_layer = 0;
        self.reset_caches();
    }

    /// Rebuilds the per-layer caches and queues every chunk (after layers are added or removed).
    pub fn reset_caches(&mut self) {
        self.meshes.reset(&self.scene.layers, false);
    }

    /// A number that changes whenever the scene does through the editor (edits, undo, redo, a
    /// new scene, [`Editor::touch`]): compare it with the value seen at the last save to know
    /// whether there is unsaved work.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Records a change made to the scene directly (a renamed, hidden or added layer), so that
    /// [`Editor::revision`] moves.
    pub fn touch(&mut self) {
        self.revision += 1;
    }

    /// Sets the history's memory budget (bytes), keeping what fits.
    pub fn set_history_budget(&mut self, bytes: usize) {
        let old = std::mem::replace(&mut self.history, History::with_budget(bytes));
        drop(old);
    }

    /// The history.
    pub fn history(&self) -> &History {
        &self.history
    }

    /// Whether a stroke is in progress.
    pub fn stroking(&self) -> bool {
        self.stroke.is_some()
    }

    /// One frame: applies the tool along the path from the previous pose (dabs every
    /// [`ToolSettings::dab_spacing`]), ends the stroke when no button is held (one undo step per
    /// stroke), then remeshes queued chunks until `remesh_budget` is spent.
    pub fn frame(&mut self, pose: &ToolPose, remesh_budget: Duration) -> Result<FrameReport, EditorError> {
        if !pose.is_valid() {
            return Err(EditorError::BadPose);
        }
        let mut report = FrameReport::default();
        let t0 = Instant::now();
        let down = pose.buttons.primary || pose.buttons.secondary;
        let result = if down { self.stroke_to(pose, &mut report) } else { Ok(()) };
        if !down || result.is_err() {
            self.end_stroke();
        }
        report.edit_time = t0.elapsed();
        self.remesh(remesh_budget, &mut report);
        result.map(|_| report)
    }

    /// Whether the tools may edit layer `layer` through its transform: it exists, is not
    /// locked, and its transform is valid.
    fn check_editable(&self, layer: usize) -> Result<(), EditorError> {
        let l = self.scene.layers.get(layer).ok_or(EditorError::NoLayer(layer))?;
        if l.locked {
            return Err(EditorError::Locked(layer));
        }
        if !l.transform.is_valid() {
            return Err(EditorError::BadLayerTransform(layer));
        }
        Ok(())
    }

    fn stroke_to(&mut self, pose: &ToolPose, report: &mut FrameReport) -> Result<(), EditorError> {
        let layer = self.active_layer;
        self.check_editable(layer)?;
        self.check_material()?;
        let inverted = pose.inverted();
        let tool = self.tool_for(pose);
        let spacing = tool.dab_spacing();
        let transform = self.scene.layers[layer].transform;
        let continuing =
            matches!(&self.stroke, Some(s) if s.layer == layer && s.inverted == inverted && s.kind == tool.kind);
        if !continuing {
            self.end_stroke();
        }
        let start = self.stroke.as_ref().map(|s| s.start);
        let position = tool.aligned(&transform, pose.position, start);
        if tool.kind == ToolKind::Grab {
            return self.grab_to(layer, position, pose, &tool, report);
        }
        let mut dabs = Vec::new();
        match &self.stroke {
            Some(s) => {
                let d = position - s.last;
                let len = d.length();
                let steps = (len / spacing).floor() as usize;
                // A jump of more than 10,000 dabs is a teleport, not a stroke: dab at the end only.
                if steps > 10_000 {
                    dabs.push(position);
                } else {
                    dabs.extend(
                        (1..=steps).map(|k| tool.aligned(&transform, s.last + d * (k as f64 * spacing / len), start)),
                    );
                }
            }
            None => {
                self.stroke = Some(Stroke::new(layer, position, pose.position, inverted, tool.kind));
                dabs.push(position);
            }
        }
        let op = tool.kind.op(inverted);
        for p in dabs {
            let last = self.stroke.as_ref().map_or(p, |s| s.last);
            let images = tool.mirrored(&transform, p, pose.orientation);
            // (The same images, in the same order, each with the stroke's direction.)
            let directions = tool.mirrored_directions(&transform, p, p - last);
            for (k, (at, orientation)) in images.into_iter().enumerate() {
                let (edit, reach) = if tool.kind.is_field_tool() {
                    let direction = directions.get(k).map(|&(_, v)| v).filter(|v| v.length() > 1e-9);
                    let l = &mut self.scene.layers[layer];
                    let edit =
                        field_tool_dab(&tool, &l.transform, &mut l.volume, at, pose.pressure, inverted, direction)?;
                    // Clay's and inflate's change stays within the ball; a tenth more covers the
                    // surface it moved.
                    (edit, tool.radius_at(pose.pressure) * 1.1)
                } else {
                    let brush = tool.brush(&transform, at, orientation, pose.pressure)?;
                    let settings = EditSettings { material: tool.material, ..self.settings.clone() };
                    let b = brush.bounds();
                    // The ball around the brush's box (grid units to world).
                    let reach = 0.5 * (b.max - b.min).length() * transform.scale * 1.05;
                    (self.scene.layers[layer].volume.apply(op, brush.as_ref(), &settings)?, reach)
                };
                self.record(layer, edit);
                if tool.kind.builds_or_carves() {
                    let s = self.stroke.as_mut().expect("a stroke is in progress");
                    s.own.push((at, reach));
                }
            }
            let s = self.stroke.as_mut().expect("a stroke is in progress");
            s.last = p;
            report.dabs += 1;
        }
        Ok(())
    }

    /// A frame of the grab tool: the surface under the stroke's anchor is dragged by the
    /// pointer's move since the last frame (mirrored under symmetry), and the anchor follows it.
    fn grab_to(
        &mut self,
        layer: usize,
        position: DVec3,
        pose: &ToolPose,
        tool: &ToolSettings,
        report: &mut FrameReport,
    ) -> Result<(), EditorError> {
        let inverted = pose.inverted();
        let Some(s) = &self.stroke else {
            self.stroke = Some(Stroke::new(layer, position, pose.position, inverted, tool.kind));
            return Ok(());
        };
        let drag = position - s.last;
        if drag.length_squared() == 0.0 {
            return Ok(());
        }
        let anchor = s.anchor;
        let transform = self.scene.layers[layer].transform;
        // Grab follows the pointer one to one: the material under the anchor moves as far as
        // the pointer (the falloff takes the rest of the ball along less far).
        let strength = 1.0;
        let radius = tool.radius_at(pose.pressure) / transform.scale;
        let mut done: Vec<EditReport> = Vec::new();
        for (at, d) in tool.mirrored_with_vector(&transform, anchor, drag) {
            let result = strata_volume::tools::Dab::new(transform.to_grid(at), radius, strength).and_then(|dab| {
                let volume = &mut self.scene.layers[layer].volume;
                strata_volume::tools::grab(volume, &dab, transform.rotation.inverse() * d / transform.scale)
            });
            match result {
                Ok(edit) => done.push(edit),
                Err(e) => {
                    // A refused drag changes nothing, mirrored images included.
                    for edit in done.into_iter().rev() {
                        self.scene.layers[layer].volume.restore(edit.undo);
                    }
                    return Err(e.into());
                }
            }
        }
        for edit in done {
            self.record(layer, edit);
        }
        let s = self.stroke.as_mut().expect("a stroke is in progress");
        s.last = position;
        s.anchor = anchor + drag * strength;
        report.dabs += 1;
        Ok(())
    }

    /// The tool a pose applies: the current tool, or smoothing with its settings while the
    /// pose's modifiers say smooth (Shift in the studio).
    fn tool_for(&self, pose: &ToolPose) -> ToolSettings {
        let mut tool = self.tool;
        if pose.modifiers.smooth {
            tool.kind = ToolKind::Smooth;
        }
        tool
    }

    /// Refuses a current material the palette does not have.
    fn check_material(&self) -> Result<(), EditorError> {
        let count = self.scene.materials.len();
        if self.tool.material as usize >= count {
            return Err(EditorError::UnknownMaterial { id: self.tool.material, count });
        }
        Ok(())
    }

    /// The material of the solid under a pick (the eyedropper): the nearest solid node of the
    /// cell just inside the picked surface.
    pub fn material_at(&self, pick: &Pick) -> Option<strata_volume::MaterialId> {
        let l = self.scene.layers.get(pick.layer)?;
        let inward = l.transform.dir_to_grid(-pick.normal).normalize_or_zero();
        let p = l.transform.to_grid(pick.point) + inward * 0.25 * l.volume.level().spacing();
        l.volume.material_near(p)
    }

    /// Queues an edit of the stroke in progress for meshing and keeps its undo record.
    fn record(&mut self, layer: usize, edit: EditReport) {
        self.queue(layer, &edit.changed, edit.reach);
        self.revision += 1;
        let s = self.stroke.as_mut().expect("a stroke is in progress");
        s.records.push(edit.undo);
    }

    /// Chunks the dab of the current tool at `pose` would visit (its brush box in chunks, or
    /// the whole volume for an intersection): what the studio compares with its frame budget.
    pub fn dab_chunks(&self, pose: &ToolPose) -> Result<u64, EditorError> {
        let layer = self.active_layer;
        let l = self.scene.layers.get(layer).ok_or(EditorError::NoLayer(layer))?;
        if !l.transform.is_valid() {
            return Err(EditorError::BadLayerTransform(layer));
        }
        let brush = self.tool_for(pose).brush(&l.transform, pose.position, pose.orientation, pose.pressure)?;
        let b = brush.bounds();
        if !b.is_valid() {
            return Err(EditorError::Edit(EditError::BadBounds));
        }
        let c = strata_volume::coords::CHUNK_CELLS as f64;
        let side = |i: usize| ((b.max[i] / c).floor() - (b.min[i] / c).floor() + 3.0).min(1e7);
        Ok((side(0) * side(1) * side(2)) as u64)
    }

    /// Starts the dab of the current tool at `pose` (the opposite tool with the secondary
    /// button) on a worker thread, as its own undo step; the stroke in progress ends first. The
    /// active layer's volume goes with the worker, so nothing else may edit or mesh that layer
    /// until [`Editor::finish_dab_job`].
    pub fn start_dab_job(&mut self, pose: &ToolPose) -> Result<DabJob, EditorError> {
        if !pose.is_valid() {
            return Err(EditorError::BadPose);
        }
        self.end_stroke();
        let layer = self.active_layer;
        self.check_editable(layer)?;
        self.check_material()?;
        let tool = self.tool_for(pose);
        let l = &mut self.scene.layers[layer];
        let inverted = pose.inverted();
        let op = tool.kind.op(inverted);
        let mut dabs = Vec::new();
        for (at, orientation) in tool.mirrored(&l.transform, pose.position, pose.orientation) {
            dabs.push((at, tool.brush(&l.transform, at, orientation, pose.pressure)?));
        }
        let placeholder = Volume::with_level(l.volume.level());
        let mut volume = std::mem::replace(&mut l.volume, placeholder);
        let control = Arc::new(EditControl::default());
        let settings =
            EditSettings { control: Some(control.clone()), material: tool.material, ..self.settings.clone() };
        let (transform, pressure) = (l.transform, pose.pressure);
        if tool.kind == ToolKind::Grab {
            // A grab drags with the pointer: a single dab has nothing to drag.
            dabs.clear();
        }
        let worker = std::thread::spawn(move || {
            let mut done: Vec<EditReport> = Vec::new();
            for (at, brush) in dabs {
                // (A field tool's dab cannot stop half-way; a cancel is honoured when it ends.)
                let result = if tool.kind.is_field_tool() {
                    field_tool_dab(&tool, &transform, &mut volume, at, pressure, inverted, None)
                        .map_err(EditorError::from)
                } else {
                    volume.apply(op, brush.as_ref(), &settings).map_err(EditorError::from)
                };
                match result {
                    Ok(edit) => done.push(edit),
                    Err(e) => {
                        // Take back the images already applied: a failed dab changes nothing.
                        for edit in done.into_iter().rev() {
                            volume.restore(edit.undo);
                        }
                        return (volume, Err(e));
                    }
                }
            }
            (volume, Ok(done))
        });
        Ok(DabJob { layer, control, started: Instant::now(), worker })
    }

    /// Waits for `job`, puts the layer's volume back and, if the edit went through, records it
    /// as one undo step and queues its chunks for meshing. A cancelled or failed edit leaves the
    /// volume as it was and returns its error.
    pub fn finish_dab_job(&mut self, job: DabJob) -> Result<usize, EditorError> {
        let (mut volume, mut result) = match job.worker.join() {
            Ok(r) => r,
            Err(panic) => std::panic::resume_unwind(panic),
        };
        if job.control.is_cancelled() {
            // Cancelled after the worker had already finished: undo what it did, so a cancel
            // always means nothing changed.
            if let Ok(edits) = result {
                for edit in edits.into_iter().rev() {
                    volume.restore(edit.undo);
                }
            }
            result = Err(EditorError::Edit(EditError::Cancelled));
        }
        let layer = job.layer;
        if let Some(l) = self.scene.layers.get_mut(layer) {
            l.volume = volume;
        }
        let edits = result?;
        let mut changed = 0;
        let mut records = Vec::with_capacity(edits.len());
        for edit in edits {
            changed += edit.changed.len();
            self.queue(layer, &edit.changed, edit.reach);
            records.push(edit.undo);
        }
        self.revision += 1;
        self.history.push(HistoryEntry { layer, records, transform: None, layers: None });
        Ok(changed)
    }

    /// Applies `brush` (grid coordinates of the layer) to layer `layer` as one undo step, with
    /// its chunks queued for meshing: how imports and scripted edits change a scene. (Edits made
    /// straight on `scene.layers[i].volume` bypass the history, whose records would then
    /// restore stale chunks: call [`Editor::clear_history`] after any.)
    pub fn apply(
        &mut self,
        layer: usize,
        op: strata_volume::CsgOp,
        brush: &dyn strata_volume::brush::Brush,
    ) -> Result<EditReport, EditorError> {
        self.end_stroke();
        let l = self.scene.layers.get_mut(layer).ok_or(EditorError::NoLayer(layer))?;
        if l.locked {
            return Err(EditorError::Locked(layer));
        }
        let settings = EditSettings { material: self.tool.material, ..self.settings.clone() };
        let mut edit = l.volume.apply(op, brush, &settings)?;
        self.queue(layer, &edit.changed, edit.reach);
        self.revision += 1;
        // The history keeps the undo record; the report returned has an empty one.
        self.history.push(HistoryEntry {
            layer,
            records: vec![std::mem::take(&mut edit.undo)],
            transform: None,
            layers: None,
        });
        Ok(edit)
    }

    /// Moves, turns or scales layer `layer` to `transform` (checked as [`LayerTransform::new`]
    /// checks it) as an undo step. With `merge`, a change that continues the newest step (a
    /// transform change of the same layer, as while a value is dragged) joins it, so the whole
    /// drag is one step.
    pub fn set_layer_transform(
        &mut self,
        layer: usize,
        transform: crate::scene::LayerTransform,
        merge: bool,
    ) -> Result<(), EditorError> {
        let checked = crate::scene::LayerTransform::new(transform.translation, transform.rotation, transform.scale)?;
        self.end_stroke();
        let l = self.scene.layers.get_mut(layer).ok_or(EditorError::NoLayer(layer))?;
        let old = std::mem::replace(&mut l.transform, checked);
        if old != checked {
            if !(merge && self.history.last_is_transform_of(layer)) {
                self.history.push(HistoryEntry { layer, records: Vec::new(), transform: Some(old), layers: None });
            }
            self.revision += 1;
        }
        Ok(())
    }

    /// Forgets every undo and redo step (after the scene was changed outside the editor).
    pub fn clear_history(&mut self) {
        self.end_stroke();
        self.history.clear();
    }

    /// The line tool: a straight stroke of the current tool from world point `a` to `b`, dabs
    /// evenly spaced by the tool's dab spacing (mirrored under symmetry), as one undo step.
    /// `modifiers` act as in a dragged stroke (the inverse tool, smoothing).
    pub fn line_stroke(
        &mut self,
        a: DVec3,
        b: DVec3,
        pressure: f64,
        modifiers: crate::pose::Modifiers,
    ) -> Result<FrameReport, EditorError> {
        let pose = |p: DVec3| ToolPose {
            position: p,
            orientation: glam::DQuat::IDENTITY,
            pressure,
            buttons: Default::default(),
            ..ToolPose::default()
        };
        if !(pose(a).is_valid() && pose(b).is_valid()) {
            return Err(EditorError::BadPose);
        }
        self.end_stroke();
        let buttons = crate::pose::Buttons { primary: true, secondary: false };
        let pose =
            |p: DVec3| ToolPose { position: p, orientation: glam::DQuat::IDENTITY, pressure, buttons, modifiers };
        let mut report = self.frame(&pose(a), Duration::ZERO)?;
        let end = self.frame(&pose(b), Duration::ZERO)?;
        report.dabs += end.dabs;
        report.edit_time += end.edit_time;
        report.remeshed.extend(end.remeshed);
        self.end_stroke();
        Ok(report)
    }

    /// Ends the stroke in progress, making it one undo step.
    pub fn end_stroke(&mut self) {
        if let Some(s) = self.stroke.take() {
            self.history.push(HistoryEntry { layer: s.layer, records: s.records, transform: None, layers: None });
        }
    }

    /// Undoes the newest step. Returns whether anything changed.
    pub fn undo(&mut self) -> bool {
        self.end_stroke();
        let changed = self.history.undo(&mut self.scene.layers, &mut self.active_layer);
        self.after_history(changed)
    }

    /// Redoes the newest undone step. Returns whether anything changed.
    pub fn redo(&mut self) -> bool {
        self.end_stroke();
        let changed = self.history.redo(&mut self.scene.layers, &mut self.active_layer);
        self.after_history(changed)
    }

    fn after_history(&mut self, restored: Option<crate::history::Restored>) -> bool {
        let Some(restored) = restored else { return false };
        self.revision += 1;
        match restored {
            // Only the restored chunks changed: remesh them and the chunks that read them.
            crate::history::Restored::Chunks(layer, keys) => self.queue(layer, &keys, None),
            crate::history::Restored::Layers => {
                self.reset_caches();
                self.structure += 1;
            }
        }
        true
    }

    /// Replaces the layer list with `layers` and the active layer with `active` as one undo
    /// step: how layers are added, deleted, duplicated, reordered and merged. The other steps
    /// keep referring to the right layers: undoing this one restores the list they were made on.
    pub fn replace_layers(&mut self, layers: Vec<Layer>, active: usize) {
        self.end_stroke();
        let old = std::mem::replace(&mut self.scene.layers, layers);
        let old_active =
            std::mem::replace(&mut self.active_layer, active.min(self.scene.layers.len().saturating_sub(1)));
        self.history.push(HistoryEntry { layers: Some((old, old_active)), ..Default::default() });
        self.reset_caches();
        self.revision += 1;
        self.structure += 1;
    }

    /// Changes whenever the layer list is replaced or restored by undo or redo (a renderer's
    /// layers must then be uploaded anew).
    pub fn structure_revision(&self) -> u64 {
        self.structure
    }

    /// Queues the meshes an edit of `layer` that changed `changed` within `reach` (`None`:
    /// anywhere in them) affects.
    fn queue(&mut self, layer: usize, changed: &[ChunkKey], reach: Option<strata_volume::Reach>) {
        self.meshes.queue(layer, &self.scene.layers[layer].volume, changed, reach);
    }

    /// Remeshes queued chunks until `budget` is spent and shows what can be shown without a
    /// crack (see [`crate::view_meshes`]).
    fn remesh(&mut self, budget: Duration, report: &mut FrameReport) {
        let t0 = Instant::now();
        let (shown, pending) = self.meshes.remesh(&self.scene.layers, budget);
        report.remeshed.extend(shown);
        report.remesh_time = t0.elapsed();
        report.pending = pending;
    }

    /// Level of detail by camera distance: with a view, every list chunk of every layer is
    /// meshed at the coarsest level whose cell looks no larger than the view's pixel error from
    /// the eye (see [`LodView`]); chunks whose level changes are queued with their neighbours.
    /// `None` meshes everything at its stored level.
    pub fn set_view(&mut self, view: Option<LodView>) {
        self.meshes.set_view(&self.scene.layers, view);
    }

    /// The level-of-detail cap of a chunk of a layer (`None`: meshed at its stored level).
    pub fn lod_level(&self, layer: usize, key: ChunkKey) -> Option<Level> {
        self.meshes.lod_level(layer, key)
    }

    /// Remeshes everything queued, whatever it takes (before a screenshot or an export).
    pub fn finish_meshing(&mut self) -> Vec<(usize, ChunkKey)> {
        let mut report = FrameReport::default();
        self.remesh(Duration::MAX, &mut report);
        report.remeshed
    }

    /// Chunks waiting for a remesh, or remeshed and waiting for their neighbours to be shown.
    pub fn pending(&self) -> usize {
        self.meshes.pending()
    }

    /// Whether chunk `key` of layer `layer` waits for a remesh or to be shown.
    pub fn is_pending(&self, layer: usize, key: ChunkKey) -> bool {
        self.meshes.is_pending(layer, key)
    }

    /// The block mesh cache of a layer (marching cubes or tetrahedra; `None` while the viewport
    /// dual-contours).
    pub fn mesh_cache(&self, layer: usize) -> Option<&MeshCache> {
        self.meshes.mesh_cache(layer)
    }

    /// The viewport's mesher and per-chunk simplification.
    pub fn view_mesher(&self) -> MeshOptions {
        self.meshes.options()
    }

    /// Meshes the viewport with `options` from now on (every chunk is queued again). Per-chunk
    /// simplification keeps each chunk's border so neighbours still meet; it applies to the
    /// meshers that mesh chunk by chunk (marching cubes and tetrahedra), dual contouring refuses
    /// it. Tetrahedra mesh a layer whose chunks mix levels with marching cubes (see
    /// [`Editor::view_mesher_used`]); level of detail by distance applies to marching cubes only.
    pub fn set_view_mesher(&mut self, options: MeshOptions) -> Result<(), EditorError> {
        if let Some(e) = options.simplify {
            if !(e.is_finite() && e >= 0.0) {
                return Err(MesherError::Simplify(strata_mesh::simplify::SimplifyError::BadError(e)).into());
            }
            if options.mesher.block().is_none() {
                return Err(MesherError::ChunkSimplify(options.mesher).into());
            }
        }
        self.meshes.set_options(options, &self.scene.layers);
        Ok(())
    }

    /// The mesher a layer's viewport meshes are made with now: the one asked for, or marching
    /// cubes where tetrahedra were asked for and the layer's chunks mix levels.
    pub fn view_mesher_used(&self, layer: usize) -> Option<Mesher> {
        self.meshes.mesher_used(layer)
    }

    /// The viewport mesh of chunk `key` of a layer (chunk-local positions), by the viewport's
    /// mesher.
    pub fn chunk_mesh(&self, layer: usize, key: ChunkKey) -> Option<&Mesh> {
        self.meshes.mesh(layer, key)
    }

    /// Every viewport chunk mesh of a layer.
    pub fn chunk_meshes(&self, layer: usize) -> Vec<(ChunkKey, &Mesh)> {
        self.meshes.meshes(layer)
    }

    /// What a renderer must do to show the viewport's meshes as they are now, since the last
    /// call (see [`ChangeList`]): the first call, and the first after the layer list or the
    /// mesher changed, or after [`Editor::redraw_all`], is a full list.
    pub fn take_changes(&mut self) -> ChangeList {
        self.meshes.take_changes(&self.scene.layers, &self.scene.materials)
    }

    /// Makes the next [`Editor::take_changes`] a full list (the renderer showed something else
    /// meanwhile).
    pub fn redraw_all(&mut self) {
        self.meshes.redraw_all();
    }

    /// The box of a layer's viewport surface in its grid coordinates (from the mesh cache:
    /// chunks not meshed yet are not counted), or `None` for a layer without surface.
    pub fn surface_bounds(&self, layer: usize) -> Option<(DVec3, DVec3)> {
        let mut b: Option<(DVec3, DVec3)> = None;
        for (key, mesh) in self.chunk_meshes(layer) {
            let o = key.origin_grid().as_dvec3();
            for p in &mesh.positions {
                let q = o + glam::Vec3::from(*p).as_dvec3();
                b = Some(b.map_or((q, q), |(lo, hi)| (lo.min(q), hi.max(q))));
            }
        }
        b
    }

    /// Triangles in all layers' caches.
    pub fn triangle_count(&self) -> usize {
        self.meshes.triangle_count()
    }

    /// A dual-contoured, welded mesh of a layer in world coordinates (sharp features; on request,
    /// not per frame).
    pub fn dual_contour_layer(&self, layer: usize) -> Result<Mesh, EditorError> {
        let l = self.scene.layers.get(layer).ok_or(EditorError::NoLayer(layer))?;
        let mut mesh = dual_contour_volume(&l.volume);
        to_world(&mut mesh, &l.transform);
        Ok(mesh)
    }

    /// One mesh of every visible layer in world coordinates, for export, by `options` (each
    /// layer welded, and simplified when asked).
    pub fn export_mesh(&self, options: MeshOptions) -> Result<Mesh, EditorError> {
        self.export_mesh_reported(options).map(|(mesh, _)| mesh)
    }

    /// [`Editor::export_mesh`], also saying what `options.remove_islands` removed, summed over
    /// the layers. Islands are measured in each layer's own cells (cells³ of its grid, before
    /// the layer's transform), so one threshold means the same on layers of any scale.
    pub fn export_mesh_reported(&self, options: MeshOptions) -> Result<(Mesh, IslandReport), EditorError> {
        let mut out = Mesh::default();
        let mut islands = IslandReport::default();
        for l in self.scene.layers.iter().filter(|l| l.visible) {
            let (mut m, removed) = strata_mesh::mesh_volume_reported(&l.volume, options)?;
            islands = islands.then(removed);
            to_world(&mut m, &l.transform);
            let base = out.positions.len() as u32;
            for i in 0..m.vertex_count() {
                out.push_vertex_from(&m, i, [0.0; 3]);
            }
            out.indices.extend(m.indices.iter().map(|i| i + base));
        }
        Ok((out, islands))
    }

    /// The first surface hit of the world ray `origin + t · dir` (`t ≤ max_t`) on a visible layer.
    ///
    /// The work is bounded per pick, whatever the scene: layers whose stored chunks the ray
    /// misses cost one box test (an empty layer nothing), layers are tried in the order the ray
    /// enters their boxes and the search stops once a hit is nearer than the next box, and all
    /// layers together walk at most [`PICK_CHUNK_STEPS`] chunks.
    pub fn pick(&self, origin: DVec3, dir: DVec3, max_t: f64) -> Option<Pick> {
        self.pick_counted(origin, dir, max_t).0
    }

    /// Where a stroke in progress meets the surface along the ray `origin + t·dir` (unit `dir`
    /// not required): the ray parameter of the first surface that is not the stroke's own work,
    /// or `None` where that surface cannot be seen (then the caller keeps the stroke's depth).
    ///
    /// A stroke follows the surface under the pointer, as sculptors expect: from the face onto
    /// the body behind it, a stroke keeps touching. Tools that build or carve
    /// ([`ToolKind::builds_or_carves`]) must not pick what their own dabs made, or each dab
    /// would start on the last one and the stroke would climb towards the camera (or dig into
    /// the model): a hit inside the balls of the stroke's dabs is skipped, the ray continues
    /// where it leaves them, and if it leaves them inside solid the surface it looks for was
    /// under the stroke's own material (`None`). With no stroke, this is [`Editor::pick`].
    pub fn stroke_surface(&self, origin: DVec3, dir: DVec3, max_t: f64) -> Option<f64> {
        let len = dir.length();
        if !(len > 0.0 && len.is_finite()) {
            return None;
        }
        let dir = dir / len;
        let Some(stroke) = &self.stroke else { return self.pick(origin, dir, max_t).map(|p| p.t / len) };
        let mut t0 = 0.0;
        // Each pass leaves the union of the balls once; a ray meets it a few times at most.
        for _ in 0..16 {
            let hit = self.pick(origin + dir * t0, dir, max_t - t0)?;
            let t = t0 + hit.t;
            if !stroke.owns(origin + dir * t) {
                return Some(t / len);
            }
            let exit = stroke.exit_own(origin, dir, t);
            if exit >= max_t || self.solid_at(origin + dir * exit) {
                return None;
            }
            t0 = exit;
        }
        None
    }

    /// Whether world point `p` is inside the solid of a visible layer.
    pub fn solid_at(&self, p: DVec3) -> bool {
        self.scene
            .layers
            .iter()
            .filter(|l| l.visible && l.transform.is_valid())
            .any(|l| l.volume.is_inside(l.transform.to_grid(p)))
    }

    /// [`Editor::pick`], also returning how many chunks it walked in all.
    pub fn pick_counted(&self, origin: DVec3, dir: DVec3, max_t: f64) -> (Option<Pick>, u64) {
        if !(origin.is_finite() && dir.is_finite() && dir.length_squared() > 0.0 && max_t >= 0.0) {
            return (None, 0);
        }
        // (entry parameter, layer) for every visible layer whose chunk box the ray meets.
        let mut candidates: Vec<(f64, usize)> = self
            .scene
            .layers
            .iter()
            .enumerate()
            .filter(|(_, l)| l.visible && l.transform.is_valid())
            .filter_map(|(i, l)| {
                let (lo, hi) = l.volume.chunk_bounds_grid()?;
                let tr = &l.transform;
                let (t0, t1) = strata_volume::clip_to_box(tr.to_grid(origin), tr.dir_to_grid(dir), lo, hi)?;
                (t1 >= 0.0 && t0 <= max_t).then_some((t0.max(0.0), i))
            })
            .collect();
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best: Option<Pick> = None;
        let mut steps_left = PICK_CHUNK_STEPS;
        for (entry, i) in candidates {
            if best.is_some_and(|b| b.t <= entry) || steps_left == 0 {
                break;
            }
            let l = &self.scene.layers[i];
            let tr = &l.transform;
            let limit = best.map_or(max_t, |b| b.t.min(max_t));
            let (hit, walked) = l.volume.raycast_limited(tr.to_grid(origin), tr.dir_to_grid(dir), limit, steps_left);
            steps_left = steps_left.saturating_sub(walked);
            if let Some(hit) = hit
                && best.is_none_or(|b| hit.t < b.t)
            {
                best = Some(Pick {
                    layer: i,
                    t: hit.t,
                    point: tr.to_world(hit.point),
                    normal: (tr.rotation * hit.normal).normalize_or(hit.normal),
                });
            }
        }
        (best, PICK_CHUNK_STEPS - steps_left)
    }
}

/// The most chunks one [`Editor::pick`] walks over all layers: a straight ray through a world
/// a million cells wide, about a millisecond of empty-chunk steps.
pub const PICK_CHUNK_STEPS: u64 = 1 << 16;

/// One dab of the field tool `tool.kind` at world point `p` on `volume`, placed in its layer's
/// grid by `transform`: a ball of the tool's radius (at `pressure`), the falloff scaled by
/// [`ToolSettings::field_strength`]; `inverted` (the secondary button) picks the inverse tool;
/// `direction` is the stroke's direction (world), the line a pinch pulls towards.
fn field_tool_dab(
    tool: &ToolSettings,
    transform: &crate::scene::LayerTransform,
    volume: &mut Volume,
    p: DVec3,
    pressure: f64,
    inverted: bool,
    direction: Option<DVec3>,
) -> Result<EditReport, strata_volume::tools::ToolError> {
    use strata_volume::tools::{Dab, Smoothing, clay, flatten, inflate, paint, pinch, smooth};
    let radius = tool.radius_at(pressure) / transform.scale;
    let dab =
        Dab { material: tool.material, ..Dab::new(transform.to_grid(p), radius, tool.field_strength.clamp(0.0, 1.0))? };
    match tool.kind {
        ToolKind::Paint => paint(volume, &Dab { material: if inverted { 0 } else { tool.material }, ..dab }),
        ToolKind::Clay => clay(volume, &dab, tool.fillet.clamp(0.0, 4.0) * radius, inverted),
        ToolKind::Smooth => {
            let method = if inverted {
                Smoothing::Laplacian
            } else if tool.paper_smoothing {
                Smoothing::Endpoints
            } else {
                Smoothing::VolumePreserving
            };
            smooth(volume, &dab, method, 4)
        }
        ToolKind::Inflate => inflate(volume, &dab, if inverted { -0.2 } else { 0.2 } * radius),
        ToolKind::Pinch => {
            let axis = direction.map(|d| transform.rotation.inverse() * d);
            pinch(volume, &dab, axis, if inverted { -0.5 } else { 0.5 })
        }
        // (Grab drags through `Editor::grab_to`; a dab of it alone has nothing to drag.)
        ToolKind::Grab => {
            Ok(EditReport { changed: Vec::new(), undo: Default::default(), repaired_nodes: 0, reach: None })
        }
        ToolKind::Detail => {
            let target = if inverted { volume.level() } else { tool.detail_level.max(volume.level()) };
            Ok(volume.set_chunk_levels(&chunks_in_ball(volume, dab.center, radius), target))
        }
        _ => flatten(volume, &dab),
    }
}

/// The list chunks of `volume` that a ball (grid coordinates) reaches.
fn chunks_in_ball(volume: &Volume, center: DVec3, radius: f64) -> Vec<ChunkKey> {
    let c = strata_volume::coords::CHUNK_CELLS as f64;
    let (Some(lo), Some(hi)) =
        (ChunkKey::containing(center - DVec3::splat(radius)), ChunkKey::containing(center + DVec3::splat(radius)))
    else {
        return Vec::new();
    };
    let keys: Vec<ChunkKey> = strata_volume::ChunkBox::between(lo, hi)
        .keys()
        .filter(|&k| {
            let min = k.origin_grid().as_dvec3();
            let nearest = center.clamp(min, min + DVec3::splat(c));
            volume.stored_level(k).is_some() && (nearest - center).length() <= radius
        })
        .collect();
    keys
}

/// Moves a grid-space mesh into world space.
pub fn to_world(mesh: &mut Mesh, tr: &crate::scene::LayerTransform) {
    for p in &mut mesh.positions {
        *p = tr.to_world(glam::Vec3::from(*p).as_dvec3()).as_vec3().into();
    }
    for n in &mut mesh.normals {
        *n = (tr.rotation * glam::Vec3::from(*n).as_dvec3()).as_vec3().into();
    }
}
