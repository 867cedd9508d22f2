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

/// Why a layer transform was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TransformError {
    /// A translation with a NaN or infinite coordinate.
    #[error("the layer translation {0} is not finite")]
    Translation(DVec3),
    /// A rotation that is NaN, infinite or too close to zero length to normalise.
    #[error("the layer rotation {0} is not a finite, non-zero quaternion")]
    Rotation(DQuat),
    /// A scale that is not finite, or not positive, or so small or large that grid coordinates
    /// lose their meaning.
    #[error("the layer scale {0} must be finite and within [{min:e}, {max:e}]", min = LayerTransform::MIN_SCALE, max = LayerTransform::MAX_SCALE)]
    Scale(f64),
}

impl LayerTransform {
    /// The smallest world units per cell accepted (a nanometre cell in metre units).
    pub const MIN_SCALE: f64 = 1e-9;
    /// The largest world units per cell accepted.
    pub const MAX_SCALE: f64 = 1e9;

    /// A transform, checked: a finite translation, a finite non-zero rotation (normalised
    /// here), a finite scale within [`Self::MIN_SCALE`, `Self::MAX_SCALE`].
    pub fn new(translation: DVec3, rotation: DQuat, scale: f64) -> Result<Self, TransformError> {
        if !translation.is_finite() {
            return Err(TransformError::Translation(translation));
        }
        let l = rotation.length();
        if !(rotation.is_finite() && l > 1e-9) {
            return Err(TransformError::Rotation(rotation));
        }
        if !(scale.is_finite() && (Self::MIN_SCALE..=Self::MAX_SCALE).contains(&scale)) {
            return Err(TransformError::Scale(scale));
        }
        Ok(LayerTransform { translation, rotation: rotation / l, scale })
    }

    /// The nearest valid transform: a non-finite translation becomes 0, a rotation that cannot
    /// be normalised the identity (others are normalised), a scale out of range the nearest
    /// bound (1 if it is NaN).
    pub fn repaired(&self) -> Self {
        let translation = if self.translation.is_finite() { self.translation } else { DVec3::ZERO };
        let l = self.rotation.length();
        let rotation = if self.rotation.is_finite() && l > 1e-9 { self.rotation / l } else { DQuat::IDENTITY };
        let scale = if self.scale.is_nan() { 1.0 } else { self.scale.clamp(Self::MIN_SCALE, Self::MAX_SCALE) };
        LayerTransform { translation, rotation, scale }
    }

    /// Whether the transform is invertible and finite (what [`LayerTransform::new`] accepts).
    pub fn is_valid(&self) -> bool {
        self.translation.is_finite()
            && self.rotation.is_finite()
            && (self.rotation.length() - 1.0).abs() < 1e-6
            && self.scale.is_finite()
            && (Self::MIN_SCALE..=Self::MAX_SCALE).contains(&self.scale)
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

/// The surface pattern a material is textured with: procedural textures made by the renderer
/// at start (no image files, no licence question), projected triplanar.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Texture {
    /// No pattern: the colour alone.
    #[default]
    Plain,
    /// Fine grain with soft tool marks.
    Clay,
    /// Cracked, layered stone.
    Rock,
    /// Blades and patches.
    Grass,
    /// Fine speckle with ripples.
    Sand,
    /// Bright, soft drifts.
    Snow,
}

impl Texture {
    /// Every texture, in palette order (the renderer's texture layers follow it).
    pub const ALL: [Texture; 6] =
        [Texture::Plain, Texture::Clay, Texture::Rock, Texture::Grass, Texture::Sand, Texture::Snow];

    /// Its name in the UI.
    pub fn name(self) -> &'static str {
        match self {
            Texture::Plain => "Plain",
            Texture::Clay => "Clay",
            Texture::Rock => "Rock",
            Texture::Grass => "Grass",
            Texture::Sand => "Sand",
            Texture::Snow => "Snow",
        }
    }

    /// Its layer in the renderer's texture array.
    pub fn layer(self) -> u32 {
        Texture::ALL.iter().position(|&t| t == self).unwrap_or(0) as u32
    }
}

/// A material of the scene's palette; volume nodes refer to it by its index (a
/// [`strata_volume::MaterialId`], so at most 256 materials).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Shown in the UI.
    pub name: String,
    /// Linear RGB in `[0, 1]`.
    pub color: [f32; 3],
    /// Surface pattern.
    pub texture: Texture,
    /// World units per texture repeat (finite, positive).
    pub scale: f32,
    /// Perceptual roughness in `[0, 1]`.
    pub roughness: f32,
}

impl Material {
    /// A material of `color` with `texture`, a 16-unit repeat and roughness 0.7.
    pub fn new(name: impl Into<String>, color: [f32; 3], texture: Texture) -> Self {
        Material { name: name.into(), color, texture, scale: 16.0, roughness: 0.7 }
    }

    /// Whether every field is in range (finite colour in `[0, 1]`, positive scale, roughness in
    /// `[0, 1]`).
    pub fn is_valid(&self) -> bool {
        self.color.iter().all(|c| (0.0..=1.0).contains(c))
            && self.scale.is_finite()
            && self.scale > 0.0
            && (0.0..=1.0).contains(&self.roughness)
    }

    /// The built-in palette of a new scene: clay, rock, grass, sand, snow and plain colours.
    pub fn builtin() -> Vec<Material> {
        vec![
            Material::new("Clay", [0.50, 0.36, 0.26], Texture::Clay),
            Material { roughness: 0.9, scale: 24.0, ..Material::new("Rock", [0.32, 0.30, 0.28], Texture::Rock) },
            Material { roughness: 0.85, ..Material::new("Grass", [0.18, 0.36, 0.09], Texture::Grass) },
            Material { roughness: 0.8, ..Material::new("Sand", [0.76, 0.64, 0.40], Texture::Sand) },
            Material { roughness: 0.5, ..Material::new("Snow", [0.90, 0.92, 0.95], Texture::Snow) },
            Material { roughness: 0.4, ..Material::new("Red", [0.70, 0.08, 0.06], Texture::Plain) },
            Material { roughness: 0.4, ..Material::new("Blue", [0.06, 0.18, 0.65], Texture::Plain) },
            Material { roughness: 0.6, ..Material::new("White", [0.85, 0.85, 0.85], Texture::Plain) },
        ]
    }
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
    /// The solid, with the material of every solid node (indices into [`Scene::materials`]).
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

impl View {
    /// A view of the stored chunks of `layers` (world bounds of their chunk boxes), at the
    /// default angles; the default view when there is nothing to frame. Always finite.
    pub fn framing<'a>(layers: impl IntoIterator<Item = &'a Layer>) -> View {
        let d = View::default();
        match world_bounds(layers) {
            Some((lo, hi)) if lo.is_finite() && hi.is_finite() => {
                let size = (hi - lo).length();
                let distance = (size * 1.2).max(1e-6);
                if distance.is_finite() { View { target: (lo + hi) / 2.0, distance, ..d } } else { d }
            }
            _ => d,
        }
    }
}

/// The world box around the stored chunks of `layers` (their chunk boxes' corners placed by
/// their transforms; layers with an invalid transform left out), if they have any.
pub fn world_bounds<'a>(layers: impl IntoIterator<Item = &'a Layer>) -> Option<(DVec3, DVec3)> {
    let mut bounds: Option<(DVec3, DVec3)> = None;
    for l in layers {
        if !l.transform.is_valid() {
            continue;
        }
        let Some((lo, hi)) = l.volume.chunk_bounds_grid() else { continue };
        for k in 0..8 {
            let c = DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let w = l.transform.to_world(c);
            bounds = Some(match bounds {
                None => (w, w),
                Some((a, b)) => (a.min(w), b.max(w)),
            });
        }
    }
    bounds
}

/// Everything a scene file holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// Layers, drawn in order.
    pub layers: Vec<Layer>,
    /// The palette the volumes' node materials index (at least one, at most 256).
    pub materials: Vec<Material>,
    /// The saved camera.
    pub view: View,
    /// Pictures placed in the world to sculpt against (scene files store them beside the
    /// layers; serde leaves them out: see [`crate::file`]).
    #[serde(skip)]
    pub references: Vec<crate::reference::ReferenceImage>,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            layers: vec![Layer::new("Layer 1")],
            materials: Material::builtin(),
            view: View::default(),
            references: Vec::new(),
        }
    }
}

impl Scene {
    /// Crossings stored over all layers.
    pub fn crossings(&self) -> usize {
        self.layers.iter().map(|l| l.volume.memory().crossings).sum()
    }

    /// The palette as mesh exports take it.
    pub fn export_palette(&self) -> Vec<strata_mesh::export::ExportMaterial> {
        self.materials
            .iter()
            .map(|m| strata_mesh::export::ExportMaterial {
                name: m.name.clone(),
                color: m.color,
                roughness: m.roughness,
            })
            .collect()
    }

    /// Bytes held by all layers' volumes.
    pub fn volume_bytes(&self) -> usize {
        self.layers.iter().map(|l| l.volume.memory().total()).sum()
    }
}
