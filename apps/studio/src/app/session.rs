//! Sculpting together in the window: the Host and Join dialogs, the people panel (who is in the
//! room, the connection's state, the address to share, Leave) and the others' brushes drawn
//! over the viewport.

use super::*;
use crate::studio::SessionParams;

/// The Host or Join dialog.
#[derive(Debug)]
pub(super) struct SessionDialog {
    /// Host (a server here) rather than join.
    pub(super) host: bool,
    pub(super) params: SessionParams,
    /// Whether the first field has been given the keyboard.
    focused: bool,
    /// Why the last try failed.
    error: Option<String>,
}

/// A colour of its own for each person in a room: a hue from the id's bits mixed by the
/// golden ratio (Fibonacci hashing), so that ids close together get hues far apart.
pub(super) fn peer_colour(client: strata_net::protocol::ClientId) -> egui::Color32 {
    let hue = (client.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f32 / (1u64 << 24) as f32;
    egui::ecolor::Hsva::new(hue, 0.75, 0.95, 1.0).into()
}

/// A dot of `colour` the size of a line of text (the default fonts have no bullet glyph).
fn swatch(ui: &mut egui::Ui, colour: egui::Color32) {
    let size = ui.text_style_height(&egui::TextStyle::Body);
    let (rect, _) = ui.allocate_exact_size(egui::vec2(size, size), egui::Sense::hover());
    ui.painter().circle_filled(rect.center(), size * 0.35, colour);
}

impl StudioApp {
    /// Opens the Host (`host`) or Join dialog with the last parameters typed, or suggested ones.
    pub(super) fn open_session_dialog(&mut self, ctx: &egui::Context, host: bool) {
        let params = match &self.session_params {
            Some(p) if !host => p.clone(),
            // A new room gets a new token: someone still trying to reconnect to the last one
            // must not land in this one.
            Some(p) => {
                let fresh = SessionParams::suggested(true);
                SessionParams { address: fresh.address, token: fresh.token, ..p.clone() }
            }
            None => SessionParams::suggested(host),
        };
        self.session_dialog = Some(SessionDialog { host, params, focused: false, error: None });
        ctx.request_repaint();
    }

    /// The Host or Join dialog: four labelled fields; Enter or the button goes, Escape or
    /// Cancel closes it. A failure is said in the dialog, which stays.
    pub(super) fn session_dialog(&mut self, ctx: &egui::Context) {
        let Some(mut d) = self.session_dialog.take() else { return };
        let (mut go, mut cancel) = (false, false);
        let title = if d.host { "Host a session" } else { "Join a session" };
        let modal = egui::Modal::new(egui::Id::unique("session dialog")).show(ctx, |ui| {
            ui.heading(title);
            ui.label(if d.host {
                "Others join this scene with this machine's address, the room's name and its token."
            } else {
                "The scene becomes the room's: everyone in it sculpts it together."
            });
            egui::Grid::new("session fields").num_columns(2).show(ui, |ui| {
                let address = if d.host { "Listen on" } else { "Server" };
                let hints = [
                    if d.host {
                        "0.0.0.0:7878 takes others on the network; 127.0.0.1:0 a free port for this machine only"
                    } else {
                        "The host's address: ws://host:7878"
                    },
                    "The room's name",
                    "The room's shared secret: whoever has it can join",
                    "The name the others see",
                ];
                let fields = [
                    (address, &mut d.params.address),
                    ("Room", &mut d.params.room),
                    ("Token", &mut d.params.token),
                    ("Your name", &mut d.params.name),
                ];
                for (i, ((label, text), hint)) in fields.into_iter().zip(hints).enumerate() {
                    let label = ui.label(label);
                    let r = ui
                        .add(egui::TextEdit::singleline(text).desired_width(320.0))
                        .labelled_by(label.id)
                        .on_hover_text(hint);
                    if i == 0 && !d.focused {
                        r.request_focus();
                        d.focused = true;
                    }
                    go |= r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
                    ui.end_row();
                }
            });
            if let Some(e) = &d.error {
                ui.colored_label(ui.visuals().error_fg_color, e);
            }
            ui.horizontal(|ui| {
                go |= ui
                    .button(if d.host { "Host" } else { "Join" })
                    .on_hover_text(if d.host {
                        "Start the room and share this scene (Enter)"
                    } else {
                        "Join the room (Enter)"
                    })
                    .clicked();
                cancel |= ui.button("Cancel").on_hover_text("Close this dialog (Escape)").clicked();
            });
        });
        cancel |= modal.should_close();
        if go {
            self.session_params = Some(d.params.clone());
            if !d.host && self.studio.is_modified() {
                // Joining replaces the scene: ask about its changes first.
                self.join_next = Some(d.params);
                self.guard(ctx, Then::Join);
                return;
            }
            let action =
                if d.host { Action::HostSession(d.params.clone()) } else { Action::JoinSession(d.params.clone()) };
            match self.studio.act(action) {
                Ok(()) => ctx.request_repaint(),
                Err(e) => {
                    // (Said in the dialog, which stays for another try.)
                    self.studio.notice = None;
                    d.error = Some(e);
                    self.session_dialog = Some(d);
                }
            }
        } else if cancel {
            self.studio.message = format!("{title}: cancelled");
        } else {
            self.session_dialog = Some(d);
        }
    }

    /// The room's people, the connection and the address to share, above the layers.
    pub(super) fn people(&mut self, ui: &mut egui::Ui) {
        let Some(c) = self.studio.collab.as_ref() else { return };
        ui.heading("Shared room");
        // (One line whatever the state says, so that Leave does not move under the pointer.)
        let state = format!("Room {:?}: {}", c.params.room, c.state_text());
        ui.add(egui::Label::new(state.as_str()).truncate()).on_hover_text(state.as_str());
        if c.hosting() {
            ui.horizontal(|ui| {
                ui.label("Join at");
                ui.add(egui::Label::new(egui::RichText::new(&c.share).monospace()).selectable(true))
                    .on_hover_text("The address, the room's name and its token are what the others type");
            });
        }
        let me = c.session.replica().client();
        ui.horizontal(|ui| {
            let colour = me.map_or(egui::Color32::GRAY, peer_colour);
            swatch(ui, colour);
            ui.label(format!("{} (you)", c.params.name));
        });
        for (client, name, presence) in c.session.peers() {
            ui.horizontal(|ui| {
                swatch(ui, peer_colour(client));
                let where_ = if presence.position.is_some() { "" } else { " (away from the model)" };
                ui.label(format!("{name}{where_}"));
            });
        }
        let leave = if c.hosting() { "Close the room" } else { "Leave session" };
        if ui.button(leave).on_hover_text("The scene stays here as it is").clicked() {
            let _ = self.studio.act(Action::LeaveSession);
        }
        ui.separator();
    }

    /// The others' brushes over the viewport: a ring of their radius where their brush is, in
    /// their colour, with their name.
    pub(super) fn peer_cursors(&self, ui: &egui::Ui, rect: egui::Rect) {
        let Some(c) = self.studio.collab.as_ref() else { return };
        let painter = ui.painter_at(rect);
        let eye = self.studio.camera.eye().as_dvec3();
        for (client, name, presence) in c.session.peers() {
            let Some(p) = presence.position.filter(|p| p.is_finite()) else { continue };
            let Some(at) = self.screen_of(p.as_vec3()) else { continue };
            let radius = (presence.radius / self.studio.world_per_point((p - eye).length())) as f32;
            let colour = peer_colour(client);
            painter.circle_stroke(at, radius.clamp(3.0, 4000.0), egui::Stroke::new(2.0, colour));
            painter.text(
                at + egui::vec2(0.0, -radius - 4.0),
                egui::Align2::CENTER_BOTTOM,
                name,
                egui::FontId::proportional(13.0),
                colour,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn people_get_colours_of_their_own_even_with_ids_close_together() {
        let colours: std::collections::HashSet<_> = (1..=64u64).map(super::peer_colour).collect();
        assert!(colours.len() >= 60, "{} colours for 64 people", colours.len());
        let random: std::collections::HashSet<_> =
            (1..=64u64).map(|i| super::peer_colour(i.wrapping_mul(0x2545_f491_4f6c_dd1d))).collect();
        assert!(random.len() >= 60, "{} colours for 64 people", random.len());
    }
}
