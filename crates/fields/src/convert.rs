//! Building the scalar fields from a segment volume (for the memory comparison on converted
//! meshes): distances near the surface are estimated from the crossings and their normals.
//!
//! A node's distance estimate combines the distances `d_x`, `d_y`, `d_z` to the nearest crossing
//! on each of its three grid lines as `1 / sqrt(Σ 1/d_a²)`, exact for a plane (the classic
//! initialisation of fast-marching methods); crossings farther than `b√3` along a line are not
//! looked at (for a plane within `b` of the node, the line closest to its normal meets it within
//! `b√3`). Signs come from the volume's node states, so the fields' node states equal the
//! volume's exactly.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::I64Vec3;
use strata_volume::{Axis, Chunk, ChunkKey, KeyHasher, Volume, VoxelBlock};

use crate::dense::FAR;
use crate::{DenseField, FieldError, N, NODES, NarrowBandField, index};

/// Unsigned distance estimates (capped at `band`) for every chunk owning a node within `band` of
/// a crossing, with the volume's node states applied as signs; values beyond the band are
/// `±outside_value`. Also every solid chunk, all `-outside_value`.
fn signed_band(volume: &Volume, band: f32, outside_value: f32) -> Vec<(ChunkKey, Box<[f32]>)> {
    let mut slot: HashMap<ChunkKey, usize, BuildHasherDefault<KeyHasher>> = HashMap::default();
    let mut bufs: Vec<(ChunkKey, Box<[f32]>)> = Vec::new();
    let reach = band * 3f32.sqrt();
    let mut block = VoxelBlock::default();
    let n = N as i64;
    for (key, chunk) in volume.chunks() {
        if !matches!(chunk, Chunk::Lists(_)) {
            continue;
        }
        volume.extract_block_into(key, &mut block);
        let origin = key.origin_grid();
        let mut last: Option<(ChunkKey, usize)> = None;
        for axis in Axis::ALL {
            let a = axis.index();
            for c in block.crossings(axis) {
                if c.lower.iter().any(|&l| l as usize >= N) {
                    continue; // a copy of a neighbour's crossing
                }
                let limit = reach;
                let pos = c.lower[a] as f32 + c.t;
                let first = (pos - limit).ceil() as i64;
                let last_node = (pos + limit).floor() as i64;
                for j in first..=last_node {
                    let d = (j as f32 - pos).abs();
                    let mut local = [c.lower[0] as i64, c.lower[1] as i64, c.lower[2] as i64];
                    local[a] = j;
                    let g = origin + I64Vec3::from_array(local);
                    let k = g.div_euclid(I64Vec3::splat(n));
                    let l = (g - k * n).as_uvec3();
                    let k = ChunkKey(k.as_ivec3());
                    let i = match last {
                        Some((lk, i)) if lk == k => i,
                        _ => {
                            let i = *slot.entry(k).or_insert_with(|| {
                                bufs.push((k, vec![f32::INFINITY; 3 * NODES].into()));
                                bufs.len() - 1
                            });
                            last = Some((k, i));
                            i
                        }
                    };
                    let v = &mut bufs[i].1[3 * index(l.x as usize, l.y as usize, l.z as usize) + a];
                    *v = v.min(d);
                }
            }
        }
    }
    // Signs from the node states; nodes the band did not reach get ±outside_value.
    let mut out = Vec::with_capacity(bufs.len());
    for (key, per_axis) in bufs {
        let chunk = volume.chunk(key);
        let lists = matches!(chunk, Some(Chunk::Lists(_)));
        if lists {
            volume.extract_block_into(key, &mut block);
        }
        let mut values: Box<[f32]> = vec![0.0; NODES].into();
        for z in 0..N {
            for y in 0..N {
                for x in 0..N {
                    let i = index(x, y, z);
                    let inv: f32 = per_axis[3 * i..3 * i + 3].iter().map(|d| 1.0 / (d * d)).sum();
                    let d = 1.0 / inv.sqrt();
                    let inside = match chunk {
                        Some(Chunk::Solid) => true,
                        Some(Chunk::Lists(_)) => block.inside(x, y, z),
                        None => false,
                    };
                    let d = if d >= band { outside_value } else { d };
                    values[i] = if inside { -d } else { d.max(1e-6) };
                }
            }
        }
        out.push((key, values));
    }
    for (key, chunk) in volume.chunks() {
        if matches!(chunk, Chunk::Solid) && !slot.contains_key(&key) {
            out.push((key, vec![-outside_value; NODES].into()));
        }
    }
    out
}

impl NarrowBandField {
    /// The narrow band of a segment volume (base level): distances estimated from the crossings
    /// (see the module docs), clamped to `±band`, signs from the volume's node states.
    pub fn from_volume(volume: &Volume, band: f32) -> Result<NarrowBandField, FieldError> {
        let mut f = NarrowBandField::new(band)?;
        for (key, values) in signed_band(volume, band, band) {
            f.insert_encoded(key, &values);
        }
        Ok(f)
    }
}

impl DenseField {
    /// A dense field of a segment volume (base level): distances estimated within `band` cells
    /// of the surface, [`FAR`] beyond (negated inside). It allocates the chunks a narrow band of
    /// the same width stores: every chunk with an inside node or a node near the surface.
    pub fn from_volume(volume: &Volume, band: f32) -> Result<DenseField, FieldError> {
        if !(band.is_finite() && band > 0.0) {
            return Err(FieldError::BadBand(band));
        }
        let mut f = DenseField::new();
        for (key, values) in signed_band(volume, band, FAR) {
            // Like the narrow band, store no chunk that is all far outside.
            if values.iter().any(|&v| v != FAR) {
                f.insert_chunk(key, values);
            }
        }
        Ok(f)
    }
}
