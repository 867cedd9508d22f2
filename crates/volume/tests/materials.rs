//! Materials inside the volume: checked against a dense reference of node materials, through
//! tools, paint, undo and redo, level changes and serialisation.

use glam::{DVec3, I64Vec3, IVec3};
use proptest::prelude::*;
use strata_volume::brush::{Brush, Cuboid, Sphere};
use strata_volume::tools::{self, Dab, Smoothing};
use strata_volume::{Chunk, ChunkKey, CsgOp, EditReport, EditSettings, Level, Volume, brush_contains_node};

/// Side of the reference region in nodes (a little over two chunks).
const SIDE: i64 = 40;

fn settings(material: u8) -> EditSettings {
    EditSettings { parallel: false, material, ..Default::default() }
}

fn chunks_of(v: &Volume) -> Vec<(ChunkKey, Chunk)> {
    let mut c: Vec<(ChunkKey, Chunk)> = v.chunks().map(|(k, c)| (k, c.clone())).collect();
    c.sort_by_key(|(k, _)| k.0.to_array());
    c
}

/// Applies an edit, then checks the invariants and that undo and redo give back both volumes
/// bit for bit (materials included).
fn checked(v: &mut Volume, edit: impl FnOnce(&mut Volume) -> EditReport) {
    let before = v.clone();
    let report = edit(v);
    v.check_invariants().unwrap();
    let after = v.clone();
    let redo = v.restore(report.undo);
    assert_eq!(*v, before, "undo restores the volume, materials included");
    v.restore(redo);
    assert_eq!(*v, after, "redo restores the edit");
}

#[derive(Clone, Debug)]
struct Op {
    op: CsgOp,
    center: DVec3,
    size: f64,
    cube: bool,
    material: u8,
}

fn op() -> impl Strategy<Value = Op> {
    (
        prop_oneof![4 => Just(CsgOp::Add), 2 => Just(CsgOp::Subtract), 1 => Just(CsgOp::Intersect)],
        (4.0..36.0f64, 4.0..36.0f64, 4.0..36.0f64),
        2.0..11.0f64,
        any::<bool>(),
        0u8..6,
        any::<bool>(),
    )
        .prop_map(|(op, c, size, cube, material, on_grid)| {
            // Half the shapes on the grid: centres on nodes, faces and poles exactly on nodes.
            let snap = |v: f64| if on_grid { v.round() } else { v };
            Op { op, center: DVec3::new(snap(c.0), snap(c.1), snap(c.2)), size: snap(size), cube, material }
        })
}

fn brush(o: &Op) -> Box<dyn Brush> {
    if o.cube {
        Box::new(Cuboid::new(o.center, DVec3::splat(o.size)).unwrap())
    } else {
        Box::new(Sphere::new(o.center, o.size).unwrap())
    }
}

fn index(n: I64Vec3) -> usize {
    (n.x + SIDE * (n.y + SIDE * n.z)) as usize
}

fn nodes() -> impl Iterator<Item = I64Vec3> {
    (0..SIDE).flat_map(|z| (0..SIDE).flat_map(move |y| (0..SIDE).map(move |x| I64Vec3::new(x, y, z))))
}

/// What `o` (its brush `b`) does to the dense reference of node materials: an add gives its
/// material to the nodes it makes solid, a subtraction or intersection empties nodes and keeps
/// the survivors' materials.
fn apply_to_reference(reference: &mut [Option<u8>], o: &Op, b: &dyn Brush) {
    for n in nodes() {
        let inside = brush_contains_node(b, n, Level::BASE);
        let r = &mut reference[index(n)];
        *r = match (o.op, inside) {
            (CsgOp::Add, true) => Some(r.unwrap_or(o.material)),
            (CsgOp::Subtract, true) | (CsgOp::Intersect, false) => None,
            _ => *r,
        };
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]

    /// An add gives its material to the nodes it makes solid and no other; subtraction and
    /// intersection leave every surviving node's material as it was.
    #[test]
    fn csg_materials_equal_a_dense_reference(ops in prop::collection::vec(op(), 1..10)) {
        let mut v = Volume::new();
        let mut reference: Vec<Option<u8>> = vec![None; (SIDE * SIDE * SIDE) as usize];
        for o in &ops {
            let b = brush(o);
            checked(&mut v, |v| v.apply(o.op, b.as_ref(), &settings(o.material)).unwrap());
            apply_to_reference(&mut reference, o, b.as_ref());
        }
        for n in nodes() {
            prop_assert_eq!(v.node_material_at(n), reference[index(n)], "node {}", n);
        }
    }

    /// Tools and paint keep every invariant, undo and redo restore materials bit for bit,
    /// painting never changes a node state or a crossing, and the volume survives serialisation.
    #[test]
    fn tools_and_paint_keep_materials_consistent(
        steps in prop::collection::vec((0u8..6, (8.0..32.0f64, 8.0..32.0f64, 8.0..32.0f64), 2.0..8.0f64, 0u8..5, 0.2..1.0f64), 1..10)
    ) {
        let mut v = Volume::new();
        v.apply(CsgOp::Add, &Sphere::new(DVec3::splat(20.0), 11.0).unwrap(), &settings(1)).unwrap();
        for (kind, c, r, material, strength) in steps {
            let center = DVec3::new(c.0, c.1, c.2);
            let dab = Dab { material, ..Dab::new(center, r, strength).unwrap() };
            match kind {
                0 => checked(&mut v, |v| v.apply(CsgOp::Add, &Sphere::new(center, r).unwrap(), &settings(material)).unwrap()),
                1 => checked(&mut v, |v| tools::clay(v, &dab, 1.0, false).unwrap()),
                2 => checked(&mut v, |v| tools::smooth(v, &dab, Smoothing::Laplacian, 2).unwrap()),
                3 => checked(&mut v, |v| tools::grab(v, &dab, DVec3::new(1.5, -0.5, 1.0)).unwrap()),
                4 => checked(&mut v, |v| tools::inflate(v, &dab, 0.8).unwrap()),
                _ => {
                    let shape = chunks_of(&v);
                    checked(&mut v, |v| tools::paint(v, &dab).unwrap());
                    prop_assert!(chunks_of(&v) == shape, "painting changed node states or crossings");
                }
            }
        }
        let bytes = postcard::to_allocvec(&v).unwrap();
        let back: Volume = postcard::from_bytes(&bytes).unwrap();
        prop_assert_eq!(back, v);
    }
}

#[test]
fn paint_is_hard_at_full_weight_and_dithered_below_it() {
    let mut v = Volume::new();
    v.add(&Cuboid::new(DVec3::splat(24.0), DVec3::splat(14.0)).unwrap()).unwrap();
    let shape = chunks_of(&v);
    let ball = Sphere::new(DVec3::splat(24.0), 8.0).unwrap();
    let report = v.paint_where(&ball, 3, &|_| 0.5).unwrap();
    v.check_invariants().unwrap();
    assert!(!report.changed.is_empty());
    let inside: Vec<I64Vec3> = nodes_in(&ball);
    let painted = inside.iter().filter(|&&n| v.node_material_at(n) == Some(3)).count();
    let share = painted as f64 / inside.len() as f64;
    assert!((0.4..0.6).contains(&share), "weight 0.5 paints about half ({share})");
    // The same dab again paints the same nodes: nothing changes.
    let again = v.paint_where(&ball, 3, &|_| 0.5).unwrap();
    assert!(again.changed.is_empty() && again.undo.is_empty());
    v.paint(&ball, 3).unwrap();
    assert!(inside.iter().all(|&n| v.node_material_at(n) == Some(3)));
    assert_eq!(chunks_of(&v), shape, "paint never changes the shape");
    // Nodes outside the ball keep material 0.
    assert_eq!(v.node_material_at(I64Vec3::new(11, 11, 11)), Some(0));
    // Material 0 painted back everywhere stores nothing.
    v.paint(&Cuboid::new(DVec3::splat(24.0), DVec3::splat(20.0)).unwrap(), 0).unwrap();
    assert!(!v.has_materials());
    assert_eq!(v.memory().materials, 0);
}

fn nodes_in(b: &dyn Brush) -> Vec<I64Vec3> {
    let bounds = b.bounds();
    let (lo, hi) = (bounds.min.ceil().as_i64vec3(), bounds.max.floor().as_i64vec3());
    let mut out = Vec::new();
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let n = I64Vec3::new(x, y, z);
                if brush_contains_node(b, n, Level::BASE) {
                    out.push(n);
                }
            }
        }
    }
    out
}

#[test]
fn smoothing_does_not_carry_a_material_across_a_boundary_it_did_not_touch() {
    let mut v = Volume::new();
    v.apply(CsgOp::Add, &Cuboid::new(DVec3::new(12.0, 20.0, 20.0), DVec3::new(10.0, 8.0, 8.0)).unwrap(), &settings(1))
        .unwrap();
    v.apply(CsgOp::Add, &Cuboid::new(DVec3::new(32.0, 20.0, 20.0), DVec3::new(10.0, 8.0, 8.0)).unwrap(), &settings(2))
        .unwrap();
    let of = |v: &Volume, id: u8| -> Vec<I64Vec3> {
        (0..48)
            .flat_map(|z| (0..48).flat_map(move |y| (0..48).map(move |x| I64Vec3::new(x, y, z))))
            .filter(|&n| v.node_material_at(n) == Some(id))
            .collect()
    };
    let twos = of(&v, 2);
    // Round the far corner of the material-1 box: well away from the boundary at x = 22.
    let dab = Dab::new(DVec3::new(4.0, 28.0, 28.0), 4.0, 1.0).unwrap();
    let r = tools::smooth(&mut v, &dab, Smoothing::Laplacian, 3).unwrap();
    assert!(!r.changed.is_empty());
    tools::inflate(&mut v, &dab, 1.0).unwrap();
    v.check_invariants().unwrap();
    assert_eq!(of(&v, 2), twos, "material 2 neither spread nor shrank");
    assert!(of(&v, 0).is_empty(), "every new node took its neighbours' material 1");
}

#[test]
fn materials_survive_level_changes_and_level_of_detail() {
    let mut v = Volume::new();
    v.apply(CsgOp::Add, &Sphere::new(DVec3::new(16.0, 16.0, 16.0), 12.0).unwrap(), &settings(1)).unwrap();
    v.apply(CsgOp::Add, &Cuboid::new(DVec3::new(22.0, 10.0, 16.0), DVec3::new(5.0, 5.0, 9.0)).unwrap(), &settings(4))
        .unwrap();
    v.paint(&Sphere::new(DVec3::new(8.0, 16.0, 16.0), 6.0).unwrap(), 2).unwrap();
    let original = v.clone();
    let key = ChunkKey::new(0, 0, 0);
    let fine = Level::new(2).unwrap();
    let raised = v.set_chunk_level(key, fine);
    v.check_invariants().unwrap();
    // A fine node on a coarse node keeps its material.
    let n = fine.cells() / Level::BASE.cells();
    for (x, y, z) in [(3usize, 9usize, 12usize), (12, 12, 12), (6, 15, 2)] {
        let coarse = original.node_material_at(I64Vec3::new(x as i64, y as i64, z as i64));
        let mut block = strata_volume::VoxelBlock::default();
        v.extract_block_into(key, &mut block);
        if coarse.is_some() {
            assert_eq!(Some(block.material(x * n, y * n, z * n)), coarse, "node ({x}, {y}, {z})");
        }
        // Level of detail: the block sampled back at the base level reads the same nodes.
        v.extract_block_capped(key, &|_| Level::BASE, &mut block);
        assert_eq!(block.level(), Level::BASE);
        if coarse.is_some() {
            assert_eq!(Some(block.material(x, y, z)), coarse, "LOD node ({x}, {y}, {z})");
        }
    }
    v.set_chunk_level(key, Level::BASE);
    v.check_invariants().unwrap();
    assert_eq!(v, original, "raising then lowering gives back the materials bit for bit");
    v.restore(raised.undo);
    v.check_invariants().unwrap();
}

#[test]
fn merging_layers_carries_the_materials_of_the_merged_layer() {
    let mut a = Volume::new();
    a.apply(CsgOp::Add, &Sphere::new(DVec3::splat(10.0), 6.0).unwrap(), &settings(1)).unwrap();
    let mut b = Volume::new();
    b.apply(CsgOp::Add, &Sphere::new(DVec3::splat(10.0), 6.0).unwrap(), &settings(5)).unwrap();
    let report = a.merge_from(&b, IVec3::new(9, 0, 0), &EditSettings::default()).unwrap();
    a.check_invariants().unwrap();
    assert_eq!(a.node_material_at(I64Vec3::new(10, 10, 10)), Some(1));
    assert_eq!(a.node_material_at(I64Vec3::new(24, 10, 10)), Some(5));
    let before = {
        let mut c = a.clone();
        c.restore(report.undo);
        c
    };
    assert_eq!(before.node_material_at(I64Vec3::new(24, 10, 10)), None);
}

#[test]
fn materials_memory_is_small_for_uniform_chunks_and_counted() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::splat(40.0), 30.0).unwrap()).unwrap();
    assert_eq!(v.memory().materials, 0, "material 0 costs nothing");
    let mut w = Volume::new();
    w.apply(CsgOp::Add, &Sphere::new(DVec3::splat(40.0), 30.0).unwrap(), &settings(7)).unwrap();
    let m = w.memory();
    assert!(m.materials > 0);
    // One uniform entry per chunk: a table slot, no runs.
    assert!(m.materials < 64 * w.chunk_count() + 4096, "{} bytes for {} chunks", m.materials, w.chunk_count());
    assert_eq!(m.total(), v.memory().total() + m.materials);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, ..ProptestConfig::default() })]

    /// A voxel block's node materials, the chunk's own and those its apron reads from its far
    /// neighbours, whole blocks and 4³-cell parts alike, are the materials the volume gives
    /// those nodes (random material CSG, half of it snapped to the grid).
    #[test]
    fn block_materials_equal_the_node_materials(ops in prop::collection::vec(op(), 1..12)) {
        let mut v = Volume::new();
        for o in &ops {
            v.apply(o.op, brush(o).as_ref(), &settings(o.material)).unwrap();
        }
        let keys: Vec<ChunkKey> = v.chunks().map(|(k, _)| k).collect();
        let mut block = strata_volume::VoxelBlock::default();
        for key in keys {
            let origin = key.origin_grid();
            let check = |block: &strata_volume::VoxelBlock| {
                let off = block.offset();
                let m = block.cells() + 1;
                for z in 0..m {
                    for y in 0..m {
                        for x in 0..m {
                            let node = origin + I64Vec3::new((x + off[0]) as i64, (y + off[1]) as i64, (z + off[2]) as i64);
                            let want = v.node_material_at(node);
                            assert_eq!(block.inside(x, y, z), want.is_some(), "node {node}");
                            if let Some(id) = want {
                                assert_eq!(block.material(x, y, z), id, "node {node} of {key:?} from {off:?}");
                            }
                        }
                    }
                }
            };
            v.extract_block_into(key, &mut block);
            check(&block);
            for off in [[0, 0, 0], [4, 8, 12], [12, 12, 12], [0, 12, 4]] {
                v.extract_part(key, off, 4, &mut block);
                check(&block);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, ..ProptestConfig::default() })]

    /// Material CSG reads only the x lines an edit changed (the change points between them are
    /// copied; in debug builds every edit also checks the result against the pass over every
    /// node of the chunk). On volumes with chunks raised to finer levels, shapes half snapped to
    /// the grid and ops in random order: the invariants hold after every edit, undo and redo
    /// are exact, and the nodes of base-level chunks carry the dense reference's materials.
    #[test]
    fn materials_from_the_changed_lines_keep_the_reference_across_levels(
        ops in prop::collection::vec(op(), 1..14),
        raised in prop::collection::vec((0i32..3, 0i32..3, 0i32..3, prop_oneof![Just(-1i8), Just(1i8), Just(2i8)]), 0..3),
    ) {
        let mut v = Volume::new();
        v.apply(CsgOp::Add, &Sphere::new(DVec3::splat(20.0), 9.0).unwrap(), &settings(3)).unwrap();
        let mut reference: Vec<Option<u8>> = nodes()
            .map(|n| brush_contains_node(&Sphere::new(DVec3::splat(20.0), 9.0).unwrap(), n, Level::BASE).then_some(3))
            .collect();
        let mut fine = Vec::new();
        for &(x, y, z, level) in &raised {
            let key = ChunkKey::new(x, y, z);
            v.set_chunk_level(key, Level::new(level).unwrap());
            v.check_invariants().unwrap();
            fine.push(key);
        }
        for o in &ops {
            let b = brush(o);
            checked(&mut v, |v| v.apply(o.op, b.as_ref(), &settings(o.material)).unwrap());
            apply_to_reference(&mut reference, o, b.as_ref());
        }
        // Nodes of chunks that stayed at the base level, away from the raised ones (whose
        // nodes between base nodes a shape may reach differently).
        let near_fine = |n: I64Vec3| {
            fine.iter().any(|k| {
                let lo = k.origin_grid() - I64Vec3::ONE;
                let hi = k.origin_grid() + I64Vec3::splat(17);
                n.cmpge(lo).all() && n.cmple(hi).all()
            })
        };
        for n in nodes().filter(|&n| !near_fine(n)) {
            prop_assert_eq!(v.node_material_at(n), reference[index(n)], "node {}", n);
        }
    }
}

/// A mesher's snapshot shares the chunks and their material runs instead of copying them, reads
/// as the volume did when it was taken, and is left as it was by later edits.
#[test]
fn shared_chunks_read_as_the_volume_did_and_outlive_its_edits() {
    let mut v = Volume::new();
    v.set_cell_size(0.5).unwrap();
    v.apply(CsgOp::Add, &Sphere::new(DVec3::new(20.0, 18.0, 15.0), 11.0).unwrap(), &settings(1)).unwrap();
    v.apply(CsgOp::Add, &Cuboid::new(DVec3::new(12.0, 10.0, 8.0), DVec3::new(22.0, 20.0, 30.0)).unwrap(), &settings(2))
        .unwrap();
    let key = ChunkKey::new(1, 1, 0);
    let before = v.clone();
    let snapshot = v.share_chunks(key.around());
    assert_eq!((snapshot.level(), snapshot.cell_size()), (v.level(), v.cell_size()));
    let mut runs = 0;
    for k in key.around() {
        assert_eq!(snapshot.chunk(k), v.chunk(k), "{k:?}");
        assert_eq!(snapshot.chunk_materials(k), v.chunk_materials(k), "{k:?}");
        if let (Some(Chunk::Lists(a)), Some(Chunk::Lists(b))) = (snapshot.chunk(k), v.chunk(k)) {
            assert!(a.shares_with(b), "{k:?} was copied, not shared");
        }
        if let (Some(strata_volume::ChunkMaterials::Runs(a)), Some(strata_volume::ChunkMaterials::Runs(b))) =
            (snapshot.chunk_materials(k), v.chunk_materials(k))
        {
            assert!(std::sync::Arc::ptr_eq(a, b), "{k:?}'s materials were copied, not shared");
            runs += 1;
        }
    }
    assert!(runs > 0, "the case holds chunks of two materials");
    assert!(snapshot.chunks().all(|(k, _)| key.around().any(|a| a == k)), "only the chunks asked for");
    let block = move |v: &Volume| {
        let mut b = strata_volume::VoxelBlock::default();
        v.extract_block_into(key, &mut b);
        b
    };
    assert_eq!(block(&snapshot), block(&v));
    // Edits replace the volume's chunks; the snapshot keeps what it shared, moved to another
    // thread and read there.
    v.apply(CsgOp::Subtract, &Sphere::new(DVec3::new(20.0, 18.0, 8.0), 6.0).unwrap(), &settings(0)).unwrap();
    assert_ne!(block(&v), block(&before), "the edit reaches the chunk");
    let read = std::thread::spawn(move || block(&snapshot)).join().unwrap();
    assert_eq!(read, block(&before));
    v.check_invariants().unwrap();
}
