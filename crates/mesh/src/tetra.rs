//! Marching tetrahedra on voxel blocks, with the integrated vertex clustering of regularised
//! marching tetrahedra (Treece, Prager and Gee 1999; the study in
//! `shared/seeds/marching-tetrahedra-terrain-study.txt`, section 3.1), made safe.
//!
//! **Lattice.** Each cell is cut into the six tetrahedra of the simple-cubic (Kuhn)
//! decomposition around its main diagonal: corner paths `0 → e_i → e_i + e_j → (1, 1, 1)`. Every
//! lattice edge joins nodes `u` and `u + d` with `d` one of the seven 0/1 vectors, the same in
//! every cell, so neighbouring cells (and chunks) cut their shared face along the same diagonal.
//! The body-centred lattice is not offered: its centre samples lie on no grid line, so the lists
//! hold no state for them; any value there would be a guess.
//!
//! **Vertices.** A vertex on an axis edge is the stored crossing itself. A face diagonal has no
//! stored crossing: its vertex is where the segment between the face's two axis crossings meets
//! the diagonal (both chunks sharing the face compute it from the same four edges, so they
//! agree). The body diagonal's vertex is the least-squares meeting point of the cell's tangent
//! planes with the diagonal, kept inside the edge.
//!
//! **Clustering.** Every vertex belongs to the node it is nearest to, and each node's vertices
//! become one vertex placed by the QEF of their tangent planes; the candidate triangles are
//! carried through in one pass, those whose corners fall together dropped. Then
//! [`SHORT_EDGE_ROUNDS`] rounds merge the remaining edges shorter than [`SHORT_EDGE_CELLS`] in
//! pairs, shortest first, where the pair's planes stay within [`SHORT_EDGE_RMS_CELLS`] of the
//! merged vertex. Nothing is assumed safe: after each clustering the result is verified exactly
//! (every vertex's link one simple cycle, no triangle turned over, no small piece vanished, every
//! member near the merged vertex and its tangent plane: [`MAX_MOVE_CELLS`], [`MAX_REACH_CELLS`]
//! for the node clusters, [`SHORT_EDGE_MOVE_CELLS`], [`SHORT_EDGE_REACH_CELLS`] for the rounds)
//! and the clusters that fail are taken apart until none does (`cluster.rs` proves this ends
//! closed and manifold).
//!
//! **Chunk by chunk** (`mesh_chunk_clustered`, the viewport's form): a vertex on a chunk face
//! is shared with the neighbouring chunk, so both must agree on it. Each face's node clusters
//! (at nodes [`FACE_EDGE_NODES`] or more from the face's edges) are made by one function of the
//! two chunks' blocks, from the slab [`SLAB_CELLS`] cells deep on each side, and verified there
//! with one more rule (each chunk's triangles around a vertex form one fan); whichever chunk
//! makes them (the first of the two in a meshing batch; each, when they are meshed in different
//! batches), they are the same bit for bit, and both chunks pin them, then cluster their
//! insides. The other face vertices (near the face's edges, and of clusters the slab took
//! apart) stay unmerged, and the short-edge rounds leave every shared vertex alone. A change
//! then reaches the meshes of the chunks around it ([`crate::MeshCache::affected`]). A lone
//! block ([`mesh_block_tetra`]) keeps all its face vertices. The whole-volume mesher
//! (`tetra_volume`) clusters the welded whole mesh instead, faces included.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use glam::{DVec3, I64Vec3, IVec3, Vec3};
use smallvec::SmallVec;
use strata_volume::normal::unpack_normal;
use strata_volume::{Axis, ChunkKey, VoxelBlock};

use crate::cluster::{Clustered, Clustering};
pub use crate::cluster::{MAX_MOVE_CELLS, MAX_REACH_CELLS};
use crate::marching::edge_material;
use crate::weld::EdgeKey;
use crate::{Mesh, VertexMaterial};

/// The seven lattice edge directions as corner bit masks (bit 0 x, 1 y, 2 z), axes first.
const DIRS: [usize; 7] = [1, 2, 4, 3, 5, 6, 7];

/// Direction index of a 0/1 offset mask.
const fn dir_of(mask: usize) -> usize {
    match mask {
        1 => 0,
        2 => 1,
        4 => 2,
        3 => 3,
        5 => 4,
        6 => 5,
        _ => 6,
    }
}

fn offset(mask: usize) -> [usize; 3] {
    [mask & 1, (mask >> 1) & 1, (mask >> 2) & 1]
}

/// The point `t` along lattice edge direction `dir` from `base` (in cells).
fn along(base: [f32; 3], dir: usize, t: f32) -> Vec3 {
    let d = offset(DIRS[dir]);
    Vec3::from(base) + Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32) * t
}

/// The end of lattice edge (`dir`, from `lower`) that a vertex `t` along it is nearest to: the
/// node whose cluster it joins (one rule for a chunk's vertices and a face slab's).
fn nearer_end(lower: [i64; 3], dir: usize, t: f32) -> [i64; 3] {
    let d = offset(DIRS[dir]);
    if t <= 0.5 { lower } else { [0, 1, 2].map(|k| lower[k] + d[k] as i64) }
}

/// Bit `x` set for each `x` in `xs`: the cells of a block row that `xs` keeps.
fn row_mask(xs: &std::ops::Range<usize>) -> u128 {
    if xs.is_empty() { 0 } else { ((1u128 << (xs.end - xs.start)) - 1) << xs.start }
}

/// Whether `block` has a mixed cell within `cells` (per axis).
fn any_mixed(block: &VoxelBlock, cells: &[std::ops::Range<usize>; 3]) -> bool {
    let xs = row_mask(&cells[0]);
    cells[2].clone().any(|z| cells[1].clone().any(|y| block.mixed_cells(y, z) & xs != 0))
}

/// The surface pieces of one tetrahedron for one corner pattern: tetrahedron-local edges (pairs
/// of its corners, lower corner first), oriented counter-clockwise seen from outside.
#[derive(Clone, Debug, Default)]
struct TetCase {
    /// Three edges (a triangle) or four in cyclic order (a quad, split at run time).
    edges: SmallVec<[(u8, u8); 4]>,
}

/// The six tetrahedra of a cell, as cell corners (bit masks) from `0` to `7`.
fn tetrahedra() -> [[usize; 4]; 6] {
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    perms.map(|[i, j, _]| [0, 1 << i, (1 << i) | (1 << j), 7])
}

/// For each tetrahedron and each pattern of its four corners (bit `k`: corner `k` inside), its
/// surface piece. Orientation is decided once, on edge midpoints: every piece separates its
/// inside corners from its outside ones for any crossing positions, so its cyclic order is the
/// same for all of them.
fn table() -> &'static [[TetCase; 16]; 6] {
    static TABLE: OnceLock<[[TetCase; 16]; 6]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let tets = tetrahedra();
        std::array::from_fn(|t| {
            let corners = tets[t];
            let pos = |k: usize| {
                let o = offset(corners[k]);
                DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64)
            };
            std::array::from_fn(|mask| {
                let inside: Vec<usize> = (0..4).filter(|k| mask >> k & 1 == 1).collect();
                let outside: Vec<usize> = (0..4).filter(|k| mask >> k & 1 == 0).collect();
                let edge = |a: usize, b: usize| (a.min(b) as u8, a.max(b) as u8);
                let mid = |e: (u8, u8)| (pos(e.0 as usize) + pos(e.1 as usize)) * 0.5;
                let centroid = |s: &[usize]| s.iter().map(|&k| pos(k)).sum::<DVec3>() / s.len() as f64;
                let mut edges: SmallVec<[(u8, u8); 4]> = match (inside.len(), outside.len()) {
                    (0, _) | (_, 0) => return TetCase::default(),
                    (1, 3) => outside.iter().map(|&o| edge(inside[0], o)).collect(),
                    (3, 1) => inside.iter().map(|&i| edge(i, outside[0])).collect(),
                    _ => {
                        let (a, b, c, d) = (inside[0], inside[1], outside[0], outside[1]);
                        [edge(a, c), edge(a, d), edge(b, d), edge(b, c)].into_iter().collect()
                    }
                };
                let out = centroid(&outside) - centroid(&inside);
                let m: Vec<DVec3> = edges.iter().map(|&e| mid(e)).collect();
                let normal =
                    if m.len() == 3 { (m[1] - m[0]).cross(m[2] - m[0]) } else { (m[2] - m[0]).cross(m[3] - m[1]) };
                if normal.dot(out) < 0.0 {
                    edges.reverse();
                }
                TetCase { edges }
            })
        })
    })
}

const NONE: u32 = u32::MAX;

/// One mesh vertex's lattice edge: direction index into [`DIRS`] and block-local lower node.
#[derive(Clone, Copy, Debug)]
struct Site {
    dir: u8,
    lower: [u8; 3],
}

/// Reusable buffers of the tetrahedra mesher.
#[derive(Debug, Default)]
pub struct TetraScratch {
    /// Vertex of each diagonal edge (directions 3..7) by lower node, or `NONE`.
    diag: [Vec<u32>; 4],
    /// Vertex of each axis crossing by its index in the block, or `NONE`.
    axis: [Vec<u32>; 3],
    sites: Vec<Site>,
    /// The candidate vertex standing for each node's cluster, or `NONE`.
    node_rep: Vec<u32>,
    /// Position along the edge from its lower node.
    ts: Vec<f32>,
    tris: Vec<[u32; 3]>,
    /// The node clusters of the chunk's faces, made with its neighbours (block-local nodes,
    /// positions in the block's frame); empty for a lone block.
    faces: Vec<FaceCluster>,
    /// For each output vertex, the face cluster it is, or `NONE`.
    face_of: Vec<u32>,
    /// The face cluster at each node of the block, or `NONE`.
    face_at: Vec<u32>,
    neighbour: VoxelBlock,
    slab: SlabScratch,
    /// The unit normal of each axis crossing of the block, decoded once (a crossing's normal
    /// is read by its own vertex and by the face and body diagonals around it).
    normals: [Vec<Vec3>; 3],
}

/// Marching tetrahedra of one block, with integrated clustering when `cluster`, into `out`
/// (cleared first): positions in grid units from the block's origin, like
/// [`crate::mesh_block`]. Vertices on edges in a chunk face are shared with the neighbouring
/// block's mesh (same position bit for bit) and are never merged (the block alone cannot say
/// how the neighbour clusters them: [`crate::MeshCache`] can); the others belong to this
/// chunk alone.
pub fn mesh_block_tetra(block: &VoxelBlock, cluster: bool, scratch: &mut TetraScratch, out: &mut Mesh) {
    scratch.faces.clear();
    mesh_candidates_and_cluster(block, cluster, scratch, out);
}

/// [`mesh_block_tetra`] with the face clusters in `scratch.faces` (none for a lone block).
fn mesh_candidates_and_cluster(block: &VoxelBlock, cluster: bool, scratch: &mut TetraScratch, out: &mut Mesh) {
    out.clear();
    let n = block.cells();
    let m = n + 1;
    let s = scratch;
    for d in &mut s.diag {
        d.clear();
        d.resize(m * m * m, NONE);
    }
    for a in Axis::ALL {
        s.axis[a.index()].clear();
        s.axis[a.index()].resize(block.crossings(a).len(), NONE);
    }
    s.sites.clear();
    s.ts.clear();
    s.tris.clear();
    s.face_of.clear();
    for a in Axis::ALL {
        let normals = &mut s.normals[a.index()];
        normals.clear();
        normals.extend(block.crossings(a).iter().map(|c| unpack_normal(c.normal).as_vec3()));
    }
    let sp = block.level().spacing() as f32;
    let with_materials = block.has_materials();
    let node = |x: usize, y: usize, z: usize| x + m * (y + m * z);
    let mut ids: SmallVec<[u32; 4]> = SmallVec::new();
    for_each_piece(block, [0..n, 0..n, 0..n], |edges| {
        ids.clear();
        for &(dir, lower, _) in edges {
            ids.push(vertex(block, s, out, dir, lower, sp, with_materials, node(lower[0], lower[1], lower[2])));
        }
        let ts = &s.ts;
        push_piece(&ids, edges, |v| ts[v as usize], &mut s.tris);
    });
    if cluster {
        cluster_block(n, sp, s, out);
    } else {
        out.indices.extend(s.tris.iter().flatten());
    }
}

/// One lattice edge of a surface piece: direction index, lower node, and the lower node's
/// offset (0 or 1 per axis) in the piece's cell.
type PieceEdge = (usize, [usize; 3], [usize; 3]);

/// Calls `piece` with the lattice edges of each surface piece of the mixed cells of `block`
/// within `cells` (per axis), in the piece's cyclic order.
fn for_each_piece(block: &VoxelBlock, cells: [std::ops::Range<usize>; 3], mut piece: impl FnMut(&[PieceEdge])) {
    let table = table();
    let tets = tetrahedra();
    let xs = row_mask(&cells[0]);
    let mut edges: SmallVec<[PieceEdge; 4]> = SmallVec::new();
    for z in cells[2].clone() {
        for y in cells[1].clone() {
            let mut mixed = block.mixed_cells(y, z) & xs;
            // The cell's corners from the four node rows around it: bits 2k and 2k + 1 of the
            // states (corners `2k`, `2k + 1`: x and x + 1) from row k = (y offset) + 2 (z offset).
            let rows = [block.row(y, z), block.row(y + 1, z), block.row(y, z + 1), block.row(y + 1, z + 1)];
            while mixed != 0 {
                let x = mixed.trailing_zeros() as usize;
                mixed &= mixed - 1;
                let states = corner_states(&rows, x);
                for (t, corners) in tets.iter().enumerate() {
                    let mask = (0..4).fold(0usize, |acc, k| acc | ((states >> corners[k] & 1) as usize) << k);
                    let case = &table[t][mask];
                    if case.edges.is_empty() {
                        continue;
                    }
                    edges.clear();
                    for &(a, b) in &case.edges {
                        let (ca, cb) = (corners[a as usize], corners[b as usize]);
                        let o = offset(ca);
                        edges.push((dir_of(ca ^ cb), [x + o[0], y + o[1], z + o[2]], o));
                    }
                    piece(&edges);
                }
            }
        }
    }
}

/// The inside states of the eight corners of the cell at `x` along the node rows `rows` (at
/// `(y, z)`, `(y + 1, z)`, `(y, z + 1)`, `(y + 1, z + 1)`): bit `c` for corner `offset(c)`. Row `k`
/// (its y offset plus twice its z offset) gives bits `2k` (node `x`) and `2k + 1` (node `x + 1`).
#[inline]
fn corner_states(rows: &[u128; 4], x: usize) -> u8 {
    rows.iter().enumerate().fold(0u8, |acc, (k, r)| acc | (((r >> x) & 3) as u8) << (2 * k))
}

/// Adds the triangles of one surface piece (its vertices `ids` in cyclic order, on `edges` at
/// `ts` along them) to `tris`: a triangle, or a quad split along its shorter diagonal (inside
/// the tetrahedron, so the choice is free). The lengths are measured in the cell's own frame,
/// so every block holding the cell (a chunk's, a face slab's) splits it alike, bit for bit.
fn push_piece(ids: &[u32], edges: &[PieceEdge], ts: impl Fn(u32) -> f32, tris: &mut Vec<[u32; 3]>) {
    if ids.len() == 3 {
        tris.push([ids[0], ids[1], ids[2]]);
        return;
    }
    let p = |i: usize| {
        let (dir, _, o) = edges[i];
        along(o.map(|c| c as f32), dir, ts(ids[i]))
    };
    if p(0).distance_squared(p(2)) <= p(1).distance_squared(p(3)) {
        tris.push([ids[0], ids[1], ids[2]]);
        tris.push([ids[0], ids[2], ids[3]]);
    } else {
        tris.push([ids[1], ids[2], ids[3]]);
        tris.push([ids[1], ids[3], ids[0]]);
    }
}

/// Cells on each side of a chunk face from which the face's node clusters are made and
/// verified: a face node's members lie in the cells beside it, and the links of the vertices
/// beside those reach one cell further.
pub(crate) const SLAB_CELLS: usize = 2;

/// Face nodes this close (nodes) to a chunk's edge keep their vertices as they are: the checks
/// of their clusters would reach into the chunks across the edge.
const FACE_EDGE_NODES: usize = 2;

/// A node cluster of a chunk face, made and verified alike by the two chunks that share the face
/// (see [`face_clusters`]).
#[derive(Clone, Copy, Debug)]
struct FaceCluster {
    /// The face node in the chunk's block.
    node: [usize; 3],
    /// Position (grid units from the block's origin) and unit normal.
    position: [f32; 3],
    normal: [f32; 3],
    material: VertexMaterial,
}

/// Buffers of [`face_clusters`].
#[derive(Debug, Default)]
struct SlabScratch {
    /// Vertex of each lattice edge of the slab, or `NONE`.
    ids: Vec<u32>,
    /// Each vertex's direction index, lower node (the upper chunk's block frame) and position
    /// along its edge.
    sites: Vec<(usize, [i64; 3], f32)>,
    mesh: Mesh,
    tris: Vec<[u32; 3]>,
    /// The chunk each triangle lies in: 0 the lower, 1 the upper.
    sides: Vec<u8>,
    found: Vec<FaceCluster>,
}

/// The node clusters of the face along `axis` between the chunks of blocks `lower` and `upper`
/// (one level, `upper` the next chunk along `axis`), in `out` in the upper block's frame.
///
/// It is a function of the two blocks alone, so whichever chunk makes a face (and whenever),
/// both get the same clusters bit for bit.
/// The candidate mesh of the slab [`SLAB_CELLS`] cells deep on each side is clustered at the face
/// nodes at least [`FACE_EDGE_NODES`] nodes from the face's edges, every other vertex kept, and
/// verified as every clustering is (the slab's outer vertices stand as chunk-face vertices do),
/// with one more rule: around every vertex, each chunk's triangles form one fan. A cluster that
/// passes is whole in both chunks' checks; each chunk then clusters its inside with these fixed
/// (`cluster.rs`: with every inside cluster taken apart a chunk holds exactly the slab's verified
/// surface, so its own checks always end; the fans' ends are edges between shared vertices, which
/// neither chunk moves, so the two chunks' fans still close into one cycle around each vertex).
fn face_clusters(lower: &VoxelBlock, upper: &VoxelBlock, axis: usize, s: &mut SlabScratch) {
    s.found.clear();
    let n = upper.cells();
    if lower.cells() != n || n < 2 * FACE_EDGE_NODES + 1 {
        return;
    }
    let m = n + 1;
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    let layers = 2 * SLAB_CELLS + 1;
    s.ids.clear();
    s.ids.resize(7 * layers * m * m, NONE);
    s.sites.clear();
    s.mesh.clear();
    s.tris.clear();
    s.sides.clear();
    let sp = upper.level().spacing() as f32;
    let with_materials = lower.has_materials() && upper.has_materials();
    let mut ids: SmallVec<[u32; 4]> = SmallVec::new();
    for (side, block) in [lower, upper].into_iter().enumerate() {
        let mut cells = [0..n, 0..n, 0..n];
        cells[axis] = if side == 0 { n - SLAB_CELLS..n } else { 0..SLAB_CELLS };
        let shift = if side == 0 { -(n as i64) } else { 0 };
        for_each_piece(block, cells, |edges| {
            ids.clear();
            for &(dir, l, _) in edges {
                let mut node = l.map(|c| c as i64);
                node[axis] += shift;
                let slot = dir
                    + 7 * ((node[axis] + SLAB_CELLS as i64) as usize
                        + layers * (node[u] as usize + m * node[w] as usize));
                if s.ids[slot] == NONE {
                    s.ids[slot] = s.mesh.positions.len() as u32;
                    let (t, normal) = edge_point(&Crossings { block, normals: None }, dir, l);
                    s.mesh.positions.push((along(node.map(|c| c as f32), dir, t) * sp).to_array());
                    s.mesh.normals.push(normal.normalize_or(Vec3::Z).to_array());
                    if with_materials {
                        s.mesh.materials.push(VertexMaterial::single(edge_vertex_material(block, dir, l)));
                    }
                    s.sites.push((dir, node, t));
                }
                ids.push(s.ids[slot]);
            }
            let before = s.tris.len();
            let sites = &s.sites;
            push_piece(&ids, edges, |v| sites[v as usize].2, &mut s.tris);
            s.sides.resize(s.tris.len().max(before), side as u8);
        });
    }
    // Clusters at the face's inner nodes; the slab's outer vertices stay.
    let count = s.sites.len();
    let mut rep: Vec<u32> = (0..count as u32).collect();
    let mut locked = vec![false; count];
    let mut first = vec![NONE; m * m];
    let free = FACE_EDGE_NODES as i64..=(n - FACE_EDGE_NODES) as i64;
    let mut any = false;
    for (v, &(dir, node, t)) in s.sites.iter().enumerate() {
        let d = offset(DIRS[dir]);
        let outer = (d[axis] == 0 && node[axis].unsigned_abs() as usize == SLAB_CELLS)
            || [u, w].iter().any(|&k| d[k] == 0 && (node[k] == 0 || node[k] == n as i64));
        if outer {
            locked[v] = true;
            continue;
        }
        let near = nearer_end(node, dir, t);
        if near[axis] != 0 || !free.contains(&near[u]) || !free.contains(&near[w]) {
            continue;
        }
        let slot = &mut first[near[u] as usize + m * near[w] as usize];
        if *slot == NONE {
            *slot = v as u32;
        } else {
            any = true;
        }
        rep[v] = *slot;
    }
    if !any {
        return;
    }
    let c = Clustering::new(&s.mesh.positions, &s.mesh.normals, &s.tris, &locked, sp)
        .with_sides(&s.sides)
        .with_snap(axis, sp / 16384.0)
        .run(rep);
    for (i, &v) in c.kept.iter().enumerate() {
        if c.samples.of(i as u32).len() < 2 {
            continue;
        }
        let (dir, node, t) = s.sites[v as usize];
        s.found.push(FaceCluster {
            node: nearer_end(node, dir, t).map(|c| c as usize),
            position: c.positions[i],
            normal: c.normals[i],
            material: s.mesh.materials.get(v as usize).copied().unwrap_or_default(),
        });
    }
}

/// The node clusters of the chunk faces made so far in one meshing batch (each by
/// [`face_clusters`]), by the face's upper chunk and axis, in that chunk's block frame: the
/// first of a face's two chunks to need it makes it (two at once make it alike), the other takes
/// it from here.
#[derive(Debug, Default)]
pub(crate) struct ChunkFaces(Mutex<HashMap<FaceKey, Arc<Vec<FaceCluster>>>>);

/// A chunk face: its upper chunk and its axis.
type FaceKey = (ChunkKey, u8);

/// The regularised tetrahedra mesh of chunk `key` of `volume` as the viewport meshes it, into
/// `out` (its block extracted into `block`): the chunk's own clusters, and the node clusters of
/// its faces, made together with the neighbouring chunks' blocks (or found in `faces`, made by
/// a neighbour in the same batch), so that chunk meshes cluster across their faces and still
/// meet exactly. `volume` must have one level.
pub(crate) fn mesh_chunk_clustered(
    volume: &strata_volume::Volume,
    key: ChunkKey,
    faces: &ChunkFaces,
    block: &mut VoxelBlock,
    s: &mut TetraScratch,
    out: &mut Mesh,
) {
    volume.extract_block_into(key, block);
    let n = block.cells();
    let sp = block.level().spacing() as f32;
    s.faces.clear();
    for axis in 0..3 {
        for this_is_lower in [false, true] {
            // A face with no surface in this chunk's slab gives it nothing to pin.
            let mut cells = [0..n, 0..n, 0..n];
            cells[axis] = if this_is_lower { n - SLAB_CELLS..n } else { 0..SLAB_CELLS };
            if !any_mixed(block, &cells) {
                continue;
            }
            let mut d = IVec3::ZERO;
            d[axis] = 1;
            let face = (if this_is_lower { key.offset(d) } else { key }, axis as u8);
            let made = faces.0.lock().ok().and_then(|m| m.get(&face).cloned());
            let made = match made {
                Some(m) => m,
                None => {
                    let other = if this_is_lower { d } else { -d };
                    volume.extract_block_into(key.offset(other), &mut s.neighbour);
                    if this_is_lower {
                        face_clusters(block, &s.neighbour, axis, &mut s.slab);
                    } else {
                        face_clusters(&s.neighbour, block, axis, &mut s.slab);
                    }
                    let m = Arc::new(std::mem::take(&mut s.slab.found));
                    if let Ok(mut map) = faces.0.lock() {
                        map.insert(face, m.clone());
                    }
                    m
                }
            };
            for f in made.iter() {
                let mut f = *f;
                if this_is_lower {
                    // Into this block's frame: exact, as the position lies on the snap's steps.
                    f.node[axis] = n;
                    f.position[axis] += n as f32 * sp;
                }
                s.faces.push(f);
            }
        }
    }
    mesh_candidates_and_cluster(block, true, s, out);
}

/// The vertex on lattice edge (`dir`, `lower`), made on first use.
#[allow(clippy::too_many_arguments)]
fn vertex(
    block: &VoxelBlock,
    s: &mut TetraScratch,
    out: &mut Mesh,
    dir: usize,
    lower: [usize; 3],
    sp: f32,
    with_materials: bool,
    node: usize,
) -> u32 {
    let slot = if dir < 3 {
        let axis = Axis::from_index(dir);
        let i = block
            .crossing_index(axis, lower[0], lower[1], lower[2])
            .expect("a voxel block has a crossing on every edge whose nodes differ");
        &mut s.axis[dir][i as usize]
    } else {
        &mut s.diag[dir - 3][node]
    };
    if *slot != NONE {
        return *slot;
    }
    let id = out.positions.len() as u32;
    *slot = id;
    let (t, normal) = edge_point(&Crossings { block, normals: Some(&s.normals) }, dir, lower);
    out.positions.push((along(lower.map(|c| c as f32), dir, t) * sp).to_array());
    out.normals.push(normal.normalize_or(Vec3::Z).to_array());
    if with_materials {
        out.materials.push(VertexMaterial::single(edge_vertex_material(block, dir, lower)));
    }
    s.sites.push(Site { dir: dir as u8, lower: lower.map(|c| c as u8) });
    s.ts.push(t);
    id
}

/// A block's axis crossings, with their normals decoded once where the caller has them.
struct Crossings<'a> {
    block: &'a VoxelBlock,
    /// Each axis's crossing normals, decoded (`unpack_normal(..).as_vec3()`), by crossing index.
    normals: Option<&'a [Vec<Vec3>; 3]>,
}

impl Crossings<'_> {
    /// The crossing on the edge along `axis` from `lower`: its position along the edge and its
    /// normal; `None` where the edge's nodes agree.
    #[inline]
    fn at(&self, axis: usize, lower: [usize; 3]) -> Option<(f32, Vec3)> {
        let i = self.block.crossing_index(Axis::from_index(axis), lower[0], lower[1], lower[2])? as usize;
        let c = &self.block.crossings(Axis::from_index(axis))[i];
        let normal = match self.normals {
            Some(n) => n[axis][i],
            None => unpack_normal(c.normal).as_vec3(),
        };
        Some((c.t, normal))
    }
}

/// Where the surface crosses lattice edge (`dir`, `lower`) of the block: the position along the
/// edge from its lower node, and the normal there (not normalised).
fn edge_point(c: &Crossings, dir: usize, lower: [usize; 3]) -> (f32, Vec3) {
    if dir < 3 {
        c.at(dir, lower).expect("a voxel block has a crossing on every edge whose nodes differ")
    } else if dir < 6 {
        face_diagonal(c, lower, offset(DIRS[dir]))
    } else {
        body_diagonal(c, lower)
    }
}

/// The material of the vertex on lattice edge (`dir`, `lower`): the solid end's, whole.
fn edge_vertex_material(block: &VoxelBlock, dir: usize, lower: [usize; 3]) -> strata_volume::MaterialId {
    if dir < 3 {
        return edge_material(block, Axis::from_index(dir), lower.map(|c| c as u8));
    }
    let d = offset(DIRS[dir]);
    let solid = if block.inside(lower[0], lower[1], lower[2]) {
        lower
    } else {
        [lower[0] + d[0], lower[1] + d[1], lower[2] + d[2]]
    };
    block.material(solid[0], solid[1], solid[2])
}

/// The crossing on a face diagonal from `lower` along the two axes of `d`: where the segment
/// between the face's two axis crossings (one on each side of the diagonal) meets it, with the
/// normals blended there. Uses only the face's four edges, which both blocks sharing the face
/// hold identically.
fn face_diagonal(crossings: &Crossings, lower: [usize; 3], d: [usize; 3]) -> (f32, Vec3) {
    let block = crossings.block;
    let axes: SmallVec<[usize; 2]> = (0..3).filter(|&k| d[k] == 1).collect();
    let (a, b) = (axes[0], axes[1]);
    // The crossing on the path through the corner `lower + e_first`, in face coordinates.
    let path = |first: usize, second: usize| -> ([f32; 2], Vec3) {
        let mut corner = lower;
        corner[first] += 1;
        let (edge_lower, along, at) =
            if block.inside(lower[0], lower[1], lower[2]) != block.inside(corner[0], corner[1], corner[2]) {
                (lower, first, 0.0)
            } else {
                (corner, second, 1.0)
            };
        let (t, normal) = crossings
            .at(along, edge_lower)
            .expect("one edge of each path from one end of the diagonal to the other changes state");
        let mut uv = [0.0f32; 2];
        let (fi, si) = if first == a { (0, 1) } else { (1, 0) };
        if along == first {
            uv[fi] = t;
        } else {
            uv[fi] = at;
            uv[si] = t;
        }
        (uv, normal)
    };
    let (p1, n1) = path(a, b);
    let (p2, n2) = path(b, a);
    // p1 lies below the diagonal (u > v), p2 above: the segment meets it strictly inside.
    let (g1, g2) = (p1[0] - p1[1], p2[0] - p2[1]);
    let lambda = (g1 / (g1 - g2)).clamp(0.0, 1.0);
    let t = p1[0] + lambda * (p2[0] - p1[0]);
    (t.clamp(1.0 / 1024.0, 1.0 - 1.0 / 1024.0), n1 * (1.0 - lambda) + n2 * lambda)
}

/// The crossing on the body diagonal of the cell at `lower`: the least-squares meeting point of
/// the tangent planes at the cell's axis crossings with the diagonal, kept inside the edge.
fn body_diagonal(crossings: &Crossings, lower: [usize; 3]) -> (f32, Vec3) {
    // The cell's twelve edges, axis by axis (the order of `VoxelBlock::cell_crossings`; the
    // next two axes in turn, as `Axis::across` names them).
    let planes = (0..3).flat_map(|axis| {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        (0..4).filter_map(move |edge| {
            let mut l = lower;
            l[u] += edge & 1;
            l[v] += edge >> 1;
            let (t, nrm) = crossings.at(axis, l)?;
            let mut p = Vec3::new((l[0] - lower[0]) as f32, (l[1] - lower[1]) as f32, (l[2] - lower[2]) as f32);
            p[axis] += t;
            Some((p, nrm))
        })
    });
    body_diagonal_from(planes)
}

/// The body diagonal's crossing from the tangent planes at a cell's axis crossings (point in the
/// cell's frame, normal), summed in the order given.
fn body_diagonal_from(planes: impl Iterator<Item = (Vec3, Vec3)>) -> (f32, Vec3) {
    let (mut num, mut den, mut normal) = (0.0f32, 0.0f32, Vec3::ZERO);
    for (p, nrm) in planes {
        let k = nrm.x + nrm.y + nrm.z;
        num += k * nrm.dot(p);
        den += k * k;
        normal += nrm;
    }
    let t = if den > 1e-6 { num / den } else { 0.5 };
    let t = if t.is_finite() { t } else { 0.5 };
    (t.clamp(0.05, 0.95), normal)
}

/// The lattice edge identity of a tetrahedra mesh vertex: its direction (3 + direction index,
/// after the three axes' 0..3 of marching cubes' keys) and the lower node's absolute position in
/// fixed-point steps.
fn site_key(key: ChunkKey, block: &VoxelBlock, site: Site, t: f32) -> EdgeKey {
    if (site.dir as usize) < 3 {
        return crate::marching::vertex_key(
            key,
            block.level(),
            Axis::from_index(site.dir as usize),
            site.lower.map(u32::from),
            t,
        );
    }
    let s = block.level().steps_per_cell() as i64;
    let l = I64Vec3::new(site.lower[0] as i64, site.lower[1] as i64, site.lower[2] as i64);
    (3 + site.dir, key.0.as_i64vec3() * crate::weld::KEY_STEPS + l * s)
}

/// The identity across chunks of each vertex of the mesh last made with `scratch` from `block`:
/// a face cluster's by its node, any other by its lattice edge.
fn vertex_keys(block: &VoxelBlock, scratch: &TetraScratch) -> Vec<EdgeKey> {
    let key = block.key().unwrap_or(ChunkKey::new(0, 0, 0));
    let steps = block.level().steps_per_cell() as i64;
    scratch
        .sites
        .iter()
        .zip(&scratch.ts)
        .enumerate()
        .map(|(v, (&site, &t))| match scratch.face_of.get(v).copied().unwrap_or(NONE) {
            NONE => site_key(key, block, site, t),
            f => {
                let node = I64Vec3::from_array(scratch.faces[f as usize].node.map(|c| c as i64));
                (FACE_CLUSTER_KEY, key.0.as_i64vec3() * crate::weld::KEY_STEPS + node * steps)
            }
        })
        .collect()
}

/// The direction code of a face cluster's identity (after the lattice edges' 0..10).
const FACE_CLUSTER_KEY: u8 = 16;

/// Clusters the candidate mesh of one block in place: the private vertices by their nearest
/// node (vertices on edges in a chunk face are shared with a neighbour and stay), the members of
/// the face clusters in `s.faces` into those, as they were made with the neighbours.
fn cluster_block(n: usize, sp: f32, s: &mut TetraScratch, out: &mut Mesh) {
    let m = n + 1;
    let count = out.positions.len();
    s.node_rep.clear();
    s.node_rep.resize(m * m * m, NONE);
    s.face_at.clear();
    if !s.faces.is_empty() {
        s.face_at.resize(m * m * m, NONE);
        for (i, f) in s.faces.iter().enumerate() {
            s.face_at[f.node[0] + m * (f.node[1] + m * f.node[2])] = i as u32;
        }
    }
    let mut rep: Vec<u32> = (0..count as u32).collect();
    let mut locked = vec![false; count];
    let mut pin = vec![NONE; if s.faces.is_empty() { 0 } else { count }];
    for (v, (site, &t)) in s.sites.iter().zip(&s.ts).enumerate() {
        let near = nearest_node(site, t);
        let at = near[0] + m * (near[1] + m * near[2]);
        let face = s.face_at.get(at).copied().unwrap_or(NONE);
        if face == NONE && on_chunk_face(site, n) {
            locked[v] = true;
            continue;
        }
        let slot = &mut s.node_rep[at];
        if *slot == NONE {
            *slot = v as u32;
        }
        rep[v] = *slot;
        if face != NONE {
            // A face cluster: shared with the neighbour, so it stays where it was made.
            locked[v] = true;
            pin[v] = face;
        }
    }
    let clustered = if s.faces.is_empty() {
        cluster_twice(out, &s.tris, rep, &locked, sp, None)
    } else {
        let places: Vec<([f32; 3], [f32; 3])> = s.faces.iter().map(|f| (f.position, f.normal)).collect();
        cluster_twice(out, &s.tris, rep, &locked, sp, Some((&pin, &places)))
    };
    let kept = finish(clustered, out);
    s.face_of = kept.iter().map(|&v| pin.get(v as usize).copied().unwrap_or(NONE)).collect();
    if !out.materials.is_empty() {
        for (material, &f) in out.materials.iter_mut().zip(&s.face_of) {
            if f != NONE {
                *material = s.faces[f as usize].material;
            }
        }
    }
    s.sites = kept.iter().map(|&v| s.sites[v as usize]).collect();
    s.ts = kept.iter().map(|&v| s.ts[v as usize]).collect();
}

/// Clusters the candidate mesh `out` (triangles `tris`) by `rep`, then merges the remaining
/// short edges in pairs, [`SHORT_EDGE_ROUNDS`] rounds, each verified as the first.
fn cluster_twice(
    out: &Mesh,
    tris: &[[u32; 3]],
    rep: Vec<u32>,
    locked: &[bool],
    cell: f32,
    pins: Option<crate::cluster::Pins<'_>>,
) -> Clustered {
    let first = Clustering::new(&out.positions, &out.normals, tris, locked, cell);
    let first = match pins {
        Some((pin, places)) => first.with_pins(pin, places),
        None => first,
    };
    let mut c = first.run(rep);
    for _ in 0..SHORT_EDGE_ROUNDS {
        let locked: Vec<bool> = c.kept.iter().map(|&v| locked[v as usize]).collect();
        let pairs = crate::cluster::short_pairs(&c, &locked, SHORT_EDGE_CELLS * cell);
        let next = Clustering::new(&c.positions, &c.normals, &c.tris, &locked, cell)
            .with_samples(&out.positions, &out.normals, &c.samples)
            .with_candidate_tris(tris)
            .with_max_rms(SHORT_EDGE_RMS_CELLS * cell)
            .with_bounds(SHORT_EDGE_REACH_CELLS, SHORT_EDGE_MOVE_CELLS)
            .run(pairs);
        let kept = next.kept.iter().map(|&v| c.kept[v as usize]).collect();
        c = Clustered { kept, ..next };
    }
    c
}

/// Short edges are merged in pairs this many rounds after the node clusters.
pub const SHORT_EDGE_ROUNDS: usize = 2;

/// The rounds merge edges shorter than this many cells, shortest first.
pub const SHORT_EDGE_CELLS: f32 = 0.9;

/// A pair stays merged only if its candidates' tangent planes pass within this root-mean-square
/// distance (cells) of the merged vertex, so edges and corners are not cut. (At 0.05 the noise
/// asteroid of Table 10 kept 77.2 % whole and 74.0 % per chunk, its ridges' planes turning too
/// fast; at 0.1 it keeps 80.8 % and 77.2 %, the other shapes within about half a point of
/// before, and the half-cell bound holds as before.)
pub const SHORT_EDGE_RMS_CELLS: f32 = 0.1;

/// And if every candidate lies within this distance (cells) of the merged vertex (the node
/// clusters' [`MAX_REACH_CELLS`] would refuse most pairs: their candidates span two nodes; at
/// 0.5 the sphere of radius 20 kept 73.8 % whole, 66.5 % per chunk, against 82.9 % and 75.8 %;
/// candidates beyond [`MAX_REACH_CELLS`] are checked against the triangles around the vertex) ...
pub const SHORT_EDGE_REACH_CELLS: f32 = 1.0;

/// ... and within this distance (cells) of its tangent plane (tighter than the node clusters'
/// [`MAX_MOVE_CELLS`]).
pub const SHORT_EDGE_MOVE_CELLS: f32 = 0.2;

/// Replaces `out` with the clustered mesh (materials: those of the vertices standing for the
/// clusters); returns the candidate vertex standing for each output vertex.
fn finish(c: Clustered, out: &mut Mesh) -> Vec<u32> {
    if !out.materials.is_empty() {
        out.materials = c.kept.iter().map(|&v| out.materials[v as usize]).collect();
    }
    out.positions = c.positions;
    out.normals = c.normals;
    out.indices.clear();
    out.indices.extend(c.tris.iter().flatten());
    c.kept
}

/// The node a vertex at `t` along its edge is nearest to (block-local).
fn nearest_node(site: &Site, t: f32) -> [usize; 3] {
    nearer_end(site.lower.map(i64::from), site.dir as usize, t).map(|c| c as usize)
}

/// One chunk's mesh with its vertices' identities: only the vertices shared with other chunks
/// (on edges in a chunk face) have one, and they come first.
type ChunkPart = (ChunkKey, Mesh, Vec<EdgeKey>);

/// The node a chunk's vertex is nearest to: its index in the chunk's block when inside the
/// chunk (no other chunk's vertex can be nearest to it), else `NONE` and its global position
/// (cells of the volume's level).
#[derive(Clone, Copy, Debug)]
pub(crate) struct NearNode {
    local: u32,
    global: I64Vec3,
}

/// Whether a vertex's lattice edge lies in a face of its chunk (`n` cells), so that the
/// neighbouring chunk meshes the same vertex.
fn on_chunk_face(site: &Site, n: usize) -> bool {
    let d = offset(DIRS[site.dir as usize]);
    let l = site.lower.map(usize::from);
    (0..3).any(|k| d[k] == 0 && (l[k] == 0 || l[k] == n))
}

/// The tetrahedra mesh of every chunk that can hold surface (clustered chunk by chunk when
/// `cluster`), shared vertices first with their identities, and each vertex's nearest node.
pub(crate) fn chunk_parts(volume: &strata_volume::Volume, cluster: bool) -> Vec<(ChunkPart, Vec<NearNode>)> {
    use rayon::prelude::*;
    let faces = ChunkFaces::default();
    crate::surface_chunks(volume)
        .par_iter()
        .map_init(
            || (VoxelBlock::default(), TetraScratch::default()),
            |(block, scratch), &key| {
                let mut m = Mesh::default();
                if cluster {
                    mesh_chunk_clustered(volume, key, &faces, block, scratch, &mut m);
                } else {
                    volume.extract_block_into(key, block);
                    mesh_block_tetra(block, false, scratch, &mut m);
                }
                let ids = vertex_keys(block, scratch);
                let n = block.cells();
                let side = n + 1;
                let origin = key.0.as_i64vec3() * n as i64;
                // Shared vertices first, each group in its old order.
                let shared: Vec<bool> = (scratch.sites.iter().enumerate())
                    .map(|(v, site)| scratch.face_of.get(v).is_some_and(|&f| f != NONE) || on_chunk_face(site, n))
                    .collect();
                let order: Vec<u32> = (0..shared.len() as u32)
                    .filter(|&v| shared[v as usize])
                    .chain((0..shared.len() as u32).filter(|&v| !shared[v as usize]))
                    .collect();
                let mut index = vec![0u32; order.len()];
                for (new, &old) in order.iter().enumerate() {
                    index[old as usize] = new as u32;
                }
                let mut part = Mesh::default();
                for &old in &order {
                    part.push_vertex_from(&m, old as usize, [0.0; 3]);
                }
                part.indices = m.indices.iter().map(|&i| index[i as usize]).collect();
                let ids: Vec<EdgeKey> =
                    order.iter().take_while(|&&v| shared[v as usize]).map(|&v| ids[v as usize]).collect();
                let nodes = order
                    .iter()
                    .map(|&v| {
                        let near = nearest_node(&scratch.sites[v as usize], scratch.ts[v as usize]);
                        let inside = near.iter().all(|&c| c > 0 && c < n);
                        NearNode {
                            local: if inside { (near[0] + side * (near[1] + side * near[2])) as u32 } else { NONE },
                            global: origin + I64Vec3::from_array(near.map(|c| c as i64)),
                        }
                    })
                    .collect();
                ((key, part, ids), nodes)
            },
        )
        .collect()
}

/// One welded marching-tetrahedra mesh of the whole volume (grid units, absolute), with the
/// integrated clustering when `cluster`. `None` for a volume whose chunks mix levels: tetrahedra
/// do not patch the seams between levels (marching cubes does).
pub(crate) fn tetra_volume(volume: &strata_volume::Volume, cluster: bool) -> Option<Mesh> {
    if !volume.single_level() {
        return None;
    }
    Some(tetra_volume_impl(volume, cluster))
}

/// Regularised marching tetrahedra chunk by chunk, as [`crate::MeshCache`] meshes them for the
/// viewport (chunk faces clustered with both chunks, the vertices near their edges never
/// merged), welded into one mesh (grid units, absolute). `None` for a volume whose chunks mix
/// levels.
pub fn tetra_volume_per_chunk(volume: &strata_volume::Volume) -> Option<Mesh> {
    if !volume.single_level() {
        return None;
    }
    Some(crate::weld::weld(chunk_parts(volume, true).into_iter().map(|(p, _)| p).collect()))
}

/// One welded marching-tetrahedra mesh of the whole volume, clustered over the whole mesh when
/// `cluster` (no chunk face is locked: the export path, where no chunk is meshed alone).
pub(crate) fn tetra_volume_impl(volume: &strata_volume::Volume, cluster: bool) -> Mesh {
    // One level throughout (checked by the callers): its spacing scales the short edges.
    let spacing = volume.chunks().next().map_or(1.0, |(k, _)| volume.mesh_level(k).spacing() as f32);
    let (parts, near): (Vec<_>, Vec<_>) = chunk_parts(volume, false).into_iter().unzip();
    let (mut out, source) = crate::weld::weld_traced(&parts);
    if cluster {
        let tris: Vec<[u32; 3]> = out.triangles().collect();
        // Nodes inside a chunk gather its vertices alone (one table per chunk, in turn);
        // nodes on chunk faces gather vertices from several chunks (sorted together).
        let mut rep: Vec<u32> = (0..out.positions.len() as u32).collect();
        let mut table: Vec<u32> = Vec::new();
        let mut touched: Vec<u32> = Vec::new();
        let mut faces: Vec<((i64, i64, i64), u32)> = Vec::new();
        let mut current = u32::MAX;
        for (v, &(part, i)) in source.iter().enumerate() {
            if part != current {
                for &t in &touched {
                    table[t as usize] = NONE;
                }
                touched.clear();
                current = part;
            }
            let node = near[part as usize][i as usize];
            if node.local == NONE {
                faces.push(((node.global.z, node.global.y, node.global.x), v as u32));
                continue;
            }
            let slot = node.local as usize;
            if slot >= table.len() {
                table.resize(slot + 1, NONE);
            }
            if table[slot] == NONE {
                table[slot] = v as u32;
                touched.push(node.local);
            }
            rep[v] = table[slot];
        }
        faces.sort_unstable();
        for group in faces.chunk_by(|a, b| a.0 == b.0) {
            for g in group {
                rep[g.1 as usize] = group[0].1;
            }
        }
        let locked = vec![false; out.positions.len()];
        let clustered = cluster_twice(&out, &tris, rep, &locked, spacing, None);
        finish(clustered, &mut out);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_six_tetrahedra_fill_the_cell_and_share_faces_with_neighbours() {
        let tets = tetrahedra();
        let vol: f64 = tets
            .iter()
            .map(|c| {
                let p = c.map(|k| {
                    let o = offset(k);
                    DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64)
                });
                ((p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]) / 6.0).abs()
            })
            .sum();
        assert!((vol - 1.0).abs() < 1e-12);
        // Every tetrahedron edge is a lattice edge: lower corner a subset of the upper.
        for c in tets {
            for i in 0..4 {
                for j in i + 1..4 {
                    assert_eq!(c[i] & c[j], c[i], "edges go up the lattice");
                }
            }
        }
    }

    /// The body diagonal as it was computed before the normals were decoded once per block:
    /// through [`VoxelBlock::cell_crossings`], each normal decoded where it is read.
    fn body_diagonal_by_cell_crossings(block: &VoxelBlock, lower: [usize; 3]) -> (f32, Vec3) {
        let [x, y, z] = lower;
        body_diagonal_from(block.cell_crossings(x, y, z).map(|(axis, l, c)| {
            let mut p = Vec3::new((l[0] - x) as f32, (l[1] - y) as f32, (l[2] - z) as f32);
            p[axis.index()] += c.t;
            (p, unpack_normal(c.normal).as_vec3())
        }))
    }

    #[test]
    fn diagonal_vertices_from_decoded_normals_equal_those_decoded_where_read() {
        use strata_volume::brush::{Cuboid, Sphere};
        let mut v = strata_volume::Volume::new();
        v.add(&Sphere::new(DVec3::new(20.3, 19.6, 21.1), 13.7).unwrap()).unwrap();
        // Faces on grid planes and a sphere cut away: crossings at nodes and normals of every sign.
        v.add(&Cuboid::new(DVec3::new(8.0, 17.0, 7.0), DVec3::new(4.0, 13.0, 2.5)).unwrap()).unwrap();
        v.subtract(&Sphere::new(DVec3::new(27.0, 25.0, 14.0), 6.2).unwrap()).unwrap();
        let mut block = VoxelBlock::default();
        let mut checked = [0usize; 4];
        let bits = |p: (f32, Vec3)| (p.0.to_bits(), p.1.to_array().map(f32::to_bits));
        for key in crate::surface_chunks(&v) {
            v.extract_block_into(key, &mut block);
            let normals: [Vec<Vec3>; 3] =
                Axis::ALL.map(|a| block.crossings(a).iter().map(|c| unpack_normal(c.normal).as_vec3()).collect());
            let decoded = Crossings { block: &block, normals: Some(&normals) };
            let where_read = Crossings { block: &block, normals: None };
            let n = block.cells();
            // Every lattice edge of the block, those on its far faces included.
            for (z, y, x) in (0..=n).flat_map(|z| (0..=n).flat_map(move |y| (0..=n).map(move |x| (z, y, x)))) {
                let lower = [x, y, z];
                for (dir, &mask) in DIRS.iter().enumerate() {
                    let d = offset(mask);
                    let upper = [x + d[0], y + d[1], z + d[2]];
                    if upper.iter().any(|&c| c > n) {
                        continue;
                    }
                    if dir < 3 {
                        let axis = Axis::from_index(dir);
                        let want =
                            block.crossing(axis, x, y, z).map(|c| bits((c.t, unpack_normal(c.normal).as_vec3())));
                        assert_eq!(decoded.at(dir, lower).map(bits), want, "axis {dir} at {lower:?}");
                        assert_eq!(where_read.at(dir, lower).map(bits), want);
                        checked[0] += want.is_some() as usize;
                        continue;
                    }
                    if block.inside(x, y, z) == block.inside(upper[0], upper[1], upper[2]) {
                        continue;
                    }
                    let got = bits(edge_point(&decoded, dir, lower));
                    assert_eq!(got, bits(edge_point(&where_read, dir, lower)), "direction {dir} at {lower:?}");
                    if dir == 6 {
                        assert_eq!(
                            got,
                            bits(body_diagonal_by_cell_crossings(&block, lower)),
                            "body diagonal at {lower:?}"
                        );
                        checked[2] += 1;
                    } else {
                        checked[1] += 1;
                    }
                }
                if x < n && y < n && z < n {
                    let rows = [block.row(y, z), block.row(y + 1, z), block.row(y, z + 1), block.row(y + 1, z + 1)];
                    let want = (0..8).fold(0u8, |acc, c| {
                        let o = offset(c);
                        acc | (block.inside(x + o[0], y + o[1], z + o[2]) as u8) << c
                    });
                    assert_eq!(corner_states(&rows, x), want, "corners of cell {lower:?}");
                    checked[3] += (want != 0 && want != 255) as usize;
                }
            }
        }
        assert!(checked.iter().all(|&c| c > 100), "too few edges or cells checked: {checked:?}");
    }
}
