//! CSG edits: a brush added to, subtracted from or intersected with a volume, chunk by chunk and
//! line by line (the paper's Algorithm 1, applied per cell because each cell holds at most one
//! crossing), with the set of changed chunks and an exact undo record.

use glam::{DVec3, I64Vec3, IVec3};
use rayon::prelude::*;
use thiserror::Error;

use crate::axis::Axis;
use crate::brush::{Aabb, Brush, SNAP_DISTANCE};
use crate::chunk::{Built, Chunk, ChunkBuilder, ChunkView, WorkLine, node_mask};
use crate::coords::{CHUNK_CELLS, ChunkKey, Level};
use crate::normal::{pack_normal, unpack_normal};
use crate::sample::LineSampler;
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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EditSettings {
    /// Edit chunks in parallel with rayon.
    pub parallel: bool,
    /// Refuse edits whose box spans more chunks than this (a brush a billion cells wide would
    /// otherwise run out of memory).
    pub max_chunks: u64,
}

impl Default for EditSettings {
    fn default() -> Self {
        EditSettings { parallel: true, max_chunks: 1 << 20 }
    }
}

/// Why an edit was refused. The volume is unchanged.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum EditError {
    /// The brush's bounds are NaN, infinite or inverted.
    #[error("the brush's bounds are not finite")]
    BadBounds,
    /// The brush covers more chunks than [`EditSettings::max_chunks`] or lies beyond the key range.
    #[error("the brush spans {chunks} chunks, more than the limit of {limit}")]
    TooLarge {
        /// Chunks the brush's box spans (saturating).
        chunks: u64,
        /// The limit.
        limit: u64,
    },
}

/// What an edit did.
#[derive(Debug, Clone)]
pub struct EditReport {
    /// Chunks whose data changed, sorted. Meshes of these chunks (and of the neighbours that
    /// read them as their apron) need rebuilding.
    pub changed: Vec<ChunkKey>,
    /// Restores the volume as it was before the edit.
    pub undo: UndoRecord,
    /// Node states of the brush that the volume repaired so that x, y and z lines agree (only
    /// for brushes whose [`Brush::lines_agree`] is false).
    pub repaired_nodes: u64,
}

/// The previous contents of every chunk an edit changed. [`Volume::restore`] puts them back bit
/// for bit and returns the record that redoes the edit.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UndoRecord {
    previous: Vec<(ChunkKey, Option<Chunk>)>,
}

impl UndoRecord {
    /// Chunks the record restores.
    pub fn keys(&self) -> impl Iterator<Item = ChunkKey> + '_ {
        self.previous.iter().map(|(k, _)| *k)
    }

    /// Heap bytes the record holds (for history memory budgets).
    pub fn heap_bytes(&self) -> usize {
        let entries = self.previous.capacity() * std::mem::size_of::<(ChunkKey, Option<Chunk>)>();
        entries
            + self
                .previous
                .iter()
                .map(|(_, c)| match c {
                    Some(Chunk::Lists(l)) => {
                        let (p, n, h) = l.heap_bytes();
                        p + n + h
                    }
                    _ => 0,
                })
                .sum::<usize>()
    }

    /// Whether the record restores nothing.
    pub fn is_empty(&self) -> bool {
        self.previous.is_empty()
    }
}

/// Per-thread scratch space for chunk edits.
#[derive(Default)]
struct Scratch {
    builder: ChunkBuilder,
    changed: Vec<(u8, u32, WorkLine)>,
    x_states: Vec<u128>,
}

struct EditCtx<'a> {
    brush: &'a dyn Brush,
    op: CsgOp,
    bounds: Aabb,
    reconcile: bool,
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
        let ctx = EditCtx { brush, op, bounds, reconcile: !brush.lines_agree() };
        let run = |scratch: &mut Scratch, key: ChunkKey| -> Option<(ChunkKey, Built, u64)> {
            let view = self.view(key);
            if op == CsgOp::Intersect && !in_range(key, cmin, cmax) {
                return Some((key, Built::Uniform(false), 0));
            }
            let level = self.level_of(key);
            edit_chunk(&ctx, key, view, level, scratch).map(|(b, r)| (key, b, r))
        };
        let mut results: Vec<(ChunkKey, Built, u64)> = if settings.parallel && keys.len() > 1 {
            keys.par_iter().map_init(Scratch::default, |s, &k| run(s, k)).flatten().collect()
        } else {
            let mut s = Scratch::default();
            keys.iter().filter_map(|&k| run(&mut s, k)).collect()
        };
        results.sort_by_key(|r| r.0);
        let mut report = EditReport { changed: Vec::with_capacity(results.len()), undo: UndoRecord::default(), repaired_nodes: 0 };
        report.undo.previous.reserve(results.len());
        for (key, built, repaired) in results {
            let previous = match built.into_chunk() {
                Some(c) => self.chunks.insert(key, c),
                None => self.chunks.remove(&key),
            };
            report.changed.push(key);
            report.undo.previous.push((key, previous));
            report.repaired_nodes += repaired;
        }
        Ok(report)
    }

    /// Puts back the chunks of `record` and returns the record that undoes this (a redo).
    pub fn restore(&mut self, record: UndoRecord) -> UndoRecord {
        let mut redo = UndoRecord { previous: Vec::with_capacity(record.previous.len()) };
        for (key, chunk) in record.previous {
            let now = match chunk {
                Some(c) => self.chunks.insert(key, c),
                None => self.chunks.remove(&key),
            };
            redo.previous.push((key, now));
        }
        redo
    }
}

/// Chunks whose lines can see a change: chunk `c` holds nodes `16c ..= 16c + 16` on each line.
fn chunk_range(bounds: &Aabb, limit: u64) -> Result<(IVec3, IVec3), EditError> {
    let c = CHUNK_CELLS as f64;
    let lo = (bounds.min / c).ceil() - DVec3::ONE;
    let hi = (bounds.max / c).floor();
    let ok = lo.cmpge(DVec3::splat(i32::MIN as f64)).all() && hi.cmple(DVec3::splat(i32::MAX as f64)).all();
    let span = (hi - lo + DVec3::ONE).max(DVec3::ZERO);
    let chunks = span.x * span.y * span.z;
    if !ok || chunks > limit as f64 {
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
/// repaired brush nodes.
fn edit_chunk(ctx: &EditCtx<'_>, key: ChunkKey, old: ChunkView<'_>, level: Level, s: &mut Scratch) -> Option<(Built, u64)> {
    let n = level.cells();
    let origin = key.origin_grid();
    let mut sampler = LineSampler::new(ctx.brush, ctx.op == CsgOp::Subtract);
    let mut repaired = 0u64;
    if ctx.reconcile {
        // Node states of the brush from the x lines, apron rows included: x_states[y + (n+1) z].
        s.x_states.clear();
        let mut line = WorkLine::EMPTY;
        for z in 0..=n {
            for y in 0..=n {
                sampler.sample(origin, level, Axis::X, y, z, &mut line);
                s.x_states.push(line.states);
            }
        }
    }
    s.changed.clear();
    let (mut old_line, mut brush_line, mut new_line) = (WorkLine::EMPTY, WorkLine::EMPTY, WorkLine::EMPTY);
    for axis in Axis::ALL {
        let (ua, va) = axis.across();
        let ranges = (across_range(&ctx.bounds, origin, ua, level), across_range(&ctx.bounds, origin, va, level));
        let ((u0, u1), (v0, v1)) = match (ctx.op, ranges) {
            (CsgOp::Intersect, _) => ((0, n - 1), (0, n - 1)),
            (_, (Some(ur), Some(vr))) => (ur, vr),
            _ => continue,
        };
        for v in v0..=v1 {
            let mut cursor = match old {
                ChunkView::Lists(l) => Some(l.cursor(axis, u0 + n * v)),
                ChunkView::Uniform(_) => None,
            };
            for u in u0..=u1 {
                let line = match (&mut cursor, old) {
                    (Some(c), _) => c.next_line(),
                    (None, view) => view.line(axis, u, v),
                };
                old_line.load(line, level);
                let inside_box = ranges.0.is_some_and(|(a, b)| (a..=b).contains(&u))
                    && ranges.1.is_some_and(|(a, b)| (a..=b).contains(&v));
                if inside_box {
                    sampler.sample(origin, level, axis, u, v, &mut brush_line);
                    if ctx.reconcile && axis != Axis::X {
                        repaired += reconcile_line(&s.x_states, axis, u, v, n, sampler.flip, &mut brush_line);
                    }
                } else {
                    brush_line.states = 0;
                }
                combine(&old_line, &brush_line, ctx.op, n, &mut new_line);
                if !new_line.same_as(&old_line, n) {
                    s.changed.push((axis as u8, (u + n * v) as u32, new_line));
                }
            }
        }
    }
    if s.changed.is_empty() {
        return None;
    }
    let b = &mut s.builder;
    b.begin(level);
    let mut next = s.changed.iter().peekable();
    for axis in Axis::ALL {
        b.begin_axis(axis);
        let mut index = 0;
        while let Some((_, i, line)) = next.next_if(|c| c.0 == axis as u8) {
            let i = *i as usize;
            b.copy_lines(old, axis, index, i - index);
            b.push_work(line);
            index = i + 1;
        }
        b.copy_lines(old, axis, index, n * n - index);
    }
    Some((b.finish(), repaired))
}

/// Forces a y or z brush line to the node states of the x lines; returns how many nodes moved.
fn reconcile_line(x_states: &[u128], axis: Axis, u: usize, v: usize, n: usize, flip: bool, line: &mut WorkLine) -> u64 {
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
    let level = Level::new((n / 16).trailing_zeros() as u8).expect("valid level");
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
            line.nrm[e] = pack_normal(-unpack_normal(line.nrm[e]));
        }
    }
    moved
}
