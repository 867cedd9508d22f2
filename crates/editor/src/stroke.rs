//! The stroke engine: poses in, aligned and mirrored dabs out. One frame's pose continues the
//! stroke in progress (dabs every spacing along the path since the last one), starts one, or
//! ends it (one undo step per stroke); the pose's modifiers pick the inverse tool or smoothing.

use std::time::{Duration, Instant};

use glam::{DQuat, DVec3};
use strata_volume::{ChunkKey, EditReport, EditSettings, Volume};

use crate::editor::{Editor, EditorError, FrameReport};
use crate::history::HistoryEntry;
use crate::op::DabRecord;
use crate::pose::ToolPose;
use crate::scene::LayerTransform;
use crate::tool::{ToolKind, ToolSettings};

pub(crate) struct Stroke {
    layer: usize,
    /// Where the last dab went (world, aligned).
    last: DVec3,
    /// The stroke's first position (world, before alignment): the axis lock's line.
    start: DVec3,
    /// Where the stabilised brush is (world, before alignment; see [`crate::Stabiliser`]).
    brush: DVec3,
    /// A grab's centre (world): it follows the material it drags.
    anchor: DVec3,
    /// A stamp dragged out (see [`crate::StampStroke::Drag`]): `last` is its middle, `brush`
    /// the pointer, and nothing is applied until the button is released.
    drag: bool,
    /// The pose's orientation when the stroke started (a dragged stamp's top where it was
    /// not dragged at all).
    orientation: DQuat,
    inverted: bool,
    /// The tool the stroke applies (the current tool, or smoothing while the pose says so).
    kind: ToolKind,
    records: Vec<strata_volume::UndoRecord>,
    /// Balls (world centre, radius) holding everything the stroke's dabs built or carved,
    /// mirror images included: the surface inside them is the stroke's own.
    own: Vec<(DVec3, f64)>,
}

impl Stroke {
    /// A stroke starting at `position` (aligned) for a pose at `start` (as given).
    fn new(layer: usize, position: DVec3, start: DVec3, inverted: bool, kind: ToolKind) -> Self {
        Stroke {
            layer,
            last: position,
            start,
            brush: start,
            anchor: position,
            drag: false,
            orientation: DQuat::IDENTITY,
            inverted,
            kind,
            records: Vec::new(),
            own: Vec::new(),
        }
    }

    /// Whether world point `p` lies in one of the stroke's own balls.
    pub(crate) fn owns(&self, p: DVec3) -> bool {
        self.own.iter().any(|&(c, r)| (p - c).length_squared() <= r * r)
    }

    /// Where the ray `origin + t·dir` (unit `dir`), at `t` in the stroke's own balls, leaves
    /// their union.
    pub(crate) fn exit_own(&self, origin: DVec3, dir: DVec3, mut t: f64) -> f64 {
        // Each pass leaves every ball holding the point; a ball is left at most once, so the
        // loop ends within as many passes as there are balls.
        for _ in 0..=self.own.len() {
            let p = origin + dir * t;
            let mut next = t;
            for &(c, r) in &self.own {
                let off = p - c;
                if off.length_squared() <= r * r {
                    // The far root of |origin + s·dir − c| = r.
                    let b = (origin - c).dot(dir);
                    let disc = b * b - ((origin - c).length_squared() - r * r);
                    next = next.max(-b + disc.max(0.0).sqrt());
                }
            }
            if next <= t {
                return t;
            }
            // Just past the boundary, so the next pass does not find the same ball.
            t = next + 1e-9 * (1.0 + next.abs());
        }
        t
    }
}

/// Where and how one field-tool dab (one mirror image) acts (world coordinates).
pub(crate) struct FieldDab<'a> {
    /// The dab's centre.
    pub at: DVec3,
    /// The pose's y axis, mirrored as the image's position is (a stamp's top unless it follows
    /// the stroke).
    pub up: DVec3,
    pub pressure: f64,
    /// The secondary button: the inverse tool.
    pub inverted: bool,
    /// The stroke's direction, the line a pinch pulls towards and a stamp's top when it
    /// follows the stroke.
    pub direction: Option<DVec3>,
    /// An image reflected an odd number of times (a stamp's picture is mirrored).
    pub mirrored: bool,
    /// The stamp tool's image.
    pub stamp: Option<&'a strata_volume::tools::StampImage>,
}

/// One dab of the field tool `tool.kind` on `volume`, placed in its layer's grid by
/// `transform`: a ball of the tool's radius (at the dab's pressure), the falloff scaled by
/// [`ToolSettings::field_strength`]; the dab's `inverted` picks the inverse tool.
pub(crate) fn field_tool_dab(
    tool: &ToolSettings,
    transform: &crate::scene::LayerTransform,
    volume: &mut Volume,
    d: &FieldDab,
) -> Result<EditReport, strata_volume::tools::ToolError> {
    use strata_volume::tools::{
        Dab, MaskStroke, Smoothing, StampPlacement, ToolError, clay, flatten, inflate, mask, paint, pinch, smooth,
        stamp,
    };
    let (p, inverted) = (d.at, d.inverted);
    let radius = tool.radius_at(d.pressure) / transform.scale;
    let dab = Dab {
        material: tool.material,
        falloff: tool.falloff,
        ..Dab::new(transform.to_grid(p), radius, tool.field_strength_at(d.pressure))?
    };
    match tool.kind {
        ToolKind::Paint => paint(volume, &Dab { material: if inverted { 0 } else { tool.material }, ..dab }),
        ToolKind::Mask => mask(volume, &dab, if inverted { MaskStroke::Subtract } else { MaskStroke::Add }),
        ToolKind::MaskSmooth => mask(volume, &dab, MaskStroke::Smooth),
        ToolKind::Clay => clay(volume, &dab, tool.fillet.clamp(0.0, 4.0) * radius, inverted),
        ToolKind::Smooth => {
            let method = if inverted {
                Smoothing::Laplacian
            } else if tool.paper_smoothing {
                Smoothing::Endpoints
            } else {
                Smoothing::VolumePreserving
            };
            smooth(volume, &dab, method, 4)
        }
        ToolKind::Inflate => inflate(volume, &dab, if inverted { -0.2 } else { 0.2 } * radius),
        ToolKind::Pinch => {
            let axis = d.direction.map(|d| transform.rotation.inverse() * d);
            pinch(volume, &dab, axis, if inverted { -0.5 } else { 0.5 })
        }
        ToolKind::Stamp => {
            let image = d.stamp.ok_or(ToolError::BadParameter { what: "the stamp's image", positive: false })?;
            let s = &tool.stamp;
            let along = s.follow_stroke || s.stroke == crate::StampStroke::Drag;
            let up = d.direction.filter(|_| along).unwrap_or(d.up);
            // A mirror image turns the other way.
            let angle = s.angle.to_radians() * if d.mirrored { -1.0 } else { 1.0 };
            let placement = StampPlacement { up: transform.rotation.inverse() * up, angle, mirrored: d.mirrored };
            let height = crate::stamps::STAMP_HEIGHT * radius * if inverted { -1.0 } else { 1.0 };
            stamp(volume, &dab, image, &placement, height)
        }
        // (Grab drags through `Editor::grab_to`; a dab of it alone has nothing to drag.)
        ToolKind::Grab => {
            Ok(EditReport { changed: Vec::new(), undo: Default::default(), repaired_nodes: 0, reach: None })
        }
        ToolKind::Detail => {
            let target = if inverted { volume.level() } else { tool.detail_level.max(volume.level()) };
            Ok(volume.set_chunk_levels(&chunks_in_ball(volume, dab.center, radius), target))
        }
        _ => flatten(volume, &dab),
    }
}

/// The box around a ball (grid coordinates): the reach a world loads before a dab.
fn ball_bounds(centre: DVec3, radius: f64) -> strata_volume::brush::Aabb {
    strata_volume::brush::Aabb::new(centre - DVec3::splat(radius), centre + DVec3::splat(radius))
}

/// The list chunks of `volume` that a ball (grid coordinates) reaches.
fn chunks_in_ball(volume: &Volume, center: DVec3, radius: f64) -> Vec<ChunkKey> {
    let c = strata_volume::coords::CHUNK_CELLS as f64;
    let (Some(lo), Some(hi)) =
        (ChunkKey::containing(center - DVec3::splat(radius)), ChunkKey::containing(center + DVec3::splat(radius)))
    else {
        return Vec::new();
    };
    let keys: Vec<ChunkKey> = strata_volume::ChunkBox::between(lo, hi)
        .keys()
        .filter(|&k| {
            let min = k.origin_grid().as_dvec3();
            let nearest = center.clamp(min, min + DVec3::splat(c));
            volume.stored_level(k).is_some() && (nearest - center).length() <= radius
        })
        .collect();
    keys
}

impl Editor {
    /// Whether a stroke is in progress.
    pub fn stroking(&self) -> bool {
        self.stroke.is_some()
    }

    /// One frame: applies the tool along the path from the previous pose (dabs every
    /// [`ToolSettings::dab_spacing`]), ends the stroke when no button is held (one undo step per
    /// stroke), then remeshes queued chunks until `remesh_budget` is spent.
    pub fn frame(&mut self, pose: &ToolPose, remesh_budget: Duration) -> Result<FrameReport, EditorError> {
        if !pose.is_valid() {
            return Err(EditorError::BadPose);
        }
        let mut report = FrameReport::default();
        let t0 = Instant::now();
        let down = pose.buttons.primary || pose.buttons.secondary;
        let result = if down { self.stroke_to(pose, &mut report) } else { self.finish_stamp_drag(&mut report) };
        self.end_op();
        if !down || result.is_err() {
            self.end_stroke();
        }
        report.edit_time = t0.elapsed();
        self.remesh(remesh_budget, &mut report);
        result.map(|_| report)
    }

    fn stroke_to(&mut self, pose: &ToolPose, report: &mut FrameReport) -> Result<(), EditorError> {
        let layer = self.active_surface();
        self.check_editable(layer)?;
        self.check_material()?;
        let inverted = pose.inverted();
        let tool = self.tool_for(pose);
        self.check_tool_target(layer, &tool)?;
        let spacing = tool.dab_spacing();
        let transform = self.surface(layer).ok_or(EditorError::NoLayer(layer))?.transform();
        let continuing =
            matches!(&self.stroke, Some(s) if s.layer == layer && s.inverted == inverted && s.kind == tool.kind);
        if !continuing {
            self.end_stroke();
        }
        let start = self.stroke.as_ref().map(|s| s.start);
        let dragging = tool.kind == ToolKind::Stamp && tool.stamp.stroke == crate::StampStroke::Drag;
        // The stabiliser's brush trails the pointer (a grab and a dragged stamp follow the
        // pointer exactly).
        let stabiliser = self.stabiliser;
        let pointer = match self.stroke.as_mut() {
            Some(s) if tool.kind != ToolKind::Grab && !dragging => {
                s.brush = stabiliser.follow(s.brush, pose.position, tool.radius_at(pose.pressure));
                s.brush
            }
            _ => pose.position,
        };
        let position = tool.aligned(&transform, pointer, start);
        if tool.kind == ToolKind::Grab {
            return self.grab_to(layer, position, pose, &tool, report);
        }
        if dragging {
            match self.stroke.as_mut() {
                Some(s) => s.brush = pose.position,
                None => {
                    let mut s = Stroke::new(layer, position, pose.position, inverted, tool.kind);
                    (s.drag, s.orientation) = (true, pose.orientation);
                    self.stroke = Some(s);
                }
            }
            return Ok(());
        }
        let mut dabs = Vec::new();
        match &self.stroke {
            Some(s) => {
                let d = position - s.last;
                let len = d.length();
                let steps = (len / spacing).floor() as usize;
                // A jump of more than 10,000 dabs is a teleport, not a stroke: dab at the end only.
                if steps > 10_000 {
                    dabs.push(position);
                } else {
                    dabs.extend(
                        (1..=steps).map(|k| tool.aligned(&transform, s.last + d * (k as f64 * spacing / len), start)),
                    );
                }
            }
            None => {
                self.stroke = Some(Stroke::new(layer, position, pose.position, inverted, tool.kind));
                dabs.push(position);
            }
        }
        self.begin_op(layer, &transform, &tool);
        for p in dabs {
            let last = self.stroke.as_ref().map_or(p, |s| s.last);
            let dab =
                DabRecord::Dab { at: p, from: last, orientation: pose.orientation, pressure: pose.pressure, inverted };
            let mut applied = Vec::new();
            self.apply_dab(layer, &tool, &transform, &dab, &mut applied)?;
            for (edit, at, reach) in applied {
                self.record(layer, edit);
                if tool.kind.builds_or_carves() {
                    let s = self.stroke.as_mut().expect("a stroke is in progress");
                    s.own.push((at, reach));
                }
            }
            self.note_dab(dab);
            let s = self.stroke.as_mut().expect("a stroke is in progress");
            s.last = p;
            report.dabs += 1;
        }
        Ok(())
    }

    /// Where a stamp being dragged out goes: its middle and radius (world), and where its top
    /// points (a zero vector until the pointer has moved); `None` unless one is.
    pub fn stamp_drag(&self) -> Option<(DVec3, f64, DVec3)> {
        let s = self.stroke.as_ref().filter(|s| s.drag)?;
        let reach = self.drag_reach(s);
        let radius = if reach == DVec3::ZERO { self.tool.radius } else { reach.length() };
        Some((s.last, radius, reach))
    }

    /// How far a dragged stamp's pointer went from the press (unsnapped, so grid snapping does
    /// not make a drag of a click); zero for less than a tenth of the tool's radius (a click).
    fn drag_reach(&self, s: &Stroke) -> DVec3 {
        let reach = s.brush - s.start;
        if reach.length() < 0.1 * self.tool.radius { DVec3::ZERO } else { reach }
    }

    /// Applies the stamp dragged out in the stroke in progress, if one is (the button was
    /// released): one dab at its middle, as large as the drag and turned towards the pointer
    /// (a click without a drag: the tool's radius, the top up the pose's y axis), whatever its
    /// size (the frame limit is for dragging). Its undo goes to the stroke.
    fn finish_stamp_drag(&mut self, report: &mut FrameReport) -> Result<(), EditorError> {
        let Some(s) = self.stroke.as_ref().filter(|s| s.drag) else { return Ok(()) };
        let (layer, centre, inverted, orientation) = (s.layer, s.last, s.inverted, s.orientation);
        let reach = self.drag_reach(s);
        let mut tool = self.tool;
        tool.kind = ToolKind::Stamp;
        tool.stamp.stroke = crate::StampStroke::Drag;
        if reach != DVec3::ZERO {
            // The drag is the radius: pressure does not scale it.
            (tool.radius, tool.strength) = (reach.length(), 0.0);
        }
        self.check_editable(layer)?;
        self.check_tool_target(layer, &tool)?;
        let transform = self.surface(layer).ok_or(EditorError::NoLayer(layer))?.transform();
        self.begin_op(layer, &transform, &tool);
        // (The dab's top points from `from` to `at`: from the pointer's mirror image.)
        let dab = DabRecord::Dab { at: centre, from: centre - reach, orientation, pressure: 1.0, inverted };
        let limit = std::mem::replace(&mut self.frame_dab_limit, u64::MAX);
        let mut applied = Vec::new();
        let result = self.apply_dab(layer, &tool, &transform, &dab, &mut applied);
        self.frame_dab_limit = limit;
        result?;
        for (edit, at, reach) in applied {
            self.record(layer, edit);
            let s = self.stroke.as_mut().expect("a stroke is in progress");
            s.own.push((at, reach));
        }
        self.note_dab(dab);
        report.dabs += 1;
        Ok(())
    }

    /// Applies one recorded dab of `tool` to surface `layer` placed by `transform`: every
    /// mirror image, each with its edit, where it went (world) and the ball (radius, world)
    /// holding what it built or carved, pushed to `applied`. All images are checked against the
    /// frame's limit before any is applied, and an image refused after others were applied
    /// takes them back: a dab is applied whole or not at all.
    pub(crate) fn apply_dab(
        &mut self,
        layer: usize,
        tool: &ToolSettings,
        transform: &LayerTransform,
        dab: &DabRecord,
        applied: &mut Vec<(EditReport, DVec3, f64)>,
    ) -> Result<(), EditorError> {
        match *dab {
            DabRecord::Dab { at, from, orientation, pressure, inverted } => {
                let result =
                    self.apply_mirrored(layer, tool, transform, (at, from, orientation), pressure, inverted, applied);
                if result.is_err() {
                    let target = self.surface_mut(layer).ok_or(EditorError::NoLayer(layer))?;
                    for (edit, _, _) in applied.drain(..).rev() {
                        target.restore(edit.undo);
                    }
                }
                result
            }
            DabRecord::Grab { anchor, drag, pressure } => {
                let edits = self.apply_grab(layer, tool, transform, anchor, drag, pressure)?;
                applied.extend(edits.into_iter().map(|e| (e, anchor, 0.0)));
                Ok(())
            }
        }
    }

    /// The mirror images of a dab at `p` (world, aligned) after one at `last`, turned by
    /// `orientation` (the `place`), applied in order (see [`Editor::apply_dab`]).
    fn apply_mirrored(
        &mut self,
        layer: usize,
        tool: &ToolSettings,
        transform: &LayerTransform,
        (p, last, orientation): (DVec3, DVec3, glam::DQuat),
        pressure: f64,
        inverted: bool,
        applied: &mut Vec<(EditReport, DVec3, f64)>,
    ) -> Result<(), EditorError> {
        let op = tool.kind.op(inverted);
        let images = tool.mirrored(transform, p, orientation);
        // (The same images, in the same order, each with the stroke's direction and whether it
        // is mirrored.)
        let directions = tool.mirrored_directions(transform, p, p - last);
        let parities = tool.mirror_parities(transform, p);
        // (A stamp's top: the pose's y axis reflected as a vector, which `M R M` applied to y
        // is not where the reflection is along y.)
        let ups = tool.mirrored_directions(transform, p, orientation * DVec3::Y);
        let image = self.stamp_image(tool)?;
        // Each image's brush (CSG tools) and box, built once; all are checked against the
        // frame's limit before any is applied, so a refused dab leaves no image behind.
        let mut planned = Vec::with_capacity(images.len());
        for &(at, orientation) in &images {
            if tool.kind.is_field_tool() {
                // Clay's, inflate's and a stamp's change stays within the ball; a tenth more
                // covers the surface it moved.
                let reach = tool.radius_at(pressure) * 1.1;
                planned.push((None, ball_bounds(transform.to_grid(at), reach / transform.scale), reach));
            } else {
                let brush = tool.brush(transform, at, orientation, pressure)?;
                let b = brush.bounds();
                // The ball around the brush's box (grid units to world).
                let reach = 0.5 * (b.max - b.min).length() * transform.scale * 1.05;
                planned.push((Some(brush), b, reach));
            }
        }
        for (_, bounds, _) in &planned {
            self.check_dab_size(bounds)?;
        }
        let settings = EditSettings { material: tool.material, ..self.settings.clone() };
        for (k, ((at, _), (brush, bounds, reach))) in images.into_iter().zip(planned).enumerate() {
            let target = self.surface_mut(layer).ok_or(EditorError::NoLayer(layer))?;
            let edit = match brush {
                None => {
                    let direction = directions.get(k).map(|&(_, v)| v).filter(|v| v.length() > 1e-9);
                    let mirrored = parities.get(k).copied().unwrap_or(false);
                    let up = ups.get(k).map_or(DVec3::Y, |&(_, v)| v);
                    let dab = FieldDab { at, up, pressure, inverted, direction, mirrored, stamp: image.as_deref() };
                    target.edit(&bounds, &mut |v| Ok(field_tool_dab(tool, transform, v, &dab)?))?
                }
                Some(brush) => target.edit(&bounds, &mut |v| Ok(v.apply(op, brush.as_ref(), &settings)?))?,
            };
            applied.push((edit, at, reach));
        }
        Ok(())
    }

    /// A frame of the grab tool: the surface under the stroke's anchor is dragged by the
    /// pointer's move since the last frame (mirrored under symmetry), and the anchor follows it.
    fn grab_to(
        &mut self,
        layer: usize,
        position: DVec3,
        pose: &ToolPose,
        tool: &ToolSettings,
        report: &mut FrameReport,
    ) -> Result<(), EditorError> {
        let inverted = pose.inverted();
        let Some(s) = &self.stroke else {
            self.stroke = Some(Stroke::new(layer, position, pose.position, inverted, tool.kind));
            return Ok(());
        };
        let drag = position - s.last;
        if drag.length_squared() == 0.0 {
            return Ok(());
        }
        let anchor = s.anchor;
        let transform = self.surface(layer).ok_or(EditorError::NoLayer(layer))?.transform();
        self.begin_op(layer, &transform, tool);
        let dab = DabRecord::Grab { anchor, drag, pressure: pose.pressure };
        let mut applied = Vec::new();
        self.apply_dab(layer, tool, &transform, &dab, &mut applied)?;
        for (edit, _, _) in applied {
            self.record(layer, edit);
        }
        self.note_dab(dab);
        let s = self.stroke.as_mut().expect("a stroke is in progress");
        s.last = position;
        s.anchor = anchor + drag;
        report.dabs += 1;
        Ok(())
    }

    /// A grab's drag by `drag` (world) of the surface under `anchor` (world), mirrored: the
    /// edits of every image, or none when one is refused.
    fn apply_grab(
        &mut self,
        layer: usize,
        tool: &ToolSettings,
        transform: &LayerTransform,
        anchor: DVec3,
        drag: DVec3,
        pressure: f64,
    ) -> Result<Vec<EditReport>, EditorError> {
        // Grab follows the pointer one to one: the material under the anchor moves as far as
        // the pointer (the falloff takes the rest of the ball along less far).
        let strength = 1.0;
        let radius = tool.radius_at(pressure) / transform.scale;
        let mut done: Vec<EditReport> = Vec::new();
        let target = self.surface_mut(layer).ok_or(EditorError::NoLayer(layer))?;
        for (at, d) in tool.mirrored_with_vector(transform, anchor, drag) {
            let centre = transform.to_grid(at);
            let moved = transform.rotation.inverse() * d / transform.scale;
            let bounds = ball_bounds(centre, radius + moved.length());
            let result = target.edit(&bounds, &mut |volume| {
                let dab = strata_volume::tools::Dab::new(centre, radius, strength)?;
                Ok(strata_volume::tools::grab(volume, &dab, moved)?)
            });
            match result {
                Ok(edit) => done.push(edit),
                Err(e) => {
                    // A refused drag changes nothing, mirrored images included (the chunks
                    // they changed are in memory: they were just edited).
                    for edit in done.into_iter().rev() {
                        target.restore(edit.undo);
                    }
                    return Err(e);
                }
            }
        }
        Ok(done)
    }

    /// The image the stamp tool uses (`None` for other tools), or [`EditorError::UnknownStamp`].
    pub(crate) fn stamp_image(
        &mut self,
        tool: &ToolSettings,
    ) -> Result<Option<std::sync::Arc<strata_volume::tools::StampImage>>, EditorError> {
        if tool.kind != ToolKind::Stamp {
            return Ok(None);
        }
        self.stamps.image(tool.stamp.source).map(Some).ok_or(EditorError::UnknownStamp)
    }

    /// Refuses a dab whose box `b` spans more chunks than [`Editor::frame_dab_limit`].
    fn check_dab_size(&self, b: &strata_volume::brush::Aabb) -> Result<(), EditorError> {
        if self.frame_dab_limit == u64::MAX {
            return Ok(());
        }
        let chunks = crate::dab_job::chunks_spanned(b)?;
        if chunks > self.frame_dab_limit {
            return Err(EditorError::DabTooLargeForFrame(chunks));
        }
        Ok(())
    }

    /// The tool a pose applies: the current tool, or smoothing with its settings while the
    /// pose's modifiers say smooth (Shift in the studio).
    pub(crate) fn tool_for(&self, pose: &ToolPose) -> ToolSettings {
        let mut tool = self.tool;
        if pose.modifiers.smooth {
            tool.kind = if tool.kind.is_mask() { ToolKind::MaskSmooth } else { ToolKind::Smooth };
        }
        tool
    }

    /// Queues an edit of the stroke in progress for meshing and keeps its undo record.
    /// (While the editor records operations, the record goes to the frame's operation instead:
    /// see [`Editor::record_ops`].)
    fn record(&mut self, layer: usize, edit: EditReport) {
        self.queue(layer, &edit.changed, edit.reach);
        self.revision += 1;
        if let Some(op) = self.recorder.as_mut().and_then(|r| r.current.as_mut()) {
            op.undo.records.push(edit.undo);
            return;
        }
        let s = self.stroke.as_mut().expect("a stroke is in progress");
        s.records.push(edit.undo);
    }

    /// The line tool: a straight stroke of the current tool from world point `a` to `b`, dabs
    /// evenly spaced by the tool's dab spacing (mirrored under symmetry), as one undo step.
    /// `modifiers` act as in a dragged stroke (the inverse tool, smoothing).
    pub fn line_stroke(
        &mut self,
        a: DVec3,
        b: DVec3,
        pressure: f64,
        modifiers: crate::pose::Modifiers,
    ) -> Result<FrameReport, EditorError> {
        let pose = |p: DVec3| ToolPose {
            position: p,
            orientation: glam::DQuat::IDENTITY,
            pressure,
            buttons: Default::default(),
            ..ToolPose::default()
        };
        if !(pose(a).is_valid() && pose(b).is_valid()) {
            return Err(EditorError::BadPose);
        }
        self.end_stroke();
        let buttons = crate::pose::Buttons { primary: true, secondary: false };
        let pose =
            |p: DVec3| ToolPose { position: p, orientation: glam::DQuat::IDENTITY, pressure, buttons, modifiers };
        // A line is applied whole, whatever its dabs' size (the frame limit is for dragging),
        // and a stamp is sprayed along it.
        let limit = std::mem::replace(&mut self.frame_dab_limit, u64::MAX);
        let stamp_stroke = std::mem::replace(&mut self.tool.stamp.stroke, crate::StampStroke::Spray);
        let first = self.frame(&pose(a), Duration::ZERO);
        let end = first.as_ref().ok().map(|_| self.frame(&pose(b), Duration::ZERO));
        self.frame_dab_limit = limit;
        self.tool.stamp.stroke = stamp_stroke;
        let mut report = first?;
        let end = end.expect("the first frame went through")?;
        report.dabs += end.dabs;
        report.edit_time += end.edit_time;
        report.remeshed.extend(end.remeshed);
        self.end_stroke();
        Ok(report)
    }

    /// Ends the stroke in progress, making it one undo step.
    pub fn end_stroke(&mut self) {
        if let Some(s) = self.stroke.take() {
            // (While recording operations, the stroke's records went to them.)
            if let Some(r) = self.recorder.as_mut() {
                r.stroke += 1;
                return;
            }
            self.history.push(HistoryEntry { layer: s.layer, records: s.records, ..Default::default() });
        }
    }
}
