//! Replayable edit operations: what the stroke engine applied in one frame, recorded so that
//! another editor holding the same lists replays it bit for bit (the network sends these).
//!
//! An operation carries everything its dabs need, and nothing of the editor that made it: the
//! surface, the surface's transform and the tool settings in force, and each dab's aligned
//! position, the position before it (the direction a pinch pulls), orientation, pressure and
//! whether the inverse tool acted (or, for grab, the anchor and the drag). Mirror images are
//! made again from the tool's symmetry on replay. Edits are deterministic, so the same
//! operations in the same order on the same lists give the same bytes on any machine and thread
//! count.

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};
use strata_volume::{ChunkKey, UndoRecord};

use crate::editor::{Editor, EditorError};
use crate::scene::LayerTransform;
use crate::tool::ToolSettings;

/// The most dabs one operation holds: a frame with more (a fast drag at a small spacing makes
/// thousands) is recorded as several operations of the same stroke.
pub const MAX_OP_DABS: usize = 4096;

/// One frame's dabs on one surface (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EditOp {
    /// The surface edited (a layer's number; on a world, the world's: see [`crate::target`]).
    pub surface: u32,
    /// The surface's transform when the dabs were made (replay places them with it).
    pub transform: LayerTransform,
    /// The tool that acted (smoothing already substituted where the pose asked for it).
    pub tool: ToolSettings,
    /// The dabs, in the order applied.
    pub dabs: Vec<DabRecord>,
    /// The stroke it belongs to, numbered by the editor that made it: an undo takes back a
    /// whole stroke, all its operations together.
    pub stroke: u64,
}

/// One dab of an [`EditOp`] (world coordinates).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum DabRecord {
    /// A dab of the tool at `at` (aligned, before mirroring), following one at `from`.
    Dab {
        /// Where it went.
        at: DVec3,
        /// Where the stroke's previous dab went (`at` for a stroke's first).
        from: DVec3,
        /// The pose's orientation (oriented brushes follow it).
        orientation: DQuat,
        /// The pose's pressure.
        pressure: f64,
        /// Whether the inverse tool acted.
        inverted: bool,
    },
    /// A grab's drag of the surface under `anchor` by `drag`.
    Grab {
        /// The grabbed point.
        anchor: DVec3,
        /// How far it moved.
        drag: DVec3,
        /// The pose's pressure.
        pressure: f64,
    },
}

impl EditOp {
    /// Every number the operation carries, for checks of finiteness (the network refuses
    /// operations with NaN or infinite values before replaying them).
    pub fn numbers(&self) -> Vec<f64> {
        let t = &self.transform;
        let mut out = Vec::with_capacity(16 + self.dabs.len() * 11);
        out.extend(t.translation.to_array());
        out.extend(t.rotation.to_array());
        out.push(t.scale);
        let tool = &self.tool;
        out.extend([tool.radius, tool.strength, tool.spacing, tool.field_strength, tool.fillet, tool.grid_snap]);
        out.extend(tool.symmetry_center.to_array());
        out.push(tool.stamp.angle);
        out.push(tool.pressure_to_strength);
        out.extend(tool.falloff.numbers());
        for curve in [tool.pressure.size, tool.pressure.strength] {
            out.extend(curve.points().into_iter().flat_map(|(t, v)| [t, v]));
        }
        for d in &self.dabs {
            match *d {
                DabRecord::Dab { at, from, orientation, pressure, .. } => {
                    out.extend(at.to_array());
                    out.extend(from.to_array());
                    out.extend(orientation.to_array());
                    out.push(pressure);
                }
                DabRecord::Grab { anchor, drag, pressure } => {
                    out.extend(anchor.to_array());
                    out.extend(drag.to_array());
                    out.push(pressure);
                }
            }
        }
        out
    }

    /// The largest radius (world units) any of its dabs reaches, pressure applied.
    pub fn max_radius(&self) -> f64 {
        self.dabs
            .iter()
            .map(|d| match *d {
                DabRecord::Dab { pressure, .. } | DabRecord::Grab { pressure, .. } => self.tool.radius_at(pressure),
            })
            .fold(0.0, f64::max)
    }
}

/// What takes an applied operation back: the undo records of its edits, restored in reverse.
/// It serialises (a room's server sends it to undo an operation everywhere); restore only
/// records from a trusted source (see [`strata_volume::UndoRecord`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OpUndo {
    pub(crate) surface: usize,
    pub(crate) records: Vec<UndoRecord>,
}

impl OpUndo {
    /// The surface the operation edited.
    pub fn surface(&self) -> usize {
        self.surface
    }

    /// The chunks the operation changed (those its records restore), sorted, without repeats.
    pub fn keys(&self) -> Vec<ChunkKey> {
        let mut keys: Vec<ChunkKey> = self.records.iter().flat_map(UndoRecord::keys).collect();
        keys.sort();
        keys.dedup();
        keys
    }

    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        self.records.iter().map(UndoRecord::heap_bytes).sum()
    }
}

/// An operation the stroke engine applied, with what takes it back.
#[derive(Debug)]
pub struct RecordedOp {
    /// What to send.
    pub op: EditOp,
    /// What undoes it here.
    pub undo: OpUndo,
}

/// The operations an editor recorded since they were last taken (see [`Editor::record_ops`]).
#[derive(Debug, Default)]
pub(crate) struct Recorder {
    pub(crate) done: Vec<RecordedOp>,
    pub(crate) current: Option<RecordedOp>,
    /// The number of the stroke in progress (or the next).
    pub(crate) stroke: u64,
}

impl Editor {
    /// Starts (`true`) or stops recording the stroke engine's edits as [`EditOp`]s. While it
    /// records, strokes leave nothing in the local history: each frame's dabs become one
    /// operation, taken with [`Editor::take_ops`], whose [`OpUndo`] is the caller's (a shared
    /// room's undo is the room's, not one editor's). Stopping drops operations not taken.
    pub fn record_ops(&mut self, on: bool) {
        self.end_stroke();
        self.recorder = on.then(Recorder::default);
    }

    /// Ends the stroke in progress and gives the next stroke's number to the caller (who makes
    /// operations of their own under it, as a shared room's redo does); `None` unless recording.
    pub fn claim_stroke(&mut self) -> Option<u64> {
        self.end_stroke();
        let r = self.recorder.as_mut()?;
        let n = r.stroke;
        r.stroke += 1;
        Some(n)
    }

    /// Whether the editor records operations.
    pub fn records_ops(&self) -> bool {
        self.recorder.is_some()
    }

    /// The operations recorded since the last call, in the order applied.
    pub fn take_ops(&mut self) -> Vec<RecordedOp> {
        let Some(r) = self.recorder.as_mut() else { return Vec::new() };
        let mut ops = std::mem::take(&mut r.done);
        if let Some(op) = r.current.take() {
            ops.push(op);
        }
        ops.retain(|o| !o.op.dabs.is_empty());
        ops
    }

    /// Opens the frame's operation on `layer` (a no-op unless recording).
    pub(crate) fn begin_op(&mut self, layer: usize, transform: &LayerTransform, tool: &ToolSettings) {
        let Some(r) = self.recorder.as_mut() else { return };
        if let Some(op) = r.current.take() {
            r.done.push(op);
        }
        r.current = Some(RecordedOp {
            op: EditOp {
                surface: layer as u32,
                transform: *transform,
                tool: *tool,
                dabs: Vec::new(),
                stroke: r.stroke,
            },
            undo: OpUndo { surface: layer, records: Vec::new() },
        });
    }

    /// Adds an applied dab to the frame's operation (a no-op unless recording); a full
    /// operation is closed and the frame's next dabs go to another of the same stroke.
    pub(crate) fn note_dab(&mut self, dab: DabRecord) {
        let Some(r) = self.recorder.as_mut() else { return };
        let Some(op) = r.current.as_mut() else { return };
        op.op.dabs.push(dab);
        if op.op.dabs.len() >= MAX_OP_DABS {
            let next = RecordedOp {
                op: EditOp {
                    surface: op.op.surface,
                    transform: op.op.transform,
                    tool: op.op.tool,
                    dabs: Vec::new(),
                    stroke: op.op.stroke,
                },
                undo: OpUndo { surface: op.undo.surface, records: Vec::new() },
            };
            let full = std::mem::replace(op, next);
            r.done.push(full);
        }
    }

    /// Closes the frame's operation (a no-op unless recording).
    pub(crate) fn end_op(&mut self) {
        if let Some(r) = self.recorder.as_mut()
            && let Some(op) = r.current.take()
        {
            r.done.push(op);
        }
    }

    /// Applies `op` (made here or by another editor) whole, outside any stroke and history,
    /// with its chunks queued for meshing; returns what takes it back. A refused dab takes back
    /// the dabs before it: on an error nothing changed. Locks and visibility, which are each
    /// editor's own, do not stop a replay; the surface, its transform and the material must be
    /// valid.
    pub fn replay(&mut self, op: &EditOp) -> Result<OpUndo, EditorError> {
        let layer = op.surface as usize;
        if self.surface(layer).is_none() {
            return Err(EditorError::NoLayer(layer));
        }
        if !op.transform.is_valid() {
            return Err(EditorError::BadLayerTransform(layer));
        }
        let count = self.scene.materials.len();
        if op.tool.material as usize >= count {
            return Err(EditorError::UnknownMaterial { id: op.tool.material, count });
        }
        self.check_tool_target(layer, &op.tool)?;
        let mut undo = OpUndo { surface: layer, records: Vec::new() };
        // The frame's limit is for dragging; a replayed operation is applied as it was.
        let limit = std::mem::replace(&mut self.frame_dab_limit, u64::MAX);
        let mut result = Ok(());
        for dab in &op.dabs {
            let mut applied = Vec::new();
            result = self.apply_dab(layer, &op.tool, &op.transform, dab, &mut applied);
            for (edit, _, _) in applied {
                self.queue(layer, &edit.changed, edit.reach);
                undo.records.push(edit.undo);
            }
            if result.is_err() {
                break;
            }
        }
        self.frame_dab_limit = limit;
        self.revision += 1;
        match result {
            Ok(()) => Ok(undo),
            Err(e) => {
                self.revert(undo).map_err(|(e, _)| e)?;
                Err(e)
            }
        }
    }

    /// Takes an applied operation back (its records in reverse), chunks queued for meshing.
    /// On an error (a world's chunk that cannot be read) nothing changed and the undo comes
    /// back with it.
    pub fn revert(&mut self, undo: OpUndo) -> Result<(), (EditorError, OpUndo)> {
        let mut keys = undo.keys();
        if undo.records.iter().any(UndoRecord::reshades_everything)
            && let Some(target) = self.surface(undo.surface)
        {
            keys.extend(target.volume().chunks().map(|(k, _)| k));
        }
        let Some(target) = self.surface_mut(undo.surface) else {
            return Err((EditorError::NoLayer(undo.surface), undo));
        };
        if let Err(e) = target.prepare(&keys) {
            return Err((e, undo));
        }
        for record in undo.records.into_iter().rev() {
            target.restore(record);
        }
        self.queue(undo.surface, &keys, None);
        self.revision += 1;
        Ok(())
    }
}
