//! The README's controls table and the studio's one binding table agree: every key the studio
//! binds is in the table, and every key the table names is bound.

use strata_studio::keymap::{BINDINGS, chord_text};

/// The first cells of the README's scene controls table (`| control | does |`).
fn readme_controls() -> Vec<String> {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../README.md")).unwrap();
    let mut lines = readme.lines().skip_while(|l| !l.starts_with("| control | does |")).skip(2);
    let mut cells = Vec::new();
    for line in lines.by_ref() {
        let Some(row) = line.strip_prefix('|') else { break };
        cells.push(row.split('|').next().unwrap().trim().to_string());
    }
    assert!(cells.len() > 10, "the README's controls table was not found");
    cells
}

/// The `quoted` keys of a cell.
fn quoted(cell: &str) -> Vec<String> {
    cell.split('`').skip(1).step_by(2).map(str::to_string).collect()
}

#[test]
fn every_binding_is_in_the_readme_and_every_key_in_the_readme_is_bound() {
    let cells = readme_controls();
    let named: Vec<String> = cells.iter().flat_map(|c| quoted(c)).collect();
    let bound: Vec<String> = BINDINGS.iter().flat_map(|b| b.keys.iter().map(|&c| chord_text(c))).collect();
    for chord in &bound {
        assert!(named.contains(chord), "the README's controls table does not name `{chord}`");
    }
    for key in &named {
        assert!(bound.contains(key), "the README names `{key}`, which the studio does not bind");
    }
}
