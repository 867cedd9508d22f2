//! Meshes into layers: the plan of a conversion (cell size, placement, an estimate of what it
//! will store) and the conversion itself, shared by the command line's `convert` and the
//! studio's File → Import mesh.
//!
//! A converted layer keeps the mesh's own units: its grid starts two cells below the mesh's
//! lowest corner (so the solid never touches the grid's first nodes) and its transform scales
//! cells back to the mesh's units.

use glam::{DQuat, DVec3};
use strata_mesh::import::TriangleMesh;
use strata_volume::brush::{MeshBrush, MeshRule};
use strata_volume::{CsgOp, EditError, EditSettings, Volume};
use thiserror::Error;

use crate::scene::{Layer, LayerTransform};

/// The most cells along a converted mesh's longest side (a box of up to 256³ chunks: the
/// bunny at 4096 cells stores about 240 MB).
pub const MAX_CELLS: u32 = 4096;

/// Bytes a stored crossing costs, headers and chunk map included, as measured on the bunny at
/// 256 to 1024 cells (4.6 to 4.8): what [`ImportPlan::estimated_bytes`] multiplies by.
pub const BYTES_PER_CROSSING: f64 = 4.8;

/// How fine a conversion is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Resolution {
    /// This many cells along the mesh's longest side.
    Cells(u32),
    /// Cells of this size, in the mesh's units.
    CellSize(f64),
}

/// Why a mesh cannot be converted.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ConvertError {
    /// A cell count of zero or above [`MAX_CELLS`].
    #[error("the cell count must be between 1 and {MAX_CELLS}, got {0}")]
    BadCells(u32),
    /// A cell size that is not finite and positive.
    #[error("the cell size must be a finite positive number, got {0}")]
    BadCellSize(f64),
    /// The cell size puts more than [`MAX_CELLS`] cells along the longest side.
    #[error("cells of {cell} put {cells:.0} cells along the mesh's longest side (at most {MAX_CELLS})")]
    TooFine {
        /// The cell size.
        cell: f64,
        /// Cells along the longest side.
        cells: f64,
    },
    /// The mesh has no extent (a point or a flat mesh with no thickness in every direction).
    #[error("the mesh has no extent")]
    NoExtent,
    /// The brush could not be built from the mesh.
    #[error("{0}")]
    Mesh(String),
    /// The conversion edit failed or was cancelled.
    #[error(transparent)]
    Edit(#[from] EditError),
}

/// What a conversion will do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImportPlan {
    /// Cell size in the mesh's units.
    pub cell: f64,
    /// Where the layer's grid origin lies, in the mesh's units.
    pub origin: DVec3,
    /// Cells along the mesh's longest side.
    pub cells_long: f64,
    /// The crossings the conversion will store, estimated from the triangles: a triangle of area
    /// `A` and unit normal `n` meets `A (|nx| + |ny| + |nz|) / cell²` grid lines.
    pub estimated_crossings: f64,
}

impl ImportPlan {
    /// The memory the layer will take, estimated (bytes).
    pub fn estimated_bytes(&self) -> f64 {
        self.estimated_crossings * BYTES_PER_CROSSING
    }
}

/// Plans converting `mesh` at `resolution`.
pub fn plan(mesh: &TriangleMesh, resolution: Resolution) -> Result<ImportPlan, ConvertError> {
    let (lo, hi) = mesh.bounds().ok_or(ConvertError::NoExtent)?;
    let extent = (hi - lo).max_element();
    if !(extent.is_finite() && extent > 0.0) {
        return Err(ConvertError::NoExtent);
    }
    let cell = match resolution {
        Resolution::Cells(n) if n == 0 || n > MAX_CELLS => return Err(ConvertError::BadCells(n)),
        Resolution::Cells(n) => extent / n as f64,
        Resolution::CellSize(s) if !(s.is_finite() && s > 0.0) => return Err(ConvertError::BadCellSize(s)),
        Resolution::CellSize(s) => s,
    };
    let cells_long = extent / cell;
    if !(cells_long <= MAX_CELLS as f64 + 1e-9) {
        return Err(ConvertError::TooFine { cell, cells: cells_long });
    }
    let mut projected = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices.get(i as usize).copied().unwrap_or_default());
        // Half the cross product: the area times the unit normal.
        let n = (b - a).cross(c - a) * 0.5;
        projected += n.x.abs() + n.y.abs() + n.z.abs();
    }
    Ok(ImportPlan {
        cell,
        origin: lo - DVec3::splat(2.0 * cell),
        cells_long,
        estimated_crossings: projected / (cell * cell),
    })
}

/// Converts `mesh` as `plan` says into a layer named `name`, deciding inside by `rule`; the
/// edit runs with `settings` (progress and cancel through its control), without its chunk limit:
/// the size is the user's explicit choice, bounded by [`MAX_CELLS`].
pub fn convert(
    mesh: &TriangleMesh,
    plan: &ImportPlan,
    rule: MeshRule,
    name: &str,
    settings: &EditSettings,
) -> Result<Layer, ConvertError> {
    let verts: Vec<DVec3> = mesh.vertices.iter().map(|&v| (v - plan.origin) / plan.cell).collect();
    let brush = MeshBrush::new(&verts, &mesh.triangles, rule).map_err(|e| ConvertError::Mesh(e.to_string()))?;
    let mut volume = Volume::new();
    let settings = EditSettings { max_chunks: u64::MAX, ..settings.clone() };
    volume.apply(CsgOp::Add, &brush, &settings)?;
    let mut layer = Layer::new(name);
    layer.volume = volume;
    layer.transform = LayerTransform::new(plan.origin, DQuat::IDENTITY, plan.cell)
        .map_err(|_| ConvertError::BadCellSize(plan.cell))?;
    Ok(layer)
}

/// Whether `mesh` is closed (every edge shared by two triangles): an open mesh is filled line
/// by line, which a user should know.
pub fn is_closed(mesh: &TriangleMesh) -> bool {
    MeshBrush::new(&mesh.vertices, &mesh.triangles, MeshRule::EvenOdd).is_ok_and(|b| b.is_closed())
}
