//! Adds one sphere of a given radius (cells) to an empty volume and prints the edit's time and
//! the process's peak memory: `cargo run --release -p strata-volume --example big_sphere -- 770
//! [single]`. Run once per configuration: the peak is the whole process's.

use std::time::Instant;

use glam::DVec3;
use strata_volume::brush::Sphere;
use strata_volume::{CsgOp, EditSettings, Volume};

fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).map(str::to_owned))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|k| k.parse::<f64>().ok()))
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let radius: f64 = args.next().and_then(|a| a.parse().ok()).unwrap_or(770.0);
    let single = args.next().is_some_and(|a| a == "single");
    let settings = EditSettings { parallel: !single, max_chunks: u64::MAX, ..Default::default() };
    let mut volume = Volume::new();
    let sphere = Sphere::new(DVec3::splat(radius + 3.5), radius).expect("a valid sphere");
    let t = Instant::now();
    let report = volume.apply(CsgOp::Add, &sphere, &settings).expect("the edit");
    let secs = t.elapsed().as_secs_f64();
    let mem = volume.memory();
    println!(
        "sphere r={radius} {}: {secs:.2} s, {} chunks changed, {} stored, volume {:.1} MiB, peak RSS {:.0} MiB",
        if single { "one thread" } else { "rayon" },
        report.changed.len(),
        volume.chunk_count(),
        mem.total() as f64 / (1024.0 * 1024.0),
        peak_rss_mib()
    );
}
