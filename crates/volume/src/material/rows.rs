//! Materials from the lines an edit changed: the x lines whose own node states changed
//! ([`RowChange`], noted by the writers), a forward reader of a chunk's change points
//! ([`IdReader`]), and the pass that rewrites only those rows ([`splice_rows`]).

use super::*;

/// One x line of a chunk whose own node states an edit changed: its index (`y + n z`, the row
/// of the materials' x-major order) and its own nodes' states before and after (bit `x`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RowChange {
    pub(crate) row: u32,
    pub(crate) before: u64,
    pub(crate) after: u64,
}

/// Notes x line `index` in `rows` when its own nodes' states went from `before` to `after`
/// (what the materials pass reads instead of every node of the chunk). Lines along y and z are
/// not noted (callers skip computing their states).
#[inline]
pub(crate) fn note_row(rows: &mut Vec<RowChange>, axis: Axis, index: usize, before: u128, after: u128, n: usize) {
    let own = (1u128 << n) - 1;
    if axis == Axis::X && (before ^ after) & own != 0 {
        // (A chunk's own nodes are at most 64 a line.)
        rows.push(RowChange { row: index as u32, before: (before & own) as u64, after: (after & own) as u64 });
    }
}

/// The change points of a chunk, walked forward once (x-major order, never going back): the id in
/// effect at a node, the ids of a run of nodes (what a block that needs a few rows of a chunk
/// reads instead of decoding all `n³` nodes), and the points of a stretch to copy.
pub(crate) struct IdReader<'a> {
    bytes: &'a [u8],
    entries: Entries<'a>,
    /// Where the next point's entry starts in `bytes`.
    next_start: usize,
    /// The id of the last point consumed (`None`: before the first point of runs, where no node
    /// is solid).
    id: Option<MaterialId>,
    /// The next point's node (`usize::MAX`: none) and id.
    next_at: usize,
    next_id: MaterialId,
}

impl<'a> IdReader<'a> {
    pub(crate) fn new(this: Option<&'a ChunkMaterials>) -> Self {
        let (bytes, id): (&[u8], _) = match this {
            None => (&[], Some(0)),
            Some(ChunkMaterials::Uniform(id)) => (&[], Some(*id)),
            Some(ChunkMaterials::Runs(bytes)) => (bytes, None),
        };
        let mut p = IdReader { bytes, entries: Entries::new(bytes), next_start: 0, id, next_at: 0, next_id: 0 };
        p.fetch();
        p
    }

    fn fetch(&mut self) {
        self.next_start = self.entries.at;
        match self.entries.next() {
            Some(Ok((delta, id))) => {
                self.next_at = self.next_at.saturating_add(delta);
                self.next_id = id;
            }
            _ => self.next_at = usize::MAX,
        }
    }

    /// Consumes the points before node `i`.
    fn skip_below(&mut self, i: usize) {
        while self.next_at < i {
            self.id = Some(self.next_id);
            self.fetch();
        }
    }

    /// The id in effect at node `i` (not before the last node asked).
    fn id_at(&mut self, i: usize) -> Option<MaterialId> {
        self.skip_below(i + 1);
        self.id
    }

    /// The ids of the nodes `start..start + out.len()`, into `out` (empty nodes before the first
    /// point read 0, as decoding gives them). `start` is at least the end of the nodes read
    /// before.
    pub(crate) fn read(&mut self, start: usize, out: &mut [MaterialId]) {
        let end = start + out.len();
        let mut i = start;
        while i < end {
            self.skip_below(i + 1);
            let stop = end.min(self.next_at);
            out[i - start..stop - start].fill(self.id.unwrap_or(0));
            i = stop;
        }
    }
}

/// Writes change points in node order, dropping those that change nothing: the canonical
/// encoding of the solid nodes' ids when fed every solid node where its id may change.
#[derive(Default)]
struct PointWriter {
    out: Vec<u8>,
    id: Option<MaterialId>,
    last_at: usize,
    points: usize,
}

impl PointWriter {
    /// A point at node `at` (after the last one), unless the id is already `id`; returns
    /// whether it was written.
    #[inline]
    fn put(&mut self, at: usize, id: MaterialId) -> bool {
        if self.id == Some(id) {
            return false;
        }
        push_varint(&mut self.out, at - self.last_at);
        self.out.push(id);
        self.last_at = at;
        self.id = Some(id);
        self.points += 1;
        true
    }

    fn finish(self) -> Option<ChunkMaterials> {
        match (self.points, self.id) {
            (0, _) | (1, Some(0)) => None,
            (1, Some(id)) => Some(ChunkMaterials::Uniform(id)),
            _ => Some(ChunkMaterials::Runs(self.out.into())),
        }
    }
}

/// The new materials of a chunk whose own node states changed only in `rows` (sorted by row,
/// each with different states), from its `old` materials: nodes solid before and after keep
/// their ids, nodes made solid take `fill`. `view` is the chunk after the edit at `level`.
/// Only the changed rows are decoded; the change points between them are copied, with a point
/// added or dropped where a stretch is entered with another id than before.
pub(crate) fn splice_rows(
    old: Option<&ChunkMaterials>,
    rows: &[RowChange],
    fill: MaterialId,
    view: ChunkView<'_>,
    level: Level,
) -> Option<ChunkMaterials> {
    let n = level.cells();
    let nodes = n * n * n;
    let mut points = IdReader::new(old);
    let mut w = PointWriter { out: Vec::with_capacity(points.bytes.len() + 8 * rows.len()), ..Default::default() };
    // The rows after the edit, read forward where a stretch needs its first solid node.
    let mut cursor = view.cursor(Axis::X, 0);
    let own = (1u128 << n) - 1;
    // (Rows are asked in increasing order: a stretch's search ends before the next stretch.)
    let mut row_states = |r: usize| -> u128 {
        cursor.advance_to(r);
        crate::chunk::line_states(cursor.next_line(), level) & own
    };
    // Copies the old points of the unchanged nodes `a..b` (whole rows).
    let mut stretch = |a: usize, b: usize, points: &mut IdReader<'_>, w: &mut PointWriter| {
        if a >= b {
            return;
        }
        points.skip_below(a);
        if let Some(entering) = points.id
            && w.id != Some(entering)
        {
            // The stretch's solid nodes before its first point had `entering`, which the writer
            // is not at: a point on the first of them.
            let end = points.next_at.min(b);
            let mut r = a / n;
            while r * n < end {
                let bits = row_states(r);
                if bits != 0 {
                    let at = r * n + bits.trailing_zeros() as usize;
                    if at < end {
                        w.put(at, entering);
                    }
                    break;
                }
                r += 1;
            }
        }
        // The stretch's points, the first ones one at a time until one is written: the rest
        // follow it as they were stored (their deltas and ids unchanged), copied as bytes.
        while points.next_at < b {
            let (at, id) = (points.next_at, points.next_id);
            points.skip_below(at + 1);
            if w.put(at, id) {
                let from = points.next_start;
                let mut count = 0;
                while points.next_at < b {
                    let (at, id) = (points.next_at, points.next_id);
                    points.skip_below(at + 1);
                    (w.last_at, w.id) = (at, Some(id));
                    count += 1;
                }
                w.out.extend_from_slice(&points.bytes[from..points.next_start]);
                w.points += count;
                break;
            }
        }
    };
    let mut done = 0;
    for c in rows {
        let base = c.row as usize * n;
        stretch(done, base, &mut points, &mut w);
        // The row's solid nodes run by run: runs made solid take `fill`, runs that stay solid
        // their old ids (the id at the run's start, then the old points inside it).
        let (kept, grown) = (c.after & c.before, c.after & !c.before);
        let mut bits = c.after;
        while bits != 0 {
            let a = bits.trailing_zeros() as usize;
            let stays = kept >> a & 1 == 1;
            let b = a + ((if stays { kept } else { grown }) >> a).trailing_ones() as usize;
            bits &= !((u64::MAX >> (64 - (b - a))) << a);
            if stays {
                w.put(base + a, points.id_at(base + a).unwrap_or(fill));
                while points.next_at < base + b {
                    let (at, id) = (points.next_at, points.next_id);
                    points.skip_below(at + 1);
                    w.put(at, id);
                }
            } else {
                w.put(base + a, fill);
            }
        }
        done = base + n;
    }
    stretch(done, nodes, &mut points, &mut w);
    w.finish()
}
