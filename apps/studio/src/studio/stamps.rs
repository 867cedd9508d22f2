//! The stamp tool's pictures: the built-in ones and PNGs loaded from files, the next one, and
//! spraying or dragging.

use super::*;
use strata_editor::{StampSource, StampStroke};
use strata_volume::tools::BuiltinStamp;

impl Studio {
    /// Every picture the stamp tool can use, with its name: the built-in ones, then those
    /// loaded.
    pub fn stamp_choices(&self) -> Vec<(StampSource, String)> {
        let mut out: Vec<(StampSource, String)> =
            BuiltinStamp::ALL.iter().map(|&b| (StampSource::Builtin(b), b.name().to_string())).collect();
        out.extend(self.editor.stamps.loaded().map(|(s, name)| (s, name.to_string())));
        out
    }

    /// The stamp tool's picture's name.
    pub fn stamp_name(&self) -> String {
        self.editor.stamps.name(self.editor.tool.stamp.source).unwrap_or("a picture not loaded here").to_string()
    }

    /// Picks the stamp tool with its next picture.
    pub fn next_stamp(&mut self) {
        let choices = self.stamp_choices();
        let now = choices.iter().position(|(s, _)| *s == self.editor.tool.stamp.source);
        let next = now.map_or(0, |i| (i + 1) % choices.len());
        self.editor.tool.stamp.source = choices[next].0;
        self.editor.tool.kind = ToolKind::Stamp;
        self.message = format!("Stamp: {}", choices[next].1);
    }

    /// Picks the stamp tool, spraying if it dragged and dragging if it sprayed.
    pub fn toggle_stamp_stroke(&mut self) {
        let stamp = &mut self.editor.tool.stamp;
        stamp.stroke = match stamp.stroke {
            StampStroke::Spray => StampStroke::Drag,
            StampStroke::Drag => StampStroke::Spray,
        };
        self.editor.tool.kind = ToolKind::Stamp;
        self.message = match stamp.stroke {
            StampStroke::Spray => "Stamp: sprayed along the stroke".into(),
            StampStroke::Drag => "Stamp: press at its middle, drag to size and turn it, release to apply".into(),
        };
    }

    /// Reads a PNG as the stamp tool's picture and picks the stamp tool.
    pub(super) fn load_stamp(&mut self, path: &Path) -> Result<(), String> {
        let image = strata_editor::stamps::load_png(path).map_err(|e| format!("Could not load the stamp: {e}"))?;
        let (w, h) = (image.width(), image.height());
        self.editor.tool.stamp.source = self.editor.stamps.add_file(path, image);
        let name = self.stamp_name();
        self.editor.tool.kind = ToolKind::Stamp;
        self.message = format!("Stamp: {name} ({w} × {h})");
        if self.in_session() {
            self.message += ": a picture loaded from a file is not shared with the room, so strokes with it are refused here until you leave";
        }
        Ok(())
    }
}
