//! Resolution levels end to end: raising and lowering chunks, level-of-detail blocks, and the
//! crack patching that makes chunks of different levels mesh into one closed surface.

use glam::{DVec3, IVec3};
use strata_mesh::checks;
use strata_volume::brush::Sphere;
use strata_volume::{ChunkKey, Level, Volume};

fn level(k: i8) -> Level {
    Level::new(k).unwrap()
}

fn list_keys(v: &Volume) -> Vec<ChunkKey> {
    let mut keys: Vec<ChunkKey> = v.chunks().filter(|(k, _)| v.stored_level(*k).is_some()).map(|(k, _)| k).collect();
    keys.sort();
    keys
}

fn closed(v: &Volume) -> strata_mesh::Mesh {
    let mesh = strata_mesh::mesh_volume_with(v, strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    if let Err(e) = checks::check_closed_manifold(&mesh) {
        panic!("mesh of {} triangles not closed: {e}", mesh.indices.len() / 3);
    }
    mesh
}

/// A uniform chunk whose list neighbours all share the coarse level, with the surface through
/// the cells at its corner edge (whose crossings its neighbours own): a solid slab with a notch
/// along the edge where four chunks meet. Read at the volume's level while its neighbours
/// meshed those cells at theirs, the corner opened (far terrain found it); read at theirs it is
/// closed.
#[test]
fn a_uniform_chunk_among_coarse_chunks_meshes_closed() {
    use strata_volume::brush::Cuboid;
    for notch in [0.6, 0.4, 0.9] {
        let mut v = Volume::new();
        v.add(&Cuboid::new(DVec3::new(0.0, -16.0, 0.0), DVec3::new(40.0, 24.0, 40.0)).unwrap()).unwrap();
        let half = DVec3::splat(20.0 + notch / 2.0).with_z(50.0);
        v.subtract(&Cuboid::new(DVec3::new(20.0 - notch / 2.0, 20.0 - notch / 2.0, 0.0), half).unwrap()).unwrap();
        for k in list_keys(&v) {
            let _ = v.set_chunk_level(k, Level::COARSEST);
        }
        v.check_invariants().unwrap();
        assert_eq!(v.stored_level(ChunkKey::new(-1, -1, 0)), None, "notch {notch}: the chunk at the corner is uniform");
        assert_eq!(v.stored_level(ChunkKey::new(0, -1, 0)), Some(Level::COARSEST));
        closed(&v);
    }
}

/// The same slab and notch with the list chunks raised above the volume's level (the detail
/// tool), the notch's sides on the fine grid and between its nodes. A uniform chunk binds its
/// neighbours only at the volume's level, so a raised chunk's node on its face, or a raised
/// line ending on it, can be in the other state: the notch's corner runs through the uniform
/// chunk's corner cells at the fine level. Read plainly at that level, the uniform chunk's line
/// ends contradicted the raised chunks' nodes and the mesh opened along a chunk face (8 open
/// edges at level 1 for notches of 0.6 to 0.9 cells, one or more at level 2); patched, it is
/// closed, and so are the level-of-detail meshes of it (capped below the stored level, sampled
/// or patched) and its dual-contouring mesh.
#[test]
fn a_uniform_chunk_among_finer_chunks_meshes_closed() {
    use strata_volume::brush::Cuboid;
    for (l, notch) in [(1i8, 0.6), (1, 0.5), (1, 0.3), (1, 0.9), (2, 0.6), (2, 0.375)] {
        let mut v = Volume::new();
        v.add(&Cuboid::new(DVec3::new(0.0, -8.0, -24.0), DVec3::new(20.0, 12.0, 20.0)).unwrap()).unwrap();
        let half = DVec3::splat(20.0 + notch / 2.0).with_z(50.0);
        v.subtract(&Cuboid::new(DVec3::new(20.0 - notch / 2.0, 20.0 - notch / 2.0, 0.0), half).unwrap()).unwrap();
        for k in list_keys(&v) {
            let _ = v.set_chunk_level(k, level(l));
        }
        v.check_invariants().unwrap();
        let at = format!("level {l}, notch {notch}");
        assert_eq!(v.stored_level(ChunkKey::new(-1, -1, -2)), None, "{at}: the chunk at the corner is uniform");
        assert_eq!(v.stored_level(ChunkKey::new(-1, -1, -3)), Some(level(l)), "{at}");
        assert_eq!(v.stored_level(ChunkKey::new(0, -1, -2)), Some(level(l)), "{at}");
        closed(&v);
        for cap in (0..l).map(level) {
            let lod = strata_mesh::mesh_volume_reported(&v, strata_mesh::MeshOptions::default(), Some(&|_| cap))
                .expect("marching cubes meshes every volume")
                .0;
            if let Err(e) = checks::check_closed_manifold(&lod) {
                panic!("{at}, capped at {cap:?}: {e}");
            }
        }
        let dual =
            strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::DualContouring))
                .expect("dual contouring meshes every volume");
        assert_eq!(unbalanced_edges(&dual), 0, "{at}: dual contouring");
    }
}

#[test]
fn one_raised_chunk_in_a_sphere_meshes_closed() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
    let before = v.clone();
    let key = ChunkKey::new(0, 0, 0);
    let r = v.set_chunk_level(key, level(1));
    assert_eq!(v.stored_level(key), Some(level(1)));
    v.check_invariants().unwrap();
    closed(&v);
    let _ = v.set_chunk_level(key, level(0));
    assert_eq!(v, before, "raise then lower gives back the lists");
    v.restore(r.undo);
}

#[test]
fn raise_then_lower_is_the_identity() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
    let before = v.clone();
    for k in list_keys(&v) {
        let _ = v.set_chunk_level(k, level(2));
        v.check_invariants().unwrap();
    }
    for k in list_keys(&v) {
        let _ = v.set_chunk_level(k, level(0));
    }
    assert_eq!(v, before);
}

#[test]
fn every_pair_of_levels_meshes_closed() {
    for (a, b) in [(0, 1), (1, 0), (0, 2), (2, 0), (1, 2), (2, 1)] {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
        for k in list_keys(&v) {
            let l = if k.0.x == 0 { a } else { b };
            let _ = v.set_chunk_level(k, level(l));
        }
        v.check_invariants().unwrap();
        closed(&v);
    }
}

#[test]
fn seams_are_patched_and_split() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
    let _ = v.set_chunk_level(ChunkKey::new(0, 0, 0), level(2));
    let (mut seams, mut patched) = (0, 0);
    for k in list_keys(&v) {
        let b = v.extract_block(k);
        seams += b.seams().len();
        patched += b.patched();
        assert_eq!(b.repaired(), 0);
    }
    eprintln!("seams {seams}, patched {patched}");
    assert!(seams > 0);
    let mesh = closed(&v);
    eprintln!("triangles {}", mesh.indices.len() / 3);
}

mod random {
    use super::*;
    use proptest::prelude::*;
    use strata_volume::brush::{Aabb, Brush, Cuboid, MeshBrush, MeshRule, SdfBrush};
    use strata_volume::{CsgOp, EditSettings};

    #[derive(Clone, Debug)]
    pub enum Step {
        /// A CSG edit: op 0 add, 1 subtract, 2 intersect (rare); shape 0 sphere, 1 box, 2 a box
        /// mesh with faces on grid planes, 3 a field ball. Centre in quarter cells (on the grid
        /// of every level), size in quarter cells.
        Edit { op: u8, shape: u8, c: [i32; 3], size: [i32; 3] },
        /// The chunk at `key` (in the 3³ block around the origin) to a level.
        Level { key: [i32; 3], level: i8 },
        /// A sculpting tool (0 smooth, 1 inflate, 2 clay, 3 grab, 4 pinch, 5 flatten) at a
        /// point in quarter cells with a radius in quarter cells.
        Tool { tool: u8, c: [i32; 3], radius: i32 },
    }

    pub fn step() -> impl Strategy<Value = Step> {
        prop_oneof![
            3 => (0u8..10, 0u8..4, prop::array::uniform3(-24i32..152), prop::array::uniform3(24i32..80)).prop_map(
                |(op, shape, c, size)| Step::Edit { op: if op < 6 { 0 } else if op < 9 { 1 } else { 2 }, shape, c, size }
            ),
            2 => (prop::array::uniform3(-1i32..2), -1i8..3).prop_map(|(key, level)| Step::Level { key, level }),
            2 => (0u8..6, prop::array::uniform3(16i32..112), 8i32..32).prop_map(|(tool, c, radius)| Step::Tool { tool, c, radius }),
        ]
    }

    pub fn brush(shape: u8, c: [i32; 3], size: [i32; 3]) -> Box<dyn Brush> {
        let c = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * 0.25;
        let h = DVec3::new(size[0] as f64, size[1] as f64, size[2] as f64) * 0.125;
        match shape {
            0 => Box::new(Sphere::new(c, h.x).unwrap()),
            1 => Box::new(Cuboid::new(c, h).unwrap()),
            2 => {
                let (v, t) = strata_tests::box_mesh(c - h, 2.0 * h);
                Box::new(MeshBrush::new(&v, &t, MeshRule::default()).unwrap())
            }
            _ => {
                let r = h.x;
                Box::new(
                    SdfBrush::new(
                        move |p: DVec3| (p - c).length() - r,
                        Aabb::new(c - DVec3::splat(r + 1.0), c + DVec3::splat(r + 1.0)),
                        1.0,
                    )
                    .unwrap(),
                )
            }
        }
    }

    pub fn apply(v: &mut Volume, s: &Step) -> strata_volume::EditReport {
        match *s {
            Step::Edit { op, shape, c, size } => {
                let op = [CsgOp::Add, CsgOp::Subtract, CsgOp::Intersect][op as usize];
                // An intersection keeps a large part: a small one leaves features so thin that
                // no mesh of node samples keeps their volume.
                let size = if op == CsgOp::Intersect { size.map(|s| s + 100) } else { size };
                let b = brush(shape, c, size);
                v.apply(op, b.as_ref(), &EditSettings::default()).unwrap()
            }
            Step::Level { key, level: l } => v.set_chunk_level(ChunkKey::new(key[0], key[1], key[2]), level(l)),
            Step::Tool { tool, c, radius } => {
                use strata_volume::tools;
                let c = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * 0.25;
                let dab = tools::Dab::new(c, radius as f64 * 0.25, 0.8).unwrap();
                match tool {
                    0 => tools::smooth(v, &dab, tools::Smoothing::default(), 2),
                    1 => tools::inflate(v, &dab, 0.6),
                    2 => tools::clay(v, &dab, 0.5 * dab.radius, false),
                    3 => tools::grab(v, &dab, DVec3::new(1.3, -0.7, 0.9)),
                    4 => tools::pinch(v, &dab, None, 0.5),
                    _ => tools::flatten(v, &dab),
                }
                .unwrap()
            }
        }
    }
}

use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Random level maps, CSG edits (shapes and levels on the grid of every level: boxes and box
    /// meshes with faces on grid planes, balls centred on nodes) and sculpting tools (which read
    /// at the finest level they touch and write each chunk at its own): the invariants hold
    /// after every step, undo restores every step exactly, the welded marching-cubes mesh is
    /// closed and manifold and the dual-contouring mesh closed. The body is a ball inside the
    /// block's middle chunks, or a box that fills the middle chunk (a uniform chunk among list
    /// chunks that the steps raise, lower and cut around).
    #[test]
    fn random_levels_and_edits_keep_every_invariant(
        boxed in any::<bool>(),
        steps in prop::collection::vec(random::step(), 1..10),
    ) {
        let mut v = Volume::new();
        if boxed {
            v.add(&strata_volume::brush::Cuboid::new(DVec3::splat(9.0), DVec3::splat(11.5)).unwrap()).unwrap();
            prop_assert_eq!(v.stored_level(ChunkKey::new(0, 0, 0)), None);
        } else {
            v.add(&Sphere::new(DVec3::new(16.0, 16.0, 16.0), 13.0).unwrap()).unwrap();
        }
        for s in &steps {
            let before = v.clone();
            let report = random::apply(&mut v, s);
            if let Err(e) = v.check_invariants() {
                panic!("after {s:?}: {e}");
            }
            let mut undone = v.clone();
            undone.restore(report.undo);
            prop_assert_eq!(&undone, &before, "undo of {:?}", s);
            let mesh = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default()).expect("marching cubes meshes every volume");
            if let Err(e) = checks::check_closed_manifold(&mesh) {
                panic!("after {s:?}: {e}");
            }
            let dual = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::DualContouring)).expect("dual contouring meshes every volume");
            let unbalanced = unbalanced_edges(&dual);
            prop_assert_eq!(unbalanced, 0, "dual contouring not closed after {:?}", s);
        }
    }

    /// Random level maps on a random ball (a smooth body: a crease, such as the rim where two
    /// balls meet, costs a node-sampled mesh volume whatever the levels, up to 1 % in these
    /// scenes at one level): after every level change the welded mesh encloses the ball's volume
    /// within 1 %. (Held against the ball, not `Volume::measured_volume`: that sum gives each
    /// line the cross-section of the cell after it, which at a seam between levels misses or
    /// doubles a slab half a coarse cell thick, 1.6 % here.)
    #[test]
    fn mixed_levels_keep_the_enclosed_volume(
        c in prop::array::uniform3(40i32..88),
        r in 40i32..80,
        steps in prop::collection::vec(random::step(), 1..8),
    ) {
        let mut v = Volume::new();
        let c = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * 0.25;
        v.add(&Sphere::new(c, r as f64 * 0.25).unwrap()).unwrap();
        for s in steps.iter().filter(|s| matches!(s, random::Step::Level { .. })) {
            random::apply(&mut v, s);
            let mesh = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default()).expect("marching cubes meshes every volume");
            checks::check_closed_manifold(&mesh).unwrap();
            let ball = 4.0 / 3.0 * std::f64::consts::PI * (r as f64 * 0.25).powi(3);
            let enclosed = checks::signed_volume(&mesh);
            prop_assert!((enclosed - ball).abs() <= 0.01 * ball, "mesh {} vs ball {}", enclosed, ball);
        }
    }
}

/// A detail of the fine chunk that touches the face it shares with a coarse chunk at nodes the
/// coarse face does not have: the fine block's face follows the coarse face and the edges from
/// it into the fine chunk are patched, so the mesh stays closed.
#[test]
fn fine_detail_on_a_coarse_face_is_patched_closed() {
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::new(8.0, 8.0, 8.0), 6.0).unwrap()).unwrap();
    v.add(&Sphere::new(DVec3::new(24.0, 8.0, 8.0), 6.0).unwrap()).unwrap();
    let fine = ChunkKey::new(0, 0, 0);
    let _ = v.set_chunk_level(fine, level(2));
    v.add(&Sphere::new(DVec3::new(16.0, 8.25, 8.25), 0.3).unwrap()).unwrap();
    v.check_invariants().unwrap();
    let b = v.extract_block(fine);
    assert!(b.patched() > 0, "the fine chunk's edges into the shared face were patched");
    assert_eq!(b.repaired(), 0);
    closed(&v);
}

/// Every one of the face table's 16 cases, on every face orientation (the finer chunk on either
/// side of each axis) and for every pair of levels: small balls around chosen corners of one
/// coarse cell face on the shared face (radius 0.3 or 0.7 of a coarse cell, so each crossing lies
/// in either half of its edge), drawn after the levels were set so the finer chunk has its own
/// finer detail. The welded mesh is closed and edge-manifold.
#[test]
fn all_face_cases_on_every_orientation_and_level_pair_mesh_closed() {
    let mut checked = 0;
    for (coarse, fine) in [(-1i8, 0i8), (-1, 1), (-1, 2), (0, 1), (0, 2), (1, 2)] {
        let sc = level(coarse).spacing();
        for axis in strata_volume::Axis::ALL {
            let (ua, va) = axis.across();
            for fine_after in [false, true] {
                for case in 0..16u32 {
                    for radii in [[0.3; 4], [0.7; 4], [0.3, 0.7, 0.3, 0.7]] {
                        let mut v = Volume::new();
                        let d = axis.unit_i64().as_ivec3();
                        let (a, b) = (ChunkKey::new(0, 0, 0), ChunkKey::new(0, 0, 0).offset(d));
                        // Something in each chunk, away from the face, to make them lists.
                        for k in [a, b] {
                            let c = k.origin_grid().as_dvec3() + DVec3::splat(8.0);
                            v.add(&Sphere::new(c, 3.0).unwrap()).unwrap();
                        }
                        let (la, lb) = if fine_after { (coarse, fine) } else { (fine, coarse) };
                        let _ = v.set_chunk_level(a, level(la));
                        let _ = v.set_chunk_level(b, level(lb));
                        // The coarse face cell at the middle of the shared face (x = 16 for x).
                        for (k, (i, j)) in [(0, 0), (1, 0), (1, 1), (0, 1)].into_iter().enumerate() {
                            if case >> k & 1 == 0 {
                                continue;
                            }
                            let mut p = DVec3::ZERO;
                            p[axis.index()] = 16.0;
                            p[ua.index()] = 8.0 + i as f64 * sc;
                            p[va.index()] = 8.0 + j as f64 * sc;
                            v.add(&Sphere::new(p, radii[k] * sc).unwrap()).unwrap();
                        }
                        v.check_invariants().unwrap();
                        assert_eq!(v.stored_level(a), Some(level(la)));
                        let mesh = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default())
                            .expect("marching cubes meshes every volume");
                        if let Err(e) = checks::check_closed_manifold(&mesh) {
                            panic!("levels {la}/{lb} across {axis:?}, case {case:04b}, radii {radii:?}: {e}");
                        }
                        checked += 1;
                    }
                }
            }
        }
    }
    assert_eq!(checked, 6 * 3 * 2 * 16 * 3);
}

/// Raising a sphere of radius 20 keeps its enclosed volume within 0.5 % and every vertex of its
/// mesh within half a base cell of the analytic sphere, and the raised mesh lies within a
/// quarter of a base cell of the old one (Hausdorff at the vertices).
#[test]
fn a_raised_sphere_keeps_its_volume_and_surface() {
    let c = DVec3::new(16.3, 15.7, 16.2);
    let r = 20.0;
    let mut v = Volume::new();
    v.add(&Sphere::new(c, r).unwrap()).unwrap();
    let old = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    for target in [1i8, 2] {
        let mut w = v.clone();
        for k in list_keys(&w) {
            let _ = w.set_chunk_level(k, level(target));
        }
        w.check_invariants().unwrap();
        let mesh = closed(&w);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        let enclosed = checks::signed_volume(&mesh);
        assert!((enclosed - exact).abs() <= 0.005 * exact, "level {target}: {enclosed} vs {exact}");
        let worst = mesh
            .positions
            .iter()
            .map(|p| ((DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) - c).length() - r).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 0.5, "level {target}: a vertex {worst} cells off the sphere");
        let h = hausdorff(&old, &mesh);
        assert!(h <= 0.25, "level {target}: the raised mesh is {h} cells from the old one");
        eprintln!(
            "raised to {target}: volume {:+.3} %, worst vertex {worst:.3}, Hausdorff to the old mesh {h:.3}",
            (enclosed / exact - 1.0) * 100.0
        );
    }
}

/// The closest distance from `p` to the triangle `t`.
fn point_triangle(p: DVec3, t: [DVec3; 3]) -> f64 {
    let (a, b, c) = (t[0], t[1], t[2]);
    let n = (b - a).cross(c - a);
    if n.length_squared() > 1e-18 {
        // Inside the prism over the triangle: the distance to its plane.
        let inside = [(a, b), (b, c), (c, a)].iter().all(|&(u, w)| (w - u).cross(p - u).dot(n) >= 0.0);
        if inside {
            return (p - a).dot(n).abs() / n.length();
        }
    }
    let seg = |u: DVec3, w: DVec3| {
        let d = w - u;
        let t = if d.length_squared() > 0.0 { ((p - u).dot(d) / d.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
        (u + d * t - p).length()
    };
    seg(a, b).min(seg(b, c)).min(seg(c, a))
}

/// The largest distance from a vertex of either mesh to the other mesh's surface (the
/// Hausdorff distance measured at the vertices).
fn hausdorff(a: &strata_mesh::Mesh, b: &strata_mesh::Mesh) -> f64 {
    fn one_way(a: &strata_mesh::Mesh, b: &strata_mesh::Mesh) -> f64 {
        use std::collections::HashMap;
        let pt = |p: &[f32; 3]| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        let tris: Vec<[DVec3; 3]> =
            b.indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| pt(&b.positions[t[k] as usize]))).collect();
        let mut grid: HashMap<IVec3, Vec<usize>> = HashMap::new();
        for (i, t) in tris.iter().enumerate() {
            let lo = t[0].min(t[1]).min(t[2]).floor().as_ivec3();
            let hi = t[0].max(t[1]).max(t[2]).floor().as_ivec3();
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        grid.entry(IVec3::new(x, y, z)).or_default().push(i);
                    }
                }
            }
        }
        let mut worst = 0.0f64;
        for p in &a.positions {
            let p = pt(p);
            let k = p.floor().as_ivec3();
            let mut best = f64::INFINITY;
            for r in 1..8 {
                for dz in -r..=r {
                    for dy in -r..=r {
                        for dx in -r..=r {
                            for &i in grid.get(&(k + IVec3::new(dx, dy, dz))).into_iter().flatten() {
                                best = best.min(point_triangle(p, tris[i]));
                            }
                        }
                    }
                }
                if best <= r as f64 {
                    break;
                }
            }
            worst = worst.max(best);
        }
        worst
    }
    one_way(a, b).max(one_way(b, a))
}

/// Level of detail: a model stored at level 2 meshed with every chunk capped at level 1 and at
/// level 0 (blocks sampled from the stored lists) stays within one coarse cell of the full mesh,
/// and a cap that differs from chunk to chunk still meshes closed. (The model has no part
/// thinner than a coarse cell: such a part has no coarse node and vanishes, as it must in any
/// node-sampled level of detail; a sliver 1.3 cells thick left by a cut measured 1.55 coarse
/// cells.)
#[test]
fn level_of_detail_meshes_stay_within_a_coarse_cell_and_closed() {
    let mut v = Volume::with_level(level(2));
    v.add(&Sphere::new(DVec3::new(16.3, 15.7, 16.2), 13.0).unwrap()).unwrap();
    v.subtract(&strata_volume::brush::Cuboid::new(DVec3::new(30.0, 16.0, 16.0), DVec3::new(8.0, 20.0, 3.0)).unwrap())
        .unwrap();
    let full = closed(&v);
    for cap in [1i8, 0, -1] {
        let lod = strata_mesh::mesh_volume_reported(&v, strata_mesh::MeshOptions::default(), Some(&|_| level(cap)))
            .expect("marching cubes meshes every volume")
            .0;
        checks::check_closed_manifold(&lod).unwrap();
        let h = hausdorff(&full, &lod);
        let coarse_cell = level(cap).spacing();
        eprintln!("cap {cap}: {} of {} triangles, Hausdorff ≤ {h:.3}", lod.indices.len() / 3, full.indices.len() / 3);
        assert!(h <= coarse_cell, "cap {cap}: {h} > {coarse_cell}");
        assert!(lod.indices.len() < full.indices.len());
    }
    let rings = |k: ChunkKey| level(((k.0.x + 2 * k.0.y + k.0.z).rem_euclid(4)) as i8 - 1);
    let mixed = strata_mesh::mesh_volume_reported(&v, strata_mesh::MeshOptions::default(), Some(&rings))
        .expect("marching cubes meshes every volume")
        .0;
    checks::check_closed_manifold(&mixed).unwrap();
    // Blocks sampled below their stored level, plainly or patched, never need repairs.
    for cap in [&(|_| level(1)) as &(dyn Fn(ChunkKey) -> Level + Sync), &rings] {
        for k in strata_mesh::surface_chunks(&v) {
            let mut b = strata_volume::VoxelBlock::default();
            v.extract_block_capped(k, cap, &mut b);
            assert_eq!(b.repaired(), 0, "{k:?}");
        }
    }
}

/// Held against an independent implementation: the transvoxel crate's transition cells at a
/// 2:1 face, on the same ball, welded by position, and ours.
#[test]
fn seams_against_transvoxel() {
    use transvoxel::prelude::*;
    let c = [16.0f32, 8.3, 7.9];
    let r = 6.2f32;
    let density =
        move |x: f32, y: f32, z: f32| r - ((x - c[0]).powi(2) + (y - c[1]).powi(2) + (z - c[2]).powi(2)).sqrt();
    let coarse = Block::new([0.0f32, 0.0, 0.0], 16.0, 16);
    let fine = Block::new([16.0f32, 0.0, 0.0], 16.0, 32);
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut triangles: Vec<[usize; 3]> = Vec::new();
    for (block, sides) in [(coarse, TransitionSide::HighX.into()), (fine, TransitionSide::none())] {
        let m =
            extract_from_field(&density, FieldCaching::CacheNothing, block, sides, 0.0f32, GenericMeshBuilder::new())
                .build();
        let base = positions.len();
        positions.extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        triangles.extend(m.triangle_indices.chunks_exact(3).map(|t| [t[0] + base, t[1] + base, t[2] + base]));
    }
    // Weld by position to 1/1024 of a cell.
    let mut ids = std::collections::HashMap::new();
    let mut welded = strata_mesh::Mesh::default();
    let remap: Vec<u32> = positions
        .iter()
        .map(|p| {
            let k = p.map(|c| (c * 1024.0).round() as i64);
            *ids.entry(k).or_insert_with(|| {
                welded.positions.push(*p);
                welded.normals.push([0.0, 0.0, 1.0]);
                welded.positions.len() as u32 - 1
            })
        })
        .collect();
    for t in &triangles {
        let t = t.map(|i| remap[i]);
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            welded.indices.extend_from_slice(&t);
        }
    }
    let theirs = open_edges(&welded);
    let mut v = Volume::new();
    let ball = Sphere::new(DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64), r as f64).unwrap();
    v.add(&ball).unwrap();
    let _ = v.set_chunk_level(ChunkKey::new(1, 0, 0), level(1));
    v.add(&ball).unwrap();
    let ours = strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::default())
        .expect("marching cubes meshes every volume");
    let our_open = open_edges(&ours);
    eprintln!(
        "transvoxel: {} triangles, {theirs} open edges; strata: {} triangles, {our_open} open edges",
        welded.indices.len() / 3,
        ours.indices.len() / 3
    );
    assert_eq!(our_open, 0);
    checks::check_closed_manifold(&ours).unwrap();
}

/// Edges used by one triangle only.
fn open_edges(m: &strata_mesh::Mesh) -> usize {
    let mut count: std::collections::HashMap<(u32, u32), i32> = std::collections::HashMap::new();
    for t in m.indices.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    count.values().filter(|&&c| c == 1).count()
}

/// Edges not used as often in one direction as in the other (0: a closed, consistently
/// oriented surface, manifold or not).
fn unbalanced_edges(m: &strata_mesh::Mesh) -> usize {
    let mut uses: std::collections::HashMap<(u32, u32), i32> = std::collections::HashMap::new();
    for t in m.indices.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *uses.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
        }
    }
    uses.values().filter(|&&c| c != 0).count()
}

#[test]
fn dual_contouring_of_mixed_levels_is_closed() {
    for (a, b) in [(0, 1), (1, 0), (0, 2), (2, 1)] {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(16.3, 15.8, 16.1), 9.3).unwrap()).unwrap();
        for k in list_keys(&v) {
            let _ = v.set_chunk_level(k, level(if k.0.x == 0 { a } else { b }));
        }
        let dual =
            strata_mesh::mesh_volume_with(&v, strata_mesh::MeshOptions::new(strata_mesh::Mesher::DualContouring))
                .expect("dual contouring meshes every volume");
        assert!(!dual.indices.is_empty());
        assert_eq!(unbalanced_edges(&dual), 0, "levels {a}/{b}");
        let r = checks::manifold_report(&dual);
        eprintln!("levels {a}/{b}: {} triangles, {} non-manifold edges", dual.indices.len() / 3, r.non_manifold);
    }
}
