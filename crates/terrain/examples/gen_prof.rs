//! Where a chunk's generation goes: node states, crossings and the whole chunk, over Table 9's
//! block of 1,024 chunks (8 × 8 chunk columns from below the cave floor to the sky).
//! `cargo run --release -p strata-terrain --example gen_prof [level]` (the base level, 0, unless
//! given: −1 for the coarse level far terrain uses).

use std::time::Instant;

use glam::{DVec3, I64Vec3};
use strata_terrain::{Recipe, TerrainField};
use strata_volume::{Axis, ChunkKey, Level, NodeField, generate_chunk};

fn main() {
    let field = TerrainField::new(&Recipe::with_seed(2021)).expect("the default recipe");
    let keys: Vec<ChunkKey> =
        (0..8).flat_map(|x| (0..8).flat_map(move |z| (-8..8).map(move |y| ChunkKey::new(x, y, z)))).collect();
    let level = std::env::args()
        .nth(1)
        .map(|a| a.parse::<i8>().ok().and_then(Level::new).expect("a level from -1 to 2"))
        .unwrap_or(Level::BASE);
    let sp = level.spacing();
    let m = level.cells() + 1;
    for round in 0..3 {
        let t = Instant::now();
        let mut undecided = 0;
        let mut rows = vec![0u128; m * m];
        let mut states = Vec::new();
        for k in &keys {
            let o: I64Vec3 = k.origin_grid();
            if field.decided(o, level).is_some() {
                continue;
            }
            undecided += 1;
            rows.iter_mut().for_each(|r| *r = 0);
            field.node_states(o, level, &mut rows);
            states.push((o, rows.clone()));
        }
        let nodes = t.elapsed();
        let t = Instant::now();
        let mut crossings = 0;
        for (o, rows) in &states {
            for z in 0..m {
                for y in 0..m {
                    for x in 0..m - 1 {
                        let a = rows[y + m * z] >> x & 1;
                        let b = rows[y + m * z] >> (x + 1) & 1;
                        if a != b {
                            crossings += 1;
                            let p = o.as_dvec3() + DVec3::new(x as f64, y as f64, z as f64) * sp;
                            std::hint::black_box(field.crossing(p, Axis::X, sp, a == 1));
                        }
                    }
                }
            }
        }
        let x_cross = t.elapsed();
        let t = Instant::now();
        for k in &keys {
            std::hint::black_box(generate_chunk(*k, level, &field));
        }
        let whole = t.elapsed();
        // A uniform solid chunk's materials are read per node of the volume's level (the base
        // level): what a world adds for a solid chunk generated at another level.
        let t = Instant::now();
        let mut solid = 0;
        for k in &keys {
            if generate_chunk(*k, level, &field).chunk == Some(strata_volume::Chunk::Solid) {
                solid += 1;
                std::hint::black_box(strata_volume::solid_chunk_materials(*k, Level::BASE, &field));
            }
        }
        let with_base_materials = t.elapsed();
        println!(
            "round {round}: {undecided} undecided chunks; node states {:.3} ms/undecided chunk; x crossings {crossings} in {:.3} ms/undecided chunk ({:.2} µs each); generate_chunk {:.3} ms/chunk",
            nodes.as_secs_f64() * 1e3 / undecided as f64,
            x_cross.as_secs_f64() * 1e3 / undecided as f64,
            x_cross.as_secs_f64() * 1e6 / crossings as f64,
            whole.as_secs_f64() * 1e3 / keys.len() as f64
        );
        println!(
            "         {solid} solid chunks; generate_chunk and base-level materials of the solid ones {:.3} ms/chunk",
            with_base_materials.as_secs_f64() * 1e3 / keys.len() as f64
        );
    }
}
