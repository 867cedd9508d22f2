//! Mesh inserts: a closed mesh (a primitive made in code, the bunny, any file the importer
//! reads) placed, turned and scaled in the world and added to, subtracted from or intersected
//! with a layer exactly, by the core's mesh brush ([`strata_volume::brush::MeshBrush`]) under
//! the placement. [`InsertMesh::preview`] is what the viewport draws before it is applied.

use std::sync::Arc;

use glam::{DQuat, DVec3};
use strata_mesh::import::TriangleMesh;
use strata_volume::CsgOp;
use strata_volume::brush::{MeshBrush, MeshRule, Transformed};
use thiserror::Error;

use crate::editor::{Editor, EditorError};
use crate::scene::LayerTransform;

/// Why a mesh cannot be inserted.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum InsertError {
    /// The mesh has a hole (an edge not shared by exactly two triangles): its inside is not
    /// defined, so it could not be added exactly.
    #[error("{0} is not closed (it has holes): only a closed mesh can be inserted")]
    Open(String),
    /// No triangles with area, NaN coordinates, or bad indices.
    #[error("{name} cannot be a brush: {reason}")]
    Bad {
        /// The mesh.
        name: String,
        /// Why.
        reason: String,
    },
    /// A placement with a NaN or infinite position or turn, or a size that is not finite and
    /// positive.
    #[error("the insert's placement must be finite, with a positive size")]
    Placement,
}

/// The shapes made in code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Primitive {
    /// A cube.
    Cube,
    /// A ball (a subdivided icosahedron).
    Ball,
    /// A cylinder along y, as tall as it is wide.
    Cylinder,
    /// A torus around y, its tube a third of its radius.
    Torus,
}

impl Primitive {
    /// Every primitive, in the menu's order.
    pub const ALL: [Primitive; 4] = [Primitive::Cube, Primitive::Ball, Primitive::Cylinder, Primitive::Torus];

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Primitive::Cube => "Cube",
            Primitive::Ball => "Ball",
            Primitive::Cylinder => "Cylinder",
            Primitive::Torus => "Torus",
        }
    }

    /// Its closed triangle mesh, outward-facing, about 2 units across.
    pub fn mesh(self) -> TriangleMesh {
        match self {
            Primitive::Cube => {
                let v: Vec<DVec3> = (0..8)
                    .map(|i| {
                        DVec3::new(
                            (i & 1) as f64 * 2.0 - 1.0,
                            ((i >> 1) & 1) as f64 * 2.0 - 1.0,
                            (i >> 2) as f64 * 2.0 - 1.0,
                        )
                    })
                    .collect();
                let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
                let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
                TriangleMesh { vertices: v, triangles }
            }
            Primitive::Ball => icosphere(3),
            Primitive::Cylinder => revolve(&[(0.0, -1.0), (1.0, -1.0), (1.0, 1.0), (0.0, 1.0)], 48),
            Primitive::Torus => {
                let ring: Vec<(f64, f64)> = (0..24)
                    .map(|k| {
                        let a = k as f64 * std::f64::consts::TAU / 24.0;
                        (0.75 + 0.25 * a.cos(), 0.25 * a.sin())
                    })
                    .collect();
                revolve_closed(&ring, 48)
            }
        }
    }
}

/// A unit icosahedron subdivided `levels` times, its vertices on the unit sphere.
fn icosphere(levels: u32) -> TriangleMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let mut m = |i: u32, j: u32| {
                *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    v.push(((v[i as usize] + v[j as usize]) * 0.5).normalize());
                    v.len() as u32 - 1
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    TriangleMesh { vertices: v, triangles: f }
}

/// The surface of revolution about y of an open profile `(radius, y)` from the axis back to the
/// axis (the first and last points at radius 0), in `segments` steps.
fn revolve(profile: &[(f64, f64)], segments: u32) -> TriangleMesh {
    let mut vertices = vec![DVec3::new(0.0, profile[0].1, 0.0)];
    let inner = &profile[1..profile.len() - 1];
    for s in 0..segments {
        let a = s as f64 * std::f64::consts::TAU / segments as f64;
        for &(r, y) in inner {
            vertices.push(DVec3::new(r * a.cos(), y, -r * a.sin()));
        }
    }
    let top = vertices.len() as u32;
    vertices.push(DVec3::new(0.0, profile[profile.len() - 1].1, 0.0));
    let n = inner.len() as u32;
    let at = |s: u32, k: u32| 1 + (s % segments) * n + k;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, at(s, 0), at(s + 1, 0)]);
        for k in 0..n - 1 {
            triangles.push([at(s, k), at(s, k + 1), at(s + 1, k + 1)]);
            triangles.push([at(s, k), at(s + 1, k + 1), at(s + 1, k)]);
        }
        triangles.push([top, at(s + 1, n - 1), at(s, n - 1)]);
    }
    TriangleMesh { vertices, triangles }
}

/// The surface of revolution about y of a closed profile loop (counter-clockwise in the
/// `(radius, y)` plane), in `segments` steps.
fn revolve_closed(profile: &[(f64, f64)], segments: u32) -> TriangleMesh {
    let n = profile.len() as u32;
    let mut vertices = Vec::new();
    for s in 0..segments {
        let a = s as f64 * std::f64::consts::TAU / segments as f64;
        for &(r, y) in profile {
            vertices.push(DVec3::new(r * a.cos(), y, -r * a.sin()));
        }
    }
    let at = |s: u32, k: u32| (s % segments) * n + (k % n);
    let mut triangles = Vec::new();
    for s in 0..segments {
        for k in 0..n {
            triangles.push([at(s, k), at(s, k + 1), at(s + 1, k + 1)]);
            triangles.push([at(s, k), at(s + 1, k + 1), at(s + 1, k)]);
        }
    }
    TriangleMesh { vertices, triangles }
}

/// `mesh` with bitwise-equal positions merged and unused vertices dropped; `Err(t)` for a
/// triangle `t` with an index out of range.
fn weld(mesh: &TriangleMesh) -> Result<TriangleMesh, usize> {
    let mut index: std::collections::HashMap<[u64; 3], u32> = std::collections::HashMap::new();
    let mut vertices = Vec::new();
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let mut out = [0u32; 3];
        for (o, &i) in out.iter_mut().zip(tri) {
            let v = *mesh.vertices.get(i as usize).ok_or(t)?;
            // (+0.0 and −0.0 are one position.)
            let key = (v + DVec3::ZERO).to_array().map(f64::to_bits);
            *o = *index.entry(key).or_insert_with(|| {
                vertices.push(v);
                vertices.len() as u32 - 1
            });
        }
        triangles.push(out);
    }
    Ok(TriangleMesh { vertices, triangles })
}

/// A closed mesh ready to insert: its brush (built once), its box's centre and largest side
/// (its own units), and its preview.
#[derive(Clone, Debug)]
pub struct InsertMesh {
    name: String,
    brush: Arc<MeshBrush>,
    centre: DVec3,
    size: f64,
    preview: Arc<strata_mesh::Mesh>,
}

/// Where an insert goes (world units): its box's centre at `position`, turned by `rotation`,
/// scaled so that its largest side is `size`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The middle of the mesh's box.
    pub position: DVec3,
    /// Its turn.
    pub rotation: DQuat,
    /// Its largest side.
    pub size: f64,
}

impl Placement {
    fn is_valid(&self) -> bool {
        self.position.is_finite()
            && self.rotation.is_finite()
            && self.rotation.length() > 1e-9
            && self.size.is_finite()
            && self.size > 0.0
    }
}

impl InsertMesh {
    /// `mesh` named `name`, checked: closed, with triangles of area, finite. Vertices at the
    /// same position are welded first (OBJ and glTF files repeat a position wherever its normal
    /// or texture coordinates change), and vertices no triangle uses are left out.
    pub fn new(name: &str, mesh: &TriangleMesh) -> Result<Self, InsertError> {
        let bad = |reason: String| InsertError::Bad { name: name.to_string(), reason };
        let mesh = &weld(mesh).map_err(|i| bad(format!("triangle {i} names a vertex the mesh does not have")))?;
        let brush =
            MeshBrush::new(&mesh.vertices, &mesh.triangles, MeshRule::default()).map_err(|e| bad(e.to_string()))?;
        if !brush.is_closed() {
            return Err(InsertError::Open(name.to_string()));
        }
        let (lo, hi) = mesh.bounds().ok_or_else(|| bad("no vertices".into()))?;
        let size = (hi - lo).max_element();
        if !(size.is_finite() && size > 0.0) {
            return Err(bad("it is flat".into()));
        }
        let centre = (lo + hi) * 0.5;
        // The preview: the mesh in its own units around its centre, flat-shaded enough to read.
        let mut preview = strata_mesh::Mesh::default();
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize] - centre);
            let n = (b - a).cross(c - a).normalize_or_zero().as_vec3().to_array();
            for p in [a, b, c] {
                preview.positions.push(p.as_vec3().to_array());
                preview.normals.push(n);
            }
            let k = preview.indices.len() as u32;
            preview.indices.extend([k, k + 1, k + 2]);
        }
        Ok(InsertMesh { name: name.to_string(), brush: Arc::new(brush), centre, size, preview: Arc::new(preview) })
    }

    /// The Stanford bunny (tests/data/bunny.ply, built into the program: see its README for
    /// the source and credit).
    pub fn bunny() -> Self {
        let mesh = strata_mesh::import::parse_mesh("ply", include_bytes!("../../../tests/data/bunny.ply"))
            .expect("the built-in bunny reads");
        InsertMesh::new("Bunny", &mesh).expect("the built-in bunny is closed")
    }

    /// A primitive.
    pub fn primitive(p: Primitive) -> Self {
        InsertMesh::new(p.name(), &p.mesh()).expect("the primitives are closed")
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Its largest side, in its own units.
    pub fn size(&self) -> f64 {
        self.size
    }

    /// The preview mesh, in its own units around its box's centre (draw it scaled by
    /// `placement.size / size()`, turned and moved by the placement).
    pub fn preview(&self) -> &strata_mesh::Mesh {
        &self.preview
    }

    /// [`InsertMesh::preview`], shared (to keep beside other borrows while drawing).
    pub fn preview_shared(&self) -> Arc<strata_mesh::Mesh> {
        self.preview.clone()
    }

    /// The brush that `placement` makes of it in the grid of a layer placed by `layer`.
    pub fn brush(
        &self,
        layer: &LayerTransform,
        placement: &Placement,
    ) -> Result<Transformed<Arc<MeshBrush>>, InsertError> {
        if !placement.is_valid() || !layer.is_valid() {
            return Err(InsertError::Placement);
        }
        let rotation = layer.rotation.inverse() * placement.rotation.normalize();
        let k = placement.size / self.size / layer.scale;
        let translation = layer.to_grid(placement.position) - rotation * (self.centre * k);
        Transformed::new(self.brush.clone(), rotation, translation, k).map_err(|_| InsertError::Placement)
    }
}

impl Editor {
    /// Adds `mesh` to layer `layer` as `placement` places it (or subtracts it, or keeps only
    /// what lies inside it), exactly as the core's CSG with the placed mesh brush, as one undo
    /// step; the edit takes the current material. Refused while recording a room's operations
    /// (an insert is not an operation the others could replay) and on a streamed world.
    pub fn insert_mesh(
        &mut self,
        layer: usize,
        mesh: &InsertMesh,
        placement: &Placement,
        op: CsgOp,
    ) -> Result<strata_volume::EditReport, EditorError> {
        if self.records_ops() {
            return Err(EditorError::NotShared("a mesh insert"));
        }
        if self.surface(layer).is_some_and(|s| s.streamed()) {
            // (An intersection would empty only the chunks in memory.)
            return Err(EditorError::InsertOnWorld);
        }
        self.check_material()?;
        let transform = self.surface(layer).ok_or(EditorError::NoLayer(layer))?.transform();
        let brush = mesh.brush(&transform, placement)?;
        self.apply(layer, op, &brush)
    }
}
