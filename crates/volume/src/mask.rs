//! Masks: a weight per grid node that every tool respects (0: free, [`PROTECTED`]: never
//! changed), stored beside the lists as runs along x, like the materials.
//!
//! A mask has one node per grid unit (the nodes of level 0, whatever the levels of the chunks
//! it covers); between nodes, at the nodes of finer chunks and along the lines, the weight is
//! the trilinear interpolation of the eight nodes around ([`MaskSampler::at`]), so a region
//! masked at both ends of an edge is masked along the whole edge.
//!
//! Storage: the weight of every node outside the stored chunks is the mask's `outside` weight
//! (0 for a new mask; [`PROTECTED`] after inverting an empty one), so inverting, clearing and
//! protecting everything are cheap on a volume of any size. A chunk `k` covers the nodes
//! `16 k .. 16 k + 16` on each axis (4,096 nodes, x-major: `i = x + 16 (y + 16 z)`):
//! - no entry: every node has the `outside` weight;
//! - [`ChunkMask::Uniform`]: every node has one other weight;
//! - [`ChunkMask::Runs`]: the change points as `(delta, weight)` pairs, the delta a LEB128
//!   varint of nodes since the previous change point (the first is 0, at node 0), each
//!   weight other than the one before, at least two of them.
//!
//! That form is canonical (deserialisation and every writer keep it): two masks with the same
//! weights store the same bytes.
//!
//! How the tools respect it (see `Volume::apply`, `Volume::write_region_with` and
//! `Volume::paint_where`): a CSG edit is made with the brush cut to the free part (nodes whose
//! weight is below one half), so a node at or above one half keeps its state and every edge
//! between two such nodes keeps its crossing; a field tool's change at a node is scaled by
//! `1 - weight` (a protected node is not handed to the tool at all); paint's share is scaled
//! the same way; a chunk with a node at or above one half is not lowered.

use std::collections::HashMap;

use glam::{DVec3, I64Vec3, IVec3};
use serde::{Deserialize, Serialize};

use crate::coords::{CHUNK_CELLS, ChunkKey};
use crate::volume::Hash;

/// A node's mask weight: 0 free, 255 ([`PROTECTED`]) never changed.
pub type MaskWeight = u8;

/// The weight of a node no tool changes.
pub const PROTECTED: MaskWeight = 255;

/// Nodes along one side of a chunk of the mask.
const N: usize = CHUNK_CELLS as usize;
/// Nodes in a chunk of the mask.
pub(crate) const MASK_NODES: usize = N * N * N;

/// The mask weights of one chunk's nodes (see the module docs).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "RawChunkMask")]
pub enum ChunkMask {
    /// Every node has this weight.
    Uniform(MaskWeight),
    /// Change points, `(varint delta, weight)` pairs.
    Runs(Box<[u8]>),
}

#[derive(Deserialize)]
enum RawChunkMask {
    Uniform(MaskWeight),
    Runs(Box<[u8]>),
}

impl TryFrom<RawChunkMask> for ChunkMask {
    type Error = String;

    fn try_from(r: RawChunkMask) -> Result<Self, String> {
        match r {
            RawChunkMask::Uniform(w) => Ok(ChunkMask::Uniform(w)),
            RawChunkMask::Runs(bytes) => {
                let mut count = 0;
                let mut at = 0usize;
                let mut last = None;
                let mut reader = Changes { bytes: &bytes, at: 0 };
                while let Some(entry) = reader.next_change()? {
                    let (delta, w) = entry;
                    if count == 0 && delta != 0 {
                        return Err("mask runs that do not start at the chunk's first node".into());
                    }
                    if count > 0 && delta == 0 {
                        return Err("two mask change points on one node".into());
                    }
                    at += delta;
                    if at >= MASK_NODES {
                        return Err("a mask change point beyond the chunk's nodes".into());
                    }
                    if last == Some(w) {
                        return Err("a mask change point that does not change the weight".into());
                    }
                    last = Some(w);
                    count += 1;
                }
                if count < 2 {
                    return Err("mask runs with fewer than two change points".into());
                }
                Ok(ChunkMask::Runs(bytes))
            }
        }
    }
}

/// Reads `(delta, weight)` pairs.
struct Changes<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Changes<'_> {
    fn next_change(&mut self) -> Result<Option<(usize, MaskWeight)>, String> {
        if self.at >= self.bytes.len() {
            return Ok(None);
        }
        let mut delta = 0usize;
        let mut shift = 0;
        loop {
            let Some(&b) = self.bytes.get(self.at) else {
                return Err("mask runs end inside a change point".into());
            };
            self.at += 1;
            if shift > 14 {
                return Err("a mask change point further than a chunk holds".into());
            }
            delta |= ((b & 0x7f) as usize) << shift;
            shift += 7;
            if b & 0x80 == 0 {
                break;
            }
        }
        let Some(&w) = self.bytes.get(self.at) else {
            return Err("mask runs end before a change point's weight".into());
        };
        self.at += 1;
        Ok(Some((delta, w)))
    }
}

fn push_varint(out: &mut Vec<u8>, mut v: usize) {
    while v >= 0x80 {
        out.push((v as u8 & 0x7f) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

impl ChunkMask {
    /// The canonical storage of `weights` (4,096, x-major) for a mask whose weight outside the
    /// stored chunks is `outside` (`None`: store nothing).
    pub fn encode(weights: &[MaskWeight], outside: MaskWeight) -> Option<ChunkMask> {
        debug_assert_eq!(weights.len(), MASK_NODES);
        let first = weights[0];
        if weights.iter().all(|&w| w == first) {
            return (first != outside).then_some(ChunkMask::Uniform(first));
        }
        let mut out = Vec::new();
        let mut last = 0usize;
        let mut current = None;
        for (i, &w) in weights.iter().enumerate() {
            if current != Some(w) {
                push_varint(&mut out, i - last);
                out.push(w);
                last = i;
                current = Some(w);
            }
        }
        Some(ChunkMask::Runs(out.into_boxed_slice()))
    }

    /// Writes the weights of every node into `out` (4,096, x-major).
    pub fn decode_into(&self, out: &mut [MaskWeight]) {
        debug_assert_eq!(out.len(), MASK_NODES);
        match self {
            ChunkMask::Uniform(w) => out.fill(*w),
            ChunkMask::Runs(bytes) => {
                let mut reader = Changes { bytes, at: 0 };
                let mut start = 0usize;
                let mut weight = 0;
                // (Checked when made or read: the entries are well formed.)
                while let Ok(Some((delta, w))) = reader.next_change() {
                    let at = (start + delta).min(MASK_NODES);
                    out[start..at].fill(weight);
                    start = at;
                    weight = w;
                }
                out[start..].fill(weight);
            }
        }
    }

    /// Heap bytes.
    pub fn heap_bytes(&self) -> usize {
        match self {
            ChunkMask::Uniform(_) => 0,
            ChunkMask::Runs(b) => b.len(),
        }
    }
}

/// A volume's mask (see the module docs).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawMask")]
pub struct Mask {
    outside: MaskWeight,
    chunks: HashMap<ChunkKey, ChunkMask, Hash>,
}

#[derive(Deserialize)]
struct RawMask {
    outside: MaskWeight,
    chunks: HashMap<ChunkKey, ChunkMask, Hash>,
}

impl TryFrom<RawMask> for Mask {
    type Error = String;

    fn try_from(r: RawMask) -> Result<Self, String> {
        if r.chunks.values().any(|c| *c == ChunkMask::Uniform(r.outside)) {
            return Err("a mask chunk stored with the weight of the nodes outside".into());
        }
        Ok(Mask { outside: r.outside, chunks: r.chunks })
    }
}

/// What takes a mask change back: the weight outside before it (if it changed) and the
/// previous storage of every chunk it changed.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MaskUndo {
    pub(crate) outside: Option<MaskWeight>,
    pub(crate) chunks: Vec<(ChunkKey, Option<ChunkMask>)>,
}

impl MaskUndo {
    /// Whether it restores nothing.
    pub fn is_empty(&self) -> bool {
        self.outside.is_none() && self.chunks.is_empty()
    }

    /// Heap bytes.
    pub fn heap_bytes(&self) -> usize {
        self.chunks.capacity() * std::mem::size_of::<(ChunkKey, Option<ChunkMask>)>()
            + self.chunks.iter().map(|(_, c)| c.as_ref().map_or(0, ChunkMask::heap_bytes)).sum::<usize>()
    }

    /// The chunks it restores.
    pub fn keys(&self) -> impl Iterator<Item = ChunkKey> + '_ {
        self.chunks.iter().map(|(k, _)| *k)
    }
}

/// The chunk holding node `p` and the node's index in it.
#[inline]
fn locate(p: I64Vec3) -> (ChunkKey, usize) {
    let n = CHUNK_CELLS;
    let k = p.div_euclid(I64Vec3::splat(n));
    let l = p - k * n;
    // (Nodes beyond the key range, which edits never reach, read the outermost chunks.)
    let k = k.clamp(I64Vec3::splat(i32::MIN as i64), I64Vec3::splat(i32::MAX as i64));
    (ChunkKey(IVec3::new(k.x as i32, k.y as i32, k.z as i32)), (l.x + n * (l.y + n * l.z)) as usize)
}

impl Mask {
    /// Whether every node is free (the mask has no effect).
    pub fn is_clear(&self) -> bool {
        self.outside == 0 && self.chunks.is_empty()
    }

    /// The weight of the nodes outside the stored chunks.
    pub fn outside(&self) -> MaskWeight {
        self.outside
    }

    /// The stored chunks.
    pub fn chunks(&self) -> impl Iterator<Item = (ChunkKey, &ChunkMask)> {
        self.chunks.iter().map(|(k, c)| (*k, c))
    }

    /// A mask from its parts (for loaders): chunks stored with the outside weight are
    /// dropped, so the result is canonical.
    pub fn from_parts(outside: MaskWeight, chunks: impl IntoIterator<Item = (ChunkKey, ChunkMask)>) -> Mask {
        let chunks = chunks.into_iter().filter(|(_, c)| *c != ChunkMask::Uniform(outside)).collect();
        Mask { outside, chunks }
    }

    /// Heap bytes of the stored chunks.
    pub fn heap_bytes(&self) -> usize {
        crate::memory::hash_table_bytes(self.chunks.capacity(), std::mem::size_of::<(ChunkKey, ChunkMask)>())
            + self.chunks.values().map(ChunkMask::heap_bytes).sum::<usize>()
    }

    /// The weight of grid node `p`.
    pub fn weight(&self, p: I64Vec3) -> MaskWeight {
        let (key, i) = locate(p);
        match self.chunks.get(&key) {
            None => self.outside,
            Some(ChunkMask::Uniform(w)) => *w,
            Some(c) => {
                let mut all = vec![0; MASK_NODES];
                c.decode_into(&mut all);
                all[i]
            }
        }
    }

    /// The weights of chunk `key` (4,096, x-major).
    pub(crate) fn decode_chunk(&self, key: ChunkKey, out: &mut [MaskWeight]) {
        match self.chunks.get(&key) {
            None => out.fill(self.outside),
            Some(c) => c.decode_into(out),
        }
    }

    /// Stores `weights` for chunk `key`; returns what was stored before.
    fn store(&mut self, key: ChunkKey, weights: &[MaskWeight]) -> Option<ChunkMask> {
        match ChunkMask::encode(weights, self.outside) {
            Some(c) => self.chunks.insert(key, c),
            None => self.chunks.remove(&key),
        }
    }

    /// Puts back what `undo` holds and returns the record that redoes the change.
    pub(crate) fn restore(&mut self, undo: MaskUndo) -> MaskUndo {
        let mut redo = MaskUndo { outside: None, chunks: Vec::with_capacity(undo.chunks.len()) };
        if let Some(o) = undo.outside {
            redo.outside = Some(self.outside);
            self.outside = o;
        }
        for (key, c) in undo.chunks {
            let now = match c {
                Some(c) => self.chunks.insert(key, c),
                None => self.chunks.remove(&key),
            };
            redo.chunks.push((key, now));
        }
        redo
    }

    /// Sets every node within `radius` of `center` (grid units) to `f(old weight, distance /
    /// radius, node)`; returns the undo record.
    pub(crate) fn modify_ball(
        &mut self,
        center: DVec3,
        radius: f64,
        mut f: impl FnMut(MaskWeight, f64, I64Vec3) -> MaskWeight,
    ) -> MaskUndo {
        let mut undo = MaskUndo::default();
        if !(center.is_finite() && radius.is_finite() && radius > 0.0) {
            return undo;
        }
        let lo = (center - DVec3::splat(radius)).ceil().as_i64vec3();
        let hi = (center + DVec3::splat(radius)).floor().as_i64vec3();
        let n = CHUNK_CELLS;
        let (klo, khi) = (lo.div_euclid(I64Vec3::splat(n)), hi.div_euclid(I64Vec3::splat(n)));
        let mut weights = vec![0; MASK_NODES];
        for kz in klo.z..=khi.z {
            for ky in klo.y..=khi.y {
                for kx in klo.x..=khi.x {
                    let key = ChunkKey(IVec3::new(kx as i32, ky as i32, kz as i32));
                    let base = I64Vec3::new(kx, ky, kz) * n;
                    self.decode_chunk(key, &mut weights);
                    let mut changed = false;
                    let (a, b) = ((lo - base).max(I64Vec3::ZERO), (hi - base).min(I64Vec3::splat(n - 1)));
                    for z in a.z..=b.z {
                        for y in a.y..=b.y {
                            for x in a.x..=b.x {
                                let p = base + I64Vec3::new(x, y, z);
                                let d = (p.as_dvec3() - center).length();
                                if d > radius {
                                    continue;
                                }
                                let i = (x + n * (y + n * z)) as usize;
                                let w = f(weights[i], d / radius, p);
                                changed |= w != weights[i];
                                weights[i] = w;
                            }
                        }
                    }
                    if changed {
                        let before = self.store(key, &weights);
                        undo.chunks.push((key, before));
                    }
                }
            }
        }
        undo
    }

    /// Applies `f` to every weight, outside and stored (it must map equal weights to equal
    /// weights); returns the undo record.
    pub(crate) fn map_all(&mut self, f: impl Fn(MaskWeight) -> MaskWeight) -> MaskUndo {
        let mut undo = MaskUndo::default();
        let outside = f(self.outside);
        if outside != self.outside {
            undo.outside = Some(self.outside);
            self.outside = outside;
        }
        let mut keys: Vec<ChunkKey> = self.chunks.keys().copied().collect();
        keys.sort();
        let mut weights = vec![0; MASK_NODES];
        for key in keys {
            let before = self.chunks.remove(&key).expect("listed");
            before.decode_into(&mut weights);
            weights.iter_mut().for_each(|w| *w = f(*w));
            if let Some(c) = ChunkMask::encode(&weights, self.outside) {
                self.chunks.insert(key, c);
            }
            undo.chunks.push((key, Some(before)));
        }
        undo
    }

    /// Sets every node to `weight`; returns the undo record.
    pub(crate) fn fill(&mut self, weight: MaskWeight) -> MaskUndo {
        let mut undo = MaskUndo::default();
        if self.outside != weight {
            undo.outside = Some(self.outside);
            self.outside = weight;
        }
        let mut chunks: Vec<(ChunkKey, ChunkMask)> = self.chunks.drain().collect();
        chunks.sort_by_key(|(k, _)| *k);
        undo.chunks = chunks.into_iter().map(|(k, c)| (k, Some(c))).collect();
        undo
    }

    /// Each node takes the largest (`grow`) or smallest weight of itself and its six face
    /// neighbours: the masked part grows or shrinks by one node. Returns the undo record.
    pub(crate) fn grow_or_shrink(&mut self, grow: bool) -> MaskUndo {
        // Only stored chunks and their neighbours can change (elsewhere every node and its
        // neighbours have the outside weight).
        let mut keys: Vec<ChunkKey> =
            self.chunks.keys().flat_map(|k| k.around()).collect::<std::collections::HashSet<_>>().into_iter().collect();
        keys.sort();
        let n = CHUNK_CELLS;
        let mut fresh = Vec::with_capacity(keys.len());
        let mut cache: HashMap<ChunkKey, Vec<MaskWeight>, Hash> = HashMap::default();
        let mut weight_at = |mask: &Mask, p: I64Vec3| -> MaskWeight {
            let (key, i) = locate(p);
            if !mask.chunks.contains_key(&key) {
                return mask.outside;
            }
            cache.entry(key).or_insert_with(|| {
                let mut w = vec![0; MASK_NODES];
                mask.decode_chunk(key, &mut w);
                w
            })[i]
        };
        for &key in &keys {
            let base = key.0.as_i64vec3() * n;
            let mut weights = vec![0; MASK_NODES];
            for z in 0..n {
                for y in 0..n {
                    for x in 0..n {
                        let p = base + I64Vec3::new(x, y, z);
                        let mut w = weight_at(self, p);
                        for d in [I64Vec3::X, I64Vec3::NEG_X, I64Vec3::Y, I64Vec3::NEG_Y, I64Vec3::Z, I64Vec3::NEG_Z] {
                            let v = weight_at(self, p + d);
                            w = if grow { w.max(v) } else { w.min(v) };
                        }
                        weights[(x + n * (y + n * z)) as usize] = w;
                    }
                }
            }
            fresh.push((key, weights));
        }
        let mut undo = MaskUndo::default();
        for (key, weights) in fresh {
            let before = self.chunks.get(&key).cloned();
            if ChunkMask::encode(&weights, self.outside) != before {
                self.store(key, &weights);
                undo.chunks.push((key, before));
            }
        }
        undo
    }

    /// A reader of the weights near `lo ..= hi` (grid units), or `None` where every node
    /// there, and one node around, is free (the mask changes nothing there).
    pub fn sampler(&self, lo: DVec3, hi: DVec3) -> Option<MaskSampler> {
        if self.is_clear() || !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let n = CHUNK_CELLS;
        let klo = lo.floor().as_i64vec3().saturating_sub(I64Vec3::ONE).div_euclid(I64Vec3::splat(n));
        let khi = hi.ceil().as_i64vec3().saturating_add(I64Vec3::ONE).div_euclid(I64Vec3::splat(n));
        let keys = (I64Vec3::splat(i32::MIN as i64), I64Vec3::splat(i32::MAX as i64));
        let (klo, khi) = (klo.clamp(keys.0, keys.1), khi.clamp(keys.0, keys.1));
        let span = khi.saturating_sub(klo).saturating_add(I64Vec3::ONE);
        let boxed = span.x.saturating_mul(span.y).saturating_mul(span.z);
        let mut chunks: HashMap<ChunkKey, Box<[MaskWeight]>, Hash> = HashMap::default();
        let inside = |k: &ChunkKey| {
            let k = k.0.as_i64vec3();
            k.cmpge(klo).all() && k.cmple(khi).all()
        };
        let decode = |c: &ChunkMask| {
            let mut w = vec![0; MASK_NODES].into_boxed_slice();
            c.decode_into(&mut w);
            w
        };
        if boxed as usize > self.chunks.len() {
            for (k, c) in &self.chunks {
                if inside(k) {
                    chunks.insert(*k, decode(c));
                }
            }
        } else {
            for kz in klo.z..=khi.z {
                for ky in klo.y..=khi.y {
                    for kx in klo.x..=khi.x {
                        let k = ChunkKey(IVec3::new(kx as i32, ky as i32, kz as i32));
                        if let Some(c) = self.chunks.get(&k) {
                            chunks.insert(k, decode(c));
                        }
                    }
                }
            }
        }
        if self.outside == 0 && chunks.is_empty() {
            return None;
        }
        let mut sampler = MaskSampler {
            outside: self.outside,
            chunks,
            origin: I64Vec3::ZERO,
            dims: I64Vec3::ZERO,
            dense: Vec::new(),
            rows: Default::default(),
        };
        // The nodes of the box (one around) in one array, where it is not too large: a lookup
        // is then an index, not a hash.
        let (a, b) =
            (lo.floor().as_i64vec3().saturating_sub(I64Vec3::ONE), hi.ceil().as_i64vec3().saturating_add(I64Vec3::ONE));
        let dims = b.saturating_sub(a).saturating_add(I64Vec3::ONE);
        let count = dims.x.saturating_mul(dims.y).saturating_mul(dims.z);
        if dims.min_element() > 0 && count <= DENSE_SAMPLER_NODES {
            let mut dense = vec![self.outside; count as usize];
            // Each decoded chunk's rows copied in (the rest keeps the outside weight).
            for (key, w) in &sampler.chunks {
                let base = key.origin_grid();
                let lo = (a - base).max(I64Vec3::ZERO);
                let hi = (b - base).min(I64Vec3::splat(n - 1));
                if lo.cmpgt(hi).any() {
                    continue;
                }
                for z in lo.z..=hi.z {
                    for y in lo.y..=hi.y {
                        let from = (lo.x + n * (y + n * z)) as usize;
                        let p = base + I64Vec3::new(lo.x, y, z) - a;
                        let to = (p.x + dims.x * (p.y + dims.y * p.z)) as usize;
                        let len = (hi.x - lo.x + 1) as usize;
                        dense[to..to + len].copy_from_slice(&w[from..from + len]);
                    }
                }
            }
            sampler.rows = row_ranges(&dense, dims);
            sampler.origin = a;
            sampler.dims = dims;
            sampler.dense = dense;
        }
        Some(sampler)
    }
}

/// The weights of a mask near an edit, decoded for reading (see [`Mask::sampler`]).
#[derive(Debug)]
pub struct MaskSampler {
    outside: MaskWeight,
    chunks: HashMap<ChunkKey, Box<[MaskWeight]>, Hash>,
    /// The first node of the dense box (see `dense`).
    origin: I64Vec3,
    /// Its nodes along each axis (zero: no dense box).
    dims: I64Vec3,
    /// The weights of the box's nodes, x-major, where the box is at most
    /// [`DENSE_SAMPLER_NODES`] nodes.
    dense: Vec<MaskWeight>,
    /// Per axis, the smallest and largest weight along each line of the dense box in that
    /// direction (indexed by the other two coordinates, the lower axis first).
    rows: [Vec<(MaskWeight, MaskWeight)>; 3],
}

/// The smallest and largest weight along every line of a dense box, per axis.
fn row_ranges(dense: &[MaskWeight], dims: I64Vec3) -> [Vec<(MaskWeight, MaskWeight)>; 3] {
    let d = dims.as_uvec3();
    let (nx, ny, nz) = (d.x as usize, d.y as usize, d.z as usize);
    let mut x = vec![(MaskWeight::MAX, 0); ny * nz];
    let mut y = vec![(MaskWeight::MAX, 0); nx * nz];
    let mut z = vec![(MaskWeight::MAX, 0); nx * ny];
    let widen = |r: &mut (MaskWeight, MaskWeight), w: MaskWeight| *r = (r.0.min(w), r.1.max(w));
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let w = dense[i + nx * (j + ny * k)];
                widen(&mut x[j + ny * k], w);
                widen(&mut y[i + nx * k], w);
                widen(&mut z[i + nx * j], w);
            }
        }
    }
    [x, y, z]
}

/// The most nodes a sampler keeps in one array (4 MiB).
const DENSE_SAMPLER_NODES: i64 = 1 << 22;

impl MaskSampler {
    /// The stored weight of node `p`, from the decoded chunks.
    #[inline]
    fn raw(&self, p: I64Vec3) -> MaskWeight {
        let (key, i) = locate(p);
        match self.chunks.get(&key) {
            None => self.outside,
            Some(c) => c[i],
        }
    }

    /// The weight of grid node `p`, 0 to 1.
    #[inline]
    pub fn node(&self, p: I64Vec3) -> f64 {
        let d = p - self.origin;
        let w = if d.cmpge(I64Vec3::ZERO).all() && d.cmplt(self.dims).all() {
            self.dense[(d.x + self.dims.x * (d.y + self.dims.y * d.z)) as usize]
        } else {
            self.raw(p)
        };
        w as f64 / PROTECTED as f64
    }

    /// The smallest and largest weight of the nodes on the grid line along `axis` through node
    /// `p` (its `axis` coordinate ignored), within the sampler's dense box; `None` where the line
    /// is not in the box.
    pub fn line_range(&self, axis: usize, p: I64Vec3) -> Option<(MaskWeight, MaskWeight)> {
        let d = p - self.origin;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let (lo, hi) = (u.min(v), u.max(v));
        if self.rows[axis].is_empty() || d[lo] < 0 || d[hi] < 0 || d[lo] >= self.dims[lo] || d[hi] >= self.dims[hi] {
            return None;
        }
        Some(self.rows[axis][(d[lo] + self.dims[lo] * d[hi]) as usize])
    }

    /// Whether every node from `lo` to `hi` (inclusive) is free for CSG (weight below one
    /// half): `Some` only where the sampler's dense box holds them all.
    pub(crate) fn free_in(&self, lo: I64Vec3, hi: I64Vec3) -> Option<bool> {
        let (a, b) = (lo - self.origin, hi - self.origin);
        if self.dense.is_empty() || a.cmplt(I64Vec3::ZERO).any() || b.cmpge(self.dims).any() {
            return None;
        }
        for z in a.z..=b.z {
            for y in a.y..=b.y {
                let row = ((y + self.dims.y * z) * self.dims.x) as usize;
                if self.dense[row + a.x as usize..=row + b.x as usize].iter().any(|&w| 2 * w as u32 >= PROTECTED as u32)
                {
                    return Some(false);
                }
            }
        }
        Some(true)
    }

    /// Whether the dense box reaches from `lo` to `hi` along `axis` (grid units).
    pub(crate) fn spans_box(&self, axis: usize, lo: f64, hi: f64) -> bool {
        !self.dense.is_empty()
            && lo >= self.origin[axis] as f64
            && hi <= (self.origin[axis] + self.dims[axis] - 1) as f64
    }

    /// The weight at grid point `p`, 0 to 1: trilinear between the nodes around it.
    pub fn at(&self, p: DVec3) -> f64 {
        let base = p.floor();
        let f = p - base;
        let b = base.as_i64vec3();
        let mut sum = 0.0;
        for c in 0..8 {
            let d = I64Vec3::new(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let wx = if d.x == 1 { f.x } else { 1.0 - f.x };
            let wy = if d.y == 1 { f.y } else { 1.0 - f.y };
            let wz = if d.z == 1 { f.z } else { 1.0 - f.z };
            let k = wx * wy * wz;
            if k != 0.0 {
                sum += k * self.node(b + d);
            }
        }
        sum
    }

    /// The gradient of [`MaskSampler::at`] at `p` (per grid unit).
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        let base = p.floor();
        let f = p - base;
        let b = base.as_i64vec3();
        let mut g = DVec3::ZERO;
        for c in 0..8 {
            let d = I64Vec3::new(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let w = self.node(b + d);
            let s = |on: i64, t: f64| if on == 1 { t } else { 1.0 - t };
            let ds = |on: i64| if on == 1 { 1.0 } else { -1.0 };
            g.x += w * ds(d.x) * s(d.y, f.y) * s(d.z, f.z);
            g.y += w * s(d.x, f.x) * ds(d.y) * s(d.z, f.z);
            g.z += w * s(d.x, f.x) * s(d.y, f.y) * ds(d.z);
        }
        g
    }

    /// Whether any node the sampler covers is protected for CSG (weight at least one half);
    /// nodes beyond its box count by the outside weight.
    pub fn any_held(&self) -> bool {
        2 * self.outside as u32 >= PROTECTED as u32
            || self.chunks.values().any(|c| c.iter().any(|&w| 2 * w as u32 >= PROTECTED as u32))
    }
}

/// Whether a weight holds a node against CSG edits: at least one half.
#[inline]
pub fn holds(weight: f64) -> bool {
    weight >= 0.5
}

impl crate::Volume {
    /// The mask (see [`crate::mask`]).
    pub fn mask(&self) -> &Mask {
        &self.mask
    }

    /// Replaces the mask (for loaders; not undoable); returns the old one.
    pub fn set_mask(&mut self, mask: Mask) -> Mask {
        std::mem::replace(&mut self.mask, mask)
    }

    /// Protects what was free and frees what was protected (every weight `w` becomes
    /// `255 - w`, everywhere).
    pub fn invert_mask(&mut self) -> crate::EditReport {
        let undo = self.mask.map_all(|w| PROTECTED - w);
        self.mask_report(undo)
    }

    /// Frees every node.
    pub fn clear_mask(&mut self) -> crate::EditReport {
        let undo = self.mask.fill(0);
        self.mask_report(undo)
    }

    /// Grows (`true`) or shrinks the masked part by one node: each node takes the largest or
    /// smallest weight of itself and its six neighbours.
    pub fn grow_mask(&mut self, grow: bool) -> crate::EditReport {
        let undo = self.mask.grow_or_shrink(grow);
        self.mask_report(undo)
    }

    /// The mask's weights near `lo ..= hi` (grid units), if any node there is not free.
    pub(crate) fn mask_sampler(&self, lo: DVec3, hi: DVec3) -> Option<MaskSampler> {
        self.mask.sampler(lo, hi)
    }

    /// Whether the mask holds a node of chunk `key` or next to it against CSG (weight at least
    /// one half).
    pub(crate) fn mask_holds_chunk(&self, key: ChunkKey) -> bool {
        let lo = key.origin_grid().as_dvec3();
        self.mask.sampler(lo, lo + DVec3::splat(CHUNK_CELLS as f64)).is_some_and(|s| s.any_held())
    }
}
