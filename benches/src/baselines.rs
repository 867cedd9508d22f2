//! The Table 1 workload replayed on the dense and narrow-band baselines ([`strata_fields`]),
//! timed the same way as the segment volume's [`crate::replay`].

use std::time::{Duration, Instant};

use strata_fields::{DenseField, NarrowBandField, PaddedValues};
use strata_volume::VoxelBlock;

use crate::Instruction;

/// Totals over one replay on a scalar field.
#[derive(Clone, Debug, Default)]
pub struct FieldReplay {
    /// Time modifying the values (for the narrow band: decoding and editing), summed.
    pub edit: Duration,
    /// Time re-encoding the narrow band's changed chunks (the paper's Time_RLE), summed.
    pub encode: Duration,
    /// Time producing the voxel blocks of the changed chunks, summed.
    pub extract: Duration,
    /// Instructions replayed.
    pub count: usize,
    /// The largest memory figure seen after any instruction (bytes).
    pub max_memory: usize,
    /// Memory at the end (bytes).
    pub final_memory: usize,
}

impl FieldReplay {
    fn per_instruction(&self, d: Duration) -> f64 {
        d.as_secs_f64() * 1e3 / self.count.max(1) as f64
    }
    /// Mean Time_d per instruction in milliseconds.
    pub fn edit_ms(&self) -> f64 {
        self.per_instruction(self.edit)
    }
    /// Mean Time_v per instruction in milliseconds.
    pub fn extract_ms(&self) -> f64 {
        self.per_instruction(self.extract)
    }
    /// Mean Time_RLE per instruction in milliseconds.
    pub fn encode_ms(&self) -> f64 {
        self.per_instruction(self.encode)
    }
}

/// Replays `instructions` on an empty dense field, single-threaded.
pub fn replay_dense(instructions: &[Instruction]) -> (FieldReplay, DenseField) {
    let mut field = DenseField::new();
    let mut r = FieldReplay { count: instructions.len(), ..Default::default() };
    let (mut scratch, mut block) = (PaddedValues::default(), VoxelBlock::default());
    for ins in instructions {
        let brush = ins.brush();
        let t0 = Instant::now();
        let changed = field.apply(ins.op, &brush).expect("workload edits are valid");
        let t1 = Instant::now();
        for &k in &changed {
            field.extract_block_into(k, &mut scratch, &mut block);
        }
        std::hint::black_box(&block);
        r.edit += t1 - t0;
        r.extract += t1.elapsed();
        r.max_memory = r.max_memory.max(field.memory());
    }
    r.final_memory = field.memory();
    (r, field)
}

/// Replays `instructions` on an empty narrow-band field of half-width `band`, single-threaded.
pub fn replay_narrow(instructions: &[Instruction], band: f32) -> (FieldReplay, NarrowBandField) {
    let mut field = NarrowBandField::new(band).expect("valid band");
    let mut r = FieldReplay { count: instructions.len(), ..Default::default() };
    let (mut scratch, mut block) = (PaddedValues::default(), VoxelBlock::default());
    for ins in instructions {
        let brush = ins.brush();
        let t0 = Instant::now();
        let decoded = field.edit(ins.op, &brush).expect("workload edits are valid");
        let t1 = Instant::now();
        let changed = field.commit(decoded);
        let t2 = Instant::now();
        for &k in &changed {
            field.extract_block_into(k, &mut scratch, &mut block);
        }
        std::hint::black_box(&block);
        r.edit += t1 - t0;
        r.encode += t2 - t1;
        r.extract += t2.elapsed();
        r.max_memory = r.max_memory.max(field.memory());
    }
    r.final_memory = field.memory();
    (r, field)
}
