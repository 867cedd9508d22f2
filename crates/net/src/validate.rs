//! What a room accepts: operations with finite numbers, a known surface and material, a brush
//! within the size bounds, and not too many dabs. A server refuses anything else before it
//! replays it; clients may check their own operations the same way.

use strata_editor::{DabRecord, EditOp, Editor};

/// Bounds on what one operation may do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Dabs in one operation (a frame's dabs: a fast drag at a small spacing makes hundreds).
    pub max_dabs: usize,
    /// A dab's radius in cells of its surface's grid, pressure applied.
    pub max_radius_cells: f64,
    /// The largest coordinate (world units) a dab or transform may have.
    pub max_coordinate: f64,
}

impl Default for Limits {
    /// 4,096 dabs (what the editor records in one operation at most), 256 cells, a million
    /// units.
    fn default() -> Self {
        Limits { max_dabs: strata_editor::op::MAX_OP_DABS, max_radius_cells: 256.0, max_coordinate: 1e6 }
    }
}

/// Why an operation was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Invalid {
    /// A NaN or infinite number.
    #[error("the operation carries a number that is not finite")]
    NotFinite,
    /// A coordinate beyond [`Limits::max_coordinate`].
    #[error("the operation reaches beyond {0} units")]
    TooFar(f64),
    /// No such surface.
    #[error("there is no surface {0}")]
    NoSurface(u32),
    /// No such material.
    #[error("material {0} is not in the palette")]
    NoMaterial(u8),
    /// No dabs, or more than [`Limits::max_dabs`].
    #[error("an operation of {0} dabs")]
    DabCount(usize),
    /// A radius that is not positive, or above [`Limits::max_radius_cells`].
    #[error("a brush radius of {0} cells")]
    Radius(f64),
    /// A pressure outside `[0, 1]`.
    #[error("a pressure of {0}")]
    Pressure(f64),
    /// A transform that is not finite and invertible.
    #[error("a surface transform that is not finite and invertible")]
    Transform,
    /// Settings outside their domain (an axis lock beyond z, a negative spacing).
    #[error("tool settings out of range")]
    Settings,
}

/// Checks `op` against `limits` and the surfaces and palette of `editor`.
pub fn validate(op: &EditOp, editor: &Editor, limits: &Limits) -> Result<(), Invalid> {
    let numbers = op.numbers();
    if numbers.iter().any(|v| !v.is_finite()) {
        return Err(Invalid::NotFinite);
    }
    // (Rotations and other unit-scale numbers are far below the bound too.)
    if numbers.iter().any(|v| v.abs() > limits.max_coordinate) {
        return Err(Invalid::TooFar(limits.max_coordinate));
    }
    if op.surface as usize >= editor.surface_count() {
        return Err(Invalid::NoSurface(op.surface));
    }
    if op.tool.material as usize >= editor.scene.materials.len() {
        return Err(Invalid::NoMaterial(op.tool.material));
    }
    if op.dabs.is_empty() || op.dabs.len() > limits.max_dabs {
        return Err(Invalid::DabCount(op.dabs.len()));
    }
    if !op.transform.is_valid() {
        return Err(Invalid::Transform);
    }
    let tool = &op.tool;
    if tool.axis_lock.is_some_and(|a| a > 2)
        || tool.spacing < 0.0
        || tool.strength < 0.0
        || tool.grid_snap < 0.0
        || !tool.falloff.is_valid()
        || !tool.pressure.is_valid()
        || !(0.0..=1.0).contains(&tool.pressure_to_strength)
    {
        return Err(Invalid::Settings);
    }
    for dab in &op.dabs {
        let pressure = match *dab {
            DabRecord::Dab { pressure, .. } | DabRecord::Grab { pressure, .. } => pressure,
        };
        if !(0.0..=1.0).contains(&pressure) {
            return Err(Invalid::Pressure(pressure));
        }
        let cells = tool.radius_at(pressure) / op.transform.scale;
        if !(cells > 0.0 && cells <= limits.max_radius_cells) {
            return Err(Invalid::Radius(cells));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::{DQuat, DVec3};
    use strata_editor::{DabRecord, EditOp, Editor, LayerTransform, ToolSettings};
    use strata_volume::tools::{Falloff, FalloffCurve};

    use super::*;

    fn op(tool: ToolSettings) -> EditOp {
        let at = DVec3::ZERO;
        let dab = DabRecord::Dab { at, from: at, orientation: DQuat::IDENTITY, pressure: 1.0, inverted: false };
        EditOp { surface: 0, transform: LayerTransform::default(), tool, dabs: vec![dab], stroke: 0 }
    }

    /// A hostile client's tool settings: a falloff curve or pressure curve damaged on the wire
    /// (out of order, a length past its points) and a pressure amount out of range are refused
    /// before any replay; sound ones pass.
    #[test]
    fn damaged_curves_and_amounts_in_an_operation_are_refused() {
        let editor = Editor::default();
        let limits = Limits::default();
        assert_eq!(validate(&op(ToolSettings::default()), &editor, &limits), Ok(()));
        let good = FalloffCurve::new(&[(0.0, 1.0), (0.5, 0.4), (1.0, 0.0)]).unwrap();
        let mut bytes = postcard::to_allocvec(&good).unwrap();
        // (The point count is the last byte: past the points it holds.)
        *bytes.last_mut().unwrap() = 200;
        let damaged: FalloffCurve = postcard::from_bytes(&bytes).unwrap();
        let sound = ToolSettings { falloff: Falloff::Curve(good), ..ToolSettings::default() };
        assert_eq!(validate(&op(sound), &editor, &limits), Ok(()));
        let bad_falloff = ToolSettings { falloff: Falloff::Curve(damaged), ..ToolSettings::default() };
        assert_eq!(validate(&op(bad_falloff), &editor, &limits), Err(Invalid::Settings));
        let mut bad_pressure = ToolSettings::default();
        bad_pressure.pressure.size = damaged;
        assert_eq!(validate(&op(bad_pressure), &editor, &limits), Err(Invalid::Settings));
        let too_much = ToolSettings { pressure_to_strength: 1.5, ..ToolSettings::default() };
        assert_eq!(validate(&op(too_much), &editor, &limits), Err(Invalid::Settings));
    }
}
