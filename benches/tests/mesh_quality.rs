//! Regularised tetrahedra against plain tetrahedra on the study's shapes (a sphere, the bunny, a
//! noise asteroid): at least 70 % fewer triangles, the lists' volume within 1 %, within half a
//! cell of the unclustered mesh, closed and edge-manifold; whole and chunk by chunk.

use strata_bench::quality::{asteroid_volume, bunny, sphere};
use strata_mesh::checks::{aspect_stats, check_closed_manifold, hausdorff, signed_volume};
use strata_mesh::tetra::tetra_volume_per_chunk;
use strata_volume::{Axis, Volume};

fn check(name: &str, v: &Volume) {
    let plain =
        strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::Tetrahedra)).ok().unwrap();
    let lists = v.measured_volume(Axis::X);
    check_closed_manifold(&plain).unwrap();
    for (how, m, least) in [
        (
            "whole",
            strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::ClusteredTetrahedra))
                .ok()
                .unwrap(),
            0.70,
        ),
        ("per chunk", tetra_volume_per_chunk(v).unwrap(), 0.60),
    ] {
        check_closed_manifold(&m).unwrap_or_else(|e| panic!("{name} {how}: {e}"));
        let reduction = 1.0 - m.triangle_count() as f64 / plain.triangle_count() as f64;
        let volume = signed_volume(&m) / lists;
        let h = hausdorff(&plain, &m, 2.0);
        let aspect = aspect_stats(&m).mean;
        eprintln!(
            "{name} {how}: {:.1} % fewer triangles, volume {volume:.4} of the lists', Hausdorff {h:.3} cells, aspect {aspect:.2}",
            100.0 * reduction
        );
        assert!(reduction >= least, "{name} {how}: reduction {reduction}");
        assert!((volume - 1.0).abs() <= 0.01, "{name} {how}: volume {volume}");
        assert!(h <= 0.5, "{name} {how}: Hausdorff {h}");
    }
}

#[test]
fn clustering_removes_most_triangles_and_keeps_the_shape() {
    let bunny_mesh =
        strata_mesh::import::load_mesh(&strata_bench::suite::repo_root().join("tests/data/bunny.ply")).unwrap();
    check("sphere", &sphere(48).volume);
    check("bunny", &bunny(&bunny_mesh.vertices, &bunny_mesh.triangles, 64).unwrap().volume);
    check("asteroid", &asteroid_volume(48));
}
