//! The keyboard: one binding table ([`BINDINGS`]) from which the shortcuts are run
//! ([`command_for`], read in the order the keys were pressed by `StudioApp::shortcuts`), the F1
//! help is listed ([`help_rows`]), and the menus, the tool palette and the tooltips name their
//! keys ([`keys_of`]). The README's controls table is checked against it by a test
//! (`tests/keymap.rs`). Mouse controls and terrain mode's held fly keys, which are not
//! commands, are listed beside it ([`POINTER_AND_HELD`]).

use eframe::egui::{Key, Modifiers};
use strata_editor::{MaskAction, ToolKind};
use strata_render::AxisView;

/// What a key press asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// Undo the last step.
    Undo,
    /// Redo the last undone step.
    Redo,
    /// Save to the scene's file (asking for one the first time).
    Save,
    /// Save to a new file.
    SaveAs,
    /// Open a scene.
    Open,
    /// Start a new scene.
    New,
    /// Show or hide the keyboard help.
    Help,
    /// Hide the keyboard help.
    CloseHelp,
    /// Shrink the brush.
    RadiusDown,
    /// Grow the brush.
    RadiusUp,
    /// Size the brush by dragging (Blender's F).
    ResizeBrush,
    /// Wireframe on or off.
    Wireframe,
    /// The next brush shape (in terrain mode: launch a bomb).
    NextShape,
    /// An axis view (true: the opposite one).
    View(AxisView, bool),
    /// Perspective or orthographic.
    Orthographic,
    /// Frame the visible layers.
    Frame,
    /// Pick a tool.
    Tool(ToolKind),
    /// Arm the line tool.
    Line,
    /// Mirror across the layer's x plane.
    MirrorX,
    /// Arm the eyedropper.
    Eyedropper,
    /// Invert, clear, grow or shrink the active layer's mask.
    Mask(MaskAction),
    /// The next stroke stabiliser setting (off, weak, strong).
    Stabiliser,
    /// The stamp tool's next image (the built-in ones, then those loaded).
    NextStamp,
    /// Spray stamps along the stroke, or drag out one.
    StampStroke,
    /// Load a PNG as a stamp image.
    LoadStamp,
    /// Pen pressure on or off.
    Pressure,
    /// The transform gizmo for the active layer on or off.
    LayerGizmo,
    /// Load a picture as a reference image.
    LoadReference,
    /// Show or hide the reference images.
    ShowReferences,
}

impl Command {
    /// Whether the command works while a text field has the keyboard (the ones with Ctrl: a
    /// field has no use for them).
    pub fn works_while_typing(self) -> bool {
        matches!(self, Command::Undo | Command::Redo | Command::Save | Command::SaveAs | Command::Open | Command::New)
    }
}

/// One command, its keys (the first is the one menus show) and what it does, in the scene and
/// in terrain mode (`None`: the key does nothing there).
#[derive(Clone, Copy, Debug)]
pub struct Binding {
    /// What the keys ask for.
    pub command: Command,
    /// Key chords, any of which runs it.
    pub keys: &'static [(Modifiers, Key)],
    /// What it does, for the help.
    pub does: &'static str,
    /// What it does in terrain mode, where that differs or is all it does there.
    pub terrain: Option<&'static str>,
}

const C: Modifiers = Modifiers::COMMAND;
const CS: Modifiers = Modifiers { shift: true, ..Modifiers::COMMAND };
const N: Modifiers = Modifiers::NONE;
const A: Modifiers = Modifiers::ALT;

const fn bind(command: Command, keys: &'static [(Modifiers, Key)], does: &'static str) -> Binding {
    Binding { command, keys, does, terrain: None }
}

const fn both(
    command: Command,
    keys: &'static [(Modifiers, Key)],
    does: &'static str,
    terrain: &'static str,
) -> Binding {
    Binding { command, keys, does, terrain: Some(terrain) }
}

/// What the fly keys do in terrain mode, where the viewport reads them as held keys.
const FLY: &str = "fly (held: W S forward, back; A D left, right; E Q up, down)";

/// Every key binding, in the order the help lists them.
pub const BINDINGS: &[Binding] = &[
    bind(Command::Tool(ToolKind::Clay), &[(N, Key::C)], "clay: adds material that meets the surface in a soft fillet"),
    both(Command::Tool(ToolKind::Add), &[(N, Key::A)], "add with the brush shape (exact CSG)", FLY),
    both(Command::Tool(ToolKind::Erase), &[(N, Key::E)], "erase with the brush shape (exact CSG)", FLY),
    both(Command::Tool(ToolKind::Smooth), &[(N, Key::S)], "smooth", FLY),
    bind(Command::Tool(ToolKind::Inflate), &[(N, Key::I)], "inflate"),
    bind(Command::Tool(ToolKind::Flatten), &[(N, Key::T)], "flatten"),
    bind(Command::Tool(ToolKind::Pinch), &[(N, Key::P)], "pinch: pull the surface towards the stroke"),
    bind(Command::Tool(ToolKind::Grab), &[(N, Key::G)], "grab: drag the surface with the pointer"),
    both(Command::Tool(ToolKind::Detail), &[(N, Key::D)], "detail: raise the chunks' resolution under the brush", FLY),
    bind(Command::Tool(ToolKind::Paint), &[(N, Key::V)], "paint the current material"),
    bind(
        Command::Tool(ToolKind::Stamp),
        &[(N, Key::H)],
        "stamp: raise a grey-scale picture on the surface (Ctrl or Alt: carve it in)",
    ),
    bind(Command::NextStamp, &[(A, Key::H)], "the stamp's next picture (built in, then loaded)"),
    bind(
        Command::StampStroke,
        &[(N, Key::J)],
        "stamp: spray along the stroke, or drag out one stamp (press at its middle, drag to size and turn it)",
    ),
    bind(Command::LoadStamp, &[(CS, Key::O)], "load a PNG as a stamp picture (or drop it on the window)"),
    bind(Command::Pressure, &[(A, Key::P)], "pen pressure on or off (its curves in the tool panel)"),
    bind(
        Command::LayerGizmo,
        &[(C, Key::T)],
        "transform gizmo for the active layer: drag an arrow to move, a ring knob to turn, the square to scale (Ctrl snaps)",
    ),
    bind(
        Command::LoadReference,
        &[(CS, Key::I)],
        "load a PNG or JPEG as a reference image, square to the view the camera is in (or drop a JPEG on the window)",
    ),
    bind(Command::ShowReferences, &[(A, Key::R)], "show or hide the reference images"),
    bind(Command::Eyedropper, &[(N, Key::K)], "eyedropper: click the model to take its material"),
    bind(
        Command::Tool(ToolKind::Mask),
        &[(N, Key::M)],
        "mask: protect what the brush covers from every tool (inverse: unmask; Shift: smooth the mask)",
    ),
    bind(
        Command::Stabiliser,
        &[(N, Key::R)],
        "stroke stabiliser: off, weak, strong (the brush trails the pointer on a rope)",
    ),
    bind(Command::Mask(MaskAction::Invert), &[(C, Key::I)], "invert the mask"),
    bind(Command::Mask(MaskAction::Clear), &[(A, Key::M)], "clear the mask"),
    bind(Command::Mask(MaskAction::Grow), &[(C, Key::G)], "grow the mask by a cell"),
    bind(Command::Mask(MaskAction::Shrink), &[(CS, Key::G)], "shrink the mask by a cell"),
    both(
        Command::NextShape,
        &[(N, Key::B)],
        "next brush shape (sphere, box, capsule, cylinder)",
        "launch a bomb along the view: it blasts a crater",
    ),
    bind(Command::RadiusDown, &[(N, Key::OpenBracket)], "brush radius down"),
    bind(Command::RadiusUp, &[(N, Key::CloseBracket)], "brush radius up"),
    bind(
        Command::ResizeBrush,
        &[(N, Key::F)],
        "size the brush by moving the pointer (click or Enter: keep, Escape or right click: cancel)",
    ),
    bind(Command::Line, &[(N, Key::L)], "line tool: click two points"),
    bind(Command::MirrorX, &[(N, Key::X)], "mirror across the layer's x plane"),
    both(Command::Wireframe, &[(N, Key::W)], "wireframe", FLY),
    // Views, in the numpad's conventions (egui does not tell the numpad's digits from the top
    // row's, so both work): 1 front, 3 right, 7 top; with Ctrl the opposite; 5 orthographic.
    bind(Command::View(AxisView::Front, false), &[(N, Key::Num1)], "front view (numpad or top row)"),
    bind(Command::View(AxisView::Right, false), &[(N, Key::Num3)], "right view"),
    bind(Command::View(AxisView::Top, false), &[(N, Key::Num7)], "top view"),
    bind(Command::View(AxisView::Front, true), &[(C, Key::Num1)], "back view"),
    bind(Command::View(AxisView::Right, true), &[(C, Key::Num3)], "left view"),
    bind(Command::View(AxisView::Top, true), &[(C, Key::Num7)], "bottom view"),
    bind(Command::Orthographic, &[(N, Key::Num5)], "perspective / orthographic"),
    bind(Command::Frame, &[(N, Key::Home), (N, Key::Period)], "frame the model"),
    bind(Command::Undo, &[(C, Key::Z)], "undo a whole stroke (in terrain mode: a stroke or a crater)"),
    bind(Command::Redo, &[(CS, Key::Z), (C, Key::Y)], "redo"),
    both(Command::Save, &[(C, Key::S)], "save (asks for a path the first time)", "write the world's edits now"),
    bind(Command::SaveAs, &[(CS, Key::S)], "save as"),
    bind(Command::Open, &[(C, Key::O)], "open a scene"),
    bind(Command::New, &[(C, Key::N)], "new scene"),
    bind(
        Command::CloseHelp,
        &[(N, Key::Escape)],
        "close the help, a prompt or a question; cancel a long job or a waiting insert",
    ),
    bind(Command::Help, &[(N, Key::F1)], "this help"),
];

/// Controls that are not key commands: the pointer, held modifiers, dropped files and terrain
/// mode's fly keys (read as held keys by the viewport). Listed by the help after the bindings.
pub const POINTER_AND_HELD: &[(&str, &str)] = &[
    ("Left drag", "sculpt with the current tool"),
    ("Right drag / middle drag / wheel", "orbit / pan / zoom towards the pointer"),
    ("Ctrl or Alt held (or Alt + right drag)", "the inverse tool"),
    ("Shift held", "smooth with any tool"),
    ("Drop a file on the window", "a scene opens, a mesh is imported as a layer"),
    ("Terrain mode: W A S D, Q E (Shift faster)", "fly forward, left, back, right, down, up"),
    ("Terrain mode: right drag", "look around"),
    ("Terrain mode: left drag", "sculpt the world with the current tool (it starts as a dig: erase; Ctrl raises)"),
];

/// How a control of the panels and dialogs is reached besides pointing at it: the rest of the
/// binding table. A control whose label ends with its keys in brackets (`Clay (C)`, `Load…
/// (Ctrl+Shift+I)`) is reached by them; an item of a list the scene or the user makes (a layer,
/// a material, a preset, a reference image, a stamp picture) by Tab and Space, as egui focuses
/// any control; every other control has a row of [`CONTROLS`]. A UI test walks every panel and
/// dialog and checks that each control has a tooltip and a way in here, and that each row's
/// key is bound and its menu entry exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reach {
    /// A key command.
    Key(Command),
    /// A menu entry: its menus and its label, `Brush > Mirror > Y` (a segment ending in `*`
    /// names the entry whose label starts with the rest).
    Menu(&'static str),
    /// A value (a slider, a number, a text field, a choice among values): Tab reaches it, the
    /// arrow keys or typing set it.
    Value,
    /// A dialog's answer: Enter or Escape, or Tab to it.
    Answer,
}

/// One panel or dialog control: its label (a label ending in `*` names every control whose
/// label starts with the rest) and how it is reached.
#[derive(Clone, Copy, Debug)]
pub struct Control {
    /// The control's label as it shows (for screen readers too).
    pub label: &'static str,
    /// How it is reached.
    pub reach: Reach,
}

const fn control(label: &'static str, reach: Reach) -> Control {
    Control { label, reach }
}

use Reach::{Answer, Menu, Value};

/// The panels' and dialogs' controls that do not name their keys (see [`Reach`]).
pub const CONTROLS: &[Control] = &[
    // The tool panel.
    control("Off", Reach::Key(Command::Stabiliser)),
    control("Weak", Reach::Key(Command::Stabiliser)),
    control("Strong", Reach::Key(Command::Stabiliser)),
    control("Sphere", Reach::Key(Command::NextShape)),
    control("Box", Reach::Key(Command::NextShape)),
    control("Capsule", Reach::Key(Command::NextShape)),
    control("Cylinder", Reach::Key(Command::NextShape)),
    control("Y", Menu("Brush > Mirror > Y")),
    control("Z", Menu("Brush > Mirror > Z")),
    control("off", Menu("Brush > Lock stroke > Off")),
    control("along X", Menu("Brush > Lock stroke > Along X")),
    control("along Y", Menu("Brush > Lock stroke > Along Y")),
    control("along Z", Menu("Brush > Lock stroke > Along Z")),
    control("Radius on screen", Menu("Brush > Radius on screen")),
    control("Follow the surface", Menu("Brush > Follow the surface")),
    control("Orient brush to surface", Menu("Brush > Orient brush to surface")),
    control("Paper's smoothing (Eq. 1)", Menu("Brush > Paper's smoothing (Eq. 1)")),
    control("32³ cells", Menu("Brush > Detail raises to > 32³ cells")),
    control("64³ cells", Menu("Brush > Detail raises to > 64³ cells")),
    control("A named shape; drag the curve's points for your own", Menu("Brush > Falloff")),
    control("Invert", Reach::Key(Command::Mask(MaskAction::Invert))),
    control("Clear", Reach::Key(Command::Mask(MaskAction::Clear))),
    control("Grow", Reach::Key(Command::Mask(MaskAction::Grow))),
    control("Shrink", Reach::Key(Command::Mask(MaskAction::Shrink))),
    control("Load PNG…", Reach::Key(Command::LoadStamp)),
    control("Spray", Reach::Key(Command::StampStroke)),
    control("Drag", Reach::Key(Command::StampStroke)),
    control("The picture the stamp raises*", Reach::Key(Command::NextStamp)),
    control("Follow stroke", Menu("Brush > Stamp follows the stroke")),
    control("Save preset…", Menu("Edit > Brush presets > Save brush as preset…")),
    control("New material", Menu("Brush > New material")),
    control("tool strength", Value),
    control("fillet (× radius)", Value),
    control("radius [ ] F", Value),
    control("radius (points) [ ] F", Value),
    control("dab spacing", Value),
    control("cells", Value),
    control("turn", Value),
    control("pressure to size", Value),
    control("pressure to strength", Value),
    control("material name", Value),
    control("texture", Value),
    control("texture scale", Value),
    control("roughness", Value),
    // A waiting insert.
    control("size", Value),
    control("turn y °", Value),
    control("x °", Value),
    control("z °", Value),
    control("Add insert", Menu("Edit > Insert mesh > Add insert")),
    control("Subtract insert", Menu("Edit > Insert mesh > Subtract insert")),
    control("Intersect insert", Menu("Edit > Insert mesh > Intersect insert")),
    control("Cancel insert", Reach::Key(Command::CloseHelp)),
    // The layers panel.
    control("visible", Menu("Layer > Layer visible")),
    control("locked", Menu("Layer > Layer locked")),
    control("Name", Value),
    control("x", Value),
    control("y", Value),
    control("z", Value),
    control("turn °", Value),
    control("scale", Value),
    control("16³", Menu("Layer > New layers' resolution > 16³ cells")),
    control("32³", Menu("Layer > New layers' resolution > 32³ cells")),
    control("64³", Menu("Layer > New layers' resolution > 64³ cells")),
    control("Add", Menu("Layer > Add layer")),
    control("Duplicate", Menu("Layer > Duplicate layer")),
    control("Delete", Menu("Layer > Delete layer")),
    control("Up", Menu("Layer > Move layer up")),
    control("Down", Menu("Layer > Move layer down")),
    control("Merge down", Menu("Layer > Merge down")),
    // The reference images panel (the selected picture's controls).
    control("shown", Menu("Layer > Reference image* > Shown")),
    control("locked in place", Menu("Layer > Reference image* > Locked in place")),
    control("Front", Menu("Layer > Reference image* > Lay square to the Front view")),
    control("Side", Menu("Layer > Reference image* > Lay square to the Side view")),
    control("Top", Menu("Layer > Reference image* > Lay square to the Top view")),
    control("Look at it", Menu("Layer > Reference image* > Look at it")),
    control("Delete image", Menu("Layer > Reference image* > Delete reference image")),
    control("opacity", Value),
    control("width", Value),
    // Dialogs and prompts.
    control("Close window", Reach::Key(Command::CloseHelp)),
    control("Path:", Value),
    control("Listen on", Value),
    control("Server", Value),
    control("cells along the longest side", Value),
    control("Address", Value),
    control("Room", Value),
    control("Token", Value),
    control("Your name", Value),
    control("OK", Answer),
    control("Cancel", Answer),
    control("Host", Answer),
    control("Join", Answer),
    control("Import", Answer),
    control("Save", Answer),
    control("Don't save", Answer),
    control("Recover", Answer),
    control("Discard", Answer),
    control("Dismiss", Answer),
];

/// Whether `label` is the one `row_label` names (exactly, or by its start for a row ending in
/// `*`).
pub fn label_matches(row_label: &str, label: &str) -> bool {
    match row_label.strip_suffix('*') {
        Some(start) => label.starts_with(start),
        None => label == row_label,
    }
}

/// The rows of [`CONTROLS`] for a control labelled `label`.
pub fn controls_for(label: &str) -> impl Iterator<Item = &'static Control> + '_ {
    CONTROLS.iter().filter(move |c| label_matches(c.label, label))
}

/// The chords a label names at its end in brackets (`Redo (Ctrl+Shift+Z or Ctrl+Y)`), if each
/// of them is bound; `None` for a label without them.
pub fn keys_in_label(label: &str) -> Option<Vec<Command>> {
    let inner = label.strip_suffix(')')?.rsplit_once('(')?.1;
    let chords: Vec<&str> = inner.split(" or ").collect();
    let mut commands = Vec::new();
    for chord in chords {
        let b = BINDINGS.iter().find(|b| b.keys.iter().any(|&k| chord_text(k) == chord))?;
        commands.push(b.command);
    }
    Some(commands)
}

/// The number of modifiers a chord asks for: among the bindings a press matches, the one that
/// asks for the most wins (Ctrl+Shift+Z is redo, though Ctrl+Z also matches it).
fn specificity(m: Modifiers) -> u8 {
    u8::from(m.shift) + u8::from(m.alt) + u8::from(m.command || m.ctrl || m.mac_cmd)
}

/// The command of a key pressed with `mods` held: of the bindings whose modifiers match (Ctrl
/// is Cmd on a Mac; Shift and Alt held beyond a binding's are ignored, as egui's `consume_key`
/// does, so Shift, held to smooth, does not stop the tool keys), the most specific.
pub fn command_for(mods: Modifiers, key: Key) -> Option<Command> {
    BINDINGS
        .iter()
        .flat_map(|b| b.keys.iter().map(move |&(m, k)| (m, k, b.command)))
        .filter(|&(m, k, _)| k == key && mods.matches_logically(m))
        .max_by_key(|&(m, _, _)| specificity(m))
        .map(|(_, _, c)| c)
}

/// A chord as the help and the menus write it: `Ctrl+Shift+Z`, `[`, `F1`.
pub fn chord_text((mods, key): (Modifiers, Key)) -> String {
    let mut s = String::new();
    if mods.command || mods.ctrl || mods.mac_cmd {
        s.push_str("Ctrl+");
    }
    if mods.alt {
        s.push_str("Alt+");
    }
    if mods.shift {
        s.push_str("Shift+");
    }
    s.push_str(key.symbol_or_name());
    s
}

/// The binding of `command`.
pub fn binding(command: Command) -> Option<&'static Binding> {
    BINDINGS.iter().find(|b| b.command == command)
}

/// The keys of `command` as the help writes them (`Ctrl+Shift+Z or Ctrl+Y`), or an empty string
/// for a command without a key.
pub fn keys_of(command: Command) -> String {
    binding(command).map_or(String::new(), |b| b.keys.iter().map(|&c| chord_text(c)).collect::<Vec<_>>().join(" or "))
}

/// `label (keys)` for a menu entry or a palette button, or `label` for a command without a key.
pub fn labelled(label: &str, command: Command) -> String {
    match keys_of(command) {
        k if k.is_empty() => label.to_string(),
        k => format!("{label} ({k})"),
    }
}

/// The rows of the F1 help: every binding (its keys, what it does), then terrain mode's
/// meanings of its keys, then the pointer and held controls.
pub fn help_rows() -> Vec<(String, String)> {
    let mut rows: Vec<(String, String)> = BINDINGS.iter().map(|b| (keys_of(b.command), b.does.to_string())).collect();
    rows.extend(
        BINDINGS.iter().filter_map(|b| b.terrain.map(|t| (format!("Terrain mode: {}", keys_of(b.command)), t.into()))),
    );
    rows.extend(POINTER_AND_HELD.iter().map(|&(k, d)| (k.to_string(), d.to_string())));
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_more_specific_binding_wins_and_plain_letters_need_no_ctrl() {
        let cs = Modifiers { shift: true, ..Modifiers::COMMAND };
        assert_eq!(command_for(cs, Key::Z), Some(Command::Redo));
        assert_eq!(command_for(Modifiers::COMMAND, Key::Z), Some(Command::Undo));
        assert_eq!(command_for(Modifiers::COMMAND, Key::S), Some(Command::Save));
        assert_eq!(command_for(cs, Key::S), Some(Command::SaveAs));
        assert_eq!(command_for(Modifiers::NONE, Key::S), Some(Command::Tool(ToolKind::Smooth)));
        assert_eq!(command_for(Modifiers::SHIFT, Key::V), Some(Command::Tool(ToolKind::Paint)));
        assert_eq!(command_for(Modifiers::COMMAND, Key::V), None, "Ctrl+V is not paint");
        assert_eq!(command_for(Modifiers::COMMAND, Key::Num1), Some(Command::View(AxisView::Front, true)));
        assert_eq!(command_for(Modifiers::NONE, Key::Num1), Some(Command::View(AxisView::Front, false)));
        assert_eq!(command_for(Modifiers::NONE, Key::Q), None);
    }

    #[test]
    fn every_chord_has_one_binding_and_every_command_one_row() {
        let chords: Vec<_> = BINDINGS.iter().flat_map(|b| b.keys.iter().copied()).collect();
        for (i, a) in chords.iter().enumerate() {
            assert!(!chords[i + 1..].contains(a), "{} is bound twice", chord_text(*a));
        }
        for (i, a) in BINDINGS.iter().enumerate() {
            assert!(!a.keys.is_empty(), "{:?} has no key", a.command);
            assert!(BINDINGS[i + 1..].iter().all(|b| b.command != a.command), "{:?} has two rows", a.command);
        }
    }

    #[test]
    fn every_chord_runs_its_own_command() {
        for b in BINDINGS {
            for &(m, k) in b.keys {
                assert_eq!(command_for(m, k), Some(b.command), "{}", chord_text((m, k)));
            }
        }
    }

    #[test]
    fn labels_name_their_keys_and_rows_their_labels() {
        assert_eq!(keys_in_label("Clay (C)"), Some(vec![Command::Tool(ToolKind::Clay)]));
        assert_eq!(keys_in_label("Redo (Ctrl+Shift+Z or Ctrl+Y)"), Some(vec![Command::Redo, Command::Redo]));
        assert_eq!(keys_in_label("fillet (× radius)"), None, "not a key");
        assert_eq!(keys_in_label("Sphere"), None);
        assert!(label_matches("The picture the stamp raises*", "The picture the stamp raises, white highest"));
        assert!(!label_matches("Off", "Offset"));
        assert_eq!(controls_for("Delete").count(), 1, "each control its own row");
        for c in CONTROLS {
            if let Reach::Key(command) = c.reach {
                assert!(binding(command).is_some(), "{}: {command:?} has no key", c.label);
            }
        }
    }

    #[test]
    fn chords_are_written_as_people_type_them() {
        assert_eq!(keys_of(Command::Redo), "Ctrl+Shift+Z or Ctrl+Y");
        assert_eq!(keys_of(Command::RadiusDown), "[");
        assert_eq!(keys_of(Command::Frame), "Home or .");
        assert_eq!(labelled("Save as…", Command::SaveAs), "Save as… (Ctrl+Shift+S)");
        assert_eq!(keys_of(Command::View(AxisView::Top, true)), "Ctrl+7");
    }
}
