//! `strata-bench collab`: sculpting together on loopback, all in one process on this machine.
//!
//! - **Latency**: clients take turns making one dab each at a fixed total rate; for each dab,
//!   the time from the author's poll that sends it to the last other client applying it
//!   (p50, p99). Every client is a full editor replaying every operation, polled in turn by one
//!   thread: the figure includes the clients' own work, as it would on one machine.
//! - **Throughput**: one raw connection submits recorded operations as fast as the socket
//!   takes them (rate limit lifted); operations the room ordered (validated, replayed, stored
//!   durably, broadcast) per second.
//! - **Bytes per operation**: the encoded `ServerMsg::Op` of the latency workload's operations.
//! - **Join**: a client joining a room holding the bunny at 1,024 cells, from `Session::join`
//!   to holding the room's scene.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use glam::DVec3;
use strata_editor::{Buttons, Editor, Scene, ToolKind, ToolPose};
use strata_net::protocol::{ClientMsg, Entry, Hello, Ordered, PROTOCOL, ServerMsg, decode, encode};
use strata_net::{Event, Session, SessionState};
use strata_server::{PgStorage, RedbStorage, Server, ServerConfig, Storage};
use strata_volume::CsgOp;
use strata_volume::brush::Sphere;

/// What to run.
#[derive(Clone, Debug)]
pub struct CollabConfig {
    /// Client counts for the latency rows.
    pub clients: Vec<usize>,
    /// Dabs per second over all clients.
    pub rate: f64,
    /// Seconds of measured dabs per row.
    pub seconds: f64,
    /// Operations in the throughput run.
    pub burst: usize,
    /// Cells of the bunny for the join row (0: skip).
    pub join_cells: u32,
    /// A PostgreSQL URL: the rows again on PostgreSQL.
    pub pg: Option<String>,
}

/// The storages a run compares.
fn storages(config: &CollabConfig, dir: &std::path::Path) -> Result<Vec<(&'static str, Arc<dyn Storage>)>> {
    let mut out: Vec<(&'static str, Arc<dyn Storage>)> =
        vec![("redb", Arc::new(RedbStorage::open(&dir.join("rooms.redb")).context("redb")?))];
    if let Some(url) = &config.pg {
        out.push(("PostgreSQL", Arc::new(PgStorage::open(url).context("PostgreSQL")?)));
    }
    Ok(out)
}

/// A room name no earlier run used (PostgreSQL keeps rooms).
fn fresh(name: &str) -> String {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    format!("{name}-{}-{nanos}", std::process::id())
}

fn ball() -> Result<Scene> {
    let mut e = Editor::default();
    e.apply(0, CsgOp::Add, &Sphere::new(DVec3::ZERO, 24.0)?)?;
    Ok(e.scene)
}

struct Member {
    editor: Editor,
    session: Session,
}

fn wait_in_room(members: &mut [Member], timeout: Duration) -> Result<()> {
    let t0 = Instant::now();
    loop {
        let mut all = true;
        for m in members.iter_mut() {
            m.session.wait(&mut m.editor, Duration::from_millis(2));
            all &= *m.session.state() == SessionState::InRoom
                && m.session.replica().has_scene()
                && m.session.replica().pending() == 0;
        }
        let seq = members[0].session.replica().seq();
        if all && members.iter().all(|m| m.session.replica().seq() == seq) {
            return Ok(());
        }
        if t0.elapsed() > timeout {
            bail!("the clients did not settle within {timeout:?}");
        }
    }
}

/// A pose with the primary button down at `at`.
fn dab_pose(at: DVec3) -> ToolPose {
    ToolPose { position: at, buttons: Buttons { primary: true, secondary: false }, ..ToolPose::default() }
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// Latency with `n` clients: (p50 ms, p99 ms, dabs measured, mean bytes per operation).
fn latency(storage: Arc<dyn Storage>, n: usize, config: &CollabConfig) -> Result<(f64, f64, usize, f64)> {
    let server_config = ServerConfig { rate: 1e6, burst: 1e6, ..ServerConfig::default() };
    let server = Server::start("127.0.0.1:0", storage, server_config)?;
    let room = fresh("latency");
    let url = server.url();
    let mut members = vec![Member {
        editor: Editor::default(),
        session: Session::host(&url, &room, "t", "0", &ball()?).map_err(anyhow::Error::msg)?,
    }];
    wait_in_room(&mut members, Duration::from_secs(60))?;
    for i in 1..n {
        members.push(Member { editor: Editor::default(), session: Session::join(&url, &room, "t", &i.to_string())? });
    }
    wait_in_room(&mut members, Duration::from_secs(120))?;
    let ids: Vec<u64> = members.iter().map(|m| m.session.replica().client().unwrap_or_default()).collect();
    // (author, number) → when it was sent, and when each other client applied it.
    let mut sent: HashMap<(u64, u64), Instant> = HashMap::new();
    let mut arrived: HashMap<(u64, u64), (usize, Instant)> = HashMap::new();
    let interval = Duration::from_secs_f64(1.0 / config.rate);
    let total = (config.rate * config.seconds).round() as usize;
    let mut next = Instant::now();
    let mut made = 0;
    let t_end = Instant::now() + Duration::from_secs_f64(config.seconds * 3.0 + 30.0);
    while (made < total || arrived.values().filter(|(k, _)| *k == n - 1).count() < sent.len()) && Instant::now() < t_end
    {
        if made < total && Instant::now() >= next {
            next += interval;
            let author = made % n;
            let m = &mut members[author];
            m.editor.tool.kind = ToolKind::Add;
            m.editor.tool.radius = 1.5;
            let angle = made as f64 * 0.37;
            let at = DVec3::new(25.0 * angle.cos(), 25.0 * angle.sin(), (made % 17) as f64 - 8.0);
            m.editor.frame(&dab_pose(at), Duration::ZERO)?;
            m.editor.frame(&ToolPose::at(at, false), Duration::ZERO)?;
            m.session.poll(&mut m.editor);
            sent.insert((ids[author], m.session.replica().last_number()), Instant::now());
            made += 1;
        }
        for (k, m) in members.iter_mut().enumerate() {
            for e in m.session.poll(&mut m.editor) {
                if let Event::Applied { author, number, .. } = e
                    && author != ids[k]
                {
                    let entry = arrived.entry((author, number)).or_insert((0, Instant::now()));
                    entry.0 += 1;
                    entry.1 = Instant::now();
                }
            }
        }
    }
    // Bytes: the workload's operation as the room sends it.
    let mut e = Editor::new(ball()?);
    e.record_ops(true);
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 1.5;
    e.frame(&dab_pose(DVec3::new(25.0, 0.0, 0.0)), Duration::ZERO)?;
    let bytes: Vec<f64> = e
        .take_ops()
        .into_iter()
        .map(|r| {
            let ordered = Ordered { seq: 1, author: 1, number: 1, entry: Entry::Edit(Box::new(r.op)) };
            encode(&ServerMsg::Op(ordered)).len() as f64
        })
        .collect();
    let mut lat: Vec<f64> = sent
        .iter()
        .filter_map(|(key, t)| {
            arrived.get(key).filter(|(k, _)| *k == n - 1).map(|(_, a)| a.duration_since(*t).as_secs_f64() * 1e3)
        })
        .collect();
    lat.sort_by(f64::total_cmp);
    let mean_bytes = bytes.iter().sum::<f64>() / bytes.len().max(1) as f64;
    Ok((quantile(&lat, 0.5), quantile(&lat, 0.99), lat.len(), mean_bytes))
}

/// Operations per second one room orders from one connection submitting `count` recorded dabs
/// as fast as the socket takes them.
fn throughput(storage: Arc<dyn Storage>, count: usize) -> Result<f64> {
    let config = ServerConfig { rate: 1e9, burst: 1e9, ..ServerConfig::default() };
    let server = Server::start("127.0.0.1:0", storage, config)?;
    let room = fresh("throughput");
    // The operations: dabs around the ball, recorded by an editor of the same scene.
    let mut e = Editor::new(ball()?);
    e.record_ops(true);
    e.tool.kind = ToolKind::Add;
    e.tool.radius = 1.5;
    let mut ops = Vec::with_capacity(count);
    for k in 0..count {
        let angle = k as f64 * 0.37;
        let at = DVec3::new(25.0 * angle.cos(), 25.0 * angle.sin(), (k % 17) as f64 - 8.0);
        e.frame(&dab_pose(at), Duration::ZERO)?;
        e.frame(&ToolPose::at(at, false), Duration::ZERO)?;
        ops.extend(e.take_ops().into_iter().map(|r| r.op));
    }
    let (mut ws, _) = tungstenite::connect(server.url())?;
    let hello = Hello {
        protocol: PROTOCOL,
        room,
        token: "t".into(),
        name: "burst".into(),
        resume: None,
        create: Some(strata_editor::file::encode(&ball()?)?),
    };
    ws.send(tungstenite::Message::Binary(encode(&ClientMsg::Hello(hello)).into()))?;
    // Welcome, snapshot.
    let read = |ws: &mut tungstenite::WebSocket<_>| -> Result<ServerMsg> {
        loop {
            if let tungstenite::Message::Binary(b) = ws.read()? {
                return Ok(decode::<ServerMsg>(&b, usize::MAX)?);
            }
        }
    };
    while !matches!(read(&mut ws)?, ServerMsg::Snapshot { .. }) {}
    let t0 = Instant::now();
    let last = ops.len() as u64;
    for (k, op) in ops.into_iter().enumerate() {
        ws.send(tungstenite::Message::Binary(
            encode(&ClientMsg::Submit { number: k as u64 + 1, op: Box::new(op) }).into(),
        ))?;
    }
    loop {
        match read(&mut ws)? {
            ServerMsg::Op(o) if o.number == last => break,
            ServerMsg::Refused { reason, .. } => bail!("the room refused an operation: {reason}"),
            _ => {}
        }
    }
    Ok(last as f64 / t0.elapsed().as_secs_f64())
}

/// Seconds for a client to join a room holding `scene` (the room made first), until it holds
/// the room's scene.
fn join(storage: Arc<dyn Storage>, scene: &Scene) -> Result<f64> {
    let server = Server::start("127.0.0.1:0", storage, ServerConfig::default())?;
    let room = fresh("join");
    let url = server.url();
    let mut host = vec![Member {
        editor: Editor::default(),
        session: Session::host(&url, &room, "t", "host", scene).map_err(anyhow::Error::msg)?,
    }];
    wait_in_room(&mut host, Duration::from_secs(300))?;
    let t0 = Instant::now();
    let mut guest = vec![Member { editor: Editor::default(), session: Session::join(&url, &room, "t", "guest")? }];
    wait_in_room(&mut guest, Duration::from_secs(300))?;
    Ok(t0.elapsed().as_secs_f64())
}

fn bunny(cells: u32) -> Result<Scene> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/bunny.ply");
    let mesh = strata_mesh::import::load_mesh(&path)?;
    let plan = strata_editor::import::plan(&mesh, strata_editor::import::Resolution::Cells(cells))?;
    let layer = strata_editor::import::convert(
        &mesh,
        &plan,
        strata_volume::brush::MeshRule::EvenOdd,
        "Bunny",
        &Default::default(),
    )?;
    Ok(Scene { layers: vec![layer], ..Scene::default() })
}

/// Runs the rows `config` asks for and returns them as markdown.
pub fn run(config: &CollabConfig) -> Result<String> {
    let dir = std::env::temp_dir().join(format!("strata-bench-collab-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mut out = String::new();
    out.push_str(&format!(
        "Latency: {} dabs a second over all clients for {} s (each client a full editor; one thread polls them all).\n\n",
        config.rate, config.seconds
    ));
    out.push_str("| storage | clients | dabs | p50 ms | p99 ms | bytes / op |\n|---|---:|---:|---:|---:|---:|\n");
    for (name, storage) in storages(config, &dir)? {
        for &n in &config.clients {
            let (p50, p99, count, bytes) = latency(storage.clone(), n, config)?;
            out.push_str(&format!("| {name} | {n} | {count} | {p50:.2} | {p99:.2} | {bytes:.0} |\n"));
        }
    }
    out.push_str(&format!("\nThroughput: {} recorded dabs from one connection.\n\n", config.burst));
    out.push_str("| storage | operations / s |\n|---|---:|\n");
    for (name, storage) in storages(config, &dir)? {
        out.push_str(&format!("| {name} | {:.0} |\n", throughput(storage, config.burst)?));
    }
    if config.join_cells > 0 {
        let scene = bunny(config.join_cells)?;
        let file = strata_editor::file::encode(&scene)?.len();
        out.push_str(&format!(
            "\nJoin: the bunny at {} cells ({:.1} MB scene file).\n\n| storage | join s |\n|---|---:|\n",
            config.join_cells,
            file as f64 / 1e6
        ));
        for (name, storage) in storages(config, &dir)? {
            out.push_str(&format!("| {name} | {:.3} |\n", join(storage, &scene)?));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(out)
}
