//! Simplification for export and for chunk meshes, by meshoptimizer's edge-collapse simplifier
//! (the `meshopt` bindings, which vendor meshoptimizer 1.3).
//!
//! The pure-Rust port `meshopt-rs` (0.1.2) was weighed against it: it ports an older
//! meshoptimizer without border locking, which per-chunk simplification needs (a chunk's border
//! vertices are shared with its neighbours, meshoptimizer issue #311), so the bindings are used.
//! `strata-bench quality` measures both on the whole-mesh export path.
//!
//! Collapses move no vertex: every surviving vertex keeps its position, normal and material.

use thiserror::Error;

use crate::Mesh;

/// Why a mesh was not simplified.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SimplifyError {
    /// The error bound is not a finite number of grid units `>= 0`.
    #[error("the simplification error must be a finite number of cells >= 0, not {0}")]
    BadError(f32),
    /// The mesh has a non-finite position (it would poison the simplifier's error metric).
    #[error("vertex {0} has a non-finite position")]
    NonFinite(usize),
}

/// How to simplify.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Simplify {
    /// How far the simplified surface may move from the original, in grid units (cells of the
    /// base level; meshes are in grid units), as meshoptimizer estimates it from its quadrics:
    /// measured Hausdorff distances reach about 1.6 times this.
    pub max_error: f32,
    /// Keep the vertices on the mesh's open border where they are, with their edges (for chunk
    /// meshes: their border is shared with the neighbouring chunks' meshes).
    pub lock_border: bool,
}

impl Simplify {
    /// Whole closed meshes (export): nothing locked.
    pub const fn export(max_error: f32) -> Self {
        Simplify { max_error, lock_border: false }
    }

    /// Chunk meshes: border locked.
    pub const fn chunk(max_error: f32) -> Self {
        Simplify { max_error, lock_border: true }
    }
}

/// `mesh` simplified as far as `how.max_error` allows (no triangle target), with unused vertices
/// dropped.
pub fn simplify(mesh: &Mesh, how: Simplify) -> Result<Mesh, SimplifyError> {
    if !(how.max_error.is_finite() && how.max_error >= 0.0) {
        return Err(SimplifyError::BadError(how.max_error));
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(SimplifyError::NonFinite(i));
    }
    if mesh.indices.is_empty() || how.max_error == 0.0 {
        return Ok(mesh.clone());
    }
    let mut options = meshopt::SimplifyOptions::ErrorAbsolute;
    if how.lock_border {
        options |= meshopt::SimplifyOptions::LockBorder;
    }
    let indices = meshopt::simplify_decoder(&mesh.indices, &mesh.positions, 0, how.max_error, options, None);
    Ok(compact(mesh, &indices))
}

/// The vertices of `mesh` that `indices` use, renumbered in order of first use.
fn compact(mesh: &Mesh, indices: &[u32]) -> Mesh {
    let mut map = vec![u32::MAX; mesh.positions.len()];
    let mut out = Mesh::default();
    let with_materials = !mesh.materials.is_empty();
    for &i in indices {
        let slot = &mut map[i as usize];
        if *slot == u32::MAX {
            *slot = out.positions.len() as u32;
            out.push_vertex(
                mesh.positions[i as usize],
                mesh.normals[i as usize],
                mesh.material(i as usize),
                with_materials,
            );
        }
        out.indices.push(*slot);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::{check_closed_manifold, signed_volume};
    use glam::DVec3;
    use strata_volume::Volume;
    use strata_volume::brush::Sphere;

    #[test]
    fn a_sphere_simplifies_closed_within_its_error() {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(9.3, 7.1, 8.4), 12.0).unwrap()).unwrap();
        let mesh = crate::marching::mesh_volume(&v);
        let simple = simplify(&mesh, Simplify::export(0.1)).unwrap();
        check_closed_manifold(&simple).unwrap();
        assert!(
            simple.triangle_count() * 2 < mesh.triangle_count(),
            "{} of {}",
            simple.triangle_count(),
            mesh.triangle_count()
        );
        let (a, b) = (signed_volume(&mesh), signed_volume(&simple));
        // A convex surface loses about its area times half the error.
        assert!((a - b).abs() / a < 0.02, "{a} {b}");
        let h = crate::checks::hausdorff(&mesh, &simple, 2.0);
        // meshoptimizer's error is a quadric estimate of the distance, not a bound: measured, the
        // surface moves up to about 1.6 times as far.
        assert!(h <= 0.2, "Hausdorff {h}");
        assert!(matches!(simplify(&mesh, Simplify::export(f32::NAN)), Err(SimplifyError::BadError(_))));
        assert!(matches!(simplify(&mesh, Simplify::export(-1.0)), Err(SimplifyError::BadError(_))));
        assert!(matches!(simplify(&mesh, Simplify::export(f32::INFINITY)), Err(SimplifyError::BadError(_))));
        let mut broken = mesh.clone();
        broken.positions[3][1] = f32::NAN;
        assert_eq!(simplify(&broken, Simplify::export(0.1)), Err(SimplifyError::NonFinite(3)));
    }
}
