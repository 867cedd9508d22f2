//! Undo/redo over whole strokes, within a memory budget.

use strata_volume::{ChunkKey, UndoRecord};

use crate::scene::{Layer, LayerTransform};

/// One undoable step: the records of every edit of a stroke on one layer, in the order applied,
/// or a change of the layer's transform.
#[derive(Debug, Default)]
pub struct HistoryEntry {
    /// The layer the step edited.
    pub layer: usize,
    /// Records in edit order; undoing restores them in reverse.
    pub records: Vec<UndoRecord>,
    /// The layer's transform before the step, for a step that moved, turned or scaled it.
    pub transform: Option<LayerTransform>,
}

impl HistoryEntry {
    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        self.records.iter().map(UndoRecord::heap_bytes).sum::<usize>()
            + self.records.capacity() * std::mem::size_of::<UndoRecord>()
    }

    /// The chunks the step's records restore, sorted, without repeats.
    fn keys(&self) -> Vec<ChunkKey> {
        let mut keys: Vec<ChunkKey> = self.records.iter().flat_map(UndoRecord::keys).collect();
        keys.sort();
        keys.dedup();
        keys
    }

    /// Restores the records in reverse order (and the transform); returns the entry that undoes
    /// this one.
    fn apply(self, layer: &mut Layer) -> HistoryEntry {
        let records = self.records.into_iter().rev().map(|r| layer.volume.restore(r)).collect();
        let transform = self.transform.map(|t| std::mem::replace(&mut layer.transform, t));
        HistoryEntry { layer: self.layer, records, transform }
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
        if entry.records.iter().all(UndoRecord::is_empty) && entry.transform.is_none() {
            return;
        }
        self.redo.clear();
        self.undo.push(entry);
        self.trim();
    }

    /// Whether the newest undo step is a transform change of `layer` (which a continuing drag of
    /// the same transform may merge into).
    pub fn last_is_transform_of(&self, layer: usize) -> bool {
        self.undo.last().is_some_and(|e| e.layer == layer && e.records.is_empty() && e.transform.is_some())
    }

    fn trim(&mut self) {
        let mut total = self.bytes();
        // Keep at least the newest step, whatever its size.
        while total > self.budget && self.undo.len() > 1 {
            total -= self.undo.remove(0).bytes();
        }
    }

    /// Undoes the newest step on the volume `volume_of` gives for its layer. Returns the layer
    /// and the chunks restored.
    pub fn undo<'a>(
        &mut self,
        layer_of: impl FnOnce(usize) -> Option<&'a mut Layer>,
    ) -> Option<(usize, Vec<ChunkKey>)> {
        let entry = self.undo.pop()?;
        let layer = entry.layer;
        // A step on a layer that no longer exists is dropped.
        let target = layer_of(layer)?;
        let redo = entry.apply(target);
        let keys = redo.keys();
        self.redo.push(redo);
        Some((layer, keys))
    }

    /// Redoes the newest undone step. Returns the layer and the chunks restored.
    pub fn redo<'a>(
        &mut self,
        layer_of: impl FnOnce(usize) -> Option<&'a mut Layer>,
    ) -> Option<(usize, Vec<ChunkKey>)> {
        let entry = self.redo.pop()?;
        let layer = entry.layer;
        // A step on a layer that no longer exists is dropped.
        let target = layer_of(layer)?;
        let undo = entry.apply(target);
        let keys = undo.keys();
        self.undo.push(undo);
        self.trim();
        Some((layer, keys))
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
