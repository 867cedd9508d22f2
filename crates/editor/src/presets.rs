//! Brush presets: named settings of a brush (tool, shape, radius, strengths, falloff, spacing,
//! stamp) that a shelf shows and a click brings back. A few are built in; the user's own are
//! kept in a presets file (JSON, written atomically), which a damaged file never loses: it is
//! refused with a message that names what is wrong, and left as it is.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use strata_volume::tools::{BuiltinStamp, Falloff};
use thiserror::Error;

use crate::Editor;
use crate::stamps::{StampLoadError, StampSettings, StampSource, StampStroke};
use crate::tool::{BrushShape, ToolKind, ToolSettings};

/// The presets file's format version.
pub const PRESETS_VERSION: u32 = 1;

/// The longest preset name (characters).
pub const MAX_NAME: usize = 64;

/// The most presets a file may hold.
pub const MAX_PRESETS: usize = 256;

/// A stamp's picture as a preset keeps it: built in, or the PNG file it was loaded from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PresetPicture {
    /// One made in code.
    Builtin(BuiltinStamp),
    /// A PNG, loaded again when the preset is picked.
    File(PathBuf),
}

/// The stamp settings of a preset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PresetStamp {
    /// The picture.
    pub picture: PresetPicture,
    /// Spray or drag.
    pub stroke: StampStroke,
    /// A sprayed stamp's top follows the stroke.
    pub follow_stroke: bool,
    /// The turn (degrees).
    pub angle: f64,
}

/// One preset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Preset {
    /// What the shelf shows.
    pub name: String,
    /// The tool.
    pub tool: ToolKind,
    /// The add and erase brushes' shape.
    pub shape: BrushShape,
    /// The radius (world units), or `None` to keep the brush's (the built-in presets: scenes
    /// differ in scale).
    pub radius: Option<f64>,
    /// The field tools' strength, in `[0, 1]`.
    pub strength: f64,
    /// How much pressure scales the radius, in `[0, 1]`.
    pub pressure_to_size: f64,
    /// The falloff.
    pub falloff: Falloff,
    /// Dab spacing (a fraction of the radius, above 0).
    pub spacing: f64,
    /// The stamp's settings, for a stamp preset.
    pub stamp: Option<PresetStamp>,
}

/// Why presets could not be read, written or picked.
#[derive(Debug, Error)]
pub enum PresetError {
    /// Reading or writing the file failed.
    #[error("presets file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not a presets file this build reads.
    #[error("presets file {path} is damaged: {reason}")]
    Damaged {
        /// The file.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// A preset's value is out of range.
    #[error("preset {name:?}: {what}")]
    Bad {
        /// The preset.
        name: String,
        /// What is wrong.
        what: String,
    },
    /// A preset's stamp picture could not be loaded.
    #[error("preset {name:?}: {source}")]
    Stamp {
        /// The preset.
        name: String,
        /// Why.
        source: StampLoadError,
    },
}

#[derive(Serialize, Deserialize)]
struct PresetsFile {
    version: u32,
    presets: Vec<Preset>,
}

impl Preset {
    /// The presets Strata comes with.
    pub fn builtin() -> Vec<Preset> {
        let base = |name: &str, tool: ToolKind, strength: f64, falloff: Falloff, spacing: f64| Preset {
            name: name.into(),
            tool,
            shape: BrushShape::Sphere,
            radius: None,
            strength,
            pressure_to_size: 0.0,
            falloff,
            spacing,
            stamp: None,
        };
        let stamp = |picture: BuiltinStamp, stroke: StampStroke, follow_stroke: bool| PresetStamp {
            picture: PresetPicture::Builtin(picture),
            stroke,
            follow_stroke,
            angle: 0.0,
        };
        vec![
            base("Soft clay", ToolKind::Clay, 0.35, Falloff::Smooth, 0.2),
            base("Blob", ToolKind::Inflate, 0.6, Falloff::Sphere, 0.2),
            base("Polish", ToolKind::Smooth, 0.8, Falloff::Sphere, 0.25),
            base("Plane", ToolKind::Flatten, 0.7, Falloff::Constant, 0.2),
            base("Crease", ToolKind::Pinch, 0.8, Falloff::Smooth, 0.15),
            Preset { shape: BrushShape::Capsule, ..base("Groove", ToolKind::Erase, 0.5, Falloff::Smooth, 0.15) },
            Preset {
                stamp: Some(stamp(BuiltinStamp::Dots, StampStroke::Drag, false)),
                ..base("Rivets", ToolKind::Stamp, 0.8, Falloff::Smooth, 0.25)
            },
            Preset {
                stamp: Some(stamp(BuiltinStamp::Cells, StampStroke::Spray, true)),
                ..base("Cobbles", ToolKind::Stamp, 0.5, Falloff::Smooth, 0.4)
            },
        ]
    }

    /// The preset of `tool` as it is, named `name`; a stamp loaded from a file is kept by its
    /// path (`None` from `stamp_path`: the picture is not from a file and a built-in one is
    /// kept instead).
    pub fn capture(name: &str, tool: &ToolSettings, stamp_path: Option<&Path>) -> Result<Preset, PresetError> {
        let stamp = (tool.kind == ToolKind::Stamp).then(|| PresetStamp {
            picture: match (tool.stamp.source, stamp_path) {
                (StampSource::Builtin(b), _) => PresetPicture::Builtin(b),
                (StampSource::Loaded(_), Some(p)) => PresetPicture::File(p.to_path_buf()),
                (StampSource::Loaded(_), None) => PresetPicture::Builtin(BuiltinStamp::default()),
            },
            stroke: tool.stamp.stroke,
            follow_stroke: tool.stamp.follow_stroke,
            angle: tool.stamp.angle,
        });
        let p = Preset {
            name: name.trim().to_string(),
            tool: tool.kind,
            shape: tool.shape,
            radius: Some(tool.radius),
            strength: tool.field_strength,
            pressure_to_size: tool.strength,
            falloff: tool.falloff,
            spacing: tool.spacing,
            stamp,
        };
        p.check()?;
        Ok(p)
    }

    /// Refuses out-of-range values, naming them.
    pub fn check(&self) -> Result<(), PresetError> {
        let bad = |what: &str| Err(PresetError::Bad { name: self.name.clone(), what: what.into() });
        let unit = |x: f64| (0.0..=1.0).contains(&x);
        if self.name.trim().is_empty() || self.name.chars().count() > MAX_NAME {
            return bad(&format!("a name must have 1 to {MAX_NAME} characters"));
        }
        if self.radius.is_some_and(|r| !(r.is_finite() && r > 0.0 && r <= 1.0e6)) {
            return bad("the radius must be finite and positive");
        }
        if !unit(self.strength) || !unit(self.pressure_to_size) {
            return bad("strengths must be in [0, 1]");
        }
        if !(self.spacing.is_finite() && self.spacing > 0.0 && self.spacing <= 100.0) {
            return bad("the spacing must be finite and positive");
        }
        if !self.falloff.is_valid() {
            return bad("the falloff curve's points are out of order or range");
        }
        if self.tool == ToolKind::MaskSmooth {
            return bad("smooth mask is not a tool of its own");
        }
        if self.stamp.as_ref().is_some_and(|s| !s.angle.is_finite()) {
            return bad("the stamp's turn must be finite");
        }
        Ok(())
    }

    /// What the shelf's tooltip says of it.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "{}, strength {:.2}, {} falloff, spacing {:.2}",
            self.tool.name(),
            self.strength,
            self.falloff.name().to_lowercase(),
            self.spacing
        );
        if let Some(r) = self.radius {
            s += &format!(", radius {r:.2}");
        }
        if let Some(stamp) = &self.stamp {
            let picture = match &stamp.picture {
                PresetPicture::Builtin(b) => b.name().to_string(),
                PresetPicture::File(p) => p.display().to_string(),
            };
            let how = match stamp.stroke {
                StampStroke::Spray => "sprayed",
                StampStroke::Drag => "dragged out",
            };
            s += &format!(", stamp {picture} {how}");
        }
        s
    }
}

impl Editor {
    /// Makes `preset` the current brush: every setting it holds, the radius only where it
    /// keeps one; a stamp from a file is loaded again (refused with its reason, the brush
    /// unchanged, when it cannot be). Ends the stroke in progress.
    pub fn apply_preset(&mut self, preset: &Preset) -> Result<(), PresetError> {
        preset.check()?;
        let mut tool = self.tool;
        if let Some(stamp) = &preset.stamp {
            let source = match &stamp.picture {
                PresetPicture::Builtin(b) => StampSource::Builtin(*b),
                PresetPicture::File(path) => {
                    let image = crate::stamps::load_png(path)
                        .map_err(|source| PresetError::Stamp { name: preset.name.clone(), source })?;
                    self.stamps.add_file(path, image)
                }
            };
            tool.stamp =
                StampSettings { source, stroke: stamp.stroke, follow_stroke: stamp.follow_stroke, angle: stamp.angle };
        }
        self.end_stroke();
        tool.kind = preset.tool;
        tool.shape = preset.shape;
        if let Some(r) = preset.radius {
            tool.radius = r;
        }
        tool.field_strength = preset.strength;
        tool.strength = preset.pressure_to_size;
        tool.falloff = preset.falloff;
        tool.spacing = preset.spacing;
        self.tool = tool;
        Ok(())
    }
}

/// Reads the user's presets from `path`: none where there is no file yet; a damaged file, or
/// one holding an out-of-range preset, is refused whole (and left as it is).
pub fn load_presets(path: &Path) -> Result<Vec<Preset>, PresetError> {
    let name = path.display().to_string();
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(source) => return Err(PresetError::Io { path: name, source }),
    };
    let damaged = |reason: String| PresetError::Damaged { path: name.clone(), reason };
    let file: PresetsFile = serde_json::from_slice(&bytes).map_err(|e| damaged(e.to_string()))?;
    if file.version != PRESETS_VERSION {
        return Err(damaged(format!("version {} (this build reads version {PRESETS_VERSION})", file.version)));
    }
    if file.presets.len() > MAX_PRESETS {
        return Err(damaged(format!("{} presets (at most {MAX_PRESETS})", file.presets.len())));
    }
    for p in &file.presets {
        p.check()?;
    }
    Ok(file.presets)
}

/// Writes the user's presets to `path` atomically (a crash keeps the old file).
pub fn save_presets(path: &Path, presets: &[Preset]) -> Result<(), PresetError> {
    if presets.len() > MAX_PRESETS {
        return Err(PresetError::Bad {
            name: presets[MAX_PRESETS].name.clone(),
            what: format!("a presets file holds at most {MAX_PRESETS} presets: delete some first"),
        });
    }
    for p in presets {
        p.check()?;
    }
    let file = PresetsFile { version: PRESETS_VERSION, presets: presets.to_vec() };
    let json = serde_json::to_vec_pretty(&file)
        .map_err(|e| PresetError::Damaged { path: path.display().to_string(), reason: e.to_string() })?;
    let io = |source| PresetError::Io { path: path.display().to_string(), source };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io)?;
    }
    strata_files::write_atomically(path, |f: &mut std::fs::File| {
        use std::io::Write;
        f.write_all(&json)
    })
    .map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("strata-presets-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn built_in_presets_are_sound_and_pick_their_settings() {
        let mut e = Editor::default();
        for p in Preset::builtin() {
            p.check().unwrap();
            let radius = e.tool.radius;
            e.apply_preset(&p).unwrap();
            assert_eq!(e.tool.kind, p.tool);
            assert_eq!(e.tool.falloff, p.falloff);
            assert_eq!(e.tool.field_strength, p.strength);
            assert_eq!(e.tool.radius, radius, "a built-in preset keeps the brush's size");
            assert!(!p.summary().is_empty());
        }
        assert_eq!(e.tool.stamp.source, StampSource::Builtin(BuiltinStamp::Cells));
    }

    #[test]
    fn presets_round_trip_through_the_file_and_a_damaged_file_is_refused_and_kept() {
        let dir = temp("file");
        let path = dir.join("presets.json");
        assert!(load_presets(&path).unwrap().is_empty(), "no file yet: no presets");
        let mut tool = ToolSettings { kind: ToolKind::Stamp, radius: 3.5, field_strength: 0.7, ..Default::default() };
        tool.falloff =
            Falloff::Curve(strata_volume::tools::FalloffCurve::new(&[(0.0, 1.0), (0.6, 0.8), (1.0, 0.0)]).unwrap());
        let png = dir.join("pic.png");
        tool.stamp.source = StampSource::Loaded(1);
        let mine = Preset::capture("  Mine  ", &tool, Some(&png)).unwrap();
        assert_eq!(mine.name, "Mine");
        assert_eq!(mine.stamp.as_ref().unwrap().picture, PresetPicture::File(png.clone()));
        let presets = vec![mine.clone(), Preset::builtin()[0].clone()];
        save_presets(&path, &presets).unwrap();
        assert_eq!(load_presets(&path).unwrap(), presets);
        // Damaged in several ways: each refused with a reason, the file left alone.
        let good = std::fs::read(&path).unwrap();
        for (bytes, says) in [
            (b"{ not json".to_vec(), "damaged"),
            (
                String::from_utf8(good.clone()).unwrap().replace("\"version\": 1", "\"version\": 9").into_bytes(),
                "version 9",
            ),
            (String::from_utf8(good.clone()).unwrap().replacen("0.7", "7.0", 1).into_bytes(), "strengths"),
        ] {
            std::fs::write(&path, &bytes).unwrap();
            let e = load_presets(&path).unwrap_err();
            assert!(e.to_string().contains(says), "{e}");
            assert_eq!(std::fs::read(&path).unwrap(), bytes, "a refused file is left as it is");
        }
        // Picking a preset whose picture file is gone is refused and changes nothing.
        let mut e = Editor::default();
        let before = e.tool;
        assert!(matches!(e.apply_preset(&mine), Err(PresetError::Stamp { .. })));
        assert_eq!(e.tool, before);
    }

    #[test]
    fn bad_presets_are_refused_by_name() {
        let tool = ToolSettings::default();
        assert!(Preset::capture("   ", &tool, None).is_err());
        assert!(Preset::capture(&"x".repeat(MAX_NAME + 1), &tool, None).is_err());
        let mut p = Preset::capture("ok", &tool, None).unwrap();
        let dir = temp("many");
        let many = vec![p.clone(); MAX_PRESETS + 1];
        assert!(save_presets(&dir.join("p.json"), &many).unwrap_err().to_string().contains("at most"));
        assert!(!dir.join("p.json").exists());
        p.radius = Some(f64::NAN);
        assert!(p.check().unwrap_err().to_string().contains("\"ok\""));
        p.radius = None;
        p.spacing = 0.0;
        assert!(p.check().is_err());
    }
}
