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
