//! Brushes placed where generic random tests never go: mesh faces on grid planes, edges on grid
//! lines, vertices on nodes (integer, half and quarter coordinates, rotations by multiples of
//! 90°), and field brushes whose Lipschitz bound understates the true slope by up to 100× or
//! whose field is discontinuous. After every edit the volume's invariants hold, and at the end
//! the marching-cubes mesh is closed and manifold.
//!
//! Cases default to 24; `PROPTEST_CASES=500 cargo test -p strata-tests --test grid_ties
//! --release` searches longer.

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use strata_mesh::checks;
use strata_volume::brush::{Aabb, Brush, Cuboid, MeshBrush, MeshRule, SdfBrush, Transformed};
use strata_volume::{CsgOp, EditSettings, Volume};

/// A cube `[0, 1]³` as twelve triangles, counter-clockwise from outside.
fn unit_cube() -> (Vec<DVec3>, Vec<[u32; 3]>) {
    strata_tests::box_mesh(DVec3::ZERO, DVec3::ONE)
}

/// A tetrahedron on four points, oriented outwards (or `None` if flat).
fn tetrahedron(p: [DVec3; 4]) -> Option<(Vec<DVec3>, Vec<[u32; 3]>)> {
    let vol = (p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]);
    if vol.abs() < 1e-9 {
        return None;
    }
    let mut t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    if vol < 0.0 {
        for tri in &mut t {
            tri.swap(1, 2);
        }
    }
    Some((p.to_vec(), t))
}

/// An octahedron with vertices on the axes.
fn octahedron() -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let v = vec![DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z];
    let t = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    (v, t)
}

#[derive(Clone, Debug)]
enum Shape {
    /// A box mesh with corners on a `1/snap` grid: `min` and `size` in snap units, rotated by
    /// quarter turns about x, y and z (around its min corner).
    Cube { min: [i32; 3], size: [i32; 3], snap: i32, turns: [u8; 3] },
    /// A tetrahedron with vertices on a `1/snap` grid.
    Tetra { p: [[i32; 3]; 4], snap: i32 },
    /// An octahedron scaled by an integer and centred on a node or a half node.
    Octa { c: [i32; 3], scale: i32, snap: i32, turns: [u8; 3] },
    /// An analytic box with faces on a `1/snap` grid, turned by quarter turns about its centre.
    OrientedBox { c: [i32; 3], half: [i32; 3], snap: i32, turns: [u8; 3] },
    /// A ball field whose stated Lipschitz bound is `1 / lie` of the true one.
    LyingBall { c: [i32; 3], r: i32, lie: f64 },
    /// A field steeper than a sphere's: `k` times the distance, stated as 1.
    SteepBall { c: [i32; 3], r: i32, k: f64 },
    /// A discontinuous field: -1 inside a box with grid-aligned faces (some nodes exactly on
    /// them), +1 outside, with stripes that flip the sign every `period` cells along x.
    Striped { min: [i32; 3], size: [i32; 3], period: i32 },
}

fn quarter_turns(turns: [u8; 3]) -> DQuat {
    let q = |axis: DVec3, n: u8| DQuat::from_axis_angle(axis, n as f64 * std::f64::consts::FRAC_PI_2);
    q(DVec3::Z, turns[2]) * q(DVec3::Y, turns[1]) * q(DVec3::X, turns[0])
}

fn v3(p: [i32; 3], snap: i32) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) / snap as f64
}

fn ball(c: DVec3, r: f64, k: f64) -> impl Fn(DVec3) -> f64 + Send + Sync {
    move |p: DVec3| k * ((p - c).length() - r)
}

impl Shape {
    fn brush(&self) -> Option<Box<dyn Brush>> {
        Some(match *self {
            Shape::Cube { min, size, snap, turns } => {
                let (v, t) = unit_cube();
                let s = v3(size, snap);
                let v: Vec<DVec3> = v.iter().map(|p| *p * s).collect();
                let m = MeshBrush::new(&v, &t, MeshRule::EvenOdd).ok()?;
                Box::new(Transformed::new(m, quarter_turns(turns), v3(min, snap), 1.0).ok()?)
            }
            Shape::Tetra { p, snap } => {
                let (v, t) = tetrahedron(p.map(|q| v3(q, snap)))?;
                Box::new(MeshBrush::new(&v, &t, MeshRule::NonZero).ok()?)
            }
            Shape::Octa { c, scale, snap, turns } => {
                let (v, t) = octahedron();
                let m = MeshBrush::new(&v, &t, MeshRule::EvenOdd).ok()?;
                Box::new(Transformed::new(m, quarter_turns(turns), v3(c, snap), scale as f64).ok()?)
            }
            Shape::OrientedBox { c, half, snap, turns } => {
                Box::new(Cuboid::oriented(v3(c, snap), v3(half, snap), quarter_turns(turns), 0.0).ok()?)
            }
            Shape::LyingBall { c, r, lie } => {
                let c = v3(c, 1);
                let r = r as f64;
                Box::new(SdfBrush::new(ball(c, r, 1.0), Aabb::new(c - r - 1.0, c + r + 1.0), 1.0 / lie).ok()?)
            }
            Shape::SteepBall { c, r, k } => {
                let c = v3(c, 1);
                let r = r as f64;
                Box::new(SdfBrush::new(ball(c, r, k), Aabb::new(c - r - 1.0, c + r + 1.0), 1.0).ok()?)
            }
            Shape::Striped { min, size, period } => {
                let (lo, hi) = (v3(min, 1), v3(min, 1) + v3(size, 1));
                let f = move |p: DVec3| {
                    let inside_box = p.cmpge(lo).all() && p.cmple(hi).all();
                    let stripe = ((p.x / period as f64).floor() as i64).rem_euclid(2) == 0;
                    if inside_box && stripe { -1.0 } else { 1.0 }
                };
                Box::new(SdfBrush::new(f, Aabb::new(lo - 0.5, hi + 0.5), 1.0).ok()?)
            }
        })
    }
}

fn ivec(lo: i32, hi: i32) -> impl Strategy<Value = [i32; 3]> {
    [lo..hi, lo..hi, lo..hi]
}

fn snap() -> impl Strategy<Value = i32> {
    prop_oneof![Just(1), Just(2), Just(4)]
}

fn turns() -> impl Strategy<Value = [u8; 3]> {
    [0..4u8, 0..4u8, 0..4u8]
}

fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        3 => (snap(), turns()).prop_flat_map(|(snap, turns)| {
            (ivec(-4 * snap, 40 * snap), ivec(snap / 2 + 1, 20 * snap)).prop_map(move |(min, size)| Shape::Cube { min, size, snap, turns })
        }),
        2 => snap().prop_flat_map(|snap| [ivec(0, 36 * snap), ivec(0, 36 * snap), ivec(0, 36 * snap), ivec(0, 36 * snap)]
            .prop_map(move |p| Shape::Tetra { p, snap })),
        1 => (snap(), turns()).prop_flat_map(|(snap, turns)| {
            (ivec(0, 36 * snap), 1..12).prop_map(move |(c, scale)| Shape::Octa { c, scale, snap, turns })
        }),
        2 => (snap(), turns()).prop_flat_map(|(snap, turns)| {
            (ivec(0, 36 * snap), ivec(1, 12 * snap)).prop_map(move |(c, half)| Shape::OrientedBox { c, half, snap, turns })
        }),
        1 => (ivec(0, 36), 1..14, 1.0..100.0f64).prop_map(|(c, r, lie)| Shape::LyingBall { c, r, lie }),
        1 => (ivec(0, 36), 1..14, 1.0..100.0f64).prop_map(|(c, r, k)| Shape::SteepBall { c, r, k }),
        1 => (ivec(-4, 36), ivec(1, 24), 1..8).prop_map(|(min, size, period)| Shape::Striped { min, size, period }),
    ]
}

fn op() -> impl Strategy<Value = CsgOp> {
    prop_oneof![6 => Just(CsgOp::Add), 4 => Just(CsgOp::Subtract), 1 => Just(CsgOp::Intersect)]
}

fn run(edits: &[(CsgOp, Shape)], parallel: bool) -> Result<(), TestCaseError> {
    let mut volume = Volume::new();
    let settings = EditSettings { parallel, ..Default::default() };
    for (i, (op, shape)) in edits.iter().enumerate() {
        let Some(brush) = shape.brush() else { continue };
        volume.apply(*op, brush.as_ref(), &settings).map_err(|e| TestCaseError::fail(e.to_string()))?;
        if let Err(e) = volume.check_invariants() {
            return Err(TestCaseError::fail(format!("edit {i} ({op:?} {shape:?}): {e}")));
        }
    }
    let mesh = strata_mesh::mesh_volume_with(&volume, strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    checks::check_closed_manifold(&mesh).map_err(|e| TestCaseError::fail(format!("mesh: {e}")))?;
    Ok(())
}

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(24)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), max_shrink_iters: 200, ..ProptestConfig::default() })]

    #[test]
    fn brushes_snapped_to_the_grid_keep_every_invariant(edits in proptest::collection::vec((op(), shape()), 1..12)) {
        run(&edits, false)?;
    }

    #[test]
    fn brushes_snapped_to_the_grid_keep_every_invariant_in_parallel(edits in proptest::collection::vec((op(), shape()), 1..6)) {
        run(&edits, true)?;
    }
}

#[test]
fn a_cube_mesh_with_integer_corners_keeps_the_axes_in_agreement() {
    let (v, t) = unit_cube();
    let v: Vec<DVec3> = v.iter().map(|p| *p * 6.0 + DVec3::splat(2.0)).collect();
    let m = MeshBrush::new(&v, &t, MeshRule::EvenOdd).unwrap();
    let mut volume = Volume::new();
    volume.add(&m).unwrap();
    volume.check_invariants().unwrap();
    checks::check_closed_manifold(
        &strata_mesh::mesh_volume_with(&volume, strata_mesh::MeshOptions::default())
            .expect("marching cubes meshes every volume"),
    )
    .unwrap();
    assert!(volume.node_inside(glam::I64Vec3::new(5, 5, 5)));
}

#[test]
fn a_field_with_a_lying_bound_keeps_chunk_borders_in_agreement() {
    // A ball at a chunk corner whose bound claims a slope 100× gentler than the truth: the
    // sampler would skip far past the chunk's last node.
    let c = DVec3::splat(16.0);
    let b = SdfBrush::new(ball(c, 9.0, 1.0), Aabb::new(c - 10.0, c + 10.0), 0.01).unwrap();
    let mut volume = Volume::new();
    volume.add(&b).unwrap();
    volume.check_invariants().unwrap();
    checks::check_closed_manifold(
        &strata_mesh::mesh_volume_with(&volume, strata_mesh::MeshOptions::default())
            .expect("marching cubes meshes every volume"),
    )
    .unwrap();
}
