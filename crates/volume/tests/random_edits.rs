//! Property test: random sequences of add / subtract / intersect edits of random shapes keep
//! every invariant, and node states always equal a brute-force dense reference evaluated with
//! the same predicate.
//!
//! Cases default to 6 (each one 200+ edits); `PROPTEST_CASES=64 cargo test -p strata-volume
//! --test random_edits --release` runs a longer search.

use glam::{DQuat, DVec3, I64Vec3};
use proptest::prelude::*;
use strata_volume::brush::{
    Aabb, Brush, Capsule, Cuboid, Cylinder, MeshBrush, MeshRule, SdfBrush, Sphere, Torus, Transformed,
};
use strata_volume::{ChunkKey, CsgOp, EditSettings, Level, Volume, brush_contains_node};

/// Side of the reference region in nodes: 3 chunks, so shapes straddle chunk borders.
const SIDE: i64 = 48;

#[derive(Clone, Debug)]
enum Shape {
    Sphere {
        c: DVec3,
        r: f64,
    },
    Box {
        c: DVec3,
        half: DVec3,
        rounding: f64,
        rot: Option<DVec3>,
    },
    Capsule {
        a: DVec3,
        b: DVec3,
        r: f64,
    },
    Cylinder {
        c: DVec3,
        axis: DVec3,
        h: f64,
        r: f64,
    },
    Torus {
        c: DVec3,
        axis: DVec3,
        major: f64,
        minor: f64,
    },
    ScaledSphere {
        c: DVec3,
        rot: DVec3,
        scale: f64,
    },
    /// An octahedron mesh, closed or with one face missing, rotated and scaled.
    Mesh {
        c: DVec3,
        rot: DVec3,
        scale: f64,
        open: bool,
    },
    /// A user field (a ball) with Lipschitz bound 1.
    Field {
        c: DVec3,
        r: f64,
    },
}

fn octahedron(open: bool) -> MeshBrush {
    let v = [DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z];
    let mut t = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    if open {
        t.pop();
    }
    MeshBrush::new(&v, &t, MeshRule::EvenOdd).unwrap()
}

impl Shape {
    fn brush(&self, offset: DVec3) -> Box<dyn Brush> {
        match *self {
            Shape::Sphere { c, r } => Box::new(Sphere::new(c + offset, r).unwrap()),
            Shape::Box { c, half, rounding, rot: None } => {
                Box::new(Cuboid::rounded(c + offset, half, rounding).unwrap())
            }
            Shape::Box { c, half, rounding, rot: Some(e) } => {
                let q = DQuat::from_euler(glam::EulerRot::XYZ, e.x, e.y, e.z);
                Box::new(Cuboid::oriented(c + offset, half, q, rounding).unwrap())
            }
            Shape::Capsule { a, b, r } => Box::new(Capsule::new(a + offset, b + offset, r).unwrap()),
            Shape::Cylinder { c, axis, h, r } => Box::new(Cylinder::new(c + offset, axis, h, r).unwrap()),
            Shape::Torus { c, axis, major, minor } => Box::new(Torus::new(c + offset, axis, major, minor).unwrap()),
            Shape::ScaledSphere { c, rot, scale } => {
                let q = DQuat::from_euler(glam::EulerRot::XYZ, rot.x, rot.y, rot.z);
                Box::new(
                    Transformed::new(Sphere::new(DVec3::new(0.5, -0.25, 0.0), 1.5).unwrap(), q, c + offset, scale)
                        .unwrap(),
                )
            }
            Shape::Mesh { c, rot, scale, open } => {
                let q = DQuat::from_euler(glam::EulerRot::XYZ, rot.x, rot.y, rot.z);
                Box::new(Transformed::new(octahedron(open), q, c + offset, scale).unwrap())
            }
            Shape::Field { c, r } => {
                let center = c + offset;
                let f = move |p: DVec3| (p - center).length() - r;
                Box::new(SdfBrush::new(f, Aabb::new(center - r, center + r), 1.0).unwrap())
            }
        }
    }
}

/// Coordinates on a 1/64 grid, so that shifting by a million cells is exact.
fn coord(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    ((lo * 64.0) as i64..(hi * 64.0) as i64).prop_map(|v| v as f64 / 64.0)
}

fn point() -> impl Strategy<Value = DVec3> {
    (coord(-8.0, 56.0), coord(-8.0, 56.0), coord(-8.0, 56.0)).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

/// Sizes from tiny (smaller than a cell) to huge (bigger than the region).
fn size() -> impl Strategy<Value = f64> {
    prop_oneof![
        3 => coord(0.1, 1.5),
        10 => coord(1.5, 12.0),
        2 => coord(12.0, 60.0),
    ]
}

fn direction() -> impl Strategy<Value = DVec3> {
    (coord(-1.0, 1.0), coord(-1.0, 1.0), coord(-1.0, 1.0))
        .prop_map(|(x, y, z)| DVec3::new(x, y, z))
        .prop_filter("non-zero", |d| d.length() > 0.1)
}

fn angles() -> impl Strategy<Value = DVec3> {
    (coord(-3.0, 3.0), coord(-3.0, 3.0), coord(-3.0, 3.0)).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        4 => (point(), size()).prop_map(|(c, r)| Shape::Sphere { c, r }),
        2 => (point(), size(), size(), size(), 0.0..1.0f64, proptest::option::of(angles())).prop_map(
            |(c, x, y, z, f, rot)| {
                let half = DVec3::new(x, y, z);
                let rounding = if f < 0.5 { 0.0 } else { ((f - 0.5) * half.min_element() * 64.0).floor() / 64.0 };
                Shape::Box { c, half, rounding, rot }
            }
        ),
        1 => (point(), point(), size()).prop_map(|(a, b, r)| Shape::Capsule { a, b, r }),
        1 => (point(), direction(), size(), size()).prop_map(|(c, axis, h, r)| Shape::Cylinder { c, axis, h, r }),
        1 => (point(), direction(), size(), size()).prop_map(|(c, axis, major, minor)| Shape::Torus { c, axis, major, minor }),
        1 => (point(), angles(), size()).prop_map(|(c, rot, scale)| Shape::ScaledSphere { c, rot, scale }),
        1 => (point(), angles(), size(), any::<bool>()).prop_map(|(c, rot, scale, open)| Shape::Mesh { c, rot, scale, open }),
        1 => (point(), size()).prop_map(|(c, r)| Shape::Field { c, r }),
    ]
}

fn op() -> impl Strategy<Value = CsgOp> {
    prop_oneof![6 => Just(CsgOp::Add), 5 => Just(CsgOp::Subtract), 1 => Just(CsgOp::Intersect)]
}

/// Node states of the region `base .. base + SIDE` (plus the chunk of nodes around it that edits
/// can also touch, which the check ignores).
struct Dense {
    base: I64Vec3,
    inside: Vec<bool>,
}

impl Dense {
    fn index(&self, p: I64Vec3) -> usize {
        let q = p - self.base;
        (q.x + SIDE * (q.y + SIDE * q.z)) as usize
    }

    fn apply(&mut self, op: CsgOp, brush: &dyn Brush) {
        let b = brush.bounds().expand(1e-6);
        for z in 0..SIDE {
            for y in 0..SIDE {
                for x in 0..SIDE {
                    let p = self.base + I64Vec3::new(x, y, z);
                    let i = self.index(p);
                    let in_box = b.contains((p - self.base).as_dvec3() + self.base.as_dvec3());
                    match op {
                        CsgOp::Add if in_box => self.inside[i] |= brush_contains_node(brush, p, Level::BASE),
                        CsgOp::Subtract if in_box => self.inside[i] &= !brush_contains_node(brush, p, Level::BASE),
                        CsgOp::Intersect => self.inside[i] &= in_box && brush_contains_node(brush, p, Level::BASE),
                        _ => {}
                    }
                }
            }
        }
    }

    fn compare(&self, v: &Volume, keys: Option<&[ChunkKey]>) -> Result<(), TestCaseError> {
        let chunks: Vec<ChunkKey> = match keys {
            Some(k) => k.to_vec(),
            None => {
                let c0 = self.base / 16;
                let mut all = Vec::new();
                for z in 0..3 {
                    for y in 0..3 {
                        for x in 0..3 {
                            let k = c0 + I64Vec3::new(x, y, z);
                            all.push(ChunkKey::new(k.x as i32, k.y as i32, k.z as i32));
                        }
                    }
                }
                all
            }
        };
        for key in chunks {
            let block = v.extract_block(key);
            prop_assert_eq!(block.repaired(), 0, "extractor repaired inconsistencies in {:?}", key);
            let o = key.origin_grid();
            for z in 0..16 {
                for y in 0..16 {
                    for x in 0..16 {
                        let p = o + I64Vec3::new(x, y, z);
                        let q = p - self.base;
                        if q.min_element() < 0 || q.max_element() >= SIDE {
                            continue;
                        }
                        prop_assert_eq!(
                            block.inside(x as usize, y as usize, z as usize),
                            self.inside[self.index(p)],
                            "node {} differs from the dense reference",
                            p
                        );
                    }
                }
            }
        }
        Ok(())
    }
}

/// Runs `edits` moved by `offset_cells` cells plus `fraction` (a fraction that is not a binary
/// fraction, like 0.1, makes every placement inexact, so rounding differs between frames).
fn run(edits: &[(CsgOp, Shape)], offset_cells: i64, fraction: f64) -> Result<(), TestCaseError> {
    let offset = DVec3::splat(offset_cells as f64 + fraction);
    let mut volume = Volume::new();
    let mut dense = Dense { base: I64Vec3::splat(offset_cells), inside: vec![false; (SIDE * SIDE * SIDE) as usize] };
    let settings = EditSettings { parallel: false, ..Default::default() };
    for (i, (op, shape)) in edits.iter().enumerate() {
        let brush = shape.brush(offset);
        let report = volume.apply(*op, brush.as_ref(), &settings).map_err(|e| TestCaseError::fail(e.to_string()))?;
        dense.apply(*op, brush.as_ref());
        if let Err(e) = volume.check_invariants() {
            return Err(TestCaseError::fail(format!("edit {i} ({op:?} {shape:?}): {e}")));
        }
        if brush.lines_agree() {
            prop_assert_eq!(report.repaired_nodes, 0);
        }
        dense
            .compare(&volume, Some(&report.changed))
            .map_err(|e| TestCaseError::fail(format!("after edit {i} ({op:?} {shape:?}): {e}")))?;
    }
    dense.compare(&volume, None)
}

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(6)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), max_shrink_iters: 20, ..ProptestConfig::default() })]

    #[test]
    fn random_edit_sequences_match_a_dense_reference(edits in proptest::collection::vec((op(), shape()), 200..230)) {
        run(&edits, 0, 0.0)?;
    }

    #[test]
    fn random_edit_sequences_with_inexact_placements_match_a_dense_reference(
        edits in proptest::collection::vec((op(), shape()), 200..230)
    ) {
        run(&edits, 0, 0.1)?;
    }

    #[test]
    fn random_edit_sequences_a_million_cells_away_match_a_dense_reference(
        edits in proptest::collection::vec((op(), shape()), 200..230)
    ) {
        run(&edits, 1_000_000, 0.0)?;
    }
}
