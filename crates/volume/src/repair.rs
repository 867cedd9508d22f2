//! Repairing a volume whose lists break the invariants (a file written by a buggy build, a
//! damaged chunk dropped by a loader): the volume is rebuilt from its own lists through the
//! ordinary edit path, with node states taken from the x lines and the y and z lines repaired
//! to match, so the result satisfies every invariant by construction.
//!
//! The rebuilt volume keeps every x line's node states and every crossing position that still
//! lies in a cell whose nodes differ; crossings on y and z lines that contradicted the x lines
//! are moved to the middle of their cell (or dropped), exactly as an edit by a brush whose lines
//! disagree is repaired.
//!
//! The rebuild reads lines on the volume's grid, so chunks stored at another level (a layer
//! whose chunks were raised or lowered) are brought to the volume's level first
//! ([`Volume::set_chunk_level`]) and back to their own level after: a coarser chunk comes back
//! bit for bit where the rebuild left it as it was (raising then lowering is exact); a finer one
//! keeps the shape of its lines at the volume's level, refined again, and its materials follow
//! its nodes as a level change moves them.

use glam::{DVec3, I64Vec3, IVec3};

use crate::axis::Axis;
use crate::brush::{Aabb, Brush, Span, unit_axis};
use crate::chunk::{Chunk, ChunkView};
use crate::coords::{CHUNK_CELLS, ChunkKey, local_pos_to_grid};
use crate::edit::{CsgOp, EditError, EditReport, EditSettings};
use crate::normal::unpack_normal;
use crate::volume::Volume;

/// What [`Volume::repair`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RepairReport {
    /// The first broken invariant found, if any (nothing was changed when `None`).
    pub problem: Option<String>,
    /// Chunks stored at a level other than the volume's, brought to the volume's level for the
    /// rebuild (whose lines are read on the volume's grid) and back to their own level after it.
    pub relevelled_chunks: usize,
    /// Of those, chunks that could not be brought to the volume's level and were dropped (none
    /// is expected: every chunk of lists can be raised and lowered).
    pub dropped_chunks: usize,
    /// Node states on y and z lines that were moved to agree with the x lines.
    pub repaired_nodes: u64,
    /// Chunks stored before the repair.
    pub chunks_before: usize,
    /// Chunks stored after the repair.
    pub chunks_after: usize,
}

impl RepairReport {
    /// Whether the volume was changed.
    pub fn changed(&self) -> bool {
        self.problem.is_some()
    }
}

/// Chunks per side of the regions a repair rebuilds one at a time: a line of a region walks at
/// most this many chunks, and a region's span table (3 · (16 · 16)² lines) stays far under the
/// table's limit, so each line's spans are computed once.
const REGION_CHUNKS: i32 = 16;

/// The lists of a volume as a brush, over a box of chunks: a line's spans are read off the
/// stored lines along its axis, its node states off the x lines.
struct ListsBrush<'a> {
    volume: &'a Volume,
    /// Chunk keys `lo..=hi` on each axis.
    lo: IVec3,
    hi: IVec3,
}

impl ListsBrush<'_> {
    fn node_state(&self, p_grid: DVec3) -> bool {
        let sp = self.volume.level.spacing();
        let node = (p_grid / sp).round();
        if !(node.abs().max_element() < 1e15) {
            return false;
        }
        let node = node.as_i64vec3();
        let n = self.volume.level.cells() as i64;
        let key = node.div_euclid(I64Vec3::splat(n));
        if key.cmplt(self.lo.as_i64vec3()).any() || key.cmpgt(self.hi.as_i64vec3()).any() {
            return false;
        }
        self.volume.node_inside(node)
    }
}

/// Turns a line's state changes into spans.
struct SpanWriter<'a> {
    inside: bool,
    open: f64,
    open_normal: DVec3,
    out: &'a mut Vec<Span>,
}

impl SpanWriter<'_> {
    fn toggle(&mut self, t: f64, normal: DVec3) {
        if self.inside {
            if t > self.open {
                self.out.push(Span { enter: self.open, exit: t, enter_normal: self.open_normal, exit_normal: normal });
            }
        } else {
            self.open = t;
            self.open_normal = normal;
        }
        self.inside = !self.inside;
    }
}

impl Brush for ListsBrush<'_> {
    fn bounds(&self) -> Aabb {
        let c = CHUNK_CELLS as f64;
        Aabb::new(self.lo.as_dvec3() * c, (self.hi.as_dvec3() + DVec3::ONE) * c)
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        if self.node_state(origin + p) { -1.0 } else { 1.0 }
    }

    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        self.node_state(origin + p)
    }

    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        out.clear();
        let Some(a) = unit_axis(dir) else { return false };
        let axis = Axis::from_index(a);
        let (ua, va) = axis.across();
        let level = self.volume.level;
        let (n, sp) = (level.cells() as i64, level.spacing());
        let w = origin + start;
        let node_u = (w[ua.index()] / sp).round() as i64;
        let node_v = (w[va.index()] / sp).round() as i64;
        let (cu, cv) = (node_u.div_euclid(n), node_v.div_euclid(n));
        let in_box = |k: i64, ax: Axis| k >= self.lo[ax.index()] as i64 && k <= self.hi[ax.index()] as i64;
        if !(in_box(cu, ua) && in_box(cv, va)) {
            return true;
        }
        let (lu, lv) = ((node_u - cu * n) as usize, (node_v - cv * n) as usize);
        let mut w_spans = SpanWriter { inside: false, open: 0.0, open_normal: -dir, out };
        let c = CHUNK_CELLS as f64;
        for k in self.lo[a]..=self.hi[a] {
            let key = ChunkKey(IVec3::from_array(crate::axis::compose(axis, k, cu as i32, cv as i32)));
            let chunk_t = k as f64 * c - w[a];
            let line = match self.volume.view(key) {
                ChunkView::Uniform(s) => crate::chunk::LineRef::uniform(s),
                ChunkView::Lists(l) if l.level() == level => l.line(axis, lu, lv),
                ChunkView::Lists(_) => crate::chunk::LineRef::uniform(false),
            };
            if line.start_inside != w_spans.inside {
                // The line jumps at the chunk border: the change sits on the border node, whose
                // state the predicate then decides.
                let normal = if w_spans.inside { dir } else { -dir };
                w_spans.toggle(chunk_t, normal);
            }
            for (q, &normal) in line.positions().zip(line.normals) {
                w_spans.toggle(chunk_t + local_pos_to_grid(q), unpack_normal(normal));
            }
        }
        if w_spans.inside {
            let end = (self.hi[a] as f64 + 1.0) * c - w[a];
            w_spans.toggle(end, dir);
        }
        true
    }

    fn lines_agree(&self) -> bool {
        false
    }
}

impl Volume {
    /// The regions of [`REGION_CHUNKS`]³ chunks that hold a stored chunk, each with the box of
    /// its stored chunks (a sparse volume far from the origin costs its chunks, not the box
    /// around them).
    fn regions(&self) -> Vec<(IVec3, IVec3)> {
        let mut regions: std::collections::BTreeMap<[i32; 3], (IVec3, IVec3)> = Default::default();
        for k in self.chunks.keys() {
            let r = regions.entry(k.0.div_euclid(IVec3::splat(REGION_CHUNKS)).to_array()).or_insert((k.0, k.0));
            *r = (r.0.min(k.0), r.1.max(k.0));
        }
        regions.into_values().collect()
    }

    /// Adds the solid of `other` (at the same level) shifted by `offset` whole cells: how layers
    /// are merged. Region by region, as a repair rebuilds; one report for all of it (its undo
    /// restores the volume as it was). A level mismatch, an `other` whose chunks are stored at
    /// more than one level ([`EditError::MixedLevels`]) or a failed edit changes nothing.
    pub fn merge_from(
        &mut self,
        other: &Volume,
        offset: IVec3,
        settings: &EditSettings,
    ) -> Result<EditReport, EditError> {
        if other.level != self.level {
            return Err(EditError::LevelMismatch);
        }
        // Its lists are read as a brush at its level: chunks stored at other levels would read as
        // empty and be lost. (This volume may mix levels: an edit samples every chunk at its own.)
        if !other.single_level() {
            return Err(EditError::MixedLevels);
        }
        let shift = offset.as_dvec3();
        let mut report: Option<EditReport> = None;
        for (lo, hi) in other.regions() {
            let inner = ListsBrush { volume: other, lo, hi };
            let brush = crate::brush::Transformed::new(inner, glam::DQuat::IDENTITY, shift, 1.0)
                .map_err(|_| EditError::BadBounds)?;
            match self.apply(CsgOp::Add, &brush, settings) {
                Ok(edit) => {
                    report = Some(match report {
                        None => edit,
                        Some(r) => r.then(edit),
                    })
                }
                Err(e) => {
                    if let Some(r) = report {
                        self.restore(r.undo);
                    }
                    return Err(e);
                }
            }
        }
        let mut report = report.unwrap_or(EditReport {
            changed: Vec::new(),
            undo: Default::default(),
            repaired_nodes: 0,
            reach: None,
        });
        let node_shift = self.level.node_of_grid(offset.as_i64vec3());
        self.carry_materials(other, node_shift, &report.undo.previous, &mut report.undo.materials);
        Ok(report)
    }

    /// Rebuilds the volume if it breaks an invariant (see the module docs); returns what was
    /// done. A volume that passes [`Volume::check_invariants`] is left exactly as it is.
    pub fn repair(&mut self) -> RepairReport {
        let mut report = RepairReport { chunks_before: self.chunk_count(), ..Default::default() };
        let problem = match self.check_invariants() {
            Ok(()) => {
                report.chunks_after = report.chunks_before;
                return report;
            }
            Err(v) => v.to_string(),
        };
        report.problem = Some(problem);
        // The rebuild re-adds the solid and may relevel chunks: the mask, which would cut the
        // one and forbid the other, is set aside and put back after.
        let mask = std::mem::take(&mut self.mask);
        self.repair_lists(&mut report);
        self.mask = mask;
        report
    }

    /// [`Volume::repair`]'s rebuild, without a mask.
    fn repair_lists(&mut self, report: &mut RepairReport) {
        let level = self.level;
        let mut wrong_level: Vec<(ChunkKey, crate::coords::Level)> = self
            .chunks
            .iter()
            .filter_map(|(k, c)| match c {
                Chunk::Lists(l) if l.level() != level => Some((*k, l.level())),
                _ => None,
            })
            .collect();
        wrong_level.sort_by_key(|(k, _)| k.0.to_array());
        for &(k, _) in &wrong_level {
            let _ = self.set_chunk_level(k, level);
            if self.stored_level(k).is_some_and(|l| l != level) {
                self.take_chunk(k);
                report.dropped_chunks += 1;
            }
        }
        report.relevelled_chunks = wrong_level.len() - report.dropped_chunks;
        let old = std::mem::replace(
            self,
            Volume {
                chunks: Default::default(),
                materials: Default::default(),
                level,
                cell_size: self.cell_size,
                mask: Default::default(),
            },
        );
        // The regions that hold a stored chunk, each with the box of its stored chunks (a sparse
        // volume far from the origin costs its chunks, not the box around them).
        let settings = EditSettings { max_chunks: u64::MAX, ..Default::default() };
        for (lo, hi) in old.regions() {
            let brush = ListsBrush { volume: &old, lo, hi };
            if let Ok(edit) = self.apply(CsgOp::Add, &brush, &settings) {
                report.repaired_nodes += edit.repaired_nodes;
            }
        }
        // Materials follow their nodes (the rebuild changes no node's state on the x lines).
        let previous: Vec<(ChunkKey, Option<Chunk>)> = self.chunks.keys().map(|k| (*k, None)).collect();
        let mut undo = Vec::new();
        self.carry_materials(&old, glam::I64Vec3::ZERO, &previous, &mut undo);
        // Back to their own levels, where the rebuild left lists; kept at the volume's level if
        // that broke an invariant (it does not: level changes keep them).
        let mut back = crate::edit::EditReport::default();
        for &(k, own) in &wrong_level {
            if self.stored_level(k).is_some() {
                back = back.then(self.set_chunk_level(k, own));
            }
        }
        if self.check_invariants().is_err() {
            self.restore(back.undo);
        }
        report.chunks_after = self.chunk_count();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brush::Sphere;

    /// A brush that lies: its x lines are one sphere's and its y and z lines another's, and it
    /// claims they agree, so an edit stores chunks whose axes disagree.
    struct Liar(Sphere, Sphere);

    impl Brush for Liar {
        fn bounds(&self) -> Aabb {
            let (a, b) = (self.0.bounds(), self.1.bounds());
            Aabb::new(a.min.min(b.min), a.max.max(b.max))
        }
        fn field(&self, origin: DVec3, p: DVec3) -> f64 {
            self.0.field(origin, p)
        }
        fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
            if dir == DVec3::X { self.0.spans(origin, start, dir, out) } else { self.1.spans(origin, start, dir, out) }
        }
    }

    fn sphere(c: f64, r: f64) -> Sphere {
        Sphere::new(DVec3::splat(c), r).unwrap()
    }

    #[test]
    fn merging_a_shifted_volume_is_the_union_of_the_two() {
        let mut a = Volume::new();
        a.add(&sphere(20.0, 9.0)).unwrap();
        let mut b = Volume::new();
        b.add(&Sphere::new(DVec3::new(12.3, 21.0, 19.6), 6.5).unwrap()).unwrap();
        b.add(&Sphere::new(DVec3::new(40.0, 5.0, 33.0), 4.0).unwrap()).unwrap();
        let before = a.clone();
        let report = a.merge_from(&b, IVec3::new(3, -2, 17), &EditSettings::default()).unwrap();
        a.check_invariants().unwrap();
        for z in 0..60i64 {
            for y in -10..40i64 {
                for x in 0..60i64 {
                    let n = I64Vec3::new(x, y, z);
                    let want = before.node_inside(n) || b.node_inside(n - I64Vec3::new(3, -2, 17));
                    assert_eq!(a.node_inside(n), want, "node {n}");
                }
            }
        }
        a.restore(report.undo);
        assert_eq!(a, before);
    }

    #[test]
    fn a_volume_whose_axes_disagree_is_rebuilt_consistent_with_its_x_lines() {
        for masked in [false, true] {
            repaired_consistent_with_its_x_lines(masked);
        }
    }

    /// The repair of a volume whose axes disagree, with a mask holding everything or without:
    /// the mask does not stop the rebuild (it once cut the rebuilt solid away) and is kept.
    fn repaired_consistent_with_its_x_lines(masked: bool) {
        let mut v = Volume::new();
        v.add(&sphere(20.0, 9.0)).unwrap();
        v.add(&Liar(sphere(14.0, 6.3), sphere(14.5, 6.0))).unwrap();
        assert!(v.check_invariants().is_err(), "the liar broke the volume");
        if masked {
            v.invert_mask();
        }
        let mask = v.mask().clone();
        let before = v.clone();
        let report = v.repair();
        assert!(report.changed());
        assert!(report.repaired_nodes > 0);
        v.check_invariants().expect("repaired");
        for z in -2..40 {
            for y in -2..40 {
                for x in -2..40 {
                    let node = I64Vec3::new(x, y, z);
                    assert_eq!(v.node_inside(node), before.node_inside(node), "node {node} keeps its x-line state");
                }
            }
        }
        assert!(*v.mask() == mask, "the mask is kept");
        // A consistent volume is left alone.
        let again = v.clone();
        assert_eq!(
            v.repair(),
            RepairReport { chunks_before: v.chunk_count(), chunks_after: v.chunk_count(), ..Default::default() }
        );
        assert_eq!(v, again);
    }

    #[test]
    fn chunks_that_do_not_continue_their_neighbours_are_rebuilt() {
        // A chunk of another solid dropped into a volume: its lines end and start unlike its
        // neighbours'.
        let mut a = Volume::new();
        a.add(&sphere(16.0, 12.0)).unwrap();
        let mut b = Volume::new();
        b.add(&sphere(20.0, 7.0)).unwrap();
        let key = ChunkKey::new(1, 1, 1);
        let foreign = b.chunks.get(&key).cloned();
        match foreign {
            Some(c) => a.chunks.insert(key, c),
            None => a.chunks.remove(&key),
        };
        a.chunks.remove(&ChunkKey::new(0, 0, 0));
        assert!(a.check_invariants().is_err());
        let report = a.repair();
        assert!(report.changed());
        a.check_invariants().expect("repaired");
        // A solid chunk with nothing around it closes at its borders.
        let mut s = Volume::new();
        s.chunks.insert(ChunkKey::new(5, -3, 7), Chunk::Solid);
        assert!(s.check_invariants().is_err());
        s.repair();
        s.check_invariants().expect("repaired");
        assert!(s.node_inside(I64Vec3::new(88, -40, 120)));
    }
}
