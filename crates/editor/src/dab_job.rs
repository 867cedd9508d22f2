//! One dab too large for a frame, on a worker thread: the layer's volume goes with the worker
//! and comes back with the edit (or the error, or a cancel that changes nothing).

use std::sync::Arc;
use std::time::{Duration, Instant};

use strata_volume::{EditControl, EditError, EditReport, EditSettings, Volume};

use crate::editor::{Editor, EditorError};
use crate::history::HistoryEntry;
use crate::pose::ToolPose;
use crate::stroke::{FieldDab, field_tool_dab};
use crate::tool::ToolKind;

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

/// Chunks a dab whose box is `b` (grid coordinates) visits: its box in chunks, grown by one
/// chunk on every side (saturating at 10⁷ chunks a side).
pub(crate) fn chunks_spanned(b: &strata_volume::brush::Aabb) -> Result<u64, EditorError> {
    if !b.is_valid() {
        return Err(EditorError::Edit(EditError::BadBounds));
    }
    let c = strata_volume::coords::CHUNK_CELLS as f64;
    let side = |i: usize| ((b.max[i] / c).floor() - (b.min[i] / c).floor() + 3.0).min(1e7);
    Ok((side(0) * side(1) * side(2)) as u64)
}

impl Editor {
    /// Chunks the dab of the current tool at `pose` would visit (its brush box in chunks, or
    /// the whole volume for an intersection): what the studio compares with its frame budget.
    pub fn dab_chunks(&self, pose: &ToolPose) -> Result<u64, EditorError> {
        let layer = self.active_surface();
        let transform = self.surface(layer).ok_or(EditorError::NoLayer(layer))?.transform();
        if !transform.is_valid() {
            return Err(EditorError::BadLayerTransform(layer));
        }
        let brush = self.tool_for(pose).brush(&transform, pose.position, pose.orientation, pose.pressure)?;
        chunks_spanned(&brush.bounds())
    }

    /// Starts the dab of the current tool at `pose` (the opposite tool with the secondary
    /// button) on a worker thread, as its own undo step; the stroke in progress ends first. The
    /// active layer's volume goes with the worker, so nothing else may edit or mesh that layer
    /// until [`Editor::finish_dab_job`]. A world's volume cannot leave it (it streams): on a
    /// world this is refused with a message that says so.
    pub fn start_dab_job(&mut self, pose: &ToolPose) -> Result<DabJob, EditorError> {
        if !pose.is_valid() {
            return Err(EditorError::BadPose);
        }
        if self.world.is_some() {
            return Err(EditorError::DabTooLargeForWorld(self.dab_chunks(pose)?));
        }
        self.end_stroke();
        let layer = self.active_layer;
        self.check_editable(layer)?;
        self.check_material()?;
        let tool = self.tool_for(pose);
        self.check_tool_target(layer, &tool)?;
        let image = self.stamp_image(&tool)?;
        let l = &mut self.scene.layers[layer];
        let inverted = pose.inverted();
        let op = tool.kind.op(inverted);
        let mut dabs = Vec::new();
        let parities = tool.mirror_parities(&l.transform, pose.position);
        let ups = tool.mirrored_directions(&l.transform, pose.position, pose.orientation * glam::DVec3::Y);
        let images = tool.mirrored(&l.transform, pose.position, pose.orientation);
        for (((at, orientation), mirrored), (_, up)) in images.into_iter().zip(parities).zip(ups) {
            dabs.push((at, up, mirrored, tool.brush(&l.transform, at, orientation, pose.pressure)?));
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
            for (at, up, mirrored, brush) in dabs {
                // (A field tool's dab cannot stop half-way; a cancel is honoured when it ends.)
                let result = if tool.kind.is_field_tool() {
                    let stamp = image.as_deref();
                    let dab = FieldDab { at, up, pressure, inverted, direction: None, mirrored, stamp };
                    field_tool_dab(&tool, &transform, &mut volume, &dab).map_err(EditorError::from)
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
        self.history.push(HistoryEntry { layer, records, ..Default::default() });
        Ok(changed)
    }
}
