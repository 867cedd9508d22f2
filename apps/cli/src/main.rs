//! `strata`: the Strata command line.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Parser, Subcommand};
use strata::commands::{self, Fill, Mesher, Resolution};

#[derive(Parser)]
#[command(
    version,
    about = "Strata: volumetric sculpting on per-grid-line crossing lists",
    after_help = "Examples:
  strata convert bunny.ply --cells 512 -o bunny.strata
  strata info bunny.strata
  strata export bunny.strata -o bunny.glb --mesher dc
  strata render bunny.strata -o bunny.png --size 1280x800
  strata demo --out demo.glb --scene demo.strata
  strata terrain --seed 7 --size 256x192x256 -o valley.glb

Every path and argument is checked before any work starts; errors are one line on standard
error with a non-zero exit code, and nothing half-written is left behind."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Args)]
#[group(required = true, multiple = false)]
struct Size {
    /// Cells along the mesh's longest side.
    #[arg(long)]
    cells: Option<u32>,
    /// The size of a cell, in the mesh's units.
    #[arg(long, allow_negative_numbers = true)]
    cell_size: Option<f64>,
}

#[derive(Subcommand)]
enum Command {
    /// Convert a triangle mesh (PLY, OBJ, STL, glTF, GLB) into an editable scene of one layer.
    #[command(after_help = "Examples:
  strata convert bunny.ply --cells 512 -o bunny.strata
  strata convert part.stl --cell-size 0.25 --fill winding -o part.strata
  strata convert scan.ply --cells 256 --remove-islands 8 -o scan.strata")]
    Convert {
        /// The mesh file.
        mesh: PathBuf,
        #[command(flatten)]
        size: Size,
        /// How inside is decided: even-odd crossings (also for meshes with holes) or the winding
        /// number (uses the triangles' orientation).
        #[arg(long, value_enum, default_value_t = Fill::EvenOdd)]
        fill: Fill,
        /// The scene file to write (.strata).
        #[arg(short, long)]
        output: PathBuf,
        /// Remove the pieces of the solid smaller than this many cells³ (nodes joined along grid
        /// edges; the largest piece is always kept). Default: keep every piece.
        #[arg(long, value_name = "CELLS", allow_negative_numbers = true)]
        remove_islands: Option<f64>,
    },
    /// Export a scene's layers as one mesh (.glb, .obj, .stl, .ply).
    #[command(after_help = "Examples:
  strata export scene.strata -o scene.glb
  strata export scene.strata -o body.stl --mesher dc --layers Body,2
  strata export scene.strata -o game.glb --mesher rmt
  strata export scene.strata -o small.glb --simplify 0.2
  strata export scene.strata -o print.stl --remove-islands 50
  strata export scene.strata -o all.stl --keep-islands")]
    Export {
        /// The scene file.
        scene: PathBuf,
        /// The mesh file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// Marching cubes (smooth), dual contouring (sharp edges) or regularised tetrahedra
        /// (fewer, regular triangles).
        #[arg(long, value_enum, default_value_t = Mesher::Mc)]
        mesher: Mesher,
        /// Simplify the mesh (meshoptimizer) as far as it stays within this many cells of the
        /// surface.
        #[arg(long, value_name = "CELLS", allow_negative_numbers = true)]
        simplify: Option<f32>,
        /// Layers to export, by index or name, comma-separated (default: the visible ones).
        #[arg(long, value_delimiter = ',')]
        layers: Vec<String>,
        /// Remove the pieces of each layer's mesh that enclose less than this many cells³ (stray
        /// islands); the largest piece is always kept. Default: 8 for .stl, off otherwise.
        #[arg(long, value_name = "CELLS", allow_negative_numbers = true, conflicts_with = "keep_islands")]
        remove_islands: Option<f32>,
        /// Keep every piece, also in an .stl.
        #[arg(long)]
        keep_islands: bool,
    },
    /// Describe a scene: file version, layers, chunks by kind and level, crossings, memory,
    /// bounds.
    #[command(after_help = "Example:\n  strata info scene.strata")]
    Info {
        /// The scene file.
        scene: PathBuf,
    },
    /// Render a scene offscreen into a PNG (needs a GPU or a software Vulkan driver).
    #[command(after_help = "Example:\n  strata render scene.strata -o shot.png --size 1280x800 --wireframe")]
    Render {
        /// The scene file.
        scene: PathBuf,
        /// The PNG to write.
        #[arg(short, long)]
        output: PathBuf,
        /// Image size, WIDTHxHEIGHT.
        #[arg(long, default_value = "1280x800", value_parser = commands::parse_size)]
        size: (u32, u32),
        /// Draw the wireframe.
        #[arg(long)]
        wireframe: bool,
    },
    /// Procedural terrain from a recipe or a seed: a new endless world (.world, for the studio's
    /// terrain mode), or a box of it as a scene (.strata) or a mesh (.glb, .obj, .stl, .ply).
    #[command(after_help = "Examples:
  strata terrain --seed 7 -o valley.world
  strata terrain --seed 7 --size 256x192x256 -o valley.glb
  strata terrain --recipe islands.json --size 512x256x512 -o islands.strata

A recipe is JSON; every field is optional (the defaults are printed by --print-recipe):
  {\"seed\": 7, \"heights\": {\"amplitude\": 60, \"ridged\": 0.5}, \"caves\": {\"strength\": 0}}")]
    Terrain {
        /// A JSON recipe file.
        #[arg(long, conflicts_with = "seed")]
        recipe: Option<PathBuf>,
        /// The default recipe with this seed. One of --seed and --recipe is required (--print-recipe
        /// alone prints the default recipe, seed 1).
        #[arg(long)]
        seed: Option<u32>,
        /// The box of a scene or mesh, XxYxZ cells (centred on the origin).
        #[arg(long, default_value = "256x192x256", value_parser = strata::terrain::parse_box)]
        size: [u32; 3],
        /// The world, scene or mesh to write.
        #[arg(short, long, required_unless_present = "print_recipe")]
        output: Option<PathBuf>,
        /// Print the recipe (the default one, or the seed's or file's) as JSON and stop.
        #[arg(long)]
        print_recipe: bool,
    },
    /// Host rooms where several people sculpt one scene together (the studio's File > Host
    /// session and Join session connect to it). Runs until stopped.
    #[command(after_help = "Examples:
  strata serve --listen 0.0.0.0:7878 --store rooms.redb
  strata serve --store postgres://strata@db.example:5432/strata

Rooms are kept in an embedded redb file by default, or in PostgreSQL when --store is a
postgres:// URL (several servers may then serve different rooms against one database). Every
operation a client saw acknowledged is on disk: a server killed and restarted loses none.")]
    Serve {
        /// The address to listen on (port 0: any free port, printed at start).
        #[arg(long, default_value = "127.0.0.1:7878")]
        listen: String,
        /// Where rooms are kept: a redb file, or a postgres:// URL.
        #[arg(long, default_value = "strata-rooms.redb")]
        store: String,
    },
    /// Sculpt a small scene from analytic brushes and print its statistics.
    #[command(after_help = "Example:\n  strata demo --out demo.glb --out demo.stl --scene demo.strata")]
    Demo {
        /// Size multiplier (1: a body of radius 24 cells).
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
        /// Write the marching-cubes mesh here (repeatable; .glb, .obj, .stl or .ply).
        #[arg(long = "out")]
        outputs: Vec<PathBuf>,
        /// Also save the sculpture as a scene file for the studio (`strata-studio --scene`).
        #[arg(long)]
        scene: Option<PathBuf>,
    },
}

fn run(command: Command) -> Result<String> {
    match command {
        Command::Convert { mesh, size, fill, output, remove_islands } => {
            let resolution = match (size.cells, size.cell_size) {
                (Some(n), _) => Resolution::Cells(n),
                (None, Some(s)) => Resolution::CellSize(s),
                (None, None) => unreachable!("clap requires one of them"),
            };
            commands::convert(&mesh, resolution, fill, remove_islands, &output)
        }
        Command::Export { scene, output, mesher, simplify, layers, remove_islands, keep_islands } => {
            let islands = commands::island_threshold(&output, remove_islands, keep_islands);
            commands::export(&scene, &output, mesher, simplify, islands, &layers)
        }
        Command::Info { scene } => commands::info(&scene),
        Command::Serve { listen, store } => strata::serve::serve(&listen, &store),
        Command::Render { scene, output, size, wireframe } => commands::render(&scene, &output, size, wireframe),
        Command::Demo { scale, outputs, scene } => strata::demo(scale, &outputs, scene.as_deref()),
        Command::Terrain { recipe, seed, size, output, print_recipe } => {
            use strata::terrain::RecipeSource;
            let source = match (&recipe, seed) {
                (Some(p), _) => RecipeSource::File(p),
                (None, Some(s)) => RecipeSource::Seed(s),
                (None, None) if print_recipe => RecipeSource::Seed(strata_terrain::Recipe::default().seed),
                (None, None) => anyhow::bail!(
                    "terrain needs --seed N or --recipe FILE to say which terrain to make (--seed 1 is the default recipe)"
                ),
            };
            if print_recipe {
                return Ok(strata::terrain::recipe(&source)?.to_json() + "\n");
            }
            let output = output.expect("clap requires --output without --print-recipe");
            strata::terrain::terrain(&source, size, &output)
        }
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // Help asked for, or shown because no command was given (`strata` alone: the usage and
        // the commands on standard error, exit code 2).
        Err(e)
            if matches!(
                e.kind(),
                clap::error::ErrorKind::DisplayHelp
                    | clap::error::ErrorKind::DisplayVersion
                    | clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) =>
        {
            e.exit()
        }
        Err(e) => {
            // clap's own message, on one line (its usage hint is what --help shows).
            let text = e.to_string();
            let message: Vec<&str> = text
                .lines()
                .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
                .flat_map(str::split_whitespace)
                .collect();
            let message = message.join(" ");
            eprintln!("strata: error: {} (see strata --help)", message.trim_start_matches("error: "));
            return ExitCode::from(2);
        }
    };
    if matches!(cli.command, Command::Render { .. }) && strata::runtime::needs_runtime_dir() {
        // The render runs in a child that has a private XDG_RUNTIME_DIR (see `runtime`).
        return match strata::runtime::rerun_with_runtime_dir() {
            Ok(code) => code,
            Err(e) => {
                eprintln!("strata: error: {}", format!("{e:#}").split_whitespace().collect::<Vec<_>>().join(" "));
                ExitCode::FAILURE
            }
        };
    }
    match run(cli.command) {
        Ok(report) => {
            print!("{report}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            // One line: the error and its causes, joined (a parser's message may span lines).
            let line = format!("{e:#}").split_whitespace().collect::<Vec<_>>().join(" ");
            eprintln!("strata: error: {line}");
            ExitCode::FAILURE
        }
    }
}
