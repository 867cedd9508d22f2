//! Per-dab time of the field tools at radius 5, 10 and 20 on a 160³-cell canvas of random
//! spheres (one thread): `cargo run --release -p strata-volume --example tool_dabs`.

use std::time::Instant;

use glam::DVec3;
use strata_volume::brush::Sphere;
use strata_volume::tools::{Dab, Smoothing, flatten, inflate, smooth};
use strata_volume::{EditSettings, Volume};

/// One tool applied as a dab.
type Tool = dyn Fn(&mut Volume, &Dab);

fn main() {
    let mut seed = 2021u64;
    let mut unit = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut v = Volume::new();
    let settings = EditSettings { parallel: false, ..Default::default() };
    for _ in 0..300 {
        let c = DVec3::new(unit(), unit(), unit()) * 160.0;
        v.apply(strata_volume::CsgOp::Add, &Sphere::new(c, 6.0 + unit() * 14.0).unwrap(), &settings).unwrap();
    }
    // Surface points to dab at: where random rays from above hit.
    let mut points = Vec::new();
    while points.len() < 200 {
        let o = DVec3::new(unit() * 160.0, 200.0, unit() * 160.0);
        if let Some(h) = v.raycast(o, -DVec3::Y, 400.0) {
            points.push(h.point);
        }
    }
    println!("| tool | radius 5 (ms) | radius 10 (ms) | radius 20 (ms) |");
    println!("|---|---:|---:|---:|");
    let tools: [(&str, &Tool); 4] = [
        ("inflate 0.5", &|v, d| drop(inflate(v, d, 0.5).unwrap())),
        ("smooth, volume-preserving, 4 passes", &|v, d| drop(smooth(v, d, Smoothing::VolumePreserving, 4).unwrap())),
        ("smooth, Laplacian, 4 passes", &|v, d| drop(smooth(v, d, Smoothing::Laplacian, 4).unwrap())),
        ("flatten", &|v, d| drop(flatten(v, d).unwrap())),
    ];
    for (name, tool) in tools {
        let mut row = format!("| {name} |");
        for radius in [5.0, 10.0, 20.0] {
            let mut w = v.clone();
            let t = Instant::now();
            for p in &points {
                tool(&mut w, &Dab::new(*p, radius, 0.5).unwrap());
            }
            row += &format!(" {:.2} |", t.elapsed().as_secs_f64() * 1e3 / points.len() as f64);
        }
        println!("{row}");
    }
}
