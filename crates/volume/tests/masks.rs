//! Masks: a node the mask protects never changes under any tool (CSG of every kind, every field
//! tool, paint, level changes), with inputs on the grid and beside it and the operations in
//! random orders; mask strokes and whole-mask actions undo exactly; the storage is canonical
//! and a damaged one is refused.

use glam::{DVec3, I64Vec3};
use proptest::prelude::*;
use strata_volume::brush::{Brush, Cuboid, Sphere};
use strata_volume::tools::{self, BuiltinStamp, Dab, MaskStroke, Smoothing, StampPlacement};
use strata_volume::{ChunkMask, CsgOp, EditReport, EditSettings, Level, Mask, PROTECTED, Volume};

/// Side of the checked region in nodes.
const SIDE: i64 = 40;

fn settings(material: u8) -> EditSettings {
    EditSettings { parallel: false, material, ..Default::default() }
}

fn nodes() -> impl Iterator<Item = I64Vec3> {
    (-2..SIDE).flat_map(|z| (-2..SIDE).flat_map(move |y| (-2..SIDE).map(move |x| I64Vec3::new(x, y, z))))
}

/// Applies an edit, then checks the invariants and that undo and redo give back both volumes
/// bit for bit (the mask included).
fn checked(v: &mut Volume, edit: impl FnOnce(&mut Volume) -> EditReport) {
    let before = v.clone();
    let report = edit(v);
    v.check_invariants().unwrap();
    let after = v.clone();
    let redo = v.restore(report.undo);
    assert_eq!(*v, before, "undo restores the volume, the mask included");
    v.restore(redo);
    assert_eq!(*v, after, "redo restores the edit");
}

/// The nodes held at `at_least` and their states, and for CSG the inside test at seven points
/// along every x edge between two held nodes (the edge's crossing).
fn held(v: &Volume, at_least: u8, edges: bool) -> Vec<(I64Vec3, bool, Vec<bool>)> {
    nodes()
        .filter(|&n| v.mask().weight(n) >= at_least)
        .map(|n| {
            let along = if edges && v.mask().weight(n + I64Vec3::X) >= at_least {
                (1..8).map(|k| v.is_inside(n.as_dvec3() + DVec3::X * (k as f64 / 8.0))).collect()
            } else {
                Vec::new()
            };
            (n, v.node_inside(n), along)
        })
        .collect()
}

#[derive(Clone, Debug)]
enum Step {
    Csg { op: CsgOp, center: DVec3, size: f64, cube: bool },
    Tool { kind: u8, center: DVec3, radius: f64, strength: f64 },
    Mask { stroke: u8, center: DVec3, radius: f64, strength: f64 },
    Whole(u8),
}

fn point(on_grid: bool) -> impl Strategy<Value = DVec3> {
    (4.0..36.0f64, 4.0..36.0f64, 4.0..36.0f64).prop_map(move |(x, y, z)| {
        let p = DVec3::new(x, y, z);
        if on_grid { p.round() } else { p }
    })
}

fn step() -> impl Strategy<Value = Step> {
    any::<bool>().prop_flat_map(|on_grid| {
        let snap = move |v: f64| if on_grid { v.round() } else { v };
        prop_oneof![
            3 => (prop_oneof![Just(CsgOp::Add), Just(CsgOp::Subtract), Just(CsgOp::Intersect)], point(on_grid), 2.0..12.0f64, any::<bool>())
                .prop_map(move |(op, center, size, cube)| Step::Csg { op, center, size: snap(size), cube }),
            3 => (0u8..11, point(on_grid), 2.0..9.0f64, 0.2..1.0f64)
                .prop_map(move |(kind, center, radius, strength)| Step::Tool { kind, center, radius: snap(radius), strength }),
            2 => (0u8..3, point(on_grid), 2.0..10.0f64, 0.3..1.0f64)
                .prop_map(move |(stroke, center, radius, strength)| Step::Mask { stroke, center, radius: snap(radius), strength }),
            1 => (0u8..4).prop_map(Step::Whole),
        ]
    })
}

fn run(v: &mut Volume, s: &Step) {
    match *s {
        Step::Csg { op, center, size, cube } => {
            let b: Box<dyn Brush> = if cube {
                Box::new(Cuboid::new(center, DVec3::splat(size)).unwrap())
            } else {
                Box::new(Sphere::new(center, size).unwrap())
            };
            checked(v, |v| v.apply(op, b.as_ref(), &settings(2)).unwrap());
        }
        Step::Tool { kind, center, radius, strength } => {
            let dab = Dab { material: 3, ..Dab::new(center, radius, strength).unwrap() };
            match kind {
                0 => checked(v, |v| tools::clay(v, &dab, 0.5, false).unwrap()),
                1 => checked(v, |v| tools::clay(v, &dab, 0.5, true).unwrap()),
                2 => checked(v, |v| tools::smooth(v, &dab, Smoothing::VolumePreserving, 2).unwrap()),
                3 => checked(v, |v| tools::smooth(v, &dab, Smoothing::Endpoints, 1).unwrap()),
                4 => checked(v, |v| tools::inflate(v, &dab, 1.0).unwrap()),
                5 => checked(v, |v| tools::flatten(v, &dab).unwrap()),
                6 => checked(v, |v| tools::grab(v, &dab, DVec3::new(2.0, -1.0, 1.5)).unwrap()),
                7 => checked(v, |v| tools::pinch(v, &dab, None, 0.8).unwrap()),
                8 => checked(v, |v| tools::paint(v, &dab).unwrap()),
                _ => {
                    let (image, height) =
                        if kind == 9 { (BuiltinStamp::Dome, 2.5) } else { (BuiltinStamp::Cells, -2.0) };
                    let placement =
                        StampPlacement { up: DVec3::new(0.3, 1.0, -0.2), angle: radius, mirrored: kind == 10 };
                    checked(v, |v| tools::stamp(v, &dab, &image.image(), &placement, height).unwrap())
                }
            }
        }
        Step::Mask { stroke, center, radius, strength } => {
            let dab = Dab::new(center, radius, strength).unwrap();
            let stroke = [MaskStroke::Add, MaskStroke::Subtract, MaskStroke::Smooth][stroke as usize];
            checked(v, |v| tools::mask(v, &dab, stroke).unwrap());
        }
        Step::Whole(k) => match k {
            0 => checked(v, |v| v.invert_mask()),
            1 => checked(v, |v| v.grow_mask(true)),
            2 => checked(v, |v| v.grow_mask(false)),
            _ => checked(v, |v| v.clear_mask()),
        },
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// Whatever runs, in whatever order: a node the mask fully protects keeps its state (at or
    /// above one half for CSG, with the crossings between two such nodes), the invariants hold,
    /// and every step undoes and redoes exactly.
    #[test]
    fn a_protected_node_never_changes(steps in prop::collection::vec(step(), 1..12), first in point(true)) {
        let mut v = Volume::new();
        v.apply(CsgOp::Add, &Sphere::new(DVec3::splat(20.0), 11.0).unwrap(), &settings(1)).unwrap();
        // A mask on half the solid to start from, then the random steps.
        checked(&mut v, |v| tools::mask(v, &Dab::new(first, 9.0, 1.0).unwrap(), MaskStroke::Add).unwrap());
        for s in &steps {
            let csg = matches!(s, Step::Csg { .. });
            let before = if csg { held(&v, 128, true) } else { held(&v, PROTECTED, false) };
            run(&mut v, s);
            if !matches!(s, Step::Mask { .. } | Step::Whole(_)) {
                let after: Vec<_> = before
                    .iter()
                    .map(|(n, _, along)| {
                        let e = if along.is_empty() {
                            Vec::new()
                        } else {
                            (1..8).map(|k| v.is_inside(n.as_dvec3() + DVec3::X * (k as f64 / 8.0))).collect()
                        };
                        (*n, v.node_inside(*n), e)
                    })
                    .collect();
                prop_assert!(after == before, "{:?} changed a protected node or edge", s);
            }
        }
        let bytes = postcard::to_allocvec(&v).unwrap();
        let back: Volume = postcard::from_bytes(&bytes).unwrap();
        prop_assert_eq!(back, v);
    }
}

#[test]
fn a_masked_half_survives_a_subtraction_of_everything() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::splat(20.0), 10.0).unwrap()).unwrap();
    let before = v.clone();
    // Protect the half x < 20 (a box of weight, inverted twice to cover the outside too).
    let half = Cuboid::new(DVec3::new(5.0, 20.0, 20.0), DVec3::new(15.5, 16.0, 16.0)).unwrap();
    for n in nodes() {
        if half.contains(DVec3::ZERO, n.as_dvec3()) {
            assert!(v.mask().weight(n) == 0);
        }
    }
    let dab = |c: DVec3| Dab::new(c, 3.0, 1.0).unwrap();
    for z in (4..=36).step_by(2) {
        for y in (4..=36).step_by(2) {
            for x in (4..=19).step_by(2) {
                tools::mask(&mut v, &dab(DVec3::new(x as f64, y as f64, z as f64)), MaskStroke::Add).unwrap();
            }
        }
    }
    v.subtract(&Sphere::new(DVec3::splat(20.0), 30.0).unwrap()).unwrap();
    v.check_invariants().unwrap();
    for n in nodes().filter(|n| v.mask().weight(*n) >= 128) {
        assert_eq!(v.node_inside(n), before.node_inside(n), "node {n}");
    }
    assert!(v.node_inside(I64Vec3::new(14, 20, 20)), "the masked half stays");
    assert!(!v.node_inside(I64Vec3::new(26, 20, 20)), "the free half goes");
    // Smoothing across the border leaves the masked side as it was.
    let masked_side = held(&v, PROTECTED, false);
    tools::smooth(&mut v, &Dab::new(DVec3::new(20.0, 20.0, 30.0), 8.0, 1.0).unwrap(), Smoothing::VolumePreserving, 3)
        .unwrap();
    assert!(held(&v, PROTECTED, false) == masked_side);
}

#[test]
fn inverting_clearing_growing_and_shrinking_the_mask() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::splat(8.0), 6.0).unwrap()).unwrap();
    assert!(v.mask().is_clear());
    let r = v.invert_mask();
    assert_eq!(v.mask().weight(I64Vec3::new(1000, -5, 3)), PROTECTED, "inverting an empty mask holds everything");
    assert!(v.mask().chunks().next().is_none(), "and stores no chunk");
    v.restore(r.undo);
    assert!(v.mask().is_clear());
    tools::mask(&mut v, &Dab::new(DVec3::splat(8.0), 2.0, 1.0).unwrap(), MaskStroke::Add).unwrap();
    assert_eq!(v.mask().weight(I64Vec3::splat(8)), PROTECTED);
    assert_eq!(v.mask().weight(I64Vec3::new(11, 8, 8)), 0);
    let was = v.clone();
    let grown = v.grow_mask(true);
    assert!(!grown.changed.is_empty());
    let sides = [I64Vec3::ZERO, I64Vec3::X, I64Vec3::NEG_X, I64Vec3::Y, I64Vec3::NEG_Y, I64Vec3::Z, I64Vec3::NEG_Z];
    for n in (0..16).map(|x| I64Vec3::new(x, 8, 8)).chain((0..16).map(|y| I64Vec3::new(9, y, 7))) {
        let most = sides.iter().map(|d| was.mask().weight(n + *d)).max().unwrap();
        assert_eq!(v.mask().weight(n), most, "node {n}");
    }
    assert_eq!(v.mask().weight(I64Vec3::new(10, 8, 8)), was.mask().weight(I64Vec3::new(9, 8, 8)));
    let before = v.clone();
    v.grow_mask(false);
    v.grow_mask(true);
    // Shrinking then growing keeps what was solidly held (a closing of the held part).
    assert_eq!(v.mask().weight(I64Vec3::splat(8)), before.mask().weight(I64Vec3::splat(8)));
    v.clear_mask();
    assert!(v.mask().is_clear());
}

#[test]
fn mask_storage_is_canonical_and_checked() {
    let mut weights = vec![0u8; 4096];
    weights[100..300].fill(200);
    weights[4000..].fill(255);
    let c = ChunkMask::encode(&weights, 0).unwrap();
    let mut back = vec![1u8; 4096];
    c.decode_into(&mut back);
    assert_eq!(back, weights);
    assert_eq!(ChunkMask::encode(&[7u8; 4096], 7), None, "a chunk of the outside weight stores nothing");
    assert_eq!(ChunkMask::encode(&[7u8; 4096], 0), Some(ChunkMask::Uniform(7)));
    let bytes = postcard::to_allocvec(&c).unwrap();
    assert_eq!(postcard::from_bytes::<ChunkMask>(&bytes).unwrap(), c);
    // Every damaged form is refused, never a panic.
    for cut in 0..bytes.len() {
        let _ = postcard::from_bytes::<ChunkMask>(&bytes[..cut]);
    }
    for (at, value) in [(2usize, 0u8), (3, 0x80), (4, 200), (bytes.len() - 1, 0)] {
        let mut b = bytes.clone();
        b[at] = value;
        if let Ok(m) = postcard::from_bytes::<ChunkMask>(&b) {
            let mut out = vec![0u8; 4096];
            m.decode_into(&mut out);
        }
    }
    let bad = ChunkMask::Runs(vec![0, 5, 10, 5].into_boxed_slice());
    let b = postcard::to_allocvec(&bad).unwrap();
    assert!(postcard::from_bytes::<ChunkMask>(&b).is_err(), "a change point that changes nothing");
    let bad = ChunkMask::Runs(vec![3, 5, 10, 6].into_boxed_slice());
    assert!(postcard::from_bytes::<ChunkMask>(&postcard::to_allocvec(&bad).unwrap()).is_err(), "not from node 0");
    let bad = ChunkMask::Runs(vec![0, 5, 0xff, 0x7f, 6].into_boxed_slice());
    assert!(postcard::from_bytes::<ChunkMask>(&postcard::to_allocvec(&bad).unwrap()).is_err(), "past the chunk");
    let m = Mask::from_parts(9, [(strata_volume::ChunkKey::new(0, 0, 0), ChunkMask::Uniform(9))]);
    assert!(m.chunks().next().is_none());
    let _ = Level::BASE;
}

#[test]
fn far_and_huge_brushes_on_a_masked_volume_are_refused_not_panics() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::splat(8.0), 5.0).unwrap()).unwrap();
    v.invert_mask();
    let before = v.clone();
    assert!(v.add(&Sphere::new(DVec3::splat(8.0), 1e300).unwrap()).is_err());
    assert!(v.subtract(&Sphere::new(DVec3::new(1e300, 0.0, 0.0), 3.0).unwrap()).is_err());
    for c in [DVec3::new(1e300, 0.0, 0.0), DVec3::new(68_719_476_736.0, 8.0, 8.0)] {
        for stroke in [MaskStroke::Add, MaskStroke::Subtract, MaskStroke::Smooth] {
            assert!(tools::mask(&mut v, &Dab::new(c, 4.0, 1.0).unwrap(), stroke).is_err(), "{c} {stroke:?}");
        }
    }
    assert!(v == before, "nothing changed");
    assert_eq!(v.mask().weight(I64Vec3::new(i64::MAX, 0, i64::MIN)), PROTECTED);
}
