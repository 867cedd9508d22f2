//! Island removal: the connected pieces of a mesh that enclose less than a given volume (stray
//! solid nodes make marching-cubes octahedra of 8 to 12 triangles) are dropped, and what was
//! dropped is counted.
//!
//! Pieces are the connected components of the triangles, joined through shared vertex indices
//! *and* through vertices at the same position, so a mesh whose vertices were split for shading
//! ([`crate::normals::crease_normals`]) splits into the same pieces as the welded one. A piece's
//! volume is its signed divergence-theorem volume, measured from one of its own vertices (exact
//! for a closed piece wherever it lies). What is guaranteed:
//! - a piece is removed only if it encloses a positive volume below the threshold; pieces of
//!   negative volume (the walls of cavities) and the piece of largest volume (every piece of that
//!   volume) are always kept, so
//!   a small model is never removed whole;
//! - a threshold of 0 removes nothing; the kept triangles, their vertices and materials are
//!   unchanged, in their original order.
//!
//! ```
//! use glam::DVec3;
//! use strata_volume::{Volume, brush::Sphere};
//! use strata_mesh::{MeshOptions, islands, mesh_volume_with};
//!
//! let mut volume = Volume::new();
//! volume.add(&Sphere::new(DVec3::new(8.0, 8.0, 8.0), 6.0)?)?;
//! volume.add(&Sphere::new(DVec3::new(24.0, 8.0, 8.0), 0.8)?)?;
//! let mut mesh = mesh_volume_with(&volume, MeshOptions::default())?;
//! let report = islands::remove_islands(&mut mesh, islands::DEFAULT_MIN_ISLAND_CELLS)?;
//! assert_eq!((report.removed, report.kept), (1, 1));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::HashMap;

use glam::DVec3;
use thiserror::Error;

use crate::Mesh;

/// A threshold for stray islands, in cells³ (grid units cubed). One isolated solid node meshes
/// by marching cubes as an octahedron of 8 triangles enclosing at most 4/3 cells³, two
/// neighbouring nodes as 12 triangles enclosing at most about 2.7 cells³ (the crossings lie
/// within one cell of their nodes); 8 cells³ removes every piece of up to about six nodes and
/// nothing a sculptor makes on purpose at the base resolution.
pub const DEFAULT_MIN_ISLAND_CELLS: f32 = 8.0;

/// Why islands were not removed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum IslandError {
    /// The threshold is not a finite volume `>= 0`.
    #[error("the island threshold must be a finite number of cells³ >= 0, not {0}")]
    BadThreshold(f32),
}

/// What [`remove_islands`] removed and kept.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IslandReport {
    /// Pieces removed.
    pub removed: usize,
    /// Triangles they held.
    pub removed_triangles: usize,
    /// The volume they enclosed, in cells³ (grid units cubed).
    pub removed_volume: f64,
    /// Pieces kept.
    pub kept: usize,
}

impl IslandReport {
    /// Both reports summed (for one export of several layers).
    pub fn then(self, later: IslandReport) -> IslandReport {
        IslandReport {
            removed: self.removed + later.removed,
            removed_triangles: self.removed_triangles + later.removed_triangles,
            removed_volume: self.removed_volume + later.removed_volume,
            kept: self.kept + later.kept,
        }
    }
}

/// The pieces of a mesh: for every triangle the index of its piece, and the piece count.
/// Triangles are in one piece when they share a vertex index or a vertex position.
pub fn pieces(mesh: &Mesh) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            let next = parent[parent[i as usize] as usize];
            parent[i as usize] = next;
            i = next;
        }
        i
    }
    let union = |parent: &mut Vec<u32>, a: u32, b: u32| {
        let (ra, rb) = (find(parent, a), find(parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    };
    // Vertices at one position (bit for bit; -0.0 taken as 0.0).
    let mut at: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    for (i, p) in mesh.positions.iter().enumerate() {
        let id = p.map(|c| (c + 0.0).to_bits());
        let first = *at.entry(id).or_insert(i as u32);
        union(&mut parent, first, i as u32);
    }
    for [a, b, c] in mesh.triangles() {
        union(&mut parent, a, b);
        union(&mut parent, a, c);
    }
    let mut number: HashMap<u32, u32> = HashMap::new();
    let of_triangle: Vec<u32> = mesh
        .triangles()
        .map(|[a, _, _]| {
            let root = find(&mut parent, a);
            let next = number.len() as u32;
            *number.entry(root).or_insert(next)
        })
        .collect();
    (of_triangle, number.len())
}

/// Removes from `mesh` the pieces that enclose a positive volume below `min_volume` cells³
/// (grid units cubed: meshes of a volume are in grid units), keeping the largest piece and every
/// piece of negative volume (see the module docs). Unused vertices are dropped. A threshold that
/// is NaN, infinite or negative is refused and the mesh is left as it was.
pub fn remove_islands(mesh: &mut Mesh, min_volume: f32) -> Result<IslandReport, IslandError> {
    if !(min_volume.is_finite() && min_volume >= 0.0) {
        return Err(IslandError::BadThreshold(min_volume));
    }
    let bad_index = mesh.indices.iter().any(|&i| i as usize >= mesh.positions.len());
    if mesh.indices.is_empty() || bad_index || !mesh.indices.len().is_multiple_of(3) {
        // Nothing to split (a malformed index buffer is the caller's to check, see
        // `checks::check_closed_manifold`; it is left as it is).
        return Ok(IslandReport::default());
    }
    let (piece, count) = pieces(mesh);
    let at = |i: u32| {
        let p = mesh.positions[i as usize];
        DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
    };
    // Each piece's volume, measured from its first vertex, and its triangle count.
    let mut reference: Vec<Option<DVec3>> = vec![None; count];
    let mut volume = vec![0.0f64; count];
    let mut triangles = vec![0usize; count];
    for (t, [a, b, c]) in mesh.triangles().enumerate() {
        let k = piece[t] as usize;
        let o = *reference[k].get_or_insert(at(a));
        let (a, b, c) = (at(a) - o, at(b) - o, at(c) - o);
        volume[k] += a.dot(b.cross(c)) / 6.0;
        triangles[k] += 1;
    }
    let largest = volume.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let removed: Vec<bool> = volume.iter().map(|&v| v < largest && v > 0.0 && v < min_volume as f64).collect();
    let mut report = IslandReport::default();
    for k in 0..count {
        if removed[k] {
            report.removed += 1;
            report.removed_triangles += triangles[k];
            report.removed_volume += volume[k];
        } else {
            report.kept += 1;
        }
    }
    if report.removed == 0 {
        return Ok(report);
    }
    // The kept vertices, renumbered in their original order, and the kept triangles over them.
    let kept = |t: usize| !removed[piece[t] as usize];
    let mut map = vec![u32::MAX; mesh.positions.len()];
    for (t, tri) in mesh.triangles().enumerate() {
        if kept(t) {
            for i in tri {
                map[i as usize] = 0;
            }
        }
    }
    let mut out = Mesh::default();
    let with_materials = !mesh.materials.is_empty();
    for (i, slot) in map.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = out.positions.len() as u32;
            let normal = mesh.normals.get(i).copied().unwrap_or([0.0, 0.0, 1.0]);
            out.push_vertex(mesh.positions[i], normal, mesh.material(i), with_materials);
        }
    }
    out.indices = mesh
        .triangles()
        .enumerate()
        .filter(|&(t, _)| kept(t))
        .flat_map(|(_, tri)| tri.map(|i| map[i as usize]))
        .collect();
    *mesh = out;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::{check_closed_manifold, signed_volume};
    use crate::marching::mesh_volume;
    use strata_volume::Volume;
    use strata_volume::brush::{Cuboid, Sphere};

    /// A sphere of radius 10 and, two chunks away, a box holding the single node (40, 8, 8).
    fn sphere_and_speck() -> (Mesh, Mesh, Mesh) {
        let sphere = Sphere::new(DVec3::new(8.3, 8.1, 7.9), 10.0).unwrap();
        let speck = Cuboid::new(DVec3::new(40.1, 7.9, 8.05), DVec3::splat(0.6)).unwrap();
        let mut both = Volume::new();
        both.add(&sphere).unwrap();
        both.add(&speck).unwrap();
        let mut alone = Volume::new();
        alone.add(&sphere).unwrap();
        let mut island = Volume::new();
        island.add(&speck).unwrap();
        (mesh_volume(&both), mesh_volume(&alone), mesh_volume(&island))
    }

    #[test]
    fn a_stray_node_is_removed_and_counted_and_the_sphere_kept() {
        let (mut mesh, sphere, speck) = sphere_and_speck();
        assert_eq!(speck.triangle_count(), 8, "one node meshes as an octahedron");
        let report = remove_islands(&mut mesh, DEFAULT_MIN_ISLAND_CELLS).unwrap();
        assert_eq!((report.removed, report.kept), (1, 1), "{report:?}");
        assert_eq!(report.removed_triangles, 8);
        let expected = signed_volume(&speck);
        assert!(expected > 0.0 && (report.removed_volume - expected).abs() < 1e-6, "{report:?} vs {expected}");
        check_closed_manifold(&mesh).unwrap();
        assert_eq!(mesh.triangle_count(), sphere.triangle_count());
        assert_eq!(mesh.vertex_count(), sphere.vertex_count(), "the speck's vertices are dropped too");
        assert!((signed_volume(&mesh) - signed_volume(&sphere)).abs() < 1e-6);
    }

    #[test]
    fn a_zero_threshold_removes_nothing_and_bad_thresholds_are_refused() {
        let (mesh, _, _) = sphere_and_speck();
        let mut same = mesh.clone();
        let report = remove_islands(&mut same, 0.0).unwrap();
        assert_eq!(report, IslandReport { removed: 0, removed_triangles: 0, removed_volume: 0.0, kept: 2 });
        assert_eq!(same, mesh, "nothing changed");
        for bad in [f32::NAN, -1.0, f32::INFINITY, f32::NEG_INFINITY] {
            let mut m = mesh.clone();
            assert!(matches!(remove_islands(&mut m, bad), Err(IslandError::BadThreshold(_))), "{bad} is refused");
            assert_eq!(m, mesh, "a refused threshold leaves the mesh as it was");
        }
        let mut empty = Mesh::default();
        assert_eq!(remove_islands(&mut empty, 8.0).unwrap(), IslandReport::default());
    }

    #[test]
    fn the_largest_piece_and_cavity_walls_are_kept_whatever_the_threshold() {
        // A hollow ball: its outer wall encloses a positive volume, the cavity's wall a negative one.
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(8.2, 8.1, 7.7), 7.0).unwrap()).unwrap();
        v.subtract(&Sphere::new(DVec3::new(8.2, 8.1, 7.7), 3.0).unwrap()).unwrap();
        let mesh = mesh_volume(&v);
        assert_eq!(pieces(&mesh).1, 2);
        let mut m = mesh.clone();
        let report = remove_islands(&mut m, 1e9).unwrap();
        assert_eq!((report.removed, report.kept), (0, 2), "{report:?}");
        assert_eq!(m, mesh);
    }

    #[test]
    fn vertices_split_for_shading_split_into_the_same_pieces() {
        let (mesh, _, _) = sphere_and_speck();
        let mut shaded = crate::normals::crease_normals(&mesh, 5.0);
        assert!(shaded.vertex_count() > mesh.vertex_count(), "the narrow crease angle splits vertices");
        assert_eq!(pieces(&shaded).1, 2);
        let report = remove_islands(&mut shaded, DEFAULT_MIN_ISLAND_CELLS).unwrap();
        assert_eq!((report.removed, report.removed_triangles), (1, 8));
        let a = IslandReport { removed: 1, removed_triangles: 8, removed_volume: 1.0, kept: 1 };
        assert_eq!(a.then(a), IslandReport { removed: 2, removed_triangles: 16, removed_volume: 2.0, kept: 2 });
    }
}
