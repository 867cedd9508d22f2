//! # strata-studio
//!
//! The desktop editor: an eframe/egui window around the editor core (`strata-editor`) with the
//! wgpu renderer (`strata-render`) drawing the 3D viewport. `main.rs` is a thin shell: the state
//! and its actions ([`Studio`]) are plain Rust, testable without a window, and the headless
//! `--screenshot` mode ([`screenshot`]) renders with the renderer's offscreen path, opening no
//! window at all.
#![warn(missing_docs)]

mod app;
mod headless;
pub mod keymap;
pub mod recent;
pub mod recovery;
mod studio;
pub mod terrain;

pub use app::{DialogRequest, DialogService, Dialogs, GizmoHandle, StudioApp, run_window};
pub use headless::{screenshot, terrain_screenshot};
pub use studio::{Action, DEFAULT_CELL, ImportJob, Islands, PendingImport, Studio, default_scene};
