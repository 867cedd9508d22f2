//! The keyboard shortcuts: one table from key presses to commands, read in the order the keys
//! were pressed (see `StudioApp::shortcuts`).

use eframe::egui::{Key, Modifiers};
use strata_editor::ToolKind;
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
}

impl Command {
    /// Whether the command works while a text field has the keyboard (the ones with Ctrl: a
    /// field has no use for them).
    pub fn works_while_typing(self) -> bool {
        matches!(self, Command::Undo | Command::Redo | Command::Save | Command::SaveAs | Command::Open | Command::New)
    }
}

/// Every binding, the more specific first (Ctrl+Shift+Z before Ctrl+Z).
const KEYMAP: &[(Modifiers, Key, Command)] = {
    const C: Modifiers = Modifiers::COMMAND;
    const CS: Modifiers = Modifiers { shift: true, ..Modifiers::COMMAND };
    const N: Modifiers = Modifiers::NONE;
    &[
        (CS, Key::Z, Command::Redo),
        (C, Key::Y, Command::Redo),
        (C, Key::Z, Command::Undo),
        (CS, Key::S, Command::SaveAs),
        (C, Key::S, Command::Save),
        (C, Key::O, Command::Open),
        (C, Key::N, Command::New),
        (C, Key::Num1, Command::View(AxisView::Front, true)),
        (C, Key::Num3, Command::View(AxisView::Right, true)),
        (C, Key::Num7, Command::View(AxisView::Top, true)),
        (N, Key::F1, Command::Help),
        (N, Key::Escape, Command::CloseHelp),
        (N, Key::OpenBracket, Command::RadiusDown),
        (N, Key::CloseBracket, Command::RadiusUp),
        (N, Key::F, Command::ResizeBrush),
        (N, Key::W, Command::Wireframe),
        (N, Key::B, Command::NextShape),
        // Views, in the numpad's conventions (egui does not tell the numpad's digits from the
        // top row's, so both work): 1 front, 3 right, 7 top; 5 switches orthographic.
        (N, Key::Num1, Command::View(AxisView::Front, false)),
        (N, Key::Num3, Command::View(AxisView::Right, false)),
        (N, Key::Num7, Command::View(AxisView::Top, false)),
        (N, Key::Num5, Command::Orthographic),
        (N, Key::Home, Command::Frame),
        (N, Key::Period, Command::Frame),
        (N, Key::A, Command::Tool(ToolKind::Add)),
        (N, Key::E, Command::Tool(ToolKind::Erase)),
        (N, Key::S, Command::Tool(ToolKind::Smooth)),
        (N, Key::I, Command::Tool(ToolKind::Inflate)),
        (N, Key::T, Command::Tool(ToolKind::Flatten)),
        (N, Key::C, Command::Tool(ToolKind::Clay)),
        (N, Key::P, Command::Tool(ToolKind::Pinch)),
        (N, Key::G, Command::Tool(ToolKind::Grab)),
        (N, Key::D, Command::Tool(ToolKind::Detail)),
        (N, Key::V, Command::Tool(ToolKind::Paint)),
        (N, Key::L, Command::Line),
        (N, Key::X, Command::MirrorX),
        (N, Key::K, Command::Eyedropper),
    ]
};

/// The command of a key pressed with `mods` held: the first binding whose modifiers match
/// (Ctrl is Cmd on a Mac; Shift and Alt held beyond a binding's are ignored, as egui's
/// `consume_key` does, so Shift, held to smooth, does not stop the tool keys).
pub fn command_for(mods: Modifiers, key: Key) -> Option<Command> {
    KEYMAP.iter().find(|(m, k, _)| *k == key && mods.matches_logically(*m)).map(|&(_, _, c)| c)
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
        assert_eq!(command_for(Modifiers::NONE, Key::Q), None);
    }

    #[test]
    fn every_key_has_one_binding_per_modifier_set() {
        for (i, a) in KEYMAP.iter().enumerate() {
            for b in &KEYMAP[i + 1..] {
                assert!(!(a.0 == b.0 && a.1 == b.1), "{:?} {:?} is bound twice", a.0, a.1);
            }
        }
    }
}
