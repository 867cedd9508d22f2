//! One Perlin octave, the `noise` crate's and this crate's (`strata_terrain::perlin`, the same
//! values bit for bit), timed over a million points in 3D and in 2D.
//! `cargo run --release -p strata-terrain --example perlin_speed`

use std::time::Instant;

use noise::NoiseFn;

fn main() {
    let ours = strata_terrain::perlin::Perlin::new(7);
    let theirs = noise::Perlin::new(7);
    let points: Vec<[f64; 3]> = (0..1_000_000)
        .map(|i| {
            let f = i as f64;
            [f * 0.0137 - 300.0, (f * 0.0071).sin() * 50.0, f * 0.0029 + 11.0]
        })
        .collect();
    let ns = |f: &dyn Fn(&[f64; 3]) -> f64| {
        let t = Instant::now();
        let sum: f64 = points.iter().map(f).sum();
        (t.elapsed().as_nanos() as f64 / points.len() as f64, sum)
    };
    for _ in 0..3 {
        let (crate3, a) = ns(&|p| theirs.get(*p));
        let (ours3, b) = ns(&|p| ours.get3(*p));
        let (crate2, c) = ns(&|p| theirs.get([p[0], p[2]]));
        let (ours2, d) = ns(&|p| ours.get2([p[0], p[2]]));
        assert!(a == b && c == d, "the same sums");
        println!(
            "3D: the crate {crate3:.1} ns, ours {ours3:.1} ns ({:.2}× faster); \
             2D: the crate {crate2:.1} ns, ours {ours2:.1} ns ({:.2}× faster)",
            crate3 / ours3,
            crate2 / ours2
        );
    }
}
