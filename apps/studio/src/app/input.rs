//! The keyboard: shortcuts read from the binding table after the frame's widgets, one key
//! event at a time, and the commands they run (in a scene and in terrain mode); the brush's
//! size dragged with F.

use super::*;

impl StudioApp {
    /// The keyboard shortcuts, run after the frame's widgets so that a text field focused in
    /// this very frame (a click and a key in one slow frame) keeps its letters. Key presses are
    /// taken one event at a time, in the order they came: three quick `]` grow the brush three
    /// times, `V` then `C` in one frame ends on clay.
    pub(super) fn shortcuts(&mut self, ctx: &egui::Context) {
        if self.modal_open() {
            // A prompt or a question has the keyboard: no key reaches the tools.
            return;
        }
        let presses: Vec<(egui::Modifiers, egui::Key)> = ctx.input(|i| {
            i.events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::Key { key, pressed: true, modifiers, .. } => Some((*modifiers, *key)),
                    _ => None,
                })
                .collect()
        });
        for (mods, key) in presses {
            let Some(command) = command_for(mods, key) else { continue };
            // Letters typed into a field are the field's; commands with Ctrl still work there.
            if (ctx.egui_wants_keyboard_input() && !command.works_while_typing()) || self.modal_open() {
                continue;
            }
            ctx.input_mut(|i| i.consume_key(mods, key));
            self.run_command(ctx, command);
            ctx.request_repaint();
        }
    }

    /// Carries out a keyboard command.
    pub(super) fn run_command(&mut self, ctx: &egui::Context, command: Command) {
        use Command as C;
        match command {
            C::Undo => {
                let _ = self.studio.act(Action::Undo);
            }
            C::Redo => {
                let _ = self.studio.act(Action::Redo);
            }
            C::SaveAs => self.ask_path(ctx, Prompt::SaveAs, None),
            C::Save if self.studio.terrain.is_some() => {
                let _ = self.studio.act(Action::SaveWorld);
            }
            C::Save => self.save(ctx, None),
            C::Open => self.guard(ctx, Then::Open),
            C::New => self.guard(ctx, Then::New),
            C::Help => self.help_open = !self.help_open,
            C::CloseHelp => {
                self.help_open = false;
                self.studio.cancel_insert();
            }
            _ if self.studio.terrain.is_some()
                && crate::keymap::binding(command).is_some_and(|b| b.terrain.is_some()) =>
            {
                self.terrain_command(command)
            }
            C::RadiusDown => {
                let _ = self.studio.act(Action::ScaleRadius(1.0 / 1.15));
            }
            C::RadiusUp => {
                let _ = self.studio.act(Action::ScaleRadius(1.15));
            }
            C::ResizeBrush => self.start_resize(ctx),
            C::Wireframe => {
                let _ = self.studio.act(Action::ToggleWireframe);
            }
            C::NextShape => {
                let tool = &mut self.studio.editor.tool;
                tool.shape = match tool.shape {
                    BrushShape::Sphere => BrushShape::Box,
                    BrushShape::Box => BrushShape::Capsule,
                    BrushShape::Capsule => BrushShape::Cylinder,
                    BrushShape::Cylinder => BrushShape::Sphere,
                };
                self.studio.message = format!("Brush shape: {:?}", tool.shape);
            }
            C::View(view, opposite) => {
                let _ = self.studio.act(Action::AxisView(view, opposite));
            }
            C::Orthographic => {
                let _ = self.studio.act(Action::ToggleOrthographic);
            }
            C::Frame => {
                let _ = self.studio.act(Action::FrameAll);
            }
            C::Tool(kind) => self.studio.set_kind(kind),
            C::Line => self.studio.toggle_line_tool(),
            C::MirrorX => self.studio.toggle_symmetry(0),
            C::Eyedropper => self.studio.toggle_eyedropper(),
            C::Stabiliser => {
                let s = self.studio.editor.stabiliser.next();
                self.studio.editor.stabiliser = s;
                self.studio.message = format!("Stroke stabiliser: {}", s.name());
            }
            C::Mask(a) => {
                let _ = self.studio.act(Action::Mask(a));
            }
            C::NextStamp => self.studio.next_stamp(),
            C::StampStroke => self.studio.toggle_stamp_stroke(),
            C::LoadStamp => self.ask_path(ctx, Prompt::LoadStamp, None),
            C::LayerGizmo => self.toggle_layer_gizmo(),
            C::LoadReference => self.ask_path(ctx, Prompt::LoadReference, None),
            C::ShowReferences => self.studio.toggle_references(),
            C::Pressure => {
                let p = &mut self.studio.editor.tool.pressure;
                p.enabled = !p.enabled;
                self.studio.message = format!("Pen pressure {}", if p.enabled { "on" } else { "off" });
            }
        }
    }

    /// The keys whose binding says they mean something else in terrain mode: B (the scene's
    /// next-shape key) bombs, the fly keys (read as held keys by the viewport) do nothing here
    /// (Ctrl+S, which writes the world, is taken before); every other key works as in a scene.
    pub(super) fn terrain_command(&mut self, command: Command) {
        if command == Command::NextShape {
            let _ = self.studio.act(Action::Bomb);
        }
    }

    /// Starts sizing the brush by dragging (F): the pointer's distance from a centre placed so
    /// that the radius starts as it is.
    pub(super) fn start_resize(&mut self, ctx: &egui::Context) {
        let Some(pointer) = ctx.pointer_latest_pos() else {
            self.studio.message = "Brush size: point at the viewport and press F".into();
            return;
        };
        let depth = self
            .studio
            .hover
            .map_or(self.studio.camera.distance as f64, |p| (p - self.studio.camera.eye().as_dvec3()).length());
        let world_per_point = self.studio.world_per_point(depth);
        let points = if self.studio.screen_radius {
            self.studio.radius_points
        } else {
            (self.studio.editor.tool.radius / world_per_point) as f32
        };
        let points = points.clamp(4.0, 2000.0);
        self.resize = Some(Resize {
            centre: pointer - egui::vec2(points, 0.0),
            before: (self.studio.editor.tool.radius, self.studio.radius_points),
            world_per_point,
        });
        self.studio.message = "Brush size: move the pointer; click or Enter keeps it, Escape cancels".into();
    }

    /// A frame of sizing the brush: the radius follows the pointer; a click or Enter (or F
    /// again) keeps it, Escape or a right click cancels. Returns whether sizing took this
    /// frame's input (the click that keeps the size is not also a dab).
    pub(super) fn resize_input(&mut self, ui: &egui::Ui) -> bool {
        let Some(r) = self.resize else { return false };
        use egui::{Key, Modifiers};
        let keep = ui.input_mut(|i| {
            i.consume_key(Modifiers::NONE, Key::Enter)
                || i.consume_key(Modifiers::NONE, Key::F)
                || i.pointer.button_pressed(egui::PointerButton::Primary)
        });
        let cancel = ui.input_mut(|i| {
            i.consume_key(Modifiers::NONE, Key::Escape) || i.pointer.button_pressed(egui::PointerButton::Secondary)
        });
        let pointer = ui.input(|i| i.pointer.latest_pos()).unwrap_or(r.centre + egui::vec2(r.before.1, 0.0));
        let points = (pointer - r.centre).length().clamp(1.0, 2000.0);
        if cancel {
            (self.studio.editor.tool.radius, self.studio.radius_points) = r.before;
            self.studio.message = "Brush size unchanged".into();
            self.resize = None;
            return true;
        }
        if self.studio.screen_radius {
            self.studio.radius_points = points;
        } else {
            self.studio.editor.tool.radius = (points as f64 * r.world_per_point).clamp(0.05, 256.0);
        }
        let stroke = egui::Stroke::new(1.5, egui::Color32::from_rgb(120, 190, 255));
        ui.painter().circle_stroke(r.centre, points, stroke);
        ui.painter().circle_filled(r.centre, 2.0, stroke.color);
        if keep {
            self.studio.message = if self.studio.screen_radius {
                format!("Brush radius {points:.0} points on screen")
            } else {
                format!("Brush radius {:.2}", self.studio.editor.tool.radius)
            };
            self.resize = None;
        }
        true
    }
}
