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
    assert!(info.contains("scene file version 4"), "{info}");
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
    ok(out);
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    refused(strata(&["render", s(&scene), "-o", s(&png), "--size", "0x10"]), "--size");
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
