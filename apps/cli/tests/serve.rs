//! `strata serve` killed with SIGKILL twenty times while eight clients sculpt, and started again
//! on the same port and store each time: no client ever sees the room go back (an operation
//! acknowledged is never lost), every client converges, and the room as stored equals every
//! client's volume.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use strata_server::room::{Room, RoomConfig};
use strata_server::{RedbStorage, Storage};
use strata_tests::collab::{Member, Rng, ball_scene, converge, digests, random_stroke, temp_dir};

/// Starts `strata serve` on `port` with `store`; returns once it listens.
fn start(port: u16, store: &Path) -> Child {
    let t0 = Instant::now();
    loop {
        let mut child = Command::new(env!("CARGO_BIN_EXE_strata"))
            .args(["serve", "--listen", &format!("127.0.0.1:{port}"), "--store"])
            .arg(store)
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

#[test]
fn a_server_killed_twenty_times_loses_no_acknowledged_operation() {
    let dir = temp_dir("serve-kill");
    let store = dir.join("rooms.redb");
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let url = format!("ws://127.0.0.1:{port}");
    let mut server = start(port, &store);
    let mut members = vec![Member::new(&url, "room", "token", "host", Some(&ball_scene()))];
    converge(&mut members, Duration::from_secs(30));
    for i in 1..8 {
        members.push(Member::new(&url, "room", "token", &format!("guest {i}"), None));
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
        server = start(port, &store);
    }
    converge(&mut members, Duration::from_secs(120));
    for (k, m) in members.iter().enumerate() {
        assert!(m.session.replica().seq() >= highest[k], "client {k} went back");
        assert!(m.trouble.is_empty(), "client {k}: {:?}", m.trouble);
    }
    server.kill().unwrap();
    server.wait().unwrap();
    let storage = Arc::new(RedbStorage::open(&store).unwrap());
    let stored = storage.open("room").unwrap().load().unwrap().unwrap();
    let room = Room::open("room", stored, RoomConfig::default()).unwrap();
    assert!(room.seq() > 40, "only {} operations were ordered", room.seq());
    let expected = digests(room.editor());
    for (k, m) in members.iter().enumerate() {
        assert_eq!(m.session.replica().seq(), room.seq());
        assert!(digests(&m.editor) == expected, "client {k} differs from the stored room");
    }
}
