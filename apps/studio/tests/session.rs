//! Sculpting together, driven as users drive it (`egui_kittest`, two studios in one process, a
//! real server on the loopback): File > Host session in one, File > Join session in the other,
//! strokes that appear in both, the others' brushes, undo through the room (refused where the
//! other edited), a dropped connection, a wrong token, leaving.

use std::time::{Duration, Instant};

use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use strata_studio::{Dialogs, Studio, StudioApp, default_scene};

type H = Harness<'static, StudioApp>;

fn harness(name: &str, scene: strata_editor::Scene) -> H {
    let dir = std::env::temp_dir().join(format!("strata-session-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let app = StudioApp::headless(Studio::new(scene), Dialogs::Typed, dir.join("recovery"));
    Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .with_max_steps(8)
        .build_ui_state(|ui, app: &mut StudioApp| app.show(ui, None), app)
}

/// Runs frames until the studio settles, or a few at most: in a live room messages keep
/// coming, and every new one asks for a frame.
fn frames(h: &mut H) {
    let _ = h.run_ok();
}

/// Types `text` as a keyboard does (a key press for keys egui knows, and the text).
fn type_keys(h: &mut H, text: &str) {
    for ch in text.chars() {
        if let Some(key) = egui::Key::from_name(&ch.to_ascii_uppercase().to_string()) {
            h.key_press(key);
        }
        h.event(egui::Event::Text(ch.to_string()));
        frames(h);
    }
}

/// Clicks the field labelled `label`, selects its text and types `text` over it.
fn fill(h: &mut H, label: &str, text: &str) {
    h.get_by_label(label).click();
    frames(h);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    frames(h);
    type_keys(h, text);
    assert_eq!(h.get_by_label(label).value().as_deref(), Some(text), "the {label} field took the typed text");
}

/// File > `item`, then the dialog's fields in order (label, text), then `button`.
fn session_dialog(h: &mut H, item: &str, fields: &[(&str, &str)], button: &str) {
    h.get_by_label("File").click();
    frames(h);
    h.get_by_label(item).click();
    frames(h);
    assert!(h.state().modal_open(), "{item} opens its dialog");
    for (label, text) in fields {
        fill(h, label, text);
    }
    h.get_by_label(button).click();
    frames(h);
}

/// Steps both studios (their networks run on their own threads) until `done` holds.
fn settle(a: &mut H, b: &mut H, what: &str, done: impl Fn(&StudioApp, &StudioApp) -> bool) {
    let start = Instant::now();
    while !done(a.state(), b.state()) {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "timed out waiting for {what}:\n  {} ({:?})\n  {} ({:?})",
            a.state().studio.status(),
            a.state().studio.notice,
            b.state().studio.status(),
            b.state().studio.notice
        );
        a.step();
        b.step();
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn digests(app: &StudioApp) -> Vec<strata_editor::file::ChunkDigest> {
    strata_editor::file::chunk_digests(&app.studio.editor.scene).expect("the scene encodes")
}

/// Both hold the same volumes and nothing of theirs waits for the room.
fn same(a: &StudioApp, b: &StudioApp) -> bool {
    let idle = |s: &StudioApp| s.studio.collab.as_ref().is_some_and(|c| c.session.replica().pending() == 0);
    idle(a) && idle(b) && digests(a) == digests(b)
}

/// Steps the host until its own connection has made the room. A guest asking before that is
/// told there is no such room; a user joins after being given the address, by then long made.
fn wait_for_the_room(host: &mut H) {
    let start = Instant::now();
    while !in_room(host.state()) {
        assert!(start.elapsed() < Duration::from_secs(60), "the host's room: {}", host.state().studio.status());
        host.step();
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn in_room(app: &StudioApp) -> bool {
    app.studio
        .collab
        .as_ref()
        .is_some_and(|c| *c.session.state() == strata_net::SessionState::InRoom && c.session.replica().has_scene())
}

/// A left drag across the middle of the viewport (where both studios see the default ball),
/// stepping `other` between moves so that the room's traffic flows while the stroke is made.
fn stroke(h: &mut H, other: &mut H, from: egui::Pos2, steps: usize) {
    h.hover_at(from);
    h.step();
    h.drag_at(from);
    h.step();
    for i in 1..=steps {
        h.hover_at(from + egui::vec2(i as f32 * 4.0, 0.0));
        h.step();
        other.step();
    }
    h.drop_at(from + egui::vec2(steps as f32 * 4.0, 0.0));
    h.step();
    h.step();
}

#[test]
fn two_studios_host_join_sculpt_see_each_other_undo_through_the_room_and_leave() {
    let mut host = harness("host", default_scene());
    frames(&mut host);
    let start = digests(host.state());
    // File > Host session on a free loopback port, with a token of our own.
    session_dialog(
        &mut host,
        "Host session…",
        &[("Listen on", "127.0.0.1:0"), ("Room", "atelier"), ("Token", "s3cret"), ("Your name", "Ana")],
        "Host",
    );
    assert!(!host.state().modal_open(), "Host closes the dialog: {}", host.state().studio.message);
    let url = host.state().studio.collab.as_ref().expect("hosting").share.clone();
    assert!(url.starts_with("ws://127.0.0.1:"), "the address to share: {url}");
    wait_for_the_room(&mut host);
    // The joiner has unsaved work of its own: joining asks about it first.
    let mut guest = harness("guest", strata_editor::Scene::default());
    frames(&mut guest);
    guest.state_mut().studio.editor.touch();
    session_dialog(
        &mut guest,
        "Join session…",
        &[("Server", &url), ("Room", "atelier"), ("Token", "s3cret"), ("Your name", "Ben")],
        "Join",
    );
    assert!(guest.state().modal_open(), "the unsaved-changes question is up before the scene is replaced");
    assert!(guest.state().studio.collab.is_none(), "nothing joined before the answer");
    guest.get_by_label("Don't save").click();
    frames(&mut guest);
    settle(&mut host, &mut guest, "both in the room with its scene", |a, b| in_room(a) && in_room(b) && same(a, b));
    assert_eq!(digests(guest.state()), start, "the guest holds the host's scene");
    assert_eq!(guest.state().studio.path, None, "the room's scene is in no file of the guest's");
    assert!(guest.state().sent_title().contains("(room atelier)"), "{}", guest.state().sent_title());
    // The people panel names the others.
    frames(&mut host);
    frames(&mut guest);
    settle(&mut host, &mut guest, "each sees the other", |a, b| {
        let sees = |s: &StudioApp, who: &str| {
            s.studio.collab.as_ref().is_some_and(|c| c.session.peers().any(|(_, n, _)| n == who))
        };
        sees(a, "Ben") && sees(b, "Ana")
    });
    // With both pointers off the model, each panel says the other's brush is away.
    host.hover_at(egui::pos2(20.0, 780.0));
    guest.hover_at(egui::pos2(20.0, 780.0));
    settle(&mut host, &mut guest, "both brushes away", |a, b| {
        let away = |s: &StudioApp| {
            s.studio.collab.as_ref().is_some_and(|c| c.session.peers().all(|(_, _, p)| p.position.is_none()))
        };
        away(a) && away(b)
    });
    host.step();
    guest.step();
    host.get_by_label("Ben (away from the model)");
    guest.get_by_label("Ana (away from the model)");
    guest.get_by_label("Ben (you)");

    // A stroke in the host appears in the guest.
    let centre = egui::pos2(640.0, 400.0);
    stroke(&mut host, &mut guest, centre, 8);
    assert_ne!(digests(host.state()), start, "the host's drag sculpted: {}", host.state().studio.message);
    settle(&mut host, &mut guest, "the host's stroke in the guest", same);
    // The guest's brush over the model shows in the host, where it is.
    guest.hover_at(centre);
    settle(&mut host, &mut guest, "the guest's brush in the host", |a, _| {
        a.studio.collab.as_ref().is_some_and(|c| c.session.peers().any(|(_, n, p)| n == "Ben" && p.position.is_some()))
    });

    // The guest sculpts over the host's stroke; the host's undo is refused, naming the guest.
    stroke(&mut guest, &mut host, centre + egui::vec2(-8.0, 0.0), 8);
    settle(&mut host, &mut guest, "the guest's stroke in the host", same);
    let both = digests(host.state());
    host.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    frames(&mut host);
    settle(&mut host, &mut guest, "the room's answer to the host's undo", |a, _| a.studio.notice.is_some());
    let notice = host.state().studio.notice.clone().unwrap();
    assert!(notice.contains("Ben"), "the refusal names who edited since: {notice}");
    // The answer may arrive after the frame's drawing (the room is read at the frame's end):
    // one more frame draws the notice before it is dismissed, as a user sees it.
    frames(&mut host);
    host.get_by_label("Dismiss").click();
    frames(&mut host);
    settle(&mut host, &mut guest, "nothing changed", same);
    assert_eq!(digests(host.state()), both, "a refused undo changes nothing");
    // With nothing undone there is nothing to redo, and the studio says so.
    host.key_press_modifiers(egui::Modifiers::COMMAND | egui::Modifiers::SHIFT, egui::Key::Z);
    frames(&mut host);
    assert_eq!(host.state().studio.message, "Nothing to redo");
    // A brush past the room's radius limit is refused before it sculpts (not made in the frame
    // and then taken back).
    // (A brush of 40 units on cells of 0.1: 400 cells. The panel keeps radii within 64 units,
    // so only a layer of fine cells reaches past the limit; the cells are set here directly.)
    let (radius, cell) =
        (host.state().studio.editor.tool.radius, host.state().studio.editor.scene.layers[0].transform.scale);
    host.state_mut().studio.editor.tool.radius = 40.0;
    host.state_mut().studio.editor.scene.layers[0].transform.scale = 0.1;
    stroke(&mut host, &mut guest, centre, 2);
    let notice = host.state_mut().studio.notice.take().expect("the refusal is said");
    assert!(notice.contains("256 cells") && notice.contains("400"), "{notice}");
    assert_eq!(digests(host.state()), both, "nothing was sculpted");
    host.state_mut().studio.editor.tool.radius = radius;
    host.state_mut().studio.editor.scene.layers[0].transform.scale = cell;
    // The palette is the room's: its materials are not edited here.
    assert!(host.query_by_label("material name").is_none(), "the material editor is hidden in a room");
    // A structure change is refused in a room, with how to get out.
    host.get_by_label("Add").click();
    frames(&mut host);
    assert_eq!(host.state().studio.editor.scene.layers.len(), 1);
    assert!(host.state().studio.message.contains("Leave session"), "{}", host.state().studio.message);
    host.state_mut().studio.notice = None;
    frames(&mut host);

    // The guest's connection drops; it reconnects by itself and the room goes on.
    guest.state().studio.collab.as_ref().unwrap().session.drop_connection();
    let welcomes = |s: &StudioApp| s.studio.collab.as_ref().map_or(0, |c| c.session.welcomes());
    assert_eq!(welcomes(guest.state()), 1);
    settle(&mut host, &mut guest, "the guest back in the room", |a, b| welcomes(b) == 2 && in_room(b) && same(a, b));
    // The guest undoes its stroke (the host's comes back as it was), then the host undoes its own.
    guest.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    frames(&mut guest);
    settle(&mut host, &mut guest, "the guest's undo everywhere", |a, b| same(a, b) && digests(a) != both);
    assert!(guest.state().studio.notice.is_none(), "{:?}", guest.state().studio.notice);
    // Redo makes the guest's stroke again, bit for bit, everywhere; undo takes it back again.
    guest.key_press_modifiers(egui::Modifiers::COMMAND | egui::Modifiers::SHIFT, egui::Key::Z);
    frames(&mut guest);
    settle(&mut host, &mut guest, "the guest's redo everywhere", |a, b| same(a, b) && digests(a) == both);
    guest.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    frames(&mut guest);
    settle(&mut host, &mut guest, "the guest's second undo everywhere", |a, b| same(a, b) && digests(a) != both);
    assert!(guest.state().studio.notice.is_none(), "{:?}", guest.state().studio.notice);
    host.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    frames(&mut host);
    settle(&mut host, &mut guest, "the host's undo everywhere", |a, b| same(a, b) && digests(a) == start);
    assert!(host.state().studio.notice.is_none(), "{:?}", host.state().studio.notice);

    // The guest leaves: the scene stays, the host sees them go.
    guest.get_by_label("Leave session").click();
    frames(&mut guest);
    assert!(guest.state().studio.collab.is_none());
    assert_eq!(digests(guest.state()), start, "the scene stays after leaving");
    settle(&mut host, &mut guest, "the host sees the guest leave", |a, _| {
        a.studio.collab.as_ref().is_some_and(|c| c.session.peers().count() == 0)
    });
    // Back on its own, the guest's strokes are its own history again.
    stroke(&mut guest, &mut host, centre, 4);
    assert_eq!(guest.state().studio.editor.history().undo_len(), 1, "{}", guest.state().studio.message);
    assert_eq!(digests(host.state()), start, "a stroke after leaving stays out of the room");
    host.get_by_label("Close the room").click();
    frames(&mut host);
    assert!(host.state().studio.collab.is_none());
}

#[test]
fn a_wrong_token_is_said_and_leaves_the_scene_alone() {
    let mut host = harness("host-token", default_scene());
    frames(&mut host);
    session_dialog(
        &mut host,
        "Host session…",
        &[("Listen on", "127.0.0.1:0"), ("Room", "atelier"), ("Token", "right"), ("Your name", "Ana")],
        "Host",
    );
    let url = host.state().studio.collab.as_ref().expect("hosting").share.clone();
    let mut guest = harness("guest-token", strata_editor::Scene::default());
    frames(&mut guest);
    let before = digests(guest.state());
    session_dialog(
        &mut guest,
        "Join session…",
        &[("Server", &url), ("Room", "atelier"), ("Token", "wrong"), ("Your name", "Eve")],
        "Join",
    );
    settle(&mut host, &mut guest, "the refusal", |_, b| b.studio.collab.is_none());
    let notice = guest.state().studio.notice.clone().expect("the refusal is a notice");
    assert!(notice.contains("no room `atelier` with that token"), "{notice}");
    assert_eq!(digests(guest.state()), before, "the scene is untouched");
    assert!(guest.state().studio.editor.history().undo_len() == 0);
    // A server that is not there: the session keeps trying and says so.
    guest.state_mut().studio.notice = None;
    drop(host);
    session_dialog(
        &mut guest,
        "Join session…",
        &[("Server", &url), ("Room", "atelier"), ("Token", "right"), ("Your name", "Eve")],
        "Join",
    );
    let start = Instant::now();
    loop {
        guest.step();
        if guest.state().studio.status().contains("reconnecting") {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "{}", guest.state().studio.status());
        std::thread::sleep(Duration::from_millis(10));
    }
    // Until the room's scene arrives, the scene on screen is not sculpted (a stroke on it
    // would go into the room's).
    let mut nobody = harness("nobody", default_scene());
    guest.state_mut().studio.editor.tool.radius = 2.5;
    stroke(&mut guest, &mut nobody, egui::pos2(640.0, 400.0), 4);
    assert_eq!(digests(guest.state()), before, "a stroke before the room's scene changed nothing");
    assert!(guest.state().studio.message.contains("Waiting for room"), "{}", guest.state().studio.message);
    guest.get_by_label("Leave session").click();
    frames(&mut guest);
    assert!(guest.state().studio.collab.is_none());
}

/// Steps `h` until its world has streamed in and is meshed, looking down at the ground.
fn settle_world(h: &mut H, other: &mut H) {
    h.state_mut().studio.terrain.as_mut().unwrap().pitch = 1.2;
    let start = Instant::now();
    loop {
        h.step();
        other.step();
        let s = &h.state().studio;
        let w = s.editor.world().unwrap();
        if w.loaded_count() > 50 && w.pending_count() == 0 && s.editor.pending() == 0 {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "the world did not settle: {}", s.status());
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn world_chunks(app: &StudioApp) -> Vec<(strata_volume::ChunkKey, strata_terrain::StoredChunk)> {
    app.studio.editor.world().expect("a world").edited_chunks().unwrap()
}

#[test]
fn a_world_is_hosted_joined_and_dug_together() {
    let dir = std::env::temp_dir().join(format!("strata-session-{}-world", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut host = harness("world-host", default_scene());
    frames(&mut host);
    // Terrain > New world…, a typed path.
    host.get_by_label("Terrain").click();
    frames(&mut host);
    host.get_by_label("New world…").click();
    frames(&mut host);
    type_keys(&mut host, &dir.join("shared.world").display().to_string());
    host.key_press(egui::Key::Enter);
    frames(&mut host);
    assert!(host.state().studio.terrain.is_some(), "{}", host.state().studio.message);
    session_dialog(
        &mut host,
        "Host session…",
        &[("Listen on", "127.0.0.1:0"), ("Room", "valley"), ("Token", "t"), ("Your name", "Ana")],
        "Host",
    );
    let url = host.state().studio.collab.as_ref().expect("hosting").share.clone();
    assert!(
        host.state().studio.editor.world().is_some_and(strata_editor::room::is_shareable),
        "the world is shared at one level"
    );
    wait_for_the_room(&mut host);
    let mut guest = harness("world-guest", default_scene());
    frames(&mut guest);
    session_dialog(
        &mut guest,
        "Join session…",
        &[("Server", &url), ("Room", "valley"), ("Token", "t"), ("Your name", "Ben")],
        "Join",
    );
    settle(&mut host, &mut guest, "both in the room", |a, b| in_room(a) && in_room(b));
    assert!(guest.state().studio.terrain.is_some(), "the guest flies through the room's world");
    assert!(guest.state().studio.editor.world().unwrap().store().is_none(), "kept in memory at the guest's");
    settle_world(&mut host, &mut guest);
    settle_world(&mut guest, &mut host);
    let generated = world_chunks(host.state());
    // The host digs; the guest's world gets the same chunks.
    stroke(&mut host, &mut guest, egui::pos2(640.0, 400.0), 6);
    settle(&mut host, &mut guest, "the host's dig at the guest's", |a, b| {
        let idle = |s: &StudioApp| s.studio.collab.as_ref().is_some_and(|c| c.session.replica().pending() == 0);
        idle(a) && idle(b) && world_chunks(a) == world_chunks(b)
    });
    assert!(world_chunks(host.state()) != generated, "the drag dug: {}", host.state().studio.message);
    // Bombs are refused in a room (a crater is not an operation the room replays).
    host.key_press(egui::Key::B);
    frames(&mut host);
    assert!(host.state().studio.terrain.as_ref().unwrap().projectiles.is_empty());
    assert!(host.state().studio.message.contains("bombs"), "{}", host.state().studio.message);
    host.state_mut().studio.notice = None;
    // The guest undoes nothing of the host's; the host's undo takes the dig back everywhere.
    host.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    frames(&mut host);
    settle(&mut host, &mut guest, "the host's undo at the guest's", |a, b| {
        world_chunks(a) == generated && world_chunks(b) == generated
    });
    // The guest leaves and closes the room's world: back to a scene.
    guest.get_by_label("Leave session").click();
    frames(&mut guest);
    guest.get_by_label("Terrain").click();
    frames(&mut guest);
    guest.get_by_label("Close world").click();
    frames(&mut guest);
    assert!(guest.state().studio.terrain.is_none() && guest.state().studio.editor.world().is_none());
    assert_eq!(guest.state().studio.editor.scene.layers.len(), 1, "a fresh scene");
    host.get_by_label("Close the room").click();
    frames(&mut host);
}
