//! # strata-terrain
//!
//! Procedural terrain for Strata, written straight into segment lists:
//!
//! - [`Recipe`]: a small serialisable description (seed, height fBm with ridges, domain warp,
//!   3D overhang noise, caves, material layers by depth, height and slope);
//! - [`TerrainField`]: the recipe's density, answering [`strata_volume::NodeField`] so that
//!   [`strata_volume::generate_chunk`] builds a chunk's lists with no dense field kept, deciding
//!   chunks that interval bounds prove uniform without visiting their nodes;
//! - [`WorldStore`]: a world on disk, the recipe plus the chunks that differ from what the recipe
//!   generates, in an embedded transactional database (`redb`);
//! - [`World`]: a streamed, editable world: chunks generated or paged in around viewers by worker
//!   threads in order of distance, integrated under a per-frame budget, evicted beyond the view
//!   distance, edited (each edit's undo record handed to the caller, restored across eviction),
//!   flushed periodically and on eviction.
//!
//! Generation is a pure function of the recipe and the chunk key: the same recipe gives the same
//! bytes on any number of threads and in any order.
#![warn(missing_docs)]

mod bound;
mod field;
/// Perlin noise, the `noise` crate's values bit for bit, computed faster.
pub mod perlin;
mod recipe;
mod region;
mod store;
mod world;

pub use field::TerrainField;
pub use recipe::{Caves, Heights, MaterialLayers, Overhangs, Recipe, RecipeError, Warp};
pub use region::{Clipped, generate_region};
pub use store::{StoreError, StoredChunk, WORLD_FORMAT, WorldStore, decode_record, encode_record};
pub use world::{UpdateReport, World, WorldError, WorldSettings};
