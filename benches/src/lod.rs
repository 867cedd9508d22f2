//! Table 7 — level of detail: a large model stored fine and meshed as seen from near, middle
//! and far (triangles, mesh memory, meshing time, open edges) against full resolution; the cost
//! of raising and lowering one chunk; the memory of detail raised only where it was sculpted
//! against the same model fine everywhere; and whole frames while sculpting with level of detail
//! on, one thread.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use glam::{DQuat, DVec3};
use serde::Serialize;
use strata_editor::{Buttons, Editor, Layer, LayerTransform, LodView, Scene, ToolKind, ToolPose, lod_levels};
use strata_mesh::{Mesh, checks};
use strata_volume::brush::{Cuboid, MeshBrush, MeshRule, Sphere};
use strata_volume::{ChunkKey, CsgOp, EditSettings, Level, Volume};

use crate::SplitMix64;

/// Pixels per radian of the views: a 1,080-pixel-high viewport with a 45° field of view.
pub const PIXELS_PER_RADIAN: f64 = 1080.0 / (std::f64::consts::PI / 4.0);
/// The largest cell a view may show (pixels).
pub const PIXEL_ERROR: f64 = 1.0;
/// The views: how many pixels the model's diagonal spans on the 1,080-pixel-high viewport.
pub const VIEWS: [(&str, f64); 3] = [("near", 1080.0), ("middle", 360.0), ("far", 108.0)];

/// One model seen from one distance.
#[derive(Clone, Debug, Serialize)]
pub struct ViewRow {
    /// The model.
    pub model: String,
    /// near, middle, far or full.
    pub view: String,
    /// Pixels the model's diagonal spans on screen (0: full resolution).
    pub pixels: f64,
    /// Chunks meshed at each level (index: level).
    pub chunks_at: [usize; 3],
    /// Triangles of the welded mesh.
    pub triangles: usize,
    /// Bytes of positions, normals and indices.
    pub mesh_bytes: usize,
    /// Meshing every chunk, all cores (ms).
    pub mesh_ms: f64,
    /// Edges used by one triangle only.
    pub open_edges: usize,
}

/// Raising or lowering one chunk.
#[derive(Clone, Debug, Serialize)]
pub struct LevelChangeRow {
    /// From level to level.
    pub change: String,
    /// Chunks changed.
    pub chunks: usize,
    /// Mean per chunk (ms).
    pub ms_per_chunk: f64,
}

/// Memory of detail where it was sculpted against everywhere.
#[derive(Clone, Debug, Serialize)]
pub struct DetailMemoryRow {
    /// What was stored.
    pub layout: String,
    /// List chunks at each level.
    pub chunks_at: [u32; 3],
    /// Bytes of the volume.
    pub bytes: usize,
}

/// Everything Table 7 measured.
#[derive(Clone, Debug, Serialize)]
pub struct LodResults {
    /// Resolution of the models (cells along the longest side at the finest level).
    pub resolution: u32,
    /// The views.
    pub views: Vec<ViewRow>,
    /// Level changes.
    pub changes: Vec<LevelChangeRow>,
    /// Memory.
    pub memory: Vec<DetailMemoryRow>,
    /// Whole frames while sculpting with level of detail on (clay, radius 10 cells of the
    /// chunks stroked, one thread): (what was stroked, frames, mean ms, p99 ms).
    pub sculpt: Vec<(String, usize, f64, f64)>,
}

/// `mesh` converted into a volume stored at the finest level, `res` finest cells along its
/// longest side.
fn fine_model(vertices: &[DVec3], triangles: &[[u32; 3]], res: u32) -> anyhow::Result<Volume> {
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for v in vertices {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    // Grid units: `res` finest cells = res / 4 base cells, plus two cells of margin.
    let scale = res as f64 / 4.0 / (hi - lo).max_element();
    let verts: Vec<DVec3> = vertices.iter().map(|&v| (v - lo) * scale + DVec3::splat(2.0)).collect();
    let brush = MeshBrush::new(&verts, triangles, MeshRule::EvenOdd)?;
    let mut volume = Volume::with_level(Level::FINEST);
    volume.apply(CsgOp::Add, &brush, &EditSettings::default())?;
    Ok(volume)
}

/// A large CSG scene stored at the finest level: a slab `res × res × res/8` finest cells with
/// 300 balls added on it and 100 cut into it.
fn csg_scene(res: u32, seed: u64) -> anyhow::Result<Volume> {
    let side = res as f64 / 4.0;
    let mut volume = Volume::with_level(Level::FINEST);
    let h = side / 16.0;
    volume.add(&Cuboid::new(
        DVec3::new(side / 2.0, side / 2.0, h),
        DVec3::new(side / 2.0 - 1.0, side / 2.0 - 1.0, h - 1.0),
    )?)?;
    let mut rng = SplitMix64::new(seed);
    for i in 0..400 {
        let c = DVec3::new(rng.unit() * side, rng.unit() * side, 2.0 * h);
        let r = (0.01 + 0.03 * rng.unit()) * side;
        let s = Sphere::new(c, r)?;
        if i % 4 == 3 {
            volume.subtract(&s)?;
        } else {
            volume.add(&s)?;
        }
    }
    Ok(volume)
}

fn mesh_bytes(m: &Mesh) -> usize {
    m.positions.len() * 12 + m.normals.len() * 12 + m.indices.len() * 4
}

fn open_edges(m: &Mesh) -> usize {
    checks::manifold_report(m).boundary
}

/// The rows of one model: full resolution and three views along a diagonal.
fn views(name: &str, volume: &Volume) -> Vec<ViewRow> {
    let (lo, hi) = volume.chunk_bounds_grid().expect("a model");
    let centre = (lo + hi) / 2.0;
    let diagonal = (hi - lo).length();
    let mut rows = Vec::new();
    let t = Instant::now();
    let full = strata_mesh::mesh_volume_with(volume, strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    let full_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut at = [0usize; 3];
    for (k, _) in volume.chunks() {
        if let Some(l) = volume.stored_level(k) {
            // The models here hold no chunk coarser than the base level.
            at[l.get().max(0) as usize] += 1;
        }
    }
    rows.push(ViewRow {
        model: name.into(),
        view: "full resolution".into(),
        pixels: 0.0,
        chunks_at: at,
        triangles: full.indices.len() / 3,
        mesh_bytes: mesh_bytes(&full),
        mesh_ms: full_ms,
        open_edges: open_edges(&full),
    });
    for (view, px) in VIEWS {
        let eye = centre + DVec3::new(1.0, 0.6, 0.8).normalize() * (diagonal * PIXELS_PER_RADIAN / px);
        let lod = LodView { eye, pixels_per_radian: PIXELS_PER_RADIAN, pixel_error: PIXEL_ERROR };
        let caps = lod_levels(volume, &LayerTransform::default(), &lod, &HashMap::new());
        let cap = |k: ChunkKey| caps.get(&k).copied().unwrap_or(Level::FINEST);
        let t = Instant::now();
        let m = strata_mesh::mesh_volume_reported(volume, strata_mesh::MeshOptions::default(), Some(&cap))
            .expect("marching cubes meshes every volume")
            .0;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let mut at = [0usize; 3];
        for (k, _) in volume.chunks() {
            if let Some(l) = volume.stored_level(k) {
                at[cap(k).min(l).get().max(0) as usize] += 1;
            }
        }
        rows.push(ViewRow {
            model: name.into(),
            view: view.into(),
            pixels: px,
            chunks_at: at,
            triangles: m.indices.len() / 3,
            mesh_bytes: mesh_bytes(&m),
            mesh_ms: ms,
            open_edges: open_edges(&m),
        });
    }
    rows
}

/// Raising every surface chunk of a base-level copy of `volume` one level at a time, then
/// lowering them again (at most `limit` chunks).
fn level_changes(volume: &Volume, limit: usize) -> Vec<LevelChangeRow> {
    let mut v = volume.clone();
    let mut keys: Vec<ChunkKey> = v.chunks().filter(|(k, _)| v.stored_level(*k).is_some()).map(|(k, _)| k).collect();
    keys.sort();
    keys.truncate(limit);
    let _ = v.set_chunk_levels(&keys, Level::BASE);
    let mut rows = Vec::new();
    for (from, to) in [(0i8, 1i8), (1, 2), (2, 1), (1, 0)] {
        let target = Level::new(to).expect("a level");
        let t = Instant::now();
        for &k in &keys {
            let _ = v.set_chunk_level(k, target);
        }
        let ms = t.elapsed().as_secs_f64() * 1e3;
        rows.push(LevelChangeRow {
            change: format!("{}³ → {}³", 16 << from, 16 << to),
            chunks: keys.len(),
            ms_per_chunk: ms / keys.len().max(1) as f64,
        });
    }
    rows
}

/// The model at the base level with the chunks within a ball a fifth of its size raised to the
/// finest level (where a user sculpted detail), against the model at the finest level everywhere.
fn detail_memory(volume: &Volume) -> Vec<DetailMemoryRow> {
    let (lo, hi) = volume.chunk_bounds_grid().expect("a model");
    let keys: Vec<ChunkKey> =
        volume.chunks().filter(|(k, _)| volume.stored_level(*k).is_some()).map(|(k, _)| k).collect();
    let base = at_base(volume);
    // The list chunks a ball a fifth of the model's size (at least a chunk and a half) reaches.
    let c = lo + (hi - lo) * DVec3::new(0.7, 0.7, 0.6);
    let r = ((hi - lo).max_element() / 5.0).max(24.0);
    let near: Vec<ChunkKey> = keys
        .iter()
        .copied()
        .filter(|k| {
            let min = k.origin_grid().as_dvec3();
            (c.clamp(min, min + DVec3::splat(16.0)) - c).length() <= r
        })
        .collect();
    let mut detailed = base.clone();
    let _ = detailed.set_chunk_levels(&near, Level::FINEST);
    let row = |name: &str, v: &Volume| DetailMemoryRow {
        layout: name.into(),
        chunks_at: {
            // Levels 0–2 (the models hold no coarser chunk).
            let c = v.level_counts();
            [c[Level::BASE.index()], c[Level::BASE.index() + 1], c[Level::BASE.index() + 2]]
        },
        bytes: v.memory().total(),
    };
    vec![
        row("base level everywhere (16³ cells a chunk)", &base),
        row("detail raised where sculpted (a ball a fifth of the model)", &detailed),
        row("finest level everywhere (64³ cells a chunk)", volume),
    ]
}

/// `volume` with every chunk lowered to the base level, as a volume whose base (the level of
/// new chunks) is 16³.
fn at_base(volume: &Volume) -> Volume {
    let mut v = volume.clone();
    let keys: Vec<ChunkKey> = v.chunks().map(|(k, _)| k).collect();
    let _ = v.set_chunk_levels(&keys, Level::BASE);
    let chunks: Vec<(ChunkKey, strata_volume::Chunk)> = v.chunks().map(|(k, c)| (k, c.clone())).collect();
    Volume::from_chunks(Level::BASE, v.cell_size(), chunks).expect("a valid cell size")
}

/// Whole frames of the editor (one thread) while a clay stroke of radius 10 cells of the model's
/// chunks runs over the model with level of detail on, the camera at the near view.
fn sculpt_frames(volume: &Volume, frames: usize) -> (usize, f64, f64) {
    let level = volume.chunks().find_map(|(k, _)| volume.stored_level(k)).unwrap_or(Level::BASE);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    pool.install(|| {
        let mut layer = Layer::new("model");
        layer.volume = volume.clone();
        let scene = Scene { layers: vec![layer], ..Default::default() };
        let mut e = Editor::new(scene);
        e.finish_meshing();
        let (lo, hi) = volume.chunk_bounds_grid().expect("a model");
        let centre = (lo + hi) / 2.0;
        let diagonal = (hi - lo).length();
        // The near view: the model fills the viewport, the sculpted part at full resolution.
        let eye = centre + DVec3::new(1.0, 0.6, 0.8).normalize() * (diagonal * PIXELS_PER_RADIAN / VIEWS[0].1);
        e.set_view(Some(LodView { eye, pixels_per_radian: PIXELS_PER_RADIAN, pixel_error: PIXEL_ERROR }));
        e.finish_meshing();
        e.tool.kind = ToolKind::Clay;
        e.tool.radius = 10.0 * volume.cell_size() * level.spacing();
        e.tool.field_strength = 0.5;
        // A stroke across the model's top, on its surface.
        let mut times = Vec::with_capacity(frames);
        let down = Buttons { primary: true, secondary: false };
        for i in 0..frames {
            let s = i as f64 / frames.max(1) as f64;
            let x = lo.x + (hi.x - lo.x) * (0.2 + 0.6 * s);
            let from = DVec3::new(x, centre.y, hi.z + 4.0);
            let p = e.pick(from, -DVec3::Z, 1e6).map(|h| h.point).unwrap_or(DVec3::new(x, centre.y, centre.z));
            let pose = ToolPose {
                position: p,
                orientation: DQuat::IDENTITY,
                pressure: 1.0,
                buttons: down,
                ..ToolPose::default()
            };
            let t = Instant::now();
            let _ = e.frame(&pose, Duration::from_millis(8));
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let _ = e.frame(&ToolPose::at(DVec3::ZERO, false), Duration::from_millis(8));
        if std::env::var("STRATA_LOD_TIMES").is_ok() {
            eprintln!("frame times: {times:?}");
        }
        let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
        let p99 = crate::quantile(&times, 0.99);
        (times.len(), mean, p99)
    })
}

/// Runs Table 7 on the mesh (`vertices`, `triangles`) converted at `res` finest cells, and a CSG
/// scene of the same size.
pub fn run(
    vertices: &[DVec3],
    triangles: &[[u32; 3]],
    res: u32,
    frames: usize,
    seed: u64,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<LodResults> {
    progress(&format!("table 7: converting the mesh at {res} finest cells"));
    let model = fine_model(vertices, triangles, res)?;
    progress("table 7: views of the mesh");
    let mut rows = views("bunny", &model);
    progress("table 7: the CSG scene");
    let scene = csg_scene(res, seed)?;
    rows.extend(views("CSG slab with 400 balls", &scene));
    progress("table 7: level changes");
    let changes = level_changes(&model, 200);
    progress("table 7: memory of detail where sculpted");
    let memory = detail_memory(&model);
    progress("table 7: sculpting with level of detail");
    let mut sculpt = Vec::new();
    let base = at_base(&model);
    for (name, v) in [("16³ chunks (the base level)", &base), ("64³ chunks (the finest level)", &model)] {
        let (n, mean, p99) = sculpt_frames(v, frames);
        sculpt.push((name.to_string(), n, mean, p99));
    }
    Ok(LodResults { resolution: res, views: rows, changes, memory, sculpt })
}
