//! Storage of one chunk: the sorted crossing lists of every grid line through it, along x, y, z.
//!
//! A [`ChunkLists`] at level `k` (`n = 16 << k` cells per side) is one allocation of 64-bit
//! words:
//! - a header of bit fields (see [`field`]; three words at level 0): the level, the state of
//!   the chunk's corner node `(0, 0, 0)`, the allocation's length, the crossing count `m`, the
//!   index of the first crossing of the y and z line families, the number of stored rows, and
//!   one *row bit* per run of eight lines;
//! - the *nonempty bits*, one per line, eight lines (a row) to a byte, with only the rows that
//!   hold a nonempty line stored (their row bits are set), padded to an even number of bytes.
//!   Lines along `axis` are indexed by `(u, v)` over [`Axis::across`], `index = u + n v`, and
//!   the three families follow each other (x, y, z), `3 n²` lines in all. Readers expand one
//!   family's bits at a time ([`ChunkLists::family_nonempty`]);
//! - the crossings in line order as 16-bit values, first all `m` positions, then all `m`
//!   octahedral normals in the same order. A position is a chunk-local fixed-point
//!   [`LocalPos`], always even; its bit 0 ([`LAST`]) marks the last crossing of its line, which
//!   is how a reader finds where one nonempty line ends and the next begins.
//!
//! An empty line therefore costs at most one bit (nothing where its whole row is empty), and a
//! crossing 32 bits plus nothing else. No line
//! stores its start state: the node states of a chunk agree across the three axes (the
//! volume's invariant), so every line's first node can be read off other lines starting from
//! the corner node (see [`ChunkLists::family_starts`]).
//!
//! A line covers the nodes `0..=n` of its chunk (node `n` belongs to the next chunk along the
//! axis) and so the cells `0..n`. Because of the node-state invariant a line has at most one
//! crossing per cell, strictly inside the cell, exactly where its two nodes differ.

use serde::{Deserialize, Serialize};

use crate::axis::Axis;
use crate::bits::BitBuf;
use crate::coords::{Level, LocalPos, edge_of};
use crate::normal::PackedNormal;

/// The header's bit fields: `(first bit, width)`, in word 0 then across into word 1. The row
/// bits follow from [`field::ROWS`].
mod field {
    pub(super) const LEVEL: (usize, u32) = (0, 2);
    pub(super) const CORNER: (usize, u32) = (2, 1);
    /// The allocation's length in words (also read by `thin`; at most 393,434 at level 2).
    pub(super) const LEN: (usize, u32) = (3, 19);
    /// Crossings (at most `3 n³` = 786,432 at level 2).
    pub(super) const CROSSINGS: (usize, u32) = (22, 20);
    pub(super) const Y_START: (usize, u32) = (42, 20);
    pub(super) const Z_START: (usize, u32) = (62, 20);
    /// Rows stored (row bits set; at most 1,536 at level 2).
    pub(super) const STORED_ROWS: (usize, u32) = (82, 11);
    /// First row bit.
    pub(super) const ROWS: usize = 93;
}
/// Bit 0 of a stored position: set on the last crossing of a line.
pub(crate) const LAST: u16 = 1;

/// The crossing lists of a chunk that is neither all empty nor all solid.
///
/// Deserialisation checks the structure (see [`crate::Volume::check_invariants`] for what) and
/// rejects malformed data with an error instead of storing it.
#[derive(Clone, PartialEq, Eq)]
pub struct ChunkLists {
    words: thin::Words,
}

/// The allocation length recorded in header word 0.
#[inline]
fn stored_len(word0: u64) -> usize {
    ((word0 >> field::LEN.0) & ((1 << field::LEN.1) - 1)) as usize
}

/// Bits `start..start + width` of a packed word slice (`width` at most 64).
#[inline]
fn read_bits(words: &[u64], start: usize, width: u32) -> u64 {
    let (w, o) = (start >> 6, (start & 63) as u32);
    let mut v = words[w] >> o;
    if o + width > 64 {
        v |= words[w + 1] << (64 - o);
    }
    if width == 64 { v } else { v & ((1u64 << width) - 1) }
}

/// Nonzero bytes of a word.
#[inline]
fn nonzero_bytes(w: u64) -> usize {
    const LOW7: u64 = 0x7f7f_7f7f_7f7f_7f7f;
    // Bit 7 of each byte: set where any bit of the byte is.
    ((((w & LOW7) + LOW7) | w) & !LOW7).count_ones() as usize
}

/// Writes `value` (which fits) into bits `start..start + width` that are still zero.
fn write_bits(words: &mut [u64], start: usize, width: u32, value: u64) {
    debug_assert!(width == 64 || value >> width == 0);
    let (w, o) = (start >> 6, (start & 63) as u32);
    words[w] |= value << o;
    if o + width > 64 {
        words[w + 1] |= value >> (64 - o);
    }
}

/// A boxed word slice behind a thin pointer: the one place in the crate with `unsafe` code.
#[allow(unsafe_code)]
mod thin {
    use std::ptr::NonNull;

    use super::stored_len;

    /// Owns a `Box<[u64]>` whose word 0 records its length (see [`stored_len`]), through an
    /// 8-byte pointer: a chunk map slot then holds the value in 8 bytes (a `Box<[u64]>` takes
    /// 16) without a second allocation per chunk.
    pub(super) struct Words {
        /// The first word of a `Box<[u64]>` released with `Box::into_raw`.
        ptr: NonNull<u64>,
    }

    impl Words {
        /// Takes ownership of `words`, whose word 0 must record `words.len()`.
        pub(super) fn new(words: Box<[u64]>) -> Self {
            assert!(
                !words.is_empty() && stored_len(words[0]) == words.len(),
                "a chunk allocation records its own length"
            );
            let raw: *mut [u64] = Box::into_raw(words);
            Words { ptr: NonNull::new(raw.cast::<u64>()).expect("a boxed slice pointer is never null") }
        }

        /// The whole allocation.
        #[inline]
        pub(super) fn get(&self) -> &[u64] {
            // SAFETY: `ptr` is the start of a live `Box<[u64]>` allocation (made in `new`, freed
            // only in `drop`) of at least one word (checked in `new`), whose word 0 records its exact
            // length; nothing writes to the words after `new` (no method hands out `&mut`).
            // Reading word 0 is therefore in bounds, the slice covers exactly the allocation,
            // and the shared borrow of `self` keeps it alive with no writer.
            unsafe {
                let len = stored_len(*self.ptr.as_ptr());
                std::slice::from_raw_parts(self.ptr.as_ptr(), len)
            }
        }
    }

    impl Drop for Words {
        fn drop(&mut self) {
            let len = self.get().len();
            // SAFETY: `ptr` and `len` are exactly the pointer and length of the `Box<[u64]>`
            // that `new` released (see `get`), and this is the only place that frees it, once.
            unsafe { drop(Box::from_raw(std::ptr::slice_from_raw_parts_mut(self.ptr.as_ptr(), len))) }
        }
    }

    impl Clone for Words {
        fn clone(&self) -> Self {
            Words::new(self.get().into())
        }
    }

    impl PartialEq for Words {
        fn eq(&self, other: &Self) -> bool {
            self.get() == other.get()
        }
    }

    impl Eq for Words {}

    // SAFETY: `Words` owns its allocation exclusively, exactly like the `Box<[u64]>` it was made
    // from (which is Send and Sync): sending it moves that ownership, and shared references
    // only read words that never change.
    unsafe impl Send for Words {}
    // SAFETY: as above; there is no interior mutability.
    unsafe impl Sync for Words {}

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn words_clone_compare_move_across_threads_and_free() {
            let make = |len: usize, fill: u64| {
                let mut b = vec![fill; len].into_boxed_slice();
                b[0] = (len as u64) << super::super::field::LEN.0;
                Words::new(b)
            };
            let a = make(5, 7);
            let b = a.clone();
            assert!(a == b);
            assert_eq!(a.get().len(), 5);
            assert_eq!(a.get()[4], 7);
            assert!(a != make(5, 8));
            assert!(a != make(6, 7));
            let moved = std::thread::spawn(move || b.get().iter().skip(1).sum::<u64>()).join().unwrap();
            assert_eq!(moved, 28);
            // Many allocations made and freed (run under valgrind or Miri to see no leak).
            let all: Vec<Words> = (2..200).map(|n| make(n, n as u64)).collect();
            let copies = all.clone();
            assert!(all.iter().zip(&copies).all(|(x, y)| x == y && x.get().len() == y.get().len()));
        }

        #[test]
        #[should_panic(expected = "records its own length")]
        fn words_refuse_an_allocation_that_misstates_its_length() {
            let _ = Words::new(vec![0u64; 3].into_boxed_slice());
        }
    }
}

impl std::fmt::Debug for ChunkLists {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ChunkLists").field("level", &self.level()).field("crossings", &self.crossing_count()).finish()
    }
}

/// The serialised form of [`ChunkLists`]: its fields one by one, independent of byte order.
#[derive(Serialize, Deserialize)]
struct RawChunkLists {
    level: Level,
    corner: bool,
    /// First crossing of the y and z families.
    family_start: [u32; 2],
    nonempty: Box<[u64]>,
    positions: Box<[u16]>,
    normals: Box<[u16]>,
}

impl Serialize for ChunkLists {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        RawChunkLists {
            level: self.level(),
            corner: self.corner(),
            family_start: [self.family_start(Axis::Y) as u32, self.family_start(Axis::Z) as u32],
            nonempty: self.nonempty_all().into(),
            positions: self.raw_positions().into(),
            normals: self.normals().into(),
        }
        .serialize(serializer)
    }
}

impl<'de> Deserialize<'de> for ChunkLists {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let r = RawChunkLists::deserialize(deserializer)?;
        ChunkLists::from_raw(r).map_err(serde::de::Error::custom)
    }
}

/// A stored chunk. Chunks missing from the volume's map are all empty.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Chunk {
    /// Every node of the chunk is inside.
    Solid,
    /// Crossing lists.
    Lists(ChunkLists),
}

impl Chunk {
    /// Heap bytes the chunk holds (0 for a solid chunk), as [`crate::Volume::memory`] counts them.
    pub fn heap_bytes(&self) -> usize {
        match self {
            Chunk::Solid => 0,
            Chunk::Lists(l) => l.heap_bytes(),
        }
    }
}

/// One line of a chunk: its first node's state and its crossings in increasing order.
#[derive(Clone, Copy, Debug)]
pub struct LineRef<'a> {
    /// Whether node 0 of the line is inside.
    pub start_inside: bool,
    /// Stored positions (bit 0 is the end-of-line mark; read them through [`LineRef::positions`]).
    raw: &'a [u16],
    /// The outward normal at each crossing.
    pub normals: &'a [PackedNormal],
}

impl<'a> LineRef<'a> {
    /// A line without crossings.
    pub(crate) fn uniform(inside: bool) -> Self {
        LineRef { start_inside: inside, raw: &[], normals: &[] }
    }

    /// Chunk-local fixed-point positions, strictly increasing, at most one per cell.
    #[inline]
    pub fn positions(&self) -> impl ExactSizeIterator<Item = LocalPos> + 'a {
        self.raw.iter().map(|&q| q & !LAST)
    }

    /// Number of crossings.
    #[inline]
    pub fn len(&self) -> usize {
        self.raw.len()
    }

    /// Whether the line has no crossing (its nodes all share `start_inside`).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.raw.is_empty()
    }

    /// Stored positions with the end mark in bit 0 of the last (cell: [`edge_of`]).
    #[inline]
    pub(crate) fn stored(&self) -> &'a [u16] {
        self.raw
    }

    /// Crossing `i`: its position (without the end mark) and normal.
    #[inline]
    pub(crate) fn crossing(&self, i: usize) -> (LocalPos, PackedNormal) {
        (self.raw[i] & !LAST, self.normals[i])
    }

    /// The state after the line's last cell.
    #[inline]
    pub fn end_inside(&self) -> bool {
        self.start_inside ^ (self.raw.len() % 2 == 1)
    }
}

/// One bit per line of one family (start states, nonempty bits): `n² / 64` words, held inline
/// at level 0 (4 words) and boxed above.
#[derive(Clone, Debug)]
pub(crate) enum FamilyBits {
    Inline([u64; 4]),
    Boxed(Box<[u64]>),
}

impl FamilyBits {
    fn zeroed(words: usize) -> Self {
        if words <= 4 { FamilyBits::Inline([0; 4]) } else { FamilyBits::Boxed(vec![0; words].into_boxed_slice()) }
    }

    /// The bit of line `index`.
    #[inline]
    pub(crate) fn get(&self, index: usize) -> bool {
        let words = self.words();
        (words[index >> 6] >> (index & 63)) & 1 == 1
    }

    #[inline]
    fn words(&self) -> &[u64] {
        match self {
            FamilyBits::Inline(w) => &w[..],
            FamilyBits::Boxed(w) => &w[..],
        }
    }

    fn words_mut(&mut self) -> &mut [u64] {
        match self {
            FamilyBits::Inline(w) => &mut w[..],
            FamilyBits::Boxed(w) => &mut w[..],
        }
    }
}

impl ChunkLists {
    /// The chunk's resolution level.
    #[inline]
    pub fn level(&self) -> Level {
        Level::new(self.field(field::LEVEL) as u8).expect("levels are checked when a chunk is built")
    }

    /// A header field.
    #[inline]
    fn field(&self, (start, width): (usize, u32)) -> u64 {
        read_bits(self.words.get(), start, width)
    }

    /// Whether the corner node `(0, 0, 0)` is inside.
    #[inline]
    fn corner(&self) -> bool {
        self.field(field::CORNER) == 1
    }

    /// Number of crossings stored, all axes.
    #[inline]
    pub fn crossing_count(&self) -> usize {
        self.field(field::CROSSINGS) as usize
    }

    /// Index of the first crossing of the `axis` family.
    #[inline]
    fn family_start(&self, axis: Axis) -> usize {
        match axis {
            Axis::X => 0,
            Axis::Y => self.field(field::Y_START) as usize,
            Axis::Z => self.field(field::Z_START) as usize,
        }
    }

    /// Number of crossings on lines along `axis`.
    pub fn axis_crossing_count(&self, axis: Axis) -> usize {
        let end = match axis {
            Axis::X => self.family_start(Axis::Y),
            Axis::Y => self.family_start(Axis::Z),
            Axis::Z => self.crossing_count(),
        };
        end - self.family_start(axis)
    }

    /// Words of the full nonempty bitmap (all three families).
    fn nonempty_words(level: Level) -> usize {
        let n = level.cells();
        3 * n * n / 64
    }

    /// Rows of eight lines, all families.
    fn row_count(level: Level) -> usize {
        let n = level.cells();
        3 * n * n / 8
    }

    /// Words of the header, row bits included.
    #[inline]
    fn header_words(level: Level) -> usize {
        (field::ROWS + Self::row_count(level)).div_ceil(64)
    }

    /// Rows with a row bit set (each stores one byte).
    #[inline]
    fn stored_rows(&self) -> usize {
        self.field(field::STORED_ROWS) as usize
    }

    /// Everything after the header: the stored rows' bytes, a zero byte if their number is odd,
    /// positions, normals, zero padding.
    #[inline]
    fn body(&self) -> &[u64] {
        &self.words.get()[Self::header_words(self.level())..]
    }

    /// Positions (with end marks), then normals, then up to three zero values of padding.
    #[inline]
    fn values(&self) -> &[u16] {
        let values: &[u16] = bytemuck::cast_slice(self.body());
        &values[self.stored_rows().div_ceil(2)..]
    }

    /// The stored rows' nonempty bytes (in row order) and the byte that pads them to an even
    /// number.
    fn row_bytes(&self) -> &[u8] {
        let bytes: &[u8] = bytemuck::cast_slice(self.body());
        &bytes[..self.stored_rows().next_multiple_of(2)]
    }

    /// The nonempty bits of the lines along `axis` (bit `index`), expanded from the stored rows.
    pub(crate) fn family_nonempty(&self, axis: Axis) -> FamilyBits {
        let n = self.level().cells();
        self.family_nonempty_head(axis, n * n / 64)
    }

    /// [`ChunkLists::family_nonempty`] for the first `64 · words_wanted` lines only (the other
    /// bits zero).
    fn family_nonempty_head(&self, axis: Axis, words_wanted: usize) -> FamilyBits {
        let n = self.level().cells();
        let mut out = FamilyBits::zeroed(n * n / 64);
        self.expand_rows(axis, &mut out.words_mut()[..words_wanted]);
        out
    }

    /// Writes the nonempty bits of the first `64 · out.len()` lines of `axis` into `out` (word
    /// `g`: lines `64 g ..`), expanded from the stored rows.
    #[inline]
    fn expand_rows(&self, axis: Axis, out: &mut [u64]) {
        let n = self.level().cells();
        let words = self.words.get();
        let first = field::ROWS + axis.index() * (n * n / 8);
        // The stored rows' bytes and everything after them: at least one more byte (a chunk
        // has a crossing), so reading the byte at `rank` is in bounds even past the last row.
        let bytes: &[u8] = bytemuck::cast_slice(self.body());
        // Stored rows before this family's first.
        let mut rank = count_ones(words, field::ROWS, first);
        for (g, word) in out.iter_mut().enumerate() {
            let stored = read_bits(words, first + 8 * g, 8);
            if stored == 0xff {
                // All eight rows stored: a plain 8-byte copy.
                let b: [u8; 8] = bytes[rank..rank + 8].try_into().expect("eight bytes");
                *word = u64::from_le_bytes(b);
                rank += 8;
                continue;
            }
            // Row r takes the next stored byte if its row bit is set: no branch on the bits.
            let mut w = 0u64;
            for r in 0..8 {
                let bit = (stored >> r) & 1;
                w |= (bytes[rank] as u64 & bit.wrapping_neg()) << (8 * r);
                rank += bit as usize;
            }
            *word = w;
        }
    }

    /// The nonempty bit of every line, families in x, y, z order.
    fn nonempty_all(&self) -> Vec<u64> {
        Axis::ALL.iter().flat_map(|&a| self.family_nonempty(a).words().to_vec()).collect()
    }

    /// Stored positions with their end-of-line marks.
    #[inline]
    fn raw_positions(&self) -> &[u16] {
        &self.values()[..self.crossing_count()]
    }

    /// Normals of all crossings in storage order.
    #[inline]
    fn normals(&self) -> &[PackedNormal] {
        let m = self.crossing_count();
        &self.values()[m..2 * m]
    }

    /// The line `(u, v)` along `axis` (derives the family's start states: for one-off reads;
    /// walk a [`LineCursor`] to read many lines). `u` and `v` index the chunk's own lines, at
    /// its level: a line outside `0..n` on either is a caller's bug and panics saying so.
    pub fn line(&self, axis: Axis, u: usize, v: usize) -> LineRef<'_> {
        let n = self.level().cells();
        assert!(
            u < n && v < n,
            "line ({u}, {v}) is outside a chunk of level {} ({n} lines a side)",
            self.level().get()
        );
        self.cursor(axis, u + n * v).next_line()
    }

    /// A cursor positioned at line `index` along `axis`, reading lines in index order.
    /// The family's start states are derived at the first [`LineCursor::next_line`]; a reader
    /// that knows them uses [`LineCursor::next_with`] and never pays for them.
    pub(crate) fn cursor(&self, axis: Axis, index: usize) -> LineCursor<'_> {
        LineCursor { raw: self.raw_cursor(axis, index), axis, starts: None }
    }

    /// A cursor that reads crossings only (no start states) from line `index` of `axis`.
    pub(crate) fn raw_cursor(&self, axis: Axis, index: usize) -> RawCursor<'_> {
        let n = self.level().cells();
        self.raw_cursor_head(axis, index, n * n)
    }

    /// A [`RawCursor`] at line `index` of `axis` that reuses the family's nonempty bits already
    /// expanded by [`ChunkLists::family_nonempty`] (for readers that open many cursors).
    pub(crate) fn raw_cursor_from(&self, axis: Axis, index: usize, nonempty: &FamilyBits) -> RawCursor<'_> {
        let mut c = RawCursor {
            lists: self,
            nonempty: nonempty.clone(),
            raw: self.raw_positions(),
            normals: self.normals(),
            index: 0,
            cross: self.family_start(axis),
        };
        c.advance_to(index);
        c
    }

    /// A [`RawCursor`] that reads no further than line `lines` (rounded up to a multiple of 64):
    /// only that many nonempty bits are expanded.
    fn raw_cursor_head(&self, axis: Axis, index: usize, lines: usize) -> RawCursor<'_> {
        let mut c = RawCursor {
            lists: self,
            nonempty: self.family_nonempty_head(axis, lines.div_ceil(64)),
            raw: self.raw_positions(),
            normals: self.normals(),
            index: 0,
            cross: self.family_start(axis),
        };
        c.advance_to(index);
        c
    }

    /// The start state of every line along `axis` (bit `u + n v`), read off other lines from
    /// the corner node. Only the first line of one family and the first row (`v = 0`, the
    /// family's first `n` lines, at the front of its crossings) of another are read:
    /// - x lines start on the face `x = 0`, whose nodes `(0, j, k)` lie on y line `k` (the y
    ///   lines of the first row have `x = 0`), which starts at `(0, 0, k)` on z line 0;
    /// - y lines start on `y = 0`: nodes `(k, 0, j)` on z line `k` (first row: `y = 0`), which
    ///   starts at `(k, 0, 0)` on x line 0;
    /// - z lines start on `z = 0`: nodes `(j, k, 0)` on x line `k` (first row: `z = 0`), which
    ///   starts at `(0, k, 0)` on y line 0.
    ///
    /// In each case node `j` of row line `k` is the start of line `j + n k` of the family.
    pub(crate) fn family_starts(&self, axis: Axis) -> FamilyBits {
        let level = self.level();
        let n = level.cells();
        let shift = 12 - level.get() as u32;
        // The states of nodes 0..n (bit j; n at most 64, so node n, never needed, drops out)
        // along a line from its start state: a crossing in cell e flips the nodes after it.
        let states = |start: bool, raw: &[u16]| -> u64 {
            let mut s = if start { u64::MAX } else { 0 };
            for &q in raw {
                s ^= (u64::MAX << ((q & !LAST) as u32 >> shift)) << 1;
            }
            s
        };
        let (first, row) = match axis {
            Axis::X => (Axis::Z, Axis::Y),
            Axis::Y => (Axis::X, Axis::Z),
            Axis::Z => (Axis::Y, Axis::X),
        };
        // Line 0 of one family and lines 0..n of another, read straight from the first 64
        // nonempty bits of each and the crossings at the front of each family.
        let raw = self.raw_positions();
        let head = |axis: Axis| {
            let mut bits = [0u64];
            self.expand_rows(axis, &mut bits);
            (bits[0], self.family_start(axis))
        };
        // The crossings of the line starting at crossing `at` if `nonempty`; moves `at` past it.
        let take = |nonempty: bool, at: &mut usize| {
            let start = *at;
            if nonempty {
                while raw[*at] & LAST == 0 {
                    *at += 1;
                }
                *at += 1;
            }
            &raw[start..*at]
        };
        let (bits, mut at) = head(first);
        let edge = states(self.corner(), take(bits & 1 == 1, &mut at));
        let (bits, mut at) = head(row);
        let mut starts = FamilyBits::zeroed(n * n / 64);
        let out = starts.words_mut();
        let mask = u64::MAX >> (64 - n);
        for k in 0..n {
            let s = states((edge >> k) & 1 == 1, take((bits >> k) & 1 == 1, &mut at)) & mask;
            // n divides 64: the n bits of a row never straddle a word.
            let i = n * k;
            out[i >> 6] |= s << (i & 63);
        }
        starts
    }

    /// Bytes of the one allocation.
    pub(crate) fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(self.words.get())
    }

    /// Bytes of positions and of normals (each `2 m`), for memory reports.
    pub(crate) fn crossing_bytes(&self) -> usize {
        2 * self.crossing_count()
    }

    /// Builds and checks a chunk from its serialised fields.
    fn from_raw(r: RawChunkLists) -> Result<Self, String> {
        let m = r.positions.len();
        if r.normals.len() != m {
            return Err("positions and normals differ in length".into());
        }
        if r.nonempty.len() != Self::nonempty_words(r.level) {
            return Err("wrong number of nonempty bits".into());
        }
        if m == 0 {
            return Err("a chunk without crossings must be stored as uniform".into());
        }
        let n = r.level.cells();
        if m > 3 * n * n * n {
            return Err("more crossings than the chunk's lines have cells".into());
        }
        let [ys, zs] = r.family_start;
        if ys as usize > m || zs as usize > m || ys > zs {
            return Err("family start offsets out of range".into());
        }
        let lists = assemble(r.level, r.corner, [ys, zs], &r.nonempty, &r.positions, &r.normals);
        check_lists(&lists)?;
        Ok(lists)
    }
}

/// Lays out a chunk's allocation from the full nonempty bitmap (`3 n²` bits) and the
/// crossings (`m` at most `3 n³`, offsets at most `m`: callers check).
fn assemble(
    level: Level,
    corner: bool,
    family_start: [u32; 2],
    nonempty: &[u64],
    positions: &[u16],
    normals: &[u16],
) -> ChunkLists {
    let m = positions.len();
    let head = ChunkLists::header_words(level);
    // Row k is byte k of the bitmap; only nonzero rows are stored, right after the header (on
    // its cache line), padded to an even number of bytes so the values that follow are aligned.
    let stored: usize = nonempty.iter().map(|&w| nonzero_bytes(w)).sum();
    let len = head + (stored.next_multiple_of(2) + 4 * m).div_ceil(8);
    let mut data = vec![0u64; len].into_boxed_slice();
    write_bits(&mut data, field::LEVEL.0, field::LEVEL.1, level.get() as u64);
    write_bits(&mut data, field::CORNER.0, field::CORNER.1, corner as u64);
    write_bits(&mut data, field::LEN.0, field::LEN.1, len as u64);
    write_bits(&mut data, field::CROSSINGS.0, field::CROSSINGS.1, m as u64);
    write_bits(&mut data, field::Y_START.0, field::Y_START.1, family_start[0] as u64);
    write_bits(&mut data, field::Z_START.0, field::Z_START.1, family_start[1] as u64);
    write_bits(&mut data, field::STORED_ROWS.0, field::STORED_ROWS.1, stored as u64);
    let (header, body) = data.split_at_mut(head);
    let bytes: &mut [u8] = bytemuck::cast_slice_mut(body);
    let mut slot = 0;
    for (i, &w) in nonempty.iter().enumerate().filter(|(_, w)| **w != 0) {
        // The eight rows of this word: their row bits go in at once.
        let mut rows = 0;
        for (b, byte) in w.to_le_bytes().into_iter().enumerate().filter(|(_, b)| *b != 0) {
            rows |= 1 << b;
            bytes[slot] = byte;
            slot += 1;
        }
        write_bits(header, field::ROWS + 8 * i, 8, rows);
    }
    let values: &mut [u16] = bytemuck::cast_slice_mut(body);
    let values = &mut values[stored.div_ceil(2)..];
    values[..m].copy_from_slice(positions);
    values[m..2 * m].copy_from_slice(normals);
    ChunkLists { words: thin::Words::new(data) }
}

/// Walks the lines of one family in index order, reading crossings only.
#[derive(Clone, Debug)]
pub(crate) struct RawCursor<'a> {
    lists: &'a ChunkLists,
    /// The family's nonempty bits.
    nonempty: FamilyBits,
    raw: &'a [u16],
    normals: &'a [u16],
    /// The next line to read.
    index: usize,
    /// Its first crossing.
    cross: usize,
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
fn skip_marks(raw: &[u16], from: usize, mut k: usize) -> usize {
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

/// Ones among bits `[from, to)`.
#[inline]
fn count_ones(words: &[u64], from: usize, to: usize) -> usize {
    if from >= to {
        return 0;
    }
    let (wa, wb) = (from >> 6, (to - 1) >> 6);
    let lo = u64::MAX << (from & 63);
    let hi = u64::MAX >> (63 - ((to - 1) & 63));
    if wa == wb {
        return (words[wa] & lo & hi).count_ones() as usize;
    }
    let mut c = (words[wa] & lo).count_ones() + (words[wb] & hi).count_ones();
    for w in &words[wa + 1..wb] {
        c += w.count_ones();
    }
    c as usize
}

/// Reads the lines of one axis family in index order, with their start states.
#[derive(Clone, Debug)]
pub(crate) struct LineCursor<'a> {
    raw: RawCursor<'a>,
    axis: Axis,
    starts: Option<FamilyBits>,
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
    pub(crate) const EMPTY: WorkLine = WorkLine { states: 0, pos: [0; MAX_NODES - 1], nrm: [0; MAX_NODES - 1] };

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
        self.normals.resize(len, 0);
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
        debug_assert_eq!(q & LAST, 0, "positions are even");
        self.positions[self.m] = q;
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
            (dp[i], dn[i]) = (r, nr);
            i += 1;
        };
        raw[..p].iter().zip(&normals[..p]).for_each(|(&r, &nr)| put((r, nr)));
        mid.iter().for_each(|&c| {
            debug_assert_eq!(c.0 & LAST, 0, "positions are even");
            put(c);
        });
        raw[q..].iter().zip(&normals[q..]).for_each(|(&r, &nr)| put((r, nr)));
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

/// Structural problems found in a chunk's own data (see [`crate::Volume::check_invariants`]).
pub(crate) fn check_lists(lists: &ChunkLists) -> Result<(), String> {
    let level = lists.level();
    let n = level.cells();
    let per_axis = n * n;
    let s = level.steps_per_cell();
    let m = lists.crossing_count();
    if m == 0 {
        return Err("a chunk without crossings must be stored as uniform".into());
    }
    // The stored rows: one nonzero byte per row bit, then a zero byte to an even number.
    let stored = lists.stored_rows();
    if count_ones(lists.words.get(), field::ROWS, field::ROWS + ChunkLists::row_count(level)) != stored {
        return Err("stored row count is wrong".into());
    }
    let bytes = lists.row_bytes();
    if bytes[..stored].contains(&0) || bytes[stored..].iter().any(|&b| b != 0) {
        return Err("nonempty rows stored wrongly".into());
    }
    let values = lists.values();
    if values.len() < 2 * m || values[2 * m..].iter().any(|&v| v != 0) {
        return Err("crossing storage has the wrong size".into());
    }
    let raw = lists.raw_positions();
    let mut cross = 0usize;
    for axis in Axis::ALL {
        if lists.family_start(axis) != cross {
            return Err(format!("axis {axis:?} start offset is wrong"));
        }
        let nonempty = lists.family_nonempty(axis);
        for index in 0..per_axis {
            if !nonempty.get(index) {
                continue;
            }
            let mut last_edge: Option<usize> = None;
            loop {
                let Some(&stored) = raw.get(cross) else {
                    return Err("the nonempty bits name more lines than the crossings end".into());
                };
                cross += 1;
                let q = stored & !LAST;
                if (q as u32).is_multiple_of(s) {
                    return Err(format!("{axis:?} line {index}: crossing {q} sits on a node"));
                }
                let e = edge_of(q, level);
                if last_edge.is_some_and(|l| l >= e) {
                    return Err(format!("{axis:?} line {index}: crossings unsorted or two in one cell"));
                }
                last_edge = Some(e);
                if stored & LAST != 0 {
                    break;
                }
            }
        }
    }
    if cross != m {
        return Err("stored crossings not all named by the nonempty lines".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Volume;
    use crate::brush::Sphere;
    use glam::{DVec3, I64Vec3};

    fn spheres() -> [Sphere; 2] {
        [Sphere::new(DVec3::new(7.3, 9.1, 5.6), 6.2).unwrap(), Sphere::new(DVec3::new(3.0, 12.5, 4.0), 3.1).unwrap()]
    }

    fn sample_lists() -> (Volume, ChunkLists) {
        let mut v = Volume::new();
        let [a, b] = spheres();
        v.add(&a).unwrap();
        v.subtract(&b).unwrap();
        let lists = match v.chunk(crate::ChunkKey::new(0, 0, 0)) {
            Some(Chunk::Lists(l)) => l.clone(),
            other => panic!("expected lists, got {other:?}"),
        };
        (v, lists)
    }

    #[test]
    fn derived_start_states_equal_the_node_states() {
        let (_, lists) = sample_lists();
        let [a, b] = spheres();
        let n = lists.level().cells();
        for axis in Axis::ALL {
            let starts = lists.family_starts(axis);
            let mut cursor = lists.cursor(axis, 0);
            for index in 0..n * n {
                let (u, w) = (index % n, index / n);
                let node = I64Vec3::from_array(crate::axis::compose(axis, 0, u as i64, w as i64));
                let inside = |s: &Sphere| crate::brush_contains_node(s, node, Level::BASE);
                let expect = inside(&a) && !inside(&b);
                assert_eq!(starts.get(index), expect, "{axis:?} line {index}");
                assert_eq!(cursor.next_line().start_inside, expect);
            }
        }
    }

    #[test]
    fn serialised_lists_round_trip_and_tampering_is_refused() {
        let (_, lists) = sample_lists();
        let bytes = postcard::to_allocvec(&lists).unwrap();
        assert_eq!(postcard::from_bytes::<ChunkLists>(&bytes).unwrap(), lists);
        let raw = || postcard::from_bytes::<RawChunkLists>(&bytes).unwrap();
        let refuse = |r: RawChunkLists, why: &str| {
            let b = postcard::to_allocvec(&r).unwrap();
            assert!(postcard::from_bytes::<ChunkLists>(&b).is_err(), "accepted: {why}");
        };
        let mut r = raw();
        let last = r.positions.iter().position(|&q| q & LAST != 0).unwrap();
        r.positions[last] &= !LAST;
        refuse(r, "a line without its end mark");
        let mut r = raw();
        r.positions[0] |= LAST;
        refuse(r, "an extra end mark");
        let mut r = raw();
        r.nonempty[0] ^= 1 << r.nonempty[0].trailing_zeros();
        refuse(r, "a nonempty line marked empty");
        let mut r = raw();
        r.family_start[0] += 1;
        refuse(r, "a wrong family offset");
        let mut r = raw();
        r.normals = r.normals[1..].into();
        refuse(r, "normals missing");
        let mut r = raw();
        r.positions[0] = 0;
        refuse(r, "a crossing on a node");
        let mut r = raw();
        r.nonempty = r.nonempty[1..].into();
        refuse(r, "nonempty bits cut short");
        let mut r = raw();
        r.positions = vec![2; 3 * 16 * 16 * 16 + 1].into();
        r.normals = r.positions.clone();
        refuse(r, "more crossings than cells");
    }

    #[test]
    fn skipping_end_marks_agrees_with_a_scalar_loop() {
        // A word-aligned buffer, read from several offsets (aligned and not).
        let mut words = vec![0u64; 40];
        let raw: &mut [u16] = bytemuck::cast_slice_mut(&mut words);
        let mut seed = 3u64;
        for q in raw.iter_mut() {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            *q = ((seed >> 40) as u16) & !LAST | u16::from((seed >> 20).is_multiple_of(3));
        }
        let raw: &[u16] = raw;
        let marks = raw.iter().filter(|&&q| q & LAST != 0).count();
        for from in [0, 1, 3, 4, 5, 17, 64] {
            let ahead = raw[from..].iter().filter(|&&q| q & LAST != 0).count();
            for k in 0..=ahead {
                let mut i = from;
                let mut left = k;
                while left > 0 {
                    left -= (raw[i] & LAST) as usize;
                    i += 1;
                }
                assert_eq!(skip_marks(raw, from, k), i, "from {from} k {k}");
            }
        }
        assert!(marks > 20);
    }

    #[test]
    fn counting_ones_agrees_with_a_bit_loop() {
        let words = [0x0123_4567_89ab_cdefu64, u64::MAX, 0, 0xf0f0_0000_ffff_0001];
        for from in 0..256 {
            for to in from..=256 {
                let expect = (from..to).filter(|&i| (words[i >> 6] >> (i & 63)) & 1 == 1).count();
                assert_eq!(count_ones(&words, from, to), expect, "{from}..{to}");
            }
        }
    }

    #[test]
    fn bit_fields_and_nonzero_bytes_agree_with_plain_loops() {
        let mut seed = 5u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            seed
        };
        for _ in 0..2000 {
            // Words with many zero and 0x80 bytes.
            let w = next() & next() & 0x80ff_00ff_8000_ff80 | (next() & 0x0080_0080_0000_0001);
            let plain = w.to_le_bytes().iter().filter(|&&b| b != 0).count();
            assert_eq!(nonzero_bytes(w), plain, "{w:#x}");
            let (start, width) = ((next() % 120) as usize, (next() % 64 + 1) as u32);
            let value = next() & if width == 64 { u64::MAX } else { (1 << width) - 1 };
            let mut words = [0u64; 3];
            write_bits(&mut words, start, width, value);
            assert_eq!(read_bits(&words, start, width), value, "{start} {width}");
            let set: usize = words.iter().map(|w| w.count_ones() as usize).sum();
            assert_eq!(set, value.count_ones() as usize, "nothing outside the field is written");
        }
    }
}
