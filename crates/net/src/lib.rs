//! # strata-net
//!
//! Sculpting together. A room on a server (`strata-server`) puts every edit in one total
//! order; each client applies its own edits at once and the room's as they arrive, rebasing
//! what the room has not ordered yet, so every editor in the room converges to the room's
//! bytes.
//!
//! - [`protocol`]: the messages (serde + postcard, versioned), carried one per WebSocket
//!   binary message.
//! - The edit operation is the editor's own record ([`strata_editor::EditOp`]): a frame's
//!   dabs with the surface's transform and tool settings, replayed bit for bit.
//! - [`Replica`]: the client's state machine, free of any transport.
//! - [`validate`]: what a room accepts.
//! - [`Link`]: a WebSocket connection on its own thread that reconnects by itself, and
//!   [`Session`]: a replica over a link, polled once a frame.
#![warn(missing_docs)]

mod hash;
mod link;
pub mod protocol;
mod replica;
mod session;
mod validate;

pub use hash::state_hash;
pub use link::{Link, LinkEvent, LinkState};
pub use replica::{Event, Replica, Step};
pub use session::{Session, SessionState};
pub use validate::{Invalid, Limits, validate};
