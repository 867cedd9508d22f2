//! The brush presets shelf (the built-in presets and the user's, kept in the presets file beside
//! the recovery folder) and the falloff curve editor.

use strata_editor::presets::{self, Preset};
use strata_volume::tools::{Falloff, FalloffCurve};

use super::*;

/// The name of the user's presets file in the studio's folder.
pub const PRESETS_FILE: &str = "presets.json";

/// The user's presets and where they live.
#[derive(Debug)]
pub(super) struct Shelf {
    /// The user's presets (after the built-in ones on the shelf).
    pub(super) user: Vec<Preset>,
    path: PathBuf,
    /// False when the file could not be read: it is left alone, and new presets are not saved.
    writable: bool,
    /// The name being typed for a new preset.
    pub(super) naming: Option<String>,
    /// The name field has had its focus (it is given focus once, when it opens).
    focused: bool,
    /// Why the file could not be read (said once, at start).
    pub(super) load_error: Option<String>,
}

impl Shelf {
    pub(super) fn load(dir: &std::path::Path) -> Self {
        let path = dir.join(PRESETS_FILE);
        match presets::load_presets(&path) {
            Ok(user) => Shelf { user, path, writable: true, naming: None, focused: false, load_error: None },
            Err(e) => Shelf {
                user: Vec::new(),
                path,
                writable: false,
                naming: None,
                focused: false,
                load_error: Some(format!("{e}; it is left as it is, and new presets are not saved this session")),
            },
        }
    }
}

/// The tools whose strength follows the falloff curve.
fn uses_falloff(kind: ToolKind) -> bool {
    matches!(
        kind,
        ToolKind::Smooth
            | ToolKind::Inflate
            | ToolKind::Flatten
            | ToolKind::Paint
            | ToolKind::Mask
            | ToolKind::MaskSmooth
    )
}

impl StudioApp {
    /// Opens the name field of a new preset (focused).
    pub(super) fn name_new_preset(&mut self) {
        self.presets.naming = Some(String::new());
        self.presets.focused = false;
    }

    /// Makes `preset` the brush, or says why not.
    pub fn pick_preset(&mut self, preset: &Preset) {
        match self.studio.apply_preset(preset) {
            Ok(()) => self.studio.message = format!("Preset {:?}: {}", preset.name, preset.summary()),
            Err(e) => self.studio.fail(format!("Could not pick the preset: {e}")),
        }
    }

    /// Saves the brush as a preset named `name` (replacing one of that name) in the presets file.
    pub fn save_preset(&mut self, name: &str) {
        let tool = self.studio.editor.tool;
        let path = self.studio.editor.stamps.path(tool.stamp.source).map(|p| p.to_path_buf());
        let preset = match Preset::capture(name, &tool, path.as_deref()) {
            Ok(p) => p,
            Err(e) => return self.studio.fail(format!("Could not save the preset: {e}")),
        };
        if !self.presets.writable {
            return self.studio.fail(format!(
                "Could not save the preset: {} could not be read at start, and is not overwritten",
                self.presets.path.display()
            ));
        }
        let mut user = self.presets.user.clone();
        match user.iter_mut().find(|p| p.name == preset.name) {
            Some(old) => *old = preset.clone(),
            None => user.push(preset.clone()),
        }
        match presets::save_presets(&self.presets.path, &user) {
            Ok(()) => {
                self.presets.user = user;
                self.studio.message = format!("Saved preset {:?}", preset.name);
            }
            Err(e) => self.studio.fail(format!("Could not save the preset: {e}")),
        }
    }

    /// Deletes the user's preset `name` from the shelf and the file.
    fn delete_preset(&mut self, name: &str) {
        let user: Vec<Preset> = self.presets.user.iter().filter(|p| p.name != name).cloned().collect();
        if !self.presets.writable {
            return self.studio.fail("Could not delete the preset: the presets file is not overwritten".into());
        }
        match presets::save_presets(&self.presets.path, &user) {
            Ok(()) => {
                self.presets.user = user;
                self.studio.message = format!("Deleted preset {name:?}");
            }
            Err(e) => self.studio.fail(format!("Could not delete the preset: {e}")),
        }
    }

    /// Every preset on the shelf: the built-in ones, then the user's.
    pub fn shelf(&self) -> Vec<(Preset, bool)> {
        let mut all: Vec<(Preset, bool)> = Preset::builtin().into_iter().map(|p| (p, false)).collect();
        all.extend(self.presets.user.iter().cloned().map(|p| (p, true)));
        all
    }

    /// The presets shelf: a button per preset (its settings in the tooltip; the user's have a
    /// Delete in their right-click menu), and Save preset with its name field.
    pub(super) fn preset_shelf(&mut self, ui: &mut egui::Ui) {
        let header = egui::CollapsingHeader::new("Presets").default_open(false).show(ui, |ui| self.preset_buttons(ui));
        header.header_response.on_hover_text("Named brushes: click one to pick it (also Edit → Brush presets)");
    }

    fn preset_buttons(&mut self, ui: &mut egui::Ui) {
        let mut picked = None;
        let mut delete = None;
        ui.horizontal_wrapped(|ui| {
            for (preset, mine) in self.shelf() {
                let r = ui.button(&preset.name).on_hover_text(preset.summary());
                if r.clicked() {
                    picked = Some(preset.clone());
                }
                if mine {
                    r.context_menu(|ui| {
                        if ui.button("Delete preset").on_hover_text("Delete this preset of yours").clicked() {
                            delete = Some(preset.name.clone());
                            ui.close();
                        }
                    });
                }
            }
        });
        let mut save = None;
        ui.horizontal(|ui| match self.presets.naming.as_mut() {
            None => {
                if ui
                    .button("Save preset…")
                    .on_hover_text("Keep the brush as it is (tool, shape, radius, strengths, falloff, spacing, stamp) under a name")
                    .clicked()
                {
                    self.presets.naming = Some(String::new());
                    self.presets.focused = false;
                }
            }
            Some(name) => {
                let field = ui
                    .add(egui::TextEdit::singleline(name).hint_text("preset name").desired_width(120.0))
                    .on_hover_text("The preset's name (Enter saves, Escape cancels)");
                if !self.presets.focused {
                    field.request_focus();
                    self.presets.focused = true;
                }
                let enter = field.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
                if ui.button("Save").on_hover_text("Save the preset under this name").clicked() || enter {
                    save = Some(name.clone());
                }
                if ui.button("Cancel").on_hover_text("Do not save it (Escape)").clicked()
                    || ui.input(|i| i.key_pressed(egui::Key::Escape))
                {
                    self.presets.naming = None;
                }
            }
        });
        if let Some(name) = save {
            self.presets.naming = None;
            self.save_preset(&name);
        }
        if let Some(p) = picked {
            self.pick_preset(&p);
        }
        if let Some(name) = delete {
            self.delete_preset(&name);
        }
    }

    /// The falloff of the current brush: its shape by name, and the curve, whose points can be
    /// dragged (that makes it a custom curve). Shown for every tool, greyed out for those that
    /// have their own profile, so the panel below never moves.
    pub(super) fn falloff_editor(&mut self, ui: &mut egui::Ui) {
        let kind = self.studio.editor.tool.kind;
        let on = uses_falloff(kind) || self.studio.smooth_held;
        ui.add_enabled_ui(on, |ui| {
            let falloff = &mut self.studio.editor.tool.falloff;
            ui.horizontal(|ui| {
                ui.label("Falloff").on_hover_text(
                    "How the strength falls from the brush's centre to its rim (each tool keeps its own; grab, pinch, clay, the stamp and add/erase have their own profiles)",
                );
                egui::ComboBox::from_id_salt("falloff shape")
                    .selected_text(falloff.name())
                    .show_ui(ui, |ui| {
                        for f in Falloff::NAMED {
                            ui.selectable_value(falloff, f, f.name());
                        }
                    })
                    .response
                    .on_hover_text("A named shape; drag the curve's points for your own");
                let shape = *falloff;
                let tip = "Drag a point to shape the falloff: centre on the left, rim on the right";
                let points = shape.to_curve().points();
                if let Some(c) = curve_plot(ui, &|t| shape.at(t.min(0.9999)), &points, tip) {
                    *falloff = Falloff::Curve(c);
                }
            });
        });
    }
}

/// A curve on the unit square, drawn from `value` with `points` as handles; the handle nearest a
/// press follows the pointer (the ends only up and down, the others between their neighbours).
/// Returns the curve with the moved point while one is dragged.
pub(super) fn curve_plot(
    ui: &mut egui::Ui,
    value: &dyn Fn(f64) -> f64,
    points: &[(f64, f64)],
    tip: &str,
) -> Option<FalloffCurve> {
    let (rect, response) = ui.allocate_exact_size(egui::vec2(110.0, 36.0), egui::Sense::click_and_drag());
    let response = response.on_hover_text(tip);
    let to_screen =
        |t: f64, v: f64| egui::pos2(rect.left() + t as f32 * rect.width(), rect.bottom() - v as f32 * rect.height());
    let painter = ui.painter_at(rect.expand(4.0));
    let visuals = ui.visuals();
    painter.rect_filled(rect, 2.0, visuals.extreme_bg_color);
    let line: Vec<egui::Pos2> = (0..=64).map(|i| i as f64 / 64.0).map(|t| to_screen(t, value(t))).collect();
    painter.add(egui::Shape::line(line, egui::Stroke::new(1.5, visuals.widgets.active.fg_stroke.color)));
    for &(t, v) in points {
        painter.circle_filled(to_screen(t, v), 3.5, visuals.selection.bg_fill);
    }
    let id = response.id.with("dragged point");
    if response.drag_started()
        && let Some(p) = response.interact_pointer_pos()
    {
        let nearest = points
            .iter()
            .enumerate()
            .map(|(i, &(t, v))| (i, to_screen(t, v).distance(p)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i);
        ui.data_mut(|d| d.insert_temp(id, nearest));
    }
    if !response.dragged() {
        return None;
    }
    let (Some(Some(i)), Some(p)) = (ui.data(|d| d.get_temp::<Option<usize>>(id)), response.interact_pointer_pos())
    else {
        return None;
    };
    let mut pts = points.to_vec();
    let n = pts.len();
    if i >= n {
        return None;
    }
    pts[i].1 = ((rect.bottom() - p.y) / rect.height()).clamp(0.0, 1.0) as f64;
    if i > 0 && i + 1 < n {
        let t = ((p.x - rect.left()) / rect.width()).clamp(0.0, 1.0) as f64;
        let (lo, hi) = (pts[i - 1].0 + 0.01, pts[i + 1].0 - 0.01);
        if lo < hi {
            pts[i].0 = t.clamp(lo, hi);
        }
    }
    FalloffCurve::new(&pts).ok()
}
