//! The stroke stabiliser ("lazy mouse", "rope"): the brush trails the pointer at the end of a
//! rope and moves only when the pointer pulls it taut, so a shaky hand draws a clean line and a
//! corner is rounded by the rope's length. The rope is a multiple of the brush radius (the
//! pressure's radius), so it feels the same at any brush size.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// How strongly strokes are stabilised.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Stabiliser {
    /// The brush is where the pointer is.
    #[default]
    Off,
    /// A rope of one brush radius.
    Weak,
    /// A rope of three brush radii.
    Strong,
}

impl Stabiliser {
    /// Every setting, in the order the studio cycles them.
    pub const ALL: [Stabiliser; 3] = [Stabiliser::Off, Stabiliser::Weak, Stabiliser::Strong];

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Stabiliser::Off => "Off",
            Stabiliser::Weak => "Weak",
            Stabiliser::Strong => "Strong",
        }
    }

    /// The next setting (after strong, off).
    pub fn next(self) -> Stabiliser {
        match self {
            Stabiliser::Off => Stabiliser::Weak,
            Stabiliser::Weak => Stabiliser::Strong,
            Stabiliser::Strong => Stabiliser::Off,
        }
    }

    /// The rope's length in brush radii.
    pub fn rope(self) -> f64 {
        match self {
            Stabiliser::Off => 0.0,
            Stabiliser::Weak => 1.0,
            Stabiliser::Strong => 3.0,
        }
    }

    /// Where the brush goes when the pointer moves to `pointer` while the brush is at `brush`,
    /// for a brush of `radius`: nowhere while the pointer is within the rope, else along the
    /// line to the pointer until the rope is taut.
    pub fn follow(self, brush: DVec3, pointer: DVec3, radius: f64) -> DVec3 {
        let rope = self.rope() * radius;
        let d = pointer - brush;
        let len = d.length();
        if !(rope > 0.0 && rope.is_finite() && len.is_finite()) {
            return pointer;
        }
        if len <= rope { brush } else { pointer - d * (rope / len) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_brush_trails_the_pointer_by_the_rope() {
        let s = Stabiliser::Strong;
        // Within the rope (3 radii of 2): the brush stays.
        assert_eq!(s.follow(DVec3::ZERO, DVec3::new(5.0, 0.0, 0.0), 2.0), DVec3::ZERO);
        // Beyond it: pulled until taut, towards the pointer.
        assert_eq!(s.follow(DVec3::ZERO, DVec3::new(10.0, 0.0, 0.0), 2.0), DVec3::new(4.0, 0.0, 0.0));
        assert_eq!(Stabiliser::Weak.follow(DVec3::ZERO, DVec3::new(0.0, 3.0, 0.0), 2.0), DVec3::new(0.0, 1.0, 0.0));
        assert_eq!(Stabiliser::Off.follow(DVec3::ZERO, DVec3::ONE, 2.0), DVec3::ONE);
        // A radius that makes no rope leaves the brush on the pointer.
        assert_eq!(s.follow(DVec3::ZERO, DVec3::ONE, f64::NAN), DVec3::ONE);
        assert_eq!(Stabiliser::ALL.map(Stabiliser::next), [Stabiliser::Weak, Stabiliser::Strong, Stabiliser::Off]);
    }
}
