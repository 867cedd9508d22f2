//! The invariants every volume keeps, checked exhaustively (for tests and debugging).

use thiserror::Error;

use crate::axis::Axis;
use crate::chunk::{Chunk, ChunkLists, ChunkView, check_lists};
use crate::coords::{ChunkKey, edge_of};
use crate::volume::Volume;

/// A broken invariant: which chunk and what.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error("chunk {key:?}: {what}")]
pub struct InvariantViolation {
    /// The chunk.
    pub key: ChunkKey,
    /// What is wrong.
    pub what: String,
}

/// Node states of a chunk's own nodes (`0..n` on each axis) as read from the lines along one
/// axis, as `rows[y + n z]` with bit `x`.
pub(crate) fn states_from(lists: &ChunkLists, axis: Axis) -> Vec<u128> {
    let level = lists.level();
    let n = level.cells();
    let mut rows = vec![0u128; n * n];
    let mut cursor = lists.cursor(axis, 0);
    if axis == Axis::X {
        // An x line is one row: its inside nodes are bit ranges.
        for row in rows.iter_mut() {
            let line = cursor.next_line();
            // A crossing in cell `e` flips the state of the nodes after node `e`.
            let (mut inside, mut from) = (line.start_inside, 0);
            for e in line.positions().map(|q| edge_of(q, level)) {
                let to = (e + 1).min(n);
                if inside && to > from {
                    *row |= ((1u128 << (to - from)) - 1) << from;
                }
                (inside, from) = (!inside, to);
            }
            if inside && n > from {
                *row |= ((1u128 << (n - from)) - 1) << from;
            }
        }
        return rows;
    }
    // A y or z line is one bit of n rows: its start state and the flips after each crossing
    // are marked where they happen, then each row takes the XOR of the rows before it along the
    // axis (node j's state is the start state flipped once per crossing before it). That costs
    // a word per row and a bit per crossing, not a bit per inside node. Node j of y line (u, v)
    // = (z, x) is bit v of row j + n u; of z line (u, v) = (x, y), bit u of row v + n j.
    let step = if axis == Axis::Y { 1 } else { n };
    let first_row = |w: usize| if axis == Axis::Y { n * w } else { w };
    for v in 0..n {
        for u in 0..n {
            let line = cursor.next_line();
            let (bit, first) = if axis == Axis::Y { (1u128 << v, first_row(u)) } else { (1u128 << u, first_row(v)) };
            if line.start_inside {
                rows[first] ^= bit;
            }
            for e in line.positions().map(|q| edge_of(q, level)) {
                if e + 1 < n {
                    rows[first + step * (e + 1)] ^= bit;
                }
            }
        }
    }
    for w in 0..n {
        let first = first_row(w);
        for j in 1..n {
            rows[first + step * j] ^= rows[first + step * (j - 1)];
        }
    }
    rows
}

impl Volume {
    /// Verifies, for every chunk: sorted lists with at most one crossing per cell and none on a
    /// node; lists in chunks that are not uniform; x, y and z lines agreeing on every node state;
    /// and continuity across chunk borders (a line's state after its last cell equals the state
    /// the next chunk's line starts with; between chunks of different levels, on the lines of the
    /// coarser level, which both have).
    pub fn check_invariants(&self) -> Result<(), InvariantViolation> {
        self.check_invariants_within(&|_| true)
    }

    /// [`Volume::check_invariants`] for a part of a larger solid held in memory (a streamed
    /// world): continuity across a border is checked only where `known` says the neighbour's
    /// contents are present (loaded, even if empty); a border with a chunk not in memory is
    /// bound by what that chunk will hold, which this volume cannot see.
    pub fn check_invariants_within(&self, known: &(dyn Fn(ChunkKey) -> bool + Sync)) -> Result<(), InvariantViolation> {
        use rayon::prelude::*;
        // Chunks are checked independently (in parallel); of several violations the one of the
        // smallest key is reported, so the answer does not depend on the thread count.
        let chunks: Vec<(&ChunkKey, &Chunk)> = self.chunks.iter().collect();
        let worst = chunks
            .par_iter()
            .filter_map(|&(&key, chunk)| self.check_chunk(key, chunk, known).err())
            .min_by_key(|v| v.key.0.to_array());
        match worst {
            Some(v) => Err(v),
            None => self.check_materials(),
        }
    }

    /// The invariants of one chunk: its lists, its level, its axes agreeing on node states, and
    /// continuity with the next chunk along each axis (and with an empty previous chunk).
    fn check_chunk(
        &self,
        key: ChunkKey,
        chunk: &Chunk,
        known: &(dyn Fn(ChunkKey) -> bool + Sync),
    ) -> Result<(), InvariantViolation> {
        let fail = |what: String| InvariantViolation { key, what };
        if let Chunk::Lists(lists) = chunk {
            check_lists(lists).map_err(fail)?;
            let from_x = states_from(lists, Axis::X);
            for axis in [Axis::Y, Axis::Z] {
                if states_from(lists, axis) != from_x {
                    return Err(fail(format!("lines along {axis:?} disagree with x lines on node states")));
                }
            }
        }
        let here = ChunkView::of(Some(chunk));
        let level_of = |v: ChunkView<'_>| match v {
            ChunkView::Lists(l) => Some(l.level()),
            ChunkView::Uniform(_) => None,
        };
        for axis in Axis::ALL {
            let step = axis.unit_i64().as_ivec3();
            let next = self.view(key.offset(step));
            let prev_missing = !self.chunks.contains_key(&key.offset(-step)) && known(key.offset(-step));
            let next_known = known(key.offset(step));
            // A uniform chunk is sampled at the volume's level, as edits sample it: the lines of
            // a finer neighbour between its nodes are not bound by it.
            let (lh, ln) = (level_of(here).unwrap_or(self.level), level_of(next).unwrap_or(self.level));
            let (nh, nn) = (lh.cells(), ln.cells());
            let ends: Vec<bool> = {
                let mut c = here.cursor(axis, 0);
                (0..nh * nh).map(|_| c.next_line().end_inside()).collect()
            };
            let starts: Vec<bool> = {
                let mut c = next.cursor(axis, 0);
                (0..nn * nn).map(|_| c.next_line().start_inside).collect()
            };
            // Lines of the coarser level are lines of both; finer ones end between the other's nodes.
            let lc = lh.min(ln);
            let nc = lc.cells();
            let (fh, fn_) = (nh / nc, nn / nc);
            for v in 0..nc {
                for u in 0..nc {
                    if next_known && ends[u * fh + nh * v * fh] != starts[u * fn_ + nn * v * fn_] {
                        let (u, v) = (u * fh, v * fh);
                        return Err(fail(format!("{axis:?} line ({u}, {v}) ends unlike the next chunk starts")));
                    }
                }
            }
            if prev_missing {
                let mut c = here.cursor(axis, 0);
                let f = nh / lh.min(self.level).cells();
                for i in 0..nh * nh {
                    let (u, v) = (i % nh, i / nh);
                    if c.next_line().start_inside && u % f == 0 && v % f == 0 {
                        return Err(fail(format!("{axis:?} line ({u}, {v}) starts inside after an empty chunk")));
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use glam::{DQuat, DVec3};

    use super::*;
    use crate::Level;
    use crate::axis::compose;
    use crate::brush::{Cuboid, Sphere};

    /// The node states read one node at a time, as they were before runs.
    fn states_node_by_node(lists: &ChunkLists, axis: Axis) -> Vec<u128> {
        let level = lists.level();
        let n = level.cells();
        let mut rows = vec![0u128; n * n];
        let mut cursor = lists.cursor(axis, 0);
        for v in 0..n {
            for u in 0..n {
                let line = cursor.next_line();
                let mut s = line.start_inside;
                let mut next = line.positions().map(|q| edge_of(q, level)).peekable();
                for j in 0..n {
                    if s {
                        let [x, y, z] = compose(axis, j, u, v);
                        rows[y + n * z] |= 1 << x;
                    }
                    if next.next_if(|&e| e == j).is_some() {
                        s = !s;
                    }
                }
            }
        }
        rows
    }

    #[test]
    fn runs_give_the_states_read_node_by_node_at_every_level_on_and_off_the_grid() {
        let mut v = Volume::new();
        // On nodes and half cells, off the grid, through chunk faces, rotated.
        v.add(&Cuboid::new(DVec3::new(16.0, 8.0, 8.5), DVec3::new(6.0, 4.0, 16.0)).unwrap()).unwrap();
        v.add(&Sphere::new(DVec3::new(3.3, 17.9, 12.1), 7.7).unwrap()).unwrap();
        v.subtract(
            &Cuboid::oriented(DVec3::new(10.0, 12.0, 9.0), DVec3::new(5.0, 2.0, 3.0), DQuat::from_rotation_z(0.7), 0.0)
                .unwrap(),
        )
        .unwrap();
        v.set_chunk_level(ChunkKey::new(0, 0, 0), Level::new(1).unwrap());
        v.set_chunk_level(ChunkKey::new(1, 0, 0), Level::new(2).unwrap());
        let mut seen = 0;
        for (_, chunk) in v.chunks() {
            if let Chunk::Lists(lists) = chunk {
                for axis in Axis::ALL {
                    assert_eq!(states_from(lists, axis), states_node_by_node(lists, axis), "{axis:?}");
                }
                seen += 1;
            }
        }
        assert!(seen >= 4, "{seen} chunks with lists");
        v.check_invariants().unwrap();
    }
}
