//! Mesh checks: closedness, edge-manifoldness, orientation, volume, area, triangle quality.

use std::collections::HashMap;

use glam::DVec3;
use thiserror::Error;

use crate::Mesh;

/// Why a mesh is not a closed, edge-manifold, consistently oriented surface.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum MeshDefect {
    /// An index names no vertex, or the index count is not a multiple of 3.
    #[error("malformed index buffer")]
    BadIndices,
    /// A triangle uses a vertex twice.
    #[error("triangle {0} is degenerate (repeats a vertex)")]
    DegenerateTriangle(usize),
    /// An edge used by one triangle only (a hole), or by more than two.
    #[error("edge {0}-{1} is used by {2} triangles")]
    NotManifold(u32, u32, usize),
    /// An edge used twice in the same direction: neighbouring triangles disagree on orientation.
    #[error("edge {0}-{1} is used twice in the same direction")]
    Misoriented(u32, u32),
}

/// Checks that every edge is shared by exactly two triangles that traverse it in opposite
/// directions (closed, edge-manifold, consistently oriented).
pub fn check_closed_manifold(mesh: &Mesh) -> Result<(), MeshDefect> {
    if !mesh.indices.len().is_multiple_of(3) || mesh.indices.iter().any(|&i| i as usize >= mesh.positions.len()) {
        return Err(MeshDefect::BadIndices);
    }
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.indices.len());
    for (t, [a, b, c]) in mesh.triangles().enumerate() {
        if a == b || b == c || a == c {
            return Err(MeshDefect::DegenerateTriangle(t));
        }
        for (p, q) in [(a, b), (b, c), (c, a)] {
            let n = directed.entry((p, q)).or_default();
            *n += 1;
            if *n > 1 {
                return Err(MeshDefect::Misoriented(p, q));
            }
        }
    }
    for &(p, q) in directed.keys() {
        if !directed.contains_key(&(q, p)) {
            return Err(MeshDefect::NotManifold(p.min(q), p.max(q), 1));
        }
    }
    Ok(())
}

fn corners(mesh: &Mesh, t: [u32; 3]) -> [DVec3; 3] {
    t.map(|i| {
        let p = mesh.positions[i as usize];
        DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
    })
}

/// Enclosed volume by the divergence theorem (positive for outward-facing closed meshes).
pub fn signed_volume(mesh: &Mesh) -> f64 {
    mesh.triangles()
        .map(|t| {
            let [a, b, c] = corners(mesh, t);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Total surface area.
pub fn surface_area(mesh: &Mesh) -> f64 {
    mesh.triangles()
        .map(|t| {
            let [a, b, c] = corners(mesh, t);
            (b - a).cross(c - a).length() / 2.0
        })
        .sum()
}

/// Triangle quality statistics. Aspect ratio is the longest edge over the shortest altitude
/// times `sqrt(3) / 2`, so an equilateral triangle scores 1; degenerate ones are infinite.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AspectStats {
    /// Triangles counted.
    pub triangles: usize,
    /// Mean aspect ratio over non-degenerate triangles.
    pub mean: f64,
    /// Largest finite aspect ratio.
    pub max: f64,
    /// Triangles with zero area.
    pub degenerate: usize,
    /// Share of triangles with aspect ratio above 4.
    pub above_4: f64,
}

/// Aspect-ratio statistics of all triangles.
pub fn aspect_stats(mesh: &Mesh) -> AspectStats {
    let mut s = AspectStats { triangles: mesh.triangle_count(), ..Default::default() };
    let (mut sum, mut finite, mut bad) = (0.0, 0usize, 0usize);
    for t in mesh.triangles() {
        let [a, b, c] = corners(mesh, t);
        let area2 = (b - a).cross(c - a).length();
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        if area2 <= 0.0 {
            s.degenerate += 1;
            continue;
        }
        let altitude = area2 / longest;
        let r = longest / altitude * (3f64.sqrt() / 2.0);
        sum += r;
        finite += 1;
        s.max = s.max.max(r);
        bad += (r > 4.0) as usize;
    }
    s.mean = if finite > 0 { sum / finite as f64 } else { 0.0 };
    s.above_4 = if s.triangles > 0 { bad as f64 / s.triangles as f64 } else { 0.0 };
    s
}

/// Edge statistics of a mesh that may not be manifold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ManifoldReport {
    /// Distinct undirected edges.
    pub edges: usize,
    /// Edges used by exactly one triangle (holes).
    pub boundary: usize,
    /// Edges used by more than two triangles, or twice in the same direction.
    pub non_manifold: usize,
}

/// Counts boundary and non-manifold edges (for meshers that do not guarantee manifoldness).
pub fn manifold_report(mesh: &Mesh) -> ManifoldReport {
    let mut uses: HashMap<(u32, u32), (u32, u32)> = HashMap::new();
    for [a, b, c] in mesh.triangles() {
        for (p, q) in [(a, b), (b, c), (c, a)] {
            let e = uses.entry((p.min(q), p.max(q))).or_default();
            if p < q { e.0 += 1 } else { e.1 += 1 }
        }
    }
    let mut r = ManifoldReport { edges: uses.len(), ..Default::default() };
    for (f, b) in uses.values() {
        match (f, b) {
            (1, 1) => {}
            _ if f + b == 1 => r.boundary += 1,
            _ => r.non_manifold += 1,
        }
    }
    r
}
