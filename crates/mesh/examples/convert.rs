//! Converts a mesh (the shipped bunny by default) into a volume at a resolution and prints the
//! time: `cargo run --release -p strata-mesh --example convert -- 1024 [MESH]`.

use std::time::Instant;

use glam::DVec3;
use strata_volume::brush::{MeshBrush, MeshRule};
use strata_volume::{CsgOp, EditSettings, Volume};

fn main() {
    let mut args = std::env::args().skip(1);
    let res: f64 = args.next().and_then(|a| a.parse().ok()).unwrap_or(1024.0);
    let path = args
        .next()
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply"));
    let m = strata_mesh::import::load_mesh(&path).expect("a mesh");
    let (lo, hi) = m.bounds().expect("vertices");
    let scale = res / (hi - lo).max_element();
    let verts: Vec<DVec3> = m.vertices.iter().map(|&v| (v - lo) * scale + DVec3::splat(2.0)).collect();
    let brush = MeshBrush::new(&verts, &m.triangles, MeshRule::EvenOdd).expect("a brush");
    let mut volume = Volume::new();
    let t = Instant::now();
    let settings = EditSettings { parallel: false, ..Default::default() };
    let report = volume.apply(CsgOp::Add, &brush, &settings).expect("the edit");
    println!(
        "{} at {res}: {:.0} ms one thread, {} chunks, {} nodes repaired",
        path.display(),
        t.elapsed().as_secs_f64() * 1e3,
        volume.chunk_count(),
        report.repaired_nodes
    );
    volume.check_invariants().expect("consistent");
}
