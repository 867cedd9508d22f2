//! Dual contouring with Hermite data. The manifold form (the default) gives a cell one vertex
//! per surface component (per marching-cubes loop of its sign-changing edges), each placed by
//! the QEF of that component's edge crossings and clamped to the cell grown by half a cell; the
//! first wave's form ([`DualCache::single_vertex`]) gives the cell one vertex for all of them.
//! One quad per sign-changing edge joins the four cells around it, each at the vertex of the
//! component holding the edge, split into two triangles along the flatter diagonal; across
//! levels a finer edge inside a coarser cell's face takes the component of the face segment
//! that cuts it.
//!
//! Chunk borders: each chunk computes the vertices of its own cells and owns the sign-changing
//! edges whose lower node lies in the chunk on the two across axes. The quad of an owned edge
//! on the chunk's `−` faces uses cells of up to three neighbours (`−u`, `−v`, `−u−v`); the chunk
//! mesh copies those vertices, which every chunk computes identically, so chunk meshes meet
//! without cracks (the paper's 2×2×2 idea, section VI-C). The result is closed, at one level and
//! across levels; it is edge-manifold at one level (tested), and nearly so across levels (a few
//! non-manifold edges in a million, measured in docs/ARCHITECTURE.md § Levels). The single-vertex
//! form is closed too but can make edges non-manifold where a cell holds several sheets
//! ([`crate::checks::manifold_report`] counts them).

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::{DVec3, I64Vec3, IVec3, Vec3};
use rayon::prelude::*;
use smallvec::SmallVec;
use strata_volume::normal::unpack_normal;
use strata_volume::{Axis, ChunkKey, KeyHasher, Level, Volume, VoxelBlock};

use crate::qef::Qef;
use crate::{Mesh, MeshCache, VertexMaterial};

/// How far (in cells) a vertex may leave its cell: half a cell, so vertices of neighbouring
/// cells can meet but never cross. With 0 the tips of rotated box corners were cut by up to
/// 0.4 cells (test `box_corners_come_out_sharp`).
pub const CELL_MARGIN: f64 = 0.5;

type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<KeyHasher>>;

/// The dual-contouring data of one chunk.
#[derive(Clone, Debug, Default, PartialEq)]
struct ChunkDual {
    n: usize,
    /// Vertices of the chunk's mixed cells, sorted by local cell index `x + n (y + n z)`:
    /// (cell index, the cell edges of the surface component the vertex stands for as bits of
    /// [`local_edge`], position in grid units from the chunk origin, normal, the blend of the
    /// materials of the cell's solid corners). Manifold dual contouring gives a cell one vertex
    /// per component; the single-vertex variant one for all.
    cells: Vec<CellVertex>,
    /// Owned sign-changing edges: axis, lower node, whether the lower node is inside.
    edges: Vec<(Axis, [u16; 3], bool)>,
    /// The `+` faces (normal axis `fa`) of cells whose four edges all cross the surface and all
    /// belong to one component of the cell: (cell index, `fa`, for each face corner
    /// `cu + 2 cv` on the face's axes `fa + 1`, `fa + 2` the midpoint of the face segment that
    /// cuts it off, chunk-local; meaningful at the inside corners). Where the cell across the
    /// face has one component through both segments too, their two vertices would join by an
    /// edge of four quads; the quads go through these midpoints instead.
    faces: Vec<(u32, u8, [Vec3; 4])>,
}

/// One vertex of a cell: cell index, component edges, position, normal, material.
type CellVertex = (u32, u16, Vec3, Vec3, VertexMaterial);

/// The bits of the four edges of a cell's face with normal `fa` at `side` (0 or 1).
fn face_edges(fa: usize, side: usize) -> u16 {
    let mut bits = 0;
    for axis in [(fa + 1) % 3, (fa + 2) % 3] {
        let other = 3 - fa - axis;
        for o in 0..2 {
            let mut off = [0; 3];
            off[fa] = side;
            off[other] = o;
            bits |= 1 << local_edge(axis, off);
        }
    }
    bits
}

/// For the `+` face along `fa` of `cell` (all four edges crossed), the midpoint of the segment
/// cutting off each face corner `cu + 2 cv` (axes `fa + 1`, `fa + 2`), chunk-local grid units.
fn face_midpoints(block: &VoxelBlock, cell: [usize; 3], fa: usize, sp: f64) -> [Vec3; 4] {
    let (u, v) = ((fa + 1) % 3, (fa + 2) % 3);
    let point = |axis: usize, at: [usize; 3]| {
        let c = block.crossing(Axis::from_index(axis), at[0], at[1], at[2]).expect("every face edge crosses");
        let mut p = Vec3::new(at[0] as f32, at[1] as f32, at[2] as f32);
        p[axis] += c.t;
        p * sp as f32
    };
    std::array::from_fn(|k| {
        let (cu, cv) = (k & 1, k >> 1);
        let mut base = cell;
        base[fa] += 1;
        // The edge along u at v-offset cv, and the edge along v at u-offset cu.
        let mut eu = base;
        eu[v] += cv;
        let mut ev = base;
        ev[u] += cu;
        (point(u, eu) + point(v, ev)) * 0.5
    })
}

/// The surface components manifold dual contouring gives a cell of `case` (bit `k`: corner
/// `(k & 1, (k >> 1) & 1, (k >> 2) & 1)` inside) one vertex each, in the CPU's order: per
/// marching-cubes loop of the case, the cell edges it crosses as bits `4 axis + o₁ + 2 o₂`
/// (`o₁`, `o₂` the edge's lower corner's offsets on the axes `axis + 1` and `axis + 2`, mod 3).
/// What a GPU mesher needs to place the same vertices.
pub fn case_components(case: u8) -> Vec<u16> {
    crate::cases::cases()[case as usize]
        .iter()
        .map(|lp| lp.edges.iter().fold(0u16, |m, e| m | 1 << local_edge(e.axis, e.lower)))
        .collect()
}

/// The chunks whose dual-contouring quads an edit that changed `changed` can move (one level):
/// the chunks whose cell vertices it moves (each changed chunk and the seven before it), and the
/// chunks after those on at most two axes — a chunk's quads use cells of the chunk and of the
/// chunks before it on at most two axes (a quad lies in a plane), so a vertex change reaches the
/// seven offsets short of (1, 1, 1). Sorted, without repeats.
pub fn dual_mesh_keys(changed: &[ChunkKey]) -> Vec<ChunkKey> {
    let mut keys: Vec<ChunkKey> = MeshCache::dependents(changed)
        .into_iter()
        .flat_map(|k| (0..7).map(move |d| k.offset(IVec3::new(d & 1, (d >> 1) & 1, (d >> 2) & 1))))
        .collect();
    keys.sort();
    keys.dedup();
    keys
}

/// One vertex of manifold dual contouring as the CPU places it: its cell (`x + n (y + n z)`),
/// the cell edges of its component ([`case_components`]' bits), its position (grid units from
/// the chunk origin), its normal and its material blend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DualVertex {
    /// The cell, `x + n (y + n z)`.
    pub cell: u32,
    /// The component's cell edges.
    pub edges: u16,
    /// Grid units from the chunk origin.
    pub position: Vec3,
    /// Unit normal (the crossings' normals summed).
    pub normal: Vec3,
    /// The blend of the cell's solid corners' materials.
    pub material: VertexMaterial,
}

/// The vertices manifold dual contouring places in `block`'s cells (every mixed cell, one per
/// component, by the QEF of its crossings), in the CPU's order: cells by index, components in
/// [`case_components`] order. For checking a GPU's placing against.
pub fn dual_vertices(block: &VoxelBlock) -> Vec<DualVertex> {
    ChunkDual::of(block, &|_| true, &|_, _| true, true)
        .cells
        .into_iter()
        .map(|(cell, edges, position, normal, material)| DualVertex { cell, edges, position, normal, material })
        .collect()
}

/// The bit of a cell's edge along `axis` whose lower corner is at `offset` (0 or 1 on the two
/// other axes) from the cell's minimum corner.
fn local_edge(axis: usize, offset: [usize; 3]) -> usize {
    4 * axis + offset[(axis + 1) % 3] + 2 * offset[(axis + 2) % 3]
}

impl ChunkDual {
    /// Vertices of the cells and the owned edges of `block` that the filters accept.
    fn of(
        block: &VoxelBlock,
        cell_ok: &dyn Fn([usize; 3]) -> bool,
        edge_ok: &dyn Fn(Axis, [usize; 3]) -> bool,
        manifold: bool,
    ) -> ChunkDual {
        Self::of_with(block, cell_ok, edge_ok, false, manifold, None)
    }

    /// [`ChunkDual::of`], keeping the edges on the `+` faces too when `apron_edges` (between
    /// chunks of different levels the finer side owns a shared face's edges, whichever side it
    /// is on).
    fn of_with(
        block: &VoxelBlock,
        cell_ok: &dyn Fn([usize; 3]) -> bool,
        edge_ok: &dyn Fn(Axis, [usize; 3]) -> bool,
        apron_edges: bool,
        manifold: bool,
        solved: Option<&[DualVertex]>,
    ) -> ChunkDual {
        let n = block.cells();
        // Vertices solved elsewhere (a GPU) for this block, in this loop's order: taken where
        // their cell and component match, the QEF solved here otherwise.
        let mut next_solved = 0usize;
        let mut take_solved = |index: u32, mask: u16| -> Option<DualVertex> {
            let s = solved?;
            while next_solved < s.len() && s[next_solved].cell < index {
                next_solved += 1;
            }
            let v = s.get(next_solved).filter(|v| v.cell == index && v.edges == mask).copied()?;
            next_solved += 1;
            Some(v)
        };
        let sp = block.level().spacing();
        let mut d = ChunkDual { n, ..Default::default() };
        let table = crate::cases::cases();
        let normals: [Vec<DVec3>; 3] =
            Axis::ALL.map(|a| block.crossings(a).iter().map(|c| unpack_normal(c.normal)).collect());
        for z in 0..n {
            for y in 0..n {
                let mut mixed = block.mixed_cells(y, z);
                while mixed != 0 {
                    let x = mixed.trailing_zeros() as usize;
                    mixed &= mixed - 1;
                    if !cell_ok([x, y, z]) {
                        continue;
                    }
                    let mut case = 0usize;
                    for c in 0..8 {
                        case |= (block.inside(x + (c & 1), y + (c >> 1 & 1), z + (c >> 2)) as usize) << c;
                    }
                    // The components: one per marching-cubes loop of the case (manifold), or one
                    // for every crossed edge of the cell.
                    let loops = &table[case];
                    let mut masks: [u16; 4] = [0; 4];
                    let count = if manifold { loops.len() } else { 1 };
                    for (k, lp) in loops.iter().enumerate() {
                        for e in &lp.edges {
                            masks[if manifold { k } else { 0 }] |= 1 << local_edge(e.axis, e.lower);
                        }
                    }
                    let index = (x + n * (y + n * z)) as u32;
                    let material = if block.has_materials() {
                        let mut ids = [0u8; 8];
                        let mut k = 0;
                        for c in 0..8 {
                            let (cx, cy, cz) = (x + (c & 1), y + (c >> 1 & 1), z + (c >> 2));
                            if block.inside(cx, cy, cz) {
                                ids[k] = block.material(cx, cy, cz);
                                k += 1;
                            }
                        }
                        VertexMaterial::blend(&ids[..k])
                    } else {
                        VertexMaterial::single(0)
                    };
                    for &mask in &masks[..count] {
                        if let Some(v) = take_solved(index, mask) {
                            d.cells.push((index, mask, v.position, v.normal, material));
                            if manifold {
                                for fa in 0..3 {
                                    if mask & face_edges(fa, 1) == face_edges(fa, 1) {
                                        d.faces.push((index, fa as u8, face_midpoints(block, [x, y, z], fa, sp)));
                                    }
                                }
                            }
                            continue;
                        }
                        let mut qef = Qef::default();
                        let mut normal = DVec3::ZERO;
                        for axis in Axis::ALL {
                            let (ua, va) = axis.across();
                            for k in 0..4 {
                                let mut off = [0; 3];
                                off[ua.index()] = k & 1;
                                off[va.index()] = k >> 1;
                                if mask >> local_edge(axis.index(), off) & 1 == 0 {
                                    continue;
                                }
                                let lower = [x + off[0], y + off[1], z + off[2]];
                                let Some(i) = block.crossing_index(axis, lower[0], lower[1], lower[2]) else {
                                    continue;
                                };
                                let c = &block.crossings(axis)[i as usize];
                                let mut p = DVec3::new(off[0] as f64, off[1] as f64, off[2] as f64);
                                p[axis.index()] += c.t as f64;
                                // Each crossing serves four cells: unpack its normal once.
                                let nrm = normals[axis.index()][i as usize];
                                qef.add(p, nrm);
                                normal += nrm;
                            }
                        }
                        // Clamp to the cell grown by CELL_MARGIN: a corner whose tip holds no
                        // node lies in a cell without a sign change, and the neighbouring cell's
                        // vertex must be free to reach it; the margin keeps vertices near their
                        // cell.
                        let local = qef.solve().clamp(DVec3::splat(-CELL_MARGIN), DVec3::splat(1.0 + CELL_MARGIN));
                        let pos = (DVec3::new(x as f64, y as f64, z as f64) + local) * sp;
                        d.cells.push((index, mask, pos.as_vec3(), normal.normalize_or(DVec3::Z).as_vec3(), material));
                        if manifold {
                            for fa in 0..3 {
                                if mask & face_edges(fa, 1) == face_edges(fa, 1) {
                                    d.faces.push((index, fa as u8, face_midpoints(block, [x, y, z], fa, sp)));
                                }
                            }
                        }
                    }
                }
            }
        }
        for axis in Axis::ALL {
            let (ua, va) = axis.across();
            for c in block.crossings(axis) {
                let lower = c.lower.map(|v| v as usize);
                if !apron_edges && (lower[ua.index()] >= n || lower[va.index()] >= n) {
                    continue; // on the + faces: owned by a neighbour
                }
                if edge_ok(axis, lower) {
                    d.edges.push((axis, c.lower.map(u16::from), block.inside(lower[0], lower[1], lower[2])));
                }
            }
        }
        d.sort_edges();
        d
    }

    fn sort_edges(&mut self) {
        self.edges.sort_unstable_by_key(|&(a, l, _)| (a.index(), l[2], l[1], l[0]));
    }

    /// Replaces the cells and edges the filters accept with those of `part`.
    fn merge(
        &mut self,
        part: ChunkDual,
        cell_ok: &dyn Fn([usize; 3]) -> bool,
        edge_ok: &dyn Fn(Axis, [usize; 3]) -> bool,
    ) {
        let n = self.n;
        let cell_of = |i: u32| {
            let i = i as usize;
            [i % n, (i / n) % n, i / (n * n)]
        };
        self.cells.retain(|c| !cell_ok(cell_of(c.0)));
        self.cells.extend(part.cells);
        // Stable: the components of one cell keep their order.
        self.cells.sort_by_key(|c| c.0);
        self.faces.retain(|f| !cell_ok(cell_of(f.0)));
        self.faces.extend(part.faces);
        self.faces.sort_by_key(|f| (f.0, f.1));
        self.edges.retain(|&(a, l, _)| !edge_ok(a, l.map(usize::from)));
        self.edges.extend(part.edges);
        self.sort_edges();
    }

    /// The segment midpoints of the `+` face along `fa` of `cell`, if it is doubled on this side.
    fn face(&self, cell: [usize; 3], fa: usize) -> Option<&[Vec3; 4]> {
        let index = (cell[0] + self.n * (cell[1] + self.n * cell[2])) as u32;
        self.faces.binary_search_by_key(&(index, fa as u8), |f| (f.0, f.1)).ok().map(|i| &self.faces[i].2)
    }

    /// The vertices of `cell`, in component order.
    fn cell_vertices(&self, cell: [usize; 3]) -> &[CellVertex] {
        let index = (cell[0] + self.n * (cell[1] + self.n * cell[2])) as u32;
        let first = self.cells.partition_point(|c| c.0 < index);
        let count = self.cells[first..].iter().take_while(|c| c.0 == index).count();
        &self.cells[first..first + count]
    }

    /// The vertex of `cell` whose component holds the cell edge `edge` (a [`local_edge`] bit),
    /// and its component's number within the cell.
    fn vertex(&self, cell: [usize; 3], edge: usize) -> Option<(usize, CellVertex)> {
        self.cell_vertices(cell).iter().enumerate().find(|(_, c)| c.1 >> edge & 1 == 1).map(|(k, c)| (k, *c))
    }

    /// The vertex of `cell` whose component holds the face segment (on the cell's face with
    /// normal `fa` at `side`) that a finer sign-changing edge inside that face belongs to, given
    /// the finer edge's inside end `inside_end` in units of the cell from its minimum corner;
    /// and its component's number within the cell.
    ///
    /// The finer side's face is the coarse face refined by the face table, so its contour is
    /// the coarse face's contour with extra vertices: the finer edge is cut by one of the coarse
    /// face's segments. Where one component holds all of the face's crossed edges (one segment,
    /// or both in one component) that is the component. Otherwise the face has four crossed
    /// edges and two segments, each cutting off an inside corner from the crossings of the two
    /// edges at it (the face rule separates inside corners), and each component holds one such
    /// pair. The segment cutting off corner `c` between crossings at `a` and `b` (`a, b < 1`
    /// from `c`) bounds the triangle `u/a + v/b ≤ 1`, whose points are less than 1 from `c` in
    /// the L1 norm, while the other corner's triangle is more than 1 from `c`: so the finer
    /// edge's inside end, which lies in its segment's triangle, picks the component.
    fn vertex_on_face(
        &self,
        cell: [usize; 3],
        fa: usize,
        side: usize,
        inside_end: DVec3,
    ) -> Option<(usize, CellVertex)> {
        let face = face_edges(fa, side);
        let vertices = self.cell_vertices(cell);
        let mut on_face = vertices.iter().enumerate().filter(|(_, c)| c.1 & face != 0);
        let first = on_face.next();
        let Some(second) = on_face.next() else {
            return first.map(|(k, c)| (k, *c));
        };
        let (u, v) = ((fa + 1) % 3, (fa + 2) % 3);
        // The corner (offsets along u and v) whose two face edges a component's mask holds.
        let corner_of = |mask: u16| {
            let mut corner = [0usize; 2];
            for (slot, axis, other) in [(1, u, v), (0, v, u)] {
                for o in 0..2 {
                    let mut off = [0; 3];
                    off[fa] = side;
                    off[other] = o;
                    if mask >> local_edge(axis, off) & 1 == 1 {
                        // An edge along `axis` at offset `o` on `other` fixes the corner there.
                        corner[slot] = o;
                    }
                }
            }
            corner
        };
        [first, Some(second)].into_iter().flatten().chain(on_face).find_map(|(k, c)| {
            let [cu, cv] = corner_of(c.1 & face);
            let l1 = (inside_end[u] - cu as f64).abs() + (inside_end[v] - cv as f64).abs();
            (l1 < 1.0).then_some((k, *c))
        })
    }
}

/// Solves the cell vertices of voxel blocks elsewhere (see [`DualCache::update_solved`]).
pub type VertexSolver<'a> = &'a mut dyn FnMut(&[&VoxelBlock]) -> Option<Vec<Vec<DualVertex>>>;

type CellFilter = Box<dyn Fn([usize; 3]) -> bool + Send + Sync>;
type EdgeFilter = Box<dyn Fn(Axis, [usize; 3]) -> bool + Send + Sync>;

/// Which cells and owned edges of a chunk depend on the chunks at offsets `ds` after it (all of
/// them when `ds` is empty): cells on the last layer towards each such chunk, and edges that end
/// on the face shared with a face neighbour.
fn border_filters(ds: &[IVec3], n: usize) -> (CellFilter, EdgeFilter) {
    if ds.is_empty() {
        return (Box::new(|_| true), Box::new(|_, _| true));
    }
    let cells = ds.to_vec();
    let edges = ds.to_vec();
    let last = n - 1;
    (
        Box::new(move |c| cells.iter().any(|d| (0..3).all(|i| d[i] == 0 || c[i] == last))),
        Box::new(move |a, l| {
            let mut unit = IVec3::ZERO;
            unit[a.index()] = 1;
            l[a.index()] == last && edges.contains(&unit)
        }),
    )
}

/// A chunk's dual-contouring mesh: chunk-local positions, and for each vertex the global cell it
/// stands for, which identifies it across chunks (level units where the volume has one level;
/// where it mixes levels, the cell's minimum corner in units of the finest level's cells with
/// the level in the two lowest bits of x).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DualChunkMesh {
    /// The triangles, positions in grid units from the chunk origin.
    pub mesh: Mesh,
    /// Global cell of each vertex.
    pub cells: Vec<I64Vec3>,
}

/// Dual-contouring meshes by chunk, kept up to date incrementally after edits.
#[derive(Debug, Default, Clone)]
pub struct DualCache {
    duals: FastMap<ChunkKey, ChunkDual>,
    meshes: FastMap<ChunkKey, DualChunkMesh>,
    /// Levels of the chunks the duals were computed at, when the volume mixes levels.
    levels: Option<FastMap<ChunkKey, Level>>,
    /// One vertex per cell for all its surface components (the first wave's dual contouring,
    /// kept for comparison) instead of one per component.
    single_vertex: bool,
}

impl DualCache {
    /// An empty cache (manifold dual contouring: one vertex per surface component of a cell).
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty cache that gives each cell one vertex for all its surface components, as the
    /// first wave's dual contouring did (two sheets in one cell then share a vertex, which can
    /// make edges non-manifold); for comparison.
    pub fn single_vertex() -> Self {
        DualCache { single_vertex: true, ..Self::default() }
    }

    /// Meshes every chunk of `volume`.
    pub fn build(volume: &Volume) -> Self {
        Self::new().built(volume)
    }

    /// [`DualCache::build`] with one vertex per cell ([`DualCache::single_vertex`]).
    pub fn build_single_vertex(volume: &Volume) -> Self {
        Self::single_vertex().built(volume)
    }

    fn built(mut self, volume: &Volume) -> Self {
        let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
        self.update(volume, &stored);
        self
    }

    /// Recomputes what an edit that changed `changed` can have affected, in parallel: cell
    /// vertices of the changed chunks, and of the border cells of the seven chunks before each
    /// (they read the changed chunk as apron); then the meshes of those chunks and of the six
    /// chunks after each that share a face or an edge (their quads use those vertices). Returns
    /// the chunks whose mesh was rebuilt.
    pub fn update(&mut self, volume: &Volume, changed: &[ChunkKey]) -> Vec<ChunkKey> {
        self.update_solved(volume, changed, None)
    }

    /// [`DualCache::update`] with the cell vertices solved by `solver` where it can (a GPU:
    /// `strata_gpu_mesh::GpuMarcher::dual_vertices`): it gets the voxel blocks of the chunks
    /// whose vertices change, all at once, and gives each block's vertices as
    /// [`dual_vertices`] would, or `None` to leave them to the CPU. The quads are joined here
    /// as always. Volumes that mix levels, and the single-vertex form, are solved on the CPU.
    pub fn update_solved(
        &mut self,
        volume: &Volume,
        changed: &[ChunkKey],
        solver: Option<VertexSolver<'_>>,
    ) -> Vec<ChunkKey> {
        if !volume.single_level() || self.levels.is_some() {
            return self.update_mixed(volume, changed);
        }
        let solver = solver.filter(|_| !self.single_vertex);
        let vertex_keys = MeshCache::dependents(changed);
        let changed_set: std::collections::HashSet<ChunkKey> = changed.iter().copied().collect();
        // A chunk before a changed one only depends on it through its border cells (and, for a
        // face neighbour, the edges that end on that face): recompute just those.
        let borders = |key: ChunkKey| -> Vec<IVec3> {
            if changed_set.contains(&key) || !self.duals.contains_key(&key) {
                Vec::new()
            } else {
                (1..8)
                    .map(|d| IVec3::new(d & 1, (d >> 1) & 1, (d >> 2) & 1))
                    .filter(|&d| changed_set.contains(&key.offset(d)))
                    .collect()
            }
        };
        let manifold = !self.single_vertex;
        let fresh: Vec<(ChunkKey, ChunkDual, Vec<IVec3>)> = match solver {
            None => vertex_keys
                .par_iter()
                .map_init(VoxelBlock::default, |block, &key| {
                    volume.extract_block_into(key, block);
                    let ds = borders(key);
                    let (cell_ok, edge_ok) = border_filters(&ds, block.cells());
                    (key, ChunkDual::of(block, &cell_ok, &edge_ok, manifold), ds)
                })
                .collect(),
            Some(solve) => {
                let blocks: Vec<VoxelBlock> = vertex_keys.par_iter().map(|&k| volume.extract_block(k)).collect();
                let refs: Vec<&VoxelBlock> = blocks.iter().collect();
                let solved = solve(&refs).filter(|s| s.len() == blocks.len());
                vertex_keys
                    .par_iter()
                    .zip(&blocks)
                    .enumerate()
                    .map(|(i, (&key, block))| {
                        let ds = borders(key);
                        let (cell_ok, edge_ok) = border_filters(&ds, block.cells());
                        let mine = solved.as_ref().map(|s| s[i].as_slice());
                        (key, ChunkDual::of_with(block, &cell_ok, &edge_ok, false, manifold, mine), ds)
                    })
                    .collect()
            }
        };
        for (key, part, ds) in fresh {
            let d = if ds.is_empty() {
                part
            } else {
                let mut d = self.duals.remove(&key).expect("partial updates only for known chunks");
                let (cell_ok, edge_ok) = border_filters(&ds, d.n);
                d.merge(part, &cell_ok, &edge_ok);
                d
            };
            if d.cells.is_empty() && d.edges.is_empty() {
                self.duals.remove(&key);
            } else {
                self.duals.insert(key, d);
            }
        }
        let mesh_keys = dual_mesh_keys(changed);
        let meshes: Vec<(ChunkKey, DualChunkMesh)> =
            mesh_keys.par_iter().map(|&key| (key, self.assemble(key))).collect();
        for (key, m) in meshes {
            if m.mesh.indices.is_empty() {
                self.meshes.remove(&key);
            } else {
                self.meshes.insert(key, m);
            }
        }
        mesh_keys
    }

    /// [`DualCache::update`] for volumes whose chunks differ in level (the paper's VI-C: every
    /// polygon is built around a chunk-corner neighbourhood of up to 2×2×2 chunks, here the four
    /// cells around each edge, each in whichever chunk holds it at that chunk's level). Every
    /// sign-changing edge of the finest level around it (its *minimal* edge) gets one polygon
    /// joining the cells around it, a triangle where a coarser cell holds two of them: with the
    /// shared faces patched to the coarser side's contour, and a finer edge inside a coarser
    /// cell's face taking the component of the face segment that cuts it (as the finer edges on
    /// that segment's ends do), every polygon edge is shared by an even number of polygons, so
    /// the surface is closed. Vertices are recomputed for the 3×3×3 chunks around each change,
    /// and polygons for the chunks around those whose cells, owned edges or level changed.
    fn update_mixed(&mut self, volume: &Volume, changed: &[ChunkKey]) -> Vec<ChunkKey> {
        let around = MeshCache::around;
        if self.levels.is_none() {
            // From one level to several: everything is recomputed once.
            self.duals.clear();
            self.meshes.clear();
            self.levels = Some(FastMap::default());
            let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
            let all = MeshCache::dependents(&stored);
            return self.update_mixed(volume, &all);
        }
        let vertex_keys = around(changed);
        let fresh: Vec<(ChunkKey, ChunkDual, Level)> = vertex_keys
            .par_iter()
            .map_init(VoxelBlock::default, |block, &key| {
                volume.extract_block_into(key, block);
                let d = ChunkDual::of_with(block, &|_| true, &|_, _| true, true, !self.single_vertex, None);
                (key, d, block.level())
            })
            .collect();
        let levels = self.levels.as_mut().expect("set above");
        // A chunk's polygons read the cells, owned edges and levels of the chunks around it:
        // only those around a chunk whose dual data or level changed are joined again.
        let mut moved: Vec<ChunkKey> = Vec::new();
        for (key, d, level) in fresh {
            let empty = d.cells.is_empty() && d.edges.is_empty();
            let same = levels.insert(key, level) == Some(level)
                && match self.duals.get(&key) {
                    Some(old) => !empty && *old == d,
                    None => empty,
                };
            if !same {
                moved.push(key);
            }
            if empty {
                self.duals.remove(&key);
            } else {
                self.duals.insert(key, d);
            }
        }
        let mesh_keys = around(&moved);
        let meshes: Vec<(ChunkKey, DualChunkMesh)> =
            mesh_keys.par_iter().map(|&key| (key, self.assemble_mixed(volume, key))).collect();
        for (key, m) in meshes {
            if m.mesh.indices.is_empty() {
                self.meshes.remove(&key);
            } else {
                self.meshes.insert(key, m);
            }
        }
        mesh_keys
    }

    /// The polygons of the minimal edges `key` owns, in a volume of mixed levels.
    fn assemble_mixed(&self, volume: &Volume, key: ChunkKey) -> DualChunkMesh {
        let mut out = DualChunkMesh::default();
        let Some(own) = self.duals.get(&key) else { return out };
        let level_of =
            |k: ChunkKey| self.levels.as_ref().and_then(|l| l.get(&k).copied()).unwrap_or_else(|| volume.mesh_level(k));
        let own_level = level_of(key);
        let sp = own_level.spacing();
        let origin = key.origin_grid().as_dvec3();
        let mut ids: FastMap<I64Vec3, u32> = FastMap::default();
        for &(axis, lower, lower_inside) in &own.edges {
            let (ua, va) = axis.across();
            let mut mid = origin + DVec3::new(lower[0] as f64, lower[1] as f64, lower[2] as f64) * sp;
            mid[axis.index()] += 0.5 * sp;
            // The four quadrants around the edge, counter-clockwise around +axis.
            let eps = 0.01 * MIN_SPACING;
            let quadrant = |su: f64, sv: f64| mid + ua.unit() * (su * eps) + va.unit() * (sv * eps);
            let points = [quadrant(-1.0, -1.0), quadrant(1.0, -1.0), quadrant(1.0, 1.0), quadrant(-1.0, 1.0)];
            let cells: Vec<(ChunkKey, Level, [usize; 3])> = points
                .iter()
                .map(|&p| {
                    let k = ChunkKey::containing(p).expect("near a stored chunk");
                    let l = level_of(k);
                    let local = ((p - k.origin_grid().as_dvec3()) * l.nodes_per_unit()).floor();
                    (k, l, [local.x as usize, local.y as usize, local.z as usize])
                })
                .collect();
            // The finest chunk around the edge owns it; of several, the first of (+,+), (-,+),
            // (+,-), (-,-) (for one level: the chunk holding the edge's lower node).
            let finest = cells.iter().map(|c| c.1).max().expect("four cells");
            if finest != own_level {
                continue;
            }
            let owner = [2usize, 3, 1, 0].into_iter().find(|&q| cells[q].1 == finest).expect("one is finest");
            if cells[owner].0 != key {
                continue;
            }
            let mut q: Vec<u32> = Vec::with_capacity(4);
            let mut complete = true;
            for &(k, l, local) in &cells {
                // The component of the cell that holds the edge, where the edge lies on one of
                // the cell's edges; a finer edge inside a coarser cell's face takes the component
                // of the face segment that cuts it (`ChunkDual::vertex_on_face`).
                let to_cell = |v: DVec3| (v - k.origin_grid().as_dvec3()) * l.nodes_per_unit();
                let (e0, e1) = (to_cell(mid - axis.unit() * (0.5 * sp)), to_cell(mid + axis.unit() * (0.5 * sp)));
                let corner = DVec3::new(local[0] as f64, local[1] as f64, local[2] as f64);
                let (r0, r1) = (e0 - corner, e1 - corner);
                let on_face = |i: usize| r0[i] == r1[i] && (r0[i] == 0.0 || r0[i] == 1.0);
                let dual = self.duals.get(&k);
                let found = if (0..3).all(|i| i == axis.index() || on_face(i)) {
                    let edge =
                        local_edge(axis.index(), [0, 1, 2].map(|i| if i == axis.index() { 0 } else { r0[i] as usize }));
                    dual.and_then(|d| d.vertex(local, edge))
                } else {
                    // Every cell around an edge holds it on its boundary: inside a face here.
                    let fa = (0..3)
                        .find(|&i| i != axis.index() && on_face(i))
                        .expect("an edge of a finer chunk lies in a face of a coarser cell");
                    let inside_end = if lower_inside { r0 } else { r1 };
                    dual.and_then(|d| d.vertex_on_face(local, fa, r0[fa] as usize, inside_end))
                };
                let Some((component, (_, _, pos, normal, material))) = found else {
                    complete = false;
                    break;
                };
                let id = cell_id(k, l, local);
                let id = I64Vec3::new(id.x * 32 + component as i64, id.y, id.z);
                if let Some(&i) = ids.get(&id) {
                    if q.last() != Some(&i) {
                        q.push(i);
                    }
                    continue;
                }
                let i = out.mesh.positions.len() as u32;
                let shift = (k.origin_grid() - key.origin_grid()).as_vec3();
                let pos = exact_in_neighbour_frames(pos) + shift;
                out.mesh.push_vertex(pos.to_array(), normal.to_array(), material, false);
                out.cells.push(id);
                ids.insert(id, i);
                q.push(i);
            }
            if q.len() > 1 && q.first() == q.last() {
                q.pop();
            }
            if !complete || q.len() < 3 {
                continue;
            }
            if !lower_inside {
                q.reverse();
            }
            if q.len() == 3 {
                out.mesh.indices.extend_from_slice(&q);
                continue;
            }
            push_quad(&mut out.mesh, [q[0], q[1], q[2], q[3]]);
        }
        out
    }

    /// The quads of the edges `key` owns.
    fn assemble(&self, key: ChunkKey) -> DualChunkMesh {
        let mut out = DualChunkMesh::default();
        let Some(own) = self.duals.get(&key) else { return out };
        let n = own.n as i64;
        let cell0 = key.0.as_i64vec3() * n;
        // Mesh vertex of each of the chunk's own cells (dense), and of borrowed cells (sparse).
        // (Four slots a cell: a marching-cubes case has at most four loops.)
        let mut own_ids = vec![u32::MAX; 4 * own.n * own.n * own.n];
        let mut ids: FastMap<I64Vec3, u32> = FastMap::default();
        for &(axis, lower, lower_inside) in &own.edges {
            let (ua, va) = axis.across();
            let (eu, ev) = (ua.unit_i64(), va.unit_i64());
            let l = I64Vec3::new(lower[0] as i64, lower[1] as i64, lower[2] as i64);
            // Counter-clockwise around +axis: the quad faces +axis.
            let ring = [l - eu - ev, l - ev, l, l - eu];
            let mut q = [0u32; 4];
            // The dual of each ring cell: its chunk offset, local cell and vertex mask.
            let mut seen: [(IVec3, [usize; 3], u16); 4] = [(IVec3::ZERO, [0; 3], 0); 4];
            let mut complete = true;
            for (k, &cell) in ring.iter().enumerate() {
                let inside_chunk = cell.cmpge(I64Vec3::ZERO).all();
                // Cells at -1 on an across axis belong to the chunk before.
                let chunk = IVec3::new(-((cell.x < 0) as i32), -((cell.y < 0) as i32), -((cell.z < 0) as i32));
                let local = cell - chunk.as_i64vec3() * n;
                let local = [local.x as usize, local.y as usize, local.z as usize];
                let source = if inside_chunk { Some(own) } else { self.duals.get(&key.offset(chunk)) };
                // The edge seen from this cell picks the component it belongs to.
                let offset = (l - cell).to_array().map(|c| c as usize);
                let edge = local_edge(axis.index(), offset);
                let found = source.and_then(|d| d.vertex(local, edge));
                let Some((component, (_, mask, pos, normal, material))) = found else {
                    complete = false;
                    break;
                };
                seen[k] = (chunk, local, mask);
                let global = cell0 + cell;
                let id = I64Vec3::new(global.x * 32 + component as i64, global.y, global.z);
                let local_slot =
                    if inside_chunk { 4 * (cell.x + n * (cell.y + n * cell.z)) as usize + component } else { 0 };
                let known = if inside_chunk {
                    Some(own_ids[local_slot]).filter(|&i| i != u32::MAX)
                } else {
                    ids.get(&id).copied()
                };
                if let Some(i) = known {
                    q[k] = i;
                    continue;
                }
                let i = out.mesh.positions.len() as u32;
                out.mesh.push_vertex((pos + chunk.as_vec3() * 16.0).to_array(), normal.to_array(), material, false);
                out.cells.push(id);
                if inside_chunk {
                    own_ids[local_slot] = i;
                } else {
                    ids.insert(id, i);
                }
                q[k] = i;
            }
            if !complete {
                continue; // unreachable for volumes built by edits: every such cell is meshed
            }
            // A face between two ring cells whose components both run through both of its
            // segments: the two vertices would share an edge with the quads of the face's other
            // segment. Pass through the segment's midpoint instead.
            let mut polygon: SmallVec<[u32; 8]> = SmallVec::new();
            for k in 0..4 {
                polygon.push(q[k]);
                let j = (k + 1) % 4;
                let (ck, cj) = (ring[k], ring[j]);
                let fa = (0..3).find(|&i| ck[i] != cj[i]).expect("ring neighbours share a face");
                let (lo, hi) = if ck[fa] < cj[fa] { (k, j) } else { (j, k) };
                if seen[lo].2 & face_edges(fa, 1) != face_edges(fa, 1)
                    || seen[hi].2 & face_edges(fa, 0) != face_edges(fa, 0)
                {
                    continue;
                }
                let (chunk, local, _) = seen[lo];
                let source = if chunk == IVec3::ZERO { Some(own) } else { self.duals.get(&key.offset(chunk)) };
                let Some(mids) = source.and_then(|d| d.face(local, fa)) else { continue };
                // The segment of this edge cuts off the edge's inside end.
                let inside_end = if lower_inside { l } else { l + axis.unit_i64() };
                let corner_at = |i: usize| (inside_end[i] - ring[lo][i]) as usize;
                let corner = corner_at((fa + 1) % 3) + 2 * corner_at((fa + 2) % 3);
                let global = cell0 + ring[lo];
                let id = I64Vec3::new(global.x * 32 + 4 + 4 * fa as i64 + corner as i64, global.y, global.z);
                let i = match ids.get(&id) {
                    Some(&i) => i,
                    None => {
                        let i = out.mesh.positions.len() as u32;
                        let (a, b) = (q[k] as usize, q[j] as usize);
                        let normal =
                            (Vec3::from(out.mesh.normals[a]) + Vec3::from(out.mesh.normals[b])).normalize_or(Vec3::Z);
                        let material = out.mesh.material(a);
                        out.mesh.push_vertex(
                            (mids[corner] + chunk.as_vec3() * 16.0).to_array(),
                            normal.to_array(),
                            material,
                            false,
                        );
                        out.cells.push(id);
                        ids.insert(id, i);
                        i
                    }
                };
                polygon.push(i);
            }
            // Outward is +axis when the lower node is inside.
            if !lower_inside {
                q.reverse();
                polygon.reverse();
            }
            if polygon.len() > 4 {
                // A fan from the polygon's centre, a vertex of this quad alone.
                let centre = polygon.iter().map(|&i| Vec3::from(out.mesh.positions[i as usize])).sum::<Vec3>()
                    / polygon.len() as f32;
                let normal = polygon.iter().map(|&i| Vec3::from(out.mesh.normals[i as usize])).sum::<Vec3>();
                let material = out.mesh.material(q[0] as usize);
                let c = out.mesh.positions.len() as u32;
                out.mesh.push_vertex(centre.to_array(), normal.normalize_or(Vec3::Z).to_array(), material, false);
                let global = cell0 + l;
                out.cells.push(I64Vec3::new(global.x * 32 + 16 + axis.index() as i64, global.y, global.z));
                for k in 0..polygon.len() {
                    out.mesh.indices.extend_from_slice(&[c, polygon[k], polygon[(k + 1) % polygon.len()]]);
                }
                continue;
            }
            push_quad(&mut out.mesh, q);
        }
        out
    }

    /// The mesh of `key`, if it has triangles.
    pub fn mesh(&self, key: ChunkKey) -> Option<&DualChunkMesh> {
        self.meshes.get(&key)
    }

    /// All chunk meshes.
    pub fn iter(&self) -> impl Iterator<Item = (ChunkKey, &DualChunkMesh)> {
        self.meshes.iter().map(|(k, m)| (*k, m))
    }

    /// Total triangles over all chunks.
    pub fn triangle_count(&self) -> usize {
        self.meshes.values().map(|m| m.mesh.triangle_count()).sum()
    }

    /// One mesh of all chunks (grid units, absolute), vertices welded by the cell they stand for.
    pub fn welded(&self) -> Mesh {
        let mut keys: Vec<&ChunkKey> = self.meshes.keys().collect();
        keys.sort();
        let mut out = Mesh::default();
        let mut welded: FastMap<I64Vec3, u32> = FastMap::default();
        for key in keys {
            let m = &self.meshes[key];
            let origin = key.origin_grid().as_vec3().to_array();
            let remap: Vec<u32> = m
                .cells
                .iter()
                .enumerate()
                .map(|(i, cell)| *welded.entry(*cell).or_insert_with(|| out.push_vertex_from(&m.mesh, i, origin)))
                .collect();
            out.indices.extend(m.mesh.indices.iter().map(|&i| remap[i as usize]));
        }
        out
    }
}

/// Appends the quad `q` (counter-clockwise) as two triangles, split along the diagonal whose
/// two triangles agree more.
fn push_quad(mesh: &mut Mesh, q: [u32; 4]) {
    let p = q.map(|i| Vec3::from(mesh.positions[i as usize]));
    let flat = |a: usize, b: usize, c: usize, d: usize| {
        let n1 = (p[b] - p[a]).cross(p[c] - p[a]).normalize_or_zero();
        let n2 = (p[c] - p[a]).cross(p[d] - p[a]).normalize_or_zero();
        n1.dot(n2)
    };
    if flat(0, 1, 2, 3) >= flat(1, 2, 3, 0) {
        mesh.indices.extend_from_slice(&[q[0], q[1], q[2], q[0], q[2], q[3]]);
    } else {
        mesh.indices.extend_from_slice(&[q[1], q[2], q[3], q[1], q[3], q[0]]);
    }
}

/// Node spacing of the finest level (grid units).
const MIN_SPACING: f64 = 0.25;

/// Vertex positions between chunks of different levels are multiples of this (grid units).
const POSITION_QUANTUM: f32 = 1.0 / (1 << 18) as f32;

/// `pos_in_chunk` (a cell vertex, within half a cell of its chunk: `[-0.5, 16.5]`) rounded to
/// [`POSITION_QUANTUM`], so that it stays exact in the frame of every chunk around its own.
///
/// A chunk mesh copies the vertices of neighbouring chunks' cells shifted into its own frame.
/// Between chunks of one level the copied cells are those of the chunks before, near their `+`
/// faces, and `pos − 16` is exact (Sterbenz); between levels the finest chunk around an edge
/// owns it, so a chunk also copies cells of the chunks after it, near their `−` faces, and
/// `0.0145 + 16` is rounded: the two chunk meshes then held the vertex 1 ulp apart (32 open
/// edges after a weld by position on a ball with one raised chunk). Multiples of 2⁻¹⁸ below 64
/// in magnitude are exact in `f32`, and the shifted positions lie in `[-16.5, 32.5]`; every
/// chunk mesh then holds the same real position less its own (integer) origin, so adding the
/// origin rounds them all alike. 2⁻¹⁸ grid units (1/65,536 of a finest cell) is below any
/// tolerance here.
fn exact_in_neighbour_frames(pos_in_chunk: Vec3) -> Vec3 {
    (pos_in_chunk / POSITION_QUANTUM).round() * POSITION_QUANTUM
}

/// A cell's identity across chunks and levels: its minimum corner in units of the finest
/// level's cells, with the level in the two lowest bits of x.
fn cell_id(key: ChunkKey, level: Level, local: [usize; 3]) -> I64Vec3 {
    let f = 1i64 << (strata_volume::coords::MAX_LEVEL - level.get());
    let corner = key.0.as_i64vec3() * (16 << strata_volume::coords::MAX_LEVEL)
        + I64Vec3::new(local[0] as i64, local[1] as i64, local[2] as i64) * f;
    I64Vec3::new(corner.x * 4 + level.index() as i64, corner.y, corner.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use strata_volume::brush::{Cuboid, Sphere};

    #[test]
    fn incremental_dual_contouring_equals_a_full_rebuild() {
        let mut volume = Volume::new();
        let mut cache = DualCache::new();
        let mut seed = 5u64;
        for i in 0..50 {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let r = |s: u64| (s % 1000) as f64 / 1000.0;
            let c = DVec3::new(r(seed >> 10), r(seed >> 20), r(seed >> 30)) * 60.0 - 10.0;
            let report = match i % 4 {
                _ if i == 30 => volume.intersect(&Cuboid::new(DVec3::splat(20.0), DVec3::splat(26.0)).unwrap()),
                0 => volume.add(&Cuboid::new(c, DVec3::new(4.0, 6.0, 3.5)).unwrap()),
                3 => volume.subtract(&Sphere::new(c, 5.0).unwrap()),
                _ => volume.add(&Sphere::new(c, 3.0 + 9.0 * r(seed >> 40)).unwrap()),
            }
            .unwrap();
            cache.update(&volume, &report.changed);
        }
        let full = DualCache::build(&volume);
        assert_eq!(cache.duals, full.duals);
        assert_eq!(cache.meshes, full.meshes);
        assert!(cache.triangle_count() > 1000);
        let welded = cache.welded();
        assert_eq!(crate::checks::manifold_report(&welded).boundary, 0, "chunk meshes meet without cracks");
    }
}
