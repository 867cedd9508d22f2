//! Materials inside the volume: one material id per solid node, stored as runs along x.
//!
//! Every solid node has a material id ([`MaterialId`], 256 of them; what an id looks like is
//! the scene's palette's business). A chunk's materials cover its own nodes (`0..n` on each
//! axis) in x-major order (`i = x + n (y + n z)`): the runs of the paper (IV-D), consecutive
//! nodes along x with one id. The runs' ends at empty nodes are the crossings the lists already
//! store, so a chunk keeps only the *change points*: the node where a run of a new id starts.
//!
//! - A chunk whose solid nodes all have id 0 stores nothing (the map has no entry); one whose
//!   solid nodes share another id stores [`ChunkMaterials::Uniform`] (one byte and the tag).
//! - Otherwise [`ChunkMaterials::Runs`] holds the change points as `(delta, id)` pairs: the
//!   distance in nodes from the previous change point as a LEB128 varint (the first from node
//!   0), then the id byte. A solid node's id is that of the last change point at or before it.
//!
//! The canonical form, which [`crate::Volume::check_invariants`] checks and every writer keeps:
//! change points lie on solid nodes, the first on the chunk's first solid node, each with an id
//! other than the one before it, at least two of them (one would be `Uniform`), and no entry
//! at all for a chunk without solid nodes or whose solid nodes are all material 0. Two volumes
//! with the same node states and node materials therefore store the same bytes.

use std::collections::HashMap;

use glam::{DVec3, I64Vec3, IVec3};
use serde::{Deserialize, Serialize};

use crate::axis::Axis;
use crate::chunk::ChunkView;
use crate::coords::{CHUNK_CELLS, ChunkKey, Level};
use crate::volume::{Hash, Volume};

mod rows;
#[cfg(test)]
mod tests;
mod volume;

pub(crate) use rows::{IdReader, RowChange, note_row, splice_rows};
pub(crate) use volume::{MaterialMap, MaterialRule, MaterialUndo, own_states};

/// A material id: an index into a palette of up to [`MATERIAL_IDS`] materials.
pub type MaterialId = u8;

/// How many material ids a volume can hold.
pub const MATERIAL_IDS: usize = 256;

/// The materials of one chunk's solid nodes (see the module docs). Deserialisation checks the
/// encoding; whether it fits the chunk's node states is [`crate::Volume::check_invariants`]'s
/// to say.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "RawMaterials")]
pub enum ChunkMaterials {
    /// Every solid node has this id (never 0: such a chunk stores nothing).
    Uniform(MaterialId),
    /// Change points, `(varint delta, id)` pairs, shared (never changed once made: a copy of
    /// the chunk, for a mesher's snapshot or an undo record, is a new share, not a new copy).
    Runs(std::sync::Arc<[u8]>),
}

#[derive(Deserialize)]
enum RawMaterials {
    Uniform(MaterialId),
    Runs(Box<[u8]>),
}

impl TryFrom<RawMaterials> for ChunkMaterials {
    type Error = String;

    fn try_from(r: RawMaterials) -> Result<Self, String> {
        match r {
            RawMaterials::Uniform(0) => Err("a chunk of material 0 stores no materials".into()),
            RawMaterials::Uniform(id) => Ok(ChunkMaterials::Uniform(id)),
            RawMaterials::Runs(bytes) => {
                let mut count = 0;
                let mut last = None;
                for entry in Entries::new(&bytes) {
                    let (delta, id) = entry?;
                    if count > 0 && delta == 0 {
                        return Err("two material change points on one node".into());
                    }
                    if last == Some(id) {
                        return Err("a material change point that does not change the material".into());
                    }
                    last = Some(id);
                    count += 1;
                }
                if count < 2 {
                    return Err("material runs with fewer than two change points".into());
                }
                Ok(ChunkMaterials::Runs(bytes.into()))
            }
        }
    }
}

/// The `(delta, id)` pairs of an encoding.
struct Entries<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Entries<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Entries { bytes, at: 0 }
    }
}

impl Iterator for Entries<'_> {
    type Item = Result<(usize, MaterialId), String>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.at >= self.bytes.len() {
            return None;
        }
        let mut delta = 0usize;
        let mut shift = 0;
        loop {
            let Some(&b) = self.bytes.get(self.at) else {
                return Some(Err("material runs end inside a change point".into()));
            };
            self.at += 1;
            if shift > 21 {
                return Some(Err("a material change point further than a chunk holds".into()));
            }
            delta |= ((b & 0x7f) as usize) << shift;
            shift += 7;
            if b & 0x80 == 0 {
                break;
            }
        }
        let Some(&id) = self.bytes.get(self.at) else {
            return Some(Err("material runs end before a change point's id".into()));
        };
        self.at += 1;
        Some(Ok((delta, id)))
    }
}

fn push_varint(out: &mut Vec<u8>, mut v: usize) {
    while v >= 0x80 {
        out.push((v as u8 & 0x7f) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

impl ChunkMaterials {
    /// Heap bytes.
    pub fn heap_bytes(&self) -> usize {
        match self {
            ChunkMaterials::Uniform(_) => 0,
            // The bytes and the two counts before them.
            ChunkMaterials::Runs(b) => b.len() + 16,
        }
    }

    /// Change points, `(node index, id)`, in order; `Err` on a malformed encoding.
    pub fn change_points(&self) -> Result<Vec<(usize, MaterialId)>, String> {
        match self {
            ChunkMaterials::Uniform(id) => Ok(vec![(0, *id)]),
            ChunkMaterials::Runs(bytes) => {
                let mut at = 0;
                Entries::new(bytes)
                    .map(|e| {
                        e.map(|(d, id)| {
                            at += d;
                            (at, id)
                        })
                    })
                    .collect()
            }
        }
    }

    /// The id of every node of a chunk of `nodes` nodes (`n³`), in x-major order; empty nodes
    /// get the id of the run before them. Change points past the end are ignored.
    pub(crate) fn decode_into(this: Option<&Self>, nodes: usize, out: &mut Vec<MaterialId>) {
        out.clear();
        match this {
            None => out.resize(nodes, 0),
            Some(ChunkMaterials::Uniform(id)) => out.resize(nodes, *id),
            Some(ChunkMaterials::Runs(bytes)) => {
                let mut id = 0;
                let mut next = 0usize;
                for (delta, to) in Entries::new(bytes).map_while(Result::ok) {
                    next += delta;
                    let end = next.min(nodes);
                    if out.len() < end {
                        out.resize(end, id);
                    }
                    id = to;
                }
                out.resize(nodes, id);
            }
        }
    }

    /// The canonical encoding of `ids` (x-major, `n³`) over the solid nodes `rows[y + n z]`
    /// (bit `x`); `None` for a chunk without solid nodes or with only material 0.
    pub(crate) fn encode(ids: &[MaterialId], rows: &[u128], n: usize) -> Option<Self> {
        let mut out = Vec::new();
        let mut points = 0usize;
        let mut current: Option<MaterialId> = None;
        let mut last_at = 0usize;
        for (r, &row) in rows.iter().enumerate() {
            // Runs of solid nodes, each scanned for ids other than the current one.
            let mut bits = row;
            while bits != 0 {
                let a = bits.trailing_zeros() as usize;
                let b = a + (bits >> a).trailing_ones() as usize;
                bits &= !(((1u128 << (b - a)) - 1) << a);
                let base = n * r;
                let mut i = base + a;
                let end = base + b;
                while i < end {
                    let id = ids[i];
                    if current != Some(id) {
                        push_varint(&mut out, i - last_at);
                        out.push(id);
                        last_at = i;
                        current = Some(id);
                        points += 1;
                    }
                    // Skip the rest of this id's stretch.
                    i += 1 + ids[i + 1..end].iter().position(|&v| v != id).unwrap_or(end - i - 1);
                }
            }
        }
        match (points, current) {
            (0, _) => None,
            (1, Some(0)) => None,
            (1, Some(id)) => Some(ChunkMaterials::Uniform(id)),
            _ => Some(ChunkMaterials::Runs(out.into())),
        }
    }

    /// Whether `self` is the canonical encoding over the solid nodes `rows`: `Err` says why not.
    pub(crate) fn check(&self, rows: &[u128], n: usize) -> Result<(), String> {
        let mut ids = Vec::new();
        ChunkMaterials::decode_into(Some(self), n * n * n, &mut ids);
        let canonical = ChunkMaterials::encode(&ids, rows, n);
        if canonical.as_ref() == Some(self) {
            return Ok(());
        }
        if let ChunkMaterials::Runs(_) = self {
            let points = self.change_points()?;
            for &(i, _) in &points {
                if i >= n * n * n {
                    return Err(format!("a material change point at node {i} past the chunk's {} nodes", n * n * n));
                }
                let (x, r) = (i % n, i / n);
                if rows[r] >> x & 1 == 0 {
                    return Err(format!("a material change point on empty node {i}"));
                }
            }
        }
        Err(match canonical {
            None => "materials stored for a chunk without solid nodes of a material other than 0".into(),
            Some(_) => "material runs that are not in canonical form (a change point that changes nothing, or a first one after the first solid node)".into(),
        })
    }
}
