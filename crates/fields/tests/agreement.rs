//! The dense and narrow-band fields agree with the segment volume on node states, and their
//! voxel blocks and encodings behave.

use glam::{DVec3, I64Vec3};
use proptest::prelude::*;
use strata_fields::{DenseField, FieldError, NarrowBandField, PaddedValues, RleChunk};
use strata_volume::brush::{Brush, Capsule, Cuboid, Sphere, Torus};
use strata_volume::{ChunkKey, CsgOp, Volume, VoxelBlock};

/// A small seeded generator, so the workload is the same everywhere.
struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

const CANVAS: f64 = 48.0;

fn workload(count: usize, seed: u64) -> Vec<(CsgOp, Box<dyn Brush>)> {
    let mut r = Rng(seed);
    (0..count)
        .map(|i| {
            let op = match r.unit() {
                u if u < 0.55 => CsgOp::Add,
                u if u < 0.97 => CsgOp::Subtract,
                _ => CsgOp::Intersect,
            };
            let c = DVec3::new(r.unit(), r.unit(), r.unit()) * CANVAS;
            let size = 2.0 + r.unit() * 9.0;
            let brush: Box<dyn Brush> = match i % 4 {
                0 => Box::new(Sphere::new(c, size).unwrap()),
                1 => Box::new(Cuboid::new(c, DVec3::new(size, size * 0.7, size * 0.5)).unwrap()),
                2 => Box::new(Capsule::new(c, c + DVec3::new(size, 3.0, -2.0), size * 0.4).unwrap()),
                _ => Box::new(Torus::new(c, DVec3::new(0.3, 1.0, 0.2), size, size * 0.3).unwrap()),
            };
            // Intersections with small shapes would empty the canvas; keep them large.
            let brush: Box<dyn Brush> = if op == CsgOp::Intersect {
                Box::new(Sphere::new(DVec3::splat(CANVAS / 2.0), CANVAS * 0.45).unwrap())
            } else {
                brush
            };
            (op, brush)
        })
        .collect()
}

/// Whether some brush of the workload has its surface within `eps` of the node: there the
/// representations may round the predicate differently.
fn near_a_surface(work: &[(CsgOp, Box<dyn Brush>)], node: I64Vec3, eps: f64) -> bool {
    let key = node.div_euclid(I64Vec3::splat(16));
    let origin = (key * 16).as_dvec3();
    let p = (node - key * 16).as_dvec3();
    work.iter().any(|(_, b)| b.field(origin, p).abs() < eps)
}

#[test]
fn dense_narrow_band_and_segments_agree_on_node_states() {
    let work = workload(300, 11);
    let mut volume = Volume::new();
    let mut dense = DenseField::new();
    let mut bands: Vec<NarrowBandField> = [1.0, 2.0, 3.0].map(|b| NarrowBandField::new(b).unwrap()).into();
    for (op, brush) in &work {
        volume.apply(*op, brush.as_ref(), &Default::default()).unwrap();
        dense.apply(*op, brush.as_ref()).unwrap();
        for nb in &mut bands {
            nb.apply(*op, brush.as_ref()).unwrap();
        }
    }
    volume.check_invariants().unwrap();
    let (mut inside, mut differ) = (0, 0);
    let r = CANVAS as i64 + 16;
    for z in -16..r {
        for y in -16..r {
            for x in -16..r {
                let node = I64Vec3::new(x, y, z);
                let d = dense.node_inside(node);
                for nb in &bands {
                    assert_eq!(nb.node_inside(node), d, "narrow band {} disagrees with dense at {node}", nb.band());
                }
                let s = volume.node_inside(node);
                inside += s as usize;
                if s != d {
                    differ += 1;
                    assert!(
                        near_a_surface(&work, node, 1e-4),
                        "segments and dense disagree at {node}, away from any surface"
                    );
                }
            }
        }
    }
    assert!(inside > 10_000, "the workload leaves a solid ({inside} inside nodes)");
    assert!(differ < 10, "{differ} nodes differ");
}

#[test]
fn blocks_of_a_sphere_match_the_segment_volume() {
    let sphere = Sphere::new(DVec3::new(17.3, 15.1, 16.7), 11.2).unwrap();
    let mut volume = Volume::new();
    volume.add(&sphere).unwrap();
    let mut dense = DenseField::new();
    dense.apply(CsgOp::Add, &sphere).unwrap();
    let mut nb = NarrowBandField::new(2.0).unwrap();
    nb.apply(CsgOp::Add, &sphere).unwrap();
    let mut scratch = PaddedValues::default();
    let (mut d_block, mut n_block) = (VoxelBlock::default(), VoxelBlock::default());
    let mut checked = 0;
    let mut t_error = 0.0;
    for z in 0..2 {
        for y in 0..2 {
            for x in 0..2 {
                let key = ChunkKey::new(x, y, z);
                let s_block = volume.extract_block(key);
                dense.extract_block_into(key, &mut scratch, &mut d_block);
                nb.extract_block_into(key, &mut scratch, &mut n_block);
                for other in [&d_block, &n_block] {
                    for zz in 0..=16 {
                        for yy in 0..=16 {
                            assert_eq!(other.row(yy, zz), s_block.row(yy, zz), "states of row {yy},{zz} in {key:?}");
                        }
                    }
                    for axis in strata_volume::Axis::ALL {
                        assert_eq!(other.crossings(axis).len(), s_block.crossings(axis).len());
                        for c in s_block.crossings(axis) {
                            let [a, b, cc] = c.lower.map(usize::from);
                            let o = other.crossing(axis, a, b, cc).expect("same edges cross");
                            // Linear interpolation of an exact distance is close except on lines
                            // that graze the sphere, where the distance is far from linear (up to
                            // 0.3 cells here): so only the mean is bounded tightly.
                            assert!(
                                (o.t - c.t).abs() < 0.5,
                                "t {} vs {} on {axis:?} {:?} of {key:?}",
                                o.t,
                                c.t,
                                c.lower
                            );
                            t_error += (o.t - c.t).abs() as f64;
                            let (no, ns) = (
                                strata_volume::normal::unpack_normal(o.normal),
                                strata_volume::normal::unpack_normal(c.normal),
                            );
                            let _ = (key, axis);
                            assert!(no.dot(ns) > 0.97, "normals {no} vs {ns}");
                            checked += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(checked > 1000);
    assert!(t_error / (checked as f64) < 0.02, "mean crossing error {}", t_error / checked as f64);
}

#[test]
fn fields_built_from_a_volume_keep_its_node_states() {
    // (the estimate's mean and worst error near the sphere are printed and bounded below)
    let mut volume = Volume::new();
    volume.add(&Sphere::new(DVec3::new(20.5, 18.2, 21.7), 14.0).unwrap()).unwrap();
    volume.subtract(&Cuboid::new(DVec3::new(28.0, 20.0, 20.0), DVec3::new(6.0, 4.0, 9.0)).unwrap()).unwrap();
    let nb1 = NarrowBandField::from_volume(&volume, 1.0).unwrap();
    let nb3 = NarrowBandField::from_volume(&volume, 3.0).unwrap();
    let dense = DenseField::from_volume(&volume, 1.0).unwrap();
    assert_eq!(dense.chunk_count(), nb1.chunk_count());
    let values = DenseField::CHUNK_BYTES * dense.chunk_count();
    assert!(dense.memory() > values && DenseField::bytes_for_chunks(dense.chunk_count()) > values);
    assert!(nb3.literal_count() > 2 * nb1.literal_count(), "a wider band stores more values");
    let (mut sum_e, mut max_e, mut count_e) = (0.0, 0.0f64, 0);
    for z in -4..44 {
        for y in -4..44 {
            for x in -4..44 {
                let node = I64Vec3::new(x, y, z);
                let s = volume.node_inside(node);
                assert_eq!(nb1.node_inside(node), s, "{node}");
                assert_eq!(nb3.node_inside(node), s, "{node}");
                assert_eq!(dense.node_inside(node), s, "{node}");
                // Estimates are distances: never beyond the band, and near the true one.
                let true_d = (node.as_dvec3() - DVec3::new(20.5, 18.2, 21.7)).length() - 14.0;
                let v = nb3.value(node) as f64;
                assert!(v.abs() <= 3.0);
                if true_d.abs() < 2.0 && (node.x as f64) < 21.0 {
                    let e = (v - true_d).abs();
                    // Within a cell of the surface the estimate decides band membership.
                    assert!(true_d.abs() > 1.0 || e < 0.35, "estimate {v} vs distance {true_d} at {node}");
                    (sum_e, max_e, count_e) = (sum_e + e, max_e.max(e), count_e + 1);
                }
            }
        }
    }
    let mean = sum_e / count_e as f64;
    println!(
        "distance estimate within 2 cells of the sphere: mean error {mean:.3}, worst {max_e:.3} ({count_e} nodes)"
    );
    assert!(mean < 0.1);
}

/// A brush whose bounds are broken (a user brush can report anything).
struct BrokenBounds;
impl Brush for BrokenBounds {
    fn bounds(&self) -> strata_volume::brush::Aabb {
        strata_volume::brush::Aabb::new(DVec3::splat(f64::NAN), DVec3::ONE)
    }
    fn field(&self, _: DVec3, _: DVec3) -> f64 {
        -1.0
    }
}

#[test]
fn bad_input_is_refused_and_changes_nothing() {
    for b in [f32::NAN, f32::INFINITY, 0.0, -1.0] {
        assert!(matches!(NarrowBandField::new(b), Err(FieldError::BadBand(_))));
    }
    let mut dense = DenseField::new();
    let mut nb = NarrowBandField::new(1.0).unwrap();
    let small = Sphere::new(DVec3::splat(5.0), 3.0).unwrap();
    dense.apply(CsgOp::Add, &small).unwrap();
    nb.apply(CsgOp::Add, &small).unwrap();
    let (dm, nm) = (dense.memory(), nb.memory());
    let huge = Sphere::new(DVec3::ZERO, 1e7).unwrap();
    let far = Sphere::new(DVec3::splat(1e12), 2.0).unwrap();
    assert!(matches!(dense.apply(CsgOp::Add, &huge), Err(FieldError::TooLarge { .. })));
    assert!(matches!(nb.apply(CsgOp::Subtract, &huge), Err(FieldError::TooLarge { .. })));
    assert!(matches!(dense.apply(CsgOp::Add, &far), Err(FieldError::OutOfRange(_))));
    assert!(matches!(nb.apply(CsgOp::Add, &far), Err(FieldError::OutOfRange(_))));
    assert!(matches!(dense.apply(CsgOp::Add, &BrokenBounds), Err(FieldError::BadBounds(_))));
    assert!(matches!(nb.apply(CsgOp::Intersect, &BrokenBounds), Err(FieldError::BadBounds(_))));
    assert_eq!((dense.memory(), nb.memory()), (dm, nm));
    assert!(dense.node_inside(I64Vec3::splat(5)) && nb.node_inside(I64Vec3::splat(5)));
}

proptest! {
    #[test]
    fn rle_round_trips(runs in proptest::collection::vec((0u8..3, 1usize..300), 1..60), seed in any::<u64>()) {
        let band = 2.0f32;
        let mut values = Vec::with_capacity(4096);
        let mut r = Rng(seed);
        for (kind, len) in runs {
            for _ in 0..len {
                values.push(match kind { 0 => band, 1 => -band, _ => ((r.unit() * 2.0 - 1.0) * 1.99) as f32 });
            }
        }
        values.resize(4096, band);
        values.truncate(4096);
        let c = RleChunk::encode(&values, band);
        let mut out = vec![0.0; 4096];
        c.decode(band, &mut out);
        prop_assert_eq!(&out, &values);
        for i in (0..4096).step_by(97) {
            prop_assert_eq!(c.get(band, i), values[i]);
        }
        prop_assert!(c.bytes() <= 2 * 4096 + 4 * 4096);
    }
}
