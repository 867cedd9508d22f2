//! What the collaboration tests share: a seeded generator, a starting scene, random strokes as
//! a user makes them (every tool, mirroring, pressure), and chunk digests to compare.

use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::file::{ChunkDigest, chunk_digests};
use strata_editor::{Buttons, Editor, Scene, ToolKind, ToolPose};
use strata_volume::CsgOp;
use strata_volume::brush::Sphere;

/// xorshift64*: seeded, reproducible.
#[derive(Debug)]
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn bits(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// In `[0, n)`.
    pub fn below(&mut self, n: u64) -> u64 {
        self.bits() % n.max(1)
    }

    /// In `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.bits() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// True with probability `p`.
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
    // (Mask strokes are left out too: they kept the random streams of these tests as they were
    // before masks; their replay is covered by the editor's operation tests.)
    let tools: Vec<ToolKind> = ToolKind::ALL.into_iter().filter(|k| *k != ToolKind::Detail && !k.is_mask()).collect();
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

/// The chunk digests of an editor's scene.
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

/// An editor in a room.
#[derive(Debug)]
pub struct Member {
    /// Its editor.
    pub editor: Editor,
    /// Its session.
    pub session: strata_net::Session,
    /// Events that say something went wrong (divergence, out of step), for the test to check.
    pub trouble: Vec<strata_net::Event>,
    /// Why the server closed connections, in order.
    pub closed: Vec<String>,
}

impl Member {
    /// Joins `room` at `url` (hosting it with `scene` when given).
    pub fn new(url: &str, room: &str, token: &str, name: &str, scene: Option<&Scene>) -> Member {
        let session = match scene {
            Some(s) => strata_net::Session::host(url, room, token, name, s).unwrap(),
            None => strata_net::Session::join(url, room, token, name).unwrap(),
        };
        Member { editor: Editor::default(), session, trouble: Vec::new(), closed: Vec::new() }
    }

    /// Polls once, waiting up to `wait` for something to arrive.
    pub fn poll(&mut self, wait: Duration) {
        let events = self.session.wait(&mut self.editor, wait);
        for e in &events {
            if let strata_net::Event::Closed { reason, .. } = e {
                self.closed.push(reason.clone());
            }
        }
        self.trouble.extend(
            events.into_iter().filter(|e| matches!(e, strata_net::Event::Diverged | strata_net::Event::OutOfStep(_))),
        );
    }

    /// Whether it is in the room, holds the room's scene and has nothing pending.
    pub fn settled(&self) -> bool {
        *self.session.state() == strata_net::SessionState::InRoom
            && self.session.replica().has_scene()
            && self.session.replica().pending() == 0
    }
}

/// Polls every member until all are in the room with nothing pending, at the same operation,
/// and nothing moved for a quarter of a second; panics after `timeout`.
pub fn converge(members: &mut [Member], timeout: Duration) {
    let t0 = std::time::Instant::now();
    let mut stable_since: Option<std::time::Instant> = None;
    let mut last = Vec::new();
    loop {
        for m in members.iter_mut() {
            m.poll(Duration::from_millis(5));
        }
        let seqs: Vec<u64> = members.iter().map(|m| m.session.replica().seq()).collect();
        let done = members.iter().all(Member::settled) && seqs.iter().all(|s| *s == seqs[0]);
        if done && seqs == last {
            let since = *stable_since.get_or_insert_with(std::time::Instant::now);
            if since.elapsed() > Duration::from_millis(250) {
                return;
            }
        } else {
            stable_since = None;
        }
        last = seqs;
        assert!(
            t0.elapsed() < timeout,
            "no convergence within {timeout:?}: {:?}",
            members
                .iter()
                .map(|m| (
                    m.session.state().clone(),
                    m.session.replica().seq(),
                    m.session.replica().pending(),
                    m.closed.iter().rev().take(3).cloned().collect::<Vec<_>>()
                ))
                .collect::<Vec<_>>()
        );
    }
}

/// The PostgreSQL URL the database tests use (`STRATA_PG_URL`, which `.ci/run` sets after
/// starting a server), or `None` with a message where they may be skipped: everywhere but CI,
/// where its absence fails the test.
pub fn pg_url() -> Option<String> {
    match std::env::var("STRATA_PG_URL") {
        Ok(url) => Some(url),
        Err(_) if std::env::var_os("CI").is_some() => {
            panic!("STRATA_PG_URL is not set: CI must start PostgreSQL (see .ci/run)")
        }
        Err(_) => {
            eprintln!("skipped: set STRATA_PG_URL=postgres://… to run the PostgreSQL tests");
            None
        }
    }
}

/// A room name no earlier run used (PostgreSQL keeps rooms between runs).
pub fn fresh_room(name: &str) -> String {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos();
    format!("{name}-{}-{nanos}", std::process::id())
}
