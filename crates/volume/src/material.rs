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
    /// Change points, `(varint delta, id)` pairs.
    Runs(Box<[u8]>),
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
                Ok(ChunkMaterials::Runs(bytes))
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

/// One x line of a chunk whose own node states an edit changed: its index (`y + n z`, the row
/// of the materials' x-major order) and its own nodes' states before and after (bit `x`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RowChange {
    pub(crate) row: u32,
    pub(crate) before: u64,
    pub(crate) after: u64,
}

/// Notes x line `index` in `rows` when its own nodes' states went from `before` to `after`
/// (what the materials pass reads instead of every node of the chunk). Lines along y and z are
/// not noted (callers skip computing their states).
#[inline]
pub(crate) fn note_row(rows: &mut Vec<RowChange>, axis: Axis, index: usize, before: u128, after: u128, n: usize) {
    let own = (1u128 << n) - 1;
    if axis == Axis::X && (before ^ after) & own != 0 {
        // (A chunk's own nodes are at most 64 a line.)
        rows.push(RowChange { row: index as u32, before: (before & own) as u64, after: (after & own) as u64 });
    }
}

/// The change points of a chunk, walked forward once (x-major order, never going back): the id in
/// effect at a node, the ids of a run of nodes (what a block that needs a few rows of a chunk
/// reads instead of decoding all `n³` nodes), and the points of a stretch to copy.
pub(crate) struct IdReader<'a> {
    bytes: &'a [u8],
    entries: Entries<'a>,
    /// Where the next point's entry starts in `bytes`.
    next_start: usize,
    /// The id of the last point consumed (`None`: before the first point of runs, where no node
    /// is solid).
    id: Option<MaterialId>,
    /// The next point's node (`usize::MAX`: none) and id.
    next_at: usize,
    next_id: MaterialId,
}

impl<'a> IdReader<'a> {
    pub(crate) fn new(this: Option<&'a ChunkMaterials>) -> Self {
        let (bytes, id): (&[u8], _) = match this {
            None => (&[], Some(0)),
            Some(ChunkMaterials::Uniform(id)) => (&[], Some(*id)),
            Some(ChunkMaterials::Runs(bytes)) => (bytes, None),
        };
        let mut p = IdReader { bytes, entries: Entries::new(bytes), next_start: 0, id, next_at: 0, next_id: 0 };
        p.fetch();
        p
    }

    fn fetch(&mut self) {
        self.next_start = self.entries.at;
        match self.entries.next() {
            Some(Ok((delta, id))) => {
                self.next_at = self.next_at.saturating_add(delta);
                self.next_id = id;
            }
            _ => self.next_at = usize::MAX,
        }
    }

    /// Consumes the points before node `i`.
    fn skip_below(&mut self, i: usize) {
        while self.next_at < i {
            self.id = Some(self.next_id);
            self.fetch();
        }
    }

    /// The id in effect at node `i` (not before the last node asked).
    fn id_at(&mut self, i: usize) -> Option<MaterialId> {
        self.skip_below(i + 1);
        self.id
    }

    /// The ids of the nodes `start..start + out.len()`, into `out` (empty nodes before the first
    /// point read 0, as decoding gives them). `start` is at least the end of the nodes read
    /// before.
    pub(crate) fn read(&mut self, start: usize, out: &mut [MaterialId]) {
        let end = start + out.len();
        let mut i = start;
        while i < end {
            self.skip_below(i + 1);
            let stop = end.min(self.next_at);
            out[i - start..stop - start].fill(self.id.unwrap_or(0));
            i = stop;
        }
    }
}

/// Writes change points in node order, dropping those that change nothing: the canonical
/// encoding of the solid nodes' ids when fed every solid node where its id may change.
#[derive(Default)]
struct PointWriter {
    out: Vec<u8>,
    id: Option<MaterialId>,
    last_at: usize,
    points: usize,
}

impl PointWriter {
    /// A point at node `at` (after the last one), unless the id is already `id`; returns
    /// whether it was written.
    #[inline]
    fn put(&mut self, at: usize, id: MaterialId) -> bool {
        if self.id == Some(id) {
            return false;
        }
        push_varint(&mut self.out, at - self.last_at);
        self.out.push(id);
        self.last_at = at;
        self.id = Some(id);
        self.points += 1;
        true
    }

    fn finish(self) -> Option<ChunkMaterials> {
        match (self.points, self.id) {
            (0, _) | (1, Some(0)) => None,
            (1, Some(id)) => Some(ChunkMaterials::Uniform(id)),
            _ => Some(ChunkMaterials::Runs(self.out.into_boxed_slice())),
        }
    }
}

/// The new materials of a chunk whose own node states changed only in `rows` (sorted by row,
/// each with different states), from its `old` materials: nodes solid before and after keep
/// their ids, nodes made solid take `fill`. `view` is the chunk after the edit at `level`.
/// Only the changed rows are decoded; the change points between them are copied, with a point
/// added or dropped where a stretch is entered with another id than before.
pub(crate) fn splice_rows(
    old: Option<&ChunkMaterials>,
    rows: &[RowChange],
    fill: MaterialId,
    view: ChunkView<'_>,
    level: Level,
) -> Option<ChunkMaterials> {
    let n = level.cells();
    let nodes = n * n * n;
    let mut points = IdReader::new(old);
    let mut w = PointWriter { out: Vec::with_capacity(points.bytes.len() + 8 * rows.len()), ..Default::default() };
    // The rows after the edit, read forward where a stretch needs its first solid node.
    let mut cursor = view.cursor(Axis::X, 0);
    let own = (1u128 << n) - 1;
    // (Rows are asked in increasing order: a stretch's search ends before the next stretch.)
    let mut row_states = |r: usize| -> u128 {
        cursor.advance_to(r);
        crate::chunk::line_states(cursor.next_line(), level) & own
    };
    // Copies the old points of the unchanged nodes `a..b` (whole rows).
    let mut stretch = |a: usize, b: usize, points: &mut IdReader<'_>, w: &mut PointWriter| {
        if a >= b {
            return;
        }
        points.skip_below(a);
        if let Some(entering) = points.id
            && w.id != Some(entering)
        {
            // The stretch's solid nodes before its first point had `entering`, which the writer
            // is not at: a point on the first of them.
            let end = points.next_at.min(b);
            let mut r = a / n;
            while r * n < end {
                let bits = row_states(r);
                if bits != 0 {
                    let at = r * n + bits.trailing_zeros() as usize;
                    if at < end {
                        w.put(at, entering);
                    }
                    break;
                }
                r += 1;
            }
        }
        // The stretch's points, the first ones one at a time until one is written: the rest
        // follow it as they were stored (their deltas and ids unchanged), copied as bytes.
        while points.next_at < b {
            let (at, id) = (points.next_at, points.next_id);
            points.skip_below(at + 1);
            if w.put(at, id) {
                let from = points.next_start;
                let mut count = 0;
                while points.next_at < b {
                    let (at, id) = (points.next_at, points.next_id);
                    points.skip_below(at + 1);
                    (w.last_at, w.id) = (at, Some(id));
                    count += 1;
                }
                w.out.extend_from_slice(&points.bytes[from..points.next_start]);
                w.points += count;
                break;
            }
        }
    };
    let mut done = 0;
    for c in rows {
        let base = c.row as usize * n;
        stretch(done, base, &mut points, &mut w);
        // The row's solid nodes run by run: runs made solid take `fill`, runs that stay solid
        // their old ids (the id at the run's start, then the old points inside it).
        let (kept, grown) = (c.after & c.before, c.after & !c.before);
        let mut bits = c.after;
        while bits != 0 {
            let a = bits.trailing_zeros() as usize;
            let stays = kept >> a & 1 == 1;
            let b = a + ((if stays { kept } else { grown }) >> a).trailing_ones() as usize;
            bits &= !((u64::MAX >> (64 - (b - a))) << a);
            if stays {
                w.put(base + a, points.id_at(base + a).unwrap_or(fill));
                while points.next_at < base + b {
                    let (at, id) = (points.next_at, points.next_id);
                    points.skip_below(at + 1);
                    w.put(at, id);
                }
            } else {
                w.put(base + a, fill);
            }
        }
        done = base + n;
    }
    stretch(done, nodes, &mut points, &mut w);
    w.finish()
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
            ChunkMaterials::Runs(b) => b.len(),
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
            _ => Some(ChunkMaterials::Runs(out.into_boxed_slice())),
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

/// The materials of a volume's chunks (chunks absent are material 0 wherever solid).
pub(crate) type MaterialMap = HashMap<ChunkKey, ChunkMaterials, Hash>;

/// What an edit does to the materials of the nodes it changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MaterialRule {
    /// Nodes made solid get this id (adding matter with a material).
    Fill(MaterialId),
    /// Nodes made solid take the id of a face neighbour that was solid, else of the run they
    /// continue (tools that move the surface: smoothing does not carry a material across a
    /// boundary it did not touch).
    Nearest,
}

/// Own node states of a chunk, `rows[y + n z]` bit `x`.
pub(crate) fn own_states(view: ChunkView<'_>, level: Level) -> Vec<u128> {
    let n = level.cells();
    match view {
        ChunkView::Uniform(false) => vec![0; n * n],
        ChunkView::Uniform(true) => vec![(1u128 << n) - 1; n * n],
        ChunkView::Lists(l) => {
            // The x lines, in index order `y + n z`, unpacked a line at a time.
            let mut cursor = l.cursor(Axis::X, 0);
            let mut line = crate::chunk::WorkLine::EMPTY;
            let own = (1u128 << n) - 1;
            (0..n * n)
                .map(|_| {
                    line.load(cursor.next_line(), level);
                    line.states & own
                })
                .collect()
        }
    }
}

/// Chunk-local node `(x, y, z)` of index `i`.
#[inline]
fn node_of(i: usize, n: usize) -> [usize; 3] {
    [i % n, (i / n) % n, i / (n * n)]
}

/// The new materials of one chunk whose node states went from `before` to `after`.
fn next_materials(
    old: Option<&ChunkMaterials>,
    before: &[u128],
    after: &[u128],
    n: usize,
    rule: MaterialRule,
    hint: MaterialId,
    ids: &mut Vec<MaterialId>,
) -> Option<ChunkMaterials> {
    let any_after = after.iter().any(|&r| r != 0);
    if !any_after {
        return None;
    }
    let any_before = before.iter().any(|&r| r != 0);
    let uniform = match old {
        None => Some(0),
        Some(ChunkMaterials::Uniform(id)) => Some(*id),
        Some(ChunkMaterials::Runs(_)) => None,
    };
    let fill = match rule {
        MaterialRule::Fill(f) => f,
        MaterialRule::Nearest => hint,
    };
    if !any_before {
        return (fill != 0).then_some(ChunkMaterials::Uniform(fill));
    }
    if let Some(u) = uniform {
        let grows = after.iter().zip(before).any(|(a, b)| a & !b != 0);
        if !grows || rule == MaterialRule::Nearest || fill == u {
            return (u != 0).then_some(ChunkMaterials::Uniform(u));
        }
    }
    ChunkMaterials::decode_into(old, n * n * n, ids);
    for (r, (&a, &b)) in after.iter().zip(before).enumerate() {
        let mut grown = a & !b;
        while grown != 0 {
            let x = grown.trailing_zeros() as usize;
            grown &= grown - 1;
            let i = x + n * r;
            ids[i] = match rule {
                MaterialRule::Fill(f) => f,
                MaterialRule::Nearest => nearest_old(ids, before, i, n).unwrap_or(ids[i]),
            };
        }
    }
    ChunkMaterials::encode(ids, after, n)
}

/// The id of a face neighbour of node `i` that was solid (`before`), if any.
fn nearest_old(ids: &[MaterialId], before: &[u128], i: usize, n: usize) -> Option<MaterialId> {
    let [x, y, z] = node_of(i, n);
    let solid = |x: usize, y: usize, z: usize| before[y + n * z] >> x & 1 == 1;
    let at = |x: usize, y: usize, z: usize| ids[x + n * (y + n * z)];
    let candidates = [
        (x > 0).then(|| (x - 1, y, z)),
        (x + 1 < n).then(|| (x + 1, y, z)),
        (y > 0).then(|| (x, y - 1, z)),
        (y + 1 < n).then(|| (x, y + 1, z)),
        (z > 0).then(|| (x, y, z - 1)),
        (z + 1 < n).then(|| (x, y, z + 1)),
    ];
    candidates.into_iter().flatten().find(|&(x, y, z)| solid(x, y, z)).map(|(x, y, z)| at(x, y, z))
}

/// The previous materials of chunks an edit changed, for its undo record.
pub(crate) type MaterialUndo = Vec<(ChunkKey, Option<ChunkMaterials>)>;

impl Volume {
    /// The material id of every own node of chunk `key` (x-major, `n³` at the chunk's level);
    /// empty nodes carry the id of the run before them.
    pub(crate) fn decode_materials(&self, key: ChunkKey, level: Level, out: &mut Vec<MaterialId>) {
        let n = level.cells();
        ChunkMaterials::decode_into(self.materials.get(&key), n * n * n, out);
    }

    /// Whether any node of the volume has a material other than 0.
    pub fn has_materials(&self) -> bool {
        !self.materials.is_empty()
    }

    /// The stored materials of chunk `key` (`None`: material 0 wherever solid).
    pub fn chunk_materials(&self, key: ChunkKey) -> Option<&ChunkMaterials> {
        self.materials.get(&key)
    }

    /// Chunks with stored materials.
    pub fn material_chunks(&self) -> impl Iterator<Item = (ChunkKey, &ChunkMaterials)> {
        self.materials.iter().map(|(k, m)| (*k, m))
    }

    /// Replaces the stored materials of chunk `key` (for loaders); nothing is checked: call
    /// [`Volume::check_chunk_materials`] before or [`Volume::check_invariants`] after.
    pub fn set_chunk_materials(&mut self, key: ChunkKey, materials: Option<ChunkMaterials>) {
        self.store_materials(key, materials);
    }

    /// Whether `materials` fit the chunk at `key` as it is stored now, as
    /// [`Volume::check_invariants`] requires: a chunk that is not empty, one id per node of the
    /// chunk's level (a uniform chunk's: the volume's level), in canonical form. `Err` says why
    /// not. Loaders call it after the chunks and the volume's level are in place.
    pub fn check_chunk_materials(&self, key: ChunkKey, materials: &ChunkMaterials) -> Result<(), String> {
        if !self.chunks.contains_key(&key) {
            return Err("materials stored for an empty chunk".into());
        }
        let level = self.level_of(key);
        materials.check(&own_states(self.view(key), level), level.cells())
    }

    /// Stores (or removes) the materials of `key`; returns what was there. The map's table is
    /// freed when its last entry goes, so a volume painted back to material 0 costs nothing.
    pub(crate) fn store_materials(
        &mut self,
        key: ChunkKey,
        materials: Option<ChunkMaterials>,
    ) -> Option<ChunkMaterials> {
        let was = match materials {
            Some(m) => self.materials.insert(key, m),
            None => self.materials.remove(&key),
        };
        if self.materials.is_empty() {
            self.materials = MaterialMap::default();
        }
        was
    }

    /// The largest material id any node has (`None` for an empty volume; 0 without materials).
    pub fn max_material(&self) -> Option<MaterialId> {
        if self.chunks.is_empty() {
            return None;
        }
        let ids = self.materials.values().flat_map(|m| m.change_points().unwrap_or_default().into_iter().map(|p| p.1));
        Some(ids.max().unwrap_or(0))
    }

    /// Gives the nodes whose material is `count` or above material 0 (after a palette lost
    /// entries); returns how many chunks changed. Node states are untouched.
    pub fn clamp_materials(&mut self, count: usize) -> usize {
        let bad: Vec<ChunkKey> = self
            .materials
            .iter()
            .filter(|(_, m)| m.change_points().map_or(true, |p| p.iter().any(|e| e.1 as usize >= count)))
            .map(|(k, _)| *k)
            .collect();
        let mut ids = Vec::new();
        for &key in &bad {
            let level = self.level_of(key);
            self.decode_materials(key, level, &mut ids);
            for id in ids.iter_mut() {
                if *id as usize >= count {
                    *id = 0;
                }
            }
            let rows = own_states(self.view(key), level);
            let next = ChunkMaterials::encode(&ids, &rows, level.cells());
            self.store_materials(key, next);
        }
        bad.len()
    }

    /// Gives every solid node material `id` (for scenes written before materials were stored,
    /// where a layer had one material).
    pub fn fill_materials(&mut self, id: MaterialId) {
        self.materials.clear();
        if id != 0 {
            let keys: Vec<ChunkKey> = self.chunks.keys().copied().collect();
            for k in keys {
                self.materials.insert(k, ChunkMaterials::Uniform(id));
            }
        }
    }

    /// The material of node `local` (chunk-local, each coordinate in `0..=n` at `level`) of chunk
    /// `key`, read in the chunk that owns the node (coordinates equal to `n` belong to the next
    /// chunk, which may be stored at another level: the nearest of its nodes is read).
    pub(crate) fn node_material(&self, key: ChunkKey, level: Level, local: [usize; 3]) -> MaterialId {
        let n = level.cells();
        let mut owner = key.0;
        let mut frac = [0.0f64; 3];
        for i in 0..3 {
            if local[i] >= n {
                owner[i] += 1;
                frac[i] = (local[i] - n) as f64 / n as f64;
            } else {
                frac[i] = local[i] as f64 / n as f64;
            }
        }
        let owner = ChunkKey(owner);
        let Some(m) = self.materials.get(&owner) else { return 0 };
        if let ChunkMaterials::Uniform(id) = m {
            return *id;
        }
        let on = self.level_of(owner).cells();
        let idx = |f: f64| ((f * on as f64).round() as usize).min(on - 1);
        let i = idx(frac[0]) + on * (idx(frac[1]) + on * idx(frac[2]));
        let mut point = 0;
        let mut id = 0;
        for (d, to) in Entries::new(match m {
            ChunkMaterials::Runs(b) => b,
            ChunkMaterials::Uniform(_) => unreachable!("handled above"),
        })
        .map_while(Result::ok)
        {
            point += d;
            if point > i {
                break;
            }
            id = to;
        }
        id
    }

    /// The material of node `node` (global node coordinates at the volume's level, in a chunk
    /// stored at that level), or `None` when the node is empty.
    pub fn node_material_at(&self, node: I64Vec3) -> Option<MaterialId> {
        if !self.node_inside(node) {
            return None;
        }
        let n = self.level.cells() as i64;
        let key = node.div_euclid(I64Vec3::splat(n));
        let local = node - key * n;
        let key = ChunkKey(key.as_ivec3());
        Some(self.node_material(key, self.level, [local.x as usize, local.y as usize, local.z as usize]))
    }

    /// The material of the solid node nearest `p` (grid coordinates) among the corners of the
    /// cell holding `p`, or `None` when they are all empty (an eyedropper's reading).
    pub fn material_near(&self, p: DVec3) -> Option<MaterialId> {
        if !p.is_finite() {
            return None;
        }
        let c = CHUNK_CELLS as f64;
        let key = (p / c).floor();
        if key.abs().max_element() > i32::MAX as f64 - 2.0 {
            return None;
        }
        let key = ChunkKey(key.as_ivec3());
        let level = self.level_of(key);
        let n = level.cells();
        let local = (p - key.origin_grid().as_dvec3()) / level.spacing();
        let cell = local.floor().clamp(DVec3::ZERO, DVec3::splat(n as f64 - 1.0));
        let mut corners: Vec<(f64, [usize; 3])> = (0..8)
            .map(|k| {
                let c = cell + DVec3::new((k & 1) as f64, (k >> 1 & 1) as f64, (k >> 2 & 1) as f64);
                ((c - local).length_squared(), [c.x as usize, c.y as usize, c.z as usize])
            })
            .collect();
        corners.sort_by(|a, b| a.0.total_cmp(&b.0));
        let origin = key.origin_grid();
        corners.into_iter().map(|(_, l)| l).find_map(|l| {
            let g = origin.as_dvec3() + DVec3::new(l[0] as f64, l[1] as f64, l[2] as f64) * level.spacing();
            self.is_inside(g).then(|| self.node_material(key, level, l))
        })
    }

    /// Brings the materials of the chunks `previous` lists (each with its contents before the
    /// edit) in line with their new node states under `rule`; returns the previous materials of
    /// the chunks whose materials changed. `rows[i]`, where the writer kept it, lists the x
    /// lines whose own node states it changed in `previous[i]`'s chunk: only those rows are
    /// decoded ([`splice_rows`]) unless nodes were made solid under [`MaterialRule::Nearest`]
    /// (which looks at the rows around them) or the chunk changed level.
    pub(crate) fn update_materials(
        &mut self,
        previous: &[(ChunkKey, Option<crate::chunk::Chunk>)],
        rule: MaterialRule,
        rows: &[Option<Vec<RowChange>>],
    ) -> MaterialUndo {
        if self.materials.is_empty() && matches!(rule, MaterialRule::Nearest | MaterialRule::Fill(0)) {
            return Vec::new();
        }
        let mut ids = Vec::new();
        let mut updates = Vec::with_capacity(previous.len());
        for (i, (key, old_chunk)) in previous.iter().enumerate() {
            let level = self.level_of(*key);
            let old = self.materials.get(key);
            let same_level = match old_chunk {
                Some(crate::chunk::Chunk::Lists(l)) => l.level() == level,
                _ => true,
            };
            // The rows the writer noted, and the id nodes made solid take, where the rows alone
            // decide the chunk's materials.
            let spliced = rows.get(i).and_then(Option::as_ref).filter(|_| same_level).and_then(|changes| {
                let fill = match rule {
                    MaterialRule::Fill(f) => Some(f),
                    MaterialRule::Nearest => changes.iter().all(|c| c.after & !c.before == 0).then_some(0),
                };
                fill.map(|f| (changes, f))
            });
            let next = match spliced {
                Some((changes, f)) => {
                    if changes.is_empty() {
                        // No own node changed state: the materials stay.
                        debug_assert_eq!(
                            old.cloned(),
                            self.whole_chunk_materials(*key, old_chunk.as_ref(), rule, &mut ids)
                        );
                        continue;
                    }
                    let next = splice_rows(old, changes, f, self.view(*key), level);
                    debug_assert_eq!(
                        next,
                        self.whole_chunk_materials(*key, old_chunk.as_ref(), rule, &mut ids),
                        "materials spliced by rows equal the whole chunk's pass"
                    );
                    next
                }
                _ => self.whole_chunk_materials(*key, old_chunk.as_ref(), rule, &mut ids),
            };
            if next.as_ref() != self.materials.get(key) {
                updates.push((*key, next));
            }
        }
        let mut undo = Vec::with_capacity(updates.len());
        for (key, next) in updates {
            let was = self.store_materials(key, next);
            undo.push((key, was));
        }
        undo
    }

    /// The materials of chunk `key` (contents before the edit `old_chunk`) under `rule`, from
    /// every node of the chunk before and after.
    fn whole_chunk_materials(
        &self,
        key: ChunkKey,
        old_chunk: Option<&crate::chunk::Chunk>,
        rule: MaterialRule,
        ids: &mut Vec<MaterialId>,
    ) -> Option<ChunkMaterials> {
        let level = self.level_of(key);
        let before_view = ChunkView::of(old_chunk);
        let before_level = match before_view {
            ChunkView::Lists(l) => l.level(),
            ChunkView::Uniform(_) => level,
        };
        let old = self.materials.get(&key);
        // Cases decided without the previous node states: a chunk of one material that
        // gains nodes of that material (or only loses or moves nodes), or of material 0
        // that gains material 0.
        let keeps = match (old, rule) {
            (Some(ChunkMaterials::Uniform(u)), MaterialRule::Fill(f)) => (f == *u).then_some(*u),
            (Some(ChunkMaterials::Uniform(u)), MaterialRule::Nearest) => Some(*u),
            (None, MaterialRule::Fill(0)) => Some(0),
            _ => None,
        };
        if let (Some(u), true) = (keeps, before_level == level) {
            return match self.view(key) {
                ChunkView::Uniform(false) => None,
                ChunkView::Uniform(true) => (u != 0).then_some(ChunkMaterials::Uniform(u)),
                // (A list chunk may, rarely, have no solid node of its own.)
                view => own_states(view, level)
                    .iter()
                    .any(|&r| r != 0)
                    .then_some(ChunkMaterials::Uniform(u))
                    .filter(|_| u != 0),
            };
        }
        let after = own_states(self.view(key), level);
        if before_level == level {
            let before = own_states(before_view, level);
            let hint = if rule == MaterialRule::Nearest && old.is_none() { self.neighbour_hint(key) } else { 0 };
            next_materials(old, &before, &after, level.cells(), rule, hint, ids)
        } else {
            // The edit replaced a chunk of another level: resample (see `resampled`).
            self.resampled(key, before_level, level, &after, ids)
        }
    }

    /// An id for new matter in chunk `key` that had no solid node: a face neighbour's (its
    /// uniform id or its first run's), else 0.
    fn neighbour_hint(&self, key: ChunkKey) -> MaterialId {
        [IVec3::X, IVec3::NEG_X, IVec3::Y, IVec3::NEG_Y, IVec3::Z, IVec3::NEG_Z]
            .into_iter()
            .find_map(|d| match self.materials.get(&ChunkKey(key.0 + d)) {
                Some(ChunkMaterials::Uniform(id)) => Some(*id),
                Some(m @ ChunkMaterials::Runs(_)) => m.change_points().ok().and_then(|p| p.first().map(|e| e.1)),
                None => None,
            })
            .unwrap_or(0)
    }

    /// The materials of chunk `key`, stored at `from`, read at `to` (whose own node states are
    /// `after`): a node that coincides with a stored node takes its id, any other the id of the
    /// nearest stored node (rounding down on ties), so raising then lowering gives back the
    /// original ids.
    pub(crate) fn resampled(
        &self,
        key: ChunkKey,
        from: Level,
        to: Level,
        after: &[u128],
        ids: &mut Vec<MaterialId>,
    ) -> Option<ChunkMaterials> {
        let old = self.materials.get(&key);
        match old {
            None => return None,
            Some(ChunkMaterials::Uniform(id)) => {
                return after.iter().any(|&r| r != 0).then_some(ChunkMaterials::Uniform(*id));
            }
            Some(ChunkMaterials::Runs(_)) => {}
        }
        let (fnn, tn) = (from.cells(), to.cells());
        let mut src = Vec::new();
        ChunkMaterials::decode_into(old, fnn * fnn * fnn, &mut src);
        let map = |i: usize| -> usize { if tn >= fnn { i / (tn / fnn) } else { (i * (fnn / tn)).min(fnn - 1) } };
        ids.clear();
        ids.resize(tn * tn * tn, 0);
        for z in 0..tn {
            for y in 0..tn {
                let base = fnn * (map(y) + fnn * map(z));
                for x in 0..tn {
                    ids[x + tn * (y + tn * z)] = src[base + map(x)];
                }
            }
        }
        ChunkMaterials::encode(ids, after, tn)
    }

    /// Gives the solid nodes inside `brush` material `id` where `weight(node)` (grid point) beats
    /// the node's dither threshold (a fixed hash of its global position in `[0, 1)`): weight 1
    /// paints every node, weight 0 none, and a weight between paints that share of the nodes,
    /// the same ones every time. Node states and crossings are not touched. Returns the chunks
    /// whose materials changed and the record that undoes it.
    pub fn paint_where(
        &mut self,
        brush: &dyn crate::brush::Brush,
        id: MaterialId,
        weight: &dyn Fn(DVec3) -> f64,
    ) -> Result<crate::EditReport, crate::EditError> {
        let bounds = brush.bounds();
        if !bounds.is_valid() {
            return Err(crate::EditError::BadBounds);
        }
        let (cmin, cmax) = crate::edit::chunk_range(&bounds, crate::EditSettings::default().max_chunks)?;
        let mut keys: Vec<ChunkKey> = Vec::new();
        for z in cmin.z..=cmax.z {
            for y in cmin.y..=cmax.y {
                for x in cmin.x..=cmax.x {
                    let k = ChunkKey::new(x, y, z);
                    if self.chunks.contains_key(&k) {
                        keys.push(k);
                    }
                }
            }
        }
        let mut ids = Vec::new();
        let mut updates = Vec::new();
        for key in keys {
            let level = self.level_of(key);
            let n = level.cells();
            let rows = own_states(self.view(key), level);
            self.decode_materials(key, level, &mut ids);
            let origin = key.origin_grid();
            let h = level.spacing();
            let mut touched = false;
            for (r, &row) in rows.iter().enumerate() {
                let (y, z) = (r % n, r / n);
                let mut bits = row;
                while bits != 0 {
                    let x = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let i = x + n * r;
                    if ids[i] == id {
                        continue;
                    }
                    let local = DVec3::new(x as f64, y as f64, z as f64) * h;
                    let p = origin.as_dvec3() + local;
                    if !bounds.contains(p) || !brush.contains(origin.as_dvec3(), local) {
                        continue;
                    }
                    let w = weight(p);
                    if w > 0.0
                        && (w >= 1.0
                            || w > dither(origin * (1 << level.get()) + I64Vec3::new(x as i64, y as i64, z as i64)))
                    {
                        ids[i] = id;
                        touched = true;
                    }
                }
            }
            if touched {
                let next = ChunkMaterials::encode(&ids, &rows, n);
                if next.as_ref() != self.materials.get(&key) {
                    updates.push((key, next));
                }
            }
        }
        // Only nodes inside the brush's box change (a cell of the coarsest level more holds
        // every edge whose vertex takes a changed node's material).
        let mut report = crate::EditReport {
            reach: Some(crate::Reach { min: bounds.min - DVec3::ONE, max: bounds.max + DVec3::ONE }),
            ..Default::default()
        };
        for (key, next) in updates {
            let was = self.store_materials(key, next);
            report.changed.push(key);
            report.undo.materials.push((key, was));
        }
        Ok(report)
    }

    /// Paints the solid nodes inside `brush` with material `id`, every one of them.
    pub fn paint(
        &mut self,
        brush: &dyn crate::brush::Brush,
        id: MaterialId,
    ) -> Result<crate::EditReport, crate::EditError> {
        self.paint_where(brush, id, &|_| 1.0)
    }

    /// Checks the materials of every chunk against its node states (part of
    /// [`Volume::check_invariants`]).
    pub(crate) fn check_materials(&self) -> Result<(), crate::InvariantViolation> {
        for (key, m) in &self.materials {
            self.check_chunk_materials(*key, m).map_err(|what| crate::InvariantViolation { key: *key, what })?;
        }
        Ok(())
    }

    /// Gives the nodes of the chunks in `previous` (with their contents before an edit) that
    /// the edit made solid the material of the node of `other` they came from (`node - shift`,
    /// in node units of this volume's level, which `other` shares); records the previous
    /// materials of chunks not yet in `undo`.
    pub(crate) fn carry_materials(
        &mut self,
        other: &Volume,
        shift: I64Vec3,
        previous: &[(ChunkKey, Option<crate::chunk::Chunk>)],
        undo: &mut MaterialUndo,
    ) {
        if other.materials.is_empty() {
            return;
        }
        let level = self.level;
        let n = level.cells();
        let ni = n as i64;
        let mut decoded: HashMap<ChunkKey, Vec<MaterialId>, Hash> = HashMap::default();
        let mut ids = Vec::new();
        let mut updates = Vec::new();
        for (key, old_chunk) in previous {
            if self.level_of(*key) != level {
                continue;
            }
            let before = own_states(ChunkView::of(old_chunk.as_ref()), level);
            let after = own_states(self.view(*key), level);
            self.decode_materials(*key, level, &mut ids);
            let origin = key.0.as_i64vec3() * ni;
            for (r, (&a, &b)) in after.iter().zip(&before).enumerate() {
                let mut grown = a & !b;
                while grown != 0 {
                    let x = grown.trailing_zeros() as usize;
                    grown &= grown - 1;
                    let node = origin + I64Vec3::new(x as i64, (r % n) as i64, (r / n) as i64) - shift;
                    let okey = node.div_euclid(I64Vec3::splat(ni));
                    let local = node - okey * ni;
                    let okey = ChunkKey(okey.as_ivec3());
                    let src = decoded.entry(okey).or_insert_with(|| {
                        let mut v = Vec::new();
                        other.decode_materials(okey, level, &mut v);
                        v
                    });
                    ids[x + n * r] = src[(local.x + ni * (local.y + ni * local.z)) as usize];
                }
            }
            let next = ChunkMaterials::encode(&ids, &after, n);
            if next.as_ref() != self.materials.get(key) {
                updates.push((*key, next));
            }
        }
        for (key, next) in updates {
            let was = self.store_materials(key, next);
            if !undo.iter().any(|(k, _)| *k == key) {
                undo.push((key, was));
            }
        }
    }

    /// Heap and table bytes of the materials.
    pub(crate) fn material_bytes(&self) -> usize {
        crate::memory::hash_table_bytes(self.materials.capacity(), std::mem::size_of::<(ChunkKey, ChunkMaterials)>())
            + self.materials.values().map(ChunkMaterials::heap_bytes).sum::<usize>()
    }
}

/// A node's dither threshold in `[0, 1)`: a fixed hash of its global node coordinates.
fn dither(node: I64Vec3) -> f64 {
    let mut h = (node.x as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    h ^= (node.y as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f).rotate_left(21);
    h ^= (node.z as u64).wrapping_mul(0x1656_67b1_9e37_79f9).rotate_left(42);
    h ^= h >> 29;
    h = h.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h ^= h >> 32;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encodings_round_trip_and_are_canonical() {
        let n = 16;
        let mut rows = vec![0u128; n * n];
        rows[3] = 0b1111_0000_1111;
        rows[200] = (1 << 16) - 1;
        let mut ids = vec![0u8; n * n * n];
        for (i, v) in ids.iter_mut().enumerate() {
            *v = (i / 700) as u8;
        }
        let enc = ChunkMaterials::encode(&ids, &rows, n).expect("mixed");
        assert!(matches!(enc, ChunkMaterials::Runs(_)));
        enc.check(&rows, n).unwrap();
        let mut back = Vec::new();
        ChunkMaterials::decode_into(Some(&enc), n * n * n, &mut back);
        for (r, &row) in rows.iter().enumerate() {
            for x in 0..n {
                if row >> x & 1 == 1 {
                    assert_eq!(back[x + n * r], ids[x + n * r]);
                }
            }
        }
        // One id everywhere: uniform, and nothing at all for id 0.
        assert_eq!(ChunkMaterials::encode(&[4; 4096], &rows, n), Some(ChunkMaterials::Uniform(4)));
        assert_eq!(ChunkMaterials::encode(&[0; 4096], &rows, n), None);
        assert_eq!(ChunkMaterials::encode(&[4; 4096], &vec![0; n * n], n), None);
        // Not canonical: a change point on an empty node, a redundant one.
        let mut bytes = Vec::new();
        push_varint(&mut bytes, 0);
        bytes.push(1);
        push_varint(&mut bytes, 1);
        bytes.push(2);
        assert!(ChunkMaterials::Runs(bytes.into()).check(&rows, n).is_err());
        let raw = RawMaterials::Runs(vec![0, 1, 5, 1].into());
        assert!(ChunkMaterials::try_from(raw).is_err());
        assert!(ChunkMaterials::try_from(RawMaterials::Uniform(0)).is_err());
        assert!(ChunkMaterials::try_from(RawMaterials::Runs(vec![0x80].into())).is_err());
    }

    #[test]
    fn reading_rows_in_order_gives_what_decoding_gives() {
        let n = 16;
        let nodes = n * n * n;
        let mut seed = 7u64;
        let mut next = |m: u64| {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 33) % m
        };
        for _ in 0..50 {
            // Random solid rows and random ids in runs.
            let rows: Vec<u128> =
                (0..n * n).map(|_| if next(4) == 0 { 0 } else { (next(1 << 16) as u128) | 1 }).collect();
            let mut ids = vec![0u8; nodes];
            let mut id = 0;
            for v in ids.iter_mut() {
                if next(40) == 0 {
                    id = next(4) as u8;
                }
                *v = id;
            }
            let m = ChunkMaterials::encode(&ids, &rows, n);
            let mut all = Vec::new();
            ChunkMaterials::decode_into(m.as_ref(), nodes, &mut all);
            let mut reader = IdReader::new(m.as_ref());
            let mut start = 0;
            while start < nodes {
                // Runs that follow each other or skip nodes.
                let len = 1 + next(20) as usize;
                let len = len.min(nodes - start);
                let mut got = vec![0u8; len];
                reader.read(start, &mut got);
                assert_eq!(got, all[start..start + len]);
                start += [len, len + 1, len + next(300) as usize][next(3) as usize];
            }
        }
    }

    #[test]
    fn dither_thresholds_spread_over_the_unit_interval() {
        let t: Vec<f64> = (0..4096).map(|i| dither(I64Vec3::new(i % 16, i / 16 % 16, i / 256))).collect();
        assert!(t.iter().all(|v| (0.0..1.0).contains(v)));
        let below = t.iter().filter(|&&v| v < 0.5).count();
        assert!((1800..2300).contains(&below), "{below}");
    }
}
