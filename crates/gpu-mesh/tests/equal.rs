//! The GPU's marching cubes equals the CPU's: for the 256 corner cases of one cell, for random
//! edits (grid-snapped ones too) meshed chunk by chunk across chunk borders, and for blocks of
//! finer levels; positions and triangles bit for bit, normals within 1e-5.
//!
//! Without a GPU adapter (not even lavapipe) these tests skip with a message, unless
//! `STRATA_REQUIRE_GPU=1` is set (CI sets it), which makes a missing adapter a failure.

use glam::{DVec3, Vec3};
use proptest::prelude::*;
use strata_gpu_mesh::{DualJoin, GpuMarcher, GpuMeshError};
use strata_mesh::{Mesh, mesh_block};
use strata_render::Gpu;
use strata_volume::Axis;
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::{ChunkKey, Level, Volume, VoxelBlock};

fn gpu() -> Option<Gpu> {
    Gpu::for_tests("the GPU meshing test")
}

/// Asserts the GPU meshes of `blocks` equal the CPU's, with crossing indices by rank and by
/// whole lookups alike.
fn assert_equal(gpu: &Gpu, marcher: &GpuMarcher, blocks: &[VoxelBlock], what: &str) {
    assert_equal_by(gpu, marcher, blocks, what);
    let mut lookups = GpuMarcher::new(&gpu.device).unwrap();
    lookups.whole_lookups = true;
    assert_equal_by(gpu, &lookups, blocks, &format!("{what}, whole lookups"));
}

fn assert_equal_by(gpu: &Gpu, marcher: &GpuMarcher, blocks: &[VoxelBlock], what: &str) {
    let refs: Vec<&VoxelBlock> = blocks.iter().collect();
    let batch = marcher.mesh(&gpu.device, &gpu.queue, &refs).unwrap();
    let meshes = batch.read_back(&gpu.device, &gpu.queue).unwrap();
    let mut triangles = 0;
    for (k, (block, got)) in blocks.iter().zip(&meshes).enumerate() {
        let mut want = Mesh::default();
        mesh_block(block, &mut want);
        // Crossings and seam points bit for bit; the centroids of triangles split on more than
        // one edge are a sum divided by three, which WGSL computes within 2.5 ulp.
        let exact = block.crossings(Axis::X).len() + block.crossings(Axis::Y).len() + block.crossings(Axis::Z).len();
        assert_eq!(got.positions.len(), want.positions.len(), "{what}: block {k}'s vertex count");
        assert_eq!(got.positions[..exact], want.positions[..exact], "{what}: block {k}'s positions");
        for (a, b) in got.positions[exact..].iter().zip(&want.positions[exact..]) {
            let d = Vec3::from(*a) - Vec3::from(*b);
            assert!(d.length() < 1e-5, "{what}: block {k}: seam vertex {a:?} against {b:?}");
        }
        assert_eq!(got.indices, want.indices, "{what}: block {k}'s triangles");
        assert_eq!(got.materials, want.materials, "{what}: block {k}'s vertex materials");
        for (a, b) in got.normals.iter().zip(&want.normals) {
            let d = Vec3::from(*a) - Vec3::from(*b);
            assert!(d.length() < 1e-5, "{what}: block {k}: normal {a:?} against {b:?}");
        }
        triangles += want.triangle_count();
    }
    assert_eq!(batch.triangle_count(&gpu.device, &gpu.queue).unwrap() as usize, triangles, "{what}");
}

/// A block for each of the 256 corner cases of one cell (nodes 1..=2 on each axis), each
/// crossing's `t` and normal from `crossing(h)` with `h` a hash of its edge.
fn corner_cases(crossing: impl Fn(usize) -> (f32, Vec3) + Copy) -> Vec<VoxelBlock> {
    (0..256usize)
        .map(|case| {
            let inside = move |x: usize, y: usize, z: usize| {
                (1..=2).contains(&x) && (1..=2).contains(&y) && (1..=2).contains(&z) && {
                    let k = (x - 1) | ((y - 1) << 1) | ((z - 1) << 2);
                    (case >> k) & 1 == 1
                }
            };
            VoxelBlock::from_fn(ChunkKey::new(case as i32, 0, 0), Level::BASE, inside, move |axis, lower| {
                crossing(lower[0] + 2 * lower[1] + 3 * lower[2] + axis.index())
            })
        })
        .collect()
}

#[test]
fn all_256_corner_cases_of_one_cell_in_one_batch() {
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    let blocks = corner_cases(|h| {
        let t = 0.3 + 0.1 * (h % 5) as f32;
        (t, Vec3::new(0.3, -0.5, 0.8).normalize())
    });
    assert_equal(&gpu, &marcher, &blocks, "corner cases");
}

#[test]
fn an_empty_batch_and_empty_blocks_make_nothing() {
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    assert_equal(&gpu, &marcher, &[], "no blocks");
    let empty = Volume::new().extract_block(ChunkKey::new(0, 0, 0));
    assert_equal(&gpu, &marcher, &[empty.clone(), empty], "empty blocks");
}

/// Every block with a surface of `v`.
fn surface_blocks(v: &Volume) -> Vec<VoxelBlock> {
    strata_mesh::surface_chunks(v).into_iter().map(|k| v.extract_block(k)).collect()
}

#[test]
fn a_sphere_across_chunk_borders_and_finer_levels() {
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    for level in [Level::BASE, Level::new(1).unwrap(), Level::new(2).unwrap()] {
        let mut v = Volume::with_level(level);
        v.add(&Sphere::new(DVec3::new(16.0, 15.5, 17.25), 11.3).unwrap()).unwrap();
        // Half of it painted material 7: the vertices on the paint's border take either.
        v.paint(&Cuboid::new(DVec3::new(24.0, 15.5, 17.25), DVec3::new(8.0, 20.0, 20.0)).unwrap(), 7).unwrap();
        let blocks = surface_blocks(&v);
        assert!(blocks.len() >= 8, "the sphere spans chunk borders");
        assert!(blocks.iter().any(|b| b.has_materials()), "painted blocks carry materials");
        assert_equal(&gpu, &marcher, &blocks, &format!("sphere at level {}", level.get()));
    }
}

#[test]
fn blocks_with_seams_are_split_as_the_cpu_splits_them() {
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    let (mut split_points, mut centroids) = (0, 0);
    for (seed, finer) in [(0, 1), (1, 2), (2, 1)] {
        let mut v = Volume::new();
        let c = DVec3::new(16.0 + seed as f64 * 1.3, 16.0, 16.0 - seed as f64 * 0.7);
        v.add(&Sphere::new(c, 10.0 + seed as f64).unwrap()).unwrap();
        v.paint(&Cuboid::new(c + DVec3::new(6.0, 0.0, 0.0), DVec3::new(6.0, 20.0, 20.0)).unwrap(), 5).unwrap();
        // Finer chunks beside coarser ones: the coarse blocks facing them have seams.
        let lists: Vec<ChunkKey> =
            v.chunks().filter(|(_, c)| matches!(c, strata_volume::Chunk::Lists(_))).map(|(k, _)| k).collect();
        for key in lists.iter().step_by(2 + seed) {
            v.set_chunk_level(*key, Level::new(finer).unwrap());
        }
        let blocks = surface_blocks(&v);
        let seamed = blocks.iter().filter(|b| !b.seams().is_empty()).count();
        assert!(seamed > 0, "blocks face finer chunks");
        assert_equal(&gpu, &marcher, &blocks, &format!("seams, case {seed}"));
        // The CPU's meshes split triangles there, some on more than one edge (centroids).
        for b in blocks.iter().filter(|b| !b.seams().is_empty()) {
            let mut m = Mesh::default();
            mesh_block(b, &mut m);
            let crossings: usize = Axis::ALL.iter().map(|&a| b.crossings(a).len()).sum();
            let points: usize = b.seams().iter().map(|s| s.points.len()).sum();
            split_points += usize::from(m.positions.len() > crossings);
            centroids += m.positions.len().saturating_sub(crossings + points);
        }
    }
    assert!(split_points > 0 && centroids > 0, "{split_points} blocks split, {centroids} centroids");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Random unions and differences of spheres and boxes, their centres and sizes snapped to
    /// the grid (faces on grid planes, crossings at node ends) or not: marching cubes and dual
    /// contouring's vertices alike.
    #[test]
    fn random_edits_mesh_alike(
        edits in prop::collection::vec((any::<bool>(), any::<bool>(), prop::array::uniform3(2.0f64..40.0), 1.0f64..9.0, any::<bool>()), 1..6),
    ) {
        let Some(gpu) = gpu() else { return Ok(()) };
        let marcher = GpuMarcher::new(&gpu.device).unwrap();
        let mut v = Volume::new();
        for (add, sphere, at, size, snapped) in edits {
            let (c, r) = if snapped { (DVec3::from_array(at).round(), size.round()) } else { (DVec3::from_array(at), size) };
            let r = r.max(1.0);
            let result = if sphere {
                let b = Sphere::new(c, r).unwrap();
                if add { v.add(&b) } else { v.subtract(&b) }
            } else {
                let b = Cuboid::new(c, DVec3::splat(r)).unwrap();
                if add { v.add(&b) } else { v.subtract(&b) }
            };
            result.unwrap();
        }
        // Painted: the vertices take their edges' solid ends' materials.
        v.paint(&Sphere::new(DVec3::new(20.0, 20.0, 20.0), 9.0).unwrap(), 3).unwrap();
        v.paint(&Cuboid::new(DVec3::new(10.0, 12.0, 30.0), DVec3::splat(6.0)).unwrap(), 200).unwrap();
        let blocks = surface_blocks(&v);
        assert_equal(&gpu, &marcher, &blocks, "random edits");
        assert_dual_equal(&gpu, &marcher, &blocks, "random edits, dual contouring");
    }
}

#[test]
fn a_batch_larger_than_the_devices_buffers_is_refused_before_it_is_built() {
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    // Blocks of 64³ cells take 3.3 MB of lookup each: enough of them pass any binding limit.
    let limit = gpu.device.limits().max_storage_buffer_binding_size;
    let v = Volume::with_level(Level::new(2).unwrap());
    let one = v.extract_block(ChunkKey::new(0, 0, 0));
    let count = (limit / (3 * 65 * 65 * 65 * 4) + 2) as usize;
    let blocks: Vec<&VoxelBlock> = std::iter::repeat_n(&one, count).collect();
    match marcher.mesh(&gpu.device, &gpu.queue, &blocks) {
        Err(GpuMeshError::TooLarge(why)) => assert!(why.contains("block data"), "{why}"),
        other => panic!("{count} blocks of 64³: {other:?}"),
    }
}

#[test]
fn meshes_for_drawing_are_placed_as_the_renderer_places_uploaded_ones() {
    use strata_gpu_mesh::DrawPlacement;
    use strata_render::{MeshRef, Placement, placed_vertices};
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(14.0, 17.5, 15.25), 12.3).unwrap()).unwrap();
    v.paint(&Sphere::new(DVec3::new(20.0, 20.0, 20.0), 7.0).unwrap(), 3).unwrap();
    // One finer chunk: the blocks facing it have seams, split with centroids.
    let key = v.chunks().find(|(_, c)| matches!(c, strata_volume::Chunk::Lists(_))).map(|(k, _)| k).unwrap();
    v.set_chunk_level(key, Level::new(1).unwrap());
    let blocks = surface_blocks(&v);
    assert!(blocks.iter().any(|b| !b.seams().is_empty()));
    // A layer turned, scaled and moved far from the origin, as the studio's layers can be.
    let model = glam::Mat4::from_scale_rotation_translation(
        Vec3::splat(0.7),
        glam::Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 0.2),
        Vec3::new(123.4, -56.7, 88.9),
    );
    let placements: Vec<DrawPlacement> = blocks
        .iter()
        .map(|b| DrawPlacement {
            placement: Placement { model, origin: b.key().unwrap().origin_grid().as_dvec3() },
            tint: [1.0, 0.8, 0.6],
        })
        .collect();
    let refs: Vec<&VoxelBlock> = blocks.iter().collect();
    let batch = marcher.mesh_for_drawing(&gpu.device, &gpu.queue, &refs, &placements).unwrap();
    let drawn = batch.read_back(&gpu.device, &gpu.queue).unwrap();
    assert_eq!(drawn.len(), blocks.len());
    // Every vertex at one grid position lands on one world position, whichever block made it.
    let mut seen: std::collections::HashMap<[u64; 3], [u32; 3]> = Default::default();
    let (mut shared, mut painted) = (0, 0);
    for ((block, got), place) in blocks.iter().zip(&drawn).zip(&placements) {
        let mut want = Mesh::default();
        mesh_block(block, &mut want);
        assert_eq!(got.triangles, want.indices, "the triangles the indirect arguments draw");
        let lines: Vec<u32> = want.indices.chunks_exact(3).flat_map(|t| [t[0], t[1], t[1], t[2], t[2], t[0]]).collect();
        assert_eq!(got.edges, lines, "the wireframe's lines");
        let materials: &[strata_render::MaterialBlend] = bytemuck::cast_slice(&want.materials);
        let cpu = MeshRef {
            positions: &want.positions,
            normals: &want.normals,
            materials,
            indices: &want.indices,
            shade: &[],
        };
        let cpu = placed_vertices(&cpu, place.placement, place.tint);
        assert_eq!(got.vertices.len(), cpu.len());
        for (i, (g, c)) in got.vertices.iter().zip(&cpu).enumerate() {
            let d = Vec3::from(g.position) - Vec3::from(c.position);
            assert!(d.length() < 1e-4, "vertex {i}: {:?} against the CPU's {:?}", g.position, c.position);
            assert!((Vec3::from(g.normal) - Vec3::from(c.normal)).length() < 1e-5, "normal {i}");
            assert_eq!((g.color, g.ids, g.weights), (c.color, c.ids, c.weights), "vertex {i}'s tint and material");
            painted += usize::from(g.ids[0] == 3);
            let grid = place.placement.origin + Vec3::from(want.positions[i]).as_dvec3();
            let bits = g.position.map(f32::to_bits);
            if let Some(before) = seen.insert(grid.to_array().map(f64::to_bits), bits) {
                assert_eq!(before, bits, "a vertex two blocks share lands on two world positions (a crack)");
                shared += 1;
            }
        }
    }
    assert!(shared > 50 && painted > 0, "{shared} shared vertices, {painted} painted");
}

/// Dual contouring's vertices placed on the GPU are the CPU's: the same cells and components in
/// the same order, normals and material blends, positions within 1e-4 cells.
fn assert_dual_equal(gpu: &Gpu, marcher: &GpuMarcher, blocks: &[VoxelBlock], what: &str) -> usize {
    let refs: Vec<&VoxelBlock> = blocks.iter().collect();
    let got = marcher.dual_vertices(&gpu.device, &gpu.queue, &refs).unwrap();
    let mut vertices = 0;
    for (k, (block, got)) in blocks.iter().zip(&got).enumerate() {
        let want = strata_mesh::dual_vertices(block);
        assert_eq!(got.len(), want.len(), "{what}: block {k}'s vertex count");
        let cell = block.level().spacing() as f32;
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!((g.cell, g.edges), (w.cell, w.edges), "{what}: block {k} vertex {i}'s cell and component");
            let d = (g.position - w.position).length() / cell;
            assert!(d < 1e-4, "{what}: block {k} vertex {i}: {} against {} ({d} cells)", g.position, w.position);
            assert!((g.normal - w.normal).length() < 1e-4, "{what}: block {k} vertex {i}'s normal");
            assert_eq!(g.material, w.material, "{what}: block {k} vertex {i}'s material blend");
        }
        vertices += want.len();
    }
    vertices
}

#[test]
fn dual_contouring_vertices_equal_the_cpus() {
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    // Every case of one cell (several components in the ambiguous ones), with planes at odd
    // angles so the full eigen-decomposition runs.
    let blocks = corner_cases(|h| {
        let n = [Vec3::X, Vec3::new(0.3, 0.9, -0.2), Vec3::new(-0.5, 0.1, 0.8), Vec3::new(0.6, -0.6, 0.5)][h % 4];
        (0.2 + 0.15 * (h % 5) as f32, n.normalize())
    });
    assert_dual_equal(&gpu, &marcher, &blocks, "corner cases");
    // Boxes (sharp edges and corners: the eigen path), spheres (the parallel-plane path),
    // painted, across chunk borders, at two levels.
    for level in [Level::BASE, Level::new(1).unwrap()] {
        let mut v = Volume::with_level(level);
        v.add(&Sphere::new(DVec3::new(16.0, 15.5, 17.25), 9.3).unwrap()).unwrap();
        v.add(&Cuboid::new(DVec3::new(23.3, 12.1, 20.6), DVec3::new(5.2, 4.4, 6.1)).unwrap()).unwrap();
        v.paint(&Cuboid::new(DVec3::new(24.0, 15.5, 17.25), DVec3::new(8.0, 20.0, 20.0)).unwrap(), 7).unwrap();
        let blocks = surface_blocks(&v);
        let n = assert_dual_equal(&gpu, &marcher, &blocks, &format!("shapes at level {}", level.get()));
        assert!(n > 500, "{n} vertices");
    }
}

/// A dual-contouring mesh's quads (two triangles each, `a b c` and `a c d` for the quad
/// `a b c d`), each as its cycle from its least vertex.
fn quads(indices: &[u32]) -> Vec<[u32; 4]> {
    assert_eq!(indices.len() % 6, 0);
    indices
        .chunks_exact(6)
        .map(|t| {
            let q = [t[0], t[1], t[2], t[5]];
            let least = (0..4).min_by_key(|&i| q[i]).unwrap();
            std::array::from_fn(|i| q[(least + i) % 4])
        })
        .collect()
}

/// Dual contouring with the GPU solving the vertices and the CPU joining the quads: the same
/// quads as the CPU's alone, vertices within 1e-4 cells, through edits that update it
/// incrementally.
#[test]
fn dual_contouring_with_gpu_vertices_joins_the_same_mesh() {
    use strata_mesh::DualCache;
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.0, 15.5, 17.25), 10.3).unwrap()).unwrap();
    v.add(&Cuboid::new(DVec3::new(25.3, 12.1, 20.6), DVec3::new(5.2, 4.4, 6.1)).unwrap()).unwrap();
    let (mut on_cpu, mut on_gpu) = (DualCache::build(&v), DualCache::new());
    let mut solves = 0;
    let mut solver = |blocks: &[&VoxelBlock]| {
        solves += 1;
        Some(marcher.dual_vertices(&gpu.device, &gpu.queue, blocks).unwrap())
    };
    let all: Vec<ChunkKey> = v.chunks().map(|(k, _)| k).collect();
    on_gpu.update_solved(&v, &all, Some(&mut solver));
    let edits = [
        (true, DVec3::new(20.0, 26.0, 18.0), 4.0),
        (false, DVec3::new(10.0, 12.0, 14.0), 5.5),
        (true, DVec3::new(31.0, 9.0, 22.0), 3.0),
    ];
    for step in 0..=edits.len() {
        if step > 0 {
            let (add, c, r) = edits[step - 1];
            let b = Sphere::new(c, r).unwrap();
            let report = if add { v.add(&b) } else { v.subtract(&b) }.unwrap();
            on_cpu.update(&v, &report.changed);
            on_gpu.update_solved(&v, &report.changed, Some(&mut solver));
        }
        let mut keys: Vec<ChunkKey> = on_cpu.iter().map(|(k, _)| k).collect();
        keys.sort();
        let mut gpu_keys: Vec<ChunkKey> = on_gpu.iter().map(|(k, _)| k).collect();
        gpu_keys.sort();
        assert_eq!(keys, gpu_keys, "step {step}: the chunks with triangles");
        for key in keys {
            let (a, b) = (&on_cpu.mesh(key).unwrap().mesh, &on_gpu.mesh(key).unwrap().mesh);
            // The same quads (each split along its flatter diagonal, which may differ where
            // the two are equally flat to within rounding).
            assert_eq!(quads(&a.indices), quads(&b.indices), "step {step}: chunk {key:?}'s quads");
            for (p, q) in a.positions.iter().zip(&b.positions) {
                assert!((Vec3::from(*p) - Vec3::from(*q)).length() < 1e-4, "step {step}: {p:?} against {q:?}");
            }
        }
    }
    assert_eq!(solves, 1 + edits.len(), "every update solved its vertices on the GPU");
}

/// Timestamp queries time a batch's compute pass where the device has them (lavapipe does);
/// a device without them says so.
#[test]
fn the_timer_times_a_batch_where_the_device_has_timestamps() {
    let Some(plain) = gpu() else { return };
    let mut marcher = GpuMarcher::new(&plain.device).unwrap();
    assert!(!marcher.enable_timer(&plain.device, &plain.queue), "no timestamps asked for");
    assert_eq!(marcher.last_gpu_time(&plain.device, &plain.queue), None);
    let gpu = Gpu::headless_with(wgpu::Features::TIMESTAMP_QUERY).unwrap();
    if !gpu.device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
        eprintln!("skipping the timer: {} has no timestamp queries", gpu.info.name);
        return;
    }
    let mut marcher = GpuMarcher::new(&gpu.device).unwrap();
    assert!(marcher.enable_timer(&gpu.device, &gpu.queue));
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.0, 15.5, 17.25), 11.3).unwrap()).unwrap();
    let blocks = surface_blocks(&v);
    let refs: Vec<&VoxelBlock> = blocks.iter().collect();
    marcher.mesh(&gpu.device, &gpu.queue, &refs).unwrap();
    let t = marcher.last_gpu_time(&gpu.device, &gpu.queue).expect("timed");
    assert!(t > std::time::Duration::ZERO && t < std::time::Duration::from_secs(60), "{t:?}");
}

/// The triangles of `mesh` as their corners' positions, each turned to start at its least
/// corner (so a triangle matches whichever corner it was written from).
fn corner_triangles(mesh: &Mesh) -> Vec<[Vec3; 3]> {
    mesh.indices
        .chunks_exact(3)
        .map(|t| {
            let p = [0, 1, 2].map(|i| Vec3::from(mesh.positions[t[i] as usize]));
            let least = (0..3).min_by(|&a, &b| p[a].to_array().partial_cmp(&p[b].to_array()).unwrap()).unwrap();
            [0, 1, 2].map(|i| p[(least + i) % 3])
        })
        .collect()
}

/// Dual contouring wholly on the GPU: vertices and quads give the CPU's mesh chunk by chunk
/// (joined at one level, or across levels where the volume mixes them, as the CPU joins it) —
/// the same triangles within 1e-3 finest cells, but for quads split along their other diagonal
/// where both are equally flat (planar quads on a box's faces: the same corners and area).
/// Returns the polygons that passed through face midpoints (fanned from a centre) and the
/// triangles.
fn assert_dual_mesh_equal(gpu: &Gpu, marcher: &GpuMarcher, v: &Volume, what: &str) -> (usize, usize) {
    let cpu = strata_mesh::DualCache::build(v);
    let polygons = cpu.iter().map(|(_, m)| m.cells.iter().filter(|c| c.x.rem_euclid(32) >= 16).count()).sum();
    let (join, keys) = if v.single_level() {
        (DualJoin::OneLevel, strata_mesh::surface_chunks(v))
    } else {
        // Every chunk around a stored one: each lends its cells, and makes the polygons it owns.
        let mut keys: Vec<ChunkKey> = v.chunks().flat_map(|(k, _)| k.around()).collect();
        keys.sort();
        keys.dedup();
        (DualJoin::AcrossLevels, keys)
    };
    let blocks: Vec<VoxelBlock> = keys.iter().map(|&k| v.extract_block(k)).collect();
    let refs: Vec<&VoxelBlock> = blocks.iter().collect();
    let meshes = marcher.dual_mesh(&gpu.device, &gpu.queue, &refs, &vec![true; refs.len()], join).unwrap();
    let (mut total, mut flipped) = (0, 0);
    let area = |t: &[Vec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).length() * 0.5;
    let tolerance = 1e-3 * if v.single_level() { v.level().spacing() as f32 } else { 0.25 };
    for (key, got) in keys.iter().zip(&meshes) {
        let want = cpu.mesh(*key).map(|m| m.mesh.clone()).unwrap_or_default();
        assert_eq!(got.triangle_count(), want.triangle_count(), "{what}: chunk {key:?}'s triangles");
        let mut left = corner_triangles(&want);
        let mut unmatched = Vec::new();
        for t in corner_triangles(got) {
            let near = |a: &[Vec3; 3]| (0..3).all(|i| (a[i] - t[i]).length() < tolerance);
            match left.iter().position(near) {
                Some(i) => {
                    left.swap_remove(i);
                }
                None => unmatched.push(t),
            }
            total += 1;
        }
        // What differs is quads split along their other diagonal (both equally flat): the same
        // corners and the same area.
        let corners = |ts: &[[Vec3; 3]]| ts.iter().flatten().copied().collect::<Vec<Vec3>>();
        let (mine, theirs) = (corners(&unmatched), corners(&left));
        for p in &mine {
            assert!(theirs.iter().any(|q| (*p - *q).length() < tolerance), "{what}: chunk {key:?}: corner {p}");
        }
        let (a, b): (f32, f32) = (unmatched.iter().map(area).sum(), left.iter().map(area).sum());
        assert!((a - b).abs() <= 1e-3 * b.max(1e-6) + 1e-5, "{what}: chunk {key:?}: re-split area {a} against {b}");
        // And the same orientation: a polygon's vector area does not depend on the diagonal it
        // is split along, and a triangle wound the other way turns it round.
        let vector = |ts: &[[Vec3; 3]]| ts.iter().map(|t| (t[1] - t[0]).cross(t[2] - t[0]) * 0.5).sum::<Vec3>();
        let (va, vb) = (vector(&unmatched), vector(&left));
        assert!(
            (va - vb).length() <= 1e-3 * b.max(1e-6) + 1e-5,
            "{what}: chunk {key:?}: re-split vector area {va} against {vb}"
        );
        flipped += unmatched.len();
    }
    assert!(flipped < total || total == 0, "{what}: none of {total} triangles matched");
    assert_eq!(total, cpu.triangle_count(), "{what}: every chunk the CPU meshes was in the batch");
    (polygons, total)
}

#[test]
fn dual_contouring_quads_on_the_gpu_make_the_cpus_mesh() {
    use strata_volume::brush::{Brush, Capsule};
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    for (level, seed) in [(Level::BASE, 0), (Level::new(1).unwrap(), 1)] {
        let mut v = Volume::with_level(level);
        let c = DVec3::new(16.0 + seed as f64, 15.5, 17.25);
        v.add(&Sphere::new(c, 10.3).unwrap()).unwrap();
        v.add(&Cuboid::new(DVec3::new(25.3, 12.1, 20.6), DVec3::new(5.2, 4.4, 6.1)).unwrap()).unwrap();
        v.subtract(&Sphere::new(c + DVec3::new(3.0, 8.0, -2.0), 4.0).unwrap()).unwrap();
        v.paint(&Cuboid::new(c + DVec3::new(6.0, 0.0, 0.0), DVec3::new(6.0, 20.0, 20.0)).unwrap(), 4).unwrap();
        assert_dual_mesh_equal(&gpu, &marcher, &v, &format!("shapes at level {}", level.get()));
    }
    // A face whose two segments one component runs through on both sides: the inside corners
    // of the face (x = 1: (1, 0, 0) and (1, 1, 1)) joined through the cells on both sides; the
    // quads around its edges pass through the segments' midpoints and are fanned. Small balls on
    // the nodes make exactly these nodes inside, turned to each axis and at chunk borders.
    let mut polygons = 0;
    let pattern = [[0, 0, 0], [0, 0, 1], [0, 1, 1], [1, 0, 0], [1, 1, 1], [2, 0, 0], [2, 0, 1], [2, 1, 1]];
    for (turn, at) in [(0, [5, 5, 5]), (1, [7, 14, 3]), (2, [15, 6, 9]), (0, [14, 15, 15])] {
        let mut v = Volume::new();
        for node in pattern {
            let p = [0, 1, 2].map(|i| node[(i + 3 - turn) % 3] + at[i]);
            v.add(&Sphere::new(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64), 0.42).unwrap()).unwrap();
        }
        polygons += assert_dual_mesh_equal(&gpu, &marcher, &v, &format!("tunnel face, turn {turn} at {at:?}")).0;
    }
    assert!(polygons >= 4, "{polygons} polygons through face midpoints");
    // Small thin shapes around a chunk corner.
    let mut seed = 2027u64;
    let mut next = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for cases in 0..60 {
        let mut v = Volume::new();
        for i in 0..4 {
            let c = DVec3::splat(16.0) + (DVec3::new(next(), next(), next()) - 0.5) * 8.0;
            let r = 0.4 + 2.6 * next();
            let brush: Box<dyn Brush> = match (cases + i) % 2 {
                0 => Box::new(Sphere::new(c, r).unwrap()),
                _ => Box::new(
                    Capsule::new(c, c + DVec3::new(next(), next(), next()) * 6.0 - 3.0, 0.3 + 0.5 * next()).unwrap(),
                ),
            };
            if i == 3 && cases % 2 == 1 { v.subtract(brush.as_ref()) } else { v.add(brush.as_ref()) }.unwrap();
        }
        assert_dual_mesh_equal(&gpu, &marcher, &v, &format!("case {cases}"));
    }
}

/// Dual contouring drawn from the GPU: the triangles the indirect arguments draw are the ones
/// `dual_mesh` reads back, placed in the world as the renderer places a chunk (a turned, scaled
/// and moved layer), with their lines.
#[test]
fn dual_contouring_for_drawing_is_placed_and_drawn_as_read_back() {
    use strata_gpu_mesh::DrawPlacement;
    use strata_render::Placement;
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.0, 15.5, 17.25), 10.3).unwrap()).unwrap();
    v.add(&Cuboid::new(DVec3::new(25.3, 12.1, 20.6), DVec3::new(5.2, 4.4, 6.1)).unwrap()).unwrap();
    v.paint(&Cuboid::new(DVec3::new(22.0, 15.5, 17.25), DVec3::new(6.0, 20.0, 20.0)).unwrap(), 6).unwrap();
    let keys = strata_mesh::surface_chunks(&v);
    let blocks: Vec<VoxelBlock> = keys.iter().map(|&k| v.extract_block(k)).collect();
    let refs: Vec<&VoxelBlock> = blocks.iter().collect();
    // Every other block makes its quads; the others only lend their vertices.
    let meshed: Vec<bool> = (0..refs.len()).map(|i| i % 2 == 0).collect();
    let model = glam::Mat4::from_scale_rotation_translation(
        Vec3::splat(0.7),
        glam::Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 0.2),
        Vec3::new(123.4, -56.7, 88.9),
    );
    let placements: Vec<DrawPlacement> = keys
        .iter()
        .map(|k| DrawPlacement { placement: Placement { model, origin: k.origin_grid().as_dvec3() }, tint: [1.0; 3] })
        .collect();
    let read = marcher.dual_mesh(&gpu.device, &gpu.queue, &refs, &meshed, DualJoin::OneLevel).unwrap();
    let batch = marcher
        .mesh_dual_for_drawing(&gpu.device, &gpu.queue, &refs, &meshed, &placements, DualJoin::OneLevel)
        .unwrap();
    let drawn = batch.read_back(&gpu.device, &gpu.queue).unwrap();
    let mut triangles = 0;
    for (k, (want, got)) in read.iter().zip(&drawn).enumerate() {
        assert_eq!(got.triangles.len(), want.indices.len(), "block {k}");
        if !meshed[k] {
            assert!(got.triangles.is_empty(), "block {k} only lends vertices");
        }
        let origin = keys[k].origin_grid().as_dvec3();
        for (g, w) in got.triangles.iter().zip(&want.indices) {
            let world = model.as_dmat4().transform_point3(origin + Vec3::from(want.positions[*w as usize]).as_dvec3());
            let at = Vec3::from(got.vertices[*g as usize].position).as_dvec3();
            assert!((world - at).length() < 1e-3, "block {k}: {at} against {world}");
            assert_eq!(got.vertices[*g as usize].ids, want.material(*w as usize).ids, "block {k}'s materials");
        }
        let lines: Vec<u32> =
            got.triangles.chunks_exact(3).flat_map(|t| [t[0], t[1], t[1], t[2], t[2], t[0]]).collect();
        assert_eq!(got.edges, lines, "block {k}'s lines");
        triangles += got.triangles.len() / 3;
    }
    assert!(triangles > 500, "{triangles} triangles");
}

/// Dual contouring across levels wholly on the GPU: chunks of levels 0, 1 and 2 side by side
/// give the CPU's mesh chunk by chunk (polygons of the finest edges, triangles where a coarser
/// cell holds two cells, finer edges inside coarser faces taking their segment's component):
/// painted shapes across raised chunks, the issue-28 scene (a coarse cell of two components
/// beside a finer chunk), and random edits and level maps on and off the grid.
#[test]
fn dual_contouring_across_levels_on_the_gpu_makes_the_cpus_mesh() {
    let Some(gpu) = gpu() else { return };
    let marcher = GpuMarcher::new(&gpu.device).unwrap();
    let level = |l: i8| Level::new(l).unwrap();
    let mut v = Volume::new();
    let c = DVec3::new(16.0, 15.5, 17.25);
    v.add(&Sphere::new(c, 10.3).unwrap()).unwrap();
    v.add(&Cuboid::new(DVec3::new(25.3, 12.1, 20.6), DVec3::new(5.2, 4.4, 6.1)).unwrap()).unwrap();
    v.subtract(&Sphere::new(c + DVec3::new(3.0, 8.0, -2.0), 4.0).unwrap()).unwrap();
    v.paint(&Cuboid::new(c + DVec3::new(6.0, 0.0, 0.0), DVec3::new(6.0, 20.0, 20.0)).unwrap(), 4).unwrap();
    v.set_chunk_level(ChunkKey::new(1, 0, 1), level(1));
    v.set_chunk_level(ChunkKey::new(0, 1, 1), level(2));
    let (_, triangles) = assert_dual_mesh_equal(&gpu, &marcher, &v, "painted shapes at levels 0, 1 and 2");
    assert!(triangles > 2000, "{triangles} triangles");
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(6.0, 15.0, 15.75), 4.5).unwrap()).unwrap();
    v.subtract(&Sphere::new(DVec3::new(6.75, 14.0, 18.25), 3.75).unwrap()).unwrap();
    v.set_chunk_level(ChunkKey::new(0, 0, 1), level(1));
    assert_dual_mesh_equal(&gpu, &marcher, &v, "a coarse cell of two components beside a finer chunk");
    // Random scenes around the chunk corner at (16, 16, 16), the 2×2×2 chunks there at random
    // levels; centres and sizes snapped to level-0 nodes, half cells, quarter cells or not.
    let mut seed = 3301u64;
    let mut next = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut triangles = 0;
    for case in 0..24 {
        let mut v = Volume::new();
        for i in 0..5 {
            let q = [0.0, 1.0, 0.5, 0.25][(next() * 4.0) as usize];
            let snap = |x: f64| if q > 0.0 { ((x / q).round() * q).max(q) } else { x };
            let c = DVec3::new(snap(9.0 + 14.0 * next()), snap(9.0 + 14.0 * next()), snap(9.0 + 14.0 * next()));
            let size = DVec3::new(snap(0.6 + 5.0 * next()), snap(0.6 + 5.0 * next()), snap(0.6 + 5.0 * next()));
            let edit = if i % 2 == 0 {
                v.add(&Sphere::new(c, size.x + 2.0).unwrap())
            } else if next() < 0.5 {
                v.subtract(&Sphere::new(c, size.x).unwrap())
            } else {
                v.add(&Cuboid::new(c, size).unwrap())
            };
            edit.unwrap();
            let key = ChunkKey::new((next() * 2.0) as i32, (next() * 2.0) as i32, (next() * 2.0) as i32);
            v.set_chunk_level(key, level((next() * 4.0) as i8 - 1));
        }
        if v.single_level() {
            v.set_chunk_level(ChunkKey::new(1, 1, 1), level(1));
        }
        triangles += assert_dual_mesh_equal(&gpu, &marcher, &v, &format!("random case {case}")).1;
    }
    assert!(triangles > 10_000, "{triangles} triangles");
}
