//! A room's logic, free of sockets and threads: it holds the room's editor (the authoritative
//! scene), puts every accepted operation in the total order, refuses what it must, and says
//! what to send to whom and what to store. The server ([`crate::server`]) runs one on its own
//! thread and stores [`Handled::logged`] durably before it sends anything.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::hash::{BuildHasher, Hasher};

use sha2::{Digest, Sha256};
use strata_editor::{Editor, OpUndo};
use strata_net::protocol::{
    ClientId, ClientMsg, Entry, Hello, Ordered, PROTOCOL, Peer, Presence, ResumeKey, Seq, ServerMsg, encode,
};
use strata_net::{Limits, state_hash, validate};
use strata_volume::ChunkKey;

use crate::store::StoredRoom;

/// A connection's number on the server.
pub type ConnId = u64;

/// How a room behaves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoomConfig {
    /// What one operation may do.
    pub limits: Limits,
    /// A state digest is sent after every this many operations.
    pub hash_every: u64,
    /// Operations kept in memory for resumes (older resumes get a snapshot).
    pub tail: usize,
    /// The log is folded into a snapshot after this many operations.
    pub compact_every: u64,
}

impl Default for RoomConfig {
    /// Default limits; a digest every 64 operations; 4,096 operations of tail; compaction every
    /// 2,048.
    fn default() -> Self {
        RoomConfig { limits: Limits::default(), hash_every: 64, tail: 4096, compact_every: 2048 }
    }
}

/// What the room wants done.
#[derive(Clone, Debug, PartialEq)]
pub enum Out {
    /// Send these bytes (an encoded [`ServerMsg`]) to a connection.
    Send(ConnId, std::sync::Arc<[u8]>),
    /// Send this error and close the connection.
    Close(ConnId, String),
}

/// What handling messages produced.
#[derive(Debug, Default)]
pub struct Handled {
    /// Operations newly ordered: store them (durably) before sending `out`.
    pub logged: Vec<Ordered>,
    /// Messages and closes, in order.
    pub out: Vec<Out>,
}

impl Handled {
    fn send(&mut self, conn: ConnId, msg: &ServerMsg) {
        self.out.push(Out::Send(conn, encode(msg).into()));
    }
}

/// A room's state to store in place of its log (see [`crate::store::RoomStore::compact`]).
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// The last operation it holds.
    pub seq: Seq,
    /// The scene file.
    pub scene: std::sync::Arc<Vec<u8>>,
    /// Each client's highest ordered number.
    pub clients: Vec<(ClientId, u64)>,
}

/// Why a room could not be opened or created.
#[derive(Debug, thiserror::Error)]
pub enum RoomError {
    /// A stored snapshot or operation does not load.
    #[error("the room's stored state does not load: {0}")]
    Damaged(String),
}

struct Conn {
    client: ClientId,
    name: String,
    /// The sequence number of the last snapshot sent to it.
    snapshot_at: Option<Seq>,
}

/// A room (see the module docs).
pub struct Room {
    name: String,
    token_hash: [u8; 32],
    editor: Editor,
    config: RoomConfig,
    seq: Seq,
    /// Every client the room ordered something of (or welcomed since it opened): its highest
    /// number seen.
    clients: BTreeMap<ClientId, u64>,
    conns: HashMap<ConnId, Conn>,
    /// Recent operations, for resumes.
    tail: VecDeque<Ordered>,
    /// The operation the stored snapshot holds up to.
    snapshot_seq: Seq,
    /// The scene file at `.0`, while no operation came since.
    encoded: Option<(Seq, std::sync::Arc<Vec<u8>>)>,
    ids: std::collections::hash_map::RandomState,
    id_counter: u64,
    /// Recent entries: who made them, where, and (for edits not undone) what undoes them.
    done: BTreeMap<Seq, Done>,
    /// Heap bytes of the undo records in `done`.
    done_bytes: usize,
    /// Each client's edits that may still be undone, newest last.
    undoable: HashMap<ClientId, Vec<Seq>>,
    /// Strokes (author, stroke) of which some entries were forgotten (older than what the room
    /// remembers, or before the stored snapshot): an undo of one would be partial, so it is
    /// refused.
    forgotten: std::collections::HashSet<(ClientId, u64)>,
}

/// An entry the room remembers for undo.
struct Done {
    author: ClientId,
    /// The author's stroke (edits only).
    stroke: Option<u64>,
    surface: usize,
    keys: Vec<ChunkKey>,
    undo: Option<OpUndo>,
}

/// The undo records a room keeps, at most (bytes); older edits cannot be undone.
const UNDO_BUDGET: usize = 256 << 20;

impl std::fmt::Debug for Room {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Room").field("name", &self.name).field("seq", &self.seq).finish_non_exhaustive()
    }
}

/// The identity a resume key stands for: the first 64 bits of its SHA-256 (public ids do not
/// give keys away).
pub fn client_of(key: &ResumeKey) -> ClientId {
    let d = Sha256::digest(key);
    u64::from_le_bytes(d[..8].try_into().expect("8 bytes"))
}

/// How a room's own world streams: it never moves a viewer, so it loads what edits reach and
/// keeps it; one worker thread (the room's thread does the edits).
fn room_world_settings() -> strata_terrain::WorldSettings {
    strata_terrain::WorldSettings { threads: 1, ..strata_terrain::WorldSettings::default() }
}

/// SHA-256 of a token.
pub fn token_hash(token: &str) -> [u8; 32] {
    Sha256::digest(token.as_bytes()).into()
}

impl Room {
    /// The room as stored: its snapshot with the logged operations replayed.
    pub fn open(name: &str, stored: StoredRoom, config: RoomConfig) -> Result<Room, RoomError> {
        let content = strata_editor::room::decode(&stored.snapshot).map_err(RoomError::Damaged)?;
        let editor = strata_editor::room::editor_for(content, room_world_settings()).map_err(RoomError::Damaged)?;
        let mut room = Room {
            name: name.to_owned(),
            token_hash: stored.token_hash,
            editor,
            config,
            seq: stored.snapshot_seq,
            clients: stored.clients.into_iter().collect(),
            conns: HashMap::new(),
            tail: VecDeque::new(),
            snapshot_seq: stored.snapshot_seq,
            encoded: None,
            ids: Default::default(),
            id_counter: 0,
            done: BTreeMap::new(),
            done_bytes: 0,
            undoable: HashMap::new(),
            forgotten: Default::default(),
        };
        // Each author's first stroke after the snapshot may have begun before it.
        let mut first_seen: std::collections::HashSet<ClientId> = std::collections::HashSet::new();
        for op in stored.ops {
            if op.seq != room.seq + 1 {
                return Err(RoomError::Damaged(format!("operation {} follows {}", op.seq, room.seq)));
            }
            // An entry was applied before it was stored: it applies again.
            let applied = match &op.entry {
                Entry::Edit(edit) => room.editor.replay(edit).map(Some).map_err(|e| e.to_string()),
                Entry::Undo { undo, .. } => undo
                    .iter()
                    .try_for_each(|u| room.editor.revert(u.clone()).map_err(|(e, _)| e.to_string()))
                    .map(|_| None),
            };
            let undo =
                applied.map_err(|e| RoomError::Damaged(format!("stored entry {} does not apply: {e}", op.seq)))?;
            if let Entry::Edit(edit) = &op.entry
                && room.snapshot_seq > 0
                && first_seen.insert(op.author)
            {
                room.forgotten.insert((op.author, edit.stroke));
            }
            room.remember(&op, undo);
            room.order(op);
        }
        Ok(room)
    }

    /// The room's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The last ordered operation.
    pub fn seq(&self) -> Seq {
        self.seq
    }

    /// The room's editor (the authoritative scene).
    pub fn editor(&self) -> &Editor {
        &self.editor
    }

    /// Whether `token` opens the room.
    pub fn admits(&self, token: &str) -> bool {
        // (Digests of equal length compared whole: no early exit to time.)
        token_hash(token).iter().zip(self.token_hash.iter()).fold(0u8, |acc, (a, b)| acc | (a ^ b)) == 0
    }

    /// Connections in the room.
    pub fn connections(&self) -> usize {
        self.conns.len()
    }

    /// Operations since the stored snapshot.
    pub fn since_snapshot(&self) -> u64 {
        self.seq - self.snapshot_seq
    }

    /// A snapshot to store, after [`RoomConfig::compact_every`] operations (`None` before).
    pub fn snapshot_due(&mut self) -> Option<Snapshot> {
        if self.since_snapshot() < self.config.compact_every {
            return None;
        }
        let scene = self.encoded_scene()?;
        Some(Snapshot { seq: self.seq, scene, clients: self.clients.iter().map(|(c, n)| (*c, *n)).collect() })
    }

    /// Records that the snapshot after `seq` is stored.
    pub fn snapshot_stored(&mut self, seq: Seq) {
        self.snapshot_seq = self.snapshot_seq.max(seq);
    }

    fn encoded_scene(&mut self) -> Option<std::sync::Arc<Vec<u8>>> {
        if let Some((seq, bytes)) = &self.encoded
            && *seq == self.seq
        {
            return Some(bytes.clone());
        }
        let bytes = std::sync::Arc::new(strata_editor::room::encode(&self.editor).ok()?);
        self.encoded = Some((self.seq, bytes.clone()));
        Some(bytes)
    }

    /// A new client's identity and its secret key: 128 bits of SipHash keyed from the operating
    /// system's randomness (a pseudo-random function: unpredictable without its keys), the
    /// identity derived from them.
    fn new_client(&mut self) -> (ClientId, ResumeKey) {
        loop {
            self.id_counter += 1;
            let mut key = [0u8; 16];
            for (half, part) in key.chunks_mut(8).enumerate() {
                let mut h = self.ids.build_hasher();
                h.write_u64(self.id_counter);
                h.write_u8(half as u8);
                part.copy_from_slice(&h.finish().to_le_bytes());
            }
            let id = client_of(&key);
            if id != 0 && !self.clients.contains_key(&id) && !self.conns.values().any(|c| c.client == id) {
                return (id, key);
            }
        }
    }

    /// A connection's hello (the server checked the token with [`Room::admits`]).
    pub fn join(&mut self, conn: ConnId, hello: Hello) -> Handled {
        let mut h = Handled::default();
        if hello.protocol != PROTOCOL {
            let reason = format!("this server speaks protocol {PROTOCOL}, not {}", hello.protocol);
            h.out.push(Out::Close(conn, reason));
            return h;
        }
        // A client known to the room resumes (its key proves who it is); anyone else is someone
        // new.
        let known = hello.resume.filter(|r| self.clients.contains_key(&client_of(&r.key)));
        let (client, key) = match known {
            Some(r) => (client_of(&r.key), r.key),
            None => self.new_client(),
        };
        // (A client is recorded with its first operation: hellos alone leave nothing behind.)
        let acked = self.clients.get(&client).copied().unwrap_or(0);
        // The same client on another connection (the old one not yet noticed dead) leaves.
        let stale: Vec<ConnId> = self.conns.iter().filter(|(_, c)| c.client == client).map(|(id, _)| *id).collect();
        for old in stale {
            self.conns.remove(&old);
            h.out.push(Out::Close(old, "the same client connected again".into()));
        }
        let name: String = hello.name.chars().take(64).collect();
        let peers: Vec<Peer> = self.conns.values().map(|c| Peer { client: c.client, name: c.name.clone() }).collect();
        h.send(conn, &ServerMsg::Welcome { client, key, acked, seq: self.seq, peers });
        let first_in_tail = self.tail.front().map_or(self.seq + 1, |o| o.seq);
        let sent_snapshot = match known {
            Some(r) if r.seq.is_some_and(|seq| seq <= self.seq && seq + 1 >= first_in_tail) => {
                let after = r.seq.unwrap_or_default();
                for op in self.tail.iter().filter(|o| o.seq > after) {
                    h.out.push(Out::Send(conn, encode(&ServerMsg::Op(op.clone())).into()));
                }
                false
            }
            _ => {
                self.send_snapshot(conn, acked, &mut h);
                true
            }
        };
        let me = Peer { client, name: name.clone() };
        for &other in self.conns.keys() {
            h.send(
                other,
                &ServerMsg::Presence { peer: me.clone(), presence: Presence { position: None, radius: 0.0 } },
            );
        }
        let snapshot_at = sent_snapshot.then_some(self.seq);
        self.conns.insert(conn, Conn { client, name, snapshot_at });
        h
    }

    fn send_snapshot(&mut self, conn: ConnId, acked: u64, h: &mut Handled) {
        match self.encoded_scene() {
            Some(scene) => {
                h.send(conn, &ServerMsg::Snapshot { seq: self.seq, acked, scene: scene.to_vec() });
                if let Some(c) = self.conns.get_mut(&conn) {
                    c.snapshot_at = Some(self.seq);
                }
            }
            None => h.out.push(Out::Close(conn, "the room's scene cannot be encoded".into())),
        }
    }

    /// A message from a joined connection.
    pub fn handle(&mut self, conn: ConnId, msg: ClientMsg, h: &mut Handled) {
        let Some(client) = self.conns.get(&conn).map(|c| c.client) else {
            h.out.push(Out::Close(conn, "not in the room".into()));
            return;
        };
        match msg {
            ClientMsg::Hello(_) => self.kick(conn, "a second hello".into(), h),
            ClientMsg::Submit { number, op } => {
                let acked = self.clients.get(&client).copied().unwrap_or(0);
                if number <= acked {
                    // Sent again after a resume: it is already in the order (or refused).
                    return;
                }
                if number != acked + 1 {
                    self.kick(conn, format!("operation {number} does not follow {acked}"), h);
                    return;
                }
                match validate(&op, &self.editor, &self.config.limits) {
                    // Numbers that are not numbers: not a client of ours.
                    Err(e @ strata_net::Invalid::NotFinite) => {
                        self.kick(conn, format!("operation {number} refused: {e}"), h);
                        return;
                    }
                    // Out of bounds: refused, taken back by its author.
                    Err(e) => {
                        self.clients.insert(client, number);
                        h.send(conn, &ServerMsg::Refused { number, reason: e.to_string() });
                        return;
                    }
                    Ok(()) => {}
                }
                self.clients.insert(client, number);
                match self.editor.replay(&op) {
                    Ok(undo) => {
                        let ordered = Ordered { seq: self.seq + 1, author: client, number, entry: Entry::Edit(op) };
                        self.publish(ordered, Some(undo), h);
                    }
                    Err(e) => h.send(conn, &ServerMsg::Refused { number, reason: e.to_string() }),
                }
            }
            ClientMsg::Presence(p) => {
                if !(p.radius.is_finite() && p.position.is_none_or(|v| v.is_finite())) {
                    self.kick(conn, "a presence that is not finite".into(), h);
                    return;
                }
                let name = self.conns.get(&conn).map(|c| c.name.clone()).unwrap_or_default();
                let msg: std::sync::Arc<[u8]> =
                    encode(&ServerMsg::Presence { peer: Peer { client, name }, presence: p }).into();
                for (&c, _) in self.conns.iter().filter(|(id, _)| **id != conn) {
                    h.out.push(Out::Send(c, msg.clone()));
                }
            }
            ClientMsg::Undo => match self.undo(client) {
                Ok(ordered) => self.publish(ordered, None, h),
                Err(reason) => h.send(conn, &ServerMsg::UndoRefused { reason }),
            },
            ClientMsg::Resync => {
                // One snapshot per connection and sequence number: asking again before
                // anything changed gets nothing more.
                if self.conns.get(&conn).is_some_and(|c| c.snapshot_at == Some(self.seq)) {
                    return;
                }
                let acked = self.clients.get(&client).copied().unwrap_or(0);
                self.send_snapshot(conn, acked, h);
            }
        }
    }

    /// A connection went away.
    pub fn leave(&mut self, conn: ConnId, h: &mut Handled) {
        if let Some(c) = self.conns.remove(&conn) {
            let msg: std::sync::Arc<[u8]> = encode(&ServerMsg::Left { client: c.client }).into();
            for &other in self.conns.keys() {
                h.out.push(Out::Send(other, msg.clone()));
            }
        }
    }

    fn kick(&mut self, conn: ConnId, reason: String, h: &mut Handled) {
        self.leave(conn, h);
        h.out.push(Out::Close(conn, reason));
    }

    /// Orders an applied entry (with what undoes it, for an edit), logs and broadcasts it,
    /// and a digest when one is due.
    fn publish(&mut self, ordered: Ordered, undo: Option<OpUndo>, h: &mut Handled) {
        self.remember(&ordered, undo);
        self.order(ordered.clone());
        let msg: std::sync::Arc<[u8]> = encode(&ServerMsg::Op(ordered.clone())).into();
        h.logged.push(ordered);
        for &c in self.conns.keys() {
            h.out.push(Out::Send(c, msg.clone()));
        }
        if self.seq.is_multiple_of(self.config.hash_every)
            && let Some(hash) = state_hash(&self.editor.scene)
        {
            let msg: std::sync::Arc<[u8]> = encode(&ServerMsg::Hash { seq: self.seq, hash }).into();
            for &c in self.conns.keys() {
                h.out.push(Out::Send(c, msg.clone()));
            }
        }
    }

    /// Remembers an entry for undo: where it changed things, and for an edit what undoes it.
    fn remember(&mut self, ordered: &Ordered, undo: Option<OpUndo>) {
        let (stroke, surface, mut keys) = match (&ordered.entry, &undo) {
            (Entry::Edit(op), Some(u)) => (Some(op.stroke), u.surface(), u.keys()),
            (Entry::Edit(op), None) => (Some(op.stroke), op.surface as usize, Vec::new()),
            (Entry::Undo { undo, .. }, _) => {
                (None, undo.first().map_or(0, OpUndo::surface), undo.iter().flat_map(OpUndo::keys).collect())
            }
        };
        keys.sort();
        keys.dedup();
        if let Entry::Undo { of, .. } = &ordered.entry {
            // (Already off the author's stack when the undo was made here; not when it is
            // read back from storage.)
            if let Some(stack) = self.undoable.get_mut(&ordered.author) {
                stack.retain(|s| !of.contains(s));
            }
            for s in of {
                if let Some(d) = self.done.get_mut(s)
                    && let Some(u) = d.undo.take()
                {
                    self.done_bytes -= u.bytes();
                }
            }
        }
        if undo.is_some() {
            self.undoable.entry(ordered.author).or_default().push(ordered.seq);
        }
        self.done_bytes += undo.as_ref().map_or(0, OpUndo::bytes);
        self.done.insert(ordered.seq, Done { author: ordered.author, stroke, surface, keys, undo });
        // Oldest first out, beyond the tail or the memory budget.
        while self.done.len() > self.config.tail.max(1) || self.done_bytes > UNDO_BUDGET {
            let Some((seq, d)) = self.done.pop_first() else { break };
            self.done_bytes -= d.undo.as_ref().map_or(0, OpUndo::bytes);
            if let Some(stroke) = d.stroke {
                self.forgotten.insert((d.author, stroke));
            }
            if let Some(stack) = self.undoable.get_mut(&d.author) {
                stack.retain(|s| *s != seq);
            }
        }
    }

    /// The entry that undoes `client`'s newest stroke not undone yet, applied; or why not.
    fn undo(&mut self, client: ClientId) -> Result<Ordered, String> {
        let stack = self.undoable.get(&client).map(Vec::as_slice).unwrap_or_default();
        let Some(&newest) = stack.last() else {
            return Err("nothing of yours is left to undo in this room".into());
        };
        // The stroke's entries: the newest and those before it of the same stroke, in a row.
        let stroke = self.done.get(&newest).and_then(|d| d.stroke);
        let group: Vec<Seq> = stack
            .iter()
            .rev()
            .take_while(|s| self.done.get(s).is_some_and(|d| d.stroke == stroke && d.undo.is_some()))
            .copied()
            .collect();
        let Some(&oldest) = group.last() else { return Err("that edit is too old to undo".into()) };
        if stroke.is_some_and(|st| self.forgotten.contains(&(client, st))) {
            return Err("that stroke is too old to undo (the room no longer holds all of it)".into());
        }
        for &s in &group {
            let d = &self.done[&s];
            // Someone else's edit since, not undone, in the same chunks. (An undone edit and its
            // undo leave the chunks as they were before it.)
            let later = self.done.range(oldest + 1..).find(|(_, l)| {
                l.author != client
                    && l.stroke.is_some()
                    && l.undo.is_some()
                    && l.surface == d.surface
                    && l.keys.iter().any(|k| d.keys.binary_search(k).is_ok())
            });
            if let Some((_, l)) = later {
                let who = self
                    .conns
                    .values()
                    .find(|c| c.client == l.author)
                    .map_or_else(|| "someone else".to_owned(), |c| c.name.clone());
                return Err(format!("{who} has edited the same place since: your stroke stays (undo refused)"));
            }
        }
        let undo: Vec<OpUndo> = group.iter().filter_map(|s| self.done[s].undo.clone()).collect();
        // (A room's surfaces are scene layers, all in memory and all there: a revert of a
        // record made on them cannot fail.)
        for u in &undo {
            self.editor.revert(u.clone()).map_err(|(e, _)| format!("the undo could not be applied: {e}"))?;
        }
        if let Some(stack) = self.undoable.get_mut(&client) {
            stack.truncate(stack.len() - group.len());
        }
        Ok(Ordered { seq: self.seq + 1, author: client, number: 0, entry: Entry::Undo { of: group, undo } })
    }

    /// Puts an applied entry in the order.
    fn order(&mut self, op: Ordered) {
        self.seq = op.seq;
        let n = self.clients.entry(op.author).or_insert(0);
        *n = (*n).max(op.number);
        self.tail.push_back(op);
        while self.tail.len() > self.config.tail {
            self.tail.pop_front();
        }
        self.encoded = None;
    }
}
