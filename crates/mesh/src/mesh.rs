//! An indexed triangle mesh.

/// Up to four materials of one vertex and their weights (0..=255, summing to 255), taken only
/// from solid nodes: weights from empty nodes would blend in materials that are not there.
/// Laid out as two `[u8; 4]` (`repr(C)`, `Pod`), so a renderer can borrow a mesh's materials as
/// bytes without copying them.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, bytemuck::Pod, bytemuck::Zeroable)]
pub struct VertexMaterial {
    /// Material ids, heaviest first (unused slots repeat the first id with weight 0).
    pub ids: [u8; 4],
    /// Weights in 255ths, summing to 255.
    pub weights: [u8; 4],
}

impl VertexMaterial {
    /// All of one material.
    pub const fn single(id: u8) -> Self {
        VertexMaterial { ids: [id; 4], weights: [255, 0, 0, 0] }
    }

    /// The blend of the materials of `nodes` (the ids of the solid nodes around a vertex, one
    /// entry per node): the four most frequent, weighted by their share (ties to the lower id).
    pub fn blend(nodes: &[u8]) -> Self {
        let Some(&first) = nodes.first() else { return VertexMaterial::single(0) };
        let mut counts: [(u8, u32); 8] = [(0, 0); 8];
        let mut used = 0;
        for &id in nodes {
            match counts[..used].iter_mut().find(|c| c.0 == id) {
                Some(c) => c.1 += 1,
                None if used < 8 => {
                    counts[used] = (id, 1);
                    used += 1;
                }
                None => {}
            }
        }
        let top = &mut counts[..used];
        top.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let top = &top[..used.min(4)];
        let total: u32 = top.iter().map(|c| c.1).sum();
        let mut out = VertexMaterial { ids: [top.first().map_or(first, |c| c.0); 4], weights: [0; 4] };
        let mut given = 0u32;
        for (k, c) in top.iter().enumerate() {
            out.ids[k] = c.0;
            let w = if k + 1 == top.len() { 255 - given } else { c.1 * 255 / total };
            out.weights[k] = w as u8;
            given += w;
        }
        out
    }

    /// The weight of material `id` in `[0, 1]`.
    pub fn weight_of(&self, id: u8) -> f32 {
        self.ids.iter().zip(self.weights).filter(|(i, _)| **i == id).map(|(_, w)| w as f32).sum::<f32>() / 255.0
    }

    /// The material with the largest weight.
    pub fn dominant(&self) -> u8 {
        self.ids[0]
    }
}

/// Triangles over shared vertices. Positions are in grid units unless a caller scales them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals, one per position.
    pub normals: Vec<[f32; 3]>,
    /// Vertex materials, one per position, or none at all: a mesh of material 0 only (as every
    /// mesh of a volume without materials, or of a dense field) keeps this empty.
    pub materials: Vec<VertexMaterial>,
    /// Three indices per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

impl Mesh {
    /// Empties the mesh, keeping its capacity.
    pub fn clear(&mut self) {
        self.positions.clear();
        self.normals.clear();
        self.materials.clear();
        self.indices.clear();
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The triangles as index triples.
    pub fn triangles(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        self.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]])
    }

    /// The material of vertex `i` (material 0 for a mesh without materials).
    #[inline]
    pub fn material(&self, i: usize) -> VertexMaterial {
        self.materials.get(i).copied().unwrap_or(VertexMaterial::single(0))
    }

    /// The mesh with the vertices that agree bit for bit in position, normal and material merged
    /// into the first of them (`-0.0` taken as `0.0`), the others dropped; triangles keep their
    /// order and orientation. Vertices split only for their normals stay apart.
    pub fn welded(&self) -> Mesh {
        let bits = |v: [f32; 3]| v.map(|c| (c + 0.0).to_bits());
        let mut first: std::collections::HashMap<([u32; 3], [u32; 3], VertexMaterial), u32> =
            std::collections::HashMap::with_capacity(self.positions.len());
        let mut out = Mesh::default();
        let with_materials = !self.materials.is_empty();
        let remap: Vec<u32> = (0..self.positions.len())
            .map(|i| {
                let normal = self.normals.get(i).copied().unwrap_or([0.0, 0.0, 1.0]);
                let key = (bits(self.positions[i]), bits(normal), self.material(i));
                *first.entry(key).or_insert_with(|| {
                    out.push_vertex(self.positions[i], normal, self.material(i), with_materials);
                    out.positions.len() as u32 - 1
                })
            })
            .collect();
        out.indices = self.indices.iter().map(|&i| remap.get(i as usize).copied().unwrap_or(i)).collect();
        out
    }

    /// Appends vertex `i` of `from` (position moved by `offset`), keeping materials aligned;
    /// returns its index here.
    pub fn push_vertex_from(&mut self, from: &Mesh, i: usize, offset: [f32; 3]) -> u32 {
        let p = from.positions[i];
        self.push_vertex(
            [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]],
            from.normals[i],
            from.material(i),
            !from.materials.is_empty(),
        );
        self.positions.len() as u32 - 1
    }

    /// Appends the vertices `vertices` of `from` and its triangles `indices` (which use only
    /// those vertices), keeping materials aligned.
    pub fn append_range(&mut self, from: &Mesh, vertices: std::ops::Range<usize>, indices: std::ops::Range<usize>) {
        let shift = self.positions.len() as i64 - vertices.start as i64;
        if from.materials.is_empty() {
            if !self.materials.is_empty() {
                self.materials.resize(self.positions.len() + vertices.len(), VertexMaterial::single(0));
            }
        } else {
            self.materials.resize(self.positions.len(), VertexMaterial::single(0));
            self.materials.extend_from_slice(&from.materials[vertices.clone()]);
        }
        self.positions.extend_from_slice(&from.positions[vertices.clone()]);
        self.normals.extend_from_slice(&from.normals[vertices]);
        self.indices.extend(from.indices[indices].iter().map(|&i| (i as i64 + shift) as u32));
    }

    /// Appends a vertex. Materials are stored once any vertex has one (`with_material`) or a
    /// material other than 0; earlier vertices are then given material 0.
    pub fn push_vertex(&mut self, position: [f32; 3], normal: [f32; 3], material: VertexMaterial, with_material: bool) {
        if (with_material || material != VertexMaterial::single(0)) && self.materials.len() < self.positions.len() {
            self.materials.resize(self.positions.len(), VertexMaterial::single(0));
        }
        self.positions.push(position);
        self.normals.push(normal);
        if !self.materials.is_empty() || with_material || material != VertexMaterial::single(0) {
            self.materials.push(material);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blends_weigh_by_share_and_sum_to_one() {
        assert_eq!(VertexMaterial::blend(&[3, 3, 3]), VertexMaterial::single(3));
        let b = VertexMaterial::blend(&[1, 2, 2, 5, 2, 1, 7, 9]);
        assert_eq!(b.ids[0], 2);
        assert_eq!(b.weights.iter().map(|&w| w as u32).sum::<u32>(), 255);
        assert!((b.weight_of(2) - 3.0 / 7.0).abs() < 0.02, "{b:?}");
        assert_eq!(b.weight_of(9), 0.0, "the fifth material is dropped");
        let mut m = Mesh::default();
        m.push_vertex([0.0; 3], [0.0, 0.0, 1.0], VertexMaterial::single(0), false);
        assert!(m.materials.is_empty());
        m.push_vertex([1.0; 3], [0.0, 0.0, 1.0], VertexMaterial::single(4), false);
        assert_eq!(m.materials, vec![VertexMaterial::single(0), VertexMaterial::single(4)]);
    }

    #[test]
    fn welding_merges_only_vertices_equal_in_position_normal_and_material() {
        let mut m = Mesh::default();
        let up = [0.0, 0.0, 1.0];
        for (p, n, id) in [
            ([0.0, 0.0, 0.0], up, 0),
            ([1.0, 0.0, 0.0], up, 0),
            ([0.0, 1.0, 0.0], up, 0),
            ([-0.0, 0.0, 0.0], up, 0),             // the first again
            ([1.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0), // another normal
            ([0.0, 1.0, 0.0], up, 3),              // another material
        ] {
            m.push_vertex(p, n, VertexMaterial::single(id), false);
        }
        m.indices = vec![0, 1, 2, 3, 4, 5];
        let w = m.welded();
        assert_eq!(w.vertex_count(), 5);
        assert_eq!(w.indices, vec![0, 1, 2, 0, 3, 4]);
        assert_eq!(w.material(4), VertexMaterial::single(3));
        assert_eq!(w.normals[3], [1.0, 0.0, 0.0]);
        assert_eq!(w.welded(), w, "welding twice changes nothing");
    }
}
