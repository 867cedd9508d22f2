//! The device-neutral tool pose: what any input device reports once per frame.

use glam::{DQuat, DVec3};

/// Buttons held during a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Buttons {
    /// The primary button (mouse left, pen tip, VR trigger): apply the tool while held.
    pub primary: bool,
    /// The secondary button: apply the opposite tool (erase while adding, add while erasing).
    pub secondary: bool,
}

/// Where the tool is and what it does in one frame, in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolPose {
    /// The tool tip.
    pub position: DVec3,
    /// The tool's orientation (oriented brushes follow it).
    pub orientation: DQuat,
    /// Pressure or trigger travel in `[0, 1]`; scales the brush radius by the tool's strength.
    pub pressure: f64,
    /// Buttons held.
    pub buttons: Buttons,
    /// How the held buttons act (the keyboard's modifiers, a controller's grip).
    pub modifiers: Modifiers,
}

/// How a pose's buttons act, said by the device layer once (Ctrl or Alt held: inverted; Shift
/// held: smooth) instead of being folded into the buttons or the tool.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Modifiers {
    /// The inverse tool (erase for add, carve for clay, deflate for inflate, …); the secondary
    /// button alone means the same.
    pub inverted: bool,
    /// Smooth, whatever the current tool, for as long as it is held.
    pub smooth: bool,
}

impl Default for ToolPose {
    /// At the origin, no rotation, full pressure, no button, no modifier.
    fn default() -> Self {
        ToolPose::at(DVec3::ZERO, false)
    }
}

impl ToolPose {
    /// A pose at `position` with no rotation, full pressure and the primary button `down`.
    pub fn at(position: DVec3, down: bool) -> Self {
        ToolPose {
            position,
            orientation: DQuat::IDENTITY,
            pressure: 1.0,
            buttons: Buttons { primary: down, secondary: false },
            modifiers: Modifiers::default(),
        }
    }

    /// Whether the inverse tool acts: the modifier, or the secondary button alone.
    pub fn inverted(&self) -> bool {
        self.modifiers.inverted || (self.buttons.secondary && !self.buttons.primary)
    }

    /// Whether the pose is usable: finite position and orientation, pressure a number.
    pub fn is_valid(&self) -> bool {
        self.position.is_finite() && self.orientation.is_finite() && self.pressure.is_finite()
    }
}
