//! The volume: a sparse map from chunk keys to chunks.

use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};

use crate::chunk::{Chunk, ChunkView};
use crate::coords::{ChunkKey, Level};

/// A small, fast hasher for chunk keys (multiply-rotate, as in rustc's FxHash).
#[derive(Clone, Copy, Debug, Default)]
pub struct KeyHasher(u64);

impl Hasher for KeyHasher {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }

    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }

    #[inline]
    fn write_u32(&mut self, i: u32) {
        self.write_u64(i as u64);
    }

    #[inline]
    fn write_i32(&mut self, i: i32) {
        self.write_u64(i as u32 as u64);
    }

    #[inline]
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

pub(crate) type Hash = BuildHasherDefault<KeyHasher>;

/// The every-solid chunk, for references into [`ChunkMap`].
static SOLID: Chunk = Chunk::Solid;

/// The chunks of a volume: a map from key to crossing lists, and a set of the keys of all-solid
/// chunks. Solid chunks are most of a large converted model (46,111 of 59,150 chunks for the
/// bunny at 1,024 cells), so keeping them as bare keys (12 bytes a slot) instead of map entries
/// (24 bytes) halves the map's memory there. Keys in neither are all empty.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "RawChunkMap")]
pub struct ChunkMap {
    lists: HashMap<ChunkKey, Chunk, Hash>,
    solid: HashSet<ChunkKey, Hash>,
    /// List chunks stored at each level (derived, kept by `insert` and `remove`).
    #[serde(skip)]
    levels: [u32; crate::coords::LEVEL_COUNT],
}

/// Unchecked deserialised form of [`ChunkMap`].
#[derive(serde::Deserialize)]
struct RawChunkMap {
    lists: HashMap<ChunkKey, Chunk, Hash>,
    solid: HashSet<ChunkKey, Hash>,
}

impl TryFrom<RawChunkMap> for ChunkMap {
    type Error = String;

    fn try_from(r: RawChunkMap) -> Result<Self, String> {
        if r.lists.values().any(|c| matches!(c, Chunk::Solid)) {
            return Err("a solid chunk stored among the list chunks".into());
        }
        if r.solid.iter().any(|k| r.lists.contains_key(k)) {
            return Err("a chunk stored both as lists and as solid".into());
        }
        let mut levels = [0; crate::coords::LEVEL_COUNT];
        for c in r.lists.values() {
            if let Chunk::Lists(l) = c {
                levels[l.level().index()] += 1;
            }
        }
        Ok(ChunkMap { lists: r.lists, solid: r.solid, levels })
    }
}

impl ChunkMap {
    /// A map holding `chunks` (later entries replace earlier ones with the same key).
    pub fn from_chunks(chunks: impl IntoIterator<Item = (ChunkKey, Chunk)>) -> Self {
        let mut m = ChunkMap::default();
        for (k, c) in chunks {
            m.insert(k, c);
        }
        m
    }

    /// The chunk at `key` (`None`: all empty).
    #[inline]
    pub fn get(&self, key: &ChunkKey) -> Option<&Chunk> {
        self.lists.get(key).or_else(|| self.solid.contains(key).then_some(&SOLID))
    }

    /// Whether `key` holds anything.
    #[inline]
    pub fn contains_key(&self, key: &ChunkKey) -> bool {
        self.lists.contains_key(key) || self.solid.contains(key)
    }

    /// Stores `chunk` at `key`; returns what was there.
    pub fn insert(&mut self, key: ChunkKey, chunk: Chunk) -> Option<Chunk> {
        let old = self.remove(&key);
        match chunk {
            Chunk::Solid => {
                self.solid.insert(key);
            }
            lists => {
                if let Chunk::Lists(l) = &lists {
                    self.levels[l.level().index()] += 1;
                }
                self.lists.insert(key, lists);
            }
        }
        old
    }

    /// Empties `key`; returns what was there.
    pub fn remove(&mut self, key: &ChunkKey) -> Option<Chunk> {
        match self.lists.remove(key) {
            Some(c) => {
                if let Chunk::Lists(l) = &c {
                    self.levels[l.level().index()] -= 1;
                }
                Some(c)
            }
            None => self.solid.remove(key).then_some(Chunk::Solid),
        }
    }

    /// How many list chunks are stored at each level (index: [`crate::Level::index`], coarsest first).
    pub fn level_counts(&self) -> [u32; crate::coords::LEVEL_COUNT] {
        self.levels
    }

    /// Every stored key.
    pub fn keys(&self) -> impl Iterator<Item = &ChunkKey> {
        self.lists.keys().chain(self.solid.iter())
    }

    /// Every stored chunk.
    pub fn iter(&self) -> impl Iterator<Item = (&ChunkKey, &Chunk)> {
        self.lists.iter().chain(self.solid.iter().map(|k| (k, &SOLID)))
    }

    /// Every stored chunk's data.
    pub fn values(&self) -> impl Iterator<Item = &Chunk> {
        self.iter().map(|(_, c)| c)
    }

    /// Stored chunks.
    pub fn len(&self) -> usize {
        self.lists.len() + self.solid.len()
    }

    /// Whether nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.lists.is_empty() && self.solid.is_empty()
    }

    /// Bytes of the two hash tables (from their capacities).
    pub fn table_bytes(&self) -> usize {
        crate::memory::hash_table_bytes(self.lists.capacity(), std::mem::size_of::<(ChunkKey, Chunk)>())
            + crate::memory::hash_table_bytes(self.solid.capacity(), std::mem::size_of::<ChunkKey>())
    }
}

impl<'a> IntoIterator for &'a ChunkMap {
    type Item = (&'a ChunkKey, &'a Chunk);
    type IntoIter = Box<dyn Iterator<Item = (&'a ChunkKey, &'a Chunk)> + 'a>;
    fn into_iter(self) -> Self::IntoIter {
        Box::new(self.iter())
    }
}

/// A solid stored as crossing lists on the grid lines of sparse 16³-cell chunks.
///
/// Coordinates are grid units (one unit per base cell); `cell_size` converts them to world units
/// for consumers. Chunks not in the map are empty; all-solid chunks are stored as
/// [`Chunk::Solid`]; every other chunk holds [`crate::ChunkLists`].
///
/// Deserialisation checks the structure of every chunk and that the cell size is finite and
/// positive; whether the lists agree with each other is [`Volume::check_invariants`]'s to say
/// (and [`Volume::repair`]'s to fix).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "RawVolume")]
pub struct Volume {
    pub(crate) chunks: ChunkMap,
    /// Node materials of the chunks that have any other than 0 (see [`crate::material`]).
    pub(crate) materials: crate::material::MaterialMap,
    pub(crate) level: Level,
    pub(crate) cell_size: f64,
    /// What the tools may not change (see [`crate::mask`]).
    pub(crate) mask: crate::mask::Mask,
}

/// Unchecked deserialised form of [`Volume`].
#[derive(serde::Deserialize)]
struct RawVolume {
    chunks: ChunkMap,
    materials: crate::material::MaterialMap,
    level: Level,
    cell_size: f64,
    mask: crate::mask::Mask,
}

impl TryFrom<RawVolume> for Volume {
    type Error = String;

    fn try_from(r: RawVolume) -> Result<Self, String> {
        if !(r.cell_size.is_finite() && r.cell_size > 0.0) {
            return Err(format!("the cell size {} is not finite and positive", r.cell_size));
        }
        if let Some(k) = r.materials.keys().find(|k| !r.chunks.contains_key(k)) {
            return Err(format!("materials stored for the empty chunk {:?}", k.0.to_array()));
        }
        Ok(Volume { chunks: r.chunks, materials: r.materials, level: r.level, cell_size: r.cell_size, mask: r.mask })
    }
}

impl Default for Volume {
    fn default() -> Self {
        Self::new()
    }
}

impl Volume {
    /// An empty volume at the base level (16 cells per chunk side), cell size 1.
    pub fn new() -> Self {
        Self::with_level(Level::BASE)
    }

    /// An empty volume whose chunks are created at `level` (`16 · 2^level` cells per side). A
    /// volume's own level is at least [`Level::BASE`] (a coarser one is taken as the base
    /// level): coarser chunks are only ever lowered there for distance.
    pub fn with_level(level: Level) -> Self {
        Volume {
            chunks: ChunkMap::default(),
            materials: Default::default(),
            level: level.max(Level::BASE),
            cell_size: 1.0,
            mask: Default::default(),
        }
    }

    /// A volume holding exactly `chunks` (later entries replace earlier ones with the same key;
    /// solid chunks as [`Chunk::Solid`]), for loaders that read chunks one at a time. Nothing is
    /// checked: call [`Volume::check_invariants`] or [`Volume::repair`] before editing it.
    /// `None` if `cell_size` is not finite and positive, or `level` is coarser than
    /// [`Level::BASE`] (see [`Volume::with_level`]).
    pub fn from_chunks(
        level: Level,
        cell_size: f64,
        chunks: impl IntoIterator<Item = (ChunkKey, Chunk)>,
    ) -> Option<Self> {
        if !(cell_size.is_finite() && cell_size > 0.0) || level < Level::BASE {
            return None;
        }
        let mut v = Volume {
            chunks: ChunkMap::default(),
            materials: Default::default(),
            level,
            cell_size,
            mask: Default::default(),
        };
        for (key, chunk) in chunks {
            v.chunks.insert(key, chunk);
        }
        Some(v)
    }

    /// A volume of the same level and cell size holding chunks `keys` as they are here, with
    /// their materials (not the mask), for a reader on another thread: a mesher's snapshot of a
    /// chunk's neighbourhood. The chunks are shared, not copied ([`ChunkLists`] and material runs
    /// never change once made), so this allocates the two tables and nothing per chunk.
    pub fn share_chunks(&self, keys: impl IntoIterator<Item = ChunkKey>) -> Volume {
        let keys = keys.into_iter();
        let mut v = Volume {
            chunks: ChunkMap::default(),
            materials: Default::default(),
            level: self.level,
            cell_size: self.cell_size,
            mask: Default::default(),
        };
        v.chunks.lists.reserve(keys.size_hint().1.unwrap_or(0).min(64));
        for key in keys {
            if let Some(c) = self.chunks.get(&key) {
                v.chunks.insert(key, c.clone());
                if let Some(m) = self.materials.get(&key) {
                    v.materials.insert(key, m.clone());
                }
            }
        }
        v
    }

    /// The resolution level of new chunks.
    pub fn level(&self) -> Level {
        self.level
    }

    /// World units per base cell.
    pub fn cell_size(&self) -> f64 {
        self.cell_size
    }

    /// Sets the world size of a base cell; a size that is not finite and positive is refused
    /// (returned as the error) and the volume keeps its cell size.
    pub fn set_cell_size(&mut self, h: f64) -> Result<(), f64> {
        if h.is_finite() && h > 0.0 {
            self.cell_size = h;
            Ok(())
        } else {
            Err(h)
        }
    }

    /// The stored chunk at `key` (`None`: all empty).
    pub fn chunk(&self, key: ChunkKey) -> Option<&Chunk> {
        self.chunks.get(&key)
    }

    /// All stored chunks (not all empty), in no particular order.
    pub fn chunks(&self) -> impl Iterator<Item = (ChunkKey, &Chunk)> {
        self.chunks.iter().map(|(k, c)| (*k, c))
    }

    /// Number of stored chunks.
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// The box of all stored chunks in grid units (lower corner of the lowest chunk, upper corner
    /// of the highest), or `None` for an empty volume. Costs a pass over the chunk keys.
    pub fn chunk_bounds_grid(&self) -> Option<(glam::DVec3, glam::DVec3)> {
        let mut keys = self.chunks.keys();
        let first = keys.next()?.0;
        let (lo, hi) = keys.fold((first, first), |(lo, hi), k| (lo.min(k.0), hi.max(k.0)));
        let c = crate::coords::CHUNK_CELLS as f64;
        Some((lo.as_dvec3() * c, (hi.as_dvec3() + glam::DVec3::ONE) * c))
    }

    /// Whether nothing is inside.
    pub fn is_empty(&self) -> bool {
        self.chunks.is_empty()
    }

    /// Replaces chunk `key` and its materials (`None`: empty, material 0) and returns what was
    /// there, for pagers and generators that move whole chunks in and out of memory. Nothing is
    /// checked: the caller keeps neighbours consistent (a generator answering nodes by their
    /// absolute position does); [`Volume::check_invariants`] says whether they are.
    pub fn put_chunk(
        &mut self,
        key: ChunkKey,
        chunk: Option<Chunk>,
        materials: Option<crate::ChunkMaterials>,
    ) -> (Option<Chunk>, Option<crate::ChunkMaterials>) {
        let materials = if chunk.is_some() { materials } else { None };
        let old = match chunk {
            Some(c) => self.chunks.insert(key, c),
            None => self.chunks.remove(&key),
        };
        let old_materials = self.store_materials(key, materials);
        (old, old_materials)
    }

    /// Removes chunk `key` and its materials and returns them (see [`Volume::put_chunk`]).
    pub fn take_chunk(&mut self, key: ChunkKey) -> (Option<Chunk>, Option<crate::ChunkMaterials>) {
        self.put_chunk(key, None, None)
    }

    pub(crate) fn view(&self, key: ChunkKey) -> ChunkView<'_> {
        ChunkView::of(self.chunks.get(&key))
    }

    /// Whether every list chunk is stored at the volume's level (then no seam needs patching).
    pub fn single_level(&self) -> bool {
        let counts = self.chunks.level_counts();
        counts.iter().enumerate().all(|(k, &c)| c == 0 || k == self.level.index())
    }

    /// How many list chunks are stored at each level (index: [`Level::index`], coarsest first).
    pub fn level_counts(&self) -> [u32; crate::coords::LEVEL_COUNT] {
        self.chunks.level_counts()
    }

    /// The level of the list chunk at `key` (`None`: uniform or empty).
    pub fn stored_level(&self, key: ChunkKey) -> Option<Level> {
        match self.chunks.get(&key) {
            Some(Chunk::Lists(l)) => Some(l.level()),
            _ => None,
        }
    }

    /// The level of the chunk at `key` (uniform chunks report the volume's level).
    pub(crate) fn level_of(&self, key: ChunkKey) -> Level {
        match self.chunks.get(&key) {
            Some(Chunk::Lists(l)) => l.level(),
            _ => self.level,
        }
    }
}
