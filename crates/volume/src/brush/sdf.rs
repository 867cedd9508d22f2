//! A brush from any signed-distance closure.

use std::fmt;

use glam::DVec3;

use super::{Aabb, Brush, BrushError};

type Field = dyn Fn(DVec3) -> f64 + Send + Sync;

/// A solid given by a closure that is negative inside, with a box that holds it and a Lipschitz
/// bound `L` (`|f(a) - f(b)| ≤ L |a - b|`; 1 for an exact distance).
///
/// The volume samples the closure at every node of the lines through the box, skipping nodes
/// that the bound proves to be on the same side as their neighbour (never a chunk line's last
/// node, which the next chunk evaluates itself), and brackets each crossing inside its cell. A
/// bound that is too small, or a discontinuous field, may hide thin parts; because the closure
/// is user-supplied the volume takes node states from the x lines and repairs the other axes, so
/// the volume stays consistent even then (`tests/grid_ties.rs` checks bounds that understate the
/// slope up to 100× and striped, discontinuous fields).
pub struct SdfBrush {
    f: Box<Field>,
    bounds: Aabb,
    lipschitz: f64,
}

impl fmt::Debug for SdfBrush {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SdfBrush")
            .field("bounds", &self.bounds)
            .field("lipschitz", &self.lipschitz)
            .finish_non_exhaustive()
    }
}

impl SdfBrush {
    /// The solid `f(p) ≤ 0` within `bounds` (grid coordinates).
    pub fn new(
        f: impl Fn(DVec3) -> f64 + Send + Sync + 'static,
        bounds: Aabb,
        lipschitz: f64,
    ) -> Result<Self, BrushError> {
        if !bounds.is_valid() {
            return Err(BrushError::NotFinite { what: "field bounds" });
        }
        super::positive("field Lipschitz bound", lipschitz)?;
        Ok(SdfBrush { f: Box::new(f), bounds, lipschitz })
    }
}

impl Brush for SdfBrush {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        let v = (self.f)(origin + p);
        // NaN counts as outside.
        if v.is_nan() { f64::INFINITY } else { v }
    }

    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        self.bounds.contains(origin + p) && self.field(origin, p) <= 0.0
    }

    fn lipschitz(&self) -> f64 {
        self.lipschitz
    }

    fn lines_agree(&self) -> bool {
        false
    }
}
