//! Scenes and layers.

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};
use strata_volume::Volume;

/// Where a layer's grid sits in the world: `world = translation + rotation · (scale · grid)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayerTransform {
    /// World position of grid point 0.
    pub translation: DVec3,
    /// Rotation of the grid axes.
    pub rotation: DQuat,
    /// World units per cell (positive).
    pub scale: f64,
}

impl Default for LayerTransform {
    fn default() -> Self {
        LayerTransform { translation: DVec3::ZERO, rotation: DQuat::IDENTITY, scale: 1.0 }
    }
}

impl LayerTransform {
    /// Whether the transform is invertible and finite.
    pub fn is_valid(&self) -> bool {
        self.translation.is_finite()
            && self.rotation.is_finite()
            && (self.rotation.length() - 1.0).abs() < 1e-6
            && self.scale.is_finite()
            && self.scale > 0.0
    }

    /// World point of a grid point.
    pub fn to_world(&self, grid: DVec3) -> DVec3 {
        self.translation + self.rotation * (grid * self.scale)
    }

    /// Grid point of a world point.
    pub fn to_grid(&self, world: DVec3) -> DVec3 {
        self.rotation.inverse() * (world - self.translation) / self.scale
    }

    /// Grid direction of a world direction (not normalised).
    pub fn dir_to_grid(&self, world: DVec3) -> DVec3 {
        self.rotation.inverse() * world / self.scale
    }
}

/// A material: a name and a base colour (linear RGB).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Shown in the UI.
    pub name: String,
    /// Linear RGB in `[0, 1]`.
    pub color: [f32; 3],
}

/// One layer: a volume and how it is shown.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Layer {
    /// Shown in the layers panel.
    pub name: String,
    /// Grid to world.
    pub transform: LayerTransform,
    /// Drawn or hidden (hidden layers are not picked either).
    pub visible: bool,
    /// Locked layers refuse edits.
    pub locked: bool,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// The solid.
    pub volume: Volume,
}

impl Layer {
    /// An empty, visible, unlocked layer with the identity transform.
    pub fn new(name: impl Into<String>) -> Self {
        Layer {
            name: name.into(),
            transform: LayerTransform::default(),
            visible: true,
            locked: false,
            material: 0,
            volume: Volume::new(),
        }
    }
}

/// The camera the scene was saved with.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct View {
    /// Orbit centre.
    pub target: DVec3,
    /// Distance from the target.
    pub distance: f64,
    /// Rotation about the vertical axis (radians).
    pub yaw: f64,
    /// Elevation (radians).
    pub pitch: f64,
}

impl Default for View {
    fn default() -> Self {
        View { target: DVec3::new(32.0, 16.0, 32.0), distance: 110.0, yaw: 0.7, pitch: 0.45 }
    }
}

/// Everything a scene file holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// Layers, drawn in order.
    pub layers: Vec<Layer>,
    /// Materials layers refer to.
    pub materials: Vec<Material>,
    /// The saved camera.
    pub view: View,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            layers: vec![Layer::new("Layer 1")],
            materials: vec![Material { name: "Clay".into(), color: [0.50, 0.36, 0.26] }],
            view: View::default(),
        }
    }
}

impl Scene {
    /// Crossings stored over all layers.
    pub fn crossings(&self) -> usize {
        self.layers.iter().map(|l| l.volume.memory().crossings).sum()
    }

    /// Bytes held by all layers' volumes.
    pub fn volume_bytes(&self) -> usize {
        self.layers.iter().map(|l| l.volume.memory().total()).sum()
    }
}
