//! A finite piece of an endless world: the terrain inside a box of grid nodes, closed at the
//! box's faces, generated in parallel (for scenes and exported meshes).

use std::sync::atomic::{AtomicU64, Ordering};

use glam::{DVec3, I64Vec3};
use rayon::prelude::*;
use strata_volume::coords::CHUNK_CELLS;
use strata_volume::{Axis, ChunkKey, Level, MaterialId, NodeField, Volume, generate_chunk};

use crate::field::TerrainField;

/// The terrain of `inner` within the nodes `lo ..= hi` (grid units, base level): solid where
/// both the terrain is and the node lies in the box. The box's faces sit half a cell outside its
/// outermost nodes, so no node is on them.
#[derive(Debug)]
pub struct Clipped<'a> {
    inner: &'a TerrainField,
    lo: I64Vec3,
    hi: I64Vec3,
}

impl<'a> Clipped<'a> {
    /// `inner` within the nodes `lo ..= hi` (every coordinate of `lo` at most that of `hi`).
    pub fn new(inner: &'a TerrainField, lo: I64Vec3, hi: I64Vec3) -> Option<Self> {
        lo.cmple(hi).all().then_some(Clipped { inner, lo, hi })
    }

    fn in_box(&self, p: DVec3) -> bool {
        p.cmpge(self.lo.as_dvec3()).all() && p.cmple(self.hi.as_dvec3()).all()
    }

    /// The chunks that can hold a node of the box (and the chunks before them whose lines end
    /// on one).
    pub fn keys(&self) -> Vec<ChunkKey> {
        let c = CHUNK_CELLS;
        let lo = (self.lo - I64Vec3::ONE).div_euclid(I64Vec3::splat(c)).as_ivec3();
        let hi = self.hi.div_euclid(I64Vec3::splat(c)).as_ivec3();
        strata_volume::ChunkBox::new(lo, hi).keys().collect()
    }
}

impl NodeField for Clipped<'_> {
    fn decided(&self, origin: I64Vec3, level: Level) -> Option<bool> {
        let far = origin + I64Vec3::splat(CHUNK_CELLS);
        if far.cmplt(self.lo).any() || origin.cmpgt(self.hi).any() {
            return Some(false);
        }
        if origin.cmpge(self.lo).all() && far.cmple(self.hi).all() { self.inner.decided(origin, level) } else { None }
    }

    fn node_states(&self, origin: I64Vec3, level: Level, rows: &mut [u128]) {
        self.inner.node_states(origin, level, rows);
        let n = level.cells();
        let sp = level.spacing();
        for z in 0..=n {
            for y in 0..=n {
                let row = &mut rows[y + (n + 1) * z];
                if *row == 0 {
                    continue;
                }
                for x in 0..=n {
                    let p = origin.as_dvec3() + DVec3::new(x as f64, y as f64, z as f64) * sp;
                    if !self.in_box(p) {
                        *row &= !(1 << x);
                    }
                }
            }
        }
    }

    fn crossing(&self, from: DVec3, axis: Axis, spacing: f64, from_inside: bool) -> (f64, DVec3) {
        let to = from + axis.unit() * spacing;
        match (self.in_box(from), self.in_box(to)) {
            (true, true) => self.inner.crossing(from, axis, spacing, from_inside),
            // The box's face, half a cell past its last node.
            (true, false) => (0.5, axis.unit()),
            _ => (0.5, -axis.unit()),
        }
    }

    fn materials(&self, origin: I64Vec3, level: Level, own: &[u128], ids: &mut [MaterialId]) {
        self.inner.materials(origin, level, own, ids);
    }
}

/// Generates the terrain of `field` within the nodes `lo ..= hi` into a volume, in parallel;
/// `done` counts finished chunks (for a progress bar). The same bytes on any thread count.
pub fn generate_region(field: &TerrainField, lo: I64Vec3, hi: I64Vec3, done: &AtomicU64) -> Option<Volume> {
    let clipped = Clipped::new(field, lo, hi)?;
    let keys = clipped.keys();
    let chunks: Vec<_> = keys
        .par_iter()
        .map(|&k| {
            let g = generate_chunk(k, Level::BASE, &clipped);
            done.fetch_add(1, Ordering::Relaxed);
            (k, g)
        })
        .collect();
    let mut v = Volume::new();
    for (k, g) in chunks {
        v.put_chunk(k, g.chunk, g.materials);
    }
    Some(v)
}
