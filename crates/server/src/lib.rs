//! # strata-server
//!
//! Rooms where several people sculpt one scene. Each room puts every operation its clients
//! send in one total order, refuses what is malformed or out of bounds, applies the rest to its
//! own editor (the authoritative scene), stores it durably and broadcasts it; joins get a
//! snapshot and the log's tail, reconnections resume from the last operation they saw, and a
//! digest every few operations lets a diverged client find out and ask for a snapshot.
//!
//! - [`room`]: a room's logic, free of sockets and threads.
//! - [`store`]: storage behind one trait: redb (embedded, the default) and PostgreSQL.
//! - [`server`]: WebSocket connections (tokio-tungstenite) and one thread per open room.
#![warn(missing_docs)]

pub mod room;
pub mod server;
pub mod store;

pub use room::{Room, RoomConfig};
pub use server::{Server, ServerConfig};
pub use store::{PgStorage, RedbStorage, RoomStore, Storage, StoreError, StoredRoom};
