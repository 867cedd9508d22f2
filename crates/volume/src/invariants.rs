//! The invariants every volume keeps, checked exhaustively (for tests and debugging).

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use thiserror::Error;

use crate::axis::Axis;
use crate::chunk::{Chunk, ChunkLists, ChunkView, check_lists};
use crate::coords::{ChunkKey, edge_of};
use crate::volume::{KeyHasher, Volume};

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
#[cfg(test)]
pub(crate) fn states_from(lists: &ChunkLists, axis: Axis) -> Vec<u128> {
    states_and_ends(lists, axis, &mut Vec::new())
}

/// [`states_from`], and in `ends` the state after each line's last cell (bit `u + n v` of line
/// `(u, v)`, in words of 64 bits).
fn states_and_ends(lists: &ChunkLists, axis: Axis, ends: &mut Vec<u64>) -> Vec<u128> {
    let level = lists.level();
    let n = level.cells();
    let mut rows = vec![0u128; n * n];
    ends.clear();
    ends.resize((n * n).div_ceil(64), 0);
    let mut cursor = lists.cursor(axis, 0);
    if axis == Axis::X {
        // An x line is one row: its inside nodes are bit ranges.
        for (i, row) in rows.iter_mut().enumerate() {
            let line = cursor.next_line();
            ends[i / 64] |= u64::from(line.end_inside()) << (i % 64);
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
            let i = u + n * v;
            ends[i / 64] |= u64::from(line.end_inside()) << (i % 64);
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
        let chunks: Vec<(&ChunkKey, &Chunk)> = self.chunks.iter().collect();
        // First each chunk of lists on its own: its lists, and its axes agreeing on node states,
        // which gives the start and end states of its lines for the borders.
        let edges: HashMap<ChunkKey, Result<LineEdges, String>, BuildHasherDefault<KeyHasher>> = chunks
            .par_iter()
            .filter_map(|&(&key, chunk)| match chunk {
                Chunk::Lists(lists) => Some((key, LineEdges::of(lists))),
                Chunk::Solid => None,
            })
            .collect::<Vec<_>>()
            .into_iter()
            .collect();
        // Then every chunk against its neighbours. Chunks are checked independently (in
        // parallel); of several violations the one of the smallest key is reported, so the
        // answer does not depend on the thread count.
        let worst = chunks
            .par_iter()
            .filter_map(|&(&key, chunk)| self.check_chunk(key, chunk, &edges, known).err())
            .min_by_key(|v| v.key.0.to_array());
        match worst {
            Some(v) => Err(v),
            None => self.check_materials(),
        }
    }

    /// The invariants of one chunk: its lists, its level, its axes agreeing on node states (from
    /// `edges`, where every chunk of lists has its [`LineEdges::of`]), and continuity with the
    /// next chunk along each axis (and with an empty previous chunk).
    fn check_chunk(
        &self,
        key: ChunkKey,
        chunk: &Chunk,
        edges: &HashMap<ChunkKey, Result<LineEdges, String>, BuildHasherDefault<KeyHasher>>,
        known: &(dyn Fn(ChunkKey) -> bool + Sync),
    ) -> Result<(), InvariantViolation> {
        let fail = |what: String| InvariantViolation { key, what };
        let mine = match chunk {
            Chunk::Lists(_) => match edges.get(&key) {
                Some(Ok(e)) => Some(e),
                Some(Err(what)) => return Err(fail(what.clone())),
                None => unreachable!("every chunk of lists has its line edges"),
            },
            Chunk::Solid => None,
        };
        let here = ChunkView::of(Some(chunk));
        for axis in Axis::ALL {
            let step = axis.unit_i64().as_ivec3();
            let next_key = key.offset(step);
            let next = self.view(next_key);
            let prev_missing = !self.chunks.contains_key(&key.offset(-step)) && known(key.offset(-step));
            let next_known = known(next_key);
            // A uniform chunk is sampled at the volume's level, as edits sample it: the lines of
            // a finer neighbour between its nodes are not bound by it.
            let (lh, ln) = (level_of(here).unwrap_or(self.level), level_of(next).unwrap_or(self.level));
            let (nh, nn) = (lh.cells(), ln.cells());
            let a = axis.index();
            // Line `i`'s state after its last cell here, and before its first in the next chunk
            // (a chunk whose own check failed is read line by line, as it stands).
            let read_starts = |view: ChunkView<'_>, count: usize| -> Vec<u64> {
                let mut c = view.cursor(axis, 0);
                let mut bits = vec![0u64; count.div_ceil(64)];
                for i in 0..count {
                    bits[i / 64] |= u64::from(c.next_line().start_inside) << (i % 64);
                }
                bits
            };
            let next_starts = match (next, edges.get(&next_key)) {
                (ChunkView::Lists(_), Some(Ok(e))) => LineBits::Words(&e.starts[a]),
                (ChunkView::Lists(_), _) => LineBits::Read(read_starts(next, nn * nn)),
                (ChunkView::Uniform(inside), _) => LineBits::All(inside),
            };
            let here_ends = mine.map_or(LineBits::All(true), |e| LineBits::Words(&e.ends[a]));
            // Lines of the coarser level are lines of both; finer ones end between the other's nodes.
            let lc = lh.min(ln);
            let nc = lc.cells();
            let (fh, fn_) = (nh / nc, nn / nc);
            if next_known {
                if fh == 1 && fn_ == 1 {
                    // One level: every line against its continuation, a word at a time.
                    if let Some(w) = (0..(nh * nh).div_ceil(64)).find(|&w| here_ends.word(w) != next_starts.word(w)) {
                        let i = 64 * w + (here_ends.word(w) ^ next_starts.word(w)).trailing_zeros() as usize;
                        let (u, v) = (i % nh, i / nh);
                        return Err(fail(format!("{axis:?} line ({u}, {v}) ends unlike the next chunk starts")));
                    }
                } else {
                    for v in 0..nc {
                        for u in 0..nc {
                            if here_ends.bit(u * fh + nh * v * fh) != next_starts.bit(u * fn_ + nn * v * fn_) {
                                let (u, v) = (u * fh, v * fh);
                                return Err(fail(format!(
                                    "{axis:?} line ({u}, {v}) ends unlike the next chunk starts"
                                )));
                            }
                        }
                    }
                }
            }
            if prev_missing {
                let starts = mine.map_or(LineBits::All(true), |e| LineBits::Words(&e.starts[a]));
                let f = nh / lh.min(self.level).cells();
                for i in 0..nh * nh {
                    let (u, v) = (i % nh, i / nh);
                    if starts.bit(i) && u % f == 0 && v % f == 0 {
                        return Err(fail(format!("{axis:?} line ({u}, {v}) starts inside after an empty chunk")));
                    }
                }
            }
        }
        Ok(())
    }
}

/// What the border checks read of a chunk of lists that passed its own checks: the state of
/// each line before its first cell and after its last (per axis, bit `u + n v` of line `(u, v)`,
/// in words of 64 bits).
struct LineEdges {
    starts: [Vec<u64>; 3],
    ends: [Vec<u64>; 3],
}

impl LineEdges {
    /// A chunk's lists checked ([`check_lists`], and the three axes agreeing on every node),
    /// and its lines' start and end states, or what is wrong with it. The axes agree, so a line's
    /// start state is its first node's, read from the x rows.
    fn of(lists: &ChunkLists) -> Result<LineEdges, String> {
        check_lists(lists)?;
        let n = lists.level().cells();
        let mut ends: [Vec<u64>; 3] = Default::default();
        let rows = states_and_ends(lists, Axis::X, &mut ends[0]);
        for axis in [Axis::Y, Axis::Z] {
            if states_and_ends(lists, axis, &mut ends[axis.index()]) != rows {
                return Err(format!("lines along {axis:?} disagree with x lines on node states"));
            }
        }
        let words = (n * n).div_ceil(64);
        let mut starts: [Vec<u64>; 3] = std::array::from_fn(|_| vec![0u64; words]);
        for v in 0..n {
            for u in 0..n {
                let i = u + n * v;
                // x line (u, v) = (y, z): node (0, y, z); y line (z, x): node (x, 0, z); z line
                // (x, y): node (x, y, 0).
                let first = [rows[u + n * v] & 1, (rows[n * u] >> v) & 1, (rows[v] >> u) & 1];
                for (a, &b) in first.iter().enumerate() {
                    starts[a][i / 64] |= (b as u64) << (i % 64);
                }
            }
        }
        Ok(LineEdges { starts, ends })
    }
}

/// The level a chunk's lists are stored at (`None` for a uniform chunk).
fn level_of(view: ChunkView<'_>) -> Option<crate::coords::Level> {
    match view {
        ChunkView::Lists(l) => Some(l.level()),
        ChunkView::Uniform(_) => None,
    }
}

/// One bit per line of a chunk's axis (bit `u + n v` of line `(u, v)`; `n²` is a multiple of 64
/// at every level): a checked chunk's words, words read line by line, or a uniform chunk's one
/// state (no words made for it).
enum LineBits<'a> {
    Words(&'a [u64]),
    Read(Vec<u64>),
    All(bool),
}

impl LineBits<'_> {
    #[inline]
    fn word(&self, w: usize) -> u64 {
        match self {
            LineBits::Words(b) => b[w],
            LineBits::Read(b) => b[w],
            LineBits::All(inside) => {
                if *inside {
                    u64::MAX
                } else {
                    0
                }
            }
        }
    }

    #[inline]
    fn bit(&self, i: usize) -> bool {
        (self.word(i / 64) >> (i % 64)) & 1 == 1
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

    /// The border checks as they were written before [`LineEdges`]: every line's start and end
    /// read through cursors, chunk by chunk (the chunk's own checks first).
    fn check_by_cursors(v: &Volume, known: &dyn Fn(ChunkKey) -> bool) -> Result<(), InvariantViolation> {
        let mut keys: Vec<ChunkKey> = v.chunks.iter().map(|(k, _)| *k).collect();
        keys.sort_by_key(|k| k.0.to_array());
        for key in keys {
            let chunk = v.chunks.get(&key).unwrap();
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
            for axis in Axis::ALL {
                let step = axis.unit_i64().as_ivec3();
                let next = v.view(key.offset(step));
                let prev_missing = !v.chunks.contains_key(&key.offset(-step)) && known(key.offset(-step));
                let next_known = known(key.offset(step));
                let (lh, ln) = (level_of(here).unwrap_or(v.level), level_of(next).unwrap_or(v.level));
                let (nh, nn) = (lh.cells(), ln.cells());
                let ends: Vec<bool> = {
                    let mut c = here.cursor(axis, 0);
                    (0..nh * nh).map(|_| c.next_line().end_inside()).collect()
                };
                let starts: Vec<bool> = {
                    let mut c = next.cursor(axis, 0);
                    (0..nn * nn).map(|_| c.next_line().start_inside).collect()
                };
                let nc = lh.min(ln).cells();
                let (fh, fn_) = (nh / nc, nn / nc);
                for vv in 0..nc {
                    for u in 0..nc {
                        if next_known && ends[u * fh + nh * vv * fh] != starts[u * fn_ + nn * vv * fn_] {
                            let (u, vv) = (u * fh, vv * fh);
                            return Err(fail(format!("{axis:?} line ({u}, {vv}) ends unlike the next chunk starts")));
                        }
                    }
                }
                if prev_missing {
                    let mut c = here.cursor(axis, 0);
                    let f = nh / lh.min(v.level).cells();
                    for i in 0..nh * nh {
                        let (u, vv) = (i % nh, i / nh);
                        if c.next_line().start_inside && u % f == 0 && vv % f == 0 {
                            return Err(fail(format!("{axis:?} line ({u}, {vv}) starts inside after an empty chunk")));
                        }
                    }
                }
            }
        }
        v.check_materials()
    }

    /// A brush whose x lines see one sphere and whose y and z lines another: its edits leave
    /// axes that disagree.
    struct Liar(Sphere, Sphere);

    impl crate::brush::Brush for Liar {
        fn bounds(&self) -> crate::brush::Aabb {
            let (a, b) = (self.0.bounds(), self.1.bounds());
            crate::brush::Aabb::new(a.min.min(b.min), a.max.max(b.max))
        }
        fn field(&self, origin: DVec3, p: DVec3) -> f64 {
            self.0.field(origin, p)
        }
        fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<crate::brush::Span>) -> bool {
            if dir == DVec3::X { self.0.spans(origin, start, dir, out) } else { self.1.spans(origin, start, dir, out) }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(96))]
        /// The check by line edges finds what the check by cursors found, the same violation of
        /// the same chunk: consistent volumes, chunks swapped in from another solid, dropped,
        /// made solid, relevelled, cut by a brush whose axes disagree, on and off the grid, with
        /// some neighbours unknown (a streamed world's border).
        #[test]
        fn line_edges_find_what_the_cursors_found(
            a in (2.0f64..30.0, 2.0f64..30.0, 2.0f64..30.0, 3.0f64..14.0),
            b in (2.0f64..30.0, 2.0f64..30.0, 2.0f64..30.0, 3.0f64..14.0),
            on_grid in proptest::prelude::any::<bool>(),
            damage in proptest::collection::vec((0u8..6, 0i32..3, 0i32..3, 0i32..3), 0..4),
            unknown in proptest::collection::vec((0i32..3, 0i32..3, 0i32..3), 0..3),
        ) {
            let snap = |x: f64| if on_grid { x.round() } else { x };
            let sphere = |(x, y, z, r): (f64, f64, f64, f64)| {
                Sphere::new(DVec3::new(snap(x), snap(y), snap(z)), snap(r)).unwrap()
            };
            let mut v = Volume::new();
            v.add(&sphere(a)).unwrap();
            let mut other = Volume::new();
            other.add(&sphere(b)).unwrap();
            for (what, x, y, z) in damage {
                let key = ChunkKey::new(x, y, z);
                match what {
                    0 => match other.chunks.get(&key).cloned() {
                        Some(c) => {
                            v.chunks.insert(key, c);
                        }
                        None => {
                            v.chunks.remove(&key);
                        }
                    },
                    1 => {
                        v.chunks.remove(&key);
                    }
                    2 => {
                        v.chunks.insert(key, Chunk::Solid);
                    }
                    3 => {
                        let _ = v.set_chunk_level(key, Level::new(1).unwrap());
                    }
                    4 => {
                        let _ = v.set_chunk_level(key, Level::new(-1).unwrap());
                    }
                    _ => {
                        let c = DVec3::new(x as f64, y as f64, z as f64) * 16.0 + 8.0;
                        let liar = Liar(Sphere::new(c, 6.3).unwrap(), Sphere::new(c, 6.0).unwrap());
                        v.add(&liar).unwrap();
                    }
                }
            }
            let unknown: Vec<ChunkKey> = unknown.into_iter().map(|(x, y, z)| ChunkKey::new(x, y, z)).collect();
            let known = |k: ChunkKey| !unknown.contains(&k);
            proptest::prop_assert_eq!(v.check_invariants_within(&known), check_by_cursors(&v, &known));
            proptest::prop_assert_eq!(v.check_invariants(), check_by_cursors(&v, &|_| true));
        }
    }
}
