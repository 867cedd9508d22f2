//! Masked strokes against unmasked ones (issue 32: masked strokes cost at most 10 % more in
//! Table 6): the Table 6 canvas with half of it masked (the chunks left of its middle held,
//! the column of chunks at the middle half held), every Table 6 tool and the CSG add and erase
//! dabbed at the same surface points with and without the mask, alternately, on one thread.

use std::fmt::Write;
use std::time::{Duration, Instant};

use glam::DVec3;
use strata_volume::brush::Sphere;
use strata_volume::{ChunkMask, CsgOp, EditSettings, Mask, Volume};

use crate::tools::{Tool, mean_ms, surface_points};
use crate::{CANVAS_CELLS, replay, table1_instructions};

/// One dab of a row at a surface point, with the stroke's direction there.
type DabFn = Box<dyn Fn(&mut Volume, DVec3, DVec3) + Send + Sync>;

/// Half of `v` masked: chunks whose x is left of the canvas's middle held, the middle column
/// half held.
fn half_masked(v: &Volume) -> Volume {
    let mid = (CANVAS_CELLS / 2.0 / strata_volume::coords::CHUNK_CELLS as f64).floor() as i32;
    let chunks = v.chunks().filter_map(|(k, _)| match k.0.x {
        x if x < mid => Some((k, ChunkMask::Uniform(strata_volume::PROTECTED))),
        x if x == mid => Some((k, ChunkMask::Uniform(128))),
        _ => None,
    });
    let mut masked = v.clone();
    masked.set_mask(Mask::from_parts(0, chunks.collect::<Vec<_>>()));
    masked
}

/// Runs the comparison and returns it as a markdown table.
pub fn run(count: usize, radii: &[f64], dabs: usize, seed: u64, progress: &mut dyn FnMut(&str)) -> String {
    let ins = table1_instructions(count, 10.0, seed);
    let canvas = replay(&ins, false).volume;
    let points = surface_points(&canvas, dabs, seed ^ 0x7001);
    let masked = half_masked(&canvas);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("thread pool");
    let mut out = String::new();
    // What a painted mask takes: mask dabs of radius 10 and strength 0.6 at the surface points
    // (soft edges, every weight in between), against the lists it protects.
    let mut painted = canvas.clone();
    for &(p, _) in &points {
        let dab = strata_volume::tools::Dab::new(p, 10.0, 0.6).expect("a valid dab");
        strata_volume::tools::mask(&mut painted, &dab, strata_volume::tools::MaskStroke::Add).expect("a mask dab");
    }
    let m = painted.mask();
    let runs = m.chunks().filter(|(_, c)| matches!(c, ChunkMask::Runs(_))).count();
    let _ = writeln!(
        out,
        "Memory: {} mask dabs (radius 10, strength 0.6) on the canvas store {} chunks of mask ({} of runs) in {} bytes of runs, {} bytes with the table: {:.1} % of the canvas's {} bytes of lists; the half-masked canvas stores {} uniform chunks in {} bytes.\n",
        points.len(),
        m.chunks().count(),
        runs,
        m.chunks().map(|(_, c)| c.heap_bytes()).sum::<usize>(),
        m.heap_bytes(),
        100.0 * m.heap_bytes() as f64 / canvas.memory().total() as f64,
        canvas.memory().total(),
        masked.mask().chunks().count(),
        masked.mask().heap_bytes(),
    );
    let _ = writeln!(
        out,
        "{} dabs per row at the Table 6 surface points, one thread, the unmasked and the masked dab alternately; the masked canvas holds its left half (the middle column of chunks at half weight).\n\n| tool | radius | unmasked dab (ms) | masked dab (ms) | masked / unmasked |\n|---|---|---|---|---|",
        points.len()
    );
    let settings = EditSettings { parallel: false, ..EditSettings::default() };
    for &r in radii {
        let mut rows: Vec<(String, DabFn)> = Tool::ALL
            .iter()
            .map(|&t| {
                let f: DabFn = Box::new(move |v, p, dir| {
                    std::hint::black_box(t.dab(v, p, r, dir));
                });
                (t.name().to_string(), f)
            })
            .collect();
        for (name, op) in [("add (CSG sphere)", CsgOp::Add), ("erase (CSG sphere)", CsgOp::Subtract)] {
            let settings = settings.clone();
            let f: DabFn = Box::new(move |v, p, _| {
                let b = Sphere::new(p, r).expect("a sphere");
                std::hint::black_box(v.apply(op, &b, &settings).expect("a valid edit"));
            });
            rows.push((name.to_string(), f));
        }
        for (name, dab) in rows {
            progress(&format!("masks: {name}, radius {r}"));
            let (mut plain, mut held) = (canvas.clone(), masked.clone());
            let (mut tp, mut tm): (Vec<Duration>, Vec<Duration>) = (Vec::new(), Vec::new());
            one.install(|| {
                for &(p, dir) in &points {
                    let t = Instant::now();
                    dab(&mut plain, p, dir);
                    tp.push(t.elapsed());
                    let t = Instant::now();
                    dab(&mut held, p, dir);
                    tm.push(t.elapsed());
                }
            });
            let (a, b) = (mean_ms(&tp), mean_ms(&tm));
            let _ = writeln!(out, "| {name} | {r} | {a:.3} | {b:.3} | {:.2} |", b / a);
        }
    }
    out
}
