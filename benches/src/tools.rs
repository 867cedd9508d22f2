//! Table 6 — the sculpting tools: per-dab and whole-frame times on the Table 1 canvas, the same
//! smoothing done godot_voxel's way (a box blur of the dense baseline's field) side by side, and
//! the smoothing methods' quality on a roughened sphere.
//!
//! Every tool runs with the studio's defaults: strength 0.5, four smoothing passes per dab, an
//! inflate of a fifth of the radius, pinch 0.5 towards a line along the stroke, clay with a fillet
//! of half the radius, a grab dragged by a quarter of the radius per frame (one dab spacing), and
//! the stamp tool's cobbles picture (its busiest) raised by a fifth of the radius, its top along the
//! stroke (issue 32).

use std::time::{Duration, Instant};

use glam::DVec3;
use serde::Serialize;
use strata_fields::DenseField;
use strata_mesh::MeshCache;
use strata_volume::brush::Sphere;
use strata_volume::tools::{
    BuiltinStamp, Dab, Smoothing, StampImage, StampPlacement, clay, flatten, grab, inflate, pinch, smooth, stamp,
};
use strata_volume::{Axis, EditReport, Volume};

use crate::baselines::replay_dense;
use crate::{CANVAS_CELLS, SplitMix64, replay, table1_instructions};

/// A tool as the table runs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tool {
    /// Volume-preserving field smoothing (the default).
    SmoothField,
    /// Laplacian field smoothing.
    SmoothLaplacian,
    /// The paper's Eq. 1 on the crossings.
    SmoothEndpoints,
    /// Inflate by a fifth of the radius at full strength.
    Inflate,
    /// Flatten.
    Flatten,
    /// Clay with a fillet of half the radius.
    Clay,
    /// Pinch towards a line.
    Pinch,
    /// Grab, dragged by a quarter of the radius.
    Grab,
    /// A stamp of the built-in cobbles, raised by a fifth of the radius, its top along the stroke.
    Stamp,
}

impl Tool {
    /// Every tool, in table order.
    pub const ALL: [Tool; 9] = [
        Tool::SmoothField,
        Tool::SmoothLaplacian,
        Tool::SmoothEndpoints,
        Tool::Inflate,
        Tool::Flatten,
        Tool::Clay,
        Tool::Pinch,
        Tool::Grab,
        Tool::Stamp,
    ];

    /// The table's name for it.
    pub fn name(self) -> &'static str {
        match self {
            Tool::SmoothField => "smooth (field, volume-preserving)",
            Tool::SmoothLaplacian => "smooth (field, Laplacian)",
            Tool::SmoothEndpoints => "smooth (paper's Eq. 1)",
            Tool::Inflate => "inflate",
            Tool::Flatten => "flatten",
            Tool::Clay => "clay",
            Tool::Pinch => "pinch",
            Tool::Grab => "grab",
            Tool::Stamp => "stamp (cells)",
        }
    }

    /// One dab at `p` of `radius` with stroke direction `dir` (a unit vector).
    pub fn dab(self, v: &mut Volume, p: DVec3, radius: f64, dir: DVec3) -> EditReport {
        let dab = Dab::new(p, radius, 0.5).expect("valid dab");
        let r = match self {
            Tool::SmoothField => smooth(v, &dab, Smoothing::VolumePreserving, 4),
            Tool::SmoothLaplacian => smooth(v, &dab, Smoothing::Laplacian, 4),
            Tool::SmoothEndpoints => smooth(v, &dab, Smoothing::Endpoints, 4),
            Tool::Inflate => inflate(v, &dab, 0.2 * radius),
            Tool::Flatten => flatten(v, &dab),
            Tool::Clay => clay(v, &dab, 0.5 * radius, false),
            Tool::Pinch => pinch(v, &dab, Some(dir), 0.5),
            Tool::Grab => grab(v, &dab, dir * 0.25 * radius),
            Tool::Stamp => {
                let placement = StampPlacement { up: dir, angle: 0.0, mirrored: false };
                stamp(v, &dab, cobbles(), &placement, 0.2 * radius)
            }
        };
        r.expect("bench dabs are valid")
    }
}

/// The built-in cobbles picture, made once.
fn cobbles() -> &'static StampImage {
    static IMAGE: std::sync::OnceLock<StampImage> = std::sync::OnceLock::new();
    IMAGE.get_or_init(|| BuiltinStamp::Cells.image())
}

/// A row of Table 6.
#[derive(Clone, Debug, Serialize)]
pub struct Table6Row {
    /// The tool.
    pub tool: String,
    /// Brush radius (cells).
    pub radius: f64,
    /// Mean dab (ms, one thread: the tools run on the calling thread).
    pub dab_ms: f64,
    /// Mean whole frame, dab + remesh of the affected chunks, one thread (ms).
    pub frame_1_ms: f64,
    /// 99th percentile of that (ms).
    pub frame_1_p99_ms: f64,
    /// Mean whole frame with the dab and the remesh on all cores (ms).
    pub frame_all_ms: f64,
    /// Chunks changed per dab, mean.
    pub changed_chunks: f64,
}

/// A row of the godot_voxel comparison.
#[derive(Clone, Debug, Serialize)]
pub struct BlurRow {
    /// Brush radius (cells).
    pub radius: f64,
    /// One box-blur smoothing dab on the dense baseline (ms).
    pub dense_ms: f64,
    /// One smoothing pass of the default (volume-preserving) method on the segments (ms).
    pub segments_ms: f64,
}

/// A row of the smoothing quality table.
#[derive(Clone, Debug, Serialize)]
pub struct QualityRow {
    /// The method.
    pub method: String,
    /// RMS radial deviation from the best-fit sphere before (cells).
    pub rms_before: f64,
    /// And after.
    pub rms_after: f64,
    /// Enclosed volume change (per cent, signed).
    pub volume_change_pct: f64,
    /// Mean time per dab (ms).
    pub dab_ms: f64,
}

/// Table 6 and its companions.
#[derive(Clone, Debug, Serialize)]
pub struct ToolsResults {
    /// Dabs per tool and radius.
    pub dabs: usize,
    /// Table 6.
    pub table6: Vec<Table6Row>,
    /// The godot_voxel-style smoothing side by side.
    pub blur: Vec<BlurRow>,
    /// The smoothing methods' quality.
    pub quality: Vec<QualityRow>,
}

/// Surface points of `v` and a tangent direction at each: rays from far outside the canvas
/// towards random points of its middle, where they first meet the solid.
pub(crate) fn surface_points(v: &Volume, count: usize, seed: u64) -> Vec<(DVec3, DVec3)> {
    let mut rng = SplitMix64::new(seed);
    let c = DVec3::splat(CANVAS_CELLS * 0.5);
    let mut out = Vec::with_capacity(count);
    for _ in 0..count * 20 {
        if out.len() == count {
            break;
        }
        let mut dir = DVec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5).normalize_or(DVec3::X);
        let target = c + DVec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5) * CANVAS_CELLS * 0.5;
        let origin = target - dir * CANVAS_CELLS * 1.5;
        if let Some(hit) = v.raycast(origin, dir, CANVAS_CELLS * 3.0) {
            // A direction across the ray: the stroke's.
            dir = dir.any_orthonormal_vector();
            out.push((hit.point, dir));
        }
    }
    out
}

pub(crate) fn mean_ms(d: &[Duration]) -> f64 {
    d.iter().map(Duration::as_secs_f64).sum::<f64>() * 1e3 / d.len().max(1) as f64
}

pub(crate) fn p99_ms(d: &[Duration]) -> f64 {
    let s: Vec<f64> = d.iter().map(|x| x.as_secs_f64() * 1e3).collect();
    crate::quantile(&s, 0.99)
}

/// Runs Table 6: `count` canvas instructions of radius 10, `dabs` dabs per tool and radius.
/// `quality_dabs` and `quality_passes` size the smoothing quality run ([`quality`]).
pub fn run(
    count: usize,
    radii: &[f64],
    dabs: usize,
    quality: (usize, u32),
    seed: u64,
    progress: &mut dyn FnMut(&str),
) -> ToolsResults {
    run_tools(&Tool::ALL, count, radii, dabs, quality, seed, progress)
}

/// [`run`] for some of the tools.
pub fn run_tools(
    tools: &[Tool],
    count: usize,
    radii: &[f64],
    dabs: usize,
    (quality_dabs, quality_passes): (usize, u32),
    seed: u64,
    progress: &mut dyn FnMut(&str),
) -> ToolsResults {
    let ins = table1_instructions(count, 10.0, seed);
    let canvas = replay(&ins, false).volume;
    let points = surface_points(&canvas, dabs, seed ^ 0x7001);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("thread pool");
    let all = rayon::ThreadPoolBuilder::new().build().expect("thread pool");
    let mut table6 = Vec::new();
    for &r in radii {
        for &tool in tools {
            progress(&format!("table 6: {}, radius {r}", tool.name()));
            let (mut dab_t, mut frame_1, mut frame_all, mut changed) = (Vec::new(), Vec::new(), Vec::new(), 0usize);
            for (pool, frames) in [(&one, &mut frame_1), (&all, &mut frame_all)] {
                let mut v = canvas.clone();
                let mut mc = pool.install(|| MeshCache::build(&v));
                let timing_dabs = std::ptr::eq(pool, &one);
                for &(p, dir) in &points {
                    let t0 = Instant::now();
                    // (The dab runs in the pool too: on one thread, or its chunks and band on
                    // all cores.)
                    let report = pool.install(|| tool.dab(&mut v, p, r, dir));
                    let t1 = Instant::now();
                    pool.install(|| mc.update(&v, &report.changed));
                    frames.push(t0.elapsed());
                    if timing_dabs {
                        dab_t.push(t1 - t0);
                        changed += report.changed.len();
                    }
                }
            }
            table6.push(Table6Row {
                tool: tool.name().into(),
                radius: r,
                dab_ms: mean_ms(&dab_t),
                frame_1_ms: mean_ms(&frame_1),
                frame_1_p99_ms: p99_ms(&frame_1),
                frame_all_ms: mean_ms(&frame_all),
                changed_chunks: changed as f64 / points.len().max(1) as f64,
            });
        }
    }
    progress("table 6: godot_voxel-style box blur on the dense field");
    let (_, dense) = replay_dense(&ins);
    let mut blur = Vec::new();
    for &r in radii {
        let mut d = dense.clone();
        let t = Instant::now();
        for &(p, _) in &points {
            std::hint::black_box(d.smooth_box_blur(p, r, 0.5).expect("valid dab"));
        }
        let dense_ms = t.elapsed().as_secs_f64() * 1e3 / points.len().max(1) as f64;
        let mut v = canvas.clone();
        let t = Instant::now();
        for &(p, _) in &points {
            let dab = Dab::new(p, r, 0.5).expect("valid dab");
            std::hint::black_box(smooth(&mut v, &dab, Smoothing::VolumePreserving, 1).expect("valid dab"));
        }
        let segments_ms = t.elapsed().as_secs_f64() * 1e3 / points.len().max(1) as f64;
        blur.push(BlurRow { radius: r, dense_ms, segments_ms });
    }
    progress("table 6: smoothing quality on the rough sphere");
    let quality = if quality_dabs > 0 { quality(quality_dabs, quality_passes) } else { Vec::new() };
    ToolsResults { dabs: points.len(), table6, blur, quality }
}

/// `count` directions spread evenly over the sphere (a Fibonacci lattice).
fn directions(count: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            DVec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

/// The RMS deviation of `radius(dir)` over `dirs` from its mean.
fn rms(dirs: &[DVec3], radius: impl Fn(DVec3) -> f64) -> f64 {
    let r: Vec<f64> = dirs.iter().map(|&d| radius(d)).collect();
    let mean = r.iter().sum::<f64>() / r.len() as f64;
    (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt()
}

/// The smoothing methods on the test: a sphere of radius 20 roughened by 200 spheres of
/// radius 1.5–3 added and subtracted on its surface, then `dabs` dabs (60 in the full suite) of
/// radius 9 at full strength and `passes` passes (12) spread over its whole surface. The dense
/// box blur runs the same dabs (`passes` blurs each).
pub fn quality(dabs: usize, passes: u32) -> Vec<QualityRow> {
    let c = DVec3::splat(32.0);
    let mut rng = SplitMix64::new(5);
    let bumps: Vec<(Sphere, bool)> = directions(200)
        .into_iter()
        .enumerate()
        .map(|(i, d)| (Sphere::new(c + d * 20.0, 1.5 + rng.unit() * 1.5).expect("valid bump"), i % 2 == 0))
        .collect();
    let mut v = Volume::new();
    let mut dense = DenseField::new();
    v.add(&Sphere::new(c, 20.0).expect("valid sphere")).expect("valid edit");
    dense.apply(strata_volume::CsgOp::Add, &Sphere::new(c, 20.0).expect("valid sphere")).expect("valid edit");
    for (b, add) in &bumps {
        let op = if *add { strata_volume::CsgOp::Add } else { strata_volume::CsgOp::Subtract };
        v.apply(op, b, &Default::default()).expect("valid edit");
        dense.apply(op, b).expect("valid edit");
    }
    let dirs = directions(400);
    let seg_radius = |v: &Volume, d: DVec3| 80.0 - v.raycast(c + d * 80.0, -d, 160.0).map_or(80.0, |h| h.t);
    let dense_radius = |f: &DenseField, d: DVec3| {
        // Marching in from outside to the first sign change, then bisection.
        let mut t = 40.0;
        while t > 0.0 && f.sample(c + d * t) > 0.0 {
            t -= 0.25;
        }
        let (mut lo, mut hi) = (t, t + 0.25);
        for _ in 0..20 {
            let mid = 0.5 * (lo + hi);
            if f.sample(c + d * mid) > 0.0 { hi = mid } else { lo = mid }
        }
        0.5 * (lo + hi)
    };
    let dense_volume = |f: &DenseField| {
        let mut n = 0usize;
        for z in 0..64 {
            for y in 0..64 {
                for x in 0..64 {
                    n += f.node_inside(glam::I64Vec3::new(x, y, z)) as usize;
                }
            }
        }
        n as f64
    };
    let rough = rms(&dirs, |d| seg_radius(&v, d));
    let rough_dense = rms(&dirs, |d| dense_radius(&dense, d));
    let mut rows = Vec::new();
    for (name, method) in [
        ("field, volume-preserving (default)", Smoothing::VolumePreserving),
        ("field, Laplacian", Smoothing::Laplacian),
        ("paper's Eq. 1", Smoothing::Endpoints),
    ] {
        let mut s = v.clone();
        let vol = s.measured_volume(Axis::X);
        let t = Instant::now();
        let dabs = directions(dabs);
        for d in &dabs {
            smooth(&mut s, &Dab::new(c + *d * 20.0, 9.0, 1.0).expect("valid dab"), method, passes).expect("valid dab");
        }
        let dab_ms = t.elapsed().as_secs_f64() * 1e3 / dabs.len() as f64;
        rows.push(QualityRow {
            method: name.into(),
            rms_before: rough,
            rms_after: rms(&dirs, |d| seg_radius(&s, d)),
            volume_change_pct: (s.measured_volume(Axis::X) / vol - 1.0) * 100.0,
            dab_ms,
        });
    }
    let mut f = dense.clone();
    let vol = dense_volume(&f);
    let t = Instant::now();
    let dabs = directions(dabs);
    for d in &dabs {
        for _ in 0..passes {
            f.smooth_box_blur(c + *d * 20.0, 9.0, 1.0).expect("valid dab");
        }
    }
    let dab_ms = t.elapsed().as_secs_f64() * 1e3 / dabs.len() as f64;
    rows.push(QualityRow {
        method: "dense box blur (godot_voxel)".into(),
        rms_before: rough_dense,
        rms_after: rms(&dirs, |d| dense_radius(&f, d)),
        volume_change_pct: (dense_volume(&f) / vol - 1.0) * 100.0,
        dab_ms,
    });
    rows
}
