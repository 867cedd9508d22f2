//! CSG edits: a brush added to, subtracted from or intersected with a volume, chunk by chunk and
//! line by line (the paper's Algorithm 1, applied per cell because each cell holds at most one
//! crossing), with the set of changed chunks and an exact undo record.
//!
//! The folder's files: the edit's types and the per-volume driver (here: which chunks, in
//! parallel, the report and the undo record), the span tables sampled once per edit and the
//! chunk edit that reads them (`table.rs`), and one chunk's lines rewritten from a brush
//! sampled line by line (`line.rs`).

use glam::{DVec3, I64Vec3, IVec3};
use rayon::prelude::*;
use thiserror::Error;

use crate::axis::Axis;
use crate::axis::compose;
use crate::brush::{Aabb, Brush, SNAP_DISTANCE, Span};
use crate::chunk::{Built, Chunk, ChunkBuilder, ChunkView, LAST, LineRef, WorkLine, line_states, node_mask};
use crate::coords::{CHUNK_CELLS, ChunkBox, ChunkKey, Level, edge_of, quantize_into_edge};
use crate::material::{MaterialRule, RowChange, note_row};
use crate::normal::{flip_normal, pack_normal, unpack_normal};
use crate::sample::{LineAt, LineSampler, pack_oriented};
use crate::volume::Volume;

mod line;
mod table;
#[cfg(test)]
mod tests;

use line::*;
use table::*;

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
        let seen: std::collections::HashSet<ChunkKey> = self.undo.previous.iter().map(|(k, _)| *k).collect();
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
        if let Some(later_masks) = later.undo.masks {
            let masks = self.undo.masks.get_or_insert_with(Default::default);
            let seen: std::collections::HashSet<ChunkKey> = masks.keys().collect();
            for (key, m) in later_masks.chunks {
                if !seen.contains(&key) {
                    masks.chunks.push((key, m));
                }
            }
            if masks.outside.is_none() {
                masks.outside = later_masks.outside;
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
///
/// Records serialise (a collaboration server sends the record that undoes an operation to
/// every client); a record is restored as it is, unchecked, so only records from a trusted
/// source (the room's server, this process) may be restored.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct UndoRecord {
    pub(crate) previous: Vec<(ChunkKey, Option<Chunk>)>,
    /// Previous materials of the chunks whose materials changed.
    pub(crate) materials: crate::material::MaterialUndo,
    /// What the mask was where a mask edit changed it.
    /// (Boxed: most records have none, and records travel in `Result`s.)
    pub(crate) masks: Option<Box<crate::mask::MaskUndo>>,
}

impl UndoRecord {
    /// Whether restoring the record changes the mask's weight outside its stored chunks: the
    /// shading of every chunk then changes (see [`UndoRecord::keys`] for the others).
    pub fn reshades_everything(&self) -> bool {
        self.masks.as_ref().is_some_and(|m| m.outside.is_some())
    }

    /// Chunks the record restores (a shared room's undo compares them with later edits).
    pub fn keys(&self) -> impl Iterator<Item = ChunkKey> + '_ {
        let only_materials =
            self.materials.iter().map(|(k, _)| *k).filter(|k| !self.previous.iter().any(|(p, _)| p == k));
        let only_masks = self
            .masks
            .iter()
            .flat_map(|m| m.keys())
            .filter(|k| !self.previous.iter().any(|(p, _)| p == k) && !self.materials.iter().any(|(m, _)| m == k));
        self.previous.iter().map(|(k, _)| *k).chain(only_materials).chain(only_masks)
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
            + self.masks.as_ref().map_or(0, |m| std::mem::size_of::<crate::mask::MaskUndo>() + m.heap_bytes())
    }

    /// Whether the record restores nothing.
    pub fn is_empty(&self) -> bool {
        self.previous.is_empty() && self.materials.is_empty() && self.masks.as_ref().is_none_or(|m| m.is_empty())
    }
}

/// Per-thread scratch space for chunk edits.
#[derive(Default)]
struct Scratch {
    builder: ChunkBuilder,
    /// A reconciled brush's node states from its x lines (see `line::NodeStates`).
    states: line::NodeStates,
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
    tables: [Option<SpanTable>; crate::coords::LEVEL_COUNT],
    /// Whether chunks note the x lines whose node states they change (for the materials).
    rows: bool,
    /// For a brush cut by the mask: the brush before the cut, when it is a distance field, and
    /// the mask (see `Volume::apply_masked`).
    plain: Option<(&'a dyn Brush, &'a crate::mask::MaskSampler)>,
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

    /// Applies one CSG edit. Nodes the mask holds keep their states, and edges between two
    /// of them their crossings (see [`crate::mask`]).
    pub fn apply(&mut self, op: CsgOp, brush: &dyn Brush, settings: &EditSettings) -> Result<EditReport, EditError> {
        let bounds = brush.bounds();
        if !bounds.is_valid() {
            return Err(EditError::BadBounds);
        }
        if self.mask.is_clear() {
            return self.apply_brush(op, brush, settings);
        }
        // (A brush out of range or too large is refused before the mask is read for it.)
        chunk_range(&bounds.expand(SNAP_DISTANCE), settings.max_chunks)?;
        // An intersection empties whatever lies outside the brush: the held part anywhere must
        // be in reach.
        let reach = match (op, self.chunk_bounds()) {
            (CsgOp::Intersect, Some(all)) => Aabb::new(bounds.min.min(all.min), bounds.max.max(all.max)),
            _ => bounds,
        };
        let margin = DVec3::splat(1.0);
        let sampler = match self.mask.sampler(reach.min - margin, reach.max + margin) {
            Some(s) if s.any_held() => s,
            _ => return self.apply_brush(op, brush, settings),
        };
        let masked =
            crate::brush::Masked { inner: brush, mask: &sampler, widen: op == CsgOp::Intersect, bounds: reach };
        self.apply_masked(op, &masked, settings, Some((brush, &sampler)))
    }

    /// The box of every stored chunk (grid units), if any.
    fn chunk_bounds(&self) -> Option<Aabb> {
        let keys = self.chunks.keys();
        let (lo, hi) = keys.fold(None, |acc: Option<(IVec3, IVec3)>, k| match acc {
            None => Some((k.0, k.0)),
            Some((lo, hi)) => Some((lo.min(k.0), hi.max(k.0))),
        })?;
        let c = CHUNK_CELLS as f64;
        Some(Aabb::new(lo.as_dvec3() * c, (hi + IVec3::ONE).as_dvec3() * c))
    }

    /// [`Volume::apply`] with the brush as it is.
    fn apply_brush(&mut self, op: CsgOp, brush: &dyn Brush, settings: &EditSettings) -> Result<EditReport, EditError> {
        self.apply_masked(op, brush, settings, None)
    }

    /// [`Volume::apply_brush`]; for a brush cut by the mask, `plain` is the brush before the
    /// cut and the mask: a chunk whose nodes are all free is decided as the plain brush
    /// decides it where that brush is a distance field (far chunks cost one value).
    fn apply_masked(
        &mut self,
        op: CsgOp,
        brush: &dyn Brush,
        settings: &EditSettings,
        plain: Option<(&dyn Brush, &crate::mask::MaskSampler)>,
    ) -> Result<EditReport, EditError> {
        let bounds = brush.bounds();
        if !bounds.is_valid() {
            return Err(EditError::BadBounds);
        }
        let bounds = bounds.expand(SNAP_DISTANCE);
        let (cmin, cmax) = chunk_range(&bounds, settings.max_chunks)?;
        let keys: Vec<ChunkKey> = match op {
            CsgOp::Add => ChunkBox::new(cmin, cmax).keys().collect(),
            CsgOp::Subtract => {
                let reach = ChunkBox::new(cmin, cmax);
                if reach.len() <= self.chunks.len() as u64 {
                    reach.keys().filter(|k| self.chunks.contains_key(k)).collect()
                } else {
                    self.chunks.keys().copied().filter(|k| reach.contains(*k)).collect()
                }
            }
            CsgOp::Intersect => self.chunks.keys().copied().collect(),
        };
        // One span table per level among the chunks edited (mixed levels are rare: most edits
        // build one). A line shared by chunks of two levels is found the same way in both.
        let mut levels = [false; crate::coords::LEVEL_COUNT];
        levels[self.level.index()] = true;
        if !self.single_level() {
            for k in &keys {
                if let Some(l) = self.stored_level(*k) {
                    levels[l.index()] = true;
                }
            }
        }
        let tables = std::array::from_fn(|k| {
            let level = Level::ALL[k];
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
            plain: plain.filter(|(b, _)| b.field_is_distance()),
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
            if op == CsgOp::Intersect && !ChunkBox::new(cmin, cmax).contains(key) {
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
            masks: Default::default(),
        };
        if let Some(masks) = record.masks {
            redo.masks = Some(Box::new(self.mask.restore(*masks)));
        }
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
