//! A brush from a closed triangle mesh, answered by ray casting along grid lines through a BVH.
//!
//! Ray–triangle tests use a watertight formulation (a shear into the ray's frame, then 2-D edge
//! functions) with a top-left tie rule: a line through a shared edge or vertex of a closed mesh
//! is counted exactly once where it crosses the surface, and zero or two times where it only
//! grazes it, so inside/outside never flips spuriously.
//!
//! Inside is decided by [`MeshRule`]. A mesh that is not closed (holes, unwelded vertices) is
//! still accepted: along each line an unmatched last crossing is ignored (the line is outside
//! after it), node states are taken from the x lines (the predicate is: the node lies in a span
//! of the x line through it) and the volume repairs the y and z lines to match, so the result is a
//! consistent solid close to what the mesh encloses, never a crash.

use std::collections::HashMap;

use glam::DVec3;
use thiserror::Error;

use super::{Aabb, Brush, Span};

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
        Ok(MeshBrush { tris, nodes, rule, closed, bounds })
    }

    /// Whether every edge is shared by exactly two triangles (by vertex index).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Calls `hit(t, facing)` for every triangle the line `o + t d` crosses (any `t`), where
    /// `facing` is +1 when the triangle's winding faces against `d` (the line enters) and −1
    /// otherwise.
    fn for_each_hit(&self, o: DVec3, d: DVec3, mut hit: impl FnMut(f64, i32, DVec3)) {
        let ray = RayFrame::new(o, d);
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
                for tri in &self.tris[node.first as usize..(node.first + node.count) as usize] {
                    if let Some((t, facing)) = ray.intersect(tri) {
                        hit(t, facing, (tri[1] - tri[0]).cross(tri[2] - tri[0]));
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
    fn intersect(&self, tri: &[DVec3; 3]) -> Option<(f64, i32)> {
        let p = tri.map(|v| self.project(v));
        // e[k]: edge function of the directed edge p[k] -> p[k+1].
        let e = [0, 1, 2].map(|k| {
            let (a, b) = (p[k], p[(k + 1) % 3]);
            a.x * b.y - a.y * b.x
        });
        let det = e[0] + e[1] + e[2];
        if det == 0.0 {
            return None;
        }
        let sgn = det.signum();
        for k in 0..3 {
            let ek = e[k] * sgn;
            if ek > 0.0 {
                continue;
            }
            if ek < 0.0 {
                return None;
            }
            // On the edge: the top-left rule takes exactly one of the two triangles sharing it.
            let (a, b) = (p[k], p[(k + 1) % 3]);
            let (dx, dy) = ((b.x - a.x) * sgn, (b.y - a.y) * sgn);
            if !(dy < 0.0 || (dy == 0.0 && dx < 0.0)) {
                return None;
            }
        }
        // Edge k is opposite vertex k + 2.
        let t = (e[1] * p[0].z + e[2] * p[1].z + e[0] * p[2].z) / det;
        // det > 0: counter-clockwise in the sheared frame, i.e. the normal points back along the
        // line in a right-handed (kx, ky, kz) frame.
        Some((t, if det > 0.0 { 1 } else { -1 }))
    }
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
        let o = origin + start;
        let mut hits: Vec<(f64, i32, DVec3)> = Vec::new();
        self.for_each_hit(o, dir, |t, facing, n| hits.push((t, facing, n)));
        hits.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut crossings, mut winding) = (0, 0);
        let mut open: Option<(f64, DVec3)> = None;
        for (t, facing, n) in hits {
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
        true
    }

    fn lines_agree(&self) -> bool {
        self.closed
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
