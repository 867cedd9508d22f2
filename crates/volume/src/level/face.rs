//! One face plane of a chunk at one level, and the face table that refines it by one level (the
//! paper's Fig. 10).
//!
//! The surface meets a cell face along the marching-cubes contour of that face: every run of
//! inside corners (walking the corners in order) is cut off by a straight segment between the
//! crossings where the run ends and begins, so on a face with two inside corners on a diagonal
//! they are separated (the rule `strata-mesh`'s case table is generated from). Refining the face
//! keeps that contour exactly: a new node takes the side of the contour it lies on, and a new
//! edge whose two nodes differ gets its crossing where the contour cuts it. The four inside
//! corners of a diagonal face are cut off by segments that never reach the face's centre (the
//! segment from `(a, 0)` to `(0, b)` with `a, b < 1` passes below `(½, ½)`), so each new edge is
//! cut at most once and the refined face's own contour, by the same rule, is the coarse contour
//! with extra vertices on it (checked for all 16 cases by the tests).

use glam::DVec3;

use crate::axis::Axis;
use crate::coords::{Level, LocalPos, quantize_steps};
use crate::normal::{PackedNormal, pack_normal, unpack_normal};

/// A crossing packed as `position << 16 | normal`; [`NONE`]: no crossing (a stored position is
/// never 0, which lies on a node).
pub(crate) type Packed = u32;
/// No crossing.
pub(crate) const NONE: Packed = 0;

#[inline]
pub(crate) fn pack(q: LocalPos, normal: PackedNormal) -> Packed {
    (q.0 as u32) << 16 | normal.0 as u32
}

#[inline]
pub(crate) fn pos(c: Packed) -> LocalPos {
    LocalPos((c >> 16) as u16)
}

#[inline]
pub(crate) fn nrm(c: Packed) -> PackedNormal {
    PackedNormal(c as u16)
}

/// Node states and in-plane crossings of one plane of a chunk at one level. The plane is normal
/// to `normal`; its nodes `(i, j)`, `i, j` in `0..=n`, run along `u` and `v`
/// (`normal.across()`), and crossing positions are chunk-local along their edge's axis.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FaceGrid {
    pub(crate) level: Level,
    pub(crate) n: usize,
    pub(crate) normal: Axis,
    pub(crate) states: Vec<bool>,
    /// The crossing on the edge along `u` from node `(i, j)`, at `i + (n + 1) j` (`i < n`).
    pub(crate) cu: Vec<Packed>,
    /// The crossing on the edge along `v` from node `(i, j)`, at `i + (n + 1) j` (`j < n`).
    pub(crate) cv: Vec<Packed>,
}

/// One in-plane edge of a face grid: direction (0: along `u`, 1: along `v`) and lower node.
pub(crate) type FaceEdge = (u8, usize, usize);

/// Every edge of a face grid of `n` cells: direction, lower node and upper node.
fn edges(n: usize) -> impl Iterator<Item = (u8, usize, usize, usize, usize)> {
    (0..2u8).flat_map(move |d| {
        (0..=n).flat_map(move |j| {
            (0..=n).filter_map(move |i| {
                let (i1, j1) = if d == 0 { (i + 1, j) } else { (i, j + 1) };
                (i1 <= n && j1 <= n).then_some((d, i, j, i1, j1))
            })
        })
    })
}

impl FaceGrid {
    /// A plane of one state without crossings.
    pub(crate) fn uniform(level: Level, normal: Axis, inside: bool) -> Self {
        let n = level.cells();
        let m = (n + 1) * (n + 1);
        FaceGrid { level, n, normal, states: vec![inside; m], cu: vec![NONE; m], cv: vec![NONE; m] }
    }

    #[inline]
    pub(crate) fn idx(&self, i: usize, j: usize) -> usize {
        i + (self.n + 1) * j
    }

    #[inline]
    pub(crate) fn state(&self, i: usize, j: usize) -> bool {
        self.states[self.idx(i, j)]
    }

    #[inline]
    pub(crate) fn set_state(&mut self, i: usize, j: usize, s: bool) {
        let k = self.idx(i, j);
        self.states[k] = s;
    }

    /// The crossing on `edge`.
    #[inline]
    pub(crate) fn crossing(&self, (d, i, j): FaceEdge) -> Packed {
        let k = self.idx(i, j);
        if d == 0 { self.cu[k] } else { self.cv[k] }
    }

    #[inline]
    pub(crate) fn set_crossing(&mut self, (d, i, j): FaceEdge, c: Packed) {
        let k = self.idx(i, j);
        if d == 0 {
            self.cu[k] = c;
        } else {
            self.cv[k] = c;
        }
    }

    /// The world axis of direction `d`.
    pub(crate) fn dir_axis(&self, d: u8) -> Axis {
        let (u, v) = self.normal.across();
        if d == 0 { u } else { v }
    }

    /// Gives every edge whose nodes differ a crossing (at its middle, with a normal from the
    /// crossings around it) and takes the crossing off every edge whose nodes agree. Returns
    /// how many edges changed. A plane read from consistent lists changes only where its
    /// border lines were replaced by a coarser neighbour's.
    pub(crate) fn make_consistent(&mut self) -> usize {
        let mut changed = 0;
        for (d, i, j, i1, j1) in edges(self.n) {
            let (a, b) = (self.state(i, j), self.state(i1, j1));
            let c = self.crossing((d, i, j));
            if a == b && c != NONE {
                self.set_crossing((d, i, j), NONE);
                changed += 1;
            } else if a != b && c == NONE {
                let e = if d == 0 { i } else { j };
                let q = quantize_steps((e as f64 + 0.5) * self.level.steps_per_cell() as f64, e, self.level);
                let normal = self.normal_near((d, i, j), a);
                self.set_crossing((d, i, j), pack(q, normal));
                changed += 1;
            }
        }
        changed
    }

    /// A normal for a crossing added on `edge`: the mean of the crossings on the edges that meet
    /// its two nodes, or the edge's direction (out of the solid) where none does.
    fn normal_near(&self, (d, i, j): FaceEdge, lower_inside: bool) -> PackedNormal {
        let n = self.n;
        let mut sum = DVec3::ZERO;
        let ends = if d == 0 { [(i, j), (i + 1, j)] } else { [(i, j), (i, j + 1)] };
        for (a, b) in ends {
            for e in [(0u8, a.wrapping_sub(1), b), (0, a, b), (1, a, b.wrapping_sub(1)), (1, a, b)] {
                let (_, ei, ej) = e;
                let ok = if e.0 == 0 { ei < n && ej <= n } else { ei <= n && ej < n };
                if ok && e != (d, i, j) {
                    let c = self.crossing(e);
                    if c != NONE {
                        sum += unpack_normal(nrm(c));
                    }
                }
            }
        }
        if sum.length_squared() < 1e-12 {
            let dir = self.dir_axis(d).unit();
            sum = if lower_inside { dir } else { -dir };
        }
        pack_normal(sum)
    }

    /// The crossings of cell `(i, j)`'s contour, in the rule's pairs: for each run of inside
    /// corners, (edge where the run ends, edge where it begins).
    pub(crate) fn cell_segments(&self, i: usize, j: usize) -> Vec<(FaceEdge, FaceEdge)> {
        // Corners in order around the cell, and the edge from corner k to corner k + 1.
        let st = [self.state(i, j), self.state(i + 1, j), self.state(i + 1, j + 1), self.state(i, j + 1)];
        let edges: [FaceEdge; 4] = [(0, i, j), (1, i + 1, j), (0, i, j + 1), (1, i, j)];
        let mut out = Vec::new();
        for k in 0..4 {
            if st[k] && !st[(k + 1) % 4] {
                let mut s = k;
                while st[(s + 3) % 4] && (s + 3) % 4 != k {
                    s = (s + 3) % 4;
                }
                out.push((edges[k], edges[(s + 3) % 4]));
            }
        }
        out
    }

    /// Position in fixed-point steps `(u, v)` of the crossing on `edge`.
    fn point(&self, e: FaceEdge) -> [f64; 2] {
        let s = self.level.steps_per_cell() as f64;
        let q = pos(self.crossing(e)).0 as f64;
        let (d, i, j) = e;
        if d == 0 { [q, j as f64 * s] } else { [i as f64 * s, q] }
    }

    /// The face one level finer (`2n` cells) whose contour is this face's contour (see the
    /// module's documentation). The face must be consistent ([`FaceGrid::make_consistent`]).
    pub(crate) fn refine(&self) -> FaceGrid {
        let n = self.n;
        let fine = Level::new(self.level.get() + 1).expect("refined below the maximum level");
        let mut f = FaceGrid::uniform(fine, self.normal, false);
        let s = self.level.steps_per_cell() as f64;
        for j in 0..=n {
            for i in 0..=n {
                f.set_state(2 * i, 2 * j, self.state(i, j));
            }
        }
        // Coarse edges: the crossing stays where it is, in the half it lies in; the middle node
        // takes the state of the other half's far end.
        for (d, i, j, i1, j1) in edges(n) {
            let (a, b) = (self.state(i, j), self.state(i1, j1));
            let (mi, mj) = (i + i1, j + j1);
            let c = self.crossing((d, i, j));
            if c == NONE {
                f.set_state(mi, mj, a);
                continue;
            }
            let e = if d == 0 { i } else { j };
            let mid = (e as f64 + 0.5) * s;
            // A position on the middle node (only in files from before levels could change)
            // moves two steps down.
            let q = if pos(c).0 as f64 == mid { LocalPos(pos(c).0 - 2) } else { pos(c) };
            let (state, lower) = if (q.0 as f64) < mid { (b, (2 * i, 2 * j)) } else { (a, (mi, mj)) };
            f.set_state(mi, mj, state);
            f.set_crossing((d, lower.0, lower.1), pack(q, nrm(c)));
        }
        for j in 0..n {
            for i in 0..n {
                self.refine_cell(i, j, &mut f);
            }
        }
        f
    }

    /// The centre node of cell `(i, j)` in `f` and the four half-edges that meet it.
    fn refine_cell(&self, i: usize, j: usize, f: &mut FaceGrid) {
        let s = self.level.steps_per_cell() as f64;
        let segs: Vec<([f64; 2], [f64; 2], PackedNormal, PackedNormal)> = self
            .cell_segments(i, j)
            .into_iter()
            .map(|(a, b)| (self.point(a), self.point(b), nrm(self.crossing(a)), nrm(self.crossing(b))))
            .collect();
        let (ci, cj) = (2 * i + 1, 2 * j + 1);
        if segs.is_empty() {
            f.set_state(ci, cj, self.state(i, j));
            return;
        }
        let (u0, v0) = (i as f64 * s, j as f64 * s);
        let (um, vm) = (u0 + s / 2.0, v0 + s / 2.0);
        // Where the segments cut the line of constant coordinate `k` (0: u, 1: v) = `at`,
        // between `lo` and `hi` on the other coordinate: (other coordinate, normal).
        let cut = |k: usize, at: f64, lo: f64, hi: f64| -> Vec<(f64, DVec3)> {
            segs.iter()
                .filter_map(|&(p, q, np, nq)| {
                    if (p[k] - at) * (q[k] - at) >= 0.0 {
                        return None;
                    }
                    let t = (at - p[k]) / (q[k] - p[k]);
                    let o = p[1 - k] + t * (q[1 - k] - p[1 - k]);
                    (o > lo && o < hi).then(|| (o, unpack_normal(np) * (1.0 - t) + unpack_normal(nq) * t))
                })
                .collect()
        };
        // The centre's side: from the bottom middle node, one state change per cut below it.
        let below = cut(0, um, v0, vm).len();
        let centre = f.state(ci, 2 * j) ^ (below % 2 == 1);
        f.set_state(ci, cj, centre);
        // The four half-edges: (edge in f, line coordinate k and value, range, fine edge index).
        let halves: [(FaceEdge, usize, f64, f64, f64, usize); 4] = [
            ((1, ci, 2 * j), 0, um, v0, vm, 2 * j),
            ((1, ci, cj), 0, um, vm, v0 + s, 2 * j + 1),
            ((0, 2 * i, cj), 1, vm, u0, um, 2 * i),
            ((0, ci, cj), 1, vm, um, u0 + s, 2 * i + 1),
        ];
        for (edge, k, at, lo, hi, fe) in halves {
            let (d, ei, ej) = edge;
            let (ei1, ej1) = if d == 0 { (ei + 1, ej) } else { (ei, ej + 1) };
            if f.state(ei, ej) == f.state(ei1, ej1) {
                continue;
            }
            let (o, normal) =
                cut(k, at, lo, hi).into_iter().next().unwrap_or(((lo + hi) / 2.0, unpack_normal(segs[0].2)));
            f.set_crossing(edge, pack(quantize_steps(o, fe, f.level), pack_normal(normal)));
        }
    }

    /// This face refined to `level` (at or above its own).
    pub(crate) fn refine_to(self, level: Level) -> FaceGrid {
        let mut g = self;
        while g.level < level {
            g = g.refine();
        }
        g
    }

    /// For each segment of the contour of cell `(i, j)` of `self`: its two crossings and the
    /// crossings of `fine` (this face refined, [`FaceGrid::refine_to`]) strictly inside the
    /// cell that the refined contour passes through between them, in order from the first.
    pub(crate) fn chains(&self, fine: &FaceGrid, i: usize, j: usize) -> Vec<(FaceEdge, FaceEdge, Vec<FaceEdge>)> {
        let r = fine.n / self.n;
        let (fi0, fj0) = (i * r, j * r);
        // Links between fine crossings inside the coarse cell.
        let mut links: Vec<(FaceEdge, FaceEdge)> = Vec::new();
        for fj in fj0..fj0 + r {
            for fi in fi0..fi0 + r {
                links.extend(fine.cell_segments(fi, fj));
            }
        }
        let on_border = |(d, a, b): FaceEdge| {
            if d == 0 { b == fj0 || b == fj0 + r } else { a == fi0 || a == fi0 + r }
        };
        // The fine edge on coarse edge `e` that holds its crossing.
        let fine_of = |(d, a, b): FaceEdge| -> Option<FaceEdge> {
            (0..r)
                .map(|k| if d == 0 { (0, a * r + k, b * r) } else { (1, a * r, b * r + k) })
                .find(|&fe| fine.crossing(fe) != NONE)
        };
        let mut out = Vec::new();
        for (a, b) in self.cell_segments(i, j) {
            let Some(mut cur) = fine_of(a) else { continue };
            let mut prev: Option<FaceEdge> = None;
            let mut inner = Vec::new();
            for _ in 0..4 * r * r + 4 {
                let next = links
                    .iter()
                    .filter_map(|&(p, q)| {
                        if p == cur && Some(q) != prev {
                            Some(q)
                        } else if q == cur && Some(p) != prev {
                            Some(p)
                        } else {
                            None
                        }
                    })
                    .next();
                let Some(next) = next else { break };
                if on_border(next) {
                    break;
                }
                inner.push(next);
                prev = Some(cur);
                cur = next;
            }
            out.push((a, b, inner));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-cell face at `level` with the given corner states and crossings at fractions `t`
    /// of each edge whose corners differ.
    fn one_cell(level: Level, states: [bool; 4], t: [f64; 4]) -> FaceGrid {
        let mut g = FaceGrid::uniform(level, Axis::Z, false);
        let s = level.steps_per_cell() as f64;
        for (k, (i, j)) in [(0, 0), (1, 0), (1, 1), (0, 1)].into_iter().enumerate() {
            g.set_state(i, j, states[k]);
        }
        let edges: [FaceEdge; 4] = [(0, 0, 0), (1, 1, 0), (0, 0, 1), (1, 0, 0)];
        for (k, e) in edges.into_iter().enumerate() {
            let (a, b) = match k {
                0 => (states[0], states[1]),
                1 => (states[1], states[2]),
                2 => (states[3], states[2]),
                _ => (states[0], states[3]),
            };
            if a != b {
                g.set_crossing(e, pack(quantize_steps(t[k] * s, 0, level), pack_normal(DVec3::X)));
            }
        }
        // The rest of the grid around the cell: made consistent, not looked at.
        g.make_consistent();
        g
    }

    fn consistent(g: &FaceGrid) -> bool {
        let mut c = g.clone();
        c.make_consistent() == 0
    }

    #[test]
    fn every_case_refines_to_a_consistent_face_whose_contour_runs_through_the_old_crossings() {
        let ts = [0.1, 0.3, 0.45, 0.55, 0.7, 0.93];
        for case in 0..16u32 {
            let states = [0, 1, 2, 3].map(|k| case >> k & 1 == 1);
            for (a, ta) in ts.iter().enumerate() {
                for tb in &ts[a..] {
                    let t = [*ta, *tb, 1.0 - ta, 1.0 - tb];
                    for from in [Level::COARSEST, Level::BASE] {
                        let g = one_cell(from, states, t);
                        assert!(consistent(&g));
                        for to in Level::ALL.into_iter().filter(|&l| l > from) {
                            let f = g.clone().refine_to(to);
                            assert!(consistent(&f), "case {case:04b}, t {t:?}: refined face inconsistent");
                            let chains = g.chains(&f, 0, 0);
                            assert_eq!(chains.len(), g.cell_segments(0, 0).len());
                            let links = f.cell_segments_all();
                            let linked = |a: FaceEdge, b: FaceEdge| {
                                links.iter().any(|&(p, q)| (p, q) == (a, b) || (q, p) == (a, b))
                            };
                            let fine_on =
                                |c: FaceEdge| -> FaceEdge {
                                    let r = f.n / g.n;
                                    (0..r)
                                        .map(|k| {
                                            if c.0 == 0 { (0, c.1 * r + k, c.2 * r) } else { (1, c.1 * r, c.2 * r + k) }
                                        })
                                        .find(|&e| f.crossing(e) != NONE)
                                        .expect("a coarse crossing stays on its edge")
                                };
                            for (pa, pb, inner) in chains {
                                let mut path = vec![fine_on(pa)];
                                path.extend(inner);
                                path.push(fine_on(pb));
                                for w in path.windows(2) {
                                    assert!(
                                        linked(w[0], w[1]),
                                        "case {case:04b}, t {t:?}: chain {path:?} is not the refined contour"
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    impl FaceGrid {
        fn cell_segments_all(&self) -> Vec<(FaceEdge, FaceEdge)> {
            let mut v = Vec::new();
            for j in 0..self.n {
                for i in 0..self.n {
                    v.extend(self.cell_segments(i, j));
                }
            }
            v
        }
    }

    #[test]
    fn refined_crossings_lie_on_the_coarse_segments() {
        // Two adjacent inside corners: the segment from the left edge to the right edge.
        let g = one_cell(Level::BASE, [true, true, false, false], [0.5, 0.2, 0.5, 0.6]);
        let f = g.clone().refine();
        let s = f.level.steps_per_cell() as f64;
        let (p, q) = (g.point((1, 0, 0)), g.point((1, 1, 0)));
        for e in [(1u8, 1usize, 0usize), (1, 1, 1)] {
            if f.crossing(e) != NONE {
                let v = pos(f.crossing(e)).0 as f64;
                let u = s; // the middle column
                let t = (u - p[0]) / (q[0] - p[0]);
                let expect = p[1] + t * (q[1] - p[1]);
                assert!((v - expect).abs() <= 2.0, "{v} vs {expect}");
            }
        }
    }
}
