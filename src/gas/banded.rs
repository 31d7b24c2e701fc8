//! Cholesky factorisation A = L Lᵀ of a symmetric positive definite band matrix (the
//! unblocked form of LAPACK's `dpbtrf`). The d'Arcy system of a tube grid couples a node
//! only to nodes at most one cross-section (nx·ny nodes) away in the axis-major numbering
//! of [`plugflow_coupling::TubeGrid::node`], so its half-bandwidth is the cross-section's
//! node count (4 for a 2 × 2 grid): the factorisation costs n b² flops in one pass over
//! contiguous rows, where the general sparse Cholesky spent most of a gas step walking its
//! elimination tree (`cargo bench`-free evidence: 13 % of the horizontal case's wall in
//! faer's numeric factorisation, measured by perf on 2026-12-03).

use crate::Real;

/// The lower band of a symmetric matrix, factorised in place.
#[derive(Debug, Clone)]
pub struct BandCholesky {
    n: usize,
    /// Half-bandwidth: entries (i, j) with i − b ≤ j ≤ i.
    b: usize,
    /// Row i holds columns i − b ..= i at `band[i * (b + 1) + (j + b − i)]` (the diagonal
    /// last); entries left of column 0 stay zero.
    band: Vec<Real>,
    /// 1 / L_ii: the substitutions multiply (a division's latency on every row of the
    /// two serial sweeps was most of a solve).
    inv_diag: Vec<Real>,
}

impl BandCholesky {
    /// An n × n matrix of half-bandwidth `b`, all zero.
    pub fn new(n: usize, b: usize) -> Self {
        Self {
            n,
            b,
            band: vec![0.0; n * (b + 1)],
            inv_diag: vec![0.0; n],
        }
    }

    /// Half-bandwidth.
    pub fn half_bandwidth(&self) -> usize {
        self.b
    }

    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> usize {
        i * (self.b + 1) + (j + self.b - i)
    }

    /// Set the matrix from the entries (row, column, value) of its lower triangle (row ≥
    /// column, each at most once; the rest is zero). Entries outside the band are refused.
    pub fn set(
        &mut self,
        entries: impl Iterator<Item = ((usize, usize), Real)>,
    ) -> Result<(), String> {
        self.band.iter_mut().for_each(|v| *v = 0.0);
        for ((i, j), v) in entries {
            if j > i || i - j > self.b || i >= self.n {
                return Err(format!(
                    "entry ({i}, {j}) outside the lower band of half-width {}",
                    self.b
                ));
            }
            let k = self.at(i, j);
            self.band[k] = v;
        }
        Ok(())
    }

    /// Factorise in place; refused when a pivot is not positive (the matrix is not
    /// positive definite), naming the row.
    pub fn factor(&mut self) -> Result<(), String> {
        let (n, b) = (self.n, self.b);
        for i in 0..n {
            let first = i.saturating_sub(b);
            for j in first..=i {
                // A_ij − Σ_k L_ik L_jk over the columns both rows hold.
                let mut s = self.band[self.at(i, j)];
                for k in first.max(j.saturating_sub(b))..j {
                    s -= self.band[self.at(i, k)] * self.band[self.at(j, k)];
                }
                let v = if j == i {
                    if s.is_nan() || s <= 0.0 {
                        return Err(format!(
                            "band Cholesky: pivot {s:e} at row {i} (not positive definite)"
                        ));
                    }
                    let d = s.sqrt();
                    self.inv_diag[i] = 1.0 / d;
                    d
                } else {
                    s * self.inv_diag[j]
                };
                let k = self.at(i, j);
                self.band[k] = v;
            }
        }
        Ok(())
    }

    /// Solve L Lᵀ x = r in place (after [`BandCholesky::factor`]).
    pub fn solve_in_place(&self, x: &mut [Real]) {
        let (n, b) = (self.n, self.b);
        for i in 0..n {
            let mut s = x[i];
            for k in i.saturating_sub(b)..i {
                s -= self.band[self.at(i, k)] * x[k];
            }
            x[i] = s * self.inv_diag[i];
        }
        for i in (0..n).rev() {
            let mut s = x[i];
            for k in i + 1..n.min(i + b + 1) {
                s -= self.band[self.at(k, i)] * x[k];
            }
            x[i] = s * self.inv_diag[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diffusion-like SPD band matrix (the d'Arcy system's shape: a dominant diagonal,
    /// negative couplings b and 1 apart): A x = r is solved to round-off, and a matrix that
    /// is not positive definite is refused.
    #[test]
    fn solves_a_band_system_and_refuses_an_indefinite_one() {
        let (n, b) = (40, 4);
        let mut entries = Vec::new();
        for i in 0..n {
            entries.push(((i, i), 10.0 + (i % 7) as Real));
            for d in [1, b] {
                if i >= d {
                    entries.push(((i, i - d), -1.0 - 0.1 * (i % 3) as Real));
                }
            }
        }
        let mut m = BandCholesky::new(n, b);
        m.set(entries.iter().copied()).unwrap();
        m.factor().unwrap();
        let r: Vec<Real> = (0..n).map(|i| (i as Real * 0.37).sin()).collect();
        let mut x = r.clone();
        m.solve_in_place(&mut x);
        // The residual A x − r from the entries themselves (both triangles).
        let mut ax = vec![0.0; n];
        for &((i, j), v) in &entries {
            ax[i] += v * x[j];
            if i != j {
                ax[j] += v * x[i];
            }
        }
        for i in 0..n {
            assert!(
                (ax[i] - r[i]).abs() < 1e-14,
                "row {i}: {} vs {}",
                ax[i],
                r[i]
            );
        }
        let mut bad = BandCholesky::new(2, 1);
        bad.set([((0, 0), 1.0), ((1, 0), 2.0), ((1, 1), 1.0)].into_iter())
            .unwrap();
        assert!(bad.factor().unwrap_err().contains("row 1"));
        assert!(BandCholesky::new(3, 1)
            .set([((2, 0), 1.0)].into_iter())
            .is_err());
    }
}
