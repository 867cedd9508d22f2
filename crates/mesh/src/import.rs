//! Reading triangle meshes (PLY, OBJ, binary or ASCII STL, glTF and GLB) for conversion into
//! volumes, through the `ply-rs`, `tobj`, `stl_io` and `gltf` crates (binary STL is read here).
//! A glTF scene's triangle primitives are gathered with their nodes' transforms applied (the
//! default scene, or every root node when there is none); a `.gltf` may name its buffers as
//! files beside it, read through the same size limit; images are never loaded. Polygons with more than
//! three corners are split into fans. Every file is validated: finite coordinates, indices in
//! range, at least one triangle; anything else is an [`ImportError`], never a panic.
//!
//! Reads are bounded: a path that is not a regular file (a FIFO, a device such as `/dev/zero`,
//! directly or through a link) or a file over [`MAX_MESH_BYTES`] is refused before a byte is
//! read, and the bytes are read into memory with that limit before any parser sees them, so a
//! file that grows while it is read cannot exhaust memory either. A binary STL is recognised by
//! its size rule (84 + 50 · count bytes), not by its first word: CAD exporters often begin the
//! 80-byte header of a binary file with `solid`.

use std::collections::HashMap;
use std::io::{self, Cursor};
use std::path::Path;

use glam::DVec3;
use thiserror::Error;

/// The largest mesh file read (2 GiB: about 40 million binary STL triangles).
pub const MAX_MESH_BYTES: u64 = 2 << 30;

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
    #[error("unknown mesh format for {0} (use .ply, .obj, .stl, .gltf or .glb)")]
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

/// The mesh file extensions [`load_mesh`] reads.
pub const MESH_EXTENSIONS: [&str; 5] = ["ply", "obj", "stl", "gltf", "glb"];

/// Parses a mesh held in memory; `format` is `"ply"`, `"obj"`, `"stl"`, `"gltf"` or `"glb"` (a
/// `.gltf` held in memory can only use embedded buffers). (Not validated: see [`load_mesh`].)
pub fn parse_mesh(format: &str, bytes: &[u8]) -> Result<TriangleMesh, String> {
    match format {
        "ply" => read_ply(bytes),
        "obj" => read_obj(bytes),
        "stl" => read_stl(bytes),
        "gltf" | "glb" => read_gltf(bytes, None),
        other => Err(format!("unknown mesh format {other:?}")),
    }
}

/// The triangles of a glTF or GLB document, `base` the folder its external buffers are read
/// from (none: only embedded and data-URI buffers).
fn read_gltf(bytes: &[u8], base: Option<&Path>) -> Result<TriangleMesh, String> {
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| e.to_string())?;
    let document = gltf.document;
    for buffer in document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source()
            && !uri.starts_with("data:")
        {
            let dir = base.ok_or("a glTF in memory cannot read external buffers")?;
            // External buffers go through the same bounded read as the file itself.
            let path = dir.join(uri);
            strata_files::read_limited(&path, MAX_MESH_BYTES).map_err(|e| format!("buffer {}: {e}", path.display()))?;
        }
    }
    let buffers = gltf::import_buffers(&document, base, gltf.blob).map_err(|e| e.to_string())?;
    let mut mesh = TriangleMesh::default();
    let roots: Vec<gltf::Node> = match document.default_scene().or_else(|| document.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => document.nodes().collect(),
    };
    let mut stack: Vec<(gltf::Node, glam::DMat4)> = roots.into_iter().map(|n| (n, glam::DMat4::IDENTITY)).collect();
    let mut visited = 0usize;
    while let Some((node, parent)) = stack.pop() {
        visited += 1;
        if visited > 1_000_000 {
            return Err("the node hierarchy is too deep or cyclic".into());
        }
        let local = glam::Mat4::from_cols_array_2d(&node.transform().matrix()).as_dmat4();
        let world = parent * local;
        if let Some(m) = node.mesh() {
            for primitive in m.primitives() {
                if primitive.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
                let Some(positions) = reader.read_positions() else { continue };
                let base = mesh.vertices.len() as u32;
                let mut count = 0u32;
                for p in positions {
                    mesh.vertices.push(world.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)));
                    count += 1;
                }
                let indices: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..count).collect(),
                };
                if indices.iter().any(|&i| i >= count) {
                    return Err("a primitive's index names a vertex that does not exist".into());
                }
                // A mirroring transform turns faces inside out: flip them back.
                let flip = world.determinant() < 0.0;
                for t in indices.chunks_exact(3) {
                    let (a, b, c) = (base + t[0], base + t[1], base + t[2]);
                    mesh.triangles.push(if flip { [a, c, b] } else { [a, b, c] });
                }
            }
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    Ok(mesh)
}

/// Reads the mesh at `path`, choosing the format by extension.
pub fn load_mesh(path: &Path) -> Result<TriangleMesh, ImportError> {
    let name = path.display().to_string();
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let parse = |reason: String| ImportError::Parse { path: name.clone(), reason };
    if !ext.as_deref().is_some_and(|e| MESH_EXTENSIONS.contains(&e)) {
        return Err(ImportError::UnknownFormat(name));
    }
    let bytes = strata_files::read_limited(path, MAX_MESH_BYTES)
        .map_err(|e| ImportError::Io(io::Error::new(e.kind(), format!("{name}: {e}"))))?;
    let mesh = match ext.as_deref() {
        Some("gltf" | "glb") => read_gltf(&bytes, Some(path.parent().unwrap_or(Path::new(".")))),
        Some(e) => parse_mesh(e, &bytes),
        None => unreachable!("checked above"),
    }
    .map_err(parse)?;
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

fn read_ply(bytes: &[u8]) -> Result<TriangleMesh, String> {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let mut f = Cursor::new(bytes);
    let ply = Parser::<DefaultElement>::new().read_ply(&mut f).map_err(|e| ply_message(&e.to_string()))?;
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

/// A `ply-rs` error as one readable line. Its messages span lines and nest the `Debug` dumps of
/// inner errors (`Error: Custom { kind: InvalidInput, error: "…" }`, a `peg` `ParseError { … }`,
/// `ParseFloatError { kind: Invalid }`); this keeps what went wrong, the line number and the
/// offending text, and drops the dumps.
fn ply_message(raw: &str) -> String {
    let (what, text) = ply_parts(raw);
    let mut out = if what.is_empty() { "not a PLY file this reader understands".to_string() } else { what };
    if let Some(t) = text {
        let shown: String = t.chars().take(48).collect();
        let more = if t.chars().count() > 48 { "…" } else { "" };
        out = format!("{out} (`{shown}{more}`)");
    }
    out.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// What a `ply-rs` message says went wrong, and the offending text if it quotes one.
fn ply_parts(raw: &str) -> (String, Option<String>) {
    /// The text of a `Debug`-quoted string, from just after its opening quote.
    fn unquote(s: &str) -> String {
        let mut out = String::new();
        let mut chars = s.chars();
        while let Some(c) = chars.next() {
            match c {
                '"' => break,
                '\\' => match chars.next() {
                    Some('n') => out.push('\n'),
                    Some('t') => out.push('\t'),
                    Some(other) => out.push(other),
                    None => break,
                },
                c => out.push(c),
            }
        }
        out
    }
    /// A sentence fragment: first letter lower-case, no final full stop, readable type names.
    fn fragment(s: &str) -> String {
        let s = s.trim().trim_end_matches([',', ' ', '.']).replace("Couln't", "Couldn't");
        let lower = |s: &str| {
            let mut c = s.chars();
            c.next().map_or(String::new(), |f| f.to_lowercase().chain(c).collect::<String>())
        };
        let mut s = match s.strip_prefix("Line ").and_then(|rest| rest.split_once(": ")) {
            Some((line, rest)) => format!("line {line}: {}", lower(rest)),
            None => lower(&s),
        };
        // `'Scalar(Float)'` → `'float'`, `'List(UChar, Int)'` → `'list of int'`.
        for (from, to) in [("'Scalar(", "'"), ("'List(", "'list of ("), (")'", "'")] {
            s = s.replace(from, to);
        }
        for t in ["Char", "UChar", "Short", "UShort", "Int", "UInt", "Float", "Double"] {
            s = s.replace(&format!("({t}, "), "").replace(t, &t.to_lowercase());
        }
        s
    }
    let mut lines = raw.lines().map(str::trim).filter(|l| !l.is_empty() && *l != "'");
    let head = lines.next().map(fragment).unwrap_or_default();
    if head == "failed to fill whole buffer" {
        return ("the file ends before its last element".into(), None);
    }
    let (mut text, mut detail) = (None, None);
    for l in lines {
        if let Some(v) = l.strip_prefix("String:").or_else(|| l.strip_prefix("Value:")) {
            let v = v.trim().trim_matches('\'').trim();
            if !v.is_empty() {
                text = Some(v.to_string());
            }
        } else if let Some(e) = l.strip_prefix("Error:") {
            let e = e.trim().trim_end_matches([',', ' ']);
            detail = if let Some(at) = e.find("error: \"") {
                // A nested io::Error: its own message, read the same way.
                let (inner, inner_text) = ply_parts(&unquote(&e[at + 8..]));
                text = text.or(inner_text);
                Some(inner)
            } else if let Some(at) = e.find("column: ").map(|a| a + 8).or_else(|| {
                // peg's Display: "error at LINE:COLUMN: expected …".
                e.strip_prefix("error at ").and_then(|r| r.find(':')).map(|c| c + 10)
            }) {
                let col: String = e[at..].chars().take_while(char::is_ascii_digit).collect();
                Some(format!("unexpected text at column {col}"))
            } else if e.contains("ParseFloatError") || e.contains("ParseIntError") {
                Some("not a number of the declared type".into())
            } else if e.contains('{') || e.contains('(') {
                None
            } else {
                Some(fragment(e))
            };
        }
    }
    let what = match detail.filter(|d| !d.is_empty()) {
        Some(d) if !head.is_empty() => format!("{head}: {d}"),
        Some(d) => d,
        None => head,
    };
    (what, text)
}

fn read_obj(bytes: &[u8]) -> Result<TriangleMesh, String> {
    let opts = tobj::LoadOptions { single_index: true, triangulate: false, ..Default::default() };
    // Materials are not read (only the geometry becomes a volume).
    let (models, _) = tobj::load_obj_buf(&mut Cursor::new(bytes), &opts, |_| Err(tobj::LoadError::OpenFileFailed))
        .map_err(|e| e.to_string())?;
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

/// Bytes of a binary STL's header and triangle count, and of each triangle record.
const STL_HEADER: usize = 84;
const STL_RECORD: usize = 50;

fn read_stl(bytes: &[u8]) -> Result<TriangleMesh, String> {
    let declared =
        (bytes.len() >= STL_HEADER).then(|| u32::from_le_bytes(bytes[80..84].try_into().expect("4 bytes")) as usize);
    if let Some(count) = declared
        && (bytes.len() - STL_HEADER) as u64 == count as u64 * STL_RECORD as u64
    {
        return Ok(read_binary_stl(&bytes[STL_HEADER..], count));
    }
    let ascii = bytes.trim_ascii_start().starts_with(b"solid") && std::str::from_utf8(bytes).is_ok();
    if !ascii {
        return Err(match declared {
            Some(count) => format!(
                "binary STL declares {count} triangles ({} bytes) but the file has {} bytes{}",
                STL_HEADER as u64 + count as u64 * STL_RECORD as u64,
                bytes.len(),
                if (bytes.len() - STL_HEADER).is_multiple_of(STL_RECORD) {
                    format!(" ({} triangles)", (bytes.len() - STL_HEADER) / STL_RECORD)
                } else {
                    String::new()
                }
            ),
            None => format!("a binary STL needs at least {STL_HEADER} bytes, the file has {}", bytes.len()),
        });
    }
    let stl = stl_io::read_stl(&mut Cursor::new(bytes)).map_err(|e| e.to_string())?;
    Ok(TriangleMesh {
        vertices: stl.vertices.iter().map(|v| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)).collect(),
        triangles: stl.faces.iter().map(|f| f.vertices.map(|i| i as u32)).collect(),
    })
}

/// The `count` triangle records of a binary STL, with bitwise-equal vertices welded (the format
/// repeats every shared vertex), so a closed model reads as a closed mesh.
fn read_binary_stl(records: &[u8], count: usize) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    for r in records.chunks_exact(STL_RECORD).take(count) {
        let float = |at: usize| f32::from_le_bytes(r[at..at + 4].try_into().expect("4 bytes"));
        let mut tri = [0u32; 3];
        for (k, corner) in tri.iter_mut().enumerate() {
            let at = 12 + 12 * k;
            let v = [float(at), float(at + 4), float(at + 8)];
            // -0.0 and 0.0 are one point.
            let bits = v.map(|c| if c == 0.0 { 0 } else { c.to_bits() });
            *corner = *index.entry(bits).or_insert_with(|| {
                mesh.vertices.push(DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64));
                (mesh.vertices.len() - 1) as u32
            });
        }
        mesh.triangles.push(tri);
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Malformed PLY files of every kind of mistake the parser reports.
    const BROKEN: [(&str, &str); 8] = [
        ("missing values", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1 2\n"),
        ("a misspelt header line", "ply\nformat ascii 1.0\nelement vertex 1\nproperty flot x\nend_header\n1\n"),
        ("a word for a number", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\nabc\n"),
        ("no format line", "ply\nelement vertex 1\nproperty float x\nend_header\n1\n"),
        ("no magic number", "hello\nformat ascii 1.0\nend_header\n"),
        (
            "a short list",
            "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 1\n",
        ),
        (
            "binary cut short",
            "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nend_header\n\x01",
        ),
        ("a fraction for an integer", "ply\nformat ascii 1.0\nelement vertex 1\nproperty int x\nend_header\n1.5\n"),
    ];

    #[test]
    fn malformed_ply_files_give_one_readable_line_without_debug_dumps() {
        for (what, text) in BROKEN {
            let message = read_ply(text.as_bytes()).expect_err(what);
            assert!(!message.contains('\n') && !message.contains('\t'), "{what}: one line: {message:?}");
            for dump in ["Custom {", "kind:", "ParseError", "LineCol", "ExpectedSet", "Scalar(", "{ "] {
                assert!(!message.contains(dump), "{what}: no debug output ({dump}): {message}");
            }
            assert!(message.len() < 160, "{what}: short: {message}");
            assert!(message.chars().any(char::is_alphabetic), "{what}: says something: {message:?}");
        }
        let missing = read_ply(BROKEN[0].1.as_bytes()).unwrap_err();
        assert_eq!(missing, "line 7: couldn't read element line: expected element of type 'float', but found nothing");
        let word = read_ply(BROKEN[2].1.as_bytes()).unwrap_err();
        assert_eq!(
            word,
            "line 6: couldn't read element line: couldn't parse element line: unexpected text at column 1 (`abc`)"
        );
        let fraction = read_ply(BROKEN[7].1.as_bytes()).unwrap_err();
        assert!(fraction.contains("not a number of the declared type") && fraction.contains("1.5"), "{fraction}");
        let header = read_ply(BROKEN[1].1.as_bytes()).unwrap_err();
        assert_eq!(header, "line 4: couldn't parse line: unexpected text at column 10 (`property flot x`)");
        let cut = read_ply(BROKEN[6].1.as_bytes()).unwrap_err();
        assert_eq!(cut, "the file ends before its last element");
    }
}
