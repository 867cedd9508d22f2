//! The wire protocol: postcard-encoded messages, one per WebSocket binary message (the
//! transport frames them; nothing here does). Every connection starts with a [`Hello`] that
//! names the protocol version; a server answers a version it does not speak with
//! [`ServerMsg::Error`] and closes.

use glam::DVec3;
use serde::{Deserialize, Serialize};
use strata_editor::{EditOp, OpUndo};

/// The protocol version this build speaks.
/// (3: tools and undo records carry masks; 4: tools carry the stamp settings.)
pub const PROTOCOL: u32 = 4;

/// The largest message a client may send after its hello (bytes); the server closes a
/// connection that sends a larger one.
pub const MAX_CLIENT_MESSAGE: usize = 1 << 20;

/// The largest hello (it may carry the scene a new room starts with: the bunny at 1,024 cells
/// a side is a 20 MB scene file).
pub const MAX_HELLO: usize = 64 << 20;

/// The largest message a server may send (a room's snapshot is the largest).
pub const MAX_SERVER_MESSAGE: usize = 1 << 30;

/// A room's total order: the sequence number of an ordered operation (the first is 1; 0 is
/// "none yet").
pub type Seq = u64;

/// A client's identity within a room, assigned by the room and kept across reconnections. It
/// is public (the others see it as the author of entries and with presence): a reconnection
/// proves it with the client's [`ResumeKey`].
pub type ClientId = u64;

/// The secret a room gives each client in its welcome, which only that client knows: a
/// reconnection that carries it goes on as the same client (its id is derived from the key by
/// the room, so knowing a public id is not enough to act as someone else).
pub type ResumeKey = [u8; 16];

/// The first message of a connection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// [`PROTOCOL`].
    pub protocol: u32,
    /// The room to join.
    pub room: String,
    /// The room's shared secret.
    pub token: String,
    /// Who is joining, as the others see it.
    pub name: String,
    /// Where a client that was in the room goes on from.
    pub resume: Option<Resume>,
    /// A scene file's bytes to start the room with, when no room of that name exists yet (the
    /// host's scene); ignored when it exists.
    pub create: Option<Vec<u8>>,
}

/// What a reconnecting client already has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Resume {
    /// The secret the room gave it with its identity.
    pub key: ResumeKey,
    /// The last operation it applied; `None` before it had the room's scene (a snapshot
    /// lost with the connection that brought it): it needs one.
    pub seq: Option<Seq>,
}

/// Messages from a client.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ClientMsg {
    /// The first message (see [`Hello`]).
    Hello(Hello),
    /// A local operation, numbered by the client from 1 without gaps.
    Submit {
        /// The client's number for it.
        number: u64,
        /// The operation.
        op: Box<EditOp>,
    },
    /// Where the client's brush is (drawn by the others; not stored).
    Presence(Presence),
    /// The client found its state diverged: it asks for a snapshot.
    Resync,
    /// Undo the client's newest stroke the room has not undone yet (refused when someone else
    /// has since edited the same chunks).
    Undo,
}

/// A brush cursor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Presence {
    /// Where the brush is (world); `None` when the pointer is off the surface.
    pub position: Option<DVec3>,
    /// Its radius (world units).
    pub radius: f64,
}

/// An entry in the room's order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ordered {
    /// Its place in the order.
    pub seq: Seq,
    /// Who made it.
    pub author: ClientId,
    /// The author's number for it (0 for an undo, which is not numbered).
    pub number: u64,
    /// What it does.
    pub entry: Entry,
}

/// What an ordered entry does.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Entry {
    /// An edit operation, replayed.
    Edit(Box<EditOp>),
    /// The undo of the author's stroke, entries `of` (newest first): the room's records of
    /// what they changed, restored in that order (no one else has edited those chunks since).
    Undo {
        /// The entries undone, newest first.
        of: Vec<Seq>,
        /// What restores each, in the same order.
        undo: Vec<OpUndo>,
    },
}

/// Messages from the server.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ServerMsg {
    /// The answer to a [`Hello`]: the client's identity, the highest of its numbers the room
    /// has ordered, and where the room is. Either the operations after the client's resume
    /// point follow, or a [`ServerMsg::Snapshot`] and the operations after it.
    Welcome {
        /// The client's identity (a new one when the room did not know the one it resumed).
        client: ClientId,
        /// The client's secret for reconnections (the one it resumed with, or a new one).
        key: ResumeKey,
        /// The highest of the client's numbers the room ordered (0: none).
        acked: u64,
        /// The room's last operation.
        seq: Seq,
        /// The people in the room.
        peers: Vec<Peer>,
    },
    /// The room's scene (a scene file's bytes) as it was after operation `seq`, which holds
    /// the client's operations up to number `acked`.
    Snapshot {
        /// The last operation it holds.
        seq: Seq,
        /// The highest of the client's numbers it holds.
        acked: u64,
        /// The scene file.
        scene: Vec<u8>,
    },
    /// The next operation in the room's order.
    Op(Ordered),
    /// The room refused the client's operation `number` (it could not be applied there): the
    /// client takes it back.
    Refused {
        /// The client's number for it.
        number: u64,
        /// Why.
        reason: String,
    },
    /// The room refused the client's undo (why: someone else edited the same place since,
    /// nothing left to undo, too old).
    UndoRefused {
        /// Why.
        reason: String,
    },
    /// A digest of the room's scene after operation `seq` (see [`crate::state_hash`]).
    Hash {
        /// The operation it follows.
        seq: Seq,
        /// The digest.
        hash: u64,
    },
    /// Someone joined, or moved their brush.
    Presence {
        /// Who.
        peer: Peer,
        /// Where their brush is.
        presence: Presence,
    },
    /// Someone left.
    Left {
        /// Who.
        client: ClientId,
    },
    /// The connection is refused or closed (the reason is for the user); nothing follows.
    Error {
        /// Why.
        reason: String,
        /// Whether connecting again may work (a room closing, a server stopping) or not (a
        /// wrong token, another protocol, a refused message).
        retry: bool,
    },
}

/// Someone in a room.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Peer {
    /// Their identity.
    pub client: ClientId,
    /// Their name.
    pub name: String,
}

/// Why a message could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    /// Larger than the protocol allows.
    #[error("a message of {size} bytes is larger than the {limit} allowed")]
    TooLarge {
        /// Its size.
        size: usize,
        /// The limit.
        limit: usize,
    },
    /// Not a message of this protocol.
    #[error("a malformed message: {0}")]
    Malformed(String),
}

/// A message's bytes.
pub fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    // Messages are plain data (no maps with non-string keys, no unsized sequences): postcard
    // cannot fail on them.
    postcard::to_allocvec(msg).expect("protocol messages always encode")
}

/// The message in `bytes`, refused above `limit` bytes or with bytes left over.
pub fn decode<'a, T: Deserialize<'a>>(bytes: &'a [u8], limit: usize) -> Result<T, DecodeError> {
    if bytes.len() > limit {
        return Err(DecodeError::TooLarge { size: bytes.len(), limit });
    }
    let (msg, rest) = postcard::take_from_bytes(bytes).map_err(|e| DecodeError::Malformed(e.to_string()))?;
    if !rest.is_empty() {
        return Err(DecodeError::Malformed(format!("{} bytes after the message", rest.len())));
    }
    Ok(msg)
}
