//! Analytic brushes. Spheres and sharp boxes answer lines in closed form; the others are exact
//! signed-distance fields (Lipschitz 1) sampled by the volume.

use glam::DVec3;

use super::{Aabb, Brush, BrushError, Span, finite, positive, unit_axis};

/// A ball.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    center: DVec3,
    radius: f64,
}

impl Sphere {
    /// A ball of `radius` cells around `center` (grid coordinates).
    pub fn new(center: DVec3, radius: f64) -> Result<Self, BrushError> {
        Ok(Sphere { center: finite("sphere centre", center)?, radius: positive("sphere radius", radius)? })
    }

    /// The centre.
    pub fn center(&self) -> DVec3 {
        self.center
    }

    /// The radius.
    pub fn radius(&self) -> f64 {
        self.radius
    }
}

impl Brush for Sphere {
    /// The exact signed distance.
    fn field_is_distance(&self) -> bool {
        true
    }

    fn bounds(&self) -> Aabb {
        Aabb::new(self.center - self.radius, self.center + self.radius)
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        (p - (self.center - origin)).length() - self.radius
    }

    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        (p - (self.center - origin)).length_squared() <= self.radius * self.radius
    }

    fn normal(&self, origin: DVec3, p: DVec3) -> DVec3 {
        (p - (self.center - origin)).normalize_or(DVec3::Z)
    }

    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        out.clear();
        let q = start - (self.center - origin);
        let (r2, inv_r) = (self.radius * self.radius, 1.0 / self.radius);
        match unit_axis(dir) {
            Some(0) => _ = self.axis_chord::<0>(q, r2, inv_r, out),
            Some(1) => _ = self.axis_chord::<1>(q, r2, inv_r, out),
            Some(_) => _ = self.axis_chord::<2>(q, r2, inv_r, out),
            None => out.extend(self.chord(q, dir, dir.length_squared(), r2, inv_r)),
        }
        true
    }

    fn spans_batch(&self, lines: &[(DVec3, DVec3)], dir: DVec3, out: &mut Vec<Span>, counts: &mut Vec<u32>) -> bool {
        counts.reserve(lines.len());
        out.reserve(lines.len());
        // What does not depend on the line, once; the grid's axis directions get a loop each.
        let (r2, inv_r) = (self.radius * self.radius, 1.0 / self.radius);
        match unit_axis(dir) {
            Some(0) => self.axis_chords::<0>(lines, r2, inv_r, out, counts),
            Some(1) => self.axis_chords::<1>(lines, r2, inv_r, out, counts),
            Some(_) => self.axis_chords::<2>(lines, r2, inv_r, out, counts),
            None => {
                let a = dir.length_squared();
                for &(origin, start) in lines {
                    let s = self.chord(start - (self.center - origin), dir, a, r2, inv_r);
                    counts.push(s.is_some() as u32);
                    out.extend(s);
                }
            }
        }
        true
    }
}

impl Sphere {
    /// [`Sphere::chord`] for the direction of grid axis `A`, where the dot product and the
    /// perpendicular part reduce to picking components: no multiplications by 0 and 1, no
    /// division. Appends the span to `out` (written in place: no `Option` to copy) and says
    /// whether there was one.
    #[inline(always)]
    fn axis_chord<const A: usize>(&self, q: DVec3, r2: f64, inv_r: f64, out: &mut Vec<Span>) -> bool {
        let (qa, perp2) = match A {
            0 => (q.x, q.y * q.y + q.z * q.z),
            1 => (q.y, q.x * q.x + q.z * q.z),
            _ => (q.z, q.x * q.x + q.y * q.y),
        };
        let disc = r2 - perp2;
        if !(disc >= 0.0) {
            return false;
        }
        let h = disc.sqrt();
        let (t0, t1) = (-qa - h, -qa + h);
        let across = q * inv_r;
        let mut enter_normal = across;
        let mut exit_normal = across;
        enter_normal[A] = (qa + t0) * inv_r;
        exit_normal[A] = (qa + t1) * inv_r;
        out.push(Span { enter: t0, exit: t1, enter_normal, exit_normal });
        true
    }

    /// [`Sphere::axis_chord`] for a batch of lines.
    #[inline(always)]
    fn axis_chords<const A: usize>(
        &self,
        lines: &[(DVec3, DVec3)],
        r2: f64,
        inv_r: f64,
        out: &mut Vec<Span>,
        counts: &mut Vec<u32>,
    ) {
        for &(origin, start) in lines {
            let hit = self.axis_chord::<A>(start - (self.center - origin), r2, inv_r, out);
            counts.push(hit as u32);
        }
    }

    /// The span of the line `q + t dir` (relative to the centre), given `a = |dir|²`, the
    /// squared radius and its inverse.
    #[inline(always)]
    fn chord(&self, q: DVec3, dir: DVec3, a: f64, r2: f64, inv_r: f64) -> Option<Span> {
        if !(a > 0.0) {
            return None;
        }
        // Closest approach first, then the half chord from the perpendicular distance: no
        // cancellation.
        let t_mid = -q.dot(dir) / a;
        let perp = q + dir * t_mid;
        let disc = r2 - perp.length_squared();
        if !(disc >= 0.0) {
            return None;
        }
        let h = (disc / a).sqrt();
        let (t0, t1) = (t_mid - h, t_mid + h);
        Some(Span { enter: t0, exit: t1, enter_normal: (q + dir * t0) * inv_r, exit_normal: (q + dir * t1) * inv_r })
    }
}

/// A box with edges along its own axes, optionally with rounded edges and corners. Use
/// [`super::Transformed`] (or [`Cuboid::oriented`]) for a rotated box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cuboid {
    center: DVec3,
    half: DVec3,
    rounding: f64,
}

impl Cuboid {
    /// A sharp box of half extents `half` around `center`.
    pub fn new(center: DVec3, half: DVec3) -> Result<Self, BrushError> {
        Self::rounded(center, half, 0.0)
    }

    /// A box whose edges and corners are rounded with `rounding` cells (at most the smallest half
    /// extent; 0 for sharp).
    pub fn rounded(center: DVec3, half: DVec3, rounding: f64) -> Result<Self, BrushError> {
        for v in half.to_array() {
            positive("box half extent", v)?;
        }
        if !(rounding.is_finite() && rounding >= 0.0 && rounding <= half.min_element()) {
            return Err(BrushError::BadSize { what: "box rounding", value: rounding });
        }
        Ok(Cuboid { center: finite("box centre", center)?, half, rounding })
    }

    /// An oriented box: this box rotated by `rotation` about its centre.
    pub fn oriented(
        center: DVec3,
        half: DVec3,
        rotation: glam::DQuat,
        rounding: f64,
    ) -> Result<super::Transformed<Cuboid>, BrushError> {
        let local = Cuboid::rounded(DVec3::ZERO, half, rounding)?;
        super::Transformed::new(local, rotation, center, 1.0)
    }
}

impl Brush for Cuboid {
    /// The exact signed distance.
    fn field_is_distance(&self) -> bool {
        true
    }

    fn bounds(&self) -> Aabb {
        Aabb::new(self.center - self.half, self.center + self.half)
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        let r = self.rounding;
        let q = (p - (self.center - origin)).abs() - (self.half - r);
        q.max(DVec3::ZERO).length() + q.max_element().min(0.0) - r
    }

    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        if self.rounding > 0.0 {
            return self.field(origin, p) <= 0.0;
        }
        (p - (self.center - origin)).abs().cmple(self.half).all()
    }

    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        if self.rounding > 0.0 {
            return false;
        }
        out.clear();
        let q = start - (self.center - origin);
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        let (mut n0, mut n1) = (DVec3::ZERO, DVec3::ZERO);
        for i in 0..3 {
            let h = self.half[i];
            if dir[i] == 0.0 {
                if q[i].abs() > h {
                    return true;
                }
                continue;
            }
            let ta = (-h - q[i]) / dir[i];
            let tb = (h - q[i]) / dir[i];
            let (lo, hi) = if ta <= tb { (ta, tb) } else { (tb, ta) };
            let mut axis = DVec3::ZERO;
            axis[i] = dir[i].signum();
            if lo > t0 {
                t0 = lo;
                n0 = -axis;
            }
            if hi < t1 {
                t1 = hi;
                n1 = axis;
            }
        }
        if t0 <= t1 && t0.is_finite() && t1.is_finite() {
            out.push(Span { enter: t0, exit: t1, enter_normal: n0, exit_normal: n1 });
        }
        true
    }
}

/// A capsule: all points within `radius` of the segment `a`–`b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Capsule {
    a: DVec3,
    b: DVec3,
    radius: f64,
}

impl Capsule {
    /// The capsule around segment `a`–`b` (equal ends give a ball).
    pub fn new(a: DVec3, b: DVec3, radius: f64) -> Result<Self, BrushError> {
        Ok(Capsule {
            a: finite("capsule end", a)?,
            b: finite("capsule end", b)?,
            radius: positive("capsule radius", radius)?,
        })
    }
}

impl Brush for Capsule {
    /// The exact signed distance.
    fn field_is_distance(&self) -> bool {
        true
    }

    fn bounds(&self) -> Aabb {
        Aabb::new(self.a.min(self.b) - self.radius, self.a.max(self.b) + self.radius)
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        let pa = p - (self.a - origin);
        let ba = self.b - self.a;
        let bb = ba.length_squared();
        let h = if bb > 0.0 { (pa.dot(ba) / bb).clamp(0.0, 1.0) } else { 0.0 };
        (pa - ba * h).length() - self.radius
    }
}

/// Splits `q` into its component along the unit `axis` and the distance from the axis.
fn axial(q: DVec3, axis: DVec3) -> (f64, f64) {
    let y = q.dot(axis);
    (y, (q - axis * y).length())
}

/// Half extents of a disc of `radius` perpendicular to the unit `axis`.
fn disc_extent(axis: DVec3, radius: f64) -> DVec3 {
    (DVec3::ONE - axis * axis).max(DVec3::ZERO).map(f64::sqrt) * radius
}

/// A capped cylinder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    center: DVec3,
    axis: DVec3,
    half_height: f64,
    radius: f64,
}

impl Cylinder {
    /// A cylinder around `center` whose axis points along `axis` (any non-zero length).
    pub fn new(center: DVec3, axis: DVec3, half_height: f64, radius: f64) -> Result<Self, BrushError> {
        let axis =
            finite("cylinder axis", axis)?.try_normalize().ok_or(BrushError::NotFinite { what: "cylinder axis" })?;
        Ok(Cylinder {
            center: finite("cylinder centre", center)?,
            axis,
            half_height: positive("cylinder half height", half_height)?,
            radius: positive("cylinder radius", radius)?,
        })
    }
}

impl Brush for Cylinder {
    /// The exact signed distance.
    fn field_is_distance(&self) -> bool {
        true
    }

    fn bounds(&self) -> Aabb {
        let e = self.axis.abs() * self.half_height + disc_extent(self.axis, self.radius);
        Aabb::new(self.center - e, self.center + e)
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        let (y, rho) = axial(p - (self.center - origin), self.axis);
        let dx = rho - self.radius;
        let dy = y.abs() - self.half_height;
        dx.max(dy).min(0.0) + (dx.max(0.0).powi(2) + dy.max(0.0).powi(2)).sqrt()
    }
}

/// A ring torus.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Torus {
    center: DVec3,
    axis: DVec3,
    major: f64,
    minor: f64,
}

impl Torus {
    /// A torus around `center` in the plane perpendicular to `axis`, with ring radius `major`
    /// and tube radius `minor`.
    pub fn new(center: DVec3, axis: DVec3, major: f64, minor: f64) -> Result<Self, BrushError> {
        let axis = finite("torus axis", axis)?.try_normalize().ok_or(BrushError::NotFinite { what: "torus axis" })?;
        Ok(Torus {
            center: finite("torus centre", center)?,
            axis,
            major: positive("torus major radius", major)?,
            minor: positive("torus minor radius", minor)?,
        })
    }
}

impl Brush for Torus {
    /// The exact signed distance.
    fn field_is_distance(&self) -> bool {
        true
    }

    fn bounds(&self) -> Aabb {
        let e = disc_extent(self.axis, self.major + self.minor) + self.axis.abs() * self.minor;
        Aabb::new(self.center - e, self.center + e)
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        let (y, rho) = axial(p - (self.center - origin), self.axis);
        ((rho - self.major).powi(2) + y * y).sqrt() - self.minor
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_sizes_are_errors_not_panics() {
        assert!(Sphere::new(DVec3::ZERO, f64::NAN).is_err());
        assert!(Sphere::new(DVec3::ZERO, -1.0).is_err());
        assert!(Sphere::new(DVec3::ZERO, 0.0).is_err());
        assert!(Sphere::new(DVec3::INFINITY, 1.0).is_err());
        assert!(Cuboid::new(DVec3::ZERO, DVec3::new(1.0, 0.0, 1.0)).is_err());
        assert!(Cuboid::rounded(DVec3::ZERO, DVec3::ONE, 2.0).is_err());
        assert!(Capsule::new(DVec3::ZERO, DVec3::NAN, 1.0).is_err());
        assert!(Cylinder::new(DVec3::ZERO, DVec3::ZERO, 1.0, 1.0).is_err());
        assert!(Torus::new(DVec3::ZERO, DVec3::Z, 3.0, f64::INFINITY).is_err());
    }

    #[test]
    fn sphere_spans_match_its_predicate() {
        let s = Sphere::new(DVec3::new(0.3, 0.2, -0.1), 5.0).unwrap();
        let mut out = Vec::new();
        assert!(s.spans(DVec3::ZERO, DVec3::new(-10.0, 1.0, 2.0), DVec3::X, &mut out));
        let sp = out[0];
        for t in [sp.enter + 1e-9, sp.exit - 1e-9] {
            assert!(s.contains(DVec3::ZERO, DVec3::new(-10.0 + t, 1.0, 2.0)));
        }
        assert!(!s.contains(DVec3::ZERO, DVec3::new(-10.0 + sp.enter - 1e-6, 1.0, 2.0)));
        assert!((sp.enter_normal.length() - 1.0).abs() < 1e-12);
        assert!(sp.enter_normal.x < 0.0 && sp.exit_normal.x > 0.0);
    }

    #[test]
    fn box_spans_report_face_normals() {
        let b = Cuboid::new(DVec3::ZERO, DVec3::new(2.0, 3.0, 4.0)).unwrap();
        let mut out = Vec::new();
        b.spans(DVec3::ZERO, DVec3::new(0.5, -10.0, 0.5), DVec3::Y, &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!((out[0].enter, out[0].exit), (7.0, 13.0));
        assert_eq!(out[0].enter_normal, -DVec3::Y);
        b.spans(DVec3::ZERO, DVec3::new(2.5, -10.0, 0.5), DVec3::Y, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn sampled_shapes_have_exact_distances_at_known_points() {
        let c = Capsule::new(DVec3::ZERO, DVec3::new(0.0, 0.0, 10.0), 2.0).unwrap();
        assert!((c.field(DVec3::ZERO, DVec3::new(5.0, 0.0, 5.0)) - 3.0).abs() < 1e-12);
        let cy = Cylinder::new(DVec3::ZERO, DVec3::Z, 5.0, 2.0).unwrap();
        assert!((cy.field(DVec3::ZERO, DVec3::new(0.0, 0.0, 7.0)) - 2.0).abs() < 1e-12);
        let t = Torus::new(DVec3::ZERO, DVec3::Z, 6.0, 1.0).unwrap();
        assert!((t.field(DVec3::ZERO, DVec3::new(6.0, 0.0, 0.0)) + 1.0).abs() < 1e-12);
        assert!((t.bounds().max - DVec3::new(7.0, 7.0, 1.0)).length() < 1e-12);
    }
}
