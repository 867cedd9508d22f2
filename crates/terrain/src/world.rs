//! A streamed, editable world: a [`Volume`] holding the chunks around the viewers.
//!
//! Each [`World::update`] (once a frame):
//! 1. works out the chunks within the view distance of any viewer (a horizontal radius and a
//!    vertical half-height, both in grid units), when a viewer has entered another chunk;
//! 2. evicts loaded chunks outside it (an edited one is kept for the next flush);
//! 3. queues the missing ones for the worker threads, nearest first (a worker reads a chunk's
//!    edited version from the database, else generates it from the recipe); sky that the
//!    recipe's bounds prove empty, and that the database holds no edit of, is loaded at once;
//! 4. integrates finished chunks until the frame's time budget is spent, nearest first, and never
//!    beyond the memory budget;
//! 5. flushes edited chunks to the database when the flush interval has passed.
//!
//! Edits ([`World::edit`]) first load, synchronously, every chunk within one chunk of the edit's
//! box, so an edit never writes into a chunk whose contents are not in memory; the chunks it
//! changed are marked edited. The world keeps no history: the edit's report carries its undo
//! record, which the editor's budgeted history keeps (`strata_editor::Editor::on_world`), and
//! [`World::restore`] loads the chunks a record restores the same way, so undo works across
//! eviction and reload. A crash loses at most the edits of the last flush interval
//! ([`WorldSettings::flush_interval`]); a flush is one transaction.

use std::collections::{HashMap, HashSet};
use std::hash::BuildHasherDefault;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use glam::{DVec3, IVec3};
use strata_volume::brush::Aabb;
use strata_volume::coords::CHUNK_CELLS;
use strata_volume::{ChunkKey, EditReport, KeyHasher, Level, UndoRecord, Volume, generate_chunk};
use thiserror::Error;

use crate::field::TerrainField;
use crate::recipe::{Recipe, RecipeError};
use crate::store::{StoreError, StoredChunk, WorldStore};

/// How a world streams and pages.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldSettings {
    /// Horizontal view distance (grid units): chunks whose nearest point is within it of a
    /// viewer (in x and z) are loaded.
    pub view_distance: f64,
    /// Vertical view distance as a fraction of the horizontal one.
    pub vertical_ratio: f64,
    /// Worker threads generating and paging in (at least 1; by default one per core: they run
    /// at the least priority, below the meshers' and the frame's thread, which still have the
    /// cores when they need them).
    pub threads: usize,
    /// Main-thread time per [`World::update`] spent integrating finished chunks.
    pub frame_budget: Duration,
    /// Edited chunks are written at least this often, and when the world is dropped (an edited
    /// chunk that leaves memory meanwhile is kept aside until then).
    pub flush_interval: Duration,
    /// Heap bytes of loaded chunks the world may hold; chunks beyond it wait.
    pub memory_budget: usize,
    /// Chunks within this horizontal distance of a viewer (and the vertical ratio of it) are
    /// generated at [`WorldSettings::detail_level`], the others at the base level (16³ cells):
    /// near terrain fine, far terrain coarse. 0 turns it off.
    pub detail_distance: f64,
    /// The level of the chunks near the viewers (1: 32³ cells a chunk, 2: 64³).
    pub detail_level: Level,
    /// Chunks with no point within this horizontal distance of any viewer (and the vertical
    /// ratio of it) are generated at [`Level::COARSEST`] (8³ cells of two grid units a chunk,
    /// about a quarter of a base chunk's generation time): a clipmap whose far ring is coarse.
    /// Edits never land in a coarse chunk: the chunks near an edit are generated again at the
    /// base level first. 0 turns it off.
    pub coarse_distance: f64,
}

impl Default for WorldSettings {
    fn default() -> Self {
        WorldSettings {
            view_distance: 256.0,
            vertical_ratio: 0.5,
            threads: std::thread::available_parallelism().map_or(2, |n| n.get()).clamp(1, 256),
            frame_budget: Duration::from_millis(4),
            flush_interval: Duration::from_secs(2),
            memory_budget: 512 << 20,
            detail_distance: 0.0,
            detail_level: Level::new(1).expect("level 1 exists"),
            coarse_distance: 0.0,
        }
    }
}

/// Why a world operation failed.
#[derive(Debug, Error)]
pub enum WorldError {
    /// The recipe is invalid.
    #[error(transparent)]
    Recipe(#[from] RecipeError),
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A setting is out of range.
    #[error("world setting `{0}` is out of range")]
    Setting(&'static str),
    /// An edit reaches chunks that could not be read.
    #[error("chunk {0:?} could not be read, so it cannot be edited: {1}")]
    Unreadable([i32; 3], String),
    /// The edit itself failed.
    #[error("{0}")]
    Edit(String),
}

/// What one [`World::update`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UpdateReport {
    /// Chunks integrated this update.
    pub integrated: usize,
    /// Chunks evicted.
    pub evicted: usize,
    /// Chunks waiting for a worker or for integration.
    pub pending: usize,
    /// Whether edited chunks were flushed.
    pub flushed: bool,
    /// Whether the memory budget held chunks back.
    pub over_budget: bool,
    /// Of the chunks integrated, those the recipe proves empty (sky above anything the terrain
    /// reaches) or solid rock (below the caves and the soil), not edited: loaded at once,
    /// without a worker.
    pub proven_empty: usize,
}

/// Sets and maps of chunk keys with the volume's fast key hasher.
type KeySet = HashSet<ChunkKey, BuildHasherDefault<KeyHasher>>;
type KeyMap<V> = HashMap<ChunkKey, V, BuildHasherDefault<KeyHasher>>;

/// One request to a worker.
struct Job {
    key: ChunkKey,
    ticket: u64,
    distance: f64,
    level: Level,
}

/// Lowers the calling worker thread's scheduling priority to the least, below the meshers', so
/// that a frame's thread does not wait for its time slices (ARCHITECTURE: "Worker threads").
/// Lowering a priority is not refused on Linux; elsewhere a refusal leaves the normal one.
fn background_priority() {
    let _ = thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Min);
}

/// Queue order: farthest first (workers pop the nearest from the end).
fn farthest_first(a: &Job, b: &Job) -> std::cmp::Ordering {
    b.distance.total_cmp(&a.distance).then(b.key.cmp(&a.key))
}

/// How many of the nearest jobs a queue keeps in order: more than the workers take between two
/// moves of a viewer across a chunk (a full sort of a fast flight's 15,000 jobs took most of a
/// frame's update).
const ORDERED: usize = 1024;

/// Orders `jobs` far enough for workers popping from the end: the nearest [`ORDERED`] last, in
/// order, every other job before them. Returns where the ordered tail starts.
fn order_tail(jobs: &mut [Job]) -> usize {
    if jobs.len() <= 2 * ORDERED {
        jobs.sort_unstable_by(farthest_first);
        return 0;
    }
    let from = jobs.len() - ORDERED;
    jobs.select_nth_unstable_by(from, farthest_first);
    jobs[from..].sort_unstable_by(farthest_first);
    from
}

/// A list of jobs whose tail from `ordered_from` is in order ([`order_tail`]).
#[derive(Default)]
struct Jobs {
    list: Vec<Job>,
    ordered_from: usize,
}

impl Jobs {
    fn pop(&mut self) -> Option<Job> {
        self.list.pop()
    }

    /// A list already ordered by [`order_tail`] from `ordered_from`.
    fn ordered(list: Vec<Job>, ordered_from: usize) -> Jobs {
        Jobs { list, ordered_from }
    }

    /// Orders it again once the workers took most of the ordered tail.
    fn keep_ordered(&mut self) {
        if self.ordered_from > 0 && self.list.len() < self.ordered_from + ORDERED / 4 {
            self.ordered_from = order_tail(&mut self.list);
        }
    }
}

/// The workers' queue.
#[derive(Default)]
struct Queue {
    /// Chunks not loaded, nearest last (workers pop the nearest from the end).
    jobs: Jobs,
    /// Loaded chunks to be generated again at another level, the same way; taken only when
    /// `jobs` is empty (the view fills before it sharpens).
    refine: Jobs,
    shutdown: bool,
}

/// A chunk's contents as a worker produced them.
struct Produced {
    stored: StoredChunk,
    /// Read from the database (an edited chunk).
    edited: bool,
    /// Uniform by the recipe's bounds (the same at every level).
    proven: bool,
}

/// A finished request.
struct Done {
    key: ChunkKey,
    ticket: u64,
    /// The level it was generated at.
    level: Level,
    result: Result<Produced, String>,
}

/// Shared with the workers.
struct Shared {
    queue: Mutex<Queue>,
    wake: Condvar,
    stop: AtomicBool,
}

/// A streamed, editable world (see the module docs).
pub struct World {
    field: Arc<TerrainField>,
    store: Option<Arc<WorldStore>>,
    settings: WorldSettings,
    level: Level,
    volume: Volume,
    /// Chunks whose contents are in `volume` (even when empty).
    loaded: KeySet,
    /// Heap bytes of the loaded chunks.
    loaded_bytes: usize,
    /// Loaded chunks edited since the last flush.
    dirty: KeySet,
    /// Loaded chunks that differ from the recipe (edited here or read from the database): their
    /// level stays what it is when the viewer moves.
    edited: KeySet,
    /// Edited chunks that left memory before they were flushed.
    evicted_dirty: KeyMap<StoredChunk>,
    /// Requests sent to workers: key → ticket.
    pending: KeyMap<u64>,
    next_ticket: u64,
    /// Finished requests not yet integrated (the frame budget ran out).
    ready: Vec<Done>,
    /// Chunks that could not be read (they are neither loaded nor editable).
    failed: KeyMap<String>,
    /// Loaded chunks generated from the recipe (neither edited nor uniform by its bounds), with
    /// the level they were generated at: those that follow the viewers' distance.
    generated: KeyMap<Level>,
    /// Chunks the database holds (edited ones): read at open, kept by every flush. A chunk not
    /// among them is what the recipe makes.
    in_store: KeySet,
    desired: KeySet,
    /// The viewers' chunks when `desired` was computed.
    desired_for: Vec<IVec3>,
    /// The view stencil (offsets from a viewer's chunk), computed once.
    stencil: Arc<[IVec3]>,
    /// The offsets whose side of the coarse distance a one-chunk move can change, computed once.
    coarse_shell: Arc<[IVec3]>,
    /// Chunks whose contents changed since [`World::take_changed`] (for meshers).
    changed: Vec<ChunkKey>,
    /// Chunks loaded or evicted empty (where nothing was, or nothing is left), since
    /// [`World::take_alone`].
    alone: Vec<ChunkKey>,
    /// Notes written with the next flush.
    notes: Vec<(String, Vec<u8>)>,
    last_flush: Instant,
    shared: Arc<Shared>,
    /// (In a mutex only so that the world is `Sync`, as an editor holding it is shared by
    /// reference; it is reached through `&mut self` by `get_mut`, never locked.)
    results: Mutex<Receiver<Done>>,
    workers: Vec<JoinHandle<()>>,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("loaded", &self.loaded.len())
            .field("pending", &self.pending.len())
            .field("dirty", &self.dirty.len())
            .field("store", &self.store.as_ref().map(|s| s.path().to_path_buf()))
            .finish()
    }
}

fn chunk_of(p: DVec3) -> IVec3 {
    (p / CHUNK_CELLS as f64).floor().as_ivec3()
}

impl World {
    /// A world of `recipe` kept in memory only (nothing is paged).
    pub fn in_memory(recipe: &Recipe, settings: WorldSettings) -> Result<Self, WorldError> {
        Self::start(TerrainField::new(recipe)?, None, settings)
    }

    /// A new world file at `path`.
    pub fn create(path: &std::path::Path, recipe: &Recipe, settings: WorldSettings) -> Result<Self, WorldError> {
        let store = WorldStore::create(path, recipe)?;
        Self::start(TerrainField::new(recipe)?, Some(store), settings)
    }

    /// Opens the world file at `path`.
    pub fn open(path: &std::path::Path, settings: WorldSettings) -> Result<Self, WorldError> {
        let store = WorldStore::open(path)?;
        let field = TerrainField::new(store.recipe())?;
        Self::start(field, Some(store), settings)
    }

    fn start(field: TerrainField, store: Option<WorldStore>, settings: WorldSettings) -> Result<Self, WorldError> {
        if !(settings.view_distance.is_finite() && settings.view_distance >= 0.0 && settings.view_distance <= 1e6) {
            return Err(WorldError::Setting("view_distance"));
        }
        if !(settings.vertical_ratio.is_finite() && (0.0..=4.0).contains(&settings.vertical_ratio)) {
            return Err(WorldError::Setting("vertical_ratio"));
        }
        if settings.threads == 0 || settings.threads > 256 {
            return Err(WorldError::Setting("threads"));
        }
        if !(settings.detail_distance.is_finite() && (0.0..=1e6).contains(&settings.detail_distance)) {
            return Err(WorldError::Setting("detail_distance"));
        }
        if !(settings.coarse_distance.is_finite() && (0.0..=1e6).contains(&settings.coarse_distance)) {
            return Err(WorldError::Setting("coarse_distance"));
        }
        let in_store = match &store {
            Some(store) => store.edited_keys()?.into_iter().collect(),
            None => KeySet::default(),
        };
        let field = Arc::new(field);
        let store = store.map(Arc::new);
        let shared = Arc::new(Shared {
            queue: Mutex::new(Queue::default()),
            wake: Condvar::new(),
            stop: AtomicBool::new(false),
        });
        let (tx, rx) = channel();
        let level = Level::BASE;
        let workers = (0..settings.threads)
            .map(|i| {
                let (field, store, shared, tx) = (field.clone(), store.clone(), shared.clone(), tx.clone());
                std::thread::Builder::new()
                    .name(format!("terrain-{i}"))
                    .spawn(move || {
                        background_priority();
                        work(&field, store.as_deref(), &shared, &tx)
                    })
                    .expect("a worker thread starts")
            })
            .collect();
        Ok(World {
            field,
            store,
            settings,
            level,
            volume: Volume::with_level(level),
            loaded: KeySet::default(),
            loaded_bytes: 0,
            dirty: KeySet::default(),
            edited: KeySet::default(),
            evicted_dirty: KeyMap::default(),
            pending: KeyMap::default(),
            next_ticket: 0,
            ready: Vec::new(),
            failed: KeyMap::default(),
            generated: KeyMap::default(),
            in_store,
            desired: KeySet::default(),
            desired_for: Vec::new(),
            stencil: Arc::new([]),
            coarse_shell: Arc::new([]),
            changed: Vec::new(),
            alone: Vec::new(),
            notes: Vec::new(),
            last_flush: Instant::now(),
            shared,
            results: Mutex::new(rx),
            workers,
        })
    }

    /// The loaded part of the world.
    pub fn volume(&self) -> &Volume {
        &self.volume
    }

    /// The recipe.
    pub fn recipe(&self) -> &Recipe {
        self.field.recipe()
    }

    /// The terrain field.
    pub fn field(&self) -> &TerrainField {
        &self.field
    }

    /// The settings.
    pub fn settings(&self) -> &WorldSettings {
        &self.settings
    }

    /// The world file, if paged.
    pub fn store(&self) -> Option<&WorldStore> {
        self.store.as_deref()
    }

    /// Whether chunk `key`'s contents are in memory.
    pub fn is_loaded(&self, key: ChunkKey) -> bool {
        self.loaded.contains(&key)
    }

    /// The loaded chunks.
    pub fn loaded(&self) -> impl Iterator<Item = ChunkKey> + '_ {
        self.loaded.iter().copied()
    }

    /// Number of loaded chunks.
    pub fn loaded_count(&self) -> usize {
        self.loaded.len()
    }

    /// Heap bytes of the loaded chunks (what the memory budget bounds).
    pub fn loaded_bytes(&self) -> usize {
        self.loaded_bytes
    }

    /// Chunks that could not be read, with why.
    pub fn failed(&self) -> impl Iterator<Item = (ChunkKey, &str)> {
        self.failed.iter().map(|(k, w)| (*k, w.as_str()))
    }

    /// Chunks requested from the workers or waiting to be integrated.
    pub fn pending_count(&self) -> usize {
        self.pending.len()
    }

    /// Edited chunks not yet written.
    pub fn unflushed(&self) -> usize {
        self.dirty.len() + self.evicted_dirty.len()
    }

    /// Changes (chunks loaded, evicted or edited) waiting for [`World::take_changed`] and
    /// [`World::take_alone`].
    pub fn changed_count(&self) -> usize {
        self.changed.len() + self.alone.len()
    }

    /// Chunks whose contents changed (loaded, evicted, edited) since the last call: a mesher
    /// remeshes every chunk that reads them. A chunk loaded or evicted empty where it read as
    /// empty either way is not among them ([`World::take_alone`]).
    pub fn take_changed(&mut self) -> Vec<ChunkKey> {
        std::mem::take(&mut self.changed)
    }

    /// Chunks loaded empty where nothing was loaded, or evicted empty, since the last call (most
    /// of them sky, as a view moves): no mesh that reads them changes, since a chunk not in
    /// memory reads as empty, but their own mesh may (the surface can pass through the cells
    /// at their edges, whose crossings their neighbours own), so a mesher meshes or drops them
    /// alone.
    pub fn take_alone(&mut self) -> Vec<ChunkKey> {
        std::mem::take(&mut self.alone)
    }

    /// Whether a chunk at offset `o` from a viewer's chunk is in view: the chunk column's
    /// nearest point is within the horizontal view distance of the viewer's chunk centre, and the
    /// chunk's height range meets the vertical view distance around it.
    fn in_stencil(&self, o: IVec3) -> bool {
        self.within(o, self.settings.view_distance)
    }

    /// [`World::in_stencil`] for a horizontal distance `r`.
    fn within(&self, o: IVec3, r: f64) -> bool {
        let c = CHUNK_CELLS as f64;
        let rv = r * self.settings.vertical_ratio;
        let near = |d: i32| {
            // Nearest point of [d c, d c + c] to the centre c / 2.
            ((c / 2.0).clamp(d as f64 * c, (d + 1) as f64 * c) - c / 2.0).abs()
        };
        let (nx, nz) = (near(o.x), near(o.z));
        let (y0, y1) = (((c / 2.0 - rv) / c).floor() as i32, ((c / 2.0 + rv) / c).floor() as i32);
        nx * nx + nz * nz <= r * r && (y0..=y1).contains(&o.y)
    }

    /// The offsets [`World::in_stencil`] accepts.
    fn stencil(&self) -> Vec<IVec3> {
        self.offsets_within(self.settings.view_distance, |o| self.in_stencil(o))
    }

    /// The offsets that `keep` accepts among those whose chunks can be within the horizontal
    /// distance `r` (and its vertical ratio) of a viewer's chunk.
    fn offsets_within(&self, r: f64, keep: impl Fn(IVec3) -> bool) -> Vec<IVec3> {
        let c = CHUNK_CELLS as f64;
        let h = (r / c).ceil() as i32 + 1;
        let v = (r * self.settings.vertical_ratio / c).ceil() as i32 + 1;
        let mut out = Vec::new();
        for z in -h..=h {
            for x in -h..=h {
                for y in -v..=v {
                    let o = IVec3::new(x, y, z);
                    if keep(o) {
                        out.push(o);
                    }
                }
            }
        }
        out
    }

    /// The chunks within the view distance of `viewers` (see [`WorldSettings`] and
    /// [`World::update`]: distances are measured from the centre of the chunk a viewer is in).
    pub fn chunks_in_view(&self, viewers: &[DVec3]) -> HashSet<ChunkKey> {
        let stencil = self.stencil();
        let mut out = HashSet::new();
        for v in viewers.iter().filter(|v| v.is_finite()) {
            let at = chunk_of(*v);
            out.extend(stencil.iter().map(|&o| ChunkKey(at + o)));
        }
        out
    }

    /// The level chunk `key` is generated at for viewers in the chunks `at`: the detail level
    /// within the detail distance, the coarsest level beyond the coarse distance, else the
    /// base level.
    fn level_for(&self, key: ChunkKey, at: &[IVec3]) -> Level {
        let (d, c) = (self.settings.detail_distance, self.settings.coarse_distance);
        if d > 0.0 && at.iter().any(|&v| self.within(key.0 - v, d)) {
            self.settings.detail_level
        } else if c > 0.0 && !at.iter().any(|&v| self.within(key.0 - v, c)) {
            Level::COARSEST
        } else {
            self.level
        }
    }

    /// The level a chunk entering the view is generated at first: with a coarse distance, a
    /// chunk the viewers want at the base level comes coarse first and is generated again at
    /// the base level once every chunk in view is loaded, so a fast flight fills the view
    /// before it sharpens it.
    fn first_level(&self, key: ChunkKey, at: &[IVec3]) -> Level {
        let want = self.level_for(key, at);
        if self.settings.coarse_distance > 0.0 && want == self.level { Level::COARSEST } else { want }
    }

    /// The level chunk `key` is generated at for the current viewers.
    pub fn generated_level(&self, key: ChunkKey) -> Level {
        self.level_for(key, &self.desired_for)
    }

    /// The offsets from a viewer's chunk on whose side of the horizontal distance `r` (and its
    /// vertical ratio) a move of the viewer by one chunk on each axis can change: within `r` plus
    /// two chunk widths and not within `r` less two (a move shifts a chunk's nearest point by
    /// under 23 grid units and its height range by one chunk).
    fn shell(&self, r: f64) -> Vec<IVec3> {
        let c = CHUNK_CELLS as f64;
        let (outer, inner) = (r + 2.0 * c, (r - 2.0 * c).max(0.0));
        self.offsets_within(outer, |o| self.within(o, outer) && !self.within(o, inner))
    }

    /// Loaded chunks that may have crossed the detail or the coarse distance when the viewers
    /// moved from the chunks `from` to [`World::desired_for`].
    fn level_candidates(&mut self, from: &[IVec3]) -> KeySet {
        let mut out = KeySet::default();
        if self.settings.detail_distance > 0.0 {
            let r = (self.settings.detail_distance / CHUNK_CELLS as f64).ceil() as i32 + 2;
            let rv =
                (self.settings.detail_distance * self.settings.vertical_ratio / CHUNK_CELLS as f64).ceil() as i32 + 2;
            for c in from.iter().chain(self.desired_for.iter()) {
                for z in -r..=r {
                    for y in -rv..=rv {
                        for x in -r..=r {
                            out.insert(ChunkKey(*c + IVec3::new(x, y, z)));
                        }
                    }
                }
            }
        }
        if self.settings.coarse_distance > 0.0 {
            let small_move = from.len() == self.desired_for.len()
                && from.iter().zip(&self.desired_for).all(|(a, b)| (*a - *b).abs().max_element() <= 1);
            if small_move {
                if self.coarse_shell.is_empty() {
                    self.coarse_shell = self.shell(self.settings.coarse_distance).into();
                }
                for c in from.iter().chain(self.desired_for.iter()) {
                    out.extend(self.coarse_shell.iter().map(|&o| ChunkKey(*c + o)));
                }
            } else {
                out.extend(self.loaded.iter().copied());
            }
        }
        out
    }

    fn stencil_cached(&mut self) -> Arc<[IVec3]> {
        if self.stencil.is_empty() {
            self.stencil = self.stencil().into();
        }
        self.stencil.clone()
    }

    fn distance(viewers: &[DVec3], key: ChunkKey) -> f64 {
        let c = CHUNK_CELLS as f64;
        let centre = (key.0.as_dvec3() + DVec3::splat(0.5)) * c;
        viewers.iter().map(|v| v.distance_squared(centre)).fold(f64::INFINITY, f64::min)
    }

    /// One frame of streaming (see the module docs).
    pub fn update(&mut self, viewers: &[DVec3]) -> UpdateReport {
        let start = Instant::now();
        let mut report = UpdateReport::default();
        let at: Vec<IVec3> = viewers.iter().map(|&v| chunk_of(v)).collect();
        if at != self.desired_for {
            // What enters and leaves the view: for one viewer that moved, the difference of the
            // view stencil at the old and new chunk (no set of the whole view is rebuilt);
            // otherwise the whole view again.
            let stencil = self.stencil_cached();
            let from = self.desired_for.clone();
            let (entering, leaving): (Vec<ChunkKey>, Vec<ChunkKey>) = if let ([old], [new]) =
                (from.as_slice(), at.as_slice())
            {
                let (old, new) = (*old, *new);
                let entering =
                    stencil.iter().filter(|&&o| !self.in_stencil(new + o - old)).map(|&o| ChunkKey(new + o)).collect();
                let leaving =
                    stencil.iter().filter(|&&o| !self.in_stencil(old + o - new)).map(|&o| ChunkKey(old + o)).collect();
                (entering, leaving)
            } else {
                let mut all = KeySet::default();
                for &c in &at {
                    all.extend(stencil.iter().map(|&o| ChunkKey(c + o)));
                }
                let leaving = self.desired.iter().copied().filter(|k| !all.contains(k)).collect();
                let entering = all.iter().copied().filter(|k| !self.desired.contains(k)).collect();
                (entering, leaving)
            };
            self.desired_for = at;
            for k in &leaving {
                self.desired.remove(k);
            }
            self.desired.extend(entering.iter().copied());
            // Evict what left the view; requests for it are dropped.
            for key in leaving {
                if self.loaded.contains(&key) {
                    self.evict(key);
                    report.evicted += 1;
                }
                self.pending.remove(&key);
            }
            self.ready.retain(|d| self.desired.contains(&d.key));
            let mut wanted: Vec<ChunkKey> = entering
                .into_iter()
                .filter(|k| !self.loaded.contains(k) && !self.pending.contains_key(k) && !self.failed.contains_key(k))
                .collect();
            // Edited chunks evicted before a flush come back from memory, not from a worker.
            wanted.retain(|k| {
                if let Some(stored) = self.evicted_dirty.remove(k) {
                    self.integrate(*k, stored);
                    self.dirty.insert(*k);
                    report.integrated += 1;
                    false
                } else {
                    true
                }
            });
            // Chunks the recipe proves empty (the sky) or solid rock (below the caves and the
            // soil) need no worker, unless the database holds an edit of them.
            wanted.retain(|&k| {
                if self.in_store.contains(&k) {
                    return true;
                }
                let stored = match self.field.decided_by_recipe(k.origin_grid()) {
                    Some(false) => StoredChunk { chunk: None, materials: None },
                    Some(true) => match self.field.proven_rock_materials(k.origin_grid()) {
                        Some(materials) => StoredChunk { chunk: Some(strata_volume::Chunk::Solid), materials },
                        None => return true,
                    },
                    None => return true,
                };
                self.integrate(k, stored);
                report.integrated += 1;
                report.proven_empty += 1;
                false
            });
            let (mut jobs, mut refine) = {
                let mut q = self.shared.queue.lock().expect("the queue lock is never poisoned");
                (std::mem::take(&mut q.jobs.list), std::mem::take(&mut q.refine.list))
            };
            // Outside the lock (workers go on with what they hold): drop stale requests, add the
            // new ones, order by distance (the old order is nearly right: the sort is cheap).
            jobs.retain(|j| self.pending.get(&j.key) == Some(&j.ticket));
            refine.retain(|j| self.pending.get(&j.key) == Some(&j.ticket));
            // Chunks that crossed the detail or the coarse distance are generated again at their
            // new level (the old version stays until the new one is integrated); edited ones
            // keep theirs.
            let mut again = Vec::new();
            for key in self.level_candidates(&from) {
                let Some(&now) = self.generated.get(&key) else { continue };
                if self.pending.contains_key(&key) {
                    continue;
                }
                if self.level_for(key, &self.desired_for) != now {
                    again.push(key);
                }
            }
            for key in wanted {
                self.next_ticket += 1;
                self.pending.insert(key, self.next_ticket);
                jobs.push(Job { key, ticket: self.next_ticket, distance: 0.0, level: Level::BASE });
            }
            for key in again {
                self.next_ticket += 1;
                self.pending.insert(key, self.next_ticket);
                refine.push(Job { key, ticket: self.next_ticket, distance: 0.0, level: Level::BASE });
            }
            for j in jobs.iter_mut() {
                j.distance = Self::distance(viewers, j.key);
                j.level = self.first_level(j.key, &self.desired_for);
            }
            // A level change asked for before the viewers moved back is dropped.
            refine.retain_mut(|j| {
                j.level = self.level_for(j.key, &self.desired_for);
                let keep = self.generated.get(&j.key) != Some(&j.level);
                if !keep {
                    self.pending.remove(&j.key);
                }
                keep
            });
            for j in refine.iter_mut() {
                j.distance = Self::distance(viewers, j.key);
            }
            let (jobs_from, refine_from) = (order_tail(&mut jobs), order_tail(&mut refine));
            {
                let mut q = self.shared.queue.lock().expect("the queue lock is never poisoned");
                // Workers found the queue empty meanwhile; nothing else adds to it.
                q.jobs = Jobs::ordered(jobs, jobs_from);
                q.refine = Jobs::ordered(refine, refine_from);
            }
            self.shared.wake.notify_all();
        }
        // Integrate finished chunks, nearest first, within the frame budget and memory budget.
        let results = self.results.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
        while let Ok(done) = results.try_recv() {
            if self.pending.get(&done.key) == Some(&done.ticket) {
                self.ready.push(done);
            }
        }
        if !self.ready.is_empty() {
            self.ready.sort_by(|a, b| {
                Self::distance(viewers, b.key).total_cmp(&Self::distance(viewers, a.key)).then(b.key.cmp(&a.key))
            });
        }
        let mut sharpen = Vec::new();
        while let Some(done) = self.ready.pop() {
            let bytes = done.result.as_ref().map_or(0, |p| p.stored.chunk.as_ref().map_or(0, |c| c.heap_bytes()));
            if self.loaded_bytes + bytes > self.settings.memory_budget {
                report.over_budget = true;
                self.ready.push(done);
                break;
            }
            self.pending.remove(&done.key);
            match done.result {
                Ok(p) => {
                    if self.dirty.contains(&done.key) {
                        // Edited since it was asked for: the edit wins.
                        continue;
                    }
                    self.integrate_produced(done.key, done.level, p);
                    report.integrated += 1;
                    // Generated coarse first (or asked for before the viewers moved): generated
                    // again at the level it is wanted at once the view is full.
                    if self.generated.get(&done.key).is_some_and(|&l| l != self.level_for(done.key, &self.desired_for))
                    {
                        sharpen.push(done.key);
                    }
                }
                Err(why) => {
                    self.failed.insert(done.key, why);
                }
            }
            if start.elapsed() >= self.settings.frame_budget {
                break;
            }
        }
        self.queue_again(sharpen, viewers);
        if let Ok(mut q) = self.shared.queue.lock() {
            q.jobs.keep_ordered();
            q.refine.keep_ordered();
        }
        report.pending = self.pending.len();
        debug_assert_eq!(
            self.loaded_bytes,
            self.loaded.iter().filter_map(|k| self.volume.chunk(*k)).map(|c| c.heap_bytes()).sum::<usize>(),
            "the running count of loaded bytes"
        );
        if self.last_flush.elapsed() >= self.settings.flush_interval && (self.unflushed() > 0 || !self.notes.is_empty())
        {
            report.flushed = self.flush().is_ok();
        }
        report
    }

    /// Queues `keys` (loaded chunks generated at another level than they are wanted at) to be
    /// generated again at their level, after every missing chunk.
    fn queue_again(&mut self, keys: Vec<ChunkKey>, viewers: &[DVec3]) {
        if keys.is_empty() {
            return;
        }
        let jobs: Vec<Job> = keys
            .into_iter()
            .map(|key| {
                self.next_ticket += 1;
                self.pending.insert(key, self.next_ticket);
                let level = self.level_for(key, &self.desired_for);
                Job { key, ticket: self.next_ticket, distance: Self::distance(viewers, key), level }
            })
            .collect();
        let mut all = {
            let mut q = self.shared.queue.lock().expect("the queue lock is never poisoned");
            std::mem::take(&mut q.refine.list)
        };
        // (Workers take from the main queue meanwhile, or wait for this one.)
        all.extend(jobs);
        let from = order_tail(&mut all);
        {
            let mut q = self.shared.queue.lock().expect("the queue lock is never poisoned");
            let taken_meanwhile = std::mem::replace(&mut q.refine, Jobs::ordered(all, from));
            debug_assert!(taken_meanwhile.list.is_empty(), "only the main thread adds jobs");
        }
        self.shared.wake.notify_all();
    }

    /// Integrates what a worker (or [`World::load_now`]) produced at `level`, noting whether it
    /// follows the viewers' distance.
    fn integrate_produced(&mut self, key: ChunkKey, level: Level, p: Produced) {
        if p.edited {
            self.edited.insert(key);
        }
        if p.edited || p.proven {
            self.generated.remove(&key);
        } else {
            self.generated.insert(key, level);
        }
        self.integrate(key, p.stored);
    }

    fn integrate(&mut self, key: ChunkKey, stored: StoredChunk) {
        self.loaded_bytes += stored.chunk.as_ref().map_or(0, |c| c.heap_bytes());
        let empty = stored.chunk.is_none();
        let (old, _) = self.volume.put_chunk(key, stored.chunk, stored.materials);
        self.loaded_bytes -= old.as_ref().map_or(0, |c| c.heap_bytes());
        if self.loaded.insert(key) && empty && old.is_none() {
            // Nothing that reads it changes: a chunk not in memory reads as empty.
            self.alone.push(key);
        } else {
            self.changed.push(key);
        }
    }

    fn evict(&mut self, key: ChunkKey) {
        self.generated.remove(&key);
        let (chunk, materials) = self.volume.take_chunk(key);
        self.loaded_bytes -= chunk.as_ref().map_or(0, |c| c.heap_bytes());
        self.loaded.remove(&key);
        self.edited.remove(&key);
        // An empty chunk leaving memory changes nothing that reads it (it reads as empty).
        if chunk.is_none() {
            self.alone.push(key)
        } else {
            self.changed.push(key)
        }
        if self.dirty.remove(&key) {
            self.evicted_dirty.insert(key, StoredChunk { chunk, materials });
        }
    }

    /// Loads, now, every chunk in `keys` that is not in memory (edited versions first from the
    /// evicted-but-unflushed ones, then the database, else generated at its level, never
    /// coarser than the base level: what is loaded now is loaded to be edited or read closely).
    pub fn load_now(&mut self, keys: &[ChunkKey]) -> Result<(), WorldError> {
        for &key in keys {
            // A request in flight (a regeneration at another level) must not replace what an
            // edit is about to change.
            if self.pending.remove(&key).is_some() {
                self.ready.retain(|d| d.key != key);
            }
            if self.loaded.contains(&key) {
                continue;
            }
            if let Some(stored) = self.evicted_dirty.remove(&key) {
                self.integrate(key, stored);
                self.dirty.insert(key);
                continue;
            }
            // What is loaded now is loaded to be edited or restored: never coarser than the base.
            let level = self.level_for(key, &self.desired_for).max(self.level);
            let p = produce(&self.field, self.store.as_deref(), level, key)
                .map_err(|why| WorldError::Unreadable(key.0.to_array(), why))?;
            self.failed.remove(&key);
            self.integrate_produced(key, level, p);
        }
        Ok(())
    }

    /// The chunks an edit within `bounds` may read or write: those touching the box grown by one
    /// chunk.
    pub fn chunks_near(bounds: &Aabb) -> Vec<ChunkKey> {
        let c = CHUNK_CELLS as f64;
        let lo = (bounds.min / c).floor().as_ivec3() - IVec3::ONE;
        let hi = (bounds.max / c).floor().as_ivec3() + IVec3::ONE;
        strata_volume::ChunkBox::new(lo, hi).keys().collect()
    }

    /// Runs an edit on the loaded volume after loading every chunk near `bounds`; the chunks it
    /// changed are marked edited. The report's undo record is the caller's to keep (the world
    /// keeps no history; [`World::restore`] takes a record back).
    pub fn edit<E: std::fmt::Display>(
        &mut self,
        bounds: Aabb,
        edit: impl FnOnce(&mut Volume) -> Result<EditReport, E>,
    ) -> Result<EditReport, WorldError> {
        if !bounds.is_valid() {
            return Err(WorldError::Edit("the edit's box is not finite".into()));
        }
        let near = Self::chunks_near(&bounds);
        if near.len() > 1 << 16 {
            return Err(WorldError::Edit(format!("an edit reaching {} chunks is too large for a world", near.len())));
        }
        self.load_now(&near)?;
        self.raise_to_base(&near);
        let before = self.bytes_of(&near);
        let result = edit(&mut self.volume).map_err(|e| WorldError::Edit(e.to_string()));
        if let Ok(report) = &result {
            self.after_change(report.undo.keys().collect::<Vec<_>>().as_slice(), &before);
        }
        // Loading dropped the requests for these chunks; those the edit left alone go on to the
        // level they are wanted at (but the ring's chunks raised for the edit stay at the base
        // level, ready for the next edit, until the viewer moves).
        let again: Vec<ChunkKey> = near
            .iter()
            .copied()
            .filter(|k| {
                let want = self.level_for(*k, &self.desired_for);
                want != Level::COARSEST
                    && self.generated.get(k).is_some_and(|&l| l != want)
                    && !self.pending.contains_key(k)
            })
            .collect();
        let c = CHUNK_CELLS as f64;
        let viewers: Vec<DVec3> = self.desired_for.iter().map(|v| (v.as_dvec3() + DVec3::splat(0.5)) * c).collect();
        self.queue_again(again, &viewers);
        result
    }

    /// Generates again, at the base level, every loaded chunk of `keys` that is coarser (far
    /// terrain, never edited: edits land at the base level or finer), so that an edit never
    /// writes at less than the base resolution. A request in flight for one is dropped.
    fn raise_to_base(&mut self, keys: &[ChunkKey]) {
        for &key in keys {
            if self.generated.get(&key).is_none_or(|&l| l >= self.level) {
                continue;
            }
            if self.pending.remove(&key).is_some() {
                self.ready.retain(|d| d.key != key);
            }
            let g = generate_chunk(key, self.level, &*self.field);
            let stored = StoredChunk { chunk: g.chunk, materials: g.materials };
            let proven = self.field.decided_by_recipe(key.origin_grid()).is_some();
            self.integrate_produced(key, self.level, Produced { stored, edited: false, proven });
        }
    }

    /// Heap bytes of each of `keys`' chunks now.
    fn bytes_of(&self, keys: &[ChunkKey]) -> KeyMap<usize> {
        keys.iter().map(|&k| (k, self.volume.chunk(k).map_or(0, |c| c.heap_bytes()))).collect()
    }

    /// Marks `keys` edited: dirty, changed, and the loaded bytes moved by their change from
    /// `before` (their bytes before the change; a key without one makes a full recount).
    fn after_change(&mut self, keys: &[ChunkKey], before: &KeyMap<usize>) {
        for &k in keys {
            self.generated.remove(&k);
            self.dirty.insert(k);
            self.edited.insert(k);
            self.loaded.insert(k);
            self.changed.push(k);
        }
        if keys.iter().all(|k| before.contains_key(k)) {
            for k in keys {
                let now = self.volume.chunk(*k).map_or(0, |c| c.heap_bytes());
                self.loaded_bytes = self.loaded_bytes - before[k] + now;
            }
        } else {
            self.loaded_bytes = self.loaded.iter().filter_map(|k| self.volume.chunk(*k)).map(|c| c.heap_bytes()).sum();
        }
    }

    /// Restores an undo record of an edit of this world (loading, first, the chunks it restores
    /// that left memory: undo works across eviction and reload) and marks them edited. Returns
    /// the record that takes this back. When a chunk cannot be loaded nothing changes and the
    /// record is handed back with the error.
    pub fn restore(&mut self, record: UndoRecord) -> Result<UndoRecord, Box<(WorldError, UndoRecord)>> {
        let keys: Vec<ChunkKey> = record.keys().collect();
        if let Err(e) = self.load_now(&keys) {
            return Err(Box::new((e, record)));
        }
        let before = self.bytes_of(&keys);
        let back = self.volume.restore(record);
        self.after_change(&keys, &before);
        Ok(back)
    }

    /// Writes every edited chunk not yet written, in one transaction. A chunk edited back to what
    /// the recipe generates loses its record. Without a database nothing is written: edited
    /// chunks that leave memory are then kept aside in memory.
    pub fn flush(&mut self) -> Result<usize, WorldError> {
        if self.store.is_none() {
            self.notes.clear();
            self.last_flush = Instant::now();
            return Ok(0);
        }
        let mut writes: Vec<(ChunkKey, Option<StoredChunk>)> = Vec::with_capacity(self.unflushed());
        let count = self.unflushed();
        for &k in &self.dirty {
            let stored = StoredChunk {
                chunk: self.volume.chunk(k).cloned(),
                materials: self.volume.chunk_materials(k).cloned(),
            };
            writes.push((k, Some(stored)));
        }
        for (k, s) in &self.evicted_dirty {
            writes.push((*k, Some(s.clone())));
        }
        writes.sort_by_key(|w| w.0);
        // A chunk that is what the recipe makes is not stored.
        for (k, s) in writes.iter_mut() {
            let g = generate_chunk(*k, self.level, &*self.field);
            if s.as_ref().is_some_and(|s| s.chunk == g.chunk && s.materials == g.materials) {
                *s = None;
            }
        }
        if let Some(store) = &self.store {
            store.write_with_notes(&writes, &self.notes)?;
        }
        for (k, s) in &writes {
            if s.is_some() {
                self.in_store.insert(*k);
            } else {
                self.in_store.remove(k);
            }
        }
        self.notes.clear();
        self.dirty.clear();
        self.evicted_dirty.clear();
        self.last_flush = Instant::now();
        Ok(count)
    }

    /// Every chunk that differs from what the recipe generates at the base level (edited here,
    /// read from the database, or kept aside after eviction), with its contents, by key: what a
    /// shared room's snapshot of the world holds. A chunk edited back to what the recipe makes
    /// is left out, so worlds with the same chunks give the same list whatever was flushed.
    pub fn edited_chunks(&self) -> Result<Vec<(ChunkKey, StoredChunk)>, WorldError> {
        let mut out: KeyMap<StoredChunk> = KeyMap::default();
        for &k in self.edited.iter().chain(self.dirty.iter()) {
            if self.loaded.contains(&k) {
                let stored = StoredChunk {
                    chunk: self.volume.chunk(k).cloned(),
                    materials: self.volume.chunk_materials(k).cloned(),
                };
                out.insert(k, stored);
            }
        }
        for (k, s) in &self.evicted_dirty {
            out.entry(*k).or_insert_with(|| s.clone());
        }
        // The file's edited chunks not in memory (those in memory were read from it and are
        // marked edited: they are above, with any change since).
        if let Some(store) = &self.store {
            for k in store.edited_keys()? {
                if !out.contains_key(&k)
                    && let Some(stored) = store.read(k)?
                {
                    out.insert(k, stored);
                }
            }
        }
        let mut list: Vec<(ChunkKey, StoredChunk)> = out
            .into_iter()
            .filter(|(k, s)| {
                let g = generate_chunk(*k, self.level, &*self.field);
                !(s.chunk == g.chunk && s.materials == g.materials)
            })
            .collect();
        list.sort_by_key(|(k, _)| *k);
        Ok(list)
    }

    /// Makes the world's edited chunks exactly `chunks` (a shared room's snapshot): chunks
    /// edited here and not in it go back to what the recipe generates at the base level; those
    /// in it take its contents. Both are marked edited (written at the next flush).
    pub fn replace_edited(&mut self, chunks: Vec<(ChunkKey, StoredChunk)>) -> Result<(), WorldError> {
        let mut want: KeyMap<StoredChunk> = chunks.into_iter().collect();
        for (k, _) in self.edited_chunks()? {
            want.entry(k).or_insert_with(|| {
                let g = generate_chunk(k, self.level, &*self.field);
                StoredChunk { chunk: g.chunk, materials: g.materials }
            });
        }
        let keys: Vec<ChunkKey> = want.keys().copied().collect();
        self.load_now(&keys)?;
        let before = self.bytes_of(&keys);
        for (k, stored) in want {
            self.volume.put_chunk(k, stored.chunk, stored.materials);
        }
        self.after_change(&keys, &before);
        Ok(())
    }

    /// Sets a named note (a camera position, a counter) written in the same transaction as the
    /// next flush's chunks; read back with [`WorldStore::note`].
    pub fn set_note(&mut self, name: &str, value: Vec<u8>) {
        self.notes.retain(|(n, _)| n != name);
        self.notes.push((name.to_string(), value));
    }

    /// Blocks until every requested chunk is integrated or `timeout` passes (tests, tools);
    /// returns whether nothing is pending.
    pub fn settle(&mut self, viewers: &[DVec3], timeout: Duration) -> bool {
        let start = Instant::now();
        loop {
            self.update(viewers);
            if self.pending.is_empty() && self.ready.is_empty() {
                return true;
            }
            if start.elapsed() > timeout {
                return false;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

impl Drop for World {
    fn drop(&mut self) {
        // Nothing edited is left behind: a last flush (errors cannot be returned from a drop;
        // callers that care call `flush` first).
        let _ = self.flush();
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Ok(mut q) = self.shared.queue.lock() {
            q.shutdown = true;
        }
        self.shared.wake.notify_all();
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
        // The workers are gone: the store is this world's alone. Give back the space of pages
        // freed by rewritten chunks (redb grows its file in regions).
        if let Some(store) = self.store.as_mut().and_then(Arc::get_mut) {
            let _ = store.compact();
        }
    }
}

/// A chunk's contents: its edited version from the database, else generated at `level`.
fn produce(field: &TerrainField, store: Option<&WorldStore>, level: Level, key: ChunkKey) -> Result<Produced, String> {
    if let Some(store) = store
        && let Some(stored) = store.read(key).map_err(|e| e.to_string())?
    {
        return Ok(Produced { stored, edited: true, proven: false });
    }
    let g = generate_chunk(key, level, field);
    // Uniform at every level only where the recipe's bounds alone decide it: a decision from
    // the columns of a coarse chunk (every other column of the base level's) proves nothing
    // about the base level, where a peak between them can cross the chunk.
    let proven = field.decided_by_recipe(key.origin_grid()).is_some();
    // A uniform chunk has no level: the volume (at the base level) reads its materials per base
    // node.
    let materials = if level != Level::BASE && g.chunk == Some(strata_volume::Chunk::Solid) {
        strata_volume::solid_chunk_materials(key, Level::BASE, field)
    } else {
        g.materials
    };
    Ok(Produced { stored: StoredChunk { chunk: g.chunk, materials }, edited: false, proven })
}

fn work(field: &TerrainField, store: Option<&WorldStore>, shared: &Shared, tx: &Sender<Done>) {
    loop {
        let job = {
            let mut q = shared.queue.lock().expect("the queue lock is never poisoned");
            loop {
                if q.shutdown || shared.stop.load(Ordering::SeqCst) {
                    return;
                }
                if let Some(j) = q.jobs.pop().or_else(|| q.refine.pop()) {
                    break j;
                }
                q = shared.wake.wait(q).expect("the queue lock is never poisoned");
            }
        };
        let result = produce(field, store, job.level, job.key);
        if tx.send(Done { key: job.key, ticket: job.ticket, level: job.level, result }).is_err() {
            return;
        }
    }
}
