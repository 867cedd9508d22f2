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

/// Samples one brush along chunk lines; keeps scratch space between lines.
pub(crate) struct LineSampler<'a> {
    pub(crate) brush: &'a dyn Brush,
    pub(crate) bounds: Aabb,
    /// Flip normals (subtraction: the brush's outside becomes the solid's outside).
    pub(crate) flip: bool,
    spans: Vec<Span>,
}

impl<'a> LineSampler<'a> {
    pub(crate) fn new(brush: &'a dyn Brush, flip: bool) -> Self {
        LineSampler { brush, bounds: brush.bounds().expand(SNAP_DISTANCE), flip, spans: Vec::new() }
    }

    /// Fills `out` with the brush's states and crossings on line `(u, v)` along `axis` of the
    /// chunk at `origin_grid` (`u`, `v` may equal `n`: apron lines owned by a neighbour).
    pub(crate) fn sample(
        &mut self,
        origin_grid: I64Vec3,
        level: Level,
        axis: Axis,
        u: usize,
        v: usize,
        out: &mut WorkLine,
    ) {
        let n = level.cells();
        let sp = level.spacing();
        let origin = origin_grid.as_dvec3();
        let start = DVec3::from_array(compose(axis, 0.0, u as f64 * sp, v as f64 * sp));
        let a = axis.index();
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
        let dir = axis.unit();
        let node_at = |j: usize| -> (DVec3, DVec3) {
            let local = compose(axis, j, u, v);
            node_point(origin_grid, local, level)
        };
        let mut spans = std::mem::take(&mut self.spans);
        if self.brush.spans(origin, start, dir, &mut spans) {
            self.from_spans(&spans, n, sp, level, dir, &node_at, out);
        } else {
            self.from_samples(origin, start, n, sp, level, dir, lo[a], hi[a], &node_at, out);
        }
        self.spans = spans;
    }

    #[allow(clippy::too_many_arguments)]
    fn from_spans(
        &self,
        spans: &[Span],
        n: usize,
        sp: f64,
        level: Level,
        dir: DVec3,
        node_at: &dyn Fn(usize) -> (DVec3, DVec3),
        out: &mut WorkLine,
    ) {
        let mut states = 0u128;
        for s in spans {
            let j0 = (s.enter / sp).ceil().max(0.0);
            let j1 = (s.exit / sp).floor().min(n as f64);
            if j0 <= j1 {
                let (j0, j1) = (j0 as usize, j1 as usize);
                states |= node_mask(j1) & !((1u128 << j0) - 1);
            }
        }
        // Nodes (practically) on the surface follow the predicate, whatever the roots said.
        for s in spans {
            for t in [s.enter, s.exit] {
                let j = (t / sp).round();
                if j >= 0.0 && j <= n as f64 && (j * sp - t).abs() <= SNAP_DISTANCE {
                    let j = j as usize;
                    let (o, p) = node_at(j);
                    if self.brush.contains(o, p) {
                        states |= 1 << j;
                    } else {
                        states &= !(1 << j);
                    }
                }
            }
        }
        out.states = states;
        let mut c = out.changes(n);
        while c != 0 {
            let e = c.trailing_zeros() as usize;
            c &= c - 1;
            let entering = (states >> (e + 1)) & 1 == 1;
            let (lo, hi) = (e as f64 * sp - SNAP_DISTANCE, (e + 1) as f64 * sp + SNAP_DISTANCE);
            let pick = if entering {
                spans.iter().rev().find(|s| s.enter >= lo && s.enter <= hi).map(|s| (s.enter, s.enter_normal))
            } else {
                spans.iter().find(|s| s.exit >= lo && s.exit <= hi).map(|s| (s.exit, s.exit_normal))
            };
            let mid = (e as f64 + 0.5) * sp;
            let (t, normal) = pick.unwrap_or_else(|| {
                // The predicate moved the change away from any root: use the nearest end.
                let nearest = spans
                    .iter()
                    .flat_map(|s| [(s.enter, s.enter_normal), (s.exit, s.exit_normal)])
                    .min_by(|a, b| (a.0 - mid).abs().total_cmp(&(b.0 - mid).abs()));
                nearest.unwrap_or((mid, if entering { -dir } else { dir }))
            });
            out.pos[e] = quantize_into_edge(t, e, level);
            out.nrm[e] = pack_normal(if self.flip { -normal } else { normal });
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn from_samples(
        &self,
        origin: DVec3,
        start: DVec3,
        n: usize,
        sp: f64,
        level: Level,
        dir: DVec3,
        t_lo: f64,
        t_hi: f64,
        node_at: &dyn Fn(usize) -> (DVec3, DVec3),
        out: &mut WorkLine,
    ) {
        let brush = self.brush;
        let lip = brush.lipschitz();
        let field_at = |t: f64| brush.field(origin, start + dir * t);
        let mut states = 0u128;
        // Field values at the nodes where they were computed (NaN where a node was skipped).
        let mut values = [f64::NAN; crate::chunk::MAX_NODES];
        let mut skip_until = 0usize;
        let mut skip_state = false;
        for j in 0..=n {
            let t = j as f64 * sp;
            if t < t_lo || t > t_hi {
                continue;
            }
            let inside = if j < skip_until {
                skip_state
            } else {
                let (o, p) = node_at(j);
                let inside = brush.contains(o, p);
                let f = field_at(t);
                values[j] = f;
                // Every point within |f| / L has the same field sign: skip nodes proved to share
                // this node's state (a small margin absorbs rounding in the field).
                let reach = f.abs() / lip * (1.0 - 1e-9) - 1e-9;
                if reach > sp && ((f > 0.0) != inside) {
                    skip_until = j + 1 + (reach / sp).floor() as usize;
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
            out.pos[e] = quantize_into_edge(t, e, level);
            out.nrm[e] = pack_normal(if self.flip { -normal } else { normal });
        }
    }
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
