//! The 3D viewport: pointer input for sculpting and the camera (scene and terrain mode), and
//! drawing: the editor's change list applied to the renderer through `strata_viewport`, the
//! brush preview, and the texture egui shows.

use super::*;

/// The GPU side of the viewport.
pub(super) struct Viewport {
    pub(super) renderer: Renderer,
    pub(super) size: (u32, u32),
    pub(super) color: Option<(wgpu::Texture, wgpu::TextureView, wgpu::TextureView)>,
    pub(super) texture_id: Option<egui::TextureId>,
    /// GPU meshing on this device, or why the adapter cannot do it.
    pub(super) gpu: Result<strata_viewport::GpuMeshing, String>,
    /// Set by the dual-contouring vertex solver when the device failed.
    pub(super) solver_failed: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl Viewport {
    /// Renders a frame into the viewport's texture and shows it in `rect`.
    fn present(
        &mut self,
        ui: &egui::Ui,
        rs: &egui_wgpu::RenderState,
        rect: egui::Rect,
        size: (u32, u32),
        settings: &FrameSettings<'_>,
    ) {
        let (_, cv, dv) = self.color.as_ref().expect("created before the first frame");
        self.renderer.render(&rs.device, &rs.queue, cv, dv, size, settings);
        if let Some(id) = self.texture_id {
            ui.painter().image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
        }
    }
}

/// Zooms `camera` by `factor` about `towards` (world), which stays where it is on screen: the
/// eye and the target both move along their lines through it. Without a point, about the target.
pub(super) fn zoom_towards(camera: &mut strata_render::Camera, towards: Option<glam::Vec3>, factor: f32) {
    let before = camera.distance;
    camera.zoom(factor);
    let Some(p) = towards.filter(|p| p.is_finite()) else { return };
    // (The zoom clamps the distance: move the target by the factor actually taken.)
    let f = camera.distance / before;
    camera.target = p + (camera.target - p) * f;
}

impl StudioApp {
    pub(super) fn viewport(&mut self, ui: &mut egui::Ui, frame: Option<&mut eframe::Frame>) {
        let (rect, response) = ui.allocate_exact_size(ui.available_size(), egui::Sense::click_and_drag());
        self.viewport_rect = Some(rect);
        let aspect = rect.width() / rect.height().max(1.0);
        if self.studio.terrain.is_some() {
            self.terrain_input(ui, &response, rect, aspect);
        } else if !self.gizmo_input(ui, rect) {
            self.scene_input(ui, &response, rect, aspect);
        }
        self.draw(ui, frame, rect);
        self.paint_gizmo(ui, rect);
        self.peer_cursors(ui, rect);
    }

    /// Terrain mode: WASD, Q and E fly (Shift faster), right drag looks; the world streams
    /// around the eye, bombs fly and debris falls; then the pointer drives the editor's tools on
    /// the world exactly as on a scene (left drag sculpts with the current tool, Ctrl or Alt the
    /// inverse tool, Shift smooths).
    pub(super) fn terrain_input(
        &mut self,
        ui: &mut egui::Ui,
        response: &egui::Response,
        rect: egui::Rect,
        aspect: f32,
    ) {
        use egui::Key;
        let typing = ui.ctx().egui_wants_keyboard_input() || self.modal_open();
        let held = |k: Key| !typing && ui.input(|i| i.key_down(k));
        let axis = |plus: Key, minus: Key| held(plus) as i32 as f64 - held(minus) as i32 as f64;
        let delta = ui.input(|i| i.pointer.delta());
        let look = if response.dragged_by(egui::PointerButton::Secondary) {
            (-delta.x as f64 * 0.005, delta.y as f64 * 0.005)
        } else {
            (0.0, 0.0)
        };
        let shift = ui.input(|i| i.modifiers.shift) && !typing;
        let input = crate::terrain::FlyInput {
            forward: axis(Key::W, Key::S),
            right: axis(Key::D, Key::A),
            up: axis(Key::E, Key::Q),
            look,
            fast: shift,
        };
        let now = Instant::now();
        let dt = self.last_frame.map_or(1.0 / 60.0, |t| now.duration_since(t).as_secs_f64());
        self.last_frame = Some(now);
        let Some(t) = self.studio.terrain.as_mut() else { return };
        t.fly(input, dt);
        t.tick(&mut self.studio.editor, dt);
        self.studio.camera = t.camera();
        self.studio.viewport_points = rect.height();
        self.studio.smooth_held = shift;
        self.studio.inverse_held = ui.input(|i| i.modifiers.command || i.modifiers.alt) && !typing;
        let (primary, alt) = ui.input(|i| (i.pointer.primary_down(), i.modifiers.alt));
        let secondary = alt && ui.input(|i| i.pointer.secondary_down());
        self.tool_pointer(ui, response, rect, aspect, primary, secondary);
        // The world streams, bombs fly and debris falls: draw every frame.
        ui.ctx().request_repaint();
    }

    pub(super) fn scene_input(&mut self, ui: &mut egui::Ui, response: &egui::Response, rect: egui::Rect, aspect: f32) {
        self.studio.viewport_points = rect.height();
        let to_ndc = |p: egui::Pos2| {
            let x = (p.x - rect.left()) / rect.width() * 2.0 - 1.0;
            let y = 1.0 - (p.y - rect.top()) / rect.height() * 2.0;
            (x, y)
        };
        if self.resize_input(ui) {
            return;
        }
        // Camera: right drag orbits, middle drag pans, the wheel zooms towards the pointer.
        let typing = ui.ctx().egui_wants_keyboard_input();
        self.studio.smooth_held = ui.input(|i| i.modifiers.shift) && !typing;
        self.studio.inverse_held = ui.input(|i| i.modifiers.command || i.modifiers.alt) && !typing;
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
        if response.hovered() {
            if scroll != 0.0 {
                let towards = response.hover_pos().map(to_ndc).map(|(x, y)| {
                    self.studio.surface_point(x, y, aspect).unwrap_or_else(|| {
                        // Nothing under the pointer: the point at the target's depth.
                        let cam = &self.studio.camera;
                        let (o, d) = cam.ray(x, y, aspect);
                        (o + d * cam.distance).as_dvec3()
                    })
                });
                zoom_towards(&mut self.studio.camera, towards.map(|p| p.as_vec3()), (-scroll * 0.001).exp());
            }
            if middle {
                self.studio.camera.pan(-delta.x / rect.height(), delta.y / rect.height());
            }
        }
        // Right drag orbits unless Alt is held (then it erases like the secondary tool button).
        let orbit = response.dragged_by(egui::PointerButton::Secondary) && !secondary_drag;
        if orbit {
            self.studio.camera.orbit(-delta.x * 0.008, delta.y * 0.008);
        }
        self.tool_pointer(ui, response, rect, aspect, primary, secondary && secondary_drag);
    }

    /// The pointer driving the tools, in a scene and on a world alike: `primary` and
    /// `secondary` the buttons held for the tool this frame (the secondary: Alt + right drag).
    fn tool_pointer(
        &mut self,
        ui: &mut egui::Ui,
        response: &egui::Response,
        rect: egui::Rect,
        aspect: f32,
        primary: bool,
        secondary: bool,
    ) {
        let to_ndc = |p: egui::Pos2| {
            let x = (p.x - rect.left()) / rect.width() * 2.0 - 1.0;
            let y = 1.0 - (p.y - rect.top()) / rect.height() * 2.0;
            (x, y)
        };
        // Presses and releases of the primary button in this frame, in order, each where it
        // happened: a quick click within one slow frame is a dab (or a line end), not lost.
        let layer = ui.layer_id();
        let clicks: Vec<(egui::Pos2, bool)> = ui.input(|i| {
            i.events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::PointerButton { pos, button: egui::PointerButton::Primary, pressed, .. } => {
                        Some((*pos, *pressed))
                    }
                    _ => None,
                })
                .collect()
        });
        let budget = Duration::from_millis(6);
        let pressure = self.read_pressure(ui);
        let mut down = self.studio.editor.stroking();
        for (pos, pressed) in clicks {
            let on_viewport = rect.contains(pos) && ui.ctx().layer_id_at(pos) == Some(layer);
            if pressed && on_viewport && !self.modal_open() {
                let held = Buttons { primary: true, secondary: false };
                self.studio.pointer(Some(to_ndc(pos)), held, pressure, aspect, budget);
                down = true;
            } else if !pressed && down {
                self.studio.pointer(Some(to_ndc(pos)), Buttons::default(), pressure, aspect, budget);
                down = false;
            }
        }
        let ndc = response.hover_pos().filter(|_| response.hovered() || response.dragged()).map(to_ndc);
        let buttons = Buttons {
            primary: primary
                && (response.dragged_by(egui::PointerButton::Primary) || response.is_pointer_button_down_on()),
            secondary,
        };
        self.studio.pointer(ndc, buttons, pressure, aspect, budget);
    }

    /// The pressure this frame's dabs are made at: the force of the latest touch event that
    /// gives one (egui's `Event::Touch`, which eframe makes of winit's touch events; winit
    /// reports a pen's pressure as such a touch's force where the platform gives it to it), held
    /// until the touch ends; full pressure without one (a mouse).
    fn read_pressure(&mut self, ui: &egui::Ui) -> f64 {
        let touches: Vec<(egui::TouchPhase, Option<f32>)> = ui.input(|i| {
            i.events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::Touch { phase, force, .. } => Some((*phase, *force)),
                    _ => None,
                })
                .collect()
        });
        let mut now = self.pen_pressure;
        for (phase, force) in touches {
            match (phase, force) {
                (egui::TouchPhase::Start | egui::TouchPhase::Move, Some(f)) if f.is_finite() => {
                    now = Some(f.clamp(0.0, 1.0) as f64)
                }
                (egui::TouchPhase::End | egui::TouchPhase::Cancel, _) => {
                    // (This frame's dabs still take the touch's last pressure.)
                    let last = now;
                    self.pen_pressure = None;
                    return last.unwrap_or(1.0);
                }
                _ => {}
            }
        }
        self.pen_pressure = now;
        now.unwrap_or(1.0)
    }

    pub(super) fn draw(&mut self, ui: &mut egui::Ui, frame: Option<&mut eframe::Frame>, rect: egui::Rect) {
        let Some(rs) = frame.and_then(|f| f.wgpu_render_state()) else {
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
        self.studio.viewport_height = size.1 as f32;
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
        // What the editor's meshes changed since the last frame (a scene's or a world's),
        // applied by the one mirror.
        // GPU meshing as asked, where this device can (a new scene's editor is set here too).
        let gpu = vp.gpu.as_mut().ok().filter(|_| self.studio.gpu_meshing);
        if self.studio.editor.gpu_meshing() != gpu.is_some() {
            self.studio.editor.set_gpu_meshing(gpu.is_some());
        }
        // Dual contouring's vertices too, solved on the GPU and joined here.
        if self.studio.editor.has_vertex_solver() != gpu.is_some() {
            let solver = gpu.as_ref().map(|g| g.vertex_solver(&rs.device, &rs.queue, vp.solver_failed.clone()));
            self.studio.editor.set_vertex_solver(solver);
        }
        let changes = self.studio.editor.take_changes();
        let applied = strata_viewport::apply_changes_with(
            &self.studio.editor,
            &changes,
            &rs.device,
            &rs.queue,
            &mut vp.renderer,
            gpu,
        );
        if let Err(e) = applied {
            // The device failed while meshing: the CPU meshes everything again.
            self.studio.gpu_meshing = false;
            self.studio.editor.set_gpu_meshing(false);
            self.studio.editor.set_vertex_solver(None);
            self.studio.fail(format!("GPU meshing failed ({e}): the CPU meshes the viewport now"));
        }
        if vp.solver_failed.swap(false, std::sync::atomic::Ordering::Relaxed) {
            self.studio.gpu_meshing = false;
            self.studio.editor.set_gpu_meshing(false);
            self.studio.editor.set_vertex_solver(None);
            self.studio.fail(
                "GPU meshing failed while solving dual contouring's vertices: the CPU meshes the viewport now".into(),
            );
        }
        self.studio.gpu_chunks = vp.renderer.indirect_count();
        if let Some(t) = &self.studio.terrain {
            // Terrain mode's debris and bombs in flight (an empty mesh drops them).
            let debris = t.particle_mesh();
            vp.renderer.upload_mesh(
                &rs.device,
                &rs.queue,
                strata_viewport::OVERLAY_ID,
                strata_viewport::mesh_ref(&debris),
                Placement::default(),
                [1.0; 3],
            );
        }
        let inverse = self.studio.inverse_held;
        let kind = self.studio.editor.tool.kind;
        let erase = matches!(
            (kind, inverse),
            (ToolKind::Erase, false) | (ToolKind::Add | ToolKind::Clay | ToolKind::Stamp, true)
        );
        let field = kind.is_field_tool() || self.studio.smooth_held;
        let wireframe = self.studio.wireframe;
        let camera = self.studio.camera;
        let dabs = self.studio.preview_dabs();
        // The waiting insert's preview mesh and where it goes (world).
        let insert = self.studio.insert.as_ref().map(|i| {
            let p = &i.placement;
            let model = Mat4::from_scale_rotation_translation(
                glam::Vec3::splat((p.size / i.mesh.size()) as f32),
                p.rotation.as_quat(),
                p.position.as_vec3(),
            );
            (i.mesh.preview_shared(), model)
        });
        let scale = glam::Vec3::splat(self.studio.preview_scale() as f32);
        self.studio.refresh_preview();
        let preview_mesh = strata_viewport::mesh_ref(self.studio.built_preview());
        let rgb = if erase { [1.0, 0.35, 0.3] } else { [0.35, 0.65, 1.0] };
        let mut previews = Vec::with_capacity(dabs.len() * 2);
        for (k, (p, q)) in dabs.into_iter().enumerate() {
            // The dab itself brighter than its mirror images.
            let alpha = if k == 0 { 0.22 } else { 0.12 };
            let model = Mat4::from_scale_rotation_translation(scale, q.as_quat(), p.as_vec3());
            previews.push(Preview { mesh: preview_mesh, model, color: [rgb[0], rgb[1], rgb[2], alpha] });
            if field {
                // The falloff: a core where the tool acts at half strength or more.
                let core = Mat4::from_scale(glam::Vec3::splat(FALLOFF_HALF as f32));
                previews.push(Preview {
                    mesh: preview_mesh,
                    model: model * core,
                    color: [rgb[0], rgb[1], rgb[2], alpha * 1.6],
                });
            }
        }
        if let Some((mesh, model)) = &insert {
            previews.push(Preview {
                mesh: strata_viewport::mesh_ref(mesh),
                model: *model,
                color: [0.45, 0.9, 0.5, 0.35],
            });
        }
        let references = if self.studio.show_references {
            strata_viewport::reference_quads(&self.studio.editor.scene)
        } else {
            Vec::new()
        };
        let settings =
            FrameSettings { camera, wireframe, previews: &previews, references: &references, ..Default::default() };
        vp.present(ui, rs, rect, size, &settings);
        // Repaint on our own only while meshing catches up or a stroke is in progress; pointer
        // and key events repaint anyway, so an idle editor uses no CPU.
        if self.studio.editor.pending() > 0 || self.studio.editor.stroking() {
            ui.ctx().request_repaint();
        }
    }
}
