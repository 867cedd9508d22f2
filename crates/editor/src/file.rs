//! Scene files: a versioned binary format that never loses work.
//!
//! Layout (little-endian): the 8-byte magic `b"STRATA\x00S"`, the format version (`u32`), the
//! payload length (`u64`), the CRC-32 (IEEE) of the payload (`u32`), then the payload, in
//! postcard. Version 4 (written since materials) frames every chunk of lists on its own, with its
//! own CRC-32, beside the layer's metadata and its list of solid chunk keys, and frames the node
//! materials of every chunk that has any but material 0 the same way (a postcard
//! [`strata_volume::ChunkMaterials`]); the palette's entries carry texture, scale and roughness.
//! Version 5 (written since masks) adds each layer's mask ([`strata_volume::mask`]): its weight
//! outside the stored chunks, and every stored chunk of it framed the same way (a postcard
//! [`strata_volume::ChunkMask`]). Version 6 (written since reference images) adds the scene's
//! [`crate::reference::ReferenceImage`]s after the view: each one's name, middle, turn, width,
//! opacity, shown and locked flags, and its picture file's bytes as loaded (a PNG or a JPEG) with
//! their CRC-32, so a scene file carries its references with it. Versions 5 (no references), 4
//! (no masks), 3 (no node materials: one material per layer) and 2 (the whole scene as one
//! postcard value) are still read: a layer of version 2 or 3 gives its material to its every
//! node, and the palette's entries get the plain texture.
//!
//! What is guaranteed:
//! - **Never refuse what can be saved, never write what cannot be read.** [`save`] runs the
//!   same validation as [`load`] first; whatever it would refuse or repair (a transform that is
//!   not finite and invertible, a missing material, a volume whose lists disagree) is repaired
//!   in what is written, and the repairs are returned. Loading a file the editor wrote gives
//!   back exactly the saved scene.
//! - **Recover what can be recovered.** [`load`] refuses a file only when nothing can be read
//!   (wrong magic, a newer or too old version, a truncated file, a payload that does not parse)
//!   or when a node names a material the palette does not have (such a file was not written by
//!   Strata; guessing a material would silently change the model).
//!   Everything else is repaired and reported in [`LoadReport`]: a layer with an invalid
//!   transform gets a valid one, a chunk whose bytes fail their CRC or do not decode is dropped,
//!   a chunk key stored more than once (solid and lists, or twice the same kind) keeps its first
//!   chunk of lists or else one solid entry and the report names what was dropped, materials
//!   stored twice, for an empty chunk or not fitting their chunk are dropped (its nodes use
//!   material 0), a volume whose lists disagree is rebuilt from its x lines ([`Volume::repair`],
//!   which keeps chunks stored at other levels than the layer's), an invalid view is reset, a chunk of a mask that fails its checksum or
//!   does not decode is dropped (its nodes take the mask's outside weight) and named, a
//!   reference whose picture fails its checksum or does not decode is dropped and named, a
//!   reference whose numbers are out of range is brought to the nearest valid one, references
//!   past [`crate::reference::MAX_REFERENCES`] are dropped. A
//!   file whose payload checksum fails is still read chunk by chunk: chunks whose own CRC fails
//!   are dropped and the report says so.
//! - **Levels.** A layer stores its base level and every chunk of lists its own; any mix is
//!   valid (a layer whose chunks were all raised is stored that way), so a layer level that
//!   differs from its chunks' is kept as it is. A level that does not exist becomes level 0; a
//!   chunk whose own level field disagrees with its data does not decode and is dropped. A
//!   uniform chunk's materials are per node of the layer's level, so runs that reach past that
//!   count are dropped; runs written for a coarser level fit and cannot be told apart.
//! - **Bounded reads.** Only regular files of at most [`MAX_SCENE_BYTES`] are read; anything else
//!   is refused before a byte is read ([`strata_files::read_limited`]), and decoding never
//!   allocates more than the file's size for the payload.
//! - **Safe saves.** [`save`] writes a temporary file with a name unique to the save (process,
//!   counter and time) in the target's folder, syncs it, renames it over the target and syncs
//!   the folder, so a crash at any moment leaves the old file or the new one, never a mix; two
//!   saves of one path at once end with one of the two complete files (the last rename wins).
//!   Temporary files left by saves that were killed are removed by the next save of that path.

use std::collections::{HashMap, HashSet, hash_map};
use std::fs;
use std::io::{self, Write};
use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use strata_volume::{Chunk, ChunkKey, ChunkLists, ChunkMap, ChunkMask, ChunkMaterials, Level, Volume};
use thiserror::Error;

use crate::reference::{MAX_REFERENCES, Picture, ReferenceImage};
use crate::scene::{Layer, LayerTransform, Material, Scene, View};

/// The first eight bytes of every scene file.
pub const MAGIC: [u8; 8] = *b"STRATA\x00S";
/// The format version this build writes for a scene with reference images, and the newest it
/// reads (a scene without them is written as version 5, which older builds read).
pub const VERSION: u32 = 6;
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
    /// A node names a material the palette does not have.
    #[error("layer {layer:?} uses material {id}, but the scene's palette has only {count} materials")]
    UnknownMaterial {
        /// The layer's name.
        layer: String,
        /// The largest id used.
        id: u8,
        /// Materials in the palette.
        count: usize,
    },
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

/// What version 4 stores per layer (public for tests that craft files; not a stable API).
#[doc(hidden)]
#[derive(Debug, Serialize, Deserialize)]
pub struct LayerRecord {
    pub name: String,
    pub transform: LayerTransform,
    pub visible: bool,
    pub locked: bool,
    /// The volume's base level; its chunks of lists each carry their own.
    pub level: u8,
    pub cell_size: f64,
    pub solid: Vec<ChunkKey>,
    pub lists: Vec<ChunkRecord>,
    /// Framed [`ChunkMaterials`], one per chunk with materials.
    pub materials: Vec<ChunkRecord>,
    /// The mask's weight outside its stored chunks (version 5).
    pub mask_outside: u8,
    /// Framed [`ChunkMask`]s, one per stored chunk of the mask (version 5).
    pub masks: Vec<ChunkRecord>,
}

/// What version 4 stored per layer: the same without a mask.
#[derive(Serialize, Deserialize)]
struct LayerRecordV4 {
    name: String,
    transform: LayerTransform,
    visible: bool,
    locked: bool,
    level: u8,
    cell_size: f64,
    solid: Vec<ChunkKey>,
    lists: Vec<ChunkRecord>,
    materials: Vec<ChunkRecord>,
}

#[derive(Serialize, Deserialize)]
struct SceneRecordV4 {
    layers: Vec<LayerRecordV4>,
    materials: Vec<Material>,
    view: View,
}

/// What version 3 stored per layer: one material for the whole layer, no node materials.
#[derive(Deserialize)]
struct LayerRecordV3 {
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

/// A palette entry of versions 2 and 3.
#[doc(hidden)]
#[derive(Debug, Serialize, Deserialize)]
pub struct MaterialV3 {
    pub name: String,
    pub color: [f32; 3],
}

#[derive(Deserialize)]
struct SceneRecordV3 {
    layers: Vec<LayerRecordV3>,
    materials: Vec<MaterialV3>,
    view: View,
}

/// A version 2 file: the scene of that time as one postcard value (public for tests that
/// craft files; not a stable API).
#[doc(hidden)]
#[derive(Debug, Serialize, Deserialize)]
pub struct SceneV2 {
    pub layers: Vec<LayerV2>,
    pub materials: Vec<MaterialV3>,
    pub view: View,
}

#[doc(hidden)]
#[derive(Debug, Serialize, Deserialize)]
pub struct LayerV2 {
    pub name: String,
    pub transform: LayerTransform,
    pub visible: bool,
    pub locked: bool,
    pub material: u32,
    pub volume: VolumeV2,
}

#[doc(hidden)]
#[derive(Debug, Serialize, Deserialize)]
pub struct VolumeV2 {
    pub chunks: ChunksV2,
    pub level: Level,
    pub cell_size: f64,
}

/// A [`ChunkMap`] as version 2 wrote it (a map of list chunks, then a set of solid keys: in
/// postcard, the same bytes as these two sequences), read without its checks so that a key
/// stored twice is resolved and reported rather than failing the whole file.
#[doc(hidden)]
#[derive(Debug, Serialize, Deserialize)]
pub struct ChunksV2 {
    pub lists: Vec<(ChunkKey, Chunk)>,
    pub solid: Vec<ChunkKey>,
}

/// The payload of a version 2 file holding `scene` (its layers' one material each taken from
/// the material of their first solid node), for tests of the reader. The chunks are written as
/// version 2 wrote them, a [`ChunkMap`], and read back as [`ChunksV2`].
#[doc(hidden)]
pub fn encode_version_2_payload(scene: &Scene) -> Result<Vec<u8>, SceneFileError> {
    let payload_err = |e: postcard::Error| SceneFileError::Payload(e.to_string());
    let mut layers = Vec::with_capacity(scene.layers.len());
    for l in &scene.layers {
        let map = ChunkMap::from_chunks(l.volume.chunks().map(|(k, c)| (k, c.clone())));
        let chunks = postcard::from_bytes(&postcard::to_allocvec(&map).map_err(payload_err)?).map_err(payload_err)?;
        layers.push(LayerV2 {
            name: l.name.clone(),
            transform: l.transform,
            visible: l.visible,
            locked: l.locked,
            material: l.volume.max_material().unwrap_or(0) as u32,
            volume: VolumeV2 { chunks, level: l.volume.level(), cell_size: l.volume.cell_size() },
        });
    }
    let materials = scene.materials.iter().map(|m| MaterialV3 { name: m.name.clone(), color: m.color }).collect();
    postcard::to_allocvec(&SceneV2 { layers, materials, view: scene.view }).map_err(payload_err)
}

/// One chunk of lists, framed: its key, the CRC-32 of its bytes and its bytes (a postcard
/// [`ChunkLists`]).
#[doc(hidden)]
#[derive(Debug, Serialize, Deserialize)]
pub struct ChunkRecord {
    pub key: ChunkKey,
    pub crc: u32,
    #[serde(with = "byte_string")]
    pub bytes: Vec<u8>,
}

/// A `Vec<u8>` (de)serialised as a byte string: in postcard the same bytes as a sequence of
/// `u8` (a varint length, then one byte each), read and written as one slice instead of byte
/// by byte.
mod byte_string {
    use serde::{Deserializer, Serializer};

    pub fn serialize<S: Serializer>(bytes: &[u8], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(bytes)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
        struct Bytes;
        impl<'de> serde::de::Visitor<'de> for Bytes {
            type Value = Vec<u8>;

            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a byte string")
            }

            fn visit_bytes<E: serde::de::Error>(self, v: &[u8]) -> Result<Vec<u8>, E> {
                Ok(v.to_vec())
            }

            fn visit_byte_buf<E: serde::de::Error>(self, v: Vec<u8>) -> Result<Vec<u8>, E> {
                Ok(v)
            }

            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<u8>, A::Error> {
                let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(1 << 20));
                while let Some(b) = seq.next_element()? {
                    out.push(b);
                }
                Ok(out)
            }
        }
        d.deserialize_byte_buf(Bytes)
    }
}

impl ChunkRecord {
    /// `bytes` framed at `key` with their CRC.
    #[doc(hidden)]
    pub fn new(key: ChunkKey, bytes: Vec<u8>) -> Self {
        ChunkRecord { key, crc: crc32fast::hash(&bytes), bytes }
    }
}

/// The payload of a version 6 file (public for tests that craft files; not a stable API).
#[doc(hidden)]
#[derive(Debug, Serialize, Deserialize)]
pub struct SceneRecord {
    pub layers: Vec<LayerRecord>,
    pub materials: Vec<Material>,
    pub view: View,
    /// The reference images (version 6).
    pub references: Vec<ReferenceRecord>,
}

/// The payload of a version 5 file: the same without references.
#[derive(Serialize, Deserialize)]
struct SceneRecordV5 {
    layers: Vec<LayerRecord>,
    materials: Vec<Material>,
    view: View,
}

/// One reference image as version 6 stores it (public for tests that craft files; not a
/// stable API): its placement and its picture file's bytes with their CRC-32.
#[doc(hidden)]
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReferenceRecord {
    pub name: String,
    pub center: glam::DVec3,
    pub rotation: glam::DQuat,
    pub width: f64,
    pub opacity: f32,
    pub visible: bool,
    pub locked: bool,
    pub crc: u32,
    #[serde(with = "byte_string")]
    pub bytes: Vec<u8>,
}

/// Checks `scene` as [`load`] does and repairs in place whatever would be refused; returns the
/// repairs (empty when the scene was valid, in which case nothing changed).
pub fn validate_scene(scene: &mut Scene) -> LoadReport {
    let mut report = LoadReport::default();
    if scene.materials.is_empty() {
        scene.materials = Scene::default().materials;
        report.repairs.push("the scene had no materials; the built-in palette was added".into());
    }
    if scene.materials.len() > strata_volume::MATERIAL_IDS {
        report.repairs.push(format!(
            "the palette had {} materials; those past the {}th were dropped",
            scene.materials.len(),
            strata_volume::MATERIAL_IDS
        ));
        scene.materials.truncate(strata_volume::MATERIAL_IDS);
    }
    for (i, m) in scene.materials.iter_mut().enumerate() {
        if !m.is_valid() {
            let fixed = Material {
                color: m.color.map(|c| if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.5 }),
                scale: if m.scale.is_finite() && m.scale > 0.0 { m.scale } else { 16.0 },
                roughness: if m.roughness.is_finite() { m.roughness.clamp(0.0, 1.0) } else { 0.7 },
                ..m.clone()
            };
            report
                .repairs
                .push(format!("material {i} ({:?}): colour, scale or roughness out of range; clamped", m.name));
            *m = fixed;
        }
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
        if l.volume.max_material().is_some_and(|m| m as usize >= scene.materials.len()) {
            let chunks = l.volume.clamp_materials(scene.materials.len());
            report.repairs.push(format!(
                "layer {name:?}: nodes in {chunks} chunks used materials past the palette's {}; they use material 0",
                scene.materials.len()
            ));
        }
        let r = l.volume.repair();
        if let Some(problem) = &r.problem {
            report.repairs.push(format!(
                "layer {name:?}: its lists were inconsistent ({problem}); rebuilt from its x lines ({} node states on y and z lines moved{}; {} chunks before, {} after)",
                r.repaired_nodes,
                relevelled(&r, l.volume.level()),
                r.chunks_before,
                r.chunks_after
            ));
        }
    }
    if scene.references.len() > MAX_REFERENCES {
        report.repairs.push(format!(
            "the scene had {} reference images; those past the {MAX_REFERENCES}th were dropped",
            scene.references.len()
        ));
        scene.references.truncate(MAX_REFERENCES);
    }
    for r in &mut scene.references {
        if !r.is_valid() {
            let fixed = r.repaired();
            report.repairs.push(format!(
                "reference image {:?}: its position, turn, width or opacity was not finite or out of range and became the nearest valid one",
                r.name
            ));
            *r = fixed;
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

/// What a repair did to chunks stored at other levels than the layer's, as a clause of the
/// repair's sentence (empty when there were none).
fn relevelled(r: &strata_volume::RepairReport, level: Level) -> String {
    let mut out = String::new();
    if r.relevelled_chunks > 0 {
        out += &format!(
            ", {} chunks stored at other levels brought to the layer's level {} for it and back",
            r.relevelled_chunks,
            level.get()
        );
    }
    if r.dropped_chunks > 0 {
        out += &format!(", {} chunks that could not be brought to level {} dropped", r.dropped_chunks, level.get());
    }
    out
}

/// The file's bytes for `scene`, which must be valid (see [`validate_scene`]; [`save`] makes
/// sure of it).
pub fn encode(scene: &Scene) -> Result<Vec<u8>, SceneFileError> {
    encode_record(&scene_record(scene, true)?)
}

/// [`encode`] without the reference images: what a shared room's snapshot holds (references
/// are each person's own).
pub fn encode_shared(scene: &Scene) -> Result<Vec<u8>, SceneFileError> {
    encode_record(&scene_record(scene, false)?)
}

/// What [`encode`] writes for `scene`, before it is framed (for tests that craft files); its
/// reference images only `with_references`.
#[doc(hidden)]
pub fn scene_record(scene: &Scene, with_references: bool) -> Result<SceneRecord, SceneFileError> {
    let payload_err = |e: postcard::Error| SceneFileError::Payload(e.to_string());
    let mut layers = Vec::with_capacity(scene.layers.len());
    for l in &scene.layers {
        let mut solid = Vec::new();
        let mut materials = Vec::new();
        let mut with_materials: Vec<(ChunkKey, &ChunkMaterials)> = l.volume.material_chunks().collect();
        with_materials.sort_by_key(|(k, _)| k.0.to_array());
        for (key, m) in with_materials {
            materials.push(ChunkRecord::new(key, postcard::to_allocvec(m).map_err(payload_err)?));
        }
        let mut masks = Vec::new();
        let mut stored: Vec<(ChunkKey, &ChunkMask)> = l.volume.mask().chunks().collect();
        stored.sort_by_key(|(k, _)| k.0.to_array());
        for (key, m) in stored {
            masks.push(ChunkRecord::new(key, postcard::to_allocvec(m).map_err(payload_err)?));
        }
        let mut chunks: Vec<(ChunkKey, &Chunk)> = l.volume.chunks().collect();
        // A canonical order: the same scene always gives the same bytes.
        chunks.sort_by_key(|(k, _)| k.0.to_array());
        let mut listed = Vec::with_capacity(chunks.len());
        for (key, chunk) in chunks {
            match chunk {
                Chunk::Solid => solid.push(key),
                Chunk::Lists(c) => listed.push((key, c)),
            }
        }
        // Each chunk's bytes and CRC on every core, in the canonical order.
        let lists = listed
            .par_iter()
            .with_min_len(64)
            .map(|&(key, c)| Ok(ChunkRecord::new(key, postcard::to_allocvec(c).map_err(payload_err)?)))
            .collect::<Result<Vec<_>, SceneFileError>>()?;
        layers.push(LayerRecord {
            name: l.name.clone(),
            transform: l.transform,
            visible: l.visible,
            locked: l.locked,
            // A volume's own level is never below the base level, so its number fits.
            level: l.volume.level().get().max(0) as u8,
            cell_size: l.volume.cell_size(),
            solid,
            lists,
            materials,
            mask_outside: l.volume.mask().outside(),
            masks,
        });
    }
    let references = if with_references { scene.references.iter().map(reference_record).collect() } else { Vec::new() };
    Ok(SceneRecord { layers, materials: scene.materials.clone(), view: scene.view, references })
}

/// What version 6 stores of `r`.
fn reference_record(r: &ReferenceImage) -> ReferenceRecord {
    let bytes = r.picture.bytes().to_vec();
    ReferenceRecord {
        name: r.name.clone(),
        center: r.center,
        rotation: r.rotation,
        width: r.width,
        opacity: r.opacity,
        visible: r.visible,
        locked: r.locked,
        crc: crc32fast::hash(&bytes),
        bytes,
    }
}

/// The file's bytes for `record` with the header: version 6, or version 5 when it holds no
/// reference images (for tests that craft files; [`encode`] is `scene_record` then this).
#[doc(hidden)]
pub fn encode_record(record: &SceneRecord) -> Result<Vec<u8>, SceneFileError> {
    if record.references.is_empty() {
        // (Without references a scene is written as version 5, which builds before reference
        // images read too: a room's snapshot always is.)
        let v5 = SceneRecordV5Ref { layers: &record.layers, materials: &record.materials, view: &record.view };
        let payload = postcard::to_allocvec(&v5).map_err(|e| SceneFileError::Payload(e.to_string()))?;
        return Ok(frame(5, payload));
    }
    let payload = postcard::to_allocvec(record).map_err(|e| SceneFileError::Payload(e.to_string()))?;
    Ok(frame(VERSION, payload))
}

/// [`SceneRecordV5`] by reference, to write.
#[derive(Serialize)]
struct SceneRecordV5Ref<'a> {
    layers: &'a [LayerRecord],
    materials: &'a [Material],
    view: &'a View,
}

/// A version 5 file of `scene` as the builds before reference images wrote it (its references
/// left out), for tests of the reader.
#[doc(hidden)]
pub fn encode_version_5(scene: &Scene) -> Result<Vec<u8>, SceneFileError> {
    let record = scene_record(scene, false)?;
    let v5 = SceneRecordV5 { layers: record.layers, materials: record.materials, view: record.view };
    let payload = postcard::to_allocvec(&v5).map_err(|e| SceneFileError::Payload(e.to_string()))?;
    Ok(frame(5, payload))
}

/// A version 4 file of `scene` as the builds before masks wrote it (its masks left out), for
/// tests of the reader.
#[doc(hidden)]
pub fn encode_version_4(scene: &Scene) -> Result<Vec<u8>, SceneFileError> {
    let record = scene_record(scene, false)?;
    let layers = record
        .layers
        .into_iter()
        .map(|l| LayerRecordV4 {
            name: l.name,
            transform: l.transform,
            visible: l.visible,
            locked: l.locked,
            level: l.level,
            cell_size: l.cell_size,
            solid: l.solid,
            lists: l.lists,
            materials: l.materials,
        })
        .collect();
    let v4 = SceneRecordV4 { layers, materials: record.materials, view: record.view };
    let payload = postcard::to_allocvec(&v4).map_err(|e| SceneFileError::Payload(e.to_string()))?;
    Ok(frame(4, payload))
}

/// The header for `payload` of format `version`, then the payload.
fn frame(version: u32, payload: Vec<u8>) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    out
}

/// The scene in `bytes`, with whatever had to be repaired (see the module docs).
pub fn decode(bytes: &[u8]) -> Result<Loaded, SceneFileError> {
    decode_with(bytes, true)
}

/// [`decode`] for a shared room's snapshot: reference images, which a snapshot never holds,
/// are skipped without decoding their pictures (an untrusted snapshot cannot make its reader
/// decode pictures).
pub fn decode_shared(bytes: &[u8]) -> Result<Loaded, SceneFileError> {
    decode_with(bytes, false)
}

fn decode_with(bytes: &[u8], with_references: bool) -> Result<Loaded, SceneFileError> {
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
    let parse_err =
        |e: postcard::Error| if intact { SceneFileError::Payload(e.to_string()) } else { SceneFileError::Checksum };
    let damaged = "the file's checksum does not match: it was damaged after it was written; every chunk was checked against its own checksum, but layer names, transforms and settings could not be verified";
    let (mut scene, fills) = match version {
        2 => {
            // One postcard value: nothing to recover from a damaged one.
            if !intact {
                return Err(SceneFileError::Checksum);
            }
            let v2: SceneV2 = postcard::from_bytes(payload).map_err(|e| SceneFileError::Payload(e.to_string()))?;
            let fills = v2.layers.iter().map(|l| Some(l.material)).collect();
            let layers = v2
                .layers
                .into_iter()
                .map(|l| {
                    let ChunksV2 { lists, solid } = l.volume.chunks;
                    let entries = solid.into_iter().map(|k| (k, Chunk::Solid)).chain(lists);
                    let chunks = resolve_chunks(&l.name, entries, &mut report);
                    let volume = Volume::from_chunks(l.volume.level, l.volume.cell_size, chunks).ok_or_else(|| {
                        SceneFileError::Payload(format!("layer {:?}: cell size not finite and positive", l.name))
                    })?;
                    Ok(Layer { name: l.name, transform: l.transform, visible: l.visible, locked: l.locked, volume })
                })
                .collect::<Result<Vec<Layer>, SceneFileError>>()?;
            let materials = v2.materials.into_iter().map(material_v3).collect();
            (Scene { layers, materials, view: v2.view, references: Vec::new() }, fills)
        }
        3 => {
            let record: SceneRecordV3 = postcard::from_bytes(payload).map_err(parse_err)?;
            if !intact {
                report.repairs.push(damaged.into());
            }
            let fills = record.layers.iter().map(|l| Some(l.material)).collect();
            let layers = record
                .layers
                .into_iter()
                .map(|l| LayerRecord {
                    name: l.name,
                    transform: l.transform,
                    visible: l.visible,
                    locked: l.locked,
                    level: l.level,
                    cell_size: l.cell_size,
                    solid: l.solid,
                    lists: l.lists,
                    materials: Vec::new(),
                    mask_outside: 0,
                    masks: Vec::new(),
                })
                .collect();
            let materials = record.materials.into_iter().map(material_v3).collect();
            let record = SceneRecord { layers, materials, view: record.view, references: Vec::new() };
            (scene_from_record(record, &mut report), fills)
        }
        4 => {
            let record: SceneRecordV4 = postcard::from_bytes(payload).map_err(parse_err)?;
            if !intact {
                report.repairs.push(damaged.into());
            }
            let fills = vec![None; record.layers.len()];
            let layers = record
                .layers
                .into_iter()
                .map(|l| LayerRecord {
                    name: l.name,
                    transform: l.transform,
                    visible: l.visible,
                    locked: l.locked,
                    level: l.level,
                    cell_size: l.cell_size,
                    solid: l.solid,
                    lists: l.lists,
                    materials: l.materials,
                    mask_outside: 0,
                    masks: Vec::new(),
                })
                .collect();
            let record = SceneRecord { layers, materials: record.materials, view: record.view, references: Vec::new() };
            (scene_from_record(record, &mut report), fills)
        }
        5 => {
            let record: SceneRecordV5 = postcard::from_bytes(payload).map_err(parse_err)?;
            if !intact {
                report.repairs.push(damaged.into());
            }
            let fills = vec![None; record.layers.len()];
            let record = SceneRecord {
                layers: record.layers,
                materials: record.materials,
                view: record.view,
                references: Vec::new(),
            };
            (scene_from_record(record, &mut report), fills)
        }
        _ => {
            let mut record: SceneRecord = postcard::from_bytes(payload).map_err(parse_err)?;
            if !intact {
                report.repairs.push(damaged.into());
            }
            if !with_references && !record.references.is_empty() {
                report.repairs.push(format!(
                    "{} reference images in a shared snapshot were left out (references are each person's own)",
                    record.references.len()
                ));
                record.references.clear();
            }
            let fills = vec![None; record.layers.len()];
            (scene_from_record(record, &mut report), fills)
        }
    };
    // Versions 2 and 3: each layer's one material becomes its nodes'.
    for (l, fill) in scene.layers.iter_mut().zip(fills) {
        let Some(m) = fill else { continue };
        let count = scene.materials.len().max(1);
        let m = if (m as usize) < count {
            m as u8
        } else {
            report.repairs.push(format!("layer {:?}: material {m} does not exist; it uses material 0", l.name));
            0
        };
        l.volume.fill_materials(m);
    }
    for l in &scene.layers {
        if let Some(id) = l.volume.max_material()
            && id as usize >= scene.materials.len().max(1)
        {
            return Err(SceneFileError::UnknownMaterial { layer: l.name.clone(), id, count: scene.materials.len() });
        }
    }
    report.repairs.extend(validate_scene(&mut scene).repairs);
    Ok(Loaded { scene, report, version })
}

fn material_v3(m: MaterialV3) -> Material {
    Material::new(m.name, m.color, crate::scene::Texture::Plain)
}

fn scene_from_record(record: SceneRecord, report: &mut LoadReport) -> Scene {
    let mut layers = Vec::with_capacity(record.layers.len());
    for l in record.layers {
        let name = l.name;
        let level =
            i8::try_from(l.level).ok().and_then(Level::new).filter(|l| *l >= Level::BASE).unwrap_or_else(|| {
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
        let mut entries: Vec<(ChunkKey, Chunk)> = l.solid.into_iter().map(|k| (k, Chunk::Solid)).collect();
        // Each chunk's checksum and decoding on every core; what they found is taken in file order.
        let decoded: Vec<Result<(ChunkKey, ChunkLists), String>> = l
            .lists
            .into_par_iter()
            .with_min_len(64)
            .map(|c| {
                let (x, y, z) = (c.key.0.x, c.key.0.y, c.key.0.z);
                if crc32fast::hash(&c.bytes) != c.crc {
                    return Err(format!("layer {name:?}: chunk ({x}, {y}, {z}) failed its checksum and was dropped"));
                }
                postcard::from_bytes::<ChunkLists>(&c.bytes)
                    .map(|lists| (c.key, lists))
                    .map_err(|e| format!("layer {name:?}: chunk ({x}, {y}, {z}) does not decode ({e}) and was dropped"))
            })
            .collect();
        entries.reserve(decoded.len());
        for d in decoded {
            match d {
                Ok((key, lists)) => entries.push((key, Chunk::Lists(lists))),
                Err(why) => report.repairs.push(why),
            }
        }
        let chunks = resolve_chunks(&name, entries, report);
        let mut volume = Volume::from_chunks(level, cell_size, chunks).expect("cell size checked");
        // Materials are checked against their chunk, now that the chunks and the level (which
        // sizes a uniform chunk's materials) are in place.
        let mut with_materials = HashSet::new();
        for c in l.materials {
            let (x, y, z) = (c.key.0.x, c.key.0.y, c.key.0.z);
            if crc32fast::hash(&c.bytes) != c.crc {
                report.repairs.push(format!(
                    "layer {name:?}: the materials of chunk ({x}, {y}, {z}) failed their checksum; its nodes use material 0"
                ));
                continue;
            }
            let m = match postcard::from_bytes::<ChunkMaterials>(&c.bytes) {
                Ok(m) => m,
                Err(e) => {
                    report.repairs.push(format!(
                        "layer {name:?}: the materials of chunk ({x}, {y}, {z}) do not decode ({e}); its nodes use material 0"
                    ));
                    continue;
                }
            };
            if !with_materials.insert(c.key) {
                report.repairs.push(format!(
                    "layer {name:?}: the materials of chunk ({x}, {y}, {z}) are stored more than once; the first record was read and a later one dropped"
                ));
            } else if volume.chunk(c.key).is_none() {
                report.repairs.push(format!(
                    "layer {name:?}: materials are stored for chunk ({x}, {y}, {z}), which is empty; they were dropped"
                ));
            } else if let Err(e) = volume.check_chunk_materials(c.key, &m) {
                report.repairs.push(format!(
                    "layer {name:?}: the materials of chunk ({x}, {y}, {z}) do not fit it ({e}) and were dropped; its nodes use material 0"
                ));
            } else {
                volume.set_chunk_materials(c.key, Some(m));
            }
        }
        // The mask: a damaged chunk of it is dropped (its nodes take the outside weight), and
        // the report says so (a mask protects work: losing part of it must not go unsaid).
        let mut mask_chunks: Vec<(ChunkKey, ChunkMask)> = Vec::new();
        let mut mask_keys: HashSet<ChunkKey> = HashSet::new();
        for c in l.masks {
            let (x, y, z) = (c.key.0.x, c.key.0.y, c.key.0.z);
            let m = if crc32fast::hash(&c.bytes) != c.crc {
                Err("failed its checksum".to_owned())
            } else {
                postcard::from_bytes::<ChunkMask>(&c.bytes).map_err(|e| format!("does not decode ({e})"))
            };
            match m {
                Err(why) => report.repairs.push(format!(
                    "layer {name:?}: the mask of chunk ({x}, {y}, {z}) {why} and was dropped; check what it protected"
                )),
                Ok(_) if !mask_keys.insert(c.key) => report.repairs.push(format!(
                    "layer {name:?}: the mask of chunk ({x}, {y}, {z}) is stored more than once; the first record was read"
                )),
                Ok(m) => mask_chunks.push((c.key, m)),
            }
        }
        volume.set_mask(strata_volume::Mask::from_parts(l.mask_outside, mask_chunks));
        layers.push(Layer { name, transform: l.transform, visible: l.visible, locked: l.locked, volume });
    }
    let mut references = Vec::with_capacity(record.references.len().min(MAX_REFERENCES));
    if record.references.len() > MAX_REFERENCES {
        report.repairs.push(format!(
            "the scene had {} reference images; those past the {MAX_REFERENCES}th were dropped unread",
            record.references.len()
        ));
    }
    for r in record.references.into_iter().take(MAX_REFERENCES) {
        let picture = if crc32fast::hash(&r.bytes) != r.crc {
            Err("failed its checksum".to_owned())
        } else {
            Picture::decode(r.bytes, &r.name).map_err(|e| format!("does not decode ({e})"))
        };
        match picture {
            Err(why) => {
                report.repairs.push(format!("reference image {:?}: its picture {why} and it was dropped", r.name))
            }
            Ok(picture) => references.push(ReferenceImage {
                name: r.name,
                picture,
                center: r.center,
                rotation: r.rotation,
                width: r.width,
                opacity: r.opacity,
                visible: r.visible,
                locked: r.locked,
            }),
        }
    }
    Scene { layers, materials: record.materials, view: record.view, references }
}

/// The chunks of layer `name`, one per key, from `entries` as the file lists them. A key stored
/// more than once keeps its first chunk of lists (a solid entry says only that every node is
/// inside; Strata never writes both), or else one solid entry; every entry dropped is reported,
/// one sentence per key, in the order the keys first appear.
fn resolve_chunks(
    name: &str,
    entries: impl IntoIterator<Item = (ChunkKey, Chunk)>,
    report: &mut LoadReport,
) -> Vec<(ChunkKey, Chunk)> {
    /// Entries dropped at one key.
    #[derive(Default)]
    struct Dropped {
        solid: usize,
        same_lists: usize,
        other_lists: usize,
        lists_seen: usize,
    }
    let mut chunks: Vec<(ChunkKey, Chunk)> = Vec::new();
    let mut dropped: Vec<Dropped> = Vec::new();
    let mut slot: HashMap<ChunkKey, usize> = HashMap::new();
    for (key, chunk) in entries {
        match slot.entry(key) {
            hash_map::Entry::Vacant(e) => {
                e.insert(chunks.len());
                dropped.push(Dropped { lists_seen: matches!(chunk, Chunk::Lists(_)) as usize, ..Default::default() });
                chunks.push((key, chunk));
            }
            hash_map::Entry::Occupied(e) => {
                let (kept, d) = (&mut chunks[*e.get()].1, &mut dropped[*e.get()]);
                match chunk {
                    Chunk::Solid => d.solid += 1,
                    Chunk::Lists(lists) => {
                        d.lists_seen += 1;
                        match kept {
                            Chunk::Solid => {
                                d.solid += 1;
                                *kept = Chunk::Lists(lists);
                            }
                            Chunk::Lists(first) if *first == lists => d.same_lists += 1,
                            Chunk::Lists(_) => d.other_lists += 1,
                        }
                    }
                }
            }
        }
    }
    for ((key, kept), d) in chunks.iter().zip(&dropped) {
        let total = 1 + d.solid + d.same_lists + d.other_lists;
        if total == 1 {
            continue;
        }
        let (x, y, z) = (key.0.x, key.0.y, key.0.z);
        let kept = match kept {
            Chunk::Solid => "one solid entry was kept",
            Chunk::Lists(_) if d.lists_seen > 1 => "the first of its lists was kept",
            Chunk::Lists(_) => "its lists were kept",
        };
        let count = |n: usize, one: &str, many: &str| match n {
            0 => None,
            1 => Some(format!("1 {one}")),
            n => Some(format!("{n} {many}")),
        };
        let parts: Vec<String> = [
            count(d.solid, "solid entry", "solid entries"),
            count(d.same_lists, "identical copy of the lists", "identical copies of the lists"),
            count(d.other_lists, "different chunk of lists", "different chunks of lists"),
        ]
        .into_iter()
        .flatten()
        .collect();
        report.repairs.push(format!(
            "layer {name:?}: chunk ({x}, {y}, {z}) is stored {total} times; {kept} and {} dropped",
            parts.join(" and ")
        ));
    }
    chunks
}

/// Reads the scene at `path` (a regular file of at most [`MAX_SCENE_BYTES`]), repairing what it
/// can. On error nothing else changes.
pub fn load(path: &Path) -> Result<Loaded, SceneFileError> {
    let bytes = strata_files::read_limited(path, MAX_SCENE_BYTES)?;
    decode(&bytes)
}

/// Writes `scene` to `path` atomically and durably (see the module docs). Whatever validation
/// would refuse is repaired in the written copy, and the returned report lists it (`scene`
/// itself is not changed: call [`validate_scene`] on it to make it match the file).
pub fn save(scene: &Scene, path: &Path) -> Result<LoadReport, SceneFileError> {
    // The full check and the encoding run side by side: a valid scene (nearly every one) is
    // written as encoded; an invalid one's encoding is dropped and its repaired copy encoded.
    let (valid, encoded) = rayon::join(|| is_valid(scene), || encode(scene));
    let (bytes, report) = if valid {
        (encoded?, LoadReport::default())
    } else {
        drop(encoded);
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
        && scene.materials.len() <= strata_volume::MATERIAL_IDS
        && scene.materials.iter().all(Material::is_valid)
        && scene.layers.iter().all(|l| {
            l.transform.is_valid()
                && l.volume.max_material().is_none_or(|m| (m as usize) < scene.materials.len())
                && l.volume.check_invariants().is_ok()
        })
        && v.target.is_finite()
        && v.distance.is_finite()
        && v.distance > 0.0
        && v.yaw.is_finite()
        && v.pitch.is_finite()
        && scene.references.len() <= MAX_REFERENCES
        && scene.references.iter().all(ReferenceImage::is_valid)
}

pub use strata_files::{stale_temp_files, temp_path};

/// Writes through `write` into a temporary file beside `path`, syncs it, renames it over `path`
/// and syncs the folder ([`strata_files::write_atomically`], which every file Strata writes
/// goes through). If anything fails, the temporary file is removed and `path` is
/// untouched.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> Result<(), SceneFileError> {
    Ok(strata_files::write_atomically::<io::Error>(path, write)?)
}

/// The digest of one chunk of one layer: a CRC-32 of its lists as a scene file stores them (0
/// for a solid chunk) and one of its materials (0 for none). Two scenes whose digests are
/// equal hold the same bytes, up to CRC collisions: how collaborating editors compare their
/// volumes without sending them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ChunkDigest {
    /// The layer.
    pub layer: u32,
    /// The chunk.
    pub key: [i32; 3],
    /// The lists' CRC (0: solid).
    pub lists: u32,
    /// The materials' CRC (0: none stored).
    pub materials: u32,
}

/// The digest of every stored chunk of `scene` (list, solid or material), by layer and key: the same scene always gives the same digests.
pub fn chunk_digests(scene: &Scene) -> Result<Vec<ChunkDigest>, SceneFileError> {
    let record = scene_record(scene, false)?;
    let mut out = Vec::new();
    for (layer, l) in record.layers.iter().enumerate() {
        let layer = layer as u32;
        let mut by_key = std::collections::BTreeMap::new();
        let blank = |k: ChunkKey| ChunkDigest { layer, key: k.0.to_array(), lists: 0, materials: 0 };
        for &k in &l.solid {
            by_key.entry(k).or_insert(blank(k));
        }
        for c in &l.lists {
            by_key.entry(c.key).or_insert(blank(c.key)).lists = c.crc;
        }
        for c in &l.materials {
            by_key.entry(c.key).or_insert(blank(c.key)).materials = c.crc;
        }
        out.extend(by_key.into_values());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The records as every earlier build wrote them: bytes as a plain sequence of `u8`.
    #[derive(Serialize, Deserialize, PartialEq, Debug)]
    struct PlainRecord {
        key: ChunkKey,
        crc: u32,
        bytes: Vec<u8>,
    }

    #[test]
    fn chunk_bytes_as_a_byte_string_are_the_bytes_written_before() {
        for len in [0usize, 1, 127, 128, 300, 70_000] {
            let bytes: Vec<u8> = (0..len).map(|i| (i * 37 % 251) as u8).collect();
            let key = ChunkKey::new(-3, 7, 1 << 20);
            let record = ChunkRecord::new(key, bytes.clone());
            let plain = PlainRecord { key, crc: record.crc, bytes };
            let written = postcard::to_allocvec(&record).unwrap();
            assert_eq!(written, postcard::to_allocvec(&plain).unwrap(), "{len} bytes");
            let read: ChunkRecord = postcard::from_bytes(&written).unwrap();
            assert_eq!((read.key, read.crc, &read.bytes), (plain.key, plain.crc, &plain.bytes));
            // A record cut short is an error, not a panic.
            if len > 0 {
                assert!(postcard::from_bytes::<ChunkRecord>(&written[..written.len() - 1]).is_err());
            }
        }
    }
}
