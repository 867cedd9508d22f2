//! The volume: a sparse map from chunk keys to chunks.

use std::collections::HashMap;
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

/// The chunk map type.
pub type ChunkMap = HashMap<ChunkKey, Chunk, BuildHasherDefault<KeyHasher>>;

/// A solid stored as crossing lists on the grid lines of sparse 16³-cell chunks.
///
/// Coordinates are grid units (one unit per base cell); `cell_size` converts them to world units
/// for consumers. Chunks not in the map are empty; all-solid chunks are stored as
/// [`Chunk::Solid`]; every other chunk holds [`crate::ChunkLists`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Volume {
    pub(crate) chunks: ChunkMap,
    pub(crate) level: Level,
    pub(crate) cell_size: f64,
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

    /// An empty volume whose chunks are created at `level` (`16 << level` cells per side).
    pub fn with_level(level: Level) -> Self {
        Volume { chunks: ChunkMap::default(), level, cell_size: 1.0 }
    }

    /// The resolution level of new chunks.
    pub fn level(&self) -> Level {
        self.level
    }

    /// World units per base cell.
    pub fn cell_size(&self) -> f64 {
        self.cell_size
    }

    /// Sets the world size of a base cell (must be finite and positive; others are ignored).
    pub fn set_cell_size(&mut self, h: f64) {
        if h.is_finite() && h > 0.0 {
            self.cell_size = h;
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

    /// Whether nothing is inside.
    pub fn is_empty(&self) -> bool {
        self.chunks.is_empty()
    }

    pub(crate) fn view(&self, key: ChunkKey) -> ChunkView<'_> {
        ChunkView::of(self.chunks.get(&key))
    }

    /// The level of the chunk at `key` (uniform chunks report the volume's level).
    pub(crate) fn level_of(&self, key: ChunkKey) -> Level {
        match self.chunks.get(&key) {
            Some(Chunk::Lists(l)) => l.level(),
            _ => self.level,
        }
    }
}
