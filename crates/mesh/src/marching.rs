//! Marching cubes on voxel blocks: one vertex per edge crossing, placed exactly at the stored
//! crossing, shared by every triangle that uses it.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::I64Vec3;
use rayon::prelude::*;
use strata_volume::normal::unpack_normal;
use strata_volume::{Axis, ChunkKey, EdgeCrossing, KeyHasher, Level, Volume, VoxelBlock};

use crate::cases::cases;
use crate::weld::{EdgeKey, KEY_STEPS, weld};
use crate::{Mesh, VertexMaterial};

/// Meshes the cells `0..n` of one block into `out` (cleared first). Positions are grid units
/// relative to the origin of the block's chunk (a part of a chunk, [`VoxelBlock::offset`], is
/// placed where it is in the chunk); vertex `i` of the axis-`a` crossings is vertex
/// `first_vertex(block, a) + i`. The block's apron makes the mesh of neighbouring blocks meet
/// exactly: both place the vertices of shared edges from the same crossing.
pub fn mesh_block(block: &VoxelBlock, out: &mut Mesh) {
    out.clear();
    let n = block.cells();
    let sp = block.level().spacing() as f32;
    let with_materials = block.has_materials();
    let offset = block.offset();
    for axis in Axis::ALL {
        for c in block.crossings(axis) {
            out.positions.push(crossing_position(offset, sp, axis, c));
            out.normals.push(unpack_normal(c.normal).as_vec3().to_array());
            if with_materials {
                out.materials.push(VertexMaterial::single(edge_material(block, axis, c.lower)));
            }
        }
    }
    let base = [0, block.crossings(Axis::X).len(), block.crossings(Axis::X).len() + block.crossings(Axis::Y).len()];
    let table = cases();
    let mut ids: Vec<u32> = Vec::with_capacity(12);
    for z in 0..n {
        for y in 0..n {
            let (r00, r10, r01, r11) =
                (block.row(y, z), block.row(y + 1, z), block.row(y, z + 1), block.row(y + 1, z + 1));
            let mut mixed = block.mixed_cells(y, z);
            while mixed != 0 {
                let x = mixed.trailing_zeros() as usize;
                mixed &= mixed - 1;
                let bit = |r: u128, dx: usize| ((r >> (x + dx)) & 1) as usize;
                let case = bit(r00, 0)
                    | bit(r00, 1) << 1
                    | bit(r10, 0) << 2
                    | bit(r10, 1) << 3
                    | bit(r01, 0) << 4
                    | bit(r01, 1) << 5
                    | bit(r11, 0) << 6
                    | bit(r11, 1) << 7;
                for lp in &table[case] {
                    ids.clear();
                    for e in &lp.edges {
                        let axis = Axis::from_index(e.axis);
                        let i = block
                            .crossing_index(axis, x + e.lower[0], y + e.lower[1], z + e.lower[2])
                            .expect("a voxel block has a crossing on every edge whose nodes differ");
                        ids.push(base[e.axis] as u32 + i);
                    }
                    // Loops run clockwise seen from outside; emit counter-clockwise triangles.
                    let (k, a) = (ids.len(), lp.apex);
                    for d in 1..k - 1 {
                        let (p, q) = (ids[(a + d) % k], ids[(a + d + 1) % k]);
                        out.indices.extend_from_slice(&[ids[a], q, p]);
                    }
                }
            }
        }
    }
    if !block.seams().is_empty() {
        split_seams(block, base, out);
    }
}

/// Where marching cubes puts the vertex of crossing `c` along `axis` of a block whose node 0
/// lies at `offset` in its chunk, `spacing` grid units a cell: chunk-local grid units.
pub fn crossing_position(offset: [usize; 3], spacing: f32, axis: Axis, c: &EdgeCrossing) -> [f32; 3] {
    let mut p = [0, 1, 2].map(|i| (c.lower[i] as usize + offset[i]) as f32);
    p[axis.index()] += c.t;
    p.map(|v| v * spacing)
}

/// The material of the solid end of the edge along `axis` from node `lower` (a vertex on the
/// edge takes it whole: the other end is empty).
pub(crate) fn edge_material(block: &VoxelBlock, axis: Axis, lower: [u8; 3]) -> u8 {
    let [x, y, z] = lower.map(usize::from);
    if block.inside(x, y, z) {
        return block.material(x, y, z);
    }
    let mut l = [x, y, z];
    l[axis.index()] += 1;
    block.material(l[0], l[1], l[2])
}

/// Splits the triangles on faces shared with finer neighbours at the vertices the finer meshes
/// have on them ([`VoxelBlock::seams`]), so both meshes share every edge there. A triangle with
/// one split edge becomes a fan from its opposite corner; one with more (a corner cut off at a
/// chunk corner) a fan from its centroid.
fn split_seams(block: &VoxelBlock, base: [usize; 3], out: &mut Mesh) {
    let mut chains: HashMap<(u32, u32), Vec<u32>, BuildHasherDefault<KeyHasher>> = HashMap::default();
    let id = |(axis, l): (Axis, [u16; 3])| {
        block.crossing_index(axis, l[0] as usize, l[1] as usize, l[2] as usize).map(|i| base[axis.index()] as u32 + i)
    };
    for seam in block.seams() {
        let (Some(a), Some(b)) = (id(seam.a), id(seam.b)) else { continue };
        let mut ids = vec![a];
        for p in &seam.points {
            let material = out.material(a as usize);
            out.push_vertex(p.position(), unpack_normal(p.normal).as_vec3().to_array(), material, false);
            ids.push(out.positions.len() as u32 - 1);
        }
        ids.push(b);
        chains.insert((a, b), ids);
    }
    // The chain from `a` to `b` without its ends, if the edge is split.
    let chain = |a: u32, b: u32| -> Option<Vec<u32>> {
        if let Some(c) = chains.get(&(a, b)) {
            return Some(c[1..c.len() - 1].to_vec());
        }
        chains.get(&(b, a)).map(|c| c[1..c.len() - 1].iter().rev().copied().collect())
    };
    let old = std::mem::take(&mut out.indices);
    for t in old.chunks_exact(3) {
        let splits: [Option<Vec<u32>>; 3] = [chain(t[0], t[1]), chain(t[1], t[2]), chain(t[2], t[0])];
        let count = splits.iter().filter(|s| s.is_some()).count();
        if count == 0 {
            out.indices.extend_from_slice(t);
            continue;
        }
        if count == 1 {
            let k = splits.iter().position(|s| s.is_some()).expect("one split");
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let mut path = vec![a];
            path.extend(splits[k].as_ref().expect("split").iter().copied());
            path.push(b);
            for w in path.windows(2) {
                out.indices.extend_from_slice(&[c, w[0], w[1]]);
            }
            continue;
        }
        let mut ring = Vec::new();
        for k in 0..3 {
            ring.push(t[k]);
            if let Some(s) = &splits[k] {
                ring.extend(s.iter().copied());
            }
        }
        let centroid = |i: usize| t.iter().map(|&v| out.positions[v as usize][i]).sum::<f32>() / 3.0;
        let normal = {
            let mut n = [0.0f32; 3];
            for &v in t {
                for (i, c) in n.iter_mut().enumerate() {
                    *c += out.normals[v as usize][i];
                }
            }
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-12);
            n.map(|c| c / l)
        };
        let material = out.material(t[0] as usize);
        out.push_vertex([centroid(0), centroid(1), centroid(2)], normal, material, false);
        let m = out.positions.len() as u32 - 1;
        for k in 0..ring.len() {
            out.indices.extend_from_slice(&[m, ring[k], ring[(k + 1) % ring.len()]]);
        }
    }
}

/// A vertex's identity in the whole volume, whatever the level of the block it came from: its
/// edge's axis and its absolute fixed-point position (65,536 steps per chunk side).
pub(crate) fn vertex_key(chunk: ChunkKey, level: Level, axis: Axis, lower: [u32; 3], t: f32) -> EdgeKey {
    let s = level.steps_per_cell() as i64;
    let mut p = chunk.0.as_i64vec3() * KEY_STEPS + I64Vec3::new(lower[0] as i64, lower[1] as i64, lower[2] as i64) * s;
    // `t` is an exact multiple of 1 / s (a power of two): this gives back the stored steps.
    p[axis.index()] += (t as f64 * s as f64).round() as i64;
    (axis as u8, p)
}

/// The identities of a block's mesh vertices in the order [`mesh_block`] makes them, up to its
/// seam vertices (centroids of split triangles come after and have none).
pub(crate) fn block_vertex_keys(block: &VoxelBlock) -> Vec<EdgeKey> {
    let key = block.key().unwrap_or(ChunkKey::new(0, 0, 0));
    let level = block.level();
    let mut ids: Vec<EdgeKey> = Axis::ALL
        .iter()
        .flat_map(|&a| block.crossings(a).iter().map(move |c| vertex_key(key, level, a, c.lower.map(u32::from), c.t)))
        .collect();
    let found =
        |(axis, l): (Axis, [u16; 3])| block.crossing_index(axis, l[0] as usize, l[1] as usize, l[2] as usize).is_some();
    for seam in block.seams() {
        // As in `split_seams`: a seam whose ends are not both crossings of this block adds no
        // vertices.
        if !(found(seam.a) && found(seam.b)) {
            continue;
        }
        for p in &seam.points {
            ids.push(vertex_key(key, p.level, p.axis, p.lower.map(u32::from), p.t));
        }
    }
    ids
}

/// The chunks whose cells can hold surface: every stored chunk and the chunks before it on
/// each axis (their last cells end on the stored chunk's nodes).
pub fn surface_chunks(volume: &Volume) -> Vec<ChunkKey> {
    let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
    crate::MeshCache::dependents(&stored)
}

/// One welded mesh of the whole volume (grid units, absolute; f32 positions lose precision far
/// from the origin, so prefer per-chunk meshes there).
pub(crate) fn mesh_volume(volume: &Volume) -> Mesh {
    mesh_volume_impl(volume, None)
}

/// [`mesh_volume`] with every chunk `k` meshed at no finer than `cap(k)` (level of detail: the
/// coarser blocks are sampled from the stored lists, and seams between the levels patched, so
/// the mesh is closed for any map of caps).
pub(crate) fn mesh_volume_capped(volume: &Volume, cap: &(dyn Fn(ChunkKey) -> Level + Sync)) -> Mesh {
    mesh_volume_impl(volume, Some(cap))
}

fn mesh_volume_impl(volume: &Volume, cap: Option<&(dyn Fn(ChunkKey) -> Level + Sync)>) -> Mesh {
    weld(chunk_parts(volume, cap))
}

/// Every chunk's marching-cubes mesh (chunk-local positions) with its vertices' identities, for
/// the weld.
pub(crate) fn chunk_parts(
    volume: &Volume,
    cap: Option<&(dyn Fn(ChunkKey) -> Level + Sync)>,
) -> Vec<(ChunkKey, Mesh, Vec<EdgeKey>)> {
    let mut keys = surface_chunks(volume);
    if cap.is_none() {
        // A chunk whose apron's owners are uniform alike with it holds no surface.
        keys.retain(|&k| !volume.plain_block_uniform(k));
    }
    keys.par_iter()
        .map_init(VoxelBlock::default, |block, &key| {
            match cap {
                Some(c) => volume.extract_block_capped(key, c, block),
                None => volume.extract_block_into(key, block),
            }
            let mut m = Mesh::default();
            mesh_block(block, &mut m);
            let ids = block_vertex_keys(block);
            (key, m, ids)
        })
        .collect()
}
