//! The studio's state and actions driven without a window.

mod studio_tests_shared {
    use super::super::*;

    pub fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("strata-studio-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    pub const DOWN: Buttons = Buttons { primary: true, secondary: false };
    pub const BUDGET: Duration = Duration::from_millis(20);
}

mod studio_tests {
    use super::super::*;
    use super::studio_tests_shared::*;

    #[test]
    fn dragging_over_the_clay_sculpts_and_undo_takes_it_back() {
        let mut s = Studio::new(default_scene());
        let before = s.editor.scene.layers[0].volume.clone();
        // The centre of the view looks at the ball.
        let p = s.surface_point(0.0, 0.0, 1.5).expect("the ball is under the centre");
        assert!((p - DVec3::new(32.0, 18.0, 32.0)).length() < 16.5);
        for i in 0..10 {
            s.pointer(Some((i as f32 * 0.01, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        }
        s.pointer(Some((0.1, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        assert_eq!(s.editor.history().undo_len(), 1);
        let _ = s.editor.take_changes();
        s.pointer(Some((0.2, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        s.pointer(Some((0.3, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        let changes = s.editor.take_changes();
        assert!(!changes.full && !changes.meshes.is_empty(), "remeshed chunks are listed for upload");
        s.act(Action::Undo).unwrap();
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers[0].volume, before);
        s.act(Action::Redo).unwrap();
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        assert!(s.status().contains("crossings"));
    }

    #[test]
    fn a_stroke_does_not_climb_onto_its_own_material() {
        let mut s = Studio::new(default_scene());
        s.editor.tool.radius = 3.0;
        let start = s.surface_point(0.0, 0.0, 1.0).unwrap();
        // Holding still for many frames adds at the same place: nothing grows towards the eye.
        for _ in 0..30 {
            s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.0, BUDGET);
        }
        s.pointer(Some((0.0, 0.0)), Buttons::default(), 1.0, 1.0, BUDGET);
        let eye = s.camera.eye().as_dvec3();
        let front = s.surface_point(0.0, 0.0, 1.0).unwrap();
        let grown = (start - eye).length() - (front - eye).length();
        assert!(grown < 3.5, "the surface moved {grown} towards the eye (brush radius 3)");
        assert!(grown > 1.0, "the dab added material in front of the start ({grown})");
    }

    #[test]
    fn a_dab_too_large_for_a_frame_runs_in_the_background_and_can_be_cancelled() {
        let mut s = Studio::new(default_scene());
        s.background_chunks = 1;
        s.editor.tool.radius = 12.0;
        let before = s.editor.scene.layers[0].volume.clone();
        s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        assert!(s.busy(), "the dab runs on a worker");
        // Cancelled: nothing changes.
        s.job.as_ref().unwrap().cancel();
        while !s.poll_job() {
            std::thread::sleep(Duration::from_millis(2));
        }
        s.pointer(Some((0.0, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert!(!s.busy());
        assert_eq!(s.editor.scene.layers[0].volume, before, "a cancelled dab changes nothing: {}", s.message);
        assert_eq!(s.editor.history().undo_len(), 0);
        // Run to the end: one undo step.
        s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        while !s.poll_job() {
            std::thread::sleep(Duration::from_millis(2));
        }
        assert!(s.message.contains("chunks changed"), "{}", s.message);
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        // Holding still does not repeat the dab.
        s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        assert!(!s.busy());
        s.pointer(Some((0.0, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert_eq!(s.editor.history().undo_len(), 1);
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers[0].volume, before);
    }

    #[test]
    fn holding_shift_smooths_and_the_field_tools_sculpt_through_the_pointer() {
        let mut s = Studio::new(default_scene());
        s.editor.tool.radius = 5.0;
        // A bump to smooth away, under the centre of the view.
        let p = s.surface_point(0.0, 0.0, 1.5).unwrap();
        let g = s.editor.scene.layers[0].transform.to_grid(p);
        s.editor.scene.layers[0].volume.add(&Sphere::new(g, 2.5 / DEFAULT_CELL).unwrap()).unwrap();
        s.editor.reset_caches();
        let bumped = s.editor.scene.layers[0].volume.clone();
        s.smooth_held = true;
        for _ in 0..3 {
            s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        }
        s.pointer(Some((0.0, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert_eq!(s.editor.tool.kind, ToolKind::Clay, "Shift only lends the smooth tool");
        let smoothed = s.editor.scene.layers[0].volume.clone();
        assert_ne!(smoothed, bumped, "{}", s.message);
        smoothed.check_invariants().unwrap();
        s.smooth_held = false;
        for kind in [ToolKind::Inflate, ToolKind::Flatten, ToolKind::Pinch] {
            s.set_kind(kind);
            let before = s.editor.scene.layers[0].volume.clone();
            s.pointer(Some((0.05, 0.0)), DOWN, 1.0, 1.5, BUDGET);
            s.pointer(Some((0.05, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
            assert_ne!(s.editor.scene.layers[0].volume, before, "{kind:?}: {}", s.message);
        }
        for _ in 0..4 {
            s.act(Action::Undo).unwrap();
        }
        assert_eq!(s.editor.scene.layers[0].volume, bumped, "four strokes, four undo steps");
    }

    #[test]
    fn the_default_ball_is_smooth_and_grab_and_the_inverse_tool_work_through_the_pointer() {
        let mut s = Studio::new(default_scene());
        s.editor.finish_meshing();
        let triangles = s.editor.triangle_count();
        assert!(triangles >= 100_000, "the default ball has {triangles} triangles");
        let cells = s.editor.tool.radius / s.editor.scene.layers[0].transform.scale;
        assert!((cells - 10.0).abs() < 1e-9, "the default brush is 10 cells ({cells})");
        // Grab: press on the ball and drag sideways; the surface follows, as one step.
        let before = s.editor.scene.layers[0].volume.clone();
        s.set_kind(ToolKind::Grab);
        for i in 0..6 {
            s.pointer(Some((0.0, i as f32 * 0.01)), DOWN, 1.0, 1.5, BUDGET);
        }
        s.pointer(Some((0.0, 0.05)), Buttons::default(), 1.0, 1.5, BUDGET);
        let grabbed = s.editor.scene.layers[0].volume.clone();
        assert!(grabbed != before, "grab moved the surface: {}", s.message);
        grabbed.check_invariants().unwrap();
        assert_eq!(s.editor.history().undo_len(), 1);
        // Ctrl or Alt held: clay carves instead of adding.
        s.set_kind(ToolKind::Clay);
        s.inverse_held = true;
        let v0 = grabbed.measured_volume(strata_volume::Axis::X);
        s.pointer(Some((0.1, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        s.pointer(Some((0.1, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        let v1 = s.editor.scene.layers[0].volume.measured_volume(strata_volume::Axis::X);
        assert!(v1 < v0, "the inverse of clay carves: {v0} -> {v1}");
        // Oriented brushes follow the surface under the pointer.
        s.inverse_held = false;
        s.editor.tool.orient_to_normal = true;
        s.pointer(Some((0.2, 0.1)), Buttons::default(), 1.0, 1.5, BUDGET);
        let n = s.hover_normal.expect("the pointer is over the ball");
        assert!((s.brush_orientation() * DVec3::Y - n).length() < 1e-9);
    }

    #[test]
    fn merge_down_unites_moved_layers_and_refuses_turned_ones() {
        let mut s = Studio::new(default_scene());
        s.act(Action::DuplicateLayer).unwrap();
        assert_eq!(s.editor.active_layer, 1);
        // Move the copy 8 cells along x (and a little: the offset is rounded to whole cells).
        let cell = s.editor.scene.layers[1].transform.scale;
        s.editor.scene.layers[1].transform.translation.x += 8.2 * cell;
        s.act(Action::MoveLayer(-1)).unwrap();
        assert_eq!(s.editor.active_layer, 0);
        let (upper, lower) = (s.editor.scene.layers[0].clone(), s.editor.scene.layers[1].clone());
        s.act(Action::MergeDown).unwrap();
        assert_eq!(s.editor.scene.layers.len(), 1);
        assert_eq!(s.editor.history().undo_len(), 3, "duplicate, move and merge are undo steps");
        let merged = &s.editor.scene.layers[0].volume;
        merged.check_invariants().unwrap();
        let c = glam::I64Vec3::new(128, 72, 128);
        for x in -80..90 {
            let n = c + glam::I64Vec3::new(x, 0, 0);
            let want = lower.volume.node_inside(n) || upper.volume.node_inside(n - glam::I64Vec3::new(8, 0, 0));
            assert_eq!(merged.node_inside(n), want, "node {n}");
        }
        assert!(merged.node_inside(c + glam::I64Vec3::new(70, 0, 0)), "the moved copy reaches further");
        // Undo takes the merge back, then the move; redo merges again.
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers.len(), 2);
        assert!(s.editor.take_changes().full, "the layer list changed: everything is drawn anew");
        assert_eq!(s.editor.scene.layers[0].volume, upper.volume);
        s.act(Action::Redo).unwrap();
        assert_eq!(s.editor.scene.layers.len(), 1);
        let merged = s.editor.scene.layers[0].volume.clone();
        // A stroke after the merge, then undoing everything, restores the one ball.
        s.act(Action::Undo).unwrap();
        s.act(Action::Undo).unwrap();
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers.len(), 1);
        assert_eq!(s.editor.scene.layers[0].volume, lower.volume);
        for _ in 0..3 {
            s.act(Action::Redo).unwrap();
        }
        assert_eq!(s.editor.scene.layers[0].volume, merged);
        // Turned layers are not merged.
        s.act(Action::DuplicateLayer).unwrap();
        s.editor.scene.layers[1].transform.rotation = DQuat::from_rotation_y(0.3);
        s.act(Action::MoveLayer(-1)).unwrap();
        let err = s.act(Action::MergeDown).unwrap_err();
        assert!(err.contains("same rotation"), "{err}");
        assert_eq!(s.editor.scene.layers.len(), 2);
        // Nothing below the last layer.
        s.editor.active_layer = 1;
        assert!(s.act(Action::MergeDown).is_err());
    }

    #[test]
    fn mirroring_centres_on_the_model_and_mirrors_strokes() {
        let mut s = Studio::new(default_scene());
        s.editor.finish_meshing();
        s.toggle_symmetry(0);
        assert_eq!(s.editor.tool.symmetry, [true, false, false]);
        assert_eq!(s.editor.tool.symmetry_center.x, 32.0 / DEFAULT_CELL, "the ball's centre: {}", s.message);
        let before = s.editor.scene.layers[0].volume.clone();
        s.pointer(Some((0.3, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        s.pointer(Some((0.3, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        s.toggle_symmetry(0);
        assert_eq!(s.editor.tool.symmetry, [false; 3]);
    }

    #[test]
    fn the_line_tool_strokes_between_two_clicks() {
        let mut s = Studio::new(default_scene());
        s.editor.tool.radius = 2.0;
        let before = s.editor.scene.layers[0].volume.clone();
        s.toggle_line_tool();
        for x in [-0.2f32, 0.2] {
            s.pointer(Some((x, 0.1)), DOWN, 1.0, 1.5, BUDGET);
            s.pointer(Some((x, 0.1)), Buttons::default(), 1.0, 1.5, BUDGET);
        }
        assert!(!s.line_mode, "the second click ends the line tool");
        assert!(s.message.starts_with("Line:"), "{}", s.message);
        assert!(s.editor.scene.layers[0].volume != before, "the stroke changed the volume: {}", s.message);
        assert_eq!(s.editor.history().undo_len(), 1, "one step");
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers[0].volume, before);
    }

    #[test]
    fn moving_a_layer_undoes_and_redraws() {
        let mut s = Studio::new(default_scene());
        let _ = s.editor.take_changes();
        let t0 = s.editor.scene.layers[0].transform;
        let moved = strata_editor::LayerTransform { translation: DVec3::new(3.0, 0.0, 0.0), ..t0 };
        s.editor.set_layer_transform(0, moved, false).unwrap();
        assert!(s.is_modified());
        assert_eq!(s.editor.take_changes().layers, vec![0], "the moved layer is drawn where it went");
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.scene.layers[0].transform, t0);
        let changes = s.editor.take_changes();
        assert_eq!(changes.layers, vec![0], "the layer is drawn where it is now");
        assert!(!changes.full && changes.meshes.iter().all(|(l, _)| *l != 0));
        assert_eq!(s.editor.take_changes(), strata_editor::ChangeList::default(), "then nothing more");
    }

    #[test]
    fn radius_keys_wireframe_and_layers() {
        let mut s = Studio::new(default_scene());
        let r = s.editor.tool.radius;
        s.act(Action::ScaleRadius(1.25)).unwrap();
        assert!((s.editor.tool.radius - r * 1.25).abs() < 1e-12);
        s.act(Action::ScaleRadius(1e9)).unwrap();
        assert_eq!(s.editor.tool.radius, 256.0);
        s.act(Action::ToggleWireframe).unwrap();
        assert!(s.wireframe);
        s.act(Action::AddLayer).unwrap();
        assert_eq!((s.editor.scene.layers.len(), s.editor.active_layer), (2, 1));
        assert!(!s.preview_mesh().indices.is_empty());
    }

    #[test]
    fn files_save_open_and_fail_without_losing_the_scene() {
        let mut s = Studio::new(default_scene());
        assert!(s.act(Action::Save).is_err(), "no path yet");
        let path = temp("scene.strata");
        s.camera.yaw = 1.25;
        s.act(Action::SaveAs(path.clone())).unwrap();
        let saved = s.editor.scene.clone();
        s.act(Action::New).unwrap();
        s.act(Action::Open(path.clone())).unwrap();
        assert_eq!(s.editor.scene, saved);
        assert!((s.camera.yaw - 1.25).abs() < 1e-6, "the view comes back");
        // A truncated file fails and the open scene stays.
        let bad = temp("bad.strata");
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&bad, &bytes[..bytes.len() - 3]).unwrap();
        let err = s.act(Action::Open(bad.clone())).unwrap_err();
        assert!(err.contains("truncated"), "{err}");
        assert_eq!(s.editor.scene, saved);
        assert_eq!(s.path.as_deref(), Some(path.as_path()));
        // A damaged one opens with what could be recovered, saying so, and counts as unsaved.
        let mut damaged = bytes.clone();
        let n = damaged.len();
        damaged[n - 3] ^= 0xff;
        std::fs::write(&bad, damaged).unwrap();
        s.act(Action::Open(bad)).unwrap();
        assert!(s.message.contains("repairs") && s.message.contains("checksum"), "{}", s.message);
        assert!(s.is_modified());
        assert_eq!(s.editor.scene.layers, saved.layers);
        s.act(Action::Open(path.clone())).unwrap();
        // Export in every format.
        for ext in ["glb", "obj", "stl", "ply"] {
            s.act(Action::Export(temp(&format!("out.{ext}")))).unwrap();
        }
        assert!(s.act(Action::Export(temp("out.xyz"))).is_err());
    }
}

mod island_tests {
    use super::super::*;

    #[test]
    fn exports_drop_stray_islands_for_stl_by_default_and_say_so() {
        let dir = std::env::temp_dir().join(format!("strata-studio-specks-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut s = Studio::new(default_scene());
        // A speck: one solid node well away from the ball.
        let cell = s.editor.scene.layers[0].transform.scale;
        let speck = DVec3::new(90.0, 18.0, 32.0) / cell;
        s.editor.scene.layers[0].volume.add(&Sphere::new(speck.round(), 0.4).unwrap()).unwrap();
        let count = |path: &std::path::Path| strata_mesh::import::load_mesh(path).unwrap().triangles.len();
        let stl = dir.join("print.stl");
        s.act(Action::Export(stl.clone())).unwrap();
        assert!(s.message.contains("removed 1 islands"), "{}", s.message);
        let obj = dir.join("game.obj");
        s.act(Action::Export(obj.clone())).unwrap();
        assert!(!s.message.contains("islands"), "{}", s.message);
        assert!(count(&obj) > count(&stl), "the OBJ keeps the speck's triangles");
        s.islands = Islands::Keep;
        s.act(Action::Export(stl.clone())).unwrap();
        assert_eq!(count(&stl), count(&obj), "kept when asked");
        s.islands = Islands::Remove;
        s.act(Action::Export(obj.clone())).unwrap();
        assert!(s.message.contains("removed 1 islands"), "{}", s.message);
        let _ = std::fs::remove_dir_all(&dir);
    }
}

mod world_tests {
    use super::super::*;
    use super::studio_tests_shared::*;

    /// A world opened in the studio becomes what the tools, the pointer and undo edit; scene
    /// commands wait for it and say so (none silently does nothing); the world is written on
    /// request; saving the scene saves the scene waiting for the world; closing the world gives
    /// the scene and its camera back.
    #[test]
    fn a_world_takes_the_tools_while_scene_commands_wait_and_the_scene_comes_back() {
        let mut s = Studio::new(default_scene());
        // A view that holds the ground under the eye (as the studio's terrain test).
        s.world_settings.view_distance = 40.0;
        s.world_settings.vertical_ratio = 1.5;
        s.world_settings.detail_distance = 16.0;
        s.world_settings.threads = 1;
        // Unsaved work in the scene.
        s.act(Action::AddLayer).unwrap();
        assert!(s.is_modified());
        let (scene, camera) = (s.editor.scene.clone(), s.camera);
        let path = temp("studio.world");
        let _ = std::fs::remove_file(&path);
        s.act(Action::NewWorld(path.clone(), 4)).unwrap();
        assert!(s.editor.world().is_some(), "the editor is the world's");
        assert!(s.is_modified(), "the scene's unsaved state is still known");
        for action in [
            Action::AddLayer,
            Action::DeleteLayer,
            Action::New,
            Action::Open(temp("x.strata")),
            Action::Export(temp("x.obj")),
            Action::FrameAll,
            Action::ViewMesher(strata_mesh::MeshOptions::new(strata_mesh::Mesher::DualContouring)),
        ] {
            let what = format!("{action:?}");
            let err = s.act(action).expect_err(&what);
            assert!(err.contains("Close world"), "{what}: {err}");
        }
        let err = s.choose_import(temp("bunny.ply")).expect_err("import waits too");
        assert!(err.contains("Close world"), "{err}");
        // A stroke through the pointer, looking down at the ground, is a step of the world's
        // editor; Ctrl+S writes the world.
        let t = s.terrain.as_mut().unwrap();
        let mut editor = std::mem::take(&mut s.editor);
        assert!(t.settle(&mut editor, Duration::from_secs(60)));
        s.editor = editor;
        let t = s.terrain.as_mut().unwrap();
        t.pitch = 1.4;
        s.camera = t.camera();
        let before = s.editor.world().unwrap().volume().clone();
        s.pointer(Some((0.0, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        s.pointer(Some((0.05, 0.0)), DOWN, 1.0, 1.5, BUDGET);
        s.pointer(Some((0.05, 0.0)), Buttons::default(), 1.0, 1.5, BUDGET);
        assert_ne!(s.editor.world().unwrap().volume(), &before, "{}", s.message);
        assert_eq!(s.editor.history().undo_len(), 1);
        s.act(Action::SaveWorld).unwrap();
        assert!(s.message.contains("World written"), "{}", s.message);
        // Saving the scene while the world is open saves the scene waiting for it (the quit
        // question's Save does this), not the world.
        let scene_file = temp("waiting.strata");
        s.act(Action::SaveAs(scene_file.clone())).unwrap();
        assert!(!s.is_modified(), "{}", s.message);
        let saved = strata_editor::file::load(&scene_file).unwrap().scene;
        assert_eq!(saved.layers.len(), scene.layers.len(), "the scene's file holds the scene");
        s.act(Action::AddLayer).expect_err("the layers still wait");
        s.act(Action::Undo).unwrap();
        assert_eq!(s.editor.world().unwrap().volume(), &before);
        s.act(Action::CloseWorld).unwrap();
        assert!(s.terrain.is_none() && s.editor.world().is_none());
        assert!(s.editor.scene.layers == scene.layers && s.camera == camera, "the scene and its camera came back");
        assert!(!s.is_modified(), "saved while the world was open");
        let _ = std::fs::remove_file(&path);
    }
}
