//! A late joiner on the bunny at 1,024 cells a side: the host makes the room with the scene (a
//! 25 MB scene file in its hello), two guests sculpt on it, and a client joining afterwards gets
//! the same bytes as everyone else.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use strata_editor::Scene;
use strata_editor::import::{Resolution, convert, plan};
use strata_server::{RedbStorage, Server, ServerConfig};
use strata_tests::collab::{Member, Rng, converge, digests, temp_dir};
use strata_volume::brush::MeshRule;

fn bunny_scene(cells: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply");
    let mesh = strata_mesh::import::load_mesh(&path).unwrap();
    let p = plan(&mesh, Resolution::Cells(cells)).unwrap();
    let layer = convert(&mesh, &p, MeshRule::EvenOdd, "Bunny", &Default::default()).unwrap();
    Scene { layers: vec![layer], ..Scene::default() }
}

#[test]
fn a_late_joiner_on_the_bunny_at_1024_cells_gets_the_same_bytes() {
    let t0 = Instant::now();
    let scene = bunny_scene(1024);
    eprintln!("bunny at 1,024 cells converted in {:?}", t0.elapsed());
    let dir = temp_dir("late-join");
    let storage = Arc::new(RedbStorage::open(&dir.join("rooms.redb")).unwrap());
    let server = Server::start("127.0.0.1:0", storage, ServerConfig::default()).unwrap();
    let url = server.url();
    let mut members = vec![Member::new(&url, "bunny", "token", "host", Some(&scene))];
    converge(&mut members, Duration::from_secs(300));
    members.push(Member::new(&url, "bunny", "token", "guest", None));
    converge(&mut members, Duration::from_secs(300));
    // Strokes on the bunny's back (its grid is a layer of 1,024 cells; the tools work in
    // world units, the mesh's).
    let transform = members[0].editor.scene.layers[0].transform;
    let mut rng = Rng(77);
    for k in 0..6 {
        let m = &mut members[k % 2];
        m.editor.tool.kind = strata_editor::ToolKind::ALL[rng.below(4) as usize];
        m.editor.tool.radius = 6.0 * transform.scale;
        let a = transform.to_world(glam::DVec3::new(300.0 + 40.0 * k as f64, 700.0, 500.0));
        let b = a + glam::DVec3::new(20.0, 0.0, 10.0) * transform.scale;
        let _ = m.editor.line_stroke(a, b, 1.0, Default::default());
    }
    converge(&mut members, Duration::from_secs(300));
    assert!(members[0].session.replica().seq() >= 6);
    let t1 = Instant::now();
    let mut late = vec![Member::new(&url, "bunny", "token", "late", None)];
    converge(&mut late, Duration::from_secs(300));
    eprintln!("the late joiner was in step after {:?} (debug build)", t1.elapsed());
    let expected = digests(&members[0].editor);
    assert!(digests(&members[1].editor) == expected);
    assert!(digests(&late[0].editor) == expected, "the late joiner's bytes differ");
}
