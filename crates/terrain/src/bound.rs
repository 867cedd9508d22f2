//! Proven ranges of the `noise` crate's 3D Perlin noise over a box, so that a box of nodes the
//! cave noise cannot carve (or must carve) is decided without sampling a node.
//!
//! The crate's `perlin_3d` at a point `p` takes the lattice cell `c = ⌊p⌋` and `d = p − c`
//! (`d ∈ [0, 1)³`), the gradient `G_k` of each corner `k` (chosen by the permutation table's hash
//! of the corner; two components ±1, one 0), the corner values `g_k = G_k · (d − k)`, and
//! interpolates them trilinearly with the weights `s(d_x)`, `s(d_y)`, `s(d_z)` of the quintic
//! `s(t) = t³ (t (6t − 15) + 10)`, times `2/√3`, clamped to `[−1, 1]`.
//!
//! Over a box of `d` inside one cell every piece has an exact range: `g_k` is linear in `d`, so
//! its range is the sum of its two terms' ranges; `s` increases on `[0, 1]`, so a weight's range
//! is `s` at the box's ends; and `lerp(a, b, t) = b t + a (1 − t)` is linear in each of `a`, `b`
//! and `t` on its own, so over a box of the three its extremes lie at the box's corners. Taking
//! the pieces as independent only widens the range, so the result holds every value of the
//! noise in the box. A box crossing cell boundaries is split at them and the ranges joined.
//! The crate computes in `f64`; the range is widened by [`ROUNDING`], far more than its rounding
//! (a few units in the last place of values below 2), and both its ends are clamped into
//! `[−1, 1]` as the crate clamps its value. The table, the gradients by hash, the weight and the
//! scale are [`crate::perlin`]'s, the one statement of the crate's noise here.

use crate::perlin::{GRADIENTS_3, Perlin, SCALE_3, quintic};

/// Added to both ends of a range: above the noise's own rounding (values below 2, a few dozen
/// operations).
const ROUNDING: f64 = 1e-9;

/// Boxes spanning more lattice cells than this on an axis get the noise's whole range (the
/// callers bound chunks and smaller boxes; a box that large decides nothing anyway).
const MAX_CELLS_PER_AXIS: i64 = 8;

/// The range of `b t + a (1 − t)` over `a`, `b`, `t` in their ranges (`t ⊂ [0, 1]`).
#[inline]
fn lerp(a: (f64, f64), b: (f64, f64), t: (f64, f64)) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for ta in [t.0, t.1] {
        for va in [a.0, a.1] {
            for vb in [b.0, b.1] {
                let v = vb * ta + va * (1.0 - ta);
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    (lo, hi)
}

/// The range of one corner's value `G · (d − k)` for `d` in `[lo, hi]` (cell-local), `G` the
/// gradient its hash picks (two axes, each ±1: the sum of two terms' ranges).
#[inline]
fn corner(hash: u8, k: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> (f64, f64) {
    let term =
        |i: usize, sign: f64| if sign > 0.0 { (lo[i] - k[i], hi[i] - k[i]) } else { (k[i] - hi[i], k[i] - lo[i]) };
    let (a, sa, b, sb) = GRADIENTS_3[usize::from(hash & 15)];
    let (ta, tb) = (term(a, sa), term(b, sb));
    (ta.0 + tb.0, ta.1 + tb.1)
}

/// Ranges of one Perlin noise (the crate's, for the same seed).
#[derive(Clone)]
pub(crate) struct PerlinRange {
    noise: Perlin,
}

impl std::fmt::Debug for PerlinRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PerlinRange")
    }
}

impl PerlinRange {
    /// The ranges of `noise::Perlin::new(seed)`.
    pub(crate) fn new(seed: u32) -> Self {
        PerlinRange { noise: Perlin::new(seed) }
    }

    /// A range holding the noise at every point of the box `[lo, hi]` (noise coordinates).
    pub(crate) fn range(&self, lo: [f64; 3], hi: [f64; 3]) -> (f64, f64) {
        if !lo.iter().chain(&hi).all(|v| v.is_finite()) {
            return (-1.0, 1.0);
        }
        let c0 = lo.map(|v| v.floor() as i64);
        let c1 = hi.map(|v| v.floor() as i64);
        if (0..3).any(|i| c1[i].saturating_sub(c0[i]) >= MAX_CELLS_PER_AXIS) {
            return (-1.0, 1.0);
        }
        let mut out = (f64::INFINITY, f64::NEG_INFINITY);
        for cz in c0[2]..=c1[2] {
            for cy in c0[1]..=c1[1] {
                for cx in c0[0]..=c1[0] {
                    let c = [cx, cy, cz];
                    // The part of the box in this cell, cell-local, inside [0, 1].
                    let l: [f64; 3] = std::array::from_fn(|i| (lo[i] - c[i] as f64).clamp(0.0, 1.0));
                    let h: [f64; 3] = std::array::from_fn(|i| (hi[i] - c[i] as f64).clamp(0.0, 1.0));
                    let r = self.cell(c, l, h);
                    out = (out.0.min(r.0), out.1.max(r.1));
                }
            }
        }
        // The crate clamps its value into [-1, 1] (unclamped it reaches 2/√3 in magnitude): so
        // are both ends, or a box wholly above 1 would not hold the 1 the crate returns.
        ((out.0 - ROUNDING).clamp(-1.0, 1.0), (out.1 + ROUNDING).clamp(-1.0, 1.0))
    }

    /// The range over the cell-local box `[l, h]` of the cell at `c`, before the rounding margin.
    fn cell(&self, c: [i64; 3], l: [f64; 3], h: [f64; 3]) -> (f64, f64) {
        let g = |x: i64, y: i64, z: i64| {
            corner(self.noise.hash3([c[0] + x, c[1] + y, c[2] + z]), [x as f64, y as f64, z as f64], l, h)
        };
        let w: [(f64, f64); 3] = std::array::from_fn(|i| (quintic(l[i]), quintic(h[i])));
        let x0 = lerp(lerp(g(0, 0, 0), g(0, 0, 1), w[2]), lerp(g(0, 1, 0), g(0, 1, 1), w[2]), w[1]);
        let x1 = lerp(lerp(g(1, 0, 0), g(1, 0, 1), w[2]), lerp(g(1, 1, 0), g(1, 1, 1), w[2]), w[1]);
        let r = lerp(x0, x1, w[0]);
        (r.0 * SCALE_3, r.1 * SCALE_3)
    }
}

#[cfg(test)]
mod tests {
    use noise::{NoiseFn, Perlin};
    use proptest::prelude::*;

    use super::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

        /// Every sample of a box lies in its range, and the range is not the trivial one for
        /// small boxes (a range that always answered `[-1, 1]` would pass the first part).
        #[test]
        fn the_range_holds_every_sample_of_the_box(
            seed in any::<u32>(),
            origin in prop::array::uniform3(-300.0f64..300.0),
            size in prop::array::uniform3(0.0f64..1.5),
            on_lattice in any::<bool>(),
        ) {
            let lo = if on_lattice { origin.map(f64::round) } else { origin };
            let hi: [f64; 3] = std::array::from_fn(|i| lo[i] + size[i]);
            let noise = Perlin::new(seed);
            let (a, b) = PerlinRange::new(seed).range(lo, hi);
            prop_assert!(a <= b);
            let steps = 6;
            let mut seen = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..=steps {
                for j in 0..=steps {
                    for i in 0..=steps {
                        let t = [i, j, k].map(|s| s as f64 / steps as f64);
                        let p: [f64; 3] = std::array::from_fn(|q| lo[q] + t[q] * size[q]);
                        let v = noise.get(p);
                        prop_assert!(a <= v && v <= b, "{v} at {p:?} outside [{a}, {b}]");
                        seen = (seen.0.min(v), seen.1.max(v));
                    }
                }
            }
            if size.iter().all(|&s| s < 0.1) {
                // Small boxes get ranges not much wider than what they hold.
                prop_assert!(b - a < (seen.1 - seen.0) + 1.5, "[{a}, {b}] for samples in {seen:?}");
            }
        }
    }

    /// Where the crate's value is clamped to ±1, the range holds the clamped value: found by a
    /// search over a fine lattice of points of a few seeds.
    #[test]
    fn points_the_crate_clamps_are_in_their_range() {
        let mut found = [false; 2];
        for seed in 0..32 {
            let (noise, range) = (Perlin::new(seed), PerlinRange::new(seed));
            for k in 0..60_000 {
                let p =
                    [(k % 40) as f64 * 0.1 + 0.05, ((k / 40) % 40) as f64 * 0.1 + 0.05, (k / 1600) as f64 * 0.1 + 0.05];
                let v = noise.get(p);
                if v.abs() < 1.0 {
                    continue;
                }
                found[(v > 0.0) as usize] = true;
                let (a, b) = range.range(p, p);
                assert!(a <= v && v <= b, "{v} at {p:?} (seed {seed}) outside [{a}, {b}]");
                let near: [f64; 3] = std::array::from_fn(|i| p[i] + 0.01);
                let (a, b) = range.range(p, near);
                assert!(a <= v && v <= b, "{v} at {p:?} (seed {seed}) outside [{a}, {b}] of a small box");
            }
        }
        assert!(found[0] && found[1], "no clamped value found: {found:?}");
    }

    #[test]
    fn non_finite_and_huge_boxes_get_the_whole_range() {
        let range = PerlinRange::new(3);
        assert_eq!(range.range([f64::NEG_INFINITY, 0.0, 0.0], [0.0, 0.0, 0.0]), (-1.0, 1.0));
        assert_eq!(range.range([0.0, f64::NAN, 0.0], [0.0, 0.0, 0.0]), (-1.0, 1.0));
        assert_eq!(range.range([-1e18, 0.0, 0.0], [1e18, 0.0, 0.0]), (-1.0, 1.0));
    }

    #[test]
    fn a_point_gets_the_noise_itself() {
        let noise = Perlin::new(7);
        let range = PerlinRange::new(7);
        for p in [[0.25, 1.5, -3.75], [10.0, 11.0, 12.0], [-0.1, -0.2, -0.3]] {
            let v = noise.get(p);
            let (a, b) = range.range(p, p);
            assert!(a <= v && v <= b && b - a < 1e-8, "{v} against [{a}, {b}]");
        }
    }
}
