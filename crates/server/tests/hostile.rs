//! A hostile client on loopback: 10,000 malformed, oversized, NaN-carrying, out-of-bounds and
//! out-of-order messages over many connections while two honest clients sculpt. The server
//! never stops serving, the hostile connections are closed with an error, the honest clients
//! converge; and a flood of well-formed messages is slowed to the connection's rate limit
//! while another client is served at once. Each on redb and on PostgreSQL (`STRATA_PG_URL`,
//! which `.ci/run` sets; without it these fail in CI and are skipped elsewhere).

use std::net::TcpStream;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use strata_editor::{DabRecord, EditOp, LayerTransform, ToolSettings};
use strata_net::protocol::{ClientMsg, Hello, PROTOCOL, Presence, ServerMsg, decode, encode};
use strata_server::{PgStorage, RedbStorage, Server, ServerConfig, Storage};
use strata_tests::collab::{Member, Rng, ball_scene, converge, digests, fresh_room, pg_url, random_stroke, temp_dir};
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

type Socket = WebSocket<MaybeTlsStream<TcpStream>>;

fn open(url: &str) -> Socket {
    let (ws, _) = tungstenite::connect(url).unwrap();
    if let MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    }
    ws
}

fn hello(room: &str, token: &str) -> ClientMsg {
    ClientMsg::Hello(Hello {
        protocol: PROTOCOL,
        room: room.into(),
        token: token.into(),
        name: "mallory".into(),
        resume: None,
        create: None,
    })
}

fn op(position: DVec3, radius: f64) -> EditOp {
    EditOp {
        surface: 0,
        transform: LayerTransform::default(),
        tool: ToolSettings { radius, ..ToolSettings::default() },
        dabs: vec![DabRecord::Dab {
            at: position,
            from: position,
            orientation: glam::DQuat::IDENTITY,
            pressure: 1.0,
            inverted: false,
        }],
        stroke: 0,
    }
}

/// Reads until the server closes the connection; whether it said why first.
fn closed_with_error(ws: &mut Socket) -> bool {
    read_until_closed(ws).0
}

/// Reads until the server closes the connection: whether it said why, and whether it refused
/// an operation before.
fn read_until_closed(ws: &mut Socket) -> (bool, bool) {
    let (mut said, mut refused) = (false, false);
    loop {
        match ws.read() {
            Ok(Message::Binary(b)) => match decode::<ServerMsg>(&b, usize::MAX) {
                Ok(ServerMsg::Error { .. }) => said = true,
                Ok(ServerMsg::Refused { .. }) => refused = true,
                _ => {}
            },
            Ok(Message::Close(_)) => {}
            Ok(_) => {}
            Err(tungstenite::Error::Io(e)) if e.kind() == std::io::ErrorKind::WouldBlock => {
                panic!("the server kept a hostile connection open")
            }
            Err(_) => return (said, refused),
        }
    }
}

/// Bad messages sent at once on each hostile connection.
const BURST: usize = 4;

/// One hostile connection of kind `kind`; returns the messages it sent.
fn attack(url: &str, room: &str, kind: u64, rng: &mut Rng) -> usize {
    let mut ws = open(url);
    // A burst of the bad message: the server closes at the first; the rest may not arrive.
    let send = |ws: &mut Socket, bytes: Vec<u8>| {
        for _ in 0..BURST {
            let _ = ws.send(Message::Binary(bytes.clone().into()));
        }
    };
    let joined = |ws: &mut Socket| {
        ws.send(Message::Binary(encode(&hello(room, "token")).into())).unwrap();
    };
    let sent = match kind {
        // Bytes that are no message at all.
        0 => {
            let n = 1 + rng.below(200) as usize;
            send(&mut ws, (0..n).map(|_| rng.bits() as u8).collect());
            BURST
        }
        // A message over the size limit.
        1 => {
            joined(&mut ws);
            send(&mut ws, vec![7u8; 1_600_000]);
            1 + BURST
        }
        // An operation carrying NaN.
        2 => {
            joined(&mut ws);
            let msg = ClientMsg::Submit { number: 1, op: Box::new(op(DVec3::new(f64::NAN, 0.0, 0.0), 2.0)) };
            send(&mut ws, encode(&msg));
            1 + BURST
        }
        // A submit before any hello, or one whose number skips ahead.
        3 => {
            if rng.chance(0.5) {
                send(&mut ws, encode(&ClientMsg::Submit { number: 1, op: Box::new(op(DVec3::ZERO, 2.0)) }));
                BURST
            } else {
                joined(&mut ws);
                send(&mut ws, encode(&ClientMsg::Submit { number: 5, op: Box::new(op(DVec3::ZERO, 2.0)) }));
                1 + BURST
            }
        }
        // Another protocol.
        4 => {
            let ClientMsg::Hello(mut h) = hello(room, "token") else { unreachable!() };
            h.protocol = 999;
            send(&mut ws, encode(&ClientMsg::Hello(h)));
            BURST
        }
        // Text instead of binary.
        5 => {
            joined(&mut ws);
            let _ = ws.send(Message::Text("hello?".into()));
            2
        }
        // Out of bounds: a huge brush, a material or a surface that does not exist, infinity.
        // Out of bounds (a huge brush, a material or a surface that does not exist): refused
        // and taken back, as an honest client's mistake would be; then infinity, which closes.
        6 => {
            joined(&mut ws);
            let mut o = op(DVec3::ZERO, 2.0);
            match rng.below(3) {
                0 => o.tool.radius = 1e9,
                1 => o.tool.material = 250,
                _ => o.surface = 9,
            }
            let _ = ws.send(Message::Binary(encode(&ClientMsg::Submit { number: 1, op: Box::new(o) }).into()));
            let mut inf = op(DVec3::ZERO, 2.0);
            inf.transform.scale = f64::INFINITY;
            send(&mut ws, encode(&ClientMsg::Submit { number: 2, op: Box::new(inf) }));
            let (said, refused) = read_until_closed(&mut ws);
            assert!(said && refused, "an out-of-bounds operation was not refused, or infinity not closed");
            return 2 + BURST;
        }
        // Out of order: a second hello after the first.
        7 => {
            joined(&mut ws);
            send(&mut ws, encode(&hello(room, "token")));
            1 + BURST
        }
        // A presence that is not finite.
        8 => {
            joined(&mut ws);
            let p = Presence { position: Some(DVec3::splat(f64::INFINITY)), radius: 1.0 };
            send(&mut ws, encode(&ClientMsg::Presence(p)));
            1 + BURST
        }
        // A well-formed message cut short.
        _ => {
            joined(&mut ws);
            let mut bytes = encode(&ClientMsg::Submit { number: 1, op: Box::new(op(DVec3::ZERO, 2.0)) });
            bytes.truncate(bytes.len() / 2);
            send(&mut ws, bytes);
            1 + BURST
        }
    };
    assert!(closed_with_error(&mut ws), "a hostile connection of kind {kind} was closed without a reason");
    sent
}

/// An operation sent again and again on a connection that stays open (the server ignores
/// numbers it has already handled): many messages, no disconnection needed.
fn replays(url: &str, room: &str, count: usize) -> usize {
    let mut ws = open(url);
    ws.send(Message::Binary(encode(&hello(room, "token")).into())).unwrap();
    let submit =
        |n: u64| Message::Binary(encode(&ClientMsg::Submit { number: n, op: Box::new(op(DVec3::ZERO, 1.0)) }).into());
    // One real operation (number 1), then the same number again and again.
    ws.send(submit(1)).unwrap();
    for _ in 0..count {
        ws.send(submit(1)).unwrap();
    }
    ws.close(None).ok();
    count + 2
}

/// 10,000 hostile messages beside two honest clients in room `room` (see the module docs).
fn hostile_session(storage: Arc<dyn Storage>, room: &str) {
    // (A rate that lets the replays through in seconds.)
    let config = ServerConfig { rate: 5000.0, burst: 5000.0, ..ServerConfig::default() };
    let server = Server::start("127.0.0.1:0", storage, config).unwrap();
    let url = server.url();
    let mut honest = vec![Member::new(&url, room, "token", "host", Some(&ball_scene()))];
    converge(&mut honest, Duration::from_secs(30));
    honest.push(Member::new(&url, room, "token", "guest", None));
    converge(&mut honest, Duration::from_secs(30));
    let hostile = {
        let url = url.clone();
        let room = room.to_owned();
        std::thread::spawn(move || {
            let mut rng = Rng(99);
            let mut sent = 0;
            let mut kind = 0;
            while sent < 10_000 {
                sent +=
                    if kind % 10 == 9 { replays(&url, &room, 100) } else { attack(&url, &room, kind % 10, &mut rng) };
                kind += 1;
            }
            (sent, kind)
        })
    };
    let mut rng = Rng(3);
    while !hostile.is_finished() {
        let i = rng.below(2) as usize;
        random_stroke(&mut honest[i].editor, &mut rng);
        for m in honest.iter_mut() {
            m.poll(Duration::from_millis(10));
        }
    }
    let (sent, connections) = hostile.join().expect("the hostile client's own checks");
    assert!(sent >= 10_000);
    converge(&mut honest, Duration::from_secs(60));
    assert!(digests(&honest[0].editor) == digests(&honest[1].editor));
    for m in &honest {
        assert!(m.trouble.is_empty(), "{:?}", m.trouble);
        assert_eq!(*m.session.state(), strata_net::SessionState::InRoom);
    }
    // Still serving: a newcomer joins and gets the same bytes.
    let mut late = vec![Member::new(&url, room, "token", "late", None)];
    converge(&mut late, Duration::from_secs(30));
    assert!(digests(&late[0].editor) == digests(&honest[0].editor));
    eprintln!("{sent} hostile messages over {connections} connections");
}

/// A flood beside an honest client in room `room` (see the module docs).
fn flood_session(storage: Arc<dyn Storage>, room: &str) {
    let config = ServerConfig { rate: 100.0, burst: 20.0, ..ServerConfig::default() };
    let server = Server::start("127.0.0.1:0", storage, config).unwrap();
    let url = server.url();
    let mut honest = vec![Member::new(&url, room, "token", "host", Some(&ball_scene()))];
    converge(&mut honest, Duration::from_secs(30));
    let mut flood = open(&url);
    flood.send(Message::Binary(encode(&hello(room, "token")).into())).unwrap();
    let t0 = Instant::now();
    // 220 presences, then a resync whose snapshot can come only after all were read.
    let p = ClientMsg::Presence(Presence { position: Some(DVec3::ZERO), radius: 1.0 });
    for _ in 0..220 {
        flood.send(Message::Binary(encode(&p).into())).unwrap();
    }
    flood.send(Message::Binary(encode(&ClientMsg::Resync).into())).unwrap();
    // Meanwhile an honest stroke is ordered and confirmed at once.
    let mut rng = Rng(8);
    random_stroke(&mut honest[0].editor, &mut rng);
    let t1 = Instant::now();
    converge(&mut honest, Duration::from_secs(30));
    let honest_wait = t1.elapsed();
    let mut snapshots = 0;
    while snapshots < 2 {
        // (The first snapshot answers the hello; the second the resync.)
        if let Message::Binary(b) = flood.read().unwrap()
            && let Ok(ServerMsg::Snapshot { .. }) = decode::<ServerMsg>(&b, usize::MAX)
        {
            snapshots += 1;
        }
    }
    let flood_wait = t0.elapsed();
    // 221 messages, 20 at once, the rest at 100 a second: at least two seconds.
    assert!(flood_wait >= Duration::from_millis(2000), "a flood of 221 messages was read in {flood_wait:?}");
    assert!(honest_wait < flood_wait, "the honest client waited {honest_wait:?}, behind the flood");
}

fn redb(name: &str) -> Arc<dyn Storage> {
    Arc::new(RedbStorage::open(&temp_dir(name).join("rooms.redb")).unwrap())
}

fn postgres() -> Option<Arc<dyn Storage>> {
    Some(Arc::new(PgStorage::open(&pg_url()?).unwrap()))
}

#[test]
fn ten_thousand_hostile_messages_leave_the_honest_clients_converging_with_redb() {
    hostile_session(redb("hostile"), "room");
}

#[test]
fn ten_thousand_hostile_messages_leave_the_honest_clients_converging_with_postgres() {
    let Some(storage) = postgres() else { return };
    hostile_session(storage, &fresh_room("hostile"));
}

#[test]
fn a_flood_is_slowed_to_the_rate_limit_while_others_are_served_with_redb() {
    flood_session(redb("flood"), "room");
}

#[test]
fn a_flood_is_slowed_to_the_rate_limit_while_others_are_served_with_postgres() {
    let Some(storage) = postgres() else { return };
    flood_session(storage, &fresh_room("flood"));
}

/// A server that takes WebSocket connections and never answers: a session's hello is given up
/// after its timeout and the connection made again, instead of joining forever.
#[test]
fn a_hello_the_server_never_answers_is_tried_again() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("ws://{}", listener.local_addr().unwrap());
    let accepted = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let count = accepted.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            count.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            std::thread::spawn(move || {
                if let Ok(mut ws) = tungstenite::accept(stream) {
                    // Reads the hello and everything after it; says nothing.
                    while ws.read().is_ok() {}
                }
            });
        }
    });
    let mut editor = strata_editor::Editor::new(ball_scene());
    let mut session = strata_net::Session::join(&url, "room", "token", "patient").unwrap();
    session.set_hello_timeout(Duration::from_millis(300));
    let start = Instant::now();
    while accepted.load(std::sync::atomic::Ordering::SeqCst) < 3 {
        session.wait(&mut editor, Duration::from_millis(20));
        assert!(start.elapsed() < Duration::from_secs(20), "the unanswered hello was not tried again");
    }
    assert!(!session.replica().joined());
}

/// A client too busy to say hello within the server's time (a machine under load, a long
/// frame) is told to connect again, and does: it is not refused for good.
#[test]
fn a_client_slow_to_say_hello_is_told_to_try_again_and_gets_in() {
    let config = ServerConfig { hello_timeout: Duration::from_millis(200), ..ServerConfig::default() };
    let server = Server::start("127.0.0.1:0", redb("slow-hello"), config).unwrap();
    let mut host = Member::new(&server.url(), "room", "token", "host", Some(&ball_scene()));
    converge(std::slice::from_mut(&mut host), Duration::from_secs(30));
    let mut slow = Member::new(&server.url(), "room", "token", "slow", None);
    // Not polled: the link connects and the server's wait for the hello runs out.
    std::thread::sleep(Duration::from_millis(1500));
    let mut members = vec![host, slow];
    converge(&mut members, Duration::from_secs(30));
    slow = members.pop().unwrap();
    assert!(
        slow.closed.iter().any(|r| r.contains("no hello")),
        "the server did not time the hello out: {:?}",
        slow.closed
    );
    assert_eq!(slow.session.welcomes(), 1);
}
