//! # strata-volume
//!
//! Solids stored as sorted lists of surface crossings on every grid line, along x, y and z (the
//! layered-depth-normal-image structure of Chen et al., *IEEE Access* 2021), in sparse chunks of
//! 16³ cells keyed by `i32` triples.
//!
//! What is guaranteed, after any sequence of edits:
//! - a node is inside iff the brushes' inside predicates, combined by the edits' CSG, hold there;
//!   the x, y and z lists agree on every node's state ([`Volume::check_invariants`]);
//! - every crossing lies strictly inside the one cell edge whose two nodes differ, so a line has
//!   at most one crossing per cell; features thinner than a cell that contain no node vanish;
//! - crossing positions are chunk-local fixed point (65,536 steps per chunk side), so the same
//!   edit anywhere in the world stores the same chunk-local data;
//! - [`Volume::restore`] with an edit's [`UndoRecord`] gives back the exact previous volume.
//!
//! What is not: positions are quantised to 1/2048 of a base cell and normals to about 0.7°.
//!
//! ```
//! use glam::DVec3;
//! use strata_volume::{Volume, brush::Sphere};
//!
//! let mut volume = Volume::new();
//! let edit = volume.add(&Sphere::new(DVec3::new(8.0, 8.0, 8.0), 5.0)?)?;
//! assert!(volume.is_inside(DVec3::new(8.0, 8.0, 8.0)));
//! volume.check_invariants()?;
//! volume.restore(edit.undo);
//! assert!(volume.is_empty());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]

pub mod axis;
mod bits;
mod block;
pub mod brush;
mod chunk;
pub mod coords;
mod edit;
pub mod generate;
mod invariants;
pub mod islands;
mod level;
pub mod mask;
pub mod material;
mod memory;
pub mod normal;
mod query;
mod repair;
mod sample;
pub mod tools;
mod volume;

pub use axis::Axis;
pub use block::{EdgeCrossing, SeamPoint, SeamSplit, VoxelBlock};
pub use chunk::{Chunk, ChunkLists, LineRef};
pub use coords::{ChunkBox, ChunkKey, Level};
pub use edit::{CsgOp, EditControl, EditError, EditReport, EditSettings, Reach, UndoRecord};
pub use generate::{GeneratedChunk, NodeField, generate_chunk, solid_chunk_materials};
pub use invariants::InvariantViolation;
pub use mask::{ChunkMask, Mask, MaskUndo, MaskWeight, PROTECTED};
pub use material::{ChunkMaterials, MATERIAL_IDS, MaterialId};
pub use memory::{MemoryReport, hash_table_bytes};
pub use query::{CrossingStats, RayHit, clip_to_box};
pub use repair::RepairReport;
pub use sample::brush_contains_node;
pub use volume::{ChunkMap, KeyHasher, Volume};
