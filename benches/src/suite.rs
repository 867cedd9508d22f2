//! The side-by-side suite: the paper's Tables 1–4 plus a meshing comparison against a peer
//! crate, every row measured in one run, printed as markdown and kept as JSON.
//!
//! `cargo run --release -p strata-bench -- suite` runs it in full and rewrites the suite's
//! section of `docs/BENCHMARKS.md`; `-- suite --quick` runs every table at reduced size (under
//! a minute) and is what the CI smoke test runs.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;
use serde::Serialize;
use strata_fields::{DenseField, NarrowBandField};
use strata_mesh::import::load_mesh;
use strata_volume::brush::{Aabb, Brush, MeshBrush, MeshRule, SdfBrush, Sphere};
use strata_volume::{CsgOp, EditSettings, Volume};

use crate::baselines::{replay_dense, replay_narrow};
use crate::{Mesher, replay, replay_frames, table1_instructions};

/// Narrow-band half-widths compared (cells).
pub const BANDS: [f32; 3] = [1.0, 2.0, 3.0];

/// Sizes of every table.
#[derive(Clone, Debug, Serialize)]
pub struct SuiteConfig {
    /// Reduced sizes (the CI smoke run).
    pub quick: bool,
    /// Instructions per radius in Tables 1 and 4.
    pub count: usize,
    /// Radii of Tables 1 and 4.
    pub radii: Vec<f64>,
    /// Instructions per radius in Table 2.
    pub frame_count: usize,
    /// Radii of Table 2.
    pub frame_radii: Vec<f64>,
    /// Resolutions (cells along the longest side) of the scanned mesh in Table 3.
    pub mesh_resolutions: Vec<u32>,
    /// Resolutions of the procedural coral in Table 3.
    pub coral_resolutions: Vec<u32>,
    /// Cells per side of the Table 5 sphere's grid.
    pub sphere_cells: u32,
    /// Instructions (radius 10) building the Table 6 canvas.
    pub tool_canvas: usize,
    /// Brush radii of Table 6.
    pub tool_radii: Vec<f64>,
    /// Dabs per tool and radius in Table 6.
    pub tool_dabs: usize,
    /// Dabs and passes of the smoothing quality run.
    pub quality: (usize, u32),
    /// Finest cells along the longest side of the Table 7 models.
    pub lod_resolution: u32,
    /// Frames of the Table 7 sculpting run.
    pub lod_frames: usize,
    /// Table 9's sizes.
    pub terrain: crate::terrain::TerrainConfig,
    /// Table 10's sizes.
    pub mesh_quality: crate::quality::QualityConfig,
    /// Workload seed.
    pub seed: u64,
}

impl SuiteConfig {
    /// The sizes of the paper (and the issue).
    pub fn full() -> Self {
        SuiteConfig {
            quick: false,
            count: 1000,
            radii: vec![5.0, 10.0, 15.0, 20.0, 40.0],
            frame_count: 1000,
            frame_radii: vec![5.0, 10.0, 15.0, 20.0],
            mesh_resolutions: vec![256, 512, 1024],
            coral_resolutions: vec![256, 512],
            sphere_cells: 256,
            tool_canvas: 1000,
            tool_radii: vec![5.0, 10.0, 20.0],
            tool_dabs: 100,
            quality: (60, 12),
            lod_resolution: 1024,
            lod_frames: 300,
            terrain: crate::terrain::TerrainConfig::full(),
            mesh_quality: crate::quality::QualityConfig::full(),
            seed: 2021,
        }
    }

    /// Every table at reduced size.
    pub fn quick() -> Self {
        SuiteConfig {
            quick: true,
            count: 60,
            radii: vec![5.0, 10.0],
            frame_count: 30,
            frame_radii: vec![5.0],
            mesh_resolutions: vec![32, 64],
            coral_resolutions: vec![32],
            sphere_cells: 64,
            tool_canvas: 60,
            tool_radii: vec![5.0, 10.0],
            tool_dabs: 3,
            quality: (4, 2),
            lod_resolution: 256,
            lod_frames: 10,
            terrain: crate::terrain::TerrainConfig::quick(),
            mesh_quality: crate::quality::QualityConfig::quick(),
            seed: 2021,
        }
    }
}

/// One narrow-band column group of Table 1.
#[derive(Clone, Debug, Serialize)]
pub struct BandTimes {
    /// Half-width in cells.
    pub band: f32,
    /// Decode + edit per instruction (ms).
    pub edit_ms: f64,
    /// Re-encode per instruction (ms).
    pub rle_ms: f64,
    /// Voxel blocks per instruction (ms).
    pub extract_ms: f64,
}

/// A row of Table 1 (and, with its memory maxima, Table 4).
#[derive(Clone, Debug, Serialize)]
pub struct Table1Row {
    /// Brush radius (cells).
    pub radius: f64,
    /// Segments: Time_d (ms).
    pub segments_edit_ms: f64,
    /// Segments: Time_v (ms).
    pub segments_extract_ms: f64,
    /// Dense: Time_d (ms).
    pub dense_edit_ms: f64,
    /// Dense: Time_v (ms).
    pub dense_extract_ms: f64,
    /// Narrow band, per half-width.
    pub narrow: Vec<BandTimes>,
    /// Maximum memory during the drawing (bytes): segments, dense, then each band.
    pub max_memory: Vec<(String, usize)>,
}

/// A row of Table 2.
#[derive(Clone, Debug, Serialize)]
pub struct Table2Row {
    /// Marching cubes or dual contouring.
    pub mesher: String,
    /// Brush radius.
    pub radius: f64,
    /// Mean frame on one thread (ms).
    pub mean_1: f64,
    /// 99th percentile on one thread (ms).
    pub p99_1: f64,
    /// Mean frame with all cores (ms).
    pub mean_all: f64,
    /// 99th percentile with all cores (ms).
    pub p99_all: f64,
}

/// A row of Table 3.
#[derive(Clone, Debug, Serialize)]
pub struct Table3Row {
    /// Which shape.
    pub shape: String,
    /// Cells along the longest side.
    pub resolution: u32,
    /// Crossings stored by the segment volume.
    pub crossings: usize,
    /// Segment volume, all allocations (bytes).
    pub segments: usize,
    /// Segment volume without normals (bytes).
    pub segments_no_normals: usize,
    /// Dense field (bytes, computed from its chunk count).
    pub dense: usize,
    /// Narrow band per half-width (bytes).
    pub narrow: Vec<usize>,
    /// Conversion into segments on one thread (ms).
    pub convert_ms: f64,
}

/// A row of Table 5.
#[derive(Clone, Debug, Serialize)]
pub struct Table5Row {
    /// What ran.
    pub method: String,
    /// Threads.
    pub threads: usize,
    /// Building the input (the dense field, or the segment volume), ms; not in `ms`.
    pub input_ms: f64,
    /// Meshing (ms).
    pub ms: f64,
    /// Million cells per second.
    pub mcells_per_s: f64,
    /// Triangles produced.
    pub triangles: usize,
}

/// Everything one run measured.
#[derive(Clone, Debug, Serialize)]
pub struct SuiteResults {
    /// The sizes.
    pub config: SuiteConfig,
    /// CPU, cores and memory of the machine.
    pub machine: String,
    /// `git` revision (with `-dirty` for uncommitted changes).
    pub revision: String,
    /// The command that reproduces the run.
    pub command: String,
    /// Table 1 (and Table 4's maxima).
    pub table1: Vec<Table1Row>,
    /// Table 2.
    pub table2: Vec<Table2Row>,
    /// Table 3.
    pub table3: Vec<Table3Row>,
    /// Table 5, and the grid's side in cells.
    pub table5: Vec<Table5Row>,
    /// Table 6 (sculpting tools), the godot_voxel-style smoothing and the smoothing quality.
    pub tools: crate::tools::ToolsResults,
    /// Table 7 (level of detail).
    pub lod: Option<crate::lod::LodResults>,
    /// Table 8 (materials).
    pub materials: Option<crate::materials::MaterialsResults>,
    /// Table 9 (terrain).
    pub terrain: Option<crate::terrain::TerrainResults>,
    /// Table 10 (mesh quality).
    pub mesh_quality: Vec<crate::quality::QualityRow>,
}

/// Runs every table. `mesh` is the scanned mesh of Table 3 (PLY, OBJ or STL).
pub fn run(config: &SuiteConfig, mesh: &Path, progress: &mut dyn FnMut(&str)) -> anyhow::Result<SuiteResults> {
    let mut out = SuiteResults {
        config: config.clone(),
        machine: machine(),
        revision: revision(),
        command: if config.quick {
            "cargo run --release -p strata-bench -- suite --quick"
        } else {
            "cargo run --release -p strata-bench -- suite"
        }
        .into(),
        table1: Vec::new(),
        table2: Vec::new(),
        table3: Vec::new(),
        table5: Vec::new(),
        tools: crate::tools::ToolsResults { dabs: 0, table6: Vec::new(), blur: Vec::new(), quality: Vec::new() },
        lod: None,
        materials: None,
        terrain: None,
        mesh_quality: Vec::new(),
    };
    for &r in &config.radii {
        progress(&format!("table 1: radius {r}"));
        out.table1.push(table1_row(config, r));
    }
    for (name, mesher) in [("marching cubes", Mesher::MarchingCubes), ("dual contouring", Mesher::DualContouring)] {
        for &r in &config.frame_radii {
            progress(&format!("table 2: {name}, radius {r}"));
            let ins = table1_instructions(config.frame_count, r, config.seed);
            let one = replay_frames(&ins, false, mesher);
            let all = replay_frames(&ins, true, mesher);
            out.table2.push(Table2Row {
                mesher: name.into(),
                radius: r,
                mean_1: one.mean_ms(),
                p99_1: one.quantile_ms(0.99),
                mean_all: all.mean_ms(),
                p99_all: all.quantile_ms(0.99),
            });
        }
    }
    let scanned = load_mesh(mesh)?;
    let name = mesh.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh").to_string();
    for &res in &config.mesh_resolutions {
        progress(&format!("table 3: {name} at {res}"));
        let (lo, hi) = scanned.bounds().expect("a loaded mesh has vertices");
        let scale = res as f64 / (hi - lo).max_element();
        // Two cells of margin, so the solid never touches the grid's lowest nodes.
        let verts: Vec<DVec3> = scanned.vertices.iter().map(|&v| (v - lo) * scale + DVec3::splat(2.0)).collect();
        let t = Instant::now();
        let brush = MeshBrush::new(&verts, &scanned.triangles, MeshRule::EvenOdd)?;
        let volume = convert(&brush)?;
        out.table3.push(table3_row(&name, res, volume, t.elapsed().as_secs_f64() * 1e3)?);
    }
    for &res in &config.coral_resolutions {
        progress(&format!("table 3: coral at {res}"));
        let t = Instant::now();
        let volume = convert(&coral(res))?;
        out.table3.push(table3_row("gyroid coral", res, volume, t.elapsed().as_secs_f64() * 1e3)?);
    }
    progress("table 5: sphere meshing");
    out.table5 = table5(config.sphere_cells);
    out.tools = crate::tools::run(
        config.tool_canvas,
        &config.tool_radii,
        config.tool_dabs,
        config.quality,
        config.seed,
        progress,
    );
    let tris: Vec<[u32; 3]> = scanned.triangles.clone();
    out.lod = Some(crate::lod::run(
        &scanned.vertices,
        &tris,
        config.lod_resolution,
        config.lod_frames,
        config.seed,
        progress,
    )?);
    let radii: Vec<f64> = config.radii.iter().copied().filter(|r| *r == 10.0 || *r == 20.0).collect();
    let paint_radii: Vec<f64> = config.tool_radii.iter().copied().filter(|r| *r == 10.0 || *r == 20.0).collect();
    out.materials = Some(crate::materials::run(
        config.count,
        &radii,
        Some((&name, &scanned.vertices, &tris)),
        config.lod_resolution,
        config.tool_canvas,
        &paint_radii,
        config.tool_dabs,
        config.seed,
        progress,
    )?);
    out.terrain = Some(crate::terrain::run(&config.terrain, progress)?);
    out.mesh_quality = crate::quality::run(&config.mesh_quality, (&scanned.vertices, &tris), progress)?;
    Ok(out)
}

fn table1_row(config: &SuiteConfig, r: f64) -> Table1Row {
    let ins = table1_instructions(config.count, r, config.seed);
    let seg = replay(&ins, false);
    let (dense, _) = replay_dense(&ins);
    let mut narrow = Vec::new();
    let mut max_memory = vec![("segments".to_string(), seg.max_memory), ("dense".to_string(), dense.max_memory)];
    for b in BANDS {
        let (nb, _) = replay_narrow(&ins, b);
        narrow.push(BandTimes { band: b, edit_ms: nb.edit_ms(), rle_ms: nb.encode_ms(), extract_ms: nb.extract_ms() });
        max_memory.push((format!("narrow band b={b}"), nb.max_memory));
    }
    Table1Row {
        radius: r,
        segments_edit_ms: seg.edit_ms(),
        segments_extract_ms: seg.extract_ms(),
        dense_edit_ms: dense.edit_ms(),
        dense_extract_ms: dense.extract_ms(),
        narrow,
        max_memory,
    }
}

/// Adds `brush` to an empty volume on one thread.
fn convert(brush: &dyn Brush) -> anyhow::Result<Volume> {
    let mut volume = Volume::new();
    volume.apply(CsgOp::Add, brush, &EditSettings { parallel: false, ..Default::default() })?;
    Ok(volume)
}

fn table3_row(shape: &str, resolution: u32, volume: Volume, convert_ms: f64) -> anyhow::Result<Table3Row> {
    let mem = volume.memory();
    let mut narrow = Vec::new();
    let mut dense_chunks = 0;
    for b in BANDS {
        let nb = NarrowBandField::from_volume(&volume, b)?;
        if b == 1.0 {
            // The dense field allocates the chunks the narrow band of width 1 stores: every
            // chunk with an inside node or a node within a cell of the surface.
            dense_chunks = nb.chunk_count();
        }
        narrow.push(nb.memory());
    }
    Ok(Table3Row {
        shape: shape.into(),
        resolution,
        crossings: mem.crossings,
        segments: mem.total(),
        segments_no_normals: mem.without_normals(),
        dense: DenseField::bytes_for_chunks(dense_chunks),
        narrow,
        convert_ms,
    })
}

/// A closed coral-like solid: a gyroid sheet (six periods across) inside a ball of diameter
/// `res` cells. Its field is `max((|g| − 0.4) / s, |p − c| − res/2)` with `g` the gyroid at
/// frequency `s`; `|∇g| ≤ s√6`, so the field is `√6`-Lipschitz.
pub fn coral(res: u32) -> SdfBrush {
    let r = res as f64 / 2.0;
    let c = DVec3::splat(r + 2.0);
    let s = std::f64::consts::TAU * 6.0 / res as f64;
    let field = move |p: DVec3| {
        let q = (p - c) * s;
        let g = q.x.sin() * q.y.cos() + q.y.sin() * q.z.cos() + q.z.sin() * q.x.cos();
        ((g.abs() - 0.4) / s).max((p - c).length() - r)
    };
    SdfBrush::new(field, Aabb::new(c - DVec3::splat(r + 1.0), c + DVec3::splat(r + 1.0)), 6f64.sqrt())
        .expect("the coral's parameters are valid")
}

/// Table 5: one sphere of radius `0.4 · cells` in a `cells³` grid, meshed by fast-surface-nets
/// from a dense `f32` field and by our meshers from the segment volume.
fn table5(cells: u32) -> Vec<Table5Row> {
    use fast_surface_nets::ndshape::{RuntimeShape, Shape};
    use fast_surface_nets::{SurfaceNetsBuffer, surface_nets};
    let n = cells as f64;
    let (centre, radius) = (DVec3::splat(n / 2.0), 0.4 * n);
    let total_cells = n * n * n;
    let mut rows = Vec::new();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    let all = rayon::ThreadPoolBuilder::new().build().expect("pool");
    let row = |method: &str, threads: usize, input_ms: f64, ms: f64, triangles: usize| Table5Row {
        method: method.into(),
        threads,
        input_ms,
        ms,
        mcells_per_s: total_cells / ms / 1e3,
        triangles,
    };
    // fast-surface-nets: samples 0..=cells plus one of padding on the far side (its convention:
    // faces are made for the cells from `min` to `max - 1`).
    let side = cells + 2;
    let shape = RuntimeShape::<u32, 3>::new([side; 3]);
    let t = Instant::now();
    let mut sdf = vec![0f32; shape.usize()];
    for (i, v) in sdf.iter_mut().enumerate() {
        let [x, y, z] = shape.delinearize(i as u32);
        *v = ((DVec3::new(x as f64, y as f64, z as f64) - centre).length() - radius) as f32;
    }
    let input_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut buffer = SurfaceNetsBuffer::default();
    let t = Instant::now();
    surface_nets(&sdf, &shape, [0; 3], [cells + 1; 3], &mut buffer);
    rows.push(row(
        "fast-surface-nets (dense f32 field)",
        1,
        input_ms,
        t.elapsed().as_secs_f64() * 1e3,
        buffer.indices.len() / 3,
    ));
    drop(sdf);

    let sphere = Sphere::new(centre, radius).expect("valid sphere");
    let t = Instant::now();
    let volume = convert(&sphere).expect("valid edit");
    let input_ms = t.elapsed().as_secs_f64() * 1e3;
    for (pool, threads) in [(&one, 1), (&all, all.current_num_threads())] {
        let t = Instant::now();
        let mc = pool.install(|| strata_mesh::MeshCache::build(&volume));
        let ms = t.elapsed().as_secs_f64() * 1e3;
        rows.push(row("marching cubes (segments → blocks → mesh)", threads, input_ms, ms, mc.triangle_count()));
        let t = Instant::now();
        let dc = pool.install(|| strata_mesh::DualCache::build(&volume));
        let ms = t.elapsed().as_secs_f64() * 1e3;
        rows.push(row("dual contouring (segments → blocks → QEF → quads)", threads, input_ms, ms, dc.triangle_count()));
    }
    rows
}

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let mem_gib = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| s.lines().next().and_then(|l| l.split_whitespace().nth(1)).and_then(|k| k.parse::<f64>().ok()))
        .map(|kib| kib / 1024.0 / 1024.0)
        .unwrap_or(0.0);
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    format!("{cpu}, {cores} cores, {mem_gib:.0} GiB")
}

fn revision() -> String {
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    match git(&["rev-parse", "--short", "HEAD"]) {
        Some(rev) => {
            let dirty = git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
            if dirty { format!("{rev}-dirty") } else { rev }
        }
        None => "unknown".into(),
    }
}

fn mib(bytes: usize) -> String {
    format!("{:.2}", bytes as f64 / (1024.0 * 1024.0))
}

/// The tables as markdown, with the machine, revision and command.
pub fn markdown(r: &SuiteResults) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "Machine: {}. Revision: `{}`. Command: `{}`.\n", r.machine, r.revision, r.command);
    let _ = writeln!(
        s,
        "### Table 1 — per-instruction edit (Time_d), voxel-block (Time_v) and re-encode (Time_RLE) times, one thread\n\n{} seeded random sphere draw/erase instructions on a 160³-cell canvas; ms per instruction.\n",
        r.config.count
    );
    let mut head = "| radius | segments Time_d | dense Time_d | dense/segments Time_d | segments Time_v | dense Time_v | dense/segments Time_v |".to_string();
    let mut rule = "|---:|---:|---:|---:|---:|---:|---:|".to_string();
    for b in BANDS {
        let _ = write!(head, " NB b={b} Time_d | NB b={b} Time_RLE | NB b={b} Time_v |");
        rule.push_str("---:|---:|---:|");
    }
    let _ = writeln!(s, "{head}\n{rule}");
    for row in &r.table1 {
        let _ = write!(
            s,
            "| {} | {:.3} | {:.3} | {:.1}× | {:.3} | {:.3} | {:.1}× |",
            row.radius,
            row.segments_edit_ms,
            row.dense_edit_ms,
            row.dense_edit_ms / row.segments_edit_ms,
            row.segments_extract_ms,
            row.dense_extract_ms,
            row.dense_extract_ms / row.segments_extract_ms
        );
        for nb in &row.narrow {
            let _ = write!(s, " {:.3} | {:.3} | {:.3} |", nb.edit_ms, nb.rle_ms, nb.extract_ms);
        }
        s.push('\n');
    }
    let _ = writeln!(s, "\n### Table 2 — whole frame (edit + voxel blocks + remesh of affected chunks)\n");
    let _ = writeln!(
        s,
        "| mesher | radius | mean 1 thread (ms) | p99 1 thread (ms) | mean all cores (ms) | p99 all cores (ms) |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
    for row in &r.table2 {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} |",
            row.mesher, row.radius, row.mean_1, row.p99_1, row.mean_all, row.p99_all
        );
    }
    let _ = writeln!(
        s,
        "\n### Table 3 — converted shapes: memory (MiB) and conversion time\n\nDense: chunk count × 16 KiB plus its map (computed, not built). Narrow band (NB): built from the segment volume.\n"
    );
    let _ = writeln!(
        s,
        "| shape | cells | crossings | segments | segments w/o normals | dense | NB b=1 | NB b=2 | NB b=3 | segments / NB b=1 | convert into segments, 1 thread (ms) |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for row in &r.table3 {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} | {:.0} |",
            row.shape,
            row.resolution,
            row.crossings,
            mib(row.segments),
            mib(row.segments_no_normals),
            mib(row.dense),
            mib(row.narrow[0]),
            mib(row.narrow[1]),
            mib(row.narrow[2]),
            row.segments as f64 / row.narrow[0] as f64,
            row.convert_ms
        );
    }
    let _ = writeln!(s, "\n### Table 4 — maximum memory during the Table 1 drawing (MiB)\n");
    let names: Vec<&str> =
        r.table1.first().map(|row| row.max_memory.iter().map(|(n, _)| n.as_str()).collect()).unwrap_or_default();
    let _ = writeln!(s, "| radius | {} |", names.join(" | "));
    let _ = writeln!(s, "|---:|{}", "---:|".repeat(names.len()));
    for row in &r.table1 {
        let cells: Vec<String> = row.max_memory.iter().map(|(_, b)| mib(*b)).collect();
        let _ = writeln!(s, "| {} | {} |", row.radius, cells.join(" | "));
    }
    let _ = writeln!(
        s,
        "\n### Table 5 — meshing one sphere (radius 0.4 × {0}) in a {0}³-cell grid\n",
        r.config.sphere_cells
    );
    let _ = writeln!(s, "| method | threads | input build (ms) | meshing (ms) | Mcells/s | triangles |");
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
    for row in &r.table5 {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {:.1} | {} |",
            row.method, row.threads, row.input_ms, row.ms, row.mcells_per_s, row.triangles
        );
    }
    let t = &r.tools;
    let _ = writeln!(
        s,
        "\n### Table 6 — sculpting tools\n\n{} dabs per tool and radius on the surface of a canvas of {} radius-10 Table 1 instructions, with the studio's defaults (strength 0.5, 4 smoothing passes, inflate 0.2 r, pinch 0.5, clay fillet 0.5 r, grab 0.25 r per frame). The dab column is the tool on one thread; the whole frame adds the remesh of the affected chunks, the dab and the remesh both on one thread or both on all cores (a dab's chunks and its band run in parallel there). Targets, one thread: whole frame ≤ 4 ms at radius 10 and ≤ 11.1 ms at radius 20.\n",
        t.dabs, r.config.tool_canvas
    );
    let _ = writeln!(
        s,
        "| tool | radius | dab (ms) | frame 1 thread (ms) | p99 1 thread (ms) | frame all cores (ms) | chunks changed |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|");
    for row in &t.table6 {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} |",
            row.tool, row.radius, row.dab_ms, row.frame_1_ms, row.frame_1_p99_ms, row.frame_all_ms, row.changed_chunks
        );
    }
    let _ = writeln!(
        s,
        "\nThe same smoothing the way godot_voxel does it: a 3×3×3 box blur of the dense baseline's field (read saturated at ±4 cells, as godot_voxel's stored SDF saturates) inside the ball, blended by `strength · (1 − d²/r²)`, against one pass of the default (volume-preserving) field smoothing on the segments, same dabs:\n"
    );
    let _ = writeln!(s, "| radius | dense box blur (ms) | segments, 1 pass (ms) | segments / dense |");
    let _ = writeln!(s, "|---:|---:|---:|---:|");
    for row in &t.blur {
        let _ = writeln!(
            s,
            "| {} | {:.3} | {:.3} | {:.0}× |",
            row.radius,
            row.dense_ms,
            row.segments_ms,
            row.segments_ms / row.dense_ms
        );
    }
    let _ = writeln!(
        s,
        "\nSmoothing quality: a sphere of radius 20 roughened by 200 spheres of radius 1.5–3, then {} dabs of radius 9 at full strength, {} passes each, over its whole surface. RMS: radial deviation from the best-fit sphere's radius over 400 directions.\n",
        r.config.quality.0, r.config.quality.1
    );
    let _ =
        writeln!(s, "| method | RMS before (cells) | RMS after (cells) | RMS reduction | volume change | ms per dab |");
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
    for row in &t.quality {
        let _ = writeln!(
            s,
            "| {} | {:.3} | {:.3} | {:.0} % | {:+.2} % | {:.1} |",
            row.method,
            row.rms_before,
            row.rms_after,
            (1.0 - row.rms_after / row.rms_before) * 100.0,
            row.volume_change_pct,
            row.dab_ms
        );
    }
    if let Some(l) = &r.lod {
        lod_markdown(&mut s, l);
    }
    if let Some(m) = &r.materials {
        crate::materials::markdown(&mut s, m);
    }
    if let Some(t) = &r.terrain {
        crate::terrain::markdown(&mut s, t);
    }
    if !r.mesh_quality.is_empty() {
        crate::quality::markdown(&r.mesh_quality, &mut s);
    }
    s
}

/// Table 7's markdown, appended to `s`.
pub fn lod_markdown(s: &mut String, l: &crate::lod::LodResults) {
    let _ = writeln!(
        s,
        "\n### Table 7 — level of detail\n\nThe models stored at the finest level (64³ cells a chunk), {} finest cells along their longest side, meshed (marching cubes, welded, all cores) at full resolution and as seen along a diagonal from where the model's diagonal spans 1,080 (near), 360 (middle) and 108 (far) pixels of a 1,080-pixel, 45° view: each chunk at the coarsest level whose cell, at the chunk's nearest point, spans at most {} pixel (blocks of coarser levels sampled from the stored lists, seams patched). Target: far view ≤ 15 % of the full triangles, no open edge.\n",
        l.resolution,
        crate::lod::PIXEL_ERROR
    );
    let _ = writeln!(
        s,
        "| model | view | chunks at 16³ / 32³ / 64³ | triangles | % of full | mesh (MiB) | meshing (ms) | open edges |"
    );
    let _ = writeln!(s, "|---|---|---|---:|---:|---:|---:|---:|");
    let mut full = 1usize;
    for row in &l.views {
        if row.view == "full resolution" {
            full = row.triangles.max(1);
        }
        let _ = writeln!(
            s,
            "| {} | {} | {} / {} / {} | {} | {:.1} % | {:.1} | {:.0} | {} |",
            row.model,
            row.view,
            row.chunks_at[0],
            row.chunks_at[1],
            row.chunks_at[2],
            row.triangles,
            row.triangles as f64 / full as f64 * 100.0,
            row.mesh_bytes as f64 / (1024.0 * 1024.0),
            row.mesh_ms,
            row.open_edges
        );
    }
    let _ = writeln!(
        s,
        "\nChanging one chunk's stored level (the bunny's first {} list chunks):\n",
        l.changes.first().map_or(0, |c| c.chunks)
    );
    let _ = writeln!(s, "| change | ms per chunk |");
    let _ = writeln!(s, "|---|---:|");
    for row in &l.changes {
        let _ = writeln!(s, "| {} | {:.2} |", row.change, row.ms_per_chunk);
    }
    let _ = writeln!(s, "\nMemory of the bunny with detail only where it was sculpted:\n");
    let _ = writeln!(s, "| stored | list chunks at 16³ / 32³ / 64³ | memory (MiB) |");
    let _ = writeln!(s, "|---|---|---:|");
    for row in &l.memory {
        let _ = writeln!(
            s,
            "| {} | {} / {} / {} | {:.2} |",
            row.layout,
            row.chunks_at[0],
            row.chunks_at[1],
            row.chunks_at[2],
            row.bytes as f64 / (1024.0 * 1024.0)
        );
    }
    let _ = writeln!(
        s,
        "\nWhole frames of the editor (edit, remesh of at least one batch of 16 chunks, new meshes committed with their neighbours) while a clay stroke of radius 10 cells (strength 0.5) runs over the bunny with level of detail on, the camera at the near view, one thread. Target: p99 ≤ 11.1 ms.\n"
    );
    let _ = writeln!(s, "| bunny stored as | frames | mean (ms) | p99 (ms) |");
    let _ = writeln!(s, "|---|---:|---:|---:|");
    for (name, n, mean, p99) in &l.sculpt {
        let _ = writeln!(s, "| {name} | {n} | {mean:.2} | {p99:.2} |");
    }
}

/// Markers around the suite's section in `docs/BENCHMARKS.md`.
pub const BEGIN: &str = "<!-- suite:begin (written by `strata-bench suite`) -->";
/// See [`BEGIN`].
pub const END: &str = "<!-- suite:end -->";

/// Replaces the text between [`BEGIN`] and [`END`] in `doc` (appending the section if absent).
pub fn splice(doc: &str, section: &str) -> String {
    match (doc.find(BEGIN), doc.find(END)) {
        (Some(b), Some(e)) if b < e => format!("{}{BEGIN}\n{section}{}", &doc[..b], &doc[e..]),
        _ => format!("{doc}\n{BEGIN}\n{section}{END}\n"),
    }
}

/// The repository root (for the default paths).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}
