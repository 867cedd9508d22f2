//! CSG edits: a brush added to, subtracted from or intersected with a volume, chunk by chunk and
//! line by line (the paper's Algorithm 1, applied per cell because each cell holds at most one
//! crossing), with the set of changed chunks and an exact undo record.

use glam::{DVec3, I64Vec3, IVec3};
use rayon::prelude::*;
use thiserror::Error;

use crate::axis::Axis;
use crate::axis::compose;
use crate::brush::{Aabb, Brush, SNAP_DISTANCE, Span};
use crate::chunk::{Built, Chunk, ChunkBuilder, ChunkView, LAST, LineRef, WorkLine, line_states, node_mask};
use crate::coords::{CHUNK_CELLS, ChunkKey, Level, edge_of, quantize_into_edge};
use crate::material::{MaterialRule, RowChange, note_row};
use crate::normal::{flip_normal, pack_normal, unpack_normal};
use crate::sample::{LineAt, LineSampler, pack_oriented};
use crate::volume::Volume;

/// How a brush combines with the volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum CsgOp {
    /// Union: the brush's inside becomes solid.
    Add,
    /// Difference: the brush's inside becomes empty.
    Subtract,
    /// Intersection: everything outside the brush becomes empty.
    Intersect,
}

/// Options for [`Volume::apply`].
#[derive(Clone, Debug)]
pub struct EditSettings {
    /// Edit chunks in parallel with rayon (edits of fewer than 32 chunks, where the hand-off
    /// costs more than it saves, still run on the calling thread).
    pub parallel: bool,
    /// Refuse edits whose box spans more chunks than this (a brush a billion cells wide would
    /// otherwise run out of memory).
    pub max_chunks: u64,
    /// Progress and cancellation, for an edit run on another thread (`None`: neither).
    pub control: Option<std::sync::Arc<EditControl>>,
    /// The material an [`CsgOp::Add`] gives the nodes it makes solid (nodes already solid keep
    /// theirs; subtraction and intersection change no surviving node's material).
    pub material: crate::MaterialId,
}

impl Default for EditSettings {
    /// Parallel, at most 2²⁰ chunks, no progress or cancellation, material 0.
    fn default() -> Self {
        EditSettings { parallel: true, max_chunks: 1 << 20, control: None, material: 0 }
    }
}

/// Shared with an edit in progress: how far it got, and a request to stop. A cancelled edit
/// returns [`EditError::Cancelled`] and leaves the volume as it was.
#[derive(Debug, Default)]
pub struct EditControl {
    cancelled: std::sync::atomic::AtomicBool,
    done: std::sync::atomic::AtomicU64,
    total: std::sync::atomic::AtomicU64,
}

impl EditControl {
    /// Asks the edit to stop (it checks between chunks).
    pub fn cancel(&self) {
        self.cancelled.store(true, std::sync::atomic::Ordering::Relaxed);
    }

    /// Whether a stop was asked for.
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Chunks visited and chunks to visit (0 of 0 before the edit starts).
    pub fn progress(&self) -> (u64, u64) {
        use std::sync::atomic::Ordering::Relaxed;
        (self.done.load(Relaxed), self.total.load(Relaxed))
    }
}

/// Why an edit was refused. The volume is unchanged.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum EditError {
    /// The brush's bounds are NaN, infinite or inverted.
    #[error("the brush's bounds are not finite")]
    BadBounds,
    /// The brush lies (partly) beyond the chunk key range (about ±3.4·10¹⁰ cells; the outermost
    /// chunk on each side is kept free so every chunk has neighbours).
    #[error("the brush reaches beyond the volume's chunk key range")]
    OutOfRange,
    /// The brush covers more chunks than [`EditSettings::max_chunks`].
    #[error("the brush spans {chunks} chunks, more than the limit of {limit}")]
    TooLarge {
        /// Chunks the brush's box spans (saturating).
        chunks: u64,
        /// The limit.
        limit: u64,
    },
    /// Stopped through [`EditControl::cancel`].
    #[error("the edit was cancelled")]
    Cancelled,
    /// Volumes at different resolution levels cannot be merged.
    #[error("the volumes are stored at different levels")]
    LevelMismatch,
    /// A volume whose chunks are stored at several levels cannot be merged (its lists are read
    /// at one level; chunks at others would be lost).
    #[error("the merged volume holds chunks at more than one resolution level")]
    MixedLevels,
}

/// What an edit did.
#[derive(Debug, Clone, Default)]
pub struct EditReport {
    /// Chunks whose data changed, sorted. Meshes of these chunks (and of the neighbours that
    /// read them as their apron) need rebuilding.
    pub changed: Vec<ChunkKey>,
    /// Restores the volume as it was before the edit.
    pub undo: UndoRecord,
    /// Node states of the brush that the volume repaired so that x, y and z lines agree (only
    /// for brushes whose [`Brush::lines_agree`] is false).
    pub repaired_nodes: u64,
    /// Where in the changed chunks the edit can have changed anything (`None`: anywhere in
    /// them). Meshers rebuild only the parts of a chunk's mesh that it reaches.
    pub reach: Option<Reach>,
}

/// A box that holds every node whose state or material an edit changed and both ends of every
/// edge whose crossing it moved, turned, added or removed: grid units, bounds included.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reach {
    /// The lowest corner.
    pub min: DVec3,
    /// The highest corner.
    pub max: DVec3,
}

impl Reach {
    /// The smallest box holding both.
    pub fn union(self, other: Reach) -> Reach {
        Reach { min: self.min.min(other.min), max: self.max.max(other.max) }
    }

    /// Whether the box meets the box `lo ..= hi` (grid units).
    pub fn meets(&self, lo: DVec3, hi: DVec3) -> bool {
        self.min.cmple(hi).all() && lo.cmple(self.max).all()
    }
}

impl EditReport {
    /// One report for this edit followed by `later`: the chunks either changed, and an undo
    /// record that restores the volume as it was before this edit (for a chunk both changed, the
    /// older contents).
    pub fn then(mut self, later: EditReport) -> EditReport {
        let seen: std::collections::HashSet<ChunkKey> = self.undo.keys().collect();
        for (key, chunk) in later.undo.previous {
            if !seen.contains(&key) {
                self.undo.previous.push((key, chunk));
            }
        }
        let seen: std::collections::HashSet<ChunkKey> = self.undo.materials.iter().map(|(k, _)| *k).collect();
        for (key, m) in later.undo.materials {
            if !seen.contains(&key) {
                self.undo.materials.push((key, m));
            }
        }
        // A report that changed nothing reaches nothing; otherwise the union, unknown where
        // either is.
        self.reach = match (self.changed.is_empty(), later.changed.is_empty()) {
            (_, true) => self.reach,
            (true, false) => later.reach,
            (false, false) => self.reach.zip(later.reach).map(|(a, b)| a.union(b)),
        };
        self.changed.extend(later.changed);
        self.changed.sort_by_key(|k| k.0.to_array());
        self.changed.dedup();
        self.repaired_nodes += later.repaired_nodes;
        self
    }
}

/// The previous contents of every chunk an edit changed. [`Volume::restore`] puts them back bit
/// for bit and returns the record that redoes the edit.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UndoRecord {
    pub(crate) previous: Vec<(ChunkKey, Option<Chunk>)>,
    /// Previous materials of the chunks whose materials changed.
    pub(crate) materials: crate::material::MaterialUndo,
}

impl UndoRecord {
    /// Chunks the record restores.
    pub fn keys(&self) -> impl Iterator<Item = ChunkKey> + '_ {
        let only_materials =
            self.materials.iter().map(|(k, _)| *k).filter(|k| !self.previous.iter().any(|(p, _)| p == k));
        self.previous.iter().map(|(k, _)| *k).chain(only_materials)
    }

    /// Heap bytes the record holds (for history memory budgets).
    pub fn heap_bytes(&self) -> usize {
        let entries = self.previous.capacity() * std::mem::size_of::<(ChunkKey, Option<Chunk>)>();
        entries
            + self
                .previous
                .iter()
                .map(|(_, c)| match c {
                    Some(Chunk::Lists(l)) => l.heap_bytes(),
                    _ => 0,
                })
                .sum::<usize>()
            + self.materials.capacity() * std::mem::size_of::<(ChunkKey, Option<crate::ChunkMaterials>)>()
            + self.materials.iter().map(|(_, m)| m.as_ref().map_or(0, crate::ChunkMaterials::heap_bytes)).sum::<usize>()
    }

    /// Whether the record restores nothing.
    pub fn is_empty(&self) -> bool {
        self.previous.is_empty() && self.materials.is_empty()
    }
}

/// Per-thread scratch space for chunk edits.
#[derive(Default)]
struct Scratch {
    builder: ChunkBuilder,
    x_states: Vec<u128>,
    /// The x lines whose own node states the chunk's edit changed (kept when `EditCtx::rows`).
    rows: Vec<RowChange>,
}

struct EditCtx<'a> {
    brush: &'a dyn Brush,
    op: CsgOp,
    bounds: Aabb,
    reconcile: bool,
    /// The brush's field is a distance ([`Brush::field_is_distance`]): chunks far from the
    /// surface are decided by one field value.
    distance_field: bool,
    /// Span tables by level (index: level number), for the levels of the chunks edited.
    tables: [Option<SpanTable>; crate::coords::MAX_LEVEL as usize + 1],
    /// Whether chunks note the x lines whose node states they change (for the materials).
    rows: bool,
}

/// The brush's spans on every grid line through its box, computed once per edit (a line
/// crosses several chunks) relative to the grid origin `base` of the first chunk of the edit's
/// range, so the result depends only on where the brush sits relative to the chunk grid.
struct SpanTable {
    base: I64Vec3,
    axes: [AxisSpans; 3],
}

#[derive(Default)]
struct AxisSpans {
    /// Node coordinates (relative to `base`, in level units) of the first line on each across
    /// axis, and the line counts.
    u0: i64,
    v0: i64,
    nu: usize,
    nv: usize,
    offsets: Vec<u32>,
    spans: Vec<Span>,
    /// Per line: the nodes `j0..=j1` (relative to the table base along the axis, level units)
    /// inside its one span when no span end lies within the snapping distance of a node, so any
    /// chunk piece of the line follows by integer arithmetic. Lines without spans hold
    /// [`NO_NODES`] and lines that need the general sampler [`ALL_NODES`]: as node ranges, they
    /// miss and meet every chunk, so one range test sorts out every line.
    simple: Vec<(i32, i32)>,
    /// Per row `v`: the first and one past the last `u` whose line has spans (empty if none).
    rows: Vec<(i64, i64)>,
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

    /// The spans of line `(u, v)` (absolute, relative to the table base).
    #[inline]
    fn line(&self, u: i64, v: i64) -> &[Span] {
        let (u, v) = (u - self.u0, v - self.v0);
        if u < 0 || v < 0 || u as usize >= self.nu || v as usize >= self.nv {
            return &[];
        }
        let i = u as usize + self.nu * v as usize;
        &self.spans[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
}

/// The simple range of a line of a span table whose pieces need the general sampler.
const ALL_NODES: (i32, i32) = (i32::MIN, i32::MAX);
/// The simple range of a line of a span table without spans.
const NO_NODES: (i32, i32) = (i32::MAX, i32::MIN);

/// The simple node range of a line (see [`AxisSpans::simple`]).
fn simple_range(spans: &[Span], inv_sp: f64) -> (i32, i32) {
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
struct RowOut {
    counts: Vec<u32>,
    spans: Vec<Span>,
    simple: Vec<(i32, i32)>,
}

/// Edits of fewer chunks run on the calling thread even when parallel edits are asked for: on
/// the Table 1 canvas the thread hand-off costs more than it saves below about this many
/// (radius-15 spheres, about 25 chunks, break even on two cores).
const PARALLEL_MIN_CHUNKS: usize = 32;

/// Tables of fewer lines are built on the calling thread, larger ones an axis per task.
const PARALLEL_TABLE_LINES: i64 = 1 << 14;
/// An axis of at least this many lines is built in runs of rows about this long, in parallel.
const PARALLEL_ROW_LINES: usize = 1 << 15;

/// Lines beyond which the table is not built (each costs a few bytes even when empty); larger
/// brushes are sampled chunk by chunk instead.
const TABLE_MAX_LINES: i64 = 1 << 22;

impl SpanTable {
    fn build(brush: &dyn Brush, bounds: &Aabb, cmin: IVec3, level: Level, parallel: bool) -> Option<Self> {
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

impl Volume {
    /// Adds `brush` (parallel, default limits).
    pub fn add(&mut self, brush: &dyn Brush) -> Result<EditReport, EditError> {
        self.apply(CsgOp::Add, brush, &EditSettings::default())
    }

    /// Subtracts `brush` (parallel, default limits).
    pub fn subtract(&mut self, brush: &dyn Brush) -> Result<EditReport, EditError> {
        self.apply(CsgOp::Subtract, brush, &EditSettings::default())
    }

    /// Intersects the volume with `brush` (parallel, default limits).
    pub fn intersect(&mut self, brush: &dyn Brush) -> Result<EditReport, EditError> {
        self.apply(CsgOp::Intersect, brush, &EditSettings::default())
    }

    /// Applies one CSG edit.
    pub fn apply(&mut self, op: CsgOp, brush: &dyn Brush, settings: &EditSettings) -> Result<EditReport, EditError> {
        let bounds = brush.bounds();
        if !bounds.is_valid() {
            return Err(EditError::BadBounds);
        }
        let bounds = bounds.expand(SNAP_DISTANCE);
        let (cmin, cmax) = chunk_range(&bounds, settings.max_chunks)?;
        let keys: Vec<ChunkKey> = match op {
            CsgOp::Add => keys_in(cmin, cmax).collect(),
            CsgOp::Subtract => {
                let span = (cmax - cmin + IVec3::ONE).as_i64vec3();
                if (span.x * span.y * span.z) as usize <= self.chunks.len() {
                    keys_in(cmin, cmax).filter(|k| self.chunks.contains_key(k)).collect()
                } else {
                    self.chunks.keys().copied().filter(|k| in_range(*k, cmin, cmax)).collect()
                }
            }
            CsgOp::Intersect => self.chunks.keys().copied().collect(),
        };
        // One span table per level among the chunks edited (mixed levels are rare: most edits
        // build one). A line shared by chunks of two levels is found the same way in both.
        let mut levels = [false; crate::coords::MAX_LEVEL as usize + 1];
        levels[self.level.get() as usize] = true;
        if !self.single_level() {
            for k in &keys {
                if let Some(l) = self.stored_level(*k) {
                    levels[l.get() as usize] = true;
                }
            }
        }
        let tables = std::array::from_fn(|k| {
            let level = Level::new(k as u8).expect("within the maximum level");
            if levels[k] { SpanTable::build(brush, &bounds, cmin, level, settings.parallel) } else { None }
        });
        let rule = match op {
            CsgOp::Add => MaterialRule::Fill(settings.material),
            CsgOp::Subtract | CsgOp::Intersect => MaterialRule::Nearest,
        };
        let ctx = EditCtx {
            brush,
            op,
            bounds,
            reconcile: !brush.lines_agree(),
            distance_field: brush.field_is_distance(),
            tables,
            rows: self.has_materials() || matches!(rule, MaterialRule::Fill(f) if f != 0),
        };
        let control = settings.control.as_deref();
        if let Some(c) = control {
            c.total.store(keys.len() as u64, std::sync::atomic::Ordering::Relaxed);
            c.done.store(0, std::sync::atomic::Ordering::Relaxed);
        }
        type Edited = (ChunkKey, Built, u64, Option<Vec<RowChange>>);
        let run = |scratch: &mut Scratch, key: ChunkKey| -> Option<Edited> {
            if let Some(c) = control {
                if c.is_cancelled() {
                    return None;
                }
                c.done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
            let view = self.view(key);
            if op == CsgOp::Intersect && !in_range(key, cmin, cmax) {
                return Some((key, Built::Uniform(false), 0, None));
            }
            let level = self.level_of(key);
            scratch.rows.clear();
            let mut noted = false;
            let edited = edit_chunk(&ctx, key, view, level, scratch, &mut noted);
            edited.map(|(b, r)| (key, b, r, noted.then(|| scratch.rows.clone())))
        };
        let mut results: Vec<Edited> = if settings.parallel && keys.len() >= PARALLEL_MIN_CHUNKS {
            keys.par_iter().with_min_len(4).map_init(Scratch::default, |s, &k| run(s, k)).flatten().collect()
        } else {
            let mut s = Scratch::default();
            keys.iter().filter_map(|&k| run(&mut s, k)).collect()
        };
        if control.is_some_and(EditControl::is_cancelled) {
            return Err(EditError::Cancelled);
        }
        results.sort_by_key(|r| r.0);
        let mut report = EditReport {
            changed: Vec::with_capacity(results.len()),
            undo: UndoRecord::default(),
            repaired_nodes: 0,
            reach: None,
        };
        report.undo.previous.reserve(results.len());
        let mut rows = Vec::with_capacity(results.len());
        for (key, built, repaired, changes) in results {
            let previous = match built.into_chunk() {
                Some(c) => self.chunks.insert(key, c),
                None => self.chunks.remove(&key),
            };
            report.changed.push(key);
            report.undo.previous.push((key, previous));
            report.repaired_nodes += repaired;
            rows.push(changes);
        }
        if self.settle_uniform(&mut report.changed, &mut report.undo.previous) {
            report.changed.sort();
            // Settling rewrote chunks after their lines were written: the noted rows may not
            // tell what changed, so every chunk's materials are recomputed whole.
            rows.clear();
        }
        report.undo.materials = self.update_materials(&report.undo.previous, rule, &rows);
        Ok(report)
    }

    /// Puts back the chunks of `record` and returns the record that undoes this (a redo).
    pub fn restore(&mut self, record: UndoRecord) -> UndoRecord {
        let mut redo = UndoRecord {
            previous: Vec::with_capacity(record.previous.len()),
            materials: Vec::with_capacity(record.materials.len()),
        };
        for (key, chunk) in record.previous {
            let now = match chunk {
                Some(c) => self.chunks.insert(key, c),
                None => self.chunks.remove(&key),
            };
            redo.previous.push((key, now));
        }
        for (key, m) in record.materials {
            let now = self.store_materials(key, m);
            redo.materials.push((key, now));
        }
        redo
    }
}

/// Chunks whose lines can see a change: chunk `c` holds nodes `16c ..= 16c + 16` on each line.
pub(crate) fn chunk_range(bounds: &Aabb, limit: u64) -> Result<(IVec3, IVec3), EditError> {
    let c = CHUNK_CELLS as f64;
    let lo = (bounds.min / c).ceil() - DVec3::ONE;
    let hi = (bounds.max / c).floor();
    let ok = lo.cmpge(DVec3::splat(i32::MIN as f64 + 1.0)).all() && hi.cmple(DVec3::splat(i32::MAX as f64 - 1.0)).all();
    if !ok {
        return Err(EditError::OutOfRange);
    }
    let span = (hi - lo + DVec3::ONE).max(DVec3::ZERO);
    let chunks = span.x * span.y * span.z;
    if chunks > limit as f64 {
        return Err(EditError::TooLarge { chunks: chunks.min(u64::MAX as f64) as u64, limit });
    }
    Ok((lo.as_ivec3(), hi.as_ivec3()))
}

fn keys_in(lo: IVec3, hi: IVec3) -> impl Iterator<Item = ChunkKey> {
    (lo.z..=hi.z).flat_map(move |z| (lo.y..=hi.y).flat_map(move |y| (lo.x..=hi.x).map(move |x| ChunkKey::new(x, y, z))))
}

fn in_range(k: ChunkKey, lo: IVec3, hi: IVec3) -> bool {
    k.0.cmpge(lo).all() && k.0.cmple(hi).all()
}

/// Per-cell CSG of two lines (`a` the volume, `b` the brush, normals of `b` already flipped for
/// subtraction). Where both operands change in the same cell, the boundary of the union is the
/// earlier entry / later exit, and of an intersection the later entry / earlier exit.
fn combine(a: &WorkLine, b: &WorkLine, op: CsgOp, n: usize, out: &mut WorkLine) {
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
fn across_range(bounds: &Aabb, origin: I64Vec3, axis: Axis, level: Level) -> Option<(usize, usize)> {
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
fn edit_chunk(
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
    let mut sampler = LineSampler::new(ctx.brush, ctx.op == CsgOp::Subtract);
    let at = |axis: Axis, u: usize, v: usize| LineAt { origin_grid: origin, level, axis, u, v };
    let mut repaired = 0u64;
    let table_level =
        ctx.tables[level.get() as usize].as_ref().map(|t| (t, ((origin - t.base) / CHUNK_CELLS) * n as i64));
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
        // Node states of the brush from the x lines, apron rows included: x_states[y + (n+1) z],
        // from the span table where there is one (each line's spans were found once for the
        // whole edit; an apron row is its owner's line, so both chunks read the same spans).
        s.x_states.clear();
        let mut line = WorkLine::EMPTY;
        let x_table = table_level.map(|(t, offset)| (&t.axes[0], offset.y, offset.z, (origin.x - t.base.x) as f64));
        for z in 0..=n {
            for y in 0..=n {
                match x_table {
                    Some((spans, off_y, off_z, shift)) => {
                        let spans = spans.line(off_y + y as i64, off_z + z as i64);
                        if spans.is_empty() {
                            line.states = 0;
                        } else {
                            sampler.fill_from_spans(spans, shift, at(Axis::X, y, z), &mut line);
                        }
                    }
                    None => sampler.sample(at(Axis::X, y, z), &mut line),
                }
                s.x_states.push(line.states);
            }
        }
        if ctx.op != CsgOp::Intersect && s.x_states.iter().all(|&r| r == 0) {
            // The brush holds no node of the chunk or its apron: nothing changes (the common
            // case for the empty chunks around a converted mesh).
            return None;
        }
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
    let Scratch { builder: b, rows, x_states } = s;
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
        let table_axis = table_level.map(|(t, offset)| (&t.axes[axis.index()], offset[ua.index()], offset[va.index()]));
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
                } else if let Some((axis_spans, off_u, off_v)) = table_axis {
                    let spans = axis_spans.line(off_u + u as i64, off_v + v as i64);
                    if spans.is_empty() {
                        brush_line.states = 0;
                    } else {
                        sampler.fill_from_spans(spans, shift_along, at(axis, u, v), &mut brush_line);
                    }
                } else {
                    sampler.sample(at(axis, u, v), &mut brush_line);
                }
                if ctx.reconcile && inside_box && axis != Axis::X {
                    repaired += reconcile_line(x_states, axis, u, v, level, sampler.flip, &mut brush_line);
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

/// A union or difference by a brush with a span table: the lines the brush reaches are visited
/// in storage order and written straight into the new chunk, the lines between them copied in
/// runs. A line whose piece of its one span is simple (see [`AxisSpans::simple`]) is spliced
/// into the stored crossings without unpacking them ([`splice_piece`]); other lines go through
/// the general sampler and [`combine`].
#[allow(clippy::too_many_arguments)]
fn edit_chunk_by_table(
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
fn meets_chunk(t: &SpanTable, offset: I64Vec3, n: usize) -> bool {
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
fn reach((j0, j1): (i32, i32), off: i64, n: usize) -> Option<(i64, i64)> {
    let (ja, jb) = (j0 as i64 - off, j1 as i64 - off);
    (jb >= 0 && ja <= n as i64 && ja <= jb).then_some((ja, jb))
}

/// One brush span on one chunk line, simple (no end within the snapping distance of a node):
/// it covers nodes `lo..=hi`, enters in cell `lo - 1` (if `lo > 0`) and leaves in cell `hi` (if
/// `hi < n`); its ends are `shift` grid units ahead of the line's node 0, quantised only where
/// they are stored. `fill` is the state the covered nodes take: inside for a union, outside for
/// a difference (whose stored normals are the brush's, flipped).
struct Piece<'a> {
    fill: bool,
    lo: usize,
    hi: usize,
    span: &'a Span,
    shift: f64,
}

/// Writes the CSG of a stored line and a simple brush piece into `b`, with the per-cell rule of
/// [`combine`] (where both change in one cell, the earlier crossing wins on the piece's enter side
/// and the later on its exit side) but without unpacking the line: the stored crossings before
/// cell `lo - 1` and after cell `hi` stay, the ones between go, and at most two crossings are
/// put in their place. Returns whether the line changed.
#[inline(always)]
fn splice_piece(b: &mut ChunkBuilder, line: LineRef<'_>, piece: Piece<'_>, level: Level) -> bool {
    let n = level.cells();
    let Piece { fill, lo, hi, span, shift } = piece;
    let stored = line.stored();
    let k = stored.len();
    let cell = |i: usize| edge_of(stored[i], level);
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
    let mut mid = [(0, 0); 2];
    let (mut m, mut kept) = (0, 0);
    // Node lo - 1 keeps its stored state; a crossing is needed where it differs from `fill`.
    if lo > 0 && line.start_inside ^ (p % 2 == 1) != fill {
        let brush = quantize_into_edge(span.enter - shift, lo - 1, level);
        let old = p < k && cell(p) == lo - 1 && stored[p] & !LAST <= brush;
        mid[m] = if old { line.crossing(p) } else { (brush, pack_oriented(span.enter_normal, !fill)) };
        (m, kept) = (m + 1, kept + old as usize);
    }
    // Node hi + 1 likewise.
    if hi < n && line.start_inside ^ (q % 2 == 1) != fill {
        let brush = quantize_into_edge(span.exit - shift, hi, level);
        let old = q > 0 && cell(q - 1) == hi && stored[q - 1] & !LAST >= brush;
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
fn chunk_side(brush: &dyn Brush, origin: I64Vec3) -> Option<bool> {
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

/// Whether every x line through the chunk (apron rows included) lies inside one span from
/// before node 0 to after node `n`, farther than the snapping distance from both ends.
fn covers_chunk(t: &SpanTable, offset: I64Vec3, origin: I64Vec3, n: usize) -> bool {
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

/// Forces a y or z brush line to the node states of the x lines; returns how many nodes moved.
fn reconcile_line(
    x_states: &[u128],
    axis: Axis,
    u: usize,
    v: usize,
    level: Level,
    flip: bool,
    line: &mut WorkLine,
) -> u64 {
    let n = level.cells();
    let m = n + 1;
    let mut expect = 0u128;
    for j in 0..=n {
        // y lines: (u, v) = (z, x), node (x, j, z); z lines: (u, v) = (x, y), node (x, y, j).
        let (x, row) = match axis {
            Axis::Y => (v, x_states[j + m * u]),
            _ => (u, x_states[v + m * j]),
        };
        expect |= ((row >> x) & 1) << j;
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Inside state of a line at fixed-point position `q` (not on a crossing).
    fn state_at(l: &WorkLine, q: u32, level: Level) -> bool {
        let e = (q / level.steps_per_cell()) as usize;
        let before = (l.states >> e) & 1 == 1;
        let after = (l.states >> (e + 1)) & 1 == 1;
        if before != after && q > l.pos[e] as u32 { after } else { before }
    }

    #[test]
    fn a_simple_range_reaches_exactly_the_chunks_holding_one_of_its_nodes() {
        let n = 16;
        for off in [-1_000_000, -40, -17, -16, -1, 0, 1, 15, 16, 17, 40, 1_000_000] {
            assert_eq!(reach(NO_NODES, off, n), None, "no spans, offset {off}");
            assert!(reach(ALL_NODES, off, n).is_some(), "general sampler, offset {off}");
            for j0 in -20..40 {
                for j1 in j0 - 2..j0 + 40 {
                    // Brute force: the chunk line's nodes 0..=n that lie in j0..=j1.
                    let inside: Vec<i64> = (0..=n as i64).filter(|&j| (j0..=j1).contains(&(off + j))).collect();
                    let got = reach((j0 as i32, j1 as i32), off, n).map(|(ja, jb)| (ja.max(0), jb.min(n as i64)));
                    let expect = inside.first().map(|&a| (a, *inside.last().unwrap()));
                    assert_eq!(got, expect, "range {j0}..={j1}, offset {off}");
                }
            }
        }
    }

    #[test]
    fn per_cell_csg_equals_continuous_csg_wherever_the_result_changes_once() {
        let level = Level::BASE;
        let n = level.cells();
        let s = level.steps_per_cell();
        let mut seed = 7u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        let random_line = |rnd: &mut dyn FnMut() -> u32| {
            let mut l = WorkLine::EMPTY;
            l.states = (rnd() as u128 | ((rnd() as u128) << 32)) & node_mask(n);
            for e in 0..n {
                l.pos[e] = (e as u32 * s + 1 + rnd() % (s - 1)) as u16;
                l.nrm[e] = rnd() as u16;
            }
            l
        };
        for _ in 0..1000 {
            let a = random_line(&mut rnd);
            let b = random_line(&mut rnd);
            for op in [CsgOp::Add, CsgOp::Subtract, CsgOp::Intersect] {
                let mut out = WorkLine::EMPTY;
                combine(&a, &b, op, n, &mut out);
                let f = |q: u32| {
                    let (x, y) = (state_at(&a, q, level), state_at(&b, q, level));
                    match op {
                        CsgOp::Add => x | y,
                        CsgOp::Subtract => x & !y,
                        CsgOp::Intersect => x & y,
                    }
                };
                for j in 0..=n {
                    let bit = |l: &WorkLine| (l.states >> j) & 1 == 1;
                    let expect = match op {
                        CsgOp::Add => bit(&a) | bit(&b),
                        CsgOp::Subtract => bit(&a) & !bit(&b),
                        CsgOp::Intersect => bit(&a) & bit(&b),
                    };
                    assert_eq!(bit(&out), expect, "node states are the CSG of node states");
                }
                let mut c = out.changes(n);
                while c != 0 {
                    let e = c.trailing_zeros() as usize;
                    c &= c - 1;
                    // The continuous result switches at most twice in the cell; where it switches
                    // once, the stored crossing must be exactly there.
                    let lo = e as u32 * s;
                    let switches: Vec<u32> = (lo + 1..lo + s).filter(|&q| f(q) != f(q - 1)).map(|q| q - 1).collect();
                    if switches.len() == 1 {
                        assert_eq!(out.pos[e] as u32, switches[0], "{op:?} cell {e}");
                    }
                }
            }
        }
    }
}
