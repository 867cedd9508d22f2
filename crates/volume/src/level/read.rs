//! Reading lines and faces of a volume at any level, whatever the levels of the chunks that
//! store them: a finer chunk is sampled (every `2^d`-th line and node, the one crossing of each
//! coarse edge whose ends differ), a coarser one refined (the 1D rule along a line, the face
//! table across a face).
//!
//! The effective data of a shared face or chunk edge, which every chunk around it meshes, is
//! that of the coarsest chunk around it (see [`effective_face`]).

use glam::IVec3;

use crate::axis::{Axis, compose};
use std::cell::RefCell;
use std::rc::Rc;

use crate::chunk::{ChunkLists, ChunkView, FamilyBits, RawCursor, WorkLine, node_mask};
use crate::coords::{ChunkKey, Level, edge_of};
use crate::level::face::{FaceGrid, NONE, pack};
use crate::volume::Volume;

/// The level every chunk is meshed at: a list chunk's own level, lowered to at most `cap(key)`
/// where a cap is given (level of detail); a uniform chunk (which has no level of its own) at
/// the highest level among its list neighbours across a face or an edge, so a uniform chunk
/// next to a fine one never lowers the seam, or the volume's level where it has none.
/// It also keeps, for the reads of one block, each chunk family's start states and nonempty
/// bits once derived (a block reads lines of up to 19 chunks in no single order).
pub(crate) struct LevelMap<'v> {
    pub(crate) volume: &'v Volume,
    pub(crate) cap: Option<&'v (dyn Fn(ChunkKey) -> Level + Sync)>,
    /// One chunk taken at another level (a level change being computed).
    pub(crate) replace: Option<(ChunkKey, Level)>,
    families: RefCell<Vec<(ChunkKey, Axis, Rc<Family>)>>,
}

/// What reading any line of one chunk family needs, derived once.
pub(crate) struct Family {
    starts: FamilyBits,
    nonempty: FamilyBits,
}

impl Family {
    fn of(lists: &ChunkLists, axis: Axis) -> Rc<Family> {
        Rc::new(Family { starts: lists.family_starts(axis), nonempty: lists.family_nonempty(axis) })
    }
}

impl<'v> LevelMap<'v> {
    pub(crate) fn new(
        volume: &'v Volume,
        cap: Option<&'v (dyn Fn(ChunkKey) -> Level + Sync)>,
        replace: Option<(ChunkKey, Level)>,
    ) -> Self {
        LevelMap { volume, cap, replace, families: RefCell::new(Vec::new()) }
    }

    pub(crate) fn stored(volume: &'v Volume) -> Self {
        Self::new(volume, None, None)
    }

    /// A reader of the lines of `key` along `axis`, sharing what earlier readers derived.
    pub(crate) fn reader(&self, key: ChunkKey, axis: Axis) -> LineReader<'v> {
        let view = self.volume.view(key);
        let ChunkView::Lists(lists) = view else { return LineReader::new(view, axis) };
        let mut families = self.families.borrow_mut();
        let family = match families.iter().find(|(k, a, _)| *k == key && *a == axis) {
            Some((_, _, f)) => f.clone(),
            None => {
                let f = Family::of(lists, axis);
                families.push((key, axis, f.clone()));
                f
            }
        };
        LineReader { view, axis, family: Some(family), cursor: None, next: 0 }
    }

    fn capped(&self, key: ChunkKey, l: Level) -> Level {
        match self.cap {
            Some(c) => l.min(c(key)),
            None => l,
        }
    }

    /// The level of a list chunk (`None` for a uniform one).
    fn list_level(&self, key: ChunkKey) -> Option<Level> {
        if let Some((k, l)) = self.replace
            && k == key
        {
            return Some(l);
        }
        match self.volume.view(key) {
            ChunkView::Lists(l) => Some(self.capped(key, l.level())),
            ChunkView::Uniform(_) => None,
        }
    }

    /// The level chunk `key` is meshed at, where anything decides it: a list chunk's own, a
    /// uniform chunk's finest list neighbour's across a face or an edge. `None` for a uniform
    /// chunk with no list chunk across a face or an edge: no surface crosses its faces (the
    /// chunks that share them are uniform too), its block has one state (see
    /// [`Volume::plain_block_uniform`]) and no block reads a crossing from it, so its level
    /// concerns no seam and agrees with any (neighbourhood is symmetric: a chunk beside it is
    /// uniform itself).
    pub(crate) fn decided_level(&self, key: ChunkKey) -> Option<Level> {
        self.list_level(key)
            .or_else(|| crate::level::NEIGHBOURS.iter().filter_map(|&d| self.list_level(key.offset(d))).max())
    }

    /// The level chunk `key` is meshed at ([`LevelMap::decided_level`], else the volume's).
    pub(crate) fn get(&self, key: ChunkKey) -> Level {
        self.decided_level(key).unwrap_or_else(|| self.capped(key, self.volume.level))
    }
}

/// Reads lines of one chunk family, fastest in increasing index order (a lower index opens a
/// new cursor).
pub(crate) struct LineReader<'a> {
    view: ChunkView<'a>,
    axis: Axis,
    family: Option<Rc<Family>>,
    cursor: Option<RawCursor<'a>>,
    next: usize,
}

impl<'a> LineReader<'a> {
    pub(crate) fn new(view: ChunkView<'a>, axis: Axis) -> Self {
        LineReader { view, axis, family: None, cursor: None, next: 0 }
    }

    /// Line `(u, v)` at `level` into `out` (node states `0..=n` and the crossings of the edges
    /// whose nodes differ). `false` where the chunk is coarser than `level` and holds no line
    /// there.
    pub(crate) fn read(&mut self, u: usize, v: usize, level: Level, out: &mut WorkLine) -> bool {
        let n = level.cells();
        let stored = match self.view {
            ChunkView::Uniform(s) => {
                out.states = if s { node_mask(n) } else { 0 };
                return true;
            }
            ChunkView::Lists(l) => l.level(),
        };
        if stored >= level {
            let f = 1usize << (stored.get() - level.get());
            let line = self.stored_line(u * f, v * f, stored);
            if f == 1 {
                out.load(line, stored);
            } else {
                sample_line(line, stored, level, out);
            }
            true
        } else {
            let f = 1usize << (level.get() - stored.get());
            if !u.is_multiple_of(f) || !v.is_multiple_of(f) {
                return false;
            }
            let mut coarse = WorkLine::EMPTY;
            coarse.load(self.stored_line(u / f, v / f, stored), stored);
            refine_line(&coarse, stored, level, out);
            true
        }
    }

    /// Stored line `(u, v)` of the chunk (at its own `level`).
    fn stored_line(&mut self, u: usize, v: usize, level: Level) -> crate::chunk::LineRef<'a> {
        let ChunkView::Lists(lists) = self.view else { unreachable!("stored lines are read from lists") };
        let n = level.cells();
        let index = u + n * v;
        let family = self.family.get_or_insert_with(|| Family::of(lists, self.axis)).clone();
        match self.cursor.as_mut() {
            Some(c) if index >= self.next => c.advance_to(index),
            _ => self.cursor = Some(lists.raw_cursor_from(self.axis, index, &family.nonempty)),
        }
        let c = self.cursor.as_mut().expect("made above");
        let line = c.next_with(family.starts.get(index));
        self.next = index + 1;
        line
    }
}

/// The stored `line` (at `from`) sampled at the coarser `to`: every `2^d`-th node, and on each
/// coarse edge whose ends differ the first crossing of the fine edges it covers. Read straight
/// from the stored crossings (a coarse view reads many lines: unpacking each at the fine level
/// first cost more than the rest of the read).
pub(crate) fn sample_line(line: crate::chunk::LineRef<'_>, from: Level, to: Level, out: &mut WorkLine) {
    let shift = from.get() - to.get();
    let n = to.cells();
    let mut inside = line.start_inside;
    let mut states = 0u128;
    // Coarse nodes below `next` have their states; coarse edge `last` has its first crossing.
    let (mut next, mut last) = (0usize, usize::MAX);
    for (q, &normal) in line.positions().zip(line.normals) {
        let k = edge_of(q, from);
        let e = k >> shift;
        // Coarse nodes up to `e` lie at or before fine node `k`: before this crossing.
        if inside {
            states |= node_mask(e) & !((1u128 << next) - 1);
        }
        next = e + 1;
        if e != last {
            out.pos[e] = q;
            out.nrm[e] = normal;
            last = e;
        }
        inside = !inside;
    }
    if inside {
        states |= node_mask(n) & !((1u128 << next) - 1);
    }
    out.states = states;
}

/// `coarse` (at `from`) refined to the finer `to` by the 1D rule: each crossing stays where it
/// is and the new nodes take the side of it they lie on.
pub(crate) fn refine_line(coarse: &WorkLine, from: Level, to: Level, out: &mut WorkLine) {
    let f = 1usize << (to.get() - from.get());
    let n = to.cells();
    let s_fine = to.steps_per_cell();
    let changes = coarse.changes(from.cells());
    let mut states = 0u128;
    for j in 0..=n {
        let e = j / f;
        let lower = (coarse.states >> e) & 1 == 1;
        let st = if j % f == 0 {
            lower
        } else if (changes >> e) & 1 == 1 {
            let q = adjusted(coarse.pos[e], s_fine);
            if ((j as u32) * s_fine) < q.0 as u32 { lower } else { !lower }
        } else {
            lower
        };
        states |= (st as u128) << j;
    }
    out.states = states;
    let mut c = changes;
    while c != 0 {
        let e = c.trailing_zeros() as usize;
        c &= c - 1;
        let q = adjusted(coarse.pos[e], s_fine);
        let k = edge_of(q, to);
        out.pos[k] = q;
        out.nrm[k] = coarse.nrm[e];
    }
    debug_assert_eq!(out.changes(n).count_ones(), changes.count_ones());
}

/// A position moved two steps down where it sits on a node `steps` apart (positions in files
/// written before levels could change).
#[inline]
fn adjusted(q: crate::coords::LocalPos, steps: u32) -> crate::coords::LocalPos {
    if (q.0 as u32).is_multiple_of(steps) { crate::coords::LocalPos(q.0 - 2) } else { q }
}

/// The `(u, v)` index of the line along `axis` through the block-local point `p`.
#[inline]
pub(crate) fn line_uv(axis: Axis, p: [usize; 3]) -> (usize, usize) {
    let (ua, va) = axis.across();
    (p[ua.index()], p[va.index()])
}

fn unit(a: Axis) -> IVec3 {
    a.unit_i64().as_ivec3()
}

/// The chunk-edge line along `axis` at the minimum corner (across coordinates 0, 0) of `owner`,
/// at `level`: the data of the coarsest of the four chunks around it, refined to `level`.
pub(crate) fn effective_line(map: &LevelMap<'_>, axis: Axis, owner: ChunkKey, level: Level, out: &mut WorkLine) {
    let (p, q) = axis.across();
    let around = [owner, owner.offset(-unit(p)), owner.offset(-unit(q)), owner.offset(-unit(p) - unit(q))];
    let coarsest = around.iter().map(|&k| map.get(k)).min().expect("four chunks");
    let at = coarsest.min(level);
    let mut reader = map.reader(owner, axis);
    let mut line = WorkLine::EMPTY;
    let ok = reader.read(0, 0, at, &mut line);
    debug_assert!(ok, "a chunk is never coarser than the coarsest around it");
    if at < level {
        refine_line(&line, at, level, out);
    } else {
        *out = line;
    }
}

/// The face normal to `normal` at the minimum face of `owner`, at `level`: the data of the
/// coarser of its two chunks (refined by the face table where `level` is finer), its border
/// lines those of the coarsest chunks around them ([`effective_line`]). Every chunk that meshes
/// this face reads exactly this, so their contours on it agree.
pub(crate) fn effective_face(map: &LevelMap<'_>, normal: Axis, owner: ChunkKey, level: Level) -> FaceGrid {
    let lf = map.get(owner).min(map.get(owner.offset(-unit(normal))));
    if level <= lf { read_face(map, normal, owner, level) } else { read_face(map, normal, owner, lf).refine_to(level) }
}

/// The face of `owner` at `level` (at most the owner's level) with its border lines replaced by
/// their effective lines and made consistent.
fn read_face(map: &LevelMap<'_>, normal: Axis, owner: ChunkKey, level: Level) -> FaceGrid {
    let (ua, va) = normal.across();
    let n = level.cells();
    let mut g = FaceGrid::uniform(level, normal, false);
    let mut line = WorkLine::EMPTY;
    // Lines along u (rows j) and along v (columns i) of the owner.
    for (d, axis) in [(0u8, ua), (1, va)] {
        let mut reader = map.reader(owner, axis);
        let mut ks: Vec<(usize, (usize, usize))> = (0..n)
            .map(|k| {
                let p = if d == 0 { compose(normal, 0, 0, k) } else { compose(normal, 0, k, 0) };
                (k, line_uv(axis, p))
            })
            .collect();
        ks.sort_by_key(|&(_, (u, v))| u + n * v);
        for (k, (u, v)) in ks {
            let ok = reader.read(u, v, level, &mut line);
            debug_assert!(ok, "read at or below the owner's level");
            put_line(&mut g, d, k, &line);
        }
    }
    // Border lines: j = 0 and i = 0 start at the owner, j = n and i = n at its neighbours.
    let borders = [(0u8, 0usize, owner), (0, n, owner.offset(unit(va))), (1, 0, owner), (1, n, owner.offset(unit(ua)))];
    for (d, k, key) in borders {
        let axis = if d == 0 { ua } else { va };
        effective_line(map, axis, key, level, &mut line);
        put_line(&mut g, d, k, &line);
    }
    g.make_consistent();
    g
}

/// Writes `line` (states `0..=n` and crossings) as row `k` (d = 0, along u) or column `k`
/// (d = 1, along v) of `g`.
fn put_line(g: &mut FaceGrid, d: u8, k: usize, line: &WorkLine) {
    let n = g.n;
    let changes = line.changes(n);
    for t in 0..=n {
        let (i, j) = if d == 0 { (t, k) } else { (k, t) };
        g.set_state(i, j, (line.states >> t) & 1 == 1);
        if t < n {
            let c = if (changes >> t) & 1 == 1 { pack(line.pos[t], line.nrm[t]) } else { NONE };
            g.set_crossing((d, i, j), c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brush::Sphere;
    use glam::DVec3;

    /// The sampling as first written: the fine line unpacked, then every `2^d`-th node and the
    /// first fine change in each coarse edge.
    fn sample_unpacked(fine: &WorkLine, from: Level, to: Level, out: &mut WorkLine) {
        let f = 1usize << (from.get() - to.get());
        let n = to.cells();
        out.states = (0..=n).fold(0, |s, j| s | ((fine.states >> (j * f)) & 1) << j);
        let fine_changes = fine.changes(from.cells());
        let mut c = out.changes(n);
        while c != 0 {
            let e = c.trailing_zeros() as usize;
            c &= c - 1;
            let window = (fine_changes >> (e * f)) & ((1u128 << f) - 1);
            let k = e * f + window.trailing_zeros() as usize;
            out.pos[e] = fine.pos[k];
            out.nrm[e] = fine.nrm[k];
        }
    }

    #[test]
    fn lines_sampled_from_their_stored_crossings_are_the_unpacked_lines_sampled() {
        // Thin walls and small balls: several fine crossings in one coarse edge, lines that
        // start inside, crossings in the first and last cells.
        let mut v = Volume::with_level(Level::FINEST);
        v.add(&Sphere::new(DVec3::new(8.1, 7.9, 8.3), 7.95).unwrap()).unwrap();
        v.subtract(&Sphere::new(DVec3::new(8.1, 7.9, 8.3), 7.6).unwrap()).unwrap();
        // Nested shells a fine cell or less apart: three crossings in one coarse edge.
        for (i, r) in [5.0, 4.8, 4.55, 4.35, 4.1, 3.85].into_iter().enumerate() {
            let ball = Sphere::new(DVec3::new(8.05, 8.1, 7.95), r).unwrap();
            if i % 2 == 0 {
                v.add(&ball).unwrap()
            } else {
                v.subtract(&ball).unwrap()
            };
        }
        for i in 0..12 {
            let c = DVec3::new(2.0 + i as f64 * 1.1, 15.9 - i as f64 * 1.3, 0.2 + i as f64 * 1.37);
            v.add(&Sphere::new(c, 0.2 + 0.1 * i as f64).unwrap()).unwrap();
        }
        // The same chunk stored one level lower, sampled from there too.
        let mut lower = v.clone();
        let key = ChunkKey::new(0, 0, 0);
        lower.set_chunk_level(key, Level::new(1).unwrap());
        assert_eq!(lower.stored_level(key), Some(Level::new(1).unwrap()));
        let (mut fast, mut fine, mut slow) = (WorkLine::EMPTY, WorkLine::EMPTY, WorkLine::EMPTY);
        let mut from_middle = 0;
        for axis in Axis::ALL {
            let (mut reader, mut full) =
                (LineReader::new(lower.view(key), axis), LineReader::new(lower.view(key), axis));
            for vv in 0..16 {
                for u in 0..16 {
                    assert!(reader.read(u, vv, Level::BASE, &mut fast));
                    assert!(full.read(2 * u, 2 * vv, Level::new(1).unwrap(), &mut fine));
                    sample_unpacked(&fine, Level::new(1).unwrap(), Level::BASE, &mut slow);
                    assert!(fast.same_as(&slow, 16), "{axis:?} {u} {vv} from level 1");
                    from_middle += (fine.changes(32).count_ones() > fast.changes(16).count_ones()) as usize;
                }
            }
        }
        assert!(from_middle > 50, "{from_middle} lines from level 1 with crossings the sampling passes over");
        let (mut checked, mut odd) = (0, 0);
        for axis in Axis::ALL {
            for to in [Level::BASE, Level::new(1).unwrap()] {
                let (n, f) = (to.cells(), 1 << (2 - to.get()));
                let (mut reader, mut full) = (LineReader::new(v.view(key), axis), LineReader::new(v.view(key), axis));
                for vv in 0..n {
                    for u in 0..n {
                        assert!(reader.read(u, vv, to, &mut fast));
                        assert!(full.read(u * f, vv * f, Level::FINEST, &mut fine));
                        sample_unpacked(&fine, Level::FINEST, to, &mut slow);
                        assert!(fast.same_as(&slow, n), "{axis:?} {u} {vv} at {to:?}");
                        checked += (fine.changes(64).count_ones() > fast.changes(n).count_ones()) as usize;
                        let fc = fine.changes(64);
                        odd += (0..n).filter(|e| ((fc >> (e * f)) & ((1 << f) - 1)).count_ones() >= 3).count();
                    }
                }
            }
        }
        assert!(checked > 100, "{checked} lines with crossings the sampling passes over");
        assert!(odd > 20, "{odd} coarse edges over three or more fine crossings");
    }
}
