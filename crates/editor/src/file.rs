//! Scene files: a versioned binary format.
//!
//! Layout (little-endian): the 8-byte magic `b"STRATA\x00S"`, the format version (`u32`), the
//! payload length (`u64`), the CRC-32 (IEEE) of the payload (`u32`), then the payload: the
//! [`Scene`] serialised with postcard. [`load`] rejects a wrong magic, a newer version, a
//! length that disagrees with the file, a checksum mismatch and a payload that does not decode,
//! each with its own [`SceneFileError`], and never allocates more than the file's size for the
//! payload. A payload that decodes is also checked: layer transforms finite and invertible,
//! materials present, every volume passing `check_invariants` (lists that are well formed but
//! disagree between axes are refused, not repaired). [`save`] writes to a temporary file in the same folder, flushes it to disk and
//! renames it over the target, so a crash or a failed write leaves the old file as it was.

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::scene::Scene;

/// The first eight bytes of every scene file.
pub const MAGIC: [u8; 8] = *b"STRATA\x00S";
/// The format version this build writes and the newest it reads.
pub const VERSION: u32 = 2;
/// The oldest version this build reads. Version 1 stored chunk lists with per-line start bits
/// and unary counts (before the layout of `strata-volume`'s `ChunkLists` changed).
pub const OLDEST_VERSION: u32 = 2;
/// Bytes before the payload.
pub const HEADER_LEN: usize = 8 + 4 + 8 + 4;

/// Why a scene file could not be read or written.
#[derive(Debug, Error)]
pub enum SceneFileError {
    /// Not a scene file.
    #[error("not a Strata scene file (wrong magic bytes)")]
    BadMagic,
    /// Written by a newer Strata.
    #[error("scene file format version {found} is newer than this build reads ({supported})")]
    NewerVersion {
        /// The file's version.
        found: u32,
        /// The newest this build reads.
        supported: u32,
    },
    /// Written by an older Strata in a layout this build no longer reads.
    #[error(
        "scene file format version {found} is older than this build reads (oldest {oldest}); re-export it from the build that wrote it"
    )]
    OldVersion {
        /// The file's version.
        found: u32,
        /// The oldest this build reads.
        oldest: u32,
    },
    /// Shorter or longer than its header says.
    #[error("scene file is truncated or has trailing bytes: header says {expected} payload bytes, file has {found}")]
    Truncated {
        /// Payload bytes the header announces.
        expected: u64,
        /// Payload bytes present.
        found: u64,
    },
    /// The payload's checksum does not match.
    #[error("scene file is corrupted (checksum mismatch)")]
    Checksum,
    /// The payload does not decode into a valid scene.
    #[error("scene file payload is invalid: {0}")]
    Payload(String),
    /// Reading or writing failed.
    #[error(transparent)]
    Io(#[from] io::Error),
}

/// The file's bytes for `scene`.
pub fn encode(scene: &Scene) -> Result<Vec<u8>, SceneFileError> {
    let payload = postcard::to_allocvec(scene).map_err(|e| SceneFileError::Payload(e.to_string()))?;
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    Ok(out)
}

/// The scene in `bytes`, validated.
pub fn decode(bytes: &[u8]) -> Result<Scene, SceneFileError> {
    if bytes.len() < 8 || bytes[..8] != MAGIC {
        return Err(SceneFileError::BadMagic);
    }
    if bytes.len() < HEADER_LEN {
        return Err(SceneFileError::Truncated { expected: 0, found: 0 });
    }
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    let version = word(8);
    if version > VERSION {
        return Err(SceneFileError::NewerVersion { found: version, supported: VERSION });
    }
    if version < OLDEST_VERSION {
        return Err(SceneFileError::OldVersion { found: version, oldest: OLDEST_VERSION });
    }
    let expected = u64::from_le_bytes(bytes[12..20].try_into().expect("8 bytes"));
    let payload = &bytes[HEADER_LEN..];
    if expected != payload.len() as u64 {
        return Err(SceneFileError::Truncated { expected, found: payload.len() as u64 });
    }
    if crc32fast::hash(payload) != word(20) {
        return Err(SceneFileError::Checksum);
    }
    let scene: Scene = postcard::from_bytes(payload).map_err(|e| SceneFileError::Payload(e.to_string()))?;
    validate(&scene)?;
    Ok(scene)
}

fn validate(scene: &Scene) -> Result<(), SceneFileError> {
    let bad = |what: &str| Err(SceneFileError::Payload(what.to_string()));
    for l in &scene.layers {
        if !l.transform.is_valid() {
            return bad("a layer's transform is not finite and invertible");
        }
        if l.material as usize >= scene.materials.len().max(1) {
            return bad("a layer names a material that does not exist");
        }
        // Well-formed lists can still contradict each other (a bit flip that kept the
        // structure): the x, y and z lists must agree on every node, as after any edit.
        if let Err(v) = l.volume.check_invariants() {
            return Err(SceneFileError::Payload(format!("layer {:?} is inconsistent: {v}", l.name)));
        }
    }
    let v = &scene.view;
    if !(v.target.is_finite() && v.distance.is_finite() && v.yaw.is_finite() && v.pitch.is_finite()) {
        return bad("the view is not finite");
    }
    Ok(())
}

/// Reads the scene at `path`. On error nothing else changes.
pub fn load(path: &Path) -> Result<Scene, SceneFileError> {
    decode(&fs::read(path)?)
}

/// Writes `scene` to `path` atomically (temporary file in the same folder, flush, rename).
pub fn save(scene: &Scene, path: &Path) -> Result<(), SceneFileError> {
    let bytes = encode(scene)?;
    write_atomically(path, |f| f.write_all(&bytes))
}

/// The temporary file `save` writes first.
pub fn temp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(format!(".{}.tmp", std::process::id()));
    path.with_file_name(name)
}

/// Writes through `write` into a temporary file beside `path`, syncs it and renames it over
/// `path`. If `write` fails, the temporary file is removed and `path` is untouched.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> Result<(), SceneFileError> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        write(&mut f)?;
        f.sync_all()?;
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    Ok(result?)
}
