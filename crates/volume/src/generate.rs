//! Writing a whole chunk from a field known node by node (procedural terrain, other generators).
//!
//! A generator does not edit: it says what a chunk *is*. [`generate_chunk`] asks the field for
//! the state of every node on the chunk's lines once, as rows of bits, and builds the x, y and z
//! lists from that one grid of states, so the three axes agree on every node by construction —
//! exact ties included, because a node's state is one bit read three times, never three
//! evaluations. Only where a line's state changes does it ask the field for the crossing inside
//! that cell ([`NodeField::crossing`]), which it then quantises strictly into the cell. No field
//! values are kept: the transient state grid of a 16³ chunk is 289 words.
//!
//! Neighbouring chunks agree on their shared nodes as long as the field answers a node from its
//! absolute grid position (the world point `origin + local · spacing` is exact in `f64`).

use glam::{DVec3, I64Vec3};

use crate::axis::{Axis, compose};
use crate::chunk::{Built, Chunk, ChunkBuilder, WorkLine, node_mask};
use crate::coords::{ChunkKey, Level, quantize_into_edge};
use crate::material::{ChunkMaterials, MaterialId};
use crate::normal::pack_normal;

/// What a chunk holds, node by node.
pub trait NodeField: Sync {
    /// `Some(inside)` when every node of the chunk whose minimum node is `origin` (grid units,
    /// `n + 1` nodes a side at `level`) is provably `inside` — decided without visiting nodes
    /// (interval bounds); `None` when the nodes must be visited. Must never be wrong.
    fn decided(&self, origin: I64Vec3, level: Level) -> Option<bool> {
        let _ = (origin, level);
        None
    }

    /// Fills `rows[y + (n + 1) z]` bit `x` with the state of node `origin + (x, y, z) · spacing`
    /// for `x, y, z` in `0..=n` (`rows` has `(n + 1)²` entries, zeroed).
    fn node_states(&self, origin: I64Vec3, level: Level, rows: &mut [u128]);

    /// The surface between node `from` (grid units) and `from + spacing · axis`, whose states
    /// differ (`from_inside` is the state at `from`): the crossing as a fraction of the edge in
    /// `(0, 1)` and the outward normal there. Out-of-range or non-finite answers are clamped
    /// into the cell and replaced by the axis direction.
    fn crossing(&self, from: DVec3, axis: Axis, spacing: f64, from_inside: bool) -> (f64, DVec3);

    /// The material of each solid node among the chunk's own nodes (`n³`, x-major:
    /// `ids[x + n (y + n z)]`); `own[y + n z]` bit `x` says which are solid. The default leaves
    /// every node material 0.
    fn materials(&self, origin: I64Vec3, level: Level, own: &[u128], ids: &mut [MaterialId]) {
        let _ = (origin, level, own, ids);
    }
}

/// A generated chunk: its lists (`None`: all empty) and its materials (`None`: material 0).
#[derive(Clone, Debug, PartialEq)]
pub struct GeneratedChunk {
    /// The chunk (`None` when no node is inside).
    pub chunk: Option<Chunk>,
    /// Node materials, canonical (`None` when every solid node is material 0).
    pub materials: Option<ChunkMaterials>,
    /// Whether the field's interval bounds decided the chunk without visiting its nodes.
    pub decided: bool,
}

/// Builds the chunk `key` at `level` from `field` (see the module docs).
pub fn generate_chunk(key: ChunkKey, level: Level, field: &dyn NodeField) -> GeneratedChunk {
    let origin = key.origin_grid();
    let n = level.cells();
    if let Some(inside) = field.decided(origin, level) {
        let chunk = inside.then_some(Chunk::Solid);
        let materials = if inside { solid_materials(origin, level, field) } else { None };
        return GeneratedChunk { chunk, materials, decided: true };
    }
    let m = n + 1;
    let mut rows = vec![0u128; m * m];
    field.node_states(origin, level, &mut rows);
    let full = node_mask(n);
    for r in rows.iter_mut() {
        *r &= full;
    }
    let sp = level.spacing();
    let mut builder = ChunkBuilder::default();
    builder.begin(level);
    let mut line = WorkLine::EMPTY;
    for axis in Axis::ALL {
        builder.begin_axis(axis);
        for v in 0..n {
            for u in 0..n {
                line.states = line_states(&rows, axis, u, v, n);
                let mut c = line.changes(n);
                while c != 0 {
                    let e = c.trailing_zeros() as usize;
                    c &= c - 1;
                    let from_inside = (line.states >> e) & 1 == 1;
                    let local = compose(axis, e, u, v);
                    let from = origin.as_dvec3() + DVec3::from_array(local.map(|k| k as f64 * sp));
                    let (t, normal) = field.crossing(from, axis, sp, from_inside);
                    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.5 };
                    let dir = axis.unit();
                    let mut normal = if normal.is_finite() && normal.length_squared() > 0.0 {
                        normal
                    } else if from_inside {
                        dir
                    } else {
                        -dir
                    };
                    // Outward along the line: towards the empty end.
                    if (normal.dot(dir) > 0.0) != from_inside {
                        normal = -normal;
                    }
                    line.pos[e] = quantize_into_edge((e as f64 + t) * sp, e, level);
                    line.nrm[e] = pack_normal(normal);
                }
                builder.push_work(&line, n);
            }
        }
    }
    let built = builder.finish();
    let chunk = built.into_chunk();
    let materials = match &chunk {
        None => None,
        Some(Chunk::Solid) => solid_materials(origin, level, field),
        Some(Chunk::Lists(_)) => {
            let own: Vec<u128> = (0..n * n)
                .map(|i| {
                    let (y, z) = (i % n, i / n);
                    rows[y + m * z] & ((1u128 << n) - 1)
                })
                .collect();
            let mut ids = vec![0; n * n * n];
            field.materials(origin, level, &own, &mut ids);
            ChunkMaterials::encode(&ids, &own, n)
        }
    };
    GeneratedChunk { chunk, materials, decided: false }
}

/// The materials of chunk `key` if every node of it is solid, per node of `level`: a volume
/// reads a uniform chunk's materials at its own level, so a solid chunk generated at another
/// level (far terrain, coarser) takes these at the volume's.
pub fn solid_chunk_materials(key: ChunkKey, level: Level, field: &dyn NodeField) -> Option<ChunkMaterials> {
    solid_materials(key.origin_grid(), level, field)
}

/// Materials of a chunk every node of which is solid.
fn solid_materials(origin: I64Vec3, level: Level, field: &dyn NodeField) -> Option<ChunkMaterials> {
    let n = level.cells();
    let own = vec![(1u128 << n) - 1; n * n];
    let mut ids = vec![0; n * n * n];
    field.materials(origin, level, &own, &mut ids);
    ChunkMaterials::encode(&ids, &own, n)
}

/// Node states of line `(u, v)` along `axis` (across axes as [`Axis::across`] orders them), bit
/// `j` for node `j`, read from the x rows.
#[inline]
fn line_states(rows: &[u128], axis: Axis, u: usize, v: usize, n: usize) -> u128 {
    let m = n + 1;
    match axis {
        Axis::X => rows[u + m * v],
        // y lines: u = z, v = x.
        Axis::Y => (0..=n).fold(0, |s, j| s | (((rows[j + m * u] >> v) & 1) << j)),
        // z lines: u = x, v = y.
        Axis::Z => (0..=n).fold(0, |s, j| s | (((rows[v + m * j] >> u) & 1) << j)),
    }
}

impl Built {
    /// Whether the build is all one state (for tests).
    #[cfg(test)]
    fn is_uniform(&self) -> bool {
        matches!(self, Built::Uniform(_))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Volume;

    /// A half-space `y < h` with a tilt: inside below the plane `y = h + s x`.
    struct Plane {
        h: f64,
        s: f64,
    }

    impl NodeField for Plane {
        fn node_states(&self, origin: I64Vec3, level: Level, rows: &mut [u128]) {
            let n = level.cells();
            let sp = level.spacing();
            for z in 0..=n {
                for y in 0..=n {
                    for x in 0..=n {
                        let p = origin.as_dvec3() + DVec3::new(x as f64, y as f64, z as f64) * sp;
                        if p.y <= self.h + self.s * p.x {
                            rows[y + (n + 1) * z] |= 1 << x;
                        }
                    }
                }
            }
        }

        fn crossing(&self, from: DVec3, axis: Axis, sp: f64, _from_inside: bool) -> (f64, DVec3) {
            let f = |p: DVec3| p.y - self.h - self.s * p.x;
            let (a, b) = (f(from), f(from + axis.unit() * sp));
            (a / (a - b), DVec3::new(-self.s, 1.0, 0.0).normalize())
        }

        fn materials(&self, _origin: I64Vec3, level: Level, own: &[u128], ids: &mut [MaterialId]) {
            let n = level.cells();
            for (i, id) in ids.iter_mut().enumerate() {
                if own[i / n] >> (i % n) & 1 == 1 {
                    *id = 3;
                }
            }
        }
    }

    #[test]
    fn a_generated_plane_keeps_every_invariant_on_and_off_the_grid() {
        // h on a node plane (ties: nodes exactly on the surface are inside) and between planes.
        for (h, s) in [(8.0, 0.0), (8.25, 0.0), (5.0, 0.5), (3.0, 0.3)] {
            let field = Plane { h, s };
            let mut v = Volume::new();
            let keys =
                [ChunkKey::new(0, 0, 0), ChunkKey::new(1, 0, 0), ChunkKey::new(0, -1, 0), ChunkKey::new(0, 1, 1)];
            for key in keys {
                let g = generate_chunk(key, Level::BASE, &field);
                v.put_chunk(key, g.chunk, g.materials);
            }
            v.check_invariants_within(&|k| keys.contains(&k)).unwrap();
            // Node states equal the predicate wherever the volume holds a chunk of lists.
            for x in 0..16 {
                for y in -16..32 {
                    let inside = v.is_inside(DVec3::new(x as f64, y as f64, 3.0));
                    assert_eq!(inside, y as f64 <= h + s * x as f64, "node ({x}, {y})");
                }
            }
            assert_eq!(v.node_material_at(I64Vec3::new(2, 0, 2)), Some(3));
        }
    }

    #[test]
    fn builds_of_one_state_are_uniform() {
        let mut b = ChunkBuilder::default();
        b.begin(Level::BASE);
        assert!(b.finish().is_uniform());
        let g = generate_chunk(ChunkKey::new(0, -3, 0), Level::BASE, &Plane { h: 8.0, s: 0.0 });
        assert_eq!(g.chunk, Some(Chunk::Solid));
        assert_eq!(g.materials, Some(ChunkMaterials::Uniform(3)));
    }

    /// A field whose crossings lie: out of the cell, NaN, normals of zero length or pointing
    /// inwards. The chunk still keeps every invariant (crossings clamped strictly into their
    /// cells, normals outward).
    struct Liar(u32);

    impl NodeField for Liar {
        fn node_states(&self, _origin: I64Vec3, level: Level, rows: &mut [u128]) {
            let n = level.cells();
            // A checkerboard of columns, solid up to a height that varies: many crossings.
            for z in 0..=n {
                for y in 0..=n {
                    for x in 0..=n {
                        if (x * 7 + z * 3 + self.0 as usize) % 11 > y % 5 {
                            rows[y + (n + 1) * z] |= 1 << x;
                        }
                    }
                }
            }
        }

        fn crossing(&self, from: DVec3, _axis: Axis, _sp: f64, _from_inside: bool) -> (f64, DVec3) {
            match (from.x as i64 + from.y as i64 + self.0 as i64).rem_euclid(4) {
                0 => (f64::NAN, DVec3::NAN),
                1 => (7.0, DVec3::ZERO),
                2 => (-3.0, DVec3::new(0.0, 1e300, -1e300)),
                _ => (1.0, DVec3::Y),
            }
        }
    }

    #[test]
    fn lying_crossings_are_clamped_into_their_cells() {
        for seed in 0..4 {
            let mut v = Volume::new();
            let g = generate_chunk(ChunkKey::new(0, 0, 0), Level::BASE, &Liar(seed));
            v.put_chunk(ChunkKey::new(0, 0, 0), g.chunk, g.materials);
            v.check_invariants_within(&|k| k == ChunkKey::new(0, 0, 0)).unwrap();
        }
    }
}
