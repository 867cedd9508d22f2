//! Tools: what a pose does to a layer.

use glam::{DQuat, DVec3};
use strata_volume::CsgOp;
use strata_volume::brush::{Brush, BrushError, Capsule, Cuboid, Cylinder, Sphere};

use crate::pose::ToolPose;
use crate::scene::LayerTransform;

/// What the primary button does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToolKind {
    /// Add material (exact CSG union with the brush).
    Add,
    /// Remove material (exact CSG difference).
    Erase,
    /// Smooth the surface under a ball of the radius (the secondary button: the Laplacian
    /// method, which also shrinks; the primary: volume-preserving).
    Smooth,
    /// Push the surface out along its normal (the secondary button: deflate).
    Inflate,
    /// Pull the surface towards the plane that fits it under the brush.
    Flatten,
}

impl ToolKind {
    /// The CSG operation, with the secondary button inverting it (field tools have none).
    pub fn op(self, inverted: bool) -> CsgOp {
        match (self, inverted) {
            (ToolKind::Add, false) | (ToolKind::Erase, true) => CsgOp::Add,
            _ => CsgOp::Subtract,
        }
    }

    /// Whether the tool works on the field of a region (smooth, inflate, flatten) rather than
    /// by CSG with a brush.
    pub fn is_field_tool(self) -> bool {
        matches!(self, ToolKind::Smooth | ToolKind::Inflate | ToolKind::Flatten)
    }
}

/// The brush's shape, sized by the tool radius and oriented by the pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BrushShape {
    /// A ball of the radius.
    Sphere,
    /// A cube of half-size the radius.
    Box,
    /// A capsule along the pose's y axis: length twice the radius, thickness the radius.
    Capsule,
    /// A cylinder along the pose's y axis: height and diameter twice the radius.
    Cylinder,
}

/// The tool's settings (what the palette edits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolSettings {
    /// Add or erase.
    pub kind: ToolKind,
    /// Brush shape.
    pub shape: BrushShape,
    /// Brush radius in world units.
    pub radius: f64,
    /// How much pressure scales the radius: 0 ignores pressure, 1 scales it fully.
    pub strength: f64,
    /// Distance between stroke dabs as a fraction of the radius.
    pub spacing: f64,
    /// Strength of the field tools (smooth, inflate, flatten) in `[0, 1]`: the falloff's
    /// factor; an inflate dab at full strength moves the surface by a fifth of the radius.
    pub field_strength: f64,
    /// Mirror every dab across the layer-grid planes `x`, `y` and/or `z` through
    /// [`ToolSettings::symmetry_center`] (up to eight dabs per dab).
    pub symmetry: [bool; 3],
    /// Where the mirror planes meet, in the layer's grid coordinates.
    pub symmetry_center: DVec3,
}

impl Default for ToolSettings {
    fn default() -> Self {
        ToolSettings {
            kind: ToolKind::Add,
            shape: BrushShape::Sphere,
            radius: 6.0,
            strength: 0.0,
            spacing: 0.25,
            field_strength: 0.5,
            symmetry: [false; 3],
            symmetry_center: DVec3::ZERO,
        }
    }
}

impl ToolSettings {
    /// The dab at world point `position` with world `orientation` and its mirror images under
    /// [`ToolSettings::symmetry`], in a layer placed by `layer`: the original first, images that
    /// coincide with one already listed (a dab on a mirror plane) left out. An orientation is
    /// mirrored as `M R M`, a rotation again, which places the symmetric brush shapes exactly.
    pub fn mirrored(&self, layer: &LayerTransform, position: DVec3, orientation: DQuat) -> Vec<(DVec3, DQuat)> {
        let g = layer.to_grid(position);
        let q = layer.rotation.inverse() * orientation;
        let c = self.symmetry_center;
        let mut out: Vec<(DVec3, DQuat)> = Vec::with_capacity(8);
        let mut grid: Vec<DVec3> = Vec::with_capacity(8);
        for mask in 0..8usize {
            if (0..3).any(|a| mask & (1 << a) != 0 && !self.symmetry[a]) {
                continue;
            }
            let (mut gm, mut qm) = (g, q);
            for a in 0..3 {
                if mask & (1 << a) != 0 {
                    gm[a] = 2.0 * c[a] - gm[a];
                    // M R M for the reflection of axis a: the other two vector parts change sign.
                    let mut v = [qm.x, qm.y, qm.z];
                    for (b, part) in v.iter_mut().enumerate() {
                        if b != a {
                            *part = -*part;
                        }
                    }
                    qm = DQuat::from_xyzw(v[0], v[1], v[2], qm.w);
                }
            }
            if grid.iter().any(|&o| (o - gm).length() <= 1e-9 * (1.0 + gm.length())) {
                continue;
            }
            grid.push(gm);
            out.push((layer.to_world(gm), layer.rotation * qm));
        }
        out
    }

    /// The radius at `pressure`.
    pub fn radius_at(&self, pressure: f64) -> f64 {
        let s = self.strength.clamp(0.0, 1.0);
        self.radius * (1.0 - s + s * pressure.clamp(0.0, 1.0))
    }

    /// Distance between dabs (world units), never below a hundredth of the radius.
    pub fn dab_spacing(&self) -> f64 {
        self.radius * self.spacing.max(0.01)
    }

    /// The brush of a dab at `position` with `orientation` and `pressure`, in the grid
    /// coordinates of a layer placed by `layer`.
    pub fn brush(
        &self,
        layer: &LayerTransform,
        position: DVec3,
        orientation: DQuat,
        pressure: f64,
    ) -> Result<Box<dyn Brush>, BrushError> {
        let r = self.radius_at(pressure) / layer.scale;
        let c = layer.to_grid(position);
        let q = layer.rotation.inverse() * orientation;
        let axis = q * DVec3::Y;
        Ok(match self.shape {
            BrushShape::Sphere => Box::new(Sphere::new(c, r)?),
            BrushShape::Box => Box::new(Cuboid::oriented(c, DVec3::splat(r), q, 0.0)?),
            BrushShape::Capsule => Box::new(Capsule::new(c - axis * r * 0.5, c + axis * r * 0.5, r * 0.5)?),
            BrushShape::Cylinder => Box::new(Cylinder::new(c, axis, r, r)?),
        })
    }

    /// [`ToolSettings::brush`] for a pose.
    pub fn brush_at(&self, layer: &LayerTransform, pose: &ToolPose) -> Result<Box<dyn Brush>, BrushError> {
        self.brush(layer, pose.position, pose.orientation, pose.pressure)
    }
}
