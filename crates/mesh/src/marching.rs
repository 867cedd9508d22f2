//! Marching cubes on voxel blocks: one vertex per edge crossing, placed exactly at the stored
//! crossing, shared by every triangle that uses it.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::I64Vec3;
use rayon::prelude::*;
use strata_volume::normal::unpack_normal;
use strata_volume::{Axis, ChunkKey, KeyHasher, Volume, VoxelBlock};

use crate::Mesh;
use crate::cases::cases;

/// Meshes the cells `0..n` of one block into `out` (cleared first). Positions are grid units
/// relative to the block's origin; vertex `i` of the axis-`a` crossings is vertex
/// `first_vertex(block, a) + i`. The block's apron makes the mesh of neighbouring blocks meet
/// exactly: both place the vertices of shared edges from the same crossing.
pub fn mesh_block(block: &VoxelBlock, out: &mut Mesh) {
    out.clear();
    let n = block.cells();
    let sp = block.level().spacing() as f32;
    for axis in Axis::ALL {
        for c in block.crossings(axis) {
            let mut p = c.lower.map(|v| v as f32);
            p[axis.index()] += c.t;
            out.positions.push(p.map(|v| v * sp));
            out.normals.push(unpack_normal(c.normal).as_vec3().to_array());
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
}

/// The chunks whose cells can hold surface: every stored chunk and the chunks before it on
/// each axis (their last cells end on the stored chunk's nodes).
pub fn surface_chunks(volume: &Volume) -> Vec<ChunkKey> {
    let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
    crate::MeshCache::dependents(&stored)
}

/// A crossing's identity in the whole volume: its axis and the global node at its lower end.
type EdgeKey = (u8, I64Vec3);

/// One welded mesh of the whole volume (grid units, absolute; f32 positions lose precision far
/// from the origin, so prefer per-chunk meshes there).
pub fn mesh_volume(volume: &Volume) -> Mesh {
    let keys = surface_chunks(volume);
    let parts: Vec<(ChunkKey, Mesh, Vec<EdgeKey>)> = keys
        .par_iter()
        .map_init(VoxelBlock::default, |block, &key| {
            volume.extract_block_into(key, block);
            let mut m = Mesh::default();
            mesh_block(block, &mut m);
            let origin = key.origin_grid();
            let ids = Axis::ALL
                .iter()
                .flat_map(|&a| {
                    let level = block.level();
                    block.crossings(a).iter().map(move |c| {
                        // Global node coordinates in the block's level units.
                        let n = level.cells() as i64;
                        let g =
                            (origin / 16) * n + I64Vec3::new(c.lower[0] as i64, c.lower[1] as i64, c.lower[2] as i64);
                        (a as u8, g)
                    })
                })
                .collect();
            (key, m, ids)
        })
        .collect();
    let mut out = Mesh::default();
    let mut welded: HashMap<EdgeKey, u32, BuildHasherDefault<KeyHasher>> = HashMap::default();
    for (key, m, ids) in parts {
        let origin = key.origin_grid().as_vec3();
        let remap: Vec<u32> = ids
            .iter()
            .enumerate()
            .map(|(i, id)| {
                *welded.entry(*id).or_insert_with(|| {
                    let p = m.positions[i];
                    out.positions.push([p[0] + origin.x, p[1] + origin.y, p[2] + origin.z]);
                    out.normals.push(m.normals[i]);
                    out.positions.len() as u32 - 1
                })
            })
            .collect();
        out.indices.extend(m.indices.iter().map(|&i| remap[i as usize]));
    }
    out
}
