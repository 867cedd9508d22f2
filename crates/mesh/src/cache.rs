//! Per-chunk meshes kept up to date incrementally after edits.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{DVec3, IVec3};
use rayon::prelude::*;
use strata_volume::{ChunkKey, Level, Reach, Volume, VoxelBlock};

use crate::simplify::{Simplify, SimplifyError, simplify};
use crate::tetra::TetraScratch;
use crate::{Mesh, mesh_block, mesh_block_tetra};

/// The meshers that mesh each chunk from its voxel block alone (so a chunk's mesh depends on the
/// chunk and the seven after it, and can be kept up to date incrementally).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BlockMesher {
    /// Marching cubes ([`crate::mesh_block`]).
    #[default]
    MarchingCubes,
    /// Marching tetrahedra without clustering ([`crate::mesh_block_tetra`]).
    Tetrahedra,
    /// Regularised marching tetrahedra: with the integrated clustering.
    ClusteredTetrahedra,
}

impl BlockMesher {
    /// Meshes `block` into `out` (tetrahedra need `scratch`), the block alone: clustered
    /// tetrahedra then keep every chunk-face vertex ([`MeshCache`] clusters faces with the
    /// neighbours' blocks, each face once for a batch of chunks).
    pub fn mesh(self, block: &VoxelBlock, scratch: &mut TetraScratch, out: &mut Mesh) {
        match self {
            BlockMesher::MarchingCubes => mesh_block(block, out),
            BlockMesher::Tetrahedra => mesh_block_tetra(block, false, scratch, out),
            BlockMesher::ClusteredTetrahedra => mesh_block_tetra(block, true, scratch, out),
        }
    }

    /// Whether this mesher can mesh blocks of a volume whose chunks mix levels (or are capped
    /// for level of detail): only marching cubes patches the seams between levels.
    pub fn handles_levels(self) -> bool {
        self == BlockMesher::MarchingCubes
    }
}

/// The voxel block [`MeshCache::compute`] meshes for chunk `key` of `volume` (under the
/// level-of-detail cap `cap`, seams with finer neighbours patched), made in `out`, for meshing
/// it elsewhere (on the GPU); `false` where the chunk and its apron are all inside or all
/// outside (no surface: `out` is left as it was).
pub fn view_block(volume: &Volume, key: ChunkKey, cap: Option<LevelCap<'_>>, out: &mut VoxelBlock) -> bool {
    if volume.plain_block_level(key, cap).is_some() && volume.plain_block_uniform(key) {
        return false;
    }
    match cap {
        Some(c) => volume.extract_block_capped(key, c, out),
        None => volume.extract_block_into(key, out),
    }
    true
}

/// Cells a side of the parts a finer chunk's marching-cubes mesh is kept in (a base chunk's
/// size): a 64³ chunk's mesh is 4³ parts, and an edit remeshes only the parts it reaches.
pub const PART_CELLS: usize = 16;

/// A finer chunk's mesh as it was last computed, in parts of [`PART_CELLS`] cells: the parts'
/// vertices and triangles follow each other in `mesh`, x fastest.
#[derive(Debug, Clone)]
struct Parts {
    /// The level the chunk was meshed at (plainly: nothing patched).
    level: Level,
    mesh: Arc<Mesh>,
    /// Per part, the end of its vertices and of its indices in `mesh`.
    ends: Vec<(u32, u32)>,
}

/// Meshes by chunk, by marching cubes or (for volumes of one level) marching tetrahedra.
/// Positions are chunk-local (grid units from the chunk's origin), so far-away chunks keep full
/// f32 precision; the renderer places each chunk.
///
/// Marching cubes keeps the mesh of a chunk finer than 16³ cells, where the chunk and its
/// neighbours share its level, in parts of 16³ cells: edits that say where they reach
/// ([`EditReport::reach`](strata_volume::EditReport::reach), given to [`MeshCache::note`])
/// remesh only the parts they reach, each from the lines through it alone. A part's triangles
/// are the whole chunk's triangles in its cells, so the mesh equals the whole-chunk mesh after
/// welding the parts' shared border vertices by position.
#[derive(Debug, Default, Clone)]
pub struct MeshCache {
    meshes: HashMap<ChunkKey, Arc<Mesh>>,
    /// The last computed parts of the finer chunks meshed in parts.
    parts: HashMap<ChunkKey, Parts>,
    /// Where each chunk changed since its parts were last computed (`None`: anywhere); a chunk
    /// not listed is remeshed whole.
    reach: HashMap<ChunkKey, Option<Reach>>,
    /// Whether a volume of mixed levels was meshed: seams then reach every neighbour.
    mixed: bool,
    /// The mesher asked for.
    mesher: BlockMesher,
    /// The mesher the stored meshes were made with: marching cubes where tetrahedra were asked
    /// for but the volume mixes levels (tetrahedra do not patch seams between levels).
    used: BlockMesher,
    /// Simplify each chunk's mesh with this error (grid units), its border locked.
    simplify: Option<f32>,
}

/// A level-of-detail cap: chunk `k` is meshed at no finer than `cap(k)`.
pub type LevelCap<'a> = &'a (dyn Fn(ChunkKey) -> Level + Sync);

impl MeshCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty cache that meshes with `mesher`.
    pub fn with_mesher(mesher: BlockMesher) -> Self {
        MeshCache { mesher, used: mesher, ..Self::default() }
    }

    /// Simplifies every chunk mesh made from now on by meshoptimizer with `max_error` grid units,
    /// the chunk's border locked so neighbours still meet (`None`: no simplification). Refuses a
    /// bound that is not finite and `>= 0`.
    pub fn set_simplify(&mut self, max_error: Option<f32>) -> Result<(), SimplifyError> {
        if let Some(e) = max_error
            && !(e.is_finite() && e >= 0.0)
        {
            return Err(SimplifyError::BadError(e));
        }
        self.simplify = max_error;
        Ok(())
    }

    /// The simplification error of chunk meshes, if any.
    pub fn simplification(&self) -> Option<f32> {
        self.simplify
    }

    /// The mesher asked for.
    pub fn mesher(&self) -> BlockMesher {
        self.mesher
    }

    /// The mesher the stored meshes were made with (marching cubes where the asked-for mesher
    /// cannot mesh the volume's mixed levels).
    pub fn mesher_used(&self) -> BlockMesher {
        self.used
    }

    /// The mesher that meshes `volume` (with or without a level-of-detail cap) with this cache.
    fn effective(&self, volume: &Volume, capped: bool) -> BlockMesher {
        if self.mesher.handles_levels() || (volume.single_level() && !capped) {
            self.mesher
        } else {
            BlockMesher::MarchingCubes
        }
    }

    /// Meshes every chunk of `volume` that can hold surface.
    pub fn build(volume: &Volume) -> Self {
        Self::build_with(volume, BlockMesher::MarchingCubes)
    }

    /// Meshes every chunk of `volume` that can hold surface with `mesher`.
    pub fn build_with(volume: &Volume, mesher: BlockMesher) -> Self {
        let mut cache = Self::with_mesher(mesher);
        let keys = crate::surface_chunks(volume);
        cache.remesh(volume, &keys);
        cache
    }

    /// The chunks whose meshes depend on the chunks in `changed`: each changed chunk and the
    /// seven chunks before it, which read it as their apron. Sorted, without repeats.
    pub fn dependents(changed: &[ChunkKey]) -> Vec<ChunkKey> {
        let mut keys: Vec<ChunkKey> = changed
            .iter()
            .flat_map(|k| (0..8).map(move |d| k.offset(-IVec3::new(d & 1, (d >> 1) & 1, (d >> 2) & 1))))
            .collect();
        keys.sort();
        keys.dedup();
        keys
    }

    /// Each chunk of `keys` and the 26 around it, sorted, without repeats.
    pub fn around(keys: &[ChunkKey]) -> Vec<ChunkKey> {
        let mut out: Vec<ChunkKey> = keys.iter().flat_map(|k| k.around()).collect();
        out.sort();
        out.dedup();
        out
    }

    /// The chunks whose meshes depend on the chunks in `changed` of `volume`: where every chunk
    /// has one level, [`MeshCache::dependents`]; where levels mix (or did, in this cache), the
    /// 3×3×3 chunks around each, whose seams the change can move, and the same for clustered
    /// tetrahedra, whose face clusters each chunk makes with its neighbours. Sorted, without
    /// repeats.
    pub fn affected(&self, volume: &Volume, changed: &[ChunkKey]) -> Vec<ChunkKey> {
        if self.effective(volume, false) != self.used {
            // Tetrahedra asked for and the volume went from one level to several or back: every
            // chunk changes mesher together, so no border joins the two.
            let mut keys: Vec<ChunkKey> = self.meshes.keys().copied().collect();
            keys.extend(crate::surface_chunks(volume));
            keys.sort();
            keys.dedup();
            return keys;
        }
        if volume.single_level() && !self.mixed && self.used != BlockMesher::ClusteredTetrahedra {
            return Self::dependents(changed);
        }
        // Seams between levels, or clustered tetrahedra, whose face clusters read two cells
        // into each chunk beside a face and are pinned by both chunks.
        Self::around(changed)
    }

    /// Remeshes what an edit that changed `changed` can have affected, in parallel. Returns the
    /// chunks whose mesh was rebuilt (upload those).
    pub fn update(&mut self, volume: &Volume, changed: &[ChunkKey]) -> Vec<ChunkKey> {
        self.update_reached(volume, changed, None)
    }

    /// [`MeshCache::update`] for an edit that changed nothing outside `reach` (`None`:
    /// anywhere in `changed`).
    pub fn update_reached(&mut self, volume: &Volume, changed: &[ChunkKey], reach: Option<Reach>) -> Vec<ChunkKey> {
        let keys = self.note(volume, changed, reach);
        self.remesh(volume, &keys);
        keys
    }

    /// Records an edit that changed the chunks `changed` of `volume` within `reach` (`None`:
    /// anywhere in them) and returns the chunks whose meshes it affects (see
    /// [`MeshCache::affected`]): queue those. Until they are computed again, their parts that
    /// the edits noted since do not reach are reused. A chunk queued without being noted (a
    /// level of detail changed, an undo) is remeshed whole.
    pub fn note(&mut self, volume: &Volume, changed: &[ChunkKey], reach: Option<Reach>) -> Vec<ChunkKey> {
        let mut keys = self.affected(volume, changed);
        if let Some(r) = reach
            && self.used == BlockMesher::ClusteredTetrahedra
            && self.effective(volume, false) == self.used
        {
            // A clustered tetrahedra chunk reads the nodes and edges within two cells of its
            // box (its faces' slabs): an edit that reaches none of them leaves its mesh.
            let margin = crate::tetra::SLAB_CELLS as f64 * volume.level().spacing();
            keys.retain(|k| {
                let lo = k.origin_grid().as_dvec3() - DVec3::splat(margin);
                r.meets(lo, lo + DVec3::splat(strata_volume::coords::CHUNK_CELLS as f64 + 2.0 * margin))
            });
        }
        for &k in &keys {
            let r = self.reach.entry(k).or_insert(reach);
            *r = r.zip(reach).map(|(a, b)| a.union(b));
        }
        keys
    }

    /// Remeshes exactly `keys` (for example a share of [`MeshCache::dependents`] that fits a
    /// frame's time budget), in parallel.
    pub fn remesh(&mut self, volume: &Volume, keys: &[ChunkKey]) {
        let fresh = self.compute(volume, keys, None);
        self.commit(fresh);
    }

    /// The meshes of `keys`, in parallel, without storing them (with an optional level-of-detail
    /// cap): [`MeshCache::commit`] them together, so neighbours swap in the same frame.
    pub fn compute(
        &mut self,
        volume: &Volume,
        keys: &[ChunkKey],
        cap: Option<LevelCap<'_>>,
    ) -> Vec<(ChunkKey, Arc<Mesh>)> {
        self.mixed |= !volume.single_level() || cap.is_some();
        let mesher = self.effective(volume, cap.is_some());
        self.used = mesher;
        let simplify_by = self.simplify.map(Simplify::chunk);
        let in_parts = mesher == BlockMesher::MarchingCubes && simplify_by.is_none();
        // Each key with where it changed since its parts were computed (`None`: anywhere) and
        // those parts.
        let jobs: Vec<(ChunkKey, Option<Reach>, Option<Parts>)> =
            keys.iter().map(|&k| (k, self.reach.remove(&k).flatten(), self.parts.remove(&k))).collect();
        // Clustered tetrahedra: each chunk face made once in the batch, by the first of its two
        // chunks to need it.
        let faces = crate::tetra::ChunkFaces::default();
        let done: Vec<(ChunkKey, Arc<Mesh>, Option<Parts>)> = jobs
            .into_par_iter()
            .map_init(
                || (VoxelBlock::default(), TetraScratch::default(), Mesh::default()),
                |(block, scratch, part), (key, reach, old)| {
                    let plain = volume.plain_block_level(key, cap);
                    if plain.is_some() && volume.plain_block_uniform(key) {
                        // The chunk and its apron are all inside or all outside: no surface.
                        return (key, Arc::new(Mesh::default()), None);
                    }
                    if let Some(level) = plain.filter(|l| in_parts && l.cells() > PART_CELLS) {
                        let old = old.filter(|o| o.level == level);
                        let parts = mesh_parts(volume, key, level, reach, old.as_ref(), block, part);
                        return (key, parts.mesh.clone(), Some(parts));
                    }
                    let mut mesh = Mesh::default();
                    if mesher == BlockMesher::ClusteredTetrahedra {
                        // One level, no cap (see `effective`): the face clusters are made with the
                        // neighbours' blocks.
                        crate::tetra::mesh_chunk_clustered(volume, key, &faces, block, scratch, &mut mesh);
                    } else {
                        match cap {
                            Some(c) => volume.extract_block_capped(key, c, block),
                            None => volume.extract_block_into(key, block),
                        }
                        mesher.mesh(block, scratch, &mut mesh);
                    }
                    if let Some(how) = simplify_by {
                        // The bound was checked by `set_simplify` and meshes are finite.
                        mesh = simplify(&mesh, how).unwrap_or(mesh);
                    }
                    (key, Arc::new(mesh), None)
                },
            )
            .collect();
        done.into_iter()
            .map(|(key, mesh, parts)| {
                if let Some(p) = parts {
                    self.parts.insert(key, p);
                }
                (key, mesh)
            })
            .collect()
    }

    /// Stores meshes made by [`MeshCache::compute`] (an empty mesh removes the chunk's).
    pub fn commit(&mut self, fresh: Vec<(ChunkKey, Arc<Mesh>)>) {
        for (key, mesh) in fresh {
            if mesh.indices.is_empty() {
                self.meshes.remove(&key);
            } else {
                self.meshes.insert(key, mesh);
            }
        }
    }

    /// The mesh of `key`, if it has triangles.
    pub fn mesh(&self, key: ChunkKey) -> Option<&Mesh> {
        self.meshes.get(&key).map(|m| &**m)
    }

    /// All chunk meshes.
    pub fn iter(&self) -> impl Iterator<Item = (ChunkKey, &Mesh)> {
        self.meshes.iter().map(|(k, m)| (*k, &**m))
    }

    /// Number of chunks with triangles.
    pub fn len(&self) -> usize {
        self.meshes.len()
    }

    /// Whether no chunk has triangles.
    pub fn is_empty(&self) -> bool {
        self.meshes.is_empty()
    }

    /// Total triangles over all chunks.
    pub fn triangle_count(&self) -> usize {
        self.meshes.values().map(|m| m.triangle_count()).sum()
    }
}

/// The mesh of the plain block of `key` at `level` in parts of [`PART_CELLS`] cells: the parts
/// `reach` meets (every part where it is `None` or nothing was kept) meshed from the lines
/// through them, the others copied from `old`.
fn mesh_parts(
    volume: &Volume,
    key: ChunkKey,
    level: Level,
    reach: Option<Reach>,
    old: Option<&Parts>,
    block: &mut VoxelBlock,
    part: &mut Mesh,
) -> Parts {
    let per_side = level.cells() / PART_CELLS;
    let sp = level.spacing();
    let origin = key.origin_grid().as_dvec3();
    let mut mesh = Mesh::default();
    let mut ends = Vec::with_capacity(per_side.pow(3));
    for i in 0..per_side.pow(3) {
        let at = [i % per_side, (i / per_side) % per_side, i / (per_side * per_side)].map(|c| c * PART_CELLS);
        // The part's nodes, apron included, in grid units.
        let lo = origin + DVec3::new(at[0] as f64, at[1] as f64, at[2] as f64) * sp;
        let hi = lo + DVec3::splat(PART_CELLS as f64 * sp);
        match old {
            Some(o) if reach.is_some_and(|r| !r.meets(lo, hi)) => {
                let (v0, i0) = if i == 0 { (0, 0) } else { o.ends[i - 1] };
                let (v1, i1) = o.ends[i];
                mesh.append_range(&o.mesh, v0 as usize..v1 as usize, i0 as usize..i1 as usize);
            }
            _ => {
                volume.extract_part(key, at, PART_CELLS, block);
                mesh_block(block, part);
                mesh.append_range(part, 0..part.positions.len(), 0..part.indices.len());
            }
        }
        ends.push((mesh.positions.len() as u32, mesh.indices.len() as u32));
    }
    Parts { level, mesh: Arc::new(mesh), ends }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use strata_volume::brush::Sphere;

    #[test]
    fn incremental_updates_equal_a_full_rebuild() {
        let mut volume = Volume::new();
        let mut cache = MeshCache::new();
        let mut seed = 3u64;
        for i in 0..60 {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let r = |s: u64| (s % 1000) as f64 / 1000.0;
            let c = DVec3::new(r(seed >> 10), r(seed >> 20), r(seed >> 30)) * 60.0 - 10.0;
            let s = Sphere::new(c, 3.0 + 9.0 * r(seed >> 40)).unwrap();
            let report = if i == 40 {
                volume.intersect(&strata_volume::brush::Cuboid::new(DVec3::splat(20.0), DVec3::splat(26.0)).unwrap())
            } else if i % 3 == 2 {
                volume.subtract(&s)
            } else {
                volume.add(&s)
            }
            .unwrap();
            cache.update(&volume, &report.changed);
        }
        let full = MeshCache::build(&volume);
        assert_eq!(cache.len(), full.len());
        for (k, m) in full.iter() {
            assert_eq!(cache.mesh(k), Some(m), "chunk {k:?}");
        }
        assert!(cache.triangle_count() > 1000);
    }
}
