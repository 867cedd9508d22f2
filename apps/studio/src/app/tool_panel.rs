//! The tool panel: the tools, their options, the brush (shape, radius, pressure, spacing),
//! alignment and mirroring, and the material palette.

use super::*;

impl StudioApp {
    pub(super) fn palette(&mut self, ui: &mut egui::Ui) {
        if self.studio.insert.is_some() {
            self.insert_panel(ui);
        }
        let tool = &mut self.studio.editor.tool;
        ui.heading("Tool");
        let tips = [
            (ToolKind::Clay, "Add clay that blends into the surface in a soft fillet (Ctrl/Alt: carve)"),
            (ToolKind::Add, "Add the brush shape exactly (CSG union; Ctrl/Alt: erase)"),
            (ToolKind::Erase, "Cut the brush shape away exactly (CSG difference; Ctrl/Alt: add)"),
            (
                ToolKind::Smooth,
                "Smooth the surface, keeping its volume (hold Shift with any tool; Ctrl/Alt: Laplacian)",
            ),
            (ToolKind::Inflate, "Push the surface out along its normal (Ctrl/Alt: deflate)"),
            (ToolKind::Flatten, "Pull the surface towards the plane that fits it under the brush"),
            (ToolKind::Pinch, "Pull the surface towards the stroke into a crease (Ctrl/Alt: push apart)"),
            (ToolKind::Grab, "Drag the surface under the brush with the pointer"),
            (
                ToolKind::Detail,
                "Add resolution under the brush for fine detail (Ctrl/Alt: back to the layer's base level)",
            ),
            (ToolKind::Paint, "Paint the current material without changing the shape (Ctrl/Alt: the first material)"),
            (
                ToolKind::Stamp,
                "Stamp: raise a grey-scale picture on the surface, white highest (Ctrl/Alt: carve it in)",
            ),
            (
                ToolKind::Mask,
                "Mask: protect what the brush covers from every tool, drawn darker (Ctrl/Alt: unmask; Shift: smooth the mask)",
            ),
        ];
        for row in tips.chunks(3) {
            ui.horizontal(|ui| {
                for &(kind, tip) in row {
                    ui.selectable_value(&mut tool.kind, kind, labelled(kind.name(), Command::Tool(kind)))
                        .on_hover_text(tip);
                }
            });
        }
        // (A tool picked here brings its own falloff at once.)
        self.studio.sync_falloff();
        self.preset_shelf(ui);
        // The tool's own options in a box of fixed height (the tallest tool's: the stamp's), so
        // that nothing below moves under the pointer when the tool changes (a mis-click once
        // landed in the material name field that way).
        let row = ui.spacing().interact_size.y + ui.spacing().item_spacing.y;
        ui.allocate_ui_with_layout(
            egui::vec2(ui.available_width(), 4.0 * row),
            egui::Layout::top_down(egui::Align::Min),
            |ui| {
                ui.set_min_height(4.0 * row);
                let tool = &mut self.studio.editor.tool;
                if tool.kind.is_field_tool() && tool.kind != ToolKind::Grab {
                    ui.add(egui::Slider::new(&mut tool.field_strength, 0.0..=1.0).text("tool strength"))
                        .on_hover_text("How strongly a dab acts at its centre; the falloff takes it to 0 at the rim");
                }
                if tool.kind == ToolKind::Grab {
                    ui.label("Grab moves the surface as far as the pointer");
                }
                if tool.kind == ToolKind::Clay {
                    ui.add(egui::Slider::new(&mut tool.fillet, 0.0..=2.0).text("fillet (× radius)"))
                        .on_hover_text("How softly clay blends into the surface: 0 is a plain union");
                }
                if tool.kind == ToolKind::Detail {
                    ui.horizontal(|ui| {
                        ui.label("raise to");
                        for k in 1..=strata_volume::coords::MAX_LEVEL {
                            let level = strata_volume::Level::new(k).expect("a level");
                            ui.selectable_value(&mut tool.detail_level, level, format!("{}³ cells", 16 << k))
                                .on_hover_text("Cells per chunk side the chunks under the brush get");
                        }
                    });
                }
                if tool.kind == ToolKind::Mask {
                    let mut run = None;
                    ui.horizontal(|ui| {
                        for a in strata_editor::MaskAction::ALL {
                            let label = a.name().trim_end_matches(" mask");
                            let tip = format!("{} ({})", super::menus::mask_tip(a), keys_of(Command::Mask(a)));
                            if ui.button(label).on_hover_text(tip).clicked() {
                                run = Some(a);
                            }
                        }
                    });
                    if let Some(a) = run {
                        let _ = self.studio.act(Action::Mask(a));
                    }
                }
                if self.studio.editor.tool.kind == ToolKind::Stamp {
                    self.stamp_options(ui);
                }
                let tool = &mut self.studio.editor.tool;
                if tool.kind == ToolKind::Smooth {
                    ui.checkbox(&mut tool.paper_smoothing, "Paper's smoothing (Eq. 1)").on_hover_text(
                        "Move crossings towards their neighbours' mean instead of smoothing the field (shrinks a little)",
                    );
                }
            },
        );
        self.falloff_editor(ui);
        ui.horizontal(|ui| {
            ui.label(labelled("Stabiliser", Command::Stabiliser));
            for s in strata_editor::Stabiliser::ALL {
                let tip = match s {
                    strata_editor::Stabiliser::Off => "The brush is where the pointer is",
                    strata_editor::Stabiliser::Weak => {
                        "The brush trails the pointer on a rope of one radius: steadier lines"
                    }
                    strata_editor::Stabiliser::Strong => {
                        "The brush trails the pointer on a rope of three radii: clean lines from a shaky hand"
                    }
                };
                ui.selectable_value(&mut self.studio.editor.stabiliser, s, s.name()).on_hover_text(tip);
            }
        });
        let mut toggle = None;
        ui.horizontal(|ui| {
            ui.label("Mirror");
            for (axis, name) in ["X (X)", "Y", "Z"].into_iter().enumerate() {
                let mut on = self.studio.editor.tool.symmetry[axis];
                if ui.checkbox(&mut on, name).on_hover_text("Mirror every dab across this plane of the layer").changed()
                {
                    toggle = Some(axis);
                }
            }
        });
        if let Some(axis) = toggle {
            self.studio.toggle_symmetry(axis);
        }
        let tool = &mut self.studio.editor.tool;
        ui.label("Shape (B cycles; add and erase)");
        ui.horizontal(|ui| {
            for (shape, name) in [
                (BrushShape::Sphere, "Sphere"),
                (BrushShape::Box, "Box"),
                (BrushShape::Capsule, "Capsule"),
                (BrushShape::Cylinder, "Cylinder"),
            ] {
                ui.selectable_value(&mut tool.shape, shape, name)
                    .on_hover_text("The shape of the add and erase brushes (field tools act in a ball)");
            }
        });
        let (down, up, drag) =
            (keys_of(Command::RadiusDown), keys_of(Command::RadiusUp), keys_of(Command::ResizeBrush));
        let keys = format!("({down} and {up} change it, {drag} drags it)");
        if self.studio.screen_radius {
            ui.add(
                egui::Slider::new(&mut self.studio.radius_points, 2.0..=400.0)
                    .logarithmic(true)
                    .text(format!("radius (points) {down} {up} {drag}")),
            )
            .on_hover_text(format!("Brush radius on screen: the same size whatever the zoom {keys}"));
        } else {
            ui.add(
                egui::Slider::new(&mut self.studio.editor.tool.radius, 0.25..=64.0)
                    .logarithmic(true)
                    .text(format!("radius {down} {up} {drag}")),
            )
            .on_hover_text(format!("Brush radius in world units {keys}"));
        }
        ui.checkbox(&mut self.studio.screen_radius, "Radius on screen")
            .on_hover_text("Keep the brush's size on screen as the view zooms, instead of its size in the world");
        let tool = &mut self.studio.editor.tool;
        ui.checkbox(&mut tool.follow_surface, "Follow the surface").on_hover_text(
            "Strokes follow the surface under the pointer; off, a stroke keeps the depth where it started",
        );
        self.pressure_controls(ui);
        let tool = &mut self.studio.editor.tool;
        ui.add(egui::Slider::new(&mut tool.spacing, 0.05..=1.0).text("dab spacing"))
            .on_hover_text("Distance between a stroke's dabs, as a fraction of the radius");
        ui.separator();
        ui.label("Alignment");
        ui.horizontal(|ui| {
            ui.label("snap to grid");
            ui.add(egui::DragValue::new(&mut tool.grid_snap).range(0.0..=64.0).speed(0.25).suffix(" cells"))
                .on_hover_text("Place dabs on multiples of this many cells of the layer's grid (0: off)");
        });
        ui.horizontal(|ui| {
            ui.label("lock stroke");
            ui.selectable_value(&mut tool.axis_lock, None, "off").on_hover_text("Strokes go where the pointer goes");
            for (axis, name) in ["along X", "along Y", "along Z"].into_iter().enumerate() {
                ui.selectable_value(&mut tool.axis_lock, Some(axis), name)
                    .on_hover_text("Keep a stroke on the line through its start along this axis of the layer");
            }
        });
        ui.checkbox(&mut tool.orient_to_normal, "Orient brush to surface")
            .on_hover_text("Turn box, capsule and cylinder brushes onto the surface normal under the pointer");
        ui.separator();
        ui.label(format!(
            "Ctrl or Alt + drag: the inverse tool. Shift: smooth. {}: line tool. {}: mirror X.",
            keys_of(Command::Line),
            keys_of(Command::MirrorX)
        ));
        ui.separator();
        self.materials(ui);
    }

    /// The material palette: the current material (what add and clay add and paint paints),
    /// each material's colour, texture, scale and roughness, the eyedropper and a new material.
    pub(super) fn materials(&mut self, ui: &mut egui::Ui) {
        ui.heading("Materials");
        let mut changed = false;
        let current = &mut self.studio.editor.tool.material;
        let palette = &mut self.studio.editor.scene.materials;
        ui.horizontal_wrapped(|ui| {
            for (i, m) in palette.iter().enumerate() {
                let [r, g, b] = m.color.map(|c| (c.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0) as u8);
                let text = egui::RichText::new(&m.name).strong().color(egui::Color32::from_rgb(r, g, b));
                ui.selectable_value(current, i as u8, text).on_hover_text("Add, clay and paint use this material");
            }
        });
        // (In a shared room the palette is the room's: its materials are not edited here.)
        let shared = self.studio.collab.is_some();
        if let Some(m) = palette.get_mut(*current as usize).filter(|_| !shared) {
            ui.horizontal(|ui| {
                let label = ui.label("material name");
                changed |= ui
                    .text_edit_singleline(&mut m.name)
                    .labelled_by(label.id)
                    .on_hover_text("The current material's name")
                    .changed();
            });
            ui.horizontal(|ui| {
                ui.label("colour");
                changed |=
                    ui.color_edit_button_rgb(&mut m.color).on_hover_text("The current material's colour").changed();
                egui::ComboBox::from_label("texture")
                    .selected_text(m.texture.name())
                    .show_ui(ui, |ui| {
                        for t in strata_editor::Texture::ALL {
                            changed |= ui
                                .selectable_value(&mut m.texture, t, t.name())
                                .on_hover_text("A procedural pattern, projected on three axes")
                                .changed();
                        }
                    })
                    .response
                    .on_hover_text("The current material's surface pattern");
            });
            changed |= ui
                .add(egui::Slider::new(&mut m.scale, 1.0..=128.0).logarithmic(true).text("texture scale"))
                .on_hover_text("World units per repeat of the texture")
                .changed();
            changed |= ui
                .add(egui::Slider::new(&mut m.roughness, 0.0..=1.0).text("roughness"))
                .on_hover_text("How blurred its highlights are: 0 glossy, 1 matte")
                .changed();
        }
        ui.horizontal(|ui| {
            let dropper = if self.studio.eyedropper { "Eyedropper (armed)" } else { "Eyedropper (K)" };
            if ui.button(dropper).on_hover_text("Click the model to take the material under the pointer").clicked() {
                self.studio.toggle_eyedropper();
            }
            if ui
                .button("New material")
                .on_hover_text("Add a material to the palette and make it current (also Brush menu)")
                .clicked()
            {
                self.studio.add_material();
            }
        });
        if changed {
            self.studio.editor.touch();
        }
    }

    /// The stamp tool's options: its picture, spray or drag, and its turn.
    fn stamp_options(&mut self, ui: &mut egui::Ui) {
        let choices = self.studio.stamp_choices();
        let mut load = false;
        ui.horizontal(|ui| {
            let current = self.studio.stamp_name();
            let tip =
                format!("The picture the stamp raises, white highest ({} picks the next)", keys_of(Command::NextStamp));
            egui::ComboBox::from_id_salt("stamp picture")
                .selected_text(current)
                .show_ui(ui, |ui| {
                    for (source, name) in &choices {
                        ui.selectable_value(&mut self.studio.editor.tool.stamp.source, *source, name.as_str());
                    }
                })
                .response
                .on_hover_text(tip);
            load = ui
                .button("Load PNG…")
                .on_hover_text(format!(
                    "Use a grey-scale PNG as the stamp's picture ({}, or drop it on the window)",
                    keys_of(Command::LoadStamp)
                ))
                .clicked();
        });
        let stamp = &mut self.studio.editor.tool.stamp;
        ui.horizontal(|ui| {
            let keys = keys_of(Command::StampStroke);
            ui.selectable_value(&mut stamp.stroke, strata_editor::StampStroke::Spray, "Spray")
                .on_hover_text(format!("A stamp every dab spacing along the stroke ({keys} switches)"));
            ui.selectable_value(&mut stamp.stroke, strata_editor::StampStroke::Drag, "Drag")
                .on_hover_text(format!(
                    "One stamp: press at its middle, drag to size it and turn its top towards the pointer, release to apply ({keys} switches)"
                ));
            ui.checkbox(&mut stamp.follow_stroke, "Follow stroke")
                .on_hover_text("A sprayed stamp's top points along the stroke (else up the screen)");
        });
        ui.add(egui::Slider::new(&mut stamp.angle, -180.0..=180.0).suffix("°").text("turn"))
            .on_hover_text("Turn the picture about the surface normal, counter-clockwise");
        if load {
            let ctx = ui.ctx().clone();
            self.ask_path(&ctx, Prompt::LoadStamp, None);
        }
    }

    /// Pressure: on or off, how much it scales the size and the strength, and the two curves.
    fn pressure_controls(&mut self, ui: &mut egui::Ui) {
        let keys = keys_of(Command::Pressure);
        let header = egui::CollapsingHeader::new(format!("Pressure ({keys})"))
            .id_salt("pressure")
            .default_open(false)
            .show(ui, |ui| self.pressure_body(ui));
        header.header_response.on_hover_text("How a pen's or a touch's pressure scales the brush");
    }

    fn pressure_body(&mut self, ui: &mut egui::Ui) {
        let tool = &mut self.studio.editor.tool;
        let keys = keys_of(Command::Pressure);
        let reading = match self.pen_pressure {
            Some(p) => format!("the pen reads {p:.2}"),
            None => "no pen pressure this touch: a mouse dabs at full pressure".into(),
        };
        ui.checkbox(&mut tool.pressure.enabled, format!("Pressure on ({keys})")).on_hover_text(format!(
            "A pen's or a touch's pressure scales the brush through the curves below; off, every dab is as at full pressure ({reading})"
        ));
        ui.add_enabled_ui(tool.pressure.enabled, |ui| {
            let tool = &mut self.studio.editor.tool;
            ui.add(egui::Slider::new(&mut tool.strength, 0.0..=1.0).text("pressure to size"))
                .on_hover_text("How much pressure scales the radius (0: not at all)");
            ui.add(egui::Slider::new(&mut tool.pressure_to_strength, 0.0..=1.0).text("pressure to strength"))
                .on_hover_text("How much pressure scales the tool strength (0: not at all)");
            ui.horizontal(|ui| {
                ui.label("curves").on_hover_text("Pressure left to right, its factor up: size, then strength");
                for size in [true, false] {
                    let curve = if size { &mut tool.pressure.size } else { &mut tool.pressure.strength };
                    let shape = *curve;
                    let tip = if size {
                        "The size curve: pressure left to right, the radius's factor up; drag a point"
                    } else {
                        "The strength curve: pressure left to right, the strength's factor up; drag a point"
                    };
                    if let Some(c) = super::presets_panel::curve_plot(ui, &|t| shape.at(t), &shape.points(), tip) {
                        *curve = c;
                    }
                }
            });
        });
    }

    /// The waiting insert: its size and turn, and the operations that apply it.
    fn insert_panel(&mut self, ui: &mut egui::Ui) {
        ui.group(|ui| {
            let Some(insert) = self.studio.insert.as_mut() else { return };
            ui.heading(format!("Insert: {}", insert.mesh.name()));
            ui.label("Press or drag on the model to place it");
            ui.add(egui::DragValue::new(&mut insert.placement.size).range(1e-3..=1.0e5).speed(0.05).prefix("size "))
                .on_hover_text("Its largest side, in world units");
            let mut changed = false;
            ui.horizontal(|ui| {
                for (k, axis) in ["turn y", "x", "z"].into_iter().enumerate() {
                    changed |= ui
                        .add(
                            egui::DragValue::new(&mut insert.turn[k])
                                .range(-180.0..=180.0)
                                .speed(1.0)
                                .prefix(format!("{axis} "))
                                .suffix("°"),
                        )
                        .on_hover_text("Turn it about the world's y axis, then x, then z")
                        .changed();
                }
            });
            if changed {
                insert.sync_rotation();
            }
            self.insert_buttons(ui);
        });
    }

    /// Add, Subtract, Intersect and Cancel for the waiting insert (the panel's and the menu's).
    pub(super) fn insert_buttons(&mut self, ui: &mut egui::Ui) {
        use strata_volume::CsgOp;
        ui.horizontal(|ui| {
            for (op, name, tip) in [
                (CsgOp::Add, "Add insert", "Add it to the active layer exactly (one undo step)"),
                (CsgOp::Subtract, "Subtract insert", "Cut it out of the active layer exactly"),
                (CsgOp::Intersect, "Intersect insert", "Keep only what lies inside it"),
            ] {
                if ui.button(name).on_hover_text(tip).clicked() {
                    let _ = self.studio.apply_insert(op).map_err(|e| self.studio.fail(e));
                    ui.close();
                }
            }
            if ui.button("Cancel insert").on_hover_text("Drop it (Escape)").clicked() {
                self.studio.cancel_insert();
                ui.close();
            }
        });
    }
}
