//! One chunk's lines rewritten: each line combined with the brush's spans cell by cell (the
//! paper's Algorithm 1), untouched stretches spliced from the old lines, chunks the brush
//! decides whole, and the reconciliation of lines that disagree at shared nodes.

use super::*;

/// Per-cell CSG of two lines (`a` the volume, `b` the brush, normals of `b` already flipped for
/// subtraction). Where both operands change in the same cell, the boundary of the union is the
/// earlier entry / later exit, and of an intersection the later entry / earlier exit.
pub(super) fn combine(a: &WorkLine, b: &WorkLine, op: CsgOp, n: usize, out: &mut WorkLine) {
    let mask = node_mask(n);
    out.states = match op {
        CsgOp::Add => a.states | b.states,
        CsgOp::Subtract => a.states & !b.states & mask,
        CsgOp::Intersect => a.states & b.states,
    };
    let (ca, cb) = (a.changes(n), b.changes(n));
    let mut c = out.changes(n);
    while c != 0 {
        let e = c.trailing_zeros() as usize;
        c &= c - 1;
        let bit = 1u128 << e;
        let from_b = match (ca & bit != 0, cb & bit != 0) {
            (true, false) => false,
            (false, true) => true,
            _ => {
                let entering = (out.states >> (e + 1)) & 1 == 1;
                let union = op == CsgOp::Add;
                // Earlier position wins when (union and entering) or (intersection and leaving).
                let earlier_wins = union == entering;
                if earlier_wins { b.pos[e] < a.pos[e] } else { b.pos[e] > a.pos[e] }
            }
        };
        let src = if from_b { b } else { a };
        out.pos[e] = src.pos[e];
        out.nrm[e] = src.nrm[e];
    }
}

/// The lines `lo..=hi` of the `n` lines along one across-axis that the box can touch.
pub(super) fn across_range(bounds: &Aabb, origin: I64Vec3, axis: Axis, level: Level) -> Option<(usize, usize)> {
    let n = level.cells();
    let sp = level.spacing();
    let i = axis.index();
    let o = origin[i] as f64;
    let lo = ((bounds.min[i] - o) / sp).ceil().max(0.0);
    let hi = ((bounds.max[i] - o) / sp).floor().min((n - 1) as f64);
    (lo <= hi).then_some((lo as usize, hi as usize))
}

/// Edits one chunk. Returns `None` when nothing changed, else the new chunk and the number of
/// repaired brush nodes. `noted` is set where the chunk was written line by line and its changed
/// x lines were noted in `s.rows` (when `ctx.rows` asks for them).
pub(super) fn edit_chunk(
    ctx: &EditCtx<'_>,
    key: ChunkKey,
    old: ChunkView<'_>,
    level: Level,
    s: &mut Scratch,
    noted: &mut bool,
) -> Option<(Built, u64)> {
    if !ctx.reconcile && old == ChunkView::Uniform(ctx.op == CsgOp::Add) && ctx.op != CsgOp::Intersect {
        // Adding to a solid chunk or subtracting from an empty one changes nothing.
        return None;
    }
    let n = level.cells();
    let origin = key.origin_grid();
    if ctx.distance_field
        && ctx.op != CsgOp::Intersect
        && let Some(inside) = chunk_side(ctx.brush, origin)
    {
        // Every node the chunk's lines hold is on one side of the surface: a chunk inside the
        // brush becomes uniform, one outside is untouched. (This is what keeps the edit's cost
        // with the surface: a radius-770 sphere fills 460,000 chunks.)
        if !inside {
            return None;
        }
        let now = ctx.op == CsgOp::Add;
        return (old != ChunkView::Uniform(now)).then_some((Built::Uniform(now), 0));
    }
    if let Some((plain, mask)) = ctx.plain
        && ctx.op != CsgOp::Intersect
        && let Some(inside) = chunk_side(plain, origin)
    {
        // The cut brush lies within the plain one: a chunk outside that is untouched. One
        // inside it whose every node is free is inside the cut brush too.
        if !inside {
            return None;
        }
        if mask.free_in(origin, origin + I64Vec3::splat(CHUNK_CELLS)) == Some(true) {
            let now = ctx.op == CsgOp::Add;
            return (old != ChunkView::Uniform(now)).then_some((Built::Uniform(now), 0));
        }
    }
    let mut sampler = LineSampler::new(ctx.brush, ctx.op == CsgOp::Subtract);
    let at = |axis: Axis, u: usize, v: usize| LineAt { origin_grid: origin, level, axis, u, v };
    let mut repaired = 0u64;
    let table_level = ctx.tables[level.index()].as_ref().map(|t| (t, ((origin - t.base) / CHUNK_CELLS) * n as i64));
    if let Some((t, offset)) = table_level
        && ctx.op != CsgOp::Intersect
        && covers_chunk(t, offset, origin, n)
    {
        // Every node of the chunk and its apron is well inside the brush (by its x lines, which
        // are also what a reconciled brush's node states come from): no line work at all, so the
        // inside of a converted mesh costs one test per chunk.
        let now = ctx.op == CsgOp::Add;
        return (old != ChunkView::Uniform(now)).then_some((Built::Uniform(now), 0));
    }
    if ctx.reconcile {
        // Node states of the brush from the x lines, apron rows included: states.x[y + (n+1) z],
        // from the span table where there is one (each line's spans were found once for the
        // whole edit; an apron row is its owner's line, so both chunks read the same spans).
        s.states.x.clear();
        let mut line = WorkLine::EMPTY;
        // (A line of one span with no end near a node takes its states from the table's node
        // range, without reading its span.)
        let x_table =
            table_level.map(|(t, offset)| (&t.axes[0], offset.x, offset.y, offset.z, (origin.x - t.base.x) as f64));
        for z in 0..=n {
            for y in 0..=n {
                let states = match x_table {
                    Some((spans, off_x, off_y, off_z, shift)) => {
                        let (u, v) = (off_y + y as i64, off_z + z as i64);
                        simple_states(spans.range_at(u, v), off_x, n)
                            .unwrap_or_else(|| sampler.states_from_spans(spans.line(u, v), shift, at(Axis::X, y, z)))
                    }
                    None => {
                        sampler.sample(at(Axis::X, y, z), &mut line);
                        line.states
                    }
                };
                s.states.x.push(states);
            }
        }
        if ctx.op != CsgOp::Intersect && s.states.x.iter().all(|&r| r == 0) {
            // The brush holds no node of the chunk or its apron: nothing changes (the common
            // case for the empty chunks around a converted mesh).
            return None;
        }
        s.states.transpose(n);
    }
    if let Some((t, offset)) = table_level
        && ctx.op != CsgOp::Intersect
        && !ctx.reconcile
    {
        *noted = ctx.rows;
        return edit_chunk_by_table(ctx, t, offset, origin, old, level, s, &mut sampler).map(|b| (b, 0));
    }
    // Lines are visited in storage order and written straight into the new chunk, the lines
    // between them copied in runs (as in `edit_chunk_by_table`).
    *noted = ctx.rows;
    let Scratch { builder: b, rows, states } = s;
    b.begin(level);
    let mut changed = false;
    let (mut old_line, mut brush_line, mut new_line) = (WorkLine::EMPTY, WorkLine::EMPTY, WorkLine::EMPTY);
    let full = node_mask(n);
    for axis in Axis::ALL {
        b.begin_axis(axis);
        let mut cursor = old.cursor(axis, 0);
        // The next line not yet written.
        let mut next = 0;
        let (ua, va) = axis.across();
        let ranges = (across_range(&ctx.bounds, origin, ua, level), across_range(&ctx.bounds, origin, va, level));
        let ((u0, u1), (v0, v1)) = match (ctx.op, ranges) {
            (CsgOp::Intersect, _) => ((0, n - 1), (0, n - 1)),
            (_, (Some(ur), Some(vr))) => (ur, vr),
            _ => {
                b.copy_view(&mut cursor, n * n);
                continue;
            }
        };
        // Per-axis constants of the table lookups (glam vectors indexed by a runtime axis cost a
        // match each time).
        let table_axis = table_level
            .map(|(t, offset)| (&t.axes[axis.index()], offset[ua.index()], offset[va.index()], offset[axis.index()]));
        let shift_along = table_level.map_or(0.0, |(t, _)| (origin[axis.index()] - t.base[axis.index()]) as f64);
        // Every line of the box is visited: an intersection empties lines without spans, and
        // repairs can give them node states.
        for v in v0..=v1 {
            for u in u0..=u1 {
                // Only an intersection visits lines outside the brush's box.
                let inside_box = ctx.op != CsgOp::Intersect
                    || (ranges.0.is_some_and(|(a, b)| (a..=b).contains(&u))
                        && ranges.1.is_some_and(|(a, b)| (a..=b).contains(&v)));
                let index = u + n * v;
                // Where the brush line is taken from: nothing, the span table, or the sampler.
                if !inside_box {
                    brush_line.states = 0;
                } else if let Some((axis_spans, off_u, off_v, off)) = table_axis {
                    let (tu, tv) = (off_u + u as i64, off_v + v as i64);
                    if simple_states(axis_spans.range_at(tu, tv), off, n) == Some(0) {
                        // No span, or one span that holds none of this piece's nodes.
                        brush_line.states = 0;
                    } else {
                        sampler.fill_from_spans(axis_spans.line(tu, tv), shift_along, at(axis, u, v), &mut brush_line);
                    }
                } else {
                    sampler.sample(at(axis, u, v), &mut brush_line);
                }
                if ctx.reconcile && inside_box && axis != Axis::X {
                    repaired += reconcile_line(states.along(axis, u, v, n), axis, level, sampler.flip, &mut brush_line);
                }
                if brush_line.states == 0 && ctx.op != CsgOp::Intersect {
                    // An empty brush line leaves a union or difference unchanged.
                    continue;
                }
                b.copy_view(&mut cursor, index - next);
                next = index + 1;
                let line = cursor.next_line();
                let uniform = line.is_empty();
                if uniform && ctx.op != CsgOp::Intersect && line.start_inside == (ctx.op == CsgOp::Add) {
                    // Adding to a full line or subtracting from an empty one changes nothing.
                    b.push_stored(line);
                    continue;
                }
                if brush_line.states == full && ctx.op != CsgOp::Intersect {
                    // The brush fills the line: the result is a full or an empty line.
                    let now = ctx.op == CsgOp::Add;
                    if line.start_inside != now || !uniform {
                        if ctx.rows && axis == Axis::X {
                            let after = if now { full } else { 0 };
                            note_row(rows, axis, index, line_states(line, level), after, n);
                        }
                        b.push_uniform(now, 1);
                        changed = true;
                    } else {
                        b.push_stored(line);
                    }
                    continue;
                }
                let (result, before) = if uniform && ctx.op != CsgOp::Intersect {
                    // An empty line gains the brush's piece, a full line loses it: the crossings
                    // are the brush's (its normals are already flipped for subtraction).
                    if ctx.op == CsgOp::Subtract {
                        brush_line.states = !brush_line.states & full;
                    }
                    (&brush_line, if line.start_inside { full } else { 0 })
                } else {
                    old_line.load(line, level);
                    combine(&old_line, &brush_line, ctx.op, n, &mut new_line);
                    if new_line.same_as(&old_line, n) {
                        b.push_stored(line);
                        continue;
                    }
                    (&new_line, old_line.states)
                };
                if ctx.rows {
                    note_row(rows, axis, index, before, result.states, n);
                }
                b.push_work(result, n);
                changed = true;
            }
        }
        b.copy_view(&mut cursor, n * n - next);
    }
    changed.then(|| (b.finish(), repaired))
}

/// One brush span on one chunk line, simple (no end within the snapping distance of a node):
/// it covers nodes `lo..=hi`, enters in cell `lo - 1` (if `lo > 0`) and leaves in cell `hi` (if
/// `hi < n`); its ends are `shift` grid units ahead of the line's node 0, quantised only where
/// they are stored. `fill` is the state the covered nodes take: inside for a union, outside for
/// a difference (whose stored normals are the brush's, flipped).
pub(super) struct Piece<'a> {
    pub(super) fill: bool,
    pub(super) lo: usize,
    pub(super) hi: usize,
    pub(super) span: &'a Span,
    pub(super) shift: f64,
}

/// Writes the CSG of a stored line and a simple brush piece into `b`, with the per-cell rule of
/// [`combine`] (where both change in one cell, the earlier crossing wins on the piece's enter side
/// and the later on its exit side) but without unpacking the line: the stored crossings before
/// cell `lo - 1` and after cell `hi` stay, the ones between go, and at most two crossings are
/// put in their place. Returns whether the line changed.
#[inline(always)]
pub(super) fn splice_piece(b: &mut ChunkBuilder, line: LineRef<'_>, piece: Piece<'_>, level: Level) -> bool {
    let n = level.cells();
    let Piece { fill, lo, hi, span, shift } = piece;
    let stored = line.stored();
    let k = stored.len();
    let cell = |i: usize| edge_of(crate::coords::LocalPos(stored[i] & !LAST), level);
    // Crossings before cell lo - 1 (none when the piece starts at node 0).
    let mut p = 0;
    if lo > 0 {
        while p < k && cell(p) < lo - 1 {
            p += 1;
        }
    }
    // Crossings up to cell hi (all when the piece reaches node n).
    let mut q = p;
    if hi < n {
        while q < k && cell(q) <= hi {
            q += 1;
        }
    } else {
        q = k;
    }
    let mut mid = [(crate::coords::LocalPos(0), crate::normal::PackedNormal(0)); 2];
    let (mut m, mut kept) = (0, 0);
    // Node lo - 1 keeps its stored state; a crossing is needed where it differs from `fill`.
    if lo > 0 && line.start_inside ^ (p % 2 == 1) != fill {
        let brush = quantize_into_edge(span.enter - shift, lo - 1, level);
        let old = p < k && cell(p) == lo - 1 && crate::coords::LocalPos(stored[p] & !LAST) <= brush;
        mid[m] = if old { line.crossing(p) } else { (brush, pack_oriented(span.enter_normal, !fill)) };
        (m, kept) = (m + 1, kept + old as usize);
    }
    // Node hi + 1 likewise.
    if hi < n && line.start_inside ^ (q % 2 == 1) != fill {
        let brush = quantize_into_edge(span.exit - shift, hi, level);
        let old = q > 0 && cell(q - 1) == hi && crate::coords::LocalPos(stored[q - 1] & !LAST) >= brush;
        mid[m] = if old { line.crossing(q - 1) } else { (brush, pack_oriented(span.exit_normal, !fill)) };
        (m, kept) = (m + 1, kept + old as usize);
    }
    let start = if lo == 0 { fill } else { line.start_inside };
    // The stored crossings p..q are replaced by mid: nothing changes when mid is exactly them
    // (the ones kept are p and q - 1 of the stored line).
    if start == line.start_inside && kept == m && q - p == m {
        b.push_stored(line);
        return false;
    }
    b.push_spliced(start, line, p, q, &mid[..m]);
    true
}

/// For a brush whose field is a distance: `Some(true)` when every node of the chunk at
/// `origin` (its lines' nodes `0..=n`, so the box `[origin, origin + 16]`) is inside the brush,
/// `Some(false)` when none is, `None` when the surface may pass through, from the field at the
/// box's centre and the distance to its corners (with a margin for rounding and snapping).
pub(super) fn chunk_side(brush: &dyn Brush, origin: I64Vec3) -> Option<bool> {
    let half = CHUNK_CELLS as f64 / 2.0;
    let f = brush.field(origin.as_dvec3(), DVec3::splat(half));
    let reach = half * 3f64.sqrt() + SNAP_DISTANCE + 1e-9 * (1.0 + f.abs());
    if f < -reach {
        Some(true)
    } else if f > reach {
        Some(false)
    } else {
        None
    }
}

/// A reconciled brush's node states, from its x lines (apron rows included), and the same states
/// as bit rows along y and z, for the y and z lines that are forced to them.
#[derive(Default)]
pub(super) struct NodeStates {
    /// `x[y + (n+1) z]`: bit `x` is node (x, y, z).
    pub(super) x: Vec<u128>,
    /// `y[z + (n+1) x]`: bit `y` is node (x, y, z).
    y: Vec<u128>,
    /// `z[x + (n+1) y]`: bit `z` is node (x, y, z).
    z: Vec<u128>,
}

impl NodeStates {
    /// Fills the y and z rows from the x rows (a chunk of `n` cells a side). Visits each inside
    /// node once, where reading a y or z line's bits from the x rows one node at a time visits
    /// every node of every line.
    pub(super) fn transpose(&mut self, n: usize) {
        let m = n + 1;
        debug_assert_eq!(self.x.len(), m * m);
        self.y.clear();
        self.y.resize(m * m, 0);
        self.z.clear();
        self.z.resize(m * m, 0);
        for z in 0..m {
            for y in 0..m {
                let mut row = self.x[y + m * z];
                while row != 0 {
                    let x = row.trailing_zeros() as usize;
                    row &= row - 1;
                    self.y[z + m * x] |= 1 << y;
                    self.z[x + m * y] |= 1 << z;
                }
            }
        }
    }

    /// The node states of the `axis` line at (`u`, `v`) (y lines: (u, v) = (z, x); z lines:
    /// (u, v) = (x, y)). Only for y and z.
    pub(super) fn along(&self, axis: Axis, u: usize, v: usize, n: usize) -> u128 {
        let m = n + 1;
        match axis {
            Axis::Y => self.y[u + m * v],
            _ => self.z[u + m * v],
        }
    }
}

/// Forces a y or z brush line to the node states `expect` the x lines give it; returns how many
/// nodes moved.
pub(super) fn reconcile_line(expect: u128, axis: Axis, level: Level, flip: bool, line: &mut WorkLine) -> u64 {
    let n = level.cells();
    if expect == line.states {
        return 0;
    }
    let moved = (expect ^ line.states).count_ones() as u64;
    let before = line.changes(n);
    line.states = expect;
    let mut c = line.changes(n);
    while c != 0 {
        let e = c.trailing_zeros() as usize;
        c &= c - 1;
        let entering = (expect >> (e + 1)) & 1 == 1;
        let dir = axis.unit();
        // The stored normal of a subtracted brush points into the brush.
        let outward = if entering != flip { -dir } else { dir };
        if before & (1 << e) == 0 {
            line.pos[e] = crate::coords::quantize_into_edge((e as f64 + 0.5) * level.spacing(), e, level);
            line.nrm[e] = pack_normal(outward);
        } else if unpack_normal(line.nrm[e]).dot(outward) < 0.0 {
            line.nrm[e] = flip_normal(line.nrm[e]);
        }
    }
    moved
}
