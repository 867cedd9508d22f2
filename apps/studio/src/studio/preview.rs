//! The brush preview: where the dab and its mirror images go, and the brush's mesh.

use super::*;

impl Studio {
    /// Where the brush preview goes: the dab at the pointer and its mirror images, each as
    /// (world placement, erasing); the shape and radius are [`Studio::preview_mesh`]'s.
    pub fn preview_dabs(&self) -> Vec<(DVec3, DQuat)> {
        // A waiting insert is previewed instead of the brush.
        if self.insert.is_some() {
            return Vec::new();
        }
        // A stamp being dragged out shows where it will go, not the pointer.
        let Some(p) = self.editor.stamp_drag().map(|(c, _, _)| c).or(self.hover) else { return Vec::new() };
        let Some(surface) = self.editor.surface(self.editor.active_surface()) else { return Vec::new() };
        self.editor.tool.mirrored(&surface.transform(), p, self.brush_orientation())
    }

    /// How much larger than [`Studio::preview_mesh`] the preview is drawn: a stamp being
    /// dragged out shows its dragged size.
    pub fn preview_scale(&self) -> f64 {
        match self.editor.stamp_drag() {
            Some((_, r, _)) if self.editor.tool.radius > 0.0 => r / self.editor.tool.radius,
            _ => 1.0,
        }
    }

    /// The brush preview mesh for the current shape and radius (rebuilt when they change),
    /// centred on the origin, in world units.
    pub fn preview_mesh(&mut self) -> &Mesh {
        self.refresh_preview();
        self.built_preview()
    }

    /// The preview mesh as last built by [`Studio::preview_mesh`] or [`Studio::refresh_preview`]
    /// (empty before).
    pub fn built_preview(&self) -> &Mesh {
        static EMPTY: Mesh =
            Mesh { positions: Vec::new(), normals: Vec::new(), materials: Vec::new(), indices: Vec::new() };
        self.preview.as_ref().map_or(&EMPTY, |p| &p.2)
    }

    /// Rebuilds the preview mesh if the shape or the radius changed.
    pub fn refresh_preview(&mut self) {
        let mut tool = self.editor.tool;
        if tool.kind.is_field_tool() || self.smooth_held {
            // Field tools act in a ball of the radius, whatever the CSG shape.
            tool.shape = strata_editor::BrushShape::Sphere;
        }
        let key = (tool.shape, tool.radius.to_bits());
        if self.preview.as_ref().is_none_or(|(s, r, _)| (*s, *r) != key) {
            // Meshed 12 cells across its radius, whatever the radius, then scaled to world units.
            let scale = tool.radius / 12.0;
            let mut v = strata_volume::Volume::new();
            let mesh = match strata_editor::LayerTransform::new(DVec3::ZERO, DQuat::IDENTITY, scale) {
                Ok(t) => match tool.brush(&t, DVec3::ZERO, DQuat::IDENTITY, 1.0).map(|b| v.add(b.as_ref()).map(|_| ()))
                {
                    Ok(Ok(())) => {
                        // (Marching cubes with no options meshes every volume: no preview is the worst.)
                        let mut m =
                            strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default()).unwrap_or_default();
                        for p in &mut m.positions {
                            *p = p.map(|c| c * scale as f32);
                        }
                        m
                    }
                    _ => Mesh::default(),
                },
                Err(_) => Mesh::default(),
            };
            self.preview = Some((key.0, key.1, mesh));
        }
    }
}
