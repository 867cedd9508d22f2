//! Level of detail by distance: which chunks of a layer the viewport meshes below their stored
//! level, and at which level, from where the viewer is.

use std::collections::HashMap;

use glam::DVec3;
use strata_volume::{ChunkKey, Level, Volume};

/// Where the viewer is, for level of detail: a chunk is meshed at the coarsest level whose cell,
/// seen from `eye` at the chunk's nearest point, spans at most `pixel_error` pixels.
/// Hysteresis: a chunk goes coarser only once the coarser level looks at most
/// `pixel_error / 1.5`, so a camera resting near a threshold does not make chunks flicker.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodView {
    /// The eye, in world units.
    pub eye: DVec3,
    /// Pixels per radian of view (the viewport's height in pixels over the vertical field of
    /// view in radians).
    pub pixels_per_radian: f64,
    /// The largest cell a chunk may show, in pixels.
    pub pixel_error: f64,
}

impl LodView {
    /// Whether every field is finite and positive where it must be.
    pub fn is_valid(&self) -> bool {
        self.eye.is_finite()
            && self.pixels_per_radian.is_finite()
            && self.pixels_per_radian > 0.0
            && self.pixel_error.is_finite()
            && self.pixel_error > 0.0
    }

    /// The level for a chunk stored at `stored`, now meshed at `current`, whose base cell is
    /// `cell` world units, `distance` world units from the eye: where `current` shows cells
    /// larger than the pixel error, the coarsest level that does not; else the coarsest level
    /// that shows at most two thirds of it, if coarser than `current`.
    pub fn level_for(&self, stored: Level, current: Level, cell: f64, distance: f64) -> Level {
        let pixels = |l: Level| cell * l.spacing() / distance * self.pixels_per_radian;
        let current = current.min(stored);
        // The coarsest level at or above `from` whose cells look at most `limit` pixels.
        let coarsest = |limit: f64| -> Option<Level> {
            (0..=stored.get()).map(|k| Level::new(k).expect("a level")).find(|&l| pixels(l) <= limit)
        };
        if pixels(current) > self.pixel_error {
            return coarsest(self.pixel_error).unwrap_or(stored).max(current);
        }
        match coarsest(self.pixel_error / 1.5) {
            Some(l) if l < current => l,
            _ => current,
        }
    }
}

/// The level-of-detail caps of the list chunks of `volume` (placed by `transform`) seen from
/// `view`, given the caps they have now (`current`, for the hysteresis): chunks to be meshed below
/// their stored level, and that level. Each chunk counts from its nearest point to the eye
/// (its centre's distance less half its diagonal).
pub fn lod_levels(
    volume: &Volume,
    transform: &crate::scene::LayerTransform,
    view: &LodView,
    current: &HashMap<ChunkKey, Level>,
) -> HashMap<ChunkKey, Level> {
    let mut next = HashMap::new();
    let world_cell = volume.cell_size() * transform.scale;
    let half_diagonal = 8.0 * 3f64.sqrt() * world_cell;
    for (key, _) in volume.chunks() {
        let Some(stored) = volume.stored_level(key) else { continue };
        let centre = key.origin_grid().as_dvec3() + DVec3::splat(8.0);
        let distance = (transform.to_world(centre * volume.cell_size()) - view.eye).length();
        let near = (distance - half_diagonal).max(1e-9);
        let now = current.get(&key).copied().unwrap_or(stored);
        let level = view.level_for(stored, now, world_cell, near);
        if level < stored {
            next.insert(key, level);
        }
    }
    next
}
