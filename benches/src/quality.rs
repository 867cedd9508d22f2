//! Table 10 — mesh quality, in the form of the tetrahedra study's Fig. 24: per shape (sphere,
//! bunny, noise asteroid, the Table 1 canvas) and per mesher, triangles, vertices, time on one
//! thread, triangle aspect ratio (mean and standard deviation), minimum angle, Hausdorff error to
//! the analytic or reference surface, and whether the mesh is closed and edge-manifold.

use std::time::Instant;

use glam::DVec3;
use noise::{Fbm, MultiFractal, NoiseFn, Perlin};
use serde::Serialize;
use strata_mesh::Mesh;
use strata_mesh::checks::{aspect_stats, distance_to, manifold_report, signed_volume, surface_samples};
use strata_mesh::{MeshOptions, Mesher, mesh_volume_with};
use strata_volume::brush::{Aabb, Brush, MeshBrush, MeshRule, SdfBrush, Sphere};
use strata_volume::{Axis, CsgOp, EditSettings, Volume};

use crate::table1_instructions;

/// A test shape: its volume and a reference to measure the error against.
#[derive(Debug)]
pub struct Shape {
    /// Its name in the table.
    pub name: String,
    /// The solid as segment lists.
    pub volume: Volume,
    /// The surface the error is measured against.
    pub reference: Reference,
}

/// What a mesh's error is measured against.
#[derive(Debug)]
pub enum Reference {
    /// A sphere: the distance to it is exact.
    Sphere(DVec3, f64),
    /// A triangle mesh in grid units (the input mesh, or a mesh of a four times finer grid).
    Mesh(Mesh),
}

impl Reference {
    /// Largest distance from the samples of `mesh` (vertices, edge midpoints, centroids) to
    /// the reference surface, in cells.
    pub fn error(&self, mesh: &Mesh) -> f64 {
        match self {
            Reference::Sphere(c, r) => {
                surface_samples(mesh).iter().map(|p| (p.distance(*c) - r).abs()).fold(0.0, f64::max)
            }
            Reference::Mesh(m) => distance_to(mesh, m, 4.0),
        }
    }
}

fn convert(brush: &dyn Brush) -> Volume {
    let mut v = Volume::new();
    v.apply(CsgOp::Add, brush, &EditSettings::default()).expect("the quality shapes are valid brushes");
    v
}

/// A sphere of diameter `res` cells, off the grid.
pub fn sphere(res: u32) -> Shape {
    let r = res as f64 / 2.0;
    let c = DVec3::splat(r + 2.3) + DVec3::new(0.17, -0.31, 0.05);
    let volume = convert(&Sphere::new(c, r).expect("a valid sphere"));
    Shape { name: format!("sphere {res}"), volume, reference: Reference::Sphere(c, r) }
}

/// The bunny (`vertices`, `triangles`) scaled to `res` cells along its longest side, with two
/// cells of margin; its reference is the input mesh.
pub fn bunny(vertices: &[DVec3], triangles: &[[u32; 3]], res: u32) -> anyhow::Result<Shape> {
    let lo = vertices.iter().fold(DVec3::splat(f64::MAX), |a, &b| a.min(b));
    let hi = vertices.iter().fold(DVec3::splat(f64::MIN), |a, &b| a.max(b));
    let scale = res as f64 / (hi - lo).max_element();
    let verts: Vec<DVec3> = vertices.iter().map(|&v| (v - lo) * scale + DVec3::splat(2.0)).collect();
    let brush = MeshBrush::new(&verts, triangles, MeshRule::EvenOdd)?;
    let mut reference = Mesh::default();
    for v in &verts {
        reference.push_vertex(v.as_vec3().to_array(), [0.0, 0.0, 1.0], Default::default(), false);
    }
    reference.indices = triangles.iter().flatten().copied().collect();
    Ok(Shape { name: format!("bunny {res}"), volume: convert(&brush), reference: Reference::Mesh(reference) })
}

/// The asteroid's field at `scale` times the grid: a ball of diameter `res` whose radius is
/// modulated by fBm Perlin noise (five octaves, ±30 %).
fn asteroid_brush(res: u32, scale: f64) -> SdfBrush {
    let r = res as f64 / 2.0 * scale;
    let c = DVec3::splat(res as f64 / 2.0 * 1.35 + 2.0) * scale;
    let fbm: Fbm<Perlin> = Fbm::new(7).set_octaves(5);
    let freq = 3.0 / (2.0 * r);
    let field = move |p: DVec3| {
        let d = p - c;
        let n = fbm.get((d * freq).to_array());
        d.length() - r * (1.0 + 0.3 * n)
    };
    // |∇n| stays below 4 per unit of the noise's input for these octaves (their gradients
    // halve in amplitude as they double in frequency); the field is 1 + 0.3 r 4 freq Lipschitz.
    let lipschitz = 1.0 + 0.3 * r * 4.0 * freq * 2.0;
    let half = DVec3::splat(r * 1.35 + 1.0);
    SdfBrush::new(field, Aabb::new(c - half, c + half), lipschitz).expect("the asteroid's parameters are valid")
}

/// A noise asteroid of about `res` cells across; its reference is the marching-cubes mesh of the
/// same field on a twice finer grid.
pub fn asteroid(res: u32) -> Shape {
    let volume = asteroid_volume(res);
    let mut reference =
        strata_mesh::mesh_volume_with(&convert(&asteroid_brush(res, 2.0)), strata_mesh::MeshOptions::default())
            .expect("marching cubes meshes every volume");
    for p in &mut reference.positions {
        *p = p.map(|c| c / 2.0);
    }
    Shape { name: format!("asteroid {res}"), volume, reference: Reference::Mesh(reference) }
}

/// The asteroid's lists alone (no reference).
pub fn asteroid_volume(res: u32) -> Volume {
    convert(&asteroid_brush(res, 1.0))
}

/// The Table 1 canvas after `count` radius-10 instructions; its reference is the same
/// instructions applied at twice the scale, meshed by marching cubes.
pub fn canvas(count: usize, seed: u64) -> Shape {
    let build = |scale: f64| {
        let mut v = Volume::new();
        for ins in table1_instructions(count, 10.0, seed) {
            let s = Sphere::new(ins.center * scale, ins.radius * scale).expect("valid spheres");
            v.apply(ins.op, &s, &EditSettings::default()).expect("valid edits");
        }
        v
    };
    let mut reference = strata_mesh::mesh_volume_with(&build(2.0), strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    for p in &mut reference.positions {
        *p = p.map(|c| c / 2.0);
    }
    Shape {
        name: format!("Table 1 canvas ({count} × r10)"), volume: build(1.0), reference: Reference::Mesh(reference)
    }
}

/// How a row's mesh was made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// A mesher on the whole volume (welded), optionally simplified by meshoptimizer.
    Whole(MeshOptions),
    /// Regularised tetrahedra chunk by chunk (chunk faces locked, as the viewport meshes),
    /// welded.
    ChunkedClustered,
    /// Marching cubes simplified by the pure-Rust port `meshopt-rs`, for comparison.
    McSimplifiedPureRust(f32),
}

impl Method {
    /// The row's name.
    pub fn name(&self) -> String {
        match self {
            Method::Whole(o) => match (o.mesher, o.simplify) {
                (Mesher::ClusteredTetrahedra, None) => "MT + clustering".into(),
                (Mesher::Tetrahedra, None) => "MT".into(),
                (Mesher::MarchingCubes, None) => "MC".into(),
                (Mesher::DualContouring, None) => "manifold DC".into(),
                (Mesher::SingleVertexDualContouring, None) => "DC (one vertex a cell)".into(),
                (m, Some(e)) => format!("{} + simplification {e} (meshopt)", m.key().to_uppercase()),
            },
            Method::ChunkedClustered => "MT + clustering, per chunk".into(),
            Method::McSimplifiedPureRust(e) => format!("MC + simplification {e} (meshopt-rs)"),
        }
    }
}

/// The methods of Table 10, in its order.
pub fn methods() -> Vec<Method> {
    vec![
        Method::Whole(MeshOptions::new(Mesher::MarchingCubes)),
        Method::Whole(MeshOptions::new(Mesher::SingleVertexDualContouring)),
        Method::Whole(MeshOptions::new(Mesher::DualContouring)),
        Method::Whole(MeshOptions::new(Mesher::Tetrahedra)),
        Method::Whole(MeshOptions::new(Mesher::ClusteredTetrahedra)),
        Method::ChunkedClustered,
        Method::Whole(MeshOptions { mesher: Mesher::MarchingCubes, simplify: Some(0.1), remove_islands: None }),
        Method::McSimplifiedPureRust(0.1),
    ]
}

/// One row of Table 10.
#[derive(Clone, Debug, Serialize)]
pub struct QualityRow {
    /// The shape.
    pub shape: String,
    /// The mesher.
    pub mesher: String,
    /// Triangles.
    pub triangles: usize,
    /// Vertices.
    pub vertices: usize,
    /// Meshing time on one thread (ms), best of the runs.
    pub ms: f64,
    /// Mean triangle aspect ratio (1 for equilateral).
    pub aspect_mean: f64,
    /// Its standard deviation.
    pub aspect_sd: f64,
    /// The smallest angle of any triangle (degrees).
    pub min_angle: f64,
    /// Hausdorff error to the reference surface (cells).
    pub error: f64,
    /// Enclosed volume over the lists' volume.
    pub volume_ratio: f64,
    /// Open edges.
    pub open_edges: usize,
    /// Non-manifold edges.
    pub non_manifold_edges: usize,
}

/// The mesh of `shape` by `method`.
pub fn mesh_with(volume: &Volume, method: Method) -> anyhow::Result<Mesh> {
    Ok(match method {
        Method::Whole(o) => mesh_volume_with(volume, o)?,
        Method::ChunkedClustered => strata_mesh::tetra::tetra_volume_per_chunk(volume)
            .ok_or_else(|| anyhow::anyhow!("tetrahedra need one level"))?,
        Method::McSimplifiedPureRust(e) => simplify_pure_rust(
            &strata_mesh::mesh_volume_with(volume, strata_mesh::MeshOptions::default())
                .expect("marching cubes meshes every volume"),
            e,
        ),
    })
}

fn simplify_pure_rust(mesh: &Mesh, max_error: f32) -> Mesh {
    // meshopt-rs takes the error relative to the mesh's extent (its longest side).
    let lo = mesh.positions.iter().fold([f32::MAX; 3], |a, p| [a[0].min(p[0]), a[1].min(p[1]), a[2].min(p[2])]);
    let hi = mesh.positions.iter().fold([f32::MIN; 3], |a, p| [a[0].max(p[0]), a[1].max(p[1]), a[2].max(p[2])]);
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max).max(1e-6);
    let mut indices = vec![0u32; mesh.indices.len()];
    let count = meshopt_rs::simplify::simplify(&mut indices, &mesh.indices, &mesh.positions, 0, max_error / extent);
    let mut out = Mesh::default();
    let mut map = vec![u32::MAX; mesh.positions.len()];
    for &i in &indices[..count] {
        if map[i as usize] == u32::MAX {
            map[i as usize] = out.push_vertex_from(mesh, i as usize, [0.0; 3]);
        }
        out.indices.push(map[i as usize]);
    }
    out
}

/// Measures `method` on `shape`: the best time of `runs` on one thread.
pub fn measure(shape: &Shape, method: Method, runs: usize) -> anyhow::Result<QualityRow> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut best = f64::MAX;
    let mut mesh = Mesh::default();
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        mesh = pool.install(|| mesh_with(&shape.volume, method))?;
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    let stats = aspect_stats(&mesh);
    let report = manifold_report(&mesh);
    let lists = shape.volume.measured_volume(Axis::X);
    Ok(QualityRow {
        shape: shape.name.clone(),
        mesher: method.name(),
        triangles: mesh.triangle_count(),
        vertices: mesh.vertex_count(),
        ms: best,
        aspect_mean: stats.mean,
        aspect_sd: stats.sd,
        min_angle: stats.min_angle_deg,
        error: shape.reference.error(&mesh),
        volume_ratio: signed_volume(&mesh) / lists,
        open_edges: report.boundary,
        non_manifold_edges: report.non_manifold,
    })
}

/// Table 10's sizes.
#[derive(Clone, Debug, Serialize)]
pub struct QualityConfig {
    /// Sphere diameter, bunny and asteroid size (cells).
    pub res: u32,
    /// Instructions of the canvas.
    pub canvas: usize,
    /// Timed runs per row (best kept).
    pub runs: usize,
}

impl QualityConfig {
    /// The full sizes.
    pub fn full() -> Self {
        QualityConfig { res: 128, canvas: 300, runs: 5 }
    }

    /// CI sizes.
    pub fn quick() -> Self {
        QualityConfig { res: 32, canvas: 20, runs: 1 }
    }
}

/// Every row of Table 10.
pub fn run(
    config: &QualityConfig,
    bunny_mesh: (&[DVec3], &[[u32; 3]]),
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<Vec<QualityRow>> {
    run_some(config, bunny_mesh, "", "", progress)
}

/// The rows of Table 10 whose shape's name contains `shape` and whose mesher's name contains
/// `mesher` (empty: all), building only the shapes asked for.
pub fn run_some(
    config: &QualityConfig,
    bunny_mesh: (&[DVec3], &[[u32; 3]]),
    shape: &str,
    mesher: &str,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<Vec<QualityRow>> {
    type Build<'a> = Box<dyn Fn() -> anyhow::Result<Shape> + 'a>;
    let shapes: [(&str, Build); 4] = [
        ("sphere", Box::new(|| Ok(sphere(config.res)))),
        ("bunny", Box::new(|| bunny(bunny_mesh.0, bunny_mesh.1, config.res))),
        ("asteroid", Box::new(|| Ok(asteroid(config.res)))),
        ("canvas", Box::new(|| Ok(canvas(config.canvas, 2021)))),
    ];
    let mut rows = Vec::new();
    for (name, build) in &shapes {
        if !name.contains(shape) {
            continue;
        }
        let shape = build()?;
        for method in methods().into_iter().filter(|m| m.name().contains(mesher)) {
            progress(&format!("table 10: {} by {}", shape.name, method.name()));
            rows.push(measure(&shape, method, config.runs)?);
        }
    }
    Ok(rows)
}

/// Table 10 as markdown.
pub fn markdown(rows: &[QualityRow], s: &mut String) {
    use std::fmt::Write;
    let _ = writeln!(
        s,
        "\n### Table 10 — mesh quality\n\nAfter the tetrahedra study's Fig. 24. Each mesher meshes the whole volume on one thread (best of the runs) and its chunks are welded; \"per chunk\" is the viewport's incremental form, whose chunk faces are clustered by both chunks alike, away from the faces' edges. Aspect ratio: longest edge over shortest altitude times √3/2 (1 is equilateral). Error: Hausdorff distance from the mesh's vertices, edge midpoints and centroids to the reference surface (the sphere itself; the bunny's input mesh; for the asteroid and the canvas, marching cubes on a twice finer grid), in cells. Volume: enclosed over the lists' volume. Targets: MT + clustering ≥ 79.5 % fewer triangles than MT, mean aspect ≤ 2.2, no open or non-manifold edge, at ≤ 1.5× marching cubes' time.\n"
    );
    let _ = writeln!(
        s,
        "| shape | mesher | triangles | vs MT | vertices | ms (1 thread) | vs MC time | aspect mean | aspect sd | min angle (°) | error (cells) | volume | open / non-manifold edges |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let same = |name: &str| rows.iter().find(|o| o.shape == r.shape && o.mesher == name);
        let vs_mt = same("MT")
            .map_or("".into(), |m| format!("{:+.1} %", 100.0 * (r.triangles as f64 / m.triangles as f64 - 1.0)));
        let vs_mc = same("MC").map_or("".into(), |m| format!("{:.2}×", r.ms / m.ms));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.2} | {} | {:.2} | {:.2} | {:.2} | {:.3} | {:.4} | {} / {} |",
            r.shape,
            r.mesher,
            r.triangles,
            vs_mt,
            r.vertices,
            r.ms,
            vs_mc,
            r.aspect_mean,
            r.aspect_sd,
            r.min_angle,
            r.error,
            r.volume_ratio,
            r.open_edges,
            r.non_manifold_edges
        );
    }
}
