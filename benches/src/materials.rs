//! Table 8 — materials: what node materials cost in memory and time.
//!
//! - The Table 1/4 workload (seeded sphere draws and erases on the 160³ canvas) replayed twice
//!   on one thread: every draw of material 0 (as Table 1 runs), then every draw of a random
//!   material 1–7. Time_d and Time_v per instruction, and the materials' bytes per crossing.
//! - The scanned mesh converted at `resolution` cells and painted in five regions (balls of a
//!   tenth of its size where rays from five directions meet it).
//! - Paint dabs at radius 10 and 20 on the Table 6 canvas (its draws in random materials):
//!   the dab alone and the whole frame (dab + remesh of the changed chunks, one thread).

use std::time::{Duration, Instant};

use glam::DVec3;
use serde::Serialize;
use strata_mesh::MeshCache;
use strata_volume::brush::{MeshBrush, MeshRule, Sphere};
use strata_volume::tools::{Dab, paint};
use strata_volume::{CsgOp, EditSettings, Volume, VoxelBlock};

use crate::tools::{mean_ms, p99_ms, surface_points};
use crate::{Instruction, SplitMix64, extract, table1_instructions};

/// One replay of the Table 1 workload.
#[derive(Clone, Debug, Serialize)]
pub struct WorkloadRow {
    /// Brush radius.
    pub radius: f64,
    /// Whether draws carried random materials.
    pub materials: bool,
    /// Time_d per instruction (ms).
    pub edit_ms: f64,
    /// Time_v per instruction (ms).
    pub extract_ms: f64,
    /// Crossings at the end.
    pub crossings: usize,
    /// Bytes of materials at the end.
    pub material_bytes: usize,
    /// All bytes at the end.
    pub total_bytes: usize,
    /// Chunks with stored materials at the end.
    pub material_chunks: usize,
}

/// The painted scan.
#[derive(Clone, Debug, Serialize)]
pub struct ScanRow {
    /// Model name.
    pub model: String,
    /// Cells along its longest side.
    pub resolution: u32,
    /// Crossings.
    pub crossings: usize,
    /// Bytes of materials after painting.
    pub material_bytes: usize,
    /// All bytes after painting.
    pub total_bytes: usize,
    /// Mean time per paint ball (ms).
    pub paint_ms: f64,
}

/// Paint dabs at one radius.
#[derive(Clone, Debug, Serialize)]
pub struct PaintRow {
    /// Dab radius (cells).
    pub radius: f64,
    /// Dabs.
    pub dabs: usize,
    /// Mean dab alone (ms).
    pub dab_ms: f64,
    /// Mean whole frame, one thread (ms).
    pub frame_ms: f64,
    /// p99 whole frame, one thread (ms).
    pub frame_p99_ms: f64,
}

/// Everything Table 8 measured.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialsResults {
    /// Workload replays, without then with materials, per radius.
    pub workload: Vec<WorkloadRow>,
    /// The painted scan.
    pub scan: Option<ScanRow>,
    /// Paint dabs.
    pub paint: Vec<PaintRow>,
}

/// A scanned mesh to paint: its name, vertices and triangles.
pub type Scan<'a> = (&'a str, &'a [DVec3], &'a [[u32; 3]]);

/// Replays `ins` on one thread, draws of material `material(i)`.
fn replay_with(ins: &[Instruction], radius: f64, materials: bool, seed: u64) -> WorkloadRow {
    let mut rng = SplitMix64::new(seed);
    let mut v = Volume::new();
    let (mut edit, mut ex) = (Duration::ZERO, Duration::ZERO);
    let mut block = VoxelBlock::default();
    let mut blocks = Vec::new();
    for i in ins {
        let material = if materials { 1 + (rng.next_u64() % 7) as u8 } else { 0 };
        let settings = EditSettings { parallel: false, material, ..Default::default() };
        let t0 = Instant::now();
        let report = v.apply(i.op, &i.brush(), &settings).expect("workload edits are valid");
        let t1 = Instant::now();
        extract(&v, &report.changed, false, &mut block, &mut blocks);
        ex += t1.elapsed();
        edit += t1 - t0;
    }
    let m = v.memory();
    let n = ins.len().max(1) as f64;
    WorkloadRow {
        radius,
        materials,
        edit_ms: edit.as_secs_f64() * 1e3 / n,
        extract_ms: ex.as_secs_f64() * 1e3 / n,
        crossings: m.crossings,
        material_bytes: m.materials,
        total_bytes: m.total(),
        material_chunks: v.material_chunks().count(),
    }
}

/// Runs Table 8: the workload of `count` instructions per radius in `radii`, the scan
/// (`vertices`, `triangles`, named `model`) at `resolution`, and `dabs` paint dabs per radius
/// of `paint_radii` on a canvas of `canvas` instructions.
#[allow(clippy::too_many_arguments)]
pub fn run(
    count: usize,
    radii: &[f64],
    scan: Option<Scan<'_>>,
    resolution: u32,
    canvas: usize,
    paint_radii: &[f64],
    dabs: usize,
    seed: u64,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<MaterialsResults> {
    let mut workload = Vec::new();
    for &r in radii {
        progress(&format!("table 8: workload, radius {r}"));
        let ins = table1_instructions(count, r, seed);
        workload.push(replay_with(&ins, r, false, seed));
        workload.push(replay_with(&ins, r, true, seed));
    }
    let scan = match scan {
        Some((model, vertices, triangles)) => {
            progress(&format!("table 8: {model} at {resolution}, painted in five regions"));
            let (lo, hi) = vertices.iter().fold((DVec3::MAX, DVec3::MIN), |(a, b), &p| (a.min(p), b.max(p)));
            let scale = resolution as f64 / (hi - lo).max_element();
            let verts: Vec<DVec3> = vertices.iter().map(|&v| (v - lo) * scale + DVec3::splat(2.0)).collect();
            let brush = MeshBrush::new(&verts, triangles, MeshRule::EvenOdd)?;
            let mut v = Volume::new();
            v.apply(CsgOp::Add, &brush, &EditSettings::default())?;
            let size = (hi - lo) * scale;
            let centre = DVec3::splat(2.0) + size * 0.5;
            let reach = size.max_element() * 2.0;
            let mut painted = Duration::ZERO;
            let dirs = [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::Z, DVec3::NEG_Z];
            for (k, d) in dirs.iter().enumerate() {
                let Some(hit) = v.raycast(centre + *d * reach, -*d, reach * 2.0) else { continue };
                let ball = Sphere::new(hit.point, size.max_element() / 10.0)?;
                let t = Instant::now();
                v.paint(&ball, 1 + k as u8)?;
                painted += t.elapsed();
            }
            let m = v.memory();
            Some(ScanRow {
                model: model.into(),
                resolution,
                crossings: m.crossings,
                material_bytes: m.materials,
                total_bytes: m.total(),
                paint_ms: painted.as_secs_f64() * 1e3 / dirs.len() as f64,
            })
        }
        None => None,
    };
    progress("table 8: paint dabs");
    let ins = table1_instructions(canvas, 10.0, seed);
    let mut canvas_volume = Volume::new();
    let mut rng = SplitMix64::new(seed ^ 0x8a1);
    for i in &ins {
        let settings = EditSettings { parallel: false, material: 1 + (rng.next_u64() % 7) as u8, ..Default::default() };
        canvas_volume.apply(i.op, &i.brush(), &settings)?;
    }
    let points = surface_points(&canvas_volume, dabs, seed ^ 0x7001);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut paint_rows = Vec::new();
    for &r in paint_radii {
        let mut v = canvas_volume.clone();
        let mut mc = one.install(|| MeshCache::build(&v));
        let (mut dab_t, mut frames) = (Vec::new(), Vec::new());
        for (k, &(p, _)) in points.iter().enumerate() {
            let dab = Dab { material: 8 + (k % 4) as u8, ..Dab::new(p, r, 0.5)? };
            let t0 = Instant::now();
            let report = paint(&mut v, &dab)?;
            let t1 = Instant::now();
            one.install(|| mc.update(&v, &report.changed));
            frames.push(t0.elapsed());
            dab_t.push(t1 - t0);
        }
        paint_rows.push(PaintRow {
            radius: r,
            dabs: points.len(),
            dab_ms: mean_ms(&dab_t),
            frame_ms: mean_ms(&frames),
            frame_p99_ms: p99_ms(&frames),
        });
    }
    Ok(MaterialsResults { workload, scan, paint: paint_rows })
}

/// Table 8's markdown, appended to `s`.
pub fn markdown(s: &mut String, m: &MaterialsResults) {
    use std::fmt::Write;
    let _ = writeln!(
        s,
        "\n### Table 8 — materials\n\nThe Table 1/4 workload on one thread, every draw of material 0 and then every draw of a random material 1–7 (erases keep what survives). Targets: materials ≤ 0.25 bytes per crossing on top of the rest; Time_d and Time_v with materials ≤ 15 % slower.\n"
    );
    let _ = writeln!(
        s,
        "| radius | materials | Time_d (ms) | Time_v (ms) | crossings | chunks with materials | materials (KiB) | materials per crossing (bytes) | all (MiB) |"
    );
    let _ = writeln!(s, "|---:|---|---:|---:|---:|---:|---:|---:|---:|");
    for pair in m.workload.chunks(2) {
        for row in pair {
            let (d, v) = if row.materials && pair.len() == 2 {
                (
                    format!(" ({:+.0} %)", (row.edit_ms / pair[0].edit_ms.max(1e-9) - 1.0) * 100.0),
                    format!(" ({:+.0} %)", (row.extract_ms / pair[0].extract_ms.max(1e-9) - 1.0) * 100.0),
                )
            } else {
                (String::new(), String::new())
            };
            let _ = writeln!(
                s,
                "| {} | {} | {:.3}{d} | {:.3}{v} | {} | {} | {:.1} | {:.3} | {:.2} |",
                row.radius,
                if row.materials { "random 1–7" } else { "none (0)" },
                row.edit_ms,
                row.extract_ms,
                row.crossings,
                row.material_chunks,
                row.material_bytes as f64 / 1024.0,
                row.material_bytes as f64 / row.crossings.max(1) as f64,
                row.total_bytes as f64 / (1024.0 * 1024.0)
            );
        }
    }
    if let Some(scan) = &m.scan {
        let _ = writeln!(
            s,
            "\nThe {} converted at {} cells and painted in five regions (balls of a tenth of its size): {} crossings, {:.1} KiB of materials ({:.3} bytes per crossing) in {:.2} MiB, {:.1} ms per ball.",
            scan.model,
            scan.resolution,
            scan.crossings,
            scan.material_bytes as f64 / 1024.0,
            scan.material_bytes as f64 / scan.crossings.max(1) as f64,
            scan.total_bytes as f64 / (1024.0 * 1024.0),
            scan.paint_ms
        );
    }
    let _ = writeln!(
        s,
        "\nPaint dabs (strength 0.5, dithered) on the Table 6 canvas drawn in random materials, one thread; the whole frame adds the remesh of the changed chunks. Targets: whole frame ≤ 4 ms at radius 10 and ≤ 11.1 ms at radius 20.\n"
    );
    let _ = writeln!(s, "| radius | dabs | dab (ms) | frame mean (ms) | frame p99 (ms) |");
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|");
    for row in &m.paint {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {:.2} | {:.2} |",
            row.radius, row.dabs, row.dab_ms, row.frame_ms, row.frame_p99_ms
        );
    }
}
