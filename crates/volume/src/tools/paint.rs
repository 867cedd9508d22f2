//! Paint: material given to the solid nodes under a brush, node states and crossings left
//! alone. Strength below 1 paints a dithered share of the nodes (a fixed hash of each node's
//! global position), the same ones every time.

use glam::{DVec3, I64Vec3};

use super::ops::{Dab, ToolError};
use crate::coords::{ChunkBox, ChunkKey};
use crate::edit::EditReport;
use crate::material::{ChunkMaterials, MaterialId, own_states};
use crate::volume::Volume;

/// Paints the solid nodes within the dab with `dab.material`, leaving node states and crossings
/// bit for bit: a node is painted where the dab's weight (strength × falloff) beats the node's
/// dither threshold (a fixed hash of its position), so the falloff shows as a share of painted
/// nodes, the same ones on every dab, and a dab of strength 1 paints its centre solidly.
pub fn paint(volume: &mut Volume, dab: &Dab) -> Result<EditReport, ToolError> {
    let ball = crate::brush::Sphere::new(dab.center, dab.radius)
        .map_err(|_| ToolError::BadParameter { what: "the dab radius", positive: true })?;
    Ok(volume.paint_where(&ball, dab.material, &|p| dab.weight(p))?)
}

impl Volume {
    /// Gives the solid nodes inside `brush` material `id` where `weight(node)` (grid point) beats
    /// the node's dither threshold (a fixed hash of its global position in `[0, 1)`): weight 1
    /// paints every node, weight 0 none, and a weight between paints that share of the nodes,
    /// the same ones every time; the mask scales the weight by `1 - mask weight`. Node states and
    /// crossings are not touched. Returns the chunks
    /// whose materials changed and the record that undoes it.
    pub fn paint_where(
        &mut self,
        brush: &dyn crate::brush::Brush,
        id: MaterialId,
        weight: &dyn Fn(DVec3) -> f64,
    ) -> Result<crate::EditReport, crate::EditError> {
        let bounds = brush.bounds();
        if !bounds.is_valid() {
            return Err(crate::EditError::BadBounds);
        }
        let (cmin, cmax) = crate::edit::chunk_range(&bounds, crate::EditSettings::default().max_chunks)?;
        let keys: Vec<ChunkKey> = ChunkBox::new(cmin, cmax).keys().filter(|k| self.chunks.contains_key(k)).collect();
        let mut ids = Vec::new();
        let mut updates = Vec::new();
        // The mask takes its share off the weight (a held node is never painted).
        let mask = self.mask_sampler(bounds.min, bounds.max);
        for key in keys {
            let level = self.level_of(key);
            let n = level.cells();
            let rows = own_states(self.view(key), level);
            self.decode_materials(key, level, &mut ids);
            let origin = key.origin_grid();
            let h = level.spacing();
            let mut touched = false;
            for (r, &row) in rows.iter().enumerate() {
                let (y, z) = (r % n, r / n);
                let mut bits = row;
                while bits != 0 {
                    let x = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let i = x + n * r;
                    if ids[i] == id {
                        continue;
                    }
                    let local = DVec3::new(x as f64, y as f64, z as f64) * h;
                    let p = origin.as_dvec3() + local;
                    if !bounds.contains(p) || !brush.contains(origin.as_dvec3(), local) {
                        continue;
                    }
                    let w = weight(p) * mask.as_ref().map_or(1.0, |m| 1.0 - m.at(p));
                    if w > 0.0
                        && (w >= 1.0
                            || w > dither(level.node_of_grid(origin) + I64Vec3::new(x as i64, y as i64, z as i64)))
                    {
                        ids[i] = id;
                        touched = true;
                    }
                }
            }
            if touched {
                let next = ChunkMaterials::encode(&ids, &rows, n);
                if next.as_ref() != self.materials.get(&key) {
                    updates.push((key, next));
                }
            }
        }
        // Only nodes inside the brush's box change (a cell of the coarsest level more holds
        // every edge whose vertex takes a changed node's material).
        let mut report = crate::EditReport {
            reach: Some(crate::Reach { min: bounds.min - DVec3::ONE, max: bounds.max + DVec3::ONE }),
            ..Default::default()
        };
        for (key, next) in updates {
            let was = self.store_materials(key, next);
            report.changed.push(key);
            report.undo.materials.push((key, was));
        }
        Ok(report)
    }

    /// Paints the solid nodes inside `brush` with material `id`, every one of them.
    pub fn paint(
        &mut self,
        brush: &dyn crate::brush::Brush,
        id: MaterialId,
    ) -> Result<crate::EditReport, crate::EditError> {
        self.paint_where(brush, id, &|_| 1.0)
    }
}

/// A node's dither threshold in `[0, 1)`: a fixed hash of its global node coordinates.
fn dither(node: I64Vec3) -> f64 {
    let mut h = (node.x as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    h ^= (node.y as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f).rotate_left(21);
    h ^= (node.z as u64).wrapping_mul(0x1656_67b1_9e37_79f9).rotate_left(42);
    h ^= h >> 29;
    h = h.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h ^= h >> 32;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dither_thresholds_spread_over_the_unit_interval() {
        let t: Vec<f64> = (0..4096).map(|i| dither(I64Vec3::new(i % 16, i / 16 % 16, i / 256))).collect();
        assert!(t.iter().all(|v| (0.0..1.0).contains(v)));
        let below = t.iter().filter(|&&v| v < 0.5).count();
        assert!((1800..2300).contains(&below), "{below}");
    }
}
