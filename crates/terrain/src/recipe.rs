//! A terrain recipe: the few numbers that describe a whole endless world.
//!
//! Lengths are grid units (base cells). The density the recipe describes, negative inside:
//!
//! ```text
//! H(x, z)  = base + amplitude · mix(fbm₂, ridged fbm₂, ridged)(warp(x, z) / wavelength)
//! s(p)     = y − H(x, z) − overhangs.amplitude · fbm₃(p / overhangs.wavelength)
//! cave(p)  = caves.strength · (fbm₃'(p / caves.wavelength) − caves.threshold) − fade(y)
//! f(p)     = max(s(p), cave(p))          (solid where f ≤ 0: under the surface, not in a cave)
//! ```
//!
//! where every fBm is normalised into `[-1, 1]` (the sum of its octaves' amplitudes divides it)
//! and `fade(y) = caves.strength · max(0, caves.floor − y) / caves.fade` keeps caves above a
//! floor. Those ranges are what lets a chunk be decided from interval bounds alone.

use serde::{Deserialize, Serialize};
use strata_volume::MaterialId;
use thiserror::Error;

/// A recipe that cannot be generated.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RecipeError {
    /// A number is NaN, infinite or out of its range.
    #[error("recipe field `{field}` is {value}: {why}")]
    Bad {
        /// Which field.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        why: &'static str,
    },
    /// The recipe file is not valid JSON of a recipe.
    #[error("not a terrain recipe: {0}")]
    Parse(String),
}

/// Height field: fractal noise over the ground plane.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Heights {
    /// Mean surface height.
    pub base: f64,
    /// Largest rise or fall from `base`.
    pub amplitude: f64,
    /// Wavelength of the first octave.
    pub wavelength: f64,
    /// Octaves (1–12).
    pub octaves: u32,
    /// Frequency factor between octaves.
    pub lacunarity: f64,
    /// Amplitude factor between octaves.
    pub gain: f64,
    /// Blend towards ridged noise (`1 − 2|n|`), 0–1: 0 rolling hills, 1 sharp ridges.
    pub ridged: f64,
}

impl Default for Heights {
    fn default() -> Self {
        Heights { base: 0.0, amplitude: 48.0, wavelength: 256.0, octaves: 5, lacunarity: 2.0, gain: 0.5, ridged: 0.35 }
    }
}

/// Domain warp of the height field's coordinates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Warp {
    /// Largest displacement (0: no warp).
    pub amplitude: f64,
    /// Wavelength of the warp noise.
    pub wavelength: f64,
}

impl Default for Warp {
    fn default() -> Self {
        Warp { amplitude: 24.0, wavelength: 160.0 }
    }
}

/// 3D noise added to the surface: overhangs and arches.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Overhangs {
    /// Largest displacement of the surface (0: a pure height field).
    pub amplitude: f64,
    /// Wavelength of the first octave.
    pub wavelength: f64,
    /// Octaves (1–12).
    pub octaves: u32,
}

impl Default for Overhangs {
    fn default() -> Self {
        Overhangs { amplitude: 10.0, wavelength: 40.0, octaves: 2 }
    }
}

/// Caves: where a 3D noise rises above a threshold, above a floor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Caves {
    /// Strength of the carving field (grid units per unit of noise; 0: no caves).
    pub strength: f64,
    /// Noise level above which there is a cave (−1–1; higher: fewer caves).
    pub threshold: f64,
    /// Wavelength of the first octave.
    pub wavelength: f64,
    /// Octaves (1–12).
    pub octaves: u32,
    /// Height below which caves fade out.
    pub floor: f64,
    /// Distance over which they fade (positive).
    pub fade: f64,
}

impl Default for Caves {
    fn default() -> Self {
        Caves { strength: 40.0, threshold: 0.3, wavelength: 48.0, octaves: 2, floor: -96.0, fade: 16.0 }
    }
}

/// Which material each solid node gets, by depth under the surface, height and slope (ids of
/// the scene palette: the built-in one has rock 1, grass 2, sand 3, snow 4, clay 0).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MaterialLayers {
    /// Deep ground.
    pub rock: MaterialId,
    /// Topsoil on gentle slopes.
    pub grass: MaterialId,
    /// Topsoil below `sand_below`.
    pub sand: MaterialId,
    /// Topsoil above `snow_above`.
    pub snow: MaterialId,
    /// Between topsoil and rock.
    pub soil: MaterialId,
    /// Depth of the topsoil.
    pub topsoil: f64,
    /// Depth below which everything is rock.
    pub soil_depth: f64,
    /// Surface heights below which the topsoil is sand.
    pub sand_below: f64,
    /// Surface heights above which the topsoil is snow.
    pub snow_above: f64,
    /// Slopes (rise over run of the height field) above which the surface is rock.
    pub steep: f64,
}

impl Default for MaterialLayers {
    fn default() -> Self {
        MaterialLayers {
            rock: 1,
            grass: 2,
            sand: 3,
            snow: 4,
            soil: 0,
            topsoil: 2.0,
            soil_depth: 8.0,
            sand_below: -28.0,
            snow_above: 34.0,
            steep: 1.2,
        }
    }
}

/// Everything a world's generated terrain depends on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Recipe {
    /// Seed of every noise.
    pub seed: u32,
    /// Height field.
    pub heights: Heights,
    /// Domain warp.
    pub warp: Warp,
    /// Overhangs and arches.
    pub overhangs: Overhangs,
    /// Caves.
    pub caves: Caves,
    /// Material layers.
    pub materials: MaterialLayers,
}

impl Default for Recipe {
    fn default() -> Self {
        Recipe {
            seed: 1,
            heights: Heights::default(),
            warp: Warp::default(),
            overhangs: Overhangs::default(),
            caves: Caves::default(),
            materials: MaterialLayers::default(),
        }
    }
}

/// Largest length a recipe may name (grid units): beyond it fBm coordinates lose their
/// fractional part in `f64` long before a world is that large.
const MAX_LENGTH: f64 = 1e9;

impl Recipe {
    /// The default recipe with another seed.
    pub fn with_seed(seed: u32) -> Self {
        Recipe { seed, ..Recipe::default() }
    }

    /// Checks every number; the error names the first bad one.
    pub fn validate(&self) -> Result<(), RecipeError> {
        fn bad(field: &'static str, value: f64, why: &'static str) -> Result<(), RecipeError> {
            Err(RecipeError::Bad { field, value, why })
        }
        let finite = |field, v: f64| {
            if v.is_finite() && v.abs() <= MAX_LENGTH {
                Ok(())
            } else {
                bad(field, v, "must be finite and at most 1e9 in size")
            }
        };
        let positive = |field, v: f64| {
            if v.is_finite() && v > 0.0 && v <= MAX_LENGTH {
                Ok(())
            } else {
                bad(field, v, "must be positive and at most 1e9")
            }
        };
        let non_negative = |field, v: f64| {
            if v.is_finite() && (0.0..=MAX_LENGTH).contains(&v) {
                Ok(())
            } else {
                bad(field, v, "must be between 0 and 1e9")
            }
        };
        let octaves =
            |field, o: u32| if (1..=12).contains(&o) { Ok(()) } else { bad(field, o as f64, "must be 1 to 12") };
        let h = &self.heights;
        finite("heights.base", h.base)?;
        non_negative("heights.amplitude", h.amplitude)?;
        positive("heights.wavelength", h.wavelength)?;
        octaves("heights.octaves", h.octaves)?;
        if !(h.lacunarity.is_finite() && (1.0..=8.0).contains(&h.lacunarity)) {
            return bad("heights.lacunarity", h.lacunarity, "must be 1 to 8");
        }
        if !(h.gain.is_finite() && h.gain > 0.0 && h.gain <= 1.0) {
            return bad("heights.gain", h.gain, "must be in (0, 1]");
        }
        if !(h.ridged.is_finite() && (0.0..=1.0).contains(&h.ridged)) {
            return bad("heights.ridged", h.ridged, "must be 0 to 1");
        }
        non_negative("warp.amplitude", self.warp.amplitude)?;
        positive("warp.wavelength", self.warp.wavelength)?;
        non_negative("overhangs.amplitude", self.overhangs.amplitude)?;
        positive("overhangs.wavelength", self.overhangs.wavelength)?;
        octaves("overhangs.octaves", self.overhangs.octaves)?;
        let c = &self.caves;
        non_negative("caves.strength", c.strength)?;
        if !(c.threshold.is_finite() && (-1.0..=1.0).contains(&c.threshold)) {
            return bad("caves.threshold", c.threshold, "must be -1 to 1");
        }
        positive("caves.wavelength", c.wavelength)?;
        octaves("caves.octaves", c.octaves)?;
        finite("caves.floor", c.floor)?;
        positive("caves.fade", c.fade)?;
        let m = &self.materials;
        non_negative("materials.topsoil", m.topsoil)?;
        non_negative("materials.soil_depth", m.soil_depth)?;
        finite("materials.sand_below", m.sand_below)?;
        finite("materials.snow_above", m.snow_above)?;
        non_negative("materials.steep", m.steep)?;
        Ok(())
    }

    /// Reads a recipe from JSON (missing fields take their defaults) and validates it.
    pub fn from_json(text: &str) -> Result<Self, RecipeError> {
        let r: Recipe = serde_json::from_str(text).map_err(|e| RecipeError::Parse(e.to_string()))?;
        r.validate()?;
        Ok(r)
    }

    /// The recipe as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a recipe is plain data")
    }

    /// The material ids the recipe uses.
    pub fn material_ids(&self) -> [MaterialId; 5] {
        let m = &self.materials;
        [m.rock, m.grass, m.sand, m.snow, m.soil]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recipes_round_trip_through_json_and_bad_numbers_are_named() {
        let r = Recipe::with_seed(42);
        assert_eq!(Recipe::from_json(&r.to_json()).unwrap(), r);
        assert_eq!(Recipe::from_json(r#"{"seed": 9}"#).unwrap(), Recipe::with_seed(9));
        let mut bad = Recipe::default();
        bad.caves.wavelength = f64::NAN;
        assert!(matches!(bad.validate(), Err(RecipeError::Bad { field: "caves.wavelength", .. })));
        bad = Recipe::default();
        bad.heights.octaves = 0;
        assert!(bad.validate().is_err());
        assert!(matches!(Recipe::from_json("{\"seed\": -1}"), Err(RecipeError::Parse(_))));
        assert!(matches!(Recipe::from_json(r#"{"heights": {"gain": 2.0}}"#), Err(RecipeError::Bad { .. })));
    }
}
