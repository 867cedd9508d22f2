//! The suite's quick mode runs every table end to end, so the bench binary never rots.

use strata_bench::suite::{BEGIN, END, SuiteConfig, markdown, repo_root, run, splice};

#[test]
fn the_quick_suite_measures_every_table() {
    let config = SuiteConfig::quick();
    let results = run(&config, &repo_root().join("tests/data/bunny.ply"), &mut |_| {}).unwrap();
    assert_eq!(results.table1.len(), config.radii.len());
    assert_eq!(results.table2.len(), 2 * config.frame_radii.len());
    assert_eq!(results.table3.len(), config.mesh_resolutions.len() + config.coral_resolutions.len());
    assert_eq!(results.table5.len(), 5);
    for row in &results.table1 {
        let times = [row.segments_edit_ms, row.segments_extract_ms, row.dense_edit_ms, row.dense_extract_ms];
        assert!(times.iter().all(|t| t.is_finite() && *t > 0.0), "{row:?}");
        assert!(row.narrow.iter().all(|b| b.edit_ms > 0.0 && b.rle_ms > 0.0 && b.extract_ms > 0.0));
        assert!(row.max_memory.iter().all(|(_, b)| *b > 0));
    }
    for row in &results.table3 {
        assert!(row.crossings > 0 && row.segments > row.segments_no_normals && row.dense > 0);
        // A wider band stores more.
        assert!(row.narrow[0] < row.narrow[1] && row.narrow[1] < row.narrow[2], "{row:?}");
    }
    // Every mesher closes the same sphere with about the same number of triangles.
    let tris: Vec<usize> = results.table5.iter().map(|r| r.triangles).collect();
    assert!(tris.iter().all(|&t| t.abs_diff(tris[0]) * 50 < tris[0]), "{tris:?}");
    let tools = &results.tools;
    assert_eq!(tools.table6.len(), config.tool_radii.len() * strata_bench::tools::Tool::ALL.len());
    assert!(
        tools.table6.iter().all(|r| r.dab_ms > 0.0 && r.frame_1_ms >= r.dab_ms && r.frame_all_ms > 0.0),
        "{:?}",
        tools.table6
    );
    assert!(tools.table6.iter().any(|r| r.changed_chunks > 0.0), "the dabs change the canvas");
    assert_eq!(tools.blur.len(), config.tool_radii.len());
    assert!(tools.blur.iter().all(|r| r.dense_ms > 0.0 && r.segments_ms > 0.0));
    assert_eq!(tools.quality.len(), 4);
    assert!(tools.quality.iter().all(|q| q.rms_after < q.rms_before), "every method smooths: {:?}", tools.quality);
    let lod = results.lod.as_ref().expect("Table 7 ran");
    assert_eq!(lod.views.len(), 8, "two models, full and three views each");
    assert!(lod.views.iter().all(|v| v.open_edges == 0 && v.triangles > 0), "{:?}", lod.views);
    for model in lod.views.chunks(4) {
        assert!(model[3].triangles <= model[1].triangles, "far has no more triangles than near: {model:?}");
        assert!(model[3].triangles < model[0].triangles, "far has fewer than full: {model:?}");
    }
    assert_eq!(lod.changes.len(), 4);
    assert!(lod.changes.iter().all(|c| c.ms_per_chunk > 0.0 && c.chunks > 0));
    assert!(lod.memory[0].bytes < lod.memory[1].bytes && lod.memory[1].bytes < lod.memory[2].bytes, "{:?}", lod.memory);
    assert_eq!(lod.sculpt.len(), 2);
    assert!(lod.sculpt.iter().all(|s| s.1 > 0 && s.3 >= s.2 && s.2 > 0.0), "{:?}", lod.sculpt);
    let mat = results.materials.as_ref().expect("Table 8 ran");
    assert_eq!(mat.workload.len(), 2, "radius 10 without and with materials");
    assert_eq!(mat.workload[0].material_bytes, 0, "draws of material 0 store no materials");
    assert!(mat.workload[1].material_bytes > 0 && mat.workload[1].material_chunks > 0);
    assert_eq!(mat.workload[0].crossings, mat.workload[1].crossings, "materials never change the shape");
    let scan = mat.scan.as_ref().expect("the scan was painted");
    assert!(scan.material_bytes > 0 && scan.crossings > 0);
    assert!(mat.paint.len() == 1 && mat.paint[0].frame_ms >= mat.paint[0].dab_ms && mat.paint[0].dabs > 0);
    let terrain = results.terrain.as_ref().expect("Table 9 ran");
    let g = &terrain.generation;
    assert!(g.decided > 0 && g.mixed > 0 && g.decided + g.mixed <= g.chunks, "{g:?}");
    assert!(g.lists_ms > 0.0 && g.dense_ms > 0.0 && g.mesh_lists_ms > 0.0 && g.noise_ns > 0.0);
    assert!(g.triangles.0 > 0 && g.triangles.1 > 0);
    assert_eq!(terrain.streaming.len(), 2, "without and with detail");
    assert!(terrain.streaming.iter().all(|f| f.frames > 0 && f.generated_per_s > 0.0), "{:?}", terrain.streaming);
    assert!(terrain.paging.iter().all(|p| p.write_batch_per_s > 0.0 && p.read_per_s > 0.0 && p.bytes_per_chunk > 0.0));
    let q = &results.mesh_quality;
    assert_eq!(q.len(), 4 * strata_bench::quality::methods().len(), "every shape by every mesher");
    for r in q {
        assert!(r.triangles > 0 && r.ms > 0.0 && r.error.is_finite(), "{r:?}");
        // Every mesher but the first wave's dual contouring (and the simplifiers, which do not
        // promise it) is closed and edge-manifold.
        if !r.mesher.contains("one vertex") && !r.mesher.contains("simplification") {
            assert_eq!((r.open_edges, r.non_manifold_edges), (0, 0), "{r:?}");
        }
    }
    let md = markdown(&results);
    for t in [
        "Table 10 — mesh quality",
        "Table 9 — terrain",
        "Table 7 — level of detail",
        "Table 8 — materials",
        "Table 1",
        "Table 2",
        "Table 3",
        "Table 4",
        "Table 5",
        "Table 6 — sculpting tools",
        "godot_voxel",
        "fast-surface-nets",
        "bunny",
        "gyroid coral",
    ] {
        assert!(md.contains(t), "the markdown names {t}");
    }
    let json = serde_json::to_string(&results).unwrap();
    assert!(json.contains("\"table5\""));
    // The docs section is replaced in place, and appended when missing.
    let doc = format!("# B\n\nbefore\n{BEGIN}\nold\n{END}\nafter\n");
    let new = splice(&doc, "new\n");
    assert_eq!(new, format!("# B\n\nbefore\n{BEGIN}\nnew\n{END}\nafter\n"));
    assert!(splice("# B\n", "x\n").ends_with(&format!("{BEGIN}\nx\n{END}\n")));
}
