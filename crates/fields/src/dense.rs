//! The dense signed-distance baseline: an `f32` per node in 16³-node chunks.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::I64Vec3;
use strata_volume::brush::Brush;
use strata_volume::{ChunkKey, CsgOp, KeyHasher, VoxelBlock, hash_table_bytes};

use crate::{
    FieldError, N, NODES, PaddedValues, edit_chunks, edit_targets, edit_values, gather, index, neighbourhood, outside,
};

/// Nodes within this many cells of a brush's bounds are updated: the crossings next to the
/// brush interpolate fresh values, and so do the central differences that give their normals.
const MARGIN: f64 = 2.0;

/// The value of every node no edit has touched: far outside.
pub const FAR: f32 = 1.0e6;

type Map<V> = HashMap<ChunkKey, V, BuildHasherDefault<KeyHasher>>;

/// A signed distance per node (`f32`, negative inside), stored in 16³-node chunks allocated where
/// an edit reaches. Untouched nodes are [`FAR`] outside.
#[derive(Clone, Debug, Default)]
pub struct DenseField {
    chunks: Map<Box<[f32]>>,
}

impl DenseField {
    /// An empty field.
    pub fn new() -> Self {
        Self::default()
    }

    /// Bytes of one chunk's values.
    pub const CHUNK_BYTES: usize = NODES * std::mem::size_of::<f32>();

    /// Applies `brush` with `op` to every node within two cells of its bounds (intersection also
    /// empties every chunk beyond them) and returns the chunks whose values changed, sorted.
    pub fn apply<B: Brush + ?Sized>(&mut self, op: CsgOp, brush: &B) -> Result<Vec<ChunkKey>, FieldError> {
        let boxed = edit_chunks(brush, MARGIN)?;
        let mut changed = Vec::new();
        if op == CsgOp::Intersect {
            let gone: Vec<ChunkKey> = self.chunks.keys().copied().filter(|k| outside(k, boxed)).collect();
            for k in gone {
                self.chunks.remove(&k);
                changed.push(k);
            }
        }
        for (key, range) in edit_targets(op, brush.bounds(), boxed, MARGIN) {
            let values = match (op, self.chunks.get_mut(&key)) {
                (_, Some(v)) => v,
                // Subtracting from or intersecting with empty space changes nothing.
                (CsgOp::Subtract | CsgOp::Intersect, None) => continue,
                (CsgOp::Add, None) => self.chunks.entry(key).or_insert_with(|| vec![FAR; NODES].into()),
            };
            if edit_values(values, key, range, op, brush, None) {
                changed.push(key);
            }
        }
        changed.sort_by_key(|k| (k.0.z, k.0.y, k.0.x));
        Ok(changed)
    }

    /// The value at a global node.
    pub fn value(&self, node: I64Vec3) -> f32 {
        let n = N as i64;
        let key = node.div_euclid(I64Vec3::splat(n));
        let l = (node - key * n).as_uvec3();
        self.chunks.get(&ChunkKey(key.as_ivec3())).map_or(FAR, |c| c[index(l.x as usize, l.y as usize, l.z as usize)])
    }

    /// Whether a global node is inside (its value is `≤ 0`).
    pub fn node_inside(&self, node: I64Vec3) -> bool {
        self.value(node) <= 0.0
    }

    /// The voxel block of chunk `key`, using `scratch` for the gathered values.
    pub fn extract_block_into(&self, key: ChunkKey, scratch: &mut PaddedValues, out: &mut VoxelBlock) {
        let keys = neighbourhood(key);
        gather(scratch, FAR, |i| self.chunks.get(&keys[i]).map(|c| &c[..]));
        scratch.fill_block(key, out);
    }

    /// Chunks allocated.
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Bytes held: every chunk's values plus the chunk map's table (from its capacity).
    pub fn memory(&self) -> usize {
        self.chunks.len() * Self::CHUNK_BYTES
            + hash_table_bytes(self.chunks.capacity(), std::mem::size_of::<(ChunkKey, Box<[f32]>)>())
    }

    /// What a dense field allocating `chunks` chunks holds (values and a tightly sized map), for
    /// sizes too large to build.
    pub fn bytes_for_chunks(chunks: usize) -> usize {
        chunks * Self::CHUNK_BYTES + hash_table_bytes(chunks, std::mem::size_of::<(ChunkKey, Box<[f32]>)>())
    }

    /// Allocated chunk keys.
    pub fn keys(&self) -> impl Iterator<Item = ChunkKey> + '_ {
        self.chunks.keys().copied()
    }

    pub(crate) fn insert_chunk(&mut self, key: ChunkKey, values: Box<[f32]>) {
        self.chunks.insert(key, values);
    }
}
