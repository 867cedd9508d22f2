//! The editor: a scene, the tool, the stroke in progress, history and mesh caches.

use std::time::{Duration, Instant};

use glam::DVec3;
use strata_mesh::islands::IslandReport;
use strata_mesh::{Mesh, MeshCache, MeshOptions, Mesher, MesherError};
use strata_volume::brush::BrushError;

use strata_volume::{ChunkKey, EditError, EditReport, EditSettings, Level};
use thiserror::Error;

use crate::history::{History, HistoryEntry};
use crate::lod::LodView;
use crate::scene::{Layer, Material, Scene};
use crate::target::EditTarget;
use crate::tool::ToolSettings;
use crate::view_meshes::{ChangeList, ViewMeshes};
use strata_terrain::World;

pub(crate) use crate::stroke::Stroke;

/// Why the editor refused something. The scene is unchanged.
#[derive(Debug, Error)]
pub enum EditorError {
    /// No layer with this index.
    #[error("there is no layer {0}")]
    NoLayer(usize),
    /// The layer is locked.
    #[error("layer {0} is locked")]
    Locked(usize),
    /// The layer's transform (set through its public fields) is not finite and invertible:
    /// nothing can be placed in its grid until it is repaired.
    #[error("layer {0} has a transform that is not finite and invertible")]
    BadLayerTransform(usize),
    /// A pose with NaN or infinite values.
    #[error("the tool pose is not finite")]
    BadPose,
    /// The tool's settings make no brush (zero or NaN radius, …).
    #[error(transparent)]
    Brush(#[from] BrushError),
    /// The edit was refused (too large, out of range).
    #[error(transparent)]
    Edit(#[from] EditError),
    /// A layer transform that is not finite and invertible.
    #[error(transparent)]
    Transform(#[from] crate::scene::TransformError),
    /// A field tool's dab was refused (a bad parameter, a region too large).
    #[error(transparent)]
    Tool(#[from] strata_volume::tools::ToolError),
    /// The mesher could not mesh a layer as asked (tetrahedra on mixed levels, a bad
    /// simplification bound).
    #[error(transparent)]
    Mesher(#[from] MesherError),
    /// The world could not load a chunk an edit or an undo needs (its database is unreadable):
    /// nothing changed.
    #[error(transparent)]
    World(strata_terrain::WorldError),
    /// A dab of the frame spans more chunks than [`Editor::frame_dab_limit`]: it was not
    /// applied (the dabs before it in the frame were), so that the caller can run it in the
    /// background ([`Editor::start_dab_job`]).
    #[error("a dab spanning {0} chunks is too large for a frame")]
    DabTooLargeForFrame(u64),
    /// A dab too large for a frame, on a world (whose volume cannot go to a worker thread while
    /// it streams): nothing changed.
    #[error(
        "a dab spanning {0} chunks is too large to sculpt into a streamed world (large dabs run in the background in scenes only): make the brush smaller"
    )]
    DabTooLargeForWorld(u64),
    /// A mask tool or action on a streamed world (whose pages keep no mask).
    #[error("masks are for scenes: a streamed world cannot hold one")]
    MaskOnWorld,
    /// A change that is not an operation (a whole-mask action) while the editor records
    /// operations for a room: the others would not see it.
    #[error("{0} cannot be shared with the room: leave the session first")]
    NotShared(&'static str),
    /// A reference image was refused (locked, out of range, too many, on a world).
    #[error(transparent)]
    Reference(#[from] crate::reference::ReferenceError),
    /// Mesh inserts are for scenes: a world streams, and an intersection would keep what is on
    /// disk.
    #[error("mesh inserts are for scenes: a streamed world cannot take one")]
    InsertOnWorld,
    /// A mesh that cannot be inserted, or a bad placement.
    #[error(transparent)]
    Insert(#[from] crate::insert::InsertError),
    /// The stamp tool names an image the editor does not hold (one loaded into another
    /// editor).
    #[error("the stamp tool's image is not loaded here: load it again or pick a built-in stamp")]
    UnknownStamp,
    /// The current material is not in the scene's palette.
    #[error("material {id} is not in the palette ({count} materials)")]
    UnknownMaterial {
        /// The tool's material.
        id: u8,
        /// Materials in the palette.
        count: usize,
    },
}

/// A change of a layer's whole mask ([`Editor::mask_all`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaskAction {
    /// Protect what was free and free what was protected.
    Invert,
    /// Free everything.
    Clear,
    /// Grow the masked part by a node.
    Grow,
    /// Shrink it by a node.
    Shrink,
}

impl MaskAction {
    /// Every action, in menu order.
    pub const ALL: [MaskAction; 4] = [MaskAction::Invert, MaskAction::Clear, MaskAction::Grow, MaskAction::Shrink];

    /// What the menu calls it.
    pub fn name(self) -> &'static str {
        match self {
            MaskAction::Invert => "Invert mask",
            MaskAction::Clear => "Clear mask",
            MaskAction::Grow => "Grow mask",
            MaskAction::Shrink => "Shrink mask",
        }
    }
}

/// What one frame did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReport {
    /// Brush dabs applied this frame.
    pub dabs: usize,
    /// Time spent editing.
    pub edit_time: Duration,
    /// Time spent remeshing.
    pub remesh_time: Duration,
    /// Chunks remeshed this frame (their GPU buffers need uploading).
    pub remeshed: Vec<(usize, ChunkKey)>,
    /// Chunks still waiting for a remesh after this frame.
    pub pending: usize,
}

/// The editor core: feed it one [`ToolPose`] per frame.
pub struct Editor {
    /// The scene being edited.
    pub scene: Scene,
    /// The current tool.
    pub tool: ToolSettings,
    /// How strongly strokes are stabilised (the brush trails the pointer on a rope; see
    /// [`crate::Stabiliser`]). Operations record where the dabs went, so a room replays them
    /// without it.
    pub stabiliser: crate::Stabiliser,
    /// The stamp tool's images (the tool names one by [`crate::StampSettings::source`]).
    pub stamps: crate::StampLibrary,
    /// The layer tools edit (on a world, the world: see [`Editor::active_surface`]).
    pub active_layer: usize,
    /// Dabs of [`Editor::frame`] whose box spans more chunks than this are refused with
    /// [`EditorError::DabTooLargeForFrame`] (`u64::MAX`, the default: none are).
    pub frame_dab_limit: u64,
    /// The streamed world the tools edit, for an editor made by [`Editor::on_world`].
    pub(crate) world: Option<World>,
    pub(crate) history: History,
    pub(crate) stroke: Option<Stroke>,
    /// The viewport's meshes of every layer.
    pub(crate) meshes: ViewMeshes,
    pub(crate) settings: EditSettings,
    pub(crate) revision: u64,
    /// Counts changes of the layer list (see [`Editor::structure_revision`]).
    pub(crate) structure: u64,
    /// The operations recorded for the network, while it records (see [`Editor::record_ops`]).
    pub(crate) recorder: Option<crate::op::Recorder>,
}

impl std::fmt::Debug for Editor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Editor")
            .field("layers", &self.scene.layers.len())
            .field("tool", &self.tool)
            .field("active_layer", &self.active_layer)
            .field("world", &self.world)
            .field("history", &self.history)
            .finish()
    }
}

impl Default for Editor {
    fn default() -> Self {
        Editor::new(Scene::default())
    }
}

impl Editor {
    /// An editor on `scene`, every layer queued for meshing.
    pub fn new(scene: Scene) -> Self {
        let mut e = Editor {
            scene,
            tool: ToolSettings::default(),
            stabiliser: crate::Stabiliser::Off,
            stamps: crate::StampLibrary::default(),
            active_layer: 0,
            history: History::default(),
            world: None,
            frame_dab_limit: u64::MAX,
            stroke: None,
            meshes: ViewMeshes::new(MeshOptions::default(), &[]),
            settings: EditSettings::default(),
            revision: 0,
            structure: 0,
            recorder: None,
        };
        e.reset_caches();
        e
    }

    /// An editor on a streamed world, coloured by `materials`: the tools, strokes, mirror
    /// images, line tool and budgeted history of a scene, applied to the world (its only
    /// surface; the scene has no layers). The world streams around the viewer given to
    /// [`Editor::stream`] and its chunks are meshed nearest the viewer first.
    pub fn on_world(world: World, materials: Vec<Material>) -> Self {
        let scene = Scene { layers: Vec::new(), materials, ..Scene::default() };
        let mut e = Editor::new(scene);
        e.world = Some(world);
        e.reset_caches();
        e
    }

    /// The world the editor edits, if it is on one.
    pub fn world(&self) -> Option<&World> {
        self.world.as_ref()
    }

    /// The world, to stream, flush or take notes (edits go through the tools, so that they
    /// join the history).
    pub fn world_mut(&mut self) -> Option<&mut World> {
        self.world.as_mut()
    }

    /// Streams the world around `eye` (one [`World::update`]) and meshes its chunks nearest
    /// `eye` first; nothing without a world.
    pub fn stream(&mut self, eye: DVec3) -> Option<strata_terrain::UpdateReport> {
        let world = self.world.as_mut()?;
        let report = world.update(&[eye]);
        self.meshes.set_focus(eye);
        Some(report)
    }

    /// The surface tools edit: the active layer, or on a world the world.
    pub fn active_surface(&self) -> usize {
        if self.world.is_some() { self.scene.layers.len() } else { self.active_layer }
    }

    /// Surfaces: the layers, then the world (see [`crate::target`]).
    pub fn surface_count(&self) -> usize {
        self.scene.layers.len() + self.world.is_some() as usize
    }

    /// Surface `i` (a layer, or after the layers the world).
    pub fn surface(&self, i: usize) -> Option<&dyn EditTarget> {
        match self.scene.layers.get(i) {
            Some(l) => Some(l),
            None if i == self.scene.layers.len() => self.world.as_ref().map(|w| w as &dyn EditTarget),
            None => None,
        }
    }

    pub(crate) fn surface_mut(&mut self, i: usize) -> Option<&mut dyn EditTarget> {
        surface_mut(&mut self.scene.layers, self.world.as_mut(), i)
    }

    /// Replaces the scene (new or loaded): clears history and remeshes everything.
    pub fn set_scene(&mut self, scene: Scene) {
        self.scene = scene;
        self.revision += 1;
        self.history.clear();
        self.stroke = None;
        self.active_layer = 0;
        self.reset_caches();
    }

    /// Rebuilds the per-layer caches and queues every chunk (after layers are added or removed).
    pub fn reset_caches(&mut self) {
        self.meshes.reset(&surfaces(&self.scene.layers, self.world.as_ref()), false);
    }

    /// A number that changes whenever the scene does through the editor (edits, undo, redo, a
    /// new scene, [`Editor::touch`]): compare it with the value seen at the last save to know
    /// whether there is unsaved work.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Records a change made to the scene directly (a renamed, hidden or added layer), so that
    /// [`Editor::revision`] moves.
    pub fn touch(&mut self) {
        self.revision += 1;
    }

    /// Sets the history's memory budget (bytes), keeping what fits.
    pub fn set_history_budget(&mut self, bytes: usize) {
        let old = std::mem::replace(&mut self.history, History::with_budget(bytes));
        drop(old);
    }

    /// The history.
    pub fn history(&self) -> &History {
        &self.history
    }

    /// Whether the tools may edit layer `layer` through its transform: it exists, is not
    /// locked, and its transform is valid.
    pub(crate) fn check_editable(&self, layer: usize) -> Result<(), EditorError> {
        let l = self.surface(layer).ok_or(EditorError::NoLayer(layer))?;
        if l.locked() {
            return Err(EditorError::Locked(layer));
        }
        if !l.transform().is_valid() {
            return Err(EditorError::BadLayerTransform(layer));
        }
        Ok(())
    }

    /// Queues an edit's chunks for meshing and pushes its undo record as one history step
    /// (the history keeps the record; `edit` is left with an empty one).
    fn commit_edit(&mut self, layer: usize, edit: &mut EditReport) {
        self.queue(layer, &edit.changed, edit.reach);
        self.revision += 1;
        self.history.push(HistoryEntry { layer, records: vec![std::mem::take(&mut edit.undo)], ..Default::default() });
    }

    /// Refuses a mask tool on a streamed surface, and a stamp loaded from a file that this
    /// editor does not hold or that a room would not have.
    pub(crate) fn check_tool_target(&self, layer: usize, tool: &crate::tool::ToolSettings) -> Result<(), EditorError> {
        if tool.kind.is_mask() && self.surface(layer).is_some_and(|s| s.streamed()) {
            return Err(EditorError::MaskOnWorld);
        }
        if tool.kind == crate::ToolKind::Stamp
            && let crate::StampSource::Loaded(_) = tool.stamp.source
        {
            if self.records_ops() {
                // (Operations name the image; the others in the room do not have it.)
                return Err(EditorError::NotShared("a stamp loaded from a file"));
            }
            if self.stamps.name(tool.stamp.source).is_none() {
                return Err(EditorError::UnknownStamp);
            }
        }
        Ok(())
    }

    /// Inverts, clears, grows or shrinks the mask of layer `layer` as one undo step, its
    /// chunks queued for meshing (their shading changes). Refused on a world and while the
    /// editor records operations for a room.
    pub fn mask_all(&mut self, layer: usize, action: MaskAction) -> Result<(), EditorError> {
        if self.records_ops() {
            return Err(EditorError::NotShared(action.name()));
        }
        if self.surface(layer).is_some_and(|s| s.streamed()) {
            return Err(EditorError::MaskOnWorld);
        }
        self.end_stroke();
        let l = self.scene.layers.get_mut(layer).ok_or(EditorError::NoLayer(layer))?;
        if l.locked {
            return Err(EditorError::Locked(layer));
        }
        let mut edit = match action {
            MaskAction::Invert => l.volume.invert_mask(),
            MaskAction::Clear => l.volume.clear_mask(),
            MaskAction::Grow => l.volume.grow_mask(true),
            MaskAction::Shrink => l.volume.grow_mask(false),
        };
        if edit.undo.is_empty() {
            return Ok(());
        }
        self.commit_edit(layer, &mut edit);
        Ok(())
    }

    /// Refuses a current material the palette does not have.
    pub(crate) fn check_material(&self) -> Result<(), EditorError> {
        let count = self.scene.materials.len();
        if self.tool.material as usize >= count {
            return Err(EditorError::UnknownMaterial { id: self.tool.material, count });
        }
        Ok(())
    }

    /// Applies `brush` (grid coordinates of the surface) to surface `layer` (a layer, or the
    /// world: [`Editor::active_surface`]) as one undo step, with its chunks queued for meshing:
    /// how imports, scripted edits and a world's craters change it. (Edits made straight on
    /// `scene.layers[i].volume` bypass the history, whose records would then restore stale
    /// chunks: call [`Editor::clear_history`] after any.)
    pub fn apply(
        &mut self,
        layer: usize,
        op: strata_volume::CsgOp,
        brush: &dyn strata_volume::brush::Brush,
    ) -> Result<EditReport, EditorError> {
        self.end_stroke();
        let settings = EditSettings { material: self.tool.material, ..self.settings.clone() };
        let l = self.surface_mut(layer).ok_or(EditorError::NoLayer(layer))?;
        if l.locked() {
            return Err(EditorError::Locked(layer));
        }
        let mut edit = l.edit(&brush.bounds(), &mut |v| Ok(v.apply(op, brush, &settings)?))?;
        self.commit_edit(layer, &mut edit);
        Ok(edit)
    }

    /// Moves, turns or scales layer `layer` to `transform` (checked as [`LayerTransform::new`]
    /// checks it) as an undo step. With `merge`, a change that continues the newest step (a
    /// transform change of the same layer, as while a value is dragged) joins it, so the whole
    /// drag is one step.
    pub fn set_layer_transform(
        &mut self,
        layer: usize,
        transform: crate::scene::LayerTransform,
        merge: bool,
    ) -> Result<(), EditorError> {
        let checked = crate::scene::LayerTransform::new(transform.translation, transform.rotation, transform.scale)?;
        self.end_stroke();
        let l = self.scene.layers.get_mut(layer).ok_or(EditorError::NoLayer(layer))?;
        let old = std::mem::replace(&mut l.transform, checked);
        if old != checked {
            if !(merge && self.history.last_is_transform_of(layer)) {
                self.history.push(HistoryEntry { layer, transform: Some(old), ..Default::default() });
            }
            self.revision += 1;
        }
        Ok(())
    }

    /// Forgets every undo and redo step (after the scene was changed outside the editor).
    pub fn clear_history(&mut self) {
        self.end_stroke();
        self.history.clear();
    }

    /// Undoes the newest step. Returns whether anything changed (`false` too when a world's
    /// chunk the step restores cannot be read: [`Editor::try_undo`] says why).
    pub fn undo(&mut self) -> bool {
        self.try_undo().unwrap_or(false)
    }

    /// Redoes the newest undone step. Returns whether anything changed (see [`Editor::undo`]).
    pub fn redo(&mut self) -> bool {
        self.try_redo().unwrap_or(false)
    }

    /// Undoes the newest step; an error (a world's chunk it restores cannot be read) changes
    /// nothing and keeps the step.
    pub fn try_undo(&mut self) -> Result<bool, EditorError> {
        self.history_step(false)
    }

    /// Redoes the newest undone step (see [`Editor::try_undo`]).
    pub fn try_redo(&mut self) -> Result<bool, EditorError> {
        self.history_step(true)
    }

    /// Undoes (or with `redo`, redoes) the newest step on the scene and the world.
    fn history_step(&mut self, redo: bool) -> Result<bool, EditorError> {
        self.end_stroke();
        let target = crate::history::StepTarget {
            layers: &mut self.scene.layers,
            active: &mut self.active_layer,
            references: &mut self.scene.references,
        };
        let world = self.world.as_mut();
        let changed = if redo { self.history.redo(target, world)? } else { self.history.undo(target, world)? };
        Ok(self.after_history(changed))
    }

    fn after_history(&mut self, restored: Option<crate::history::Restored>) -> bool {
        let Some(restored) = restored else { return false };
        self.revision += 1;
        match restored {
            // Only the restored chunks changed: remesh them and the chunks that read them.
            crate::history::Restored::Chunks(layer, keys) => self.queue(layer, &keys, None),
            crate::history::Restored::Layers => {
                self.reset_caches();
                self.structure += 1;
            }
            crate::history::Restored::References => {}
        }
        true
    }

    /// Replaces the layer list with `layers` and the active layer with `active` as one undo
    /// step: how layers are added, deleted, duplicated, reordered and merged. The other steps
    /// keep referring to the right layers: undoing this one restores the list they were made on.
    pub fn replace_layers(&mut self, layers: Vec<Layer>, active: usize) {
        self.end_stroke();
        let old = std::mem::replace(&mut self.scene.layers, layers);
        let old_active =
            std::mem::replace(&mut self.active_layer, active.min(self.scene.layers.len().saturating_sub(1)));
        self.history.push(HistoryEntry { layers: Some((old, old_active)), ..Default::default() });
        self.reset_caches();
        self.revision += 1;
        self.structure += 1;
    }

    /// Changes whenever the layer list is replaced or restored by undo or redo (a renderer's
    /// layers must then be uploaded anew).
    pub fn structure_revision(&self) -> u64 {
        self.structure
    }

    /// Queues the meshes an edit of `layer` that changed `changed` within `reach` (`None`:
    /// anywhere in them) affects.
    pub(crate) fn queue(&mut self, layer: usize, changed: &[ChunkKey], reach: Option<strata_volume::Reach>) {
        if let Some(l) = self.scene.layers.get(layer) {
            self.meshes.queue(layer, &l.volume, changed, reach);
        }
        // (A world's changes reach its meshes through its own list: see `Editor::remesh`.)
    }

    /// Remeshes queued chunks until `budget` is spent and shows what can be shown without a
    /// crack (see [`crate::view_meshes`]).
    pub(crate) fn remesh(&mut self, budget: Duration, report: &mut FrameReport) {
        let t0 = Instant::now();
        let world_surface = self.scene.layers.len();
        if let Some(world) = self.world.as_mut() {
            let (changed, alone) = (world.take_changed(), world.take_alone());
            let world = &*world;
            self.meshes.streamed_changes(world_surface, world.volume(), &changed, &alone, &|k| world.is_loaded(k));
        }
        let world = self.world.as_ref();
        let loaded = |k: ChunkKey| world.is_none_or(|w| w.is_loaded(k));
        let (shown, pending) = self.meshes.remesh(&surfaces(&self.scene.layers, world), &loaded, budget);
        report.remeshed.extend(shown);
        report.remesh_time = t0.elapsed();
        report.pending = pending;
    }

    /// Level of detail by camera distance: with a view, every list chunk of every layer is
    /// meshed at the coarsest level whose cell looks no larger than the view's pixel error from
    /// the eye (see [`LodView`]); chunks whose level changes are queued with their neighbours.
    /// `None` meshes everything at its stored level.
    pub fn set_view(&mut self, view: Option<LodView>) {
        self.meshes.set_view(&surfaces(&self.scene.layers, self.world.as_ref()), view);
    }

    /// The level-of-detail cap of a chunk of a layer (`None`: meshed at its stored level).
    pub fn lod_level(&self, layer: usize, key: ChunkKey) -> Option<Level> {
        self.meshes.lod_level(layer, key)
    }

    /// Remeshes everything queued, whatever it takes (before a screenshot or an export).
    pub fn finish_meshing(&mut self) -> Vec<(usize, ChunkKey)> {
        let mut report = FrameReport::default();
        self.remesh(Duration::MAX, &mut report);
        // A world's chunks are meshed on worker threads: wait for them.
        while self.world.is_some() && self.pending() > 0 {
            std::thread::sleep(Duration::from_millis(1));
            let mut more = FrameReport::default();
            self.remesh(Duration::MAX, &mut more);
            report.remeshed.extend(more.remeshed);
        }
        report.remeshed
    }

    /// Chunks waiting for a remesh, or remeshed and waiting for their neighbours to be shown
    /// (under dual contouring, the chunks edits changed since the last remesh).
    pub fn pending(&self) -> usize {
        // (A world's changes not yet taken will queue chunks too.)
        self.meshes.pending() + self.world.as_ref().map_or(0, World::changed_count)
    }

    /// Whether chunk `key` of layer `layer` waits for a remesh or to be shown (under dual
    /// contouring: whether an edit changed it since the last remesh).
    pub fn is_pending(&self, layer: usize, key: ChunkKey) -> bool {
        self.meshes.is_pending(layer, key)
    }

    /// The block mesh cache of a layer (marching cubes or tetrahedra; `None` while the viewport
    /// dual-contours).
    pub fn mesh_cache(&self, layer: usize) -> Option<&MeshCache> {
        self.meshes.mesh_cache(layer)
    }

    /// The viewport's mesher and per-chunk simplification.
    pub fn view_mesher(&self) -> MeshOptions {
        self.meshes.options()
    }

    /// Meshes the viewport with `options` from now on (every chunk is queued again). Per-chunk
    /// simplification keeps each chunk's border so neighbours still meet; it applies to the
    /// meshers that mesh chunk by chunk (marching cubes and tetrahedra), dual contouring refuses
    /// it. Tetrahedra mesh a layer whose chunks mix levels with marching cubes (see
    /// [`Editor::view_mesher_used`]); level of detail by distance applies to marching cubes only.
    pub fn set_view_mesher(&mut self, options: MeshOptions) -> Result<(), EditorError> {
        if let Some(e) = options.simplify {
            if !(e.is_finite() && e >= 0.0) {
                return Err(MesherError::Simplify(strata_mesh::simplify::SimplifyError::BadError(e)).into());
            }
            if options.mesher.block().is_none() {
                return Err(MesherError::ChunkSimplify(options.mesher).into());
            }
        }
        self.meshes.set_options(options, &surfaces(&self.scene.layers, self.world.as_ref()));
        Ok(())
    }

    /// The mesher a layer's viewport meshes are made with now: the one asked for, or marching
    /// cubes where tetrahedra were asked for and the layer's chunks mix levels.
    pub fn view_mesher_used(&self, layer: usize) -> Option<Mesher> {
        self.meshes.mesher_used(layer)
    }

    /// GPU meshing for the viewport: with `on`, the surfaces meshed by marching cubes without
    /// per-chunk simplification, or by dual contouring (scene layers without a mask; not a
    /// streamed world), are no longer meshed by the editor. Their changed chunks are listed in [`Editor::take_changes`]
    /// (all of them for a full list: [`Editor::caller_chunks`]) and the caller meshes each from
    /// [`Editor::view_block`] (`strata_viewport` does, on the GPU). Every chunk is queued again
    /// when this changes anything. Exports keep meshing on the CPU.
    pub fn set_gpu_meshing(&mut self, on: bool) {
        self.meshes.set_gpu(on, &surfaces(&self.scene.layers, self.world.as_ref()));
    }

    /// Whether GPU meshing is asked for ([`Editor::set_gpu_meshing`]).
    pub fn gpu_meshing(&self) -> bool {
        self.meshes.gpu()
    }

    /// Dual contouring in the viewport with its cell vertices solved by `solver` (GPU meshing:
    /// `strata_viewport::GpuMeshing::vertex_solver`), the quads joined here; `None` solves them
    /// on the CPU. Volumes that mix levels are solved on the CPU either way.
    pub fn set_vertex_solver(&mut self, solver: Option<crate::view_meshes::BoxedVertexSolver>) {
        self.meshes.set_solver(solver);
    }

    /// Whether a vertex solver is set ([`Editor::set_vertex_solver`]).
    pub fn has_vertex_solver(&self) -> bool {
        self.meshes.has_solver()
    }

    /// Whether surface `i`'s viewport chunks are meshed by the caller (GPU meshing).
    pub fn meshed_by_caller(&self, i: usize) -> bool {
        self.meshes.by_caller(i)
    }

    /// Whether caller-meshed surface `i` is meshed by dual contouring (its listed chunks are
    /// the ones whose quads change: [`strata_mesh::dual_mesh_keys`]; the caller adds
    /// the chunks before them, which lend their cells' vertices), else by marching cubes.
    pub fn caller_dual(&self, i: usize) -> bool {
        self.meshes.caller_dual(i)
    }

    /// Whether caller-meshed dual-contouring surface `i`'s quads are joined across levels
    /// (`strata_gpu_mesh::DualJoin::AcrossLevels`: its volume has had mixed levels since its
    /// meshes were made), else at one level.
    pub fn caller_dual_across_levels(&self, i: usize) -> bool {
        self.meshes.caller_dual_across_levels(i)
    }

    /// Every chunk of caller-meshed surface `i` that can hold surface (empty for the others).
    pub fn caller_chunks(&self, i: usize) -> Vec<ChunkKey> {
        match self.surface(i) {
            Some(s) => self.meshes.caller_chunks(i, s.volume()),
            None => Vec::new(),
        }
    }

    /// The voxel block the viewport's marching cubes meshes for chunk `key` of surface `i`
    /// (capped by level of detail, seams with finer neighbours patched), made in `out`; `false`
    /// where the chunk can hold no surface or there is no such surface.
    pub fn view_block(&self, i: usize, key: ChunkKey, out: &mut strata_volume::VoxelBlock) -> bool {
        match self.surface(i) {
            Some(s) => self.meshes.block(i, s.volume(), key, out),
            None => false,
        }
    }

    /// The viewport mesh of chunk `key` of a layer (chunk-local positions), by the viewport's
    /// mesher.
    pub fn chunk_mesh(&self, layer: usize, key: ChunkKey) -> Option<&Mesh> {
        self.meshes.mesh(layer, key)
    }

    /// Every viewport chunk mesh of a layer.
    pub fn chunk_meshes(&self, layer: usize) -> Vec<(ChunkKey, &Mesh)> {
        self.meshes.meshes(layer)
    }

    /// What a renderer must do to show the viewport's meshes as they are now, since the last
    /// call (see [`ChangeList`]): the first call, and the first after the layer list or the
    /// mesher changed, or after [`Editor::redraw_all`], is a full list.
    pub fn take_changes(&mut self) -> ChangeList {
        self.meshes.take_changes(&surfaces(&self.scene.layers, self.world.as_ref()), &self.scene.materials)
    }

    /// Makes the next [`Editor::take_changes`] a full list (the renderer showed something else
    /// meanwhile).
    pub fn redraw_all(&mut self) {
        self.meshes.redraw_all();
    }

    /// The box of a layer's viewport surface in its grid coordinates (from the mesh cache:
    /// chunks not meshed yet are not counted; under GPU meshing, whose meshes stay on the GPU,
    /// the box of the chunks that can hold surface), or `None` for a layer without surface.
    pub fn surface_bounds(&self, layer: usize) -> Option<(DVec3, DVec3)> {
        let mut b: Option<(DVec3, DVec3)> = None;
        if self.meshed_by_caller(layer) {
            // The mesh's vertices are the blocks' crossings, placed as the mesher places them.
            let mut block = strata_volume::VoxelBlock::default();
            for key in self.caller_chunks(layer) {
                if !self.view_block(layer, key, &mut block) {
                    continue;
                }
                let (o, sp, off) = (key.origin_grid().as_dvec3(), block.level().spacing() as f32, block.offset());
                for axis in strata_volume::Axis::ALL {
                    for c in block.crossings(axis) {
                        let q = o + glam::Vec3::from(strata_mesh::crossing_position(off, sp, axis, c)).as_dvec3();
                        b = Some(b.map_or((q, q), |(lo, hi)| (lo.min(q), hi.max(q))));
                    }
                }
            }
            return b;
        }
        for (key, mesh) in self.chunk_meshes(layer) {
            let o = key.origin_grid().as_dvec3();
            for p in &mesh.positions {
                let q = o + glam::Vec3::from(*p).as_dvec3();
                b = Some(b.map_or((q, q), |(lo, hi)| (lo.min(q), hi.max(q))));
            }
        }
        b
    }

    /// Triangles in all layers' caches.
    pub fn triangle_count(&self) -> usize {
        self.meshes.triangle_count()
    }

    /// A dual-contoured, welded mesh of a layer in world coordinates (sharp features; on request,
    /// not per frame).
    pub fn dual_contour_layer(&self, layer: usize) -> Result<Mesh, EditorError> {
        let l = self.scene.layers.get(layer).ok_or(EditorError::NoLayer(layer))?;
        let mut mesh = strata_mesh::mesh_volume_with(&l.volume, MeshOptions::new(Mesher::DualContouring))?;
        to_world(&mut mesh, &l.transform);
        Ok(mesh)
    }

    /// One mesh of every visible layer in world coordinates, for export, by `options` (each
    /// layer welded, and simplified when asked).
    pub fn export_mesh(&self, options: MeshOptions) -> Result<Mesh, EditorError> {
        self.export_mesh_reported(options).map(|(mesh, _)| mesh)
    }

    /// [`Editor::export_mesh`], also saying what `options.remove_islands` removed, summed over
    /// the layers. Islands are measured in each layer's own cells (cells³ of its grid, before
    /// the layer's transform), so one threshold means the same on layers of any scale.
    pub fn export_mesh_reported(&self, options: MeshOptions) -> Result<(Mesh, IslandReport), EditorError> {
        self.export_layers(|v| strata_mesh::mesh_volume_reported(v, options, None))
    }

    /// [`Editor::export_mesh_reported`] with shading normals for a file
    /// ([`strata_mesh::mesh_volume_shaded`]): creased at `crease_degrees` in each layer's grid
    /// (the layer transforms are similarities, so the creases are the same in the world),
    /// except for dual contouring and simplified meshes.
    pub fn export_mesh_shaded(
        &self,
        options: MeshOptions,
        crease_degrees: f32,
    ) -> Result<(Mesh, IslandReport), EditorError> {
        self.export_layers(|v| strata_mesh::mesh_volume_shaded(v, options, crease_degrees))
    }

    /// The visible layers meshed by `mesh` and moved into the world, one after the other.
    fn export_layers(
        &self,
        mesh: impl Fn(&strata_volume::Volume) -> Result<(Mesh, IslandReport), MesherError>,
    ) -> Result<(Mesh, IslandReport), EditorError> {
        let mut out = Mesh::default();
        let mut islands = IslandReport::default();
        for l in self.scene.layers.iter().filter(|l| l.visible) {
            let (mut m, removed) = mesh(&l.volume)?;
            islands = islands.then(removed);
            to_world(&mut m, &l.transform);
            if out.positions.is_empty() && out.indices.is_empty() {
                out = m;
                continue;
            }
            let (nv, ni) = (m.vertex_count(), m.indices.len());
            out.append_range(&m, 0..nv, 0..ni);
        }
        Ok((out, islands))
    }
}

/// The surfaces of an editor: `layers`, then `world` (see [`crate::target`]).
pub(crate) fn surfaces<'a>(layers: &'a [Layer], world: Option<&'a World>) -> Vec<&'a dyn EditTarget> {
    let mut out: Vec<&dyn EditTarget> = layers.iter().map(|l| l as &dyn EditTarget).collect();
    out.extend(world.map(|w| w as &dyn EditTarget));
    out
}

/// Surface `i` of `layers` and `world`, to edit.
pub(crate) fn surface_mut<'a>(
    layers: &'a mut [Layer],
    world: Option<&'a mut World>,
    i: usize,
) -> Option<&'a mut dyn EditTarget> {
    let n = layers.len();
    match layers.get_mut(i) {
        Some(l) => Some(l),
        None if i == n => world.map(|w| w as &mut dyn EditTarget),
        None => None,
    }
}

/// Moves a grid-space mesh into world space.
pub fn to_world(mesh: &mut Mesh, tr: &crate::scene::LayerTransform) {
    use rayon::prelude::*;
    // (Each vertex on its own: on every core, in runs long enough to be worth a hand-off.)
    mesh.positions
        .par_iter_mut()
        .with_min_len(1 << 14)
        .for_each(|p| *p = tr.to_world(glam::Vec3::from(*p).as_dvec3()).as_vec3().into());
    mesh.normals
        .par_iter_mut()
        .with_min_len(1 << 14)
        .for_each(|n| *n = (tr.rotation * glam::Vec3::from(*n).as_dvec3()).as_vec3().into());
}
