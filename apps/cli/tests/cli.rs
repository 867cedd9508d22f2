//! The real `strata` binary, run as a user runs it: round trips convert → info → export on the
//! bunny and on a mesh with holes, and every bad input refused with one line and a non-zero exit,
//! leaving no output file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn strata(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strata")).args(args).output().expect("the binary runs")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-cli-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn bunny() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply")
}

/// Asserts success and returns standard output.
fn ok(out: Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the command failed: {stderr}");
    String::from_utf8(out.stdout).unwrap()
}

/// Asserts a refusal: a non-zero exit and exactly one line on standard error, naming `what`.
fn refused(out: Output, what: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected a refusal, got success: {}", String::from_utf8_lossy(&out.stdout));
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line of error: {stderr:?}");
    assert!(lines[0].contains(what), "the error names {what:?}: {stderr:?}");
}

#[test]
fn convert_info_and_export_round_trip_the_bunny() {
    let dir = temp("bunny");
    let scene = dir.join("bunny.strata");
    let report = ok(strata(&["convert", s(&bunny()), "--cells", "48", "-o", s(&scene)]));
    assert!(report.contains("crossings") && report.contains("wrote"), "{report}");
    let info = ok(strata(&["info", s(&scene)]));
    assert!(info.contains("scene file version 5"), "{info}");
    assert!(info.contains("\"bunny\""), "the layer is named after the file: {info}");
    assert!(info.contains("crossings") && info.contains("bounds") && info.contains("memory"), "{info}");
    for (ext, mesher) in [("glb", "mc"), ("stl", "dc"), ("obj", "mc"), ("ply", "dc")] {
        let out = dir.join(format!("bunny.{ext}"));
        let report = ok(strata(&["export", s(&scene), "-o", s(&out), "--mesher", mesher]));
        assert!(report.contains("triangles"), "{report}");
        assert!(std::fs::metadata(&out).unwrap().len() > 1000);
    }
    // Regularised tetrahedra and simplification: fewer triangles, reported in the summary.
    let count = |r: &str| -> usize {
        r.split(", ").find_map(|p| p.strip_suffix(" triangles")?.parse().ok()).unwrap_or_else(|| panic!("{r}"))
    };
    let mc = count(&ok(strata(&["export", s(&scene), "-o", s(&dir.join("mc.glb"))])));
    let rmt = ok(strata(&["export", s(&scene), "-o", s(&dir.join("rmt.glb")), "--mesher", "rmt"]));
    assert!(rmt.contains("regularised tetrahedra") && count(&rmt) < mc, "{rmt}");
    let simple = ok(strata(&["export", s(&scene), "-o", s(&dir.join("simple.ply")), "--simplify", "0.3"]));
    assert!(simple.contains("simplified within 0.3 cells") && count(&simple) < mc / 2, "{simple}");
    for bad in ["nan", "-1", "inf"] {
        let out = dir.join("bad.glb");
        refused(strata(&["export", s(&scene), "-o", s(&out), "--simplify", bad]), "simplification error");
        assert!(!out.exists(), "nothing written for --simplify {bad}");
    }
    // The exported mesh converts again (STL here), and the layer is in the mesh's own units:
    // the bunny's bounds survive the trip.
    let again = dir.join("again.strata");
    ok(strata(&["convert", s(&dir.join("bunny.stl")), "--cells", "40", "-o", s(&again)]));
    let original = strata_mesh::import::load_mesh(&bunny()).unwrap().bounds().unwrap();
    let exported = strata_mesh::import::load_mesh(&dir.join("bunny.stl")).unwrap().bounds().unwrap();
    let extent = (original.1 - original.0).max_element();
    assert!((exported.0 - original.0).abs().max_element() < 0.05 * extent, "{exported:?} vs {original:?}");
    assert!((exported.1 - original.1).abs().max_element() < 0.05 * extent, "{exported:?} vs {original:?}");
    // The GLB export converts too (glTF import).
    ok(strata(&["convert", s(&dir.join("bunny.glb")), "--cells", "32", "-o", s(&dir.join("from-glb.strata"))]));
    // Layers by name and by index; an unknown one is refused.
    ok(strata(&["export", s(&scene), "-o", s(&dir.join("one.glb")), "--layers", "bunny"]));
    ok(strata(&["export", s(&scene), "-o", s(&dir.join("two.glb")), "--layers", "0"]));
    let missing = dir.join("none.glb");
    refused(strata(&["export", s(&scene), "-o", s(&missing), "--layers", "3"]), "no layer 3");
    refused(strata(&["export", s(&scene), "-o", s(&missing), "--layers", "ears"]), "ears");
    assert!(!missing.exists());
}

#[test]
fn a_mesh_with_holes_converts_and_exports() {
    let dir = temp("holes");
    // A box without its top face.
    let obj = dir.join("open.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 0 0 4\nv 4 0 4\nv 4 4 4\nv 0 4 4\n\
         f 1 3 2\nf 1 4 3\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n",
    )
    .unwrap();
    let scene = dir.join("open.strata");
    let report = ok(strata(&["convert", s(&obj), "--cell-size", "0.25", "-o", s(&scene)]));
    assert!(report.contains("holes"), "the report says the mesh is open: {report}");
    ok(strata(&["info", s(&scene)]));
    ok(strata(&["export", s(&scene), "-o", s(&dir.join("open.glb"))]));
}

#[test]
fn bad_input_is_one_line_a_failure_and_no_output() {
    let dir = temp("bad");
    let out = dir.join("out.strata");
    let bad_mesh = dir.join("bad.ply");
    std::fs::write(&bad_mesh, b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1 2\n").unwrap();
    let text = dir.join("notes.xyz");
    std::fs::write(&text, b"hello").unwrap();
    let b = bunny();
    let (b, out_s, bad_s, text_s, dir_s) =
        (s(&b).to_string(), s(&out).to_string(), s(&bad_mesh).to_string(), s(&text).to_string(), s(&dir).to_string());
    let missing = dir.join("missing.strata");
    let (missing, glb_out, png_out, scene_glb) = (
        s(&missing).to_string(),
        s(&dir.join("x.glb")).to_string(),
        s(&dir.join("x.png")).to_string(),
        s(&dir.join("out.glb")).to_string(),
    );
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["convert", "/nonexistent/bunny.ply", "--cells", "32", "-o", &out_s], "no such file"),
        (vec!["convert", &text_s, "--cells", "32", "-o", &out_s], "not a mesh file"),
        (vec!["convert", &bad_s, "--cells", "32", "-o", &out_s], "bad.ply"),
        (vec!["convert", &b, "--cells", "0", "-o", &out_s], "--cells"),
        (vec!["convert", &b, "--cell-size", "NaN", "-o", &out_s], "--cell-size"),
        (vec!["convert", &b, "--cell-size", "0", "-o", &out_s], "--cell-size"),
        (vec!["convert", &b, "--cell-size", "-1", "-o", &out_s], "--cell-size"),
        (vec!["convert", &b, "--cell-size", "1e-9", "-o", &out_s], "cells along"),
        (vec!["convert", &b, "--cells", "32", "-o", "/nonexistent/dir/out.strata"], "does not exist"),
        (vec!["convert", &b, "--cells", "32", "-o", &scene_glb], "not a scene file"),
        (vec!["convert", &b, "--cells", "32", "-o", &dir_s], "not a scene file"),
        (vec!["info", &missing], "no such file"),
        (vec!["info", &text_s], "not a scene file"),
        (vec!["export", &missing, "-o", &glb_out], "no such file"),
        (vec!["render", &missing, "-o", &png_out], "no such file"),
        (vec!["demo", "--scale", "NaN"], "--scale"),
        (vec!["convert", &b, "-o", &out_s], "--cells"),
        (vec!["convert", &b, "--cells", "12", "--cell-size", "1", "-o", &out_s], "cannot be used"),
        (vec!["frobnicate"], "frobnicate"),
    ];
    for (args, what) in cases {
        refused(strata(&args), what);
        assert!(!out.exists(), "{args:?} left an output");
    }
    // A damaged scene file: refused with its name, nothing written.
    let scene = dir.join("damaged.strata");
    std::fs::write(&scene, b"STRATA\0S garbage").unwrap();
    refused(strata(&["info", s(&scene)]), "damaged.strata");
    let glb = dir.join("from-damaged.glb");
    refused(strata(&["export", s(&scene), "-o", s(&glb)]), "damaged.strata");
    assert!(!glb.exists());
    // The demo checks every output before sculpting: nothing is written when one is bad.
    let good = dir.join("good.glb");
    refused(strata(&["demo", "--out", s(&good), "--out", s(&dir.join("bad.nope"))]), "bad.nope");
    assert!(!good.exists(), "the good output was not written before the bad one was found");
    // No temporary or probe file is left in the folder.
    let left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn help_shows_examples_for_every_command() {
    let top = ok(strata(&["--help"]));
    assert!(top.contains("Examples:") && top.contains("strata convert"), "{top}");
    for cmd in ["convert", "export", "info", "render", "demo"] {
        let h = ok(strata(&[cmd, "--help"]));
        assert!(h.contains("Example"), "{cmd} --help has examples: {h}");
    }
}

#[test]
fn render_writes_a_png_where_a_gpu_or_software_driver_exists() {
    let dir = temp("render");
    let scene = dir.join("demo.strata");
    ok(strata(&["demo", "--scale", "0.3", "--scene", s(&scene)]));
    let png = dir.join("demo.png");
    let out = strata(&["render", s(&scene), "-o", s(&png), "--size", "160x100"]);
    if !out.status.success() && std::env::var("STRATA_REQUIRE_GPU").as_deref() != Ok("1") {
        eprintln!("skipped: no GPU adapter ({})", String::from_utf8_lossy(&out.stderr).trim());
        return;
    }
    // A successful render says nothing on standard error, whatever XDG_RUNTIME_DIR holds (the
    // Wayland probe complained twice when it was unset or relative).
    for runtime_dir in [None, Some("relative/dir"), Some("")] {
        let mut command = Command::new(env!("CARGO_BIN_EXE_strata"));
        command.args(["render", s(&scene), "-o", s(&png), "--size", "160x100"]);
        match runtime_dir {
            None => command.env_remove("XDG_RUNTIME_DIR"),
            Some(v) => command.env("XDG_RUNTIME_DIR", v),
        };
        let out = command.output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "XDG_RUNTIME_DIR {runtime_dir:?}: {stderr}");
        assert_eq!(stderr, "", "XDG_RUNTIME_DIR {runtime_dir:?}: nothing on standard error");
        assert!(String::from_utf8_lossy(&out.stdout).contains("rendered 160x100"));
    }
    let left: Vec<_> = std::fs::read_dir(std::env::temp_dir())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with("strata-runtime-"))
        .filter(|e| e.metadata().and_then(|m| m.modified()).is_ok_and(|t| t.elapsed().is_ok_and(|d| d.as_secs() < 60)))
        .collect();
    assert!(left.is_empty(), "the private runtime folders are removed: {left:?}");
    ok(out);
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    refused(strata(&["render", s(&scene), "-o", s(&png), "--size", "0x10"]), "--size");
}

#[test]
fn no_arguments_show_the_usage_and_every_command() {
    let out = strata(&[]);
    assert_eq!(out.status.code(), Some(2), "a usage error");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("Usage: strata <COMMAND>"), "{stderr}");
    assert!(stderr.contains("Commands:"), "{stderr}");
    for cmd in ["convert", "export", "info", "render", "terrain", "demo"] {
        assert!(stderr.lines().any(|l| l.trim_start().starts_with(cmd)), "{cmd} is listed: {stderr}");
    }
    assert!(!stderr.contains("strata: error:"), "help, not an error line: {stderr}");
}

#[test]
fn a_malformed_ply_is_refused_in_one_readable_line() {
    let dir = temp("ply");
    let out = dir.join("out.strata");
    let files = [
        ("short.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1 2\n", "line 7"),
        ("typo.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty flot x\nend_header\n1\n", "property flot x"),
        ("word.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty int x\nend_header\nabc\n", "abc"),
        ("magic.ply", "hello\nformat ascii 1.0\nend_header\n", "magic number"),
        (
            "cut.ply",
            "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nend_header\n\x01",
            "ends before",
        ),
    ];
    for (name, text, what) in files {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let result = strata(&["convert", s(&path), "--cells", "16", "-o", s(&out)]);
        let stderr = String::from_utf8_lossy(&result.stderr).into_owned();
        refused(result, what);
        assert!(stderr.contains(name), "the file is named: {stderr}");
        for dump in ["Custom {", "kind:", "ParseError", "LineCol", "ExpectedSet", "Scalar(", "\\n", "\t"] {
            assert!(!stderr.contains(dump), "{name}: no parser debug output ({dump}): {stderr}");
        }
        assert!(stderr.trim_end().len() < 200, "{name}: a short line: {stderr}");
        assert!(!out.exists());
    }
}

#[test]
fn terrain_without_a_seed_or_recipe_says_which_it_needs() {
    let dir = temp("terrain-seed");
    let glb = dir.join("t.glb");
    let out = strata(&["terrain", "--size", "16x16x16", "-o", s(&glb)]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    refused(out, "--seed");
    assert!(stderr.contains("--recipe"), "{stderr}");
    assert!(!glb.exists(), "nothing generated");
    // --print-recipe alone still prints the default recipe (seed 1).
    let printed = ok(strata(&["terrain", "--print-recipe"]));
    assert!(printed.contains("\"seed\": 1"), "{printed}");
}

/// A GLB's vertex count and its number of distinct positions.
fn vertices_and_positions(path: &Path) -> (usize, usize) {
    let m = strata_mesh::import::load_mesh(path).unwrap();
    let distinct: std::collections::HashSet<[u64; 3]> =
        m.vertices.iter().map(|v| v.to_array().map(f64::to_bits)).collect();
    (m.vertices.len(), distinct.len())
}

#[test]
fn simplified_exports_are_welded() {
    let dir = temp("weld");
    let scene = dir.join("bunny.strata");
    ok(strata(&["convert", s(&bunny()), "--cells", "48", "-o", s(&scene)]));
    for mesher in ["mc", "dc", "rmt"] {
        let glb = dir.join(format!("simple-{mesher}.glb"));
        let report = ok(strata(&["export", s(&scene), "-o", s(&glb), "--simplify", "0.3", "--mesher", mesher]));
        let (vertices, positions) = vertices_and_positions(&glb);
        assert_eq!(vertices, positions, "{mesher}: one vertex per position: {report}");
        assert!(report.contains(&format!("{vertices} vertices")), "{report}");
    }
}

/// The number in `report` just before `suffix` (`"removed 4 islands"` → 4 for `" islands"`).
fn number_before(report: &str, suffix: &str) -> f64 {
    let end = report.find(suffix).unwrap_or_else(|| panic!("{suffix:?} in {report}"));
    let start = report[..end].rfind([' ', '(']).map_or(0, |i| i + 1);
    report[start..end].parse().unwrap_or_else(|_| panic!("a number before {suffix:?} in {report}"))
}

#[test]
fn exports_remove_stray_islands_by_default_for_stl_and_count_them() {
    let dir = temp("islands");
    let scene = dir.join("demo.strata");
    ok(strata(&["demo", "--scene", s(&scene)]));
    let triangles = |r: &str| number_before(r, " triangles, ") as usize;
    // The demo sculpture leaves stray nodes; an STL drops them and says so.
    let stl = ok(strata(&["export", s(&scene), "-o", s(&dir.join("demo.stl"))]));
    let islands = number_before(&stl, " islands (") as usize;
    assert!(islands >= 1, "{stl}");
    let removed_triangles = number_before(&stl, " triangles, 0") as usize;
    assert!((8 * islands..=12 * islands).contains(&removed_triangles), "8 to 12 triangles an island: {stl}");
    let volume = number_before(&stl, " cells³)");
    assert!(volume > 0.0 && volume < 8.0 * islands as f64, "{stl}");
    assert!(stl.contains("kept 1 piece"), "{stl}");
    // --keep-islands keeps them (and says nothing of islands); other formats keep them too.
    let kept = ok(strata(&["export", s(&scene), "-o", s(&dir.join("all.stl")), "--keep-islands"]));
    assert!(!kept.contains("removed"), "{kept}");
    assert_eq!(triangles(&kept), triangles(&stl) + removed_triangles, "{kept} vs {stl}");
    let glb = ok(strata(&["export", s(&scene), "-o", s(&dir.join("all.glb"))]));
    assert_eq!(triangles(&glb), triangles(&kept), "{glb}");
    // On request for any format, with any threshold; 0 removes nothing.
    let glb = ok(strata(&["export", s(&scene), "-o", s(&dir.join("clean.glb")), "--remove-islands", "8"]));
    assert_eq!(triangles(&glb), triangles(&stl), "{glb}");
    let none = ok(strata(&["export", s(&scene), "-o", s(&dir.join("none.stl")), "--remove-islands", "0"]));
    assert!(none.contains("removed 0 islands (0 triangles, 0.00 cells³)"), "{none}");
    for bad in ["nan", "-1", "inf"] {
        let out = dir.join("bad.stl");
        refused(strata(&["export", s(&scene), "-o", s(&out), "--remove-islands", bad]), "--remove-islands");
        assert!(!out.exists());
    }
    refused(
        strata(&["export", s(&scene), "-o", s(&dir.join("x.stl")), "--remove-islands", "3", "--keep-islands"]),
        "cannot be used",
    );
}

#[test]
fn convert_removes_islands_of_the_solid_on_request() {
    let dir = temp("convert-islands");
    // A 4-unit cube and, apart from it, a speck 0.3 units wide: at 0.25 units a cell, the speck
    // holds between 1 and 8 nodes, the cube 4,096.
    let obj = dir.join("speck.obj");
    let mut text = String::new();
    for (o, e) in [([0.0, 0.0, 0.0], 4.0), ([7.0, 1.0, 1.0], 0.3)] {
        for k in 0..8 {
            let c = |bit: usize, i: usize| o[i] + if k & bit == 0 { 0.0 } else { e };
            text += &format!("v {} {} {}\n", c(1, 0), c(2, 1), c(4, 2));
        }
    }
    for base in [0, 8] {
        for f in [[1, 3, 4, 2], [5, 6, 8, 7], [1, 2, 6, 5], [3, 7, 8, 4], [1, 5, 7, 3], [2, 4, 8, 6]] {
            text += &format!("f {} {} {} {}\n", f[0] + base, f[1] + base, f[2] + base, f[3] + base);
        }
    }
    std::fs::write(&obj, text).unwrap();
    let pieces = |scene: &Path| strata_editor::file::load(scene).unwrap().scene.layers[0].volume.piece_sizes().unwrap();
    let plain = dir.join("plain.strata");
    ok(strata(&["convert", s(&obj), "--cell-size", "0.25", "-o", s(&plain)]));
    let before = pieces(&plain);
    assert_eq!(before.len(), 2, "the cube and the speck: {before:?}");
    let clean = dir.join("clean.strata");
    let report = ok(strata(&["convert", s(&obj), "--cell-size", "0.25", "--remove-islands", "10", "-o", s(&clean)]));
    let line = format!("islands         removed 1 (of 2: {} nodes, {:.2} cells³) in ", before[1], before[1] as f64);
    assert!(report.contains(&line), "{line:?} in {report}");
    assert_eq!(pieces(&clean), &before[..1]);
    let loaded = strata_editor::file::load(&clean).unwrap();
    assert!(loaded.report.is_clean());
    loaded.scene.layers[0].volume.check_invariants().unwrap();
    let out = dir.join("bad.strata");
    refused(
        strata(&["convert", s(&obj), "--cell-size", "0.25", "--remove-islands", "-2", "-o", s(&out)]),
        "--remove-islands",
    );
    assert!(!out.exists());
}

#[test]
fn terrain_writes_worlds_scenes_and_meshes_and_refuses_bad_recipes() {
    let dir = temp("terrain");
    let world = dir.join("valley.world");
    let report = ok(strata(&["terrain", "--seed", "7", "-o", s(&world)]));
    assert!(report.contains("endless world"), "{report}");
    let store = strata_terrain::WorldStore::open(&world).unwrap();
    assert_eq!(store.recipe(), &strata_terrain::Recipe::with_seed(7));
    drop(store);
    // A world is never overwritten.
    refused(strata(&["terrain", "--seed", "8", "-o", s(&world)]), "already exists");
    // A box of it as a scene, which opens and describes itself.
    let scene = dir.join("valley.strata");
    ok(strata(&["terrain", "--seed", "7", "--size", "64x96x48", "-o", s(&scene)]));
    let info = ok(strata(&["info", s(&scene)]));
    assert!(info.contains("terrain") && info.contains("Rock"), "{info}");
    let loaded = strata_editor::file::load(&scene).unwrap();
    assert!(loaded.report.is_clean());
    loaded.scene.layers[0].volume.check_invariants().unwrap();
    // And as a coloured mesh.
    let glb = dir.join("valley.glb");
    let report = ok(strata(&["terrain", "--seed", "7", "--size", "64x96x48", "-o", s(&glb)]));
    assert!(report.contains("triangles"), "{report}");
    assert!(gltf::Gltf::open(&glb).is_ok());
    // A recipe file, printed and read back.
    let printed = ok(strata(&["terrain", "--seed", "5", "--print-recipe"]));
    let recipe = dir.join("r.json");
    std::fs::write(&recipe, printed.replace("\"amplitude\": 48.0", "\"amplitude\": 20.0")).unwrap();
    ok(strata(&["terrain", "--recipe", s(&recipe), "--size", "32x32x32", "-o", s(&dir.join("r.ply"))]));
    // Bad input: one line each, nothing written.
    std::fs::write(&recipe, r#"{"heights": {"gain": 7}}"#).unwrap();
    refused(strata(&["terrain", "--recipe", s(&recipe), "-o", s(&dir.join("x.glb"))]), "heights.gain");
    std::fs::write(&recipe, "not json").unwrap();
    refused(strata(&["terrain", "--recipe", s(&recipe), "-o", s(&dir.join("x.glb"))]), "recipe");
    refused(strata(&["terrain", "--seed", "1", "--size", "0x4x4", "-o", s(&dir.join("x.glb"))]), "size");
    refused(strata(&["terrain", "--seed", "1", "-o", s(&dir.join("x.txt"))]), "x.txt");
    assert!(!dir.join("x.glb").exists());
    let _ = std::fs::remove_dir_all(dir);
}
