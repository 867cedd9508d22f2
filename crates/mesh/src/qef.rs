//! The quadratic error function of dual contouring, solved stably.
//!
//! Minimises `Σ (nᵢ · (x − pᵢ))²` over the planes (point `pᵢ`, unit normal `nᵢ`) of a cell's
//! edge crossings. The normal equations `A x = b` (`A = Σ nᵢ nᵢᵀ`) are solved around the mass
//! point `c` (the mean of the `pᵢ`) with a pseudo-inverse from an eigen-decomposition of the
//! symmetric `A`: directions whose eigenvalue falls below `EIGEN_CUTOFF` times the largest are
//! left at the mass point. Flat regions so get the mass point along the surface, edges keep
//! their line, corners their point.

use glam::{DMat3, DVec3};

/// Relative eigenvalue cut-off. Normals are stored with 8 + 8-bit octahedral precision (≤ 0.7°
/// error, so noise eigenvalues of about `k · sin²(0.7°) ≈ 1.5e-4 k` for `k` planes); a true
/// feature direction has an eigenvalue of order `k · sin²(angle)` with the feature's angle. The
/// cut at 0.02 keeps features sharper than about 8° (sin² 8° ≈ 0.02) and drops noise by two
/// orders of magnitude; the box-corner tests (corners within 0.05 cells) pass with it.
pub const EIGEN_CUTOFF: f64 = 0.02;

/// Accumulates planes and solves.
#[derive(Clone, Copy, Debug)]
pub struct Qef {
    ata: DMat3,
    atb: DVec3,
    btb: f64,
    mass: DVec3,
    normal_sum: DVec3,
    count: u32,
}

impl Default for Qef {
    /// No planes. (`DMat3::default()` is the identity, so this cannot be derived.)
    fn default() -> Self {
        Qef { ata: DMat3::ZERO, atb: DVec3::ZERO, btb: 0.0, mass: DVec3::ZERO, normal_sum: DVec3::ZERO, count: 0 }
    }
}

impl Qef {
    /// Adds the plane through `p` with unit normal `n`.
    pub fn add(&mut self, p: DVec3, n: DVec3) {
        self.ata += DMat3::from_cols(n * n.x, n * n.y, n * n.z);
        let d = n.dot(p);
        self.atb += n * d;
        self.btb += d * d;
        self.mass += p;
        self.normal_sum += n;
        self.count += 1;
    }

    /// The number of planes added.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// The mass point (mean of the added points).
    pub fn mass_point(&self) -> DVec3 {
        if self.count == 0 { DVec3::ZERO } else { self.mass / self.count as f64 }
    }

    /// The minimiser, biased to the mass point in directions the planes do not constrain.
    pub fn solve(&self) -> DVec3 {
        let c = self.mass_point();
        // Solve A (x - c) = b - A c.
        let rhs = self.atb - self.ata * c;
        // Nearly parallel planes (smooth surface, most cells): if every normal is within about
        // 5.7 degrees of their mean `m`, the other eigenvalues are below the cut-off
        // (k sin² 5.7° ≈ 0.01 k < 0.02 k), so the pseudo-inverse keeps only the direction `m`:
        // no eigen-decomposition needed. The spread bound: k (1 - |mean|) ≥ 1 - cos(max angle).
        let k = self.count as f64;
        let resultant = self.normal_sum.length();
        if k > 0.0 && k * (1.0 - resultant / k) < 1.0 - 5.7f64.to_radians().cos() {
            let m = self.normal_sum / resultant;
            let lambda = m.dot(self.ata * m);
            return if lambda > 0.0 { c + m * (m.dot(rhs) / lambda) } else { c };
        }
        let (values, vectors) = symmetric_eigen(self.ata);
        let largest = values.abs().max_element();
        if largest <= 0.0 {
            return c;
        }
        let mut x = DVec3::ZERO;
        for i in 0..3 {
            if values[i].abs() > EIGEN_CUTOFF * largest {
                let v = vectors.col(i);
                x += v * (v.dot(rhs) / values[i]);
            }
        }
        c + x
    }

    /// The residual error at `x`.
    pub fn error(&self, x: DVec3) -> f64 {
        (x.dot(self.ata * x) - 2.0 * x.dot(self.atb) + self.btb).max(0.0)
    }
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 3×3 matrix by cyclic Jacobi rotations.
pub fn symmetric_eigen(m: DMat3) -> (DVec3, DMat3) {
    let mut a = m.to_cols_array_2d();
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..32 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        if off < 1e-24 * (a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2]).max(1e-300) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-300 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A' = Jᵀ A J with the rotation J in the (p, q) plane.
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * rp[k] - s * rq[k];
                a[q][k] = s * rp[k] + c * rq[k];
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    // `v` holds eigenvectors as columns in row-major layout: v[row][col].
    let vectors = DMat3::from_cols(
        DVec3::new(v[0][0], v[1][0], v[2][0]),
        DVec3::new(v[0][1], v[1][1], v[2][1]),
        DVec3::new(v[0][2], v[1][2], v[2][2]),
    );
    (DVec3::new(a[0][0], a[1][1], a[2][2]), vectors)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_decomposition_reconstructs_the_matrix() {
        let m = DMat3::from_cols(DVec3::new(4.0, 1.0, 0.5), DVec3::new(1.0, 3.0, 0.2), DVec3::new(0.5, 0.2, 1.0));
        let (values, vectors) = symmetric_eigen(m);
        let back = vectors * DMat3::from_diagonal(values) * vectors.transpose();
        assert!((back - m).abs().to_cols_array().iter().all(|&e| e < 1e-10), "{back} vs {m}");
    }

    #[test]
    fn three_planes_meet_at_their_corner_and_two_keep_their_edge() {
        let corner = DVec3::new(0.3, 0.7, 0.4);
        let mut q = Qef::default();
        for (n, d) in [
            (DVec3::X, DVec3::new(0.0, 0.1, 0.9)),
            (DVec3::Y, DVec3::new(0.8, 0.0, 0.2)),
            (DVec3::Z, DVec3::new(0.1, 0.6, 0.0)),
        ] {
            q.add(corner + d - n * n.dot(d), n);
            q.add(corner + d * 0.5 - n * n.dot(d * 0.5), n);
        }
        assert!((q.solve() - corner).length() < 1e-9, "{}", q.solve());
        let mut e = Qef::default();
        e.add(DVec3::new(0.3, 0.1, 0.2), DVec3::X);
        e.add(DVec3::new(0.3, 0.9, 0.8), DVec3::X);
        e.add(DVec3::new(0.6, 0.7, 0.5), DVec3::Y);
        e.add(DVec3::new(0.1, 0.7, 0.1), DVec3::Y);
        let x = e.solve();
        assert!((x.x - 0.3).abs() < 1e-9 && (x.y - 0.7).abs() < 1e-9, "{x}");
        assert!((x.z - e.mass_point().z).abs() < 1e-9, "free direction stays at the mass point");
        assert!(e.error(x) < 1e-18);
    }

    #[test]
    fn nearly_parallel_planes_take_the_fast_path_and_agree_with_the_eigen_solve() {
        let mut q = Qef::default();
        let normals = [DVec3::new(0.02, 0.0, 1.0), DVec3::new(-0.01, 0.03, 1.0), DVec3::new(0.0, -0.02, 1.0)];
        for (i, n) in normals.iter().enumerate() {
            q.add(DVec3::new(0.2 + 0.3 * i as f64, 0.7 - 0.2 * i as f64, 0.41 + 0.01 * i as f64), n.normalize());
        }
        let fast = q.solve();
        // The general path on the same data: force it by asking for the eigen pseudo-inverse.
        let c = q.mass_point();
        let rhs = q.atb - q.ata * c;
        let (values, vectors) = symmetric_eigen(q.ata);
        let largest = values.abs().max_element();
        let mut x = DVec3::ZERO;
        for i in 0..3 {
            if values[i].abs() > EIGEN_CUTOFF * largest {
                let v = vectors.col(i);
                x += v * (v.dot(rhs) / values[i]);
            }
        }
        assert!((fast - (c + x)).length() < 1e-3, "{fast} vs {}", c + x);
    }

    #[test]
    fn an_empty_qef_holds_no_plane() {
        let mut q = Qef::default();
        q.add(DVec3::new(0.25, 0.5, 0.5), DVec3::X);
        let x = q.solve();
        assert!((x - DVec3::new(0.25, 0.5, 0.5)).length() < 1e-12, "{x}");
    }
}
