//! `strata-bench`: prints benchmark tables as markdown.
//!
//! `cargo run --release -p strata-bench -- table1` replays the paper's Table 1 workload.

use anyhow::Result;
use clap::{Parser, Subcommand};
use strata_bench::{replay, replay_frames, table1_instructions};

#[derive(Parser)]
#[command(about = "Strata benchmark suite: prints markdown tables")]
struct Cli {
    #[command(subcommand)]
    suite: Suite,
}

#[derive(Subcommand)]
enum Suite {
    /// Table 1: 1000 random sphere draw/erase instructions on a 160³ canvas, per radius.
    Table1 {
        /// Instructions per radius.
        #[arg(long, default_value_t = 1000)]
        count: usize,
        /// Radii to run.
        #[arg(long, value_delimiter = ',', default_values_t = vec![5.0, 10.0, 15.0, 20.0, 40.0])]
        radii: Vec<f64>,
        /// Workload seed.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
    },
    /// Table 2 (marching cubes): whole-frame time of edit + voxel blocks + remesh, per radius.
    FrameMc {
        /// Instructions per radius.
        #[arg(long, default_value_t = 1000)]
        count: usize,
        /// Radii to run.
        #[arg(long, value_delimiter = ',', default_values_t = vec![5.0, 10.0, 15.0, 20.0])]
        radii: Vec<f64>,
        /// Workload seed.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
    },
}

fn main() -> Result<()> {
    match Cli::parse().suite {
        Suite::Table1 { count, radii, seed } => table1(count, &radii, seed),
        Suite::FrameMc { count, radii, seed } => frame_mc(count, &radii, seed),
    }
    Ok(())
}

fn table1(count: usize, radii: &[f64], seed: u64) {
    println!(
        "| radius | Time_d 1 thread (ms) | Time_v 1 thread (ms) | Time_d rayon (ms) | Time_v rayon (ms) | chunks changed / edit | crossings | B/crossing | B/crossing w/o normals | longest chunk line |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for &r in radii {
        let ins = table1_instructions(count, r, seed);
        let single = replay(&ins, false);
        let par = replay(&ins, true);
        assert_eq!(single.volume, par.volume, "parallel and single-threaded edits must agree");
        let mem = single.volume.memory();
        let stats = single.volume.crossing_stats();
        println!(
            "| {r} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} | {} | {:.2} | {:.2} | {} |",
            single.edit_ms(),
            single.extract_ms(),
            par.edit_ms(),
            par.extract_ms(),
            single.changed_chunks as f64 / count as f64,
            mem.crossings,
            mem.bytes_per_crossing(true),
            mem.bytes_per_crossing(false),
            stats.max_line,
        );
    }
}

fn frame_mc(count: usize, radii: &[f64], seed: u64) {
    println!(
        "| radius | mean 1 thread (ms) | p99 1 thread (ms) | mean rayon (ms) | p99 rayon (ms) | triangles at end |"
    );
    println!("|---:|---:|---:|---:|---:|---:|");
    for &r in radii {
        let ins = table1_instructions(count, r, seed);
        let single = replay_frames(&ins, false);
        let par = replay_frames(&ins, true);
        println!(
            "| {r} | {:.2} | {:.2} | {:.2} | {:.2} | {} |",
            single.mean_ms(),
            single.quantile_ms(0.99),
            par.mean_ms(),
            par.quantile_ms(0.99),
            single.triangles
        );
    }
}
