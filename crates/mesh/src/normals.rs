//! Shading normals: area-weighted averages of face normals, split at creases.

use glam::Vec3;

use crate::Mesh;
use crate::mesh::VertexMaterial;

/// The paper's crease angle: faces meeting at less than this are smoothed together.
pub const DEFAULT_CREASE_DEGREES: f32 = 30.0;

/// Triangles with less than this share of the largest incident triangle's area never start a
/// crease group of their own. 0.05 cuts spurious splits on a marching-cubes sphere of radius 10
/// from 370 to 18 (of 1,902 vertices) while box edges from dual contouring still split.
const SLIVER_AREA_RATIO: f32 = 0.05;

/// A render mesh with normals recomputed from the faces: at each vertex, the incident triangles
/// are grouped so that every triangle's face normal is within `crease_degrees` of its group's
/// running mean (seeded by the largest triangles first); each group gets its own copy of the
/// vertex with the area-weighted mean normal of its triangles. Smooth surfaces keep shared
/// vertices; sharp edges and corners (box edges from dual contouring) shade sharply.
///
/// The result is for shading: split vertices make it non-manifold by index, so run mesh checks
/// on the mesh before this step.
pub fn crease_normals(mesh: &Mesh, crease_degrees: f32) -> Mesh {
    // Area-weighted face normals (the cross product's length is twice the area).
    let face: Vec<Face> = mesh
        .triangles()
        .map(|t| {
            let [a, b, c] = t.map(|i| Vec3::from(mesh.positions[i as usize]));
            Face::new((b - a).cross(c - a))
        })
        .collect();
    let (mut start, mut corners) = (Vec::new(), Vec::new());
    // (Whole triangles only: a malformed tail of indices is left at vertex 0, as before.)
    rows_by(&mesh.indices[..3 * face.len()], mesh.positions.len(), &mut start, &mut corners);
    let mut out = Mesh::default();
    let mut indices = vec![0; mesh.indices.len()];
    let with_materials = !mesh.materials.is_empty();
    let mut creaser = Creaser::new(crease_degrees);
    for v in 0..mesh.positions.len() {
        creaser.clear();
        for &c in &corners[start[v] as usize..start[v + 1] as usize] {
            creaser.push(face[c as usize / 3], c);
        }
        creaser.split_into(&mut out, &mut indices, mesh.positions[v], mesh.material(v), with_materials);
    }
    out.indices = indices;
    out
}

/// The positions `0..keys.len()` grouped by their key (a stable counting sort):
/// `order[start[k]..start[k + 1]]` are the positions of key `k`, in increasing order (compressed
/// rows: one flat list, no list a key). With a mesh's indices as keys, the corners around each
/// vertex in triangle order.
pub(crate) fn rows_by(keys: &[u32], rows: usize, start: &mut Vec<u32>, order: &mut Vec<u32>) {
    start.clear();
    start.resize(rows + 1, 0);
    for &k in keys {
        start[k as usize + 1] += 1;
    }
    for k in 0..rows {
        start[k + 1] += start[k];
    }
    order.clear();
    order.resize(keys.len(), 0);
    // `start[k]` moves to the end of `k`'s run as it is filled, then every entry shifts back.
    for (i, &k) in keys.iter().enumerate() {
        order[start[k as usize] as usize] = i as u32;
        start[k as usize] += 1;
    }
    start.copy_within(0..rows, 1);
    start[0] = 0;
}

/// A triangle as the grouping reads it: its area-weighted normal, that normal's length (twice
/// the area) and its direction (zero for a triangle without area), found once per triangle
/// rather than once per corner.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Face {
    length: f32,
    pub(crate) normal: Vec3,
    dir: Vec3,
}

impl Face {
    /// The face of area-weighted normal `normal`.
    #[inline]
    pub(crate) fn new(normal: Vec3) -> Self {
        Face { length: normal.length(), normal, dir: normal.normalize_or_zero() }
    }
}

/// The grouping of [`crease_normals`] around one vertex, shared with the streamed export
/// ([`crate::creased`]): faces are pushed in mesh order, then [`Creaser::split`] groups them.
pub(crate) struct Creaser {
    cos_limit: f32,
    /// Each face around the vertex, and its corner that names the vertex.
    around: Vec<(Face, u32)>,
    /// (normal sum, its direction, vertex index) of each group.
    groups: Vec<(Vec3, Vec3, u32)>,
}

impl Creaser {
    pub(crate) fn new(crease_degrees: f32) -> Self {
        Creaser { cos_limit: crease_degrees.to_radians().cos(), around: Vec::new(), groups: Vec::new() }
    }

    /// Starts the next vertex.
    pub(crate) fn clear(&mut self) {
        self.around.clear();
    }

    /// One face around the vertex and the corner that names the vertex (faces come in mesh
    /// order).
    #[inline]
    pub(crate) fn push(&mut self, face: Face, corner: u32) {
        self.around.push((face, corner));
    }

    /// Groups the faces pushed since [`Creaser::clear`]: largest first (ties in mesh order), a
    /// face joins the first group whose running mean is within the crease angle, a sliver the
    /// closest group, any other face starts a group. `vertex(normal)` adds a group's vertex
    /// (its normal is set once the group is complete, so it is given `[0, 0, 0]` first and the
    /// final unit normal through `normal` afterwards) and returns its index; `corner(c, i)`
    /// points corner `c` at vertex `i`.
    fn split(&mut self, mut vertex: impl FnMut([f32; 3]) -> u32, mut corner: impl FnMut(u32, u32)) {
        self.around.sort_by(|a, b| b.0.length.total_cmp(&a.0.length));
        self.groups.clear();
        let largest = self.around.first().map_or(0.0, |a| a.0.length);
        for &(Face { length, normal: f, dir }, c) in &self.around {
            let closeness = |g: &(Vec3, Vec3, u32)| g.1.dot(dir);
            let mut slot = self.groups.iter().position(|g| closeness(g) >= self.cos_limit);
            // Slivers (marching cubes makes some next to nodes) have unreliable normals: they
            // join the closest group instead of starting a crease.
            if slot.is_none() && length < SLIVER_AREA_RATIO * largest {
                slot = (0..self.groups.len())
                    .max_by(|&a, &b| closeness(&self.groups[a]).total_cmp(&closeness(&self.groups[b])));
            }
            let index = match slot {
                Some(g) => {
                    let group = &mut self.groups[g];
                    group.0 += f;
                    group.1 = group.0.normalize_or_zero();
                    group.2
                }
                None => {
                    let index = vertex([0.0; 3]);
                    self.groups.push((f, dir, index));
                    index
                }
            };
            corner(c, index);
        }
    }

    /// [`Creaser::split`] into `out`: each group's copy of the vertex pushed at `position` with
    /// `material` and given its group's unit normal, and the corners of `indices` pointed at
    /// their copies.
    pub(crate) fn split_into(
        &mut self,
        out: &mut Mesh,
        indices: &mut [u32],
        position: [f32; 3],
        material: VertexMaterial,
        with_materials: bool,
    ) {
        self.split_with(out, position, material, with_materials, |c, i| indices[c as usize] = i);
    }

    /// [`Creaser::split_into`] with each corner's new vertex given to `corner(c, i)`.
    pub(crate) fn split_with(
        &mut self,
        out: &mut Mesh,
        position: [f32; 3],
        material: VertexMaterial,
        with_materials: bool,
        corner: impl FnMut(u32, u32),
    ) {
        self.split(
            |normal| {
                out.push_vertex(position, normal, material, with_materials);
                out.positions.len() as u32 - 1
            },
            corner,
        );
        for (normal, i) in self.normals() {
            out.normals[i as usize] = normal;
        }
    }

    /// The groups of the last [`Creaser::split`]: (unit normal, vertex index).
    fn normals(&self) -> impl Iterator<Item = ([f32; 3], u32)> + '_ {
        self.groups.iter().map(|&(sum, _, index)| (sum.normalize_or(Vec3::Z).to_array(), index))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks;
    use crate::marching::mesh_volume;

    fn dual_contour_volume(v: &strata_volume::Volume) -> crate::Mesh {
        crate::DualCache::build(v).welded()
    }
    use glam::DVec3;
    use strata_volume::Volume;
    use strata_volume::brush::{Cuboid, Sphere};

    #[test]
    fn box_corners_split_into_three_normals_and_spheres_stay_smooth() {
        let mut v = Volume::new();
        v.add(&Cuboid::new(DVec3::new(8.37, 7.71, 8.29), DVec3::new(5.21, 4.63, 6.11)).unwrap()).unwrap();
        let dc = dual_contour_volume(&v);
        let shaded = crease_normals(&dc, DEFAULT_CREASE_DEGREES);
        assert_eq!(shaded.triangle_count(), dc.triangle_count());
        // Every shading normal of a box is (close to) an axis.
        for n in &shaded.normals {
            let m = Vec3::from(*n).abs().max_element();
            assert!(m > 0.99, "normal {n:?} is not axis-aligned");
        }
        // Each of the 8 corners is split into three copies and each of the 12 edges into two.
        assert!(shaded.vertex_count() >= dc.vertex_count() + 8 * 2);

        let mut s = Volume::new();
        s.add(&Sphere::new(DVec3::new(8.0, 8.0, 8.0), 10.0).unwrap()).unwrap();
        let mc = mesh_volume(&s);
        let shaded = crease_normals(&mc, DEFAULT_CREASE_DEGREES);
        // Marching cubes makes a few badly shaped triangles next to nodes; they may still split
        // a vertex here and there, but the shading follows the sphere.
        let splits = shaded.vertex_count() - mc.vertex_count();
        assert!(splits * 50 < mc.vertex_count(), "{splits} splits on a smooth sphere");
        let mut mean = 0.0;
        for (p, n) in shaded.positions.iter().zip(&shaded.normals) {
            let radial = (Vec3::from(*p) - Vec3::splat(8.0)).normalize();
            mean += radial.dot(Vec3::from(*n)).clamp(-1.0, 1.0).acos().to_degrees() / shaded.vertex_count() as f32;
        }
        assert!(mean < 5.0, "mean shading error {mean} degrees");
        assert!((checks::signed_volume(&shaded) - checks::signed_volume(&mc)).abs() < 1e-6);
    }
    /// The grouping as it was written before the compressed rows and the shared [`Creaser`]:
    /// one list of faces a vertex, sorted by recomputed areas.
    fn crease_by_lists(mesh: &Mesh, crease_degrees: f32) -> Mesh {
        let cos_limit = crease_degrees.to_radians().cos();
        let tris: Vec<[u32; 3]> = mesh.triangles().collect();
        let face: Vec<Vec3> = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| Vec3::from(mesh.positions[i as usize]));
                (b - a).cross(c - a)
            })
            .collect();
        let mut incident: Vec<Vec<(u32, u8)>> = vec![Vec::new(); mesh.positions.len()];
        for (ti, t) in tris.iter().enumerate() {
            for (k, &v) in t.iter().enumerate() {
                incident[v as usize].push((ti as u32, k as u8));
            }
        }
        let mut out = Mesh { indices: vec![0; mesh.indices.len()], ..Default::default() };
        for (v, list) in incident.iter_mut().enumerate() {
            list.sort_by(|a, b| face[b.0 as usize].length().total_cmp(&face[a.0 as usize].length()));
            let mut groups: Vec<(Vec3, u32)> = Vec::new();
            let largest = list.first().map_or(0.0, |&(ti, _)| face[ti as usize].length());
            for &(ti, k) in list.iter() {
                let f = face[ti as usize];
                let dir = f.normalize_or_zero();
                let closeness = |g: &(Vec3, u32)| g.0.normalize_or_zero().dot(dir);
                let mut slot = groups.iter().position(|g| closeness(g) >= cos_limit);
                if slot.is_none() && f.length() < SLIVER_AREA_RATIO * largest {
                    slot = (0..groups.len()).max_by(|&a, &b| closeness(&groups[a]).total_cmp(&closeness(&groups[b])));
                }
                let index = match slot {
                    Some(g) => {
                        groups[g].0 += f;
                        groups[g].1
                    }
                    None => {
                        let index = out.positions.len() as u32;
                        out.push_vertex(mesh.positions[v], [0.0; 3], mesh.material(v), !mesh.materials.is_empty());
                        groups.push((f, index));
                        index
                    }
                };
                out.indices[ti as usize * 3 + k as usize] = index;
            }
            for (sum, index) in groups {
                out.normals[index as usize] = sum.normalize_or(Vec3::Z).to_array();
            }
        }
        out
    }

    #[test]
    fn the_grouping_is_the_one_written_before_bit_for_bit() {
        use strata_volume::brush::Torus;
        let mut v = Volume::new();
        v.add(&Cuboid::new(DVec3::new(8.37, 7.71, 8.29), DVec3::new(5.21, 4.63, 6.11)).unwrap()).unwrap();
        v.add(&Cuboid::new(DVec3::new(20.0, 16.0, 8.0), DVec3::new(4.0, 4.0, 4.0)).unwrap()).unwrap();
        v.add(&Torus::new(DVec3::new(-6.0, 3.0, 2.0), DVec3::new(0.3, 1.0, 0.2), 7.0, 2.5).unwrap()).unwrap();
        v.subtract(&Sphere::new(DVec3::new(10.0, 9.0, 12.0), 4.5).unwrap()).unwrap();
        for mesh in [mesh_volume(&v), dual_contour_volume(&v)] {
            for degrees in [0.0, 10.0, DEFAULT_CREASE_DEGREES, 75.0, 180.0] {
                let (new, old) = (crease_normals(&mesh, degrees), crease_by_lists(&mesh, degrees));
                assert_eq!(new.indices, old.indices, "{degrees}");
                assert_eq!(new.positions, old.positions, "{degrees}");
                assert_eq!(new.normals, old.normals, "{degrees}");
                assert_eq!(new.materials, old.materials, "{degrees}");
            }
        }
    }

    #[test]
    fn a_tail_of_indices_short_of_a_triangle_is_not_a_panic() {
        let mut m = Mesh::default();
        for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            m.push_vertex(p, [0.0, 0.0, 1.0], crate::mesh::VertexMaterial::single(0), false);
        }
        m.indices = vec![0, 1, 2, 1];
        let out = crease_normals(&m, DEFAULT_CREASE_DEGREES);
        assert_eq!(out.vertex_count(), 3);
        assert_eq!(out.indices.len(), 4);
    }
}
