//! Where rooms live between server runs: behind one trait, two back-ends.
//!
//! - [`RedbStorage`] (the default): one embedded redb file holding every room's operation log
//!   and snapshot, as the terrain keeps its chunks (atomic, checksummed commits that survive
//!   `kill -9`, no server to run).
//! - [`PgStorage`]: PostgreSQL tables, for rooms that outgrow one machine: several server
//!   processes serve different rooms against one database, each room held by one process at a
//!   time through a session advisory lock (CockroachDB and YugabyteDB speak the same wire
//!   protocol; the lock is PostgreSQL's).
//!
//! A room's stored state is its token's digest, a snapshot (a scene file, the room after
//! operation `snapshot_seq`, with each client's highest ordered number) and the ordered
//! operations after it. [`RoomStore::append`] returns only once the operations are durable:
//! the server acknowledges nothing before. [`RoomStore::compact`] folds the log into a new
//! snapshot in one transaction.

use std::path::Path;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use strata_net::protocol::{ClientId, Ordered, Seq};

/// Why storage failed.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The database refused or failed.
    #[error("storage: {0}")]
    Database(String),
    /// A stored record could not be read back.
    #[error("storage holds a damaged record: {0}")]
    Damaged(String),
    /// Another server process holds the room.
    #[error("room `{0}` is served by another server process")]
    Busy(String),
}

/// A room as stored (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct StoredRoom {
    /// SHA-256 of the room's token.
    pub token_hash: [u8; 32],
    /// The last operation the snapshot holds.
    pub snapshot_seq: Seq,
    /// The scene file after it.
    pub snapshot: Vec<u8>,
    /// Each client's highest ordered number, as of the snapshot.
    pub clients: Vec<(ClientId, u64)>,
    /// The operations after the snapshot, in order.
    pub ops: Vec<Ordered>,
}

/// The snapshot row's metadata (postcard).
#[derive(Serialize, Deserialize)]
struct SnapshotMeta {
    token_hash: [u8; 32],
    snapshot_seq: Seq,
    clients: Vec<(ClientId, u64)>,
}

/// A storage back-end: opens rooms.
pub trait Storage: Send + Sync {
    /// The store of room `name` (which may not exist yet), held by this process until dropped.
    fn open(&self, name: &str) -> Result<Box<dyn RoomStore>, StoreError>;
}

/// One room's store.
pub trait RoomStore: Send {
    /// The room, or `None` when it was never created.
    fn load(&mut self) -> Result<Option<StoredRoom>, StoreError>;
    /// Creates the room with its first snapshot (operation 0).
    fn create(&mut self, token_hash: [u8; 32], snapshot: &[u8]) -> Result<(), StoreError>;
    /// Appends ordered operations, durably, in one transaction.
    fn append(&mut self, ops: &[Ordered]) -> Result<(), StoreError>;
    /// Replaces the snapshot with one after `seq` and drops the operations it holds, in one
    /// transaction.
    fn compact(&mut self, seq: Seq, snapshot: &[u8], clients: &[(ClientId, u64)]) -> Result<(), StoreError>;
}

fn dberr<E: std::fmt::Display>(e: E) -> StoreError {
    StoreError::Database(e.to_string())
}

fn encode_op(op: &Ordered) -> Vec<u8> {
    strata_net::protocol::encode(op)
}

fn decode_op(bytes: &[u8]) -> Result<Ordered, StoreError> {
    strata_net::protocol::decode(bytes, usize::MAX).map_err(|e| StoreError::Damaged(e.to_string()))
}

fn decode_meta(bytes: &[u8]) -> Result<SnapshotMeta, StoreError> {
    postcard::from_bytes(bytes).map_err(|e| StoreError::Damaged(e.to_string()))
}

// ---------------------------------------------------------------------------------------------
// redb

use redb::{Database, TableDefinition};

/// (room, seq) → an ordered operation.
const OPS: TableDefinition<(&str, u64), &[u8]> = TableDefinition::new("ops");
/// room → its snapshot's metadata.
const META: TableDefinition<&str, &[u8]> = TableDefinition::new("rooms");
/// room → its snapshot (a scene file).
const SNAPSHOTS: TableDefinition<&str, &[u8]> = TableDefinition::new("snapshots");

/// Every room in one redb file (see the module docs).
#[derive(Clone)]
pub struct RedbStorage {
    db: Arc<Database>,
    held: Arc<std::sync::Mutex<std::collections::HashSet<String>>>,
}

impl std::fmt::Debug for RedbStorage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RedbStorage").finish_non_exhaustive()
    }
}

impl RedbStorage {
    /// Opens (or creates) the file at `path`.
    pub fn open(path: &Path) -> Result<RedbStorage, StoreError> {
        let db = Database::create(path).map_err(dberr)?;
        let txn = db.begin_write().map_err(dberr)?;
        {
            txn.open_table(OPS).map_err(dberr)?;
            txn.open_table(META).map_err(dberr)?;
            txn.open_table(SNAPSHOTS).map_err(dberr)?;
        }
        txn.commit().map_err(dberr)?;
        Ok(RedbStorage { db: Arc::new(db), held: Default::default() })
    }
}

impl Storage for RedbStorage {
    fn open(&self, name: &str) -> Result<Box<dyn RoomStore>, StoreError> {
        // One file, one process: the room is held within this process.
        let mut held = self.held.lock().unwrap_or_else(|p| p.into_inner());
        if !held.insert(name.to_owned()) {
            return Err(StoreError::Busy(name.to_owned()));
        }
        Ok(Box::new(RedbRoom { storage: self.clone(), name: name.to_owned() }))
    }
}

struct RedbRoom {
    storage: RedbStorage,
    name: String,
}

impl Drop for RedbRoom {
    fn drop(&mut self) {
        self.storage.held.lock().unwrap_or_else(|p| p.into_inner()).remove(&self.name);
    }
}

impl RoomStore for RedbRoom {
    fn load(&mut self) -> Result<Option<StoredRoom>, StoreError> {
        let txn = self.storage.db.begin_read().map_err(dberr)?;
        let meta = txn.open_table(META).map_err(dberr)?;
        let Some(m) = meta.get(self.name.as_str()).map_err(dberr)? else { return Ok(None) };
        let m = decode_meta(m.value())?;
        let snapshots = txn.open_table(SNAPSHOTS).map_err(dberr)?;
        let snapshot = snapshots
            .get(self.name.as_str())
            .map_err(dberr)?
            .ok_or_else(|| StoreError::Damaged(format!("room `{}` has no snapshot", self.name)))?
            .value()
            .to_vec();
        let table = txn.open_table(OPS).map_err(dberr)?;
        let mut ops = Vec::new();
        for row in
            table.range((self.name.as_str(), m.snapshot_seq + 1)..=(self.name.as_str(), u64::MAX)).map_err(dberr)?
        {
            let (_, v) = row.map_err(dberr)?;
            ops.push(decode_op(v.value())?);
        }
        Ok(Some(StoredRoom {
            token_hash: m.token_hash,
            snapshot_seq: m.snapshot_seq,
            snapshot,
            clients: m.clients,
            ops,
        }))
    }

    fn create(&mut self, token_hash: [u8; 32], snapshot: &[u8]) -> Result<(), StoreError> {
        self.compact_with(SnapshotMeta { token_hash, snapshot_seq: 0, clients: Vec::new() }, snapshot)
    }

    fn append(&mut self, ops: &[Ordered]) -> Result<(), StoreError> {
        let txn = self.storage.db.begin_write().map_err(dberr)?;
        {
            let mut table = txn.open_table(OPS).map_err(dberr)?;
            for op in ops {
                table.insert((self.name.as_str(), op.seq), encode_op(op).as_slice()).map_err(dberr)?;
            }
        }
        // (redb's default durability: the commit is on disk when it returns.)
        txn.commit().map_err(dberr)
    }

    fn compact(&mut self, seq: Seq, snapshot: &[u8], clients: &[(ClientId, u64)]) -> Result<(), StoreError> {
        let token_hash = {
            let txn = self.storage.db.begin_read().map_err(dberr)?;
            let meta = txn.open_table(META).map_err(dberr)?;
            let m =
                meta.get(self.name.as_str()).map_err(dberr)?.ok_or_else(|| StoreError::Damaged("no room".into()))?;
            decode_meta(m.value())?.token_hash
        };
        self.compact_with(SnapshotMeta { token_hash, snapshot_seq: seq, clients: clients.to_vec() }, snapshot)
    }
}

impl RedbRoom {
    fn compact_with(&mut self, meta: SnapshotMeta, snapshot: &[u8]) -> Result<(), StoreError> {
        let name = self.name.as_str();
        let txn = self.storage.db.begin_write().map_err(dberr)?;
        {
            let bytes = postcard::to_allocvec(&meta).map_err(dberr)?;
            txn.open_table(META).map_err(dberr)?.insert(name, bytes.as_slice()).map_err(dberr)?;
            txn.open_table(SNAPSHOTS).map_err(dberr)?.insert(name, snapshot).map_err(dberr)?;
            let mut table = txn.open_table(OPS).map_err(dberr)?;
            table.retain_in((name, 0)..=(name, meta.snapshot_seq), |_, _| false).map_err(dberr)?;
        }
        txn.commit().map_err(dberr)
    }
}

// ---------------------------------------------------------------------------------------------
// PostgreSQL

/// Rooms in PostgreSQL tables (see the module docs). Each open room holds its own connection
/// and the room's advisory lock on it.
#[derive(Clone, Debug)]
pub struct PgStorage {
    url: String,
}

const PG_SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS strata_rooms (
    name TEXT PRIMARY KEY,
    token_hash BYTEA NOT NULL,
    snapshot_seq BIGINT NOT NULL,
    snapshot BYTEA NOT NULL,
    clients BYTEA NOT NULL
);
CREATE TABLE IF NOT EXISTS strata_ops (
    room TEXT NOT NULL,
    seq BIGINT NOT NULL,
    op BYTEA NOT NULL,
    PRIMARY KEY (room, seq)
);";

impl PgStorage {
    /// Connects to `url` (`postgres://user@host:port/db`) and makes the tables if missing.
    pub fn open(url: &str) -> Result<PgStorage, StoreError> {
        let mut client = postgres::Client::connect(url, postgres::NoTls).map_err(dberr)?;
        // Two servers starting at once may both create the tables: one waits for the other.
        let mut txn = client.transaction().map_err(dberr)?;
        txn.execute("SELECT pg_advisory_xact_lock(7142)", &[]).map_err(dberr)?;
        txn.batch_execute(PG_SCHEMA).map_err(dberr)?;
        txn.commit().map_err(dberr)?;
        Ok(PgStorage { url: url.to_owned() })
    }
}

impl Storage for PgStorage {
    fn open(&self, name: &str) -> Result<Box<dyn RoomStore>, StoreError> {
        let mut client = postgres::Client::connect(&self.url, postgres::NoTls).map_err(dberr)?;
        // A 64-bit key from the name's SHA-256: two rooms never share a lock in practice (a
        // 32-bit hash would make collisions likely past tens of thousands of rooms).
        let digest = <sha2::Sha256 as sha2::Digest>::digest(name.as_bytes());
        let key = i64::from_le_bytes(digest[..8].try_into().expect("8 bytes"));
        let row = client.query_one("SELECT pg_try_advisory_lock($1)", &[&key]).map_err(dberr)?;
        if !row.get::<_, bool>(0) {
            return Err(StoreError::Busy(name.to_owned()));
        }
        Ok(Box::new(PgRoom { client, name: name.to_owned() }))
    }
}

struct PgRoom {
    client: postgres::Client,
    name: String,
}

fn to_i64(v: u64) -> Result<i64, StoreError> {
    i64::try_from(v).map_err(|_| StoreError::Database(format!("sequence {v} beyond PostgreSQL's bigint")))
}

impl RoomStore for PgRoom {
    fn load(&mut self) -> Result<Option<StoredRoom>, StoreError> {
        let mut txn = self.client.build_transaction().read_only(true).start().map_err(dberr)?;
        let Some(row) = txn
            .query_opt(
                "SELECT token_hash, snapshot_seq, snapshot, clients FROM strata_rooms WHERE name = $1",
                &[&self.name],
            )
            .map_err(dberr)?
        else {
            return Ok(None);
        };
        let token: Vec<u8> = row.get(0);
        let token_hash: [u8; 32] =
            token.try_into().map_err(|_| StoreError::Damaged("a token digest that is not 32 bytes".into()))?;
        let snapshot_seq: i64 = row.get(1);
        let snapshot: Vec<u8> = row.get(2);
        let clients: Vec<u8> = row.get(3);
        let clients: Vec<(ClientId, u64)> =
            postcard::from_bytes(&clients).map_err(|e| StoreError::Damaged(e.to_string()))?;
        let mut ops = Vec::new();
        for r in txn
            .query("SELECT op FROM strata_ops WHERE room = $1 AND seq > $2 ORDER BY seq", &[&self.name, &snapshot_seq])
            .map_err(dberr)?
        {
            ops.push(decode_op(r.get::<_, &[u8]>(0))?);
        }
        txn.commit().map_err(dberr)?;
        Ok(Some(StoredRoom { token_hash, snapshot_seq: snapshot_seq as u64, snapshot, clients, ops }))
    }

    fn create(&mut self, token_hash: [u8; 32], snapshot: &[u8]) -> Result<(), StoreError> {
        let clients = postcard::to_allocvec(&Vec::<(ClientId, u64)>::new()).map_err(dberr)?;
        self.client
            .execute(
                "INSERT INTO strata_rooms (name, token_hash, snapshot_seq, snapshot, clients) VALUES ($1, $2, 0, $3, $4)",
                &[&self.name, &token_hash.as_slice(), &snapshot, &clients],
            )
            .map_err(dberr)?;
        Ok(())
    }

    fn append(&mut self, ops: &[Ordered]) -> Result<(), StoreError> {
        let mut txn = self.client.transaction().map_err(dberr)?;
        let insert = txn.prepare("INSERT INTO strata_ops (room, seq, op) VALUES ($1, $2, $3)").map_err(dberr)?;
        for op in ops {
            txn.execute(&insert, &[&self.name, &to_i64(op.seq)?, &encode_op(op)]).map_err(dberr)?;
        }
        // (synchronous_commit is on by default: the commit is on disk when it returns.)
        txn.commit().map_err(dberr)
    }

    fn compact(&mut self, seq: Seq, snapshot: &[u8], clients: &[(ClientId, u64)]) -> Result<(), StoreError> {
        let seq = to_i64(seq)?;
        let clients = postcard::to_allocvec(clients).map_err(dberr)?;
        let mut txn = self.client.transaction().map_err(dberr)?;
        txn.execute(
            "UPDATE strata_rooms SET snapshot_seq = $2, snapshot = $3, clients = $4 WHERE name = $1",
            &[&self.name, &seq, &snapshot, &clients],
        )
        .map_err(dberr)?;
        txn.execute("DELETE FROM strata_ops WHERE room = $1 AND seq <= $2", &[&self.name, &seq]).map_err(dberr)?;
        txn.commit().map_err(dberr)
    }
}
