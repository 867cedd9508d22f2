//! Any brush under a rigid motion and uniform scale.

use glam::{DQuat, DVec3};

use super::{Aabb, Brush, BrushError, Span, finite, positive, unit_rotation};

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

    /// `origin + p` in the inner brush's frame. `origin - translation` is exact whenever the
    /// difference is representable, which keeps far-away edits identical to edits near 0.
    #[inline]
    fn to_local(&self, origin: DVec3, p: DVec3) -> DVec3 {
        self.inverse_rotation * ((origin - self.translation) + p) / self.scale
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

    fn contains_on_line(&self, origin: DVec3, p: DVec3, dir: DVec3) -> bool {
        let local_dir = self.inverse_rotation * dir / self.scale;
        self.inner.contains_on_line(DVec3::ZERO, self.to_local(origin, p), local_dir)
    }

    fn normal(&self, origin: DVec3, p: DVec3) -> DVec3 {
        self.rotation * self.inner.normal(DVec3::ZERO, self.to_local(origin, p))
    }

    fn lipschitz(&self) -> f64 {
        self.inner.lipschitz()
    }

    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        let local_start = self.to_local(origin, start);
        let local_dir = self.inverse_rotation * dir / self.scale;
        if !self.inner.spans(DVec3::ZERO, local_start, local_dir, out) {
            return false;
        }
        for s in out.iter_mut() {
            s.enter_normal = self.rotation * s.enter_normal;
            s.exit_normal = self.rotation * s.exit_normal;
        }
        true
    }

    fn lines_agree(&self) -> bool {
        self.inner.lines_agree()
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
