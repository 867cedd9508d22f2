//! `strata-bench`: prints benchmark tables as markdown.
//!
//! `cargo run --release -p strata-bench -- table1` replays the paper's Table 1 workload.

/// The studio's allocator, so the flights measure what the studio runs: mimalloc, whose frees of
/// memory another thread allocated never wait for that thread's lock (docs/BENCHMARKS.md,
/// "Generation on every core").
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use anyhow::Result;
use clap::{Parser, Subcommand};
use strata_bench::{Mesher, replay, replay_frames, table1_instructions};

#[derive(Parser)]
#[command(about = "Strata benchmark suite: prints markdown tables")]
struct Cli {
    #[command(subcommand)]
    suite: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Table 1: 1000 random sphere draw/erase instructions on a 160³ canvas, per radius.
    Table1 {
        /// Instructions per radius.
        #[arg(long, default_value_t = 1000)]
        count: usize,
        /// Radii to run.
        #[arg(long, value_delimiter = ',', default_values_t = vec![5.0, 10.0, 15.0, 20.0, 40.0])]
        radii: Vec<f64>,
        /// Workload seed.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
        /// Skip the rayon run (one thread only; for profiling).
        #[arg(long)]
        single: bool,
    },
    /// Table 2: whole-frame time of edit + voxel blocks + remesh, per radius, with marching
    /// cubes and with dual contouring.
    Frame {
        /// Instructions per radius.
        #[arg(long, default_value_t = 1000)]
        count: usize,
        /// Radii to run.
        #[arg(long, value_delimiter = ',', default_values_t = vec![5.0, 10.0, 15.0, 20.0])]
        radii: Vec<f64>,
        /// Workload seed.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
    },
    /// The side-by-side suite: Tables 1–5 (segments, dense and narrow band; meshing against
    /// fast-surface-nets). Rewrites the suite's section of docs/BENCHMARKS.md and writes the raw
    /// numbers as JSON.
    Suite {
        /// Every table at reduced size (under a minute); writes no docs unless --docs is given.
        #[arg(long)]
        quick: bool,
        /// The scanned mesh of Table 3.
        #[arg(long)]
        mesh: Option<std::path::PathBuf>,
        /// Where to write the JSON (default: docs/benchmarks.json for a full run).
        #[arg(long)]
        json: Option<std::path::PathBuf>,
        /// The markdown file whose suite section to rewrite (default: docs/BENCHMARKS.md for a
        /// full run).
        #[arg(long)]
        docs: Option<std::path::PathBuf>,
    },
    /// A recorded 10-second stroke (poses at 90 Hz, radius 10) replayed through the editor core
    /// with marching cubes: per-frame cost (edit + remesh; no GPU upload yet), p50 and p99.
    Stroke {
        /// Seconds of stroke.
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
    },
    /// Converts the scanned mesh of Table 3 at one resolution and prints where the time and the
    /// bytes go.
    Convert {
        /// Cells along the longest side.
        #[arg(long, default_value_t = 1024)]
        res: u32,
        /// The mesh (PLY, OBJ or STL); the shipped bunny by default.
        #[arg(long)]
        mesh: Option<std::path::PathBuf>,
    },
    /// Table 6 alone: per-dab and whole-frame times of every sculpting tool on the Table 1
    /// canvas (printed, not written to the docs; `suite` writes them).
    Tools {
        /// Canvas instructions (radius 10).
        #[arg(long, default_value_t = 1000)]
        canvas: usize,
        /// Brush radii.
        #[arg(long, value_delimiter = ',', default_values_t = vec![5.0, 10.0, 20.0])]
        radii: Vec<f64>,
        /// Dabs per tool and radius.
        #[arg(long, default_value_t = 100)]
        dabs: usize,
        /// Workload seed.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
        /// Only the tools whose Table 6 names contain one of these (all when none is given).
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
    },
    /// Masked strokes against unmasked ones on the Table 6 canvas (issue 32), printed.
    Masks {
        /// Canvas instructions (radius 10).
        #[arg(long, default_value_t = 1000)]
        canvas: usize,
        /// Brush radii.
        #[arg(long, value_delimiter = ',', default_values_t = vec![10.0, 20.0])]
        radii: Vec<f64>,
        /// Dabs per tool and radius.
        #[arg(long, default_value_t = 100)]
        dabs: usize,
        /// Workload seed.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
    },
    /// Table 7 alone (level of detail): views, level changes, memory of detail where sculpted
    /// and sculpting frames, printed (not written to the docs; `suite` writes them).
    Lod {
        /// Finest cells along the models' longest side.
        #[arg(long, default_value_t = 1024)]
        res: u32,
        /// Sculpting frames.
        #[arg(long, default_value_t = 300)]
        frames: usize,
        /// The mesh (PLY, OBJ or STL); the shipped bunny by default.
        #[arg(long)]
        mesh: Option<std::path::PathBuf>,
    },
    /// Table 10 alone (mesh quality): every mesher on a sphere, the bunny, a noise asteroid and
    /// the Table 1 canvas, printed (not written to the docs; `suite` writes them).
    Quality {
        /// The reduced sizes of `suite --quick`.
        #[arg(long)]
        quick: bool,
        /// Sphere diameter and bunny and asteroid size in cells (overrides the default).
        #[arg(long)]
        res: Option<u32>,
        /// Only the shapes whose name contains this (sphere, bunny, asteroid, canvas).
        #[arg(long, default_value = "")]
        shape: String,
        /// Only the meshers whose name contains this (for example "MT" or "clustering").
        #[arg(long, default_value = "")]
        mesher: String,
    },
    /// Table 8 alone (materials): the workload with and without materials, the painted scan
    /// and paint dabs, printed (not written to the docs; `suite` writes them).
    Materials {
        /// Instructions per radius.
        #[arg(long, default_value_t = 1000)]
        count: usize,
        /// Cells along the scan's longest side.
        #[arg(long, default_value_t = 1024)]
        res: u32,
        /// Paint dabs per radius.
        #[arg(long, default_value_t = 100)]
        dabs: usize,
    },
    /// Table 9 alone (terrain): generation against dense sampling, a streamed flight and paging,
    /// printed (not written to the docs; `suite` writes them).
    Terrain {
        /// The CI sizes.
        #[arg(long)]
        quick: bool,
    },
    /// Sculpting together on loopback: dab-to-everyone latency with several client counts,
    /// the operations a room orders per second, bytes per operation, and the join time for the
    /// bunny at 1,024 cells; on redb and, with --pg or STRATA_PG_URL, on PostgreSQL.
    Collab {
        /// Client counts for the latency rows (repeatable).
        #[arg(long, default_values_t = [8, 32])]
        clients: Vec<usize>,
        /// Dabs per second over all clients.
        #[arg(long, default_value_t = 30.0)]
        rate: f64,
        /// Seconds of dabs per latency row.
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
        /// Operations in the throughput run.
        #[arg(long, default_value_t = 2000)]
        burst: usize,
        /// Bunny cells for the join row (0: skip it).
        #[arg(long, default_value_t = 1024)]
        join_cells: u32,
        /// A PostgreSQL URL (default: STRATA_PG_URL when set).
        #[arg(long)]
        pg: Option<String>,
    },
    /// Marching cubes on the GPU against the CPU: per frame of the Table 2 workload and a full
    /// remesh of the bunny (lavapipe where there is no GPU).
    Gpu {
        /// Frames measured (after ten of warm-up).
        #[arg(long, default_value_t = 100)]
        frames: usize,
        /// Frames measured across levels (after three of warm-up).
        #[arg(long, default_value_t = 20)]
        mixed_frames: usize,
        /// The workload's radius.
        #[arg(long, default_value_t = 20.0)]
        radius: f64,
        /// The bunny's cells along its longest side.
        #[arg(long, default_value_t = 256)]
        bunny: u32,
    },
    /// Meshing throughput on the Table 1 canvas after the radius-20 workload: marching cubes and
    /// dual contouring over every chunk that can hold surface, one thread and all cores.
    MeshSpeed {
        /// Workload seed.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
    },
}

fn main() -> Result<()> {
    match Cli::parse().suite {
        Command::Table1 { count, radii, seed, single } => table1(count, &radii, seed, single),
        Command::Frame { count, radii, seed } => frame(count, &radii, seed),
        Command::MeshSpeed { seed } => mesh_speed(seed),
        Command::Gpu { frames, mixed_frames, radius, bunny } => {
            print!("{}", strata_bench::gpu::run(frames, mixed_frames, radius, bunny)?)
        }
        Command::Collab { clients, rate, seconds, burst, join_cells, pg } => {
            let pg = pg.or_else(|| std::env::var("STRATA_PG_URL").ok());
            let config = strata_bench::collab::CollabConfig { clients, rate, seconds, burst, join_cells, pg };
            print!("{}", strata_bench::collab::run(&config)?);
        }
        Command::Tools { canvas, radii, dabs, seed, only } => tools(canvas, &radii, dabs, seed, &only),
        Command::Masks { canvas, radii, dabs, seed } => {
            let start = std::time::Instant::now();
            let md = strata_bench::masks::run(canvas, &radii, dabs, seed, &mut |step| {
                eprintln!("[{:6.1} s] {step}", start.elapsed().as_secs_f64());
            });
            println!("{md}");
        }
        Command::Lod { res, frames, mesh } => return lod(res, frames, mesh),
        Command::Materials { count, res, dabs } => return materials(count, res, dabs),
        Command::Quality { quick, res, shape, mesher } => return quality(quick, res, &shape, &mesher),
        Command::Terrain { quick } => return terrain(quick),
        Command::Stroke { seconds } => stroke(seconds),
        Command::Convert { res, mesh } => return convert(res, mesh),
        Command::Suite { quick, mesh, json, docs } => return suite(quick, mesh, json, docs),
    }
    Ok(())
}

fn quality(quick: bool, res: Option<u32>, shape: &str, mesher: &str) -> Result<()> {
    use strata_bench::quality;
    let mut config = if quick { quality::QualityConfig::quick() } else { quality::QualityConfig::full() };
    if let Some(r) = res {
        config.res = r;
    }
    let bunny = strata_mesh::import::load_mesh(&strata_bench::suite::repo_root().join("tests/data/bunny.ply"))?;
    let rows =
        quality::run_some(&config, (&bunny.vertices, &bunny.triangles), shape, mesher, &mut |p| eprintln!("{p}"))?;
    let mut s = String::new();
    quality::markdown(&rows, &mut s);
    println!("{s}");
    Ok(())
}

fn suite(
    quick: bool,
    mesh: Option<std::path::PathBuf>,
    json: Option<std::path::PathBuf>,
    docs: Option<std::path::PathBuf>,
) -> Result<()> {
    use strata_bench::suite;
    let root = suite::repo_root();
    let config = if quick { suite::SuiteConfig::quick() } else { suite::SuiteConfig::full() };
    let mesh = mesh.unwrap_or_else(|| root.join("tests/data/bunny.ply"));
    let start = std::time::Instant::now();
    let results = suite::run(&config, &mesh, &mut |step| {
        eprintln!("[{:6.1} s] {step}", start.elapsed().as_secs_f64());
    })?;
    let md = suite::markdown(&results);
    println!("{md}");
    let json = json.or_else(|| (!quick).then(|| root.join("docs/benchmarks.json")));
    if let Some(path) = json {
        std::fs::write(&path, serde_json::to_string_pretty(&results)?)?;
        eprintln!("wrote {}", path.display());
    }
    let docs = docs.or_else(|| (!quick).then(|| root.join("docs/BENCHMARKS.md")));
    if let Some(path) = docs {
        let old = std::fs::read_to_string(&path).unwrap_or_default();
        let tmp = path.with_extension("md.tmp");
        std::fs::write(&tmp, suite::splice(&old, &md))?;
        std::fs::rename(&tmp, &path)?;
        eprintln!("rewrote the suite section of {}", path.display());
    }
    eprintln!("suite done in {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}

fn lod(res: u32, frames: usize, mesh: Option<std::path::PathBuf>) -> Result<()> {
    let path = mesh.unwrap_or_else(|| strata_bench::suite::repo_root().join("tests/data/bunny.ply"));
    let m = strata_mesh::import::load_mesh(&path)?;
    let start = std::time::Instant::now();
    let r = strata_bench::lod::run(&m.vertices, &m.triangles, res, frames, 2021, &mut |step| {
        eprintln!("[{:6.1} s] {step}", start.elapsed().as_secs_f64());
    })?;
    let mut s = String::new();
    strata_bench::suite::lod_markdown(&mut s, &r);
    println!("{s}");
    Ok(())
}

fn materials(count: usize, res: u32, dabs: usize) -> Result<()> {
    let path = strata_bench::suite::repo_root().join("tests/data/bunny.ply");
    let m = strata_mesh::import::load_mesh(&path)?;
    let start = std::time::Instant::now();
    let scan = ("bunny", &m.vertices[..], &m.triangles[..]);
    let r = strata_bench::materials::run(
        count,
        &[10.0, 20.0],
        Some(scan),
        res,
        1000,
        &[10.0, 20.0],
        dabs,
        2021,
        &mut |step| {
            eprintln!("[{:6.1} s] {step}", start.elapsed().as_secs_f64());
        },
    )?;
    let mut s = String::new();
    strata_bench::materials::markdown(&mut s, &r);
    println!("{s}");
    Ok(())
}

fn tools(canvas: usize, radii: &[f64], dabs: usize, seed: u64, only: &[String]) {
    let start = std::time::Instant::now();
    let chosen: Vec<strata_bench::tools::Tool> = strata_bench::tools::Tool::ALL
        .into_iter()
        .filter(|t| only.is_empty() || only.iter().any(|o| t.name().contains(o.as_str())))
        .collect();
    let r = strata_bench::tools::run_tools(&chosen, canvas, radii, dabs, (0, 0), seed, &mut |step| {
        eprintln!("[{:6.1} s] {step}", start.elapsed().as_secs_f64());
    });
    println!(
        "| tool | radius | dab (ms) | frame 1 thread (ms) | p99 1 thread (ms) | frame all cores (ms) | chunks changed |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for row in &r.table6 {
        println!(
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} |",
            row.tool, row.radius, row.dab_ms, row.frame_1_ms, row.frame_1_p99_ms, row.frame_all_ms, row.changed_chunks
        );
    }
    for row in &r.blur {
        println!(
            "radius {}: dense box blur {:.3} ms, segments 1 pass {:.3} ms",
            row.radius, row.dense_ms, row.segments_ms
        );
    }
}

fn table1(count: usize, radii: &[f64], seed: u64, single_only: bool) {
    println!(
        "| radius | Time_d 1 thread (ms) | Time_v 1 thread (ms) | Time_d rayon (ms) | Time_v rayon (ms) | chunks changed / edit | crossings | B/crossing | B/crossing w/o normals | longest chunk line |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for &r in radii {
        let ins = table1_instructions(count, r, seed);
        let single = replay(&ins, false);
        let par = if single_only { single.clone() } else { replay(&ins, true) };
        assert_eq!(single.volume, par.volume, "parallel and single-threaded edits must agree");
        let mem = single.volume.memory();
        let stats = single.volume.crossing_stats();
        println!(
            "| {r} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} | {} | {:.2} | {:.2} | {} |",
            single.edit_ms(),
            single.extract_ms(),
            par.edit_ms(),
            par.extract_ms(),
            single.changed_chunks as f64 / count as f64,
            mem.crossings,
            mem.bytes_per_crossing(true),
            mem.bytes_per_crossing(false),
            stats.max_line,
        );
    }
}

fn frame(count: usize, radii: &[f64], seed: u64) {
    println!(
        "| mesher | radius | mean 1 thread (ms) | p99 1 thread (ms) | mean rayon (ms) | p99 rayon (ms) | triangles at end |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for (name, mesher) in [("marching cubes", Mesher::MarchingCubes), ("dual contouring", Mesher::DualContouring)] {
        for &r in radii {
            let ins = table1_instructions(count, r, seed);
            let single = replay_frames(&ins, false, mesher);
            let par = replay_frames(&ins, true, mesher);
            println!(
                "| {name} | {r} | {:.2} | {:.2} | {:.2} | {:.2} | {} |",
                single.mean_ms(),
                single.quantile_ms(0.99),
                par.mean_ms(),
                par.quantile_ms(0.99),
                single.triangles
            );
        }
    }
}

fn mesh_speed(seed: u64) {
    use std::time::Instant;
    let volume = replay(&table1_instructions(1000, 20.0, seed), true).volume;
    let keys = strata_mesh::surface_chunks(&volume);
    let cells = keys.len() as f64 * 4096.0;
    // One chunk: the stored chunk with the most crossings, meshed repeatedly on one thread.
    let busiest = volume
        .chunks()
        .filter_map(|(k, c)| match c {
            strata_volume::Chunk::Lists(l) => Some((l.crossing_count(), k)),
            _ => None,
        })
        .max()
        .expect("the canvas has list chunks");
    let (busiest_crossings, busiest) = busiest;
    let mut block = strata_volume::VoxelBlock::default();
    let mut mesh = strata_mesh::Mesh::default();
    let reps = 2000;
    let t = Instant::now();
    for _ in 0..reps {
        volume.extract_block_into(busiest, &mut block);
        strata_mesh::mesh_block(&block, &mut mesh);
    }
    let per = t.elapsed().as_secs_f64() * 1e3 / reps as f64;
    println!(
        "One chunk (the busiest, {} crossings), extract + marching cubes: {per:.3} ms = {:.1} Mcells/s, {} triangles\n",
        busiest_crossings,
        4096.0 / per / 1e3,
        mesh.triangle_count()
    );
    println!("| mesher | threads | chunks | ms | Mcells/s | triangles |");
    println!("|---|---:|---:|---:|---:|---:|");
    for threads in [1, 0] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        let label = if threads == 1 { "1".to_string() } else { rayon::current_num_threads().to_string() };
        let t = Instant::now();
        let cache = pool.install(|| strata_mesh::MeshCache::build(&volume));
        let ms = t.elapsed().as_secs_f64() * 1e3;
        println!(
            "| marching cubes (blocks + mesh) | {label} | {} | {ms:.1} | {:.1} | {} |",
            keys.len(),
            cells / ms / 1e3,
            cache.triangle_count()
        );
        let t = Instant::now();
        let dc = pool.install(|| {
            strata_mesh::mesh_volume_with(&volume, strata_mesh::MeshOptions::new(strata_mesh::Mesher::DualContouring))
                .expect("dual contouring meshes every volume")
        });
        let ms = t.elapsed().as_secs_f64() * 1e3;
        println!(
            "| dual contouring (blocks + QEF + weld) | {label} | {} | {ms:.1} | {:.1} | {} |",
            keys.len(),
            cells / ms / 1e3,
            dc.triangle_count()
        );
    }
}

fn stroke(seconds: f64) {
    use glam::{DQuat, DVec3, Mat4};
    use std::time::{Duration, Instant};
    use strata_editor::{Buttons, Editor, ToolPose};
    let mut editor = Editor::default();
    editor.tool.radius = 10.0;
    // Uploads go to a real (or software) GPU when one is there.
    let gpu = strata_render::Gpu::headless().ok();
    let mut renderer =
        gpu.as_ref().map(|g| strata_render::Renderer::new(&g.device, wgpu::TextureFormat::Rgba8UnormSrgb));
    let frames = (seconds * 90.0).round() as usize;
    let mut costs = Vec::with_capacity(frames);
    let mut dabs = 0;
    for i in 0..frames {
        // A figure-eight over a 160-cell canvas at about 60 cells per second, pen down,
        // lifting for a moment every two seconds (a new stroke each time).
        let t = i as f64 / 90.0;
        let position = DVec3::new(80.0 + 60.0 * (0.5 * t).sin(), 40.0 + 8.0 * (1.3 * t).sin(), 80.0 + 40.0 * t.sin());
        let down = (t % 2.0) < 1.9;
        let pose = ToolPose {
            position,
            orientation: DQuat::IDENTITY,
            pressure: 1.0,
            buttons: Buttons { primary: down, secondary: false },
            ..ToolPose::default()
        };
        let t0 = Instant::now();
        let report = editor.frame(&pose, Duration::from_millis(8)).expect("valid stroke");
        if let (Some(g), Some(r)) = (&gpu, &mut renderer) {
            for &(layer, key) in &report.remeshed {
                match editor.mesh_cache(layer).and_then(|c| c.mesh(key)) {
                    Some(mesh) => r.upload_mesh(
                        &g.device,
                        &g.queue,
                        strata_viewport::chunk_id(layer as u32, key),
                        strata_viewport::mesh_ref(mesh),
                        strata_viewport::chunk_placement(Mat4::IDENTITY, key),
                        [0.5, 0.4, 0.3],
                    ),
                    None => r.remove_mesh(strata_viewport::chunk_id(layer as u32, key)),
                }
            }
            g.queue.submit([]);
        }
        costs.push(t0.elapsed().as_secs_f64() * 1e3);
        dabs += report.dabs;
    }
    let q = |p: f64| strata_bench::quantile(&costs, p);
    let upload = match &gpu {
        Some(g) => format!("edit + remesh + upload to {}", g.info.name),
        None => "edit + remesh (no GPU adapter: no upload)".to_string(),
    };
    println!("Frame cost: {upload}.\n");
    println!("| frames | dabs | p50 (ms) | p99 (ms) | max (ms) | triangles at end | strokes (undo steps) |");
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    println!(
        "| {frames} | {dabs} | {:.2} | {:.2} | {:.2} | {} | {} |",
        q(0.5),
        q(0.99),
        q(1.0),
        editor.triangle_count(),
        editor.history().undo_len()
    );
}

fn convert(res: u32, mesh: Option<std::path::PathBuf>) -> Result<()> {
    use glam::DVec3;
    use std::time::Instant;
    use strata_volume::brush::{MeshBrush, MeshRule};
    let path = mesh.unwrap_or_else(|| strata_bench::suite::repo_root().join("tests/data/bunny.ply"));
    let m = strata_mesh::import::load_mesh(&path)?;
    let (lo, hi) = m.bounds().expect("vertices");
    let scale = res as f64 / (hi - lo).max_element();
    let verts: Vec<DVec3> = m.vertices.iter().map(|&v| (v - lo) * scale + DVec3::splat(2.0)).collect();
    let t = Instant::now();
    let brush = MeshBrush::new(&verts, &m.triangles, MeshRule::EvenOdd)?;
    let build = t.elapsed();
    let mut volume = strata_volume::Volume::new();
    let t = Instant::now();
    let settings = strata_volume::EditSettings { parallel: false, ..Default::default() };
    volume.apply(strata_volume::CsgOp::Add, &brush, &settings)?;
    let edit = t.elapsed();
    let mem = volume.memory();
    let stats = volume.crossing_stats();
    println!(
        "{} at {res}: BVH {:.1} ms, edit {:.1} ms (one thread)",
        path.display(),
        build.as_secs_f64() * 1e3,
        edit.as_secs_f64() * 1e3
    );
    println!(
        "crossings {}, list chunks {}, solid chunks {}; bytes: positions {}, normals {}, headers {}, chunk map {}, total {} ({:.2} MiB, {:.2} B/crossing)",
        mem.crossings,
        stats.list_chunks,
        stats.solid_chunks,
        mem.positions,
        mem.normals,
        mem.headers,
        mem.chunk_map,
        mem.total(),
        mem.total() as f64 / (1024.0 * 1024.0),
        mem.bytes_per_crossing(true)
    );
    Ok(())
}

fn terrain(quick: bool) -> Result<()> {
    use strata_bench::terrain;
    let config = if quick { terrain::TerrainConfig::quick() } else { terrain::TerrainConfig::full() };
    let start = std::time::Instant::now();
    let results = terrain::run(&config, &mut |step| eprintln!("[{:6.1} s] {step}", start.elapsed().as_secs_f64()))?;
    let mut md = String::new();
    terrain::markdown(&mut md, &results);
    println!("{md}");
    Ok(())
}
