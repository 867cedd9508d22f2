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
//!   there is already as fine as the new level, its own nodes are taken instead;
//! - the new nodes of the chunk's first faces that the lines of a neighbour before it, already
//!   as fine as the new level, end on take the states those lines end in ([`take_ends_before`]).
//!
//! Node states are decided first and crossings only where the two ends of an edge differ, so the
//! result satisfies every invariant by construction. Old crossings never sit on a new node
//! ([`crate::coords::quantize_into_edge`]), so lowering again gives back the old lists bit for
//! bit, but for a crossing on a first face that a finer neighbour's line end contradicts (moved
//! into the other half of its edge). Where two finer neighbours before the chunk disagree on a
//! node of one of its edges, one of them has that line's last cell made to end as the chunk now
//! says (the one case where a raise writes a neighbour; it is in the same undo record); a raise
//! that would leave that neighbour uniform is not made.
//!
//! Lowering keeps every second line and node and, on each coarse edge whose ends differ, the one
//! crossing of the two fine edges it covers; a lowering that would leave a uniform chunk that a
//! neighbour contradicts is not made (see [`super::settle`]).

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
        // A coarser neighbour's lines end on nodes of the old level, which keep their states.
        if volume.stored_level(before).is_none_or(|l| l < r.level) {
            continue;
        }
        if let Some(b) = end_lines_on(volume, before, normal, &r) {
            if matches!(b, Built::Uniform(_)) {
                // Its only crossings were last cells the raise takes away: a raise never empties
                // or fills a neighbour, so this one is not made.
                return None;
            }
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
            take_starts_after(volume, owner, normal, &mut r);
        }
    }
    take_ends_before(volume, key, &mut r);
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

/// Sets the nodes of the last face along `normal` of `r` that the chunk's own lines end on
/// (`u, v < n`) to the states the lines of `owner`, the list chunk after it and stored at least
/// as fine as `r`, start in: the invariant binds every one of those ends to the neighbour's own
/// node. The effective face put there first takes its border lines (the face's rows and columns
/// through the chunk's edges) from the coarsest chunk around each edge, refined back up by the
/// 1D rule, which guesses the new nodes on them: two crossings of the neighbour's line in one
/// cell of that coarser level (a face just past the chunk plane, another box beside it) refine to
/// a node of the wrong state there.
fn take_starts_after(volume: &Volume, owner: ChunkKey, normal: Axis, r: &mut Dense) {
    let n = r.n;
    let mut reader = LineReader::new(volume.view(owner), normal);
    let mut line = WorkLine::EMPTY;
    for v in 0..n {
        for u in 0..n {
            let ok = reader.read(u, v, r.level, &mut line);
            debug_assert!(ok, "read at or below the neighbour's level");
            let k = r.index(compose(normal, n, u, v));
            r.states[k] = line.states & 1 == 1;
        }
    }
}

/// One line of a neighbour before a chunk that ends on a node of the chunk's first face: the
/// state it ends in, whether its last cell holds a crossing (which making it end otherwise would
/// take away), and whether it can be made to end otherwise at all (a uniform neighbour's cannot).
#[derive(Clone, Copy)]
pub(super) struct End {
    pub(super) node: usize,
    pub(super) inside: bool,
    pub(super) last_crossed: bool,
    pub(super) rewritable: bool,
}

/// Sets each node of `d` that lines in `ends` end on to the state they end in; returns the nodes
/// whose state changed.
///
/// A node on one of the chunk's three edges through its minimum corner ends lines of two
/// neighbours. Where they disagree, the node follows the one that cannot be rewritten, else the
/// one whose last cell holds a crossing while the other's does not, so the other's line, made
/// to end there ([`end_lines_on`]), gains a crossing rather than losing one (else the lower
/// axis).
pub(super) fn take_ends(d: &mut Dense, mut ends: Vec<End>) -> Vec<usize> {
    // Ends on one node are next to each other, in axis order.
    ends.sort_by_key(|e| e.node);
    let mut changed = Vec::new();
    for group in ends.chunk_by(|a, b| a.node == b.node) {
        let against = |e: End| group.iter().filter(move |o| o.inside != e.inside);
        let wins = *group
            .iter()
            .find(|e| !e.rewritable)
            .or_else(|| group.iter().find(|e| e.last_crossed && against(**e).all(|o| !o.last_crossed)))
            .unwrap_or(&group[0]);
        debug_assert!(against(wins).all(|o| o.rewritable), "two uniform neighbours disagree on a node");
        if d.states[wins.node] != wins.inside {
            d.states[wins.node] = wins.inside;
            changed.push(wins.node);
        }
    }
    changed
}

/// The lines of the chunk `before` along `normal` that end on plane 0 of `d` (the first face of
/// the chunk after it), for [`take_ends`]: one per line of the coarser of `d`'s level and the
/// chunk's own (a uniform chunk's: `d`'s) whose node `(u, v)` of `d` `keep` accepts.
pub(super) fn ends_of(
    volume: &Volume,
    before: ChunkKey,
    normal: Axis,
    d: &Dense,
    keep: impl Fn(usize, usize) -> bool,
) -> Vec<End> {
    let mut ends = Vec::new();
    let mut line = WorkLine::EMPTY;
    let view = volume.view(before);
    let stored = match view {
        ChunkView::Lists(l) => Some(l.level()),
        ChunkView::Uniform(_) => None,
    };
    // Lines are read at `lattice` (the coarser of `d`'s level and the chunk's), `f` nodes of `d`
    // apart; `g` of the chunk's own lines apart.
    let lattice = stored.map_or(d.level, |l| l.min(d.level));
    let f = 1usize << (d.level.get() - lattice.get());
    let (read_at, g) = match stored {
        Some(l) => (l, 1usize << (l.get() - lattice.get())),
        None => (lattice, 1),
    };
    let n = read_at.cells();
    let mut reader = LineReader::new(view, normal);
    for v in 0..lattice.cells() {
        for u in 0..lattice.cells() {
            if !keep(u * f, v * f) {
                continue;
            }
            reader.read(u * g, v * g, read_at, &mut line);
            let inside = (line.states >> n) & 1 == 1;
            let last_crossed = ((line.states >> (n - 1)) & 1 == 1) != inside;
            let node = d.index(compose(normal, 0, u * f, v * f));
            ends.push(End { node, inside, last_crossed, rewritable: stored.is_some() });
        }
    }
    ends
}

/// The new nodes of the first faces of `r` (the chunk `key` one level finer than stored) that
/// the lines of a neighbour before it, stored at least as fine as `r`, end on: each takes the
/// state those lines end in ([`take_ends`]), so the neighbour's lines keep their ends and
/// lowering the chunk again leaves the neighbour as it was. (Those ends are the neighbour's own
/// finer data; the face table would guess them from the chunk's coarser face.)
///
/// A crossing of the chunk on a coarse edge whose middle node now lies on the crossing's side of
/// it moves, as little as it can, into the other half of the edge, so every old crossing stays on
/// its edge and lowering gives back that edge's crossing within half a coarse cell.
fn take_ends_before(volume: &Volume, key: ChunkKey, r: &mut Dense) {
    let mut ends = Vec::new();
    for normal in Axis::ALL {
        let before = key.offset(-normal.unit_i64().as_ivec3());
        if volume.stored_level(before).is_some_and(|l| l >= r.level) {
            // The nodes of the old level are bound already and kept as they are.
            ends.extend(ends_of(volume, before, normal, r, |u, v| u % 2 == 1 || v % 2 == 1));
        }
    }
    let m = r.n + 1;
    for node in take_ends(r, ends) {
        let p = [node % m, (node / m) % m, node / (m * m)];
        // The coarse edge this node is the middle of: exactly one odd coordinate.
        let mut odd = (0..3).filter(|&i| p[i] % 2 == 1);
        let (Some(e), None) = (odd.next(), odd.next()) else { continue };
        let mut lo = p;
        lo[e] -= 1;
        let mut hi = p;
        hi[e] += 1;
        let (s_lo, s_mid, s_hi) = (r.state(lo), r.states[node], r.state(hi));
        let (k_lo, k_mid) = (r.index(lo), node);
        let (c_lo, c_mid) = (r.cross[e][k_lo], r.cross[e][k_mid]);
        if c_lo != NONE && c_mid == NONE && s_lo == s_mid && s_mid != s_hi {
            r.cross[e][k_mid] = pack(quantize_steps(pos(c_lo).0 as f64, p[e], r.level), nrm(c_lo));
            r.cross[e][k_lo] = NONE;
        } else if c_mid != NONE && c_lo == NONE && s_mid == s_hi && s_lo != s_mid {
            r.cross[e][k_lo] = pack(quantize_steps(pos(c_mid).0 as f64, lo[e], r.level), nrm(c_mid));
            r.cross[e][k_mid] = NONE;
        }
    }
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
            p[axis.index()] = pos(cr).0 as f64 / sp - c[axis.index()] as f64;
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

/// The list chunk `before` (the neighbour before the chunk of `r` along `normal`) with the last
/// cells of its lines along `normal` changed to end in the states of `r`'s plane 0, where some
/// line disagrees (`None` where none does, or the chunk is uniform). Its lines of the coarser of
/// the two levels end on nodes of `r`; its finer ones end between them and are left alone.
pub(super) fn end_lines_on(volume: &Volume, before: ChunkKey, normal: Axis, r: &Dense) -> Option<Built> {
    let ChunkView::Lists(lists) = volume.view(before) else { return None };
    let level = lists.level();
    // Line (u, v) is bound where both are multiples of `f`; it ends on node (u, v) / f * g of `r`.
    let (f, g) = if level >= r.level {
        (1usize << (level.get() - r.level.get()), 1)
    } else {
        (1, 1usize << (r.level.get() - level.get()))
    };
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
                    let want = r.state(compose(normal, 0, u / f * g, v / f * g));
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

/// The chunk at `key` (lists at level `l > 0`) lowered to `l - 1`; `None` where it is at level 0
/// or where it would become uniform and a face neighbour's line contradicts that
/// ([`uniform_fits`]: possible only below the volume's level), which keeps it as it is.
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
    let built = b.finish();
    if let Built::Uniform(inside) = built
        && !uniform_fits(volume, key, inside)
    {
        return None;
    }
    Some(built)
}

/// Whether the chunk at `key` can be stored as uniform `inside` without contradicting a
/// neighbour across a face. A uniform chunk has no level: edits and the invariant checker sample
/// it at the volume's level, so every line of a face neighbour at that level (or at the
/// neighbour's, where it is coarser) that ends on the chunk's first face or starts on the face
/// after it must end or start `inside`. A list chunk below the volume's level binds only every
/// second of those lines, and the others can disagree (a neighbour's node between its nodes, or
/// a neighbour's line ending on a node of the chunk that the chunk's level does not have).
pub(super) fn uniform_fits(volume: &Volume, key: ChunkKey, inside: bool) -> bool {
    let mut line = WorkLine::EMPTY;
    for axis in Axis::ALL {
        let step = axis.unit_i64().as_ivec3();
        for (k, ends_here) in [(key.offset(-step), true), (key.offset(step), false)] {
            let level = volume.level_of(k).min(volume.level);
            let n = level.cells();
            let mut reader = LineReader::new(volume.view(k), axis);
            for v in 0..n {
                for u in 0..n {
                    reader.read(u, v, level, &mut line);
                    let state = if ends_here { (line.states >> n) & 1 == 1 } else { line.states & 1 == 1 };
                    if state != inside {
                        return false;
                    }
                }
            }
        }
    }
    true
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
