//! Dual contouring across chunks of different levels: closed on random level maps (counted both
//! after a weld by position of the chunk meshes and in the welded mesh's own indices), with the
//! non-manifold edges at mixed levels measured.

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use strata_mesh::checks::{manifold_report, weld_by_position};
use strata_mesh::{DualCache, Mesh};
use strata_volume::brush::{Brush, Cuboid, Sphere};
use strata_volume::{ChunkKey, Level, Volume};

/// Edges used more often in one direction than in the other (0: closed and consistently
/// oriented, manifold or not).
fn unbalanced_edges(m: &Mesh) -> usize {
    let mut uses: std::collections::HashMap<(u32, u32), i32> = std::collections::HashMap::new();
    for [a, b, c] in m.triangles() {
        for (p, q) in [(a, b), (b, c), (c, a)] {
            *uses.entry((p.min(q), p.max(q))).or_default() += if p < q { 1 } else { -1 };
        }
    }
    uses.values().filter(|&&c| c != 0).count()
}

/// What a dual-contouring mesh of `v` looks like at its seams.
#[derive(Debug, Default, Clone, Copy)]
struct Seams {
    /// Open edges after welding the chunk meshes by position.
    open_by_position: usize,
    /// Open edges of the mesh welded by cell and component (the project's own indices).
    open_in_own_indices: usize,
    /// Edges of the welded mesh not traversed as often one way as the other.
    unbalanced: usize,
    /// Edges of the welded mesh with more than two triangles.
    non_manifold: usize,
    /// Edges of the welded mesh.
    edges: usize,
}

fn seams(v: &Volume) -> Seams {
    let cache = DualCache::build(v);
    let by_position = weld_by_position(cache.iter().map(|(k, m)| (k, &m.mesh)));
    let own = cache.welded();
    let r = manifold_report(&own);
    Seams {
        open_by_position: manifold_report(&by_position).boundary,
        open_in_own_indices: r.boundary,
        unbalanced: unbalanced_edges(&own),
        non_manifold: r.non_manifold,
        edges: r.edges,
    }
}

fn level(k: i8) -> Level {
    Level::new(k).expect("levels 0 to 2 exist")
}

/// Issue 28, defect 2: a coarse cell beside a finer chunk has two surface components, and the
/// face it shares with the finer chunk is cut by the second one only; the finer edges inside
/// that face took the first, so four polygon edges near (9.75, 16.35, 17.80) stayed open.
#[test]
fn a_finer_edge_inside_a_coarse_face_takes_the_component_of_its_segment() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(6.0, 15.0, 15.75), 4.5).unwrap()).unwrap();
    v.subtract(&Sphere::new(DVec3::new(6.75, 14.0, 18.25), 3.75).unwrap()).unwrap();
    v.set_chunk_level(ChunkKey::new(0, 0, 1), level(1));
    let s = seams(&v);
    assert!(s.edges > 1000, "the scene has a surface: {s:?}");
    assert_eq!(s.open_by_position, 0, "open edges after a weld by position: {s:?}");
    assert_eq!(s.open_in_own_indices, 0, "open edges in the mesh's own indices: {s:?}");
    assert_eq!(s.unbalanced, 0, "closed and consistently oriented: {s:?}");
}

/// A ball with one raised chunk: the raised chunk owns the edges of the face it shares with the
/// chunk after it, so its mesh copies that chunk's cells near their `−` face, shifted by +16 into
/// its own frame; rounded there, 32 edges stayed open after a weld by position (none in the
/// welded mesh's own indices).
#[test]
fn chunk_meshes_at_mixed_levels_hold_shared_vertices_at_one_position() {
    let mut v = Volume::new();
    v.add(
        &Sphere::new(DVec3::new(8.0, 13.798_460_407_639_17, 23.623_605_760_335_526), 11.229_299_615_993_614).unwrap(),
    )
    .unwrap();
    v.set_chunk_level(ChunkKey::new(0, 0, 1), level(1));
    let s = seams(&v);
    assert!(s.edges > 1000, "the scene has a surface: {s:?}");
    assert_eq!(s.open_by_position, 0, "open edges after a weld by position: {s:?}");
    assert_eq!(s.open_in_own_indices, 0, "open edges in the mesh's own indices: {s:?}");
}

/// One random edit or level change.
#[derive(Clone, Debug)]
enum Step {
    /// Add or subtract a sphere (shape 0), box (1) or rotated box (2) at `c` with size `size`
    /// (grid units), or add a thin crescent (3: a ball less a shifted smaller one, which gives
    /// cells of several components on the seams: without it one case in 15 met the issue-28
    /// defect, with it one in 6); `c` and `size` snapped per `snap`: 0 not at all, 1 to level-0
    /// nodes, 2 to half cells, 3 to quarter cells (nodes of every level).
    Edit { subtract: bool, shape: u8, snap: u8, c: [f64; 3], size: [f64; 3], angle: f64 },
    /// The chunk `key` (in the 2×2×2 block at the origin) to `level`.
    Level { key: [i32; 3], level: i8 },
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        3 => (any::<bool>(), 0u8..4, 0u8..4, prop::array::uniform3(9.0f64..23.0), prop::array::uniform3(0.6f64..5.0), 0.0f64..3.0)
            .prop_map(|(subtract, shape, snap, c, size, angle)| Step::Edit { subtract, shape, snap, c, size, angle }),
        // Levels 0 and 2 as often as 1: neighbours two levels apart are common.
        2 => (prop::array::uniform3(0i32..2), -1i8..3).prop_map(|(key, level)| Step::Level { key, level }),
    ]
}

fn apply(v: &mut Volume, s: &Step) {
    match *s {
        Step::Edit { subtract, shape, snap, c, size, angle } => {
            let q = [0.0, 1.0, 0.5, 0.25][snap as usize];
            let snapped = |x: f64| if q > 0.0 { ((x / q).round() * q).max(q) } else { x };
            let c = DVec3::from_array(c.map(snapped));
            let size = DVec3::from_array(size.map(snapped));
            let brush: Box<dyn Brush> = match shape {
                0 => Box::new(Sphere::new(c, size.x).unwrap()),
                1 => Box::new(Cuboid::new(c, size).unwrap()),
                2 => Box::new(Cuboid::oriented(c, size, DQuat::from_rotation_y(angle), 0.0).unwrap()),
                _ => {
                    // A thin crescent: a ball less a slightly smaller, shifted one.
                    let r = size.x + 1.0;
                    v.add(&Sphere::new(c, r).unwrap()).unwrap();
                    let shift = DVec3::new(angle.cos(), size.y / 8.0 - 0.5, angle.sin()) * (0.25 * r);
                    Box::new(Sphere::new(c + shift, 0.85 * r).unwrap())
                }
            };
            let subtract = subtract || shape == 3;
            if subtract { v.subtract(brush.as_ref()) } else { v.add(brush.as_ref()) }.unwrap();
        }
        Step::Level { key, level: l } => {
            v.set_chunk_level(ChunkKey::new(key[0], key[1], key[2]), level(l));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Random level maps (chunks of a 2×2×2 block raised to levels 1 or 2 and lowered again,
    /// neighbours up to two levels apart) with random spheres and boxes added and subtracted
    /// before and after, on and off the grid: after every step the dual-contouring mesh has no
    /// open edge, neither after a weld by position nor in its own indices, and every edge is
    /// traversed as often one way as the other.
    #[test]
    fn dual_contouring_is_closed_on_random_level_maps(
        first in prop::array::uniform3(8.0f64..24.0),
        radius in 4.0f64..12.0,
        steps in prop::collection::vec(step(), 1..8),
    ) {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::from_array(first), radius).unwrap()).unwrap();
        for s in &steps {
            apply(&mut v, s);
            let r = seams(&v);
            prop_assert_eq!(r.open_by_position, 0, "open edges by position after {:?}: {:?}", s, r);
            prop_assert_eq!(r.open_in_own_indices, 0, "open edges in own indices after {:?}: {:?}", s, r);
            prop_assert_eq!(r.unbalanced, 0, "unbalanced edges after {:?}: {:?}", s, r);
        }
    }
}

/// `apply` that says which chunks the step changed.
fn apply_reporting(v: &mut Volume, s: &Step) -> Vec<ChunkKey> {
    let before = v.clone();
    apply(v, s);
    // (A crescent is two edits: every chunk either may touch, from the stored chunks' contents.)
    let mut keys: Vec<ChunkKey> = before.chunks().chain(v.chunks()).map(|(k, _)| k).collect();
    keys.sort();
    keys.dedup();
    keys.retain(|&k| before.chunk(k) != v.chunk(k) || before.stored_level(k) != v.stored_level(k));
    keys
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// The cache kept across levels by incremental updates (cells around each change, polygons
    /// around the chunks whose cells or levels moved) holds, after every step, the meshes a
    /// fresh build of the volume gives.
    #[test]
    fn incremental_updates_across_levels_equal_a_fresh_build(
        first in prop::array::uniform3(8.0f64..24.0),
        radius in 4.0f64..12.0,
        steps in prop::collection::vec(step(), 1..8),
    ) {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::from_array(first), radius).unwrap()).unwrap();
        v.set_chunk_level(ChunkKey::new(1, 1, 1), level(1));
        let mut cache = DualCache::build(&v);
        for s in &steps {
            let changed = apply_reporting(&mut v, s);
            cache.update(&v, &changed);
            if v.single_level() {
                continue; // (a fresh build joins one level; the cache keeps joining across)
            }
            let fresh = DualCache::build(&v);
            let mine: std::collections::BTreeMap<ChunkKey, &Mesh> = cache.iter().map(|(k, m)| (k, &m.mesh)).collect();
            let theirs: std::collections::BTreeMap<ChunkKey, &Mesh> = fresh.iter().map(|(k, m)| (k, &m.mesh)).collect();
            prop_assert_eq!(mine.keys().collect::<Vec<_>>(), theirs.keys().collect::<Vec<_>>(), "chunks after {:?}", s);
            for (k, m) in &mine {
                prop_assert!(*m == theirs[k], "chunk {:?}'s mesh after {:?}", k, s);
            }
        }
    }
}

/// A fixed-seed generator (the measured count below must not move with a library's RNG).
struct Lcg(u64);

impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn pick(&mut self, n: usize) -> usize {
        ((self.unit() * n as f64) as usize).min(n - 1)
    }
}

/// The same kind of scenes from a fixed seed, for a number to state: manifold dual contouring
/// at mixed levels is closed but not proven edge-manifold (the tunnel-face midpoints of one
/// level are not built there, and a seam can meet such a face); docs/ARCHITECTURE.md states the
/// count measured here.
#[test]
fn non_manifold_edges_at_mixed_levels_are_measured() {
    let mut rng = Lcg(28);
    let (mut steps, mut edges, mut non_manifold, mut single_non_manifold) = (0, 0, 0, 0);
    for _ in 0..30 {
        let mut v = Volume::new();
        let c = DVec3::new(8.0 + 16.0 * rng.unit(), 8.0 + 16.0 * rng.unit(), 8.0 + 16.0 * rng.unit());
        v.add(&Sphere::new(c, 4.0 + 8.0 * rng.unit()).unwrap()).unwrap();
        for _ in 0..2 + rng.pick(8) {
            let s = if rng.pick(5) < 3 {
                Step::Edit {
                    subtract: rng.pick(2) == 1,
                    shape: rng.pick(4) as u8,
                    snap: rng.pick(4) as u8,
                    c: [0; 3].map(|_| 9.0 + 14.0 * rng.unit()),
                    size: [0; 3].map(|_| 0.6 + 4.4 * rng.unit()),
                    angle: 3.0 * rng.unit(),
                }
            } else {
                Step::Level { key: [0; 3].map(|_| rng.pick(2) as i32), level: rng.pick(4) as i8 - 1 }
            };
            apply(&mut v, &s);
            if v.single_level() {
                continue;
            }
            let r = seams(&v);
            assert_eq!((r.open_by_position, r.open_in_own_indices, r.unbalanced), (0, 0, 0), "closed after {s:?}");
            steps += 1;
            edges += r.edges;
            non_manifold += r.non_manifold;
            single_non_manifold += manifold_report(&DualCache::build_single_vertex(&v).welded()).non_manifold;
        }
    }
    eprintln!(
        "mixed levels, {steps} scenes: {non_manifold} non-manifold edges of {edges}; one vertex a cell: {single_non_manifold}"
    );
    assert!(steps > 50, "the scenes mix levels: {steps}");
    assert!(
        non_manifold * 10 < single_non_manifold,
        "one vertex per component stays far more manifold than one per cell at mixed levels too"
    );
}
