//! What the collaboration tests share: a seeded generator, a starting scene, random strokes as
//! a user makes them (every tool, mirroring, pressure), and chunk digests to compare.
#![allow(dead_code)]

use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::file::{ChunkDigest, chunk_digests};
use strata_editor::{Buttons, Editor, Scene, ToolKind, ToolPose};
use strata_volume::CsgOp;
use strata_volume::brush::Sphere;

/// xorshift64*: seeded, reproducible.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// In `[0, n)`.
    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }

    /// In `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn chance(&mut self, p: f64) -> bool {
        self.range(0.0, 1.0) < p
    }
}

/// A scene with a ball of clay of radius 9 at the origin.
pub fn ball_scene() -> Scene {
    let mut e = Editor::default();
    e.apply(0, CsgOp::Add, &Sphere::new(DVec3::ZERO, 9.0).unwrap()).unwrap();
    e.scene
}

/// One random stroke of a few frames near the ball: a random tool, radius, mirroring and
/// pressure; dab positions on the grid half of the time. (Not the detail tool: chunks it
/// refines make every later dab sixteen times the work, for no more coverage of the network;
/// `strata-editor`'s operation tests replay it.)
pub fn random_stroke(e: &mut Editor, rng: &mut Rng) {
    let tools: Vec<ToolKind> = ToolKind::ALL.into_iter().filter(|k| *k != ToolKind::Detail).collect();
    e.tool.kind = tools[rng.below(tools.len() as u64) as usize];
    e.tool.radius = rng.range(1.5, 4.0);
    e.tool.strength = 0.5;
    e.tool.symmetry = [rng.chance(0.2), false, rng.chance(0.1)];
    e.tool.material = rng.below(3) as u8;
    let snapped = rng.chance(0.5);
    let point = |rng: &mut Rng| {
        let p = DVec3::new(rng.range(-11.0, 11.0), rng.range(-11.0, 11.0), rng.range(-11.0, 11.0));
        if snapped { p.round() } else { p }
    };
    let frames = 1 + rng.below(4);
    let start = point(rng);
    let end = point(rng);
    for k in 0..=frames {
        let at = start.lerp(end, k as f64 / frames as f64);
        let pose = ToolPose {
            position: at,
            orientation: DQuat::IDENTITY,
            pressure: 0.5 + 0.5 * (k as f64 / frames as f64),
            buttons: Buttons { primary: true, secondary: false },
            ..ToolPose::default()
        };
        let _ = e.frame(&pose, Duration::ZERO);
    }
    let _ = e.frame(&ToolPose::at(end, false), Duration::ZERO);
}

pub fn digests(e: &Editor) -> Vec<ChunkDigest> {
    chunk_digests(&e.scene).unwrap()
}

/// A unique temporary folder for one test.
pub fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-collab-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
