//! Dual contouring with Hermite data: one vertex per cell with a sign change, placed by the QEF
//! of the cell's edge crossings and clamped to the cell grown by half a cell; one quad per sign-changing edge joining
//! the four cells around it, split into two triangles along the flatter diagonal.
//!
//! Chunk borders: every block computes the vertices of its own cells; quads are emitted for the
//! edges each block owns (lower node inside the block on the two across axes), looking the four
//! cells up in a volume-wide map, so quads that straddle chunks join vertices of up to four
//! chunks and the mesh has no cracks. The result is closed; a cell whose surface has several
//! sheets gets one vertex for all of them, which can make edges non-manifold
//! ([`crate::checks::manifold_report`] counts them).

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::{DVec3, I64Vec3, Vec3};
use rayon::prelude::*;
use strata_volume::normal::unpack_normal;
use strata_volume::{Axis, KeyHasher, Volume, VoxelBlock};

use crate::Mesh;
use crate::qef::Qef;

/// How far (in cells) a vertex may leave its cell: half a cell, so vertices of neighbouring
/// cells can meet but never cross. With 0 the tips of rotated box corners were cut by up to
/// 0.4 cells (test `box_corners_come_out_sharp`).
pub const CELL_MARGIN: f64 = 0.5;

/// A cell vertex: global cell (level units), position (grid units), normal.
type CellVertex = (I64Vec3, DVec3, Vec3);
/// An owned sign-changing edge: axis, global lower node, whether the lower node is inside.
type OwnedEdge = (Axis, I64Vec3, bool);

fn block_part(block: &VoxelBlock) -> (Vec<CellVertex>, Vec<OwnedEdge>) {
    let n = block.cells();
    let sp = block.level().spacing();
    let origin_nodes = block.origin_grid() / 16 * n as i64;
    let origin = block.origin_grid().as_dvec3();
    let mut vertices = Vec::new();
    let mut edges = Vec::new();
    for z in 0..n {
        for y in 0..n {
            let mut mixed = block.mixed_cells(y, z);
            while mixed != 0 {
                let x = mixed.trailing_zeros() as usize;
                mixed &= mixed - 1;
                let mut qef = Qef::default();
                let mut normal = DVec3::ZERO;
                for (axis, lower, c) in block.cell_crossings(x, y, z) {
                    let mut p =
                        DVec3::new(lower[0] as f64 - x as f64, lower[1] as f64 - y as f64, lower[2] as f64 - z as f64);
                    p[axis.index()] += c.t as f64;
                    let nrm = unpack_normal(c.normal);
                    qef.add(p, nrm);
                    normal += nrm;
                }
                // Clamp to the cell grown by CELL_MARGIN: a corner whose tip holds no node lies in
                // a cell without a sign change, and the neighbouring cell's vertex must be free
                // to reach it; the margin keeps vertices near the cell they stand for.
                let local = qef.solve().clamp(DVec3::splat(-CELL_MARGIN), DVec3::splat(1.0 + CELL_MARGIN));
                let cell = I64Vec3::new(x as i64, y as i64, z as i64);
                let pos = origin + (cell.as_dvec3() + local) * sp;
                vertices.push((origin_nodes + cell, pos, normal.normalize_or(DVec3::Z).as_vec3()));
            }
        }
    }
    for axis in Axis::ALL {
        let (ua, va) = axis.across();
        for c in block.crossings(axis) {
            let lower = c.lower.map(|v| v as usize);
            if lower[ua.index()] >= n || lower[va.index()] >= n {
                continue; // apron edge, owned by a neighbour
            }
            let g = origin_nodes + I64Vec3::new(lower[0] as i64, lower[1] as i64, lower[2] as i64);
            edges.push((axis, g, block.inside(lower[0], lower[1], lower[2])));
        }
    }
    (vertices, edges)
}

/// One welded dual-contouring mesh of the whole volume (grid units, absolute).
pub fn dual_contour_volume(volume: &Volume) -> Mesh {
    let keys = crate::surface_chunks(volume);
    let parts: Vec<(Vec<CellVertex>, Vec<OwnedEdge>)> = keys
        .par_iter()
        .map_init(VoxelBlock::default, |block, &key| {
            volume.extract_block_into(key, block);
            block_part(block)
        })
        .collect();
    let mut out = Mesh::default();
    let mut cell_index: HashMap<I64Vec3, u32, BuildHasherDefault<KeyHasher>> = HashMap::default();
    for (vertices, _) in &parts {
        for (cell, pos, normal) in vertices {
            cell_index.insert(*cell, out.positions.len() as u32);
            out.positions.push(pos.as_vec3().to_array());
            out.normals.push(normal.to_array());
        }
    }
    for (_, edges) in &parts {
        for &(axis, g, lower_inside) in edges {
            let (ua, va) = axis.across();
            let (eu, ev) = (ua.unit_i64(), va.unit_i64());
            // Counter-clockwise around +axis: the quad faces +axis.
            let ring = [g - eu - ev, g - ev, g, g - eu];
            let Some(ids) = ring.iter().map(|c| cell_index.get(c).copied()).collect::<Option<Vec<u32>>>() else {
                continue; // unreachable for volumes built by edits: every such cell is meshed
            };
            let mut q = [ids[0], ids[1], ids[2], ids[3]];
            // Outward is +axis when the lower node is inside.
            if !lower_inside {
                q.reverse();
            }
            let p = q.map(|i| Vec3::from(out.positions[i as usize]));
            let flat = |a: usize, b: usize, c: usize, d: usize| {
                let n1 = (p[b] - p[a]).cross(p[c] - p[a]).normalize_or_zero();
                let n2 = (p[c] - p[a]).cross(p[d] - p[a]).normalize_or_zero();
                n1.dot(n2)
            };
            // Split along the diagonal whose two triangles agree more.
            if flat(0, 1, 2, 3) >= flat(1, 2, 3, 0) {
                out.indices.extend_from_slice(&[q[0], q[1], q[2], q[0], q[2], q[3]]);
            } else {
                out.indices.extend_from_slice(&[q[1], q[2], q[3], q[1], q[3], q[0]]);
            }
        }
    }
    out
}
