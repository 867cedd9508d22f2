//! The narrow-band baseline: signed distances clamped to ±b cells, each chunk run-length encoded.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::I64Vec3;
use strata_volume::brush::Brush;
use strata_volume::{ChunkKey, CsgOp, KeyHasher, VoxelBlock, hash_table_bytes};

use crate::{
    FieldError, N, NODES, PaddedValues, edit_chunks, edit_targets, edit_values, gather, index, neighbourhood, outside,
};

type Map<V> = HashMap<ChunkKey, V, BuildHasherDefault<KeyHasher>>;

const KIND_SHIFT: u32 = 14;
const COUNT_MASK: u16 = (1 << KIND_SHIFT) - 1;
const RUN_OUT: u16 = 0;
const RUN_IN: u16 = 1;
const LITERALS: u16 = 2;

/// One chunk's `16³` values, run-length encoded in node order (`x` fastest): each code is a run
/// of `+b` (outside the band), a run of `−b` (inside it), or a count of literal values in the
/// band, taken in order from `values`. Codes are `u16`: two bits of kind, fourteen of count.
#[derive(Clone, Debug, PartialEq)]
pub struct RleChunk {
    codes: Box<[u16]>,
    values: Box<[f32]>,
}

impl RleChunk {
    /// Encodes 4,096 values clamped to `±band`.
    pub fn encode(values: &[f32], band: f32) -> RleChunk {
        assert_eq!(values.len(), NODES, "a chunk has 16³ values");
        let mut codes: Vec<u16> = Vec::new();
        let mut lits: Vec<f32> = Vec::new();
        let mut i = 0;
        while i < NODES {
            let v = values[i];
            let kind = if v >= band {
                RUN_OUT
            } else if v <= -band {
                RUN_IN
            } else {
                LITERALS
            };
            let start = i;
            while i < NODES && {
                let w = values[i];
                match kind {
                    RUN_OUT => w >= band,
                    RUN_IN => w <= -band,
                    _ => w > -band && w < band,
                }
            } {
                i += 1;
            }
            if kind == LITERALS {
                lits.extend_from_slice(&values[start..i]);
            }
            codes.push((kind << KIND_SHIFT) | (i - start) as u16);
        }
        RleChunk { codes: codes.into_boxed_slice(), values: lits.into_boxed_slice() }
    }

    /// Decodes into `out` (4,096 values).
    pub fn decode(&self, band: f32, out: &mut [f32]) {
        let mut i = 0;
        let mut lit = 0;
        for &c in self.codes.iter() {
            let count = (c & COUNT_MASK) as usize;
            match c >> KIND_SHIFT {
                RUN_OUT => out[i..i + count].fill(band),
                RUN_IN => out[i..i + count].fill(-band),
                _ => {
                    out[i..i + count].copy_from_slice(&self.values[lit..lit + count]);
                    lit += count;
                }
            }
            i += count;
        }
    }

    /// The value of node `i` (node order) without decoding the rest.
    pub fn get(&self, band: f32, i: usize) -> f32 {
        let mut at = 0;
        let mut lit = 0;
        for &c in self.codes.iter() {
            let count = (c & COUNT_MASK) as usize;
            let kind = c >> KIND_SHIFT;
            if i < at + count {
                return match kind {
                    RUN_OUT => band,
                    RUN_IN => -band,
                    _ => self.values[lit + i - at],
                };
            }
            if kind == LITERALS {
                lit += count;
            }
            at += count;
        }
        band
    }

    /// Whether the chunk is one run of `+b` (empty: not stored).
    fn is_empty_run(&self) -> bool {
        self.codes.len() == 1 && self.codes[0] >> KIND_SHIFT == RUN_OUT
    }

    /// Bytes of this chunk's two allocations.
    pub fn bytes(&self) -> usize {
        self.codes.len() * 2 + self.values.len() * 4
    }

    /// Literal values stored (nodes inside the band).
    pub fn literal_count(&self) -> usize {
        self.values.len()
    }
}

/// Chunks an edit has decoded and modified, not yet re-encoded (see [`NarrowBandField::commit`]).
#[derive(Debug, Default)]
pub struct DecodedEdit {
    chunks: Vec<(ChunkKey, Box<[f32]>)>,
    removed: Vec<ChunkKey>,
}

impl DecodedEdit {
    /// Chunks decoded and changed.
    pub fn len(&self) -> usize {
        self.chunks.len() + self.removed.len()
    }

    /// Whether the edit changed nothing.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A narrow-band signed distance field: values clamped to `±b` cells, stored per 16³-node chunk
/// run-length encoded ([`RleChunk`]). Chunks that are all `+b` are not stored.
#[derive(Clone, Debug)]
pub struct NarrowBandField {
    band: f32,
    chunks: Map<RleChunk>,
    scratch: Vec<f32>,
}

impl NarrowBandField {
    /// An empty field of band half-width `band` cells.
    pub fn new(band: f32) -> Result<Self, FieldError> {
        if !(band.is_finite() && band > 0.0) {
            return Err(FieldError::BadBand(band));
        }
        Ok(NarrowBandField { band, chunks: Map::default(), scratch: vec![0.0; NODES] })
    }

    /// The band half-width in cells.
    pub fn band(&self) -> f32 {
        self.band
    }

    /// Decodes every chunk within `band` cells of the brush's bounds, applies the brush to the
    /// nodes there, and returns the changed chunks still decoded. Nothing is stored until
    /// [`NarrowBandField::commit`]; the split lets a benchmark time encoding apart.
    pub fn edit<B: Brush + ?Sized>(&self, op: CsgOp, brush: &B) -> Result<DecodedEdit, FieldError> {
        let margin = self.band as f64;
        let boxed = edit_chunks(brush, margin)?;
        let mut out = DecodedEdit::default();
        if op == CsgOp::Intersect {
            out.removed = self.chunks.keys().copied().filter(|k| outside(k, boxed)).collect();
        }
        for (key, range) in edit_targets(op, brush.bounds(), boxed, margin) {
            let existing = self.chunks.get(&key);
            if existing.is_none() && op != CsgOp::Add {
                continue;
            }
            let mut values: Box<[f32]> = vec![self.band; NODES].into();
            if let Some(c) = existing {
                c.decode(self.band, &mut values);
            }
            if edit_values(&mut values, key, range, op, brush, Some(self.band)) {
                out.chunks.push((key, values));
            }
        }
        Ok(out)
    }

    /// Re-encodes and stores the chunks of an edit (the paper's Time_RLE); returns the changed
    /// chunks, sorted.
    pub fn commit(&mut self, edit: DecodedEdit) -> Vec<ChunkKey> {
        let mut changed = edit.removed;
        for k in &changed {
            self.chunks.remove(k);
        }
        for (key, values) in edit.chunks {
            let c = RleChunk::encode(&values, self.band);
            if c.is_empty_run() {
                self.chunks.remove(&key);
            } else {
                self.chunks.insert(key, c);
            }
            changed.push(key);
        }
        changed.sort_by_key(|k| (k.0.z, k.0.y, k.0.x));
        changed
    }

    /// [`NarrowBandField::edit`] then [`NarrowBandField::commit`].
    pub fn apply<B: Brush + ?Sized>(&mut self, op: CsgOp, brush: &B) -> Result<Vec<ChunkKey>, FieldError> {
        let e = self.edit(op, brush)?;
        Ok(self.commit(e))
    }

    /// The value at a global node.
    pub fn value(&self, node: I64Vec3) -> f32 {
        let n = N as i64;
        let key = node.div_euclid(I64Vec3::splat(n));
        let l = (node - key * n).as_uvec3();
        self.chunks
            .get(&ChunkKey(key.as_ivec3()))
            .map_or(self.band, |c| c.get(self.band, index(l.x as usize, l.y as usize, l.z as usize)))
    }

    /// Whether a global node is inside (its value is `≤ 0`).
    pub fn node_inside(&self, node: I64Vec3) -> bool {
        self.value(node) <= 0.0
    }

    /// The voxel block of chunk `key`: decodes the chunk and its 26 neighbours into `scratch`.
    pub fn extract_block_into(&mut self, key: ChunkKey, scratch: &mut PaddedValues, out: &mut VoxelBlock) {
        let keys = neighbourhood(key);
        let mut decoded = std::mem::take(&mut self.scratch);
        decoded.resize(27 * NODES, 0.0);
        let mut present = [false; 27];
        for (i, k) in keys.iter().enumerate() {
            if let Some(c) = self.chunks.get(k) {
                c.decode(self.band, &mut decoded[i * NODES..(i + 1) * NODES]);
                present[i] = true;
            }
        }
        gather(scratch, self.band, |i| present[i].then(|| &decoded[i * NODES..(i + 1) * NODES]));
        scratch.fill_block(key, out);
        self.scratch = decoded;
    }

    /// Stored chunks.
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Literal values stored (nodes within the band).
    pub fn literal_count(&self) -> usize {
        self.chunks.values().map(RleChunk::literal_count).sum()
    }

    /// Bytes held: codes and literal values of every chunk (exact boxed-slice sizes) plus the
    /// chunk map's table (from its capacity).
    pub fn memory(&self) -> usize {
        self.chunks.values().map(RleChunk::bytes).sum::<usize>()
            + hash_table_bytes(self.chunks.capacity(), std::mem::size_of::<(ChunkKey, RleChunk)>())
    }

    pub(crate) fn insert_encoded(&mut self, key: ChunkKey, values: &[f32]) {
        let c = RleChunk::encode(values, self.band);
        if !c.is_empty_run() {
            self.chunks.insert(key, c);
        }
    }
}
