//! Any brush under a rigid motion and uniform scale.

use glam::{DQuat, DVec3};

use super::{Aabb, Brush, BrushError, Span, finite, positive, unit_axis, unit_rotation};

/// `inner` scaled by `scale`, rotated by `rotation`, then moved by `translation`:
/// `world = translation + rotation · (scale · local)`.
#[derive(Clone, Debug)]
pub struct Transformed<B> {
    inner: B,
    rotation: DQuat,
    inverse_rotation: DQuat,
    translation: DVec3,
    scale: f64,
}

impl<B: Brush> Transformed<B> {
    /// Places `inner`; a NaN, infinite or zero-length rotation, or a scale that is not finite
    /// and positive, is an error.
    pub fn new(inner: B, rotation: DQuat, translation: DVec3, scale: f64) -> Result<Self, BrushError> {
        let rotation = unit_rotation("brush rotation", rotation)?;
        Ok(Transformed {
            inner,
            rotation,
            inverse_rotation: rotation.inverse(),
            translation: finite("brush translation", translation)?,
            scale: positive("brush scale", scale)?,
        })
    }

    /// The brush being placed.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    /// `origin + p` in the inner brush's frame. The world point is formed first (exact for a
    /// chunk origin plus a small chunk-local offset), so every chunk that asks about one world
    /// point computes the same local point; `world - translation` is exact whenever the
    /// difference is representable, which keeps far-away edits identical to edits near 0.
    #[inline]
    fn to_local(&self, origin: DVec3, p: DVec3) -> DVec3 {
        self.inverse_rotation * ((origin + p) - self.translation) / self.scale
    }

    /// The line `origin + start + t · dir` in the inner frame, from a point that depends only on
    /// the world line (for a grid-axis direction, the point where the line passes the brush's
    /// translation along its axis), and the parameter of `origin + start` on it. Every chunk
    /// along one grid line then asks the inner brush exactly the same question, so ties (a line
    /// in a face's plane) are decided once per line, not once per chunk.
    fn local_line(&self, origin: DVec3, start: DVec3, dir: DVec3) -> (DVec3, DVec3, f64) {
        let local_dir = self.inverse_rotation * dir / self.scale;
        let mut rel = (origin + start) - self.translation;
        let shift = match unit_axis(dir) {
            Some(a) => std::mem::replace(&mut rel[a], 0.0),
            None => 0.0,
        };
        (self.inverse_rotation * rel / self.scale, local_dir, shift)
    }
}

impl<B: Brush> Brush for Transformed<B> {
    fn bounds(&self) -> Aabb {
        let corners = self.inner.bounds().corners();
        Aabb::from_points(corners.iter().map(|&c| self.translation + self.rotation * (c * self.scale)))
            .expect("eight corners")
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        self.inner.field(DVec3::ZERO, self.to_local(origin, p)) * self.scale
    }

    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        self.contains_on_line(origin, p, DVec3::X)
    }

    /// Inside as the spans of the line through the point say (when the inner brush answers
    /// lines by spans), so node states and line states come from one computation per line.
    fn contains_on_line(&self, origin: DVec3, p: DVec3, dir: DVec3) -> bool {
        let mut spans = Vec::new();
        if self.spans(origin, p, dir, &mut spans) {
            return spans.iter().any(|s| s.enter <= 0.0 && 0.0 <= s.exit);
        }
        let local_dir = self.inverse_rotation * dir / self.scale;
        self.inner.contains_on_line(DVec3::ZERO, self.to_local(origin, p), local_dir)
    }

    fn normal(&self, origin: DVec3, p: DVec3) -> DVec3 {
        self.rotation * self.inner.normal(DVec3::ZERO, self.to_local(origin, p))
    }

    fn lipschitz(&self) -> f64 {
        self.inner.lipschitz()
    }

    /// A rigid motion and a uniform scale (the field is multiplied by it) keep a distance a
    /// distance.
    fn field_is_distance(&self) -> bool {
        self.inner.field_is_distance()
    }

    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        let (local_start, local_dir, shift) = self.local_line(origin, start, dir);
        if !self.inner.spans(DVec3::ZERO, local_start, local_dir, out) {
            return false;
        }
        for s in out.iter_mut() {
            s.enter -= shift;
            s.exit -= shift;
            s.enter_normal = self.rotation * s.enter_normal;
            s.exit_normal = self.rotation * s.exit_normal;
        }
        true
    }

    /// Only without rotation: a rotation mixes the axes in floating point, so a face that a
    /// quarter turn lays on a grid plane is not exactly on it, and lines along different axes
    /// could decide its nodes differently. Rotated brushes therefore take node states from the x
    /// lines and have the others repaired to match.
    fn lines_agree(&self) -> bool {
        self.inner.lines_agree() && (self.rotation == DQuat::IDENTITY || self.rotation == -DQuat::IDENTITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brush::{Cuboid, Sphere};

    #[test]
    fn degenerate_transforms_are_errors() {
        let s = Sphere::new(DVec3::ZERO, 1.0).unwrap();
        assert!(Transformed::new(s, DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), DVec3::ZERO, 1.0).is_err());
        assert!(Transformed::new(s, DQuat::IDENTITY, DVec3::NAN, 1.0).is_err());
        assert!(Transformed::new(s, DQuat::IDENTITY, DVec3::ZERO, 0.0).is_err());
        assert!(Transformed::new(s, DQuat::IDENTITY, DVec3::ZERO, f64::INFINITY).is_err());
    }

    #[test]
    fn a_rotated_scaled_box_contains_what_its_spans_say() {
        let b = Cuboid::new(DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0)).unwrap();
        let t = Transformed::new(b, DQuat::from_rotation_z(0.5), DVec3::new(10.0, 0.0, 0.0), 2.0).unwrap();
        let mut out = Vec::new();
        assert!(t.spans(DVec3::new(8.0, 0.0, 0.0), DVec3::new(-20.0, 0.5, 0.25), DVec3::X, &mut out));
        assert_eq!(out.len(), 1);
        let mid = (out[0].enter + out[0].exit) / 2.0;
        assert!(t.contains(DVec3::new(8.0, 0.0, 0.0), DVec3::new(-20.0 + mid, 0.5, 0.25)));
        assert!(!t.contains(DVec3::new(8.0, 0.0, 0.0), DVec3::new(-20.0 + out[0].exit + 1e-6, 0.5, 0.25)));
        assert!(out[0].enter_normal.x < 0.0);
    }
}
