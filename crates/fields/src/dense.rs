//! The dense signed-distance baseline: an `f32` per node in 16³-node chunks.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::{DVec3, I64Vec3};
use strata_volume::brush::Brush;
use strata_volume::{ChunkKey, CsgOp, KeyHasher, VoxelBlock, hash_table_bytes};

use crate::{
    FieldError, N, NODES, PaddedValues, edit_chunks, edit_targets, edit_values, gather, index, neighbourhood, outside,
};

/// Nodes within this many cells of a brush's bounds are updated: the crossings next to the
/// brush interpolate fresh values, and so do the central differences that give their normals.
const MARGIN: f64 = 2.0;

/// The most chunks one smoothing dab may cover (a ball of radius about 250 cells).
pub const MAX_BLUR_CHUNKS: u64 = 1 << 15;

/// The magnitude at which [`DenseField::smooth_box_blur`] saturates the values it reads (cells).
pub const BLUR_CLAMP: f32 = 4.0;

/// The value of every node no edit has touched: far outside.
pub const FAR: f32 = 1.0e6;

type Map<V> = HashMap<ChunkKey, V, BuildHasherDefault<KeyHasher>>;

/// A signed distance per node (`f32`, negative inside), stored in 16³-node chunks allocated where
/// an edit reaches. Untouched nodes are [`FAR`] outside.
#[derive(Clone, Debug, Default)]
pub struct DenseField {
    chunks: Map<Box<[f32]>>,
}

impl DenseField {
    /// An empty field.
    pub fn new() -> Self {
        Self::default()
    }

    /// Bytes of one chunk's values.
    pub const CHUNK_BYTES: usize = NODES * std::mem::size_of::<f32>();

    /// Applies `brush` with `op` to every node within two cells of its bounds (intersection also
    /// empties every chunk beyond them) and returns the chunks whose values changed, sorted.
    pub fn apply<B: Brush + ?Sized>(&mut self, op: CsgOp, brush: &B) -> Result<Vec<ChunkKey>, FieldError> {
        let boxed = edit_chunks(brush, MARGIN)?;
        let mut changed = Vec::new();
        if op == CsgOp::Intersect {
            let gone: Vec<ChunkKey> = self.chunks.keys().copied().filter(|k| outside(k, boxed)).collect();
            for k in gone {
                self.chunks.remove(&k);
                changed.push(k);
            }
        }
        for (key, range) in edit_targets(op, brush.bounds(), boxed, MARGIN) {
            let values = match (op, self.chunks.get_mut(&key)) {
                (_, Some(v)) => v,
                // Subtracting from or intersecting with empty space changes nothing.
                (CsgOp::Subtract | CsgOp::Intersect, None) => continue,
                (CsgOp::Add, None) => self.chunks.entry(key).or_insert_with(|| vec![FAR; NODES].into()),
            };
            if edit_values(values, key, range, op, brush, None) {
                changed.push(key);
            }
        }
        changed.sort_by_key(|k| (k.0.z, k.0.y, k.0.x));
        Ok(changed)
    }

    /// The value at a global node.
    pub fn value(&self, node: I64Vec3) -> f32 {
        let n = N as i64;
        let key = node.div_euclid(I64Vec3::splat(n));
        let l = (node - key * n).as_uvec3();
        self.chunks.get(&ChunkKey(key.as_ivec3())).map_or(FAR, |c| c[index(l.x as usize, l.y as usize, l.z as usize)])
    }

    /// Whether a global node is inside (its value is `≤ 0`).
    pub fn node_inside(&self, node: I64Vec3) -> bool {
        self.value(node) <= 0.0
    }

    /// The voxel block of chunk `key`, using `scratch` for the gathered values.
    pub fn extract_block_into(&self, key: ChunkKey, scratch: &mut PaddedValues, out: &mut VoxelBlock) {
        let keys = neighbourhood(key);
        gather(scratch, FAR, |i| self.chunks.get(&keys[i]).map(|c| &c[..]));
        scratch.fill_block(key, out);
    }

    /// godot_voxel's smooth tool on this field (its `VoxelToolLodTerrain` "smooth" mode): inside
    /// the ball of `radius` (grid units) about `center`, every node moves towards the mean of its
    /// 3×3×3 neighbourhood (a box blur of the values before the dab), by
    /// `strength · (1 − d² / r²)`. Returns the chunks whose values changed, sorted; chunks that no
    /// edit allocated read [`FAR`] and are allocated only if a value in them changes.
    pub fn smooth_box_blur(&mut self, center: DVec3, radius: f64, strength: f32) -> Result<Vec<ChunkKey>, FieldError> {
        if !(center.is_finite() && radius.is_finite() && radius > 0.0 && (0.0..=1.0).contains(&strength)) {
            return Err(FieldError::BadDab);
        }
        let lo = (center - DVec3::splat(radius)).floor() - DVec3::ONE;
        let hi = (center + DVec3::splat(radius)).ceil() + DVec3::ONE;
        let bounds = strata_volume::brush::Aabb { min: lo, max: hi };
        if lo.min_element() < -(i32::MAX as f64) * N as f64 || hi.max_element() > (i32::MAX as f64) * N as f64 {
            return Err(FieldError::OutOfRange(bounds));
        }
        let d = hi - lo + DVec3::ONE;
        let chunks = (d / N as f64).ceil() + DVec3::ONE;
        if chunks.x * chunks.y * chunks.z > MAX_BLUR_CHUNKS as f64 {
            return Err(FieldError::TooLarge {
                chunks: (chunks.x * chunks.y * chunks.z) as u64,
                limit: MAX_BLUR_CHUNKS,
            });
        }
        let (o, dims) = (lo.as_i64vec3(), [d.x as usize, d.y as usize, d.z as usize]);
        // The values of the box, copied chunk by chunk (as godot_voxel copies the box to a buffer).
        let mut values = vec![FAR; dims[0] * dims[1] * dims[2]];
        let at = |x: usize, y: usize, z: usize| x + dims[0] * (y + dims[1] * z);
        let n = N as i64;
        let (klo, khi) =
            (o.div_euclid(I64Vec3::splat(n)), (o + d.as_i64vec3() - I64Vec3::ONE).div_euclid(I64Vec3::splat(n)));
        let each_node = |key: I64Vec3, f: &mut dyn FnMut(usize, usize)| {
            let base = key * n;
            let (a, b) = ((o - base).max(I64Vec3::ZERO), (o + d.as_i64vec3() - base).min(I64Vec3::splat(n)));
            for z in a.z..b.z {
                for y in a.y..b.y {
                    for x in a.x..b.x {
                        let g = base + I64Vec3::new(x, y, z) - o;
                        f(index(x as usize, y as usize, z as usize), at(g.x as usize, g.y as usize, g.z as usize));
                    }
                }
            }
        };
        for kz in klo.z..=khi.z {
            for ky in klo.y..=khi.y {
                for kx in klo.x..=khi.x {
                    let key = I64Vec3::new(kx, ky, kz);
                    if let Some(c) = self.chunks.get(&ChunkKey(key.as_ivec3())) {
                        each_node(key, &mut |ci, vi| values[vi] = c[ci]);
                    }
                }
            }
        }
        // The blur reads the values saturated at ±BLUR_CLAMP cells, as godot_voxel's stored SDF
        // saturates: this field's far sentinel would otherwise diffuse into the solid pass by
        // pass. Only values that the blur changes are written back.
        let clamped: Vec<f32> = values.iter().map(|v| v.clamp(-BLUR_CLAMP, BLUR_CLAMP)).collect();
        // The blur, blended by the ball's weight, into a second buffer.
        let mut out = values.clone();
        let r2 = radius * radius;
        let mut touched = vec![false; values.len()];
        for z in 1..dims[2] - 1 {
            for y in 1..dims[1] - 1 {
                for x in 1..dims[0] - 1 {
                    let p = o.as_dvec3() + DVec3::new(x as f64, y as f64, z as f64);
                    let d2 = (p - center).length_squared();
                    if d2 >= r2 {
                        continue;
                    }
                    let mut sum = 0.0f32;
                    for dz in 0..3 {
                        for dy in 0..3 {
                            for dx in 0..3 {
                                sum += clamped[at(x + dx - 1, y + dy - 1, z + dz - 1)];
                            }
                        }
                    }
                    let w = strength * (1.0 - (d2 / r2) as f32);
                    let i = at(x, y, z);
                    let blurred = clamped[i] + (sum / 27.0 - clamped[i]) * w;
                    // (A node whose saturated neighbourhood is uniform keeps its exact value.)
                    if blurred != clamped[i] {
                        out[i] = blurred;
                        touched[i] = true;
                    }
                }
            }
        }
        let mut changed = Vec::new();
        for kz in klo.z..=khi.z {
            for ky in klo.y..=khi.y {
                for kx in klo.x..=khi.x {
                    let key = I64Vec3::new(kx, ky, kz);
                    let ck = ChunkKey(key.as_ivec3());
                    let mut differs = false;
                    each_node(key, &mut |_, vi| differs |= touched[vi] && out[vi] != values[vi]);
                    if !differs {
                        continue;
                    }
                    let c = self.chunks.entry(ck).or_insert_with(|| vec![FAR; NODES].into());
                    each_node(key, &mut |ci, vi| {
                        if touched[vi] {
                            c[ci] = out[vi];
                        }
                    });
                    changed.push(ck);
                }
            }
        }
        changed.sort_by_key(|k| (k.0.z, k.0.y, k.0.x));
        Ok(changed)
    }

    /// The field at grid point `p`, trilinearly interpolated between the nodes.
    pub fn sample(&self, p: DVec3) -> f32 {
        let b = p.floor();
        let f = p - b;
        let g = b.as_i64vec3();
        let v = |dx: i64, dy: i64, dz: i64| self.value(g + I64Vec3::new(dx, dy, dz)) as f64;
        let l = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let x00 = l(v(0, 0, 0), v(1, 0, 0), f.x);
        let x10 = l(v(0, 1, 0), v(1, 1, 0), f.x);
        let x01 = l(v(0, 0, 1), v(1, 0, 1), f.x);
        let x11 = l(v(0, 1, 1), v(1, 1, 1), f.x);
        l(l(x00, x10, f.y), l(x01, x11, f.y), f.z) as f32
    }

    /// Chunks allocated.
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Bytes held: every chunk's values plus the chunk map's table (from its capacity).
    pub fn memory(&self) -> usize {
        self.chunks.len() * Self::CHUNK_BYTES
            + hash_table_bytes(self.chunks.capacity(), std::mem::size_of::<(ChunkKey, Box<[f32]>)>())
    }

    /// What a dense field allocating `chunks` chunks holds (values and a tightly sized map), for
    /// sizes too large to build.
    pub fn bytes_for_chunks(chunks: usize) -> usize {
        chunks * Self::CHUNK_BYTES + hash_table_bytes(chunks, std::mem::size_of::<(ChunkKey, Box<[f32]>)>())
    }

    /// Allocated chunk keys.
    pub fn keys(&self) -> impl Iterator<Item = ChunkKey> + '_ {
        self.chunks.keys().copied()
    }

    pub(crate) fn insert_chunk(&mut self, key: ChunkKey, values: Box<[f32]>) {
        self.chunks.insert(key, values);
    }
}
