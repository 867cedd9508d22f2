//! Marching-cubes cases, generated rather than typed: for each of the 256 corner sign patterns,
//! the closed loops of cell edges that the surface passes through.
//!
//! Each face of the cell is cut independently by one rule that both cells sharing the face
//! apply identically: every run of inside corners (walking the face's corners in order) is cut
//! off by one segment from the crossing where the run ends to the crossing where it begins. On
//! an ambiguous face (two inside corners on a diagonal) the inside corners are therefore always
//! separated. The two cells that share a face walk it in opposite directions and so produce the
//! same segments with opposite directions, which makes the union of all cells' polygons a
//! closed, consistently oriented surface. In one cell every crossed edge ends one segment and
//! starts another, so the segments chain into closed loops.

use std::sync::OnceLock;

/// Corner `k` of a cell sits at `(k & 1, (k >> 1) & 1, (k >> 2) & 1)`.
pub(crate) fn corner_offset(k: usize) -> [usize; 3] {
    [k & 1, (k >> 1) & 1, (k >> 2) & 1]
}

/// A cell edge: its axis and the offset of its lower corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct CellEdge {
    pub(crate) axis: usize,
    pub(crate) lower: [usize; 3],
}

/// One loop of a case: cell edges in order, clockwise seen from outside the solid (the mesher
/// reverses it into counter-clockwise triangles), and how to triangulate it.
#[derive(Clone, Debug)]
pub(crate) struct Loop {
    pub(crate) edges: Vec<CellEdge>,
    /// Fan from this loop position: none of the fan's diagonals lies in a face of the cell, so
    /// no diagonal can coincide with an edge of the neighbouring cell. Such a position exists
    /// for every loop of every case (checked exhaustively by the tests).
    pub(crate) apex: usize,
}

/// The loops of one case.
pub(crate) type CaseLoops = Vec<Loop>;

/// Whether two cell edges lie in a common face of the cell.
fn share_face(a: CellEdge, b: CellEdge) -> bool {
    (0..3).any(|f| f != a.axis && f != b.axis && a.lower[f] == b.lower[f])
}

fn plan(edges: Vec<CellEdge>) -> Loop {
    let k = edges.len();
    let apex = (0..k)
        .find(|&i| (2..k - 1).all(|d| !share_face(edges[i], edges[(i + d) % k])))
        .expect("every marching-cubes loop has a fan apex without in-face diagonals");
    Loop { edges, apex }
}

fn edge_between(a: usize, b: usize) -> CellEdge {
    let (pa, pb) = (corner_offset(a), corner_offset(b));
    let axis = (0..3).find(|&i| pa[i] != pb[i]).expect("adjacent corners");
    let mut lower = pa;
    lower[axis] = 0;
    CellEdge { axis, lower }
}

/// The four corners of face (`axis`, `side`) in counter-clockwise order seen from outside the
/// cell.
fn face_corners(axis: usize, side: usize) -> [usize; 4] {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let at = |cu: usize, cv: usize| {
        let mut p = [0; 3];
        p[axis] = side;
        p[u] = cu;
        p[v] = cv;
        p[0] | (p[1] << 1) | (p[2] << 2)
    };
    let ccw = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)];
    if side == 1 { ccw } else { [ccw[0], ccw[3], ccw[2], ccw[1]] }
}

fn build(case: usize) -> CaseLoops {
    let inside = |k: usize| (case >> k) & 1 == 1;
    // Directed segments: (from edge, to edge).
    let mut segments: Vec<(CellEdge, CellEdge)> = Vec::new();
    for axis in 0..3 {
        for side in 0..2 {
            let c = face_corners(axis, side);
            for i in 0..4 {
                // A run of inside corners starts at c[i] when c[i-1] is outside.
                let prev = c[(i + 3) % 4];
                if !inside(c[i]) || inside(prev) {
                    continue;
                }
                let mut j = i;
                while inside(c[(j + 1) % 4]) {
                    j = (j + 1) % 4;
                }
                let begin = edge_between(prev, c[i]);
                let end = edge_between(c[j], c[(j + 1) % 4]);
                segments.push((end, begin));
            }
        }
    }
    let mut loops = Vec::new();
    while let Some((first, mut next)) = segments.pop() {
        let mut lp = vec![first];
        while next != first {
            lp.push(next);
            let i = segments.iter().position(|s| s.0 == next).expect("every crossed edge starts one segment");
            next = segments.swap_remove(i).1;
        }
        loops.push(plan(lp));
    }
    loops
}

/// The loops of every case, built once.
pub(crate) fn cases() -> &'static [CaseLoops] {
    static CASES: OnceLock<Vec<CaseLoops>> = OnceLock::new();
    CASES.get_or_init(|| (0..256).map(build).collect())
}

/// One edge of a cell as a triangle names it: its axis (0 x, 1 y, 2 z) and its lower corner's
/// offset in the cell.
pub type TriangleEdge = (usize, [usize; 3]);

/// The triangles [`crate::mesh_block`] makes in a cell of `case` (bit `k` set: corner `k`,
/// at `(k & 1, (k >> 1) & 1, (k >> 2) & 1)`, is inside), in the order it makes them, each as
/// the three cell edges its vertices lie on, counter-clockwise seen from outside: what a GPU
/// mesher needs to make the same mesh.
pub fn case_triangles(case: u8) -> Vec<[TriangleEdge; 3]> {
    let mut out = Vec::new();
    for lp in &cases()[case as usize] {
        let e: Vec<TriangleEdge> = lp.edges.iter().map(|e| (e.axis, e.lower)).collect();
        let (k, a) = (e.len(), lp.apex);
        for d in 1..k - 1 {
            // As `mesh_block`: [apex, q, p] with p = loop[a + d], q = loop[a + d + 1].
            out.push([e[a], e[(a + d + 1) % k], e[(a + d) % k]]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn case_triangles_fan_each_loop_and_cross_only_crossed_edges() {
        let mut most = 0;
        for case in 0..=255u8 {
            let tris = case_triangles(case);
            let edges: usize = cases()[case as usize].iter().map(|l| l.edges.len()).sum();
            let loops = cases()[case as usize].len();
            assert_eq!(tris.len(), edges - 2 * loops, "case {case}");
            let inside = |c: [usize; 3]| (case >> (c[0] | (c[1] << 1) | (c[2] << 2))) & 1 == 1;
            for (axis, lower) in tris.iter().flatten() {
                let mut upper = *lower;
                upper[*axis] += 1;
                assert_ne!(inside(*lower), inside(upper), "case {case}: edge {axis} {lower:?} is not crossed");
            }
            most = most.max(tris.len());
        }
        assert_eq!(most, 5, "a cell makes at most five triangles");
    }

    #[test]
    fn every_crossed_edge_appears_in_exactly_one_loop_of_its_case() {
        for (case, loops) in cases().iter().enumerate() {
            let inside = |k: usize| (case >> k) & 1 == 1;
            let mut seen = Vec::new();
            for lp in loops {
                assert!(lp.edges.len() >= 3, "case {case}: loop {lp:?}");
                seen.extend(lp.edges.iter().copied());
            }
            let mut crossed = 0;
            for a in 0..8 {
                for b in a + 1..8 {
                    let (pa, pb) = (corner_offset(a), corner_offset(b));
                    let d: usize = (0..3).map(|i| pa[i].abs_diff(pb[i])).sum();
                    if d == 1 && inside(a) != inside(b) {
                        crossed += 1;
                        let e = edge_between(a, b);
                        assert_eq!(seen.iter().filter(|&&s| s == e).count(), 1, "case {case} edge {e:?}");
                    }
                }
            }
            assert_eq!(seen.len(), crossed);
        }
        assert!(cases()[0].is_empty() && cases()[255].is_empty());
        let longest = cases().iter().flatten().map(|l| l.edges.len()).max();
        assert_eq!(longest, Some(7));
    }
}
