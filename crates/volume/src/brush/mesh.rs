//! A brush from a closed triangle mesh, answered by ray casting along grid lines.
//!
//! Lines along a grid axis (all the lines an edit asks about) find their candidate triangles in
//! a bucket grid over the plane across that axis, built on the first such line: each triangle
//! is listed in the buckets its footprint's bounding box covers, so a line tests only the few
//! triangles whose footprint box contains it. Other lines walk a BVH. Either way every triangle
//! whose box holds the line is tested with the same exact test, and hits are ordered by
//! parameter, then triangle, so both give the same spans.
//!
//! Ray–triangle tests use a watertight formulation (a shear into the ray's frame, then 2-D edge
//! functions) with a top-left tie rule: a line through a shared edge or vertex of a closed mesh
//! is counted exactly once where it crosses the surface, and zero or two times where it only
//! grazes it, so inside/outside never flips spuriously.
//!
//! Inside is decided by [`MeshRule`]. A mesh that is not closed (holes, unwelded vertices) is
//! still accepted: along each line an unmatched last crossing is ignored (the line is outside
//! after it). For every mesh, closed or not, node states are taken from the x lines (the
//! predicate is: the node lies in a span of the x line through it) and the volume repairs the y
//! and z lines to match, because exact ties (a face on a grid plane, an edge on a grid line, a
//! vertex on a node) are seen differently along different axes; the result is a consistent solid
//! close to what the mesh encloses, never a crash.

use std::collections::HashMap;
use std::sync::OnceLock;

use glam::DVec3;
use thiserror::Error;

use super::{Aabb, Brush, Span, unit_axis};

/// How crossings along a line decide inside.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MeshRule {
    /// Inside after an odd number of crossings (ignores triangle orientation).
    #[default]
    EvenOdd,
    /// Inside where the winding number is non-zero (uses triangle orientation; counter-clockwise
    /// triangles seen from outside).
    NonZero,
}

/// One triangle a line crosses: line parameter, triangle, facing (+1 entering), unnormalised
/// normal.
type Hit = (f64, u32, i32, DVec3);

/// Why a mesh cannot be a brush.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MeshError {
    /// No triangles (or none with area).
    #[error("the mesh has no triangles with area")]
    Empty,
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {0} is not finite")]
    NonFiniteVertex(usize),
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} uses vertex {index}, but there are only {vertices} vertices")]
    IndexOutOfRange {
        /// Triangle number.
        triangle: usize,
        /// The bad index.
        index: u32,
        /// Vertex count.
        vertices: usize,
    },
}

#[derive(Clone, Copy, Debug)]
struct BvhNode {
    min: DVec3,
    max: DVec3,
    /// Leaf: first triangle in `order`; inner: index of the right child (the left is next).
    first: u32,
    /// Triangles in a leaf, 0 for an inner node.
    count: u32,
}

/// A closed triangle mesh used as a brush (coordinates in grid units; place it with
/// [`super::Transformed`]).
#[derive(Clone, Debug)]
pub struct MeshBrush {
    tris: Vec<[DVec3; 3]>,
    nodes: Vec<BvhNode>,
    rule: MeshRule,
    closed: bool,
    bounds: Aabb,
    /// Per grid axis, the triangles bucketed across it (built on the first line along it;
    /// `None` where a grid would be too large).
    grids: [OnceLock<Option<AxisGrid>>; 3],
}

/// Triangles bucketed by the bounding boxes of their footprints on the plane across one grid
/// axis (coordinates `kx = axis + 1`, `ky = axis + 2`, mod 3, as the ray frame uses them).
#[derive(Clone)]
struct AxisGrid {
    /// The footprint of the whole mesh: its lower corner and upper corner.
    min: [f64; 2],
    max: [f64; 2],
    /// Buckets per grid unit, and buckets along each side.
    inv_cell: f64,
    dims: [usize; 2],
    /// Bucket `i + dims[0] j` lists `tris[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    tris: Vec<u32>,
}

impl std::fmt::Debug for AxisGrid {
    /// The grid's size, not its millions of entries.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AxisGrid").field("dims", &self.dims).field("entries", &self.tris.len()).finish()
    }
}

/// Buckets along one side at most (the grid stays under 4 million buckets).
const GRID_MAX_SIDE: usize = 2048;

impl AxisGrid {
    /// The grid across `axis`, or `None` where the triangles' boxes would make too many entries
    /// (long slivers over a fine grid) even after coarsening it a few times: the BVH answers then.
    fn new(tris: &[[DVec3; 3]], bounds: &Aabb, axis: usize) -> Option<Self> {
        let (kx, ky) = ((axis + 1) % 3, (axis + 2) % 3);
        let min = [bounds.min[kx], bounds.min[ky]];
        let max = [bounds.max[kx], bounds.max[ky]];
        let ext = [max[0] - min[0], max[1] - min[1]];
        // About eight buckets per triangle over the footprint (a flat mesh: along its long side).
        let count = tris.len() as f64;
        let mut cell = (ext[0] * ext[1] / (8.0 * count)).sqrt();
        if !(cell > 0.0) {
            cell = ext[0].max(ext[1]) / (8.0 * count);
        }
        // At most 16 entries per triangle on average (and within the u32 offsets).
        let budget = tris.len().saturating_mul(16).min(u32::MAX as usize / 2);
        for _ in 0..8 {
            let inv_cell = if cell > 0.0 && cell.is_finite() { 1.0 / cell } else { 1.0 };
            let side = |e: f64| ((e * inv_cell).floor().min(GRID_MAX_SIDE as f64 - 1.0) as usize) + 1;
            let dims = [side(ext[0]), side(ext[1])];
            let mut grid = AxisGrid { min, max, inv_cell, dims, starts: Vec::new(), tris: Vec::new() };
            let boxes: Vec<[[usize; 2]; 2]> = tris
                .iter()
                .map(|t| {
                    let lo = [t[0][kx].min(t[1][kx]).min(t[2][kx]), t[0][ky].min(t[1][ky]).min(t[2][ky])];
                    let hi = [t[0][kx].max(t[1][kx]).max(t[2][kx]), t[0][ky].max(t[1][ky]).max(t[2][ky])];
                    [grid.bucket(lo), grid.bucket(hi)]
                })
                .collect();
            let entries =
                boxes.iter().fold(0usize, |n, [lo, hi]| n.saturating_add((hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1)));
            if entries > budget {
                cell *= 2.0;
                continue;
            }
            grid.starts = vec![0; dims[0] * dims[1] + 1];
            for [lo, hi] in &boxes {
                for j in lo[1]..=hi[1] {
                    for i in lo[0]..=hi[0] {
                        grid.starts[i + dims[0] * j + 1] += 1;
                    }
                }
            }
            for b in 0..dims[0] * dims[1] {
                grid.starts[b + 1] += grid.starts[b];
            }
            let mut fill = grid.starts.clone();
            grid.tris = vec![0; entries];
            for (t, [lo, hi]) in boxes.iter().enumerate() {
                for j in lo[1]..=hi[1] {
                    for i in lo[0]..=hi[0] {
                        let b = i + dims[0] * j;
                        grid.tris[fill[b] as usize] = t as u32;
                        fill[b] += 1;
                    }
                }
            }
            return Some(grid);
        }
        None
    }

    /// The bucket of a point of the footprint. Monotonic in each coordinate, so a point inside
    /// a triangle's footprint box falls in one of the buckets that box covers.
    #[inline]
    fn bucket(&self, p: [f64; 2]) -> [usize; 2] {
        let index = |i: usize| (((p[i] - self.min[i]) * self.inv_cell).max(0.0) as usize).min(self.dims[i] - 1);
        [index(0), index(1)]
    }

    /// The triangles whose footprint boxes may contain the point (none outside the mesh's).
    #[inline]
    fn candidates(&self, p: [f64; 2]) -> &[u32] {
        if !(p[0] >= self.min[0] && p[0] <= self.max[0] && p[1] >= self.min[1] && p[1] <= self.max[1]) {
            return &[];
        }
        let [i, j] = self.bucket(p);
        let b = i + self.dims[0] * j;
        &self.tris[self.starts[b] as usize..self.starts[b + 1] as usize]
    }
}

const LEAF_SIZE: usize = 4;

impl MeshBrush {
    /// Builds the BVH. Degenerate (zero-area) triangles are dropped.
    pub fn new(vertices: &[DVec3], triangles: &[[u32; 3]], rule: MeshRule) -> Result<Self, MeshError> {
        if let Some(i) = vertices.iter().position(|v| !v.is_finite()) {
            return Err(MeshError::NonFiniteVertex(i));
        }
        let mut tris = Vec::with_capacity(triangles.len());
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        for (t, tri) in triangles.iter().enumerate() {
            for &index in tri {
                if index as usize >= vertices.len() {
                    return Err(MeshError::IndexOutOfRange { triangle: t, index, vertices: vertices.len() });
                }
            }
            let [a, b, c] = tri.map(|i| vertices[i as usize]);
            if (b - a).cross(c - a).length_squared() == 0.0 {
                continue;
            }
            for k in 0..3 {
                let (i, j) = (tri[k], tri[(k + 1) % 3]);
                *edges.entry((i.min(j), i.max(j))).or_default() += 1;
            }
            tris.push([a, b, c]);
        }
        if tris.is_empty() {
            return Err(MeshError::Empty);
        }
        let closed = edges.values().all(|&c| c == 2);
        let bounds = Aabb::from_points(tris.iter().flatten().copied()).expect("non-empty");
        let mut order: Vec<u32> = (0..tris.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF_SIZE + 1);
        build(&tris, &mut order, 0, tris.len(), &mut nodes);
        let tris = order.iter().map(|&i| tris[i as usize]).collect();
        Ok(MeshBrush { tris, nodes, rule, closed, bounds, grids: Default::default() })
    }

    /// Whether every edge is shared by exactly two triangles (by vertex index).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Calls `hit(t, triangle, facing, normal)` for every triangle the line `o + t d` crosses
    /// (any `t`), where `facing` is +1 when the triangle's winding faces against `d` (the line
    /// enters) and −1 otherwise.
    fn for_each_hit(&self, o: DVec3, d: DVec3, hit: impl FnMut(f64, u32, i32, DVec3)) {
        match unit_axis(d) {
            Some(axis) => self.grid_hits(axis, o, hit),
            None => self.bvh_hits(o, d, hit),
        }
    }

    /// [`MeshBrush::for_each_hit`] for a line along grid axis `axis`, through its bucket grid.
    fn grid_hits(&self, axis: usize, o: DVec3, mut hit: impl FnMut(f64, u32, i32, DVec3)) {
        let mut d = DVec3::ZERO;
        d[axis] = 1.0;
        let Some(grid) = self.grids[axis].get_or_init(|| AxisGrid::new(&self.tris, &self.bounds, axis)) else {
            return self.bvh_hits(o, d, hit);
        };
        let (kx, ky) = ((axis + 1) % 3, (axis + 2) % 3);
        let test = axis_test(axis);
        for &t in grid.candidates([o[kx], o[ky]]) {
            let tri = &self.tris[t as usize];
            if let Some((p, facing)) = test(o, tri) {
                hit(p, t, facing, (tri[1] - tri[0]).cross(tri[2] - tri[0]));
            }
        }
    }

    /// [`MeshBrush::for_each_hit`] through the BVH (any direction; a grid axis with the same test
    /// as the grid's).
    fn bvh_hits(&self, o: DVec3, d: DVec3, mut hit: impl FnMut(f64, u32, i32, DVec3)) {
        let ray = RayFrame::new(o, d);
        let axis = unit_axis(d);
        let test = |tri: &[DVec3; 3]| match axis {
            Some(a) => axis_test(a)(o, tri),
            None => ray.intersect(tri),
        };
        let inv = d.recip();
        // Median splits keep the depth below log2(triangles) + 2, far under the stack size.
        let mut stack = [0u32; 128];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let index = stack[top];
            let node = self.nodes[index as usize];
            if !line_hits_box(o, d, inv, node.min, node.max) {
                continue;
            }
            if node.count > 0 {
                for t in node.first..node.first + node.count {
                    let tri = &self.tris[t as usize];
                    if let Some((p, facing)) = test(tri) {
                        hit(p, t, facing, (tri[1] - tri[0]).cross(tri[2] - tri[0]));
                    }
                }
            } else {
                stack[top] = index + 1;
                stack[top + 1] = node.first;
                top += 2;
            }
        }
    }

    fn inside(&self, crossings: i32, winding: i32) -> bool {
        match self.rule {
            MeshRule::EvenOdd => crossings % 2 != 0,
            MeshRule::NonZero => winding != 0,
        }
    }
}

fn build(tris: &[[DVec3; 3]], order: &mut [u32], start: usize, end: usize, nodes: &mut Vec<BvhNode>) -> u32 {
    let me = nodes.len() as u32;
    let items = &order[start..end];
    let bounds = Aabb::from_points(items.iter().flat_map(|&i| tris[i as usize])).expect("non-empty");
    nodes.push(BvhNode { min: bounds.min, max: bounds.max, first: start as u32, count: (end - start) as u32 });
    if end - start <= LEAF_SIZE {
        return me;
    }
    let centroid = |i: u32| {
        let t = tris[i as usize];
        (t[0] + t[1] + t[2]) / 3.0
    };
    let cb = Aabb::from_points(items.iter().map(|&i| centroid(i))).expect("non-empty");
    let ext = cb.max - cb.min;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    if ext[axis] == 0.0 {
        return me;
    }
    let mid = (start + end) / 2;
    order[start..end].select_nth_unstable_by(mid - start, |&a, &b| centroid(a)[axis].total_cmp(&centroid(b)[axis]));
    build(tris, order, start, mid, nodes);
    let right = build(tris, order, mid, end, nodes);
    nodes[me as usize].first = right;
    nodes[me as usize].count = 0;
    me
}

/// A triangle test for lines from a point: the hit's line parameter and facing.
type TriangleTest = fn(DVec3, &[DVec3; 3]) -> Option<(f64, i32)>;

/// The triangle test for lines along grid axis `axis` (0, 1 or 2).
fn axis_test(axis: usize) -> TriangleTest {
    match axis {
        0 => intersect_axis::<0>,
        1 => intersect_axis::<1>,
        _ => intersect_axis::<2>,
    }
}

fn line_hits_box(o: DVec3, d: DVec3, inv: DVec3, min: DVec3, max: DVec3) -> bool {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..3 {
        if d[i] == 0.0 {
            if o[i] < min[i] || o[i] > max[i] {
                return false;
            }
        } else {
            let a = (min[i] - o[i]) * inv[i];
            let b = (max[i] - o[i]) * inv[i];
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    t0 <= t1
}

/// A line sheared so that it runs along +z' through the 2-D origin (Woop, Benthin, Wald 2013).
struct RayFrame {
    o: DVec3,
    k: [usize; 3],
    shear: DVec3,
}

impl RayFrame {
    fn new(o: DVec3, d: DVec3) -> Self {
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        RayFrame { o, k: [kx, ky, kz], shear: DVec3::new(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]) }
    }

    #[inline]
    fn project(&self, v: DVec3) -> DVec3 {
        let a = v - self.o;
        let [kx, ky, kz] = self.k;
        DVec3::new(a[kx] - self.shear.x * a[kz], a[ky] - self.shear.y * a[kz], self.shear.z * a[kz])
    }

    /// The line parameter of the hit and whether the triangle's front faces the line.
    #[inline]
    fn intersect(&self, tri: &[DVec3; 3]) -> Option<(f64, i32)> {
        edge_test(self.project(tri[0]), self.project(tri[1]), self.project(tri[2]))
    }
}

/// [`RayFrame::intersect`] for a line from `o` along grid axis `KZ`, whose frame needs no shear:
/// the vertices relative to `o`, their coordinates rotated to (kx, ky, kz) by constant indices.
#[inline]
fn intersect_axis<const KZ: usize>(o: DVec3, tri: &[DVec3; 3]) -> Option<(f64, i32)> {
    let p = |v: DVec3| {
        let a = (v - o).to_array();
        DVec3::new(a[(KZ + 1) % 3], a[(KZ + 2) % 3], a[KZ])
    };
    edge_test(p(tri[0]), p(tri[1]), p(tri[2]))
}

/// The watertight test of a triangle projected into a line's frame (the line through the 2-D
/// origin along +z): the line parameter of the hit and whether the triangle's front faces the line.
#[inline]
fn edge_test(p0: DVec3, p1: DVec3, p2: DVec3) -> Option<(f64, i32)> {
    // e_k: edge function of the directed edge p_k -> p_(k+1) (a shared edge gets exactly the
    // negated value in the neighbouring triangle, which keeps the test watertight).
    let e0 = p0.x * p1.y - p0.y * p1.x;
    let e1 = p1.x * p2.y - p1.y * p2.x;
    if (e0 > 0.0 && e1 < 0.0) || (e0 < 0.0 && e1 > 0.0) {
        // One of them has the sign opposite to the determinant's: the line misses (most
        // candidates from the bucket grid do).
        return None;
    }
    let e2 = p2.x * p0.y - p2.y * p0.x;
    let det = e0 + e1 + e2;
    if det == 0.0 {
        return None;
    }
    let sgn = det.signum();
    let inside = |e: f64, a: DVec3, b: DVec3| {
        let e = e * sgn;
        if e > 0.0 {
            return true;
        }
        if e < 0.0 {
            return false;
        }
        // On the edge: the top-left rule takes exactly one of the two triangles sharing it.
        let (dx, dy) = ((b.x - a.x) * sgn, (b.y - a.y) * sgn);
        dy < 0.0 || (dy == 0.0 && dx < 0.0)
    };
    if !(inside(e0, p0, p1) && inside(e1, p1, p2) && inside(e2, p2, p0)) {
        return None;
    }
    // Edge k is opposite vertex k + 2.
    let t = (e1 * p0.z + e2 * p1.z + e0 * p2.z) / det;
    // det > 0: counter-clockwise in the sheared frame, i.e. the normal points back along the
    // line in a right-handed (kx, ky, kz) frame.
    Some((t, if det > 0.0 { 1 } else { -1 }))
}

impl Brush for MeshBrush {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        if self.contains(origin, p) { -1.0 } else { 1.0 }
    }

    /// Inside iff the point lies in one of the spans of the x line through it, so the
    /// predicate and the x lines agree, closed mesh or not.
    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        self.contains_on_line(origin, p, DVec3::X)
    }

    fn contains_on_line(&self, origin: DVec3, p: DVec3, dir: DVec3) -> bool {
        if !self.bounds.expand(1e-9 * (1.0 + self.bounds.max.abs().max_element())).contains(origin + p) {
            return false;
        }
        let mut spans = Vec::new();
        self.spans(origin, p, dir, &mut spans);
        spans.iter().any(|s| s.enter <= 0.0 && 0.0 <= s.exit)
    }

    fn normal(&self, origin: DVec3, p: DVec3) -> DVec3 {
        // Only used for fallbacks; spans carry exact triangle normals.
        let _ = (origin, p);
        DVec3::Z
    }

    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        out.clear();
        self.line_spans(origin + start, dir, &mut Vec::new(), out);
        true
    }

    fn spans_batch(&self, lines: &[(DVec3, DVec3)], dir: DVec3, out: &mut Vec<Span>, counts: &mut Vec<u32>) -> bool {
        // One scratch list of hits for the whole batch.
        let mut hits = Vec::new();
        for &(origin, start) in lines {
            let before = out.len();
            self.line_spans(origin + start, dir, &mut hits, out);
            counts.push((out.len() - before) as u32);
        }
        true
    }

    /// Never: even a closed mesh leaves exact ties open. A face on a grid plane puts nodes on
    /// the surface, and a line lying in that plane sees no crossing of the face (its triangle
    /// test is degenerate there) while the lines through the face see one at the node; an edge
    /// on a grid line is decided by the top-left rule in one frame and not in the other. The
    /// volume therefore takes node states from the x lines (which `contains` reads) and repairs
    /// the y and z lines, for every mesh.
    fn lines_agree(&self) -> bool {
        false
    }
}

impl MeshBrush {
    /// Appends the spans of the line `o + t dir` to `out` (`hits` is scratch space).
    fn line_spans(&self, o: DVec3, dir: DVec3, hits: &mut Vec<Hit>, out: &mut Vec<Span>) {
        hits.clear();
        self.for_each_hit(o, dir, |t, tri, facing, n| hits.push((t, tri, facing, n)));
        self.spans_from_hits(dir, hits, out);
    }

    /// Turns the hits of one line into its spans by the brush's rule.
    fn spans_from_hits(&self, dir: DVec3, hits: &mut [Hit], out: &mut Vec<Span>) {
        // By parameter, then triangle: the order does not depend on how they were found.
        hits.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let (mut crossings, mut winding) = (0, 0);
        let mut open: Option<(f64, DVec3)> = None;
        for &(t, _, facing, n) in hits.iter() {
            crossings += 1;
            winding += facing;
            let n = n.normalize_or(dir);
            match (open, self.inside(crossings, winding)) {
                (None, true) => {
                    let n = if n.dot(dir) > 0.0 { -n } else { n };
                    open = Some((t, n));
                }
                (Some((t0, n0)), false) => {
                    let n = if n.dot(dir) < 0.0 { -n } else { n };
                    if t > t0 {
                        out.push(Span { enter: t0, exit: t, enter_normal: n0, exit_normal: n });
                    }
                    open = None;
                }
                _ => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An octahedron with vertices on the axes at distance `r`, counter-clockwise from outside.
    pub(crate) fn octahedron(r: f64) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let v = vec![DVec3::X * r, -DVec3::X * r, DVec3::Y * r, -DVec3::Y * r, DVec3::Z * r, -DVec3::Z * r];
        let t = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        (v, t)
    }

    #[test]
    fn lines_through_edges_and_vertices_of_a_closed_mesh_count_once() {
        let (v, t) = octahedron(4.0);
        let m = MeshBrush::new(&v, &t, MeshRule::EvenOdd).unwrap();
        assert!(m.is_closed());
        let mut out = Vec::new();
        // Through the two vertices on the x axis, and through edges in the z = 0 plane.
        for (start, dir) in [
            (DVec3::new(-10.0, 0.0, 0.0), DVec3::X),
            (DVec3::new(-10.0, 1.0, 0.0), DVec3::X),
            (DVec3::new(-10.0, 0.0, 1.0), DVec3::X),
            (DVec3::new(0.0, -10.0, 0.0), DVec3::Y),
        ] {
            m.spans(DVec3::ZERO, start, dir, &mut out);
            assert_eq!(out.len(), 1, "line from {start}");
        }
        // Winding rule agrees on a consistently oriented closed mesh.
        let w = MeshBrush::new(&v, &t, MeshRule::NonZero).unwrap();
        w.spans(DVec3::ZERO, DVec3::new(-10.0, 0.5, 0.5), DVec3::X, &mut out);
        assert_eq!(out.len(), 1);
        assert!(w.contains(DVec3::ZERO, DVec3::new(0.5, 0.5, 0.5)));
        assert!(!w.contains(DVec3::ZERO, DVec3::new(3.5, 0.5, 0.5)));
    }

    /// A UV sphere whose vertices are snapped to half units, so that many grid lines at quarter
    /// steps pass exactly through its vertices and edges.
    fn snapped_sphere(radius: f64, rings: u32, segments: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let snap = |p: DVec3| (p * 2.0).round() / 2.0;
        let mut verts = vec![snap(DVec3::Z * radius), snap(-DVec3::Z * radius)];
        for r in 1..rings {
            let phi = std::f64::consts::PI * r as f64 / rings as f64;
            for k in 0..segments {
                let th = std::f64::consts::TAU * k as f64 / segments as f64;
                verts.push(snap(radius * DVec3::new(phi.sin() * th.cos(), phi.sin() * th.sin(), phi.cos())));
            }
        }
        let ring = |r: u32, k: u32| 2 + (r - 1) * segments + k % segments;
        let mut tris = Vec::new();
        for k in 0..segments {
            tris.push([0, ring(1, k), ring(1, k + 1)]);
            tris.push([1, ring(rings - 1, k + 1), ring(rings - 1, k)]);
            for r in 1..rings - 1 {
                tris.push([ring(r, k), ring(r + 1, k), ring(r + 1, k + 1)]);
                tris.push([ring(r, k), ring(r + 1, k + 1), ring(r, k + 1)]);
            }
        }
        (verts, tris)
    }

    #[test]
    fn the_bucket_grid_finds_exactly_the_hits_of_the_bvh() {
        let (v, mut t) = octahedron(4.0);
        let mut meshes = vec![(v.clone(), t.clone()), snapped_sphere(6.0, 12, 24)];
        // Open: the octahedron without one face.
        t.pop();
        meshes.push((v, t));
        // Slivers: a bipyramid of 400 long triangles (its grids across x and y are coarsened to
        // keep within the entry budget).
        let mut spiky = vec![DVec3::new(0.0, 0.0, 20.0), DVec3::new(0.0, 0.0, -20.0)];
        let mut fan = Vec::new();
        for k in 0..200u32 {
            let a = std::f64::consts::TAU * k as f64 / 200.0;
            spiky.push(DVec3::new(2.0 * a.cos(), 2.0 * a.sin(), 0.0));
            let (p, q) = (2 + k, 2 + (k + 1) % 200);
            fan.push([0, p, q]);
            fan.push([1, q, p]);
        }
        meshes.push((spiky, fan));
        // Flat: a square in the plane z = 1 (its footprint across x and y is a segment).
        let square = vec![
            DVec3::new(-2.0, -2.0, 1.0),
            DVec3::new(2.0, -2.0, 1.0),
            DVec3::new(2.0, 2.0, 1.0),
            DVec3::new(-2.0, 2.0, 1.0),
        ];
        meshes.push((square, vec![[0, 1, 2], [0, 2, 3]]));
        for (v, t) in meshes {
            let m = MeshBrush::new(&v, &t, MeshRule::EvenOdd).unwrap();
            let b = m.bounds();
            let mut lines_with_hits = 0;
            for axis in 0..3 {
                let (kx, ky) = ((axis + 1) % 3, (axis + 2) % 3);
                let mut d = DVec3::ZERO;
                d[axis] = 1.0;
                let steps = |k: usize| ((b.max[k] - b.min[k] + 2.0) * 4.0) as usize + 1;
                for i in 0..steps(kx) {
                    for j in 0..steps(ky) {
                        let mut o = DVec3::ZERO;
                        o[axis] = b.min[axis] - 3.0;
                        o[kx] = b.min[kx] - 1.0 + i as f64 * 0.25;
                        o[ky] = b.min[ky] - 1.0 + j as f64 * 0.25;
                        let (mut grid, mut bvh) = (Vec::new(), Vec::new());
                        m.grid_hits(axis, o, |t, tri, f, n| grid.push((t, tri, f, n)));
                        m.bvh_hits(o, d, |t, tri, f, n| bvh.push((t, tri, f, n)));
                        let order = |a: &Hit, b: &Hit| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
                        grid.sort_by(order);
                        bvh.sort_by(order);
                        assert_eq!(grid, bvh, "axis {axis}, line through {o}");
                        lines_with_hits += usize::from(!grid.is_empty());
                    }
                }
            }
            assert!(lines_with_hits > 20, "{lines_with_hits} lines hit the mesh");
            for grid in m.grids.iter().filter_map(|g| g.get().and_then(Option::as_ref)) {
                assert!(grid.tris.len() <= 16 * m.tris.len(), "the entry budget holds");
                assert!(format!("{grid:?}").starts_with("AxisGrid { dims: ["), "a short summary");
            }
        }
    }

    #[test]
    fn a_grid_that_would_be_too_large_leaves_the_lines_to_the_bvh() {
        // 200,000 copies of one triangle: every copy's box covers the whole footprint, so even
        // a grid coarsened eight times would list over 16 entries per triangle.
        let v = [DVec3::new(0.0, -5.0, -5.0), DVec3::new(0.0, 5.0, -5.0), DVec3::new(0.0, 0.0, 5.0)];
        let m = MeshBrush::new(&v, &vec![[0, 1, 2]; 200_000], MeshRule::EvenOdd).unwrap();
        let mut out = Vec::new();
        m.spans(DVec3::ZERO, DVec3::new(-3.0, 0.5, 0.5), DVec3::X, &mut out);
        assert!(matches!(m.grids[0].get(), Some(None)), "no grid across x");
        // An even number of crossings at one place: no span.
        assert!(out.is_empty());
        let mut hits = 0;
        m.grid_hits(0, DVec3::new(-3.0, 0.5, 0.5), |_, _, _, _| hits += 1);
        assert_eq!(hits, 200_000);
    }

    #[test]
    fn bad_meshes_are_errors() {
        assert_eq!(MeshBrush::new(&[], &[], MeshRule::EvenOdd).unwrap_err(), MeshError::Empty);
        let v = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert!(matches!(MeshBrush::new(&v, &[[0, 1, 7]], MeshRule::EvenOdd), Err(MeshError::IndexOutOfRange { .. })));
        assert_eq!(MeshBrush::new(&v, &[[0, 1, 1]], MeshRule::EvenOdd).unwrap_err(), MeshError::Empty);
        let nan = [DVec3::NAN, DVec3::X, DVec3::Y];
        assert_eq!(MeshBrush::new(&nan, &[[0, 1, 2]], MeshRule::EvenOdd).unwrap_err(), MeshError::NonFiniteVertex(0));
    }
}
