//! Sculpting together from the studio: hosting a room (a server in this process, its log in a
//! file of its own), joining one, the frame's poll that sends our strokes and brush and applies
//! everyone's, undo through the room, and leaving.

use std::path::PathBuf;
use std::sync::Arc;

use strata_net::{Event, Session, SessionState};
use strata_server::{RedbStorage, Server, ServerConfig};

use super::*;

/// What a Host or Join dialog asks for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SessionParams {
    /// Hosting: where the server listens (`0.0.0.0:7878` for the network, `127.0.0.1:0` for a
    /// free port on this machine only). Joining: the server (`ws://host:7878` or `host:7878`).
    pub address: String,
    /// The room's name.
    pub room: String,
    /// The room's token: the shared secret everyone in the room types.
    pub token: String,
    /// The name the others see.
    pub name: String,
}

impl SessionParams {
    /// The parameters the dialogs start with: the default port, the room `sculpt`, a fresh
    /// random token and the user's login name.
    pub fn suggested(host: bool) -> SessionParams {
        let name = std::env::var("USER").or_else(|_| std::env::var("USERNAME")).unwrap_or_else(|_| "Sculptor".into());
        SessionParams {
            address: if host { "0.0.0.0:7878".into() } else { "ws://127.0.0.1:7878".into() },
            room: "sculpt".into(),
            token: if host { fresh_token() } else { String::new() },
            name,
        }
    }

    /// Says what is missing or malformed, or gives the fields trimmed.
    fn checked(&self) -> Result<SessionParams, String> {
        let p = SessionParams {
            address: self.address.trim().to_owned(),
            room: self.room.trim().to_owned(),
            token: self.token.trim().to_owned(),
            name: self.name.trim().to_owned(),
        };
        for (value, what) in [(&p.address, "an address"), (&p.room, "a room name"), (&p.token, "the room's token")] {
            if value.is_empty() {
                return Err(format!("Type {what} first"));
            }
        }
        if p.name.is_empty() {
            return Err("Type the name the others will see first".into());
        }
        if p.name.chars().count() > 64 || p.room.chars().count() > 128 {
            return Err("Room names are at most 128 characters and people's names at most 64".into());
        }
        Ok(p)
    }
}

/// A token hard to guess: 64 bits from the clock, the process and the standard library's
/// randomly keyed hasher, in hexadecimal.
fn fresh_token() -> String {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u128(std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos()));
    h.write_u32(std::process::id());
    format!("{:016x}", h.finish())
}

/// `ws://` in front of an address typed without a scheme.
fn ws_url(address: &str) -> String {
    if address.contains("://") { address.to_owned() } else { format!("ws://{address}") }
}

/// The studio's part in a room.
#[derive(Debug)]
pub struct Collab {
    /// The replica over its link.
    pub session: Session,
    /// The server, when this studio hosts the room (dropping it ends the room).
    server: Option<Server>,
    /// The host's room log, removed when the session ends.
    store: Option<PathBuf>,
    /// What the session was started with.
    pub params: SessionParams,
    /// The address the others join (ws://…).
    pub share: String,
    /// The state last reported.
    said: SessionState,
    /// Whether the view was set from the room's scene (a joiner's first snapshot).
    framed: bool,
}

impl Collab {
    /// Whether this studio hosts the room.
    pub fn hosting(&self) -> bool {
        self.server.is_some()
    }

    /// The session's state in words, for the status bar and the people panel.
    pub fn state_text(&self) -> String {
        match self.session.state() {
            SessionState::Connecting => format!("connecting to {}…", self.share),
            SessionState::Joining => "joining…".into(),
            SessionState::InRoom if !self.session.replica().has_scene() => "receiving the scene…".into(),
            SessionState::InRoom => "connected".into(),
            SessionState::Retrying(why) => format!("connection lost ({why}): reconnecting…"),
            SessionState::Refused(why) => format!("refused: {why}"),
        }
    }
}

impl Drop for Collab {
    fn drop(&mut self) {
        // The server holds the log open: it stops first.
        self.server.take();
        if let Some(path) = self.store.take() {
            let _ = std::fs::remove_file(path);
        }
    }
}

impl Studio {
    /// Whether the studio is in a room (or trying to be).
    pub fn in_session(&self) -> bool {
        self.collab.is_some()
    }

    /// Refuses `what` (a change to the scene's structure: its layers, palette or file) while in
    /// a room, whose operations are strokes on the layers everyone has.
    pub fn refuse_in_session(&self, what: &str) -> Result<(), String> {
        match &self.collab {
            Some(c) => Err(format!("In the shared room {:?}: File > Leave session first, then {what}", c.params.room)),
            None => Ok(()),
        }
    }

    /// Hosts a room on this machine: a server listening on `params.address` with the room's
    /// log in a file of its own, the room created with the scene as it is now, and this
    /// studio in it.
    pub(super) fn host_session(&mut self, params: SessionParams) -> Result<(), String> {
        self.ready_for_session()?;
        let p = params.checked()?;
        self.share_world_at_one_level()?;
        self.editor.end_stroke();
        let camera = self.camera;
        self.editor.scene.view = strata_viewport::view_of(&camera);
        let snapshot = strata_editor::room::encode(&self.editor).map_err(|e| format!("Could not share: {e}"))?;
        let store = std::env::temp_dir().join(format!("strata-host-{}-{}.redb", std::process::id(), fresh_token()));
        let storage = RedbStorage::open(&store).map_err(|e| format!("Could not keep the room's log: {e}"))?;
        let server = Server::start(&p.address, Arc::new(storage), ServerConfig::default()).map_err(|e| {
            let _ = std::fs::remove_file(&store);
            format!("Could not listen on {}: {e}", p.address)
        })?;
        let addr = server.addr();
        // This studio reaches its own server on the loopback when it listens everywhere.
        let local = if addr.ip().is_unspecified() {
            std::net::SocketAddr::new(std::net::Ipv4Addr::LOCALHOST.into(), addr.port())
        } else {
            addr
        };
        let share = if addr.ip().is_unspecified() {
            match network_address() {
                Some(ip) => format!("ws://{}", std::net::SocketAddr::new(ip, addr.port())),
                None => format!("ws://<this machine's address>:{}", addr.port()),
            }
        } else {
            server.url()
        };
        let session = match Session::host_snapshot(&format!("ws://{local}"), &p.room, &p.token, &p.name, snapshot) {
            Ok(s) => s,
            Err(e) => {
                // (The server holds the log open: it stops first.)
                drop(server);
                let _ = std::fs::remove_file(&store);
                return Err(format!("Could not start the session: {e}"));
            }
        };
        self.message = format!("Hosting room {:?} at {share}: the others join with its token", p.room);
        self.collab = Some(Collab {
            session,
            server: Some(server),
            store: Some(store),
            params: p,
            share,
            said: SessionState::Connecting,
            framed: true,
        });
        Ok(())
    }

    /// Joins a room: the scene becomes the room's once it arrives (the caller has asked about
    /// unsaved changes).
    pub(super) fn join_session(&mut self, params: SessionParams) -> Result<(), String> {
        self.refuse_in_world("join a session")?;
        self.ready_for_session()?;
        let p = params.checked()?;
        let url = ws_url(&p.address);
        let mut session =
            Session::join(&url, &p.room, &p.token, &p.name).map_err(|e| format!("Could not start the session: {e}"))?;
        // (A room may hold a world: it streams here as the studio's worlds do.)
        session.set_world_settings(self.world_settings.clone());
        self.editor.end_stroke();
        self.message = format!("Joining room {:?} at {url}…", p.room);
        self.collab = Some(Collab {
            session,
            server: None,
            store: None,
            params: p,
            share: url,
            said: SessionState::Connecting,
            framed: false,
        });
        Ok(())
    }

    /// A world is shared with every chunk at the base level (see [`strata_editor::room`]): an
    /// open world that makes finer chunks near the viewer is written and opened again so.
    fn share_world_at_one_level(&mut self) -> Result<(), String> {
        if self.editor.world().is_none_or(strata_editor::room::is_shareable) {
            return Ok(());
        }
        let path = self.world_path.clone().ok_or("The open world has no file to share from")?;
        self.leave_world()?;
        let settings = strata_editor::room::shared_world_settings(self.world_settings.clone());
        let materials = self.scene_editor().scene.materials.clone();
        let (mode, editor) = crate::terrain::TerrainMode::open(&path, settings, materials)
            .map_err(|e| format!("Could not open the world {} again to share it: {e}", path.display()))?;
        self.enter_world(mode, editor)?;
        self.world_path = Some(path);
        Ok(())
    }

    /// Terrain mode follows what the room holds: a world that arrived in a snapshot is flown
    /// through; a scene that replaced a world goes back to scene mode.
    fn follow_room_content(&mut self) {
        match (self.editor.world(), self.terrain.is_some()) {
            (Some(world), false) => {
                let mode = crate::terrain::TerrainMode::viewing(world);
                self.camera = mode.camera();
                self.terrain = Some(mode);
                self.world_path = None;
                self.editor.tool.kind = ToolKind::Erase;
                self.editor.tool.radius = crate::terrain::WORLD_BRUSH_RADIUS;
                self.line_mode = false;
                self.line_start = None;
                self.editor.redraw_all();
                self.message = "The room holds a world: fly with WASD, dig with the left button".into();
            }
            (None, true) => {
                self.terrain = None;
                self.world_path = None;
                self.camera = strata_viewport::camera_of(&self.editor.scene.view);
                self.editor.redraw_all();
            }
            _ => {}
        }
    }

    /// Nothing may be running that a session would miss.
    fn ready_for_session(&self) -> Result<(), String> {
        if self.collab.is_some() {
            return Err("Already in a session: File > Leave session first".into());
        }
        if self.busy() {
            return Err("Wait for the large dab or the import to finish".into());
        }
        Ok(())
    }

    /// Leaves the room (ending it for everyone when this studio hosts it); the scene stays
    /// here as it is, with a fresh local history.
    pub(super) fn leave_session(&mut self) -> Result<(), String> {
        let Some(mut c) = self.collab.take() else { return Err("Not in a session".into()) };
        // What was sculpted since the last frame goes out first.
        c.session.poll(&mut self.editor);
        // Operations the room has not confirmed may not have reached it (a connection down, a
        // room that had no time to answer): wait a moment for them, then say what stays here.
        let until = std::time::Instant::now() + std::time::Duration::from_millis(500);
        while c.session.replica().pending() > 0 && *c.session.state() == SessionState::InRoom {
            let left = until.saturating_duration_since(std::time::Instant::now());
            if left.is_zero() {
                break;
            }
            c.session.wait(&mut self.editor, left);
        }
        let unsent = c.session.replica().pending();
        self.editor.record_ops(false);
        self.editor.clear_history();
        let hosting = c.hosting();
        let room = c.params.room.clone();
        drop(c);
        self.message = if hosting {
            format!("Room {room:?} closed: the scene stays here")
        } else {
            format!("Left room {room:?}: the scene stays here")
        };
        if unsent > 0 {
            self.fail(format!(
                "Left room {room:?} with {unsent} operations the room had not confirmed: they stay in this scene but may be missing from the room's"
            ));
        }
        Ok(())
    }

    /// Undo in a room: asks the room to undo our newest stroke (the answer arrives in a later
    /// poll).
    pub(super) fn undo_in_session(&mut self) -> Result<(), String> {
        let Some(c) = self.collab.as_mut() else { return Ok(()) };
        self.editor.end_stroke();
        let events = c.session.undo(&mut self.editor).map_err(|e| format!("Could not undo: {e}"))?;
        self.message = "Asked the room to undo your last stroke…".into();
        self.session_events(events);
        Ok(())
    }

    /// Redo in a room: makes our stroke the room undid last again, as a new stroke.
    pub(super) fn redo_in_session(&mut self) -> Result<(), String> {
        let Some(c) = self.collab.as_mut() else { return Ok(()) };
        if !c.session.replica().can_redo() {
            self.message = "Nothing to redo".into();
            return Ok(());
        }
        let (events, done) = c.session.redo(&mut self.editor);
        self.session_events(events);
        done.map_err(|e| format!("Could not redo: {e}"))?;
        self.message = "Redone (sent to the room)".into();
        Ok(())
    }

    /// One frame of the session (call every frame, after the pointer): sends our new strokes
    /// and where our brush is, applies what the room sent, and reports what happened. Returns
    /// whether the session is live (the caller keeps frames coming while it is).
    pub fn poll_session(&mut self) -> bool {
        let Some(c) = self.collab.as_mut() else { return false };
        let events = c.session.poll(&mut self.editor);
        c.session.presence(self.hover, self.editor.tool.radius);
        self.session_events(events);
        let Some(c) = self.collab.as_mut() else { return false };
        let state = c.session.state().clone();
        if state != c.said {
            c.said = state.clone();
            match state {
                SessionState::InRoom => {
                    self.message = format!("In room {:?} at {} as {:?}", c.params.room, c.share, c.params.name)
                }
                SessionState::Retrying(_) => self.message = format!("Room {:?}: {}", c.params.room, c.state_text()),
                SessionState::Refused(why) => {
                    let room = c.params.room.clone();
                    self.collab = None;
                    self.editor.record_ops(false);
                    self.fail(format!("Could not join room {room:?}: {why}"));
                    return false;
                }
                SessionState::Connecting | SessionState::Joining => {}
            }
        }
        true
    }

    /// Says what the room's events mean to the user (errors in a notice).
    fn session_events(&mut self, events: Vec<Event>) {
        for e in events {
            match e {
                Event::Snapshot => {
                    self.follow_room_content();
                    let Some(c) = self.collab.as_mut() else { continue };
                    if !c.framed {
                        // A joiner looks at the room's scene as its host saved the view.
                        c.framed = true;
                        if self.terrain.is_none() {
                            self.camera = strata_viewport::camera_of(&self.editor.scene.view);
                        }
                        // The scene is the room's from now on, in no file of this machine's.
                        self.path = None;
                        self.message = format!("Received room {:?}'s scene", c.params.room);
                    }
                    self.line_start = None;
                    self.editor.redraw_all();
                }
                Event::Refused(why) => self.fail(format!("The room refused a stroke (taken back here): {why}")),
                Event::UndoRefused(why) => self.fail(format!("Could not undo: {why}")),
                Event::Undone => self.message = "Undone in the room".into(),
                Event::Diverged => self.message = "Out of step with the room: fetching its scene".into(),
                Event::OutOfStep(why) => {
                    self.message = format!("Out of step with the room ({why}): fetching its scene")
                }
                Event::Closed { reason, retry: true } => {
                    self.message = format!("The room closed the connection: {reason}")
                }
                Event::Closed { reason, retry: false } => {
                    // (A refusal at the door is said once, as the session ends.)
                    if !matches!(self.collab.as_ref().map(|c| c.session.state()), Some(SessionState::Refused(_))) {
                        self.fail(format!("The room closed the connection: {reason}"));
                    }
                }
                Event::Joined { .. } | Event::Applied { .. } | Event::Presence(..) | Event::Left(_) => {}
            }
        }
    }
}

/// This machine's address on its network (the one its default route leaves from), for the
/// address the host shares; `None` without a network. (Connecting a UDP socket sends nothing.)
fn network_address() -> Option<std::net::IpAddr> {
    let socket = std::net::UdpSocket::bind("0.0.0.0:0").ok()?;
    socket.connect("192.0.2.1:7878").ok()?;
    let ip = socket.local_addr().ok()?.ip();
    (!ip.is_unspecified() && !ip.is_loopback()).then_some(ip)
}
