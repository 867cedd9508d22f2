//! The server's input and output: WebSocket connections on a tokio runtime, one thread per
//! open room.
//!
//! A connection's first message must be a hello (within [`ServerConfig::hello_timeout`]);
//! its messages then go to its room's thread in arrival order, read no faster than the
//! connection's rate limit allows (a token bucket: a flood is slowed, not served). A message
//! that cannot be read, one over the size limit, or one the room refuses as hostile closes the
//! connection with an error. The room's thread takes every message that waits, handles them,
//! stores the operations they ordered in one durable transaction and only then sends
//! anything: an operation a client saw acknowledged survives a `kill -9` of the server.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use strata_net::protocol::{ClientMsg, Hello, MAX_CLIENT_MESSAGE, MAX_HELLO, ServerMsg, decode, encode};
use tokio::sync::mpsc as async_mpsc;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;

use crate::room::{ConnId, Handled, Out, Room, RoomConfig, token_hash};
use crate::store::{Storage, StoredRoom};

/// How the server behaves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServerConfig {
    /// Each room's behaviour.
    pub room: RoomConfig,
    /// Messages a connection may send per second, sustained.
    pub rate: f64,
    /// Messages a connection may send at once.
    pub burst: f64,
    /// How long a new connection has to say hello.
    pub hello_timeout: Duration,
    /// Messages waiting for a slow connection before it is closed.
    pub out_queue: usize,
}

impl Default for ServerConfig {
    /// 240 messages a second with bursts of 480 (a 120 Hz tool's operations and a 30 Hz
    /// presence with room to spare), 10 s to say hello, 8,192 messages queued per connection.
    fn default() -> Self {
        ServerConfig {
            room: RoomConfig::default(),
            rate: 240.0,
            burst: 480.0,
            hello_timeout: Duration::from_secs(10),
            out_queue: 8192,
        }
    }
}

/// What one connection is sent.
#[derive(Debug)]
enum Outgoing {
    Bytes(Arc<[u8]>),
    /// The error to send before closing, and whether connecting again may work.
    Close(String, bool),
}

/// How a room reaches one connection: its queue, and a signal that ends it at once (when the
/// queue is full, so that even a close cannot be queued).
#[derive(Clone, Debug)]
struct ConnLink {
    out: async_mpsc::Sender<Outgoing>,
    kill: Arc<tokio::sync::Notify>,
}

impl ConnLink {
    /// Queues `o`; a connection whose queue is full is ended (it resumes when it reconnects).
    fn send(&self, o: Outgoing) -> bool {
        let sent = self.out.try_send(o).is_ok();
        if !sent {
            self.kill.notify_one();
        }
        sent
    }
}

enum RoomInput {
    Join { conn: ConnId, hello: Hello, link: ConnLink },
    Msg { conn: ConnId, msg: ClientMsg },
    Leave { conn: ConnId },
}

/// Messages waiting for a room's thread, at most (a connection's reader waits beyond).
const ROOM_QUEUE: usize = 4096;

type Rooms = Arc<Mutex<HashMap<String, mpsc::SyncSender<RoomInput>>>>;

/// What the connection tasks share.
struct Shared {
    rooms: Rooms,
    storage: Arc<dyn Storage>,
    config: ServerConfig,
    next_conn: AtomicU64,
    room_threads: Mutex<Vec<JoinHandle<()>>>,
}

/// The answer to a hello for a room that does not exist or a wrong token: the same words, so
/// that a client without the token learns nothing of the room.
fn no_room(name: &str) -> String {
    format!("no room `{name}` with that token on this server")
}

/// A running server (see the module docs). Dropping it stops it.
#[derive(Debug)]
pub struct Server {
    addr: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl Server {
    /// Listens on `listen` (`127.0.0.1:0` picks a free port) and serves rooms kept in
    /// `storage`.
    pub fn start(listen: &str, storage: Arc<dyn Storage>, config: ServerConfig) -> std::io::Result<Server> {
        let listener = std::net::TcpListener::bind(listen)?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
        let (stop, stopped) = tokio::sync::oneshot::channel();
        let shared = Arc::new(Shared {
            rooms: Default::default(),
            storage,
            config,
            next_conn: AtomicU64::new(1),
            room_threads: Mutex::new(Vec::new()),
        });
        let thread = std::thread::Builder::new().name("strata-server".into()).spawn(move || {
            runtime.block_on(async {
                let Ok(listener) = tokio::net::TcpListener::from_std(listener) else { return };
                tokio::pin!(stopped);
                loop {
                    tokio::select! {
                        _ = &mut stopped => break,
                        accepted = listener.accept() => if let Ok((stream, _)) = accepted {
                            let shared = shared.clone();
                            tokio::spawn(async move { connection(stream, shared).await });
                        },
                    }
                }
            });
            // Tasks end with the runtime; the rooms' inputs close and their threads end.
            drop(runtime);
            shared.rooms.lock().unwrap_or_else(|p| p.into_inner()).clear();
            let threads = std::mem::take(&mut *shared.room_threads.lock().unwrap_or_else(|p| p.into_inner()));
            for t in threads {
                let _ = t.join();
            }
        })?;
        Ok(Server { addr, stop: Some(stop), thread: Some(thread) })
    }

    /// Where it listens.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The address clients connect to (`ws://host:port`).
    pub fn url(&self) -> String {
        format!("ws://{}", self.addr)
    }

    /// Runs until the process ends (for `strata serve`).
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A token bucket (see [`ServerConfig::rate`]).
struct Bucket {
    tokens: f64,
    rate: f64,
    burst: f64,
    at: Instant,
}

impl Bucket {
    /// Waits until a message may be handled.
    async fn take(&mut self) {
        let now = Instant::now();
        self.tokens = (self.tokens + now.duration_since(self.at).as_secs_f64() * self.rate).min(self.burst);
        self.at = now;
        if self.tokens < 1.0 {
            let wait = (1.0 - self.tokens) / self.rate;
            tokio::time::sleep(Duration::from_secs_f64(wait)).await;
            self.tokens = 1.0;
            self.at = Instant::now();
        }
        self.tokens -= 1.0;
    }
}

async fn connection(stream: tokio::net::TcpStream, shared: Arc<Shared>) {
    let _ = stream.set_nodelay(true);
    // The hello may carry a new room's scene; every later message is held to
    // MAX_CLIENT_MESSAGE when it is decoded.
    let ws_config = WebSocketConfig::default().max_message_size(Some(MAX_HELLO)).max_frame_size(Some(MAX_HELLO));
    let Ok(Ok(ws)) = tokio::time::timeout(
        shared.config.hello_timeout,
        tokio_tungstenite::accept_async_with_config(stream, Some(ws_config)),
    )
    .await
    else {
        return;
    };
    let (mut sink, mut incoming) = ws.split();
    let refuse = |reason: String| Message::Binary(encode(&ServerMsg::Error { reason, retry: false }).into());
    let hello = match tokio::time::timeout(shared.config.hello_timeout, incoming.next()).await {
        Ok(Some(Ok(Message::Binary(bytes)))) => match decode::<ClientMsg>(&bytes, MAX_HELLO) {
            Ok(ClientMsg::Hello(h)) => h,
            Ok(_) => {
                let _ = sink.send(refuse("the first message must be a hello".into())).await;
                return;
            }
            Err(e) => {
                let _ = sink.send(refuse(e.to_string())).await;
                return;
            }
        },
        Ok(Some(Ok(_))) => {
            let _ = sink.send(refuse("the first message must be a binary hello".into())).await;
            return;
        }
        // (The connection ended or failed before a hello: no one is left to tell.)
        Ok(None | Some(Err(_))) => return,
        // A client that was slow to speak (a busy machine) may well do better next time.
        Err(_) => {
            let why = format!("no hello within {:?}; connect again", shared.config.hello_timeout);
            let again = Message::Binary(encode(&ServerMsg::Error { reason: why, retry: true }).into());
            let _ = sink.send(again).await;
            return;
        }
    };
    if hello.room.is_empty() || hello.room.len() > 128 || hello.token.len() > 1024 {
        let _ = sink.send(refuse(no_room(&hello.room.chars().take(128).collect::<String>()))).await;
        return;
    }
    let conn = shared.next_conn.fetch_add(1, Ordering::Relaxed);
    let (out, mut out_rx) = async_mpsc::channel(shared.config.out_queue);
    let link = ConnLink { out, kill: Arc::new(tokio::sync::Notify::new()) };
    let room = match enter(&shared, conn, hello, link.clone()) {
        Ok(room) => room,
        Err(why) => {
            let again = Message::Binary(encode(&ServerMsg::Error { reason: why, retry: true }).into());
            let _ = sink.send(again).await;
            return;
        }
    };
    // The writer: what the room sends, in order; a close sends the reason and ends.
    let mut writer = tokio::spawn(async move {
        while let Some(o) = out_rx.recv().await {
            match o {
                Outgoing::Bytes(b) => {
                    if sink.send(Message::Binary(b.to_vec().into())).await.is_err() {
                        return;
                    }
                }
                Outgoing::Close(reason, retry) => {
                    let _ = sink.send(Message::Binary(encode(&ServerMsg::Error { reason, retry }).into())).await;
                    let _ = sink.close().await;
                    return;
                }
            }
        }
    });
    let close = |reason: String| {
        link.send(Outgoing::Close(reason, false));
    };
    let mut bucket = Bucket {
        tokens: shared.config.burst,
        rate: shared.config.rate,
        burst: shared.config.burst,
        at: Instant::now(),
    };
    let mut last_presence: Option<Instant> = None;
    let mut killed = false;
    let mut writer_done = false;
    loop {
        let next = tokio::select! {
            next = incoming.next() => next,
            _ = link.kill.notified() => {
                killed = true;
                break;
            }
            _ = &mut writer => {
                writer_done = true;
                break;
            }
        };
        let bytes = match next {
            Some(Ok(Message::Binary(bytes))) => bytes,
            Some(Ok(Message::Close(_))) | None => break,
            Some(Ok(Message::Text(_))) => {
                close("text messages are not part of the protocol".into());
                break;
            }
            Some(Ok(_)) => continue,
            Some(Err(e)) => {
                close(e.to_string());
                break;
            }
        };
        bucket.take().await;
        let msg = match decode::<ClientMsg>(&bytes, MAX_CLIENT_MESSAGE) {
            Ok(m) => m,
            Err(e) => {
                close(e.to_string());
                break;
            }
        };
        if matches!(msg, ClientMsg::Presence(_)) {
            // At most 30 a second; the rest are dropped.
            if last_presence.is_some_and(|t| t.elapsed() < Duration::from_millis(30)) {
                continue;
            }
            last_presence = Some(Instant::now());
        }
        // A busy room's queue holds this reader back (a flood waits here, not in memory).
        let mut input = RoomInput::Msg { conn, msg };
        loop {
            match room.try_send(input) {
                Ok(()) => break,
                Err(mpsc::TrySendError::Full(back)) => {
                    input = back;
                    tokio::time::sleep(Duration::from_millis(2)).await;
                }
                Err(mpsc::TrySendError::Disconnected(_)) => {
                    link.send(Outgoing::Close("the room closed; connect again".into(), true));
                    break;
                }
            }
        }
    }
    // (A full queue cannot block the leave: the room learns of it at its next message.)
    let _ = room.send(RoomInput::Leave { conn });
    drop(link);
    if killed {
        // Too far behind to take even a close: the socket just ends; the client resumes.
        writer.abort();
    }
    if !writer_done {
        let _ = writer.await;
    }
}

/// Hands a hello to its room's thread, starting the thread when the room is not open; or says
/// why not (worth trying again).
fn enter(
    shared: &Arc<Shared>,
    conn: ConnId,
    hello: Hello,
    link: ConnLink,
) -> Result<mpsc::SyncSender<RoomInput>, String> {
    let mut rooms = shared.rooms.lock().unwrap_or_else(|p| p.into_inner());
    let name = hello.room.clone();
    let mut input = RoomInput::Join { conn, hello, link };
    // Threads of rooms that closed are reaped as new ones start.
    shared.room_threads.lock().unwrap_or_else(|p| p.into_inner()).retain(|t| !t.is_finished());
    // A room whose thread just ended is started again (twice at most).
    for _ in 0..2 {
        let tx = match rooms.get(&name) {
            Some(tx) => tx.clone(),
            None => {
                let (tx, rx) = mpsc::sync_channel(ROOM_QUEUE);
                let s = shared.clone();
                let n = name.clone();
                let t = std::thread::Builder::new()
                    .name(format!("room {name}"))
                    .spawn(move || room_thread(&n, &s, rx))
                    .map_err(|e| format!("the server cannot open a room now ({e}); connect again"))?;
                shared.room_threads.lock().unwrap_or_else(|p| p.into_inner()).push(t);
                rooms.insert(name.clone(), tx.clone());
                tx
            }
        };
        match tx.try_send(input) {
            Ok(()) => return Ok(tx),
            Err(mpsc::TrySendError::Full(_)) => return Err("the room is busy; connect again".into()),
            Err(mpsc::TrySendError::Disconnected(back)) => {
                rooms.remove(&name);
                input = back;
            }
        }
    }
    Err("the server is stopping".into())
}

/// A room's thread: opens the room from storage and handles its messages in batches until no
/// connection is left.
fn room_thread(name: &str, shared: &Arc<Shared>, rx: mpsc::Receiver<RoomInput>) {
    let mut conns: HashMap<ConnId, ConnLink> = HashMap::new();
    let result = serve_room(name, shared, &rx, &mut conns);
    // Out of service: no new inputs; those waiting are told, as are the connections (they
    // may connect again: the room opens anew).
    shared.rooms.lock().unwrap_or_else(|p| p.into_inner()).remove(name);
    let reason = match result {
        Ok(()) => "the room closed; connect again".to_owned(),
        Err(e) => format!("the room stopped: {e}; connect again"),
    };
    for input in rx.try_iter() {
        if let RoomInput::Join { link, .. } = input {
            link.send(Outgoing::Close(reason.clone(), true));
        }
    }
    for (_, link) in conns {
        link.send(Outgoing::Close(reason.clone(), true));
    }
}

fn serve_room(
    name: &str,
    shared: &Arc<Shared>,
    rx: &mpsc::Receiver<RoomInput>,
    conns: &mut HashMap<ConnId, ConnLink>,
) -> Result<(), String> {
    let config = shared.config.room;
    let mut store = shared.storage.open(name).map_err(|e| e.to_string())?;
    let mut room = match store.load().map_err(|e| e.to_string())? {
        Some(stored) => Some(Room::open(name, stored, config).map_err(|e| e.to_string())?),
        None => None,
    };
    loop {
        // Idle rooms with no one in them close (their thread ends; a hello opens them again).
        let first = match rx.recv_timeout(Duration::from_secs(30)) {
            Ok(i) => i,
            Err(mpsc::RecvTimeoutError::Timeout) if conns.is_empty() => return Ok(()),
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => return Ok(()),
        };
        let mut h = Handled::default();
        for input in std::iter::once(first).chain(rx.try_iter().take(1023)) {
            match input {
                RoomInput::Join { conn, hello, link } => {
                    conns.insert(conn, link);
                    if room.is_none()
                        && let Some(scene) = &hello.create
                    {
                        // A new room: its first snapshot must load.
                        if strata_editor::room::decode(scene).is_ok() {
                            let stored = StoredRoom {
                                token_hash: token_hash(&hello.token),
                                snapshot_seq: 0,
                                snapshot: scene.clone(),
                                clients: Vec::new(),
                                ops: Vec::new(),
                            };
                            store.create(stored.token_hash, scene).map_err(|e| e.to_string())?;
                            room = Some(Room::open(name, stored, config).map_err(|e| e.to_string())?);
                        }
                    }
                    match room.as_mut() {
                        Some(r) if r.admits(&hello.token) => {
                            let joined = r.join(conn, hello);
                            h.out.extend(joined.out);
                        }
                        _ => h.out.push(Out::Close(conn, no_room(name))),
                    }
                }
                RoomInput::Msg { conn, msg } => match room.as_mut() {
                    Some(r) => r.handle(conn, msg, &mut h),
                    None => h.out.push(Out::Close(conn, no_room(name))),
                },
                RoomInput::Leave { conn } => {
                    conns.remove(&conn);
                    if let Some(r) = room.as_mut() {
                        r.leave(conn, &mut h);
                    }
                }
            }
        }
        // Durable before anything is said of it.
        if !h.logged.is_empty() {
            store.append(&h.logged).map_err(|e| e.to_string())?;
        }
        deliver(h.out, conns, room.as_mut());
        if let Some(r) = room.as_mut()
            && let Some(snapshot) = r.snapshot_due()
        {
            store.compact(snapshot.seq, &snapshot.scene, &snapshot.clients).map_err(|e| e.to_string())?;
            r.snapshot_stored(snapshot.seq);
        }
        if room.is_none() && conns.is_empty() {
            return Ok(());
        }
    }
}

/// Sends the room's messages and closes; a connection too slow to take a message is ended
/// (it resumes when it reconnects) and the others are told it left.
fn deliver(mut outs: Vec<Out>, conns: &mut HashMap<ConnId, ConnLink>, mut room: Option<&mut Room>) {
    while !outs.is_empty() {
        let mut more = Vec::new();
        for o in outs {
            match o {
                Out::Send(conn, bytes) => {
                    if let Some(link) = conns.get(&conn)
                        && !link.send(Outgoing::Bytes(bytes))
                    {
                        conns.remove(&conn);
                        if let Some(r) = room.as_deref_mut() {
                            let mut left = Handled::default();
                            r.leave(conn, &mut left);
                            more.extend(left.out);
                        }
                    }
                }
                Out::Close(conn, reason) => {
                    if let Some(link) = conns.remove(&conn) {
                        link.send(Outgoing::Close(reason, false));
                    }
                }
            }
        }
        outs = more;
    }
}
