//! The viewport and exports by every mesher: the editor's chunk meshes meet across chunk
//! borders after strokes, exports are closed, bad choices are refused with a clear error.

use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::{Buttons, Editor, EditorError, Scene, ToolKind, ToolPose};
use strata_mesh::checks::{check_closed_manifold, manifold_report, signed_volume};
use strata_mesh::{Mesh, MeshOptions, Mesher, MesherError};
use strata_volume::brush::Sphere;

fn ball_editor() -> Editor {
    let mut scene = Scene::default();
    scene.layers[0].volume.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 10.0).unwrap()).unwrap();
    Editor::new(scene)
}

/// The viewport's chunk meshes of layer 0, welded by exact position (chunk meshes share their
/// border vertices bit for bit). Dual contouring's chunk meshes repeat vertices of the cells
/// before them, which weld the same way.
fn viewport(e: &Editor) -> Mesh {
    let mut parts = e.chunk_meshes(0);
    parts.sort_by_key(|(k, _)| *k);
    strata_mesh::checks::weld_by_position(parts)
}

fn stroke(e: &mut Editor) {
    for i in 0..=4 {
        let p = DVec3::new(26.0, 12.0 + 2.0 * i as f64, 16.0);
        let pose = ToolPose {
            position: p,
            orientation: DQuat::IDENTITY,
            pressure: 1.0,
            buttons: Buttons { primary: true, secondary: false },
            ..ToolPose::default()
        };
        e.frame(&pose, Duration::from_millis(50)).unwrap();
    }
    let pose = ToolPose {
        position: DVec3::new(26.0, 20.0, 16.0),
        orientation: DQuat::IDENTITY,
        pressure: 1.0,
        buttons: Buttons { primary: false, secondary: false },
        ..ToolPose::default()
    };
    e.frame(&pose, Duration::from_millis(50)).unwrap();
    e.finish_meshing();
}

#[test]
fn every_viewport_mesher_meshes_closed_after_strokes_and_undo() {
    for mesher in Mesher::ALL {
        let mut e = ball_editor();
        e.set_view_mesher(MeshOptions::new(mesher)).unwrap();
        e.finish_meshing();
        assert_eq!(e.view_mesher().mesher, mesher);
        assert_eq!(e.view_mesher_used(0), Some(mesher));
        stroke(&mut e);
        assert!(e.triangle_count() > 0);
        let m = viewport(&e);
        let r = manifold_report(&m);
        assert_eq!(r.boundary, 0, "{mesher:?}: chunk meshes meet without cracks");
        if mesher != Mesher::SingleVertexDualContouring {
            check_closed_manifold(&m).unwrap_or_else(|err| panic!("{mesher:?}: {err}"));
        }
        assert!(e.undo());
        e.finish_meshing();
        assert_eq!(manifold_report(&viewport(&e)).boundary, 0, "{mesher:?} after undo");
    }
}

#[test]
fn per_chunk_simplification_keeps_chunk_borders_shared() {
    let mut e = ball_editor();
    let full = {
        e.finish_meshing();
        e.triangle_count()
    };
    for mesher in [Mesher::MarchingCubes, Mesher::ClusteredTetrahedra] {
        e.set_view_mesher(MeshOptions { mesher, simplify: Some(0.2), remove_islands: None }).unwrap();
        e.finish_meshing();
        let m = viewport(&e);
        assert_eq!(manifold_report(&m).boundary, 0, "{mesher:?}: locked borders still meet");
        assert!(e.triangle_count() < full, "{mesher:?}: {} of {full}", e.triangle_count());
    }
    // Dual contouring is simplified on export only; bad bounds are refused.
    let dc = MeshOptions { mesher: Mesher::DualContouring, simplify: Some(0.2), remove_islands: None };
    assert!(matches!(e.set_view_mesher(dc), Err(EditorError::Mesher(MesherError::ChunkSimplify(_)))));
    for bad in [f32::NAN, -0.1, f32::INFINITY] {
        let o = MeshOptions { mesher: Mesher::MarchingCubes, simplify: Some(bad), remove_islands: None };
        assert!(e.set_view_mesher(o).is_err(), "{bad}");
    }
    assert_eq!(e.view_mesher().simplify, Some(0.2), "a refused choice changes nothing");
}

#[test]
fn exports_by_every_mesher_and_tetrahedra_refuse_mixed_levels() {
    let mut e = ball_editor();
    let mc = e.export_mesh(MeshOptions::default()).unwrap();
    let volume = signed_volume(&mc);
    for mesher in Mesher::ALL {
        for simplify in [None, Some(0.1)] {
            let m = e.export_mesh(MeshOptions { mesher, simplify, remove_islands: None }).unwrap();
            assert!(m.triangle_count() > 0);
            assert!((signed_volume(&m) - volume).abs() / volume < 0.03, "{mesher:?} {simplify:?}");
            if mesher != Mesher::SingleVertexDualContouring && simplify.is_none() {
                check_closed_manifold(&m).unwrap_or_else(|err| panic!("{mesher:?}: {err}"));
            }
        }
    }
    // Detail in one chunk: tetrahedra refuse the layer, the viewport falls back to marching
    // cubes for the whole layer.
    e.set_view_mesher(MeshOptions::new(Mesher::ClusteredTetrahedra)).unwrap();
    e.finish_meshing();
    e.tool.kind = ToolKind::Detail;
    stroke(&mut e);
    assert!(!e.scene.layers[0].volume.single_level(), "the detail tool raised chunks");
    assert_eq!(e.view_mesher_used(0), Some(Mesher::MarchingCubes));
    check_closed_manifold(&viewport(&e)).unwrap();
    let err = e.export_mesh(MeshOptions::new(Mesher::ClusteredTetrahedra)).unwrap_err();
    assert!(matches!(err, EditorError::Mesher(MesherError::MixedLevels(_))));
    assert!(err.to_string().contains("mixes levels"), "{err}");
    assert!(e.export_mesh(MeshOptions::new(Mesher::DualContouring)).is_ok());
}

/// Under GPU meshing a dual-contoured layer whose chunks mix levels is left to the caller and
/// joined across levels: after every stroke (adding, erasing, a Detail stroke that raises more
/// chunks) the chunks listed for it cover every chunk whose mesh, as the CPU's cache joins the
/// volume from scratch, changed — none is left stale.
#[test]
fn gpu_meshing_lists_every_dual_chunk_an_edit_moves_across_levels() {
    use strata_mesh::DualCache;
    use strata_volume::{ChunkKey, Level};
    let mut scene = Scene::default();
    let v = &mut scene.layers[0].volume;
    v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 10.0).unwrap()).unwrap();
    v.add(&Sphere::new(DVec3::new(30.2, 17.1, 15.4), 7.5).unwrap()).unwrap();
    v.set_chunk_level(ChunkKey::new(1, 0, 0), Level::new(1).unwrap());
    v.set_chunk_level(ChunkKey::new(0, 1, 1), Level::new(2).unwrap());
    let mut e = Editor::new(scene);
    e.set_view_mesher(MeshOptions::new(Mesher::DualContouring)).unwrap();
    e.set_gpu_meshing(true);
    e.finish_meshing();
    assert!(e.take_changes().full, "the first list is full");
    assert!(e.caller_dual(0) && e.caller_dual_across_levels(0), "mixed levels are joined across levels");
    let strokes = [
        (ToolKind::Add, DVec3::new(16.5, 17.0, 26.0), 3.0),
        (ToolKind::Erase, DVec3::new(15.2, 16.3, 15.9), 4.0),
        (ToolKind::Add, DVec3::new(31.0, 8.5, 14.0), 2.5),
        (ToolKind::Detail, DVec3::new(24.0, 16.0, 16.0), 2.0),
        (ToolKind::Erase, DVec3::new(32.2, 16.4, 16.7), 3.5),
        (ToolKind::Add, DVec3::new(17.0, 16.0, 31.5), 2.0),
    ];
    let mut moved_total = 0;
    for (n, &(kind, at, radius)) in strokes.iter().enumerate() {
        let before = DualCache::build(&e.scene.layers[0].volume);
        e.tool.kind = kind;
        e.tool.radius = radius;
        e.tool.detail_level = Level::new(2).unwrap();
        let down = Buttons { primary: true, secondary: false };
        for i in 0..3 {
            let position = at + DVec3::new(0.0, 0.7 * i as f64, 0.0);
            let pose = ToolPose {
                position,
                orientation: DQuat::IDENTITY,
                pressure: 1.0,
                buttons: down,
                ..ToolPose::default()
            };
            e.frame(&pose, Duration::from_millis(50)).unwrap();
        }
        e.frame(&ToolPose::at(at, false), Duration::from_millis(50)).unwrap();
        e.finish_meshing();
        let after = DualCache::build(&e.scene.layers[0].volume);
        assert!(!e.scene.layers[0].volume.single_level(), "stroke {n}: still mixed");
        let changes = e.take_changes();
        assert!(!changes.full, "stroke {n}: an edit lists its chunks");
        let listed: std::collections::HashSet<ChunkKey> =
            changes.meshes.iter().filter(|(i, _)| *i == 0).map(|(_, k)| *k).collect();
        let mut keys: Vec<ChunkKey> = before.iter().chain(after.iter()).map(|(k, _)| k).collect();
        keys.sort();
        keys.dedup();
        let moved: Vec<ChunkKey> = keys.into_iter().filter(|&k| before.mesh(k) != after.mesh(k)).collect();
        assert!(!moved.is_empty(), "stroke {n} ({kind:?}) moved some chunk's mesh");
        for k in &moved {
            assert!(listed.contains(k), "stroke {n} ({kind:?}): chunk {k:?}'s mesh moved but was not listed");
        }
        moved_total += moved.len();
    }
    assert!(moved_total > 20, "{moved_total} chunk meshes moved");
}
