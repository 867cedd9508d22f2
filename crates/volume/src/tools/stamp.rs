//! Stamps (alphas): a grey-scale image as a dab's footprint. The image's square is laid on the
//! plane that fits the surface under the dab, `2 × radius` on a side, centred on the dab and
//! turned about the surface normal; the surface under it moves along that normal by `height`
//! times the image's value (1 for white), so a stamp raises its picture in relief or, with a
//! negative height, carves it in. As in Blender's texture brushes the ball of the radius clips
//! the square's corners, and the last sixth of the radius fades to nothing, so an image that is
//! not black at its edges leaves no cliff at the rim.
//!
//! Like [`super::inflate`] the move is an offset of the region's distance field, scaled per
//! node by the stamp's value there, the dab's strength, and (through the region's writer) the
//! mask.

use glam::DVec3;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::ops::{Dab, ToolError, finite};
use crate::edit::EditReport;
use crate::volume::Volume;

/// The largest side a stamp image may have (pixels).
pub const STAMP_MAX_SIDE: usize = 4096;

/// The side of the built-in stamps (pixels).
pub const BUILTIN_SIDE: usize = 128;

/// From this fraction of the radius outwards a stamp fades to 0 at the radius.
const RIM_FADE_FROM: f64 = 5.0 / 6.0;

/// Why an image cannot be a stamp.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum StampError {
    /// No pixels, or more than [`STAMP_MAX_SIDE`] on a side.
    #[error("a stamp must be 1 to {STAMP_MAX_SIDE} pixels on a side, not {width} × {height}")]
    BadSize {
        /// Pixels across.
        width: usize,
        /// Pixels down.
        height: usize,
    },
    /// Fewer or more values than pixels.
    #[error("a {width} × {height} stamp needs {} values, not {values}", width * height)]
    BadLength {
        /// Pixels across.
        width: usize,
        /// Pixels down.
        height: usize,
        /// Values given.
        values: usize,
    },
}

/// A grey-scale image: 16-bit values (0 black, 65535 white), rows from the top.
#[derive(Clone, PartialEq, Eq)]
pub struct StampImage {
    width: usize,
    height: usize,
    values: Vec<u16>,
}

impl std::fmt::Debug for StampImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "StampImage({} × {})", self.width, self.height)
    }
}

impl StampImage {
    /// An image of `width × height` values, rows from the top, checked.
    pub fn new(width: usize, height: usize, values: Vec<u16>) -> Result<Self, StampError> {
        if width == 0 || height == 0 || width > STAMP_MAX_SIDE || height > STAMP_MAX_SIDE {
            return Err(StampError::BadSize { width, height });
        }
        if values.len() != width * height {
            return Err(StampError::BadLength { width, height, values: values.len() });
        }
        Ok(StampImage { width, height, values })
    }

    /// A square image of `side` pixels (at most [`STAMP_MAX_SIDE`]) whose value at each pixel's
    /// centre is `f(u, v)`, clamped to `[0, 1]` (NaN reads 0), with `u` to the right and `v` up,
    /// both from −1 to 1 across the image.
    pub fn from_fn(side: usize, f: impl Fn(f64, f64) -> f64) -> Self {
        let side = side.clamp(1, STAMP_MAX_SIDE);
        let mut values = Vec::with_capacity(side * side);
        let to_unit = |i: usize| (i as f64 + 0.5) / side as f64 * 2.0 - 1.0;
        for row in 0..side {
            let v = -to_unit(row);
            for col in 0..side {
                let value = f(to_unit(col), v);
                let value = if value.is_nan() { 0.0 } else { value.clamp(0.0, 1.0) };
                values.push((value * 65535.0).round() as u16);
            }
        }
        StampImage { width: side, height: side, values }
    }

    /// Pixels across.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Pixels down.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The values, rows from the top.
    pub fn values(&self) -> &[u16] {
        &self.values
    }

    /// The value (0 to 1) at `(u, v)`: `u` to the right and `v` up, both from −1 to 1 across the
    /// image, interpolated bilinearly between pixel centres (the edge pixels hold to the edge);
    /// 0 outside the image and for a NaN coordinate.
    pub fn sample(&self, u: f64, v: f64) -> f64 {
        if !((-1.0..=1.0).contains(&u) && (-1.0..=1.0).contains(&v)) {
            return 0.0;
        }
        let x = ((u + 1.0) * 0.5 * self.width as f64 - 0.5).clamp(0.0, (self.width - 1) as f64);
        let y = ((1.0 - v) * 0.5 * self.height as f64 - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let at = |x: usize, y: usize| self.values[y * self.width + x] as f64 / 65535.0;
        let top = at(x0, y0) + (at(x1, y0) - at(x0, y0)) * fx;
        let bottom = at(x0, y1) + (at(x1, y1) - at(x0, y1)) * fx;
        top + (bottom - top) * fy
    }
}

/// The stamps made in code (each [`BUILTIN_SIDE`] pixels square, black outside the unit disc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum BuiltinStamp {
    /// A smooth round bump.
    #[default]
    Dome,
    /// A raised ring.
    Ring,
    /// A five-pointed star with soft edges.
    Star,
    /// Parallel ridges (turn the stamp to turn them).
    Stripes,
    /// A grid of small rivets.
    Dots,
    /// Rounded cobbles between grooves (cells of a jittered grid).
    Cells,
}

impl BuiltinStamp {
    /// Every built-in stamp, in the palette's order.
    pub const ALL: [BuiltinStamp; 6] = [
        BuiltinStamp::Dome,
        BuiltinStamp::Ring,
        BuiltinStamp::Star,
        BuiltinStamp::Stripes,
        BuiltinStamp::Dots,
        BuiltinStamp::Cells,
    ];

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            BuiltinStamp::Dome => "Dome",
            BuiltinStamp::Ring => "Ring",
            BuiltinStamp::Star => "Star",
            BuiltinStamp::Stripes => "Stripes",
            BuiltinStamp::Dots => "Dots",
            BuiltinStamp::Cells => "Cells",
        }
    }

    /// Its image (made anew on each call: callers keep it). Its transcendental functions are
    /// `libm`'s, not the platform's, so every machine makes the same pixels (a room's replicas
    /// replay stamps bit for bit).
    pub fn image(self) -> StampImage {
        StampImage::from_fn(BUILTIN_SIDE, |u, v| {
            let t = (u * u + v * v).sqrt();
            // Every built-in stamp fades to black at the unit circle.
            let edge = smoothstep(0.97, 0.75, t);
            edge * match self {
                BuiltinStamp::Dome => libm::cos(t.min(1.0) * std::f64::consts::FRAC_PI_2).powi(2),
                BuiltinStamp::Ring => libm::exp(-((t - 0.55) / 0.16).powi(2)),
                BuiltinStamp::Star => {
                    // The outline's radius at this angle: 0.75 at the points, 0.35 between them.
                    let angle = libm::atan2(u, v);
                    let spoke = libm::cos(angle * 5.0) * 0.5 + 0.5;
                    let outline = 0.35 + 0.4 * spoke.powi(3);
                    smoothstep(outline + 0.06, outline - 0.06, t)
                }
                BuiltinStamp::Stripes => 0.5 + 0.5 * libm::cos(u * std::f64::consts::PI * 5.0),
                BuiltinStamp::Dots => {
                    // Rivets on a 5 × 5 grid of spacing 0.36.
                    let cell = |x: f64| (x / 0.36).round() * 0.36;
                    let d = ((u - cell(u)).powi(2) + (v - cell(v)).powi(2)).sqrt();
                    (1.0 - (d / 0.13).powi(2)).max(0.0).sqrt()
                }
                BuiltinStamp::Cells => cobbles(u, v),
            }
        })
    }
}

/// `0` at `a`, `1` at `b`, the smooth Hermite step between (either order).
fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Rounded cobbles: a jittered grid's cells, high in the middle of each and falling into a
/// groove where two cells meet (the second-nearest point's distance less the nearest's).
fn cobbles(u: f64, v: f64) -> f64 {
    const CELLS: f64 = 3.5;
    let (x, y) = ((u + 1.0) * CELLS, (v + 1.0) * CELLS);
    let (cx, cy) = (x.floor() as i64, y.floor() as i64);
    let (mut d1, mut d2) = (f64::MAX, f64::MAX);
    for j in cy - 1..=cy + 1 {
        for i in cx - 1..=cx + 1 {
            // A fixed hash of the cell: the same cobbles on every machine.
            let h = (i.wrapping_mul(73_856_093) ^ j.wrapping_mul(19_349_663)) as u64;
            let h = h.wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let jx = ((h >> 11) & 0xFFFF) as f64 / 65535.0;
            let jy = ((h >> 33) & 0xFFFF) as f64 / 65535.0;
            let d = ((i as f64 + 0.15 + 0.7 * jx - x).powi(2) + (j as f64 + 0.15 + 0.7 * jy - y).powi(2)).sqrt();
            if d < d1 {
                d2 = d1;
                d1 = d;
            } else if d < d2 {
                d2 = d;
            }
        }
    }
    smoothstep(0.0, 0.35, d2 - d1)
}

/// How a stamp lies on the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StampPlacement {
    /// Where the image's top points (grid coordinates): projected onto the plane that fits the
    /// surface (any direction across the normal where this one is along it or zero).
    pub up: DVec3,
    /// A further turn about the normal, counter-clockwise seen from outside (radians).
    pub angle: f64,
    /// Whether the image is mirrored (left for right), as a mirror image of a dab is.
    pub mirrored: bool,
}

impl Default for StampPlacement {
    fn default() -> Self {
        StampPlacement { up: DVec3::Y, angle: 0.0, mirrored: false }
    }
}

/// The plane a stamp lies in: its normal (out of the solid) and the image's right and up
/// directions, all unit and orthogonal (grid coordinates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StampFrame {
    /// Out of the surface.
    pub normal: DVec3,
    /// The image's right.
    pub right: DVec3,
    /// The image's up.
    pub up: DVec3,
}

impl StampFrame {
    /// The frame of `placement` on a surface of normal `normal` (unit): `up` projected onto the
    /// plane and turned by the angle (its sine and cosine `libm`'s, the same on every machine),
    /// right = up × normal (the image reads the right way round seen from outside), or its
    /// opposite when mirrored.
    pub fn new(normal: DVec3, placement: &StampPlacement) -> Self {
        let along = placement.up - normal * normal.dot(placement.up);
        let up = if along.length() > 1e-6 * placement.up.length().max(1e-300) && along.is_finite() {
            along.normalize()
        } else {
            normal.any_orthonormal_vector()
        };
        let (s, c) = libm::sincos(placement.angle);
        let up = (up * c + normal.cross(up) * s).normalize();
        let right = up.cross(normal);
        StampFrame { normal, up, right: if placement.mirrored { -right } else { right } }
    }
}

/// Stamps `image` on the surface under `dab` (see the module docs): the surface moves along its
/// normal by `height` grid units (negative carves) times the image's value, the dab's strength,
/// and the rim's fade. The plane is fitted to the surface within half the radius of the centre
/// (within the radius where none is that close); with no surface under the dab nothing changes.
pub fn stamp(
    volume: &mut Volume,
    dab: &Dab,
    image: &StampImage,
    placement: &StampPlacement,
    height: f64,
) -> Result<EditReport, ToolError> {
    let height = finite("the stamp height", height)?;
    finite("the stamp's turn", placement.angle)?;
    if !placement.up.is_finite() {
        return Err(ToolError::BadParameter { what: "the stamp's up direction", positive: false });
    }
    let r = DVec3::splat(dab.radius);
    let sp = volume.level_near(dab.center - r, dab.center + r).spacing();
    let mut region = dab.region(volume, 2, (height * dab.strength).abs().min(dab.radius) + sp)?;
    let Some(normal) = surface_normal(&region, dab) else {
        region.weight.fill(0.0);
        return Ok(volume.write_region(&region)?);
    };
    let frame = StampFrame::new(normal, placement);
    let per_node = (height / region.spacing()) as f32;
    let d = region.dims;
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                let i = region.index(x, y, z);
                if region.weight[i] <= 0.0 {
                    continue;
                }
                let off = (region.grid_point(x, y, z) - dab.center) / dab.radius;
                let (u, v) = (off.dot(frame.right), off.dot(frame.up));
                let rim = smoothstep(1.0, RIM_FADE_FROM, off.length());
                let w = (dab.strength * rim * image.sample(u, v)) as f32;
                region.weight[i] = w;
                region.phi[i] -= per_node * w;
            }
        }
    }
    Ok(volume.write_region(&region)?)
}

/// The mean outward normal of the surface near the dab's centre: the field's gradient at the
/// nodes within a node of the surface, weighted by the falloff, over half the radius (or the
/// whole ball where nothing lies that close). `None` where there is no surface in the ball.
fn surface_normal(region: &super::Region, dab: &Dab) -> Option<DVec3> {
    let d = region.dims;
    let (sy, sz) = (d[0], d[0] * d[1]);
    let mut sums = [DVec3::ZERO; 2];
    for z in 1..d[2].saturating_sub(1) {
        for y in 1..d[1].saturating_sub(1) {
            for x in 1..d[0].saturating_sub(1) {
                let i = region.index(x, y, z);
                let (phi, w) = (region.phi[i], region.weight[i] as f64);
                if w <= 0.0 || phi.abs() > 1.0 {
                    continue;
                }
                let p = &region.phi;
                let g = DVec3::new(
                    (p[i + 1] - p[i - 1]) as f64,
                    (p[i + sy] - p[i - sy]) as f64,
                    (p[i + sz] - p[i - sz]) as f64,
                );
                let n = g.normalize_or_zero() * w;
                let near = (region.grid_point(x, y, z) - dab.center).length() <= 0.5 * dab.radius;
                sums[usize::from(!near)] += n;
            }
        }
    }
    let n = if sums[0] != DVec3::ZERO { sums[0] } else { sums[0] + sums[1] };
    let n = n.normalize_or_zero();
    (n != DVec3::ZERO && n.is_finite()).then_some(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_is_checked_and_sampled_bilinearly_with_nothing_outside() {
        assert!(StampImage::new(0, 3, vec![]).is_err());
        assert!(StampImage::new(STAMP_MAX_SIDE + 1, 1, vec![0; STAMP_MAX_SIDE + 1]).is_err());
        assert!(StampImage::new(2, 2, vec![0; 3]).is_err());
        // Left column black, right column white; top row and bottom row the same.
        let img = StampImage::new(2, 2, vec![0, 65535, 0, 65535]).unwrap();
        assert_eq!(img.sample(-1.0, 0.0), 0.0);
        assert_eq!(img.sample(1.0, 0.0), 1.0);
        assert!((img.sample(0.0, 0.3) - 0.5).abs() < 1e-12);
        assert_eq!(img.sample(1.01, 0.0), 0.0);
        assert_eq!(img.sample(f64::NAN, 0.0), 0.0);
        // Rows run from the top: v = 1 is the first row.
        let img = StampImage::new(1, 2, vec![65535, 0]).unwrap();
        assert_eq!(img.sample(0.0, 1.0), 1.0);
        assert_eq!(img.sample(0.0, -1.0), 0.0);
    }

    #[test]
    fn built_in_stamps_are_black_at_the_rim_and_show_their_picture() {
        for s in BuiltinStamp::ALL {
            let img = s.image();
            assert_eq!(img.width(), BUILTIN_SIDE);
            for a in 0..32 {
                let (y, x) = (a as f64 * std::f64::consts::TAU / 32.0).sin_cos();
                assert!(img.sample(x * 0.999, y * 0.999) < 1e-3, "{} at the rim", s.name());
            }
            assert!(img.values().iter().any(|&v| v > 60000), "{} has a high point", s.name());
        }
        // The dome is high in the middle, the ring low there and high at 0.55.
        assert!(BuiltinStamp::Dome.image().sample(0.0, 0.0) > 0.99);
        let ring = BuiltinStamp::Ring.image();
        assert!(ring.sample(0.0, 0.0) < 0.01 && ring.sample(0.55, 0.0) > 0.95);
        // The star's points are up (v) and four more at 72° steps; between them it is low.
        let star = BuiltinStamp::Star.image();
        assert!(star.sample(0.0, 0.6) > 0.9);
        let (s, c) = (36f64).to_radians().sin_cos();
        assert!(star.sample(0.6 * s, 0.6 * c) < 0.1);
    }

    #[test]
    fn a_frame_is_orthonormal_turns_with_the_angle_and_mirrors() {
        let n = DVec3::new(0.3, 0.9, -0.2).normalize();
        let p = StampPlacement { up: DVec3::new(0.2, 0.1, 1.0), angle: 0.7, mirrored: false };
        let f = StampFrame::new(n, &p);
        for (a, b) in [(f.up, f.right), (f.up, f.normal), (f.right, f.normal)] {
            assert!(a.dot(b).abs() < 1e-12);
        }
        assert!((f.right.cross(f.up) - n).length() < 1e-12, "seen from outside, right then up is counter-clockwise");
        let turned = StampFrame::new(n, &StampPlacement { angle: 0.7 + std::f64::consts::FRAC_PI_2, ..p });
        assert!((turned.up + f.right).length() < 1e-12, "a quarter turn more puts up where left was");
        let m = StampFrame::new(n, &StampPlacement { mirrored: true, ..p });
        assert!((m.right + f.right).length() < 1e-12 && (m.up - f.up).length() < 1e-12);
        // An up along the normal still gives a frame.
        let f = StampFrame::new(DVec3::Y, &StampPlacement { up: DVec3::Y, ..p });
        assert!(f.up.is_finite() && f.up.dot(DVec3::Y).abs() < 1e-12);
    }
}
