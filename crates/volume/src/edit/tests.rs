use super::*;

/// Inside state of a line at fixed-point position `q` (not on a crossing).
fn state_at(l: &WorkLine, q: u32, level: Level) -> bool {
    let e = (q / level.steps_per_cell()) as usize;
    let before = (l.states >> e) & 1 == 1;
    let after = (l.states >> (e + 1)) & 1 == 1;
    if before != after && q > l.pos[e].0 as u32 { after } else { before }
}

#[test]
fn a_simple_range_reaches_exactly_the_chunks_holding_one_of_its_nodes() {
    let n = 16;
    for off in [-1_000_000, -40, -17, -16, -1, 0, 1, 15, 16, 17, 40, 1_000_000] {
        assert_eq!(reach(NO_NODES, off, n), None, "no spans, offset {off}");
        assert!(reach(ALL_NODES, off, n).is_some(), "general sampler, offset {off}");
        for j0 in -20..40 {
            for j1 in j0 - 2..j0 + 40 {
                // Brute force: the chunk line's nodes 0..=n that lie in j0..=j1.
                let inside: Vec<i64> = (0..=n as i64).filter(|&j| (j0..=j1).contains(&(off + j))).collect();
                let got = reach((j0 as i32, j1 as i32), off, n).map(|(ja, jb)| (ja.max(0), jb.min(n as i64)));
                let expect = inside.first().map(|&a| (a, *inside.last().unwrap()));
                assert_eq!(got, expect, "range {j0}..={j1}, offset {off}");
            }
        }
    }
}

#[test]
fn per_cell_csg_equals_continuous_csg_wherever_the_result_changes_once() {
    let level = Level::BASE;
    let n = level.cells();
    let s = level.steps_per_cell();
    let mut seed = 7u64;
    let mut rnd = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 33) as u32
    };
    let random_line = |rnd: &mut dyn FnMut() -> u32| {
        let mut l = WorkLine::EMPTY;
        l.states = (rnd() as u128 | ((rnd() as u128) << 32)) & node_mask(n);
        for e in 0..n {
            l.pos[e] = crate::coords::LocalPos((e as u32 * s + 1 + rnd() % (s - 1)) as u16);
            l.nrm[e] = crate::normal::PackedNormal(rnd() as u16);
        }
        l
    };
    for _ in 0..1000 {
        let a = random_line(&mut rnd);
        let b = random_line(&mut rnd);
        for op in [CsgOp::Add, CsgOp::Subtract, CsgOp::Intersect] {
            let mut out = WorkLine::EMPTY;
            combine(&a, &b, op, n, &mut out);
            let f = |q: u32| {
                let (x, y) = (state_at(&a, q, level), state_at(&b, q, level));
                match op {
                    CsgOp::Add => x | y,
                    CsgOp::Subtract => x & !y,
                    CsgOp::Intersect => x & y,
                }
            };
            for j in 0..=n {
                let bit = |l: &WorkLine| (l.states >> j) & 1 == 1;
                let expect = match op {
                    CsgOp::Add => bit(&a) | bit(&b),
                    CsgOp::Subtract => bit(&a) & !bit(&b),
                    CsgOp::Intersect => bit(&a) & bit(&b),
                };
                assert_eq!(bit(&out), expect, "node states are the CSG of node states");
            }
            let mut c = out.changes(n);
            while c != 0 {
                let e = c.trailing_zeros() as usize;
                c &= c - 1;
                // The continuous result switches at most twice in the cell; where it switches
                // once, the stored crossing must be exactly there.
                let lo = e as u32 * s;
                let switches: Vec<u32> = (lo + 1..lo + s).filter(|&q| f(q) != f(q - 1)).map(|q| q - 1).collect();
                if switches.len() == 1 {
                    assert_eq!(out.pos[e].0 as u32, switches[0], "{op:?} cell {e}");
                }
            }
        }
    }
}

proptest::proptest! {
    /// The y and z rows a reconciled brush's lines are forced to read, bit for bit, the nodes of
    /// the x rows they came from (every line of the chunk and its apron, at every chunk size).
    #[test]
    fn node_states_along_y_and_z_read_the_x_rows_node_by_node(
        size in 0usize..3,
        seed in proptest::prelude::any::<u64>(),
        density in 0u32..=4,
    ) {
        let n = [16usize, 32, 64][size];
        let m = n + 1;
        let full = (1u128 << m) - 1;
        // Random rows, sparse to dense (density 0: empty, 4: every node inside).
        let mut state = seed | 1;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut states = NodeStates::default();
        for _ in 0..m * m {
            let mut row = full;
            for _ in density..4 {
                row &= (u128::from(next()) << 64 | u128::from(next())) | !full;
            }
            states.x.push(if density == 0 { 0 } else { row & full });
        }
        states.transpose(n);
        for u in 0..m {
            for v in 0..m {
                let (mut y, mut z) = (0u128, 0u128);
                for j in 0..m {
                    // y line (u, v) = (z, x): node (v, j, u); z line (u, v) = (x, y): node (u, v, j).
                    y |= ((states.x[j + m * u] >> v) & 1) << j;
                    z |= ((states.x[v + m * j] >> u) & 1) << j;
                }
                proptest::prop_assert_eq!(states.along(Axis::Y, u, v, n), y, "y line {} {}", u, v);
                proptest::prop_assert_eq!(states.along(Axis::Z, u, v, n), z, "z line {} {}", u, v);
            }
        }
    }

    /// A line's node states read without its crossings equal the states of the full reading,
    /// and a table line's simple node range gives them without reading its span: spans with ends
    /// on nodes, within and just beyond the snapping distance of them, and between them, on
    /// lines of every level in chunks before, on and after the table's base.
    #[test]
    fn node_states_from_a_simple_range_equal_the_samplers(
        level in 0usize..4,
        chunk in -3i64..4,
        ends in proptest::collection::vec((-40i64..100, 0usize..8, 0u32..1000), 0..7),
    ) {
        let level = Level::ALL[level];
        let (n, sp, inv_sp) = (level.cells(), level.spacing(), level.nodes_per_unit());
        // An end at a node (table node units), moved on or off the grid.
        let mut ts: Vec<f64> = ends
            .iter()
            .map(|&(j, how, frac)| {
                let moved = [
                    0.0,
                    0.5 * SNAP_DISTANCE,
                    -0.5 * SNAP_DISTANCE,
                    2.0 * SNAP_DISTANCE,
                    -2.0 * SNAP_DISTANCE,
                    1e-12,
                    f64::from(frac) / 1000.0 * sp,
                    -f64::from(frac) / 1000.0 * sp,
                ][how];
                j as f64 * sp + moved
            })
            .collect();
        ts.sort_by(f64::total_cmp);
        ts.dedup();
        let spans: Vec<Span> = ts
            .chunks_exact(2)
            .filter(|p| p[0] < p[1])
            .map(|p| Span { enter: p[0], exit: p[1], enter_normal: -DVec3::X, exit_normal: DVec3::X })
            .collect();
        let brush = crate::brush::Sphere::new(DVec3::new(20.0, 3.0, -5.0), 30.0).unwrap();
        let sampler = LineSampler::new(&brush, false);
        // The chunk `chunk` x chunks ahead of the table's base, on one of its lines.
        let (shift, off) = ((chunk * CHUNK_CELLS) as f64, chunk * n as i64);
        let at = LineAt { origin_grid: I64Vec3::new(chunk * CHUNK_CELLS, 0, 0), level, axis: Axis::X, u: 1, v: 2 };
        let states = sampler.states_from_spans(&spans, shift, at);
        let mut full = WorkLine::EMPTY;
        sampler.fill_from_spans(&spans, shift, at, &mut full);
        proptest::prop_assert_eq!(states, full.states, "spans {:?}", spans);
        if let Some(simple) = simple_states(simple_range(&spans, inv_sp), off, n) {
            proptest::prop_assert_eq!(simple, states, "spans {:?}", spans);
        }
    }
}
