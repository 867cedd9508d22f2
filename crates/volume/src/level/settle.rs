//! Uniform chunks next to data between their nodes.
//!
//! A uniform chunk has no level: edits and the invariant checker read it at the volume's level,
//! so every line of a face neighbour at that level (or at the neighbour's, where it is coarser)
//! that ends on the chunk's first face or starts on the face after it is bound to the chunk's
//! state. A list chunk stored *below* the volume's level binds only every second (or fourth) of
//! those lines, so the others can end or start otherwise: a neighbour's node between its nodes,
//! or a neighbour's line ending on a node of the chunk that the chunk's level does not have.
//! When such a chunk loses its last crossing, storing it as uniform would contradict those lines.
//!
//! - Lowering never does it: a lowering step that would is not made ([`super::change::lower`]).
//! - An edit or a tool that does it ([`Volume::settle_uniform`]) stores the chunk as lists at the
//!   volume's level instead, uniform but for what the neighbours' lines say: the nodes of its
//!   first faces take the states the lines before it end in, the lines ending on the faces after
//!   it end in the states the neighbours there start in.

use crate::axis::{Axis, compose};
use crate::chunk::{Built, Chunk, ChunkView, WorkLine};
use crate::coords::ChunkKey;
use crate::level::change::{End, end_lines_on, ends_of, take_ends, uniform_fits};
use crate::level::dense::Dense;
use crate::level::read::LineReader;
use crate::volume::Volume;

/// The chunk at `key` as lists at the volume's level, `inside` but for what its face
/// neighbours' lines bind, and the neighbours before it whose lines' last cells had to change
/// (where two of them disagree on a node of one of the chunk's edges, see [`take_ends`]).
fn fit(volume: &Volume, key: ChunkKey, inside: bool) -> (Built, Vec<(ChunkKey, Built)>) {
    let mut d = Dense::new(volume.level);
    d.states.fill(inside);
    let n = d.n;
    let mut line = WorkLine::EMPTY;
    let mut ends: Vec<End> = Vec::new();
    for axis in Axis::ALL {
        let step = axis.unit_i64().as_ivec3();
        // The faces after the chunk: its lines end where the neighbour's lines start.
        let after = key.offset(step);
        let lattice = volume.level_of(after).min(volume.level);
        let f = n / lattice.cells();
        let mut reader = LineReader::new(volume.view(after), axis);
        for v in 0..lattice.cells() {
            for u in 0..lattice.cells() {
                reader.read(u, v, lattice, &mut line);
                let k = d.index(compose(axis, n, u * f, v * f));
                d.states[k] = line.states & 1 == 1;
            }
        }
        // The first faces: the chunk's own nodes, where lines before it end.
        ends.extend(ends_of(volume, key.offset(-step), axis, &d, |_, _| true));
    }
    take_ends(&mut d, ends);
    d.make_consistent();
    let mut neighbours = Vec::new();
    for normal in Axis::ALL {
        let before = key.offset(-normal.unit_i64().as_ivec3());
        if let Some(b) = end_lines_on(volume, before, normal, &d) {
            neighbours.push((before, b));
        }
    }
    (d.build(), neighbours)
}

impl Volume {
    /// Called by a writer after storing its chunks, whose previous contents are in `previous`
    /// (an undo record's): every one of them that was lists below the volume's level and is now
    /// uniform where a face neighbour's line contradicts that is stored as lists at the volume's
    /// level instead ([`fit`]). Chunks this writes are added to `previous` (their contents
    /// before the writer) and to `changed`; returns whether there were any.
    pub(crate) fn settle_uniform(
        &mut self,
        changed: &mut Vec<ChunkKey>,
        previous: &mut Vec<(ChunkKey, Option<Chunk>)>,
    ) -> bool {
        let below = |c: &Option<Chunk>, base| matches!(c, Some(Chunk::Lists(l)) if l.level() < base);
        let mut work: Vec<ChunkKey> = previous.iter().filter(|(_, c)| below(c, self.level)).map(|(k, _)| *k).collect();
        let mut wrote = false;
        // Each chunk settled here is then at the volume's level (or uniform where it fits), and a
        // neighbour is queued only when a rewrite made it uniform below that level, so this ends.
        while let Some(key) = work.pop() {
            let ChunkView::Uniform(inside) = self.view(key) else { continue };
            if uniform_fits(self, key, inside) {
                continue;
            }
            let (built, neighbours) = fit(self, key, inside);
            wrote = true;
            for (k, b) in std::iter::once((key, built)).chain(neighbours) {
                let old = self.put_built(k, b);
                if !previous.iter().any(|(j, _)| *j == k) {
                    previous.push((k, old.clone()));
                    changed.push(k);
                }
                if k != key && below(&old, self.level) && self.stored_level(k).is_none() {
                    work.push(k);
                }
            }
        }
        wrote
    }
}
