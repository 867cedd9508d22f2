//! A brush cut by a mask, so that a CSG edit leaves the nodes the mask holds as they are (see
//! [`crate::mask`]): for union and difference the brush becomes its part where the mask is
//! free (`B ∩ U`, `U` the points whose interpolated weight is below one half), for intersection
//! it takes in the held part too (`B ∪ H`). A held node is then never inside the cut brush
//! (union adds nothing there, difference removes nothing) and always inside the widened one
//! (intersection keeps it), and an edge with both nodes held lies wholly in `H` (the weight is
//! linear along it), so its crossing stays.

use glam::DVec3;

use super::{Aabb, Brush, Span, unit_axis};
use crate::mask::{MaskSampler, PROTECTED, holds};

/// See the module docs.
pub(crate) struct Masked<'a> {
    pub inner: &'a dyn Brush,
    pub mask: &'a MaskSampler,
    /// `true`: `B ∪ H` (intersection); `false`: `B ∩ U`.
    pub widen: bool,
    /// The bounds (for `B ∪ H`, wide enough for every chunk the mask can hold).
    pub bounds: Aabb,
}

impl Masked<'_> {
    /// `0.5 - weight`: negative where held.
    #[inline]
    fn held_field(&self, origin: DVec3, p: DVec3) -> f64 {
        0.5 - self.mask.at(origin + p)
    }

    #[inline]
    fn combine(&self, inside: bool, origin: DVec3, p: DVec3) -> bool {
        let held = holds(self.mask.at(origin + p));
        if self.widen { inside || held } else { inside && !held }
    }
}

impl Brush for Masked<'_> {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        let b = self.inner.field(origin, p);
        let h = self.held_field(origin, p);
        if self.widen { b.min(h) } else { b.max(-h) }
    }

    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        self.combine(self.inner.contains(origin, p), origin, p)
    }

    fn contains_on_line(&self, origin: DVec3, p: DVec3, dir: DVec3) -> bool {
        self.combine(self.inner.contains_on_line(origin, p, dir), origin, p)
    }

    fn normal(&self, origin: DVec3, p: DVec3) -> DVec3 {
        let b = self.inner.field(origin, p);
        let h = self.held_field(origin, p);
        let gradient = self.mask.gradient(origin + p);
        // The mask's part decides where its field is the one combined in.
        if self.widen && h < b {
            (-gradient).normalize_or(self.inner.normal(origin, p))
        } else if !self.widen && -h > b {
            gradient.normalize_or(self.inner.normal(origin, p))
        } else {
            self.inner.normal(origin, p)
        }
    }

    fn lipschitz(&self) -> f64 {
        // The weight is trilinear between nodes a grid unit apart, each in [0, 1].
        self.inner.lipschitz().max(3f64.sqrt())
    }

    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        // The cut along a grid line: the brush's spans less where the weight holds. (The wide
        // form samples: its held part reaches beyond the brush's spans.)
        let Some(axis) = unit_axis(dir) else { return false };
        if self.widen {
            return false;
        }
        let mut inner = Vec::new();
        if !self.inner.spans(origin, start, dir, &mut inner) {
            return false;
        }
        out.clear();
        let base = origin + start;
        // Along the line the weight is linear between the integer positions `k` of the axis,
        // where it is the bilinear blend of four nodes across (one when the line runs through
        // nodes): `line_weight(k)`.
        let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
        let (fu, fv) = (base[ua] - base[ua].floor(), base[va] - base[va].floor());
        let (bu, bv) = (base[ua].floor() as i64, base[va].floor() as i64);
        let line_weight = |k: i64| {
            let mut node = glam::I64Vec3::ZERO;
            node[axis] = k;
            let mut sum = 0.0;
            for (du, wu) in [(0, 1.0 - fu), (1, fu)] {
                for (dv, wv) in [(0, 1.0 - fv), (1, fv)] {
                    let w = wu * wv;
                    if w != 0.0 {
                        node[ua] = bu + du;
                        node[va] = bv + dv;
                        sum += w * self.mask.node(node);
                    }
                }
            }
            sum
        };
        let a = base[axis];
        let weight_at = |t: f64, below: f64, above: f64| {
            let u = a + t;
            below + (above - below) * (u - u.floor())
        };
        let normal_at = |t: f64, fallback: DVec3| {
            let mut p = base;
            p[axis] += t;
            self.mask.gradient(p).normalize_or(fallback)
        };
        // A line whose nodes (the one to four it runs between) are all free, or all held, in
        // the sampler's box: the brush's spans as they are, or none.
        if let (Some(first), Some(last)) = (inner.first(), inner.last())
            && self.mask.spans_box(axis, a + first.enter - 1.0, a + last.exit + 1.0)
        {
            let mut range = (u8::MAX, 0u8);
            let mut known = true;
            for (du, dv) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                if (du == 1 && fu == 0.0) || (dv == 1 && fv == 0.0) {
                    continue;
                }
                let mut node = glam::I64Vec3::ZERO;
                node[ua] = bu + du;
                node[va] = bv + dv;
                match self.mask.line_range(axis, node) {
                    Some((lo, hi)) => range = (range.0.min(lo), range.1.max(hi)),
                    None => known = false,
                }
            }
            if known && !holds(range.1 as f64 / PROTECTED as f64) {
                out.extend_from_slice(&inner);
                return true;
            }
            if known && holds(range.0 as f64 / PROTECTED as f64) {
                return true;
            }
        }
        for s in inner {
            // Walk the integer positions over the span, the weight linear between them.
            let mut k = (a + s.enter).floor() as i64;
            let (mut below, mut above) = (line_weight(k), line_weight(k + 1));
            let mut t = s.enter;
            let mut w0 = weight_at(t, below, above);
            let mut free = !holds(w0);
            let mut open = free.then_some((s.enter, s.enter_normal));
            while t < s.exit {
                let next = ((k + 1) as f64 - a).min(s.exit);
                let w1 = if next < s.exit || (a + next).fract() == 0.0 { above } else { weight_at(next, below, above) };
                let free_end = !holds(w1);
                if free != free_end {
                    // The root of the linear weight on [t, next], kept inside it.
                    let root = if w1 != w0 { (t + (0.5 - w0) / (w1 - w0) * (next - t)).clamp(t, next) } else { next };
                    if free {
                        let (enter, enter_normal) = open.take().expect("a free part is open");
                        out.push(Span { enter, exit: root, enter_normal, exit_normal: normal_at(root, dir) });
                    } else {
                        open = Some((root, normal_at(root, -dir)));
                    }
                    free = free_end;
                }
                t = next;
                w0 = w1;
                k += 1;
                below = above;
                above = line_weight(k + 1);
            }
            if let Some((enter, enter_normal)) = open {
                out.push(Span { enter, exit: s.exit, enter_normal, exit_normal: s.exit_normal });
            }
        }
        true
    }

    fn lines_agree(&self) -> bool {
        self.inner.lines_agree()
    }
}
