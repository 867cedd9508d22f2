//! The one writer of chunk lists: lines unpacked for editing ([`WorkLine`]) and assembled in
//! storage order into a chunk ([`ChunkBuilder`]), which every list writer goes through.

use super::*;

/// Maximum nodes per line (`16 << MAX_LEVEL` cells plus one).
pub(crate) const MAX_NODES: usize = 65;

/// Bits `0..=n`: the nodes of a line with `n` cells.
#[inline]
pub(crate) fn node_mask(n: usize) -> u128 {
    (1u128 << (n + 1)) - 1
}

/// The node states of a stored line (bit `i` for node `i`, `0..=n`), without unpacking its
/// crossings.
#[inline]
pub(crate) fn line_states(line: LineRef<'_>, level: Level) -> u128 {
    let full = node_mask(level.cells());
    let mut s = if line.start_inside { full } else { 0 };
    for q in line.positions() {
        s ^= full & !((1u128 << (edge_of(q, level) + 1)) - 1);
    }
    s
}

/// A line unpacked for editing: node states as bits and, per cell, the crossing data (valid only
/// on cells whose two nodes differ).
#[derive(Clone, Copy, Debug)]
pub(crate) struct WorkLine {
    pub(crate) states: u128,
    pub(crate) pos: [LocalPos; MAX_NODES - 1],
    pub(crate) nrm: [PackedNormal; MAX_NODES - 1],
}

impl WorkLine {
    pub(crate) const EMPTY: WorkLine =
        WorkLine { states: 0, pos: [LocalPos(0); MAX_NODES - 1], nrm: [PackedNormal(0); MAX_NODES - 1] };

    /// Unpacks a stored line.
    pub(crate) fn load(&mut self, line: LineRef<'_>, level: Level) {
        let n = level.cells();
        let mut s = if line.start_inside { node_mask(n) } else { 0 };
        for (q, &nr) in line.positions().zip(line.normals) {
            let e = edge_of(q, level);
            self.pos[e] = q;
            self.nrm[e] = nr;
            s ^= node_mask(n) & !((1u128 << (e + 1)) - 1);
        }
        self.states = s;
    }

    /// Cells whose two nodes differ (bit `e` for the cell between nodes `e` and `e + 1`).
    #[inline]
    pub(crate) fn changes(&self, n: usize) -> u128 {
        (self.states ^ (self.states >> 1)) & (node_mask(n) >> 1)
    }

    /// Equality of the stored meaning: states, and crossing data where the states change.
    pub(crate) fn same_as(&self, other: &WorkLine, n: usize) -> bool {
        if self.states != other.states {
            return false;
        }
        let mut c = self.changes(n);
        while c != 0 {
            let e = c.trailing_zeros() as usize;
            if self.pos[e] != other.pos[e] || self.nrm[e] != other.nrm[e] {
                return false;
            }
            c &= c - 1;
        }
        true
    }
}

/// What a finished build produced.
#[derive(Debug)]
pub(crate) enum Built {
    Uniform(bool),
    Lists(ChunkLists),
}

impl Built {
    pub(crate) fn into_chunk(self) -> Option<Chunk> {
        match self {
            Built::Uniform(false) => None,
            Built::Uniform(true) => Some(Chunk::Solid),
            Built::Lists(l) => Some(Chunk::Lists(l)),
        }
    }
}

/// Assembles a chunk line by line, in storage order. Reusable: keeps its buffers' capacity.
///
/// Crossings are written into buffers grown ahead of the writes (`positions[..m]` and
/// `normals[..m]` hold the ones written), so a line costs a length check and slice copies, not
/// a `Vec` growth check per value.
#[derive(Debug)]
pub(crate) struct ChunkBuilder {
    level: Level,
    /// The start state of x line 0 once it is pushed.
    corner: Option<bool>,
    nonempty: BitBuf,
    positions: Vec<u16>,
    normals: Vec<PackedNormal>,
    /// Crossings written.
    m: usize,
    family_start: [u32; 2],
}

impl Default for ChunkBuilder {
    fn default() -> Self {
        ChunkBuilder {
            level: Level::BASE,
            corner: None,
            nonempty: BitBuf::default(),
            positions: Vec::new(),
            normals: Vec::new(),
            m: 0,
            family_start: [0; 2],
        }
    }
}

impl ChunkBuilder {
    pub(crate) fn begin(&mut self, level: Level) {
        self.level = level;
        self.corner = None;
        self.nonempty.clear();
        self.m = 0;
    }

    /// Marks the start of the lines along `axis` (call in x, y, z order).
    pub(crate) fn begin_axis(&mut self, axis: Axis) {
        if axis != Axis::X {
            self.family_start[axis.index() - 1] = self.m as u32;
        }
    }

    /// Makes room for `k` more crossings.
    #[inline]
    fn room(&mut self, k: usize) {
        if self.m + k > self.positions.len() {
            self.grow(self.m + k);
        }
    }

    #[cold]
    fn grow(&mut self, need: usize) {
        let len = need.max(2 * self.positions.len()).max(1024);
        self.positions.resize(len, 0);
        self.normals.resize(len, PackedNormal(0));
    }

    /// Appends stored positions (end marks as they are) and their normals.
    #[inline(always)]
    fn write(&mut self, raw: &[u16], normals: &[PackedNormal]) {
        let (m, k) = (self.m, raw.len());
        self.room(k);
        let (dp, dn) = (&mut self.positions[m..m + k], &mut self.normals[m..m + k]);
        if k <= 8 {
            // A line's few crossings: a call to memcpy would cost more than the copy.
            for (i, (&q, &nr)) in raw.iter().zip(normals).enumerate() {
                dp[i] = q;
                dn[i] = nr;
            }
        } else {
            dp.copy_from_slice(raw);
            dn.copy_from_slice(normals);
        }
        self.m = m + k;
    }

    /// Appends one crossing (room must have been made).
    #[inline]
    fn write_one(&mut self, q: LocalPos, normal: PackedNormal) {
        debug_assert_eq!(q.0 & LAST, 0, "positions are even");
        self.positions[self.m] = q.0;
        self.normals[self.m] = normal;
        self.m += 1;
    }

    /// Marks the last written crossing as the end of its line.
    #[inline]
    fn mark_last(&mut self) {
        self.positions[self.m - 1] |= LAST;
    }

    /// Appends `count` uniform lines without crossings.
    #[inline]
    pub(crate) fn push_uniform(&mut self, state: bool, count: usize) {
        if count > 0 {
            self.corner.get_or_insert(state);
            self.nonempty.push_zeros(count);
        }
    }

    /// Appends `count` lines read from `cursor` and moves it past them. `corner` is the source
    /// chunk's corner state, which line 0 of the x family (if copied) carries.
    #[inline]
    pub(crate) fn copy_from(&mut self, cursor: &mut RawCursor<'_>, count: usize) {
        if count == 0 {
            return;
        }
        let src = cursor.lists;
        debug_assert_eq!(src.level(), self.level);
        self.corner.get_or_insert(src.corner());
        let (first, cross) = (cursor.index, cursor.cross);
        cursor.advance_to(cursor.index + count);
        self.nonempty.extend_from(cursor.nonempty.words(), first, count);
        self.write(&cursor.raw[cross..cursor.cross], &cursor.normals[cross..cursor.cross]);
    }

    /// Appends `count` lines read from `cursor` and moves it past them (a uniform view gives
    /// uniform lines).
    #[inline]
    pub(crate) fn copy_view(&mut self, cursor: &mut ViewCursor<'_>, count: usize) {
        if count == 0 {
            return;
        }
        match cursor {
            ViewCursor::Uniform(state) => self.push_uniform(*state, count),
            ViewCursor::Lists(c) => self.copy_from(&mut c.raw, count),
        }
    }

    /// Appends a stored line unchanged.
    #[inline]
    pub(crate) fn push_stored(&mut self, line: LineRef<'_>) {
        self.corner.get_or_insert(line.start_inside);
        self.nonempty.push(!line.raw.is_empty());
        self.write(line.raw, line.normals);
    }

    /// Appends the crossings of a work line (at the cells where its node states change).
    /// Pushes an edited line: the stored `line` as it is if `edited` means the same as `old`
    /// (its unpacked form), else `edited`; returns whether the line changed.
    #[inline]
    pub(crate) fn push_edited(&mut self, line: LineRef<'_>, old: &WorkLine, edited: &WorkLine, n: usize) -> bool {
        if edited.same_as(old, n) {
            self.push_stored(line);
            false
        } else {
            self.push_work(edited, n);
            true
        }
    }

    pub(crate) fn push_work(&mut self, line: &WorkLine, n: usize) {
        self.corner.get_or_insert(line.states & 1 == 1);
        let mut c = line.changes(n);
        self.nonempty.push(c != 0);
        if c == 0 {
            return;
        }
        self.room(c.count_ones() as usize);
        while c != 0 {
            let e = c.trailing_zeros() as usize;
            c &= c - 1;
            self.write_one(line.pos[e], line.nrm[e]);
        }
        self.mark_last();
    }

    /// Appends `line` with its crossings `p..q` replaced by `mid` (even positions, sorted, in
    /// cells after those of crossings `..p` and before those of `q..`), starting in `start`.
    #[inline]
    pub(crate) fn push_spliced(
        &mut self,
        start: bool,
        line: LineRef<'_>,
        p: usize,
        q: usize,
        mid: &[(LocalPos, PackedNormal)],
    ) {
        let (raw, normals) = (line.raw, line.normals);
        self.corner.get_or_insert(start);
        let k = raw.len();
        let out = p + mid.len() + (k - q);
        self.nonempty.push(out > 0);
        if out == 0 {
            return;
        }
        self.room(out);
        // One pair of destination slices for the whole line (a line holds a few crossings: a
        // slice copy per part and a room check per write cost more than the copying).
        let m = self.m;
        let (dp, dn) = (&mut self.positions[m..m + out], &mut self.normals[m..m + out]);
        let mut i = 0;
        let mut put = |(r, nr): (LocalPos, PackedNormal)| {
            (dp[i], dn[i]) = (r.0, nr);
            i += 1;
        };
        raw[..p].iter().zip(&normals[..p]).for_each(|(&r, &nr)| put((LocalPos(r), nr)));
        mid.iter().for_each(|&c| {
            debug_assert_eq!(c.0.0 & LAST, 0, "positions are even");
            put(c);
        });
        raw[q..].iter().zip(&normals[q..]).for_each(|(&r, &nr)| put((LocalPos(r), nr)));
        if p == k && k > 0 {
            // Stored crossing k - 1 carried the end mark and is no longer last.
            dp[p - 1] &= !LAST;
        }
        dp[out - 1] |= LAST;
        self.m = m + out;
    }

    /// Finishes the chunk: lists, or a uniform state when no line has a crossing.
    pub(crate) fn finish(&mut self) -> Built {
        let corner = self.corner.unwrap_or(false);
        if self.m == 0 {
            return Built::Uniform(corner);
        }
        Built::Lists(assemble(
            self.level,
            corner,
            self.family_start,
            &self.nonempty.words,
            &self.positions[..self.m],
            &self.normals[..self.m],
        ))
    }
}
