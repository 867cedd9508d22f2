//! A WebSocket connection to a room's server on its own thread (a one-thread tokio runtime),
//! reconnecting by itself after a drop, with a growing pause (0.1 s doubling to 2 s). Each
//! connection has a number, and every message is sent on a numbered connection: nothing meant
//! for a connection that dropped reaches the next one before its hello.

use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use tokio::sync::mpsc as async_mpsc;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;

use crate::protocol::{ClientMsg, MAX_SERVER_MESSAGE, ServerMsg, decode, encode};

/// What the link reports.
#[derive(Debug)]
pub enum LinkEvent {
    /// Connection `n` is open (send the hello first).
    Connected(u64),
    /// A message arrived.
    Message(Box<ServerMsg>),
    /// The connection dropped (why); the link retries by itself.
    Disconnected(String),
}

/// Where the link is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LinkState {
    /// Trying to connect.
    Connecting,
    /// Connected.
    Connected,
    /// The last try failed (why); the next one is under way.
    Retrying(String),
}

enum Command {
    Send(u64, Vec<u8>),
    Drop,
    Shutdown,
}

/// A reconnecting WebSocket link (see the module docs).
#[derive(Debug)]
pub struct Link {
    commands: async_mpsc::UnboundedSender<Command>,
    events: mpsc::Receiver<LinkEvent>,
    state: LinkState,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Command {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Command::Send(..) => "Send",
            Command::Drop => "Drop",
            Command::Shutdown => "Shutdown",
        })
    }
}

impl Link {
    /// Opens a link to `url` (`ws://host:port`).
    pub fn open(url: &str) -> std::io::Result<Link> {
        let (commands, rx) = async_mpsc::unbounded_channel();
        let (tx, events) = mpsc::channel();
        let url = url.to_owned();
        let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
        let thread =
            std::thread::Builder::new().name("strata-link".into()).spawn(move || runtime.block_on(run(url, rx, tx)))?;
        Ok(Link { commands, events, state: LinkState::Connecting, thread: Some(thread) })
    }

    /// Sends `msg` on connection `connection` (as [`LinkEvent::Connected`] numbered it;
    /// dropped when that one has gone).
    pub fn send(&self, connection: u64, msg: &ClientMsg) {
        let _ = self.commands.send(Command::Send(connection, encode(msg)));
    }

    /// What happened since the last call.
    pub fn poll(&mut self) -> Vec<LinkEvent> {
        let events: Vec<LinkEvent> = self.events.try_iter().collect();
        events.iter().for_each(|e| self.note(e));
        events
    }

    /// Waits up to `timeout` for something to happen, then returns what did.
    pub fn wait(&mut self, timeout: Duration) -> Vec<LinkEvent> {
        let Ok(first) = self.events.recv_timeout(timeout) else { return Vec::new() };
        let mut events = vec![first];
        events.extend(self.events.try_iter());
        events.iter().for_each(|e| self.note(e));
        events
    }

    fn note(&mut self, e: &LinkEvent) {
        match e {
            LinkEvent::Connected(_) => self.state = LinkState::Connected,
            LinkEvent::Disconnected(why) => self.state = LinkState::Retrying(why.clone()),
            LinkEvent::Message(_) => {}
        }
    }

    /// Where the link is.
    pub fn state(&self) -> &LinkState {
        &self.state
    }

    /// Closes the current connection as a network failure would; the link reconnects.
    pub fn drop_connection(&self) {
        let _ = self.commands.send(Command::Drop);
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        let _ = self.commands.send(Command::Shutdown);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The link's thread: connect, pass messages both ways, retry.
async fn run(url: String, mut commands: async_mpsc::UnboundedReceiver<Command>, events: mpsc::Sender<LinkEvent>) {
    let config =
        WebSocketConfig::default().max_message_size(Some(MAX_SERVER_MESSAGE)).max_frame_size(Some(MAX_SERVER_MESSAGE));
    let mut pause = Duration::from_millis(100);
    let mut connection = 0u64;
    loop {
        let attempt = tokio::time::timeout(
            Duration::from_secs(5),
            tokio_tungstenite::connect_async_with_config(url.as_str(), Some(config), true),
        )
        .await;
        let why = match attempt {
            Err(_) => "the server did not answer within 5 s".to_owned(),
            Ok(Err(e)) => e.to_string(),
            Ok(Ok((mut ws, _))) => {
                connection += 1;
                pause = Duration::from_millis(100);
                if events.send(LinkEvent::Connected(connection)).is_err() {
                    return;
                }
                loop {
                    tokio::select! {
                        incoming = ws.next() => match incoming {
                            Some(Ok(Message::Binary(bytes))) => match decode::<ServerMsg>(&bytes, MAX_SERVER_MESSAGE) {
                                Ok(msg) => {
                                    if events.send(LinkEvent::Message(Box::new(msg))).is_err() {
                                        return;
                                    }
                                }
                                Err(e) => break format!("the server sent {e}"),
                            },
                            Some(Ok(Message::Close(_))) | None => break "the server closed the connection".to_owned(),
                            Some(Ok(_)) => {}
                            Some(Err(e)) => break e.to_string(),
                        },
                        command = commands.recv() => match command {
                            Some(Command::Send(n, bytes)) => {
                                // (The server refuses what is too large, with a reason.)
                                if n == connection
                                    && let Err(e) = ws.send(Message::Binary(bytes.into())).await
                                {
                                    break e.to_string();
                                }
                            }
                            Some(Command::Drop) => {
                                let _ = ws.close(None).await;
                                break "the connection was dropped".to_owned();
                            }
                            Some(Command::Shutdown) | None => {
                                let _ = ws.close(None).await;
                                return;
                            }
                        },
                    }
                }
            }
        };
        if events.send(LinkEvent::Disconnected(why)).is_err() {
            return;
        }
        // Wait before the next try, still obeying a shutdown.
        let wake = tokio::time::sleep(pause);
        tokio::pin!(wake);
        loop {
            tokio::select! {
                _ = &mut wake => break,
                command = commands.recv() => match command {
                    Some(Command::Shutdown) | None => return,
                    // (Nothing to send or drop between connections.)
                    Some(_) => {}
                },
            }
        }
        pause = (pause * 2).min(Duration::from_secs(2));
    }
}
