//! Octahedral normal encoding: 8 + 8 bits per unit vector (worst-case error about 0.7°).

use glam::DVec3;

/// A unit normal packed into 16 bits (octahedral: 8 bits a coordinate).
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    PartialOrd,
    Ord,
    bytemuck::Pod,
    bytemuck::Zeroable,
    serde::Serialize,
    serde::Deserialize,
)]
#[repr(transparent)]
#[serde(transparent)]
pub struct PackedNormal(pub u16);

/// Packs a normal. Zero or non-finite input packs to +z.
#[inline]
pub fn pack_normal(n: DVec3) -> PackedNormal {
    let l1 = n.x.abs() + n.y.abs() + n.z.abs();
    // Zero, infinite or NaN (which fails both tests).
    if !(l1 > 0.0 && l1.is_finite()) {
        return pack_normal(DVec3::Z);
    }
    // Scale straight to the 0..=255 grid: one division, then branch-free folding.
    let inv = 127.5 / l1;
    let (x, y) = (n.x * inv, n.y * inv);
    let fx = (127.5 - y.abs()).copysign(x);
    let fy = (127.5 - x.abs()).copysign(y);
    let lower = n.z < 0.0;
    let (x, y) = (if lower { fx } else { x }, if lower { fy } else { y });
    // x + 127.5 lies in [0, 255] up to rounding; + 0.5 rounds, `as` truncates and saturates.
    let qx = (x + 128.0).min(255.0) as u16;
    let qy = (y + 128.0).min(255.0) as u16;
    PackedNormal(qx | (qy << 8))
}

/// Unpacks a normal to a unit vector.
pub fn unpack_normal(p: PackedNormal) -> DVec3 {
    let x = (p.0 & 0xff) as f64 / 255.0 * 2.0 - 1.0;
    let y = (p.0 >> 8) as f64 / 255.0 * 2.0 - 1.0;
    let z = 1.0 - x.abs() - y.abs();
    let (x, y) = if z < 0.0 { ((1.0 - y.abs()) * sign(x), (1.0 - x.abs()) * sign(y)) } else { (x, y) };
    DVec3::new(x, y, z).normalize()
}

/// Flips a packed normal (used by subtraction, where the brush's outside becomes the solid's).
pub fn flip_normal(p: PackedNormal) -> PackedNormal {
    pack_normal(-unpack_normal(p))
}

#[inline]
fn sign(v: f64) -> f64 {
    if v >= 0.0 { 1.0 } else { -1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packed_normals_round_trip_within_one_degree() {
        let mut worst: f64 = 1.0;
        for i in 0..2000 {
            let a = i as f64 * 2.399963;
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / 2000.0;
            let r = (1.0 - z * z).sqrt();
            let n = DVec3::new(r * a.cos(), r * a.sin(), z);
            worst = worst.min(unpack_normal(pack_normal(n)).dot(n));
        }
        assert!(worst > 1.0f64.to_radians().cos(), "worst cosine {worst}");
        for bad in
            [DVec3::NAN, DVec3::ZERO, DVec3::new(f64::INFINITY, 0.0, 1.0), DVec3::new(0.0, f64::NEG_INFINITY, 0.0)]
        {
            assert_eq!(pack_normal(bad), pack_normal(DVec3::Z), "{bad:?} packs to +z");
        }
        // Very short vectors are still directions.
        let tiny = DVec3::new(-1e-300, 0.0, 0.0);
        assert!(unpack_normal(pack_normal(tiny)).x < -0.99);
    }
}
