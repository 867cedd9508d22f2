//! `strata`: the Strata command line.

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(version, about = "Strata: volumetric sculpting on per-grid-line crossing lists")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Sculpt a small scene from analytic brushes and print its statistics.
    Demo {
        /// Size multiplier (1: a body of radius 24 cells).
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
        /// Write the marching-cubes mesh here (repeatable; .glb, .obj, .stl or .ply).
        #[arg(long = "out")]
        outputs: Vec<std::path::PathBuf>,
        /// Also save the sculpture as a scene file for the studio (`strata-studio --scene`).
        #[arg(long)]
        scene: Option<std::path::PathBuf>,
    },
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::Demo { scale, outputs, scene } => print!("{}", strata::demo(scale, &outputs, scene.as_deref())?),
    }
    Ok(())
}
