//! `strata terrain`: a world from a recipe or a seed, as a world database, a scene or a mesh.

use std::fmt::Write as _;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use glam::I64Vec3;
use strata_editor::file;
use strata_editor::{Editor, Layer, Scene, View};
use strata_mesh::export::save_mesh_with;
use strata_mesh::normals::{DEFAULT_CREASE_DEGREES, crease_normals};
use strata_terrain::{Recipe, TerrainField, World, WorldSettings, generate_region};

use crate::commands::{EXPORT_EXTENSIONS, SCENE_EXTENSIONS, bar};
use crate::paths::{check_input, check_output};

/// World files written by `terrain`.
pub const WORLD_EXTENSIONS: [&str; 1] = ["world"];

/// Largest box side `terrain` generates into a scene or mesh (cells).
pub const MAX_SIDE: u32 = 8192;

/// Parses `XxYxZ` (cells), each side 1 to [`MAX_SIDE`].
pub fn parse_box(s: &str) -> Result<[u32; 3], String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let [x, y, z] = parts.as_slice() else { return Err(format!("expected XxYxZ cells, got `{s}`")) };
    let side = |t: &str| -> Result<u32, String> {
        let v: u32 = t.trim().parse().map_err(|_| format!("`{t}` is not a whole number of cells"))?;
        if v == 0 || v > MAX_SIDE { Err(format!("a side of {v} cells is outside 1..={MAX_SIDE}")) } else { Ok(v) }
    };
    Ok([side(x)?, side(y)?, side(z)?])
}

/// Where the recipe comes from.
#[derive(Debug, Clone)]
pub enum RecipeSource<'a> {
    /// A JSON recipe file.
    File(&'a Path),
    /// The default recipe with this seed.
    Seed(u32),
}

/// Reads or builds the recipe.
pub fn recipe(source: &RecipeSource<'_>) -> Result<Recipe> {
    match source {
        RecipeSource::Seed(s) => Ok(Recipe::with_seed(*s)),
        RecipeSource::File(p) => {
            check_input(p, &["json"], "recipe file")?;
            // A recipe is a few hundred bytes of JSON; a megabyte is surely not one.
            let bytes = strata_files::read_limited(p, 1 << 20).with_context(|| format!("reading {}", p.display()))?;
            let text = String::from_utf8(bytes).map_err(|_| anyhow::anyhow!("{}: not UTF-8 text", p.display()))?;
            Recipe::from_json(&text).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))
        }
    }
}

/// Generates the terrain of `source` into `out`: a `.world` database (the endless world: its
/// recipe, no chunk yet), a `.strata` scene or a mesh (`.glb`, `.obj`, `.stl`, `.ply`) of the
/// box of `size` cells centred on the origin horizontally, from `-size.y / 2` up.
pub fn terrain(source: &RecipeSource<'_>, size: [u32; 3], out: &Path) -> Result<String> {
    let ext = out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    let mut kinds: Vec<&str> = WORLD_EXTENSIONS.to_vec();
    kinds.extend(SCENE_EXTENSIONS);
    kinds.extend(EXPORT_EXTENSIONS);
    check_output(out, &kinds, "world, scene or mesh file")?;
    let recipe = recipe(source)?;
    let mut r = String::new();
    if WORLD_EXTENSIONS.contains(&ext.as_str()) {
        if out.exists() {
            bail!("{} already exists: a world is never overwritten (open it in the studio)", out.display());
        }
        let world = World::create(out, &recipe, WorldSettings { threads: 1, ..WorldSettings::default() })
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        drop(world);
        writeln!(
            r,
            "{}: a new endless world from seed {} (open it in the studio's terrain mode)",
            out.display(),
            recipe.seed
        )?;
        return Ok(r);
    }
    let field = TerrainField::new(&recipe).map_err(|e| anyhow::anyhow!("{e}"))?;
    let half = |v: u32| (v / 2) as i64;
    let lo = I64Vec3::new(-half(size[0]), -half(size[1]), -half(size[2]));
    let hi = lo + I64Vec3::new(size[0] as i64, size[1] as i64, size[2] as i64);
    let chunks = strata_terrain::Clipped::new(&field, lo, hi).expect("an ordered box").keys().len() as u64;
    let done = AtomicU64::new(0);
    let progress = bar(chunks, "generating");
    let t = Instant::now();
    let volume = std::thread::scope(|s| {
        let worker = s.spawn(|| generate_region(&field, lo, hi, &done));
        while !worker.is_finished() {
            progress.set_position(done.load(Ordering::Relaxed));
            std::thread::sleep(Duration::from_millis(50));
        }
        worker.join().expect("generation does not panic")
    })
    .expect("an ordered box");
    progress.finish_and_clear();
    let gen_ms = t.elapsed().as_secs_f64() * 1e3;
    let stats = volume.crossing_stats();
    writeln!(
        r,
        "terrain of seed {} in {}x{}x{} cells from {lo}: {} chunks generated in {gen_ms:.0} ms ({} lists, {} solid)",
        recipe.seed, size[0], size[1], size[2], chunks, stats.list_chunks, stats.solid_chunks
    )?;
    let mut scene = Scene::default();
    let mut layer = Layer::new("terrain");
    layer.volume = volume;
    scene.layers[0] = layer;
    scene.view = View::framing(&scene.layers);
    if SCENE_EXTENSIONS.contains(&ext.as_str()) {
        file::save(&scene, out).with_context(|| format!("writing {}", out.display()))?;
    } else {
        let palette = scene.export_palette();
        let t = Instant::now();
        let mesh = Editor::new(scene).export_mesh(strata_mesh::MeshOptions::default())?;
        let mesh = crease_normals(&mesh, DEFAULT_CREASE_DEGREES);
        if mesh.indices.is_empty() {
            bail!("the box holds no terrain surface: move it or make it taller");
        }
        save_mesh_with(&mesh, out, &palette).map_err(|e| anyhow::anyhow!("{}: {e}", out.display()))?;
        writeln!(
            r,
            "  meshed          {} triangles in {:.0} ms",
            mesh.triangle_count(),
            t.elapsed().as_secs_f64() * 1e3
        )?;
    }
    writeln!(r, "  wrote           {}", out.display())?;
    Ok(r)
}
