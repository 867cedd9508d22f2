//! `strata serve` killed with SIGKILL twenty times while eight clients sculpt, and started again
//! on the same port and store each time: no client ever sees the room go back (an operation
//! acknowledged is never lost), every client converges, and the room as stored equals every
//! client's volume. On redb and on PostgreSQL (`STRATA_PG_URL`, which `.ci/run` sets).

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use strata_server::room::{Room, RoomConfig};
use strata_tests::collab::{Member, Rng, ball_scene, converge, digests, fresh_room, pg_url, random_stroke, temp_dir};

/// Starts `strata serve` on `port` with `store` (a redb file or a postgres:// URL); returns
/// once it listens.
fn start(port: u16, store: &str) -> Child {
    let t0 = Instant::now();
    loop {
        let mut child = Command::new(env!("CARGO_BIN_EXE_strata"))
            .args(["serve", "--listen", &format!("127.0.0.1:{port}"), "--store", store])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        if line.contains("serving rooms on") {
            return child;
        }
        // (The port may linger a moment after a kill.)
        let _ = child.wait();
        assert!(t0.elapsed() < Duration::from_secs(30), "strata serve did not start: {line}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Eight clients in room `room` of a `strata serve` on `store`, killed twenty times.
fn killed_twenty_times(store: &str, room: &str) {
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let url = format!("ws://127.0.0.1:{port}");
    let mut server = start(port, store);
    let mut members = vec![Member::new(&url, room, "token", "host", Some(&ball_scene()))];
    converge(&mut members, Duration::from_secs(30));
    for i in 1..8 {
        members.push(Member::new(&url, room, "token", &format!("guest {i}"), None));
    }
    converge(&mut members, Duration::from_secs(60));
    let mut rng = Rng(2024);
    let mut highest = vec![0u64; members.len()];
    for kill in 0..20 {
        let until = Instant::now() + Duration::from_millis(150 + rng.below(250));
        while Instant::now() < until {
            let i = rng.below(members.len() as u64) as usize;
            random_stroke(&mut members[i].editor, &mut rng);
            for (k, m) in members.iter_mut().enumerate() {
                m.poll(Duration::ZERO);
                let seq = m.session.replica().seq();
                assert!(seq >= highest[k], "kill {kill}: client {k} went back from operation {} to {seq}", highest[k]);
                highest[k] = seq;
            }
        }
        server.kill().unwrap();
        server.wait().unwrap();
        server = start(port, store);
    }
    converge(&mut members, Duration::from_secs(120));
    for (k, m) in members.iter().enumerate() {
        assert!(m.session.replica().seq() >= highest[k], "client {k} went back");
        assert!(m.trouble.is_empty(), "client {k}: {:?}", m.trouble);
    }
    server.kill().unwrap();
    server.wait().unwrap();
    // The room as the store holds it (the same storage `strata serve --store` opens).
    // (PostgreSQL frees the killed server's hold on the room when it sees the connection gone.)
    let storage = strata::serve::storage(store).unwrap();
    let t0 = Instant::now();
    let mut held = storage.open(room);
    while held.is_err() && t0.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(100));
        held = storage.open(room);
    }
    let stored = held.unwrap().load().unwrap().unwrap();
    let room = Room::open(room, stored, RoomConfig::default()).unwrap();
    assert!(room.seq() > 40, "only {} operations were ordered", room.seq());
    let expected = digests(room.editor());
    for (k, m) in members.iter().enumerate() {
        assert_eq!(m.session.replica().seq(), room.seq());
        assert!(digests(&m.editor) == expected, "client {k} differs from the stored room");
    }
}

#[test]
fn a_server_killed_twenty_times_loses_no_acknowledged_operation_with_redb() {
    let store = temp_dir("serve-kill").join("rooms.redb");
    killed_twenty_times(store.to_str().unwrap(), "room");
}

#[test]
fn a_server_killed_twenty_times_loses_no_acknowledged_operation_with_postgres() {
    let Some(url) = pg_url() else { return };
    killed_twenty_times(&url, &fresh_room("serve-kill"));
}
