//! A world on disk: the recipe plus the chunks that differ from what the recipe generates, in
//! an embedded transactional database ([`redb`]).
//!
//! Why redb and not SQLite: both give atomic, durable commits that survive `kill -9` (see
//! docs/BENCHMARKS.md, Table 9, for both measured on this workload). redb is pure Rust (no C
//! toolchain for a `-sys` crate, nothing to link), typed keys (`(i32, i32, i32)` chunk keys sort
//! as tuples) and its copy-on-write B-tree with checksummed commits needs no journal files next
//! to the world. Every [`WorldStore::write`] is one write transaction: after a crash, each chunk
//! is either its old or its new version, never a mixture.
//!
//! A chunk record is `crc32 (4 bytes LE) ‖ postcard(StoredChunk)`; the checksum catches a
//! record damaged on disk that the database's own page checksums let through (or a record
//! written by a broken program), and the chunk's deserialisation checks its structure.

use std::path::{Path, PathBuf};

use redb::{Database, ReadableTable, ReadableTableMetadata, TableDefinition};
use serde::{Deserialize, Serialize};
use strata_volume::{Chunk, ChunkKey, ChunkMaterials};
use thiserror::Error;

use crate::recipe::{Recipe, RecipeError};

const CHUNKS: TableDefinition<(i32, i32, i32), &[u8]> = TableDefinition::new("chunks");
const META: TableDefinition<&str, &[u8]> = TableDefinition::new("meta");

/// The world format this code writes.
pub const WORLD_FORMAT: u32 = 1;

/// Why a world could not be opened, read or written.
#[derive(Debug, Error)]
pub enum StoreError {
    /// The database layer refused (an unreadable or corrupt file, a full disk, a world opened by
    /// another program).
    #[error("world database {path}: {message}")]
    Database {
        /// The world file.
        path: PathBuf,
        /// What the database said.
        message: String,
    },
    /// The file is a database but not a Strata world, or of a newer format.
    #[error("{path} is not a Strata world: {why}")]
    NotAWorld {
        /// The world file.
        path: PathBuf,
        /// Why.
        why: String,
    },
    /// The world's recipe is unreadable or invalid.
    #[error("the recipe stored in {path}: {error}")]
    Recipe {
        /// The world file.
        path: PathBuf,
        /// The recipe's error.
        error: RecipeError,
    },
    /// A stored chunk is damaged.
    #[error("chunk {key:?} in {path} is damaged: {why}")]
    Chunk {
        /// The world file.
        path: PathBuf,
        /// The chunk.
        key: [i32; 3],
        /// What is wrong.
        why: String,
    },
}

/// One chunk as stored.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StoredChunk {
    /// The chunk's lists (`None`: all empty).
    pub chunk: Option<Chunk>,
    /// Its materials (`None`: material 0).
    pub materials: Option<ChunkMaterials>,
}

/// Encodes a record: checksum, then the chunk.
pub fn encode_record(stored: &StoredChunk) -> Vec<u8> {
    let body = postcard::to_allocvec(stored).expect("chunks serialise");
    let mut out = Vec::with_capacity(body.len() + 4);
    out.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
    out.extend_from_slice(&body);
    out
}

/// Decodes a record written by [`encode_record`].
pub fn decode_record(bytes: &[u8]) -> Result<StoredChunk, String> {
    if bytes.len() < 4 {
        return Err(format!("a record of {} bytes is shorter than its checksum", bytes.len()));
    }
    let (sum, body) = bytes.split_at(4);
    let want = u32::from_le_bytes(sum.try_into().expect("four bytes"));
    if crc32fast::hash(body) != want {
        return Err("checksum mismatch".into());
    }
    let (stored, rest): (StoredChunk, &[u8]) = postcard::take_from_bytes(body).map_err(|e| e.to_string())?;
    if !rest.is_empty() {
        return Err(format!("{} bytes after the chunk", rest.len()));
    }
    Ok(stored)
}

/// An open world file.
#[derive(Debug)]
pub struct WorldStore {
    db: Database,
    path: PathBuf,
    recipe: Recipe,
}

fn key_tuple(k: ChunkKey) -> (i32, i32, i32) {
    (k.0.x, k.0.y, k.0.z)
}

impl WorldStore {
    fn db_error(path: &Path, e: impl std::fmt::Display) -> StoreError {
        StoreError::Database { path: path.to_path_buf(), message: e.to_string() }
    }

    /// Creates a new world at `path` from `recipe` (a file already there is refused).
    pub fn create(path: &Path, recipe: &Recipe) -> Result<Self, StoreError> {
        recipe.validate().map_err(|error| StoreError::Recipe { path: path.to_path_buf(), error })?;
        if path.exists() {
            return Err(StoreError::NotAWorld { path: path.to_path_buf(), why: "a file is already there".into() });
        }
        let db = Database::create(path).map_err(|e| Self::db_error(path, e))?;
        let txn = db.begin_write().map_err(|e| Self::db_error(path, e))?;
        {
            let mut meta = txn.open_table(META).map_err(|e| Self::db_error(path, e))?;
            meta.insert("format", WORLD_FORMAT.to_le_bytes().as_slice()).map_err(|e| Self::db_error(path, e))?;
            meta.insert("recipe", recipe.to_json().as_bytes()).map_err(|e| Self::db_error(path, e))?;
            txn.open_table(CHUNKS).map_err(|e| Self::db_error(path, e))?;
        }
        txn.commit().map_err(|e| Self::db_error(path, e))?;
        Ok(WorldStore { db, path: path.to_path_buf(), recipe: recipe.clone() })
    }

    /// Opens the world at `path`.
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        if !path.is_file() {
            return Err(StoreError::NotAWorld { path: path.to_path_buf(), why: "no such file".into() });
        }
        // The database layer must not take the program down on a damaged file: a panic inside
        // it is reported as the file's error.
        let opened = std::panic::catch_unwind(|| Database::open(path));
        let db = match opened {
            Ok(r) => r.map_err(|e| Self::db_error(path, e))?,
            Err(_) => return Err(Self::db_error(path, "the database layer failed on this file")),
        };
        let not = |why: String| StoreError::NotAWorld { path: path.to_path_buf(), why };
        let txn = db.begin_read().map_err(|e| Self::db_error(path, e))?;
        let meta = txn.open_table(META).map_err(|e| not(format!("no world metadata ({e})")))?;
        let format = meta
            .get("format")
            .map_err(|e| Self::db_error(path, e))?
            .ok_or_else(|| not("no format number".into()))?
            .value()
            .to_vec();
        let format = u32::from_le_bytes(format.try_into().map_err(|_| not("a malformed format number".into()))?);
        if format > WORLD_FORMAT {
            return Err(not(format!("format {format} is newer than this program's {WORLD_FORMAT}")));
        }
        let recipe = meta.get("recipe").map_err(|e| Self::db_error(path, e))?.ok_or_else(|| not("no recipe".into()))?;
        let text = std::str::from_utf8(recipe.value()).map_err(|_| StoreError::Recipe {
            path: path.to_path_buf(),
            error: RecipeError::Parse("not UTF-8".into()),
        })?;
        let recipe = Recipe::from_json(text).map_err(|error| StoreError::Recipe { path: path.to_path_buf(), error })?;
        txn.open_table(CHUNKS).map_err(|e| not(format!("no chunk table ({e})")))?;
        drop(meta);
        drop(txn);
        Ok(WorldStore { db, path: path.to_path_buf(), recipe })
    }

    /// The world's recipe.
    pub fn recipe(&self) -> &Recipe {
        &self.recipe
    }

    /// The world file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The stored version of chunk `key`, or `None` if it is as the recipe generates it.
    pub fn read(&self, key: ChunkKey) -> Result<Option<StoredChunk>, StoreError> {
        let txn = self.db.begin_read().map_err(|e| Self::db_error(&self.path, e))?;
        let table = txn.open_table(CHUNKS).map_err(|e| Self::db_error(&self.path, e))?;
        let Some(bytes) = table.get(key_tuple(key)).map_err(|e| Self::db_error(&self.path, e))? else {
            return Ok(None);
        };
        decode_record(bytes.value()).map(Some).map_err(|why| StoreError::Chunk {
            path: self.path.clone(),
            key: key.0.to_array(),
            why,
        })
    }

    /// Writes, in one transaction, every chunk of `writes` (`Some`: its edited version; `None`:
    /// it is back to what the recipe generates, and its record goes). Atomic: after a crash the
    /// world holds all of them or none.
    pub fn write(&self, writes: &[(ChunkKey, Option<StoredChunk>)]) -> Result<(), StoreError> {
        self.write_with_notes(writes, &[])
    }

    /// [`WorldStore::write`] that also sets named notes (a viewer's position, a counter) in the
    /// same transaction. Names `format` and `recipe` are the world's own and are refused.
    pub fn write_with_notes(
        &self,
        writes: &[(ChunkKey, Option<StoredChunk>)],
        notes: &[(String, Vec<u8>)],
    ) -> Result<(), StoreError> {
        if writes.is_empty() && notes.is_empty() {
            return Ok(());
        }
        if let Some((name, _)) = notes.iter().find(|(n, _)| n == "format" || n == "recipe") {
            return Err(StoreError::NotAWorld {
                path: self.path.clone(),
                why: format!("the note name `{name}` is reserved"),
            });
        }
        let err = |e: &dyn std::fmt::Display| Self::db_error(&self.path, e);
        let txn = self.db.begin_write().map_err(|e| err(&e))?;
        {
            let mut table = txn.open_table(CHUNKS).map_err(|e| err(&e))?;
            for (key, stored) in writes {
                match stored {
                    Some(s) => {
                        table.insert(key_tuple(*key), encode_record(s).as_slice()).map_err(|e| err(&e))?;
                    }
                    None => {
                        table.remove(key_tuple(*key)).map_err(|e| err(&e))?;
                    }
                }
            }
        }
        if !notes.is_empty() {
            let mut meta = txn.open_table(META).map_err(|e| err(&e))?;
            for (name, value) in notes {
                meta.insert(format!("note:{name}").as_str(), value.as_slice()).map_err(|e| err(&e))?;
            }
        }
        txn.commit().map_err(|e| err(&e))
    }

    /// A note set by [`WorldStore::write_with_notes`].
    pub fn note(&self, name: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let txn = self.db.begin_read().map_err(|e| Self::db_error(&self.path, e))?;
        let meta = txn.open_table(META).map_err(|e| Self::db_error(&self.path, e))?;
        let v = meta.get(format!("note:{name}").as_str()).map_err(|e| Self::db_error(&self.path, e))?;
        Ok(v.map(|g| g.value().to_vec()))
    }

    /// The keys of every stored (edited) chunk.
    pub fn edited_keys(&self) -> Result<Vec<ChunkKey>, StoreError> {
        let txn = self.db.begin_read().map_err(|e| Self::db_error(&self.path, e))?;
        let table = txn.open_table(CHUNKS).map_err(|e| Self::db_error(&self.path, e))?;
        let mut keys = Vec::with_capacity(table.len().unwrap_or(0) as usize);
        for entry in table.iter().map_err(|e| Self::db_error(&self.path, e))? {
            let (k, _) = entry.map_err(|e| Self::db_error(&self.path, e))?;
            let (x, y, z) = k.value();
            keys.push(ChunkKey::new(x, y, z));
        }
        Ok(keys)
    }

    /// Checks every stored record (the checksum and the chunk's structure); the first damaged
    /// one is the error.
    pub fn verify(&self) -> Result<usize, StoreError> {
        let txn = self.db.begin_read().map_err(|e| Self::db_error(&self.path, e))?;
        let table = txn.open_table(CHUNKS).map_err(|e| Self::db_error(&self.path, e))?;
        let mut count = 0;
        for entry in table.iter().map_err(|e| Self::db_error(&self.path, e))? {
            let (k, v) = entry.map_err(|e| Self::db_error(&self.path, e))?;
            let (x, y, z) = k.value();
            decode_record(v.value()).map_err(|why| StoreError::Chunk {
                path: self.path.clone(),
                key: [x, y, z],
                why,
            })?;
            count += 1;
        }
        Ok(count)
    }

    /// Compacts the database file (gives back the space of pages freed by rewritten chunks);
    /// `false` when there was nothing to compact.
    pub fn compact(&mut self) -> Result<bool, StoreError> {
        self.db.compact().map_err(|e| Self::db_error(&self.path, e))
    }

    /// Bytes of the database file.
    pub fn file_bytes(&self) -> u64 {
        std::fs::metadata(&self.path).map(|m| m.len()).unwrap_or(0)
    }
}
