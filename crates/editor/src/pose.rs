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
}

impl ToolPose {
    /// A pose at `position` with no rotation, full pressure and the primary button `down`.
    pub fn at(position: DVec3, down: bool) -> Self {
        ToolPose {
            position,
            orientation: DQuat::IDENTITY,
            pressure: 1.0,
            buttons: Buttons { primary: down, secondary: false },
        }
    }

    /// Whether the pose is usable: finite position and orientation, pressure a number.
    pub fn is_valid(&self) -> bool {
        self.position.is_finite() && self.orientation.is_finite() && self.pressure.is_finite()
    }
}
