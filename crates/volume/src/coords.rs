//! Chunk keys, resolution levels and chunk-local fixed-point positions.
//!
//! Spaces, and the names that carry them:
//! - *grid space* (`p_grid`, `DVec3`): base-level cells, one unit per base cell; world space is
//!   grid space times the volume's cell size.
//! - *node space* (`node`, `I64Vec3`): integer lattice of a resolution level; at level `k` node
//!   `i` sits at grid coordinate `i * 16 / (16 << k)`.
//! - *chunk-local fixed point* (`LocalPos`, `u16`): a position along a chunk's extent in 65,536
//!   steps, whatever the chunk's level.

use glam::{DVec3, I64Vec3, IVec3};
use serde::{Deserialize, Serialize};

/// Cells along one side of a chunk at level 0 (the paper's `w`).
pub const CHUNK_CELLS: i64 = 16;
/// Fixed-point steps across one chunk side.
pub const CHUNK_STEPS: u32 = 1 << 16;
/// Finest supported resolution level: 16 << 2 = 64 cells per chunk side.
pub const MAX_LEVEL: i8 = 2;
/// Coarsest supported resolution level: 8 cells of two grid units per chunk side.
pub const MIN_LEVEL: i8 = -1;

/// Identifies a chunk: the chunk `k` covers grid coordinates `[16 k, 16 k + 16)` on each axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ChunkKey(pub IVec3);

impl PartialOrd for ChunkKey {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Keys order by z, then y, then x (the storage order of lines).
impl Ord for ChunkKey {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.0.z, self.0.y, self.0.x).cmp(&(other.0.z, other.0.y, other.0.x))
    }
}

impl ChunkKey {
    /// The key from its three integer coordinates.
    pub const fn new(x: i32, y: i32, z: i32) -> Self {
        ChunkKey(IVec3::new(x, y, z))
    }

    /// Grid coordinate of the chunk's minimum corner.
    #[inline]
    pub fn origin_grid(self) -> I64Vec3 {
        self.0.as_i64vec3() * CHUNK_CELLS
    }

    /// The neighbouring key offset by `d` chunks (wrapping at the ends of the `i32` range,
    /// which edits never reach: they keep the outermost keys free).
    #[inline]
    pub fn offset(self, d: IVec3) -> ChunkKey {
        ChunkKey(self.0.wrapping_add(d))
    }

    /// This chunk and its 26 neighbours (across a face, an edge or a corner): the chunks whose
    /// meshes can share a seam with it.
    pub fn around(self) -> impl Iterator<Item = ChunkKey> {
        (0..27).map(move |d| self.offset(IVec3::new(d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1)))
    }

    /// The chunk holding the grid point `p_grid` (a point on a chunk's minimum face belongs to it).
    pub fn containing(p_grid: DVec3) -> Option<ChunkKey> {
        let c = (p_grid / CHUNK_CELLS as f64).floor();
        let ok = c.is_finite() && c.abs().max_element() <= i32::MAX as f64 && c.min_element() >= i32::MIN as f64;
        ok.then(|| ChunkKey(c.as_ivec3()))
    }
}

/// A box of chunk keys, both corners included: the chunks an edit, a region or a load reaches.
/// Its keys come in storage order (z, then y, then x), as [`ChunkKey`]'s `Ord` sorts them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChunkBox {
    /// The lowest corner.
    pub lo: IVec3,
    /// The highest corner (included).
    pub hi: IVec3,
}

impl ChunkBox {
    /// The keys from `lo` to `hi`, both included (empty where `hi` is below `lo` on an axis).
    pub fn new(lo: IVec3, hi: IVec3) -> Self {
        ChunkBox { lo, hi }
    }

    /// The box from chunk `lo` to chunk `hi`.
    pub fn between(lo: ChunkKey, hi: ChunkKey) -> Self {
        ChunkBox { lo: lo.0, hi: hi.0 }
    }

    /// How many keys it holds (`u64::MAX` for a box of more).
    pub fn len(&self) -> u64 {
        let span = (self.hi.as_i64vec3() - self.lo.as_i64vec3() + glam::I64Vec3::ONE).max(glam::I64Vec3::ZERO);
        let n = span.x as u128 * span.y as u128 * span.z as u128;
        u64::try_from(n).unwrap_or(u64::MAX)
    }

    /// Whether it holds no key.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether `k` is inside.
    pub fn contains(&self, k: ChunkKey) -> bool {
        k.0.cmpge(self.lo).all() && k.0.cmple(self.hi).all()
    }

    /// Every key, in storage order.
    pub fn keys(self) -> impl Iterator<Item = ChunkKey> {
        let ChunkBox { lo, hi } = self;
        (lo.z..=hi.z)
            .flat_map(move |z| (lo.y..=hi.y).flat_map(move |y| (lo.x..=hi.x).map(move |x| ChunkKey::new(x, y, z))))
    }
}

/// A per-chunk resolution level: level `k` has `16 · 2^k` cells along each side of the chunk,
/// from [`MIN_LEVEL`] (−1: 8 cells of two grid units, for far terrain) to [`MAX_LEVEL`] (2: 64).
/// Serialised as its number in one signed byte, so files written before the coarse level
/// existed (levels 0–2) read the same.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "i8", into = "i8")]
pub struct Level(u8);

impl std::fmt::Debug for Level {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Level({})", self.get())
    }
}

impl TryFrom<i8> for Level {
    type Error = String;

    fn try_from(k: i8) -> Result<Self, String> {
        Level::new(k).ok_or_else(|| format!("resolution level {k} is outside {MIN_LEVEL}..={MAX_LEVEL}"))
    }
}

impl From<Level> for i8 {
    fn from(l: Level) -> i8 {
        l.get()
    }
}

/// How many levels there are (arrays indexed by [`Level::index`]).
pub const LEVEL_COUNT: usize = (MAX_LEVEL - MIN_LEVEL) as usize + 1;

impl Level {
    /// The coarsest level, [`MIN_LEVEL`]: 8 cells per chunk side, each two grid units.
    pub const COARSEST: Level = Level(0);

    /// The base level, 16 cells per chunk side.
    pub const BASE: Level = Level((-MIN_LEVEL) as u8);

    /// The finest level, [`MAX_LEVEL`] (64 cells per chunk side).
    pub const FINEST: Level = Level((MAX_LEVEL - MIN_LEVEL) as u8);

    /// Every level, coarsest first.
    pub const ALL: [Level; LEVEL_COUNT] = [Level(0), Level(1), Level(2), Level(3)];

    /// The level `k`, or `None` outside [`MIN_LEVEL`]`..=`[`MAX_LEVEL`].
    pub const fn new(k: i8) -> Option<Level> {
        if k >= MIN_LEVEL && k <= MAX_LEVEL { Some(Level((k - MIN_LEVEL) as u8)) } else { None }
    }

    /// The level number (0 the base level, negative coarser, positive finer).
    #[inline]
    pub fn get(self) -> i8 {
        self.0 as i8 + MIN_LEVEL
    }

    /// Its place among the levels, coarsest 0: an index into arrays of [`LEVEL_COUNT`].
    #[inline]
    pub fn index(self) -> usize {
        self.0 as usize
    }

    /// The next finer level, if any.
    #[inline]
    pub fn finer(self) -> Option<Level> {
        (self < Level::FINEST).then_some(Level(self.0 + 1))
    }

    /// The next coarser level, if any.
    #[inline]
    pub fn coarser(self) -> Option<Level> {
        (self > Level::COARSEST).then(|| Level(self.0 - 1))
    }

    /// How many times finer than `coarse` this level is (`2^(self - coarse)`); `coarse` must
    /// not be finer.
    #[inline]
    pub fn ratio_to(self, coarse: Level) -> usize {
        debug_assert!(coarse <= self);
        1 << (self.0 - coarse.0)
    }

    /// Its two-bit code in a chunk's header: the level number for levels 0–2, as chunks were
    /// stored before the coarse level existed, and 3 for level −1.
    #[inline]
    pub(crate) fn code(self) -> u8 {
        self.get().rem_euclid(4) as u8
    }

    /// The level of a header code ([`Level::code`]).
    #[inline]
    pub(crate) fn from_code(c: u8) -> Option<Level> {
        match c {
            0..=2 => Level::new(c as i8),
            3 => Some(Level::COARSEST),
            _ => None,
        }
    }

    /// The node at grid point `g` (on this level's lattice: even coordinates at level −1).
    #[inline]
    pub fn node_of_grid(self, g: I64Vec3) -> I64Vec3 {
        if self >= Level::BASE { g * (1 << (self.0 - Level::BASE.0)) } else { g.div_euclid(I64Vec3::splat(2)) }
    }

    /// Cells (and node lines) along one chunk side.
    #[inline]
    pub fn cells(self) -> usize {
        8 << self.0
    }

    /// Fixed-point steps per cell.
    #[inline]
    pub fn steps_per_cell(self) -> u32 {
        8192 >> self.0
    }

    /// log2 of [`Level::steps_per_cell`].
    #[inline]
    pub fn steps_shift(self) -> u32 {
        13 - self.0 as u32
    }

    /// Distance between neighbouring nodes in grid units.
    #[inline]
    pub fn spacing(self) -> f64 {
        // Exact powers of two; a table avoids a division on hot paths.
        [2.0, 1.0, 0.5, 0.25][self.0 as usize]
    }

    /// Nodes per grid unit (`1 / spacing`).
    #[inline]
    pub fn nodes_per_unit(self) -> f64 {
        [0.5, 1.0, 2.0, 4.0][self.0 as usize]
    }
}

/// A position along a chunk's extent: `value / 65536` of the chunk side. Positions are always
/// even (2,048 steps per base cell): chunk storage keeps them as plain 16-bit words in one stream
/// with the normals ([`crate::normal::PackedNormal`]) and uses bit 0 of a stored word to mark
/// the last crossing of a line, so a `LocalPos` (what readers see) never has bit 0 set. A type
/// of its own so that a position is never taken for a normal, a node index or a marked word.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(transparent)]
pub struct LocalPos(pub u16);

impl std::fmt::Display for LocalPos {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

/// Grid-unit offset (from the chunk's minimum face) of a fixed-point position.
#[inline]
pub fn local_pos_to_grid(q: LocalPos) -> f64 {
    q.0 as f64 * (CHUNK_CELLS as f64 / CHUNK_STEPS as f64)
}

/// Quantises a grid-unit offset along a chunk line into the open cell `edge` of `level`: the
/// result is even and lies strictly between the fixed-point positions of the edge's two nodes,
/// so a crossing never sits on a node — of this level or of any finer one (a position on a node
/// of level [`MAX_LEVEL`] moves by two steps), so raising a chunk's level never finds a crossing
/// on one of its new nodes and lowering it again gives back the same positions.
#[inline]
pub fn quantize_into_edge(t_grid: f64, edge: usize, level: Level) -> LocalPos {
    quantize_steps(t_grid * (CHUNK_STEPS as f64 / CHUNK_CELLS as f64), edge, level)
}

/// [`quantize_into_edge`] for a position given in fixed-point steps from the chunk's minimum face.
#[inline]
pub fn quantize_steps(steps: f64, edge: usize, level: Level) -> LocalPos {
    // In units of two fixed-point steps.
    let s = level.steps_per_cell() as i64 / 2;
    let lo = edge as i64 * s + 1;
    let hi = (edge as i64 + 1) * s - 1;
    // Round half up without a libm call: the cast truncates towards zero and saturates, which
    // the clamp makes harmless for values below `lo` (at least 1) or far beyond `hi`.
    let q = steps / 2.0 + 0.5;
    let q = if q.is_nan() { (lo + hi) / 2 } else { q as i64 };
    let mut q = q.clamp(lo, hi);
    if q % FINEST_HALF_STEPS == 0 {
        // On a node of the finest level: one unit towards the inside of the edge.
        q += if q < hi { 1 } else { -1 };
    }
    LocalPos((q * 2) as u16)
}

/// Half-steps (units of two fixed-point steps) between nodes of the finest level.
const FINEST_HALF_STEPS: i64 = (4096 >> MAX_LEVEL) / 2;

/// Whether a stored position lies on a node of the finest level (only files written before
/// resolution levels could be changed hold such positions).
#[inline]
pub fn on_finest_node(q: LocalPos) -> bool {
    (q.0 as i64 / 2) % FINEST_HALF_STEPS == 0
}

/// The cell (edge index along the line) a fixed-point position lies in.
#[inline]
pub fn edge_of(q: LocalPos, level: Level) -> usize {
    (q.0 as u32 >> level.steps_shift()) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chunk_box_lists_its_keys_in_storage_order_and_counts_them() {
        let b = ChunkBox::new(IVec3::new(-1, 0, 2), IVec3::new(0, 2, 3));
        let keys: Vec<ChunkKey> = b.keys().collect();
        assert_eq!(keys.len() as u64, b.len());
        assert_eq!(b.len(), 2 * 3 * 2);
        assert!(keys.windows(2).all(|w| w[0] < w[1]), "storage order");
        assert!(keys.iter().all(|&k| b.contains(k)));
        assert!(!b.contains(ChunkKey::new(1, 0, 2)) && !b.contains(ChunkKey::new(-1, 0, 4)));
        let empty = ChunkBox::new(IVec3::ONE, IVec3::ZERO);
        assert!(empty.is_empty() && empty.keys().next().is_none());
        let huge = ChunkBox::new(IVec3::splat(i32::MIN), IVec3::splat(i32::MAX));
        assert_eq!(huge.len(), u64::MAX, "2⁹⁶ keys saturate");
    }

    #[test]
    fn quantised_positions_stay_strictly_inside_their_edge() {
        for k in 0..=MAX_LEVEL {
            let level = Level::new(k).unwrap();
            let s = level.steps_per_cell();
            for edge in [0, 1, level.cells() - 1] {
                let mid = (edge as f64 + 0.5) * level.spacing();
                for t in [-5.0, 0.0, edge as f64 * level.spacing(), mid, mid + 0.25, 1e9, f64::NAN] {
                    let q = quantize_into_edge(t, edge, level);
                    assert_eq!(edge_of(q, level), edge);
                    assert_ne!(q.0 as u32 % s, 0, "a crossing must not sit on a node");
                    assert_eq!(q.0 % 2, 0, "positions are even");
                    assert!(!on_finest_node(q), "nor on a node of a finer level");
                }
            }
        }
    }

    #[test]
    fn chunk_of_negative_points_rounds_down() {
        assert_eq!(ChunkKey::containing(DVec3::new(-0.5, 0.0, 16.0)), Some(ChunkKey::new(-1, 0, 1)));
        assert_eq!(ChunkKey::containing(DVec3::splat(f64::NAN)), None);
        assert_eq!(ChunkKey::containing(DVec3::splat(1e30)), None);
    }
}
