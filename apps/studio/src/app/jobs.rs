//! Long jobs: the progress of a large dab on its worker (with cancel), the mesh import's
//! options and its progress.

use super::*;

impl StudioApp {
    /// A large dab on its worker: a progress bar and a cancel button, until it finishes.
    pub(super) fn job_progress(&mut self, ctx: &egui::Context) {
        if self.studio.poll_job() {
            ctx.request_repaint();
            return;
        }
        let Some(job) = self.studio.job.as_ref() else { return };
        let (done, total) = job.progress();
        let fraction = if total > 0 { done as f32 / total as f32 } else { 0.0 };
        let mut cancel = false;
        egui::Modal::new(egui::Id::unique("large dab")).show(ctx, |ui| {
            ui.heading("Sculpting a large dab");
            ui.add(egui::ProgressBar::new(fraction).show_percentage().desired_width(320.0));
            ui.label(format!("{done} of {total} chunks · {:.1} s", job.elapsed().as_secs_f64()));
            cancel = ui.button("Cancel").on_hover_text("Stop; the layer stays as it was").clicked();
        });
        if cancel || ctx.input(|i| i.key_pressed(egui::Key::Escape)) {
            job.cancel();
        }
        ctx.request_repaint_after(Duration::from_millis(50));
    }

    /// The resolution dialog of a mesh about to be imported: cells along its longest side, with
    /// a live estimate of what the layer will hold.
    pub(super) fn import_dialog(&mut self, ctx: &egui::Context) {
        let Some(p) = self.studio.pending_import.as_mut() else { return };
        let (mut go, mut cancel) = (false, false);
        let modal = egui::Modal::new(egui::Id::unique("import mesh")).show(ctx, |ui| {
            ui.heading("Import mesh as a new layer");
            ui.label(format!(
                "{}: {} triangles, {}",
                p.path.display(),
                p.mesh.triangles.len(),
                if p.closed { "closed" } else { "with holes (filled line by line)" }
            ));
            ui.add(egui::Slider::new(&mut p.cells, 16..=2048).logarithmic(true).text("cells along the longest side"))
                .on_hover_text("Finer keeps more detail and takes more memory and time");
            match p.plan() {
                Ok(plan) => ui.label(format!(
                    "cells of {:.4} units · about {:.0} thousand crossings · about {:.1} MiB",
                    plan.cell,
                    plan.estimated_crossings / 1e3,
                    plan.estimated_bytes() / (1024.0 * 1024.0)
                )),
                Err(e) => ui.label(e.to_string()),
            };
            ui.horizontal(|ui| {
                go = ui.button("Import").on_hover_text("Convert the mesh into a new layer (Enter)").clicked();
                cancel = ui.button("Cancel").on_hover_text("Do not import it (Escape)").clicked();
            });
        });
        if cancel || modal.should_close() {
            self.studio.pending_import = None;
        } else if go && let Err(e) = self.studio.start_import() {
            self.studio.message = e;
        }
    }

    /// A mesh conversion on its worker: a progress bar and a cancel button.
    pub(super) fn import_progress(&mut self, ctx: &egui::Context) {
        if self.studio.poll_import() {
            ctx.request_repaint();
            return;
        }
        let Some(job) = self.studio.import_job.as_ref() else { return };
        let (done, total) = job.control.progress();
        let fraction = if total > 0 { done as f32 / total as f32 } else { 0.0 };
        let mut cancel = false;
        egui::Modal::new(egui::Id::unique("importing")).show(ctx, |ui| {
            ui.heading(format!("Importing {}", job.name));
            ui.add(egui::ProgressBar::new(fraction).show_percentage().desired_width(320.0));
            ui.label(format!("{done} of {total} chunks · {:.1} s", job.started.elapsed().as_secs_f64()));
            cancel = ui.button("Cancel import").on_hover_text("Stop; the scene stays as it was").clicked();
        });
        if cancel || ctx.input(|i| i.key_pressed(egui::Key::Escape)) {
            job.control.cancel();
        }
        ctx.request_repaint_after(Duration::from_millis(50));
    }
}
