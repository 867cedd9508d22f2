//! Picking: the first surface a ray meets over every visible layer (bounded by
//! [`PICK_CHUNK_STEPS`]), the surface a stroke follows, and the material under a pick.

use glam::DVec3;

use crate::editor::Editor;

/// A surface point found by [`Editor::pick`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pick {
    /// The layer hit.
    pub layer: usize,
    /// Ray parameter of the hit (world units for a unit direction).
    pub t: f64,
    /// World point.
    pub point: DVec3,
    /// World outward normal.
    pub normal: DVec3,
}

/// The most chunks one [`Editor::pick`] walks over all layers: a straight ray through a world
/// a million cells wide, about a millisecond of empty-chunk steps.
pub const PICK_CHUNK_STEPS: u64 = 1 << 16;

impl Editor {
    /// The material of the solid under a pick (the eyedropper): the nearest solid node of the
    /// cell just inside the picked surface.
    pub fn material_at(&self, pick: &Pick) -> Option<strata_volume::MaterialId> {
        let l = self.surface(pick.layer)?;
        let (tr, volume) = (l.transform(), l.volume());
        let inward = tr.dir_to_grid(-pick.normal).normalize_or_zero();
        let p = tr.to_grid(pick.point) + inward * 0.25 * volume.level().spacing();
        volume.material_near(p)
    }

    /// The first surface hit of the world ray `origin + t · dir` (`t ≤ max_t`) on a visible
    /// layer or the editor's world (its [`Pick::layer`] the surface's number).
    ///
    /// The work is bounded per pick, whatever the scene: layers whose stored chunks the ray
    /// misses cost one box test (an empty layer nothing), layers are tried in the order the ray
    /// enters their boxes and the search stops once a hit is nearer than the next box, and all
    /// layers together walk at most [`PICK_CHUNK_STEPS`] chunks.
    pub fn pick(&self, origin: DVec3, dir: DVec3, max_t: f64) -> Option<Pick> {
        self.pick_counted(origin, dir, max_t).0
    }

    /// Where a stroke in progress meets the surface along the ray `origin + t·dir` (unit `dir`
    /// not required): the ray parameter of the first surface that is not the stroke's own work,
    /// or `None` where that surface cannot be seen (then the caller keeps the stroke's depth).
    ///
    /// A stroke follows the surface under the pointer, as sculptors expect: from the face onto
    /// the body behind it, a stroke keeps touching. Tools that build or carve
    /// ([`ToolKind::builds_or_carves`]) must not pick what their own dabs made, or each dab
    /// would start on the last one and the stroke would climb towards the camera (or dig into
    /// the model): a hit inside the balls of the stroke's dabs is skipped, the ray continues
    /// where it leaves them, and if it leaves them inside solid the surface it looks for was
    /// under the stroke's own material (`None`). With no stroke, this is [`Editor::pick`].
    pub fn stroke_surface(&self, origin: DVec3, dir: DVec3, max_t: f64) -> Option<f64> {
        let len = dir.length();
        if !(len > 0.0 && len.is_finite()) {
            return None;
        }
        let dir = dir / len;
        let Some(stroke) = &self.stroke else { return self.pick(origin, dir, max_t).map(|p| p.t / len) };
        let mut t0 = 0.0;
        // Each pass leaves the union of the balls once; a ray meets it a few times at most.
        for _ in 0..16 {
            let hit = self.pick(origin + dir * t0, dir, max_t - t0)?;
            let t = t0 + hit.t;
            if !stroke.owns(origin + dir * t) {
                return Some(t / len);
            }
            let exit = stroke.exit_own(origin, dir, t);
            if exit >= max_t || self.solid_at(origin + dir * exit) {
                return None;
            }
            t0 = exit;
        }
        None
    }

    /// Whether world point `p` is inside the solid of a visible layer (or the world).
    pub fn solid_at(&self, p: DVec3) -> bool {
        crate::editor::surfaces(&self.scene.layers, self.world.as_ref())
            .into_iter()
            .filter(|l| l.shown() && l.transform().is_valid())
            .any(|l| l.volume().is_inside(l.transform().to_grid(p)))
    }

    /// [`Editor::pick`], also returning how many chunks it walked in all.
    pub fn pick_counted(&self, origin: DVec3, dir: DVec3, max_t: f64) -> (Option<Pick>, u64) {
        if !(origin.is_finite() && dir.is_finite() && dir.length_squared() > 0.0 && max_t >= 0.0) {
            return (None, 0);
        }
        // (entry parameter, layer) for every visible layer whose chunk box the ray meets.
        let surfaces = crate::editor::surfaces(&self.scene.layers, self.world.as_ref());
        let mut candidates: Vec<(f64, usize)> = surfaces
            .iter()
            .enumerate()
            .filter(|(_, l)| l.shown() && l.transform().is_valid())
            .filter_map(|(i, l)| {
                let (lo, hi) = l.volume().chunk_bounds_grid()?;
                let tr = &l.transform();
                let (t0, t1) = strata_volume::clip_to_box(tr.to_grid(origin), tr.dir_to_grid(dir), lo, hi)?;
                (t1 >= 0.0 && t0 <= max_t).then_some((t0.max(0.0), i))
            })
            .collect();
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best: Option<Pick> = None;
        let mut steps_left = PICK_CHUNK_STEPS;
        for (entry, i) in candidates {
            if best.is_some_and(|b| b.t <= entry) || steps_left == 0 {
                break;
            }
            let l = surfaces[i];
            let tr = &l.transform();
            let limit = best.map_or(max_t, |b| b.t.min(max_t));
            let (hit, walked) = l.volume().raycast_limited(tr.to_grid(origin), tr.dir_to_grid(dir), limit, steps_left);
            steps_left = steps_left.saturating_sub(walked);
            if let Some(hit) = hit
                && best.is_none_or(|b| hit.t < b.t)
            {
                best = Some(Pick {
                    layer: i,
                    t: hit.t,
                    point: tr.to_world(hit.point),
                    normal: (tr.rotation * hit.normal).normalize_or(hit.normal),
                });
            }
        }
        (best, PICK_CHUNK_STEPS - steps_left)
    }
}
