//! Reading a region: the node states and crossings near its box, straight from the chunks' own
//! lines (no voxel block is built), then the signed distance field from them.

use glam::{DVec3, I64Vec3, IVec3};

use super::band::{Band, band, grow_nearest, sweep_nearest};
use super::{
    BAND, FAR, GROW_LAYERS, MAX_LATERAL, MAX_REGION_NODES, MIN_DISTANCE, Reach, Region, RegionCrossing, RegionError,
};
use crate::axis::{Axis, compose};
use crate::chunk::{ChunkLists, ChunkView, node_mask};
use crate::coords::{ChunkKey, Level, edge_of};
use crate::normal::unpack_normal;
use crate::volume::Volume;

/// Per row `(y, z)` of a region's nodes, the x range `lo..hi` of the nodes a convex set holds
/// there (a ball or a capsule meets every row in one range).
#[derive(Clone, Debug)]
pub(crate) struct RowSpans {
    dims: [usize; 3],
    lo: Vec<u32>,
    hi: Vec<u32>,
}

impl RowSpans {
    /// Every node.
    pub(crate) fn full(dims: [usize; 3]) -> Self {
        let rows = dims[1] * dims[2];
        RowSpans { dims, lo: vec![0; rows], hi: vec![dims[0] as u32; rows] }
    }

    /// The nodes (coordinates `origin + (x, y, z)`) within `limit` of the segment from `a` to
    /// `b` (all in node units).
    pub(crate) fn near_segment(origin: I64Vec3, dims: [usize; 3], a: DVec3, b: DVec3, limit: f64) -> Self {
        let rows = dims[1] * dims[2];
        let (mut lo, mut hi) = (vec![0u32; rows], vec![0u32; rows]);
        let o = origin.as_dvec3();
        let last = dims[0] as f64 - 1.0;
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                let r = y + dims[1] * z;
                let q = o + DVec3::new(0.0, y as f64, z as f64);
                let (x0, x1) = if a == b {
                    let (dy, dz) = (q.y - a.y, q.z - a.z);
                    let left = limit * limit - dy * dy - dz * dz;
                    if left < 0.0 {
                        continue;
                    }
                    let half = left.sqrt();
                    ((a.x - half - o.x).ceil().max(0.0), (a.x + half - o.x).floor().min(last))
                } else {
                    // The distance to a segment is convex along the row: walk in from both ends
                    // of the segment's x extent.
                    let inside = |x: f64| segment_distance(q + DVec3::X * x, a, b) <= limit;
                    let mut x0 = (a.x.min(b.x) - limit - o.x).floor().max(0.0);
                    let mut x1 = (a.x.max(b.x) + limit - o.x).ceil().min(last);
                    while x0 <= x1 && !inside(x0) {
                        x0 += 1.0;
                    }
                    while x1 >= x0 && !inside(x1) {
                        x1 -= 1.0;
                    }
                    (x0, x1)
                };
                if x0 <= x1 {
                    lo[r] = x0 as u32;
                    hi[r] = x1 as u32 + 1;
                }
            }
        }
        RowSpans { dims, lo, hi }
    }

    /// The x range of row `(y, z)`.
    #[inline]
    pub(crate) fn row(&self, y: usize, z: usize) -> (usize, usize) {
        let r = y + self.dims[1] * z;
        (self.lo[r] as usize, self.hi[r] as usize)
    }

    /// The region indices the spans hold, in storage order.
    pub(crate) fn indices(&self) -> impl Iterator<Item = usize> + '_ {
        let d = self.dims;
        (0..d[1] * d[2]).flat_map(move |r| {
            let row = r * d[0];
            (row + self.lo[r] as usize)..(row + self.hi[r].max(self.lo[r]) as usize)
        })
    }

    /// The spans as one flag per node.
    pub(crate) fn mask(&self) -> Vec<bool> {
        let mut m = vec![false; self.dims.iter().product()];
        for i in self.indices() {
            m[i] = true;
        }
        m
    }
}

/// The distance from `p` to the segment from `a` to `b`.
pub(crate) fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).length()
}

/// What a region read gathers from the chunks: node states, and the stored crossings near the
/// box (points in node units, unit normals).
struct Gathered {
    inside: Vec<bool>,
    crossings: Vec<RegionCrossing>,
}

/// The box a read gathers from, in node coordinates of its level: node states of `states`
/// (inclusive), crossings of the lines through `lines` (inclusive: the state box and [`BAND`]
/// nodes around it).
#[derive(Clone, Copy)]
struct ReadBox {
    origin: I64Vec3,
    dims: [usize; 3],
    lines_lo: I64Vec3,
    lines_hi: I64Vec3,
}

impl ReadBox {
    #[inline]
    fn index(&self, g: I64Vec3) -> usize {
        let l = g - self.origin;
        l.x as usize + self.dims[0] * (l.y as usize + self.dims[1] * l.z as usize)
    }

    /// The chunks of level `level` whose own lines the line box may hold, with the node of
    /// their node 0, in z, y, x order.
    fn chunks(&self, level: Level) -> impl Iterator<Item = (ChunkKey, I64Vec3)> {
        let n = level.cells() as i64;
        let (lo, hi) = (self.lines_lo.div_euclid(I64Vec3::splat(n)), self.lines_hi.div_euclid(I64Vec3::splat(n)));
        (lo.z..=hi.z).flat_map(move |z| {
            (lo.y..=hi.y).flat_map(move |y| {
                (lo.x..=hi.x)
                    .map(move |x| (ChunkKey(IVec3::new(x as i32, y as i32, z as i32)), I64Vec3::new(x, y, z) * n))
            })
        })
    }

    #[inline]
    fn holds_node(&self, g: I64Vec3) -> bool {
        let l = g - self.origin;
        l.min_element() >= 0
            && (l.x as usize) < self.dims[0]
            && (l.y as usize) < self.dims[1]
            && (l.z as usize) < self.dims[2]
    }
}

impl Volume {
    /// The own nodes and crossings of the list chunk `key` (stored at `stored`, coarser than
    /// `level`) as raising it to `level` would store them, into `block`; `false` if it cannot
    /// be read there.
    fn read_refined(&self, key: ChunkKey, level: Level, block: &mut crate::VoxelBlock) -> bool {
        match crate::level::refined(self, key, level) {
            Some(d) => {
                block.fill_from_dense(key, level, &d, 0);
                true
            }
            None => false,
        }
    }

    /// Reads the nodes of the box `[min, max]` (grid coordinates, rounded outwards to nodes) plus
    /// `apron` nodes on every side into a [`Region`] (see the module docs).
    pub fn read_region(&self, min: DVec3, max: DVec3, apron: usize) -> Result<Region, RegionError> {
        self.read_region_within(min, max, apron, Reach::Everywhere)
    }

    /// [`Volume::read_region`] with the distance computed only within `reach` (plus `apron`
    /// nodes); the rest of the box reads [`FAR`] with the node's sign. Operators must then own
    /// only nodes at least one node inside the reach.
    pub fn read_region_within(
        &self,
        min: DVec3,
        max: DVec3,
        apron: usize,
        reach: Reach,
    ) -> Result<Region, RegionError> {
        if !(min.is_finite() && max.is_finite() && min.cmple(max).all()) {
            return Err(RegionError::BadBox);
        }
        if !reach.is_finite() {
            return Err(RegionError::BadBox);
        }
        let level = self.level_near(min, max);
        let inv_sp = level.nodes_per_unit();
        let limit = (i32::MAX as f64 - 2.0) * level.cells() as f64;
        let lo = (min * inv_sp).floor() - DVec3::splat(apron as f64);
        let hi = (max * inv_sp).ceil() + DVec3::splat(apron as f64);
        if lo.min_element() < -limit || hi.max_element() > limit {
            return Err(RegionError::OutOfRange);
        }
        let dims_f = hi - lo + DVec3::ONE;
        let nodes = dims_f.x * dims_f.y * dims_f.z;
        if nodes > MAX_REGION_NODES as f64 {
            return Err(RegionError::TooLarge { nodes: nodes as u64, limit: MAX_REGION_NODES });
        }
        let origin = lo.as_i64vec3();
        let dims = [dims_f.x as usize, dims_f.y as usize, dims_f.z as usize];
        let count = dims[0] * dims[1] * dims[2];
        let band_nodes = BAND.ceil() as i64;
        let top = origin + I64Vec3::new(dims[0] as i64, dims[1] as i64, dims[2] as i64) - I64Vec3::ONE;
        let at = ReadBox {
            origin,
            dims,
            lines_lo: origin - I64Vec3::splat(band_nodes),
            lines_hi: top + I64Vec3::splat(band_nodes),
        };
        let Gathered { inside, crossings } = self.gather(level, &at);

        let reach_nodes = reach.in_nodes(inv_sp, apron as f64);
        let (needed, mode) = match reach_nodes {
            None => (RowSpans::full(dims), Mode::Sweep),
            Some(Reach::Capsule { a, b, radius, depth }) => {
                let needed = RowSpans::near_segment(origin, dims, a, b, radius);
                let mode = if depth <= BAND {
                    Mode::Band
                } else if depth <= BAND + GROW_LAYERS {
                    Mode::Grow(depth)
                } else {
                    Mode::Sweep
                };
                (needed, mode)
            }
            Some(Reach::Everywhere) => unreachable!("in_nodes gives a capsule or nothing"),
        };
        // Where the band is computed: the needed nodes alone when nothing propagates from it;
        // else the nodes the propagation runs over, the reach widened by its depth, so that the
        // straight path from a needed node to its nearest crossing (both in the convex reach
        // widened by the depth) is open to it.
        let swept = match (mode, reach_nodes) {
            (Mode::Band, _) => None,
            (_, Some(Reach::Capsule { a, b, radius, depth })) => {
                Some(RowSpans::near_segment(origin, dims, a, b, radius + depth))
            }
            _ => Some(RowSpans::full(dims)),
        };
        // A crossing farther than the depth from every needed node is nobody's nearest within
        // the depth.
        let skip = |p: DVec3| match reach_nodes {
            Some(Reach::Capsule { a, b, radius, depth }) => segment_distance(p, a, b) > radius + depth,
            _ => false,
        };
        let Band { near2, lateral2, plane, mut nearest } =
            band(&crossings, skip, origin, dims, swept.as_ref().unwrap_or(&needed), mode != Mode::Band);
        // The distance to the nearest crossing: from the band, and beyond it by propagating each
        // node's nearest crossing to its neighbours (a closest-point transform; the crossings lie
        // about a cell apart, so far from the surface this is the distance to it within a small
        // fraction of a cell).
        // (The band alone needs no distance array: its squared distances are rooted per node.)
        let mut dist: Vec<f64> = Vec::new();
        let points: Vec<DVec3> =
            if mode == Mode::Band { Vec::new() } else { crossings.iter().map(|c| c.point).collect() };
        if mode != Mode::Band {
            dist = near2.iter().map(|&d| (d as f64).sqrt()).collect();
        }
        // Within a reach only `depth` matters. For a shallow depth the nearest crossing grows out
        // from the band layer by layer, through the nodes within the depth of the surface only,
        // and the needed nodes it does not reach read one node beyond the depth; for a deep one
        // the sweep runs over the reach widened by the depth.
        // (Growing costs the surface times the layers, the sweep the region's volume: growing
        // wins up to about three layers beyond the band.)
        let beyond = match (mode, reach_nodes) {
            (Mode::Band, Some(Reach::Capsule { depth, .. })) => Some(depth + 1.0),
            (Mode::Grow(depth), _) => {
                let open = swept.as_ref().expect("a grow has its spans").mask();
                grow_nearest(&mut nearest, &mut dist, &points, origin, dims, &open, depth);
                Some(depth + 1.0)
            }
            _ => {
                let open = swept.as_ref().expect("a sweep has its spans").mask();
                sweep_nearest(&mut nearest, &mut dist, &points, origin, dims, &open);
                None
            }
        };
        let distance = |i: usize| if mode == Mode::Band { (near2[i] as f64).sqrt() } else { dist[i] };
        let mut phi = vec![f32::INFINITY; count];
        for i in needed.indices() {
            let di = distance(i);
            if di.is_finite() {
                let close = lateral2[i] <= (MAX_LATERAL * MAX_LATERAL) as f32;
                let d = if close { (plane[i] as f64).min(di) } else { di };
                phi[i] = match beyond {
                    Some(b) => d.min(b) as f32,
                    None => d as f32,
                };
            } else if let Some(b) = beyond
                && !crossings.is_empty()
            {
                phi[i] = b as f32;
            }
        }
        for (v, &inside) in phi.iter_mut().zip(&inside) {
            let m = if v.is_finite() { v.max(MIN_DISTANCE) } else { FAR };
            *v = if inside { -m } else { m };
        }
        Ok(Region { origin, dims, original: phi.clone(), phi, weight: vec![0.0; count], crossings, level })
    }

    /// The node states of `at`'s box and the crossings of the lines through its line box, read
    /// at `level` from the chunks' own lines (a chunk stored coarser reads what raising it would
    /// store).
    fn gather(&self, level: Level, at: &ReadBox) -> Gathered {
        let count = at.dims.iter().product();
        let mut g = Gathered { inside: vec![false; count], crossings: Vec::new() };
        let n = level.cells() as i64;
        let mut block = None;
        for (key, base) in at.chunks(level) {
            match self.view(key) {
                ChunkView::Uniform(s) => {
                    if s {
                        for_own_nodes(at, base, n, |i, _| g.inside[i] = true);
                    }
                }
                ChunkView::Lists(l) if l.level() == level => read_own_lines(l, base, at, &mut g),
                ChunkView::Lists(_) => {
                    let block = block.get_or_insert_with(crate::VoxelBlock::default);
                    if self.read_refined(key, level, block) {
                        read_block(block, base, n, at, &mut g);
                    }
                }
            }
        }
        g
    }
}

/// How a read computes distances beyond the band.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    /// The band alone: nodes beyond it read one node beyond the depth.
    Band,
    /// The nearest crossing grown out from the band to this depth (nodes).
    Grow(f64),
    /// The nearest crossing swept over the whole reach.
    Sweep,
}

/// The own node states and crossings of the list chunk at node `base` (stored at the read's
/// level), from its lines through the read box: x lines give the states, every line its
/// crossings.
fn read_own_lines(l: &ChunkLists, base: I64Vec3, at: &ReadBox, g: &mut Gathered) {
    let level = l.level();
    let n = level.cells();
    let s = level.steps_per_cell();
    let inv_s = 1.0 / s as f32;
    for axis in Axis::ALL {
        let (ua, va) = axis.across();
        let a = axis.index();
        let range = |c: usize| {
            let lo = (at.lines_lo[c] - base[c]).max(0);
            let hi = (at.lines_hi[c] - base[c]).min(n as i64 - 1);
            (lo <= hi).then_some((lo as usize, hi as usize))
        };
        let (Some((u0, u1)), Some((v0, v1))) = (range(ua.index()), range(va.index())) else { continue };
        let mut cursor = l.cursor(axis, u0 + n * v0);
        for v in v0..=v1 {
            for u in u0..=u1 {
                cursor.advance_to(u + n * v);
                // x lines derive their start states (they give the node states); the others
                // are read for their crossings only.
                let line = if axis == Axis::X { cursor.next_line() } else { cursor.next_with(false) };
                let mut states = if line.start_inside { node_mask(n) } else { 0 };
                for (q, &nr) in line.positions().zip(line.normals) {
                    let e = edge_of(q, level);
                    states ^= node_mask(n) & !((1u128 << (e + 1)) - 1);
                    let lower = compose(axis, e as i64, u as i64, v as i64);
                    let mut p = (base + I64Vec3::from_array(lower)).as_dvec3();
                    p[a] += ((q.0 as u32 - e as u32 * s) as f32 * inv_s) as f64;
                    g.crossings.push(RegionCrossing {
                        axis,
                        point: p,
                        normal: unpack_normal(nr).normalize_or(axis.unit()),
                    });
                }
                if axis == Axis::X {
                    // Line (u, v) along x holds the nodes (x, u, v).
                    let row = base + I64Vec3::new(0, u as i64, v as i64);
                    for x in 0..n as i64 {
                        let node = row + I64Vec3::new(x, 0, 0);
                        if at.holds_node(node) {
                            g.inside[at.index(node)] = (states >> x) & 1 == 1;
                        }
                    }
                }
            }
        }
    }
}

/// The own node states of `block` (the chunk at node `base`) and the crossings of its own lines
/// through the read's line box into the read.
fn read_block(block: &crate::VoxelBlock, base: I64Vec3, n: i64, at: &ReadBox, g: &mut Gathered) {
    for_own_nodes(at, base, n, |i, local| {
        g.inside[i] = block.inside(local[0], local[1], local[2]);
    });
    for axis in Axis::ALL {
        let (ua, va) = axis.across();
        for c in block.crossings(axis) {
            let lower = c.lower.map(|v| v as usize);
            if lower[ua.index()] >= n as usize || lower[va.index()] >= n as usize {
                // An apron edge: its owner lists it.
                continue;
            }
            let line = base + I64Vec3::new(lower[0] as i64, lower[1] as i64, lower[2] as i64);
            if [ua.index(), va.index()].iter().any(|&k| line[k] < at.lines_lo[k] || line[k] > at.lines_hi[k]) {
                // A line that does not pass through the read's line box.
                continue;
            }
            let mut p = line.as_dvec3();
            p[axis.index()] += c.t as f64;
            g.crossings.push(RegionCrossing {
                axis,
                point: p,
                normal: unpack_normal(c.normal).normalize_or(axis.unit()),
            });
        }
    }
}

/// Calls `f(region index, chunk-local node)` for every node of the chunk at node `base` (its own
/// nodes `0..n` on each axis) that lies in the read's box.
fn for_own_nodes(at: &ReadBox, base: I64Vec3, n: i64, mut f: impl FnMut(usize, [usize; 3])) {
    let d = at.dims;
    let lo = (base - at.origin).max(I64Vec3::ZERO);
    let hi = (base + I64Vec3::splat(n) - at.origin).min(I64Vec3::new(d[0] as i64, d[1] as i64, d[2] as i64));
    for z in lo.z..hi.z {
        for y in lo.y..hi.y {
            for x in lo.x..hi.x {
                let local = at.origin + I64Vec3::new(x, y, z) - base;
                f(
                    x as usize + d[0] * (y as usize + d[1] * z as usize),
                    [local.x as usize, local.y as usize, local.z as usize],
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brush::{Cuboid, Sphere};

    /// The gather as it was before reads went to the lines: the voxel block of every list chunk
    /// (plain at its own level, its own lines made consistent where a neighbour has another
    /// level, raised where it is coarser), its own crossings and nodes.
    fn gather_by_blocks(v: &Volume, level: Level, at: &ReadBox) -> Gathered {
        let count = at.dims.iter().product();
        let mut g = Gathered { inside: vec![false; count], crossings: Vec::new() };
        let n = level.cells() as i64;
        let mut block = crate::VoxelBlock::default();
        for (key, base) in at.chunks(level) {
            match v.view(key) {
                ChunkView::Uniform(true) => for_own_nodes(at, base, n, |i, _| g.inside[i] = true),
                ChunkView::Uniform(false) => {}
                ChunkView::Lists(l)
                    if l.level() == level
                        && (v.single_level() || crate::level::plain(&crate::level::LevelMap::stored(v), key)) =>
                {
                    v.extract_block_into(key, &mut block);
                    read_block(&block, base, n, at, &mut g);
                }
                ChunkView::Lists(l) if l.level() == level => {
                    let mut d = crate::level::Dense::new(level);
                    d.read_own(v.view(key));
                    d.make_consistent();
                    block.fill_from_dense(key, level, &d, 0);
                    read_block(&block, base, n, at, &mut g);
                }
                ChunkView::Lists(_) => {
                    if v.read_refined(key, level, &mut block) {
                        read_block(&block, base, n, at, &mut g);
                    }
                }
            }
        }
        // Only the lines through the line box.
        g.crossings.retain(|c| {
            let (ua, va) = c.axis.across();
            [ua.index(), va.index()].iter().all(|&k| {
                let x = c.point[k].round() as i64;
                x >= at.lines_lo[k] && x <= at.lines_hi[k]
            })
        });
        g
    }

    fn sorted(g: &Gathered) -> Vec<(u8, [u64; 6])> {
        let mut s: Vec<(u8, [u64; 6])> = g
            .crossings
            .iter()
            .map(|c| {
                let (p, n) = (c.point, c.normal);
                (c.axis.index() as u8, [p.x, p.y, p.z, n.x, n.y, n.z].map(f64::to_bits))
            })
            .collect();
        s.sort();
        s
    }

    #[test]
    fn reading_the_lines_gathers_what_the_voxel_blocks_held() {
        let mut rng = 0x2901u64;
        let mut next = move |m: u64| {
            rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (rng >> 33) % m
        };
        for case in 0..12 {
            let mut v = Volume::new();
            for _ in 0..6 {
                // Centres on nodes, half-cells and arbitrary points.
                let snap = [1.0, 2.0, 7.3][next(3) as usize];
                let c =
                    DVec3::new(next(160) as f64, next(160) as f64, next(160) as f64) / (snap * 2.0) + DVec3::splat(8.0);
                let r = 1.0 + next(12) as f64 / snap;
                if next(2) == 0 {
                    v.add(&Sphere::new(c, r).unwrap()).unwrap();
                } else {
                    v.subtract(&Cuboid::new(c, DVec3::new(r, r * 0.7, r * 0.4)).unwrap()).unwrap();
                }
            }
            // Mixed levels in half the cases: a few chunks raised.
            if case % 2 == 1 {
                for key in [ChunkKey::new(1, 1, 1), ChunkKey::new(2, 1, 1), ChunkKey::new(1, 2, 2)] {
                    v.set_chunk_level(key, Level::new(1 + (next(2) as i8)).unwrap());
                }
            }
            for _ in 0..6 {
                let c = DVec3::new(next(40) as f64, next(40) as f64, next(40) as f64) + DVec3::splat(8.0);
                let h = 1.0 + next(16) as f64;
                let level = v.level_near(c - h, c + h);
                let inv = level.nodes_per_unit();
                let origin = ((c - h) * inv).floor().as_i64vec3();
                let top = ((c + h) * inv).ceil().as_i64vec3();
                let d = top - origin + I64Vec3::ONE;
                let at = ReadBox {
                    origin,
                    dims: [d.x as usize, d.y as usize, d.z as usize],
                    lines_lo: origin - I64Vec3::splat(3),
                    lines_hi: top + I64Vec3::splat(3),
                };
                let (lines, blocks) = (v.gather(level, &at), gather_by_blocks(&v, level, &at));
                assert_eq!(lines.inside, blocks.inside, "case {case}: node states differ");
                let (a, b) = (sorted(&lines), sorted(&blocks));
                if a != b {
                    let only_a: Vec<_> = a.iter().filter(|x| !b.contains(x)).take(3).collect();
                    let only_b: Vec<_> = b.iter().filter(|x| !a.contains(x)).take(3).collect();
                    let show = |v: &[&(u8, [u64; 6])]| -> Vec<(u8, [f64; 6])> {
                        v.iter().map(|(ax, w)| (*ax, w.map(f64::from_bits))).collect()
                    };
                    panic!(
                        "case {case}: {} crossings read from the lines, {} from the blocks; only in the lines {:?}, only in the blocks {:?}",
                        a.len(),
                        b.len(),
                        show(&only_a),
                        show(&only_b)
                    );
                }
            }
        }
    }
}
