//! `strata-bench gpu`: marching cubes on the GPU (`strata-gpu-mesh`) against the CPU's, per
//! frame of the Table 2 workload and for a full remesh of the bunny.
//!
//! A frame: one instruction of the Table 1 workload at the radius, then the voxel blocks of
//! every chunk whose mesh depends on a changed chunk (extracted on the CPU, both sides), meshed
//! by the CPU (`mesh_block` per block, on all cores) or by the GPU (one batch: upload, four
//! dispatches, waiting for it to finish; nothing read back), and by the GPU as the viewport's GPU
//! meshing does it (the same, plus the renderer's vertices placed in the world, the indirect
//! draw arguments and the wireframe's lines: three more dispatches). Times
//! are wall-clock from the first block to the end (the GPU's wait included), and, where the
//! device has timestamp queries, the GPU's own time for the batch's compute pass, after a warm-up of
//! ten frames; medians and 95th percentiles over the frames. Dual contouring's frame is the
//! whole cache update (blocks extracted, vertices solved, quads joined) by the CPU alone, and
//! with the vertices solved on the GPU and read back (`DualCache::update_solved`), and wholly on
//! the GPU (`GpuMarcher::dual_mesh`: the changed chunks' quads and their neighbours' vertices in
//! one batch, read back). Then the same across levels: the canvas's stored chunks raised to
//! level 1 in a checkerboard and more instructions applied, the CPU's cache (joining across
//! levels) against the GPU (`DualJoin::AcrossLevels`: the chunks within two of a change and the
//! 26 around each that lend their cells, one batch per 256 meshed chunks, read back).

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use rayon::prelude::*;
use strata_mesh::{Mesh, mesh_block};
use strata_volume::{EditSettings, Volume, VoxelBlock};

/// Median and 95th percentile of `d` (ms).
fn quantiles(d: &mut [Duration]) -> (f64, f64) {
    d.sort();
    let at = |q: f64| d[((d.len() - 1) as f64 * q).round() as usize].as_secs_f64() * 1e3;
    (at(0.5), at(0.95))
}

/// Meshes `blocks` on the GPU and waits for it.
fn gpu_mesh(gpu: &strata_render::Gpu, marcher: &strata_gpu_mesh::GpuMarcher, blocks: &[&VoxelBlock]) -> Result<()> {
    marcher.mesh(&gpu.device, &gpu.queue, blocks)?;
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).context("waiting for the GPU")?;
    Ok(())
}

/// Meshes `blocks` on the GPU for drawing (the viewport's road: the renderer's vertices placed
/// in the world, indirect draw arguments and the wireframe's lines too) and waits for it.
fn gpu_mesh_for_drawing(
    gpu: &strata_render::Gpu,
    marcher: &strata_gpu_mesh::GpuMarcher,
    blocks: &[&VoxelBlock],
) -> Result<()> {
    let placements: Vec<strata_gpu_mesh::DrawPlacement> = blocks
        .iter()
        .map(|b| strata_gpu_mesh::DrawPlacement {
            placement: strata_render::Placement {
                model: glam::Mat4::IDENTITY,
                origin: b.key().map_or(glam::DVec3::ZERO, |k| k.origin_grid().as_dvec3()),
            },
            tint: [1.0; 3],
        })
        .collect();
    marcher.mesh_for_drawing(&gpu.device, &gpu.queue, blocks, &placements)?;
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).context("waiting for the GPU")?;
    Ok(())
}

fn cpu_mesh(blocks: &[&VoxelBlock]) -> usize {
    blocks
        .par_iter()
        .map(|b| {
            let mut m = Mesh::default();
            mesh_block(b, &mut m);
            m.triangle_count()
        })
        .sum()
}

/// The report, as markdown.
pub fn run(frames: usize, mixed_frames: usize, radius: f64, bunny_cells: u32) -> Result<String> {
    let gpu =
        strata_render::Gpu::headless_with(wgpu::Features::TIMESTAMP_QUERY).context("a GPU adapter (or lavapipe)")?;
    let mut marcher = strata_gpu_mesh::GpuMarcher::new(&gpu.device)?;
    let timed = marcher.enable_timer(&gpu.device, &gpu.queue);
    let mut out = format!(
        "Adapter: {} ({:?}){}\n\n",
        gpu.info.name,
        gpu.info.backend,
        if timed { ", compute passes timed by timestamp queries" } else { ", no timestamp queries" }
    );
    // Table 2's frames.
    let warm = 10;
    let ins = crate::table1_instructions(frames + warm, radius, 2021);
    let mut volume = Volume::new();
    let settings = EditSettings { parallel: true, ..Default::default() };
    let (mut cpu, mut gpus, mut draws, mut chunks) = (Vec::new(), Vec::new(), Vec::new(), 0usize);
    // The GPU's own time for the passes (timestamps), plain and for drawing.
    let (mut pass_times, mut draw_pass_times) = (Vec::new(), Vec::new());
    // Dual contouring's frame: the CPU's cache, and one whose vertices the GPU solves.
    let (mut dual_cpu, mut dual_gpu) = (strata_mesh::DualCache::new(), strata_mesh::DualCache::new());
    let (mut dc_cpu, mut dc_gpu, mut dc_whole) = (Vec::new(), Vec::new(), Vec::new());
    let mut solver = |blocks: &[&VoxelBlock]| marcher.dual_vertices(&gpu.device, &gpu.queue, blocks).ok();
    for (i, instruction) in ins.iter().enumerate() {
        let report = volume.apply(instruction.op, &instruction.brush(), &settings)?;
        let keys = strata_mesh::MeshCache::dependents(&report.changed);
        let blocks: Vec<VoxelBlock> = keys.par_iter().map(|&k| volume.extract_block(k)).collect();
        // (A chunk whose block has seams is meshed on the CPU either way; this workload has one
        // level, so none has.)
        let refs: Vec<&VoxelBlock> = blocks.iter().filter(|b| b.seams().is_empty()).collect();
        let t = Instant::now();
        cpu_mesh(&refs);
        let c = t.elapsed();
        let t = Instant::now();
        gpu_mesh(&gpu, &marcher, &refs)?;
        let g = t.elapsed();
        let gt = marcher.last_gpu_time(&gpu.device, &gpu.queue);
        let t = Instant::now();
        gpu_mesh_for_drawing(&gpu, &marcher, &refs)?;
        let d = t.elapsed();
        let dt = marcher.last_gpu_time(&gpu.device, &gpu.queue);
        if i >= warm {
            pass_times.extend(gt);
            draw_pass_times.extend(dt);
        }
        let t = Instant::now();
        dual_cpu.update(&volume, &report.changed);
        let dc = t.elapsed();
        let t = Instant::now();
        dual_gpu.update_solved(&volume, &report.changed, Some(&mut solver));
        let dg = t.elapsed();
        // Wholly on the GPU: the chunks whose quads change, and the chunks before them that lend
        // their cells' vertices, in one batch; read back.
        let t = Instant::now();
        let meshed: std::collections::BTreeSet<strata_volume::ChunkKey> =
            strata_mesh::dual_mesh_keys(&report.changed).into_iter().collect();
        let mut batch: std::collections::BTreeSet<strata_volume::ChunkKey> = meshed.clone();
        for k in &meshed {
            batch.extend(strata_mesh::MeshCache::dependents(&[*k]));
        }
        let keys: Vec<strata_volume::ChunkKey> = batch.into_iter().collect();
        let dual_blocks: Vec<VoxelBlock> = keys.par_iter().map(|&k| volume.extract_block(k)).collect();
        let dual_refs: Vec<&VoxelBlock> = dual_blocks.iter().collect();
        let flags: Vec<bool> = keys.iter().map(|k| meshed.contains(k)).collect();
        marcher.dual_mesh(&gpu.device, &gpu.queue, &dual_refs, &flags, strata_gpu_mesh::DualJoin::OneLevel)?;
        let dw = t.elapsed();
        if i >= warm {
            dc_whole.push(dw);
            dc_cpu.push(dc);
            dc_gpu.push(dg);
            cpu.push(c);
            gpus.push(g);
            draws.push(d);
            chunks += refs.len();
        }
    }
    let per = chunks as f64 / frames as f64;
    let ((cm, cp), (gm, gp), (dm, dp)) = (quantiles(&mut cpu), quantiles(&mut gpus), quantiles(&mut draws));
    let pass_row = |d: &mut Vec<Duration>| {
        if d.is_empty() {
            " n/a | n/a |".to_string()
        } else {
            let (m, p) = quantiles(d);
            format!(" {m:.2} | {p:.2} |")
        }
    };
    let (gpu_pass, draw_pass) = (pass_row(&mut pass_times), pass_row(&mut draw_pass_times));
    out += &format!(
        "Table 2 workload, radius {radius}, {frames} frames after {warm} of warm-up, {per:.1} chunks meshed a frame:\n\n"
    );
    out += "| mesher | median (ms) | p95 (ms) | chunks per ms (median) | GPU pass median (ms, timestamps) | GPU pass p95 (ms) |\n|---|---:|---:|---:|---:|---:|\n";
    out += &format!("| CPU marching cubes, all cores | {cm:.2} | {cp:.2} | {:.1} | | |\n", per / cm.max(1e-9));
    out += &format!("| GPU marching cubes | {gm:.2} | {gp:.2} | {:.1} |{gpu_pass}\n", per / gm.max(1e-9));
    out += &format!(
        "| GPU marching cubes for drawing (world vertices, indirect arguments, edges) | {dm:.2} | {dp:.2} | {:.1} |{draw_pass}\n\n",
        per / dm.max(1e-9)
    );
    let ((cm, cp), (gm, gp), (wm, wp)) = (quantiles(&mut dc_cpu), quantiles(&mut dc_gpu), quantiles(&mut dc_whole));
    out += "Dual contouring's frame (the cache's update: blocks, vertices, quads, on the same frames):\n\n";
    out += "| dual contouring | median (ms) | p95 (ms) |\n|---|---:|---:|\n";
    out += &format!("| CPU, all cores | {cm:.2} | {cp:.2} |\n");
    out += &format!("| vertices on the GPU (read back), quads on the CPU | {gm:.2} | {gp:.2} |\n");
    out += &format!("| vertices and quads on the GPU (read back) | {wm:.2} | {wp:.2} |\n\n");
    out += &across_levels(&gpu, &marcher, &mut volume, mixed_frames, radius)?;
    // The bunny, every surface chunk at once.
    let path = crate::suite::repo_root().join("tests/data/bunny.ply");
    let m = strata_mesh::import::load_mesh(&path)?;
    let (lo, hi) = m.bounds().context("the bunny has vertices")?;
    let scale = bunny_cells as f64 / (hi - lo).max_element();
    let verts: Vec<glam::DVec3> = m.vertices.iter().map(|&v| (v - lo) * scale + glam::DVec3::splat(2.0)).collect();
    let brush = strata_volume::brush::MeshBrush::new(&verts, &m.triangles, strata_volume::brush::MeshRule::EvenOdd)?;
    let mut bunny = Volume::new();
    bunny.apply(strata_volume::CsgOp::Add, &brush, &settings)?;
    let keys = strata_mesh::surface_chunks(&bunny);
    let blocks: Vec<VoxelBlock> = keys.par_iter().map(|&k| bunny.extract_block(k)).collect();
    let refs: Vec<&VoxelBlock> = blocks.iter().collect();
    let (mut cpu, mut gpus) = (Vec::new(), Vec::new());
    let mut triangles = 0;
    for _ in 0..7 {
        let t = Instant::now();
        triangles = cpu_mesh(&refs);
        cpu.push(t.elapsed());
        let t = Instant::now();
        // (Batches of 1,000 blocks: 60 MB of block data for 16³ blocks, within every device's
        // buffer limits.)
        for batch in refs.chunks(1000) {
            gpu_mesh(&gpu, &marcher, batch)?;
        }
        gpus.push(t.elapsed());
    }
    let ((cm, _), (gm, _)) = (quantiles(&mut cpu), quantiles(&mut gpus));
    out += &format!(
        "Full remesh of the bunny at {bunny_cells} cells ({} chunks, {triangles} triangles; blocks extracted beforehand), median of 7:\n\n",
        refs.len()
    );
    out += "| mesher | ms |\n|---|---:|\n";
    out += &format!("| CPU marching cubes, all cores | {cm:.1} |\n| GPU marching cubes | {gm:.1} |\n");
    Ok(out)
}

/// Dual contouring's frame across levels: `volume`'s stored chunks raised to level 1 in a
/// checkerboard, then `frames` instructions (after three of warm-up), each followed by the CPU
/// cache's update and by the GPU's polygons of the same chunks (read back); markdown.
fn across_levels(
    gpu: &strata_render::Gpu,
    marcher: &strata_gpu_mesh::GpuMarcher,
    volume: &mut Volume,
    frames: usize,
    radius: f64,
) -> Result<String> {
    use std::collections::BTreeSet;
    use strata_volume::{ChunkKey, Level};
    let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
    for k in stored.iter().filter(|k| (k.0.x + k.0.y + k.0.z).rem_euclid(2) == 0) {
        volume.set_chunk_level(*k, Level::new(1).expect("level 1 exists"));
    }
    let around = strata_mesh::MeshCache::around;
    let warm = 3;
    let settings = EditSettings { parallel: true, ..Default::default() };
    let ins = crate::table1_instructions(frames + warm, radius, 2027);
    let mut cache = strata_mesh::DualCache::build(volume);
    let (mut cpu, mut gpus, mut meshed_total, mut blocks_total, mut triangles) = (Vec::new(), Vec::new(), 0, 0, 0);
    for (i, instruction) in ins.iter().enumerate() {
        let report = volume.apply(instruction.op, &instruction.brush(), &settings)?;
        let t = Instant::now();
        cache.update(volume, &report.changed);
        let c = t.elapsed();
        let t = Instant::now();
        let meshed = around(&around(&report.changed));
        let mut made = 0;
        let (mut frame_meshed, mut frame_blocks) = (0, 0);
        for part in meshed.chunks(256) {
            let keys = around(part);
            let blocks: Vec<(ChunkKey, VoxelBlock)> = keys
                .par_iter()
                .map(|&k| (k, volume.extract_block(k)))
                .filter(|(_, b)| strata_volume::Axis::ALL.iter().any(|&a| !b.crossings(a).is_empty()))
                .collect();
            let wanted: BTreeSet<ChunkKey> = part.iter().copied().collect();
            let refs: Vec<&VoxelBlock> = blocks.iter().map(|(_, b)| b).collect();
            let flags: Vec<bool> = blocks.iter().map(|(k, _)| wanted.contains(k)).collect();
            let meshes =
                marcher.dual_mesh(&gpu.device, &gpu.queue, &refs, &flags, strata_gpu_mesh::DualJoin::AcrossLevels)?;
            made += meshes.iter().map(Mesh::triangle_count).sum::<usize>();
            frame_meshed += flags.iter().filter(|f| **f).count();
            frame_blocks += refs.len();
        }
        let g = t.elapsed();
        if i >= warm {
            cpu.push(c);
            gpus.push(g);
            meshed_total += frame_meshed;
            blocks_total += frame_blocks;
            triangles += made;
        }
    }
    let ((cm, cp), (gm, gp)) = (quantiles(&mut cpu), quantiles(&mut gpus));
    let per = |n: usize| n as f64 / frames.max(1) as f64;
    let mut out = format!(
        "Dual contouring's frame across levels (the canvas's stored chunks raised to level 1 in a checkerboard, {frames} more instructions after {warm} of warm-up; the GPU meshed {:.0} chunks a frame from batches holding {:.0} blocks, {:.0} triangles):\n\n",
        per(meshed_total),
        per(blocks_total),
        per(triangles)
    );
    out += "| dual contouring across levels | median (ms) | p95 (ms) |\n|---|---:|---:|\n";
    out += &format!("| CPU, all cores (the cache's update) | {cm:.2} | {cp:.2} |\n");
    out += &format!("| vertices and quads on the GPU (blocks extracted, read back) | {gm:.2} | {gp:.2} |\n\n");
    Ok(out)
}
