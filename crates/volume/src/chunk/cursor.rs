//! Cursors over a chunk's lines: one family's crossings in index order ([`RawCursor`]),
//! lines with their node states ([`LineCursor`]), and either over any chunk, uniform or
//! stored ([`ChunkView`], [`ViewCursor`]).

use super::*;

/// Walks the lines of one family in index order, reading crossings only.
#[derive(Clone, Debug)]
pub(crate) struct RawCursor<'a> {
    pub(super) lists: &'a ChunkLists,
    /// The family's nonempty bits.
    pub(super) nonempty: FamilyBits,
    pub(super) raw: &'a [u16],
    pub(super) normals: &'a [PackedNormal],
    /// The next line to read.
    pub(super) index: usize,
    /// Its first crossing.
    pub(super) cross: usize,
}

impl<'a> RawCursor<'a> {
    /// Moves forward to line `index` (not backwards).
    #[inline]
    pub(crate) fn advance_to(&mut self, index: usize) {
        debug_assert!(index >= self.index);
        let lines = count_ones(self.nonempty.words(), self.index, index);
        self.cross = skip_marks(self.raw, self.cross, lines);
        self.index = index;
    }

    /// The crossings of the next line (with end marks) and moves past it.
    #[inline]
    pub(crate) fn next_raw(&mut self) -> &'a [u16] {
        let start = self.cross;
        if self.nonempty.get(self.index) {
            let mut j = start;
            while self.raw[j] & LAST == 0 {
                j += 1;
            }
            self.cross = j + 1;
        }
        self.index += 1;
        &self.raw[start..self.cross]
    }

    /// The next line's crossings as a line with the given start state.
    #[inline]
    pub(crate) fn next_with(&mut self, start_inside: bool) -> LineRef<'a> {
        let first = self.cross;
        let raw = self.next_raw();
        LineRef { start_inside, raw, normals: &self.normals[first..first + raw.len()] }
    }
}

/// The index just after the `k`-th end mark at or after `from` (`from` itself for `k = 0`).
/// Reads four positions per step from the first 8-byte-aligned one on.
#[inline]
pub(super) fn skip_marks(raw: &[u16], from: usize, mut k: usize) -> usize {
    let mut i = from;
    // Positions before index `i` with `(phase + i) % 4 == 0` start an aligned word.
    let phase = (raw.as_ptr() as usize / 2) & 3;
    // Scalar up to an aligned word, and for short skips.
    while k > 0 && ((phase + i) & 3 != 0 || k < 3) {
        k -= (raw[i] & LAST) as usize;
        i += 1;
    }
    if k == 0 {
        return i;
    }
    const MARKS: u64 = 0x0001_0001_0001_0001;
    let whole = (raw.len() - i) / 4 * 4;
    if let Ok(words) = bytemuck::try_cast_slice::<u16, u64>(&raw[i..i + whole]) {
        for (w_index, &w) in words.iter().enumerate() {
            let marks = w & MARKS;
            let c = marks.count_ones() as usize;
            if c >= k {
                let mut m = marks;
                for _ in 1..k {
                    m &= m - 1;
                }
                return i + 4 * w_index + m.trailing_zeros() as usize / 16 + 1;
            }
            k -= c;
        }
        i += whole;
    }
    while k > 0 {
        k -= (raw[i] & LAST) as usize;
        i += 1;
    }
    i
}

/// Reads the lines of one axis family in index order, with their start states.
#[derive(Clone, Debug)]
pub(crate) struct LineCursor<'a> {
    pub(super) raw: RawCursor<'a>,
    pub(super) axis: Axis,
    pub(super) starts: Option<FamilyBits>,
}

impl<'a> LineCursor<'a> {
    /// Moves forward to line `index` (not backwards).
    #[inline]
    pub(crate) fn advance_to(&mut self, index: usize) {
        self.raw.advance_to(index);
    }

    /// The next line with its own start state (derived for the family on first use).
    #[inline(always)]
    pub(crate) fn next_line(&mut self) -> LineRef<'a> {
        if self.starts.is_none() {
            self.derive_starts();
        }
        let start = self.starts.as_ref().expect("derived above").get(self.raw.index);
        self.raw.next_with(start)
    }

    /// The next line, starting in the state `start_inside` given by the caller.
    #[inline]
    pub(crate) fn next_with(&mut self, start_inside: bool) -> LineRef<'a> {
        self.raw.next_with(start_inside)
    }

    #[cold]
    fn derive_starts(&mut self) {
        self.starts = Some(self.raw.lists.family_starts(self.axis));
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

    /// A cursor over the lines of `axis` from line `index`, whatever the storage.
    pub(crate) fn cursor(self, axis: Axis, index: usize) -> ViewCursor<'a> {
        match self {
            ChunkView::Uniform(s) => ViewCursor::Uniform(s),
            ChunkView::Lists(l) => ViewCursor::Lists(l.cursor(axis, index)),
        }
    }
}

/// A [`LineCursor`] over any chunk view (uniform chunks give uniform lines).
#[derive(Clone, Debug)]
pub(crate) enum ViewCursor<'a> {
    Uniform(bool),
    Lists(LineCursor<'a>),
}

impl<'a> ViewCursor<'a> {
    #[inline]
    pub(crate) fn advance_to(&mut self, index: usize) {
        if let ViewCursor::Lists(c) = self {
            c.advance_to(index);
        }
    }

    /// The next line with its own start state.
    #[inline]
    pub(crate) fn next_line(&mut self) -> LineRef<'a> {
        match self {
            ViewCursor::Uniform(s) => LineRef::uniform(*s),
            ViewCursor::Lists(c) => c.next_line(),
        }
    }

    /// The next line, starting in the state `start_inside` (uniform chunks keep their own).
    #[inline]
    pub(crate) fn next_with(&mut self, start_inside: bool) -> LineRef<'a> {
        match self {
            ViewCursor::Uniform(s) => LineRef::uniform(*s),
            ViewCursor::Lists(c) => c.next_with(start_inside),
        }
    }
}
