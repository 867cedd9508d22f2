//! The values a voxel block needs, gathered into one array: nodes `-1..=17` of a chunk on each
//! axis (the block's `0..=16` plus one more on each side for central-difference gradients).

use glam::Vec3;
use strata_volume::{ChunkKey, Level, VoxelBlock};

use crate::N;

/// Nodes per side of the padded array.
pub const P: usize = N + 3;

/// Node values of one chunk and its surroundings: index `(x + 1) + P (y + 1) + P² (z + 1)` for
/// chunk-local node `(x, y, z)`, each coordinate in `-1..=17`.
#[derive(Clone, Debug)]
pub struct PaddedValues {
    values: Box<[f32]>,
}

impl Default for PaddedValues {
    fn default() -> Self {
        PaddedValues { values: vec![0.0; P * P * P].into_boxed_slice() }
    }
}

impl PaddedValues {
    /// Index of chunk-local node `(x, y, z)`, each in `-1..=17`.
    #[inline]
    pub fn index(x: isize, y: isize, z: isize) -> usize {
        (x + 1) as usize + P * ((y + 1) as usize + P * (z + 1) as usize)
    }

    /// The value at chunk-local node `(x, y, z)`, each in `-1..=17`.
    #[inline]
    pub fn get(&self, x: isize, y: isize, z: isize) -> f32 {
        self.values[Self::index(x, y, z)]
    }

    /// All values, in index order.
    pub fn values_mut(&mut self) -> &mut [f32] {
        &mut self.values
    }

    /// Central-difference gradient at block node `(x, y, z)` (each in `0..=16`).
    #[inline]
    fn gradient(&self, x: usize, y: usize, z: usize) -> Vec3 {
        let (x, y, z) = (x as isize, y as isize, z as isize);
        Vec3::new(
            self.get(x + 1, y, z) - self.get(x - 1, y, z),
            self.get(x, y + 1, z) - self.get(x, y - 1, z),
            self.get(x, y, z + 1) - self.get(x, y, z - 1),
        )
    }

    /// The voxel block of chunk `key`: a node is inside iff its value is `≤ 0`; an edge whose
    /// nodes differ crosses where the linear interpolation of its two values is zero, with the
    /// normal interpolated from the nodes' gradients there.
    pub fn fill_block(&self, key: ChunkKey, out: &mut VoxelBlock) {
        let at = |x: usize, y: usize, z: usize| self.get(x as isize, y as isize, z as isize);
        out.fill_from_fn(
            key,
            Level::BASE,
            |x, y, z| at(x, y, z) <= 0.0,
            |axis, lower| {
                let [x, y, z] = lower;
                let mut upper = lower;
                upper[axis.index()] += 1;
                let (v0, v1) = (at(x, y, z), at(upper[0], upper[1], upper[2]));
                let t = v0 / (v0 - v1);
                let t = if t.is_finite() { t } else { 0.5 };
                let g = self.gradient(x, y, z).lerp(self.gradient(upper[0], upper[1], upper[2]), t);
                // The field grows outward; fall back to the edge direction if the gradient vanishes.
                let mut fallback = Vec3::ZERO;
                fallback[axis.index()] = if v1 > v0 { 1.0 } else { -1.0 };
                (t, g.try_normalize().unwrap_or(fallback))
            },
        );
    }
}
