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
//!
//! The folder's files: the storage and its accessors (here), the cursors that walk a chunk's
//! lines (`cursor.rs`), the one writer every list writer goes through (`builder.rs`, the
//! [`ChunkBuilder`]) and the structural check of a chunk's data (`check.rs`).

use serde::{Deserialize, Serialize};

use crate::axis::Axis;
use crate::bits::BitBuf;
use crate::coords::{Level, LocalPos, edge_of};
use crate::normal::PackedNormal;

mod builder;
mod check;
mod cursor;
#[cfg(test)]
mod tests;

pub(crate) use builder::{Built, ChunkBuilder, MAX_NODES, WorkLine, line_states, node_mask};
pub(crate) use check::check_lists;
pub(crate) use cursor::{ChunkView, LineCursor, RawCursor, ViewCursor};

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

/// A shared, never-changing word slice behind a thin pointer: the one place in the crate with
/// `unsafe` code.
#[allow(unsafe_code)]
mod thin {
    use std::alloc::{Layout, alloc_zeroed, dealloc, handle_alloc_error};
    use std::ptr::NonNull;
    use std::sync::atomic::{AtomicU64, Ordering, fence};

    use super::stored_len;

    /// Owns a share of one allocation `[count, word 0, word 1, …]`, through an 8-byte pointer: a
    /// chunk map slot then holds the value in 8 bytes (a `Box<[u64]>` takes 16, an `Arc<[u64]>`
    /// 16 and two counts) without a second allocation per chunk. Word 0 records the number of
    /// words after the count (see [`stored_len`]). The words never change once made, so a clone
    /// is a new share (one atomic add), not a copy: a mesher's snapshot of a chunk's
    /// neighbourhood, an undo record or a copied volume allocates nothing per chunk.
    pub(super) struct Words {
        /// The count word at the start of an allocation made in `filled` with `layout(len)`.
        ptr: NonNull<u64>,
    }

    /// The allocation of `len` words and the count before them (aligned for an `AtomicU64`).
    fn layout(len: usize) -> Layout {
        let bytes = len.checked_add(1).and_then(|n| n.checked_mul(8)).expect("a chunk allocation's size fits");
        Layout::from_size_align(bytes, std::mem::align_of::<AtomicU64>().max(8)).expect("a chunk allocation's layout")
    }

    /// Frees an allocation if the closure filling it panics.
    struct Unfinished {
        ptr: NonNull<u64>,
        layout: Layout,
    }

    impl Drop for Unfinished {
        fn drop(&mut self) {
            // SAFETY: `ptr` was returned by `alloc_zeroed(layout)` in `filled` and nothing else
            // frees it (`filled` forgets this guard once the allocation is handed to `Words`).
            unsafe { dealloc(self.ptr.as_ptr().cast(), self.layout) }
        }
    }

    impl Words {
        /// `len` zeroed words filled by `fill`, which must record `len` in word 0.
        pub(super) fn filled(len: usize, fill: impl FnOnce(&mut [u64])) -> Self {
            assert!(len >= 1, "a chunk allocation holds its header");
            let layout = layout(len);
            // SAFETY: the layout's size is at least 16 bytes, never zero.
            let raw = unsafe { alloc_zeroed(layout) }.cast::<u64>();
            let Some(ptr) = NonNull::new(raw) else { handle_alloc_error(layout) };
            let guard = Unfinished { ptr, layout };
            // SAFETY: the allocation holds `len + 1` zeroed (so initialised) `u64`s, aligned; words
            // 1..=len are borrowed mutably here only, while no `Words` exists for them yet.
            let words = unsafe { std::slice::from_raw_parts_mut(ptr.as_ptr().add(1), len) };
            fill(words);
            assert!(stored_len(words[0]) == len, "a chunk allocation records its own length");
            std::mem::forget(guard);
            // SAFETY: as above, the count word is in bounds and aligned for an `AtomicU64`; no other
            // reference to it exists yet.
            unsafe { ptr.as_ptr().write(1) };
            Words { ptr }
        }

        /// The share count, read and changed only atomically.
        #[inline]
        fn count(&self) -> &AtomicU64 {
            // SAFETY: `ptr` points at the count word of a live allocation (freed only when the last
            // share drops), aligned for `AtomicU64` (see `layout`); after `filled` the word is only
            // ever reached through this atomic view.
            unsafe { AtomicU64::from_ptr(self.ptr.as_ptr()) }
        }

        /// The words (not the count).
        #[inline]
        pub(super) fn get(&self) -> &[u64] {
            // SAFETY: `ptr` is the count word of a live allocation of `len + 1` words (made in
            // `filled`, freed only in `drop` when the last share goes), whose word 0 (at `ptr + 1`)
            // records `len` (checked in `filled`); nothing writes to words 0..len after `filled`
            // (no method hands out `&mut`), so a shared slice of them is sound for as long as
            // `self` is borrowed.
            unsafe {
                let words = self.ptr.as_ptr().add(1);
                std::slice::from_raw_parts(words, stored_len(*words))
            }
        }

        /// Whether the two share one allocation.
        #[inline]
        pub(super) fn same(&self, other: &Self) -> bool {
            self.ptr == other.ptr
        }

        /// How many values share this allocation (for tests).
        #[cfg(test)]
        pub(super) fn shares(&self) -> u64 {
            self.count().load(Ordering::Acquire)
        }
    }

    impl Drop for Words {
        fn drop(&mut self) {
            // The last share frees: the release-acquire pair orders every other share's reads
            // before the free (as `Arc` does).
            if self.count().fetch_sub(1, Ordering::Release) != 1 {
                return;
            }
            fence(Ordering::Acquire);
            let layout = layout(self.get().len());
            // SAFETY: this was the last share, so nothing else reads the allocation; `ptr` and
            // `layout` are exactly what `filled` allocated with (the length is word 0's, checked
            // there), and only the last share reaches this line, once.
            unsafe { dealloc(self.ptr.as_ptr().cast(), layout) }
        }
    }

    impl Clone for Words {
        fn clone(&self) -> Self {
            // Relaxed as in `Arc`: a share is made from a live share, which keeps the allocation
            // alive meanwhile. Far more shares than memory could hold means a leak of shares: stop
            // before the count could wrap.
            if self.count().fetch_add(1, Ordering::Relaxed) > i64::MAX as u64 {
                std::process::abort();
            }
            Words { ptr: self.ptr }
        }
    }

    impl PartialEq for Words {
        fn eq(&self, other: &Self) -> bool {
            self.same(other) || self.get() == other.get()
        }
    }

    impl Eq for Words {}

    // SAFETY: every share only reads words that never change after `filled`, and the count is
    // changed only atomically, so shares may be sent to and dropped on any thread (the last one
    // frees, after every other share's reads, as in `Arc<[u64]>`, which is Send and Sync).
    unsafe impl Send for Words {}
    // SAFETY: as above; there is no other interior mutability.
    unsafe impl Sync for Words {}

    #[cfg(test)]
    mod tests {
        use super::*;

        fn make(len: usize, fill: u64) -> Words {
            Words::filled(len, |w| {
                w.fill(fill);
                w[0] = (len as u64) << super::super::field::LEN.0;
            })
        }

        #[test]
        fn words_share_compare_move_across_threads_and_free() {
            let a = make(5, 7);
            let b = a.clone();
            assert!(a == b && a.same(&b));
            assert_eq!(a.shares(), 2);
            assert_eq!(a.get().len(), 5);
            assert_eq!(a.get()[4], 7);
            assert!(a != make(5, 8));
            assert!(a != make(6, 7));
            // Equal words in another allocation are equal, not the same.
            let c = make(5, 7);
            assert!(a == c && !a.same(&c));
            // A share dropped on another thread leaves the others readable.
            let moved = std::thread::spawn(move || b.get().iter().skip(1).sum::<u64>()).join().unwrap();
            assert_eq!(moved, 28);
            assert_eq!(a.shares(), 1);
            // Many shares made and dropped on many threads at once: the last frees, once (run
            // under valgrind or Miri to see no leak and no double free).
            let all: Vec<Words> = (2..200).map(|n| make(n, n as u64)).collect();
            std::thread::scope(|s| {
                for _ in 0..4 {
                    let copies = all.clone();
                    s.spawn(move || {
                        let more: Vec<Words> = copies.iter().flat_map(|w| [w.clone(), w.clone()]).collect();
                        assert!(more.chunks(2).zip(&copies).all(|(p, w)| p[0].same(w) && p[1] == *w));
                    });
                }
            });
            assert!(all.iter().all(|w| w.shares() == 1));
            let last = all.into_iter().last().unwrap();
            assert_eq!(last.get().len(), 199);
        }

        #[test]
        #[should_panic(expected = "records its own length")]
        fn words_refuse_an_allocation_that_misstates_its_length() {
            let _ = Words::filled(3, |_| {});
        }

        #[test]
        fn a_panicking_fill_frees_its_allocation_and_unwinds() {
            let r = std::panic::catch_unwind(|| Words::filled(4, |_| panic!("fill failed")));
            assert!(r.is_err());
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
            normals: bytemuck::cast_slice::<PackedNormal, u16>(self.normals()).into(),
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
        self.raw.iter().map(|&q| LocalPos(q & !LAST))
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
        (LocalPos(self.raw[i] & !LAST), self.normals[i])
    }

    /// The state after the line's last cell.
    #[inline]
    pub fn end_inside(&self) -> bool {
        self.start_inside ^ (self.raw.len() % 2 == 1)
    }
}

/// One bit per line of one family (start states, nonempty bits): `n² / 64` words, held inline
/// up to level 0 (4 words; the first `.1` of them used) and boxed above.
#[derive(Clone, Debug)]
pub(crate) enum FamilyBits {
    Inline([u64; 4], u8),
    Boxed(Box<[u64]>),
}

impl FamilyBits {
    fn zeroed(words: usize) -> Self {
        if words <= 4 {
            FamilyBits::Inline([0; 4], words as u8)
        } else {
            FamilyBits::Boxed(vec![0; words].into_boxed_slice())
        }
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
            FamilyBits::Inline(w, n) => &w[..*n as usize],
            FamilyBits::Boxed(w) => &w[..],
        }
    }

    fn words_mut(&mut self) -> &mut [u64] {
        match self {
            FamilyBits::Inline(w, n) => &mut w[..*n as usize],
            FamilyBits::Boxed(w) => &mut w[..],
        }
    }
}

impl ChunkLists {
    /// The chunk's resolution level.
    #[inline]
    pub fn level(&self) -> Level {
        Level::from_code(self.field(field::LEVEL) as u8).expect("levels are checked when a chunk is built")
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
        // (Positions and normals share one stream of 16-bit words.)
        bytemuck::cast_slice(&self.values()[m..2 * m])
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
        let shift = level.steps_shift();
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

    /// Whether `self` and `other` share one allocation (a clone is a share, never a copy).
    pub fn shares_with(&self, other: &ChunkLists) -> bool {
        self.words.same(&other.words)
    }

    /// Bytes of the one allocation (its words and their share count).
    pub(crate) fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(self.words.get()) + 8
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
        let lists = assemble(r.level, r.corner, [ys, zs], &r.nonempty, &r.positions, bytemuck::cast_slice(&r.normals));
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
    normals: &[PackedNormal],
) -> ChunkLists {
    let m = positions.len();
    let head = ChunkLists::header_words(level);
    // Row k is byte k of the bitmap; only nonzero rows are stored, right after the header (on
    // its cache line), padded to an even number of bytes so the values that follow are aligned.
    let stored: usize = nonempty.iter().map(|&w| nonzero_bytes(w)).sum();
    let len = head + (stored.next_multiple_of(2) + 4 * m).div_ceil(8);
    let words = thin::Words::filled(len, |data| {
        write_bits(data, field::LEVEL.0, field::LEVEL.1, level.code() as u64);
        write_bits(data, field::CORNER.0, field::CORNER.1, corner as u64);
        write_bits(data, field::LEN.0, field::LEN.1, len as u64);
        write_bits(data, field::CROSSINGS.0, field::CROSSINGS.1, m as u64);
        write_bits(data, field::Y_START.0, field::Y_START.1, family_start[0] as u64);
        write_bits(data, field::Z_START.0, field::Z_START.1, family_start[1] as u64);
        write_bits(data, field::STORED_ROWS.0, field::STORED_ROWS.1, stored as u64);
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
        values[m..2 * m].copy_from_slice(bytemuck::cast_slice(normals));
    });
    ChunkLists { words }
}

/// Ones among bits `[from, to)`.
#[inline]
pub(super) fn count_ones(words: &[u64], from: usize, to: usize) -> usize {
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
