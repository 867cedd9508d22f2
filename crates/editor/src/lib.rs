//! # strata-editor
//!
//! The editor core, independent of any window, GPU or input device: a [`Scene`] of layers
//! (each a segment volume with a name, transform, visibility and lock), tools driven by a stream
//! of device-neutral [`ToolPose`]s (a mouse, a pen or a VR controller produce the same poses),
//! strokes that sweep a brush along the pose path with even spacing, undo/redo with a memory
//! budget, a per-layer mesh cache remeshed within a per-frame time budget, picking, and
//! versioned binary scene files (see [`file`]). The same tools, strokes and history edit a
//! streamed terrain world ([`Editor::on_world`], through the seam in [`target`]).
#![warn(missing_docs)]

mod dab_job;
mod editor;
pub mod file;
mod history;
pub mod import;
pub mod insert;
mod lod;
pub mod op;
mod pick;
mod pose;
pub mod presets;
pub mod reference;
pub mod room;
mod scene;
pub mod stabiliser;
pub mod stamps;
mod stroke;
pub mod target;
mod tool;
mod view_meshes;

pub use dab_job::DabJob;
pub use editor::{Editor, EditorError, FrameReport, MaskAction, to_world};
pub use history::{History, HistoryEntry, Restored, StepTarget};
pub use insert::{InsertError, InsertMesh, Placement, Primitive};
pub use lod::{LodView, lod_levels};
pub use op::{DabRecord, EditOp, OpUndo, RecordedOp};
pub use pick::{PICK_CHUNK_STEPS, Pick};
pub use pose::{Buttons, Modifiers, ToolPose};
pub use presets::{Preset, PresetError};
pub use reference::{Picture, PictureError, ReferenceError, ReferenceImage, ReferencePlane};
pub use scene::{Layer, LayerTransform, Material, Scene, Texture, TransformError, View, world_bounds};
pub use stabiliser::Stabiliser;
pub use stamps::{StampLibrary, StampSettings, StampSource, StampStroke};
pub use target::EditTarget;
pub use tool::{BrushShape, Pressure, ToolKind, ToolSettings, orientation_for_normal};
pub use view_meshes::{BoxedVertexSolver, ChangeList};
