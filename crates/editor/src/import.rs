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
/// 256 to 1024 cells (4.5 to 4.7): what [`ImportPlan::estimated_bytes`] multiplies by.
pub const BYTES_PER_CROSSING: f64 = 4.6;

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

#[cfg(test)]
mod tests {
    use super::*;

    fn bunny() -> TriangleMesh {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply");
        strata_mesh::import::load_mesh(&path).unwrap()
    }

    #[test]
    fn the_plan_estimates_what_the_conversion_stores() {
        let mesh = bunny();
        for cells in [32, 96] {
            let plan = plan(&mesh, Resolution::Cells(cells)).unwrap();
            assert!((plan.cells_long - cells as f64).abs() < 1e-9);
            let layer = convert(&mesh, &plan, MeshRule::EvenOdd, "bunny", &EditSettings::default()).unwrap();
            layer.volume.check_invariants().unwrap();
            let stored = layer.volume.crossing_stats().total as f64;
            assert!((plan.estimated_crossings / stored - 1.0).abs() < 0.05, "{} vs {stored}", plan.estimated_crossings);
            let bytes = layer.volume.memory().total() as f64;
            assert!((plan.estimated_bytes() / bytes - 1.0).abs() < 0.25, "{} vs {bytes}", plan.estimated_bytes());
            // The layer sits where the mesh was, in the mesh's units.
            let (lo, _) = mesh.bounds().unwrap();
            assert!((layer.transform.to_world(DVec3::splat(2.0)) - lo).length() < 1e-9);
        }
        assert!(is_closed(&mesh));
    }

    #[test]
    fn bad_resolutions_and_flat_meshes_are_refused() {
        let mesh = bunny();
        assert_eq!(plan(&mesh, Resolution::Cells(0)), Err(ConvertError::BadCells(0)));
        assert_eq!(plan(&mesh, Resolution::Cells(MAX_CELLS + 1)), Err(ConvertError::BadCells(MAX_CELLS + 1)));
        for s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(plan(&mesh, Resolution::CellSize(s)), Err(ConvertError::BadCellSize(_))), "{s}");
        }
        assert!(matches!(plan(&mesh, Resolution::CellSize(1e-9)), Err(ConvertError::TooFine { .. })));
        let point = TriangleMesh { vertices: vec![DVec3::ONE; 3], triangles: vec![[0, 1, 2]] };
        assert_eq!(plan(&point, Resolution::Cells(8)), Err(ConvertError::NoExtent));
    }
}
