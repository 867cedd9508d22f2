//! Resolution levels: raising and lowering a chunk's level, reading any chunk at a coarser level
//! (level of detail), and the crack patching that lets neighbouring chunks of different levels
//! mesh into one closed surface.
//!
//! Any mix of levels is allowed (no 2:1 rule): the face table refines a face by one level at a
//! time, so a seam between levels 0 and 2 is refined twice.

mod change;
pub(crate) use change::refined;
mod dense;
mod extract;
pub(crate) mod face;
mod read;
mod settle;

pub(crate) use dense::Dense;
pub(crate) use extract::{NEIGHBOURS, extract_patched, plain, same_level_around};
pub(crate) use read::{LevelMap, LineReader};

use crate::coords::{ChunkKey, Level};
use crate::edit::{EditReport, UndoRecord};
use crate::volume::Volume;

impl Volume {
    /// Changes the stored level of the list chunk at `key` to `level`, one level at a time
    /// (raising by the face table and the cells' Hermite data, lowering by dropping the lines
    /// the coarser level does not have). Uniform and empty chunks have no level and are left as
    /// they are. A step that would break an invariant is not made and the chunk stays at the
    /// level it reached: a lowering that would leave a uniform chunk that a face neighbour's line
    /// at the volume's level contradicts (only below the volume's level), a raise that would
    /// leave a neighbour it rewrites uniform, and any lowering of a chunk where the mask holds a
    /// node (see [`crate::mask`]). The report's undo restores the volume exactly;
    /// `changed` lists the chunks whose meshes the change touches (the chunk and its 26
    /// neighbours).
    pub fn set_chunk_level(&mut self, key: ChunkKey, level: Level) -> EditReport {
        let mut undo: Vec<(ChunkKey, Option<crate::chunk::Chunk>)> = Vec::new();
        let mut material_undo: crate::material::MaterialUndo = Vec::new();
        // Each step's materials follow its chunks (resampled where the level changed); the record
        // keeps the oldest contents of every chunk.
        let mut remember = |volume: &mut Volume, undo: &mut Vec<_>, key: ChunkKey, old: Option<crate::chunk::Chunk>| {
            for (k, m) in volume.update_materials(&[(key, old.clone())], crate::material::MaterialRule::Nearest, &[]) {
                if !material_undo.iter().any(|(j, _)| *j == k) {
                    material_undo.push((k, m));
                }
            }
            if !undo.iter().any(|(k, _): &(ChunkKey, _)| *k == key) {
                undo.push((key, old));
            }
        };
        while let Some(now) = self.stored_level(key) {
            if now < level {
                let Some((built, neighbours)) = change::raise(self, key) else { break };
                for (k, b) in neighbours {
                    let old = self.put_built(k, b);
                    remember(self, &mut undo, k, old);
                }
                let old = self.put_built(key, built);
                remember(self, &mut undo, key, old);
            } else if now > level {
                // Lowering drops lines: a chunk the mask holds keeps them.
                if self.mask_holds_chunk(key) {
                    break;
                }
                let Some(built) = change::lower(self, key) else { break };
                let old = self.put_built(key, built);
                remember(self, &mut undo, key, old);
            } else {
                break;
            }
        }
        let changed = if undo.is_empty() {
            Vec::new()
        } else {
            let mut c: Vec<ChunkKey> = key.around().collect();
            c.sort();
            c
        };
        EditReport {
            changed,
            undo: UndoRecord { previous: undo, materials: material_undo, masks: Default::default() },
            repaired_nodes: 0,
            reach: None,
        }
    }

    /// [`Volume::set_chunk_level`] for several chunks, in key order, as one report.
    pub fn set_chunk_levels(&mut self, keys: &[ChunkKey], level: Level) -> EditReport {
        let mut keys = keys.to_vec();
        keys.sort();
        keys.dedup();
        let mut report = EditReport::default();
        for k in keys {
            let r = self.set_chunk_level(k, level);
            report = report.then(r);
        }
        report
    }
}
