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
