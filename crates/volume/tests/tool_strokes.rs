//! Strokes of every sculpting tool keep every invariant and undo exactly (issue 29): random
//! strokes (dabs a quarter radius apart, radius 1–30, centres on nodes, on half-cells and
//! anywhere, mirrored across a node plane) of smoothing (all three methods), inflate and
//! deflate, flatten, clay and its erase, pinch, grab, paint, and stamps raised and carved at
//! any turn (issue 32), with every falloff shape and an edited curve, on volumes whose shapes sit on
//! nodes and grid planes, half of them with chunks at finer levels. After every dab:
//! `check_invariants` (what the loader requires); after the stroke, undoing its dabs in reverse
//! gives the volume back bit for bit.
//!
//! Cases default to 12; `PROPTEST_CASES=200 cargo test -p strata-volume --test tool_strokes
//! --release` runs a longer search.

use glam::DVec3;
use proptest::prelude::*;
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::tools::{self, BuiltinStamp, Dab, Falloff, FalloffCurve, Smoothing, StampPlacement};
use strata_volume::{ChunkKey, EditReport, Level, Volume};

/// The tools, by number.
const TOOLS: u8 = 14;

fn dab_of(v: &mut Volume, tool: u8, dab: &Dab, dir: DVec3) -> EditReport {
    let r = dab.radius;
    let result = match tool {
        0 => tools::smooth(v, dab, Smoothing::VolumePreserving, 4),
        1 => tools::smooth(v, dab, Smoothing::Laplacian, 2),
        2 => tools::smooth(v, dab, Smoothing::Endpoints, 1),
        3 => tools::inflate(v, dab, 0.2 * r),
        4 => tools::inflate(v, dab, -0.2 * r),
        5 => tools::flatten(v, dab),
        6 => tools::clay(v, dab, 0.5 * r, false),
        7 => tools::clay(v, dab, 0.5 * r, true),
        8 => tools::pinch(v, dab, Some(dir), 0.5),
        9 => tools::pinch(v, dab, None, -0.5),
        10 => tools::grab(v, dab, dir * 0.25 * r),
        11 => tools::paint(v, dab),
        // Stamps turned every way: up along the stroke, turned further by an angle of it, and
        // mirrored for the carving one.
        12 | 13 => {
            let (stamp, height) =
                if tool == 12 { (BuiltinStamp::Star, 0.3 * r) } else { (BuiltinStamp::Cells, -0.25 * r) };
            let placement = StampPlacement { up: dir, angle: dir.x.atan2(dir.z) * 3.0, mirrored: tool == 13 };
            tools::stamp(v, dab, &stamp.image(), &placement, height)
        }
        _ => unreachable!("tool {tool}"),
    };
    match result {
        Ok(report) => report,
        // A large dab over fine chunks may need a region past the node limit: a clear refusal
        // that changes nothing (the stroke's undo check sees any change), not a failure.
        Err(tools::ToolError::Region(tools::RegionError::TooLarge { .. })) => EditReport::default(),
        Err(e) => panic!("tool {tool} refused a valid dab {dab:?}: {e}"),
    }
}

/// Every named falloff, and an edited curve with a plateau and a sharp drop near the rim.
fn falloff_of(k: usize) -> Falloff {
    match Falloff::NAMED.get(k) {
        Some(&f) => f,
        None => Falloff::Curve(FalloffCurve::new(&[(0.0, 0.6), (0.4, 1.0), (0.9, 0.95), (1.0, 0.0)]).unwrap()),
    }
}

/// The scene: two or three shapes whose centres and sizes are in quarter cells (on nodes, on
/// half-cells, on grid planes), some chunks raised to finer levels.
fn scene(shapes: &[(u8, [i32; 3], i32)], fine: &[(u8, i8)]) -> Volume {
    let mut v = Volume::new();
    for &(kind, c, size) in shapes {
        let c = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * 0.25;
        let s = size as f64 * 0.25;
        match kind {
            0 => v.add(&Sphere::new(c, s).unwrap()).unwrap(),
            1 => v.add(&Cuboid::new(c, DVec3::new(s, s * 0.75, s * 0.5)).unwrap()).unwrap(),
            _ => v.subtract(&Sphere::new(c, s * 0.5).unwrap()).unwrap(),
        };
    }
    for &(key, level) in fine {
        let k = ChunkKey::new((key & 1) as i32 + 1, ((key >> 1) & 1) as i32 + 1, ((key >> 2) & 1) as i32 + 1);
        v.set_chunk_level(k, Level::new(level).unwrap());
    }
    v
}

/// A radius from 1 to 30, most of them small (large dabs cost a debug build seconds).
fn radius() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => prop::sample::select(vec![1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.5]),
        2 => prop::sample::select(vec![7.0, 9.5, 12.0]),
        1 => prop::sample::select(vec![16.0, 20.0, 30.0]),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|c| c.parse().ok()).unwrap_or(12),
        ..ProptestConfig::default()
    })]

    #[test]
    fn strokes_of_every_tool_keep_the_invariants_and_undo_exactly(
        shapes in prop::collection::vec((0u8..3, prop::array::uniform3(64i32..192), 16i32..64), 2..4),
        fine in prop::collection::vec((0u8..8, prop_oneof![Just(-1i8), Just(1i8), Just(2i8)]), 0..3),
        tool in 0u8..TOOLS,
        r in radius(),
        snap in 0u8..3,
        start in prop::array::uniform3(64i32..192),
        dir in prop::array::uniform3(-8i32..8),
        dabs in 2usize..5,
        strength in prop::sample::select(vec![0.25, 0.5, 1.0]),
        mirrored in any::<bool>(),
        material in 0u16..3,
        falloff in 0usize..8,
    ) {
        let mut v = scene(&shapes, &fine);
        let before = v.clone();
        // Centres on nodes (whole cells), half-cells, or off the grid.
        let snap_to = |p: DVec3| match snap {
            0 => p.round(),
            1 => (p * 2.0).round() * 0.5,
            _ => p + DVec3::new(0.137, 0.291, 0.053),
        };
        let dir = DVec3::new(dir[0] as f64, dir[1] as f64, dir[2] as f64).normalize_or(DVec3::X);
        let start = DVec3::new(start[0] as f64, start[1] as f64, start[2] as f64) * 0.25;
        let mut undo = Vec::new();
        for k in 0..dabs {
            let c = snap_to(start + dir * (k as f64 * 0.25 * r));
            let mut centres = vec![c];
            if mirrored {
                // The image across the node plane x = 24.
                centres.push(DVec3::new(48.0 - c.x, c.y, c.z));
            }
            for c in centres {
                let dab = Dab { material: material as u8, falloff: falloff_of(falloff), ..Dab::new(c, r, strength).unwrap() };
                let report = dab_of(&mut v, tool, &dab, dir);
                if let Err(e) = v.check_invariants() {
                    prop_assert!(false, "tool {} dab {} at {:?} radius {}: {}", tool, k, c, r, e);
                }
                undo.push(report.undo);
            }
        }
        for record in undo.into_iter().rev() {
            v.restore(record);
        }
        prop_assert!(v == before, "undoing the stroke of tool {} did not give the volume back", tool);
    }
}

/// A dab's chunks and its band run in parallel where there are several threads: every tool's
/// strokes give the same volume, bit for bit, on one thread and on four.
#[test]
fn every_tool_gives_the_same_volume_on_one_thread_and_on_four() {
    let shapes = [(0u8, [96, 100, 104], 60), (1, [130, 96, 110], 40), (2, [110, 120, 100], 40)];
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let four = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
    for tool in 0..TOOLS {
        for (r, fine) in [(12.0, vec![]), (20.0, vec![(0u8, 1i8)])] {
            let run = |pool: &rayon::ThreadPool| {
                pool.install(|| {
                    let mut v = scene(&shapes, &fine);
                    let dir = DVec3::new(0.6, 0.8, 0.0);
                    let mut changed = Vec::new();
                    for k in 0..4 {
                        let c = DVec3::new(24.0, 25.0, 14.0) + dir * (k as f64 * 0.25 * r);
                        let dab = Dab { material: 1, ..Dab::new(c, r, 0.5).unwrap() };
                        changed.push(dab_of(&mut v, tool, &dab, dir).changed);
                    }
                    (v, changed)
                })
            };
            let (a, b) = (run(&one), run(&four));
            assert!(
                a.1.iter().any(|c| !c.is_empty()),
                "tool {tool} at radius {r} changed nothing: a test that cannot fail"
            );
            assert_eq!(a.1, b.1, "tool {tool} at radius {r}: the changed chunks differ");
            assert!(a.0 == b.0, "tool {tool} at radius {r}: the volumes differ between one thread and four");
        }
    }
}
