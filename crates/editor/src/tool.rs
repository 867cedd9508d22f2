//! Tools: what a pose does to a layer.

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};
use strata_volume::CsgOp;
use strata_volume::brush::{Brush, BrushError, Capsule, Cuboid, Cylinder, Sphere};

use crate::pose::ToolPose;
use crate::scene::LayerTransform;

/// What the primary button does. The secondary button (or holding Ctrl/Alt in the studio)
/// uses the inverse tool, as [`ToolKind::inverse_name`] names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ToolKind {
    /// Add material that blends into the surface in a soft fillet (a smooth union of a ball
    /// with the field, fillet [`ToolSettings::fillet`] of the radius); inverse: clay erase (a
    /// smooth difference). The default tool.
    #[default]
    Clay,
    /// Add material (exact CSG union with the brush of the chosen shape); inverse: erase.
    Add,
    /// Remove material (exact CSG difference); inverse: add.
    Erase,
    /// Smooth the surface under a ball of the radius: volume-preserving field smoothing;
    /// inverse: the Laplacian method, which also shrinks. ([`ToolSettings::paper_smoothing`]
    /// uses the paper's Eq. 1 instead.)
    Smooth,
    /// Push the surface out along its normal; inverse: deflate.
    Inflate,
    /// Pull the surface towards the plane that fits it under the brush.
    Flatten,
    /// Pull the surface sideways towards the stroke's line; inverse: push it away (magnify).
    Pinch,
    /// Drag the surface under the brush with the pointer (the brush follows it).
    Grab,
    /// Add resolution where fine detail is sculpted: raises the chunks under a ball of the
    /// radius to [`ToolSettings::detail_level`]; inverse: lowers them to the layer's base level.
    /// The surface stays as it was (raising reproduces it; lowering keeps the coarser lines).
    Detail,
    /// Give the solid under a ball of the radius the current material
    /// ([`ToolSettings::material`]) without changing its shape; the falloff (scaled by the field
    /// strength) shows as a dithered share of painted nodes. Inverse: paint the scene's first
    /// material back.
    Paint,
    /// Raise the stamp's grey-scale picture ([`ToolSettings::stamp`]) in relief on the surface,
    /// by up to [`crate::stamps::STAMP_HEIGHT`] of the radius times the field strength where it
    /// is white; sprayed along the stroke or dragged out as one stamp. Inverse: carve it in.
    Stamp,
    /// Paint protection on: the nodes under a ball of the radius gain mask weight (the falloff
    /// scaled by the field strength), and no tool changes what the mask holds (see
    /// [`strata_volume::mask`]); drawn darkened. Inverse: take the mask off. With the smooth
    /// modifier: [`ToolKind::MaskSmooth`].
    Mask,
    /// Smooth the mask's weights under the ball (what the smooth modifier makes of
    /// [`ToolKind::Mask`]; not in the palette).
    MaskSmooth,
}

impl ToolKind {
    /// Every tool, in palette order.
    pub const ALL: [ToolKind; 12] = [
        ToolKind::Clay,
        ToolKind::Add,
        ToolKind::Erase,
        ToolKind::Smooth,
        ToolKind::Inflate,
        ToolKind::Flatten,
        ToolKind::Pinch,
        ToolKind::Grab,
        ToolKind::Detail,
        ToolKind::Paint,
        ToolKind::Stamp,
        ToolKind::Mask,
    ];

    /// The tool's name.
    pub fn name(self) -> &'static str {
        match self {
            ToolKind::Clay => "Clay",
            ToolKind::Add => "Add",
            ToolKind::Erase => "Erase",
            ToolKind::Smooth => "Smooth",
            ToolKind::Inflate => "Inflate",
            ToolKind::Flatten => "Flatten",
            ToolKind::Pinch => "Pinch",
            ToolKind::Grab => "Grab",
            ToolKind::Detail => "Detail",
            ToolKind::Paint => "Paint",
            ToolKind::Stamp => "Stamp",
            ToolKind::Mask => "Mask",
            ToolKind::MaskSmooth => "Smooth mask",
        }
    }

    /// What the inverse tool (secondary button, Ctrl or Alt) does.
    pub fn inverse_name(self) -> &'static str {
        match self {
            ToolKind::Clay => "clay erase",
            ToolKind::Add => "erase",
            ToolKind::Erase => "add",
            ToolKind::Smooth => "Laplacian smoothing",
            ToolKind::Inflate => "deflate",
            ToolKind::Flatten => "flatten",
            ToolKind::Pinch => "magnify",
            ToolKind::Grab => "grab",
            ToolKind::Detail => "lower detail",
            ToolKind::Paint => "paint the first material",
            ToolKind::Stamp => "carve the stamp in",
            ToolKind::Mask => "unmask",
            ToolKind::MaskSmooth => "smooth the mask",
        }
    }

    /// The CSG operation, with the secondary button inverting it (field tools have none).
    pub fn op(self, inverted: bool) -> CsgOp {
        match (self, inverted) {
            (ToolKind::Add, false) | (ToolKind::Erase, true) => CsgOp::Add,
            _ => CsgOp::Subtract,
        }
    }

    /// Whether the tool works on the field of a region (every tool but the exact CSG add and
    /// erase) rather than by CSG with a brush of the chosen shape.
    pub fn is_field_tool(self) -> bool {
        !matches!(self, ToolKind::Add | ToolKind::Erase)
    }

    /// Whether the tool changes the mask, not the solid (masks are for scenes: a world has
    /// none).
    pub fn is_mask(self) -> bool {
        matches!(self, ToolKind::Mask | ToolKind::MaskSmooth)
    }

    /// Whether the tool builds material up or carves it away where it acts (add, erase, clay,
    /// inflate, stamp, and their inverses): a stroke of it must not pick the surface it made itself, or
    /// it would climb onto its own dabs (see [`crate::Editor::stroke_surface`]).
    pub fn builds_or_carves(self) -> bool {
        matches!(self, ToolKind::Add | ToolKind::Erase | ToolKind::Clay | ToolKind::Inflate | ToolKind::Stamp)
    }
}

/// The brush's shape, sized by the tool radius and oriented by the pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
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
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
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
    /// The clay tool's fillet radius as a fraction of the brush radius (0: a plain union).
    pub fillet: f64,
    /// Smooth with the paper's Eq. 1 on the crossings instead of the field method.
    pub paper_smoothing: bool,
    /// Alignment: snap dab positions to multiples of this many layer-grid cells (0: off).
    pub grid_snap: f64,
    /// Alignment: keep a stroke on the line through its first dab along this layer-grid axis
    /// (0: x, 1: y, 2: z).
    pub axis_lock: Option<usize>,
    /// Alignment: turn box, capsule and cylinder brushes so that their y axis follows the
    /// surface normal under the pointer (the studio passes it in the pose's orientation).
    pub orient_to_normal: bool,
    /// The level the detail tool raises chunks to (1: 32 cells per chunk side, 2: 64).
    pub detail_level: strata_volume::Level,
    /// The current material (an index into the scene's palette): what add and clay give the
    /// matter they add, and what paint paints.
    pub material: strata_volume::MaterialId,
    /// A stroke follows the surface under the pointer from dab to dab (the sculptors'
    /// convention; see [`crate::Editor::stroke_surface`]); off, it keeps the depth where it
    /// started (a flat path in the view, as the line tool draws). Grab always keeps its depth.
    pub follow_surface: bool,
    /// The stamp tool's image, stroke and turn.
    pub stamp: crate::stamps::StampSettings,
    /// How a pen's pressure scales the radius (by [`ToolSettings::strength`]) and the field
    /// strength (by [`ToolSettings::pressure_to_strength`]), through curves; off, every dab is
    /// made as at full pressure.
    pub pressure: Pressure,
    /// How much pressure scales the field tools' strength: 0 ignores pressure, 1 scales it fully.
    pub pressure_to_strength: f64,
    /// How the field tools' strength falls from the brush's centre to its rim (smooth, inflate,
    /// flatten, paint and mask; grab and pinch keep the smooth falloff, clay and the stamp have
    /// their own profiles).
    pub falloff: strata_volume::tools::Falloff,
}

impl Default for ToolSettings {
    fn default() -> Self {
        ToolSettings {
            kind: ToolKind::Clay,
            detail_level: strata_volume::Level::FINEST,
            shape: BrushShape::Sphere,
            radius: 6.0,
            strength: 0.0,
            spacing: 0.25,
            field_strength: 0.5,
            symmetry: [false; 3],
            symmetry_center: DVec3::ZERO,
            fillet: 0.5,
            paper_smoothing: false,
            grid_snap: 0.0,
            axis_lock: None,
            orient_to_normal: false,
            material: 0,
            follow_surface: true,
            stamp: crate::stamps::StampSettings::default(),
            falloff: strata_volume::tools::Falloff::Smooth,
            pressure: Pressure::default(),
            pressure_to_strength: 0.0,
        }
    }
}

/// The smallest share of the radius pressure leaves.
pub const MIN_PRESSURE_SIZE: f64 = 0.02;

/// How a pen's pressure (0 to 1) acts: a curve for the size and one for the strength, each
/// mapping pressure to a factor (linear by default), and a switch.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pressure {
    /// Pressure counts at all (off: every dab as at full pressure).
    pub enabled: bool,
    /// Pressure → radius factor.
    pub size: strata_volume::tools::FalloffCurve,
    /// Pressure → strength factor.
    pub strength: strata_volume::tools::FalloffCurve,
}

impl Default for Pressure {
    fn default() -> Self {
        let linear = strata_volume::tools::FalloffCurve::linear();
        Pressure { enabled: true, size: linear, strength: linear }
    }
}

impl Pressure {
    fn factor(&self, curve: &strata_volume::tools::FalloffCurve, pressure: f64) -> f64 {
        if !self.enabled {
            return 1.0;
        }
        // (NaN pressure reads as none.)
        let p = if pressure >= 0.0 { pressure.min(1.0) } else { 0.0 };
        curve.at(p)
    }

    /// The size curve's factor at `pressure` (1 when off).
    pub fn size_at(&self, pressure: f64) -> f64 {
        self.factor(&self.size, pressure)
    }

    /// The strength curve's factor at `pressure` (1 when off).
    pub fn strength_at(&self, pressure: f64) -> f64 {
        self.factor(&self.strength, pressure)
    }

    /// Whether both curves are sound.
    pub fn is_valid(&self) -> bool {
        self.size.is_valid() && self.strength.is_valid()
    }
}

/// The rotation that turns the brush's y axis onto `normal` (a unit world vector) by the
/// shortest arc: how a brush is oriented to the surface. A zero or non-finite normal gives the
/// identity.
pub fn orientation_for_normal(normal: DVec3) -> DQuat {
    let n = normal.normalize_or_zero();
    if !n.is_finite() || n == DVec3::ZERO {
        return DQuat::IDENTITY;
    }
    DQuat::from_rotation_arc(DVec3::Y, n)
}

impl ToolSettings {
    /// The mirror images of grid point `g` under [`ToolSettings::symmetry`], as masks (bit `a`:
    /// reflected across the plane of axis `a`), the identity first; images that coincide with
    /// one already listed (a dab on a mirror plane) are left out.
    fn masks(&self, g: DVec3) -> Vec<usize> {
        let mut masks = Vec::with_capacity(8);
        let mut seen: Vec<DVec3> = Vec::with_capacity(8);
        for mask in 0..8usize {
            if (0..3).any(|a| mask & (1 << a) != 0 && !self.symmetry[a]) {
                continue;
            }
            let p = self.reflect_point(g, mask);
            if seen.iter().any(|&o| (o - p).length() <= 1e-9 * (1.0 + p.length())) {
                continue;
            }
            seen.push(p);
            masks.push(mask);
        }
        masks
    }

    fn reflect_point(&self, mut g: DVec3, mask: usize) -> DVec3 {
        for a in (0..3).filter(|a| mask & (1 << a) != 0) {
            g[a] = 2.0 * self.symmetry_center[a] - g[a];
        }
        g
    }

    fn reflect_vector(mut v: DVec3, mask: usize) -> DVec3 {
        for a in (0..3).filter(|a| mask & (1 << a) != 0) {
            v[a] = -v[a];
        }
        v
    }

    /// `M R M` for the reflections of `mask`: for each reflected axis the other two vector parts
    /// of the quaternion change sign (a rotation again).
    fn reflect_rotation(mut q: DQuat, mask: usize) -> DQuat {
        for a in (0..3).filter(|a| mask & (1 << a) != 0) {
            let mut v = [q.x, q.y, q.z];
            for (b, part) in v.iter_mut().enumerate() {
                if b != a {
                    *part = -*part;
                }
            }
            q = DQuat::from_xyzw(v[0], v[1], v[2], q.w);
        }
        q
    }

    /// The dab at world point `position` with world `orientation` and its mirror images under
    /// [`ToolSettings::symmetry`], in a layer placed by `layer`: the original first, images that
    /// coincide with one already listed (a dab on a mirror plane) left out. An orientation is
    /// mirrored as `M R M`, a rotation again, which places the symmetric brush shapes exactly.
    pub fn mirrored(&self, layer: &LayerTransform, position: DVec3, orientation: DQuat) -> Vec<(DVec3, DQuat)> {
        let g = layer.to_grid(position);
        let q = layer.rotation.inverse() * orientation;
        self.masks(g)
            .into_iter()
            .map(|m| (layer.to_world(self.reflect_point(g, m)), layer.rotation * Self::reflect_rotation(q, m)))
            .collect()
    }

    /// For each image of [`ToolSettings::mirrored`] (the same order), whether it is reflected an
    /// odd number of times (left and right swapped: a stamp's picture is mirrored on it).
    pub fn mirror_parities(&self, layer: &LayerTransform, position: DVec3) -> Vec<bool> {
        self.masks(layer.to_grid(position)).into_iter().map(|m| m.count_ones() % 2 == 1).collect()
    }

    /// [`ToolSettings::mirrored`] for a dab that also carries a world direction (a pinch's
    /// stroke line): the same images, each with the direction mirrored as its position is.
    pub fn mirrored_directions(&self, layer: &LayerTransform, position: DVec3, vector: DVec3) -> Vec<(DVec3, DVec3)> {
        let g = layer.to_grid(position);
        let v = layer.rotation.inverse() * vector;
        self.masks(g)
            .into_iter()
            .map(|m| (layer.to_world(self.reflect_point(g, m)), layer.rotation * Self::reflect_vector(v, m)))
            .collect()
    }

    /// The images of a grab's drag: like [`ToolSettings::mirrored_directions`], except that a
    /// dab on a mirror plane keeps its mirrored drag too (the two drags together keep the
    /// surface on the plane symmetric: a point on the plane moves only along it).
    pub fn mirrored_with_vector(&self, layer: &LayerTransform, position: DVec3, vector: DVec3) -> Vec<(DVec3, DVec3)> {
        let g = layer.to_grid(position);
        let v = layer.rotation.inverse() * vector;
        let close = |x: DVec3, y: DVec3| (x - y).length() <= 1e-9 * (1.0 + x.length());
        let mut out: Vec<(DVec3, DVec3)> = Vec::with_capacity(8);
        let mut grid: Vec<(DVec3, DVec3)> = Vec::with_capacity(8);
        for mask in 0..8usize {
            if (0..3).any(|a| mask & (1 << a) != 0 && !self.symmetry[a]) {
                continue;
            }
            let (gm, vm) = (self.reflect_point(g, mask), Self::reflect_vector(v, mask));
            if grid.iter().any(|&(o, ov)| close(o, gm) && close(ov, vm)) {
                continue;
            }
            grid.push((gm, vm));
            out.push((layer.to_world(gm), layer.rotation * vm));
        }
        out
    }

    /// The alignment tool on a stroke position (world): locked to the axis line through the
    /// stroke's `start` (world) if [`ToolSettings::axis_lock`] is set, then snapped to the grid
    /// of [`ToolSettings::grid_snap`], both in the layer placed by `layer`.
    pub fn aligned(&self, layer: &LayerTransform, position: DVec3, start: Option<DVec3>) -> DVec3 {
        let mut g = layer.to_grid(position);
        if let (Some(axis), Some(start)) = (self.axis_lock.filter(|&a| a < 3), start) {
            let s = layer.to_grid(start);
            for a in 0..3 {
                if a != axis {
                    g[a] = s[a];
                }
            }
        }
        let step = self.grid_snap;
        if step.is_finite() && step > 0.0 {
            g = (g / step).round() * step;
        }
        layer.to_world(g)
    }

    /// The radius at `pressure`: scaled by the size curve's value there, as far as
    /// [`ToolSettings::strength`] says, and never below [`MIN_PRESSURE_SIZE`] of the radius (a
    /// pen's lightest touch still dabs).
    pub fn radius_at(&self, pressure: f64) -> f64 {
        let s = self.strength.clamp(0.0, 1.0);
        self.radius * (1.0 - s + s * self.pressure.size_at(pressure)).max(MIN_PRESSURE_SIZE)
    }

    /// The field tools' strength at `pressure`: scaled by the strength curve's value there, as
    /// far as [`ToolSettings::pressure_to_strength`] says.
    pub fn field_strength_at(&self, pressure: f64) -> f64 {
        let k = self.pressure_to_strength.clamp(0.0, 1.0);
        self.field_strength.clamp(0.0, 1.0) * (1.0 - k + k * self.pressure.strength_at(pressure))
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
