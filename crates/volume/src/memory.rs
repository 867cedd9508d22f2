//! Memory accounting from the real allocations.

use crate::chunk::Chunk;
use crate::volume::Volume;

/// Bytes held by a volume, by category. Every figure is the size of a live allocation
/// (capacity, not length): boxed slices are allocated exactly, and the chunk map's two tables
/// (list chunks, solid keys) are counted from their capacities using hashbrown's layout (one slot and one control byte per bucket, plus a
/// 16-byte control group).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryReport {
    /// Crossing positions (2 bytes each).
    pub positions: usize,
    /// Crossing normals (2 bytes each).
    pub normals: usize,
    /// Chunk headers (24 bytes a chunk at level 0), stored rows of nonempty-line bits and padding
    /// to whole words.
    pub headers: usize,
    /// The chunk map's tables.
    pub chunk_map: usize,
    /// Node materials: the material map's table and the chunks' runs (see
    /// [`crate::material`]; 0 for a volume of material 0 only).
    pub materials: usize,
    /// The mask: its table and its chunks' runs (see [`crate::mask`]; 0 for no mask).
    pub mask: usize,
    /// Crossings stored (not bytes).
    pub crossings: usize,
}

impl MemoryReport {
    /// All bytes.
    pub fn total(&self) -> usize {
        self.positions + self.normals + self.headers + self.chunk_map + self.materials + self.mask
    }

    /// All bytes except normals.
    pub fn without_normals(&self) -> usize {
        self.total() - self.normals
    }

    /// Bytes per stored crossing, with or without normals (0 when there are none).
    pub fn bytes_per_crossing(&self, with_normals: bool) -> f64 {
        if self.crossings == 0 {
            return 0.0;
        }
        let b = if with_normals { self.total() } else { self.without_normals() };
        b as f64 / self.crossings as f64
    }
}

/// Bytes of a hashbrown table of `capacity` usable slots holding `slot` bytes each.
pub fn hash_table_bytes(capacity: usize, slot: usize) -> usize {
    if capacity == 0 {
        return 0;
    }
    let buckets =
        if capacity < 8 { (capacity + 1).next_power_of_two() } else { (capacity * 8 / 7).next_power_of_two() };
    buckets * slot + buckets + 16
}

impl Volume {
    /// Bytes held, by category.
    pub fn memory(&self) -> MemoryReport {
        let mut r = MemoryReport {
            chunk_map: self.chunks.table_bytes(),
            materials: self.material_bytes(),
            mask: self.mask.heap_bytes(),
            ..Default::default()
        };
        for chunk in self.chunks.values() {
            if let Chunk::Lists(l) = chunk {
                let (all, c) = (l.heap_bytes(), l.crossing_bytes());
                r.positions += c;
                r.normals += c;
                r.headers += all - 2 * c;
                r.crossings += l.crossing_count();
            }
        }
        r
    }
}
