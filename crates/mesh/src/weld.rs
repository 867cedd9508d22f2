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

/// Whether the crossing `key` lies on a face of the chunk grid, so that another chunk's mesh can
/// hold it too; a crossing off every face belongs to the one chunk whose box holds it.
pub(crate) fn on_chunk_face(key: &EdgeKey) -> bool {
    (0..3).any(|i| key.1[i].rem_euclid(KEY_STEPS) == 0)
}

/// One mesh of chunk meshes (chunk-local positions), welding vertices with equal identities
/// (`ids[i]` for vertex `i`; vertices after the ids belong to their chunk alone, and so does a
/// vertex whose identity lies on no chunk face: a chunk's mesh holds each of its crossings once).
pub(crate) fn weld(parts: Vec<(ChunkKey, Mesh, Vec<EdgeKey>)>) -> Mesh {
    weld_traced(&parts).0
}

/// [`weld`], also returning where each welded vertex came from: (part, vertex in the part).
///
/// Only the identities on chunk faces (about a tenth of a fine mesh's) go through the hash map,
/// and the result's arrays are reserved once from the parts' sizes: grown by doubling, a mesh of
/// millions of vertices was copied into fresh pages again and again, which under mimalloc (whose
/// large reallocations copy where glibc's remap) doubled the whole meshing's time.
pub(crate) fn weld_traced(parts: &[(ChunkKey, Mesh, Vec<EdgeKey>)]) -> (Mesh, Vec<(u32, u32)>) {
    let vertices: usize = parts.iter().map(|(_, m, _)| m.positions.len()).sum();
    let shared: usize = parts.iter().map(|(_, _, ids)| ids.iter().filter(|id| on_chunk_face(id)).count()).sum();
    let mut out = Mesh::default();
    out.positions.reserve_exact(vertices);
    out.normals.reserve_exact(vertices);
    if parts.iter().any(|(_, m, _)| !m.materials.is_empty()) {
        out.materials.reserve_exact(vertices);
    }
    out.indices.reserve_exact(parts.iter().map(|(_, m, _)| m.indices.len()).sum());
    let mut source: Vec<(u32, u32)> = Vec::with_capacity(vertices);
    // (Each shared identity is met about twice: half as many entries as meetings, and room to
    // spare.)
    let mut welded: HashMap<EdgeKey, u32, BuildHasherDefault<KeyHasher>> =
        HashMap::with_capacity_and_hasher(shared / 2 + 16, Default::default());
    let mut remap: Vec<u32> = Vec::new();
    for (part, (key, m, ids)) in parts.iter().enumerate() {
        let origin = key.origin_grid().as_vec3().to_array();
        let mut place = |out: &mut Mesh, i: usize| {
            source.push((part as u32, i as u32));
            out.push_vertex_from(m, i, origin)
        };
        remap.clear();
        remap.reserve(m.positions.len());
        for (i, id) in ids.iter().enumerate() {
            let v = if !on_chunk_face(id) {
                place(&mut out, i)
            } else {
                match welded.get(id) {
                    Some(&v) => v,
                    None => {
                        let v = place(&mut out, i);
                        welded.insert(*id, v);
                        v
                    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use proptest::prelude::*;
    use strata_volume::brush::{Cuboid, Sphere};
    use strata_volume::{Level, Volume};

    /// The weld as written before: every identity through the map, the arrays grown as they fill.
    fn weld_every_identity(parts: &[(ChunkKey, Mesh, Vec<EdgeKey>)]) -> (Mesh, Vec<(u32, u32)>) {
        let mut out = Mesh::default();
        let mut source = Vec::new();
        let mut welded: HashMap<EdgeKey, u32> = HashMap::new();
        for (part, (key, m, ids)) in parts.iter().enumerate() {
            let origin = key.origin_grid().as_vec3().to_array();
            let mut remap = Vec::new();
            for i in 0..m.positions.len() {
                let fresh = |out: &mut Mesh, source: &mut Vec<(u32, u32)>| {
                    source.push((part as u32, i as u32));
                    out.push_vertex_from(m, i, origin)
                };
                let v = match ids.get(i) {
                    Some(id) => match welded.get(id) {
                        Some(&v) => v,
                        None => {
                            let v = fresh(&mut out, &mut source);
                            welded.insert(*id, v);
                            v
                        }
                    },
                    None => fresh(&mut out, &mut source),
                };
                remap.push(v);
            }
            out.indices.extend(m.indices.iter().map(|&i| remap[i as usize]));
        }
        (out, source)
    }

    fn assert_same_weld(parts: &[(ChunkKey, Mesh, Vec<EdgeKey>)]) -> Result<(), TestCaseError> {
        let ((new, new_source), (old, old_source)) = (weld_traced(parts), weld_every_identity(parts));
        prop_assert_eq!(&new.positions, &old.positions);
        prop_assert_eq!(&new.normals, &old.normals);
        prop_assert_eq!(&new.materials, &old.materials);
        prop_assert_eq!(&new.indices, &old.indices);
        prop_assert_eq!(new_source, old_source);
        Ok(())
    }

    /// A value on the grid (a node, a half cell) or anywhere, as `snap` picks.
    fn place(x: f64, snap: u8) -> f64 {
        match snap {
            0 => x.round(),
            1 => x.round() + 0.5,
            _ => x,
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// The weld that sends only identities on chunk faces through its map makes the mesh the
        /// map of every identity makes, vertex for vertex: marching cubes of random unions and
        /// differences (sizes and centres on nodes, on half cells or anywhere, so faces fall on
        /// chunk planes), stored at one level or with chunks raised and lowered, meshed whole or
        /// with levels capped; and the marching tetrahedra parts, clustered or not.
        #[test]
        fn welding_through_the_map_only_on_chunk_faces_changes_nothing(
            shapes in proptest::collection::vec(
                (0u8..3, -20.0f64..36.0, -20.0f64..36.0, -20.0f64..36.0, 1.0f64..14.0, 0u8..3), 1..5),
            relevel in proptest::collection::vec((-2i32..3, -2i32..3, -2i32..3, -1i8..3), 0..4),
        ) {
            let mut v = Volume::new();
            for (i, &(kind, x, y, z, r, snap)) in shapes.iter().enumerate() {
                let c = DVec3::new(place(x, snap), place(y, snap), place(z, snap));
                let r = place(r, snap).max(1.0);
                let op = if i > 0 && i % 3 == 2 { strata_volume::CsgOp::Subtract } else { strata_volume::CsgOp::Add };
                let settings = strata_volume::EditSettings::default();
                let _ = match kind {
                    0 => v.apply(op, &Sphere::new(c, r).unwrap(), &settings),
                    _ => v.apply(op, &Cuboid::new(c, DVec3::new(r, r * 0.7, r * 1.3)).unwrap(), &settings),
                };
            }
            assert_same_weld(&crate::marching::chunk_parts(&v, None))?;
            for cluster in [false, true] {
                let parts: Vec<_> = crate::tetra::chunk_parts(&v, cluster).into_iter().map(|(p, _)| p).collect();
                assert_same_weld(&parts)?;
            }
            let cap = |k: ChunkKey| if (k.0.x + k.0.y + k.0.z).rem_euclid(2) == 0 { Level::BASE } else { Level::FINEST };
            assert_same_weld(&crate::marching::chunk_parts(&v, Some(&cap)))?;
            for &(x, y, z, l) in &relevel {
                v.set_chunk_level(ChunkKey::new(x, y, z), Level::new(l).unwrap());
            }
            assert_same_weld(&crate::marching::chunk_parts(&v, None))?;
        }
    }
}
