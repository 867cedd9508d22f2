//! The `convert`, `export` and `info` commands. Each checks every argument and path before it
//! starts, reports long work on a progress bar (drawn only when standard error is a terminal),
//! and writes its output atomically, so a failure leaves no half-written file.

use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use strata_editor::file;
use strata_editor::import::{self, ConvertError};
pub use strata_editor::import::{MAX_CELLS, Resolution};
use strata_editor::{Editor, Scene, View};
use strata_mesh::export::save_mesh_with;
use strata_mesh::import::{MESH_EXTENSIONS, load_mesh};
use strata_mesh::islands::DEFAULT_MIN_ISLAND_CELLS;
use strata_mesh::normals::DEFAULT_CREASE_DEGREES;
use strata_volume::brush::MeshRule;
use strata_volume::{Axis, Chunk, EditControl, EditSettings};

use crate::paths::{check_input, check_output, extension};

/// Scene files.
pub const SCENE_EXTENSIONS: [&str; 1] = ["strata"];

/// Mesh formats written by `export`.
pub const EXPORT_EXTENSIONS: [&str; 4] = ["glb", "obj", "stl", "ply"];

/// How a converted mesh decides inside.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Fill {
    /// Inside after an odd number of crossings (ignores orientation; meshes with holes too).
    EvenOdd,
    /// Inside where the winding number is not zero (uses the triangles' orientation).
    Winding,
}

/// Which mesher `export` uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Mesher {
    /// Marching cubes: smooth shapes, vertices on the stored crossings.
    Mc,
    /// Dual contouring (manifold: one vertex per surface component of a cell): keeps sharp
    /// edges and corners.
    Dc,
    /// Regularised marching tetrahedra: clustered, regular triangles, several times fewer
    /// (needs every chunk at one resolution level).
    Rmt,
    /// Marching tetrahedra without clustering.
    Mt,
    /// The first wave's dual contouring, one vertex a cell (for comparison).
    Dc1,
}

impl Mesher {
    /// The mesher it names.
    pub fn mesher(self) -> strata_mesh::Mesher {
        match self {
            Mesher::Mc => strata_mesh::Mesher::MarchingCubes,
            Mesher::Dc => strata_mesh::Mesher::DualContouring,
            Mesher::Rmt => strata_mesh::Mesher::ClusteredTetrahedra,
            Mesher::Mt => strata_mesh::Mesher::Tetrahedra,
            Mesher::Dc1 => strata_mesh::Mesher::SingleVertexDualContouring,
        }
    }
}

/// A progress bar on standard error, hidden when that is not a terminal.
pub(crate) fn bar(len: u64, what: &str) -> ProgressBar {
    let b = ProgressBar::new(len);
    b.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} {elapsed_precise} (eta {eta})")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    b.set_message(what.to_string());
    b
}

fn spinner(what: &str) -> ProgressBar {
    let b = ProgressBar::new_spinner();
    b.set_message(what.to_string());
    b.enable_steady_tick(Duration::from_millis(120));
    b
}

/// Converts the mesh at `mesh` into a scene of one layer at `out`. With `remove_islands`, the
/// pieces of the solid smaller than that many cells³ are removed before saving
/// ([`strata_volume::Volume::remove_islands`]). Returns a report.
pub fn convert(
    mesh: &Path,
    resolution: Resolution,
    fill: Fill,
    remove_islands: Option<f64>,
    out: &Path,
) -> Result<String> {
    check_input(mesh, &MESH_EXTENSIONS, "mesh file")?;
    check_output(out, &SCENE_EXTENSIONS, "scene file")?;
    if let Some(n) = remove_islands
        && !(n.is_finite() && n >= 0.0)
    {
        bail!("--remove-islands must be a finite number of cells³ >= 0, got {n}");
    }
    match resolution {
        Resolution::Cells(n) if n == 0 || n > MAX_CELLS => {
            bail!("--cells must be between 1 and {MAX_CELLS}, got {n}")
        }
        Resolution::CellSize(s) if !(s.is_finite() && s > 0.0) => {
            bail!("--cell-size must be a finite positive number, got {s}")
        }
        _ => {}
    }
    let t0 = Instant::now();
    let read = spinner(&format!("reading {}", mesh.display()));
    let tri = load_mesh(mesh);
    read.finish_and_clear();
    let tri = tri.map_err(|e| anyhow::anyhow!("{e}"))?;
    let plan = import::plan(&tri, resolution).map_err(|e| match e {
        ConvertError::TooFine { cell, cells } => {
            anyhow::anyhow!(
                "--cell-size {cell} puts {cells:.0} cells along the mesh's longest side (at most {MAX_CELLS})"
            )
        }
        e => anyhow::anyhow!("{}: {e}", mesh.display()),
    })?;
    let rule = match fill {
        Fill::EvenOdd => MeshRule::EvenOdd,
        Fill::Winding => MeshRule::NonZero,
    };
    let closed = import::is_closed(&tri);
    let read_ms = t0.elapsed().as_secs_f64() * 1e3;
    // The conversion on a worker, its progress (chunks done) on the bar.
    let control = Arc::new(EditControl::default());
    let settings = EditSettings { control: Some(control.clone()), ..Default::default() };
    let t1 = Instant::now();
    let progress = bar(0, "converting");
    let name = mesh.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh").to_string();
    let layer = std::thread::scope(|s| {
        let worker = s.spawn(|| import::convert(&tri, &plan, rule, &name, &settings));
        while !worker.is_finished() {
            let (done, total) = control.progress();
            progress.set_length(total.max(1));
            progress.set_position(done);
            std::thread::sleep(Duration::from_millis(50));
        }
        worker.join().expect("the conversion does not panic")
    });
    progress.finish_and_clear();
    let mut layer = layer.with_context(|| format!("converting {}", mesh.display()))?;
    let convert_ms = t1.elapsed().as_secs_f64() * 1e3;
    let t_islands = Instant::now();
    let islands = remove_islands
        .map(|n| layer.volume.remove_islands(n))
        .transpose()
        .with_context(|| format!("removing islands of {}", mesh.display()))?;
    let islands_ms = t_islands.elapsed().as_secs_f64() * 1e3;
    let mut scene = Scene::default();
    scene.layers[0] = layer;
    scene.view = View::framing(&scene.layers);
    let saving = spinner(&format!("writing {}", out.display()));
    let t2 = Instant::now();
    let repairs = file::save(&scene, out).with_context(|| format!("writing {}", out.display()));
    let save_ms = t2.elapsed().as_secs_f64() * 1e3;
    saving.finish_and_clear();
    let repairs = repairs?;
    let v = &scene.layers[0].volume;
    // The report's counts, read from each chunk's header (`crossing_stats` would walk every
    // line for a histogram this report does not print).
    let (mut list_chunks, mut solid_chunks, mut crossings) = (0u64, 0u64, 0u64);
    for (_, chunk) in v.chunks() {
        match chunk {
            Chunk::Solid => solid_chunks += 1,
            Chunk::Lists(l) => {
                list_chunks += 1;
                crossings += l.crossing_count() as u64;
            }
        }
    }
    let mut r = String::new();
    writeln!(r, "{}: {} vertices, {} triangles", mesh.display(), tri.vertices.len(), tri.triangles.len())?;
    writeln!(
        r,
        "  cells           {} units each, {:.0} along the longest side ({:?} fill{})",
        plan.cell,
        plan.cells_long,
        fill,
        if closed { "" } else { "; the mesh has holes: inside is decided line by line" }
    )?;
    writeln!(r, "  chunks          {list_chunks} lists, {solid_chunks} solid")?;
    writeln!(r, "  crossings       {crossings} (estimated {:.0})", plan.estimated_crossings)?;
    writeln!(r, "  memory          {}", bytes(v.memory().total()))?;
    writeln!(r, "  read + index    {read_ms:.0} ms")?;
    writeln!(r, "  convert         {convert_ms:.0} ms")?;
    if let Some(i) = &islands {
        writeln!(
            r,
            "  islands         removed {} (of {}: {} nodes, {} cells³) in {islands_ms:.0} ms",
            i.removed,
            i.removed + i.kept,
            i.removed_nodes,
            cells3(i.removed_volume)
        )?;
    }
    writeln!(r, "  check + save    {save_ms:.0} ms")?;
    for repair in &repairs.repairs {
        writeln!(r, "  repaired        {repair}")?;
    }
    writeln!(r, "  wrote           {}", out.display())?;
    Ok(r)
}

/// The names of the materials a volume's nodes use (`none` for an empty volume).
fn layer_materials(scene: &strata_editor::Scene, v: &strata_volume::Volume) -> String {
    if v.chunk_count() == 0 {
        return "none".into();
    }
    let mut ids = std::collections::BTreeSet::new();
    if v.chunks().count() > v.material_chunks().count() {
        ids.insert(0u8);
    }
    for (_, m) in v.material_chunks() {
        ids.extend(m.change_points().unwrap_or_default().into_iter().map(|p| p.1));
    }
    ids.iter()
        .map(|&i| scene.materials.get(i as usize).map_or(format!("#{i}"), |m| m.name.clone()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Which layers `export` writes: by index or by name, or every visible layer.
fn select_layers(scene: &Scene, layers: &[String]) -> Result<Vec<usize>> {
    if layers.is_empty() {
        return Ok((0..scene.layers.len()).filter(|&i| scene.layers[i].visible).collect());
    }
    let mut out = Vec::new();
    for l in layers {
        let i = match l.parse::<usize>() {
            Ok(i) if i < scene.layers.len() => i,
            Ok(i) => bail!("--layers: there is no layer {i} (the scene has {})", scene.layers.len()),
            Err(_) => match scene.layers.iter().position(|x| x.name == *l) {
                Some(i) => i,
                None => bail!("--layers: no layer is named {l:?}"),
            },
        };
        if !out.contains(&i) {
            out.push(i);
        }
    }
    Ok(out)
}

/// Loads a scene file, saying on standard error what was repaired.
fn load_scene(path: &Path) -> Result<file::Loaded> {
    check_input(path, &SCENE_EXTENSIONS, "scene file")?;
    let loaded = file::load(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    if !loaded.report.is_clean() {
        eprintln!("strata: {}: repaired while loading: {}", path.display(), loaded.report);
    }
    Ok(loaded)
}

/// The island threshold `export` uses for `out`: `--remove-islands N` as given, none with
/// `--keep-islands`, else [`DEFAULT_MIN_ISLAND_CELLS`] for an STL (a print: stray pieces are
/// printed as specks) and none for the other formats.
pub fn island_threshold(out: &Path, remove: Option<f32>, keep: bool) -> Option<f32> {
    match (remove, keep) {
        (Some(n), _) => Some(n),
        (None, true) => None,
        (None, false) => (extension(out).as_deref() == Some("stl")).then_some(DEFAULT_MIN_ISLAND_CELLS),
    }
}

/// A volume in cells³ for reports: whole numbers when large, two decimals when small.
fn cells3(v: f64) -> String {
    if v >= 100.0 { format!("{v:.0}") } else { format!("{v:.2}") }
}

/// Exports the chosen layers of the scene at `scene` as one mesh at `out`. Returns a report.
/// With `remove_islands`, the pieces of each layer's mesh enclosing less than that many cells³
/// are dropped first ([`strata_mesh::islands`]); with `simplify`, the welded mesh is then
/// simplified by meshoptimizer within that many cells, keeps the mesher's normals and is welded
/// (vertices equal in position, normal and material merged).
pub fn export(
    scene: &Path,
    out: &Path,
    mesher: Mesher,
    simplify: Option<f32>,
    remove_islands: Option<f32>,
    layers: &[String],
) -> Result<String> {
    check_input(scene, &SCENE_EXTENSIONS, "scene file")?;
    check_output(out, &EXPORT_EXTENSIONS, "mesh file")?;
    let mut s = load_scene(scene)?.scene;
    let chosen = select_layers(&s, layers)?;
    for (i, l) in s.layers.iter_mut().enumerate() {
        l.visible = chosen.contains(&i);
    }
    if let Some(n) = remove_islands
        && !(n.is_finite() && n >= 0.0)
    {
        bail!("--remove-islands must be a finite number of cells³ >= 0, got {n}");
    }
    let options = strata_mesh::MeshOptions { mesher: mesher.mesher(), simplify, remove_islands };
    let meshing = spinner(&format!("meshing {} layer(s) with {}", chosen.len(), options.mesher));
    let t = Instant::now();
    let palette = s.export_palette();
    // Creased shading normals, made chunk by chunk for plain marching cubes; dual contouring
    // and simplified meshes keep the mesher's (see `strata_mesh::mesh_volume_shaded`).
    let (mesh, islands) = Editor::new(s)
        .export_mesh_shaded(options, DEFAULT_CREASE_DEGREES)
        .map_err(|e| anyhow::anyhow!("{}: {e}", scene.display()))?;
    let mesh_ms = t.elapsed().as_secs_f64() * 1e3;
    meshing.finish_and_clear();
    if mesh.indices.is_empty() {
        bail!("{}: the chosen layers hold no surface to export", scene.display());
    }
    save_mesh_with(&mesh, out, &palette).map_err(|e| anyhow::anyhow!("{}: {e}", out.display()))?;
    let mut r = format!(
        "{}: {} layer(s), {} triangles, {} vertices ({}{}, {mesh_ms:.0} ms)\n",
        scene.display(),
        chosen.len(),
        mesh.triangle_count(),
        mesh.vertex_count(),
        options.mesher,
        simplify.map_or(String::new(), |e| format!(", simplified within {e} cells")),
    );
    if let Some(n) = remove_islands {
        writeln!(
            r,
            "  removed {} island{} ({} triangles, {} cells³) below {n} cells³; kept {} piece{}",
            islands.removed,
            if islands.removed == 1 { "" } else { "s" },
            islands.removed_triangles,
            cells3(islands.removed_volume),
            islands.kept,
            if islands.kept == 1 { "" } else { "s" },
        )?;
    }
    writeln!(r, "  wrote {}", out.display())?;
    Ok(r)
}

fn bytes(n: usize) -> String {
    if n >= 1 << 20 { format!("{:.2} MiB ({n} bytes)", n as f64 / (1 << 20) as f64) } else { format!("{n} bytes") }
}

/// Describes the scene at `path`: file version, layers, chunks by kind and level, crossings,
/// memory by category and bounds.
pub fn info(path: &Path) -> Result<String> {
    let loaded = load_scene(path)?;
    let s = &loaded.scene;
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let mut r = String::new();
    writeln!(r, "{}: scene file version {}, {} bytes", path.display(), loaded.version, size)?;
    writeln!(r, "  layers          {}", s.layers.len())?;
    for (i, l) in s.layers.iter().enumerate() {
        let v = &l.volume;
        let stats = v.crossing_stats();
        let mem = v.memory();
        let mut levels = std::collections::BTreeMap::new();
        for (_, chunk) in v.chunks() {
            if let Chunk::Lists(c) = chunk {
                *levels.entry(c.level().cells()).or_insert(0u64) += 1;
            }
        }
        let t = &l.transform;
        writeln!(
            r,
            "  [{i}] {:?}{}{}: materials {}, cell {} units, at {:.3}, turned {:.1}°",
            l.name,
            if l.visible { "" } else { " (hidden)" },
            if l.locked { " (locked)" } else { "" },
            layer_materials(s, &l.volume),
            t.scale,
            t.translation,
            t.rotation.to_axis_angle().1.to_degrees()
        )?;
        writeln!(
            r,
            "      chunks      {} lists, {} solid; by cells per side: {}",
            stats.list_chunks,
            stats.solid_chunks,
            if levels.is_empty() {
                "none".into()
            } else {
                levels.iter().map(|(c, n)| format!("{c}: {n}")).collect::<Vec<_>>().join(", ")
            }
        )?;
        writeln!(
            r,
            "      crossings   {} (x {}, y {}, z {}); longest chunk line {}",
            stats.total, stats.per_axis[0], stats.per_axis[1], stats.per_axis[2], stats.max_line
        )?;
        writeln!(
            r,
            "      memory      {}: positions {}, normals {}, headers {}, chunk map {}",
            bytes(mem.total()),
            mem.positions,
            mem.normals,
            mem.headers,
            mem.chunk_map
        )?;
        match v.chunk_bounds_grid() {
            Some((lo, hi)) => {
                let corners: Vec<DVec3> = (0..8)
                    .map(|k| {
                        t.to_world(DVec3::new(
                            if k & 1 == 0 { lo.x } else { hi.x },
                            if k & 2 == 0 { lo.y } else { hi.y },
                            if k & 4 == 0 { lo.z } else { hi.z },
                        ))
                    })
                    .collect();
                let (a, b) = corners.iter().fold((corners[0], corners[0]), |(a, b), &c| (a.min(c), b.max(c)));
                writeln!(r, "      bounds      {a:.3} to {b:.3} (world, whole chunks)")?;
                writeln!(r, "      volume      {:.3} units³", v.measured_volume(Axis::X) * t.scale.powi(3))?;
            }
            None => writeln!(r, "      bounds      empty")?,
        }
    }
    writeln!(r, "  materials       {}", s.materials.iter().map(|m| m.name.clone()).collect::<Vec<_>>().join(", "))?;
    if !loaded.report.is_clean() {
        writeln!(r, "  repaired        {}", loaded.report)?;
    }
    Ok(r)
}

/// Renders the scene at `scene` offscreen into the PNG at `out` (the studio's headless path,
/// [`strata_viewport::render_scene`], on a GPU or a software Vulkan driver; no GUI is linked).
/// Returns a report.
pub fn render(scene: &Path, out: &Path, size: (u32, u32), wireframe: bool) -> Result<String> {
    check_input(scene, &SCENE_EXTENSIONS, "scene file")?;
    check_output(out, &["png"], "PNG file")?;
    if size.0 == 0 || size.1 == 0 || size.0 > 8192 || size.1 > 8192 {
        bail!("--size must be between 1x1 and 8192x8192, got {}x{}", size.0, size.1);
    }
    let loaded = file::load(scene).with_context(|| format!("could not open {}", scene.display()))?;
    let repaired =
        if loaded.report.is_clean() { String::new() } else { format!("  repaired while loading: {}\n", loaded.report) };
    let adapter = strata_viewport::render_scene(loaded.scene, out, size, wireframe)?;
    Ok(format!(
        "{}: rendered {}x{} on {adapter}\n{repaired}  wrote {}\n",
        scene.display(),
        size.0,
        size.1,
        out.display()
    ))
}

/// Parses `WxH`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once('x').ok_or_else(|| format!("{s:?} is not WIDTHxHEIGHT"))?;
    let n = |v: &str| v.trim().parse::<u32>().map_err(|_| format!("{s:?} is not WIDTHxHEIGHT"));
    Ok((n(w)?, n(h)?))
}
