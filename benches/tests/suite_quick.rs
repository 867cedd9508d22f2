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
    let md = markdown(&results);
    for t in ["Table 1", "Table 2", "Table 3", "Table 4", "Table 5", "fast-surface-nets", "bunny", "gyroid coral"] {
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
