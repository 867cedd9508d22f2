//! The viewport's meshes: for every surface (a scene layer) one [`SurfaceMeshes`], made by one
//! of the mesh back-ends ([`Backend`]), remeshed within a frame's time budget, and the list of
//! what changed since the renderer was last told ([`ChangeList`]).
//!
//! A surface's chunks go through three states: *queued* (an edit or a level-of-detail change
//! touched them), *staged* (remeshed, waiting until no queued neighbour can still move a seam
//! they share) and *shown* (committed to the back-end's cache, listed in the next change list).

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;
use std::time::{Duration, Instant};

use strata_mesh::{BlockMesher, DualCache, Mesh, MeshCache, MeshOptions, Mesher};
use strata_volume::{ChunkKey, Level, Reach, Volume};

use crate::lod::{LodView, lod_levels};
use crate::scene::{Layer, LayerTransform, Material};

/// How a surface's viewport meshes are made.
#[derive(Debug)]
enum Backend {
    /// Marching cubes or marching tetrahedra, chunk by chunk from voxel blocks, within a time
    /// budget, with level of detail (marching cubes) and per-chunk simplification.
    Blocks(MeshCache),
    /// Dual contouring: the cache finds and rebuilds what the queued chunks affect, in one
    /// parallel pass (no time budget, no level of detail).
    Dual(DualCache),
}

/// One surface's meshes and the work waiting for them.
#[derive(Debug)]
struct SurfaceMeshes {
    backend: Backend,
    /// Blocks: chunks to remesh. Dual: chunks an edit changed (the cache widens them itself).
    queued: BTreeSet<ChunkKey>,
    /// Meshes computed but not yet shown: a chunk's new mesh is committed only together with
    /// every neighbour's, so no seam is ever drawn between a new mesh and a stale one.
    staged: HashMap<ChunkKey, Arc<Mesh>>,
    /// Level-of-detail caps (chunks missing are meshed at their stored level).
    lod: HashMap<ChunkKey, Level>,
}

impl SurfaceMeshes {
    /// A surface of `volume` meshed by `options`, every chunk queued.
    fn new(options: MeshOptions, volume: &Volume, lod: HashMap<ChunkKey, Level>) -> Self {
        let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
        let (backend, queued) = match options.mesher.block() {
            Some(block) => {
                let mut c = MeshCache::with_mesher(block);
                // Bounds are checked by `Editor::set_view_mesher`.
                let _ = c.set_simplify(options.simplify);
                (Backend::Blocks(c), MeshCache::dependents(&stored).into_iter().collect())
            }
            None => {
                let single = options.mesher == Mesher::SingleVertexDualContouring;
                let d = if single { DualCache::single_vertex() } else { DualCache::new() };
                (Backend::Dual(d), stored.into_iter().collect())
            }
        };
        SurfaceMeshes { backend, queued, staged: HashMap::new(), lod }
    }

    fn mesh(&self, key: ChunkKey) -> Option<&Mesh> {
        match &self.backend {
            Backend::Blocks(c) => c.mesh(key),
            Backend::Dual(d) => d.mesh(key).map(|m| &m.mesh),
        }
    }

    fn meshes(&self) -> Vec<(ChunkKey, &Mesh)> {
        match &self.backend {
            Backend::Blocks(c) => c.iter().collect(),
            Backend::Dual(d) => d.iter().map(|(k, m)| (k, &m.mesh)).collect(),
        }
    }

    fn triangle_count(&self) -> usize {
        match &self.backend {
            Backend::Blocks(c) => c.triangle_count(),
            Backend::Dual(d) => d.triangle_count(),
        }
    }

    fn pending(&self) -> usize {
        self.queued.len() + self.staged.len()
    }

    /// Shows the staged meshes that no queued chunk can still change the seams of: a staged
    /// chunk waits while a neighbour (across a face, edge or corner) is queued, or is itself
    /// waiting; all the others are committed at once. Returns the committed chunks.
    fn commit_staged(&mut self) -> Vec<ChunkKey> {
        let Backend::Blocks(cache) = &mut self.backend else { return Vec::new() };
        if self.staged.is_empty() {
            return Vec::new();
        }
        let (queued, staged) = (&self.queued, &self.staged);
        let mut waiting: BTreeSet<ChunkKey> =
            staged.keys().copied().filter(|&k| k.around().any(|n| queued.contains(&n))).collect();
        let mut frontier: Vec<ChunkKey> = waiting.iter().copied().collect();
        while let Some(k) = frontier.pop() {
            for n in k.around() {
                if staged.contains_key(&n) && waiting.insert(n) {
                    frontier.push(n);
                }
            }
        }
        let ready: Vec<ChunkKey> = staged.keys().copied().filter(|k| !waiting.contains(k)).collect();
        let fresh: Vec<(ChunkKey, Arc<Mesh>)> =
            ready.iter().map(|k| (*k, self.staged.remove(k).expect("staged"))).collect();
        cache.commit(fresh);
        ready
    }
}

/// What the renderer must do to show the viewport's meshes as they are now, since the last
/// [`crate::Editor::take_changes`]: the one road from the editor's meshes to a renderer (see
/// `strata_viewport::apply_changes`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChangeList {
    /// Draw everything anew (the first list, a new layer list, another mesher, or a renderer
    /// that showed something else meanwhile): the other fields are then empty.
    pub full: bool,
    /// Chunks whose mesh changed, by layer index: upload the editor's mesh, or drop the chunk
    /// where there is none or its layer is hidden.
    pub meshes: Vec<(usize, ChunkKey)>,
    /// Layers whose placement or visibility changed: every chunk of theirs drawn anew.
    pub layers: Vec<usize>,
    /// The materials changed: the palette is set anew.
    pub palette: bool,
}

/// What the last change list left the renderer showing.
#[derive(Clone, Debug, PartialEq)]
struct Shown {
    generation: u64,
    materials: Vec<Material>,
    placements: Vec<(LayerTransform, bool)>,
}

/// The viewport's meshes of every layer of a scene (see the module docs).
#[derive(Debug)]
pub(crate) struct ViewMeshes {
    options: MeshOptions,
    surfaces: Vec<SurfaceMeshes>,
    view: Option<LodView>,
    /// Counts resets: a change list after one is full.
    generation: u64,
    shown: Option<Shown>,
    /// Chunks shown since the last change list.
    unshown: BTreeSet<(usize, ChunkKey)>,
}

impl ViewMeshes {
    /// Meshes of `layers` by `options`, every chunk queued.
    pub(crate) fn new(options: MeshOptions, layers: &[Layer]) -> Self {
        let mut m = ViewMeshes {
            options,
            surfaces: Vec::new(),
            view: None,
            generation: 0,
            shown: None,
            unshown: BTreeSet::new(),
        };
        m.reset(layers, false);
        m
    }

    /// Drops every mesh and queues every chunk of `layers` (after layers are added, removed or
    /// replaced), keeping the level-of-detail caps where `keep_lod` (same layers, another mesher).
    pub(crate) fn reset(&mut self, layers: &[Layer], keep_lod: bool) {
        let mut lods: Vec<HashMap<ChunkKey, Level>> =
            if keep_lod { self.surfaces.iter_mut().map(|s| std::mem::take(&mut s.lod)).collect() } else { Vec::new() };
        lods.resize_with(layers.len(), HashMap::new);
        self.surfaces =
            layers.iter().zip(lods).map(|(l, lod)| SurfaceMeshes::new(self.options, &l.volume, lod)).collect();
        self.generation += 1;
        self.unshown.clear();
    }

    /// The mesher and per-chunk simplification.
    pub(crate) fn options(&self) -> MeshOptions {
        self.options
    }

    /// Meshes with `options` from now on (checked by the caller), every chunk queued again.
    pub(crate) fn set_options(&mut self, options: MeshOptions, layers: &[Layer]) {
        if options != self.options {
            self.options = options;
            self.reset(layers, true);
        }
    }

    /// Queues the meshes an edit of `layer` (whose volume is now `volume`) that changed `changed`
    /// within `reach` (`None`: anywhere in them) affects.
    pub(crate) fn queue(&mut self, layer: usize, volume: &Volume, changed: &[ChunkKey], reach: Option<Reach>) {
        let Some(s) = self.surfaces.get_mut(layer) else { return };
        match &mut s.backend {
            Backend::Blocks(c) => s.queued.extend(c.note(volume, changed, reach)),
            Backend::Dual(_) => s.queued.extend(changed.iter().copied()),
        }
    }

    /// Remeshes queued chunks, in batches, until `budget` is spent (at least one batch), then
    /// shows the new meshes that can be shown without a crack. Returns the chunks shown, and the
    /// chunks still queued or staged.
    pub(crate) fn remesh(&mut self, layers: &[Layer], budget: Duration) -> (Vec<(usize, ChunkKey)>, usize) {
        let t0 = Instant::now();
        const BATCH: usize = 16;
        let mut computed = false;
        let mut shown = Vec::new();
        // Level of detail caps only marching cubes (tetrahedra do not patch seams between levels).
        let lod_on = self.options.mesher == Mesher::MarchingCubes;
        for (layer, (s, l)) in self.surfaces.iter_mut().zip(layers).enumerate() {
            match &mut s.backend {
                Backend::Dual(d) => {
                    if !s.queued.is_empty() {
                        let queued: Vec<ChunkKey> = std::mem::take(&mut s.queued).into_iter().collect();
                        shown.extend(d.update(&l.volume, &queued).into_iter().map(|k| (layer, k)));
                    }
                    continue;
                }
                Backend::Blocks(cache) => {
                    while !s.queued.is_empty() {
                        if computed && t0.elapsed() >= budget {
                            break;
                        }
                        let batch: Vec<ChunkKey> = std::iter::from_fn(|| s.queued.pop_first()).take(BATCH).collect();
                        let lod = &s.lod;
                        let cap = |k: ChunkKey| lod.get(&k).copied().unwrap_or(Level::FINEST);
                        let capped: Option<strata_mesh::LevelCap<'_>> =
                            if lod.is_empty() || !lod_on { None } else { Some(&cap) };
                        s.staged.extend(cache.compute(&l.volume, &batch, capped));
                        computed = true;
                    }
                }
            }
            shown.extend(s.commit_staged().into_iter().map(|k| (layer, k)));
        }
        // Only what a renderer already showing these layers needs; otherwise the next list is
        // full anyway (and nothing accumulates in an editor no renderer follows).
        if self.shown.as_ref().is_some_and(|s| s.generation == self.generation) {
            self.unshown.extend(shown.iter().copied());
        }
        (shown, self.pending())
    }

    /// Level of detail by camera distance: with a view, every list chunk of every layer is
    /// meshed at the coarsest level whose cell looks no larger than the view's pixel error from
    /// the eye (see [`LodView`]); chunks whose level changes are queued with their neighbours.
    /// `None` meshes everything at its stored level.
    pub(crate) fn set_view(&mut self, layers: &[Layer], view: Option<LodView>) {
        self.view = view;
        for (s, l) in self.surfaces.iter_mut().zip(layers) {
            let next = match view.filter(LodView::is_valid) {
                Some(v) => lod_levels(&l.volume, &l.transform, &v, &s.lod),
                None => HashMap::new(),
            };
            let old = std::mem::replace(&mut s.lod, next);
            let moved = old
                .iter()
                .filter(|(k, l)| s.lod.get(k) != Some(l))
                .chain(s.lod.iter().filter(|(k, l)| old.get(k) != Some(l)))
                .map(|(k, _)| *k);
            let keys: Vec<ChunkKey> = moved.flat_map(|k| k.around()).collect();
            s.queued.extend(keys);
        }
    }

    /// The level-of-detail cap of a chunk of a layer (`None`: meshed at its stored level).
    pub(crate) fn lod_level(&self, layer: usize, key: ChunkKey) -> Option<Level> {
        self.surfaces.get(layer)?.lod.get(&key).copied()
    }

    /// Chunks waiting for a remesh, or remeshed and waiting for their neighbours to be shown.
    /// (Under dual contouring the queue holds the chunks an edit changed; the cache rebuilds
    /// them and their neighbours, so more chunks change than are counted here.)
    pub(crate) fn pending(&self) -> usize {
        self.surfaces.iter().map(SurfaceMeshes::pending).sum()
    }

    /// Whether chunk `key` of layer `layer` waits for a remesh or to be shown (under dual
    /// contouring: whether an edit changed it since the last remesh).
    pub(crate) fn is_pending(&self, layer: usize, key: ChunkKey) -> bool {
        self.surfaces.get(layer).is_some_and(|s| s.queued.contains(&key) || s.staged.contains_key(&key))
    }

    /// The block mesh cache of a layer (`None` under dual contouring).
    pub(crate) fn mesh_cache(&self, layer: usize) -> Option<&MeshCache> {
        match &self.surfaces.get(layer)?.backend {
            Backend::Blocks(c) => Some(c),
            Backend::Dual(_) => None,
        }
    }

    /// The mesher a layer's meshes are made with now.
    pub(crate) fn mesher_used(&self, layer: usize) -> Option<Mesher> {
        Some(match &self.surfaces.get(layer)?.backend {
            Backend::Dual(_) => self.options.mesher,
            Backend::Blocks(c) => match c.mesher_used() {
                BlockMesher::MarchingCubes => Mesher::MarchingCubes,
                BlockMesher::Tetrahedra => Mesher::Tetrahedra,
                BlockMesher::ClusteredTetrahedra => Mesher::ClusteredTetrahedra,
            },
        })
    }

    /// The shown mesh of chunk `key` of a layer (chunk-local positions).
    pub(crate) fn mesh(&self, layer: usize, key: ChunkKey) -> Option<&Mesh> {
        self.surfaces.get(layer)?.mesh(key)
    }

    /// Every shown chunk mesh of a layer.
    pub(crate) fn meshes(&self, layer: usize) -> Vec<(ChunkKey, &Mesh)> {
        self.surfaces.get(layer).map(SurfaceMeshes::meshes).unwrap_or_default()
    }

    /// Triangles shown in all layers.
    pub(crate) fn triangle_count(&self) -> usize {
        self.surfaces.iter().map(SurfaceMeshes::triangle_count).sum()
    }

    /// The next change list for a renderer showing `layers`' meshes (see [`ChangeList`]).
    pub(crate) fn take_changes(&mut self, layers: &[Layer], materials: &[Material]) -> ChangeList {
        let placements: Vec<(LayerTransform, bool)> = layers.iter().map(|l| (l.transform, l.visible)).collect();
        let unshown = std::mem::take(&mut self.unshown);
        match &mut self.shown {
            Some(was) if was.generation == self.generation && was.placements.len() == placements.len() => {
                let moved: Vec<usize> = (0..placements.len()).filter(|&i| was.placements[i] != placements[i]).collect();
                was.placements = placements;
                // The palette is copied only when it changed (a comparison a frame, no clone).
                let palette = was.materials != materials;
                if palette {
                    was.materials = materials.to_vec();
                }
                ChangeList {
                    full: false,
                    meshes: unshown.into_iter().filter(|(l, _)| !moved.contains(l)).collect(),
                    layers: moved,
                    palette,
                }
            }
            _ => {
                self.shown = Some(Shown { generation: self.generation, materials: materials.to_vec(), placements });
                ChangeList { full: true, ..ChangeList::default() }
            }
        }
    }

    /// Makes the next change list full (the renderer showed something else meanwhile).
    pub(crate) fn redraw_all(&mut self) {
        self.shown = None;
        self.unshown.clear();
    }
}
