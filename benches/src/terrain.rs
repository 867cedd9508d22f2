//! Table 9 — terrain: generating chunks into lists against dense sampling, streaming while
//! flying, and paging edited chunks through the world database.
//!
//! - **Generation**, one thread, over a block of chunk columns from the cave floor to the sky:
//!   lists (`generate_chunk`, interval-bounded chunk and node decisions, crossings only where
//!   states change) against the seeds' way (the same density sampled at every node of a dense
//!   17³ field per chunk, as the Godot tutorial does), with the column heights computed per node
//!   and per column; the noise crate's own cost per sample × 4,096; then meshing each chunk
//!   (marching cubes from the lists' blocks, and from a dense padded 19³ field with gradient
//!   normals).
//! - **Streaming**: a viewer flying straight at `speed` chunks a second for `seconds` with a
//!   view distance of `view` cells, 60 frames a second in real time, through the studio's road:
//!   an editor on the world (`Editor::on_world`), whose `stream` integrates finished chunks
//!   (workers generate) and whose `frame` hands changed chunks to a mesher thread nearest first
//!   and shows what it finished, both under budgets. Main-thread frame times, and chunks
//!   generated and shown per second.
//! - **Paging**: `count` edited chunks written to a fresh world in one transaction and one
//!   transaction each, read back in random order; bytes of the database per edited chunk. With
//!   the `sqlite` feature the same workload on SQLite (rusqlite, WAL, synchronous=FULL).

use std::time::{Duration, Instant};

use glam::DVec3;
use noise::NoiseFn;
use serde::Serialize;
use strata_mesh::{Mesh, mesh_block};
use strata_terrain::{Recipe, StoredChunk, TerrainField, World, WorldSettings, WorldStore, encode_record};
use strata_volume::brush::Sphere;
use strata_volume::{Chunk, ChunkKey, Level, Volume, VoxelBlock, generate_chunk};

use crate::tools::{mean_ms, p99_ms};

/// Generation and meshing per chunk.
#[derive(Clone, Debug, Serialize)]
pub struct GenerationRow {
    /// Chunks in the block.
    pub chunks: usize,
    /// Of them decided by interval bounds.
    pub decided: usize,
    /// Of them holding lists.
    pub mixed: usize,
    /// Lists generated, ms per chunk.
    pub lists_ms: f64,
    /// Dense 17³ sampling, density per node, ms per chunk.
    pub dense_ms: f64,
    /// Dense 17³ sampling, heights per column, ms per chunk.
    pub dense_columns_ms: f64,
    /// The noise crate's 3D Perlin, ns per sample.
    pub noise_ns: f64,
    /// Meshing from the lists (block extraction + marching cubes), ms per chunk.
    pub mesh_lists_ms: f64,
    /// Dense padded sampling + marching cubes with gradient normals, ms per chunk.
    pub mesh_dense_ms: f64,
    /// Triangles from the lists and from the dense field.
    pub triangles: (usize, usize),
}

/// The flight.
#[derive(Clone, Debug, Serialize)]
pub struct StreamingRow {
    /// View distance (cells).
    pub view: f64,
    /// Detail distance (cells; 0: every chunk at the base level).
    pub detail: f64,
    /// Coarse distance (cells; chunks beyond it at 8³ cells; 0: off).
    pub coarse: f64,
    /// Speed (chunk widths a second).
    pub speed: f64,
    /// Worker threads.
    pub threads: usize,
    /// Frames.
    pub frames: usize,
    /// Main-thread frame, mean and p99 (ms).
    pub frame_mean_ms: f64,
    /// p99.
    pub frame_p99_ms: f64,
    /// [`World::update`] alone, mean and p99 (ms).
    pub update_mean_ms: f64,
    /// p99.
    pub update_p99_ms: f64,
    /// Chunks integrated a second.
    pub generated_per_s: f64,
    /// Chunks meshed a second.
    pub meshed_per_s: f64,
    /// Chunks in view at the end, and of them loaded.
    pub in_view: usize,
    /// Loaded at the end.
    pub loaded: usize,
    /// Chunks waiting for a mesh at the end (loaded but not yet drawn as they are, or changed by
    /// a neighbour's arrival): [`strata_editor::Editor::pending`].
    pub waiting: usize,
}

/// Paging throughput.
#[derive(Clone, Debug, Serialize)]
pub struct PagingRow {
    /// Database.
    pub database: String,
    /// Edited chunks.
    pub chunks: usize,
    /// Written in one transaction, chunks a second.
    pub write_batch_per_s: f64,
    /// Written one transaction each (each durable), chunks a second.
    pub write_each_per_s: f64,
    /// Read back in random order, chunks a second.
    pub read_per_s: f64,
    /// Database bytes per edited chunk (after the batch write).
    pub bytes_per_chunk: f64,
    /// The same after compaction (redb's `compact`, SQLite's `VACUUM`).
    pub compacted_bytes_per_chunk: f64,
    /// What each chunk adds: (file after − empty file) / chunks.
    pub marginal_bytes_per_chunk: f64,
    /// Mean record bytes (the chunk's own encoding).
    pub record_bytes: f64,
}

/// Table 9.
#[derive(Clone, Debug, Serialize)]
pub struct TerrainResults {
    /// Generation.
    pub generation: GenerationRow,
    /// Streaming.
    pub streaming: Vec<StreamingRow>,
    /// Paging.
    pub paging: Vec<PagingRow>,
}

/// Sizes of a run.
#[derive(Clone, Debug, Serialize)]
pub struct TerrainConfig {
    /// Chunk columns along x and z of the generation block.
    pub columns: i32,
    /// Chunks from the lowest to the highest of each column.
    pub layers: (i32, i32),
    /// Flights: view distance (cells), speed (chunks a second), duration (s), detail
    /// distance and coarse distance (cells, 0: off).
    pub flights: Vec<(f64, f64, f64, f64, f64)>,
    /// Edited chunks paged.
    pub paged: usize,
}

impl TerrainConfig {
    /// The full run.
    pub fn full() -> Self {
        TerrainConfig {
            columns: 8,
            layers: (-8, 7),
            flights: vec![
                (256.0, 30.0, 10.0, 0.0, 0.0),
                (256.0, 2.0, 10.0, 40.0, 0.0),
                (256.0, 30.0, 10.0, 0.0, 128.0),
                (256.0, 30.0, 10.0, 0.0, 64.0),
                (256.0, 2.0, 10.0, 40.0, 128.0),
            ],
            paged: 512,
        }
    }

    /// The CI run.
    pub fn quick() -> Self {
        TerrainConfig {
            columns: 2,
            layers: (-3, 2),
            flights: vec![(48.0, 4.0, 1.0, 0.0, 0.0), (48.0, 4.0, 1.0, 16.0, 32.0)],
            paged: 32,
        }
    }
}

fn time_per<T>(count: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let t = Instant::now();
    let out = f();
    (t.elapsed().as_secs_f64() * 1e3 / count.max(1) as f64, out)
}

/// Runs Table 9.
pub fn run(config: &TerrainConfig, progress: &mut dyn FnMut(&str)) -> anyhow::Result<TerrainResults> {
    let recipe = Recipe::with_seed(2021);
    let field = TerrainField::new(&recipe)?;
    progress("table 9: generation");
    let generation = generation(&field, config);
    progress("table 9: streaming");
    let streaming = config.flights.iter().map(|&f| streaming(&recipe, f)).collect::<anyhow::Result<Vec<_>>>()?;
    progress("table 9: paging");
    #[cfg_attr(not(feature = "sqlite"), allow(unused_mut))]
    let mut paging = vec![paging_redb(&field, config.paged)?];
    #[cfg(feature = "sqlite")]
    paging.push(sqlite::paging(&field, config.paged)?);
    Ok(TerrainResults { generation, streaming, paging })
}

fn block_keys(config: &TerrainConfig) -> Vec<ChunkKey> {
    let mut keys = Vec::new();
    for z in 0..config.columns {
        for x in 0..config.columns {
            for y in config.layers.0..=config.layers.1 {
                keys.push(ChunkKey::new(x, y, z));
            }
        }
    }
    keys
}

fn generation(field: &TerrainField, config: &TerrainConfig) -> GenerationRow {
    let keys = block_keys(config);
    let count = keys.len();
    let level = Level::BASE;
    let (lists_ms, generated) =
        time_per(count, || keys.iter().map(|&k| (k, generate_chunk(k, level, field))).collect::<Vec<_>>());
    let decided = generated.iter().filter(|(_, g)| g.decided).count();
    let mixed = generated.iter().filter(|(_, g)| matches!(g.chunk, Some(Chunk::Lists(_)))).count();
    let n = level.cells();
    let m = n + 1;
    let mut dense = vec![0f32; m * m * m];
    let (dense_ms, _) = time_per(count, || {
        for &k in &keys {
            let o = k.origin_grid().as_dvec3();
            for z in 0..m {
                for y in 0..m {
                    for x in 0..m {
                        dense[x + m * (y + m * z)] = field.density(o + DVec3::new(x as f64, y as f64, z as f64)) as f32;
                    }
                }
            }
            std::hint::black_box(&dense);
        }
    });
    let (dense_columns_ms, _) = time_per(count, || {
        for &k in &keys {
            let o = k.origin_grid().as_dvec3();
            for z in 0..m {
                for x in 0..m {
                    let h = field.height(o.x + x as f64, o.z + z as f64);
                    for y in 0..m {
                        dense[x + m * (y + m * z)] =
                            field.density_h(o + DVec3::new(x as f64, y as f64, z as f64), h) as f32;
                    }
                }
            }
            std::hint::black_box(&dense);
        }
    });
    let perlin = noise::Perlin::new(7);
    let samples = 2_000_000;
    let t = Instant::now();
    let mut acc = 0.0;
    for i in 0..samples {
        let f = i as f64 * 0.013;
        acc += perlin.get([f, f * 0.7, f * 0.3]);
    }
    std::hint::black_box(acc);
    let noise_ns = t.elapsed().as_secs_f64() * 1e9 / samples as f64;
    // Meshing: the block's chunks as a volume (the chunks around the block's edge see empty
    // neighbours, in both methods alike).
    let mut volume = Volume::new();
    for (k, g) in generated {
        volume.put_chunk(k, g.chunk, g.materials);
    }
    let mut block = VoxelBlock::default();
    let mut mesh = Mesh::default();
    let mut tris_lists = 0;
    let (mesh_lists_ms, _) = time_per(count, || {
        for &k in &keys {
            volume.extract_block_into(k, &mut block);
            mesh.clear();
            mesh_block(&block, &mut mesh);
            tris_lists += mesh.triangle_count();
        }
    });
    let mut padded = strata_fields::PaddedValues::default();
    let mut tris_dense = 0;
    let (mesh_dense_ms, _) = time_per(count, || {
        for &k in &keys {
            let o = k.origin_grid();
            let values = padded.values_mut();
            let p = strata_fields::N + 3;
            for z in 0..p {
                for x in 0..p {
                    let (gx, gz) = ((o.x + x as i64 - 1) as f64, (o.z + z as i64 - 1) as f64);
                    let h = field.height(gx, gz);
                    for y in 0..p {
                        let q = DVec3::new(gx, (o.y + y as i64 - 1) as f64, gz);
                        values[x + p * (y + p * z)] = field.density_h(q, h) as f32;
                    }
                }
            }
            padded.fill_block(k, &mut block);
            mesh.clear();
            mesh_block(&block, &mut mesh);
            tris_dense += mesh.triangle_count();
        }
    });
    GenerationRow {
        chunks: count,
        decided,
        mixed,
        lists_ms,
        dense_ms,
        dense_columns_ms,
        noise_ns,
        mesh_lists_ms,
        mesh_dense_ms,
        triangles: (tris_lists, tris_dense),
    }
}

/// Handing chunks to the mesher stops this far into a frame.
const MESH_DEADLINE: Duration = Duration::from_millis(6);

fn streaming(
    recipe: &Recipe,
    (view, speed, seconds, detail, coarse): (f64, f64, f64, f64, f64),
) -> anyhow::Result<StreamingRow> {
    // A generating worker per core, below the mesher's priority (as `WorldSettings` defaults).
    let threads = WorldSettings::default().threads;
    let settings = WorldSettings {
        view_distance: view,
        vertical_ratio: 0.5,
        threads,
        frame_budget: Duration::from_millis(2),
        flush_interval: Duration::from_secs(2),
        memory_budget: usize::MAX,
        detail_distance: detail,
        coarse_distance: coarse,
        ..WorldSettings::default()
    };
    // The studio's road: an editor on the world, streamed and meshed by its frames.
    let world = World::in_memory(recipe, settings)?;
    let mut editor = strata_editor::Editor::on_world(world, strata_editor::Material::builtin());
    let frame = Duration::from_secs_f64(1.0 / 60.0);
    let frames = (seconds * 60.0).round() as usize;
    let step = speed * 16.0 / 60.0;
    let mut times = Vec::with_capacity(frames);
    let mut updates = Vec::with_capacity(frames);
    let (mut integrated, mut meshed) = (0usize, 0usize);
    let start = Instant::now();
    let mut viewer = DVec3::new(0.0, 0.0, 0.0);
    for f in 0..frames {
        let t = Instant::now();
        viewer.x = f as f64 * step;
        let r = editor.stream(viewer).expect("the editor is on a world");
        updates.push(t.elapsed());
        integrated += r.integrated;
        // Chunks are handed to the mesher thread nearest the viewer first until the deadline;
        // what it finished is shown.
        let idle = strata_editor::ToolPose::at(viewer, false);
        let report = editor.frame(&idle, MESH_DEADLINE.saturating_sub(t.elapsed()))?;
        meshed += report.remeshed.len();
        let spent = t.elapsed();
        times.push(spent);
        if let Some(rest) = frame.checked_sub(spent) {
            std::thread::sleep(rest);
        }
    }
    let world = editor.world().expect("the editor is on a world");
    let elapsed = start.elapsed().as_secs_f64();
    let in_view = world.chunks_in_view(&[viewer]).len();
    let loaded = world.loaded_count();
    Ok(StreamingRow {
        view,
        detail,
        coarse,
        speed,
        threads,
        frames,
        frame_mean_ms: mean_ms(&times),
        frame_p99_ms: p99_ms(&times),
        update_mean_ms: mean_ms(&updates),
        update_p99_ms: p99_ms(&updates),
        generated_per_s: integrated as f64 / elapsed,
        meshed_per_s: meshed as f64 / elapsed,
        in_view,
        loaded,
        waiting: editor.pending(),
    })
}

/// `count` edited chunks: mixed chunks of the surface with a ball carved out of each.
fn edited_chunks(field: &TerrainField, count: usize) -> Vec<(ChunkKey, StoredChunk)> {
    let mut out = Vec::with_capacity(count);
    let mut x = 0;
    while out.len() < count {
        for y in -4..4 {
            let key = ChunkKey::new(x, y, x / 7);
            let g = generate_chunk(key, Level::BASE, field);
            if !matches!(g.chunk, Some(Chunk::Lists(_))) {
                continue;
            }
            let mut v = Volume::new();
            v.put_chunk(key, g.chunk, g.materials);
            let c = key.origin_grid().as_dvec3() + DVec3::splat(8.0);
            let _ = v.subtract(&Sphere::new(c, 5.0).expect("a valid ball"));
            let (chunk, materials) = v.take_chunk(key);
            out.push((key, StoredChunk { chunk, materials }));
            if out.len() == count {
                break;
            }
        }
        x += 1;
    }
    out
}

fn shuffled<T: Clone>(items: &[T]) -> Vec<T> {
    let mut v = items.to_vec();
    let mut rng = crate::SplitMix64::new(99);
    for i in (1..v.len()).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        v.swap(i, j);
    }
    v
}

fn scratch_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-bench-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}

fn paging_redb(field: &TerrainField, count: usize) -> anyhow::Result<PagingRow> {
    let chunks = edited_chunks(field, count);
    let dir = scratch_dir("redb");
    let mut store = WorldStore::create(&dir.join("batch.redb"), field.recipe())?;
    let empty = store.file_bytes() as f64;
    let writes: Vec<(ChunkKey, Option<StoredChunk>)> = chunks.iter().map(|(k, s)| (*k, Some(s.clone()))).collect();
    let t = Instant::now();
    store.write(&writes)?;
    let write_batch_per_s = count as f64 / t.elapsed().as_secs_f64();
    let bytes_per_chunk = store.file_bytes() as f64 / count as f64;
    let marginal_bytes_per_chunk = (store.file_bytes() as f64 - empty) / count as f64;
    store.compact()?;
    let compacted_bytes_per_chunk = store.file_bytes() as f64 / count as f64;
    let order = shuffled(&chunks);
    let t = Instant::now();
    for (k, s) in &order {
        let back = store.read(*k)?.expect("written");
        anyhow::ensure!(&back == s, "chunk {k:?} read back differently");
    }
    let read_per_s = count as f64 / t.elapsed().as_secs_f64();
    let each = WorldStore::create(&dir.join("each.redb"), field.recipe())?;
    let t = Instant::now();
    for w in &writes {
        each.write(std::slice::from_ref(w))?;
    }
    let write_each_per_s = count as f64 / t.elapsed().as_secs_f64();
    let record_bytes = chunks.iter().map(|(_, s)| encode_record(s).len()).sum::<usize>() as f64 / count as f64;
    drop((store, each));
    let _ = std::fs::remove_dir_all(&dir);
    Ok(PagingRow {
        database: "redb 2 (chosen)".into(),
        chunks: count,
        write_batch_per_s,
        write_each_per_s,
        read_per_s,
        bytes_per_chunk,
        compacted_bytes_per_chunk,
        marginal_bytes_per_chunk,
        record_bytes,
    })
}

#[cfg(feature = "sqlite")]
mod sqlite {
    use super::*;

    /// The same workload on SQLite: one table keyed by the chunk key, WAL, synchronous=FULL.
    pub fn paging(field: &TerrainField, count: usize) -> anyhow::Result<PagingRow> {
        let chunks = edited_chunks(field, count);
        let dir = scratch_dir("sqlite");
        let open = |name: &str| -> anyhow::Result<rusqlite::Connection> {
            let c = rusqlite::Connection::open(dir.join(name))?;
            c.pragma_update(None, "journal_mode", "WAL")?;
            c.pragma_update(None, "synchronous", "FULL")?;
            c.execute(
                "CREATE TABLE chunks (x INTEGER, y INTEGER, z INTEGER, data BLOB NOT NULL, PRIMARY KEY (x, y, z)) WITHOUT ROWID",
                [],
            )?;
            Ok(c)
        };
        let records: Vec<(ChunkKey, Vec<u8>)> = chunks.iter().map(|(k, s)| (*k, encode_record(s))).collect();
        let put = |c: &rusqlite::Connection, (k, r): &(ChunkKey, Vec<u8>)| -> anyhow::Result<()> {
            c.execute(
                "INSERT OR REPLACE INTO chunks VALUES (?1, ?2, ?3, ?4)",
                rusqlite::params![k.0.x, k.0.y, k.0.z, r],
            )?;
            Ok(())
        };
        let mut batch = open("batch.sqlite")?;
        batch.execute_batch("PRAGMA wal_checkpoint(TRUNCATE)")?;
        let empty = std::fs::metadata(dir.join("batch.sqlite"))?.len() as f64;
        let t = Instant::now();
        let txn = batch.transaction()?;
        for r in &records {
            put(&txn, r)?;
        }
        txn.commit()?;
        let write_batch_per_s = count as f64 / t.elapsed().as_secs_f64();
        batch.execute_batch("PRAGMA wal_checkpoint(TRUNCATE)")?;
        let bytes = std::fs::metadata(dir.join("batch.sqlite"))?.len();
        batch.execute_batch("VACUUM")?;
        let compacted = std::fs::metadata(dir.join("batch.sqlite"))?.len();
        let order = shuffled(&records);
        let t = Instant::now();
        for (k, r) in &order {
            let back: Vec<u8> = batch.query_row(
                "SELECT data FROM chunks WHERE x = ?1 AND y = ?2 AND z = ?3",
                rusqlite::params![k.0.x, k.0.y, k.0.z],
                |row| row.get(0),
            )?;
            let stored = strata_terrain::decode_record(&back).map_err(anyhow::Error::msg)?;
            anyhow::ensure!(&encode_record(&stored) == r, "chunk {k:?} read back differently");
        }
        let read_per_s = count as f64 / t.elapsed().as_secs_f64();
        let each = open("each.sqlite")?;
        let t = Instant::now();
        for r in &records {
            put(&each, r)?;
        }
        let write_each_per_s = count as f64 / t.elapsed().as_secs_f64();
        drop((batch, each));
        let _ = std::fs::remove_dir_all(&dir);
        Ok(PagingRow {
            database: "SQLite (rusqlite, bundled)".into(),
            chunks: count,
            write_batch_per_s,
            write_each_per_s,
            read_per_s,
            bytes_per_chunk: bytes as f64 / count as f64,
            compacted_bytes_per_chunk: compacted as f64 / count as f64,
            marginal_bytes_per_chunk: (bytes as f64 - empty) / count as f64,
            record_bytes: records.iter().map(|(_, r)| r.len()).sum::<usize>() as f64 / count as f64,
        })
    }
}

/// Table 9's markdown, appended to `s`.
pub fn markdown(s: &mut String, t: &TerrainResults) {
    use std::fmt::Write;
    let g = &t.generation;
    let _ = writeln!(
        s,
        "\n### Table 9 — terrain\n\nGeneration on one thread of {} chunks of 16³ cells (a block of chunk columns from below the cave floor to the sky; the default recipe, seed 2021: fBm heights with ridges and warp, overhangs, caves): {} decided by interval bounds, {} holding lists. Target: lists ≥ 2× faster than dense sampling.\n",
        g.chunks, g.decided, g.mixed
    );
    let _ = writeln!(s, "| per chunk | ms | lists faster by |");
    let _ = writeln!(s, "|---|---:|---:|");
    let _ = writeln!(s, "| lists (`generate_chunk`) | {:.3} | |", g.lists_ms);
    let _ = writeln!(
        s,
        "| dense 17³, density per node (the seeds' way) | {:.3} | {:.1}× |",
        g.dense_ms,
        g.dense_ms / g.lists_ms
    );
    let _ = writeln!(
        s,
        "| dense 17³, heights per column | {:.3} | {:.1}× |",
        g.dense_columns_ms,
        g.dense_columns_ms / g.lists_ms
    );
    let _ = writeln!(
        s,
        "| noise crate: 3D Perlin {:.1} ns a sample × 4,096 | {:.3} | |",
        g.noise_ns,
        g.noise_ns * 4096.0 / 1e6
    );
    let _ = writeln!(s, "| meshing from the lists (block + marching cubes) | {:.3} | |", g.mesh_lists_ms);
    let _ = writeln!(
        s,
        "| dense padded 19³ sampling + marching cubes | {:.3} | {:.1}× |",
        g.mesh_dense_ms,
        g.mesh_dense_ms / (g.lists_ms + g.mesh_lists_ms)
    );
    let _ = writeln!(s, "\nTriangles: {} from the lists, {} from the dense field.", g.triangles.0, g.triangles.1);
    let f = &t.streaming[0];
    let _ = writeln!(
        s,
        "\nStreaming: flying straight for {} frames (60 a second, real time), view distance {} cells (vertical {}), {} generating worker thread(s); each frame integrates finished chunks (2 ms budget), hands changed chunks to one mesher thread nearest first (snapshots of their neighbourhoods, until 6 ms into the frame) and takes the meshes it finished. With detail, chunks within the detail distance are generated at 32³ cells; with a coarse distance, chunks beyond it at 8³ cells (a chunk's size stays 16 base cells). Target: main-thread frame p99 ≤ 11.1 ms, ≥ 95 % of the view loaded. Waiting: chunks queued for a mesh at the end (not yet drawn as they are).\n",
        f.frames,
        f.view,
        f.view * 0.5,
        f.threads
    );
    let _ = writeln!(
        s,
        "| speed (chunks/s) | detail (cells) | coarse beyond (cells) | frame mean (ms) | frame p99 (ms) | update mean / p99 (ms) | chunks integrated / s | chunks meshed / s | in view at the end | loaded | waiting for a mesh |"
    );
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for f in &t.streaming {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} / {:.2} | {:.0} | {:.0} | {} | {} | {} |",
            f.speed,
            if f.detail > 0.0 { format!("{}", f.detail) } else { "off".into() },
            if f.coarse > 0.0 { format!("{}", f.coarse) } else { "off".into() },
            f.frame_mean_ms,
            f.frame_p99_ms,
            f.update_mean_ms,
            f.update_p99_ms,
            f.generated_per_s,
            f.meshed_per_s,
            f.in_view,
            f.loaded,
            f.waiting
        );
    }
    let _ = writeln!(
        s,
        "\nPaging edited chunks (a ball carved out of each of {} surface chunks):\n",
        t.paging.first().map_or(0, |p| p.chunks)
    );
    let _ = writeln!(
        s,
        "| database | write, one transaction (chunks/s) | write, one durable transaction each (chunks/s) | read, random order (chunks/s) | file bytes per chunk | after compaction | added per chunk | record bytes |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|");
    for p in &t.paging {
        let _ = writeln!(
            s,
            "| {} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} |",
            p.database,
            p.write_batch_per_s,
            p.write_each_per_s,
            p.read_per_s,
            p.bytes_per_chunk,
            p.compacted_bytes_per_chunk,
            p.marginal_bytes_per_chunk,
            p.record_bytes
        );
    }
}
