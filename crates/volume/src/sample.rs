//! Turning a brush into node states and crossings on one chunk line, respecting the node-state
//! invariant: a node's state is the brush's predicate there (evaluated in the chunk that owns the
//! node), and every crossing lies strictly inside a cell whose two nodes differ.

use glam::{DVec3, I64Vec3};

use crate::axis::{Axis, compose};
use crate::brush::{Aabb, Brush, SNAP_DISTANCE, Span};
use crate::chunk::{WorkLine, node_mask};
use crate::coords::{ChunkKey, Level, quantize_into_edge};
use crate::normal::pack_normal;

/// The origin and chunk-relative point at which the predicate of node `local` (level units,
/// each coordinate in `0..=n`) of the chunk at `origin_grid` is evaluated: coordinates equal to
/// `n` belong to the next chunk, and are evaluated there, so every node has exactly one answer.
#[inline]
pub(crate) fn node_point(origin_grid: I64Vec3, local: [usize; 3], level: Level) -> (DVec3, DVec3) {
    let n = level.cells();
    let mut origin = origin_grid;
    let mut p = DVec3::ZERO;
    for i in 0..3 {
        if local[i] >= n {
            origin[i] += crate::coords::CHUNK_CELLS;
            p[i] = (local[i] - n) as f64 * level.spacing();
        } else {
            p[i] = local[i] as f64 * level.spacing();
        }
    }
    (origin.as_dvec3(), p)
}

/// The brush's predicate at a node of `level` given in global node coordinates: the reference
/// that a volume's node states must equal after adding the brush to an empty volume.
pub fn brush_contains_node(brush: &dyn Brush, node: I64Vec3, level: Level) -> bool {
    let n = level.cells() as i64;
    let key = node.div_euclid(I64Vec3::splat(n));
    let local = (node - key * n).as_uvec3();
    let key = ChunkKey(key.as_ivec3());
    let (origin, p) = node_point(key.origin_grid(), [local.x as usize, local.y as usize, local.z as usize], level);
    brush.contains(origin, p)
}

/// Packs a brush's outward normal as stored: flipped for a subtraction, where the brush's
/// outside becomes the solid's inside.
#[inline]
pub(crate) fn pack_oriented(normal: DVec3, flip: bool) -> crate::normal::PackedNormal {
    pack_normal(if flip { -normal } else { normal })
}

/// Samples one brush along chunk lines; keeps scratch space between lines.
pub(crate) struct LineSampler<'a> {
    pub(crate) brush: &'a dyn Brush,
    pub(crate) bounds: Aabb,
    /// Flip normals (subtraction: the brush's outside becomes the solid's outside).
    pub(crate) flip: bool,
    spans: Vec<Span>,
}

/// Where a line sits: the chunk's grid origin, its level, axis and across coordinates (`u`,
/// `v` may equal `n`: apron lines owned by a neighbour).
#[derive(Clone, Copy, Debug)]
pub(crate) struct LineAt {
    pub(crate) origin_grid: I64Vec3,
    pub(crate) level: Level,
    pub(crate) axis: Axis,
    pub(crate) u: usize,
    pub(crate) v: usize,
}

impl LineAt {
    fn start(&self) -> DVec3 {
        let sp = self.level.spacing();
        DVec3::from_array(compose(self.axis, 0.0, self.u as f64 * sp, self.v as f64 * sp))
    }

    /// Canonical predicate point of node `j` of the line.
    #[inline]
    fn node(&self, j: usize) -> (DVec3, DVec3) {
        node_point(self.origin_grid, compose(self.axis, j, self.u, self.v), self.level)
    }
}

impl<'a> LineSampler<'a> {
    pub(crate) fn new(brush: &'a dyn Brush, flip: bool) -> Self {
        LineSampler { brush, bounds: brush.bounds().expand(SNAP_DISTANCE), flip, spans: Vec::new() }
    }

    /// Fills `out` with the brush's states and crossings on one chunk line, asking the brush.
    pub(crate) fn sample(&mut self, at: LineAt, out: &mut WorkLine) {
        let n = at.level.cells();
        let origin = at.origin_grid.as_dvec3();
        let start = at.start();
        let a = at.axis.index();
        out.states = 0;
        // Reject lines that miss the brush's box.
        let lo = self.bounds.min - origin;
        let hi = self.bounds.max - origin;
        for i in 0..3 {
            if i != a && (start[i] < lo[i] || start[i] > hi[i]) {
                return;
            }
        }
        if hi[a] < 0.0 || lo[a] > crate::coords::CHUNK_CELLS as f64 {
            return;
        }
        let dir = at.axis.unit();
        let mut spans = std::mem::take(&mut self.spans);
        if self.brush.spans(origin, start, dir, &mut spans) {
            self.fill_from_spans(&spans, 0.0, at, out);
        } else {
            self.fill_from_samples(origin, start, n, lo[a], hi[a], at, out);
        }
        self.spans = spans;
    }

    /// Fills `out` from spans whose parameter is `shift` grid units ahead of the line's node 0.
    pub(crate) fn fill_from_spans(&self, all: &[Span], shift: f64, at: LineAt, out: &mut WorkLine) {
        let n = at.level.cells();
        let sp = at.level.spacing();
        let spans = near_chunk(all, shift);
        if covers_line(spans, shift) {
            // The whole chunk line is well inside.
            out.states = node_mask(n);
            return;
        }
        if let [s] = spans
            && let Some(line) = single_span(s, self.flip, shift, at.level)
        {
            line.apply(out);
            return;
        }
        let states = self.general_states(spans, shift, at);
        out.states = states;
        let mut c = out.changes(n);
        while c != 0 {
            let e = c.trailing_zeros() as usize;
            c &= c - 1;
            let entering = (states >> (e + 1)) & 1 == 1;
            let (lo, hi) = (e as f64 * sp - SNAP_DISTANCE + shift, (e + 1) as f64 * sp + SNAP_DISTANCE + shift);
            let pick = if entering {
                spans.iter().rev().find(|s| s.enter >= lo && s.enter <= hi).map(|s| (s.enter, s.enter_normal))
            } else {
                spans.iter().find(|s| s.exit >= lo && s.exit <= hi).map(|s| (s.exit, s.exit_normal))
            };
            let mid = (e as f64 + 0.5) * sp + shift;
            let (t, normal) = pick.unwrap_or_else(|| {
                // The predicate moved the change away from any root: use the nearest end.
                let nearest = all
                    .iter()
                    .flat_map(|s| [(s.enter, s.enter_normal), (s.exit, s.exit_normal)])
                    .min_by(|a, b| (a.0 - mid).abs().total_cmp(&(b.0 - mid).abs()));
                nearest.unwrap_or_else(|| {
                    let dir = at.axis.unit();
                    (mid, if entering { -dir } else { dir })
                })
            });
            out.pos[e] = quantize_into_edge(t - shift, e, at.level);
            out.nrm[e] = pack_oriented(normal, self.flip);
        }
    }

    /// The node states [`LineSampler::fill_from_spans`] gives the line, without its crossings
    /// (what a reconciled edit reads from its x lines).
    pub(crate) fn states_from_spans(&self, all: &[Span], shift: f64, at: LineAt) -> u128 {
        let spans = near_chunk(all, shift);
        if covers_line(spans, shift) {
            return node_mask(at.level.cells());
        }
        if let [s] = spans
            && let Some((j0, j1)) = single_span_nodes(s, shift, at.level)
        {
            return node_range(j0, j1);
        }
        self.general_states(spans, shift, at)
    }

    /// Node states from spans near the chunk (see [`near_chunk`]) by rounding their ends to
    /// nodes, where nodes (practically) on the surface follow the predicate, whatever the roots
    /// said.
    fn general_states(&self, spans: &[Span], shift: f64, at: LineAt) -> u128 {
        let n = at.level.cells();
        let sp = at.level.spacing();
        let inv_sp = at.level.nodes_per_unit();
        let mut states = 0u128;
        for s in spans {
            let (enter, exit) = (s.enter - shift, s.exit - shift);
            let j0 = ceil_clamped(enter * inv_sp, n);
            let j1 = floor_clamped(exit * inv_sp, n);
            if let (Some(j0), Some(j1)) = (j0, j1) {
                states |= node_range(j0, j1);
            }
        }
        for s in spans {
            for t in [s.enter - shift, s.exit - shift] {
                let Some(j) = nearest_node(t * inv_sp, n) else { continue };
                if (j as f64 * sp - t).abs() <= SNAP_DISTANCE {
                    let (o, p) = at.node(j);
                    if self.brush.contains(o, p) {
                        states |= 1 << j;
                    } else {
                        states &= !(1 << j);
                    }
                }
            }
        }
        states
    }

    fn fill_from_samples(
        &self,
        origin: DVec3,
        start: DVec3,
        n: usize,
        t_lo: f64,
        t_hi: f64,
        at: LineAt,
        out: &mut WorkLine,
    ) {
        let sp = at.level.spacing();
        let dir = at.axis.unit();
        let brush = self.brush;
        let lip = brush.lipschitz();
        let field_at = |t: f64| brush.field(origin, start + dir * t);
        let mut states = 0u128;
        // Field values at the nodes where they were computed (NaN where a node was skipped).
        let mut values = [f64::NAN; crate::chunk::MAX_NODES];
        let mut skip_until = 0usize;
        let mut skip_state = false;
        #[allow(clippy::needless_range_loop)] // j is a node index used for more than `values`
        for j in 0..=n {
            let t = j as f64 * sp;
            if t < t_lo || t > t_hi {
                continue;
            }
            // The line's last node is always evaluated: it is the next chunk's first node,
            // which that chunk evaluates itself, so a skip that a wrong Lipschitz bound or a
            // discontinuous field made unsound must not decide it here differently.
            let inside = if j < skip_until && j < n {
                skip_state
            } else {
                let (o, p) = at.node(j);
                let inside = brush.contains(o, p);
                let f = field_at(t);
                values[j] = f;
                // Every point within |f| / L has the same field sign: skip nodes proved to share
                // this node's state (a small margin absorbs rounding in the field).
                let reach = f.abs() / lip * (1.0 - 1e-9) - 1e-9;
                if reach > sp && ((f > 0.0) != inside) {
                    skip_until = j + 1 + (reach / sp) as usize;
                    skip_state = inside;
                }
                inside
            };
            if inside {
                states |= 1 << j;
            }
        }
        out.states = states;
        let mut c = out.changes(n);
        while c != 0 {
            let e = c.trailing_zeros() as usize;
            c &= c - 1;
            let entering = (states >> (e + 1)) & 1 == 1;
            let (t0, t1) = (e as f64 * sp, (e + 1) as f64 * sp);
            let f0 = if values[e].is_nan() { field_at(t0) } else { values[e] };
            let f1 = if values[e + 1].is_nan() { field_at(t1) } else { values[e + 1] };
            let t = if (f0 <= 0.0) != (f1 <= 0.0) { find_root(&field_at, t0, f0, t1, f1) } else { (t0 + t1) / 2.0 };
            let mut normal = brush.normal(origin, start + dir * t);
            // Keep the normal pointing out of the solid along the line.
            if (normal.dot(dir) > 0.0) == entering {
                normal = -normal;
            }
            out.pos[e] = quantize_into_edge(t, e, at.level);
            out.nrm[e] = pack_oriented(normal, self.flip);
        }
    }
}

/// The result of one span on a chunk line when no node lies within the snapping distance of
/// its ends (the common case, taken without a predicate call).
struct SingleSpan {
    states: u128,
    enter: Option<(usize, crate::coords::LocalPos, crate::normal::PackedNormal)>,
    exit: Option<(usize, crate::coords::LocalPos, crate::normal::PackedNormal)>,
}

impl SingleSpan {
    fn apply(&self, out: &mut WorkLine) {
        out.states = self.states;
        for (e, q, nrm) in [self.enter, self.exit].into_iter().flatten() {
            out.pos[e] = q;
            out.nrm[e] = nrm;
        }
    }
}

/// Which spans of a line can decide its chunk piece's nodes or crossings: those reaching within
/// a cell of the piece (the spans are sorted and disjoint), so a long line through a complex
/// mesh costs each chunk only the spans it holds.
#[inline]
fn near_chunk(all: &[Span], shift: f64) -> &[Span] {
    let end = crate::coords::CHUNK_CELLS as f64;
    let first = all.partition_point(|s| s.exit - shift < -1.0);
    let last = all.partition_point(|s| s.enter - shift <= end + 1.0);
    &all[first..last.max(first)]
}

/// Whether the spans near a chunk are one span holding the whole chunk line, farther than the
/// snapping distance from both ends.
#[inline]
fn covers_line(spans: &[Span], shift: f64) -> bool {
    let end = crate::coords::CHUNK_CELLS as f64;
    matches!(spans, [s] if s.enter - shift < -SNAP_DISTANCE && s.exit - shift > end + SNAP_DISTANCE)
}

/// Nodes `j0..=j1` (none where `j0 > j1`).
#[inline]
fn node_range(j0: usize, j1: usize) -> u128 {
    if j0 > j1 { 0 } else { node_mask(j1) & !((1u128 << j0) - 1) }
}

/// The nodes `j0..=j1` of the chunk line inside a span no end of which is within the snapping
/// distance of a node of the piece (`j0 > j1` where it holds none), or `None` where the span
/// needs the general reading (an end near a node, or the span beside the piece).
#[inline]
fn single_span_nodes(s: &Span, shift: f64, level: Level) -> Option<(usize, usize)> {
    let n = level.cells();
    let inv_sp = level.nodes_per_unit();
    let (enter, exit) = ((s.enter - shift) * inv_sp, (s.exit - shift) * inv_sp);
    let snap = SNAP_DISTANCE * inv_sp;
    let near = |x: f64| x > -snap - 0.5 && x < n as f64 + 0.5 + snap && (x - (x + 0.5).floor()).abs() <= snap;
    if near(enter) || near(exit) {
        return None;
    }
    Some((ceil_clamped(enter, n)?, floor_clamped(exit, n)?))
}

#[inline]
fn single_span(s: &Span, flip: bool, shift: f64, level: Level) -> Option<SingleSpan> {
    let n = level.cells();
    let (j0, j1) = single_span_nodes(s, shift, level)?;
    if j0 > j1 {
        return Some(SingleSpan { states: 0, enter: None, exit: None });
    }
    let states = node_range(j0, j1);
    let enter = (j0 > 0)
        .then(|| (j0 - 1, quantize_into_edge(s.enter - shift, j0 - 1, level), pack_oriented(s.enter_normal, flip)));
    let exit =
        (j1 < n).then(|| (j1, quantize_into_edge(s.exit - shift, j1, level), pack_oriented(s.exit_normal, flip)));
    Some(SingleSpan { states, enter, exit })
}

/// `ceil(x)` as a node index if it is at most `n` (negative values give 0).
#[inline]
fn ceil_clamped(x: f64, n: usize) -> Option<usize> {
    if !(x <= n as f64) {
        return None;
    }
    if x <= 0.0 {
        return Some(0);
    }
    let i = x as usize;
    Some(if (i as f64) < x { i + 1 } else { i })
}

/// `floor(x)` clamped to `n`, or `None` below 0.
#[inline]
fn floor_clamped(x: f64, n: usize) -> Option<usize> {
    if !(x >= 0.0) {
        return None;
    }
    if x >= n as f64 {
        return Some(n);
    }
    Some(x as usize)
}

/// The nearest node index to `x`, if it is one of `0..=n`.
#[inline]
fn nearest_node(x: f64, n: usize) -> Option<usize> {
    let r = x + 0.5;
    (r >= 0.0 && r < (n + 1) as f64).then_some(r as usize)
}

/// Illinois-modified regula falsi on a bracket with `f(lo)` and `f(hi)` of opposite signs.
fn find_root(f: &dyn Fn(f64) -> f64, mut lo: f64, mut flo: f64, mut hi: f64, mut fhi: f64) -> f64 {
    let mut side = 0;
    for _ in 0..60 {
        if hi - lo < 1e-7 {
            break;
        }
        let mut c = (lo * fhi - hi * flo) / (fhi - flo);
        if !(c > lo && c < hi) {
            c = 0.5 * (lo + hi);
        }
        let fc = f(c);
        if fc == 0.0 {
            return c;
        }
        if (fc <= 0.0) == (flo <= 0.0) {
            lo = c;
            flo = fc;
            if side == -1 {
                fhi *= 0.5;
            }
            side = -1;
        } else {
            hi = c;
            fhi = fc;
            if side == 1 {
                flo *= 0.5;
            }
            side = 1;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regula_falsi_finds_roots_of_curved_functions() {
        let f = |t: f64| t * t * t - 0.3;
        let r = find_root(&f, 0.0, f(0.0), 1.0, f(1.0));
        assert!((r - 0.3f64.cbrt()).abs() < 1e-6, "{r}");
    }
}

#[cfg(test)]
mod snap_tests {
    use super::*;
    use crate::Volume;
    use crate::brush::Sphere;

    /// A sphere whose spans are pushed inwards by 1e-9 cells, as a rounding closed form might.
    struct Jittered(Sphere);

    impl Brush for Jittered {
        fn bounds(&self) -> Aabb {
            self.0.bounds()
        }
        fn field(&self, origin: DVec3, p: DVec3) -> f64 {
            self.0.field(origin, p)
        }
        fn contains(&self, origin: DVec3, p: DVec3) -> bool {
            self.0.contains(origin, p)
        }
        fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
            self.0.spans(origin, start, dir, out);
            for s in out.iter_mut() {
                s.enter += 1e-9;
                s.exit -= 1e-9;
            }
            true
        }
    }

    #[test]
    fn nodes_on_the_surface_follow_the_predicate_even_when_roots_round_inwards() {
        // Radius 5 around a node: nodes like (3, 4, 0) away from the centre lie exactly on it.
        let brush = Jittered(Sphere::new(DVec3::new(8.0, 8.0, 8.0), 5.0).unwrap());
        let mut v = Volume::new();
        v.add(&brush).unwrap();
        v.check_invariants().unwrap();
        let mut on_surface = 0;
        for z in 0..17 {
            for y in 0..17 {
                for x in 0..17 {
                    let node = I64Vec3::new(x, y, z);
                    let expect = brush_contains_node(&brush, node, Level::BASE);
                    assert_eq!(v.node_inside(node), expect, "node {node}");
                    on_surface += ((node - 8).length_squared() == 25) as u32;
                }
            }
        }
        assert!(on_surface > 20);
    }
}
