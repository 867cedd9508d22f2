//! A chunk's nodes and edges at one level held densely, for the rare work on chunks whose
//! neighbours differ in level (seams, level changes): node states and, per axis, the crossing of
//! each edge by its lower node.

use glam::DVec3;

use crate::axis::{Axis, compose};
use crate::chunk::{Built, ChunkBuilder, ChunkView, WorkLine};
use crate::coords::{Level, quantize_steps};
use crate::level::face::{FaceGrid, NONE, Packed, nrm, pack, pos};
use crate::level::read::LineReader;
use crate::normal::{pack_normal, unpack_normal};

/// Nodes `0..=n` on each axis of one chunk (its own nodes and its apron) at `level`.
#[derive(Clone, Debug)]
pub(crate) struct Dense {
    pub(crate) level: Level,
    pub(crate) n: usize,
    pub(crate) states: Vec<bool>,
    /// Per axis, the crossing of the edge from node `index(p)` to the next node along the axis.
    pub(crate) cross: [Vec<Packed>; 3],
}

impl Dense {
    pub(crate) fn new(level: Level) -> Self {
        let n = level.cells();
        let m = (n + 1).pow(3);
        Dense { level, n, states: vec![false; m], cross: [vec![NONE; m], vec![NONE; m], vec![NONE; m]] }
    }

    #[inline]
    pub(crate) fn index(&self, p: [usize; 3]) -> usize {
        let m = self.n + 1;
        p[0] + m * (p[1] + m * p[2])
    }

    #[inline]
    pub(crate) fn state(&self, p: [usize; 3]) -> bool {
        self.states[self.index(p)]
    }

    #[inline]
    pub(crate) fn crossing(&self, axis: Axis, p: [usize; 3]) -> Packed {
        self.cross[axis.index()][self.index(p)]
    }

    /// Fills the lines the chunk of `view` owns (`u, v < n` on every family: its own nodes,
    /// the apron nodes its lines end on, and its cells), read at this level.
    pub(crate) fn read_own(&mut self, view: ChunkView<'_>) {
        self.read_own_with(|axis| LineReader::new(view, axis));
    }

    /// [`Dense::read_own`] through readers `reader(axis)` gives.
    pub(crate) fn read_own_with<'a>(&mut self, mut reader_for: impl FnMut(Axis) -> LineReader<'a>) {
        let n = self.n;
        let mut line = WorkLine::EMPTY;
        for axis in Axis::ALL {
            let mut reader = reader_for(axis);
            for v in 0..n {
                for u in 0..n {
                    let ok = reader.read(u, v, self.level, &mut line);
                    debug_assert!(ok, "own lines are read at or below the chunk's level");
                    self.put_line(axis, u, v, &line);
                }
            }
        }
    }

    /// Writes one line (states `0..=n`, crossings where they change).
    pub(crate) fn put_line(&mut self, axis: Axis, u: usize, v: usize, line: &WorkLine) {
        let n = self.n;
        let changes = line.changes(n);
        for t in 0..=n {
            let k = self.index(compose(axis, t, u, v));
            self.states[k] = (line.states >> t) & 1 == 1;
            if t < n {
                self.cross[axis.index()][k] =
                    if (changes >> t) & 1 == 1 { pack(line.pos[t], line.nrm[t]) } else { NONE };
            }
        }
    }

    /// Line `(u, v)` along `axis` (states `0..=n`, crossings where they change).
    pub(crate) fn line(&self, axis: Axis, u: usize, v: usize) -> WorkLine {
        let mut w = WorkLine::EMPTY;
        for t in 0..=self.n {
            let p = compose(axis, t, u, v);
            w.states |= (self.state(p) as u128) << t;
            if t < self.n {
                let c = self.crossing(axis, p);
                if c != NONE {
                    w.pos[t] = pos(c);
                    w.nrm[t] = nrm(c);
                }
            }
        }
        w
    }

    /// Writes face grid `g` (at this level) as the plane at coordinate `c` along its normal.
    pub(crate) fn put_face(&mut self, g: &FaceGrid, c: usize) {
        debug_assert_eq!(g.level, self.level);
        let (ua, va) = g.normal.across();
        for j in 0..=self.n {
            for i in 0..=self.n {
                let k = self.index(compose(g.normal, c, i, j));
                self.states[k] = g.state(i, j);
                if i < self.n {
                    self.cross[ua.index()][k] = g.crossing((0, i, j));
                }
                if j < self.n {
                    self.cross[va.index()][k] = g.crossing((1, i, j));
                }
            }
        }
    }

    /// The plane at coordinate `c` along `normal` as a face grid.
    pub(crate) fn face(&self, normal: Axis, c: usize) -> FaceGrid {
        let (ua, va) = normal.across();
        let mut g = FaceGrid::uniform(self.level, normal, false);
        for j in 0..=self.n {
            for i in 0..=self.n {
                let k = self.index(compose(normal, c, i, j));
                g.set_state(i, j, self.states[k]);
                if i < self.n {
                    g.set_crossing((0, i, j), self.cross[ua.index()][k]);
                }
                if j < self.n {
                    g.set_crossing((1, i, j), self.cross[va.index()][k]);
                }
            }
        }
        g
    }

    /// Gives every edge whose nodes differ a crossing and takes it off every edge whose nodes
    /// agree (as [`FaceGrid::make_consistent`]). Returns how many edges changed.
    pub(crate) fn make_consistent(&mut self) -> usize {
        let n = self.n;
        let mut changed = 0;
        for axis in Axis::ALL {
            let a = axis.index();
            for z in 0..=n {
                for y in 0..=n {
                    for x in 0..=n {
                        let p = [x, y, z];
                        if p[a] == n {
                            continue;
                        }
                        let mut p1 = p;
                        p1[a] += 1;
                        let k = self.index(p);
                        let (s0, s1) = (self.states[k], self.state(p1));
                        let c = self.cross[a][k];
                        if s0 == s1 && c != NONE {
                            self.cross[a][k] = NONE;
                            changed += 1;
                        } else if s0 != s1 && c == NONE {
                            let e = p[a];
                            let q =
                                quantize_steps((e as f64 + 0.5) * self.level.steps_per_cell() as f64, e, self.level);
                            let normal = self.normal_near(axis, p, s0);
                            self.cross[a][k] = pack(q, normal);
                            changed += 1;
                        }
                    }
                }
            }
        }
        changed
    }

    /// The mean normal of the crossings on the other edges at the two ends of an edge, or the
    /// edge's direction out of the solid.
    fn normal_near(&self, axis: Axis, p: [usize; 3], lower_inside: bool) -> crate::normal::PackedNormal {
        let n = self.n;
        let mut p1 = p;
        p1[axis.index()] += 1;
        let mut sum = DVec3::ZERO;
        for end in [p, p1] {
            for b in Axis::ALL {
                if b == axis {
                    continue;
                }
                let i = b.index();
                for lower in [end[i].checked_sub(1), (end[i] < n).then_some(end[i])] {
                    let Some(li) = lower else { continue };
                    let mut q = end;
                    q[i] = li;
                    let c = self.crossing(b, q);
                    if c != NONE {
                        sum += unpack_normal(nrm(c));
                    }
                }
            }
        }
        if sum.length_squared() < 1e-12 {
            let dir = axis.unit();
            sum = if lower_inside { dir } else { -dir };
        }
        pack_normal(sum)
    }

    /// The chunk whose lines are this grid's own lines (`u, v < n`).
    pub(crate) fn build(&self) -> Built {
        let n = self.n;
        let mut b = ChunkBuilder::default();
        b.begin(self.level);
        for axis in Axis::ALL {
            b.begin_axis(axis);
            for v in 0..n {
                for u in 0..n {
                    b.push_work(&self.line(axis, u, v), n);
                }
            }
        }
        b.finish()
    }
}
