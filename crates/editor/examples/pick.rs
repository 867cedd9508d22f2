//! Times one pick over a scene of 100 empty layers at scale 10⁻⁵ and over the same scene with
//! one sculpted layer in front: `cargo run --release -p strata-editor --example pick`.

use std::time::Instant;

use glam::{DQuat, DVec3};
use strata_editor::{Editor, Layer, LayerTransform, Scene};
use strata_volume::brush::Sphere;

fn median_pick_us(e: &Editor, origin: DVec3, dir: DVec3, runs: usize) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(e.pick(origin, dir, 1e4));
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[runs / 2]
}

fn main() {
    let mut scene = Scene::default();
    scene.layers.clear();
    for i in 0..100 {
        let mut l = Layer::new(format!("empty {i}"));
        l.transform = LayerTransform { translation: DVec3::ZERO, rotation: DQuat::IDENTITY, scale: 1e-5 };
        scene.layers.push(l);
    }
    let e = Editor::new(scene.clone());
    let (o, d) = (DVec3::new(0.0, 0.0, -50.0), DVec3::Z);
    println!("100 empty layers at scale 1e-5: median pick {:.2} µs", median_pick_us(&e, o, d, 11));
    let mut clay = Layer::new("clay");
    clay.volume.add(&Sphere::new(DVec3::splat(16.0), 12.0).unwrap()).unwrap();
    scene.layers.push(clay);
    let e = Editor::new(scene);
    let (o, d) = (DVec3::new(16.0, 16.0, -50.0), DVec3::Z);
    println!("the same with a sculpted layer: median pick {:.2} µs", median_pick_us(&e, o, d, 11));
}
