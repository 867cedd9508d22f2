//! `strata-studio`: the desktop editor. See `--help`.

/// The allocator: mimalloc, whose frees of memory another thread allocated never wait for a
/// lock that thread holds. With the system allocator, a frame that freed what a terrain worker at
/// the least priority had allocated could wait out that worker's time slice. It holds freed memory
/// longer: a CLI built with it peaked 75 % higher converting a mesh, and a mesh import here may
/// too (docs/BENCHMARKS.md, "Generation on every core").
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::path::PathBuf;

use clap::Parser;
use strata_studio::{Studio, default_scene, run_window, screenshot};

#[derive(Parser)]
#[command(about = "Strata Studio: sculpt volumes with the mouse or a pen")]
struct Cli {
    /// Render one frame headless into this PNG and exit (opens no window).
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// A scene file to open (or to render with --screenshot).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Screenshot size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x800")]
    size: String,
    /// Draw the wireframe in the screenshot.
    #[arg(long)]
    wireframe: bool,
    /// With --screenshot: render terrain of the default recipe with this seed instead of a scene.
    #[arg(long)]
    terrain: Option<u32>,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    if let Some(out) = cli.screenshot {
        let (w, h) = cli
            .size
            .split_once('x')
            .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
            .ok_or_else(|| anyhow::anyhow!("--size must look like 1280x800"))?;
        let adapter = match cli.terrain {
            Some(seed) => strata_studio::terrain_screenshot(seed, &out, (w, h))?,
            None => screenshot(cli.scene.as_deref(), &out, (w, h), cli.wireframe)?,
        };
        eprintln!("wrote {} ({w}×{h}, {adapter})", out.display());
        return Ok(());
    }
    let mut studio = match &cli.scene {
        Some(path) => {
            let loaded = strata_editor::file::load(path)
                .map_err(|e| anyhow::anyhow!("could not open {}: {e}", path.display()))?;
            let mut s = Studio::new(loaded.scene);
            if !loaded.report.is_clean() {
                s.message = format!("Opened {} with repairs: {}", path.display(), loaded.report);
            }
            s.path = Some(path.clone());
            s
        }
        None => Studio::new(default_scene()),
    };
    studio.editor.finish_meshing();
    run_window(studio)
}
