//! Storage of one chunk: the sorted crossing lists of every grid line through it, along x, y, z.
//!
//! Layout of a [`ChunkLists`] at level `k` (`n = 16 << k` cells per side):
//! - lines along `axis` are indexed by `(u, v)` over [`Axis::across`], `index = u + n v`, and the
//!   three families are stored one after the other (x, y, z): `3 n²` lines in all;
//! - `bits` holds one *start bit* per line (is the line's first node inside), then the crossing
//!   count of every line in unary (`count` one bits and a zero), so an empty line costs two bits;
//! - `crossings` holds every crossing in line order, in one allocation: first all chunk-local
//!   fixed-point positions ([`LocalPos`]), then all octahedral normals in the same order.
//!
//! A line covers the nodes `0..=n` of its chunk (node `n` belongs to the next chunk along the
//! axis) and so the cells `0..n`. Because of the node-state invariant a line has at most one
//! crossing per cell, strictly inside the cell, exactly where its two nodes differ.

use serde::{Deserialize, Serialize};

use crate::axis::Axis;
use crate::bits::{BitBuf, bit, ones_run, skip_zeros};
use crate::coords::{Level, LocalPos, edge_of};
use crate::normal::PackedNormal;

/// The crossing lists of a chunk that is neither all empty nor all solid.
///
/// Deserialisation checks the structure (see [`crate::Volume::check_invariants`] for what) and
/// rejects malformed data with an error instead of storing it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "RawChunkLists")]
pub struct ChunkLists {
    level: Level,
    bits: Box<[u64]>,
    /// Per axis: bit offset (into the unary part of `bits`) and crossing index of its first line.
    axis_start: [(u32, u32); 3],
    /// Positions, then normals: `2 m` values for `m` crossings.
    crossings: Box<[u16]>,
}

/// Unchecked deserialised form of [`ChunkLists`].
#[derive(Deserialize)]
struct RawChunkLists {
    level: Level,
    bits: Box<[u64]>,
    axis_start: [(u32, u32); 3],
    crossings: Box<[u16]>,
}

impl TryFrom<RawChunkLists> for ChunkLists {
    type Error = String;

    fn try_from(r: RawChunkLists) -> Result<Self, String> {
        let lists = ChunkLists { level: r.level, bits: r.bits, axis_start: r.axis_start, crossings: r.crossings };
        if !lists.crossings.len().is_multiple_of(2) {
            return Err("positions and normals differ in length".into());
        }
        let n = lists.level.cells();
        if lists.bits.len() * 64 < 6 * n * n + lists.positions().len() {
            return Err("chunk bit stream too short".into());
        }
        check_lists(&lists)?;
        Ok(lists)
    }
}

/// A stored chunk. Chunks missing from the volume's map are all empty.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Chunk {
    /// Every node of the chunk is inside.
    Solid,
    /// Crossing lists.
    Lists(Box<ChunkLists>),
}

/// One line of a chunk: its first node's state and its crossings in increasing order.
#[derive(Clone, Copy, Debug)]
pub struct LineRef<'a> {
    /// Whether node 0 of the line is inside.
    pub start_inside: bool,
    /// Chunk-local fixed-point positions, strictly increasing, at most one per cell.
    pub positions: &'a [LocalPos],
    /// The outward normal at each crossing.
    pub normals: &'a [PackedNormal],
}

impl ChunkLists {
    /// The chunk's resolution level.
    pub fn level(&self) -> Level {
        self.level
    }

    /// Number of crossings stored, all axes.
    pub fn crossing_count(&self) -> usize {
        self.crossings.len() / 2
    }

    /// Normals of all crossings in storage order.
    fn normals(&self) -> &[PackedNormal] {
        &self.crossings[self.crossings.len() / 2..]
    }

    /// Number of crossings on lines along `axis`.
    pub fn axis_crossing_count(&self, axis: Axis) -> usize {
        let a = axis.index();
        let end = if a == 2 { self.crossing_count() as u32 } else { self.axis_start[a + 1].1 };
        (end - self.axis_start[a].1) as usize
    }

    fn lines_per_axis(&self) -> usize {
        let n = self.level.cells();
        n * n
    }

    fn unary_offset(&self) -> usize {
        3 * self.lines_per_axis()
    }

    /// Whether node 0 of line `index` along `axis` is inside.
    #[inline]
    pub fn start_inside(&self, axis: Axis, index: usize) -> bool {
        bit(&self.bits, axis.index() * self.lines_per_axis() + index)
    }

    /// The line `(u, v)` along `axis`.
    pub fn line(&self, axis: Axis, u: usize, v: usize) -> LineRef<'_> {
        let n = self.level.cells();
        self.cursor(axis, u + n * v).next_line()
    }

    /// A cursor positioned at line `index` along `axis`, reading lines in index order.
    pub(crate) fn cursor(&self, axis: Axis, index: usize) -> LineCursor<'_> {
        let (b0, c0) = self.axis_start[axis.index()];
        let (bitpos, ones) = skip_zeros(&self.bits, self.unary_offset() + b0 as usize, index);
        LineCursor { lists: self, axis, index, bit: bitpos, cross: c0 as usize + ones }
    }

    /// Bytes held by positions, normals and the bit stream plus this struct (its box).
    pub(crate) fn heap_bytes(&self) -> (usize, usize, usize) {
        (
            std::mem::size_of_val(self.positions()),
            std::mem::size_of_val(self.normals()),
            std::mem::size_of_val(&*self.bits) + std::mem::size_of::<ChunkLists>(),
        )
    }

    /// All crossing positions in storage order (for tests and statistics).
    pub fn positions(&self) -> &[LocalPos] {
        &self.crossings[..self.crossings.len() / 2]
    }
}

/// Reads the lines of one axis family in index order.
#[derive(Debug)]
pub(crate) struct LineCursor<'a> {
    lists: &'a ChunkLists,
    axis: Axis,
    index: usize,
    bit: usize,
    cross: usize,
}

impl<'a> LineCursor<'a> {
    /// Moves forward to line `index` (not backwards).
    #[inline]
    pub(crate) fn advance_to(&mut self, index: usize) {
        debug_assert!(index >= self.index);
        let (bit, ones) = skip_zeros(&self.lists.bits, self.bit, index - self.index);
        self.bit = bit;
        self.cross += ones;
        self.index = index;
    }

    #[inline]
    pub(crate) fn next_line(&mut self) -> LineRef<'a> {
        let count = ones_run(&self.lists.bits, self.bit);
        let r = LineRef {
            start_inside: self.lists.start_inside(self.axis, self.index),
            positions: &self.lists.positions()[self.cross..self.cross + count],
            normals: &self.lists.normals()[self.cross..self.cross + count],
        };
        self.bit += count + 1;
        self.cross += count;
        self.index += 1;
        r
    }
}

/// Read access to a chunk whatever its storage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum ChunkView<'a> {
    Uniform(bool),
    Lists(&'a ChunkLists),
}

impl<'a> ChunkView<'a> {
    pub(crate) fn of(chunk: Option<&'a Chunk>) -> Self {
        match chunk {
            None => ChunkView::Uniform(false),
            Some(Chunk::Solid) => ChunkView::Uniform(true),
            Some(Chunk::Lists(l)) => ChunkView::Lists(l),
        }
    }

    pub(crate) fn line(self, axis: Axis, u: usize, v: usize) -> LineRef<'a> {
        match self {
            ChunkView::Uniform(s) => LineRef { start_inside: s, positions: &[], normals: &[] },
            ChunkView::Lists(l) => l.line(axis, u, v),
        }
    }
}

/// Maximum nodes per line (`16 << MAX_LEVEL` cells plus one).
pub(crate) const MAX_NODES: usize = 65;

/// Bits `0..=n`: the nodes of a line with `n` cells.
#[inline]
pub(crate) fn node_mask(n: usize) -> u128 {
    (1u128 << (n + 1)) - 1
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
    pub(crate) const EMPTY: WorkLine = WorkLine { states: 0, pos: [0; MAX_NODES - 1], nrm: [0; MAX_NODES - 1] };

    /// Unpacks a stored line.
    pub(crate) fn load(&mut self, line: LineRef<'_>, level: Level) {
        let n = level.cells();
        let mut s = if line.start_inside { node_mask(n) } else { 0 };
        for (&q, &nr) in line.positions.iter().zip(line.normals) {
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
            Built::Lists(l) => Some(Chunk::Lists(Box::new(l))),
        }
    }
}

/// Assembles a chunk line by line, in storage order. Reusable: keeps its buffers' capacity.
#[derive(Debug)]
pub(crate) struct ChunkBuilder {
    level: Level,
    starts: BitBuf,
    unary: BitBuf,
    positions: Vec<LocalPos>,
    normals: Vec<PackedNormal>,
    axis_start: [(u32, u32); 3],
    axis: usize,
}

impl Default for ChunkBuilder {
    fn default() -> Self {
        ChunkBuilder {
            level: Level::BASE,
            starts: BitBuf::default(),
            unary: BitBuf::default(),
            positions: Vec::new(),
            normals: Vec::new(),
            axis_start: [(0, 0); 3],
            axis: 0,
        }
    }
}

impl ChunkBuilder {
    pub(crate) fn begin(&mut self, level: Level) {
        self.level = level;
        self.starts.clear();
        self.unary.clear();
        self.positions.clear();
        self.normals.clear();
        self.axis = 0;
    }

    /// Marks the start of the lines along `axis` (call in x, y, z order).
    pub(crate) fn begin_axis(&mut self, axis: Axis) {
        self.axis = axis.index();
        self.axis_start[self.axis] = (self.unary.len as u32, self.positions.len() as u32);
    }

    /// Appends a line given by its start state and crossings.
    pub(crate) fn push_line(&mut self, start_inside: bool, crossings: &[(LocalPos, PackedNormal)]) {
        self.starts.push(start_inside);
        for &(q, n) in crossings {
            self.positions.push(q);
            self.normals.push(n);
        }
        self.unary.push_run(true, crossings.len());
        self.unary.push(false);
    }

    /// Appends `count` uniform lines without crossings.
    pub(crate) fn push_uniform(&mut self, state: bool, count: usize) {
        self.starts.push_run(state, count);
        self.unary.push_run(false, count);
    }

    /// Appends `count` lines read from `cursor` (along `axis`) and moves it past them.
    pub(crate) fn copy_from(&mut self, cursor: &mut LineCursor<'_>, axis: Axis, count: usize) {
        if count == 0 {
            return;
        }
        let src = cursor.lists;
        debug_assert_eq!(src.level, self.level);
        let (bit, cross) = (cursor.bit, cursor.cross);
        self.starts.extend_from(&src.bits, axis.index() * src.lines_per_axis() + cursor.index, count);
        cursor.advance_to(cursor.index + count);
        self.unary.extend_from(&src.bits, bit, cursor.bit - bit);
        self.positions.extend_from_slice(&src.positions()[cross..cursor.cross]);
        self.normals.extend_from_slice(&src.normals()[cross..cursor.cross]);
    }

    /// Finishes the chunk: lists, or a uniform state when no line has a crossing.
    pub(crate) fn finish(&mut self) -> Built {
        if self.positions.is_empty() {
            return Built::Uniform(self.starts.len > 0 && bit(&self.starts.words, 0));
        }
        let mut all = BitBuf { words: Vec::with_capacity((self.starts.len + self.unary.len).div_ceil(64)), len: 0 };
        all.extend_from(&self.starts.words, 0, self.starts.len);
        all.extend_from(&self.unary.words, 0, self.unary.len);
        Built::Lists(ChunkLists {
            level: self.level,
            bits: all.words.into_boxed_slice(),
            axis_start: self.axis_start,
            crossings: self.positions.iter().chain(&self.normals).copied().collect(),
        })
    }
}

/// Structural problems found in a chunk's own data (see [`crate::Volume::check_invariants`]).
pub(crate) fn check_lists(lists: &ChunkLists) -> Result<(), String> {
    let n = lists.level.cells();
    let per_axis = n * n;
    let unary = 3 * per_axis;
    let mut bitpos = unary;
    let mut cross = 0usize;
    let total_bits = lists.bits.len() * 64;
    let s = lists.level.steps_per_cell();
    if !lists.crossings.len().is_multiple_of(2) {
        return Err("positions and normals differ in length".into());
    }
    if lists.crossing_count() == 0 {
        return Err("a chunk without crossings must be stored as uniform".into());
    }
    for axis in Axis::ALL {
        if lists.axis_start[axis.index()] != ((bitpos - unary) as u32, cross as u32) {
            return Err(format!("axis {axis:?} start offsets are wrong"));
        }
        for index in 0..per_axis {
            let mut count = 0;
            while bitpos < total_bits && bit(&lists.bits, bitpos) {
                count += 1;
                bitpos += 1;
            }
            if bitpos >= total_bits {
                return Err("unary count stream ends early".into());
            }
            bitpos += 1;
            let pos =
                lists.positions().get(cross..cross + count).ok_or("count stream names more crossings than stored")?;
            let mut last_edge: Option<usize> = None;
            for &q in pos {
                if (q as u32).is_multiple_of(s) {
                    return Err(format!("{axis:?} line {index}: crossing {q} sits on a node"));
                }
                let e = edge_of(q, lists.level);
                if last_edge.is_some_and(|l| l >= e) {
                    return Err(format!("{axis:?} line {index}: crossings unsorted or two in one cell"));
                }
                last_edge = Some(e);
            }
            cross += count;
        }
    }
    if cross != lists.crossing_count() {
        return Err("stored crossings not all named by the count stream".into());
    }
    Ok(())
}
