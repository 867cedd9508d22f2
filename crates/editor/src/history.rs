//! Undo/redo over whole strokes, within a memory budget.

use strata_terrain::World;
use strata_volume::{ChunkKey, UndoRecord};

use crate::editor::{EditorError, surface_mut};
use crate::reference::ReferenceImage;
use crate::scene::{Layer, LayerTransform};

/// One undoable step: the records of every edit of a stroke on one surface (a layer, or an
/// editor's world: see [`crate::target`]), in the order applied,
/// a change of the layer's transform, or a change of the layer list itself (layers added,
/// deleted, duplicated, reordered or merged).
#[derive(Debug, Default)]
pub struct HistoryEntry {
    /// The surface the step edited (a layer's number, or on a world the world's).
    pub layer: usize,
    /// Records in edit order; undoing restores them in reverse.
    pub records: Vec<UndoRecord>,
    /// The layer's transform before the step, for a step that moved, turned or scaled it.
    pub transform: Option<LayerTransform>,
    /// The whole layer list and the active layer before the step, for a step that changed the
    /// list (layer numbers, which the other steps refer to, are those of the list restored).
    pub layers: Option<(Vec<Layer>, usize)>,
    /// The reference images before the step, for a step that added, changed or deleted one
    /// (their pictures are shared, not copied).
    pub references: Option<Vec<ReferenceImage>>,
    /// For a step that changed one reference image alone, its number (a drag of it joins it).
    pub reference: Option<usize>,
}

/// What a step restores: the scene's layers, its active layer and its reference images.
#[derive(Debug)]
pub struct StepTarget<'a> {
    /// The layer list.
    pub layers: &'a mut Vec<Layer>,
    /// The active layer (restored with the list).
    pub active: &'a mut usize,
    /// The reference images.
    pub references: &'a mut Vec<ReferenceImage>,
}

/// A step that could not be restored (a world's chunk unreadable), with why.
type Refused = Box<(EditorError, HistoryEntry)>;

/// What an undo or redo restored.
#[derive(Debug, Clone, PartialEq)]
pub enum Restored {
    /// Chunks of one layer (and perhaps its transform).
    Chunks(usize, Vec<ChunkKey>),
    /// The layer list (and the active layer).
    Layers,
    /// The reference images.
    References,
}

impl HistoryEntry {
    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        self.records.iter().map(UndoRecord::heap_bytes).sum::<usize>()
            + self.records.capacity() * std::mem::size_of::<UndoRecord>()
            + self.layers.as_ref().map_or(0, |(l, _)| l.iter().map(|l| l.volume.memory().total()).sum())
    }

    /// The chunks the step's records restore, sorted, without repeats.
    fn keys(&self) -> Vec<ChunkKey> {
        let mut keys: Vec<ChunkKey> = self.records.iter().flat_map(UndoRecord::keys).collect();
        keys.sort();
        keys.dedup();
        keys
    }

    /// Restores the step on `layers` and `world` (its records in reverse order and its
    /// transform, or the layer list); returns the entry that undoes this one and what it
    /// restored, or `None` (and nothing changed) for a step on a surface that no longer exists.
    /// When a world cannot load a chunk the step restores, nothing changes and the step comes
    /// back with the error.
    fn apply(
        self,
        scene: StepTarget<'_>,
        world: Option<&mut World>,
    ) -> Result<Option<(HistoryEntry, Restored)>, Refused> {
        let StepTarget { layers, active, references } = scene;
        if let Some(list) = self.references {
            let now = std::mem::replace(references, list);
            return Ok(Some((HistoryEntry { references: Some(now), ..Default::default() }, Restored::References)));
        }
        if let Some((list, was_active)) = self.layers {
            let now = std::mem::replace(layers, list);
            let now_active = std::mem::replace(active, was_active);
            let entry = HistoryEntry { layers: Some((now, now_active)), ..Default::default() };
            return Ok(Some((entry, Restored::Layers)));
        }
        let Some(target) = surface_mut(layers, world, self.layer) else { return Ok(None) };
        if let Err(e) = target.prepare(&self.keys()) {
            return Err(Box::new((e, self)));
        }
        let records: Vec<UndoRecord> = self.records.into_iter().rev().map(|r| target.restore(r)).collect();
        // (A mask's outside weight changed: every chunk is drawn anew.)
        let everything: Vec<ChunkKey> = if records.iter().any(UndoRecord::reshades_everything) {
            target.volume().chunks().map(|(k, _)| k).collect()
        } else {
            Vec::new()
        };
        let transform = match (self.transform, layers.get_mut(self.layer)) {
            (Some(t), Some(layer)) => Some(std::mem::replace(&mut layer.transform, t)),
            _ => None,
        };
        let entry = HistoryEntry { layer: self.layer, records, transform, ..Default::default() };
        let mut keys = entry.keys();
        if !everything.is_empty() {
            keys.extend(everything);
            keys.sort();
            keys.dedup();
        }
        Ok(Some((entry, Restored::Chunks(self.layer, keys))))
    }
}

/// Undo and redo stacks. When their bytes exceed the budget, the oldest undo steps are dropped.
#[derive(Debug)]
pub struct History {
    undo: Vec<HistoryEntry>,
    redo: Vec<HistoryEntry>,
    budget: usize,
}

impl Default for History {
    fn default() -> Self {
        History::with_budget(512 << 20)
    }
}

impl History {
    /// Empty stacks that hold at most `budget` bytes.
    pub fn with_budget(budget: usize) -> Self {
        History { undo: Vec::new(), redo: Vec::new(), budget }
    }

    /// Records a finished step; clears the redo stack.
    pub fn push(&mut self, entry: HistoryEntry) {
        if entry.records.iter().all(UndoRecord::is_empty)
            && entry.transform.is_none()
            && entry.layers.is_none()
            && entry.references.is_none()
        {
            return;
        }
        self.redo.clear();
        self.undo.push(entry);
        self.trim();
    }

    /// Whether the newest undo step is a transform change of `layer` (which a continuing drag of
    /// the same transform may merge into).
    pub fn last_is_transform_of(&self, layer: usize) -> bool {
        self.undo
            .last()
            .is_some_and(|e| e.layer == layer && e.records.is_empty() && e.transform.is_some() && e.layers.is_none())
    }

    /// Whether the newest undo step changed reference image `i` alone (which a continuing drag
    /// of it may merge into).
    pub fn last_is_reference(&self, i: usize) -> bool {
        self.undo.last().is_some_and(|e| e.references.is_some() && e.reference == Some(i))
    }

    /// Forgets the redo steps (a change merged into the newest step makes them stale, as a
    /// new step does).
    pub fn forget_redo(&mut self) {
        self.redo.clear();
    }

    fn trim(&mut self) {
        let mut total = self.bytes();
        // Keep at least the newest step, whatever its size.
        while total > self.budget && self.undo.len() > 1 {
            total -= self.undo.remove(0).bytes();
        }
    }

    /// Undoes the newest step on `scene` (its layers, active layer and references) and `world`
    /// (an editor's world, the surface after the layers). Returns what it restored;
    /// on an error (a world's chunk cannot be read) nothing changed and the step stays.
    pub fn undo(&mut self, scene: StepTarget<'_>, world: Option<&mut World>) -> Result<Option<Restored>, EditorError> {
        Self::step(&mut self.undo, &mut self.redo, scene, world)
    }

    /// Redoes the newest undone step (see [`History::undo`]).
    pub fn redo(&mut self, scene: StepTarget<'_>, world: Option<&mut World>) -> Result<Option<Restored>, EditorError> {
        let restored = Self::step(&mut self.redo, &mut self.undo, scene, world)?;
        self.trim();
        Ok(restored)
    }

    /// Restores the newest step of `from` and keeps the step that takes it back on `to`. A
    /// step on a layer that no longer exists is dropped; a refused one goes back on `from`.
    fn step(
        from: &mut Vec<HistoryEntry>,
        to: &mut Vec<HistoryEntry>,
        scene: StepTarget<'_>,
        world: Option<&mut World>,
    ) -> Result<Option<Restored>, EditorError> {
        let Some(entry) = from.pop() else { return Ok(None) };
        match entry.apply(scene, world) {
            Ok(Some((back, restored))) => {
                to.push(back);
                Ok(Some(restored))
            }
            Ok(None) => Ok(None),
            Err(failed) => {
                let (e, entry) = *failed;
                from.push(entry);
                Err(e)
            }
        }
    }

    /// Steps that can be undone.
    pub fn undo_len(&self) -> usize {
        self.undo.len()
    }

    /// Steps that can be redone.
    pub fn redo_len(&self) -> usize {
        self.redo.len()
    }

    /// Bytes held by both stacks.
    pub fn bytes(&self) -> usize {
        self.undo.iter().chain(&self.redo).map(HistoryEntry::bytes).sum()
    }

    /// Forgets everything (a new or loaded scene).
    pub fn clear(&mut self) {
        self.undo.clear();
        self.redo.clear();
    }
}
