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
    /// Standard deviation of the aspect ratio over non-degenerate triangles.
    pub sd: f64,
    /// The smallest interior angle of any triangle, in degrees (0 with a degenerate one).
    pub min_angle_deg: f64,
}

/// Aspect-ratio statistics of all triangles.
pub fn aspect_stats(mesh: &Mesh) -> AspectStats {
    let mut s = AspectStats { triangles: mesh.triangle_count(), ..Default::default() };
    let (mut sum, mut sum2, mut finite, mut bad) = (0.0, 0.0, 0usize, 0usize);
    s.min_angle_deg = if mesh.indices.is_empty() { 0.0 } else { 180.0 };
    for t in mesh.triangles() {
        let [a, b, c] = corners(mesh, t);
        let area2 = (b - a).cross(c - a).length();
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        if area2 <= 0.0 {
            s.degenerate += 1;
            s.min_angle_deg = 0.0;
            continue;
        }
        for (p, q, r) in [(a, b, c), (b, c, a), (c, a, b)] {
            s.min_angle_deg = s.min_angle_deg.min((q - p).angle_between(r - p).to_degrees());
        }
        let altitude = area2 / longest;
        let r = longest / altitude * (3f64.sqrt() / 2.0);
        sum += r;
        sum2 += r * r;
        finite += 1;
        s.max = s.max.max(r);
        bad += (r > 4.0) as usize;
    }
    s.mean = if finite > 0 { sum / finite as f64 } else { 0.0 };
    s.sd = if finite > 0 { (sum2 / finite as f64 - s.mean * s.mean).max(0.0).sqrt() } else { 0.0 };
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

/// Distance from `p` to the triangle `abc`.
pub fn point_triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    // Ericson, Real-Time Collision Detection, 5.1.5: the closest point by Voronoi regions.
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return p.distance(a);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return p.distance(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return p.distance(a + ab * (d1 / (d1 - d3)));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return p.distance(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return p.distance(a + ac * (d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return p.distance(b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denom = va + vb + vc;
    if denom.abs() < 1e-300 {
        return p.distance(a).min(p.distance(b)).min(p.distance(c));
    }
    p.distance(a + ab * (vb / denom) + ac * (vc / denom))
}

/// Triangles of a mesh bucketed in a uniform grid, for nearest-surface queries.
#[derive(Debug)]
pub struct SurfaceIndex<'a> {
    mesh: &'a Mesh,
    cell: f64,
    buckets: HashMap<(i64, i64, i64), Vec<u32>>,
}

impl<'a> SurfaceIndex<'a> {
    /// Buckets of side `cell` (grid units; about the longest edge is a good choice).
    pub fn new(mesh: &'a Mesh, cell: f64) -> Self {
        let mut buckets: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
        for (i, t) in mesh.triangles().enumerate() {
            let [a, b, c] = corners(mesh, t);
            let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
            let (l, h) = ((lo / cell).floor(), (hi / cell).floor());
            for z in l.z as i64..=h.z as i64 {
                for y in l.y as i64..=h.y as i64 {
                    for x in l.x as i64..=h.x as i64 {
                        buckets.entry((x, y, z)).or_default().push(i as u32);
                    }
                }
            }
        }
        SurfaceIndex { mesh, cell, buckets }
    }

    /// Distance from `p` to the nearest triangle, searched out to `max` (returns `max` if none
    /// is nearer). Searches shells of buckets outwards and stops once the nearest triangle is
    /// nearer than any unsearched bucket.
    pub fn distance(&self, p: DVec3, max: f64) -> f64 {
        let c = (p / self.cell).floor();
        let (cx, cy, cz) = (c.x as i64, c.y as i64, c.z as i64);
        let reach = (max / self.cell).ceil() as i64;
        let mut best = max;
        for r in 0..=reach {
            for z in -r..=r {
                for y in -r..=r {
                    for x in -r..=r {
                        if x.abs().max(y.abs()).max(z.abs()) != r {
                            continue; // searched in an earlier shell
                        }
                        let Some(ts) = self.buckets.get(&(cx + x, cy + y, cz + z)) else { continue };
                        for &t in ts {
                            let i = 3 * t as usize;
                            let tri = [self.mesh.indices[i], self.mesh.indices[i + 1], self.mesh.indices[i + 2]];
                            let [a, b, cc] = corners(self.mesh, tri);
                            best = best.min(point_triangle_distance(p, a, b, cc));
                        }
                    }
                }
            }
            // Every point of an unsearched bucket is at least `r` buckets away.
            if best <= r as f64 * self.cell {
                break;
            }
        }
        best
    }
}

/// Points spread over a mesh's surface: its vertices, edge midpoints and triangle centroids.
pub fn surface_samples(mesh: &Mesh) -> Vec<DVec3> {
    let mut out: Vec<DVec3> =
        mesh.positions.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).collect();
    for t in mesh.triangles() {
        let [a, b, c] = corners(mesh, t);
        out.extend([(a + b + c) / 3.0, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5]);
    }
    out
}

/// The symmetric Hausdorff distance between two meshes, measured at the vertices, edge midpoints
/// and centroids of each against the other's triangles, capped at `max` (grid units).
pub fn hausdorff(a: &Mesh, b: &Mesh, max: f64) -> f64 {
    distance_to(a, b, max).max(distance_to(b, a, max))
}

/// The one-way Hausdorff distance: the largest distance from `from`'s surface samples
/// ([`surface_samples`]) to `to`'s triangles, capped at `max` (grid units).
pub fn distance_to(from: &Mesh, to: &Mesh, max: f64) -> f64 {
    let index = SurfaceIndex::new(to, 0.5);
    surface_samples(from).into_iter().map(|p| index.distance(p, max)).fold(0.0, f64::max)
}

/// Chunk meshes (chunk-local positions) welded into one mesh by exact position: vertices two
/// chunks share on their common face are computed from the same crossings by both, so they
/// agree bit for bit and weld, and any crack between chunk meshes shows as open edges.
pub fn weld_by_position<'a>(parts: impl IntoIterator<Item = (strata_volume::ChunkKey, &'a Mesh)>) -> Mesh {
    let mut out = Mesh::default();
    let mut at: HashMap<[u32; 3], u32> = HashMap::new();
    for (key, m) in parts {
        let o = key.origin_grid().as_vec3().to_array();
        let remap: Vec<u32> = (0..m.positions.len())
            .map(|i| {
                let p = m.positions[i];
                let id = [p[0] + o[0], p[1] + o[1], p[2] + o[2]].map(f32::to_bits);
                *at.entry(id).or_insert_with(|| out.push_vertex_from(m, i, o))
            })
            .collect();
        out.indices.extend(m.indices.iter().map(|&i| remap[i as usize]));
    }
    out
}
