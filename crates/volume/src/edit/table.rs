//! Span tables: the brush's spans on every grid line through its box, sampled once per edit
//! and shared by the chunks a line crosses, and the chunk edit that reads them.

use super::*;

/// The brush's spans on every grid line through its box, computed once per edit (a line
/// crosses several chunks) relative to the grid origin `base` of the first chunk of the edit's
/// range, so the result depends only on where the brush sits relative to the chunk grid.
pub(super) struct SpanTable {
    pub(super) base: I64Vec3,
    pub(super) axes: [AxisSpans; 3],
}

#[derive(Default)]
pub(super) struct AxisSpans {
    /// Node coordinates (relative to `base`, in level units) of the first line on each across
    /// axis, and the line counts.
    pub(super) u0: i64,
    pub(super) v0: i64,
    pub(super) nu: usize,
    pub(super) nv: usize,
    pub(super) offsets: Vec<u32>,
    pub(super) spans: Vec<Span>,
    /// Per line: the nodes `j0..=j1` (relative to the table base along the axis, level units)
    /// inside its one span when no span end lies within the snapping distance of a node, so any
    /// chunk piece of the line follows by integer arithmetic. Lines without spans hold
    /// [`NO_NODES`] and lines that need the general sampler [`ALL_NODES`]: as node ranges, they
    /// miss and meet every chunk, so one range test sorts out every line.
    pub(super) simple: Vec<(i32, i32)>,
    /// Per row `v`: the first and one past the last `u` whose line has spans (empty if none).
    pub(super) rows: Vec<(i64, i64)>,
}

impl AxisSpans {
    /// Lines `u` of row `v` (absolute, relative to the table base) that can have spans.
    #[inline]
    fn row_range(&self, v: i64) -> (i64, i64) {
        // (A table without lines across has no rows at all.)
        match usize::try_from(v - self.v0).ok().and_then(|r| self.rows.get(r)) {
            Some(&(a, b)) => (a + self.u0, b + self.u0),
            None => (0, 0),
        }
    }

    /// Row `v` (`0..n`) of the chunk whose first line is `(off_u, off_v)` (relative to the table
    /// base): the chunk-relative `u` of the first line that can have spans, its index in the
    /// table, and the simple ranges of the lines from there to the last that can (none if no
    /// line can).
    #[inline]
    fn chunk_row(&self, off_u: i64, off_v: i64, v: usize, n: usize) -> (usize, usize, &[(i32, i32)]) {
        let row = off_v + v as i64;
        let (a, e) = self.row_range(row);
        let (a, e) = (a.max(off_u), e.min(off_u + n as i64));
        if a >= e {
            return (0, 0, &[]);
        }
        let i = (a - self.u0) as usize + self.nu * (row - self.v0) as usize;
        ((a - off_u) as usize, i, &self.simple[i..i + (e - a) as usize])
    }

    /// The spans of the line at table index `i`.
    #[inline]
    fn spans_at(&self, i: usize) -> &[Span] {
        &self.spans[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// The simple range of line `(u, v)` (absolute, relative to the table base; [`NO_NODES`]
    /// outside the table).
    #[inline]
    pub(super) fn range_at(&self, u: i64, v: i64) -> (i32, i32) {
        let (u, v) = (u - self.u0, v - self.v0);
        if u < 0 || v < 0 || u as usize >= self.nu || v as usize >= self.nv {
            return NO_NODES;
        }
        self.simple[u as usize + self.nu * v as usize]
    }

    /// The spans of line `(u, v)` (absolute, relative to the table base).
    #[inline]
    pub(super) fn line(&self, u: i64, v: i64) -> &[Span] {
        let (u, v) = (u - self.u0, v - self.v0);
        if u < 0 || v < 0 || u as usize >= self.nu || v as usize >= self.nv {
            return &[];
        }
        let i = u as usize + self.nu * v as usize;
        &self.spans[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
}

/// The simple range of a line of a span table whose pieces need the general sampler.
pub(super) const ALL_NODES: (i32, i32) = (i32::MIN, i32::MAX);
/// The simple range of a line of a span table without spans.
pub(super) const NO_NODES: (i32, i32) = (i32::MAX, i32::MIN);

/// The simple node range of a line (see [`AxisSpans::simple`]).
pub(super) fn simple_range(spans: &[Span], inv_sp: f64) -> (i32, i32) {
    let s = match spans {
        [] => return NO_NODES,
        [s] => s,
        _ => return ALL_NODES,
    };
    let snap = SNAP_DISTANCE * inv_sp;
    let (enter, exit) = (s.enter * inv_sp, s.exit * inv_sp);
    let (first, last) = (enter.ceil(), exit.floor());
    // An end is near a node when its distance to the node on either side is within `snap`.
    let near = |gap: f64| gap <= snap || gap >= 1.0 - snap;
    let limit = (i32::MAX / 2) as f64;
    if near(first - enter) || near(exit - last) || !(enter.abs() < limit && exit.abs() < limit) {
        return ALL_NODES;
    }
    (first as i32, last as i32)
}

/// What the rows of a span table produce.
#[derive(Default)]
pub(super) struct RowOut {
    pub(super) counts: Vec<u32>,
    pub(super) spans: Vec<Span>,
    pub(super) simple: Vec<(i32, i32)>,
}

/// Edits of fewer chunks run on the calling thread even when parallel edits are asked for: on
/// the Table 1 canvas the thread hand-off costs more than it saves below about this many
/// (radius-15 spheres, about 25 chunks, break even on two cores).
pub(super) const PARALLEL_MIN_CHUNKS: usize = 32;

/// Tables of fewer lines are built on the calling thread, larger ones an axis per task.
pub(super) const PARALLEL_TABLE_LINES: i64 = 1 << 14;
/// An axis of at least this many lines is built in runs of rows about this long, in parallel.
pub(super) const PARALLEL_ROW_LINES: usize = 1 << 15;

/// Lines beyond which the table is not built (each costs a few bytes even when empty); larger
/// brushes are sampled chunk by chunk instead.
pub(super) const TABLE_MAX_LINES: i64 = 1 << 22;

impl SpanTable {
    pub(super) fn build(brush: &dyn Brush, bounds: &Aabb, cmin: IVec3, level: Level, parallel: bool) -> Option<Self> {
        let base = ChunkKey(cmin).origin_grid();
        let origin = base.as_dvec3();
        let mut probe = Vec::new();
        if !brush.spans(origin, DVec3::ZERO, DVec3::X, &mut probe) {
            return None;
        }
        let sp = level.spacing();
        let range = |i: usize| {
            let lo = ((bounds.min[i] - origin[i]) / sp).ceil().max(0.0) as i64;
            let hi = ((bounds.max[i] - origin[i]) / sp).floor() as i64;
            (lo, (hi - lo + 1).max(0))
        };
        let mut total = 0;
        for axis in Axis::ALL {
            let (ua, va) = axis.across();
            total += range(ua.index()).1 * range(va.index()).1;
        }
        if total > TABLE_MAX_LINES {
            return None;
        }
        let build_axis = |axis: Axis| -> Option<AxisSpans> {
            let (ua, va) = axis.across();
            let ((u0, nu), (v0, nv)) = (range(ua.index()), range(va.index()));
            let n = level.cells() as i64;
            let shift = n.trailing_zeros();
            let dir = axis.unit();
            // One row of lines: appends span counts, spans and simple ranges.
            let (step_u, step_v) = (ua.unit() * sp, va.unit() * sp);
            let (mask, inv_sp) = (n - 1, level.nodes_per_unit());
            let row = |v: i64, out: &mut RowOut, lines: &mut Vec<(DVec3, DVec3)>| {
                // Across the line, measure from the origin of the chunk that owns the line,
                // exactly as the node predicate does; along it, from the table's base. A box
                // face that falls on a node plane then includes or excludes the line exactly as
                // `contains` includes or excludes its nodes. (n is a power of two: shifts and
                // masks, no divisions; the start points are exact: small multiples of `sp`.)
                let (cv, lv) = (v >> shift, step_v * (v & mask) as f64);
                lines.clear();
                let mut u = u0;
                while u < u0 + nu {
                    let cu = u >> shift;
                    let chunk = I64Vec3::from_array(compose(axis, 0, cu, cv));
                    let line_origin = origin + (chunk * CHUNK_CELLS).as_dvec3();
                    let end = ((cu + 1) << shift).min(u0 + nu);
                    lines.extend((u..end).map(|u| (line_origin, lv + step_u * (u & mask) as f64)));
                    u = end;
                }
                let (first_count, mut next) = (out.counts.len(), out.spans.len());
                if !brush.spans_batch(lines, dir, &mut out.spans, &mut out.counts) {
                    // The brush samples after all: no table (the caller samples chunk by chunk).
                    return false;
                }
                let RowOut { counts, spans, simple } = out;
                simple.extend(counts[first_count..].iter().map(|&c| {
                    let end = next + c as usize;
                    let range = simple_range(&spans[next..end], inv_sp);
                    next = end;
                    range
                }));
                true
            };
            let mut a = AxisSpans { u0, v0, nu: nu as usize, nv: nv as usize, ..Default::default() };
            let lines_total = (nu * nv) as usize;
            let mut out = RowOut {
                counts: Vec::with_capacity(lines_total),
                spans: Vec::with_capacity(lines_total),
                simple: Vec::with_capacity(lines_total),
            };
            if parallel && lines_total >= PARALLEL_ROW_LINES {
                // Rows in parallel, in runs of about PARALLEL_ROW_LINES lines per task.
                let per_task = (PARALLEL_ROW_LINES / nu.max(1) as usize).max(1);
                let runs: Option<Vec<RowOut>> = (0..nv as usize)
                    .into_par_iter()
                    .with_min_len(per_task)
                    .fold(
                        || Some((RowOut::default(), Vec::new())),
                        |acc, i| {
                            let (mut o, mut lines) = acc?;
                            row(v0 + i as i64, &mut o, &mut lines).then_some((o, lines))
                        },
                    )
                    .map(|acc| acc.map(|(o, _)| o))
                    .collect();
                for o in runs? {
                    out.counts.extend(o.counts);
                    out.spans.extend(o.spans);
                    out.simple.extend(o.simple);
                }
            } else {
                let mut lines = Vec::with_capacity(nu as usize);
                for v in v0..v0 + nv {
                    if !row(v, &mut out, &mut lines) {
                        return None;
                    }
                }
            }
            let counts = out.counts;
            a.spans = out.spans;
            a.simple = out.simple;
            // (Collected from iterators rather than pushed: a push per line kept the length in
            // memory and took a seventh of the table's time.)
            let mut total = 0;
            a.offsets = std::iter::once(0)
                .chain(counts.iter().map(|&c| {
                    total += c;
                    total
                }))
                .collect();
            a.rows = counts
                .chunks(nu.max(1) as usize)
                .map(|r| match (r.iter().position(|&c| c > 0), r.iter().rposition(|&c| c > 0)) {
                    (Some(f), Some(l)) => (f as i64, l as i64 + 1),
                    _ => (0, 0),
                })
                .collect();
            Some(a)
        };
        // Small tables are built on the calling thread: a task hand-off costs more than they do.
        let axes: Vec<AxisSpans> = if parallel && total >= PARALLEL_TABLE_LINES {
            Axis::ALL.par_iter().map(|&axis| build_axis(axis)).collect::<Option<_>>()?
        } else {
            Axis::ALL.iter().map(|&axis| build_axis(axis)).collect::<Option<_>>()?
        };
        let axes: [AxisSpans; 3] = axes.try_into().ok()?;
        Some(SpanTable { base, axes })
    }
}

/// A union or difference by a brush with a span table: the lines the brush reaches are visited
/// in storage order and written straight into the new chunk, the lines between them copied in
/// runs. A line whose piece of its one span is simple (see [`AxisSpans::simple`]) is spliced
/// into the stored crossings without unpacking them ([`splice_piece`]); other lines go through
/// the general sampler and [`combine`].
#[allow(clippy::too_many_arguments)]
pub(super) fn edit_chunk_by_table(
    ctx: &EditCtx<'_>,
    t: &SpanTable,
    offset: I64Vec3,
    origin: I64Vec3,
    old: ChunkView<'_>,
    level: Level,
    s: &mut Scratch,
    sampler: &mut LineSampler<'_>,
) -> Option<Built> {
    let n = level.cells();
    if !meets_chunk(t, offset, n) {
        // No span reaches the chunk: nothing to read or copy.
        return None;
    }
    let fill = ctx.op == CsgOp::Add;
    let Scratch { builder: b, rows, .. } = s;
    b.begin(level);
    let mut changed = false;
    let (mut old_line, mut brush_line, mut new_line) = (WorkLine::EMPTY, WorkLine::EMPTY, WorkLine::EMPTY);
    for axis in Axis::ALL {
        b.begin_axis(axis);
        let (ua, va) = axis.across();
        let spans = &t.axes[axis.index()];
        // Per-axis constants (glam vectors indexed by a runtime axis cost a match each time).
        let (off_u, off_v, off) = (offset[ua.index()], offset[va.index()], offset[axis.index()]);
        let shift_along = (origin[axis.index()] - t.base[axis.index()]) as f64;
        let mut cursor = old.cursor(axis, 0);
        // The next line not yet written.
        let mut next = 0;
        for v in 0..n {
            let (a, first_line, simple) = spans.chunk_row(off_u, off_v, v, n);
            for (j, &range) in simple.iter().enumerate() {
                let u = a + j;
                let Some((ja, jb)) = reach(range, off, n) else {
                    // No span, or one that misses this chunk's piece of the line.
                    continue;
                };
                let index = u + n * v;
                if range != ALL_NODES {
                    let (lo, hi) = (ja.max(0) as usize, jb.min(n as i64) as usize);
                    b.copy_view(&mut cursor, index - next);
                    next = index + 1;
                    let line = cursor.next_line();
                    if line.is_empty() && line.start_inside == fill {
                        // Adding to a full line or subtracting from an empty one changes nothing.
                        b.push_stored(line);
                        continue;
                    }
                    let span = &spans.spans[spans.offsets[first_line + j] as usize];
                    let piece = Piece { fill, lo, hi, span, shift: shift_along };
                    let spliced = splice_piece(b, line, piece, level);
                    if spliced && ctx.rows && axis == Axis::X {
                        // The piece's nodes `lo..=hi` take the fill state.
                        let before = line_states(line, level);
                        let covered = node_mask(hi) & !((1u128 << lo) - 1);
                        let after = if fill { before | covered } else { before & !covered };
                        note_row(rows, axis, index, before, after, n);
                    }
                    changed |= spliced;
                } else {
                    sampler.fill_from_spans(
                        spans.spans_at(first_line + j),
                        shift_along,
                        LineAt { origin_grid: origin, level, axis, u, v },
                        &mut brush_line,
                    );
                    if brush_line.states == 0 {
                        continue;
                    }
                    b.copy_view(&mut cursor, index - next);
                    next = index + 1;
                    let line = cursor.next_line();
                    old_line.load(line, level);
                    combine(&old_line, &brush_line, ctx.op, n, &mut new_line);
                    if ctx.rows {
                        note_row(rows, axis, index, old_line.states, new_line.states, n);
                    }
                    changed |= b.push_edited(line, &old_line, &new_line, n);
                }
            }
        }
        b.copy_view(&mut cursor, n * n - next);
    }
    changed.then(|| b.finish())
}

/// Whether the span of some line through the chunk at `offset` (node units from the table's
/// base) reaches its nodes: the test [`edit_chunk_by_table`] makes for each line, stopping at the
/// first that passes. About a quarter of the chunks in a sphere's box are met by no span (the
/// box's corners); they are left without building a copy of them to throw away.
pub(super) fn meets_chunk(t: &SpanTable, offset: I64Vec3, n: usize) -> bool {
    Axis::ALL.iter().any(|&axis| {
        let (ua, va) = axis.across();
        let spans = &t.axes[axis.index()];
        let (off_u, off_v, off) = (offset[ua.index()], offset[va.index()], offset[axis.index()]);
        (0..n).any(|v| spans.chunk_row(off_u, off_v, v, n).2.iter().any(|&r| reach(r, off, n).is_some()))
    })
}

/// The nodes `ja..=jb` of a chunk line that a table line's simple range `(j0, j1)` covers,
/// relative to the chunk (whose node 0 is node `off` of the table; the shift is exact), if it
/// covers any of the chunk's nodes `0..=n`. [`NO_NODES`] never does, [`ALL_NODES`] always.
#[inline(always)]
pub(super) fn reach((j0, j1): (i32, i32), off: i64, n: usize) -> Option<(i64, i64)> {
    let (ja, jb) = (j0 as i64 - off, j1 as i64 - off);
    (jb >= 0 && ja <= n as i64 && ja <= jb).then_some((ja, jb))
}

/// The node states a chunk line takes from a table line's simple range (see [`reach`]): what
/// [`crate::sample::LineSampler::states_from_spans`] reads from the line's one span, whose ends
/// lie farther than the snapping distance from every node. `None` for a line that needs the
/// general sampler.
#[inline]
pub(super) fn simple_states(range: (i32, i32), off: i64, n: usize) -> Option<u128> {
    if range == ALL_NODES {
        return None;
    }
    Some(reach(range, off, n).map_or(0, |(ja, jb)| {
        let (lo, hi) = (ja.max(0) as usize, jb.min(n as i64) as usize);
        node_mask(hi) & !((1u128 << lo) - 1)
    }))
}

/// Whether every x line through the chunk (apron rows included) lies inside one span from
/// before node 0 to after node `n`, farther than the snapping distance from both ends.
pub(super) fn covers_chunk(t: &SpanTable, offset: I64Vec3, origin: I64Vec3, n: usize) -> bool {
    let shift = (origin.x - t.base.x) as f64;
    let end = CHUNK_CELLS as f64;
    for z in 0..=n as i64 {
        for y in 0..=n as i64 {
            let spans = t.axes[0].line(offset.y + y, offset.z + z);
            let covered =
                spans.iter().any(|s| s.enter - shift < -SNAP_DISTANCE && s.exit - shift > end + SNAP_DISTANCE);
            if !covered {
                return false;
            }
        }
    }
    true
}
