//! A replica over a link: what the studio (and the tests) hold while in a room. Poll it once a
//! frame after the editor's frame; it sends the hello on every new connection, resumes where
//! the replica is, keeps the people in the room and their brushes, and reconnects by itself.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use glam::DVec3;
use strata_editor::{Editor, Scene};

use crate::link::{Link, LinkEvent, LinkState};
use crate::protocol::{ClientId, ClientMsg, Presence};
use crate::replica::{Event, Replica};

/// Where a session is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SessionState {
    /// Connecting (or reconnecting) to the server.
    Connecting,
    /// Connected; waiting for the room's welcome.
    Joining,
    /// In the room.
    InRoom,
    /// The connection dropped (why); reconnecting.
    Retrying(String),
    /// The room refused us (a wrong token, no such room, another protocol): no more tries.
    Refused(String),
}

/// A hello the room has not answered in this long is given up: the connection is dropped and
/// made again (an answer lost on the server's side must not leave a session joining forever).
pub const HELLO_ANSWER_TIMEOUT: Duration = Duration::from_secs(10);

/// Presence is sent at most this often.
const PRESENCE_INTERVAL: Duration = Duration::from_millis(33);

/// A replica of a room over a reconnecting link (see the module docs).
#[derive(Debug)]
pub struct Session {
    link: Option<Link>,
    replica: Replica,
    room: String,
    token: String,
    name: String,
    create: Option<Vec<u8>>,
    state: SessionState,
    /// The connection messages go on (0: none).
    connection: u64,
    peers: BTreeMap<ClientId, (String, Presence)>,
    last_presence: Option<Instant>,
    /// How many times the room welcomed us.
    welcomes: u64,
    /// When the hello of the current connection was sent, until the room answers it.
    hello_sent: Option<Instant>,
    /// See [`HELLO_ANSWER_TIMEOUT`].
    hello_timeout: Duration,
}

impl Session {
    /// Joins room `room` on the server at `url` (`ws://host:port`) with its token, as `name`.
    pub fn join(url: &str, room: &str, token: &str, name: &str) -> std::io::Result<Session> {
        Ok(Session {
            link: Some(Link::open(url)?),
            replica: Replica::new(),
            room: room.to_owned(),
            token: token.to_owned(),
            name: name.to_owned(),
            create: None,
            state: SessionState::Connecting,
            connection: 0,
            peers: BTreeMap::new(),
            last_presence: None,
            welcomes: 0,
            hello_sent: None,
            hello_timeout: HELLO_ANSWER_TIMEOUT,
        })
    }

    /// Joins room `room`, creating it with `scene` when the server has no room of that name:
    /// how a session is hosted.
    pub fn host(url: &str, room: &str, token: &str, name: &str, scene: &Scene) -> Result<Session, String> {
        let bytes = strata_editor::file::encode_shared(scene).map_err(|e| e.to_string())?;
        Session::host_snapshot(url, room, token, name, bytes)
    }

    /// [`Session::host`] with the room's content as a snapshot ([`strata_editor::room::encode`]:
    /// a scene, or a world).
    pub fn host_snapshot(url: &str, room: &str, token: &str, name: &str, snapshot: Vec<u8>) -> Result<Session, String> {
        let mut s = Session::join(url, room, token, name).map_err(|e| e.to_string())?;
        s.create = Some(snapshot);
        Ok(s)
    }

    /// Applies what arrived to `editor` and sends its new operations (it records them from
    /// now on; see [`Editor::record_ops`]); returns what happened.
    pub fn poll(&mut self, editor: &mut Editor) -> Vec<Event> {
        let events = self.link.as_mut().map(Link::poll).unwrap_or_default();
        self.handle(editor, events)
    }

    /// As [`Session::poll`], after waiting up to `timeout` for something to arrive.
    pub fn wait(&mut self, editor: &mut Editor, timeout: Duration) -> Vec<Event> {
        let events = self.link.as_mut().map(|l| l.wait(timeout)).unwrap_or_default();
        self.handle(editor, events)
    }

    fn handle(&mut self, editor: &mut Editor, events: Vec<LinkEvent>) -> Vec<Event> {
        if !editor.records_ops() {
            editor.record_ops(true);
            // Local undo records would restore chunks others have changed since.
            editor.clear_history();
        }
        let mut out = Vec::new();
        let mut incoming = Vec::new();
        for e in events {
            if self.link.is_none() {
                // Refused: whatever the link said after (a reconnection) is moot.
                break;
            }
            match e {
                LinkEvent::Message(m) => incoming.push(*m),
                LinkEvent::Connected(n) => {
                    // (What came on the last connection is applied first.)
                    out.extend(self.flush(editor, std::mem::take(&mut incoming)));
                    self.connection = n;
                    let hello = self.replica.hello(&self.room, &self.token, &self.name, self.create.clone());
                    self.send(&hello);
                    self.state = SessionState::Joining;
                    self.hello_sent = Some(Instant::now());
                }
                LinkEvent::Disconnected(why) => {
                    // Nothing more goes on the connection that dropped (what its messages
                    // ask for is asked again after the next hello).
                    self.connection = 0;
                    self.replica.disconnected();
                    out.extend(self.flush(editor, std::mem::take(&mut incoming)));
                    if self.link.is_some() {
                        self.state = SessionState::Retrying(why);
                    }
                }
            }
        }
        out.extend(self.flush(editor, incoming));
        if self.state != SessionState::Joining {
            self.hello_sent = None;
        } else if self.hello_sent.is_some_and(|t| t.elapsed() > self.hello_timeout) {
            self.hello_sent = None;
            self.drop_connection();
        }
        out
    }

    /// Sets how long a hello may wait for the room's answer (see [`HELLO_ANSWER_TIMEOUT`]).
    pub fn set_hello_timeout(&mut self, timeout: Duration) {
        self.hello_timeout = timeout;
    }

    /// One replica step over `incoming`, its messages sent.
    fn flush(&mut self, editor: &mut Editor, incoming: Vec<crate::protocol::ServerMsg>) -> Vec<Event> {
        let step = self.replica.step(editor, incoming);
        for msg in &step.send {
            self.send(msg);
        }
        self.note(step.events)
    }

    fn note(&mut self, events: Vec<Event>) -> Vec<Event> {
        for e in &events {
            match e {
                Event::Joined { .. } => {
                    self.state = SessionState::InRoom;
                    self.welcomes += 1;
                }
                Event::Presence(peer, presence) => {
                    self.peers.insert(peer.client, (peer.name.clone(), *presence));
                }
                Event::Left(client) => {
                    self.peers.remove(client);
                }
                Event::Closed { reason, retry: false } if self.state == SessionState::Joining => {
                    // Refused at the door: trying again would be refused again.
                    self.state = SessionState::Refused(reason.clone());
                    self.link = None;
                }
                _ => {}
            }
        }
        events
    }

    fn send(&self, msg: &ClientMsg) {
        if let Some(l) = &self.link
            && self.connection != 0
        {
            l.send(self.connection, msg);
        }
    }

    /// Tells the room where our brush is (at most 30 times a second; calls in between are
    /// dropped).
    pub fn presence(&mut self, position: Option<DVec3>, radius: f64) {
        if self.state != SessionState::InRoom || self.last_presence.is_some_and(|t| t.elapsed() < PRESENCE_INTERVAL) {
            return;
        }
        self.last_presence = Some(Instant::now());
        self.send(&ClientMsg::Presence(Presence { position, radius }));
    }

    /// Asks the room to undo our newest operation it has not undone; the answer comes as
    /// [`Event::Undone`] or [`Event::UndoRefused`]. Refused at once (with why) when not in
    /// the room.
    /// (`editor`'s new operations are sent first: the undo is for the newest.)
    pub fn undo(&mut self, editor: &mut Editor) -> Result<Vec<Event>, String> {
        if self.state != SessionState::InRoom {
            return Err("not in the room: nothing can be undone until the connection is back".into());
        }
        let events = self.handle(editor, Vec::new());
        self.send(&ClientMsg::Undo);
        Ok(events)
    }

    /// How many times the room has welcomed this session: 1 once in, one more for each
    /// reconnection.
    pub fn welcomes(&self) -> u64 {
        self.welcomes
    }

    /// Redoes our stroke the room undid last (see [`Replica::redo`]) and sends it at once;
    /// returns what happened meanwhile, and whether the redo was made (or why not).
    pub fn redo(&mut self, editor: &mut Editor) -> (Vec<Event>, Result<(), String>) {
        if self.state != SessionState::InRoom {
            return (Vec::new(), Err("not in the room: nothing can be redone until the connection is back".into()));
        }
        // (What the editor made before is taken first: new work forgets what could be redone.)
        let mut events = self.handle(editor, Vec::new());
        let done = self.replica.redo(editor);
        if done.is_ok() {
            events.extend(self.handle(editor, Vec::new()));
        }
        (events, done)
    }

    /// Where the session is.
    pub fn state(&self) -> &SessionState {
        &self.state
    }

    /// Where the link is (`None` once the room refused us).
    pub fn link_state(&self) -> Option<&LinkState> {
        self.link.as_ref().map(Link::state)
    }

    /// The others in the room: name and brush.
    pub fn peers(&self) -> impl Iterator<Item = (ClientId, &str, &Presence)> {
        self.peers.iter().filter(|(c, _)| Some(**c) != self.replica.client()).map(|(c, (n, p))| (*c, n.as_str(), p))
    }

    /// How a world that arrives from the room streams here (see [`Replica::set_world_settings`]).
    pub fn set_world_settings(&mut self, settings: strata_terrain::WorldSettings) {
        self.replica.set_world_settings(settings);
    }

    /// The replica (sequence, pending work).
    pub fn replica(&self) -> &Replica {
        &self.replica
    }

    /// The room's name.
    pub fn room(&self) -> &str {
        &self.room
    }

    /// Drops the connection as a network failure would (the session reconnects and resumes).
    pub fn drop_connection(&self) {
        if let Some(l) = &self.link {
            l.drop_connection();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::ServerMsg;

    fn error(retry: bool) -> LinkEvent {
        LinkEvent::Message(Box::new(ServerMsg::Error { reason: "no".into(), retry }))
    }

    /// A session that nothing polled for a while gets its refusal and the link's next
    /// connection in one batch: the refusal stands (it once went back to joining, with no link
    /// left to join on, for good).
    #[test]
    fn a_refusal_is_not_undone_by_a_reconnection_in_the_same_batch() {
        let mut editor = Editor::default();
        // (Nothing listens there: the link's own tries fail quietly.)
        let mut s = Session::join("ws://127.0.0.1:9", "room", "token", "me").unwrap();
        let batch = vec![
            LinkEvent::Connected(1),
            error(false),
            LinkEvent::Disconnected("gone".into()),
            LinkEvent::Connected(2),
        ];
        s.handle(&mut editor, batch);
        assert_eq!(*s.state(), SessionState::Refused("no".into()));
        assert!(s.link_state().is_none());
    }

    /// An error worth retrying leaves the session trying: the next connection says hello.
    #[test]
    fn an_error_worth_retrying_goes_on_to_the_next_connection() {
        let mut editor = Editor::default();
        let mut s = Session::join("ws://127.0.0.1:9", "room", "token", "me").unwrap();
        let batch = vec![LinkEvent::Connected(1), error(true), LinkEvent::Disconnected("gone".into())];
        s.handle(&mut editor, batch);
        assert_eq!(*s.state(), SessionState::Retrying("gone".into()));
        s.handle(&mut editor, vec![LinkEvent::Connected(2)]);
        assert_eq!(*s.state(), SessionState::Joining);
        assert_eq!(s.connection, 2);
    }
}
