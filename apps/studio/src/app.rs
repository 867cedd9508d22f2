//! The eframe window: menus, tool palette, layers panel, status bar and the 3D viewport (the
//! renderer draws into a texture that egui shows).

use std::path::PathBuf;
use std::time::Duration;

use eframe::egui;
use glam::Mat4;
use strata_editor::{BrushShape, Buttons, ToolKind};
use strata_render::{DEPTH_FORMAT, FrameSettings, Preview, Renderer};

use crate::headless::{layer_model, upload_all};
use crate::studio::{Action, Studio};

/// The GPU side of the viewport.
struct Viewport {
    renderer: Renderer,
    size: (u32, u32),
    color: Option<(wgpu::Texture, wgpu::TextureView, wgpu::TextureView)>,
    texture_id: Option<egui::TextureId>,
}

/// Which path prompt is open.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Prompt {
    Open,
    SaveAs,
    Export,
}

/// The desktop app.
pub struct StudioApp {
    /// State and actions.
    pub studio: Studio,
    viewport: Option<Viewport>,
    prompt: Option<(Prompt, String)>,
}

impl std::fmt::Debug for StudioApp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StudioApp").field("studio", &self.studio).finish()
    }
}

impl StudioApp {
    /// The app on `studio`, with GPU resources from eframe's wgpu state when there is one.
    pub fn new(cc: &eframe::CreationContext<'_>, studio: Studio) -> Self {
        let viewport = cc.wgpu_render_state.as_ref().map(|rs| Viewport {
            renderer: Renderer::new(&rs.device, wgpu::TextureFormat::Rgba8UnormSrgb),
            size: (0, 0),
            color: None,
            texture_id: None,
        });
        StudioApp { studio, viewport, prompt: None }
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        use egui::{Key, Modifiers};
        // Each key event carries the modifiers held when it happened, so consume by event:
        // a fast Ctrl+Z can be released before the frame that sees it.
        let typing = ctx.egui_wants_keyboard_input();
        let pressed = |mods: Modifiers, key: Key| ctx.input_mut(|i| i.consume_key(mods, key));
        let redo = pressed(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z) || pressed(Modifiers::COMMAND, Key::Y);
        let undo = pressed(Modifiers::COMMAND, Key::Z);
        let save = pressed(Modifiers::COMMAND, Key::S);
        if redo {
            let _ = self.studio.act(Action::Redo);
        }
        if undo {
            let _ = self.studio.act(Action::Undo);
        }
        if save {
            if self.studio.path.is_some() {
                let _ = self.studio.act(Action::Save);
            } else {
                self.prompt = Some((Prompt::SaveAs, "scene.strata".into()));
            }
        }
        if typing {
            return;
        }
        if pressed(Modifiers::NONE, Key::OpenBracket) {
            let _ = self.studio.act(Action::ScaleRadius(1.0 / 1.15));
        }
        if pressed(Modifiers::NONE, Key::CloseBracket) {
            let _ = self.studio.act(Action::ScaleRadius(1.15));
        }
        if pressed(Modifiers::NONE, Key::W) {
            let _ = self.studio.act(Action::ToggleWireframe);
        }
        let shapes = [
            (Key::Num1, BrushShape::Sphere),
            (Key::Num2, BrushShape::Box),
            (Key::Num3, BrushShape::Capsule),
            (Key::Num4, BrushShape::Cylinder),
        ];
        for (key, shape) in shapes {
            if pressed(Modifiers::NONE, key) {
                self.studio.editor.tool.shape = shape;
            }
        }
        if pressed(Modifiers::NONE, Key::A) {
            self.studio.set_kind(ToolKind::Add);
        }
        if pressed(Modifiers::NONE, Key::E) {
            self.studio.set_kind(ToolKind::Erase);
        }
    }

    fn menu(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("New").clicked() {
                    let _ = self.studio.act(Action::New);
                }
                if ui.button("Open…").clicked() {
                    self.prompt = Some((Prompt::Open, "scene.strata".into()));
                }
                if ui.button("Save (Ctrl+S)").clicked() {
                    if self.studio.path.is_some() {
                        let _ = self.studio.act(Action::Save);
                    } else {
                        self.prompt = Some((Prompt::SaveAs, "scene.strata".into()));
                    }
                }
                if ui.button("Save as…").clicked() {
                    self.prompt = Some((Prompt::SaveAs, "scene.strata".into()));
                }
                ui.separator();
                if ui.button("Export mesh… (glb, obj, stl, ply)").clicked() {
                    self.prompt = Some((Prompt::Export, "sculpt.glb".into()));
                }
                ui.checkbox(&mut self.studio.export_dual, "Export with dual contouring");
            });
            ui.menu_button("Edit", |ui| {
                if ui.button("Undo (Ctrl+Z)").clicked() {
                    let _ = self.studio.act(Action::Undo);
                }
                if ui.button("Redo (Ctrl+Shift+Z)").clicked() {
                    let _ = self.studio.act(Action::Redo);
                }
            });
            ui.menu_button("View", |ui| {
                if ui.checkbox(&mut self.studio.wireframe, "Wireframe (W)").changed() {
                    ui.close();
                }
            });
        });
    }

    fn palette(&mut self, ui: &mut egui::Ui) {
        let tool = &mut self.studio.editor.tool;
        ui.heading("Tool");
        ui.horizontal(|ui| {
            ui.selectable_value(&mut tool.kind, ToolKind::Add, "Add (A)");
            ui.selectable_value(&mut tool.kind, ToolKind::Erase, "Erase (E)");
        });
        ui.label("Shape (1–4)");
        for (shape, name) in [
            (BrushShape::Sphere, "Sphere"),
            (BrushShape::Box, "Box"),
            (BrushShape::Capsule, "Capsule"),
            (BrushShape::Cylinder, "Cylinder"),
        ] {
            ui.selectable_value(&mut tool.shape, shape, name);
        }
        ui.add(egui::Slider::new(&mut tool.radius, 0.25..=64.0).logarithmic(true).text("radius [ ]"));
        ui.add(egui::Slider::new(&mut tool.strength, 0.0..=1.0).text("pressure to size"));
        ui.add(egui::Slider::new(&mut tool.spacing, 0.05..=1.0).text("dab spacing"));
        ui.separator();
        ui.label("Alt + right drag: the opposite tool (erase while adding, add while erasing).");
    }

    fn layers(&mut self, ui: &mut egui::Ui) {
        ui.heading("Layers");
        let mut changed = false;
        let active = self.studio.editor.active_layer;
        let mut select = None;
        for (i, layer) in self.studio.editor.scene.layers.iter_mut().enumerate() {
            ui.horizontal(|ui| {
                if ui.selectable_label(i == active, &layer.name).clicked() {
                    select = Some(i);
                }
                changed |= ui.checkbox(&mut layer.visible, "visible").changed();
                ui.checkbox(&mut layer.locked, "locked");
            });
        }
        if let Some(i) = select {
            self.studio.editor.active_layer = i;
        }
        if let Some(layer) = self.studio.editor.scene.layers.get_mut(self.studio.editor.active_layer) {
            ui.horizontal(|ui| {
                ui.label("Name");
                ui.text_edit_singleline(&mut layer.name);
            });
        }
        if ui.button("Add layer").clicked() {
            let _ = self.studio.act(Action::AddLayer);
        }
        if changed {
            self.studio.full_upload = true;
        }
    }

    fn prompt(&mut self, ctx: &egui::Context) {
        let Some((kind, mut text)) = self.prompt.take() else { return };
        let title = match kind {
            Prompt::Open => "Open scene",
            Prompt::SaveAs => "Save scene as",
            Prompt::Export => "Export mesh",
        };
        let mut keep = true;
        let mut go = false;
        egui::Window::new(title).collapsible(false).show(ctx, |ui| {
            ui.label("Path:");
            let r = ui.text_edit_singleline(&mut text);
            go = r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            ui.horizontal(|ui| {
                go |= ui.button("OK").clicked();
                if ui.button("Cancel").clicked() {
                    keep = false;
                }
            });
        });
        if go {
            let path = PathBuf::from(text.trim());
            let _ = self.studio.act(match kind {
                Prompt::Open => Action::Open(path),
                Prompt::SaveAs => Action::SaveAs(path),
                Prompt::Export => Action::Export(path),
            });
        } else if keep {
            self.prompt = Some((kind, text));
        }
    }

    fn viewport(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let (rect, response) = ui.allocate_exact_size(ui.available_size(), egui::Sense::click_and_drag());
        let aspect = rect.width() / rect.height().max(1.0);
        // Camera: right drag orbits, middle drag pans, the wheel zooms.
        let (delta, scroll, secondary_drag, middle, primary, secondary) = ui.input(|i| {
            (
                i.pointer.delta(),
                i.smooth_scroll_delta.y,
                i.pointer.button_down(egui::PointerButton::Secondary) && i.modifiers.alt,
                i.pointer.button_down(egui::PointerButton::Middle),
                i.pointer.primary_down(),
                i.pointer.secondary_down(),
            )
        });
        let cam = &mut self.studio.camera;
        if response.hovered() {
            if scroll != 0.0 {
                cam.zoom((-scroll * 0.002).exp());
            }
            if middle {
                cam.pan(-delta.x / rect.height(), delta.y / rect.height());
            }
        }
        // Right drag orbits unless Alt is held (then it erases like the secondary tool button).
        let orbit = response.dragged_by(egui::PointerButton::Secondary) && !secondary_drag;
        if orbit {
            cam.orbit(-delta.x * 0.008, delta.y * 0.008);
        }
        let ndc = response.hover_pos().filter(|_| response.hovered() || response.dragged()).map(|p| {
            let x = (p.x - rect.left()) / rect.width() * 2.0 - 1.0;
            let y = 1.0 - (p.y - rect.top()) / rect.height() * 2.0;
            (x, y)
        });
        let buttons = Buttons {
            primary: primary
                && (response.dragged_by(egui::PointerButton::Primary) || response.is_pointer_button_down_on()),
            secondary: secondary && secondary_drag,
        };
        self.studio.pointer(ndc, buttons, 1.0, aspect, Duration::from_millis(6));

        let Some(rs) = frame.wgpu_render_state() else {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "No wgpu renderer",
                egui::FontId::default(),
                egui::Color32::RED,
            );
            return;
        };
        let Some(vp) = self.viewport.as_mut() else { return };
        let ppp = ui.ctx().pixels_per_point();
        let size = (((rect.width() * ppp) as u32).max(1), ((rect.height() * ppp) as u32).max(1));
        if vp.size != size || vp.color.is_none() {
            let make = |format, usage, label, view_formats: &[wgpu::TextureFormat]| {
                rs.device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats,
                })
            };
            let color = make(
                wgpu::TextureFormat::Rgba8UnormSrgb,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
                "viewport colour",
                &[wgpu::TextureFormat::Rgba8Unorm],
            );
            let depth = make(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT, "viewport depth", &[]);
            let (cv, dv) = (color.create_view(&Default::default()), depth.create_view(&Default::default()));
            // The renderer writes sRGB-encoded bytes; egui composites in gamma space, so it reads
            // them through a plain (non-sRGB) view and shows exactly what the PNG path writes.
            let egui_view = color.create_view(&wgpu::TextureViewDescriptor {
                format: Some(wgpu::TextureFormat::Rgba8Unorm),
                ..Default::default()
            });
            let mut egui_renderer = rs.renderer.write();
            match vp.texture_id {
                Some(id) => egui_renderer.update_egui_texture_from_wgpu_texture(
                    &rs.device,
                    &egui_view,
                    wgpu::FilterMode::Linear,
                    id,
                ),
                None => {
                    vp.texture_id =
                        Some(egui_renderer.register_native_texture(&rs.device, &egui_view, wgpu::FilterMode::Linear))
                }
            }
            vp.color = Some((color, cv, dv));
            vp.size = size;
        }
        // Upload what the editor remeshed.
        if self.studio.full_upload {
            upload_all(&self.studio, &rs.device, &rs.queue, &mut vp.renderer);
            self.studio.full_upload = false;
            self.studio.uploads.clear();
        } else {
            for (layer, key) in std::mem::take(&mut self.studio.uploads) {
                let scene = &self.studio.editor.scene;
                let Some(l) = scene.layers.get(layer) else { continue };
                let mesh = self.studio.editor.mesh_cache(layer).and_then(|c| c.mesh(key));
                match mesh.filter(|_| l.visible) {
                    Some(mesh) => {
                        let color = scene.materials.get(l.material as usize).map_or([0.7, 0.6, 0.5], |m| m.color);
                        vp.renderer.upload_chunk(&rs.device, &rs.queue, layer as u32, key, mesh, layer_model(l), color);
                    }
                    None => vp.renderer.remove_chunk(layer as u32, key),
                }
            }
        }
        let hover = self.studio.hover;
        let erase = self.studio.editor.tool.kind == ToolKind::Erase;
        let wireframe = self.studio.wireframe;
        let camera = self.studio.camera;
        let preview_mesh = self.studio.preview_mesh();
        let preview = hover.map(|p| Preview {
            mesh: preview_mesh,
            model: Mat4::from_translation(p.as_vec3()),
            color: if erase { [1.0, 0.35, 0.3, 0.28] } else { [0.35, 0.65, 1.0, 0.28] },
        });
        let settings = FrameSettings { camera, wireframe, preview, ..Default::default() };
        let (_, cv, dv) = vp.color.as_ref().expect("created above");
        vp.renderer.render(&rs.device, &rs.queue, cv, dv, size, &settings);
        if let Some(id) = vp.texture_id {
            ui.painter().image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
        }
        // Repaint on our own only while meshing catches up or a stroke is in progress; pointer
        // and key events repaint anyway, so an idle editor uses no CPU.
        if self.studio.editor.pending() > 0 || self.studio.editor.stroking() {
            ui.ctx().request_repaint();
        }
    }
}

impl eframe::App for StudioApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.shortcuts(&ctx);
        egui::Panel::top("menu").show(ui, |ui| self.menu(ui));
        egui::Panel::bottom("status").show(ui, |ui| {
            ui.label(self.studio.status());
        });
        egui::Panel::left("tools").resizable(false).show(ui, |ui| self.palette(ui));
        egui::Panel::right("layers").show(ui, |ui| self.layers(ui));
        egui::CentralPanel::default().show(ui, |ui| self.viewport(ui, frame));
        self.prompt(&ctx);
    }
}

/// Opens the window on `studio` and runs until it closes.
pub fn run_window(studio: Studio) -> anyhow::Result<()> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_title("Strata Studio"),
        ..Default::default()
    };
    eframe::run_native("Strata Studio", options, Box::new(|cc| Ok(Box::new(StudioApp::new(cc, studio)))))
        .map_err(|e| anyhow::anyhow!("the window could not start: {e}"))
}
