//! The pointer over the viewport: one pick per frame, the pose (position, orientation,
//! pressure, buttons, modifiers) handed to the editor, strokes that follow the surface, the
//! line tool, the eyedropper, large dabs in the background, and the brush's size on screen.

use super::*;

/// Where the ray `o + t·d` meets the ground plane y = 0 in front of the eye, if it does.
pub(super) fn ground_point(o: DVec3, d: DVec3) -> Option<DVec3> {
    (d.y < -1e-6).then(|| o + d * (-o.y / d.y))
}

impl Studio {
    /// World units per screen point at distance `depth` from the eye (for a perspective view;
    /// an orthographic view has the same scale everywhere).
    pub fn world_per_point(&self, depth: f64) -> f64 {
        let c = &self.camera;
        let half = (c.fov_y as f64 * 0.5).tan();
        let span = if c.orthographic { 2.0 * c.distance as f64 * half } else { 2.0 * depth.max(1e-6) * half };
        span / self.viewport_points.max(1.0) as f64
    }

    /// With a screen-space radius, sets the tool's world radius from
    /// [`Studio::radius_points`] at the depth of `at` (or of the view's target).
    pub fn apply_screen_radius(&mut self, at: Option<DVec3>) {
        if !self.screen_radius {
            return;
        }
        let eye = self.camera.eye().as_dvec3();
        let depth = at.map_or(self.camera.distance as f64, |p| (p - eye).length());
        let r = self.radius_points.clamp(1.0, 2000.0) as f64 * self.world_per_point(depth);
        if r.is_finite() {
            self.editor.tool.radius = r.clamp(0.05, 256.0);
        }
    }

    /// One frame of pointer input over the viewport: `ndc` the pointer in normalised device
    /// coordinates (`None` when outside), the buttons held, and the viewport's aspect ratio.
    /// The tool acts at the surface under the pointer (or on the ground plane when nothing is
    /// hit) while a button is held; a stroke keeps its depth when it leaves the surface.
    pub fn pointer(&mut self, ndc: Option<(f32, f32)>, buttons: Buttons, pressure: f64, aspect: f32, budget: Duration) {
        self.update_lod();
        // Joining a room: the scene on screen is about to be replaced by the room's, and a
        // stroke on it would be sent into the room's.
        let held = buttons.primary || buttons.secondary;
        if let Some(c) = self.collab.as_ref().filter(|c| !c.session.replica().has_scene()) {
            if held && !self.prev_held {
                self.message = format!("Waiting for room {:?}'s scene before sculpting…", c.params.room);
            }
            self.prev_held = held;
            self.hover = None;
            return;
        }
        // A dab the room would refuse is not made (in a room every dab is made in the frame:
        // one over the room's limit would hold the window, then be taken back).
        if held && let Some(cells) = self.over_room_radius(pressure) {
            if !self.prev_held {
                self.fail(format!(
                    "In a shared room a brush may reach {} cells of its layer at most (this one reaches {cells:.0}): make it smaller",
                    strata_net::Limits::default().max_radius_cells
                ));
            }
            self.prev_held = held;
            return;
        }
        // Holding Shift smooths, whatever the tool; Ctrl or Alt inverts it (the sculptors'
        // conventions): the pose says so, the tool and the buttons stay as they are.
        let modifiers = Modifiers { inverted: self.inverse_held, smooth: self.smooth_held };
        if self.insert.is_some() {
            self.place_insert(ndc, buttons.primary, aspect);
        } else if self.eyedropper && self.job.is_none() {
            self.eyedropper_click(ndc, buttons, aspect);
        } else if self.line_mode && self.job.is_none() {
            self.line_click(ndc, buttons, modifiers, pressure, aspect);
        } else {
            self.pointer_with_tool(ndc, buttons, modifiers, pressure, aspect, budget);
        }
        self.prev_held = buttons.primary || buttons.secondary;
    }

    /// In a room, the radius in cells of the surface the tools edit when it is over the room's
    /// limit.
    fn over_room_radius(&self, pressure: f64) -> Option<f64> {
        self.collab.as_ref()?;
        let scale = self.editor.surface(self.editor.active_surface())?.transform().scale;
        let cells = self.editor.tool.radius_at(pressure) / scale;
        (cells > strata_net::Limits::default().max_radius_cells).then_some(cells)
    }

    /// Tells the editor where the camera is, for level of detail (when the view changed).
    pub fn update_lod(&mut self) {
        let view = self.lod.then(|| strata_editor::LodView {
            eye: self.camera.eye().as_dvec3(),
            pixels_per_radian: (self.viewport_height.max(1.0) / self.camera.fov_y.max(1e-3)) as f64,
            pixel_error: self.lod_pixels.max(0.1),
        });
        if view != self.last_lod {
            self.editor.set_view(view);
            self.last_lod = view;
        }
    }

    /// A frame of the armed eyedropper: a click on the model takes the material under it.
    pub(super) fn eyedropper_click(&mut self, ndc: Option<(f32, f32)>, buttons: Buttons, aspect: f32) {
        let pick = ndc.and_then(|(x, y)| {
            let (o, d) = self.camera.ray(x, y, aspect);
            self.editor.pick(o.as_dvec3(), d.as_dvec3(), 1.0e4)
        });
        self.hover = pick.as_ref().map(|p| p.point);
        let held = buttons.primary || buttons.secondary;
        if !held || self.prev_held {
            return;
        }
        let Some(pick) = pick else { return };
        match self.editor.material_at(&pick) {
            Some(id) => {
                self.editor.tool.material = id;
                let name = self.editor.scene.materials.get(id as usize).map_or("?", |m| m.name.as_str());
                self.message = format!("Material: {name}");
            }
            None => self.message = "Eyedropper: no material there".into(),
        }
        self.eyedropper = false;
    }

    /// A frame of the armed line tool: the first click picks the line's start, the second its end
    /// and applies the stroke (one undo step).
    pub(super) fn line_click(
        &mut self,
        ndc: Option<(f32, f32)>,
        buttons: Buttons,
        modifiers: Modifiers,
        pressure: f64,
        aspect: f32,
    ) {
        let target = ndc.and_then(|(x, y)| self.surface_point(x, y, aspect));
        self.hover = target;
        let held = buttons.primary || buttons.secondary;
        let (Some(p), true) = (target, held && !self.prev_held) else { return };
        match self.line_start.take() {
            None => {
                self.line_start = Some(p);
                self.message = "Line: click the other end".into();
            }
            Some(a) => {
                let modifiers = Modifiers { inverted: modifiers.inverted || !buttons.primary, ..modifiers };
                match self.editor.line_stroke(a, p, pressure, modifiers) {
                    Ok(report) => {
                        self.message = format!("Line: {} dabs", report.dabs);
                    }
                    Err(e) => self.fail(e.to_string()),
                }
                self.line_mode = false;
            }
        }
    }

    pub(super) fn pointer_with_tool(
        &mut self,
        ndc: Option<(f32, f32)>,
        buttons: Buttons,
        modifiers: Modifiers,
        pressure: f64,
        aspect: f32,
        budget: Duration,
    ) {
        let held = buttons.primary || buttons.secondary;
        // A stroke follows the surface under the pointer, skipping what its own dabs built or
        // carved (`Editor::stroke_surface`); where that surface is hidden under the stroke's
        // own work, and always with "follow the surface" off or for grab, it keeps its depth.
        let ray = ndc.map(|(x, y)| {
            let (o, d) = self.camera.ray(x, y, aspect);
            (o.as_dvec3(), d.as_dvec3())
        });
        // (Shift smooths whatever the tool: a smoothing stroke follows the surface, even with grab
        // chosen.)
        let follow = self.editor.tool.follow_surface && (self.editor.tool.kind != ToolKind::Grab || modifiers.smooth);
        let target = match (ray, self.stroke_depth.filter(|_| held)) {
            (Some((o, d)), Some(depth)) => {
                let depth = if follow && self.editor.stroking() {
                    self.editor.stroke_surface(o, d, 1.0e4).unwrap_or(depth)
                } else {
                    depth
                };
                self.stroke_depth = Some(depth);
                Some(o + d * depth)
            }
            (Some((o, d)), None) => {
                // One pick: the point under the pointer and its normal (for oriented brushes).
                let hit = self.editor.pick(o, d, 1.0e4);
                self.hover_normal = hit.map(|h| h.normal);
                let p = hit.map(|h| h.point).or_else(|| self.ground_fallback(o, d));
                if held {
                    self.stroke_depth = p.map(|p| (p - o).length());
                }
                p
            }
            (None, _) => None,
        };
        if !held {
            self.stroke_depth = None;
        }
        self.hover = target;
        self.apply_screen_radius(target);
        if self.job.is_some() {
            // A large dab is running: input waits for it (the app shows its progress).
            return;
        }
        if !held {
            self.last_background_dab = None;
        }
        let pose = match target {
            Some(p) if held => {
                ToolPose { position: p, orientation: self.brush_orientation(), pressure, buttons, modifiers }
            }
            _ => ToolPose {
                position: target.unwrap_or_default(),
                orientation: self.brush_orientation(),
                pressure,
                buttons: Buttons::default(),
                ..ToolPose::default()
            },
        };
        // Dabs too large for a frame are refused by the editor (which builds each dab's brush
        // once) and run in the background instead.
        // (In a room every dab is an operation of the frame: none goes to the background, and
        // the room refuses dabs over its radius limit.)
        self.editor.frame_dab_limit = if self.in_session() { u64::MAX } else { self.background_chunks };
        match self.editor.frame(&pose, budget) {
            Err(strata_editor::EditorError::DabTooLargeForFrame(_)) => {
                // Like a stroke's dabs: the next large dab waits until the pointer has moved by
                // the dab spacing (holding still does not repeat it).
                let spacing = self.editor.tool.dab_spacing();
                if self.last_background_dab.is_some_and(|last| (pose.position - last).length() < spacing) {
                    return;
                }
                self.last_background_dab = Some(pose.position);
                match self.editor.start_dab_job(&pose) {
                    Ok(job) => {
                        self.job = Some(job);
                        self.message = "Sculpting a large dab…".into();
                    }
                    Err(e) => self.fail(e.to_string()),
                }
            }
            Ok(report) => {
                if report.dabs > 0 {
                    self.last_edit_ms = report.edit_time.as_secs_f64() * 1e3;
                }
                if !report.remeshed.is_empty() {
                    self.last_remesh_ms = report.remesh_time.as_secs_f64() * 1e3;
                }
            }
            Err(e) => self.fail(e.to_string()),
        }
    }

    /// The brush's orientation for the next dab: the camera's for the stamp tool (its y axis,
    /// the stamp's top, is the screen's up), onto the surface normal under the pointer when the
    /// alignment tool orients brushes, else the world's axes.
    pub fn brush_orientation(&self) -> DQuat {
        if self.editor.tool.kind == ToolKind::Stamp {
            let eye = self.camera.eye().as_dvec3();
            let back = (eye - self.camera.target.as_dvec3()).normalize_or(DVec3::Z);
            let right = DVec3::Y.cross(back).normalize_or(DVec3::X);
            return DQuat::from_mat3(&glam::DMat3::from_cols(right, back.cross(right), back));
        }
        match self.hover_normal.filter(|_| self.editor.tool.orient_to_normal) {
            Some(n) => strata_editor::orientation_for_normal(n),
            None => DQuat::IDENTITY,
        }
    }

    /// Collects a finished background dab (call every frame); returns whether one finished.
    pub fn poll_job(&mut self) -> bool {
        if !self.job.as_ref().is_some_and(|j| j.is_finished()) {
            return false;
        }
        let job = self.job.take().expect("checked above");
        let secs = job.elapsed().as_secs_f64();
        self.message = match self.editor.finish_dab_job(job) {
            Ok(changed) => format!("Large dab: {changed} chunks changed in {secs:.1} s"),
            Err(strata_editor::EditorError::Edit(strata_volume::EditError::Cancelled)) => {
                "Large dab cancelled: nothing changed".into()
            }
            Err(e) => {
                self.notice = Some(e.to_string());
                e.to_string()
            }
        };
        true
    }

    /// The world point the tool acts on under viewport point `(x, y)` (NDC): the first surface
    /// hit, or the ground plane y = 0 when nothing is hit.
    pub fn surface_point(&self, x: f32, y: f32, aspect: f32) -> Option<DVec3> {
        let (o, d) = self.camera.ray(x, y, aspect);
        self.ray_target(o.as_dvec3(), d.as_dvec3())
    }

    /// Where a ray that meets no surface acts: the ground plane y = 0 in a scene; nowhere on a
    /// world (whose ground is its surface: a miss looks at the sky or past what is loaded).
    fn ground_fallback(&self, o: DVec3, d: DVec3) -> Option<DVec3> {
        if self.editor.world().is_some() { None } else { ground_point(o, d) }
    }

    pub(super) fn ray_target(&self, o: DVec3, d: DVec3) -> Option<DVec3> {
        self.editor.pick(o, d, 1.0e4).map(|hit| hit.point).or_else(|| self.ground_fallback(o, d))
    }
}
