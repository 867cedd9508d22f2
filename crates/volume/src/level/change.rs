//! Raising and lowering a chunk's stored level (the paper's VI-A and VI-B).
//!
//! Raising builds the finer lists from the chunk's own data, one cell at a time:
//! - nodes and edges on the planes of the old cells' faces come from the face table
//!   ([`FaceGrid::refine`]): old nodes keep their states and old crossings their exact
//!   positions, new nodes take the side of the face's contour they lie on, and new edges are cut
//!   where the contour cuts them;
//! - the node at a cell's centre and the six half-edges through it (the line through the
//!   centre, which no face table reaches) are intersected with the cell's surface, estimated
//!   from its Hermite data: the planes of its crossings, weighted by inverse squared distance;
//! - the faces the chunk's lines end on keep the states the lines end in; where the neighbour
//!   there is already as fine as the new level, its own nodes are taken instead.
//!
//! Node states are decided first and crossings only where the two ends of an edge differ, so the
//! result satisfies every invariant by construction. Old crossings never sit on a new node
//! ([`crate::coords::quantize_into_edge`]), so lowering again gives back the old lists bit for
//! bit. A finer neighbour before the chunk, whose lines end on the chunk's first face, has those
//! lines' last cells made to end as the refined face now says.
//!
//! Lowering keeps every second line and node and, on each coarse edge whose ends differ, the one
//! crossing of the two fine edges it covers.

use glam::DVec3;

use crate::axis::{Axis, compose};
use crate::chunk::{Built, Chunk, ChunkBuilder, ChunkView, WorkLine};
use crate::coords::{ChunkKey, Level, quantize_steps};
use crate::level::dense::Dense;
use crate::level::face::{NONE, nrm, pack, pos};
use crate::level::read::{LevelMap, LineReader, effective_face};
use crate::normal::{pack_normal, unpack_normal};
use crate::volume::Volume;

/// The chunk at `key` (lists at level `l`) raised to `l + 1`, and the finer neighbours before it
/// whose last cells changed.
pub(crate) fn raise(volume: &Volume, key: ChunkKey) -> Option<(Built, Vec<(ChunkKey, Built)>)> {
    let s = source(volume, key)?;
    if s.level.get() >= crate::coords::MAX_LEVEL {
        return None;
    }
    let r = refine(volume, key, &s);
    let built = r.build();
    let mut neighbours = Vec::new();
    for normal in Axis::ALL {
        let before = key.offset(-normal.unit_i64().as_ivec3());
        if let Some(b) = end_lines_on(volume, before, normal, &r) {
            neighbours.push((before, b));
        }
    }
    Some((built, neighbours))
}

/// The list chunk at `key` refined to `level` (at or above its own) without storing anything:
/// what raising it would store, with its apron (for tools that work at a finer level than the
/// chunk's).
pub(crate) fn refined(volume: &Volume, key: ChunkKey, level: Level) -> Option<Dense> {
    let mut d = source(volume, key)?;
    while d.level < level {
        d = refine(volume, key, &d);
    }
    Some(d)
}

/// The chunk's own data at its level, with the faces its lines end on completed from the
/// neighbours (`None` for a uniform chunk).
fn source(volume: &Volume, key: ChunkKey) -> Option<Dense> {
    let ChunkView::Lists(lists) = volume.view(key) else { return None };
    let level = lists.level();
    let n = level.cells();
    let old_map = LevelMap::stored(volume);
    let mut s = Dense::new(level);
    s.read_own(volume.view(key));
    for normal in Axis::ALL {
        let owner = key.offset(normal.unit_i64().as_ivec3());
        let g = effective_face(&old_map, normal, owner, level);
        let (ua, va) = normal.across();
        for j in 0..=n {
            for i in 0..=n {
                let k = s.index(compose(normal, n, i, j));
                if i == n || j == n {
                    s.states[k] = g.state(i, j);
                }
                if i < n {
                    s.cross[ua.index()][k] = g.crossing((0, i, j));
                }
                if j < n {
                    s.cross[va.index()][k] = g.crossing((1, i, j));
                }
            }
        }
    }
    s.make_consistent();
    Some(s)
}

/// `s` (the chunk `key` at some level `l`, apron included) refined to `l + 1`.
fn refine(volume: &Volume, key: ChunkKey, s: &Dense) -> Dense {
    let n = s.n;
    let fine = Level::new(s.level.get() + 1).expect("refined below the maximum level");
    let mut r = Dense::new(fine);
    for normal in Axis::ALL {
        for c in 0..=n {
            r.put_face(&s.face(normal, c).refine(), 2 * c);
        }
    }
    // Where the neighbour after the chunk is as fine as the new level, its nodes decide.
    let new_map = LevelMap::new(volume, None, Some((key, fine)));
    for normal in Axis::ALL {
        let owner = key.offset(normal.unit_i64().as_ivec3());
        if volume.stored_level(owner).is_some_and(|l| l >= fine) {
            r.put_face(&effective_face(&new_map, normal, owner, fine), 2 * n);
        }
    }
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                refine_centre(s, &mut r, [x, y, z]);
            }
        }
    }
    r.make_consistent();
    r
}

/// The centre node of cell `c` of `s` and the six half-edges through it, in `r` (one level finer).
fn refine_centre(s: &Dense, r: &mut Dense, c: [usize; 3]) {
    let centre = c.map(|v| 2 * v + 1);
    // The cell's crossings: cell-local points and normals.
    let mut planes: Vec<(DVec3, DVec3)> = Vec::new();
    let corner = s.state(c);
    let mut mixed = false;
    for axis in Axis::ALL {
        let (ua, va) = axis.across();
        for k in 0..4 {
            let mut lower = c;
            lower[ua.index()] += k & 1;
            lower[va.index()] += k >> 1;
            let cr = s.crossing(axis, lower);
            if cr == NONE {
                continue;
            }
            mixed = true;
            let sp = s.level.steps_per_cell() as f64;
            let mut p = DVec3::new((lower[0] - c[0]) as f64, (lower[1] - c[1]) as f64, (lower[2] - c[2]) as f64);
            p[axis.index()] = pos(cr) as f64 / sp - c[axis.index()] as f64;
            planes.push((p, unpack_normal(nrm(cr))));
        }
    }
    let ci = r.index(centre);
    if !mixed {
        r.states[ci] = corner;
        return;
    }
    let field = |p: DVec3| -> (f64, DVec3) {
        let (mut d, mut w_sum, mut nsum) = (0.0, 0.0, DVec3::ZERO);
        for &(q, nq) in &planes {
            let w = 1.0 / ((p - q).length_squared() + 1e-3);
            d += w * nq.dot(p - q);
            w_sum += w;
            nsum += w * nq;
        }
        (d / w_sum, nsum)
    };
    let mid = DVec3::splat(0.5);
    let inside = field(mid).0 < 0.0;
    r.states[ci] = inside;
    for axis in Axis::ALL {
        let a = axis.index();
        for side in 0..2usize {
            let mut face = centre;
            face[a] = 2 * c[a] + 2 * side;
            if r.state(face) == inside {
                continue;
            }
            let mut fp = mid;
            fp[a] = side as f64;
            // Root of the estimate between the face's centre and the cell's, else the middle.
            let (df, dc) = (field(fp).0, field(mid).0);
            let t = if (df < 0.0) != (dc < 0.0) {
                let (mut lo, mut hi) = (0.0f64, 1.0f64);
                for _ in 0..24 {
                    let m = 0.5 * (lo + hi);
                    let dm = field(fp.lerp(mid, m)).0;
                    if (dm < 0.0) == (df < 0.0) {
                        lo = m;
                    } else {
                        hi = m;
                    }
                }
                0.5 * (lo + hi)
            } else {
                0.5
            };
            let p = fp.lerp(mid, t);
            let normal = field(p).1;
            let lower = if side == 0 { face } else { centre };
            let sp = s.level.steps_per_cell() as f64;
            let q = quantize_steps((c[a] as f64 + p[a]) * sp, lower[a], r.level);
            let li = r.index(lower);
            r.cross[a][li] = pack(q, pack_normal(normal));
        }
    }
}

/// The chunk `before` (the neighbour before the raised chunk along `normal`) with the last cells
/// of its lines along `normal` changed to end in the states of the raised chunk's first face
/// (`r`'s plane 0), where it is a list chunk at least as fine as `r` and some line disagrees.
fn end_lines_on(volume: &Volume, before: ChunkKey, normal: Axis, r: &Dense) -> Option<Built> {
    let ChunkView::Lists(lists) = volume.view(before) else { return None };
    let level = lists.level();
    if level < r.level {
        return None;
    }
    let f = 1usize << (level.get() - r.level.get());
    let n = level.cells();
    let mut b = ChunkBuilder::default();
    b.begin(level);
    let mut changed = false;
    let mut line = WorkLine::EMPTY;
    for axis in Axis::ALL {
        b.begin_axis(axis);
        let mut reader = LineReader::new(volume.view(before), axis);
        for v in 0..n {
            for u in 0..n {
                reader.read(u, v, level, &mut line);
                if axis == normal && u % f == 0 && v % f == 0 {
                    let want = r.state(compose(normal, 0, u / f, v / f));
                    if ((line.states >> n) & 1 == 1) != want {
                        // Toggle the last node's state: the last cell gains or loses its crossing.
                        line.states ^= 1u128 << n;
                        let lower_inside = (line.states >> (n - 1)) & 1 == 1;
                        if lower_inside != want {
                            let e = n - 1;
                            line.pos[e] = quantize_steps((e as f64 + 0.5) * level.steps_per_cell() as f64, e, level);
                            let dir = normal.unit();
                            line.nrm[e] = pack_normal(if lower_inside { dir } else { -dir });
                        }
                        changed = true;
                    }
                }
                b.push_work(&line, n);
            }
        }
    }
    changed.then(|| b.finish())
}

/// The chunk at `key` (lists at level `l > 0`) lowered to `l - 1`.
pub(crate) fn lower(volume: &Volume, key: ChunkKey) -> Option<Built> {
    let ChunkView::Lists(lists) = volume.view(key) else { return None };
    let coarse = Level::new(lists.level().get().checked_sub(1)?)?;
    let n = coarse.cells();
    let mut b = ChunkBuilder::default();
    b.begin(coarse);
    let mut line = WorkLine::EMPTY;
    for axis in Axis::ALL {
        b.begin_axis(axis);
        let mut reader = LineReader::new(volume.view(key), axis);
        for v in 0..n {
            for u in 0..n {
                reader.read(u, v, coarse, &mut line);
                b.push_work(&line, n);
            }
        }
    }
    Some(b.finish())
}

impl Volume {
    /// Applies a built chunk and returns what was there.
    pub(crate) fn put_built(&mut self, key: ChunkKey, built: Built) -> Option<Chunk> {
        match built.into_chunk() {
            Some(c) => self.chunks.insert(key, c),
            None => self.chunks.remove(&key),
        }
    }
}
