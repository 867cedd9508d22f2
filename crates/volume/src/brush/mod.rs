//! Brushes: closed shapes that answer, for one grid line, where the line is inside them.
//!
//! Every method takes an `origin` and a point or ray *relative to it*: the world point is
//! `origin + p`. The volume passes the (integer, exactly representable) origin of the chunk being
//! edited, and brushes subtract it from their own placement first, so the arithmetic that decides
//! a crossing depends only on chunk-local quantities. That is what makes an edit at the origin and
//! the same edit a million cells away store identical chunk-local data (exactly so whenever the
//! brush's placement is exactly representable after the shift, e.g. any multiple of 2⁻²⁰).
//!
//! A brush answers a line in one of two ways:
//! - [`Brush::spans`]: the sorted intervals where the ray is inside, with normals (closed forms
//!   for spheres and boxes, ray casting for meshes). The volume then re-evaluates
//!   [`Brush::contains`] at any node within [`SNAP_DISTANCE`] of an interval end, so node states
//!   follow the predicate even where the closed form rounds differently.
//! - otherwise the volume samples [`Brush::contains`] at every node the line passes and finds
//!   each crossing by bracketing a sign change of [`Brush::field`] inside its cell; the field's
//!   Lipschitz bound ([`Brush::lipschitz`]) lets it skip nodes that cannot be near the surface.

mod masked;
mod mesh;
mod sdf;
mod shapes;
mod transform;

pub(crate) use masked::Masked;
pub use mesh::{MeshBrush, MeshError, MeshRule};
pub use sdf::SdfBrush;
pub use shapes::{Capsule, Cuboid, Cylinder, Sphere, Torus};
pub use transform::Transformed;

use glam::{DQuat, DVec3};
use thiserror::Error;

/// Node states within this distance (grid units) of a span end are re-evaluated with
/// [`Brush::contains`]. Closed-form roots are accurate to about 1e-12 cells for brushes up to a
/// million cells; 1e-6 leaves a wide margin and costs a predicate call only for nodes that
/// practically sit on the surface.
pub const SNAP_DISTANCE: f64 = 1e-6;

/// An axis-aligned box in grid space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: DVec3,
    /// Maximum corner.
    pub max: DVec3,
}

impl Aabb {
    /// The box spanning two corners.
    pub fn new(min: DVec3, max: DVec3) -> Self {
        Aabb { min, max }
    }

    /// Whether both corners are finite and ordered.
    pub fn is_valid(&self) -> bool {
        self.min.is_finite() && self.max.is_finite() && self.min.cmple(self.max).all()
    }

    /// The box grown by `d` on every side.
    pub fn expand(&self, d: f64) -> Aabb {
        Aabb::new(self.min - DVec3::splat(d), self.max + DVec3::splat(d))
    }

    /// The box moved by `d`.
    pub fn translate(&self, d: DVec3) -> Aabb {
        Aabb::new(self.min + d, self.max + d)
    }

    /// Whether the point lies in the closed box.
    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The eight corners.
    pub fn corners(&self) -> [DVec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            DVec3::new(a.x, a.y, a.z),
            DVec3::new(b.x, a.y, a.z),
            DVec3::new(a.x, b.y, a.z),
            DVec3::new(b.x, b.y, a.z),
            DVec3::new(a.x, a.y, b.z),
            DVec3::new(b.x, a.y, b.z),
            DVec3::new(a.x, b.y, b.z),
            DVec3::new(b.x, b.y, b.z),
        ]
    }

    /// The smallest box holding all points.
    pub fn from_points(points: impl IntoIterator<Item = DVec3>) -> Option<Aabb> {
        let mut it = points.into_iter();
        let first = it.next()?;
        let (mut min, mut max) = (first, first);
        for p in it {
            min = min.min(p);
            max = max.max(p);
        }
        Some(Aabb::new(min, max))
    }
}

/// An interval of a ray inside a brush: `origin + start + t · dir` for `t` in `[enter, exit]`,
/// with the outward normals at both ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Ray parameter where the ray enters.
    pub enter: f64,
    /// Ray parameter where the ray leaves.
    pub exit: f64,
    /// Outward unit normal at the entry.
    pub enter_normal: DVec3,
    /// Outward unit normal at the exit.
    pub exit_normal: DVec3,
}

/// A closed solid that can be added to, subtracted from or intersected with a volume.
///
/// Coordinates are grid units (one unit per base cell); see the module docs for `origin`.
pub trait Brush: Send + Sync {
    /// A box holding the whole solid (absolute grid coordinates).
    fn bounds(&self) -> Aabb;

    /// A function negative inside and positive outside, `lipschitz()`-Lipschitz: the exact
    /// signed distance for the analytic shapes.
    fn field(&self, origin: DVec3, p: DVec3) -> f64;

    /// The inside predicate that defines node states: a node is inside iff this holds there.
    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        self.field(origin, p) <= 0.0
    }

    /// The inside predicate for brushes whose inside depends on a ray direction (meshes with
    /// holes): inside as seen along the line through the point with direction `dir`. The volume
    /// defines node states by `contains`, which transformed brushes answer along the world x
    /// axis through this method. Defaults to `contains`.
    fn contains_on_line(&self, origin: DVec3, p: DVec3, dir: DVec3) -> bool {
        let _ = dir;
        self.contains(origin, p)
    }

    /// The outward unit normal near the surface point `origin + p`.
    fn normal(&self, origin: DVec3, p: DVec3) -> DVec3 {
        let e = 1e-5;
        let d = |v: DVec3| self.field(origin, p + v) - self.field(origin, p - v);
        DVec3::new(d(DVec3::X * e), d(DVec3::Y * e), d(DVec3::Z * e)).normalize_or(DVec3::Z)
    }

    /// A bound `L` with `|field(a) - field(b)| ≤ L |a - b|`.
    fn lipschitz(&self) -> f64 {
        1.0
    }

    /// Whether [`Brush::field`] is known to be 1-Lipschitz with the sign of [`Brush::contains`]
    /// away from the surface (the exact signed distances of the analytic shapes): the volume
    /// then decides a whole chunk from one field value at its centre (every node inside, or
    /// none), so an edit costs its surface, not the volume it fills. User fields and meshes,
    /// whose fields cannot be trusted, answer `false` (the default).
    fn field_is_distance(&self) -> bool {
        false
    }

    /// Fills `out` with the sorted, disjoint spans where the infinite line
    /// `origin + start + t · dir` is inside, and returns `true`; or returns `false` if the brush
    /// answers lines by sampling instead.
    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        let _ = (origin, start, dir, out);
        false
    }

    /// [`Brush::spans`] for many lines with one direction: line `i` is
    /// `lines[i].0 + lines[i].1 + t · dir` (origin, start). Appends each line's spans to `out`
    /// and their number to `counts`, in line order; returns `false` (appending nothing) if the
    /// brush samples instead. Must give exactly what `spans` gives line by line (the default
    /// does just that); closed forms override it to save a call and a copy per line.
    fn spans_batch(&self, lines: &[(DVec3, DVec3)], dir: DVec3, out: &mut Vec<Span>, counts: &mut Vec<u32>) -> bool {
        let (out_len, counts_len) = (out.len(), counts.len());
        let mut line = Vec::new();
        for &(origin, start) in lines {
            if !self.spans(origin, start, dir, &mut line) {
                out.truncate(out_len);
                counts.truncate(counts_len);
                return false;
            }
            counts.push(line.len() as u32);
            out.extend_from_slice(&line);
        }
        true
    }

    /// Whether lines along x, y and z always agree on node states. Brushes that cannot promise
    /// it (meshes with holes, user fields whose Lipschitz bound may be wrong) return `false`, and
    /// the volume then takes node states from the x lines and repairs the y and z lines.
    fn lines_agree(&self) -> bool {
        true
    }
}

/// Forwards every `Brush` method through a pointer type.
macro_rules! forward_brush {
    ($($ptr:ty),*) => {$(
        impl<B: Brush + ?Sized> Brush for $ptr {
            fn bounds(&self) -> Aabb {
                (**self).bounds()
            }
            fn field(&self, origin: DVec3, p: DVec3) -> f64 {
                (**self).field(origin, p)
            }
            fn contains(&self, origin: DVec3, p: DVec3) -> bool {
                (**self).contains(origin, p)
            }
            fn contains_on_line(&self, origin: DVec3, p: DVec3, dir: DVec3) -> bool {
                (**self).contains_on_line(origin, p, dir)
            }
            fn normal(&self, origin: DVec3, p: DVec3) -> DVec3 {
                (**self).normal(origin, p)
            }
            fn lipschitz(&self) -> f64 {
                (**self).lipschitz()
            }
            fn field_is_distance(&self) -> bool {
                (**self).field_is_distance()
            }
            fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
                (**self).spans(origin, start, dir, out)
            }
            fn spans_batch(
                &self,
                lines: &[(DVec3, DVec3)],
                dir: DVec3,
                out: &mut Vec<Span>,
                counts: &mut Vec<u32>,
            ) -> bool {
                (**self).spans_batch(lines, dir, out, counts)
            }
            fn lines_agree(&self) -> bool {
                (**self).lines_agree()
            }
        }
    )*};
}

forward_brush!(&B, Box<B>, std::sync::Arc<B>);

/// A brush parameter that cannot make a solid.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum BrushError {
    /// A size (radius, half extent, scale) that is zero, negative, NaN or infinite.
    #[error("{what} must be finite and positive, got {value}")]
    BadSize {
        /// Which parameter.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A position or rotation that is NaN or infinite, or a zero-length rotation quaternion.
    #[error("{what} must be finite")]
    NotFinite {
        /// Which parameter.
        what: &'static str,
    },
    /// A mesh that cannot be a brush.
    #[error(transparent)]
    Mesh(#[from] MeshError),
}

/// The index of the unit axis `dir` is exactly (`+x`, `+y` or `+z`), if any: lines along a grid
/// axis, which brushes answer by faster paths.
#[inline]
pub(crate) fn unit_axis(dir: DVec3) -> Option<usize> {
    [DVec3::X, DVec3::Y, DVec3::Z].iter().position(|&a| a == dir)
}

pub(crate) fn positive(what: &'static str, value: f64) -> Result<f64, BrushError> {
    if value.is_finite() && value > 0.0 { Ok(value) } else { Err(BrushError::BadSize { what, value }) }
}

pub(crate) fn finite(what: &'static str, v: DVec3) -> Result<DVec3, BrushError> {
    if v.is_finite() { Ok(v) } else { Err(BrushError::NotFinite { what }) }
}

pub(crate) fn unit_rotation(what: &'static str, q: DQuat) -> Result<DQuat, BrushError> {
    let l = q.length();
    if q.is_finite() && l > 1e-12 { Ok(q / l) } else { Err(BrushError::NotFinite { what }) }
}
