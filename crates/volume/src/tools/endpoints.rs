//! The paper's smoothing (IV-C, Eq. 1), driven by the stored crossings rather than by the
//! field: every crossing under the dab moves along its line towards the mean of its four
//! neighbours (the crossings of the same orientation on the four parallel lines beside it),
//! `p_s = w · (n_l + n_r + n_f + n_b) / 4 + (1 − w) · p`, `w` the dab's weight there.
//!
//! The paper then draws a ball of radius half the displacement between `p` and `p_s` so that
//! its segment edit stays manifold. Here the region writer keeps the lists consistent by
//! construction, and the moves are applied to the region's field directly: every node within
//! [`REACH`] nodes of moved crossings is offset by the closeness-weighted mean of their moves
//! along the outward normal. (Drawing the balls into the field instead, `min`/`max` with their
//! distances, was tried first: the linear roots then moved only part of the way and a bump's
//! apex jumped between passes, 19.09 → 18.00 → 19.00 cells, where the offset lowers it steadily.)
//!
//! A neighbour line with no crossing of the same orientation within 1.5 nodes (the surface turns
//! steeply there; the paper then samples the edges across) contributes the point where the
//! crossing's own tangent plane meets that line, or, where the plane is nearly parallel to the
//! lines, the crossing is left where it is.

use std::collections::HashMap;

use glam::DVec3;

use super::ops::{Dab, ToolError};
use crate::edit::EditReport;
use crate::volume::Volume;

/// How far (nodes, along the line) a neighbour may lie and still count as the same sheet.
const NEIGHBOUR_WINDOW: f64 = 1.5;

/// How far (nodes) from a moved crossing its move reaches into the field.
const REACH: f64 = 2.0;

/// One pass of Eq. 1 smoothing under `dab` (see the module docs).
pub(crate) fn smooth_endpoints_pass(volume: &mut Volume, dab: &Dab) -> Result<EditReport, ToolError> {
    // Crossings move by less than the neighbour window: the band's distances are enough.
    let mut region = dab.region(volume, 2, 0.0)?;
    let sp = region.spacing();
    // The crossings by line: (axis, u, v) → (position along the line, leaves the solid).
    let mut lines: HashMap<(usize, i64, i64), Vec<(f64, bool)>> = HashMap::new();
    for c in region.crossings() {
        let (ua, va) = c.axis.across();
        let key = (c.axis.index(), c.point[ua.index()].round() as i64, c.point[va.index()].round() as i64);
        lines.entry(key).or_default().push((c.point[c.axis.index()], c.normal[c.axis.index()] > 0.0));
    }
    // The moves: (midpoint of the old and new position, node units; outward distance).
    let mut moves: Vec<(DVec3, f64)> = Vec::new();
    for c in region.crossings() {
        let w = dab.weight(c.point * sp);
        if w <= 0.0 {
            continue;
        }
        let a = c.axis.index();
        let (ua, va) = c.axis.across();
        let (u, v) = (c.point[ua.index()].round() as i64, c.point[va.index()].round() as i64);
        let s = c.point[a];
        let leaving = c.normal[a] > 0.0;
        let mut sum = 0.0;
        let mut found = 0;
        for (du, dv) in [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)] {
            let near = lines.get(&(a, u + du, v + dv)).and_then(|list| {
                list.iter()
                    .filter(|&&(t, l)| l == leaving && (t - s).abs() <= NEIGHBOUR_WINDOW)
                    .map(|&(t, _)| t)
                    .min_by(|x, y| (x - s).abs().total_cmp(&(y - s).abs()))
            });
            let n = c.normal;
            let plane = || {
                // Where the crossing's tangent plane meets the neighbour line.
                (n[a].abs() > 0.3).then(|| s - (n[ua.index()] * du as f64 + n[va.index()] * dv as f64) / n[a])
            };
            if let Some(t) = near.or_else(plane) {
                sum += t;
                found += 1;
            }
        }
        if found < 4 {
            continue;
        }
        let target = w * sum / 4.0 + (1.0 - w) * s;
        let shift = target - s;
        if shift.abs() < 1e-4 {
            continue;
        }
        let mut mid = c.point;
        mid[a] = s + 0.5 * shift;
        // A crossing that leaves the solid and moves up the line, or enters it and moves down,
        // moves out of the solid; along the normal, by the shift times the normal's part along
        // the line.
        let outward = if leaving { shift } else { -shift } * c.normal[a].abs();
        moves.push((mid, outward));
    }
    // Each node within `REACH` nodes of moved crossings takes the mean of their moves along
    // the outward normal (weighted by closeness): a sheet of crossings moving together moves
    // the field's zero set with them.
    let d = region.dims;
    let origin = region.origin;
    let top = glam::I64Vec3::new(d[0] as i64 - 1, d[1] as i64 - 1, d[2] as i64 - 1);
    let (mut sum, mut weights) = (vec![0.0f64; region.phi.len()], vec![0.0f64; region.phi.len()]);
    for &(at, outward) in &moves {
        let lo = ((at - DVec3::splat(REACH)).floor().as_i64vec3() - origin).max(glam::I64Vec3::ZERO);
        let hi = ((at + DVec3::splat(REACH)).ceil().as_i64vec3() - origin).min(top);
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let g = (origin + glam::I64Vec3::new(x, y, z)).as_dvec3();
                    let k = 1.0 - (g - at).length() / REACH;
                    if k > 0.0 {
                        let i = x as usize + d[0] * (y as usize + d[1] * z as usize);
                        sum[i] += k * outward;
                        weights[i] += k;
                    }
                }
            }
        }
    }
    let mut phi = std::mem::take(&mut region.phi);
    for i in 0..phi.len() {
        if weights[i] > 0.0 {
            phi[i] -= (sum[i] / weights[i]) as f32;
        }
    }
    region.phi = phi;
    Ok(volume.write_region(&region)?)
}
