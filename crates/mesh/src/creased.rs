//! A whole volume's marching-cubes mesh with creased shading normals, made chunk by chunk:
//! what `strata export` writes, without holding every chunk's mesh, a hash map of every vertex
//! and a second whole mesh at once (the bunny at 1,024 cells peaked at 1.1 GiB that way).
//!
//! A vertex strictly inside a chunk's box belongs to that chunk's triangles alone, so its
//! crease groups ([`crate::normals::crease_normals`]) are settled while the chunk is meshed;
//! only the vertices on chunk faces (about a tenth) wait, with their faces, until every chunk
//! around them has been meshed. The result equals [`crate::normals::crease_normals`] of the
//! welded mesh (`mesh_volume`) up to the order of vertices and triangles.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::Vec3;
use rayon::prelude::*;
use strata_volume::{ChunkKey, KeyHasher, Volume, VoxelBlock};

use crate::Mesh;
use crate::marching::{block_vertex_keys, mesh_block, surface_chunks};
use crate::mesh::VertexMaterial;
use crate::normals::{Creaser, Face, rows_by};
use crate::weld::{EdgeKey, on_chunk_face};

/// Chunks meshed together before their parts are joined: enough to keep both cores busy, few
/// enough that their meshes stay a small share of the whole.
const BATCH: usize = 512;

/// A vertex on a chunk face, as one chunk saw it: its faces are `faces[start..end]` of its part.
struct Border {
    key: EdgeKey,
    position: [f32; 3],
    material: VertexMaterial,
    faces: std::ops::Range<u32>,
}

/// One chunk's share: its own vertices with their final normals, its triangles (corners at
/// border vertices are filled in when those are settled), and its border vertices with the
/// (area-weighted face normal, corner in the chunk's indices) of the chunk's faces around them.
struct Part {
    mesh: Mesh,
    border: Vec<Border>,
    faces: Vec<(Vec3, u32)>,
}

/// What one worker reuses from chunk to chunk.
struct Scratch {
    block: VoxelBlock,
    mesh: Mesh,
    creaser: Creaser,
    /// Each triangle's area-weighted normal (and its length and direction).
    face: Vec<Face>,
    /// The corners around each vertex: `corners[start[v]..start[v + 1]]`, in triangle order.
    start: Vec<u32>,
    corners: Vec<u32>,
}

fn part(volume: &Volume, key: ChunkKey, s: &mut Scratch) -> Option<Part> {
    if volume.plain_block_uniform(key) {
        // The chunk and its apron's owners are uniform alike: no surface, nothing to read (most
        // of the chunks around a converted mesh are inside it or outside it).
        return None;
    }
    volume.extract_block_into(key, &mut s.block);
    let m = &mut s.mesh;
    mesh_block(&s.block, m);
    if m.indices.is_empty() {
        return None;
    }
    let ids = block_vertex_keys(&s.block);
    let origin = key.origin_grid().as_vec3().to_array();
    // Absolute positions, as the weld places them.
    for p in &mut m.positions {
        *p = [p[0] + origin[0], p[1] + origin[1], p[2] + origin[2]];
    }
    s.face.clear();
    s.face.extend(m.indices.chunks_exact(3).map(|t| {
        let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(m.positions[t[k] as usize]));
        Face::new((b - a).cross(c - a))
    }));
    let nv = m.positions.len();
    rows_by(&m.indices, nv, &mut s.start, &mut s.corners);
    let mut out = Part { mesh: Mesh::default(), border: Vec::new(), faces: Vec::new() };
    let mut indices = vec![0u32; m.indices.len()];
    let with_materials = !m.materials.is_empty();
    for v in 0..nv {
        let around = &s.corners[s.start[v] as usize..s.start[v + 1] as usize];
        if around.is_empty() {
            continue;
        }
        // Centroids of split seam triangles (after the ids) belong to this chunk alone.
        if let Some(id) = ids.get(v).filter(|id| on_chunk_face(id)) {
            let first = out.faces.len() as u32;
            out.faces.extend(around.iter().map(|&c| (s.face[c as usize / 3].normal, c)));
            out.border.push(Border {
                key: *id,
                position: m.positions[v],
                material: m.material(v),
                faces: first..out.faces.len() as u32,
            });
            continue;
        }
        s.creaser.clear();
        for &c in around {
            s.creaser.push(s.face[c as usize / 3], c);
        }
        s.creaser.split_into(&mut out.mesh, &mut indices, m.positions[v], m.material(v), with_materials);
    }
    out.mesh.indices = indices;
    Some(out)
}

/// The parts of `batch`, in its order, meshed on every core.
fn parts(volume: &Volume, batch: &[ChunkKey], crease_degrees: f32) -> Vec<Option<Part>> {
    batch
        .par_iter()
        .map_init(
            || Scratch {
                block: VoxelBlock::default(),
                mesh: Mesh::default(),
                creaser: Creaser::new(crease_degrees),
                face: Vec::new(),
                start: Vec::new(),
                corners: Vec::new(),
            },
            |s, &key| part(volume, key, s),
        )
        .collect()
}

/// The vertices on chunk faces met so far, and the faces around them in mesh order.
#[derive(Default)]
struct Borders {
    slot: HashMap<EdgeKey, u32, BuildHasherDefault<KeyHasher>>,
    /// First position and material of each.
    vertex: Vec<([f32; 3], VertexMaterial)>,
    /// The vertex of each face around one, and the face: (area-weighted normal, corner in the
    /// whole mesh's indices).
    face_vertex: Vec<u32>,
    faces: Vec<(Vec3, u32)>,
}

/// Appends `parts` to `out`.
fn join(out: &mut Mesh, borders: &mut Borders, parts: Vec<Option<Part>>) {
    for p in parts.into_iter().flatten() {
        let corner0 = out.indices.len() as u32;
        let (nv, ni) = (p.mesh.positions.len(), p.mesh.indices.len());
        out.append_range(&p.mesh, 0..nv, 0..ni);
        for b in &p.border {
            let slot = *borders.slot.entry(b.key).or_insert_with(|| {
                borders.vertex.push((b.position, b.material));
                borders.vertex.len() as u32 - 1
            });
            let faces = &p.faces[b.faces.start as usize..b.faces.end as usize];
            borders.face_vertex.extend(std::iter::repeat_n(slot, faces.len()));
            borders.faces.extend(faces.iter().map(|&(f, c)| (f, c + corner0)));
        }
    }
}

/// The marching-cubes mesh of `volume` (grid units, absolute, welded as `mesh_volume` welds)
/// with shading normals creased at `crease_degrees` as [`crate::normals::crease_normals`]
/// creases them, made in batches of chunks on every core (a batch is joined to the mesh while
/// the next one is meshed).
pub fn mesh_volume_creased(volume: &Volume, crease_degrees: f32) -> Mesh {
    let keys = surface_chunks(volume);
    let mut out = Mesh::default();
    // About one vertex a crossing and two triangles a vertex: reserved once, not regrown.
    let crossings: usize = volume
        .chunks()
        .map(|(_, c)| match c {
            strata_volume::Chunk::Lists(l) => l.crossing_count(),
            strata_volume::Chunk::Solid => 0,
        })
        .sum();
    out.positions.reserve(crossings + crossings / 16);
    out.normals.reserve(crossings + crossings / 16);
    out.indices.reserve(6 * crossings + 64);
    let mut borders = Borders::default();
    let mut joining: Vec<Option<Part>> = Vec::new();
    for batch in keys.chunks(BATCH) {
        let (next, ()) = rayon::join(
            || parts(volume, batch, crease_degrees),
            || join(&mut out, &mut borders, std::mem::take(&mut joining)),
        );
        joining = next;
    }
    join(&mut out, &mut borders, joining);
    let Borders { slot, vertex, face_vertex, faces } = borders;
    drop(slot);
    // The faces around each border vertex, in mesh order.
    let (mut start, mut order) = (Vec::new(), Vec::new());
    rows_by(&face_vertex, vertex.len(), &mut start, &mut order);
    drop(face_vertex);
    let with_materials = !out.materials.is_empty();
    // Runs of border vertices creased on every core, each into a mesh of its own with the
    // corners it moved; joined in order, they add the vertices the loop over all of them adds.
    let runs: Vec<(Mesh, Vec<(u32, u32)>)> = (0..vertex.len())
        .into_par_iter()
        .with_min_len(BORDER_RUN)
        .fold(
            || (Creaser::new(crease_degrees), Mesh::default(), Vec::new()),
            |(mut creaser, mut mesh, mut corners), v| {
                let (position, material) = vertex[v];
                creaser.clear();
                for &i in &order[start[v] as usize..start[v + 1] as usize] {
                    let (f, c) = faces[i as usize];
                    creaser.push(Face::new(f), c);
                }
                creaser.split_with(&mut mesh, position, material, with_materials, |c, i| corners.push((c, i)));
                (creaser, mesh, corners)
            },
        )
        .map(|(_, mesh, corners)| (mesh, corners))
        .collect();
    let mut indices = std::mem::take(&mut out.indices);
    for (mesh, corners) in runs {
        let first = out.positions.len() as u32;
        out.append_range(&mesh, 0..mesh.positions.len(), 0..0);
        for (c, i) in corners {
            indices[c as usize] = first + i;
        }
    }
    out.indices = indices;
    out
}

/// Border vertices creased together on one core at least.
const BORDER_RUN: usize = 1 << 12;
