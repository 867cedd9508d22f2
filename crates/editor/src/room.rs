//! What a shared room holds and sends as its snapshot: a scene (a scene file's bytes), or a
//! streamed world — its recipe, its palette and every chunk that differs from what the recipe
//! generates at the base level (the rest is generated, the same everywhere).
//!
//! Chunks are generated at one level in a shared world ([`shared_world_settings`]): a world
//! that generates finer chunks near its viewer holds different lists for the same chunk on two
//! machines whose viewers differ, and the same operation would give different bytes.

use serde::{Deserialize, Serialize};
use strata_terrain::{Recipe, StoredChunk, World, WorldSettings};
use strata_volume::{ChunkKey, Volume};

use crate::{Editor, Material, Scene};

/// The first bytes of a world snapshot (a scene snapshot is a scene file).
pub const WORLD_MAGIC: [u8; 8] = *b"STRATAWR";

/// The world snapshot format's version.
const WORLD_VERSION: u32 = 1;

/// A shared world: its recipe, palette and the chunks that differ from the recipe's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorldContent {
    /// The recipe every chunk not listed is generated from.
    pub recipe: Recipe,
    /// The palette.
    pub materials: Vec<Material>,
    /// The chunks that differ from the recipe's, by key.
    pub chunks: Vec<(ChunkKey, StoredChunk)>,
}

/// What a room holds.
#[derive(Clone, Debug)]
pub enum RoomContent {
    /// A scene.
    Scene(Scene),
    /// A streamed world.
    World(WorldContent),
}

/// How a world in a shared room streams: every chunk at the base level (see the module docs),
/// the rest as `settings` says.
pub fn shared_world_settings(settings: WorldSettings) -> WorldSettings {
    WorldSettings { detail_distance: 0.0, coarse_distance: 0.0, ..settings }
}

/// Whether a world streams as a shared room needs (one level everywhere).
pub fn is_shareable(world: &World) -> bool {
    world.settings().detail_distance == 0.0 && world.settings().coarse_distance == 0.0
}

/// The snapshot of what `editor` holds: its scene's file, or its world's content.
pub fn encode(editor: &Editor) -> Result<Vec<u8>, String> {
    let Some(world) = editor.world() else {
        return crate::file::encode_shared(&editor.scene).map_err(|e| e.to_string());
    };
    if !is_shareable(world) {
        return Err(
            "a world that generates finer chunks near its viewer or coarser ones far away cannot be shared".into()
        );
    }
    let content = WorldContent {
        recipe: world.recipe().clone(),
        materials: editor.scene.materials.clone(),
        chunks: world.edited_chunks().map_err(|e| e.to_string())?,
    };
    let mut out = WORLD_MAGIC.to_vec();
    out.extend_from_slice(&WORLD_VERSION.to_le_bytes());
    out.extend(postcard::to_allocvec(&content).map_err(|e| e.to_string())?);
    Ok(out)
}

/// Reads a snapshot [`encode`] wrote. A world's chunks must keep the volume's invariants and
/// use materials of its palette (a snapshot may come from anyone who can reach a server).
pub fn decode(bytes: &[u8]) -> Result<RoomContent, String> {
    let Some(rest) = bytes.strip_prefix(&WORLD_MAGIC) else {
        let loaded = crate::file::decode_shared(bytes).map_err(|e| e.to_string())?;
        return Ok(RoomContent::Scene(loaded.scene));
    };
    if rest.len() < 4 {
        return Err("a world snapshot without its version".into());
    }
    let (version, body) = rest.split_at(4);
    let version = u32::from_le_bytes(version.try_into().expect("four bytes"));
    if version != WORLD_VERSION {
        return Err(format!("a world snapshot of version {version} (this build reads {WORLD_VERSION})"));
    }
    let content: WorldContent = postcard::from_bytes(body).map_err(|e| format!("a damaged world snapshot: {e}"))?;
    let mut scene = Scene { layers: Vec::new(), materials: content.materials.clone(), ..Scene::default() };
    let report = crate::file::validate_scene(&mut scene);
    if !report.is_clean() || scene.materials.is_empty() {
        return Err(format!("a world snapshot's palette is invalid: {report}"));
    }
    check_world(&content)?;
    Ok(RoomContent::World(content))
}

/// The checks a world snapshot passes: a valid recipe, each chunk once, the volume's
/// invariants, materials of its palette.
fn check_world(content: &WorldContent) -> Result<(), String> {
    strata_terrain::TerrainField::new(&content.recipe).map_err(|e| format!("a world snapshot's recipe: {e}"))?;
    let mut volume = Volume::new();
    let mut seen = std::collections::HashSet::new();
    for (key, stored) in &content.chunks {
        if !seen.insert(*key) {
            return Err(format!("a world snapshot lists chunk {:?} twice", key.0));
        }
        volume.put_chunk(*key, stored.chunk.clone(), stored.materials.clone());
    }
    // (The chunks' neighbours are the recipe's, elsewhere: each is checked within the list.)
    volume
        .check_invariants_within(&|k| seen.contains(&k))
        .map_err(|e| format!("a world snapshot's chunks are inconsistent: {e}"))?;
    if volume.max_material().is_some_and(|m| m as usize >= content.materials.len()) {
        return Err("a world snapshot's chunks use materials past its palette".into());
    }
    Ok(())
}

/// An editor on `content`: a scene's, or one on an in-memory world of the content's recipe
/// with its chunks (streaming as `settings` says, at one level).
pub fn editor_for(content: RoomContent, settings: WorldSettings) -> Result<Editor, String> {
    match content {
        RoomContent::Scene(scene) => Ok(Editor::new(scene)),
        RoomContent::World(w) => {
            let mut world = World::in_memory(&w.recipe, shared_world_settings(settings)).map_err(|e| e.to_string())?;
            world.replace_edited(w.chunks).map_err(|e| e.to_string())?;
            Ok(Editor::on_world(world, w.materials))
        }
    }
}

impl Editor {
    /// Makes this editor hold `content` in place, when it holds the same kind (a scene, or a
    /// world of the same recipe streaming at one level): the scene is replaced, or the world's
    /// edited chunks become the content's. Returns `false` (nothing changed) for another kind.
    pub fn load_room(&mut self, content: &RoomContent) -> Result<bool, String> {
        match (content, self.world.as_mut()) {
            (RoomContent::Scene(scene), None) => {
                // (Reference images are each person's own: a room's scene never holds them,
                // and loading it keeps this editor's.)
                let references = std::mem::take(&mut self.scene.references);
                self.set_scene(Scene { references, ..scene.clone() });
                Ok(true)
            }
            (RoomContent::World(w), Some(world)) if *world.recipe() == w.recipe && is_shareable(world) => {
                world.replace_edited(w.chunks.clone()).map_err(|e| e.to_string())?;
                self.scene.materials = w.materials.clone();
                self.redraw_all();
                Ok(true)
            }
            _ => Ok(false),
        }
    }
}
