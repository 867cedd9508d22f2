//! The viewport's meshes: for every surface (a scene layer, or a streamed world: see
//! [`crate::target`]) one [`SurfaceMeshes`], made by one of the mesh back-ends ([`Backend`]),
//! remeshed within a frame's time budget, and the list of what changed since the renderer was
//! last told ([`ChangeList`]).
//!
//! A surface's chunks go through three states: *queued* (an edit or a level-of-detail change
//! touched them), *staged* (remeshed, waiting until no queued neighbour can still move a seam
//! they share) and *shown* (committed to the back-end's cache, listed in the next change list).

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use strata_mesh::{BlockMesher, DualCache, Mesh, MeshCache, MeshOptions, MeshWorkers, Mesher, dual_mesh_keys};
use strata_volume::{ChunkKey, Level, Reach, Volume};

use crate::lod::{LodView, lod_levels};
use crate::scene::{LayerTransform, Material};
use crate::target::EditTarget;

/// How a surface's viewport meshes are made.
#[derive(Debug)]
enum Backend {
    /// Marching cubes or marching tetrahedra, chunk by chunk from voxel blocks, within a time
    /// budget, with level of detail (marching cubes) and per-chunk simplification.
    Blocks(MeshCache),
    /// Dual contouring: the cache finds and rebuilds what the queued chunks affect, in one
    /// parallel pass (no time budget, no level of detail).
    Dual(DualCache),
    /// A streamed world's chunks, marching cubes on worker threads from snapshots of each
    /// chunk's neighbourhood, handed out nearest the focus first within the frame's budget;
    /// chunks that leave memory lose their meshes.
    Streamed(Streamed),
}

/// The streamed back-end's state.
#[derive(Debug)]
struct Streamed {
    workers: MeshWorkers,
    meshes: HashMap<ChunkKey, Mesh>,
    /// Where the viewer is (grid units): queued chunks nearest it are meshed first.
    focus: DVec3,
    /// Meshes the workers finished by the last frame's remesh: requests beyond twice that
    /// (and [`MIN_BACKLOG`]) stay queued on the main thread, where they cost no snapshot, can
    /// be superseded for free and are ordered by the focus of the frame that sends them.
    finished_last: usize,
}

/// The fewest requests a streamed surface keeps with its workers.
const MIN_BACKLOG: usize = 16;

/// One surface's meshes and the work waiting for them.
#[derive(Debug)]
struct SurfaceMeshes {
    backend: Backend,
    /// GPU meshing: the caller meshes this surface's chunks from their voxel blocks (see
    /// [`ViewMeshes::set_gpu`]); its queued chunks are listed at once, nothing is cached.
    by_caller: bool,
    /// The caller-meshed surface has mixed levels or been capped by level of detail since it
    /// was made: an edit then moves seams on every side of a chunk, not only the chunks before
    /// it (kept once set, so undoing the mix still reaches the seams it left). For dual
    /// contouring (levels only, it is not capped): its quads are joined across levels from then
    /// on, as the CPU's cache joins them once it has met mixed levels.
    mixed_seen: bool,
    /// Blocks: chunks to remesh. Dual: chunks an edit changed (the cache widens them itself).
    queued: BTreeSet<ChunkKey>,
    /// Meshes computed but not yet shown: a chunk's new mesh is committed only together with
    /// every neighbour's, so no seam is ever drawn between a new mesh and a stale one.
    staged: HashMap<ChunkKey, Arc<Mesh>>,
    /// Level-of-detail caps (chunks missing are meshed at their stored level).
    lod: HashMap<ChunkKey, Level>,
}

impl SurfaceMeshes {
    /// A surface of `volume` meshed by `options` (a streamed surface by workers whatever the
    /// options), every chunk queued.
    fn new(options: MeshOptions, volume: &Volume, lod: HashMap<ChunkKey, Level>, streamed: bool) -> Self {
        let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
        let (backend, queued) = match options.mesher.block() {
            _ if streamed => {
                let s = Streamed {
                    workers: MeshWorkers::new(1),
                    meshes: HashMap::new(),
                    focus: DVec3::ZERO,
                    finished_last: 0,
                };
                let queued = stored.iter().flat_map(|&k| MeshWorkers::readers(volume, k)).collect();
                (Backend::Streamed(s), queued)
            }
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
        let mixed_seen = !volume.single_level();
        SurfaceMeshes { backend, by_caller: false, mixed_seen, queued, staged: HashMap::new(), lod }
    }

    fn mesh(&self, key: ChunkKey) -> Option<&Mesh> {
        match &self.backend {
            Backend::Blocks(c) => c.mesh(key),
            Backend::Dual(d) => d.mesh(key).map(|m| &m.mesh),
            Backend::Streamed(s) => s.meshes.get(&key),
        }
    }

    fn meshes(&self) -> Vec<(ChunkKey, &Mesh)> {
        match &self.backend {
            Backend::Blocks(c) => c.iter().collect(),
            Backend::Dual(d) => d.iter().map(|(k, m)| (k, &m.mesh)).collect(),
            Backend::Streamed(s) => s.meshes.iter().map(|(k, m)| (*k, m)).collect(),
        }
    }

    fn triangle_count(&self) -> usize {
        match &self.backend {
            Backend::Blocks(c) => c.triangle_count(),
            Backend::Dual(d) => d.triangle_count(),
            Backend::Streamed(s) => s.meshes.values().map(Mesh::triangle_count).sum(),
        }
    }

    fn pending(&self) -> usize {
        let working = if let Backend::Streamed(s) = &self.backend { s.workers.pending() } else { 0 };
        self.queued.len() + self.staged.len() + working
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

/// Solves dual contouring's cell vertices of voxel blocks elsewhere (a GPU), for the viewport's
/// dual contouring (see [`crate::Editor::set_vertex_solver`]): per block what
/// `strata_mesh::dual_vertices` gives, or `None` to leave them to the CPU.
pub type BoxedVertexSolver =
    Box<dyn FnMut(&[&strata_volume::VoxelBlock]) -> Option<Vec<Vec<strata_mesh::DualVertex>>> + Send + Sync>;

/// A [`BoxedVertexSolver`] the view meshes hold.
struct Solver(BoxedVertexSolver);

impl std::fmt::Debug for Solver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Solver")
    }
}

/// The viewport's meshes of every layer of a scene (see the module docs).
#[derive(Debug)]
pub(crate) struct ViewMeshes {
    /// Dual contouring's vertices solved elsewhere (GPU meshing), if set.
    solver: Option<Solver>,
    options: MeshOptions,
    surfaces: Vec<SurfaceMeshes>,
    view: Option<LodView>,
    /// Counts resets: a change list after one is full.
    generation: u64,
    shown: Option<Shown>,
    /// Chunks shown since the last change list.
    unshown: BTreeSet<(usize, ChunkKey)>,
    /// GPU meshing asked for (see [`ViewMeshes::set_gpu`]).
    gpu: bool,
}

/// Whether a surface is meshed by the caller from its blocks under GPU meshing: a scene layer
/// (not a streamed world) whose mask is clear (masked vertices are shaded from the mask on the
/// CPU), meshed by marching cubes without per-chunk simplification, or by manifold dual
/// contouring (at one level or across levels: [`ViewMeshes::caller_dual_across_levels`]).
fn meshed_by_caller(gpu: bool, options: MeshOptions, surface: &dyn EditTarget) -> bool {
    let mesher = match options.mesher {
        Mesher::MarchingCubes => options.simplify.is_none(),
        Mesher::DualContouring => true,
        _ => false,
    };
    gpu && mesher && !surface.streamed() && surface.volume().mask().is_clear()
}

impl ViewMeshes {
    /// Meshes of `surfaces` by `options`, every chunk queued.
    pub(crate) fn new(options: MeshOptions, surfaces: &[&dyn EditTarget]) -> Self {
        let mut m = ViewMeshes {
            options,
            surfaces: Vec::new(),
            view: None,
            generation: 0,
            shown: None,
            unshown: BTreeSet::new(),
            gpu: false,
            solver: None,
        };
        m.reset(surfaces, false);
        m
    }

    /// Drops every mesh and queues every chunk of `surfaces` (after layers are added, removed or
    /// replaced), keeping the level-of-detail caps where `keep_lod` (same layers, another mesher).
    pub(crate) fn reset(&mut self, surfaces: &[&dyn EditTarget], keep_lod: bool) {
        let mut lods: Vec<HashMap<ChunkKey, Level>> =
            if keep_lod { self.surfaces.iter_mut().map(|s| std::mem::take(&mut s.lod)).collect() } else { Vec::new() };
        lods.resize_with(surfaces.len(), HashMap::new);
        self.surfaces = surfaces
            .iter()
            .zip(lods)
            .map(|(t, lod)| {
                let mut s = SurfaceMeshes::new(self.options, t.volume(), lod, t.streamed());
                s.by_caller = meshed_by_caller(self.gpu, self.options, *t);
                s
            })
            .collect();
        self.generation += 1;
        self.unshown.clear();
    }

    /// GPU meshing: with `on`, the surfaces [`meshed_by_caller`] accepts are no longer meshed
    /// here; their chunks are listed in the change lists as they change (and all of them in a
    /// full list: [`ViewMeshes::caller_chunks`]) for the caller to mesh from
    /// [`ViewMeshes::block`]. Every chunk is queued again when this changes anything.
    pub(crate) fn set_gpu(&mut self, on: bool, surfaces: &[&dyn EditTarget]) {
        if on != self.gpu {
            self.gpu = on;
            self.reset(surfaces, true);
        }
    }

    /// Whether GPU meshing is asked for.
    pub(crate) fn gpu(&self) -> bool {
        self.gpu
    }

    /// Dual contouring's vertices solved by `solver` from now on (`None`: on the CPU). Meshes
    /// already shown stay (the two agree within 1e-4 cells).
    pub(crate) fn set_solver(&mut self, solver: Option<BoxedVertexSolver>) {
        self.solver = solver.map(Solver);
    }

    /// Whether a vertex solver is set.
    pub(crate) fn has_solver(&self) -> bool {
        self.solver.is_some()
    }

    /// Whether surface `i`'s chunks are meshed by the caller (see [`ViewMeshes::set_gpu`]).
    pub(crate) fn by_caller(&self, i: usize) -> bool {
        self.surfaces.get(i).is_some_and(|s| s.by_caller)
    }

    /// Every chunk of a caller-meshed surface of `volume` that can hold surface.
    pub(crate) fn caller_chunks(&self, i: usize, volume: &Volume) -> Vec<ChunkKey> {
        match self.surfaces.get(i) {
            Some(s) if s.by_caller && matches!(s.backend, Backend::Dual(_)) => {
                let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
                if s.mixed_seen { MeshCache::around(&stored) } else { dual_mesh_keys(&stored) }
            }
            Some(s) if s.by_caller => strata_mesh::surface_chunks(volume),
            _ => Vec::new(),
        }
    }

    /// Whether caller-meshed surface `i` is meshed by dual contouring (else marching cubes).
    pub(crate) fn caller_dual(&self, i: usize) -> bool {
        self.surfaces.get(i).is_some_and(|s| s.by_caller && matches!(s.backend, Backend::Dual(_)))
    }

    /// Whether caller-meshed dual-contouring surface `i` joins its quads across levels (its
    /// volume has mixed levels since it was made; else at one level): each chunk's polygons
    /// then take cells of all 26 chunks around it, and an edit moves the polygons of the chunks
    /// within two chunks of what it changed.
    pub(crate) fn caller_dual_across_levels(&self, i: usize) -> bool {
        self.caller_dual(i) && self.surfaces[i].mixed_seen
    }

    /// The voxel block the CPU would mesh for chunk `key` of surface `i` of `volume` (capped
    /// by level of detail, seams with finer neighbours patched) into `out`; `false` where the
    /// chunk can hold no surface.
    pub(crate) fn block(&self, i: usize, volume: &Volume, key: ChunkKey, out: &mut strata_volume::VoxelBlock) -> bool {
        let lod = self.surfaces.get(i).map(|s| &s.lod);
        let cap = |k: ChunkKey| lod.and_then(|l| l.get(&k)).copied().unwrap_or(Level::FINEST);
        let capped: Option<strata_mesh::LevelCap<'_>> =
            if lod.is_none_or(HashMap::is_empty) || self.options.mesher != Mesher::MarchingCubes {
                None
            } else {
                Some(&cap)
            };
        strata_mesh::view_block(volume, key, capped, out)
    }

    /// The mesher and per-chunk simplification.
    pub(crate) fn options(&self) -> MeshOptions {
        self.options
    }

    /// Meshes with `options` from now on (checked by the caller), every chunk queued again.
    pub(crate) fn set_options(&mut self, options: MeshOptions, surfaces: &[&dyn EditTarget]) {
        if options != self.options {
            self.options = options;
            self.reset(surfaces, true);
        }
    }

    /// Queues the meshes an edit of `layer` (whose volume is now `volume`) that changed `changed`
    /// within `reach` (`None`: anywhere in them) affects.
    pub(crate) fn queue(&mut self, layer: usize, volume: &Volume, changed: &[ChunkKey], reach: Option<Reach>) {
        let Some(s) = self.surfaces.get_mut(layer) else { return };
        match &mut s.backend {
            // (Nothing is cached: no parts to note.)
            Backend::Blocks(_) if s.by_caller => {
                s.mixed_seen |= !volume.single_level() || !s.lod.is_empty();
                if s.mixed_seen {
                    s.queued.extend(changed.iter().flat_map(|k| k.around()));
                } else {
                    s.queued.extend(MeshCache::dependents(changed));
                }
            }
            Backend::Blocks(c) => s.queued.extend(c.note(volume, changed, reach)),
            Backend::Dual(_) if s.by_caller => {
                let was = s.mixed_seen;
                s.mixed_seen |= !volume.single_level();
                if s.mixed_seen && !was {
                    // From one level to several: every polygon is joined again across levels.
                    // (And around what the change touched: a chunk it emptied is not stored.)
                    let stored: Vec<ChunkKey> = volume.chunks().map(|(k, _)| k).collect();
                    s.queued.extend(MeshCache::around(&stored));
                    s.queued.extend(MeshCache::around(&MeshCache::around(changed)));
                } else if s.mixed_seen {
                    // The vertices of the chunks around a change move (their blocks read it);
                    // the polygons of the chunks around those use them.
                    s.queued.extend(MeshCache::around(&MeshCache::around(changed)));
                } else {
                    s.queued.extend(dual_mesh_keys(changed));
                }
            }
            Backend::Dual(_) => s.queued.extend(changed.iter().copied()),
            // A streamed surface learns of its changes from the world ([`ViewMeshes::streamed_changes`]).
            Backend::Streamed(_) => {}
        }
    }

    /// Tells streamed surface `surface` (whose volume is `volume`) that chunks `changed` were
    /// loaded, evicted or edited: the loaded chunks that read them are queued, the others lose
    /// their meshes (listed in the next change list); and that chunks `alone` were loaded or
    /// evicted empty where they read as empty either way (no mesh reading them changes): they
    /// are queued, or lose their meshes, alone.
    pub(crate) fn streamed_changes(
        &mut self,
        surface: usize,
        volume: &Volume,
        changed: &[ChunkKey],
        alone: &[ChunkKey],
        loaded: &dyn Fn(ChunkKey) -> bool,
    ) {
        let Some(s) = self.surfaces.get_mut(surface) else { return };
        let Backend::Streamed(st) = &mut s.backend else { return };
        let mut dropped = Vec::new();
        let readers = |k: ChunkKey| MeshWorkers::readers(volume, k);
        let alone = alone.iter().map(|&k| vec![k]);
        for ds in changed.iter().map(|&k| readers(k)).chain(alone) {
            for d in ds {
                if loaded(d) {
                    s.queued.insert(d);
                } else {
                    s.queued.remove(&d);
                    st.workers.cancel(d);
                    if st.meshes.remove(&d).is_some() {
                        dropped.push((surface, d));
                    }
                }
            }
        }
        self.shown_now(&dropped);
    }

    /// Meshes a streamed surface's queued chunks nearest `focus` first (grid units).
    pub(crate) fn set_focus(&mut self, focus: DVec3) {
        for s in &mut self.surfaces {
            if let Backend::Streamed(st) = &mut s.backend
                && focus.is_finite()
            {
                st.focus = focus;
            }
        }
    }

    /// Notes chunks shown (or dropped) for the next change list, when a renderer follows.
    fn shown_now(&mut self, shown: &[(usize, ChunkKey)]) {
        // Only what a renderer already showing these surfaces needs; otherwise the next list is
        // full anyway (and nothing accumulates in an editor no renderer follows).
        if self.shown.as_ref().is_some_and(|s| s.generation == self.generation) {
            self.unshown.extend(shown.iter().copied());
        }
    }

    /// Remeshes queued chunks, in batches, until `budget` is spent (at least one batch), then
    /// shows the new meshes that can be shown without a crack; a streamed surface hands its
    /// queued chunks to its workers, nearest the focus first, until `budget` is spent and shows
    /// what they have finished. Returns the chunks shown, and the
    /// chunks still queued or staged.
    pub(crate) fn remesh(
        &mut self,
        surfaces: &[&dyn EditTarget],
        loaded: &dyn Fn(ChunkKey) -> bool,
        budget: Duration,
    ) -> (Vec<(usize, ChunkKey)>, usize) {
        let t0 = Instant::now();
        const BATCH: usize = 16;
        let mut computed = false;
        let mut shown = Vec::new();
        // Level of detail caps only marching cubes (tetrahedra do not patch seams between levels).
        let lod_on = self.options.mesher == Mesher::MarchingCubes;
        // A mask made or cleared moves a layer between the caller's meshing and this: its
        // chunks are queued anew and the next change list is full.
        for (s, l) in self.surfaces.iter_mut().zip(surfaces) {
            let by_caller = meshed_by_caller(self.gpu, self.options, *l);
            if s.by_caller != by_caller {
                let lod = std::mem::take(&mut s.lod);
                *s = SurfaceMeshes::new(self.options, l.volume(), lod, l.streamed());
                s.by_caller = by_caller;
                self.generation += 1;
            }
        }
        for (layer, (s, l)) in self.surfaces.iter_mut().zip(surfaces).enumerate() {
            let volume = l.volume();
            if s.by_caller {
                // Listed at once, all together (so no seam is drawn between new and stale).
                shown.extend(std::mem::take(&mut s.queued).into_iter().map(|k| (layer, k)));
                continue;
            }
            match &mut s.backend {
                Backend::Dual(d) => {
                    if !s.queued.is_empty() {
                        let queued: Vec<ChunkKey> = std::mem::take(&mut s.queued).into_iter().collect();
                        let solver = self.solver.as_mut().map(|f| &mut *f.0 as strata_mesh::VertexSolver<'_>);
                        shown.extend(d.update_solved(volume, &queued, solver).into_iter().map(|k| (layer, k)));
                    }
                    continue;
                }
                Backend::Streamed(st) => {
                    let finished = st.workers.finished();
                    st.finished_last = finished.len();
                    for (k, mesh) in finished {
                        // A chunk that left memory meanwhile keeps no mesh.
                        if !loaded(k) {
                            continue;
                        }
                        let had = if mesh.indices.is_empty() {
                            st.meshes.remove(&k).is_some()
                        } else {
                            st.meshes.insert(k, mesh);
                            true
                        };
                        if had {
                            shown.push((layer, k));
                        }
                    }
                    // The workers keep about two frames of work; the rest waits here, nearest
                    // the focus sent first.
                    let room = (2 * st.finished_last).max(MIN_BACKLOG).saturating_sub(st.workers.pending());
                    let focus = st.focus;
                    let distance = |k: &ChunkKey| {
                        let centre =
                            k.origin_grid().as_dvec3() + DVec3::splat(strata_volume::coords::CHUNK_CELLS as f64 / 2.0);
                        centre.distance_squared(focus)
                    };
                    let mut order: Vec<(f64, ChunkKey)> = s.queued.iter().map(|k| (distance(k), *k)).collect();
                    let nearest = |a: &(f64, ChunkKey), b: &(f64, ChunkKey)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
                    if order.len() > room {
                        if room == 0 {
                            order.clear();
                        } else {
                            order.select_nth_unstable_by(room - 1, nearest);
                            order.truncate(room);
                        }
                    }
                    order.sort_unstable_by(nearest);
                    for (_, k) in order {
                        if t0.elapsed() >= budget {
                            break;
                        }
                        s.queued.remove(&k);
                        if loaded(k) {
                            st.workers.submit(volume, k);
                        }
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
                        s.staged.extend(cache.compute(volume, &batch, capped));
                        computed = true;
                    }
                }
            }
            shown.extend(s.commit_staged().into_iter().map(|k| (layer, k)));
        }
        self.shown_now(&shown);
        (shown, self.pending())
    }

    /// Level of detail by camera distance: with a view, every list chunk of every layer is
    /// meshed at the coarsest level whose cell looks no larger than the view's pixel error from
    /// the eye (see [`LodView`]); chunks whose level changes are queued with their neighbours.
    /// `None` meshes everything at its stored level.
    pub(crate) fn set_view(&mut self, surfaces: &[&dyn EditTarget], view: Option<LodView>) {
        self.view = view;
        for (s, l) in self.surfaces.iter_mut().zip(surfaces) {
            if matches!(s.backend, Backend::Streamed(_)) {
                // A world chooses its chunks' levels as it streams them.
                continue;
            }
            let next = match view.filter(LodView::is_valid) {
                Some(v) => lod_levels(l.volume(), &l.transform(), &v, &s.lod),
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
            Backend::Dual(_) | Backend::Streamed(_) => None,
        }
    }

    /// The mesher a layer's meshes are made with now.
    pub(crate) fn mesher_used(&self, layer: usize) -> Option<Mesher> {
        Some(match &self.surfaces.get(layer)?.backend {
            Backend::Dual(_) => self.options.mesher,
            Backend::Streamed(_) => Mesher::MarchingCubes,
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
    pub(crate) fn take_changes(&mut self, surfaces: &[&dyn EditTarget], materials: &[Material]) -> ChangeList {
        let placements: Vec<(LayerTransform, bool)> = surfaces.iter().map(|l| (l.transform(), l.shown())).collect();
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
                // A full list has the caller mesh every chunk of its surfaces: nothing queued for
                // it is left to list again.
                for s in self.surfaces.iter_mut().filter(|s| s.by_caller) {
                    s.queued.clear();
                }
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
