//! Voxel blocks: what meshers see of one chunk. The inside/outside state of its `(n+1)³` nodes
//! and, on every cell edge whose two nodes differ, the crossing position and normal (the paper's
//! V and P_s), with the `+1` apron read from the neighbouring chunks.
//!
//! Border contract: a block owns the cells `0..n` on each axis; its apron nodes (index `n`) and
//! the edges that lie on its `+x`, `+y`, `+z` faces are copies of the neighbours' data, so two
//! blocks agree exactly on what they share and meshes of neighbouring chunks meet without cracks.

use glam::{I64Vec3, IVec3};
use rayon::prelude::*;

use crate::axis::{Axis, compose};
use crate::chunk::{ChunkView, ViewCursor, node_mask};
use crate::coords::{ChunkKey, Level, edge_of};
use crate::normal::PackedNormal;
use crate::volume::Volume;

/// A surface crossing on one cell edge of a block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeCrossing {
    /// Block-local node at the lower end of the edge.
    pub lower: [u8; 3],
    /// Position along the edge, strictly between 0 (the lower node) and 1.
    pub t: f32,
    /// Outward normal, octahedral-packed (see [`crate::normal::unpack_normal`]).
    pub normal: PackedNormal,
}

/// A vertex that a finer neighbour's mesh has on a contour segment of a shared face: a crossing
/// of the neighbour's level, given in this block's frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeamPoint {
    /// The axis of the fine edge it lies on.
    pub axis: Axis,
    /// The finer level.
    pub level: Level,
    /// Lower node of the fine edge, block-local in units of `level`'s cells.
    pub lower: [u16; 3],
    /// Position along the fine edge, strictly between 0 and 1.
    pub t: f32,
    /// Outward normal, octahedral-packed.
    pub normal: PackedNormal,
}

impl SeamPoint {
    /// Position in grid units from the block's origin.
    pub fn position(&self) -> [f32; 3] {
        let sp = self.level.spacing() as f32;
        let mut p = self.lower.map(|c| c as f32);
        p[self.axis.index()] += self.t;
        p.map(|c| c * sp)
    }
}

/// One contour segment of a block face shared with a finer neighbour, between the crossings on
/// edges `a` and `b` of the block (axis, lower node): the finer mesh passes through `points`
/// (in order from `a`) on its way, so the triangle of this block on that segment must be split
/// there for the two meshes to share edges.
#[derive(Clone, Debug, PartialEq)]
pub struct SeamSplit {
    /// The crossing where the segment starts.
    pub a: (Axis, [u16; 3]),
    /// The crossing where it ends.
    pub b: (Axis, [u16; 3]),
    /// The finer neighbour's vertices between them.
    pub points: Vec<SeamPoint>,
}

/// Node states and edge crossings of one chunk plus its apron.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoxelBlock {
    key: Option<ChunkKey>,
    level: Option<Level>,
    n: usize,
    /// Node `(0, 0, 0)` of the block is node `offset` of its chunk (zero for a whole chunk's
    /// block, see [`Volume::extract_part`]).
    offset: [usize; 3],
    /// `rows[y + (n+1) z]`, bit `x`: whether node `(x, y, z)` is inside.
    rows: Vec<u128>,
    crossings: [Vec<EdgeCrossing>; 3],
    /// Per axis, the index into `crossings` of the edge whose lower node is `node_index(..)`, or
    /// `u32::MAX`.
    lookup: [Vec<u32>; 3],
    repaired: u32,
    /// Edges changed to meet a neighbour of another level (crack patching).
    patched: u32,
    pub(crate) seams: Vec<SeamSplit>,
    /// Material of every node (`x + (n+1) (y + (n+1) z)`), read in the chunk that owns it;
    /// empty when the volume has no material but 0.
    materials: Vec<crate::MaterialId>,
}

const NONE: u32 = u32::MAX;

impl VoxelBlock {
    /// The material of node `(x, y, z)` (each in `0..=n`), meaningful where the node is inside:
    /// the id stored for the node of the chunk that owns it (at a coarser block level, the
    /// stored node it coincides with; across a border to a coarser chunk, its nearest node).
    #[inline]
    pub fn material(&self, x: usize, y: usize, z: usize) -> crate::MaterialId {
        if self.materials.is_empty() { 0 } else { self.materials[self.node_index(x, y, z)] }
    }

    /// Whether any node of the block may have a material other than 0.
    pub fn has_materials(&self) -> bool {
        !self.materials.is_empty()
    }

    /// Sets the material of every node from `id(x, y, z)` (for blocks built with
    /// [`VoxelBlock::from_fn`]).
    pub fn set_materials(&mut self, id: impl Fn(usize, usize, usize) -> crate::MaterialId) {
        let m = self.n + 1;
        self.materials.clear();
        self.materials.resize(m * m * m, 0);
        for z in 0..m {
            for y in 0..m {
                for x in 0..m {
                    self.materials[x + m * (y + m * z)] = id(x, y, z);
                }
            }
        }
    }

    /// The chunk this block was extracted from (`None` before the first extraction).
    pub fn key(&self) -> Option<ChunkKey> {
        self.key
    }

    /// Cells per side.
    pub fn cells(&self) -> usize {
        self.n
    }

    /// The chunk's resolution level.
    pub fn level(&self) -> Level {
        self.level.unwrap_or(Level::BASE)
    }

    /// Grid coordinate of the chunk's node `(0, 0, 0)` (the block's own first node is
    /// [`VoxelBlock::offset`] cells of its level further).
    pub fn origin_grid(&self) -> I64Vec3 {
        self.key.map(|k| k.origin_grid()).unwrap_or_default()
    }

    /// The chunk node that is node `(0, 0, 0)` of this block, in cells of its level: zero for
    /// a chunk's whole block, the part's first cell for [`Volume::extract_part`].
    pub fn offset(&self) -> [usize; 3] {
        self.offset
    }

    #[inline]
    fn node_index(&self, x: usize, y: usize, z: usize) -> usize {
        let m = self.n + 1;
        x + m * (y + m * z)
    }

    /// Whether node `(x, y, z)` (each in `0..=n`) is inside.
    #[inline]
    pub fn inside(&self, x: usize, y: usize, z: usize) -> bool {
        (self.rows[y + (self.n + 1) * z] >> x) & 1 == 1
    }

    /// Bits along x of the node row `(y, z)`: bit `x` is node `(x, y, z)`.
    #[inline]
    pub fn row(&self, y: usize, z: usize) -> u128 {
        self.rows[y + (self.n + 1) * z]
    }

    /// Cells of the row `(y, z)` (`y`, `z` in `0..n`) whose eight corners are not all alike: bit
    /// `x` for cell `(x, y, z)`.
    #[inline]
    pub fn mixed_cells(&self, y: usize, z: usize) -> u128 {
        let (r00, r10, r01, r11) = (self.row(y, z), self.row(y + 1, z), self.row(y, z + 1), self.row(y + 1, z + 1));
        let any = r00 | r10 | r01 | r11;
        let all = r00 & r10 & r01 & r11;
        (any | (any >> 1)) & !(all & (all >> 1)) & ((1u128 << self.n) - 1)
    }

    /// The crossings on the twelve edges of cell `(x, y, z)`: axis, the edge's lower node, and
    /// the crossing.
    pub fn cell_crossings(
        &self,
        x: usize,
        y: usize,
        z: usize,
    ) -> impl Iterator<Item = (Axis, [usize; 3], &EdgeCrossing)> {
        Axis::ALL.into_iter().flat_map(move |axis| {
            let (ua, va) = axis.across();
            (0..4).filter_map(move |k| {
                let mut lower = [x, y, z];
                lower[ua.index()] += k & 1;
                lower[va.index()] += k >> 1;
                self.crossing(axis, lower[0], lower[1], lower[2]).map(|c| (axis, lower, c))
            })
        })
    }

    /// The crossings on edges along `axis`.
    pub fn crossings(&self, axis: Axis) -> &[EdgeCrossing] {
        &self.crossings[axis.index()]
    }

    /// The crossing on the edge along `axis` whose lower node is `(x, y, z)`.
    #[inline]
    pub fn crossing(&self, axis: Axis, x: usize, y: usize, z: usize) -> Option<&EdgeCrossing> {
        let i = *self.lookup[axis.index()].get(self.node_index(x, y, z))?;
        self.crossings[axis.index()].get(i as usize)
    }

    /// Index of that crossing in [`VoxelBlock::crossings`].
    #[inline]
    pub fn crossing_index(&self, axis: Axis, x: usize, y: usize, z: usize) -> Option<u32> {
        let i = *self.lookup[axis.index()].get(self.node_index(x, y, z))?;
        (i != NONE).then_some(i)
    }

    /// Inconsistent crossings the extractor found and repaired: a crossing on an edge whose nodes
    /// agree (dropped) or an edge whose nodes differ without a crossing (given one at its
    /// middle). Zero for every volume built by this crate's edits.
    pub fn repaired(&self) -> u32 {
        self.repaired
    }

    /// Edges the extractor changed so that the block meets a neighbour of another level: the
    /// edges from a shared face into the chunk whose face node the coarser side decided
    /// (crack patching, on the block only; the stored lists are untouched).
    pub fn patched(&self) -> u32 {
        self.patched
    }

    /// The contour segments of faces shared with finer neighbours that the neighbours' meshes
    /// split (empty where every neighbour has this block's level).
    pub fn seams(&self) -> &[SeamSplit] {
        &self.seams
    }

    /// Lists each axis's crossings line by line: lines across the axis in
    /// [`Axis::across`] order (line `u + (n+1) v`), then along each line, as extraction lists
    /// them from the stored lines (a block filled from a dense grid, as crack patching and
    /// [`VoxelBlock::from_fn`] fill one, lists every axis in node order, z then y then x, which
    /// is line order for x only). The lookup follows; nothing else changes. Returns whether any
    /// crossing moved.
    pub fn list_line_by_line(&mut self) -> bool {
        let m = self.n + 1;
        let mut moved = false;
        for axis in Axis::ALL {
            let a = axis.index();
            let (ua, va) = (axis.across().0.index(), axis.across().1.index());
            let order = |c: &EdgeCrossing| (c.lower[ua] as usize + m * c.lower[va] as usize, c.lower[a]);
            if self.crossings[a].is_sorted_by_key(order) {
                continue;
            }
            moved = true;
            self.crossings[a].sort_unstable_by_key(order);
            for (i, c) in self.crossings[a].iter().enumerate() {
                let [x, y, z] = c.lower.map(usize::from);
                let at = x + m * (y + m * z);
                self.lookup[a][at] = i as u32;
            }
        }
        moved
    }

    /// A block from a dense grid of node states and crossings.
    pub(crate) fn fill_from_dense(&mut self, key: ChunkKey, level: Level, d: &crate::level::Dense, patched: u32) {
        self.fill_from_parts(
            key,
            level,
            |x, y, z| d.state([x, y, z]),
            |axis, lower| {
                let c = d.crossing(axis, lower);
                let e = lower[axis.index()] as u32;
                let s = level.steps_per_cell();
                let q = crate::level::face::pos(c).0 as u32;
                ((q - e * s) as f32 * (1.0 / s as f32), crate::level::face::nrm(c))
            },
        );
        self.patched = patched;
    }
    /// A block built from functions instead of a volume (for other representations and tests):
    /// `inside(x, y, z)` for every node in `0..=n`, and `crossing(axis, lower, nodes differ)` the
    /// position in `(0, 1)` and outward normal of the crossing on each edge whose nodes differ.
    pub fn from_fn(
        key: ChunkKey,
        level: Level,
        inside: impl Fn(usize, usize, usize) -> bool,
        crossing: impl Fn(Axis, [usize; 3]) -> (f32, glam::Vec3),
    ) -> VoxelBlock {
        let mut b = VoxelBlock::default();
        b.fill_from_fn(key, level, inside, crossing);
        b
    }

    /// [`VoxelBlock::from_fn`] into an existing block, reusing its allocations. Crossings are
    /// visited per axis in node order (`x` fastest), the order extraction from a volume uses.
    pub fn fill_from_fn(
        &mut self,
        key: ChunkKey,
        level: Level,
        inside: impl Fn(usize, usize, usize) -> bool,
        crossing: impl Fn(Axis, [usize; 3]) -> (f32, glam::Vec3),
    ) {
        self.fill_from_parts(key, level, inside, |axis, lower| {
            let (t, normal) = crossing(axis, lower);
            (t.clamp(1e-6, 1.0 - 1e-6), crate::normal::pack_normal(normal.as_dvec3()))
        });
    }

    /// [`VoxelBlock::fill_from_fn`] with packed normals and positions already inside the edge.
    fn fill_from_parts(
        &mut self,
        key: ChunkKey,
        level: Level,
        inside: impl Fn(usize, usize, usize) -> bool,
        crossing: impl Fn(Axis, [usize; 3]) -> (f32, PackedNormal),
    ) {
        self.reset(key, level);
        let n = self.n;
        let m = n + 1;
        for z in 0..m {
            for y in 0..m {
                let mut row = 0u128;
                for x in 0..m {
                    row |= (inside(x, y, z) as u128) << x;
                }
                self.rows[y + m * z] = row;
            }
        }
        for axis in Axis::ALL {
            let a = axis.index();
            for z in 0..m {
                for y in 0..m {
                    let row = self.rows[y + m * z];
                    // Bit x: the edge along `axis` from node (x, y, z) changes state.
                    let mut changes = match axis {
                        Axis::X => (row ^ (row >> 1)) & ((1u128 << n) - 1),
                        Axis::Y if y < n => row ^ self.rows[y + 1 + m * z],
                        Axis::Z if z < n => row ^ self.rows[y + m * (z + 1)],
                        _ => 0,
                    };
                    while changes != 0 {
                        let x = changes.trailing_zeros() as usize;
                        changes &= changes - 1;
                        let lower = [x, y, z];
                        let (t, normal) = crossing(axis, lower);
                        let idx = self.node_index(x, y, z);
                        self.lookup[a][idx] = self.crossings[a].len() as u32;
                        self.crossings[a].push(EdgeCrossing { lower: lower.map(|c| c as u8), t, normal });
                    }
                }
            }
        }
    }

    fn reset(&mut self, key: ChunkKey, level: Level) {
        self.reset_part(key, level, [0; 3], level.cells());
    }

    /// Empties the block for `n` cells a side of the chunk `key` from its node `offset`.
    fn reset_part(&mut self, key: ChunkKey, level: Level, offset: [usize; 3], n: usize) {
        let m = n + 1;
        self.key = Some(key);
        self.level = Some(level);
        self.n = n;
        self.offset = offset;
        self.rows.clear();
        self.rows.resize(m * m, 0);
        for a in 0..3 {
            self.crossings[a].clear();
            self.lookup[a].clear();
            self.lookup[a].resize(m * m * m, NONE);
        }
        self.repaired = 0;
        self.patched = 0;
        self.seams.clear();
        self.materials.clear();
    }
}

impl Volume {
    /// The voxel block of the chunk at `key`.
    pub fn extract_block(&self, key: ChunkKey) -> VoxelBlock {
        let mut b = VoxelBlock::default();
        self.extract_block_into(key, &mut b);
        b
    }

    /// The voxel blocks of `keys`, in parallel.
    pub fn extract_blocks(&self, keys: &[ChunkKey]) -> Vec<VoxelBlock> {
        keys.par_iter().map(|&k| self.extract_block(k)).collect()
    }

    /// Extracts the block of `key` into `out`, reusing its allocations. Where the chunk or a
    /// neighbour across a face or an edge is stored at another level, the shared faces are
    /// patched to meet (see [`VoxelBlock::patched`] and [`VoxelBlock::seams`]). A uniform
    /// chunk whose face and edge neighbours are all meshed at one level at or below the
    /// volume's, or are uniform with no list chunk beside them (far terrain's coarse chunks
    /// around the sky and the rock beside them), is read at that level straight from its
    /// neighbours' lines, as level of detail reads it: nothing differs in level there to patch.
    pub fn extract_block_into(&self, key: ChunkKey, out: &mut VoxelBlock) {
        if !self.single_level() {
            let map = crate::level::LevelMap::stored(self);
            if !crate::level::plain(&map, key) {
                // (The cheap test first: most blocks that fail it hold sky or rock alone.)
                if !self.plain_block_uniform(key) && crate::level::same_level_around(&map, key) {
                    extract_sampled(&map, key, out);
                } else {
                    self.extract_unplain(&map, key, out);
                }
                self.fill_block_materials(out);
                return;
            }
        }
        self.extract_plain(key, out);
        self.fill_block_materials(out);
    }

    /// Fills the block's node materials from the chunks owning its nodes (nothing when the
    /// volume has no material but 0).
    fn fill_block_materials(&self, out: &mut VoxelBlock) {
        out.materials.clear();
        let Some(key) = out.key else { return };
        if !self.has_materials() {
            return;
        }
        // The block's cells per side, the chunk's, and the chunk node of the block's node 0.
        let (w, n, off) = (out.n, out.level().cells(), out.offset);
        let m = w + 1;
        out.materials.resize(m * m * m, 0);
        // The owners: this chunk (o = 0) and its neighbours across the far faces, edges and
        // corner (bit 0: x = n, bit 1: y = n, bit 2: z = n), each read at its stored level.
        let mut ids = Vec::new();
        for o in 0..8usize {
            let far = [o & 1 == 1, o & 2 == 2, o & 4 == 4];
            let owner = key.offset(IVec3::new(far[0] as i32, far[1] as i32, far[2] as i32));
            // The block's nodes on axis `i` that `owner` holds: those before the chunk's node n,
            // or that node itself.
            let range = |i: usize| {
                let near_end = (n - off[i]).min(m);
                if far[i] { near_end..m } else { 0..near_end }
            };
            let (xs, ys, zs) = (range(0), range(1), range(2));
            if xs.is_empty() || ys.is_empty() || zs.is_empty() {
                continue;
            }
            match self.chunk_materials(owner) {
                None => {} // material 0: already there
                Some(crate::ChunkMaterials::Uniform(id)) => {
                    for z in zs {
                        for y in ys.clone() {
                            let row = m * (y + m * z);
                            out.materials[row + xs.start..row + xs.end].fill(*id);
                        }
                    }
                }
                Some(stored) if self.level_of(owner).cells() == n => {
                    // The owner at the block's level: only the rows the block needs, read in
                    // order from the change points.
                    let mut reader = crate::material::IdReader::new(Some(stored));
                    let at = |c: usize, i: usize| if far[i] { 0 } else { c + off[i] };
                    for z in zs {
                        for y in ys.clone() {
                            let row = m * (y + m * z);
                            let src = at(xs.start, 0) + n * (at(y, 1) + n * at(z, 2));
                            reader.read(src, &mut out.materials[row + xs.start..row + xs.end]);
                        }
                    }
                }
                Some(_) => {
                    // An owner at another level: its nearest node.
                    let level = self.level_of(owner);
                    let on = level.cells();
                    self.decode_materials(owner, level, &mut ids);
                    // The owner's node for block node `c` on axis `i`.
                    let at =
                        |c: usize, i: usize| if far[i] { 0 } else { (((c + off[i]) * on + n / 2) / n).min(on - 1) };
                    for z in zs {
                        for y in ys.clone() {
                            let src = on * (at(y, 1) + on * at(z, 2));
                            let row = m * (y + m * z);
                            for x in xs.clone() {
                                out.materials[row + x] = ids[src + at(x, 0)];
                            }
                        }
                    }
                }
            }
        }
    }

    /// The block of `key` meshed at no finer than `cap(k)` for every chunk `k` (level of detail:
    /// a coarser block sampled from the stored lists, the paper's VI-B), with the seams between
    /// chunks of different levels patched as in [`Volume::extract_block_into`].
    pub fn extract_block_capped(&self, key: ChunkKey, cap: &(dyn Fn(ChunkKey) -> Level + Sync), out: &mut VoxelBlock) {
        let map = crate::level::LevelMap::new(self, Some(cap), None);
        if self.single_level() && crate::level::plain(&map, key) {
            self.extract_plain(key, out);
        } else if crate::level::same_level_around(&map, key) {
            extract_sampled(&map, key, out);
        } else {
            self.extract_unplain(&map, key, out);
        }
        self.fill_block_materials(out);
    }

    /// The block of `key` where its neighbours are meshed at other levels: one state at every
    /// node where the chunk and its apron's owners are uniform alike (nothing to read, no
    /// crossing to patch: what patching gives, without its dense grid), else patched.
    fn extract_unplain(&self, map: &crate::level::LevelMap<'_>, key: ChunkKey, out: &mut VoxelBlock) {
        if !self.plain_block_uniform(key) {
            crate::level::extract_patched(map, key, out);
            return;
        }
        let level = map.get(key);
        out.reset(key, level);
        if self.view(key) == ChunkView::Uniform(true) {
            let full = node_mask(level.cells());
            out.rows.iter_mut().for_each(|r| *r = full);
        }
    }

    /// The level `key` is meshed at (its own for a list chunk; for a uniform chunk the highest
    /// of its list neighbours across a face or an edge, else the volume's level).
    pub fn mesh_level(&self, key: ChunkKey) -> Level {
        crate::level::LevelMap::stored(self).get(key)
    }

    fn extract_plain(&self, key: ChunkKey, out: &mut VoxelBlock) {
        self.extract_lines(key, [0; 3], self.level_of(key).cells(), out);
    }

    /// The block of the cells `offset .. offset + cells` (on each axis, in cells of the chunk's
    /// level) of chunk `key`, with their `+1` apron: what [`Volume::extract_block_into`] gives
    /// for those cells, as a block of `cells` cells a side whose [`VoxelBlock::offset`] is
    /// `offset`. Only the lines through the part are read. Meaningful where the chunk's block is
    /// read plainly ([`Volume::plain_block_level`]): a part has no seams to patch.
    ///
    /// # Panics
    /// If `cells` is 0 or the part reaches past the chunk.
    pub fn extract_part(&self, key: ChunkKey, offset: [usize; 3], cells: usize, out: &mut VoxelBlock) {
        let n = self.level_of(key).cells();
        assert!(
            cells > 0 && offset.iter().all(|&o| o + cells <= n),
            "a part of {cells} cells from {offset:?} of a {n}-cell chunk"
        );
        self.extract_lines(key, offset, cells, out);
        self.fill_block_materials(out);
    }

    /// The level at which the block of `key` is read straight from its own lines and those of
    /// its neighbours at one level, nothing patched (level of detail capped by `cap`, if any):
    /// the chunk's stored level where its face and edge neighbours share it, else `None`.
    pub fn plain_block_level(&self, key: ChunkKey, cap: Option<&(dyn Fn(ChunkKey) -> Level + Sync)>) -> Option<Level> {
        let plain = match cap {
            None => self.single_level() || crate::level::plain(&crate::level::LevelMap::stored(self), key),
            // (Every chunk around capped at its stored level: read as stored.)
            Some(c) => crate::level::plain(&crate::level::LevelMap::new(self, Some(c), None), key),
        };
        plain.then(|| self.level_of(key))
    }

    /// Whether every node of the plain block of `key` has one state: the chunk and the six
    /// after it across a face or an edge (its apron's owners but the corner one) are uniform
    /// alike, so the block holds no surface. (The corner node, owned by the chunk after it
    /// across the corner, lies at the end of a line of an edge neighbour: uniform, that line
    /// binds it to the same state whatever the corner chunk stores.)
    pub fn plain_block_uniform(&self, key: ChunkKey) -> bool {
        let state = |k: ChunkKey| match self.view(k) {
            ChunkView::Uniform(s) => Some(s),
            ChunkView::Lists(_) => None,
        };
        let Some(first) = state(key) else { return false };
        (1..7).all(|d| state(key.offset(IVec3::new(d & 1, (d >> 1) & 1, (d >> 2) & 1))) == Some(first))
    }

    /// Node states and crossings of the part of `key`'s block from node `offset`, `w` cells a
    /// side (the whole block for offset 0 and `w = n`), read from the lines through it.
    fn extract_lines(&self, key: ChunkKey, offset: [usize; 3], w: usize, out: &mut VoxelBlock) {
        let level = self.level_of(key);
        out.reset_part(key, level, offset, w);
        let n = level.cells();
        let m = w + 1;
        let s = level.steps_per_cell();
        let inv_s = 1.0 / s as f32;
        for axis in Axis::ALL {
            let (ua, va) = axis.across();
            let a = axis.index();
            let (oa, ou, ov) = (offset[a], offset[ua.index()], offset[va.index()]);
            let mut expected_ok = true;
            // One cursor per source chunk: this chunk, its neighbours along `ua`, `va` and both.
            let mut cursors: [Option<ViewCursor<'_>>; 4] = [None, None, None, None];
            // (Each source chunk looked up once, not once a row.)
            let mut views: [Option<ChunkView<'_>>; 4] = [None; 4];
            for v in ov..=ov + w {
                // Lines u < n come from one chunk, u = n from its neighbour along `ua`.
                let base = key.offset(if v == n { unit(va) } else { IVec3::ZERO });
                let far = if ou + w == n { n..n + 1 } else { 0..0 };
                let sources = [(base, ou..(ou + w + 1).min(n)), (base.offset(unit(ua)), far)];
                for (k, (source, us)) in sources.into_iter().enumerate() {
                    if us.is_empty() {
                        continue;
                    }
                    let view = *views[2 * usize::from(v == n) + k].get_or_insert_with(|| self.view(source));
                    if let ChunkView::Lists(l) = view
                        && l.level() != level
                    {
                        // Mixed levels are not created by any edit yet; read nothing rather than
                        // misread (the extractor's repair then closes the surface).
                        continue;
                    }
                    let cursor = cursors[2 * usize::from(v == n) + k].get_or_insert_with(|| view.cursor(axis, 0));
                    cursor.advance_to((us.start % n) + n * (v % n));
                    for u in us {
                        let (pu, pv) = (u - ou, v - ov);
                        // x lines derive their start states; y and z lines start on nodes the x
                        // lines have already given (only their crossings are read here).
                        let line = match axis {
                            Axis::X => cursor.next_line(),
                            Axis::Y | Axis::Z => cursor.next_with(false),
                        };
                        let mut states = if line.start_inside { node_mask(n) } else { 0 };
                        for (q, &nr) in line.positions().zip(line.normals) {
                            let e = edge_of(q, level);
                            if axis == Axis::X {
                                states ^= node_mask(n) & !((1u128 << (e + 1)) - 1);
                            }
                            if e < oa || e >= oa + w {
                                continue;
                            }
                            let pe = e - oa;
                            if axis != Axis::X && !edge_changes(out, axis, pe, pu, pv) {
                                out.repaired += 1;
                                expected_ok = false;
                                continue;
                            }
                            let lower = compose(axis, pe, pu, pv);
                            let idx = out.node_index(lower[0], lower[1], lower[2]);
                            out.lookup[a][idx] = out.crossings[a].len() as u32;
                            out.crossings[a].push(EdgeCrossing {
                                lower: lower.map(|c| c as u8),
                                t: (q.0 as u32 - e as u32 * s) as f32 * inv_s,
                                normal: nr,
                            });
                        }
                        if axis == Axis::X {
                            out.rows[pu + m * pv] = (states >> oa) & node_mask(w);
                        }
                    }
                }
            }
            if axis != Axis::X && (!expected_ok || out.crossings[a].len() != expected_changes(out, axis)) {
                fill_missing(out, axis);
            }
        }
    }
}

/// The block of `key` where it and every face and edge neighbour are meshed at one level at or
/// below their stored levels (level of detail away from the boundaries between its rings):
/// every line read straight from its owner at that level, nothing to patch.
fn extract_sampled(map: &crate::level::LevelMap<'_>, key: ChunkKey, out: &mut VoxelBlock) {
    let level = map.get(key);
    out.reset(key, level);
    let n = level.cells();
    let m = n + 1;
    let s = level.steps_per_cell();
    let inv_s = 1.0 / s as f32;
    let mut line = crate::chunk::WorkLine::EMPTY;
    for axis in Axis::ALL {
        let (ua, va) = axis.across();
        let a = axis.index();
        // Readers of this chunk, its neighbours along `ua`, `va` and both.
        let owners = [key, key.offset(unit(ua)), key.offset(unit(va)), key.offset(unit(ua) + unit(va))];
        let mut readers: [Option<crate::level::LineReader<'_>>; 4] = [None, None, None, None];
        for v in 0..=n {
            for u in 0..=n {
                let k = usize::from(u == n) + 2 * usize::from(v == n);
                let reader = readers[k].get_or_insert_with(|| map.reader(owners[k], axis));
                let ok = reader.read(u % n, v % n, level, &mut line);
                debug_assert!(ok, "every chunk around is at or above the block's level");
                if axis == Axis::X {
                    out.rows[u + m * v] = line.states;
                }
                let mut c = line.changes(n);
                while c != 0 {
                    let e = c.trailing_zeros() as usize;
                    c &= c - 1;
                    let lower = compose(axis, e, u, v);
                    let idx = out.node_index(lower[0], lower[1], lower[2]);
                    out.lookup[a][idx] = out.crossings[a].len() as u32;
                    out.crossings[a].push(EdgeCrossing {
                        lower: lower.map(|c| c as u8),
                        t: (line.pos[e].0 as u32 - e as u32 * s) as f32 * inv_s,
                        normal: line.nrm[e],
                    });
                }
            }
        }
        if axis != Axis::X && out.crossings[a].len() != expected_changes(out, axis) {
            fill_missing(out, axis);
        }
    }
}

fn unit(a: Axis) -> IVec3 {
    let mut v = IVec3::ZERO;
    v[a.index()] = 1;
    v
}

/// Whether the nodes at both ends of edge `e` of line `(u, v)` along `axis` differ (per the rows).
#[inline]
fn edge_changes(b: &VoxelBlock, axis: Axis, e: usize, u: usize, v: usize) -> bool {
    let [x0, y0, z0] = compose(axis, e, u, v);
    let [x1, y1, z1] = compose(axis, e + 1, u, v);
    b.inside(x0, y0, z0) != b.inside(x1, y1, z1)
}

/// Number of edges along `axis` (y or z) whose two nodes differ.
fn expected_changes(b: &VoxelBlock, axis: Axis) -> usize {
    let m = b.n + 1;
    let mut total = 0;
    for z in 0..m {
        for y in 0..m {
            let next = match axis {
                Axis::Y if y < b.n => b.rows[y + 1 + m * z],
                Axis::Z if z < b.n => b.rows[y + m * (z + 1)],
                _ => continue,
            };
            total += (b.rows[y + m * z] ^ next).count_ones() as usize;
        }
    }
    total
}

/// Gives every changing edge along `axis` without a crossing one at its middle, with the axis as
/// normal, and counts each as repaired.
fn fill_missing(b: &mut VoxelBlock, axis: Axis) {
    let n = b.n;
    let a = axis.index();
    for z in 0..=n {
        for y in 0..=n {
            for x in 0..=n {
                let [x1, y1, z1] = match axis {
                    Axis::Y => [x, y + 1, z],
                    Axis::Z => [x, y, z + 1],
                    Axis::X => [x + 1, y, z],
                };
                if x1 > n || y1 > n || z1 > n {
                    continue;
                }
                let (i0, i1) = (b.inside(x, y, z), b.inside(x1, y1, z1));
                let idx = b.node_index(x, y, z);
                if i0 != i1 && b.lookup[a][idx] == NONE {
                    let dir = axis.unit();
                    let normal = if i1 { -dir } else { dir };
                    b.lookup[a][idx] = b.crossings[a].len() as u32;
                    b.crossings[a].push(EdgeCrossing {
                        lower: [x as u8, y as u8, z as u8],
                        t: 0.5,
                        normal: crate::normal::pack_normal(normal),
                    });
                    b.repaired += 1;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brush::Sphere;
    use glam::DVec3;

    /// Blocks patched to meet neighbours of other levels list the patched crossings after the
    /// others; listed line by line again they hold the same crossings in line order, and the
    /// lookup finds each one where it now is.
    #[test]
    fn patched_blocks_listed_line_by_line_keep_their_crossings() {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(16.3, 15.2, 17.7), 9.4).unwrap()).unwrap();
        v.set_chunk_level(ChunkKey::new(1, 0, 1), Level::new(1).unwrap());
        v.set_chunk_level(ChunkKey::new(0, 1, 0), Level::new(2).unwrap());
        let mut moved = 0;
        for key in [(0, 0, 0), (1, 0, 0), (0, 1, 1), (1, 0, 1), (0, 0, 1), (1, 1, 0)] {
            let block = v.extract_block(ChunkKey::new(key.0, key.1, key.2));
            let mut listed = block.clone();
            if listed.list_line_by_line() {
                moved += 1;
            }
            assert!(!listed.clone().list_line_by_line(), "{key:?}: a second listing moves nothing");
            let m = block.cells() + 1;
            for axis in Axis::ALL {
                let a = axis.index();
                let (u, w) = (axis.across().0.index(), axis.across().1.index());
                let order: Vec<(usize, u8)> = listed
                    .crossings(axis)
                    .iter()
                    .map(|c| (c.lower[u] as usize + m * c.lower[w] as usize, c.lower[a]))
                    .collect();
                assert!(order.windows(2).all(|p| p[0] < p[1]), "{key:?} {axis:?}: in line order");
                let mut before = block.crossings(axis).to_vec();
                let mut after = listed.crossings(axis).to_vec();
                let by_node = |c: &EdgeCrossing| c.lower;
                before.sort_by_key(by_node);
                after.sort_by_key(by_node);
                assert_eq!(before, after, "{key:?} {axis:?}: the same crossings");
                for c in listed.crossings(axis) {
                    let [x, y, z] = c.lower.map(usize::from);
                    assert_eq!(listed.crossing(axis, x, y, z), Some(c), "{key:?} {axis:?}: the lookup");
                    assert_eq!(listed.crossing(axis, x, y, z), block.crossing(axis, x, y, z));
                }
            }
        }
        assert!(moved > 0, "some block was patched out of line order");
    }

    /// Blocks whose chunk and apron owners are uniform alike, beside chunks of other levels
    /// (stored, and capped for level of detail): the shortcut gives the block patching gives.
    #[test]
    fn uniform_blocks_among_other_levels_are_the_patched_ones() {
        use crate::brush::Cuboid;
        let mut v = Volume::new();
        // A solid box over whole chunks (uniform solid chunks inside), a ball beside it, on and
        // off the grid, then chunks raised to levels 1 and 2.
        v.add(&Cuboid::new(DVec3::new(32.0, 32.0, 32.0), DVec3::new(24.0, 24.0, 24.0)).unwrap()).unwrap();
        v.add(&Sphere::new(DVec3::new(70.3, 30.1, 33.7), 9.6).unwrap()).unwrap();
        let lists: Vec<ChunkKey> = v.chunks().filter(|(k, _)| v.stored_level(*k).is_some()).map(|(k, _)| k).collect();
        for (i, &k) in lists.iter().enumerate() {
            v.set_chunk_level(k, Level::new((i % 3) as i8).unwrap());
        }
        let odd = |k: ChunkKey| if (k.0.x + k.0.y + k.0.z) % 2 == 0 { Level::BASE } else { Level::FINEST };
        let caps: [Option<&(dyn Fn(ChunkKey) -> Level + Sync)>; 2] = [None, Some(&odd)];
        let mut seen = 0;
        for cap in caps {
            let map = crate::level::LevelMap::new(&v, cap, None);
            for x in -1..6 {
                for y in -1..6 {
                    for z in -1..6 {
                        let key = ChunkKey::new(x, y, z);
                        if crate::level::plain(&map, key) || !v.plain_block_uniform(key) {
                            continue;
                        }
                        let (mut fast, mut patched) = (VoxelBlock::default(), VoxelBlock::default());
                        v.extract_unplain(&map, key, &mut fast);
                        crate::level::extract_patched(&map, key, &mut patched);
                        assert_eq!(fast, patched, "{key:?}");
                        seen += 1;
                    }
                }
            }
        }
        assert!(seen > 20, "{seen} uniform blocks among other levels");
    }

    /// Blocks read straight from their owners because every chunk around is meshed at their
    /// level, or is uniform with no list chunk across a face or an edge (which agrees with any
    /// level): the block patching gives. A model stored fine and meshed coarser, as a middle
    /// view does (the caps name the list chunks only, as the editor's do: the uniform chunks
    /// around the model take its level, those farther out the volume's), rings of other caps,
    /// and list chunks stored at every level, some below the volume's.
    #[test]
    fn sampled_blocks_beside_uniform_chunks_of_other_levels_are_the_patched_ones() {
        let mut fine = Volume::with_level(Level::FINEST);
        fine.add(&Sphere::new(DVec3::new(33.3, 30.1, 29.7), 21.6).unwrap()).unwrap();
        fine.subtract(&Sphere::new(DVec3::new(40.0, 36.0, 31.0), 9.0).unwrap()).unwrap();
        let mut mixed = fine.clone();
        let lists: Vec<ChunkKey> =
            fine.chunks().filter(|(k, _)| fine.stored_level(*k).is_some()).map(|(k, _)| k).collect();
        for (i, &k) in lists.iter().enumerate() {
            mixed.set_chunk_level(k, Level::new((i % 3) as i8).unwrap());
        }
        // Far terrain: every list chunk stored below the volume's level, the uniform chunks
        // among them read at theirs.
        let mut coarse = Volume::new();
        coarse.add(&Sphere::new(DVec3::new(33.3, 30.1, 29.7), 21.6).unwrap()).unwrap();
        coarse.subtract(&Sphere::new(DVec3::new(40.0, 36.0, 31.0), 9.0).unwrap()).unwrap();
        let coarse_lists: Vec<ChunkKey> =
            coarse.chunks().filter(|(k, _)| coarse.stored_level(*k).is_some()).map(|(k, _)| k).collect();
        coarse.set_chunk_levels(&coarse_lists, Level::COARSEST);
        let listed: std::collections::HashSet<ChunkKey> = lists.iter().copied().collect();
        let middle = |k: ChunkKey| if listed.contains(&k) { Level::new(1).unwrap() } else { Level::FINEST };
        let odd = |k: ChunkKey| if (k.0.x + k.0.y + k.0.z) % 2 == 0 { Level::BASE } else { Level::new(1).unwrap() };
        type Cap<'a> = Option<&'a (dyn Fn(ChunkKey) -> Level + Sync)>;
        let cases: [(&Volume, Cap<'_>); 5] =
            [(&fine, Some(&middle)), (&fine, Some(&odd)), (&mixed, None), (&mixed, Some(&odd)), (&coarse, None)];
        for (case, (v, cap)) in cases.into_iter().enumerate() {
            let map = crate::level::LevelMap::new(v, cap, None);
            let (mut sampled, mut beside_isolated) = (0, 0);
            for x in -2..6 {
                for y in -2..6 {
                    for z in -2..6 {
                        let key = ChunkKey::new(x, y, z);
                        if !crate::level::same_level_around(&map, key) {
                            continue;
                        }
                        let level = map.get(key);
                        if crate::level::NEIGHBOURS.iter().any(|&d| map.get(key.offset(d)) != level) {
                            beside_isolated += 1;
                        }
                        let (mut fast, mut patched) = (VoxelBlock::default(), VoxelBlock::default());
                        extract_sampled(&map, key, &mut fast);
                        crate::level::extract_patched(&map, key, &mut patched);
                        // The same blocks, the crossings listed in another order.
                        assert!(fast.rows == patched.rows, "case {case}, {key:?}: node states");
                        assert_eq!(fast.repaired(), 0, "case {case}, {key:?}: nothing to repair");
                        assert!(fast.seams == patched.seams && patched.patched() == 0, "case {case}, {key:?}: seams");
                        for axis in Axis::ALL {
                            let a = axis.index();
                            assert_eq!(fast.crossings[a].len(), patched.crossings[a].len(), "case {case}, {key:?}");
                            for c in &fast.crossings[a] {
                                let [x, y, z] = c.lower.map(usize::from);
                                assert_eq!(patched.crossing(axis, x, y, z), Some(c), "case {case}, {key:?}");
                                assert_eq!(fast.crossing(axis, x, y, z), Some(c), "case {case}, {key:?}");
                            }
                        }
                        sampled += 1;
                    }
                }
            }
            assert!(sampled > 50, "case {case}: {sampled} sampled blocks");
            if case == 4 {
                // The uniform chunks among the coarse ones are read so when their blocks are.
                let uniform = (-2..6)
                    .flat_map(|x| (-2..6).flat_map(move |y| (-2..6).map(move |z| ChunkKey::new(x, y, z))))
                    .filter(|&k| v.stored_level(k).is_none() && crate::level::same_level_around(&map, k))
                    .filter(|&k| !v.plain_block_uniform(k) && map.get(k) == Level::COARSEST)
                    .count();
                assert!(uniform > 10, "{uniform} uniform chunks among coarse ones");
            }
            // (Case 2's stored levels, all at or above the volume's, leave no uniform chunk at
            // another level than its neighbours'; case 4's coarse chunks do, beside the uniform
            // chunks farther out, meshed at the volume's.)
            assert!(case == 2 || beside_isolated > 10, "case {case}: {beside_isolated} blocks beside isolated chunks");
        }
    }

    #[test]
    fn a_block_reports_every_sign_change_once_with_a_crossing() {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(15.3, 16.2, 14.9), 7.4).unwrap()).unwrap();
        let b = v.extract_block(ChunkKey::new(0, 0, 0));
        assert_eq!(b.repaired(), 0);
        let n = b.cells();
        for axis in Axis::ALL {
            let mut count = 0;
            for z in 0..=n {
                for y in 0..=n {
                    for x in 0..=n {
                        let mut p1 = [x, y, z];
                        p1[axis.index()] += 1;
                        if p1.iter().any(|&c| c > n) {
                            continue;
                        }
                        let changes = b.inside(x, y, z) != b.inside(p1[0], p1[1], p1[2]);
                        let c = b.crossing(axis, x, y, z);
                        assert_eq!(changes, c.is_some(), "{axis:?} edge at {x},{y},{z}");
                        if let Some(c) = c {
                            assert!(c.t > 0.0 && c.t < 1.0);
                            count += 1;
                        }
                    }
                }
            }
            assert_eq!(count, b.crossings(axis).len());
            assert!(count > 0);
        }
    }
}
