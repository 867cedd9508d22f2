//! An orbit camera: a target, a distance, yaw and pitch; y is up.

use glam::{Mat4, Vec3, Vec4Swizzles};

/// The axis views of [`Camera::axis_view`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisView {
    /// From +z (numpad 1).
    Front,
    /// From +x (numpad 3).
    Right,
    /// From +y (numpad 7).
    Top,
}

/// Orbits `target` at `distance`, turned by `yaw` about +y and raised by `pitch`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// The point looked at and orbited.
    pub target: Vec3,
    /// Distance from the target.
    pub distance: f32,
    /// Radians about +y.
    pub yaw: f32,
    /// Radians above the horizon, within ±1.54.
    pub pitch: f32,
    /// Vertical field of view (radians); an orthographic view shows the height the perspective
    /// view has at the target.
    pub fov_y: f32,
    /// Orthographic instead of perspective projection.
    pub orthographic: bool,
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            target: Vec3::new(32.0, 16.0, 32.0),
            distance: 110.0,
            yaw: 0.7,
            pitch: 0.45,
            fov_y: 0.8,
            orthographic: false,
        }
    }
}

impl Camera {
    /// The eye position.
    pub fn eye(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + Vec3::new(cp * sy, sp, cp * cy) * self.distance
    }

    fn near_far(&self) -> (f32, f32) {
        ((self.distance * 0.01).max(0.01), self.distance * 20.0 + 1000.0)
    }

    /// World to clip space for a viewport of `aspect` (width / height), depth 0..1.
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let (near, far) = self.near_far();
        // wgpu's clip space: depth 0..1, y up (the DirectX convention).
        let aspect = aspect.max(1e-3);
        let proj = if self.orthographic {
            let h = self.distance * (self.fov_y * 0.5).tan();
            let w = h * aspect;
            glam::camera::rh::proj::directx::orthographic(-w, w, -h, h, near, far)
        } else {
            glam::camera::rh::proj::directx::perspective(self.fov_y, aspect, near, far)
        };
        // (The pitch stays within ±1.54, so +y is never the view direction.)
        proj * glam::camera::rh::view::look_at_mat4(self.eye(), self.target, Vec3::Y)
    }

    /// The world ray through a viewport point given in normalised device coordinates
    /// (`x`, `y` in −1..1, y up): origin on the near plane and unit direction.
    pub fn ray(&self, ndc_x: f32, ndc_y: f32, aspect: f32) -> (Vec3, Vec3) {
        let inv = self.view_proj(aspect).inverse();
        let near = inv * glam::Vec4::new(ndc_x, ndc_y, 0.0, 1.0);
        let far = inv * glam::Vec4::new(ndc_x, ndc_y, 1.0, 1.0);
        let (near, far) = (near.xyz() / near.w, far.xyz() / far.w);
        (near, (far - near).normalize_or(Vec3::NEG_Z))
    }

    /// Looks along a world axis at the target, keeping the distance: `view` as the numpad's
    /// views name it (front looks along −z from +z, right along −x from +x, top down from +y;
    /// `opposite` gives back, left and bottom).
    pub fn axis_view(&mut self, view: AxisView, opposite: bool) {
        let (yaw, pitch) = match view {
            AxisView::Front => (0.0, 0.0),
            AxisView::Right => (std::f32::consts::FRAC_PI_2, 0.0),
            AxisView::Top => (0.0, 1.54),
        };
        (self.yaw, self.pitch) = match (view, opposite) {
            (AxisView::Top, true) => (yaw, -pitch),
            (_, true) => (yaw + std::f32::consts::PI, pitch),
            _ => (yaw, pitch),
        };
    }

    /// Turns the camera by `dyaw` and `dpitch` radians.
    pub fn orbit(&mut self, dyaw: f32, dpitch: f32) {
        self.yaw += dyaw;
        self.pitch = (self.pitch + dpitch).clamp(-1.54, 1.54);
    }

    /// Moves the target in the view plane by `dx`, `dy` (fractions of the distance).
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let forward = (self.target - self.eye()).normalize_or(Vec3::NEG_Z);
        let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
        let up = right.cross(forward);
        self.target += (right * dx + up * dy) * self.distance;
    }

    /// Scales the distance by `factor` (below 1 zooms in).
    pub fn zoom(&mut self, factor: f32) {
        if factor.is_finite() && factor > 0.0 {
            self.distance = (self.distance * factor).clamp(0.5, 1.0e5);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_ray_points_at_the_target() {
        let c = Camera::default();
        let (o, d) = c.ray(0.0, 0.0, 1.5);
        let to_target = (c.target - o).normalize();
        assert!(d.dot(to_target) > 0.9999, "{d} vs {to_target}");
        let clip = c.view_proj(1.5) * c.target.extend(1.0);
        assert!((clip.x / clip.w).abs() < 1e-4 && (clip.y / clip.w).abs() < 1e-4);
    }

    #[test]
    fn axis_views_and_the_orthographic_projection() {
        let mut c = Camera::default();
        c.axis_view(AxisView::Front, false);
        assert!((c.eye() - c.target).normalize().abs_diff_eq(Vec3::Z, 1e-5));
        c.axis_view(AxisView::Right, true);
        assert!((c.eye() - c.target).normalize().abs_diff_eq(-Vec3::X, 1e-5));
        c.axis_view(AxisView::Top, false);
        assert!((c.eye() - c.target).normalize().y > 0.99);
        assert!(c.view_proj(1.5).is_finite());
        // Orthographic: every ray through the viewport is parallel, and the target projects to
        // the centre as in perspective.
        c.axis_view(AxisView::Front, false);
        c.orthographic = true;
        let (o1, d1) = c.ray(-0.5, 0.3, 1.5);
        let (o2, d2) = c.ray(0.7, -0.2, 1.5);
        assert!(d1.abs_diff_eq(d2, 1e-5) && d1.abs_diff_eq(-Vec3::Z, 1e-4));
        assert!((o1 - o2).length() > 1.0);
        let p = c.view_proj(1.5) * c.target.extend(1.0);
        assert!((p.x / p.w).abs() < 1e-5 && (p.y / p.w).abs() < 1e-5);
    }

    #[test]
    fn orbit_pan_and_zoom_keep_the_camera_sane() {
        let mut c = Camera::default();
        c.orbit(0.3, 10.0);
        assert!(c.pitch <= 1.54);
        let before = c.target;
        c.pan(0.1, 0.0);
        assert!((c.target - before).length() > 1.0);
        c.zoom(0.5);
        assert!((c.distance - 55.0).abs() < 1e-3);
        c.zoom(f32::NAN);
        c.zoom(0.0);
        assert!((c.distance - 55.0).abs() < 1e-3);
    }
}
