//! The export's chunk-by-chunk creased marching cubes against the whole-mesh road it replaced:
//! weld every chunk's mesh, then crease the welded mesh. Same triangles, corner for corner
//! (position, normal and material bit for bit), same vertex count; random edits on and off the
//! grid, several materials, mixed levels, negative coordinates.

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use strata_mesh::normals::{DEFAULT_CREASE_DEGREES, crease_normals};
use strata_mesh::{
    Mesh, MeshOptions, Mesher, mesh_block, mesh_volume_creased, mesh_volume_shaded, mesh_volume_with, surface_chunks,
};
use strata_volume::brush::{Brush, Cuboid, Sphere};
use strata_volume::{ChunkKey, CsgOp, EditSettings, Level, Volume, VoxelBlock};

/// A triangle corner: position bits, normal bits, material ids and weights.
type Corner = ([u32; 3], [u32; 3], [u8; 4], [u8; 4]);

/// Each triangle as its three corners, turned to start at its least corner (orientation kept);
/// the triangles sorted.
fn canonical(m: &Mesh) -> Vec<[Corner; 3]> {
    let corner = |i: u32| {
        let i = i as usize;
        let bits = |v: [f32; 3]| v.map(|c| (c + 0.0).to_bits());
        let mat = m.material(i);
        (bits(m.positions[i]), bits(m.normals[i]), mat.ids, mat.weights)
    };
    let mut out: Vec<_> = m
        .triangles()
        .map(|t| {
            let c = t.map(corner);
            let first = (0..3).min_by(|&a, &b| c[a].cmp(&c[b])).unwrap();
            [c[first], c[(first + 1) % 3], c[(first + 2) % 3]]
        })
        .collect();
    out.sort();
    out
}

fn assert_same(v: &Volume, degrees: f32) -> Result<(), TestCaseError> {
    // Both roads skip the chunks whose apron's owners are uniform alike with them: read and
    // meshed all the same, such a chunk has no surface.
    let mut block = VoxelBlock::default();
    let mut mesh = Mesh::default();
    for key in surface_chunks(v).into_iter().filter(|&k| v.plain_block_uniform(k)) {
        v.extract_block_into(key, &mut block);
        mesh_block(&block, &mut mesh);
        prop_assert!(mesh.indices.is_empty(), "chunk {:?} was skipped but has a surface", key);
    }
    let whole = crease_normals(&mesh_volume_with(v, MeshOptions::default()).unwrap(), degrees);
    let streamed = mesh_volume_creased(v, degrees);
    prop_assert_eq!(streamed.vertex_count(), whole.vertex_count());
    prop_assert_eq!(streamed.triangle_count(), whole.triangle_count());
    prop_assert!(canonical(&streamed) == canonical(&whole), "the triangles differ");
    Ok(())
}

#[derive(Clone, Debug)]
enum Step {
    Edit { subtract: bool, cube: bool, snap: u8, c: [f64; 3], size: f64, angle: f64, material: u8 },
    Level { key: [i32; 3], level: i8 },
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        3 => (any::<bool>(), any::<bool>(), 0u8..3, prop::array::uniform3(-20.0f64..40.0), 1.0f64..14.0, 0.0f64..3.0, 0u8..3)
            .prop_map(|(subtract, cube, snap, c, size, angle, material)| Step::Edit { subtract, cube, snap, c, size, angle, material }),
        1 => (prop::array::uniform3(-1i32..2), -1i8..2).prop_map(|(key, level)| Step::Level { key, level }),
    ]
}

fn apply(v: &mut Volume, s: &Step) {
    match *s {
        Step::Edit { subtract, cube, snap, c, size, angle, material } => {
            // Snapped to nodes, to half cells, or anywhere.
            let q = [0.0, 1.0, 0.5][snap as usize];
            let snapped = |x: f64| if q > 0.0 { ((x / q).round() * q).max(q) } else { x };
            let c = DVec3::from_array(c.map(snapped));
            let size = snapped(size);
            let brush: Box<dyn Brush> = if cube {
                Box::new(
                    Cuboid::oriented(c, DVec3::new(size, 0.7 * size + 0.5, size), DQuat::from_rotation_z(angle), 0.0)
                        .unwrap(),
                )
            } else {
                Box::new(Sphere::new(c, size).unwrap())
            };
            let op = if subtract { CsgOp::Subtract } else { CsgOp::Add };
            v.apply(op, brush.as_ref(), &EditSettings { material, ..Default::default() }).unwrap();
        }
        Step::Level { key, level } => {
            let l = Level::new(level).unwrap();
            v.set_chunk_level(ChunkKey::new(key[0], key[1], key[2]), l);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, max_shrink_iters: 50, ..ProptestConfig::default() })]

    #[test]
    fn chunk_by_chunk_equals_welding_then_creasing(
        steps in prop::collection::vec(step(), 1..10),
        degrees in prop_oneof![Just(DEFAULT_CREASE_DEGREES), 0.0f32..90.0],
    ) {
        let mut v = Volume::new();
        for s in &steps {
            apply(&mut v, s);
        }
        assert_same(&v, degrees)?;
    }
}

#[test]
fn a_box_on_chunk_faces_splits_its_edges_and_corners_as_before() {
    // Faces on the chunk planes x = 0 and y = 16: every vertex there is a border vertex.
    let mut v = Volume::new();
    v.add(&Cuboid::new(DVec3::new(8.0, 16.0, 5.5), DVec3::new(8.0, 7.25, 3.0)).unwrap()).unwrap();
    assert_same(&v, DEFAULT_CREASE_DEGREES).unwrap();
    let m = mesh_volume_creased(&v, DEFAULT_CREASE_DEGREES);
    // Split for shading only: welded by position it is closed.
    let by_position = strata_mesh::checks::weld_by_position([(ChunkKey::new(0, 0, 0), &m)]);
    strata_mesh::checks::check_closed_manifold(&by_position).unwrap();
}

#[test]
fn the_export_door_creases_marching_cubes_and_refuses_bad_angles() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(3.0, 4.0, 5.0), 9.0).unwrap()).unwrap();
    let (m, _) = mesh_volume_shaded(&v, MeshOptions::default(), 30.0).unwrap();
    assert!(canonical(&m) == canonical(&mesh_volume_creased(&v, 30.0)));
    for bad in [f32::NAN, f32::INFINITY, -1.0, 181.0] {
        assert!(mesh_volume_shaded(&v, MeshOptions::default(), bad).is_err(), "{bad}");
    }
    // Dual contouring keeps its own normals; a simplified mesh is welded, not creased.
    let dc = MeshOptions::new(Mesher::DualContouring);
    let (d, _) = mesh_volume_shaded(&v, dc, 30.0).unwrap();
    assert!(canonical(&d) == canonical(&mesh_volume_with(&v, dc).unwrap()));
    let simplified = MeshOptions { simplify: Some(0.3), ..Default::default() };
    let (s, _) = mesh_volume_shaded(&v, simplified, 30.0).unwrap();
    assert!(canonical(&s) == canonical(&mesh_volume_with(&v, simplified).unwrap().welded()));
}

#[test]
fn far_from_the_origin_where_f32_positions_round_it_is_the_same() {
    // Grid coordinates near 10⁵: chunk-local positions plus origins round in f32, the same way
    // in every chunk that shares a vertex.
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(100_000.3, -70_000.2, 50_000.7), 12.4).unwrap()).unwrap();
    v.add(&Cuboid::new(DVec3::new(100_016.0, -70_000.0, 50_008.5), DVec3::new(6.0, 9.0, 4.25)).unwrap()).unwrap();
    assert_same(&v, DEFAULT_CREASE_DEGREES).unwrap();
}

#[test]
fn border_vertices_creased_in_many_runs_on_every_core_are_the_same() {
    // Over 12,288 vertices on chunk faces: the border vertices are creased in three runs or
    // more in parallel and joined; a second material reaches some of them; over a hundred solid
    // chunks inside are skipped.
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(0.5, 1.25, -0.3), 100.0).unwrap()).unwrap();
    let settings = EditSettings { material: 2, ..Default::default() };
    v.apply(CsgOp::Add, &Cuboid::new(DVec3::new(70.0, 0.0, 0.0), DVec3::new(40.0, 32.0, 16.0)).unwrap(), &settings)
        .unwrap();
    let m = mesh_volume_creased(&v, DEFAULT_CREASE_DEGREES);
    let on_faces = m.positions.iter().filter(|p| p.iter().any(|&c| c.rem_euclid(16.0) == 0.0)).count();
    assert!(on_faces > 3 << 12, "{on_faces} vertices on chunk faces: too few for several runs");
    let skipped = surface_chunks(&v).into_iter().filter(|&k| v.plain_block_uniform(k)).count();
    assert!(skipped > 100, "{skipped} chunks skipped");
    assert_same(&v, DEFAULT_CREASE_DEGREES).unwrap();
}
