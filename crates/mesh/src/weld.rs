//! Welding chunk meshes into one: vertices that stand for the same crossing of the volume (the
//! same [`EdgeKey`]) become one vertex, placed from chunk-local into absolute grid positions.
//! Marching cubes and marching tetrahedra both weld here.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::I64Vec3;
use strata_volume::{ChunkKey, KeyHasher};

use crate::Mesh;

/// A crossing's identity in the whole volume (see `marching::vertex_key`).
pub(crate) type EdgeKey = (u8, I64Vec3);

/// Fixed-point steps per chunk side in an [`EdgeKey`]'s position.
pub(crate) const KEY_STEPS: i64 = 65536;

/// One mesh of chunk meshes (chunk-local positions), welding vertices with equal identities
/// (`ids[i]` for vertex `i`; vertices after the ids belong to their chunk alone).
pub(crate) fn weld(parts: Vec<(ChunkKey, Mesh, Vec<EdgeKey>)>) -> Mesh {
    weld_traced(&parts).0
}

/// [`weld`], also returning where each welded vertex came from: (part, vertex in the part).
pub(crate) fn weld_traced(parts: &[(ChunkKey, Mesh, Vec<EdgeKey>)]) -> (Mesh, Vec<(u32, u32)>) {
    let mut out = Mesh::default();
    let mut source: Vec<(u32, u32)> = Vec::new();
    let mut welded: HashMap<EdgeKey, u32, BuildHasherDefault<KeyHasher>> = HashMap::default();
    for (part, (key, m, ids)) in parts.iter().enumerate() {
        let origin = key.origin_grid().as_vec3().to_array();
        let mut place = |out: &mut Mesh, i: usize| {
            source.push((part as u32, i as u32));
            out.push_vertex_from(m, i, origin)
        };
        let mut remap: Vec<u32> = Vec::with_capacity(m.positions.len());
        for (i, id) in ids.iter().enumerate() {
            let v = match welded.get(id) {
                Some(&v) => v,
                None => {
                    let v = place(&mut out, i);
                    welded.insert(*id, v);
                    v
                }
            };
            remap.push(v);
        }
        // Centroids of split seam triangles belong to this chunk alone.
        for i in ids.len()..m.positions.len() {
            remap.push(place(&mut out, i));
        }
        out.indices.extend(m.indices.iter().map(|&i| remap[i as usize]));
    }
    (out, source)
}
