//! Workloads shared by the criterion benches and the `strata-bench` binary.
//!
//! Table 1 (after the paper): a 160³-cell canvas (10³ chunks), 1000 seeded random sphere
//! draw/erase instructions of one radius, applied in order to an initially empty volume.

use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

pub mod baselines;
pub mod collab;
pub mod gpu;
pub mod lod;
pub mod masks;
pub mod materials;
pub mod quality;
pub mod suite;
pub mod terrain;
pub mod tools;
use strata_volume::brush::Sphere;
use strata_volume::{ChunkKey, CsgOp, EditSettings, Volume, VoxelBlock};

/// Side of the Table 1 canvas in cells.
pub const CANVAS_CELLS: f64 = 160.0;

/// A small, fast, seedable generator (SplitMix64), so workloads are identical everywhere.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A uniform number in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// One draw or erase instruction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instruction {
    /// Add (draw) or subtract (erase).
    pub op: CsgOp,
    /// Sphere centre, uniform in the canvas.
    pub center: DVec3,
    /// Sphere radius.
    pub radius: f64,
}

impl Instruction {
    /// The sphere brush.
    pub fn brush(&self) -> Sphere {
        Sphere::new(self.center, self.radius).expect("valid workload sphere")
    }
}

/// `count` instructions of one radius: 60 % draws, 40 % erases, centres uniform in the canvas.
pub fn table1_instructions(count: usize, radius: f64, seed: u64) -> Vec<Instruction> {
    let mut rng = SplitMix64::new(seed ^ radius.to_bits());
    (0..count)
        .map(|_| {
            let op = if rng.unit() < 0.6 { CsgOp::Add } else { CsgOp::Subtract };
            let center = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * CANVAS_CELLS;
            Instruction { op, center, radius }
        })
        .collect()
}

/// Totals over one replay of an instruction list.
#[derive(Clone, Debug, Default)]
pub struct Replay {
    /// Time modifying the lists (the paper's Time_d), summed.
    pub edit: Duration,
    /// Time producing the voxel blocks of the changed chunks (Time_v), summed.
    pub extract: Duration,
    /// Instructions replayed.
    pub count: usize,
    /// Chunks changed, summed.
    pub changed_chunks: usize,
    /// The volume afterwards.
    pub volume: Volume,
    /// The largest [`Volume::memory`] total seen after any instruction (bytes).
    pub max_memory: usize,
}

impl Replay {
    /// Mean Time_d per instruction in milliseconds.
    pub fn edit_ms(&self) -> f64 {
        self.edit.as_secs_f64() * 1e3 / self.count.max(1) as f64
    }

    /// Mean Time_v per instruction in milliseconds.
    pub fn extract_ms(&self) -> f64 {
        self.extract.as_secs_f64() * 1e3 / self.count.max(1) as f64
    }
}

/// Replays `instructions` on an empty volume, timing edits and block extraction separately.
/// `parallel` uses rayon for both (chunks in parallel); otherwise everything runs on this thread.
pub fn replay(instructions: &[Instruction], parallel: bool) -> Replay {
    let mut r = Replay { count: instructions.len(), ..Default::default() };
    let settings = EditSettings { parallel, ..Default::default() };
    let mut block = VoxelBlock::default();
    let mut blocks: Vec<VoxelBlock> = Vec::new();
    for ins in instructions {
        let brush = ins.brush();
        let t0 = Instant::now();
        let report = r.volume.apply(ins.op, &brush, &settings).expect("workload edits are valid");
        let t1 = Instant::now();
        extract(&r.volume, &report.changed, parallel, &mut block, &mut blocks);
        let t2 = Instant::now();
        r.edit += t1 - t0;
        r.extract += t2 - t1;
        r.changed_chunks += report.changed.len();
        r.max_memory = r.max_memory.max(r.volume.memory().total());
    }
    r
}

/// Whole-frame times: per instruction, the edit plus the voxel blocks and
/// meshes of every chunk whose mesh depends on a changed chunk (the paper's Table 2 work,
/// without rendering).
#[derive(Clone, Debug, Default)]
pub struct FrameReplay {
    /// Per-instruction frame times, in order.
    pub frames: Vec<Duration>,
    /// Triangles in the final mesh cache.
    pub triangles: usize,
}

impl FrameReplay {
    /// Mean frame time in milliseconds.
    pub fn mean_ms(&self) -> f64 {
        self.frames.iter().map(Duration::as_secs_f64).sum::<f64>() * 1e3 / self.frames.len().max(1) as f64
    }

    /// The `q`-quantile frame time in milliseconds (see [`quantile`]).
    pub fn quantile_ms(&self, q: f64) -> f64 {
        let v: Vec<f64> = self.frames.iter().map(|d| d.as_secs_f64() * 1e3).collect();
        quantile(&v, q)
    }
}

/// The `q`-quantile of `samples` (`q` in `[0, 1]`) by the nearest-rank definition: the smallest
/// sample with at least a share `q` of the samples at or below it (p99 of 100 frames is the
/// 99th smallest, of 300 the 297th), `0` for no samples. Every p50, p99 and max of the bench
/// is this function.
pub fn quantile(samples: &[f64], q: f64) -> f64 {
    let mut v = samples.to_vec();
    v.sort_by(f64::total_cmp);
    let rank = ((v.len() as f64 * q.clamp(0.0, 1.0)).ceil() as usize).max(1);
    v.get(rank - 1).copied().unwrap_or(0.0)
}

#[cfg(test)]
mod quantile_tests {
    use super::quantile;

    #[test]
    fn quantiles_are_nearest_ranks() {
        let v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        assert_eq!(quantile(&v, 0.99), 99.0);
        assert_eq!(quantile(&v, 0.5), 50.0);
        assert_eq!(quantile(&v, 1.0), 100.0);
        assert_eq!(quantile(&v, 0.0), 1.0);
        let w: Vec<f64> = (1..=300).map(f64::from).collect();
        assert_eq!(quantile(&w, 0.99), 297.0);
        assert_eq!(quantile(&[], 0.99), 0.0);
        assert_eq!(quantile(&[7.0], 0.99), 7.0);
    }
}

/// Which mesher a frame runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mesher {
    /// Marching cubes ([`strata_mesh::MeshCache`]).
    MarchingCubes,
    /// Dual contouring ([`strata_mesh::DualCache`]).
    DualContouring,
}

/// Replays `instructions`, timing edit + remesh of affected chunks per instruction.
pub fn replay_frames(instructions: &[Instruction], parallel: bool, mesher: Mesher) -> FrameReplay {
    let mut volume = Volume::new();
    let mut mc = strata_mesh::MeshCache::new();
    let mut dc = strata_mesh::DualCache::new();
    let settings = EditSettings { parallel, ..Default::default() };
    let mut frames = Vec::with_capacity(instructions.len());
    let pool = rayon::ThreadPoolBuilder::new().num_threads(if parallel { 0 } else { 1 }).build().expect("thread pool");
    for ins in instructions {
        let brush = ins.brush();
        let t0 = Instant::now();
        let report = volume.apply(ins.op, &brush, &settings).expect("workload edits are valid");
        pool.install(|| match mesher {
            Mesher::MarchingCubes => mc.update(&volume, &report.changed),
            Mesher::DualContouring => dc.update(&volume, &report.changed),
        });
        frames.push(t0.elapsed());
    }
    let triangles = match mesher {
        Mesher::MarchingCubes => mc.triangle_count(),
        Mesher::DualContouring => dc.triangle_count(),
    };
    FrameReplay { frames, triangles }
}

pub(crate) fn extract(
    volume: &Volume,
    keys: &[ChunkKey],
    parallel: bool,
    block: &mut VoxelBlock,
    blocks: &mut Vec<VoxelBlock>,
) {
    if parallel {
        blocks.resize_with(keys.len().max(blocks.len()), VoxelBlock::default);
        blocks[..keys.len()].par_iter_mut().zip(keys).for_each(|(b, &k)| volume.extract_block_into(k, b));
    } else {
        for &k in keys {
            volume.extract_block_into(k, block);
        }
    }
    std::hint::black_box(&*block);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table1_workload_replays_identically_on_one_thread_and_with_rayon() {
        let ins = table1_instructions(40, 12.0, 7);
        assert_eq!(ins, table1_instructions(40, 12.0, 7), "the workload is seeded");
        let a = replay(&ins, false);
        let b = replay(&ins, true);
        assert_eq!(a.volume, b.volume);
        a.volume.check_invariants().unwrap();
        assert!(a.changed_chunks > 0 && a.volume.memory().crossings > 0);
        assert!(ins.iter().any(|i| i.op == CsgOp::Subtract) && ins.iter().any(|i| i.op == CsgOp::Add));
    }
}
