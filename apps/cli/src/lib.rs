//! The `strata` command line. `main.rs` only parses arguments; the work lives here so it can be
//! tested.

pub mod commands;
pub mod paths;
pub mod runtime;
pub mod serve;
pub mod terrain;

use std::fmt::Write as _;
use std::time::Instant;

use std::path::PathBuf;

use anyhow::{Context, Result};
use glam::{DQuat, DVec3};
use strata_mesh::checks;
use strata_mesh::export::save_mesh;
use strata_mesh::normals::{DEFAULT_CREASE_DEGREES, crease_normals};
use strata_volume::brush::{Brush, Capsule, Cuboid, Cylinder, Sphere, Torus};
use strata_volume::{Axis, CsgOp, EditSettings, Volume};

/// One step of the demo sculpture.
struct Step {
    what: &'static str,
    op: CsgOp,
    brush: Box<dyn Brush>,
}

fn demo_steps(scale: f64) -> Result<Vec<Step>> {
    let s = scale;
    let c = DVec3::splat(40.0 * s);
    let rot = DQuat::from_euler(glam::EulerRot::XYZ, 0.4, 0.3, 0.2);
    Ok(vec![
        Step { what: "body: sphere", op: CsgOp::Add, brush: Box::new(Sphere::new(c, 24.0 * s)?) },
        Step {
            what: "ring: torus",
            op: CsgOp::Add,
            brush: Box::new(Torus::new(c, DVec3::new(0.2, 1.0, 0.1), 28.0 * s, 5.0 * s)?),
        },
        Step {
            what: "window: rotated rounded box",
            op: CsgOp::Subtract,
            brush: Box::new(Cuboid::oriented(c + DVec3::X * 20.0 * s, DVec3::splat(12.0 * s), rot, 3.0 * s)?),
        },
        Step {
            what: "tunnel: cylinder",
            op: CsgOp::Subtract,
            brush: Box::new(Cylinder::new(c, DVec3::Z, 40.0 * s, 7.0 * s)?),
        },
        Step {
            what: "handle: capsule",
            op: CsgOp::Add,
            brush: Box::new(Capsule::new(
                c - DVec3::new(30.0, 0.0, 0.0) * s,
                c + DVec3::new(-30.0, 25.0, 10.0) * s,
                4.0 * s,
            )?),
        },
        Step {
            what: "trim: intersect with a big box",
            op: CsgOp::Intersect,
            brush: Box::new(Cuboid::new(c + DVec3::Y * 6.0 * s, DVec3::new(60.0, 26.0, 60.0) * s)?),
        },
    ])
}

/// Sculpts the demo scene at `scale` (1 = a body of radius 24 cells), checks it, meshes it with
/// marching cubes, writes the mesh to each of `outputs` (format from the extension: .glb, .obj,
/// .stl, .ply) and returns a report of what each edit did and what the volume and mesh hold.
pub fn demo(scale: f64, outputs: &[PathBuf], scene: Option<&std::path::Path>) -> Result<String> {
    anyhow::ensure!(scale.is_finite() && scale > 0.0 && scale <= 40.0, "--scale must be in (0, 40], got {scale}");
    // Every output is checked before the work starts.
    for path in outputs {
        paths::check_output(path, &commands::EXPORT_EXTENSIONS, "mesh file")?;
    }
    if let Some(path) = scene {
        paths::check_output(path, &commands::SCENE_EXTENSIONS, "scene file")?;
    }
    let mut volume = Volume::new();
    let mut out = String::new();
    writeln!(out, "Sculpting the demo scene (scale {scale}):")?;
    let steps = demo_steps(scale)?;
    // A progress bar on a terminal (a large scale takes a while); nothing when piped.
    let progress = indicatif::ProgressBar::new(steps.len() as u64 + 1);
    for step in steps {
        progress.set_message(step.what);
        progress.inc(1);
        let t = Instant::now();
        let report = volume
            .apply(step.op, step.brush.as_ref(), &EditSettings::default())
            .with_context(|| format!("applying {}", step.what))?;
        writeln!(
            out,
            "  {:<32} {:>9} {:>5} chunks changed in {:.2} ms",
            step.what,
            format!("{:?}", step.op),
            report.changed.len(),
            t.elapsed().as_secs_f64() * 1e3
        )?;
    }
    progress.set_message("meshing");
    progress.inc(1);
    volume.check_invariants().context("the volume's invariants")?;
    let stats = volume.crossing_stats();
    let mem = volume.memory();
    writeln!(out, "\nVolume statistics:")?;
    writeln!(out, "  chunks stored          {} lists, {} solid", stats.list_chunks, stats.solid_chunks)?;
    writeln!(
        out,
        "  crossings              {} (x {}, y {}, z {})",
        stats.total, stats.per_axis[0], stats.per_axis[1], stats.per_axis[2]
    )?;
    writeln!(out, "  longest chunk line     {} crossings", stats.max_line)?;
    writeln!(
        out,
        "  enclosed volume        {:.0} cells³ (x {:.0}, y {:.0}, z {:.0})",
        volume.measured_volume(Axis::X),
        volume.measured_volume(Axis::X),
        volume.measured_volume(Axis::Y),
        volume.measured_volume(Axis::Z)
    )?;
    writeln!(
        out,
        "  memory                 {} bytes: positions {}, normals {}, headers {}, chunk map {}",
        mem.total(),
        mem.positions,
        mem.normals,
        mem.headers,
        mem.chunk_map
    )?;
    writeln!(
        out,
        "  bytes per crossing     {:.2} with normals, {:.2} without",
        mem.bytes_per_crossing(true),
        mem.bytes_per_crossing(false)
    )?;
    let origin = DVec3::new(-50.0, 40.0 * scale, 40.0 * scale + 0.5);
    match volume.raycast(origin, DVec3::X, 1e4) {
        Some(hit) => writeln!(out, "  ray from {origin} along +x hits at {:.3} (normal {:.2})", hit.point, hit.normal)?,
        None => writeln!(out, "  ray from {origin} along +x misses")?,
    }
    writeln!(out, "  invariants             hold")?;
    let t = Instant::now();
    let mesh = strata_mesh::mesh_volume_with(&volume, strata_mesh::MeshOptions::default()).context("meshing")?;
    let mesh_ms = t.elapsed().as_secs_f64() * 1e3;
    progress.finish_and_clear();
    checks::check_closed_manifold(&mesh).context("the marching-cubes mesh")?;
    writeln!(out, "\nMarching cubes ({mesh_ms:.1} ms):")?;
    writeln!(out, "  triangles / vertices   {} / {}", mesh.triangle_count(), mesh.vertex_count())?;
    writeln!(out, "  closed, edge-manifold  yes")?;
    writeln!(
        out,
        "  mesh volume / area     {:.0} cells³ / {:.0} cells²",
        checks::signed_volume(&mesh),
        checks::surface_area(&mesh)
    )?;
    let shaded = crease_normals(&mesh, DEFAULT_CREASE_DEGREES);
    for path in outputs {
        save_mesh(&shaded, path).with_context(|| format!("writing {}", path.display()))?;
        writeln!(out, "  wrote                  {}", path.display())?;
    }
    if let Some(path) = scene {
        // A scene for the studio: the sculpture as one layer, the camera on its chunks (finite
        // even when the sculpture is empty).
        let mut s = strata_editor::Scene::default();
        s.layers[0].name = "Demo".into();
        s.layers[0].volume = volume;
        s.view = strata_editor::View { yaw: 0.6, pitch: 0.35, ..strata_editor::View::framing(&s.layers) };
        let repairs = strata_editor::file::save(&s, path).with_context(|| format!("writing {}", path.display()))?;
        for r in &repairs.repairs {
            writeln!(out, "  repaired before saving {r}")?;
        }
        writeln!(out, "  wrote scene            {}", path.display())?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demo_sculpts_a_consistent_volume_and_reports_it() {
        let dir = std::env::temp_dir().join(format!("strata-cli-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let glb = dir.join("demo.glb");
        let scene = dir.join("demo.strata");
        let report = demo(0.5, std::slice::from_ref(&glb), Some(&scene)).unwrap();
        let loaded = strata_editor::file::load(&scene).unwrap();
        assert!(loaded.report.is_clean(), "{}", loaded.report);
        let loaded = loaded.scene;
        assert_eq!(loaded.layers.len(), 1);
        assert!(!loaded.layers[0].volume.is_empty());
        assert!(report.contains("invariants             hold"), "{report}");
        assert!(report.contains("hits at"), "{report}");
        assert!(report.contains("closed, edge-manifold  yes"), "{report}");
        assert!(std::fs::metadata(&glb).unwrap().len() > 1000);
        assert!(demo(f64::NAN, &[], None).is_err());
        assert!(demo(0.0, &[], None).is_err());
        assert!(demo(0.5, &[dir.join("demo.nope")], None).is_err());
    }

    #[test]
    fn a_demo_too_small_to_hold_a_node_still_saves_a_scene_that_reopens() {
        let dir = std::env::temp_dir().join(format!("strata-cli-tiny-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene = dir.join("tiny.strata");
        demo(0.01, &[], Some(&scene)).unwrap();
        let loaded = strata_editor::file::load(&scene).unwrap();
        assert!(loaded.report.is_clean(), "{}", loaded.report);
        assert!(loaded.scene.view.distance.is_finite());
    }
}
