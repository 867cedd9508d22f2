//! Island removal against a brute-force model: random unions and differences of boxes whose
//! faces lie halfway between nodes (so the node states are exact), their pieces found by a flood
//! fill over a dense grid of nodes, and the small pieces removed from both.

use std::collections::{BTreeMap, HashSet, VecDeque};

use glam::{DVec3, I64Vec3, IVec3};
use proptest::prelude::*;
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::islands::IslandError;
use strata_volume::{Axis, Chunk, ChunkKey, Level, Volume};

/// The dense model's box of nodes: it spans chunks -2..=2 on every axis, across the origin.
const LO: i64 = -20;
const HI: i64 = 36;

/// A box holding exactly the nodes `lo..=hi`.
fn node_box(lo: I64Vec3, hi: I64Vec3) -> Cuboid {
    let (a, b) = (lo.as_dvec3() - DVec3::splat(0.5), hi.as_dvec3() + DVec3::splat(0.5));
    Cuboid::new((a + b) / 2.0, (b - a) / 2.0).unwrap()
}

#[derive(Clone, Debug)]
struct Edit {
    add: bool,
    lo: I64Vec3,
    hi: I64Vec3,
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    let corner = || (LO + 1..HI - 1, LO + 1..HI - 1, LO + 1..HI - 1);
    let size = || (0i64..9, 0i64..9, 0i64..9);
    prop::collection::vec((any::<bool>(), corner(), size()), 1..10).prop_map(|v| {
        v.into_iter()
            .enumerate()
            .map(|(i, (add, (x, y, z), (a, b, c)))| {
                let lo = I64Vec3::new(x, y, z);
                let hi = (lo + I64Vec3::new(a, b, c)).min(I64Vec3::splat(HI - 1));
                // The first edit always adds.
                Edit { add: add || i == 0, lo, hi }
            })
            .collect()
    })
}

/// The node states of the model, `[x][y][z]` from `LO`.
struct Dense {
    inside: Vec<bool>,
}

impl Dense {
    const SIDE: usize = (HI - LO) as usize;

    fn index(p: I64Vec3) -> Option<usize> {
        let q = p - I64Vec3::splat(LO);
        let s = Self::SIDE as i64;
        (q.cmpge(I64Vec3::ZERO).all() && q.cmplt(I64Vec3::splat(s)).all()).then(|| (q.x + s * (q.y + s * q.z)) as usize)
    }

    fn nodes() -> impl Iterator<Item = I64Vec3> {
        (LO..HI).flat_map(|z| (LO..HI).flat_map(move |y| (LO..HI).map(move |x| I64Vec3::new(x, y, z))))
    }

    fn new(edits: &[Edit]) -> Self {
        let mut inside = vec![false; Self::SIDE.pow(3)];
        for p in Self::nodes() {
            let i = Self::index(p).unwrap();
            for e in edits {
                if p.cmpge(e.lo).all() && p.cmple(e.hi).all() {
                    inside[i] = e.add;
                }
            }
        }
        Dense { inside }
    }

    fn at(&self, p: I64Vec3) -> bool {
        Self::index(p).is_some_and(|i| self.inside[i])
    }

    /// The pieces by a flood fill over the six neighbours.
    fn pieces(&self) -> Vec<Vec<I64Vec3>> {
        let mut seen = vec![false; self.inside.len()];
        let mut out = Vec::new();
        for p in Self::nodes() {
            let i = Self::index(p).unwrap();
            if !self.inside[i] || seen[i] {
                continue;
            }
            seen[i] = true;
            let mut piece = Vec::new();
            let mut queue = VecDeque::from([p]);
            while let Some(q) = queue.pop_front() {
                piece.push(q);
                for d in [I64Vec3::X, I64Vec3::NEG_X, I64Vec3::Y, I64Vec3::NEG_Y, I64Vec3::Z, I64Vec3::NEG_Z] {
                    if let Some(j) = Self::index(q + d)
                        && self.inside[j]
                        && !seen[j]
                    {
                        seen[j] = true;
                        queue.push_back(q + d);
                    }
                }
            }
            out.push(piece);
        }
        out
    }
}

fn volume_of(edits: &[Edit]) -> Volume {
    let mut v = Volume::new();
    for e in edits {
        let b = node_box(e.lo, e.hi);
        if e.add {
            v.add(&b).unwrap();
        } else {
            v.subtract(&b).unwrap();
        }
    }
    v
}

/// Every stored crossing: (chunk, axis, line across, position).
fn crossings(v: &Volume) -> BTreeMap<(ChunkKey, usize, usize, usize), Vec<u16>> {
    let mut out = BTreeMap::new();
    for (key, chunk) in v.chunks() {
        let Chunk::Lists(l) = chunk else { continue };
        let n = l.level().cells();
        for axis in Axis::ALL {
            for vv in 0..n {
                for u in 0..n {
                    let line = l.line(axis, u, vv);
                    if !line.is_empty() {
                        out.insert((key, axis.index(), u, vv), line.positions().map(|q| q.0).collect());
                    }
                }
            }
        }
    }
    out
}

/// The two nodes of the edge a stored crossing lies in (base level).
fn edge_nodes(key: ChunkKey, axis: usize, u: usize, v: usize, q: u16) -> [I64Vec3; 2] {
    let e = strata_volume::coords::edge_of(strata_volume::coords::LocalPos(q), Level::BASE) as i64;
    let axis = Axis::ALL[axis];
    let (ua, va) = axis.across();
    let mut p = key.origin_grid();
    p[axis.index()] += e;
    p[ua.index()] += u as i64;
    p[va.index()] += v as i64;
    [p, p + axis.unit_i64()]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn islands_match_a_dense_flood_fill_and_only_they_are_removed(edits in edits(), min in 0u64..40) {
        let model = Dense::new(&edits);
        let mut volume = volume_of(&edits);
        for p in Dense::nodes() {
            prop_assert_eq!(volume.node_inside(p), model.at(p), "node {} before removal", p);
        }
        let pieces = model.pieces();
        let mut sizes: Vec<u64> = pieces.iter().map(|p| p.len() as u64).collect();
        sizes.sort_unstable_by(|a, b| b.cmp(a));
        prop_assert_eq!(volume.piece_sizes().unwrap(), sizes.clone());

        let largest = sizes.first().copied().unwrap_or(0);
        let removed: HashSet<I64Vec3> = pieces
            .iter()
            .filter(|p| (p.len() as u64) < largest && (p.len() as u64) < min)
            .flatten()
            .copied()
            .collect();
        let islands = pieces.iter().filter(|p| (p.len() as u64) < largest && (p.len() as u64) < min).count();
        let before = volume.clone();
        let before_crossings = crossings(&volume);
        let report = volume.remove_islands(min as f64).unwrap();
        prop_assert_eq!(report.removed, islands);
        prop_assert_eq!(report.kept, pieces.len() - islands);
        prop_assert_eq!(report.removed_nodes, removed.len() as u64);
        prop_assert!((report.removed_volume - removed.len() as f64).abs() < 1e-9);
        volume.check_invariants().unwrap();
        for p in Dense::nodes() {
            let expected = model.at(p) && !removed.contains(&p);
            prop_assert_eq!(volume.node_inside(p), expected, "node {} after removal", p);
        }
        // Every crossing not next to a removed node stays where it was; none is added.
        let mut expected = before_crossings.clone();
        for ((key, axis, u, v), list) in expected.iter_mut() {
            list.retain(|&q| edge_nodes(*key, *axis, *u, *v, q).iter().all(|n| !removed.contains(n)));
        }
        expected.retain(|_, l| !l.is_empty());
        prop_assert_eq!(crossings(&volume), expected);
        // One undo gives back every island.
        volume.restore(report.edit.undo);
        prop_assert_eq!(crossings(&volume), before_crossings);
        for p in Dense::nodes() {
            prop_assert_eq!(volume.node_inside(p), before.node_inside(p));
        }
    }
}

#[test]
fn a_stray_node_beside_a_sphere_is_removed_and_counted() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(8.3, 8.1, 7.9), 10.0).unwrap()).unwrap();
    v.add(&node_box(I64Vec3::new(40, 8, 8), I64Vec3::new(40, 8, 8))).unwrap();
    // Two nodes touching only diagonally: separate pieces of one node each.
    v.add(&node_box(I64Vec3::new(-30, 0, 0), I64Vec3::new(-30, 0, 0))).unwrap();
    v.add(&node_box(I64Vec3::new(-29, 1, 0), I64Vec3::new(-29, 1, 0))).unwrap();
    let sizes = v.piece_sizes().unwrap();
    assert_eq!(sizes.len(), 4, "{sizes:?}");
    assert_eq!(&sizes[1..], &[1, 1, 1]);
    let sphere = sizes[0];
    let before = v.clone();
    let report = v.remove_islands(8.0).unwrap();
    assert_eq!((report.removed, report.removed_nodes, report.kept), (3, 3, 1));
    assert_eq!(report.removed_volume, 3.0);
    v.check_invariants().unwrap();
    assert_eq!(v.piece_sizes().unwrap(), vec![sphere]);
    assert!(!v.node_inside(I64Vec3::new(40, 8, 8)));
    assert!(v.node_inside(I64Vec3::new(8, 8, 8)));
    // The chunk that held only the speck is gone; the sphere's chunks are untouched.
    assert!(v.chunk(ChunkKey(IVec3::new(2, 0, 0))).is_none());
    for (key, chunk) in before.chunks() {
        if key.0.x >= 0 && key.0.x <= 1 {
            assert_eq!(v.chunk(key), Some(chunk), "chunk {key:?} of the sphere");
        }
    }
}

#[test]
fn a_zero_threshold_removes_nothing_and_bad_thresholds_are_refused() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(8.3, 8.1, 7.9), 6.0).unwrap()).unwrap();
    v.add(&node_box(I64Vec3::new(30, 8, 8), I64Vec3::new(30, 8, 8))).unwrap();
    let before = v.clone();
    let report = v.remove_islands(0.0).unwrap();
    assert_eq!((report.removed, report.kept), (0, 2));
    assert!(report.edit.changed.is_empty());
    for bad in [f64::NAN, -1.0, f64::INFINITY] {
        assert!(matches!(v.remove_islands(bad), Err(IslandError::BadThreshold(_))), "{bad} is refused");
    }
    assert_eq!(crossings(&v), crossings(&before));
    // The largest piece is kept however large the threshold: a small solid is never emptied.
    let report = v.remove_islands(1e12).unwrap();
    assert_eq!((report.removed, report.kept), (1, 1));
    assert!(!v.is_empty());
    // An empty volume has nothing to remove.
    assert_eq!(Volume::new().remove_islands(8.0).unwrap().kept, 0);
}

#[test]
fn finer_levels_count_nodes_as_fractions_of_a_cell_and_mixed_levels_are_refused() {
    let fine = Level::new(1).unwrap();
    let mut v = Volume::with_level(fine);
    v.add(&Sphere::new(DVec3::new(8.3, 8.1, 7.9), 5.0).unwrap()).unwrap();
    // One node of spacing 0.5 at grid (20, 8, 8): node (40, 16, 16).
    v.add(&Cuboid::new(DVec3::new(20.0, 8.0, 8.0), DVec3::splat(0.2)).unwrap()).unwrap();
    let report = v.remove_islands(1.0).unwrap();
    assert_eq!((report.removed, report.removed_nodes), (1, 1));
    assert_eq!(report.removed_volume, 0.125, "a node of a level-1 chunk is an eighth of a cell");
    v.check_invariants().unwrap();
    assert!(!v.node_inside(I64Vec3::new(40, 16, 16)));
    // Chunks of two levels in one volume.
    let chunks: Vec<(ChunkKey, Chunk)> = v.chunks().map(|(k, c)| (k, c.clone())).collect();
    let mut base = Volume::new();
    base.add(&Sphere::new(DVec3::new(40.0, 8.0, 8.0), 4.0).unwrap()).unwrap();
    let mixed =
        Volume::from_chunks(Level::BASE, 1.0, chunks.into_iter().chain(base.chunks().map(|(k, c)| (k, c.clone()))));
    let mut mixed = mixed.unwrap();
    assert!(!mixed.single_level());
    assert!(matches!(mixed.remove_islands(8.0), Err(IslandError::MixedLevels)));
    assert!(mixed.piece_sizes().is_none());
}
