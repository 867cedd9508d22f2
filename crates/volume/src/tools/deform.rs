//! Deformation tools: grab and pinch move the surface with a displacement field instead of
//! changing the field's values in place.
//!
//! A deformation is a sequence of small maps `x → x + δₖ(x)`, each moving no point by more than
//! [`MAX_STEP`] nodes and each with `|∇δₖ| < 1`, so each map is one-to-one and onto: it cannot
//! fold the surface over itself or tear it open, and neither can their composition, however
//! many steps a long drag takes. The new field at a node `p` is the field as read at the point
//! that ends at `p`: `p` traced back through the steps (`q ← q − δₖ(q)`, last step first) and
//! the region's field sampled there once, so a long drag blurs no more than a short one (no
//! repeated resampling). Nodes that no step moves keep their field, so the region's
//! exact-preservation rule leaves everything outside the brush's path bit for bit.

use glam::DVec3;

use super::ops::{Dab, ToolError, falloff, finite};
use super::region::{Reach, Region, RowSpans};
use crate::edit::EditReport;
use crate::volume::Volume;

/// The most a deformation step moves a point, in nodes (the paper's 0.3-cell bound on a
/// vertex's step).
pub const MAX_STEP: f64 = 0.3;

/// The most steps one deformation takes (a drag of 30,000 nodes at full strength).
pub const MAX_STEPS: usize = 100_000;

/// Moves `region`'s surface by `steps` maps `x → x + δ(k, x)` (grid units, see the module
/// docs) and writes it back. `moved` bounds where any step moves a point: within the distance
/// `moved.2` of the segment from `moved.0` to `moved.1`.
fn deform(
    volume: &mut Volume,
    mut region: Region,
    moved: (DVec3, DVec3, f64),
    steps: usize,
    delta: impl Fn(usize, DVec3) -> DVec3,
) -> Result<EditReport, ToolError> {
    let d = region.dims;
    // Nodes farther than `moved.2` from the segment `moved.0`–`moved.1` (grid units) no step
    // moves: they keep weight 0.
    let inv_sp = 1.0 / region.spacing();
    let spans = RowSpans::near_segment(region.origin, d, moved.0 * inv_sp, moved.1 * inv_sp, moved.2 * inv_sp + 1.0);
    for z in 0..d[2] {
        for y in 0..d[1] {
            let (x0, x1) = spans.row(y, z);
            for x in x0..x1 {
                let p = region.grid_point(x, y, z);
                let mut q = p;
                for k in (0..steps).rev() {
                    q -= delta(k, q);
                }
                let i = region.index(x, y, z);
                if q != p {
                    region.phi[i] = region.sample_original(q);
                    region.weight[i] = 1.0;
                } else {
                    region.weight[i] = 0.0;
                }
            }
        }
    }
    Ok(volume.write_region(&region)?)
}

/// How many steps a displacement of at most `largest` grid units per dab needs so that each
/// moves a point by at most [`MAX_STEP`] nodes and stays one-to-one for a falloff of `radius`
/// (the falloff's slope is at most 16/9 per radius, so a step below 9/32 of the radius keeps
/// `|∇δ| ≤ 1/2`).
fn step_count(largest: f64, radius: f64, spacing: f64) -> Result<usize, ToolError> {
    let per_step = (MAX_STEP * spacing).min(radius * 9.0 / 32.0);
    let steps = (largest / per_step).ceil();
    if !(steps <= MAX_STEPS as f64) {
        return Err(ToolError::BadParameter { what: "the drag (at most 100,000 steps of 0.3 nodes)", positive: false });
    }
    Ok((steps as usize).max(1))
}

/// Grab: drags the surface under the dab by `drag` (grid units), the brush following the
/// material under its centre. A point at distance `t · radius` from the (moving) centre moves
/// by `strength · falloff(t)` of each step, so the surface at the centre moves by
/// `strength · drag` and the rim stays put. However far the drag, the surface is neither torn
/// nor folded (see the module docs); a drag longer than the region limit allows is refused.
pub fn grab(volume: &mut Volume, dab: &Dab, drag: DVec3) -> Result<EditReport, ToolError> {
    if !drag.is_finite() {
        return Err(ToolError::BadParameter { what: "the drag", positive: false });
    }
    let travel = drag * dab.strength;
    let r = DVec3::splat(dab.radius);
    let (lo, hi) = (dab.center.min(dab.center + travel) - r, dab.center.max(dab.center + travel) + r);
    let sp = volume.level_near(lo, hi).spacing();
    let steps = step_count(travel.length(), dab.radius, sp)?;
    if travel == DVec3::ZERO {
        return Ok(EditReport { changed: Vec::new(), undo: Default::default(), repaired_nodes: 0, reach: None });
    }
    let region = volume.read_region_within(
        lo,
        hi,
        2,
        // (The field is sampled where the surface was: the band's distances are enough.)
        Reach::Capsule { a: dab.center, b: dab.center + travel, radius: dab.radius, depth: 0.0 },
    )?;
    let step = travel / steps as f64;
    let (c0, radius, r2) = (dab.center, dab.radius, dab.radius * dab.radius);
    deform(volume, region, (c0, c0 + travel, radius), steps, |k, q| {
        let c = c0 + step * k as f64;
        let off = q - c;
        let d2 = off.length_squared();
        if d2 >= r2 { DVec3::ZERO } else { step * falloff(d2.sqrt() / radius) }
    })
}

/// Pinch: pulls the surface under the dab sideways towards the dab's centre line, the line
/// through its centre along `axis` (a stroke's direction; `None` for a single dab, which pulls
/// towards the centre point). Movement along the surface's normal at the centre (the region
/// field's gradient there) is taken out, so the surface gathers into a crease rather than
/// sinking. A point at distance `t · radius` moves `amount · strength · falloff(t)` of its way
/// to the line (`amount` in `[-1, 1]`; a negative amount pushes away from the line: magnify).
pub fn pinch(volume: &mut Volume, dab: &Dab, axis: Option<DVec3>, amount: f64) -> Result<EditReport, ToolError> {
    let amount = finite("the pinch amount", amount)?;
    if !(-1.0..=1.0).contains(&amount) {
        return Err(ToolError::BadParameter { what: "the pinch amount (in [-1, 1])", positive: false });
    }
    let axis = match axis {
        Some(a) if !a.is_finite() => return Err(ToolError::BadParameter { what: "the pinch axis", positive: false }),
        Some(a) => a.normalize_or_zero(),
        None => DVec3::ZERO,
    };
    let r = DVec3::splat(dab.radius);
    let region =
        volume.read_region_within(dab.center - r, dab.center + r, 2, Reach::ball(dab.center, dab.radius, 0.0))?;
    let sp = region.spacing();
    let normal = field_normal(&region, dab.center);
    // Only the part of `c − x` across the normal and the line's axis (the axis made
    // perpendicular to the normal first, so the two projections are exact together).
    let axis = (axis - normal * normal.dot(axis)).normalize_or_zero();
    let across = move |v: DVec3| v - normal * normal.dot(v) - axis * axis.dot(v);
    let pull = amount * dab.strength;
    // The largest move: `pull · t · falloff(t) · radius`, at most 0.45 · pull · radius.
    // At most a quarter of the way per step keeps each step one-to-one.
    let steps = step_count(0.45 * pull.abs() * dab.radius, dab.radius, sp)?.max((4.0 * pull.abs()).ceil() as usize);
    let per = pull / steps as f64;
    let (c, radius, r2) = (dab.center, dab.radius, dab.radius * dab.radius);
    deform(volume, region, (c, c, radius), steps, move |_, q| {
        let off = q - c;
        let d2 = off.length_squared();
        if d2 >= r2 { DVec3::ZERO } else { across(-off) * (per * falloff(d2.sqrt() / radius)) }
    })
}

/// The unit gradient of the region's field (as read) at grid point `p`, or zero where it has
/// none.
pub(crate) fn field_normal(region: &Region, p: DVec3) -> DVec3 {
    let h = region.spacing();
    let g = DVec3::new(
        (region.sample_original(p + DVec3::X * h) - region.sample_original(p - DVec3::X * h)) as f64,
        (region.sample_original(p + DVec3::Y * h) - region.sample_original(p - DVec3::Y * h)) as f64,
        (region.sample_original(p + DVec3::Z * h) - region.sample_original(p - DVec3::Z * h)) as f64,
    );
    if g.is_finite() { g.normalize_or_zero() } else { DVec3::ZERO }
}
