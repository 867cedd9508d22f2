//! Scene files: a versioned binary format that never loses work.
//!
//! Layout (little-endian): the 8-byte magic `b"STRATA\x00S"`, the format version (`u32`), the
//! payload length (`u64`), the CRC-32 (IEEE) of the payload (`u32`), then the payload, in
//! postcard. Version 3 (written since the second wave) frames every chunk of lists on its own,
//! with its own CRC-32, beside the layer's metadata and its list of solid chunk keys; version 2
//! (the whole [`Scene`] as one postcard value) is still read.
//!
//! What is guaranteed:
//! - **Never refuse what can be saved, never write what cannot be read.** [`save`] runs the
//!   same validation as [`load`] first; whatever it would refuse or repair (a transform that is
//!   not finite and invertible, a missing material, a volume whose lists disagree) is repaired
//!   in what is written, and the repairs are returned. Loading a file the editor wrote gives
//!   back exactly the saved scene.
//! - **Recover what can be recovered.** [`load`] refuses a file only when nothing can be read
//!   (wrong magic, a newer or too old version, a truncated file, a payload that does not parse).
//!   Everything else is repaired and reported in [`LoadReport`]: a layer with an invalid
//!   transform gets a valid one, a chunk whose bytes fail their CRC or do not decode is dropped,
//!   a volume whose lists disagree is rebuilt from its x lines ([`Volume::repair`]), an invalid
//!   view is reset. A file whose payload checksum fails is still read chunk by chunk: chunks whose
//!   own CRC fails are dropped and the report says so.
//! - **Bounded reads.** Only regular files of at most [`MAX_SCENE_BYTES`] are read; anything else
//!   is refused before a byte is read ([`strata_mesh::import::read_limited`]), and decoding never
//!   allocates more than the file's size for the payload.
//! - **Safe saves.** [`save`] writes a temporary file with a name unique to the save (process,
//!   counter and time) in the target's folder, syncs it, renames it over the target and syncs
//!   the folder, so a crash at any moment leaves the old file or the new one, never a mix; two
//!   saves of one path at once end with one of the two complete files (the last rename wins).
//!   Temporary files left by saves that were killed are removed by the next save of that path.

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use serde::{Deserialize, Serialize};
use strata_volume::{Chunk, ChunkKey, ChunkLists, Level, Volume};
use thiserror::Error;

use crate::scene::{Layer, LayerTransform, Material, Scene, View};

/// The first eight bytes of every scene file.
pub const MAGIC: [u8; 8] = *b"STRATA\x00S";
/// The format version this build writes and the newest it reads.
pub const VERSION: u32 = 3;
/// The oldest version this build reads. Version 1 stored chunk lists with per-line start bits
/// and unary counts (before the layout of `strata-volume`'s `ChunkLists` changed).
pub const OLDEST_VERSION: u32 = 2;
/// Bytes before the payload.
pub const HEADER_LEN: usize = 8 + 4 + 8 + 4;
/// The largest scene file read: 4 GiB (the bunny at 1,024 cells a side takes 25 MB).
pub const MAX_SCENE_BYTES: u64 = 4 << 30;

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
    /// The payload's checksum does not match and its structure cannot be read either.
    #[error("scene file is corrupted (checksum mismatch)")]
    Checksum,
    /// The payload does not decode into a scene.
    #[error("scene file payload is invalid: {0}")]
    Payload(String),
    /// Reading or writing failed.
    #[error(transparent)]
    Io(#[from] io::Error),
}

/// What a load or a save repaired or dropped, one sentence per finding, naming the layer.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// Each repair, e.g. `layer "rocks": chunk (1, 0, 2) failed its checksum and was dropped`.
    pub repairs: Vec<String>,
}

impl LoadReport {
    /// Whether nothing needed repair.
    pub fn is_clean(&self) -> bool {
        self.repairs.is_empty()
    }
}

impl std::fmt::Display for LoadReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.repairs.is_empty() {
            return f.write_str("nothing needed repair");
        }
        f.write_str(&self.repairs.join("; "))
    }
}

/// A scene read from a file, and what was repaired to read it.
#[derive(Clone, Debug, PartialEq)]
pub struct Loaded {
    /// The scene, valid in every respect [`validate_scene`] checks.
    pub scene: Scene,
    /// What was repaired or dropped (empty for a file this build wrote intact).
    pub report: LoadReport,
    /// The file format version the scene was read from.
    pub version: u32,
}

/// What version 3 stores per layer: everything but the chunks of lists.
#[derive(Serialize, Deserialize)]
struct LayerRecord {
    name: String,
    transform: LayerTransform,
    visible: bool,
    locked: bool,
    material: u32,
    level: u8,
    cell_size: f64,
    solid: Vec<ChunkKey>,
    lists: Vec<ChunkRecord>,
}

/// One chunk of lists, framed: its key, the CRC-32 of its bytes and its bytes (a postcard
/// [`ChunkLists`]).
#[derive(Serialize, Deserialize)]
struct ChunkRecord {
    key: ChunkKey,
    crc: u32,
    bytes: Vec<u8>,
}

#[derive(Serialize, Deserialize)]
struct SceneRecord {
    layers: Vec<LayerRecord>,
    materials: Vec<Material>,
    view: View,
}

/// Checks `scene` as [`load`] does and repairs in place whatever would be refused; returns the
/// repairs (empty when the scene was valid, in which case nothing changed).
pub fn validate_scene(scene: &mut Scene) -> LoadReport {
    let mut report = LoadReport::default();
    if scene.materials.is_empty() {
        scene.materials = Scene::default().materials;
        report.repairs.push("the scene had no materials; the default material was added".into());
    }
    for l in &mut scene.layers {
        let name = &l.name;
        if !l.transform.is_valid() {
            let fixed = l.transform.repaired();
            report.repairs.push(format!(
                "layer {name:?}: its transform (translation {}, rotation {}, scale {}) was not finite and invertible and became (translation {}, rotation {}, scale {})",
                l.transform.translation, l.transform.rotation, l.transform.scale, fixed.translation, fixed.rotation, fixed.scale
            ));
            l.transform = fixed;
        }
        if l.material as usize >= scene.materials.len() {
            report.repairs.push(format!("layer {name:?}: material {} does not exist; it uses material 0", l.material));
            l.material = 0;
        }
        let r = l.volume.repair();
        if let Some(problem) = &r.problem {
            report.repairs.push(format!(
                "layer {name:?}: its lists were inconsistent ({problem}); rebuilt from its x lines ({} node states on y and z lines moved{}; {} chunks before, {} after)",
                r.repaired_nodes,
                if r.dropped_chunks > 0 { format!(", {} chunks at a foreign level dropped", r.dropped_chunks) } else { String::new() },
                r.chunks_before,
                r.chunks_after
            ));
        }
    }
    let v = &mut scene.view;
    if !(v.target.is_finite() && v.distance.is_finite() && v.distance > 0.0 && v.yaw.is_finite() && v.pitch.is_finite())
    {
        let fixed = View::framing(scene.layers.iter());
        report.repairs.push(format!("the saved view was not finite; the camera frames the scene instead ({fixed:?})"));
        scene.view = fixed;
    }
    report
}

/// The file's bytes for `scene`, which must be valid (see [`validate_scene`]; [`save`] makes
/// sure of it).
pub fn encode(scene: &Scene) -> Result<Vec<u8>, SceneFileError> {
    let payload_err = |e: postcard::Error| SceneFileError::Payload(e.to_string());
    let mut layers = Vec::with_capacity(scene.layers.len());
    for l in &scene.layers {
        let mut solid = Vec::new();
        let mut lists = Vec::new();
        let mut chunks: Vec<(ChunkKey, &Chunk)> = l.volume.chunks().collect();
        // A canonical order: the same scene always gives the same bytes.
        chunks.sort_by_key(|(k, _)| k.0.to_array());
        for (key, chunk) in chunks {
            match chunk {
                Chunk::Solid => solid.push(key),
                Chunk::Lists(c) => {
                    let bytes = postcard::to_allocvec(c).map_err(payload_err)?;
                    lists.push(ChunkRecord { key, crc: crc32fast::hash(&bytes), bytes });
                }
            }
        }
        layers.push(LayerRecord {
            name: l.name.clone(),
            transform: l.transform,
            visible: l.visible,
            locked: l.locked,
            material: l.material,
            level: l.volume.level().get(),
            cell_size: l.volume.cell_size(),
            solid,
            lists,
        });
    }
    let record = SceneRecord { layers, materials: scene.materials.clone(), view: scene.view };
    let payload = postcard::to_allocvec(&record).map_err(payload_err)?;
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    Ok(out)
}

/// The scene in `bytes`, with whatever had to be repaired (see the module docs).
pub fn decode(bytes: &[u8]) -> Result<Loaded, SceneFileError> {
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
    let intact = crc32fast::hash(payload) == word(20);
    let mut report = LoadReport::default();
    let mut scene = if version == 2 {
        // One postcard value: nothing to recover from a damaged one.
        if !intact {
            return Err(SceneFileError::Checksum);
        }
        postcard::from_bytes::<Scene>(payload).map_err(|e| SceneFileError::Payload(e.to_string()))?
    } else {
        let record: SceneRecord = match postcard::from_bytes(payload) {
            Ok(r) => r,
            Err(_) if !intact => return Err(SceneFileError::Checksum),
            Err(e) => return Err(SceneFileError::Payload(e.to_string())),
        };
        if !intact {
            report.repairs.push(
                "the file's checksum does not match: it was damaged after it was written; every chunk was checked against its own checksum, but layer names, transforms and settings could not be verified".into(),
            );
        }
        scene_from_record(record, &mut report)
    };
    report.repairs.extend(validate_scene(&mut scene).repairs);
    Ok(Loaded { scene, report, version })
}

fn scene_from_record(record: SceneRecord, report: &mut LoadReport) -> Scene {
    let mut layers = Vec::with_capacity(record.layers.len());
    for l in record.layers {
        let name = l.name;
        let level = Level::new(l.level).unwrap_or_else(|| {
            report
                .repairs
                .push(format!("layer {name:?}: resolution level {} does not exist; it uses level 0", l.level));
            Level::BASE
        });
        let cell_size = if l.cell_size.is_finite() && l.cell_size > 0.0 {
            l.cell_size
        } else {
            report
                .repairs
                .push(format!("layer {name:?}: cell size {} is not finite and positive; it is 1", l.cell_size));
            1.0
        };
        let mut chunks: Vec<(ChunkKey, Chunk)> = l.solid.into_iter().map(|k| (k, Chunk::Solid)).collect();
        for c in l.lists {
            let (x, y, z) = (c.key.0.x, c.key.0.y, c.key.0.z);
            if crc32fast::hash(&c.bytes) != c.crc {
                report
                    .repairs
                    .push(format!("layer {name:?}: chunk ({x}, {y}, {z}) failed its checksum and was dropped"));
                continue;
            }
            match postcard::from_bytes::<ChunkLists>(&c.bytes) {
                Ok(lists) => chunks.push((c.key, Chunk::Lists(lists))),
                Err(e) => report
                    .repairs
                    .push(format!("layer {name:?}: chunk ({x}, {y}, {z}) does not decode ({e}) and was dropped")),
            }
        }
        let volume = Volume::from_chunks(level, cell_size, chunks).expect("cell size checked");
        layers.push(Layer {
            name,
            transform: l.transform,
            visible: l.visible,
            locked: l.locked,
            material: l.material,
            volume,
        });
    }
    Scene { layers, materials: record.materials, view: record.view }
}

/// Reads the scene at `path` (a regular file of at most [`MAX_SCENE_BYTES`]), repairing what it
/// can. On error nothing else changes.
pub fn load(path: &Path) -> Result<Loaded, SceneFileError> {
    let bytes = strata_mesh::import::read_limited(path, MAX_SCENE_BYTES)?;
    decode(&bytes)
}

/// Writes `scene` to `path` atomically and durably (see the module docs). Whatever validation
/// would refuse is repaired in the written copy, and the returned report lists it (`scene`
/// itself is not changed: call [`validate_scene`] on it to make it match the file).
pub fn save(scene: &Scene, path: &Path) -> Result<LoadReport, SceneFileError> {
    let (bytes, report) = if is_valid(scene) {
        (encode(scene)?, LoadReport::default())
    } else {
        let mut fixed = scene.clone();
        let report = validate_scene(&mut fixed);
        (encode(&fixed)?, report)
    };
    write_atomically(path, |f| f.write_all(&bytes))?;
    Ok(report)
}

/// Whether [`validate_scene`] would leave `scene` as it is.
pub fn is_valid(scene: &Scene) -> bool {
    let v = &scene.view;
    !scene.materials.is_empty()
        && scene.layers.iter().all(|l| {
            l.transform.is_valid()
                && (l.material as usize) < scene.materials.len()
                && l.volume.check_invariants().is_ok()
        })
        && v.target.is_finite()
        && v.distance.is_finite()
        && v.distance > 0.0
        && v.yaw.is_finite()
        && v.pitch.is_finite()
}

/// A name unique to one save (process, a counter, the time), for the temporary file beside
/// `path`: `.NAME.PID-COUNTER-NANOS.strata-tmp`.
pub fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let count = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.subsec_nanos());
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".{}-{count}-{nanos}{TEMP_SUFFIX}", std::process::id()));
    path.with_file_name(name)
}

const TEMP_SUFFIX: &str = ".strata-tmp";

/// Temporary files of saves of `path` whose process is gone (killed mid-save), which the next
/// save removes. Only files named by [`temp_path`] for this very target are considered, and only
/// when their process no longer runs (on systems without `/proc`, when they are over an hour
/// old), so a save in progress in another process is never disturbed.
pub fn stale_temp_files(path: &Path) -> Vec<PathBuf> {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else { return Vec::new() };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let prefix = format!(".{name}.");
    let Ok(entries) = fs::read_dir(&dir) else { return Vec::new() };
    let me = std::process::id();
    let mut out = Vec::new();
    for e in entries.flatten() {
        let file = e.file_name();
        let Some(file) = file.to_str() else { continue };
        let Some(rest) = file.strip_prefix(&prefix).and_then(|r| r.strip_suffix(TEMP_SUFFIX)) else { continue };
        let Some(pid) = rest.split('-').next().and_then(|p| p.parse::<u32>().ok()) else { continue };
        if pid == me || rest.split('-').count() != 3 {
            continue;
        }
        let gone = if Path::new("/proc/self").exists() {
            !Path::new(&format!("/proc/{pid}")).exists()
        } else {
            e.metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_some_and(|age| age > std::time::Duration::from_secs(3600))
        };
        if gone {
            out.push(e.path());
        }
    }
    out
}

/// Writes through `write` into a temporary file beside `path` (see [`temp_path`]), syncs it,
/// renames it over `path` and syncs the folder. If anything fails, the temporary file is
/// removed and `path` is untouched. Stale temporary files of earlier, killed saves of `path`
/// are removed first.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> Result<(), SceneFileError> {
    for stale in stale_temp_files(path) {
        let _ = fs::remove_file(stale);
    }
    let tmp = temp_path(path);
    let result = (|| {
        let mut f = fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        write(&mut f)?;
        f.sync_all()?;
        drop(f);
        fs::rename(&tmp, path)?;
        sync_parent(path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    Ok(result?)
}

/// Syncs the folder holding `path`, so a rename into it survives a power cut.
fn sync_parent(path: &Path) -> io::Result<()> {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        fs::File::open(dir)?.sync_all()
    }
    #[cfg(not(unix))]
    {
        // Folders cannot be opened for syncing here; the rename itself is what the system offers.
        let _ = path;
        Ok(())
    }
}
