//! Voxel blocks of chunks whose neighbours differ in level (crack patching, the paper's VI-C).
//!
//! Every face a block shares with a neighbour is taken from [`effective_face`]: the data of the
//! coarser chunk, refined by the face table where the block is finer. The block's edges that run
//! from a face into the chunk are then made to agree with the face's nodes (a crossing added at
//! the edge's middle where they now differ, removed where they now agree), so the block stays
//! consistent on all three axes. Only the block changes; the stored lists are untouched.
//!
//! The coarser block of a seam also records, for each contour segment on the shared face, the
//! extra vertices the finer block's contour has on it ([`SeamSplit`]), so a mesher can split its
//! triangle there and the two meshes share every edge.

use glam::IVec3;

use crate::axis::{Axis, compose};
use crate::block::{SeamPoint, SeamSplit, VoxelBlock};
use crate::coords::ChunkKey;
use crate::level::dense::Dense;
use crate::level::face::pos;
use crate::level::read::{LevelMap, effective_face};

/// The face and edge neighbours of a chunk (whose data or level its block depends on).
pub(crate) const NEIGHBOURS: [IVec3; 18] = [
    IVec3::new(1, 0, 0),
    IVec3::new(-1, 0, 0),
    IVec3::new(0, 1, 0),
    IVec3::new(0, -1, 0),
    IVec3::new(0, 0, 1),
    IVec3::new(0, 0, -1),
    IVec3::new(1, 1, 0),
    IVec3::new(1, -1, 0),
    IVec3::new(-1, 1, 0),
    IVec3::new(-1, -1, 0),
    IVec3::new(1, 0, 1),
    IVec3::new(1, 0, -1),
    IVec3::new(-1, 0, 1),
    IVec3::new(-1, 0, -1),
    IVec3::new(0, 1, 1),
    IVec3::new(0, 1, -1),
    IVec3::new(0, -1, 1),
    IVec3::new(0, -1, -1),
];

/// Whether the block of `key` can be read by the plain extractor: it and its face and edge
/// neighbours are all meshed at the level they are stored at, which is the block's level, and
/// the plain extractor's level for it (a uniform chunk's is the volume's). Without the last
/// condition a uniform chunk whose list neighbours all share another level (far terrain at
/// the coarse level in a base-level world) was read plainly at the volume's level while they
/// meshed the cells at its corner edges at theirs, and the surface through them opened. A
/// uniform neighbour is read plainly only at the volume's level or below ([`uniform_binds`]).
pub(crate) fn plain(map: &LevelMap<'_>, key: ChunkKey) -> bool {
    let level = map.get(key);
    let same = |k: ChunkKey| {
        let stored_ok = match map.volume.stored_level(k) {
            Some(l) => l == level,
            None => uniform_binds(map, level),
        };
        stored_ok && map.get(k) == level
    };
    map.volume.level_of(key) == level && same(key) && NEIGHBOURS.iter().all(|&d| same(key.offset(d)))
}

/// Whether a uniform chunk's lines read at `level` agree with its list neighbours: at the
/// volume's level or below. A uniform chunk binds its neighbours' lines only at the volume's
/// level (as edits and the invariant checker read it), so a neighbour stored finer can end a
/// line between its nodes, or start one on a node of its own face, in the other state. Read
/// plainly at that finer level, the uniform chunk's line ends there would then contradict the
/// neighbour's nodes (a notch along a four-chunk edge under the detail tool opened the mesh);
/// patched, every shared face and chunk edge is taken from its effective data instead, and the
/// blocks on both sides agree.
fn uniform_binds(map: &LevelMap<'_>, level: crate::coords::Level) -> bool {
    level <= map.volume.level
}

/// Whether `key` and its face and edge neighbours are all meshed at one level in `map` (then
/// every line can be read straight from its owner at that level, with nothing to patch). A
/// neighbour whose level nothing decides (uniform, no list chunk across a face or an edge:
/// [`LevelMap::decided_level`]) agrees with any level: its lines are uniform at every level and
/// no seam runs along it. (Without that, the uniform chunks around a model viewed coarser than
/// it is stored, which take the level of their list neighbours, met uniform chunks farther out
/// at the volume's level, and each was patched through a dense grid.) A uniform chunk (the
/// block's own or a neighbour) whose level a list chunk decides agrees only where it binds its
/// neighbours at that level ([`uniform_binds`]).
pub(crate) fn same_level_around(map: &LevelMap<'_>, key: ChunkKey) -> bool {
    let level = map.get(key);
    let binds = |k: ChunkKey| map.volume.stored_level(k).is_some() || uniform_binds(map, level);
    binds(key)
        && NEIGHBOURS.iter().all(|&d| match map.decided_level(key.offset(d)) {
            Some(l) => l == level && binds(key.offset(d)),
            None => {
                // (It has no list neighbour: the block beside it is uniform too.)
                debug_assert!(map.volume.stored_level(key).is_none());
                true
            }
        })
}

/// The block of `key` at its level in `map`, with every shared face taken from its effective
/// data, and the seams towards finer neighbours recorded.
pub(crate) fn extract_patched(map: &LevelMap<'_>, key: ChunkKey, out: &mut VoxelBlock) {
    let level = map.get(key);
    let n = level.cells();
    let mut d = Dense::new(level);
    d.read_own_with(|axis| map.reader(key, axis));
    let mut faces = Vec::with_capacity(6);
    for normal in Axis::ALL {
        let step = normal.unit_i64().as_ivec3();
        for side in 0..2usize {
            let owner = if side == 0 { key } else { key.offset(step) };
            let g = effective_face(map, normal, owner, level);
            d.put_face(&g, side * n);
            let other = if side == 0 { key.offset(-step) } else { owner };
            faces.push((side, g, map.get(other)));
        }
    }
    let patched = d.make_consistent();
    out.fill_from_dense(key, level, &d, patched as u32);
    for (side, g, other_level) in faces {
        if other_level <= level {
            continue;
        }
        // The finer neighbour meshes this face refined to its level (the same computation).
        let fine = g.clone().refine_to(other_level);
        let r = fine.n / n;
        let s_fine = other_level.steps_per_cell();
        for j in 0..n {
            for i in 0..n {
                for (a, b, inner) in g.chains(&fine, i, j) {
                    if inner.is_empty() {
                        continue;
                    }
                    let edge = |(dir, ei, ej): (u8, usize, usize)| {
                        (g.dir_axis(dir), compose(g.normal, side * n, ei, ej).map(|c| c as u16))
                    };
                    let points = inner
                        .into_iter()
                        .map(|(dir, fi, fj)| {
                            let c = fine.crossing((dir, fi, fj));
                            let e = if dir == 0 { fi } else { fj };
                            SeamPoint {
                                axis: fine.dir_axis(dir),
                                level: other_level,
                                lower: compose(g.normal, side * n * r, fi, fj).map(|c| c as u16),
                                t: (pos(c).0 as u32 - e as u32 * s_fine) as f32 * (1.0 / s_fine as f32),
                                normal: crate::level::face::nrm(c),
                            }
                        })
                        .collect();
                    out.seams.push(SeamSplit { a: edge(a), b: edge(b), points });
                }
            }
        }
    }
}
