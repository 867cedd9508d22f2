//! Queries: inside tests, crossing statistics and ray casts.

use glam::{DVec3, I64Vec3, IVec3};

use crate::axis::Axis;
use crate::block::VoxelBlock;
use crate::chunk::{Chunk, ChunkLists, ChunkView};
use crate::coords::{CHUNK_CELLS, CHUNK_STEPS, ChunkKey, Level};
use crate::normal::unpack_normal;
use crate::volume::Volume;

/// Crossing counts over the whole volume.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CrossingStats {
    /// Crossings stored, all axes.
    pub total: u64,
    /// Crossings per axis (x, y, z).
    pub per_axis: [u64; 3],
    /// Chunks stored as lists.
    pub list_chunks: u64,
    /// Chunks stored as all solid.
    pub solid_chunks: u64,
    /// The longest chunk line (crossings on one line within one chunk).
    pub max_line: usize,
    /// `histogram[k]`: chunk lines with `k` crossings, over chunks stored as lists.
    pub histogram: Vec<u64>,
}

/// Where a ray first meets the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Ray parameter of the hit (distance when the direction is a unit vector).
    pub t: f64,
    /// The hit point (grid coordinates).
    pub point: DVec3,
    /// Outward surface normal at the hit.
    pub normal: DVec3,
}

impl Volume {
    /// Whether the node `node` (global, in the volume's level units) is inside.
    ///
    /// Exact for every node of the chunk holding it, whatever level that chunk is stored at. A
    /// chunk stored at a coarser level than the volume's has no lines between its own nodes: a
    /// node there is read exactly along x, on the x line of the chunk's nodes at or below it
    /// on y and z.
    pub fn node_inside(&self, node: I64Vec3) -> bool {
        let n = self.level.cells() as i64;
        let key = node.div_euclid(I64Vec3::splat(n));
        let Some(key) = key_of(key) else { return false };
        let local = node - key.0.as_i64vec3() * n;
        match self.view(key) {
            ChunkView::Uniform(s) => s,
            ChunkView::Lists(l) => {
                // A crossing in cell `e` lies before node `x` exactly when `e < x`, that is when
                // it lies before the node's position.
                let x_steps = local.x as u32 * self.level.steps_per_cell();
                x_line_state(l, self.level, local.y as usize, local.z as usize, |q| (q.0 as u32) < x_steps)
            }
        }
    }

    /// Whether the grid point `p_grid` is inside, read from the x line through the nearest row
    /// of nodes at the volume's level (exact along x, within half a cell across; in a chunk
    /// stored at a coarser level, the row of the chunk's nodes at or below that row, within one
    /// of the chunk's cells). Non-finite points are outside.
    pub fn is_inside(&self, p_grid: DVec3) -> bool {
        if !p_grid.is_finite() {
            return false;
        }
        let sp = self.level.spacing();
        let n = self.level.cells() as i64;
        let ny = (p_grid.y / sp).round();
        let nz = (p_grid.z / sp).round();
        let kx = (p_grid.x / CHUNK_CELLS as f64).floor();
        if [ny, nz, kx].iter().any(|v| v.abs() > 1e15) {
            return false;
        }
        let (ny, nz) = (ny as i64, nz as i64);
        let Some(key) = key_of(I64Vec3::new(kx as i64, ny.div_euclid(n), nz.div_euclid(n))) else { return false };
        match self.view(key) {
            ChunkView::Uniform(s) => s,
            ChunkView::Lists(l) => {
                let t = (p_grid.x - kx * CHUNK_CELLS as f64) * (CHUNK_STEPS as f64 / CHUNK_CELLS as f64);
                let (u, v) = (ny.rem_euclid(n) as usize, nz.rem_euclid(n) as usize);
                x_line_state(l, self.level, u, v, |q| (q.0 as f64) < t)
            }
        }
    }

    /// Crossing counts and the distribution of chunk-line lengths.
    pub fn crossing_stats(&self) -> CrossingStats {
        let mut s = CrossingStats::default();
        for chunk in self.chunks.values() {
            match chunk {
                Chunk::Solid => s.solid_chunks += 1,
                Chunk::Lists(l) => {
                    s.list_chunks += 1;
                    let n = l.level().cells();
                    for axis in Axis::ALL {
                        s.per_axis[axis.index()] += l.axis_crossing_count(axis) as u64;
                        let mut cursor = l.raw_cursor(axis, 0);
                        for _ in 0..n * n {
                            let k = cursor.next_raw().len();
                            if s.histogram.len() <= k {
                                s.histogram.resize(k + 1, 0);
                            }
                            s.histogram[k] += 1;
                            s.max_line = s.max_line.max(k);
                        }
                    }
                }
            }
        }
        s.total = s.per_axis.iter().sum();
        s
    }

    /// The first surface point along `origin + t · dir`, `0 ≤ t ≤ max_t` (grid coordinates). A
    /// ray that starts inside the solid hits at `t = 0`. Within a cell the surface is the plane
    /// fitted to the cell's edge crossings, so hits are accurate to a fraction of a cell. The ray
    /// is first clipped to the box of stored chunks (an empty volume costs nothing) and walks at
    /// most 2²⁴ chunks.
    pub fn raycast(&self, origin: DVec3, dir: DVec3, max_t: f64) -> Option<RayHit> {
        self.raycast_limited(origin, dir, max_t, 1 << 24).0
    }

    /// [`Volume::raycast`] walking at most `max_chunks` chunks of the clipped ray; also returns
    /// how many it walked (callers share one budget between several volumes).
    pub fn raycast_limited(&self, origin: DVec3, dir: DVec3, max_t: f64, max_chunks: u64) -> (Option<RayHit>, u64) {
        if !(origin.is_finite() && dir.is_finite() && dir.length_squared() > 0.0 && max_t >= 0.0) {
            return (None, 0);
        }
        let Some((lo, hi)) = self.chunk_bounds_grid() else { return (None, 0) };
        let Some((t_in, t_out)) = clip_to_box(origin, dir, lo, hi) else { return (None, 0) };
        let t_start = t_in.max(0.0);
        let t_end = t_out.min(max_t).min(1e9);
        if !(t_start <= t_end) {
            return (None, 0);
        }
        let mut walked = 0u64;
        let mut block = VoxelBlock::default();
        let chunk_size = CHUNK_CELLS as f64;
        let ray_start = origin + dir * t_start;
        for (cell, t0, t1, entry_axis) in Dda::new(ray_start / chunk_size, dir / chunk_size, t_end - t_start) {
            if walked >= max_chunks {
                break;
            }
            walked += 1;
            let (t0, t1) = (t0 + t_start, t1 + t_start);
            let Some(key) = key_of(cell) else { break };
            let entry_normal = entry_normal(entry_axis, dir);
            match self.view(key) {
                ChunkView::Uniform(false) => {}
                ChunkView::Uniform(true) => return (Some(hit(origin, dir, t0, entry_normal)), walked),
                ChunkView::Lists(l) => {
                    self.extract_block_into(key, &mut block);
                    let sp = l.level().spacing();
                    let chunk_origin = key.origin_grid().as_dvec3();
                    let local_o = (origin - chunk_origin) / sp;
                    let n = block.cells() as i64;
                    let start = t0;
                    for (c, c0, c1, axis) in Dda::new(local_o + dir / sp * start, dir / sp, (t1 - t0).max(0.0)) {
                        if c.cmplt(I64Vec3::ZERO).any() || c.cmpge(I64Vec3::splat(n)).any() {
                            continue;
                        }
                        let (c0, c1) = (start + c0, start + c1);
                        let normal_in = if c0 == start { entry_normal } else { self::entry_normal(axis, dir) };
                        if let Some(h) = hit_in_cell(&block, c, origin, dir, chunk_origin, sp, c0, c1, normal_in) {
                            return (Some(h), walked);
                        }
                    }
                }
            }
        }
        (None, walked)
    }
}

/// The parameter interval where `origin + t · dir` lies in the box `[lo, hi]` (any `t`), if the
/// line meets it.
pub fn clip_to_box(origin: DVec3, dir: DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..3 {
        if dir[i] == 0.0 {
            if origin[i] < lo[i] || origin[i] > hi[i] {
                return None;
            }
        } else {
            let a = (lo[i] - origin[i]) / dir[i];
            let b = (hi[i] - origin[i]) / dir[i];
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// The state read along an x line of `lists` where `before(q)` says whether the crossing at
/// `q` lies before the point: the line of row `(y, z)` of level `at` (`0..at.cells()` each), or
/// where the chunk is stored at a coarser level and has no such line, the line of its own nodes
/// at or below it on y and z.
fn x_line_state(
    lists: &ChunkLists,
    at: Level,
    y: usize,
    z: usize,
    before: impl Fn(crate::coords::LocalPos) -> bool,
) -> bool {
    let (stored, at) = (lists.level().get(), at.get());
    let (y, z) =
        if stored >= at { (y << (stored - at), z << (stored - at)) } else { (y >> (at - stored), z >> (at - stored)) };
    let line = lists.line(Axis::X, y, z);
    let crossed = line.positions().take_while(|&q| before(q)).count();
    line.start_inside ^ (crossed % 2 == 1)
}

fn key_of(k: I64Vec3) -> Option<ChunkKey> {
    let ok = k.cmpge(I64Vec3::splat(i32::MIN as i64)).all() && k.cmple(I64Vec3::splat(i32::MAX as i64)).all();
    ok.then(|| ChunkKey(IVec3::new(k.x as i32, k.y as i32, k.z as i32)))
}

fn hit(origin: DVec3, dir: DVec3, t: f64, normal: DVec3) -> RayHit {
    RayHit { t, point: origin + dir * t, normal }
}

fn entry_normal(axis: Option<usize>, dir: DVec3) -> DVec3 {
    match axis {
        Some(a) => {
            let mut n = DVec3::ZERO;
            n[a] = -dir[a].signum();
            n
        }
        None => -dir.normalize(),
    }
}

#[allow(clippy::too_many_arguments)]
fn hit_in_cell(
    b: &VoxelBlock,
    c: I64Vec3,
    origin: DVec3,
    dir: DVec3,
    chunk_origin: DVec3,
    sp: f64,
    t0: f64,
    t1: f64,
    normal_in: DVec3,
) -> Option<RayHit> {
    let (x, y, z) = (c.x as usize, c.y as usize, c.z as usize);
    let mut inside = 0;
    for k in 0..8 {
        inside += b.inside(x + (k & 1), y + ((k >> 1) & 1), z + (k >> 2)) as u32;
    }
    if inside == 0 {
        return None;
    }
    if inside == 8 {
        return Some(hit(origin, dir, t0, normal_in));
    }
    // Fit a plane to the crossings on the cell's twelve edges.
    let (mut sum_p, mut sum_n, mut count) = (DVec3::ZERO, DVec3::ZERO, 0.0);
    for (axis, lower, e) in b.cell_crossings(x, y, z) {
        let mut p = DVec3::new(lower[0] as f64, lower[1] as f64, lower[2] as f64);
        p[axis.index()] += e.t as f64;
        sum_p += p;
        sum_n += unpack_normal(e.normal);
        count += 1.0;
    }
    let normal = sum_n.normalize_or(normal_in);
    if count > 0.0 {
        let point = chunk_origin + sum_p / count * sp;
        let denom = dir.dot(normal);
        if denom.abs() > 1e-12 {
            let t = (point - origin).dot(normal) / denom;
            let slack = 1e-9 * (1.0 + t0.abs());
            if t >= t0 - slack && t <= t1 + slack {
                return Some(hit(origin, dir, t.clamp(t0, t1), normal));
            }
        }
    }
    // The plane missed the ray's stretch in this cell: take the cell entry if the corner nearest
    // to the middle of that stretch is inside.
    let mid = (origin + dir * (0.5 * (t0 + t1)) - chunk_origin) / sp - c.as_dvec3();
    let k = mid.round().clamp(DVec3::ZERO, DVec3::ONE);
    b.inside(x + k.x as usize, y + k.y as usize, z + k.z as usize).then(|| hit(origin, dir, t0, normal))
}

/// Cells of a unit grid along a ray, with the ray interval in each and the axis crossed to enter.
struct Dda {
    cell: I64Vec3,
    step: I64Vec3,
    t_next: DVec3,
    t_delta: DVec3,
    t: f64,
    max_t: f64,
    axis: Option<usize>,
    steps_left: u32,
}

impl Dda {
    fn new(o: DVec3, d: DVec3, max_t: f64) -> Self {
        let cell = o.floor();
        let mut step = I64Vec3::ZERO;
        let mut t_next = DVec3::INFINITY;
        let mut t_delta = DVec3::INFINITY;
        for i in 0..3 {
            if d[i] > 0.0 {
                step[i] = 1;
                t_delta[i] = 1.0 / d[i];
                t_next[i] = (cell[i] + 1.0 - o[i]) / d[i];
            } else if d[i] < 0.0 {
                step[i] = -1;
                t_delta[i] = -1.0 / d[i];
                t_next[i] = (cell[i] - o[i]) / d[i];
            }
        }
        let ok = cell.abs().max_element() < 4e18;
        Dda {
            cell: if ok { cell.as_i64vec3() } else { I64Vec3::ZERO },
            step,
            t_next,
            t_delta,
            t: 0.0,
            max_t,
            axis: None,
            steps_left: if ok { 1 << 24 } else { 0 },
        }
    }
}

impl Iterator for Dda {
    type Item = (I64Vec3, f64, f64, Option<usize>);

    fn next(&mut self) -> Option<Self::Item> {
        if self.t > self.max_t || self.steps_left == 0 {
            return None;
        }
        self.steps_left -= 1;
        let a = if self.t_next.x <= self.t_next.y && self.t_next.x <= self.t_next.z {
            0
        } else if self.t_next.y <= self.t_next.z {
            1
        } else {
            2
        };
        let exit = self.t_next[a].min(self.max_t);
        let item = (self.cell, self.t, exit, self.axis);
        self.t = self.t_next[a];
        if !self.t.is_finite() {
            self.steps_left = 0;
        }
        self.cell[a] += self.step[a];
        self.t_next[a] += self.t_delta[a];
        self.axis = Some(a);
        Some(item)
    }
}

impl Volume {
    /// The enclosed volume (grid units³) measured from the lines along `axis`: the total length
    /// of their inside segments times the cross-section each line stands for (the cell after it
    /// on both across axes). Where a chunk follows a chunk of another level on an across axis
    /// (uniform chunks count at the volume's level), that sum is off by half the difference of
    /// their spacings times the inside length of the later chunk's first lines; the measure adds
    /// that back, so it does not depend on where the levels change.
    pub fn measured_volume(&self, axis: Axis) -> f64 {
        let mut total = 0.0;
        let spacing_of = |k: ChunkKey| self.stored_level(k).unwrap_or(self.level).spacing();
        let single = self.single_level();
        for (&key, chunk) in self.chunks.iter() {
            match chunk {
                Chunk::Solid => {
                    total += (CHUNK_CELLS * CHUNK_CELLS * CHUNK_CELLS) as f64;
                    if !single {
                        total += self.seam_correction(key, axis, None, &spacing_of);
                    }
                }
                Chunk::Lists(l) => {
                    let n = l.level().cells();
                    let area = l.level().spacing() * l.level().spacing();
                    let mut steps = 0u64;
                    let mut cursor = l.cursor(axis, 0);
                    // Inside steps of the first row of lines along each across axis.
                    let mut first = [0u64; 2];
                    for i in 0..n * n {
                        let line = cursor.next_line();
                        let len = inside_steps(line);
                        steps += len;
                        if i % n == 0 {
                            first[0] += len;
                        }
                        if i < n {
                            first[1] += len;
                        }
                    }
                    total += steps as f64 * (CHUNK_CELLS as f64 / CHUNK_STEPS as f64) * area;
                    if !single {
                        total += self.seam_correction(key, axis, Some((l.level(), first)), &spacing_of);
                    }
                }
            }
        }
        total
    }

    /// The correction of [`Volume::measured_volume`] at the chunk `key`'s minimum faces across
    /// `axis`: `lists` gives its level and the inside steps of its first row of lines along
    /// each across axis (`None`: a solid chunk).
    fn seam_correction(
        &self,
        key: ChunkKey,
        axis: Axis,
        lists: Option<(crate::coords::Level, [u64; 2])>,
        spacing_of: &dyn Fn(ChunkKey) -> f64,
    ) -> f64 {
        let (ua, va) = axis.across();
        let sp = lists.map_or(self.level.spacing(), |(l, _)| l.spacing());
        let mut c = 0.0;
        for (k, across) in [ua, va].into_iter().enumerate() {
            let before = spacing_of(key.offset(-across.unit_i64().as_ivec3()));
            if before == sp {
                continue;
            }
            // The first row's inside length times its extent along the other across axis.
            let row = match lists {
                Some((_, first)) => first[k] as f64 * (CHUNK_CELLS as f64 / CHUNK_STEPS as f64) * sp,
                None => (CHUNK_CELLS * CHUNK_CELLS) as f64,
            };
            c += (before - sp) / 2.0 * row;
        }
        c
    }
}

/// Fixed-point steps of `line` that are inside.
fn inside_steps(line: crate::chunk::LineRef<'_>) -> u64 {
    let mut steps = 0u64;
    let mut inside_from = line.start_inside.then_some(0u64);
    for q in line.positions() {
        match inside_from.take() {
            Some(s) => steps += q.0 as u64 - s,
            None => inside_from = Some(q.0 as u64),
        }
    }
    if let Some(s) = inside_from {
        steps += CHUNK_STEPS as u64 - s;
    }
    steps
}
