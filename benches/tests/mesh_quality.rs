//! Regularised tetrahedra against plain tetrahedra on the study's shapes (a sphere, the bunny, a
//! noise asteroid): at least 70 % fewer triangles whole and 60 % per chunk (the asteroid at 64
//! cells: at least 78 % and 75 %), the lists' volume within 1 %, within half a cell of the
//! unclustered mesh, closed and edge-manifold.

use strata_bench::quality::{asteroid_volume, bunny, sphere};
use strata_mesh::checks::{aspect_stats, check_closed_manifold, hausdorff, signed_volume};
use strata_mesh::tetra::tetra_volume_per_chunk;
use strata_volume::{Axis, Volume};

/// Checks `v`'s clustered meshes, whole and per chunk; returns their reductions against plain MT.
fn check(name: &str, v: &Volume) -> [f64; 2] {
    let plain =
        strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::Tetrahedra)).ok().unwrap();
    let lists = v.measured_volume(Axis::X);
    check_closed_manifold(&plain).unwrap();
    let mut reductions = [0.0; 2];
    for (i, (how, m, least)) in [
        (
            "whole",
            strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::ClusteredTetrahedra))
                .ok()
                .unwrap(),
            0.70,
        ),
        ("per chunk", tetra_volume_per_chunk(v).unwrap(), 0.60),
    ]
    .into_iter()
    .enumerate()
    {
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
        reductions[i] = reduction;
    }
    reductions
}

#[test]
fn clustering_removes_most_triangles_and_keeps_the_shape() {
    let bunny_mesh =
        strata_mesh::import::load_mesh(&strata_bench::suite::repo_root().join("tests/data/bunny.ply")).unwrap();
    check("sphere", &sphere(48).volume);
    check("bunny", &bunny(&bunny_mesh.vertices, &bunny_mesh.triangles, 64).unwrap().volume);
}

#[test]
fn the_noise_asteroid_loses_most_triangles_despite_ridges_narrower_than_a_cell() {
    // Its ridges' tangent planes turn fast. With the pairs' residual at 0.05 cells it kept
    // 73.5 % whole and 70.8 % per chunk here; at 0.1, 78.6 % and 75.3 % (at Table 10's 128
    // cells, 80.8 % and 77.2 %: the bars of 80 % whole and 75 % per chunk).
    let [whole, per_chunk] = check("asteroid", &asteroid_volume(64));
    assert!(whole >= 0.78, "whole: {whole:.3}");
    assert!(per_chunk >= 0.75, "per chunk: {per_chunk:.3}");
}
