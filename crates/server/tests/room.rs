//! A room and its replicas without sockets: messages travel through queues that deliver in
//! random amounts at random moments, connections drop (whatever was in flight is lost) and
//! resume, clients sculpt random strokes all the while, and at the end every replica's chunk
//! digests equal the room's. Run over many seeds, this searches interleavings the loopback
//! tests cannot steer.

use std::collections::VecDeque;

use strata_editor::Editor;
use strata_net::protocol::{ClientMsg, ServerMsg, decode};
use strata_net::{Event, Replica};
use strata_server::room::{ConnId, Handled, Out, Room, RoomConfig, token_hash};
use strata_server::store::StoredRoom;
use strata_tests::collab::{Rng, ball_scene, digests, random_stroke};

struct Client {
    editor: Editor,
    replica: Replica,
    /// Its connection, while connected.
    conn: Option<ConnId>,
    /// Client → room, in flight.
    up: VecDeque<ClientMsg>,
    /// Room → client, in flight.
    down: VecDeque<ServerMsg>,
    refused: usize,
    undone: usize,
    snapshots: usize,
}

struct World {
    room: Room,
    clients: Vec<Client>,
    next_conn: ConnId,
}

impl World {
    fn deliver(&mut self, h: Handled) {
        for o in h.out {
            let (conn, msg) = match o {
                Out::Send(conn, bytes) => (conn, decode::<ServerMsg>(&bytes, usize::MAX).unwrap()),
                Out::Close(conn, reason) => (conn, ServerMsg::Error { reason, retry: false }),
            };
            if let Some(c) = self.clients.iter_mut().find(|c| c.conn == Some(conn)) {
                c.down.push_back(msg);
            }
        }
    }

    fn connect(&mut self, i: usize) {
        self.next_conn += 1;
        let conn = self.next_conn;
        let c = &mut self.clients[i];
        c.conn = Some(conn);
        let ClientMsg::Hello(hello) = c.replica.hello("r", "secret", &format!("c{i}"), None) else { unreachable!() };
        assert!(self.room.admits(&hello.token));
        let h = self.room.join(conn, hello);
        self.deliver(h);
    }

    fn drop_connection(&mut self, i: usize) {
        let c = &mut self.clients[i];
        let Some(conn) = c.conn.take() else { return };
        c.up.clear();
        c.down.clear();
        c.replica.disconnected();
        let mut h = Handled::default();
        self.room.leave(conn, &mut h);
        self.deliver(h);
    }

    /// Up to `n` of client `i`'s messages reach the room.
    fn pump_up(&mut self, i: usize, n: usize) {
        let Some(conn) = self.clients[i].conn else { return };
        let mut h = Handled::default();
        for _ in 0..n {
            let Some(msg) = self.clients[i].up.pop_front() else { break };
            self.room.handle(conn, msg, &mut h);
        }
        self.deliver(h);
    }

    /// Up to `n` of the room's messages reach client `i` (and what it sends is queued).
    fn pump_down(&mut self, i: usize, n: usize) {
        let c = &mut self.clients[i];
        let take = n.min(c.down.len());
        let incoming: Vec<ServerMsg> = c.down.drain(..take).collect();
        let step = c.replica.step(&mut c.editor, incoming);
        for e in &step.events {
            match e {
                Event::Undone => c.undone += 1,
                Event::Closed { reason, .. } => panic!("the room closed client {i}: {reason}"),
                Event::OutOfStep(r) => panic!("client {i} out of step: {r}"),
                Event::Diverged => panic!("client {i} diverged (snapshots loaded: {})", c.snapshots),
                Event::Snapshot => c.snapshots += 1,
                Event::Refused(_) => c.refused += 1,
                _ => {}
            }
        }
        if c.conn.is_some() {
            c.up.extend(step.send);
        }
    }

    fn quiet(&self) -> bool {
        self.clients.iter().all(|c| c.up.is_empty() && c.down.is_empty() && c.replica.pending() == 0)
    }
}

/// A room on the ball scene and `clients` recording replicas, not connected yet.
fn unconnected(clients: usize, config: RoomConfig) -> World {
    unconnected_on(strata_editor::file::encode(&ball_scene()).unwrap(), clients, config)
}

/// A room on `scene` (a snapshot: a scene file or a world) and `clients` recording replicas
/// on empty scenes, not connected yet.
fn unconnected_on(scene: Vec<u8>, clients: usize, config: RoomConfig) -> World {
    let stored = StoredRoom {
        token_hash: token_hash("secret"),
        snapshot_seq: 0,
        snapshot: scene,
        clients: Vec::new(),
        ops: Vec::new(),
    };
    let room = Room::open("r", stored, config).unwrap();
    let mut w = World { room, clients: Vec::new(), next_conn: 0 };
    for _ in 0..clients {
        let mut editor = Editor::default();
        editor.record_ops(true);
        w.clients.push(Client {
            editor,
            replica: Replica::new(),
            conn: None,
            up: VecDeque::new(),
            down: VecDeque::new(),
            refused: 0,
            undone: 0,
            snapshots: 0,
        });
    }
    w
}

/// A room on the ball scene with `clients` connected, recording replicas, all settled.
fn world(clients: usize, config: RoomConfig) -> World {
    let mut w = unconnected(clients, config);
    for i in 0..clients {
        w.connect(i);
    }
    w.settle();
    w
}

impl World {
    /// Delivers everything until nothing is in flight.
    fn settle(&mut self) {
        for _ in 0..1000 {
            if self.quiet() {
                return;
            }
            for i in 0..self.clients.len() {
                self.pump_down(i, usize::MAX);
                self.pump_up(i, usize::MAX);
            }
        }
        panic!("messages still in flight");
    }

    /// A line stroke of client `i` from `a` to `b` (add, radius 2), settled.
    fn line(&mut self, i: usize, a: [f64; 3], b: [f64; 3]) {
        let e = &mut self.clients[i].editor;
        e.tool.kind = strata_editor::ToolKind::Add;
        e.tool.radius = 2.0;
        e.line_stroke(a.into(), b.into(), 1.0, Default::default()).unwrap();
        self.pump_down(i, 0);
        self.settle();
    }

    /// Client `i` asks for an undo; returns the events its replica saw once settled.
    fn undo(&mut self, i: usize) -> Vec<Event> {
        self.clients[i].up.push_back(ClientMsg::Undo);
        let mut events = Vec::new();
        for _ in 0..100 {
            self.pump_up(i, usize::MAX);
            let c = &mut self.clients[i];
            let incoming: Vec<ServerMsg> = c.down.drain(..).collect();
            events.extend(c.replica.step(&mut c.editor, incoming).events);
            self.settle();
            if events.iter().any(|e| matches!(e, Event::Undone | Event::UndoRefused(_))) {
                return events;
            }
        }
        panic!("no answer to the undo");
    }

    fn all_equal_the_room(&self) -> Vec<strata_editor::file::ChunkDigest> {
        let expected = digests(self.room.editor());
        for (i, c) in self.clients.iter().enumerate() {
            assert!(digests(&c.editor) == expected, "client {i} differs from the room");
        }
        expected
    }
}

#[test]
fn an_undo_takes_back_ones_own_edit_everywhere_unless_someone_else_edited_there_since() {
    let mut w = world(2, RoomConfig::default());
    let start = w.all_equal_the_room();
    // Two edits of client 0 in one place, one of client 1 far away.
    w.line(0, [9.0, 0.0, 0.0], [10.0, 2.0, 0.0]);
    w.line(0, [9.0, 1.0, 0.0], [10.0, 3.0, 0.0]);
    w.line(1, [-9.0, 0.0, 0.0], [-10.0, 0.0, 2.0]);
    let with_all = w.all_equal_the_room();
    // Client 1 never edited near client 0's edits: both undo, newest first, everywhere.
    assert!(w.undo(0).contains(&Event::Undone));
    assert!(w.undo(0).contains(&Event::Undone));
    let undone = w.all_equal_the_room();
    assert!(undone != with_all);
    // What is left is client 1's edit alone on the starting scene.
    let mut reference = world(1, RoomConfig::default());
    reference.line(0, [-9.0, 0.0, 0.0], [-10.0, 0.0, 2.0]);
    let want = reference.all_equal_the_room();
    if undone != want {
        let a: std::collections::BTreeSet<_> = undone.iter().collect();
        let b: std::collections::BTreeSet<_> = want.iter().collect();
        eprintln!("only after undo: {:?}", a.difference(&b).collect::<Vec<_>>());
        eprintln!("only in reference: {:?}", b.difference(&a).collect::<Vec<_>>());
    }
    assert!(undone == want, "the undos left something of client 0's edits");
    // Nothing of client 0's is left to undo.
    let events = w.undo(0);
    assert!(events.iter().any(|e| matches!(e, Event::UndoRefused(r) if r.contains("nothing"))), "{events:?}");
    // Now client 1 edits where client 0 edits next: client 0's undo is refused, naming client 1.
    w.line(0, [0.0, 9.0, 0.0], [2.0, 10.0, 0.0]);
    w.line(1, [1.0, 9.5, 0.0], [2.0, 10.0, 1.0]);
    let before = w.all_equal_the_room();
    let events = w.undo(0);
    assert!(events.iter().any(|e| matches!(e, Event::UndoRefused(r) if r.contains("c1"))), "{events:?}");
    assert!(w.all_equal_the_room() == before, "a refused undo changed something");
    // Client 1's own undo goes through; then client 0's does too.
    assert!(w.undo(1).contains(&Event::Undone));
    assert!(w.undo(0).contains(&Event::Undone));
    // Client 1's first edit, far away, undoes as well: back to the start.
    assert!(w.undo(1).contains(&Event::Undone));
    assert!(w.all_equal_the_room() == start, "undoing everything did not give the start back");
}

#[test]
fn a_redo_makes_the_undone_stroke_again_everywhere_until_new_work_forgets_it() {
    let mut w = world(2, RoomConfig::default());
    let start = w.all_equal_the_room();
    w.line(0, [9.0, 0.0, 0.0], [10.0, 2.0, 0.0]);
    w.line(1, [-9.0, 0.0, 0.0], [-10.0, 0.0, 2.0]);
    let with_all = w.all_equal_the_room();
    assert!(!w.clients[0].replica.can_redo(), "nothing undone yet");
    assert!(w.undo(0).contains(&Event::Undone));
    let undone = w.all_equal_the_room();
    assert!(w.clients[0].replica.can_redo() && !w.clients[1].replica.can_redo());
    // Redo: the same dabs on the same chunks give the same bytes, everywhere.
    let c = &mut w.clients[0];
    c.replica.redo(&mut c.editor).unwrap();
    w.pump_down(0, 0);
    w.settle();
    assert!(w.all_equal_the_room() == with_all, "the redo did not give the stroke back bit for bit");
    // The redone stroke is a stroke of its own: it undoes again, and redoes again.
    assert!(w.undo(0).contains(&Event::Undone));
    assert!(w.all_equal_the_room() == undone);
    // New work forgets what could be redone.
    w.line(0, [0.0, 9.0, 0.0], [2.0, 10.0, 0.0]);
    assert!(!w.clients[0].replica.can_redo());
    let c = &mut w.clients[0];
    assert!(c.replica.redo(&mut c.editor).is_err());
    assert!(w.undo(0).contains(&Event::Undone));
    assert!(w.undo(1).contains(&Event::Undone));
    assert!(w.all_equal_the_room() == start);
}

/// Returns how many undos went through.
fn run(seed: u64, clients: usize, rounds: usize) -> usize {
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    // A digest every 8 operations and a short tail, so resumes past it get snapshots.
    let mut w = unconnected(clients, RoomConfig { hash_every: 8, tail: 24, ..RoomConfig::default() });
    for i in 0..clients {
        w.connect(i);
    }
    for _ in 0..rounds {
        let i = rng.below(clients as u64) as usize;
        match rng.below(10) {
            0..=2 => {
                random_stroke(&mut w.clients[i].editor, &mut rng);
                // (The stroke's operations become pending at the next step.)
                w.pump_down(i, 0);
            }
            3 if rng.chance(0.3) && w.clients[i].conn.is_some() => {
                // An undo of this client's newest stroke (refused where others edited since).
                w.pump_down(i, 0);
                w.clients[i].up.push_back(ClientMsg::Undo);
            }
            4 if rng.chance(0.3) && w.clients[i].replica.can_redo() => {
                // A redo of this client's stroke the room undid last (a new stroke to the room).
                let c = &mut w.clients[i];
                c.replica.redo(&mut c.editor).unwrap();
                w.pump_down(i, 0);
            }
            3..=5 => w.pump_up(i, 1 + rng.below(4) as usize),
            6..=8 => w.pump_down(i, 1 + rng.below(6) as usize),
            _ => {
                if w.clients[i].conn.is_some() {
                    w.drop_connection(i);
                } else {
                    w.connect(i);
                }
            }
        }
    }
    // Everyone reconnects and everything in flight arrives.
    for i in 0..clients {
        if w.clients[i].conn.is_none() {
            w.connect(i);
        }
    }
    for _ in 0..10_000 {
        if w.quiet() {
            break;
        }
        for i in 0..clients {
            w.pump_down(i, usize::MAX);
            w.pump_up(i, usize::MAX);
        }
    }
    assert!(w.quiet(), "seed {seed}: messages still in flight");
    // Each client then undoes its newest stroke (refused where another has edited there since),
    // so that every seed takes the undo path, whatever its random rounds did.
    for i in 0..clients {
        if w.undo(i).contains(&Event::Undone) {
            w.clients[i].undone += 1;
        }
    }
    w.settle();
    assert!(w.quiet(), "seed {seed}: messages still in flight after the last undos");
    let expected = digests(w.room.editor());
    let undone = w.clients.iter().map(|c| c.undone).sum();
    for (i, c) in w.clients.iter().enumerate() {
        assert_eq!(c.replica.seq(), w.room.seq(), "seed {seed}: client {i} is behind");
        assert!(digests(&c.editor) == expected, "seed {seed}: client {i}'s volume differs from the room's");
        c.editor.scene.layers[0].volume.check_invariants().unwrap();
    }
    assert!(w.room.seq() > 0, "seed {seed}: nothing was ordered");
    undone
}

#[test]
fn replicas_converge_to_the_room_through_random_delays_drops_and_resumes() {
    let seeds: u64 = std::env::var("STRATA_ROOM_SEEDS").ok().and_then(|v| v.parse().ok()).unwrap_or(4);
    let mut undone = 0;
    for seed in 0..seeds {
        undone += run(seed, 4, 160);
    }
    assert!(undone > 0, "no undo went through in {seeds} sessions");
}

#[test]
fn eight_replicas_converge() {
    run(1234, 8, 400);
}

#[test]
fn a_client_whose_resync_answer_was_lost_asks_again_when_it_reconnects() {
    let mut w = world(2, RoomConfig::default());
    w.line(1, [9.0, 0.0, 0.0], [10.0, 2.0, 0.0]);
    // A digest that cannot match: the client asks for a snapshot…
    let c = &mut w.clients[0];
    let wrong = ServerMsg::Hash { seq: c.replica.seq(), hash: 1 };
    let step = c.replica.step(&mut c.editor, vec![wrong]);
    assert!(step.events.contains(&Event::Diverged));
    assert_eq!(step.send, vec![ClientMsg::Resync]);
    // …but the connection drops before the answer comes.
    w.drop_connection(0);
    w.line(1, [-9.0, 0.0, 0.0], [-10.0, 2.0, 0.0]);
    // The hello asks for a snapshot (no sequence number to resume from), and the client is
    // back in step with the room.
    let ClientMsg::Hello(h) = w.clients[0].replica.hello("r", "secret", "c0", None) else { unreachable!() };
    assert_eq!(h.resume.and_then(|r| r.seq), None);
    w.connect(0);
    w.settle();
    w.line(1, [0.0, 9.0, 0.0], [2.0, 10.0, 0.0]);
    w.all_equal_the_room();
    assert_eq!(w.clients[0].replica.seq(), w.room.seq());
}

#[test]
fn a_stroke_the_room_no_longer_holds_whole_is_too_old_to_undo() {
    // The room remembers its last three entries only.
    let mut w = world(1, RoomConfig { tail: 3, ..RoomConfig::default() });
    let e = &mut w.clients[0].editor;
    e.tool.kind = strata_editor::ToolKind::Add;
    e.tool.radius = 1.0;
    // One stroke of five frames: five operations.
    for k in 0..5 {
        let pose = strata_editor::ToolPose {
            position: glam::DVec3::new(9.0, k as f64, 0.0),
            buttons: strata_editor::Buttons { primary: true, secondary: false },
            ..strata_editor::ToolPose::default()
        };
        e.frame(&pose, std::time::Duration::ZERO).unwrap();
    }
    e.frame(&strata_editor::ToolPose::at(glam::DVec3::new(9.0, 4.0, 0.0), false), std::time::Duration::ZERO).unwrap();
    w.pump_down(0, 0);
    w.settle();
    assert_eq!(w.room.seq(), 5);
    let before = w.all_equal_the_room();
    let events = w.undo(0);
    assert!(events.iter().any(|e| matches!(e, Event::UndoRefused(r) if r.contains("too old"))), "{events:?}");
    assert!(w.all_equal_the_room() == before, "a partial undo was applied");
}

/// The first welcome in `h` (its client and key).
fn welcome(h: &Handled) -> (u64, strata_net::protocol::ResumeKey) {
    for o in &h.out {
        if let Out::Send(_, bytes) = o
            && let Ok(ServerMsg::Welcome { client, key, .. }) = decode::<ServerMsg>(bytes, usize::MAX)
        {
            return (client, key);
        }
    }
    panic!("no welcome");
}

#[test]
fn knowing_someones_public_id_is_not_enough_to_resume_as_them() {
    let mut w = world(2, RoomConfig::default());
    // Client 0 is known to the room (it sculpted); everyone sees its id as the author.
    w.line(0, [9.0, 0.0, 0.0], [10.0, 2.0, 0.0]);
    let victim = w.clients[0].replica.client().unwrap();
    let hello = |key: [u8; 16]| strata_net::protocol::Hello {
        protocol: strata_net::protocol::PROTOCOL,
        room: "r".into(),
        token: "secret".into(),
        name: "mallory".into(),
        resume: Some(strata_net::protocol::Resume { key, seq: Some(0) }),
        create: None,
    };
    // Keys made from the public id, or guessed, make someone new; the victim stays connected.
    let mut guesses = vec![[0u8; 16], [0xff; 16]];
    let mut id_key = [0u8; 16];
    id_key[..8].copy_from_slice(&victim.to_le_bytes());
    guesses.push(id_key);
    for (k, key) in guesses.into_iter().enumerate() {
        let h = w.room.join(900 + k as u64, hello(key));
        let (client, new_key) = welcome(&h);
        assert_ne!(client, victim, "a made-up key resumed as the victim");
        assert_ne!(new_key, key, "a new client gets a key of its own");
        assert_eq!(strata_server::room::client_of(&new_key), client);
        assert!(h.out.iter().all(|o| !matches!(o, Out::Close(..))), "no one was disconnected");
    }
    // The victim's own key resumes it (its old connection, not yet seen dead, is closed).
    w.drop_connection(0);
    w.connect(0);
    w.settle();
    assert_eq!(w.clients[0].replica.client(), Some(victim));
    w.line(0, [-9.0, 0.0, 0.0], [-10.0, 2.0, 0.0]);
    assert!(w.undo(0).contains(&Event::Undone));
}

/// The chunks of a world editor that differ from its recipe's.
fn world_chunks(e: &Editor) -> Vec<(strata_volume::ChunkKey, strata_terrain::StoredChunk)> {
    e.world().expect("a world").edited_chunks().unwrap()
}

/// An editor on an in-memory world of seed 3, shared as a room streams (one level), with a
/// trench dug along x.
fn dug_world() -> Editor {
    use strata_editor::room;
    let settings = room::shared_world_settings(strata_terrain::WorldSettings { threads: 1, ..Default::default() });
    let world = strata_terrain::World::in_memory(&strata_terrain::Recipe::with_seed(3), settings).unwrap();
    let mut host = Editor::on_world(world, strata_editor::Scene::default().materials);
    host.tool.kind = strata_editor::ToolKind::Erase;
    host.tool.radius = 6.0;
    host.line_stroke([0.0, 0.0, 0.0].into(), [20.0, 0.0, 0.0].into(), 1.0, Default::default()).unwrap();
    host
}

#[test]
fn replicas_of_a_shared_world_converge_through_drops_resumes_undos_and_redos() {
    let host = dug_world();
    let dug = world_chunks(&host);
    assert!(!dug.is_empty());
    let snapshot = strata_editor::room::encode(&host).unwrap();
    for seed in 1..=3u64 {
        let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
        let config = RoomConfig { hash_every: 8, tail: 24, ..RoomConfig::default() };
        let mut w = unconnected_on(snapshot.clone(), 3, config);
        for i in 0..3 {
            w.connect(i);
        }
        w.settle();
        for c in &w.clients {
            assert!(world_chunks(&c.editor) == dug, "a joiner holds the room's world");
        }
        for _ in 0..120 {
            let i = rng.below(3) as usize;
            match rng.below(10) {
                0..=2 => {
                    random_stroke(&mut w.clients[i].editor, &mut rng);
                    w.pump_down(i, 0);
                }
                3 if rng.chance(0.3) && w.clients[i].conn.is_some() => {
                    w.pump_down(i, 0);
                    w.clients[i].up.push_back(ClientMsg::Undo);
                }
                4 if w.clients[i].replica.can_redo() => {
                    let c = &mut w.clients[i];
                    c.replica.redo(&mut c.editor).unwrap();
                    w.pump_down(i, 0);
                }
                3..=5 => w.pump_up(i, 1 + rng.below(4) as usize),
                6..=8 => w.pump_down(i, 1 + rng.below(6) as usize),
                _ => {
                    if w.clients[i].conn.is_some() {
                        w.drop_connection(i);
                    } else {
                        w.connect(i);
                    }
                }
            }
        }
        for i in 0..3 {
            if w.clients[i].conn.is_none() {
                w.connect(i);
            }
        }
        w.settle();
        let expected = world_chunks(w.room.editor());
        assert!(expected != dug, "seed {seed}: the clients' strokes changed the world");
        for (i, c) in w.clients.iter().enumerate() {
            assert_eq!(c.replica.seq(), w.room.seq(), "seed {seed}: client {i} is behind");
            assert!(world_chunks(&c.editor) == expected, "seed {seed}: client {i}'s world differs from the room's");
        }
    }
}

#[test]
fn a_world_snapshot_that_is_damaged_or_breaks_its_rules_is_refused() {
    use strata_editor::room;
    let good = room::encode(&dug_world()).unwrap();
    let room::RoomContent::World(content) = room::decode(&good).unwrap() else { panic!("a world") };
    let framed = |c: &room::WorldContent| {
        let mut bytes = room::WORLD_MAGIC.to_vec();
        bytes.extend_from_slice(&1u32.to_le_bytes());
        bytes.extend(postcard::to_allocvec(c).unwrap());
        bytes
    };
    assert!(matches!(room::decode(&framed(&content)), Ok(room::RoomContent::World(_))));
    // A chunk listed twice.
    let mut twice = content.clone();
    twice.chunks.push(twice.chunks[0].clone());
    assert!(room::decode(&framed(&twice)).unwrap_err().contains("twice"));
    // No palette.
    let mut bare = content.clone();
    bare.materials.clear();
    assert!(room::decode(&framed(&bare)).is_err());
    // Truncated, and of another version.
    assert!(room::decode(&good[..good.len() / 2]).is_err());
    let mut other = good.clone();
    other[8] = 9;
    assert!(room::decode(&other).unwrap_err().contains("version"));
    // A world that makes finer chunks near its viewer is not shared.
    let fine = strata_terrain::World::in_memory(
        &strata_terrain::Recipe::with_seed(3),
        strata_terrain::WorldSettings { threads: 1, detail_distance: 32.0, ..Default::default() },
    )
    .unwrap();
    assert!(room::encode(&Editor::on_world(fine, strata_editor::Scene::default().materials)).is_err());
}
