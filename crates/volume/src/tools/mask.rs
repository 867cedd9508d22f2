//! Mask dabs: painting weight on, taking it off, and smoothing it, under a ball with the
//! tools' falloff (see [`crate::mask`]). Every node within the radius changes, inside the solid
//! or not: the mask is a weight per grid node, and what it protects is a region, not a skin.

use glam::{DVec3, I64Vec3};

use super::ops::{Dab, ToolError};
use super::region::{MAX_REGION_NODES, RegionError};
use crate::edit::{EditReport, UndoRecord};
use crate::mask::{MaskUndo, MaskWeight, PROTECTED};
use crate::volume::Volume;

/// How a mask dab changes the weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaskStroke {
    /// Adds `strength × falloff` of full protection.
    Add,
    /// Takes it off.
    Subtract,
    /// Moves each weight towards the mean of its six neighbours by `strength × falloff`.
    Smooth,
}

/// Applies one mask dab; the report lists the chunks whose shading changes and undoes the
/// dab exactly.
pub fn mask(volume: &mut Volume, dab: &Dab, stroke: MaskStroke) -> Result<EditReport, ToolError> {
    // A ball beyond the chunk key range is refused, as an edit there is.
    let r = DVec3::splat(dab.radius + 1.0);
    crate::edit::chunk_range(&crate::brush::Aabb::new(dab.center - r, dab.center + r), u64::MAX)?;
    let side = 2.0 * dab.radius + 1.0;
    let nodes = side * side * side;
    if nodes > MAX_REGION_NODES as f64 {
        let nodes = nodes.min(u64::MAX as f64) as u64;
        return Err(RegionError::TooLarge { nodes, limit: MAX_REGION_NODES }.into());
    }
    let scale = |w: MaskWeight, t: f64, to: f64| {
        let k = dab.strength * dab.falloff.at(t);
        (w as f64 + (to - w as f64) * k).round().clamp(0.0, PROTECTED as f64) as MaskWeight
    };
    let undo = match stroke {
        MaskStroke::Add => volume.mask.modify_ball(dab.center, dab.radius, |w, t, _| scale(w, t, PROTECTED as f64)),
        MaskStroke::Subtract => volume.mask.modify_ball(dab.center, dab.radius, |w, t, _| scale(w, t, 0.0)),
        MaskStroke::Smooth => {
            // The means are taken from the weights before the dab.
            let r = DVec3::splat(dab.radius + 1.0);
            let Some(before) = volume.mask.sampler(dab.center - r, dab.center + r) else {
                return Ok(EditReport::default());
            };
            let mean = |p: I64Vec3| {
                let n = [I64Vec3::X, I64Vec3::NEG_X, I64Vec3::Y, I64Vec3::NEG_Y, I64Vec3::Z, I64Vec3::NEG_Z];
                n.iter().map(|d| before.node(p + *d)).sum::<f64>() / 6.0 * PROTECTED as f64
            };
            volume.mask.modify_ball(dab.center, dab.radius, |w, t, p| scale(w, t, mean(p)))
        }
    };
    Ok(volume.mask_report(undo))
}

impl Volume {
    /// The report of a mask change: the chunks holding something near the nodes it changed
    /// (their meshes' shading reads the weights around them), and its undo.
    pub(crate) fn mask_report(&self, masks: MaskUndo) -> EditReport {
        let mut changed: Vec<_> = if masks.outside.is_some() {
            self.chunks.keys().copied().collect()
        } else {
            masks.keys().flat_map(|k| k.around()).filter(|k| self.chunks.contains_key(k)).collect()
        };
        changed.sort();
        changed.dedup();
        let masks = (!masks.is_empty()).then(|| Box::new(masks));
        EditReport { changed, undo: UndoRecord { masks, ..UndoRecord::default() }, repaired_nodes: 0, reach: None }
    }
}
