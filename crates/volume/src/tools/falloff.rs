//! Falloff curves: how a dab's strength falls from its centre (`t = 0`) to its rim (`t = 1`).
//! The default is SculptGL's smooth polynomial ([`super::falloff`]); a few other shapes are
//! named, as in Blender's brush falloff menu, and any curve through up to
//! [`MAX_CURVE_POINTS`] points can be edited ([`FalloffCurve`], interpolated by a monotone
//! cubic, so it never overshoots its points).
//!
//! The region tools weigh their nodes by it (smooth, inflate, flatten, paint and the mask dabs,
//! through [`super::Dab::weight`]). Grab and pinch keep the smooth falloff whatever the dab says:
//! their sub-steps are sized from its slope so that the surface never folds, which a steep curve
//! would break.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The most points an edited curve holds.
pub const MAX_CURVE_POINTS: usize = 8;

/// A falloff shape.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub enum Falloff {
    /// `3t⁴ − 4t³ + 1`: flat at the centre and at the rim (the default).
    #[default]
    Smooth,
    /// `√(1 − t²)`: a ball's profile, full almost to the rim.
    Sphere,
    /// `√(1 − t)`: full in the middle, steep at the rim.
    Root,
    /// `(1 − t)²`: a sharp peak at the centre.
    Sharp,
    /// `1 − t`: a cone.
    Linear,
    /// `1` up to the rim: a flat disc.
    Constant,
    /// An edited curve.
    Curve(FalloffCurve),
}

impl Falloff {
    /// The named shapes, in the menu's order.
    pub const NAMED: [Falloff; 6] =
        [Falloff::Smooth, Falloff::Sphere, Falloff::Root, Falloff::Sharp, Falloff::Linear, Falloff::Constant];

    /// Its name.
    pub fn name(&self) -> &'static str {
        match self {
            Falloff::Smooth => "Smooth",
            Falloff::Sphere => "Sphere",
            Falloff::Root => "Root",
            Falloff::Sharp => "Sharp",
            Falloff::Linear => "Linear",
            Falloff::Constant => "Constant",
            Falloff::Curve(_) => "Custom",
        }
    }

    /// The weight at `t` (distance from the centre over the radius): in `[0, 1]`, 0 from the rim
    /// on and for NaN.
    pub fn at(&self, t: f64) -> f64 {
        if !(t < 1.0) {
            return 0.0;
        }
        let t = t.max(0.0);
        let v = match self {
            Falloff::Smooth => super::falloff(t),
            Falloff::Sphere => (1.0 - t * t).sqrt(),
            Falloff::Root => (1.0 - t).sqrt(),
            Falloff::Sharp => (1.0 - t) * (1.0 - t),
            Falloff::Linear => 1.0 - t,
            Falloff::Constant => 1.0,
            Falloff::Curve(c) => c.at(t),
        };
        if v >= 0.0 { v.min(1.0) } else { 0.0 }
    }

    /// Whether its numbers are sound (an edited curve's points checked as
    /// [`FalloffCurve::new`] checks them; a curve from the network may not be).
    pub fn is_valid(&self) -> bool {
        match self {
            Falloff::Curve(c) => c.is_valid(),
            _ => true,
        }
    }

    /// The shape as an editable curve: an edited one as it is, a named one sampled at five
    /// points.
    pub fn to_curve(&self) -> FalloffCurve {
        match self {
            Falloff::Curve(c) => *c,
            other => {
                let points: Vec<(f64, f64)> =
                    [0.0, 0.25, 0.5, 0.75, 1.0].iter().map(|&t| (t, if t < 1.0 { other.at(t) } else { 0.0 })).collect();
                FalloffCurve::new(&points).expect("five ordered points in the unit square")
            }
        }
    }

    /// The numbers it carries (for finiteness checks of what arrives over the network).
    pub fn numbers(&self) -> Vec<f64> {
        match self {
            Falloff::Curve(c) => c.points().iter().flat_map(|&(t, v)| [t, v]).collect(),
            _ => Vec::new(),
        }
    }
}

/// Why points do not make a falloff curve.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FalloffError {
    /// Fewer than two points or more than [`MAX_CURVE_POINTS`].
    #[error("a falloff curve has 2 to {MAX_CURVE_POINTS} points, not {0}")]
    Count(usize),
    /// A coordinate outside `[0, 1]` or not finite, ends not at `t = 0` and `t = 1`, or `t` not
    /// increasing.
    #[error("a falloff curve's points must run from t = 0 to t = 1 with t increasing and values in [0, 1]")]
    Points,
}

/// An edited falloff (or any curve on the unit square: the editor's pressure curves are these
/// too): points `(t, value)` from `t = 0` to `t = 1`, `t` increasing, values in `[0, 1]`, joined
/// by a monotone cubic (Fritsch–Butland tangents: no overshoot, flat where a point is a peak or
/// a valley).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FalloffCurve {
    points: [[f32; 2]; MAX_CURVE_POINTS],
    len: u8,
}

impl FalloffCurve {
    /// A curve through `points`, checked (see [`FalloffError`]).
    pub fn new(points: &[(f64, f64)]) -> Result<Self, FalloffError> {
        if !(2..=MAX_CURVE_POINTS).contains(&points.len()) {
            return Err(FalloffError::Count(points.len()));
        }
        let unit = |x: f64| (0.0..=1.0).contains(&x);
        let ordered = points.windows(2).all(|w| w[0].0 < w[1].0);
        let ends = points[0].0 == 0.0 && points[points.len() - 1].0 == 1.0;
        if !(ordered && ends && points.iter().all(|&(t, v)| unit(t) && unit(v))) {
            return Err(FalloffError::Points);
        }
        let mut out = [[0.0f32; 2]; MAX_CURVE_POINTS];
        for (o, &(t, v)) in out.iter_mut().zip(points) {
            *o = [t as f32, v as f32];
        }
        // (Rounding to f32 keeps the order: the points' t differ by more than an f32's step
        // only if the caller's do; two that round together are refused.)
        if !out[..points.len()].windows(2).all(|w| w[0][0] < w[1][0]) {
            return Err(FalloffError::Points);
        }
        Ok(FalloffCurve { points: out, len: points.len() as u8 })
    }

    /// The straight line from `(0, 0)` to `(1, 1)`.
    pub fn linear() -> Self {
        FalloffCurve::new(&[(0.0, 0.0), (1.0, 1.0)]).expect("two ordered points in the unit square")
    }

    /// Whether its points are sound (one that arrived through serde may not be).
    pub fn is_valid(&self) -> bool {
        FalloffCurve::new(&self.points()).is_ok()
    }

    /// Its points.
    pub fn points(&self) -> Vec<(f64, f64)> {
        let n = (self.len as usize).min(MAX_CURVE_POINTS);
        self.points[..n].iter().map(|p| (p[0] as f64, p[1] as f64)).collect()
    }

    /// The value at `t` in `[0, 1]` (clamped to the ends outside).
    pub fn at(&self, t: f64) -> f64 {
        let n = (self.len as usize).min(MAX_CURVE_POINTS);
        if n < 2 {
            return 0.0;
        }
        let p = |i: usize| (self.points[i][0] as f64, self.points[i][1] as f64);
        let k = (0..n - 1).find(|&i| t <= p(i + 1).0).unwrap_or(n - 2);
        let ((x0, y0), (x1, y1)) = (p(k), p(k + 1));
        let h = x1 - x0;
        if !(h > 0.0) {
            return y0;
        }
        let slope = |i: usize| {
            let ((a, fa), (b, fb)) = (p(i), p(i + 1));
            if b > a { (fb - fa) / (b - a) } else { 0.0 }
        };
        // The tangent at point i: the weighted harmonic mean of the slopes beside it where they
        // agree in sign, else 0; the one-sided slope at an end.
        let tangent = |i: usize| -> f64 {
            if i == 0 {
                return slope(0);
            }
            if i == n - 1 {
                return slope(n - 2);
            }
            let (d0, d1) = (slope(i - 1), slope(i));
            if d0 * d1 <= 0.0 {
                return 0.0;
            }
            let (h0, h1) = (p(i).0 - p(i - 1).0, p(i + 1).0 - p(i).0);
            3.0 * (h0 + h1) / ((2.0 * h1 + h0) / d0 + (h1 + 2.0 * h0) / d1)
        };
        let (m0, m1) = (tangent(k), tangent(k + 1));
        let s = ((t - x0) / h).clamp(0.0, 1.0);
        let (s2, s3) = (s * s, s * s * s);
        let v = (2.0 * s3 - 3.0 * s2 + 1.0) * y0
            + (s3 - 2.0 * s2 + s) * h * m0
            + (-2.0 * s3 + 3.0 * s2) * y1
            + (s3 - s2) * h * m1;
        v.clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_shapes_run_from_one_to_nothing_and_smooth_is_the_tools_own() {
        for f in Falloff::NAMED {
            assert_eq!(f.at(0.0), 1.0, "{}", f.name());
            assert_eq!(f.at(1.0), 0.0);
            assert_eq!(f.at(f64::NAN), 0.0);
            assert_eq!(f.at(-0.5), 1.0, "before the centre reads as the centre");
            let mut last = 1.0;
            for i in 1..100 {
                let v = f.at(i as f64 / 100.0);
                assert!(v <= last + 1e-12 && (0.0..=1.0).contains(&v), "{} at {i}", f.name());
                last = v;
            }
        }
        for i in 0..=20 {
            let t = i as f64 / 20.0;
            assert_eq!(Falloff::Smooth.at(t), crate::tools::falloff(t));
        }
        assert_eq!(Falloff::Constant.at(0.999), 1.0);
    }

    #[test]
    fn a_curve_passes_through_its_points_without_overshoot() {
        let c = FalloffCurve::new(&[(0.0, 1.0), (0.3, 0.9), (0.5, 0.2), (0.8, 0.25), (1.0, 0.0)]).unwrap();
        for (t, v) in c.points() {
            assert!((c.at(t) - v).abs() < 1e-6, "through ({t}, {v})");
        }
        // Between two points the curve stays within their values where they rise or fall.
        for i in 0..=100 {
            let t = 0.3 + 0.2 * i as f64 / 100.0;
            let v = c.at(t);
            assert!((0.2 - 1e-9..=0.9 + 1e-9).contains(&v), "{t}: {v}");
        }
        let f = Falloff::Curve(c);
        assert!(f.is_valid());
        let line = FalloffCurve::linear();
        for i in 0..=10 {
            let t = i as f64 / 10.0;
            assert!((line.at(t) - t).abs() < 1e-12);
        }
        assert_eq!(line.at(1.0), 1.0);
        assert_eq!(f.at(1.0), 0.0, "nothing from the rim on, whatever the curve");
        assert_eq!(f.numbers().len(), 10);
    }

    #[test]
    fn bad_points_are_refused_and_named_shapes_become_curves() {
        assert_eq!(FalloffCurve::new(&[(0.0, 1.0)]), Err(FalloffError::Count(1)));
        assert!(FalloffCurve::new(&[(0.0, 1.0); 9]).is_err());
        for bad in [
            vec![(0.1, 1.0), (1.0, 0.0)],
            vec![(0.0, 1.0), (0.9, 0.0)],
            vec![(0.0, 1.0), (0.5, 0.5), (0.5, 0.4), (1.0, 0.0)],
            vec![(0.0, 1.5), (1.0, 0.0)],
            vec![(0.0, f64::NAN), (1.0, 0.0)],
        ] {
            assert_eq!(FalloffCurve::new(&bad), Err(FalloffError::Points), "{bad:?}");
        }
        for f in Falloff::NAMED {
            let c = f.to_curve();
            assert_eq!(c.points().len(), 5);
            assert!((c.at(0.5) - f.at(0.5)).abs() < 1e-6, "{}", f.name());
        }
        // A curve that arrives damaged (through serde) evaluates without panicking and says so.
        let mut c = FalloffCurve::new(&[(0.0, 1.0), (1.0, 0.0)]).unwrap();
        c.len = 200;
        assert!(!Falloff::Curve(c).is_valid());
        assert!((0.0..=1.0).contains(&Falloff::Curve(c).at(0.5)));
    }
}
