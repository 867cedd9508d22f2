//! The distance field from the stored crossings: the band (each crossing's tangent plane and
//! distance in the nodes within [`BAND`] of it), and beyond it the nearest crossing propagated
//! from node to node.

use glam::{DVec3, I64Vec3};

use rayon::prelude::*;

use super::read::RowSpans;
use super::{BAND, RegionCrossing};

/// The width of the band's fixed-width rows: the 7 nodes a ball of radius [`BAND`] spans along x,
/// and one more.
const LANES: usize = 8;

/// Per node of a region, from the crossings within [`BAND`] nodes of it (infinite where there is
/// none): the squared distance to the nearest, the squared lateral distance of the crossing
/// whose normal line passes closest, and that crossing's tangent-plane distance.
pub(super) struct Band {
    pub(super) near2: Vec<f32>,
    pub(super) lateral2: Vec<f32>,
    pub(super) plane: Vec<f32>,
    /// The nearest crossing's index in the crossings (`u32::MAX`: none), when asked for; else
    /// empty.
    pub(super) nearest: Vec<u32>,
}

/// The band of `crossings` (points in node units, unit normals) over the nodes `spans` holds of
/// the region at `origin` with `dims` (the rest stay infinite), leaving out the crossings `skip`
/// refuses. On a smooth surface the crossing whose normal line passes closest to a node sits
/// near the node's foot point, so its plane's distance is the surface's to a small fraction of a
/// cell; where no normal line passes near, at edges and corners, the distance to the nearest
/// crossing is used instead (see the read).
pub(super) fn band(
    crossings: &[RegionCrossing],
    skip: impl Fn(DVec3) -> bool,
    origin: I64Vec3,
    dims: [usize; 3],
    spans: &RowSpans,
    with_nearest: bool,
) -> Band {
    let count = dims[0] * dims[1] * dims[2];
    let mut out = Band {
        near2: vec![f32::INFINITY; count],
        lateral2: vec![f32::INFINITY; count],
        plane: vec![f32::INFINITY; count],
        nearest: if with_nearest { vec![u32::MAX; count] } else { Vec::new() },
    };
    let kept: Vec<u32> = (0..crossings.len() as u32).filter(|&k| !skip(crossings[k as usize].point)).collect();
    // Slabs of z planes, each written by the crossings whose balls reach it, in the crossings'
    // order: the same values whatever the slabs, so on several cores the slabs run in parallel.
    let threads = rayon::current_num_threads();
    let planes = if threads > 1 && count >= PARALLEL_NODES { dims[2].div_ceil(threads * 4).max(1) } else { dims[2] };
    let plane_len = dims[0] * dims[1];
    let mut slabs = Vec::new();
    let (mut near2, mut lateral2, mut plane) = (&mut out.near2[..], &mut out.lateral2[..], &mut out.plane[..]);
    let mut nearest = &mut out.nearest[..];
    let mut z = 0;
    while z < dims[2] {
        let end = (z + planes).min(dims[2]);
        let len = (end - z) * plane_len;
        let (a, rest) = std::mem::take(&mut near2).split_at_mut(len);
        near2 = rest;
        let (b, rest) = std::mem::take(&mut lateral2).split_at_mut(len);
        lateral2 = rest;
        let (c, rest) = std::mem::take(&mut plane).split_at_mut(len);
        plane = rest;
        let (d, rest) = std::mem::take(&mut nearest).split_at_mut(if with_nearest { len } else { 0 });
        nearest = rest;
        slabs.push(Slab { z: z..end, near2: a, lateral2: b, plane: c, nearest: d });
        z = end;
    }
    let fill = |slab: Slab<'_>| fill_slab(slab, crossings, &kept, origin, dims, spans, with_nearest);
    if slabs.len() > 1 {
        slabs.into_par_iter().for_each(fill);
    } else {
        slabs.into_iter().for_each(fill);
    }
    out
}

/// Band reads of at least this many nodes split into slabs on several cores.
const PARALLEL_NODES: usize = 1 << 15;

/// The z planes `z` of a band's arrays.
struct Slab<'a> {
    z: std::ops::Range<usize>,
    near2: &'a mut [f32],
    lateral2: &'a mut [f32],
    plane: &'a mut [f32],
    /// Empty unless the nearest crossings are asked for.
    nearest: &'a mut [u32],
}

/// The band of the `kept` crossings in one slab (see [`band`]).
fn fill_slab(
    slab: Slab<'_>,
    crossings: &[RegionCrossing],
    kept: &[u32],
    origin: I64Vec3,
    dims: [usize; 3],
    spans: &RowSpans,
    with_nearest: bool,
) {
    let Slab { z: planes, near2, lateral2, plane, nearest } = slab;
    let first_row = planes.start * dims[1];
    let b2 = (BAND * BAND) as f32;
    for &k in kept {
        let RegionCrossing { point: p, normal: nrm, .. } = crossings[k as usize];
        // The nodes of the ball of radius BAND about the crossing, row by row (a row's x range
        // from what is left of the radius), so no node outside it is visited. Offsets from the
        // crossing are small: single precision holds them to a millionth of a node.
        let local = p - origin.as_dvec3();
        let (lx, ly, lz) = (local.x as f32, local.y as f32, local.z as f32);
        let n = nrm.as_vec3();
        let z0 = (local.z - BAND).ceil().max(planes.start as f64) as usize;
        let z1 = (local.z + BAND).floor().min(planes.end as f64 - 1.0);
        let y0 = (local.y - BAND).ceil().max(0.0) as usize;
        let y1 = (local.y + BAND).floor().min(dims[1] as f64 - 1.0);
        if z1 < z0 as f64 || y1 < 0.0 {
            continue;
        }
        // The x lanes of the ball: from the first node within BAND below the crossing, when all
        // eight lie in the region's rows.
        let first = (local.x - BAND).ceil();
        let full_width = (first >= 0.0 && first + LANES as f64 <= dims[0] as f64).then_some(first as usize);
        let (mut lane_x, mut lane_dx) = ([0f32; LANES], [0f32; LANES]);
        for j in 0..LANES {
            lane_x[j] = (first + j as f64) as f32;
            lane_dx[j] = ((first + j as f64) - local.x) as f32;
        }
        for z in z0..=z1 as usize {
            let dz = z as f32 - lz;
            for y in y0..=y1 as usize {
                let dy = y as f32 - ly;
                let dyz2 = dy * dy + dz * dz;
                let left = b2 - dyz2;
                if left < 0.0 {
                    continue;
                }
                let along_yz = n.y * dy + n.z * dz;
                let row = (y + dims[1] * z - first_row) * dims[0];
                let (slo, shi) = spans.row(y, z);
                if let (Some(xb), false) = (full_width, with_nearest) {
                    // Eight lanes from `xb` (all inside the row), the ball's and the span's
                    // ends as a mask: fixed-width arithmetic without branches, which the
                    // compiler vectorises, instead of a short loop per row.
                    let base = row + xb;
                    let (slo, shi) = (slo as f32, shi as f32);
                    let lane_near2: &mut [f32; LANES] = (&mut near2[base..base + LANES]).try_into().expect("lanes");
                    let lane_lateral2: &mut [f32; LANES] =
                        (&mut lateral2[base..base + LANES]).try_into().expect("lanes");
                    let lane_plane: &mut [f32; LANES] = (&mut plane[base..base + LANES]).try_into().expect("lanes");
                    let (mut nd, mut la, mut pl) = (*lane_near2, *lane_lateral2, *lane_plane);
                    for j in 0..LANES {
                        let (x, dx) = (lane_x[j], lane_dx[j]);
                        let held = (dx * dx <= left) & (x >= slo) & (x < shi);
                        let d2 = if held { dx * dx + dyz2 } else { f32::INFINITY };
                        nd[j] = if d2 < nd[j] { d2 } else { nd[j] };
                        let along = n.x * dx + along_yz;
                        let l2 = d2 - along * along;
                        let better = l2 < la[j];
                        la[j] = if better { l2 } else { la[j] };
                        pl[j] = if better { along.abs() } else { pl[j] };
                    }
                    (*lane_near2, *lane_lateral2, *lane_plane) = (nd, la, pl);
                    continue;
                }
                let half = left.sqrt();
                let x0 = ((lx - half).ceil().max(0.0) as usize).max(slo);
                let x1 = (((lx + half).floor() + 1.0).max(0.0) as usize).min(shi);
                for x in x0..x1 {
                    let i = row + x;
                    let dx = x as f32 - lx;
                    let d2 = dx * dx + dyz2;
                    if d2 < near2[i] {
                        near2[i] = d2;
                        if with_nearest {
                            nearest[i] = k;
                        }
                    }
                    let along = n.x * dx + along_yz;
                    let l2 = d2 - along * along;
                    if l2 < lateral2[i] {
                        lateral2[i] = l2;
                        plane[i] = along.abs();
                    }
                }
            }
        }
    }
}

/// Propagates each node's nearest crossing (`nearest`, with its distance `dist`) to the
/// `needed` nodes beyond the band (those whose `dist` is infinite on entry; nodes in the band
/// already know theirs exactly), comparing squared distances.
pub(super) fn sweep_nearest(
    nearest: &mut [u32],
    dist: &mut [f64],
    samples: &[DVec3],
    origin: I64Vec3,
    dims: [usize; 3],
    needed: &[bool],
) {
    if samples.is_empty() {
        return;
    }
    let open: Vec<bool> = dist.iter().zip(needed).map(|(d, &n)| n && !d.is_finite()).collect();
    if !open.iter().any(|&o| o) {
        return;
    }
    let mut d2: Vec<f64> = dist.iter().map(|d| d * d).collect();
    let steps = [1, dims[0] as i64, (dims[0] * dims[1]) as i64];
    // The 13 neighbours before a node in storage order (a forward pass reads them) and the 13
    // after it (a backward pass): two passes propagate a nearest crossing in every direction, as
    // a two-pass chamfer transform does; a third catches most of what bends around (0.13 cells
    // at worst on the test sphere, against 0.17 after two passes and 0.12 after four).
    let mut before = Vec::new();
    for dz in -1i64..=1 {
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let off = dx + steps[1] * dy + steps[2] * dz;
                if off < 0 {
                    before.push(([dx, dy, dz], off));
                }
            }
        }
    }
    let count = dims[0] * dims[1] * dims[2];
    for pass in 0..3 {
        let forward = pass % 2 == 0;
        for step in 0..count {
            let i = if forward { step } else { count - 1 - step };
            if !open[i] {
                continue;
            }
            let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1]));
            let q = (origin + I64Vec3::new(x as i64, y as i64, z as i64)).as_dvec3();
            for &(d, off) in &before {
                let (d, off) = if forward { (d, off) } else { ([-d[0], -d[1], -d[2]], -off) };
                let (nx, ny, nz) = (x as i64 + d[0], y as i64 + d[1], z as i64 + d[2]);
                if nx < 0 || ny < 0 || nz < 0 || nx >= dims[0] as i64 || ny >= dims[1] as i64 || nz >= dims[2] as i64 {
                    continue;
                }
                let k = nearest[(i as i64 + off) as usize];
                if k == u32::MAX || k == nearest[i] {
                    continue;
                }
                let dd = (q - samples[k as usize]).length_squared();
                if dd < d2[i] {
                    d2[i] = dd;
                    nearest[i] = k;
                }
            }
        }
    }
    for (d, s) in dist.iter_mut().zip(&d2) {
        *d = s.sqrt();
    }
}

/// Grows each band node's nearest crossing (`nearest`, distance `dist`) out to the `open` nodes
/// beyond the band that lie within `depth` (nodes) of a crossing, layer by layer through the 26
/// neighbours: a node takes a neighbour's nearest crossing when that is closer than its own, and
/// a node that improved passes it on in the next layer. Only the band's outer shell starts (a
/// node within `BAND − √3` of its crossing has all its neighbours in the band), so the work
/// follows the surface times the depth, not the region's volume.
pub(super) fn grow_nearest(
    nearest: &mut [u32],
    dist: &mut [f64],
    samples: &[DVec3],
    origin: I64Vec3,
    dims: [usize; 3],
    open: &[bool],
    depth: f64,
) {
    if samples.is_empty() || depth <= BAND {
        return;
    }
    let count = dims[0] * dims[1] * dims[2];
    let inner = BAND - 3f64.sqrt();
    let mut frontier: Vec<usize> = (0..count).filter(|&i| dist[i].is_finite() && dist[i] > inner).collect();
    let mut stamp = vec![0u32; count];
    let mut d2: Vec<f64> = dist.iter().map(|d| d * d).collect();
    let limit2 = (depth + 1.0) * (depth + 1.0);
    let point = |i: usize| {
        let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1]));
        (origin + I64Vec3::new(x as i64, y as i64, z as i64)).as_dvec3()
    };
    let mut layer = 0u32;
    // Each layer moves at least one node step outwards, so depth − band + 2 layers reach the
    // depth; a few more settle nodes that a bent path reached first.
    let max_layers = (depth - BAND).ceil() as u32 + 4;
    while !frontier.is_empty() && layer < max_layers {
        layer += 1;
        let mut next = Vec::new();
        for &i in &frontier {
            let k = nearest[i];
            let p = samples[k as usize];
            let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1]));
            for dz in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (nx, ny, nz) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                        if nx < 0
                            || ny < 0
                            || nz < 0
                            || nx >= dims[0] as i64
                            || ny >= dims[1] as i64
                            || nz >= dims[2] as i64
                        {
                            continue;
                        }
                        let j = nx as usize + dims[0] * (ny as usize + dims[1] * nz as usize);
                        if !open[j] || nearest[j] == k {
                            continue;
                        }
                        let dd = (point(j) - p).length_squared();
                        if dd < d2[j] && dd <= limit2 {
                            d2[j] = dd;
                            nearest[j] = k;
                            if stamp[j] != layer {
                                stamp[j] = layer;
                                next.push(j);
                            }
                        }
                    }
                }
            }
        }
        frontier = next;
    }
    for (d, s) in dist.iter_mut().zip(&d2) {
        *d = s.sqrt();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_crossing_sweep_finds_the_nearest_crossing() {
        // Samples on a sphere of radius 10, a cell apart on grid lines, as stored crossings are.
        let c = DVec3::new(20.3, 19.7, 20.1);
        let mut samples = Vec::new();
        for a in 0..3 {
            for u in 5..36 {
                for v in 5..36 {
                    let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
                    let (du, dv) = (u as f64 - c[ua], v as f64 - c[va]);
                    let h = 100.0 - du * du - dv * dv;
                    if h <= 0.0 {
                        continue;
                    }
                    for s in [-1.0, 1.0] {
                        let mut p = DVec3::ZERO;
                        p[ua] = u as f64;
                        p[va] = v as f64;
                        p[a] = c[a] + s * h.sqrt();
                        samples.push((p, (p - c).normalize()));
                    }
                }
            }
        }
        let origin = I64Vec3::splat(6);
        let dims = [29, 29, 29];
        let count = 29 * 29 * 29;
        let (mut nearest, mut dist) = (vec![u32::MAX; count], vec![f64::INFINITY; count]);
        // Seeded as `read_region` seeds it: every node within the band of a crossing.
        for (k, &(p, _)) in samples.iter().enumerate() {
            for z in 0..29usize {
                for y in 0..29usize {
                    for x in 0..29usize {
                        let j = x + 29 * (y + 29 * z);
                        let d = (p - (origin + I64Vec3::new(x as i64, y as i64, z as i64)).as_dvec3()).length();
                        if d <= BAND && d < dist[j] {
                            dist[j] = d;
                            nearest[j] = k as u32;
                        }
                    }
                }
            }
        }
        let points: Vec<DVec3> = samples.iter().map(|s| s.0).collect();
        sweep_nearest(&mut nearest, &mut dist, &points, origin, dims, &vec![true; count]);
        let mut worst = 0.0f64;
        for z in 0..29 {
            for y in 0..29 {
                for x in 0..29 {
                    let q = (origin + I64Vec3::new(x, y, z)).as_dvec3();
                    let exact = samples.iter().map(|(p, _)| (q - *p).length()).fold(f64::INFINITY, f64::min);
                    let e = dist[x as usize + 29 * (y as usize + 29 * z as usize)] - exact;
                    worst = worst.max(e);
                }
            }
        }
        // Propagating one crossing per node through its 26 neighbours is not an exact nearest-
        // point search: on this sphere it overestimates by at most 0.13 cells, beyond the band.
        assert!(worst < 0.15, "the sweep is {worst} cells off the nearest crossing");
    }
}
