//! Writing a region back as an ordinary edit.

use glam::{DVec3, I64Vec3, IVec3};
use rayon::prelude::*;

use super::{Region, RegionError};
use crate::axis::{Axis, compose};
use crate::chunk::{Built, ChunkBuilder, ChunkView, WorkLine};
use crate::coords::{ChunkKey, Level, quantize_into_edge};
use crate::edit::{EditReport, UndoRecord};
use crate::material::{RowChange, note_row};
use crate::normal::pack_normal;
use crate::volume::Volume;

/// Writes of at least this many chunks run in parallel where there are several threads.
const PARALLEL_CHUNKS: usize = 4;

/// The field a write takes from a region: the operator's where it owns the node (a positive
/// weight, not on the region's outer layer), else the field as read.
struct Written<'a> {
    region: &'a Region,
    owned: Vec<bool>,
}

impl<'a> Written<'a> {
    /// The owned nodes of `region` and the box (node coordinates, inclusive) that holds them, if
    /// any.
    fn new(region: &'a Region) -> (Self, Option<(I64Vec3, I64Vec3)>) {
        let d = region.dims;
        let mut owned = vec![false; region.phi.len()];
        let (mut lo, mut hi) = (I64Vec3::MAX, I64Vec3::MIN);
        for z in 1..d[2].saturating_sub(1) {
            for y in 1..d[1].saturating_sub(1) {
                let row = d[0] * (y + d[1] * z);
                for x in 1..d[0].saturating_sub(1) {
                    if region.weight[row + x] > 0.0 {
                        owned[row + x] = true;
                        let g = region.origin + I64Vec3::new(x as i64, y as i64, z as i64);
                        lo = lo.min(g);
                        hi = hi.max(g);
                    }
                }
            }
        }
        (Written { region, owned }, (lo.x <= hi.x).then_some((lo, hi)))
    }

    #[inline]
    fn effective(&self, i: usize) -> f32 {
        if self.owned[i] { self.region.phi[i] } else { self.region.original[i] }
    }

    /// Whether the write leaves node `i` as read.
    #[inline]
    fn untouched(&self, i: usize) -> bool {
        !self.owned[i] || self.region.phi[i] == self.region.original[i]
    }

    /// The gradient of the effective field at node `i` (central differences, one-sided at the
    /// region's faces).
    fn gradient(&self, i: usize) -> DVec3 {
        let d = self.region.dims;
        let c = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
        let mut g = DVec3::ZERO;
        for a in 0..3 {
            let step = [1, d[0], d[0] * d[1]][a];
            let (lo, hi) = (if c[a] > 0 { i - step } else { i }, if c[a] + 1 < d[a] { i + step } else { i });
            let span = ((hi - lo) / step) as f64;
            if span > 0.0 {
                g[a] = (self.effective(hi) - self.effective(lo)) as f64 / span;
            }
        }
        g
    }
}

impl Volume {
    /// Writes `region` back (see the module docs): returns the changed chunks and the undo
    /// record. Nodes the operator does not own, and crossings between them, stay bit for bit.
    pub fn write_region(&mut self, region: &Region) -> Result<EditReport, RegionError> {
        self.write_region_with(region, None)
    }

    /// [`Volume::write_region`], where the nodes made solid get material `fill` (`None`: the
    /// material of a face neighbour that was solid, else of the run they continue).
    pub fn write_region_with(
        &mut self,
        region: &Region,
        fill: Option<crate::MaterialId>,
    ) -> Result<EditReport, RegionError> {
        let count = region.dims[0] * region.dims[1] * region.dims[2];
        if region.phi.len() != count || region.weight.len() != count || region.original.len() != count {
            return Err(RegionError::Mismatch);
        }
        let mut report =
            EditReport { changed: Vec::new(), undo: UndoRecord::default(), repaired_nodes: 0, reach: None };
        let sp = region.level.spacing();
        let far = region.origin + I64Vec3::new(region.dims[0] as i64, region.dims[1] as i64, region.dims[2] as i64);
        let masked;
        let region = match self.mask_sampler(region.origin.as_dvec3() * sp, far.as_dvec3() * sp) {
            Some(mask) => {
                masked = region.masked(&mask);
                &masked
            }
            None => region,
        };
        let (written, owned_box) = Written::new(region);
        let Some((lo, hi)) = owned_box else { return Ok(report) };
        let level = region.level;
        // Only owned nodes change, and the crossings of edges with an owned end: one cell of the
        // coarsest level around the owned box holds both ends of those edges in every chunk.
        report.reach =
            Some(crate::edit::Reach { min: lo.as_dvec3() * sp - DVec3::ONE, max: hi.as_dvec3() * sp + DVec3::ONE });
        let n = level.cells() as i64;
        // Chunk c holds nodes c n ..= c n + n along each line, so a node on a chunk plane is also
        // the last node of the chunk below.
        let (klo, khi) = ((lo - I64Vec3::ONE).div_euclid(I64Vec3::splat(n)), hi.div_euclid(I64Vec3::splat(n)));
        let mut jobs = Vec::new();
        for kz in klo.z..=khi.z {
            for ky in klo.y..=khi.y {
                for kx in klo.x..=khi.x {
                    let key = ChunkKey(IVec3::new(kx as i32, ky as i32, kz as i32));
                    // A chunk is written at its own level (a new one at the volume's), its nodes
                    // every `stride` nodes of the region.
                    let chunk_level = match self.view(key) {
                        ChunkView::Lists(l) => l.level(),
                        ChunkView::Uniform(_) => self.level.min(level),
                    };
                    if chunk_level > level {
                        return Err(RegionError::Mismatch);
                    }
                    let stride = 1i64 << (level.get() - chunk_level.get());
                    let base = I64Vec3::new(kx, ky, kz) * n;
                    jobs.push((key, Stride { base, level: chunk_level, stride }));
                }
            }
        }
        // Chunks are rewritten independently; on several cores, a dab's chunks in parallel
        // (the results, in the same order, are the same whatever the thread count).
        // The x lines whose node states change are noted for the materials where there are any
        // to keep or give.
        let note = self.has_materials() || fill.is_some_and(|f| f != 0);
        let this = &*self;
        type Scratch = (ChunkBuilder, Vec<RowChange>);
        let rewrite = |(b, rows): &mut Scratch, &(key, at): &(ChunkKey, Stride)| {
            rows.clear();
            let built = rewrite_chunk(this.view(key), at, &written, (lo, hi), b, note.then_some(&mut *rows))?;
            Some((key, built, note.then(|| rows.clone())))
        };
        let results: Vec<(ChunkKey, Built, Option<Vec<RowChange>>)> =
            if jobs.len() >= PARALLEL_CHUNKS && rayon::current_num_threads() > 1 {
                jobs.par_iter().map_init(Scratch::default, rewrite).flatten().collect()
            } else {
                let mut scratch = Scratch::default();
                jobs.iter().filter_map(|job| rewrite(&mut scratch, job)).collect()
            };
        let mut rows = Vec::with_capacity(results.len());
        for (key, built, changes) in results {
            let previous = match built.into_chunk() {
                Some(c) => self.chunks.insert(key, c),
                None => self.chunks.remove(&key),
            };
            report.changed.push(key);
            report.undo.previous.push((key, previous));
            rows.push(changes);
        }
        if self.settle_uniform(&mut report.changed, &mut report.undo.previous) {
            // Settled chunks were rewritten after their lines: their materials are found whole.
            rows.clear();
        }
        let rule = fill.map_or(crate::material::MaterialRule::Nearest, crate::material::MaterialRule::Fill);
        report.undo.materials = self.update_materials(&report.undo.previous, rule, &rows);
        report.changed.sort_by_key(|k| k.0.to_array());
        Ok(report)
    }
}

/// Where a chunk's nodes sit among a region's: its node 0 at region node `base`, one node of the
/// chunk's `level` every `stride` region nodes (1 where the levels agree).
#[derive(Clone, Copy, Debug)]
struct Stride {
    base: I64Vec3,
    level: Level,
    stride: i64,
}

/// The chunk at `at` with the region's owned nodes (box `owned`) written in, or `None` if
/// nothing in it changes; the x lines whose node states change are noted in `rows`, if given.
fn rewrite_chunk(
    old: ChunkView<'_>,
    at: Stride,
    written: &Written<'_>,
    owned: (I64Vec3, I64Vec3),
    b: &mut ChunkBuilder,
    mut rows: Option<&mut Vec<RowChange>>,
) -> Option<Built> {
    let Stride { base, level, stride } = at;
    let region = written.region;
    let n = level.cells();
    let sp = level.spacing();
    b.begin(level);
    let mut changed = false;
    let (mut old_line, mut new_line) = (WorkLine::EMPTY, WorkLine::EMPTY);
    for axis in Axis::ALL {
        b.begin_axis(axis);
        let (ua, va) = axis.across();
        let a = axis.index();
        let mut cursor = old.cursor(axis, 0);
        let mut next = 0;
        for v in 0..n {
            for u in 0..n {
                let g0 = base + I64Vec3::from_array(compose(axis, 0, u as i64, v as i64)) * stride;
                // Lines that hold no owned node are copied as they are.
                let (gu, gv) = (g0[ua.index()], g0[va.index()]);
                if gu < owned.0[ua.index()]
                    || gu > owned.1[ua.index()]
                    || gv < owned.0[va.index()]
                    || gv > owned.1[va.index()]
                    || g0[a] + (n as i64) * stride < owned.0[a]
                    || g0[a] > owned.1[a]
                {
                    continue;
                }
                let index = u + n * v;
                b.copy_view(&mut cursor, index - next);
                next = index + 1;
                let line = cursor.next_line();
                old_line.load(line, level);
                new_line.states = old_line.states;
                // Per node of the line: its region index if the operator owns it. (The line
                // crosses the owned box, which lies inside the region: only its nodes along
                // the axis can fall outside.)
                let mut ids = [usize::MAX; crate::chunk::MAX_NODES];
                let local = g0 - region.origin;
                let d = region.dims;
                let steps = [1, d[0], d[0] * d[1]];
                let cross =
                    local[ua.index()] as usize * steps[ua.index()] + local[va.index()] as usize * steps[va.index()];
                let mut any = false;
                for (j, id) in ids.iter_mut().enumerate().take(n + 1) {
                    let t = local[a] + stride * j as i64;
                    if t >= 0 && (t as usize) < d[a] {
                        let i = cross + t as usize * steps[a];
                        *id = i;
                        if written.owned[i] {
                            any = true;
                            let inside = region.phi[i] <= 0.0;
                            if inside {
                                new_line.states |= 1 << j;
                            } else {
                                new_line.states &= !(1u128 << j);
                            }
                        }
                    }
                }
                if !any {
                    b.push_stored(line);
                    continue;
                }
                if let Some(rows) = rows.as_deref_mut() {
                    note_row(rows, axis, index, old_line.states, new_line.states, n);
                }
                let old_changes = old_line.changes(n);
                let mut c = new_line.changes(n);
                while c != 0 {
                    let e = c.trailing_zeros() as usize;
                    c &= c - 1;
                    let (i0, i1) = (ids[e], ids[e + 1]);
                    let untouched = |i: usize| i == usize::MAX || written.untouched(i);
                    if old_changes & (1 << e) != 0 && untouched(i0) && untouched(i1) {
                        new_line.pos[e] = old_line.pos[e];
                        new_line.nrm[e] = old_line.nrm[e];
                        continue;
                    }
                    // Both ends are in the region where the chunk has the region's level (an
                    // owned node is never on its outer layer); a coarser chunk's edge spans
                    // `stride` region nodes, so its far end can lie beyond: that end kept its
                    // state, and a distance of a coarse cell stands in for its field.
                    let value = |i: usize, j: usize| {
                        if i == usize::MAX {
                            let inside = (new_line.states >> j) & 1 == 1;
                            if inside { -(stride as f64) } else { stride as f64 }
                        } else {
                            written.effective(i) as f64
                        }
                    };
                    let (f0, f1) = (value(i0, e), value(i1, e + 1));
                    let t = if (f0 <= 0.0) != (f1 <= 0.0) && f0 != f1 { (f0 / (f0 - f1)).clamp(0.0, 1.0) } else { 0.5 };
                    let grad_at = |i: usize| if i == usize::MAX { DVec3::ZERO } else { written.gradient(i) };
                    let grad = grad_at(i0) * (1.0 - t) + grad_at(i1) * t;
                    let entering = (new_line.states >> (e + 1)) & 1 == 1;
                    let fallback = if entering { -axis.unit() } else { axis.unit() };
                    let mut normal = grad.normalize_or(fallback);
                    if normal[a] != 0.0 && (normal[a] > 0.0) == entering {
                        // A field whose gradient points inwards here: the line's own direction.
                        normal = fallback;
                    }
                    new_line.pos[e] = quantize_into_edge((e as f64 + t) * sp, e, level);
                    new_line.nrm[e] = pack_normal(normal);
                }
                changed |= b.push_edited(line, &old_line, &new_line, n);
            }
        }
        b.copy_view(&mut cursor, n * n - next);
    }
    changed.then(|| b.finish())
}
