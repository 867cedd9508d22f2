//! Axes and the axis frame that lets the three families of grid lines share one code path.

use glam::{DVec3, I64Vec3};
use serde::{Deserialize, Serialize};

/// One of the three coordinate axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Axis {
    /// The x axis.
    X = 0,
    /// The y axis.
    Y = 1,
    /// The z axis.
    Z = 2,
}

impl Axis {
    /// All three axes in storage order.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// 0, 1 or 2.
    #[inline]
    pub fn index(self) -> usize {
        self as usize
    }

    /// The axis with the given index (0..3).
    #[inline]
    pub fn from_index(i: usize) -> Axis {
        Self::ALL[i % 3]
    }

    /// The two axes that span the plane of the lines running along `self`, in cyclic order:
    /// lines along x are indexed by (y, z), along y by (z, x), along z by (x, y).
    #[inline]
    pub fn across(self) -> (Axis, Axis) {
        match self {
            Axis::X => (Axis::Y, Axis::Z),
            Axis::Y => (Axis::Z, Axis::X),
            Axis::Z => (Axis::X, Axis::Y),
        }
    }

    /// The unit vector along the axis.
    #[inline]
    pub fn unit(self) -> DVec3 {
        let mut v = DVec3::ZERO;
        v[self.index()] = 1.0;
        v
    }

    /// The integer unit vector along the axis.
    #[inline]
    pub fn unit_i64(self) -> I64Vec3 {
        let mut v = I64Vec3::ZERO;
        v[self.index()] = 1;
        v
    }
}

/// Places `(t, u, v)` given in a line frame (t along `axis`, u and v along [`Axis::across`]) into
/// x, y, z order.
#[inline]
pub fn compose<T: Copy + Default>(axis: Axis, t: T, u: T, v: T) -> [T; 3] {
    let (ua, va) = axis.across();
    let mut out = [T::default(); 3];
    out[axis.index()] = t;
    out[ua.index()] = u;
    out[va.index()] = v;
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compose_places_line_coordinates_on_the_right_axes() {
        assert_eq!(compose(Axis::X, 1, 2, 3), [1, 2, 3]);
        assert_eq!(compose(Axis::Y, 1, 2, 3), [3, 1, 2]);
        assert_eq!(compose(Axis::Z, 1, 2, 3), [2, 3, 1]);
    }
}
