//! Mesh files: binary glTF 2.0 (`.glb`), Wavefront OBJ, binary STL and binary PLY.
//!
//! Saving is atomic: the file is written to a temporary file in the same folder, flushed and
//! renamed over the target, so a crash mid-save leaves any previous file intact.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use thiserror::Error;

use crate::Mesh;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Binary glTF 2.0: positions, normals, 32-bit indices.
    Glb,
    /// Wavefront OBJ (text): `v`, `vn` and `f v//vn`.
    Obj,
    /// Binary STL: one facet normal per triangle, no shared vertices.
    Stl,
    /// Binary little-endian PLY: float positions and normals, int32 triangle indices.
    Ply,
}

impl MeshFormat {
    /// The format named by a path's extension (`glb`, `obj`, `stl`, `ply`; any case).
    pub fn from_path(path: &Path) -> Option<Self> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "glb" => Some(MeshFormat::Glb),
            "obj" => Some(MeshFormat::Obj),
            "stl" => Some(MeshFormat::Stl),
            "ply" => Some(MeshFormat::Ply),
            _ => None,
        }
    }
}

/// Why a mesh could not be written.
#[derive(Debug, Error)]
pub enum ExportError {
    /// The path's extension names no supported format.
    #[error("unknown mesh format for {0} (use .glb, .obj, .stl or .ply)")]
    UnknownFormat(String),
    /// The mesh's index buffer names missing vertices or is not made of triangles.
    #[error("the mesh is malformed: {0}")]
    Malformed(&'static str),
    /// Reading or writing failed.
    #[error(transparent)]
    Io(#[from] io::Error),
}

fn validate(mesh: &Mesh) -> Result<(), ExportError> {
    if mesh.indices.is_empty() {
        // glTF forbids zero-count accessors, and an empty file helps nobody.
        return Err(ExportError::Malformed("the mesh has no triangles (nothing to export)"));
    }
    if !mesh.indices.len().is_multiple_of(3) {
        return Err(ExportError::Malformed("index count is not a multiple of 3"));
    }
    if mesh.indices.iter().any(|&i| i as usize >= mesh.positions.len()) {
        return Err(ExportError::Malformed("an index names no vertex"));
    }
    if mesh.normals.len() != mesh.positions.len() {
        return Err(ExportError::Malformed("normals and positions differ in count"));
    }
    if mesh.positions.iter().flatten().any(|v| !v.is_finite()) {
        return Err(ExportError::Malformed("a position is not finite"));
    }
    Ok(())
}

/// Writes `mesh` to `path` in the format its extension names, atomically.
pub fn save_mesh(mesh: &Mesh, path: &Path) -> Result<(), ExportError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| ExportError::UnknownFormat(path.display().to_string()))?;
    validate(mesh)?;
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("mesh");
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| -> Result<(), ExportError> {
        let mut w = BufWriter::new(File::create(&tmp)?);
        write_mesh(mesh, format, &mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)?;
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `mesh` in `format`.
pub fn write_mesh(mesh: &Mesh, format: MeshFormat, w: &mut impl Write) -> Result<(), ExportError> {
    validate(mesh)?;
    match format {
        MeshFormat::Glb => write_glb(mesh, w)?,
        MeshFormat::Obj => write_obj(mesh, w)?,
        MeshFormat::Stl => write_stl(mesh, w)?,
        MeshFormat::Ply => write_ply(mesh, w)?,
    }
    Ok(())
}

fn write_obj(mesh: &Mesh, w: &mut impl Write) -> io::Result<()> {
    writeln!(w, "# Strata mesh: {} vertices, {} triangles", mesh.vertex_count(), mesh.triangle_count())?;
    for p in &mesh.positions {
        writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
    }
    for n in &mesh.normals {
        writeln!(w, "vn {} {} {}", n[0], n[1], n[2])?;
    }
    for [a, b, c] in mesh.triangles() {
        let (a, b, c) = (a + 1, b + 1, c + 1);
        writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
    }
    Ok(())
}

fn write_stl(mesh: &Mesh, w: &mut impl Write) -> io::Result<()> {
    let mut header = [0u8; 80];
    let text = b"Strata binary STL";
    header[..text.len()].copy_from_slice(text);
    w.write_all(&header)?;
    w.write_all(&(mesh.triangle_count() as u32).to_le_bytes())?;
    for t in mesh.triangles() {
        let [a, b, c] = t.map(|i| glam::Vec3::from(mesh.positions[i as usize]));
        let n = (b - a).cross(c - a).normalize_or_zero();
        for v in [n, a, b, c] {
            for x in v.to_array() {
                w.write_all(&x.to_le_bytes())?;
            }
        }
        w.write_all(&[0, 0])?;
    }
    Ok(())
}

fn write_ply(mesh: &Mesh, w: &mut impl Write) -> io::Result<()> {
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment Strata mesh\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.vertex_count(),
        mesh.triangle_count()
    )?;
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        for x in p.iter().chain(n) {
            w.write_all(&x.to_le_bytes())?;
        }
    }
    for t in mesh.triangles() {
        w.write_all(&[3])?;
        for i in t {
            w.write_all(&(i as i32).to_le_bytes())?;
        }
    }
    Ok(())
}

fn write_glb(mesh: &Mesh, w: &mut impl Write) -> io::Result<()> {
    let nv = mesh.vertex_count();
    let mut bin: Vec<u8> = Vec::with_capacity(nv * 24 + mesh.indices.len() * 4);
    for p in &mesh.positions {
        p.iter().for_each(|x| bin.extend_from_slice(&x.to_le_bytes()));
    }
    let normals_at = bin.len();
    for n in &mesh.normals {
        n.iter().for_each(|x| bin.extend_from_slice(&x.to_le_bytes()));
    }
    let indices_at = bin.len();
    mesh.indices.iter().for_each(|i| bin.extend_from_slice(&i.to_le_bytes()));
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let (mut min, mut max) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in &mesh.positions {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    let json = serde_json::json!({
        "asset": { "version": "2.0", "generator": "Strata" },
        "scene": 0,
        "scenes": [ { "nodes": [0] } ],
        "nodes": [ { "mesh": 0, "name": "strata" } ],
        "meshes": [ { "primitives": [ {
            "attributes": { "POSITION": 0, "NORMAL": 1 },
            "indices": 2,
            "mode": 4
        } ] } ],
        "buffers": [ { "byteLength": bin.len() } ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": normals_at, "target": 34962 },
            { "buffer": 0, "byteOffset": normals_at, "byteLength": indices_at - normals_at, "target": 34962 },
            { "buffer": 0, "byteOffset": indices_at, "byteLength": mesh.indices.len() * 4, "target": 34963 }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": nv, "type": "VEC3", "min": min, "max": max },
            { "bufferView": 1, "componentType": 5126, "count": nv, "type": "VEC3" },
            { "bufferView": 2, "componentType": 5125, "count": mesh.indices.len(), "type": "SCALAR" }
        ]
    });
    let mut text = serde_json::to_vec(&json).map_err(io::Error::other)?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bin.len();
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&(total as u32).to_le_bytes())?;
    w.write_all(&(text.len() as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(&text)?;
    w.write_all(&(bin.len() as u32).to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    w.write_all(&bin)?;
    Ok(())
}
