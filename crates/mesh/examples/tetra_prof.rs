//! Profiling aid: meshes a sphere of radius 60 cells with each mesher, one thread, and prints the
//! times, and regularised tetrahedra chunk by chunk as the viewport meshes them (`chunks`: only
//! those; `cargo run --release -p strata-mesh --example tetra_prof`).
use std::time::Instant;

use glam::DVec3;
use strata_mesh::{MeshOptions, Mesher, mesh_volume_with};
use strata_volume::Volume;
use strata_volume::brush::Sphere;

fn main() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::splat(64.3), 60.0).unwrap()).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let arg = std::env::args().nth(1);
    let which: Vec<Mesher> = match arg.as_deref() {
        Some("chunks") => Vec::new(),
        Some(k) => vec![k.parse().unwrap()],
        None => vec![Mesher::MarchingCubes, Mesher::Tetrahedra, Mesher::ClusteredTetrahedra],
    };
    for m in which {
        let mut best = f64::MAX;
        let mut tris = 0;
        for _ in 0..5 {
            let t = Instant::now();
            let mesh = pool.install(|| mesh_volume_with(&v, MeshOptions::new(m)).unwrap());
            best = best.min(t.elapsed().as_secs_f64() * 1e3);
            tris = mesh.triangle_count();
        }
        println!("{:<24} {:>8} triangles {:>8.2} ms", m.name(), tris, best);
    }
    if arg.is_none() || arg.as_deref() == Some("chunks") {
        // As the viewport meshes it: chunk by chunk.
        let mut best = f64::MAX;
        let mut tris = 0;
        for _ in 0..5 {
            let t = Instant::now();
            let mesh = pool.install(|| strata_mesh::tetra::tetra_volume_per_chunk(&v).unwrap());
            best = best.min(t.elapsed().as_secs_f64() * 1e3);
            tris = mesh.triangle_count();
        }
        println!("{:<24} {:>8} triangles {:>8.2} ms", "regularised, per chunk", tris, best);
    }
}
