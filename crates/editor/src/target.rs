//! What the tools edit: the edit-target seam. A scene [`Layer`] and a streamed
//! [`strata_terrain::World`] both answer [`EditTarget`], so strokes, their mirror images, the
//! line tool, large dabs and the budgeted undo history are one pipeline for scenes and worlds.
//!
//! An editor's *surfaces* are its scene's layers (numbered from 0) followed, when the editor is
//! on a world ([`crate::Editor::on_world`]), by the world; the viewport's meshes, the change
//! list and the history refer to surfaces by that number.

use strata_terrain::World;
use strata_volume::brush::Aabb;
use strata_volume::{ChunkKey, EditReport, UndoRecord, Volume};

use crate::editor::EditorError;
use crate::scene::{Layer, LayerTransform};

/// A volume the editor's tools may change (see the module docs).
pub trait EditTarget {
    /// The lists tools read (picking, field tools' regions, materials).
    fn volume(&self) -> &Volume;

    /// Where its grid sits in the world.
    fn transform(&self) -> LayerTransform;

    /// Whether it is drawn and picked.
    fn shown(&self) -> bool;

    /// Whether tools may change it.
    fn locked(&self) -> bool;

    /// Whether its chunks come and go as a viewer moves (a world): the viewport meshes it on
    /// worker threads nearest the viewer first, and learns of its changes from it.
    fn streamed(&self) -> bool {
        false
    }

    /// Runs `edit` on the lists, after making sure every chunk within `bounds` (grid
    /// coordinates, the edit's whole reach) is in memory; the chunks it changed are recorded
    /// where the target keeps such a record. The report's undo record is the caller's.
    fn edit(
        &mut self,
        bounds: &Aabb,
        edit: &mut dyn FnMut(&mut Volume) -> Result<EditReport, EditorError>,
    ) -> Result<EditReport, EditorError>;

    /// Makes sure the chunks `keys` are in memory before records restore them (a world loads
    /// chunks that left memory); on an error nothing changed.
    fn prepare(&mut self, keys: &[ChunkKey]) -> Result<(), EditorError>;

    /// Restores an undo record (after [`EditTarget::prepare`] of its keys); returns the record
    /// that takes it back.
    fn restore(&mut self, record: UndoRecord) -> UndoRecord;
}

impl EditTarget for Layer {
    fn volume(&self) -> &Volume {
        &self.volume
    }

    fn transform(&self) -> LayerTransform {
        self.transform
    }

    fn shown(&self) -> bool {
        self.visible
    }

    fn locked(&self) -> bool {
        self.locked
    }

    fn edit(
        &mut self,
        _bounds: &Aabb,
        edit: &mut dyn FnMut(&mut Volume) -> Result<EditReport, EditorError>,
    ) -> Result<EditReport, EditorError> {
        // A layer's chunks are all in memory.
        edit(&mut self.volume)
    }

    fn prepare(&mut self, _keys: &[ChunkKey]) -> Result<(), EditorError> {
        Ok(())
    }

    fn restore(&mut self, record: UndoRecord) -> UndoRecord {
        self.volume.restore(record)
    }
}

impl EditTarget for World {
    fn volume(&self) -> &Volume {
        World::volume(self)
    }

    /// A world's grid is the world: one unit a cell, no turn.
    fn transform(&self) -> LayerTransform {
        LayerTransform::default()
    }

    fn shown(&self) -> bool {
        true
    }

    fn locked(&self) -> bool {
        false
    }

    fn streamed(&self) -> bool {
        true
    }

    fn edit(
        &mut self,
        bounds: &Aabb,
        edit: &mut dyn FnMut(&mut Volume) -> Result<EditReport, EditorError>,
    ) -> Result<EditReport, EditorError> {
        // The world reports an edit's refusal as text; the editor's own error is kept to be
        // returned as it was.
        let mut refused = None;
        let result = World::edit(self, *bounds, |v| {
            edit(v).map_err(|e| {
                let text = e.to_string();
                refused = Some(e);
                text
            })
        });
        result.map_err(|e| refused.take().unwrap_or(EditorError::World(e)))
    }

    fn prepare(&mut self, keys: &[ChunkKey]) -> Result<(), EditorError> {
        self.load_now(keys).map_err(EditorError::World)
    }

    fn restore(&mut self, record: UndoRecord) -> UndoRecord {
        // `prepare` loaded every chunk the record restores and nothing ran since, so the world
        // loads nothing here: no I/O, nothing that can fail (a failure would be a bug in the
        // editor's history, not bad input).
        World::restore(self, record)
            .unwrap_or_else(|b| panic!("a world restored a record whose chunks were not prepared: {}", b.0))
    }
}
