//! The edit fast paths (a line's one span turned into node states by integer arithmetic, whole
//! lines skipped when the result cannot change, spans computed a row at a time) give exactly the
//! volume the general path gives.

use glam::DVec3;
use strata_volume::brush::{Aabb, Brush, Cuboid, Span, Sphere};
use strata_volume::{CsgOp, EditSettings, Volume};

/// Forwards a brush with two changes a test can ask for: `agree: false` declares that its lines
/// may disagree, which sends every edit through the general sampler with x-line repairs (none
/// are needed for these shapes); `spans_below_y` answers only lines below that height by spans
/// and asks to be sampled on the others.
struct Tweaked<B> {
    inner: B,
    agree: bool,
    spans_below_y: f64,
}

impl<B: Brush> Brush for Tweaked<B> {
    fn bounds(&self) -> Aabb {
        self.inner.bounds()
    }
    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        self.inner.field(origin, p)
    }
    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        self.inner.contains(origin, p)
    }
    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        (origin + start).y < self.spans_below_y && self.inner.spans(origin, start, dir, out)
    }
    fn lines_agree(&self) -> bool {
        self.agree
    }
}

/// The general path for `inner`.
fn general_path<B: Brush>(inner: B) -> Tweaked<B> {
    Tweaked { inner, agree: false, spans_below_y: f64::INFINITY }
}

struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn fast_and_general_edits_build_identical_volumes() {
    for level in [0, 1] {
        let level = strata_volume::Level::new(level).unwrap();
        fast_and_general_edits_agree_at(level, if level == strata_volume::Level::BASE { 150 } else { 40 });
    }
}

fn fast_and_general_edits_agree_at(level: strata_volume::Level, edits: usize) {
    let mut rng = Rng(99);
    let (mut fast, mut general) = (Volume::with_level(level), Volume::with_level(level));
    for parallel in [false, true] {
        let settings = EditSettings { parallel, ..Default::default() };
        for i in 0..edits {
            let c = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * 48.0;
            // Some radii and centres on exact node values, so span ends fall on nodes and take
            // the snapping path too.
            let r = if i % 7 == 0 { 5.0 } else { 1.0 + rng.unit() * 14.0 };
            let c = if i % 5 == 0 { c.round() } else { c };
            let op = match i % 10 {
                _ if i % 50 == 25 => CsgOp::Intersect,
                0..=5 => CsgOp::Add,
                _ => CsgOp::Subtract,
            };
            let a = if i % 3 == 0 {
                let b = Cuboid::new(c, DVec3::new(r, r * 0.5, r * 0.8)).unwrap();
                let x = fast.apply(op, &b, &settings).unwrap();
                let y = general.apply(op, &general_path(b), &settings).unwrap();
                (x, y)
            } else {
                let s = Sphere::new(c, r).unwrap();
                let x = fast.apply(op, &s, &settings).unwrap();
                let y = general.apply(op, &general_path(s), &settings).unwrap();
                (x, y)
            };
            assert_eq!(a.1.repaired_nodes, 0, "edit {i}: these shapes need no repair");
            assert_eq!(a.0.changed, a.1.changed, "edit {i}: changed chunks");
            assert!(fast == general, "edit {i} ({op:?}): volumes differ");
        }
    }
    fast.check_invariants().unwrap();
    assert!(fast.crossing_stats().total > 1000);
}

#[test]
fn batched_spans_equal_spans_line_by_line() {
    let mut rng = Rng(5);
    let sphere = Sphere::new(DVec3::new(3.3, -2.1, 7.9), 6.5).unwrap();
    let cuboid = Cuboid::new(DVec3::new(1.0, 2.0, 3.0), DVec3::new(4.0, 2.5, 3.5)).unwrap();
    let brushes: [&dyn Brush; 2] = [&sphere, &cuboid];
    let (mut hits, mut misses) = (0, 0);
    for brush in brushes {
        for dir in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(0.6, 0.0, 0.8)] {
            let lines: Vec<(DVec3, DVec3)> = (0..200)
                .map(|_| {
                    let origin = (DVec3::new(rng.unit(), rng.unit(), rng.unit()) * 2.0).floor() * 16.0 - 16.0;
                    let start = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * 16.0;
                    (origin, start)
                })
                .collect();
            let (mut batch, mut counts) = (Vec::new(), Vec::new());
            assert!(brush.spans_batch(&lines, dir, &mut batch, &mut counts));
            let mut expect = Vec::new();
            let mut one = Vec::new();
            for &(o, s) in &lines {
                assert!(brush.spans(o, s, dir, &mut one));
                expect.push(one.clone());
            }
            assert_eq!(counts, expect.iter().map(|v| v.len() as u32).collect::<Vec<_>>());
            assert_eq!(batch, expect.concat());
            hits += counts.iter().filter(|&&c| c > 0).count();
            misses += counts.iter().filter(|&&c| c == 0).count();
        }
    }
    assert!(hits > 100 && misses > 100, "hits {hits}, misses {misses}");
}

#[test]
fn a_brush_that_answers_only_some_lines_is_sampled_and_still_exact() {
    // A sphere that answers some lines in closed form and asks to be sampled on others.
    let inner = Sphere::new(DVec3::new(20.3, 19.6, 21.1), 9.4).unwrap();
    let brush = Tweaked { inner, agree: true, spans_below_y: 20.0 };
    let mut v = Volume::new();
    for parallel in [false, true] {
        v.apply(CsgOp::Add, &brush, &EditSettings { parallel, ..Default::default() }).unwrap();
        v.check_invariants().unwrap();
        for z in 8..34 {
            for y in 8..34 {
                for x in 8..34 {
                    let node = glam::I64Vec3::new(x, y, z);
                    let expect = strata_volume::brush_contains_node(&brush, node, strata_volume::Level::BASE);
                    assert_eq!(v.node_inside(node), expect, "node {node}");
                }
            }
        }
    }
}

#[test]
fn large_brushes_give_the_same_volume_on_one_thread_and_in_parallel() {
    // Big enough that the span table is built an axis per task and in runs of rows (over 32,768
    // lines an axis), with a mixed-answer brush among them whose table is abandoned midway.
    let big = Sphere::new(DVec3::new(3.7, -11.2, 5.9), 120.0).unwrap();
    let hole = Cuboid::new(DVec3::new(-20.5, 10.25, 3.0), DVec3::new(90.0, 30.0, 70.0)).unwrap();
    let mixed =
        Tweaked { inner: Sphere::new(DVec3::new(60.2, 0.4, -8.8), 100.0).unwrap(), agree: true, spans_below_y: 0.0 };
    let mut volumes = Vec::new();
    for parallel in [false, true] {
        let settings = EditSettings { parallel, ..Default::default() };
        let mut v = Volume::new();
        v.apply(CsgOp::Add, &big, &settings).unwrap();
        v.apply(CsgOp::Subtract, &hole, &settings).unwrap();
        v.apply(CsgOp::Add, &mixed, &settings).unwrap();
        volumes.push(v);
    }
    assert!(volumes[0] == volumes[1], "parallel and single-threaded edits differ");
    volumes[1].check_invariants().unwrap();
    assert!(volumes[1].crossing_stats().total > 100_000);
}

#[test]
fn chunks_decided_by_one_distance_value_match_the_general_path() {
    use strata_volume::brush::{Capsule, Cylinder, Torus, Transformed};
    let mut rng = Rng(7);
    let (mut fast, mut general) = (Volume::new(), Volume::new());
    let settings = EditSettings { parallel: true, ..Default::default() };
    for i in 0..24 {
        let c = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * 64.0;
        let c = if i % 4 == 0 { c.round() } else { c };
        let r = 20.0 + rng.unit() * 40.0;
        let brush: Box<dyn Brush> = match i % 6 {
            0 => Box::new(Sphere::new(c, r).unwrap()),
            1 => Box::new(Cuboid::rounded(c, DVec3::new(r, r * 0.7, r * 0.9), 4.0).unwrap()),
            2 => Box::new(Capsule::new(c, c + DVec3::new(30.0, 10.0, -20.0), r * 0.6).unwrap()),
            3 => Box::new(Cylinder::new(c, DVec3::new(0.3, 1.0, 0.2), r, r * 0.8).unwrap()),
            4 => Box::new(Torus::new(c, DVec3::Y, r, r * 0.45).unwrap()),
            _ => Box::new(
                Transformed::new(Sphere::new(DVec3::ZERO, 10.0).unwrap(), glam::DQuat::from_rotation_y(0.4), c, 3.0)
                    .unwrap(),
            ),
        };
        assert!(brush.field_is_distance());
        let op = if i % 3 == 2 { CsgOp::Subtract } else { CsgOp::Add };
        let a = fast.apply(op, brush.as_ref(), &settings).unwrap();
        let b = general.apply(op, &general_path(&brush), &settings).unwrap();
        assert_eq!(a.changed, b.changed, "edit {i}: the same chunks change");
        assert_eq!(fast, general, "edit {i}: the same volume");
    }
    fast.check_invariants().unwrap();
    assert!(fast.chunks().filter(|(_, c)| matches!(c, strata_volume::Chunk::Solid)).count() > 50);
}
