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
mod keymap;
pub mod recent;
pub mod recovery;
mod studio;
pub mod terrain;

pub use app::{DialogRequest, DialogService, Dialogs, StudioApp, run_window};
pub use headless::{screenshot, terrain_screenshot};
pub use studio::{Action, DEFAULT_CELL, ImportJob, Islands, PendingImport, Studio, default_scene};

/// Every keyboard and mouse binding, as the help overlay (F1) lists them.
pub const SHORTCUTS: &[(&str, &str)] = &[
    ("Left drag", "sculpt with the current tool"),
    ("Right drag / middle drag / wheel", "orbit / pan / zoom towards the pointer"),
    ("Ctrl or Alt held (or Alt + right drag)", "the inverse tool"),
    ("Shift held", "smooth with any tool"),
    ("C  A  E", "clay, add, erase"),
    ("S  I  T", "smooth, inflate, flatten"),
    ("P  G  D", "pinch, grab, detail (raise the chunks' resolution under the brush)"),
    ("V  K", "paint the current material, eyedropper (click the model to take its material)"),
    ("B", "next brush shape (sphere, box, capsule, cylinder)"),
    ("[  ]", "brush radius down, up"),
    ("F", "size the brush by moving the pointer (click or Enter: keep, Escape or right click: cancel)"),
    ("L", "line tool: click two points"),
    ("X", "mirror across the layer's x plane"),
    ("W", "wireframe"),
    ("1  3  7 (numpad or top row)", "front, right, top view; with Ctrl: back, left, bottom"),
    ("5", "perspective / orthographic"),
    ("Home  or  .", "frame the model"),
    ("Ctrl+Z  Ctrl+Shift+Z  Ctrl+Y", "undo, redo"),
    ("Ctrl+S  Ctrl+Shift+S", "save, save as"),
    ("Ctrl+O  Ctrl+N", "open, new"),
    ("Drop a file on the window", "a scene opens, a mesh is imported as a layer"),
    ("Escape", "close a prompt or question; cancel a long job"),
    ("F1", "this help"),
    ("Terrain mode: W A S D, Q E (Shift faster)", "fly forward, left, back, right, down, up"),
    ("Terrain mode: right drag", "look around"),
    ("Terrain mode: left click / Shift + left click", "dig / raise the ground (hold to repeat)"),
    ("Terrain mode: B", "launch a bomb along the view: it blasts a crater"),
    ("Terrain mode: [  ]  Ctrl+Z  Ctrl+Y", "dig radius down, up; undo, redo"),
];
