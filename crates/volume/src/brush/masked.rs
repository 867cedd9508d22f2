//! A brush cut by a mask, so that a CSG edit leaves the nodes the mask holds as they are (see
//! [`crate::mask`]): for union and difference the brush becomes its part where the mask is
//! free (`B ∩ U`, `U` the points whose interpolated weight is below one half), for intersection
//! it takes in the held part too (`B ∪ H`). A held node is then never inside the cut brush
//! (union adds nothing there, difference removes nothing) and always inside the widened one
//! (intersection keeps it), and an edge with both nodes held lies wholly in `H` (the weight is
//! linear along it), so its crossing stays.

use glam::DVec3;

use super::{Aabb, Brush, Span, unit_axis};
use crate::mask::{MaskSampler, holds};

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
        let at = |t: f64| {
            let mut p = base;
            p[axis] += t;
            p
        };
        let weight = |t: f64| self.mask.at(at(t));
        let normal_at = |t: f64, fallback: DVec3| self.mask.gradient(at(t)).normalize_or(fallback);
        for s in inner {
            // The weight is linear between the nodes along the line: walk them over the span.
            let mut t = s.enter;
            let mut free = !holds(weight(t));
            let mut open = free.then_some((s.enter, s.enter_normal));
            let first = (base[axis] + s.enter).floor() + 1.0;
            let mut node = first;
            while t < s.exit {
                let next = (node - base[axis]).min(s.exit);
                let (w0, w1) = (weight(t), weight(next));
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
                node += 1.0;
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
