//! Mesh files: binary glTF 2.0 (`.glb`), Wavefront OBJ, binary STL and binary PLY.
//!
//! With a palette ([`save_mesh_with`]), the formats that can carry colour do: every vertex's
//! colour is its material blend ([`crate::VertexMaterial`]) over the palette's colours (sRGB
//! bytes). A glb gets `COLOR_0` (normalised unsigned bytes, VEC4) and one primitive per material
//! present, split by each triangle's dominant material, each with a glTF material named after
//! the palette entry (base colour white, so the vertex colours show unchanged; its roughness
//! from the palette); an OBJ gets vertex colours (`v x y z r g b`, as Blender and tobj read
//! them), `usemtl` groups by dominant material and an MTL file beside it (`Kd` per material);
//! a PLY gets `red green blue` bytes per vertex. STL has no colour.
//!
//! Saving is atomic: the file is written to a temporary file in the same folder, flushed and
//! renamed over the target, so a crash mid-save leaves any previous file intact.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use rayon::prelude::*;
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
    // (The scans of a large mesh run on every core: an export checks millions of indices.)
    if mesh.indices.par_iter().with_min_len(1 << 16).any(|&i| i as usize >= mesh.positions.len()) {
        return Err(ExportError::Malformed("an index names no vertex"));
    }
    if mesh.normals.len() != mesh.positions.len() {
        return Err(ExportError::Malformed("normals and positions differ in count"));
    }
    if !mesh.materials.is_empty() && mesh.materials.len() != mesh.positions.len() {
        return Err(ExportError::Malformed("vertex materials and positions differ in count"));
    }
    if mesh.positions.par_iter().with_min_len(1 << 16).flatten().any(|v| !v.is_finite()) {
        return Err(ExportError::Malformed("a position is not finite"));
    }
    Ok(())
}

/// One palette entry as exports see it.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportMaterial {
    /// Material name (glTF material name, OBJ `newmtl`).
    pub name: String,
    /// Linear RGB in `[0, 1]`.
    pub color: [f32; 3],
    /// Perceptual roughness in `[0, 1]`.
    pub roughness: f32,
}

/// Linear to sRGB-encoded byte.
fn srgb_byte(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 { c * 12.92 } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// A linear colour channel as a linear byte (glTF's `COLOR_0` is linear).
fn linear_byte(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// The linear colour of vertex `i` over `palette` (ids past its end count as its first entry).
pub fn vertex_color(mesh: &Mesh, i: usize, palette: &[ExportMaterial]) -> [f32; 3] {
    let m = mesh.material(i);
    let mut c = [0.0f32; 3];
    for (id, w) in m.ids.iter().zip(m.weights) {
        let p = palette.get(*id as usize).or(palette.first()).map_or([0.8; 3], |p| p.color);
        for k in 0..3 {
            c[k] += p[k] * w as f32 / 255.0;
        }
    }
    c
}

/// The dominant material of each triangle: the most common dominant id of its corners (the
/// first corner's on a three-way tie).
fn triangle_materials(mesh: &Mesh) -> Vec<u8> {
    mesh.indices
        .par_chunks_exact(3)
        .with_min_len(1 << 14)
        .map(|t| {
            let d = [t[0], t[1], t[2]].map(|i| mesh.material(i as usize).dominant());
            if d[1] == d[2] { d[1] } else { d[0] }
        })
        .collect()
}

/// Writes 4-byte words little-endian: their own bytes where the machine is little-endian (one
/// write, no copy), converted a piece at a time elsewhere.
fn write_le_words<T: bytemuck::Pod>(w: &mut impl Write, words: &[T]) -> io::Result<()> {
    let words: &[u32] = bytemuck::cast_slice(words);
    if cfg!(target_endian = "little") {
        return w.write_all(bytemuck::cast_slice(words));
    }
    write_le_words_converted(w, words)
}

/// [`write_le_words`] on any machine: each word converted to little-endian bytes.
fn write_le_words_converted(w: &mut impl Write, words: &[u32]) -> io::Result<()> {
    for part in words.chunks(1 << 14) {
        let bytes: Vec<u8> = part.iter().flat_map(|x| x.to_le_bytes()).collect();
        w.write_all(&bytes)?;
    }
    Ok(())
}

/// Writes `mesh` to `path` in the format its extension names, atomically, without colours.
pub fn save_mesh(mesh: &Mesh, path: &Path) -> Result<(), ExportError> {
    save_mesh_with(mesh, path, &[])
}

/// [`save_mesh`] with the vertex materials coloured from `palette` (see the module docs; an
/// empty palette writes no colour). An OBJ's MTL file is written beside it, atomically too.
pub fn save_mesh_with(mesh: &Mesh, path: &Path, palette: &[ExportMaterial]) -> Result<(), ExportError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| ExportError::UnknownFormat(path.display().to_string()))?;
    validate(mesh)?;
    let mtl = (format == MeshFormat::Obj && !palette.is_empty()).then(|| path.with_extension("mtl"));
    if let Some(mtl) = &mtl {
        write_atomic(mtl, |w| write_mtl(mesh, palette, w))?;
    }
    let mtl_name = mtl.as_ref().and_then(|m| m.file_name()).and_then(|n| n.to_str()).map(str::to_owned);
    write_atomic(path, |w| match format {
        MeshFormat::Glb => Ok(write_glb(mesh, palette, w)?),
        MeshFormat::Obj => Ok(write_obj(mesh, palette, mtl_name.as_deref(), w)?),
        MeshFormat::Stl => Ok(write_stl(mesh, w)?),
        MeshFormat::Ply => Ok(write_ply(mesh, palette, w)?),
    })
}

/// Writes through `write` atomically ([`strata_files::write_atomically`]), buffered.
fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> Result<(), ExportError>,
) -> Result<(), ExportError> {
    strata_files::write_atomically(path, |f| {
        let mut w = BufWriter::new(f);
        write(&mut w)?;
        w.flush()?;
        Ok(())
    })
}

/// Writes `mesh` in `format`.
pub fn write_mesh(mesh: &Mesh, format: MeshFormat, w: &mut impl Write) -> Result<(), ExportError> {
    validate(mesh)?;
    match format {
        MeshFormat::Glb => write_glb(mesh, &[], w)?,
        MeshFormat::Obj => write_obj(mesh, &[], None, w)?,
        MeshFormat::Stl => write_stl(mesh, w)?,
        MeshFormat::Ply => write_ply(mesh, &[], w)?,
    }
    Ok(())
}

/// The name a material is written under: the palette's, made safe for OBJ and MTL lines.
fn material_name(palette: &[ExportMaterial], id: u8) -> String {
    let name = palette.get(id as usize).map_or("material", |p| p.name.as_str());
    let safe: String = name.chars().map(|c| if c.is_alphanumeric() || c == '-' { c } else { '_' }).collect();
    format!("{id}_{safe}")
}

fn write_mtl(mesh: &Mesh, palette: &[ExportMaterial], w: &mut impl Write) -> Result<(), ExportError> {
    let mut used: Vec<u8> = triangle_materials(mesh);
    used.sort_unstable();
    used.dedup();
    writeln!(w, "# Strata materials")?;
    for id in used {
        let p = palette.get(id as usize).or(palette.first()).expect("a palette");
        writeln!(w, "newmtl {}", material_name(palette, id))?;
        writeln!(w, "Kd {} {} {}", p.color[0], p.color[1], p.color[2])?;
        writeln!(w, "Ns {}", ((1.0 - p.roughness.clamp(0.0, 1.0)) * 1000.0).round())?;
        writeln!(w, "illum 2")?;
    }
    Ok(())
}

fn write_obj(mesh: &Mesh, palette: &[ExportMaterial], mtl: Option<&str>, w: &mut impl Write) -> io::Result<()> {
    writeln!(w, "# Strata mesh: {} vertices, {} triangles", mesh.vertex_count(), mesh.triangle_count())?;
    if let Some(mtl) = mtl {
        writeln!(w, "mtllib {mtl}")?;
    }
    for (i, p) in mesh.positions.iter().enumerate() {
        if palette.is_empty() {
            writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
        } else {
            let c = vertex_color(mesh, i, palette);
            writeln!(w, "v {} {} {} {} {} {}", p[0], p[1], p[2], c[0], c[1], c[2])?;
        }
    }
    for n in &mesh.normals {
        writeln!(w, "vn {} {} {}", n[0], n[1], n[2])?;
    }
    let materials = triangle_materials(mesh);
    let mut order: Vec<usize> = (0..mesh.triangle_count()).collect();
    if mtl.is_some() {
        order.sort_by_key(|&t| materials[t]);
    }
    let mut current = None;
    for t in order {
        if mtl.is_some() && current != Some(materials[t]) {
            current = Some(materials[t]);
            writeln!(w, "usemtl {}", material_name(palette, materials[t]))?;
        }
        let (a, b, c) = (mesh.indices[3 * t] + 1, mesh.indices[3 * t + 1] + 1, mesh.indices[3 * t + 2] + 1);
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

fn write_ply(mesh: &Mesh, palette: &[ExportMaterial], w: &mut impl Write) -> io::Result<()> {
    let colors =
        if palette.is_empty() { "" } else { "property uchar red\nproperty uchar green\nproperty uchar blue\n" };
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment Strata mesh\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n{colors}element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.vertex_count(),
        mesh.triangle_count()
    )?;
    for (i, (p, n)) in mesh.positions.iter().zip(&mesh.normals).enumerate() {
        for x in p.iter().chain(n) {
            w.write_all(&x.to_le_bytes())?;
        }
        if !palette.is_empty() {
            w.write_all(&vertex_color(mesh, i, palette).map(srgb_byte))?;
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

fn write_glb(mesh: &Mesh, palette: &[ExportMaterial], w: &mut impl Write) -> io::Result<()> {
    // The binary chunk is laid out first and streamed after the JSON: positions, normals,
    // colours, then the indices (no second copy of the mesh in memory).
    let nv = mesh.vertex_count();
    let normals_at = nv * 12;
    let colors_at = normals_at + nv * 12;
    let indices_at = colors_at + if palette.is_empty() { 0 } else { nv * 4 };
    // Index ranges: one for the whole mesh, or one per dominant material, in id order.
    let dominant = (!palette.is_empty()).then(|| triangle_materials(mesh));
    let mut groups: Vec<(Option<u8>, usize, usize)> = Vec::new();
    match &dominant {
        None => groups.push((None, indices_at, mesh.indices.len())),
        Some(dominant) => {
            let mut count = [0usize; 256];
            for &id in dominant {
                count[id as usize] += 3;
            }
            let mut at = indices_at;
            for (id, &n) in count.iter().enumerate().filter(|(_, n)| **n > 0) {
                groups.push((Some(id as u8), at, n));
                at += n * 4;
            }
        }
    }
    // Every piece is a whole number of 4-byte words: no padding.
    let bin_len = indices_at + mesh.indices.len() * 4;
    let bounds = |(mut min, mut max): ([f32; 3], [f32; 3]), p: &[f32; 3]| {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
        (min, max)
    };
    let none = || ([f32::MAX; 3], [f32::MIN; 3]);
    let (min, max) = mesh.positions.par_iter().with_min_len(1 << 16).fold(none, bounds).reduce(
        none,
        |(amin, amax), (bmin, bmax)| {
            (std::array::from_fn(|k| amin[k].min(bmin[k])), std::array::from_fn(|k| amax[k].max(bmax[k])))
        },
    );
    let mut views = vec![
        serde_json::json!({ "buffer": 0, "byteOffset": 0, "byteLength": normals_at, "target": 34962 }),
        serde_json::json!({ "buffer": 0, "byteOffset": normals_at, "byteLength": colors_at - normals_at, "target": 34962 }),
    ];
    let mut accessors = vec![
        serde_json::json!({ "bufferView": 0, "componentType": 5126, "count": nv, "type": "VEC3", "min": min, "max": max }),
        serde_json::json!({ "bufferView": 1, "componentType": 5126, "count": nv, "type": "VEC3" }),
    ];
    let mut attributes = serde_json::json!({ "POSITION": 0, "NORMAL": 1 });
    if !palette.is_empty() {
        views.push(serde_json::json!({ "buffer": 0, "byteOffset": colors_at, "byteLength": indices_at - colors_at, "target": 34962 }));
        accessors.push(serde_json::json!({ "bufferView": 2, "componentType": 5121, "normalized": true, "count": nv, "type": "VEC4" }));
        attributes["COLOR_0"] = serde_json::json!(2);
    }
    let mut primitives = Vec::new();
    let mut materials = Vec::new();
    for &(id, at, count) in &groups {
        views.push(serde_json::json!({ "buffer": 0, "byteOffset": at, "byteLength": count * 4, "target": 34963 }));
        accessors.push(serde_json::json!({ "bufferView": views.len() - 1, "componentType": 5125, "count": count, "type": "SCALAR" }));
        let mut prim =
            serde_json::json!({ "attributes": attributes.clone(), "indices": accessors.len() - 1, "mode": 4 });
        if let Some(id) = id {
            let p = palette.get(id as usize).or(palette.first()).expect("a palette");
            materials.push(serde_json::json!({
                "name": p.name,
                "pbrMetallicRoughness": { "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": p.roughness.clamp(0.0, 1.0) }
            }));
            prim["material"] = serde_json::json!(materials.len() - 1);
        }
        primitives.push(prim);
    }
    let mut json = serde_json::json!({
        "asset": { "version": "2.0", "generator": "Strata" },
        "scene": 0,
        "scenes": [ { "nodes": [0] } ],
        "nodes": [ { "mesh": 0, "name": "strata" } ],
        "meshes": [ { "primitives": primitives } ],
        "buffers": [ { "byteLength": bin_len } ],
        "bufferViews": views,
        "accessors": accessors
    });
    if !materials.is_empty() {
        json["materials"] = serde_json::json!(materials);
    }
    let mut text = serde_json::to_vec(&json).map_err(io::Error::other)?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bin_len;
    let total = u32::try_from(total)
        .map_err(|_| io::Error::other(format!("the mesh needs {total} bytes; a GLB file holds at most 4 GiB")))?;
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&total.to_le_bytes())?;
    w.write_all(&(text.len() as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(&text)?;
    w.write_all(&(bin_len as u32).to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    write_le_words(w, bytemuck::cast_slice::<[f32; 3], f32>(&mesh.positions))?;
    write_le_words(w, bytemuck::cast_slice::<[f32; 3], f32>(&mesh.normals))?;
    if !palette.is_empty() {
        let colors: Vec<[u8; 4]> = (0..nv)
            .into_par_iter()
            .with_min_len(1 << 14)
            .map(|i| {
                let c = vertex_color(mesh, i, palette).map(linear_byte);
                [c[0], c[1], c[2], 255]
            })
            .collect();
        w.write_all(bytemuck::cast_slice(&colors))?;
    }
    match &dominant {
        Some(dominant) if groups.len() > 1 => {
            // One material's triangles after another, staged a piece at a time.
            let mut picked: Vec<u32> = Vec::with_capacity(3 << 14);
            for &(id, _, _) in &groups {
                for (t, _) in mesh.indices.chunks_exact(3).zip(dominant).filter(|(_, d)| Some(**d) == id) {
                    picked.extend_from_slice(t);
                    if picked.len() >= 3 << 14 {
                        write_le_words(w, &picked)?;
                        picked.clear();
                    }
                }
                write_le_words(w, &picked)?;
                picked.clear();
            }
        }
        _ => write_le_words(w, &mesh.indices)?,
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_are_written_little_endian_on_either_road() {
        let positions = [[1.5f32, -0.0, f32::MAX], [3.25e-7, 2.0, -7.0]];
        let (mut direct, mut converted) = (Vec::new(), Vec::new());
        write_le_words(&mut direct, &positions).unwrap();
        write_le_words_converted(&mut converted, bytemuck::cast_slice(&positions)).unwrap();
        let expected: Vec<u8> = positions.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        assert_eq!(direct, expected);
        assert_eq!(converted, expected);
        let indices: Vec<u32> = (0..70_000u32).map(|i| i.wrapping_mul(2_654_435_761)).collect();
        converted.clear();
        write_le_words_converted(&mut converted, &indices).unwrap();
        assert_eq!(converted, indices.iter().flat_map(|i| i.to_le_bytes()).collect::<Vec<u8>>());
    }
}
