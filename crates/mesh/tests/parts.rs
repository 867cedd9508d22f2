//! Fine chunks remeshed in parts (issue 29): a marching-cubes mesh of a chunk finer than 16³
//! cells is kept as parts of 16³ cells, and an edit remeshes only the parts it reaches. Checked
//! here: after random strokes of every sculpting tool and CSG edits (centres on nodes, on
//! half-cells and anywhere; some chunks at other levels), with the cache updated after every
//! dab from the edit's reach alone,
//! - the cache equals a cache built from scratch, chunk for chunk, bit for bit;
//! - every chunk's mesh has the same triangles as the chunk's whole block meshed at once (after
//!   welding the parts' border vertices by position), with the same normals and materials;
//! - the whole surface, welded by position, is closed and edge-manifold across part, chunk and
//!   level borders;
//! - a part read from the lines through it equals the whole block there.
//!
//! Cases default to 12; `PROPTEST_CASES=200 cargo test -p strata-mesh --test parts --release`
//! runs a longer search.

use std::collections::HashMap;

use glam::DVec3;
use proptest::prelude::*;
use strata_mesh::checks::check_closed_manifold;
use strata_mesh::{Mesh, MeshCache, PART_CELLS, mesh_block};
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::tools::{self, Dab, Smoothing};
use strata_volume::{Axis, ChunkKey, EditReport, Level, Volume, VoxelBlock};

/// The finest level: 64³ cells a chunk, a quarter grid unit a cell.
fn fine() -> Level {
    Level::new(2).unwrap()
}

/// A dab of tool `tool` (0–10: field tools and paint; 11 and 12: CSG, which does not say where
/// it reaches) at `c`, radius `r` grid units.
fn dab_of(v: &mut Volume, tool: u8, c: DVec3, r: f64, dir: DVec3, material: u8) -> EditReport {
    let dab = Dab { material, ..Dab::new(c, r, 0.5).unwrap() };
    let result = match tool {
        0 => tools::smooth(v, &dab, Smoothing::VolumePreserving, 2),
        1 => tools::smooth(v, &dab, Smoothing::Laplacian, 2),
        2 => tools::inflate(v, &dab, 0.2 * r),
        3 => tools::inflate(v, &dab, -0.2 * r),
        4 => tools::flatten(v, &dab),
        5 => tools::clay(v, &dab, 0.5 * r, false),
        6 => tools::clay(v, &dab, 0.5 * r, true),
        7 => tools::pinch(v, &dab, Some(dir), 0.5),
        8 => tools::grab(v, &dab, dir * 0.25 * r),
        9 | 10 => tools::paint(v, &dab),
        11 => return v.add(&Sphere::new(c, r * 0.5).unwrap()).unwrap(),
        _ => return v.subtract(&Cuboid::new(c, DVec3::splat(r * 0.4)).unwrap()).unwrap(),
    };
    result.unwrap_or_else(|e| panic!("tool {tool} refused a valid dab at {c:?}, radius {r}: {e}"))
}

/// Shapes across the corner where eight 64³ chunks meet (grid point (16, 16, 16)), with centres
/// and sizes in eighths of a grid unit (nodes and half-cells of the fine level); chunks listed in
/// `coarse` are lowered to level −1, 0 or 1.
fn scene(shapes: &[(u8, [i32; 3], i32)], coarse: &[(u8, i8)], material: u8) -> Volume {
    scene_at(fine(), shapes, coarse, material)
}

/// [`scene`] with new chunks at `level`.
fn scene_at(level: Level, shapes: &[(u8, [i32; 3], i32)], coarse: &[(u8, i8)], material: u8) -> Volume {
    let mut v = Volume::with_level(level);
    for &(kind, c, size) in shapes {
        let c = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * 0.125;
        let s = size as f64 * 0.125;
        match kind {
            0 => v.add(&Sphere::new(c, s).unwrap()).unwrap(),
            1 => v.add(&Cuboid::new(c, DVec3::new(s, s * 0.75, s * 0.5)).unwrap()).unwrap(),
            _ => v.subtract(&Sphere::new(c, s * 0.5).unwrap()).unwrap(),
        };
    }
    if material > 0 {
        tools::paint(&mut v, &Dab { material, ..Dab::new(DVec3::splat(16.0), 5.0, 1.0).unwrap() }).unwrap();
    }
    for &(key, level) in coarse {
        let k = ChunkKey::new((key & 1) as i32, ((key >> 1) & 1) as i32, ((key >> 2) & 1) as i32);
        v.set_chunk_level(k, Level::new(level).unwrap());
    }
    v
}

/// The triangles of `mesh` placed at `origin`, each as its three positions' bits from the
/// smallest (orientation kept), sorted; and each position's normal and material.
type Canonical = (Vec<[[u32; 3]; 3]>, HashMap<[u32; 3], ([u32; 3], u8)>);

fn canonical(mesh: &Mesh) -> Canonical {
    let bits = |p: [f32; 3]| p.map(|c| (c + 0.0).to_bits());
    let mut tris: Vec<[[u32; 3]; 3]> = mesh
        .triangles()
        .map(|t| {
            let p = t.map(|i| bits(mesh.positions[i as usize]));
            let k = (0..3).min_by_key(|&k| p[k]).unwrap();
            [p[k], p[(k + 1) % 3], p[(k + 2) % 3]]
        })
        .collect();
    tris.sort();
    let mut attributes = HashMap::new();
    for i in 0..mesh.positions.len() {
        let a = (bits(mesh.normals[i]), mesh.material(i).dominant());
        let old = attributes.insert(bits(mesh.positions[i]), a);
        assert!(old.is_none_or(|o| o == a), "two vertices at one position differ: {old:?} and {a:?}");
    }
    (tris, attributes)
}

/// Every chunk mesh of `cache`, placed and welded by position.
fn surface(cache: &MeshCache) -> Mesh {
    let mut out = Mesh::default();
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    for (key, m) in cache.iter() {
        let o = key.origin_grid().as_vec3();
        let remap: Vec<u32> = m
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let q = [p[0] + o.x, p[1] + o.y, p[2] + o.z];
                *index.entry(q.map(|c| (c + 0.0).to_bits())).or_insert_with(|| {
                    out.positions.push(q);
                    out.normals.push(m.normals[i]);
                    out.positions.len() as u32 - 1
                })
            })
            .collect();
        out.indices.extend(m.indices.iter().map(|&i| remap[i as usize]));
    }
    out
}

/// Whether two meshes are equal, a mesh without materials counting as all of material 0 (the
/// first material given anywhere in a volume gives every block materials, while meshes of
/// chunks the edit did not reach keep none).
fn same(a: &Mesh, b: &Mesh) -> bool {
    let materials = |m: &Mesh| (0..m.positions.len()).map(|i| m.material(i)).collect::<Vec<_>>();
    a.positions == b.positions && a.normals == b.normals && a.indices == b.indices && materials(a) == materials(b)
}

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(12)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), max_shrink_iters: 30, ..ProptestConfig::default() })]

    #[test]
    fn parts_remeshed_where_edits_reach_equal_whole_chunks_and_stay_closed(
        shapes in prop::collection::vec((0u8..3, prop::array::uniform3(80i32..176), 24i32..72), 1..3),
        coarse in prop::collection::vec((0u8..8, -1i8..2), 0..2),
        material in 0u8..3,
        strokes in prop::collection::vec(
            (0u8..13, prop::array::uniform3(96i32..160), prop::array::uniform3(-8i32..8), 0u8..3,
             prop::sample::select(vec![0.5, 1.0, 2.0, 3.0, 5.0])),
            1..4,
        ),
    ) {
        let mut v = scene(&shapes, &coarse, material);
        let mut cache = MeshCache::build(&v);
        for (tool, start, dir, snap, r) in strokes {
            let dir = DVec3::new(dir[0] as f64, dir[1] as f64, dir[2] as f64).normalize_or(DVec3::X);
            let start = DVec3::new(start[0] as f64, start[1] as f64, start[2] as f64) * 0.125;
            for k in 0..3 {
                let p = start + dir * (k as f64 * 0.25 * r);
                // Centres on fine nodes, on fine half-cells, or off the grid.
                let c = match snap {
                    0 => (p * 4.0).round() * 0.25,
                    1 => (p * 8.0).round() * 0.125,
                    _ => p + DVec3::new(0.0137, 0.0291, 0.0053),
                };
                let report = dab_of(&mut v, tool, c, r, dir, 1 + tool % 2);
                let keys = cache.note(&v, &report.changed, report.reach);
                let fresh = cache.compute(&v, &keys, None);
                cache.commit(fresh);
            }
        }
        let full = MeshCache::build(&v);
        prop_assert_eq!(cache.len(), full.len());
        for (k, m) in full.iter() {
            prop_assert!(cache.mesh(k).is_some_and(|c| same(c, m)), "chunk {:?}: the remeshed parts differ from a fresh build", k);
        }
        let mut block = VoxelBlock::default();
        let mut whole = Mesh::default();
        for (k, m) in cache.iter() {
            v.extract_block_into(k, &mut block);
            mesh_block(&block, &mut whole);
            prop_assert!(canonical(m) == canonical(&whole), "chunk {:?}: the parts' triangles are not the whole block's", k);
        }
        let s = surface(&cache);
        prop_assert!(check_closed_manifold(&s).is_ok(), "{:?}", check_closed_manifold(&s));
    }
}

/// A part read from the lines through it holds what the chunk's whole block holds there: node
/// states, crossings (position and normal), and materials, for every part of 64³ chunks and of
/// 32³ ones, next to empty and solid neighbours.
#[test]
fn a_part_read_from_its_lines_equals_the_whole_block_there() {
    let shapes = [(0, [128, 128, 128], 70), (1, [150, 110, 120], 40), (2, [120, 140, 130], 40)];
    let finest = scene(&shapes, &[], 2);
    let middle = scene_at(Level::new(1).unwrap(), &shapes, &[], 2);
    let mut checked = 0;
    let keys = [ChunkKey::new(0, 0, 0), ChunkKey::new(1, 1, 1), ChunkKey::new(0, 1, 0), ChunkKey::new(1, 0, 1)];
    for (v, key) in keys.iter().map(|&k| (&finest, k)).chain(keys.iter().map(|&k| (&middle, k))) {
        assert!(v.plain_block_level(key, None).is_some(), "{key:?} is read plainly");
        let whole = v.extract_block(key);
        let n = whole.cells();
        let mut part = VoxelBlock::default();
        for pz in (0..n).step_by(PART_CELLS) {
            for py in (0..n).step_by(PART_CELLS) {
                for px in (0..n).step_by(PART_CELLS) {
                    let at = [px, py, pz];
                    v.extract_part(key, at, PART_CELLS, &mut part);
                    assert_eq!(part.offset(), at);
                    assert_eq!(part.cells(), PART_CELLS);
                    for z in 0..=PART_CELLS {
                        for y in 0..=PART_CELLS {
                            for x in 0..=PART_CELLS {
                                let g = [x + px, y + py, z + pz];
                                assert_eq!(
                                    part.inside(x, y, z),
                                    whole.inside(g[0], g[1], g[2]),
                                    "{key:?} {at:?} node {x},{y},{z}"
                                );
                                if whole.inside(g[0], g[1], g[2]) {
                                    assert_eq!(part.material(x, y, z), whole.material(g[0], g[1], g[2]));
                                }
                                for axis in Axis::ALL {
                                    let mut end = [x, y, z];
                                    end[axis.index()] += 1;
                                    if end.iter().any(|&c| c > PART_CELLS) {
                                        continue;
                                    }
                                    let (a, b) = (part.crossing(axis, x, y, z), whole.crossing(axis, g[0], g[1], g[2]));
                                    assert_eq!(a.map(|c| (c.t, c.normal)), b.map(|c| (c.t, c.normal)));
                                    checked += usize::from(a.is_some());
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    assert!(checked > 1000, "only {checked} crossings compared: the parts missed the surface");
}
