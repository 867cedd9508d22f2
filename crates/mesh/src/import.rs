//! Reading triangle meshes (PLY, OBJ, binary or ASCII STL) for conversion into volumes, through
//! the `ply-rs`, `tobj` and `stl_io` crates. Polygons with more than three corners are split
//! into fans. Every file is validated: finite coordinates, indices in range, at least one
//! triangle; anything else is an [`ImportError`], never a panic.

use std::io::{self, BufReader};
use std::path::Path;

use glam::DVec3;
use thiserror::Error;

/// Vertices and triangles read from a file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions, in the file's units.
    pub vertices: Vec<DVec3>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// The smallest box holding every vertex (`None` for no vertices).
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        let first = *self.vertices.first()?;
        Some(self.vertices.iter().fold((first, first), |(lo, hi), &v| (lo.min(v), hi.max(v))))
    }
}

/// Why a mesh file could not be read.
#[derive(Debug, Error)]
pub enum ImportError {
    /// The extension names no supported format.
    #[error("unknown mesh format for {0} (use .ply, .obj or .stl)")]
    UnknownFormat(String),
    /// The file could not be parsed.
    #[error("cannot parse {path}: {reason}")]
    Parse {
        /// The file.
        path: String,
        /// What the parser said.
        reason: String,
    },
    /// The file parsed but does not describe a usable triangle mesh.
    #[error("{path} is not a usable triangle mesh: {reason}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// Opening or reading failed.
    #[error(transparent)]
    Io(#[from] io::Error),
}

/// Reads the mesh at `path`, choosing the format by extension.
pub fn load_mesh(path: &Path) -> Result<TriangleMesh, ImportError> {
    let name = path.display().to_string();
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let parse = |reason: String| ImportError::Parse { path: name.clone(), reason };
    let mesh = match ext.as_deref() {
        Some("ply") => read_ply(path).map_err(parse)?,
        Some("obj") => read_obj(path).map_err(parse)?,
        Some("stl") => read_stl(path).map_err(parse)?,
        _ => return Err(ImportError::UnknownFormat(name)),
    };
    validate(&mesh).map_err(|reason| ImportError::Invalid { path: name, reason })?;
    Ok(mesh)
}

fn validate(m: &TriangleMesh) -> Result<(), &'static str> {
    if m.triangles.is_empty() {
        return Err("it has no triangles");
    }
    if m.vertices.iter().any(|v| !v.is_finite()) {
        return Err("a vertex coordinate is NaN or infinite");
    }
    if m.triangles.iter().flatten().any(|&i| i as usize >= m.vertices.len()) {
        return Err("a face names a vertex that does not exist");
    }
    Ok(())
}

/// Splits a polygon into a fan of triangles (faces with fewer than three corners are dropped).
fn push_fan(out: &mut Vec<[u32; 3]>, corners: &[u32]) {
    for k in 2..corners.len() {
        out.push([corners[0], corners[k - 1], corners[k]]);
    }
}

fn read_ply(path: &Path) -> Result<TriangleMesh, String> {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let mut f = BufReader::new(std::fs::File::open(path).map_err(|e| e.to_string())?);
    let ply = Parser::<DefaultElement>::new().read_ply(&mut f).map_err(|e| e.to_string())?;
    let scalar = |p: Option<&Property>| -> Option<f64> {
        Some(match p? {
            Property::Float(v) => *v as f64,
            Property::Double(v) => *v,
            Property::Int(v) => *v as f64,
            Property::UInt(v) => *v as f64,
            Property::Short(v) => *v as f64,
            Property::UShort(v) => *v as f64,
            Property::Char(v) => *v as f64,
            Property::UChar(v) => *v as f64,
            _ => return None,
        })
    };
    let mut mesh = TriangleMesh::default();
    for e in ply.payload.get("vertex").map(Vec::as_slice).unwrap_or_default() {
        let (x, y, z) = (scalar(e.get("x")), scalar(e.get("y")), scalar(e.get("z")));
        match (x, y, z) {
            (Some(x), Some(y), Some(z)) => mesh.vertices.push(DVec3::new(x, y, z)),
            _ => return Err("a vertex lacks numeric x, y or z".into()),
        }
    }
    for e in ply.payload.get("face").map(Vec::as_slice).unwrap_or_default() {
        let list = e.get("vertex_indices").or_else(|| e.get("vertex_index"));
        let corners: Vec<u32> = match list {
            Some(Property::ListInt(v)) => v.iter().map(|&i| u32::try_from(i).unwrap_or(u32::MAX)).collect(),
            Some(Property::ListUInt(v)) => v.clone(),
            Some(Property::ListShort(v)) => v.iter().map(|&i| u32::try_from(i).unwrap_or(u32::MAX)).collect(),
            Some(Property::ListUShort(v)) => v.iter().map(|&i| i as u32).collect(),
            Some(Property::ListUChar(v)) => v.iter().map(|&i| i as u32).collect(),
            _ => return Err("a face lacks an integer vertex_indices list".into()),
        };
        push_fan(&mut mesh.triangles, &corners);
    }
    Ok(mesh)
}

fn read_obj(path: &Path) -> Result<TriangleMesh, String> {
    let opts = tobj::LoadOptions { single_index: true, triangulate: false, ..Default::default() };
    let (models, _) = tobj::load_obj(path, &opts).map_err(|e| e.to_string())?;
    let mut mesh = TriangleMesh::default();
    for m in models {
        let base = mesh.vertices.len() as u32;
        let p = &m.mesh.positions;
        mesh.vertices.extend(p.chunks_exact(3).map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)));
        let idx = &m.mesh.indices;
        if m.mesh.face_arities.is_empty() {
            for t in idx.chunks_exact(3) {
                mesh.triangles.push([base + t[0], base + t[1], base + t[2]]);
            }
        } else {
            let mut at = 0;
            for &n in &m.mesh.face_arities {
                let corners: Vec<u32> = idx[at..at + n as usize].iter().map(|&i| base + i).collect();
                push_fan(&mut mesh.triangles, &corners);
                at += n as usize;
            }
        }
    }
    Ok(mesh)
}

fn read_stl(path: &Path) -> Result<TriangleMesh, String> {
    let mut f = BufReader::new(std::fs::File::open(path).map_err(|e| e.to_string())?);
    let stl = stl_io::read_stl(&mut f).map_err(|e| e.to_string())?;
    Ok(TriangleMesh {
        vertices: stl.vertices.iter().map(|v| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)).collect(),
        triangles: stl.faces.iter().map(|f| f.vertices.map(|i| i as u32)).collect(),
    })
}
