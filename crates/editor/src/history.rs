//! Undo/redo over whole strokes, within a memory budget.

use strata_volume::{ChunkKey, UndoRecord};

use crate::scene::{Layer, LayerTransform};

/// One undoable step: the records of every edit of a stroke on one layer, in the order applied,
/// a change of the layer's transform, or a change of the layer list itself (layers added,
/// deleted, duplicated, reordered or merged).
#[derive(Debug, Default)]
pub struct HistoryEntry {
    /// The layer the step edited.
    pub layer: usize,
    /// Records in edit order; undoing restores them in reverse.
    pub records: Vec<UndoRecord>,
    /// The layer's transform before the step, for a step that moved, turned or scaled it.
    pub transform: Option<LayerTransform>,
    /// The whole layer list and the active layer before the step, for a step that changed the
    /// list (layer numbers, which the other steps refer to, are those of the list restored).
    pub layers: Option<(Vec<Layer>, usize)>,
}

/// What an undo or redo restored.
#[derive(Debug, Clone, PartialEq)]
pub enum Restored {
    /// Chunks of one layer (and perhaps its transform).
    Chunks(usize, Vec<ChunkKey>),
    /// The layer list (and the active layer).
    Layers,
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

    /// Restores the step on `layers` (its records in reverse order and its transform, or the
    /// layer list); returns the entry that undoes this one and what it restored, or `None` (and
    /// nothing changed) for a step on a layer that no longer exists.
    fn apply(self, layers: &mut Vec<Layer>, active: &mut usize) -> Option<(HistoryEntry, Restored)> {
        if let Some((list, was_active)) = self.layers {
            let now = std::mem::replace(layers, list);
            let now_active = std::mem::replace(active, was_active);
            let entry = HistoryEntry { layers: Some((now, now_active)), ..Default::default() };
            return Some((entry, Restored::Layers));
        }
        let layer = layers.get_mut(self.layer)?;
        let records: Vec<UndoRecord> = self.records.into_iter().rev().map(|r| layer.volume.restore(r)).collect();
        let transform = self.transform.map(|t| std::mem::replace(&mut layer.transform, t));
        let entry = HistoryEntry { layer: self.layer, records, transform, layers: None };
        let keys = entry.keys();
        Some((entry, Restored::Chunks(self.layer, keys)))
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
        if entry.records.iter().all(UndoRecord::is_empty) && entry.transform.is_none() && entry.layers.is_none() {
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

    fn trim(&mut self) {
        let mut total = self.bytes();
        // Keep at least the newest step, whatever its size.
        while total > self.budget && self.undo.len() > 1 {
            total -= self.undo.remove(0).bytes();
        }
    }

    /// Undoes the newest step on `layers` (`active` the active layer, restored with the list).
    /// Returns what it restored.
    pub fn undo(&mut self, layers: &mut Vec<Layer>, active: &mut usize) -> Option<Restored> {
        let entry = self.undo.pop()?;
        // A step on a layer that no longer exists is dropped.
        let (redo, restored) = entry.apply(layers, active)?;
        self.redo.push(redo);
        Some(restored)
    }

    /// Redoes the newest undone step. Returns what it restored.
    pub fn redo(&mut self, layers: &mut Vec<Layer>, active: &mut usize) -> Option<Restored> {
        let entry = self.redo.pop()?;
        let (undo, restored) = entry.apply(layers, active)?;
        self.undo.push(undo);
        self.trim();
        Some(restored)
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
