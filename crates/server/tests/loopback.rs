//! Sculpting together over real WebSockets on loopback, with each storage back-end: eight
//! clients sculpt random strokes at once with random pauses, connections drop and resume,
//! and at the end every client's chunk digests equal the room's as its storage holds it.
//!
//! The PostgreSQL tests need a server: `STRATA_PG_URL` (`.ci/run` starts one and sets it).
//! Without it they fail in CI and are skipped elsewhere, with a message.

use std::sync::Arc;
use std::time::Duration;

use strata_net::SessionState;
use strata_server::room::{Room, RoomConfig};
use strata_server::{PgStorage, RedbStorage, Server, ServerConfig, Storage};
use strata_tests::collab::{Member, Rng, ball_scene, converge, digests, fresh_room, pg_url, random_stroke, temp_dir};

/// Eight clients sculpting at once through drops and resumes (see the module docs); returns
/// the clients' final digests after checking them against the stored room.
fn session(storage: Arc<dyn Storage>, room: &str, seed: u64) {
    // The log is folded into snapshots every 16 operations, and resumes further back than 12
    // get one: both happen many times in a session.
    let config = ServerConfig {
        room: RoomConfig { compact_every: 16, tail: 12, ..RoomConfig::default() },
        ..ServerConfig::default()
    };
    let server = Server::start("127.0.0.1:0", storage.clone(), config).unwrap();
    let url = server.url();
    let mut rng = Rng(seed | 1);
    let mut members = vec![Member::new(&url, room, "token", "host", Some(&ball_scene()))];
    // The host makes the room; the guests join it.
    converge(&mut members, Duration::from_secs(30));
    for i in 1..8 {
        members.push(Member::new(&url, room, "token", &format!("guest {i}"), None));
    }
    converge(&mut members, Duration::from_secs(60));
    let mut drops = 0;
    for _ in 0..120 {
        let i = rng.below(members.len() as u64) as usize;
        let m = &mut members[i];
        match rng.below(10) {
            0..=4 => random_stroke(&mut m.editor, &mut rng),
            // An undo of the member's newest stroke (refused where someone else edited since,
            // or while reconnecting).
            5 => {
                let _ = m.session.undo(&mut m.editor);
            }
            6 => {
                m.session.drop_connection();
                drops += 1;
            }
            _ => std::thread::sleep(Duration::from_millis(rng.below(20))),
        }
        for m in members.iter_mut() {
            m.poll(Duration::ZERO);
        }
    }
    converge(&mut members, Duration::from_secs(120));
    drop(server);
    // The room as its storage holds it: what a restarted server would serve.
    let stored = storage.open(room).unwrap().load().unwrap().expect("the room is stored");
    assert!(stored.snapshot_seq > 0, "the log was never compacted");
    assert!(stored.ops.len() < 16 + 16, "{} operations after the snapshot", stored.ops.len());
    let room = Room::open(room, stored, RoomConfig::default()).unwrap();
    let expected = digests(room.editor());
    assert!(room.seq() > 20, "only {} operations were ordered", room.seq());
    assert!(drops > 3);
    for (i, m) in members.iter().enumerate() {
        assert!(m.trouble.is_empty(), "client {i}: {:?}", m.trouble);
        assert_eq!(m.session.replica().seq(), room.seq(), "client {i} is behind");
        assert!(digests(&m.editor) == expected, "client {i}'s volume differs from the stored room's");
    }
}

#[test]
fn eight_clients_converge_through_drops_with_redb() {
    let dir = temp_dir("loopback-redb");
    let storage = Arc::new(RedbStorage::open(&dir.join("rooms.redb")).unwrap());
    session(storage, "sculpt", 7);
}

#[test]
fn eight_clients_converge_through_drops_with_postgres() {
    let Some(url) = pg_url() else { return };
    let storage = Arc::new(PgStorage::open(&url).unwrap());
    session(storage, &fresh_room("sculpt"), 11);
}

#[test]
fn two_servers_serve_different_rooms_against_one_database_and_never_the_same_one() {
    let Some(url) = pg_url() else { return };
    let a = Server::start("127.0.0.1:0", Arc::new(PgStorage::open(&url).unwrap()), ServerConfig::default()).unwrap();
    let b = Server::start("127.0.0.1:0", Arc::new(PgStorage::open(&url).unwrap()), ServerConfig::default()).unwrap();
    let (room_a, room_b) = (fresh_room("a"), fresh_room("b"));
    let mut on_a = vec![Member::new(&a.url(), &room_a, "t", "one", Some(&ball_scene()))];
    let mut on_b = vec![Member::new(&b.url(), &room_b, "t", "two", Some(&ball_scene()))];
    converge(&mut on_a, Duration::from_secs(30));
    converge(&mut on_b, Duration::from_secs(30));
    let mut rng = Rng(5);
    random_stroke(&mut on_a[0].editor, &mut rng);
    random_stroke(&mut on_b[0].editor, &mut rng);
    converge(&mut on_a, Duration::from_secs(30));
    converge(&mut on_b, Duration::from_secs(30));
    // Room a is held by server a: server b does not serve it twice, and says why (the client
    // keeps trying: the room may be free later).
    let mut intruder = Member::new(&b.url(), &room_a, "t", "three", None);
    let t0 = std::time::Instant::now();
    while !intruder.closed.iter().any(|why| why.contains("another server")) {
        intruder.poll(Duration::from_millis(20));
        assert_ne!(*intruder.session.state(), SessionState::InRoom, "server b served a room server a holds");
        assert!(t0.elapsed() < Duration::from_secs(30), "no refusal: {:?}", intruder.closed);
    }
}

#[test]
fn a_wrong_token_or_an_unknown_room_is_refused_with_the_same_words() {
    let dir = temp_dir("loopback-token");
    let storage = Arc::new(RedbStorage::open(&dir.join("rooms.redb")).unwrap());
    let server = Server::start("127.0.0.1:0", storage, ServerConfig::default()).unwrap();
    let mut host = vec![Member::new(&server.url(), "private", "right", "host", Some(&ball_scene()))];
    converge(&mut host, Duration::from_secs(30));
    let refusal = |room: &str, token: &str| {
        let mut m = Member::new(&server.url(), room, token, "stranger", None);
        let t0 = std::time::Instant::now();
        loop {
            m.poll(Duration::from_millis(20));
            match m.session.state() {
                SessionState::Refused(why) => return why.replace(room, "ROOM"),
                SessionState::InRoom => panic!("joined {room} with token {token}"),
                _ => assert!(t0.elapsed() < Duration::from_secs(30)),
            }
        }
    };
    let wrong = refusal("private", "wrong");
    let unknown = refusal("nowhere", "right");
    assert_eq!(wrong, unknown, "a refusal tells whether the room exists");
    // The stranger saw nothing of the room: the host is alone.
    host[0].poll(Duration::from_millis(50));
    assert_eq!(host[0].session.peers().count(), 0);
}
